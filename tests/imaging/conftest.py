"""A facade with balconies shared by the imaging tests (as a fixture: test modules never import
this file, whose module name ``conftest`` is not unique in the test tree)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest


@dataclass(frozen=True)
class BalconyScene:
    """Class probabilities ``prob`` (H, W, K) over ``classes`` of two rows of four windows
    (25 × 35 px): a balcony ``band`` runs in front of the upper row's feet, a balcony stands in
    front of the feet of each middle window of the lower row (``per_window``); balcony pixels
    are painted over the windows, as CMP labels them.  Boxes ``(x0, y0, x1, y1)``."""

    classes: tuple[str, ...]
    prob: np.ndarray
    windows: list[tuple[int, int, int, int]]
    band: tuple[int, int, int, int]
    per_window: list[tuple[int, int, int, int]]

    @property
    def balconies(self) -> list[tuple[int, int, int, int]]:
        return [self.band, *self.per_window]


@pytest.fixture(scope="session")
def balcony_scene() -> BalconyScene:
    classes = ("background", "wall", "window", "door", "balcony", "shop")
    windows = [(20 + 50 * j, 15 + 60 * i, 45 + 50 * j, 50 + 60 * i)
               for i in range(2) for j in range(4)]
    band, per_window = (10, 40, 215, 58), [(65, 100, 100, 118), (115, 100, 150, 118)]
    index = np.full((200, 230), classes.index("wall"))
    for label, boxes in (("window", windows), ("balcony", [band, *per_window])):
        for x0, y0, x1, y1 in boxes:
            index[y0:y1, x0:x1] = classes.index(label)
    prob = (0.02 + 0.88 * np.eye(len(classes))[index]).astype(np.float32)
    return BalconyScene(classes, prob, windows, band, per_window)
