"""Shared fixtures of the parsing tests."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.datasets import get_label_set
from facadeforge.engine import load_rules
from facadeforge.parsing.energy import SegmentationEnergy
from facadeforge.parsing.fit import grammar_path
from facadeforge.parsing.layout import SplitLayout


@pytest.fixture(scope="session")
def known_layout():
    """``(rules, prob, truth)``: a layout of the generic grammar (5 floors, 4 tiles, shops), its
    ecp7 label map, and noisy probabilities favouring it (0.7 + noise on the true class)."""
    ecp7 = get_label_set("ecp7")
    rules = load_rules(grammar_path("generic"))
    truth_attrs = {"floors": 5, "tiles": 4, "sideMargin": 0.06, "windowWidth": 0.5,
                   "windowHeight": 0.6, "groundFrac": 0.2, "groundKind": "shops",
                   "balconyFrac": 0.0, "skyFrac": 0.05, "windowsPerTile": 1}
    lay = SplitLayout(rules).derive(14.0, 21.0, truth_attrs)
    truth = SegmentationEnergy(np.full((150, 100, 7), 1 / 7, np.float32), ecp7).rasterize(lay)
    rng = np.random.default_rng(0)
    prob = np.full((150, 100, 7), 0.05, np.float32)
    np.put_along_axis(prob, truth[:, :, None].astype(int), 0.7, axis=2)
    prob += rng.uniform(0, 0.15, prob.shape).astype(np.float32)  # noise
    prob /= prob.sum(axis=2, keepdims=True)
    return rules, prob, truth
