"""facadeforge.editor.scene: every file we write becomes a layer in one y-up frame."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facadeforge.editor import scene as scene_mod
from facadeforge.editor.scene import TO_CGA, load_scene
from facadeforge.errors import InputError
from facadeforge.points.cloud import PointCloud
from facadeforge.points.io import write_ply


def _cloud(path, n=500, offset=(0.0, 0.0, 0.0), **attrs):
    rng = np.random.default_rng(1)
    xyz = rng.uniform(0, 10, (n, 3)) + np.asarray(offset)
    write_ply(PointCloud(xyz=xyz, **attrs), path)
    return xyz


def _points(layer):
    n = int.from_bytes(layer.payload[:4], "little")
    pos = np.frombuffer(layer.payload, np.float32, n * 3, 4).reshape(n, 3)
    rgb = np.frombuffer(layer.payload, np.uint8, n * 3, 4 + 12 * n).reshape(n, 3)
    return pos, rgb


def test_a_cloud_is_drawn_y_up_around_its_centre(tmp_path):
    xyz = _cloud(tmp_path / "c.ply", offset=(500000.0, 5400000.0, 30.0),
                 rgb=np.full((500, 3), 200, np.uint8))
    sc = load_scene([tmp_path / "c.ply"])
    (la,) = sc.layers
    pos, rgb = _points(la)
    centre = (xyz.min(0) + xyz.max(0)) / 2
    assert np.allclose(pos, (xyz - centre) @ TO_CGA.T, atol=1e-3)
    assert (rgb == 200).all() and la.info["colour"] == "rgb"
    assert sc.origin == pytest.approx(centre.tolist())


def test_a_large_cloud_is_thinned_and_says_so(tmp_path, monkeypatch):
    _cloud(tmp_path / "c.ply", n=1000)
    monkeypatch.setattr(scene_mod, "MAX_VIEW_POINTS", 100)
    (la,) = load_scene([tmp_path / "c.ply"]).layers
    assert la.info == {"points": 1000, "shown": 100, "colour": "height"}
    assert len(_points(la)[0]) == 100


def test_a_points_model_lies_over_its_cloud(tmp_path):
    out = tmp_path / "points-out"
    out.mkdir()
    origin = [100.0, 200.0, 10.0]
    (out / "report.json").write_text(json.dumps({"origin": origin}))
    (out / "planes.json").write_text("{}")
    (out / "model.glb").write_bytes(b"glTF")
    xyz = _cloud(tmp_path / "scan.ply", offset=(95, 195, 8))
    sc = load_scene([out / "model.glb", tmp_path / "scan.ply"])
    assert sc.origin == origin
    model, cloud = sc.layers
    assert model.offset == [0.0, 0.0, 0.0]
    pos, _ = _points(cloud)
    assert np.allclose(pos, (xyz - origin) @ TO_CGA.T, atol=1e-3)


def test_cityjson_and_cityjsonseq_become_gltf(reconstructed, tmp_path):
    from facadeforge.exchange import load
    from facadeforge.exchange.cityjson import export_cityjsonseq

    models = load(reconstructed / "model.glb")
    export_cityjsonseq(models, tmp_path / "m.city.jsonl")
    sc = load_scene([reconstructed / "model.city.json", tmp_path / "m.city.jsonl"])
    for la in sc.layers:
        assert la.kind == "gltf" and la.payload[:4] == b"glTF" and la.info["buildings"] >= 1


def test_a_tileset_lists_its_contents_with_y_up_matrices(tmp_path):
    from facadeforge.city.tileset import ContentTile, write_tileset

    (tmp_path / "a.glb").write_bytes(b"glTF")
    (tmp_path / "b.glb").write_bytes(b"glTF")
    write_tileset(tmp_path / "tileset.json", [
        ContentTile("a.glb", [0, 0, 0], [10, 10, 10]),
        ContentTile("b.glb", [0, 0, 0], [10, 10, 10], offset=(30.0, 40.0, 5.0))])
    (la,) = load_scene([tmp_path / "tileset.json"]).layers
    assert la.kind == "tiles" and la.info["tiles"] == 2
    by_uri = {c["uri"]: np.asarray(c["matrix"]).reshape(4, 4).T for c in la.info["contents"]}
    assert np.allclose(by_uri["a.glb"], np.eye(4))
    # a tile offset (x 30, y 40, z-up 5) is drawn at x 30, y-up 5, z -40
    assert np.allclose(by_uri["b.glb"][:3, 3], [30, 5, -40])
    assert np.allclose(by_uri["b.glb"][:3, :3], np.eye(3))


def test_a_tileset_is_drawn_at_its_finest_level(tmp_path):
    """The coarse blocks of the parents (REPLACE tiles with children) are not drawn over the
    detailed tiles that replace them."""
    from facadeforge.city.tileset import ContentTile, write_tileset

    tiles = []
    for k in range(3):
        (tmp_path / f"{k}.glb").write_bytes(b"glTF")
        tiles.append(ContentTile(f"{k}.glb", [k * 20, 0, 0], [k * 20 + 10, 10, 10],
                                 buildings=[([k * 20, 0, 0], [k * 20 + 10, 10, 10])]))
    write_tileset(tmp_path / "tileset.json", tiles)
    doc = json.loads((tmp_path / "tileset.json").read_text())
    assert doc["root"]["content"]["uri"].startswith("coarse_")
    (la,) = load_scene([tmp_path / "tileset.json"]).layers
    assert sorted(c["uri"] for c in la.info["contents"]) == ["0.glb", "1.glb", "2.glb"]


@pytest.mark.parametrize("name, message", [
    ("missing.glb", "is not a file"),
    ("notes.txt.bak", "is not a file the viewer shows"),
])
def test_bad_files_are_refused(tmp_path, name, message):
    if name != "missing.glb":
        (tmp_path / name).write_text("x")
    with pytest.raises(InputError, match=message):
        load_scene([tmp_path / name])


def test_a_json_that_is_no_tileset_is_refused(tmp_path):
    (tmp_path / "tileset.json").write_text('{"asset": {}}')
    with pytest.raises(InputError, match="not a 3D Tiles tileset"):
        load_scene([tmp_path / "tileset.json"])


@pytest.mark.parametrize("up", [0, 1, 2])
def test_clouds_of_any_up_axis_are_rotated_not_mirrored(up):
    from facadeforge.editor.scene import view_axes

    m = view_axes(up)
    assert np.isclose(np.linalg.det(m), 1.0)
    assert np.allclose(m @ np.eye(3)[up], [0, 1, 0])     # the cloud's up is the scene's y
