"""A label map completed from its own repetition (not in seed ``shang2023``, which completes
labels by direction-guided PatchMatch, §3.2).

What an occluder hides on a facade is mostly known from the facade's structure: windows stand in
rows (shared y-intervals) and columns (shared x-intervals), so a window hidden by a tree is
where the row of its neighbours crosses the column of the windows above it.

:func:`element_groups`
    Instances of repeated elements — connected components of each element class, grouped into
    clusters of one class and similar size linked by row or column alignment.  The clusters are
    the ``groups`` of :func:`facadeforge.repair.repetition.repetition_fill`.

:func:`complete_labels_structure`
    1. *Visible elements*: components of each element class among the known pixels.  For a
       component touching the hole an edge of its box is *seen* where the component reaches it
       next to a visible pixel (elements are rectangles: one such pixel confirms the whole
       edge); its y-extent is reliable when top and bottom are seen, its x-extent when left and
       right are.
    2. *Rows*: elements of one class with reliable y-extents whose tops and bottoms agree
       (within ``max(2, 0.2·h)`` px) form a row, its interval the medians; *columns* the same
       with x-extents.  Each row records the median width of its members, each column the
       median height (the cluster's size) — unless the members' sizes disagree (fewer than 3 in
       4 within 25 % of the median: shop fronts of assorted widths), when it has no size.
    3. *Cells*: every row × column of the same class whose sizes agree (within 25 %) is a grid
       cell.  A cell that lies (partly) in the hole, whose row *and* column each hold a visible
       element elsewhere, and whose visible part does not contradict it (at least half of its
       visible pixels are of the class, or under 10 % of it is visible) is painted into the
       hole — completing a partly hidden element, or restoring a wholly hidden one.
    4. *Partly hidden elements* the grid does not explain are grown into the hole along the
       side they are open on (one per axis): to their row's far edge when their near edge is
       the row's, else by the size of the column (row) they align with; an element open at the
       bottom with nothing to tell its height, over a hole reaching down to the facade's
       bottom (the lowest row whose visible pixels are mostly wall or elements), grows to
       it — doors and shop fronts stand on the ground.  Again the visible part of the grown
       box must not contradict it.  Cells and grown boxes are painted class by class in the
       order of ``element_classes``, later classes over earlier ones (balconies over windows).
    5. *Wall*: a hole pixel not explained so far becomes ``wall`` only where it is
       surrounded by wall: looking left, right, up and down, the first pixel outside the
       undecided hole is, in at least three directions (image borders do not count) and in
       every direction that has one, wall or a *complete* element (a painted or grown box, a
       visible element in a row and a column, or one that does not touch the hole) — the wall
       goes on around complete elements — and wall in at least one.  Everything else stays
       undecided for a texture-driven completion (PatchMatch) to take.

The undecided rest is best taken from the visible pixels (how this completion scored
against the nearest visible pixel: ``docs/design-measurements.md``).  An element seen only
in its row, or only in its column, and hidden whole is not restored (a balcony with no
balcony above or below it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage as ndi

from facadeforge.errors import InputError

__all__ = ["Element", "complete_labels_structure", "element_groups", "visible_elements"]

#: Tolerance of interval agreement (fraction of the element's side, at least ``2`` px).
ALIGN_FRAC = 0.2
#: Relative size difference two elements of one cluster may have.
SIZE_FRAC = 0.25


@dataclass(frozen=True)
class Element:
    """One connected component of an element class.

    ``box`` is ``(x0, y0, x1, y1)``, exclusive ends; ``touches`` whether it borders the hole;
    ``full_x`` / ``full_y`` whether its x- / y-extent is known: both its left and right (top
    and bottom) edges are seen, reached by the component next to a visible pixel; ``open``
    which edges (top, bottom, left, right) are not seen, so it may go on into the hole there.
    """

    cls: int
    box: tuple[int, int, int, int]
    area: int
    touches: bool
    full_x: bool
    full_y: bool
    open: tuple[bool, bool, bool, bool] = (False, False, False, False)   # top, bottom, l, r

    @property
    def w(self) -> int:
        return self.box[2] - self.box[0]

    @property
    def h(self) -> int:
        return self.box[3] - self.box[1]


def _check_labels(labels, hole, who: str) -> tuple[np.ndarray, np.ndarray]:
    lab = np.asarray(labels)
    if lab.ndim != 2 or not np.issubdtype(lab.dtype, np.integer):
        raise InputError(f"{who}: labels must be an (H, W) integer class-index map, got shape "
                         f"{lab.shape} dtype {lab.dtype}")
    if hole is None:
        return lab, np.zeros(lab.shape, bool)
    m = np.asarray(hole)
    if m.shape != lab.shape:
        raise InputError(f"{who}: hole has shape {m.shape}, the labels {lab.shape}; pass an "
                         "(H, W) bool mask of the label map's size")
    return lab, m.astype(bool)


def visible_elements(labels: np.ndarray, classes: Sequence[int], hole: np.ndarray | None = None,
                     *, min_area: int = 20) -> list[Element]:
    """Connected components (4-connected) of each class among the pixels outside ``hole``."""
    lab, m = _check_labels(labels, hole, "visible_elements")
    h, w = lab.shape
    grown = ndi.binary_dilation(m) if m.any() else m
    out = []
    for c in classes:
        comp, n = ndi.label((lab == c) & ~m)
        if n == 0:
            continue
        areas = np.bincount(comp.ravel(), minlength=n + 1)
        touch = np.bincount(comp[grown].ravel(), minlength=n + 1) > 0
        for k, sl in enumerate(ndi.find_objects(comp), start=1):
            if sl is None or areas[k] < min_area:
                continue
            y0, y1, x0, x1 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
            full_x = full_y = True
            top = bot = left = right = True
            if touch[k]:
                own = comp[sl] == k
                # an edge is seen where the component reaches it next to a visible pixel
                top = y0 == 0 or bool((own[0] & ~m[y0 - 1, x0:x1]).any())
                bot = y1 == h or bool((own[-1] & ~m[y1, x0:x1]).any())
                left = x0 == 0 or bool((own[:, 0] & ~m[y0:y1, x0 - 1]).any())
                right = x1 == w or bool((own[:, -1] & ~m[y0:y1, x1]).any())
                full_y, full_x = top and bot, left and right
            out.append(Element(int(c), (x0, y0, x1, y1), int(areas[k]), bool(touch[k]),
                               full_x, full_y, (not top, not bot, not left, not right)))
    return out


class _Union:
    def __init__(self, n: int):
        self.p = list(range(n))

    def find(self, a: int) -> int:
        while self.p[a] != a:
            self.p[a] = self.p[self.p[a]]
            a = self.p[a]
        return a

    def join(self, a: int, b: int) -> None:
        self.p[self.find(a)] = self.find(b)

    def sets(self) -> list[list[int]]:
        out: dict[int, list[int]] = {}
        for i in range(len(self.p)):
            out.setdefault(self.find(i), []).append(i)
        return list(out.values())


def _agree(a0: float, a1: float, b0: float, b1: float) -> bool:
    """Both ends of two intervals within the alignment tolerance."""
    tol = max(2.0, ALIGN_FRAC * min(a1 - a0, b1 - b0))
    return abs(a0 - b0) <= tol and abs(a1 - b1) <= tol


def _similar(a: float, b: float) -> bool:
    return abs(a - b) <= max(2.0, SIZE_FRAC * max(a, b))


def _overlap(a0: float, a1: float, b0: float, b1: float) -> float:
    return max(0.0, min(a1, b1) - max(a0, b0))


def element_groups(labels: np.ndarray, classes: Sequence[int], *, hole: np.ndarray | None = None,
                   min_area: int = 20) -> list[list[tuple[int, int, int, int]]]:
    """Clusters of repeated elements in a class-index label map, as lists of boxes.

    Components (4-connected, at least ``min_area`` px) of each class in ``classes``; two of
    one class are linked when their widths and heights agree within 25 % and they share a row
    (their y-intervals overlap by half the smaller height) or a column (x-intervals likewise).
    A cluster is a connected set of links with at least two members.  With ``hole``, components
    touching it do not make links of their own (a partly hidden or half-completed element has
    an unreliable box): they join the cluster of a clean component they are linked to, or are
    left out — so an occluded instance is in its cluster exactly when its box has that
    cluster's size, which is what :func:`~facadeforge.repair.repetition.repetition_fill` needs
    to paint it.  The label map is read whole, hole included (pass the completed labels).

    Returns
    -------
    list of list of (x0, y0, x1, y1)
        Clusters in the order of ``classes``, then top to bottom; boxes in raster order.
    """
    lab, m = _check_labels(labels, hole, "element_groups")
    grown = ndi.binary_dilation(m) if m.any() else m
    elems = []
    for c in classes:
        comp, n = ndi.label(lab == c)
        if n == 0:
            continue
        areas = np.bincount(comp.ravel(), minlength=n + 1)
        touch = np.bincount(comp[grown].ravel(), minlength=n + 1) > 0
        for k, sl in enumerate(ndi.find_objects(comp), start=1):
            if sl is not None and areas[k] >= min_area:
                elems.append((int(c), (sl[1].start, sl[0].start, sl[1].stop, sl[0].stop),
                              bool(touch[k])))
    uf = _Union(len(elems))
    linked = [False] * len(elems)
    for i, (ci, (ax0, ay0, ax1, ay1), ti) in enumerate(elems):
        for j in range(i + 1, len(elems)):
            cj, (bx0, by0, bx1, by1), tj = elems[j]
            if cj != ci or (ti and tj):
                continue
            if not (_similar(ax1 - ax0, bx1 - bx0) and _similar(ay1 - ay0, by1 - by0)):
                continue
            row = _overlap(ay0, ay1, by0, by1) >= 0.5 * min(ay1 - ay0, by1 - by0)
            col = _overlap(ax0, ax1, bx0, bx1) >= 0.5 * min(ax1 - ax0, bx1 - bx0)
            if not (row or col):
                continue
            if ti or tj:                 # a touching element hangs on, never bridges
                t, o = (i, j) if ti else (j, i)
                if linked[t]:
                    continue
                linked[t] = True
                uf.join(t, o)
            else:
                uf.join(i, j)
    order = {c: k for k, c in enumerate(classes)}
    groups = []
    for s in uf.sets():
        clean = [k for k in s if not elems[k][2]]
        if len(s) < 2 or not clean:
            continue
        boxes = sorted((elems[k][1] for k in s), key=lambda b: (b[1], b[0]))
        groups.append((order[elems[s[0]][0]], boxes[0][1], [tuple(map(int, b)) for b in boxes]))
    groups.sort(key=lambda g: (g[0], g[1]))
    return [g[2] for g in groups]


@dataclass
class _Line:
    """A row (axis 1: y-interval) or column (x-interval) of one class."""

    cls: int
    lo: float
    hi: float
    members: list[int]
    size: float | None          # median extent of the members along the other axis


def _lines(elems: list[Element], axis: int) -> list[_Line]:
    """Rows (``axis=1``, shared y-intervals) or columns (``axis=0``) of same-class elements."""
    idx = [k for k, e in enumerate(elems) if (e.full_y if axis == 1 else e.full_x)]
    iv = {k: ((elems[k].box[1], elems[k].box[3]) if axis == 1 else
              (elems[k].box[0], elems[k].box[2])) for k in idx}
    uf = _Union(len(idx))
    for a in range(len(idx)):
        for b in range(a + 1, len(idx)):
            ea, eb = elems[idx[a]], elems[idx[b]]
            if ea.cls == eb.cls and _agree(*iv[idx[a]], *iv[idx[b]]):
                uf.join(a, b)
    out = []
    for s in uf.sets():
        mem = [idx[k] for k in s]
        lo = float(np.median([iv[k][0] for k in mem]))
        hi = float(np.median([iv[k][1] for k in mem]))
        other = [(elems[k].w if axis == 1 else elems[k].h) for k in mem
                 if (elems[k].full_x if axis == 1 else elems[k].full_y)]
        size = float(np.median(other)) if other else None
        if size is not None and sum(_similar(o, size) for o in other) < 0.75 * len(other):
            size = None                 # members of assorted sizes (shop fronts): no one size
        out.append(_Line(elems[mem[0]].cls, lo, hi, mem, size))
    return out


#: Grow a partly hidden element down to the facade's bottom when nothing else tells its height
#: and the hole runs down to it (shops and doors stand on the ground).
GROUND = True
#: Directions whose first pixel outside the hole must be wall for the wall rule.
MIN_WALL_HITS = 1


def _ground(lab: np.ndarray, m: np.ndarray, facade: list[int]) -> int | None:
    """One past the lowest row whose visible pixels are mostly facade (wall or elements)."""
    seen = (~m).sum(1)
    fac = (np.isin(lab, facade) & ~m).sum(1)
    rows = np.nonzero((seen > 0) & (fac >= 0.5 * seen))[0]
    return int(rows[-1]) + 1 if len(rows) else None


def _extend(e: Element, m: np.ndarray, rows: list[_Line], cols: list[_Line], h: int, w: int,
            ground: int | None) -> tuple[int, int, int, int] | None:
    """The box of a partly hidden element grown into the hole along one open side per axis:
    to its row's far edge when its near edge is the row's, else by its column's (row's) size;
    None when nothing is known."""
    x0, y0, x1, y1 = e.box
    open_t, open_b, open_l, open_r = e.open
    same_r = [r for r in rows if r.cls == e.cls]
    same_c = [c for c in cols if c.cls == e.cls]

    def tol(a, b):
        return max(2.0, ALIGN_FRAC * (b - a))

    nx0, ny0, nx1, ny1 = x0, y0, x1, y1
    if open_b != open_t:
        if open_b:
            far = [r.hi for r in same_r if abs(r.lo - y0) <= tol(r.lo, r.hi) and r.hi > y1]
            far += [y0 + c.size for c in same_c if c.size and _agree(c.lo, c.hi, x0, x1)
                    and y0 + c.size > y1]
            if (not far and ground is not None and ground > y1
                    and m[y1:ground, (x0 + x1) // 2].all()):
                far = [ground]
            if far:
                ny1 = int(round(far[0]))
        else:
            far = [r.lo for r in same_r if abs(r.hi - y1) <= tol(r.lo, r.hi) and r.lo < y0]
            far += [y1 - c.size for c in same_c if c.size and _agree(c.lo, c.hi, x0, x1)
                    and y1 - c.size < y0]
            if far:
                ny0 = int(round(far[0]))
    if open_r != open_l:
        if open_r:
            far = [c.hi for c in same_c if abs(c.lo - x0) <= tol(c.lo, c.hi) and c.hi > x1]
            far += [x0 + r.size for r in same_r if r.size and _agree(r.lo, r.hi, y0, y1)
                    and x0 + r.size > x1]
            if far:
                nx1 = int(round(far[0]))
        else:
            far = [c.lo for c in same_c if abs(c.hi - x1) <= tol(c.lo, c.hi) and c.lo < x0]
            far += [x1 - r.size for r in same_r if r.size and _agree(r.lo, r.hi, y0, y1)
                    and x1 - r.size < x0]
            if far:
                nx0 = int(round(far[0]))
    nx0, ny0, nx1, ny1 = max(nx0, 0), max(ny0, 0), min(nx1, w), min(ny1, h)
    if (nx0, ny0, nx1, ny1) == (x0, y0, x1, y1):
        return None
    return nx0, ny0, nx1, ny1


def _first_hit(known: np.ndarray, axis: int, reverse: bool) -> np.ndarray:
    """Index along ``axis`` of the nearest ``known`` pixel before (or after, ``reverse``) each
    pixel; -1 where there is none."""
    k = np.moveaxis(known, axis, -1)
    n = k.shape[-1]
    if reverse:
        k = k[..., ::-1]
    pos = np.where(k, np.arange(n), -1)
    last = np.maximum.accumulate(pos, axis=-1)
    prev = np.concatenate([np.full(last.shape[:-1] + (1,), -1), last[..., :-1]], -1)
    if reverse:
        prev = np.where(prev >= 0, n - 1 - prev, -1)[..., ::-1]
    return np.moveaxis(prev, -1, axis)


def complete_labels_structure(labels: np.ndarray, hole: np.ndarray, *,
                              element_classes: Sequence[int], wall: int,
                              min_area: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Complete the hole of a label map from the facade grid of its visible elements.

    Parameters
    ----------
    labels : (H, W) int
        Class-index map; values under ``hole`` are ignored.
    hole : (H, W) bool
        Unknown pixels.
    element_classes : sequence of int
        Classes of repeated elements (windows, balconies, doors…), in painting order.
    wall : int
        The wall class, given to hole pixels surrounded by wall.
    min_area : int
        Smallest component taken for an element.

    Returns
    -------
    (labels, decided)
        A completed copy and the ``(H, W)`` bool mask of the hole pixels it set; the other hole
        pixels keep their input values.

    Raises
    ------
    InputError
        Bad shapes or dtype, ``wall`` among ``element_classes``.
    """
    lab, m = _check_labels(labels, hole, "complete_labels_structure")
    classes = [int(c) for c in element_classes]
    if int(wall) in classes:
        raise InputError(f"complete_labels_structure: wall={wall} is also an element class; "
                         "pass the wall class apart from element_classes")
    out = lab.copy()
    decided = np.zeros_like(m)
    if not m.any():
        return out, decided
    h, w = lab.shape
    elems = visible_elements(lab, classes, m, min_area=min_area)
    rows, cols = _lines(elems, 1), _lines(elems, 0)
    complete = np.zeros_like(m)               # pixels of elements whose extent is known
    for e in elems:
        x0, y0, x1, y1 = e.box
        if not e.touches:
            complete[y0:y1, x0:x1] |= lab[y0:y1, x0:x1] == e.cls
    in_row = {k for r in rows for k in r.members}
    in_col = {k for c in cols for k in c.members}
    for k, e in enumerate(elems):
        if e.touches and k in in_row and k in in_col:
            x0, y0, x1, y1 = e.box
            complete[y0:y1, x0:x1] |= lab[y0:y1, x0:x1] == e.cls
    ground = _ground(lab, m, classes + [int(wall)]) if GROUND else None
    proposals: dict[int, list[tuple[int, int, int, int]]] = {c: [] for c in classes}
    for c in classes:
        for r in (r for r in rows if r.cls == c):
            for col in (q for q in cols if q.cls == c):
                if r.size is not None and not _similar(r.size, col.hi - col.lo):
                    continue
                if col.size is not None and not _similar(col.size, r.hi - r.lo):
                    continue
                x0, x1 = int(round(col.lo)), int(round(col.hi))
                y0, y1 = int(round(r.lo)), int(round(r.hi))
                if x1 <= x0 or y1 <= y0:
                    continue
                cell_hole = m[y0:y1, x0:x1]
                if not cell_hole.any():
                    continue
                # the row and the column must each show the element somewhere else
                if not any(_overlap(elems[k].box[0], elems[k].box[2], x0, x1) == 0
                           for k in r.members):
                    continue
                if not any(_overlap(elems[k].box[1], elems[k].box[3], y0, y1) == 0
                           for k in col.members):
                    continue
                seen = ~cell_hole
                n_seen = int(seen.sum())
                if n_seen >= 0.1 * seen.size:
                    agree = int((lab[y0:y1, x0:x1][seen] == c).sum())
                    if agree < 0.5 * n_seen:
                        continue
                proposals[c].append((x0, y0, x1, y1))
    # partly hidden elements: grown from one row or one column
    for e in elems:
        if not e.touches:
            continue
        box = _extend(e, m, rows, cols, h, w, ground)
        if box is None:
            continue
        x0, y0, x1, y1 = box
        seen = ~m[y0:y1, x0:x1]
        if seen.any() and (lab[y0:y1, x0:x1][seen] == e.cls).mean() < 0.5:
            continue
        proposals[e.cls].append(box)
    for c in classes:                       # in the given order: later classes over earlier
        for x0, y0, x1, y1 in proposals[c]:
            sub_m = m[y0:y1, x0:x1]
            out[y0:y1, x0:x1][sub_m] = c
            decided[y0:y1, x0:x1] |= sub_m
            complete[y0:y1, x0:x1] |= sub_m
    # wall where the rest of the hole is surrounded by wall (or by complete elements)
    rest = m & ~decided
    if rest.any():
        known = ~rest
        ok_px = (out == wall) | complete
        is_wall = out == wall
        yy, xx = np.mgrid[:h, :w]
        okd, walld, hasd = [], [], []
        for axis, rev in ((1, False), (1, True), (0, False), (0, True)):
            idx = _first_hit(known, axis, rev)
            has = idx >= 0
            iy = np.where(has, idx, 0) if axis == 0 else yy
            ix = np.where(has, idx, 0) if axis == 1 else xx
            hasd.append(has)
            okd.append(has & ok_px[iy, ix])
            walld.append(has & is_wall[iy, ix])
        hits = sum(x.astype(np.int8) for x in hasd)
        oks = sum(x.astype(np.int8) for x in okd)
        walls = sum(x.astype(np.int8) for x in walld)
        to_wall = rest & (oks == hits) & (walls >= MIN_WALL_HITS) & (hits >= 3)
        out[to_wall] = wall
        decided |= to_wall
    return out, decided
