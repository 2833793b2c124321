"""Floors, tiles and tile refinements around detected elements: the shape tree's splits when a
classifier found the facade's elements (:mod:`.detect`).

Müller et al. 2007 find floors and tiles first (§2, repetition detection) and the elements
inside the tiles afterwards (§3).  On CMP the repetition periods are often found at half or
double their value, and a regular grid at the wrong period cuts through most windows.  Once the
elements are known the order can be reversed: split lines must run through wall, so

- **floor lines** go into the gaps between rows of elements — every interior run of image rows
  that no element box covers holds one line (two touching rows: the line between them), at the
  minimum of the §2.4 interest function
  ``Ver(y)`` (eq. 4: strong horizontal edges such as ledges and sills) within the gap's middle
  60 %;
- **tile lines** go, per floor, into the gaps between the floor's elements — at the quietest
  column of the gap's middle 60 % (all edge energy, as stage 1 places tile lines between
  repeated windows, :func:`~.splits.floor_and_tile_split`);
- each tile's **refinement** is the §3 split tree that isolates its element: a ``dual-x`` (or
  ``left``/``right``) split into wall | centre | wall, then a ``dual-y`` (or ``top``/``bottom``)
  split of the centre into wall / element / wall — the split types of §3.1, so rule
  extraction (§5) treats them like detected refinements.  The rare tile holding several
  elements (stacked ones that no floor line separates) is cut recursively at the gaps between
  them.  Boxes in a pinwheel (no straight cut separates them) cannot be a split tree: the
  strongest is kept and the others dropped (none of the 3616 elements detected on the 300 CMP
  facades was).

Every line gets a confidence: how clearly it runs through wall, ``1 − mean P(element)`` along
it (the summed probability of the detected classes).

Elements that stand in front of the wall (balconies, :func:`~.detect.detect_protruding`) are
not part of the partition: a balcony hides the foot of the window behind it, which stays whole
(CMP's convention and the 3D reality).  They only move a floor line out of their way — into
the longest part of its gap that no balcony covers, so that a line runs under the balcony's
slab rather than through its railing — and are hung on the shape they stand in front of
(:attr:`ElementLayout.fronts`): the tile holding at least :data:`HOST_SHARE` of the balcony's
width when that tile is split around an element (a balcony per window), else the floor (a
balcony band running in front of several tiles).  The floor is the one holding the balcony's
centre row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .detect import Element
from .refine import Region, element_leaves
from .splits import edge_maps, interest_functions

__all__ = ["ElementLayout", "element_layout", "element_region", "refine_clusters"]

#: Fraction of a gap on each side where no line is placed (lines sit in the gap's middle).
GAP_MARGIN: float = 0.2
#: Share of a balcony's width that must lie in one tile for the balcony to hang on that tile
#: (less: it runs in front of several tiles and hangs on the floor).
HOST_SHARE: float = 0.9


@dataclass
class ElementLayout:
    """Floors ``(y0, y1)`` top to bottom, per floor its tiles ``(x0, x1)``, per tile a
    :class:`~.refine.Region` tree (``None`` = plain wall), the line confidences in the
    layout of :class:`~.splits.FacadeStructure` (``{"floors": [...], "tiles": [[...]]}``) and,
    per floor, the protruding elements in front of it as ``(tile index or None, leaf)``
    pairs (``None``: hung on the floor; the leaf a :class:`~.refine.Region` of role
    ``"element"``, left to right)."""

    floors: list[tuple[int, int]]
    tiles: list[list[tuple[int, int]]]
    regions: list[list[Region | None]]
    confidences: dict[str, list]
    floor_period_px: float = 0.0   # storey height: median of the floors between two lines
    fronts: list[list[tuple[int | None, Region]]] = field(default_factory=list)


def _gaps(spans: Sequence[tuple[int, int]]) -> list[tuple[int, int]]:
    """The gaps ``[a, b)`` between groups of overlapping 1-D ``spans`` (``a == b`` where two
    groups touch), in increasing order."""
    out: list[tuple[int, int]] = []
    ordered = sorted(spans)
    if not ordered:
        return out
    end = ordered[0][1]
    for a, b in ordered[1:]:
        if a >= end:
            out.append((end, a))
        end = max(end, b)
    return out


def _line_in_gap(cost: np.ndarray, gap: tuple[int, int]) -> int:
    """The line position in ``gap``: the minimum of ``cost`` over the gap's middle."""
    a, b = gap
    if b - a <= 1:
        return a
    m = int(GAP_MARGIN * (b - a))
    lo, hi = a + m, max(a + m + 1, b - m)
    return lo + int(np.argmin(cost[lo:hi]))


def _free_part(gap: tuple[int, int], spans: Sequence[tuple[int, int]]) -> tuple[int, int]:
    """The longest part of ``gap`` that no span covers (the gap itself when they cover it all)."""
    a, b = gap
    inside = [(max(s, a), min(e, b)) for s, e in spans if s < b and e > a]
    if not inside:
        return gap
    free = [g for g in _gaps([(a - 1, a), *inside, (b, b + 1)]) if g[1] > g[0]]
    return max(free, key=lambda g: g[1] - g[0]) if free else gap


def _host(e: Element, tiles: Sequence[tuple[int, int]],
          regions: Sequence[Region | None]) -> int | None:
    """Index of the tile ``e`` stands in front of, or ``None`` (module docstring)."""
    x0, _, x1, _ = e.box
    for j, (a, b) in enumerate(tiles):
        split = regions[j] is not None and regions[j].children   # a tile that is split
        if split and min(x1, b) - max(x0, a) >= HOST_SHARE * (x1 - x0):
            return j
    return None


def _hang(fronts: Sequence[Element], floors: Sequence[tuple[int, int]],
          tiles: Sequence[Sequence[tuple[int, int]]], regions: Sequence[Sequence[Region | None]]
          ) -> list[list[tuple[int | None, Region]]]:
    """:attr:`ElementLayout.fronts` of protruding elements (module docstring)."""
    out: list[list[tuple[int | None, Region]]] = [[] for _ in floors]
    starts = [y0 for y0, _ in floors]
    for e in sorted(fronts, key=lambda e: (e.box[0], e.box[1])):
        i = max(0, int(np.searchsorted(starts, (e.box[1] + e.box[3]) / 2, side="right")) - 1)
        leaf = Region(box=e.box, role="element", label=e.label, strength=e.score)
        out[i].append((_host(e, tiles[i], regions[i]), leaf))
    return out


def element_region(box: tuple[int, int, int, int], elements: Sequence[Element]) -> Region:
    """The §3-style split tree of a tile ``box`` isolating each of its ``elements``.

    Element leaves have ``role="element"`` and the element's ``label``; the rest is wall.
    """
    x0, y0, x1, y1 = box
    if not elements:
        return Region(box=box, role="wall")
    if len(elements) == 1:
        e = elements[0]
        ex0, ey0, ex1, ey1 = (max(x0, e.box[0]), max(y0, e.box[1]), min(x1, e.box[2]),
                              min(y1, e.box[3]))
        leaf = Region(box=(ex0, ey0, ex1, ey1), role="element", label=e.label,
                      strength=e.score)
        centre = _peel(leaf, (ex0, y0, ex1, y1), "y", ey0, ey1, e.score)
        return _peel(centre, box, "x", ex0, ex1, e.score)
    # several elements: cut between them (rows first, as floors are cut before tiles)
    for axis in ("y", "x"):
        k = 1 if axis == "y" else 0
        cut = _separating_cut(elements, k)
        if cut is None:
            continue
        first = (x0, y0, x1, cut) if axis == "y" else (x0, y0, cut, y1)
        second = (x0, cut, x1, y1) if axis == "y" else (cut, y0, x1, y1)
        parts = [element_region(first, [e for e in elements if e.box[k + 2] <= cut]),
                 element_region(second, [e for e in elements if e.box[k] >= cut])]
        return Region(box=box, split="top" if axis == "y" else "left", children=parts,
                      strength=float(min(e.score for e in elements)))
    # no straight cut separates them (a pinwheel; never seen on CMP): keep the strongest
    return element_region(box, [max(elements, key=lambda e: (e.score * e.area, e.box))])


def _separating_cut(elements: Sequence[Element], k: int) -> int | None:
    """A coordinate along axis ``k`` (0: x, 1: y) with every element wholly on one side of it
    (the middle of the first gap between their extents; gaps may be empty), or ``None``."""
    gaps = _gaps([(e.box[k], e.box[k + 2]) for e in elements])
    return (gaps[0][0] + gaps[0][1]) // 2 if gaps else None


def _peel(inner: Region, box, axis: str, a: int, b: int, strength: float) -> Region:
    """``box`` split along ``axis`` into [wall before ``a``], ``inner``, [wall after ``b``]."""
    x0, y0, x1, y1 = box
    lo, hi = (x0, x1) if axis == "x" else (y0, y1)
    before, after = a > lo, b < hi
    if not before and not after:
        return inner

    def wall(s: int, e: int) -> Region:
        return Region(box=(s, y0, e, y1) if axis == "x" else (x0, s, x1, e), role="wall")

    if before and after:
        split, kids = ("dual-x" if axis == "x" else "dual-y"), [wall(lo, a), inner, wall(b, hi)]
    elif before:   # a strip before the element: [left strip, rest] / [top strip, rest]
        split, kids = ("left" if axis == "x" else "top"), [wall(lo, a), inner]
    else:          # a strip after it: [rest, right strip] / [rest, bottom strip]
        split, kids = ("right" if axis == "x" else "bottom"), [inner, wall(b, hi)]
    return Region(box=box, split=split, children=kids, strength=strength)


def element_layout(elements: Sequence[Element], gray: np.ndarray, occupancy: np.ndarray,
                   px_per_m: float, edges: tuple[np.ndarray, np.ndarray] | None = None,
                   fronts: Sequence[Element] = ()) -> ElementLayout:
    """Floors, tiles and tile refinements around ``elements`` (module docstring).

    Parameters
    ----------
    elements : detected elements (:func:`~.detect.detect_elements`), pixel boxes of ``gray``
    gray : (H, W) float
        The rectified photo's luminance (edge interest for the line positions).
    occupancy : (H, W) float
        Summed probability of the detected classes (line confidences).
    px_per_m : float
        Scale for the interest functions' smoothing (σ = 0.1 m).
    edges : (hor, ver), optional
        :func:`~.splits.edge_maps` of ``gray`` when the caller has them already.
    fronts : protruding elements (:func:`~.detect.detect_protruding`), pixel boxes of ``gray``
        Balconies: they may overlap ``elements`` and are hung on tiles and floors (module
        docstring).
    """
    h, w = gray.shape
    hor, ver = edge_maps(gray) if edges is None else edges
    sigma = max(1.0, 0.1 * px_per_m)
    ver_y, _ = interest_functions(hor, ver, sigma_px=sigma)
    railings = [(e.box[1], e.box[3]) for e in fronts]
    lines = [_line_in_gap(ver_y, _free_part(g, railings))
             for g in _gaps([(e.box[1], e.box[3]) for e in elements])]
    edges = [0] + lines + [h]
    floors = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]
    floor_conf = [round(float(1.0 - occupancy[y].mean()), 4) for y in lines]

    tiles: list[list[tuple[int, int]]] = []
    regions: list[list[Region | None]] = []
    tile_conf: list[list[float]] = []
    for y0, y1 in floors:
        mine = [e for e in elements if y0 <= (e.box[1] + e.box[3]) / 2 < y1]
        quiet = gaussian_filter1d((hor[y0:y1] + ver[y0:y1]).sum(axis=0), sigma, mode="nearest")
        xl = [_line_in_gap(quiet, g) for g in _gaps([(e.box[0], e.box[2]) for e in mine])] \
            if mine else []
        xs = [0] + xl + [w]
        row = [(a, b) for a, b in zip(xs[:-1], xs[1:]) if b > a]
        tiles.append(row)
        tile_conf.append([round(float(1.0 - occupancy[y0:y1, x].mean()), 4) for x in xl])
        regs: list[Region | None] = []
        for x0, x1 in row:
            inside = [e for e in mine if x0 <= (e.box[0] + e.box[2]) / 2 < x1]
            regs.append(element_region((x0, y0, x1, y1), inside) if inside else None)
        regions.append(regs)
    inner = [b - a for a, b in floors[1:-1]]          # floors bounded by two lines
    period = float(np.median(inner)) if inner else 0.0
    return ElementLayout(floors=floors, tiles=tiles, regions=regions,
                         confidences={"floors": floor_conf, "tiles": tile_conf},
                         floor_period_px=period, fronts=_hang(fronts, floors, tiles, regions))


def _leader_groups(sigs: list[np.ndarray], tol: float) -> list[int]:
    """Group index per signature: each joins the first group whose leader (first member) is
    within ``tol`` in every component, else starts a group."""
    leaders: list[np.ndarray] = []
    out = []
    for s in sigs:
        for g, lead in enumerate(leaders):
            if lead.shape == s.shape and float(np.abs(lead - s).max(initial=0.0)) <= tol:
                out.append(g)
                break
        else:
            leaders.append(s)
            out.append(len(leaders) - 1)
    return out


def _signature(leaves: Sequence[Region], x0: int, y0: int) -> tuple[tuple, list[int]]:
    """Labels and boxes (relative to ``(x0, y0)``) of element leaves, or of the protruding
    elements of one host."""
    sig: list[int] = []
    for r in leaves:
        bx0, by0, bx1, by1 = r.box
        sig += [bx0 - x0, by0 - y0, bx1 - bx0, by1 - by0]
    return tuple(r.label for r in leaves), sig


def refine_clusters(floors: Sequence[tuple[int, int]], tiles: Sequence[Sequence[tuple[int, int]]],
                    regions: Sequence[Sequence[Region | None]] | None,
                    floor_clusters: Sequence[int], tile_clusters: Sequence[Sequence[int]],
                    tol: float, fronts: Sequence[Sequence[tuple[int | None, Region]]] = ()
                    ) -> tuple[list[int], list[list[int]]]:
    """Appearance clusters (§2.3) split further by geometry, so that the rules extracted from
    the tree (§5: one rule per cluster, sizes averaged over its members) derive every member
    within about ``tol`` pixels of where it was found.

    Tiles stay together when they share an appearance cluster and their element labels, and
    their sizes and element boxes (relative to the tile) agree within ``tol``; floors when they
    share an appearance cluster and their sequence of tile clusters, and their heights agree
    within ``tol``.  Protruding elements (``fronts``, :attr:`ElementLayout.fronts`) count as
    elements of the tile or floor they hang on.  The elements themselves are not moved:
    synchronising them instead (§3.2: every window edge moved to the median of its 1-D cluster
    of edges) lowered window F1 on CMP val (``docs/design-measurements.md``).

    ``floors``, ``tiles`` and ``regions`` are an :class:`ElementLayout`'s (or stage 1's with
    the §3 refinements: element leaves are those with ``role == "element"``).  Returns new
    dense floor and tile cluster ids (0, 1, … in order of first appearance).
    """
    def hung(i: int, j: int | None) -> list[Region]:
        return [r for k, r in fronts[i] if k == j] if i < len(fronts) else []

    keys, sigs, where = [], [], []
    for i, row in enumerate(tiles):
        y0, y1 = floors[i]
        for j, (x0, x1) in enumerate(row):
            el_labels, el_sig = _signature(
                element_leaves(regions[i][j] if regions is not None else None), x0, y0)
            labels, front_sig = _signature(hung(i, j), x0, y0)
            keys.append((int(tile_clusters[i][j]), el_labels, labels))
            sigs.append(np.asarray([x1 - x0, y1 - y0, *el_sig, *front_sig], np.float64))
            where.append((i, j))
    new_tiles = [[0] * len(row) for row in tiles]
    ids: dict[tuple, int] = {}
    for key in dict.fromkeys(keys):                       # keys in order of first appearance
        idx = [k for k, kk in enumerate(keys) if kk == key]
        for k, g in zip(idx, _leader_groups([sigs[k] for k in idx], tol)):
            i, j = where[k]
            new_tiles[i][j] = ids.setdefault((key, g), len(ids))
    fkeys, heights = [], []
    for i, (a, b) in enumerate(floors):
        labels, front_sig = _signature(hung(i, None), 0, a)
        fkeys.append((int(floor_clusters[i]), tuple(new_tiles[i]), labels))
        heights.append(np.array([b - a, *front_sig], np.float64))
    new_floors = [0] * len(floors)
    fids: dict[tuple, int] = {}
    for key in dict.fromkeys(fkeys):
        idx = [k for k, kk in enumerate(fkeys) if kk == key]
        for k, g in zip(idx, _leader_groups([heights[k] for k in idx], tol)):
            new_floors[k] = fids.setdefault((key, g), len(fids))
    # renumber tiles in order of first appearance (floors top to bottom, tiles left to right)
    order: dict[int, int] = {}
    for row in new_tiles:
        for c in row:
            order.setdefault(c, len(order))
    return new_floors, [[order[c] for c in row] for row in new_tiles]
