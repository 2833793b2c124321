"""The shape tree of an analysed facade (imaging.shape_tree) with balconies inserted in front of
its partition: rasterising, JSON, and the extracted rules deriving it back (Müller 2007 §5)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facadeforge.engine import derive_facade
from facadeforge.exchange.raster import LABEL_INDEX, label_map
from facadeforge.grammar.extract import extract_rules
from facadeforge.imaging.detect import detect_elements, detect_protruding
from facadeforge.imaging.element_layout import element_layout, refine_clusters
from facadeforge.imaging.refine import Region
from facadeforge.imaging.shape_tree import PixelFrame, build_shape_tree
from facadeforge.model.shape import INSERT, Shape

DEPTHS = {"balcony": 0.9}          # windows flat: their derived leaves keep the photo's scope
BALCONY, WINDOW = LABEL_INDEX["balcony"], LABEL_INDEX["window"]


def _leaf_info(region, cluster: str) -> dict:
    if region is None or region.role != "element":
        return {"label": "wall"}
    return {"label": region.label, "depth": DEPTHS.get(region.label)}


@pytest.fixture(scope="module")
def balcony_tree(balcony_scene):
    """The tree of ``balcony_scene`` (conftest): a balcony band in front of the upper window
    row, a balcony in front of each middle window of the lower row."""
    prob, classes = balcony_scene.prob, balcony_scene.classes
    windows = detect_elements(prob, classes, behind=("balcony",))
    fronts = detect_protruding(prob, classes)
    h, w = prob.shape[:2]
    lay = element_layout(windows, np.full((h, w), 0.5), np.zeros((h, w)), 20.0, fronts=fronts)
    floor_c, tile_c = refine_clusters(lay.floors, lay.tiles, lay.regions, [0] * len(lay.floors),
                                      [[0] * len(r) for r in lay.tiles], tol=2.0,
                                      fronts=lay.fronts)
    tree = build_shape_tree(PixelFrame(w, h, (20.0, 20.0)), lay.floors, lay.tiles, floor_c,
                            tile_c, regions=lay.regions, leaf_info=_leaf_info,
                            fronts=lay.fronts)
    return tree, windows, balcony_scene


def _inserted(tree: Shape) -> list[Shape]:
    return [s for s in tree.walk() if s.operator == INSERT]


def test_balconies_hang_outside_the_partition(balcony_tree):
    tree, windows, sc = balcony_tree
    ins = _inserted(tree)
    assert sorted(tuple(s.tags["box_px"]) for s in ins) == sorted(sc.balconies)
    assert {s.label for s in ins} == {"balcony"} and all(not s.children for s in ins)
    hosts = {tuple(s.tags["box_px"]): s.parent.symbol for s in ins}
    assert hosts == {sc.band: "Floor", sc.per_window[0]: "Tile", sc.per_window[1]: "Tile"}
    for s in ins:                       # after the host's split children, which still tile it
        kids = s.parent.children
        split = [c for c in kids if c.operator != INSERT]
        assert kids.index(s) >= len(split) and all(c.operator == "split" for c in split)
        assert s.tags["depth"] == 0.9 and s.tags["cluster"].startswith(
            s.parent.tags["cluster"] + ".p")
    # the windows behind the railings stay whole
    boxes = sorted(tuple(s.tags["box_px"]) for s in tree.leaves() if s.label == "window")
    assert boxes == sorted(e.box for e in windows)


def test_balconies_are_painted_over_the_windows_behind_them(balcony_tree):
    tree, windows, sc = balcony_tree
    labels = label_map(tree, size=sc.prob.shape[:2])
    for x0, y0, x1, y1 in sc.balconies:
        assert (labels[y0:y1, x0:x1] == BALCONY).all()
    for e in windows:                                  # above the railing: the window
        x0, y0, x1, _ = e.box
        assert (labels[y0:y0 + 20, x0:x1] == WINDOW).all()
    assert (labels == BALCONY).sum() == sum((x1 - x0) * (y1 - y0)
                                            for x0, y0, x1, y1 in sc.balconies)


def test_inserted_shapes_are_painted_over_shapes_walked_after_them():
    """A balcony hung on the lower floor that reaches up into the floor above (walked after
    it: floors go bottom first) is still drawn in front."""
    balcony = Region(box=(10, 30, 70, 60), role="element", label="balcony")
    window = Region(box=(20, 45, 60, 80), role="element", label="window")
    lower = Region(box=(0, 40, 80, 80), split="top",
                   children=[Region(box=(0, 40, 80, 45), role="wall"), window])
    tree = build_shape_tree(PixelFrame(80, 80, (10.0, 10.0)), [(0, 40), (40, 80)],
                            [[(0, 80)], [(0, 80)]], [0, 1], [[0], [1]],
                            regions=[[None], [lower]], leaf_info=_leaf_info,
                            fronts=[[], [(0, balcony)]])
    (ins,) = _inserted(tree)
    assert ins.parent.symbol == "Tile"
    labels = label_map(tree, size=(80, 80))
    assert (labels[30:60, 10:70] == BALCONY).all()
    assert (labels[60:80, 20:60] == WINDOW).all() and (labels[:30] == LABEL_INDEX["wall"]).all()
    assert tree.painting_order()[-1] is ins
    # a tile that is a leaf cannot hold it (it would lose its label): the floor does
    tree = build_shape_tree(PixelFrame(80, 80, (10.0, 10.0)), [(0, 40), (40, 80)],
                            [[(0, 80)], [(0, 80)]], [0, 1], [[0], [1]],
                            fronts=[[], [(0, balcony)]], leaf_info=_leaf_info)
    (ins,) = _inserted(tree)
    assert ins.parent.symbol == "Floor" and len(list(tree.leaves())) == 3


def test_tree_json_round_trips_with_balconies(balcony_tree):
    tree, _, sc = balcony_tree
    back = Shape.from_dict(json.loads(json.dumps(tree.to_dict())))
    assert back.dump() == tree.dump() and "<insert index=0>" in back.dump()
    size = sc.prob.shape[:2]
    assert (label_map(back, size=size) == label_map(tree, size=size)).all()


def test_rules_derive_the_balconies_back(balcony_tree):
    """§5: the extracted rules rebuild every leaf — balconies included, in front of the facade
    plane — within 1 % of the facade size."""
    tree, _, _ = balcony_tree
    rules = extract_rules(tree, depths=DEPTHS)
    assert rules.count("[ t('") == 2                  # the band's floor and the tiles' rule
    w, h = tree.scope.size[:2]
    model = derive_facade(rules, w, h)
    assert model.warnings == []
    tol = 0.01 * max(w, h)
    want = [s for s in tree.leaves() if s.label != "wall"]
    got = [s for s in model.root.leaves() if s.label != "wall"]
    assert len(got) == len(want) and sum(s.label == "balcony" for s in got) == 3
    for s in want:
        assert any(g.label == s.label and np.abs(g.scope.origin[:2] - s.scope.origin[:2]).max()
                   <= tol and np.abs(g.scope.size[:2] - s.scope.size[:2]).max() <= tol
                   for g in got), (s.label, s.scope)
    front = [p for p in model.parts if p.label == "balcony"]
    assert front and max(p.mesh.vertices[:, 2].max() for p in front) == pytest.approx(0.9)
