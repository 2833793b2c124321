"""The expected colour of hidden facade pixels: smooth interpolation from the surroundings and
the facade's own periodicity.

A texture fill (quilting, PatchMatch) paints *a* plausible facade behind a tree; its details
are in the wrong phase wherever the truth is not predictable, and each of them then costs
twice its contrast in error.  The estimate with the least expected error is the conditional
mean, which this module approximates with two predictors whose errors are little correlated:

- :func:`normalized_fill` — normalised convolution at growing scales (Knutsson & Westin 1993):
  each hidden pixel is the Gaussian-weighted mean of the visible pixels at the smallest scale
  that sees enough of them (a pull–push interpolation, smoother and less streaky than
  OpenCV's Telea/Navier–Stokes fills);
- :func:`period_fill` — the facade's vertical and horizontal periods (floors, window axes) from
  the masked autocorrelation of the gradient profiles; each hidden pixel is the median of the
  visible pixels one, two, … periods above, below, left and right of it (what repetition says
  is there, aligned to the pixel).

:func:`expected_fill` blends them with weights chosen on CMP *train* facades with LabelMeFacade
*train* occluders (``benchmarks/repair.py --tune``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["PERIOD_WEIGHT", "expected_fill", "facade_periods", "normalized_fill", "period_fill"]

#: Weight of :func:`period_fill` in :func:`expected_fill` (the rest is :func:`normalized_fill`).
PERIOD_WEIGHT: float = 0.3


def normalized_fill(rgb: np.ndarray, hole: np.ndarray,
                    sigmas: tuple[float, ...] = (2, 4, 8, 16, 32, 64, 128),
                    support: float = 0.05) -> np.ndarray:
    """``rgb`` (H, W, 3) with ``hole`` pixels replaced by the normalised convolution of the
    visible ones at the smallest ``sigma`` whose Gaussian weight of visible pixels reaches
    ``support``; float32."""
    import cv2

    img = rgb.astype(np.float32)
    w = (~hole).astype(np.float32)
    out = img.copy()
    todo = hole.copy()
    for s in sigmas:
        if not todo.any():
            break
        num = cv2.GaussianBlur(img * w[..., None], (0, 0), s)
        den = cv2.GaussianBlur(w, (0, 0), s)
        ok = todo & (den > support)
        out[ok] = num[ok] / den[ok, None]
        todo &= ~ok
    if todo.any():
        out[todo] = img[~hole].mean(axis=0) if (~hole).any() else 128.0
    return out


def _period(gray: np.ndarray, known: np.ndarray, axis: int, lo: int, hi: int) -> int | None:
    """The lag in ``[lo, hi)`` of the best normalised autocorrelation of the mean gradient
    profile along ``axis`` (visible pixels only); ``None`` when the profile is too short."""
    g = np.abs(np.diff(gray, axis=axis, prepend=gray.take([0], axis=axis))) * known
    w = known.sum(axis=1 - axis).astype(np.float64)
    prof = g.sum(axis=1 - axis) / np.maximum(w, 1.0)
    prof = prof - prof.mean()
    hi = min(hi, len(prof) // 2)
    best, lag = -np.inf, None
    for t in range(lo, hi):
        a, b = prof[:-t], prof[t:]
        c = float((a * b).sum() / (np.sqrt((a * a).sum() * (b * b).sum()) + 1e-9))
        if c > best:
            best, lag = c, t
    return lag


def facade_periods(rgb: np.ndarray, hole: np.ndarray) -> tuple[int | None, int | None]:
    """``(vertical, horizontal)`` periods in pixels (a floor, a window axis) of the visible
    facade; lags from 1/20 (vertical) and 1/30 (horizontal) of the side to a half and a third."""
    gray = rgb.astype(np.float32).mean(axis=2)
    known = ~hole
    h, w = hole.shape
    return (_period(gray, known, 0, max(8, h // 20), h // 2),
            _period(gray, known, 1, max(6, w // 30), w // 3))


def period_fill(rgb: np.ndarray, hole: np.ndarray, *, reach: int = 4
                ) -> tuple[np.ndarray, np.ndarray]:
    """Each hidden pixel as the per-channel median of the visible pixels up to ``reach``
    periods away along the facade's axes (:func:`facade_periods`).  Returns the float32 image
    and the hidden pixels that got a value (those no shifted copy sees keep their colour)."""
    h, w = hole.shape
    ty, tx = facade_periods(rgb, hole)
    shifts = [(k * ty, 0) for k in range(-reach, reach + 1) if k and ty] + \
             [(0, k * tx) for k in range(-reach, reach + 1) if k and tx]
    img = rgb.astype(np.float32)
    out = img.copy()
    ys, xs = np.nonzero(hole)
    if not shifts or not len(ys):
        return out, np.zeros_like(hole)
    cand = np.full((len(shifts), len(ys), 3), np.nan, np.float32)
    for i, (dy, dx) in enumerate(shifts):
        y, x = ys + dy, xs + dx
        ok = (y >= 0) & (y < h) & (x >= 0) & (x < w)
        ok[ok] &= ~hole[y[ok], x[ok]]
        cand[i, ok] = img[y[ok], x[ok]]
    seen = ~np.isnan(cand[:, :, 0]).all(axis=0)
    med = np.zeros((len(ys), 3), np.float32)
    if seen.any():
        med[seen] = np.nanmedian(cand[:, seen], axis=0)
    got = np.zeros_like(hole)
    got[ys[seen], xs[seen]] = True
    out[ys[seen], xs[seen]] = med[seen]
    return out, got


def expected_fill(rgb: np.ndarray, hole: np.ndarray, *,
                  period_weight: float = PERIOD_WEIGHT) -> np.ndarray:
    """The blend ``(1 − period_weight) · normalized_fill + period_weight · period_fill`` over
    the hole (pixels no period sees: the normalised fill alone); float32 (H, W, 3)."""
    smooth = normalized_fill(rgb, hole)
    if period_weight <= 0:
        return smooth
    per, got = period_fill(rgb, hole)
    out = smooth.copy()
    out[got] = (1 - period_weight) * smooth[got] + period_weight * per[got]
    return out
