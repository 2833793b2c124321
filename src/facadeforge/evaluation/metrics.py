"""Benchmark metrics: semantic labelling, window detection, structure counts and run cost.

Conventions
-----------
Semantic labelling
    A confusion matrix ``C`` of shape ``(K, K)`` has rows = ground truth, columns = prediction:
    ``C[i, j]`` counts pixels labelled ``i`` that were predicted ``j``.  Pixels whose truth equals
    ``ignore_index`` are left out (whatever was predicted there).  Any other truth or prediction
    outside ``[0, K)`` raises :class:`MetricInputError` instead of being dropped silently.
    Per-class accuracy (recall) is ``NaN`` for a class absent from the truth; per-class IoU is
    ``NaN`` where the union is empty (absent from truth *and* prediction).  A class absent from the
    truth but predicted somewhere has IoU 0: its false positives are penalised.  Means
    (class-average accuracy, mIoU) skip ``NaN`` entries; a mean over nothing is ``NaN``.
    Scores from a matrix accumulated over a data set are *data-set level* (pixels pooled), the
    usual convention of the facade-parsing literature.
Object detection
    Boxes are ``(x0, y0, x1, y1)`` in pixels, ``x1``/``y1`` exclusive, so a box's area is
    ``(x1 - x0) * (y1 - y0)``; degenerate boxes have area 0 and never match.  A prediction matches
    a truth box when IoU >= ``threshold`` (0.5), one-to-one, greedily.  Counts are pooled over
    images (micro average).  ``precision = tp / (tp + fp)`` is 1 when nothing was predicted,
    ``recall = tp / (tp + fn)`` is 1 when there was nothing to find, and
    ``f1 = 2 tp / (2 tp + fp + fn)`` (the harmonic mean of the two) is 1 when both are empty.
    So an image with no windows and no predictions scores P = R = F1 = 1; no predictions on an
    image with windows scores P = 1, R = 0, F1 = 0; predictions on an image without windows
    score P = 0, R = 1, F1 = 0.
Structure counts
    Absolute error ``|pred - true|`` per image; a summary gives the mean absolute error and the
    exact-match rate (fraction of images with error 0).
Run cost
    :func:`measure` reports wall-clock seconds (``time.perf_counter``) and peak bytes allocated
    while the call ran, as seen by ``tracemalloc``.
"""

from __future__ import annotations

import math
import sys
import time
import tracemalloc
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError

__all__ = [
    "MetricInputError",
    "confusion_matrix",
    "ConfusionAccumulator",
    "pixel_accuracy",
    "class_accuracies",
    "class_average_accuracy",
    "iou_per_class",
    "mean_iou",
    "row_normalised",
    "SegmentationScores",
    "box_iou",
    "greedy_match",
    "match_boxes",
    "DetectionScores",
    "DetectionAccumulator",
    "count_error",
    "count_scores",
    "CountScores",
    "StructureCountAccumulator",
    "RunCost",
    "measure",
]


class MetricInputError(InputError, ValueError):
    """An array handed to a metric has the wrong shape, dtype or values.

    Subclasses both :class:`~facadeforge.errors.InputError` and :class:`ValueError`, so callers
    may catch either.
    """


# -- helpers -----------------------------------------------------------------------------------


def _nan_mean(values: np.ndarray) -> float:
    """Mean of the finite entries of ``values``; ``NaN`` (without a warning) when there are none."""
    ok = ~np.isnan(values)
    return float(values[ok].mean()) if ok.any() else math.nan


def _safe_divide(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """``num / den`` as float64 with ``NaN`` where ``den == 0``."""
    num = np.asarray(num, np.float64)
    den = np.asarray(den, np.float64)
    out = np.full(np.broadcast(num, den).shape, np.nan)
    np.divide(num, den, out=out, where=den != 0)
    return out


def _json_float(x: float) -> float | None:
    """A Python float, or ``None`` for NaN (JSON has no NaN)."""
    x = float(x)
    return None if math.isnan(x) else x


def _json_matrix(m: np.ndarray) -> list:
    """Nested lists of Python floats with ``None`` for NaN."""
    return [[_json_float(v) for v in row] for row in np.asarray(m, np.float64)]


def _label_array(a, name: str) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype == np.bool_:
        return a.astype(np.int64)
    if not np.issubdtype(a.dtype, np.integer):
        raise MetricInputError(
            f"{name}: label map has dtype {a.dtype}, expected integers; "
            f"convert class ids with `.astype(np.int64)` (not colours or probabilities)")
    return a


def _check_confusion(confusion) -> np.ndarray:
    c = np.asarray(confusion)
    if c.ndim != 2 or c.shape[0] != c.shape[1] or c.shape[0] == 0:
        raise MetricInputError(
            f"confusion: expected a square (K, K) matrix with K >= 1, got shape {c.shape}; "
            f"build it with confusion_matrix() or ConfusionAccumulator")
    if not (np.issubdtype(c.dtype, np.integer) or np.issubdtype(c.dtype, np.floating)):
        raise MetricInputError(f"confusion: dtype {c.dtype} is not numeric; pass pixel counts")
    if np.issubdtype(c.dtype, np.floating) and not np.isfinite(c).all():
        raise MetricInputError("confusion: contains NaN or infinity; pass raw pixel counts, "
                               "not a normalised matrix")
    if (c < 0).any():
        raise MetricInputError("confusion: contains negative counts; pass raw pixel counts")
    return c


# -- semantic labelling --------------------------------------------------------------------------


def confusion_matrix(truth, pred, n_classes: int, ignore_index: int | None = 255) -> np.ndarray:
    """Pixel confusion matrix of one label map against its ground truth.

    Parameters
    ----------
    truth : (H, W) int array
        Ground-truth class ids in ``[0, n_classes)``, or ``ignore_index``.  Any shape works as
        long as ``pred`` has the same one.
    pred : (H, W) int array
        Predicted class ids in ``[0, n_classes)`` (checked only where truth is not ignored).
    n_classes : int
        ``K``, the number of classes.
    ignore_index : int or None
        Truth value marking unlabelled pixels, excluded from the matrix; ``None`` keeps every
        pixel.

    Returns
    -------
    (K, K) int64
        ``C[i, j]`` = number of pixels with truth ``i`` predicted as ``j``.

    Raises
    ------
    MetricInputError
        Shapes differ, labels are not integers, ``n_classes < 1``, or a non-ignored truth or
        prediction lies outside ``[0, n_classes)``.
    """
    k = int(n_classes)
    if k < 1:
        raise MetricInputError(f"n_classes: got {n_classes}, need at least 1 class")
    truth = _label_array(truth, "truth")
    pred = _label_array(pred, "pred")
    if truth.shape != pred.shape:
        raise MetricInputError(
            f"pred: shape {pred.shape} differs from truth shape {truth.shape}; score predictions "
            f"in the ground truth's pixel frame (resample or warp back first)")
    t = truth.ravel()
    p = pred.ravel()
    if ignore_index is not None:
        keep = t != ignore_index
        if not keep.all():
            t, p = t[keep], p[keep]
    t = t.astype(np.int64, copy=False)
    p = p.astype(np.int64, copy=False)
    for arr, name in ((t, "truth"), (p, "pred")):
        bad = (arr < 0) | (arr >= k)
        if bad.any():
            values = np.unique(arr[bad])
            shown = ", ".join(str(v) for v in values[:8]) + (", …" if values.size > 8 else "")
            hint = (f"map labels to 0..{k - 1} or pass ignore_index={values[0]}"
                    if name == "truth" else f"the method must output class ids 0..{k - 1}")
            raise MetricInputError(
                f"{name}: {int(bad.sum())} non-ignored pixel(s) have class ids outside "
                f"[0, {k}) ({shown}); {hint}")
    return np.bincount(t * k + p, minlength=k * k).reshape(k, k).astype(np.int64, copy=False)


class ConfusionAccumulator:
    """Sum of per-image confusion matrices over a data set.

    Parameters
    ----------
    n_classes : int
        ``K``.
    ignore_index : int or None
        As in :func:`confusion_matrix`.

    Attributes
    ----------
    matrix : (K, K) int64
        The running total.
    n_images : int
        Number of images added.
    """

    def __init__(self, n_classes: int, ignore_index: int | None = 255):
        if int(n_classes) < 1:
            raise MetricInputError(f"n_classes: got {n_classes}, need at least 1 class")
        self.n_classes = int(n_classes)
        self.ignore_index = ignore_index
        self.matrix = np.zeros((self.n_classes, self.n_classes), np.int64)
        self.n_images = 0

    def add(self, truth, pred) -> np.ndarray:
        """Add one image; returns its own (K, K) int64 matrix (for per-image scores)."""
        c = confusion_matrix(truth, pred, self.n_classes, self.ignore_index)
        self.matrix += c
        self.n_images += 1
        return c

    def scores(self) -> SegmentationScores:
        """Scores of the pooled matrix."""
        return SegmentationScores.from_confusion(self.matrix)


def pixel_accuracy(confusion) -> float:
    """Fraction of counted pixels labelled correctly: ``trace(C) / sum(C)``; NaN if empty.

    Parameters
    ----------
    confusion : (K, K) array of counts
    """
    c = _check_confusion(confusion)
    total = c.sum()
    return float(np.trace(c) / total) if total > 0 else math.nan


def class_accuracies(confusion) -> np.ndarray:
    """Per-class recall ``C[i, i] / sum_j C[i, j]``.

    Parameters
    ----------
    confusion : (K, K) array of counts

    Returns
    -------
    (K,) float64
        NaN for classes absent from the truth (empty row).
    """
    c = _check_confusion(confusion)
    return _safe_divide(np.diag(c), c.sum(axis=1))


def class_average_accuracy(confusion) -> float:
    """Mean of :func:`class_accuracies` over the classes present in the truth (NaN if none)."""
    return _nan_mean(class_accuracies(confusion))


def iou_per_class(confusion) -> np.ndarray:
    """Per-class intersection over union ``C[i, i] / (row_i + col_i - C[i, i])``.

    Parameters
    ----------
    confusion : (K, K) array of counts

    Returns
    -------
    (K,) float64
        NaN where the union is empty (class neither in truth nor in prediction).
    """
    c = _check_confusion(confusion)
    diag = np.diag(c).astype(np.float64)
    return _safe_divide(diag, c.sum(axis=0) + c.sum(axis=1) - diag)


def mean_iou(confusion) -> float:
    """Mean of :func:`iou_per_class` over classes with a non-empty union (NaN if none)."""
    return _nan_mean(iou_per_class(confusion))


def row_normalised(confusion) -> np.ndarray:
    """Confusion matrix with each truth row scaled to percent.

    Parameters
    ----------
    confusion : (K, K) array of counts

    Returns
    -------
    (K, K) float64
        ``100 * C[i, j] / sum_j C[i, j]``; rows of classes absent from the truth are NaN.
    """
    c = _check_confusion(confusion)
    return 100.0 * _safe_divide(c, c.sum(axis=1, keepdims=True))


@dataclass(frozen=True)
class SegmentationScores:
    """All semantic-labelling scores of one confusion matrix.

    Attributes
    ----------
    confusion : (K, K) int64
        Counts, rows = truth, columns = prediction.
    pixel_accuracy : float
    class_accuracies : (K,) float64
        NaN for classes absent from the truth.
    class_avg_accuracy : float
    iou : (K,) float64
        NaN where the union is empty.
    miou : float
    support : (K,) int64
        Truth pixels per class (row sums).
    """

    confusion: np.ndarray
    pixel_accuracy: float
    class_accuracies: np.ndarray
    class_avg_accuracy: float
    iou: np.ndarray
    miou: float
    support: np.ndarray

    @classmethod
    def from_confusion(cls, confusion) -> SegmentationScores:
        """Compute every score from a ``(K, K)`` count matrix."""
        c = _check_confusion(confusion)
        if np.issubdtype(c.dtype, np.floating):
            if (c != np.round(c)).any():
                raise MetricInputError("confusion: counts are not whole numbers; pass raw pixel "
                                       "counts, not a normalised matrix")
        c = c.astype(np.int64)
        acc = class_accuracies(c)
        iou = iou_per_class(c)
        return cls(confusion=c, pixel_accuracy=pixel_accuracy(c), class_accuracies=acc,
                   class_avg_accuracy=_nan_mean(acc), iou=iou, miou=_nan_mean(iou),
                   support=c.sum(axis=1))

    @property
    def n_classes(self) -> int:
        return int(self.confusion.shape[0])

    def confusion_percent(self) -> np.ndarray:
        """(K, K) float64 row-normalised confusion in percent (see :func:`row_normalised`)."""
        return row_normalised(self.confusion)

    def to_dict(self, class_names: Sequence[str] | None = None) -> dict[str, Any]:
        """JSON-ready summary; NaN becomes ``None``.

        Parameters
        ----------
        class_names : sequence of K str, optional
            Keys of ``per_class``; default ``"0"``, ``"1"``, ...

        Returns
        -------
        dict
            ``pixel_accuracy``, ``class_avg_accuracy``, ``miou`` (float or None), ``per_class``
            (name -> ``{"accuracy", "iou", "support"}``), ``confusion`` (K lists of K int) and
            ``confusion_percent`` (K lists of K float or None).
        """
        k = self.n_classes
        names = [str(i) for i in range(k)] if class_names is None else [str(n) for n in class_names]
        if len(names) != k:
            raise MetricInputError(
                f"class_names: got {len(names)} names for {k} classes; pass one name per row of "
                f"the confusion matrix")
        if len(set(names)) != k:
            raise MetricInputError("class_names: names must be unique (they key per_class)")
        return {
            "pixel_accuracy": _json_float(self.pixel_accuracy),
            "class_avg_accuracy": _json_float(self.class_avg_accuracy),
            "miou": _json_float(self.miou),
            "per_class": {
                name: {"accuracy": _json_float(a), "iou": _json_float(u), "support": int(s)}
                for name, a, u, s in zip(names, self.class_accuracies, self.iou, self.support)
            },
            "confusion": self.confusion.astype(np.int64).tolist(),
            "confusion_percent": _json_matrix(self.confusion_percent()),
        }


# -- object detection ----------------------------------------------------------------------------


def _boxes(a, name: str) -> np.ndarray:
    b = np.asarray(a, np.float64)
    if b.size == 0:
        return b.reshape(0, 4)
    if b.ndim != 2 or b.shape[1] != 4:
        raise MetricInputError(
            f"{name}: expected an (N, 4) array of boxes x0, y0, x1, y1, got shape {b.shape}")
    if not np.isfinite(b).all():
        raise MetricInputError(f"{name}: boxes contain NaN or infinity; drop or fix those boxes")
    return b


def _area(b: np.ndarray) -> np.ndarray:
    return np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)


def box_iou(a, b) -> np.ndarray:
    """Pairwise intersection over union of two sets of axis-aligned boxes.

    Parameters
    ----------
    a : (N, 4) float
        Boxes ``x0, y0, x1, y1`` in pixels, ``x1``/``y1`` exclusive.
    b : (M, 4) float

    Returns
    -------
    (N, M) float64
        IoU in ``[0, 1]``; 0 where the union is empty (two degenerate boxes).
    """
    a = _boxes(a, "a")
    b = _boxes(b, "b")
    ix = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]),
                 0, None)
    iy = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]),
                 0, None)
    inter = ix * iy
    union = _area(a)[:, None] + _area(b)[None, :] - inter
    out = np.zeros_like(inter)
    np.divide(inter, union, out=out, where=union > 0)
    return out


def greedy_match(truth, pred, scores=None, threshold: float = 0.5) -> np.ndarray:
    """One-to-one greedy matching of predicted boxes to truth boxes.

    With ``scores``, predictions are visited in descending score order (ties: input order) and
    each takes the still-unmatched truth box of highest IoU, if that IoU >= ``threshold``
    (PASCAL VOC / COCO style).  Without scores, candidate pairs are taken in descending IoU order
    (ties: truth index, then prediction index) while both boxes are free.

    Parameters
    ----------
    truth : (N, 4) float
    pred : (M, 4) float
    scores : (M,) float, optional
        Prediction confidences.
    threshold : float
        Minimum IoU of a match (inclusive).

    Returns
    -------
    (P, 2) int64
        Matched ``(truth_index, pred_index)`` pairs, ``P <= min(N, M)``.
    """
    truth = _boxes(truth, "truth")
    pred = _boxes(pred, "pred")
    iou = box_iou(truth, pred)
    n, m = iou.shape
    if not 0.0 < threshold <= 1.0:
        raise MetricInputError(f"threshold: IoU threshold {threshold} is not in (0, 1]")
    pairs: list[tuple[int, int]] = []
    if n == 0 or m == 0:
        return np.zeros((0, 2), np.int64)
    if scores is not None:
        s = np.asarray(scores, np.float64).ravel()
        if s.shape != (m,):
            raise MetricInputError(
                f"scores: got {s.shape[0]} scores for {m} predicted boxes; pass one per box")
        if np.isnan(s).any():
            raise MetricInputError("scores: contain NaN; give every prediction a confidence")
        free = np.ones(n, bool)
        # One step per prediction (not per pixel): each step is a vector op over the truth boxes.
        for j in np.argsort(-s, kind="stable"):
            col = np.where(free, iou[:, j], -1.0)
            i = int(np.argmax(col))
            if col[i] >= threshold:
                free[i] = False
                pairs.append((i, int(j)))
    else:
        ti, pj = np.nonzero(iou >= threshold)
        order = np.lexsort((pj, ti, -iou[ti, pj]))
        used_t = np.zeros(n, bool)
        used_p = np.zeros(m, bool)
        for i, j in zip(ti[order].tolist(), pj[order].tolist()):
            if not used_t[i] and not used_p[j]:
                used_t[i] = used_p[j] = True
                pairs.append((i, j))
    return np.asarray(pairs, np.int64).reshape(-1, 2)


@dataclass(frozen=True)
class DetectionScores:
    """Matched-detection counts and the scores derived from them.

    Counts add up over images with ``+`` or :meth:`total` (micro average).  See the module
    docstring for the 0/0 conventions.

    Attributes
    ----------
    tp, fp, fn : int
        True positives (matched predictions), false positives (unmatched predictions), false
        negatives (unmatched truth boxes).
    """

    tp: int = 0
    fp: int = 0
    fn: int = 0

    def __add__(self, other: DetectionScores) -> DetectionScores:
        if not isinstance(other, DetectionScores):
            return NotImplemented
        return DetectionScores(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn)

    @classmethod
    def total(cls, items: Iterable[DetectionScores]) -> DetectionScores:
        """Sum of the counts of many images."""
        out = cls()
        for item in items:
            out = out + item
        return out

    @property
    def precision(self) -> float:
        """``tp / (tp + fp)``; 1.0 when nothing was predicted."""
        d = self.tp + self.fp
        return self.tp / d if d else 1.0

    @property
    def recall(self) -> float:
        """``tp / (tp + fn)``; 1.0 when there was nothing to find."""
        d = self.tp + self.fn
        return self.tp / d if d else 1.0

    @property
    def f1(self) -> float:
        """``2 tp / (2 tp + fp + fn)``; 1.0 when there is neither truth nor prediction."""
        d = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / d if d else 1.0

    def to_dict(self, prefix: str = "") -> dict[str, Any]:
        """``{prefix+"precision", ... "recall", "f1", "tp", "fp", "fn"}`` (JSON-ready)."""
        return {f"{prefix}precision": self.precision, f"{prefix}recall": self.recall,
                f"{prefix}f1": self.f1, f"{prefix}tp": self.tp, f"{prefix}fp": self.fp,
                f"{prefix}fn": self.fn}


def match_boxes(truth, pred, scores=None, threshold: float = 0.5) -> DetectionScores:
    """Count true/false positives and misses of one image's boxes.

    Parameters
    ----------
    truth : (N, 4) float
        Ground-truth boxes ``x0, y0, x1, y1`` (pixels, ``x1``/``y1`` exclusive).
    pred : (M, 4) float
        Predicted boxes.
    scores : (M,) float, optional
        Confidences; see :func:`greedy_match` for the matching order.
    threshold : float
        Minimum IoU of a match (inclusive), 0.5 by default.

    Returns
    -------
    DetectionScores
        ``tp`` = matches, ``fp = M - tp``, ``fn = N - tp``.
    """
    pairs = greedy_match(truth, pred, scores, threshold)
    n = _boxes(truth, "truth").shape[0]
    m = _boxes(pred, "pred").shape[0]
    tp = int(pairs.shape[0])
    return DetectionScores(tp=tp, fp=m - tp, fn=n - tp)


class DetectionAccumulator:
    """Pooled detection counts over a data set.

    Parameters
    ----------
    threshold : float
        IoU threshold of a match.

    Attributes
    ----------
    scores : DetectionScores
        The running total.
    n_images : int
    """

    def __init__(self, threshold: float = 0.5):
        self.threshold = threshold
        self.scores = DetectionScores()
        self.n_images = 0

    def add(self, truth, pred, scores=None) -> DetectionScores:
        """Match one image's boxes, add its counts; returns that image's counts."""
        s = match_boxes(truth, pred, scores, self.threshold)
        self.scores = self.scores + s
        self.n_images += 1
        return s


# -- structure counts ----------------------------------------------------------------------------


def _counts(a, name: str) -> np.ndarray:
    c = np.asarray(a)
    if not (np.issubdtype(c.dtype, np.integer) or np.issubdtype(c.dtype, np.floating)):
        raise MetricInputError(f"{name}: counts have dtype {c.dtype}; pass whole numbers")
    if np.issubdtype(c.dtype, np.floating):
        if not np.isfinite(c).all() or (c != np.round(c)).any():
            raise MetricInputError(f"{name}: counts must be finite whole numbers, got {a!r}; "
                                   f"round the estimate before scoring")
    if (c < 0).any():
        raise MetricInputError(f"{name}: counts must be >= 0, got {a!r}")
    return c.astype(np.int64)


def count_error(true_count, pred_count):
    """Absolute count error ``|pred - true|``.

    Parameters
    ----------
    true_count : int or (n,) int
    pred_count : int or (n,) int
        Same shape as ``true_count``.

    Returns
    -------
    int or (n,) int64
        An ``int`` for scalar inputs, else an array.
    """
    t = _counts(true_count, "true_count")
    p = _counts(pred_count, "pred_count")
    if t.shape != p.shape:
        raise MetricInputError(
            f"pred_count: shape {p.shape} differs from true_count shape {t.shape}; pass one "
            f"predicted count per image")
    err = np.abs(p - t)
    return int(err) if err.ndim == 0 else err


@dataclass(frozen=True)
class CountScores:
    """Summary of per-image count errors.

    Attributes
    ----------
    n_images : int
    mean_abs_error : float
        NaN when ``n_images == 0``.
    exact_match_rate : float
        Fraction of images with error 0; NaN when ``n_images == 0``.
    max_abs_error : int
        0 when ``n_images == 0``.
    """

    n_images: int
    mean_abs_error: float
    exact_match_rate: float
    max_abs_error: int

    def to_dict(self, prefix: str = "") -> dict[str, Any]:
        """JSON-ready dict with keys ``prefix + {n_images, mae, exact, max_error}``."""
        return {f"{prefix}n_images": self.n_images, f"{prefix}mae": _json_float(self.mean_abs_error),
                f"{prefix}exact": _json_float(self.exact_match_rate),
                f"{prefix}max_error": self.max_abs_error}


def count_scores(true_counts, pred_counts) -> CountScores:
    """Mean absolute error and exact-match rate of counts over images.

    Parameters
    ----------
    true_counts : (n,) int
    pred_counts : (n,) int

    Returns
    -------
    CountScores
    """
    err = np.atleast_1d(count_error(np.atleast_1d(np.asarray(true_counts)).ravel(),
                                    np.atleast_1d(np.asarray(pred_counts)).ravel()))
    n = int(err.size)
    if n == 0:
        return CountScores(0, math.nan, math.nan, 0)
    return CountScores(n, float(err.mean()), float((err == 0).mean()), int(err.max()))


class StructureCountAccumulator:
    """Floor and column count errors over a data set.

    Images where a method gives no estimate (``None``) for a quantity are left out of that
    quantity's scores.
    """

    def __init__(self):
        self._floors: list[tuple[int, int]] = []
        self._columns: list[tuple[int, int]] = []

    def add(self, true_floors=None, pred_floors=None, true_columns=None, pred_columns=None):
        """Record one image's floor and/or column counts (a pair with a ``None`` is skipped)."""
        if true_floors is not None and pred_floors is not None:
            count_error(true_floors, pred_floors)  # validates
            self._floors.append((int(true_floors), int(pred_floors)))
        if true_columns is not None and pred_columns is not None:
            count_error(true_columns, pred_columns)
            self._columns.append((int(true_columns), int(pred_columns)))

    @staticmethod
    def _scores(pairs: list[tuple[int, int]]) -> CountScores:
        a = np.asarray(pairs, np.int64).reshape(-1, 2)
        return count_scores(a[:, 0], a[:, 1])

    @property
    def floors(self) -> CountScores:
        return self._scores(self._floors)

    @property
    def columns(self) -> CountScores:
        return self._scores(self._columns)

    def to_dict(self) -> dict[str, Any]:
        """``floor_count_*`` and ``column_count_*`` keys (see :meth:`CountScores.to_dict`)."""
        return {**self.floors.to_dict("floor_count_"), **self.columns.to_dict("column_count_")}


# -- run cost ------------------------------------------------------------------------------------


class RunCost(NamedTuple):
    """Result of :func:`measure`; unpacks as ``result, seconds, peak_memory_bytes``."""

    result: Any
    seconds: float
    peak_memory_bytes: int


def _peak_rss_bytes() -> int:
    """Peak resident set size of this process (0 where the platform does not report it)."""
    try:
        import resource
    except ImportError:  # Windows
        return 0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak) if sys.platform == "darwin" else int(peak) * 1024  # macOS reports bytes


def measure(fn: Callable[..., Any], *args, trace_memory: bool = True, **kwargs) -> RunCost:
    """Call ``fn(*args, **kwargs)`` and report its wall time and peak memory.

    Parameters
    ----------
    fn : callable
    *args, **kwargs
        Passed to ``fn``.
    trace_memory : bool
        ``False``: do not trace (no slowdown); the memory figure is then the process's peak
        resident set size so far (``ru_maxrss``), not the call's own peak.

    Returns
    -------
    RunCost
        ``(result, seconds, peak_memory_bytes)``.  ``seconds`` is ``time.perf_counter`` wall
        time.  ``peak_memory_bytes`` is the peak of memory traced by ``tracemalloc`` during the
        call, above what was traced when it began: allocations through Python's allocators,
        which include numpy array buffers (numpy reports them to ``tracemalloc``).  Memory
        allocated by native libraries outside those allocators (e.g. some C/C++ or GPU
        libraries) is not counted.  Tracing slows allocation-heavy Python code, so the time
        includes that overhead; compare timings taken the same way.

    Notes
    -----
    If ``tracemalloc`` is already tracing (e.g. nested ``measure`` calls), it is left running,
    but its peak is reset, so an enclosing measurement may under-report its own peak.
    """
    if not trace_memory:
        t0 = time.perf_counter()
        result = fn(*args, **kwargs)
        seconds = time.perf_counter() - t0
        return RunCost(result, seconds, _peak_rss_bytes())
    was_tracing = tracemalloc.is_tracing()
    if not was_tracing:
        tracemalloc.start()
    base, _ = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()
    t0 = time.perf_counter()
    try:
        result = fn(*args, **kwargs)
    finally:
        seconds = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        if not was_tracing:
            tracemalloc.stop()
    return RunCost(result, seconds, max(int(peak) - int(base), 0))
