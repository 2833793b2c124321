"""The measured search seed: the classifier's window grid read into grid.cga attributes."""

from __future__ import annotations

import numpy as np

from facadeforge.datasets import get_label_set
from facadeforge.engine import load_rules
from facadeforge.parsing.fit import fit_grammar, grammar_path
from facadeforge.parsing.init import grid_seed, window_boxes

CMP6 = get_label_set("cmp6")


def _prob(labels: np.ndarray) -> np.ndarray:
    p = np.full((*labels.shape, CMP6.num_classes), 0.02, np.float32)
    np.put_along_axis(p, labels[:, :, None].astype(int), 0.9, axis=2)
    return p / p.sum(axis=2, keepdims=True)


def _grid_labels():
    lab = np.full((200, 160), CMP6.index("wall"), np.uint8)
    cols = [10, 50, 90, 125]          # uneven spacing
    rows = [20, 70, 120]              # window tops, 3 upper floors
    for r in rows:
        for c in cols:
            lab[r:r + 30, c:c + 20] = CMP6.index("window")
    lab[170:] = CMP6.index("shop")
    return lab, cols, rows


def test_window_boxes_and_grid_seed():
    lab, cols, rows = _grid_labels()
    prob = _prob(lab)
    assert len(window_boxes(prob, CMP6)) == 12
    assert len(window_boxes(prob, CMP6, one_facade=True)) == 12
    joined = lab.copy()                      # two windows of a row touch through a bridge
    joined[30:33, 30:50] = CMP6.index("window")
    for one_facade in (False, True):
        assert len(window_boxes(_prob(joined), CMP6, one_facade)) == 12
    seed = grid_seed(prob, CMP6)
    assert seed["nColumns"] == 4 and seed["nFloors"] == 3
    np.testing.assert_allclose([seed[f"column{j}"] for j in range(1, 5)],
                               np.array(cols) / 160, atol=1e-6)
    assert abs(seed["windowWidth"] - 20 / 160) < 1e-6
    assert seed["groundKind"] == "shops"
    assert grid_seed(_prob(np.full((50, 50), 1, np.uint8)), CMP6) is None  # no windows


def test_seeded_fit_recovers_uneven_columns():
    lab, cols, rows = _grid_labels()
    from facadeforge.parsing.init import initialiser_for

    rules = load_rules(grammar_path("grid"))
    assert initialiser_for(load_rules(grammar_path("generic"))) is None
    seeded = fit_grammar(_prob(lab), CMP6, rules, method="evolution", budget=400,
                         initialiser=initialiser_for(rules))
    plain = fit_grammar(_prob(lab), CMP6, rules, method="evolution", budget=400)
    agree = (seeded.labels == lab).mean()
    # the grid grammar cannot place the top window exactly (shared sill fraction, taller top
    # floor), hence not 1.0; an unseeded search at the same budget does clearly worse
    assert agree > 0.9, agree
    assert agree > (plain.labels == lab).mean() + 0.02


def test_grid_seed_ignores_a_neighbours_offset_rows():
    """A second building at the side, with its windows at other heights, adds no floors: rows
    need windows in half the columns."""
    lab, cols, rows = _grid_labels()
    lab = np.concatenate([lab, np.full((200, 40), CMP6.index("wall"), np.uint8)], axis=1)
    for r in (40, 95, 140):                  # the neighbour's column, between the main rows
        lab[r:r + 25, 172:190] = CMP6.index("window")
    seed = grid_seed(_prob(lab), CMP6)
    assert seed["nFloors"] == 3 and seed["nColumns"] == 4


def test_grid_seed_reads_balcony_guards_per_floor():
    lab, cols, rows = _grid_labels()
    for c in cols:                            # guards under the windows of the lowest floor
        lab[142:150, c:c + 20] = CMP6.index("balcony")
    seed = grid_seed(_prob(lab), CMP6)
    assert seed["guard1"] is True and seed["guard2"] is False and seed["guard3"] is False
    assert 0.1 < seed["guardFrac"] < 0.5


def test_grid_seed_reads_margins_street_and_an_arcade():
    """Background beside and below the building becomes margins and a street band; shop
    openings under the window columns, with wall piers between them and a door under the
    third column, become an arcade."""
    lab, cols, rows = _grid_labels()
    lab[170:] = CMP6.index("wall")
    for c in cols:
        lab[172:195, c - 2:c + 22] = CMP6.index("shop")
    lab[172:195, cols[2] - 2:cols[2] + 22] = CMP6.index("door")
    bg = CMP6.index("background")
    lab = np.concatenate([np.full((200, 16), bg, np.uint8), lab,
                          np.full((200, 24), bg, np.uint8)], axis=1)          # 200 x 200
    lab = np.concatenate([lab, np.full((10, 200), bg, np.uint8)], axis=0)     # street rows
    seed = grid_seed(_prob(lab), CMP6)
    assert abs(seed["leftMargin"] - 16 / 200) < 1e-6 and abs(seed["rightMargin"] - 24 / 200) < 1e-6
    assert abs(seed["streetFrac"] - 10 / 210) < 1e-6
    # no sky above: the wall from the roof line to the top is attic, less the roof band
    assert abs(seed["atticFrac"] - (1 - seed["roofLine"] - 0.03)) < 1e-6
    np.testing.assert_allclose([seed[f"column{j}"] for j in range(1, 5)],
                               (np.array(cols) + 16) / 200, atol=1e-6)
    assert seed["groundKind"] == "arcade" and seed["arcadeKind"] == "shop"
    assert seed["doorColumn"] == 3.0
    assert abs(seed["arcadeWidth"] - 24 / 200) < 1e-6
    # without surroundings in the grammar the seed leaves them out, and the ground floor is
    # measured on the whole width
    plain = grid_seed(_prob(lab), CMP6, surroundings=False)
    assert plain["leftMargin"] == 0 and "arcadeWidth" not in plain


def test_margins_are_pinned_for_a_classifier_without_background():
    from facadeforge.parsing.init import pinned_for

    rules = load_rules(grammar_path("grid"))
    assert pinned_for(rules, get_label_set("ecp7")) == {
        "atticFrac": 0.0, "leftMargin": 0.0, "rightMargin": 0.0, "streetFrac": 0.0}
    assert pinned_for(rules, CMP6) == {}
    assert pinned_for(load_rules(grammar_path("haussmann")), get_label_set("ecp7")) == {}


def test_street_windows_ignore_uniform_probabilities_outside_the_photo():
    """Outside a warped street photo the probabilities are uniform, and their argmax is class
    0 — window, in ecp7.  Windows beside that area keep their own boxes."""
    ecp7 = get_label_set("ecp7")
    lab = np.full((200, 160), ecp7.index("wall"), np.uint8)
    for r in (20, 70, 120):
        for c in (10, 50, 90, 125):
            lab[r:r + 30, c:c + 20] = ecp7.index("window")
    p = np.full((*lab.shape, ecp7.num_classes), 0.02, np.float32)
    np.put_along_axis(p, lab[:, :, None].astype(int), 0.9, axis=2)
    p /= p.sum(axis=2, keepdims=True)
    p[:, 145:] = 1 / ecp7.num_classes                    # outside the warped photo
    boxes = window_boxes(p, ecp7)
    assert len(boxes) == 12 and boxes[:, 2].max() == 145
    assert grid_seed(p, ecp7)["nColumns"] == 4


def test_wide_margins_do_not_make_a_street():
    """Rows are measured between the margins: with margins of a third of the width on each
    side, the shop ground floor stays a ground floor of shops, not street."""
    lab, cols, rows = _grid_labels()
    bg = CMP6.index("background")
    lab = np.concatenate([np.full((200, 130), bg, np.uint8), lab,
                          np.full((200, 130), bg, np.uint8)], axis=1)          # 200 x 420
    seed = grid_seed(_prob(lab), CMP6)
    assert seed["streetFrac"] == 0.0 and seed["groundKind"] == "shops"
    assert abs(seed["leftMargin"] - 130 / 420) < 1e-6


def test_windows_beside_a_door_are_the_ground_floor():
    """A residential ground floor: windows in the columns and a door between them.  The row
    of windows beside the door is the ground floor's (the door is seeded inside it), not a
    fourth upper floor above an empty ground band."""
    lab, cols, rows = _grid_labels()
    lab[170:] = CMP6.index("wall")
    for c in cols:
        lab[168:190, c:c + 20] = CMP6.index("window")      # ground-floor windows
    lab[160:200, 72:88] = CMP6.index("door")                # the door between columns 2 and 3
    seed = grid_seed(_prob(lab), CMP6)
    assert seed["nFloors"] == 3                             # the three upper floors only
    assert seed["groundTop"] >= 0.19   # up to the gap below the first upper row: holds the door
    assert seed["doorWidth"] > 0 and abs(seed["doorWidth"] - 16 / 160) < 0.02
    lab[160:200, 72:88] = CMP6.index("wall")                # without the door: four floors
    assert grid_seed(_prob(lab), CMP6)["nFloors"] == 4


def test_a_door_under_the_middle_window_keeps_its_column():
    """Two rows of windows, the lower beside a door that stands under the upper row's middle
    window: the upper row alone gives the columns, so the door's column is one (with the door
    in it) rather than lost for having a single window."""
    lab = np.full((120, 200), CMP6.index("wall"), np.uint8)
    xs = [15, 55, 95, 135, 175]
    for x in xs:
        lab[20:50, x - 8:x + 8] = CMP6.index("window")      # the upper row: five windows
    for x in xs[:2] + xs[3:]:
        lab[72:102, x - 8:x + 8] = CMP6.index("window")     # the lower row: four beside a door
    lab[68:120, 87:103] = CMP6.index("door")
    seed = grid_seed(_prob(lab), CMP6)
    assert seed["nFloors"] == 1 and seed["nColumns"] == 5
    assert seed["groundKind"] == "arcade" and seed["doorColumn"] == 3
