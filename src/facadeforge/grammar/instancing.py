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

Subtrees instanced by chance nest: a tile of three windows, each window choosing its texture.
The windows are *slots* of the tile's recording (``Recording.slots``), not part of its choices.
Every replay of the tile resolves each slot (``Derivation._resolve``): the slot's random
stream follows from the replay's seed along the slot's successor indices, and picks the window
recording whose choices that stream repeats.  Variants of one key that all draw alike are found
by their outcomes in one lookup (``Derivation._variant``).  A slot whose stream makes a choice
that no variant has is derived alone (``Derivation._fill``): its key's first shape is derived
again, with the slot's seed, in that shape's own frame, and kept as a new variant.  The tile
around the slot is not derived again.  Recordings with no choices of their own are flattened
into the recording under way.

Enabled only when the caller drops shape trees (the CLI), and never for rule sets that use
occlusion queries (replayed shapes would not leave occluders behind).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import ast as A
from .functions import FUNCTIONS, bare_call
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
# operations after which a shape's texture coordinates are its new geometry's own (an asset's,
# a primitive's, none): the same wherever the shape is
FRESH_UV_OPS = {"i", "insert", "primitiveCube", "primitiveQuad", "primitiveCylinder",
                "primitiveCone", "primitiveDisk", "primitiveSphere", "deleteUV"}
# names of the world's or the initial shape's heading (selectors, axes, built-ins): all but
# the vertical ones make a subtree depend on how its scope is turned about the vertical
_HEADED = ("world.", "object.", "street.", "streetSide", "noStreetSide")
_UPRIGHT = {"world.up", "world.down", "world.y"}
YAWED_OPS = {"alignScopeToAxes", "alignScopeToGeometry", "setPivot", "rotate", "translate"}
YAWED_CALLS = {"geometry.angle", "convert", "getGeoCoord"}
# rounding of a random draw that makes it a discrete choice: ``floor(rand(0, 9.99))``
DISCRETE_OF_RAND = {"floor", "ceil", "rint"}
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
# operations that put new geometry in the scope, whatever the shape's was, and operations that
# read nothing of it but its scope (when their arguments read none of it either)
REPLACING_OPS = {"i", "insert", "primitiveCube", "primitiveQuad", "primitiveCylinder",
                 "primitiveCone", "primitiveDisk", "primitiveSphere"}
SCOPE_ONLY_OPS = {"s", "t", "r", "center", "rotateScope", "color", "texture", "set",
                  "setupProjection", "label"}
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
    centers: bool = False  # calls center on its own shape (depends on the pivot it inherits)
    uses_uv: bool = False  # reads or rewrites the texture coordinates it inherits (tileUV, …)
    # rewrites texture coordinates that a projectUV below made from an inherited projection:
    # then the projection's place matters, not only its direction and scale
    uv_projected: bool = False
    trims: bool = False  # inserts or trims (depends on the trim planes it inherits)
    assets: set = field(default_factory=set)  # the i("literal") assets it inserts
    far: bool = False  # may put geometry beyond its scope box (s, t, extrude, primitives…)
    chance: bool = False  # makes stochastic choices (``p% : … else : …``), itself or below
    # reads the heading of the world or of the initial shape (``world.south``, ``object.front``,
    # alignScopeToAxes…): without it, a subtree turned about the vertical makes the same parts,
    # turned, and shapes whose scopes differ only by that turn share one recording
    yawed: bool = False
    calls: set = field(default_factory=set)  # (module id, rule or function name)
    # the calls made while the shape's texture coordinates were still the inherited ones, and
    # while they came from a projectUV of its own: their use of UVs counts for this rule
    uv_calls: set = field(default_factory=set)
    projected_calls: set = field(default_factory=set)
    sets: set = field(default_factory=set)  # attributes set (``set(name, …)``) here or below
    # replaces its shape's geometry before reading it (``Purity._fresh_first``); None: unknown
    fresh: bool | None = None


class Purity:
    """Which rules have position-independent, deterministic subtrees (fixpoint over calls).

    With ``chance``, stochastic choices (``30% : A else : B``) do not count as impure: a rule is
    then *pure by chance* when its subtree depends on nothing but its key and the outcomes of
    its choices (``RuleInfo.chance`` says it makes any), which the interpreter replays by
    outcome (see ``Derivation._instanced``)."""

    def __init__(self, ruleset: RuleSet, chance: bool = False, fold=None):
        self.chance = chance
        # ``fold(module, condition) -> bool | None``: the value of a case condition that
        # depends on nothing but attributes no rule sets (``case Mode == "3DPrint"``), which
        # a derivation knows before it starts; only the branch taken is then looked at
        self.fold = fold
        self.modules = {id(m): m for m in ruleset.main.all_modules()}
        self.info: dict[tuple, RuleInfo] = {}
        self.uses_occlusion = False
        # whether a query may look at the neighbouring buildings (``inter``, ``all`` or a
        # target not known before the derivation): only then are neighbours derived first
        self.queries_neighbours = False
        self._uv = "inherited"  # where the UVs come from, for the expression being looked at
        self._params: set[str] = set()  # parameters of the rule being looked at
        # while a rule is specialised: (its parameter values, constant) and the calls whose
        # arguments follow from them (:meth:`specialised`)
        self._bound = None
        self._spec: list | None = None
        for m in self.modules.values():
            for name, overloads in m.rules.items():
                info = RuleInfo()
                for rdef in overloads.values():
                    self._rule(m, rdef, info)
                self.info[(id(m), name)] = info
            for name, redefined in m.rule_overrides.items():  # an importer's version wins
                info = RuleInfo()
                for owner, rdef in redefined.values():
                    self._rule(owner, rdef, info)
                for arity, rdef in m.rules.get(name, {}).items():  # and the rest stay
                    if arity not in redefined:
                        self._rule(m, rdef, info)
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
                    if other is not None and _absorb(info, other, callee in info.uv_calls,
                                                     callee in info.projected_calls):
                        changed = True

    def rule(self, module: Module, name: str) -> RuleInfo | None:
        found = module.resolve(name) if "." in name else (module, name)
        if found is None:
            return None
        return self.info.get((id(found[0]), found[1]))

    def specialised(self, mod: Module, rdef: A.RuleDef, args, constant, memo: dict,
                    context=(), depth: int = 0) -> RuleInfo | None:
        """The analysis of one rule called with these argument values: a case whose conditions
        read only its parameters (and attributes no rule sets) is decided, and a call whose
        arguments follow from them is looked at for its own values, down the subtree.
        ``Tile(n) --> … SubTile(n)``, ``SubTile(n) --> case n > 0 : Windows(n) else :
        GroundSubTile(n)`` (Esri's Candler): the rule as a whole edits inherited texture
        coordinates (the ground-floor branch), ``Tile(1)`` does not, and can be instanced.

        ``constant(module, expr, bound)`` gives an expression's value when it depends on
        nothing but the ``bound`` parameter values, literals and attributes, else
        :data:`UNKNOWN` (the derivation's: it knows the attribute values where the rule is
        called; ``context`` is a key of them).  ``memo`` (the derivation's) keeps the answers;
        ``None`` while one is being worked out (a rule that calls itself with the same values:
        the caller takes the rule's general analysis), and for more than
        :data:`SPECIAL_DEPTH` nested values or :data:`SPECIAL_RULES` in all."""
        key = (id(mod), id(rdef), tuple(_hashable(a) for a in args), context)
        if key in memo:
            return memo[key]
        if depth > SPECIAL_DEPTH or len(memo) >= SPECIAL_RULES:
            return None
        memo[key] = None
        bound = {p.name: v for p, v in zip(rdef.params, args)}
        saved = (self.fold, self._params, self._spec, self._bound)
        info = RuleInfo()
        self.fold = lambda m, cond, params: _truth(constant(m, cond, bound))
        self._bound, self._spec = (bound, constant), []
        try:
            self._rule(mod, rdef, info)
            calls = self._spec
        finally:
            self.fold, self._params, self._spec, self._bound = saved
        for callee in list(info.calls):
            other = self.info.get(callee)
            if other is not None:
                _absorb(info, other, callee in info.uv_calls, callee in info.projected_calls)
        for m, name, values, uv in calls:
            found = m.rule(name, len(values))
            if found is None:
                continue  # no such rule: the shape is left as it is (a warning, when derived)
            other = self.specialised(found[0], found[1], values, constant, memo, context,
                                     depth + 1)
            if other is None:
                other = self.rule(m, name)
            if other is not None:
                _absorb(info, other, uv == "inherited", uv == "projected")
        memo[key] = info
        return info

    # -- local analysis -------------------------------------------------------------------------
    def _rule(self, m: Module, rdef: A.RuleDef, info: RuleInfo) -> None:
        """Note one rule definition (an overload) in ``info``."""
        self._params = {p.name for p in rdef.params}
        self._ops(m, rdef.body, info)
        info.fresh = info.fresh is not False and self._fresh_first(m, rdef.body)

    def _fresh_first(self, m: Module, ops) -> bool:
        """Whether ``ops`` replace the shape's geometry (an insert, a primitive) before anything
        reads it, on every path: then which geometry the shape had does not matter, only its
        scope (a window asset inserted on a quad whose corners start anywhere)."""
        for op in ops:
            t = type(op)
            if t is A.CaseOps:
                branches, taken = op.branches, None
                if self.fold is not None:
                    branches, taken = self._fold_case(m, op)
                if taken is not None:
                    return self._fresh_first(m, taken)
                return (all(_geometry_free(m, c) and self._fresh_first(m, b)
                            for c, b in branches) and self._fresh_first(m, op.otherwise))
            if t is not A.Successor:
                return False
            from .ops import operation_of

            if operation_of(op, m) is None or not all(_geometry_free(m, a) for a in op.args):
                return False
            if op.name in REPLACING_OPS:
                return True
            if op.name not in SCOPE_ONLY_OPS:
                return False
        return False

    def _callee(self, m: Module, name: str, prefix: str = ""):
        found = m.resolve(name) if "." in name else (m, name)
        return None if found is None else (id(found[0]), prefix + found[1])

    def _ops(self, m, ops, info, uv: str = "inherited", top: bool = True) -> str:
        """Note what ``ops`` do in ``info``.  ``uv`` says where the shape's texture coordinates
        come from at the first op — ``inherited`` (the caller's), ``fresh`` (an inserted asset's
        or a primitive's own: the same wherever the shape is) or ``projected`` (a projectUV of
        this subtree) — and the state after the last op is returned.  ``top``: the ops work on
        the rule's own shape (not a piece of a split or comp, nor a pushed copy, whose pivot is
        their own), where center() aligns to the pivot the shape inherits."""
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
                    if name == "set" and args and isinstance(args[0], A.Name):
                        if args[0].name.startswith(("scope.t", "trim.")):
                            info.pure = False  # sets an absolute position, or which planes trim
                        info.sets.update((args[0].name, args[0].name.rsplit(".", 1)[-1]))
                    if name == "center" and top:
                        info.centers = True
                    if name in YAWED_OPS:
                        info.yawed = True
                    if name in UV_OPS:
                        self._uses_uv(info, uv)
                    _note_reach(name, args, info)
                    self._uv = uv
                    self._args(m, spec, args, info)
                    if name == "projectUV":
                        info.projects = True
                        if not (args and isinstance(args[0], A.Num) and args[0].value != 0):
                            uv = "projected"  # only UV set 0 is kept
                    elif name in FRESH_UV_OPS and (name != "deleteUV" or (
                            args and isinstance(args[0], A.Num) and args[0].value == 0)):
                        uv = "fresh"
                    continue
                if t is A.Successor:
                    values = self._constant_args(m, args) if args else None
                    if values is not None:  # specialised: the callee for these values
                        self._spec.append((m, name, values, uv))
                    else:
                        callee = self._callee(m, name)
                        if callee is not None:
                            self._call(info, callee, uv)
                self._uv = uv
                for a in args:
                    self._expr(m, a, info)
            elif t is A.BodyOp:
                if op.name in IMPURE_OPS:
                    info.pure = False
                if op.name in YAWED_OPS:
                    info.yawed = True
                _note_reach(op.name, op.args, info)
                if op.name == "split" and op.args and isinstance(op.args[0], A.Name) \
                        and op.args[0].name in ("u", "v"):
                    self._uses_uv(info, uv)
                self._uv = uv
                self._args(m, OPERATIONS.get(op.name), op.args, info)
                self._branches(m, op.branches, info, uv)
            elif t is A.Push:
                self._ops(m, op.ops, info, uv, top=False)
            elif t is A.Inline or t is A.Boolean:
                for part in ((op.ops,) if t is A.Inline else (op.a, op.b)):
                    self._ops(m, part, info, uv, top=False)
                # the merged leaves' UVs may come from anywhere below: the least known
                uv = "inherited" if uv == "inherited" else "projected"
            elif t is A.CaseOps:
                branches = op.branches
                if self.fold is not None:
                    branches, taken = self._fold_case(m, op)
                    if taken is not None:
                        return self._ops(m, taken, info, uv, top)
                ends = []
                for c, b in branches:
                    self._uv = uv
                    self._expr(m, c, info)
                    ends.append(self._ops(m, b, info, uv, top))
                ends.append(self._ops(m, op.otherwise, info, uv, top))
                return _worst(ends)
            elif t is A.StochasticOps:
                if not self.chance:
                    info.pure = False
                    continue
                info.chance = True
                ends = [self._ops(m, b, info, uv, top) for _, b in op.branches]
                ends.append(self._ops(m, op.otherwise, info, uv, top))
                return _worst(ends)
        return uv

    def _constant_args(self, m, args):
        """The values of a call's arguments while a rule is specialised (:meth:`specialised`)
        and all of them follow from its parameter values; else ``None``."""
        if self._bound is None:
            return None
        bound, constant = self._bound
        values = []
        for a in args:
            v = constant(m, a, bound)
            if v is UNKNOWN:
                return None
            values.append(v)
        return values

    def _fold_case(self, m, op: A.CaseOps):
        """(branches still to look at, ops of the branch surely taken or None)."""
        for k, (cond, ops) in enumerate(op.branches):
            value = self.fold(m, cond, self._params)
            if value is None:
                return op.branches[k:], None
            if value:
                return (), ops
        return (), op.otherwise

    def _uses_uv(self, info: RuleInfo, uv: str) -> None:
        """An operation or query works on the shape's texture coordinates in state ``uv``."""
        if uv == "inherited":
            info.uses_uv = True
        elif uv == "projected":
            info.uv_projected = True

    def _call(self, info: RuleInfo, callee, uv: str) -> None:
        info.calls.add(callee)
        if uv == "inherited":
            info.uv_calls.add(callee)
        elif uv == "projected":
            info.projected_calls.add(callee)

    def _args(self, m, spec, args, info):
        """An operation's arguments, but the bare keywords it takes (``offset(-1, inside)``:
        no occlusion query)."""
        keywords = spec.selector_positions(len(args)) if spec is not None else ()
        for i, a in enumerate(args):
            if not (i in keywords and type(a) is A.Name):
                self._expr(m, a, info)

    def _branches(self, m, branches, info, uv: str = "inherited"):
        for b in branches:
            if isinstance(b, A.RepeatGroup):
                self._branches(m, b.branches, info, uv)
            else:
                self._uv = uv
                self._expr(m, b.selector, info, selector=True)
                if b.depth is not None:
                    self._expr(m, b.depth, info)
                self._ops(m, b.ops, info, uv, top=False)

    def _expr(self, m, node, info, selector: bool = False):
        """``selector``: ``node`` selects components, where ``inside`` (offset's inner face)
        and the other selector words are no queries."""
        stack = [node]
        while stack:
            n = stack.pop()
            t = type(n)
            if t is A.Name:
                if n.name.startswith(_HEADED) and n.name not in _UPRIGHT:
                    info.yawed = True
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
                    self._uses_uv(info, self._uv)
                elif m.function(n.name, 0) is not None:
                    callee = self._callee(m, n.name, "fn:")
                    if callee is not None:
                        self._call(info, callee, self._uv)
            elif t is A.Call:
                if n.name in YAWED_CALLS:
                    info.yawed = True
                if n.name in UV_NAMES:
                    self._uses_uv(info, self._uv)
                if (self.chance and n.name in DISCRETE_OF_RAND and len(n.args) == 1
                        and discrete_rand(m, n)):
                    info.chance = True  # floor(rand(a, b)): a choice among whole numbers
                    stack.extend(n.args[0].args)
                    continue
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
                        self._call(info, callee, self._uv)
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


def set_targets(ruleset: RuleSet) -> set[str]:
    """Names of the attributes some rule of the set changes (``set(name, …)``), short and as
    written."""
    out: set[str] = set()
    stack: list = []
    for m in ruleset.main.all_modules():
        stack.extend(r.body for by_arity in m.rules.values() for r in by_arity.values())
        stack.extend(r.body for by_arity in m.rule_overrides.values() for _, r in by_arity.values())
        stack.extend(r.body for by_arity in m.qualified_rules.values() for r in by_arity.values())
    while stack:
        n = stack.pop()
        if isinstance(n, (tuple, list)):
            stack.extend(n)
        elif isinstance(n, A.Node):
            if type(n) is A.Successor and n.name == "set" and n.args \
                    and type(n.args[0]) is A.Name:
                out.add(n.args[0].name)
                out.add(n.args[0].name.rsplit(".", 1)[-1])
            stack.extend(getattr(n, f) for f in n.__dataclass_fields__
                         if f not in ("line", "column"))
    return out


def constant_attributes(m: Module, node, changed: set[str], local: set[str] = frozenset(),
                        bound=frozenset()):
    """The ``(module, AttrDef)`` an expression reads when it reads nothing but attributes no
    rule changes, literals and CGA's deterministic functions of them; else ``None``.
    ``local``: the names of the rule's parameters, which hide attributes; ``bound``: those of
    them whose values are known (a specialised rule's, :meth:`Purity.specialised`)."""
    from .ops import SHAPE_FUNCTIONS

    deps, stack = [], [node]
    while stack:
        n = stack.pop()
        t = type(n)
        if t in (A.Num, A.Str, A.Bool):
            continue
        if t is A.Name and n.name in bound:
            continue
        if t is A.Name:
            found = m.attr(n.name) if n.name not in local else None
            if found is None or n.name in changed or found[1].name in changed:
                return None
            deps.append(found)
        elif t is A.Unary:
            stack.append(n.operand)
        elif t is A.Binary:
            stack.extend((n.left, n.right))
        elif t is A.Call:
            if (n.name in IMPURE_CALLS or n.name in SHAPE_FUNCTIONS or n.name in OCCLUSION_CALLS
                    or m.function(n.name, len(n.args)) is not None or "." in n.name
                    or n.name not in FUNCTIONS):
                return None
            stack.extend(n.args)
        else:
            return None
    return deps


#: a value that cannot be known before the derivation (:meth:`Purity.specialised`)
UNKNOWN = object()
#: nested argument values followed at most, and specialised analyses kept at most, per
#: derivation: ``R(n) --> … R(n + 1)`` would otherwise be followed without end
SPECIAL_DEPTH = 24
SPECIAL_RULES = 512


def _geometry_free(m: Module, node) -> bool:
    """Whether an expression reads nothing of the shape's geometry (``geometry.*``, or a
    function of the rules, which might)."""
    stack = [node]
    while stack:
        n = stack.pop()
        if isinstance(n, (tuple, list)):
            stack.extend(n)
            continue
        if not isinstance(n, A.Node):
            continue
        t = type(n)
        if t is A.Name and (n.name.startswith("geometry.") or m.function(n.name, 0) is not None):
            return False
        if t is A.Call and (n.name.startswith("geometry.")
                            or m.function(n.name, len(n.args)) is not None):
            return False
        stack.extend(getattr(n, f) for f in n.__dataclass_fields__ if f not in ("line", "column"))
    return True


def _truth(value) -> bool | None:
    if value is UNKNOWN:
        return None
    return bool(value)


def _absorb(info: RuleInfo, other: RuleInfo, inherited: bool, projected: bool) -> bool:
    """What a callee's analysis adds to its caller's; whether it changed.  ``inherited`` and
    ``projected``: the callee is called while the caller's texture coordinates are the ones it
    inherited, or ones a projectUV of its own made."""
    before = (info.pure, len(info.reads), info.projects, info.uses_uv, info.uv_projected,
              info.trims, len(info.assets), info.far, info.chance, info.yawed, len(info.sets))
    info.sets |= other.sets
    info.pure &= other.pure
    info.yawed |= other.yawed
    info.chance |= other.chance
    info.reads |= other.reads
    info.projects |= other.projects
    # a callee's center() aligns to the scope its caller had when calling it (every
    # successor's pivot), which the caller's key fixes: not propagated
    if inherited:
        info.uses_uv |= other.uses_uv
    if projected:
        info.uv_projected |= other.uses_uv
    info.uv_projected |= other.uv_projected
    info.trims |= other.trims
    info.assets |= other.assets
    info.far |= other.far
    return (info.pure, len(info.reads), info.projects, info.uses_uv, info.uv_projected,
            info.trims, len(info.assets), info.far, info.chance, info.yawed,
            len(info.sets)) != before


def _worst(states: list[str]) -> str:
    """The texture coordinates after one of several branches: the least known of theirs."""
    for state in ("inherited", "projected"):
        if state in states:
            return state
    return "fresh"


def discrete_rand(m: Module, call: A.Call) -> bool:
    """Whether ``call`` is ``floor(rand(…))`` (or ceil, rint) of CGA's own functions: a draw
    whose outcome is one of a few whole numbers, which instancing by chance can match."""
    inner = call.args[0]
    return (type(inner) is A.Call and inner.name == "rand" and len(inner.args) <= 2
            and m.function(call.name, 1) is None and m.function("rand", len(inner.args)) is None)


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
    proj0 = state.projections.get(0)
    proj0_map = None
    if proj0 is not None and (info.projects or g.corner_uvs is not None):
        proj0_map = projection_uv_map(proj0, rot, org)
    if info.fresh:  # the subtree puts its own geometry in the scope first
        geom_key = ("fresh", g.n_faces > 0)
    elif g.n_faces:
        if g.corner_uvs is not None and info.uses_uv:
            return None, None  # the subtree works on the inherited UV values themselves
        local = (g.vertices[g.corners] - org) @ rot
        geom_key = (rounded(local, 6), g.starts.tobytes(), g.corner_uvs is not None)
        if g.corner_uvs is not None:
            # most inherited UVs are the projection's (a facade's projectUV): its map, when it
            # gives them, saves a least-squares fit
            if proj0_map is not None and np.abs(
                    local @ proj0_map[:3] + proj0_map[3] - g.corner_uvs).max() <= 1e-7:
                uv_map = proj0_map
            how = "projection" if uv_map is not None else "fit"
            if uv_map is None:
                uv_map = affine_uv_map(local, g.corner_uvs)
            if uv_map is None:
                return None, None
            geom_key = (*geom_key, how)
    else:
        geom_key = ()
    ctx = state.context
    ctx_key = tuple((k, _hashable(ctx.get(k))) for k in sorted(info.reads))
    extra = (ctx.get("label"), _face_data_key(g))
    proj_key = ()
    proj_map = None
    if info.projects and info.uv_projected:  # UVs projected below are edited: all of it
        proj_key = tuple(sorted(
            (k, rounded((o - org) @ rot, 6), rounded(u @ rot, 9),
             rounded(v @ rot, 9), w, h, off)
            for k, (o, u, v, w, h, off) in state.projections.items()))
    elif info.projects:
        # where the projection lies moves the UVs a projectUV below makes by a constant, which
        # the replay puts right (its map, affine in the scope frame): the key holds only the
        # projection's directions and tile sizes; set 0 is the only one kept in the geometry
        if proj0 is not None:
            o, u, v, w, h, off = proj0
            proj_key = (rounded(np.concatenate([u, v]).reshape(2, 3) @ rot, 9), w, h)
        proj_map = proj0_map
    pivot_key = ()
    if info.centers and state.pivot is not None:
        p = state.pivot
        pivot_key = (rounded((p.origin - org) @ rot, 6), rounded(p.size, 6),
                     rounded(rot.T @ p.rotation, 9))
    trims = trim_key(state, info.assets, info.far) if info.trims else ()
    # the scope's turn: whole, or only where the vertical lies in it (its up in scope axes)
    turn = rounded(rot if info.yawed else rot[1], 9)
    key = (id(mod), name, tuple(_hashable(a) for a in args), rounded(sc.size, 6),
           turn, info.yawed, geom_key, tuple(sorted((k, _hashable(v))
                                                              for k, v in state.material.items())),
           tuple(sorted((k, _hashable(v)) for k, v in state.attrs.items())), ctx_key, extra,
           state.label, proj_key, pivot_key, trims)
    return key, (uv_map, proj_map)


def rounded(a, decimals: int) -> bytes:
    """An array rounded as a cache key: ``-0.0`` is ``0.0`` (they differ as bytes)."""
    return (a.round(decimals) + 0.0).tobytes()


def moved_uv_map(m: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A (4, 2) UV map of a frame, in a frame placed in it by ``x = x_new @ a + b``."""
    out = np.empty((4, 2))
    out[:3] = a @ m[:3]
    out[3] = b @ m[:3] + m[3]
    return out


def projection_uv_map(projection, rot: np.ndarray, org: np.ndarray) -> np.ndarray:
    """(4, 2) map with ``[x, y, z, 1] @ map`` the UVs ``projectUV(0)`` gives a point at
    ``x, y, z`` of the scope frame ``rot``, ``org`` (ops/appearance.py, ``op_project_uv``)."""
    o, u, v, w, h, off = projection
    out = np.empty((4, 2))
    out[:3, 0] = (u @ rot) / w
    out[:3, 1] = (v @ rot) / h
    d = org - o
    out[3, 0] = (d @ u - off[0]) / w
    out[3, 1] = (d @ v - off[1]) / h
    return out


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

    __slots__ = ("tries", "hits", "recorded", "records", "off", "judge_after", "slotted")

    def __init__(self, tries: int | None = None):
        self.tries = self.hits = self.recorded = self.records = 0
        self.off = False
        self.judge_after = self.TRIES if tries is None else tries
        # its recordings fill slots of larger recordings by chance: what it saves is theirs
        self.slotted = False

    def note(self, hit: bool, shapes: int) -> None:
        """One try: a hit, or a new recording of ``shapes`` shapes."""
        self.tries += 1
        if hit:
            self.hits += 1
        else:
            self.records += 1
            self.recorded += shapes + 1  # the subtree's shapes and its root
        if self.tries >= self.judge_after and self.records and not self.slotted:
            saved = self.hits / self.tries * (self.recorded / self.records)
            self.off = saved < self.MIN_SAVED


@dataclass
class Recording:
    """What a subtree produced, relative to its root's scope frame."""

    parts: list  # (local Mesh, label, material, symbol)
    reports: list  # (name, value) in order
    prints: list
    shapes: int  # the subtree's shapes, but those of its slots
    # the affine UV maps at recording (the inherited UVs', projectUV(0)'s), or None each
    uv_map: tuple
    # subtrees instanced by chance inside this one, left to each replay to choose
    # (``Derivation._resolve``): ``(successor indices from the root, key, A, b, maps)``, the
    # slot's scope frame in the root's (``x_root = x_slot @ A + b``) and, per UV map of the
    # slot, which of the root's it follows
    slots: tuple = ()
    _uv_corners: dict = field(default_factory=dict)
    _seeds: tuple | None = None

    def seed_program(self) -> tuple:
        """How a replay finds its slots' random streams: steps ``(from, index)``, each the
        stream of successor ``index`` of an earlier one (0: the root's, ``k``: step ``k``'s),
        and per slot the stream it takes.  Slots' paths share their beginnings (the windows of
        one tile): each stream is made once."""
        if self._seeds is None:
            nodes: dict = {(): 0}
            steps, of_slot = [], []
            for spath, *_ in self.slots:
                n = len(spath)
                while spath[:n] not in nodes:
                    n -= 1
                for m in range(n, len(spath)):
                    steps.append((nodes[spath[:m]], spath[m]))
                    nodes[spath[:m + 1]] = len(steps)
                of_slot.append(nodes[spath])
            self._seeds = (tuple(steps), tuple(of_slot))
        return self._seeds

    def uv_corners(self, j: int):
        """Part ``j``'s corners as ``[x, y, z, 1]`` rows, and per UV map the corners whose UVs
        it gave (the first map that does; ``None`` where it gave none): the corners a replay
        re-derives when that map differs for the shape it goes to."""
        got = self._uv_corners.get(j)
        if got is None:
            local = self.parts[j][0]
            pts = np.column_stack([local.vertices[local.corners], np.ones(len(local.corners))])
            done = np.zeros(len(pts), bool)
            hits = []
            for m in self.uv_map:
                if m is None:
                    hits.append(None)
                    continue
                hit = ~done & (np.abs(pts @ m - local.corner_uvs).max(axis=1) < 1e-7)
                done |= hit
                hits.append(np.flatnonzero(hit) if hit.any() else None)
            got = self._uv_corners[j] = (pts, hits)
        return got
