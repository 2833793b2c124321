"""``ShapeGrammar.Tools``: the shape-grammar words of CityFit's GML (Hohmann et al. 2009, Fig. 13).

A *scope* value on the operand stack is a node of the derivation tree (a
:class:`~facadeforge.model.shape.Shape` with an oriented box) and, optionally, a convex
polyhedron inside that box.  Splitting pushes the sub-scopes back on the stack, the *first part
on top*, so that the words after a split consume the parts in the order of its size array
(``[0.1 -1 0.1] /X split E D E``: the first ``E`` takes the part at x = 0).  Terminal words
consume a scope and make the leaf geometry.  Coordinates are the model's: metres, y up.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.mesh import Mesh
from ..model.labels import label_for_name
from ..model.model import MAX_COORDINATE, Material, Part
from ..model.scope import Scope
from ..model.shape import Shape
from .interpreter import Interpreter, Name, Point, control_repeat, is_number, type_name
from .polyhedra import Plane, Polyhedron

_AXES = {"X": 0, "Y": 1, "Z": 2, "x": 0, "y": 1, "z": 2}


class GScope:
    """A scope on the GML stack: its shape-tree node and its convex polyhedron (``None`` for
    the whole box)."""

    gml_type = "scope"
    __slots__ = ("shape", "poly")

    def __init__(self, shape: Shape, poly: Polyhedron | None = None):
        self.shape, self.poly = shape, poly

    @property
    def empty(self) -> bool:
        if self.poly is not None:
            return self.poly.empty
        return int(np.count_nonzero(self.shape.scope.size > 0)) < 2

    def polyhedron(self) -> Polyhedron:
        sc = self.shape.scope
        if self.poly is not None:
            return self.poly
        return Polyhedron.frame_box(sc.origin, sc.rotation, sc.size)

    def __repr__(self) -> str:
        return f"<scope {self.shape.symbol or '?'} {self.shape.scope.size.round(3).tolist()}>"


class Grammar:
    """What the words build: root shapes, leaf parts, warnings."""

    def __init__(self, it: Interpreter):
        self.it = it
        self.roots: list[Shape] = []
        self.parts: list[Part] = []
        self.warnings: list[str] = []
        self.shapes = 0
        self.finished = False

    def count(self, n: int) -> None:
        self.shapes += n
        if self.shapes > self.it.limits.max_shapes:
            raise self.it.limit("max_shapes", "the grammar made too many shapes")

    def root(self, scope: Scope, symbol: str = "", poly: Polyhedron | None = None) -> GScope:
        self.count(1)
        self.it.count_cells(1)
        shape = Shape(symbol, scope, operator="scope")
        self.roots.append(shape)
        return GScope(shape, poly)


def grammar_of(it: Interpreter) -> Grammar:
    g = getattr(it, "grammar", None)
    if g is None:
        g = it.grammar = Grammar(it)
    return g


def on_call(it: Interpreter, name: str) -> None:
    """Name the scope a rule is about to work on: the topmost scope among the top operands
    (rules take their numbers above the scope, as ``0.15 3 Ledge``) gets the rule's name if it
    has none yet — as CGA names a shape by the rule that derives it."""
    st = it.stack
    for k in range(len(st) - 1, max(len(st) - 9, -1), -1):
        v = st[k]
        if isinstance(v, GScope):
            if not v.shape.symbol:
                v.shape.symbol = name
            return


# ------------------------------------------------------------------------------ helpers


def check_extent(it: Interpreter, scope: Scope) -> None:
    """A scope must stay finite and within ±MAX_COORDINATE metres of the origin."""
    reach = np.abs(scope.origin) + scope.size
    if not (np.isfinite(reach).all() and reach.max() <= MAX_COORDINATE):
        raise it.error(f"the scope would reach beyond ±{MAX_COORDINATE:.0e} m (an absurd move "
                       "or scale?)", "range")


def check_points(it: Interpreter, *points) -> None:
    for p in points:
        if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in p):
            raise it.error(f"point {p!r} is not finite or beyond ±{MAX_COORDINATE:.0e} m",
                           "range")


def pop_scope(it: Interpreter) -> GScope:
    return it.pop_type(lambda v: isinstance(v, GScope), "a scope (made by 'scope' or a split)")


def pop_axis(it: Interpreter) -> int:
    n = it.pop_name()
    if str(n) not in _AXES:
        raise it.error(f"the direction is /X, /Y or /Z, not /{n}", "grammar")
    return _AXES[str(n)]


def _finite(it: Interpreter, values, what: str) -> list[float]:
    out = []
    for v in values:
        if not is_number(v):
            raise it.error(f"{what} must be numbers, got {type_name(v)}", "type")
        if not math.isfinite(v):
            raise it.error(f"{what} must be finite, got {v}", "range")
        out.append(float(v))
    return out


def _lengths(extent: float, sizes: list[float]) -> list[float]:
    """Absolute (> 0) sizes as given, relative (< 0) ones share what is left in proportion;
    parts beyond the scope's end are cut (to length 0)."""
    absolute = sum(s for s in sizes if s > 0)
    weights = sum(-s for s in sizes if s < 0)
    rest = max(extent - absolute, 0.0)
    raw = [s if s > 0 else (rest * -s / weights if s < 0 else 0.0) for s in sizes]
    out, pos = [], 0.0
    for r in raw:
        length = max(min(r, extent - pos), 0.0)
        out.append(length)
        pos += length
    return out


def _child(parent: GScope, axis: int, start: float, length: float, operator: str,
           params: dict) -> GScope:
    ps = parent.shape.scope
    a = ps.rotation[:, axis]
    size = ps.size.copy()
    size[axis] = length
    scope = Scope.trusted(ps.origin + a * start, ps.rotation, size, ps.unit)
    shape = Shape("", scope, label=parent.shape.label, material=parent.shape.material,
                  operator=operator, params=params, rule=parent.shape.symbol)
    parent.shape.add(shape)
    if length <= 0 < ps.size[axis]:
        shape.tags["empty"] = True  # cut off by the parts before it
    poly = None
    if parent.poly is not None:
        o = float(a @ ps.origin)
        poly = parent.poly.clip(Plane(-a, -(o + start))).clip(Plane(a, o + start + length))
    return GScope(shape, poly)


def split_scope(it: Interpreter, g: GScope, axis: int, lengths: list[float], operator: str,
                params: dict | None = None) -> list[GScope]:
    grammar_of(it).count(len(lengths))
    it.count_cells(len(lengths))
    if not all(math.isfinite(v) for v in lengths):
        raise it.error("the sizes overflow (absurdly large numbers?)", "range")
    parts, pos = [], 0.0
    for i, length in enumerate(lengths):
        p = {"axis": "xyz"[axis], "index": i}
        if params:
            p.update(params)
        parts.append(_child(g, axis, pos, length, operator, p))
        pos += length
    return parts


def push_first_on_top(it: Interpreter, parts: list) -> None:
    if len(it.stack) + len(parts) > it.limits.max_stack:
        raise it.limit("max_stack", "the operand stack grew too deep")
    it.stack.extend(reversed(parts))


# ------------------------------------------------------------------------------ words

WORDS: dict = {}


def word(*names: str):
    def deco(fn):
        for n in names:
            WORDS[n] = fn
        return fn

    return deco


@word("ShapeGrammar.Tools.init")
def w_init(it: Interpreter) -> None:
    """Start a grammar (the words are always available; this is where programs begin)."""
    grammar_of(it)


@word("scope")
def w_scope(it: Interpreter) -> None:
    """``scope → s``: a new scope, the unit box at the origin."""
    it.push(grammar_of(it).root(Scope(np.zeros(3), np.eye(3), np.ones(3))))


def _modified(it: Interpreter, g: GScope, operator: str, params: dict) -> GScope:
    """Transform in place while the scope has not been split; else a child takes the change."""
    if not g.shape.children:
        return g
    grammar_of(it).count(1)
    sc = g.shape.scope.copy()
    shape = Shape("", sc, label=g.shape.label, material=g.shape.material, operator=operator,
                  params=params, rule=g.shape.symbol)
    g.shape.add(shape)
    return GScope(shape, g.poly)


@word("move")
def w_move(it: Interpreter) -> None:
    """``s (dx,dy,dz) move → s``: translate along the scope's own axes."""
    d = np.array(it.pop_point())
    check_points(it, d)
    g = _modified(it, pop_scope(it), "move", {"by": [float(v) for v in d]})
    sc = g.shape.scope
    shift = sc.rotation @ d
    check_extent(it, Scope.trusted(sc.origin + shift, sc.rotation, sc.size))
    sc.origin = sc.origin + shift
    if g.poly is not None:
        g.poly = g.poly.transformed(np.eye(3), shift)
    it.push(g)


@word("scale")
def w_scale(it: Interpreter) -> None:
    """``s (fx,fy,fz) scale → s``: multiply the size (and the polyhedron) about the origin."""
    f = np.array(it.pop_point())
    if not np.isfinite(f).all() or (f < 0).any():
        raise it.error(f"scale factors must be finite and ≥ 0, got {Point(f)!r}", "range")
    g = pop_scope(it)
    if g.poly is not None and (f <= 0).any():
        raise it.error("a polyhedral scope scales by factors > 0 only", "range")
    g = _modified(it, g, "scale", {"by": [float(v) for v in f]})
    sc = g.shape.scope
    check_extent(it, Scope.trusted(sc.origin, sc.rotation, sc.size * f))
    sc.size = sc.size * f
    if g.poly is not None:
        r = sc.rotation
        m = r @ np.diag(f) @ r.T
        g.poly = g.poly.transformed(m, sc.origin - m @ sc.origin)
    it.push(g)


@word("extrude")
def w_extrude(it: Interpreter) -> None:
    """``s d extrude → s``: set the scope's depth (z size) to d ≥ 0 — a facade rectangle
    becomes a box standing d in front of it (as CGA's ``extrude``)."""
    d = it.pop_num()
    if not (math.isfinite(d) and d >= 0):
        raise it.error(f"the depth must be a finite number ≥ 0, got {d}", "range")
    g = pop_scope(it)
    if g.poly is not None:
        raise it.error("a polyhedral scope cannot be extruded", "grammar")
    g = _modified(it, g, "extrude", {"depth": float(d)})
    sc = g.shape.scope
    size = sc.size.copy()
    size[2] = d
    check_extent(it, Scope.trusted(sc.origin, sc.rotation, size))
    sc.size = size
    it.push(g)


@word("split")
def w_split(it: Interpreter) -> None:
    """``s [sizes] /X split → s1 … sn`` (s1 on top): absolute (> 0) and relative (< 0) sizes."""
    axis = pop_axis(it)
    sizes = _finite(it, it.pop_array(), "split sizes")
    g = pop_scope(it)
    lengths = _lengths(float(g.shape.scope.size[axis]), sizes)
    push_first_on_top(it, split_scope(it, g, axis, lengths, "split"))


@word("split-r")
def w_split_r(it: Interpreter) -> None:
    """``s [sizes] /X split-r → s1 … sn``: the sizes rescaled to fill the scope exactly (the
    magnitudes are proportions)."""
    axis = pop_axis(it)
    sizes = [abs(v) for v in _finite(it, it.pop_array(), "split-r sizes")]
    g = pop_scope(it)
    extent, total = float(g.shape.scope.size[axis]), sum(sizes)
    lengths = [extent * (s / total) if total > 0 else 0.0 for s in sizes]
    push_first_on_top(it, split_scope(it, g, axis, lengths, "split"))


@word("repeat")
def w_repeat(it: Interpreter) -> None:
    """Two words in one.  ``n { … } repeat``: the loop.  ``s k /X repeat → s1 … sk k``: k equal
    parts (s1 on top) and their count, ready for ``{ … } repeat``."""
    if it.stack and not isinstance(it.stack[-1], Name):
        control_repeat(it)
        return
    axis = pop_axis(it)
    k = it.pop_int()
    if k < 0:
        raise it.error(f"repeats into k ≥ 0 parts, got {k}", "range")
    if k > it.limits.max_stack:
        raise it.limit("max_stack", f"a repeat into {k:,} parts does not fit on the stack")
    g = pop_scope(it)
    extent = float(g.shape.scope.size[axis])
    push_first_on_top(it, split_scope(it, g, axis, [extent / k] * k if k else [], "repeat"))
    it.push(k)


@word("subdivide")
def w_subdivide(it: Interpreter) -> None:
    """``s smin /X subdivide → s1 … sn n``: as many equal parts as fit with each ≥ smin.
    ``s [w1 … wk] /X subdivide → s1 … sk k``: parts in proportion to the weights (``1r 2r 2r 1r``
    is ``[1 2 2 1]``; signs are ignored)."""
    axis = pop_axis(it)
    spec = it.pop()
    g = pop_scope(it)
    extent = float(g.shape.scope.size[axis])
    if type(spec) is list:
        w = [abs(v) for v in _finite(it, spec, "subdivide weights")]
        total = sum(w)
        lengths = [extent * (v / total) if total > 0 else 0.0 for v in w]
    elif is_number(spec):
        if not spec > 0 or not math.isfinite(spec):
            raise it.error(f"s_min must be a finite number > 0, got {spec}", "range")
        n = int(extent // spec) if extent > 0 else 0
        if n > it.limits.max_stack:
            raise it.limit("max_stack", f"a subdivision into {n:,} parts does not fit on the stack")
        lengths = [extent / n] * n if n else []
    else:
        raise it.error(f"expects s_min (a number) or an array of weights, got {type_name(spec)}",
                       "type")
    push_first_on_top(it, split_scope(it, g, axis, lengths, "subdivide"))
    it.push(len(lengths))


def box_mesh(scope: Scope) -> Mesh:
    """The scope's box (6 quads, outward), or its rectangle when one side is 0."""
    s = scope.size
    zero = [i for i in range(3) if s[i] <= 0]
    if not zero:
        return Polyhedron.frame_box(scope.origin, scope.rotation, s).to_mesh()
    if len(zero) > 1:
        return Mesh()
    k = zero[0]
    i, j = (k + 1) % 3, (k + 2) % 3
    r, o = scope.rotation, scope.origin
    ring = [o, o + r[:, i] * s[i], o + r[:, i] * s[i] + r[:, j] * s[j], o + r[:, j] * s[j]]
    return Mesh(np.array(ring), [[0, 1, 2, 3]])


def _label_of(shape: Shape) -> str:
    if shape.label:
        return shape.label
    guess = label_for_name(shape.symbol) if shape.symbol else None
    return guess.value if guess is not None else ""


@word("terminal-box")
def w_terminal_box(it: Interpreter) -> None:
    """``s terminal-box →``: the scope becomes a leaf with its box (or polyhedron) as geometry."""
    g = pop_scope(it)
    gram = grammar_of(it)
    if g.shape.tags.get("empty"):
        return
    mesh = g.poly.to_mesh() if g.poly is not None else box_mesh(g.shape.scope)
    if not mesh.n_faces:
        g.shape.tags["empty"] = True
        return
    it.count_cells(mesh.n_faces)
    label = _label_of(g.shape)
    if not g.shape.symbol:  # a part no rule was named for: call it after its label
        g.shape.symbol = label.capitalize() if label else "Terminal"
    g.shape.geometry = mesh
    g.shape.tags["terminal"] = "box"
    gram.parts.append(Part(mesh, label, g.shape.material, g.shape.symbol, g.shape.id))


@word("terminal-void")
def w_terminal_void(it: Interpreter) -> None:
    """``s terminal-void →``: the scope becomes an empty leaf (a hole)."""
    g = pop_scope(it)
    g.shape.tags["terminal"] = "void"


@word("label")
def w_label(it: Interpreter) -> None:
    """``s /window label → s``: semantic label (canonical when the name is a known one)."""
    n = str(it.pop_name())
    g = pop_scope(it)
    guess = label_for_name(n)
    label = guess.value if guess is not None else n
    for node in g.shape.walk():
        node.label = label
    it.push(g)


@word("color")
def w_color(it: Interpreter) -> None:
    """``s (r,g,b) color → s``: colour in 0–1."""
    c = it.pop_point()
    if not all(math.isfinite(v) for v in c):
        raise it.error("colour components must be finite", "range")
    g = pop_scope(it)
    rgb = tuple(min(max(float(v), 0.0), 1.0) for v in c)
    g.shape.material = Material(name=f"gml-{'-'.join(f'{v:.3f}' for v in rgb)}", color=rgb)
    it.push(g)


@word("scope-size")
def w_scope_size(it: Interpreter) -> None:
    """``s scope-size → s (sx,sy,sz)``."""
    g = pop_scope(it)
    it.push(g)
    it.push(Point(g.shape.scope.size))


@word("finish")
def w_finish(it: Interpreter) -> None:
    """End of the grammar: scopes still on the stack are reported as not derived."""
    gram = grammar_of(it)
    gram.finished = True
    left = sum(isinstance(v, GScope) for v in it.stack)
    if left:
        gram.warnings.append(f"finish: {left} scope(s) left on the stack were not derived")


# -- convex polyhedra


@word("cp-plane")
def w_cp_plane(it: Interpreter) -> None:
    """``p1 p2 p3 cp-plane → e``: the directed plane through three points (16.16 fixed point);
    its interior is where ``(p2-p1) × (p3-p1)`` points away from."""
    p3, p2, p1 = it.pop_point(), it.pop_point(), it.pop_point()
    check_points(it, p1, p2, p3)
    plane = Plane.from_points(p1, p2, p3)
    if plane is None:
        raise it.error("the three points are collinear (no plane)", "range")
    it.count_cells(1)
    it.push(plane)


def _pop_plane(it: Interpreter) -> Plane:
    return it.pop_type(lambda v: isinstance(v, Plane), "a plane (cp-plane)")


@word("cp-shell")
def w_cp_shell(it: Interpreter) -> None:
    """``[ e1 … en ] cp-shell → s``: the convex polyhedron inside all planes."""
    planes = it.pop_array()
    for p in planes:
        if not isinstance(p, Plane):
            raise it.error(f"expects an array of planes, found {type_name(p)}", "type")
    if len(planes) > it.limits.max_planes:
        raise it.limit("max_planes", f"a shell of {len(planes)} planes is too large")
    try:
        poly = Polyhedron.shell(planes)
    except ValueError as e:
        raise it.error(str(e), "range") from None
    if poly.empty:
        raise it.error("the planes' interiors do not intersect (empty polyhedron)", "range")
    it.count_cells(len(poly.faces))
    it.push(poly)


@word("cp-box")
def w_cp_box(it: Interpreter) -> None:
    """``lo hi cp-box → s``: the axis-aligned box polyhedron between two corners."""
    hi, lo = np.array(it.pop_point()), np.array(it.pop_point())
    check_points(it, lo, hi)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all() and (hi > lo).all()):
        raise it.error("cp-box needs finite corners with lo < hi on every axis", "range")
    it.push(Polyhedron.box(lo, hi))


@word("cp-scope")
def w_cp_scope(it: Interpreter) -> None:
    """``s cp-scope → scope``: a new root scope holding the polyhedron (axis-aligned box)."""
    poly = it.pop_type(lambda v: isinstance(v, Polyhedron), "a convex polyhedron")
    lo, hi = poly.bounds_in(np.zeros(3), np.eye(3))
    it.push(grammar_of(it).root(Scope(lo, np.eye(3), hi - lo), poly=poly))


def _piece(it: Interpreter, g: GScope, poly: Polyhedron, index: int) -> GScope:
    ps = g.shape.scope
    if poly.empty:
        scope = Scope.trusted(ps.origin.copy(), ps.rotation, np.zeros(3), ps.unit)
    else:
        lo, hi = poly.bounds_in(ps.origin, ps.rotation)
        scope = Scope.trusted(ps.to_world(lo[None])[0], ps.rotation, hi - lo, ps.unit)
    shape = Shape("", scope, label=g.shape.label, material=g.shape.material,
                  operator="split-plane", params={"side": ("inside", "outside")[index]},
                  rule=g.shape.symbol)
    g.shape.add(shape)
    return GScope(shape, poly)


@word("split-plane")
def w_split_plane(it: Interpreter) -> None:
    """``s e split-plane → inside outside`` (inside on top): cut a scope by a plane into two
    convex pieces, each in a scope fitted to it (either may be empty)."""
    plane = _pop_plane(it)
    g = pop_scope(it)
    grammar_of(it).count(2)
    inside, outside = g.polyhedron().split(plane)
    push_first_on_top(it, [_piece(it, g, inside, 0), _piece(it, g, outside, 1)])


@word("chop")
def w_chop(it: Interpreter) -> None:
    """``s e chop → s'``: keep the part of the scope inside the plane."""
    plane = _pop_plane(it)
    g = pop_scope(it)
    grammar_of(it).count(1)
    it.push(_piece(it, g, g.polyhedron().clip(plane), 0))
