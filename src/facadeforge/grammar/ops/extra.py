"""Less common CityEngine operations: ``innerRectangle``, ``roofRidge``, ``splitArea``."""

from __future__ import annotations

import math

import numpy as np

from ...geometry.cut import split_along_axis
from ...geometry.holed import HOLED
from ...geometry.mesh import EPS, Mesh, cross3, polygon_normal
from ...geometry.polygon import simple_pieces
from ...model.scope import Scope
from ..values import CGARuntimeError
from . import operation
from .roofs import _roof
from .subdivision import _AXES, OFFSET_COLUMNS, _selector_key, call_pieces
from .tagging import without_tags

# ---- innerRectangle -------------------------------------------------------------------------

_FINE = 64  # uniform grid lines along each axis for faces with slanted edges
_REFINE = 24  # extra lines around each side of the rectangle found on that grid


def _in_plane(axis: np.ndarray, normal: np.ndarray) -> np.ndarray | None:
    """``axis`` projected onto the plane with ``normal``, normalised; None if degenerate."""
    a = axis - normal * (axis @ normal)
    n = np.linalg.norm(a)
    return a / n if n > 1e-6 else None


def _grid_lines(values, lo, hi, tol, fine):
    """Sorted grid lines through ``values`` (and ``fine`` + 1 uniform lines over [lo, hi]),
    lines closer than ``tol`` merged."""
    g = np.sort(np.concatenate([values, np.linspace(lo, hi, fine + 1)]) if fine else values)
    keep = np.concatenate([[True], np.diff(g) > tol])
    return g[keep]


def _max_rect(inside, gx, gy, centre):
    """Largest block of True cells of the grid with lines gx (columns) and gy (rows), by
    area in metres; ties go to the block whose centre is nearest ``centre``.
    Row-by-row maximal-rectangle recurrence (height, left, right), vectorised along the row."""
    ny, nx = inside.shape
    cols = np.arange(nx)
    height = np.zeros(nx)
    start = np.zeros(nx, np.int64)  # first row of the run ending at the current row
    left = np.zeros(nx, np.int64)
    right = np.full(nx, nx, np.int64)
    best, best_d, best_rect = 0.0, math.inf, None
    tol = 1e-9 * (gx[-1] - gx[0]) * (gy[-1] - gy[0])
    for r in range(ny):
        row = inside[r]
        if not row.any():
            height[:] = 0.0
            left[:] = 0
            right[:] = nx
            continue
        dy = gy[r + 1] - gy[r]
        start = np.where(row & (height > 0), start, r)
        height = np.where(row, height + dy, 0.0)
        cur_left = np.maximum.accumulate(np.where(row, 0, cols + 1))
        left = np.where(row, np.maximum(left, cur_left), 0)
        cur_right = np.minimum.accumulate(np.where(row, nx, cols)[::-1])[::-1]
        right = np.where(row, np.minimum(right, cur_right), nx)
        area = np.where(row, height * (gx[right] - gx[left]), 0.0)
        top = area.max()
        if top < best - tol:
            continue
        cand = np.flatnonzero(area >= max(best, top) - tol)
        d = (0.5 * (gx[left[cand]] + gx[right[cand]]) - centre[0]) ** 2 + \
            (0.5 * (gy[start[cand]] + gy[r + 1]) - centre[1]) ** 2
        k = int(np.argmin(d))
        if top > best + tol or d[k] < best_d:
            c = cand[k]
            best, best_d, best_rect = max(best, top), d[k], (left[c], start[c], right[c], r + 1)
    return best_rect


def _covered_cells(poly, xy, gx, gy, tol):
    """``[row, col]``: whether the cell of the grid (rows ``gy``, columns ``gx``) lies inside
    the polygon: its centre is inside and no slanted edge crosses it (edges along grid lines
    only bound cells)."""
    import shapely

    cx, cy = 0.5 * (gx[:-1] + gx[1:]), 0.5 * (gy[:-1] + gy[1:])
    inside = shapely.contains_xy(poly, *np.meshgrid(cx, cy))
    a, b = xy, np.roll(xy, -1, axis=0)
    for (x0, y0), (x1, y1) in zip(a, b):
        if abs(x1 - x0) <= tol or abs(y1 - y0) <= tol:
            continue  # along a grid line: it bounds cells but crosses none
        if x0 > x1:
            x0, y0, x1, y1 = x1, y1, x0, y0
        c0 = max(np.searchsorted(gx, x0, side="right") - 1, 0)
        c1 = min(np.searchsorted(gx, x1, side="left"), len(gx) - 1)
        xs = np.clip(gx[c0:c1 + 1], x0, x1)
        ys = y0 + (xs - x0) * ((y1 - y0) / (x1 - x0))
        ylo, yhi = np.minimum(ys[:-1], ys[1:]), np.maximum(ys[:-1], ys[1:])
        crossed = (gy[1:][None, :] > ylo[:, None] + tol) & (gy[:-1][None, :] < yhi[:, None] - tol)
        inside[:, c0:c1] &= ~crossed.T
    return inside


def _inner_rect_2d(xy: np.ndarray):
    """Largest rectangle aligned to the x/y axes inside the simple polygon ``xy`` (k, 2).

    The grid's lines are the polygon's vertex coordinates, so for a rectilinear polygon every
    cell is wholly inside or outside and the largest block of inside cells is the exact answer.
    With slanted edges, 64 uniform lines per axis are added (cells a slanted edge crosses do not
    count), the search is repeated with 24 more lines around each side of the block found, and
    each side is then pushed outwards by bisection as far as the rectangle stays covered
    (containment is monotone in each side), so the sides end on the polygon's edges.
    Returns ``(x0, y0, x1, y1)`` or None.
    """
    import shapely

    poly = shapely.Polygon(xy).buffer(0)
    if poly.is_empty or poly.area <= EPS:
        return None
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    ext = hi - lo
    tol = 1e-9 * max(ext)
    e = np.roll(xy, -1, axis=0) - xy
    slanted = bool(((np.abs(e[:, 0]) > tol) & (np.abs(e[:, 1]) > tol)).any())
    fine = _FINE if slanted else 0
    gx = _grid_lines(xy[:, 0], lo[0], hi[0], tol, fine)
    gy = _grid_lines(xy[:, 1], lo[1], hi[1], tol, fine)
    inside = _covered_cells(poly, xy, gx, gy, tol)
    c = np.asarray(poly.centroid.coords[0])
    rect = _max_rect(inside, gx, gy, c)
    if rect is None:
        return None
    r = [gx[rect[0]], gy[rect[1]], gx[rect[2]], gy[rect[3]]]
    if not slanted:  # the grid is the polygon's own: the block is the answer
        return tuple(float(v) for v in r)
    h = 1.5 * ext / _FINE
    gx, gy = (_grid_lines(np.concatenate(
        [g, np.linspace(r[k] - h[k], r[k] + h[k], _REFINE),
         np.linspace(r[k + 2] - h[k], r[k + 2] + h[k], _REFINE)]).clip(lo[k], hi[k]),
        lo[k], hi[k], tol, 0) for k, g in ((0, gx), (1, gy)))
    inside = _covered_cells(poly, xy, gx, gy, tol)
    rect = _max_rect(inside, gx, gy, c)  # the finer grid holds the first: a block is found
    r = [gx[rect[0]], gy[rect[1]], gx[rect[2]], gy[rect[3]]]
    limits = [lo[0], lo[1], hi[0], hi[1]]
    test = poly.buffer(tol)
    shapely.prepare(test)

    def fits(q):
        return q[2] - q[0] > 0 and q[3] - q[1] > 0 and test.covers(shapely.box(*q))

    for _ in range(2):
        for side in range(4):
            good, bad = r[side], limits[side]
            trial = list(r)
            trial[side] = bad
            if fits(trial):
                r[side] = bad
                continue
            for _ in range(48):
                mid = 0.5 * (good + bad)
                trial[side] = mid
                if fits(trial):
                    good = mid
                else:
                    bad = mid
                if abs(bad - good) <= tol:
                    break
            r[side] = good
    # snap to polygon vertex coordinates within the tolerance (clean remainder, no slivers)
    for k in range(4):
        coords = xy[:, k % 2]
        j = np.argmin(np.abs(coords - r[k]))
        if abs(coords[j] - r[k]) <= 10 * tol:
            r[k] = float(coords[j])
    return tuple(float(v) for v in r)


@operation("innerRectangle", 1, 1, selectors=(0,), body=True)
def op_inner_rectangle(call):
    """``innerRectangle(scope|edge){ shape : A | remainder : B }`` (CityEngine 2018.1 semantics).

    Per face, the largest inscribed rectangle: with ``scope`` its sides follow the shape's scope
    x axis projected into the face plane (scope z where x is normal to the face); with ``edge``
    it is aligned to the face edge, among those at least a quarter as long as the longest one,
    that gives the largest rectangle.  Ties go to the rectangle closest to the face centroid.
    ``shape`` receives the rectangles, ``remainder`` the rest of the faces (face minus
    rectangle); the scope orientation is kept and fitted to the new geometry.  The rectangle is
    found on a grid through the face's vertex coordinates (exact for rectilinear faces; finer
    grids and a push to the edges otherwise, see :func:`_inner_rect_2d`).
    """
    import shapely

    mode = call.sel(0)
    if mode not in ("scope", "edge"):
        raise CGARuntimeError(f"innerRectangle: the alignment is scope or edge, not '{mode}'")
    st = call.state
    mesh = st.geometry
    rects, rests, rect_src, rest_src = [], [], [], []
    rot = st.scope.rotation
    for f, poly in enumerate(mesh.polygons()):
        n = polygon_normal(poly)
        if not n.any():
            continue
        n = n / np.linalg.norm(n)
        axes = []
        if mode == "scope":
            u = _in_plane(rot[:, 0], n)
            if u is None:
                u = _in_plane(rot[:, 2], n)
            axes = [u] if u is not None else []
        else:
            e = np.roll(poly, -1, axis=0) - poly
            ln = np.linalg.norm(e, axis=1)
            for k in np.flatnonzero(ln >= 0.25 * ln.max()):
                u = _in_plane(e[k], n)
                if u is not None:
                    axes.append(u)
        best = None
        for u in axes:
            v = cross3(n, u)
            xy = (poly - poly[0]) @ np.column_stack([u, v])
            r = _inner_rect_2d(xy)
            if r is None:
                continue
            area = (r[2] - r[0]) * (r[3] - r[1])
            if best is None or area > best[0] + EPS:
                best = (area, r, u, v, xy)
        if best is None:
            continue
        _, (x0, y0, x1, y1), u, v, xy = best

        def lift(ring2, u=u, v=v, p0=poly[0]):
            return p0 + np.outer(ring2[:, 0], u) + np.outer(ring2[:, 1], v)

        rects.append(lift(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])))
        rect_src.append(f)
        face = shapely.Polygon(xy).buffer(0)
        rest = face.difference(shapely.box(x0, y0, x1, y1))
        for g in getattr(rest, "geoms", [rest]):
            if g.geom_type == "Polygon" and g.area > 1e-9 * max(face.area, 1.0):
                pieces = [lift(ring) for ring in simple_pieces(g)]
                rests.extend(pieces)
                rest_src.extend([f] * len(pieces))
    out = []
    for branch in call.branches:
        key = _selector_key(call, branch)
        if key not in ("shape", "remainder"):
            raise CGARuntimeError(f"innerRectangle selectors are shape and remainder, not '{key}'")
        faces, source = (rects, rect_src) if key == "shape" else (rests, rest_src)
        if not faces:
            continue
        ps = st.child(len(out))
        ps.geometry = Mesh.from_polygons(faces).inherit(mesh, source, drop=("kind", HOLED))
        ps.fit_scope()
        out.append((ps, branch.ops, {"sel": key}))
    return out


# ---- roofRidge ------------------------------------------------------------------------------

def _ridge_faces(xy: np.ndarray, d: np.ndarray, mode: str, value: float) -> list[np.ndarray]:
    """Tent roof over the CCW polygon ``xy`` with a horizontal ridge along unit direction ``d``.

    The ridge runs through the middle of the polygon's extent across ``d``; two roof planes rise
    from the extreme lines of that extent (the long sides of a rectangle) at ``value`` degrees
    (``byAngle``) or to a ridge of height ``value`` (``byHeight``); vertical walls (gables) close
    the volume along every edge that is not at zero height.  Faces are (k, 3) (x, y, height).
    """
    import shapely

    m = np.array([-d[1], d[0]])
    s = xy @ m
    smin, smax = float(s.min()), float(s.max())
    half = 0.5 * (smax - smin)
    if half <= EPS:
        raise ValueError("the face has no width across the ridge")
    mid = smin + half
    height = half * math.tan(math.radians(value)) if mode == "byAngle" else value

    def z(p):
        return height * (1.0 - np.abs(p @ m - mid) / half)

    faces = []
    poly = shapely.Polygon(xy).buffer(0)
    big = 10.0 * (float(np.ptp(xy, axis=0).max()) + 1.0)
    c = xy.mean(axis=0)
    for lo_s, hi_s in ((smin - 1.0, mid), (mid, smax + 1.0)):
        a = c - d * big
        b = c + d * big
        slab = shapely.Polygon([a + m * (lo_s - a @ m), b + m * (lo_s - b @ m),
                                b + m * (hi_s - b @ m), a + m * (hi_s - a @ m)])
        part = poly.intersection(slab)
        for g in getattr(part, "geoms", [part]):
            if g.geom_type != "Polygon" or g.area <= EPS:
                continue
            for ring in simple_pieces(g):
                faces.append(np.column_stack([ring, z(ring)]))
    zero = 1e-9 * max(height, 1.0)
    k = len(xy)
    for i in range(k):
        a, b = xy[i], xy[(i + 1) % k]
        sa, sb = a @ m - mid, b @ m - mid
        tops = [a]
        if sa * sb < 0:
            tops.append(a + (b - a) * (sa / (sa - sb)))
        tops.append(b)
        zt = z(np.array(tops))
        if zt.max() <= zero:
            continue
        wall = [np.array([a[0], a[1], 0.0]), np.array([b[0], b[1], 0.0])]
        for p, h in reversed(list(zip(tops, zt))):
            if h > zero:
                wall.append(np.array([p[0], p[1], h]))
        faces.append(np.array(wall))
    return faces


@operation("roofRidge", 2, 2, selectors=(0,))
def op_roof_ridge(call):
    """``roofRidge(byAngle|byHeight, value)`` (CityEngine 2021.0): one ridge parallel to the
    scope's x axis projected on each face.

    Two roof planes rise from the two extreme lines of the face across x (the long sides of a
    rectangle whose x is its length), to the ridge at mid-width; vertical walls close the gables.
    Like the other roofs the result is a closed volume with the original face as bottom and the
    scope's y along the (first) face normal.  ``byHeight`` gives the ridge height directly.
    """
    mode = call.sel(0)
    if mode not in ("byAngle", "byHeight"):
        raise CGARuntimeError(f"roofRidge: the first argument is byAngle or byHeight, not '{mode}'")
    value = call.num(1)
    if mode == "byAngle" and not 0 < value < 90:
        raise CGARuntimeError(f"roofRidge: the roof angle must be between 0 and 90 degrees, not {value}")
    if mode == "byHeight" and value <= 0:
        raise CGARuntimeError(f"roofRidge: the ridge height must be positive, not {value}")
    rot = call.state.scope.rotation

    def build(xy, basis, n, holes):
        # the ridge runs along the scope's x projected into the face (its z when x is normal)
        u = _in_plane(rot[:, 0], n)
        if u is None:
            u = _in_plane(rot[:, 2], n)
        d = (u @ basis[:, :2]) if u is not None else np.array([1.0, 0.0])
        return _ridge_faces(xy, d / max(np.linalg.norm(d), EPS), mode, value)

    _roof(call, build)


# ---- splitArea ------------------------------------------------------------------------------

@operation("splitArea", 1, 1, selectors=(0,), body=True)
def op_split_area(call):
    """``splitArea(x|y|z){ area : A | ~area : B | 'r : C | … }``: a split whose sizes are areas.

    The pattern is resolved like ``split`` with the shape's surface area as the total (absolute
    areas as is, ``'r`` as a fraction of the area, ``~`` floating areas sharing the rest, repeat
    groups allowed); each area boundary is then turned into a cut position along the axis by
    bisection on the area of the geometry below the cut, and the shape is split there
    (scope adjusted to each piece).  Exact for planar faces; for volumes the area measured is the
    surface area without the cut caps.
    """
    axis_name = call.sel(0)
    axis = _AXES.get(axis_name)
    if axis is None:
        raise CGARuntimeError(f"splitArea axis must be x, y or z, not '{axis_name}'")
    st = call.state
    local = st.local_geometry()
    if not local.n_faces:
        return []
    coord = local.vertices[local.corners][:, axis]
    lo, hi = float(coord.min()), float(coord.max())
    total = local.area()
    pieces = call_pieces(call, total)
    if not pieces:
        return []

    def area_below(t):
        if t <= lo:
            return 0.0
        if t >= hi:
            return total
        return split_along_axis(local, axis, np.array([lo, t]), cap=False)[0].area()

    def position(a):
        if a <= EPS:
            return lo
        if a >= total - EPS:
            return hi
        p, q = lo, hi
        for _ in range(60):
            mid = 0.5 * (p + q)
            if area_below(mid) < a:
                p = mid
            else:
                q = mid
            if q - p <= 1e-10 * max(hi - lo, 1.0):
                break
        return 0.5 * (p + q)

    bounds = [pieces[0][1]] + [start + size for _, start, size in pieces]
    cuts = np.array([position(a) for a in bounds])
    cuts = np.maximum.accumulate(cuts)
    meshes = split_along_axis(local, axis, cuts, tick=call.tick)
    out = []
    n = len(pieces)
    for i, ((branch, _, _), mesh) in enumerate(zip(pieces, meshes)):
        if not mesh.n_faces:
            continue
        ps = st.child(i)
        ps.geometry = mesh.with_vertices(st.scope.to_world(mesh.vertices))
        ps.scope = Scope.trusted(st.scope.origin, st.scope.rotation, st.scope.size)
        ps.fit_scope()
        # CityEngine's splitArea does not support tags and clears them
        ps.geometry = without_tags(ps.geometry.without_columns(*OFFSET_COLUMNS))
        ctx = dict(st.context)
        ctx["split.index"], ctx["split.total"] = i, n
        ps.context = ctx
        out.append((ps, branch.ops, {"axis": axis_name, "index": i}))
    return out
