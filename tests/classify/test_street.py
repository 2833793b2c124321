"""The street classifier's partial labels, its augmentation and its place as a default."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.classify.convnet_train import _partial_labels, _photometric_and_perspective
from facadeforge.classify.street import STREET_CLASSES, UMBRELLA, partial_table
from facadeforge.datasets import IGNORE, LABEL_SETS, get_label_set

STREET = get_label_set("street12")


def _allowed(label_set: str, name: str) -> set[str]:
    ls = get_label_set(label_set)
    row = partial_table(ls)[list(ls.dataset_names).index(name)]
    return {STREET.classes[k] for k in np.flatnonzero(row)}


def test_street12_is_the_street_classes():
    assert STREET.classes == STREET_CLASSES and len(STREET_CLASSES) == 12
    # canonical labels the street set lacks land somewhere sensible
    assert STREET.classes[STREET.index("ground")] == "pavement"
    assert STREET.classes[STREET.index("person")] == "other"
    assert STREET.classes[STREET.index("cornice")] == "wall"
    assert STREET.classes[STREET.index("blind")] == "window"


@pytest.mark.parametrize("name", sorted(LABEL_SETS))
def test_every_class_of_every_set_may_be_some_street_class(name: str):
    table = partial_table(name)
    assert table.shape == (get_label_set(name).num_classes, 12) and table.any(1).all()


def test_umbrella_classes_and_exact_classes():
    assert _allowed("ecp7", "window") == {"window"} and _allowed("ecp7", "roof") == {"roof"}
    assert _allowed("cmp12", "cornice") == {"wall"} and _allowed("cmp12", "blind") == {"window"}
    assert _allowed("cmp6", "background") == set(UMBRELLA["cmp6"]["background"])
    assert "wall" not in _allowed("cmp6", "background")
    assert {"sky", "roof", "car", "vegetation"} <= _allowed("cmp12", "background")
    assert _allowed("street12", "car") == {"car"}
    if "lmf9" in LABEL_SETS:
        assert {"wall", "window"} <= _allowed("lmf9", "building")
        assert "sky" not in _allowed("lmf9", "various")
        assert _allowed("lmf9", "vegetation") == {"vegetation"}
        assert _allowed("lmf9", "car") == {"car"}


def test_partial_labels_share_one_table_per_label_set():
    a = np.array([[0, 1], [2, 255]], np.uint8)
    b = np.array([[0, 0], [1, 7]], np.uint8)
    t_a, t_b = partial_table("ecp7"), partial_table("cmp6")
    labs, table = _partial_labels([a, b, a], [t_a, t_b, t_a], 12)
    assert table.shape == (7 + 6, 12)
    assert labs[0].tolist() == [[0, 1], [2, IGNORE]] and labs[2].tolist() == labs[0].tolist()
    assert labs[1].tolist() == [[7, 7], [8, IGNORE]]           # offset 7; 7 ≥ 6 classes: ignored
    assert (table[7] == t_b[0]).all()
    # no table: label k is class k
    labs, table = _partial_labels([b], [None], 12)
    assert (table == np.eye(12, dtype=bool)).all() and labs[0][1, 1] == 7


def test_street_augmentation_keeps_labels_and_is_seeded():
    rgb = np.zeros((64, 48, 3), np.uint8)
    rgb[:, 24:] = 200
    lab = np.zeros((64, 48), np.uint8)
    lab[:, 24:] = 3
    outs = []
    for _ in range(2):
        rng = np.random.default_rng(5)
        outs.append([_photometric_and_perspective(rgb, lab, rng) for _ in range(6)])
    for (r1, l1), (r2, l2) in zip(*outs):
        assert r1.shape == rgb.shape and r1.dtype == np.uint8 and l1.shape == lab.shape
        assert set(np.unique(l1)) <= {0, 3, IGNORE}
        assert (r1 == r2).all() and (l1 == l2).all()
    # the bright half stays labelled 3 under the warps: labels move with the pixels
    for r, lab_out in outs[0]:
        bright = r.mean(2) > r.mean()
        assert (lab_out[bright & (lab_out != IGNORE)] == 3).mean() > 0.9


def test_a_shipped_street_network_serves_the_label_sets_it_is_projected_onto(tmp_path, monkeypatch):
    import facadeforge.classify as classify
    from facadeforge.classify import save_classifier
    from facadeforge.classify.convnet import ConvNetClassifier, ConvNetSpec

    spec = ConvNetSpec(width=2, multipliers=(1, 2, 3), rowcol=(2,))
    rng = np.random.default_rng(0)
    weights = {n: rng.normal(0, 0.3, s).astype(np.float32) for n, s in spec.shapes(12).items()}
    net = ConvNetClassifier(spec, weights, STREET_CLASSES, "street12", {"note": "random"})
    monkeypatch.setattr(classify, "MODEL_DIR", tmp_path)
    monkeypatch.setattr(classify, "_LOADED", {})
    with pytest.raises(Exception, match="no shipped"):
        classify.default_classifier("lmf9")                     # nothing shipped here
    save_classifier(net, tmp_path / "convnet-street12.npz")
    assert set(classify.PROJECTED) == {"lmf9"}           # ecp7 keeps its forest (README)
    monkeypatch.setitem(classify.PROJECTED, "ecp7", "convnet-street12")
    for name in ("ecp7", "lmf9"):
        clf = classify.default_classifier(name)
        assert clf.kind == "ensemble" and clf.label_set == name
        assert clf.classes == get_label_set(name).classes
        p = clf.predict_proba(rng.integers(0, 255, (40, 30, 3), dtype=np.uint8))
        assert p.shape == (40, 30, get_label_set(name).num_classes)
        np.testing.assert_allclose(p.sum(2), 1, atol=1e-4)
