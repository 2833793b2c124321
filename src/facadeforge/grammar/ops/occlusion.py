"""Occlusion queries ``inside()``, ``overlaps()``, ``touches()``.

As in CityEngine, a shape that is split into components (``comp``, ``split``) on a closed volume
leaves an *occluder*: its volume; so does a leaf shape whose geometry is closed (a roof, a
tree).  An ``intra`` query tests the current shape's geometry against the occluders of the same
building that are not its own ancestors; an ``inter`` query against the occluders of the
neighbouring buildings, which ``engine.derive`` finds by deriving every initial shape once
before the real derivation (as CityEngine's procedural runtime generates occluders first);
``all``, the default, against both.
"""

from __future__ import annotations

import numpy as np

from ...geometry.mesh import EPS, Mesh
from ..values import CGARuntimeError, to_str
from . import shape_function

TOUCH_TOL = 1e-3


class Occluder:
    __slots__ = ("id", "mesh", "bounds", "planes", "convex", "label", "_triangles")

    def __init__(self, oid: int, mesh: Mesh, label: str = ""):
        self.id = oid
        self.mesh = mesh
        self.bounds = mesh.bounds()
        self.label = label
        n = mesh.face_normals()
        d = np.einsum("ij,ij->i", n, mesh.vertices[mesh.corners[mesh.starts[:-1]]])
        self.planes = (n, d)
        # convex when every vertex lies behind every face plane
        self.convex = bool(np.all(mesh.vertices @ n.T - d <= 1e-6))
        self._triangles = None  # ray-casting data, made on the first non-convex query

    def contains(self, pts: np.ndarray, strict: bool) -> np.ndarray:
        """(N,) whether points are inside (strictly, or within the touch tolerance)."""
        lo, hi = self.bounds
        tol = -TOUCH_TOL if strict else TOUCH_TOL
        inbox = np.all((pts >= lo - tol) & (pts <= hi + tol), axis=1)
        if not inbox.any():
            return inbox
        if self.convex:
            n, d = self.planes
            return inbox & np.all(pts @ n.T - d <= tol, axis=1)
        if self._triangles is None:
            self._triangles = _ray_triangles(self.mesh)
        out = np.zeros(len(pts), bool)
        out[inbox] = _ray_inside(self._triangles, pts[inbox], strict)
        return out


class OccluderSet:
    """Occluders in the order they were added, with their bounding boxes stacked so that a
    query finds the few whose boxes can matter in one vectorised test (a facade of a thousand
    tiles queries a thousand occluders per tile otherwise)."""

    def __init__(self, items=()):
        self.items: list[Occluder] = []
        self._lo = np.empty((16, 3))
        self._hi = np.empty((16, 3))
        for o in items:
            self.append(o)

    def append(self, occ: Occluder) -> None:
        k = len(self.items)
        if k == len(self._lo):
            self._lo = np.concatenate([self._lo, np.empty_like(self._lo)])
            self._hi = np.concatenate([self._hi, np.empty_like(self._hi)])
        self._lo[k], self._hi[k] = occ.bounds
        self.items.append(occ)

    def __len__(self) -> int:
        return len(self.items)

    def __iter__(self):
        return iter(self.items)

    def near(self, lo: np.ndarray, hi: np.ndarray, *, enclosing: bool = False) -> list[Occluder]:
        """Occluders whose box comes within the touch tolerance of the box ``lo``–``hi``; with
        ``enclosing``, only those whose box holds it (the only ones that can hold the shape)."""
        n = len(self.items)
        if not n:
            return []
        olo, ohi = self._lo[:n], self._hi[:n]
        if enclosing:
            ok = np.all((olo <= lo + TOUCH_TOL) & (ohi >= hi - TOUCH_TOL), axis=1)
        else:
            ok = np.all((olo <= hi + TOUCH_TOL) & (ohi >= lo - TOUCH_TOL), axis=1)
        return [self.items[i] for i in np.flatnonzero(ok)]


#: Ray direction of the inside test: slightly off the axes, so that rays along a building's
#: walls do not graze the edges between its triangles (which would break the even-odd count)
_RAY = np.linalg.qr(np.array([[1.0, 0.0012345, 0.0023456], [0, 1, 0], [0, 0, 1]]).T)[0].T


def _ray_triangles(mesh: Mesh):
    """The mesh's triangles in the ray frame (:data:`_RAY`), with what the crossing test needs:
    corner ``a``, edges ``v0``, ``v1``, and the determinant across the ray (``ok`` where the
    triangle is not edge-on to the ray)."""
    pos, _, _, _ = mesh.triangulate()
    tri = (pos @ _RAY.T).reshape(-1, 3, 3)
    a = tri[:, 0]
    v0, v1 = tri[:, 1] - a, tri[:, 2] - a
    den = v0[:, 1] * v1[:, 2] - v0[:, 2] * v1[:, 1]
    ok = np.abs(den) > EPS
    return a, v0, v1, np.where(ok, den, 1.0), ok


def _ray_inside(triangles, pts: np.ndarray, strict: bool) -> np.ndarray:
    """Even-odd ray casting along :data:`_RAY`'s first axis against :func:`_ray_triangles`:
    per point, the triangles the ray crosses beyond it, all points against all triangles at once
    (in blocks, to bound memory)."""
    a, v0, v1, safe, ok = triangles
    q = pts @ _RAY.T
    out = np.zeros(len(pts), bool)
    margin = TOUCH_TOL if strict else -TOUCH_TOL
    step = max(1, 200_000 // max(len(a), 1))
    for k in range(0, len(q), step):
        # barycentric coordinates in the plane across the ray, then the crossing beyond p
        w = q[k:k + step, None, :] - a[None]
        s = (w[..., 1] * v1[:, 2] - w[..., 2] * v1[:, 1]) / safe
        t = (v0[:, 1] * w[..., 2] - v0[:, 2] * w[..., 1]) / safe
        hit = ok & (s >= 0) & (t >= 0) & (s + t <= 1)
        x = a[:, 0] + s * v0[:, 0] + t * v1[:, 0]
        out[k:k + step] = np.count_nonzero(hit & (x > q[k:k + step, :1] + margin), axis=1) % 2 == 1
    return out


def _candidates(env, args, pts: np.ndarray, enclosing: bool = False):
    """Occluders a query about the points ``pts`` tests: ``intra`` those of this building that
    are not the shape's own ancestors, ``inter`` those of the neighbouring buildings, ``all``
    (the default) both; only those whose boxes reach the points' box (hold it, ``enclosing``)."""
    mode = to_str(args[0]) if args else "all"
    if mode not in ("intra", "inter", "all"):
        raise CGARuntimeError(f"occlusion target '{mode}' is not intra, inter or all")
    label = to_str(args[1]) if len(args) > 1 else None
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    occ = []
    if mode != "inter":
        own = env.state.context.get("occluder_ancestors", ())
        occ = [o for o in env.derivation.occluders.near(lo, hi, enclosing=enclosing)
               if o.id not in own]
    if mode != "intra":
        occ.extend(env.derivation.neighbours.near(lo, hi, enclosing=enclosing))
    if label:
        occ = [o for o in occ if o.label == label]
    return occ


def _centroids(mesh: Mesh) -> np.ndarray:
    """(F, 3) mean corner of each face."""
    return np.add.reduceat(mesh.vertices[mesh.corners], mesh.starts[:-1], axis=0) \
        / mesh.face_sizes[:, None]


def _sample(mesh: Mesh) -> np.ndarray:
    """Vertices plus face centroids: enough to tell inside from partly inside."""
    if not mesh.n_faces:
        return np.zeros((0, 3))
    return np.concatenate([mesh.used_vertices(), _centroids(mesh)])


def _geometry(env):
    g = env.state.geometry
    if g.n_faces:
        return g
    sc = env.state.scope  # scope-only shapes are queried with their scope box centre
    return Mesh.from_polygons([sc.corners()[[0, 1, 3, 2]]])


@shape_function("inside")
def _inside(env, args):
    pts = _sample(_geometry(env))
    if not len(pts):
        return False
    return any(bool(np.all(o.contains(pts, strict=False)))
               for o in _candidates(env, args, pts, enclosing=True))


@shape_function("overlaps")
def _overlaps(env, args):
    pts = _sample(_geometry(env))
    if not len(pts):
        return False
    return any(bool(np.any(o.contains(pts, strict=True))) for o in _candidates(env, args, pts))


def _face_interior(mesh: Mesh) -> np.ndarray:
    """Face centroids and the corners pulled a tenth of the way towards them: points that lie on
    an occluder's surface only when a face touches it over an area, not along an edge."""
    cent = _centroids(mesh)
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    inner = mesh.vertices[mesh.corners] * 0.9 + cent[face_of] * 0.1
    return np.concatenate([cent, inner])


@shape_function("touches")
def _touches(env, args):
    """Overlap, or contact over an area (CityEngine: "overlaps or has planar contact"): a
    tile meeting a neighbour only along its edge does not touch it."""
    g = _geometry(env)
    pts = _sample(g)
    if not len(pts):
        return False
    interior = _face_interior(g)
    return any(np.any(o.contains(pts, strict=True)) or np.any(o.contains(interior, strict=False))
               for o in _candidates(env, args, pts))
