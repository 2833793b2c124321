"""Edge/interest functions, optimal split subsets and floor/tile splitting (Müller 2007, §2.4)."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets.synthetic import generate
from facadeforge.imaging.splits import (
    edge_maps,
    floor_and_tile_split,
    interest_functions,
    local_minima,
    optimal_subset,
    split_lines,
)


def test_edge_maps_orientation():
    y = np.arange(40)[:, None] * np.ones((1, 30))
    stripes_h = (y // 5 % 2).astype(float)                 # horizontal edges only
    hor, ver = edge_maps(stripes_h)
    assert hor.max() > 0 and np.all(ver == 0)
    hor, ver = edge_maps(stripes_h.T)
    assert ver.max() > 0 and np.all(hor == 0)
    diag = np.add.outer(np.arange(20.0), np.arange(20.0))   # |I_x| = |I_y|: neither dominates
    hor, ver = edge_maps(diag, alpha=0.9)
    assert np.all(hor == 0) and np.all(ver == 0)


def test_interest_minima_between_windows():
    img = np.ones((100, 60))
    for y0 in (10, 45, 80):                                  # three "window rows"
        img[y0:y0 + 10, 10:20] = 0.0
        img[y0:y0 + 10, 35:45] = 0.0
    hor, ver = edge_maps(img)
    ver_y, hor_x = interest_functions(hor, ver, sigma_px=2.0)
    assert ver_y.shape == (100,) and hor_x.shape == (60,)
    lines = split_lines(ver_y, 25, 45)
    assert len(lines) >= 2
    for y in lines:                                          # never through a window row
        assert not any(y0 <= y < y0 + 10 for y0 in (10, 45, 80))


def test_local_minima():
    f = np.array([3, 1, 2, 2, 0, 0, 0, 5, 4, 4])
    assert local_minima(f).tolist() == [1, 5]
    assert local_minima(np.ones(5)).size == 0


def _feasible(p, sel, lo, hi, start, end):
    q = p[list(sel)]
    if np.any(np.diff(q) < lo) or np.any(np.diff(q) > hi):
        return False
    if start is not None and q[0] > start + hi:
        return False
    return not (end is not None and q[-1] < end - hi)


def test_optimal_subset_matches_brute_force():
    rng = np.random.default_rng(7)
    for trial in range(150):
        m = int(rng.integers(1, 10))
        p = np.sort(rng.choice(60, size=m, replace=False)).astype(float)
        v = rng.normal(size=m)
        lo, hi = float(rng.integers(2, 8)), float(rng.integers(8, 25))
        start, end = (0.0, 59.0) if trial % 2 else (None, None)
        best = np.inf
        for k in range(1, m + 1):
            for sel in itertools.combinations(range(m), k):
                if _feasible(p, sel, lo, hi, start, end):
                    best = min(best, float(v[list(sel)].mean()))
        got = optimal_subset(p, v, lo, hi, start=start, end=end)
        if not np.isfinite(best):
            assert got.size == 0
            continue
        assert got.size > 0 and _feasible(p, got, lo, hi, start, end)
        assert float(v[got].mean()) == pytest.approx(best, abs=1e-12)


def test_optimal_subset_unsorted_positions():
    p = np.array([30.0, 10.0, 20.0])
    v = np.array([-1.0, -1.0, -1.0])
    assert sorted(optimal_subset(p, v, 5, 12).tolist()) == [0, 1, 2]


def test_split_lines_periodic():
    x = np.arange(200)
    f = np.cos(2 * np.pi * x / 20.0)                         # minima at 10, 30, …, 190
    lines = split_lines(f, 15, 25)
    assert lines.tolist() == list(range(10, 200, 20))


def test_floor_and_tile_split_structure():
    rng = np.random.default_rng(8)
    img = (rng.random((120, 90, 3)) * 255).astype(np.uint8)
    st = floor_and_tile_split(img, 0.05)
    assert st.floors[0][0] == 0 and st.floors[-1][1] == 120
    assert all(a[1] == b[0] for a, b in zip(st.floors[:-1], st.floors[1:]))
    assert len(st.tiles) == len(st.floors)
    for row in st.tiles:
        assert row[0][0] == 0 and row[-1][1] == 90
    assert len(st.confidences["floors"]) == len(st.floors) - 1
    for c in st.confidences["floors"] + sum(st.confidences["tiles"], []):
        assert 0.0 <= c <= 1.0
    # degenerate images: no traceback
    for bad in (np.zeros((8, 8, 3), np.uint8), np.full((60, 50), 128, np.uint8)):
        st = floor_and_tile_split(bad)
        assert st.floors and st.floors[-1][1] == bad.shape[0]


def _upper_floor_heights(node: dict, out: list[float]) -> list[float]:
    sym = node.get("symbol", "")
    if sym.endswith("Floor") and not sym.startswith(("Base", "Ground")):
        out.append(float(node["scope"]["size"][1]))
    for child in node.get("children", []):
        _upper_floor_heights(child, out)
    return out


@pytest.fixture(scope="module")
def synthetic_facades(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("synth")
    generate(6, 5, d, size=280)
    return d


def test_floor_period_on_synthetic_facades(synthetic_facades):
    good, report = 0, []
    for photo in sorted(synthetic_facades.glob("*.jpg")):
        stem = photo.with_suffix("")
        meta = json.loads(Path(f"{stem}.meta.json").read_text())
        tree = json.loads(Path(f"{stem}.tree.json").read_text())
        heights = _upper_floor_heights(tree, [])
        assert heights, "tree has no floors"
        true_px = float(np.median(heights)) / meta["metres_per_pixel"][1]
        img = np.asarray(Image.open(photo).convert("RGB"))
        st = floor_and_tile_split(img, meta["metres_per_pixel"])
        err = abs(st.floor_period_px - true_px) / true_px
        report.append((meta["style"], round(true_px, 1), st.floor_period_px, round(err, 3)))
        good += err <= 0.10
        assert st.scale_source == "metres_per_pixel"
        assert st.floors[-1][1] == img.shape[0]
    assert good >= 4, report
