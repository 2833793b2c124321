"""Evolutionary parsing search (simon2011 §5.2): budget, determinism, optimisation quality,
SPEA-II Pareto answers, island model, argument checks, and recovery of a known layout."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.datasets import get_label_set
from facadeforge.errors import InputError
from facadeforge.parsing import fit as fit_module
from facadeforge.parsing.evolution import evolve, pareto_mask, spea2_fitness, spea2_select
from facadeforge.parsing.search import Parameter, random_point

ECP7 = get_label_set("ecp7")

PARAMS = [Parameter("a", 0.0, -5, 5), Parameter("b", 1.0, -5, 5),
          Parameter("kind", "x", choices=("x", "y", "z")), Parameter("c", 5.0, 0, 10),
          Parameter("d", 2.0, -3, 3)]
KIND_COST = {"x": 1.0, "y": 0.0, "z": 2.0}


def smooth(at) -> float:
    """A smooth, coupled 4-D bowl plus an enum penalty; minimum ≈ -0.95 at kind = "y"."""
    return ((at["a"] - 1.3) ** 2 + 2 * (at["b"] + 2.1) ** 2 + 0.5 * (at["c"] - 7.7) ** 2
            + (at["d"] - 0.4) ** 2 + 0.3 * at["a"] * at["b"] + KIND_COST[at["kind"]])


def two_objectives(at) -> np.ndarray:
    """Conflicting objectives: distance to two different points (a convex Pareto front)."""
    f1 = (at["a"] - 2) ** 2 + (at["b"] - 1) ** 2 + KIND_COST[at["kind"]]
    f2 = (at["a"] + 1) ** 2 + (at["b"] + 2) ** 2 + 0.1 * (at["c"] - 3) ** 2
    return np.array([f1, f2])


def test_exact_budget_deterministic_and_monotone():
    calls = []

    def f(at):
        calls.append(dict(at))
        return smooth(at)

    r1 = evolve(f, PARAMS, budget=321, seed=7)
    assert len(calls) == 321 and r1.derivations == 321 and len(r1.curve) == 321
    assert r1.method == "evolution"
    assert all(b <= a for a, b in zip(r1.curve, r1.curve[1:]))
    assert r1.energy == r1.curve[-1] == pytest.approx(smooth(r1.attrs))
    assert calls[0] == {p.name: p.default for p in PARAMS}  # the expert seed comes first
    for at in calls:                                          # repair: every genome is valid
        for p in PARAMS:
            assert at[p.name] in p.choices if p.discrete else p.lo <= at[p.name] <= p.hi
    first = list(calls)
    calls.clear()
    r2 = evolve(f, PARAMS, budget=321, seed=7)
    assert calls == first and r2.attrs == r1.attrs and r2.curve == r1.curve
    r3 = evolve(smooth, PARAMS, budget=321, seed=8)
    assert r3.curve != r1.curve


@pytest.mark.parametrize("budget", [1, 5, 47])
def test_small_budgets_are_exact(budget):
    r = evolve(smooth, PARAMS, budget=budget, seed=0, population=8, islands=3)
    assert r.derivations == budget and len(r.curve) == budget


@pytest.mark.parametrize("seed", range(3))
def test_beats_random_search_at_equal_budget(seed):
    budget = 500
    r = evolve(smooth, PARAMS, budget=budget, seed=seed)
    rng = np.random.default_rng(seed)
    random_best = min(smooth(random_point(PARAMS, rng)) for _ in range(budget))
    assert r.energy < random_best
    assert r.attrs["kind"] == "y"
    assert r.energy < -0.5           # the minimum is ≈ -0.95


def test_stepped_parameters_stay_on_their_grid():
    params = [Parameter("n", 3.0, 1, 9, 1), Parameter("x", 0.0, -2, 2)]
    r = evolve(lambda at: (at["n"] - 6) ** 2 + (at["x"] - 0.5) ** 2, params, budget=200, seed=1)
    assert r.attrs["n"] == 6.0 and abs(r.attrs["x"] - 0.5) < 0.1


def test_spea2_answer_is_on_the_pareto_front_of_all_evaluations():
    seen = []

    def f(at):
        v = two_objectives(at)
        seen.append(v)
        return v

    r = evolve(f, PARAMS, budget=600, seed=3)
    assert len(seen) == 600
    F = np.array(seen)
    best = two_objectives(r.attrs)
    dominated = (F <= best).all(axis=1) & (F < best).any(axis=1)
    assert not dominated.any()
    assert r.energy == pytest.approx(best.sum())
    assert r.energy == pytest.approx(F.sum(axis=1).min())
    assert all(b <= a for a, b in zip(r.curve, r.curve[1:]))
    # weights move the answer along the front
    ra = evolve(two_objectives, PARAMS, budget=600, seed=3, weights=[1.0, 0.01])
    rb = evolve(two_objectives, PARAMS, budget=600, seed=3, weights=[0.01, 1.0])
    assert two_objectives(ra.attrs)[0] < two_objectives(rb.attrs)[0]
    assert two_objectives(ra.attrs)[1] > two_objectives(rb.attrs)[1]


def test_spea2_fitness_and_archive_truncation():
    F = np.array([[0.0, 4.0], [1.0, 1.0], [4.0, 0.0], [1.1, 1.1], [3.0, 3.0], [1.0, 1.05]])
    assert pareto_mask(F).tolist() == [True, True, True, False, False, False]
    fit = spea2_fitness(F)
    assert (fit[:3] < 1).all() and (fit[3:] >= 1).all()     # non-dominated ⇔ R = 0
    assert fit[4] > fit[3]                                  # dominated by more / stronger
    kept = spea2_select(F, 4)                               # fill with the fittest dominated
    assert sorted(kept.tolist())[:3] == [0, 1, 2] and len(kept) == 4
    G = np.array([[0.0, 1.0], [0.5, 0.5], [0.51, 0.49], [1.0, 0.0]])
    kept = sorted(spea2_select(G, 3).tolist())               # drop one of the crowded pair
    assert kept[0] == 0 and kept[-1] == 3 and len(kept) == 3


@pytest.mark.parametrize("islands", [1, 2, 4])
def test_island_counts(islands):
    r = evolve(smooth, PARAMS, budget=400, seed=2, islands=islands, population=8,
               migration_every=2)
    assert r.derivations == 400
    assert r.energy < 0.0


def test_invalid_arguments():
    with pytest.raises(InputError):
        evolve(smooth, PARAMS, budget=0)
    with pytest.raises(InputError):
        evolve(smooth, PARAMS, budget=10, population=1)
    with pytest.raises(InputError):
        evolve(smooth, PARAMS, budget=10, islands=0)
    with pytest.raises(InputError):
        evolve(smooth, PARAMS, budget=10, crossover=1.5)
    with pytest.raises(InputError):
        evolve(smooth, [], budget=10)
    with pytest.raises(InputError):
        evolve(two_objectives, PARAMS, budget=10, weights=[1.0, 1.0, 1.0])
    with pytest.raises(InputError):
        evolve(two_objectives, PARAMS, budget=10, weights=[-1.0, 1.0])
    with pytest.raises(InputError):
        evolve(smooth, PARAMS, budget=10, seeded=1.5)


@pytest.mark.parametrize("seeded", [0.0, 0.5])
def test_islands_start_near_the_seed(seeded):
    """The first generation: the expert seed on island 0 whatever ``seeded`` says, then a
    ``seeded`` share of each island within a few small mutations of it, the rest spread."""
    calls = []

    def f(at):
        calls.append(dict(at))
        return smooth(at)

    evolve(f, PARAMS, budget=48, seed=3, islands=3, population=16, seeded=seeded)
    expert = {p.name: p.default for p in PARAMS}
    assert calls[0] == expert
    conts = [p for p in PARAMS if not p.discrete]

    def near(at):  # within 0.25 of each range, every continuous parameter
        return all(abs(at[p.name] - expert[p.name]) <= 0.25 * (p.hi - p.lo) for p in conts)

    first = [near(at) for at in calls[:48]]
    per_island = [sum(first[16 * i:16 * (i + 1)]) for i in range(3)]
    if seeded == 0.0:
        assert per_island[0] >= 1 and max(per_island) <= 6   # the seed, and hypercube luck
    else:
        assert all(n >= 8 for n in per_island)


def test_evolution_recovers_a_known_layout(known_layout):
    generic, prob, truth = known_layout
    fit = fit_module.fit_grammar(prob, ECP7, generic, method="evolution", budget=2500, seed=1)
    assert fit.search.method == "evolution" and fit.search.derivations == 2500
    assert all(b <= a for a, b in zip(fit.search.curve, fit.search.curve[1:]))
    agree = (fit.labels == truth).mean()
    assert agree > 0.85, agree
