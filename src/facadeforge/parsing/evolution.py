"""Evolutionary search of a parse grammar's procedural space (``simon2011`` §5.2).

§5.2 replaces the hill climbing of §4.2 (:func:`~.search.hill_climb`) by an evolutionary
algorithm (Fig. 5.2 / the EA loop of §5.2.1): a population is *selected* (tournaments, elitism),
*recombined*, *mutated*, *evaluated* and *re-inserted*; several populations evolve as islands
(Algorithm 5.2) and, with several objectives, selection is the modified strength-Pareto scheme
SPEA-II (Algorithm 5.3).  The thesis evolves parse trees; our engine's procedural space is fixed
dimensional (§4.1.1: one rule per symbol, consistent derivation), so a *genome* is the dict of
the grammar's ``@Range`` / ``@Enum`` values (:func:`~.search.parameters_of`, in declaration
order).  The §5.2.2 operators map onto it as follows.

Genotype and repair (§5.2.2 "Genotype")
    A parse-tree node ``n = (r, x, p)`` is a rule choice ``r`` and its real parameters ``x``.
    Rule choices are our ``@Enum`` parameters, ``x`` our ``@Range`` ones.  The thesis must
    *repair* a tree after each operator (children symbols must match the parent's rule; nodes
    with the same symbol and tag must share rule and parameters).  Both predicates hold by
    construction here: the derivation is a function of the parameter vector and consistency is
    built into the fixed space (one value per attribute for every floor/tile).  Repair reduces to
    :meth:`~.search.Parameter.clip` — clamp to ``[lo, hi]`` and snap to ``step``.

Rule mutation (§5.2.2 "Mutation" 1)
    Replace ``r`` by another rule of ``R_p``: re-draw one ``@Enum`` parameter to a *different*
    choice.

Parameter mutation (eq. 5.1)
    ``x_i ← x_i + u`` for one randomly chosen continuous parameter.  The thesis draws
    ``u ~ U([-δ, δ])`` with δ set by a coarse or fine policy; we draw ``u ~ N(0, σ·range_i)`` (as
    eq. 4.8 of the hill climber) with σ = island policy (coarse/fine) × a schedule that shrinks
    geometrically ×0.1 over the budget × a per-island factor adapted by the "one-fifth rule" the
    thesis cites (grow σ when more than 1/5 of the offspring beat their parent, shrink it
    otherwise).  A stepped parameter (a count: floors, tiles) whose draw rounds back to its value
    moves by one step instead, so no derivation is spent on a no-op.

Concurrent mutation (eq. 5.2)
    The thesis picks ``x_i`` and ``x_j`` "from the same node or from successive ones" and moves
    them by ``+u`` and ``−u``, so one architectural element moves while the rest of the layout
    stays put (e.g. ``roofHeight + u`` with ``skyHeight − u`` lifts the roof's top edge alone:
    their sum, hence every other split, is unchanged).  In our genome parameters of the same or
    of successive rules are *neighbours in declaration order*, so ``j`` is the next or previous
    continuous parameter of ``i`` (stepped counts are left out: ``±u`` has no meaning for them).  ``u ~ N(0, σ·min(range_i, range_j))`` is applied in the
    parameters' own units (split sizes are metres, like the thesis's), and ``u`` is first clamped
    to the interval that keeps *both* values in range, so the compensation stays exact (up to
    ``step`` snapping) instead of being broken by clipping one side.

Recombination (§5.2.2 "Recombination")
    *Rule recombination* swaps a node's rule together with its parameters, i.e. a sub-tree: a
    grammar declares a rule's attributes consecutively, so a contiguous block of the declaration
    order is a sub-tree's genes — blocked (two-point) crossover copies one random contiguous
    block from the second parent.  *Parameter recombination* swaps single components
    ``x_i ↔ x'_i``: uniform crossover.  Each mating uses one of the two (island policy); the
    child is always mutated afterwards (recombination then mutation, Fig. 5.2).

Selection and replacement (§5.2.2 "Selection", §5.2.1)
    Tournaments of ``tournament`` candidates drawn with replacement (the thesis uses 2), the
    fittest wins and stays in the pool.  Replacement is (μ + λ): the new generation is the best μ
    of parents ∪ offspring — the elitism the thesis insists on.  With a scalar objective the
    fitness is the energy itself.

SPEA-II (Algorithm 5.3, [Zitzler 2001])
    When ``objective_fn`` returns several values, each island keeps an archive ``A`` of its
    island size: fitness on ``A ∪ offspring`` is ``F = R + D`` with strength ``S(i)`` = number of
    individuals ``i`` dominates, raw fitness ``R(i) = Σ S(j)`` over the ``j`` dominating ``i``
    and density ``D(i) = 1 / (σ_k + 2)`` from the distance to the k-th nearest neighbour
    (``k = ⌊√N⌋``, objectives normalised to [0, 1]).  The archive takes every non-dominated
    individual, is filled up with the fittest dominated ones, or truncated by repeatedly removing
    the individual at the densest location (lexicographically smallest nearest-neighbour
    distances); genitors are chosen by tournament on ``A`` by ``F``.  The answer (§5.2.3) is the
    evaluated layout of lowest weighted sum (``weights``, default all 1 — eq. 5.3 generalised);
    with non-negative weights it lies on the Pareto front of everything evaluated.
    ``weights="auto"`` is the thesis's automatic choice (:func:`auto_alpha`, Fig. 5.6): the
    weights that make the iso-lines of eq. 5.3 parallel to the diagonal of the Pareto set's
    bounding box, so the answer is the Pareto layout farthest below that diagonal, and its
    *strength* the range of α that keeps it optimal (``SearchResult.alpha_range``).

Island model (Algorithm 5.2, §5.2.2 "Concurrent populations")
    ``islands`` sub-populations evolve independently with different policies, as in the thesis:
    one mostly by rule mutation and sub-tree recombination, one by coarse and one by fine
    parameter mutation (cycled when there are more islands; one island uses a mixed policy).
    Every ``migration_every`` generations each island's best individual migrates to the next
    island of a ring, replacing its worst.  Resources: before every generation
    ``n_i ← allocate resource(P_i)`` gives each island a share of the constant global population
    (``population × islands``) — and so of the derivations still to spend, since an island of
    size ``n_i`` breeds ``n_i`` children a generation — half equally, half in proportion to its
    recent improvement of its best energy (exponential moving average), so the better it does the
    bigger it grows; each island keeps at least 2 individuals.

Initial population: the expert seed (every parameter's ``default``) in the first island, Latin
hypercube draws (:func:`~.search.latin_hypercube`) for the rest.  The budget counts derivations
exactly (:class:`~.search.Objective`); everything draws from one seeded generator.  Offspring
identical to an already evaluated genome are mutated again (a few tries) rather than re-derived.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from .search import Objective, Parameter, SearchResult, latin_hypercube

__all__ = ["auto_alpha", "evolve", "pareto_mask", "spea2_fitness", "spea2_select"]


@dataclass
class _Ind:
    attrs: dict[str, Any]
    vec: np.ndarray      # objective values (length 1 for a scalar objective)
    e: float             # weighted sum of ``vec`` (the energy with a scalar objective)


@dataclass(frozen=True)
class _Policy:
    """Operator mix of an island (§5.2.2 "Concurrent populations")."""

    name: str
    p_rule: float         # probability that a mutation is a rule mutation (if enums exist)
    p_concurrent: float   # probability that a parameter mutation is concurrent (eq. 5.2)
    sigma: float          # mutation amplitude, fraction of a parameter's range
    p_blocked: float      # probability that a crossover is blocked (sub-tree) vs uniform


_ISLAND_POLICIES = (
    _Policy("rules", p_rule=0.6, p_concurrent=0.3, sigma=0.25, p_blocked=0.8),
    _Policy("coarse", p_rule=0.1, p_concurrent=0.4, sigma=0.25, p_blocked=0.5),
    _Policy("fine", p_rule=0.05, p_concurrent=0.4, sigma=0.1, p_blocked=0.2),
)
_MIXED = _Policy("mixed", p_rule=0.25, p_concurrent=0.4, sigma=0.15, p_blocked=0.5)
#: σ schedule: the amplitude shrinks geometrically by this factor over the whole budget
_SCHEDULE_END = 0.1
#: one-fifth rule step and bounds of the adaptive factor
_FIFTH_STEP, _ADAPT_MIN, _ADAPT_MAX = 1.22, 0.1, 4.0
#: memory of the improvement moving average used to allocate resources
_EMA = 0.7


# --------------------------------------------------------------------------------- SPEA-II


def _dominance(F: np.ndarray) -> np.ndarray:
    """``dom[i, j]``: ``i`` dominates ``j`` (all objectives ≤, one <)."""
    le = (F[:, None, :] <= F[None, :, :]).all(axis=2)
    lt = (F[:, None, :] < F[None, :, :]).any(axis=2)
    return le & lt


def pareto_mask(F: np.ndarray) -> np.ndarray:
    """Rows of ``F`` (n × m, minimised) that no other row dominates."""
    F = np.asarray(F, float)
    return ~_dominance(F).any(axis=0)


def _normalised(F: np.ndarray) -> np.ndarray:
    F = np.array(F, float)
    for c in range(F.shape[1]):
        col = F[:, c]
        fin = np.isfinite(col)
        if not fin.any():
            F[:, c] = 0.0
            continue
        lo, hi = col[fin].min(), col[fin].max()
        span = hi - lo if hi > lo else 1.0
        col[~fin] = hi + span          # unusable layouts: far beyond the worst finite one
        F[:, c] = (col - lo) / span
    return F


def _distances(F: np.ndarray) -> np.ndarray:
    N = _normalised(F)
    d = np.sqrt(((N[:, None, :] - N[None, :, :]) ** 2).sum(axis=2))
    np.fill_diagonal(d, np.inf)
    return d


def auto_alpha(F: np.ndarray) -> tuple[int, float, tuple[float, float]]:
    """§5.2.3's automatic weight on two objectives ``F`` (n × 2, minimised): ``(row, α,
    (α_lo, α_hi))``.

    α makes the iso-lines of ``E = α E_a + (1 − α) E_d`` (eq. 5.3) parallel to the diagonal of
    the Pareto set's bounding box (Fig. 5.6): ``α = Δ_d / (Δ_a + Δ_d)`` with ``Δ`` the box's
    extents, so the chosen row — the Pareto row of least ``E`` — is the one farthest below that
    diagonal.  ``(α_lo, α_hi)`` is the range of α for which the same row stays optimal among the
    Pareto rows ("the strength of the solution"): narrow means a challenger is close and a person
    should look.
    """
    F = np.asarray(F, float)
    if F.ndim != 2 or F.shape[1] != 2 or not len(F):
        raise InputError(f"auto_alpha needs an (n, 2) array of two energies, got {F.shape}")
    ok = np.isfinite(F).all(axis=1)
    if not ok.any():
        return 0, 0.5, (0.0, 1.0)
    idx = np.flatnonzero(ok)
    front = idx[pareto_mask(F[idx])]
    P = F[front]
    span = P.max(0) - P.min(0)
    if span[0] <= 0 and span[1] <= 0:
        return int(front[0]), 0.5, (0.0, 1.0)
    alpha = float(span[1] / (span[0] + span[1]))
    e = alpha * P[:, 0] + (1 - alpha) * P[:, 1]
    k = int(np.argmin(e))
    # i stays optimal against j while α (a_i − a_j) + (1 − α)(d_i − d_j) ≤ 0, a linear condition
    lo, hi = 0.0, 1.0
    for j in range(len(P)):
        if j == k:
            continue
        da, dd = P[k, 0] - P[j, 0], P[k, 1] - P[j, 1]
        # α (da − dd) ≤ −dd
        c = da - dd
        if abs(c) < 1e-300:
            continue
        bound = -dd / c
        if c > 0:
            hi = min(hi, bound)
        else:
            lo = max(lo, bound)
    return int(front[k]), alpha, (max(0.0, lo), min(1.0, hi))


def spea2_fitness(F: np.ndarray) -> np.ndarray:
    """SPEA-II fitness ``R + D`` of the rows of ``F`` (lower is better; < 1 ⇔ non-dominated)."""
    F = np.asarray(F, float)
    n = len(F)
    dom = _dominance(F)
    strength = dom.sum(axis=1)
    raw = (dom * strength[:, None]).sum(axis=0).astype(float)
    if n < 2:
        return raw + 0.5
    k = max(1, min(n - 1, int(math.sqrt(n))))
    sigma_k = np.sort(_distances(F), axis=1)[:, k - 1]
    return raw + 1.0 / (sigma_k + 2.0)


def spea2_select(F: np.ndarray, size: int) -> np.ndarray:
    """Algorithm 5.3's archive update: indices of the ``size`` rows kept.

    Every non-dominated row; if fewer than ``size``, the fittest dominated rows fill up; if more,
    the row at the densest location (smallest distance to its nearest neighbour, ties broken by
    the next nearest, …) is removed until ``size`` remain.
    """
    F = np.asarray(F, float)
    fit = spea2_fitness(F)
    nd = np.flatnonzero(fit < 1.0)
    if len(nd) <= size:
        rest = np.setdiff1d(np.arange(len(F)), nd)
        rest = rest[np.argsort(fit[rest], kind="stable")]
        return np.concatenate([nd, rest[:size - len(nd)]]).astype(int)
    keep = list(nd)
    d = _distances(F[nd])
    alive = np.ones(len(nd), bool)
    while alive.sum() > size:
        idx = np.flatnonzero(alive)
        sub = np.sort(d[np.ix_(idx, idx)], axis=1)
        # lexicographic minimum of the sorted distance rows
        order = np.lexsort(sub.T[::-1])
        alive[idx[order[0]]] = False
    return np.array([keep[i] for i in np.flatnonzero(alive)], int)


# --------------------------------------------------------------------------------- operators


def _key(attrs: Mapping[str, Any], params: Sequence[Parameter]) -> tuple:
    return tuple(attrs[p.name] for p in params)


def _rule_mutation(child: dict[str, Any], enums: list[Parameter], rng: np.random.Generator):
    p = enums[rng.integers(len(enums))]
    others = [c for c in p.choices if c != child[p.name]]
    child[p.name] = others[rng.integers(len(others))]


def _parameter_mutation(child: dict[str, Any], conts: list[Parameter], sigma: float,
                        rng: np.random.Generator):
    """Eq. 5.1: ``x_i ← x_i + u``."""
    p = conts[rng.integers(len(conts))]
    x = child[p.name]
    v = p.clip(x + rng.normal(0.0, sigma * (p.hi - p.lo)))
    if p.step > 0 and v == x:      # a count moves by one step at least (else a no-op)
        v = p.clip(x + (p.step if rng.uniform() < 0.5 else -p.step))
        v = v if v != x else p.clip(x + p.step if x <= p.lo else x - p.step)
    child[p.name] = v


def _concurrent_mutation(child: dict[str, Any], conts: list[Parameter], sigma: float,
                         rng: np.random.Generator):
    """Eq. 5.2: ``x_i ← x_i + u``, ``x_j ← x_j − u`` for neighbours ``i``, ``j`` in declaration
    order, ``u`` clamped so both stay in range (an exact compensation)."""
    i = int(rng.integers(len(conts)))
    if i == 0:
        j = 1
    elif i == len(conts) - 1:
        j = i - 1
    else:
        j = i + (1 if rng.uniform() < 0.5 else -1)
    pi, pj = conts[i], conts[j]
    xi, xj = float(child[pi.name]), float(child[pj.name])
    u = rng.normal(0.0, sigma * min(pi.hi - pi.lo, pj.hi - pj.lo))
    u_lo = max(pi.lo - xi, xj - pj.hi)
    u_hi = min(pi.hi - xi, xj - pj.lo)
    u = min(max(u, min(u_lo, 0.0)), max(u_hi, 0.0))
    child[pi.name] = pi.clip(xi + u)
    child[pj.name] = pj.clip(xj - u)


def _crossover(a: Mapping[str, Any], b: Mapping[str, Any], params: Sequence[Parameter],
               blocked: bool, rng: np.random.Generator) -> dict[str, Any]:
    """Recombination: a contiguous block of ``b`` (a sub-tree's genes) into ``a``, or uniform."""
    child = dict(a)
    n = len(params)
    if blocked and n > 1:
        i = int(rng.integers(n))
        j = int(rng.integers(i + 1, n + 1))
        if i == 0 and j == n:          # never the whole genome: that is just a copy of b
            j = n - 1
        names = [p.name for p in params[i:j]]
    else:
        names = [p.name for p in params if rng.uniform() < 0.5]
    for name in names:
        child[name] = b[name]
    return child


# --------------------------------------------------------------------------------- the EA


class _Islands:
    """State shared by the generations: evaluation, bookkeeping, operators."""

    def __init__(self, objective_fn, params, budget, weights, rng):
        self.params = list(params)
        self.enums = [p for p in self.params if p.discrete]
        self.conts = [p for p in self.params if not p.discrete]
        #: partners of concurrent mutations: sizes, not stepped counts (eq. 5.2 needs ±u)
        self.smooth = [p for p in self.conts if p.step <= 0]
        self.rng = rng
        self.weights = None if weights is None else np.asarray(weights, float).ravel()
        self.m: int | None = None
        self._last: np.ndarray | None = None
        self.objective_fn = objective_fn
        self.obj = Objective(self._scalar, budget)
        self.seen: set[tuple] = set()
        self.history: list[_Ind] = []

    def _scalar(self, attrs: Mapping[str, Any]) -> float:
        v = np.atleast_1d(np.asarray(self.objective_fn(attrs), float)).ravel()
        if self.m is None:
            if v.size < 1:
                raise InputError("the objective returned an empty array: return a float or a "
                                 "1-D array of energies")
            self.m = v.size
            if self.weights is None:
                self.weights = np.ones(self.m)
            elif self.weights.size != self.m:
                raise InputError(f"weights has {self.weights.size} values but the objective "
                                 f"returns {self.m}: give one weight per objective")
        elif v.size != self.m:
            raise InputError(f"the objective returned {v.size} values after {self.m}: it must "
                             "always return the same number of energies")
        v = np.where(np.isfinite(v), v, np.inf)
        self._last = v
        if not np.isfinite(v).all():
            return math.inf
        return float(self.weights @ v)

    @property
    def multi(self) -> bool:
        return bool(self.m and self.m > 1)

    def evaluate(self, attrs: dict[str, Any]) -> _Ind:
        e = self.obj(attrs)
        ind = _Ind(dict(attrs), self._last.copy(), e)
        self.seen.add(_key(attrs, self.params))
        self.history.append(ind)
        return ind

    # -- selection ---------------------------------------------------------------------------

    def fitness(self, pop: list[_Ind]) -> np.ndarray:
        if self.multi:
            return spea2_fitness(np.array([i.vec for i in pop]))
        return np.array([i.e for i in pop])

    def survivors(self, pool: list[_Ind], size: int) -> list[_Ind]:
        """(μ + λ) replacement, or Algorithm 5.3's archive update with several objectives."""
        if self.multi:
            idx = spea2_select(np.array([i.vec for i in pool]), size)
            kept = [pool[i] for i in idx]
            return sorted(kept, key=lambda i: i.e)
        order = np.argsort([i.e for i in pool], kind="stable")
        return [pool[i] for i in order[:size]]

    def tournament(self, pop: list[_Ind], fit: np.ndarray, size: int) -> _Ind:
        cand = self.rng.integers(len(pop), size=size)
        return pop[int(cand[np.argmin(fit[cand])])]

    # -- variation ---------------------------------------------------------------------------

    def mutate(self, child: dict[str, Any], policy: _Policy, sigma: float):
        rng = self.rng
        n_ops = 1
        while n_ops < len(self.params) and rng.uniform() < 0.3:
            n_ops += 1
        for _ in range(n_ops):
            if self.enums and (not self.conts or rng.uniform() < policy.p_rule):
                _rule_mutation(child, self.enums, rng)
            elif len(self.smooth) > 1 and rng.uniform() < policy.p_concurrent:
                _concurrent_mutation(child, self.smooth, sigma, rng)
            else:
                _parameter_mutation(child, self.conts, sigma, rng)

    def offspring(self, pop: list[_Ind], fit: np.ndarray, policy: _Policy, sigma: float,
                  crossover: float, tsize: int) -> tuple[dict[str, Any], _Ind]:
        rng = self.rng
        mother = self.tournament(pop, fit, tsize)
        if len(pop) > 1 and rng.uniform() < crossover:
            father = self.tournament(pop, fit, tsize)
            child = _crossover(mother.attrs, father.attrs, self.params,
                               rng.uniform() < policy.p_blocked, rng)
        else:
            child = dict(mother.attrs)
        for _ in range(6):
            self.mutate(child, policy, sigma)
            if _key(child, self.params) not in self.seen:
                break
        return child, mother


def _allocate(perf: np.ndarray, total: int) -> list[int]:
    """Island sizes: half the global population equally, half by recent improvement."""
    m = len(perf)
    s = perf.sum()
    share = np.full(m, 1.0 / m) if s <= 0 else 0.5 / m + 0.5 * perf / s
    minimum = min(2, total // m)
    raw = minimum + share * (total - minimum * m)
    sizes = np.floor(raw).astype(int)
    rest = total - sizes.sum()
    for i in np.argsort(-(raw - sizes), kind="stable")[:rest]:
        sizes[i] += 1
    return sizes.tolist()


def evolve(objective_fn: Callable[[Mapping[str, Any]], Any], params: list[Parameter], *,
           budget: int = 1500, seed: int = 0, population: int = 16, islands: int = 3,
           tournament: int = 3, crossover: float = 0.7, migration_every: int = 5,
           weights: Sequence[float] | str | None = None, seeded: float = 0.5) -> SearchResult:
    """Minimise ``objective_fn`` over ``params`` by the island-model EA of §5.2 (module doc).

    ``objective_fn(attrs)`` returns an energy or a 1-D array of energies (multi-objective:
    SPEA-II selection, Algorithm 5.3; the result and the best-so-far curve use the ``weights``
    sum, eq. 5.3).  ``population`` is the initial size of each of the ``islands`` populations
    (Algorithm 5.2; the global size ``population × islands`` stays constant while resources move
    between islands); a ``seeded`` share of each island starts near the parameters' defaults
    (the expert or measured seed), the rest spread by a Latin hypercube.  Exactly ``budget``
    derivations; deterministic for a ``seed``.
    """
    t0 = time.perf_counter()
    if budget < 1:
        raise InputError(f"evolution budget {budget}: give at least 1 derivation")
    if population < 2:
        raise InputError(f"population {population}: an island needs at least 2 individuals")
    if islands < 1:
        raise InputError(f"islands {islands}: give at least 1 population")
    if tournament < 1:
        raise InputError(f"tournament {tournament}: give at least 1 candidate")
    if not 0.0 <= crossover <= 1.0:
        raise InputError(f"crossover {crossover}: give a probability in [0, 1]")
    if not 0.0 <= seeded <= 1.0:
        raise InputError(f"seeded {seeded}: give a share in [0, 1]")
    if migration_every < 1:
        raise InputError(f"migration_every {migration_every}: give at least 1 generation")
    if not params:
        raise InputError("no parameters to evolve: the procedural space is empty")
    auto = isinstance(weights, str)
    if auto and weights != "auto":
        raise InputError(f"weights {weights!r}: give numbers or 'auto'")
    if auto:
        weights = None
    if weights is not None:
        w = np.asarray(weights, float).ravel()
        if w.size == 0 or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
            raise InputError(f"weights {list(w)}: give non-negative finite weights, one > 0")

    rng = np.random.default_rng(seed)
    ev = _Islands(objective_fn, params, budget, weights, rng)
    obj = ev.obj
    total = population * islands
    policies = [_MIXED] if islands == 1 else [
        _ISLAND_POLICIES[i % len(_ISLAND_POLICIES)] for i in range(islands)]

    # initial populations: expert seed + Latin hypercube (Algorithm 5.2, first line)
    expert = {p.name: (p.default if p.discrete and p.default in p.choices
                       else p.choices[0] if p.discrete
                       else p.clip(p.default if p.default is not None else (p.lo + p.hi) / 2))
              for p in params}
    # Each island starts from the expert seed's neighbourhood (variants with a few small
    # mutations) as well as the hypercube: in a space of ~70 parameters a random layout is far
    # from any facade, and an island of only random layouts spends its budget catching up with
    # the island that holds the seed.
    # The expert seed itself always starts on island 0 (with seeded=0 too, as Algorithm 5.2
    # has it); the hypercube fills what the seed's neighbourhood leaves of each island.
    n_near = max(1, round(seeded * population)) if seeded > 0 else 0
    spread = latin_hypercube(params, total, rng)
    pops: list[list[_Ind]] = [[] for _ in range(islands)]
    for i in range(islands):
        near = [expert] if i == 0 else []
        while len(near) < n_near:
            variant = dict(expert)
            for _ in range(1 + int(rng.integers(3))):
                ev.mutate(variant, policies[i], 0.05)
            near.append(variant)
        for attrs in (near + spread[i * population:(i + 1) * population])[:population]:
            if obj.left > 0:
                pops[i].append(ev.evaluate(attrs))

    sizes = [population] * islands
    perf = np.zeros(islands)
    adapt = np.ones(islands)
    generation = 0
    while obj.left > 0:
        generation += 1
        schedule = _SCHEDULE_END ** (obj.used / budget)
        for i in range(islands):
            if obj.left <= 0:
                break
            pop = pops[i]
            if not pop:
                continue
            policy = policies[i]
            sigma = min(0.5, policy.sigma * adapt[i] * schedule)
            fit = ev.fitness(pop)
            best_before = min(ind.e for ind in pop)
            children, wins = [], 0
            for _ in range(min(sizes[i], obj.left)):
                attrs, mother = ev.offspring(pop, fit, policy, sigma, crossover, tournament)
                child = ev.evaluate(attrs)
                wins += child.e < mother.e
                children.append(child)
            pops[i] = ev.survivors(pop + children, sizes[i])
            # one-fifth rule (§5.2.1 footnote 2)
            rate = wins / max(1, len(children))
            adapt[i] = min(_ADAPT_MAX, max(_ADAPT_MIN, adapt[i] * (
                _FIFTH_STEP if rate > 0.2 else 1 / _FIFTH_STEP if rate < 0.2 else 1.0)))
            gain = best_before - min(ind.e for ind in pops[i])
            gain = gain if math.isfinite(gain) else 0.0
            perf[i] = _EMA * perf[i] + (1 - _EMA) * max(0.0, gain)
        if islands > 1:
            if generation % migration_every == 0:        # migrate (ring)
                bests = [min(p, key=lambda ind: ind.e) if p else None for p in pops]
                for i in range(islands):
                    migrant, dst = bests[i], pops[(i + 1) % islands]
                    if migrant is None or not dst or any(ind is migrant for ind in dst):
                        continue
                    worst = max(range(len(dst)), key=lambda k: dst[k].e)
                    dst[worst] = migrant
            sizes = _allocate(perf, total)                # allocate resource (P_i)

    alpha = alpha_range = None
    front: list[list[float]] = []
    if ev.multi and ev.history:
        F = np.array([ind.vec for ind in ev.history])
        ok = np.isfinite(F).all(axis=1)
        keep = np.flatnonzero(ok)[pareto_mask(F[ok])] if ok.any() else np.zeros(0, int)
        front = [F[i].tolist() for i in keep]
    if ev.multi and auto and ev.m == 2:
        row, alpha, alpha_range = auto_alpha(F)
        best_attrs = dict(ev.history[row].attrs)
    elif ev.multi:
        cands = [ind for ind in ev.history if ind.e == obj.best]
        if cands:
            keep = pareto_mask(np.array([c.vec for c in cands]))
            best_attrs = dict(cands[int(np.flatnonzero(keep)[0])].attrs)
        else:
            best_attrs = dict(ev.history[0].attrs)
    else:
        best_attrs = dict(obj.best_attrs) if obj.best_attrs else dict(ev.history[0].attrs)
    return SearchResult(best_attrs, obj.best, obj.used, time.perf_counter() - t0,
                        list(obj.curve), "evolution", front=front, alpha=alpha,
                        alpha_range=alpha_range)
