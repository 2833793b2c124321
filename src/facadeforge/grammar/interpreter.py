"""Derive CGA rules on initial shapes: the shape-grammar interpreter.

Breadth-first over shapes (as CityEngine derives generation by generation), with an operation
registry, per-shape random streams, CGA warnings for runtime problems and hard caps on depth,
shape count and time.
"""

from __future__ import annotations

import difflib
import gc
import math
import sys
import threading
import zlib
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..errors import DerivationError, RuleError
from ..geometry.mesh import Mesh
from ..model.labels import label_for_name
from ..model.model import Material, Model, Part
from ..model.shape import Shape
from . import ast as A
from .budget import Budget
from .chance import combinations, outcome, rand_value
from .expressions import Evaluator
from .functions import FUNCTIONS, bare_call, rand_bounds
from .instancing import (
    UNKNOWN,
    Payoff,
    Purity,
    Recording,
    _hashable,
    constant_attributes,
    instance_key,
    moved_uv_map,
    set_targets,
)
from .module import Module, RuleSet
from .ops import OPERATIONS, OpCall, load_all, operation_of
from .ops import SHAPE_FUNCTIONS as _SHAPE_FUNCTIONS
from .ops.scoping import euler_xyz_deg, pivot_frame, pivot_value
from .state import ShapeState, child_seed, random_value
from .values import CGARuntimeError, to_bool, to_float, to_str

load_all()

MAX_CALL_DEPTH = 1000  # CGA function calls in a chain: rules walk lists by recursion
MAX_INLINE_DEPTH = 64
#: Python frames a derivation may need: a CGA function call is about ten of them, so Esri's
#: Plant_Distributor, which sums a 127-plant list by recursion, needs more than Python's default
#: 1,000; 1,000 CGA calls stay well inside a thread's 8 MB stack (about 3 KB a call measured)
PYTHON_RECURSION_LIMIT = 20_000


@dataclass
class Limits:
    """Caps that keep a derivation bounded (STYLE: "derivations and loops are bounded")."""

    max_depth: int = 1024
    #: shapes of one derivation (Candler Building, a production rule, makes 12,400)
    max_shapes: int = 1_000_000
    #: wall-clock seconds of one derivation (``budget.Budget``); ``--max-seconds``
    max_seconds: float = 30.0
    #: growth of the process's memory during one derivation, MiB; ``--max-memory``
    max_memory_mb: float = 1536.0
    max_warnings: int = 1000


_running_lock = threading.Lock()
# derivations running, and the process settings found when the first of them started
_running = {"count": 0, "gc_was_enabled": False, "recursion_limit": 0}


@contextmanager
def deriving():
    """The process-wide settings a derivation needs, back as they were when the last
    derivation running leaves (threads share them, so the calls are counted).

    - Python's cyclic garbage collector is paused.  A derivation allocates hundreds of
      thousands of small objects that live until it ends (shapes, states, scopes, meshes); the
      collector's passes traverse them again and again (``benchmarks/cga_speed.py``: Candler
      Building on seven lots 12.2 s with it, 9.0 s without).  Reference counting frees
      everything, since a derivation makes no reference cycle: an environment is its own
      expression evaluator (``expressions.Evaluator``) rather than pointing at one that points
      back, and a shape holds its parent weakly (``Shape.parent``).
    - Python's recursion limit is raised to :data:`PYTHON_RECURSION_LIMIT`.  In a thread of
      your own, give it a stack of 8 MB or more (``threading.stack_size``) before starting it:
      macOS gives threads 512 KB, which a CGA recursion a few hundred calls deep overflows."""
    with _running_lock:
        if _running["count"] == 0:
            _running["gc_was_enabled"] = gc.isenabled()
            _running["recursion_limit"] = sys.getrecursionlimit()
            gc.disable()
            if _running["recursion_limit"] < PYTHON_RECURSION_LIMIT:
                sys.setrecursionlimit(PYTHON_RECURSION_LIMIT)
        _running["count"] += 1
    try:
        yield
    finally:
        with _running_lock:
            _running["count"] -= 1
            if _running["count"] == 0:
                sys.setrecursionlimit(_running["recursion_limit"])
                if _running["gc_was_enabled"]:
                    gc.enable()


class Env(Evaluator):
    """Name and function resolution while a rule runs on one shape."""

    __slots__ = ("derivation", "module", "locals", "state", "call_depth", "rule")

    def __init__(self, derivation, module: Module, local_vars: dict, state: ShapeState, rule=None,
                 call_depth: int = 0):
        self.derivation = derivation
        self.module = module
        self.locals = local_vars
        self.state = state
        self.rule = rule
        self.call_depth = call_depth

    def with_state(self, state: ShapeState) -> Env:
        return Env(self.derivation, self.module, self.locals, state, self.rule, self.call_depth)

    def random_float(self) -> float:
        return self.state.random_float()

    def discrete_rand(self, node):
        if self.derivation._chance_log is None:  # nobody records choices: the general path
            return NotImplemented
        inner = node.args[0]
        if self.module.function(node.name, 1) is not None or \
                self.module.function("rand", len(inner.args)) is not None or len(inner.args) > 2:
            return NotImplemented
        bounds = rand_bounds([self.evaluate(a) for a in inner.args])
        got = FUNCTIONS[node.name][0](self, [rand_value(self.random_float(), bounds)])
        self.note_choice(node.name, bounds, got)
        return got

    def note_choice(self, kind: str, params, outcome) -> None:
        log = self.derivation._chance_log
        if log is not None:  # recorded for instancing by chance
            log.append((self.state.path, self.state.draws, kind, params, outcome))

    # -- names -------------------------------------------------------------------------------
    def lookup(self, name: str, node):
        if name in self.locals:
            return self.locals[name]
        getter = _SHAPE_VALUES.get(name)
        if getter is not None:
            return getter(self)
        found = self.module.attr(name)
        if found is not None:
            return self.derivation.attr_value(found[0], found[1], self.state)
        if self.module.function(name, 0) is not None:  # CGA calls 0-ary functions without ()
            return self.call(name, [], node)
        if bare_call(name):  # so are built-ins: ~(rand) in Esri's rules
            return self.call(name, [], node)
        if name in _SHAPE_FUNCTIONS:  # geometry.uMin and friends read like attributes
            return _SHAPE_FUNCTIONS[name](self, [])
        if name.startswith("material."):
            return _material_value(self.state, name)
        raise CGARuntimeError(f"unknown attribute or variable '{name}'")

    def comp_function(self, node: A.CompFunction):
        """``comp(f|e|v){ selector : value | … }``: one value per component, in component order;
        components no selector takes get the type's default (0, "", false)."""
        from .ops.subdivision import component_count, op_comp
        from .values import make_array

        kind = node.kind.name if isinstance(node.kind, A.Name) else to_str(self.evaluate(node.kind))
        state = self.state.copy()
        call = OpCall("comp", [kind], state, self.derivation, self, node.branches, False)
        pieces = op_comp(call) or []
        n = component_count(state, kind)
        values: list = [None] * n
        for piece_state, expr, info in pieces:
            v = self.with_state(piece_state).evaluate(expr)
            for c in info.get("components") or [info.get("component")]:
                if c is not None and 0 <= c < n:
                    values[c] = v
        sample = next((v for v in values if v is not None), 0.0)
        default = "" if isinstance(sample, str) else (False if isinstance(sample, bool) else 0.0)
        return make_array([default if v is None else v for v in values]) if values else make_array([])

    def call(self, name: str, args: list, node):
        found = self.module.function(name, len(args))
        if found is not None:
            mod, fdef = found
            if self.call_depth >= MAX_CALL_DEPTH:
                raise CGARuntimeError(f"function '{name}' recurses deeper than {MAX_CALL_DEPTH} calls")
            self.derivation.budget.check("function", name, mod.path, fdef.line)
            env = Env(self.derivation, mod, {p.name: v for p, v in zip(fdef.params, args)},
                      self.state, self.rule, self.call_depth + 1)
            return env.evaluate(fdef.body)
        if not args:
            found_attr = self.module.attr(name)  # ``const c = …`` called as ``c()``
            if found_attr is not None:
                return self.derivation.attr_value(found_attr[0], found_attr[1], self.state)
        shape_fn = _SHAPE_FUNCTIONS.get(name)
        if shape_fn is not None:
            return shape_fn(self, args)
        entry = FUNCTIONS.get(name)
        if entry is not None:
            fn, lo, hi = entry
            if not lo <= len(args) <= hi:
                raise CGARuntimeError(f"{name}() takes {lo if lo == hi else f'{lo} to {hi}'} "
                                      f"arguments, got {len(args)}")
            return fn(self, args)
        raise CGARuntimeError(f"unknown function '{name}' with {len(args)} arguments")


def _material_value(state: ShapeState, name: str):
    key = name[len("material."):]
    m = state.material
    if key == "color.r":
        return m.get("color", (1, 1, 1))[0]
    if key == "color.g":
        return m.get("color", (1, 1, 1))[1]
    if key == "color.b":
        return m.get("color", (1, 1, 1))[2]
    if key == "color.rgb":
        c = m.get("color", (1, 1, 1))
        return "#" + "".join(f"{int(round(max(0, min(1, x)) * 255)):02x}" for x in c)
    if key == "opacity":
        return m.get("opacity", 1.0)
    if key == "name":
        return m.get("name", "")
    v = m.get(key)
    if v is None:
        return "" if key.endswith("map") or key == "name" else 0.0
    return v


def _scope_in_pivot(env) -> tuple[np.ndarray, np.ndarray]:
    """The scope's translation (3,) and rotation angles (3,) relative to the shape's pivot, as
    CityEngine's ``scope.t`` and ``scope.r`` are (reference, "scope attribute")."""
    origin, rotation = pivot_frame(env.state, env.derivation)
    sc = env.state.scope
    t = (sc.origin - origin) @ rotation
    r = euler_xyz_deg(rotation.T @ sc.rotation)
    return t, r


_SHAPE_VALUES = {
    "scope.sx": lambda e: float(e.state.scope.size[0]),
    "scope.sy": lambda e: float(e.state.scope.size[1]),
    "scope.sz": lambda e: float(e.state.scope.size[2]),
    "scope.tx": lambda e: float(_scope_in_pivot(e)[0][0]),
    "scope.ty": lambda e: float(_scope_in_pivot(e)[0][1]),
    "scope.tz": lambda e: float(_scope_in_pivot(e)[0][2]),
    "scope.rx": lambda e: float(_scope_in_pivot(e)[1][0]) + 0.0,
    "scope.ry": lambda e: float(_scope_in_pivot(e)[1][1]) + 0.0,
    "scope.rz": lambda e: float(_scope_in_pivot(e)[1][2]) + 0.0,
    # above sea level: the world y of the scope's origin (reference, "scope attribute")
    "scope.elevation": lambda e: float(e.state.scope.origin[1]),
    "split.index": lambda e: float(e.state.context.get("split.index", 0)),
    "split.total": lambda e: float(e.state.context.get("split.total", 0)),
    "comp.index": lambda e: float(e.state.context.get("comp.index", 0)),
    "comp.total": lambda e: float(e.state.context.get("comp.total", 0)),
    "comp.sel": lambda e: str(e.state.context.get("comp.sel", "")),
    "initialShape.origin.px": lambda e: float(e.derivation.initial_origin[0]),
    "initialShape.origin.py": lambda e: float(e.derivation.initial_origin[1]),
    "initialShape.origin.pz": lambda e: float(e.derivation.initial_origin[2]),
    "initialShape.origin.ox": lambda e: 0.0,
    "initialShape.origin.oy": lambda e: 0.0,
    "initialShape.origin.oz": lambda e: 0.0,
    "initialShape.name": lambda e: e.derivation.name,
    "initialShape.startRule": lambda e: e.derivation.ruleset.start_rule,
    "seedian": lambda e: float(e.derivation.seed),
    "pi": lambda e: math.pi,
    "PI": lambda e: math.pi,
    "pivot.px": lambda e: pivot_value(e, "px"), "pivot.py": lambda e: pivot_value(e, "py"),
    "pivot.pz": lambda e: pivot_value(e, "pz"), "pivot.ox": lambda e: pivot_value(e, "ox"),
    "pivot.oy": lambda e: pivot_value(e, "oy"), "pivot.oz": lambda e: pivot_value(e, "oz"),
}

class Derivation:
    """One derivation of a rule set on one initial shape.

    Parameters
    ----------
    ruleset : RuleSet
    state : ShapeState
        The initial shape (lot or facade) with its scope and geometry.
    name : str
        Initial shape name (``initialShape.name``; object id in exports).
    attrs : dict
        ``--attr`` overrides: ``{"height": 20, "facade.floorHeight": 3.5}``.
    seed : int
    strict : bool
        Turn CGA warnings into ``DerivationError``.
    assets : AssetResolver or None
    instancing : bool
        Derive repeated pure subtrees once (``instancing.py``); the shape tree then holds only
        their first instance, so use it when the tree is not needed.
    """

    def __init__(self, ruleset: RuleSet, state: ShapeState, name: str = "building",
                 attrs: dict | None = None, seed: int = 0, strict: bool = False, assets=None,
                 limits: Limits | None = None, start_rule: str | None = None,
                 instancing: bool = False, neighbours=None):
        self.ruleset = ruleset
        self.initial = state
        self.name = name
        self.overrides = dict(attrs or {})
        self.seed = int(seed)
        self.root_seed = self.seed * 0x9E3779B1 + 0x7F4A7C15  # the initial shape's stream
        self.strict = strict
        self.assets = assets
        self.limits = limits or Limits()
        self.start_rule = start_rule or ruleset.start_rule
        self.initial_origin = state.scope.origin.copy()
        self.object_scope = state.scope.copy()
        self.warnings: list[str] = []
        self.reports: dict[str, list] = {}
        self.prints: list[str] = []
        self.parts: list[Part] = []
        self._attr_cache: dict = {}
        self._materials: dict = {}
        self._column_groups: dict = {}
        self._attr_busy: set = set()
        self.shape_count = 0
        self._ids = 0
        self.budget = Budget(self.limits.max_seconds, self.limits.max_memory_mb)
        from .ops.occlusion import OccluderSet

        self.occluders = OccluderSet()  # closed volumes left for occlusion queries
        # occluders of the other buildings around this one (``inter`` occlusion queries;
        # engine.derive finds them in a first pass over all initial shapes)
        self.neighbours = OccluderSet(neighbours or ())
        self._instances: dict = {}
        self._payoff: dict = {}  # id(RuleInfo) -> instancing.Payoff
        self._special: dict = {}  # id(Purity) -> its analyses for argument values
        self.sink: list | None = None  # collects leaf shapes while an ``inline`` derives
        self.inline_depth = 0
        self._purity = None
        purity = getattr(ruleset, "_purity", None)
        if purity is None:
            purity = ruleset._purity = Purity(ruleset)
        # occluders (closed volumes split into parts, closed leaf shapes) are worth keeping only
        # when some rule asks an occlusion query
        self.keeps_occluders = purity.uses_occlusion
        # rules pure but for their stochastic choices, instanced by the choices' outcomes
        self._chance = None
        self._chance_log: list | None = None  # the choices of the subtree being recorded
        self._chance_instances: dict = {}  # key -> [(choices, Recording)]
        # key -> (what its variants' choices draw, {their outcomes: variant}) while all of
        # them draw alike (the usual case: one texture choice), None once they do not
        self._chance_index: dict = {}
        self._chance_closed: set = set()  # keys derived directly from now on
        # seeds of shapes on the way to a slot that could not be filled (:meth:`_resolve`)
        self._unfilled: set = set()
        # per key instanced by chance, the state its first recording was derived from: a slot
        # whose stream makes a choice no recording has yet is derived again from it, with the
        # slot's seed, in its own frame (:meth:`_fill`)
        self._prototypes: dict = {}
        # the recording by chance under way: its slots, its root's frame, UV maps and seed,
        # and the shapes of its slots (:meth:`_slot`)
        self._slots: list | None = None
        self._slot_root = None
        self._slot_shapes = 0
        if instancing and not purity.uses_occlusion:
            self._purity = self._folded_purity(chance=False)
            self._chance = self._folded_purity(chance=True)

    def _folded_purity(self, chance: bool) -> Purity:
        """The purity analysis of the rule set for this derivation's attribute values: a case
        whose conditions read only attributes that no rule sets is decided before the
        derivation starts, and only its branch taken counts (``case Mode == "3DPrint" : …``
        in Esri's rules).  Kept on the rule set with the attribute values it was worked out
        for, and reused by derivations whose values are the same."""
        ruleset = self.ruleset
        cache = ruleset.__dict__.setdefault("_folded_purities", [])
        for c, deps, purity in cache:
            if c == chance and all(_hashable(self.attr_value(m, a, self.initial)) == v
                                   for m, a, v in deps):
                return purity
        changed = ruleset.__dict__.get("_set_targets")
        if changed is None:
            changed = ruleset._set_targets = set_targets(ruleset)
        deps: dict = {}

        def fold(module, cond, params):
            attrs = constant_attributes(module, cond, changed, params)
            if attrs is None:
                return None
            try:
                value = to_bool(Env(self, module, {}, self.initial.copy()).evaluate(cond))
                for m, a in attrs:
                    deps[(id(m), a.name)] = (m, a, _hashable(self.attr_value(m, a, self.initial)))
            except (CGARuntimeError, DerivationError, ArithmeticError, TypeError, ValueError):
                return None
            return value

        purity = Purity(ruleset, chance=chance, fold=fold)
        if len(cache) < 16:
            cache.append((chance, list(deps.values()), purity))
        return purity

    def _specialised(self, purity: Purity, mod: Module, rdef, args, state: ShapeState, info):
        """``purity``'s analysis of ``rdef`` called with ``args`` on ``state``
        (:meth:`Purity.specialised`), worked out once per derivation: conditions and arguments
        may read attributes that no rule of the subtree sets (``info.sets``, the rule's
        general analysis), with their values on this shape."""
        sets = info.sets
        known = {k: v for k, v in state.attrs.items() if k[1] not in sets}
        context = tuple(sorted((k, _hashable(v)) for k, v in known.items()))
        memo = self._special.setdefault(id(purity), {})
        at: list = []  # the shape the values are read on, made when first needed (a memo hit
        # needs none)

        def constant(module: Module, expr, bound: dict):
            if constant_attributes(module, expr, sets, set(bound), bound) is None:
                return UNKNOWN
            if not at:
                at.append(self.initial.copy())
                at[0].attrs = known
            try:
                return Env(self, module, dict(bound), at[0]).evaluate(expr)
            except (CGARuntimeError, DerivationError, ArithmeticError, TypeError, ValueError):
                return UNKNOWN
        return purity.specialised(mod, rdef, args, constant, memo, context)

    # -- attributes --------------------------------------------------------------------------
    def attr_value(self, module: Module, adef: A.AttrDef, state: ShapeState):
        key = (id(module), adef.name)
        if key in state.attrs:
            return state.attrs[key]
        if key in self._attr_cache:
            return self._attr_cache[key]
        qualified = f"{module.name}.{adef.name}" if module.name else adef.name
        if not adef.const and qualified in self.overrides:
            value = _coerce_override(self.overrides[qualified], adef)
        elif not adef.const and adef.name in module.import_overrides:
            importer, expr = module.import_overrides[adef.name]
            value = Env(self, importer, {}, self._attr_state(qualified)).evaluate(expr)
        elif not adef.const and (source := module.propagated_from(adef.name)) is not None:
            # the importer's value, which a set() on this shape may have changed: not cached
            return self.attr_value(*source, state)
        else:
            if key in self._attr_busy:
                raise CGARuntimeError(f"attribute '{adef.name}' depends on itself")
            self._attr_busy.add(key)
            try:
                value = Env(self, module, {}, self._attr_state(qualified)).evaluate(adef.value)
            finally:
                self._attr_busy.discard(key)
        self._attr_cache[key] = value
        return value

    def _attr_state(self, qualified: str) -> ShapeState:
        """The initial shape as an attribute's value sees it, with a random stream of its own
        that follows from the derivation's seed (``attr h = rand(20, 60)``: another height for
        another seed, and another than ``attr w = rand(20, 60)``'s)."""
        state = self.initial.copy()
        state.seed = child_seed(self.root_seed, zlib.crc32(qualified.encode()))
        return state

    # -- warnings ----------------------------------------------------------------------------
    def warn(self, message: str, node=None, rule: str | None = None) -> None:
        where = ""
        if node is not None and getattr(node, "line", 0):
            path = self.current_path or self.ruleset.main.path
            where = f"{path}:{node.line}:{node.column}: "
        text = where + message + (f" (in rule {rule})" if rule else "")
        if self.strict:
            raise DerivationError(text + "; derivation stopped because of --strict")
        if len(self.warnings) < self.limits.max_warnings:
            if text not in self.warnings:
                self.warnings.append(text)

    current_path = ""

    def located(self, error: DerivationError, node, rule: str) -> DerivationError:
        """``error`` with the file position of ``node`` in front, once (the innermost
        operation that raised it is where the rule went wrong)."""
        if getattr(error, "located", False) or not getattr(node, "line", 0):
            return error
        path = self.current_path or self.ruleset.main.path
        out = DerivationError(f"{path}:{node.line}:{node.column}: {error} (in rule {rule})")
        out.located = True
        return out

    # -- main loop ---------------------------------------------------------------------------
    def run(self) -> Model:
        try:
            with deriving():
                return self._run()
        except RecursionError:
            raise DerivationError(
                f"expressions or rule calls nest too deeply in '{self.name}' (more than Python "
                "can follow); a function probably calls itself without end") from None
        except MemoryError:
            raise DerivationError(
                f"the derivation of '{self.name}' ran out of memory; a rule that makes ever "
                "larger values or shapes?") from None

    def _run(self) -> Model:
        self.budget.start()
        root = Shape(self.start_rule, self.initial.scope, operator="initial", id=self.new_id())
        state = self.initial.copy()
        state.seed = self.root_seed
        state.label = ""
        queue: deque = deque([(root, state, self.start_rule, (), self.ruleset.main, 0)])
        while queue:
            node, st, name, args, module, depth = queue.popleft()
            self._apply(queue, node, st, name, args, module, depth)
        model = Model(self.parts, root, self.reports, self.warnings, self.name)
        model.attributes = {"startRule": self.start_rule, "seed": self.seed}
        return model

    def _apply(self, queue, node, state, name, args, module, depth):
        found = module.rule(name, len(args))
        if found is None:
            if module.has_rule_name(name):
                self.warn(f"rule '{name}' has no overload with {len(args)} parameters; shape left as is")
            elif "." in name:
                self.warn(_undefined_qualified(module, name))
            self._output(node, state, name)
            return
        mod, rdef = found
        if depth >= self.limits.max_depth:
            raise DerivationError(
                f"derivation deeper than {self.limits.max_depth} levels in rule '{name}' "
                f"({mod.path}:{rdef.line}); a rule probably calls itself without shrinking its shape")
        self.budget.check("rule", name, mod.path, rdef.line)
        hint = label_for_name(name.split(".")[-1])
        if hint is not None:
            state.label = hint.value
        if self._purity is not None:
            info = self._purity.rule(module, name)  # as called: an override counts
            if args and info is not None and not _usable(info, state, False):
                info = self._specialised(self._purity, mod, rdef, args, state, info) or info
            if info is not None and info.pure:
                payoff = self._payoff.get(id(info))
                if payoff is None:
                    payoff = self._payoff[id(info)] = Payoff()
                if not payoff.off:
                    key, uv_map = instance_key(mod, (rdef.name, id(rdef)), args, state, info)
                    if key is not None:
                        self._instanced(key, uv_map, node, state, name, args, module, depth,
                                        payoff)
                        return
            elif self._chance is not None:
                info = self._chance.rule(module, name)
                if args and info is not None and not _usable(info, state, True):
                    info = self._specialised(self._chance, mod, rdef, args, state, info) or info
                if info is not None and info.pure and info.chance:
                    payoff = self._payoff.get(id(info))
                    if payoff is None:
                        # its first tries record a variant per outcome: judged later
                        payoff = self._payoff[id(info)] = Payoff(CHANCE_TRIES)
                    if not payoff.off and state.seed not in self._unfilled:
                        key, uv_map = instance_key(mod, (rdef.name, id(rdef)), args, state, info)
                        if key is not None and self._by_chance(key, uv_map, node, state, name,
                                                                args, module, depth, payoff):
                            return
        self._run_rule(queue, node, state, name, args, mod, rdef, depth)

    def _run_rule(self, queue, node, state, name, args, mod, rdef, depth):
        local_vars = {}
        for p, v in zip(rdef.params, args):
            local_vars[p.name] = v
        env = Env(self, mod, local_vars, state, name)
        self.current_path = mod.path
        ctx = _RunContext(self, queue, node, depth, name)
        consumed = ctx.run(rdef.body, state, env, None)
        if not consumed:
            self._output(node, state, name)
        elif ctx.deleted and not node.children:
            # NIL removes the shape from the tree (CityEngine): nothing of it may be painted
            parent = node.parent
            if parent is not None:
                parent.children.remove(node)

    # -- instancing (see instancing.py) -------------------------------------------------------
    def _instanced(self, key, uv_map, node, state, name, args, module, depth, payoff) -> None:
        rec = self._instances.get(key)
        scope0 = state.scope  # the recording moves it: replays go where the shape was
        fresh = rec is None
        if fresh:
            rec = self._instances[key] = self._record(uv_map, node, state, name, args, module,
                                                      depth, slotted=False)
        payoff.note(not fresh, rec.shapes)
        self._replay_one(rec, scope0.rotation, scope0.origin, uv_map, node)
        if not fresh:
            self._count(node, rec.shapes)

    def _record(self, uv_map, node, state, name, args, module, depth, slotted) -> Recording:
        """Derive a subtree now, depth first, and keep what it made relative to its scope.
        ``slotted`` (a recording by chance): subtrees instanced by chance below it become
        slots that each replay chooses for itself (:meth:`_slot`)."""
        scope0 = state.scope
        saved = (self.parts, self.reports, self.prints, self._purity, self._slots,
                 self._slot_root, self._slot_shapes)
        count0 = self.shape_count
        self.parts, self.reports, self.prints = [], {}, []
        self._slots = [] if slotted else None
        self._slot_root = (scope0.rotation, scope0.origin, uv_map, state.seed)
        self._slot_shapes = 0
        try:
            sub: deque = deque()
            mod, rdef = module.rule(name, len(args))
            self._run_rule(sub, node, state, name, args, mod, rdef, depth)
            while sub:
                item = sub.popleft()
                self._apply(sub, *item)
            rot, org = scope0.rotation, scope0.origin
            # parts alike in label, material and symbol become one mesh: replays (and exports)
            # then handle a few meshes instead of one per leaf shape
            groups: dict = {}
            for p in self.parts:
                groups.setdefault((p.label, p.material.key(), p.symbol), []).append(p)
            parts = []
            for (label, _, symbol), ps in groups.items():
                merged = Mesh.merge(p.mesh for p in ps)
                parts.append((merged.with_vertices((merged.vertices - org) @ rot), label,
                              ps[0].material, symbol))
            return Recording(parts, [(k, list(v)) for k, v in self.reports.items()], self.prints,
                             self.shape_count - count0 - self._slot_shapes, uv_map,
                             tuple(self._slots or ()))
        finally:
            (self.parts, self.reports, self.prints, self._purity, self._slots,
             self._slot_root, self._slot_shapes) = saved

    def _by_chance(self, key, uv_map, node, state, name, args, module, depth, payoff) -> bool:
        """Instancing of a subtree that is pure but for its stochastic choices: a recording is
        kept with the outcome of every choice it made (where in the subtree, which draw of that
        shape's random stream, the percentages, the branch taken).  Another shape of the same
        key replays it when its own random streams, which follow from its seed along the same
        successor indices, give every choice the same outcome; else it is derived (and
        recorded, up to :data:`CHANCE_VARIANTS` recordings a key).  A subtree instanced by
        chance below it is not part of the recording's choices but a slot, which every replay
        fills with the recording of that key whose choices its own streams repeat (a tile of
        windows, each with its own texture, is one recording).  Returns False when the shape
        is left to the caller to derive directly."""
        variants = self._chance_instances.setdefault(key, [])
        if key in self._chance_closed:  # its choices have more outcomes than recordings kept
            payoff.note(False, 0)
            return False
        scope0 = state.scope
        got = self._variant(key, state.seed) if variants else None
        if got is not None:
            choices, rec = got
            plan = self._resolve(rec, state.seed, scope0.rotation, scope0.origin, uv_map,
                                 choices, key)
            if plan is None:  # a slot's streams make a choice no recording can be made for:
                return False  # derived, the slot's subtree records it (no try counted)
            payoff.note(True, sum(e.rec.shapes for e in plan))
            self._place(plan, node, state, payoff, count=True)
            return True
        if len(variants) >= CHANCE_VARIANTS:
            payoff.note(False, 0)
            return False
        if key not in self._prototypes:
            self._prototypes[key] = (state.copy(), uv_map, name, args, module, depth, payoff)
        choices, rec, stored = self._record_by_chance(key, uv_map, node, state, name, args,
                                                      module, depth, payoff)
        # its slots were filled just now, by recordings kept under their keys
        plan = self._resolve(rec, state.seed, scope0.rotation, scope0.origin, uv_map, choices,
                             key if stored else None)
        self._place(plan, node, state, payoff, count=False)
        return True

    def _record_by_chance(self, key, uv_map, node, state, name, args, module, depth, payoff):
        """Record a subtree by chance with the choices it makes (paths from its root), kept
        among the key's variants when every choice has a path; ``(choices, rec, stored)``."""
        outer_log, outer_path = self._chance_log, state.path
        self._chance_log, state.path = [], ()
        try:
            rec = self._record(uv_map, node, state, name, args, module, depth, slotted=True)
            choices = tuple(self._chance_log)
        finally:
            self._chance_log, state.path = outer_log, outer_path
        if combinations(choices) > CHANCE_VARIANTS:
            # a subtree of several choices of its own (not in slots): its recordings would
            # rarely repeat, while the subtrees of each choice do; shapes of this key are
            # derived directly from now on, their parts instanced
            self._chance_closed.add(key)
        stored = all(path is not None for path, *_ in choices)
        if stored:
            self._chance_instances[key].append((choices, rec))
            drawn, outcomes = tuple(c[:4] for c in choices), tuple(c[4] for c in choices)
            index = self._chance_index.get(key, ())
            if index == ():
                self._chance_index[key] = (drawn, {outcomes: (choices, rec)})
            elif index is not None:
                if index[0] == drawn:
                    index[1].setdefault(outcomes, (choices, rec))
                else:
                    self._chance_index[key] = None
        payoff.note(False, rec.shapes)
        return choices, rec, stored

    def _variant(self, key, seed: int):
        """The first recording of ``key`` whose choices the streams below ``seed`` repeat,
        as ``(choices, rec)``, or ``None``: by the outcomes of the choices when every variant
        of the key draws alike, else variant by variant."""
        index = self._chance_index.get(key)
        if index:
            drawn, table = index
            outcomes = []
            for path, draw, kind, params in drawn:
                s = seed
                for i in path:
                    s = child_seed(s, i)
                outcomes.append(outcome(kind, random_value(s, draw), params))
            return table.get(tuple(outcomes))
        memo: dict = {}
        return next(((c, v) for c, v in self._chance_instances.get(key, ())
                     if _choices_hold(seed, c, memo)), None)

    def _fill(self, key, seed: int):
        """A recording for a slot of ``key`` whose stream (``seed``) makes a choice that no
        recording of the key has: the key's first shape derived again with that seed, in its
        own frame (shapes of one key make the same subtree relative to their frames, but for
        their choices), kept as a new variant.  ``(choices, rec)``, or ``None`` where the key
        keeps no more variants.  The shapes it derives are left to the replay to count."""
        proto = self._prototypes.get(key)
        variants = self._chance_instances.get(key)
        if proto is None or key in self._chance_closed or len(variants) >= CHANCE_VARIANTS:
            return None
        st0, uv_map, name, args, module, depth, payoff = proto
        state = st0.copy()
        state.seed = seed
        node = Shape(name, state.scope, id=self.new_id())
        count0, path0 = self.shape_count, self.current_path
        try:
            choices, rec, stored = self._record_by_chance(key, uv_map, node, state, name, args,
                                                          module, depth, payoff)
        finally:
            self.shape_count, self.current_path = count0, path0
        return (choices, rec) if stored else None

    def _resolve(self, rec, seed: int, rot, org, uv_map, choices, key=None):
        """The recordings a replay of ``rec`` at this frame and random stream puts down: ``rec``
        and, for every slot, the recording of the slot's key whose choices the slot's own
        stream repeats, at the slot's frame, down the slots of slots (:class:`_Placed`, each
        after the one whose slot it fills); ``None`` when a slot's stream makes a choice that
        no recording of its key has."""
        plan = [_Placed(rec, seed, choices, (), -1, key)]  # first which recordings, then where
        k = 0
        while k < len(plan):
            r, path = plan[k].rec, plan[k].path
            if not r.slots:
                k += 1
                continue
            steps, of_slot = r.seed_program()
            seeds = [plan[k].seed]
            for src, i in steps:
                seeds.append(child_seed(seeds[src], i))
            for j, (spath, skey, *_) in enumerate(r.slots):
                s = seeds[of_slot[j]]
                got = self._variant(skey, s) if skey in self._chance_instances else None
                if got is None:
                    got = self._fill(skey, s)
                if got is None:
                    # the shapes between the root and this slot would find the same gap: they
                    # are derived without trying (:meth:`_by_chance`)
                    s = seed
                    for i in (*path, *spath)[:-1]:
                        s = child_seed(s, i)
                        self._unfilled.add(s)
                    return None
                plan.append(_Placed(got[1], s, got[0], (*path, *spath), k, skey, j))
            k += 1
        for e in plan:
            if e.parent < 0:
                e.rot, e.org, e.maps = rot, org, uv_map
                continue
            up = plan[e.parent]
            _, _, a, b, follows = up.rec.slots[e.slot]
            maps = []
            for j in follows:
                if j is not None and up.maps[j] is None:
                    return None
                maps.append(None if j is None else moved_uv_map(up.maps[j], a, b))
            e.rot, e.org, e.maps = up.rot @ a.T, b @ up.rot.T + up.org, tuple(maps)
        return plan

    def _place(self, plan, node, state: ShapeState, payoff, count: bool) -> None:
        """Put a resolved replay down.  Within a recording by chance, a recording of the plan
        that makes choices (and can be filled again: it has a key) becomes a slot of it, with
        what fills its own slots; the others' parts become its parts (their choices, if any,
        its choices).  ``state``: the shape's, whose path leads from the recording's root."""
        slotted = self._slots is not None and state.path is not None
        if slotted:  # the streams below follow the root's along its path (:meth:`_slot`)
            s = self._slot_root[3]
            for i in state.path:
                s = child_seed(s, i)
            slotted = s == plan[0].seed
        covered = [False] * len(plan)
        total = slot_shapes = 0
        for k, e in enumerate(plan):
            total += e.rec.shapes
            if e.parent >= 0 and covered[e.parent]:
                covered[k] = True
                slot_shapes += e.rec.shapes
                continue
            if slotted and e.choices and e.key is not None:
                slot = self._slot(e, state.path)
                if slot is not None:
                    self._slots.append(slot)
                    payoff.slotted = True
                    covered[k] = True
                    slot_shapes += e.rec.shapes
                    continue
            self._note_choices(state, e.choices, e.path)
            self._replay_one(e.rec, e.rot, e.org, e.maps, node)
        self._slot_shapes += slot_shapes
        if count:
            self._count(node, total)

    def _slot(self, e: _Placed, prefix: tuple):
        """The slot a placed recording becomes in the recording by chance under way: where it
        lies in the root's frame, its random stream's path from the root's (``prefix``, the
        placed replay's own path, then the recording's within it: :meth:`_place` has checked
        that the replay's stream follows the root's), and which of the root's UV maps each of
        its own follows.  ``None`` where its UV maps do not follow from the root's."""
        rot0, org0, maps0, _ = self._slot_root
        path = (*prefix, *e.path)
        a = e.rot.T @ rot0
        b = (e.org - org0) @ rot0
        follows = []
        for i, m in enumerate(e.maps):
            if m is None:
                follows.append(None)
                continue
            j = next((j for j in (i, 1 - i) if maps0[j] is not None and np.abs(
                moved_uv_map(maps0[j], a, b) - m).max() <= 1e-9 * max(1.0, np.abs(m).max())),
                None)
            if j is None:
                return None
            follows.append(j)
        return (path, e.key, a, b, tuple(follows))

    def _note_choices(self, state: ShapeState, choices, below=()) -> None:
        """Within a subtree being recorded by chance, the choices of a nested one count too,
        found from the outer root along the nested root's successor indices (and ``below``
        them, for a slot of the nested one)."""
        if self._chance_log is not None and choices:
            prefix = state.path
            self._chance_log.extend(
                (None if prefix is None or path is None else (*prefix, *below, *path), *rest)
                for path, *rest in choices)

    def _count(self, node, shapes: int) -> None:
        self.shape_count += shapes
        if self.shape_count > self.limits.max_shapes:
            self.count_shape(node.symbol)

    def _replay_one(self, rec, rot, org, uv_map, node) -> None:
        # UVs that follow from where the shape is — inherited from its ancestors, or made by a
        # projectUV below from an inherited projection — are affine in the scope frame: the
        # corners that carry the recording's map get this shape's
        moved = [i for i, (a, b) in enumerate(zip(rec.uv_map, uv_map))
                 if a is not None and b is not None and not np.array_equal(a, b)]
        for j, (local, label, material, symbol) in enumerate(rec.parts):
            mesh = local.with_vertices(local.vertices @ rot.T + org)
            if moved and local.corner_uvs is not None:
                pts, hits = rec.uv_corners(j)
                uv = None
                for i in moved:
                    hit = hits[i]
                    if hit is not None:
                        uv = local.corner_uvs.copy() if uv is None else uv
                        uv[hit] = pts[hit] @ uv_map[i]
                if uv is not None:
                    mesh = mesh.with_uvs(uv)
            self.parts.append(Part(mesh, label, material, symbol, node.id))
        for k, values in rec.reports:
            self.reports.setdefault(k, []).extend(values)
        self.prints.extend(rec.prints)

    def _output(self, node: Shape, state: ShapeState, symbol: str) -> None:
        if self.sink is not None:  # an ``inline`` collects its leaf shapes
            self.sink.append((state, symbol))
            return
        node.scope = state.scope
        node.geometry = state.geometry
        node.tags.update(state.tags)
        label = state.label
        leaf_hint = label_for_name(symbol.split(".")[-1])
        if leaf_hint is not None:
            label = leaf_hint.value
        if "label" in state.context:
            label = state.context["label"]
        node.label = label
        if state.geometry.n_faces == 0:
            return
        node.material = self.material(state)
        self.add_occluder(state)
        own = state.geometry.column("material")
        if own is not None:  # faces with their own material: one part per material
            for am, faces in self._material_groups(own):
                mat = node.material if am is None else self.material(state, am)
                self.parts.append(Part(state.geometry.subset(faces), label, mat, symbol, node.id))
            return
        self.parts.append(Part(state.geometry, label, node.material, symbol, node.id))

    def _material_groups(self, column: np.ndarray) -> list:
        """``[(material, face indices)]`` of a face column, in order of first use; an inserted
        asset's column is shared by its copies, so it is grouped once."""
        hit = self._column_groups.get(id(column))
        if hit is not None and hit[0] is column:
            return hit[1]
        groups: dict = {}
        for f, am in enumerate(column):
            groups.setdefault(id(am), (am, []))[1].append(f)
        out = [(am, np.array(faces)) for am, faces in groups.values()]
        if len(self._column_groups) > 4096:
            self._column_groups.clear()
        self._column_groups[id(column)] = (column, out)  # the column kept: its id stays its own
        return out

    def material(self, state: ShapeState, asset_material=None) -> Material:
        """Exported material: the shape's material attributes over an asset's own material."""
        try:
            key = (tuple(sorted(state.material.items())), id(asset_material))
            hit = self._materials.get(key)
        except TypeError:  # an unhashable material value (an array): no caching
            key, hit = None, None
        if hit is not None:
            return hit
        mat = self._make_material(state, asset_material)
        if key is not None:
            self._materials[key] = mat
        return mat

    def _make_material(self, state: ShapeState, asset_material) -> Material:
        m = state.material
        if asset_material is not None:
            base = {"color": tuple(asset_material.color), "opacity": asset_material.opacity,
                    "name": asset_material.name}
            if asset_material.texture:
                base["colormap"] = asset_material.texture
            m = {**base, **m}
        tex = m.get("colormap") or None
        path = None
        if tex and asset_material is not None and tex == asset_material.texture:
            path = tex  # already resolved (and confined) when the asset was read
        elif tex and self.assets is not None:
            path = self.assets.texture(tex, self)
        color = tuple(float(c) for c in m.get("color", (1.0, 1.0, 1.0)))
        name = m.get("name") or (f"tex_{tex}" if tex else "color_" + "".join(
            f"{int(round(max(0, min(1, c)) * 255)):02x}" for c in color))
        return Material(name=str(name), color=color, opacity=float(m.get("opacity", 1.0)),
                        texture=path, metallic=float(m.get("metallic", 0.0)),
                        roughness=float(m.get("roughness", 0.9)))

    def add_occluder(self, state: ShapeState):
        """Register a closed volume about to be split into components as an occluder; return
        the occluder ids its descendants must ignore (their own ancestors)."""
        if not self.keeps_occluders:
            return None
        g = state.geometry
        ancestors = state.context.get("occluder_ancestors", ())
        if g.n_faces < 4 or not g.is_closed():
            return None
        from .ops.occlusion import Occluder

        occ = Occluder(len(self.occluders), g, state.context.get("label", ""))
        self.occluders.append(occ)
        return (*ancestors, occ.id)

    def new_id(self) -> int:
        """The next shape id of this derivation: numbered per building, so that a city's
        output is the same whichever worker derived which building."""
        self._ids += 1
        return self._ids

    def count_shape(self, rule: str) -> None:
        self.shape_count += 1
        self.budget.check("rule", rule)
        if self.shape_count > self.limits.max_shapes:
            raise DerivationError(f"more than {self.limits.max_shapes} shapes (last rule '{rule}'); "
                                  "a repeat split on a huge scope or a runaway recursion?")


#: Recordings kept per key of a subtree instanced by the outcomes of its stochastic choices.
CHANCE_VARIANTS = 16
#: Tries after which instancing by chance is judged for a rule (see ``instancing.Payoff``).
CHANCE_TRIES = 64


class _Placed:
    """One recording of a replay by chance (``Derivation._resolve``): the recording, the seed
    of the shape it stands for, the outcomes its choices had, its successor indices from the
    replay's root, the index of the one whose slot it fills (``-1``: the root) and which slot,
    its key (``None``: kept under none), and where it goes (rotation, origin, UV maps)."""

    __slots__ = ("rec", "seed", "choices", "path", "parent", "key", "slot", "rot", "org",
                 "maps")

    def __init__(self, rec, seed, choices, path, parent, key, slot=-1):
        self.rec, self.seed, self.choices, self.path = rec, seed, choices, path
        self.parent, self.key, self.slot = parent, key, slot
        self.rot = self.org = self.maps = None


def _usable(info, state: ShapeState, chance: bool) -> bool:
    """Whether a rule's analysis lets this shape be instanced (plainly, or by chance)."""
    if not info.pure or (chance and not info.chance):
        return False
    g = state.geometry
    return not (info.uses_uv and g.corner_uvs is not None and g.n_faces)


def _choices_hold(seed: int, choices, memo: dict | None = None) -> bool:
    """Whether the random streams below a shape of ``seed`` give every recorded choice
    ``(successor indices, draw, kind, parameters, outcome)`` the same outcome: the streams by
    ``child_seed`` and ``random_value``, the outcome by :func:`chance.outcome`, as when the
    shapes derive.  ``memo`` keeps the outcomes worked out for this seed, for checking the
    next recording of the same key."""
    for path, draw, kind, params, recorded in choices:
        key = (path, draw, kind, params)
        got = memo.get(key, memo) if memo is not None else memo
        if got is memo:
            s = seed
            for i in path:
                s = child_seed(s, i)
            got = outcome(kind, random_value(s, draw), params)
            if memo is not None:
                memo[key] = got
        if got != recorded:
            return False
    return True


def _undefined_qualified(module: Module, name: str) -> str:
    """The warning for a call of ``Alias.Rule`` that finds no rule, with the nearest name."""
    prefix, short = name.rsplit(".", 1)
    found = module.resolve(name)
    if found is None:  # the alias (or one along the chain) is not imported
        head = prefix.rpartition(".")[0]
        owner = module if not head else (module.resolve(head + ".x") or (None,))[0]
        known = [] if owner is None else [(head + "." if head else "") + a for a in owner.imports]
        close = difflib.get_close_matches(prefix, known, n=1)
        hint = f"; did you mean '{close[0]}.{short}'?" if close else ""
        return f"rule '{name}' is not defined (no such import: '{prefix}'{hint}); the shape is a leaf"
    mod = found[0]
    close = difflib.get_close_matches(short, list(mod.rules), n=1)
    hint = f"; did you mean '{prefix}.{close[0]}'?" if close else ""
    return f"rule '{name}' is not defined (no such rule there: '{prefix}'{hint}); the shape is a leaf"


class _RunContext:
    """Runs the operation sequence of one rule application."""

    __slots__ = ("d", "queue", "node", "depth", "rule", "emitted", "deleted")

    def __init__(self, derivation, queue, node, depth, rule):
        self.d, self.queue, self.node, self.depth, self.rule = derivation, queue, node, depth, rule
        self.emitted = 0
        self.deleted = False

    def emit(self, state: ShapeState, name: str, args: tuple, module: Module, origin, leaf=False):
        child_state = state.child(self.emitted)
        self.emitted += 1
        self.d.count_shape(name)
        child = self.node.add(Shape(name, child_state.scope, id=self.d.new_id()))
        if origin:
            child.operator, child.params = origin
        if leaf:
            self.d._output(child, child_state, name)
        else:
            self.queue.append((child, child_state, name, args, module, self.depth + 1))

    def run(self, ops: tuple, state: ShapeState, env: Env, origin) -> bool:
        """Run ``ops`` on ``state``; returns whether the shape was consumed (replaced)."""
        consumed = False
        for op in ops:
            t = type(op)
            try:
                if t is A.Successor:
                    spec = operation_of(op, env.module)
                    if spec is not None:
                        self.call_op(spec, op, state, env, ())
                    else:
                        args = tuple(env.evaluate(a) for a in op.args)
                        self.emit(state, op.name, args, env.module, origin)
                        consumed = True
                elif t is A.Leaf:
                    self.emit(state, op.name, (), env.module, origin, leaf=True)
                    consumed = True
                elif t is A.BodyOp:
                    spec = OPERATIONS.get(op.name)
                    if spec is None or not spec.body:
                        raise CGARuntimeError(f"'{op.name}' takes no {{ … }} body")
                    pieces = self.call_op(spec, op, state, env, op.branches)
                    if spec.keeps_shape:  # modify: the shape goes on with its edited geometry
                        continue
                    own = self.d.add_occluder(state) if pieces else None
                    for piece_state, piece_ops, info in pieces or ():
                        piece_state.mark_pivot()
                        if own is not None:
                            piece_state.context["occluder_ancestors"] = own
                        sub = env.with_state(piece_state)
                        if not self.run(piece_ops, piece_state, sub, (op.name, info)):
                            self.d.count_shape(self.rule)
                            piece = Shape(self.rule, piece_state.scope, operator=op.name,
                                          params=info, id=self.d.new_id())
                            self.node.add(piece)
                            self.d._output(piece, piece_state, self.rule)
                    # the current shape is now an inner node of the tree, never a leaf; as in
                    # CityEngine, operations after the body go on with it unchanged (its own
                    # volume, now an occluder, is an ancestor of what follows)
                    if own is not None:
                        state.context = {**state.context, "occluder_ancestors": own}
                    consumed = True
                elif t is A.Inline or t is A.Boolean:
                    self.inline(op, state, env)
                elif t is A.Push:
                    sub_state = state.copy()
                    sub_state.draws = state.draws
                    sub_state.mark_pivot()  # center() aligns to the pushed shape (reference)
                    if self.run(op.ops, sub_state, env.with_state(sub_state), origin):
                        consumed = True
                    state.draws = sub_state.draws
                elif t is A.Nil:
                    self.deleted = True
                    return True
                elif t is A.CaseOps:
                    chosen = op.otherwise
                    for cond, branch in op.branches:
                        if to_bool(env.evaluate(cond)):
                            chosen = branch
                            break
                    return self.run(chosen, state, env, origin) or consumed
                elif t is A.StochasticOps:
                    pcts = tuple(pct for pct, _ in op.branches)
                    index = outcome("pct", state.random_float(), pcts)
                    env.note_choice("pct", pcts, index)
                    chosen = op.branches[index][1] if index < len(pcts) else op.otherwise
                    return self.run(chosen, state, env, origin) or consumed
            except CGARuntimeError as e:
                self.d.warn(str(e), op, self.rule)
            except DerivationError as e:
                raise self.d.located(e, op, self.rule) from None
            except (RecursionError, MemoryError, KeyboardInterrupt):
                raise
            except Exception as e:  # a geometry kernel failing on odd input: keep deriving
                self.d.warn(f"{getattr(op, 'name', type(op).__name__)} failed on this shape "
                            f"({type(e).__name__}: {e}); the shape is left as it was", op, self.rule)
        return consumed

    def inline(self, op, state, env) -> None:
        """``inline …`` and ``union|subtract|intersect { A | B }`` (ops/inlining.py)."""
        from .ops.inlining import boolean_into, derive_now, merge_into

        d = self.d
        if d.inline_depth >= MAX_INLINE_DEPTH:
            raise DerivationError(f"inline nested deeper than {MAX_INLINE_DEPTH} levels in rule "
                                  f"'{self.rule}'; a rule probably inlines itself")
        d.inline_depth += 1
        try:
            if type(op) is A.Inline:
                merge_into(d, state, derive_now(self, op.ops, state, env), op.strategy)
            else:
                a = derive_now(self, op.a, state, env)
                b = derive_now(self, op.b, state, env)
                boolean_into(d, state, op.kind, a, b)
        finally:
            d.inline_depth -= 1

    def call_op(self, spec, op, state, env, branches):
        n = len(op.args)
        if not spec.min_args <= n <= spec.max_args:
            want = spec.min_args if spec.min_args == spec.max_args else f"{spec.min_args} to {spec.max_args}"
            raise CGARuntimeError(f"{spec.name}() takes {want} arguments, got {n}")
        args = []
        selectors = spec.selector_positions(n)
        for k, a in enumerate(op.args):
            if isinstance(a, A.Name) and (k in spec.names or (
                    k in selectors and a.name not in env.locals
                    and env.module.attr(a.name) is None
                    and env.module.function(a.name, 0) is None)):
                args.append(a.name)
            else:
                args.append(env.evaluate(a))
        call = OpCall(spec.name, args, state, self.d, env, branches, getattr(op, "repeat", False))
        call.rule = self.rule  # type: ignore[attr-defined]
        call.run = self  # type: ignore[attr-defined]
        return spec.fn(call)


def _coerce_override(value, adef: A.AttrDef):
    """``--attr`` values arrive as text: convert to the attribute's declared or default type."""
    if not isinstance(value, str):
        return value
    kind = adef.type
    if kind is None:
        init = adef.value
        kind = {A.Num: "float", A.Str: "string", A.Bool: "bool"}.get(type(init))
        if isinstance(init, A.Unary) and isinstance(init.operand, A.Num):
            kind = "float"
    if kind == "float":
        try:
            return float(value)
        except ValueError:
            raise RuleError(f"attribute '{adef.name}' is a float; cannot set it to '{value}'") from None
    if kind == "bool":
        if value.lower() not in ("true", "false", "1", "0"):
            raise RuleError(f"attribute '{adef.name}' is a bool; use true or false, not '{value}'")
        return value.lower() in ("true", "1")
    if kind == "string":
        return value
    try:
        return float(value)
    except ValueError:
        return value


__all__ = ["Derivation", "Env", "Limits", "to_float", "to_str"]
