"""MRF-Potts baseline (simon2011 §4.4.1, eq. 4.14): smoothing, energy, large maps, bad input."""

import time

import numpy as np
import pytest
from maxflow import fastmin

from facadeforge.errors import InputError
from facadeforge.parsing.mrf import potts_energy, potts_labels


def _truth(h=60, w=80):
    """Three regions: a wall, a window rectangle and a bottom shop band."""
    t = np.zeros((h, w), np.int64)
    t[10:30, 15:45] = 1
    t[int(h * 0.75):, :] = 2
    return t


def _noisy_prob(truth, k=3, signal=1.0, noise=1.0, seed=0):
    """Softmax of (signal * one-hot + Gaussian noise): a noisy per-pixel classifier."""
    rng = np.random.default_rng(seed)
    logits = signal * np.eye(k)[truth] + noise * rng.standard_normal(truth.shape + (k,))
    e = np.exp(logits - logits.max(axis=2, keepdims=True))
    return e / e.sum(axis=2, keepdims=True)


def test_potts_beats_argmax_on_noisy_regions():
    truth = _truth()
    prob = _noisy_prob(truth)
    argmax = prob.argmax(axis=2)
    labels = potts_labels(prob, smoothness=1.0)
    acc_arg = float(np.mean(argmax == truth))
    acc_mrf = float(np.mean(labels == truth))
    assert labels.shape == truth.shape and labels.dtype == np.uint8
    assert acc_arg < 0.75  # the classifier really is noisy
    assert acc_mrf > 0.95
    assert acc_mrf > acc_arg + 0.2
    assert potts_energy(labels, prob, 1.0) < potts_energy(argmax, prob, 1.0)


def test_two_region_map():
    truth = np.zeros((40, 50), np.int64)
    truth[:, 25:] = 1
    prob = _noisy_prob(truth, k=2, signal=1.0, noise=1.2, seed=3)
    labels = potts_labels(prob, smoothness=1.5)
    assert np.mean(prob.argmax(axis=2) == truth) < 0.8
    assert np.mean(labels == truth) > 0.97


def test_smoothness_zero_is_argmax_exactly():
    prob = _noisy_prob(_truth(), seed=1)
    assert np.array_equal(potts_labels(prob, smoothness=0.0), prob.argmax(axis=2))
    # also when the map would be downscaled for a positive smoothness
    assert np.array_equal(potts_labels(prob, smoothness=0, max_pixels=100), prob.argmax(axis=2))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("lam", [0.05, 0.5, 2.0, 10.0])
def test_never_worse_than_argmax(seed, lam):
    rng = np.random.default_rng(seed)
    prob = rng.dirichlet(np.full(4, 0.7), size=(23, 31))
    labels = potts_labels(prob, smoothness=lam)
    start = potts_energy(prob.argmax(axis=2), prob, lam)
    assert potts_energy(labels, prob, lam) <= start + 1e-9 * max(1.0, abs(start))


def test_energy_hand_case():
    prob = np.array([[[0.9, 0.1], [0.2, 0.8]],
                     [[0.5, 0.5], [1.0, 0.0]]])
    labels = np.array([[0, 1], [1, 0]])
    unary = -np.log(0.9) - np.log(0.8) - np.log(0.5) - np.log(1.0)
    # differing 4-neighbour pairs: (0,0)-(0,1), (1,0)-(1,1), (0,0)-(1,0), (0,1)-(1,1) -> 4
    assert potts_energy(labels, prob, 0.7) == pytest.approx(unary + 4 * 0.7)
    # clipped zero probability costs -log(eps)
    assert potts_energy(np.array([[0, 1], [1, 1]]), prob, 0.0) == pytest.approx(
        -np.log(0.9) - np.log(0.8) - np.log(0.5) - np.log(1e-4))


def test_energy_matches_pymaxflow_reference():
    rng = np.random.default_rng(7)
    prob = rng.dirichlet(np.ones(5), size=(17, 13))
    labels = rng.integers(0, 5, size=(17, 13))
    unary = -np.log(np.clip(prob, 1e-4, 1.0))
    ref = fastmin.energy_of_grid_labeling(unary, 0.3 * (1 - np.eye(5)), labels)
    assert potts_energy(labels, prob, 0.3) == pytest.approx(float(ref))


def test_input_not_modified():
    prob = _noisy_prob(_truth(), seed=2)
    before = prob.copy()
    potts_labels(prob, 1.0)
    potts_labels(prob, 1.0, max_pixels=500)
    assert np.array_equal(prob, before)


def test_large_map_is_downscaled_and_keeps_shape():
    truth = _truth(301, 437)
    prob = _noisy_prob(truth, seed=4).astype(np.float32)
    labels = potts_labels(prob, smoothness=1.0, max_pixels=5_000)
    assert labels.shape == truth.shape and labels.dtype == np.uint8
    # still a sensible segmentation after the coarse solve and nearest-neighbour upsampling
    assert np.mean(labels == truth) > 0.9
    assert set(np.unique(labels)) <= {0, 1, 2}


def test_extreme_aspect_ratio_downscale():
    prob = _noisy_prob(np.zeros((2, 3000), np.int64), k=2, seed=5)
    labels = potts_labels(prob, smoothness=1.0, max_pixels=1_000)
    assert labels.shape == (2, 3000)


def test_single_pixel():
    assert potts_labels(np.array([[[0.2, 0.8]]]), 1.0).tolist() == [[1]]


@pytest.mark.parametrize("bad, fragment", [
    (np.ones((4, 4)) / 2, "(H, W, K)"),
    (np.ones((4, 4, 1)), "K >= 2"),
    (np.full((4, 4, 2), np.nan), "NaN"),
    (np.full((4, 4, 2), np.inf), "NaN or infinite"),
    (np.full((4, 4, 2), -0.5), "negative"),
    (np.zeros((0, 4, 2)), "empty"),
    (np.array([[["a", "b"]]]), "numeric"),
])
def test_bad_prob_raises(bad, fragment):
    with pytest.raises(InputError, match="prob") as info:
        potts_labels(bad, 1.0)
    assert fragment in str(info.value)


@pytest.mark.parametrize("lam", [-1.0, float("nan"), float("inf"), "1", None, True])
def test_bad_smoothness_raises(lam):
    prob = np.full((3, 3, 2), 0.5)
    with pytest.raises(InputError, match="smoothness"):
        potts_labels(prob, lam)
    with pytest.raises(InputError, match="smoothness"):
        potts_energy(np.zeros((3, 3), int), prob, lam)


def test_bad_options_and_labels_raise():
    prob = np.full((3, 3, 2), 0.5)
    with pytest.raises(InputError, match="max_cycles"):
        potts_labels(prob, 1.0, max_cycles=0)
    with pytest.raises(InputError, match="max_pixels"):
        potts_labels(prob, 1.0, max_pixels=0)
    with pytest.raises(InputError, match="eps"):
        potts_labels(prob, 1.0, eps=0.0)
    with pytest.raises(InputError, match="labels"):
        potts_energy(np.zeros((2, 3), int), prob, 1.0)
    with pytest.raises(InputError, match="labels"):
        potts_energy(np.full((3, 3), 2), prob, 1.0)
    with pytest.raises(InputError, match="labels"):
        potts_energy(np.zeros((3, 3)), prob, 1.0)


def test_report_timing_400x300x7(capsys):
    """Prints the time of a 400x300x7 map (reported, never asserted)."""
    rng = np.random.default_rng(0)
    truth = rng.integers(0, 7, size=(8, 6)).repeat(50, axis=0).repeat(50, axis=1)
    prob = _noisy_prob(truth, k=7, seed=0)
    assert prob.shape == (400, 300, 7)
    t0 = time.perf_counter()
    labels = potts_labels(prob, smoothness=1.0)
    dt = time.perf_counter() - t0
    with capsys.disabled():
        print(f"\npotts_labels 400x300x7 (max_cycles=5): {dt:.3f} s, "
              f"accuracy {np.mean(labels == truth):.3f} vs argmax "
              f"{np.mean(prob.argmax(axis=2) == truth):.3f}")
