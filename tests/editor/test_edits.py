"""facadeforge.editor.edits: the tree edits, cluster synchronisation, and bad edits refused
without a change."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from facadeforge.editor.edits import (
    MIN_PART_M,
    EditError,
    apply_edit,
    cluster_of,
    node_at,
    partition,
)
from facadeforge.model.scope import Scope
from facadeforge.model.shape import INSERT, Shape


def _rect(sym, x, y, w, h, **tags):
    return Shape(sym, Scope([x, y, 0], np.eye(3), [w, h, 0]), tags=dict(tags))


def _facade() -> Shape:
    """Two identical floors (cluster F1) over a ground floor; each upper floor has two tiles of
    cluster T1 whose middle region (a dual-x split) holds a window T1.1."""
    root = _rect("Facade", 0, 0, 10, 9, box_px=[0, 0, 100, 90])
    g = root.add(_rect("Floor", 0, 0, 10, 3, cluster="F0"))
    g.params = {"axis": "y", "index": 0}
    g.add(_rect("Region", 0, 0, 10, 3, cluster="W0")).label = "wall"
    for j in (1, 2):
        f = root.add(_rect("Floor", 0, 3 * j, 10, 3, cluster="F1"))
        f.params = {"axis": "y", "index": j}
        for t in range(2):
            tile = f.add(_rect("Tile", 5 * t, 3 * j, 5, 3, cluster="T1"))
            tile.params = {"axis": "x", "index": t}
            for r, (x, w, lab) in enumerate([(0, 1.5, "wall"), (1.5, 2, "window"),
                                             (3.5, 1.5, "wall")]):
                leaf = tile.add(_rect("Region", 5 * t + x, 3 * j, w, 3,
                                      cluster=f"T1.{r}", split="dual-x"))
                leaf.params = {"axis": "x", "index": r, "split": "dual-x"}
                leaf.label = lab
                if lab == "window":
                    leaf.tags["depth"] = -0.25
    bal = root.children[1].add(_rect("Balcony", 1, 3.2, 3, 1, cluster="B"))
    bal.operator, bal.label = INSERT, "balcony"
    for c in root.children:
        c.operator = "split"
    return root


def _sizes(node, k):
    kids, _ = partition(node)
    return [round(float(c.scope.size[k]), 6) for c in kids]


def _tiles_exactly(node, k=None):
    """Every partition covers its parent without gaps or overlaps, on both axes."""
    for n in node.walk():
        kids, axis = partition(n)
        if not kids:
            continue
        a = 0 if axis == "x" else 1
        pos = float(n.scope.origin[a])
        for c in kids:
            assert float(c.scope.origin[a]) == pytest.approx(pos, abs=1e-9)
            pos += float(c.scope.size[a])
            b = 1 - a
            assert float(c.scope.origin[b]) == pytest.approx(float(n.scope.origin[b]), abs=1e-9)
            assert float(c.scope.size[b]) == pytest.approx(float(n.scope.size[b]), abs=1e-9)
        assert pos == pytest.approx(float(n.scope.origin[a] + n.scope.size[a]), abs=1e-9)


def test_move_split_moves_the_boundary_and_lays_the_subtrees_out_again():
    t = _facade()
    done = apply_edit(t, {"op": "move_split", "path": [], "index": 1, "delta": 0.3})
    assert done["applied_delta"] == 0.3 and done["axis"] == "y"
    assert _sizes(t, 1) == [3.3, 2.7, 3.0]
    floor = t.children[1]
    assert float(floor.scope.origin[1]) == pytest.approx(3.3)
    # the tiles follow the floor in y; the balcony keeps its height above the floor's bottom
    assert float(floor.children[0].scope.size[1]) == pytest.approx(2.7)
    bal = floor.children[-1]
    assert float(bal.scope.origin[1]) == pytest.approx(3.5)
    _tiles_exactly(t)


def test_move_split_applies_to_the_whole_cluster():
    t = _facade()
    done = apply_edit(t, {"op": "move_split", "path": [1, 0], "index": 1, "delta": 0.5})
    assert done["shapes"] == 4          # every T1 tile of both F1 floors
    tiles = cluster_of(t, node_at(t, [1, 0]))
    assert len(tiles) == 4
    for tile in tiles:
        assert _sizes(tile, 0) == [2.0, 1.5, 1.5]
    _tiles_exactly(t)


def test_move_split_in_a_tile_moves_every_member_and_keeps_the_window_width():
    t = _facade()
    apply_edit(t, {"op": "move_split", "path": [1, 0], "index": 2, "delta": -0.5})
    for tile in cluster_of(t, node_at(t, [1, 0])):
        assert _sizes(tile, 0) == [1.5, 1.5, 2.0]
    _tiles_exactly(t)


def test_move_split_is_clamped_so_no_part_vanishes():
    t = _facade()
    done = apply_edit(t, {"op": "move_split", "path": [], "index": 1, "delta": 50})
    assert done["applied_delta"] == pytest.approx(3 - MIN_PART_M)
    assert min(_sizes(t, 1)) >= MIN_PART_M - 1e-9
    _tiles_exactly(t)


def test_resizing_a_floor_makes_the_outer_parts_of_a_dual_split_take_the_change():
    t = _facade()
    apply_edit(t, {"op": "move_split", "path": [1], "index": 1, "delta": 1.0})   # tiles 6 | 4
    tile = node_at(t, [1, 0])
    s = _sizes(tile, 0)
    assert s[1] == pytest.approx(2.0)          # the window keeps its width
    assert s[0] + s[2] == pytest.approx(4.0)
    _tiles_exactly(t)


def test_set_depth_sets_the_leaf_cluster():
    t = _facade()
    done = apply_edit(t, {"op": "set_depth", "path": [1, 0, 1], "depth": -0.6})
    assert done == {"shapes": 4, "before": -0.25}
    assert sorted({s.tags.get("depth") for s in t.leaves() if s.label == "window"}) == [-0.6]


@pytest.mark.parametrize("edit, message", [
    ({"op": "move_split", "path": [], "index": 0, "delta": 1}, "boundary 1..2"),
    ({"op": "move_split", "path": [], "index": 1, "delta": float("inf")}, "number of metres"),
    ({"op": "move_split", "path": [], "index": 1, "delta": 1e6}, "beyond"),
    ({"op": "move_split", "path": [], "index": 1, "delta": 10 ** 400}, "number of metres"),
    ({"op": "move_split", "path": [0, 0], "index": 1, "delta": 1}, "no split line"),
    ({"op": "set_depth", "path": [1], "depth": -0.3}, "not an element"),
    ({"op": "set_depth", "path": [1, 0, 1], "depth": "deep"}, "number of metres"),
    ({"op": "set_depth", "path": [1, 0, 1], "depth": 99}, "beyond"),
    ({"op": "set_depth", "path": "1/0", "depth": 1}, "list of child indices"),
    ({"op": "set_depth", "path": [7], "depth": 1}, "no child 7"),
    ({"op": "set_label", "path": [1, 0, 1], "label": "unicorn"}, "must be one of"),
    ({"op": "set_element", "path": [1, 0, 1], "element": "../../etc/passwd"}, "not in the element"),
    ({"op": "set_split", "path": [1, 0], "split": "top"}, "must be one of dual-x"),
    ({"op": "remove", "path": [0, 0]}, "only part"),
    ({"op": "add", "path": []}, "facade itself"),
    ({"op": "exec", "code": "import os"}, "unknown"),
    (["not", "an", "object"], "an edit is an object"),
])
def test_bad_edits_are_refused_and_change_nothing(edit, message):
    t = _facade()
    before = t.to_dict()
    with pytest.raises(EditError, match=message):
        apply_edit(t, edit)
    assert t.to_dict() == before


def test_set_element_and_label_change_the_cluster():
    from facadeforge.elements.library import element_library

    door = next(s for s in element_library() if s.kind == "door")
    t = _facade()
    done = apply_edit(t, {"op": "set_element", "path": [1, 0, 1], "element": door.name})
    assert done["shapes"] == 4 and done["label"] == "door"
    leaves = [s for s in t.leaves() if s.tags.get("cluster") == "T1.1"]
    assert {s.tags["asset"] for s in leaves} == {f"assets/{door.name}.obj"}
    assert {s.label for s in leaves} == {"door"}
    apply_edit(t, {"op": "set_label", "path": [1, 0, 1], "label": "wall"})
    assert all("asset" not in s.tags for s in leaves)


def test_reverse_split_mirrors_the_parts_of_every_member():
    t = _facade()
    apply_edit(t, {"op": "move_split", "path": [1, 0], "index": 1, "delta": 1.0})
    assert _sizes(node_at(t, [1, 0]), 0) == [2.5, 1.0, 1.5]
    apply_edit(t, {"op": "reverse_split", "path": [1, 0]})
    for tile in cluster_of(t, node_at(t, [1, 0])):
        kids, _ = partition(tile)
        assert _sizes(tile, 0) == [1.5, 1.0, 2.5]
        assert [k.label for k in kids] == ["wall", "window", "wall"]
        assert [c.params["index"] for c in kids] == [0, 1, 2]
    _tiles_exactly(t)


def test_add_and_remove_a_column_in_every_floor_of_the_cluster():
    t = _facade()
    done = apply_edit(t, {"op": "add", "path": [1, 1]})
    assert done == {"shapes": 2, "parts": 3}
    for f in (t.children[1], t.children[2]):
        assert _sizes(f, 0) == pytest.approx([10 / 3] * 3)
        assert [c.params["index"] for c in partition(f)[0]] == [0, 1, 2]
    _tiles_exactly(t)
    twin = node_at(t, [1, 2])
    assert twin.tags["cluster"] == "T1" and twin.id != node_at(t, [1, 1]).id
    apply_edit(t, {"op": "remove", "path": [1, 0]})
    assert _sizes(t.children[1], 0) == pytest.approx([5, 5])
    _tiles_exactly(t)
    assert t.children[1].children[-1].operator == INSERT   # the balcony stays


def test_add_a_floor_shrinks_the_others_in_proportion():
    t = _facade()
    apply_edit(t, {"op": "add", "path": [2]})
    assert _sizes(t, 1) == pytest.approx([9 / 4] * 4)
    _tiles_exactly(t)


def test_box_px_follow_the_scopes():
    t = _facade()
    apply_edit(t, {"op": "move_split", "path": [], "index": 1, "delta": 1.0})
    assert t.tags["box_px"] == [0, 0, 100, 90]
    t2 = copy.deepcopy(t)
    for s in t2.walk():
        s.tags["box_px"] = [0, 0, 0, 0]
    t2.tags["box_px"] = [0, 0, 100, 90]
    from facadeforge.editor.edits import update_boxes

    update_boxes(t2)
    floor = t2.children[1]
    assert floor.tags["box_px"] == [0, 30, 100, 50]   # y 4..6 m of 9 m: 30..50 px from the top
