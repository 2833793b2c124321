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
from ..grammar.parameters import Parameter, parameters_of

__all__ = ["Parameter", "SearchResult", "hill_climb", "parameters_of"]  # re-exported


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
    #: several objectives: the Pareto set of everything evaluated (one row of energies each)
    front: list[list[float]] = field(default_factory=list)
    #: ``weights="auto"``: the chosen α of eq. 5.3 and the range of α keeping the answer (§5.2.3)
    alpha: float | None = None
    alpha_range: tuple[float, float] | None = None


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


def coordinate_sweep(obj: Objective, params: list[Parameter], current: dict[str, Any],
                     e_cur: float, span: float, points: int, rng: np.random.Generator
                     ) -> tuple[dict[str, Any], float]:
    """One steepest-descent pass along each parameter axis (random order): ``points`` values
    within ``± span · range`` of the current one (every other choice of an enum); then the
    coupled count × enum moves (the spirit of the thesis's concurrent mutation, §5.2.2)."""
    for i in rng.permutation(len(params)):
        p = params[i]
        if obj.left <= 0:
            break
        if p.discrete:
            values = [c for c in p.choices if c != current[p.name]]
        else:
            half = span * (p.hi - p.lo)
            grid = np.linspace(current[p.name] - half, current[p.name] + half, points)
            values = sorted({p.clip(v) for v in grid} - {current[p.name]})
        for v in values[:obj.left]:
            cand = {**current, p.name: v}
            e = obj(cand)
            if e < e_cur:
                current, e_cur = cand, e
    # Coupled structural moves: every value of a count (a stepped range) together with every
    # other choice of an enum — e.g. twice the tiles with one window each instead of paired
    # windows — which no single-axis move reaches through the worse layouts in between.
    # Only structural switches (enums of at most three choices) pair with counts: an index
    # such as grid.cga's doorColumn would multiply the moves past any budget.
    counts = [p for p in params if not p.discrete and p.step > 0]
    enums = [p for p in params if p.discrete and len(p.choices) <= 3]
    for a in counts:
        for b in enums:
            for va in np.arange(a.lo, a.hi + a.step / 2, a.step):
                for vb in b.choices:
                    if obj.left <= 0:
                        return current, e_cur
                    if vb == current[b.name]:
                        continue
                    cand = {**current, a.name: a.clip(va), b.name: vb}
                    e = obj(cand)
                    if e < e_cur:
                        current, e_cur = cand, e
    return current, e_cur


def hill_climb(objective_fn: Callable[[Mapping[str, Any]], float], params: list[Parameter], *,
               budget: int = 2000, k: int = 12, sigma0: float = 0.3, sigma1: float = 0.01,
               explore: float = 0.15, sweeps: float = 0.6, points: int = 9, starts: int = 4,
               seed: int = 0) -> SearchResult:
    """Algorithm 4.1 (module docstring) within ``budget`` derivations.

    Phases: the expert seed and ``explore · budget`` Latin-hypercube layouts; then
    ``sweeps · budget`` derivations of coordinate sweeps whose span halves each pass (steepest
    descent along one parameter at a time: it aligns a grid of windows that random joint moves
    rarely hit), shared by the ``starts`` best starting layouts; then, from the best of them, Gaussian perturbation rounds of ``k`` samples with σ shrinking from
    ``sigma0`` to ``sigma1`` (eq. 4.8).
    """
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    obj = Objective(objective_fn, budget)
    seed_point = {p.name: p.default for p in params}
    pool = [(obj(seed_point), 0, seed_point)]
    n_explore = min(obj.left, int(explore * budget))
    for i, pt in enumerate(latin_hypercube(params, n_explore, rng)):
        pool.append((obj(pt), i + 1, pt))
    # Coordinate sweeps from the best few starting points (multi-start: the landscape of a
    # repeat grammar is rugged, one start often sits in the wrong basin); the best goes on.
    pool.sort(key=lambda t: (t[0], t[1]))
    starts = pool[:max(1, starts)]
    sweep_budget = int(sweeps * budget)
    finished = []
    for j, (e_cur, _, current) in enumerate(starts):
        share = sweep_budget // len(starts) if j < len(starts) - 1 else \
            sweep_budget - (sweep_budget // len(starts)) * (len(starts) - 1)
        end = min(obj.budget, obj.used + share)
        span = 0.5
        while obj.used < end:
            sub = Objective(obj, end - obj.used)
            before = e_cur
            current, e_cur = coordinate_sweep(sub, params, current, e_cur, span, points, rng)
            span = max(span / 2, 0.01)
            if span <= 0.01 and e_cur >= before:
                break
        finished.append((e_cur, j, current))
    e_cur, _, current = min(finished, key=lambda t: (t[0], t[1]))
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
