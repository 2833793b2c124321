"""Scribble GMM classifier (simon2011 §4.3.2): training, posteriors, file round trip, scribbles."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image
from scipy.stats import multivariate_normal

from facadeforge.classify import model as clf_model
from facadeforge.classify.gmm import GMMClassifier, ScribbleError, read_scribbles, train_gmm
from facadeforge.datasets.labelsets import IGNORE, get_label_set
from facadeforge.errors import InputError

ECP7 = get_label_set("ecp7")
WINDOW, WALL, SKY = ECP7.classes.index("window"), ECP7.classes.index("wall"), \
    ECP7.classes.index("sky")

# Three bands: sky on top, wall, and a dark window inside the wall.
COLORS = {SKY: (150, 200, 240), WALL: (205, 180, 140), WINDOW: (45, 55, 75)}


def _scene(noise: float = 10.0, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(60, 80, 3) noisy photo and its (60, 80) ecp7 truth."""
    truth = np.full((60, 80), WALL, np.uint8)
    truth[:15] = SKY
    truth[25:50, 20:45] = WINDOW
    rng = np.random.default_rng(seed)
    img = np.zeros((60, 80, 3), np.float64)
    for k, c in COLORS.items():
        img[truth == k] = c
    img += rng.normal(0.0, noise, img.shape)
    return np.clip(img, 0, 255).round().astype(np.uint8), truth


def _strokes() -> np.ndarray:
    """Class-index scribbles covering a small part of each region."""
    s = np.full((60, 80), IGNORE, np.uint8)
    s[3:8, 5:60] = SKY
    s[20:23, 50:75] = WALL
    s[55:58, 10:70] = WALL
    s[30:34, 25:40] = WINDOW
    return s


def test_classes_are_stroked_classes_in_label_set_order():
    img, _ = _scene()
    clf = train_gmm(img, _strokes(), "ecp7")
    assert clf.kind == "gmm"
    assert clf.classes == ("window", "wall", "sky")
    assert clf.label_set == "ecp7"
    assert clf.meta["components"] == 3
    assert clf.meta["pixels"] == {"window": 60, "wall": 75 + 180, "sky": 275}
    arrays = clf.to_arrays()
    assert arrays["weights"].shape == (3, 3)
    assert arrays["means"].shape == (3, 3, 3)
    assert arrays["covariances"].shape == (3, 3, 3, 3)
    np.testing.assert_allclose(arrays["weights"].sum(axis=1), 1.0)


def test_accuracy_on_unstroked_pixels():
    img, truth = _scene()
    strokes = _strokes()
    clf = train_gmm(img, strokes, "ecp7")
    proba = clf.predict_proba(img)
    assert proba.shape == (60, 80, 3) and proba.dtype == np.float32
    pred = np.array([ECP7.classes.index(c) for c in clf.classes])[proba.argmax(axis=2)]
    free = strokes == IGNORE
    assert (pred[free] == truth[free]).mean() > 0.95
    np.testing.assert_allclose(proba.sum(axis=2), 1.0, atol=1e-5)
    assert (proba >= 0).all()


def _reference_posterior(clf: GMMClassifier, rgb: np.ndarray) -> np.ndarray:
    """Eq. 4.11 with scipy's Gaussian pdf, then eq. 4.13 (equal priors) in linear space."""
    x = rgb.reshape(-1, 3).astype(float)
    lik = np.zeros((x.shape[0], clf.num_classes))
    for i in range(clf.num_classes):
        for k in range(clf.num_components):
            lik[:, i] += clf.weights[i, k] * multivariate_normal.pdf(
                x, clf.means[i, k], clf.covariances[i, k])
    return lik / lik.sum(axis=1, keepdims=True)


def test_posterior_is_eq_4_13_on_overlapping_classes():
    # Broad, correlated, unequally weighted components: posteriors are far from 0/1, so the
    # weights, determinants and Mahalanobis terms all matter.
    a = np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.2], [0.1, 0.0, 1.0]])
    cov = np.stack([np.stack([900 * a @ a.T, 400 * np.eye(3)]),
                    np.stack([600 * np.eye(3), 1500 * a.T @ a])])
    clf = GMMClassifier(weights=[[0.8, 0.2], [0.3, 0.7]],
                        means=[[[100, 100, 100], [160, 120, 90]],
                               [[130, 130, 110], [90, 140, 160]]],
                        covariances=cov, classes=("wall", "window"), label_set="ecp7")
    rgb = np.random.default_rng(0).integers(40, 220, (8, 9, 3)).astype(np.uint8)
    got = clf.predict_proba(rgb).reshape(-1, 2)
    want = _reference_posterior(clf, rgb)
    assert ((want[:, 0] > 0.1) & (want[:, 0] < 0.9)).sum() > 10
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_trained_posterior_is_eq_4_13():
    img, _ = _scene()
    clf = train_gmm(img, _strokes(), "ecp7")
    pix = np.array([[[60, 70, 90], [200, 180, 150], [178, 190, 190], [175, 191, 193]]],
                   np.uint8)
    np.testing.assert_allclose(clf.predict_proba(pix)[0], _reference_posterior(clf, pix),
                               atol=1e-5)


def test_far_pixels_are_finite_and_normalised():
    # Sharp, nearly flat classes: at pure white every density underflows to 0 in linear space.
    img = np.zeros((10, 20, 3), np.uint8)
    img[:, 10:] = (0, 0, 40)
    clf = train_gmm(img, np.where(np.arange(20) < 10, WINDOW, WALL).astype(np.uint8)[None]
                    .repeat(10, 0), "ecp7")
    p = clf.predict_proba(np.full((1, 1, 3), 255, np.uint8))
    assert np.isfinite(p).all()
    np.testing.assert_allclose(p.sum(axis=2), 1.0, atol=1e-6)
    assert p[0, 0, 1] > 0.99  # white is nearer (0, 0, 40): the wall


def test_gray_and_rgba_inputs():
    img, _ = _scene()
    clf = train_gmm(img, _strokes(), "ecp7")
    rgba = np.concatenate([img, np.full((60, 80, 1), 255, np.uint8)], axis=2)
    np.testing.assert_array_equal(clf.predict_proba(rgba), clf.predict_proba(img))
    gray = img.mean(axis=2).astype(np.uint8)
    p = clf.predict_proba(gray)
    assert p.shape == (60, 80, 3)
    np.testing.assert_array_equal(p, clf.predict_proba(np.repeat(gray[..., None], 3, axis=2)))


def test_deterministic_for_a_seed():
    img, _ = _scene()
    a = train_gmm(img, _strokes(), "ecp7", seed=3).to_arrays()
    b = train_gmm(img, _strokes(), "ecp7", seed=3).to_arrays()
    for name in a:
        np.testing.assert_array_equal(a[name], b[name])


def test_subsample_caps_pixels(monkeypatch):
    from facadeforge.classify import gmm
    monkeypatch.setattr(gmm, "MAX_SAMPLES", 100)
    img, _ = _scene()
    clf = train_gmm(img, _strokes(), "ecp7")
    assert clf.meta["samples"] == {"window": 60, "wall": 100, "sky": 100}
    assert clf.meta["pixels"]["sky"] == 275


def test_save_load_round_trip(tmp_path):
    img, _ = _scene()
    clf = train_gmm(img, _strokes(), "ecp7", components=2)
    path = clf_model.save_classifier(clf, tmp_path / "gmm.npz")
    back = clf_model.load_classifier(path)
    assert isinstance(back, GMMClassifier)
    assert back.classes == clf.classes and back.label_set == "ecp7"
    assert back.meta == clf.meta
    np.testing.assert_array_equal(back.predict_proba(img), clf.predict_proba(img))


def test_from_arrays_rejects_bad_shapes():
    w = np.full((2, 3), 1 / 3)
    mu = np.zeros((2, 3, 3))
    cov = np.tile(np.eye(3), (2, 3, 1, 1))
    GMMClassifier.from_arrays({"weights": w, "means": mu, "covariances": cov},
                              ("wall", "window"), "ecp7", {})
    with pytest.raises(clf_model.ClassifierFileError, match="means"):
        GMMClassifier.from_arrays({"weights": w, "means": mu[:, :2], "covariances": cov},
                                  ("wall", "window"), "ecp7", {})
    with pytest.raises(clf_model.ClassifierFileError, match="positive definite"):
        GMMClassifier.from_arrays({"weights": w, "means": mu, "covariances": -cov},
                                  ("wall", "window"), "ecp7", {})


# ------------------------------------------------------------------------- read_scribbles
def test_read_colour_scribbles(tmp_path):
    rgb = np.zeros((4, 5, 3), np.uint8)  # black background = no stroke
    rgb[0, :] = ECP7.colors[WALL]
    rgb[1, :2] = ECP7.colors[WINDOW]
    rgb[2, 0] = (255, 255, 255)  # white: not a class colour
    rgb[2, 1] = (250, 0, 0)      # anti-aliased red: not a class colour
    rgb[3, 4] = ECP7.colors[SKY]
    Image.fromarray(rgb).save(tmp_path / "s.png")
    got = read_scribbles(tmp_path / "s.png", "ecp7")
    want = np.full((4, 5), IGNORE, np.uint8)
    want[0, :] = WALL
    want[1, :2] = WINDOW
    want[3, 4] = SKY
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(read_scribbles(rgb, "ecp7"), want)


def test_read_rgba_scribbles_alpha_zero_is_no_stroke(tmp_path):
    rgba = np.zeros((3, 3, 4), np.uint8)
    rgba[..., :3] = ECP7.colors[WALL]
    rgba[0, :, 3] = 255
    rgba[1, 0] = (*ECP7.colors[WINDOW], 128)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "a.png")
    got = read_scribbles(tmp_path / "a.png", "ecp7")
    want = np.full((3, 3), IGNORE, np.uint8)
    want[0] = WALL
    want[1, 0] = WINDOW
    np.testing.assert_array_equal(got, want)


def test_read_index_scribbles(tmp_path):
    idx = np.array([[0, 1, 2], [7, 0, 3]], np.uint8)  # k+1 = class k, 0 = no stroke
    Image.fromarray(idx, "L").save(tmp_path / "i.png")
    got = read_scribbles(tmp_path / "i.png", "ecp7")
    np.testing.assert_array_equal(got, [[IGNORE, 0, 1], [6, IGNORE, 2]])
    bad = idx.copy()
    bad[0, 0] = 9
    Image.fromarray(bad, "L").save(tmp_path / "bad.png")
    with pytest.raises(ScribbleError, match=r"index values \[9\]"):
        read_scribbles(tmp_path / "bad.png", "ecp7")


def test_read_scribbles_missing_file(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        read_scribbles(tmp_path / "nope.png", "ecp7")


def test_train_from_scribble_png(tmp_path):
    img, truth = _scene()
    colour = np.zeros((60, 80, 3), np.uint8)
    s = _strokes()
    colour[s != IGNORE] = ECP7.colors[s[s != IGNORE]]
    Image.fromarray(colour).save(tmp_path / "strokes.png")
    a = train_gmm(img, tmp_path / "strokes.png", "ecp7")
    b = train_gmm(img, s, "ecp7")
    np.testing.assert_array_equal(a.to_arrays()["means"], b.to_arrays()["means"])


# ------------------------------------------------------------------------- errors
def test_error_size_mismatch():
    img, _ = _scene()
    with pytest.raises(ScribbleError, match=r"80x59 pixels but the image is 80x60"):
        train_gmm(img, _strokes()[:59], "ecp7")


def test_error_fewer_than_two_classes():
    img, _ = _scene()
    s = _strokes()
    s[s != WALL] = IGNORE
    with pytest.raises(ScribbleError, match=r"mark 1 class\(es\) \(wall\); stroke at least two"):
        train_gmm(img, s, "ecp7")
    with pytest.raises(ScribbleError, match=r"mark 0 class\(es\) \(none\)"):
        train_gmm(img, np.full((60, 80), IGNORE, np.uint8), "ecp7")


def test_error_class_with_too_few_pixels():
    img, _ = _scene()
    s = _strokes()
    s[s == WINDOW] = IGNORE
    s[30, 25:30] = WINDOW  # 5 pixels < 2 * 3
    with pytest.raises(ScribbleError, match=r"window has 5 pixels; a 3-component mixture needs "
                                            r"at least 6"):
        train_gmm(img, s, "ecp7")
    train_gmm(img, s, "ecp7", components=2)  # 5 >= 4: fine


def test_error_index_map_with_foreign_classes():
    img, _ = _scene()
    s = _strokes()
    s[0, 0] = 7
    with pytest.raises(ScribbleError, match=r"class indices \[7\]"):
        train_gmm(img, s, "ecp7")


def test_predict_in_blocks_matches_one_block(monkeypatch):
    from facadeforge.classify import gmm
    img, _ = _scene()
    clf = train_gmm(img, _strokes(), "ecp7")
    whole = clf.predict_proba(img)
    monkeypatch.setattr(gmm, "_CHUNK", 997)  # 4800 pixels: 5 blocks, the last one partial
    np.testing.assert_array_equal(clf.predict_proba(img), whole)
