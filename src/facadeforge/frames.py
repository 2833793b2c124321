"""Pixel frames: label maps and boxes carried between a photo and another frame of it (a
rectified or cropped facade) through a homography.

Convention everywhere: a homography maps *source-frame* pixel coordinates to *target-frame*
pixel coordinates with pixel edges at integers — pixel ``(r, c)`` covers ``[c, c+1) × [r, r+1)``
and has its centre at ``(c + 0.5, r + 0.5)``.  Used by the benchmark harness (predictions in a
rectified frame scored in the photo's), by ``reconstruct`` and by ``parse`` (results mapped back
to the input photo).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .datasets.labelsets import IGNORE
from .errors import InputError

__all__ = ["box_to_image", "warp", "warp_to_image"]


def _check_homography(h: Any, where: str) -> np.ndarray:
    m = np.asarray(h, np.float64)
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise InputError(f"{where}: homography must be a finite 3x3 matrix, got shape {m.shape}")
    if abs(np.linalg.det(m)) < 1e-12 * max(1.0, float(np.abs(m).max()) ** 3):
        raise InputError(f"{where}: homography is singular; it must map the prediction frame "
                         "onto the photo one-to-one")
    return m


def warp(image: np.ndarray, homography: np.ndarray, shape: tuple[int, int], *,
         nearest: bool = False) -> np.ndarray:
    """OpenCV's ``warpPerspective`` for a homography in this module's pixel-edge convention
    (OpenCV puts pixel centres at integers): ``image`` resampled into an ``(H, W)`` = ``shape``
    target, bilinear (``nearest``: nearest neighbour, for label maps), 0 outside the source.
    Any number of channels (OpenCV handles at most four at a time reliably)."""
    import cv2

    half = np.array([[1, 0, 0.5], [0, 1, 0.5], [0, 0, 1.0]])
    hcv = np.linalg.inv(half) @ np.asarray(homography, np.float64) @ half
    h, w = int(shape[0]), int(shape[1])
    flags = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR

    def one(a: np.ndarray) -> np.ndarray:
        return cv2.warpPerspective(a, hcv, (w, h), flags=flags,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    image = np.asarray(image)
    if image.ndim < 3 or image.shape[2] <= 4:
        return one(image).reshape(h, w, *image.shape[2:])
    out = np.empty((h, w, image.shape[2]), image.dtype)
    for c0 in range(0, image.shape[2], 4):
        c1 = min(image.shape[2], c0 + 4)
        out[:, :, c0:c1] = one(np.ascontiguousarray(image[:, :, c0:c1])).reshape(h, w, c1 - c0)
    return out


def warp_to_image(labels: np.ndarray, homography: np.ndarray, shape: tuple[int, int]
                  ) -> np.ndarray:
    """Resample a label map predicted in another frame into the photo's pixel frame.

    Parameters
    ----------
    labels : (h, w) uint8
        Prediction in its own frame.
    homography : (3, 3) float
        Prediction-frame pixel coordinates → photo pixel coordinates (pixel-edge convention:
        pixel ``(r, c)`` has its centre at ``(c + 0.5, r + 0.5)``).
    shape : (H, W)
        The photo's size.

    Returns
    -------
    (H, W) uint8
        For each photo pixel, the prediction at the inverse-mapped pixel centre (nearest
        neighbour); :data:`~facadeforge.datasets.IGNORE` where that falls outside the prediction or behind the camera.
    """
    labels = np.asarray(labels)
    inv = np.linalg.inv(_check_homography(homography, "warp_to_image"))
    big_h, big_w = int(shape[0]), int(shape[1])
    ph, pw = labels.shape
    out = np.full((big_h, big_w), IGNORE, np.uint8)
    if big_h == 0 or big_w == 0 or ph == 0 or pw == 0:
        return out
    xs = np.arange(big_w, dtype=np.float64) + 0.5
    centre = inv @ np.array([big_w / 2, big_h / 2, 1.0])
    sign = 1.0 if centre[2] >= 0 else -1.0  # the side of the plane the photo sees
    step = max(1, (1 << 22) // max(big_w, 1))  # rows per block: bounded temporary memory
    for r0 in range(0, big_h, step):
        ys = np.arange(r0, min(big_h, r0 + step), dtype=np.float64)[:, None] + 0.5
        z = (inv[2, 0] * xs + inv[2, 1] * ys + inv[2, 2]) * sign
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (inv[0, 0] * xs + inv[0, 1] * ys + inv[0, 2]) * sign / z
            v = (inv[1, 0] * xs + inv[1, 1] * ys + inv[1, 2]) * sign / z
        ok = (z > 1e-12) & (u >= 0) & (u < pw) & (v >= 0) & (v < ph)
        block = out[r0:r0 + ys.shape[0]]
        block[ok] = labels[v[ok].astype(np.intp), u[ok].astype(np.intp)]
    return out


def box_to_image(boxes: np.ndarray, homography: np.ndarray, shape: tuple[int, int]
                 ) -> np.ndarray:
    """Map boxes from a prediction frame into the photo: bounding box of the mapped corners.

    Parameters
    ----------
    boxes : (N, 4) float
        ``x0, y0, x1, y1`` in prediction-frame pixels.
    homography : (3, 3) float
        Prediction frame → photo (as in :func:`warp_to_image`).
    shape : (H, W)
        The photo's size; boxes are clipped to it.

    Returns
    -------
    (N, 4) float64
    """
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    if b.shape[0] == 0:
        return b
    m = _check_homography(homography, "box_to_image")
    corners = np.stack([b[:, [0, 1]], b[:, [2, 1]], b[:, [0, 3]], b[:, [2, 3]]], axis=1)
    pts = np.concatenate([corners, np.ones((*corners.shape[:2], 1))], axis=2) @ m.T
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = pts[..., :2] / pts[..., 2:3]
    xy = np.nan_to_num(xy, nan=0.0, posinf=1e12, neginf=-1e12)
    out = np.concatenate([xy.min(axis=1), xy.max(axis=1)], axis=1)
    h, w = shape
    out[:, [0, 2]] = np.clip(out[:, [0, 2]], 0, w)
    out[:, [1, 3]] = np.clip(out[:, [1, 3]], 0, h)
    return out
