"""CityEngine trim planes: made by ``comp(f)``, applied by ``i()``, the primitives and ``trim()``.

References (CityEngine CGA reference):

* trim operation — https://doc.arcgis.com/en/cityengine/latest/cga/cga-trim.htm
* trim attribute — https://doc.arcgis.com/en/cityengine/latest/cga/cga-trim-attribute.htm
* insert operation, note on trim planes — https://doc.arcgis.com/en/cityengine/latest/cga/cga-i.htm

``comp(f)`` gives every new shape one trim plane per edge its face(s) share with another face of
the split geometry: the plane through that edge bisecting the angle between the two faces, so
that geometry inserted on two neighbouring faces meets cleanly (at 45° on a box corner).  A
plane is *vertical* when its edge makes 40° or more with the xz-plane of the new shape's pivot
(the face frame: x along the face's first edge, z along its normal), else *horizontal*;
``trim.vertical`` (default true) and ``trim.horizontal`` (default false) switch the two kinds on
and off for a shape and its successors.  Successors (split pieces, inserted assets…) inherit the
planes; they stay where ``comp`` put them in world space.

Where the reference is silent, this runtime does what a CityEngine user expects:

* every edge shared by exactly two faces makes a plane, closed volume or not (the reference's
  examples trim the faces of an open hip roof); edges of three or more faces make none;
* a new ``comp(f)`` replaces the inherited planes with its own (``comp(e|v)`` keeps them);
* planes are unbounded; cutting removes the part beyond the plane without capping the cut
  (the mitred faces of neighbouring pieces meet there);
* ``=`` groups get planes only at edges shared with faces outside the group.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...geometry.cut import _clip_slab, _convex_faces, clip_convex_faces
from ...geometry.mesh import EPS, Mesh, cross3, plane_basis, ranges_index, weld_ids
from ..values import CGARuntimeError, to_bool, type_name
from . import operation, shape_function

#: sin(40°): an edge at least this steep against the pivot's xz-plane makes a vertical plane
_VERTICAL_SIN = math.sin(math.radians(40.0))


class MeshEdges:
    """Which face shares each face edge of a mesh, computed once per ``comp(f)`` and only when
    a successor asks for its planes (most never insert anything)."""

    def __init__(self, mesh: Mesh):
        self.mesh = mesh
        self._partner = None
        self._frame = None

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(face normals, next corner of each corner, face of each corner)``, once per mesh:
        every component of the ``comp`` reads them."""
        if self._frame is None:
            m = self.mesh
            self._frame = (m.face_normals(), m.next_corners(),
                           np.repeat(np.arange(m.n_faces), m.face_sizes))
        return self._frame

    def partner(self) -> np.ndarray:
        """(C,) the corner of the other face on the same edge, -1 for border and non-manifold
        edges (corner ``c`` stands for the edge from its vertex to the next corner's)."""
        if self._partner is None:
            self._partner = _edge_partners(self.mesh)
        return self._partner


def _edge_partners(mesh: Mesh) -> np.ndarray:
    w = weld_ids(mesh.vertices)[mesh.corners]
    pairs = np.sort(np.stack([w, w[mesh.next_corners()]], axis=1), axis=1)
    _, edge, count = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    edge = edge.reshape(-1)
    partner = np.full(len(w), -1, np.int64)
    two = (count[edge] == 2) & (pairs[:, 0] != pairs[:, 1])
    order = np.flatnonzero(two)[np.argsort(edge[two], kind="stable")]
    a, b = order[0::2], order[1::2]
    partner[a], partner[b] = b, a
    return partner


class FacePlanes:
    """The trim planes of one ``comp(f)`` successor: faces ``faces`` of ``edges.mesh``,
    classified against the pivot's y axis ``up``.  Computed on first use, then shared by every
    descendant."""

    def __init__(self, edges: MeshEdges, faces, up: np.ndarray):
        self.edges = edges
        self.faces = faces
        self.up = up
        self._planes = None
        self._active = {}

    def planes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(origins (N, 3), normals (N, 3), vertical (N,) bool)``; a point ``p`` is kept
        when ``(p - origin) · normal >= 0``."""
        if self._planes is None:
            self._planes = _bisecting_planes(self.edges, self.faces, self.up)
        return self._planes

    def active(self, horizontal: bool, vertical: bool):
        """``(normals, offsets)`` of the planes switched on (a point ``p`` is kept when
        ``normal · p >= offset``), or ``None`` when there are none; cached per switch setting."""
        key = (horizontal, vertical)
        if key not in self._active:
            origins, normals, is_vertical = self.planes()
            on = (is_vertical & vertical) | (~is_vertical & horizontal)
            self._active[key] = ((normals[on], np.einsum("pk,pk->p", origins[on], normals[on]))
                                 if on.any() else None)
        return self._active[key]


def _bisecting_planes(edges: MeshEdges, faces, up: np.ndarray):
    mesh = edges.mesh
    partner = edges.partner()
    normals, nxt, face_of = edges.frame()
    faces = np.asarray(faces, np.int64)
    # the components' own corners only: a comp of F faces must not cost F × F
    c = np.concatenate([np.arange(mesh.starts[f], mesh.starts[f + 1]) for f in faces])
    c = c[partner[c] >= 0]
    c = c[~np.isin(face_of[partner[c]], faces)]
    a = mesh.vertices[mesh.corners[c]]
    e = _unit(mesh.vertices[mesh.corners[nxt[c]]] - a)
    p = partner[c]
    e_other = _unit(mesh.vertices[mesh.corners[nxt[p]]] - mesh.vertices[mesh.corners[p]])
    # inward directions of both faces, perpendicular to the edge: their difference is the normal
    # of the plane through the edge that halves the angle between the faces
    m = cross3(normals[face_of[c]], e) - cross3(normals[face_of[p]], e_other)
    length = np.linalg.norm(m, axis=1)
    ok = length > 1e-6
    m = m[ok] / length[ok, None]
    vertical = np.abs(e[ok] @ up) >= _VERTICAL_SIN - 1e-9
    return a[ok], m, vertical


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), EPS)


@dataclass(frozen=True)
class TrimState:
    """What ``ShapeState.trim`` holds: the inherited planes and the two ``trim.*`` switches.
    Immutable, so states share it freely (``None`` in a state means the default)."""

    planes: FacePlanes | None = None
    horizontal: bool = False
    vertical: bool = True

    def active(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Normals and offsets of the planes switched on, or ``None`` when there are none."""
        if self.planes is None or not (self.horizontal or self.vertical):
            return None
        return self.planes.active(self.horizontal, self.vertical)


_DEFAULT = TrimState()


def comp_trim(state, edges: MeshEdges, faces, scope) -> TrimState:
    """Trim state of a ``comp(f)`` successor made of ``faces`` with pivot ``scope``."""
    old = state.trim or _DEFAULT
    return TrimState(FacePlanes(edges, faces, scope.rotation[:, 1]), old.horizontal, old.vertical)


# ---- applying planes -----------------------------------------------------------------------

def trim_mesh(mesh: Mesh, normals: np.ndarray, offsets: np.ndarray) -> tuple[Mesh, np.ndarray]:
    """Cut away what lies beyond each plane (keep ``normal · p >= offset``); returns the mesh
    and, per new face, the face it came from.  Faces wholly on the kept side are kept as they
    are (no copy when none is cut)."""
    source = np.arange(mesh.n_faces)
    for n, c in zip(normals, offsets):  # bounded: one pass per plane
        if not mesh.n_faces:
            break
        mesh, kept_from = _cut(mesh, n * c, n)
        source = source[kept_from]
    return mesh, source


def _cut(mesh: Mesh, origin: np.ndarray, normal: np.ndarray) -> tuple[Mesh, np.ndarray]:
    d = ((mesh.vertices - origin) @ normal)[mesh.corners]
    lo = np.minimum.reduceat(d, mesh.starts[:-1])
    hi = np.maximum.reduceat(d, mesh.starts[:-1])
    keep = lo >= -EPS
    crossing = np.flatnonzero(~keep & (hi > EPS))
    if keep.all():
        return mesh, np.arange(mesh.n_faces)
    kept = np.flatnonzero(keep)
    if not len(crossing):
        return mesh.subset(kept), kept
    frame = plane_basis(normal)  # columns: two in-plane axes, then the normal
    local = (mesh.vertices - origin) @ frame
    normals = mesh.face_normals()
    convex = _convex_faces(mesh, normals)
    if convex[crossing].all():  # the usual case: every cut face clipped at once
        sizes = mesh.starts[crossing + 1] - mesh.starts[crossing]
        idx = ranges_index(mesh.starts[crossing], sizes)
        q, quv, starts, left = clip_convex_faces(
            local[mesh.corners[idx]], None if mesh.corner_uvs is None else mesh.corner_uvs[idx],
            np.concatenate([[0], np.cumsum(sizes)]), 2, 0.0, False)
        src = crossing[left]
        cut = Mesh(q @ frame.T + origin, corners=np.arange(len(q)), starts=starts,
                   corner_uvs=quv).inherit(mesh, src) if len(src) else Mesh()
        return Mesh.merge([mesh.subset(kept), cut]), np.concatenate([kept, src]).astype(np.int64)
    big = float(d.max()) + 1.0
    polys, uvs, src = [], [], []
    for f in crossing:
        c0, c1 = mesh.starts[f], mesh.starts[f + 1]
        uv = None if mesh.corner_uvs is None else mesh.corner_uvs[c0:c1]
        for q, quv in _clip_slab(local[mesh.corners[c0:c1]], uv, 2, 0.0, big,
                                 normals[f] @ frame, convex[f]):
            polys.append(q @ frame.T + origin)
            uvs.append(quv)
            src.append(f)
    cut = Mesh.from_polygons(polys, uvs if mesh.corner_uvs is not None else None).inherit(mesh, src)
    return Mesh.merge([mesh.subset(kept), cut]), np.concatenate([kept, src]).astype(np.int64)


def apply_trim(st, fitted: bool = False) -> bool:
    """Cut the shape's geometry at its active trim planes (``i()``, primitives, ``trim()``);
    the faces' data (materials, tags, ``offset`` kinds) follows them.  True if anything was cut.
    ``fitted``: the geometry was just fitted to the scope box, so planes clear of the box are
    skipped without looking at the vertices."""
    trim = st.trim
    active = trim.active() if trim is not None else None
    mesh = st.geometry
    if active is None or not mesh.n_faces:
        return False
    if fitted:
        local, at_origin = _in_scope_frame(*active, st.scope)
        reaching = _nearest(local, at_origin, st.scope.size, np.zeros(3)) < EPS
        if not reaching.any():
            return False
        active = (active[0][reaching], active[1][reaching])
    out, _ = trim_mesh(mesh, *active)
    if out is mesh:
        return False
    st.geometry = out
    return True


@operation("trim", 0, 0)
def op_trim(call):
    """``trim()``: apply the shape's active trim planes to its geometry (CityEngine "trim
    operation", https://doc.arcgis.com/en/cityengine/latest/cga/cga-trim.htm).  The scope is
    kept; without planes (no ``comp(f)`` above) the geometry stays as it is."""
    apply_trim(call.state)


# ---- the trim attribute --------------------------------------------------------------------

def set_trim(st, key: str, value) -> None:
    """``set(trim.horizontal|vertical, bool)`` for the shape and its successors (CityEngine
    "trim attribute", https://doc.arcgis.com/en/cityengine/latest/cga/cga-trim-attribute.htm)."""
    if key not in ("horizontal", "vertical"):
        raise CGARuntimeError(f"set: 'trim.{key}' is not a trim attribute; use trim.horizontal "
                              "or trim.vertical")
    if not isinstance(value, (bool, int, float)):
        raise CGARuntimeError(f"set(trim.{key}, …) takes true or false, not a {type_name(value)}")
    st.trim = replace(st.trim or _DEFAULT, **{key: to_bool(value)})


@shape_function("trim.horizontal")
def _trim_horizontal(env, args):
    return (env.state.trim or _DEFAULT).horizontal


@shape_function("trim.vertical")
def _trim_vertical(env, args):
    return (env.state.trim or _DEFAULT).vertical


# ---- instancing ----------------------------------------------------------------------------

#: per inserted asset name, how far it reaches along each axis when fitted to a flat scope:
#: its extent there over the smallest other extent (bounded by the rules' asset names)
_PROPORTIONS: dict[str, np.ndarray] = {}


_NOTED: dict[str, bytes] = {}  # per asset name, the bounds last noted (the usual repeat is free)


def note_asset(name: str, bounds: np.ndarray) -> None:
    """Remember the proportions of an asset ``i()`` inserts (for :func:`trim_key`)."""
    key = bounds.tobytes()
    if _NOTED.get(name) == key:
        return
    _NOTED[name] = key
    ext = np.maximum(bounds[1] - bounds[0], 0.0)
    ratio = np.ones(3)
    for k in range(3):
        others = [ext[j] for j in range(3) if j != k and ext[j] > EPS]
        ratio[k] = ext[k] / min(others) if others else 1.0
    # one name may be different files (another rule package, another asset folder): keep the
    # largest reach seen, so an instancing key never misses a plane an asset could reach
    known = _PROPORTIONS.get(name)
    _PROPORTIONS[name] = ratio if known is None else np.maximum(known, ratio)


def _reach(size: np.ndarray, assets, far: bool) -> np.ndarray:
    """How far (per axis) a subtree's inserted geometry may stick out of a scope box with one or
    two zero sizes.  CityEngine fits a zero size to the mean of the others times the asset's
    proportion; with known assets and only operations that stay in the box that bounds it,
    otherwise the mean of the other sizes (at least 1 m) stands in."""
    sx, sy, sz = size.tolist()  # three numbers: plain floats are faster than arrays here
    flat = (sx < 1e-6, sy < 1e-6, sz < 1e-6)
    if all(flat):
        return np.full(3, 1e6)  # a point scope: assets keep their own size
    if not any(flat):
        return np.zeros(3)
    kept = [v for v, f in zip((sx, sy, sz), flat) if not f]
    mean = sum(kept) / len(kept)
    known = [_PROPORTIONS.get(a) for a in assets]
    if far or not known or any(r is None for r in known):
        fill = max(mean, 1.0)
        return np.array([fill if f else 0.0 for f in flat])
    most = np.max(known, axis=0) if len(known) > 1 else known[0]
    return np.array([mean * most[k] if f else 0.0 for k, f in enumerate(flat)])


def trim_key(state, assets=(), far: bool = True) -> tuple:
    """The part of an instancing cache key that trim planes decide: the active planes that may
    cut what the subtree inserts (those reaching the scope box grown by :func:`_reach`), in
    the scope frame.  Planes farther away leave the key, so tiles away from a corner still share
    one recording.  ``assets`` and ``far`` come from the subtree's analysis (instancing.py)."""
    trim = state.trim
    active = trim.active() if trim is not None else None
    if active is None:
        return ()
    sc = state.scope
    local, at_origin = _in_scope_frame(*active, sc)
    near = _nearest(local, at_origin, sc.size, _reach(sc.size, assets, far)) < 1e-6
    if not near.any():
        return ()
    return ((np.round(local[near], 9) + 0.0).tobytes(),  # -0.0 is 0.0 (not as bytes)
            (np.round(at_origin[near], 6) + 0.0).tobytes())


def _in_scope_frame(normals: np.ndarray, offsets: np.ndarray, scope):
    """Plane normals in the scope frame and the signed distance of the scope origin."""
    return normals @ scope.rotation, normals @ scope.origin - offsets


def _nearest(local: np.ndarray, at_origin: np.ndarray, size: np.ndarray, reach: np.ndarray):
    """Per plane, the smallest signed distance over the scope box grown by ``reach`` per axis
    (negative: part of the box lies on the cut side)."""
    return at_origin + (np.minimum(local * size, 0.0) - np.abs(local) * reach).sum(axis=1)
