"""Rectification (Müller 2007 App. A) against synthetic facades with a known homography."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets.synthetic import generate
from facadeforge.errors import InputError
from facadeforge.imaging.rectify import (
    Rectification,
    detect_segments,
    rectify,
    rectifying_homography,
    segment_geometry,
    vanishing_points,
)

RUEMONGE = Path("/work/shared/data/ruemonge/train/img")


def _apply(H, pts):
    p = np.c_[np.asarray(pts, float), np.ones(len(pts))] @ H.T
    return p[:, :2] / p[:, 2:3]


def _rectangle_error_deg(quad: np.ndarray) -> float:
    """Largest deviation (degrees) of the edges of quad (TL, TR, BR, BL) from → ↓ ← ↑."""
    worst = 0.0
    for k, target in enumerate((0.0, 90.0, 180.0, -90.0)):
        d = quad[(k + 1) % 4] - quad[k]
        ang = np.degrees(np.arctan2(d[1], d[0]))
        worst = max(worst, abs((ang - target + 180.0) % 360.0 - 180.0))
    return worst


def _load(photo: Path):
    meta = json.loads(photo.with_suffix(".meta.json").read_text())
    return np.asarray(Image.open(photo).convert("RGB")), meta


@pytest.fixture(scope="module")
def perspective_set(tmp_path_factory):
    out = tmp_path_factory.mktemp("persp")
    return [_load(p) for p in generate(6, 11, out, perspective=True, size=280)]


@pytest.fixture(scope="module")
def flat_set(tmp_path_factory):
    out = tmp_path_factory.mktemp("flat")
    return [_load(p) for p in generate(2, 5, out, perspective=False, size=260)]


def test_perspective_facades_come_out_rectangular(perspective_set):
    for img, meta in perspective_set:
        h, w = img.shape[:2]
        res = rectify(img)
        assert res, res.reason
        assert 0.0 < res.confidence <= 1.0
        # generator H: rectified -> photo; ours: photo -> rectified
        both = res.homography @ np.asarray(meta["homography"], float)
        quad = _apply(both, [[0, 0], [w, 0], [w, h], [0, h]])
        assert _rectangle_error_deg(quad) < 3.0, meta["name"]
        assert np.allclose(res.homography @ res.inverse, np.eye(3), atol=1e-8)
        # positive orientation, sensible size
        x, y = quad[:, 0], quad[:, 1]
        assert np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) > 0
        rh, rw = res.image.shape[:2]
        assert res.image.dtype == np.uint8 and res.image.shape[2] == 3
        assert 0.2 * w * h < rh * rw < 4.0 * w * h


def test_uncropped_output_covers_warped_input(perspective_set):
    img, _ = perspective_set[0]
    h, w = img.shape[:2]
    res = rectify(img, crop=False)
    quad = res.to_rectified([[0, 0], [w, 0], [w, h], [0, h]])
    rh, rw = res.image.shape[:2]
    assert quad.min() > -1e-6
    assert quad[:, 0].max() <= rw + 1e-6 and quad[:, 1].max() <= rh + 1e-6
    assert np.allclose(res.to_input(res.to_rectified([[10.0, 20.0]])), [[10.0, 20.0]])


def test_rectified_facade_stays_rectified(flat_set):
    for img, _ in flat_set:
        h, w = img.shape[:2]
        res = rectify(img)
        assert res, res.reason
        quad = res.to_rectified([[0, 0], [w, 0], [w, h], [0, h]])
        assert _rectangle_error_deg(quad) < 2.0


def test_blank_image_fails_with_reason():
    res = rectify(np.full((200, 160, 3), 128, np.uint8))
    assert not res
    assert isinstance(res, Rectification) and "segments" in res.reason
    assert np.array_equal(res.homography, np.eye(3))
    assert res.image.shape == (200, 160, 3)


def test_tiny_image_fails_cleanly():
    try:
        res = rectify(np.zeros((8, 8, 3), np.uint8))
    except InputError:
        return
    assert not res and res.reason


def test_bad_shapes_raise():
    with pytest.raises(InputError):
        rectify(np.zeros((10, 10, 3, 2), np.uint8))


def test_gray_rgba_and_16bit_inputs(flat_set):
    img, _ = flat_set[0]
    gray = img.mean(axis=2).astype(np.uint8)
    rgba = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    deep = img.astype(np.uint16) * 257
    for x in (gray, rgba, deep):
        res = rectify(x)
        assert res, res.reason
        assert res.image.ndim == 3 and res.image.shape[2] == 3 and res.image.dtype == np.uint8


def test_segments_and_geometry(flat_set):
    img, _ = flat_set[0]
    segs = detect_segments(img[:, :, 0])
    assert segs.ndim == 2 and segs.shape[1] == 4 and len(segs) > 20
    lengths, angles = segment_geometry(segs)
    assert np.all(np.diff(lengths) <= 1e-9) and np.all((angles >= 0) & (angles < np.pi))


def test_parallel_lines_give_points_at_infinity():
    rng = np.random.default_rng(3)
    xs = rng.uniform(10, 290, 15)
    vert = np.c_[xs, np.full(15, 20.0), xs, np.full(15, 180.0)]
    ys = rng.uniform(10, 190, 15)
    hor = np.c_[np.full(15, 20.0), ys, np.full(15, 280.0), ys]
    vv, vh = vanishing_points(np.r_[vert, hor], image_shape=(200, 300), rng=0)
    assert abs(vv[2]) < 1e-6 and abs(vv[0]) < 1e-6
    assert abs(vh[2]) < 1e-6 and abs(vh[1]) < 1e-6
    H = rectifying_homography(vv, vh, (200, 300))
    assert np.allclose(H[2], [0, 0, 1], atol=1e-9)
    assert np.allclose(H[:2, :2], np.eye(2) * H[0, 0], atol=1e-9) and H[0, 0] > 0


def test_converging_verticals():
    # lines through a vertical VP at (150, -2000): the rectified versions are vertical
    vp = np.array([150.0, -2000.0, 1.0])
    bottoms = np.c_[np.linspace(20, 280, 12), np.full(12, 190.0)]
    tops = bottoms + (vp[:2] - bottoms) * (160.0 / 2190.0)
    vert = np.c_[tops, bottoms]
    ys = np.linspace(15, 185, 12)
    hor = np.c_[np.full(12, 10.0), ys, np.full(12, 290.0), ys]
    vv, vh = vanishing_points(np.r_[vert, hor], image_shape=(200, 300), rng=1)
    assert np.allclose(vv[:2] / vv[2], vp[:2], rtol=1e-3)
    H = rectifying_homography(vv, vh, (200, 300))
    a, b = _apply(H, vert[:, 0:2]), _apply(H, vert[:, 2:4])
    assert np.allclose(a[:, 0], b[:, 0], atol=1e-6)


@pytest.mark.skipif(not RUEMONGE.is_dir(), reason="RueMonge not present")
def test_ruemonge_photos():
    photos = sorted(RUEMONGE.glob("*.jpg"))[:2]
    if not photos:
        pytest.skip("no RueMonge photos")
    for p in photos:
        img = np.asarray(Image.open(p).convert("RGB"))
        res = rectify(img)
        assert res, res.reason
        assert res.confidence > 0.3
