"""Auto-context forests: the stronger pixel classifier, trained here from the shared datasets.

The thesis's randomised forest (§4.3.1, :mod:`.forest`) sees a 15 × 15 patch and nothing else;
its window detection rate is 30 %.  Facades are far more predictable than that from *context*:
windows come in rows and columns, sky is on top, shops at the bottom.  Auto-context (Tu & Bai,
PAMI 2010), which Jampani, Gadde & Gehler (WACV 2015) showed to be state of the art on facade
datasets with simple features, feeds each stage the previous stage's probability maps as extra
features:

- stage 0: :func:`~.features.appearance_features` (colour and filter bank, position, row/column
  edge profiles) plus 32 §4.3.1 patch tests;
- stage s ≥ 1: the same appearance features plus :func:`~.features.context_features` of stage
  s − 1 (probabilities at the pixel, at 8 offsets, and along its row and column).

Each stage is a :class:`~.forest.TreeEnsemble`.  Training (:func:`.train.train_classifier`)
gives stage s + 1 out-of-fold probabilities of stage s, so it learns how much to trust them on
facades the earlier stage has not seen.
"""

from __future__ import annotations

import numpy as np

from .features import (
    APPEARANCE_NAMES,
    analysis_image,
    appearance_features,
    context_features,
    draw_patch_tests,
    patch_tests,
)
from .forest import TreeEnsemble, check_tests
from .model import PixelClassifier, register_kind

__all__ = ["AutoContextClassifier", "stage_features"]

PATCH_TESTS = 32


def stage_features(small_rgb: np.ndarray, stage: int, tests: np.ndarray,
                   previous: np.ndarray | None, appearance: np.ndarray | None = None
                   ) -> np.ndarray:
    """``(h, w, F)`` features of ``stage`` on analysis image ``small_rgb``.

    ``previous`` is stage ``stage - 1``'s ``(h, w, K)`` probabilities (None for stage 0);
    ``appearance`` may pass precomputed :func:`appearance_features`.
    """
    app = appearance_features(small_rgb) if appearance is None else appearance
    if stage == 0:
        return np.concatenate([app, patch_tests(small_rgb, tests)], axis=2)
    if previous is None:
        raise ValueError("stages after the first need the previous stage's probabilities")
    return np.concatenate([app, context_features(previous)], axis=2)


@register_kind
class AutoContextClassifier(PixelClassifier):
    """A chain of forests, each reading the previous one's probability maps (module docstring)."""

    kind = "autocontext"

    def __init__(self, stages: list[TreeEnsemble], tests: np.ndarray, classes, label_set,
                 meta=None):
        super().__init__(classes, label_set, meta)
        if not stages:
            raise ValueError("an auto-context classifier needs at least one stage")
        self.stages = list(stages)
        self.tests = np.asarray(tests, np.int16)

    @staticmethod
    def default_tests(seed: int = 0) -> np.ndarray:
        return draw_patch_tests(PATCH_TESTS, radius=7, seed=seed)

    def predict_small(self, small: np.ndarray) -> np.ndarray:
        """``(h, w, K)`` probabilities of the last stage on an analysis-scale image."""
        h, w = small.shape[:2]
        app = appearance_features(small)
        prob = None
        for s, trees in enumerate(self.stages):
            f = stage_features(small, s, self.tests, prob, app)
            prob = trees.predict_proba(f.reshape(h * w, -1)).reshape(h, w, -1)
        return prob

    def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
        return self.predict_small(analysis_image(image))

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"tests": self.tests, "num_stages": np.asarray(len(self.stages))}
        for s, trees in enumerate(self.stages):
            out.update(trees.to_arrays(f"s{s}_"))
        return out

    @classmethod
    def from_arrays(cls, arrays, classes, label_set, meta) -> AutoContextClassifier:
        n = int(arrays["num_stages"])
        if not 1 <= n <= 16:
            raise ValueError(f"{n} auto-context stages in the model file")
        tests = check_tests(arrays["tests"])
        stages = [TreeEnsemble.from_arrays(arrays, f"s{s}_", len(classes)) for s in range(n)]
        k = len(classes)
        for s, trees in enumerate(stages):
            trees.check_features(len(APPEARANCE_NAMES) + (len(tests) if s == 0 else 11 * k))
        return cls(stages, tests, classes, label_set, meta)
