"""Runs of ``True`` in a 1-D mask: the profile arithmetic behind element detection (XY-cut
rows and columns), tile refinement (the longest edge run), the facade crop and the arcade
seed of grammar parsing."""

from __future__ import annotations

import numpy as np

__all__ = ["longest_run", "runs"]


def runs(on: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` of each run of ``True`` in a 1-D mask, left to right."""
    d = np.diff(np.concatenate([[0], np.asarray(on).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def longest_run(mask: np.ndarray, gap: int = 0) -> tuple[int, int]:
    """``(start, end)`` of the longest run of ``True``, gaps of at most ``gap`` ``False``
    bridged (the first of equally long runs); ``(0, 0)`` when there is none."""
    found = runs(mask)
    if not found:
        return 0, 0
    starts = np.array([s for s, _ in found])
    ends = np.array([e for _, e in found])
    brk = starts[1:] - ends[:-1] > gap
    gs, ge = starts[np.r_[True, brk]], ends[np.r_[brk, True]]
    i = int(np.argmax(ge - gs))
    return int(gs[i]), int(ge[i])
