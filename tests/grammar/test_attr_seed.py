"""An attribute whose value is random (``attr h = rand(…)``) draws from a stream of its own that
follows from the derivation's seed, as the initial shape's attributes do in CityEngine."""

import numpy as np

from facadeforge import derive, load_rules

RULES = """
attr h = rand(5, 50)
attr w = rand(5, 50)
Lot --> extrude(h) s(w, '1, '1) X.
"""


def _size(seed: int) -> tuple[float, float]:
    m = derive(load_rules(RULES), lot_size="10x10", seed=seed)[0]
    v = np.concatenate([p.mesh.vertices for p in m.parts])
    ext = v.max(axis=0) - v.min(axis=0)
    return round(float(ext[1]), 6), round(float(ext[0]), 6)


def test_random_attributes_follow_the_seed_and_differ_from_each_other():
    sizes = {seed: _size(seed) for seed in range(6)}
    assert _size(3) == sizes[3]  # the same seed, the same values
    assert len({h for h, _ in sizes.values()}) >= 5  # another seed, another height
    assert all(h != w for h, w in sizes.values())  # each attribute its own draw
    assert all(5 <= h <= 50 and 5 <= w <= 50 for h, w in sizes.values())
