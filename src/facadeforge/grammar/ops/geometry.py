"""Geometry-creating operations: extrude, offset, convexify, primitives, asset insertion…"""

from __future__ import annotations

import math

import numpy as np

from ...errors import InputError
from ...geometry.holed import HOLED, face_groups, fresh_ids, outline, plane_polygon, rings
from ...geometry.mesh import (
    EPS,
    Mesh,
    cross3,
    plane_basis,
    polygon_normal,
    weld_ids,
)
from ...geometry.polygon import simple_pieces
from ...geometry.primitives import PRIMITIVES, unit_ring
from ...model.scope import Scope
from ..values import CGARuntimeError, to_bool, to_float, to_str
from . import operation, shape_function
from .subdivision import (
    SHAPE_KIND,
    classify_faces,
    component_count,
    edge_or_vertex,
    face_scope,
    hole_polygons,
)
from .tagging import VERTEX_TAGS, auto_tag, corner_tags, edges_with, faces_from_edges
from .transform import mirrored
from .trimming import apply_trim, note_asset

# ---- extrude ----------------------------------------------------------------------------------

def extrude_mesh(mesh: Mesh, direction_of_face, distance: float) -> tuple[Mesh, list[str]]:
    """Prism of every face: bottom (reversed), side quads, top.  Returns the mesh and each face's
    part: "bottom", "side.outer", "side.inner" (a side rising from a hole's edge) or "top".

    Face data follows CityEngine's tag propagation: every face keeps the data of the face it
    rose from, a side face also takes the tags of the edge it rose from, the top's and
    bottom's edges and vertices keep theirs (corner data), and an edge rising from a vertex
    takes that vertex's tags.

    Where two faces share an edge and move the same way, their two side quads on it would be
    one wall seen from both sides, enclosing nothing: both are left out, so pieces that share
    edges (a face with a hole stored as triangles, a recomposed footprint) extrude to one
    volume without inner walls."""
    polys, kinds, sides, source, from_edge = [], [], [], [], []
    track = mesh.corner_data is not None
    vsrc, esrc, rise = [], [], []  # rise: the vertex a vertical edge rises from
    normals = mesh.face_normals()
    for f in range(mesh.n_faces):
        base = int(mesh.starts[f])
        p = mesh.vertices[mesh.face(f)]
        d = direction_of_face(normals[f]) * distance
        k = len(p)
        own = list(range(base, base + k))
        faces = [p[::-1]]
        none = [-1] * k
        corner_src = [(own, own, none, True)]  # (vertex, edge, rising-edge sources, reversed)
        for j in range(k):
            a, b = p[j], p[(j + 1) % k]
            if mesh.n_faces > 1:
                sides.append((len(polys) + len(faces), a, b, d))
            faces.append(np.array([a, b, b + d, a + d]))
            nb = base + (j + 1) % k
            corner_src.append(([base + j, nb, nb, base + j], [base + j, -1, base + j, -1],
                               [-1, nb, -1, base + j], False))
        faces.append(p + d)
        corner_src.append((own, own, none, False))
        flip = distance < 0
        for q, (vs, es, rs, rev) in zip(faces, corner_src):
            polys.append(q[::-1] if flip else q)
            if track:
                for _ in range(int(rev) + int(flip)):  # reversing moves an edge's data along
                    n = len(vs)
                    vs = vs[::-1]
                    es, rs = ([x[(n - 2 - i) % n] for i in range(n)] for x in (es, rs))
                vsrc.extend(vs)
                esrc.extend(es)
                rise.extend(rs)
        kinds.extend(["bottom"] + ["side.outer"] * k + ["top"])
        source.extend([f] * (k + 2))
        from_edge.extend([-1] + own + [-1])
    inner = _paired_walls(sides)
    if inner:
        keep = [i for i in range(len(polys)) if i not in inner]
        if track:
            first = np.concatenate([[0], np.cumsum([len(q) for q in polys])])
            cs = np.concatenate([np.arange(first[i], first[i + 1]) for i in keep])
            vsrc, esrc, rise = ([x[c] for c in cs] for x in (vsrc, esrc, rise))
        polys, kinds = [polys[i] for i in keep], [kinds[i] for i in keep]
        source, from_edge = [source[i] for i in keep], [from_edge[i] for i in keep]
    for i in _hole_walls(polys, kinds) if mesh.n_faces > 1 else ():  # one face has no hole
        kinds[i] = "side.inner"
    out = Mesh.from_polygons(polys).inherit(mesh, source, drop=("kind", HOLED),
                                            corner_source=(vsrc, esrc) if track else None)
    holed = mesh.column(HOLED)
    if holed is not None:  # a face with holes has one bottom and one top, each pieces
        out = out.with_column(HOLED, fresh_ids(
            None if holed[f] is None or k.startswith("side") else (holed[f], k)
            for f, k in zip(source, kinds)))
    out = faces_from_edges(out, mesh, from_edge)
    if mesh.corner_column(VERTEX_TAGS) is not None:  # an edge rising from a vertex
        vertex_tags = corner_tags(mesh, VERTEX_TAGS)
        out = edges_with(out, [vertex_tags[r] if r >= 0 else () for r in rise])
    out.closed = True if mesh.n_faces == 1 else None  # a single face's prism is closed
    return out, kinds


def _hole_walls(polys: list, kinds: list) -> list[int]:
    """The side walls standing on a hole's edge: their bottom edges form loops that turn
    clockwise around the extrusion (an outline turns counter-clockwise)."""
    walls = [i for i, k in enumerate(kinds) if k.startswith("side")]
    if len(walls) < 3:
        return []
    pts = np.array([polys[i][:2] for i in walls]).reshape(-1, 3)
    ids = weld_ids(pts).reshape(-1, 2)
    up = np.array([polys[i][3] - polys[i][0] for i in walls])
    nxt = {}
    for w, (a, b) in enumerate(ids):
        nxt.setdefault(a, []).append((b, w))
    seen, out = set(), []
    for start in range(len(walls)):
        if start in seen:
            continue
        loop, w = [], start
        while w not in seen:
            seen.add(w)
            loop.append(w)
            cand = nxt.get(ids[w][1], [])
            w = next((x for _, x in cand if x not in seen), start)
        ring = pts.reshape(-1, 2, 3)[loop, 0]
        turn = cross3(ring, np.roll(ring, -1, axis=0)).sum(axis=0)
        if turn @ up[loop].sum(axis=0) < 0:
            out.extend(walls[x] for x in loop)
    return out


def _paired_walls(sides: list) -> set:
    """Indices of side walls whose edge another face has the other way round with the same
    extrusion vector (within 1e-6 m; a tree query, so rounding boundaries cannot split a pair)."""
    if len(sides) < 2:
        return set()
    from scipy.spatial import cKDTree

    fwd = np.array([np.concatenate([a, b, d]) for _, a, b, d in sides])
    rev = np.array([np.concatenate([b, a, d]) for _, a, b, d in sides])
    hits = cKDTree(fwd).query_ball_point(rev, r=1e-6)
    return {sides[i][0] for i, js in enumerate(hits) if any(j != i for j in js)}


_WORLD_UP = ("world.y", "world.up", "world.up.flatTop")  # extrude directions
_NORMAL = ("face.normal", "vertex.normal", "normal")


@operation("extrude", 1, 2, selectors=(0,), selector_min_args=2)
def op_extrude(call):
    """Extrude each face along its normal (or ``world.y``); the scope keeps its orientation."""
    st = call.state
    if len(call.args) == 2:
        mode, dist = call.sel(0), call.num(1)
    else:
        mode, dist = "face.normal", call.num(0)
    if abs(dist) < EPS:
        return
    if mode not in _WORLD_UP + _NORMAL:
        raise CGARuntimeError(f"extrude direction '{mode}' is not supported; use face.normal or "
                              "world.up")
    if not st.geometry.n_faces:
        if edge_or_vertex(st) == "edge":
            _extrude_edge(st, mode, dist)
        return
    if mode in _WORLD_UP:
        def direction(n):
            return np.array([0.0, 1.0 if n[1] >= 0 else -1.0, 0.0])
    else:
        def direction(n):
            return n
    first_normal = st.geometry.face_normals()[0]
    st.geometry, kinds = extrude_mesh(st.geometry, direction, dist)
    st.geometry = auto_tag(st.geometry, "extrude", kinds)
    align_scope_y(st, direction(first_normal))
    st.fit_scope()


def _extrude_edge(st, mode: str, dist: float) -> None:
    """An edge shape (from ``comp(e|fe)``) extruded: the quad it sweeps along world up
    (``world.up…``) or along its normal (its scope's z axis, the mean normal of the faces it
    bordered), facing away from the face it came from ("Edges can also be extruded, e.g., when
    working on shapes created from comp(e|fe)", extrude reference)."""
    sc = st.scope
    length = sc.size[0]
    if abs(length) < EPS:
        return
    a = sc.origin
    b = a + sc.rotation[:, 0] * length
    up = np.array([0.0, 1.0, 0.0]) if mode.startswith("world") else sc.rotation[:, 2]
    d = up * dist
    st.geometry = auto_tag(Mesh.from_polygons([np.array([a, b, b + d, a + d])]), "extrude",
                           ["side.outer"])
    st.context.pop(SHAPE_KIND, None)
    align_scope_y(st, up if dist > 0 else -up)
    st.fit_scope()


def align_scope_y(st, y_axis: np.ndarray) -> None:
    """Scope y along ``y_axis``, x the old x projected onto the plane normal to it, z = x × y
    (CityEngine's scope after extrude and roof operations)."""
    y = np.asarray(y_axis, float)
    if np.linalg.norm(y) < EPS:
        return
    y = y / np.linalg.norm(y)
    x = st.scope.rotation[:, 0] - y * (st.scope.rotation[:, 0] @ y)
    if np.linalg.norm(x) < EPS:
        x = st.scope.rotation[:, 2] - y * (st.scope.rotation[:, 2] @ y)
    x = x / np.linalg.norm(x)
    st.own_scope().rotation = np.column_stack([x, y, cross3(x, y)])


# ---- offset -----------------------------------------------------------------------------------

def _offset_ring(xy: np.ndarray, d: float) -> np.ndarray | None:
    """Mitre offset of a CCW ring by ``d`` (negative = inward), vertex for vertex; None if invalid."""
    k = len(xy)
    e = np.roll(xy, -1, axis=0) - xy
    length = np.linalg.norm(e, axis=1)
    if np.any(length < EPS):
        return None
    t = e / length[:, None]
    n_out = np.column_stack([t[:, 1], -t[:, 0]])  # right of a CCW edge = outside
    p = xy + n_out * d  # points on the offset lines
    out = np.empty_like(xy)
    for j in range(k):
        i = (j - 1) % k  # previous edge
        a1, d1, a2, d2 = p[i], t[i], p[j], t[j]
        den = d1[0] * d2[1] - d1[1] * d2[0]
        if abs(den) < 1e-12:
            out[j] = xy[j] + n_out[j] * d
        else:
            s = ((a2 - a1)[0] * d2[1] - (a2 - a1)[1] * d2[0]) / den
            out[j] = a1 + s * d1
    import shapely

    poly = shapely.Polygon(out)
    if not poly.is_valid or poly.area < EPS:
        return None
    x, y = out[:, 0], out[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) <= 0:
        return None
    return out


@operation("offset", 1, 2, selectors=(1,))
def op_offset(call):
    """Offset every face in its plane.  ``inside`` keeps the inner polygon, ``border`` the ring,
    ``all`` (default) both, tagged so that ``comp(f){ inside : … | border : … }`` can pick them."""
    import shapely

    st = call.state
    d = call.num(0)
    mode = call.sel(1, "all")
    if mode not in ("all", "inside", "border"):
        raise CGARuntimeError(f"offset mode must be all, inside or border, not '{mode}'")
    mesh = st.geometry
    polys, kinds, keys, source, from_edge = [], [], [], [], []
    normals = mesh.face_normals()

    def add(ring, kind, key, edge=-1):
        polys.append(lift(ring))
        kinds.append(kind)
        keys.append(key)
        from_edge.append(edge)

    for group in face_groups(mesh):
        f = group[0]
        p = mesh.vertices[mesh.face(f)]
        n = normals[f]
        if not n.any():
            continue
        before = len(polys)
        basis = plane_basis(n, p[1] - p[0])
        lift = lambda q, p0=p[0], b=basis: p0 + q @ b[:, :2].T  # noqa: E731
        inner = None
        if len(group) == 1:
            xy = (p - p[0]) @ basis[:, :2]
            inner = _offset_ring(xy, d)
        if inner is not None:  # the exact mitre offset, vertex for vertex
            if mode in ("all", "inside"):
                add(inner, "inside", None)
            if mode in ("all", "border"):
                k = len(xy)
                outer_ring, inner_ring = (xy, inner) if d < 0 else (inner, xy)
                for j in range(k):
                    jn = (j + 1) % k
                    add(np.array([outer_ring[j], outer_ring[jn], inner_ring[jn], inner_ring[j]]),
                        "border", (f, "border"), int(mesh.starts[f]) + j)
        else:  # large offsets and faces with holes: shapely's mitre buffer, holed parts in pieces
            base = (shapely.Polygon(xy).buffer(0) if len(group) == 1
                    else plane_polygon(mesh, group, p[0], basis))
            off = base.buffer(d, join_style="mitre", mitre_limit=10.0)
            if mode in ("all", "inside"):
                for i, (outer, holes) in enumerate(rings(off)):
                    for q in simple_pieces(shapely.Polygon(outer, holes)):
                        add(q, "inside", (f, "inside", i) if holes else None)
            if mode in ("all", "border"):
                for outer, holes in rings(base.difference(off) if d < 0 else off.difference(base)):
                    for q in simple_pieces(shapely.Polygon(outer, holes)):
                        add(q, "border", (f, "border"))
        source.extend([f] * (len(polys) - before))
    # CityEngine's border is one face with a hole; here it is pieces sharing an id, so that
    # comp(f){ border : … } makes one shape of each, as CityEngine does
    out = (Mesh.from_polygons(polys).inherit(mesh, source, drop=(HOLED,))
           .with_column("kind", kinds).with_column(HOLED, fresh_ids(keys)))
    st.geometry = faces_from_edges(out, mesh, from_edge)  # a border piece rising from an edge
    if st.geometry.n_faces:
        st.fit_scope()


# ---- convexify --------------------------------------------------------------------------------

def convex_parts(poly: np.ndarray, max_length: float = math.inf) -> list[np.ndarray]:
    """Convex pieces of a planar polygon (k, 3) by split lines, as CityEngine's ``convexify``
    describes them: at a concave corner, one of its two edges is carried on into the polygon
    until it meets the outline, and the polygon is cut along that line.  The shortest such
    line of all concave corners is cut first, then each piece in turn, until every piece is
    convex; ``max_length`` leaves lines longer than it uncut (a piece may stay concave).
    Corners are shared: a cut point on an edge becomes a corner of both pieces."""
    n = polygon_normal(poly)
    if not n.any():
        return []
    basis = plane_basis(n)
    xy = ((poly - poly[0]) @ basis[:, :2]).tolist()
    pts = [list(map(float, q)) for q in poly]
    out: list[list] = []
    todo = [(xy, pts)]
    while todo:
        if len(out) + len(todo) > 10_000:
            raise CGARuntimeError("convexify: more than 10,000 pieces; cleanupGeometry first?")
        xy, pts = todo.pop()
        cut = _shortest_split(xy, max_length)
        if cut is None:
            out.append(pts)
            continue
        todo.extend(_cut_polygon(xy, pts, *cut))
    return [np.array(q) for q in out]


def _shortest_split(xy: list, max_length: float):
    """``(corner, edge, t, length)`` of the shortest split line from a concave corner of the
    counter-clockwise ring ``xy``: an edge of the corner carried on until it meets edge
    ``edge`` at parameter ``t``; ``None`` when the ring is convex (or no line is short enough)."""
    k = len(xy)
    if k < 4:
        return None
    best = None
    for i in range(k):
        a, v, b = xy[i - 1], xy[i], xy[(i + 1) % k]
        turn = (v[0] - a[0]) * (b[1] - v[1]) - (v[1] - a[1]) * (b[0] - v[0])
        scale = math.hypot(v[0] - a[0], v[1] - a[1]) * math.hypot(b[0] - v[0], b[1] - v[1])
        if turn >= -1e-9 * max(scale, 1e-12):
            continue  # convex (or straight) corner
        for d in ((v[0] - a[0], v[1] - a[1]), (v[0] - b[0], v[1] - b[1])):
            hit = _ray_hit(xy, i, d)
            if hit is not None and hit[2] <= max_length and (best is None or hit[2] < best[3] - 1e-12):
                best = (i, hit[0], hit[1], hit[2])
    return best


def _ray_hit(xy: list, i: int, d) -> tuple[int, float, float] | None:
    """First crossing ``(edge, t, distance)`` of the ray from corner ``i`` along ``d`` with an
    edge of the ring not at that corner (``t`` in [0, 1) along the edge)."""
    k = len(xy)
    norm = math.hypot(*d)
    if norm < 1e-12:
        return None
    dx, dy = d[0] / norm, d[1] / norm
    ox, oy = xy[i]
    best = None
    for e in range(k):
        if e == i or (e + 1) % k == i:
            continue
        p, q = xy[e], xy[(e + 1) % k]
        ex, ey = q[0] - p[0], q[1] - p[1]
        den = dx * ey - dy * ex
        if abs(den) < 1e-12:
            continue
        wx, wy = p[0] - ox, p[1] - oy
        s = (wx * ey - wy * ex) / den          # along the ray
        t = (wx * dy - wy * dx) / den          # along the edge
        if s > 1e-9 and -1e-9 <= t < 1 - 1e-9 and (best is None or s < best[2]):
            best = (e, min(max(t, 0.0), 1.0), s)
    return best


def _cut_polygon(xy: list, pts: list, i: int, e: int, t: float, _length: float):
    """The two rings of ``xy`` (and of its 3D corners ``pts``) cut from corner ``i`` to the
    point at ``t`` along edge ``e``."""
    k = len(xy)
    j = (e + 1) % k
    if t <= 1e-9:  # the line ends at a corner
        hit_xy, hit_p, at = None, None, e
    else:
        hit_xy = [xy[e][c] + t * (xy[j][c] - xy[e][c]) for c in range(2)]
        hit_p = [pts[e][c] + t * (pts[j][c] - pts[e][c]) for c in range(3)]
        at = None

    def walk(frm: int, to: int) -> list[int]:
        idx, c = [], frm
        while True:
            idx.append(c)
            if c == to:
                return idx
            c = (c + 1) % k

    if at is not None:
        a, b = walk(i, at), walk(at, i)
        return [([xy[c] for c in a], [pts[c] for c in a]), ([xy[c] for c in b], [pts[c] for c in b])]
    a = walk(i, e)   # i … e, then the cut point
    b = walk(j, i)   # the cut point, then j … i
    return [([xy[c] for c in a] + [hit_xy], [pts[c] for c in a] + [hit_p]),
            ([hit_xy] + [xy[c] for c in b], [hit_p] + [pts[c] for c in b])]


@operation("convexify", 0, 1)
def op_convexify(call):
    """``convexify()`` / ``convexify(maxLength)``: every face cut into convex pieces along
    split lines no longer than ``maxLength`` (:func:`convex_parts`)."""
    st = call.state
    max_length = call.num(0) if call.args else math.inf
    polys, source = [], []
    for f, p in enumerate(st.geometry.polygons()):
        parts = convex_parts(p, max_length)
        polys.extend(parts)
        source.extend([f] * len(parts))
    # convex parts are faces of their own (a face with holes too: its pieces come apart)
    st.geometry = Mesh.from_polygons(polys).inherit(st.geometry, source, drop=("kind", HOLED))


# ---- small geometry edits -------------------------------------------------------------------------

@operation("reverseNormals", 0)
def op_reverse_normals(call):
    call.state.geometry = call.state.geometry.reversed()


@operation("envelope", 3, 8, selectors=(0,))
def op_envelope(call):
    """``envelope(direction, maxHeight, baseHeight, angle…)``: walls up to ``baseHeight``, then
    planes inclined inwards at the first angle (straight skeleton), cut flat at ``maxHeight``."""
    from ...geometry.roofs import roof_hip

    st = call.state
    max_h, base_h = call.num(1), call.num(2)
    angle = call.num(3, 45.0)
    polys, parts, source = [], [], []
    mesh = st.geometry
    if hole_polygons(mesh):
        raise CGARuntimeError("envelope: the face has holes (a courtyard), which envelope does "
                              "not take; deleteHoles() first, or extrude and roofHip")
    for group in face_groups(mesh):  # a face stored as pieces: its outline
        f = group[0]
        p = mesh.vertices[mesh.face(f)] if len(group) == 1 else outline(mesh, group)
        n = polygon_normal(p)
        if not n.any():
            continue
        basis = plane_basis(n, p[1] - p[0])
        xy = (p - p[0]) @ basis[:, :2]
        walls, kinds = extrude_mesh(Mesh.from_polygons([p]), lambda nn: nn, base_h)
        for q, kind in zip(walls.polygons(), kinds):
            if kind != "top":
                polys.append(q)
                parts.append("side.base" if kind == "side.outer" else kind)
        faces = roof_hip(xy, angle).faces
        h_top = max_h - base_h
        for q in faces:
            q = np.asarray(q, float)
            polys.append(p[0] + q[:, :2] @ basis[:, :2].T + np.outer(np.minimum(q[:, 2], h_top) + base_h, n))
            parts.append("top" if np.all(q[:, 2] >= h_top) else "side.slope")
        source.extend([f] * (len(parts) - len(source)))
    keep = [i for i, q in enumerate(polys) if np.linalg.norm(cross3(q[1] - q[0], q[-1] - q[0])) > 0]
    out = Mesh.from_polygons([polys[i] for i in keep]).inherit(
        mesh, [source[i] for i in keep], drop=("kind", HOLED))
    st.geometry = auto_tag(out, "envelope", [parts[i] for i in keep])
    st.fit_scope()


# ---- primitives and assets -------------------------------------------------------------------

def _fit_unit_mesh(st, mesh: Mesh, bounds: np.ndarray) -> None:
    """Place a mesh given in its own frame into the scope, scaled to the scope size.

    Zero scope dimensions take the asset's proportions (CityEngine's insert operation): one
    zero size is the mean scale of the other two times the asset's, the scope staying where it
    is; with two zero sizes the asset scales uniformly by the third and the scope moves along
    the two by the asset's scaled offset; with all three zero the asset keeps its size and its
    place relative to the scope's origin.
    """
    lo, hi = bounds
    ext = hi - lo
    size = st.scope.size
    if min(ext.tolist()) > EPS and min(size.tolist()) > EPS:  # the usual case: the scope stays
        local = (mesh.vertices - lo) * (size / ext)
    else:
        factors = np.where((ext > EPS) & (size > EPS), size / np.where(ext > EPS, ext, 1.0),
                           np.nan)
        known = factors[~np.isnan(factors)]
        fill = float(known.mean()) if len(known) else 1.0
        zero = np.isnan(factors) & (size <= EPS)
        factors = np.where(np.isnan(factors), fill, factors)
        new_size = np.where(ext > EPS, ext * factors, size)
        local = (mesh.vertices - lo) * factors
        sc = st.own_scope()
        if zero.sum() >= 2:  # line or point scopes move by the asset's own offset
            sc.origin = sc.to_world((np.where(zero, lo * factors, 0.0))[None])[0]
        sc.size = new_size
    st.geometry = mesh.with_vertices(st.scope.to_world(local))
    if mirrored(st.scope.rotation):  # a mirrored scope (mirrorScope): faces stay outward
        st.geometry = st.geometry.reversed()


_INSERT_MODES = ("alignSizeAndPosition", "keepSizeAndPosition", "keepSizeAlignPosition")


@operation("i", 1, 4, selectors=(1, 2, 3))
def op_insert(call):
    """``i(filePath[, yUp|zUp[, insertMode[, numericalCleanup|noCleanup]]])``: insert an asset
    (a file or ``builtin:…``) fitted to the scope, then cut at the shape's trim planes
    (CityEngine "insert operation", https://doc.arcgis.com/en/cityengine/latest/cga/cga-i.htm).

    ``zUp`` turns a z-up asset by -90° about x; ``keepSizeAndPosition`` is ``s(0,0,0)`` first
    (the asset keeps its size and place); ``keepSizeAlignPosition`` keeps its size and stands
    it in the xz centre of the scope on y = 0.  Assets are never cleaned up numerically, so both
    cleanup modes give the same."""
    st = call.state
    name = call.text(0)
    up = call.sel(1, "yUp")
    mode = call.sel(2, "alignSizeAndPosition")
    cleanup = call.sel(3, "numericalCleanup")
    if up not in ("yUp", "zUp") or mode not in _INSERT_MODES \
            or cleanup not in ("numericalCleanup", "noCleanup"):
        raise CGARuntimeError("i(filePath, yUp|zUp, alignSizeAndPosition|keepSizeAndPosition|"
                              "keepSizeAlignPosition, numericalCleanup|noCleanup)")
    mesh, asset = load_asset(call, name)
    if up == "zUp":
        v = mesh.vertices
        mesh = mesh.with_vertices(np.column_stack([v[:, 0], v[:, 2], -v[:, 1]]))
        bounds = mesh.bounds()
    else:
        known = _BOUNDS.get(id(mesh))
        if known is None or known[0] is not mesh:
            if len(_BOUNDS) >= 1024:  # assets of many rule packages in one process: bounded
                _BOUNDS.clear()
            known = _BOUNDS[id(mesh)] = (mesh, mesh.bounds())
        bounds = known[1]
    note_asset(name, bounds)
    if mode == "keepSizeAndPosition":
        st.own_scope().size = np.zeros(3)
    elif mode == "keepSizeAlignPosition":
        sc = st.own_scope()
        ext = bounds[1] - bounds[0]
        sc.origin = sc.to_world(np.array([[(sc.size[0] - ext[0]) / 2, 0.0,
                                           (sc.size[2] - ext[2]) / 2]]))[0]
        sc.size = ext.copy()
    _fit_unit_mesh(st, mesh, bounds)
    st.context.pop("asset_material", None)
    several = asset is not None and asset.face_material is not None
    if several:  # per-face materials before the cut, which keeps them with their faces
        apply_asset_material(st, asset, asset.face_material)
    apply_trim(st, fitted=True)
    if asset is not None and not several:
        apply_asset_material(st, asset, None)
    st.context["inserted"] = (name, st.geometry)  # geometry.isInstanced (ops/queries.py)


#: ``builtin:…`` meshes, made once (meshes are never changed in place)
_BUILTIN: dict[str, Mesh] = {}
#: id(asset mesh) -> (mesh, its bounds): inserted assets are a few meshes inserted many times
_BOUNDS: dict[int, tuple] = {}


def load_asset(call, name: str):
    """``(mesh, asset)`` of an asset argument: a ``builtin:…`` primitive (``asset`` None) or a
    file under the asset roots (``i``, ``insertAlongUV``)."""
    if name.startswith("builtin:"):
        mesh = _BUILTIN.get(name)
        if mesh is None:
            make = PRIMITIVES.get(name.split(":")[1])
            if make is None:
                raise CGARuntimeError(f"unknown builtin asset '{name}'; use one of "
                                      + ", ".join("builtin:" + k for k in sorted(PRIMITIVES)))
            mesh = _BUILTIN[name] = make()
        return mesh, None
    resolver = call.derivation.assets
    if resolver is None:
        raise CGARuntimeError(f"asset '{name}' cannot be inserted: no asset folder was given (--assets DIR)")
    try:
        asset = resolver.mesh(name)
    except InputError as e:
        raise CGARuntimeError(str(e)) from None
    if asset is None:
        raise CGARuntimeError(f"asset '{name}' not found under {resolver.roots[0] if resolver.roots else '?'}")
    return asset.mesh, asset


def apply_asset_material(st, asset, face_material) -> None:
    """An inserted asset's material on the shape: ``face_material`` (one material index per face
    of ``st.geometry``, or None) keeps several materials per face until an operation changes
    the faces; a single material gives its texture and colour where the shape has none."""
    if face_material is not None:
        whole = face_material is asset.face_material
        st.geometry = st.geometry.with_column(
            "material", asset.material_column() if whole
            else [asset.materials[k] for k in face_material])
        return
    own = {}
    if asset.material.texture:
        own["colormap"] = asset.material.texture
    if asset.material.color != (1.0, 1.0, 1.0):
        own["color"] = tuple(asset.material.color)
    st.material.update({k: v for k, v in own.items() if k not in st.material})
    st.context["asset_material"] = (own, st.geometry.n_faces)  # for resetMaterial


def asset_material_keys(st) -> dict:
    """The material attributes an inserted single-material asset brings (its texture and
    colour), while the shape still holds that asset's faces; else ``{}``."""
    rec = st.context.get("asset_material")
    return rec[0] if rec is not None and rec[1] == st.geometry.n_faces else {}


#: Per primitive: (resolution arguments, dimension arguments) of CityEngine's signatures, e.g.
#: ``primitiveCylinder(sides, radius, height)``; ``primitiveCube(width, height, depth)``.
_PRIMITIVE_ARGS = {"cube": (0, 3), "quad": (0, 2), "cylinder": (1, 2), "cone": (1, 2),
                   "disk": (1, 1), "sphere": (2, 1)}


def _primitive_size(kind: str, dims: list[float]) -> np.ndarray:
    if kind == "cube":
        return np.array(dims)
    if kind in ("cylinder", "cone"):
        return np.array([2 * dims[0], dims[1], 2 * dims[0]])
    return np.full(3, 2 * dims[0])                                        # sphere


def _scope_plane(size: np.ndarray) -> tuple[int, int]:
    """The two scope axes of a flat primitive: those of the scope's non-zero dimensions (a
    facade's x, y; a lot's x, z), x and z when none is zero (CityEngine's default)."""
    flat = [k for k in range(3) if size[k] <= EPS]
    return (0, 1) if flat == [2] else (1, 2) if flat == [0] else (0, 2)


def _flat_in_scope_plane(outline: np.ndarray, size: np.ndarray) -> Mesh:
    """A flat primitive — ``outline``, (n, 2) points of the unit square, counter-clockwise —
    in the plane :func:`_scope_plane` picks, facing that plane's third axis (a lot's quad or
    disk faces up, a facade's faces out), with the outline as its UVs."""
    a, b = _scope_plane(size)
    v = np.zeros((len(outline), 3))
    v[:, a], v[:, b] = outline[:, 0], outline[:, 1]
    order = np.arange(len(outline))
    if polygon_normal(v)[3 - a - b] < 0:
        order = order[::-1]
    return Mesh(v, [order.tolist()], [outline[order].copy()])


_SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
#: Faces one primitive may have (its subdivisions multiplied): a 300 × 300 sphere; the faces
#: are built in Python, so 2000 × 2000 took minutes.
MAX_PRIMITIVE_FACES = 100_000


def _primitive_op(kind):
    n_res, n_dims = _PRIMITIVE_ARGS[kind]

    def fn(call):
        """CityEngine's primitive operations: no arguments fit the primitive to the scope;
        resolution arguments (sides, rows…) refine it; with its dimensions it gets that size,
        centred in the scope's xz and lying on its y = 0 — a quad or disk centred in the plane
        of the scope's non-zero dimensions instead (a facade's xy)."""
        st = call.state
        n = len(call.args)
        if n not in (0, n_res, n_res + n_dims) and not (kind == "sphere" and n == 1):
            raise CGARuntimeError(f"primitive{kind.title()}() takes {n_res} resolution and "
                                  f"{n_dims} size arguments, got {n} arguments")
        values = [call.num(k) for k in range(n)]
        res = [max(3, int(round(v))) if abs(v) < 1e9 else 10**9 for v in values[:min(n, n_res)]]
        if math.prod(res + ([16] if kind == "sphere" and len(res) == 1 else [])) \
                > MAX_PRIMITIVE_FACES:
            raise CGARuntimeError(f"primitive{kind.title()}({', '.join(map(str, res))}) makes more "
                                  f"than {MAX_PRIMITIVE_FACES:,} faces; use fewer subdivisions")
        dims = values[n_res:] if n > n_res else []
        # a negative size reaches the other way, as a negative s() does: the primitive is
        # centred in x and z anyway, and a negative height puts it below y = 0
        down = kind not in ("quad", "disk") and len(dims) >= 2 and dims[1] < 0
        dims = [abs(d) for d in dims]
        if kind in ("quad", "disk"):
            mesh = _flat_in_scope_plane(_SQUARE if kind == "quad" else unit_ring(*res),
                                        st.scope.size)
        elif kind == "sphere" and res:
            mesh = PRIMITIVES[kind](*(res + [16] if len(res) == 1 else res))
        else:
            mesh = PRIMITIVES[kind](*res)
        if dims:
            sc = st.own_scope()
            old = sc.size
            if kind in ("quad", "disk"):    # flat: the two sizes go along the scope's plane
                a, b = _scope_plane(st.scope.size)
                size = np.zeros(3)
                size[a], size[b] = (dims[0], dims[1]) if kind == "quad" else (2 * dims[0],) * 2
                shift = (old - size) / 2 * (size > 0)
            else:
                size = _primitive_size(kind, dims)
                shift = np.where(np.arange(3) == 1, -size[1] if down else 0.0, (old - size) / 2)
            sc.origin = sc.to_world(shift[None])[0]
            sc.size = size
        _fit_unit_mesh(st, mesh, mesh.bounds())
        apply_trim(st, fitted=True)
    return fn


for _op, _kind in (("primitiveCube", "cube"), ("primitiveQuad", "quad"),
                   ("primitiveCylinder", "cylinder"), ("primitiveSphere", "sphere"),
                   ("primitiveCone", "cone"), ("primitiveDisk", "disk")):
    operation(_op, 0, sum(_PRIMITIVE_ARGS[_kind]))(_primitive_op(_kind))


# ---- shape functions reading geometry ----------------------------------------------------------

def _face_selection(env, args) -> np.ndarray:
    st = env.state
    mesh = st.geometry
    if not args:
        return np.ones(mesh.n_faces, bool)
    key = to_str(args[0])
    table = classify_faces(mesh.face_normals(), st.scope.rotation,
                           env.derivation.object_scope.rotation)
    if key not in table:
        raise CGARuntimeError(f"unknown face selector '{key}'")
    return table[key]


@shape_function("geometry.area")
def _geometry_area(env, args):
    mesh = env.state.geometry
    if not mesh.n_faces:
        return 0.0
    return float(mesh.face_areas()[_face_selection(env, args)].sum())


@shape_function("geometry.volume")
def _geometry_volume(env, args):
    mesh = env.state.geometry
    return abs(mesh.volume()) if mesh.is_closed() else 0.0


@shape_function("geometry.nFaces")
def _geometry_nfaces(env, args):
    """Faces as ``comp(f)`` counts them (a face with holes once, whatever its pieces)."""
    return float(component_count(env.state, "f"))


@shape_function("geometry.nVertices")
def _geometry_nvertices(env, args):
    """Vertices as ``comp(v)`` counts them: coincident ones once (a box has 8)."""
    return float(component_count(env.state, "v"))


@shape_function("geometry.nEdges")
def _geometry_nedges(env, args):
    """Edges as ``comp(e)`` counts them: shared ones once, not the seams inside a face with
    holes (a box has 12)."""
    return float(component_count(env.state, "e"))


@shape_function("geometry.isClosedSurface")
def _geometry_closed(env, args):
    return env.state.geometry.is_closed()


@shape_function("geometry.isPlanar")
def _geometry_planar(env, args):
    mesh = env.state.geometry
    tol = to_float(args[0]) if args else 0.0
    n = mesh.face_normals()
    return bool(len(n)) and bool(np.all(np.degrees(np.arccos(np.clip(n @ n[0], -1, 1))) <= tol + 1e-6))


@shape_function("geometry.isRectangular")
def _geometry_rectangular(env, args):
    mesh = env.state.geometry
    tol = to_float(args[0]) if args else 0.0
    if mesh.n_faces != 1 or mesh.face_sizes[0] != 4:
        return False
    p = mesh.vertices[mesh.face(0)]
    e = np.roll(p, -1, axis=0) - p
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), EPS)
    ang = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", e, np.roll(e, -1, axis=0))), 0, 1)))
    return bool(np.all(90 - ang <= tol + 1e-6))


@shape_function("geometry.height")
def _geometry_height(env, args):
    b = env.state.geometry.bounds()
    return float(b[1, 1] - b[0, 1])


@shape_function("geometry.angle")
def _geometry_angle(env, args):
    mesh = env.state.geometry
    if not mesh.n_faces:
        return 0.0
    n = mesh.face_normals()[0]
    which = to_str(args[0]) if args else "maxSlope"
    if which == "azimuth":
        return float(np.degrees(np.arctan2(n[0], n[2])) % 360)
    return float(np.degrees(np.arccos(np.clip(abs(n[1]), 0, 1))))


@shape_function("fileExists")
def _file_exists(env, args):
    res = env.derivation.assets
    if res is None:
        return False
    try:
        return res.resolve(to_str(args[0])) is not None
    except InputError:
        return False


@shape_function("fileSearch")
def _file_search(env, args):
    res = env.derivation.assets
    items = res.search(to_str(args[0])) if res is not None else []
    return "".join(x + ";" for x in items)


@shape_function("fileRandom")
def _file_random(env, args):
    res = env.derivation.assets
    items = res.search(to_str(args[0])) if res is not None else []
    if not items:
        return ""
    return items[min(int(env.random_float() * len(items)), len(items) - 1)]


@shape_function("assetInfo")
def _asset_info(env, args):
    res = env.derivation.assets
    name = to_str(args[0])
    key = to_str(args[1]) if len(args) > 1 else "sx"
    if name.startswith("builtin:"):
        return 1.0
    try:
        asset = res.mesh(name) if res is not None else None
    except InputError:
        asset = None
    if asset is None:
        return 0.0
    lo, hi = asset.mesh.bounds()
    table = {"sx": hi[0] - lo[0], "sy": hi[1] - lo[1], "sz": hi[2] - lo[2], "tx": lo[0],
             "ty": lo[1], "tz": lo[2]}
    return float(table.get(key, 0.0))


__all__ = ["Scope", "convex_parts", "extrude_mesh", "face_scope", "to_bool"]


def _uv_bounds(env):
    uv = env.state.geometry.corner_uvs
    if uv is None or not len(uv):
        return np.zeros(2), np.zeros(2)
    return uv.min(axis=0), uv.max(axis=0)


for _name, _fn in {"geometry.uMin": lambda lo, hi: lo[0], "geometry.uMax": lambda lo, hi: hi[0],
                   "geometry.vMin": lambda lo, hi: lo[1], "geometry.vMax": lambda lo, hi: hi[1],
                   "geometry.du": lambda lo, hi: hi[0] - lo[0],
                   "geometry.dv": lambda lo, hi: hi[1] - lo[1]}.items():
    shape_function(_name)(lambda env, args, _fn=_fn: float(_fn(*_uv_bounds(env))))


@shape_function("imageInfo")
def _image_info(env, args):
    """``imageInfo(path, sx|sy)``: image width or height in pixels (0 when unreadable)."""
    res = env.derivation.assets
    key = to_str(args[1]) if len(args) > 1 else "sx"
    try:
        p = res.resolve(to_str(args[0])) if res is not None else None
    except InputError:
        p = None
    if p is None:
        return 0.0
    from PIL import Image

    try:
        with Image.open(p) as im:
            w, h = im.size
    except OSError:
        return 0.0
    return float({"sx": w, "sy": h}.get(key, 0))


@operation("scatter", 2, 6, selectors=(0, 2, 3), body=True)
def op_scatter(call):
    """``scatter(surface|volume|scope, n, uniform|gaussian, …){ ops }``: n point shapes.

    Points are drawn from the shape's random stream, area-weighted over the faces (``surface``),
    or uniformly in the scope box (``scope``, ``volume``).  Surface points get the face normal as
    scope y.  Gaussian distributions are centred on the scope centre with the given deviation.
    """
    st = call.state
    domain = call.sel(0)
    n = int(round(call.num(1)))
    dist = call.sel(2, "uniform")
    if n <= 0:  # counts are often worked out from the area (floor(geometry.area / 400)): none
        return []
    n = min(n, 100_000)
    mesh = st.geometry
    out = []
    rnd = st.random_float
    if domain == "surface" and mesh.n_faces:
        pos, _, _, face_of = mesh.triangulate()
        tri = pos.reshape(-1, 3, 3)
        area = np.linalg.norm(cross3(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
        cdf = np.cumsum(area) / max(area.sum(), EPS)
        normals = mesh.face_normals()
        for _ in range(n):
            t = int(np.searchsorted(cdf, rnd()))
            t = min(t, len(tri) - 1)
            a, b = rnd(), rnd()
            if a + b > 1:
                a, b = 1 - a, 1 - b
            p = tri[t, 0] + a * (tri[t, 1] - tri[t, 0]) + b * (tri[t, 2] - tri[t, 0])
            nrm = normals[face_of[t]]
            x = st.scope.rotation[:, 0] - nrm * (st.scope.rotation[:, 0] @ nrm)
            if np.linalg.norm(x) < EPS:
                x = st.scope.rotation[:, 2]
            out.append(Scope.from_axes(p, x, nrm))
    else:
        for _ in range(n):
            if dist == "gaussian":
                u = np.array([0.5 + 0.16 * _gauss(rnd) for _ in range(3)]).clip(0, 1)
            else:
                u = np.array([rnd(), rnd(), rnd()])
            p = st.scope.to_world((u * st.scope.size)[None])[0]
            out.append(Scope(p, st.scope.rotation.copy(), np.zeros(3)))
    branch = call.branches[0]
    result = []
    for k, sc in enumerate(out):
        ps = st.child(k)
        ps.scope = sc
        ps.geometry = Mesh()
        result.append((ps, branch.ops, {"index": k}))
    return result


def _gauss(rnd) -> float:
    import math

    u1, u2 = max(rnd(), 1e-12), rnd()
    return math.sqrt(-2 * math.log(u1)) * math.cos(2 * math.pi * u2)


@shape_function("convert")
def _convert(env, args):
    """``convert(x|y|z, fromSys, toSys, pos|dir, x, y, z)`` between scope, pivot, object and
    world coordinates."""
    from .scoping import pivot_frame

    comp = "xyz".find(to_str(args[0]))
    src, dst, kind = to_str(args[1]), to_str(args[2]), to_str(args[3])
    v = np.array([to_float(a) for a in args[4:7]])
    st = env.state
    frames = {"scope": (st.scope.origin, st.scope.rotation),
              "world": (np.zeros(3), np.eye(3)),
              "object": (env.derivation.object_scope.origin, env.derivation.object_scope.rotation),
              "pivot": pivot_frame(st, env.derivation)}
    if comp < 0 or src not in frames or dst not in frames:
        raise CGARuntimeError("convert(x|y|z, scope|pivot|object|world, …, pos|dir, x, y, z)")
    (o1, r1), (o2, r2) = frames[src], frames[dst]
    if kind == "pos":
        w = r1 @ v + o1
        out = r2.T @ (w - o2)
    else:
        out = r2.T @ (r1 @ v)
    return float(out[comp])


def asset_file(env, name: str, what: str, mesh: bool = False):
    """A readable file under the asset roots for a rule's file function (its loaded asset with
    ``mesh``), or a CGA warning."""
    res = env.derivation.assets
    try:
        p = (res.mesh(name) if mesh else res.resolve(name)) if res is not None else None
    except InputError as e:
        raise CGARuntimeError(str(e)) from None
    if p is None:
        raise CGARuntimeError(f"{what} '{name}' not found under the asset root")
    return p


def _read_table(env, args):
    """Rows of a CSV file under the asset root (``readFloatTable``/``readStringTable``).  As in
    CityEngine the delimiter is detected (comma, semicolon, tab or spaces) and UTF-8 and
    UTF-16 (with its byte-order mark) are read; unprintable characters become '?'."""
    import csv
    import io

    raw = read_small_file(env, to_str(args[0]), "table")
    text = raw.decode("utf-16") if raw[:2] in (b"\xff\xfe", b"\xfe\xff") else \
        raw.decode("utf-8-sig", errors="replace")
    text = "".join(c if c.isprintable() or c in "\r\n\t" else "?" for c in text)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    delimiter = ","
    for d in (",", ";", "\t"):
        if any(d in ln for ln in lines[:20]):
            delimiter = d
            break
    else:
        if any(" " in ln.strip() for ln in lines[:20]):
            delimiter = " "
    reader = csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter,
                        skipinitialspace=delimiter == " ")
    rows = [[c.strip() for c in r] for r in reader if r]
    width = max((len(r) for r in rows), default=0)
    return [r + [""] * (width - len(r)) for r in rows]


@shape_function("readFloatTable")
def _read_float_table(env, args):
    rows = _read_table(env, args)

    def num(x):
        try:
            return float(x)
        except ValueError:
            return float("nan")
    return np.array([[num(x) for x in r] for r in rows], float).reshape(len(rows), -1)


@shape_function("readStringTable")
def _read_string_table(env, args):
    rows = _read_table(env, args)
    return np.array(rows, dtype=object).reshape(len(rows), -1)


@shape_function("readTextFile")
def _read_text_file(env, args):
    return read_small_file(env, to_str(args[0]), "text file").decode("utf-8", errors="replace")


def read_small_file(env, name: str, what: str) -> bytes:
    """The bytes of a text or table file under the asset roots (at most
    ``assets.MAX_TEXT_BYTES``), or a CGA warning."""
    res = env.derivation.assets
    try:
        data = res.read_bytes(name) if res is not None else None
    except InputError as e:
        raise CGARuntimeError(str(e)) from None
    if data is None:
        raise CGARuntimeError(f"{what} '{name}' not found under the asset root")
    return data


def _scope_ratio(env, axes: str) -> float:
    idx = {"x": 0, "y": 1, "z": 2}
    a, b = idx.get(axes[:1], 0), idx.get(axes[1:2], 1)
    size = env.state.scope.size
    return float(size[a] / size[b]) if size[b] > EPS else float("inf")


def _sort_by_ratio(env, items: list[str], axes: str, dims) -> str:
    """Files sorted by how well their aspect ratio matches the scope's on ``axes`` (best first)."""
    target = _scope_ratio(env, axes)
    scored = []
    for k, name in enumerate(items):
        w, h = dims(name)
        if w <= 0 or h <= 0 or not np.isfinite(target) or target <= 0:
            err = float("inf")
        else:
            err = abs(np.log((w / h) / target))
        scored.append((err, k, name))
    return "".join(name + ";" for _, _, name in sorted(scored))


def _list(text) -> list[str]:
    """File names from a string list or (CGA 2021.0 on) a string array."""
    if isinstance(text, np.ndarray):
        return [to_str(x) for x in text.reshape(-1).tolist() if to_str(x)]
    return [x for x in to_str(text).split(";") if x]


@shape_function("imagesSortRatio")
def _images_sort_ratio(env, args):
    def dims(name):
        sx = _image_info(env, [name, "sx"])
        sy = _image_info(env, [name, "sy"])
        return sx, sy
    return _sort_by_ratio(env, _list(args[0]), to_str(args[1]) if len(args) > 1 else "xy", dims)


@shape_function("assetsSortRatio")
def _assets_sort_ratio(env, args):
    axes = to_str(args[1]) if len(args) > 1 else "xy"

    def dims(name):
        return (_asset_info(env, [name, "s" + axes[:1]]), _asset_info(env, [name, "s" + axes[1:2]]))
    return _sort_by_ratio(env, _list(args[0]), axes, dims)


def size_error(env, name: str, axes: str) -> float:
    """Largest relative scaling |scope / asset - 1| an asset needs to fit the scope on ``axes``."""
    size = env.state.scope.size
    worst = 0.0
    for a in axes:
        s = _asset_info(env, [name, "s" + a])
        target = float(size["xyz".index(a)])
        worst = max(worst, abs(target / s - 1.0) if s > EPS else float("inf"))
    return worst


def sort_by_size(env, files: list[str], axes: str, max_scale_error: float = 0.0) -> list[str]:
    """``files`` ordered by the scaling they need (best first); with ``max_scale_error`` > 0
    only those within it (0.1 = ±10 %)."""
    if any(a not in "xyz" for a in axes) or not axes:
        raise CGARuntimeError(f"axis selector '{axes}' is not one of x, y, z, xy, xz, yz, xyz")
    errors = [size_error(env, f, axes) for f in files]
    order = sorted(range(len(files)), key=errors.__getitem__)
    return [files[k] for k in order if max_scale_error <= 0 or errors[k] <= max_scale_error + 1e-9]


@shape_function("assetsSortSize")
def _assets_sort_size(env, args):
    """``assetsSortSize(fileList, axes, maxScaleError)``: assets sorted by how little scaling
    they need to fit the scope on the given axes (func_assetsSortSize.html)."""
    axes = to_str(args[1]) if len(args) > 1 else "xyz"
    limit = to_float(args[2]) if len(args) > 2 else 0.0
    return "".join(name + ";" for name in sort_by_size(env, _list(args[0]), axes, limit))
