"""Facade elements found on a facade's depth map: windows and doors as recesses, balconies as
protrusions (CityFit §3's "segmentation for the depth map").

``hohmann2009`` §3 segments the depth map by plane ("the same z-value is a strong clue for
elements to carry the same grammar symbol") and notes what a laser sees of a facade: reflective
glass returns little and what it lets through lies behind the wall (``simon2011`` §5.4.3).  So an
opening is a part of the facade where most points lie *behind* the wall plane — the window frame
and glass set back in the wall, the shop interior seen through a shop front — and a balcony or
sign is where the front-most points stand well *in front* of it:

1. per cell, ``recessed`` (its back-most point below −:data:`RECESS` m from the wall around it
   — what a railing, a tree or a car in front hides shows behind them;
   :func:`wall_depth`: houses of a street front stand at different depths) and ``occupied``
   (any point); empty pieces of the facade where glass gave no return, next to a recess,
   count as recessed (:func:`glass_holes`: glass "returns little", ``simon2011`` §5.4.3);
   (a density cue — cells with under 30 % of the wall's point density around them as flush
   glass — was tried and lowered F1 on NUIST and on the synthetic scans);
2. the recessed share of the occupied cells in a :data:`WINDOW_M` box (a box filter on each),
   above :data:`MIN_SHARE` where at least :data:`MIN_OCCUPIED` of the box holds points — the
   scan's line pattern leaves empty stripes on a wall, and an opening with no return at all is
   an occlusion, a removed sign or the sky, not evidence of a window;
3. a morphological closing then opening of :data:`CLOSE_M` (mullions and transoms, which sit
   at the frame's depth too, do not cut a window in two; speckle goes);
4. each connected piece is an element: its bounding rectangle, shrunk to the rows and
   columns holding its evidence (:func:`_tighten`), kept when at least
   :data:`MIN_SIDE_M` on both sides and filled to :data:`MIN_FILL` by the mask;
5. its **label**: ``door`` when its foot is within :data:`DOOR_FOOT_M` of the facade's foot
   and it is at least :data:`DOOR_MIN_HEIGHT` tall (doors and shop fronts), else ``window``;
   its **depth** is the measured one, the median depth of its recessed cells.

A piece larger than :data:`MAX_OPENING_SHARE` of the facade or wider than
:data:`MAX_OPENING_M` is no opening but a house standing back from the plane: its own wall
depth is measured and its openings found as recesses of it.

A window whose foot meets a balcony below is a French window behind it: it reaches down to
the balcony's floor (what the balcony hides, the scan cannot see).

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

__all__ = ["Element", "detect_elements", "glass_holes", "sparse_glass", "wall_depth"]

#: Which depth of a cell decides whether it is recessed: its back-most point or its median.
BEHIND = "back"
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
#: A hole (no return) is glass when this share of its rim is recessed.
HOLE_RECESS_SHARE = 0.25
#: Largest side (m) of a hole taken for glass (a bigger void is sky or a missing wall).
MAX_HOLE_M = 4.0
#: A piece is flush glass where the share of cells with a point is below this share of the
#: wall's around it.
SPARSE_SHARE = 0.3
#: A door's foot lies within this of the facade's foot (m) and it is at least this tall (m).
DOOR_FOOT_M, DOOR_MIN_HEIGHT = 0.5, 1.6
#: Share of a column's cells a depth must hold (±2 cm) to be its wall.
WALL_SUPPORT = 0.12
#: Share of its peak row (column) count of evidence at which a box edge is drawn.
TIGHTEN = 0.3
#: A window whose foot is within this (m) above a balcony's top stands behind it.
BALCONY_GAP_M = 0.3
#: Width (m) over which the wall's depth is smoothed along the facade.
WALL_SPAN_M = 6.0
#: An opening larger than this share of the facade, or wider than this (m), is a wall set
#: back from the plane, searched again for openings relative to its own depth.
MAX_OPENING_SHARE, MAX_OPENING_M = 0.12, 8.0
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


def wall_depth(maps: FacadeMaps) -> np.ndarray:
    """The wall's depth (m) in each column of the rasters: of the depths (2 cm bins, ±2 cm
    windows) holding at least :data:`WALL_SUPPORT` of the column's cells, the one nearest the
    plane (not the front-most: that would take a shop sign a hand in front of the wall for the
    wall; the same on every scan measured here), else the most common; median-filtered over :data:`WALL_SPAN_M`.  One plane rarely holds a whole street front: a house set back or
    standing forward from its neighbour is wall at its own depth, and its windows are recesses
    *of that wall*."""
    d = maps.depth
    h, w = d.shape
    bins = np.round(np.clip(np.nan_to_num(d, nan=-9.0), -1.0, 1.0) / 0.02).astype(np.int64) + 50
    ok = np.isfinite(d)
    hist = np.zeros((w, 101), np.int64)
    cols = np.broadcast_to(np.arange(w), (h, w))
    np.add.at(hist, (cols[ok], bins[ok]), 1)
    # a 3-bin window (±2 cm) per depth, then the support nearest the plane that holds at
    # least WALL_SUPPORT of the column: the wall, unless the whole column stands elsewhere
    tot = hist.sum(1)
    has = tot > 0
    sm = hist + np.roll(hist, 1, axis=1) + np.roll(hist, -1, axis=1)
    strong = sm >= WALL_SUPPORT * np.maximum(tot, 1)[:, None]
    dist = np.abs(np.arange(101) - 50)[None, :] + np.where(strong, 0, 1000)
    mode = (np.argmin(dist, axis=1) - 50) * 0.02
    weak = ~strong.any(1)
    mode[weak] = (np.argmax(sm[weak], axis=1) - 50) * 0.02
    if not has.any():
        return np.zeros(w)
    mode = np.interp(np.arange(w), np.flatnonzero(has), mode[has])
    k = max(1, int(round(WALL_SPAN_M / maps.resolution))) | 1
    return ndimage.median_filter(mode, size=k, mode="nearest")


def _tighten(evidence: np.ndarray, box, piece: np.ndarray) -> tuple[int, int, int, int]:
    """A piece's box shrunk to its evidence: the rows and columns where the evidence cells
    of the piece reach :data:`TIGHTEN` of their peak count (the box filter and the closing
    grow a piece by about half their size)."""
    x0, y0, x1, y1 = box
    ev = evidence[y0:y1, x0:x1] & piece
    rows, cols = ev.sum(1), ev.sum(0)
    if not rows.any():
        return box
    r = np.flatnonzero(rows >= TIGHTEN * rows.max())
    c = np.flatnonzero(cols >= TIGHTEN * cols.max())
    return x0 + int(c[0]), y0 + int(r[0]), x0 + int(c[-1]) + 1, y0 + int(r[-1]) + 1


def glass_holes(occupied: np.ndarray, recessed: np.ndarray, res: float) -> np.ndarray:
    """Cells of the facade where glass gave no return: empty pieces inside the facade's
    silhouette, :data:`MIN_SIDE_M` to :data:`MAX_HOLE_M` across, that touch a recess over
    :data:`HOLE_RECESS_SHARE` of their rim — the pane below a window frame that did return.
    (Empty pieces enclosed by wall alone were tried as panes with no return at all: on the
    NUIST facade they merged the void of a gable into a window, and they found no more windows
    on the synthetic scans.)  The scan's line pattern leaves empty stripes on walls: an
    opening by :data:`MIN_SIDE_M` / 2 removes them first."""
    s = np.ones((9, 9), bool)
    inside = ndimage.binary_fill_holes(ndimage.binary_closing(occupied, s, border_value=0))
    k = max(3, _cells(MIN_SIDE_M / 2, res)) | 1
    empty = ndimage.binary_opening(inside & ~occupied, np.ones((k, k), bool))
    lab, _ = ndimage.label(empty)
    out = np.zeros_like(occupied)
    min_side = _cells(MIN_SIDE_M, res)
    max_side = _cells(MAX_HOLE_M, res)
    for i, sl in enumerate(ndimage.find_objects(lab), start=1):
        if sl is None:
            continue
        y0, y1 = max(sl[0].start - 1, 0), min(sl[0].stop + 1, lab.shape[0])
        x0, x1 = max(sl[1].start - 1, 0), min(sl[1].stop + 1, lab.shape[1])
        piece = lab[y0:y1, x0:x1] == i
        hh, ww = sl[0].stop - sl[0].start, sl[1].stop - sl[1].start
        if min(hh, ww) < min_side or max(hh, ww) > max_side:
            continue
        rim = ndimage.binary_dilation(piece, np.ones((3, 3), bool)) & ~piece
        if not rim.any():
            continue
        if recessed[y0:y1, x0:x1][rim].mean() >= HOLE_RECESS_SHARE:
            out[y0:y1, x0:x1] |= piece
    return out


def sparse_glass(occupied: np.ndarray, res: float) -> np.ndarray:
    """Flush glazing that returned few points: pieces of the facade, inside its silhouette and
    clear of its outline, where the share of cells holding a point (over :data:`WINDOW_M`)
    falls below :data:`SPARSE_SHARE` of the wall's around it (the 90th percentile of that share
    within :data:`WALL_SPAN_M`, which follows a scanner's fall of density with range), at least
    :data:`MIN_SIDE_M` and at most :data:`MAX_HOLE_M` across and filling :data:`MIN_FILL` of
    their rectangle (a pane, not a void of the outline)."""
    k = _cells(WINDOW_M, res) | 1
    share = ndimage.uniform_filter(occupied.astype(np.float32), k)
    span = max(3, _cells(WALL_SPAN_M / 2, res) // 4)
    ref = ndimage.percentile_filter(share[::4, ::4], 90, size=span)
    ref = np.kron(ref, np.ones((4, 4), np.float32))[:share.shape[0], :share.shape[1]]
    s = np.ones((9, 9), bool)
    inside = ndimage.binary_fill_holes(ndimage.binary_closing(occupied, s, border_value=0))
    core = ndimage.binary_erosion(inside, np.ones((2 * k + 1,) * 2, bool))
    sparse = core & (ref > 0.3) & (share < SPARSE_SHARE * ref)
    lab, _ = ndimage.label(sparse)
    out = np.zeros_like(occupied)
    lo, hi = _cells(MIN_SIDE_M, res), _cells(MAX_HOLE_M, res)
    for i, sl in enumerate(ndimage.find_objects(lab), start=1):
        if sl is None:
            continue
        hh, ww = sl[0].stop - sl[0].start, sl[1].stop - sl[1].start
        piece = lab[sl] == i
        if min(hh, ww) >= lo and max(hh, ww) <= hi and piece.mean() >= MIN_FILL:
            out[sl] |= piece
    return out


class _Sub:
    """A window of a facade's rasters, for :func:`wall_depth` on part of a facade."""

    def __init__(self, maps: FacadeMaps, box):
        x0, y0, x1, y1 = box
        self.depth = maps.depth[y0:y1, x0:x1]
        self.resolution = maps.resolution


def detect_elements(maps: FacadeMaps) -> list[Element]:
    """Windows, doors, balconies (and other protrusions) of one facade, left to right then
    top to bottom; see the module docstring.  Depths are measured from the wall around the
    element (:func:`wall_depth`)."""
    res = maps.resolution
    occupied = maps.count > 0
    wall = wall_depth(maps)[None, :]
    depth = np.nan_to_num(maps.depth - wall, nan=0.0)
    front = np.nan_to_num(maps.front - wall, nan=0.0)
    out: list[Element] = []
    # the facade's foot: the lowest row with wall points across a tenth of the width
    rows = np.flatnonzero((occupied & (np.abs(depth) < 2 * RECESS)).sum(1) > 0.1 * maps.shape[1])
    foot = (maps.shape[0] - 1 - rows.max()) * res if len(rows) else 0.0
    behind = maps.back if (BEHIND == "back" and maps.back is not None) else maps.depth
    back = np.nan_to_num(behind - wall, nan=0.0)
    recessed = back < -RECESS
    holes = glass_holes(occupied, recessed, res)
    if SPARSE_SHARE > 0:
        holes |= sparse_glass(occupied, res)
    recessed |= holes
    occupied = occupied | holes
    mask, share = _pieces(recessed, occupied, res)
    found = list(_boxes(mask, share, res))
    limit = MAX_OPENING_SHARE * maps.shape[0] * maps.shape[1]
    for box, piece, score in list(found):
        x0, y0, x1, y1 = box
        if (x1 - x0) * (y1 - y0) <= limit and (x1 - x0) * res <= MAX_OPENING_M:
            continue
        # too big to be an opening: a wall standing back from the plane (a house set back
        # from its neighbours); its openings are recesses of *its* depth
        found.remove((box, piece, score))
        sub = _Sub(maps, box)
        inner = np.nan_to_num(maps.depth[y0:y1, x0:x1] - wall_depth(sub)[None, :], nan=0.0)
        rec_in = inner < -RECESS
        m_in, s_in = _pieces(rec_in, occupied[y0:y1, x0:x1], res)
        for b, p, sc in _boxes(m_in, s_in, res):
            bx = (b[0] + x0, b[1] + y0, b[2] + x0, b[3] + y0)
            if (b[2] - b[0]) * (b[3] - b[1]) <= limit and (b[2] - b[0]) * res <= MAX_OPENING_M:
                depth[bx[1]:bx[3], bx[0]:bx[2]] = inner[b[1]:b[3], b[0]:b[2]]
                recessed[bx[1]:bx[3], bx[0]:bx[2]] = rec_in[b[1]:b[3], b[0]:b[2]]
                found.append((bx, p, sc))
    for box, piece, score in found:
        tight = _tighten(recessed & occupied, box, piece)
        piece = piece[tight[1] - box[1]:tight[3] - box[1], tight[0] - box[0]:tight[2] - box[0]]
        box = tight
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
    _behind_balconies(out, maps)
    out.sort(key=lambda e: (-e.box_m[3], e.box_m[0]))
    return out


def _behind_balconies(elements: list[Element], maps: FacadeMaps) -> None:
    """A window whose foot meets a balcony is a French window opening onto it: the balcony
    hides the rest of it from the street, so it reaches down to the balcony's floor (in place).
    """
    balconies = [e for e in elements if e.label == "balcony"]
    for i, e in enumerate(elements):
        if e.label != "window":
            continue
        u0, v0, u1, v1 = e.box_m
        for b in balconies:
            bu0, bv0, bu1, bv1 = b.box_m
            overlap = min(u1, bu1) - max(u0, bu0)
            if overlap < 0.5 * (u1 - u0) or not (bv0 < v0 <= bv1 + BALCONY_GAP_M):
                continue
            x0, _, x1, y1 = e.box_px
            y1 = max(y1, b.box_px[3])
            elements[i] = Element(e.label, (u0, bv0, u1, v1), (x0, e.box_px[1], x1, y1),
                                  e.depth, e.score)
            break
