"""Dataset loaders on tiny generated folders, their errors, and a few real files when present."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets import (
    IGNORE,
    LABEL_SETS,
    LOADERS,
    ObjectBox,
    load_cmp,
    load_dataset,
    load_folder,
    load_palette,
    load_ruemonge,
    objects_from_labels,
    read_cmp_xml,
    read_image,
)
from facadeforge.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
CMP_PALETTE = [0, 0, 0] + LABEL_SETS["cmp12"].colors.ravel().tolist()


# ------------------------------------------------------------------------------- fixtures
def _photo(path: Path, h: int, w: int, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    Image.fromarray(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)).save(path)


def _cmp_ids() -> np.ndarray:
    """(10, 20) CMP ids: background row, facade, a window block, a blind, a shop strip."""
    ids = np.full((10, 20), 2, np.uint8)
    ids[0] = 1
    ids[2:5, 5:10] = 3          # window
    ids[2:5, 10:12] = 8         # blind
    ids[8:, :] = 12             # shop
    return ids


def _cmp_xml(objects) -> str:
    # like the real files: no root element, \r line breaks
    parts = []
    for (x0, x1, y0, y1), k, name in objects:
        parts.append(f"<object>\r<points>\r<x>\r{x0}\r</x>\r<x>\r{x1}\r</x>\r<y>\r{y0}\r</y>\r"
                     f"<y>\r{y1}\r</y>\r</points>\r<label>\r{k}\r</label>\r<labelname>\r{name}"
                     f"\r</labelname>\r<flag>\r1\r</flag>\r</object>\r")
    return "".join(parts)


@pytest.fixture
def cmp_dir(tmp_path: Path) -> Path:
    root = tmp_path / "cmp"
    root.mkdir()
    for n in (2, 1):
        stem = f"cmp_b000{n}"
        _photo(root / f"{stem}.jpg", 10, 20, n)
        label = Image.fromarray(_cmp_ids(), mode="P")
        label.putpalette(CMP_PALETTE)
        label.save(root / f"{stem}.png")
    (root / "cmp_b0001.xml").write_text(_cmp_xml([
        # CMP's <x> pair is the vertical extent (rows), <y> the horizontal one (columns)
        ((0.2, 0.5, 0.25, 0.5), 3, "window"),
        ((0.2, 0.5, 0.6, 0.5), 8, "blind"),      # columns given right-to-left
        ((0.1, 1.2, 0.0, 1.0), 2, "facade"),      # clipped to the photo
    ]))
    (root / "label_names.txt").write_text("1 background 1\n")
    return root


@pytest.fixture
def ruemonge_dir(tmp_path: Path) -> Path:
    root = tmp_path / "ruemonge"
    for split in ("train", "val"):
        (root / split / "img").mkdir(parents=True)
        (root / split / "label").mkdir()
    ids = np.full((100, 200), 2, np.uint8)   # wall
    ids[:10] = 6                              # sky
    ids[10:15] = 5                            # roof
    ids[20:40, 20:50] = 1                     # window A
    ids[20:40, 60:90] = 1                     # window B
    ids[70, 150] = 1                          # 1 px < 0.01 % of 20000 px: not an object
    ids[90:] = 0                              # unlabelled street
    for stem in ("IMG_2", "IMG_1"):
        _photo(root / "train" / "img" / f"{stem}.jpg", 100, 200)
        Image.fromarray(ids, mode="L").save(root / "train" / "label" / f"{stem}.png")
    _photo(root / "val" / "img" / "IMG_9.jpg", 100, 200)
    Image.fromarray(ids, mode="L").save(root / "val" / "label" / "IMG_9.png")
    return root


# ------------------------------------------------------------------------------- CMP
def test_load_cmp(cmp_dir: Path):
    samples = load_cmp(cmp_dir)
    assert [s.id for s in samples] == ["cmp_b0001", "cmp_b0002"]
    s = samples[0]
    assert s.label_set is LABEL_SETS["cmp6"] and s.meta["dataset"] == "cmp"
    img = s.image()
    assert img.shape == (10, 20, 3) and img.dtype == np.uint8
    assert s.image_shape() == (10, 20)
    labels = s.labels()
    assert labels.shape == (10, 20) and labels.dtype == np.uint8
    expected = np.full((10, 20), 1)
    expected[0] = 0
    expected[2:5, 5:12] = 2      # window + blind → window
    expected[8:] = 5
    assert np.array_equal(labels, expected)
    assert np.array_equal(load_cmp(cmp_dir, "cmp12")[0].labels(),
                          LABEL_SETS["cmp12"].from_dataset(_cmp_ids()))


def test_cmp_objects_from_xml(cmp_dir: Path):
    boxes = load_cmp(cmp_dir, label_set="cmp6")[0].objects()
    assert boxes == [ObjectBox("window", 5.0, 2.0, 10.0, 5.0),
                     ObjectBox("blind", 10.0, 2.0, 12.0, 5.0),
                     ObjectBox("wall", 0.0, 1.0, 20.0, 10.0)]
    assert boxes[0].width == 5 and boxes[0].height == 3 and boxes[0].area == 15
    assert read_cmp_xml(cmp_dir / "cmp_b0001.xml", 40, 20)[0].as_array().tolist() == [
        10, 4, 20, 10]


def test_cmp_without_xml_uses_components(cmp_dir: Path):
    s = load_cmp(cmp_dir)[1]
    assert s.meta["objects_from"] == "components"
    windows = [b for b in s.objects() if b.label == "window"]
    assert windows == [ObjectBox("window", 5.0, 2.0, 12.0, 5.0)]


def test_cmp_rgb_label_image(cmp_dir: Path):
    rgb = LABEL_SETS["cmp12"].to_color(LABEL_SETS["cmp12"].from_dataset(_cmp_ids()))
    Image.fromarray(rgb).save(cmp_dir / "cmp_b0002.png")
    assert np.array_equal(load_cmp(cmp_dir)[1].labels(), load_cmp(cmp_dir)[0].labels())


def test_cmp_errors(tmp_path: Path, cmp_dir: Path):
    with pytest.raises(InputError, match="does not exist"):
        load_cmp(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no .jpg photos"):
        load_cmp(tmp_path / "empty")
    with pytest.raises(InputError, match="unknown label set"):
        load_cmp(cmp_dir, label_set="cmp5")
    bad_xml = cmp_dir / "cmp_b0002.xml"
    bad_xml.write_text("<object><points><x>0.1</x></points></object>")
    with pytest.raises(InputError, match="bad <points>"):
        load_cmp(cmp_dir)[1].objects()
    bad_xml.write_text("<object><points>")
    with pytest.raises(InputError, match="not valid XML"):
        load_cmp(cmp_dir)[1].objects()
    Image.fromarray(np.ones((5, 5), np.uint8)).save(cmp_dir / "cmp_b0002.png")
    with pytest.raises(InputError, match=r"5x5 px .* 20x10"):
        load_cmp(cmp_dir)[1].labels()
    (cmp_dir / "cmp_b0002.jpg").write_bytes(b"not a jpeg at all")
    with pytest.raises(InputError, match="cannot be read"):
        load_cmp(cmp_dir)[1].image()
    (cmp_dir / "cmp_b0002.png").unlink()
    with pytest.raises(InputError, match="has no label cmp_b0002.png"):
        load_cmp(cmp_dir)


# ------------------------------------------------------------------------------- RueMonge
def test_load_ruemonge(ruemonge_dir: Path):
    samples = load_ruemonge(ruemonge_dir)
    assert [s.id for s in samples] == ["IMG_1", "IMG_2"]
    s = samples[0]
    assert s.meta["split"] == "train" and s.label_set is LABEL_SETS["ecp7"]
    labels = s.labels()
    assert labels.shape == (100, 200) and s.image().shape == (100, 200, 3)
    assert labels[95, 0] == IGNORE and labels[0, 0] == 5 and labels[12, 0] == 4
    assert labels[30, 30] == 0 and labels[50, 0] == 1
    windows = [b for b in s.objects() if b.label == "window"]
    assert windows == [ObjectBox("window", 20, 20, 50, 40), ObjectBox("window", 60, 20, 90, 40)]
    assert {b.label for b in s.objects()} == {"window", "wall", "roof", "sky"}
    assert [s.id for s in load_ruemonge(ruemonge_dir, split="val")] == ["IMG_9"]


def test_ruemonge_split_folder_and_other_sets(ruemonge_dir: Path):
    direct = load_ruemonge(ruemonge_dir / "train", split="train", label_set="cmp6")
    assert len(direct) == 2
    labels = direct[0].labels()
    assert labels[0, 0] == 0 and labels[12, 0] == 0      # sky, roof → background
    assert labels[30, 30] == 2 and labels[95, 0] == IGNORE


def test_ruemonge_label_color_fallback(ruemonge_dir: Path):
    base = ruemonge_dir / "val"
    ecp7 = LABEL_SETS["ecp7"]
    expected = load_ruemonge(ruemonge_dir, "val")[0].labels()
    (base / "label" / "IMG_9.png").unlink()
    (base / "label_color").mkdir()
    Image.fromarray(ecp7.to_color(expected)).save(base / "label_color" / "IMG_9.png")
    assert np.array_equal(load_ruemonge(ruemonge_dir, "val")[0].labels(), expected)


def test_ruemonge_errors(tmp_path: Path, ruemonge_dir: Path):
    with pytest.raises(InputError, match="does not exist"):
        load_ruemonge(tmp_path / "nope")
    with pytest.raises(InputError, match="splits found: train, val"):
        load_ruemonge(ruemonge_dir, split="test")
    (ruemonge_dir / "train" / "label" / "IMG_2.png").unlink()
    with pytest.raises(InputError, match="IMG_2.jpg has no label"):
        load_ruemonge(ruemonge_dir)
    for p in (ruemonge_dir / "val" / "img").iterdir():
        p.unlink()
    with pytest.raises(InputError, match="no photos"):
        load_ruemonge(ruemonge_dir, "val")


# ------------------------------------------------------------------------------- folder
def _palette(root: Path, **spec) -> None:
    (root / "palette.json").write_text(json.dumps(spec))


def test_load_folder_ids_palette(tmp_path: Path):
    _palette(tmp_path, name="mine", classes=["background", "facade", "window"],
             ids=[0, [1, 5], 2], ignore=9)
    ids = np.array([[0, 1, 5], [2, 9, 7]], np.uint8)
    _photo(tmp_path / "a.jpg", 2, 3)
    Image.fromarray(ids).save(tmp_path / "a.png")                 # a.jpg + a.png
    Image.fromarray(np.zeros((2, 3, 3), np.uint8)).save(tmp_path / "b.png")
    Image.fromarray(ids).save(tmp_path / "b_label.png")           # b.png + b_label.png
    samples = load_folder(tmp_path)
    assert [s.id for s in samples] == ["a", "b"]
    assert samples[0].label_set.name == "mine"
    assert samples[0].label_set.classes == ("background", "wall", "window")
    assert samples[0].labels().tolist() == [[0, 1, 1], [2, IGNORE, IGNORE]]
    assert samples[1].labels().tolist() == [[0, 1, 1], [2, IGNORE, IGNORE]]
    ecp = load_folder(tmp_path, label_set="ecp7")[0].labels()
    assert ecp.tolist() == [[5, 1, 1], [0, IGNORE, IGNORE]]       # background → sky
    assert load_dataset("folder", tmp_path)[1].id == "b"


def test_load_folder_color_palette(tmp_path: Path):
    _palette(tmp_path, classes=["wall", "window", "door"],
             colors=[[200, 200, 200], [0, 0, 255], [255, 0, 0]], ignore=[0, 0, 0])
    rgb = np.array([[[200, 200, 200], [0, 0, 255]], [[255, 0, 0], [0, 0, 0]]], np.uint8)
    _photo(tmp_path / "x.jpg", 2, 2)
    Image.fromarray(rgb).save(tmp_path / "x.png")
    s = load_folder(tmp_path)[0]
    assert s.labels().tolist() == [[0, 1], [2, IGNORE]]
    # a palette PNG of the same colours is decoded by colour, not index, when only colours given
    quant = Image.fromarray(rgb).quantize(colors=4)
    quant.save(tmp_path / "x.png")
    assert load_folder(tmp_path)[0].labels().tolist() == [[0, 1], [2, IGNORE]]
    big = np.zeros((40, 40, 3), np.uint8)
    big[:] = (200, 200, 200)
    big[5:15, 5:15] = (0, 0, 255)
    _photo(tmp_path / "x.jpg", 40, 40)
    Image.fromarray(big).save(tmp_path / "x.png")
    assert [b for b in load_folder(tmp_path)[0].objects() if b.label == "window"] == [
        ObjectBox("window", 5, 5, 15, 15)]


def test_load_folder_with_label_set_and_no_palette(tmp_path: Path):
    _photo(tmp_path / "f.jpg", 2, 2)
    Image.fromarray(np.array([[0, 1], [5, 6]], np.uint8)).save(tmp_path / "f_label.png")
    with pytest.raises(InputError, match="no palette.json"):
        load_folder(tmp_path)
    assert load_folder(tmp_path, label_set="ecp7")[0].labels().tolist() == [[IGNORE, 0], [4, 5]]


def test_folder_errors(tmp_path: Path):
    with pytest.raises(InputError, match="does not exist"):
        load_folder(tmp_path / "missing", label_set="cmp6")
    _palette(tmp_path, classes=["wall", "window"])
    with pytest.raises(InputError, match="no photos"):
        load_folder(tmp_path)
    _photo(tmp_path / "lonely.jpg", 2, 2)
    with pytest.raises(InputError, match=r"lonely_label\.png, lonely\.png"):
        load_folder(tmp_path)
    for spec, message in [
        ({"classes": []}, "non-empty"),
        ({"classes": ["wall", "nonsense"]}, "not a canonical label"),
        ({"classes": ["wall", "window"], "ids": [0]}, "one id"),
        ({"classes": ["wall", "window"], "ids": [0, 0]}, "two classes"),
        ({"classes": ["wall"], "colors": [[0, 0]]}, "colors"),
        ({"classes": ["wall"], "ignore": "x"}, "ignore"),
    ]:
        _palette(tmp_path, **spec)
        with pytest.raises(InputError, match=message):
            load_palette(tmp_path / "palette.json")
    (tmp_path / "palette.json").write_text("{oops")
    with pytest.raises(InputError, match="not valid JSON"):
        load_folder(tmp_path)


# ------------------------------------------------------------------------------- images
@pytest.mark.parametrize("mode", ["L", "RGBA", "P", "I;16", "1", "CMYK"])
def test_read_image_converts_to_rgb(tmp_path: Path, mode: str):
    grey = np.array([[0, 100], [200, 255]], np.uint8)
    if mode == "I;16":
        im = Image.fromarray(grey.astype(np.uint16) * 257)
        assert im.mode.startswith("I;16")
    elif mode == "1":
        im = Image.fromarray(grey > 127)
    else:
        im = Image.fromarray(grey).convert(mode)
    path = tmp_path / f"im.{'tif' if mode == 'CMYK' else 'png'}"
    im.save(path)
    rgb = read_image(path)
    assert rgb.shape == (2, 2, 3) and rgb.dtype == np.uint8
    if mode in ("L", "RGBA", "P", "I;16"):
        assert np.array_equal(rgb[..., 0], grey) and np.array_equal(rgb[..., 2], grey)


def test_read_image_errors(tmp_path: Path):
    with pytest.raises(InputError, match="does not exist"):
        read_image(tmp_path / "none.png")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(InputError, match="cannot be read"):
        read_image(tmp_path / "bad.png")
    ok = tmp_path / "trunc.jpg"
    _photo(ok, 64, 64)
    ok.write_bytes(ok.read_bytes()[:200])
    with pytest.raises(InputError, match="cannot be read"):
        read_image(ok)


def test_objects_from_labels_min_size_and_ignore():
    m = np.full((100, 100), IGNORE, np.uint8)
    m[10:20, 10:30] = 2
    m[50, 50] = 2                       # 1 px of 10000 = 0.01 %: kept (not smaller)
    m[60:70, 0:5] = 0
    boxes = objects_from_labels(m, LABEL_SETS["cmp6"])
    assert boxes == [ObjectBox("background", 0, 60, 5, 70), ObjectBox("window", 10, 10, 30, 20),
                     ObjectBox("window", 50, 50, 51, 51)]
    assert objects_from_labels(m, LABEL_SETS["cmp6"], min_fraction=2e-4,
                               classes=("window",)) == [ObjectBox("window", 10, 10, 30, 20)]


def test_loader_registry():
    assert set(LOADERS) == {"cmp", "ruemonge", "labelmefacade", "folder", "synthetic"}
    with pytest.raises(InputError, match="unknown dataset layout"):
        load_dataset("nope", ".")


# ------------------------------------------------------------------------------- real data
def _need(path: Path) -> Path:
    if not path.is_dir():
        pytest.skip(f"shared dataset {path} is absent (expected ../shared/data beside the project)")
    return path


def test_real_cmp():
    samples = load_cmp(_need(DATA / "cmp"))
    assert len(samples) == 300
    for s in (samples[0], samples[-1]):
        img, labels = s.image(), s.labels()
        assert img.shape[:2] == labels.shape and img.shape[2] == 3
        assert labels.max() < 6
        boxes = s.objects()
        assert any(b.label == "window" for b in boxes)
        h, w = labels.shape
        assert all(0 <= b.x0 <= b.x1 <= w and 0 <= b.y0 <= b.y1 <= h for b in boxes)
    labels12 = load_cmp(DATA / "cmp", "cmp12")[0].labels()
    assert labels12.max() < 12


def test_real_ruemonge():
    samples = load_ruemonge(_need(DATA / "ruemonge"), split="train")
    assert len(samples) == 113
    s = samples[0]
    labels = s.labels()
    assert s.image().shape == (*labels.shape, 3)
    valid = labels[labels != IGNORE]
    assert valid.size and valid.max() < 7 and (labels == IGNORE).any()
    assert any(b.label == "window" for b in s.objects())


def test_palette_hostile_json(tmp_path: Path):
    # read through facadeforge.jsonfile: a BOM is fine, nesting and ragged colours are not
    palette = tmp_path / "palette.json"
    palette.write_text(json.dumps({"classes": ["wall", "window"]}), encoding="utf-8-sig")
    assert load_palette(palette).classes == ("wall", "window")
    palette.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match="palette '.*palette.json': JSON nested too deeply"):
        load_palette(palette)
    _palette(tmp_path, classes=["wall", "window"], colors=[[1, 2, 3], [4]])
    with pytest.raises(InputError, match="colors"):
        load_palette(palette)
