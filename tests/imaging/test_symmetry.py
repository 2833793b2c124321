"""Mutual information, S(y, h) and the irreducible facade (Müller 2007, §2.1–2.3)."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.imaging.symmetry import (
    collapse,
    dominant_period,
    irreducible_facade,
    irreducible_facade_2d,
    mutual_information,
    quantise,
    symmetry_profile,
)


def _entropy(levels: np.ndarray) -> float:
    p = np.bincount(levels.ravel()) / levels.size
    p = p[p > 0]
    return float(-(p * np.log(p)).sum())


def test_mi_identical_is_entropy():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 8, size=(50, 40))
    assert mutual_information(a, a, bins=8) == pytest.approx(_entropy(a), abs=1e-12)
    # any relabelling keeps all the information
    perm = rng.permutation(8)
    assert mutual_information(a, perm[a], bins=8) == pytest.approx(_entropy(a), abs=1e-12)


def test_mi_independent_is_zero():
    rng = np.random.default_rng(1)
    a = rng.integers(0, 8, size=(200, 200))
    assert mutual_information(a, np.zeros_like(a), bins=8) == pytest.approx(0.0, abs=1e-12)
    b = rng.integers(0, 8, size=(200, 200))
    assert 0.0 <= mutual_information(a, b, bins=8) < 0.01
    # a 2x2 product distribution exactly
    x = np.array([0, 0, 1, 1])
    y = np.array([0, 1, 0, 1])
    assert mutual_information(x, y, bins=2) == pytest.approx(0.0, abs=1e-15)
    assert mutual_information(x, x, bins=2) == pytest.approx(np.log(2))


def test_mi_float_inputs_quantised():
    rng = np.random.default_rng(2)
    a = rng.random((30, 30))
    assert mutual_information(a, 3.0 * a + 1.0, bins=16) == pytest.approx(
        _entropy(quantise(a, 16)), abs=1e-9)
    with pytest.raises(ValueError):
        mutual_information(a, a[:10])


def _reference_S(q: np.ndarray, hs: np.ndarray, bins: int) -> np.ndarray:
    """Direct eq. 2: rebuild the histograms of R_{y,h} and R_{y-h,h} for every (y, h)."""
    n = q.shape[0]
    S = np.full((n, hs.size), np.nan)
    for i, h in enumerate(hs):
        for y in range(h, n - h + 1):
            S[y, i] = mutual_information(q[y:y + h], q[y - h:y], bins=bins)
    return S


@pytest.mark.parametrize("bins", [4, 8, 32])
@pytest.mark.parametrize("axis", [0, 1])
def test_fast_profile_equals_reference(bins, axis):
    rng = np.random.default_rng(3 + bins + axis)
    g = rng.random((37, 23))
    g[20:30] = g[5:15] + 0.01 * rng.random((10, 23))       # some real repetition
    prof = symmetry_profile(g, (2, 12), axis=axis, bins=bins)
    q = quantise(g, bins)
    ref = _reference_S(q if axis == 0 else q.T, prof.hs, bins)
    assert prof.S.shape == ref.shape
    assert np.array_equal(np.isnan(prof.S), np.isnan(ref))
    np.testing.assert_allclose(prof.S[~np.isnan(ref)], ref[~np.isnan(ref)], atol=1e-10)
    ok = ~np.isnan(ref).all(axis=1)
    np.testing.assert_allclose(prof.s_max[ok], np.nanmax(ref[ok], axis=1), atol=1e-10)
    assert np.all(prof.h_max[~ok] == -1) and np.all(np.isnan(prof.s_max[~ok]))


def _periodic(period: int, reps: int, width: int = 40, seed: int = 4) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tile = rng.random((period, width))
    return np.tile(tile, (reps, 1)) + 0.02 * rng.random((period * reps, width))


def test_periodic_rows_found():
    g = _periodic(9, 6)
    prof = symmetry_profile(g, (5, 13), bins=16)
    assert dominant_period(prof) == 9
    ok = np.isfinite(prof.s_max)
    assert np.mean(prof.h_max[ok] == 9) > 0.8


def test_irreducible_facade_collapses_period():
    g = _periodic(8, 5)
    prof = symmetry_profile(g, (4, 12), bins=16)
    groups = irreducible_facade(prof)
    flat = sorted(i for grp in groups for i in grp)
    assert flat == list(range(g.shape[0]))                  # reversible: a partition
    assert len(groups) < g.shape[0] - 8                     # it shrank by whole periods
    stacked = [grp for grp in groups if len(grp) > 1]
    assert stacked and all(len({i % 8 for i in grp}) == 1 for grp in stacked)
    img = collapse(g, groups)
    assert img.shape == (len(groups), g.shape[1])


def test_irreducible_facade_without_symmetry_is_identity():
    rng = np.random.default_rng(5)
    prof = symmetry_profile(rng.random((30, 20)), (3, 8), bins=8)
    prof.s_max[:] = np.nan
    assert irreducible_facade(prof) == [[i] for i in range(30)]


def test_irreducible_facade_2d():
    rng = np.random.default_rng(6)
    tile = rng.random((7, 5))
    g = np.tile(tile, (4, 6)) + 0.01 * rng.random((28, 30))
    rows, cols = irreducible_facade_2d(g, (4, 10), (3, 8), bins=16)
    assert sorted(i for r in rows for i in r) == list(range(28))
    assert sorted(i for c in cols for i in c) == list(range(30))
    assert len(rows) < 28 and len(cols) < 30


def test_degenerate_inputs():
    prof = symmetry_profile(np.zeros((5, 5)), (3, 10))    # h > n/2: nothing defined
    assert prof.hs.size == 0 and dominant_period(prof) == 0
    assert irreducible_facade(prof) == [[i] for i in range(5)]
    flat = symmetry_profile(np.ones((20, 6)), (2, 5), bins=8)
    assert np.allclose(flat.S[np.isfinite(flat.S)], 0.0)
