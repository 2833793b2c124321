"""The expected-colour fills: normalised convolution and the facade's periods."""

from __future__ import annotations

import numpy as np

from facadeforge.repair.smooth import expected_fill, facade_periods, normalized_fill, period_fill


def _grid(h=300, w=360, py=60, px=45, seed=0):
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float32)
    img[:] = (200, 185, 160)
    for y0 in range(20, h - 40, py):
        for x0 in range(10, w - 30, px):
            img[y0:y0 + 35, x0:x0 + 22] = (50, 60, 80)
    img += rng.normal(0, 3, (h, w, 1))
    return np.clip(img, 0, 255).astype(np.uint8)


def _psnr(a, b, m):
    err = ((a[m].astype(float) - b[m].astype(float)) ** 2).mean()
    return 10 * np.log10(255 ** 2 / max(err, 1e-9))


def test_periods_of_a_window_grid():
    img = _grid()
    hole = np.zeros(img.shape[:2], bool)
    hole[180:260, 100:220] = True
    ty, tx = facade_periods(img, hole)
    assert ty == 60 and tx == 45


def test_period_fill_restores_hidden_windows():
    import cv2

    img = _grid()
    hole = np.zeros(img.shape[:2], bool)
    hole[150:240, 90:200] = True
    occ = img.copy()
    occ[hole] = (30, 120, 40)
    per, got = period_fill(occ, hole)
    assert got[hole].all()
    ours = _psnr(per, img, hole)
    telea = _psnr(cv2.inpaint(occ, hole.astype(np.uint8), 5, cv2.INPAINT_TELEA), img, hole)
    assert ours > 30 and ours > telea + 10, (ours, telea)
    assert np.array_equal(per[~hole], occ[~hole].astype(np.float32))


def test_normalized_fill_is_smooth_and_bounded():
    img = np.zeros((100, 100, 3), np.uint8)
    img[:, :50] = 40
    img[:, 50:] = 200
    hole = np.zeros((100, 100), bool)
    hole[30:70, 30:70] = True
    out = normalized_fill(img, hole)
    assert out.min() >= 40 - 1e-3 and out.max() <= 200 + 1e-3
    row = out[50, 30:70, 0]
    assert (np.diff(row) >= -1e-3).all()          # monotone from the dark side to the light
    assert np.array_equal(out[~hole], img[~hole].astype(np.float32))
    all_hidden = normalized_fill(img, np.ones((100, 100), bool))
    assert np.allclose(all_hidden, 128.0)


def test_expected_fill_blends_both():
    img = _grid(seed=1)
    hole = np.zeros(img.shape[:2], bool)
    hole[150:240, 90:200] = True
    occ = img.copy()
    occ[hole] = 0
    e0 = expected_fill(occ, hole, period_weight=0.0)
    e1 = expected_fill(occ, hole, period_weight=1.0)
    e5 = expected_fill(occ, hole, period_weight=0.5)
    assert np.allclose(e0, normalized_fill(occ, hole))
    assert np.allclose(e5[hole], 0.5 * (e0[hole] + e1[hole]), atol=1e-3)
    assert _psnr(e1, img, hole) > _psnr(e0, img, hole)
