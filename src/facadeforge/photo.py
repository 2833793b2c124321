"""Facade photos as the analysis commands take them (``reconstruct``, ``parse``): read from a
path or any image array into RGB uint8, checked for a usable size, and downscaled to an
analysis copy when huge (with the pixel homography that maps back)."""

from __future__ import annotations

import os

import numpy as np

from .errors import InputError

__all__ = ["MAX_ANALYSIS_SIDE", "MIN_SIDE", "analysis_copy", "as_rgb", "check_facade_size",
           "check_size"]

#: Photos with a longer side are analysed at this size (the homography maps back).
MAX_ANALYSIS_SIDE: int = 1600
#: Smallest photo side we analyse (a floor needs a few rows of pixels).
MIN_SIDE: int = 64


def as_rgb(photo) -> tuple[np.ndarray, str]:
    """(H, W, 3) uint8 and a name for messages, from a path or any image array (gray, RGBA,
    16-bit and float images are converted)."""
    if isinstance(photo, (str, os.PathLike)):
        from .datasets.folder import read_image

        if os.path.isdir(photo):   # else reported as missing: the reader wants a file
            raise InputError(f"photo {photo} is a folder, not an image file; give one photo "
                             f"in it, e.g. {_example_in(photo)}")
        return read_image(photo), str(photo)
    from .imaging.rectify import to_rgb8

    a = np.asarray(photo)
    if a.dtype == object:
        raise InputError("photo array holds Python objects; pass a numeric (H, W[, C]) array")
    return to_rgb8(a), "<array>"


def check_size(rgb: np.ndarray, name: str) -> None:
    """Refuse photos with a side shorter than :data:`MIN_SIDE`."""
    h, w = rgb.shape[:2]
    if min(h, w) < MIN_SIDE:
        raise InputError(f"photo {name} is only {w}x{h} px; facade analysis needs at least "
                         f"{MIN_SIDE} px per side (use a larger or less cropped photo)")


def check_facade_size(width_m, height_m) -> None:
    """Refuse ``--width-m`` / ``--height-m`` values that are not facade sizes."""
    for name, v in (("--width-m", width_m), ("--height-m", height_m)):
        if v is not None and not (np.isfinite(v) and 1.0 <= v <= 1000.0):
            raise InputError(f"{name} {v} is not a facade size; give metres between 1 and 1000")


def analysis_copy(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Downscale huge photos to :data:`MAX_ANALYSIS_SIDE`; returns the copy and the
    input→copy pixel homography."""
    h, w = rgb.shape[:2]
    f = min(1.0, MAX_ANALYSIS_SIDE / max(h, w))
    if f >= 1.0:
        return rgb, np.eye(3)
    import cv2

    size = (max(1, round(w * f)), max(1, round(h * f)))
    small = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    sx, sy = size[0] / w, size[1] / h
    return small, np.diag([sx, sy, 1.0])


def _example_in(folder) -> str:
    """An image file of ``folder`` to suggest in a message (a made-up name when it has none)."""
    from pathlib import Path

    suffixes = {".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp"}
    try:
        names = sorted(p for p in Path(folder).iterdir()
                       if p.suffix.lower() in suffixes and p.is_file())
    except OSError:
        names = []
    return str(names[0] if names else Path(folder) / "facade.jpg")
