"""repair_model / ``facadeforge repair-model``: facade textures of a 3D model repaired in their
UV rectangles, the geometry and every other pixel unchanged, the input untouched."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge import derive, load_rules
from facadeforge.cli import main
from facadeforge.errors import InputError
from facadeforge.exchange import export, load
from facadeforge.geometry.mesh import Mesh
from facadeforge.model.model import Material, Model, Part
from facadeforge.repair import pipeline
from facadeforge.repair.model_textures import facade_rectangles, repair_model

GREEN = (40, 150, 45)
MAGENTA = np.array([255, 0, 255], np.uint8)


def _facade_texture(w: int = 240, h: int = 180) -> tuple[np.ndarray, np.ndarray]:
    """A plaster wall with a 4 × 3 grid of windows and a green bush: pixels and bush mask."""
    rng = np.random.default_rng(0)
    rgb = np.full((h, w, 3), (205, 190, 170), np.float32) + rng.normal(0, 5, (h, w, 1))
    for r in range(3):
        for c in range(4):
            y0, x0 = 20 + 55 * r, 20 + 58 * c
            rgb[y0:y0 + 32, x0:x0 + 22] = (60, 70, 85)
    yy, xx = np.mgrid[:h, :w]
    bush = ((xx - 120) / 40.0) ** 2 + ((yy - 150) / 28.0) ** 2 < 1
    rgb[bush] = GREEN
    return np.clip(rgb, 0, 255).astype(np.uint8), bush


@pytest.fixture()
def building(tmp_path):
    """A 12 × 10 × 9 m box: four walls projected onto facade.png (UVs 0–1), the roof onto
    roof.png; written as model.obj (+ .mtl, textures/) and model.glb in ``tmp_path/in``."""
    src = tmp_path / "src"
    src.mkdir()
    tex, bush = _facade_texture()
    Image.fromarray(tex).save(src / "facade.png")
    Image.new("RGB", (64, 64), (90, 40, 40)).save(src / "roof.png")
    rules = load_rules(
        'Lot --> extrude(9) comp(f) { top : Top | side : Side }\n'
        'Top --> setupProjection(0, scope.xy, scope.sx, scope.sy) projectUV(0) '
        'texture("roof.png")\n'
        'Side --> setupProjection(0, scope.xy, scope.sx, scope.sy) projectUV(0) '
        'texture("facade.png")\n', assets=src)
    (model,) = derive(rules, lot_size="12x10")
    folder = tmp_path / "in"
    export(model, folder / "model.obj")
    export(model, folder / "model.glb")
    return folder, tex, bush


def _hashes(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _fake_repair(calls: list):
    """A stand-in for repair_photo: repairs the crop's lower right quarter with magenta."""
    def fake(crop, *, mask=None, rectified=True, seed=0, **kw):
        calls.append({"shape": crop.shape, "crop": crop.copy(), "rectified": rectified,
                      "mask": mask})
        h, w = crop.shape[:2]
        m = np.zeros((h, w), bool)
        m[h // 2:, w // 2:] = True
        out = crop.copy()
        out[m] = MAGENTA
        out[~m] = 0          # not masked: must not be pasted back

        class R:
            repaired, report = out, {"mask": {"source": "fake", "fraction": float(m.mean())},
                                     "filled": {"patchmatch": int(m.sum())}}
        R.mask = m
        return R
    return fake


def _geometry(models):
    parts = [p for m in models for p in m.parts]
    return ([np.asarray(p.mesh.vertices)[p.mesh.corners] for p in parts],
            [p.mesh.corner_uvs for p in parts], [Path(p.material.texture).name for p in parts])


def _texture_of(models, facade: bool = True) -> np.ndarray:
    """The texture of the walls (or of the roof) of the loaded models (a GLB's textures come
    back under names of its own)."""
    for m in models:
        for p in m.parts:
            if p.material.texture and (abs(p.mesh.face_normals()[0, 1]) < 0.5) == facade:
                return np.asarray(Image.open(p.material.texture).convert("RGB"))
    raise AssertionError("no such texture")


@pytest.mark.parametrize("fmt", ["obj", "glb"])
def test_plumbing_crops_paste_and_geometry(building, tmp_path, monkeypatch, fmt):
    folder, tex, _ = building
    before = _hashes(folder)
    calls: list = []
    monkeypatch.setattr(pipeline, "repair_photo", _fake_repair(calls))
    out = tmp_path / "out" / f"repaired.{fmt}"
    report = repair_model(folder / f"model.{fmt}", out, report_path=tmp_path / "r.json")

    # one rectangle: the four walls share the whole facade texture; the roof is not a facade
    assert len(calls) == 1 and calls[0]["rectified"] and calls[0]["mask"] is None
    assert calls[0]["shape"] == tex.shape and (calls[0]["crop"] == tex).all()
    s = report["summary"]
    assert (s["textures"], s["textures_repaired"], s["facade_rectangles"]) == (2, 1, 1)
    facade = next(e for e in report["textures"] if e.get("output"))
    # four walls: quads in an OBJ, two triangles each in a GLB
    assert facade["facade_faces"] == (4 if fmt == "obj" else 8)
    assert facade["rectangles"][0]["box"] == [0, 0, 240, 180]
    roof = next(e for e in report["textures"] if not e.get("output"))
    assert roof["facade_faces"] == 0 and roof["rectangles"] == []
    assert json.loads((tmp_path / "r.json").read_text())["summary"] == s

    assert _hashes(folder) == before                 # the input is untouched
    a, b = load(folder / f"model.{fmt}"), load(out)
    (va, ua, _), (vb, ub, names) = _geometry(a), _geometry(b)
    assert len(va) == len(vb)
    for x, y in zip(va, vb):
        np.testing.assert_allclose(x, y, atol=1e-5)
    for x, y in zip(ua, ub):
        np.testing.assert_allclose(x, y, atol=1e-6)
    assert facade["output"].endswith("_repaired.png")     # a GLB's image: model_image1_…
    if fmt == "obj":
        assert sorted(set(names)) == ["facade_repaired.png", "roof.png"]
    got = _texture_of(b)
    changed = (got != tex).any(axis=2)
    quarter = np.zeros(changed.shape, bool)
    quarter[90:, 120:] = True
    assert (changed == quarter).all() and (got[quarter] == MAGENTA).all()
    roof_in, roof_out = _texture_of(a, facade=False), _texture_of(b, facade=False)
    assert (roof_in == roof_out).all()


def _quad(x0, x1, z, u0, u1, v0=0.0, v1=1.0, horizontal=False) -> Mesh:
    if horizontal:
        verts = [[x0, 5, 0], [x1, 5, 0], [x1, 5, -4], [x0, 5, -4]]
    else:
        verts = [[x0, 0, z], [x1, 0, z], [x1, 4, z], [x0, 4, z]]
    return Mesh(verts, corners=[0, 1, 2, 3], starts=[0, 4],
                corner_uvs=[[u0, v0], [u1, v0], [u1, v1], [u0, v1]])


def test_atlas_rectangles_tiled_faces_and_roofs(tmp_path, monkeypatch):
    """One atlas: two facades side by side (two rectangles), a roof in its top strip (left
    alone), a tiled wall (UVs beyond 1: a repeated material, skipped)."""
    rgb = np.full((200, 400, 3), 180, np.uint8)
    Image.fromarray(rgb).save(tmp_path / "atlas.png")
    mat = Material(name="atlas", texture=str(tmp_path / "atlas.png"))
    parts = [Part(_quad(0, 4, 0, 0.0, 0.25, 0.0, 0.5), "wall", mat),      # facade A, two faces
             Part(_quad(4, 8, 0, 0.25, 0.45, 0.0, 0.5), "wall", mat),
             Part(_quad(9, 13, 0, 0.55, 1.0, 0.0, 0.6), "wall", mat),     # facade B
             Part(_quad(0, 8, 0, 0.0, 1.0, 0.8, 1.0, horizontal=True), "roof", mat),
             Part(_quad(0, 8, 3, 0.0, 3.0), "wall", mat)]                  # tiled
    export(Model(parts=parts, name="atlas"), tmp_path / "in" / "atlas.obj")   # quads stay quads
    calls: list = []
    monkeypatch.setattr(pipeline, "repair_photo", _fake_repair(calls))
    report = repair_model(tmp_path / "in" / "atlas.obj", tmp_path / "atlas_out.glb")
    entry = report["textures"][0]
    assert (entry["facade_faces"], entry["tiled_faces"], entry["other_faces"]) == (3, 1, 1)
    assert [r["box"] for r in entry["rectangles"]] == [[0, 100, 180, 200], [220, 80, 400, 200]]
    assert [r["faces"] for r in entry["rectangles"]] == [2, 1]
    got = _texture_of(load(tmp_path / "atlas_out.glb"))
    changed = (got != rgb).any(axis=2)
    assert changed[150:, 90:180].all() and changed[140:, 310:].all()
    assert not changed[:80].any()                    # the roof's strip
    assert changed.sum() == 50 * 90 + 60 * 90


def test_facade_rectangles_merge_until_disjoint():
    boxes = np.array([[0, 0, 10, 10], [10, 0, 20, 5],       # touching: one
                      [30, 20, 40, 40], [0, 30, 30, 40],    # an L's bounding box …
                      [20, 22, 25, 27]])                    # … swallows this one
    assert facade_rectangles(boxes, (50, 50)) == [(0, 0, 20, 10), (0, 20, 40, 40)]
    assert facade_rectangles(boxes[:1], (50, 50)) == [(0, 0, 10, 10)]
    assert facade_rectangles(np.zeros((0, 4), int), (8, 8)) == []


def test_real_repair_with_a_given_mask_changes_only_the_bush(building, tmp_path):
    folder, tex, bush = building
    seen = []

    def given(texture, box, crop):
        seen.append((Path(texture).name, box))
        return bush[box[1]:box[3], box[0]:box[2]]

    out = tmp_path / "fixed.obj"
    report = repair_model(folder / "model.obj", out, mask=given)
    assert seen == [("facade.png", (0, 0, 240, 180))]
    rect = report["textures"][[e["texture"] for e in report["textures"]].index("facade.png")][
        "rectangles"][0]
    assert rect["mask"] == "given" and rect["pixels"] == int(bush.sum())
    got = _texture_of(load(out))
    assert (got[~bush] == tex[~bush]).all()
    green = lambda a: (a[..., 1].astype(int) - a[..., [0, 2]].max(axis=-1) > 60)  # noqa: E731
    assert green(tex[bush]).mean() > 0.99 and green(got[bush]).mean() < 0.05
    assert (out.parent / "textures" / "facade_repaired.png").is_file()


def test_bad_input_is_refused(building, tmp_path):
    folder, _, _ = building
    with pytest.raises(InputError, match=r"\.obj .*\.glb"):
        repair_model(folder / "model.obj", tmp_path / "out.city.json")
    (tmp_path / "m.ply").write_text("ply\n")
    with pytest.raises(InputError, match="m.ply"):
        repair_model(tmp_path / "m.ply", tmp_path / "out.obj")
    with pytest.raises(InputError, match="no such file"):
        repair_model(tmp_path / "missing.obj", tmp_path / "out.obj")
    with pytest.raises(InputError, match="file the run reads"):
        repair_model(folder / "model.glb", folder / "model.glb")
    # model.obj → other.obj would write other.mtl: fine; but a name whose .mtl is the input's
    (folder / "model.mtl").rename(folder / "lib.mtl")
    text = (folder / "model.obj").read_text().replace("mtllib model.mtl", "mtllib lib.mtl")
    (folder / "model.obj").write_text(text)
    with pytest.raises(InputError, match="lib.mtl"):
        repair_model(folder / "model.obj", folder / "lib.obj")
    plain = Model(parts=[Part(_quad(0, 4, 0, 0, 1), "wall", Material())], name="plain")
    export(plain, tmp_path / "plain.glb")
    with pytest.raises(InputError, match="no textured faces"):
        repair_model(tmp_path / "plain.glb", tmp_path / "plain_out.glb")


def test_cli_repair_model(building, tmp_path, monkeypatch, capsys):
    folder, _, _ = building
    monkeypatch.setattr(pipeline, "repair_photo", _fake_repair([]))
    out = tmp_path / "cli" / "model.glb"
    assert main(["repair-model", str(folder / "model.obj"), "-o", str(out),
                 "--report", str(tmp_path / "report.json")]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("repaired ") and "1 of 2 textures" in line and str(out) in line
    assert out.is_file() and (tmp_path / "report.json").is_file()
    assert main(["repair-model", str(folder / "model.obj"), "-o", str(tmp_path / "x.ply")]) == 2
    assert "facadeforge: error:" in capsys.readouterr().err
