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
    seeded = fit_grammar(_prob(lab), CMP6, rules, budget=300, initialiser=initialiser_for(rules))
    plain = fit_grammar(_prob(lab), CMP6, rules, budget=300)
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
