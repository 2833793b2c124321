"""Subdivision operations: ``split``, ``comp``, ``setback`` (CityEngine semantics)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ...errors import DerivationError
from ...geometry.cut import split_along_axis
from ...geometry.holed import (
    connected_faces,
    connected_parts,
    edge_corners,
    face_groups,
    outline,
    plane_polygon,
    rings,
    seams,
)
from ...geometry.mesh import EPS, Mesh, cross3, plane_basis, weld_ids
from ...geometry.polygon import simple_pieces
from ...model.scope import Scope
from .. import ast as A
from ..values import CGARuntimeError, Floating, Relative, to_bool, to_float
from . import operation
from .tagging import (
    EDGE_TAGS,
    TagIndex,
    auto_tag_edges,
    component_env,
    corner_tags,
    edges_with,
)
from .trimming import MeshEdges, comp_trim

_AXES = {"x": 0, "y": 1, "z": 2}

#: Face columns that describe the last ``offset`` (its ``inside``/``border`` parts): its
#: successors' splits and components no longer have them.
OFFSET_COLUMNS = ("kind",)


# ---- split --------------------------------------------------------------------------------

@dataclass
class SizeItem:
    kind: str  # "abs", "rel", "float"
    value: float
    branch: A.Branch


@dataclass
class RepeatItem:
    items: list


#: Pieces one split may make when no derivation bounds it by its own shape cap.
MAX_PIECES = 1_000_000


def resolve_split(items: list, total: float, max_pieces: int = MAX_PIECES,
                  notes: list | None = None) -> list[tuple[A.Branch, float, float]]:
    """Positions of the pieces of a split (CityEngine semantics).

    Parameters
    ----------
    items : list of SizeItem | RepeatItem
        The split pattern; a whole-split repeat ``{…}*`` is one ``RepeatItem``.
    total : float
        Scope size along the split axis.
    max_pieces : int
        More pieces than this raise :class:`DerivationError` (a repeat is never cut short
        silently).
    notes : list of str, optional
        Receives a note for each repeat that makes nothing because its sizes add up to no
        length (``{1e-300: B}*``), so the caller can warn.

    Returns
    -------
    list of (branch, start, size)
        Only pieces with positive size inside ``[0, total]``; the last one may be cut.

    Notes
    -----
    Absolute sizes are taken as is, relative ones (``'r``) as ``r * total``.  A repeat group is
    repeated ``n`` times: with floating sizes inside, ``n = max(1, rint(space / pattern))`` so the
    floats stretch as little as possible; with fixed sizes only, as often as it starts inside the
    space (the last copy is cut at the border).  Floating sizes then share what fixed sizes leave,
    in proportion to their nominal sizes; when nothing is left they are not generated.
    """
    def nominal(it: SizeItem) -> float:
        return it.value * total if it.kind == "rel" else it.value

    top_fixed = sum(nominal(it) for it in items if isinstance(it, SizeItem) and it.kind != "float")
    top_float = sum(it.value for it in items if isinstance(it, SizeItem) and it.kind == "float")
    groups = [it for it in items if isinstance(it, RepeatItem)]
    space = total - top_fixed - top_float
    pattern_len = [sum(max(nominal(x), 0.0) for x in g.items) for g in groups]
    all_len = sum(pattern_len)
    counts = _float_repeats(groups, pattern_len, top_fixed, top_float, total)
    flat: list[SizeItem] = []
    for it in items:
        if isinstance(it, SizeItem):
            flat.append(it)
            continue
        k = next(i for i, g in enumerate(groups) if g is it)  # by identity: alike repeats
        plen = pattern_len[k]
        if plen <= EPS:
            if notes is not None:
                notes.append(f"a repeat whose sizes add up to {plen:g} m (at most {EPS:g} m) "
                             "makes no pieces")
            continue
        share = space * plen / all_len if all_len > 0 else 0.0
        has_float = any(x.kind == "float" for x in it.items)
        if k in counts:
            n = counts[k]
        elif share <= EPS:
            n = 0
        elif has_float:
            n = max(1, int(math.floor(share / plen + 0.5)))
        else:
            n = int(math.ceil(share / plen - 1e-9))
        if n * len(it.items) > max_pieces:
            raise DerivationError(
                f"the repeat of {plen:g} m in {share:g} m makes {n * len(it.items):,} pieces, more "
                f"than the {max_pieces:,} shapes the derivation may still make; use larger sizes "
                "or split a smaller scope")
        flat.extend(it.items * n)
    fixed = sum(nominal(it) for it in flat if it.kind != "float")
    floats = sum(it.value for it in flat if it.kind == "float" and it.value > 0)
    rest = total - fixed
    out, pos = [], 0.0
    for it in flat:
        if it.kind == "float":
            size = it.value * rest / floats if (rest > EPS and floats > 0 and it.value > 0) else 0.0
        else:
            size = nominal(it)
        if size <= EPS:
            continue
        if pos >= total - EPS:
            break
        size = min(size, total - pos)
        out.append((it.branch, pos, size))
        pos += size
    return out


def _float_repeats(groups, pattern_len, top_fixed: float, top_float: float,
                   total: float) -> dict:
    """Copies of each repeat when every repeat of the split has floating sizes: the total
    number of copies (at least one a repeat) that stretches or squeezes the floating sizes the
    least — the room they get over their nominal sum closest to 1 — shared among the repeats
    in proportion to their pattern lengths, a remainder going to the last ones (Esri's Candler
    building: a 2.15 m window bay of ``{ ~0.72 : Window | 0.25 : Wall }* | ~0.72 : Window``
    holds three windows, a 23 m floor of two ``{ ~3.55 : Tile }*`` between fixed tiles holds
    one and two)."""
    if not groups or not all(any(x.kind == "float" for x in g.items) for g in groups):
        return {}
    if any(pl <= EPS for pl in pattern_len):
        return {}
    all_len = sum(pattern_len)
    space = total - top_fixed - top_float
    if space <= EPS:
        return {}
    g = len(groups)
    fixed_k = [sum(x.value * total if x.kind == "rel" else x.value for x in gr.items
                   if x.kind != "float") for gr in groups]
    float_k = [sum(x.value for x in gr.items if x.kind == "float") for gr in groups]
    x = space / (all_len / g)

    def counts(n: int) -> dict:
        shares = [n * pl / all_len for pl in pattern_len]
        out = {k: max(1, int(math.floor(v + 1e-9))) for k, v in enumerate(shares)}
        k = g - 1
        while sum(out.values()) < n:
            out[k] += 1
            k = k - 1 if k > 0 else g - 1
        return out

    best, best_dev = None, math.inf
    for n in sorted({max(g, int(math.floor(x))), max(g, int(math.ceil(x)))}):
        c = counts(n)
        floats = top_float + sum(c[k] * float_k[k] for k in c)
        room = total - top_fixed - sum(c[k] * fixed_k[k] for k in c)
        if floats <= EPS or room <= EPS:
            continue
        dev = abs(room / floats - 1.0)
        if dev < best_dev - 1e-12:
            best, best_dev = c, dev
    return best or {}


def call_pieces(call, total: float) -> list[tuple[A.Branch, float, float]]:
    """:func:`resolve_split` of a split call's branches (a whole-split ``{…}*`` repeats)."""
    items = _size_items(call.branches, call.env)
    if call.repeat:
        items = [RepeatItem(items)]
    d = getattr(call, "derivation", None)
    if d is None:
        return resolve_split(items, total)
    notes: list[str] = []
    pieces = resolve_split(items, total, max(d.limits.max_shapes - d.shape_count, 0), notes)
    for note in notes:
        d.warn(f"{call.name}: {note}")
    return pieces


def _size_items(branches, env) -> list:
    items = []
    for b in branches:
        if isinstance(b, A.RepeatGroup):
            items.append(RepeatItem(_size_items(b.branches, env)))
            continue
        v = env.evaluate(b.selector)
        if isinstance(v, Relative):
            items.append(SizeItem("rel", v.value, b))
        elif isinstance(v, Floating):
            items.append(SizeItem("float", v.value, b))
        else:
            items.append(SizeItem("abs", to_float(v, "split size"), b))
    return items


@operation("split", 1, 3, selectors=(0, 1), body=True)
def op_split(call):
    axis_name = call.sel(0)
    if axis_name in ("u", "v"):
        return _split_uv(call, "uv".index(axis_name))
    axis = _AXES.get(axis_name)
    if axis is None:
        raise CGARuntimeError(f"split axis must be x, y or z, not '{axis_name}'")
    adjust = call.sel(1, "adjust") != "noAdjust"
    st = call.state
    total = float(st.scope.size[axis])
    pieces = call_pieces(call, total)
    if not pieces:
        return []
    cuts = [pieces[0][1]] + [p[1] + p[2] for p in pieces]
    local = st.local_geometry()
    meshes = (split_along_axis(local, axis, np.array(cuts), tick=call.tick) if local.n_faces
              else [Mesh() for _ in pieces])
    rot, org, size = st.scope.rotation, st.scope.origin, st.scope.size
    keep = [i for i, m in enumerate(meshes) if m.n_faces or not local.n_faces]
    if not keep:
        return []
    # all pieces go to world coordinates in one product, their bounding boxes in one reduction
    if local.n_faces:
        verts = [meshes[i].vertices for i in keep]
        counts = np.array([len(v) for v in verts])
        allv = np.concatenate(verts)
        world = allv @ rot.T + org
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        lo = np.minimum.reduceat(allv, first, axis=0)
        hi = np.maximum.reduceat(allv, first, axis=0)
        origins = lo @ rot.T + org
        sizes = hi - lo
    out = []
    n = len(pieces)
    for j, i in enumerate(keep):
        if not j & 1023:
            call.tick()
        branch, start, width = pieces[i]
        mesh = meshes[i]
        ps = st.child(i)
        if local.n_faces:
            ps.geometry = mesh.with_vertices(world[first[j]:first[j] + counts[j]])
        else:
            ps.geometry = mesh
        if adjust and local.n_faces:
            ps.scope = Scope.trusted(origins[j], rot, sizes[j])
        else:
            o = np.zeros(3)
            o[axis] = start
            sz = size.copy()
            sz[axis] = width
            ps.scope = Scope.trusted(o @ rot.T + org, rot, sz)
        ps.geometry = ps.geometry.without_columns(*OFFSET_COLUMNS)
        ctx = dict(st.context)
        ctx["split.index"] = i
        ctx["split.total"] = n
        ps.context = ctx
        out.append((ps, branch.ops, {"axis": axis_name, "index": i}))
    return out


def _split_uv(call, k: int):
    """``split(u|v, uvSpace|unitSpace, uvSet){…}``: cut faces at texture coordinates.

    Borders are the min/max of the selected coordinate over the geometry; ``unitSpace`` sizes are
    metres on the surface, converted with the metres-per-uv-unit of the first face (exact for
    planar projections, approximate for distorted parameterisations).
    """
    st = call.state
    space = call.sel(1, "uvSpace")
    mesh = st.geometry
    if mesh.corner_uvs is None or not mesh.n_faces:
        raise CGARuntimeError("split(u|v): the shape has no texture coordinates (projectUV first)")
    uv = mesh.corner_uvs
    lo, hi = float(uv[:, k].min()), float(uv[:, k].max())
    scale = 1.0
    if space == "unitSpace":
        scale = _metres_per_uv(mesh, k)
    total = (hi - lo) * scale
    pieces = call_pieces(call, total)
    out = []
    n = len(pieces)
    for i, (branch, start, width) in enumerate(pieces):
        a, b = lo + start / scale, lo + (start + width) / scale
        polys, uvs, source = [], [], []
        for f in range(mesh.n_faces):
            c0, c1 = mesh.starts[f], mesh.starts[f + 1]
            pts = np.column_stack([uv[c0:c1], mesh.vertices[mesh.corners[c0:c1]]]).tolist()
            for value, keep_below in ((b, True), (a, False)):
                pts = _clip_generic(pts, k, value, keep_below)
                if len(pts) < 3:
                    break
            if len(pts) >= 3:
                arr = np.array(pts)
                polys.append(arr[:, 2:5])
                uvs.append(arr[:, 0:2])
                source.append(f)
        if not polys:
            continue
        ps = st.child(i)
        ps.geometry = Mesh.from_polygons(polys, uvs).inherit(mesh, source, drop=OFFSET_COLUMNS)
        ps.fit_scope()
        ctx = dict(st.context)
        ctx["split.index"], ctx["split.total"] = i, n
        ps.context = ctx
        out.append((ps, branch.ops, {"axis": "uv"[k], "index": i}))
    return out


def _metres_per_uv(mesh: Mesh, k: int) -> float:
    c0, c1 = mesh.starts[0], mesh.starts[1]
    uv = mesh.corner_uvs[c0:c1]
    p = mesh.vertices[mesh.corners[c0:c1]]
    a = np.column_stack([uv, np.ones(len(uv))])
    coef, *_ = np.linalg.lstsq(a, p, rcond=None)  # p ≈ u * du + v * dv + p0
    m = float(np.linalg.norm(coef[k]))
    return m if m > EPS else 1.0


def _clip_generic(pts: list, axis: int, value: float, keep_below: bool) -> list:
    """Sutherland–Hodgman on points of any dimension, keeping ``p[axis] <= value`` (or ``>=``)."""
    sign = 1.0 if keep_below else -1.0
    d = [(q[axis] - value) * sign for q in pts]
    out = []
    k = len(pts)
    for j in range(k):
        jn = (j + 1) % k
        if d[j] <= EPS:
            out.append(pts[j])
        if (d[j] < -EPS and d[jn] > EPS) or (d[j] > EPS and d[jn] < -EPS):
            t = d[j] / (d[j] - d[jn])
            out.append([x + t * (y - x) for x, y in zip(pts[j], pts[jn])])
    return out


# ---- comp ---------------------------------------------------------------------------------

_DIRS = ("right", "left", "top", "bottom", "front", "back")  # +x, -x, +y, -y, +z, -z
_WORLD = {"world.east": 0, "world.west": 1, "world.up": 2, "world.down": 3, "world.south": 4,
          "world.north": 5}


def _direction_index(local_normals: np.ndarray) -> np.ndarray:
    """Index into ``_DIRS`` of the quadrant each (F, 3) normal falls in."""
    ax = np.argmax(np.abs(local_normals), axis=1)
    neg = local_normals[np.arange(len(ax)), ax] < 0
    return ax * 2 + neg


def _angle_class(local_y: np.ndarray) -> np.ndarray:
    ang = np.degrees(np.arcsin(np.clip(local_y, -1, 1)))
    out = np.full(len(ang), "vertical", dtype=object)
    out[ang > 11.25] = "aslant"
    out[ang > 78.75] = "horizontal"
    out[ang < -11.25] = "nutant"
    out[ang < -78.75] = "horizontal"
    return out


class FaceSelectors(Mapping):
    """Selector keywords matching each face: ``{keyword: (F,) bool}``, each family of keywords
    (the scope's directions and slopes, ``object.*`` and ``street.*``, ``world.*``) worked out
    when one of its words is first asked for; a ``comp`` usually asks for a few."""

    _SCOPE = (*_DIRS, "vertical", "horizontal", "aslant", "nutant", "side")
    _OBJECT = (*("object." + d for d in _DIRS), "object.side", *("street." + d for d in _DIRS),
               "street.side", "streetSide", "noStreetSide")
    _WORLDS = (*_WORLD, "world.side")
    _KEYS = (*_SCOPE, *_OBJECT, *_WORLDS, "all")
    _FAMILY = {**{k: "scope" for k in _SCOPE}, **{k: "object" for k in _OBJECT},
               **{k: "world" for k in _WORLDS}, "all": "all"}

    def __init__(self, normals: np.ndarray, scope_rot: np.ndarray, object_rot: np.ndarray):
        self.normals, self.scope_rot, self.object_rot = normals, scope_rot, object_rot
        self._sel: dict = {}

    def __getitem__(self, key):
        sel = self._sel
        if key not in sel:
            family = self._FAMILY[key]  # KeyError for an unknown word, as a dict
            getattr(self, "_" + family)(sel)
        return sel[key]

    def __contains__(self, key) -> bool:
        return key in self._FAMILY

    def __iter__(self):
        return iter(self._KEYS)

    def __len__(self) -> int:
        return len(self._KEYS)

    def _scope(self, sel: dict) -> None:
        loc = self.normals @ self.scope_rot
        d = _direction_index(loc)
        for i, name in enumerate(_DIRS):
            sel[name] = d == i
        ang = _angle_class(loc[:, 1])
        for k in ("vertical", "horizontal", "aslant", "nutant"):
            sel[k] = ang == k
        sel["side"] = ~sel["horizontal"]  # CityEngine: every face that is not horizontal

    def _object(self, sel: dict) -> None:
        obj = _direction_index(self.normals @ self.object_rot)
        for i, name in enumerate(_DIRS):
            sel["object." + name] = obj == i
        sel["object.side"] = (obj < 2) | (obj >= 4)
        # street.* need street widths on the initial shape; without them CityEngine falls back
        # to the object frame (reference, "comp operation")
        _add_street_fallback(sel)

    def _world(self, sel: dict) -> None:
        wd = _direction_index(self.normals)
        for name, i in _WORLD.items():
            sel[name] = wd == i
        sel["world.side"] = (wd < 2) | (wd >= 4)

    def _all(self, sel: dict) -> None:
        sel["all"] = np.ones(len(self.normals), bool)


def classify_faces(normals: np.ndarray, scope_rot: np.ndarray, object_rot: np.ndarray):
    """Selector keywords matching each face (:class:`FaceSelectors`)."""
    return FaceSelectors(normals, scope_rot, object_rot)


def face_scope(poly: np.ndarray, normal: np.ndarray) -> Scope:
    """Scope of a face: x along its first edge, z along its normal, fitted to the face."""
    origin, rot, size = face_frames(Mesh.from_polygons([poly]), np.asarray(normal, float)[None])
    return Scope.trusted(origin[0], rot[0], size[0])


def face_frames(mesh: Mesh, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scope of every face of ``mesh`` (unit ``normals``) in one vectorised pass, as
    origins (F, 3), rotations (F, 3, 3) and sizes (F, 3): x along the face's first edge that is
    not of zero length, z along its normal, fitted to the face; a face without normal or such
    an edge gets the world axes and its bounding box."""
    starts = mesh.starts
    sizes = np.diff(starts)
    n_corners = int(starts[-1])
    pos = mesh.vertices[mesh.corners]
    face_of = np.repeat(np.arange(mesh.n_faces), sizes)
    nxt = np.arange(1, n_corners + 1)
    nxt[starts[1:] - 1] = starts[:-1]
    nc = normals[face_of]
    e = pos[nxt] - pos
    e = e - nc * np.einsum("ij,ij->i", e, nc)[:, None]
    length = np.sqrt(np.einsum("ij,ij->i", e, e))
    first = np.minimum.reduceat(np.where(length > EPS, np.arange(n_corners), n_corners),
                                starts[:-1])
    good = (first < starts[1:]) & normals.any(axis=1)
    rot = np.broadcast_to(np.eye(3), (mesh.n_faces, 3, 3)).copy()
    if good.any():
        x = e[first[good]] / length[first[good]][:, None]
        z = normals[good]
        rot[good] = np.stack([x, cross3(z, x), z], axis=2)
    p0 = pos[starts[:-1]]
    # (row vector) @ matrix, as Scope.fit_to computes it, so a face's scope is bit for bit the
    # one face_scope gave when it was a loop of its own
    local = np.matmul((pos - p0[face_of])[:, None, :], rot[face_of])[:, 0]
    lo = np.minimum.reduceat(local, starts[:-1], axis=0)
    hi = np.maximum.reduceat(local, starts[:-1], axis=0)
    return np.matmul(lo[:, None, :], rot.transpose(0, 2, 1))[:, 0] + p0, rot, hi - lo


#: Selector keywords of comp, setback and their kin: a name among these is the selector even
#: where a rule has an attribute of that name (``attr shape = "auto"`` beside ``{ shape : … }``)
SELECTOR_WORDS = frozenset({
    "front", "back", "left", "right", "top", "bottom", "side", "vertical", "horizontal",
    "aslant", "nutant", "all", "inside", "border", "remainder", "shape", "streetSide",
    "noStreetSide", "eave", "ridge", "hip", "valley"})


class LogicalSelector:
    """A selector that is an expression over components: ``isTagged(…)``, or selector words
    combined with ``!``, ``&&`` and ``||`` (CityEngine 2023.1, "logical selector expressions").
    It is evaluated once per component with the words bound to that component's truth values;
    other names and functions in it (``scope.sy``, ``geometry.area``, a user function) read
    the component's shape where the operation provides one (``comp(f)``, ``comp(e)``), else
    the shape being split."""

    __slots__ = ("expr", "env")

    def __init__(self, expr, env):
        self.expr, self.env = expr, env

    @staticmethod
    def wanted(expr) -> bool:
        return (isinstance(expr, A.Call) and expr.name == "isTagged") or (
            isinstance(expr, A.Unary) and expr.op == "!") or (
            isinstance(expr, A.Binary) and expr.op in ("&&", "||"))

    @staticmethod
    def _nodes(node):
        """The expression's nodes, depth first."""
        yield node
        for child in vars(node).values():
            for c in child if isinstance(child, tuple) else (child,):
                if isinstance(c, A.Node):
                    yield from LogicalSelector._nodes(c)

    def mask(self, table: dict, n: int, tags, states=None) -> np.ndarray:
        """(n,) bool; ``tags(query, sub)`` gives the components a tag query selects,
        ``states(i)`` component ``i``'s shape."""
        nodes = list(self._nodes(self.expr))
        words = {x.name: table[x.name] for x in nodes
                 if isinstance(x, A.Name) and x.name in table}
        # anything but selector words, isTagged and literals reads the component's own shape
        reads_shape = any((isinstance(x, A.Name) and x.name not in table
                           and x.name not in ("e", "v"))
                          or (isinstance(x, A.Call) and x.name != "isTagged") for x in nodes)
        masks: dict = {}
        index = tags if tags is not None else (lambda q, sub: np.zeros(n, bool))
        own = states is not None and reads_shape
        return np.array([to_bool(component_env(self.env, i, words, masks, index,
                                               states(i) if own else None)
                                 .evaluate(self.expr)) for i in range(n)], bool)

    def __str__(self) -> str:  # comp.sel
        return _selector_text(self.expr)


def _selector_text(node) -> str:
    if isinstance(node, A.Name):
        return node.name
    if isinstance(node, A.Str):
        return f'"{node.value}"'
    if isinstance(node, A.Call):
        return f"{node.name}({', '.join(_selector_text(a) for a in node.args)})"
    if isinstance(node, A.Unary):
        return node.op + _selector_text(node.operand)
    if isinstance(node, A.Binary):
        return f"{_selector_text(node.left)} {node.op} {_selector_text(node.right)}"
    return "…"


def _tag_masks(mesh, kind: str):
    """``(query, sub) -> mask`` over ``mesh``'s components of ``kind`` (f, e, v, or p: the
    edges of a single polygon in corner order), its tag index built on first use."""
    built: list = []

    def masks(query, sub):
        if not built:
            built.append(TagIndex(mesh))
        ix = built[0]
        return {"f": ix.faces, "e": ix.edges, "v": ix.vertices, "p": ix.polygon_edges}[kind](
            query, sub)
    return masks


def _selector_key(call, branch) -> object:
    s = branch.selector
    env = call.env
    if LogicalSelector.wanted(s):
        return LogicalSelector(s, env)
    if isinstance(s, A.Name) and (s.name in SELECTOR_WORDS or not (
            s.name in env.locals or env.module.attr(s.name) is not None
            or env.module.function(s.name, 0) is not None)):
        return s.name   # a selector keyword; a parameter or attribute is its value (an index)
    v = env.evaluate(s)
    if isinstance(v, bool):
        return v
    if isinstance(v, (int, float)):
        return int(v)
    return str(v)


#: context key marking the shapes ``comp(e|fe)`` and ``comp(v|fv)`` make: their geometry is their
#: scope (an edge along scope x, a vertex at the origin), not a mesh (docs/cga-dialect.md)
SHAPE_KIND = "shape.kind"


def edge_or_vertex(st) -> str | None:
    """``"edge"`` or ``"vertex"`` for a shape ``comp(e|v)`` made (and its split pieces), while
    it has no mesh of its own; else ``None``."""
    return None if st.geometry.n_faces else st.context.get(SHAPE_KIND)


def component_count(st, kind: str) -> int:
    """Number of components ``comp(kind)`` splits the shape into (the comp function's size)."""
    mesh = st.geometry
    lower = edge_or_vertex(st)
    if lower is not None:  # an edge: 0 faces, 1 edge, 2 vertices; a vertex: 1 vertex
        return {"f": 0, "e": int(lower == "edge"), "fe": int(lower == "edge"),
                "v": 1 + (lower == "edge"), "fv": 1 + (lower == "edge")}.get(kind, 0)
    if kind == "f":
        return len(face_groups(mesh)) if mesh.column("holed") is not None else mesh.n_faces
    if kind in ("v", "fv"):
        return len(vertex_points(mesh, kind == "fv")[0])
    if kind == "fe" and mesh.column("holed") is None:
        return len(mesh.corners)
    if kind in ("e", "fe") and mesh.column("holed") is not None:  # seams are no edges
        weld = weld_ids(mesh.vertices)
        inner = seams(mesh, weld)
        if kind == "fe":  # as comp(fe) lists them
            return len(edge_corners(mesh, weld, inner))
        keys = [(min(weld[a], weld[b]), max(weld[a], weld[b]))
                for a, b in zip(mesh.corners, mesh.corners[mesh.next_corners()])]
        return len({k for k in keys if k[0] != k[1]} - inner)
    if kind == "h":
        return len(hole_polygons(mesh))
    if kind in ("m", "g"):
        return len(_part_faces(st, kind))
    return len(mesh.welded_edges()[0])


def _add_street_selectors(table: dict, outward=None, object_rot=None) -> None:
    """Edge selectors beyond the scope quadrants: ``object.*`` and ``world.*`` (the edges'
    outward directions, world vectors ``outward``, classified in the initial shape's frame and
    the world's), ``street.*`` and the older ``streetSide``/``noStreetSide``.  Without street
    widths on the initial shape (we have none) CityEngine falls back to ``object.*`` for
    ``street.*`` (reference, "setback operation"); ``streetSide`` is then the street front."""
    if outward is not None and object_rot is not None:
        obj = _direction_index(outward @ object_rot)
        wd = _direction_index(outward)
        for i, name in enumerate(_DIRS):
            table["object." + name] = obj == i
        table["object.side"] = (obj < 2) | (obj >= 4)
        for name, i in _WORLD.items():
            table[name] = wd == i
        table["world.side"] = (wd < 2) | (wd >= 4)
    else:
        for name in _DIRS:
            table["object." + name] = table[name]
        table["object.side"] = table["side"]
    _add_street_fallback(table)


def _add_street_fallback(table: dict) -> None:
    for name in _DIRS:
        table["street." + name] = table["object." + name]
    table["street.side"] = table["object.left"] | table["object.right"]
    table["streetSide"] = table["street.front"]
    table["noStreetSide"] = ~table["street.front"]


@operation("comp", 1, 2, selectors=(0, 1), body=True)
def op_comp(call):
    kind = call.sel(0)
    align = call.sel(1, "zUp")
    if align not in ("zUp", "noAlign"):
        raise CGARuntimeError(f"comp: unknown scope alignment '{align}'; use zUp or noAlign")
    st = call.state
    if kind == "f":
        pieces = _comp_faces(call, st)
    elif kind in ("e", "fe"):
        pieces = _comp_edges(call, st, per_face=kind == "fe")
    elif kind in ("v", "fv"):
        pieces = _comp_vertices(call, st, per_face=kind == "fv")
    elif kind == "h":
        pieces = _comp_holes(call, st)
    elif kind in ("m", "g"):
        pieces = _comp_parts(call, st, kind)
    else:
        raise CGARuntimeError(f"comp({kind}) is not a component type; use f, e, v, fe, fv, m, "
                              "g or h")
    if align == "noAlign":
        # CityEngine: pivot and scope keep their orientation; size and position fit the piece
        for ps, _, _ in pieces:
            ps.scope = st.scope
            ps.fit_scope()
    else:
        # zUp (default): "pivot and scope are aligned" – each piece's pivot is its scope frame
        from .scoping import set_pivot_frame

        for ps, _, _ in pieces:
            set_pivot_frame(ps, ps.scope.origin, ps.scope.rotation)
    return pieces


def _part_faces(st, kind: str) -> list:
    """Face index arrays of the components of ``comp(m|g)``.

    ``m``: one component per material, in order of first use (an inserted asset's own materials
    count; a shape without per-face materials is one component).  ``g``: one per OBJ group of
    an inserted asset (face column ``group``), in the file's order; geometry without groups is
    one group, as in CityEngine.  (``comp(h)``: :func:`_comp_holes`.)"""
    n = st.geometry.n_faces
    if n == 0:
        return []
    column = st.geometry.column("material" if kind == "m" else "group")
    if column is not None:
        groups: dict = {}
        for f, m in enumerate(column):
            groups.setdefault(id(m) if kind == "m" else m, []).append(f)
        keys = list(groups) if kind == "m" else sorted(groups, key=lambda g: (g is None, g))
        return [np.array(groups[k]) for k in keys]
    return [np.arange(n)]


def hole_polygons(mesh: Mesh) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(polygon, normal)`` filling each hole of the mesh's faces with holes, turned the way
    its face is (a face with holes is pieces sharing an id, ``geometry.holed``)."""
    out = []
    if mesh.column("holed") is None:
        return out
    normals = mesh.face_normals()
    for group in face_groups(mesh):
        if len(group) < 2:
            continue
        f = group[0]
        p = mesh.vertices[mesh.face(f)]
        basis = plane_basis(normals[f], p[1] - p[0])
        for _, holes in rings(plane_polygon(mesh, group, p[0], basis)):
            for h in holes:
                out.append((p[0] + h[::-1] @ basis[:, :2].T, normals[f]))
    return out


def _comp_holes(call, st):
    """``comp(h)``: one shape per hole of the faces with holes, the hole's polygon facing the
    way its face does (reference: hole components)."""
    holes = hole_polygons(st.geometry)
    n = len(holes)
    out, taken = [], np.zeros(n, bool)
    for branch in call.branches:
        if isinstance(branch, A.RepeatGroup):
            raise CGARuntimeError("comp bodies cannot contain repeat groups")
        key = _selector_key(call, branch)
        m = _match(key, {"all": np.ones(n, bool)}, n) & ~taken
        taken |= m
        idx = np.flatnonzero(m)
        sel_name = key if isinstance(key, str) else str(key)
        if branch.mode == "=" and len(idx):
            idx_groups = [idx]
        else:
            idx_groups = [[i] for i in idx]
        for j, chosen in enumerate(idx_groups):
            ps = st.child(len(out))
            ps.geometry = Mesh.from_polygons([holes[i][0] for i in chosen])
            ps.scope = face_scope(holes[chosen[0]][0], holes[chosen[0]][1])
            ps.fit_scope()
            ps.context = {**st.context, "comp.index": j, "comp.total": len(idx_groups),
                          "comp.sel": sel_name}
            out.append((ps, branch.ops, {"sel": sel_name, "index": j,
                                         "components": [int(i) for i in chosen]}))
    return out


def _comp_parts(call, st, kind: str):
    """``comp(m|g)``: components made of several faces keep the shape's scope orientation,
    fitted to the component."""
    parts = _part_faces(st, kind)
    out, taken = [], np.zeros(len(parts), bool)
    faces = _tag_masks(st.geometry, "f")

    def tags(query, sub):  # a group or material is tagged when one of its faces is
        hit = faces(query, sub)
        return np.array([hit[p].any() for p in parts], bool)

    for branch in call.branches:
        if isinstance(branch, A.RepeatGroup):
            raise CGARuntimeError("comp bodies cannot contain repeat groups")
        key = _selector_key(call, branch)
        m = _match(key, {"all": np.ones(len(parts), bool)}, len(parts), None, tags) & ~taken
        taken |= m
        idx = np.flatnonzero(m)
        sel_name = key if isinstance(key, str) else str(key)
        if branch.mode == "=" and len(idx):
            groups = [np.concatenate([parts[i] for i in idx])]
        elif branch.mode == "=:" and len(idx):  # the selected components that connect
            chosen = [parts[i] for i in idx]
            groups = [np.concatenate([chosen[k] for k in g])
                      for g in connected_parts(st.geometry, chosen)]
        else:
            groups = [parts[i] for i in idx]
        for j, faces in enumerate(groups):
            ps = st.child(len(out))
            ps.geometry = st.geometry.subset(faces).without_columns(*OFFSET_COLUMNS)
            ps.fit_scope()
            ps.context = {**st.context, "comp.index": j,
                          "comp.total": len(groups), "comp.sel": sel_name}
            out.append((ps, branch.ops, {"sel": sel_name, "index": j,
                                         "components": faces.tolist()}))
    return out


def _match(key, sel_table, n, extra=None, tags=None, states=None) -> np.ndarray:
    """Components ``key`` selects: a word of ``sel_table`` or ``extra`` (arrays of n), an index,
    a bool, or a :class:`LogicalSelector` (``tags``: ``(query, sub) -> mask`` for its
    ``isTagged``, ``states(i)``: component ``i``'s shape for the rest of it)."""
    if isinstance(key, LogicalSelector):
        return key.mask({**sel_table, **(extra or {})}, n, tags, states)
    if isinstance(key, bool):
        return np.full(n, key)
    if isinstance(key, int):
        m = np.zeros(n, bool)
        if 0 <= key < n:
            m[key] = True
        return m
    if extra is not None and key in extra:
        return extra[key]
    if key in sel_table:
        return sel_table[key]
    raise CGARuntimeError(f"unknown comp selector '{key}'")


def _comp_faces(call, st):
    """``comp(f)``: one component per face, the pieces of a face with holes being one face
    (``geometry.holed``): its selectors, index, scope (from its outline) and comp function
    value are the whole face's."""
    mesh = st.geometry
    if mesh.n_faces == 0:
        return []
    normals = mesh.face_normals()
    groups = face_groups(mesh) if mesh.column("holed") is not None else None
    # selectors per face with holes: its first piece's (all coplanar); still worked out lazily
    firsts = np.array([g[0] for g in groups]) if groups is not None else None
    table = classify_faces(normals if firsts is None else normals[firsts], st.scope.rotation,
                           call.derivation.object_scope.rotation)
    kinds = mesh.column("kind")
    if kinds is not None:
        extra = {"inside": kinds == "inside", "border": kinds == "border"}
    else:
        extra = {"inside": np.zeros(mesh.n_faces, bool), "border": np.zeros(mesh.n_faces, bool)}
    tags = _tag_masks(mesh, "f")
    if groups is not None:
        extra = {k: v[firsts] for k, v in extra.items()}
        face_tags = tags

        def tags(query, sub):  # noqa: F811 -- a face with holes is tagged as its pieces are
            hit = face_tags(query, sub)
            return np.array([hit[g].any() for g in groups], bool)
    n = len(groups) if groups is not None else mesh.n_faces

    def members(i) -> list[int]:
        return groups[i] if groups is not None else [int(i)]

    frames: list = []  # every face's scope frame, worked out at the first need

    def comp_scope(i):
        if groups is None:
            if not frames:
                frames.extend(face_frames(mesh, normals))
            return Scope.trusted(frames[0][i], frames[1][i], frames[2][i])
        faces = members(i)
        ring = mesh.vertices[mesh.face(faces[0])] if len(faces) == 1 else outline(mesh, faces)
        lead = next((f for f in faces if normals[f].any()), faces[0])
        return face_scope(ring, normals[lead])

    def face_state(i):  # a component's own shape, for logical selectors that read it
        ps = st.copy()
        ps.geometry = mesh.subset(members(i))
        ps.scope = comp_scope(i)
        return ps

    taken = np.zeros(n, bool)
    out = []
    edges = MeshEdges(mesh)  # trim planes, worked out only if a successor needs them
    for branch in call.branches:
        if isinstance(branch, A.RepeatGroup):
            raise CGARuntimeError("comp bodies cannot contain repeat groups")
        key = _selector_key(call, branch)
        m = _match(key, table, n, extra, tags, face_state) & ~taken
        idx = np.flatnonzero(m)
        taken |= m
        if len(idx) == 0:
            continue
        sel_name = key if isinstance(key, str) else str(key)
        if branch.mode in ("=", "=:"):
            # "=": the selected faces as one shape; "=:" (CityEngine 2025.0): one shape per
            # connected piece of them (faces sharing an edge, coincident vertices welded)
            selected = [f for i in idx for f in members(i)]
            pieces = [selected] if branch.mode == "=" else connected_faces(mesh, selected)
            component_of = {f: int(i) for i in idx for f in members(i)}
            for j, faces in enumerate(pieces):
                group = list(dict.fromkeys(component_of[f] for f in faces))
                ps = st.child(len(out))
                ps.scope = comp_scope(group[0])
                ps.geometry = mesh.subset(faces).without_columns(*OFFSET_COLUMNS)
                ps.fit_scope()
                ps.trim = comp_trim(st, edges, np.array(faces), ps.scope)
                ps.context = {**st.context, "comp.index": j, "comp.total": len(pieces),
                              "comp.sel": sel_name}
                info = {"sel": sel_name, "components": group}
                if branch.mode == "=:":
                    info["index"] = j
                out.append((ps, branch.ops, info))
            continue
        geoms = mesh.single_faces(idx) if groups is None else None
        for j, i in enumerate(idx):
            faces = members(i)
            ps = st.child(len(out))
            ps.scope = comp_scope(i)
            ps.geometry = (geoms[j] if geoms is not None else mesh.subset(faces)
                           ).without_columns(*OFFSET_COLUMNS)
            if len(faces) > 1:
                ps.fit_scope()
            ps.trim = comp_trim(st, edges, tuple(faces), ps.scope)
            ps.context = {**st.context, "comp.index": j,
                          "comp.total": len(idx), "comp.sel": sel_name}
            out.append((ps, branch.ops, {"sel": sel_name, "index": j, "component": int(i)}))
    return out


def _comp_edges(call, st, per_face: bool = False):
    """``comp(e)``: the edges, coincident vertices welded, each once; ``comp(fe)``
    (``per_face``): every face's edges, so an edge two faces share is two components, each
    seen from its own face."""
    mesh = st.geometry
    if mesh.n_faces == 0:
        return []
    weld = weld_ids(mesh.vertices)
    edges, seen, edge_faces = [], {}, []
    normals = mesh.face_normals()
    corner_edge = []
    nxt = mesh.next_corners()
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    # each face's edges in turn, a face with holes' as its rings (seams between pieces are none)
    for c in edge_corners(mesh, weld).tolist():
        a, b, f = mesh.corners[c], mesh.corners[nxt[c]], int(face_of[c])
        k = (min(weld[a], weld[b]), max(weld[a], weld[b]))
        corner_edge.append((a, b, f, seen.get(k, len(edges)) if k[0] != k[1] else -1))
        if k[0] == k[1]:
            continue
        if k in seen:
            edges[seen[k]][3] += 1
            edge_faces[seen[k]].append(f)
            continue
        seen[k] = len(edges)
        edges.append([mesh.vertices[a], mesh.vertices[b], normals[f], 1])
        edge_faces.append([f])
    welded_of = None
    if per_face:  # one component per corner, with its welded edge's neighbours
        welded_of = np.array([e for *_, e in corner_edge], np.int64)
        edges = [[mesh.vertices[a], mesh.vertices[b], normals[f], edges[e][3] if e >= 0 else 1]
                 for a, b, f, e in corner_edge]
        edge_faces = [edge_faces[e] if e >= 0 else [f] for _, _, f, e in corner_edge]
    n = len(edges)
    dirs = np.array([e[1] - e[0] for e in edges])
    lengths = np.linalg.norm(dirs, axis=1)
    unit = dirs / np.maximum(lengths, EPS)[:, None]
    loc_y = np.abs(unit @ st.scope.rotation[:, 1])
    table = {"all": np.ones(n, bool), "vertical": loc_y > math.cos(math.radians(11.25)),
             "horizontal": loc_y < math.sin(math.radians(11.25)),
             "border": np.array([e[3] == 1 for e in edges]),
             "inside": np.array([e[3] > 1 for e in edges])}
    table["aslant"] = ~table["vertical"] & ~table["horizontal"]
    table.update(_roof_edges(mesh, normals, edges, edge_faces, unit))
    # the side an edge faces: its face normal crossed with the edge, in the scope frame
    outward = np.array([cross3(u, e[2]) for u, e in zip(unit, edges)])
    d = _direction_index(outward @ st.scope.rotation) if n else np.zeros(0, int)
    for i, name in enumerate(_DIRS):
        table[name] = d == i
    table["side"] = (d < 2) | (d >= 4)
    _add_street_selectors(table, outward, call.derivation.object_scope.rotation)
    taken = np.zeros(n, bool)
    out = []
    tags = _tag_masks(mesh, "e")
    if welded_of is not None:
        welded = tags

        def tags(query, sub):  # noqa: F811 -- a face edge is tagged as its edge is
            hit = welded(query, sub)
            return np.where(welded_of >= 0, hit[np.maximum(welded_of, 0)], False)

    def edge_normal(e):
        """The mean normal of the faces at edge ``e`` (its own face's for ``comp(fe)``)."""
        own = edges[e][2]
        if welded_of is not None or len(edge_faces[e]) < 2:
            return own
        mean = normals[edge_faces[e]].sum(axis=0)
        return mean / np.linalg.norm(mean) if np.linalg.norm(mean) > 1e-6 else own

    def edge_scope(e):
        """An edge shape's scope (``zUp``, comp's default alignment): x along the edge, z the
        mean normal of its faces, y = z × x (on a one-face edge: in the face, into it; on a
        ridge: level, so ``t(0, 2, 0)`` moves it sideways as CityEngine's modify example
        shows)."""
        a = edges[e][0]
        normal = edge_normal(e)
        up = normal if abs(unit[e] @ normal) < 0.99 else st.scope.rotation[:, 1]
        z = up - unit[e] * (up @ unit[e])
        if np.linalg.norm(z) < EPS:
            z = np.array([0.0, 1.0, 0.0])
        z = z / np.linalg.norm(z)
        return Scope.from_axes(a, unit[e], cross3(z, unit[e]), (lengths[e], 0.0, 0.0))

    def edge_state(e):  # an edge's own shape, for logical selectors that read it
        ps = st.copy()
        ps.scope, ps.geometry = edge_scope(e), Mesh()
        return ps

    for branch in call.branches:
        _warn_unmerged(call, branch, "edge")
        k = _selector_key(call, branch)
        idx = np.flatnonzero(_match(k, table, n, None, tags, edge_state) & ~taken)
        taken[idx] = True
        for j, e in enumerate(idx):
            ps = st.child(len(out))
            ps.scope = edge_scope(e)
            ps.geometry = Mesh()
            ps.context = {**st.context, "comp.index": j, "comp.total": len(idx),
                          "comp.sel": str(k), SHAPE_KIND: "edge"}
            out.append((ps, branch.ops, {"sel": str(k), "index": j, "component": int(e)}))
    return out


def _warn_unmerged(call, branch, kind: str) -> None:
    """Edge and vertex shapes are scopes without geometry here, so ``=``/``=:`` cannot merge
    them into one shape: each stays its own, with a warning (docs/cga-dialect.md).  The comp
    function (``comp(fe){ street.back = 4 | … }``, a value per component) is not warned about:
    the value reaches every selected component either way."""
    if branch.mode != ":" and isinstance(branch.ops, tuple | list):
        call.derivation.warn(f"comp: '{branch.mode}' does not merge {kind} components yet; each "
                             f"{kind} is its own shape", branch, call.env.rule)


def _roof_edges(mesh, normals, edges, edge_faces, unit) -> dict:
    """CityEngine's roof edge selectors ``eave ridge hip valley`` (used by its tutorials'
    roof rules; the current reference no longer lists them): among faces that look up (roof
    planes), a *ridge* is a horizontal edge where two of them meet convexly, a *hip* a sloping
    convex one, a *valley* a concave one, and an *eave* a horizontal edge of a single roof face
    at its lower border.  Horizontal means within 11.25° of the world's xz plane."""
    n = len(edges)
    out = {k: np.zeros(n, bool) for k in ("eave", "ridge", "hip", "valley")}
    if not n:
        return out
    roof = normals[:, 1] > 0.05
    centroid = np.array([mesh.vertices[mesh.face(f)].mean(axis=0) for f in range(mesh.n_faces)])
    level = np.abs(unit[:, 1]) < math.sin(math.radians(11.25))
    for i, fs in enumerate(edge_faces):
        up = [f for f in fs if roof[f]]
        a = edges[i][0]
        if len(up) == 2:
            f1, f2 = up
            convex = (centroid[f2] - a) @ normals[f1] < -1e-9
            if not convex:
                out["valley"][i] = True
            elif level[i]:
                out["ridge"][i] = True
            else:
                out["hip"][i] = True
        elif len(up) == 1 and level[i] and centroid[up[0]][1] > max(a[1], edges[i][1][1]) + 1e-9:
            out["eave"][i] = True
    return out


def vertex_points(mesh: Mesh, per_face: bool) -> tuple[np.ndarray, np.ndarray]:
    """``comp(v)``'s vertices (coincident ones welded, each once, in order of first use) or
    ``comp(fv)``'s (every face's corners, face by face): their positions and, for each, one
    used vertex (its index among ``Mesh.used_vertices``)."""
    if not mesh.n_faces:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    used = np.unique(mesh.corners)
    slot = np.searchsorted(used, mesh.corners)       # corner -> its used-vertex index
    if per_face:
        return mesh.vertices[mesh.corners], slot
    weld = weld_ids(mesh.vertices[used])
    _, first = np.unique(weld, return_index=True)
    first = np.sort(first)
    return mesh.vertices[used[first]], first


def _comp_vertices(call, st, per_face: bool = False):
    """``comp(v)``: one shape per vertex, coincident vertices welded (a box has 8);
    ``comp(fv)``: one per corner of every face (a box has 24)."""
    mesh = st.geometry
    pts, rep = vertex_points(mesh, per_face)
    n = len(pts)
    table = {"all": np.ones(n, bool)}
    out = []
    taken = np.zeros(n, bool)
    used_tags = _tag_masks(mesh, "v")

    def tags(query, sub):
        return used_tags(query, sub)[rep]
    for branch in call.branches:
        _warn_unmerged(call, branch, "vertex")
        k = _selector_key(call, branch)
        idx = np.flatnonzero(_match(k, table, n, None, tags) & ~taken)
        taken[idx] = True
        for j, v in enumerate(idx):
            ps = st.child(len(out))
            ps.scope = Scope(pts[v], st.scope.rotation.copy(), np.zeros(3))
            ps.geometry = Mesh()
            ps.context = {**st.context, "comp.index": j, "comp.total": len(idx),
                          "comp.sel": str(k), SHAPE_KIND: "vertex"}
            out.append((ps, branch.ops, {"sel": str(k), "index": j, "component": int(v)}))
    return out


# ---- setback ------------------------------------------------------------------------------

class _PlanarEdges:
    """The single planar face of a shape (a face with holes included: pieces sharing a
    ``holed`` id), in its own 2D frame, with edge directions classified like ``comp(e)``
    selectors (front/back/left/right/side/all) relative to the shape's scope.  Edges are the
    outline's, then each hole's (``seg_a`` → ``seg_b``, the face on their left)."""

    def __init__(self, st, opname: str, object_rot=None, mesh: Mesh | None = None):
        import shapely

        mesh = st.geometry if mesh is None else mesh  # one face of the shape (:func:`_faces_of`)
        groups = face_groups(mesh)
        if len(groups) != 1:
            raise CGARuntimeError(f"{opname} needs a single planar face (use comp(f) first)")
        poly = mesh.vertices[mesh.face(0)]
        self.normal = mesh.face_normals()[0]
        self.sc = face_scope(poly, self.normal)
        self.holes: list = []
        self.pieces = len(groups[0]) > 1
        if not self.pieces:
            self.xy = self.sc.to_local(poly)[:, :2]
            self.shape = shapely.Polygon(self.xy).buffer(0)
        else:
            # its edges' index is not always comp(e)'s: the FHNW rules' setbacks and shapeO on
            # courtyard lots change form with comp(e)'s ring order, which needs a study against
            # CityEngine first (widths from comp(fe) are matched by position: from_face_edges)
            outlines = rings(plane_polygon(mesh, groups[0], self.sc.origin, self.sc.rotation))
            if len(outlines) != 1:
                raise CGARuntimeError(f"{opname} needs a single planar face (use comp(f) first)")
            self.xy, self.holes = outlines[0]
            self.shape = shapely.Polygon(self.xy, self.holes)
        ring_list = [self.xy, *self.holes]
        self.seg_a = np.concatenate(ring_list)
        self.seg_b = np.concatenate([np.roll(r, -1, axis=0) for r in ring_list])
        first = np.cumsum([0] + [len(r) for r in ring_list])
        idx = [np.arange(a, b) for a, b in zip(first[:-1], first[1:])]
        self.prev = np.concatenate([np.roll(i, 1) for i in idx])   # the edge before, same ring
        self.next = np.concatenate([np.roll(i, -1) for i in idx])
        k = self.k = len(self.seg_a)
        e = self.seg_b - self.seg_a
        outward3 = cross3(np.column_stack([e, np.zeros(k)]) @ self.sc.rotation.T, self.normal)
        d_idx = _direction_index(outward3 @ st.scope.rotation)
        t = {name: d_idx == i for i, name in enumerate(_DIRS)}
        t["side"] = (d_idx < 2) | (d_idx >= 4)
        t["all"] = np.ones(k, bool)
        _add_street_selectors(t, outward3, object_rot)
        self.table = t
        self.mesh = mesh
        self.tags = _tag_masks(mesh, "p") if not self.pieces else self._piece_tags
        self._edges_on: list | None = None

    def edges_on_segments(self) -> list[list[int]]:
        """For each outline or hole segment of a face stored as pieces, the ``TagIndex`` edges
        (welded, seams left out) lying on it."""
        if self._edges_on is None:
            ix = TagIndex(self.mesh)
            nxt = self.mesh.next_corners()
            a, d = self.seg_a, self.seg_b - self.seg_a
            dd = np.maximum((d * d).sum(axis=1), EPS)
            out: list[list[int]] = [[] for _ in range(self.k)]
            for e, cs in enumerate(ix.edge_corners):
                c = cs[0]
                ends = self.sc.to_local(self.mesh.vertices[self.mesh.corners[[c, nxt[c]]]])[:, :2]
                for i in range(self.k):
                    t = ((ends - a[i]) @ d[i]) / dd[i]
                    if np.all(np.abs(a[i] + t[:, None] * d[i] - ends) <= 1e-6) \
                            and t.min() >= -1e-9 and t.max() <= 1 + 1e-9:
                        out[i].append(e)
                        break
            self._edges_on = [out, ix]
        return self._edges_on

    def _piece_tags(self, query, sub):
        """``isTagged`` on a face stored as pieces: a segment matches when an edge on it does
        (its own tags, or a face's next to it)."""
        on, ix = self.edges_on_segments()
        hit = ix.edges(query, sub)
        return np.array([any(hit[e] for e in es) for es in on], bool)

    def from_face_edges(self, values: np.ndarray) -> np.ndarray:
        """Per-edge values given in ``comp(fe)`` order (``setback(comp(fe){…})``) in this
        face's segment order: the same for one face; for pieces, each segment takes the value of
        the piece edge on it."""
        if not self.pieces or not isinstance(values, np.ndarray) or len(values) != self.k:
            return values
        on, ix = self.edges_on_segments()
        fe = edge_corners(self.mesh, weld_ids(self.mesh.vertices)).tolist()
        at = {int(ix.edge_of[c]): k for k, c in enumerate(fe)}
        return np.array([values[at[es[0]]] if es and es[0] in at else values[i]
                         for i, es in enumerate(on)], float)

    def setback_tags(self, face: Mesh, mesh: Mesh, selected, remainder: bool) -> Mesh:
        """Setback auto-tags on the edges of ``mesh``, a piece of the single face ``face``
        (reference, setback "Component tags"): on an original edge, ``setback.front`` if that
        edge was selected, else ``setback.side`` (``setback.remainder`` on every original edge
        of the remainder); elsewhere ``setback.back`` for the new setback edges, which run along
        a selected edge and take its tags, and ``setback.side`` for the ends of a band that
        stops at a corner.  Edges between two pieces of the same
        shape (a holed piece stored as pieces) get none."""
        a, b = self.seg_a, self.seg_b
        d = b - a
        dd = np.maximum((d * d).sum(axis=1), EPS)
        unit = d / np.sqrt(dd)[:, None]
        own = None  # each segment's own edge tags, which its setback line copies
        if face.corner_column(EDGE_TAGS) is not None:
            tags = corner_tags(face, EDGE_TAGS)
            if not self.pieces:
                own = [tags[int(face.starts[0]) + i] for i in range(self.k)]
            else:  # the tags of the piece edge lying on the segment
                on, ix = self.edges_on_segments()
                own = [tags[ix.edge_corners[es[0]][0]] if es else () for es in on]
        local = self.sc.to_local(mesh.vertices[mesh.corners])[:, :2]
        nxt = mesh.next_corners()
        ends = [tuple(np.round(np.concatenate([local[c], local[nxt[c]]]), 7)) for c in range(len(local))]
        twins = {(e[2], e[3], e[0], e[1]) for e in ends}
        parts, copied = [], []
        for c, (q, r) in enumerate(zip(local, local[nxt])):
            tq = ((q - a) * d).sum(axis=1) / dd
            tr = ((r - a) * d).sum(axis=1) / dd
            on = (np.abs(a + tq[:, None] * d - q).max(axis=1) <= 1e-6) & \
                (np.abs(a + tr[:, None] * d - r).max(axis=1) <= 1e-6) & \
                (np.minimum(tq, tr) >= -1e-9) & (np.maximum(tq, tr) <= 1 + 1e-9)
            k = np.flatnonzero(on)
            extra = ()
            if len(k):
                part = "remainder" if remainder else "front" if selected[k[0]] else "side"
            elif ends[c] in twins:
                part = ""
            else:
                e = (r - q) / max(np.linalg.norm(r - q), EPS)
                along = np.flatnonzero(selected & (np.abs(unit @ e) > 1 - 1e-6))
                # a new edge along a selected one is its setback line; across, a band's end
                part = "back" if len(along) else "side"
                if own is not None and len(along):  # the nearest selected edge it runs along
                    w = q - a[along]
                    dist = np.abs(unit[along, 0] * w[:, 1] - unit[along, 1] * w[:, 0])
                    extra = own[int(along[np.argmin(dist)])]
            parts.append(part)
            copied.append(extra)
        return edges_with(auto_tag_edges(mesh, "setback", parts), copied)

    def band(self, edges, width, others=None):
        """Strip inside the face along the given edges, ``width`` wide (a number, or an array
        with one width per edge): the area between each edge and its offset line, as a
        setback with the other edges held still would sweep it.  At a convex corner the strip
        runs on to the neighbouring edge, on that edge's inner side only (the face's outline
        clips it there); at a reflex corner it stops at the corner, unless the neighbour is set
        back too (``others``: every edge the operation sets back, default ``edges``), when the
        two offset lines meet in a mitre.  Strips never run past a corner into other parts of
        the face (a courtyard's far side, the other wing of a U)."""
        import shapely

        widths = np.broadcast_to(np.asarray(width, float), (self.k,))
        chosen = np.zeros(self.k, bool)
        chosen[np.asarray(list(edges), int)] = True
        chosen &= widths > 0
        moving = chosen if others is None else (np.asarray(others, bool) & (widths > 0)) | chosen
        d = self.seg_b - self.seg_a
        length = np.maximum(np.linalg.norm(d, axis=1), EPS)
        t = d / length[:, None]
        inward = np.column_stack([-t[:, 1], t[:, 0]])
        big = 4.0 * (float(np.ptp(self.seg_a, axis=0).max()) + float(widths.max(initial=0.0))) + 1

        def inner_side(j):  # the half-plane left of edge j: the face's side of it
            a = self.seg_a[j]
            return shapely.Polygon([a - t[j] * big, a + t[j] * big,
                                    a + t[j] * big + inward[j] * big, a - t[j] * big + inward[j] * big])

        parts = []
        for i in np.flatnonzero(chosen):
            a, b, w = self.seg_a[i], self.seg_b[i], widths[i]
            off = inward[i] * w
            parts.append(shapely.Polygon([a, b, b + off, a + off]))
            for j, end, sign in ((self.prev[i], a, -1.0), (self.next[i], b, 1.0)):
                e1, e2 = (t[j], t[i]) if sign < 0 else (t[i], t[j])
                convex = e1[0] * e2[1] - e1[1] * e2[0] > EPS
                if convex and not moving[j]:  # on to the neighbour, on its inner side
                    ext = t[i] * sign * (length[j] + w)
                    piece = shapely.Polygon([end, end + ext, end + ext + off, end + off])
                    parts.append(piece.intersection(inner_side(j)))
            j = self.next[i]  # a reflex corner between two edges set back: the mitre
            if moving[j] and t[i][0] * t[j][1] - t[i][1] * t[j][0] < -EPS:
                p1, p2 = b + inward[i] * w, b + inward[j] * widths[j]
                den = t[i][0] * t[j][1] - t[i][1] * t[j][0]
                q = p2 - p1
                m = p1 + t[i] * ((q[0] * t[j][1] - q[1] * t[j][0]) / den)
                parts.append(shapely.Polygon([b, p1, m, p2]).buffer(0))
        parts = [p for p in parts if p.is_valid and p.area > 0]
        return shapely.union_all(parts) if parts else shapely.Polygon()

    def polygons(self, geom) -> list[list[np.ndarray]]:
        """The polygons of a piece (shapely geometry in this face's frame), each as its simple
        faces in world coordinates (a polygon with holes is several); slivers are left out."""
        out = []
        for g in getattr(geom, "geoms", [geom]):
            if g.geom_type != "Polygon" or g.area <= EPS:
                continue
            faces = []
            for ring in simple_pieces(g):
                x, y = ring[:, 0], ring[:, 1]
                if abs(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) <= 1e-9:
                    continue  # a sliver the cut left along a straight edge
                faces.append(self.sc.to_world(np.column_stack([ring, np.zeros(len(ring))])))
            if faces:
                out.append(faces)
        return out

    def piece_mesh(self, faces: list[np.ndarray], selected=None, remainder=False) -> Mesh:
        """A piece of this face as a mesh: the face's data, the tags of the edges it keeps and,
        with ``selected`` (the original edges the bands run along), the setback family's
        auto-tags (those of a remainder when ``remainder``)."""
        mesh = Mesh.from_polygons(faces).inherit(self.mesh, [0] * len(faces), drop=OFFSET_COLUMNS)
        if selected is not None:
            mesh = self.setback_tags(self.mesh, mesh, selected, remainder)
        return mesh

    def shapes(self, st, pieces, selected=None, remainder=None) -> list:
        """``[(branch, shapely geometry)]`` → successor states, one per branch (all its
        polygons in one shape): :func:`_successors` of this face alone."""
        return _successors(st, [(self, pieces, selected, remainder)], by_polygon=False)


def _faces_of(st, opname: str, object_rot) -> list[_PlanarEdges]:
    """Every face of the shape (a face with holes being one), for the setback family, which
    works on each face of a shape with several (reference: the operator "also applies to shapes
    with more than one face"; distance arrays are "in face-edge order")."""
    groups = face_groups(st.geometry)
    if len(groups) <= 1:
        return [_PlanarEdges(st, opname, object_rot)]
    return [_PlanarEdges(st, opname, object_rot, st.geometry.subset(g)) for g in groups]


def _successors(st, per_face, by_polygon: bool = True) -> list:
    """Successor states of a setback-family operation from ``per_face``: for each face
    ``(edges, [(branch, shapely piece)], selected edges or None, remainder branch or None)``.

    Branches come in the order the faces list them.  With ``by_polygon``, as the reference's
    operators say, a ``:`` branch makes one shape of each polygon ("each polygon is put into a
    new shape") and a ``=`` branch one shape of all its polygons over every face ("combined into
    one new shape"); otherwise one shape per branch and face.  Each piece keeps the shape's
    scope orientation, fitted to it (as split pieces do): Esri's International City splits
    setback pieces along z and reads their ``scope.sz``, on lots whose scope has y up."""
    groups: dict[int, tuple] = {}  # id(branch) -> (branch, the meshes of each of its shapes)
    for pe, pieces, selected, remainder in per_face:
        for branch, geom in pieces:
            meshes = [pe.piece_mesh(faces, selected, branch is remainder)
                      for faces in pe.polygons(geom)]
            if not meshes:
                continue
            shapes = groups.setdefault(id(branch), (branch, []))[1]
            if not by_polygon:
                shapes.append(meshes)
            elif getattr(branch, "mode", ":") == ":":
                shapes.extend([m] for m in meshes)
            elif shapes:  # "=": one shape over every face
                shapes[0].extend(meshes)
            else:
                shapes.append(meshes)
    result = []
    for branch, parts in groups.values():
        for meshes in parts:
            ps = st.child(len(result))
            ps.geometry = Mesh.merge(meshes) if len(meshes) > 1 else meshes[0]
            ps.fit_scope()
            result.append((ps, branch.ops, {"index": len(result)}))
    return result


@operation("setback", 1, 1, body=True)
def op_setback(call):
    """``setback(d){ selector : A | remainder : B }`` on a planar shape.

    Edges are selected like ``comp(e)`` (front/back/left/right/side/all/index); the band of width
    ``d`` along the selected edges becomes one shape per branch, the rest is ``remainder``.
    ``d`` may be an array with one width per edge (``setback(comp(fe){ front : 4 | all : 1 })``).
    """
    st = call.state
    faces = _faces_of(st, "setback", call.derivation.object_scope.rotation)
    widths = _face_edge_widths(_edge_widths(call), faces)
    return _successors(st, [(pe, *_setback_pieces(call, pe, w)) for pe, w in zip(faces, widths)])


def _setback_pieces(call, pe, widths) -> tuple:
    """``[(branch, shapely geometry)]`` of a setback with ``widths`` (a number or one per
    edge): each branch takes the band along its still untaken edges, ``remainder`` the rest;
    then the selected edges and the remainder branch."""
    remaining, out, remainder_branch = pe.shape, [], None
    taken = np.zeros(pe.k, bool)
    chosen = []
    for branch in call.branches:
        key = _selector_key(call, branch)
        if key == "remainder":
            remainder_branch = branch
            continue
        idx = np.flatnonzero(_match(key, pe.table, pe.k, None, pe.tags) & ~taken)
        taken[idx] = True
        chosen.append((branch, idx))
    for branch, idx in chosen:  # corners see every edge set back, whichever branch has it
        band = pe.band(idx, widths, taken)
        piece = remaining.intersection(band)
        remaining = remaining.difference(band)
        if piece.area > EPS:
            out.append((branch, piece))
    if remainder_branch is not None and remaining.area > EPS:
        out.append((remainder_branch, remaining))
    return out, taken, remainder_branch


@operation("setbackPerEdge", 1, 2, body=True)
def op_setback_per_edge(call):
    """Registered so the checks know it takes a body; the parser rewrites every use with a body
    to ``setback(comp(fe){ all : d }){ … }`` (:meth:`facadeforge.grammar.parser` ``body_op``),
    so this never runs on parsed rules."""
    raise CGARuntimeError("setbackPerEdge(d){ … } is rewritten to setback(comp(fe){ all : d })"
                          " when the rules are parsed")


@operation("setbackToArea", 1, 4, body=True)
def op_setback_to_area(call):
    """``setbackToArea(area[, minDistances[, maxDistances]][, uvSet]){…}``: a setback whose
    distances are chosen so that the remainder has ``area`` — one distance for every selected
    edge, or ``minDistances`` raised by a common offset and capped at ``maxDistances`` (found
    by bisection; the remainder's area falls as the offset grows).  An unreachable area gives
    the closest setback (none, or the largest)."""
    st = call.state
    pe = _PlanarEdges(st, "setbackToArea", call.derivation.object_scope.rotation)
    target = call.num(0)

    def per_edge(k: int, default: float) -> np.ndarray:
        """Argument ``k`` (minDistances, maxDistances): one number for every edge, or one
        per edge."""
        if len(call.args) <= k:
            return np.full(pe.k, default)
        a = call.args[k]
        if not isinstance(a, np.ndarray):
            return np.full(pe.k, call.num(k))
        a = np.asarray(a, float).reshape(-1)
        if a.size != pe.k:
            raise CGARuntimeError(f"setbackToArea: a distance array has {a.size} values; give "
                                  f"one per edge ({pe.k})")
        return pe.from_face_edges(a)

    lo, hi = per_edge(1, 0.0), per_edge(2, np.inf)
    selected = np.zeros(pe.k, bool)
    for branch in call.branches:
        key = _selector_key(call, branch)
        if key != "remainder":
            selected |= _match(key, pe.table, pe.k, None, pe.tags)
    edges = np.flatnonzero(selected)

    def widths(offset: float) -> np.ndarray:
        return np.minimum(lo + offset, hi)

    def remainder(offset: float) -> float:
        return pe.shape.difference(pe.band(edges, widths(offset))).area

    span = float(np.ptp(pe.xy, axis=0).max()) if len(pe.xy) else 0.0
    a, b = 0.0, span
    if remainder(a) <= target:
        b = a
    elif remainder(b) >= target:
        a = b
    for _ in range(50):                     # bounded: 50 halvings reach float precision
        if b - a <= 1e-6 * max(span, 1.0):
            break
        mid = (a + b) / 2
        a, b = (mid, b) if remainder(mid) > target else (a, mid)
    return _successors(st, [(pe, *_setback_pieces(call, pe, widths((a + b) / 2)))])


def _edge_widths(call):
    """The width argument of a per-edge operation: one number, or an array of numbers in
    face-edge order (``comp(fe)``)."""
    arg = call.args[0] if call.args else None
    if isinstance(arg, np.ndarray):
        if arg.dtype.kind not in "fi":
            raise CGARuntimeError(f"{call.name}: the width array holds non-numbers; give one "
                                  "number per face edge, e.g. comp(fe){ front : 4 | all : 1 }")
        return arg.astype(float).reshape(-1)
    return call.num(0)


def _face_edge_widths(widths, faces: list[_PlanarEdges]) -> list:
    """Per face, its edges' widths from ``widths``: one number for all, or an array in
    face-edge order, the first face's edges first.  As the reference says, "if the array does
    not contain enough elements no setback is performed on the respective missing face edges",
    and elements past the last face edge are ignored."""
    if not isinstance(widths, np.ndarray):
        return [widths] * len(faces)
    out, at = [], 0
    for pe in faces:
        mine = np.zeros(pe.k)
        got = widths[at:at + pe.k]
        mine[:len(got)] = got
        out.append(pe.from_face_edges(mine))
        at += pe.k
    return out


def _letter_pieces(call, pe: _PlanarEdges, sides: tuple[str, ...]) -> tuple:
    """``(pieces, selected edges, remainder branch)`` of ``shapeL/U/O`` on one face."""
    import shapely

    shape = shapely.Polygon()
    widths = np.zeros(pe.k)
    for k, side in enumerate(sides):
        widths[pe.table[side] & (widths == 0)] = max(call.num(k), 0.0)
    for k, side in enumerate(sides):
        if call.num(k) > 0:
            shape = shape.union(pe.band(np.flatnonzero(pe.table[side]), widths, widths > 0))
    shape = pe.shape.intersection(shape)
    remainder = pe.shape.difference(shape)
    selected = np.zeros(pe.k, bool)
    for k, side in enumerate(sides):
        if call.num(k) > 0:
            selected |= pe.table[side]
    out, rest = [], None
    for branch in call.branches:
        key = _selector_key(call, branch)
        geom = shape if key == "shape" else remainder if key == "remainder" else None
        if geom is None:
            raise CGARuntimeError(f"{call.name} selectors are shape and remainder, not '{key}'")
        rest = branch if key == "remainder" else rest
        if geom.area > EPS:
            out.append((branch, geom))
    return out, selected, rest


def _shape_letter(sides: tuple[str, ...]):
    def op(call):
        """``shapeL/U/O(widths…){ shape : A | remainder : B }``: bands along the named sides of
        each face."""
        st = call.state
        faces = _faces_of(st, call.name, call.derivation.object_scope.rotation)
        return _successors(st, [(pe, *_letter_pieces(call, pe, sides)) for pe in faces])
    return op


for _name, _sides in (("shapeL", ("front", "left")), ("shapeU", ("front", "right", "left")),
                      ("shapeO", ("front", "right", "back", "left"))):
    operation(_name, len(_sides), body=True)(_shape_letter(_sides))


__all__ = ["classify_faces", "face_scope", "resolve_split", "to_float"]
