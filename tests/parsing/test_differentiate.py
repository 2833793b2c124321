"""Differentiation after the consistent fit: per-instance windows, balconies, bands and shops."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.datasets import get_label_set
from facadeforge.engine import load_rules
from facadeforge.parsing.differentiate import differentiate, supports_differentiation
from facadeforge.parsing.energy import SegmentationEnergy
from facadeforge.parsing.fit import fit_grammar, grammar_path
from facadeforge.parsing.layout import SplitLayout
from facadeforge.parsing.parse import write_fitted_rules
from facadeforge.parsing.search import parameters_of

CMP6 = get_label_set("cmp6")
W, H = 15.0, 20.0
SHAPE = (200, 150)


@pytest.fixture(scope="module")
def grid():
    rules = load_rules(grammar_path("grid"))
    attrs = {p.name: p.default for p in parameters_of(rules)}
    attrs.update(balcony2=True, guard3=True, groundKind="shops", facadeWidth=W)
    return rules, SplitLayout(rules), attrs


def _prob(truth: np.ndarray, p: float = 0.8) -> np.ndarray:
    prob = np.full((*truth.shape, CMP6.num_classes), (1 - p) / (CMP6.num_classes - 1),
                   np.float32)
    np.put_along_axis(prob, truth[..., None].astype(np.int64), p, axis=2)
    return prob


def _uniform_energy() -> SegmentationEnergy:
    return SegmentationEnergy(np.full((*SHAPE, CMP6.num_classes), 1 / 6, np.float32), CMP6)


def test_zero_cells_derive_the_consistent_layout(grid):
    rules, layout, attrs = grid
    rng = np.random.default_rng(1)
    params = parameters_of(rules)
    for _ in range(20):
        a = {p.name: (p.choices[rng.integers(len(p.choices))] if p.discrete
                      else rng.uniform(p.lo, p.hi)) for p in params}
        a["facadeWidth"] = W
        consistent = layout.derive(W, H, a)
        flat = layout.derive(W, H, {**a, "differentiated": True,
                                    "windowCells": np.zeros(10 * 12 * 7),
                                    "bandCells": np.zeros(30), "shopCells": np.zeros(6),
                                    "archCells": np.zeros(48)})
        # guards are per instance once differentiated: zero cells mean no guard
        if not any(a[f"guard{i}"] for i in range(1, 11)):
            assert flat.labels == consistent.labels
            assert np.allclose(flat.boxes, consistent.boxes)


def test_instances_that_differ_are_found(grid):
    rules, layout, attrs = grid
    consistent = layout.derive(W, H, attrs)
    energy0 = _uniform_energy()
    truth = energy0.rasterize(consistent)
    win, wall, bal, shop = (CMP6.index(c) for c in ("window", "wall", "balcony", "shop"))
    boxes = [b for b, lab in zip(energy0.pixel_boxes(consistent), consistent.labels)
             if lab == "window"]
    r0, c0, r1, c1 = boxes[-1]           # the top floor's last window: missing
    truth[r0:r1, c0:c1] = wall
    r0, c0, r1, c1 = boxes[-3]           # a wider window
    truth[r0:r1, c0 - 2:c1 + 2] = win
    r0, c0, r1, c1 = boxes[-7]           # a balcony in front of one window, wider than it
    truth[r1 - 4:r1 + 2, c0 - 2:c1 + 2] = bal
    shops = np.argwhere(truth == shop)   # the shops stop below the ground floor's top
    truth[shops[:, 0].min():shops[:, 0].min() + 5][truth[shops[:, 0].min():
                                                        shops[:, 0].min() + 5] == shop] = wall
    energy = SegmentationEnergy(_prob(truth), CMP6)
    out = differentiate(energy, layout, attrs, W, H, parameters_of(rules))
    assert out is not None and out["differentiated"] is True
    before = (energy.rasterize(consistent) == truth).mean()
    lay = layout.derive(W, H, out)
    after = (energy.rasterize(lay) == truth).mean()
    assert energy(lay) < energy(consistent)
    assert before < 0.985 and after > 0.995, (before, after)


def test_never_worse_and_none_without_the_attributes(grid):
    rules, layout, attrs = grid
    rng = np.random.default_rng(0)
    prob = rng.dirichlet(np.ones(CMP6.num_classes), SHAPE).astype(np.float32)
    energy = SegmentationEnergy(prob, CMP6)
    out = differentiate(energy, layout, attrs, W, H, parameters_of(rules))
    if out is not None:
        assert energy(layout.derive(W, H, out)) < energy(layout.derive(W, H, attrs))
    generic = SplitLayout(load_rules(grammar_path("generic")))
    assert not supports_differentiation(generic)
    assert differentiate(energy, generic, {"facadeWidth": W}, W, H) is None


def test_fitted_rules_with_arrays_derive_the_same_layout(grid, tmp_path):
    rules, layout, attrs = grid
    cells = np.zeros(10 * 12 * 7)
    cells[0:7] = (-0.2, 0.1, 0.05, -0.1, 0.3, 0.1, 0.05)
    fitted = {**attrs, "differentiated": True, "windowCells": cells,
              "bandCells": np.array([0.0, 0.0, 0.0, -0.5, 0.1, 0.2] + [0.0] * 24),
              "shopCells": np.array([0.1, 0.0, 0.2, 0.0, 0.1, 0.0]),
              "archCells": np.zeros(48)}
    path = tmp_path / "fitted.cga"
    path.write_text(write_fitted_rules(grammar_path("grid").read_text(), fitted))
    own = SplitLayout(load_rules(path)).derive(W, H)   # the file's own defaults
    expected = layout.derive(W, H, fitted)
    assert own.labels == expected.labels
    assert np.allclose(own.boxes, expected.boxes)


def test_fit_grammar_differentiates_only_when_asked(grid):
    rules, layout, attrs = grid
    truth = _uniform_energy().rasterize(layout.derive(W, H, attrs))
    prob = _prob(truth)
    on = fit_grammar(prob, CMP6, rules, method="hill", budget=60, seed=0)
    off = fit_grammar(prob, CMP6, rules, method="hill", budget=60, seed=0, differentiate=False)
    assert "windowCells" not in off.attrs
    assert on.energy_per_pixel <= off.energy_per_pixel


def test_instances_are_told_apart_when_a_column_runs_off_the_facade(grid):
    """A column placeholder past the facade's right edge derives no window, so the windows can
    no longer be matched to placeholders by their rank; the grammar's own probe still tells
    every opening's floor and column, and a missing window is still found."""
    rules, layout, attrs = grid
    attrs = {**attrs, "nColumns": 6.0, "column6": 0.995}
    consistent = layout.derive(W, H, attrs)
    energy0 = _uniform_energy()
    truth = energy0.rasterize(consistent)
    wall = CMP6.index("wall")
    windows = [b for b, lab in zip(energy0.pixel_boxes(consistent), consistent.labels)
               if lab == "window" and b[3] - b[1] > 0 and b[2] - b[0] > 0]
    assert len(windows) == 4 * 5 + 4          # five whole windows per floor, a sliver in the 6th
    r0, c0, r1, c1 = windows[2]               # the first floor's third window: missing
    truth[r0:r1, c0:c1] = wall
    energy = SegmentationEnergy(_prob(truth), CMP6)
    out = differentiate(energy, layout, attrs, W, H, parameters_of(rules))
    assert out is not None
    lay = layout.derive(W, H, out)
    assert (energy.rasterize(lay) == truth).mean() > 0.995
    # the missing window is written into its own cell: floor 1, column 3
    assert out["windowCells"][(0 * 12 + 2) * 7 + 1] == -1.0


def test_separate_balconies_replace_a_running_band(grid):
    """Floor 2 has a running band in the consistent fit, but the photo shows one balcony in
    front of each window (the band's pixels between them are wall): the band is removed and
    each window gets its own balcony, reaching down over where the band was."""
    rules, layout, attrs = grid
    consistent = layout.derive(W, H, attrs)
    energy0 = _uniform_energy()
    truth = energy0.rasterize(consistent)
    wall, bal = CMP6.index("wall"), CMP6.index("balcony")
    pix = energy0.pixel_boxes(consistent)
    band = next(b for b, lab in zip(pix, consistent.labels) if lab == "balcony"
                and b[3] - b[1] > 100)                      # the running band: full width
    r0, c0, r1, c1 = band
    truth[r0:r1, c0:c1] = wall
    above = [b for b, lab in zip(pix, consistent.labels) if lab == "window" and 0 < r0 - b[2] < 12]
    assert len(above) == 5
    for _, x0, w1, x1 in above:                             # a balcony per window, from the
        truth[w1 - 3:r1, x0 - 2:x1 + 2] = bal               # band's foot up into the window
    energy = SegmentationEnergy(_prob(truth), CMP6)
    out = differentiate(energy, layout, attrs, W, H, parameters_of(rules))
    assert out is not None
    lay = layout.derive(W, H, out)
    before = (energy.rasterize(consistent) == truth).mean()
    after = (energy.rasterize(lay) == truth).mean()
    assert after > 0.995 and before < 0.98, (before, after)
    assert out["bandCells"][(2 - 1) * 3] == -1.0             # floor 2's band is gone


def test_instances_are_told_apart_beside_a_sliver_of_wall(grid):
    """The last column ends 1.5 mm short of the facade's edge: widening the windows to tell
    them apart makes that sliver of wall vanish, so a smaller widening is tried, and a missing
    window is still found."""
    rules, layout, attrs = grid
    attrs = {**attrs, "column5": 1 - attrs["windowWidth"] - 1e-4}
    consistent = layout.derive(W, H, attrs)
    energy0 = _uniform_energy()
    truth = energy0.rasterize(consistent)
    windows = [b for b, lab in zip(energy0.pixel_boxes(consistent), consistent.labels)
               if lab == "window"]
    r0, c0, r1, c1 = windows[2]
    truth[r0:r1, c0:c1] = CMP6.index("wall")
    energy = SegmentationEnergy(_prob(truth), CMP6)
    out = differentiate(energy, layout, attrs, W, H, parameters_of(rules))
    assert out is not None
    assert (energy.rasterize(layout.derive(W, H, out)) == truth).mean() > 0.995
