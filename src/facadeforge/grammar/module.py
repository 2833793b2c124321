"""Linked rule files: a ``Module`` per .cga file with its imports, attributes, functions, rules."""

from __future__ import annotations

import difflib
import os
from collections.abc import Callable
from pathlib import Path

from ..errors import RuleError
from . import ast as A
from .parser import DEFAULT_STYLE, parse_rules

MAX_IMPORT_DEPTH = 32
MAX_MODULES = 1000  # import statements in all files together (each is an instance)

# names the runtime provides inside expressions (beside attributes, constants and parameters)
BUILTIN_NAMES = {
    "scope.sx", "scope.sy", "scope.sz", "scope.tx", "scope.ty", "scope.tz", "scope.rx", "scope.ry",
    "scope.rz", "scope.elevation", "split.index", "split.total", "comp.index", "comp.total",
    "comp.sel", "initialShape.origin.px", "initialShape.origin.py", "initialShape.origin.pz",
    "initialShape.origin.ox", "initialShape.origin.oy", "initialShape.origin.oz",
    "initialShape.name", "initialShape.startRule", "seedian", "pi", "PI", "nil",
    "material.name", "material.color.r", "material.color.g", "material.color.b",
    "material.color.a", "material.opacity", "material.colormap", "material.bumpmap",
    "material.normalmap", "material.specularmap", "material.opacitymap", "material.dirtmap",
    "material.shininess", "material.metallic", "material.roughness", "material.reflectivity",
    "material.color.rgb", "material.colormap.su", "material.colormap.sv",
    "material.colormap.tu", "material.colormap.tv", "material.colormap.rw",
    "material.ambient.r", "material.ambient.g", "material.ambient.b",
    "material.specular.r", "material.specular.g", "material.specular.b", "pivot.px", "pivot.py",
    "pivot.pz", "pivot.ox", "pivot.oy", "pivot.oz", "world.up",
}


class Module:
    """One parsed .cga file, linked to the modules it imports.

    Parameters
    ----------
    rule_file : RuleFile
        Parsed AST.
    name : str
        ``""`` for the main file, else the import alias chain (``"facade"``, ``"facade.win"``).
    """

    def __init__(self, rule_file: A.RuleFile, name: str = "", style: str | None = None):
        self.ast = rule_file
        self.path = rule_file.path
        self.name = name
        self.style = style or DEFAULT_STYLE
        self.imports: dict[str, Module] = {}
        self.attrs: dict[str, A.AttrDef] = {}
        self.functions: dict[str, dict[int, A.FuncDef]] = {}
        self.rules: dict[str, dict[int, A.RuleDef]] = {}
        # CityEngine styles: the chosen style's declarations replace those of the style it
        # extends (by default the Default style), by name (attributes) or name and arity
        chain = _style_chain(rule_file, self.style)
        for attrs, functions, rules in chain:
            self.attrs.update({a.name: a for a in attrs})
            for f in functions:
                self.functions.setdefault(f.name, {})[len(f.params)] = f
            for r in rules:
                self.rules.setdefault(r.name, {})[len(r.params)] = r
        # ``st.Facade --> …`` defines rule Facade of the import st (CityEngine's help, "Rule
        # file import"): kept apart, attached to that module by ``link``
        self.qualified_rules = {k: v for k, v in self.rules.items() if "." in k}
        for k in self.qualified_rules:
            del self.rules[k]
        # dotted names this file declares for itself (the prefix is no import): rules kept
        # by ``link`` out of qualified_rules, and dotted attributes and functions
        self.dotted: set[str] = set()
        # rules of this module redefined by an importer (qualified rules, extension overrides
        # in the import statement): name -> arity -> (importer, rule); they win over own rules
        self.rule_overrides: dict[str, dict[int, tuple[Module, A.RuleDef]]] = {}
        # ``( Ext -> MyExt )``: calls of Ext inside this module run the importer's MyExt
        self.rule_forwards: dict[str, tuple[Module, str]] = {}
        # this file's own declarations in its style (anonymous imports add theirs to the
        # namespace below; they are checked in their own file)
        self.own_declarations: tuple[list, list, list] = (
            list(self.attrs.values()),
            [f for by_arity in self.functions.values() for f in by_arity.values()],
            [r for by_arity in (*self.rules.values(), *self.qualified_rules.values())
             for r in by_arity.values()])
        # ``import F : "f.cga" (a = expr)``: attribute a of this module evaluated in the importer
        self.import_overrides: dict[str, tuple[Module, A.Node]] = {}
        # the module whose import statement made this one, and the attributes that statement
        # protects from propagation (``(a, b)``; ``()`` protects all)
        self.importer: Module | None = None
        self.protected: set[str] = set()
        self.protect_all = False
        self.anonymous: list[Module] = []  # files imported without an id (merged in here)
        self.merged = False  # imported without an id: its names live in the importer's
        # @StartRule of the chosen style first, then of the styles it extends, then Default's
        self.start_rules = list(dict.fromkeys(
            r.name for _, _, rules in reversed(chain) for r in rules
            if any(a.name == "StartRule" for a in r.annotations)))

    # -- lookups -----------------------------------------------------------------------------
    def resolve(self, qualified: str) -> tuple[Module, str] | None:
        """``"F.G.Rule"`` → (module of G, "Rule"); ``None`` if an alias is unknown.

        A dotted name whose prefix is no import names a declaration of that file made under
        the dotted name (``Lot.Green --> …``, ``attr Report.enabled = …``): it resolves to
        (that module, the whole remaining name)."""
        mod, parts = self, qualified.split(".")
        for i, alias in enumerate(parts[:-1]):
            nxt = mod.imports.get(alias)
            if nxt is None:
                rest = ".".join(parts[i:])
                return (mod, rest) if rest in mod.dotted else None
            mod = nxt
        return mod, parts[-1]

    def rule(self, name: str, arity: int) -> tuple[Module, A.RuleDef] | None:
        found = self.resolve(name) if "." in name else (self, name)
        if found is None:
            return None
        mod, short = found
        forward = self.rule_forwards.get(name) if "." not in name else None
        if forward is not None:  # only calls inside the file; imp.Ext keeps the default
            importer, target = forward
            return importer.rule(target, arity)
        redefined = mod.rule_overrides.get(short)
        if redefined is not None and arity in redefined:
            return redefined[arity]
        overloads = mod.rules.get(short)
        if overloads is None or arity not in overloads:
            return None
        return mod, overloads[arity]

    def has_rule_name(self, name: str) -> bool:
        found = self.resolve(name) if "." in name else (self, name)
        return found is not None and (found[1] in found[0].rules
                                      or found[1] in found[0].rule_overrides
                                      or found[1] in found[0].rule_forwards)

    def function(self, name: str, arity: int) -> tuple[Module, A.FuncDef] | None:
        found = self.resolve(name) if "." in name else (self, name)
        if found is None:
            return None
        mod, short = found
        f = mod.functions.get(short, {}).get(arity)
        return (mod, f) if f is not None else None

    def attr(self, name: str) -> tuple[Module, A.AttrDef] | None:
        found = self.resolve(name) if "." in name else (self, name)
        if found is None:
            return None
        mod, short = found
        a = mod.attrs.get(short)
        return (mod, a) if a is not None else None

    def propagated_from(self, name: str) -> tuple[Module, A.AttrDef] | None:
        """The importer's attribute that gives attribute ``name`` of this module its value
        (CityEngine propagates an importer's attribute to the same-named attribute of the
        file it imports unless the import statement protects it)."""
        imp = self.importer
        if imp is None or self.protect_all or name in self.protected:
            return None
        a = imp.attrs.get(name)
        return (imp, a) if a is not None and not a.const else None

    def all_modules(self):
        """This module and every module it imports, directly or not, each once."""
        seen, ids, stack = [], set(), [self]
        while stack:
            m = stack.pop()
            if id(m) in ids:
                continue
            ids.add(id(m))
            seen.append(m)
            stack.extend(m.imports.values())
            stack.extend(m.anonymous)
        return seen


class RuleSet:
    """A main module and everything it imports.

    Parameters
    ----------
    main : Module
    start_rule : str
        The rule derivation starts with (``@StartRule`` or the first rule unless overridden).
    asset_root : Path or None
        Folder against which relative asset paths resolve.
    """

    def __init__(self, main: Module, start_rule: str | None = None, asset_root=None,
                 resolver=None):
        self.main = main
        self.asset_root = Path(asset_root) if asset_root else None
        self.resolver = resolver
        if start_rule is None:
            if main.start_rules:
                start_rule = main.start_rules[0]
            elif main.rules:
                start_rule = next(iter(main.rules))
            else:
                raise RuleError("the rule file defines no rules", main.path)
        elif not main.has_rule_name(start_rule):
            raise RuleError(f"start rule '{start_rule}' is not defined{_did_you_mean(start_rule, main.rules)}",
                            main.path)
        self.start_rule = start_rule

    def parameter_ranges(self) -> dict:
        """Attributes an optimiser may vary: ``{name: (min, max)}`` of the ``@Range`` parameters
        (:func:`facadeforge.grammar.parameters.parameters_of`, seed simon2011 §4.1.1)."""
        from .parameters import parameters_of

        return {p.name: (p.lo, p.hi) for p in parameters_of(self, required=False)
                if not p.discrete}


def _did_you_mean(name: str, candidates) -> str:
    close = difflib.get_close_matches(name, list(candidates), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def _style_chain(rule_file: A.RuleFile, style: str) -> list[tuple[tuple, tuple, tuple]]:
    """``(attrs, functions, rules)`` of the Default style and of each style from the one
    ``style`` extends down to ``style`` itself, base first."""
    by_name = {sd.name: sd for sd in rule_file.styles}
    chain: list[A.StyleDef] = []
    name: str | None = style
    while name is not None and name != DEFAULT_STYLE:
        sd = by_name.get(name)
        if sd is None:
            known = ", ".join([DEFAULT_STYLE, *by_name])
            if not chain:
                raise RuleError(f"unknown style '{name}'; {Path(rule_file.path).name} defines "
                                f"{known}", rule_file.path)
            raise RuleError(f"style '{chain[-1].name}' extends unknown style '{name}'; "
                            f"defined: {known}", rule_file.path, chain[-1].line, chain[-1].column)
        if sd in chain:
            raise RuleError(f"style '{name}' extends itself (through "
                            f"{' → '.join(s.name for s in chain)})", rule_file.path, sd.line,
                            sd.column)
        chain.append(sd)
        name = sd.extends
    return ([(rule_file.attrs, rule_file.functions, rule_file.rules)]
            + [(sd.attrs, sd.functions, sd.rules) for sd in reversed(chain)])


def link(text: str, path: str, read: Callable[[str, str], tuple[str, str]] | None = None, *,
         style: str | None = None) -> Module:
    """Parse ``text`` and, through ``read(importer_path, import_path) -> (text, path)``, its
    imports; ``style`` selects a style of the main file.

    Each import statement is its own instance of the imported file (CityEngine's "import"
    keyword): ``import a : "x.cga" (h = 5)`` and ``import b : "x.cga" (h = 7)`` give two
    modules whose attributes, import-statement overrides and redefined rules are their own.
    A file is parsed once however often it is imported.  An imported file uses the style chosen
    for the main file when it has it (and its import statement lets it in), else the first
    style the statement lists (``import id (Style) : "x.cga"``), else its Default style."""
    main = Module(parse_rules(text, path), style=style)
    parsed: dict[str, A.RuleFile] = {}
    pending = [(main, (os.path.realpath(path),))]
    anonymous: list[tuple[Module, Module]] = []  # (importer, imported), importers first
    count = 1
    while pending:
        mod, chain = pending.pop()
        for imp in mod.ast.imports:
            if len(chain) > MAX_IMPORT_DEPTH:
                raise RuleError(f"imports nest deeper than {MAX_IMPORT_DEPTH} files", mod.path,
                                imp.line, imp.column)
            if read is None:
                raise RuleError(f"cannot import '{imp.path}' from rule text without a file",
                                mod.path, imp.line, imp.column)
            try:
                itext, ipath = read(mod.path, imp.path)
            except (OSError, KeyError) as e:
                raise RuleError(f"cannot import '{imp.path}': {e}; check the path relative to "
                                f"{Path(mod.path).name}", mod.path, imp.line, imp.column) from None
            key = os.path.realpath(ipath)
            if key in chain:
                cycle = " → ".join(Path(p).name for p in (*chain[chain.index(key):], key))
                raise RuleError(f"import cycle: {cycle}; a rule file cannot import itself",
                                mod.path, imp.line, imp.column)
            count += 1
            if count > MAX_MODULES:
                raise RuleError(f"more than {MAX_MODULES} imported rule files (each import "
                                f"statement is one); import shared files fewer times",
                                mod.path, imp.line, imp.column)
            ast = parsed.get(key)
            if ast is None:
                ast = parsed[key] = parse_rules(itext, ipath)
            name = f"{mod.name}.{imp.alias}" if mod.name and imp.alias else (imp.alias or mod.name)
            child = Module(ast, name, style=_imported_style(ast, imp, mod.path, main.style))
            pending.append((child, (*chain, key)))
            if imp.alias:
                if imp.alias in mod.imports:
                    raise RuleError(f"import id '{imp.alias}' is used twice; each import needs "
                                    "its own id", mod.path, imp.line, imp.column)
                mod.imports[imp.alias] = child
                child.importer = mod
                child.protect_all = imp.protect_all
                for item in imp.overrides:
                    if isinstance(item, A.RuleForward):  # ( Ext -> MyExt )
                        child.rule_forwards[item.name] = (mod, item.target)
                    elif isinstance(item, A.RuleDef):  # ( Roof(angle) --> roofGable(angle) )
                        child.rule_overrides.setdefault(item.name, {})[len(item.params)] = \
                            (mod, item)
                    elif item[1] is None:           # ( height ): protected
                        child.protected.add(item[0])
                    else:                           # ( height = 5 ): redefined
                        child.import_overrides[item[0]] = (mod, item[1])
            else:
                anonymous.append((mod, child))
                mod.anonymous.append(child)
                child.merged = True
    # an anonymous import's definitions join its importer's namespace (deepest first, so
    # those it took from its own anonymous imports come along)
    for into, m in reversed(anonymous):
        for k, v in m.attrs.items():
            into.attrs.setdefault(k, v)
        for k, v in m.functions.items():
            into.functions.setdefault(k, v)
        for k, v in m.rules.items():
            into.rules.setdefault(k, v)
        for k, v in m.imports.items():
            if into.imports.setdefault(k, v) is v and v.importer is m:
                v.importer = into  # m's attributes are into's now: propagation starts there
    _attach_qualified_rules(main)
    for into, m in reversed(anonymous):  # dotted rules of an anonymous import join it too
        for k in m.dotted:
            if k in m.rules:
                into.rules.setdefault(k, m.rules[k])
            into.dotted.add(k)
    return main


def _imported_style(ast: A.RuleFile, imp: A.Import, importer: str, chosen: str) -> str:
    """The style an imported file is derived in.  Its styles join the importer's (all of them,
    or those the import statement lists): the style chosen for the main file where the file
    has it and the statement lets it in, else the first style listed, else Default."""
    known = {DEFAULT_STYLE, *(sd.name for sd in ast.styles)}
    for s in imp.styles:
        if s not in known:
            raise RuleError(f"style '{s}' is not defined in {Path(ast.path).name} (it defines "
                            f"{', '.join(sorted(known))})", importer, imp.line, imp.column)
    if chosen in known and (not imp.styles or chosen in imp.styles):
        return chosen
    return imp.styles[0] if imp.styles else DEFAULT_STYLE


def _import_of(m: Module, qualified: str) -> tuple[Module, str] | None:
    """(imported module, short name) when every alias before the last dot of ``qualified`` is
    an import (``st.Facade``, ``st.win.Frame``), else ``None``."""
    mod, parts = m, qualified.split(".")
    for alias in parts[:-1]:
        mod = mod.imports.get(alias)
        if mod is None:
            return None
    return mod, parts[-1]


def _attach_qualified_rules(main: Module) -> None:
    """Dotted names in declarations, as CityEngine compiles them.

    * ``st.Facade --> …`` where ``st`` is an import redefines rule ``Facade`` of that import:
      calls of ``Facade`` inside st (and ``st.Facade`` outside) run the importer's rule
      (CityEngine's help, "Rule file import").
    * ``Lot.Green_tile --> …`` where ``Lot`` is no import is a rule of this file under the
      dotted name; ``Lot.Green_tile`` calls it.  Dotted attributes and functions
      (``attr Report.enabled = true``, ``Util.half(x) = x / 2``) are the same: declarations
      of this file under their dotted name.
    * An import's attribute or function cannot be redefined by a dotted declaration (CityEngine
      redefines an import's attribute in the import statement or through a same-named
      attribute of the importer): that is an error naming the way that works."""
    for m in main.all_modules():
        for qualified, overloads in m.qualified_rules.items():
            found = _import_of(m, qualified)
            if found is None:  # the prefix is no import: a rule of this file
                m.rules[qualified] = overloads
                m.dotted.add(qualified)
                continue
            target, short = found
            for arity, rdef in overloads.items():
                target.rule_overrides.setdefault(short, {})[arity] = (m, rdef)
        own_attrs = {a.name for a in m.own_declarations[0]}
        own_functions = {f.name for f in m.own_declarations[1]}
        for kind, names in (("attribute", [k for k in m.attrs if "." in k]),
                            ("function", [k for k in m.functions if "." in k])):
            for qualified in names:
                if kind == "attribute" and qualified not in own_attrs:
                    continue  # taken from an anonymous import: checked in its own file
                if kind == "function" and qualified not in own_functions:
                    continue
                found = _import_of(m, qualified)
                if found is None:
                    m.dotted.add(qualified)
                    continue
                node = (m.attrs[qualified] if kind == "attribute"
                        else next(iter(m.functions[qualified].values())))
                prefix, short = qualified.rsplit(".", 1)
                how = (f"import {prefix} : \"…\" ({short} = …), or an attribute '{short}' "
                       "of this file, which the import takes" if kind == "attribute" else
                       f"a rule, or an attribute of {prefix} that its function reads")
                raise RuleError(f"{kind} '{qualified}' redefines the {kind} '{short}' of the "
                                f"import '{prefix}', which CGA does not allow; use {how}",
                                m.path, node.line, node.column)
