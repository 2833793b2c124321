"""Camera file formats: VisualSFM (cameras_v2.txt, NVM), Bundler bundle.out, COLMAP text models.

The reprojection tests write each format by hand in its own convention (Bundler user manual,
"Output format": camera looking down −z, y up, image origin at the centre with y up; COLMAP
"Output format": world → camera quaternion ``QW QX QY QZ`` and ``t``, x right, y down) and check
that :meth:`Camera.project` gives the pixels computed from that convention directly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation

from facadeforge.datasets import cameras as cameras_module
from facadeforge.datasets.cameras import (
    Camera,
    read_cameras,
    read_visualsfm,
    write_bundler,
    write_colmap,
    write_visualsfm,
)
from facadeforge.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
RUEMONGE = DATA / "ruemonge" / "train"

W, H = 640, 480


def _num(*values: float) -> str:
    return " ".join(repr(float(v)) for v in values)


def _wxyz(R: np.ndarray) -> np.ndarray:
    """scipy's quaternion (scalar last) in COLMAP's and VisualSFM's order (scalar first)."""
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def _look_at(C: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """right, up and forward world axes of a camera at ``C`` looking at ``target`` (z up)."""
    forward = (target - C) / np.linalg.norm(target - C)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


def _scene(seed: int = 0):
    """40 points of a facade-sized box and 4 cameras across the street looking at it."""
    rng = np.random.default_rng(seed)
    X = rng.uniform([-3.0, -1.0, -1.0], [3.0, 1.0, 3.0], (40, 3))
    views = []
    for x in (-3.0, -1.0, 1.0, 3.0):
        C = np.array([x, -8.0, 1.5]) + rng.normal(0, 0.2, 3)
        views.append((C, *_look_at(C, np.array([x / 2, 0.0, 1.0]) + rng.normal(0, 0.3, 3))))
    return X, views


def _random_cameras(n: int, seed: int, *, centred: bool, square: bool) -> list[Camera]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        size = (int(rng.integers(300, 2000)), int(rng.integers(300, 2000)))
        principal = (size[0] / 2, size[1] / 2) if centred else \
            tuple(float(v) for v in rng.uniform(100, 300, 2))
        f = float(rng.uniform(300, 3000))
        out.append(Camera(
            f"IMG_{1000 + k}", f"{k:08d}.jpg", f, principal,
            Rotation.random(random_state=int(rng.integers(1 << 30))).as_matrix(),
            rng.normal(0, 10, 3), float(rng.normal(0, 0.1)),
            0.0 if square else float(rng.normal(0, 0.01)),
            focal_y=None if square else f * float(rng.uniform(0.9, 1.1)),
            image_size=size if centred else None))
    return out


def _in_front(cam: Camera, rng: np.random.Generator, n: int = 20) -> np.ndarray:
    local = np.c_[rng.uniform(-1, 1, (n, 2)), rng.uniform(1, 5, n)]
    return cam.C + local @ cam.R


def _same(a: Camera, b: Camera, rng: np.random.Generator) -> None:
    assert np.allclose(a.K, b.K, atol=1e-6)
    assert np.allclose(a.R, b.R, atol=1e-6) and np.allclose(a.C, b.C, atol=1e-6)
    X = _in_front(a, rng)
    assert np.allclose(a.project(X), b.project(X), atol=1e-6)


# ---------------------------------------------------------------------------- round trips
def test_round_trip_visualsfm(tmp_path: Path):
    cams = _random_cameras(5, 1, centred=False, square=True)
    back = read_cameras(write_visualsfm(cams, tmp_path / "cameras_v2.txt"))
    assert list(back) == [c.id for c in cams]
    rng = np.random.default_rng(0)
    for c in cams:
        _same(c, back[c.id], rng)
        assert back[c.id].radial == pytest.approx(c.radial) and back[c.id].file == c.file
    assert read_cameras(tmp_path).keys() == back.keys()        # the folder holding it


def test_round_trip_bundler(tmp_path: Path):
    cams = _random_cameras(5, 2, centred=True, square=True)
    out = write_bundler(cams, tmp_path / "bundle.out")
    assert (tmp_path / "list.txt").read_text().split() == [f"{c.id}.jpg" for c in cams]
    back = read_cameras(out, image_size={c.id: c.size for c in cams})
    rng = np.random.default_rng(0)
    for c in cams:
        _same(c, back[c.id], rng)
        assert back[c.id].size == c.size
        assert (back[c.id].radial, back[c.id].radial2) == pytest.approx((c.radial, c.radial2))


def test_round_trip_colmap(tmp_path: Path):
    cams = (_random_cameras(4, 3, centred=False, square=False)
            + _random_cameras(2, 4, centred=True, square=True)[:1])
    cams[-1] = Camera("plain", "plain.png", 800.0, (320.0, 240.0), np.eye(3), np.zeros(3))
    folder = write_colmap(cams, tmp_path / "sparse" / "0")
    models = [line.split()[1] for line in (folder / "cameras.txt").read_text().splitlines()
              if not line.startswith("#")]
    assert models == ["OPENCV"] * 4 + ["SIMPLE_PINHOLE"]
    rng = np.random.default_rng(0)
    for path in (folder, folder / "images.txt", folder / "cameras.txt", folder / "points3D.txt"):
        back = read_cameras(path)
        assert list(back) == [c.id for c in cams]
        for c in cams:
            _same(c, back[c.id], rng)
            assert back[c.id].size == c.size
    assert back["plain"].focal_y is None and back["plain"].file == "plain.png"


def test_writers_refuse_what_the_format_cannot_hold(tmp_path: Path):
    skew = _random_cameras(1, 5, centred=False, square=False)
    with pytest.raises(InputError, match="fx ≠ fy"):
        write_visualsfm(skew, tmp_path / "c.txt")
    off = _random_cameras(1, 5, centred=False, square=True)
    with pytest.raises(InputError, match="not the centre"):
        write_bundler(off, tmp_path / "bundle.out")
    twice = _random_cameras(1, 5, centred=True, square=True) * 2
    with pytest.raises(InputError, match="duplicate ids"):
        write_colmap(twice, tmp_path / "m")


def test_ray_inverts_project():
    cam = _random_cameras(1, 6, centred=False, square=False)[0]
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 400, (10, 2))
    rays = cam.ray(xy)
    assert np.allclose(np.linalg.norm(rays, axis=1), 1.0)
    for t in (0.5, 3.0, 40.0):
        assert np.allclose(cam.project(cam.C + t * rays), xy, atol=1e-6)
    assert np.all(cam.depth(cam.C + rays) > 0)
    # a photo stored turned a quarter (module docstring): pixels of the photo as stored
    turned = Camera("t", "t.jpg", 1000.0, (533.5, 400.0), cam.R, cam.C)
    shape = (1067, 800)
    assert turned.turned(shape)
    xy = rng.uniform(0, 800, (10, 2))
    assert np.allclose(turned.project(turned.C + 2 * turned.ray(xy, shape), shape), xy,
                       atol=1e-6)


# ------------------------------------------------- reprojection, each format's convention
def test_bundler_reprojection_in_bundlers_convention(tmp_path: Path):
    X, views = _scene()
    f, lines, pixels, names = 500.0, ["# Bundle file v0.3", f"{len(views) + 1} 0"], [], []
    for k, (C, right, up, forward) in enumerate(views):
        Rb = np.array([right, up, -forward])        # Bundler: looking down −z, y up
        t = -Rb @ C
        P = X @ Rb.T + t                            # manual: P = R X + t, p = −P / P.z
        p = -P[:, :2] / P[:, 2:]
        pixels.append(np.c_[W / 2 + f * p[:, 0], H / 2 - f * p[:, 1]])   # centred, y up
        lines += [_num(f, 0, 0), *(_num(*r) for r in Rb), _num(*t)]
        names.append(f"images/view{k}.jpg")
        if k == 1:                                  # an unregistered photo in the middle
            lines += ["0 0 0", "0 0 0", "0 0 0", "0 0 0", "0 0 0"]
            names.append("images/lost.jpg")
    (tmp_path / "bundle").mkdir()
    (tmp_path / "bundle" / "bundle.out").write_text("\n".join(lines) + "\n")
    (tmp_path / "list.txt").write_text("".join(f"{n} 0 {f}\n" for n in names))   # Bundler's
    cams = read_cameras(tmp_path / "bundle" / "bundle.out", image_size=(W, H))
    assert list(cams) == [f"view{k}" for k in range(len(views))]
    for cam, uv in zip(cams.values(), pixels, strict=True):
        assert np.all(cam.depth(X) > 0)
        assert np.allclose(cam.project(X), uv, atol=1e-6)
        # skipping diag(1, −1, −1) would be caught
        Rb = np.diag([1.0, -1.0, -1.0]) @ cam.R
        wrong = Camera(cam.id, cam.file, cam.focal, cam.principal, Rb, cam.C)
        assert np.median(np.linalg.norm(wrong.project(X) - uv, axis=1)) > 10


def test_colmap_reprojection_in_colmaps_convention(tmp_path: Path):
    X, views = _scene(1)
    intr = [("SIMPLE_PINHOLE", (520.0, 320.0, 240.0)), ("PINHOLE", (510.0, 530.0, 300.0, 250.0)),
            ("SIMPLE_RADIAL", (500.0, 330.0, 230.0, 0.0)),
            ("OPENCV", (505.0, 495.0, 310.0, 245.0, 0, 0, 0, 0))]
    cam_lines = ["# Camera list with one line of data per camera:"]
    img_lines = ["# Image list with two lines of data per image:"]
    pixels = []
    for k, ((C, right, up, forward), (model, params)) in enumerate(zip(views, intr, strict=True)):
        R = np.array([right, -up, forward])         # COLMAP: x right, y down, looking down +z
        t = -R @ C
        cam_lines.append(f"{k + 7} {model} {W} {H} {_num(*params)}")
        points = "" if k % 2 else "12.5 40.25 -1 100.0 7.0 3"   # an empty points line too
        img_lines += [f"{k + 1} {_num(*_wxyz(R), *t)} {k + 7} sub/view{k}.png", points]
        fx, fy = (params[0], params[1]) if model in ("PINHOLE", "OPENCV") else params[:1] * 2
        cx, cy = params[2:4] if model in ("PINHOLE", "OPENCV") else params[1:3]
        x = X @ R.T + t
        pixels.append(np.c_[fx * x[:, 0] / x[:, 2] + cx, fy * x[:, 1] / x[:, 2] + cy])
    (tmp_path / "cameras.txt").write_text("\n".join(cam_lines) + "\n")
    (tmp_path / "images.txt").write_text("\n".join(img_lines) + "\n")
    cams = read_cameras(tmp_path / "images.txt")
    assert list(cams) == [f"view{k}" for k in range(len(views))]
    for cam, uv in zip(cams.values(), pixels, strict=True):
        assert cam.image_size == (W, H)
        assert np.allclose(cam.project(X), uv, atol=1e-6)
        # reading the rotation as camera → world, or t as the centre, would be caught
        for R, C in ((cam.R.T, cam.C), (cam.R, -(cam.R @ cam.C))):
            wrong = Camera(cam.id, cam.file, cam.focal, cam.principal, R, C,
                           focal_y=cam.focal_y)
            assert np.median(np.linalg.norm(wrong.project(X) - uv, axis=1)) > 10


def test_visualsfm_formats_reprojection(tmp_path: Path):
    X, views = _scene(2)
    f = 480.0
    nvm = ["NVM_V3", "", str(len(views))]
    v2 = ["# cameras_v2", str(len(views))]
    pixels = []
    for k, (C, right, up, forward) in enumerate(views):
        R = np.array([right, -up, forward])         # VisualSFM: as ours
        nvm.append(f"IMG_{k}.jpg {_num(f, *_wxyz(R), *C, 0.0)} 0")
        v2 += ["", f"{k:08d}.jpg", f"/orig/IMG_{k}.JPG", _num(f), _num(W / 2, H / 2),
               _num(*(-R @ C)), _num(*C), "0 0 0", _num(*_wxyz(R)), *(_num(*r) for r in R),
               "0 0"]
        d = (X - C)
        pixels.append(np.c_[W / 2 + f * (d @ right) / (d @ forward),
                            H / 2 - f * (d @ up) / (d @ forward)])
    (tmp_path / "model.nvm").write_text("\n".join(nvm + ["0", "", "0"]) + "\n")
    (tmp_path / "cameras_v2.txt").write_text("\n".join(v2) + "\n")
    for cams in (read_cameras(tmp_path / "model.nvm", image_size=(W, H)),
                 read_cameras(tmp_path / "cameras_v2.txt")):
        assert list(cams) == [f"IMG_{k}" for k in range(len(views))]
        for cam, uv in zip(cams.values(), pixels, strict=True):
            assert np.allclose(cam.project(X), uv, atol=1e-6)


def test_bundler_image_size_from_the_image(tmp_path: Path):
    (tmp_path / "images").mkdir()
    Image.new("RGB", (64, 48)).save(tmp_path / "images" / "a.png")
    (tmp_path / "bundle.out").write_text(
        "# Bundle file v0.3\n1 0\n100 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n")
    (tmp_path / "list.txt").write_text("images/a.png 0 100\n")
    cam = read_cameras(tmp_path / "bundle.out")["a"]
    assert cam.principal == (32.0, 24.0) and cam.size == (64, 48)
    (tmp_path / "images" / "a.png").unlink()
    with pytest.raises(InputError, match=r"image_size=\(width, height\)"):
        read_cameras(tmp_path / "bundle.out")
    (tmp_path / "list.txt").unlink()
    cam = read_cameras(tmp_path / "bundle.out", image_size=(10, 20))["camera_0000"]
    assert cam.principal == (5.0, 10.0)


# --------------------------------------------------------------------------------- errors
_BUNDLE = "# Bundle file v0.3\n2 0\n" + "100 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n" * 2
_COLMAP_CAMS = "# Camera list with one line of data per camera:\n1 PINHOLE 640 480 500 500 320 240\n"
_COLMAP_IMAGE = "{i} 1 0 0 0 0 0 {i} 1 {name}\n\n"


def _colmap(tmp_path: Path, images: str, cams: str = _COLMAP_CAMS) -> Path:
    (tmp_path / "cameras.txt").write_text(cams)
    (tmp_path / "images.txt").write_text(images)
    return tmp_path


@pytest.mark.parametrize("text, match", [
    ("", "is empty"),
    ("\n  \n", "is empty"),
    ("hello world\n", r"VisualSFM .*Bundler .*COLMAP"),
    ("ply\nformat ascii 1.0\n", "not a camera file"),
    ("# Bundle file v0.3\n2 0\n100 0 0\n1 0 0\n0 1 0\n", r"x:5: .*ends in camera 0.*truncated"),
    ("# Bundle file v0.3\n", "no camera count"),
    ("NVM_V3\n\n2\na.jpg 100 1 0 0 0 0 0 0 0 0\n", r"x:4: .*announces 2 cameras.*truncated"),
    ("# c\n3\n", r"x:2: .*ends after 0"),
    ("# Bundle file v0.3\n1 0\n100 0 0\n2 0 0\n0 1 0\n0 0 1\n0 0 0\n", "orthonormal"),
    ("# Bundle file v0.3\n1 0\n100 0 0\n1 0 0\n0 1 0\n0 0 -1\n0 0 0\n", "reflection"),
])
def test_bad_files(tmp_path: Path, text: str, match: str):
    f = tmp_path / "x"
    f.write_text(text)
    with pytest.raises(InputError, match=match):
        read_cameras(f, image_size=(10, 10))


def test_bad_colmap_models(tmp_path: Path):
    two = _COLMAP_IMAGE.format(i=1, name="a.jpg") + _COLMAP_IMAGE.format(i=2, name="b.jpg")
    assert list(read_cameras(_colmap(tmp_path, two))) == ["a", "b"]
    with pytest.raises(InputError, match="'FULL_OPENCV' is not read; supported: SIMPLE_PINHOLE"):
        read_cameras(_colmap(tmp_path, two, "1 FULL_OPENCV 640 480 " + "1 " * 12 + "\n"))
    with pytest.raises(InputError, match="4 parameters"):
        read_cameras(_colmap(tmp_path, two, "1 PINHOLE 640 480 500 500 320\n"))
    with pytest.raises(InputError, match=r"images.txt:3: .*truncated or malformed"):
        read_cameras(_colmap(tmp_path, two[:-12]))
    counted = "# Number of images: 3, mean observations per image: 0\n" + two
    with pytest.raises(InputError, match="announces 3 images but the file holds 2"):
        read_cameras(_colmap(tmp_path, counted))
    # one line per image (the empty points lines dropped) is refused, not misread
    with pytest.raises(InputError, match=r"images.txt:2: .*two lines per image"):
        read_cameras(_colmap(tmp_path, two.replace("\n\n", "\n")))
    twice = _COLMAP_IMAGE.format(i=1, name="x/a.jpg") + _COLMAP_IMAGE.format(i=2, name="y/a.jpg")
    with pytest.raises(InputError, match="'a' occurs twice"):
        read_cameras(_colmap(tmp_path, twice))
    with pytest.raises(InputError, match="unit quaternion"):
        read_cameras(_colmap(tmp_path, "1 2 0 0 0 0 0 0 1 a.jpg\n\n"))
    with pytest.raises(InputError, match="refers to camera 5"):
        read_cameras(_colmap(tmp_path, "1 1 0 0 0 0 0 0 5 a.jpg\n\n"))
    (tmp_path / "images.txt").unlink()
    with pytest.raises(InputError, match="images.txt not found"):
        read_cameras(tmp_path / "cameras.txt")


def test_duplicates_and_limits(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    f = tmp_path / "bundle.out"
    f.write_text(_BUNDLE)
    (tmp_path / "list.txt").write_text("one/a.jpg\ntwo/a.jpg\n")
    with pytest.raises(InputError, match="'a' occurs twice"):
        read_cameras(f, image_size=(10, 10))
    (tmp_path / "list.txt").write_text("a.jpg\n")
    with pytest.raises(InputError, match="names 1 images but .* holds 2 cameras"):
        read_cameras(f, image_size=(10, 10))
    (tmp_path / "list.txt").unlink()
    assert list(read_cameras(f, image_size=(10, 10))) == ["camera_0000", "camera_0001"]
    monkeypatch.setattr(cameras_module, "MAX_CAMERA_FILE_BYTES", 64)
    with pytest.raises(InputError, match="larger than"):
        read_cameras(f, image_size=(10, 10))
    with pytest.raises(InputError, match="not found"):
        read_cameras(tmp_path / "missing.txt")
    (tmp_path / "nothing").mkdir()
    with pytest.raises(InputError, match="holds no camera file"):
        read_cameras(tmp_path / "nothing")


def test_ruemonge_cameras_read_alike():
    if not (RUEMONGE / "cameras.txt").is_file():
        pytest.skip(f"RueMonge cameras {RUEMONGE / 'cameras.txt'} absent (expected ../shared/data)")
    a, b = read_cameras(RUEMONGE / "cameras.txt"), read_visualsfm(RUEMONGE / "cameras.txt")
    assert list(a) == list(b) and len(a) > 100
    for k in a:
        assert (a[k].file, a[k].focal, a[k].principal, a[k].radial) == \
            (b[k].file, b[k].focal, b[k].principal, b[k].radial)
        assert np.array_equal(a[k].R, b[k].R) and np.array_equal(a[k].C, b[k].C)
