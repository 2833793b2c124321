"""``splitAndSetbackPerimeter``: split a face's perimeter into sections, set each back by its depth.

Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-split-and-setback-perimeter.htm
"""

from __future__ import annotations

import numpy as np

from ...geometry.mesh import EPS
from ..values import CGARuntimeError, to_float
from . import operation
from .subdivision import RepeatItem, _PlanarEdges, _size_items, resolve_split

_NAME = "splitAndSetbackPerimeter"
#: The most sections one call may make (a repeat on a long perimeter with tiny lengths).
MAX_SECTIONS = 100_000


@operation(_NAME, 1, 3, body=True)
def op_split_and_setback_perimeter(call):
    """``splitAndSetbackPerimeter(splitOffset[, firstEdgeIndex, selectedEdgesMask])
    { length : depth : ops | … }[*] { remainder : ops }`` on a single planar face.

    As the reference describes: the chain of selected edges, from ``firstEdgeIndex`` on and
    counter-clockwise around the face (the face's own edge order), is split like ``split`` with
    the lengths (absolute, ``'`` of the chain's length, ``~`` floating; ``*`` repeats the
    pattern), the pattern starting ``splitOffset`` (``'`` relative) along the chain.  Each section
    becomes the band of its ``depth`` inside the face along its piece of the perimeter; what no
    section takes is ``remainder``.  ``selectedEdgesMask`` holds one bool per edge; missing
    elements count as not selected.

    Where the reference is silent we do what a CityEngine user expects: two sections meeting at a
    corner are divided along the corner's bisector; a section ending at a corner whose next edge
    is not selected runs on to the face's border (as ``setback`` does); a section ending
    mid-edge ends square to the edge.  Sections are cut in chain order, so where bands of far
    apart edges overlap (narrow faces) the earlier section keeps the overlap.  The offset wraps
    around the chain, so a section may run over the chain's start.  A depth of 0 makes no shape;
    a negative one is an error.  Sections get ``split.index`` and ``split.total``.
    """
    st = call.state
    pe = _PlanarEdges(st, _NAME, call.derivation.object_scope.rotation)
    if pe.holes:
        raise CGARuntimeError(f"{_NAME}: the face has holes (a courtyard); deleteHoles() first")
    chain = _chain(call, pe)
    pattern = [b for b in call.branches if getattr(b, "depth", None) is not None]
    others = [b for b in call.branches if getattr(b, "depth", None) is None]
    remainder = _remainder_branch(call, others)
    total = float(chain.lengths.sum())
    offset = call.size(0, total) if total > EPS else 0.0
    pieces, taken = [], None
    for branch, start, width in _sections(call, pattern, total):
        band = _section_band(pe, chain, (offset + start) % total, width, _depth(call, branch))
        if band is None:
            continue
        geom = pe.shape.intersection(band)
        if taken is not None:
            geom = geom.difference(taken)
        taken = band if taken is None else taken.union(band)
        if geom.area > EPS:
            pieces.append((branch, geom))
    n = len(pieces)
    if remainder is not None:
        # the rest of the face is what the sections left, not the face minus the union of the
        # bands: that union can lose slivers on near-degenerate coordinates, so a piece would be
        # counted twice (sections and remainder always add up to the face)
        from shapely import union_all

        used = union_all([g for _, g in pieces]) if pieces else None
        rest = pe.shape if used is None else pe.shape.difference(used, grid_size=1e-9)
        pieces.append((remainder, rest))
    out = pe.shapes(st, pieces, chain.selected, remainder)  # the setback family's edge tags
    for ps, _, info in out:
        if info["index"] < n:
            ps.context = {**ps.context, "split.index": info["index"], "split.total": n}
    return out


def _remainder_branch(call, branches):
    """The ``remainder`` branch (at most one); any other plain selector is an error."""
    found = None
    for b in branches:
        name = getattr(b.selector, "name", None)
        if name != "remainder":
            raise CGARuntimeError(f"{_NAME}: the second body takes only 'remainder : …'; write "
                                  "the sections as 'length : depth : operations'")
        found = b
    return found


def _sections(call, pattern, total):
    """``[(branch, start, length)]`` of the split pattern along a chain ``total`` long."""
    if total <= EPS or not pattern:
        return []
    items = _size_items(pattern, call.env)
    if call.repeat:
        items = [RepeatItem(items)]
    sections = resolve_split(items, total)
    if len(sections) > MAX_SECTIONS:
        raise CGARuntimeError(f"{_NAME}: the pattern makes {len(sections)} sections (more than "
                              f"{MAX_SECTIONS}); use longer section lengths")
    return sections


def _depth(call, branch) -> float:
    depth = to_float(call.env.evaluate(branch.depth), f"{_NAME} depth")
    if not np.isfinite(depth) or depth < 0:
        raise CGARuntimeError(f"{_NAME}: section depth must be a number >= 0, got {depth}")
    return depth


class _Chain:
    """The selected edges in chain order: ``edges`` (indices), their ``lengths`` and where each
    starts along the chain (``starts``); ``selected`` marks them among all the face's edges."""

    def __init__(self, pe, edges):
        k = pe.k
        self.edges = np.asarray(edges, int)
        seg = np.roll(pe.xy, -1, axis=0) - pe.xy
        self.edge_len = np.linalg.norm(seg, axis=1)
        self.lengths = self.edge_len[self.edges]
        selected = np.zeros(k, bool)
        selected[self.edges] = True
        self.selected = selected
        self.starts = np.concatenate([[0.0], np.cumsum(self.lengths)])


def _chain(call, pe) -> _Chain:
    k = pe.k
    first = int(call.num(1, 0.0)) % k if len(call.args) > 1 else 0
    mask = np.ones(k, bool)
    if len(call.args) > 2:
        arg = call.args[2]
        if not isinstance(arg, np.ndarray) or arg.dtype.kind != "b":
            raise CGARuntimeError(f"{_NAME}: selectedEdgesMask must be a bool array with one "
                                  f"value per edge ({k}), e.g. [true, false, true, true]")
        given = arg.reshape(-1)[:k]
        mask = np.zeros(k, bool)
        mask[:len(given)] = given
    order = [(first + j) % k for j in range(k)]
    return _Chain(pe, [i for i in order if mask[i]])


def _section_band(pe, chain, start, width, depth):
    """Union of the strips (shapely) a section lays along its part of the chain, or None."""
    import shapely

    if depth <= EPS or width <= EPS:
        return None
    total = chain.starts[-1]
    intervals = [(start, min(start + width, total))]
    if start + width > total + EPS:                       # runs over the chain's start
        intervals.append((0.0, start + width - total))
    strips = []
    for a, b in intervals:
        for j, e in enumerate(chain.edges):
            lo, hi = max(a, chain.starts[j]), min(b, chain.starts[j + 1])
            if hi - lo > EPS:
                strips.append(_strip(pe, chain, int(e), lo - chain.starts[j],
                                     hi - chain.starts[j], depth))
    strips = [s for s in strips if s is not None and not s.is_empty]
    return shapely.union_all(strips) if strips else None


def _strip(pe, chain, i, t0, t1, depth):
    """Band of ``depth`` inside edge ``i`` between ``t0`` and ``t1`` metres along it.

    An end inside the edge is square to it.  At a corner whose other edge is selected too, the
    band stays on this edge's side of the corner's bisector (an end at that corner follows the
    bisector); an end at a corner whose other edge is not selected runs on to the face's border
    at a convex corner and stays square at a concave one."""
    import shapely

    k = pe.k
    a, b = pe.xy[i], pe.xy[(i + 1) % k]
    length = chain.edge_len[i]
    if length <= EPS:
        return None
    t = (b - a) / length
    n = np.array([-t[1], t[0]])                           # inward for a counter-clockwise face
    big = 4.0 * (float(np.ptp(pe.xy, axis=0).max()) + depth) + 1.0
    clips, ext = [], [0.0, 0.0]
    for end, (vertex, other, at_vertex) in enumerate((((i, (i - 1) % k, t0 <= EPS)),
                                                      ((i + 1) % k, (i + 1) % k,
                                                       t1 >= length - EPS))):
        prev_t = _unit(pe.xy[vertex] - pe.xy[(vertex - 1) % k])
        next_t = _unit(pe.xy[(vertex + 1) % k] - pe.xy[vertex])
        if chain.selected[other]:
            clips.append(_bisector_side(pe.xy[vertex], prev_t, next_t, t if end == 0 else -t, big))
        convex = prev_t[0] * next_t[1] - prev_t[1] * next_t[0] > EPS
        if at_vertex and (chain.selected[other] or convex):
            ext[end] = big
    p0 = a + t * (t0 - ext[0])
    p1 = a + t * (t1 + ext[1])
    strip = shapely.Polygon([p0, p1, p1 + n * depth, p0 + n * depth])
    for half in clips:
        if half is not None:
            strip = strip.intersection(half)
    return strip


def _unit(v):
    length = np.linalg.norm(v)
    return v / length if length > EPS else v * 0.0


def _bisector_side(v, prev_t, next_t, toward, big):
    """The half-plane bounded by the bisector of the corner at ``v`` (edges coming in along
    ``prev_t``, leaving along ``next_t``) on the side ``toward`` points to."""
    import shapely

    inward = np.array([-prev_t[1], prev_t[0]]) + np.array([-next_t[1], next_t[0]])
    if np.linalg.norm(inward) <= EPS:                    # a spike: no corner to divide
        return None
    d = _unit(inward)
    m = np.array([-d[1], d[0]])
    side = m @ toward
    if abs(side) <= EPS:
        return None
    m = m if side > 0 else -m
    return shapely.Polygon([v - d * big, v + d * big, v + d * big + m * big, v - d * big + m * big])
