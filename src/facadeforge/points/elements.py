"""Facade elements found on a facade's depth map: windows and doors as recesses, balconies as
protrusions (CityFit §3's "segmentation for the depth map").

``hohmann2009`` §3 segments the depth map by plane ("the same z-value is a strong clue for
elements to carry the same grammar symbol") and notes what a laser sees of a facade: reflective
glass returns little and what it lets through lies behind the wall (``simon2011`` §5.4.3).  So an
opening is a part of the facade where most points lie *behind* the wall plane — the window frame
and glass set back in the wall, the shop interior seen through a shop front — and a balcony or
sign is where the front-most points stand well *in front* of it:

1. per cell, ``recessed`` (median depth below −:data:`RECESS` m) and ``occupied`` (any point);
2. the recessed share of the occupied cells in a :data:`WINDOW_M` box (a box filter on each),
   above :data:`MIN_SHARE` where at least :data:`MIN_OCCUPIED` of the box holds points — the
   scan's line pattern leaves empty stripes on a wall, and an opening with no return at all is
   an occlusion, a removed sign or the sky, not evidence of a window;
3. a morphological closing then opening of :data:`CLOSE_M` (mullions and transoms, which sit
   at the frame's depth too, do not cut a window in two; speckle goes);
4. each connected piece is an element: its bounding rectangle, kept when at least
   :data:`MIN_SIDE_M` on both sides and filled to :data:`MIN_FILL` by the mask;
5. its **label**: ``door`` when its foot is within :data:`DOOR_FOOT_M` of the facade's foot
   and it is at least :data:`DOOR_MIN_HEIGHT` tall (doors and shop fronts), else ``window``;
   its **depth** is the measured one, the median depth of its recessed cells.

Protrusions (``front`` above +:data:`PROTRUDE` m) go through the same steps; those whose foot
is above the ground floor (:data:`BALCONY_MIN_HEIGHT`) are ``balcony`` elements with their
measured depth (the front-most depth's median), lower ones (awnings, shop signs, parked
things) are not elements of the grammar and are reported as ``protrusion``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .maps import FacadeMaps

__all__ = ["Element", "detect_elements"]

#: Depth (m) behind the wall from which a cell counts as recessed.
RECESS = 0.06
#: Depth (m) in front of the wall from which a cell counts as protruding.
PROTRUDE = 0.25
#: Side (m) of the box in which the recessed share is measured.
WINDOW_M = 0.35
#: Recessed share of a box's occupied cells that makes it part of an opening.
MIN_SHARE = 0.35
#: Share of a box that must hold points for its share to count.
MIN_OCCUPIED = 0.2
#: Structuring element (m) of the closing and opening.
CLOSE_M = 0.25
#: Smallest element side (m) and the share of its rectangle the mask must fill.
MIN_SIDE_M, MIN_FILL = 0.4, 0.45
#: A door's foot lies within this of the facade's foot (m) and it is at least this tall (m).
DOOR_FOOT_M, DOOR_MIN_HEIGHT = 0.5, 1.6
#: A protrusion whose foot is at least this high (m) is a balcony.
BALCONY_MIN_HEIGHT = 2.5


@dataclass
class Element:
    """One element on a facade: a rectangle in facade metres and in raster cells."""

    label: str                               # window, door, balcony, protrusion
    box_m: tuple[float, float, float, float]  # (u0, v0, u1, v1), facade frame, v up
    box_px: tuple[int, int, int, int]         # (x0, y0, x1, y1), raster cells, rows down
    depth: float                              # measured depth (m), negative = recessed
    score: float                              # mean share of the evidence inside the box

    @property
    def width(self) -> float:
        return self.box_m[2] - self.box_m[0]

    @property
    def height(self) -> float:
        return self.box_m[3] - self.box_m[1]

    def to_dict(self, frame=None) -> dict:
        out = {"label": self.label, "box_m": [round(float(v), 4) for v in self.box_m],
               "depth_m": round(float(self.depth), 4), "score": round(float(self.score), 4)}
        if frame is not None:
            u0, v0, u1, v1 = self.box_m
            out["corners"] = [[round(float(x), 4) for x in p]
                              for p in frame.rectangle(u0, v0, u1, v1, self.depth)]
        return out


def _cells(metres: float, res: float) -> int:
    return max(1, int(round(metres / res)))


def _pieces(evidence: np.ndarray, occupied: np.ndarray, res: float) -> tuple[np.ndarray, np.ndarray]:
    """The element mask of step 2–3 and the smoothed share."""
    k = _cells(WINDOW_M, res) | 1
    occ = ndimage.uniform_filter(occupied.astype(np.float32), k)
    ev = ndimage.uniform_filter((evidence & occupied).astype(np.float32), k)
    share = np.divide(ev, occ, out=np.zeros_like(ev), where=occ > 1e-6)
    mask = (share > MIN_SHARE) & (occ > MIN_OCCUPIED)
    s = np.ones((_cells(CLOSE_M, res) | 1,) * 2, bool)
    mask = ndimage.binary_closing(mask, s, border_value=0)
    mask = ndimage.binary_opening(mask, s, border_value=0)
    return mask, share


def _boxes(mask: np.ndarray, share: np.ndarray, res: float):
    lab, _ = ndimage.label(mask)
    min_side = _cells(MIN_SIDE_M, res)
    for i, sl in enumerate(ndimage.find_objects(lab), start=1):
        if sl is None:
            continue
        y0, y1, x0, x1 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
        if min(y1 - y0, x1 - x0) < min_side:
            continue
        piece = lab[sl] == i
        if piece.mean() < MIN_FILL:
            continue
        yield (x0, y0, x1, y1), piece, float(share[sl][piece].mean())


def detect_elements(maps: FacadeMaps) -> list[Element]:
    """Windows, doors, balconies (and other protrusions) of one facade, left to right then
    top to bottom; see the module docstring."""
    res = maps.resolution
    occupied = maps.count > 0
    depth = np.nan_to_num(maps.depth, nan=0.0)
    front = np.nan_to_num(maps.front, nan=0.0)
    out: list[Element] = []
    # the facade's foot: the lowest row with wall points across a tenth of the width
    rows = np.flatnonzero((occupied & (np.abs(depth) < 2 * RECESS)).sum(1) > 0.1 * maps.shape[1])
    foot = (maps.shape[0] - 1 - rows.max()) * res if len(rows) else 0.0
    recessed = depth < -RECESS
    mask, share = _pieces(recessed, occupied, res)
    for box, piece, score in _boxes(mask, share, res):
        x0, y0, x1, y1 = box
        u0, v0, u1, v1 = maps.box_m(box)
        sub = recessed[y0:y1, x0:x1] & piece & occupied[y0:y1, x0:x1]
        d = float(np.median(depth[y0:y1, x0:x1][sub])) if sub.any() else -RECESS
        door = v0 - foot <= DOOR_FOOT_M and v1 - v0 >= DOOR_MIN_HEIGHT
        out.append(Element("door" if door else "window", (u0, v0, u1, v1), box, d, score))
    protruding = front > PROTRUDE
    mask, share = _pieces(protruding, occupied, res)
    for box, piece, score in _boxes(mask, share, res):
        x0, y0, x1, y1 = box
        u0, v0, u1, v1 = maps.box_m(box)
        sub = protruding[y0:y1, x0:x1] & piece
        d = float(np.median(front[y0:y1, x0:x1][sub])) if sub.any() else PROTRUDE
        label = "balcony" if v0 - foot >= BALCONY_MIN_HEIGHT else "protrusion"
        out.append(Element(label, (u0, v0, u1, v1), box, d, score))
    out.sort(key=lambda e: (-e.box_m[3], e.box_m[0]))
    return out
