"""OBJ + MTL export and import."""

from __future__ import annotations

from pathlib import Path

import pytest

from facadeforge.exchange import EXPORTERS, IMPORTERS, export, load
from facadeforge.exchange.obj import export_obj, load_obj
from facadeforge.model import Model


def test_registered():
    assert EXPORTERS["obj"] is export_obj
    assert IMPORTERS["obj"] is load_obj


def test_round_trip(tmp_path: Path, house: Model, texture_png: str, by_label):
    written = export(house, tmp_path / "out" / "house.obj")
    out = tmp_path / "out"
    assert written == [out / "house.obj", out / "house.mtl", out / "textures" / "brick.png"]
    assert (out / "textures" / "brick.png").read_bytes() == Path(texture_png).read_bytes()

    models = load(out / "house.obj")
    assert [m.name for m in models] == ["house"]
    back = models[0]
    assert back.attributes == house.attributes
    assert len(back.parts) == len(house.parts)
    assert sum(p.mesh.n_faces for p in back.parts) == sum(p.mesh.n_faces for p in house.parts)
    assert back.mesh().area() == pytest.approx(house.mesh().area(), abs=1e-4)
    before, after = by_label([house]), by_label(models)
    assert set(after) == set(before)
    for label, d in before.items():
        assert after[label]["faces"] == d["faces"]
        assert after[label]["area"] == pytest.approx(d["area"], abs=1e-4)
        assert after[label]["symbols"] == d["symbols"]
        assert after[label]["material"].color == pytest.approx(d["material"].color)
        assert after[label]["material"].opacity == pytest.approx(d["material"].opacity)
    wall = next(p for p in back.parts if p.label == "wall")
    assert Path(wall.material.texture) == out / "textures" / "brick.png"
    assert wall.mesh.corner_uvs is not None
    assert [p.shape_id for p in back.parts] == [p.shape_id for p in house.parts]


def test_polygons_stay_polygons(tmp_path: Path, house: Model):
    export(house, tmp_path / "h.obj")
    text = (tmp_path / "h.obj").read_text()
    sizes = sorted(len(line.split()) - 1 for line in text.splitlines() if line.startswith("f "))
    assert sizes == sorted(int(n) for p in house.parts for n in p.mesh.face_sizes)
    assert "mtllib h.mtl" in text and "usemtl glass" in text and "g Window" in text
    mtl = (tmp_path / "h.mtl").read_text()
    assert "map_Kd textures/brick.png" in mtl
    assert "Kd 0.2 0.4 0.6" in mtl and "d 0.5" in mtl


def test_unreadable_texture_is_skipped(tmp_path: Path, house_factory):
    written = export(house_factory(str(tmp_path / "missing.png")), tmp_path / "h.obj")
    assert written == [tmp_path / "h.obj", tmp_path / "h.mtl"]
    assert "map_Kd" not in (tmp_path / "h.mtl").read_text()
    assert not (tmp_path / "textures").exists()


def test_several_models(tmp_path: Path, house_factory):
    export([house_factory(name="left house"), house_factory(name="right")], tmp_path / "m.obj")
    assert [m.name for m in load(tmp_path / "m.obj")] == ["left_house", "right"]


def test_foreign_obj(tmp_path: Path):
    (tmp_path / "f.mtl").write_text("newmtl red\nKd 1 0 0\nTr 0.25\n")
    (tmp_path / "f.obj").write_text(
        "mtllib f.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"
        "g WindowFrame\nusemtl red\nf 1//1 2//1 3//1 4//1\n"
        "g Stuff\nf -4 -3 -2\n")
    (model,) = load(tmp_path / "f.obj")
    assert model.name == "f"
    assert [(p.symbol, p.label, p.mesh.n_faces) for p in model.parts] == [
        ("WindowFrame", "window", 1), ("Stuff", "", 1)]
    assert model.parts[0].material.color == (1.0, 0.0, 0.0)
    assert model.parts[0].material.opacity == pytest.approx(0.75)
    assert model.mesh().area() == pytest.approx(1.5)


def test_bad_face_index(tmp_path: Path):
    (tmp_path / "b.obj").write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="b.obj:2"):
        load(tmp_path / "b.obj")


def test_trimesh_reads_it(tmp_path: Path, house: Model):
    trimesh = pytest.importorskip("trimesh")
    export(house, tmp_path / "h.obj")
    scene = trimesh.load(tmp_path / "h.obj", force="scene", group_material=False)
    assert sum(g.area for g in scene.dump()) == pytest.approx(house.mesh().area(), rel=1e-5)


def test_material_names_survive_obj_comments(tmp_path: Path):
    """``#`` starts a comment in OBJ/MTL: colour-named materials must not begin with it."""
    import facadeforge as ff

    models = ff.derive("Lot --> extrude(3) color(\"#aa5533\") X.", lot_size="4x4")
    export(models, tmp_path / "m.obj")
    mtl = (tmp_path / "m.mtl").read_text()
    names = [line.split(None, 1)[1] for line in mtl.splitlines() if line.startswith("newmtl")]
    assert names and all("#" not in n for n in names)
    assert load(tmp_path / "m.obj")[0].parts[0].material.color == pytest.approx((0xaa / 255, 0x55 / 255, 0x33 / 255), abs=1e-3)


@pytest.mark.parametrize("tag, message", [
    ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ("[1]", "not an object"),
    ("{oops", "not valid JSON"),
])
def test_bad_attribute_lines(tmp_path: Path, tag: str, message: str):
    # the JSON of a tag line is parsed by facadeforge.jsonfile: a LoadError naming the line,
    # with the line itself shortened
    from facadeforge.exchange.errors import LoadError

    (tmp_path / "a.obj").write_text(f"o a\n# facadeforge attributes {tag}\nv 0 0 0\n")
    with pytest.raises(LoadError, match=message) as err:
        load(tmp_path / "a.obj")
    assert "a.obj:2" in str(err.value) and len(str(err.value)) < 400


@pytest.mark.parametrize("text, message", [
    ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "obj:3: cannot parse 'v nan 1 0' (nan is not a "
                                               "finite number"),
    ("v 0 0 0\nv 1 0 0\nv 1e300 1 0\nf 1 2 3\n", "obj:3: cannot parse 'v 1e300 1 0' (1e+300 is "
                                                 "not a finite number of magnitude at most 1e+09"),
    ("v 0 0 0\nv 1 0 0\nv 1 1\nf 1 2 3\n", "obj:3: cannot parse 'v 1 1' (3 numbers needed, "
                                           "got 2)"),
    ("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt inf 0\nf 1/1 2/1 3/1\n", "obj:4: cannot parse 'vt inf 0'"),
    ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n", "obj:4: cannot parse 'f 1 2 7' (index 7 refers to "
                                             "none of the 3 defined above the line)"),
    ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 0\n", "index 0 refers to none of the 3"),
    ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf\n", "obj:4: cannot parse 'f' (a face needs the numbers"),
])
def test_bad_numbers_and_missing_vertices_are_load_errors(tmp_path: Path, text: str,
                                                          message: str):
    from facadeforge.exchange.errors import LoadError

    (tmp_path / "m.obj").write_text(text)
    with pytest.raises(LoadError) as err:
        load(tmp_path / "m.obj")
    assert message in str(err.value)


def test_cli_render_reports_a_non_finite_obj_in_one_line(tmp_path: Path, capsys):
    from facadeforge.cli import main

    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    assert main(["render", str(tmp_path / "m.obj"), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("facadeforge: error: ") and "m.obj:3" in err and "\n" not in err
