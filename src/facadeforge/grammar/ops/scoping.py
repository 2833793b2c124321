"""Scope and pivot operations, and a few small ones: ``alignScopeToGeometryBBox setPivot
mirrorScope footprint taper resetMaterial copyUV`` and the ``pivot.*`` shape attributes.

The pivot is CityEngine's shape coordinate system (reference: "pivot attribute",
https://doc.arcgis.com/en/cityengine/latest/cga/cga-pivot-attribute.htm).  It is kept in the
shape's context as a world frame ``(origin, rotation)`` and inherited by successors; a shape
without one has the initial shape's frame (``initialShape.origin``), so ``pivot.*`` reads 0.
It is not ``ShapeState.pivot``, which is the predecessor's scope that ``center`` aligns to.
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry.holed import HOLED
from ...geometry.mesh import EPS, Mesh, plane_basis, polygon_normal, weld_ids
from ...geometry.polygon import simple_pieces
from ...model.scope import Scope
from ..values import CGARuntimeError, to_bool
from . import operation
from .geometry import align_scope_y, asset_material_keys
from .tagging import auto_tag, faces_from_edges

PIVOT_KEY = "pivot"
UV_SETS_KEY = "uv_sets"
_NONE = object()

# ---- the pivot ---------------------------------------------------------------------------------


def pivot_frame(state, derivation) -> tuple[np.ndarray, np.ndarray]:
    """World origin (3,) and rotation (3, 3) of the shape's pivot."""
    frame = state.context.get(PIVOT_KEY)
    if frame is not None:
        return frame
    obj = derivation.object_scope
    return obj.origin, obj.rotation


def set_pivot_frame(state, origin: np.ndarray, rotation: np.ndarray) -> None:
    state.context[PIVOT_KEY] = (np.array(origin, float), np.array(rotation, float))


def pivot_value(env, key: str) -> float:
    """``pivot.px|py|pz`` (position) and ``pivot.ox|oy|oz`` (orientation, degrees of the ordered
    rotations about x, y, z), both in object coordinates, i.e. relative to ``initialShape.origin``
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-pivot-attribute.htm)."""
    origin, rotation = pivot_frame(env.state, env.derivation)
    obj = env.derivation.object_scope
    axis = "xyz".index(key[1])
    if key[0] == "p":
        return float(obj.to_local(origin[None])[0][axis])
    return float(euler_xyz_deg(obj.rotation.T @ rotation)[axis]) + 0.0  # no -0.0


def euler_xyz_deg(r: np.ndarray) -> np.ndarray:
    """Angles (degrees) of the rotations about x, then y, then z that make ``r`` (the order of
    ``r()`` and ``scope.rx/ry/rz``); at ry = ±90 degrees, where only rx ± rz is defined, rz = 0."""
    ry = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    if math.cos(ry) > 1e-9:
        rx, rz = math.atan2(r[2, 1], r[2, 2]), math.atan2(r[1, 0], r[0, 0])
    else:
        rx, rz = math.atan2(-r[1, 2], r[1, 1]), 0.0
    return np.degrees([rx, ry, rz])


# ---- alignScopeToGeometryBBox ------------------------------------------------------------------

_AXIS = {"x": 0, "y": 1, "z": 2}


def _plane_points(points: np.ndarray, fixed: int) -> np.ndarray:
    """Scope-frame points (N, 3) seen along axis ``fixed``, as 2D coordinates (N, 2) of the two
    other axes taken in cyclic order (so that they and ``fixed`` form a right-handed frame)."""
    return points[:, [(fixed + 1) % 3, (fixed + 2) % 3]]


def min_area_rectangle(pts: np.ndarray, prefer: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Minimum-area bounding rectangle of 2D points by rotating calipers over the convex hull.

    Returns the unit direction (2,) of one rectangle side and the extents along it and across it.
    Among rectangles of (numerically) equal area, the one whose side is closest to ``prefer``
    (a unit 2D direction, up to quarter turns) wins, so an already aligned shape stays aligned.
    """
    import shapely

    hull = shapely.MultiPoint(pts).convex_hull
    if hull.geom_type == "Polygon":
        pts = np.asarray(hull.exterior.coords)
    elif hull.geom_type == "LineString":
        pts = np.asarray(hull.coords)
    else:  # a single point
        pts = pts[:1]
    edges = np.diff(pts, axis=0)
    lengths = np.linalg.norm(edges, axis=1)
    edges = edges[lengths > EPS] / lengths[lengths > EPS, None]
    if not len(edges):
        return np.asarray(prefer, float), 0.0, 0.0
    across = np.column_stack([-edges[:, 1], edges[:, 0]])
    along_p, across_p = pts @ edges.T, pts @ across.T  # (N, E)
    ext_a = along_p.max(axis=0) - along_p.min(axis=0)
    ext_c = across_p.max(axis=0) - across_p.min(axis=0)
    area = ext_a * ext_c
    tol = 1e-9 * max(1.0, float(area.max()))
    candidates = np.flatnonzero(area <= area.min() + tol)
    # closeness to ``prefer`` modulo quarter turns: |cos 4θ| is largest when aligned
    cos = edges[candidates] @ prefer
    sin = edges[candidates] @ np.array([-prefer[1], prefer[0]])
    score = np.cos(4 * np.arctan2(sin, cos))
    best = candidates[int(np.argmax(score - 1e-12 * np.arange(len(candidates))))]
    return edges[best], float(ext_a[best]), float(ext_c[best])


@operation("alignScopeToGeometryBBox", 1, 1, selectors=(0,))
def op_align_scope_to_geometry_bbox(call):
    """``alignScopeToGeometryBBox(xy|yx|xz|zx|yz|zy)``: the two named scope axes span the
    minimum-area rectangle enclosing the geometry seen along the third axis, which stays fixed;
    the first named axis takes the rectangle's longer side; the pivot moves to the scope origin
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-align-scope-to-geometry-box.htm).

    Where the reference is silent: among equal rectangles (a rectangle's four sides, a square's
    two) the one closest to the current axes wins, and of the two senses of the longer side the
    one closer to the current first axis (then to the current second axis), so a shape that is
    already aligned keeps its scope.  The pivot takes the scope's orientation as well.
    """
    st = call.state
    axes = call.sel(0)
    if len(axes) != 2 or axes[0] == axes[1] or any(a not in _AXIS for a in axes):
        raise CGARuntimeError(f"alignScopeToGeometryBBox: '{axes}' is not one of xy, yx, xz, zx, "
                              "yz, zy")
    if not st.geometry.n_faces:
        return
    first, second = _AXIS[axes[0]], _AXIS[axes[1]]
    fixed = 3 - first - second
    old = st.scope.rotation
    pts2 = _plane_points(st.scope.to_local(st.geometry.used_vertices()), fixed)
    # the current first axis in the same 2D coordinates
    prefer = _plane_points(np.eye(3)[first][None], fixed)[0]
    side, along, across = min_area_rectangle(pts2, prefer)
    longer = side if along >= across - EPS else np.array([-side[1], side[0]])
    p_axis, q_axis = old[:, (fixed + 1) % 3], old[:, (fixed + 2) % 3]
    a = longer[0] * p_axis + longer[1] * q_axis
    d_first, d_second = a @ old[:, first], a @ old[:, second]
    if d_first < -EPS or (abs(d_first) <= EPS and d_second < 0):
        a = -a
    cols = [None, None, None]
    cols[fixed], cols[first] = old[:, fixed], a
    cols[second] = np.cross(cols[(second + 1) % 3], cols[(second + 2) % 3])
    sc = st.own_scope()
    sc.rotation = np.column_stack(cols)
    st.fit_scope()
    set_pivot_frame(st, st.scope.origin, st.scope.rotation)


# ---- setPivot and mirrorScope ------------------------------------------------------------------

#: axisMap -> which old scope axis each new axis (x, y, z) follows at corner 0
_AXIS_MAPS = {"xyz": (0, 1, 2), "yzx": (2, 0, 1), "zxy": (1, 2, 0)}

#: cornerIndex -> corner of the scope box in units of its size: the bottom (y = 0) corners 0-3
#: from the origin along x first, then the top corners 4-7 above them in the same order
SCOPE_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1],
                          [0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]], float)


def pivot_at_corner(scope: Scope, axis_map: str, corner: int) -> Scope:
    """The scope re-expressed with its origin at ``corner`` and axes permuted by ``axis_map``,
    every axis pointing into the box and the frame right-handed (x and z trade places where the
    corner's inward directions would make it left-handed)."""
    perm = _AXIS_MAPS[axis_map]
    c = SCOPE_CORNERS[corner]
    signs = 1.0 - 2.0 * c  # +1 at the box's low side of an axis, -1 at its high side
    cols = [signs[p] * scope.rotation[:, p] for p in perm]
    sizes = [scope.size[p] for p in perm]
    if np.linalg.det(np.column_stack(cols)) < 0:
        cols[0], cols[2] = cols[2], cols[0]
        sizes[0], sizes[2] = sizes[2], sizes[0]
    origin = scope.to_world((c * scope.size)[None])[0]
    return Scope.trusted(origin, np.column_stack(cols), np.array(sizes, float), scope.unit)


@operation("setPivot", 2, 2, selectors=(0,))
def op_set_pivot(call):
    """``setPivot(axisMap, cornerIndex)``: the pivot moves to corner ``cornerIndex`` (0-7) of the
    scope, its axes the scope axes permuted by ``axisMap`` (``xyz``, ``yzx``, ``zxy``) and turned to
    point into the scope; the scope takes the pivot's frame (zero translation and rotation relative
    to it) and the geometry stays where it is
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-set-pivot.htm).

    The reference numbers the corners only in a picture; here 0-3 are the bottom corners
    (0,0,0), (sx,0,0), (sx,0,sz), (0,0,sz) in scope coordinates and 4-7 the top corners above
    them in the same order.  Other axis maps (``xzy``…) would make a left-handed pivot and
    are refused, as the reference lists only the three rotations.
    """
    st = call.state
    axis_map = call.sel(0)
    if axis_map not in _AXIS_MAPS:
        raise CGARuntimeError(f"setPivot: axisMap '{axis_map}' is not one of xyz, yzx, zxy")
    corner = call.num(1)
    if not (0 <= corner <= 7 and corner == int(corner)):
        raise CGARuntimeError(f"setPivot: cornerIndex must be an integer in [0, 7], got {corner:g}")
    st.scope = pivot_at_corner(st.scope, axis_map, int(corner))
    set_pivot_frame(st, st.scope.origin, st.scope.rotation)


@operation("mirrorScope", 3)
def op_mirror_scope(call):
    """``mirrorScope(xFlip, yFlip, zFlip)``: each flagged scope axis is reversed, the scope's
    origin moving to the opposite face so the box stays where it is; the geometry is unchanged
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-mirrorscope.htm).  An odd number of
    flips leaves a mirrored (left-handed) scope, which is what mirrors inserted assets."""
    st = call.state
    flags = [to_bool(call.args[k]) for k in range(3)]
    if not any(flags):
        return
    sc = st.own_scope()
    rot, origin = sc.rotation.copy(), sc.origin.copy()
    for k, flip in enumerate(flags):
        if flip:
            origin = origin + rot[:, k] * sc.size[k]
            rot[:, k] = -rot[:, k]
    sc.origin, sc.rotation = origin, rot


# ---- footprint and taper -----------------------------------------------------------------------


def footprint_mesh(st) -> Mesh:
    """The union of the geometry's faces projected onto the plane scope.y = 0, as faces whose
    normals point along scope y (holes are triangulated, as meshes hold simple polygons)."""
    import shapely

    g = st.geometry
    local = st.scope.to_local(g.vertices)
    # 2D coordinates (z, x): counter-clockwise there means a normal along +y
    rings = [local[g.face(f)][:, [2, 0]] for f in range(g.n_faces)]
    polys = [shapely.Polygon(r).buffer(0) for r in rings if len(r) >= 3]
    polys = [p for p in polys if p.area > EPS]
    if not polys:
        return Mesh()
    union = shapely.unary_union(polys, grid_size=1e-9)
    faces = []
    for part in getattr(union, "geoms", [union]):
        if part.geom_type != "Polygon" or part.area <= EPS:
            continue
        for ring in simple_pieces(part):
            faces.append(np.column_stack([ring[:, 1], np.zeros(len(ring)), ring[:, 0]]))
    return Mesh.from_polygons([st.scope.to_world(f) for f in faces])


@operation("footprint", 0)
def op_footprint(call):
    """``footprint()``: the geometry becomes its orthogonal projection onto the plane scope.y = 0
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-footprint-operation.htm).

    Where the reference is silent: overlapping projections are merged into one outline (a
    building's footprint, not its faces stacked), faces point along scope y so that ``extrude``
    rebuilds the volume upwards, texture coordinates are dropped, and the scope keeps its
    orientation and is fitted to the result (scope.sy = 0).  A geometry with no extent in the
    plane (a vertical wall seen from above) leaves an empty footprint.
    """
    st = call.state
    if not st.geometry.n_faces:
        return
    st.geometry = footprint_mesh(st)
    if st.geometry.n_faces:
        st.fit_scope()


def polygon_centroid(p: np.ndarray) -> np.ndarray:
    """Centre of gravity (3,) of a planar polygon (k, 3); the vertex mean when degenerate."""
    n = polygon_normal(p)
    if not n.any():
        return p.mean(axis=0)
    basis = plane_basis(n)
    xy = (p - p[0]) @ basis[:, :2]
    x, y = xy[:, 0], xy[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = cross.sum() / 2
    if abs(a) < EPS * EPS:
        return p.mean(axis=0)
    c = np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * a)
    return p[0] + c @ basis[:, :2].T


def taper_mesh(base: np.ndarray, normal: np.ndarray, height: float) -> Mesh:
    """Pyramid over polygon ``base`` (k, 3): the base reversed and one triangle per edge to the
    apex ``height`` along ``normal`` above its centre of gravity; faces point outwards."""
    apex = polygon_centroid(base) + normal * height
    k = len(base)
    faces = [base[::-1]] + [np.array([base[j], base[(j + 1) % k], apex]) for j in range(k)]
    if height < 0:
        faces = [f[::-1] for f in faces]
    out = Mesh.from_polygons(faces)
    out.closed = True
    return out


@operation("taper", 1)
def op_taper(call):
    """``taper(height)``: a pyramid over the first face, its apex ``height`` along the face normal
    above the face's centre of gravity; scope y along the normal, x the old x projected onto the
    face plane, sizes fitted to the pyramid; a negative height tapers downwards and leaves
    scope.sy < 0 (https://doc.arcgis.com/en/cityengine/latest/cga/cga-taper.htm).

    Faces are the base and one triangle per edge (``comp(f)`` sees them as bottom and sides).
    Where the reference is silent: ``taper(0)`` leaves the shape unchanged, as ``extrude(0)``
    does, and other faces than the first are dropped, as the reference says only the first is
    taken.
    """
    st = call.state
    height = call.num(0)
    if abs(height) < EPS or not st.geometry.n_faces:
        return
    g = st.geometry
    base = g.vertices[g.face(0)]
    normal = polygon_normal(base)
    if not normal.any():
        raise CGARuntimeError("taper: the first face is degenerate (no area); nothing to taper")
    pyramid = taper_mesh(base, normal, height).inherit(g, [0] * (len(base) + 1),
                                                       drop=("kind", HOLED))
    # a side rising from an edge takes its tags
    pyramid = faces_from_edges(pyramid, g, [-1] + [int(g.starts[0]) + j for j in range(len(base))])
    st.geometry = auto_tag(pyramid, "taper", ["bottom"] + ["side"] * len(base))
    align_scope_y(st, normal)
    st.fit_scope()
    if height < 0:  # the scope starts at the base and reaches down: scope.sy < 0
        sc = st.own_scope()
        sc.origin = sc.origin + sc.rotation[:, 1] * sc.size[1]
        sc.size = sc.size * np.array([1.0, -1.0, 1.0])


# ---- materials and texture coordinates ---------------------------------------------------------


@operation("resetMaterial", 0, 1, selectors=(0,))
def op_reset_material(call):
    """``resetMaterial([shape|geometry|all])``: back to CGA's default material
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-reset-material.htm).

    ``shape`` (the default) drops every material attribute the rules set (``color``,
    ``texture``, ``set(material.…)``), so an inserted asset shows its own material again;
    ``geometry`` drops the materials the geometry brought (an asset's, per face or whole);
    ``all`` does both.  (Single-material assets lend the shape their texture and colour, as
    ``i`` does; those are what ``shape`` keeps and ``geometry`` removes.)
    """
    st = call.state
    target = call.sel(0, "shape")
    if target not in ("shape", "geometry", "all"):
        raise CGARuntimeError(f"resetMaterial: target '{target}' is not one of shape, geometry, all")
    own = asset_material_keys(st)
    if target in ("geometry", "all"):
        st.geometry = st.geometry.without_columns("material")
        st.context.pop("asset_material", None)
        st.material = {k: v for k, v in st.material.items() if own.get(k, _NONE) != v}
        own = {}
    if target in ("shape", "all"):
        st.material = dict(own)


@operation("copyUV", 2)
def op_copy_uv(call):
    """``copyUV(uvSetSource, uvSetDest)``: the texture coordinates of one set (0-9) are copied to
    another (https://doc.arcgis.com/en/cityengine/latest/cga/cga-copy-uv.htm).

    Only set 0 (the colormap's) is exported; copies of it to other sets are kept with the
    shape while its faces stay the same, so ``copyUV(0, 1) … copyUV(1, 0)`` restores them.
    Copying from a set that holds no coordinates is an error, as CityEngine has nothing to copy.
    """
    st = call.state
    src, dst = (call.num(k) for k in (0, 1))
    for v in (src, dst):
        if not (0 <= v <= 9 and v == int(v)):
            raise CGARuntimeError(f"copyUV: uv sets are integers in [0, 9], got {v:g}")
    src, dst = int(src), int(dst)
    g = st.geometry
    if src == dst or not g.n_faces:
        return
    # the sets belong to these very faces: moving them keeps them (same corner array), cutting
    # or rebuilding the faces does not
    held = st.context.get(UV_SETS_KEY)
    sets = dict(held[1]) if held is not None and held[0] is g.corners else {}
    uv = g.corner_uvs if src == 0 else sets.get(src)
    if uv is None:
        raise CGARuntimeError(f"copyUV: uv set {src} holds no texture coordinates for these "
                              f"faces; only set 0 is projected here, so fill set {src} with "
                              f"copyUV(0, {src}) on the same faces")
    if dst == 0:
        st.geometry = g.with_uvs(uv.copy())
    else:
        sets[dst] = uv.copy()
    st.context[UV_SETS_KEY] = (g.corners, sets)


# ---- rectify -----------------------------------------------------------------------------------


def _groups(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Connected components of ``n`` items joined by the pairs ``(i[k], j[k])``: a label each."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _group_mean(values: np.ndarray, labels: np.ndarray) -> np.ndarray:
    _, inv = np.unique(labels, return_inverse=True)
    return (np.bincount(inv, values) / np.bincount(inv))[inv]


def rectified_mesh(mesh: Mesh, scope: Scope, max_angle: float) -> Mesh:
    """``mesh`` with every edge that deviates less than ``max_angle`` degrees from a scope axis,
    seen in the scope plane the shape is most parallel to, made parallel to that axis."""
    local = scope.to_local(mesh.vertices)
    newell = mesh._newell() @ scope.rotation  # area-weighted normals in the scope frame
    total = newell.sum(axis=0)
    if np.linalg.norm(total) < 0.5 * np.linalg.norm(newell, axis=1).sum():
        raise CGARuntimeError("rectify: the faces point in different directions (a volume?); "
                              "rectify a lot, a facade or a roof plane instead")
    c = int(np.argmax(np.abs(total)))
    a, b = (c + 1) % 3, (c + 2) % 3
    # weld coincident corners so that neighbouring faces move together
    weld = weld_ids(local)
    corners = weld[mesh.corners]
    i, j = corners, corners[mesh.next_corners()]
    pts = np.zeros((weld.max() + 1, 3))
    pts[weld] = local
    d = pts[j] - pts[i]
    angle = np.degrees(np.arctan2(np.abs(d[:, b]), np.abs(d[:, a])))  # 0: along a, 90: along b
    moving = np.linalg.norm(d[:, [a, b]], axis=1) > EPS
    along_a = moving & (angle < max_angle)
    along_b = moving & (90 - angle < max_angle)
    out = pts.copy()
    out[:, b] = _group_mean(pts[:, b], _groups(len(pts), i[along_a], j[along_a]))
    out[:, a] = _group_mean(pts[:, a], _groups(len(pts), i[along_b], j[along_b]))
    moved = local + out[weld] - pts[weld]
    return mesh.with_vertices(scope.to_world(_back_onto_planes(mesh, local, moved, c)))


def _back_onto_planes(mesh: Mesh, local: np.ndarray, moved: np.ndarray, c: int) -> np.ndarray:
    """Moved vertices lifted along scope axis ``c`` back onto their face's original plane (the
    first face using a vertex decides), so that slanted faces stay planar."""
    normals = mesh.face_normals()
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    owner = np.full(len(local), -1)
    owner[mesh.corners[::-1]] = face_of[::-1]
    used = owner >= 0
    n = normals[owner[used]]
    p0 = local[mesh.corners[mesh.starts[:-1]]][owner[used]]
    ok = np.abs(n[:, c]) > 1e-6
    q = moved[used]
    rest = np.einsum("ij,ij->i", n, p0 - q) + n[:, c] * q[:, c]
    q[ok, c] = rest[ok] / n[ok, c]
    out = moved.copy()
    out[used] = q
    return out


@operation("rectify", 1)
def op_rectify(call):
    """``rectify(angle)``: edges deviating less than ``angle`` degrees (0-45) from a scope axis are
    made parallel to it, in the scope plane (xy, yz or zx) the shape is most parallel to
    (https://doc.arcgis.com/en/cityengine/latest/cga/cga-rectify-operation.htm).

    How: corners joined by an edge to be made parallel to axis a take the mean of their other
    coordinate, chains of such edges moving together (an edge 2.9 degrees off in a 10.0 / 10.4 m
    trapezoid becomes the side of a 10.2 m rectangle); each corner then goes back onto its face's
    plane along the third axis.  Coincident corners of neighbouring faces move together.  Like
    CityEngine's, it refuses volumes (faces pointing every way) and may, on odd shapes, create
    self-intersections; the scope keeps its orientation and is fitted to the result.
    """
    st = call.state
    max_angle = call.num(0)
    if not 0 <= max_angle <= 45:
        raise CGARuntimeError(f"rectify: angle must be in [0, 45] degrees, got {max_angle:g}")
    if not st.geometry.n_faces or max_angle == 0:
        return
    st.geometry = rectified_mesh(st.geometry, st.scope, max_angle)
    st.fit_scope()
