"""GLB export and import."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib
import pytest
from PIL import Image

from facadeforge.exchange import EXPORTERS, IMPORTERS, export, load
from facadeforge.exchange.gltf import export_glb, load_glb
from facadeforge.model import Model


def test_registered():
    assert EXPORTERS["glb"] is export_glb
    assert IMPORTERS["glb"] is load_glb


def test_round_trip(tmp_path: Path, house: Model, texture_png: str, by_label):
    written = export(house, tmp_path / "house.glb")
    assert written == [tmp_path / "house.glb"]
    models = load(tmp_path / "house.glb", texture_dir=tmp_path / "tex")
    assert len(models) == 1
    back = models[0]
    assert back.name == "house"
    assert back.attributes == house.attributes
    assert back.mesh().area() == pytest.approx(house.mesh().area(), rel=1e-6)
    assert sum(p.mesh.n_faces for p in back.parts) == house.stats()["triangles"]

    before, after = by_label([house]), by_label(models)
    assert set(after) == set(before)
    for label, d in before.items():
        assert after[label]["area"] == pytest.approx(d["area"], rel=1e-6)
        assert after[label]["symbols"] == d["symbols"]
        assert after[label]["material"].color == pytest.approx(d["material"].color)
        assert after[label]["material"].opacity == pytest.approx(d["material"].opacity)

    wall = next(p for p in back.parts if p.label == "wall")
    assert wall.material.texture is not None
    assert Path(wall.material.texture).read_bytes() == Path(texture_png).read_bytes()
    assert Path(wall.material.texture).parent == tmp_path / "tex"
    uv = wall.mesh.corner_uvs
    assert uv is not None and uv.min() == pytest.approx(0) and uv.max() == pytest.approx(1)
    assert {p.shape_id for p in back.parts} == {p.shape_id for p in house.parts}


def test_uvs_and_positions_match(tmp_path: Path, house: Model):
    export(house, tmp_path / "h.glb")
    wall = next(p for p in load(tmp_path / "h.glb")[0].parts if p.label == "wall")
    src = next(p for p in house.parts if p.label == "wall").mesh
    tri = src.triangle_corners()
    assert np.allclose(wall.mesh.vertices, src.vertices[src.corners[tri]].reshape(-1, 3))
    assert np.allclose(wall.mesh.corner_uvs, src.corner_uvs[tri].reshape(-1, 2))


def test_file_layout(tmp_path: Path, house: Model):
    export(house, tmp_path / "h.glb")
    g = pygltflib.GLTF2.load_binary(str(tmp_path / "h.glb"))
    assert len(g.nodes) == len(g.meshes) == 1
    assert g.nodes[0].name == "house"
    assert g.nodes[0].extras["attributes"]["floors"] == 2
    prims = g.meshes[0].primitives
    assert len(prims) == len({(p.material.key(), p.label) for p in house.parts})
    labels = sorted(p.extras["label"] for p in prims)
    assert labels == sorted(p.label for p in house.parts)
    for prim in prims:
        assert prim.attributes.NORMAL is None and prim.indices is not None  # clients: flat normals
        count = g.accessors[prim.indices].count
        acc = g.accessors[prim.extras["parts_accessor"]]
        view = g.bufferViews[acc.bufferView]
        blob = g.binary_blob()[view.byteOffset:view.byteOffset + view.byteLength]
        records = np.frombuffer(blob, dtype=np.uint32).reshape(-1, 4)
        assert records[:, 2].sum() * 3 == count
    glass = next(m for m in g.materials if m.name == "glass")
    assert glass.alphaMode == "BLEND"
    assert glass.pbrMetallicRoughness.baseColorFactor == pytest.approx([0.2, 0.4, 0.6, 0.5])
    plaster = next(m for m in g.materials if m.name == "plaster")
    assert plaster.alphaMode == "OPAQUE"
    image = g.images[g.textures[plaster.pbrMetallicRoughness.baseColorTexture.index].source]
    assert image.mimeType == "image/png"
    wall = next(p for p in prims if p.extras["label"] == "wall")
    assert wall.attributes.TEXCOORD_0 is not None


def test_jpeg_texture_embedded_as_is(tmp_path: Path, house_factory):
    jpg = tmp_path / "t.jpg"
    Image.new("RGB", (4, 4), (10, 200, 30)).save(jpg)
    export(house_factory(str(jpg)), tmp_path / "h.glb")
    g = pygltflib.GLTF2.load_binary(str(tmp_path / "h.glb"))
    assert [im.mimeType for im in g.images] == ["image/jpeg"]
    view = g.bufferViews[g.images[0].bufferView]
    blob = g.binary_blob()
    assert blob[view.byteOffset:view.byteOffset + view.byteLength] == jpg.read_bytes()


def test_unreadable_texture_is_skipped(tmp_path: Path, house_factory):
    bad = tmp_path / "not-an-image.png"
    bad.write_bytes(b"garbage")
    for texture in (str(tmp_path / "missing.png"), str(bad)):
        export(house_factory(texture), tmp_path / "h.glb")
        g = pygltflib.GLTF2.load_binary(str(tmp_path / "h.glb"))
        assert not g.images and not g.textures
        assert all(p.material.texture is None for p in load(tmp_path / "h.glb")[0].parts)


def test_several_models_and_an_empty_one(tmp_path: Path, house_factory):
    models = [house_factory(name="a"), Model(name="empty", attributes={"k": 1}),
              house_factory(name="b")]
    export(models, tmp_path / "m.glb")
    back = load(tmp_path / "m.glb")
    assert [m.name for m in back] == ["a", "empty", "b"]
    assert back[1].parts == [] and back[1].attributes == {"k": 1}


def test_trimesh_reads_it(tmp_path: Path, house: Model):
    trimesh = pytest.importorskip("trimesh")
    export(house, tmp_path / "h.glb")
    scene = trimesh.load(tmp_path / "h.glb", force="scene")
    area = sum(g.area for g in scene.dump())
    assert area == pytest.approx(house.mesh().area(), rel=1e-5)


def test_node_transform_applied(tmp_path: Path, house: Model):
    export(house, tmp_path / "h.glb")
    g = pygltflib.GLTF2.load_binary(str(tmp_path / "h.glb"))
    g.nodes[0].translation = [10.0, 0.0, 0.0]
    g.save_binary(str(tmp_path / "moved.glb"))
    moved = load_glb(tmp_path / "moved.glb")[0]
    assert moved.mesh().bounds()[0][0] == pytest.approx(house.mesh().bounds()[0][0] + 10)


def test_not_a_glb(tmp_path: Path):
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"nope")
    with pytest.raises(ValueError):
        load(bad)
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "missing.glb")
