"""Mesh clean-up: weld vertices, drop degenerate and duplicate faces, merge coplanar faces, drop
collinear corners, fill holes, orient faces consistently, simplify by edge collapses.

These are the kernels of CGA's ``cleanupGeometry``, ``deleteHoles``, ``setNormals(conform)`` and
``reduceGeometry`` (``grammar/ops/cleanup.py``).  Each function takes a :class:`Mesh` and returns
the new mesh and ``source``: for every output face, the input face it came from, so that callers
can carry per-face data (materials, ``comp`` face kinds) over.

Texture coordinates are per face corner and are kept as they are: welding vertices never touches
them, and faces or corners are merged away only where the texture stays continuous, so the
appearance of a textured model does not change (CityEngine: "discontinuous texture coordinates
are preserved").
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from .mesh import EPS, Mesh, polygon_normal, weld_ids

WELD_EPS = 1e-6  # metres: "identical" vertices (the weld of Mesh.is_closed)
ANGLE_EPS = 1e-6  # radians: "collinear" / "coplanar" at tolerance 0
UV_EPS = 1e-6  # texture units: continuity of texture coordinates


@dataclass
class Poly:
    """A face being edited: vertex ids, per-corner UVs (``(k, 2)`` or ``None``), input face."""

    verts: list
    uvs: np.ndarray | None
    src: int


# -- building blocks -----------------------------------------------------------------------------

def weld(vertices: np.ndarray, distance: float) -> np.ndarray:
    """Per vertex, the id of the vertex it merges into.  In id order, each vertex not merged yet
    keeps its position and takes in the unmerged vertices within ``distance`` of it (at least
    :data:`WELD_EPS`): no chains, so a merged vertex never moves further than ``distance``.
    ``distance`` 0 is the weld of ``Mesh.is_closed`` (:func:`weld_ids`), each group merging
    into its first vertex."""
    n = len(vertices)
    target = np.arange(n)
    if n == 0:
        return target
    if distance <= WELD_EPS:
        ids = weld_ids(vertices, WELD_EPS)
        return np.unique(ids, return_index=True)[1][ids]
    from scipy.spatial import cKDTree

    near = cKDTree(vertices).query_ball_point(vertices, max(distance, WELD_EPS))
    done = np.zeros(n, bool)
    for i in range(n):
        if done[i] or len(near[i]) == 1:
            continue
        group = [j for j in near[i] if not done[j]]
        target[group] = i
        done[group] = True
    return target


def to_polys(mesh: Mesh, remap: np.ndarray | None = None) -> list[Poly]:
    """The faces as :class:`Poly`, vertex ids through ``remap``; corners that repeat the previous
    one (an edge welded to a point) are dropped."""
    ids = mesh.corners if remap is None else remap[mesh.corners]
    sizes, starts = mesh.face_sizes, mesh.starts
    full = sizes > 0
    prev = np.arange(-1, len(ids) - 1)
    prev[starts[:-1][full]] = starts[1:][full] - 1
    keep = ids != ids[prev]
    face_of = np.repeat(np.arange(mesh.n_faces), sizes)
    kept = np.bincount(face_of, weights=keep, minlength=mesh.n_faces)
    keep[starts[:-1][full & (kept == 0)]] = True  # welded to one point: one corner stays
    corners = np.flatnonzero(keep)
    verts = ids[corners].tolist()
    uvs = None if mesh.corner_uvs is None else mesh.corner_uvs[corners]
    per_face = np.bincount(face_of[corners], minlength=mesh.n_faces)
    bounds = np.concatenate([[0], np.cumsum(per_face)]).tolist()
    return [Poly(verts[a:b], None if uvs is None else uvs[a:b], f)
            for f, (a, b) in enumerate(zip(bounds, bounds[1:]))]


def to_mesh(vertices: np.ndarray, polys: list[Poly], has_uvs: bool) -> tuple[Mesh, np.ndarray]:
    """Mesh of ``polys`` on the vertices they use, and the source face of each."""
    if not polys:
        return Mesh(), np.zeros(0, np.int64)
    flat = np.concatenate([np.asarray(p.verts, np.int64) for p in polys])
    used, corners = np.unique(flat, return_inverse=True)
    starts = np.concatenate([[0], np.cumsum([len(p.verts) for p in polys])])
    cuv = np.concatenate([p.uvs for p in polys]) if has_uvs else None
    mesh = Mesh(vertices[used], corners=corners, starts=starts, corner_uvs=cuv)
    return mesh, np.array([p.src for p in polys], np.int64)


def _faces(vertices, polys: list[Poly]) -> Mesh:
    """The polygons as a mesh on ``vertices``, for vectorised normals and areas."""
    return Mesh(vertices, [p.verts for p in polys])


def drop_degenerate(vertices, polys: list[Poly], max_area: float) -> list[Poly]:
    """Faces with fewer than three corners or an area not above ``max_area`` (at least EPS) go."""
    limit = max(max_area, EPS)
    areas = _faces(vertices, polys).face_areas()
    return [p for p, a in zip(polys, areas) if len(p.verts) >= 3 and a > limit]


def _rotation_key(p: Poly, group) -> tuple:
    k = int(np.argmin(p.verts))
    verts = tuple(p.verts[k:] + p.verts[:k])
    uv = () if p.uvs is None else tuple(
        np.round(np.concatenate([p.uvs[k:], p.uvs[:k]]) / UV_EPS).astype(np.int64).ravel())
    return group, verts, uv


def drop_duplicates(polys: list[Poly], groups) -> list[Poly]:
    """Faces repeating an earlier face (same corners in the same cyclic order, same texture
    coordinates, same group) go.  A back-to-back pair (same corners, reversed order) is two
    visible sides of a wall, not a duplicate: both stay."""
    seen, out = set(), []
    for p in polys:
        key = _rotation_key(p, groups[p.src])
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle in radians between two unit vectors."""
    return math.acos(max(-1.0, min(1.0, float(a @ b))))


# -- merging coplanar faces ------------------------------------------------------------------------

def _edge_faces(polys: list[Poly]) -> dict:
    """Directed edge (a, b) -> indices of the faces that run along it."""
    edges: dict = {}
    for i, p in enumerate(polys):
        v = p.verts
        for k in range(len(v)):
            edges.setdefault((v[k], v[(k + 1) % len(v)]), []).append(i)
    return edges


def _neighbours(polys: list[Poly], edges: dict, i: int) -> list[int]:
    """Faces sharing a manifold edge with face ``i`` (each edge once in each direction)."""
    out = []
    v = polys[i].verts
    for k in range(len(v)):
        a, b = v[k], v[(k + 1) % len(v)]
        other = edges.get((b, a), ())
        if len(other) == 1 and len(edges[(a, b)]) == 1 and other[0] != i:
            out.append(other[0])
    return out


def _affine_uv(vertices, p: Poly):
    """Least-squares affine map position -> uv of a face, or ``None`` if its UVs are not affine."""
    x = np.column_stack([vertices[p.verts], np.ones(len(p.verts))])
    m = np.linalg.lstsq(x, p.uvs, rcond=None)[0]
    return m if np.abs(x @ m - p.uvs).max() <= UV_EPS else None


def _uv_fits(vertices, p: Poly, m) -> bool:
    x = np.column_stack([vertices[p.verts], np.ones(len(p.verts))])
    return bool(np.abs(x @ m - p.uvs).max() <= UV_EPS)


def _outline(polys: list[Poly], members, out: dict | None = None) -> dict | None:
    """Outline of faces ``members`` (added to outline ``out``) as ``vertex -> (next vertex, uv
    at vertex)``: edges met once each way are interior and cancel.  ``None`` when a vertex would
    start two outline edges (the faces touch at a corner only)."""
    edges = {} if out is None else dict(out)
    for i in members:
        p = polys[i]
        for k, a in enumerate(p.verts):
            b = p.verts[(k + 1) % len(p.verts)]
            edges[(a, b)] = None if p.uvs is None else p.uvs[k]
    result: dict = {}
    for (a, b), uv in edges.items():
        if (b, a) in edges:
            continue
        if a in result:
            return None
        result[a] = (b, uv)
    return result


def _edges_of(outline: dict) -> dict:
    return {(a, b): uv for a, (b, uv) in outline.items()}


def _one_loop(out: dict) -> bool:
    if len(out) < 3:
        return False
    start = next(iter(out))
    a, steps = start, 0
    while steps < len(out):
        nxt = out.get(a)
        if nxt is None:
            return False
        a, steps = nxt[0], steps + 1
        if a == start:
            break
    return a == start and steps == len(out)


def _loop(out: dict, first) -> tuple[list, list]:
    """Vertices and uvs of a one-loop boundary, starting at ``first`` when it is on it."""
    a = first if first in out else next(iter(out))
    verts, uvs = [], []
    for _ in range(len(out)):
        verts.append(a)
        uvs.append(out[a][1])
        a = out[a][0]
    return verts, uvs


def _grow(outline: dict, p: Poly) -> dict | None:
    """The outline with face ``p`` added, or ``None`` when it is not one simple loop: the same
    dict (entries in the same order) as ``_outline(.., [p], _edges_of(outline))`` checked with
    :func:`_one_loop`, but in time proportional to ``p``'s size, not the outline's.

    ``outline`` must be one simple loop; when ``p`` is accepted it is updated in place.  For a
    face with distinct corners and no edge along the outline in the same direction, the edges
    it shares with the outline (run the other way) decide:

    * none: ``p`` only touches the loop at corners, or not at all (two loops, or a vertex
      starting two edges);
    * one unbroken run of them: the loop loses the run and gains the rest of ``p``'s edges; the
      result is one simple loop unless a corner of ``p`` off the run is already on the loop;
    * two runs: they cut the loop into two loops (``p`` closes a ring around a hole);
    * all of them: nothing is left.

    Anything else (repeated corners, overlapping edges, three or more runs) is rare and goes
    the general way."""
    v, n = p.verts, len(p.verts)
    if n < 3 or len(outline) < 3 or len(set(v)) < n:
        return _grow_general(outline, p)
    shared = []
    for k in range(n):
        a, b = v[k], v[(k + 1) % n]
        if outline.get(a, (None,))[0] == b:
            return _grow_general(outline, p)  # an edge on top of the outline's, same direction
        shared.append(outline.get(b, (None,))[0] == a)
    runs = sum(shared[k] and not shared[k - 1] for k in range(n))
    if runs >= 3:
        return _grow_general(outline, p)
    if runs != 1:  # no shared edge, two runs, or every edge shared
        return None
    m = sum(shared)
    start = next(k for k in range(n) if shared[k] and not shared[k - 1])
    off_run = [v[(start + m + j) % n] for j in range(1, n - m)]  # corners strictly after the run
    if any(w in outline for w in off_run):
        return None
    for k in range(n):
        if shared[k]:
            del outline[v[(k + 1) % n]]
    for k in range(n):
        if not shared[k]:
            outline[v[k]] = (v[(k + 1) % n], None if p.uvs is None else p.uvs[k])
    return outline


def _grow_general(outline: dict, p: Poly) -> dict | None:
    """:func:`_grow` by rebuilding the whole outline (time proportional to its size)."""
    grown = _outline([p], [0], _edges_of(outline))
    return grown if grown is not None and _one_loop(grown) else None


def merge_coplanar(vertices, polys: list[Poly], max_angle: float, groups) -> list[Poly]:
    """Merge faces across shared edges into one polygon while their normals stay within
    ``max_angle`` of the first face's (at least :data:`ANGLE_EPS`), they are in the same group,
    their texture coordinates are one affine map, and the merged outline is one simple loop (no
    holes, no vertex twice).  The merged face starts at its first face's first vertex.

    Regions grow from each face not merged yet (in face order), depth first through manifold
    edges; a neighbour that fails a test stays out for now and is tried again when another of
    its neighbours joins.  The outline is kept up to date face by face (:func:`_grow`), so a
    region of F faces costs O(F), not O(F²)."""
    limit = max(max_angle, ANGLE_EPS)
    if len(polys) < 2:
        return polys
    normals = _faces(vertices, polys).face_normals()
    flat = ~normals.any(axis=1)  # no normal (degenerate): never merged
    edges = _edge_faces(polys)
    taken = [False] * len(polys)
    out = []
    for seed, p in enumerate(polys):
        if taken[seed]:
            continue
        taken[seed] = True
        uv_map = None if p.uvs is None else _affine_uv(vertices, p)
        if len(set(p.verts)) < len(p.verts) or flat[seed] or (
                p.uvs is not None and uv_map is None):
            out.append(p)
            continue
        outline = _outline(polys, [seed])
        queue, merged = _neighbours(polys, edges, seed), False
        while queue:  # only an accepted face (once each) pushes its neighbours: bounded
            q = queue.pop()
            cand = polys[q]
            if taken[q] or groups[cand.src] != groups[p.src] or flat[q] \
                    or _angle(normals[q], normals[seed]) > limit \
                    or (uv_map is not None and not _uv_fits(vertices, cand, uv_map)):
                continue
            grown = _grow(outline, cand)
            if grown is None:
                continue
            outline, taken[q], merged = grown, True, True
            queue.extend(_neighbours(polys, edges, q))
        if not merged:
            out.append(p)
            continue
        verts, uvs = _loop(outline, p.verts[0])
        out.append(Poly(verts, None if p.uvs is None else np.array(uvs), p.src))
    return out


# -- collinear corners ------------------------------------------------------------------------------

def _straight_corners(vertices, polys: list[Poly], max_angle: float) -> list[list[bool]]:
    """Per face, whether each corner lies on the straight line through its neighbours (turn
    angle within ``max_angle``) and, where the face has texture coordinates, its coordinate on
    the line between theirs: every corner of every face in one vectorised pass."""
    sizes = np.array([len(p.verts) for p in polys], np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    ids = np.fromiter((v for p in polys for v in p.verts), np.int64, int(starts[-1]))
    local = np.arange(len(ids)) - np.repeat(starts[:-1], sizes)
    n = np.repeat(sizes, sizes)
    first = np.repeat(starts[:-1], sizes)
    prev = first + (local - 1) % n
    nxt = first + (local + 1) % n
    a, b, c = vertices[ids[prev]], vertices[ids], vertices[ids[nxt]]
    d1, d2 = b - a, c - b
    l1 = np.sqrt(np.einsum("ij,ij->i", d1, d1))
    l2 = np.sqrt(np.einsum("ij,ij->i", d2, d2))
    ok = (l1 > EPS) & (l2 > EPS)
    cos = np.einsum("ij,ij->i", d1, d2) / np.where(ok, l1 * l2, 1.0)
    straight = ok & (np.arccos(np.clip(cos, -1.0, 1.0)) <= max_angle)
    if any(p.uvs is not None for p in polys):  # faces without: zeros, which always fit
        uv = np.concatenate([np.zeros((len(p.verts), 2)) if p.uvs is None else p.uvs
                             for p in polys])
        t = (l1 / np.where(ok, l1 + l2, 1.0))[:, None]
        expect = uv[prev] * (1 - t) + uv[nxt] * t
        straight &= np.abs(uv - expect).max(axis=1) <= UV_EPS
    flags = straight.tolist()
    bounds = starts.tolist()
    return [flags[x:y] for x, y in zip(bounds, bounds[1:])]


def drop_collinear(vertices, polys: list[Poly], max_angle: float) -> list[Poly]:
    """Remove corners on a straight edge.  A vertex goes only where it is straight in every face
    that uses it, so a neighbour never keeps it as a corner (no cracks); a face keeps at least
    three corners."""
    limit = max(max_angle, ANGLE_EPS)
    if not polys:
        return polys
    straight = _straight_corners(vertices, polys, limit)
    bent = set()
    for p, flags in zip(polys, straight):
        bent.update(v for v, s in zip(p.verts, flags) if not s)
    out = []
    for p, flags in zip(polys, straight):
        keep = [not s or v in bent for v, s in zip(p.verts, flags)]
        if sum(keep) < 3 or all(keep):
            out.append(p)
            continue
        out.append(Poly([v for v, k in zip(p.verts, keep) if k],
                        None if p.uvs is None else p.uvs[np.array(keep)], p.src))
    return out


# -- the operations ---------------------------------------------------------------------------------

COMPONENTS = ("vertices", "edges", "faces", "all")


def cleanup(mesh: Mesh, components: str, tolerance: float, groups=None) -> tuple[Mesh, np.ndarray]:
    """CityEngine's ``cleanupGeometry(components, tolerance)`` on a mesh.

    ``tolerance`` in [0, 1] scales CityEngine's limits: vertices merge up to ``tolerance`` metres
    apart, edges are collinear and normals coplanar up to ``10 * tolerance`` degrees, faces up to
    ``tolerance`` m² are degenerate.  Every mode merges vertices; ``vertices`` then drops collinear
    corners, ``edges`` merges coplanar faces, ``faces`` drops degenerate and duplicate faces,
    ``all`` does all of it.  ``groups`` (per input face, hashable) keeps faces of different groups
    (materials) apart.
    """
    if components not in COMPONENTS:
        raise ValueError(f"components must be one of {', '.join(COMPONENTS)}, not '{components}'")
    if mesh.n_faces == 1 and len(mesh.vertices) <= _SMALL:
        untouched = _untouched_face(mesh, components, tolerance)
        if untouched is not None:
            return untouched, np.zeros(1, np.int64)
    groups = [0] * mesh.n_faces if groups is None else groups
    remap = weld(mesh.vertices, tolerance)
    v = mesh.vertices
    polys = [p for p in to_polys(mesh, remap) if len(p.verts) >= 3]
    angle = math.radians(10.0 * tolerance)
    if components in ("faces", "all"):
        polys = drop_duplicates(drop_degenerate(v, polys, tolerance), groups)
    if components in ("edges", "all"):
        polys = merge_coplanar(v, polys, angle, groups)
    if components in ("vertices", "all"):
        polys = drop_collinear(v, polys, angle)
    return to_mesh(v, polys, mesh.corner_uvs is not None)


#: Vertices of a one-face mesh small enough for :func:`_untouched_face`'s plain-float tests.
_SMALL = 12
#: How far from a limit a test must be for the fast path to trust it (relative to the limit
#: for distances and areas, absolute radians for angles: arccos near 0 is ill-conditioned).
_MARGIN = 1e-6


def _untouched_face(mesh: Mesh, components: str, tolerance: float) -> Mesh | None:
    """What :func:`cleanup` returns for a single face that it leaves as it is, without its
    general machinery (a kd-tree, polygon lists; 0.3 ms a call, and production rules clean
    every face of an asset one by one); ``None`` unless every test is clear of its limit by
    :data:`_MARGIN`, so that the general path decides every close call and the result is the
    same either way."""
    ids = mesh.corners.tolist()
    k = len(ids)
    if k < 3 or any(ids[i] == ids[i - 1] for i in range(k)):
        return None
    pts = mesh.vertices.tolist()
    if tolerance <= WELD_EPS:  # the grid weld: every vertex in a cell of its own
        if len(np.unique(weld_ids(mesh.vertices, WELD_EPS))) != len(mesh.vertices):
            return None
    else:
        reach = tolerance * tolerance * (1.0 + _MARGIN)
        for i in range(len(pts)):
            a = pts[i]
            for b in pts[i + 1:]:
                if (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2 <= reach:
                    return None
    if components in ("faces", "all"):
        if not mesh.face_areas()[0] > max(tolerance, EPS) * (1.0 + _MARGIN):
            return None
    if components in ("vertices", "all"):
        limit = max(math.radians(10.0 * tolerance), ANGLE_EPS) + _MARGIN
        corners = [pts[i] for i in ids]
        for j in range(k):
            a, b, c = corners[j - 1], corners[j], corners[(j + 1) % k]
            d1 = (b[0] - a[0], b[1] - a[1], b[2] - a[2])
            d2 = (c[0] - b[0], c[1] - b[1], c[2] - b[2])
            l1 = math.sqrt(d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2])
            l2 = math.sqrt(d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2])
            if l1 <= EPS * 2 or l2 <= EPS * 2:
                return None
            cos = (d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]) / (l1 * l2)
            if math.acos(min(1.0, max(-1.0, cos))) <= limit:
                return None
    # the mesh as the general path rebuilds it: the vertices the face uses, in id order
    used, local = np.unique(mesh.corners, return_inverse=True)
    uvs = None if mesh.corner_uvs is None else mesh.corner_uvs.copy()
    return Mesh(mesh.vertices[used], corners=local.reshape(-1),
                starts=np.array([0, k], np.int64), corner_uvs=uvs)


def _loops(out: dict) -> list[list]:
    """Every loop of a boundary given as ``vertex -> next vertex`` (vertices at most once)."""
    left, loops = dict(out), []
    while left:
        a = next(iter(left))
        loop = []
        while a in left:  # each step removes one entry: bounded
            loop.append(a)
            a = left.pop(a)
        loops.append(loop)
    return loops


def _regions(vertices, polys: list[Poly], groups) -> list[list[int]]:
    """Connected sets of exactly coplanar faces of one group (through manifold edges)."""
    normals = _faces(vertices, polys).face_normals()
    edges = _edge_faces(polys)
    region = [-1] * len(polys)
    out = []
    for seed in range(len(polys)):
        if region[seed] >= 0:
            continue
        region[seed] = len(out)
        members, queue = [seed], [seed]
        while queue:
            i = queue.pop()
            for q in _neighbours(polys, edges, i):
                if region[q] < 0 and groups[polys[q].src] == groups[polys[seed].src] \
                        and _angle(normals[q], normals[seed]) <= ANGLE_EPS:
                    region[q] = region[seed]
                    members.append(q)
                    queue.append(q)
        out.append(members)
    return out


def _outer_loop(vertices, polys: list[Poly], members: list[int]):
    """The outline of a region with holes: ``(verts, uvs)``, or ``None`` when it has no hole or
    its outline is not one outer loop plus inner ones."""
    out = _outline(polys, members)
    if out is None:
        return None
    loops = _loops({a: b for a, (b, _) in out.items()})
    if len(loops) < 2:
        return None
    normal = polygon_normal(vertices[polys[members[0]].verts])
    outer = [lp for lp in loops if len(lp) >= 3 and polygon_normal(vertices[lp]) @ normal > 0]
    if len(outer) != 1:
        return None
    verts = outer[0]
    return verts, [out[a][1] for a in verts]


def count_holes(mesh: Mesh) -> int:
    """How many holes the faces have: our faces are simple polygons, so a face with holes is a
    connected set of coplanar pieces whose outline has inner loops (see :func:`fill_holes`)."""
    v = mesh.vertices
    polys = [p for p in to_polys(mesh, weld(v, 0.0)) if len(p.verts) >= 3]
    holes = 0
    for members in _regions(v, polys, [0] * mesh.n_faces):
        out = _outline(polys, members) if len(members) > 1 else None
        if out is not None:
            holes += max(len(_loops({a: b for a, (b, _) in out.items()})) - 1, 0)
    return holes


def fill_holes(mesh: Mesh, groups=None) -> tuple[Mesh, np.ndarray]:
    """CityEngine's ``deleteHoles()``: every face with holes becomes the face of its outline.

    Our meshes hold simple polygons only, so a face with holes (``offset(d, border)``, a lot with
    a courtyard, the remainder of ``setback``) is a connected set of coplanar pieces whose outline
    has inner loops.  Such a set is replaced by one polygon, its outer loop (texture coordinates
    from the pieces' corners); faces without holes stay as they are.
    """
    groups = [0] * mesh.n_faces if groups is None else groups
    v = mesh.vertices
    polys = [p for p in to_polys(mesh, weld(v, 0.0)) if len(p.verts) >= 3]
    out = []
    for members in _regions(v, polys, groups):
        outline = _outer_loop(v, polys, members) if len(members) > 1 else None
        if outline is None:
            out.extend(polys[i] for i in members)
            continue
        first = polys[members[0]]
        verts, uvs = outline
        out.append(Poly(verts, None if first.uvs is None else np.array(uvs), first.src))
    return to_mesh(v, out, mesh.corner_uvs is not None)


def conform(mesh: Mesh) -> tuple[Mesh, np.ndarray]:
    """CityEngine's ``setNormals(conform)``: faces of each connected part turned to agree with
    their neighbours (a shared edge runs once each way), then the part turned outwards when it is
    closed (positive volume), else so that its normals favour the world's up direction (summed
    area-weighted y not negative).  Non-orientable parts keep the orientation found first."""
    if not mesh.n_faces:
        return mesh.copy(), np.zeros(0, np.int64)
    polys = to_polys(mesh, weld(mesh.vertices, 0.0))
    undirected: dict = {}
    for i, p in enumerate(polys):
        for k, a in enumerate(p.verts):
            b = p.verts[(k + 1) % len(p.verts)]
            undirected.setdefault((min(a, b), max(a, b)), []).append((i, a < b))
    flip = np.zeros(len(polys), bool)
    part = np.full(len(polys), -1)
    n_parts = 0
    for seed in range(len(polys)):
        if part[seed] >= 0:
            continue
        part[seed], queue = n_parts, [seed]
        while queue:  # every face is queued once
            i = queue.pop()
            p = polys[i]
            for k, a in enumerate(p.verts):
                b = p.verts[(k + 1) % len(p.verts)]
                forward_i = (a < b) != flip[i]
                for j, forward_j in undirected[(min(a, b), max(a, b))]:
                    if part[j] < 0:
                        part[j] = n_parts
                        flip[j] = forward_j == forward_i  # same direction: turn j
                        queue.append(j)
        n_parts += 1
    oriented = _flip(mesh, flip)
    newell = oriented.face_normals() * oriented.face_areas()[:, None]
    for k in range(n_parts):
        faces = np.flatnonzero(part == k)
        sub = oriented.subset(faces)
        score = sub.volume() if sub.is_closed() else float(newell[faces, 1].sum())
        if score < -EPS:
            flip[faces] = ~flip[faces]
    return _flip(mesh, flip), np.arange(mesh.n_faces)


def _flip(mesh: Mesh, flip: np.ndarray) -> Mesh:
    """``mesh`` with the faces where ``flip`` is true reversed."""
    rev = mesh.reversed()
    sizes = mesh.face_sizes
    take = np.repeat(flip, sizes)
    corners = np.where(take, rev.corners, mesh.corners)
    cuv = None if mesh.corner_uvs is None else np.where(take[:, None], rev.corner_uvs, mesh.corner_uvs)
    return Mesh(mesh.vertices, corners=corners, starts=mesh.starts, corner_uvs=cuv)


# -- simplification ---------------------------------------------------------------------------------

def _plane_quadric(normal: np.ndarray, point: np.ndarray, weight: float) -> np.ndarray:
    p = np.append(normal, -float(normal @ point))
    return weight * np.outer(p, p)


class _Reducer:
    """Half-edge collapses (a vertex moves onto a neighbour) ordered by quadric error (Garland &
    Heckbert), on a triangle mesh of welded vertices.  Border edges carry a stiff perpendicular
    plane so outlines keep their shape."""

    def __init__(self, vertices: np.ndarray, tris: np.ndarray):
        self.v = vertices
        self.tris = tris.copy()
        self.alive = np.ones(len(tris), bool)
        self.dead = np.zeros(len(vertices), bool)
        self.version = np.zeros(len(vertices), np.int64)
        self.faces_of = [set() for _ in range(len(vertices))]
        for t, tri in enumerate(tris):
            for a in tri:
                self.faces_of[a].add(t)
        self.q = np.zeros((len(vertices), 4, 4))
        self._quadrics()
        self.heap: list = []
        for a in range(len(vertices)):
            self._push_from(a)

    def _quadrics(self) -> None:
        p = self.v[self.tris]
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        area = np.linalg.norm(n, axis=1)
        count: dict = {}
        for t, tri in enumerate(self.tris):
            if area[t] <= EPS:
                continue
            unit = n[t] / area[t]
            quad = _plane_quadric(unit, p[t, 0], area[t] / 2)
            for k in range(3):
                self.q[tri[k]] += quad
                e = (min(tri[k], tri[(k + 1) % 3]), max(tri[k], tri[(k + 1) % 3]))
                count[e] = count.get(e, 0) + 1
        for t, tri in enumerate(self.tris):  # border edges: a plane along the edge, across it
            if area[t] <= EPS:
                continue
            for k in range(3):
                a, b = tri[k], tri[(k + 1) % 3]
                if count.get((min(a, b), max(a, b))) != 1:
                    continue
                edge = self.v[b] - self.v[a]
                across = np.cross(edge, n[t] / area[t])
                length = np.linalg.norm(across)
                if length > EPS:
                    quad = _plane_quadric(across / length, self.v[a], 100.0 * float(edge @ edge))
                    self.q[a] += quad
                    self.q[b] += quad

    def _cost(self, a: int, b: int) -> float:
        h = np.append(self.v[b], 1.0)
        return float(h @ (self.q[a] + self.q[b]) @ h)

    def _neighbours(self, a: int) -> set:
        return {int(x) for t in self.faces_of[a] for x in self.tris[t]} - {a}

    def _push_from(self, a: int) -> None:
        for b in self._neighbours(a):
            heapq.heappush(self.heap, (self._cost(a, b), int(self.version[a]),
                                       int(self.version[b]), a, b))

    def _valid(self, a: int, b: int) -> bool:
        """Link condition (no pinched surface), ``a`` in some triangle that stays (the surface
        never just loses its triangles at ``a``), and no triangle turned over or squashed."""
        shared = self.faces_of[a] & self.faces_of[b]
        if len(self._neighbours(a) & self._neighbours(b)) != len(shared) \
                or not self.faces_of[a] - shared:
            return False
        for t in self.faces_of[a] - shared:
            p = self.v[self.tris[t]]
            before = np.cross(p[1] - p[0], p[2] - p[0])
            p = np.where((self.tris[t] == a)[:, None], self.v[b], p)
            after = np.cross(p[1] - p[0], p[2] - p[0])
            if float(after @ before) <= 0.2 * float(np.linalg.norm(after) * np.linalg.norm(before)):
                return False
        return True

    def collapse_some(self, count: int) -> None:
        done = 0
        while done < count and self.heap:  # every pop removes a heap entry: bounded
            _, va, vb, a, b = heapq.heappop(self.heap)
            if self.dead[a] or self.dead[b] or va != self.version[a] or vb != self.version[b]:
                continue
            if not self._valid(a, b):
                continue
            for t in self.faces_of[a] & self.faces_of[b]:
                self.alive[t] = False
                for x in self.tris[t]:
                    self.faces_of[x].discard(t)
            for t in self.faces_of[a]:
                self.tris[t][self.tris[t] == a] = b
                self.faces_of[b].add(t)
            self.faces_of[a] = set()
            self.q[b] += self.q[a]
            self.dead[a] = True
            for x in self._neighbours(b) | {b}:
                self.version[x] += 1
            for x in self._neighbours(b) | {b}:
                self._push_from(x)
            done += 1


def reduce(mesh: Mesh, fraction: float) -> tuple[Mesh, np.ndarray]:
    """CityEngine's ``reduceGeometry(tolerance)``: remove ``fraction`` of the (welded) vertices by
    edge collapses of least quadric error.  The result is triangles (as in the reference's
    example); each keeps its corners' texture coordinates.  Fewer vertices go when further
    collapses would turn a triangle over or pinch the surface."""
    remap = weld(mesh.vertices, 0.0)
    corner_tris = mesh.triangle_corners()
    if fraction <= 0 or not len(corner_tris):
        return mesh.copy(), np.arange(mesh.n_faces)
    tris = remap[mesh.corners[corner_tris]]
    face_of = np.searchsorted(mesh.starts, corner_tris[:, 0], side="right") - 1
    n_used = len(np.unique(tris))
    r = _Reducer(mesh.vertices, tris)
    r.collapse_some(int(round(fraction * n_used)))
    keep = r.alive & (r.tris[:, 0] != r.tris[:, 1]) & (r.tris[:, 1] != r.tris[:, 2]) \
        & (r.tris[:, 0] != r.tris[:, 2])
    polys = [Poly(r.tris[t].tolist(), None if mesh.corner_uvs is None
                  else mesh.corner_uvs[corner_tris[t]], int(face_of[t]))
             for t in np.flatnonzero(keep)]
    return to_mesh(mesh.vertices, polys, mesh.corner_uvs is not None)
