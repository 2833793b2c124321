"""facadeforge.city.enhance / ``facadeforge enhance``: a textured mass model made procedural
(Müller et al. 2007 §1, Fig. 2, Fig. 16)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from tests.cjval import cjval_problems, needs_cjval

from facadeforge.city.enhance import enhance
from facadeforge.cli import main
from facadeforge.datasets.mass_models import DEPTH, HEIGHT, TEXTURE_PPM, WIDTH
from facadeforge.datasets.mass_models import box_mass_model as _build
from facadeforge.errors import InputError
from facadeforge.exchange import export, load
from facadeforge.geometry.mesh import Mesh
from facadeforge.model.model import Material, Model, Part

LOW_PPM = 8                               # the aerial-like low-resolution variant


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    d = tmp_path_factory.mktemp("enhance_full")
    path, truth = _build(d / "in")
    out = d / "out"
    return enhance(path, out), out, truth


@pytest.fixture(scope="module")
def low(tmp_path_factory):
    d = tmp_path_factory.mktemp("enhance_low")
    path, truth = _build(d / "in", textured=(0,), ppm=LOW_PPM)
    out = d / "out"
    return enhance(path, out), out, truth


def test_windows_found_within_a_quarter_of_the_truth(full):
    result, out, truth = full
    found = [f.record["windows"] for f in result.facades]
    print("windows found", found, "truth", truth)
    assert len(result.facades) == 4 and not result.skipped
    assert abs(sum(found) - sum(truth)) <= 0.25 * sum(truth)
    report = json.loads((out / "report.json").read_text())
    assert [r["windows"] for r in report["facades"]] == found
    for r in report["facades"]:
        assert r["building"] == "block" and r["floors"] >= 3 and isinstance(r["flags"], list)
        assert r["px_per_m"] == pytest.approx(TEXTURE_PPM, rel=0.02)
        assert {r["width_m"], r["height_m"]} <= {WIDTH, DEPTH, HEIGHT}


def test_outdir_files(full):
    result, out, _ = full
    for name in ("model.glb", "model.city.json", "report.json"):
        assert (out / name).is_file(), name
    for f in result.facades:
        for name in ("rules.cga", "shape_tree.json", "texture.png"):
            assert (out / f.folder / name).is_file(), (f.folder, name)
        img = Image.open(out / f.folder / "texture.png")
        w_m, h_m = f.frame.size_m
        assert img.size == (round(w_m * 40), round(h_m * 40))
    models = load(out / "model.glb", texture_dir=out.parent / "reread")
    labels = {p.label for m in models for p in m.parts}
    assert {"window", "roof"} <= labels


@needs_cjval
def test_model_cityjson_passes_cjval(full):
    _, out, _ = full
    assert cjval_problems(out / "model.city.json") == []


def test_roof_kept_and_walls_replaced(full):
    result, _, _ = full
    (model,) = result.models
    roofs = [p for p in model.parts if p.label == "roof"]
    assert len(roofs) == 1 and roofs[0].mesh.n_faces == 2      # GLB triangles: the same quad
    b = roofs[0].mesh.bounds()
    assert np.allclose(b, [[0, HEIGHT, 0], [WIDTH, HEIGHT, DEPTH]], atol=1e-4)
    # no original wall face is left: every wall was textured and replaced
    assert not [p for p in model.parts if p.symbol == "Wall"]
    assert result.report["summary"]["kept_faces"] == 2


def test_facades_lie_on_their_walls(full):
    result, _, _ = full
    for f in result.facades:
        fr = f.frame
        pts = np.concatenate([p.mesh.vertices[p.mesh.corners] for p in f.parts])
        rel = pts - fr.origin
        along_n, along_u, along_v = rel @ fr.n, rel @ fr.u, rel @ fr.v
        w_m, h_m = fr.size_m
        assert np.abs(along_n).max() <= 1.5, f.folder
        assert along_u.min() >= -0.05 and along_u.max() <= w_m + 0.05, f.folder
        assert along_v.min() >= -0.05 and along_v.max() <= h_m + 0.05, f.folder
        # the wall's outward normal: the box's centre is behind it
        centre = np.array([WIDTH / 2, HEIGHT / 2, DEPTH / 2])
        assert (centre - fr.origin) @ fr.n < 0
        assert np.allclose(fr.v, [0, 1, 0]) and np.allclose(np.cross(fr.v, fr.n), fr.u)


def test_low_resolution_texture(low):
    result, out, truth = low
    (f,) = result.facades
    print("low-res windows found", f.record["windows"], "truth", truth)
    assert f.record["px_per_m"] == pytest.approx(LOW_PPM, rel=0.05)
    assert f.record["resampled_px_per_m"] == 40 and f.record["upsampled"] == pytest.approx(
        40 / LOW_PPM, rel=0.05)
    assert any("upsampled" in n for n in f.record["notes"])
    assert f.image.shape[:2] == (round(HEIGHT * 40), round(WIDTH * 40))
    # the untextured walls and the roof are kept as they were
    (model,) = result.models
    assert len([p for p in model.parts if p.symbol == "Wall"]) == 3
    report = json.loads((out / "report.json").read_text())
    assert report["facades"][0]["px_per_m"] == pytest.approx(LOW_PPM, rel=0.05)


def test_model_without_textures_is_refused(tmp_path):
    path, _ = _build(tmp_path / "in", textured=())
    with pytest.raises(InputError, match="no textured faces"):
        enhance(path, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_small_and_missing_walls_are_skipped(tmp_path):
    from facadeforge.city.enhance import _group_walls

    quad = np.array([(0, 0, 0), (1.5, 0, 0), (1.5, 3, 0), (0, 3, 0)], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    tex = tmp_path / "t.png"
    Image.fromarray(np.full((120, 60, 3), 128, np.uint8)).save(tex)
    parts = [Part(Mesh(quad, faces=[np.arange(4)], uvs=[uv]),
                  material=Material(texture=str(tex)))]
    roof = Part(Mesh(quad[:, [0, 2, 1]], faces=[np.arange(4)], uvs=[uv]),
                material=Material(texture=str(tex)))
    assert len(_group_walls(parts + [roof])) == 1          # the horizontal face is no wall
    path = tmp_path / "small.glb"
    export([Model(parts=parts, name="shed")], path)
    result = enhance(path)
    assert not result.facades and "smaller than 2 m" in result.skipped[0]["reason"]
    assert result.models[0].parts[0].mesh.n_faces == 2      # kept as it was


@pytest.mark.parametrize("name, match", [("missing.glb", "no such file"),
                                         ("model.ply", "reads a textured .obj")])
def test_bad_input(tmp_path, name, match):
    path = tmp_path / name
    if path.suffix == ".ply":
        path.write_text("ply\n")
    with pytest.raises(InputError, match=match):
        enhance(path)
    with pytest.raises(InputError, match="px-per-m"):
        enhance(Path(__file__), px_per_m=0)


def test_cli(tmp_path, capsys):
    path, _ = _build(tmp_path / "in", textured=(1,))
    out = tmp_path / "out"
    assert main(["enhance", str(path), "-o", str(out), "--px-per-m", "30"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and "1 facade" in lines[0] and str(out) in lines[0]
    assert (out / "facade_00" / "rules.cga").is_file()
    assert main(["enhance", str(tmp_path / "nope.glb"), "-o", str(tmp_path / "o2")]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "no such file" in err[0] and not captured.out


def test_z_up_model(tmp_path, capsys):
    """The same mass model written z up (as GIS and photogrammetry tools write city models):
    with ``--up z`` it gives the same facades, windows and walls as the y-up original; read as
    y up, its textured wall stands on its side (width and height swapped)."""
    from facadeforge.city.enhance import Z_UP_TO_Y_UP

    path, _ = _build(tmp_path / "in", textured=(1,))
    y_up = enhance(path, px_per_m=30)
    turned = [Model(parts=[Part(p.mesh.with_vertices(p.mesh.vertices @ Z_UP_TO_Y_UP), p.label,
                                p.material, p.symbol) for p in m.parts], name=m.name)
              for m in load(path)]
    z_path = tmp_path / "z_up.glb"
    export(turned, z_path)
    assert np.ptp(np.concatenate([p.mesh.vertices for m in turned for p in m.parts]), 0)[2] \
        == pytest.approx(HEIGHT)                     # up is z now
    out = tmp_path / "out"
    assert main(["enhance", str(z_path), "--up", "z", "--px-per-m", "30", "-o", str(out)]) == 0
    capsys.readouterr()
    z_up = json.loads((out / "report.json").read_text())
    assert [f["windows"] for f in z_up["facades"]] == [f.record["windows"] for f in y_up.facades]
    for a, b in zip(z_up["facades"], (f.record for f in y_up.facades)):
        assert a["width_m"] == b["width_m"] and a["height_m"] == b["height_m"]
        np.testing.assert_allclose(a["normal"], b["normal"], atol=1e-4)
    misread = enhance(z_path, px_per_m=30)  # as y up: the wall stands on its side
    assert [(f.record["width_m"], f.record["height_m"]) for f in misread.facades] != \
        [(f.record["width_m"], f.record["height_m"]) for f in y_up.facades]
    with pytest.raises(InputError, match="--up 'x'"):
        enhance(z_path, up="x")


def test_gable_wall_models_its_rectangle_and_keeps_the_gable(tmp_path):
    """A street wall that is a pentagon (a gable end): the facade is modelled in the largest
    rectangle in it, below the eaves, and the gable keeps its texture, no geometry above the
    wall's outline."""
    from facadeforge.datasets.mass_models import GABLE_RISE, gable_mass_model

    path, truth = gable_mass_model(tmp_path / "in")
    r = enhance(path, tmp_path / "out")
    (f,) = r.facades
    rec = f.record
    assert rec["wall_cover"] < 0.98
    assert rec["rectangle_m"] == pytest.approx([0.0, 0.0, WIDTH, HEIGHT], abs=0.11)
    assert "not a rectangle" in rec["notes"][0]
    assert abs(rec["windows"] - truth) <= 0.25 * truth
    # the classifier may crop the facade further inside the rectangle (the photo's top is
    # roof): the kept texture is the wall less the region modelled
    x0, y0, x1, y1 = rec["region_m"]
    assert y1 <= HEIGHT + 0.11
    kept = [p for p in f.parts if p.symbol == "WallMargin"]
    wall = WIDTH * HEIGHT + 0.5 * WIDTH * GABLE_RISE
    assert kept and sum(p.mesh.area() for p in kept) == pytest.approx(
        wall - (x1 - x0) * (y1 - y0), rel=0.01)
    facade = [p for p in f.parts if p.symbol != "WallMargin"]
    top = max(p.mesh.vertices[:, 1].max() for p in facade)
    assert top <= y1 + 0.12
    # the whole model: the gable's texture, nothing sticking out of the pentagon's corners
    (m,) = r.models
    for p in m.parts:
        v = p.mesh.vertices
        outside = (v[:, 1] > HEIGHT + 0.12) & (np.abs(v[:, 0] - WIDTH / 2) > (
            HEIGHT + GABLE_RISE - v[:, 1]) * WIDTH / (2 * GABLE_RISE) + 0.05)
        assert not outside.any(), p.symbol
