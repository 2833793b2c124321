"""Subdivision of facade tiles into regions (Müller et al. 2007, §3): stage 2 of the pipeline.

Input: the grayscale photo and the tiles found by stage 1 (:mod:`.splits`), each with an
appearance cluster and its floor/column index (:class:`Tile`).  Output: one :class:`Region`
tree per tile.  The loop of §3 runs level by level over all tiles at once::

    initialize all tiles
    while non-leaf and non-subdivided region left          (at most ``max_levels`` times)
      find best split candidate for each region             §3.1, :func:`_local_split`
      synchronize splits of tiles within same group         §3.2, :func:`_sync_clusters`
      globally synchronize all split candidates             §3.2, :func:`_sync_distances`
      subdivide regions into new regions
      mark non-subdivided regions as leafs
      mark small new regions as leafs                       (min side < ``tau_size``)

§3.1 — local split detection
    Split lines lie on pixel *boundaries*: a vertical line at ``x = k`` separates columns
    ``k − 1`` and ``k``; its per-pixel response is the squared forward difference
    ``(I[y, k] − I[y, k − 1])²`` (the energy of the gradient component across the line, the
    ``I_x²`` of the eq. 3 edge maps) and its *edge strength* in a region is the mean response
    over the rows of the region (horizontal lines likewise with ``I_y²``).  Strengths of all
    lines of a region come from column/row cumulative sums, so a region costs two vector
    operations.  The *wall noise level* of a tile is the mean squared gradient magnitude
    ``I_x² + I_y²`` in a zone of half-width ``max(2, min(w, h) // 10)`` px around the
    *original* tile boundary (stage 1 puts tile boundaries on walls), floored at
    ``noise_floor``.  A line is *relevant* when its strength exceeds ``tau_edge`` × noise.
    Energies rather than magnitudes: on textured walls (brick, ashlar) a window edge that
    covers half of a tile line reaches only 1.5–2.5× the mean wall *magnitude* — below the
    paper's ``τ_edge = 4`` — while energies separate it from the texture about twice as well.
    A candidate must also leave strips of at least ``tau_size`` px on both sides (thin
    multi-line mouldings are not peeled one line per level).  Scanning inward from each of the
    four sides, the first relevant line that is a local maximum of the strength profile (the
    region's own boundaries take part in the comparison, so the blurred flank of the edge a
    region was cut along is not taken again) is that side's candidate — at most four.

    Each candidate's *edge-responding segment* is the longest run (gaps of ≤ 2 px bridged) of
    pixels along the line whose response exceeds the same threshold.  A candidate whose line
    cuts through the responding segment of a perpendicular candidate (more than ``cross_tol`` px
    of that segment on both sides of the line) is dropped — the white lines of Fig. 9: cutting
    there would split an edge.  Among the survivors the one with the longest responding segment
    wins (ties: left, right, top, bottom); if the runner-up is parallel, at another position and
    at least 80 % as long (``dual_ratio``), both are taken: a dual split.  Split types:
    ``dual-x``, ``dual-y``, ``left``, ``right``, ``top``, ``bottom``, ``none``.

§3.2 — split synchronisation (``synchronise=True``)
    Regions correspond across tiles through their *path* (child indices from the root): tiles
    of one cluster get identical split types, hence identical tree shapes.  Per group
    ``(cluster, path)``:

    1. the most frequent split type wins (ties: larger summed strength, then the order of
       :data:`SPLIT_TYPES`) and is imposed on every member;
    2. a member that did not choose the imposed type gets, for each line the type needs, its own
       first relevant line from that side when that lies within ``search`` px
       (``max(2, extent // 10)``) of the prediction — the group's median *relative* position —
       else the strongest line within ``search`` px of the prediction if its strength is at
       least half the relevance threshold, else the prediction itself;
    3. vertical lines are aligned within columns of tiles (same ``col``) and horizontal lines
       within rows (same ``row``): absolute positions are clustered in 1-D (greedy, span
       ≤ ``sync_tol`` px) and replaced by the cluster medians.

    Then the distances between parallel split lines — the centre width of a dual split, or the
    distance of a single split line from a region side that is itself a split line (distances
    to the original tile boundary are not element sizes and are left alone) — are clustered in
    1-D, first per group, then over the whole facade, and replaced by their cluster medians
    (:func:`_sync_distances`; a dual split keeps its midpoint).

Leaf roles
    After refinement a leaf is an ``"element"`` (window, door or balcony candidate) when it
    touches neither the left, the right nor the top border of its tile, and — if it touches
    the bottom border — it is at least half as tall as the tile (doors reach the floor; the
    wall strip under a window also touches the bottom but is short).  "Touches" means: comes
    closer than ``max(tau_size, extent // 10)`` px (so a thin moulding strip peeled off the
    tile top does not turn the wall below it into an element).  Every other leaf is
    ``"wall"``; a tile without any split is a single ``"wall"`` leaf.  :func:`elements` returns
    the maximal subtrees made only of element leaves (a window split into panes is one
    element).

Everything is deterministic (no randomness, stable orders) and every loop is bounded: at most
``max_levels`` levels, one candidate per side, one pass of each synchronisation step per level.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np

from .runs import longest_run
from .splits import to_gray

__all__ = ["SPLIT_TYPES", "Region", "Tile", "elements", "leaves", "refine_tiles"]

#: The seven split types of §3.1, in tie-break order.
SPLIT_TYPES: tuple[str, ...] = ("dual-x", "dual-y", "left", "right", "top", "bottom", "none")

_SIDES: tuple[str, ...] = ("left", "right", "top", "bottom")
_TYPE_SIDES: dict[str, tuple[str, ...]] = {
    "dual-x": ("left", "right"), "dual-y": ("top", "bottom"), "left": ("left",),
    "right": ("right",), "top": ("top",), "bottom": ("bottom",), "none": ()}
_VERTICAL = frozenset(("left", "right"))


@dataclass
class Tile:
    """A tile found by stage 1 (§2.4).

    Attributes
    ----------
    box : (int, int, int, int)
        ``x0, y0, x1, y1`` in pixels, exclusive ends, rows going down.
    cluster : int
        Appearance group: tiles of the same cluster look alike (§3.2).
    row : int
        Floor index, 0 = top floor in image order.
    col : int
        Tile index within its floor, left to right.
    """

    box: tuple[int, int, int, int]
    cluster: int
    row: int
    col: int


@dataclass
class Region:
    """A node of a tile's subdivision tree (§3).

    Attributes
    ----------
    box : (int, int, int, int)
        ``x0, y0, x1, y1`` pixels, exclusive ends.
    split : str
        One of :data:`SPLIT_TYPES`; ``"none"`` on leaves.
    children : list of Region
        Ordered by increasing coordinate: ``left``: [left strip, rest]; ``right``: [rest, right
        strip]; ``top``: [top strip, rest]; ``bottom``: [rest, bottom strip]; ``dual-x``:
        [left, centre, right]; ``dual-y``: [top, centre, bottom].
    strength : float
        Edge strength of the chosen split line(s) (the weaker one of a dual split) divided by
        the tile's wall noise level; relevant lines have ``strength > tau_edge``, lines imposed
        by synchronisation may be weaker.  A confidence input.
    role : str
        On leaves: ``"wall"`` or ``"element"`` (see the module docstring); ``""`` on inner nodes.
    label : str
        Canonical label of an element leaf when it is known (elements a classifier detected,
        :mod:`.element_layout`); ``""`` when element matching (§4) decides.
    """

    box: tuple[int, int, int, int]
    split: str = "none"
    children: list[Region] = field(default_factory=list)
    strength: float = 0.0
    role: str = ""
    label: str = ""


def leaves(region: Region) -> list[Region]:
    """The leaves of a region tree, left to right / top to bottom (depth-first order)."""
    out: list[Region] = []
    stack = [region]
    while stack:
        r = stack.pop()
        if r.children:
            stack.extend(reversed(r.children))
        else:
            out.append(r)
    return out


def element_leaves(region: Region | None) -> list[Region]:
    """The leaves of role ``"element"`` (none for ``None``, a tile without a refinement)."""
    return [] if region is None else [r for r in leaves(region) if r.role == "element"]


def elements(region: Region) -> list[Region]:
    """Maximal subtrees of ``region`` whose leaves all have role ``"element"`` (depth-first)."""
    out: list[Region] = []
    stack = [region]
    while stack:
        r = stack.pop()
        if all(leaf.role == "element" for leaf in leaves(r)):
            out.append(r)
        else:
            stack.extend(reversed(r.children))
    return out


# ================================================================================ image terms
class _Edges:
    """Per-image tables: boundary responses and their cumulative sums, gradient magnitude."""

    def __init__(self, gray: np.ndarray):
        g = np.asarray(gray, dtype=np.float64)
        h, w = g.shape
        dx = np.zeros((h, w + 1))
        dx[:, 1:w] = np.diff(g, axis=1) ** 2             # dx[y, k]: boundary k (cols k-1 | k)
        dy = np.zeros((h + 1, w))
        dy[1:h, :] = np.diff(g, axis=0) ** 2             # dy[m, x]: boundary m (rows m-1 | m)
        self.dx, self.dy = dx, dy
        self.cx = np.vstack([np.zeros((1, w + 1)), np.cumsum(dx, axis=0)])   # (h+1, w+1)
        self.cy = np.hstack([np.zeros((h + 1, 1)), np.cumsum(dy, axis=1)])   # (h+1, w+1)
        mag = 0.5 * (dx[:, :-1] + dx[:, 1:] + dy[:-1] + dy[1:])
        self.sat = np.zeros((h + 1, w + 1))
        self.sat[1:, 1:] = mag.cumsum(0).cumsum(1)
        self.shape = (h, w)

    def _box_sum(self, x0: int, y0: int, x1: int, y1: int) -> float:
        s = self.sat
        return float(s[y1, x1] - s[y0, x1] - s[y1, x0] + s[y0, x0])

    def noise(self, box: tuple[int, int, int, int], floor: float) -> float:
        """Mean squared gradient magnitude in the zone around the tile boundary (§3.1), at least
        ``floor``."""
        h, w = self.shape
        x0, y0, x1, y1 = box
        b = max(2, min(x1 - x0, y1 - y0) // 10)
        ox0, oy0, ox1, oy1 = max(0, x0 - b), max(0, y0 - b), min(w, x1 + b), min(h, y1 + b)
        total, area = self._box_sum(ox0, oy0, ox1, oy1), (ox1 - ox0) * (oy1 - oy0)
        ix0, iy0, ix1, iy1 = x0 + b, y0 + b, x1 - b, y1 - b
        if ix1 > ix0 and iy1 > iy0:
            total -= self._box_sum(ix0, iy0, ix1, iy1)
            area -= (ix1 - ix0) * (iy1 - iy0)
        return max(total / max(area, 1), floor)

    def profile(self, box: tuple[int, int, int, int], vertical: bool) -> np.ndarray:
        """Edge strength of every line of the region, its two boundaries included: index ``i``
        is the line at ``x0 + i`` (vertical) or ``y0 + i`` (horizontal)."""
        x0, y0, x1, y1 = box
        if vertical:
            return (self.cx[y1, x0:x1 + 1] - self.cx[y0, x0:x1 + 1]) / (y1 - y0)
        return (self.cy[y0:y1 + 1, x1] - self.cy[y0:y1 + 1, x0]) / (x1 - x0)

    def response(self, box: tuple[int, int, int, int], vertical: bool, pos: int) -> np.ndarray:
        """Per-pixel response along one line of the region."""
        x0, y0, x1, y1 = box
        return self.dx[y0:y1, pos] if vertical else self.dy[pos, x0:x1]


def _cluster_1d(values: np.ndarray, tol: float) -> np.ndarray:
    """Greedy 1-D clustering (sorted; a cluster spans ≤ ``tol``): each value → its cluster's
    median, rounded half up to an integer."""
    v = np.asarray(values, dtype=np.float64)
    out = v.copy()
    if v.size < 2:
        return np.floor(out + 0.5)
    order = np.argsort(v, kind="stable")
    s = v[order]
    start = 0
    for i in range(1, s.size + 1):
        if i == s.size or s[i] - s[start] > tol:
            out[order[start:i]] = np.median(s[start:i])
            start = i
    return np.floor(out + 0.5)


# ================================================================================ §3.1
@dataclass
class _Cand:
    side: str
    pos: int
    strength: float                  # mean response / noise
    seg: tuple[int, int]             # responding segment, absolute coordinates along the line

    @property
    def vertical(self) -> bool:
        return self.side in _VERTICAL

    @property
    def length(self) -> int:
        return self.seg[1] - self.seg[0]


@dataclass
class _Work:
    """An active region at the current level with its local analysis."""

    tile: int
    path: tuple[int, ...]
    region: Region
    cands: dict[str, _Cand]
    kind: str = "none"
    pos: dict[str, int] = field(default_factory=dict)


def _bounds(box: tuple[int, int, int, int], side: str) -> tuple[int, int]:
    x0, y0, x1, y1 = box
    return (x0, x1) if side in _VERTICAL else (y0, y1)


def _candidates(edges: _Edges, box: tuple[int, int, int, int], thr: float,
                noise: float, min_strip: int) -> dict[str, _Cand]:
    """First relevant line from each side (local maximum of the strength profile above
    ``thr``, leaving strips of at least ``min_strip`` px) with its edge-responding segment."""
    out: dict[str, _Cand] = {}
    x0, y0 = box[:2]
    for vertical, sides in ((True, ("left", "right")), (False, ("top", "bottom"))):
        p = edges.profile(box, vertical)
        if p.size < 3:
            continue
        mid = p[1:-1]
        ok = (mid > thr) & (mid > p[:-2]) & (mid >= p[2:])
        ok[:max(0, min_strip - 1)] = False               # strips of at least min_strip px
        ok[max(0, ok.size - min_strip + 1):] = False
        peak = np.flatnonzero(ok) + 1
        if peak.size == 0:
            continue
        lo = x0 if vertical else y0
        along = y0 if vertical else x0
        for side, i in zip(sides, (int(peak[0]), int(peak[-1]))):
            pos = lo + i
            s, e = longest_run(edges.response(box, vertical, pos) > thr, gap=2)
            out[side] = _Cand(side, pos, float(p[i]) / noise, (along + s, along + e))
    return out


def _crosses(line: _Cand, other: _Cand, tol: int) -> bool:
    """Whether ``line`` (full length across the region) cuts ``other``'s responding segment."""
    s, e = other.seg
    return line.pos - s > tol and e - line.pos > tol


def _local_split(cands: dict[str, _Cand], dual_ratio: float, cross_tol: int
                 ) -> tuple[str, dict[str, int]]:
    """§3.1 selection: crossing test, longest responding segment, 80 % dual rule."""
    alive = [c for c in (cands.get(s) for s in _SIDES) if c is not None and c.length > 0]
    alive = [c for c in alive
             if not any(o.vertical != c.vertical and _crosses(c, o, cross_tol) for o in alive)]
    if not alive:
        return "none", {}
    ranked = sorted(alive, key=lambda c: -c.length)      # stable: ties keep the side order
    win = ranked[0]
    if len(ranked) > 1:
        run = ranked[1]
        if run.vertical == win.vertical and run.length >= dual_ratio * win.length:
            a, b = sorted((win, run), key=lambda c: _SIDES.index(c.side))
            if a.pos < b.pos:
                return ("dual-x" if win.vertical else "dual-y"), {a.side: a.pos, b.side: b.pos}
    return win.side, {win.side: win.pos}


# ================================================================================ §3.2
def _redetect(edges: _Edges, w: _Work, side: str, rel: float, thr: float) -> int:
    """Line position for an imposed side: own candidate near the prediction, else the strongest
    line near it (if at least half relevant), else the prediction."""
    lo, hi = _bounds(w.region.box, side)
    pred = int(np.clip(round(lo + rel * (hi - lo)), lo + 1, hi - 1))
    search = max(2, (hi - lo) // 10)
    own = w.cands.get(side)
    if own is not None and abs(own.pos - pred) <= search:
        return own.pos
    p = edges.profile(w.region.box, side in _VERTICAL)
    a, b = max(1, pred - lo - search), min(p.size - 2, pred - lo + search)
    if b >= a:
        i = a + int(np.argmax(p[a:b + 1]))
        if p[i] >= 0.5 * thr:
            return lo + i
    return pred


def _sync_clusters(edges: _Edges, works: list[_Work], tiles: list[Tile],
                   thresholds: list[float], tol: float) -> None:
    """Impose the most frequent split type per ``(cluster, path)`` group and align line
    positions within tile columns (vertical lines) and rows (horizontal lines)."""
    groups: dict[tuple, list[int]] = defaultdict(list)
    for i, w in enumerate(works):
        groups[(tiles[w.tile].cluster, w.path)].append(i)
    for members in groups.values():
        votes = Counter(works[i].kind for i in members)
        power: dict[str, float] = defaultdict(float)
        for i in members:
            w = works[i]
            power[w.kind] += sum(w.cands[s].strength for s in w.pos if s in w.cands)
        kind = min(votes, key=lambda k: (-votes[k], -power[k], SPLIT_TYPES.index(k)))
        sides = _TYPE_SIDES[kind]
        rels: dict[str, float] = {}
        for side in sides:
            r = []
            for i in members:
                w = works[i]
                if w.kind == kind:
                    lo, hi = _bounds(w.region.box, side)
                    r.append((w.pos[side] - lo) / (hi - lo))
            rels[side] = float(np.median(r))
        for i in members:
            w = works[i]
            if w.kind != kind:
                w.pos = {s: _redetect(edges, w, s, rels[s], thresholds[w.tile]) for s in sides}
                w.kind = kind
        for side in sides:                              # align within columns / rows
            sub: dict[int, list[int]] = defaultdict(list)
            for i in members:
                t = tiles[works[i].tile]
                sub[t.col if side in _VERTICAL else t.row].append(i)
            for idx in sub.values():
                if len(idx) < 2:
                    continue
                new = _cluster_1d(np.array([works[i].pos[side] for i in idx]), tol)
                for i, v in zip(idx, new):
                    works[i].pos[side] = int(v)


def _distance(w: _Work, tile_box: tuple[int, int, int, int]):
    """``(axis, distance, mode)`` of a split, see :func:`_sync_distances`; ``None`` if none."""
    if w.kind == "none":
        return None
    vertical = w.kind == "dual-x" or w.kind in _VERTICAL
    if w.kind in ("dual-x", "dual-y"):
        a, b = (w.pos["left"], w.pos["right"]) if vertical else (w.pos["top"], w.pos["bottom"])
        return vertical, b - a, "dual"
    lo, hi = _bounds(w.region.box, w.kind)
    tlo, thi = _bounds(tile_box, w.kind)
    p = w.pos[w.kind]
    if lo != tlo:
        return vertical, p - lo, "lo"
    if hi != thi:
        return vertical, hi - p, "hi"
    return None


def _set_distance(w: _Work, mode: str, d: int) -> None:
    if mode == "dual":
        a_s, b_s = _TYPE_SIDES[w.kind]
        mid2 = w.pos[a_s] + w.pos[b_s]                   # twice the midpoint
        a = (mid2 - d + 1) // 2
        w.pos[a_s], w.pos[b_s] = a, a + d
        return
    lo, hi = _bounds(w.region.box, w.kind)
    w.pos[w.kind] = lo + d if mode == "lo" else hi - d


def _sync_distances(works: list[_Work], tiles: list[Tile], tol: float) -> None:
    """Cluster distances between parallel split lines, per group then globally (§3.2)."""
    recs = []
    for i, w in enumerate(works):
        d = _distance(w, tiles[w.tile].box)
        if d is not None:
            recs.append((i, *d))
    groups: dict[tuple, list[int]] = defaultdict(list)
    for k, (i, vertical, _, mode) in enumerate(recs):
        groups[(tiles[works[i].tile].cluster, works[i].path, vertical, mode == "dual")].append(k)
    scopes = list(groups.values())
    glob: dict[tuple, list[int]] = defaultdict(list)
    for k, (_, vertical, _, mode) in enumerate(recs):
        glob[(vertical, mode == "dual")].append(k)
    scopes += list(glob.values())
    dist = [float(r[2]) for r in recs]
    for ks in scopes:
        if len(ks) < 2:
            continue
        new = _cluster_1d(np.array([dist[k] for k in ks]), tol)
        for k, v in zip(ks, new):
            dist[k] = float(v)
    for (i, _, _, mode), d in zip(recs, dist):
        _set_distance(works[i], mode, int(d))


# ================================================================================ driver
def _subdivide(w: _Work, strength_of) -> list[Region]:
    """Apply ``w.kind`` at ``w.pos`` to ``w.region`` (invalid lines are dropped)."""
    reg = w.region
    x0, y0, x1, y1 = reg.box
    kind = w.kind
    sides = [s for s in _TYPE_SIDES[kind]
             if _bounds(reg.box, s)[0] < w.pos.get(s, -1) < _bounds(reg.box, s)[1]]
    if kind in ("dual-x", "dual-y") and len(sides) == 2 and w.pos[sides[0]] >= w.pos[sides[1]]:
        sides = sides[:1]
    if len(sides) < len(_TYPE_SIDES[kind]):
        kind = sides[0] if sides else "none"
    if kind == "none":
        return []
    reg.split = kind
    reg.strength = min(strength_of(s, w.pos[s]) for s in sides)
    if kind in _VERTICAL or kind == "dual-x":
        cuts = [x0] + [w.pos[s] for s in sides] + [x1]
        reg.children = [Region((a, y0, b, y1)) for a, b in zip(cuts[:-1], cuts[1:])]
    else:
        cuts = [y0] + [w.pos[s] for s in sides] + [y1]
        reg.children = [Region((x0, a, x1, b)) for a, b in zip(cuts[:-1], cuts[1:])]
    return reg.children


def _assign_roles(root: Region, tile_box: tuple[int, int, int, int], tau_size: int) -> None:
    tx0, ty0, tx1, ty1 = tile_box
    if not root.children:
        root.role = "wall"
        return
    mx = max(tau_size, (tx1 - tx0) // 10)
    my = max(tau_size, (ty1 - ty0) // 10)
    for leaf in leaves(root):
        x0, y0, x1, y1 = leaf.box
        border = x0 - tx0 < mx or tx1 - x1 < mx or y0 - ty0 < my
        floor = ty1 - y1 < my and 2 * (y1 - y0) < ty1 - ty0
        leaf.role = "wall" if border or floor else "element"


def refine_tiles(gray: np.ndarray, tiles: list[Tile], *, tau_edge: float = 4.0,
                 tau_size: int = 5, max_levels: int = 6, synchronise: bool = True,
                 dual_ratio: float = 0.8, cross_tol: int = 2, sync_tol: float = 2.0,
                 noise_floor: float = 1e-3) -> list[Region]:
    """Hierarchical subdivision of facade tiles (Müller et al. 2007, §3).

    Parameters
    ----------
    gray : numpy.ndarray
        The (rectified) facade photo; gray or colour, any dtype :func:`~.splits.to_gray` reads.
    tiles : list of Tile
        Tiles from stage 1 with their cluster, floor (``row``) and column (``col``).
    tau_edge : float
        Relevance factor over the wall noise level (§3.1; 4 in the paper).
    tau_size : int
        Regions whose smaller side is below this many pixels become leaves (§3; 5 px).
    max_levels : int
        Bound on the number of subdivision rounds (the paper reports 2–5 for ground images).
    synchronise : bool
        Apply the §3.2 synchronisation (cluster vote, row/column alignment, distance
        clustering); ``False`` gives the per-tile local result.
    dual_ratio : float
        A parallel runner-up at least this fraction as long as the winner gives a dual split.
    cross_tol : int
        A line cuts a perpendicular responding segment when more than this many pixels of the
        segment lie on each side of it.
    sync_tol : float
        Span (px) of the 1-D clusters of line positions and distances (§3.2).
    noise_floor : float
        Lower bound of the wall noise level (squared intensity steps, intensities in
        ``[0, 1]``), for noiseless images.

    Returns
    -------
    list of Region
        One tree per tile, in input order; leaves carry a ``role`` (module docstring).
    """
    g = to_gray(gray)
    h, w = g.shape
    edges = _Edges(g)
    roots: list[Region] = []
    noises: list[float] = []
    for t in tiles:
        x0, y0, x1, y1 = (int(v) for v in t.box)
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
        if x1 <= x0 or y1 <= y0:
            raise ValueError(f"tile box {t.box} is empty inside a {w}x{h} image")
        roots.append(Region((x0, y0, x1, y1)))
        noises.append(edges.noise((x0, y0, x1, y1), noise_floor))
    tiles = [Tile(r.box, t.cluster, t.row, t.col) for r, t in zip(roots, tiles)]
    thresholds = [tau_edge * n for n in noises]

    def small(r: Region) -> bool:
        x0, y0, x1, y1 = r.box
        return min(x1 - x0, y1 - y0) < tau_size

    active = [(i, (), r) for i, r in enumerate(roots) if not small(r)]
    for _level in range(max(0, int(max_levels))):
        if not active:
            break
        works = [_Work(i, path, r, _candidates(edges, r.box, thresholds[i], noises[i], tau_size))
                 for i, path, r in active]
        for wk in works:
            wk.kind, wk.pos = _local_split(wk.cands, dual_ratio, cross_tol)
        if synchronise:
            _sync_clusters(edges, works, tiles, thresholds, sync_tol)
            _sync_distances(works, tiles, sync_tol)
        nxt = []
        for wk in works:
            def strength_of(side: str, pos: int, wk: _Work = wk) -> float:
                p = edges.profile(wk.region.box, side in _VERTICAL)
                return float(p[pos - _bounds(wk.region.box, side)[0]]) / noises[wk.tile]

            kids = _subdivide(wk, strength_of)
            nxt.extend((wk.tile, wk.path + (k,), c) for k, c in enumerate(kids) if not small(c))
        active = nxt
    for r, t in zip(roots, tiles):
        _assign_roles(r, t.box, tau_size)
    return roots
