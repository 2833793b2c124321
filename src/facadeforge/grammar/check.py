"""Static checks after linking: unknown attributes, functions and qualified rules are errors with
the file, line and column (and a suggestion), before anything is derived."""

from __future__ import annotations

import difflib
from pathlib import Path

from ..errors import RuleError
from . import ast as A
from .functions import FUNCTIONS, bare_call
from .module import BUILTIN_NAMES, Module, RuleSet
from .ops import OPERATIONS, operation_of

# names that are selector keywords wherever an operation takes a selector
_KEYWORDS = {
    "x", "y", "z", "xy", "xz", "yz", "xyz", "u", "v", "f", "e", "fe", "fv", "g", "m", "h",
    "adjust", "noAdjust", "inside", "border", "all", "remainder", "front", "back", "left", "right",
    "top", "bottom", "side", "vertical", "horizontal", "aslant", "nutant", "scopeOrigin",
    "scopeCenter", "rel", "abs", "scope", "world", "object", "byAngle", "byHeight", "yUp", "zUp",
    "largest", "longest", "shortest", "uniform", "gaussian", "surface", "volume", "keepSizeAndPosition",
    "fitScope", "unitSpace", "uvSpace", "inter", "intra", "occlusion", "none", "true", "false",
    "normal", "even", "shape", "keepSizeAlignPosition", "alignSizeAndPosition",
    "hard", "soft", "flat", "auto", "conform", "sx", "sy", "sz", "tx", "ty", "tz", "rx", "ry",
    "rz", "maxSlope", "azimuth", "zenith", "noAlign", "edge", "face", "vertex", "yes", "no",
    "center", "uniformScale", "any", "lowest", "world.lowest", "pos", "scale", "rotation", "dirX", "dirZ", "zyx", "xzy", "yxz", "yzx", "zxy",
}


#: Prefixes of CityEngine's built-in names (``geometry.area``, ``scope.sx``…), never imports.
_BUILTIN_NAMESPACES = frozenset({"geometry", "scope", "split", "comp", "initialShape", "material",
                                 "world", "pivot", "edgeAttr", "convexHull", "street", "object"})


def _shape_function_names() -> set:
    from .ops import SHAPE_FUNCTIONS, load_all

    load_all()
    return set(SHAPE_FUNCTIONS)


class _Checker:
    def __init__(self, module: Module):
        self.m = module
        self.shape_fns = _shape_function_names()

    def fail(self, msg, node, candidates=()):
        close = difflib.get_close_matches(msg.split("'")[1] if "'" in msg else "", list(candidates), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise RuleError(msg + hint, self.m.path, getattr(node, "line", 0), getattr(node, "column", 0))

    def known_name(self, name, scope) -> bool:
        return (name in scope or name in BUILTIN_NAMES or name.startswith("material.")
                or self.m.attr(name) is not None or self.m.function(name, 0) is not None
                or name in self.shape_fns or bare_call(name))

    def expr(self, node, scope, selector_ok=False):
        t = type(node)
        if t is A.Name:
            if self.known_name(node.name, scope):
                return
            if selector_ok:  # selector vocabularies are open-ended (x, inside, sy, maxSlope, …)
                return
            prefix = node.name.split(".")[0]
            if "." in node.name and prefix in _BUILTIN_NAMESPACES:
                self.fail(f"unknown built-in '{node.name}'", node,
                          [n for n in BUILTIN_NAMES | self.shape_fns
                           if n.startswith(prefix + ".")])
            if "." in node.name and self.m.resolve(node.name) is None:
                self.fail(f"unknown import '{prefix}' in '{node.name}'", node, self.m.imports)
            self.fail(f"unknown attribute or variable '{node.name}'", node,
                      list(scope) + list(self.m.attrs) + (sorted(_KEYWORDS) if selector_ok else []))
        elif t is A.Call:
            n = len(node.args)
            if not (self.m.function(node.name, n) is not None or node.name in FUNCTIONS
                    or (n == 0 and self.m.attr(node.name) is not None)
                    or node.name in self.shape_fns or node.name in _OCCLUSION):
                if self.m.resolve(node.name) is not None and self.m.function(node.name, n) is None \
                        and self._has_function_any_arity(node.name):
                    self.fail(f"function '{node.name}' does not take {n} arguments", node)
                self.fail(f"unknown function '{node.name}'", node,
                          list(FUNCTIONS) + list(self.m.functions))
            sel = node.name in self.shape_fns or node.name in _OCCLUSION
            for a in node.args:
                self.expr(a, scope, selector_ok=sel)
        elif t is A.Index:
            self.expr(node.target, scope)
            for i in node.indices:
                self.expr(i, scope)
        elif t is A.Array:
            for row in node.rows:
                for e in row:
                    self.expr(e, scope)
        elif t is A.Colon:
            for e in (node.start, node.step, node.stop):
                if e is not None:
                    self.expr(e, scope)
        elif t is A.Unary:  # a logical selector (``!inside``, ``left || right``) keeps its words
            self.expr(node.operand, scope, selector_ok=selector_ok and node.op == "!")
        elif t is A.Binary:
            logical = selector_ok and node.op in ("&&", "||")
            self.expr(node.left, scope, selector_ok=logical)
            self.expr(node.right, scope, selector_ok=logical)
        elif t in (A.CaseExpr,):
            for c, v in node.branches:
                self.expr(c, scope)
                self.expr(v, scope)
            self.expr(node.otherwise, scope)
        elif t is A.StochasticExpr:
            for _, v in node.branches:
                self.expr(v, scope)
            self.expr(node.otherwise, scope)
        elif t is A.CompFunction:
            for b in node.branches:
                self.expr(b.selector, scope, selector_ok=True)
                self.expr(b.ops, scope)

    def _has_function_any_arity(self, name):
        found = self.m.resolve(name) if "." in name else (self.m, name)
        return found is not None and found[1] in found[0].functions

    def ops(self, ops, scope):
        for op in ops:
            t = type(op)
            if t is A.Successor:
                spec = operation_of(op, self.m)
                if spec is not None:
                    if spec.body:
                        raise RuleError(f"{op.name}() needs a {{ … }} body saying what its parts "
                                        f"become, e.g. {op.name}(…) {{ all : A | remainder : B }}"
                                        if op.name in ("setback", "setbackPerEdge",
                                                       "setbackToArea", "shapeL", "shapeU",
                                                       "shapeO", "innerRectangle")
                                        else f"{op.name}() needs a {{ … }} body saying what its "
                                        f"parts become", self.m.path, op.line, op.column)
                    if not spec.min_args <= len(op.args) <= spec.max_args:
                        want = (spec.min_args if spec.min_args == spec.max_args
                                else f"{spec.min_args} to {spec.max_args}")
                        raise RuleError(f"{op.name}() takes {want} arguments, got {len(op.args)}",
                                        self.m.path, op.line, op.column)
                    positions = spec.selector_positions(len(op.args))
                    for k, a in enumerate(op.args):
                        self.expr(a, scope, selector_ok=k in positions)
                    continue
                # a rule of an import that is not there ('SU.DryWall2' in a file that imports
                # SULO only, in the FHNW Swiss building rules) is, as any undefined rule, a
                # leaf: CityEngine warns ("not necessarily a problem") and generates; so does
                # the derivation when it gets there
                # a rule called with a number of arguments none of its versions takes is, as an
                # undefined rule, a leaf: the derivation warns when it gets there (CityEngine's
                # own tutorials and libraries contain such calls on branches rarely taken)
                if op.has_parens and not self.m.has_rule_name(op.name) and op.name[:1].islower() \
                        and op.name not in OPERATIONS:
                    self.fail(f"unknown operation '{op.name}'", op, list(OPERATIONS))
                for a in op.args:
                    self.expr(a, scope)
            elif t is A.BodyOp:
                spec = OPERATIONS.get(op.name)
                if spec is None or not spec.body:
                    self.fail(f"unknown operation '{op.name}' with a {{ … }} body", op,
                              [k for k, s in OPERATIONS.items() if s.body])
                positions = spec.selector_positions(len(op.args))
                for k, a in enumerate(op.args):
                    self.expr(a, scope, selector_ok=k in positions)
                self.branches(op.name, op.branches, scope)
            elif t is A.Push or t is A.Inline:
                self.ops(op.ops, scope)
            elif t is A.Boolean:
                self.ops(op.a, scope)
                self.ops(op.b, scope)
            elif t is A.CaseOps:
                for c, b in op.branches:
                    self.expr(c, scope)
                    self.ops(b, scope)
                self.ops(op.otherwise, scope)
            elif t is A.StochasticOps:
                for _, b in op.branches:
                    self.ops(b, scope)
                self.ops(op.otherwise, scope)

    def branches(self, opname, branches, scope):
        for b in branches:
            if isinstance(b, A.RepeatGroup):
                self.branches(opname, b.branches, scope)
                continue
            # a split size or a perimeter section's length is an expression, not a selector
            self.expr(b.selector, scope, selector_ok=opname != "split" and b.depth is None)
            if b.depth is not None:
                self.expr(b.depth, scope)
            self.ops(b.ops, scope)


_OCCLUSION = {"inside", "overlaps", "touches", "minimumDistance", "contextCompare", "contextCount",
              "imageInfo", "convert", "edgeAttr.getFloat", "edgeAttr.getString", "edgeAttr.getBool",
              "readFloatTable", "readStringTable", "readBoolTable", "readTextFile"}


def check_rules(ruleset: RuleSet) -> None:
    """Raise ``RuleError`` for the first unknown name in any linked module (a file imported
    several times in one style is checked once), and for an import statement that protects or
    redefines an attribute or rule its file does not have."""
    checked = set()
    for mod in ruleset.main.all_modules():
        if mod.merged:  # included without an id: it may use its importer's names
            continue
        _check_import_statements(mod)
        if (mod.path, mod.style) in checked:
            continue
        checked.add((mod.path, mod.style))
        c = _Checker(mod)
        attrs, functions, rules = mod.own_declarations    # in the module's style
        for a in attrs:
            c.expr(a.value, set())
        for f in functions:
            c.expr(f.body, {p.name for p in f.params})
        for r in rules:
            c.ops(r.body, {p.name for p in r.params})


def _check_import_statements(mod: Module) -> None:
    """What an import statement names exists in the imported file, and its expressions and
    rule bodies (evaluated in the importer) name what the importer has."""
    for imp in mod.ast.imports:
        child = mod.imports.get(imp.alias) if imp.alias else None
        if child is None:
            continue
        checker = _Checker(mod)
        for item in imp.overrides:
            if isinstance(item, A.RuleForward):
                if item.name not in child.rules:
                    raise RuleError(f"import '{imp.alias}' sends rule '{item.name}' on, which "
                                    f"{Path(child.path).name} does not define",
                                    mod.path, item.line, item.column)
                if not mod.has_rule_name(item.target):
                    raise RuleError(f"import '{imp.alias}' sends rule '{item.name}' to "
                                    f"'{item.target}', which {Path(mod.path).name} does not "
                                    "define", mod.path, item.line, item.column)
                continue
            if isinstance(item, A.RuleDef):
                if item.name not in child.rules:
                    close = difflib.get_close_matches(item.name, list(child.rules), n=1)
                    raise RuleError(
                        f"import '{imp.alias}' redefines rule '{item.name}', which "
                        f"{Path(child.path).name} does not define"
                        + (f"; did you mean '{close[0]}'?" if close else ""),
                        mod.path, item.line, item.column)
                arities = sorted(child.rules[item.name])
                if len(item.params) not in arities:
                    raise RuleError(
                        f"import '{imp.alias}' redefines rule '{item.name}' with "
                        f"{len(item.params)} parameters; {Path(child.path).name} defines it "
                        f"with {' or '.join(str(a) for a in arities)}",
                        mod.path, item.line, item.column)
                checker.ops(item.body, {p.name for p in item.params})
                continue
            if item[1] is not None:
                checker.expr(item[1], set())
            name = item[0]
            a = child.attrs.get(name)
            if a is None or a.const:
                what = "a constant, not an attribute" if a is not None else "not an attribute of it"
                close = difflib.get_close_matches(
                    name, [k for k, v in child.attrs.items() if not v.const], n=1)
                raise RuleError(
                    f"import '{imp.alias}' {'protects' if item[1] is None else 'redefines'} "
                    f"'{name}', {what} ({Path(child.path).name})"
                    + (f"; did you mean '{close[0]}'?" if close else ""),
                    mod.path, imp.line, imp.column)
