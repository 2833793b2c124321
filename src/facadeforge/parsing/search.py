"""The procedural space of a parse grammar and the hill-climbing search of ``simon2011`` §4.2.

§4.1.1 turns a grammar into a fixed-dimensional space: one rule per symbol, consistent
derivation, so a layout is a vector of parameters.  In our CGA dialect those parameters are the
attributes annotated ``@Range(lo, hi[, step])`` (continuous, or stepped: integers for counts) and
``@Enum(a, b, …)`` (a discrete rule choice, e.g. whether floors carry running balconies) — the
parameter-range extension of the engine.  The reserved attribute ``facadeWidth`` is the photo's
width in metres: the scale is searched like any other parameter, so grammar sizes stay in metres.

:func:`hill_climb` is Algorithm 4.1: from a seed, draw ``k`` perturbations of every parameter
(eq. 4.8, Gaussian with σ a fraction of the range; enums flip with probability σ), keep the best
if it lowers the energy, and shrink σ geometrically from exploration to exploitation (the
"exploitation–exploration trade-off" the thesis describes).  Improvement over the thesis: the
expert seed competes with a few random layouts drawn first (Latin-hypercube), since a seed far
off in scale traps a local search.  Everything is seeded; the budget counts derivations.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ..grammar import ast as A
from ..grammar.values import to_float
from .layout import ParseGrammarError

__all__ = ["Parameter", "SearchResult", "hill_climb", "parameters_of"]


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
    raise ParseGrammarError(f"line {node.line}: @Range/@Enum arguments must be literals")


def parameters_of(rules) -> list[Parameter]:
    """The searchable attributes of a loaded parse grammar, in declaration order."""
    params = []
    for adef in rules.ruleset.main.ast.attrs:
        ann = {a.name: a for a in adef.annotations}
        if adef.const or not ({"Range", "Enum"} & ann.keys()):
            continue
        default = _literal(adef.value) if isinstance(adef.value, A.Num | A.Str | A.Bool | A.Unary
                                                     ) else None
        if "Enum" in ann:
            choices = tuple(_literal(a) for a in ann["Enum"].args)
            if len(choices) < 2:
                raise ParseGrammarError(f"attr {adef.name}: @Enum needs two or more choices")
            params.append(Parameter(adef.name, default if default in choices else choices[0],
                                    choices=choices))
            continue
        args = [to_float(_literal(a)) for a in ann["Range"].args]
        if len(args) < 2 or not args[0] < args[1]:
            raise ParseGrammarError(f"attr {adef.name}: @Range(lo, hi[, step]) needs lo < hi")
        p = Parameter(adef.name, None, args[0], args[1], args[2] if len(args) > 2 else 0.0)
        d = p.clip(float(default)) if isinstance(default, float) else p.clip((p.lo + p.hi) / 2)
        params.append(Parameter(p.name, d, p.lo, p.hi, p.step))
    if not params:
        raise ParseGrammarError("the parse grammar has no @Range or @Enum attributes to fit")
    return params


@dataclass
class SearchResult:
    """Best parameters found, their energy, and the search's trace."""

    attrs: dict[str, Any]
    energy: float
    derivations: int
    seconds: float
    #: best energy after each derivation (a monotone curve, Fig. 5.8 style)
    curve: list[float] = field(default_factory=list)
    method: str = "hill"


class Objective:
    """Counts derivations, keeps the best-so-far curve, enforces the budget."""

    def __init__(self, fn: Callable[[Mapping[str, Any]], float], budget: int):
        if budget < 1:
            raise InputError(f"search budget {budget}: give at least 1 derivation")
        self.fn = fn
        self.budget = int(budget)
        self.used = 0
        self.best = math.inf
        self.best_attrs: dict[str, Any] = {}
        self.curve: list[float] = []

    @property
    def left(self) -> int:
        return self.budget - self.used

    def __call__(self, attrs: Mapping[str, Any]) -> float:
        e = float(self.fn(attrs))
        if not math.isfinite(e):
            e = math.inf
        self.used += 1
        if e < self.best:
            self.best = e
            self.best_attrs = dict(attrs)
        self.curve.append(self.best)
        return e


def random_point(params: list[Parameter], rng: np.random.Generator) -> dict[str, Any]:
    return {p.name: (p.choices[rng.integers(len(p.choices))] if p.discrete
                     else p.clip(rng.uniform(p.lo, p.hi))) for p in params}


def latin_hypercube(params: list[Parameter], n: int, rng: np.random.Generator
                    ) -> list[dict[str, Any]]:
    """``n`` points stratified along every continuous parameter."""
    pts = [dict() for _ in range(n)]
    for p in params:
        if p.discrete:
            vals = [p.choices[i % len(p.choices)] for i in rng.permutation(n)]
        else:
            u = (rng.permutation(n) + rng.uniform(size=n)) / n
            vals = [p.clip(p.lo + x * (p.hi - p.lo)) for x in u]
        for pt, v in zip(pts, vals):
            pt[p.name] = v
    return pts


def perturb(point: Mapping[str, Any], params: list[Parameter], sigma: float,
            rng: np.random.Generator) -> dict[str, Any]:
    """Eq. 4.8: every continuous parameter moves by N(0, σ·range); enums flip with prob. σ."""
    out = dict(point)
    for p in params:
        if p.discrete:
            if rng.uniform() < sigma:
                out[p.name] = p.choices[rng.integers(len(p.choices))]
        else:
            out[p.name] = p.clip(out[p.name] + rng.normal(0.0, sigma * (p.hi - p.lo)))
    return out


def hill_climb(objective_fn: Callable[[Mapping[str, Any]], float], params: list[Parameter], *,
               budget: int = 600, k: int = 12, sigma0: float = 0.3, sigma1: float = 0.01,
               explore: float = 0.15, seed: int = 0) -> SearchResult:
    """Algorithm 4.1 (module docstring) within ``budget`` derivations."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    obj = Objective(objective_fn, budget)
    current = {p.name: p.default for p in params}
    e_cur = obj(current)
    n_explore = min(obj.left, int(explore * budget))
    for pt in latin_hypercube(params, n_explore, rng):
        e = obj(pt)
        if e < e_cur:
            current, e_cur = pt, e
    iterations = max(1, math.ceil(obj.left / max(1, k)))
    for n in range(iterations):
        frac = n / max(1, iterations - 1)
        sigma = sigma0 * (sigma1 / sigma0) ** frac
        best, e_best = None, math.inf
        for _ in range(min(k, obj.left)):
            cand = perturb(current, params, sigma, rng)
            e = obj(cand)
            if e < e_best:
                best, e_best = cand, e
        if best is not None and e_best < e_cur:
            current, e_cur = best, e_best
    return SearchResult(dict(obj.best_attrs), obj.best, obj.used, time.perf_counter() - t0,
                        obj.curve, "hill")
