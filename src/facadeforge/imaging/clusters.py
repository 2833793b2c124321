"""Groups of similar floors and tiles (Müller et al. 2007, §2.3 and §3).

The irreducible facade of §2.3 stacks rows and columns that repeat; the groups it implies —
*which tiles look alike* — drive split synchronisation (§3.2), element matching per cluster
(§4, eq. 8) and the repeats of the extracted rules (§5).  Stage 1 of this package finds floors
and tiles by split lines, so the groups are recovered here directly: every region is resampled
to a small canonical patch, normalised (zero mean, unit norm) and regions are joined by
average-linkage agglomerative clustering on ``1 − NCC`` (normalised cross-correlation), cut at
a fixed distance.  NCC on normalised patches is invariant to the brightness and contrast changes
between floors that shading and exposure produce, which is what the MI of §2.1 buys as well,
at a fraction of the cost for a few dozen regions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["canonical_patches", "cluster_regions", "patch_distances"]


def canonical_patches(gray: np.ndarray, boxes: Sequence[Sequence[int]],
                      size: tuple[int, int] = (24, 24)) -> np.ndarray:
    """Regions of ``gray`` resampled to ``size`` (rows, cols), zero mean and unit norm.

    Parameters
    ----------
    gray : (H, W) float
        Image intensities.
    boxes : (N, 4) int
        ``x0, y0, x1, y1`` pixel boxes (exclusive ends).

    Returns
    -------
    (N, rows·cols) float64
        One flattened patch per region; constant regions are all zero.
    """
    import cv2

    rows, cols = size
    out = np.zeros((len(boxes), rows * cols), np.float64)
    img = np.asarray(gray, np.float32)
    for i, (x0, y0, x1, y1) in enumerate(boxes):
        crop = img[max(0, int(y0)):max(int(y0) + 1, int(y1)), max(0, int(x0)):max(int(x0) + 1, int(x1))]
        if crop.size == 0:
            continue
        p = cv2.resize(crop, (cols, rows), interpolation=cv2.INTER_AREA).astype(np.float64).ravel()
        p -= p.mean()
        n = np.linalg.norm(p)
        if n > 1e-9:
            out[i] = p / n
    return out


def patch_distances(patches: np.ndarray) -> np.ndarray:
    """``(N, N)`` distances ``1 − NCC`` between :func:`canonical_patches` rows, in ``[0, 2]``."""
    d = 1.0 - patches @ patches.T
    np.fill_diagonal(d, 0.0)
    return np.clip((d + d.T) * 0.5, 0.0, 2.0)


def cluster_regions(gray: np.ndarray, boxes: Sequence[Sequence[int]], *, threshold: float = 0.55,
                    size: tuple[int, int] = (24, 24), must_differ: np.ndarray | None = None
                    ) -> np.ndarray:
    """Cluster ids (0, 1, … in order of first appearance) of similar-looking regions.

    Parameters
    ----------
    gray : (H, W) float
        Image intensities.
    boxes : (N, 4) int
        ``x0, y0, x1, y1`` pixel boxes.
    threshold : float
        Average-linkage cut on ``1 − NCC``: 0.55 joins regions whose patches correlate at about
        0.45 or better, which keeps a window tile apart from a door tile but joins the same
        window under different light.
    size : (rows, cols)
        Canonical patch size.
    must_differ : (N, N) bool, optional
        Pairs pushed apart (distance 2, anti-correlated), e.g. floors with different tile
        counts; under average linkage they still join only if everything else agrees.

    Returns
    -------
    (N,) int
    """
    n = len(boxes)
    if n == 0:
        return np.zeros(0, np.int64)
    if n == 1:
        return np.zeros(1, np.int64)
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    d = patch_distances(canonical_patches(gray, boxes, size))
    if must_differ is not None:
        d = np.where(must_differ, 2.0, d)   # 2 = anti-correlated: never below the cut
    z = linkage(squareform(d, checks=False), method="average")
    raw = fcluster(z, t=threshold, criterion="distance")
    order: dict[int, int] = {}
    return np.array([order.setdefault(int(c), len(order)) for c in raw], np.int64)
