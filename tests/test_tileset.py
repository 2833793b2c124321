"""3D Tiles 1.1 tilesets (facadeforge.city.tileset): the tree, its boxes and errors, the
checks, the globe transform, and a real glTF content file."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from facadeforge.city.tileset import (
    COARSE_ERROR,
    FANOUT,
    ContentTile,
    box_volume,
    enu_transform,
    tileset_dict,
    tileset_problems,
    write_tileset,
)


def tiles(n: int, with_files: Path | None = None) -> list[ContentTile]:
    out = []
    for k in range(n):
        lo, hi = (k * 30.0, 0.0, -20.0), (k * 30.0 + 20, 12.0 + k, -5.0)
        if with_files is not None:
            (with_files / f"{k:05d}.glb").write_bytes(b"glTF")
        out.append(ContentTile(f"{k:05d}.glb", lo, hi))
    return out


def test_one_level_root_with_content_children():
    doc = tileset_dict(tiles(3))
    assert doc["asset"]["version"] == "1.1"
    root = doc["root"]
    assert "content" not in root and root["refine"] == "ADD" and len(root["children"]) == 3
    assert doc["geometricError"] == root["geometricError"] > 0
    leaf = root["children"][1]
    assert leaf["content"] == {"uri": "00001.glb"} and leaf["geometricError"] == 0
    # y up (glTF) → z up (tiles): x 30..50, north = -z 5..20, up = y 0..13
    c, hx, hy, hz = leaf["boundingVolume"]["box"][:3], *np.reshape(
        leaf["boundingVolume"]["box"][3:], (3, 3))
    assert c == pytest.approx([40, 12.5, 6.5]) and hx[0] == pytest.approx(10, abs=1e-5)
    assert hy[1] == pytest.approx(7.5, abs=1e-5) and hz[2] == pytest.approx(6.5, abs=1e-5)


def test_many_tiles_make_levels_whose_errors_shrink(tmp_path):
    n = FANOUT * FANOUT + 3
    path = write_tileset(tmp_path / "tileset.json", tiles(n, tmp_path))
    assert tileset_problems(path) == []
    doc = json.loads(path.read_text())
    depth, node, errors = 0, doc["root"], []
    while "children" in node:
        errors.append(node["geometricError"])
        node, depth = node["children"][0], depth + 1
    assert depth == 3 and errors == sorted(errors, reverse=True) and node["geometricError"] == 0
    uris = []

    def walk(t):
        uris.extend([t["content"]["uri"]] if "content" in t else [])
        assert len(t.get("children", [])) <= FANOUT
        for ch in t.get("children", []):
            walk(ch)
    walk(doc["root"])
    assert uris == [f"{k:05d}.glb" for k in range(n)]
    assert not list(tmp_path.glob(".*.part"))


def test_parents_of_content_tiles_show_the_buildings_as_blocks(tmp_path):
    """With the tiles' building bounds, each parent of content tiles holds their blocks
    (``coarse_NNNNN.glb``, REPLACE, error COARSE_ERROR); so does the root, all of them (fewer
    than MAX_BLOCKS)."""
    n = FANOUT * 2 + 1
    ts = tiles(n, tmp_path)
    for t in ts:   # two buildings a tile, side by side inside its bounds
        lo, hi = np.asarray(t.lo), np.asarray(t.hi)
        mid = (lo + hi) / 2
        t.buildings = [(lo, [mid[0], hi[1], hi[2]]), ([mid[0], lo[1], lo[2]], hi)]
    path = write_tileset(tmp_path / "tileset.json", ts)
    assert tileset_problems(path) == []
    doc = json.loads(path.read_text())
    root = doc["root"]
    assert root["content"]["uri"] == "coarse_00003.glb" and root["refine"] == "REPLACE"
    assert root["geometricError"] == COARSE_ERROR
    parents = root["children"]
    assert [p["content"]["uri"] for p in parents] == [f"coarse_{k:05d}.glb" for k in range(3)]
    assert all(p["refine"] == "REPLACE" and p["geometricError"] == COARSE_ERROR
               for p in parents)
    assert doc["geometricError"] > COARSE_ERROR
    top = pygltflib.GLTF2().load(str(tmp_path / "coarse_00003.glb"))
    assert top.accessors[top.meshes[0].primitives[0].attributes.POSITION].count == 2 * n * 24
    blocks = pygltflib.GLTF2().load(str(tmp_path / "coarse_00002.glb"))
    pos = blocks.accessors[blocks.meshes[0].primitives[0].attributes.POSITION]
    assert pos.count == 2 * 24  # the last parent holds one tile: two blocks of 24 corners
    lo, hi = np.array(pos.min), np.array(pos.max)
    assert lo == pytest.approx(np.asarray(ts[-1].lo)) and hi == pytest.approx(np.asarray(ts[-1].hi))
    assert not list(tmp_path.glob(".*.part"))
    # without building bounds, no blocks: parents stay empty
    plain = tileset_dict(tiles(3))
    assert "content" not in plain["root"] and plain["root"]["refine"] == "ADD"


def test_offset_tiles_carry_a_translation_inside_the_parent(tmp_path):
    ts = tiles(2, tmp_path)
    ts[1].offset = (1000.0, -500.0, 0.0)
    path = write_tileset(tmp_path / "tileset.json", ts)
    assert tileset_problems(path) == []
    child = json.loads(path.read_text())["root"]["children"][1]
    assert child["transform"][12:15] == [1000.0, -500.0, 0.0]


def test_problems_are_found(tmp_path):
    path = write_tileset(tmp_path / "tileset.json", tiles(2, tmp_path))
    (tmp_path / "00001.glb").unlink()
    assert tileset_problems(path) == ["root.children[1]: content 00001.glb does not exist"]
    doc = json.loads(path.read_text())
    doc["asset"]["version"] = "2.0"
    doc["root"]["children"][0]["boundingVolume"]["box"][0] += 500
    doc["root"]["children"][0]["geometricError"] = 1e9
    doc["root"]["children"][1]["content"]["uri"] = "/etc/passwd"
    path.write_text(json.dumps(doc))
    problems = tileset_problems(path)
    assert "asset.version must be '1.0' or '1.1'" in problems
    assert "root.children[0]: bounding volume not inside its parent's" in problems
    assert any("above its parent's" in p for p in problems)
    assert "root.children[1]: content.uri must be a relative URI" in problems


def test_box_keeps_a_flat_tile_a_volume():
    box = box_volume([0, 0, 0], [10, 5, 0])
    assert box[11] > 0 and box[3] == pytest.approx(5, abs=1e-5)


def test_no_tiles_or_bad_bounds_are_refused():
    with pytest.raises(ValueError, match="at least one tile"):
        tileset_dict([])
    with pytest.raises(ValueError, match="not finite"):
        tileset_dict([ContentTile("a.glb", (0, 0, 0), (math.inf, 1, 1))])


def test_enu_transform_puts_the_origin_on_the_globe():
    # ETRS89 / UTM 32N, near Stuttgart
    m = np.array(enu_transform(513_000.0, 5_402_000.0, 250.0, 25832)).reshape(4, 4).T
    east, north, up, origin = m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3]
    assert 6.35e6 < np.linalg.norm(origin) < 6.40e6
    assert np.allclose(np.linalg.norm([east, north, up], axis=1), 1)
    assert abs(east @ north) < 1e-9 and abs(east @ up) < 1e-9
    assert np.degrees(np.arccos(up @ origin / np.linalg.norm(origin))) < 0.3  # ≈ radial
    with pytest.raises(ValueError, match="EPSG:999999"):
        enu_transform(0.0, 0.0, 0.0, 999999)


def test_batch_tileset_content_is_gltf(tmp_path):
    """A tile written by the batch machinery's exporter loads with pygltflib and lies in its
    tile's box (tiles axes)."""
    from facadeforge.engine import derive
    from facadeforge.exchange import export_glb

    models = derive("Lot --> extrude(8) comp(f) { side : Wall. | top : Roof. }\n",
                    lot_size="12x9", workers=1)
    export_glb(models, tmp_path / "00000.glb")
    s = models[0].stats()
    path = write_tileset(tmp_path / "tileset.json",
                         [ContentTile("00000.glb", s["bbox"][0], s["bbox"][1])])
    assert tileset_problems(path) == []
    glb = pygltflib.GLTF2().load(str(tmp_path / "00000.glb"))
    acc = glb.accessors[glb.meshes[0].primitives[0].attributes.POSITION]
    lo, hi = np.array(acc.min), np.array(acc.max)                  # glTF, y up
    box = json.loads(path.read_text())["root"]["children"][0]["boundingVolume"]["box"]
    c, h = np.array(box[:3]), np.array([box[3], box[7], box[11]])
    tiles_lo = np.array([lo[0], -hi[2], lo[1]])
    tiles_hi = np.array([hi[0], -lo[2], hi[1]])
    assert (tiles_lo >= c - h - 1e-6).all() and (tiles_hi <= c + h + 1e-6).all()


def test_higher_parents_show_the_largest_blocks_and_say_what_they_leave_out(tmp_path,
                                                                          monkeypatch):
    """Above the first parents a tile shows the MAX_BLOCKS largest blocks beneath it; its
    error is the diagonal of the largest block it leaves out (at least its children's)."""
    from facadeforge.city import tileset as ts_module

    monkeypatch.setattr(ts_module, "MAX_BLOCKS", 5)
    n = FANOUT + 1                  # two first-level parents under the root
    ts = tiles(n, tmp_path)
    for t in ts:
        t.buildings = [(t.lo, t.hi)]   # one building a tile: 20 x (12 + k) x 15 m
    path = write_tileset(tmp_path / "tileset.json", ts)
    assert tileset_problems(path) == []
    doc = json.loads(path.read_text())
    root = doc["root"]
    glb = pygltflib.GLTF2().load(str(tmp_path / root["content"]["uri"]))
    assert glb.accessors[glb.meshes[0].primitives[0].attributes.POSITION].count == 5 * 24
    # the tallest five shown (k = 4..8); the largest left out is k = 3: 20 x 15 x 15 m
    pos = glb.accessors[glb.meshes[0].primitives[0].attributes.POSITION]
    assert pos.min[0] == pytest.approx(4 * 30.0)
    assert root["geometricError"] == pytest.approx(np.linalg.norm([20, 15, 15]), abs=1e-3)
    assert all(c["geometricError"] == COARSE_ERROR for c in root["children"])
    assert doc["geometricError"] > root["geometricError"]
