"""frames.warp: OpenCV's warpPerspective under the pixel-edge convention, any channel count."""

from __future__ import annotations

import numpy as np

from facadeforge.frames import warp


def test_an_integer_shift_moves_pixels_exactly_in_every_channel():
    rng = np.random.default_rng(0)
    img = rng.random((20, 30, 6)).astype(np.float32)
    shift = np.array([[1, 0, 3], [0, 1, 2], [0, 0, 1.0]])        # 3 right, 2 down
    for nearest in (False, True):
        out = warp(img, shift, (25, 35), nearest=nearest)
        assert out.shape == (25, 35, 6) and out.dtype == np.float32
        np.testing.assert_allclose(out[2:22, 3:33], img, atol=1e-6)
        assert not out[:2].any() and not out[:, :3].any()        # outside the source: 0
    one = warp(img[:, :, :1], shift, (25, 35))
    assert one.shape == (25, 35, 1)
    assert warp(img[:, :, 0], shift, (25, 35)).shape == (25, 35)


def test_a_two_times_scale_keeps_pixel_edges_on_pixel_edges():
    labels = np.arange(12, dtype=np.uint8).reshape(3, 4)
    up = warp(labels, np.diag([2.0, 2.0, 1.0]), (6, 8), nearest=True)
    np.testing.assert_array_equal(up, np.kron(labels, np.ones((2, 2), np.uint8)))
