"""Outcomes of CGA's random choices, one formula for deriving and for replaying.

A stochastic rule or expression (``30% : A 20% : B else : C``), ``p(prob)`` and
``listRandom(list)`` each turn one draw ``r`` in [0, 1) of the shape's random stream into a
discrete outcome.  The interpreter derives with :func:`outcome`, and instancing by chance
(``interpreter.Derivation._by_chance``) recomputes recorded outcomes with it from other shapes'
streams, so both always agree.
"""

from __future__ import annotations


def outcome(kind: str, r: float, params):
    """The outcome of a draw ``r``.

    Parameters
    ----------
    kind : {"pct", "p", "list"}
        A stochastic choice (``params``: its percentages, in order; the outcome is the index of
        the branch taken, ``len(params)`` for ``else``), ``p(prob)`` (``params``: the
        probability; the outcome is a bool) or ``listRandom`` (``params``: the number of items;
        the outcome is the index of the item).
    r : float
        The draw, in [0, 1).
    """
    if kind == "p":
        return r < params
    if kind == "list":
        return min(int(r * params), params - 1)
    r = r * 100.0
    acc = 0.0
    for k, pct in enumerate(params):
        acc += pct
        if r < acc:
            return k
    return len(params)
