"""The parameters of a rule file an optimiser may vary (seed ``simon2011`` §4.1.1).

In our CGA dialect an attribute annotated ``@Range(lo, hi[, step])`` is a continuous parameter
(stepped: a count), ``@Enum(a, b, …)`` a discrete one (a rule choice).  Grammar-driven parsing
(:mod:`facadeforge.parsing`) searches over them; :meth:`RuleSet.parameter_ranges` lists the
ranges.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import RuleError
from . import ast as A
from .values import to_float

__all__ = ["Parameter", "ParameterError", "parameters_of"]


class ParameterError(RuleError):
    """A ``@Range``/``@Enum`` annotation that does not describe a parameter."""


@dataclass(frozen=True)
class Parameter:
    """One degree of freedom: a ``@Range`` (``lo``, ``hi``, ``step``) or ``@Enum`` (``choices``)."""

    name: str
    default: Any
    lo: float = 0.0
    hi: float = 0.0
    step: float = 0.0
    choices: tuple = ()

    @property
    def discrete(self) -> bool:
        return bool(self.choices)

    def clip(self, v: float) -> float:
        v = min(max(v, self.lo), self.hi)
        if self.step > 0:
            v = self.lo + round((v - self.lo) / self.step) * self.step
        return float(v)


def _literal(node) -> Any:
    if isinstance(node, A.Num):
        return float(node.value)
    if isinstance(node, A.Str | A.Bool):
        return node.value
    if isinstance(node, A.Unary) and node.op == "-" and isinstance(node.operand, A.Num):
        return -float(node.operand.value)
    raise ParameterError(f"line {node.line}: @Range/@Enum arguments must be literals")


def parameters_of(rules, *, required: bool = True) -> list[Parameter]:
    """The ``@Range``/``@Enum`` attributes of loaded rules (or a rule set), in declaration order;
    ``required``: raise when there are none."""
    ruleset = getattr(rules, "ruleset", rules)
    params = []
    for adef in ruleset.main.attrs.values():
        ann = {a.name: a for a in adef.annotations}
        if adef.const or not ({"Range", "Enum"} & ann.keys()):
            continue
        default = _literal(adef.value) if isinstance(adef.value, A.Num | A.Str | A.Bool | A.Unary
                                                     ) else None
        if "Enum" in ann:
            choices = tuple(_literal(a) for a in ann["Enum"].args)
            if len(choices) < 2:
                raise ParameterError(f"attr {adef.name}: @Enum needs two or more choices")
            params.append(Parameter(adef.name, default if default in choices else choices[0],
                                    choices=choices))
            continue
        args = [to_float(_literal(a)) for a in ann["Range"].args]
        if len(args) < 2 or not args[0] < args[1]:
            raise ParameterError(f"attr {adef.name}: @Range(lo, hi[, step]) needs lo < hi")
        p = Parameter(adef.name, None, args[0], args[1], args[2] if len(args) > 2 else 0.0)
        d = p.clip(float(default)) if isinstance(default, float) else p.clip((p.lo + p.hi) / 2)
        params.append(Parameter(p.name, d, p.lo, p.hi, p.step))
    if not params and required:
        raise ParameterError("the rules have no @Range or @Enum attributes to fit")
    return params
