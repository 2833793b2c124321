"""One facade at a time (issue 24 item 4): :func:`facadeforge.imaging.facades.find_facades` on
synthetic corners, houses side by side, plain facades and textureless images, on RueMonge
photos, and the OUTDIR of ``facadeforge reconstruct`` for photos of one and of several
facades."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from facadeforge import InputError
from facadeforge.cli import main
from facadeforge.imaging.facades import FacadeSplit, draw_facades, find_facades
from facadeforge.reconstruction import reconstruct_facades

RUEMONGE = Path(__file__).resolve().parents[3] / "shared" / "data" / "ruemonge" / "train" / "img"
OUT_FILES = ("rectified.png", "structure.png", "labels.png", "labels_input.png",
             "shape_tree.json", "rules.cga", "model.glb", "model.obj", "model.city.json",
             "report.json")
SKY = (90, 150, 230)


# ------------------------------------------------------------------------------- scenes
def _front(w: int, h: int, wall, floor_h: int, top: int, cols: int, rng, offset: int = 0):
    """A house front, ``w`` × ``h``: sky above row ``top``, a wall with ``cols`` window
    columns, floors ``floor_h`` apart (the first ``offset`` lower), a cornice line and a sill
    per floor, a little noise."""
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = SKY
    img[top:] = wall
    col_w = w / cols
    y = top + 12 + offset
    while y + floor_h * 0.75 < h - 10:
        cv2.line(img, (0, int(y - 6)), (w - 1, int(y - 6)), tuple(int(c * 0.7) for c in wall), 2)
        for j in range(cols):
            x0, x1 = int(j * col_w + col_w * 0.28), int(j * col_w + col_w * 0.72)
            y1 = int(y + floor_h * 0.55)
            cv2.rectangle(img, (x0, int(y)), (x1, y1), (40, 45, 60), -1)
            cv2.rectangle(img, (x0 - 2, y1), (x1 + 2, y1 + 3), (235, 235, 225), -1)
        y += floor_h
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


def _warp_into(canvas: np.ndarray, tex: np.ndarray, quad) -> None:
    h, w = tex.shape[:2]
    H = cv2.getPerspectiveTransform(np.float32([[0, 0], [w, 0], [w, h], [0, h]]),
                                    np.float32(quad))
    size = canvas.shape[1::-1]
    warped = cv2.warpPerspective(tex, H, size)
    inside = cv2.warpPerspective(np.full((h, w), 255, np.uint8), H, size) > 128
    canvas[inside] = warped[inside]


def corner_scene(seed: int = 0) -> tuple[np.ndarray, int]:
    """Two facade planes of a box seen at its corner (two window grids warped by two
    homographies sharing the vertical edge at column ``xc``), sky and street; and ``xc``."""
    rng = np.random.default_rng(seed)
    img = np.zeros((600, 800, 3), np.uint8)
    img[:] = SKY
    img[520:] = (70, 70, 70)
    xc = 430
    _warp_into(img, _front(600, 500, (200, 180, 150), 80, 0, 6, rng),
               [[20, 150], [xc, 40], [xc, 560], [20, 470]])
    _warp_into(img, _front(600, 500, (195, 175, 150), 80, 0, 6, rng),
               [[xc, 40], [780, 140], [780, 480], [xc, 560]])
    return img, xc


def two_houses_scene(seed: int = 0) -> tuple[np.ndarray, int]:
    """Two houses side by side in one plane: different walls, floor heights and floor lines
    offset, the right one's roof line lower; and the column where they meet."""
    rng = np.random.default_rng(seed)
    xb = 360
    left = _front(xb, 600, (205, 185, 140), 78, 70, 4, rng)
    right = _front(800 - xb, 600, (160, 160, 165), 92, 130, 5, rng, offset=30)
    return np.concatenate([left, right], axis=1), xb


def plain_scene(seed: int = 0) -> np.ndarray:
    return _front(800, 600, (200, 185, 160), 85, 60, 8, np.random.default_rng(seed))


def _vertical_edge_u(region) -> tuple[float, float]:
    """Columns of a region's left and right edges at its middle."""
    p = region.polygon
    return float((p[0, 0] + p[3, 0]) / 2), float((p[1, 0] + p[2, 0]) / 2)


# ------------------------------------------------------------------------------- find_facades
def test_a_corner_gives_two_planes_split_at_the_corner():
    img, xc = corner_scene()
    split = find_facades(img)
    assert isinstance(split, FacadeSplit)
    assert len(split.planes) == 2
    assert [r.id for r in split.regions] == [1, 2]
    left, right = split.regions
    assert (left.plane, right.plane) == (0, 1)
    assert left.ok and right.ok, (left.flags, right.flags)
    assert abs(_vertical_edge_u(left)[1] - xc) < 12
    assert abs(_vertical_edge_u(right)[0] - xc) < 12
    # each is rectified by its own horizontal vanishing point: its floor lines come out level
    for r in split.regions:
        rect = r.rectified(img)
        assert rect.shape == (*r.size, 3)
        q = r.quality
        assert q["horizontal_inliers"] >= 20 and q["vertical_inliers"] >= 10
        assert q["line_share"] > 0.6 and q["residual_deg"] < 1.0
        assert 0 < q["viewing_angle_deg"] < 90 and q["stretch"] >= 1.0
        # the polygon is the crop's outline: the homography maps it onto the crop's corners
        p = np.c_[r.polygon, np.ones(4)] @ r.homography.T
        h, w = r.size
        assert np.allclose(p[:, :2] / p[:, 2:], [[0, 0], [w, 0], [w, h], [0, h]], atol=1e-6)


def test_the_corner_edge_follows_converging_verticals():
    """Looking up, the verticals converge: the planes' boundary is the line through the
    vertical vanishing point along the corner, not an image column."""
    img, xc = corner_scene(1)
    h, w = img.shape[:2]
    cx = 200.0                           # the camera's axis left of the corner
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -0.0007, 1.0]])
    tilt = np.array([[1, 0, cx], [0, 1, h], [0, 0, 1]]) @ tilt @ np.array(
        [[1, 0, -cx], [0, 1, -h], [0, 0, 1.0]])
    tilted = cv2.warpPerspective(img, tilt, (w, h), borderValue=SKY)
    split = find_facades(tilted)
    assert len(split.planes) == 2 and len(split.regions) == 2
    edge = np.c_[[[xc, 80], [xc, 520]], np.ones(2)] @ tilt.T
    edge = edge[:, :2] / edge[:, 2:]
    assert abs(edge[0, 0] - edge[1, 0]) > 30          # the corner edge is slanted
    a, b = split.regions[0].polygon[1], split.regions[0].polygon[2]    # right edge of 1
    normal = np.array([b[1] - a[1], a[0] - b[0]]) / np.hypot(*(b - a))
    assert np.all(np.abs((edge - a) @ normal) < 12)


def test_two_houses_side_by_side_give_two_regions_at_their_boundary():
    img, xb = two_houses_scene()
    split = find_facades(img)
    assert len(split.planes) == 1
    assert len(split.regions) == 2 and all(r.ok for r in split.regions)
    assert abs(_vertical_edge_u(split.regions[0])[1] - xb) < 16
    assert abs(_vertical_edge_u(split.regions[1])[0] - xb) < 16
    assert split.planes[0]["houses"] and split.planes[0]["boundary_cues"][0]["roof"] > 0.5


def test_a_plain_facade_is_one_region():
    split = find_facades(plain_scene())
    assert len(split.regions) == 1 and split.regions[0].ok
    assert split.planes[0]["houses"] == []


@pytest.mark.parametrize("kind", ["flat", "noise"])
def test_a_textureless_image_is_flagged_not_ok(kind):
    rng = np.random.default_rng(0)
    img = np.full((480, 640, 3), 128, np.uint8)
    if kind == "noise":
        img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    split = find_facades(img)
    assert len(split.regions) == 1
    r = split.regions[0]
    assert not r.ok and any(f.startswith("few lines") for f in r.flags)
    assert r.polygon.shape == (4, 2)


def test_no_boundary_inside_a_single_house_with_a_shadow():
    """A cast shadow across the lower floors (a horizontal shadow edge) changes neither the
    floor lines nor the colour row by row: no boundary."""
    img = plain_scene(3).astype(np.float32)
    img[330:] *= 0.45
    img[200:330, 500:] *= 0.45                    # a step in the shadow's edge
    split = find_facades(img.astype(np.uint8))
    assert len(split.regions) == 1


def test_drawing_and_report_of_a_split():
    img, _ = corner_scene()
    split = find_facades(img)
    pic = draw_facades(img, split)
    assert pic.shape == img.shape and pic.dtype == np.uint8
    assert np.abs(pic.astype(int) - img).sum() > 0
    d = split.to_dict()
    json.dumps(d)                                   # plain JSON types
    assert [f["id"] for f in d["facades"]] == [1, 2]
    assert {"polygon", "ok", "flags", "quality", "homography", "rectified_size"} <= set(
        d["facades"][0])
    assert d["focal"]["source"]


def test_gray_and_float_images_and_a_seed():
    img, _ = corner_scene()
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    a = find_facades(gray, rng=3)
    b = find_facades(img.astype(np.float32) / 255.0, rng=3)
    assert len(a.regions) == len(b.regions) == 2


# ------------------------------------------------------------------------------- RueMonge
#: Photos looked at (facades.png of each): IMG_5901 is a corner (the left face and, across
#: the corner, the right face; the far street beside it is flagged), IMG_5802 two houses side
#: by side (a white one and a darker, taller-floored one), IMG_5807 one house filling the
#: photo.  (row: photo, facades found, usable facades, the boundary's share of the width)
_PHOTOS = [("IMG_5901.jpg", (3, 5), 2, 0.43), ("IMG_5802.jpg", (2, 2), 2, 0.38),
           ("IMG_5807.jpg", (1, 1), 1, None)]


@pytest.mark.skipif(not RUEMONGE.is_dir(), reason=f"RueMonge photos not found at {RUEMONGE} "
                    "(shared data: see /work/shared/data/README.md)")
@pytest.mark.parametrize("name, found, usable, boundary", _PHOTOS)
def test_ruemonge_photos(name, found, usable, boundary):
    img = np.asarray(Image.open(RUEMONGE / name).convert("RGB"))
    split = find_facades(img)
    assert found[0] <= len(split.regions) <= found[1], [r.flags for r in split.regions]
    assert len(split.usable) == usable, [r.flags for r in split.regions]
    if boundary is not None:
        first = split.usable[0]
        x = _vertical_edge_u(first)[1] / img.shape[1]
        assert abs(x - boundary) < 0.05, x
    assert split.seconds < 5.0


# ------------------------------------------------------------------------------- OUTDIR
@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    d = tmp_path_factory.mktemp("facade_photos")
    paths = {}
    for name, img in (("corner", corner_scene()[0]), ("plain", plain_scene())):
        paths[name] = d / f"{name}.png"
        Image.fromarray(img).save(paths[name])
    return paths


def test_cli_writes_a_folder_per_facade(photos, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["reconstruct", str(photos["corner"]), "--no-classifier", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 facades found, 2 modelled" in text and "facade_01:" in text
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "facade_01", "facade_02", "facades.png", "labels_input.png", "report.json"]
    for folder in ("facade_01", "facade_02"):
        for name in OUT_FILES:
            assert (out / folder / name).is_file(), (folder, name)
        assert (out / folder).stat().st_mode & 0o055 == 0o055     # not a scratch folder's 0700
        sub = json.loads((out / folder / "report.json").read_text())
        assert sub["region"]["id"] == int(folder[-2:])
        assert sub["rectification"]["applied"] and sub["floors"] >= 2
    report = json.loads((out / "report.json").read_text())
    assert [f["id"] for f in report["facades"]] == [1, 2]
    for f, folder in zip(report["facades"], ("facade_01", "facade_02")):
        assert f["folder"] == folder and f["ok"] and f["plane"] in (0, 1)
        assert len(f["polygon"]) == 4 and f["summary"]["floors"] >= 2
        assert {"line_share", "stretch", "viewing_angle_deg"} <= set(f["quality"])
    assert {"load", "facades", "facade_01", "facade_02", "export", "total"} <= set(
        report["timings"])
    photo = np.asarray(Image.open(photos["corner"]))
    labels = np.asarray(Image.open(out / "labels_input.png"))
    assert labels.shape == photo.shape[:2]
    left, right = labels[:, :400], labels[:, 460:]        # both facades are labelled
    assert (left > 0).mean() > 0.3 and (right > 0).mean() > 0.3
    assert Image.open(out / "facades.png").size == (photo.shape[1], photo.shape[0])
    # a second run replaces the folder whole (one staging folder for all of it)
    assert main(["reconstruct", str(photos["corner"]), "--no-classifier", "--facades", "one",
                 "-o", str(out)]) == 0
    assert not (out / "facade_01").exists() and (out / "rectified.png").is_file()
    assert not [p for p in tmp_path.iterdir() if ".staging" in p.name]


def test_cli_keeps_the_one_facade_layout(photos, tmp_path, capsys):
    out = tmp_path / "one"
    assert main(["reconstruct", str(photos["plain"]), "--no-classifier", "-o", str(out)]) == 0
    assert "facades found" not in capsys.readouterr().out
    for name in OUT_FILES:
        assert (out / name).is_file(), name
    assert not list(out.glob("facade_*")) and not (out / "facades.png").exists()
    report = json.loads((out / "report.json").read_text())
    assert [f["folder"] for f in report["facades"]] == ["."]
    assert report["rectification"]["applied"]


def test_facades_one_and_rectified_photos_are_not_split(photos):
    one = reconstruct_facades(photos["corner"], facades="one", model=False, classifier=False)
    assert one.single is not None and one.split is None
    assert "facades" not in one.single.report
    rect = reconstruct_facades(photos["corner"], rectified=True, model=False,
                               classifier=False)
    assert rect.single is not None and rect.split is None
    assert not rect.single.report["rectification"]["applied"]


def test_sizes_given_for_a_photo_of_several_facades_are_not_applied(photos):
    res = reconstruct_facades(photos["corner"], width_m=20.0, model=False, classifier=False)
    assert res.single is None and len(res.facades) == 2
    assert any("--width-m" in n for n in res.report["notes"])
    assert all(r.report["facade"]["scale_source"] != "given" for r in res.facades)


def test_a_bad_facades_mode_is_an_error(photos):
    with pytest.raises(InputError, match="--facades"):
        reconstruct_facades(photos["plain"], facades="many")
