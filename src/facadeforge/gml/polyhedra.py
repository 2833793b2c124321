"""Convex polyhedra as CityFit's GML uses them (Hohmann et al. 2009, §5).

A convex polyhedron is the intersection of half-spaces; a half-space is a directed plane
whose *interior* is ``normal · x ≤ offset`` (the normal points outward).  ``cp-plane`` rounds its
three points to 16.16 fixed point (``round(x · 65536) / 65536``, about 1/65 mm), as CityFit does
with all its data.

A polyhedron is kept as its faces (each a polygon counter-clockwise around its outward normal,
with that face's plane) and is built and split by clipping: start from a large box and cut it by
each plane in turn (each face polygon is clipped, the points on the cutting plane make the new
face).  That is exact up to rounding, needs no enumeration of plane triples and keeps the faces
ordered.  A shell whose planes do not enclose a bounded region is an error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.mesh import Mesh

FIXED = 65536.0
#: Half the side of the largest box a shell is clipped from; a vertex on it means "not bounded"
#: (beyond the models' ±1e9 m, :data:`facadeforge.model.model.MAX_COORDINATE`).
BIG = 4.0e9
EPS = 1.0e-9


def fixed(x) -> np.ndarray:
    """Round coordinates to 16.16 fixed point."""
    return np.round(np.asarray(x, float) * FIXED) / FIXED


@dataclass(frozen=True, eq=False)
class Plane:
    """A directed plane: interior ``normal · x ≤ offset``, ``normal`` of unit length."""

    normal: np.ndarray
    offset: float
    gml_type = "plane"

    @staticmethod
    def from_points(p1, p2, p3) -> Plane | None:
        """The plane through three points (16.16 fixed point), normal ``(p2-p1) × (p3-p1)``:
        seen from outside, the points run counter-clockwise.  ``None`` when they are collinear."""
        a, b, c = fixed(p1), fixed(p2), fixed(p3)
        n = np.cross(b - a, c - a)
        length = float(np.linalg.norm(n))
        if not math.isfinite(length) or length < 1e-12:
            return None
        n = n / length
        return Plane(n, float(n @ a))

    @staticmethod
    def through(point, normal) -> Plane:
        n = np.asarray(normal, float)
        n = n / np.linalg.norm(n)
        return Plane(n, float(n @ np.asarray(point, float)))

    def flipped(self) -> Plane:
        return Plane(-self.normal, -self.offset)

    def distance(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points, float) @ self.normal - self.offset

    def __repr__(self) -> str:
        n = ",".join(f"{v:.4g}" for v in self.normal)
        return f"Plane(n=({n}), d={self.offset:.4g})"


class Polyhedron:
    """A convex polyhedron: ``faces`` is a list of ``(polygon (k, 3), Plane)``; empty when it has
    no volume."""

    gml_type = "convex polyhedron"
    __slots__ = ("faces",)

    def __init__(self, faces: list[tuple[np.ndarray, Plane]]):
        self.faces = faces

    # -- construction ----------------------------------------------------------------------------
    @staticmethod
    def box(lo, hi) -> Polyhedron:
        """The axis-aligned box between corners ``lo`` and ``hi``."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        return Polyhedron.frame_box(lo, np.eye(3), hi - lo)

    @staticmethod
    def frame_box(origin, rotation, size) -> Polyhedron:
        """The box of an oriented scope: ``origin``, axes the columns of ``rotation``, ``size``."""
        o, r, s = np.asarray(origin, float), np.asarray(rotation, float), np.asarray(size, float)
        unit = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
        c = (unit * s) @ r.T + o  # index = 4i + 2j + k
        quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                 (1, 5, 7, 3)]
        normals = [-r[:, 0], r[:, 0], -r[:, 1], r[:, 1], -r[:, 2], r[:, 2]]
        faces = []
        for q, n in zip(quads, normals):
            poly = c[list(q)]
            faces.append((poly, Plane(n, float(n @ poly[0]))))
        return Polyhedron(faces)

    @staticmethod
    def shell(planes: list[Plane]) -> Polyhedron:
        """The intersection of the planes' interiors.  ``ValueError`` when it is unbounded.

        Clipping starts from a box a few times larger than the planes' distances from the
        origin (small, so rounding stays small) and grows it while the result touches it."""
        big = max(1e3, 10 * max((abs(p.offset) for p in planes), default=0.0))
        while True:
            p = Polyhedron.box((-big,) * 3, (big,) * 3)
            for plane in planes:
                p = p.clip(plane)
                if p.empty:
                    return p
            if np.abs(p.vertices()).max() < big * (1 - 1e-9):
                return p
            if big >= BIG:
                raise ValueError("the planes do not enclose a bounded region (a side is open)")
            big = min(big * 1e3, BIG)

    # -- queries ---------------------------------------------------------------------------------
    @property
    def empty(self) -> bool:
        return not self.faces

    def vertices(self) -> np.ndarray:
        """The distinct vertices (V, 3), merged in 16.16 fixed point."""
        if not self.faces:
            return np.zeros((0, 3))
        pts = np.concatenate([f for f, _ in self.faces])
        _, first = np.unique(np.round(pts * FIXED).astype(np.int64), axis=0, return_index=True)
        return pts[np.sort(first)]

    def volume(self) -> float:
        if not self.faces:
            return 0.0
        ref = self.faces[0][0][0]
        vol = 0.0
        for poly, _ in self.faces:
            a = poly[0] - ref
            for k in range(1, len(poly) - 1):
                vol += float(np.dot(a, np.cross(poly[k] - ref, poly[k + 1] - ref)))
        return vol / 6.0

    def is_convex(self, tol: float = 1e-6) -> bool:
        """Every vertex inside or on every face plane, every face planar."""
        v = self.vertices()
        return all(plane.distance(v).max() <= tol and np.abs(plane.distance(poly)).max() <= tol
                   for poly, plane in self.faces)

    def bounds_in(self, origin, rotation) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box of the vertices in a frame (``rotation`` columns are its axes)."""
        local = (self.vertices() - np.asarray(origin, float)) @ np.asarray(rotation, float)
        return local.min(axis=0), local.max(axis=0)

    # -- operations ------------------------------------------------------------------------------
    def clip(self, plane: Plane) -> Polyhedron:
        """The part inside ``plane`` (``normal · x ≤ offset``)."""
        if not self.faces:
            return self
        eps = EPS * max(1.0, abs(plane.offset))
        dist = [plane.distance(poly) for poly, _ in self.faces]
        hi = max(float(d.max()) for d in dist)
        lo = min(float(d.min()) for d in dist)
        if hi <= eps:
            return self
        if lo >= -eps:
            return Polyhedron([])
        faces = []
        cap: list[np.ndarray] = []
        for (poly, fplane), d in zip(self.faces, dist):
            out = []
            k = len(poly)
            for i in range(k):
                a, b = poly[i], poly[(i + 1) % k]
                da, db = d[i], d[(i + 1) % k]
                if da <= eps:
                    out.append(a)
                    if da >= -eps:
                        cap.append(a)
                if (da < -eps and db > eps) or (da > eps and db < -eps):
                    t = da / (da - db)
                    x = a + (b - a) * t
                    out.append(x)
                    cap.append(x)
            poly2 = _dedupe_ring(out)
            if len(poly2) >= 3:
                faces.append((poly2, fplane))
        pts = _unique_points(cap)
        if len(pts) >= 3:
            faces.append((_order_ccw(pts, plane.normal), plane))
        result = Polyhedron(faces)
        if len(faces) < 4 or result.volume() <= 1e-12:
            return Polyhedron([])
        return result

    def split(self, plane: Plane) -> tuple[Polyhedron, Polyhedron]:
        """(inside, outside) of ``plane``: two convex polyhedra, either possibly empty."""
        return self.clip(plane), self.clip(plane.flipped())

    def transformed(self, matrix, offset) -> Polyhedron:
        """``x → matrix @ x + offset`` (an affine map with positive determinant)."""
        m, t = np.asarray(matrix, float), np.asarray(offset, float)
        faces = []
        for poly, _ in self.faces:
            p = poly @ m.T + t
            n = _newell(p)
            length = float(np.linalg.norm(n))
            if length < 1e-15:
                return Polyhedron([])
            n = n / length
            faces.append((p, Plane(n, float(n @ p.mean(axis=0)))))
        return Polyhedron(faces)

    def to_mesh(self) -> Mesh:
        """One polygon per face, vertices shared (merged in 16.16 fixed point)."""
        if not self.faces:
            return Mesh()
        verts = self.vertices()
        keys = {tuple(k): i for i, k in enumerate(np.round(verts * FIXED).astype(np.int64))}
        faces = []
        for poly, _ in self.faces:
            idx = [keys[tuple(k)] for k in np.round(poly * FIXED).astype(np.int64)]
            ring = [i for j, i in enumerate(idx) if i != idx[j - 1]]
            if len(ring) >= 3:
                faces.append(ring)
        return Mesh(verts, faces)

    def __repr__(self) -> str:
        return f"Polyhedron({len(self.faces)} faces, volume {self.volume():.4g})"


def _newell(p: np.ndarray) -> np.ndarray:
    q = np.roll(p, -1, axis=0)
    return np.array([np.sum((p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2])),
                     np.sum((p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0])),
                     np.sum((p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1]))])


def _dedupe_ring(points: list[np.ndarray], tol: float = 1e-9) -> np.ndarray:
    out: list[np.ndarray] = []
    for p in points:
        if not out or np.abs(p - out[-1]).max() > tol * max(1.0, np.abs(p).max()):
            out.append(p)
    if len(out) > 1 and np.abs(out[0] - out[-1]).max() <= tol * max(1.0, np.abs(out[0]).max()):
        out.pop()
    return np.array(out) if out else np.zeros((0, 3))


def _unique_points(points: list[np.ndarray], tol: float = 1e-7) -> np.ndarray:
    out: list[np.ndarray] = []
    for p in points:
        if all(np.abs(p - q).max() > tol * max(1.0, np.abs(p).max()) for q in out):
            out.append(p)
    return np.array(out) if out else np.zeros((0, 3))


def _order_ccw(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Points of a convex polygon, counter-clockwise around ``normal``; collinear ones dropped."""
    c = points.mean(axis=0)
    u = points[np.argmax(np.linalg.norm(points - c, axis=1))] - c
    u = u / np.linalg.norm(u)
    v = np.cross(normal, u)
    ang = np.arctan2((points - c) @ v, (points - c) @ u)
    ring = points[np.argsort(ang)]
    # drop points on a straight edge (they come from edges cut exactly at a vertex)
    keep = []
    k = len(ring)
    for i in range(k):
        a, b, d = ring[i - 1], ring[i], ring[(i + 1) % k]
        if np.linalg.norm(np.cross(b - a, d - b)) > 1e-12 * max(1.0, np.abs(b).max()) ** 2:
            keep.append(b)
    return np.array(keep) if len(keep) >= 3 else ring
