"""Synthetic facades: grammars, determinism, labels = rasterised tree, objects, loader, perspective."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets import LABEL_SETS, LOADERS, ObjectBox, load_dataset
from facadeforge.datasets import synthetic as S
from facadeforge.engine import derive_facade
from facadeforge.errors import InputError
from facadeforge.exchange.raster import LABEL_INDEX, label_map
from facadeforge.model.shape import Shape

WIDTH = 160
SUFFIXES = (".jpg", ".png", ".tree.json", ".objects.json", ".meta.json")


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _raw_labels(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        assert im.mode == "P"
        return np.asarray(im).copy()


@pytest.fixture(scope="module")
def flat(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("synth")
    S.generate(4, 3, out, size=WIDTH)
    return out


@pytest.fixture(scope="module")
def tilted(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("persp")
    S.generate(2, 5, out, size=WIDTH, perspective=True)
    return out


# ------------------------------------------------------------------------------- grammars
@pytest.mark.parametrize("style", S.STYLES)
def test_every_grammar_derives_without_warnings(style: str):
    rules = S.load_style(style)
    space = S.attribute_space(rules)
    assert {"facadeWidth", "skyHeight", "nFloors", "nTrees", "nCars"} <= set(space)
    seen: set[str] = set()
    for k in range(20):
        rng = np.random.default_rng([k, 17])
        attrs = S.draw_attributes(rules, rng)
        for name, spec in space.items():
            if spec[0] == "range":
                assert spec[1] - 1e-9 <= attrs[name] <= spec[2] + 1e-9, name
            else:
                assert attrs[name] in spec[1], name
        height = S._measure(rules, attrs, k) + attrs["skyHeight"]
        model = derive_facade(rules, attrs["facadeWidth"], height, attrs=attrs, seed=k)
        assert model.warnings == [], (style, k, model.warnings[:3])
        seen |= {leaf.label for leaf in model.root.leaves() if leaf.scope.size[:2].all()}
    assert {"wall", "window", "door", "sky"} <= seen
    assert seen <= set(LABEL_INDEX), seen - set(LABEL_INDEX)


def test_styles_cover_the_vocabulary():
    forced = {"haussmann": {"windowKind": "shutters", "continuousBalconies": True,
                            "shopsLeft": True, "pediments": True, "nTrees": 1, "streetHeight": 0.45},
              "modern": {"groundKind": "storefront", "balconyKind": "glass", "blindChance": 0.5,
                         "windowKind": "punched", "nCars": 1},
              "residential": {"windowKind": "blinds", "neighbourWidth": 1.5}}
    seen: set[str] = set()
    for style in S.STYLES:
        f = S.make_facade(style, np.random.default_rng(1), size=96, attrs=forced[style])
        seen |= {r.label for r in f.leaves}
    assert {"wall", "window", "door", "balcony", "shop", "roof", "sky", "cornice", "sill",
            "blind", "deco", "molding", "pillar", "vegetation", "car", "ground",
            "background"} <= seen


def test_unknown_style_is_refused(tmp_path: Path):
    with pytest.raises(InputError, match="unknown facade style 'gothic'"):
        S.generate(1, 0, tmp_path, styles=["gothic"])


# ------------------------------------------------------------------------------- determinism
def test_same_seed_same_bytes_other_seed_other_bytes(flat: Path, tmp_path: Path):
    again = tmp_path / "again"
    S.generate(4, 3, again, size=WIDTH)
    assert _files(again) == _files(flat)
    other = tmp_path / "other"
    S.generate(2, 4, other, size=WIDTH)
    a = [v for k, v in sorted(_files(flat).items()) if k.endswith(".jpg")]
    b = [v for k, v in sorted(_files(other).items()) if k.endswith(".jpg")]
    assert len(a) == 4 and len(b) == 2 and all(x != y for x, y in zip(a, b))


def test_every_facade_writes_five_files(flat: Path):
    names = sorted(p.name for p in flat.iterdir())
    assert names == sorted(f"synth_3_{i:04d}{s}" for i in range(4) for s in SUFFIXES)
    for i in range(4):
        meta = json.loads((flat / f"synth_3_{i:04d}.meta.json").read_text())
        with Image.open(flat / f"synth_3_{i:04d}.jpg") as im:
            assert im.format == "JPEG" and im.mode == "RGB"
            assert list(im.size) == meta["image_size"] and im.size[0] == WIDTH
        assert meta["style"] in S.STYLES and meta["homography"] is None
        assert meta["seed"] == 3 and meta["index"] == i and meta["warnings"] == []
        assert 70 <= meta["jpeg_quality"] <= 92 and meta["label_encoding"] == "canonical"
        w_m, h_m = meta["facade_size_m"]
        assert meta["metres_per_pixel"] == pytest.approx([w_m / WIDTH, h_m / im.size[1]])
        assert meta["floors"] >= 2 and meta["columns"] >= 1


# ------------------------------------------------------------------------------- labels
def test_label_png_is_the_rasterised_saved_tree(flat: Path):
    for i in range(4):
        stem = flat / f"synth_3_{i:04d}"
        tree = Shape.from_dict(json.loads(stem.with_suffix(".tree.json").read_text()))
        raw = _raw_labels(stem.with_suffix(".png"))
        assert np.array_equal(raw, label_map(tree, size=raw.shape))
        present = set(np.unique(raw).tolist())
        assert {LABEL_INDEX["wall"], LABEL_INDEX["window"], LABEL_INDEX["sky"]} <= present


def test_painted_leaf_rectangles_reproduce_the_label_map():
    """The renderer paints exactly the pixels the label map gives each leaf."""
    for k, style in enumerate(S.STYLES):
        f = S.make_facade(style, np.random.default_rng([k, 9]), size=(150, 170))
        assert (f.width_px, f.height_px) == (150, 170)
        painted = np.zeros((170, 150), np.uint8)
        for r in f.leaves:
            painted[r.r0:r.r1, r.c0:r.c1] = LABEL_INDEX[r.label]
        assert np.array_equal(painted, f.label_map())


def test_objects_cover_their_label_pixels(flat: Path):
    for i in range(4):
        stem = flat / f"synth_3_{i:04d}"
        raw = _raw_labels(stem.with_suffix(".png"))
        h, w = raw.shape
        objects = json.loads(stem.with_suffix(".objects.json").read_text())
        assert objects and all(o["label"] in S.OBJECT_LABELS for o in objects)
        for label in ("window", "door", "shop", "balcony"):
            mask = raw == LABEL_INDEX[label]
            covered = np.zeros_like(mask)
            boxes = [o["box"] for o in objects if o["label"] == label]
            for x0, y0, x1, y1 in boxes:
                assert 0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h
                covered[int(y0):int(y1), int(x0):int(x1)] = True
            assert not (mask & ~covered).any(), (stem.name, label)
            # most boxes show their own label (the rest are hidden behind occluders)
            if boxes:
                shown = [mask[int(y0):int(y1), int(x0):int(x1)].any() for x0, y0, x1, y1 in boxes]
                assert np.mean(shown) >= 0.8
        windows = [o for o in objects if o["label"] == "window"]
        assert windows and all(o["rect_m"][2] > o["rect_m"][0] for o in windows)


# ------------------------------------------------------------------------------- loader
def test_loader_round_trip(flat: Path):
    samples = load_dataset("synthetic", flat)
    assert LOADERS["synthetic"] is S.load_synthetic
    assert [s.id for s in samples] == [f"synth_3_{i:04d}" for i in range(4)]
    cmp6 = LABEL_SETS["cmp6"]
    for s in samples:
        img, labels = s.image(), s.labels()
        assert img.shape == labels.shape + (3,) and img.dtype == np.uint8
        raw = _raw_labels(s.label_path)
        assert np.array_equal(labels, cmp6.from_canonical(raw))
        assert labels.max() < cmp6.num_classes
        objects = s.objects()
        saved = json.loads(Path(s.meta["objects_path"]).read_text())
        assert objects == [ObjectBox(o["label"], *o["box"]) for o in saved]
        meta = json.loads(Path(s.meta["meta_path"]).read_text())
        assert s.meta["floors"] == meta["floors"] and s.meta["style"] == meta["style"]
        assert s.meta["dataset"] == "synthetic" and s.meta["objects_from"] == "tree"
    ecp7 = S.load_synthetic(flat, label_set="ecp7")[0]
    assert ecp7.label_set.name == "ecp7"
    sky = _raw_labels(ecp7.label_path) == LABEL_INDEX["sky"]
    assert (ecp7.labels()[sky] == LABEL_SETS["ecp7"].classes.index("sky")).all()


def test_loader_errors(tmp_path: Path, flat: Path):
    with pytest.raises(InputError, match="does not exist"):
        S.load_synthetic(tmp_path / "nope")
    with pytest.raises(InputError, match="no .jpg photos"):
        S.load_synthetic(tmp_path)
    (tmp_path / "x.jpg").write_bytes((flat / "synth_3_0000.jpg").read_bytes())
    with pytest.raises(InputError, match="no label PNG x.png"):
        S.load_synthetic(tmp_path)


# ------------------------------------------------------------------------------- perspective
def test_perspective_warps_labels_with_the_stored_homography(tilted: Path):
    for i in range(2):
        stem = tilted / f"synth_5_{i:04d}"
        meta = json.loads(stem.with_suffix(".meta.json").read_text())
        hmat = np.array(meta["homography"])
        assert hmat.shape == (3, 3) and not np.allclose(hmat, np.eye(3))
        tree = Shape.from_dict(json.loads(stem.with_suffix(".tree.json").read_text()))
        w, h = meta["image_size"]
        rectified = label_map(tree, size=(h, w))
        raw = _raw_labels(stem.with_suffix(".png"))
        assert np.array_equal(raw, S.warp_labels(rectified, hmat, (h, w)))
        # independently: photo pixel centres mapped back through the homography
        rng = np.random.default_rng(i)
        rows, cols = rng.integers(0, h, 400), rng.integers(0, w, 400)
        src = np.linalg.inv(hmat) @ np.stack([cols + 0.5, rows + 0.5, np.ones(400)])
        sx, sy = np.floor(src[:2] / src[2]).astype(int)
        inside = (sx >= 0) & (sx < w) & (sy >= 0) & (sy < h)
        expect = np.where(inside, rectified[np.clip(sy, 0, h - 1), np.clip(sx, 0, w - 1)],
                          LABEL_INDEX["background"])
        assert np.array_equal(raw[rows, cols], expect)
        assert inside.any()  # the sample reaches the facade, so the comparison above means something
        # object boxes follow the warp: window boxes still cover every window pixel
        mask = raw == LABEL_INDEX["window"]
        covered = np.zeros_like(mask)
        for o in json.loads(stem.with_suffix(".objects.json").read_text()):
            if o["label"] == "window":
                x0, y0, x1, y1 = o["box"]
                covered[int(np.floor(y0)):int(np.ceil(y1)), int(np.floor(x0)):int(np.ceil(x1))] = True
        assert not (mask & ~covered).any()


def test_homography_from_points_maps_the_corners():
    src = np.array([[0, 0], [10, 0], [10, 20], [0, 20]], float)
    dst = np.array([[1, 2], [9, 1], [11, 19], [-1, 21]], float)
    hmat = S.homography_from_points(src, dst)
    mapped = np.c_[src, np.ones(4)] @ hmat.T
    assert np.allclose(mapped[:, :2] / mapped[:, 2:], dst)


# ------------------------------------------------------------------------------- CLI
def test_cli_synth(tmp_path: Path, capsys):
    parser = argparse.ArgumentParser(prog="facadeforge")
    sub = parser.add_subparsers(dest="command")
    p = S.add_parser(sub)
    assert "facadeforge synth" in p.epilog
    args = parser.parse_args(["synth", "-n", "2", "--seed", "9", "-o", str(tmp_path),
                              "--style", "residential", "--width-px", "96"])
    assert S.cmd_synth(args) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("wrote 2 synthetic facades (residential 2; seed 9)") and "\n" not in line
    assert len(list(tmp_path.glob("*.jpg"))) == 2
    with Image.open(tmp_path / "synth_9_0000.jpg") as im:
        assert im.size[0] == 96


def test_loader_refuses_hostile_json(tmp_path: Path, flat: Path):
    # metadata and object lists are read through facadeforge.jsonfile: nesting and shape
    # errors name the file
    for suffix in (".jpg", ".png", ".meta.json", ".objects.json"):
        (tmp_path / f"x{suffix}").write_bytes((flat / f"synth_3_0000{suffix}").read_bytes())
    (tmp_path / "x.objects.json").write_text("[5]")
    (sample,) = S.load_synthetic(tmp_path)
    with pytest.raises(InputError, match=r"x.objects.json must list"):
        sample.objects()
    (tmp_path / "x.meta.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match=r"x.meta.json': JSON nested too deeply"):
        S.load_synthetic(tmp_path)
    (tmp_path / "x.meta.json").write_text("[1]")
    with pytest.raises(InputError, match="must hold a JSON object"):
        S.load_synthetic(tmp_path)


# ------------------------------------------------------------------------------ atomic writes
def test_a_failing_run_leaves_no_temporary_file(tmp_path: Path, monkeypatch):
    """The reproducer: a run stopped while writing left ``NAME.tree.json.tmp`` (a fixed name)
    behind; now what was written is whole and under its final name, and nothing else is."""
    import os

    real = os.replace

    def replace(src, dst):
        if str(dst).endswith(".tree.json"):      # the tree of the first facade
            raise OSError(28, "No space left on device")
        return real(src, dst)
    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError, match="No space left"):
        S.generate(2, 4, tmp_path, size=WIDTH)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["synth_4_0000.jpg", "synth_4_0000.png"]
    with Image.open(tmp_path / "synth_4_0000.jpg") as im:
        im.load()


def test_a_killed_runs_folder_is_removed_by_the_next_run(tmp_path: Path):
    import subprocess
    import sys

    from facadeforge.scratch import owner_tag

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    host = owner_tag().rsplit("-", 1)[0]
    stale = tmp_path / f"{S.STAGE_PREFIX}{host}-{dead}-abc123"
    stale.mkdir()
    (stale / "synth_1_0000.jpg").write_bytes(b"half a JPEG")
    other = tmp_path / f"{S.STAGE_PREFIX}otherhost-{dead}-abc123"   # not ours to judge
    other.mkdir()
    S.generate(1, 1, tmp_path, size=WIDTH)
    assert not stale.exists() and other.is_dir()
    assert len(list(tmp_path.glob("synth_1_0000.*"))) == 5
