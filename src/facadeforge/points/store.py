"""CityFit's point store: 16.16 fixed-point coordinates in a quadtree of 4 m columns.

``hohmann2009`` §3 stores every LIDAR point of Graz in **16.16 fixed point** (a 32-bit integer per
coordinate, 1/65536 m ≈ 1/65 mm everywhere within 32 km of the origin, where float32 has that
spacing only within 128 m of its origin) and **sorts the points into a regular 2D grid of 4 m × 4 m
columns of infinite height**, organised as a **quadtree** so that empty cells are not stored; the
coordinates live in **one array grouped by cell and sorted by z inside a cell**, and the quadtree's
leaves store an offset into it.  Equal integer triples are equal points (a 96-bit point id), and a
distance-independent epsilon (2⁻¹³ m ≈ 0.12 mm) merges close points.  Rays are intersected with
the points drawn as spheres (10 cm) by walking the cells along the ray (Amanatides & Woo 1987).
:class:`PointStore` is that store; it reads a :class:`~.cloud.PointCloud`.

Units
    Query arguments and results are **metres** in the cloud's frame.  Internally a coordinate is
    ``q = round((x − origin) · 65536)``, an int32 (:data:`SCALE` units per metre), so the stored
    position is ``origin + q / 65536`` and a round trip ``from_fixed(to_fixed(x))`` is within
    2⁻¹⁷ m of ``x`` (plus float64's own rounding of the result, ≤ ½ ulp of ``x``: 0.5 nm at
    5·10⁶ m).  A coordinate more than 32768 m from the origin raises :class:`PointCloudError`.

Exactness
    Every query is answered on the stored fixed-point positions, never on the cloud's floats.
    Query positions (box corners, rectangle corners, centres) are put on the fixed-point grid like
    points, ``u = rint((x − origin) · 65536)`` — so a query at a stored point's own coordinates
    finds it, however far from the origin — while lengths (radii, half sizes) and the ray (origin
    and direction) stay float64 in the fixed frame.  Box tests are then integer comparisons;
    distance tests are float64 on the integers, in axis order 0, 1, 2 (exact while the
    differences stay under 2²⁶ units, 1 km).  A brute-force scan doing the same arithmetic returns
    the same set; the tests check exactly that.

Layout (flat numpy arrays, no Python object per point, cell or node)
    - ``origin`` float64 (3,); the default is the centre of the cloud's bounding box, its
      horizontal part floored to a multiple of the cell size and its vertical part to the metre,
      so that clouds up to 65 km across fit (the min corner would leave only 32 km) and the
      columns line up with the world's 4 m grid.
    - the points, int32, **grouped by cell in Morton (Z-) order of the cells and sorted by the up
      coordinate inside a cell** (ties in original order), one contiguous int32 array per axis
      (so that a cell's z run is a contiguous slice for ``searchsorted``), and the permutation
      ``order``: store position → index in the original cloud, so attributes of the cloud
      (intensity, labels…) are fetched for any result; queries return original indices.
    - the leaves (occupied cells) in the same Morton order: their Morton codes, cell coordinates
      and the CSR offsets ``offsets`` (C + 1,): leaf ``c`` holds ``(start, count) = (offsets[c],
      offsets[c+1] − offsets[c])``.
    - the quadtree, built bottom-up from the leaves' sorted Morton codes: level ``L`` (0 = root,
      ``depth`` = leaves) groups the codes ``m >> 2·(depth − L)``; an internal node stores its four
      children (``-1`` = empty quadrant; a child index is a node index, or a leaf index for the
      last internal level) and the range ``[lo, hi)`` of leaves under it — contiguous, because
      leaves are in Morton order, and so are the points under it.

Which cell lookups use what, and why
    *A single cell* (is cell (i, j) occupied, which leaf is it?) is found by **binary search on the
    sorted Morton codes**: the leaves are stored in Morton order, so the sorted codes are the leaf
    array's key; a search costs O(log C) with no pointer chasing, and ``np.searchsorted`` answers
    any number of lookups in one call, where a descent costs one step per level (``depth``
    numpy calls when vectorised).  :meth:`~PointStore.lookup` is that search;
    :meth:`~PointStore.descend` walks the tree to the same answer (kept for the tests).  The
    tree's nodes are used where they pay: **rectangle enumeration** (``box``, ``column``,
    ``radius``) of more than 256 cells descends the tree, drops empty quadrants without visiting
    their cells, and takes a node that lies wholly inside the rectangle as one leaf range (whose
    points are one contiguous range); smaller rectangles are enumerated cell by cell with the
    Morton search, which is cheaper than a descent for a handful of cells.

Queries (results are original indices, int64, sorted unless ``sort=False``)
    - :meth:`~PointStore.box` — axis-aligned 3D box: cells of its horizontal rectangle, then in
      each cell the z range by binary search (the z sort), the horizontal test only in the border
      cells;
    - :meth:`~PointStore.column` / :meth:`~PointStore.rectangle` — horizontal rectangle, any
      height: inner cells are taken whole, border cells tested;
    - :meth:`~PointStore.radius`, :meth:`~PointStore.radius_many` — balls: the box of the ball,
      then the exact distance; many balls in one call;
    - :meth:`~PointStore.nearest` — k nearest, by cubes growing from the local point density
      until the k-th distance lies inside the cube;
    - :meth:`~PointStore.ray` — picking: the first sphere of radius ``radius`` around a point that
      the ray enters at ``t > 0``.  The 2D column grid is walked along the ray's horizontal
      projection in Amanatides & Woo order (next crossing = the nearer of the next x and next y
      grid line); each step's ``t`` interval is cut into pieces of at most one cell length (steep
      rays), and each piece tests the cells within ``ceil((radius + 1 unit) / cell)`` of the
      step's cell, each only over the ``t`` range where the ray passes within ``radius`` of it and
      the ray's z range there (z sort).  The walk stops after the first piece ``[u, v]`` with a
      hit before ``v − radius``: a later centre's foot on the ray lies beyond ``v``, and its
      sphere is entered no earlier than ``foot − radius``.
    - :meth:`~PointStore.unique`, :meth:`~PointStore.merge` — exact duplicates by the 96-bit
      integer triple; near duplicates (distance < ``radius``, default 2⁻¹³ m) by a grid hash
      (each point looks in its own hash cell and in the neighbours its ball reaches), joined
      transitively (single linkage: a chain of points each closer than ``radius`` to the next is
      one group).  The compiled path packs the hash cell (8 radii wide) into a 64-bit key local
      to the 4 m column and sorts each column's keys, so that lookups stay inside one or two
      columns' memory (a global hash table of a million points is one cache miss per probe).

Engines
    Each query is written twice.  ``engine="numba"`` (default) runs one compiled kernel per query
    (``@njit(cache=True)``, compiled on first use; numba is imported then, not with the module),
    because the numpy version of a single query is dozens of small array calls whose fixed cost
    (≈ 1–2 µs each) is 10–20× the work of a query of a few hundred points.  ``engine="numpy"``
    is the vectorised reference (rectangle descent level by level over the frontier, per-cell z
    searches in lock step, the ray's cells from merged grid-line crossings in segments of
    growing length, the merge by a sorted hash and ``searchsorted``).  The point tests are the
    same arithmetic, operation for operation, so both engines return the same results; the tests
    compare both against brute force.  (STYLE rule 3 puts kernels in a ``_kernels.py``; they are
    in this module to keep the store in one file.)

Storage: :meth:`~PointStore.save` writes a ``.npz`` (the sorted integers, the permutation, origin,
cell size, up axis) atomically (temporary file, then ``os.replace``); :meth:`~PointStore.load`
rebuilds leaves and tree from the sorted points in O(N), without sorting again.
"""

from __future__ import annotations

import functools
import math
import os
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .cloud import PointCloud, PointCloudError

__all__ = ["MERGE_RADIUS", "RESOLUTION", "SCALE", "Groups", "PointStore", "RayHit"]

#: Fixed-point units per metre (16 fractional bits).
SCALE = 65536.0
#: Size of one fixed-point unit, metres.
RESOLUTION = 1.0 / SCALE
#: Default merge radius of :meth:`PointStore.merge`, metres (``hohmann2009`` §3: 2⁻¹³ ≈ 0.12 mm).
MERGE_RADIUS = 2.0**-13

_I32_MIN, _I32_MAX = -(2**31), 2**31 - 1
_ZERO3 = np.zeros(3)
_FORMAT = "facadeforge.points.store"
_VERSION = 1
#: Rectangles of at most this many cells are enumerated cell by cell (Morton lookups), larger ones
#: by descending the quadtree (the kernel ``_k_leaves`` has the same 256).
_SMALL_RECT = 256
#: numpy ray walk: first segment length and largest segment length, in cells.
_RAY_FIRST, _RAY_MAX = 2.0, 64.0
#: Candidate (query, point) pairs handled at once by :meth:`PointStore.radius_many`.
_PAIR_CHUNK = 1 << 21


class RayHit(NamedTuple):
    """First point hit by a ray: ``index`` into the original cloud, ``t`` in metres along the
    (unit) ray direction to where the ray enters the point's sphere."""

    index: int
    t: float


class Groups(NamedTuple):
    """Points grouped as the same point.

    ``keep`` (G,) int64: sorted original indices, one per group (its smallest index);
    ``group`` (N,) int64: the group of every original point, ``group[keep] == arange(G)``.
    """

    keep: np.ndarray
    group: np.ndarray


# ------------------------------------------------------------------------------------- Morton
_M = [np.uint64(c) for c in (0x00000000FFFFFFFF, 0x0000FFFF0000FFFF, 0x00FF00FF00FF00FF,
                             0x0F0F0F0F0F0F0F0F, 0x3333333333333333, 0x5555555555555555)]
_S = [np.uint64(s) for s in (16, 8, 4, 2, 1)]


def _spread(v: np.ndarray) -> np.ndarray:
    """Bits of ``v`` (< 2³²) moved to the even bit positions of a uint64."""
    v = np.asarray(v).astype(np.uint64) & _M[0]
    for s, m in zip(_S, _M[1:]):
        v = (v | (v << s)) & m
    return v


def _gather(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_spread`: the even bits of a uint64 as an int64."""
    v = np.asarray(v, np.uint64) & _M[5]
    for s, m in zip(_S[::-1], [_M[4], _M[3], _M[2], _M[1], _M[0]]):
        v = (v | (v >> s)) & m
    return v.astype(np.int64)


def _morton(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Morton code of cells ``(i, j)`` (non-negative, < 2³²): ``i`` on the even bits."""
    return _spread(i) | (_spread(j) << np.uint64(1))


# ------------------------------------------------------------------------------- small helpers
def _ranges(starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(starts[k], stops[k])`` over k, vectorised (int64)."""
    n = stops - starts
    keep = n > 0
    if not keep.all():
        starts, n = starts[keep], n[keep]
    total = int(n.sum())
    if total == 0:
        return np.empty(0, np.int64)
    before = np.cumsum(n) - n
    return np.repeat(starts - before, n) + np.arange(total, dtype=np.int64)


def _lower_bound(z: np.ndarray, lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    """First index in ``[lo, hi)`` with ``z[index] >= t``, for many ranges at once (``hi`` when
    none): a binary search run in lock step, ``log2(longest range) + 1`` vectorised steps."""
    lo = lo.astype(np.int64, copy=True)
    hi = hi.astype(np.int64, copy=True)
    if not len(lo):
        return lo
    steps = int((hi - lo).max()).bit_length()
    last = len(z) - 1
    for _ in range(steps):
        mid = (lo + hi) >> 1
        active = lo < hi
        below = z[np.minimum(mid, last)] < t
        lo = np.where(active & below, mid + 1, lo)
        hi = np.where(active & ~below, mid, hi)
    return lo


def _floor_i64(u) -> np.ndarray:
    """``floor`` of fixed-frame floats as int64, clipped far outside int32 (no overflow)."""
    return np.floor(np.minimum(np.maximum(u, -2.0**40), 2.0**40)).astype(np.int64)


def _ceil_i64(u) -> np.ndarray:
    return np.ceil(np.minimum(np.maximum(u, -2.0**40), 2.0**40)).astype(np.int64)


def _as_point(v, n: int, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (n,):
        raise PointCloudError(f"{what} must be {n} numbers, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise PointCloudError(f"{what} must be finite, got {a.tolist()}")
    return a


def _as_length(v, what: str, positive: bool = False) -> float:
    x = float(v)
    if not math.isfinite(x) or x < 0 or (positive and x == 0):
        raise PointCloudError(f"{what} must be a finite {'positive' if positive else 'non-negative'}"
                              f" length in metres, got {v!r}")
    return x


# ---------------------------------------------------------------------------------- the store
class PointStore:
    """Fixed-point points sorted into a quadtree of square columns (module docstring).

    Build one with :meth:`from_cloud` or :meth:`load`.

    Attributes
    ----------
    origin : (3,) float64
        Metres; fixed-point coordinates are relative to it.
    cell : float
        Side of a column, metres (a whole number of fixed-point units).
    up : int
        Vertical axis; ``axes`` are the two horizontal axes (increasing order).
    order : (N,) int32 or int64
        Store position → index in the original cloud.
    offsets : (C + 1,) int64
        Leaf ``c`` holds the store positions ``offsets[c] : offsets[c + 1]``.
    depth : int
        Levels of the quadtree below the root (leaves at level ``depth``).
    """

    def __init__(self, points: np.ndarray, order: np.ndarray, origin: np.ndarray,
                 cell_units: int, up: int, source: str = "<memory>"):
        # ``points`` (3, N) int32 already in store order; use from_cloud / load.
        self.origin = np.asarray(origin, np.float64).reshape(3).copy()
        self.up = int(up)
        self.axes = tuple(a for a in range(3) if a != self.up)
        self.source = source
        self._cu = int(cell_units)
        self.cell = self._cu / SCALE
        self._p = np.ascontiguousarray(points, dtype=np.int32)
        self.order = order
        self._rank: np.ndarray | None = None
        self.engine = "numba"
        self._kargs: tuple | None = None
        self._index_leaves()

    # ------------------------------------------------------------------------------ building
    @classmethod
    def from_cloud(cls, cloud: PointCloud, origin=None, cell: float = 4.0) -> PointStore:
        """Store the points of a cloud.

        Parameters
        ----------
        cloud : PointCloud
            Its ``xyz`` (metres) and ``up`` axis are used; attributes stay in the cloud and are
            fetched with the original indices the queries return.
        origin : (3,) float, optional
            Metres.  Default: the bounding-box centre, horizontally floored to a multiple of
            ``cell``, vertically to the metre.
        cell : float
            Column side in metres (4 m in ``hohmann2009``); rounded to whole fixed-point units.

        Raises
        ------
        PointCloudError
            A point lies more than 32768 m from the origin along an axis; bad ``cell``/``origin``.
        """
        if not isinstance(cloud, PointCloud):
            raise PointCloudError(f"PointStore.from_cloud needs a PointCloud, got "
                                  f"{type(cloud).__name__}")
        cell = _as_length(cell, "cell", positive=True)
        cu = int(round(cell * SCALE))
        if not 1 <= cu <= 2**30:
            raise PointCloudError(f"{cloud.source}: cell {cell!r} m is outside "
                                  f"{RESOLUTION} … 16384 m; use a column size such as 4.0")
        up = cloud.up
        if origin is None:
            if len(cloud):
                lo, hi = cloud.bounds
                mid = (lo + hi) / 2
                origin = np.floor(mid)
                for a in range(3):
                    if a != up:
                        origin[a] = math.floor(mid[a] / (cu / SCALE)) * (cu / SCALE)
            else:
                origin = np.zeros(3)
        origin = _as_point(origin, 3, f"{cloud.source}: origin")
        q = _to_fixed(cloud.xyz, origin, cloud.source)
        n = len(q)
        h0, h1 = (a for a in range(3) if a != up)
        if n:
            ci = np.floor_divide(q[:, h0], cu, dtype=np.int64)
            cj = np.floor_divide(q[:, h1], cu, dtype=np.int64)
            codes = _morton(ci - ci.min(), cj - cj.min())
            # Stable two-key sort: by cell (Morton), then up coordinate, ties in original order.
            perm = np.lexsort((q[:, up], codes))
        else:
            perm = np.empty(0, np.int64)
        order = perm.astype(np.int32 if n < 2**31 else np.int64)
        pts = np.ascontiguousarray(q[perm].T)
        return cls(pts, order, origin, cu, up, cloud.source)

    def _index_leaves(self) -> None:
        """Leaves (occupied cells) and quadtree from the sorted points, O(N), no sorting."""
        p, cu = self._p, self._cu
        n = p.shape[1]
        self._z = p[self.up]
        if n:
            ci = np.floor_divide(p[self.axes[0]], cu, dtype=np.int64)
            cj = np.floor_divide(p[self.axes[1]], cu, dtype=np.int64)
            self._cmin = np.array([ci.min(), cj.min()], np.int64)
            ci -= self._cmin[0]
            cj -= self._cmin[1]
            codes = _morton(ci, cj)
            new = np.empty(n, bool)
            new[0] = True
            np.not_equal(codes[1:], codes[:-1], out=new[1:])
            first = np.flatnonzero(new)
            self._codes = codes[first]
            if len(self._codes) > 1 and not (self._codes[1:] > self._codes[:-1]).all():
                raise PointCloudError(f"{self.source}: stored points are not grouped by cell in "
                                      "Morton order; rebuild the store with PointStore.from_cloud")
            zc = self._z.astype(np.int64)
            if n > 1 and ((zc[1:] < zc[:-1]) & ~new[1:]).any():
                raise PointCloudError(f"{self.source}: stored points are not sorted by the up "
                                      "coordinate inside their cell; rebuild the store")
            self._cell_ij = np.stack([ci[first], cj[first]], axis=1)
            self.offsets = np.append(first, n).astype(np.int64)
            self._lo = p.min(axis=1).astype(np.int64)
            self._hi = p.max(axis=1).astype(np.int64)
            extent = int(self._cell_ij.max()) + 1
        else:
            self._cmin = np.zeros(2, np.int64)
            self._codes = np.empty(0, np.uint64)
            self._cell_ij = np.empty((0, 2), np.int64)
            self.offsets = np.zeros(1, np.int64)
            self._lo = self._hi = np.zeros(3, np.int64)
            extent = 1
        self.depth = max(1, (extent - 1).bit_length())
        self._extent = 1 << self.depth
        self._build_tree()

    def _build_tree(self) -> None:
        """Internal nodes bottom-up from the leaves' sorted Morton codes (flat arrays)."""
        d = self.depth
        codes = self._codes
        per_level = []
        lo = np.arange(len(codes), dtype=np.int64)
        hi = lo + 1
        for _ in range(d):
            parent = codes >> np.uint64(2)
            if len(parent):
                new = np.empty(len(parent), bool)
                new[0] = True
                np.not_equal(parent[1:], parent[:-1], out=new[1:])
                first = np.flatnonzero(new)
                which = np.cumsum(new) - 1
                last = np.append(first[1:], len(parent)) - 1
            else:
                first = which = last = np.empty(0, np.int64)
            child = np.full((len(first), 4), -1, np.int64)
            child[which, (codes & np.uint64(3)).astype(np.int64)] = np.arange(len(codes))
            lo, hi = lo[first], hi[last]
            codes = parent[first]
            per_level.append((codes, child, lo, hi))
        per_level.reverse()                                        # root level first
        if not len(per_level[0][0]):                               # empty store: a bare root
            per_level[0] = (np.zeros(1, np.uint64), np.full((1, 4), -1, np.int64),
                            np.zeros(1, np.int64), np.zeros(1, np.int64))
        sizes = [len(c) for c, *_ in per_level]
        self._level_start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        children = []
        for level, (_, child, _, _) in enumerate(per_level):
            if level < d - 1:                                      # children are nodes
                child = np.where(child >= 0, child + self._level_start[level + 1], -1)
            children.append(child)
        self._node_child = np.concatenate(children).astype(np.int32)
        self._node_lo = np.concatenate([lo for *_, lo, _ in per_level]).astype(np.int64)
        self._node_hi = np.concatenate([hi for *_, hi in per_level]).astype(np.int64)
        shift = np.concatenate([np.full(s, d - level, np.int64) for level, s in enumerate(sizes)])
        ncodes = np.concatenate([c for c, *_ in per_level])
        self._node_x0 = _gather(ncodes) << shift
        self._node_y0 = _gather(ncodes >> np.uint64(1)) << shift

    @property
    def engine(self) -> str:
        """``"numba"`` (default: compiled kernels, one per query) or ``"numpy"`` (the vectorised
        reference, no compilation); both return the same results."""
        return self._engine

    @engine.setter
    def engine(self, value: str) -> None:
        if value not in ("numba", "numpy"):
            raise PointCloudError(f"engine must be 'numba' or 'numpy', got {value!r}")
        self._engine = value

    def _kernel_args(self) -> tuple:
        """The arrays and sizes every kernel takes (compiled on first use)."""
        if self._kargs is None:
            _jit()
            self._kargs = (self._p, self._z, self.offsets, self._codes, self._cell_ij,
                           self._node_child, self._node_x0, self._node_y0, self._node_lo,
                           self._node_hi, np.int64(self.depth), np.int64(self._extent),
                           np.int64(self._cu), self._cmin, np.array([*self.axes, self.up], np.int64))
        return self._kargs

    # ------------------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return self._p.shape[1]

    def __repr__(self) -> str:
        return (f"PointStore({len(self)} points, {self.cells} cells of {self.cell:g} m, depth "
                f"{self.depth}, origin {self.origin.tolist()}, {self.memory_bytes / 2**20:.1f} MiB)")

    @property
    def cells(self) -> int:
        """Number of occupied cells (quadtree leaves)."""
        return len(self._codes)

    @property
    def nodes(self) -> int:
        """Number of internal quadtree nodes."""
        return len(self._node_child)

    @property
    def memory_bytes(self) -> int:
        """Bytes of every array the store holds (points, permutation, leaves, tree)."""
        arrays = [self._p, self.order, self.offsets, self._codes, self._cell_ij,
                  self._node_child, self._node_lo, self._node_hi, self._node_x0, self._node_y0,
                  self._level_start, self.origin]
        if self._rank is not None:
            arrays.append(self._rank)
        return int(sum(a.nbytes for a in arrays))

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(min, max)`` (3,) float64 metres of the stored positions (raises when empty)."""
        if not len(self):
            raise PointCloudError(f"{self.source}: the store is empty")
        return self.from_fixed(self._lo), self.from_fixed(self._hi)

    def leaf(self, leaf: int) -> tuple[int, int]:
        """``(start, count)`` of a leaf: its points are store positions ``start … start+count−1``."""
        s = int(self.offsets[leaf])
        return s, int(self.offsets[leaf + 1]) - s

    # ------------------------------------------------------------------------------ fixed point
    def to_fixed(self, xyz) -> np.ndarray:
        """Metres → fixed point.

        Parameters
        ----------
        xyz : (..., 3) float
            Metres in the cloud's frame.

        Returns
        -------
        (..., 3) int32
            ``round((xyz − origin) · 65536)``.

        Raises
        ------
        PointCloudError
            A coordinate is 32768 m or more from the origin (not representable in int32).
        """
        return _to_fixed(xyz, self.origin, self.source)

    def from_fixed(self, q) -> np.ndarray:
        """Fixed point → metres: ``origin + q / 65536``, (..., 3) float64."""
        return np.asarray(q, np.float64) * RESOLUTION + self.origin

    def _inverse(self) -> np.ndarray:
        if self._rank is None:
            rank = np.empty(len(self), self.order.dtype)
            rank[self.order] = np.arange(len(self), dtype=self.order.dtype)
            self._rank = rank
        return self._rank

    def fixed(self, index=None) -> np.ndarray:
        """Fixed-point coordinates (M, 3) int32 of original points ``index`` (default: all, in
        the original cloud's order)."""
        if index is None:
            out = np.empty((len(self), 3), np.int32)
            out[self.order] = self._p.T
            return out
        pos = self._inverse()[np.asarray(index, np.int64)]
        return np.ascontiguousarray(self._p[:, pos].T)

    def xyz(self, index=None) -> np.ndarray:
        """Stored positions in metres (M, 3) float64 of original points ``index`` (default: all,
        in the original cloud's order)."""
        return self.from_fixed(self.fixed(index))

    def _frame(self, x) -> np.ndarray:
        """Metres → the fixed frame as float64 (not rounded): ``(x − origin) · 65536``."""
        return (np.asarray(x, np.float64) - self.origin) * SCALE

    def _grid(self, x) -> np.ndarray:
        """Metres → the nearest fixed-point grid position, as (integer-valued) float64; like
        :meth:`to_fixed` but never raising (far query positions just find nothing)."""
        return np.rint(np.minimum(np.maximum(self._frame(x), -2.0**40), 2.0**40))

    def _result(self, pos: np.ndarray, sort: bool) -> np.ndarray:
        idx = self.order[pos].astype(np.int64)
        if sort:
            idx.sort()
        return idx

    # ------------------------------------------------------------------------------ cells
    def _cell_range(self, lo: np.ndarray, hi: np.ndarray):
        """Cells (relative) touched by and fully inside integer rectangle ``[lo, hi]`` (2,)."""
        cu, cmin = self._cu, self._cmin
        outer0 = np.floor_divide(lo, cu) - cmin
        outer1 = np.floor_divide(hi, cu) - cmin
        inner0 = -np.floor_divide(-lo, cu) - cmin                 # ceil
        inner1 = np.floor_divide(hi + 1, cu) - 1 - cmin
        top = self._extent - 1
        return (np.clip(outer0, 0, top), np.clip(outer1, -1, top), inner0, inner1,
                (outer1 >= 0) & (outer0 <= top))

    def _leaves_in_rect(self, lo: np.ndarray, hi: np.ndarray):
        """Leaves of the integer horizontal rectangle ``[lo, hi]`` (fixed units, inclusive).

        Returns ``(inner_lo, inner_hi, border)``: leaf ranges ``[inner_lo[k], inner_hi[k])`` whose
        cells lie wholly inside the rectangle, and the leaves (int64) it covers only partly.
        """
        empty = np.empty(0, np.int64)
        if not self.cells or (lo > hi).any():
            return empty, empty, empty
        o0, o1, i0, i1, ok = self._cell_range(lo, hi)
        if not ok.all() or (o0 > o1).any():
            return empty, empty, empty
        n_cells = int((o1[0] - o0[0] + 1) * (o1[1] - o0[1] + 1))
        if n_cells <= _SMALL_RECT:
            ii, jj = np.meshgrid(np.arange(o0[0], o1[0] + 1), np.arange(o0[1], o1[1] + 1),
                                 indexing="ij")
            ii, jj = ii.ravel(), jj.ravel()
            leaves = self._find(_morton(ii, jj))
            found = leaves >= 0
            ii, jj, leaves = ii[found], jj[found], leaves[found]
            inside = (ii >= i0[0]) & (ii <= i1[0]) & (jj >= i0[1]) & (jj <= i1[1])
            return leaves[inside], leaves[inside] + 1, leaves[~inside]
        return self._descend_rect(o0, o1, i0, i1)

    def _descend_rect(self, o0, o1, i0, i1):
        """Quadtree descent for :meth:`_leaves_in_rect`, vectorised over each level's frontier."""
        in_lo, in_hi = [], []
        front = np.zeros(1, np.int64)                               # the root touches the grid
        d = self.depth
        for level in range(d):
            size = 1 << (d - level)
            x0, y0 = self._node_x0[front], self._node_y0[front]
            full = (x0 >= i0[0]) & (x0 + size - 1 <= i1[0]) & (y0 >= i0[1]) & (y0 + size - 1 <= i1[1])
            if full.any():
                in_lo.append(self._node_lo[front[full]])
                in_hi.append(self._node_hi[front[full]])
                front = front[~full]
            child = self._node_child[front].ravel().astype(np.int64)
            child = child[child >= 0]
            if level < d - 1:
                half = size >> 1
                cx, cy = self._node_x0[child], self._node_y0[child]
                touch = (cx <= o1[0]) & (cx + half - 1 >= o0[0]) & (cy <= o1[1]) & (cy + half - 1 >= o0[1])
                front = child[touch]
            else:
                cij = self._cell_ij[child]
                touch = ((cij[:, 0] >= o0[0]) & (cij[:, 0] <= o1[0]) & (cij[:, 1] >= o0[1])
                         & (cij[:, 1] <= o1[1]))
                inside = ((cij[:, 0] >= i0[0]) & (cij[:, 0] <= i1[0]) & (cij[:, 1] >= i0[1])
                          & (cij[:, 1] <= i1[1]))
                in_lo.append(child[touch & inside])
                in_hi.append(child[touch & inside] + 1)
                border = child[touch & ~inside]
        return (np.concatenate(in_lo) if in_lo else np.empty(0, np.int64),
                np.concatenate(in_hi) if in_hi else np.empty(0, np.int64), border)

    def _find(self, codes: np.ndarray) -> np.ndarray:
        """Leaf of each Morton code, ``-1`` where the cell is empty (binary search)."""
        k = np.searchsorted(self._codes, codes)
        k = np.minimum(k, len(self._codes) - 1)
        if not len(self._codes):
            return np.full(len(codes), -1, np.int64)
        return np.where(self._codes[k] == codes, k, -1).astype(np.int64)

    def lookup(self, h) -> np.ndarray:
        """Leaf index of the cell holding each horizontal position (binary search on the sorted
        Morton codes), ``-1`` for empty cells.

        Parameters
        ----------
        h : (M, 2) or (2,) float
            Metres along ``axes``.

        Returns
        -------
        (M,) int64
        """
        h = np.asarray(h, np.float64).reshape(-1, 2)
        u = (h - self.origin[list(self.axes)]) * SCALE
        c = np.floor_divide(_floor_i64(u), self._cu) - self._cmin
        ok = ((c >= 0) & (c < self._extent)).all(axis=1)
        out = np.full(len(h), -1, np.int64)
        if ok.any():
            out[ok] = self._find(_morton(c[ok, 0], c[ok, 1]))
        return out

    def descend(self, h) -> np.ndarray:
        """Same as :meth:`lookup` by walking the quadtree from the root (one vectorised step per
        level); kept to check the tree, :meth:`lookup` is the faster path."""
        h = np.asarray(h, np.float64).reshape(-1, 2)
        u = (h - self.origin[list(self.axes)]) * SCALE
        c = np.floor_divide(_floor_i64(u), self._cu) - self._cmin
        node = np.where(((c >= 0) & (c < self._extent)).all(axis=1), 0, -1).astype(np.int64)
        for level in range(self.depth):
            bit = self.depth - level - 1
            slot = ((c[:, 0] >> bit) & 1) | (((c[:, 1] >> bit) & 1) << 1)
            ok = node >= 0
            nxt = np.full(len(h), -1, np.int64)
            nxt[ok] = self._node_child[node[ok], slot[ok]]
            node = nxt
        return node

    # ------------------------------------------------------------------------------ candidates
    def _z_ranges(self, leaves: np.ndarray, zlo, zhi) -> tuple[np.ndarray, np.ndarray]:
        """Store positions ``[s, e)`` of each leaf's points with ``zlo <= z <= zhi`` (integers)."""
        s, e = self.offsets[leaves], self.offsets[leaves + 1]
        zlo = np.broadcast_to(np.asarray(zlo, np.int64), s.shape)
        zhi = np.broadcast_to(np.asarray(zhi, np.int64), s.shape)
        if len(leaves) <= 4:                                       # few cells: searchsorted each
            a, b = np.empty_like(s), np.empty_like(e)
            for k in range(len(leaves)):
                seg = self._z[s[k]:e[k]]
                lo_k = np.int32(min(max(zlo[k], _I32_MIN), _I32_MAX))
                hi_k = np.int32(min(max(zhi[k], _I32_MIN), _I32_MAX))
                a[k] = s[k] + np.searchsorted(seg, lo_k, "left")
                b[k] = s[k] + np.searchsorted(seg, hi_k, "right")
            return a, b
        both = _lower_bound(self._z, np.concatenate([s, s]), np.concatenate([e, e]),
                            np.concatenate([zlo, zhi + 1]))
        return both[:len(s)], both[len(s):]

    def _box_positions(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Store positions of the points with integer coordinates in ``[lo, hi]`` (3,) int64."""
        if not len(self) or (lo > hi).any():
            return np.empty(0, np.int64)
        if self._engine == "numba":
            out, n = _k_scan(*self._kernel_args(), lo, hi, 0, np.zeros(3), 0.0,
                             np.empty(64, np.int64), 0)
            return out[:n]
        a0, a1 = self.axes
        hlo, hhi = lo[[a0, a1]], hi[[a0, a1]]
        in_lo, in_hi, border = self._leaves_in_rect(hlo, hhi)
        zlo, zhi = lo[self.up], hi[self.up]
        inner = _ranges(in_lo, in_hi)
        s, e = self._z_ranges(np.concatenate([inner, border]), zlo, zhi)
        k = len(inner)
        pos_in = _ranges(s[:k], e[:k])
        pos_b = _ranges(s[k:], e[k:])
        if len(pos_b):
            x, y = self._p[a0, pos_b], self._p[a1, pos_b]
            pos_b = pos_b[(x >= hlo[0]) & (x <= hhi[0]) & (y >= hlo[1]) & (y <= hhi[1])]
        return np.concatenate([pos_in, pos_b])

    def _int_box(self, lo, hi) -> tuple[np.ndarray, np.ndarray]:
        """Integer bounds of a metric box: ``ceil`` / ``floor`` of its fixed-frame corners."""
        return _ceil_i64(self._grid(lo)), _floor_i64(self._grid(hi))

    # ------------------------------------------------------------------------------ queries
    def box(self, lo, hi, sort: bool = True) -> np.ndarray:
        """Points inside an axis-aligned box (faces included).

        Parameters
        ----------
        lo, hi : (3,) float
            Opposite corners, metres; an axis with ``lo > hi`` makes the box empty.
        sort : bool
            Return the indices sorted (default) or in store order (cell, then height).

        Returns
        -------
        (K,) int64
            Indices into the original cloud.
        """
        lo = _as_point(lo, 3, "box lo")
        hi = _as_point(hi, 3, "box hi")
        if self._engine == "numba" and len(self):
            return _k_select(*self._kernel_args(), self.order, self._grid(lo), self._grid(hi),
                             0, _ZERO3, 0.0, sort)
        return self._result(self._box_positions(*self._int_box(lo, hi)), sort)

    def rectangle(self, lo, hi, sort: bool = True) -> np.ndarray:
        """Points whose horizontal position is in a rectangle, at any height.

        Parameters
        ----------
        lo, hi : (2,) float
            Opposite corners along ``axes``, metres (edges included).

        Returns
        -------
        (K,) int64
            Indices into the original cloud.
        """
        lo = _as_point(lo, 2, "rectangle lo")
        hi = _as_point(hi, 2, "rectangle hi")
        ax = list(self.axes)
        ulo = self._grid(np.insert(lo, self.up, self.origin[self.up]))
        uhi = self._grid(np.insert(hi, self.up, self.origin[self.up]))
        ilo, ihi = _ceil_i64(ulo[ax]), _floor_i64(uhi[ax])
        if not len(self) or (ilo > ihi).any():
            return np.empty(0, np.int64)
        if self._engine == "numba":
            return _k_select(*self._kernel_args(), self.order, ulo, uhi, 2, _ZERO3, 0.0, sort)
        in_lo, in_hi, border = self._leaves_in_rect(ilo, ihi)
        # Leaves wholly inside are whole point ranges; runs of consecutive leaves are one range.
        pos_in = _ranges(self.offsets[in_lo], self.offsets[in_hi])
        pos_b = _ranges(self.offsets[border], self.offsets[border + 1])
        if len(pos_b):
            x, y = self._p[ax[0], pos_b], self._p[ax[1], pos_b]
            pos_b = pos_b[(x >= ilo[0]) & (x <= ihi[0]) & (y >= ilo[1]) & (y <= ihi[1])]
        return self._result(np.concatenate([pos_in, pos_b]), sort)

    def column(self, center, half_size, sort: bool = True) -> np.ndarray:
        """Points in the infinite vertical column of a horizontal rectangle around ``center``.

        Parameters
        ----------
        center : (2,) float
            Metres along ``axes``.
        half_size : float or (2,) float
            Half the rectangle's side(s), metres.

        Returns
        -------
        (K,) int64
            Indices into the original cloud.
        """
        c = _as_point(center, 2, "column center")
        h = np.broadcast_to(np.asarray(half_size, np.float64), (2,))
        for v in h:
            _as_length(v, "column half_size")
        return self.rectangle(c - h, c + h, sort=sort)

    def radius(self, center, r: float, sort: bool = True) -> np.ndarray:
        """Points within distance ``r`` of ``center`` (boundary included).

        Parameters
        ----------
        center : (3,) float
            Metres.
        r : float
            Metres.

        Returns
        -------
        (K,) int64
            Indices into the original cloud.
        """
        c = self._grid(_as_point(center, 3, "radius center"))
        rf = _as_length(r, "radius r") * SCALE
        if self._engine == "numba" and len(self):
            return _k_select(*self._kernel_args(), self.order, c, c, 1, c, rf, sort)
        pos = self._box_positions(_floor_i64(c - rf) - 1, _ceil_i64(c + rf) + 1)
        if len(pos):
            p = self._p[:, pos].astype(np.float64)
            d2 = (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2 + (p[2] - c[2]) ** 2
            pos = pos[d2 <= rf * rf]
        return self._result(pos, sort)

    def radius_many(self, centers, r: float, csr: bool = False):
        """:meth:`radius` for many centres in one vectorised pass.

        Parameters
        ----------
        centers : (M, 3) float
            Metres.
        r : float
            Metres, the same for every centre.
        csr : bool
            Return ``(offsets (M+1,), indices)`` instead of a list.

        Returns
        -------
        list of (K_m,) int64, or (offsets, indices)
            Sorted indices into the original cloud for each centre.
        """
        cen = np.asarray(centers, np.float64)
        if cen.ndim != 2 or cen.shape[1] != 3 or not np.isfinite(cen).all():
            raise PointCloudError(f"radius_many centers must be a finite (M, 3) array, got shape "
                                  f"{cen.shape}")
        rf = _as_length(r, "radius_many r") * SCALE
        m = len(cen)
        if not m or not len(self):
            offsets, hits = np.zeros(m + 1, np.int64), np.empty(0, np.int64)
            return (offsets, hits) if csr else [hits.copy() for _ in range(m)]
        c = self._grid(cen)
        lo = _floor_i64(c - rf) - 1
        hi = _ceil_i64(c + rf) + 1
        if self._engine == "numba":
            offsets, idx = _k_radius_many(*self._kernel_args(), self.order, lo, hi, c, rf * rf)
            return (offsets, idx) if csr else np.split(idx, offsets[1:-1])
        a0, a1 = self.axes
        ci0 = np.floor_divide(lo[:, [a0, a1]], self._cu) - self._cmin
        ci1 = np.floor_divide(hi[:, [a0, a1]], self._cu) - self._cmin
        ci0 = np.maximum(ci0, 0)
        ci1 = np.minimum(ci1, self._extent - 1)
        n0 = int(max((ci1[:, 0] - ci0[:, 0]).max() + 1, 0))
        n1 = int(max((ci1[:, 1] - ci0[:, 1]).max() + 1, 0))
        di, dj = np.meshgrid(np.arange(n0), np.arange(n1), indexing="ij")
        ii = ci0[:, :1] + di.ravel()
        jj = ci0[:, 1:] + dj.ravel()
        ok = (ii <= ci1[:, :1]) & (jj <= ci1[:, 1:])
        q = np.nonzero(ok)[0]
        leaves = self._find(_morton(ii[ok], jj[ok]))
        q, leaves = q[leaves >= 0], leaves[leaves >= 0]
        s, e = self._z_ranges(leaves, lo[q, self.up], hi[q, self.up])
        keep = e > s
        q, s, e = q[keep], s[keep], e[keep]
        found_q, found_p = [], []
        cum = np.cumsum(e - s)
        start = 0
        while start < len(q):                                      # bounded candidate batches
            base = cum[start - 1] if start else 0
            stop = max(int(np.searchsorted(cum, base + _PAIR_CHUNK, "right")), start + 1)
            n = e[start:stop] - s[start:stop]
            pos = _ranges(s[start:stop], e[start:stop])
            qq = np.repeat(q[start:stop], n)
            p = self._p[:, pos].astype(np.float64)
            cq = c[qq]
            d2 = (p[0] - cq[:, 0]) ** 2 + (p[1] - cq[:, 1]) ** 2 + (p[2] - cq[:, 2]) ** 2
            hit = d2 <= rf * rf
            found_q.append(qq[hit])
            found_p.append(pos[hit])
            start = stop
        qq = np.concatenate(found_q) if found_q else np.empty(0, np.int64)
        idx = self.order[np.concatenate(found_p)].astype(np.int64) if found_q else qq.copy()
        srt = np.lexsort((idx, qq))
        qq, idx = qq[srt], idx[srt]
        offsets = np.searchsorted(qq, np.arange(m + 1))
        if csr:
            return offsets.astype(np.int64), idx
        return np.split(idx, offsets[1:-1])

    def nearest(self, center, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` points nearest to ``center`` (ties: smaller index first).

        Parameters
        ----------
        center : (3,) float
            Metres.
        k : int
            How many (fewer when the store holds fewer).

        Returns
        -------
        index : (k,) int64
            Indices into the original cloud, nearest first.
        distance : (k,) float64
            Metres, between ``center`` and the stored positions.
        """
        k = int(k)
        if k < 1:
            raise PointCloudError(f"nearest k must be at least 1, got {k}")
        c = self._grid(_as_point(center, 3, "nearest center"))
        k = min(k, len(self))
        if not k:
            return np.empty(0, np.int64), np.empty(0)
        reach = float(np.maximum(np.abs(self._lo - c), np.abs(self._hi - c)).max()) + 2
        h = self._cu / 2.0
        if self._engine == "numba" and k <= 64:                    # the kernel's top-k is O(n k)
            idx, d2 = _k_nearest(*self._kernel_args(), self.order, c, np.int64(k), h, reach)
            return idx, np.sqrt(d2) * RESOLUTION
        while True:
            pos = self._box_positions(_floor_i64(c - h) - 1, _ceil_i64(c + h) + 1)
            if len(pos) >= k or h >= reach:
                p = self._p[:, pos].astype(np.float64)
                d2 = (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2 + (p[2] - c[2]) ** 2
                idx = self.order[pos].astype(np.int64)
                srt = np.lexsort((idx, d2))[:k]
                # Every point within h lies in the cube; the k-th distance must not exceed it.
                if d2[srt[-1]] <= h * h or h >= reach:
                    return idx[srt], np.sqrt(d2[srt]) * RESOLUTION
                h = math.sqrt(d2[srt[-1]]) + 1.0
            else:
                h *= 2.0

    def ray(self, origin, direction, radius: float = 0.1) -> RayHit | None:
        """The first point sphere a ray enters (``hohmann2009`` §3 picking).

        Every point is a ball of ``radius`` around its stored position.  A ray
        ``origin + t · direction/|direction|`` hits a ball when it passes within ``radius`` of the
        centre and enters it at ``t > 0`` (a ball that holds ``origin`` is not hit, as a depth
        sprite shows only its front).  The cells are walked in order along the ray (module
        docstring) and the walk stops as soon as no unvisited cell can hold an earlier hit.

        Parameters
        ----------
        origin, direction : (3,) float
            Metres; ``direction`` non-zero (its length does not matter).
        radius : float
            Sphere radius, metres (10 cm in CityFit's viewer).

        Returns
        -------
        RayHit or None
            ``(index, t)``: the original index of the point (the smaller index on a tie) and the
            distance in metres from ``origin`` to where the ray enters its sphere; ``None`` when
            the ray hits no sphere.
        """
        o = self._frame(_as_point(origin, 3, "ray origin"))
        d = _as_point(direction, 3, "ray direction")
        norm = float(np.sqrt(d @ d))
        if norm == 0:
            raise PointCloudError("ray direction must not be zero")
        d = d / norm
        rho = _as_length(radius, "ray radius") * SCALE
        if not len(self):
            return None
        pad = rho + 1.0
        t0, t1 = _slab(o, d, self._lo - pad, self._hi + pad, 0.0, math.inf)
        if t0 > t1:
            return None
        cu = float(self._cu)
        span = int(math.ceil(pad / cu))
        if self._engine == "numba":
            a = self._kernel_args()
            t, i = _k_ray(a[0], a[1], a[2], a[3], a[13], a[11], a[12], a[14], self.order, o, d,
                          rho, pad, t0, t1, np.int64(span))
            return None if i < 0 else RayHit(int(i), float(t) * RESOLUTION)
        sten = np.arange(-span, span + 1)
        si, sj = (g.ravel() for g in np.meshgrid(sten, sten, indexing="ij"))
        best_t, best_i = math.inf, -1
        ta, seg = t0, _RAY_FIRST * cu
        while ta <= t1:
            tb = min(ta + seg, t1)
            cells = self._ray_cells(o, d, ta, tb)
            ii = (cells[:, :1] + si).ravel()
            jj = (cells[:, 1:] + sj).ravel()
            ok = (ii >= 0) & (jj >= 0) & (ii < self._extent) & (jj < self._extent)
            codes = np.unique(_morton(ii[ok], jj[ok]))
            leaves = self._find(codes)
            leaves = leaves[leaves >= 0]
            if len(leaves):
                hit = self._ray_cells_hit(leaves, o, d, rho, pad, ta, tb)
                if hit is not None and (hit[0] < best_t or (hit[0] == best_t and hit[1] < best_i)):
                    best_t, best_i = hit
            # A sphere entered at t has its centre's foot at t_c <= t + rho, and every centre
            # whose foot lies before tb has been tested.
            if best_i >= 0 and best_t < tb - rho:
                break
            if tb >= t1:
                break
            ta, seg = tb, min(seg * 2.0, _RAY_MAX * cu)
        if best_i < 0:
            return None
        return RayHit(int(best_i), best_t * RESOLUTION)

    def _ray_cells(self, o, d, ta: float, tb: float) -> np.ndarray:
        """Cells (relative, (K, 2) int64) the horizontal projection of the ray crosses for
        ``t`` in ``[ta, tb]``, in order: Amanatides & Woo's grid-line crossings, merged."""
        cu = float(self._cu)
        ts = [np.array([ta, tb])]
        for a in self.axes:
            if d[a] == 0:
                continue
            ua, ub = (o[a] + ta * d[a]) / cu, (o[a] + tb * d[a]) / cu
            first, last = math.floor(min(ua, ub)) + 1, math.floor(max(ua, ub))
            if last >= first:
                lines = np.arange(first, last + 1, dtype=np.float64) * cu
                ts.append((lines - o[a]) / d[a])
        t = np.sort(np.concatenate(ts))
        t = np.concatenate([t, (t[:-1] + t[1:]) / 2])
        t = t[(t >= ta) & (t <= tb)]
        out = np.empty((len(t), 2), np.int64)
        for k, a in enumerate(self.axes):
            out[:, k] = np.floor((o[a] + t * d[a]) / cu).astype(np.int64) - self._cmin[k]
        return out

    def _ray_cells_hit(self, leaves, o, d, rho, pad, ta, tb):
        """Earliest sphere entry ``(t, original index)`` among the points of ``leaves`` whose
        centre's foot on the ray can lie in ``[ta, tb]``, or None."""
        cu = float(self._cu)
        a0, a1, up = self.axes[0], self.axes[1], self.up
        ij = self._cell_ij[leaves] + self._cmin
        lo_t = np.full(len(leaves), ta)
        hi_t = np.full(len(leaves), tb)
        for k, a in enumerate((a0, a1)):                           # slab of the widened cell
            lo_a = ij[:, k] * cu - pad
            hi_a = (ij[:, k] + 1) * cu + pad
            if d[a] == 0:
                inside = (o[a] >= lo_a) & (o[a] <= hi_a)
                hi_t = np.where(inside, hi_t, -np.inf)
                continue
            u, v = (lo_a - o[a]) / d[a], (hi_a - o[a]) / d[a]
            lo_t = np.maximum(lo_t, np.minimum(u, v))
            hi_t = np.minimum(hi_t, np.maximum(u, v))
        live = lo_t <= hi_t
        if not live.any():
            return None
        leaves, lo_t, hi_t = leaves[live], lo_t[live], hi_t[live]
        za, zb = o[up] + lo_t * d[up], o[up] + hi_t * d[up]
        zlo = _floor_i64(np.minimum(za, zb) - pad)
        zhi = _ceil_i64(np.maximum(za, zb) + pad)
        s, e = self._z_ranges(leaves, zlo, zhi)
        pos = _ranges(s, e)
        if not len(pos):
            return None
        t, ok = _sphere_entry(self._p[:, pos].astype(np.float64), o, d, rho)
        if not ok.any():
            return None
        t, idx = t[ok], self.order[pos[ok]].astype(np.int64)
        best = np.lexsort((idx, t))[0]
        return float(t[best]), int(idx[best])

    # ------------------------------------------------------------------------------ equality
    def unique(self) -> Groups:
        """Group exactly equal points (equal int32 triples: the 96-bit point id).

        Returns
        -------
        Groups
            ``keep``: one original index per distinct point (the smallest), sorted; ``group``:
            the group of every original point.
        """
        n = len(self)
        if not n:
            return Groups(np.empty(0, np.int64), np.empty(0, np.int64))
        if self._engine == "numba":
            groups = self._merge_kernel(0.0)
            if groups is not None:
                return groups
        p = self._p
        orig = self.order.astype(np.int64)
        srt = np.lexsort((orig, p[2], p[1], p[0]))
        ps = p[:, srt]
        new = np.empty(n, bool)
        new[0] = True
        np.any(ps[:, 1:] != ps[:, :-1], axis=0, out=new[1:])
        label_sorted = np.cumsum(new) - 1
        labels = np.empty(n, np.int64)
        labels[orig[srt]] = label_sorted
        return _relabel(labels, int(label_sorted[-1]) + 1)

    def merge(self, radius: float = MERGE_RADIUS) -> Groups:
        """Group points closer than ``radius`` (transitively: chains of close points are one
        group); exact duplicates are always merged.

        Parameters
        ----------
        radius : float
            Metres (default 2⁻¹³ m ≈ 0.12 mm, ``hohmann2009`` §3); distances are between stored
            positions, so the test does not depend on how far the points are from the origin.

        Returns
        -------
        Groups
            As :meth:`unique`.
        """
        rf = _as_length(radius, "merge radius") * SCALE
        if self._engine == "numba" and len(self):
            groups = self._merge_kernel(rf if rf > 1.0 else 0.0)
            if groups is not None:
                return groups
        exact = self.unique()
        if rf <= 1.0 or len(exact.keep) < 2:                       # distinct ints are >= 1 apart
            return exact
        u = self.fixed(exact.keep).astype(np.int64)                # distinct points, (G, 3)
        g = 2 * int(math.ceil(rf))                                 # hash cell: twice the radius
        cell = np.floor_divide(u, g)
        side = np.where(u - cell * g < g // 2, -1, 1)              # the half a point's ball leans to
        key = _hash3(cell)
        srt = np.argsort(key, kind="stable")
        skey = key[srt]
        pairs_i, pairs_j = [], []
        for corner in np.ndindex(2, 2, 2):
            nb = cell + side * np.array(corner)
            nkey = _hash3(nb)
            s = np.searchsorted(skey, nkey, "left")
            e = np.searchsorted(skey, nkey, "right")
            cnt = e - s
            i = np.repeat(np.arange(len(u)), cnt)
            j = srt[_ranges(s, e)]
            keep = j > i
            i, j = i[keep], j[keep]
            diff = (u[i] - u[j]).astype(np.float64)
            close = (diff[:, 0] ** 2 + diff[:, 1] ** 2 + diff[:, 2] ** 2) < rf * rf
            pairs_i.append(i[close])
            pairs_j.append(j[close])
        i, j = np.concatenate(pairs_i), np.concatenate(pairs_j)
        if not len(i):
            return exact
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        m = len(u)
        graph = coo_matrix((np.ones(len(i), np.int8), (i, j)), shape=(m, m)).tocsr()
        n_comp, comp = connected_components(graph, directed=False)
        return _relabel(comp[exact.group].astype(np.int64), n_comp)

    def _merge_kernel(self, rf: float) -> Groups | None:
        """:func:`_k_merge` with hash cells of 8 radii (at least 64 units, at most a column); None
        when the radius exceeds half a column or the packed cell key would not fit 63 bits
        (columns of kilometres): the numpy path does those."""
        a = self._kernel_args()
        reach = int(math.ceil(rf))
        g = min(8 * max(reach, 8), self._cu)
        if 2 * reach > g:                                          # a ball wider than a column
            return None
        bx = (self._cu // g - 1).bit_length()
        zbits = int((self._hi[self.up] - self._lo[self.up]) // g).bit_length()
        if 2 * bx + zbits > 62:
            return None
        root = _k_merge(self._p, self.offsets, self._codes, self._cell_ij, self._cmin,
                        np.int64(self._cu), a[14], self.order, np.int64(g),
                        np.int64(self._lo[self.up]), np.int64(bx), rf * rf)
        return _groups_of_roots(root)

    # ------------------------------------------------------------------------------ files
    def save(self, path) -> Path:
        """Write the store to a ``.npz`` file atomically (temporary file, then ``os.replace``).

        Returns the path written.  Leaves and tree are rebuilt on :meth:`load`.
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(fh, format=np.array(_FORMAT), version=np.array(_VERSION),
                         points=self._p, order=self.order, origin=self.origin,
                         cell_units=np.array(self._cu, np.int64), up=np.array(self.up),
                         source=np.array(self.source))
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path) -> PointStore:
        """Read a store written by :meth:`save`.

        Raises
        ------
        PointCloudError
            Not such a file, another version, or inconsistent arrays.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as f:
                data = {k: f[k] for k in f.files}
        except (OSError, ValueError, EOFError) as exc:
            raise PointCloudError(f"{path}: cannot read a point store ({exc}); write it with "
                                  "PointStore.save") from None
        need = {"format", "version", "points", "order", "origin", "cell_units", "up"}
        if not need <= set(data) or str(data["format"]) != _FORMAT:
            raise PointCloudError(f"{path}: not a facadeforge point store (.npz from "
                                  "PointStore.save)")
        if int(data["version"]) != _VERSION:
            raise PointCloudError(f"{path}: point store version {int(data['version'])}, this "
                                  f"facadeforge reads version {_VERSION}; rebuild it from the cloud")
        pts, order = data["points"], data["order"]
        n = pts.shape[1] if pts.ndim == 2 else -1
        if (pts.ndim != 2 or pts.shape[0] != 3 or pts.dtype != np.int32 or order.shape != (n,)
                or order.dtype.kind != "i"):
            raise PointCloudError(f"{path}: point arrays have shapes {pts.shape}, {order.shape}; "
                                  "the file is damaged, rebuild it")
        if n and (order.min() < 0 or order.max() >= n
                  or not (np.bincount(order, minlength=n) == 1).all()):
            raise PointCloudError(f"{path}: the permutation is not one; the file is damaged")
        if int(data["up"]) not in (0, 1, 2) or int(data["cell_units"]) < 1:
            raise PointCloudError(f"{path}: bad up axis or cell size; the file is damaged")
        return cls(pts, order, data["origin"], int(data["cell_units"]), int(data["up"]),
                   str(data.get("source", path)))


# ------------------------------------------------------------------------------ numba kernels
# Plain Python functions, compiled on first use by _jit() (numba is imported there, not with the
# module).  Each does for one query what the vectorised numpy methods do with many small array
# calls, whose fixed cost (about 1 µs a call) dominates a query of a few hundred points; the numpy
# path (``engine="numpy"``) is the reference the tests compare them against.  The arithmetic of
# every point test is the numpy path's, operation for operation, so both give the same sets.
_KERNELS: dict = {}


def _kernel(fn):
    _KERNELS[fn.__name__] = fn
    return fn


@_kernel
def _k_morton(i, j):
    """Morton code of one cell (the scalar form of :func:`_morton`)."""
    out = np.uint64(0)
    for src, shift in ((np.uint64(i), np.uint64(0)), (np.uint64(j), np.uint64(1))):
        v = src & np.uint64(0x00000000FFFFFFFF)
        v = (v | (v << np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)
        v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)
        v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
        v = (v | (v << np.uint64(2))) & np.uint64(0x3333333333333333)
        v = (v | (v << np.uint64(1))) & np.uint64(0x5555555555555555)
        out |= v << shift
    return out


@_kernel
def _k_find(codes, i, j):
    """Leaf of cell (i, j), -1 when empty: binary search on the sorted Morton codes."""
    code = _k_morton(i, j)
    k = np.searchsorted(codes, code)
    if k < len(codes) and codes[k] == code:
        return k
    return -1


@_kernel
def _k_lower(z, lo, hi, t):
    """First index in [lo, hi) with z >= t (hi when none)."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if z[mid] < t:
            lo = mid + 1
        else:
            hi = mid
    return lo


@_kernel
def _k_leaves(codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, o, inner_box, leaves, inner):
    """Leaves touching the cell rectangle ``o`` = (i0, i1, j0, j1) (inclusive, clipped to the
    grid) into ``leaves`` and whether each lies within ``inner_box``; returns their count.
    Small rectangles: one Morton lookup per cell; large ones: quadtree descent (stack)."""
    i0, i1, j0, j1 = o[0], o[1], o[2], o[3]
    n0, n1, m0, m1 = inner_box[0], inner_box[1], inner_box[2], inner_box[3]
    k = 0
    if (i1 - i0 + 1) * (j1 - j0 + 1) <= 256:
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                leaf = _k_find(codes, i, j)
                if leaf >= 0:
                    leaves[k] = leaf
                    inner[k] = n0 <= i <= n1 and m0 <= j <= m1
                    k += 1
        return k
    stack = np.empty(4 * depth + 4, np.int64)
    level = np.empty(4 * depth + 4, np.int64)
    stack[0], level[0], sp = 0, 0, 1
    while sp > 0:
        sp -= 1
        node, lev = stack[sp], level[sp]
        size = np.int64(1) << (depth - lev)
        x0, y0 = nx0[node], ny0[node]
        if x0 >= n0 and x0 + size - 1 <= n1 and y0 >= m0 and y0 + size - 1 <= m1:
            for leaf in range(nlo[node], nhi[node]):
                leaves[k] = leaf
                inner[k] = True
                k += 1
            continue
        half = size >> 1
        for slot in range(4):
            ch = child[node, slot]
            if ch < 0:
                continue
            if lev == depth - 1:
                i, j = cell_ij[ch, 0], cell_ij[ch, 1]
                if i0 <= i <= i1 and j0 <= j <= j1:
                    leaves[k] = ch
                    inner[k] = n0 <= i <= n1 and m0 <= j <= m1
                    k += 1
            else:
                cx, cy = nx0[ch], ny0[ch]
                if cx <= i1 and cx + half - 1 >= i0 and cy <= j1 and cy + half - 1 >= j0:
                    stack[sp], level[sp] = ch, lev + 1
                    sp += 1
    return k


@_kernel
def _k_scan(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, extent, cu,
            cmin, axes, lo, hi, mode, c, r2, out, n):
    """Append to ``out[n:]`` the store positions of points in the integer box ``[lo, hi]``
    (``mode`` 1: and within ``sqrt(r2)`` of ``c``, fixed frame); returns ``(out, n)``, ``out``
    grown when full."""
    a0, a1, up = axes[0], axes[1], axes[2]
    if lo[0] > hi[0] or lo[1] > hi[1] or lo[2] > hi[2] or len(codes) == 0:
        return out, n
    o = np.empty(4, np.int64)
    inner_box = np.empty(4, np.int64)
    for k, a in enumerate((a0, a1)):
        top = extent - 1
        c0 = lo[a] // cu - cmin[k]
        c1 = hi[a] // cu - cmin[k]
        if c1 < 0 or c0 > top:
            return out, n
        o[2 * k], o[2 * k + 1] = max(c0, 0), min(c1, top)
        inner_box[2 * k] = -((-lo[a]) // cu) - cmin[k]
        inner_box[2 * k + 1] = (hi[a] + 1) // cu - 1 - cmin[k]
    cap = min((o[1] - o[0] + 1) * (o[3] - o[2] + 1), len(codes))
    leaves = np.empty(cap, np.int64)
    inner = np.empty(cap, np.bool_)
    nl = _k_leaves(codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, o, inner_box, leaves, inner)
    zlo, zhi1 = lo[up], hi[up] + 1
    for m in range(nl):
        leaf = leaves[m]
        s = _k_lower(z, offsets[leaf], offsets[leaf + 1], zlo)
        e = _k_lower(z, s, offsets[leaf + 1], zhi1)
        if n + (e - s) > len(out):
            grown = np.empty(max(2 * len(out), n + (e - s)), np.int64)
            grown[:n] = out[:n]
            out = grown
        test_xy = not inner[m]
        for q in range(s, e):
            if test_xy:
                x, y = p[a0, q], p[a1, q]
                if x < lo[a0] or x > hi[a0] or y < lo[a1] or y > hi[a1]:
                    continue
            if mode == 1:
                d0 = float(p[0, q]) - c[0]
                d1 = float(p[1, q]) - c[1]
                d2 = float(p[2, q]) - c[2]
                if d0 * d0 + d1 * d1 + d2 * d2 > r2:
                    continue
            out[n] = q
            n += 1
    return out, n


@_kernel
def _k_select(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, extent, cu, cmin,
              axes, order, ulo, uhi, mode, c, rf, sort):
    """One query, original indices out.  ``mode`` 0: box ``[ceil(ulo), floor(uhi)]``; 1: ball of
    radius ``rf`` around ``c``; 2: horizontal rectangle of ``ulo``/``uhi``, any height (all in
    the fixed frame, as float64)."""
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    for a in range(3):
        if mode == 1:
            lo[a] = np.int64(np.floor(max(c[a] - rf, -2.0**40))) - 1
            hi[a] = np.int64(np.ceil(min(c[a] + rf, 2.0**40))) + 1
        elif mode == 2 and a == axes[2]:
            lo[a], hi[a] = -2147483648, 2147483647
        else:
            lo[a] = np.int64(np.ceil(min(max(ulo[a], -2.0**40), 2.0**40)))
            hi[a] = np.int64(np.floor(min(max(uhi[a], -2.0**40), 2.0**40)))
    out, n = _k_scan(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, extent, cu,
                     cmin, axes, lo, hi, 1 if mode == 1 else 0, c, rf * rf,
                     np.empty(64, np.int64), 0)
    res = np.empty(n, np.int64)
    for q in range(n):
        res[q] = order[out[q]]
    if sort:
        res.sort()
    return res


@_kernel
def _k_nearest(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, extent, cu,
               cmin, axes, order, c, k, h, reach):
    """The k nearest stored points to ``c`` (fixed frame): ``(original indices, squared
    distances)``, nearest first, ties by index.  Cubes grow from half-size ``h`` (half a cell,
    shrunk by ``sqrt(k / points in c's cell)`` where that cell is dense) until they hold k points
    and the k-th distance is within the cube."""
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    ci = np.int64(np.floor(c[axes[0]] / cu)) - cmin[0]
    cj = np.int64(np.floor(c[axes[1]] / cu)) - cmin[1]
    if 0 <= ci < extent and 0 <= cj < extent:                      # start from the local density
        leaf = _k_find(codes, ci, cj)
        if leaf >= 0:
            count = offsets[leaf + 1] - offsets[leaf]
            if count > k:
                h = max(h * np.sqrt(k / count), 1.0)
    while True:
        for a in range(3):
            lo[a] = np.int64(np.floor(max(c[a] - h, -2.0**40))) - 1
            hi[a] = np.int64(np.ceil(min(c[a] + h, 2.0**40))) + 1
        out, n = _k_scan(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth,
                         extent, cu, cmin, axes, lo, hi, 0, c, 0.0, np.empty(64, np.int64), 0)
        if n >= k or h >= reach:
            # the k best by (distance, index): insertion into a sorted list of k
            top_d = np.full(k, np.inf)
            top_i = np.full(k, np.iinfo(np.int64).max)
            for q in range(n):
                d0 = float(p[0, out[q]]) - c[0]
                d1 = float(p[1, out[q]]) - c[1]
                dz = float(p[2, out[q]]) - c[2]
                dq = d0 * d0 + d1 * d1 + dz * dz
                iq = np.int64(order[out[q]])
                if dq > top_d[k - 1] or (dq == top_d[k - 1] and iq > top_i[k - 1]):
                    continue
                m = k - 1
                while m > 0 and (top_d[m - 1] > dq or (top_d[m - 1] == dq and top_i[m - 1] > iq)):
                    top_d[m], top_i[m] = top_d[m - 1], top_i[m - 1]
                    m -= 1
                top_d[m], top_i[m] = dq, iq
            if top_d[k - 1] <= h * h or h >= reach:
                return top_i, top_d
            h = np.sqrt(top_d[k - 1]) + 1.0
        else:
            h *= 2.0


@_kernel
def _k_radius_many(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth, extent,
                   cu, cmin, axes, order, lo, hi, c, r2):
    """Balls of one radius around many centres: CSR ``(offsets (M+1,), sorted original
    indices)``; ``lo``/``hi`` (M, 3) the integer boxes, ``c`` (M, 3) the centres (fixed frame)."""
    m = len(c)
    res = np.empty(max(16 * m, 64), np.int64)
    starts = np.zeros(m + 1, np.int64)
    n = 0
    for k in range(m):
        res, n2 = _k_scan(p, z, offsets, codes, cell_ij, child, nx0, ny0, nlo, nhi, depth,
                          extent, cu, cmin, axes, lo[k], hi[k], 1, c[k], r2, res, n)
        for q in range(n, n2):
            res[q] = order[res[q]]
        res[n:n2].sort()
        n = n2
        starts[k + 1] = n
    return starts, res[:n]


@_kernel
def _k_ray(p, z, offsets, codes, cmin, extent, cu, axes, order, o, d, rho, pad, t0, t1, span):
    """Amanatides & Woo walk of the 2D column grid along the ray ``o + t d`` (fixed frame, ``d``
    unit) from ``t0`` to ``t1``; each step's ``t`` interval in pieces of at most one cell, each
    piece testing the cells within ``span`` of the step's cell.  Returns ``(t, original index)``
    of the first sphere entered at t > 0, ``(inf, -1)`` when none."""
    a0, a1, up = axes[0], axes[1], axes[2]
    cuf = float(cu)
    rho2 = rho * rho
    best_t, best_i = np.inf, -1
    ci = np.int64(np.floor((o[a0] + t0 * d[a0]) / cuf)) - cmin[0]
    cj = np.int64(np.floor((o[a1] + t0 * d[a1]) / cuf)) - cmin[1]
    si = 1 if d[a0] > 0 else (-1 if d[a0] < 0 else 0)
    sj = 1 if d[a1] > 0 else (-1 if d[a1] < 0 else 0)
    ta = t0
    while True:
        tx, ty = np.inf, np.inf
        if si != 0:
            tx = ((ci + cmin[0] + (1 if si > 0 else 0)) * cuf - o[a0]) / d[a0]
        if sj != 0:
            ty = ((cj + cmin[1] + (1 if sj > 0 else 0)) * cuf - o[a1]) / d[a1]
        tb = min(tx, ty, t1)
        if tb < ta:
            tb = ta
        u = ta
        while True:
            v = min(u + cuf, tb)
            for di in range(-span, span + 1):
                ni = ci + di
                if ni < 0 or ni >= extent:
                    continue
                for dj in range(-span, span + 1):
                    nj = cj + dj
                    if nj < 0 or nj >= extent:
                        continue
                    leaf = _k_find(codes, ni, nj)
                    if leaf < 0:
                        continue
                    lo_t, hi_t = u, v
                    for k in range(2):
                        a = a0 if k == 0 else a1
                        cell_k = (ni if k == 0 else nj) + cmin[k]
                        lo_a = cell_k * cuf - pad
                        hi_a = (cell_k + 1) * cuf + pad
                        if d[a] == 0:
                            if o[a] < lo_a or o[a] > hi_a:
                                hi_t = -np.inf
                        else:
                            ua, va = (lo_a - o[a]) / d[a], (hi_a - o[a]) / d[a]
                            lo_t = max(lo_t, min(ua, va))
                            hi_t = min(hi_t, max(ua, va))
                    if lo_t > hi_t:
                        continue
                    za, zb = o[up] + lo_t * d[up], o[up] + hi_t * d[up]
                    zlo = np.int64(np.floor(max(min(za, zb) - pad, -2.0**40)))
                    zhi = np.int64(np.ceil(min(max(za, zb) + pad, 2.0**40)))
                    s = _k_lower(z, offsets[leaf], offsets[leaf + 1], zlo)
                    e = _k_lower(z, s, offsets[leaf + 1], zhi + 1)
                    for q in range(s, e):
                        w0 = float(p[0, q]) - o[0]
                        w1 = float(p[1, q]) - o[1]
                        w2 = float(p[2, q]) - o[2]
                        tc = w0 * d[0] + w1 * d[1] + w2 * d[2]
                        q0, q1, q2 = w0 - tc * d[0], w1 - tc * d[1], w2 - tc * d[2]
                        h2 = q0 * q0 + q1 * q1 + q2 * q2
                        if h2 > rho2:
                            continue
                        t = tc - np.sqrt(rho2 - h2)
                        if t > 0 and (t < best_t or (t == best_t and order[q] < best_i)):
                            best_t, best_i = t, order[q]
            if best_i >= 0 and best_t < v - rho:
                return best_t, best_i
            if v >= tb:
                break
            u = v
        if tb >= t1:
            return best_t, best_i
        if tx <= ty:
            ci += si
        else:
            cj += sj
        ta = tb


@_kernel
def _k_merge(p, offsets, codes, cell_ij, cmin, cu, axes, order, g, zmin, bx, r2):
    """Groups of equal points (``r2 == 0``) or of points closer than ``sqrt(r2)`` joined
    transitively; returns the root (smallest original index) of every original point.

    Grid hash, column by column: inside each 4 m column a point's hash cell (side ``g`` units,
    ``g`` >= 2 ``sqrt(r2)``, the last cell of a column up to ``2 g`` wide) is the packed key ``gz << 2 bx | gx << bx | gy`` (``gx``, ``gy``
    local to the column, ``gz`` from the lowest point); each column's keys are sorted once, and a
    point looks up its own cell and the neighbour cells across the faces its ball reaches (on
    average 2 of 8) by binary search in the sorted keys of the column holding them, so every
    lookup stays in one column's few kilobytes.  Union-find with the smaller index as root."""
    a0, a1, up = axes[0], axes[1], axes[2]
    n = p.shape[1]
    nx = cu // g                     # hash cells per column side; the last one takes the rest
    skey = np.empty(n, np.int64)
    spos = np.empty(n, np.int64)
    for c in range(len(offsets) - 1):
        s, e = offsets[c], offsets[c + 1]
        x0 = (cell_ij[c, 0] + cmin[0]) * cu
        y0 = (cell_ij[c, 1] + cmin[1]) * cu
        keys = np.empty(e - s, np.int64)
        for q in range(s, e):
            gx = min((np.int64(p[a0, q]) - x0) // g, nx - 1)
            gy = min((np.int64(p[a1, q]) - y0) // g, nx - 1)
            gz = (np.int64(p[up, q]) - zmin) // g
            keys[q - s] = (gz << (2 * bx)) | (gx << bx) | gy
        perm = np.argsort(keys)
        for m in range(e - s):
            skey[s + m] = keys[perm[m]]
            spos[s + m] = s + perm[m]
    parent = np.arange(n)
    reach = np.int64(np.ceil(np.sqrt(r2)))
    lo_face = np.empty(3, np.int64)
    hi_face = np.empty(3, np.int64)
    side = np.empty(3, np.int64)
    cellq = np.empty(3, np.int64)
    t = np.empty(3, np.int64)
    for c in range(len(offsets) - 1):
        ci, cj = cell_ij[c, 0], cell_ij[c, 1]
        x0 = (ci + cmin[0]) * cu
        y0 = (cj + cmin[1]) * cu
        for q in range(offsets[c], offsets[c + 1]):
            local = (np.int64(p[a0, q]) - x0, np.int64(p[a1, q]) - y0, np.int64(p[up, q]) - zmin)
            near = 0
            for k in range(3):
                cellq[k] = local[k] // g
                if k < 2 and cellq[k] > nx - 1:
                    cellq[k] = nx - 1
                side[k] = 0
                lo_face[k] = cellq[k] * g
                hi_face[k] = (cellq[k] + 1) * g
                if k < 2 and cellq[k] == nx - 1:
                    hi_face[k] = cu                                # the last cell: to the border
                if r2 > 0:
                    if local[k] - lo_face[k] < reach:
                        side[k] = -1
                    elif hi_face[k] - local[k] <= reach:
                        side[k] = 1
                    if side[k] != 0:
                        near |= 1 << k
            oq = order[q]
            for corner in range(8):
                if corner & ~near:
                    continue
                dc_i, dc_j = 0, 0
                for k in range(3):
                    t[k] = cellq[k] + (side[k] if (corner >> k) & 1 else 0)
                if t[2] < 0:
                    continue
                if t[0] < 0:
                    dc_i, t[0] = -1, nx - 1
                elif t[0] >= nx:
                    dc_i, t[0] = 1, 0
                if t[1] < 0:
                    dc_j, t[1] = -1, nx - 1
                elif t[1] >= nx:
                    dc_j, t[1] = 1, 0
                leaf = c
                if dc_i != 0 or dc_j != 0:
                    if ci + dc_i < 0 or cj + dc_j < 0:
                        continue
                    leaf = _k_find(codes, ci + dc_i, cj + dc_j)
                    if leaf < 0:
                        continue
                key = (t[2] << (2 * bx)) | (t[0] << bx) | t[1]
                s, e = offsets[leaf], offsets[leaf + 1]
                m = s + np.searchsorted(skey[s:e], key)
                while m < e and skey[m] == key:
                    q2 = spos[m]
                    m += 1
                    o2 = order[q2]
                    if o2 <= oq:
                        continue
                    d0 = float(np.int64(p[0, q]) - np.int64(p[0, q2]))
                    d1 = float(np.int64(p[1, q]) - np.int64(p[1, q2]))
                    d2 = float(np.int64(p[2, q]) - np.int64(p[2, q2]))
                    dd = d0 * d0 + d1 * d1 + d2 * d2
                    if (r2 > 0 and dd < r2) or (r2 == 0 and dd == 0):
                        ra, rb = np.int64(oq), np.int64(o2)         # union, smaller root wins
                        while parent[ra] != ra:
                            parent[ra] = parent[parent[ra]]
                            ra = parent[ra]
                        while parent[rb] != rb:
                            parent[rb] = parent[parent[rb]]
                            rb = parent[rb]
                        if ra < rb:
                            parent[rb] = ra
                        elif rb < ra:
                            parent[ra] = rb
    for i in range(n):                                             # roots, ascending: O(n)
        parent[i] = parent[parent[i]]
    return parent


@functools.cache
def _jit() -> None:
    """Compile the kernels (numba imported here) and bind them in place of the plain functions,
    so that kernels calling kernels call the compiled ones."""
    import numba

    for name, fn in _KERNELS.items():
        globals()[name] = numba.njit(cache=True, nogil=True)(fn)


# ------------------------------------------------------------------------------ module helpers
def _to_fixed(xyz, origin: np.ndarray, source: str) -> np.ndarray:
    a = np.asarray(xyz, np.float64)
    if a.shape[-1:] != (3,):
        raise PointCloudError(f"{source}: coordinates must be (..., 3), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise PointCloudError(f"{source}: coordinates must be finite to become fixed point")
    u = np.rint((a - origin) * SCALE)
    bad = ~((u >= _I32_MIN) & (u <= _I32_MAX))
    if bad.any():
        rows = bad.reshape(-1, 3).any(axis=1)
        far = float(np.nanmax(np.abs(a - origin).reshape(-1, 3)[rows]))
        raise PointCloudError(
            f"{source}: {int(rows.sum())} point(s) lie up to {far:.1f} m from the origin "
            f"{origin.tolist()}; 16.16 fixed point holds ±32768 m around it — give an origin "
            "nearer the points or split the cloud into tiles under 65 km")
    return u.astype(np.int32)


def _relabel(labels: np.ndarray, n_groups: int) -> Groups:
    """Number groups by their smallest member; ``keep`` = those members, sorted."""
    first = np.full(n_groups, len(labels), np.int64)
    np.minimum.at(first, labels, np.arange(len(labels)))
    keep_order = np.argsort(first)
    rank = np.empty(n_groups, np.int64)
    rank[keep_order] = np.arange(n_groups)
    return Groups(first[keep_order], rank[labels])


def _groups_of_roots(root: np.ndarray) -> Groups:
    """Groups from union-find roots that are each group's smallest index (O(N), no sort)."""
    is_root = root == np.arange(len(root))
    rank = np.cumsum(is_root) - 1
    return Groups(np.flatnonzero(is_root).astype(np.int64), rank[root].astype(np.int64))


_H = [np.uint64(c) for c in (0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9)]


def _hash3(cell: np.ndarray) -> np.ndarray:
    """64-bit hash of integer triples (M, 3); collisions only add candidates, never lose one."""
    c = cell.astype(np.uint64)
    h = c[:, 0] * _H[0]
    h ^= c[:, 1] * _H[1]
    h ^= c[:, 2] * _H[2]
    return h ^ (h >> np.uint64(29))


def _slab(o, d, lo, hi, t0: float, t1: float) -> tuple[float, float]:
    """Parameter interval of the ray ``o + t d`` inside the box ``[lo, hi]``, within [t0, t1]."""
    for a in range(3):
        if d[a] == 0:
            if not lo[a] <= o[a] <= hi[a]:
                return math.inf, -math.inf
            continue
        u, v = (lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]
        t0, t1 = max(t0, min(u, v)), min(t1, max(u, v))
    return t0, t1


def _sphere_entry(p: np.ndarray, o: np.ndarray, d: np.ndarray, rho: float):
    """Entry parameter of the ray into balls of radius ``rho`` around ``p`` (3, K) float64 (all
    in the fixed frame), and whether it enters them at ``t > 0``."""
    w0, w1, w2 = p[0] - o[0], p[1] - o[1], p[2] - o[2]
    tc = w0 * d[0] + w1 * d[1] + w2 * d[2]
    q0, q1, q2 = w0 - tc * d[0], w1 - tc * d[1], w2 - tc * d[2]
    h2 = q0 * q0 + q1 * q1 + q2 * q2
    inside = h2 <= rho * rho
    t = tc - np.sqrt(np.where(inside, rho * rho - h2, 0.0))
    return t, inside & (t > 0)
