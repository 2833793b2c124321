"""Outcomes of CGA's random choices, one formula for deriving and for replaying.

A stochastic rule or expression (``30% : A 20% : B else : C``), ``p(prob)`` and
``listRandom(list)`` each turn one draw ``r`` in [0, 1) of the shape's random stream into a
discrete outcome.  The interpreter derives with :func:`outcome`, and instancing by chance
(``interpreter.Derivation._by_chance``) recomputes recorded outcomes with it from other shapes'
streams, so both always agree.
"""

from __future__ import annotations

import math

import numpy as np


def _whole(f):
    """``f`` (math.floor, math.ceil, round: halves to even, as numpy's rint) on a float, as a
    float; infinities and NaN as they are (numpy's rounding keeps them)."""
    return lambda x: float(f(x)) if math.isfinite(x) else x


#: ``floor(rand(lo, hi))`` and its kin: a draw rounded to a whole number is a discrete choice
ROUNDINGS = {"floor": _whole(math.floor), "ceil": _whole(math.ceil), "rint": _whole(round)}


def rand_value(r: float, params) -> float:
    """``rand(lo, hi)`` of the draw ``r`` (``params``: ``(lo, hi)``), as the builtin has it."""
    lo, hi = params
    return lo + r * (hi - lo)


def outcome(kind: str, r: float, params):
    """The outcome of a draw ``r``.

    Parameters
    ----------
    kind : {"pct", "p", "list", "floor", "ceil", "rint"}
        A stochastic choice (``params``: its percentages, in order; the outcome is the index of
        the branch taken, ``len(params)`` for ``else``), ``p(prob)`` (``params``: the
        probability; the outcome is a bool) or ``listRandom`` (``params``: the number of items;
        the outcome is the index of the item), or a rounded ``rand(lo, hi)``
        (``params``: ``(lo, hi)``; the outcome is the whole number).
    r : float
        The draw, in [0, 1).
    """
    if kind == "p":
        return r < params
    if kind in ROUNDINGS:  # floor(rand(lo, hi)): params (lo, hi)
        return float(ROUNDINGS[kind](rand_value(r, params)))
    if kind == "list":
        return min(int(r * params), params - 1)
    r = r * 100.0
    acc = 0.0
    for k, pct in enumerate(params):
        acc += pct
        if r < acc:
            return k
    return len(params)


def outcomes(kind: str, params) -> float:
    """How many outcomes a choice can have (``inf`` when it cannot be told)."""
    if kind == "p":
        return 2
    if kind == "list":
        return max(int(params), 1)
    if kind == "pct":
        return len(params) + 1
    if kind in ROUNDINGS:
        lo, hi = sorted(params)
        if not (np.isfinite(lo) and np.isfinite(hi)):
            return float("inf")
        return float(np.floor(hi) - np.floor(lo) + 2)  # floor, ceil and rint alike, at most
    return float("inf")


def combinations(choices) -> float:
    """How many outcome combinations the recorded ``choices`` of a subtree (``(path, draw,
    kind, params, outcome)``) could have had: the product of their outcome counts."""
    n = 1.0
    for _, _, kind, params, _ in choices:
        n *= outcomes(kind, params)
    return n
