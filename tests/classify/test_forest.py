"""Forest classifiers: tree export matches scikit-learn, training learns, files round-trip."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from sklearn.ensemble import RandomForestClassifier

from facadeforge.classify import load_classifier, save_classifier
from facadeforge.classify.forest import TreeEnsemble
from facadeforge.classify.model import ClassifierFileError
from facadeforge.classify.train import train_classifier
from facadeforge.datasets import get_label_set
from facadeforge.errors import InputError

ECP7 = get_label_set("ecp7")


@dataclass
class FakeSample:
    """Window rows on a wall: dark glass rectangles in a grid, light stone around them."""

    id: str
    seed: int
    label_set = ECP7

    def _make(self):
        rng = np.random.default_rng(self.seed)
        h, w = 180, 140
        labels = np.full((h, w), ECP7.index("wall"), np.uint8)
        top = rng.integers(4, 14)
        for r in range(top, h - 30, 40):
            for c in range(rng.integers(6, 16), w - 20, 34):
                labels[r:r + 24, c:c + 14] = ECP7.index("window")
        labels[:top] = ECP7.index("sky")
        img = np.empty((h, w, 3), np.float64)
        img[:] = (200, 190, 170)
        img[labels == ECP7.index("window")] = (60, 70, 90)
        img[labels == ECP7.index("sky")] = (150, 190, 240)
        img += rng.normal(0, 18, img.shape)
        return np.clip(img, 0, 255).astype(np.uint8), labels

    def image(self):
        return self._make()[0]

    def labels(self):
        return self._make()[1]


def test_tree_export_matches_sklearn():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(600, 5)).astype(np.float32)
    y = (X[:, 0] + X[:, 1] * X[:, 2] > 0).astype(int) + (X[:, 3] > 1)
    rf = RandomForestClassifier(n_estimators=4, random_state=0).fit(X, y)
    ens = TreeEnsemble.from_sklearn(rf, 3)
    Xt = rng.normal(size=(300, 5)).astype(np.float32)
    ours = ens.predict_proba(Xt)
    np.testing.assert_allclose(ours, rf.predict_proba(Xt), atol=2e-3)  # float16 leaves


def test_tree_export_places_missing_classes():
    """A forest trained on classes {0, 2} of 3 fills column 1 with zeros."""
    rng = np.random.default_rng(1)
    X = rng.normal(size=(200, 2)).astype(np.float32)
    y = np.where(X[:, 0] > 0, 2, 0)
    ens = TreeEnsemble.from_sklearn(RandomForestClassifier(3, random_state=0).fit(X, y), 3)
    p = ens.predict_proba(np.array([[3.0, 0.0], [-3.0, 0.0]], np.float32))
    assert p[0, 2] > 0.9 and p[1, 0] > 0.9 and np.all(p[:, 1] == 0)


@pytest.mark.parametrize("kind", ["forest", "autocontext"])
def test_training_learns_and_round_trips(kind, tmp_path):
    train = [FakeSample(f"f{i}", i) for i in range(4)]
    clf = train_classifier(train, ECP7, kind=kind, trees=4, per_image=600, stages=2)
    test = FakeSample("t", 99)
    truth = test.labels()
    prob = clf.predict_proba(test.image())
    assert prob.shape == (*truth.shape, 7)
    np.testing.assert_allclose(prob.sum(axis=2), 1, atol=1e-3)
    acc = (prob.argmax(axis=2) == truth).mean()
    assert acc > 0.9, acc
    path = save_classifier(clf, tmp_path / "m.npz")
    again = load_classifier(path)
    assert again.kind == kind and again.classes == ECP7.classes
    np.testing.assert_array_equal(again.predict_proba(test.image()), prob)


def test_bad_files_and_inputs(tmp_path):
    with pytest.raises(ClassifierFileError, match="no such file"):
        load_classifier(tmp_path / "missing.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(ClassifierFileError, match="not a facadeforge classifier"):
        load_classifier(junk)
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ClassifierFileError):
        load_classifier(tmp_path / "other.npz")
    with pytest.raises(InputError, match="at least"):
        train_classifier([FakeSample("a", 0)], ECP7, kind="forest")
    with pytest.raises(InputError, match="cannot be trained"):
        train_classifier([FakeSample("a", 0), FakeSample("b", 1)], ECP7, kind="gmm")


def test_cli_errors_are_one_line(tmp_path, capsys):
    from facadeforge.cli import main

    assert main(["train-classifier", "--kind", "forest", "-o", str(tmp_path / "m.npz")]) == 2
    assert "needs --dataset and --data" in capsys.readouterr().err
    assert main(["train-classifier", "--dataset", "cmp", "--data", str(tmp_path),
                 "-o", str(tmp_path / "m.pkl")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and ".npz" in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("damage", ["feature", "cycle", "tests", "classes"])
def test_tampered_model_files_are_refused(tmp_path, damage):
    """A model file is untrusted: arrays that would crash or hang the compiled traversal are
    rejected when loading, with a one-line error."""
    clf = train_classifier([FakeSample("a", 0), FakeSample("b", 1)], ECP7, kind="forest",
                           trees=2, per_image=300)
    good = save_classifier(clf, tmp_path / "good.npz")
    with np.load(good, allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    inner = arrays["t_feature"] >= 0
    if damage == "feature":
        arrays["t_feature"][inner] = 30000
    elif damage == "cycle":
        arrays["t_left"][inner] = 0
    elif damage == "tests":
        arrays["tests"][:, 0] = 5000
    else:
        arrays["t_value"] = arrays["t_value"][:, :3]
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ClassifierFileError, match="damaged or inconsistent"):
        load_classifier(bad)
