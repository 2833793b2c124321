"""Parse CGA text into the typed AST (``ast.py``) with Lark; syntax errors become ``RuleSyntaxError``."""

from __future__ import annotations

import functools
import hashlib
import re
import sys
from dataclasses import dataclass
from importlib import resources

import lark
from lark import Lark, Token, Transformer, v_args
from lark.exceptions import (
    LarkError,
    UnexpectedCharacters,
    UnexpectedEOF,
    UnexpectedInput,
    VisitError,
)

from ..errors import RuleSyntaxError
from ..user_cache import private_folder
from . import ast as A

MAX_SOURCE_BYTES = 8 * 1024 * 1024  # a rule file larger than this is not a rule file
#: Tokens of one rule file.  Lark spends 25-120 µs a token (an array element passes ten
#: grammar levels), so this bounds a parse to seconds; the largest real rule files we know
#: (Esri's Candler Building, reconstructions of wide facades) hold 3,000-15,000 tokens.
MAX_TOKENS = 250_000
#: Brackets ``( [ {`` open at once.  Real rules nest a handful; every level costs Lark's tree
#: and our checker stack frames.
MAX_BRACKETS = 100
#: Depth of the expression and operation tree (a sum of 1,000 terms is 1,000 deep).
MAX_NESTING = 2_000
#: The style of the declarations before any ``style`` line (CityEngine's name for it).
DEFAULT_STYLE = "Default"


@functools.lru_cache(maxsize=1)
def _parser() -> Lark:
    """The CGA parser.  Building its LALR tables takes about a second, which every command
    would pay, so Lark keeps them in the user's private cache folder, keyed by the grammar's
    hash, Lark's and Python's versions (Lark checks the hash again and rebuilds a stale, foreign
    or broken file)."""
    text = resources.files(__package__).joinpath("cga.lark").read_text(encoding="utf-8")
    folder = private_folder("parser")
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    cache = (str(folder / f"cga-{digest}-lark{lark.__version__}-py{sys.version_info[0]}"
                          f"{sys.version_info[1]}.pickle") if folder else False)
    return Lark(text, parser="lalr", propagate_positions=True, maybe_placeholders=True,
                cache=cache, postlex=_Bounds())


class _Bounds:
    """Lark post-lexer that stops a rule file with more than :data:`MAX_TOKENS` tokens or
    :data:`MAX_BRACKETS` open brackets, at the token where it happens (a ``_SourceError``)."""

    always_accept = ()
    _OPEN = frozenset(("LPAR", "LSQB", "LBRACE"))
    _CLOSE = frozenset(("RPAR", "RSQB", "RBRACE"))

    def process(self, stream):
        depth = 0
        for n, tok in enumerate(stream):
            if n >= MAX_TOKENS:
                raise _SourceError(f"the rule file has more than {MAX_TOKENS:,} tokens; split it "
                                   "into files that import each other", tok)
            t = tok.type
            if t in self._OPEN:
                depth += 1
                if depth > MAX_BRACKETS:
                    raise _SourceError(f"brackets nest deeper than {MAX_BRACKETS} levels here",
                                       tok)
            elif t in self._CLOSE:
                depth -= 1
            yield tok


def _deepest(items) -> tuple[int, object]:
    """The depth of the deepest AST node below ``items`` and that node, walked without
    recursion (the tree may be deeper than Python's stack)."""
    best, where = 0, None
    stack = [(x, 1) for x in items]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, tuple | list):
            stack.extend((x, depth) for x in node)
        elif isinstance(node, A.Node):
            if depth > best:
                best, where = depth, node
            stack.extend((getattr(node, f), depth + 1) for f in node.__dataclass_fields__
                         if f not in ("line", "column"))
    return best, where


def _pos(meta_or_token) -> dict:
    line = getattr(meta_or_token, "line", 0) or 0
    col = getattr(meta_or_token, "column", 0) or 0
    return {"line": line, "column": col}


_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", '"': '"', "\\": "\\", "'": "'"}


def _unquote(tok: str) -> str:
    body = tok[1:-1]
    return re.sub(r"\\(.)", lambda m: _ESCAPES.get(m.group(1), m.group(1)), body)


def _percent(tok: str) -> float:
    return float(tok.rstrip().rstrip("%").strip())


class _SourceError(ValueError):
    """A construct that parses but is not valid CGA; becomes a ``RuleSyntaxError`` with its
    position."""

    def __init__(self, message: str, meta):
        super().__init__(message)
        self.line, self.column = _pos(meta)["line"], _pos(meta)["column"]


@dataclass(frozen=True)
class _Group:
    """``{ … }`` inside a split body without ``*``: inlined by :meth:`_ToAst.body`."""

    branches: tuple


@v_args(meta=True)
class _ToAst(Transformer):
    # -- expressions --
    def number(self, meta, c):
        return A.Num(float(c[0]), **_pos(meta))

    def string(self, meta, c):
        return A.Str(_unquote(str(c[0])), **_pos(meta))

    def true(self, meta, c):
        return A.Bool(True, **_pos(meta))

    def false(self, meta, c):
        return A.Bool(False, **_pos(meta))

    def name(self, meta, c):
        return A.Name(str(c[0]), **_pos(meta))

    def call(self, meta, c):
        args = tuple(a for a in c[1:] if a is not None)
        return A.Call(str(c[0]), args, **_pos(meta))

    def comp_fn(self, meta, c):
        name = str(c[0])
        args = [a for a in c[1:] if a is not None and not isinstance(a, A.Branch)]
        branches = tuple(a for a in c[1:] if isinstance(a, A.Branch))
        if name != "comp" or len(args) != 1:
            raise ValueError("only comp(f|e|v){ selector : value | … } has a { } body in an expression")
        return A.CompFunction(args[0], branches, **_pos(meta))

    def fn_each(self, meta, c):
        return A.Branch(c[0], ":", c[1], **_pos(meta))

    def fn_all(self, meta, c):
        return A.Branch(c[0], "=", c[1], **_pos(meta))

    def fn_connected(self, meta, c):
        return A.Branch(c[0], "=:", c[1], **_pos(meta))

    def index(self, meta, c):
        return A.Index(c[0], tuple(c[1:]), **_pos(meta))

    def array(self, meta, c):
        rows = c[0] if c and c[0] is not None else ()
        return A.Array(tuple(rows), **_pos(meta))

    def array_rows(self, meta, c):
        return tuple(c)

    def array_row(self, meta, c):
        return tuple(c)

    def _fold(self, meta, c, default_op=None):
        if len(c) == 1:
            return c[0]
        node = c[0]
        i = 1
        while i < len(c):
            if isinstance(c[i], Token):
                op, rhs = str(c[i]), c[i + 1]
                i += 2
            else:
                op, rhs = default_op, c[i]
                i += 1
            node = A.Binary(op, node, rhs, **_pos(meta))
        return node

    def or_(self, meta, c):
        return self._fold(meta, c, "||")

    def and_(self, meta, c):
        return self._fold(meta, c, "&&")

    def compare(self, meta, c):
        return self._fold(meta, c)

    def arith(self, meta, c):
        return self._fold(meta, c)

    def power(self, meta, c):
        return c[0] if len(c) == 1 else A.Binary(str(c[1]), c[0], c[2], **_pos(meta))

    def element_not(self, meta, c):
        return A.Unary(".!", c[0], **_pos(meta))

    def colon(self, meta, c):
        start, *rest = c
        step, stop = (rest[0], rest[1]) if len(rest) == 2 else (None, rest[0])
        return A.Colon(start, step, stop, **_pos(meta))

    def neg(self, meta, c):
        if isinstance(c[0], A.Num):
            return A.Num(-c[0].value, **_pos(meta))
        return A.Unary("-", c[0], **_pos(meta))

    def not_(self, meta, c):
        return A.Unary("!", c[0], **_pos(meta))

    def relative(self, meta, c):
        return A.Unary("'", c[0], **_pos(meta))

    def floating(self, meta, c):
        return A.Unary("~", c[0], **_pos(meta))

    def unary_expr(self, meta, c):  # unary plus
        return c[0]

    def case_expr(self, meta, c):
        pairs = tuple((c[i], c[i + 1]) for i in range(0, len(c) - 1, 2))
        return A.CaseExpr(pairs, c[-1], **_pos(meta))

    def stochastic_expr(self, meta, c):
        pairs = tuple((_percent(c[i]), c[i + 1]) for i in range(0, len(c) - 1, 2))
        return A.StochasticExpr(pairs, c[-1], **_pos(meta))

    # -- operations --
    def args(self, meta, c):
        return tuple(a for a in c if a is not None)

    def successor(self, meta, c):
        has = len(c) > 1 and c[1] is not None
        return A.Successor(str(c[0]), c[1] if has else (), has, **_pos(meta))

    def leaf(self, meta, c):
        return A.Leaf(str(c[0]), **_pos(meta))

    def nil(self, meta, c):
        return A.Nil(**_pos(meta))

    def push(self, meta, c):
        return A.Push(c[0], **_pos(meta))

    def ops(self, meta, c):
        return tuple(c)

    def ops_single(self, meta, c):
        return (c[0],)

    def body_op(self, meta, c):
        repeat = len(c) > 3 and c[3] is not None
        name, args = str(c[0]), tuple(c[1] or ())
        if name == "setbackPerEdge" and args:
            # CityEngine documents it as a shortcut: setback(comp(fe){ all : distance }){ … },
            # the distance evaluated on each face edge in turn
            pos = _pos(meta)
            per_edge = A.CompFunction(A.Name("fe", **pos),
                                      (A.Branch(A.Name("all", **pos), ":", args[0], **pos),), **pos)
            name, args = "setback", (per_edge, *args[1:])
        return A.BodyOp(name, args, c[2], repeat, **_pos(meta))

    def inline_op(self, meta, c):
        args = c[1] if len(c) > 2 else ()
        target = c[-1]
        ops = target if isinstance(target, tuple) else (target,)
        strategy = "append"
        if args:
            if len(args) != 1 or not isinstance(args[0], A.Name):
                raise _SourceError("inline takes one merge strategy: inline(append), "
                                   "inline(unify) or inline(recompose)", meta)
            strategy = args[0].name
        if strategy not in ("append", "unify", "recompose"):
            raise _SourceError(f"unknown inline merge strategy '{strategy}'; use append, unify "
                               "or recompose", meta)
        return A.Inline(strategy, ops, **_pos(meta))

    def bool_op(self, meta, c):
        return A.Boolean(str(c[0]), c[1], c[2], **_pos(meta))

    def bool_rule_op(self, meta, c):
        # CityEngine before 2025.0: ``subtract Rule`` (the current shape is operand A) and
        # ``subtract(swap) Rule`` (it is operand B); the same as the braced form with a leaf
        args = c[1] if len(c) == 3 else ()
        swap = len(args) == 1 and isinstance(args[0], A.Name) and args[0].name == "swap"
        if args and not swap:
            raise _SourceError(f"{c[0]}(…) Rule takes only 'swap'", meta)
        current = (A.Leaf("Operand", **_pos(meta)),)
        rule = (c[-1],)
        a, b = (rule, current) if swap else (current, rule)
        return A.Boolean(str(c[0]), a, b, **_pos(meta))

    def scatter_op(self, meta, c):
        # ``scatter(...){ ops }``: one implicit branch for every scattered point
        branch = A.Branch(A.Name("all", **_pos(meta)), ":", c[1], **_pos(meta))
        return A.BodyOp("scatter", c[0] or (), (branch,), False, **_pos(meta))

    def body(self, meta, c):
        out = []
        for item in c:      # a group without "*" is its branches, once (CityEngine accepts it)
            out.extend(item.branches if isinstance(item, _Group) else (item,))
        return tuple(out)

    def nested_group(self, meta, c):
        return _Group(c[0])

    def branch_each(self, meta, c):
        return A.Branch(c[0], ":", c[1], **_pos(meta))

    def branch_all(self, meta, c):
        return A.Branch(c[0], "=", c[1], **_pos(meta))

    def branch_connected(self, meta, c):
        return A.Branch(c[0], "=:", c[1], **_pos(meta))

    def perimeter_op(self, meta, c):
        # ``splitAndSetbackPerimeter(…){ length : depth : ops | … }[*] { remainder : ops }``:
        # one branch list, the remainder body last
        branches = tuple(c[1]) + tuple(c[3] or ())
        return A.BodyOp("splitAndSetbackPerimeter", tuple(c[0] or ()), branches, c[2] is not None,
                        **_pos(meta))

    def perimeter_body(self, meta, c):
        return tuple(c)

    def perimeter_branch(self, meta, c):
        return A.Branch(c[0], ":", c[2], depth=c[1], **_pos(meta))

    def nested_repeat(self, meta, c):
        return A.RepeatGroup(c[0], **_pos(meta))

    def case_ops(self, meta, c):
        pairs = tuple((c[i], c[i + 1]) for i in range(0, len(c) - 1, 2))
        return A.CaseOps(pairs, c[-1], **_pos(meta))

    def stochastic_ops(self, meta, c):
        pairs = tuple((_percent(c[i]), c[i + 1]) for i in range(0, len(c) - 1, 2))
        return A.StochasticOps(pairs, c[-1], **_pos(meta))

    def rule_body(self, meta, c):
        return c[0]

    # -- declarations --
    def annotation(self, meta, c):
        text = str(c[0])
        name, _, raw = text[1:].partition("(")
        args = _annotation_args(raw[:-1]) if raw else ()
        return A.Annotation(name.strip(), args, **_pos(meta))

    def param(self, meta, c):
        if len(c) == 2:
            return A.Param(str(c[1]), str(c[0]) if c[0] is not None else None, **_pos(meta))
        return A.Param(str(c[0]), **_pos(meta))

    def params(self, meta, c):
        return tuple(p for p in c if p is not None)

    def decl_name(self, meta, c):
        return c[0] if isinstance(c[0], tuple) else (None, str(c[0]))

    def typed_name(self, meta, c):
        return (str(c[0]), str(c[1]))

    def attr_def(self, meta, c):
        typ, name = c[0]
        return A.AttrDef(name, c[1], False, typ, **_pos(meta))

    def const_def(self, meta, c):
        typ, name = c[0]
        return A.AttrDef(name, c[1], True, typ, **_pos(meta))

    def func_def(self, meta, c):
        params = c[1] if len(c) == 3 else ()
        return A.FuncDef(str(c[0]), params or (), c[-1], **_pos(meta))

    def rule_def(self, meta, c):
        c = [x for x in c if not (isinstance(x, Token) and x.type == "EXTENSION")]
        params = c[1] if len(c) == 3 else ()
        return A.RuleDef(str(c[0]), params or (), c[-1], **_pos(meta))

    def style_def(self, meta, c):
        return A.StyleDef(str(c[0]), str(c[1]) if len(c) > 1 else None, **_pos(meta))

    def annotated(self, meta, c):
        *anns, decl = c
        if decl is None:
            return None
        return type(decl)(**{**decl.__dict__, "annotations": tuple(anns)})

    def version(self, meta, c):
        return ("version", _unquote(str(c[0])))

    def import_stmt(self, meta, c):
        # import id [( style, … )] : "file.cga" [( attr | attr = expr | Ext --> ops, … )]
        styles = c[1] if len(c) > 1 and isinstance(c[1], list) else []
        rest = c[2:] if styles else c[1:]
        overrides = tuple(rest[1]) if len(rest) > 1 else ()
        return A.Import(str(c[0]), _unquote(str(rest[0])), overrides, styles=tuple(styles),
                        protect_all=len(rest) > 1 and not overrides, **_pos(meta))

    def import_styles(self, meta, c):
        return [str(x) for x in c]

    def import_override(self, meta, c):
        return (str(c[0]), c[1] if len(c) > 1 else None)

    def import_rule_override(self, meta, c):
        # ``import F : "f.cga" ( Roof(angle) --> roofGable(angle) )``: an extension rule of the
        # imported file redefined by the importer
        params = c[1] if len(c) == 3 else ()
        return A.RuleDef(str(c[0]), params or (), c[-1], **_pos(meta))

    def import_rule_forward(self, meta, c):
        return A.RuleForward(str(c[0]), str(c[1]), **_pos(meta))

    def import_anon(self, meta, c):
        return A.Import(None, _unquote(str(c[0])), (), **_pos(meta))

    def import_overrides(self, meta, c):
        return tuple(x for x in c if x is not None)


def _split_top(text: str) -> list[str]:
    """Split annotation arguments at top-level commas (not inside quotes or parentheses)."""
    parts, depth, quote, cur = [], 0, False, []
    for i, ch in enumerate(text):
        if ch == '"' and (i == 0 or text[i - 1] != "\\"):
            quote = not quote
        elif not quote and ch == "(":
            depth += 1
        elif not quote and ch == ")":
            depth -= 1
        elif not quote and depth == 0 and ch == ",":
            parts.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    if "".join(cur).strip():
        parts.append("".join(cur))
    return parts


def _annotation_args(raw: str) -> tuple:
    """Annotation arguments: expressions where they parse (``@Range(min=1, max=10)``, ``@Enum("a",
    "b")``), the raw text otherwise (``@Handle(shape=Post*, axis=x)``)."""
    out = []
    for part in _split_top(raw):
        value = part.split("=", 1)[1] if re.match(r"\s*[A-Za-z_]\w*\s*=[^=]", part) else part
        try:
            tree = _parser().parse(f"const __v = {value.strip()}\n")
            out.append(_ToAst().transform(tree).children[0].value)
        except (LarkError, VisitError, ValueError):
            out.append(A.Str(value.strip()))
    return tuple(out)


def parse_rules(text: str, path: str = "<rules>") -> A.RuleFile:
    """Parse CGA source.

    Parameters
    ----------
    text : str
        The rule file's content.
    path : str
        Shown in error messages.

    Raises
    ------
    RuleSyntaxError
        With file:line:col, the offending source line and a caret.  It is the only exception this
        function raises for any text.
    """
    if not isinstance(text, str):
        raise RuleSyntaxError("rule text must be a str", path)
    if len(text) > MAX_SOURCE_BYTES:
        raise RuleSyntaxError(f"rule file is larger than {MAX_SOURCE_BYTES} bytes", path)
    if text.startswith("\ufeff"):  # a UTF-8 byte-order mark, as Windows editors write it
        text = text[1:]
    lines = text.splitlines()

    def located(x) -> RuleSyntaxError:
        src = lines[x.line - 1] if 0 < x.line <= len(lines) else ""
        return RuleSyntaxError(str(x), path, x.line, x.column, src)

    from .interpreter import deriving  # the raised recursion limit: trees MAX_NESTING deep

    try:
        with deriving():
            tree = _parser().parse(text)
            items = _ToAst().transform(tree).children
    except _SourceError as e:
        raise located(e) from None
    except UnexpectedInput as e:
        line, col = getattr(e, "line", 0) or 0, getattr(e, "column", 0) or 0
        src = lines[line - 1] if 0 < line <= len(lines) else ""
        raise RuleSyntaxError(_describe(e), path, line, col, src) from None
    except VisitError as e:
        if isinstance(e.orig_exc, _SourceError):
            raise located(e.orig_exc) from None
        raise RuleSyntaxError(f"cannot parse rules: {type(e).__name__}", path) from None
    except (LarkError, RecursionError, ValueError) as e:
        raise RuleSyntaxError(f"cannot parse rules: {type(e).__name__}", path) from None
    depth, node = _deepest(items)
    if depth > MAX_NESTING:
        x = _SourceError(f"expressions and operations nest {depth:,} levels deep here, more "
                         f"than {MAX_NESTING:,}; split the expression with functions", node)
        raise located(x) from None
    version, imports = None, []
    sections: list[tuple[A.StyleDef | None, list, list, list]] = [(None, [], [], [])]
    for item in items:
        if item is None:
            continue
        if isinstance(item, tuple) and item[0] == "version":
            version = item[1]
        elif isinstance(item, A.Import):
            imports.append(item)
        elif isinstance(item, A.StyleDef):
            if any(sd is not None and sd.name == item.name for sd, *_ in sections) \
                    or item.name == DEFAULT_STYLE:
                raise RuleSyntaxError(f"style '{item.name}' is declared twice", path,
                                      item.line, item.column)
            sections.append((item, [], [], []))
        elif isinstance(item, A.AttrDef):
            sections[-1][1].append(item)
        elif isinstance(item, A.FuncDef):
            sections[-1][2].append(item)
        elif isinstance(item, A.RuleDef):
            sections[-1][3].append(item)
    _, attrs, funcs, rules = sections[0]
    styles = tuple(A.StyleDef(sd.name, sd.extends, tuple(a), tuple(f), tuple(r),
                              line=sd.line, column=sd.column)
                   for sd, a, f, r in sections[1:])
    return A.RuleFile(path, version, tuple(imports), tuple(attrs), tuple(funcs), tuple(rules),
                      styles)


_TOKEN_WORDS = {
    "RULE_HEAD": "a rule definition", "FUNC_HEAD": "a function definition", "NAME": "a name",
    "QNAME": "a dotted name", "NUMBER": "a number", "STRING": "a string", "PERCENT": "a percentage",
    "LPAR": "'('", "RPAR": "')'", "LBRACE": "'{'", "RBRACE": "'}'", "LSQB": "'['", "RSQB": "']'",
    "COLON": "':'", "COMMA": "','", "VBAR": "'|'", "EQUAL": "'='", "ELSE": "'else'",
    "__ANON_0": "'-->'", "_CONNECTED": "'=:'",
}


def _describe(e: UnexpectedInput) -> str:
    if isinstance(e, UnexpectedEOF):
        return "unexpected end of file (an unclosed '(', '{' or '[', or a case without else?)"
    if isinstance(e, UnexpectedCharacters):
        return f"unexpected character {e.char!r}"
    tok = getattr(e, "token", None)
    expected = sorted(getattr(e, "expected", None) or [])
    words = sorted({_TOKEN_WORDS.get(x, x.lower().strip("_")) for x in expected})[:6]
    got = "end of file" if tok is None or tok.type == "$END" else repr(str(tok))
    hint = ""
    if tok is not None and str(tok) == "-->":
        hint = " (a rule name must start a new definition)"
    return f"unexpected {got}" + (f"; expected {', '.join(words)}" if words else "") + hint
