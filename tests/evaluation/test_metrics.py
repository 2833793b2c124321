"""Benchmark metrics against hand-computed small cases, plus a few properties."""

import json
import math
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from facadeforge.errors import InputError
from facadeforge.evaluation import (
    ConfusionAccumulator,
    DetectionAccumulator,
    DetectionScores,
    MetricInputError,
    SegmentationScores,
    StructureCountAccumulator,
    box_iou,
    class_accuracies,
    class_average_accuracy,
    confusion_matrix,
    count_error,
    count_scores,
    greedy_match,
    iou_per_class,
    match_boxes,
    mean_iou,
    measure,
    pixel_accuracy,
    row_normalised,
)

# 3x4 case, K = 3.  Supports: class 0 -> 4 px, class 1 -> 5 px, class 2 -> 3 px.
TRUTH = np.array([[0, 0, 1, 1],
                  [0, 0, 1, 1],
                  [2, 2, 2, 1]])
PRED = np.array([[0, 1, 1, 1],
                 [0, 0, 1, 2],
                 [2, 0, 2, 1]])
C = np.array([[3, 1, 0],
              [0, 4, 1],
              [1, 0, 2]])


# -- semantic labelling ------------------------------------------------------------------------


def test_confusion_matrix_hand_case():
    c = confusion_matrix(TRUTH, PRED, 3)
    assert c.dtype == np.int64
    np.testing.assert_array_equal(c, C)


def test_scores_hand_case():
    assert pixel_accuracy(C) == pytest.approx(9 / 12)
    np.testing.assert_allclose(class_accuracies(C), [3 / 4, 4 / 5, 2 / 3])
    assert class_average_accuracy(C) == pytest.approx((3 / 4 + 4 / 5 + 2 / 3) / 3)
    # IoU = diag / (row + col - diag): 3/(4+4-3), 4/(5+5-4), 2/(3+3-2)
    np.testing.assert_allclose(iou_per_class(C), [3 / 5, 2 / 3, 1 / 2])
    assert mean_iou(C) == pytest.approx((3 / 5 + 2 / 3 + 1 / 2) / 3)
    np.testing.assert_allclose(row_normalised(C), [[75, 25, 0], [0, 80, 20],
                                                   [100 / 3, 0, 200 / 3]])


def test_ignore_index_honoured():
    truth = TRUTH.copy()
    pred = PRED.copy()
    truth[2, :] = 255
    pred[2, :] = 9  # out of range, but only where truth is ignored: not an error
    c = confusion_matrix(truth, pred, 3)
    np.testing.assert_array_equal(c, [[3, 1, 0], [0, 3, 1], [0, 0, 0]])
    assert c.sum() == 8
    # ignore_index=None counts everything, so 255 in truth is then an error
    with pytest.raises(MetricInputError, match="truth"):
        confusion_matrix(truth, PRED, 3, ignore_index=None)
    # a class id may itself be the ignore label (RueMonge's class 0)
    c0 = confusion_matrix(TRUTH, PRED, 3, ignore_index=0)
    np.testing.assert_array_equal(c0, [[0, 0, 0], [0, 4, 1], [1, 0, 2]])


def test_absent_class_gives_nan_and_is_excluded_from_means():
    c = confusion_matrix(TRUTH, PRED, 4)  # class 3 in neither truth nor prediction
    acc, iou = class_accuracies(c), iou_per_class(c)
    assert math.isnan(acc[3]) and math.isnan(iou[3])
    assert class_average_accuracy(c) == pytest.approx(class_average_accuracy(C))
    assert mean_iou(c) == pytest.approx(mean_iou(C))
    assert np.isnan(row_normalised(c)[3]).all()


def test_class_predicted_but_absent_from_truth_scores_iou_zero():
    truth = np.zeros((2, 2), int)
    pred = np.array([[0, 0], [0, 1]])
    c = confusion_matrix(truth, pred, 2)
    assert math.isnan(class_accuracies(c)[1])
    assert iou_per_class(c)[1] == 0.0
    assert class_average_accuracy(c) == pytest.approx(3 / 4)
    assert mean_iou(c) == pytest.approx((3 / 4 + 0) / 2)


def test_empty_matrix_scores_are_nan_without_warnings():
    c = np.zeros((3, 3), np.int64)
    with np.errstate(all="raise"):
        s = SegmentationScores.from_confusion(c)
    assert math.isnan(s.pixel_accuracy) and math.isnan(s.miou)
    assert math.isnan(s.class_avg_accuracy)


def test_accumulator_equals_matrix_of_concatenated_images():
    rng = np.random.default_rng(0)
    acc = ConfusionAccumulator(5)
    truths, preds = [], []
    for w in (3, 7, 4):
        t = rng.integers(0, 5, (6, w))
        t[rng.random(t.shape) < 0.2] = 255
        p = rng.integers(0, 5, (6, w))
        own = acc.add(t, p)
        np.testing.assert_array_equal(own, confusion_matrix(t, p, 5))
        truths.append(t)
        preds.append(p)
    whole = confusion_matrix(np.concatenate(truths, 1), np.concatenate(preds, 1), 5)
    np.testing.assert_array_equal(acc.matrix, whole)
    assert acc.n_images == 3
    assert acc.scores().miou == pytest.approx(mean_iou(whole))


def test_segmentation_scores_to_dict_is_json_ready():
    c = confusion_matrix(TRUTH, PRED, 4)
    d = SegmentationScores.from_confusion(c).to_dict(["wall", "window", "door", "shop"])
    text = json.dumps(d, allow_nan=False)  # no NaN leaks into JSON
    assert set(d) == {"pixel_accuracy", "class_avg_accuracy", "miou", "per_class", "confusion",
                      "confusion_percent"}
    assert d["pixel_accuracy"] == pytest.approx(0.75)
    assert d["per_class"]["window"] == {"accuracy": pytest.approx(0.8),
                                        "iou": pytest.approx(2 / 3), "support": 5}
    assert d["per_class"]["shop"] == {"accuracy": None, "iou": None, "support": 0}
    assert d["confusion"][1] == [0, 4, 1, 0]
    assert d["confusion_percent"][3] == [None] * 4
    assert json.loads(text)["confusion_percent"][0][0] == pytest.approx(75.0)
    assert list(SegmentationScores.from_confusion(C).to_dict()["per_class"]) == ["0", "1", "2"]
    with pytest.raises(MetricInputError, match="class_names"):
        SegmentationScores.from_confusion(C).to_dict(["a", "b"])


def test_bad_label_inputs_raise_typed_errors():
    with pytest.raises(MetricInputError, match="pred") as err:
        confusion_matrix(TRUTH, PRED + 1, 3)
    assert isinstance(err.value, ValueError) and isinstance(err.value, InputError)
    assert "0..2" in str(err.value)
    with pytest.raises(MetricInputError, match="pred"):
        confusion_matrix(TRUTH, np.where(PRED == 0, -1, PRED), 3)
    with pytest.raises(MetricInputError, match="shape"):
        confusion_matrix(TRUTH, PRED[:, :3], 3)
    with pytest.raises(MetricInputError, match="dtype"):
        confusion_matrix(TRUTH, PRED.astype(float), 3)
    with pytest.raises(MetricInputError, match="n_classes"):
        confusion_matrix(TRUTH, PRED, 0)
    with pytest.raises(MetricInputError, match="square"):
        mean_iou(np.zeros((2, 3)))


def test_uint8_labels_do_not_overflow():
    t = np.full((4, 4), 200, np.uint8)
    p = np.full((4, 4), 199, np.uint8)
    c = confusion_matrix(t, p, 201)
    assert c[200, 199] == 16 and c.sum() == 16


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 6).flatmap(lambda k: st.tuples(
    st.just(k),
    hnp.arrays(np.int64, st.tuples(st.integers(1, 8), st.integers(1, 8)),
               elements=st.sampled_from(list(range(k)) + [255])),
    st.randoms(use_true_random=False))))
def test_confusion_total_and_miou_range(case):
    k, truth, rnd = case
    pred = np.array([rnd.randrange(k) for _ in range(truth.size)]).reshape(truth.shape)
    c = confusion_matrix(truth, pred, k)
    assert c.sum() == int((truth != 255).sum())
    s = SegmentationScores.from_confusion(c)
    if c.sum() == 0:
        assert math.isnan(s.miou)
    else:
        assert 0.0 <= s.miou <= 1.0
        assert 0.0 <= s.pixel_accuracy <= 1.0
        assert 0.0 <= s.class_avg_accuracy <= 1.0
        rows = row_normalised(c)[c.sum(axis=1) > 0]
        np.testing.assert_allclose(rows.sum(axis=1), 100.0)


# -- object detection --------------------------------------------------------------------------


def test_box_iou_hand_cases():
    a = np.array([[0, 0, 4, 2]])
    b = np.array([[10, 10, 12, 12],   # disjoint
                  [1, 0, 3, 2],       # nested inside a: 4 / 8
                  [2, 0, 6, 2],       # half of a, shifted: 4 / (8 + 8 - 4)
                  [4, 0, 6, 2],       # touching edge (x1 exclusive): 0
                  [0, 0, 4, 2]])      # identical
    iou = box_iou(a, b)
    assert iou.shape == (1, 5)
    np.testing.assert_allclose(iou[0], [0, 0.5, 1 / 3, 0, 1])
    np.testing.assert_allclose(box_iou(b, a), iou.T)
    assert box_iou(np.zeros((0, 4)), b).shape == (0, 5)
    assert box_iou([[1, 1, 1, 1]], [[1, 1, 1, 1]])[0, 0] == 0.0  # degenerate: no NaN


def test_duplicate_predictions_on_one_window():
    truth = [[10, 10, 20, 30]]
    pred = [[10, 10, 20, 30], [11, 10, 21, 30]]
    s = match_boxes(truth, pred, scores=[0.9, 0.8])
    assert (s.tp, s.fp, s.fn) == (1, 1, 0)
    assert s.precision == pytest.approx(0.5)
    assert s.recall == 1.0
    assert s.f1 == pytest.approx(2 / 3)
    assert match_boxes(truth, pred) == s  # without scores too


def test_greedy_order_by_score_then_by_iou():
    truth = [[0, 0, 10, 10]]
    pred = [[0, 0, 10, 10],   # IoU 1, low score
            [0, 0, 10, 6]]    # IoU 0.6, high score
    np.testing.assert_array_equal(greedy_match(truth, pred, scores=[0.1, 0.9]), [[0, 1]])
    np.testing.assert_array_equal(greedy_match(truth, pred), [[0, 0]])


def test_match_threshold_is_inclusive_and_one_to_one():
    truth = [[0, 0, 4, 2], [20, 0, 24, 2]]
    pred = [[0, 0, 2, 2],      # IoU 0.5 with truth 0: a match
            [20, 0, 21, 2],    # IoU 0.25: no match
            [50, 50, 60, 60]]  # nowhere
    s = match_boxes(truth, pred)
    assert (s.tp, s.fp, s.fn) == (1, 2, 1)
    assert s.precision == pytest.approx(1 / 3)
    assert s.recall == pytest.approx(1 / 2)
    assert s.f1 == pytest.approx(2 * 1 / (2 * 1 + 2 + 1))


def test_detection_zero_division_conventions():
    empty = np.zeros((0, 4))
    box = [[0, 0, 5, 5]]
    both_empty = match_boxes(empty, empty)
    assert (both_empty.precision, both_empty.recall, both_empty.f1) == (1.0, 1.0, 1.0)
    missed = match_boxes(box, empty)
    assert (missed.precision, missed.recall, missed.f1) == (1.0, 0.0, 0.0)
    spurious = match_boxes(empty, box)
    assert (spurious.precision, spurious.recall, spurious.f1) == (0.0, 1.0, 0.0)


def test_detection_accumulation_pools_counts():
    acc = DetectionAccumulator()
    acc.add([[0, 0, 4, 4]], [[0, 0, 4, 4]])
    acc.add([[0, 0, 4, 4], [10, 0, 14, 4]], [[10, 0, 14, 4], [30, 0, 34, 4]])
    acc.add(np.zeros((0, 4)), np.zeros((0, 4)))
    assert acc.scores == DetectionScores(tp=2, fp=1, fn=1)
    assert acc.n_images == 3
    assert DetectionScores.total([DetectionScores(1, 0, 0), DetectionScores(1, 1, 1)]) == acc.scores
    d = acc.scores.to_dict("window_")
    assert d["window_precision"] == pytest.approx(2 / 3)
    assert d["window_recall"] == pytest.approx(2 / 3)
    assert d["window_f1"] == pytest.approx(2 / 3)


def test_bad_boxes_raise():
    with pytest.raises(MetricInputError, match="truth"):
        match_boxes([[0, 0, 1]], [[0, 0, 1, 1]])
    with pytest.raises(MetricInputError, match="scores"):
        match_boxes([[0, 0, 1, 1]], [[0, 0, 1, 1]], scores=[0.5, 0.2])


# -- structure counts ------------------------------------------------------------------------------


def test_count_error_and_scores():
    assert count_error(5, 3) == 2
    assert count_error(3, 5) == 2
    assert isinstance(count_error(4, 4), int)
    np.testing.assert_array_equal(count_error([5, 4, 6], [5, 3, 8]), [0, 1, 2])
    s = count_scores([5, 4, 6, 2], [5, 3, 8, 2])
    assert s.n_images == 4
    assert s.mean_abs_error == pytest.approx(3 / 4)
    assert s.exact_match_rate == pytest.approx(2 / 4)
    assert s.max_abs_error == 2
    empty = count_scores([], [])
    assert empty.n_images == 0 and math.isnan(empty.mean_abs_error)
    with pytest.raises(MetricInputError, match="pred_count"):
        count_error(3, -1)
    with pytest.raises(MetricInputError, match="pred_count"):
        count_error([1, 2], [1])


def test_structure_count_accumulator():
    acc = StructureCountAccumulator()
    acc.add(true_floors=5, pred_floors=5, true_columns=6, pred_columns=4)
    acc.add(true_floors=4, pred_floors=3)              # no column estimate: skipped
    acc.add(true_floors=6, pred_floors=None, true_columns=3, pred_columns=3)
    assert acc.floors.n_images == 2 and acc.floors.mean_abs_error == pytest.approx(0.5)
    assert acc.floors.exact_match_rate == pytest.approx(0.5)
    assert acc.columns.n_images == 2 and acc.columns.mean_abs_error == pytest.approx(1.0)
    d = acc.to_dict()
    assert d["floor_count_mae"] == pytest.approx(0.5)
    assert d["column_count_exact"] == pytest.approx(0.5)
    json.dumps(StructureCountAccumulator().to_dict(), allow_nan=False)


# -- run cost --------------------------------------------------------------------------------------


def test_measure_reports_time_and_numpy_peak_memory():
    def work(n, fill=1.0):
        a = np.full(n, fill)
        return float(a.sum())

    result, seconds, peak = measure(work, 1_000_000, fill=2.0)
    assert result == 2_000_000.0
    assert seconds >= 0.0
    assert peak >= 8_000_000  # the float64 buffer
    assert not tracemalloc.is_tracing()


def test_measure_leaves_outer_tracing_running_and_propagates_errors():
    tracemalloc.start()
    try:
        cost = measure(lambda: np.zeros(100_000))
        assert tracemalloc.is_tracing()
        assert cost.peak_memory_bytes >= 800_000
    finally:
        tracemalloc.stop()

    def boom():
        raise RuntimeError("x")

    with pytest.raises(RuntimeError):
        measure(boom)
    assert not tracemalloc.is_tracing()
