"""LabelMeFacade loader: split files, colour labels (RGB / RGBA), unknown colours, errors, the
bench's splits, and the shared data when present."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets import (
    DEFAULT_LABEL_SETS,
    IGNORE,
    LABEL_SETS,
    LOADERS,
    ObjectBox,
    load_dataset,
    load_labelmefacade,
)
from facadeforge.datasets.labelmefacade import read_split_file
from facadeforge.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "labelmefacade"
LMF9 = LABEL_SETS["lmf9"]
H, W = 24, 32
# class indices of lmf9
VARIOUS, BUILDING, CAR, DOOR, PAVEMENT, ROAD, SKY, VEGETATION, WINDOW = range(9)


def _ids(n: int = 0) -> np.ndarray:
    """(H, W) lmf9 class indices of a small street photo."""
    ids = np.full((H, W), BUILDING, np.uint8)
    ids[:4] = SKY
    ids[-4:] = ROAD
    ids[-6:-4] = PAVEMENT
    ids[6:10, 4 + n:10 + n] = WINDOW
    ids[6:10, 20:26] = WINDOW
    ids[12:18, 14:18] = DOOR
    ids[14:20, 24:31] = CAR
    ids[10:18, 0:3] = VEGETATION
    ids[0, 0] = VARIOUS
    return ids


def _write(root: Path, name: str, ids: np.ndarray, rgba: bool = False,
           photo_suffix: str = ".jpg") -> None:
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "labels").mkdir(exist_ok=True)
    Image.fromarray(np.full((*ids.shape, 3), 120, np.uint8)).save(
        root / "images" / f"{name}{photo_suffix}")
    rgb = LMF9.colors[ids]
    if rgba:
        Image.fromarray(np.dstack([rgb, np.full(ids.shape, 255, np.uint8)]), mode="RGBA").save(
            root / "labels" / f"{name}.png")
    else:
        Image.fromarray(rgb).save(root / "labels" / f"{name}.png")


@pytest.fixture
def lmf(tmp_path: Path) -> Path:
    """Five labelled photos (two RGBA, one with dots in its name), one photo without a label;
    train.txt lists two, test.txt three (with a CRLF, a blank line, a comment, a folder and an
    extension on some lines)."""
    root = tmp_path / "lmf"
    names = ["a_street", "b_street", "img-10.21op9-p-015t000", "d_street", "e_street"]
    for n, name in enumerate(names):
        _write(root, name, _ids(n), rgba=n % 2 == 1)
    Image.new("RGB", (W, H)).save(root / "images" / "unlabelled.jpg")
    (root / "train.txt").write_text("b_street\nimg-10.21op9-p-015t000\n")
    (root / "test.txt").write_text("# test split\r\nimages/a_street.jpg\r\n\r\nd_street\n"
                                   "e_street  \n")
    return root


# ------------------------------------------------------------------------------- loading
def test_splits_ids_and_meta(lmf: Path):
    train = load_labelmefacade(lmf, split="train")
    test = load_labelmefacade(lmf, split="test")
    every = load_labelmefacade(lmf)                      # split="all" by default
    assert [s.id for s in train] == ["b_street", "img-10.21op9-p-015t000"]
    assert [s.id for s in test] == ["a_street", "d_street", "e_street"]
    assert [s.id for s in every] == sorted(s.id for s in train + test)   # not "unlabelled"
    s = train[1]
    assert s.image_path == lmf / "images" / "img-10.21op9-p-015t000.jpg"
    assert s.label_set is LMF9
    assert s.meta == {"dataset": "labelmefacade", "split": "train",
                      "label_path": str(lmf / "labels" / "img-10.21op9-p-015t000.png"),
                      "objects_from": "components"}
    assert every[0].meta["split"] == "all"


def test_rgb_and_rgba_labels_decode_exactly(lmf: Path):
    by_id = {s.id: s for s in load_labelmefacade(lmf)}
    for n, name in enumerate(["a_street", "b_street", "img-10.21op9-p-015t000", "d_street",
                              "e_street"]):
        labels = by_id[name].labels()
        assert labels.dtype == np.uint8 and np.array_equal(labels, _ids(n)), name
        assert by_id[name].meta["unknown_color_pixels"] == 0
    # RGBA (b_street) and RGB (a_street) give the same kind of map
    assert Image.open(by_id["b_street"].label_path).mode == "RGBA"
    assert Image.open(by_id["a_street"].label_path).mode == "RGB"


def test_objects_are_components(lmf: Path):
    s = load_labelmefacade(lmf, split="test")[0]          # a_street, n = 0
    windows = [o for o in s.objects() if o.label == "window"]
    assert windows == [ObjectBox("window", 4, 6, 10, 10), ObjectBox("window", 20, 6, 26, 10)]
    labels = {o.label for o in s.objects()}
    assert labels == {"other", "wall", "car", "door", "pavement", "road", "sky", "vegetation",
                      "window"}


def test_other_label_sets_through_canonical_labels(lmf: Path):
    s = load_labelmefacade(lmf, split="test", label_set="cmp6")[0]
    cmp6 = LABEL_SETS["cmp6"]
    labels = s.labels()
    assert s.label_set is cmp6
    # building → wall; window, door kept; sky, road, pavement, car, vegetation → background;
    # various is canonical "other", a piece of facade wherever there is no class for it
    assert labels[8, 5] == cmp6.index("window") and labels[14, 15] == cmp6.index("door")
    assert labels[12, 8] == labels[0, 0] == cmp6.index("wall")
    assert {labels[1, 5], labels[-1, 5], labels[-5, 5], labels[16, 27],
            labels[12, 1]} == {cmp6.index("background")}
    ecp7 = load_labelmefacade(lmf, split="test", label_set="ecp7")[0].labels()
    e = LABEL_SETS["ecp7"]
    assert ecp7[1, 5] == e.index("sky") and ecp7[16, 27] == e.index("wall")


def test_unknown_colours_are_ignored_counted_and_warned_once(tmp_path: Path):
    root = tmp_path / "lmf"
    for name in ("p", "q"):
        _write(root, name, _ids())
        rgb = np.asarray(Image.open(root / "labels" / f"{name}.png")).copy()
        rgb[2:4, 2:5] = (127, 1, 0)                      # anti-aliased / off-palette
        rgb[5, 5] = (255, 255, 255)
        Image.fromarray(rgb).save(root / "labels" / f"{name}.png")
    samples = load_labelmefacade(root)
    with pytest.warns(UserWarning, match=r"7 pixels .* outside the lmf9 palette") as record:
        first = samples[0].labels()
        second = samples[1].labels()
    assert len([w for w in record if "palette" in str(w.message)]) == 1
    for labels, s in ((first, samples[0]), (second, samples[1])):
        assert (labels[2:4, 2:5] == IGNORE).all() and labels[5, 5] == IGNORE
        assert (labels != IGNORE).sum() == H * W - 7
        assert s.meta["unknown_color_pixels"] == 7


def test_photo_suffixes_and_split_file_forms(tmp_path: Path):
    root = tmp_path / "lmf"
    _write(root, "x.y", _ids(), photo_suffix=".png")
    _write(root, "z", _ids(), photo_suffix=".jpeg")
    (root / "train.txt").write_text("\ufeffx.y.png\nsub\\folder\\z\nz\n")   # BOM, Windows path
    assert read_split_file(root / "train.txt") == ["x.y", "z"]
    assert [s.id for s in load_labelmefacade(root, split="train")] == ["x.y", "z"]
    assert [s.id for s in load_labelmefacade(root, split="all")] == ["x.y", "z"]


def test_registered_layout():
    assert LOADERS["labelmefacade"] is load_labelmefacade
    assert DEFAULT_LABEL_SETS["labelmefacade"] == "lmf9"


def test_load_dataset_passes_split(lmf: Path):
    assert len(load_dataset("labelmefacade", lmf, split="test")) == 3


# ------------------------------------------------------------------------------- errors
def test_missing_folder_and_subfolders(tmp_path: Path, lmf: Path):
    with pytest.raises(InputError, match="does not exist.*images/, labels/"):
        load_labelmefacade(tmp_path / "nope")
    (tmp_path / "bare").mkdir()
    with pytest.raises(InputError, match="has no images/ folder"):
        load_labelmefacade(tmp_path / "bare")
    (tmp_path / "bare" / "images").mkdir()
    with pytest.raises(InputError, match="has no labels/ folder"):
        load_labelmefacade(tmp_path / "bare")
    (tmp_path / "bare" / "labels").mkdir()
    with pytest.raises(InputError, match="no photo in images/ with a label"):
        load_labelmefacade(tmp_path / "bare")


def test_unknown_split_and_val(lmf: Path):
    with pytest.raises(InputError, match="no val split; score the test split"):
        load_labelmefacade(lmf, split="val")
    with pytest.raises(InputError, match="use one of train, test, all"):
        load_labelmefacade(lmf, split="dev")
    with pytest.raises(InputError, match="unknown label set"):
        load_labelmefacade(lmf, label_set="lmf10")


def test_missing_split_file(lmf: Path):
    (lmf / "test.txt").unlink()
    with pytest.raises(InputError, match=r"test\.txt does not exist.*--split all"):
        load_labelmefacade(lmf, split="test")
    (lmf / "test.txt").write_text("\n# nothing\n")
    with pytest.raises(InputError, match="lists no photos"):
        load_labelmefacade(lmf, split="test")


def test_listed_names_missing_on_disk(lmf: Path):
    (lmf / "train.txt").write_text("b_street\nghost_1\nghost_2\n")
    with pytest.raises(InputError, match=r"lists 2 of 3 names without .*images/<name>\.jpg: "
                                         r"ghost_1, ghost_2; add the files or remove"):
        load_labelmefacade(lmf, split="train")
    (lmf / "train.txt").write_text("b_street\n")
    (lmf / "labels" / "b_street.png").unlink()
    with pytest.raises(InputError, match=r"without .*labels/<name>\.png: b_street"):
        load_labelmefacade(lmf, split="train")


def test_single_channel_label_is_refused(tmp_path: Path):
    root = tmp_path / "lmf"
    _write(root, "g", _ids())
    Image.fromarray(_ids()).save(root / "labels" / "g.png")    # class indices as grey
    s = load_labelmefacade(root)[0]
    with pytest.raises(InputError, match="single-channel image; labels must be colour PNGs"):
        s.labels()


# ------------------------------------------------------------------------------- bench
def test_bench_splits(lmf: Path):
    from facadeforge.evaluation.bench import select_samples

    scored, fit, rule = select_samples("labelmefacade", lmf, "test")
    assert [s.id for s in scored] == ["a_street", "d_street", "e_street"]
    assert [s.id for s in fit] == ["b_street", "img-10.21op9-p-015t000"]
    assert "3 photos of" in rule and "test.txt" in rule and "fitted on the 2 photos" in rule
    scored, fit, _ = select_samples("labelmefacade", lmf, "train")
    assert [s.id for s in scored] == [s.id for s in fit] == ["b_street",
                                                             "img-10.21op9-p-015t000"]
    scored, fit, rule = select_samples("labelmefacade", lmf, "all")
    assert len(scored) == 5 and len(fit) == 2 and "train and test" in rule
    with pytest.raises(InputError, match="no val: use --split test"):
        select_samples("labelmefacade", lmf, "val")
    scored, _, _ = select_samples("labelmefacade", lmf, "test", labels="cmp6")
    assert scored[0].label_set is LABEL_SETS["cmp6"]
    (lmf / "train.txt").unlink()
    scored, fit, rule = select_samples("labelmefacade", lmf, "all")
    assert len(scored) == 5 and fit == [] and "no training set" in rule


def test_bench_cli_on_fake_folder(lmf: Path, tmp_path: Path, capsys):
    from facadeforge.cli import main

    out = tmp_path / "r.json"
    assert main(["bench", "--method", "prior", "--dataset", "labelmefacade", "--data", str(lmf),
                 "--split", "test", "-o", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["n_images"] == 3 and r["fit_images"] == 2 and r["label_set"] == "lmf9"
    assert list(r["per_class"]) == r["classes"] == list(LMF9.dataset_names)
    assert r["canonical_classes"] == list(LMF9.classes)
    assert r["unknown_color_pixels"] == 0
    assert "| building |" in (tmp_path / "r.md").read_text()
    assert main(["bench", "--method", "prior", "--dataset", "labelmefacade", "--data", str(lmf),
                 "--split", "val", "-o", str(out)]) == 2
    assert "no val: use --split test" in capsys.readouterr().err


# ------------------------------------------------------------------------------- shared data
def _need_data() -> Path:
    if not (DATA / "images").is_dir():
        pytest.skip(f"shared LabelMeFacade data not found at {DATA}")
    return DATA


def test_shared_splits_and_classes():
    root = _need_data()
    train = load_labelmefacade(root, split="train")
    test = load_labelmefacade(root, split="test")
    every = load_labelmefacade(root, split="all")
    assert (len(train), len(test), len(every)) == (100, 200, 300)
    assert not {s.id for s in train} & {s.id for s in test}
    assert {s.id for s in every} == {s.id for s in train} | {s.id for s in test}
    seen: set[int] = set()
    for s in train[::10]:
        labels = s.labels()
        assert labels.shape == s.image_shape()
        assert s.meta["unknown_color_pixels"] == 0 and (labels != IGNORE).all()
        seen |= set(np.unique(labels).tolist())
    assert seen == set(range(9))              # every class appears in a tenth of train


def test_shared_label_decoded_at_pixels():
    root = _need_data()
    s = next(s for s in load_labelmefacade(root, split="test")
             if s.id == "05june05_static_street_boston__p1010744")
    labels = s.labels()
    assert labels.shape == (512, 683)
    names = {(y, x): LMF9.dataset_names[labels[y, x]]
             for y, x in ((5, 5), (100, 300), (200, 200), (300, 50), (400, 100))}
    assert names == {(5, 5): "vegetation", (100, 300): "building", (200, 200): "window",
                     (300, 50): "car", (400, 100): "road"}


def test_shared_bench_cli_test_split(tmp_path: Path):
    """The CLI end to end on the shared test split (first 4 photos; prior fits on train.txt)."""
    from facadeforge.cli import main

    root = _need_data()
    out = tmp_path / "lmf.json"
    t = time.perf_counter()
    assert main(["bench", "--method", "prior", "--dataset", "labelmefacade", "--data",
                 str(root), "--split", "test", "--limit", "4", "-o", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["n_images"] == 4 and r["fit_images"] == 100
    assert r["unknown_color_pixels"] == 0           # the shared labels hold palette colours only
    assert list(r["per_class"]) == ["various", "building", "car", "door", "pavement", "road",
                                    "sky", "vegetation", "window"]
    assert r["per_class"]["building"]["accuracy"] == 1.0      # the prior: everything building
    assert "test.txt" in r["split_rule"] and "train.txt" in r["split_rule"]
    assert time.perf_counter() - t < 30
