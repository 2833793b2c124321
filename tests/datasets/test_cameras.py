"""VisualSFM camera files: reading, errors, and the RueMonge photos' orientation by reprojection."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from facadeforge.datasets.cameras import read_visualsfm, seen_intervals
from facadeforge.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
RUEMONGE = DATA / "ruemonge" / "train"

_BLOCK = """{name}
/data/seq/IMG_{n}.JPG
1000
533.5 400
0 0 0
{cx} 0 0
0 0 0
1 0 0 0
{R}
0.01
0 0 0
"""
_LOOK_Z = "1 0 0\n0 1 0\n0 0 1"


def _write(path: Path, blocks: list[str], count: int | None = None) -> Path:
    path.write_text(f"# header\n\n{len(blocks) if count is None else count}\n\n"
                    + "\n".join(blocks))
    return path


def test_reads_blocks(tmp_path: Path):
    f = _write(tmp_path / "cameras_v2.txt",
               [_BLOCK.format(name=f"{i:08d}.jpg", n=5000 + i, cx=i, R=_LOOK_Z) for i in range(3)])
    cams = read_visualsfm(f)
    assert list(cams) == ["IMG_5000", "IMG_5001", "IMG_5002"]
    c = cams["IMG_5002"]
    assert c.focal == 1000 and c.size == (1067, 800) and c.radial == 0.01
    assert np.allclose(c.C, [2, 0, 0])
    uv = c.project(np.array([[2.0, 0.0, 10.0]]))
    assert np.allclose(uv, [[533.5, 400]])
    # a portrait photo of the landscape calibration is turned; pixels map both ways
    shape = (1067, 800)
    assert c.turned(shape) and not c.turned((800, 1067))
    xy = c.project(np.array([[2.0, 0.0, 10.0]]), shape)
    assert np.allclose(c.from_photo(xy, shape), uv)


@pytest.mark.parametrize("text, match", [
    ("", "no cameras"),
    ("3\n", "ends after 0"),
    ("x\n", "expected 1 numbers"),
])
def test_bad_files(tmp_path: Path, text: str, match: str):
    f = tmp_path / "c.txt"
    f.write_text(text)
    with pytest.raises(InputError, match=match):
        read_visualsfm(f)


def test_bad_blocks(tmp_path: Path):
    with pytest.raises(InputError, match="not found"):
        read_visualsfm(tmp_path / "missing.txt")
    bad = _BLOCK.format(name="a.jpg", n=1, cx=0, R="2 0 0\n0 1 0\n0 0 1")
    with pytest.raises(InputError, match="orthonormal"):
        read_visualsfm(_write(tmp_path / "r.txt", [bad]))
    nan = _BLOCK.format(name="a.jpg", n=1, cx="nan", R=_LOOK_Z)
    with pytest.raises(InputError, match=r"c.txt:\d+: expected 3 numbers"):
        read_visualsfm(_write(tmp_path / "c.txt", [nan]))
    twice = [_BLOCK.format(name=f"{i}.jpg", n=7, cx=i, R=_LOOK_Z) for i in range(2)]
    with pytest.raises(InputError, match="occurs twice"):
        read_visualsfm(_write(tmp_path / "d.txt", twice))


def test_seen_intervals_of_a_straight_street(tmp_path: Path):
    # cameras along x looking along +z; a facade 4 units away; each sees ±4·400/1000 = ±1.6
    R = "0 1 0\n1 0 0\n0 0 1"   # turned calibration: x axis (down the photo) is world y
    f = _write(tmp_path / "s.txt",
               [_BLOCK.format(name=f"{i}.jpg", n=100 + i, cx=i, R=R) for i in range(8)])
    cams = read_visualsfm(f)
    iv = seen_intervals([cams[k] for k in sorted(cams)], 4.0)
    assert np.allclose(iv[:, 1] - iv[:, 0], 3.2) and np.allclose(iv[:, 0], np.arange(8) - 1.6)


def _sift(path: Path):
    im = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    keys, desc = cv2.SIFT_create(2000).detectAndCompute(im, None)
    return im.shape, np.array([k.pt for k in keys]), desc


def test_ruemonge_orientation_by_reprojection():
    """The README's warning: the photos are the calibrated images turned a quarter."""
    if not (RUEMONGE / "cameras.txt").is_file():
        pytest.skip(f"RueMonge cameras {RUEMONGE / 'cameras.txt'} absent (expected ../shared/data)")
    cams = read_visualsfm(RUEMONGE / "cameras.txt")
    a, b = cams["IMG_5800"], cams["IMG_5802"]
    shape, pa, da = _sift(RUEMONGE / "img" / "IMG_5800.jpg")
    _, pb, db = _sift(RUEMONGE / "img" / "IMG_5802.jpg")
    pairs = cv2.BFMatcher().knnMatch(da, db, k=2)
    good = [m for m, n in pairs if m.distance < 0.7 * n.distance]
    assert len(good) > 100
    A = a.from_photo(pa[[m.queryIdx for m in good]], shape)
    B = b.from_photo(pb[[m.trainIdx for m in good]], shape)
    X = cv2.triangulatePoints(a.P, b.P, A.T, B.T)
    X = (X[:3] / X[3]).T
    err = np.maximum(np.linalg.norm(a.project(X, shape) - pa[[m.queryIdx for m in good]], axis=1),
                     np.linalg.norm(b.project(X, shape) - pb[[m.trainIdx for m in good]], axis=1))
    assert np.median(err) < 2.0
    inliers = err < 2.0
    assert 3.0 < np.median(a.depth(X[inliers])) < 4.5          # the facade (STREET_DEPTH 4)
    # the other quarter turn does not fit
    wrong = np.c_[shape[0] - 1 - pa[[m.queryIdx for m in good]][:, 1],
                  pa[[m.queryIdx for m in good]][:, 0]]
    wrong_b = np.c_[shape[0] - 1 - pb[[m.trainIdx for m in good]][:, 1],
                    pb[[m.trainIdx for m in good]][:, 0]]
    Y = cv2.triangulatePoints(a.P, b.P, wrong.T, wrong_b.T)
    Y = (Y[:3] / Y[3]).T
    assert np.median(np.linalg.norm(a.project(Y) - wrong, axis=1)) > 5.0
