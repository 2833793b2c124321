"""Geometry tags (CityEngine 2023.1+): strings stored on a geometry's faces, edges and vertices
that name its parts.

Reference: "Geometry Tagging: Essential Knowledge"
(https://esri.github.io/cityengine-sdk/html/cgaref/cgareference/cga_componentTags.html) and the
``tag``, ``deleteTags``, ``comp`` (``isTagged``), ``geometry.hasTags`` and ``geometry.tags`` pages.

* A tag is a string; ``.`` groups it into subtags (``"Facade.Front"``).  A *tag query* may use
  ``?`` for exactly one subtag and ``*`` for one or more, and matches a tag when it matches the
  tag's leading subtags: ``"Facade"`` matches ``"Facade.Front"``, not ``"Front.Facade"``
  (:func:`matches`).  Matching is case-sensitive.
* Tags live in the mesh: face column ``tags`` and corner columns ``edge_tags`` (the edge from a
  corner to the next) and ``vertex_tags`` (tuples of strings), so every operation that keeps,
  cuts or copies faces carries them as it carries materials (``Mesh.inherit``): a split piece
  keeps its face's tags and those of the edges it keeps, a new cap face or cut edge has none, a
  face built on a face (an extrusion's top) takes that face's tags, a face rising from an edge
  (an extrusion's side) that edge's.
* Auto-tags: ``extrude``, ``taper``, ``envelope``, the roofs and the Boolean operations name the
  faces they build (``"extrude.top"``, ``"roof.side"``, ``"bool.A"``), the setback family the
  edges (``"setback.front"``); calling such an operation again replaces its earlier auto-tags
  (:func:`auto_tag`).
* ``isTagged(query)`` (and ``isTagged(query, e|v)``) is a selector of ``comp`` and the setback
  operations, alone or in a logical selector (``isTagged("A") && side``).  Edges also count as
  tagged when a face next to them is, vertices when an edge or face next to them is
  (:class:`TagIndex`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ...geometry.holed import edge_corners
from ...geometry.mesh import Mesh, weld_ids
from ..values import CGARuntimeError, to_str
from . import operation, shape_function

TAGS, EDGE_TAGS, VERTEX_TAGS = "tags", "edge_tags", "vertex_tags"


def clean_tag(name: str) -> str:
    """A tag name as CityEngine stores it: the reserved wildcards ``?`` and ``*`` filtered out,
    empty subtags dropped (``"a..b"`` is ``"a.b"``)."""
    name = name.replace("?", "").replace("*", "")
    return ".".join(p for p in name.split(".") if p)


class _Query:
    """A compiled tag query: ``match(tag)`` by dynamic programming over the subtags (a regular
    expression with several ``*`` backtracks exponentially on long tags)."""

    __slots__ = ("parts",)

    def __init__(self, query: str):
        self.parts = tuple(p for p in query.split(".") if p)

    def match(self, tag: str) -> bool:
        q, t = self.parts, tag.split(".")
        if not q:
            return True
        # ok[j]: the first i query parts match the first j subtags exactly
        ok = [True] + [False] * len(t)
        for part in q:
            new = [False] * (len(t) + 1)
            if part == "*":
                seen = False
                for j in range(1, len(t) + 1):  # one or more subtags after a matched prefix
                    seen = seen or ok[j - 1]
                    new[j] = seen
            else:
                for j in range(1, len(t) + 1):
                    new[j] = ok[j - 1] and (part == "?" or part == t[j - 1])
            ok = new
            if not any(ok):
                return False
        return any(ok)  # the tag may go on with more subtags


@lru_cache(maxsize=4096)
def _query(query: str) -> _Query:
    return _Query(query)


def matches(query: str, tag: str) -> bool:
    """Whether tag ``query`` matches ``tag``: subtag by subtag from the start (``?`` one subtag,
    ``*`` one or more), the tag may go on with more subtags; the empty query matches every
    tag."""
    return _query(query).match(tag)


def _any_match(rx: _Query, tags) -> bool:
    return bool(tags) and any(rx.match(t) for t in tags)


# ---- tags on a mesh ----------------------------------------------------------------------------

def _tuples(col, n: int) -> list:
    return [()] * n if col is None else [t or () for t in col]


def face_tags(mesh: Mesh) -> list:
    """Each face's tags as a tuple (``()`` when it has none)."""
    return _tuples(mesh.column(TAGS), mesh.n_faces)


def corner_tags(mesh: Mesh, name: str) -> list:
    """Each corner's edge (``EDGE_TAGS``) or vertex (``VERTEX_TAGS``) tags as a tuple."""
    return _tuples(mesh.corner_column(name), len(mesh.corners))


def _column(tags) -> list | None:
    """A tag column from tuples: None when nothing is tagged (the column is then dropped)."""
    return [tuple(t) if t else None for t in tags] if any(tags) else None


def with_face_tags(mesh: Mesh, tags) -> Mesh:
    return mesh.with_column(TAGS, _column(tags))


def with_corner_tags(mesh: Mesh, name: str, tags) -> Mesh:
    return mesh.with_corner_column(name, _column(tags))


def without_tags(mesh: Mesh) -> Mesh:
    """``mesh`` with no face, edge or vertex tags (operations that do not support tags clear
    them, as ``reduceGeometry`` and ``splitArea`` do in CityEngine)."""
    return (mesh.without_columns(TAGS).with_corner_column(EDGE_TAGS, None)
            .with_corner_column(VERTEX_TAGS, None))


def _added(tags: tuple, extra) -> tuple:
    return tags + tuple(t for t in extra if t not in tags)


def auto_tag(mesh: Mesh, op: str, parts) -> Mesh:
    """``mesh`` after operation ``op`` built it: every earlier ``op`` auto-tag (faces, edges and
    vertices) is removed, then face ``i`` gets ``op + "." + parts[i]`` (none for an empty
    part)."""
    rx = _query(op)
    new = [tuple(x for x in t if not rx.match(x)) + ((f"{op}.{part}",) if part else ())
           for t, part in zip(face_tags(mesh), parts)]
    mesh = with_face_tags(mesh, new)
    for name in (EDGE_TAGS, VERTEX_TAGS):
        if mesh.corner_column(name) is not None:
            mesh = with_corner_tags(mesh, name, [tuple(x for x in t if not rx.match(x))
                                                 for t in corner_tags(mesh, name)])
    return mesh


def auto_tag_edges(mesh: Mesh, op: str, parts, replace: bool = True) -> Mesh:
    """Edge auto-tags: earlier ``op`` tags removed everywhere (unless ``replace`` is False: the
    operation has just tagged the faces), corner ``c``'s edge tagged ``op + "." + parts[c]``
    (none for an empty part)."""
    if replace:
        mesh = auto_tag(mesh, op, [""] * mesh.n_faces)
    return with_corner_tags(mesh, EDGE_TAGS, [
        _added(t, (f"{op}.{part}",)) if part else t
        for t, part in zip(corner_tags(mesh, EDGE_TAGS), parts)])


def faces_from_edges(mesh: Mesh, parent: Mesh, from_edge) -> Mesh:
    """Faces rising from edges of ``parent`` take those edges' tags: face ``i`` adds the tags
    of the edge starting at parent corner ``from_edge[i]`` (-1: none)."""
    if parent.corner_column(EDGE_TAGS) is None:
        return mesh
    tags = corner_tags(parent, EDGE_TAGS)
    extra = [tags[c] if c >= 0 else () for c in from_edge]
    if not any(extra):
        return mesh
    return with_face_tags(mesh, [_added(t, e) for t, e in zip(face_tags(mesh), extra)])


def edges_with(mesh: Mesh, extra) -> Mesh:
    """``mesh`` with corner ``c``'s edge also tagged ``extra[c]`` (a tuple, maybe empty)."""
    if not any(extra):
        return mesh
    return with_corner_tags(mesh, EDGE_TAGS, [_added(t, e) for t, e in
                                              zip(corner_tags(mesh, EDGE_TAGS), extra)])


# ---- which components a query selects -----------------------------------------------------

class TagIndex:
    """What ``isTagged`` sees on a mesh: its faces, its edges in ``comp(e)`` order (coincident
    vertices welded) and its used vertices in ``comp(v)`` order, with their own tags and their
    neighbours'."""

    def __init__(self, mesh: Mesh):
        self.mesh = mesh
        n_c = len(mesh.corners)
        self.ftags = face_tags(mesh)
        self.etags = corner_tags(mesh, EDGE_TAGS)
        self.vtags = corner_tags(mesh, VERTEX_TAGS)
        self.face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
        vw = weld_ids(mesh.vertices)
        w = vw[mesh.corners] if n_c else np.zeros(0, np.int64)
        nxt = mesh.next_corners() if n_c else np.zeros(0, np.int64)
        self.weld = w
        self.edge_of = np.full(n_c, -1, np.int64)
        self.edge_corners: list[list[int]] = []
        seen: dict = {}
        for c in edge_corners(mesh, vw).tolist():  # comp(e)'s order, seams left out
            k = (min(w[c], w[nxt[c]]), max(w[c], w[nxt[c]]))
            if k[0] == k[1]:
                continue
            e = seen.setdefault(k, len(self.edge_corners))
            if e == len(self.edge_corners):
                self.edge_corners.append([])
            self.edge_corners[e].append(c)
            self.edge_of[c] = e
        self.edge_ends = [(w[cs[0]], w[nxt[cs[0]]]) for cs in self.edge_corners]

    def _faces_own(self, rx) -> np.ndarray:
        return np.array([_any_match(rx, t) for t in self.ftags], bool)

    def _edges_rule(self, rx) -> np.ndarray:
        """Edge rule: its own tags or a neighbouring face's."""
        face_ok = self._faces_own(rx)
        return np.array([any(_any_match(rx, self.etags[c]) or face_ok[self.face_of[c]]
                             for c in cs) for cs in self.edge_corners], bool)

    def _welded_vertex_rule(self, rx) -> dict:
        """Vertex rule per welded vertex: its own tags or a neighbouring edge's or face's."""
        ok: dict = {}
        face_ok = self._faces_own(rx)
        edge_own = [any(_any_match(rx, self.etags[c]) for c in cs) for cs in self.edge_corners]
        for c, u in enumerate(self.weld):
            if _any_match(rx, self.vtags[c]) or face_ok[self.face_of[c]]:
                ok[u] = True
        for e, (a, b) in enumerate(self.edge_ends):
            if edge_own[e]:
                ok[a] = ok[b] = True
        return ok

    def faces(self, query: str, sub: str | None = None) -> np.ndarray:
        rx = _query(query)
        if sub is None:
            return self._faces_own(rx)
        out = np.zeros(self.mesh.n_faces, bool)
        if sub == "e":
            edge_ok = self._edges_rule(rx)
            for c, e in enumerate(self.edge_of):
                if e >= 0 and edge_ok[e]:
                    out[self.face_of[c]] = True
        else:
            ok = self._welded_vertex_rule(rx)
            for c, u in enumerate(self.weld):
                if ok.get(u):
                    out[self.face_of[c]] = True
        return out

    def edges(self, query: str, sub: str | None = None) -> np.ndarray:
        rx = _query(query)
        if sub is None:
            return self._edges_rule(rx)
        ok = self._welded_vertex_rule(rx)
        return np.array([bool(ok.get(a) or ok.get(b)) for a, b in self.edge_ends], bool)

    def vertices(self, query: str, sub: str | None = None) -> np.ndarray:
        """Used vertices in ``comp(v)`` order (``Mesh.used_vertices``)."""
        ok = self._welded_vertex_rule(_query(query))
        used, first = np.unique(self.mesh.corners, return_index=True)
        return np.array([bool(ok.get(self.weld[c])) for c in first], bool)

    def polygon_edges(self, query: str, sub: str | None = None) -> np.ndarray:
        """The edges of a single-face shape in corner order (the setback operations')."""
        edge_ok = self.edges(query, sub)
        return np.array([e >= 0 and edge_ok[e] for e in self.edge_of], bool)


# ---- the selector --------------------------------------------------------------------------

#: The local through which a selector's ``isTagged`` call reaches its component.
_COMPONENT = "\0component"


@shape_function("isTagged")
def _is_tagged(env, args):
    """``isTagged(query)``, ``isTagged(query, e|v)``: a selector of ``comp``, ``setback``,
    ``setbackToArea`` and ``setbackPerEdge`` (and the comp function)."""
    hit = env.locals.get(_COMPONENT)
    if hit is None:
        raise CGARuntimeError("isTagged(…) selects components in comp and setback; elsewhere "
                              'ask geometry.hasTags(…), e.g. case geometry.hasTags("roof") : …')
    if not 1 <= len(args) <= 2:
        raise CGARuntimeError(f"isTagged takes a tag query and optionally e or v, got "
                              f"{len(args)} arguments")
    sub = to_str(args[1]) if len(args) == 2 else None
    if sub not in (None, "e", "v"):
        raise CGARuntimeError(f"isTagged: the subcomponent is e or v, not '{sub}'")
    masks, index, i = hit
    key = (to_str(args[0]), sub)
    if key not in masks:
        masks[key] = index(*key)
    return bool(masks[key][i])


def component_env(env, i: int, words: dict, masks: dict, index, state=None) -> object:
    """``env`` for evaluating a logical selector on component ``i``: selector words bound to
    the component's truth values, ``isTagged`` to ``index`` (``(query, sub) -> mask``), other
    names and functions reading ``state`` (the component's shape; default the env's)."""
    from ..interpreter import Env

    local = dict(env.locals)
    local.update({w: bool(m[i]) for w, m in words.items()})
    local.setdefault("e", "e")
    local.setdefault("v", "v")
    local[_COMPONENT] = (masks, index, i)
    return Env(env.derivation, env.module, local, env.state if state is None else state,
               env.rule, env.call_depth)


# ---- operations ------------------------------------------------------------------------------

def _components(call, i: int, default: str, allowed) -> str:
    comp = call.sel(i, default)
    if comp not in allowed:
        raise CGARuntimeError(f"{call.name}: components must be one of {', '.join(allowed)}, "
                              f"not '{comp}'")
    return comp


@operation("tag", 1, 2, selectors=(1,))
def op_tag(call):
    """``tag(name)``, ``tag(name, auto|faces|edges|vertices)``: add tag ``name`` (wildcards
    filtered out) to every face (``auto``: the faces, the highest-dimensional components), edge
    or vertex."""
    comp = _components(call, 1, "auto", ("auto", "faces", "edges", "vertices"))
    name = clean_tag(call.text(0))
    st = call.state
    g = st.geometry
    if not name or not g.n_faces:
        return
    if comp in ("auto", "faces"):
        st.geometry = with_face_tags(g, [_added(t, (name,)) for t in face_tags(g)])
    else:
        col = EDGE_TAGS if comp == "edges" else VERTEX_TAGS
        st.geometry = with_corner_tags(g, col, [_added(t, (name,)) for t in corner_tags(g, col)])


_DELETE_COMPONENTS = ("all", "faces", "edges", "vertices")


def _columns_of(comp: str) -> tuple:
    return {"all": (TAGS, EDGE_TAGS, VERTEX_TAGS), "faces": (TAGS,), "edges": (EDGE_TAGS,),
            "vertices": (VERTEX_TAGS,)}[comp]


@operation("deleteTags", 0, 2, selectors=(1,))
def op_delete_tags(call):
    """``deleteTags()``, ``deleteTags(query)``, ``deleteTags(query, all|faces|edges|vertices)``:
    remove the tags ``query`` matches (all tags without a query) from those components."""
    comp = _components(call, 1, "all", _DELETE_COMPONENTS)
    rx = _query(call.text(0, ""))
    st = call.state
    g = st.geometry
    for col in _columns_of(comp):
        if col == TAGS and g.column(TAGS) is not None:
            g = with_face_tags(g, [tuple(t for t in ts if not rx.match(t)) for ts in face_tags(g)])
        elif col != TAGS and g.corner_column(col) is not None:
            g = with_corner_tags(g, col, [tuple(t for t in ts if not rx.match(t))
                                          for ts in corner_tags(g, col)])
    st.geometry = g


def _stored(mesh: Mesh, comp: str):
    """Every tag stored on the ``comp`` components, one tuple per component."""
    for col in _columns_of(comp):
        yield from (face_tags(mesh) if col == TAGS else corner_tags(mesh, col))


# ---- functions -------------------------------------------------------------------------------

def _query_args(args, name: str) -> tuple[str, str]:
    if len(args) > 2:
        raise CGARuntimeError(f"{name} takes a tag query and optionally the components, got "
                              f"{len(args)} arguments")
    comp = to_str(args[1]) if len(args) == 2 else "all"
    if comp not in _DELETE_COMPONENTS:
        raise CGARuntimeError(f"{name}: components must be one of {', '.join(_DELETE_COMPONENTS)}"
                              f", not '{comp}'")
    return (to_str(args[0]) if args else ""), comp


@shape_function("geometry.hasTags")
def _has_tags(env, args):
    """``geometry.hasTags([query[, components]])``: whether a face, edge or vertex of the
    geometry itself has a tag (one the query matches); neighbours' tags do not count."""
    query, comp = _query_args(args, "geometry.hasTags")
    rx = _query(query)
    return any(_any_match(rx, t) for t in _stored(env.state.geometry, comp))


@shape_function("geometry.tags")
def _tags(env, args):
    """``geometry.tags([query[, components]])``: the distinct tags on the geometry's faces,
    edges and vertices (those the query matches), sorted alphabetically."""
    query, comp = _query_args(args, "geometry.tags")
    rx = _query(query)
    found = {t for ts in _stored(env.state.geometry, comp) for t in ts if rx.match(t)}
    return np.array(sorted(found), dtype=object)
