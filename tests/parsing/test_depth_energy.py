"""The depth energy of simon2011 eq. 5.9 and the automatic α of §5.2.3."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.errors import InputError
from facadeforge.parsing.energy import DepthEnergy
from facadeforge.parsing.evolution import auto_alpha, evolve
from facadeforge.parsing.layout import Layout
from facadeforge.parsing.search import Parameter


def _brute(depth, layout, depths):
    h, w = depth.shape
    dm = np.zeros((h, w))
    for (x0, y0, x1, y1), lab in zip(layout.boxes, layout.labels):
        c0, c1 = int(round(x0 * w / layout.width)), int(round(x1 * w / layout.width))
        r0 = int(round((layout.height - y1) * h / layout.height))
        r1 = int(round((layout.height - y0) * h / layout.height))
        dm[r0:r1, c0:c1] = depths.get(lab, 0.0)
    ok = np.isfinite(depth)
    e = dm[ok] - depth[ok]
    return float(((e - e.mean()) ** 2).sum())


def test_depth_energy_is_eq_5_9():
    rng = np.random.default_rng(0)
    depth = rng.normal(0, 0.02, (40, 60))
    depth[10:20, 10:25] -= 0.3
    depth[rng.random(depth.shape) < 0.2] = np.nan
    lay = Layout(np.array([[1.0, 4.0, 5.0, 6.0], [7.0, 1.0, 9.0, 3.0]]), ("window", "door"),
                 12.0, 8.0)
    depths = {"window": -0.3, "door": -0.2}
    e = DepthEnergy(depth, depths)
    assert e(lay) == pytest.approx(_brute(depth, lay, depths), rel=1e-9)
    # the mean gap d̄ is free: a constant offset of the scan changes nothing
    assert DepthEnergy(depth + 0.5, depths)(lay) == pytest.approx(e(lay), rel=1e-9)
    # the layout whose window sits on the recess explains the scan better than one beside it
    good = Layout(np.array([[10 / 5, 8 - 20 / 5, 25 / 5, 8 - 10 / 5]]), ("window",), 12.0, 8.0)
    bad = Layout(np.array([[30 / 5, 8 - 20 / 5, 45 / 5, 8 - 10 / 5]]), ("window",), 12.0, 8.0)
    assert e(good) < 0.2 * e(bad)
    assert e.rasterize(good).min() == -0.3


def test_depth_energy_errors():
    with pytest.raises(InputError):
        DepthEnergy(np.zeros(5), {})
    e = DepthEnergy(np.full((4, 4), np.nan), {"window": -0.2})
    assert e(Layout(np.zeros((0, 4)), (), 1.0, 1.0)) == 0.0


def test_auto_alpha_picks_the_knee_and_its_strength():
    # a convex front: the knee (1, 1) is farthest below the bounding box's diagonal
    F = np.array([[0.0, 10.0], [1.0, 1.0], [10.0, 0.0], [5.0, 5.0], [2.0, 8.0]])
    row, alpha, (lo, hi) = auto_alpha(F)
    assert row == 1
    assert alpha == pytest.approx(0.5)
    assert 0.0 < lo < alpha < hi < 1.0
    # scaling one objective scales α but not the choice
    row2, alpha2, _ = auto_alpha(F * np.array([100.0, 1.0]))
    assert row2 == 1 and alpha2 == pytest.approx(10 / 1010)
    # a dominating row is optimal for every α
    row3, _, rng = auto_alpha(np.array([[1.0, 1.0], [2.0, 3.0], [4.0, 2.0]]))
    assert row3 == 0 and rng == (0.0, 1.0)
    with pytest.raises(InputError):
        auto_alpha(np.zeros((3, 3)))


def test_evolve_auto_weights_returns_front_and_alpha():
    params = [Parameter("x", 0.5, 0.0, 1.0), Parameter("y", 0.5, 0.0, 1.0)]

    def two(attrs):
        x, y = attrs["x"], attrs["y"]
        return np.array([x ** 2 + y, (1 - x) ** 2 + y])

    r = evolve(two, params, budget=300, seed=1, weights="auto")
    assert r.alpha is not None and 0 <= r.alpha_range[0] <= r.alpha <= r.alpha_range[1] <= 1
    assert len(r.front) >= 3
    F = np.array(r.front)
    assert (F[:, 0] + F[:, 1]).min() < 0.6          # the front reaches the true one (y = 0)
    assert r.attrs["y"] < 0.1
    with pytest.raises(InputError):
        evolve(two, params, budget=10, weights="knee")
