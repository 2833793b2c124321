"""Runs of True in 1-D masks (imaging/runs.py)."""

from __future__ import annotations

import numpy as np

from facadeforge.imaging.runs import longest_run, runs


def test_runs_are_half_open_and_ordered():
    m = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1, 1], bool)
    assert runs(m) == [(1, 3), (5, 6), (7, 10)]
    assert runs(np.zeros(4, bool)) == [] and runs(np.ones(3, bool)) == [(0, 3)]


def test_longest_run_bridges_small_gaps_only():
    m = np.array([1, 1, 0, 1, 0, 0, 0, 1, 1, 1, 1, 0], bool)
    assert longest_run(m) == (7, 11)
    assert longest_run(m, gap=1) == (0, 4)            # as long as (7, 11): the first wins
    assert longest_run(m, gap=3) == (0, 11)
    assert longest_run(np.zeros(5, bool)) == (0, 0)
