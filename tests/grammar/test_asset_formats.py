"""Inserting assets in the formats CityEngine's ``i()`` takes besides OBJ: glTF (.glb/.gltf,
read with pygltflib) and FBX, COLLADA… (read with assimp)."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.exchange import export
from facadeforge.geometry.asset_formats import load_assimp, load_gltf

DATA = Path(__file__).resolve().parents[1] / "data" / "assets"
RED = (0.8, 0.1, 0.1)


def insert(tmp_path, name, scope="s(4, 6, 8)"):
    rules = load_rules(f'Lot --> {scope} i("{name}") X.', assets=tmp_path)
    return derive(rules, None, lot_size="10x10")[0]


@pytest.mark.parametrize("name", ["box.dae", "box.fbx"])
def test_assimp_formats_read_the_box(name):
    a = load_assimp(DATA / name)
    assert np.allclose(a.mesh.bounds(), [[0, 0, -3], [1, 2, 0]])
    assert a.mesh.is_closed() and a.mesh.volume() == pytest.approx(6)
    assert a.material.name == "red" and a.material.color == pytest.approx(RED)


@pytest.mark.parametrize("name", ["box.dae", "box.fbx"])
def test_inserted_fbx_and_dae_fill_the_scope(tmp_path, name):
    shutil.copy(DATA / name, tmp_path / name)
    m = insert(tmp_path, name)
    assert not m.warnings
    (part,) = m.parts
    assert np.allclose(part.mesh.bounds(), [[0, 0, 0], [4, 6, 8]])
    assert part.material.color == pytest.approx(RED)


def _textured_glb(folder: Path) -> Path:
    from PIL import Image

    Image.new("RGB", (4, 4), (0, 200, 0)).save(folder / "green.png")
    src = load_rules('Lot --> extrude(2) setupProjection(0, scope.xy, 1, 1) projectUV(0) '
                     'texture("green.png") X.', assets=folder)
    model = derive(src, None, lot_size="1x3")[0]
    export(model, folder / "made.glb")
    (folder / "green.png").unlink()  # the texture now lives only inside the .glb
    return folder / "made.glb"


def test_glb_asset_with_its_embedded_texture(tmp_path):
    path = _textured_glb(tmp_path)
    a = load_gltf(path)
    assert np.allclose(a.mesh.bounds(), [[0, 0, 0], [1, 2, 3]])
    assert a.material.texture is not None and Path(a.material.texture).is_file()
    m = insert(tmp_path, "made.glb")
    assert not m.warnings
    assert np.allclose(m.stats()["bbox"], [[0, 0, 0], [4, 6, 8]])
    assert {Path(p.material.texture).read_bytes() for p in m.parts} \
        == {Path(a.material.texture).read_bytes()}


def test_gltf_with_a_buffer_outside_its_folder_is_refused(tmp_path):
    (tmp_path / "assets").mkdir()
    doc = {"asset": {"version": "2.0"}, "buffers": [{"uri": "../secret.bin", "byteLength": 4}]}
    (tmp_path / "assets" / "bad.gltf").write_text(json.dumps(doc))
    (tmp_path / "secret.bin").write_bytes(b"\0" * 4)
    m = insert(tmp_path / "assets", "bad.gltf")
    assert any("buffer '../secret.bin' lies outside the asset's folder" in w for w in m.warnings)


@pytest.mark.parametrize("name, content, message", [
    ("broken.fbx", b"; FBX 7.4.0 project file\nObjects: { Geometry", "not a readable FBX asset"),
    ("broken.glb", b"glTF not really", "not a readable glTF asset"),
    ("model.blend", b"BLENDER", ".blend cannot be inserted; use .obj, .glb"),
])
def test_unreadable_assets_are_warnings(tmp_path, name, content, message):
    (tmp_path / name).write_bytes(content)
    m = insert(tmp_path, name)
    assert any(message in w for w in m.warnings), m.warnings
    assert m.parts[0].mesh.n_faces == 1  # the lot, left as it was


def _gltf(folder: Path, doc: dict, name: str = "x.gltf") -> str:
    (folder / name).write_text(json.dumps({"asset": {"version": "2.0"}, **doc}))
    return name


def test_gltf_nodes_reached_twice_are_refused(tmp_path):
    # node i has node i+1 twice as child: 2^40 visits if nothing stopped it
    nodes = [{"children": [i + 1, i + 1]} for i in range(40)] + [{}]
    name = _gltf(tmp_path, {"scene": 0, "scenes": [{"nodes": [0]}], "nodes": nodes})
    m = insert(tmp_path, name)
    assert any("is reached twice" in w for w in m.warnings), m.warnings


def test_gltf_accessor_claiming_more_than_its_data_is_refused(tmp_path):
    doc = {"scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
           "accessors": [{"componentType": 5126, "count": 50_000_000, "type": "VEC3"}]}
    m = insert(tmp_path, _gltf(tmp_path, doc))
    assert any("has no data for its 50000000 elements" in w for w in m.warnings), m.warnings


@pytest.mark.parametrize("ops, bbox", [
    # the box is x 0..1, y 0..2, z -3..0 in its file; the scope starts at (1, 0, -2), 2 x 3 x 4
    ('i("box.dae")', [[1, 0, -2], [3, 3, 2]]),
    ('i("box.dae", zUp)', [[1, 0, -2], [3, 3, 2]]),
    ('i("box.dae", yUp, keepSizeAndPosition)', [[1, 0, -5], [2, 2, -2]]),
    ('i("box.dae", yUp, keepSizeAlignPosition)', [[1.5, 0, -1.5], [2.5, 2, 1.5]]),
    ('i("box.dae", yUp, alignSizeAndPosition, noCleanup)', [[1, 0, -2], [3, 3, 2]]),
    ('s(0, 0, 0) i("box.dae")', [[1, 0, -5], [2, 2, -2]]),
    # two zero sizes: uniform scale by the third, the scope moved by the scaled offset
    ('s(0, 6, 0) i("box.dae")', [[1, 0, -11], [4, 6, -2]]),
])
def test_insert_modes_and_zero_sized_scopes(tmp_path, ops, bbox):
    shutil.copy(DATA / "box.dae", tmp_path / "box.dae")
    m = derive(load_rules(f"Lot --> t(1, 0, -2) s(2, 3, 4) {ops} X.", assets=tmp_path), None,
               lot_size="6x6")[0]
    assert not m.warnings
    assert np.allclose(m.stats()["bbox"], bbox)


def test_z_up_assets_stand_up(tmp_path):
    shutil.copy(DATA / "box.dae", tmp_path / "box.dae")
    m = derive(load_rules('Lot --> s(0, 0, 0) i("box.dae", zUp) X.', assets=tmp_path), None,
               lot_size="6x6")[0]
    # (x, y, z) -> (x, z, -y): the file's z -3..0 is now y -3..0, its y 0..2 now z -2..0,
    # kept in place and size
    assert np.allclose(m.stats()["bbox"], [[0, -3, -2], [1, 0, 0]])


@pytest.mark.parametrize("content, message", [
    ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ("[1, 2]", "its JSON is not an object"),
])
def test_hostile_gltf_json_is_a_warning(tmp_path, content, message):
    # the .gltf JSON is read by facadeforge.jsonfile before pygltflib sees it
    (tmp_path / "x.gltf").write_text(content)
    m = insert(tmp_path, "x.gltf")
    assert any(message in w for w in m.warnings), m.warnings
