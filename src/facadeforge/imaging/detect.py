"""Facade elements (windows, doors, shops; balconies in front of them) as boxes from a pixel
classifier's probabilities.

Why this exists
    Müller et al. 2007 find windows from image edges alone (§2–3); on the varied facades of
    CMP that path finds few of them (the ``structure-edges`` benchmark rows).  A pixel
    classifier (:mod:`facadeforge.classify`, ``simon2011`` §4.3) sees most window pixels, but
    the connected components of its class map are poor objects: neighbouring windows merge
    through piers it half sees, fragments and faint blobs appear.  :func:`detect_elements`
    turns the class map into one box per element in five steps; each was kept because it
    raised window F1 (IoU ≥ 0.5) on the 60 CMP val facades (:mod:`benchmarks.detect` re-measures
    every step — see ``benchmarks/results/detect_cmp.json``):

    1. **XY-cut** (the projection-profile segmentation of document analysis) of the class mask,
       applied recursively: a region is cut at the runs of rows, then of columns, whose mask
       profile drops below ``xy_tol`` × its peak.  It separates windows joined by bridges a
       few pixels wide, which components cannot.  (On photos of several houses with offset
       floors its whole-image rows chop windows; ``xy_tol=None`` starts from connected
       components instead, as the parse seed does for street photos.)
    2. **Valley splits** on the class probability: a box is cut by a vertical line where its
       smoothed column profile falls below ``dip`` × the smaller of the peaks on either side.
       This catches piers between side-by-side windows that the classifier sees only faintly.
       (Row valleys too cut windows at their transoms, and scored lower.)
    3. **Size**: boxes smaller than ``rel_area`` × the median box of their class, or below
       :data:`MIN_ELEMENT_FRACTION` of the image, are fragments.
    4. **Evidence**: boxes whose mean class probability is below ``min_score`` are dropped.
    5. **Row consistency** (windows): the elements of a floor repeat (Müller 2007 §2, and the
       size synchronisation of §3.2), so a window box at least ``row_ratio`` times as wide as
       the median of the other windows in its row (two or more) is two or more windows merged
       through a pier the classifier missed.  It is cut into ``max(2, round((w + g) / (m + g)))``
       parts (``m`` the row's median width, ``g`` its median gap) at the probability minima
       nearest the even cut positions, each part trimmed to its columns above half its peak.

    6. **Behind railings** (``behind``, for datasets that draw windows whole behind balconies,
       as CMP): windows extended down through the balcony rows below them, by at most a third
       of their height (by their whole height it lost F1).
    7. **Closed shutters** (``covers``, for datasets whose window rectangles include the
       shutters closed over them, as CMP's ``blind``): the covering classes count as window in
       steps 1–5, then each box is trimmed to the columns its glass spans (shutters *open*
       beside a window are not the window); a box with no glass is a closed window when it is
       the size of the windows with glass and stands in one of their columns (pale wall the
       classifier calls shutter is not).  A tenth of the window and blind pixels of CMP's
       labels are blind; what the step gains is step 7 of
       ``benchmarks/results/detect_cmp.json``.

    Tried on the same split and not kept (no gain): splitting boxes wider than 1.7 median
    widths, splitting at full-height mullions (CMP marks some mullioned windows as one window
    and others as two), completing the grid of window rows × columns, and snapping box edges to
    image edges.

Boxes are ``(x0, y0, x1, y1)`` pixels with exclusive ends, rows down, in the frame of the
probabilities.  Boxes of one class never overlap (both cuts partition); across classes, the
weaker of two overlapping boxes is dropped, so the boxes are disjoint (:mod:`.element_layout`
lays split lines between them).  The parameters were chosen on the CMP val split, so the F1
measured there is not a held-out result.

Balconies (:data:`PROTRUDING_LABELS`) stand in front of the wall and of the windows' feet:
:func:`detect_protruding` gives their boxes by steps 1–4 with the same parameters — a band
running along a floor is one box, the XY-cut separates the balconies of single windows — and
keeps them apart from the other elements, which they overlap (a window behind a railing stays
a window).  Leaving step 2 out or a looser XY-cut was tried for them and was not better
(figures: ``docs/design-measurements.md``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..datasets.folder import MIN_OBJECT_FRACTION
from ..errors import InputError
from .runs import runs

__all__ = ["DETECTED_LABELS", "MIN_ELEMENT_FRACTION", "PROTRUDING_LABELS", "Element",
           "detect_elements", "detect_protruding", "row_split", "valley_split", "xy_cut"]

#: Canonical labels detected as elements, disjoint boxes (split lines run between them).
DETECTED_LABELS: tuple[str, ...] = ("window", "door", "shop")
#: Canonical labels detected as elements in front of the wall, overlapping the others.
PROTRUDING_LABELS: tuple[str, ...] = ("balcony",)
#: Boxes smaller than this fraction of the image are noise (the benchmark's object threshold,
#: :data:`facadeforge.datasets.folder.MIN_OBJECT_FRACTION`, so no scored object is lost).
MIN_ELEMENT_FRACTION: float = MIN_OBJECT_FRACTION
#: Depth limit of both recursive cuts (a facade has far fewer than 2**12 elements in a row).
MAX_CUT_DEPTH: int = 12


@dataclass(frozen=True)
class Element:
    """One detected element: canonical ``label``, pixel ``box`` ``(x0, y0, x1, y1)`` (exclusive
    ends) and ``score``, its mean class probability."""

    label: str
    box: tuple[int, int, int, int]
    score: float

    @property
    def area(self) -> int:
        x0, y0, x1, y1 = self.box
        return (x1 - x0) * (y1 - y0)


def _tighten(mask: np.ndarray, box: tuple[int, int, int, int]) -> tuple[int, int, int, int] | None:
    """The bounding box of ``mask`` inside ``box``, or ``None`` when it is empty there."""
    x0, y0, x1, y1 = box
    sub = mask[y0:y1, x0:x1]
    rows, cols = np.flatnonzero(sub.any(axis=1)), np.flatnonzero(sub.any(axis=0))
    if rows.size == 0:
        return None
    return x0 + int(cols[0]), y0 + int(rows[0]), x0 + int(cols[-1]) + 1, y0 + int(rows[-1]) + 1


def xy_cut(mask: np.ndarray, tol: float = 0.2, min_run: int = 3) -> list[tuple[int, int, int, int]]:
    """Recursive XY-cut of a boolean mask: leaf boxes, tightened to the mask.

    A region is cut along rows first, then columns: its mask profile (fraction of set pixels per
    row or column) is thresholded at ``tol`` × the profile's peak; when at least two runs of
    ``min_run`` pixels or more lie above it, each becomes a child region and shorter runs are
    dropped as noise.  Otherwise (one long run, perhaps beside short ones) the region is a leaf,
    tightened to all its mask pixels.
    """
    m = np.asarray(mask, bool)
    h, w = m.shape
    out: list[tuple[int, int, int, int]] = []
    stack: list[tuple[tuple[int, int, int, int], int]] = [((0, 0, w, h), 0)]
    while stack:
        box, depth = stack.pop()
        tight = _tighten(m, box)
        if tight is None:
            continue
        x0, y0, x1, y1 = tight
        sub = m[y0:y1, x0:x1]
        children: list[tuple[int, int, int, int]] = []
        if depth < MAX_CUT_DEPTH:
            for axis in (1, 0):              # axis 1: profile per row (cut rows first)
                prof = sub.mean(axis=axis)
                parts = [r for r in runs(prof > tol * prof.max()) if r[1] - r[0] >= min_run]
                if len(parts) > 1:
                    children = [(x0, y0 + a, x1, y0 + b) if axis == 1 else (x0 + a, y0, x0 + b, y1)
                                for a, b in parts]
                    break
        if children:
            stack.extend((c, depth + 1) for c in children)
        else:
            out.append(tight)
    return sorted(out, key=lambda b: (b[1], b[0]))


def _deepest_valley(prob: np.ndarray, box, dip: float, min_px: int) -> int | None:
    """Column offset of the deepest valley of ``box``'s column profile below ``dip`` × the
    smaller peak on either side, or ``None``."""
    x0, y0, x1, y1 = box
    prof = prob[y0:y1, x0:x1].mean(axis=0)
    n = prof.size
    if n < 2 * min_px + 1:
        return None
    prof = gaussian_filter1d(prof.astype(np.float64), 1.0)
    left = np.maximum.accumulate(prof)
    right = np.maximum.accumulate(prof[::-1])[::-1]
    k = np.arange(min_px, n - min_px)
    is_min = (prof[k] <= prof[k - 1]) & (prof[k] <= prof[k + 1])
    ratio = prof[k] / np.maximum(np.minimum(left[k - 1], right[k + 1]), 1e-6)
    ok = is_min & (ratio < dip)
    if not ok.any():
        return None
    return int(k[int(np.argmin(np.where(ok, ratio, np.inf)))])


def valley_split(prob: np.ndarray, mask: np.ndarray, box, dip: float = 0.7,
                 min_px: int = 2) -> list[tuple[int, int, int, int]]:
    """``box`` cut recursively by vertical lines at the deepest valley of its column profile of
    ``prob`` that lies below ``dip`` × the smaller peak on either side; parts tightened to
    ``mask``."""
    out: list[tuple[int, int, int, int]] = []
    stack = [(tuple(int(v) for v in box), 0)]
    while stack:
        b, depth = stack.pop()
        v = _deepest_valley(prob, b, dip, min_px) if depth < MAX_CUT_DEPTH else None
        if v is None:
            out.append(b)
            continue
        x0, y0, x1, y1 = b
        for p in ((x0, y0, x0 + v, y1), (x0 + v, y0, x1, y1)):
            t = _tighten(mask, p)
            if t is not None:
                stack.append((t, depth + 1))
    return sorted(out, key=lambda b: (b[1], b[0]))


def row_split(els: list[Element], prob: np.ndarray, ratio: float = 1.8) -> list[Element]:
    """Step 5 of the module docstring on one class's elements; ``prob`` is that class's
    probability map."""
    if len(els) < 3:
        return list(els)
    B = np.array([e.box for e in els], float)
    out: list[Element] = []
    for i, e in enumerate(els):
        x0, y0, x1, y1 = e.box
        shared = np.minimum(B[:, 3], y1) - np.maximum(B[:, 1], y0)
        peers = np.flatnonzero((shared > 0.5 * np.minimum(B[:, 3] - B[:, 1], y1 - y0))
                               & (np.arange(len(B)) != i))
        width = x1 - x0
        median = float(np.median(B[peers, 2] - B[peers, 0])) if len(peers) >= 2 else width
        if width <= 0 or median <= 0 or width < ratio * median:
            out.append(e)
            continue
        row = B[np.append(peers, i)]          # the box itself too: peers may flank it
        row = row[np.argsort(row[:, 0])]
        gaps = row[1:, 0] - row[:-1, 2]
        gaps = gaps[gaps > 0]
        gap = float(np.median(gaps)) if len(gaps) else 0.25 * median
        n = max(2, round((width + gap) / (median + gap)))
        prof = prob[y0:y1, x0:x1].mean(axis=0)
        cols = np.arange(width)
        edges = [0]
        for k in range(1, n):
            at = k * width / n
            lo = int(max(edges[-1] + 1, at - median / 3))
            hi = int(min(width - 1, at + median / 3))
            if hi <= lo:
                break
            # the lowest column, the one nearest the even cut among equals (a flat pier)
            edges.append(lo + int(np.argmin(prof[lo:hi] + 1e-6 * np.abs(cols[lo:hi] - at))))
        edges.append(width)
        parts = []
        for a, b in zip(edges[:-1], edges[1:]):
            seg = prof[a:b]
            on = np.flatnonzero(seg > 0.5 * seg.max()) if seg.size else seg
            if len(on):
                box = (x0 + a + int(on[0]), y0, x0 + a + int(on[-1]) + 1, y1)
                parts.append(Element(e.label, box,
                                     float(prob[y0:y1, box[0]:box[2]].mean())))
        out.extend(parts if len(parts) >= 2 else [e])
    return out


def _components(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Boxes of the 4-connected components of ``mask``."""
    _, _, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=4)
    return [(int(x), int(y), int(x + w), int(y + h)) for x, y, w, h, _ in stats[1:]]


def _overlap(a, b) -> bool:
    return min(a[2], b[2]) > max(a[0], b[0]) and min(a[3], b[3]) > max(a[1], b[1])


def _covered(p, argmax, classes, covers):
    """``p`` and its argmax with the classes ``covers`` (closed shutters) counted as window,
    and the mask of the window's own pixels (``None`` when nothing is merged)."""
    idx = [list(classes).index(c) for c in covers if c in classes]
    if not idx or "window" not in classes:
        return p, argmax, None
    w = list(classes).index("window")
    q = p.astype(np.float32, copy=True)
    q[:, :, w] += q[:, :, idx].sum(axis=2)
    q[:, :, idx] = 0.0
    return q, np.argmax(q, axis=2), argmax == w


# Step 7 (module docstring), chosen on the CMP val split (``detect_cmp.json``: not a held-out
# figure).
#: A window box with less than this share of glass pixels is a closed one (shutters only).
GLASS_SHARE = 0.1
#: A box with glass is trimmed to the columns holding at least this share of its glassiest one.
GLASS_COLUMN = 0.1
#: A closed window is at least this share of the median height and area of those with glass…
SHUTTER_SIZE = 0.5
#: …and shares at least this much of its width with one of them (windows stand in columns).
ALIGN = 0.5
#: …and is no shutter open beside a window with glass: a box within this share of the median
#: window width of one, beside it in the same rows.
BESIDE = 0.25


def _beside(a, b, gap: float) -> bool:
    """Box ``a`` stands beside box ``b``, within ``gap`` pixels, over half of ``a``'s rows."""
    rows = min(a[3], b[3]) - max(a[1], b[1])
    apart = max(a[0], b[0]) - min(a[2], b[2])
    return rows >= 0.5 * (a[3] - a[1]) and apart <= gap


def _x_share(a, b) -> float:
    """The share of box ``a``'s width that box ``b``'s columns cover."""
    return max(0, min(a[2], b[2]) - max(a[0], b[0])) / max(1, a[2] - a[0])


def _to_glass(els: list[Element], glass: np.ndarray) -> list[Element]:
    """Window boxes of the merged mask (:func:`_covered`) trimmed to the columns their glass
    spans (open shutters beside a window are not the window); a box with no glass (shutters
    closed) is kept whole when it is the size of the windows with glass (:data:`SHUTTER_SIZE`:
    a pale patch of wall the classifier calls shutter is smaller), stands in one of their
    columns (:data:`ALIGN`) and not right beside one (:data:`BESIDE`: an open shutter).  With
    fewer than three windows with glass there is nothing to compare with, and all are kept."""
    trimmed, closed = [], []
    for e in els:
        x0, y0, x1, y1 = e.box
        sub = glass[y0:y1, x0:x1]
        if sub.mean() < GLASS_SHARE:
            closed.append(e)
            continue
        cols = sub.mean(axis=0)
        on = np.flatnonzero(cols >= GLASS_COLUMN * cols.max())
        trimmed.append(Element(e.label, (x0 + int(on[0]), y0, x0 + int(on[-1]) + 1, y1),
                               e.score))
    if len(trimmed) >= 3:
        h = float(np.median([e.box[3] - e.box[1] for e in trimmed]))
        a = float(np.median([e.area for e in trimmed]))
        w = float(np.median([e.box[2] - e.box[0] for e in trimmed]))
        closed = [e for e in closed if e.box[3] - e.box[1] >= SHUTTER_SIZE * h
                  and e.area >= SHUTTER_SIZE * a
                  and any(_x_share(e.box, g.box) >= ALIGN for g in trimmed)
                  and not any(_beside(e.box, g.box, BESIDE * w) for g in trimmed)]
    return trimmed + closed


def _extend_down(e: Element, front: np.ndarray) -> Element:
    """``e`` with its bottom moved down through the rows right below it that are mostly
    ``front`` across its width (at most a third of its height further)."""
    x0, y0, x1, y1 = e.box
    limit = min(front.shape[0], y1 + (y1 - y0) // 3)
    share = front[y1:limit, x0:x1].mean(axis=1) if limit > y1 else np.zeros(0)
    stop = np.flatnonzero(share <= 0.5)
    n = int(stop[0]) if len(stop) else len(share)
    return e if n == 0 else Element(e.label, (x0, y0, x1, y1 + n), e.score)


@dataclass(frozen=True)
class _Steps:
    """Parameters of steps 1–4 (module docstring) on an image of ``shape`` ``(H, W)``."""

    shape: tuple[int, int]
    xy_tol: float | None
    dip: float
    rel_area: float
    min_score: float
    min_prob: float

    @property
    def min_px(self) -> int:
        return max(2, int(0.005 * max(self.shape)))

    @property
    def min_area(self) -> float:
        return MIN_ELEMENT_FRACTION * self.shape[0] * self.shape[1]


def _checked(prob: np.ndarray, classes: Sequence[str], who: str) -> tuple[np.ndarray, np.ndarray]:
    """``prob`` as an array with one channel per class, and its argmax map."""
    p = np.asarray(prob)
    if p.ndim != 3 or p.shape[2] != len(classes):
        raise InputError(f"{who}: probabilities of shape {p.shape} do not hold one "
                         f"channel per class of {list(classes)}")
    return p, np.argmax(p, axis=2)


def _class_elements(p: np.ndarray, argmax: np.ndarray, classes: Sequence[str], label: str,
                    steps: _Steps) -> list[Element]:
    """Steps 1–4 of the module docstring on one class: its boxes, none overlapping another."""
    if label not in classes:
        return []
    c = list(classes).index(label)
    mask = argmax == c
    if steps.min_prob > 0:
        mask &= p[:, :, c] > steps.min_prob
    if not mask.any():
        return []
    pc = p[:, :, c].astype(np.float32)
    start = xy_cut(mask, steps.xy_tol) if steps.xy_tol is not None else _components(mask)
    boxes = [part for b in start for part in valley_split(pc, mask, b, steps.dip, steps.min_px)]
    els = [Element(label, b, float(pc[b[1]:b[3], b[0]:b[2]].mean())) for b in boxes]
    els = [e for e in els if e.area >= steps.min_area]
    if len(els) >= 3:
        med = float(np.median([e.area for e in els]))
        els = [e for e in els if e.area >= steps.rel_area * med]
    return [e for e in els if e.score >= steps.min_score]


def detect_elements(prob: np.ndarray, classes: Sequence[str],
                    labels: Sequence[str] = DETECTED_LABELS, *, xy_tol: float | None = 0.2,
                    dip: float = 0.7, rel_area: float = 0.3, min_score: float = 0.5,
                    row_ratio: float = 1.8, min_prob: float = 0.0,
                    behind: Sequence[str] = (), covers: Sequence[str] = ()) -> list[Element]:
    """Element boxes of ``labels`` from class probabilities (module docstring).

    Parameters
    ----------
    prob : (H, W, K) float
        Class probabilities (a classifier's ``predict_proba``).
    classes : sequence of K canonical labels
        The channels of ``prob``; labels it lacks are not detected.
    labels : canonical labels to detect
    xy_tol, dip, rel_area, min_score, row_ratio
        Steps 1–5 of the module docstring; ``dip=0``, ``rel_area=0``, ``min_score=0`` and
        ``row_ratio=inf`` each switch a step off (the ablation of ``benchmarks/detect.py``).
        ``xy_tol=None`` starts from the connected components of the class mask instead of the
        XY-cut: for photos of several houses whose floors are offset, which the XY-cut's
        whole-image rows would chop.
    min_prob : float
        A pixel belongs to a class's mask only where that class is the most probable *and*
        above this probability: ``1/K``-uniform probabilities (outside a warped photo) have an
        arbitrary argmax, which must not join the windows beside them.
    behind : canonical labels
        Classes that stand in front of a window's foot (a balcony's railing) in a dataset that
        draws each window whole behind them, as CMP does (12 % of its windows overlap a
        balcony box, by a median 39 % of their area): a window is extended down through the
        rows below it where these classes are most probable across its width, by at most a
        third of its height (step 6 of ``benchmarks/results/detect_cmp.json``; by up to its
        whole height it scored lower: ``docs/design-measurements.md``).
    covers : canonical labels
        Classes that cover a window inside its frame (closed shutters) in a dataset that draws
        the window's rectangle over them, as CMP does: step 7 of the module docstring.

    Returns
    -------
    list of Element
        Top to bottom, then left to right.
    """
    p, argmax = _checked(prob, classes, "detect_elements")
    steps = _Steps(p.shape[:2], xy_tol, dip, rel_area, min_score, min_prob)
    found: list[Element] = []
    for label in labels:
        pw, aw, glass = (_covered(p, argmax, classes, covers) if label == "window"
                         else (p, argmax, None))
        els = _class_elements(pw, aw, classes, label, steps)
        if label == "window" and els:           # the parts pass step 4's test too
            pc = pw[:, :, list(classes).index(label)].astype(np.float32)
            els = [e for e in row_split(els, pc, row_ratio) if e.score >= min_score]
            if glass is not None:
                els = _to_glass(els, glass)
            occluders = [list(classes).index(b) for b in behind if b in classes]
            if occluders:
                front = np.isin(argmax, occluders)
                els = [_extend_down(e, front) for e in els]
        found += els
    kept: list[Element] = []
    for e in sorted(found, key=lambda e: (-e.score * e.area, e.box)):
        if not any(_overlap(e.box, k.box) for k in kept):
            kept.append(e)
    return sorted(kept, key=lambda e: (e.box[1], e.box[0], e.label))


def detect_protruding(prob: np.ndarray, classes: Sequence[str],
                      labels: Sequence[str] = PROTRUDING_LABELS, *, xy_tol: float | None = 0.2,
                      dip: float = 0.7, rel_area: float = 0.3, min_score: float = 0.5,
                      min_prob: float = 0.0) -> list[Element]:
    """Boxes of the elements that stand in front of the wall (balconies) from class
    probabilities: steps 1–4 of the module docstring, nothing dropped for overlapping the
    boxes of :func:`detect_elements` (a balcony stands in front of its window's foot).

    Parameters
    ----------
    prob, classes, xy_tol, dip, rel_area, min_score, min_prob
        As for :func:`detect_elements`: ``(H, W, K)`` class probabilities, their K canonical
        labels, and the options of steps 1–4.
    labels : canonical labels to detect (those ``classes`` lacks are not)

    Returns
    -------
    list of Element
        Top to bottom, then left to right; boxes of one class never overlap each other.
    """
    p, argmax = _checked(prob, classes, "detect_protruding")
    steps = _Steps(p.shape[:2], xy_tol, dip, rel_area, min_score, min_prob)
    found = [e for label in labels for e in _class_elements(p, argmax, classes, label, steps)]
    return sorted(found, key=lambda e: (e.box[1], e.box[0], e.label))
