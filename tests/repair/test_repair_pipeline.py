"""repair_photo end to end on synthetic facades: only masked pixels change, the fill beats OpenCV's
inpainting, labels are completed, the outputs are written whole, bad input is refused."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from facadeforge.cli import main
from facadeforge.errors import InputError
from facadeforge.exchange.raster import LABEL_INDEX
from facadeforge.repair.pipeline import FILL_METHODS, repair_photo

WALL, WINDOW, VEG = LABEL_INDEX["wall"], LABEL_INDEX["window"], LABEL_INDEX["vegetation"]


def _facade(seed: int = 0):
    """A 5 × 4 grid of windows on a noisy plaster wall; returns rgb and canonical labels."""
    rng = np.random.default_rng(seed)
    h, w = 320, 400
    rgb = np.empty((h, w, 3), np.float32)
    rgb[:] = (205, 190, 170)
    rgb += rng.normal(0, 6, (h, w, 1))
    lab = np.full((h, w), WALL, np.int64)
    for r in range(4):
        for c in range(5):
            y0, x0 = 30 + 75 * r, 25 + 75 * c
            rgb[y0:y0 + 45, x0:x0 + 30] = (60, 70, 85)
            rgb[y0:y0 + 45, x0 + 14:x0 + 16] = 235
            rgb[y0 + 45:y0 + 49, x0 - 3:x0 + 33] = 240           # sill
            lab[y0:y0 + 45, x0:x0 + 30] = WINDOW
    return np.clip(rgb, 0, 255).astype(np.uint8), lab


def _occlude(rgb, lab):
    """A bush in front of the lower middle: the true mask, the occluded photo and labels."""
    h, w = lab.shape
    yy, xx = np.mgrid[:h, :w]
    mask = ((xx - 200) / 60.0) ** 2 + ((yy - 270) / 55.0) ** 2 < 1
    occ = rgb.copy()
    occ[mask] = (40, 110, 45)
    lab_occ = lab.copy()
    lab_occ[mask] = VEG
    return occ, lab_occ, mask


def _psnr(a, b, m):
    err = ((a[m].astype(float) - b[m].astype(float)) ** 2).mean()
    return 10 * np.log10(255 ** 2 / max(err, 1e-9))


@pytest.mark.parametrize("fill", ["expected", "texture"])
def test_repair_with_mask_beats_telea_and_changes_only_the_mask(fill):
    import cv2

    clean, lab = _facade()
    occ, lab_occ, mask = _occlude(clean, lab)
    r = repair_photo(occ, mask=mask, labels=lab_occ, rectified=True, fill=fill)
    assert r.report["fill"] == fill
    assert r.repaired.shape == occ.shape and r.repaired.dtype == np.uint8
    assert np.array_equal(r.repaired[~r.mask], occ[~r.mask])
    assert r.mask[mask].all()
    telea = cv2.inpaint(occ, mask.astype(np.uint8), 5, cv2.INPAINT_TELEA)
    ours, base = _psnr(r.repaired, clean, mask), _psnr(telea, clean, mask)
    assert ours > base + 1.5, (ours, base)
    # the hidden windows come back in the labels
    assert (r.labels[mask] == lab[mask]).mean() > 0.85
    assert set(r.report["filled"]) == set(FILL_METHODS)
    assert sum(r.report["filled"].values()) == int(r.mask.sum())


def test_repair_takes_the_mask_from_occluder_labels():
    clean, lab = _facade(1)
    occ, lab_occ, mask = _occlude(clean, lab)
    r = repair_photo(occ, labels=lab_occ, rectified=True)
    assert r.report["mask"]["source"] == "labels"
    assert np.array_equal(r.mask, mask)
    assert VEG not in np.unique(r.labels[mask])


def test_repair_of_an_unrectified_photo_keeps_its_frame():
    from facadeforge.frames import warp

    clean, lab = _facade(2)
    occ, lab_occ, mask = _occlude(clean, lab)
    H = np.array([[1.0, 0.08, 10], [0.02, 1.0, 5], [1e-4, 0, 1]])
    photo = warp(occ, H, (360, 440))
    pmask = warp(mask.astype(np.uint8), H, (360, 440), nearest=True).astype(bool)
    r = repair_photo(photo, mask=pmask, rectified=False)
    assert r.repaired.shape == photo.shape
    assert np.array_equal(r.repaired[~r.mask], photo[~r.mask])
    assert r.report["rectification"]["applied"]


def test_repair_refuses_bad_input():
    clean, lab = _facade()
    with pytest.raises(InputError, match="same size"):
        repair_photo(clean, mask=np.zeros((10, 10), bool), rectified=True)
    with pytest.raises(InputError, match="labels are"):
        repair_photo(clean, labels=lab[:10], rectified=True)
    with pytest.raises(InputError, match="canonical label"):
        repair_photo(clean, labels=lab + 100, rectified=True)
    with pytest.raises(InputError, match="wall"):
        repair_photo(clean, labels=lab, wall="paint", rectified=True)


def test_cli_repair_writes_the_outputs(tmp_path, capsys):
    clean, lab = _facade(3)
    occ, _, mask = _occlude(clean, lab)
    Image.fromarray(occ).save(tmp_path / "f.png")
    Image.fromarray(mask.astype(np.uint8) * 255).save(tmp_path / "m.png")
    out = tmp_path / "out"
    assert main(["repair", str(tmp_path / "f.png"), "--rectified", "--mask",
                 str(tmp_path / "m.png"), "-o", str(out)]) == 0
    line = capsys.readouterr().out
    assert "repaired" in line and "mask from given" in line
    for name in ("repaired.png", "mask.png", "labels_completed.png", "report.json"):
        assert (out / name).is_file(), name
    rep = json.loads((out / "report.json").read_text())
    assert rep["mask"]["pixels"] == int(mask.sum())
    assert np.asarray(Image.open(out / "repaired.png")).shape == occ.shape
    # a mask of another size: one line, exit 2, the output folder untouched
    Image.fromarray(np.zeros((5, 5), np.uint8)).save(tmp_path / "small.png")
    before = sorted(p.name for p in out.iterdir())
    assert main(["repair", str(tmp_path / "f.png"), "--rectified", "--mask",
                 str(tmp_path / "small.png"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "same size" in err
    assert sorted(p.name for p in out.iterdir()) == before


def test_cli_synthesize(tmp_path, capsys):
    from facadeforge.repair.synthesis import DEFAULT_WEIGHTS

    if not DEFAULT_WEIGHTS.is_file():
        pytest.skip(f"no shipped synthesis weights at {DEFAULT_WEIGHTS}")
    clean, lab = _facade(4)
    from facadeforge.exchange.raster import write_label_png

    write_label_png(lab, tmp_path / "labels.png")
    Image.fromarray(clean).save(tmp_path / "style.png")
    out = tmp_path / "tex.png"
    assert main(["synthesize", str(tmp_path / "labels.png"), "--label-set", "canonical",
                 "--style", str(tmp_path / "style.png"), "--style-labels",
                 str(tmp_path / "labels.png"), "-o", str(out)]) == 0
    assert "synthesized" in capsys.readouterr().out
    tex = np.asarray(Image.open(out))
    assert tex.shape == clean.shape
    # the wall is painted in the style's wall colour, the windows darker than it
    wall, win = lab == WALL, lab == WINDOW
    assert np.abs(tex[wall].mean(0) - clean[wall].mean(0)).max() < 12
    assert tex[win].mean() < tex[wall].mean() - 40
    assert main(["synthesize", str(tmp_path / "labels.png"), "--style",
                 str(tmp_path / "style.png"), "-o", str(tmp_path / "tex.jpg")]) == 2
    assert "PNG" in capsys.readouterr().err
