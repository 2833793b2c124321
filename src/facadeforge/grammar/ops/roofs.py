"""Roof operations on the straight skeleton: ``roofHip roofGable roofPyramid roofShed``."""

from __future__ import annotations

import math

import numpy as np

from ...geometry.holed import HOLED, face_groups, fresh_ids, outline, plane_polygon, rings
from ...geometry.mesh import EPS, Mesh, plane_basis, polygon_normal
from ..values import CGARuntimeError
from . import operation
from .tagging import auto_tag, faces_from_edges


def _roof(call, builder, holes_ok: bool = False):
    """Roof volume on every face: the roof planes (and gable/shed walls) plus the original face
    as the bottom, as CityEngine builds it; the scope's y follows the first face normal.  Faces
    keep their face's data and are auto-tagged ``roof.bottom``, ``roof.top`` (the planes) and
    ``roof.side`` (gable walls; ``roof.side.outer`` for the other roofs' walls).

    ``builder(xy, basis, normal, holes)`` gets each counter-clockwise face in its plane frame
    (``basis`` columns u, v, normal), with its holes (clockwise rings; a face with holes is pieces
    sharing an id, see ``geometry.holed``), and returns roof faces as (k, 3) arrays of (u, v,
    height).  Builders that cannot take holes (``holes_ok`` False) get none: a face with holes
    is then an error naming the roofs that can."""
    from .geometry import align_scope_y

    st = call.state
    mesh = st.geometry
    if not mesh.n_faces:
        return
    first_normal = mesh.face_normals()[0]
    polys, source, parts, keys, from_edge = [], [], [], [], []
    side = "side" if call.name == "roofGable" else "side.outer"
    holed = mesh.column(HOLED)
    for group in face_groups(mesh):
        f = group[0]
        p = mesh.vertices[mesh.face(f)]
        n = polygon_normal(p)
        if not n.any():
            continue
        basis = plane_basis(n, p[1] - p[0])
        if len(group) == 1:
            outlines = [((p - p[0]) @ basis[:, :2], [])]
        else:
            # the outer ring starts where the face's outline does (comp(fe) order), so edge
            # indices (roofShed's, roofGable's) count as for the face itself
            start = (outline(mesh, group)[0] - p[0]) @ basis[:, :2]
            outlines = [(np.roll(xy, -int(np.argmin(np.linalg.norm(xy - start, axis=1))),
                                 axis=0), holes)
                        for xy, holes in rings(plane_polygon(mesh, group, p[0], basis))]
        # the roof faces, the face edge each rises from, their kinds and the key of the face
        # with holes a piece belongs to (a shed plane round a courtyard is pieces of one face)
        roofs, rose_from, kinds, piece_of = [], [], [], []
        for xy, holes in outlines:
            x, y = xy[:, 0], xy[:, 1]
            if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) <= EPS:
                continue
            if holes and not holes_ok:
                raise CGARuntimeError(f"{call.name}: the face has holes (a courtyard); roofHip, "
                                      "roofGable and roofShed roof faces with holes, or "
                                      "deleteHoles() first")
            try:
                built = builder(xy, basis, n, holes)
            except ValueError as e:
                raise CGARuntimeError(f"{call.name}: {e}") from None
            faces = getattr(built, "faces", built)
            roofs.extend(faces)
            kinds.extend(getattr(built, "kind", None) or [""] * len(faces))
            outline_no = len(roofs)  # tells this outline's faces with holes from the next's
            piece_of.extend(None if k is None else (f, outline_no, k)
                            for k in getattr(built, "pieces", None) or [None] * len(faces))
            edges = getattr(built, "edge_index", None)
            single = len(group) == 1 and edges is not None and len(edges) == len(faces)
            rose_from.extend(int(mesh.starts[f]) + int(e) if single and 0 <= e < len(xy) else -1
                             for e in (edges if single else [-1] * len(faces)))
        if not roofs:
            continue
        for g in group:  # the bottom: the face itself, turned over
            polys.append(mesh.vertices[mesh.face(g)][::-1])
            parts.append("bottom")
            source.append(g)
            keys.append(None if holed is None else holed[g])
            from_edge.append(-1)
        from_edge.extend(rose_from)
        for q, kind, key in zip(roofs, kinds, piece_of):
            q = np.asarray(q, float)
            polys.append(p[0] + q[:, :2] @ basis[:, :2].T + np.outer(q[:, 2], n))
            # a wall (gable, the shed's high side) stands upright on the face; planes slope
            upright = abs(polygon_normal(polys[-1]) @ n) < 1e-6
            parts.append(("side.inner" if kind == "side.inner" else side) if upright else "top")
            source.append(f)
            keys.append(key)
    out = Mesh.from_polygons(polys).inherit(mesh, source, drop=("kind", HOLED))
    if holed is not None or any(k is not None for k in keys):
        out = out.with_column(HOLED, fresh_ids(keys))
    out = faces_from_edges(out, mesh, from_edge)  # a roof plane rises from its eave's edge
    st.geometry = auto_tag(out, "roof", parts)
    align_scope_y(st, first_normal)
    st.fit_scope()


def _angle(call, k=0):
    a = call.num(k)
    if not 0 < a < 90:
        raise CGARuntimeError(f"{call.name}: the roof angle must be between 0 and 90 degrees, not {a}")
    return a


def _slope(call):
    """The roof slope arguments: ``(angle, height, k)``, ``k`` the index of the next argument.

    ``roofX(angle, …)`` and ``roofX(byAngle, angle, …)`` give an angle, ``roofX(byHeight,
    height, …)`` a height (CityEngine's ``valueType``)."""
    first = call.args[0] if call.args else None
    if not isinstance(first, str):
        return _angle(call), None, 1
    if first == "byAngle":
        return _angle(call, 1), None, 2
    if first != "byHeight":
        raise CGARuntimeError(f"{call.name}: the first argument is an angle, byAngle or byHeight, "
                              f"not '{first}'")
    h = call.num(1)
    if h <= 0:
        raise CGARuntimeError(f"{call.name}: the roof height must be positive, not {h}")
    return None, h, 2


def _sloped(angle, height, make):
    """``make(angle)`` → roof builder.  Given a ``height`` (``byHeight``), each face's roof gets
    the angle that puts its highest point at that height: roof heights grow with tan(angle), so
    the angle follows from a 45° trial roof (overhangs included, which hang below the eaves)."""
    if height is None:
        return make(angle)

    def build(xy, basis, n, holes):
        trial = make(45.0)(xy, basis, n, holes)
        top = max((float(np.max(np.asarray(f)[:, 2])) for f in getattr(trial, "faces", trial)),
                  default=0.0)
        if top <= EPS:
            raise ValueError("the face gives the roof nothing to rise over")
        return make(math.degrees(math.atan(height / top)))(xy, basis, n, holes)
    return build


@operation("roofHip", 1, 4, selectors=(0,))
def op_roof_hip(call):
    """``roofHip([byAngle|byHeight,] value[, overhang[, even]])``."""
    from ...geometry.roofs import roof_hip

    angle, height, k = _slope(call)
    overhang = call.num(k, 0.0)
    _roof(call, _sloped(angle, height, lambda a: lambda xy, basis, n, holes: roof_hip(
        xy, a, overhang, holes=holes)), holes_ok=True)


@operation("roofGable", 1, 6, selectors=(0,))
def op_roof_gable(call):
    """``roofGable([byAngle|byHeight,] value[, overhangX[, overhangY[, even[, index]]]])``:
    ``index`` makes that edge's side and the side opposite it the gables."""
    from ...geometry.roofs import roof_gable

    angle, height, k = _slope(call)
    ox = call.num(k, 0.0)
    oy = call.num(k + 1, ox)  # CityEngine: the y overhang defaults to the x overhang
    even = bool(call.args[k + 2]) if len(call.args) > k + 2 else False
    index = int(call.num(k + 3)) if len(call.args) > k + 3 else None
    _roof(call, _sloped(angle, height, lambda a: lambda xy, basis, n, holes: roof_gable(
        xy, a, ox, oy, even, index=index, holes=holes)), holes_ok=True)


@operation("roofPyramid", 1, 2, selectors=(0,))
def op_roof_pyramid(call):
    """``roofPyramid([byAngle|byHeight,] value)``."""
    from ...geometry.roofs import roof_pyramid

    angle, height, _ = _slope(call)
    _roof(call, _sloped(angle, height, lambda a: lambda xy, basis, n, holes: roof_pyramid(xy, a)))


@operation("roofShed", 1, 3, selectors=(0,))
def op_roof_shed(call):
    """``roofShed([byAngle|byHeight,] value[, index])``: the plane rises from edge ``index``."""
    from ...geometry.roofs import roof_shed

    angle, height, k = _slope(call)
    edge = int(call.num(k, 0.0))
    _roof(call, _sloped(angle, height, lambda a: lambda xy, basis, n, holes: roof_shed(
        xy, a, edge, holes=holes)), holes_ok=True)
