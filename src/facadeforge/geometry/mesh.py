"""Polygon meshes: the geometry carried by a ``Shape``.

A mesh is a vertex array and a list of simple planar polygons (counter-clockwise seen from the side
their normal points to), with optional per-corner texture coordinates.  CGA works on polygons, not
triangles: a facade stays one quad until a rule splits it, so faces are kept as polygons and
triangulated only for export and rendering.

Faces are stored flat (CSR): ``corners`` lists vertex indices face after face and ``starts`` (F+1)
marks where each face begins.  Transforming or merging a 10 000-face asset is then a handful of
numpy calls instead of a Python loop per face, which is what makes inserting assets cheap.

Per-face data travels with the faces: ``face_data`` maps a column name to an (F,) object array
(``None`` = unset).  The grammar keeps there what CityEngine stores on a geometry's faces: a face's
own material, its geometry tags, its OBJ group, which ``offset`` part it is and which face with
holes it is a piece of (see :data:`FACE_COLUMNS`); ``corner_data`` holds edge and vertex tags.  Selecting, merging, moving and reversing faces carry the columns; an
operation that builds new faces says which old face each came from (:meth:`Mesh.inherit`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

EPS = 1e-9  # geometric tolerance in metres: one place, used by every cut and classification

FACE_COLUMNS = {
    "material": "the face's own material (an asset's, an inline's or a Boolean operand's), "
                "under the shape's material attributes",
    "tags": "the face's geometry tags, a tuple of strings (CGA ``tag``, auto-tags)",
    "kind": "which part of an ``offset`` the face is: 'inside' or 'border'",
    "group": "the OBJ group (``g``/``o``) of an inserted asset's face, as (its rank in the "
             "file, its name) (``comp(g)``)",
    "holed": "the face with holes a piece belongs to: faces here are simple polygons, so "
             "CityEngine's face with holes (a courtyard footprint, an ``offset`` border) is pieces "
             "sharing one id, which ``comp(f)``, the roofs, ``offset`` and ``setback`` take as "
             "one face",
}


#: Per-corner columns and what they describe: ``edge`` columns the edge from the corner to the
#: next corner of its face, ``vertex`` columns the corner's vertex.
CORNER_COLUMNS = {"edge_tags": "edge", "vertex_tags": "vertex"}


def _column(values, n: int) -> np.ndarray:
    """An (n,) object array from a sequence (or ``None``: all unset)."""
    out = np.empty(n, dtype=object)
    if values is not None:
        out[:] = list(values) if not isinstance(values, np.ndarray) else values
    return out


def _take_column(column: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``column`` at ``index`` (-1: unset)."""
    new = index < 0
    out = column[np.where(new, 0, index)] if len(column) else _column(None, len(index))
    if new.any():
        out[new] = None
    return out


def _take(data: dict | None, index) -> dict | None:
    """Columns at ``index`` (-1: unset).  Columns are never changed in place once made: meshes
    share them."""
    if data is None:
        return None
    if isinstance(index, slice):
        return {k: v[index].copy() for k, v in data.items()}
    index = np.asarray(index, np.int64)
    return {k: _take_column(v, index) for k, v in data.items()}


def _set_column(data: dict | None, name: str, values, n: int) -> dict | None:
    out = dict(data or {})
    if values is None:
        out.pop(name, None)
    elif isinstance(values, np.ndarray) and values.dtype == object and len(values) == n:
        out[name] = values  # columns are never changed in place: shared as is
    else:
        out[name] = _column(values, n)
    return out or None


def _concat_columns(parts: list) -> dict | None:
    """Columns of meshes appended in order (``parts``: (columns or None, length) each); a mesh
    without a column gets unset values there."""
    names = sorted({k for data, _ in parts if data for k in data})
    if not names:
        return None
    return {k: np.concatenate([data[k] if data and k in data else _column(None, n)
                               for data, n in parts]) for k in names}


def corner_sources_anywhere(mesh: Mesh, parent: Mesh, tol: float = 1e-6) -> np.ndarray:
    """As :func:`_corner_sources`, but a corner may take the data of any parent corner (faces
    merged by a clean-up have edges of several parent faces): (2, C) vertex and edge sources,
    the edge source being a parent edge that starts where the corner's edge does and runs the
    same way."""
    out = np.full((2, len(mesh.corners)), -1, np.int64)
    if not len(mesh.corners) or not len(parent.corners):
        return out
    key = np.round(parent.vertices[parent.corners] / tol).astype(np.int64)
    at: dict = {}
    for c, k in enumerate(map(tuple, key.tolist())):
        at.setdefault(k, []).append(c)
    pnext = parent.next_corners()
    p = mesh.vertices[mesh.corners]
    r = p[mesh.next_corners()]
    for c, k in enumerate(map(tuple, np.round(p / tol).astype(np.int64).tolist())):
        cands = at.get(k, ())
        if not cands:
            continue
        out[0, c] = cands[0]
        d = r[c] - p[c]
        n = np.linalg.norm(d)
        for pc in cands:
            e = parent.vertices[parent.corners[pnext[pc]]] - parent.vertices[parent.corners[pc]]
            m = np.linalg.norm(e)
            if n > tol and m > tol and e @ d > (1 - 1e-9) * n * m:
                out[1, c] = pc
                break
    return out


def _corner_sources(mesh: Mesh, parent: Mesh, source: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """For each corner of ``mesh``, the corner of its face's source face in ``parent`` whose
    data it keeps (-1 none): for vertex columns the parent corner at the same place, for edge
    columns the parent edge the corner's edge lies on.  Returns (2, C): vertex and edge
    sources.  Every corner is tested against every corner of its source face at once."""
    n = len(mesh.corners)
    out = np.full((2, n), -1, np.int64)
    if not n:
        return out
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    src = np.asarray(source, np.int64)[face_of]
    cs = np.flatnonzero(src >= 0)
    if not len(cs):
        return out
    k = parent.face_sizes[src[cs]]
    c = np.repeat(cs, k)                                   # (P,) new corner of each pair
    first = np.repeat(np.cumsum(k) - k, k)
    pc = np.repeat(parent.starts[src[cs]], k) + np.arange(len(c)) - first  # its parent corner
    p = mesh.vertices[mesh.corners]
    q, r = p[c], p[mesh.next_corners()[c]]
    a = parent.vertices[parent.corners[pc]]
    d = parent.vertices[parent.corners[parent.next_corners()[pc]]] - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), tol * tol)
    at_vertex = np.abs(a - q).max(axis=1) <= tol
    tq = np.einsum("ij,ij->i", q - a, d) / dd
    tr = np.einsum("ij,ij->i", r - a, d) / dd
    on_edge = ((np.abs(a + tq[:, None] * d - q).max(axis=1) <= tol)
               & (np.abs(a + tr[:, None] * d - r).max(axis=1) <= tol)
               & (tq >= -tol) & (tq <= 1 + tol) & (tr >= -tol) & (tr <= 1 + tol))
    for row, hit in ((0, at_vertex), (1, on_edge)):
        hc, hp = c[hit], pc[hit]
        if len(hc):  # the first matching parent corner of each new corner
            _, at = np.unique(hc, return_index=True)
            out[row, hc[at]] = hp[at]
    return out

class Mesh:
    """Polygon mesh.

    Parameters
    ----------
    vertices : (V, 3) float
        World coordinates.
    faces : list of (k,) int arrays, optional
        Vertex indices of each polygon, counter-clockwise around its outward normal.
    uvs : list of (k, 2) float arrays or None, optional
        Texture coordinates per face corner (uv set 0).  Faces without UVs get zeros.
    corners, starts : (C,) int and (F + 1,) int, optional
        The flat form of ``faces`` (use instead of ``faces``).
    corner_uvs : (C, 2) float or None, optional
        The flat form of ``uvs``.
    """

    __slots__ = ("vertices", "corners", "starts", "corner_uvs", "closed", "face_data",
                 "corner_data", "_newell_cache")

    def __init__(self, vertices=None, faces: Sequence | None = None, uvs: Sequence | None = None,
                 *, corners=None, starts=None, corner_uvs=None, closed: bool | None = None,
                 face_data: dict | None = None, corner_data: dict | None = None):
        self.closed = closed  # cached topology: None = not yet known
        self._newell_cache = None  # (F, 3) Newell vectors, read-only, at the first need
        self.face_data = face_data or None  # column -> (F,) object array; see FACE_COLUMNS
        self.corner_data = corner_data or None  # column -> (C,) object array; CORNER_COLUMNS
        self.vertices = (np.zeros((0, 3)) if vertices is None
                         else np.asarray(vertices, dtype=float).reshape(-1, 3))
        if corners is not None:
            self.corners = np.asarray(corners, dtype=np.int64)
            self.starts = np.asarray(starts, dtype=np.int64)
            self.corner_uvs = None if corner_uvs is None else np.asarray(corner_uvs, float).reshape(-1, 2)
            return
        faces = [] if faces is None else [np.asarray(f, dtype=np.int64).reshape(-1) for f in faces]
        lengths = np.array([len(f) for f in faces], dtype=np.int64)
        self.starts = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        self.corners = np.concatenate(faces) if faces else np.zeros(0, np.int64)
        self.corner_uvs = None
        if uvs is not None and any(u is not None for u in uvs):
            self.corner_uvs = np.concatenate([
                np.zeros((n, 2)) if u is None else np.asarray(u, float).reshape(-1, 2)
                for u, n in zip(uvs, lengths)]) if faces else None

    # -- list views (convenient, not for hot paths) -----------------------------------------
    @property
    def faces(self) -> list[np.ndarray]:
        return np.split(self.corners, self.starts[1:-1]) if self.n_faces else []

    @property
    def uvs(self) -> list[np.ndarray | None]:
        if self.corner_uvs is None:
            return [None] * self.n_faces
        return np.split(self.corner_uvs, self.starts[1:-1]) if self.n_faces else []

    @property
    def n_faces(self) -> int:
        return len(self.starts) - 1

    @property
    def face_sizes(self) -> np.ndarray:
        return np.diff(self.starts)

    def face(self, i: int) -> np.ndarray:
        return self.corners[self.starts[i]:self.starts[i + 1]]

    # -- construction ------------------------------------------------------------------------
    @staticmethod
    def from_polygons(polygons: Iterable[np.ndarray], uvs: Sequence | None = None) -> Mesh:
        """Mesh with one face per polygon (each (k, 3)), vertices not shared (no face data: see
        :meth:`inherit`)."""
        polys = [np.asarray(p, float).reshape(-1, 3) for p in polygons]
        if not polys:
            return Mesh()
        lengths = np.array([len(p) for p in polys], np.int64)
        starts = np.concatenate([[0], np.cumsum(lengths)])
        cuv = None
        if uvs is not None and any(u is not None for u in uvs):
            cuv = np.concatenate([np.zeros((n, 2)) if u is None else np.asarray(u, float).reshape(-1, 2)
                                  for u, n in zip(uvs, lengths)])
        return Mesh(np.concatenate(polys), corners=np.arange(starts[-1]), starts=starts, corner_uvs=cuv)

    @staticmethod
    def merge(meshes: Iterable[Mesh]) -> Mesh:
        ms = [m for m in meshes if m.n_faces]
        if not ms:
            return Mesh()
        if len(ms) == 1:
            return ms[0].copy()
        voff = np.cumsum([0] + [len(m.vertices) for m in ms[:-1]])
        coff = np.cumsum([0] + [len(m.corners) for m in ms[:-1]])
        corners = np.concatenate([m.corners + o for m, o in zip(ms, voff)])
        starts = np.concatenate([[0]] + [m.starts[1:] + o for m, o in zip(ms, coff)])
        cuv = None
        if any(m.corner_uvs is not None for m in ms):
            cuv = np.concatenate([np.zeros((len(m.corners), 2)) if m.corner_uvs is None else m.corner_uvs
                                  for m in ms])
        return Mesh(np.concatenate([m.vertices for m in ms]), corners=corners, starts=starts,
                    corner_uvs=cuv,
                    face_data=_concat_columns([(m.face_data, m.n_faces) for m in ms]),
                    corner_data=_concat_columns([(m.corner_data, len(m.corners)) for m in ms]))

    def copy(self) -> Mesh:
        return Mesh(self.vertices.copy(), corners=self.corners.copy(), starts=self.starts.copy(),
                    corner_uvs=None if self.corner_uvs is None else self.corner_uvs.copy(),
                    closed=self.closed, face_data=_take(self.face_data, slice(None)),
                    corner_data=_take(self.corner_data, slice(None)))

    def _like(self, vertices=None, **changes) -> Mesh:
        """This mesh with some of its arrays replaced (the others shared)."""
        kw = dict(corners=self.corners, starts=self.starts, corner_uvs=self.corner_uvs,
                  closed=self.closed, face_data=self.face_data, corner_data=self.corner_data)
        kw.update(changes)
        return Mesh(self.vertices if vertices is None else vertices, **kw)

    # -- per-face and per-corner data ------------------------------------------------------------
    def column(self, name: str) -> np.ndarray | None:
        """The (F,) object array of face column ``name``, or None when no face has it."""
        return None if self.face_data is None else self.face_data.get(name)

    def corner_column(self, name: str) -> np.ndarray | None:
        """The (C,) object array of corner column ``name`` (see :data:`CORNER_COLUMNS`)."""
        return None if self.corner_data is None else self.corner_data.get(name)

    def with_column(self, name: str, values) -> Mesh:
        """Same mesh with face column ``name`` set to ``values`` (one per face; None drops it)."""
        return self._like(face_data=_set_column(self.face_data, name, values, self.n_faces))

    def with_corner_column(self, name: str, values) -> Mesh:
        """Same mesh with corner column ``name`` set (one value per corner; None drops it)."""
        return self._like(corner_data=_set_column(self.corner_data, name, values,
                                                  len(self.corners)))

    def without_columns(self, *names: str) -> Mesh:
        """Same mesh without the face columns ``names`` (itself when it has none of them)."""
        data = self.face_data
        if data is None or data.keys().isdisjoint(names):
            return self
        data = {k: v for k, v in data.items() if k not in names}
        return self._like(face_data=data or None)

    def inherit(self, parent: Mesh, source, drop: Iterable[str] = (), corner_source=None) -> Mesh:
        """This mesh with the data of ``parent``: face ``i`` takes that of parent face
        ``source[i]`` (-1: a new face, unset); face columns named in ``drop`` are not taken.

        Corner data (edge and vertex tags) follows ``corner_source`` when given: (2, C), per
        corner the parent corner whose vertex data and whose edge data it takes (-1 none).
        Else geometry decides: a corner takes the data of the source face's vertex it lies on,
        and its edge that of the source face's edge it lies on, so pieces of a cut face keep the
        tags of the edges they keep and new cut edges have none."""
        if parent.face_data is None and parent.corner_data is None:
            return self
        src = np.asarray(source, np.int64).reshape(-1)
        if len(src) != self.n_faces:
            raise ValueError(f"inherit: {len(src)} sources for {self.n_faces} faces")
        face_data = None
        if parent.face_data is not None:
            keep = {k: v for k, v in parent.face_data.items() if k not in drop}
            face_data = _take(keep, src) or None
        corner_data = None
        if parent.corner_data is not None:
            vsrc, esrc = (_corner_sources(self, parent, src) if corner_source is None
                          else np.asarray(corner_source, np.int64))
            corner_data = {k: _take_column(v, esrc if CORNER_COLUMNS.get(k) == "edge" else vsrc)
                           for k, v in parent.corner_data.items()}
        return self._like(face_data=face_data, corner_data=corner_data)

    def polygons(self) -> list[np.ndarray]:
        """Face corner positions, one (k, 3) array per face."""
        return [self.vertices[f] for f in self.faces]

    def subset(self, indices: Iterable[int]) -> Mesh:
        """The faces ``indices`` as a new mesh (vertices not shared)."""
        idx = np.asarray(list(indices), np.int64)
        if len(idx) == 0:
            return Mesh()
        lengths = self.face_sizes[idx]
        starts = np.concatenate([[0], np.cumsum(lengths)])
        # corner positions of the chosen faces without a loop: face start + offset within face
        sel = np.repeat(self.starts[idx] - starts[:-1], lengths) + np.arange(starts[-1])
        return Mesh(self.vertices[self.corners[sel]], corners=np.arange(len(sel)), starts=starts,
                    corner_uvs=None if self.corner_uvs is None else self.corner_uvs[sel],
                    face_data=_take(self.face_data, idx), corner_data=_take(self.corner_data, sel))

    def single_faces(self, indices: Iterable[int]) -> list[Mesh]:
        """The faces ``indices``, each as a mesh of its own (``subset([i])`` for each, made in
        one go)."""
        pos = self.vertices[self.corners]
        bounds = self.starts
        ranges: dict = {}
        out = []
        for f in np.asarray(indices, np.int64).tolist():
            a, b = int(bounds[f]), int(bounds[f + 1])
            k = b - a
            if k not in ranges:
                ranges[k] = (np.arange(k, dtype=np.int64), np.array([0, k], np.int64))
            corners, starts = ranges[k]
            out.append(Mesh(pos[a:b], corners=corners, starts=starts,
                            corner_uvs=None if self.corner_uvs is None else self.corner_uvs[a:b],
                            face_data=_take(self.face_data, [f]),
                            corner_data=_take(self.corner_data, slice(a, b))))
        return out

    def with_vertices(self, vertices: np.ndarray) -> Mesh:
        """Same faces on moved vertices (topology, hence closedness, is kept)."""
        return Mesh(vertices, corners=self.corners, starts=self.starts, corner_uvs=self.corner_uvs,
                    closed=self.closed, face_data=self.face_data, corner_data=self.corner_data)

    def with_uvs(self, corner_uvs: np.ndarray | None) -> Mesh:
        return Mesh(self.vertices, corners=self.corners, starts=self.starts, corner_uvs=corner_uvs,
                    closed=self.closed, face_data=self.face_data, corner_data=self.corner_data)

    def transformed(self, matrix: np.ndarray, offset: np.ndarray | None = None) -> Mesh:
        """Apply ``v @ matrix.T + offset``; faces are reversed when the map mirrors."""
        matrix = np.asarray(matrix, float)
        v = self.vertices @ matrix.T
        if offset is not None:
            v = v + offset
        m = self.with_vertices(v)
        return m.reversed() if np.linalg.det(matrix) < 0 else m

    def reversed(self) -> Mesh:
        """Every face with its corner order reversed (normals flipped); an edge's data stays
        with the edge, which now starts at the other end."""
        if not self.n_faces:
            return self.copy()
        sizes = self.face_sizes
        face_id = np.repeat(np.arange(self.n_faces), sizes)
        pos = np.arange(len(self.corners)) - self.starts[face_id]
        src = self.starts[face_id] + sizes[face_id] - 1 - pos
        corner_data = None
        if self.corner_data is not None:
            edge_src = self.starts[face_id] + (sizes[face_id] - 2 - pos) % sizes[face_id]
            corner_data = {k: v[edge_src if CORNER_COLUMNS.get(k) == "edge" else src]
                           for k, v in self.corner_data.items()}
        return self._like(corners=self.corners[src],
                          corner_uvs=None if self.corner_uvs is None else self.corner_uvs[src],
                          corner_data=corner_data)

    # -- measures ----------------------------------------------------------------------------
    @property
    def is_empty(self) -> bool:
        return self.n_faces == 0

    def _newell(self) -> np.ndarray:
        """(F, 3) Newell vectors: twice the area times the unit normal of each face (worked
        out once: a mesh's arrays are never changed in place, every edit makes a new mesh)."""
        if self._newell_cache is None:
            self._newell_cache = self._compute_newell()
            self._newell_cache.flags.writeable = False
        return self._newell_cache

    def _compute_newell(self) -> np.ndarray:
        if not self.n_faces:
            return np.zeros((0, 3))
        # coordinate by coordinate: numpy reduces (N, 3) arrays along axis 0 at half the speed
        # of three (N,) arrays (the sums, face by face in corner order, are the same)
        nxt = np.arange(1, len(self.corners) + 1)
        nxt[self.starts[1:] - 1] = self.starts[:-1]
        following = self.corners[nxt]
        x, y, z = (self.vertices[:, k] for k in range(3))
        px, py, pz = x[self.corners], y[self.corners], z[self.corners]
        qx, qy, qz = x[following], y[following], z[following]
        first = self.starts[:-1]
        out = np.empty((len(first), 3))
        out[:, 0] = np.add.reduceat((py - qy) * (pz + qz), first)
        out[:, 1] = np.add.reduceat((pz - qz) * (px + qx), first)
        out[:, 2] = np.add.reduceat((px - qx) * (py + qy), first)
        return out

    def face_normals(self) -> np.ndarray:
        n = self._newell()
        length = _row_lengths(n)[:, None]
        return np.where(length > EPS, n / np.maximum(length, EPS), 0.0)

    def face_areas(self) -> np.ndarray:
        return _row_lengths(self._newell()) / 2

    def area(self) -> float:
        return float(self.face_areas().sum())

    def volume(self) -> float:
        """Signed volume by the divergence theorem (exact for closed meshes)."""
        if not self.n_faces:
            return 0.0
        p = self.vertices[self.corners]
        first = np.repeat(self.starts[:-1], self.face_sizes)
        # fan triangles (first, k, k+1) for every corner k that is not a face's first or last
        k = np.arange(len(self.corners))
        last = np.repeat(self.starts[1:] - 1, self.face_sizes)
        ok = (k != first) & (k != last)
        a, b, c = p[first[ok]], p[k[ok]], p[k[ok] + 1]
        return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)

    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corner of the used vertices; zeros for an empty mesh."""
        if not self.n_faces:
            return np.zeros((2, 3))
        return np.array(column_bounds(self.vertices[self.corners]))

    def used_vertices(self) -> np.ndarray:
        if not self.n_faces:
            return np.zeros((0, 3))
        return self.vertices[np.unique(self.corners)]

    def triangle_count(self) -> int:
        return int(np.maximum(self.face_sizes - 2, 0).sum())

    def is_closed(self) -> bool:
        """True when every edge (after welding coincident vertices) is used exactly twice."""
        if self.closed is not None:
            return self.closed
        if self.n_faces < 4:
            self.closed = False
            return False
        self.closed = self._compute_closed()
        return self.closed

    def _compute_closed(self) -> bool:
        _, counts = self.welded_edges()
        return bool(len(counts)) and bool(np.all(counts == 2))

    def next_corners(self) -> np.ndarray:
        """(C,) for each corner, the index of the next corner of its face."""
        nxt = np.arange(1, len(self.corners) + 1)
        nxt[self.starts[1:] - 1] = self.starts[:-1]
        return nxt

    def welded_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """The edges after coincident vertices are welded (:func:`weld_ids`): (E, 2) sorted
        welded-vertex pairs, and how many faces use each."""
        w = weld_ids(self.vertices)[self.corners]
        a, b = w, w[self.next_corners()]
        keep = a != b
        e = np.sort(np.stack([a[keep], b[keep]], axis=1), axis=1)
        if not len(e):
            return np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
        return np.unique(e, axis=0, return_counts=True)

    # -- triangulation -----------------------------------------------------------------------
    def triangulate(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Triangles for export and rendering.

        Returns
        -------
        positions : (3T, 3) float
        uvs : (3T, 2) float (zeros where the mesh has no UVs)
        has_uv : (T,) bool
        face_of : (T,) int  index of the polygon each triangle came from
        """
        tri = self.triangle_corners()
        pos = self.vertices[self.corners[tri]].reshape(-1, 3)
        face_of = np.searchsorted(self.starts, tri[:, 0], side="right") - 1
        if self.corner_uvs is None:
            return pos, np.zeros((len(pos), 2)), np.zeros(len(tri), bool), face_of
        return pos, self.corner_uvs[tri].reshape(-1, 2), np.ones(len(tri), bool), face_of

    def triangle_corners(self) -> np.ndarray:
        """(T, 3) indices into ``corners``; triangles and convex quads without a Python loop."""
        if not self.n_faces:
            return np.zeros((0, 3), np.int64)
        sizes = self.face_sizes
        s = self.starts[:-1]
        out = []
        tri = sizes == 3
        if tri.any():
            b = s[tri]
            out.append(np.stack([b, b + 1, b + 2], axis=1))
        quad = sizes == 4
        if quad.any():
            b = s[quad]
            p = self.vertices[self.corners[b[:, None] + np.arange(4)]]
            n = cross3(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
            e = p[:, [1, 2, 3, 0]] - p
            turn = np.einsum("fkj,fj->fk", cross3(e, e[:, [1, 2, 3, 0]]), n)
            convex = np.all(turn >= -EPS, axis=1)
            bc = b[convex]
            out.append(np.stack([bc, bc + 1, bc + 2], axis=1))
            out.append(np.stack([bc, bc + 2, bc + 3], axis=1))
            rest_quads = b[~convex]
        else:
            rest_quads = np.zeros(0, np.int64)
        big = s[sizes > 4]
        if len(big):
            # convex polygons (most of an asset's n-gons: cylinder caps, mouldings) as fans,
            # all at once; the others by ear clipping below
            k = sizes[sizes > 4]
            corner = ranges_index(big, k)
            first = np.concatenate([[0], np.cumsum(k)[:-1]])
            nxt = np.arange(1, len(corner) + 1)
            nxt[first + k - 1] = first
            p = self.vertices[self.corners[corner]]
            e = p[nxt] - p
            turn = cross3(e, e[nxt])
            n = np.add.reduceat(turn, first, axis=0)
            convex = np.minimum.reduceat(
                np.einsum("ij,ij->i", turn, np.repeat(n, k, axis=0)), first) >= -EPS
            if convex.any():
                bc, kc = big[convex], k[convex]
                fan = np.repeat(bc, kc - 2)
                j = ranges_index(np.ones(len(kc), np.int64), kc - 2)
                out.append(np.stack([fan, fan + j, fan + j + 1], axis=1))
            big = big[~convex]
        others = np.concatenate([big, rest_quads])
        for b in np.sort(others):
            k = int(self.starts[np.searchsorted(self.starts, b) + 1] - b)
            local = triangulate_polygon(self.vertices[self.corners[b:b + k]])
            if len(local):
                out.append(local + b)
        if not out:
            return np.zeros((0, 3), np.int64)
        allt = np.concatenate(out)
        return allt[np.argsort(allt[:, 0], kind="stable")]

    def __repr__(self) -> str:
        return f"Mesh(vertices={len(self.vertices)}, faces={self.n_faces})"


# -- polygon helpers -------------------------------------------------------------------------

def ranges_index(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The indices ``starts[0] … starts[0] + lengths[0] - 1``, then those of the next range…,
    as one array (the corners of chosen faces or rings, gathered at once)."""
    lengths = np.asarray(lengths, np.int64)
    return np.repeat(np.asarray(starts, np.int64) - (np.cumsum(lengths) - lengths), lengths) \
        + np.arange(int(lengths.sum()))


def weld_ids(points: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
    """(N,) for each point, the id of its welded vertex: points on the same ``tolerance`` grid
    cell are one vertex (ids number the distinct cells)."""
    if not len(points):
        return np.zeros(0, np.int64)
    key = np.round(np.asarray(points, float) / tolerance).astype(np.int64)
    return np.unique(key, axis=0, return_inverse=True)[1].reshape(-1)


def column_bounds(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-column minimum and maximum of ``points`` (N, K), column by column: numpy's
    ``min(axis=0)`` over short rows is several times slower on large arrays."""
    return (np.array([points[:, j].min() for j in range(points.shape[1])]),
            np.array([points[:, j].max() for j in range(points.shape[1])]))


def _row_lengths(v: np.ndarray) -> np.ndarray:
    """Euclidean length of each row of (N, 3) ``v``: ``np.linalg.norm(v, axis=1)``, the same
    values, three times faster on large arrays."""
    return np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` for (..., 3) arrays without its axis juggling (a hot path on tiny arrays)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _newell(p: np.ndarray) -> np.ndarray:
    q = np.roll(p, -1, axis=0)
    return np.array([
        np.sum((p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2])),
        np.sum((p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0])),
        np.sum((p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1])),
    ])


def polygon_normal(p: np.ndarray) -> np.ndarray:
    """Unit normal (3,) of a polygon (k, 3) by Newell's method; zeros when degenerate."""
    n = _newell(np.asarray(p, float))
    length = np.linalg.norm(n)
    return n / length if length > EPS else np.zeros(3)


def polygon_area(p: np.ndarray) -> float:
    return float(np.linalg.norm(_newell(np.asarray(p, float))) / 2)


def plane_basis(normal: np.ndarray, first_edge: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) orthonormal basis whose columns are u, v (in the plane) and the normal."""
    n = np.asarray(normal, float)
    if first_edge is not None and np.linalg.norm(first_edge - n * (first_edge @ n)) > EPS:
        u = first_edge - n * (first_edge @ n)
        u = u / np.linalg.norm(u)
        v = np.cross(n, u)
        return np.column_stack([u, v, n])
    # helper × n for the helper axis (x, or y when n is near x), on plain floats: numpy's
    # per-call cost dominates on three numbers, and the trim of every inserted asset asks
    nx, ny, nz = n.tolist()
    ux, uy, uz = (0.0, -nz, ny) if abs(nx) < 0.9 else (nz, 0.0, -nx)
    r = math.sqrt(ux * ux + uy * uy + uz * uz)
    if not r:  # a zero normal: NaN axes, as numpy's division gives them
        return np.column_stack([np.full(3, np.nan), np.full(3, np.nan), n])
    ux, uy, uz = ux / r, uy / r, uz / r
    return np.array([[ux, ny * uz - nz * uy, nx],
                     [uy, nz * ux - nx * uz, ny],
                     [uz, nx * uy - ny * ux, nz]])


#: Polygons with more corners than this are triangulated by GEOS (:func:`_triangulate_large`):
#: earcut's time grows with the square of the corners on round outlines (a 100,000-corner
#: circle: 12 s), GEOS's constrained Delaunay triangulation stays under a second.  Below it,
#: earcut (a few milliseconds), whose triangles every export and test was made with.
EARCUT_MAX_CORNERS = 4096


def triangulate_polygon(p: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) of local corner indices for a planar simple polygon (k, 3) (earcut, or
    GEOS above :data:`EARCUT_MAX_CORNERS` corners)."""
    k = len(p)
    if k < 3:
        return np.zeros((0, 3), np.int64)
    if k == 3:
        return np.array([[0, 1, 2]])
    n = polygon_normal(p)
    if not n.any():
        return np.zeros((0, 3), np.int64)
    import mapbox_earcut as earcut

    basis = plane_basis(n)
    xy = (p - p[0]) @ basis[:, :2]
    if k > EARCUT_MAX_CORNERS:
        tri = _triangulate_large(xy)
        if tri is not None:
            return tri
    tri = earcut.triangulate_float64(xy, np.array([k], dtype=np.uint32))
    return np.asarray(tri, np.int64).reshape(-1, 3)


def _triangulate_large(xy: np.ndarray) -> np.ndarray | None:
    """Triangles (T, 3) of corner indices of the simple polygon ``xy`` (k, 2) by GEOS's
    constrained Delaunay triangulation, or None where it cannot serve (an invalid ring, or
    triangles whose corners are not the polygon's own: repeated points), for earcut to try.
    GEOS copies the corners' coordinates exactly, so each triangle corner is found among them
    by an exact search."""
    import shapely

    g = shapely.Polygon(xy)
    if not g.is_valid:
        return None
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(g))
    q = shapely.get_coordinates(shapely.get_exterior_ring(tris)).reshape(-1, 4, 2)[:, :3]
    key = xy[:, 0] + 1j * xy[:, 1]  # complex numbers sort by x, then y
    order = np.argsort(key, kind="stable")
    if (np.diff(key[order]) == 0).any():
        return None
    want = (q[..., 0] + 1j * q[..., 1]).ravel()
    at = np.minimum(np.searchsorted(key[order], want), len(key) - 1)
    if (key[order][at] != want).any():
        return None
    tri = order[at].reshape(-1, 3).astype(np.int64)
    # counter-clockwise in the plane, as earcut's are (the polygon's own winding in the basis
    # of its normal)
    x, y = xy[tri, 0], xy[tri, 1]
    area2 = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    tri[area2 < 0] = tri[area2 < 0, ::-1]
    return tri[area2 != 0]
