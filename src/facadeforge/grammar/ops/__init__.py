"""Operation registry: one small function per CGA operation (ShapeML habit).

An operation is registered with its name, argument count range and which argument positions are
selector keywords (``split(x)``, ``offset(-1, inside)``).  The interpreter validates the call, then
hands the op an ``OpCall`` holding the evaluated arguments and the current shape state.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import import_module

from ..values import CGARuntimeError, Floating, Relative, to_float, to_str


@dataclass(frozen=True)
class OpSpec:
    name: str
    fn: Callable
    min_args: int
    max_args: int
    selectors: frozenset = field(default_factory=frozenset)
    body: bool = False
    names: frozenset = field(default_factory=frozenset)  # positions taking a bare name (set)
    selector_min_args: int = 0  # selectors only when called with at least this many arguments
    keeps_shape: bool = False  # a body operation whose shape goes on (``modify``), not a split

    def selector_positions(self, n_args: int) -> frozenset:
        return self.selectors if n_args >= self.selector_min_args else self.names


OPERATIONS: dict[str, OpSpec] = {}


#: Operations that may be written without parentheses (Esri's own rules write
#: ``primitiveQuad``); other bare lower-case names stay rule calls or leaves (``trim``, ``tag``).
BARE_OPERATIONS: frozenset[str] = frozenset({
    "primitiveCube", "primitiveQuad", "primitiveCylinder", "primitiveCone", "primitiveDisk",
    "primitiveSphere", "reverseNormals", "convexify"})


def operation_of(op, module) -> OpSpec | None:
    """The operation a successor ``op`` calls, or ``None`` when it calls a rule: a name with
    parentheses, or a bare name of :data:`BARE_OPERATIONS` (``primitiveQuad`` for
    ``primitiveQuad()``), unless ``module`` defines a rule of that name."""
    spec = OPERATIONS.get(op.name)
    if spec is None or module.has_rule_name(op.name):
        return None
    if not getattr(op, "has_parens", False) and op.name not in BARE_OPERATIONS:
        return None
    return spec

# functions that read the current shape (``geometry.area``, ``fileExists``…): name -> fn(env, args)
SHAPE_FUNCTIONS: dict[str, Callable] = {}


def shape_function(name: str):
    def deco(fn):
        SHAPE_FUNCTIONS[name] = fn
        return fn
    return deco


def operation(name: str, min_args: int = 0, max_args: int | None = None, selectors=(),
              body: bool = False, names=(), selector_min_args: int = 0, keeps_shape: bool = False):
    def deco(fn):
        OPERATIONS[name] = OpSpec(name, fn, min_args, min_args if max_args is None else max_args,
                                  frozenset(selectors) | frozenset(names), body,
                                  frozenset(names), selector_min_args, keeps_shape)
        return fn
    return deco


@dataclass
class OpCall:
    """What an operation receives."""

    name: str
    args: list
    state: object  # ShapeState
    derivation: object  # Derivation (assets, warnings, reports)
    env: object  # Env (to evaluate split sizes lazily, read attributes)
    branches: tuple = ()
    repeat: bool = False

    def tick(self) -> None:
        """Draw on the derivation's time and memory budget (long geometry kernels call it)."""
        if self.derivation is not None:
            self.derivation.budget.check("operation", self.name)

    def num(self, i: int, default: float | None = None) -> float:
        if i >= len(self.args):
            if default is None:
                raise CGARuntimeError(f"{self.name}: argument {i + 1} is missing")
            return default
        v = to_float(self.args[i], f"{self.name} argument {i + 1}")
        if v != v or v in (float("inf"), float("-inf")):
            raise CGARuntimeError(f"{self.name}: argument {i + 1} is {v} (a string that is not a "
                                  "number, or a division by zero?); the shape is left as it was")
        return v

    def size(self, i: int, current: float, default: float | None = None) -> float:
        """A size argument: number, ``'relative`` (× current) or ``~float`` (taken as is)."""
        if i >= len(self.args):
            if default is None:
                raise CGARuntimeError(f"{self.name}: argument {i + 1} is missing")
            return default
        v = self.args[i]
        if isinstance(v, Relative):
            return v.value * current
        if isinstance(v, Floating):
            return v.value
        return to_float(v, f"{self.name} argument {i + 1}")

    def text(self, i: int, default: str | None = None) -> str:
        if i >= len(self.args):
            if default is None:
                raise CGARuntimeError(f"{self.name}: argument {i + 1} is missing")
            return default
        return to_str(self.args[i])

    def sel(self, i: int, default: str | None = None) -> str:
        return self.text(i, default)


def load_all() -> dict[str, OpSpec]:
    """Import every op module so that their decorators register them."""
    from . import (  # noqa: F401
        alonguv,
        appearance,
        cleanup,
        extra,
        geometry,
        inlining,
        materials,
        meta,
        modifying,
        occlusion,
        perimeter,
        queries,
        roofs,
        scoping,
        subdivision,
        tagging,
        transform,
        trimming,
    )
    # last: it registers only the CityEngine operations no module above implements
    import_module(f"{__package__}.unsupported")

    return OPERATIONS
