"""Rule inlining and Boolean 3D operations.

``inline(strategy) …`` derives a rule, a subdivision or an operation sequence *now* and merges the
resulting shapes into the current one, which the rule then goes on with (CityEngine reference,
"inline operation").  ``union | subtract | intersect { opsA | opsB }`` inlines both operand
sequences with the ``unify`` strategy and combines them with a Boolean 3D operation (reference,
"union / subtract / intersect (Boolean 3D operations)").

Merging, as the reference describes it:

* a single resulting shape is taken as is (scope, geometry, material, attributes);
* several are combined by the strategy: ``append`` puts the faces in one mesh, ``recompose``
  welds shared vertices and inserts vertices where a corner of one piece lies on another's edge
  (see "Shape Recomposition"), ``unify`` computes their Boolean union;
* conflicting materials are written to the geometry per face, so every face keeps its look; other
  attributes (and the scope) take the results' value where they all agree and keep the current
  shape's where they conflict;
* the inlined subtree does not appear in the shape tree.

Booleans use the Manifold library (``manifold3d``): exact, robust and fast on closed meshes.
Operands that are not closed volumes cannot be combined as solids; coplanar polygons are then
combined in their plane with shapely, and anything else is appended with a warning.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ...geometry.holed import HOLED, fresh_ids
from ...geometry.mesh import EPS, Mesh, plane_basis, polygon_normal, weld_ids
from ..values import CGARuntimeError
from .tagging import auto_tag, auto_tag_edges

#: Vertices closer than this are one vertex when ``recompose`` reconnects pieces (metres).
WELD_TOLERANCE = 1e-6
#: Above this many edge × vertex tests, ``recompose`` only welds (a warning says so).
MAX_TJUNCTION_TESTS = 20_000_000


# ---- deriving operands ------------------------------------------------------------------------

def derive_now(run, ops: tuple, state, env) -> list:
    """Derive ``ops`` on a copy of ``state`` to completion; the resulting leaf shapes as
    ``(ShapeState, rule name)``, in derivation order.

    ``run`` is the interpreter's running rule context.  Leaf shapes are collected instead of
    output, and instancing is off meanwhile (it would record parts, not shapes).  The random
    stream of the current shape goes on through the inlined derivation.
    """
    d = run.d
    sink: list = []
    saved = d.sink, d._purity, d.current_path
    d.sink, d._purity = sink, None
    work = state.copy()
    work.draws = state.draws
    work.mark_pivot()  # center() inside aligns to the shape entering the operand
    try:
        from ...model.shape import Shape

        root = Shape(run.rule, state.scope, operator="inline", id=d.new_id())
        queue: deque = deque()
        ctx = type(run)(d, queue, root, run.depth, run.rule)
        consumed = ctx.run(ops, work, env.with_state(work), None)
        if not consumed:
            sink.append((work, run.rule))
        while queue:
            d._apply(queue, *queue.popleft())
    finally:
        d.sink, d._purity, d.current_path = saved
    state.draws = work.draws
    return sink


# ---- merging results into the current shape --------------------------------------------------

def merge_into(d, state, results: list, strategy: str) -> None:
    """Replace ``state``'s geometry and attributes by the merged ``results`` (``inline``)."""
    if not results:
        state.geometry = Mesh()
        return
    if len(results) == 1:
        _take(state, results[0][0])
        if strategy != "unify" or not state.geometry.n_faces:
            return
        states = [results[0][0]]  # unify cleans up even one shape (CityEngine 2025.0)
    else:
        states = [s for s, _ in results]
        _agree(state, states)
    meshes, shared = _pieces(d, states)
    if strategy == "unify":
        mesh, origin = boolean(meshes, [], "union", d)
    elif strategy == "recompose":
        mesh, origin = recompose(meshes, d)
    else:
        mesh, origin = Mesh.merge(meshes), _appended(meshes)
    _set_geometry(state, mesh, origin, meshes, shared)


def boolean_into(d, state, kind: str, a_results: list, b_results: list) -> None:
    """``kind { A | B }``: operand A gives the shape's attributes; both operands are unified,
    then combined (reference, "union / subtract / intersect")."""
    a_states, b_states = [s for s, _ in a_results], [s for s, _ in b_results]
    if len(a_states) == 1:
        _take(state, a_states[0])
    elif a_states:
        _agree(state, a_states)
    meshes, shared = _pieces(d, a_states + b_states)
    n_a = sum(1 for s in a_states if s.geometry.n_faces)
    mesh, origin = boolean(meshes[:n_a], meshes[n_a:], kind, d)
    _set_geometry(state, mesh, origin, meshes, shared)
    if len(origin):  # auto-tags: each face names the operand it came from
        from_a = origin[:, 0] < n_a
        g = _cut_edges(auto_tag(state.geometry, "bool", np.where(from_a, "A", "B").tolist()),
                       from_a)
        # the pieces left of one operand face are one face (with holes where the cut went
        # through it); pieces that do not touch are told apart by geometry.holed.face_groups
        old = g.column(HOLED)  # an operand face that already had holes stays one face
        keys = [(p, "holed", old[i]) if old is not None and old[i] is not None else (p, f)
                for i, (p, f) in enumerate(origin.tolist())]
        state.geometry = g.with_column(HOLED, fresh_ids(keys))


def _cut_edges(mesh: Mesh, from_a: np.ndarray) -> Mesh:
    """``bool.cut`` on the intersection edges: those where a face of operand A meets one of
    operand B (CityEngine, Boolean 3D "Component tags")."""
    w = weld_ids(mesh.vertices)[mesh.corners]
    nxt = mesh.next_corners()
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    key = np.sort(np.stack([w, w[nxt]], axis=1), axis=1)
    _, edge = np.unique(key, axis=0, return_inverse=True)
    edge = edge.reshape(-1)
    has_a = np.zeros(edge.max() + 1 if len(edge) else 0, bool)
    has_b = np.zeros_like(has_a)
    np.logical_or.at(has_a, edge, from_a[face_of])
    np.logical_or.at(has_b, edge, ~from_a[face_of])
    cut = has_a[edge] & has_b[edge] & (key[:, 0] != key[:, 1])
    if not cut.any():
        return mesh
    return auto_tag_edges(mesh, "bool", np.where(cut, "cut", "").tolist(), replace=False)


def _appended(meshes: list) -> np.ndarray:
    """Origin of each face of the meshes appended in order: (piece, face in piece)."""
    return np.array([(k, f) for k, m in enumerate(meshes) for f in range(m.n_faces)],
                    np.int64).reshape(-1, 2)


def _set_geometry(state, mesh: Mesh, origin: np.ndarray, pieces: list, shared) -> None:
    """The merged mesh; each face keeps the data of the piece face it came from (``origin``:
    (piece, face) per face): its tags, and its material unless the pieces ``shared`` one."""
    if mesh.n_faces and pieces:
        offsets = np.cumsum([0] + [m.n_faces for m in pieces[:-1]])
        mesh = mesh.inherit(Mesh.merge(pieces), offsets[origin[:, 0]] + origin[:, 1])
    state.geometry = mesh
    if shared is not None:
        state.material = shared
    elif mesh.n_faces:
        state.material = {}


def _take(state, result) -> None:
    """A single result is taken as is."""
    state.scope = result.scope
    state.geometry = result.geometry
    state.material = dict(result.material)
    state.attrs = dict(result.attrs)
    state.projections = dict(result.projections)
    state.label = result.label
    state.tags = dict(result.tags)
    state.trim = result.trim


def _pieces(d, states):
    """Meshes of the results that have faces, and the one material dict they all share, or
    None; then every face carries its exported material (face column ``material``)."""
    keep = [s for s in states if s.geometry.n_faces]
    if all(s.material == keep[0].material and s.geometry.column("material") is None for s in keep):
        return [s.geometry for s in keep], dict(keep[0].material) if keep else {}
    meshes = []
    for s in keep:
        own = s.geometry.column("material")
        made: dict = {}
        column = []
        for am in (own if own is not None else [None] * s.geometry.n_faces):
            if id(am) not in made:
                made[id(am)] = d.material(s, am)
            column.append(made[id(am)])
        meshes.append(s.geometry.with_column("material", column))
    return meshes, None


def _agree(state, states) -> None:
    """Attributes the results all agree on replace the current shape's."""
    first = states[0]
    for key, value in first.attrs.items():
        try:
            if all(key in s.attrs and s.attrs[key] == value for s in states[1:]):
                state.attrs[key] = value
        except ValueError:  # arrays compare element-wise: treat as conflicting
            continue
    if all(s.label == first.label for s in states):
        state.label = first.label


# ---- recompose --------------------------------------------------------------------------------

def recompose(meshes: list, d=None) -> tuple[Mesh, np.ndarray]:
    """Append ``meshes``, weld vertices closer than :data:`WELD_TOLERANCE` and insert a vertex
    wherever a vertex lies on another face's edge, so that pieces of a subdivided shape share
    edges again (reference, "Shape Recomposition: Essential Knowledge").  Returns the mesh and,
    per face, the index of the mesh it came from."""
    merged = Mesh.merge(meshes)
    origin = _appended(meshes)
    if not merged.n_faces:
        return merged, origin
    v = merged.vertices
    inverse = weld_ids(v, WELD_TOLERANCE)
    verts = v[np.unique(inverse, return_index=True)[1]]  # each welded vertex at its first point
    corners = inverse[merged.corners]
    faces = np.split(corners, merged.starts[1:-1])
    uvs = merged.uvs
    n_tests = len(corners) * len(verts)
    if n_tests > MAX_TJUNCTION_TESTS:
        if d is not None:
            d.warn(f"inline(recompose): {len(verts)} vertices are too many to look for vertices "
                   "on edges; vertices were only welded")
    else:
        faces, uvs = _split_edges(verts, faces, uvs)
    out = Mesh(verts, faces, uvs if merged.corner_uvs is not None else None)
    return out, origin


def _split_edges(verts, faces, uvs):
    """Insert into each face edge the vertices lying on it (T-junctions), in order along it."""
    out_f, out_uv = [], []
    for f, uv in zip(faces, uvs):
        a = verts[f]
        b = verts[np.roll(f, -1)]
        ab = b - a
        length2 = np.einsum("ij,ij->i", ab, ab)
        rel = verts[None, :, :] - a[:, None, :]                      # (k, V, 3)
        t = np.einsum("kvj,kj->kv", rel, ab) / np.maximum(length2, EPS)[:, None]
        off = rel - t[:, :, None] * ab[:, None, :]
        near = (np.einsum("kvj,kvj->kv", off, off) < WELD_TOLERANCE ** 2) & (t > 1e-9) \
            & (t < 1 - 1e-9)
        if not near.any():
            out_f.append(f)
            out_uv.append(uv)
            continue
        nf, nuv = [], []
        for k in range(len(f)):
            nf.append(f[k])
            if uv is not None:
                nuv.append(uv[k])
            idx = np.flatnonzero(near[k])
            idx = idx[~np.isin(idx, f)]
            for j in idx[np.argsort(t[k, idx])]:
                nf.append(j)
                if uv is not None:
                    nuv.append(uv[k] + t[k, j] * (uv[(k + 1) % len(f)] - uv[k]))
        out_f.append(np.array(nf))
        out_uv.append(None if uv is None else np.array(nuv))
    return out_f, out_uv


# ---- Boolean 3D -------------------------------------------------------------------------------

def boolean(a_meshes: list, b_meshes: list, kind: str, d) -> tuple[Mesh, np.ndarray]:
    """``union``/``subtract``/``intersect`` of the union of ``a_meshes`` with the union of
    ``b_meshes`` (for ``union`` of one list, ``b_meshes`` may be empty).  Returns the result
    and, per face, its origin: (input mesh, A's first then B's; polygon of that mesh)."""
    meshes = [*a_meshes, *b_meshes]
    if all(m.n_faces == 0 or m.is_closed() for m in meshes):
        return _solid_boolean(a_meshes, b_meshes, kind)
    planar = _common_plane(meshes)
    if planar is not None:
        return _planar_boolean(a_meshes, b_meshes, kind, planar)
    if d is not None:
        d.warn(f"{kind}: the operands are neither closed volumes nor polygons in one plane; "
               "their faces are appended")
    if kind == "intersect":
        return Mesh(), np.zeros((0, 2), np.int64)
    keep = a_meshes if kind == "subtract" else meshes
    return Mesh.merge(keep), _appended(keep)


def _solid_boolean(a_meshes, b_meshes, kind):
    import manifold3d as mf

    inputs = [*a_meshes, *b_meshes]
    first_face = np.cumsum([0] + [m.n_faces for m in inputs])
    solids = [_to_manifold(m, int(f0)) if m.n_faces else mf.Manifold()
              for m, f0 in zip(inputs, first_face)]

    def unite(parts):
        # an input may hold several overlapping shells: unite its connected pieces too
        pieces = [p for s in parts for p in s.decompose()]
        return mf.Manifold.batch_boolean(pieces, mf.OpType.Add) if pieces else mf.Manifold()

    a = unite(solids[:len(a_meshes)])
    if kind == "union" and not b_meshes:
        result = a
    else:
        b = unite(solids[len(a_meshes):])
        op = {"union": mf.OpType.Add, "subtract": mf.OpType.Subtract,
              "intersect": mf.OpType.Intersect}[kind]
        result = mf.Manifold.batch_boolean([a, b], op)
    return _from_manifold(result, inputs, first_face)


def _to_manifold(mesh: Mesh, first_face: int):
    """A closed Mesh as a Manifold: corners unshared (properties x, y, z, u, v per corner),
    merged by position; each triangle's face id is its polygon's number among all inputs."""
    import manifold3d as mf

    pos, uv, _, face_of = mesh.triangulate()
    props = np.column_stack([pos, uv]).astype(np.float64)
    tris = np.arange(len(pos), dtype=np.uint32).reshape(-1, 3)
    face_id = (face_of + first_face).astype(np.uint32)
    m = mf.Mesh64(vert_properties=props, tri_verts=tris, face_id=face_id)
    m.merge()
    solid = mf.Manifold(m)
    if solid.status() != mf.Error.NoError:
        raise CGARuntimeError(f"Boolean operation: an operand is not a valid closed volume "
                              f"({solid.status().name})")
    return solid


def _from_manifold(result, inputs: list, first_face: np.ndarray) -> tuple[Mesh, np.ndarray]:
    """Our Mesh from a Manifold result: the triangles of each input polygon are joined back into
    one polygon where they form a simple one, so a cut box still has quads where it was not cut."""
    out = result.to_mesh64()
    props = np.asarray(out.vert_properties, float)
    tris = np.asarray(out.tri_verts, np.int64).reshape(-1, 3)
    if len(tris) == 0:
        return Mesh(), np.zeros((0, 2), np.int64)
    fid = np.asarray(out.face_id, np.int64)
    polys, uvs, origin = [], [], []
    for key in np.unique(fid):
        group = tris[fid == key]
        piece = int(np.searchsorted(first_face, key, side="right") - 1)
        source = inputs[piece]
        src_poly = source.vertices[source.face(int(key - first_face[piece]))]
        src_normal = polygon_normal(src_poly)
        for loop in _join_triangles(props, group):
            # a subtracted operand's faces come out turned over: their first edge runs backwards
            turned = polygon_normal(props[loop, :3]) @ src_normal < 0
            first = src_poly[1] - src_poly[0]
            loop = _keep_first_edge(props, loop, -first if turned else first)
            polys.append(props[loop, :3])
            uvs.append(props[loop, 3:5])
            origin.append((piece, key - first_face[piece]))
    has_uv = any(m.corner_uvs is not None for m in inputs)
    mesh = Mesh.from_polygons(polys, uvs if has_uv else None)
    return mesh, np.asarray(origin, np.int64).reshape(-1, 2)


def _keep_first_edge(props: np.ndarray, loop: list, first: np.ndarray) -> list:
    """``loop`` started at the corner whose outgoing edge runs most nearly along the input
    polygon's first edge ``first``, so that a face's scope (x along its first edge) comes out as
    it went in: a wall's first edge stays its bottom edge."""
    p = props[loop, :3]
    e = np.roll(p, -1, axis=0) - p
    length = np.linalg.norm(e, axis=1)
    f = first / max(np.linalg.norm(first), EPS)
    score = np.where(length > EPS, (e @ f) / np.maximum(length, EPS), -2.0)
    k = int(np.argmax(score - 1e-9 * np.arange(len(loop))))
    return loop[k:] + loop[:k]


def _join_triangles(props: np.ndarray, tris: np.ndarray) -> list:
    """Outer loops of the triangles of one coplanar group, as vertex-index lists; the triangles
    themselves where they do not form simple polygons without holes."""
    if len(tris) == 1:
        return [list(tris[0])]
    edges = {}
    for t in tris:
        for i in range(3):
            a, b = int(t[i]), int(t[(i + 1) % 3])
            edges[(a, b)] = edges.get((a, b), 0) + 1
    boundary = {a: b for (a, b) in edges if (b, a) not in edges}
    # vertices may be duplicated with equal positions (different properties): compare positions
    starts = set(boundary)
    if len(starts) != len(boundary.values()) or set(boundary.values()) != starts:
        return [list(t) for t in tris]
    loops, seen = [], set()
    for s in boundary:
        if s in seen:
            continue
        loop, cur = [], s
        while cur not in seen and len(loop) <= len(boundary):
            seen.add(cur)
            loop.append(cur)
            cur = boundary.get(cur, s)
        loops.append(loop)
    if len(loops) != 1:  # holes or disjoint parts: keep triangles
        return [list(t) for t in tris]
    # collinear corners stay: a neighbouring face may end there, and the mesh stays watertight
    return [loops[0]] if len(loops[0]) >= 3 else [list(t) for t in tris]


def _common_plane(meshes):
    """(origin, basis) of the plane all faces lie in, or None."""
    ms = [m for m in meshes if m.n_faces]
    if not ms:
        return None
    pts = np.concatenate([m.vertices[m.corners] for m in ms])
    n = polygon_normal(ms[0].vertices[ms[0].face(0)])
    if not n.any():
        return None
    n = n / np.linalg.norm(n)
    if np.abs((pts - pts[0]) @ n).max() > 1e-6:
        return None
    return pts[0], plane_basis(n)


def _planar_boolean(a_meshes, b_meshes, kind, plane):
    """Booleans of polygons lying in one plane (shapely in the plane's 2D frame)."""
    from shapely import Polygon, make_valid, union_all

    from ...geometry.polygon import simple_pieces

    origin, basis = plane
    to2d = basis[:, :2]

    def region(ms):
        polys = [Polygon((p - origin) @ to2d) for m in ms for p in m.polygons() if len(p) >= 3]
        return union_all([make_valid(p) for p in polys]) if polys else Polygon()

    a = region(a_meshes)
    if kind == "union":
        res = a.union(region(b_meshes)) if b_meshes else a
    elif kind == "subtract":
        res = a.difference(region(b_meshes))
    else:
        res = a.intersection(region(b_meshes))
    out = []
    for g in getattr(res, "geoms", [res]):
        if g.geom_type == "Polygon" and not g.is_empty:
            # a polygon with holes becomes triangles (our faces have none), as offset does
            out.extend(origin + ring @ to2d.T for ring in simple_pieces(g))
    mesh = Mesh.from_polygons(out)
    # faces of a planar Boolean result no longer map to single input faces: each takes the
    # first input's first material
    return mesh, np.zeros((mesh.n_faces, 2), np.int64)
