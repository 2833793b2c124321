"""Element boxes from class probabilities (imaging.detect) and the layout around them
(imaging.element_layout)."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge import InputError
from facadeforge.imaging.detect import (
    Element,
    detect_elements,
    detect_protruding,
    row_split,
    valley_split,
    xy_cut,
)
from facadeforge.imaging.element_layout import element_layout, element_region, refine_clusters
from facadeforge.imaging.refine import SPLIT_TYPES, leaves

CLASSES = ("background", "wall", "window", "door", "balcony", "shop")


def _prob(h: int, w: int, boxes: dict[str, list], p: float = 0.9) -> np.ndarray:
    """Probabilities: wall everywhere, ``p`` of the given class inside each box."""
    prob = np.full((h, w, len(CLASSES)), (1 - 0.9) / (len(CLASSES) - 1), np.float32)
    prob[:, :, 1] = 0.9
    for label, bs in boxes.items():
        c = CLASSES.index(label)
        for x0, y0, x1, y1, *q in bs:
            v = q[0] if q else p
            prob[y0:y1, x0:x1] = (1 - v) / (len(CLASSES) - 1)
            prob[y0:y1, x0:x1, c] = v
    return prob


def test_xy_cut_separates_windows_joined_by_a_thin_bridge():
    m = np.zeros((60, 100), bool)
    m[10:40, 10:30] = True
    m[10:40, 50:70] = True
    m[24:26, 30:50] = True                     # a 2-px bridge: one connected component
    assert xy_cut(m, tol=0.2) == [(10, 10, 30, 40), (50, 10, 70, 40)]
    # rows first: two window rows, each tightened to its mask
    m2 = np.zeros((100, 40), bool)
    m2[5:30, 5:15] = m2[60:90, 20:35] = True
    assert xy_cut(m2) == [(5, 5, 15, 30), (20, 60, 35, 90)]
    assert xy_cut(np.zeros((10, 10), bool)) == []


def test_valley_split_cuts_at_a_faint_pier():
    prob = np.zeros((50, 90), np.float32)
    prob[10:40, 10:40] = 0.9
    prob[10:40, 50:80] = 0.9
    prob[10:40, 40:50] = 0.45                  # the pier the classifier half sees
    mask = prob > 0.4                          # argmax says window across the pier
    (box,) = xy_cut(mask)
    assert box == (10, 10, 80, 40)
    parts = valley_split(prob, mask, box, dip=0.7)
    assert len(parts) == 2
    (a, b) = parts
    assert a[2] <= b[0] and 40 <= a[2] <= 50 and a[0] == 10 and b[2] == 80
    # no valley below the threshold: left whole
    assert valley_split(prob, mask, box, dip=0.4) == [box]


def test_row_split_cuts_a_box_twice_as_wide_as_its_row():
    """Four 20-px windows in a row with 20-px piers; the last two merged: step 5 cuts the
    merged box at the pier."""
    prob = np.zeros((60, 200), np.float32)
    for x in (10, 50, 90, 130):
        prob[20:50, x:x + 20] = 0.9
    prob[20:50, 110:130] = 0.4
    els = [Element("window", (10, 20, 30, 50), 0.9), Element("window", (50, 20, 70, 50), 0.9),
           Element("window", (90, 20, 150, 50), 0.8)]
    out = row_split(els, prob)
    assert [e.box for e in out] == [(10, 20, 30, 50), (50, 20, 70, 50), (90, 20, 110, 50),
                                    (130, 20, 150, 50)]
    # three windows merged between two others: cut into three (the row's gaps count the
    # merged box's own neighbours)
    flanked = np.zeros((60, 200), np.float32)
    for x in (10, 50, 90, 130, 170):
        flanked[20:50, x:x + 20] = 0.9
    flanked[20:50, 70:90] = flanked[20:50, 110:130] = 0.4
    row = [Element("window", (10, 20, 30, 50), 0.9), Element("window", (50, 20, 150, 50), 0.8),
           Element("window", (170, 20, 190, 50), 0.9)]
    assert [e.box for e in row_split(row, flanked)] == [
        (10, 20, 30, 50), (50, 20, 70, 50), (90, 20, 110, 50), (130, 20, 150, 50),
        (170, 20, 190, 50)]
    # a wide window alone in its row, or in a row of wide windows, stays whole
    assert row_split(els[2:], prob) == els[2:]
    wide = [Element("window", (10 + 60 * k, 20, 60 + 60 * k, 50), 0.9) for k in range(3)]
    assert row_split(wide, prob) == wide
    # and in detect_elements it is step 5
    merged = _prob(60, 200, {"window": [(10, 20, 30, 50), (50, 20, 70, 50), (90, 20, 150, 50)]})
    merged[20:50, 110:130, CLASSES.index("window")] = 0.65   # too shallow for step 2 (dip 0.7)
    four = [e.box for e in detect_elements(merged, CLASSES) if e.label == "window"]
    three = [e.box for e in detect_elements(merged, CLASSES, row_ratio=np.inf)
             if e.label == "window"]
    assert len(three) == 3 and len(four) == 4


def test_detect_elements_drops_fragments_and_weak_boxes():
    windows = [(10 + 40 * k, 20, 35 + 40 * k, 60) for k in range(4)]
    prob = _prob(200, 200, {"window": [*windows,
                                       (180, 150, 184, 154),           # a fragment
                                       (10, 120, 40, 160, 0.42)],      # weak evidence
                            "door": [(60, 130, 90, 195)]})
    els = detect_elements(prob, CLASSES)
    assert [e.box for e in els if e.label == "window"] == windows
    assert [e.box for e in els if e.label == "door"] == [(60, 130, 90, 195)]
    assert all(0.85 < e.score <= 0.9 + 1e-6 for e in els)
    # with the weak one kept (min_score 0.4), it is found too
    weak = detect_elements(prob, CLASSES, min_score=0.4)
    assert (10, 120, 40, 160) in [e.box for e in weak]
    # labels missing from the classifier are skipped; wrong channel counts are refused
    assert detect_elements(prob[:, :, :3] / prob[:, :, :3].sum(2, keepdims=True),
                           CLASSES[:3])[0].label == "window"
    with pytest.raises(InputError, match="channel per class"):
        detect_elements(prob, CLASSES[:4])


def test_overlapping_boxes_of_two_classes_keep_the_stronger():
    # the shop is painted over the window's lower right corner: the window's mask loses the
    # corner but its box still overlaps the shop's box; the shop (score × area) wins
    prob = _prob(100, 100, {"window": [(10, 10, 40, 50)], "shop": [(30, 40, 90, 95, 0.95)]})
    els = detect_elements(prob, CLASSES)
    assert [(e.label, e.box) for e in els] == [("shop", (30, 40, 90, 95))]
    # apart, both are kept
    prob = _prob(100, 100, {"window": [(10, 10, 25, 35)], "shop": [(30, 40, 90, 95, 0.95)]})
    assert [e.label for e in detect_elements(prob, CLASSES)] == ["window", "shop"]


def _grid(rows=3, cols=4, jitter=0, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(rows):
        for j in range(cols):
            dx, dy = rng.integers(-jitter, jitter + 1, 2) if jitter else (0, 0)
            x0, y0 = 20 + 50 * j + dx, 15 + 60 * i + dy
            out.append(Element("window", (int(x0), int(y0), int(x0 + 25), int(y0 + 35)), 0.9))
    return out


@pytest.mark.parametrize("jitter", [0, 6])
def test_layout_lines_run_through_wall_and_keep_every_element(jitter):
    h, w = 200, 230
    els = _grid(jitter=jitter, seed=jitter) + [Element("door", (100, 185, 120, 200), 0.8)]
    gray = np.random.default_rng(1).uniform(0.4, 0.6, (h, w))
    lay = element_layout(els, gray, np.zeros((h, w)), px_per_m=20.0)
    # floors partition the rows, tiles each floor's columns
    assert lay.floors[0][0] == 0 and lay.floors[-1][1] == h
    assert all(a[1] == b[0] for a, b in zip(lay.floors, lay.floors[1:]))
    for row in lay.tiles:
        assert row[0][0] == 0 and row[-1][1] == w
        assert all(a[1] == b[0] for a, b in zip(row, row[1:]))
    # no line crosses an element
    for y0, _ in lay.floors[1:]:
        assert not any(e.box[1] < y0 < e.box[3] for e in els)
    found = []
    for i, row in enumerate(lay.regions):
        for j, region in enumerate(row):
            if region is None:
                continue
            x0, x1 = lay.tiles[i][j]
            y0, y1 = lay.floors[i]
            assert region.box == (x0, y0, x1, y1)
            for leaf in leaves(region):
                if leaf.role == "element":
                    found.append((leaf.label, leaf.box))
            for node in _walk(region):
                assert node.split in SPLIT_TYPES
                if node.children:                   # children tile their parent along one axis
                    k = 1 if node.split in ("top", "bottom", "dual-y") else 0
                    kids = node.children
                    assert kids[0].box[k] == node.box[k] and kids[-1].box[k + 2] == node.box[k + 2]
                    assert all(a.box[k + 2] == b.box[k] for a, b in zip(kids, kids[1:]))
                    o = 1 - k
                    assert all(c.box[o] == node.box[o] and c.box[o + 2] == node.box[o + 2]
                               and c.box[k + 2] > c.box[k] for c in kids)
    assert sorted(found) == sorted((e.label, e.box) for e in els)
    assert len(lay.confidences["floors"]) == len(lay.floors) - 1
    assert all(c == 1.0 for c in lay.confidences["floors"])     # zero occupancy on every line
    # confidence = 1 − the mean element probability along the line
    occupancy = np.full((h, w), 0.3)
    occupancy[:, : w // 2] = 0.7
    half = element_layout(els, gray, occupancy, px_per_m=20.0)
    assert half.floors == lay.floors
    assert half.confidences["floors"] == pytest.approx([0.5] * (len(lay.floors) - 1), abs=0.01)


def _walk(region):
    yield region
    for c in region.children:
        yield from _walk(c)


def test_region_of_touching_stacked_elements_keeps_both():
    top = Element("window", (10, 5, 30, 20), 0.7)
    low = Element("window", (12, 20, 28, 50), 0.9)      # touches the one above, no gap
    root = element_region((0, 0, 40, 60), [top, low])
    assert root.split == "top"
    assert sorted(leaf.box for leaf in leaves(root) if leaf.role == "element") == [
        top.box, low.box]
    one = element_region((0, 0, 40, 60), [Element("door", (0, 10, 40, 60), 0.8)])
    assert one.split == "top" and [c.role for c in one.children] == ["wall", "element"]
    assert one.children[1].label == "door"


def test_refine_clusters_splits_appearance_clusters_by_geometry():
    gray = np.full((80, 230), 0.5)

    def ids(elements, tol):
        lay = element_layout(elements, gray, np.zeros(gray.shape), px_per_m=20.0)
        assert [len(r) for r in lay.tiles] == [4]
        floor_c, tile_c = refine_clusters(lay.floors, lay.tiles, lay.regions, [0],
                                          [[0, 0, 0, 0]], tol=tol)
        assert floor_c == [0]
        return tile_c[0]

    els = _grid(rows=1, cols=4)
    same = ids(els, tol=2.0)
    assert same[1] == same[2]                   # two inner tiles, identical: one rule
    m = els[2]
    els[2] = Element("window", (m.box[0], m.box[1] + 8, m.box[2], m.box[3] + 8), 0.9)
    moved = ids(els, tol=2.0)
    assert moved[1] != moved[2]                 # the moved element gets its own rule
    assert ids(els, tol=50.0)[1] == ids(els, tol=50.0)[2]
    assert sorted(set(moved)) == list(range(len(set(moved))))


def test_layout_of_no_elements_is_one_wall_tile():
    lay = element_layout([], np.full((50, 80), 0.5), np.zeros((50, 80)), px_per_m=20.0)
    assert lay.floors == [(0, 50)] and lay.tiles == [[(0, 80)]] and lay.regions == [[None]]
    assert lay.floor_period_px == 0.0


def test_layout_floor_period_is_the_storey_between_two_lines():
    els = _grid(rows=4, cols=2)                    # window rows every 60 px
    lay = element_layout(els, np.full((260, 130), 0.5), np.zeros((260, 130)), px_per_m=20.0)
    assert len(lay.floors) == 4
    assert lay.floor_period_px == pytest.approx(60, abs=2)


def test_windows_extend_through_the_railing_in_front_of_them():
    """``behind``: a window whose foot is hidden by a balcony railing (CMP draws the window
    whole) reaches down through the railing rows, by at most a third of its height."""
    classes = ("wall", "window", "balcony")
    prob = np.zeros((60, 40, 3), np.float32)
    prob[:, :, 0] = 1
    prob[10:40, 10:30] = (0, 1, 0)        # window rows 10-39
    prob[40:60, 5:35] = (0, 0, 1)         # railing below it, deeper than a third of the window
    plain = detect_elements(prob, classes, labels=("window",))
    through = detect_elements(prob, classes, labels=("window",), behind=("balcony",))
    assert [e.box for e in plain] == [(10, 10, 30, 40)]
    assert [e.box for e in through] == [(10, 10, 30, 50)]   # 30 px window + 10 px
    prob[44:60, 5:35] = (1, 0, 0)         # the railing ends after 4 rows: so does the window
    through = detect_elements(prob, classes, labels=("window",), behind=("balcony",))
    assert [e.box for e in through] == [(10, 10, 30, 44)]


def test_closed_shutters_are_windows_and_open_ones_beside_glass_are_not():
    """``covers``: a window whose shutters are closed (CMP draws its rectangle over them) is a
    window; shutters open beside a window's glass are trimmed off it; patches of wall the
    classifier calls shutter, smaller than the windows or in none of their columns, are no
    windows."""
    classes = ("wall", "window", "blind")
    prob = np.zeros((100, 200, 3), np.float32)
    prob[:, :, 0] = 1
    for x in (10, 60, 110):                  # three glass windows in a row, 20 x 30 px
        prob[10:40, x:x + 20] = (0, 1, 0)
    prob[10:40, 130:136] = (0, 0, 1)         # the third one's shutter, open beside its glass
    prob[60:90, 10:30] = (0, 0, 1)           # a closed window below the first: shutters only
    prob[60:90, 60:80] = (0, 1, 0)           # a glass window below the second, its lower
    prob[75:90, 60:80] = (0, 0, 1)           # half behind closed shutters
    prob[60:72, 110:126] = (0, 0, 1)         # shutter-coloured patches of wall: one small,
    prob[60:90, 165:185] = (0, 0, 1)         # one in no column of windows
    plain = detect_elements(prob, classes, labels=("window",))
    covered = detect_elements(prob, classes, labels=("window",), covers=("blind",))
    assert sorted(e.box for e in plain) == [(10, 10, 30, 40), (60, 10, 80, 40),
                                            (60, 60, 80, 75), (110, 10, 130, 40)]
    assert sorted(e.box for e in covered) == [(10, 10, 30, 40), (10, 60, 30, 90),
                                              (60, 10, 80, 40), (60, 60, 80, 90),
                                              (110, 10, 130, 40)]


# -- balconies: protruding elements ----------------------------------------------------------

def test_detect_protruding_finds_a_band_and_per_window_balconies(balcony_scene):
    sc = balcony_scene
    fronts = detect_protruding(sc.prob, sc.classes)
    assert [(e.label, e.box) for e in fronts] == [("balcony", b) for b in sc.balconies]
    # the windows behind them are all still found, reaching down behind the railings
    windows = detect_elements(sc.prob, sc.classes, behind=("balcony",))
    assert len(windows) == 8 and {e.label for e in windows} == {"window"}
    for e, truth in zip(windows, sc.windows):
        assert e.box[:3] == truth[:3] and truth[3] - 3 <= e.box[3] <= truth[3]
    # balconies overlap the windows: in detect_elements' cross-class step they would be lost
    assert all(any(_overlaps(f.box, w.box) for w in windows) for f in fronts)
    mixed = detect_elements(sc.prob, sc.classes, labels=("window", "balcony"),
                            behind=("balcony",))
    assert len(mixed) < len(windows) + len(fronts)
    no_balcony = tuple("roof" if c == "balcony" else c for c in sc.classes)
    assert detect_protruding(sc.prob, no_balcony) == []     # a classifier without balconies


def _overlaps(a, b) -> bool:
    return min(a[2], b[2]) > max(a[0], b[0]) and min(a[3], b[3]) > max(a[1], b[1])


def test_layout_hangs_balconies_on_their_floor_or_tile_and_keeps_lines_off_them(balcony_scene):
    sc = balcony_scene
    windows = detect_elements(sc.prob, sc.classes, behind=("balcony",))
    fronts = detect_protruding(sc.prob, sc.classes)
    gray = np.full(sc.prob.shape[:2], 0.5)
    lay = element_layout(windows, gray, np.zeros(gray.shape), 20.0, fronts=fronts)
    plain = element_layout(windows, gray, np.zeros(gray.shape), 20.0)
    # the floor line runs under the band's slab, not through its railing
    assert len(lay.floors) == len(plain.floors) == 2
    assert sc.band[3] <= lay.floors[1][0] < sc.windows[4][1] and plain.floors[1][0] < sc.band[3]
    # the band hangs on the upper floor, each per-window balcony on its window's tile
    assert [(j, r.box) for j, r in lay.fronts[0]] == [(None, sc.band)]
    assert [(j, r.box) for j, r in lay.fronts[1]] == list(zip((1, 2), sc.per_window))
    assert all(r.role == "element" and r.label == "balcony" for _, r in lay.fronts[1])
    # the windows behind them are whole element leaves of the partition
    found = sorted(leaf.box for row in lay.regions for r in row for leaf in leaves(r)
                   if leaf.role == "element")
    assert found == sorted(e.box for e in windows)
    # a tile with a balcony is not clustered with one without
    floor_c, tile_c = refine_clusters(lay.floors, lay.tiles, lay.regions, [0, 0],
                                      [[0] * len(r) for r in lay.tiles], tol=2.0,
                                      fronts=lay.fronts)
    assert tile_c[1][1] == tile_c[1][2] != tile_c[1][0]
    no_fronts = refine_clusters(lay.floors, lay.tiles, lay.regions, [0, 0],
                                [[0] * len(r) for r in lay.tiles], tol=2.0)[1]
    assert no_fronts[1][0] == no_fronts[1][1]
    assert floor_c[0] != floor_c[1]
