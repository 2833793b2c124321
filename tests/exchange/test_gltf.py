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


# -- hostile and careless files: every member read is checked, no claim is allocated ---------

def _glb(doc: dict, blob: bytes) -> bytes:
    """A GLB container of the JSON ``doc`` and the binary chunk ``blob``."""
    import json
    import struct

    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    if blob:
        body += struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def _triangle() -> tuple[dict, bytes]:
    """One indexed triangle: positions (36 bytes) then indices (12 bytes)."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    idx = np.array([0, 1, 2], np.uint32).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
           "buffers": [{"byteLength": 48}]}
    return doc, pos + idx


def test_tiny_triangle_reads(tmp_path: Path):
    doc, blob = _triangle()
    (tmp_path / "t.glb").write_bytes(_glb(doc, blob))
    (model,) = load(tmp_path / "t.glb")
    assert model.mesh().area() == pytest.approx(0.5)


@pytest.mark.parametrize("count, view", [(10**9, False), (10**8, False), (10**8, True),
                                         (2**26, True)])
def test_a_small_file_claiming_huge_accessors_allocates_nothing(tmp_path: Path, count, view):
    """The reproducer: a 1 KB .glb declaring 10^9 vertices must not allocate 12 GB."""
    import tracemalloc

    from facadeforge.exchange.errors import LoadError

    doc, blob = _triangle()
    doc["accessors"][0]["count"] = count
    if not view:
        del doc["accessors"][0]["bufferView"]
    (tmp_path / "h.glb").write_bytes(_glb(doc, blob))
    assert (tmp_path / "h.glb").stat().st_size < 1024
    tracemalloc.start()
    try:
        with pytest.raises(LoadError, match="accessors\\[0\\]") as err:
            load(tmp_path / "h.glb")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 64 * 2**20, peak
    assert str(err.value).startswith(f"glTF file '{tmp_path / 'h.glb'}': accessors[0]")


def _edit(doc: dict, path: tuple, value) -> dict:
    target = doc
    for key in path[:-1]:
        target = target[key]
    if value is KeyError:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return doc


P = ("meshes", 0, "primitives", 0)


@pytest.mark.parametrize("path, value, message", [
    ((*P, "indices"), 7, "meshes[0].primitives[0].indices is 7, not an integer from 0 below 2"),
    ((*P, "indices"), -1, "meshes[0].primitives[0].indices is -1"),
    ((*P, "attributes", "POSITION"), 1, "accessors[1].type is SCALAR, but meshes[0].primitives"
                                        "[0].attributes.POSITION must be VEC3"),
    ((*P, "attributes", "TEXCOORD_0"), 0, "accessors[0].type is VEC3, but"),
    (("accessors", 0, "bufferView"), 5, "accessors[0].bufferView is 5, not an integer from 0 "
                                        "below 2"),
    (("accessors", 0, "componentType"), 5127, "accessors[0].componentType is 5127, not one of"),
    (("accessors", 1, "componentType"), 5126, "accessors[1].componentType is 5126, but "
                                              "meshes[0].primitives[0].indices must be one of"),
    (("accessors", 0, "type"), "VEC7", "accessors[0].type is 'VEC7', not one of"),
    (("accessors", 0, "count"), -3, "accessors[0].count is -3, not an integer from 0"),
    (("accessors", 0, "byteOffset"), -4, "accessors[0].byteOffset is -4"),
    (("accessors", 1, "count"), 2, "holds 2 indices, not whole triangles"),
    (("bufferViews", 0, "byteLength"), 24, "accessors[0] runs past its buffer view"),
    (("bufferViews", 1, "byteOffset"), 40, "accessors[1] runs past its buffer view"),
    (("bufferViews", 0, "byteStride"), 4, "bufferViews[0].byteStride is 4, not from 12"),
    (("bufferViews", 0, "buffer"), 1, "bufferViews[0].buffer is not 0"),
    (("nodes", 0, "mesh"), 3, "nodes[0].mesh is 3, not an integer from 0 below 1"),
    (("nodes", 0, "children"), [0], "nodes[0].children[0] is node 0, which is reached twice"),
    (("nodes", 0, "translation"), [0, 0], "nodes[0].translation must be an array of 3 numbers"),
    (("nodes", 0, "matrix"), [float("nan")] * 16, "nodes[0].matrix[0] must be a finite number"),
    (("nodes", 0, "scale"), [1e300, 1e300, 1e300], "attributes.POSITION holds positions that "
                                                   "are not finite or lie beyond"),
    (("scene",), 4, "scene is 4, not an integer from 0 below 1"),
    (("scenes", 0, "nodes"), [9], "scenes[0].nodes[0] is 9"),
    ((*P, "material"), 0, "meshes[0].primitives[0].material is 0, not an integer from 0 below 0"),
    ((*P, "extras"), {"parts": [[0, 0, 5, 0]]}, "extras.parts[0] selects triangles 0 to 5 of "
                                                "the primitive's 1"),
    ((*P, "extras"), {"parts": [[0, "a", 1]]}, "extras.parts[0] must be an array [symbol"),
    ((*P, "extras"), {"symbols": "Wall"}, "extras.symbols must be an array, not a string"),
])
def test_malformed_members_are_load_errors_naming_their_json_path(tmp_path: Path, path, value,
                                                                  message):
    from facadeforge.exchange.errors import LoadError

    doc, blob = _triangle()
    (tmp_path / "t.glb").write_bytes(_glb(_edit(doc, path, value), blob))
    with pytest.raises(LoadError) as err:
        load(tmp_path / "t.glb")
    assert str(err.value).startswith(f"glTF file '{tmp_path / 't.glb'}': ")
    assert message in str(err.value) and str(err.value).endswith("export the file again")


def test_material_members_are_checked(tmp_path: Path):
    from facadeforge.exchange.errors import LoadError

    doc, blob = _triangle()
    doc["meshes"][0]["primitives"][0]["material"] = 0
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1],
                                                  "baseColorTexture": {"index": 2}}}]
    (tmp_path / "t.glb").write_bytes(_glb(doc, blob))
    with pytest.raises(LoadError, match=r"baseColorTexture.index is 2, not an integer from 0 "
                                        r"below 0"):
        load(tmp_path / "t.glb")
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0]}}]
    (tmp_path / "t.glb").write_bytes(_glb(doc, blob))
    with pytest.raises(LoadError, match=r"materials\[0\].pbrMetallicRoughness.baseColorFactor "
                                        r"must be an array of 4 numbers"):
        load(tmp_path / "t.glb")


def test_cli_render_reports_a_malformed_glb_in_one_line(tmp_path: Path, capsys):
    from facadeforge.cli import main

    doc, blob = _triangle()
    doc["accessors"][0]["count"] = 10**9
    (tmp_path / "h.glb").write_bytes(_glb(doc, blob))
    assert main(["render", str(tmp_path / "h.glb"), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("facadeforge: error: glTF file") and "accessors[0].count" in err
    assert "\n" not in err and not (tmp_path / "x.png").exists()
