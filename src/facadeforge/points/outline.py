"""A facade plane's outline: where its wall stops, and the houses of different heights along it.

One RANSAC plane (:mod:`.planes`) often holds a whole street front — houses of two, four and six
storeys side by side, a gable above a shop — while a split grammar's facade is a rectangle.  Left
whole, the rectangle of the tallest house puts wall into the sky above its neighbours (the model
then stands where the scan has nothing: ``simon2011`` eq. 5.10 counts it).  CityFit splits a
facade "vertically along symmetry axes or into superordinate structures" first (``hohmann2009``
§4, *Split order*); here the superordinate structures are the runs of columns whose wall reaches
the same height:

1. per raster column, the wall's **top**: the highest cell with a point near the wall plane,
   taken as the :data:`TOP_PERCENTILE` th percentile of the column's occupied rows so that a
   stray point above the eaves (a lamp, a wire) does not count;
2. the tops median-filtered over :data:`SMOOTH_M`, then cut where they jump by more than
   :data:`STEP_M`, at a column that no element crosses (an element is never cut);
3. runs narrower than :data:`MIN_WIDTH_M` join the neighbour nearest in height;
4. each run is a **segment**: its columns and its height (the run's median top, so the
   rectangle follows the eaves, not a chimney or a gable's ridge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .elements import Element
from .maps import FacadeMaps

__all__ = ["Segment", "column_tops", "segments"]

#: Percentile of a column's occupied rows (from the bottom) taken as its wall top.
TOP_PERCENTILE = 98
#: Smoothing (m) of the tops along the facade.
SMOOTH_M = 1.0
#: A jump of the wall top (m) that separates two segments.
STEP_M = 1.5
#: Narrowest segment (m).
MIN_WIDTH_M = 2.0


@dataclass(frozen=True)
class Segment:
    """Columns ``x0:x1`` of a facade's rasters whose wall reaches row ``top`` (rows down)."""

    x0: int
    x1: int
    top: int


def column_tops(maps: FacadeMaps, wall_band: float = 0.5) -> np.ndarray:
    """The wall's top per column, as a height (m) above the frame's foot; 0 where the column
    holds no wall point."""
    h, w = maps.shape
    near = (maps.count > 0) & (np.abs(np.nan_to_num(maps.depth, nan=9.0)) < wall_band)
    heights = (h - np.arange(h))[:, None] * maps.resolution       # top of each row, metres
    tops = np.zeros(w)
    any_ = near.any(0)
    if not any_.any():
        return tops
    hv = np.where(near, heights, np.nan)
    tops[any_] = np.nanpercentile(hv[:, any_], TOP_PERCENTILE, axis=0)
    return tops


def segments(maps: FacadeMaps, elements: list[Element]) -> list[Segment]:
    """The facade's segments, left to right (see the module docstring); one segment spanning
    the whole raster when the wall's top is even."""
    h, w = maps.shape
    res = maps.resolution
    tops = column_tops(maps)
    has = tops > 0
    if not has.any():
        return [Segment(0, w, 0)]
    tops = np.interp(np.arange(w), np.flatnonzero(has), tops[has])
    k = max(1, int(round(SMOOTH_M / res))) | 1
    tops = ndimage.median_filter(tops, size=k, mode="nearest")
    blocked = np.zeros(w + 1, bool)                  # cut positions inside an element
    for e in elements:
        x0, _, x1, _ = e.box_px
        blocked[max(x0 + 1, 0):min(x1, w)] = True
    cuts = [0]
    jump = np.abs(np.diff(tops))
    step = int(round(STEP_M / res))
    x = 1
    while x < w:
        if jump[x - 1] * 1.0 > 0 and abs(tops[min(x + k, w - 1)] - tops[max(x - k - 1, 0)]) \
                > STEP_M and not blocked[x]:
            # the steepest change within the next few cells
            lo, hi = x, min(w - 1, x + 2 * k)
            best = lo + int(np.argmax(jump[lo - 1:hi]))
            if not blocked[best]:
                cuts.append(best)
                x = best + max(step, 1)
                continue
        x += 1
    cuts.append(w)
    runs = [(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]
    min_w = int(round(MIN_WIDTH_M / res))
    merged = True
    while merged and len(runs) > 1:
        merged = False
        for i, (a, b) in enumerate(runs):
            if b - a >= min_w:
                continue
            here = float(np.median(tops[a:b]))
            left = abs(float(np.median(tops[runs[i - 1][0]:runs[i - 1][1]])) - here) \
                if i > 0 else np.inf
            right = abs(float(np.median(tops[runs[i + 1][0]:runs[i + 1][1]])) - here) \
                if i + 1 < len(runs) else np.inf
            j = i - 1 if left <= right else i + 1
            lo, hi = min(i, j), max(i, j)
            runs[lo:hi + 1] = [(runs[lo][0], runs[hi][1])]
            merged = True
            break
    out = []
    for a, b in runs:
        top_m = float(np.median(tops[a:b]))
        top_m = max(top_m, max((e.box_m[3] for e in elements
                                if a <= (e.box_px[0] + e.box_px[2]) / 2 < b), default=0.0))
        row = int(np.clip(h - int(np.ceil(top_m / res + 1)), 0, h - 1))
        out.append(Segment(a, b, row))
    return out
