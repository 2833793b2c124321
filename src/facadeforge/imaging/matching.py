"""Matching image regions with 3D library elements by mutual information (Müller et al. 2007,
§4, eq. 7–8).

Every library element ``e_i`` has a 2D representation ``p(e_i)``, its fronto-parallel render
(:func:`facadeforge.elements.render_front`).  The type of a rectangular image region ``R`` is

    ``T(R) = argmax_i MI(I(p(e_i)), I(R))``                         (eq. 7)

and, since regions of one cluster of the irreducible facade should be the same element, the type
of a cluster ``C`` is

    ``T(C) = argmax_i Σ_{R ∈ C} MI(I(p(e_i)), I(R))``                (eq. 8).

MI is eq. 1 (§2.1) on corresponding pixels.  To compare a region with a render pixel by pixel,
both are resampled to one canonical ``size × size`` grid: the render is made at that size
directly (the element is stretched to the region's rectangle, exactly as a rule scales the unit
box element into the region), the region is area-resampled.  Both are quantised to the same
number of bins, each over its own intensity range (:func:`~.symmetry.quantise`), which makes MI
indifferent to brightness and contrast changes.

All ``n_regions × n_candidates`` joint histograms come from a single ``np.bincount`` on
``pair · bins² + a · bins + b``; with ``Σ c log c`` from a lookup table every MI is
``log N + (Σ c_ab log c_ab − Σ c_a log c_a − Σ c_b log c_b) / N`` (see :mod:`.symmetry`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from .symmetry import _clogc_table, quantise

__all__ = ["Match", "match_elements", "mutual_information_matrix", "region_stack"]


@dataclass
class Match:
    """Eq. 8 result for one cluster.

    Attributes
    ----------
    cluster : int
        The cluster id.
    element : str
        Name of the winning element (``T(C)``, eq. 8).
    score : float
        Its summed MI over the cluster's regions (nats).
    region_scores : (n_regions_in_cluster, n_candidates) float
        ``MI(I(p(e_i)), I(R))`` of every region of the cluster and every candidate (eq. 7).
    candidates : list of str
        Element names, the columns of ``region_scores``.
    regions : (n_regions_in_cluster,) int
        Indices of the cluster's regions in the ``boxes`` given to :func:`match_elements`.
    """

    cluster: int
    element: str
    score: float
    region_scores: np.ndarray
    candidates: list[str]
    regions: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def region_elements(self) -> list[str]:
        """Eq. 7 winner of each region on its own."""
        if self.region_scores.size == 0:
            return []
        return [self.candidates[i] for i in np.argmax(self.region_scores, axis=1)]

    @property
    def kind(self) -> str:
        """Canonical label of the winning element."""
        from ..elements import element_spec

        return element_spec(self.element).kind


def region_stack(gray: np.ndarray, boxes: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Regions ``(x0, y0, x1, y1)`` of ``gray`` area-resampled to ``size × size``.

    Returns ``(stack (N, size, size) float32, valid (N,) bool)``; boxes empty after clipping to
    the image are zeros and not valid.
    """
    import cv2

    gray = np.asarray(gray, np.float32)
    H, W = gray.shape
    boxes = np.asarray(boxes, float).reshape(-1, 4)
    out = np.zeros((len(boxes), size, size), np.float32)
    valid = np.zeros(len(boxes), bool)
    for k, (x0, y0, x1, y1) in enumerate(boxes):
        a0, a1 = int(np.clip(np.floor(x0), 0, W)), int(np.clip(np.ceil(x1), 0, W))
        b0, b1 = int(np.clip(np.floor(y0), 0, H)), int(np.clip(np.ceil(y1), 0, H))
        if a1 - a0 < 1 or b1 - b0 < 1:
            continue
        crop = gray[b0:b1, a0:a1]
        interp = cv2.INTER_AREA if (a1 - a0 >= size and b1 - b0 >= size) else cv2.INTER_LINEAR
        out[k] = cv2.resize(crop, (size, size), interpolation=interp)
        valid[k] = True
    return out, valid


def _row_hist(x: np.ndarray, bins: int) -> np.ndarray:
    """Histogram of every row of integer levels: (n, bins)."""
    off = (np.arange(len(x), dtype=np.int64) * bins)[:, None]
    return np.bincount((x + off).ravel(), minlength=len(x) * bins).reshape(len(x), bins)


def mutual_information_matrix(a: np.ndarray, b: np.ndarray, bins: int,
                              normalised: bool = False) -> np.ndarray:
    """MI (eq. 1, nats) of every row of ``a`` (n, P) with every row of ``b`` (m, P), both
    integer levels in ``[0, bins)``; returns (n, m).

    ``normalised=True`` gives ``2 MI / (H(a) + H(b))`` in 0..1 instead (not in the paper: plain
    MI favours candidates with more intensity levels, since ``MI ≤ min(H(a), H(b))``).
    """
    a = np.asarray(a, np.int64)
    b = np.asarray(b, np.int64)
    n, P = a.shape
    m = b.shape[0]
    if n == 0 or m == 0 or P == 0:
        return np.zeros((n, m))
    bb = bins * bins
    pair = (np.arange(n * m, dtype=np.int64) * bb).reshape(n, m, 1)
    idx = pair + (a * bins)[:, None, :] + b[None, :, :]
    joint = np.bincount(idx.ravel(), minlength=n * m * bb).reshape(n, m, bb)
    table = _clogc_table(P)
    ha = table[_row_hist(a, bins)].sum(axis=1)  # (n,)
    hb = table[_row_hist(b, bins)].sum(axis=1)  # (m,)
    hab = table[joint].sum(axis=2)  # (n, m)
    mi = np.maximum(np.log(P) + (hab - ha[:, None] - hb[None, :]) / P, 0.0)
    if normalised:
        ent = 2 * np.log(P) - (ha[:, None] + hb[None, :]) / P  # H(a) + H(b)
        mi = np.where(ent > 1e-12, 2 * mi / np.maximum(ent, 1e-12), 0.0)
    return mi


def match_elements(gray: np.ndarray, boxes, clusters, *, library=None,
                   kinds: Iterable[str] | None = None, size: int = 32,
                   bins: int = 16, normalised: bool = False) -> dict[int, Match]:
    """Best library element per cluster of regions (§4, eq. 7 per region, eq. 8 per cluster).

    Parameters
    ----------
    gray : (H, W) float
        Rectified facade intensities in 0..1.
    boxes : (N, 4) array
        Regions as pixel boxes ``x0, y0, x1, y1`` (rows grow downwards).
    clusters : (N,) int
        Cluster id of each region (regions of one cluster share one element, eq. 8).
    library : iterable of ElementSpec, optional
        The candidates ``{e_i}``; defaults to :func:`facadeforge.elements.element_library`.
    kinds : iterable of str, optional
        Keep only candidates of these kinds (e.g. ``{"window", "door"}``).
    size : int
        Side of the canonical grid both region and render are compared on.
    bins : int
        Quantisation levels of both intensities (the same for both).
    normalised : bool
        Score with normalised MI ``2 MI / (H(R) + H(p(e_i)))`` instead of the paper's plain MI
        (see :func:`mutual_information_matrix`).

    Returns
    -------
    dict of cluster id → :class:`Match`
    """
    from ..elements import element_library, render_front
    from ..errors import InputError

    specs = list(element_library() if library is None else library)
    wanted = None if kinds is None else {str(k) for k in kinds}
    if wanted is not None:
        specs = [s for s in specs if s.kind in wanted]
    if not specs:
        raise InputError(f"no library element to match (kinds={sorted(wanted or ())!r})")
    gray = np.asarray(gray, np.float32)
    if gray.ndim != 2:
        raise InputError(f"match_elements needs a gray (H, W) image, got shape {gray.shape}")
    boxes = np.asarray(boxes, float).reshape(-1, 4)
    clusters = np.asarray(clusters).reshape(-1)
    if len(clusters) != len(boxes):
        raise InputError(f"{len(boxes)} boxes but {len(clusters)} cluster ids")
    names = [s.name for s in specs]
    renders = np.stack([quantise(render_front(s, size, size)[0], bins).ravel() for s in specs])
    stack, valid = region_stack(gray, boxes, size)
    regions = np.stack([quantise(r, bins).ravel() for r in stack]) if len(stack) else \
        np.zeros((0, size * size), np.int32)
    scores = mutual_information_matrix(regions, renders, bins, normalised)
    scores[~valid] = 0.0
    out: dict[int, Match] = {}
    for c in np.unique(clusters):
        members = np.flatnonzero(clusters == c)
        rs = scores[members]
        total = rs.sum(axis=0)
        best = int(np.argmax(total))
        out[int(c)] = Match(int(c), names[best], float(total[best]), rs, names, members)
    return out
