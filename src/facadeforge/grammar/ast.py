"""Typed, frozen AST of the CGA language.  Every node carries its source position."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Node:
    line: int = field(default=0, kw_only=True, compare=False)
    column: int = field(default=0, kw_only=True, compare=False)


# ---- expressions ------------------------------------------------------------------------

@dataclass(frozen=True)
class Num(Node):
    value: float


@dataclass(frozen=True)
class Str(Node):
    value: str


@dataclass(frozen=True)
class Bool(Node):
    value: bool


@dataclass(frozen=True)
class Name(Node):
    """A variable, attribute or selector keyword; dotted names keep their dots (``scope.sx``)."""

    name: str


@dataclass(frozen=True)
class Call(Node):
    name: str
    args: tuple


@dataclass(frozen=True)
class CompFunction(Node):
    """``comp(f){ selector : value | … }``: an array with one value per component."""

    kind: Node
    branches: tuple  # Branch whose ``ops`` slot holds the value expression


@dataclass(frozen=True)
class Index(Node):
    target: Node
    indices: tuple


@dataclass(frozen=True)
class Colon(Node):
    """``start : stop`` or ``start : step : stop`` inside ``[ ]`` (CGA's colon operator)."""

    start: Node
    step: Node | None
    stop: Node


@dataclass(frozen=True)
class Array(Node):
    rows: tuple  # tuple of tuples of expressions; one row for 1-D arrays


@dataclass(frozen=True)
class Unary(Node):
    op: str  # "-", "!", ".!", "'", "~"
    operand: Node


@dataclass(frozen=True)
class Binary(Node):
    op: str
    left: Node
    right: Node


@dataclass(frozen=True)
class CaseExpr(Node):
    branches: tuple  # ((cond, value), ...)
    otherwise: Node


@dataclass(frozen=True)
class StochasticExpr(Node):
    branches: tuple  # ((percent, value), ...)
    otherwise: Node


# ---- operation sequences ----------------------------------------------------------------

@dataclass(frozen=True)
class Successor(Node):
    """``Name``, ``Name(args)`` or an operation call without a body (``extrude(10)``)."""

    name: str
    args: tuple
    has_parens: bool = False


@dataclass(frozen=True)
class Leaf(Node):
    """``Name.``: a terminal shape (no rule is applied)."""

    name: str


@dataclass(frozen=True)
class Branch(Node):
    selector: Node
    mode: str  # ":" one shape per part, "=" all matching parts as one shape, "=:" one per
    #            connected piece of them (CityEngine 2025.0)
    ops: tuple
    depth: Node | None = None  # ``length : depth : ops`` of splitAndSetbackPerimeter


@dataclass(frozen=True)
class RepeatGroup(Node):
    branches: tuple


@dataclass(frozen=True)
class BodyOp(Node):
    """An operation with a ``{ … }`` body: split, comp, setback…"""

    name: str
    args: tuple
    branches: tuple  # Branch | RepeatGroup
    repeat: bool


@dataclass(frozen=True)
class Inline(Node):
    """``inline(strategy) …``: derive ``ops`` now and merge the resulting shapes into the
    current one (strategy ``append``, ``unify`` or ``recompose``)."""

    strategy: str
    ops: tuple


@dataclass(frozen=True)
class Boolean(Node):
    """``union|subtract|intersect { opsA | opsB }``: a Boolean 3D operation on two inlined
    operands."""

    kind: str
    a: tuple
    b: tuple


@dataclass(frozen=True)
class Push(Node):
    ops: tuple


@dataclass(frozen=True)
class Nil(Node):
    pass


@dataclass(frozen=True)
class CaseOps(Node):
    branches: tuple  # ((cond, ops), ...)
    otherwise: tuple


@dataclass(frozen=True)
class StochasticOps(Node):
    branches: tuple  # ((percent, ops), ...)
    otherwise: tuple


# ---- declarations -----------------------------------------------------------------------

@dataclass(frozen=True)
class Annotation(Node):
    name: str  # without "@"
    args: tuple


@dataclass(frozen=True)
class Param(Node):
    name: str
    type: str | None = None


@dataclass(frozen=True)
class AttrDef(Node):
    name: str
    value: Node
    const: bool = False
    type: str | None = None
    annotations: tuple = ()


@dataclass(frozen=True)
class FuncDef(Node):
    name: str
    params: tuple
    body: Node
    annotations: tuple = ()


@dataclass(frozen=True)
class RuleDef(Node):
    name: str
    params: tuple
    body: tuple  # operations
    annotations: tuple = ()


@dataclass(frozen=True)
class Import(Node):
    """``import alias [( styles )] : "path" [( overrides )]`` (CityEngine's import keyword).

    ``overrides`` holds ``(attr, None)`` (protected from propagation), ``(attr, expression)``
    (redefined, evaluated in the importer), ``RuleDef`` (an extension rule redefined) and
    ``RuleForward`` (an extension rule sent to a rule of the importer);
    ``protect_all`` is an empty ``()``; ``styles`` limits the imported styles."""

    alias: str | None
    path: str
    overrides: tuple = ()
    annotations: tuple = ()
    styles: tuple = ()
    protect_all: bool = False


@dataclass(frozen=True)
class RuleForward(Node):
    """``import imp : "imp.cga" ( Ext -> MyExt )``: calls of the extension rule ``Ext`` inside
    the imported file run the importer's rule ``MyExt`` (CityEngine 2024.0); ``imp.Ext`` from
    the importer still runs the file's own ``Ext``."""

    name: str
    target: str


@dataclass(frozen=True)
class StyleDef(Node):
    """``style Name [extends Base]`` and the attributes, functions and rules declared after it
    (until the next ``style``): they replace the base style's same-named declarations."""

    name: str
    extends: str | None = None
    attrs: tuple = ()
    functions: tuple = ()
    rules: tuple = ()
    annotations: tuple = ()


@dataclass(frozen=True)
class RuleFile(Node):
    path: str
    version: str | None
    imports: tuple
    attrs: tuple
    functions: tuple
    rules: tuple
    styles: tuple = ()  # StyleDef, in file order; the declarations above are the Default style
