"""Benchmark harness: method registry, warping, scoring and the files a run writes."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest
from PIL import Image

from facadeforge import datasets
from facadeforge.datasets import IGNORE, LABEL_SETS, load_cmp
from facadeforge.errors import InputError
from facadeforge.evaluation.bench import (
    RESULT_KEYS,
    add_parser,
    box_to_image,
    cmd_bench,
    run_bench,
    select_samples,
    warp_to_image,
)
from facadeforge.evaluation.methods import (
    METHODS,
    Prediction,
    get_method,
    register_method,
)
from facadeforge.evaluation.sheet import IGNORED_COLOR, RIGHT_COLOR, WRONG_COLOR, error_map

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
CMP_PALETTE = [0, 0, 0] + LABEL_SETS["cmp12"].colors.ravel().tolist()
H, W = 30, 40


# ------------------------------------------------------------------------------- fixtures
def _cmp_xml(objects) -> str:
    # the real format: bare <object> elements, \r line breaks; <x> holds the normalised top and
    # bottom (rows), <y> the left and right (columns)
    return "".join(
        f"<object>\r<points>\r<x>\r{r0}\r</x>\r<x>\r{r1}\r</x>\r<y>\r{c0}\r</y>\r<y>\r{c1}\r</y>\r"
        f"</points>\r<label>\r{k}\r</label>\r<labelname>\r{name}\r</labelname>\r<flag>\r1\r"
        f"</flag>\r</object>\r" for (r0, r1, c0, c1), k, name in objects)


def _facade(n: int) -> tuple[np.ndarray, list]:
    """(H, W) CMP ids of facade ``n`` and its XML objects: sky row, windows, door, shop."""
    ids = np.full((H, W), 2, np.uint8)          # facade
    ids[:3] = 1                                  # background
    objects = [((0.1, 1.0, 0.0, 1.0), 2, "facade")]   # (rows, columns), normalised
    shift = n % 3
    for row in range(2):
        for col in range(3):
            x0, y0 = 4 + 12 * col + shift, 6 + 8 * row
            ids[y0:y0 + 5, x0:x0 + 6] = 3        # window 6 x 5 px
            objects.append(((y0 / H, (y0 + 5) / H, x0 / W, (x0 + 6) / W), 3, "window"))
    ids[22:, 4:10] = 4                            # door
    ids[24:, 20 + shift:36] = 12                  # shop
    return ids, objects


@pytest.fixture
def cmp_dir(tmp_path: Path) -> Path:
    root = tmp_path / "cmp"
    root.mkdir()
    rng = np.random.default_rng(0)
    for n in range(1, 9):
        stem = f"cmp_b{n:04d}"
        ids, objects = _facade(n)
        photo = LABEL_SETS["cmp12"].colors[ids - 1].astype(np.int16)
        photo = np.clip(photo + rng.integers(-20, 21, photo.shape), 0, 255).astype(np.uint8)
        Image.fromarray(photo).save(root / f"{stem}.jpg", quality=90)
        label = Image.fromarray(ids, mode="P")
        label.putpalette(CMP_PALETTE)
        label.save(root / f"{stem}.png")
        (root / f"{stem}.xml").write_text(_cmp_xml(objects))
    return root


@pytest.fixture
def register():
    """Register test-only methods; they are removed afterwards."""
    added: list[str] = []

    def add(name: str, fn, label_space: str = "label_set"):
        register_method(name, label_space, replace=True)(fn)
        added.append(name)
        return fn

    yield add
    for name in added:
        METHODS.pop(name, None)


def _truth_windows(sample) -> np.ndarray:
    return np.array([(o.x0, o.y0, o.x1, o.y1) for o in sample.objects() if o.label == "window"],
                    np.float64).reshape(-1, 4)


def oracle(sample, label_set):
    """Test only: returns the truth itself."""
    return Prediction(labels=sample.labels(), windows=_truth_windows(sample))


def oracle_2x(sample, label_set):
    """Test only: the truth in a 2x scaled frame, with the homography back to the photo."""
    big = np.repeat(np.repeat(sample.labels(), 2, axis=0), 2, axis=1)
    return Prediction(labels=big, homography=np.diag([0.5, 0.5, 1.0]),
                      windows=_truth_windows(sample) * 2)


def _load(path: Path) -> dict:
    return json.loads(path.read_text())


# ------------------------------------------------------------------------------- baselines
@pytest.mark.parametrize("method", ["rowcol-prior", "prior"])
def test_baselines_write_every_key(cmp_dir: Path, tmp_path: Path, method: str):
    out = tmp_path / "res" / "RESULT.json"
    r = run_bench(method, "cmp", cmp_dir, out=out, progress=False)
    saved = _load(out)
    assert saved == json.loads(json.dumps(r))
    assert set(RESULT_KEYS) <= set(saved)
    assert saved["method"] == method and saved["dataset"] == "cmp"
    assert saved["split"] == "val" and saved["label_set"] == "cmp6"
    assert saved["n_images"] == 2 and saved["fit_images"] == 6   # 8 facades: val = 1st, 6th
    assert [p["id"] for p in saved["per_image"]] == ["cmp_b0001", "cmp_b0006"]
    for key in ("pixel_accuracy", "class_avg_accuracy", "miou", "window_precision",
                "window_recall", "window_f1", "unpredicted_fraction"):
        assert 0.0 <= saved[key] <= 1.0, key
    k = 6
    assert np.array(saved["confusion"]).shape == (k, k)
    assert np.array(saved["confusion_percent"], dtype=float).shape == (k, k)
    assert sum(map(sum, saved["confusion"])) == 2 * H * W          # CMP labels every pixel
    assert set(saved["per_class"]) == set(LABEL_SETS["cmp6"].classes)
    assert saved["seconds_per_image"] >= 0 and saved["peak_memory_mb"] >= 0
    assert {"cores", "cpu", "python"} <= set(saved["machine"])
    assert saved["date"] and saved["data"] == str(cmp_dir.resolve())
    assert "floor_count_mae" not in saved                            # no floors on either side
    md = out.with_suffix(".md").read_text()
    assert "## Per class" in md and "## Confusion" in md and method in md
    sheet = tmp_path / "res" / "RESULT_sheet.png"
    with Image.open(sheet) as im:
        assert im.format == "PNG" and im.width > 4 * 40 and im.height > 100
    assert saved["best"] and set(saved["best"]).isdisjoint(saved["worst"])


def test_prior_predicts_the_training_majority(cmp_dir: Path, tmp_path: Path):
    r = run_bench("prior", "cmp", cmp_dir, out=tmp_path / "r.json", progress=False)
    wall = LABEL_SETS["cmp6"].classes.index("wall")
    confusion = np.array(r["confusion"])
    assert (confusion[:, wall] == confusion.sum(axis=1)).all()      # everything predicted wall
    assert r["window_f1"] == 0.0 and r["window_fp"] == 0             # no windows predicted
    assert r["window_fn"] == 12                                      # 6 windows x 2 facades


def test_rowcol_prior_learns_the_layout(cmp_dir: Path, tmp_path: Path):
    r = run_bench("rowcol-prior", "cmp", cmp_dir, out=tmp_path / "r.json", progress=False)
    p = run_bench("prior", "cmp", cmp_dir, out=tmp_path / "p.json", progress=False)
    assert r["pixel_accuracy"] > p["pixel_accuracy"]
    assert r["per_class"]["background"]["iou"] > 0.9                 # the sky row is always there
    assert r["windows_from"] == {"method": 0, "label_components": 2}
    every = run_bench("rowcol-prior", "cmp", cmp_dir, split="all", out=tmp_path / "a.json",
                      progress=False)                              # 8 facades: sheet keeps 6
    mious = {p["id"]: p["miou"] for p in every["per_image"]}
    assert len(every["best"]) == len(every["worst"]) == 3
    assert min(mious[i] for i in every["best"]) >= max(mious[i] for i in every["worst"])
    assert sorted(mious.values())[0] == mious[every["worst"][0]]


# ------------------------------------------------------------------------------- oracles
def test_oracle_scores_perfectly(cmp_dir: Path, tmp_path: Path, register):
    register("oracle", oracle)
    r = run_bench("oracle", "cmp", cmp_dir, split="all", out=tmp_path / "o.json",
                  progress=False)
    assert r["n_images"] == 8
    assert r["pixel_accuracy"] == 1.0 and r["miou"] == 1.0 and r["class_avg_accuracy"] == 1.0
    assert r["window_f1"] == 1.0 and r["window_tp"] == 48 and r["window_fp"] == 0
    assert r["windows_from"] == {"method": 8, "label_components": 0}
    assert all(p["miou"] == 1.0 for p in r["per_image"])


def test_label_oracle_windows_match_the_xml_boxes(cmp_dir: Path, tmp_path: Path, register):
    """Windows from the true label map's components (not from the XML boxes) match the XML
    window boxes: the boxes are read in the right axis order (<x> = rows)."""
    register("labels-only", lambda s, ls: Prediction(labels=s.labels()))
    r = run_bench("labels-only", "cmp", cmp_dir, split="all", out=tmp_path / "l.json",
                  progress=False)
    assert r["windows_from"] == {"method": 0, "label_components": 8}
    assert r["window_f1"] == 1.0 and r["window_tp"] == 48


def test_rectified_frame_is_warped_back(cmp_dir: Path, tmp_path: Path, register):
    register("oracle", oracle)
    register("oracle-2x", oracle_2x)
    a = run_bench("oracle", "cmp", cmp_dir, split="all", out=tmp_path / "a.json",
                  progress=False)
    b = run_bench("oracle-2x", "cmp", cmp_dir, split="all", out=tmp_path / "b.json",
                  progress=False)
    for key in ("pixel_accuracy", "miou", "window_f1", "confusion"):
        assert a[key] == b[key], key
    assert b["pixel_accuracy"] == 1.0 and b["window_f1"] == 1.0


def test_unpredicted_pixels_count_as_wrong(cmp_dir: Path, tmp_path: Path, register):
    def left_part(sample, label_set):          # predicts only the left 30 of 40 columns
        return Prediction(labels=sample.labels()[:, :30], homography=np.eye(3))

    register("left-part", left_part)
    r = run_bench("left-part", "cmp", cmp_dir, split="all", out=tmp_path / "l.json",
                  progress=False)
    assert r["pixel_accuracy"] == pytest.approx(30 / 40)
    assert r["unpredicted_fraction"] == pytest.approx(10 / 40)
    assert sum(r["unpredicted"]) == 8 * H * 10
    assert "unpredicted" in Path(r["files"]["markdown"]).read_text()


def test_canonical_label_space(cmp_dir: Path, tmp_path: Path, register):
    def canonical(sample, label_set):
        return Prediction(labels=label_set.to_canonical(sample.labels()),
                          windows=_truth_windows(sample))

    register("canonical-oracle", canonical, "canonical")
    r = run_bench("canonical-oracle", "cmp", cmp_dir, out=tmp_path / "c.json", progress=False)
    assert r["pixel_accuracy"] == 1.0


def test_fit_gets_the_train_split(cmp_dir: Path, tmp_path: Path, register):
    seen: list[str] = []

    class Recorder:
        def fit(self, train, label_set):
            seen.extend(s.id for s in train)

        def __call__(self, sample, label_set):
            return Prediction(labels=sample.labels())

    register("recorder", Recorder())
    assert get_method("recorder").fit is not None
    run_bench("recorder", "cmp", cmp_dir, limit=1, out=tmp_path / "f.json", progress=False)
    assert seen == ["cmp_b0002", "cmp_b0003", "cmp_b0004", "cmp_b0005", "cmp_b0007",
                    "cmp_b0008"]


def test_counts_and_later_layouts_plug_in(cmp_dir: Path, tmp_path: Path, register,
                                          monkeypatch):
    def synthetic(root, label_set="cmp6"):     # stands in for a layout registered later
        samples = load_cmp(root, label_set=label_set)
        for s in samples:
            s.meta["floors"] = 2
        return samples

    monkeypatch.setattr(datasets, "LOADERS",
                        MappingProxyType({**datasets.LOADERS, "synthetic": synthetic}))
    register("floors", lambda s, ls: Prediction(labels=s.labels(), floors=3))
    r = run_bench("floors", "synthetic", cmp_dir, split="all", out=tmp_path / "s.json",
                  progress=False)
    assert r["dataset"] == "synthetic" and r["n_images"] == 8
    assert r["floor_count_mae"] == 1.0 and r["floor_count_exact"] == 0.0
    assert "column_count_mae" not in r


# ------------------------------------------------------------------------------- errors
def test_unknown_method_and_dataset_name_the_choices(cmp_dir: Path, tmp_path: Path):
    with pytest.raises(InputError, match=r"unknown method 'nope'.*prior.*rowcol-prior"):
        run_bench("nope", "cmp", cmp_dir, out=tmp_path / "x.json")
    with pytest.raises(InputError,
                       match=r"unknown dataset 'nope'.*cmp, ruemonge, labelmefacade, folder"):
        run_bench("prior", "nope", cmp_dir, out=tmp_path / "x.json")
    with pytest.raises(InputError, match=r"unknown split 'test'.*train, val, all"):
        run_bench("prior", "cmp", cmp_dir, split="test", out=tmp_path / "x.json")
    with pytest.raises(InputError, match=r"unknown label set 'cmp5'"):
        run_bench("prior", "cmp", cmp_dir, labels="cmp5", out=tmp_path / "x.json")
    with pytest.raises(InputError, match="positive"):
        run_bench("prior", "cmp", cmp_dir, limit=0, out=tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()


def test_bad_predictions_are_named(cmp_dir: Path, tmp_path: Path, register):
    register("small", lambda s, ls: Prediction(labels=np.zeros((3, 3), np.uint8)))
    with pytest.raises(InputError, match=r"'small' on cmp_b0001.*3x3 px.*40x30.*homography"):
        run_bench("small", "cmp", cmp_dir, out=tmp_path / "x.json", progress=False)
    register("too-big", lambda s, ls: Prediction(labels=np.full((H, W), 9, np.uint8)))
    with pytest.raises(InputError, match=r"class indices \[9\] are outside 0..5"):
        run_bench("too-big", "cmp", cmp_dir, out=tmp_path / "x.json", progress=False)
    with pytest.raises(InputError, match="already registered"):
        register_method("prior")(oracle)


# ------------------------------------------------------------------------------- geometry
def test_warp_to_image():
    labels = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert np.array_equal(warp_to_image(labels, np.eye(3), (3, 4)), labels)
    big = np.repeat(np.repeat(labels, 2, 0), 2, 1)
    assert np.array_equal(warp_to_image(big, np.diag([0.5, 0.5, 1]), (3, 4)), labels)
    assert np.array_equal(warp_to_image(labels, -np.eye(3), (3, 4)), labels)   # scale-free
    shifted = warp_to_image(labels, [[1, 0, 1], [0, 1, 0], [0, 0, 1]], (3, 4))  # 1 px right
    assert (shifted[:, 0] == IGNORE).all() and np.array_equal(shifted[:, 1:], labels[:, :3])
    with pytest.raises(InputError, match="singular"):
        warp_to_image(labels, np.zeros((3, 3)), (3, 4))
    boxes = box_to_image([[2, 2, 6, 4]], np.diag([0.5, 0.5, 1]), (3, 4))
    assert boxes.tolist() == [[1, 1, 3, 2]]


def test_error_map_colours():
    truth = np.array([[0, 1, IGNORE]], np.uint8)
    pred = np.array([[0, 2, 1]], np.uint8)
    assert error_map(truth, pred)[0].tolist() == [list(RIGHT_COLOR), list(WRONG_COLOR),
                                                 list(IGNORED_COLOR)]


# ------------------------------------------------------------------------------- RueMonge splits
def _ruemonge(root: Path, split: str, stems) -> None:
    (root / split / "img").mkdir(parents=True)
    (root / split / "label").mkdir()
    ids = np.full((8, 10), 2, np.uint8)
    ids[:2] = 6
    ids[3:5, 2:4] = 1
    for stem in stems:
        Image.fromarray(np.zeros((8, 10, 3), np.uint8)).save(root / split / "img" / f"{stem}.jpg")
        Image.fromarray(ids, mode="L").save(root / split / "label" / f"{stem}.png")


def test_ruemonge_split_rule(tmp_path: Path):
    root = tmp_path / "rm"
    _ruemonge(root, "train", [f"IMG_{i}" for i in range(10)])
    # none of these ids is a development val id: held-out photos, scored whole
    scored, fit, rule = select_samples("ruemonge", root, "val")
    assert len(scored) == 10 and fit == [] and "held-out" in rule
    scored, fit, rule = select_samples("ruemonge", root, "train")
    # no development ids: no building split to take val from, so all of it is train
    assert [s.id for s in scored] == [f"IMG_{i}" for i in range(10)]
    assert "by building" in rule
    scored, fit, _ = select_samples("ruemonge", root / "train", "train")
    assert len(scored) == 10 and fit == []                     # a split folder, scored whole
    _ruemonge(root, "val", ["IMG_90", "IMG_91"])
    scored, fit, _ = select_samples("ruemonge", root, "val")
    assert [s.id for s in scored] == ["IMG_90", "IMG_91"] and len(fit) == 10
    assert len(select_samples("ruemonge", root, "all")[0]) == 12
    r = run_bench("rowcol-prior", "ruemonge", root, out=tmp_path / "rm.json", progress=False)
    assert r["label_set"] == "ecp7" and r["n_images"] == 2 and r["pixel_accuracy"] == 1.0


# ------------------------------------------------------------------------------- CLI glue
def test_cli_glue(cmp_dir: Path, tmp_path: Path, capsys):
    parser = argparse.ArgumentParser(prog="facadeforge")
    add_parser(parser.add_subparsers(dest="command"))
    out = tmp_path / "cli.json"
    args = parser.parse_args(["bench", "--method", "prior", "--dataset", "cmp", "--data",
                              str(cmp_dir), "--split", "all", "--labels", "cmp12", "--limit",
                              "2", "-o", str(out)])
    assert cmd_bench(args) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("prior on cmp/all (2 facades, cmp12): pixel acc") and "mIoU" in line
    assert _load(out)["label_set"] == "cmp12"
    with pytest.raises(SystemExit):
        parser.parse_args(["bench", "--method", "prior", "--dataset", "cmp", "--data", "d",
                           "--limit", "0", "-o", "x.json"])
    assert "examples:" in parser._subparsers._group_actions[0].choices["bench"].epilog


@pytest.mark.parametrize("output, message", [
    ("dir", "is a folder; bench writes a result file"),          # an existing folder
    ("new/", "is a folder; bench writes a result file"),         # meant as one
    ("result", "is not a .json file"),
    ("cmp/result.json", "inside the dataset folder"),            # never write into the input
])
def test_a_bad_output_is_refused_before_any_file(cmp_dir: Path, tmp_path: Path, output: str,
                                                 message: str, monkeypatch):
    """The reproducer: ``bench -o DIR`` wrote DIR.md and DIR_sheet.png, then failed."""
    (tmp_path / "dir").mkdir()
    before = sorted(tmp_path.rglob("*"))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=message):
        run_bench("prior", "cmp", cmp_dir, out=output if output.endswith("/") else
                  tmp_path / output, progress=False)
    assert sorted(tmp_path.rglob("*")) == before


def test_results_are_written_all_three_or_none(cmp_dir: Path, tmp_path: Path, monkeypatch):
    from facadeforge.evaluation import bench

    out = tmp_path / "r.json"
    run_bench("prior", "cmp", cmp_dir, limit=2, out=out, progress=False)
    first = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert sorted(first) == ["r.json", "r.md", "r_sheet.png"]

    def broken(result):
        raise OSError("disk full")

    monkeypatch.setattr(bench, "markdown_summary", broken)   # fails after the sheet is drawn
    with pytest.raises(OSError, match="disk full"):
        run_bench("prior", "cmp", cmp_dir, split="all", out=out, progress=False)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == first


# ------------------------------------------------------------------------------- real data
@pytest.mark.skipif(not (DATA / "cmp").is_dir(), reason=f"shared CMP data not found at {DATA}")
def test_real_cmp_limit_3(tmp_path: Path):
    r = run_bench("rowcol-prior", "cmp", DATA / "cmp", split="val", labels="cmp6", limit=3,
                  out=tmp_path / "cmp.json", progress=False)
    assert r["n_images"] == 3 and r["fit_images"] == 240
    assert [p["id"] for p in r["per_image"]] == ["cmp_b0001", "cmp_b0006", "cmp_b0012"]
    assert 0.3 < r["pixel_accuracy"] < 1.0 and r["window_fn"] > 0
    assert (tmp_path / "cmp_sheet.png").is_file() and (tmp_path / "cmp.md").is_file()


def test_held_out_cmp_folder_is_scored_whole(tmp_path):
    """A CMP-layout folder without the development ids is held-out data: --split val scores all."""
    from facadeforge.evaluation.bench import select_samples

    folder = tmp_path / "held"
    folder.mkdir()
    from PIL import Image

    for k in range(7):
        name = f"cmp_x{k:04d}"
        Image.new("RGB", (20, 16), (120, 110, 100)).save(folder / f"{name}.jpg")
        lab = Image.new("P", (20, 16), 2)
        lab.putpalette([0, 0, 0] * 256)
        lab.save(folder / f"{name}.png")
    scored, fit, rule = select_samples("cmp", folder, "val")
    assert len(scored) == 7 and fit == [] and "held-out" in rule


# ------------------------------------------------------------------------------- every dataset kind
def _folder_dataset(root: Path) -> Path:
    """A tiny generic folder: palette.json, photos and single-channel label PNGs."""
    root.mkdir()
    (root / "palette.json").write_text(json.dumps(
        {"classes": ["background", "wall", "window"], "ids": [0, 1, 2], "ignore": 255}))
    for n in range(5):
        ids = np.ones((H, W), np.uint8)
        ids[:3] = 0
        ids[-2:] = IGNORE
        for col in range(3):
            x0 = 4 + 12 * col + n % 3
            ids[8:14, x0:x0 + 6] = 2
        Image.fromarray(np.full((H, W, 3), 90 + 10 * n, np.uint8)).save(root / f"f{n}.jpg")
        Image.fromarray(ids, mode="L").save(root / f"f{n}.png")
    return root


def _synthetic_dataset(root: Path, perspective: bool = False) -> Path:
    from facadeforge.datasets.synthetic import generate

    generate(2, 7, root, size=96, perspective=perspective)
    return root


def _labelmefacade_dataset(root: Path) -> Path:
    """A tiny LabelMeFacade folder: images/, RGBA colour labels/, train.txt and test.txt."""
    colors = LABEL_SETS["lmf9"].colors
    (root / "images").mkdir(parents=True)
    (root / "labels").mkdir()
    names = [f"street_{n}" for n in range(4)]
    for n, name in enumerate(names):
        ids = np.ones((H, W), np.uint8)             # building
        ids[:4] = 6                                 # sky
        ids[-5:] = 5                                # road
        ids[-8:-5] = 4                              # pavement
        ids[14:22, 2 + n:12 + n] = 2                # a car
        for col in range(2):
            ids[6:11, 18 + 10 * col:24 + 10 * col] = 8   # windows
        Image.fromarray(np.full((H, W, 3), 100 + 20 * n, np.uint8)).save(
            root / "images" / f"{name}.jpg")
        rgba = np.dstack([colors[ids], np.full((H, W), 255, np.uint8)])
        Image.fromarray(rgba, mode="RGBA").save(root / "labels" / f"{name}.png")
    (root / "train.txt").write_text("\n".join(names[:2]) + "\n")
    (root / "test.txt").write_text("\n".join(names[2:]) + "\n")
    return root


def _dataset_kinds():
    kinds = [pytest.param("synthetic", lambda tmp: _synthetic_dataset(tmp / "synth"),
                          id="synthetic"),
             pytest.param("synthetic", lambda tmp: _synthetic_dataset(tmp / "persp", True),
                          id="synthetic-perspective"),
             pytest.param("folder", lambda tmp: _folder_dataset(tmp / "folder"), id="folder"),
             pytest.param("labelmefacade", lambda tmp: _labelmefacade_dataset(tmp / "lmf"),
                          id="labelmefacade")]
    for name in ("cmp", "ruemonge", "labelmefacade"):
        kinds.append(pytest.param(
            name, lambda tmp, name=name: DATA / name, id=f"{name}-shared",
            marks=pytest.mark.skipif(not (DATA / name).is_dir(),
                                     reason=f"shared {name} data not found at {DATA / name}")))
    return kinds


def test_every_registered_layout_has_an_oracle_case():
    """A layout added to LOADERS needs a case in _dataset_kinds (the cmp fixture has its own)."""
    covered = {p.values[0] for p in _dataset_kinds()}
    assert set(datasets.LOADERS) <= covered


@pytest.mark.parametrize("dataset, build", _dataset_kinds())
def test_oracle_scores_one_on_every_dataset_kind(dataset: str, build, tmp_path: Path, register):
    """The truth, returned as a prediction through the whole bench path (loader, default label
    set, split, scoring, windows, sheet), scores 1.0: truth and scoring share one frame and one
    label set on every layout."""
    data = build(tmp_path)
    register("oracle", oracle)
    r = run_bench("oracle", dataset, data, split="all", limit=3, out=tmp_path / "o.json",
                  progress=False)
    assert r["n_images"] >= 1
    assert r["pixel_accuracy"] == 1.0 and r["miou"] == 1.0 and r["class_avg_accuracy"] == 1.0
    assert r["unpredicted_fraction"] == 0.0
    assert all(p["miou"] == 1.0 and p["pixel_accuracy"] == 1.0 for p in r["per_image"])
    if r["window_tp"] + r["window_fn"]:
        assert r["window_f1"] == 1.0 and r["window_fp"] == r["window_fn"] == 0
    # the sheet's error panels are white or grey: no right pixel drawn as wrong
    sheet = np.asarray(Image.open(tmp_path / "o_sheet.png").convert("RGB"))
    assert not (sheet == np.array(WRONG_COLOR, np.uint8)).all(axis=2).any()


@pytest.mark.parametrize("perspective", [False, True])
def test_synthetic_photos_are_rectified_unless_warped(tmp_path: Path, monkeypatch,
                                                     perspective: bool):
    """Issue 24 item 6: synthetic facades are front-on and labelled in CMP's conventions
    (neighbours, roof and sky are background); a method that rectified them again and used the
    street-photo classifier (ecp7: no background, neighbours are wall) scored mIoU 0.158."""
    import facadeforge.reconstruction as reconstruction
    from facadeforge.evaluation.methods import StructureMethod, is_rectified

    samples = datasets.load_synthetic(_synthetic_dataset(tmp_path / "s", perspective))
    assert [is_rectified(s) for s in samples] == [not perspective] * len(samples)
    seen = []

    def fake(photo, *, rectified=False, **kw):
        seen.append(rectified)
        raise RuntimeError("stop")

    monkeypatch.setattr(reconstruction, "reconstruct", fake)
    with pytest.raises(RuntimeError, match="stop"):
        StructureMethod()(samples[0], samples[0].label_set)
    assert seen == [not perspective]
