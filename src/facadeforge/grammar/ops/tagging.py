"""Geometry tags (CityEngine 2023.0+): strings stored on a geometry's faces that name its parts.

Reference: "Geometry Tagging: Essential Knowledge"
(https://esri.github.io/cityengine-sdk/html/cgaref/cgareference/cga_componentTags.html) and the
``tag``, ``deleteTags``, ``geometry.hasTags`` and ``geometry.tags`` pages.

* A tag is a string; ``.`` groups it into subtags (``"Facade.Front"``).  A *tag query* may use
  ``?`` for exactly one subtag and ``*`` for one or more, and matches a tag when it matches the
  tag's leading subtags: ``"Facade"`` matches ``"Facade.Front"`` (:func:`matches`).
* Tags live in the mesh's face column ``tags`` (a tuple of strings per face), so every operation
  that keeps, cuts or copies faces carries them the way it carries the faces' materials: a split
  piece keeps its face's tags, a new cap face has none, a face built from a face (an extrusion's
  sides and top) takes its face's.
* Auto-tags: ``extrude``, ``taper``, ``envelope``, the roof operations and the Boolean
  operations name the parts they build (``"extrude.top"``, ``"roof.…"``); calling the operation
  again replaces its earlier auto-tags (:func:`auto_tag`).
* ``comp(f) { isTagged("extrude.top") : Top | … }`` selects the faces with a matching tag.
"""

from __future__ import annotations

import re
from functools import lru_cache

import numpy as np

from .. import ast as A
from ..values import CGARuntimeError, to_str
from . import operation, shape_function

TAGS = "tags"  # the face column


def clean_tag(name: str) -> str:
    """A tag name as CityEngine stores it: the reserved wildcards ``?`` and ``*`` filtered out,
    empty subtags dropped (``"a..b"`` is ``"a.b"``)."""
    name = name.replace("?", "").replace("*", "")
    return ".".join(p for p in name.split(".") if p)


@lru_cache(maxsize=4096)
def _query_regex(query: str) -> re.Pattern:
    parts = [p for p in query.split(".") if p]
    sub = r"[^.]+"
    body = r"\.".join(sub if p == "?" else rf"{sub}(?:\.{sub})*" if p == "*" else re.escape(p)
                      for p in parts)
    return re.compile(rf"{body}(?:\..+)?\Z" if body else r".*\Z", re.DOTALL)


def matches(query: str, tag: str) -> bool:
    """Whether tag ``query`` matches ``tag``: subtag by subtag (``?`` one subtag, ``*`` one or
    more), the tag may go on with more subtags; the empty query matches every tag."""
    return _query_regex(query).match(tag) is not None


def face_tags(mesh) -> np.ndarray:
    """(F,) object array: each face's tags as a tuple (``()`` when it has none)."""
    col = mesh.column(TAGS)
    out = np.empty(mesh.n_faces, dtype=object)
    out[:] = [()] * mesh.n_faces if col is None else [t or () for t in col]
    return out


def tagged_faces(mesh, query: str) -> np.ndarray:
    """(F,) bool: faces with at least one tag matched by ``query``."""
    col = mesh.column(TAGS)
    if col is None:
        return np.zeros(mesh.n_faces, bool)
    rx = _query_regex(query)
    return np.array([any(rx.match(t) for t in (ts or ())) for ts in col], dtype=bool)


def with_tags(mesh, tags) -> object:
    """``mesh`` with the per-face tag tuples ``tags`` (no column when no face has a tag)."""
    if not any(tags):
        return mesh.without_columns(TAGS)
    return mesh.with_column(TAGS, [tuple(t) if t else None for t in tags])


def add_tag(mesh, name: str, faces=None):
    """``mesh`` with tag ``name`` added to ``faces`` (a bool mask; all when None)."""
    old = face_tags(mesh)
    pick = np.ones(mesh.n_faces, bool) if faces is None else faces
    return with_tags(mesh, [t + (name,) if p and name not in t else t for t, p in zip(old, pick)])


def auto_tag(mesh, op: str, parts) -> object:
    """``mesh`` after operation ``op`` built it: each face's earlier ``op`` auto-tags are
    replaced by ``op + "." + part`` (``parts`` per face; an empty part adds none)."""
    old = face_tags(mesh)
    rx = _query_regex(op)
    new = []
    for t, part in zip(old, parts):
        kept = tuple(x for x in t if not rx.match(x))
        new.append(kept + (f"{op}.{part}",) if part else kept)
    return with_tags(mesh, new)


# ---- the comp selector ---------------------------------------------------------------------

class TagQuery:
    """The comp selector ``isTagged(query)``."""

    __slots__ = ("query",)

    def __init__(self, query: str):
        self.query = query

    def faces(self, mesh) -> np.ndarray:
        return tagged_faces(mesh, self.query)

    def __str__(self) -> str:  # comp.sel
        return f'isTagged("{self.query}")'


def tag_selector(expr, env) -> TagQuery | None:
    """The :class:`TagQuery` of a comp selector written ``isTagged(query)``, else None."""
    if isinstance(expr, A.Call) and expr.name == "isTagged":
        if len(expr.args) != 1:
            raise CGARuntimeError(f"isTagged takes one tag query, got {len(expr.args)} arguments; "
                                  'e.g. comp(f) { isTagged("extrude.top") : Top }')
        return TagQuery(to_str(env.evaluator(expr.args[0])))
    return None


# ---- operations ------------------------------------------------------------------------------

_COMPONENTS = ("auto", "faces", "edges", "vertices", "all")


def _components(call, i: int, default: str, allowed) -> str:
    comp = call.sel(i, default)
    if comp not in allowed:
        raise CGARuntimeError(f"{call.name}: components must be one of {', '.join(allowed)}, "
                              f"not '{comp}'")
    return comp


@operation("tag", 1, 2, selectors=(1,))
def op_tag(call):
    """``tag(name)``, ``tag(name, auto|faces|edges|vertices)``: add tag ``name`` (wildcards
    filtered out) to every face.  Tags are kept on faces only: ``auto`` and ``faces`` tag the
    faces; edge and vertex tags are not stored, so ``edges`` and ``vertices`` are a warning."""
    comp = _components(call, 1, "auto", _COMPONENTS[:4])
    name = clean_tag(call.text(0))
    st = call.state
    if not name or not st.geometry.n_faces:
        return
    if comp in ("edges", "vertices"):
        raise CGARuntimeError(f"tag: {comp} tags are not supported (faces only); "
                              "the shape is left unchanged")
    st.geometry = add_tag(st.geometry, name)


@operation("deleteTags", 0, 2, selectors=(1,))
def op_delete_tags(call):
    """``deleteTags()``, ``deleteTags(query)``, ``deleteTags(query, all|faces|edges|vertices)``:
    remove the tags ``query`` matches (all tags without a query)."""
    comp = _components(call, 1, "all", ("all", "faces", "edges", "vertices"))
    query = call.text(0, "")
    st = call.state
    if comp in ("edges", "vertices") or st.geometry.column(TAGS) is None:
        return  # no edge or vertex tags are stored
    rx = _query_regex(query)
    st.geometry = with_tags(st.geometry, [tuple(t for t in ts if not rx.match(t))
                                          for ts in face_tags(st.geometry)])


# ---- functions -------------------------------------------------------------------------------

def _query_arg(args, name: str) -> str:
    if len(args) > 1:
        raise CGARuntimeError(f"{name} takes at most one tag query, got {len(args)} arguments")
    return to_str(args[0]) if args else ""


@shape_function("geometry.hasTags")
def _has_tags(env, args):
    """``geometry.hasTags()``, ``geometry.hasTags(query)``: whether any face has a tag (one the
    query matches)."""
    return bool(tagged_faces(env.state.geometry, _query_arg(args, "geometry.hasTags")).any())


@shape_function("geometry.tags")
def _tags(env, args):
    """``geometry.tags()``, ``geometry.tags(query)``: the distinct tags on the geometry (those
    the query matches), in order of first appearance over the faces."""
    rx = _query_regex(_query_arg(args, "geometry.tags"))
    seen: dict = {}
    for ts in face_tags(env.state.geometry):
        for t in ts:
            if rx.match(t):
                seen.setdefault(t, None)
    return np.array(list(seen), dtype=object)
