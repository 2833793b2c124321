"""Instancing: derive a repeated, position-independent subtree once and replay it.

Facades repeat: every tile of a floor, every floor of a facade, runs the same rules on a shape of
the same size and orientation.  When a rule's whole subtree is *pure* — it reads neither the
shape's absolute position, nor random numbers, nor occlusion, nor split/comp indices it is not
keyed on — its output relative to the shape's scope depends only on what the cache key holds:
the rule and its arguments, the scope's size and rotation, the geometry in the scope frame,
material, attribute overrides and the context values the subtree reads.  The first such shape is
derived normally (depth-first, into a recorder); the others replay the recorded parts, reports
and prints moved into their own scope.

Texture coordinates inherited from a facade-wide projection differ from tile to tile but are an
affine function of position; they are left out of the key and re-derived on replay from the
input's affine map (corners whose UVs came from the input are recognised by that map).

A subtree that is pure but for stochastic choices (``30% : A else : B``, ``p(prob)``,
``listRandom``, stochastic expressions) is instanced *by chance*: it is recorded with the outcome
of each choice it made, found by the successor indices from the subtree's root, the draw of
that shape's random stream, and the choice's parameters; a later shape of the same key replays
the recording whose choices its own random streams repeat (the streams follow from a shape's
seed and those indices alone), and is derived and recorded otherwise (up to a few recordings a
key; ``Derivation._by_chance``).  Continuous random values (``rand()``) keep a subtree impure.

Enabled only when the caller drops shape trees (the CLI), and never for rule sets that use
occlusion queries (replayed shapes would not leave occluders behind).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import ast as A
from .functions import bare_call
from .module import Module, RuleSet
from .ops import OPERATIONS
from .ops.subdivision import SELECTOR_WORDS
from .ops.trimming import trim_key

IMPURE_NAMES = {"scope.tx", "scope.ty", "scope.tz", "scope.rx", "scope.ry", "scope.rz",
                "scope.elevation", "pivot.px", "pivot.py", "pivot.pz", "pivot.ox", "pivot.oy",
                "pivot.oz", "geometry.isInstanced", "geometry.groups"}
IMPURE_CALLS = {"rand", "p", "listRandom", "fileRandom", "convert", "minimumDistance",
                "contextCompare", "contextCount", "geometry.isInstanced", "geometry.groups",
                "getGeoCoord",
                "assetApproxRatio", "assetApproxSize", "assetFitSize", "imageApproxRatio"}
OCCLUSION_CALLS = {"inside", "overlaps", "touches"}
# random functions whose outcome is discrete: instancing by chance records it (interpreter)
CHANCE_CALLS = {"p", "listRandom"}
IMPURE_OPS = {"scatter", "consistent", "differentiate", "translate", "rotate",
              "resetGeometry"}  # resetGeometry: back to the initial shape, wherever this one is
CONTEXT_NAMES = {"split.index", "split.total", "comp.index", "comp.total", "comp.sel"}
# operations whose result depends on the UV values a shape inherits (not only on its position)
UV_OPS = {"tileUV", "translateUV", "offsetUV", "scaleUV", "rotateUV", "normalizeUV", "copyUV",
          "insertAlongUV"}
# operations that cut their geometry at the shape's trim planes (ops/trimming.py)
TRIM_OPS = {"i", "trim", "primitiveCube", "primitiveQuad", "primitiveCylinder", "primitiveCone",
            "primitiveDisk", "primitiveSphere"}
# operations that keep a shape's geometry inside its scope box, so that an asset inserted below
# them reaches no farther than its proportions allow (which trim planes can cut it)
IN_SCOPE_OPS = {"split", "comp", "setback", "setbackPerEdge", "setbackToArea", "shapeL",
                "shapeU", "shapeO", "splitArea", "color", "report", "print", "label", "texture",
                "setupProjection", "projectUV", "deleteUV", "set", "NIL"} | (UV_OPS - {"insertAlongUV"})
UV_NAMES = {"geometry.uMin", "geometry.uMax", "geometry.vMin", "geometry.vMax", "geometry.du",
            "geometry.dv"}


def _intra_only(m: Module, call: A.Call) -> bool:
    """Whether an occlusion query names the target ``intra`` literally (the default, and any
    expression, may reach the neighbours)."""
    if not call.args:
        return False
    target = call.args[0]
    if isinstance(target, A.Str):
        return target.value == "intra"
    return (isinstance(target, A.Name) and target.name == "intra"
            and m.attr("intra") is None and m.function("intra", 0) is None)


@dataclass
class RuleInfo:
    pure: bool = True
    reads: set = field(default_factory=set)  # context names read (split.index, …)
    projects: bool = False  # calls projectUV (depends on inherited projections)
    centers: bool = False  # calls center (depends on the pivot scope)
    uses_uv: bool = False  # reads or rewrites texture coordinates (tileUV, split(u|v), …)
    trims: bool = False  # inserts or trims (depends on the trim planes it inherits)
    assets: set = field(default_factory=set)  # the i("literal") assets it inserts
    far: bool = False  # may put geometry beyond its scope box (s, t, extrude, primitives…)
    chance: bool = False  # makes stochastic choices (``p% : … else : …``), itself or below
    calls: set = field(default_factory=set)  # (module id, rule or function name)


class Purity:
    """Which rules have position-independent, deterministic subtrees (fixpoint over calls).

    With ``chance``, stochastic choices (``30% : A else : B``) do not count as impure: a rule is
    then *pure by chance* when its subtree depends on nothing but its key and the outcomes of
    its choices (``RuleInfo.chance`` says it makes any), which the interpreter replays by
    outcome (see ``Derivation._instanced``)."""

    def __init__(self, ruleset: RuleSet, chance: bool = False):
        self.chance = chance
        self.modules = {id(m): m for m in ruleset.main.all_modules()}
        self.info: dict[tuple, RuleInfo] = {}
        self.uses_occlusion = False
        # whether a query may look at the neighbouring buildings (``inter``, ``all`` or a
        # target not known before the derivation): only then are neighbours derived first
        self.queries_neighbours = False
        for m in self.modules.values():
            for name, overloads in m.rules.items():
                info = RuleInfo()
                for rdef in overloads.values():
                    self._ops(m, rdef.body, info)
                self.info[(id(m), name)] = info
            for name, redefined in m.rule_overrides.items():  # an importer's version wins
                info = RuleInfo()
                for owner, rdef in redefined.values():
                    self._ops(owner, rdef.body, info)
                for arity, rdef in m.rules.get(name, {}).items():  # and the rest stay
                    if arity not in redefined:
                        self._ops(m, rdef.body, info)
                self.info[(id(m), name)] = info
            for name, (owner, target) in m.rule_forwards.items():
                # calls inside the file run the importer's rule, imp.Ext the file's own:
                # what holds for the rule holds for both
                info = self.info.setdefault((id(m), name), RuleInfo())
                callee = self._callee(owner, target)
                if callee is not None:
                    info.calls.add(callee)
            for name, overloads in m.functions.items():
                info = RuleInfo()
                for fdef in overloads.values():
                    self._expr(m, fdef.body, info)
                self.info[(id(m), "fn:" + name)] = info
            for adef in m.attrs.values():  # an attribute may ask an occlusion query too
                self._expr(m, adef.value, RuleInfo())
            for importer, expr in m.import_overrides.values():  # import F : "f.cga" (a = …)
                self._expr(importer, expr, RuleInfo())
        changed = True
        while changed:  # propagate impurity and reads along calls
            changed = False
            for info in self.info.values():
                for callee in list(info.calls):
                    other = self.info.get(callee)
                    if other is None:
                        continue
                    before = (info.pure, len(info.reads), info.projects, info.centers,
                              info.uses_uv, info.trims, len(info.assets), info.far, info.chance)
                    info.pure &= other.pure
                    info.chance |= other.chance
                    info.reads |= other.reads
                    info.projects |= other.projects
                    info.centers |= other.centers
                    info.uses_uv |= other.uses_uv
                    info.trims |= other.trims
                    info.assets |= other.assets
                    info.far |= other.far
                    if (info.pure, len(info.reads), info.projects, info.centers,
                            info.uses_uv, info.trims, len(info.assets), info.far,
                            info.chance) != before:
                        changed = True

    def rule(self, module: Module, name: str) -> RuleInfo | None:
        found = module.resolve(name) if "." in name else (module, name)
        if found is None:
            return None
        return self.info.get((id(found[0]), found[1]))

    # -- local analysis -------------------------------------------------------------------------
    def _callee(self, m: Module, name: str, prefix: str = ""):
        found = m.resolve(name) if "." in name else (m, name)
        return None if found is None else (id(found[0]), prefix + found[1])

    def _ops(self, m, ops, info):
        for op in ops:
            t = type(op)
            if t is A.Successor or t is A.Leaf:
                name = op.name
                args = getattr(op, "args", ())
                from .ops import operation_of

                spec = operation_of(op, m)
                if spec is not None:
                    if name in IMPURE_OPS:
                        info.pure = False
                    if name == "setupProjection" and len(args) > 1 and isinstance(args[1], A.Name) \
                            and args[1].name.startswith("world."):
                        info.pure = False
                    if name == "projectUV":
                        info.projects = True
                    if name == "set" and args and isinstance(args[0], A.Name) \
                            and args[0].name.startswith(("scope.t", "trim.")):
                        info.pure = False  # sets an absolute position, or which planes trim
                    if name == "center":
                        info.centers = True
                    if name in UV_OPS:
                        info.uses_uv = True
                    _note_reach(name, args, info)
                    self._args(m, spec, args, info)
                    continue
                if t is A.Successor:
                    callee = self._callee(m, name)
                    if callee is not None:
                        info.calls.add(callee)
                for a in args:
                    self._expr(m, a, info)
            elif t is A.BodyOp:
                if op.name in IMPURE_OPS:
                    info.pure = False
                _note_reach(op.name, op.args, info)
                if op.name == "split" and op.args and isinstance(op.args[0], A.Name) \
                        and op.args[0].name in ("u", "v"):
                    info.uses_uv = True
                self._args(m, OPERATIONS.get(op.name), op.args, info)
                self._branches(m, op.branches, info)
            elif t is A.Push or t is A.Inline:
                self._ops(m, op.ops, info)
            elif t is A.Boolean:
                self._ops(m, op.a, info)
                self._ops(m, op.b, info)
            elif t is A.CaseOps:
                for c, b in op.branches:
                    self._expr(m, c, info)
                    self._ops(m, b, info)
                self._ops(m, op.otherwise, info)
            elif t is A.StochasticOps:
                if not self.chance:
                    info.pure = False
                    continue
                info.chance = True
                for _, b in op.branches:
                    self._ops(m, b, info)
                self._ops(m, op.otherwise, info)

    def _args(self, m, spec, args, info):
        """An operation's arguments, but the bare keywords it takes (``offset(-1, inside)``:
        no occlusion query)."""
        keywords = spec.selector_positions(len(args)) if spec is not None else ()
        for i, a in enumerate(args):
            if not (i in keywords and type(a) is A.Name):
                self._expr(m, a, info)

    def _branches(self, m, branches, info):
        for b in branches:
            if isinstance(b, A.RepeatGroup):
                self._branches(m, b.branches, info)
            else:
                self._expr(m, b.selector, info, selector=True)
                if b.depth is not None:
                    self._expr(m, b.depth, info)
                self._ops(m, b.ops, info)

    def _expr(self, m, node, info, selector: bool = False):
        """``selector``: ``node`` selects components, where ``inside`` (offset's inner face)
        and the other selector words are no queries."""
        stack = [node]
        while stack:
            n = stack.pop()
            t = type(n)
            if t is A.Name:
                if selector and n.name in SELECTOR_WORDS:
                    continue
                if n.name in OCCLUSION_CALLS and m.attr(n.name) is None:  # `case inside : …`
                    info.pure = False
                    self.uses_occlusion = self.queries_neighbours = True
                elif n.name in IMPURE_NAMES or (n.name in IMPURE_CALLS and bare_call(n.name)):
                    info.pure = False
                elif n.name in CONTEXT_NAMES:
                    info.reads.add(n.name)
                elif n.name in UV_NAMES:
                    info.uses_uv = True
                elif m.function(n.name, 0) is not None:
                    callee = self._callee(m, n.name, "fn:")
                    if callee is not None:
                        info.calls.add(callee)
            elif t is A.Call:
                if n.name in UV_NAMES:
                    info.uses_uv = True
                if n.name in IMPURE_CALLS:
                    if self.chance and n.name in CHANCE_CALLS:
                        info.chance = True
                    else:
                        info.pure = False
                if n.name in OCCLUSION_CALLS:
                    info.pure = False
                    self.uses_occlusion = True
                    if not _intra_only(m, n):
                        self.queries_neighbours = True
                if m.function(n.name, len(n.args)) is not None:
                    callee = self._callee(m, n.name, "fn:")
                    if callee is not None:
                        info.calls.add(callee)
                stack.extend(n.args)
            elif t is A.StochasticExpr:
                if not self.chance:
                    info.pure = False
                    continue
                info.chance = True
                stack.extend(v for _, v in n.branches)
                stack.append(n.otherwise)
            elif t in (A.Binary,):
                stack.extend((n.left, n.right))
            elif t is A.Unary:
                stack.append(n.operand)
            elif t is A.Index:
                stack.append(n.target)
                stack.extend(n.indices)
            elif t is A.Array:
                for row in n.rows:
                    stack.extend(row)
            elif t is A.Colon:
                stack.extend(e for e in (n.start, n.step, n.stop) if e is not None)
            elif t is A.CaseExpr:
                for c, v in n.branches:
                    stack.extend((c, v))
                stack.append(n.otherwise)
            elif t is A.CompFunction:
                for b in n.branches:
                    stack.extend((b.selector, b.ops))


def _note_reach(name: str, args, info: RuleInfo) -> None:
    """What an operation tells about where trim planes may cut below it (``trims``, ``assets``,
    ``far``)."""
    if name in TRIM_OPS:
        info.trims = True
        if name == "i" and len(args) == 1 and isinstance(args[0], A.Str):
            info.assets.add(args[0].value)
            return
    first = args[0].name if args and isinstance(args[0], A.Name) else None
    if name not in IN_SCOPE_OPS or (name == "set" and str(first).startswith("scope.")) or (
            name == "comp" and first != "f"):  # comp(e|v): assets keep their size on an edge
        info.far = True


def _hashable(v):
    if isinstance(v, np.ndarray):
        return ("arr", v.shape, tuple(v.reshape(-1).tolist()))
    if isinstance(v, float):
        return round(v, 9)
    try:
        hash(v)
        return v
    except TypeError:
        return repr(v)


def _face_data_key(g) -> tuple:
    """The geometry's face and corner columns as a key: tags and offset kinds as they are,
    materials by identity, faces with holes by which pieces share one (not by their ids)."""
    if g.face_data is None and g.corner_data is None:
        return ()
    out = [(k, tuple(v)) for k, v in sorted((g.corner_data or {}).items())]
    if g.face_data is None:
        return tuple(out)
    for k in sorted(g.face_data):
        col = g.face_data[k]
        if k == "holed":
            ids: dict = {}
            out.append((k, tuple(None if r is None else ids.setdefault(r, len(ids)) for r in col)))
        elif k == "material":
            out.append((k, tuple(id(m) for m in col)))
        else:
            out.append((k, tuple(col)))
    return tuple(out)


def instance_key(mod, name, args, state, info: RuleInfo):
    """Cache key of a shape about to run ``name``, and the input's UV map; ``None`` when the
    shape cannot be instanced (UVs that are not an affine function of position)."""
    sc = state.scope
    g = state.geometry
    rot, org = sc.rotation, sc.origin
    uv_map = None
    if g.n_faces:
        local = (g.vertices[g.corners] - org) @ rot
        geom_key = (np.round(local, 6).tobytes(), g.starts.tobytes(), g.corner_uvs is not None)
        if g.corner_uvs is not None:
            if info.uses_uv:  # the subtree works on the inherited UV values themselves
                return None, None
            uv_map = affine_uv_map(local, g.corner_uvs)
            if uv_map is None:
                return None, None
    else:
        geom_key = ()
    ctx = state.context
    ctx_key = tuple((k, _hashable(ctx.get(k))) for k in sorted(info.reads))
    extra = (ctx.get("label"), _face_data_key(g))
    proj_key = ()
    if info.projects:
        proj_key = tuple(sorted(
            (k, np.round((o - org) @ rot, 6).tobytes(), np.round(u @ rot, 9).tobytes(),
             np.round(v @ rot, 9).tobytes(), w, h, off)
            for k, (o, u, v, w, h, off) in state.projections.items()))
    pivot_key = ()
    if info.centers and state.pivot is not None:
        p = state.pivot
        pivot_key = (np.round((p.origin - org) @ rot, 6).tobytes(), np.round(p.size, 6).tobytes(),
                     np.round(rot.T @ p.rotation, 9).tobytes())
    trims = trim_key(state, info.assets, info.far) if info.trims else ()
    key = (id(mod), name, tuple(_hashable(a) for a in args), np.round(sc.size, 6).tobytes(),
           np.round(rot, 9).tobytes(), geom_key, tuple(sorted((k, _hashable(v))
                                                              for k, v in state.material.items())),
           tuple(sorted((k, _hashable(v)) for k, v in state.attrs.items())), ctx_key, extra,
           state.label, proj_key, pivot_key, trims)
    return key, uv_map


def affine_uv_map(local: np.ndarray, uv: np.ndarray) -> np.ndarray | None:
    """(4, 2) map with ``[x, y, z, 1] @ map ≈ uv`` when the UVs are affine in position."""
    a = np.column_stack([local, np.ones(len(local))])
    coef, *_ = np.linalg.lstsq(a, uv, rcond=None)
    if np.abs(a @ coef - uv).max() > 1e-7:
        return None
    return coef


class Payoff:
    """Whether instancing a rule pays, judged from its first tries (per derivation).

    A try costs about as much as deriving one shape (the cache key: the geometry in the scope
    frame, rounded, and the UV map), and a hit saves the shapes of the recorded subtree.  A rule
    whose shapes rarely repeat (every window opening a different size) or whose subtree is a
    single leaf (a wall texture) loses time to instancing; after :data:`TRIES` tries, such a rule
    is derived directly for the rest of the derivation.  The decision depends only on counts,
    so a derivation stays deterministic."""

    TRIES = 16
    MIN_SAVED = 2.0  # shapes saved per try, on average, for instancing to pay

    __slots__ = ("tries", "hits", "recorded", "records", "off")

    def __init__(self):
        self.tries = self.hits = self.recorded = self.records = 0
        self.off = False

    def note(self, hit: bool, shapes: int) -> None:
        """One try: a hit, or a new recording of ``shapes`` shapes."""
        self.tries += 1
        if hit:
            self.hits += 1
        else:
            self.records += 1
            self.recorded += shapes + 1  # the subtree's shapes and its root
        if self.tries >= self.TRIES and self.records:
            saved = self.hits / self.tries * (self.recorded / self.records)
            self.off = saved < self.MIN_SAVED


@dataclass
class Recording:
    """What a subtree produced, relative to its root's scope frame."""

    parts: list  # (local Mesh, label, material, symbol)
    reports: list  # (name, value) in order
    prints: list
    shapes: int
    uv_map: np.ndarray | None
