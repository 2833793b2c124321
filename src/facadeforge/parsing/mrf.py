"""MRF-Potts segmentation: the pixel-wise baseline that grammar-driven parsing is compared with.

``simon2011`` §4.4.1 ("Comparison with Markov Random Field segmentation") smooths a pixel
classifier's output with a Markov random field on the image grid and compares the result with the
procedural (grammar-driven) segmentation.  The labelling ``c`` minimises eq. 4.14::

    E(c) = sum_{x_i in I} -log p(c_i | f_{x_i})  +  lambda * sum_{x_i ~ x_j} [c_i != c_j]

* **Unary** terms are per pixel: ``-log p(c|f_x)`` read from the classifier's ``(H, W, K)``
  probability map (:meth:`facadeforge.classify.model.PixelClassifier.predict_proba`), with the
  probability clipped to ``[eps, 1]`` so an impossible class costs ``-log(eps)`` instead of
  infinity.
* **Pairwise** terms follow the Potts model on the 4-connected grid: ``smoothness`` (λ) is paid
  once per *unordered* pair of 4-neighbours (each horizontal and each vertical edge) whose labels
  differ.  Eq. 4.14 as printed sums over ``x_i`` and then over ``x_j ~ x_i``, which visits every
  edge twice; the thesis' λ therefore corresponds to ``smoothness = 2 λ`` here.  λ = 0 gives back
  the independent per-pixel (argmax) classification, as the thesis notes.

The energy is minimised approximately by alpha-expansion graph cuts (Boykov, Veksler & Zabih,
TPAMI 2001) from PyMaxflow's :func:`maxflow.fastmin.aexpansion_grid`, started from the argmax
labelling.  Each expansion move never increases the energy, so the result is never worse than
the argmax in the sense of eq. 4.14 (on the grid it was solved on — see below).

**Large photos.**  The cost grows with the number of pixels times the number of classes and
cycles.  When ``H * W > max_pixels``, :func:`potts_labels` area-averages the probability map
down to at most ``max_pixels`` pixels (``cv2.INTER_AREA``, aspect ratio kept), solves the MRF
there and upsamples the labels to ``(H, W)`` by nearest neighbour.  That bounds the time on huge
photos at the price of label boundaries quantised to the coarse grid.  To keep the balance
between the unary and the boundary terms (unaries scale with area, boundaries with length),
λ on the coarse grid is multiplied by the linear scale factor ``s = sqrt(h*w / (H*W))``.  The
"never worse than argmax" guarantee then holds on the coarse grid, not necessarily for the
upsampled labels at full resolution.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from maxflow import fastmin

from ..classify.features import resize_proba
from ..errors import InputError

__all__ = ["potts_energy", "potts_labels"]

_MAX_CLASSES = 256  # labels are returned as uint8


def _check_prob(prob: object, name: str = "prob") -> np.ndarray:
    arr = np.asarray(prob)
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.floating)
                                   or np.issubdtype(arr.dtype, np.integer)):
        raise InputError(f"{name} must be a numeric (H, W, K) array of class probabilities, got "
                         f"dtype {arr.dtype}; pass the output of predict_proba().")
    if arr.ndim != 3:
        raise InputError(f"{name} must have shape (H, W, K) (one probability per class per pixel), "
                         f"got shape {arr.shape}; add a class axis last.")
    h, w, k = arr.shape
    if h < 1 or w < 1:
        raise InputError(f"{name} is empty (shape {arr.shape}); pass a map of at least one pixel.")
    if k < 2:
        raise InputError(f"{name} has K={k} classes; a segmentation needs K >= 2 probability "
                         "channels on the last axis.")
    if k > _MAX_CLASSES:
        raise InputError(f"{name} has K={k} classes; at most {_MAX_CLASSES} are supported "
                         "(labels are uint8) — merge classes first.")
    arr = arr.astype(np.float64, copy=False)
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite values; fix the classifier output "
                         "(e.g. np.nan_to_num) before smoothing.")
    if np.any(arr < 0):
        raise InputError(f"{name} contains negative values (min {float(arr.min()):.3g}); "
                         "probabilities must be >= 0 — pass probabilities, not logits.")
    return arr


def _check_smoothness(smoothness: object) -> float:
    if isinstance(smoothness, bool) or not isinstance(smoothness, (int, float, np.integer,
                                                                   np.floating)):
        raise InputError(f"smoothness must be a real number >= 0 (the Potts λ per 4-neighbour "
                         f"edge), got {smoothness!r}.")
    lam = float(smoothness)
    if not math.isfinite(lam) or lam < 0:
        raise InputError(f"smoothness must be finite and >= 0 (the Potts λ per 4-neighbour "
                         f"edge), got {lam}; use 0 for the plain argmax.")
    return lam


def _check_eps(eps: object) -> float:
    try:
        value = float(eps)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        value = float("nan")
    if not (0 < value < 1):
        raise InputError(f"eps must lie in (0, 1) (the probability floor for -log p), got "
                         f"{eps!r}; the default 1e-4 is a good choice.")
    return value


def _unary(prob: np.ndarray, eps: float) -> np.ndarray:
    # PyMaxflow accepts only float64 (or int) unaries, C order is the safe layout.
    return np.ascontiguousarray(-np.log(np.clip(prob, eps, 1.0)), dtype=np.float64)


def _coarse_shape(h: int, w: int, max_pixels: int) -> tuple[int, int]:
    s = math.sqrt(max_pixels / (h * w))
    ch = min(h, max(1, int(h * s)))
    cw = min(w, max(1, int(w * s)), max(1, max_pixels // ch))
    return ch, cw


def potts_labels(prob: np.ndarray, smoothness: float = 1.0, *, max_cycles: int = 5,
                 eps: float = 1e-4, max_pixels: int = 250_000) -> np.ndarray:
    """Potts-MRF segmentation of a class-probability map (``simon2011`` §4.4.1, eq. 4.14).

    ``prob`` is ``(H, W, K)`` with non-negative probabilities (each pixel's row summing to about
    one); ``smoothness`` is λ, paid once per pair of 4-neighbours with different labels.
    Returns the ``(H, W)`` uint8 labelling found by at most ``max_cycles`` alpha-expansion
    cycles started from the argmax.  ``smoothness=0`` returns exactly ``prob.argmax(-1)``.

    If ``H * W > max_pixels`` the MRF is solved on an area-averaged copy of at most
    ``max_pixels`` pixels (λ scaled by the linear downscale factor) and the labels are
    upsampled by nearest neighbour — this bounds the run time on huge photos.
    """
    arr = _check_prob(prob)
    lam = _check_smoothness(smoothness)
    eps = _check_eps(eps)
    if isinstance(max_cycles, bool) or not isinstance(max_cycles, (int, np.integer)) \
            or max_cycles < 1:
        raise InputError(f"max_cycles must be an integer >= 1 (alpha-expansion cycles), got "
                         f"{max_cycles!r}.")
    if isinstance(max_pixels, bool) or not isinstance(max_pixels, (int, np.integer)) \
            or max_pixels < 1:
        raise InputError(f"max_pixels must be an integer >= 1 (the largest grid solved at full "
                         f"resolution), got {max_pixels!r}.")

    h, w, k = arr.shape
    if lam == 0.0:
        return arr.argmax(axis=2).astype(np.uint8)

    if h * w > max_pixels:
        ch, cw = _coarse_shape(h, w, int(max_pixels))
        work = resize_proba(arr, (ch, cw), interpolation=cv2.INTER_AREA,
                            normalise=False).astype(np.float64)
        lam_work = lam * math.sqrt((ch * cw) / (h * w))
    else:
        ch, cw, work, lam_work = h, w, arr, lam

    unary = _unary(work, eps)
    pairwise = lam_work * (1.0 - np.eye(k, dtype=np.float64))  # Potts: a metric, as required
    # PyMaxflow wants signed integer labels (uint8 is rejected) and edits them in place.
    labels = np.ascontiguousarray(work.argmax(axis=2), dtype=np.int32)
    labels = fastmin.aexpansion_grid(unary, pairwise, max_cycles=int(max_cycles), labels=labels)
    out = np.asarray(labels).astype(np.uint8)
    if (ch, cw) != (h, w):
        out = cv2.resize(out, (w, h), interpolation=cv2.INTER_NEAREST_EXACT)
    return out


def potts_energy(labels: np.ndarray, prob: np.ndarray, smoothness: float,
                 eps: float = 1e-4) -> float:
    """Eq. 4.14 of ``simon2011`` evaluated directly: per-pixel ``-log clip(p, eps, 1)`` of the
    chosen class plus ``smoothness`` times the number of 4-neighbour pairs with different labels
    (each unordered pair counted once)."""
    arr = _check_prob(prob)
    lam = _check_smoothness(smoothness)
    eps = _check_eps(eps)
    lab = np.asarray(labels)
    if lab.shape != arr.shape[:2]:
        raise InputError(f"labels must have the shape of prob without its class axis, "
                         f"{arr.shape[:2]}, got {lab.shape}.")
    if not np.issubdtype(lab.dtype, np.integer):
        raise InputError(f"labels must be an integer array, got dtype {lab.dtype}; "
                         "cast class indices with .astype(int).")
    k = arr.shape[2]
    if lab.size and (lab.min() < 0 or lab.max() >= k):
        raise InputError(f"labels must lie in [0, {k - 1}] (K={k} classes in prob), got range "
                         f"[{int(lab.min())}, {int(lab.max())}].")
    lab = lab.astype(np.intp)
    p = np.take_along_axis(arr, lab[:, :, None], axis=2)[:, :, 0]
    unary = float(-np.log(np.clip(p, eps, 1.0)).sum())
    cuts = int(np.count_nonzero(lab[1:, :] != lab[:-1, :])
               + np.count_nonzero(lab[:, 1:] != lab[:, :-1]))
    return unary + lam * cuts
