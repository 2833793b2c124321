"""Per-pixel feature maps for the forest classifiers, computed at one analysis scale.

Three families, all ``(h, w, F)`` float32 maps of the photo resized to :data:`ANALYSIS_SIDE`:

- :func:`patch_tests` — the randomised-forest tests of ``simon2011`` §4.3.1: inside a square patch
  around the pixel, the difference of two pixel values or one pixel value (to be compared with a
  threshold by the tree).  The tests are drawn once from a seed and stored with the model, so a
  tree node "compares two pixels of the patch" exactly as in the thesis.
- :func:`appearance_features` — a small filter bank (CIE-Lab colour at four blur scales,
  gradient magnitudes, oriented gradient energies, Laplacian-of-Gaussian, local contrast), the
  pixel's normalised position, and row/column profiles of edge energy: floors and window columns
  are long horizontal and vertical structures, so a pixel's row and column say much about it.
- :func:`context_features` — auto-context (Tu & Bai 2010; Jampani, Gadde & Gehler 2015 for
  facades): a previous stage's class probabilities at the pixel, at eight offsets around it, and
  averaged along its row and its column.  A window pixel sits in a row and a column of windows.

Everything is plain OpenCV/numpy filtering of whole images: a 320-px photo takes a few
milliseconds per family.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["ANALYSIS_SIDE", "analysis_image", "appearance_features", "context_features",
           "draw_patch_tests", "patch_tests", "resize_proba"]

#: Long side (pixels) of the image the classifiers see; probabilities are resized back.
ANALYSIS_SIDE: int = 320

#: Offsets (pixels at analysis scale) at which context features sample the previous stage.
CONTEXT_OFFSETS: tuple[int, ...] = (4, 12)


def analysis_image(rgb: np.ndarray, side: int = ANALYSIS_SIDE) -> np.ndarray:
    """``rgb`` (uint8) resized so its long side is ``side`` (area averaging when shrinking)."""
    h, w = rgb.shape[:2]
    s = side / max(h, w)
    size = (max(8, round(w * s)), max(8, round(h * s)))
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    return cv2.resize(rgb, size, interpolation=interp)


def resize_proba(prob: np.ndarray, shape: tuple[int, int], *,
                 interpolation: int = cv2.INTER_LINEAR, normalise: bool = True) -> np.ndarray:
    """``(h, w, K)`` probabilities resized to ``shape`` = (H, W) float32 (bilinear by default;
    ``cv2.INTER_AREA`` to shrink), rows renormalised to sum to one unless ``normalise=False``."""
    H, W = shape
    k = prob.shape[2]
    out = np.empty((H, W, k), np.float32)
    for c0 in range(0, k, 4):  # cv2.resize handles at most 4 channels reliably
        c1 = min(k, c0 + 4)
        chunk = cv2.resize(np.ascontiguousarray(prob[:, :, c0:c1], np.float32), (W, H),
                           interpolation=interpolation)
        out[:, :, c0:c1] = chunk.reshape(H, W, c1 - c0)
    if normalise:
        out /= np.maximum(out.sum(axis=2, keepdims=True), 1e-12)
    return out


def _lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB).astype(np.float32)


def _blur(a: np.ndarray, sigma: float) -> np.ndarray:
    return cv2.GaussianBlur(a, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)


# ------------------------------------------------------------------------------- patch tests
def draw_patch_tests(n: int, radius: int = 7, seed: int = 0) -> np.ndarray:
    """``(n, 5)`` int16 tests ``(dy1, dx1, dy2, dx2, channel)``; ``dy2 = dx2 = 127`` marks a
    single-pixel test.  Half are two-pixel differences, half single pixels (§4.3.1)."""
    rng = np.random.default_rng(seed)
    tests = rng.integers(-radius, radius + 1, size=(n, 5)).astype(np.int16)
    tests[:, 4] = rng.integers(0, 3, size=n)
    tests[n // 2:, 2:4] = 127
    return tests


def _shift(a: np.ndarray, dy: int, dx: int, radius: int) -> np.ndarray:
    """``a`` (padded by ``radius``) read at offset (dy, dx) for every pixel of the unpadded map."""
    h = a.shape[0] - 2 * radius
    w = a.shape[1] - 2 * radius
    return a[radius + dy:radius + dy + h, radius + dx:radius + dx + w]


def patch_tests(rgb: np.ndarray, tests: np.ndarray) -> np.ndarray:
    """``(h, w, n)`` values of the patch ``tests`` on analysis image ``rgb`` (Lab, blurred σ = 1
    to tame JPEG noise; borders reflected)."""
    lab = _blur(_lab(rgb), 1.0)
    r = int(np.abs(tests[:, :4][tests[:, :4] != 127]).max(initial=0))
    pad = cv2.copyMakeBorder(lab, r, r, r, r, cv2.BORDER_REFLECT)
    h, w = rgb.shape[:2]
    out = np.empty((h, w, len(tests)), np.float32)
    for i, (dy1, dx1, dy2, dx2, ch) in enumerate(tests.tolist()):
        v = _shift(pad[:, :, ch], dy1, dx1, r)
        if dy2 != 127:
            v = v - _shift(pad[:, :, ch], dy2, dx2, r)
        out[:, :, i] = v
    return out


# ------------------------------------------------------------------------------ appearance
APPEARANCE_NAMES: tuple[str, ...] = (
    *(f"lab{c}_s{s}" for s in (0, 2, 4, 8) for c in "Lab"),
    "grad_s1", "grad_s2", "grad_s4", "gx_s2", "gy_s2", "gx_s6", "gy_s6",
    "log_s2", "log_s4", "log_s8", "std_s4", "pos_y", "pos_x",
    "row_gx", "col_gy", "row_L", "col_L",
)


def appearance_features(rgb: np.ndarray) -> np.ndarray:
    """``(h, w, len(APPEARANCE_NAMES))`` filter-bank features of analysis image ``rgb``."""
    h, w = rgb.shape[:2]
    lab = _lab(rgb)
    feats = [lab]
    for s in (2, 4, 8):
        feats.append(_blur(lab, s))
    L = lab[:, :, 0]
    for s in (1, 2, 4):
        Ls = _blur(L, s)
        gx = cv2.Sobel(Ls, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(Ls, cv2.CV_32F, 0, 1, ksize=3)
        feats.append(np.sqrt(gx * gx + gy * gy)[:, :, None])
    L1 = _blur(L, 1)
    ax = np.abs(cv2.Sobel(L1, cv2.CV_32F, 1, 0, ksize=3))
    ay = np.abs(cv2.Sobel(L1, cv2.CV_32F, 0, 1, ksize=3))
    for s in (2, 6):
        feats.append(_blur(ax, s)[:, :, None])
        feats.append(_blur(ay, s)[:, :, None])
    for s in (2, 4, 8):
        feats.append((cv2.Laplacian(_blur(L, s), cv2.CV_32F) * s * s)[:, :, None])
    mean = _blur(L, 4)
    var = np.maximum(_blur(L * L, 4) - mean * mean, 0)
    feats.append(np.sqrt(var)[:, :, None])
    yy, xx = np.meshgrid((np.arange(h, dtype=np.float32) + 0.5) / h,
                         (np.arange(w, dtype=np.float32) + 0.5) / w, indexing="ij")
    feats += [yy[:, :, None], xx[:, :, None]]
    row_gx = ax.mean(axis=1)
    col_gy = ay.mean(axis=0)
    feats.append(np.broadcast_to((row_gx / (row_gx.mean() + 1e-6))[:, None, None], (h, w, 1)))
    feats.append(np.broadcast_to((col_gy / (col_gy.mean() + 1e-6))[None, :, None], (h, w, 1)))
    feats.append(np.broadcast_to(L.mean(axis=1)[:, None, None], (h, w, 1)))
    feats.append(np.broadcast_to(L.mean(axis=0)[None, :, None], (h, w, 1)))
    return np.concatenate(feats, axis=2).astype(np.float32)


# --------------------------------------------------------------------------------- context
def context_features(prob: np.ndarray) -> np.ndarray:
    """``(h, w, 11 K)`` auto-context features of a previous stage's ``(h, w, K)`` probabilities."""
    h, w, k = prob.shape
    p = np.empty_like(prob)
    for c in range(k):
        p[:, :, c] = cv2.blur(prob[:, :, c], (3, 3), borderType=cv2.BORDER_REFLECT)
    r = max(CONTEXT_OFFSETS)
    pad = np.pad(p, ((r, r), (r, r), (0, 0)), mode="edge")
    feats = [p]
    for d in CONTEXT_OFFSETS:
        for dy, dx in ((-d, 0), (d, 0), (0, -d), (0, d)):
            feats.append(pad[r + dy:r + dy + h, r + dx:r + dx + w])
    feats.append(np.broadcast_to(p.mean(axis=1)[:, None, :], (h, w, k)))
    feats.append(np.broadcast_to(p.mean(axis=0)[None, :, :], (h, w, k)))
    return np.concatenate(feats, axis=2).astype(np.float32)
