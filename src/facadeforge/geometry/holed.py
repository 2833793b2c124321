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

from .mesh import EPS, Mesh, plane_basis, weld_ids
from .polygon import ring_points

HOLED = "holed"
_IDS = itertools.count()


def fresh_ids(keys) -> list:
    """New ids, one per distinct hashable key (``None`` stays None): unique in the process, so
    faces stay apart when meshes are merged."""
    ids: dict = {}
    return [None if k is None else ids.setdefault(k, next(_IDS)) for k in keys]


def face_groups(mesh: Mesh, faces=None) -> list[list[int]]:
    """The faces (``faces``, default all) as CityEngine's faces: the pieces of one face with
    holes together, in order of their first piece; every other face alone.  Pieces sharing an
    id but not an edge (the two strips a split leaves of a courtyard block's face) are apart."""
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
    out = []
    for g in groups:
        out.extend(connected_faces(mesh, g) if len(g) > 1 else [g])
    return out


def connected_faces(mesh: Mesh, faces: list[int]) -> list[list[int]]:
    """``faces`` in groups joined through shared edges (coincident vertices welded), each in
    face order, the groups in order of their first face."""
    corners = np.concatenate([np.arange(mesh.starts[f], mesh.starts[f + 1]) for f in faces])
    owner = np.repeat(np.arange(len(faces)), [mesh.starts[f + 1] - mesh.starts[f] for f in faces])
    w = weld_ids(mesh.vertices[mesh.corners[corners]])
    nxt = np.arange(1, len(corners) + 1)
    ends = np.cumsum([mesh.starts[f + 1] - mesh.starts[f] for f in faces])
    nxt[ends - 1] = ends - np.diff(np.concatenate([[0], ends]))
    key = np.sort(np.stack([w, w[nxt]], axis=1), axis=1)
    parent = list(range(len(faces)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    seen: dict = {}
    for k, o in zip(map(tuple, key.tolist()), owner.tolist()):
        if k[0] == k[1]:
            continue
        other = seen.setdefault(k, o)
        if other != o:
            a, b = root(other), root(o)
            if a != b:
                parent[max(a, b)] = min(a, b)
    comps: dict = {}
    for i, f in enumerate(faces):
        comps.setdefault(root(i), []).append(f)
    return list(comps.values())


def connected_parts(mesh: Mesh, parts: list) -> list[list[int]]:
    """The ``parts`` (lists of face indices) joined where a face of one shares an edge with a
    face of another (``=:``): groups of part indices, each in order, the groups in order of
    their first part.  A part is never split, even when its own faces do not touch (a
    material on two separate walls)."""
    owner: dict[int, int] = {}
    for k, p in enumerate(parts):
        for f in p:
            owner.setdefault(int(f), k)
    parent = list(range(len(parts)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for piece in connected_faces(mesh, list(owner)):
        first = root(owner[piece[0]])
        for f in piece[1:]:
            other = root(owner[f])
            if other != first:
                parent[max(first, other)] = min(first, other)
                first = min(first, other)
    groups: dict = {}
    for k in range(len(parts)):
        groups.setdefault(root(k), []).append(k)
    return list(groups.values())


def seams(mesh: Mesh, weld: np.ndarray) -> set:
    """The edges inside faces with holes (between two of their pieces): welded vertex pairs
    ``(min, max)`` of ``weld`` (per vertex), which ``comp(e)`` and tag queries do not see."""
    if mesh.column(HOLED) is None:
        return set()
    group_of = np.full(mesh.n_faces, -1, np.int64)
    for k, g in enumerate(face_groups(mesh)):
        if len(g) > 1:
            group_of[g] = k
    owners: dict = {}
    for f in np.flatnonzero(group_of >= 0):
        face = mesh.face(f)
        for a, b in zip(face, np.roll(face, -1)):
            key = (min(weld[a], weld[b]), max(weld[a], weld[b]))
            owners.setdefault(key, []).append(group_of[f])
    return {key for key, gs in owners.items() if len(gs) >= 2 and len(set(gs)) == 1}


def edge_corners(mesh: Mesh, weld: np.ndarray, inner: set | None = None) -> np.ndarray:
    """The corners whose edges ``comp(e)``, ``comp(fe)`` and tag queries list, in their order:
    each face's corners in turn, a face with holes (pieces) taking its place at its first piece
    as its rings (:func:`boundary_rings`), the edges between its pieces (``inner``, default
    :func:`seams`) left out.  ``weld`` is the welded id of each vertex."""
    n_c = len(mesh.corners)
    if inner is None:
        inner = seams(mesh, weld)
    w = weld[mesh.corners] if n_c else np.zeros(0, np.int64)
    nxt = mesh.next_corners() if n_c else np.zeros(0, np.int64)
    if not inner:
        return np.arange(n_c)
    keep = np.array([(min(a, b), max(a, b)) not in inner for a, b in zip(w, w[nxt])], bool)
    order = []
    for group in face_groups(mesh):
        if len(group) == 1:
            f = group[0]
            order.append(np.arange(mesh.starts[f], mesh.starts[f + 1]))
            continue
        corners = np.concatenate([np.arange(mesh.starts[f], mesh.starts[f + 1]) for f in group])
        rings_found = boundary_rings(mesh, group, corners[keep[corners]], w, nxt)
        order.append(np.concatenate(rings_found) if rings_found is not None
                     else corners[keep[corners]])
    return np.concatenate(order) if order else np.zeros(0, np.int64)


def boundary_rings(mesh: Mesh, faces, boundary: np.ndarray, w: np.ndarray, nxt: np.ndarray):
    """The ``boundary`` corners of the pieces ``faces`` of one face with holes as its rings,
    each a corner array with the face on the edges' left: the outline first, starting where
    :func:`outline` starts (so a face's first edge is its scope's x axis), then the holes by
    the distance of their nearest corner to that start, each starting at that corner (a
    footprint's courtyard ring, given from its corner nearest the lot's first, comes back as
    given).  ``None`` when the boundary is not such rings (two rings touching at a vertex)."""
    start_of: dict = {}
    for c in boundary:
        if w[c] == w[nxt[c]]:
            continue
        if w[c] in start_of:
            return None
        start_of[w[c]] = c
    loops, left = [], dict(start_of)
    while left:
        c = next(iter(left.values()))
        loop = []
        while w[c] in left:  # each step removes one entry: bounded
            del left[w[c]]
            loop.append(c)
            c = start_of.get(w[nxt[c]])
            if c is None:
                return None
        loops.append(np.array(loop, np.int64))
    normal = mesh.face_normals()[faces].sum(axis=0)
    pts = [mesh.vertices[mesh.corners[lp]] for lp in loops]
    areas = [float(np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0) @ normal) for p in pts]
    outer = [i for i, a in enumerate(areas) if a > 0]
    if len(outer) != 1:
        return None
    start = outline(mesh, faces)[0]
    o = outer[0]
    first = int(np.argmin(np.linalg.norm(pts[o] - start, axis=1)))
    # back to where the straight run of that first edge begins (pieces may leave corners on
    # a straight edge: a wall's bottom edge, split where a piece meets it, starts at its end)
    d = np.roll(pts[o], -1, axis=0) - pts[o]
    n = len(d)
    for _ in range(n - 1):
        a, b = d[(first - 1) % n], d[first]
        if np.linalg.norm(np.cross(a, b)) > 1e-9 * np.linalg.norm(a) * np.linalg.norm(b) \
                or a @ b <= 0:
            break
        first = (first - 1) % n
    out = [np.roll(loops[o], -first)]
    holes = []
    for i, (lp, p) in enumerate(zip(loops, pts)):
        if i != o:
            d = np.linalg.norm(p - start, axis=1)
            k = int(np.argmin(d))
            holes.append((float(d[k]), i, np.roll(lp, -k)))
    out.extend(h for *_, h in sorted(holes, key=lambda t: (t[0], t[1])))
    return out


def outline(mesh: Mesh, faces) -> np.ndarray:
    """The outer ring (k, 3) of the pieces ``faces`` of one face with holes, counter-clockwise
    about their normal, for its scope: a wall's starts with its bottom edge (as an extruded
    wall's does); another face's with the edge that runs along its first piece's first edge,
    else at the corner nearest that piece's first corner."""
    normals = mesh.face_normals()
    f = next((g for g in faces if normals[g].any()), None)
    if f is None:
        return mesh.vertices[mesh.face(faces[0])]
    p = mesh.vertices[mesh.face(f)]
    basis = plane_basis(normals[f], p[1] - p[0])
    found = rings(plane_polygon(mesh, faces, p[0], basis))
    if not found:
        return p
    ring = max(found, key=lambda r: abs(_area2(r[0])))[0]
    world = p[0] + ring @ basis[:, :2].T
    d = np.roll(world, -1, axis=0) - world
    length = np.linalg.norm(d, axis=1)
    if abs(normals[f][1]) < 0.99:  # a wall: its bottom edge first, as an extruded wall has
        level = np.flatnonzero(np.abs(d[:, 1]) <= 1e-9 * np.maximum(length, 1.0))
        if len(level):
            low = world[level, 1].min()
            bottom = level[world[level, 1] <= low + 1e-9]
            return np.roll(world, -int(bottom[np.argmax(length[bottom])]), axis=0)
    u = (p[1] - p[0]) / max(np.linalg.norm(p[1] - p[0]), EPS)
    along = np.flatnonzero((d @ u) > (1 - 1e-9) * np.maximum(length, EPS))
    near = np.linalg.norm(world - p[0], axis=1)
    start = int(along[np.argmin(near[along])]) if len(along) else int(np.argmin(near))
    return np.roll(world, -start, axis=0)


def _area2(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


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
        outer = ring_points(g.exterior)
        if not g.exterior.is_ccw:
            outer = outer[::-1]
        holes = []
        for r in g.interiors:
            h = ring_points(r)
            holes.append(h[::-1] if r.is_ccw else h)
        out.append((outer, holes))
    return out
