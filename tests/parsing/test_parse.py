"""``facadeforge parse`` end to end on a synthetic facade with the shipped classifier."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from facadeforge.cli import main
from facadeforge.engine import derive_facade, load_rules
from facadeforge.exchange.raster import label_map
from facadeforge.parsing.parse import parse, write_fitted_rules


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    """A light wall with a 4 x 5 grid of dark windows and a dark shop band."""
    rng = np.random.default_rng(0)
    img = np.full((300, 240, 3), (205, 195, 175), np.float64)
    for r in range(30, 220, 48):
        for c in range(20, 230, 46):
            img[r:r + 30, c:c + 22] = (55, 65, 80)
    img[250:] = (90, 60, 50)
    img += rng.normal(0, 8, img.shape)
    path = tmp_path_factory.mktemp("photo") / "facade.png"
    Image.fromarray(np.clip(img, 0, 255).astype(np.uint8)).save(path)
    return path


def test_parse_writes_every_file_and_rules_derive_the_same_layout(photo, tmp_path):
    out = tmp_path / "out"
    assert main(["parse", str(photo), "--rectified", "--budget", "300", "-o", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"labels.png", "labels_input.png", "shape_tree.json", "rules.cga", "model.glb",
            "model.obj", "model.city.json", "rectified.png", "energy.png",
            "report.json"} <= names
    report = json.loads((out / "report.json").read_text())
    assert report["derivations"] == 300 and report["method"] == "evolution"
    assert set(report["timings"]) >= {"classify", "search", "derive", "total"}
    labels = np.array(Image.open(out / "labels.png"))
    # rules.cga alone (fitted values as defaults) derives the same label layout
    w, h = report["facade_m"]
    again = label_map(derive_facade(load_rules(out / "rules.cga"), w, h).root,
                      size=labels.shape)
    assert (again == labels).mean() > 0.99
    assert not [p for p in out.iterdir() if p.name.startswith(".staging")]


def test_parse_finds_windows(photo):
    p = parse(str(photo), rectified=True, budget=800, model=False)
    assert p.report["elements"]["window"] >= 4
    win = p.labels == 2  # canonical index of window
    assert win.any()


def test_write_fitted_rules_replaces_defaults():
    src = ('@Range(0, 1) attr a = 0.5   # comment\nattr b = "x"\n@Enum(1, 2) attr n = 1\n')
    out = write_fitted_rules(src, {"a": 0.25, "b": "y", "n": 2.0})
    assert "attr a = 0.25   # comment" in out and 'attr b = "y"' in out and "attr n = 2" in out


def test_cli_errors(photo, tmp_path, capsys):
    assert main(["parse", str(tmp_path / "missing.jpg"), "-o", str(tmp_path / "o")]) == 2
    assert main(["parse", str(photo), "--grammar", "nope", "-o", str(tmp_path / "o")]) == 2
    assert "built-in grammar" in capsys.readouterr().err
    assert main(["parse", str(photo), "--budget", "0", "-o", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_parse_with_a_scribble_gmm(photo, tmp_path):
    """A GMM knows only the scribbled classes; parse spreads them onto the label set."""
    from facadeforge.classify.gmm import train_gmm
    from facadeforge.datasets import get_label_set

    ecp7 = get_label_set("ecp7")
    img = np.array(Image.open(photo).convert("RGB"))
    strokes = np.full(img.shape[:2], 255, np.uint8)
    strokes[35:55, 25:40] = ecp7.index("window")
    strokes[5:20, 5:200] = ecp7.index("wall")
    strokes[260:290, 20:200] = ecp7.index("shop")
    gmm = train_gmm(img, strokes, label_set="ecp7")
    assert len(gmm.classes) == 3
    p = parse(str(photo), classifier=gmm, rectified=True, budget=200, model=False)
    labels = p.labels_input()
    from facadeforge.datasets import CANONICAL_INDEX

    assert (labels == CANONICAL_INDEX["window"]).any()
    assert not (labels == CANONICAL_INDEX["balcony"]).any()  # a class the GMM never saw


def test_coarse_probabilities_warp_straight_into_the_energy_frame():
    """parse warps the classifier's working-scale probabilities by ``to_energy · H ·
    to_prob⁻¹`` into the 256-pixel energy frame; that must agree with the long way round
    (resize to the photo, warp there, area-shrink), here for a perspective homography."""
    import cv2

    from facadeforge.classify.features import resize_proba
    from facadeforge.parsing.fit import energy_shape, shrink_proba
    from facadeforge.parsing.parse import _warp_prob

    h, w = 900, 1200                                          # the photo
    yy, xx = np.mgrid[0:240, 0:320] / np.array([240.0, 320.0])[:, None, None]
    stripes = np.stack([np.sin(6 * np.pi * xx) ** 2, np.cos(5 * np.pi * yy) ** 2, xx * yy], 2)
    coarse = (stripes + 0.05) / (stripes + 0.05).sum(axis=2, keepdims=True)   # (240, 320, 3)
    src = np.float32([[100, 80], [1100, 40], [1150, 880], [60, 820]])
    rh, rw = 700, 1000                                        # the rectified facade
    H = cv2.getPerspectiveTransform(src, np.float32([[0, 0], [rw, 0], [rw, rh], [0, rh]]))
    to_prob = np.diag([320 / w, 240 / h, 1.0])
    eh, ew = energy_shape(rh, rw)
    to_energy = np.diag([ew / rw, eh / rh, 1.0])
    short = _warp_prob(coarse.astype(np.float32), to_energy @ H @ np.linalg.inv(to_prob),
                       (eh, ew))
    long = shrink_proba(_warp_prob(resize_proba(coarse, (h, w)), H, (rh, rw)), 256)
    assert short.shape == long.shape == (eh, ew, 3)
    assert np.abs(short - long).mean() < 0.01
    assert (np.argmax(short, 2) == np.argmax(long, 2)).mean() > 0.97
    # the composition's order matters: the inverse left out samples the wrong pixels
    wrong = _warp_prob(coarse.astype(np.float32), to_energy @ H @ to_prob, (eh, ew))
    assert np.abs(wrong - long).mean() > 0.05


def test_labels_input_weighs_the_derivation_against_the_evidence():
    """The derivation is a prior worth EVIDENCE nats: a confident classifier overrides it (sky
    above the roof line, a class the grammar lacks), an unsure one does not."""
    from facadeforge.datasets import get_label_set
    from facadeforge.exchange.raster import LABEL_INDEX
    from facadeforge.parsing.parse import Parse

    ls = get_label_set("cmp6")

    derived = np.full((20, 20), LABEL_INDEX["wall"], np.uint8)
    derived[8:14, 6:14] = LABEL_INDEX["window"]
    prob = np.full((20, 20, ls.num_classes), 0.02, np.float32)
    prob[..., ls.index("wall")] = 0.9
    prob[:4, :, ls.index("background")] = 0.97          # confident: the sky
    prob[:4, :, ls.index("wall")] = 0.01
    prob[8:14, 6:14, ls.index("window")] = 0.4          # unsure window under the derived one
    prob[8:14, 6:14, ls.index("wall")] = 0.5
    prob /= prob.sum(2, keepdims=True)
    eye = np.eye(3)
    p = Parse(photo=np.zeros((20, 20, 3), np.uint8), rectified=np.zeros((20, 20, 3), np.uint8),
              homography=eye, inverse=eye, fit=None, tree=None, labels=derived,
              fallback=derived, rules="", report={}, prob=prob, label_set="cmp6", evidence=1.0)
    out = p.labels_input()
    assert (out[:4] == LABEL_INDEX["background"]).all()          # overridden: 97 % against 1 %
    assert (out[8:14, 6:14] == LABEL_INDEX["window"]).all()      # kept: 0.5 / 0.4 < e
    assert (p.labels_input(float("inf")) == derived).all()
    assert (p.labels_input(0.0)[8:14, 6:14] == LABEL_INDEX["wall"]).all()   # the classifier
