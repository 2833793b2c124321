"""Scope and geometry transformations: ``t s r center rotateScope align… mirror translate``."""

from __future__ import annotations

import math

import numpy as np

from ...geometry.mesh import EPS, cross3
from ..values import CGARuntimeError, Relative
from . import operation


def _vec(call, start: int, size: np.ndarray) -> np.ndarray:
    return np.array([call.size(start + k, float(size[k])) for k in range(3)])


@operation("t", 3)
def op_t(call):
    """Translate the scope (and geometry) along the scope axes; ``'`` is relative to the size."""
    st = call.state
    d = st.scope.rotation @ _vec(call, 0, st.scope.size)
    st.own_scope().origin = st.scope.origin + d
    if st.geometry.n_faces:
        st.geometry = st.geometry.with_vertices(st.geometry.vertices + d)


@operation("s", 3)
def op_s(call):
    """Set the scope size; the geometry is scaled with it, anchored at the scope origin."""
    st = call.state
    old = st.scope.size.copy()
    new = _vec(call, 0, old)
    if np.any(new < 0):
        new = np.abs(new)
    if st.geometry.n_faces:
        factor = np.where(old > EPS, new / np.where(old > EPS, old, 1.0), 1.0)
        local = st.scope.to_local(st.geometry.vertices) * factor
        st.geometry = st.geometry.with_vertices(st.scope.to_world(local))
    st.own_scope().size = new


def mirrored(rot: np.ndarray) -> bool:
    """Whether a scope rotation is a mirror (negative determinant; ``mirrorScope``)."""
    (a, b, c), (d, e, f), (g, h, i) = rot.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) < 0


def rotation_xyz(angles_deg) -> np.ndarray:
    """Rotation matrix of successive rotations about x, then y, then z (degrees)."""
    ax, ay, az = (math.radians(float(a)) for a in angles_deg)
    cx, sx, cy, sy, cz, sz = (math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay),
                              math.cos(az), math.sin(az))
    return np.array([[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
                     [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
                     [-sy, cy * sx, cy * cx]])  # Rz @ Ry @ Rx


def turned(call, angles, frame: str = "pivot", mode: str = "rel") -> np.ndarray:
    """The scope rotation after adding ``angles`` (degrees, CityEngine's x-then-y-then-z order)
    to the scope's angles in ``frame`` (``rel``), or setting them (``abs``).  CityEngine keeps
    ``scope.r`` as angles in the pivot's frame and ``r()`` "adds the given angles to
    scope.r": ``r(90, 0, 0) r(0, 45, 0)`` is ``r(90, 45, 0)``, not a turn about the turned
    axes.  The current angles are read back from the rotation (:func:`euler_xyz_deg`)."""
    from .scoping import euler_xyz_deg, pivot_frame

    st = call.state
    if frame == "scope":
        f = st.scope.rotation
    elif frame == "world":
        f = np.eye(3)
    elif frame == "object":
        f = call.derivation.object_scope.rotation
    elif frame == "pivot":
        f = pivot_frame(st, call.derivation)[1]
    else:
        raise CGARuntimeError(f"unknown coordinate system '{frame}'; use scope, pivot, object or "
                              "world")
    a = np.asarray(angles, float)
    if frame == "scope":  # the scope's own axes: a mirrored scope stays mirrored
        return f @ rotation_xyz(a)
    # angles describe a proper rotation: a mirrored scope (mirrorScope) is read and rebuilt
    # through its z flip, so it stays mirrored and r(0, 0, 0) changes nothing
    flip = _Z_FLIP if mirrored(st.scope.rotation) else _SAME
    current = euler_xyz_deg(f.T @ st.scope.rotation @ flip)
    return f @ rotation_xyz(current + a if mode == "rel" else a) @ flip


_Z_FLIP = np.diag([1.0, 1.0, -1.0])
_SAME = np.eye(3)


def _turn(st, new_rotation: np.ndarray, centre: np.ndarray) -> None:
    """Scope and geometry turned about ``centre`` so that the scope gets ``new_rotation``."""
    world_rot = new_rotation @ st.scope.rotation.T
    st.own_scope().rotation = new_rotation
    st.own_scope().origin = (st.scope.origin - centre) @ world_rot.T + centre
    if st.geometry.n_faces:
        st.geometry = st.geometry.with_vertices((st.geometry.vertices - centre) @ world_rot.T
                                                + centre)


@operation("r", 3, 4, selectors=(0,))
def op_r(call):
    """``r([scopeOrigin|scopeCenter,] x, y, z)``: add the angles to the scope's rotation in the
    pivot's frame (``rotate(rel, pivot, …)``), turning scope and geometry about the scope origin
    or centre."""
    st = call.state
    pivot_mode = "scopeOrigin"
    args = call.args
    if len(args) == 4:
        pivot_mode = str(args[0])
        angles = [call.num(k) for k in (1, 2, 3)]
    else:
        angles = [call.num(k) for k in range(3)]
    centre = st.scope.center if pivot_mode == "scopeCenter" else st.scope.origin.copy()
    _turn(st, turned(call, angles), centre)


@operation("rotateScope", 3)
def op_rotate_scope(call):
    """Add the angles to the scope's rotation in the pivot's frame (as ``r``), the geometry
    staying where it is and the scope refitted around it."""
    st = call.state
    st.own_scope().rotation = turned(call, [call.num(k) for k in range(3)])
    if st.geometry.n_faces:
        st.fit_scope()


@operation("center", 1, 1, selectors=(0,))
def op_center(call):
    """Move the scope so its centre matches the predecessor's scope centre on the given axes."""
    st = call.state
    axes = call.sel(0)
    ref = st.pivot if st.pivot is not None else st.scope
    ref_center_local = st.scope.to_local(ref.center[None])[0]
    my_center_local = st.scope.size / 2
    delta = np.zeros(3)
    for k, a in enumerate("xyz"):
        if a in axes:
            delta[k] = ref_center_local[k] - my_center_local[k]
    d = st.scope.rotation @ delta
    st.own_scope().origin = st.scope.origin + d
    if st.geometry.n_faces:
        st.geometry = st.geometry.with_vertices(st.geometry.vertices + d)


@operation("alignScopeToAxes", 0, 1, selectors=(0,))
def op_align_scope_to_axes(call):
    st = call.state
    axis = call.sel(0, "xyz")
    if axis in ("y", "world.y"):
        # keep the scope's x direction projected onto the ground, y up
        x = st.scope.rotation[:, 0].copy()
        x[1] = 0
        if np.linalg.norm(x) < EPS:
            x = np.array([1.0, 0, 0])
        x /= np.linalg.norm(x)
        st.own_scope().rotation = np.column_stack([x, [0, 1, 0], cross3(x, np.array([0.0, 1.0, 0.0]))])
    else:
        st.own_scope().rotation = np.eye(3)
    if st.geometry.n_faces:
        st.fit_scope()


@operation("alignScopeToGeometry", 1, 3, selectors=(0, 1, 2))
def op_align_scope_to_geometry(call):
    """Scope axis ``upAxis`` along the normal of face ``faceIndex`` (an index, ``largest``,
    ``world.lowest``/``world.highest`` — the face with the lowest/highest centre —, or ``any``:
    the face holding the selected edge), x along edge ``edgeIndex`` (an index, ``longest``,
    ``shortest``, ``world.lowest`` — the bottom edge, as Esri's facade rules use it —,
    ``world.highest`` or ``any``)."""
    st = call.state
    mesh = st.geometry
    if not mesh.n_faces:
        return
    up = call.sel(0, "zUp")
    fsel = call.args[1] if len(call.args) > 1 else 0
    esel = call.args[2] if len(call.args) > 2 else 0
    normals = mesh.face_normals()
    areas = mesh.face_areas()
    def edge_of(poly: np.ndarray) -> tuple[int, float]:
        """The selected edge of a face and a score for choosing among faces (lower wins)."""
        nxt = np.roll(poly, -1, axis=0)
        lengths = np.linalg.norm(nxt - poly, axis=1)
        mid_y = np.round((poly[:, 1] + nxt[:, 1]) / 2, 9)
        if not isinstance(esel, str):
            return int(esel) % len(poly), 0.0
        # edges of no length (repeated corners) are never chosen by a keyword
        real = np.flatnonzero(lengths > EPS)
        if not len(real):
            return 0, 0.0
        lengths, mid_y = lengths[real], mid_y[real]
        if esel == "longest":
            e = int(np.argmax(lengths))
            return int(real[e]), -float(lengths[e])
        if esel == "shortest":
            e = int(np.argmin(lengths))
            return int(real[e]), float(lengths[e])
        if esel in ("world.lowest", "lowest"):         # the bottom edge (the longest of ties)
            e = int(np.lexsort((-lengths, mid_y))[0])
            return int(real[e]), float(mid_y[e])
        if esel in ("world.highest", "highest"):
            e = int(np.lexsort((-lengths, -mid_y))[0])
            return int(real[e]), -float(mid_y[e])
        return int(real[0]), 0.0                       # "any": the first edge

    faces = [mesh.vertices[mesh.face(i)] for i in range(mesh.n_faces)]
    if fsel == "any" and isinstance(esel, str) and esel != "any":
        f = min(range(len(faces)), key=lambda i: (edge_of(faces[i])[1], i))  # the extremal edge's face
    elif fsel == "largest":
        f = int(np.argmax(areas))
    elif fsel in ("world.lowest", "world.highest"):
        cy = np.array([p[:, 1].mean() for p in faces])
        f = int(np.argmin(cy) if fsel == "world.lowest" else np.argmax(cy))
    elif isinstance(fsel, str):
        f = 0
    else:
        f = int(fsel) % mesh.n_faces
    poly = faces[f]
    k = len(poly)
    e = edge_of(poly)[0]
    n = normals[f]
    x = poly[(e + 1) % k] - poly[e]
    x = x - n * (x @ n)
    if np.linalg.norm(x) < EPS:
        raise CGARuntimeError("alignScopeToGeometry: degenerate edge")
    x /= np.linalg.norm(x)
    if up in ("yUp", "world.y"):
        rot = np.column_stack([x, n, cross3(x, n)])
    else:
        rot = np.column_stack([x, cross3(n, x), n])
    st.own_scope().rotation = rot
    st.own_scope().origin = poly[e].copy()
    st.fit_scope()
    # the pivot takes the new axes, its origin at the new scope's (reference)
    from .scoping import set_pivot_frame

    set_pivot_frame(st, st.scope.origin, st.scope.rotation)


@operation("mirror", 3)
def op_mirror(call):
    """Mirror the geometry inside the scope along the axes whose flag is true."""
    st = call.state
    flags = [bool(call.args[k]) for k in range(3)]
    if not st.geometry.n_faces or not any(flags):
        return
    local = st.scope.to_local(st.geometry.vertices)
    for k, f in enumerate(flags):
        if f:
            local[:, k] = st.scope.size[k] - local[:, k]
    mirrored = st.geometry.with_vertices(st.scope.to_world(local))
    st.geometry = mirrored.reversed() if sum(flags) % 2 else mirrored


@operation("translate", 5, selectors=(0, 1))
def op_translate(call):
    """``translate(rel|abs, scope|world|object, x, y, z)``."""
    st = call.state
    mode, frame = call.sel(0), call.sel(1)
    v = np.array([call.num(k) for k in (2, 3, 4)])
    if frame == "world":
        d = v
    elif frame == "object":
        d = call.derivation.object_scope.rotation @ v
    else:
        d = st.scope.rotation @ v
    if mode == "abs":
        if frame == "scope":
            raise CGARuntimeError("translate(abs, scope, …) is not meaningful; use rel")
        target = v if frame == "world" else call.derivation.object_scope.to_world(v[None])[0]
        d = target - st.scope.origin
    st.own_scope().origin = st.scope.origin + d
    if st.geometry.n_faces:
        st.geometry = st.geometry.with_vertices(st.geometry.vertices + d)


@operation("rotate", 5, selectors=(0, 1))
def op_rotate(call):
    """``rotate(rel|abs, scope|pivot|object|world, x, y, z)`` about the scope origin: the angles
    are added to (``rel``) or replace (``abs``) the scope's angles in that frame."""
    st = call.state
    mode, frame = call.sel(0), call.sel(1)
    if mode not in ("rel", "abs"):
        raise CGARuntimeError(f"rotate: the mode is rel or abs, not '{mode}'")
    if mode == "abs" and frame == "scope":
        raise CGARuntimeError("rotate(abs, scope, …) is not meaningful; use rel")
    angles = [call.num(k) for k in (2, 3, 4)]
    _turn(st, turned(call, angles, frame, mode), st.scope.origin.copy())


__all__ = ["Relative", "rotation_xyz"]
