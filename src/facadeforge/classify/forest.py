"""Randomised forests on patch tests (``simon2011`` §4.3.1), and the tree format every forest
classifier of facadeforge shares.

§4.3.1: each tree sends a pixel's patch down tests that compare two pixels of the patch or one
pixel with a threshold; a leaf holds the class histogram of the training patches that reached
it, ``P(c | l) = h_c / Σ h_i`` (eq. 4.9), and the forest averages its trees (eq. 4.10).  About ten
deep trees; the thesis settles on 10 trees of depth 18 and 15 × 15 patches (Fig. 4.7).

Here the tests are a fixed, seeded bank (:func:`~.features.draw_patch_tests`, stored with the
model) evaluated for every pixel; scikit-learn's :class:`~sklearn.ensemble.RandomForestClassifier`
grows the trees, choosing at each node the best of a random subset of tests and its threshold —
exactly a randomised tree over patch tests.  Grown trees are exported to plain arrays
(:class:`TreeEnsemble`), so models are stored without pickle and evaluated with numpy.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from .features import analysis_image, draw_patch_tests, patch_tests
from .model import PixelClassifier, register_kind

__all__ = ["ForestClassifier", "TreeEnsemble", "grow_forest"]


def check_tests(tests: np.ndarray) -> np.ndarray:
    """Patch tests read from a model file: ``(n, 5)`` integers, offsets within ±64 px, channels
    0–2 (a model file is untrusted input)."""
    t = np.asarray(tests)
    ok = (t.ndim == 2 and t.shape[1] == 5 and np.issubdtype(t.dtype, np.integer)
          and (np.abs(t[:, :2]) <= 64).all() and ((np.abs(t[:, 2:4]) <= 64) | (t[:, 2:4] == 127)
                                                  ).all() and np.isin(t[:, 4], (0, 1, 2)).all())
    if not ok:
        raise ValueError("patch tests in the model file are malformed")
    return t.astype(np.int16)


@numba.njit(cache=True, nogil=True)
def _leaves(X, feature, threshold, left, right, roots):  # pragma: no cover - compiled
    """``(T, n)`` leaf index of every row of ``X`` in every tree."""
    out = np.empty((roots.shape[0], X.shape[0]), np.int32)
    for t in range(roots.shape[0]):
        for i in range(X.shape[0]):
            node = roots[t]
            while feature[node] >= 0:
                if X[i, feature[node]] <= threshold[node]:
                    node = left[node]
                else:
                    node = right[node]
            out[t, i] = node
    return out


@dataclass(frozen=True)
class TreeEnsemble:
    """Decision trees as flat arrays (all trees' nodes concatenated).

    ``feature[n] < 0`` marks a leaf; an inner node sends ``x`` left when
    ``x[feature[n]] <= threshold[n]``.  ``value[n]`` is the class distribution of leaf ``n``.
    """

    feature: np.ndarray    # (N,) int16
    threshold: np.ndarray  # (N,) float32
    left: np.ndarray       # (N,) int32, absolute node index
    right: np.ndarray      # (N,) int32
    value: np.ndarray      # (N, K) float16
    roots: np.ndarray      # (T,) int32
    depth: int

    @classmethod
    def from_sklearn(cls, forest: Any, num_classes: int) -> TreeEnsemble:
        """Export a fitted sklearn forest whose ``classes_`` are class indices < ``num_classes``."""
        feats, thrs, lefts, rights, values, roots = [], [], [], [], [], []
        offset = 0
        depth = 0
        cols = np.asarray(forest.classes_, np.int64)
        for est in forest.estimators_:
            t = est.tree_
            n = t.node_count
            leaf = t.children_left < 0
            feats.append(np.where(leaf, -1, t.feature).astype(np.int16))
            thrs.append(t.threshold.astype(np.float32))
            lefts.append(np.where(leaf, -1, t.children_left + offset).astype(np.int32))
            rights.append(np.where(leaf, -1, t.children_right + offset).astype(np.int32))
            v = np.zeros((n, num_classes), np.float64)
            raw = t.value[:, 0, :]
            v[:, cols] = raw / np.maximum(raw.sum(axis=1, keepdims=True), 1e-12)
            values.append(v.astype(np.float16))
            roots.append(offset)
            offset += n
            depth = max(depth, int(t.max_depth))
        return cls(np.concatenate(feats), np.concatenate(thrs), np.concatenate(lefts),
                   np.concatenate(rights), np.concatenate(values),
                   np.asarray(roots, np.int32), depth)

    @property
    def num_classes(self) -> int:
        return self.value.shape[1]

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """``(n, K)`` float32 mean leaf distribution of the trees (eq. 4.10) for rows of ``X``."""
        X = np.ascontiguousarray(X, np.float32)
        self.check_features(X.shape[1])
        leaves = _leaves(X, self.feature, self.threshold, self.left, self.right, self.roots)
        out = np.zeros((X.shape[0], self.num_classes), np.float32)
        for t in range(len(self.roots)):
            out += self.value[leaves[t]]
        out /= len(self.roots)
        return out

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {f"{prefix}feature": self.feature, f"{prefix}threshold": self.threshold,
                f"{prefix}left": self.left, f"{prefix}right": self.right,
                f"{prefix}value": self.value, f"{prefix}roots": self.roots,
                f"{prefix}depth": np.asarray(self.depth)}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str,
                    num_classes: int | None = None) -> TreeEnsemble:
        """Rebuild from :meth:`to_arrays` output, checking that the arrays describe trees: a
        model file is untrusted input, and the compiled traversal does no bounds checks."""
        a = {k: np.asarray(arrays[f"{prefix}{k}"]) for k in
             ("feature", "threshold", "left", "right", "value", "roots", "depth")}
        n = len(a["feature"])
        shapes = (a["feature"].shape == (n,) and a["threshold"].shape == (n,)
                  and a["left"].shape == (n,) and a["right"].shape == (n,)
                  and a["value"].ndim == 2 and a["value"].shape[0] == n and n > 0
                  and a["roots"].ndim == 1 and a["depth"].ndim == 0
                  and all(np.issubdtype(a[k].dtype, np.integer)
                          for k in ("feature", "left", "right", "roots")))
        if not shapes:
            raise ValueError(f"tree arrays {prefix!r} have inconsistent shapes or types")
        inner = a["feature"] >= 0
        node = np.arange(n)
        # sklearn numbers children after their parent: requiring it rules out cycles
        links = (inner <= ((a["left"] > node) & (a["left"] < n) & (a["right"] > node)
                           & (a["right"] < n))).all()
        roots = ((a["roots"] >= 0) & (a["roots"] < n)).all() and len(a["roots"]) > 0
        finite = np.isfinite(a["threshold"][inner]).all() and np.isfinite(
            a["value"].astype(np.float32)).all()
        classes = num_classes is None or a["value"].shape[1] == num_classes
        if not (links and roots and finite and classes and 0 <= int(a["depth"]) < 10_000):
            raise ValueError(f"tree arrays {prefix!r} do not describe decision trees")
        return cls(a["feature"].astype(np.int16), a["threshold"].astype(np.float32),
                   a["left"].astype(np.int32), a["right"].astype(np.int32),
                   a["value"].astype(np.float16), a["roots"].astype(np.int32), int(a["depth"]))

    def check_features(self, num_features: int) -> None:
        """Raise unless every split reads a feature below ``num_features``."""
        if int(self.feature.max(initial=-1)) >= num_features:
            raise ValueError(f"the trees read feature {int(self.feature.max())} but only "
                             f"{num_features} are computed; the model file does not match this "
                             "facadeforge")


def grow_forest(X: np.ndarray, y: np.ndarray, num_classes: int, *, trees: int = 10,
                max_depth: int | None = 18, min_samples_leaf: int = 5,
                max_leaf_nodes: int | None = None, max_features: str | float = "sqrt",
                seed: int = 0, jobs: int = 2) -> TreeEnsemble:
    """Grow a randomised forest on samples ``X`` (n, F), labels ``y`` (n,) in 0..K-1."""
    from sklearn.ensemble import RandomForestClassifier

    rf = RandomForestClassifier(n_estimators=trees, max_depth=max_depth,
                                min_samples_leaf=min_samples_leaf, max_leaf_nodes=max_leaf_nodes,
                                max_features=max_features, n_jobs=jobs, random_state=seed)
    rf.fit(X, y)
    return TreeEnsemble.from_sklearn(rf, num_classes)


@register_kind
class ForestClassifier(PixelClassifier):
    """The §4.3.1 randomised forest: patch tests only (no position, no context)."""

    kind = "forest"

    def __init__(self, trees: TreeEnsemble, tests: np.ndarray, classes, label_set, meta=None):
        super().__init__(classes, label_set, meta)
        self.trees = trees
        self.tests = np.asarray(tests, np.int16)

    @staticmethod
    def features(small_rgb: np.ndarray, tests: np.ndarray) -> np.ndarray:
        return patch_tests(small_rgb, tests)

    @staticmethod
    def default_tests(seed: int = 0) -> np.ndarray:
        """96 tests in a 15 × 15 patch (the thesis's patch size) at analysis scale."""
        return draw_patch_tests(96, radius=7, seed=seed)

    def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
        small = analysis_image(image)
        f = self.features(small, self.tests)
        h, w = small.shape[:2]
        return self.trees.predict_proba(f.reshape(h * w, -1)).reshape(h, w, -1)

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"tests": self.tests, **self.trees.to_arrays("t_")}

    @classmethod
    def from_arrays(cls, arrays, classes, label_set, meta) -> ForestClassifier:
        tests = check_tests(arrays["tests"])
        trees = TreeEnsemble.from_arrays(arrays, "t_", len(classes))
        trees.check_features(len(tests))
        return cls(trees, tests, classes, label_set, meta)
