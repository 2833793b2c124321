"""Faces with holes, kept as pieces.

Meshes here hold simple polygons only.  CityEngine's face with holes (a courtyard footprint, an
``offset`` border, a Boolean cut through a slab) is stored as coplanar pieces that share an id in
the face column ``holed`` (see ``geometry.mesh.FACE_COLUMNS``).  These helpers find such groups
and turn them back into one planar polygon with holes for the operations that need the whole face
(roofs, ``offset``, ``setback``), and make the ids of the pieces they build.
"""

from __future__ import annotations

import itertools

import numpy as np

from .mesh import EPS, Mesh

HOLED = "holed"
_IDS = itertools.count()


def fresh_ids(keys) -> list:
    """New ids, one per distinct hashable key (``None`` stays None): unique in the process, so
    faces stay apart when meshes are merged."""
    ids: dict = {}
    return [None if k is None else ids.setdefault(k, next(_IDS)) for k in keys]


def face_groups(mesh: Mesh, faces=None) -> list[list[int]]:
    """The faces (``faces``, default all) as CityEngine's faces: the pieces of one face with
    holes together, in order of their first piece; every other face alone."""
    col = mesh.column(HOLED)
    faces = range(mesh.n_faces) if faces is None else faces
    if col is None:
        return [[int(f)] for f in faces]
    groups, at = [], {}
    for f in faces:
        key = col[f]
        if key is None:
            groups.append([int(f)])
        elif key in at:
            at[key].append(int(f))
        else:
            at[key] = [int(f)]
            groups.append(at[key])
    return groups


def plane_polygon(mesh: Mesh, faces, origin: np.ndarray, basis: np.ndarray):
    """The union of ``faces`` (coplanar pieces) in the plane frame (``origin``, ``basis``
    columns u, v): a shapely Polygon or MultiPolygon with its holes."""
    import shapely

    parts = []
    for f in faces:
        xy = (mesh.vertices[mesh.face(f)] - origin) @ basis[:, :2]
        p = shapely.Polygon(xy)
        if p.area > EPS:
            parts.append(p if p.is_valid else p.buffer(0))
    if not parts:
        return shapely.Polygon()
    return shapely.union_all(parts).buffer(0)


def rings(polygon) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """``(outer, holes)`` of each polygon of a shapely geometry: outer counter-clockwise, holes
    clockwise, without the closing point."""
    out = []
    for g in getattr(polygon, "geoms", [polygon]):
        if g.geom_type != "Polygon" or g.area <= EPS:
            continue
        outer = np.asarray(g.exterior.coords)[:-1]
        if not g.exterior.is_ccw:
            outer = outer[::-1]
        holes = []
        for r in g.interiors:
            h = np.asarray(r.coords)[:-1]
            holes.append(h[::-1] if r.is_ccw else h)
        out.append((outer, holes))
    return out
