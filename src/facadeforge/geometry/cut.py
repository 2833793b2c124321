"""Cutting meshes by axis-aligned planes: the geometry behind CGA ``split``.

Faces are clipped against slabs of the scope frame.  A closed mesh (an extruded mass) stays closed:
each cut is capped with the cross-section polygons, found by polygonising the cut segments and
keeping the regions inside the solid by the even-odd rule.
"""

from __future__ import annotations

import numpy as np

from .mesh import EPS, Mesh, cross3, plane_basis, polygon_normal
from .polygon import ring_points, simple_pieces

_OTHER = {0: (1, 2), 1: (2, 0), 2: (0, 1)}  # right-handed (u, v) for the cap plane of each axis


def split_along_axis(mesh: Mesh, axis: int, cuts: np.ndarray, cap: bool | None = None,
                     tick=None) -> list[Mesh]:
    """Cut a mesh given in scope coordinates into slabs along one axis.

    Parameters
    ----------
    mesh : Mesh
        Geometry in the scope frame (so the axis is 0, 1 or 2 of the coordinates).
    axis : int
        0, 1, 2 for x, y, z.
    cuts : (n + 1,) float
        Increasing slab boundaries; slab ``i`` is ``cuts[i] <= coord <= cuts[i+1]``.
    cap : bool or None
        Close the cut faces of a closed mesh.  ``None`` decides by ``mesh.is_closed()``.
    tick : callable, optional
        Called once a slab; it raises to stop (a derivation's time and memory budget: a
        closed mass cut into 50,000 slabs takes minutes).

    Returns
    -------
    list of Mesh
        One (possibly empty) mesh per slab, in the scope frame.  A cut face keeps its face data
        (tags, material); cap faces have none (CityEngine, "Tag propagation").
    """
    cuts = np.asarray(cuts, float)
    n = len(cuts) - 1
    if n <= 0 or mesh.is_empty:
        return [Mesh() for _ in range(max(n, 0))]
    if mesh.n_faces == 1:
        fast = _split_single_face(mesh, axis, cuts, tick)
        if fast is not None:
            return fast
    if cap is None:
        cap = mesh.is_closed()
    coord = mesh.vertices[:, axis]
    fmin = np.minimum.reduceat(coord[mesh.corners], mesh.starts[:-1])
    fmax = np.maximum.reduceat(coord[mesh.corners], mesh.starts[:-1])
    normals = mesh.face_normals()
    convex = _convex_faces(mesh, normals)
    # faces lying in a cut plane (normal along the axis) go to exactly one slab: the one above
    # the plane for faces pointing down the axis and below for those pointing up
    out = []
    for i in range(n):
        if tick is not None:
            tick()
        lo, hi = cuts[i], cuts[i + 1]
        if hi - lo <= EPS:
            out.append(Mesh())
            continue
        inside = (fmin >= lo - EPS) & (fmax <= hi + EPS)
        flat = inside & (fmax - fmin <= EPS)
        if flat.any():
            at_lo = flat & (np.abs(fmin - lo) <= EPS)
            at_hi = flat & (np.abs(fmax - hi) <= EPS)
            # a face in the plane at lo belongs here only if it faces down (it is this slab's floor)
            inside &= ~(at_lo & (normals[:, axis] > 0) & (i > 0))
            inside &= ~(at_hi & (normals[:, axis] < 0) & (i < n - 1))
        crossing = np.flatnonzero((fmin < hi - EPS) & (fmax > lo + EPS) & ~inside)
        parts = [mesh.subset(np.flatnonzero(inside))] if inside.any() else []
        polys, uvs, source = [], [], []
        for f in crossing:
            idx = mesh.face(f)
            p = mesh.vertices[idx]
            uv = None if mesh.corner_uvs is None else mesh.corner_uvs[mesh.starts[f]:mesh.starts[f + 1]]
            for q, quv in _clip_slab(p, uv, axis, lo, hi, normals[f], convex[f]):
                polys.append(q)
                uvs.append(quv)
                source.append(f)
        if polys:
            parts.append(Mesh.from_polygons(polys, uvs if mesh.corner_uvs is not None else None)
                         .inherit(mesh, source))
        if cap:
            for c, sign in ((lo, -1.0), (hi, 1.0)):
                if (sign < 0 and i == 0 and lo <= coord.min() + EPS) or (
                        sign > 0 and i == n - 1 and hi >= coord.max() - EPS):
                    continue
                caps = cross_section(mesh, axis, c, fmin, fmax)
                if caps:
                    parts.append(_cap_mesh(caps, axis, c, sign, mesh.corner_uvs is not None))
        out.append(Mesh.merge(parts))
    return out


def _split_single_face(mesh: Mesh, axis: int, cuts: np.ndarray, tick=None) -> list[Mesh] | None:
    """Fast path for the commonest split: one convex planar face (a facade, a floor, a tile).

    Sweeps the polygon once, peeling off one slab per cut with plain-float Sutherland–Hodgman
    (numpy's per-call overhead dominates on 4-vertex polygons).  Returns ``None`` for a
    non-convex face, which takes the general path.
    """
    p = mesh.vertices[mesh.corners]
    uv = mesh.corner_uvs
    if len(p) > 4 and not _convex_faces(mesh, mesh.face_normals())[0]:
        return None
    pts = p.tolist()
    if len(pts) == 4 and not _convex_quad(pts):
        return None
    if mesh.corner_data is None:
        slabs = _slabs_of_prism(p, uv, axis, cuts, mesh.face_data)
        if slabs is not None:
            return slabs
    uvs = uv.tolist() if uv is not None else None
    # edge and vertex data (tags) follow the clipping exactly when the face has any
    labels = [(c, c) for c in range(len(pts))] if mesh.corner_data is not None else None
    lo = float(cuts[0])
    pts, uvs, *rest = _clip_py(pts, uvs, axis, lo, False, labels)
    labels = rest[0] if rest else None
    out: list[Mesh] = []
    for k, c in enumerate(cuts[1:]):
        if tick is not None and not k & 1023:
            tick()
        c = float(c)
        if len(pts) < 3:
            out.append(Mesh())
            continue
        below, buv, *blab = _clip_py(pts, uvs, axis, c, True, labels)
        pts, uvs, *rest = _clip_py(pts, uvs, axis, c, False, labels)
        labels = rest[0] if rest else None
        if len(below) >= 3:
            piece = Mesh(np.array(below), corners=np.arange(len(below)),
                         starts=np.array([0, len(below)]),
                         corner_uvs=None if buv is None else np.array(buv), closed=False,
                         face_data=mesh.face_data)
            if blab:
                piece = piece.inherit(mesh, [0], corner_source=np.array(blab[0]).T)
            out.append(piece)
        else:
            out.append(Mesh())
    return out


def _slabs_of_prism(p: np.ndarray, uv, axis: int, cuts: np.ndarray, face_data):
    """All slabs of a convex face at once, when its corners lie on the two planes that bound
    it along the axis (a facade, a floor, a tile in its scope frame) and every inner cut falls
    strictly between them.  Each slab's corners are then a fixed pattern — the face's corners
    on a bounding plane, or points of its edges at the slab's cuts — in the order
    :func:`_clip_py` gives them; the pattern is found once by clipping marks, and the points
    of every slab computed together.  ``None`` for any other face or cuts."""
    coord = p[:, axis]
    lo, hi = float(coord.min()), float(coord.max())
    at_lo = coord <= lo + EPS
    n = len(cuts) - 1
    if n < 2 or not (at_lo | (coord >= hi - EPS)).all() or hi - lo <= 4 * EPS \
            or cuts[0] > lo + EPS or cuts[-1] < hi - EPS or cuts[1] <= lo + EPS \
            or cuts[-2] >= hi - EPS or (np.diff(cuts[1:-1]) <= EPS).any():
        return None
    # a mark: (lo corner, hi corner, cut) is the point of that edge at a cut (1, 2, 3: three
    # cuts in a row), (corner, corner, 0) one of the face's own corners
    marks = [(j, j, 0) for j in range(len(p))]

    def below(m, cut: int) -> bool:
        return bool(at_lo[m[0]]) if m[2] == 0 else m[2] < cut

    def clip(poly, keep_below: bool, cut: int):  # _clip_py on marks
        out = []
        for j, m in enumerate(poly):
            mn = poly[(j + 1) % len(poly)]
            if below(m, cut) == keep_below:
                out.append(m)
            if below(m, cut) != below(mn, cut):  # the segment lies on one edge lo → hi
                a, b = (m[0], m[1]) if m[2] else (mn[0], mn[1]) if mn[2] else (m[0], mn[0])
                out.append((a, b, cut) if at_lo[a] else (b, a, cut))
        return out
    first, rest = clip(marks, True, 1), clip(marks, False, 1)
    middle, rest = clip(rest, True, 2), clip(rest, False, 2)
    later, rest = clip(rest, True, 3), clip(rest, False, 3)
    # the slabs between cuts repeat one pattern (checked on two of them), the last is the rest
    if min(len(first), len(middle), len(rest)) < 3 or len(middle) != len(later) or any(
            (a, b, c - 1) != (d, e, f - 2) for (a, b, c), (d, e, f) in zip(middle, later)):
        return None
    lower = np.asarray(cuts[:-1], float)
    upper = np.asarray(cuts[1:], float)

    def slabs(pattern, base: int, rows: slice):
        """Corners (and UVs) of the slabs ``rows`` of one pattern: cut ``base`` is a slab's
        lower cut, ``base + 1`` its upper."""
        ea = np.array([a for a, _, _ in pattern])
        eb = np.array([b for _, b, _ in pattern])
        cut = np.array([c for _, _, c in pattern])
        own = cut == 0
        value = np.where(cut == base, lower[rows, None], upper[rows, None])  # (m, k)
        pa, pb = p[ea], p[eb]
        span = np.where(own, 1.0, pb[:, axis] - pa[:, axis])
        t = np.where(own, 0.0, (value - pa[:, axis]) / span)
        v = pa + t[..., None] * (pb - pa)
        v[..., axis] = np.where(own, pa[:, axis], value)
        w = None if uv is None else uv[ea] + t[..., None] * (uv[eb] - uv[ea])
        return v, w
    parts = [slabs(first, 0, slice(0, 1))]
    if n > 2:
        parts.append(slabs(middle, 1, slice(1, n - 1)))
    parts.append(slabs(rest, 3, slice(n - 1, n)))
    out: list[Mesh] = []
    for v, w in parts:
        for i in range(len(v)):
            m = v.shape[1]
            out.append(Mesh(v[i], corners=np.arange(m), starts=np.array([0, m]),
                            corner_uvs=None if w is None else w[i], closed=False,
                            face_data=face_data))
    return out


def _convex_quad(q) -> bool:
    """Whether a planar quad (4 lists of xyz) turns the same way at every corner."""
    e = [[q[(i + 1) % 4][k] - q[i][k] for k in range(3)] for i in range(4)]
    turns = []
    for i in range(4):
        a, b = e[i], e[(i + 1) % 4]
        turns.append((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))
    n = [turns[0][k] + turns[2][k] for k in range(3)]
    return all(t[0] * n[0] + t[1] * n[1] + t[2] * n[2] >= -EPS for t in turns)


def _clip_py(pts, uvs, axis, value, keep_below, labels=None):
    """Sutherland–Hodgman on Python lists: keep ``coord <= value`` (or ``>=``).

    ``labels`` (optional, one ``(vertex, edge)`` pair per point: the parent corner the point
    is, and the parent corner whose edge runs from it to the next point; -1 for none) are
    carried along and returned third: a point kept keeps its vertex, a cut point has none; an
    edge kept or shortened keeps its parent edge, an edge along the cut has none."""
    k = len(pts)
    if k == 0:
        return (pts, uvs) if labels is None else (pts, uvs, labels)
    sign = 1.0 if keep_below else -1.0
    d = [(q[axis] - value) * sign for q in pts]
    if max(d) <= EPS:
        return (pts, uvs) if labels is None else (pts, uvs, labels)
    if min(d) > EPS:
        empty = (None if uvs is None else [])
        return ([], empty) if labels is None else ([], empty, [])
    out, out_uv = [], ([] if uvs is not None else None)
    out_lab = [] if labels is not None else None
    for j in range(k):
        jn = j + 1 if j + 1 < k else 0
        da, db = d[j], d[jn]
        a = pts[j]
        if da <= EPS:
            out.append(a if abs(da) > EPS else _snap(a, axis, value))
            if uvs is not None:
                out_uv.append(uvs[j])
            if labels is not None:  # on to b, or to the cut point on this edge: the same edge
                vid, eid = labels[j]
                out_lab.append((vid, eid if db <= EPS or da < -EPS else -1))
        if (da < -EPS and db > EPS) or (da > EPS and db < -EPS):
            t = da / (da - db)
            b = pts[jn]
            q = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])]
            q[axis] = value
            out.append(q)
            if uvs is not None:
                ua, ub = uvs[j], uvs[jn]
                out_uv.append([ua[0] + t * (ub[0] - ua[0]), ua[1] + t * (ub[1] - ua[1])])
            if labels is not None:  # leaving: the cut runs on; entering: this edge runs on
                out_lab.append((-1, -1 if da < -EPS else labels[j][1]))
    return (out, out_uv) if labels is None else (out, out_uv, out_lab)


def _snap(a, axis, value):
    q = list(a)
    q[axis] = value
    return q


def _convex_faces(mesh: Mesh, normals: np.ndarray) -> np.ndarray:
    if not mesh.n_faces:
        return np.zeros(0, bool)
    p = mesh.vertices[mesh.corners]
    nxt = np.arange(1, len(mesh.corners) + 1)
    nxt[mesh.starts[1:] - 1] = mesh.starts[:-1]
    e = p[nxt] - p
    turn = np.einsum("ij,ij->i", cross3(e, e[nxt]),
                     np.repeat(normals, mesh.face_sizes, axis=0))
    return np.minimum.reduceat(turn, mesh.starts[:-1]) >= -1e-12


def _clip_halfspace(p, uv, axis, value, keep_below):
    """Sutherland–Hodgman clip of one polygon to ``coord <= value`` (or ``>=``)."""
    d = p[:, axis] - value
    if not keep_below:
        d = -d
    out_p, out_uv = [], []
    k = len(p)
    for j in range(k):
        a, b = j, (j + 1) % k
        da, db = d[a], d[b]
        if da <= EPS:
            out_p.append(p[a])
            if uv is not None:
                out_uv.append(uv[a])
        if (da < -EPS and db > EPS) or (da > EPS and db < -EPS):
            t = da / (da - db)
            out_p.append(p[a] + t * (p[b] - p[a]))
            if uv is not None:
                out_uv.append(uv[a] + t * (uv[b] - uv[a]))
    if len(out_p) < 3:
        return None, None
    q = np.array(out_p)
    q[:, axis] = np.where(np.abs(q[:, axis] - value) <= EPS, value, q[:, axis])
    return q, (np.array(out_uv) if uv is not None else None)


def clip_convex_faces(p, uv, starts, axis: int, value: float, keep_below: bool):
    """:func:`_clip_halfspace` of many convex polygons at once: ``p`` (C, 3) their corners one
    polygon after the other, ``uv`` (C, 2) or ``None``, ``starts`` (F + 1,) where each begins.
    Each corner puts down itself if kept, then the point where its edge to the next corner
    crosses the plane, as the loop does.  Returns the points, their UVs, the offsets of the
    polygons left (at least three points) and which input polygon each is."""
    d = p[:, axis] - value
    if not keep_below:
        d = -d
    nxt = np.arange(1, len(p) + 1)
    nxt[starts[1:] - 1] = starts[:-1]
    db = d[nxt]
    keep = d <= EPS
    cross = ((d < -EPS) & (db > EPS)) | ((d > EPS) & (db < -EPS))
    t = np.where(cross, d / np.where(cross, d - db, 1.0), 0.0)[:, None]
    emit = np.column_stack([keep, cross]).ravel()
    q = np.stack([p, p + t * (p[nxt] - p)], axis=1).reshape(-1, 3)[emit]
    quv = None if uv is None else np.stack([uv, uv + t * (uv[nxt] - uv)],
                                           axis=1).reshape(-1, 2)[emit]
    counts = np.add.reduceat(keep.astype(np.int64) + cross, starts[:-1])
    ok = counts >= 3
    if not ok.all():
        rows = np.repeat(ok, counts)
        q = q[rows]
        quv = None if quv is None else quv[rows]
        counts = counts[ok]
    q[:, axis] = np.where(np.abs(q[:, axis] - value) <= EPS, value, q[:, axis])
    return q, quv, np.concatenate([[0], np.cumsum(counts)]), np.flatnonzero(ok)


def _clip_slab(p, uv, axis, lo, hi, normal, convex):
    """Pieces of polygon ``p`` inside ``lo <= coord <= hi`` as a list of (poly, uv)."""
    if convex:
        q, quv = _clip_halfspace(p, uv, axis, hi, True)
        if q is None:
            return []
        q, quv = _clip_halfspace(q, quv, axis, lo, False)
        return [] if q is None else [(q, quv)]
    return _clip_slab_shapely(p, uv, axis, lo, hi, normal)


def _clip_slab_shapely(p, uv, axis, lo, hi, normal):
    """Exact clip of a non-convex planar polygon (may fall apart into several pieces)."""
    import shapely

    basis = plane_basis(normal)
    origin = p[0]
    xy = (p - origin) @ basis[:, :2]
    poly = shapely.Polygon(xy).buffer(0)
    # the slab as a polygon in the face plane: a big box clipped by two lines
    d = basis[axis, :2]  # how the axis coordinate changes along u and v
    c0 = origin[axis]
    big = 1e3 * (1 + np.abs(xy).max())
    box = shapely.box(-big, -big, big, big)
    if abs(d[0]) + abs(d[1]) < EPS:
        return [(p, uv)] if lo - EPS <= c0 <= hi + EPS else []
    halfplanes = _halfplane(d, lo - c0, big, below=False).intersection(
        _halfplane(d, hi - c0, big, below=True))
    region = poly.intersection(halfplanes.intersection(box))
    pieces = []
    geoms = getattr(region, "geoms", [region])
    affine = None
    if uv is not None:
        a = np.column_stack([xy, np.ones(len(xy))])
        affine, *_ = np.linalg.lstsq(a, uv, rcond=None)
    for g in geoms:
        if g.geom_type != "Polygon" or g.area <= EPS:
            continue
        for ring in simple_pieces(g):
            q = origin + ring @ basis[:, :2].T
            quv = None if affine is None else np.column_stack([ring, np.ones(len(ring))]) @ affine
            pieces.append((q, quv))
    return pieces


def _halfplane(d, value, big, below):
    """Polygon of points (u, v) with ``d·(u, v) <= value`` (or ``>=``), clipped to a big box."""
    import shapely

    n = np.asarray(d, float)
    n = n / (n @ n)
    p0 = n * value
    t = np.array([-n[1], n[0]])
    t = t / np.linalg.norm(t) * big * 4
    out = -n / np.linalg.norm(n) * big * 4 if below else n / np.linalg.norm(n) * big * 4
    return shapely.Polygon([p0 - t, p0 + t, p0 + t + out, p0 - t + out])


def cross_section(mesh: Mesh, axis: int, value: float, fmin=None, fmax=None) -> list:
    """Regions of a closed mesh's cross-section with the plane ``coord[axis] == value``.

    Returns a list of shapely Polygons in the plane's (u, v) coordinates, ``_OTHER[axis]``.
    """
    import shapely
    from shapely.ops import polygonize

    coord = mesh.vertices[:, axis]
    if fmin is None:
        fmin = np.minimum.reduceat(coord[mesh.corners], mesh.starts[:-1])
        fmax = np.maximum.reduceat(coord[mesh.corners], mesh.starts[:-1])
    u, v = _OTHER[axis]
    segs = []
    for f in np.flatnonzero((fmin < value - EPS) & (fmax > value + EPS)):
        p = mesh.vertices[mesh.face(f)]
        d = p[:, axis] - value
        pts = []
        k = len(p)
        for j in range(k):
            a, b = j, (j + 1) % k
            if abs(d[a]) <= EPS:
                pts.append(p[a])
            elif (d[a] < -EPS and d[b] > EPS) or (d[a] > EPS and d[b] < -EPS):
                t = d[a] / (d[a] - d[b])
                pts.append(p[a] + t * (p[b] - p[a]))
        pts2 = [(q[u], q[v]) for q in pts]
        # a convex face meets the plane in one segment; a non-convex one in several, pairwise
        pts2 = sorted(set((round(a, 9), round(b, 9)) for a, b in pts2))
        for j in range(0, len(pts2) - 1, 2):
            segs.append(shapely.LineString([pts2[j], pts2[j + 1]]))
    if not segs:
        return []
    merged = shapely.unary_union(segs)
    faces = list(polygonize(merged))
    if not faces:
        return []
    seg_arr = np.array([np.asarray(s.coords) for s in segs])  # (S, 2, 2)
    keep = []
    for g in faces:
        pt = np.asarray(g.representative_point().coords[0])
        if _inside_even_odd(pt, seg_arr):
            keep.append(g)
    return keep


def _inside_even_odd(pt, segs):
    a, b = segs[:, 0], segs[:, 1]
    cond = (a[:, 1] > pt[1]) != (b[:, 1] > pt[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[:, 0] + (pt[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return int(np.count_nonzero(cond & (x > pt[0]))) % 2 == 1


def _cap_mesh(polys, axis, value, sign, with_uv) -> Mesh:
    """Cap faces from cross-section polygons; normal along ``sign`` × axis."""
    import mapbox_earcut as earcut

    u, v = _OTHER[axis]
    out = []
    for g in polys:
        rings = [ring_points(g.exterior)] + [ring_points(r) for r in g.interiors]
        if len(rings) == 1:
            ring = rings[0]
            if (shapely_ccw(ring)) != (sign > 0):
                ring = ring[::-1]
            out.append(_lift(ring, axis, value, u, v))
            continue
        flat = np.concatenate(rings)
        ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
        tri = np.asarray(earcut.triangulate_float64(flat, ends), np.int64).reshape(-1, 3)
        pts3 = _lift(flat, axis, value, u, v)
        for t in tri:
            q = pts3[t]
            if (polygon_normal(q)[axis] > 0) != (sign > 0):
                q = q[::-1]
            out.append(q)
    mesh = Mesh.from_polygons(out, [np.zeros((len(q), 2)) for q in out] if with_uv else None)
    return mesh


def shapely_ccw(ring: np.ndarray) -> bool:
    x, y = ring[:, 0], ring[:, 1]
    return float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) > 0


def _lift(ring2, axis, value, u, v):
    q = np.zeros((len(ring2), 3))
    q[:, axis] = value
    q[:, u] = ring2[:, 0]
    q[:, v] = ring2[:, 1]
    return q
