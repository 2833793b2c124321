"""Occlusion masks: what stands in front of a facade (Shang 2023 §3.1: "we identify occluded
regions based on semantics"), from a user's mask, from occluder labels in a label map, from a
pixel classifier's occluder classes, and from the facade's own repetition (an instance of a
repeated element that differs from its siblings where the classifier also suspects an occluder).

Arrays in, arrays out: masks are ``(H, W)`` bool, True = occluded (to be repaired).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError

__all__ = ["OCCLUDERS", "clean_mask", "mask_from_labels", "occluder_probability", "read_mask",
           "repetition_breaks"]

#: Canonical labels that occlude a facade: what is in front of it, not part of it.
OCCLUDERS: tuple[str, ...] = ("vegetation", "car", "person")


def read_mask(mask, shape: tuple[int, int], name: str = "--mask") -> np.ndarray:
    """A user's mask as ``(H, W)`` bool: a path (grey, black-and-white or RGB PNG) or an array
    (an RGBA array's alpha counts when it is not all opaque); non-zero = occluded.  It must
    have the photo's size."""
    if isinstance(mask, (str, bytes)) or hasattr(mask, "__fspath__"):
        from ..datasets.folder import read_label_image

        arr = read_label_image(mask)
    else:
        arr = np.asarray(mask)
    if arr.dtype == object or arr.ndim not in (2, 3):
        raise InputError(f"{name}: expected an (H, W) or (H, W, C) image, got shape "
                         f"{getattr(arr, 'shape', '?')}; give a black-and-white PNG, white = "
                         "occluded")
    if arr.ndim == 3:
        if arr.shape[2] == 4 and arr[..., 3].min() < arr[..., 3].max():
            arr = arr[..., 3]
        else:
            arr = arr[..., :3].max(axis=2)
    if arr.shape[:2] != tuple(shape):
        raise InputError(f"{name} is {arr.shape[1]}x{arr.shape[0]} px but the photo is "
                         f"{shape[1]}x{shape[0]}; draw the mask on the photo itself (same size)")
    out = np.asarray(arr) > (0.5 if arr.dtype.kind == "f" else 0)
    return out


def mask_from_labels(labels: np.ndarray, occluders: Sequence[int]) -> np.ndarray:
    """Pixels of a class-index map whose class is one of ``occluders`` (class indices)."""
    return np.isin(labels, np.asarray(list(occluders), dtype=np.int64))


def occluder_probability(prob: np.ndarray, classes: Sequence[str],
                         occluders: Sequence[str] = OCCLUDERS) -> np.ndarray:
    """``(H, W)`` float32: the summed probability of the occluder classes of a classifier's
    ``(H, W, K)`` output (``classes`` names its channels, canonical labels); zeros when the
    classifier knows none of them."""
    idx = [i for i, c in enumerate(classes) if c in occluders]
    if not idx:
        return np.zeros(prob.shape[:2], np.float32)
    return prob[:, :, idx].sum(axis=2).astype(np.float32)


def clean_mask(mask: np.ndarray, *, min_area: float = 0.002, grow: float = 0.006) -> np.ndarray:
    """A detected mask made usable for repair: components smaller than ``min_area`` of the
    image dropped (specks of green wall), holes inside a component closed, and the mask grown
    by ``grow`` of the image diagonal (at least 2 px) so an occluder's soft edge and its
    shadow-free halo are repaired too — a repair that leaves the rim of a car shows it."""
    import cv2
    from scipy import ndimage

    m = np.asarray(mask, bool)
    if not m.any():
        return m.copy()
    h, w = m.shape
    n, comp, stats, _ = cv2.connectedComponentsWithStats(m.astype(np.uint8), connectivity=8)
    keep = np.zeros(n, bool)
    keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= min_area * h * w
    m = keep[comp]
    m = ndimage.binary_fill_holes(m)
    r = max(2, int(round(grow * np.hypot(h, w))))
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(m.astype(np.uint8), k).astype(bool)


def repetition_breaks(rgb: np.ndarray, groups: Sequence[Sequence[tuple[int, int, int, int]]],
                      *, k: float = 3.0, min_instances: int = 3) -> np.ndarray:
    """``(H, W)`` bool: pixels of a repeated element that break its cluster's repetition — the
    colour is more than ``k`` robust deviations (MAD) from the per-pixel median of the
    cluster's instances (each resampled to the median size).  An occluder in front of one
    window of a row shows here; a real difference between instances (an open shutter) shows
    too, so this is evidence to combine with a classifier's, not a mask on its own."""
    import cv2

    out = np.zeros(rgb.shape[:2], bool)
    img = rgb.astype(np.float32)
    for boxes in groups:
        boxes = [b for b in boxes if b[2] - b[0] >= 3 and b[3] - b[1] >= 3]
        if len(boxes) < min_instances:
            continue
        ws = int(np.median([b[2] - b[0] for b in boxes]))
        hs = int(np.median([b[3] - b[1] for b in boxes]))
        stack = np.stack([cv2.resize(img[y0:y1, x0:x1], (ws, hs), interpolation=cv2.INTER_AREA)
                          for x0, y0, x1, y1 in boxes])
        med = np.median(stack, axis=0)
        dev = np.abs(stack - med).sum(axis=3)                  # (n, hs, ws) L1 over RGB
        mad = np.median(dev, axis=0) * 1.4826 + 6.0            # floor: JPEG noise, 2 levels/ch
        for (x0, y0, x1, y1), d in zip(boxes, dev):
            bad = (d > k * mad).astype(np.uint8)
            out[y0:y1, x0:x1] |= cv2.resize(bad, (x1 - x0, y1 - y0),
                                            interpolation=cv2.INTER_NEAREST).astype(bool)
    return out
