"""Fast 2D layouts of split grammars: the candidate generator of grammar-driven parsing.

Parsing (``simon2011`` ch. 4–5) scores thousands of derivations per facade.  A full derivation by
:mod:`facadeforge.grammar.interpreter` builds meshes, states and a shape tree (≈ 50 µs per
shape); the energy of §4.2.2 only needs each terminal's rectangle and label.  :class:`SplitLayout`
derives the *same rules* restricted to what a 2D facade layout uses, returning leaf rectangles:

- ``split(x|y) { … }`` and ``{ … }*`` with absolute, relative (``'``) and floating (``~``) sizes,
  resolved by the interpreter's own :func:`~facadeforge.grammar.ops.subdivision.resolve_split`;
- successor rules with parameters, ``case … else`` on expressions, ``NIL``;
- ``label("…")`` (a leaf's label; otherwise the label guessed from the rule name, as for
  derived models); appearance-only operations (``color``, ``t``, ``s``, ``texture``, …) are
  ignored, since they do not move a 2D rectangle.

Expressions are evaluated by the interpreter's :class:`~facadeforge.grammar.expressions.Evaluator`
(attributes, rule parameters, ``scope.sx``/``scope.sy``, built-in functions).  Because nothing in
this subset depends on a shape's position or on randomness, a rule applied to two shapes of the
same size with the same arguments yields the same layout up to translation: results are memoised
per (rule, arguments, size), so twenty identical floors cost one.  The memo also outlives a
derivation: its key holds the values of the attributes the rule reads (through the rules,
functions and attribute defaults it reaches), so a search that moves one floor line derives
the floors it did not move from the memo.  A grammar using anything else
(``rand``, ``comp``, ``extrude``, ``split.index``…) raises :class:`ParseGrammarError` naming the rule
and line; such grammars still derive in the engine, just not in the parser's inner loop.

Tests check the rectangles against full derivations by the engine.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..errors import InputError
from ..grammar import ast as A
from ..grammar.expressions import Evaluator
from ..grammar.functions import FUNCTIONS
from ..grammar.ops import OPERATIONS
from ..grammar.ops.subdivision import call_pieces
from ..grammar.values import CGARuntimeError, to_bool, to_str
from ..model.labels import label_for_name

__all__ = ["Layout", "ParseGrammarError", "SplitLayout"]

#: Operations that change nothing about a 2D rectangle and its label.
_APPEARANCE_OPS = frozenset({
    "color", "t", "s", "r", "texture", "setupProjection", "projectUV", "set", "print", "report",
    "tileUV", "scaleUV", "translateUV", "rotateUV", "normalizeUV", "deleteUV", "alignScopeToAxes",
    "center", "i", "extrude", "primitiveQuad", "setNormals", "softenNormals", "cleanupGeometry", "tag"})

MAX_DEPTH = 64
MAX_LEAVES = 100_000
#: Rule results kept across derivations before the memo is cleared.
MEMO_SIZE = 50_000


#: Marks an attribute whose default is being evaluated (a cycle reads it again).
_EVALUATING = object()


def _typed(values) -> tuple:
    """Values paired with their types, as a memo key (``True == 1 == 1.0`` in Python, but a
    CGA ``str()`` or comparison can tell them apart)."""
    return tuple((type(v), v) for v in values)


class ParseGrammarError(InputError, ValueError):
    """A grammar uses something the parser's 2D layout derivation does not support."""


@dataclass(frozen=True)
class Layout:
    """Leaf rectangles of one derivation, metres, facade frame (x right, y up from the bottom).

    ``boxes`` is ``(n, 4)`` float ``x0, y0, x1, y1``; ``labels`` the canonical label of each.
    """

    boxes: np.ndarray
    labels: tuple[str, ...]
    width: float
    height: float


class _Env(Evaluator):
    """What the expression evaluator asks of an environment, for the 2D subset."""

    __slots__ = ("layout", "locals", "sx", "sy")

    def __init__(self, layout: SplitLayout, local_vars: Mapping[str, Any], sx: float, sy: float):
        self.layout = layout
        self.locals = local_vars
        self.sx = sx
        self.sy = sy

    def random_float(self) -> float:
        raise CGARuntimeError("parse grammars must be deterministic: rand() is not supported")

    def lookup(self, name: str, node):
        if name in self.locals:
            return self.locals[name]
        if name == "scope.sx":
            return self.sx
        if name == "scope.sy":
            return self.sy
        if name == "scope.sz":
            return 0.0
        if name in self.layout.attr_defs:
            return self.layout.attr_value(name)
        raise CGARuntimeError(f"'{name}' is not available in a parse grammar (attributes, rule "
                              "parameters and scope.sx/scope.sy are)")

    def call(self, name: str, args: list, node):
        if name in self.layout.functions and len(self.layout.functions[name].params) == len(args):
            fdef = self.layout.functions[name]
            env = _Env(self.layout, {p.name: v for p, v in zip(fdef.params, args)}, self.sx,
                       self.sy)
            return env.evaluate(fdef.body)
        if name in ("rand", "p"):
            raise CGARuntimeError(f"parse grammars must be deterministic: {name}() is not "
                                  "supported")
        entry = FUNCTIONS.get(name)
        if entry is None:
            raise CGARuntimeError(f"function '{name}' is not available in a parse grammar")
        return entry[0](self, args)

    def comp_function(self, node):
        raise CGARuntimeError("comp(…) functions are not available in a parse grammar")


class SplitLayout:
    """The 2D layout derivation of a loaded rule set (module docstring).

    Parameters
    ----------
    rules : facadeforge.engine.Rules
        Loaded rules (:func:`facadeforge.engine.load_rules`); only the main file is used.
    start : str, optional
        Start rule (default: the rules' ``@StartRule``).
    """

    def __init__(self, rules, start: str | None = None):
        module = rules.ruleset.main
        self.module = module
        self.start = start or rules.ruleset.start_rule
        if not self.start:
            raise ParseGrammarError("the parse grammar has no @StartRule; mark one or pass start")
        self.rule_defs: dict[tuple[str, int], A.RuleDef] = {}
        for name, by_arity in module.rules.items():
            for arity, rdef in by_arity.items():
                self.rule_defs[(name, arity)] = rdef
        if (self.start, 0) not in self.rule_defs:
            raise ParseGrammarError(f"start rule '{self.start}' is not defined (without "
                                    "parameters) in the parse grammar")
        self.attr_defs: dict[str, A.AttrDef] = dict(module.attrs)
        self.functions = {f.name: f for by_arity in module.functions.values()
                          for f in by_arity.values()}
        self._overrides: dict[str, Any] = {}
        self._attr_cache: dict[str, Any] = {}
        self._array_keys: dict[str, tuple] = {}
        self._memo: dict[tuple, list[tuple]] = {}
        self._pieces: dict[tuple, list] = {}
        self._rule_attrs: dict[str, tuple[str, ...]] = {}
        self._split_cache: dict[int, tuple[frozenset[str], tuple[str, ...]]] = {}
        self._sig: dict[Any, tuple] = {}
        self._terminals: dict[int, str | None] = {}
        self._plans: dict[int, tuple[str, tuple] | None] = {}

    # ------------------------------------------------------------------ attributes
    def attr_value(self, name: str):
        if name in self._attr_cache:
            value = self._attr_cache[name]
            if value is _EVALUATING:
                raise CGARuntimeError(f"attribute '{name}' is defined through itself")
            return value
        adef = self.attr_defs[name]
        if not adef.const and name in self._overrides:
            value = self._overrides[name]
        else:
            self._attr_cache[name] = _EVALUATING  # cycle guard
            try:
                value = _Env(self, {}, 0.0, 0.0).evaluate(adef.value)
            except BaseException:
                del self._attr_cache[name]
                raise
        self._attr_cache[name] = value
        return value

    def _attr_key(self, name: str):
        """The attribute's value as a memo key: an array by its contents (once per
        derivation), anything else as it is."""
        value = self.attr_value(name)
        if type(value) is not np.ndarray:
            return value
        key = self._array_keys.get(name)
        if key is None:
            key = self._array_keys[name] = (value.shape, value.dtype.str, value.tobytes())
        return key

    # ------------------------------------------------------------------ derivation
    def derive(self, width: float, height: float, attrs: Mapping[str, Any] | None = None
               ) -> Layout:
        """Leaf rectangles of the start rule on a ``width`` × ``height`` facade."""
        if not (width > 0 and height > 0):
            raise InputError(f"layout size {width} x {height} must be positive")
        self._overrides = dict(attrs or {})
        self._attr_cache = {}
        self._array_keys = {}
        self._sig = {}
        self._count = 0
        if len(self._memo) > MEMO_SIZE:
            self._memo.clear()
        if len(self._pieces) > MEMO_SIZE:
            self._pieces.clear()
        leaves = self._rule(self.start, (), width, height, None, 0)
        if len(leaves) > MAX_LEAVES:
            raise ParseGrammarError(f"the parse grammar makes more than {MAX_LEAVES} leaves")
        boxes = np.array([lf[:4] for lf in leaves], float).reshape(-1, 4)
        return Layout(boxes, tuple(lf[4] for lf in leaves), float(width), float(height))

    # Leaves travel as tuples (x0, y0, x1, y1, label) relative to the shape's own corner: far
    # cheaper than small numpy arrays in this recursion.
    def _rule(self, name: str, args: tuple, sx: float, sy: float, label: str | None, depth: int
              ) -> list[tuple]:
        rdef = self.rule_defs.get((name, len(args)))
        if rdef is None:  # a leaf: an undefined successor is a terminal shape
            return self._leaf(name, label, sx, sy)
        if depth > MAX_DEPTH:
            raise ParseGrammarError(f"rule '{name}' (line {rdef.line}) nests deeper than "
                                    f"{MAX_DEPTH} levels")
        terminal = self._terminal(rdef)
        if terminal is not None:   # appearance operations and a constant label: a leaf
            return self._leaf(name, terminal or label, sx, sy)
        sig = self._sig.get(name, _EVALUATING)
        if sig is _EVALUATING:
            sig = self._signature(name, self._reads_attrs)
        key = hit = None
        if sig is not None:
            try:
                # typed values (True, 1 and 1.0 are equal keys otherwise); the depth too, so a
                # result found at one depth is not reused where its subtree would nest too deep
                key = (name, _typed(args) if args else (), round(sx, 9), round(sy, 9), label,
                       depth, sig)
                hit = self._memo.get(key)
            except TypeError:  # an unhashable argument or attribute (an array): no memo
                key = None
        if hit is not None:
            return hit
        env = _Env(self, {p.name: v for p, v in zip(rdef.params, args)}, sx, sy)
        try:
            out = self._ops(rdef.body, env, name, sx, sy, label, depth, rdef.line)
        except CGARuntimeError as exc:
            raise ParseGrammarError(f"parse grammar, rule '{name}' (line {rdef.line}): {exc}"
                                    ) from None
        if key is not None:
            self._memo[key] = out
        return out

    def _signature(self, owner, reads) -> tuple | None:
        """The typed values of the attributes ``reads(owner)`` names, once per derivation, or
        ``None`` when one of them cannot be evaluated (then nothing is memoised, and the error
        surfaces only if the derivation really reads that attribute)."""
        k = id(owner) if isinstance(owner, A.Node) else owner   # an int or a rule name
        if k in self._sig:
            return self._sig[k]
        try:
            values = tuple(map(self._attr_key, reads(owner)))
            sig = (values, tuple(map(type, values)))   # typed, as _typed, but two C loops
        except CGARuntimeError:
            sig = None
        self._sig[k] = sig
        return sig

    def _split_reads(self, op: A.BodyOp) -> tuple[frozenset[str], tuple[str, ...]]:
        """The scope sizes and the attributes a split's size expressions read."""
        hit = self._split_cache.get(id(op))
        if hit is None:
            hit = self._split_cache[id(op)] = self._reads_in([op.branches], follow_rules=False)
        return hit

    def _reads_attrs(self, rule: str) -> tuple[str, ...]:
        """The attributes a rule's layout can depend on: those named in its body and in the
        bodies of the rules, functions and attribute defaults it reaches (sorted)."""
        hit = self._rule_attrs.get(rule)
        if hit is None:
            roots = [rdef.body for (n, _), rdef in self.rule_defs.items() if n == rule]
            hit = self._rule_attrs[rule] = self._reads_in(roots, follow_rules=True)[1]
        return hit

    def _reads_in(self, roots: list, follow_rules: bool
                  ) -> tuple[frozenset[str], tuple[str, ...]]:
        """``(scope sizes, attributes)`` the expressions under ``roots`` read, through the
        bodies of the functions they call (a function sees its caller's scope) and the
        defaults of the attributes they read; with ``follow_rules``, through the successor
        rules too, else only the selectors (sizes) of split branches."""
        scope: set[str] = set()
        found: set[str] = set()
        seen: set[str] = set()
        stack: list[Any] = list(roots)
        while stack:
            node = stack.pop()
            if isinstance(node, tuple | list):
                stack.extend(node)
                continue
            if not isinstance(node, A.Node):
                continue
            if isinstance(node, A.Branch) and not follow_rules:
                stack.append(node.selector)
                continue
            ref = getattr(node, "name", None)
            if isinstance(node, A.Name):
                if ref in self.attr_defs and ref not in found:
                    found.add(ref)
                    stack.append(self.attr_defs[ref].value)
                elif ref in ("scope.sx", "scope.sy"):
                    scope.add(ref)
            elif isinstance(node, A.Successor | A.Leaf | A.Call) and ref not in seen:
                seen.add(ref)
                if follow_rules:
                    stack.extend(rdef.body for (n, _), rdef in self.rule_defs.items()
                                 if n == ref)
                if ref in self.functions:   # its body reads the caller's scope, if any
                    stack.append(self.functions[ref].body)
            stack.extend(v for v in vars(node).values() if isinstance(v, A.Node | tuple))
        return frozenset(scope), tuple(sorted(found))

    def _leaf(self, name: str, label: str | None, sx: float, sy: float):
        self._count += 1
        if self._count > MAX_LEAVES:
            raise ParseGrammarError(f"the parse grammar makes more than {MAX_LEAVES} leaves")
        lab = label or str(label_for_name(name) or "other")
        return [(0.0, 0.0, sx, sy, lab)]

    def _ops(self, ops, env: _Env, name: str, sx: float, sy: float, label, depth, line: int):
        for i, op in enumerate(ops):
            last = i == len(ops) - 1
            if isinstance(op, A.Successor) and op.name == "label":
                label = to_str(env.evaluate(op.args[0])) if op.args else label
                continue
            if isinstance(op, A.Successor) and op.name in _APPEARANCE_OPS:
                continue
            if isinstance(op, A.Nil):
                return []
            if isinstance(op, A.Leaf) or (isinstance(op, A.Successor) and last
                                           and op.name not in OPERATIONS):
                args = tuple(env.evaluate(a) for a in getattr(op, "args", ()))
                return self._rule(op.name, args, sx, sy, label, depth + 1)
            if isinstance(op, A.CaseOps):
                for cond, body in op.branches:
                    if to_bool(env.evaluate(cond)):
                        return self._ops(body, env, name, sx, sy, label, depth, line)
                return self._ops(op.otherwise, env, name, sx, sy, label, depth, line)
            if isinstance(op, A.BodyOp) and op.name == "split" and last:
                return self._split(op, env, sx, sy, label, depth)
            what = getattr(op, "name", type(op).__name__)
            raise ParseGrammarError(f"parse grammar, rule '{name}' (line {line}): "
                                    f"'{what}' is not supported in a 2D parse grammar (use "
                                    "split, case, label and successor rules)")
        return self._leaf(name, label, sx, sy)

    def _split(self, op: A.BodyOp, env: _Env, sx: float, sy: float, label, depth):
        axis_name = op.args[0].name if op.args and isinstance(op.args[0], A.Name) else None
        if axis_name not in ("x", "y"):
            raise ParseGrammarError(f"parse grammar, line {op.line}: only split(x) and split(y) "
                                    "are supported")
        total = sx if axis_name == "x" else sy
        out: list[tuple] = []
        # The pieces depend on the split's size expressions: attributes (fixed during one
        # derivation), rule parameters, and the scope sizes they read.  Cache them per split,
        # keyed by what they can depend on, so twenty floors of one width share one x split.
        reads, _ = self._split_reads(op)
        sig = self._signature(op, lambda op: self._split_reads(op)[1])
        key = pieces = None
        if sig is not None:
            try:
                local = tuple((n, type(v), v) for n, v in sorted(env.locals.items()))
                key = (id(op), local, total, sx if "scope.sx" in reads else None,
                       sy if "scope.sy" in reads else None, sig)
                pieces = self._pieces.get(key)
            except TypeError:  # an unhashable rule argument (an array): no caching
                key = None
        if pieces is None:
            call = SimpleNamespace(branches=op.branches, env=env, repeat=op.repeat)
            pieces = call_pieces(call, total)
            if key is not None:
                self._pieces[key] = pieces
        horizontal = axis_name == "x"
        for branch, start, size in pieces:
            w, h = (size, sy) if horizontal else (sx, size)
            call = self._successor(branch)
            if call is not None:  # the common piece, one successor rule: no ops loop
                rule, arg_nodes = call
                if arg_nodes:
                    ev = _Env(self, env.locals, w, h).evaluate
                    args = tuple(ev(a) for a in arg_nodes)
                else:
                    args = ()
                leaves = self._rule(rule, args, w, h, None, depth + 2)
            else:
                sub_env = _Env(self, env.locals, w, h)
                leaves = self._ops(branch.ops, sub_env, "split", w, h, None, depth + 1,
                                   branch.line)
            if len(out) + len(leaves) > MAX_LEAVES:
                raise ParseGrammarError(f"the parse grammar makes more than {MAX_LEAVES} leaves")
            if horizontal:
                out += [(x0 + start, y0, x1 + start, y1, lab) for x0, y0, x1, y1, lab in leaves]
            else:
                out += [(x0, y0 + start, x1, y1 + start, lab) for x0, y0, x1, y1, lab in leaves]
        return out

    def _terminal(self, rdef) -> str | None:
        """For a rule whose body is only appearance operations and ``label`` calls with a
        non-empty string literal (``Wall --> color(…) label("wall")``): the last label, or
        ``""`` without one (the leaf keeps the label it inherits); ``None`` for any other rule,
        which :meth:`_ops` derives."""
        key = id(rdef)
        if key in self._terminals:
            return self._terminals[key]
        found: str | None = ""
        for op in rdef.body:
            if not isinstance(op, A.Successor):
                found = None
            elif op.name == "label":
                ok = len(op.args) == 1 and isinstance(op.args[0], A.Str) and op.args[0].value
                found = op.args[0].value if ok and found is not None else None
            elif op.name not in _APPEARANCE_OPS:
                found = None
            if found is None:
                break
        self._terminals[key] = found
        return found

    def _successor(self, branch: A.Branch) -> tuple[str, tuple] | None:
        """``(rule, argument nodes)`` when a split piece's operations are one successor rule
        call (what ``_ops`` would do with them), else ``None``."""
        key = id(branch)
        if key in self._plans:
            return self._plans[key]
        plan = None
        ops = branch.ops
        if len(ops) == 1:
            op = ops[0]
            if isinstance(op, A.Leaf):
                plan = (op.name, ())
            elif (isinstance(op, A.Successor) and op.name != "label"
                  and op.name not in _APPEARANCE_OPS and op.name not in OPERATIONS):
                plan = (op.name, tuple(op.args))
        self._plans[key] = plan
        return plan
