"""Rule files, imports, rule packages (.rpk), assets and their confinement, initial shapes."""

import json

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import InputError, RuleError
from facadeforge.geometry.footprints import load_footprints

CUBE_OBJ = """v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nv 0 0 1\nv 2 0 1\nv 2 1 1\nv 0 1 1
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 2 3 7 6\nf 1 5 8 4
"""


def write_project(root):
    (root / "rules").mkdir()
    (root / "assets").mkdir()
    (root / "assets" / "box.obj").write_text(CUBE_OBJ)
    (root / "rules" / "facade.cga").write_text(
        'attr floorH = 3\n'
        'attr tag = "f"\n'
        'Facade --> split(y) { { ~floorH : Floor }* }\n'
        'Floor --> report("floors", 1) report("tag", tag) i("/Proj/assets/box.obj")\n')
    (root / "rules" / "main.cga").write_text(
        'version "2019.0"\n'
        'import F : "facade.cga"\n'
        'attr height = 9\n'
        'attr floorH = 4.5\n'
        '@StartRule\n'
        'Lot --> extrude(height) comp(f) { front : F.Facade | all : NIL }\n')
    return root / "rules" / "main.cga"


def pack(folder, rpk):
    import py7zr

    with py7zr.SevenZipFile(rpk, "w") as z:
        for f in sorted(folder.rglob("*")):
            if f.is_file():
                z.write(f, arcname=str(f.relative_to(folder)))


def test_import_qualified_rules_and_attribute_propagation(tmp_path):
    main = write_project(tmp_path)
    m = derive(main, lot_size="10x6", assets=tmp_path / "assets")[0]
    # floorH propagates from the importer (4.5 on 9 m: two floors)
    assert len(m.reports["floors"]) == 2 and m.reports["tag"] == ["f", "f"]
    assert not m.warnings
    # the inserted box fills each floor tile scope (10 x 4.5, depth from proportions)
    assert len(m.parts) == 2 and all(p.mesh.n_faces == 6 for p in m.parts)


def test_qualified_attribute_override(tmp_path):
    main = write_project(tmp_path)
    m = derive(main, lot_size="10x6", assets=tmp_path / "assets",
               attrs={"height": "12", "F.tag": "g"})[0]
    assert m.reports["tag"] == ["g"] * 3


def test_rule_package(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    write_project(src)
    (src / "rules" / "main.cgb").write_bytes(b"compiled")
    (src / ".resolvemap.xml").write_text(
        '<resolvemap><entry key="/Proj/assets/box.obj" value="assets/box.obj"/></resolvemap>')
    rpk = tmp_path / "pkg.rpk"
    pack(src, rpk)
    m = derive(rpk, lot_size="10x6")[0]
    assert len(m.reports["floors"]) == 2 and not m.warnings
    # --rule picks another file; a wrong name is a clear error
    with pytest.raises(InputError, match="rule files"):
        load_rules(rpk, rule="rules/nope.cga")


def test_rule_package_main_rule_found_by_its_compiled_twin_in_bin(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    write_project(src)
    (src / "rules" / "other.cga").write_text("@StartRule\nLot --> X.\n")
    (src / "bin").mkdir()
    (src / "bin" / "main.cgb").write_bytes(b"compiled")
    rpk = tmp_path / "pkg.rpk"
    pack(src, rpk)
    assert load_rules(rpk).source.endswith("main.cga")


def test_rule_package_with_only_compiled_rules_is_refused(tmp_path):
    src = tmp_path / "src"
    (src / "rules").mkdir(parents=True)
    (src / "rules" / "main.cgb").write_bytes(b"\0compiled")
    rpk = tmp_path / "bin.rpk"
    pack(src, rpk)
    with pytest.raises(InputError, match="Include CGA source"):
        load_rules(rpk)


def test_corrupt_rule_package(tmp_path):
    bad = tmp_path / "bad.rpk"
    bad.write_bytes(b"not a 7z archive")
    with pytest.raises(InputError, match="not a readable rule package"):
        load_rules(bad)


def test_asset_paths_stay_inside_the_root(tmp_path):
    (tmp_path / "assets").mkdir()
    (tmp_path / "secret.obj").write_text(CUBE_OBJ)
    rules = load_rules('Lot --> i("../secret.obj") X', assets=tmp_path / "assets")
    m = derive(rules, lot_size="4x4")[0]
    assert any("leaves the asset root" in w for w in m.warnings)
    assert m.parts[0].mesh.n_faces == 1  # the lot polygon, untouched


def test_missing_import_is_a_rule_error(tmp_path):
    p = tmp_path / "a.cga"
    p.write_text('import G : "nope.cga"\nLot --> X\n')
    with pytest.raises(RuleError, match="cannot import 'nope.cga'"):
        load_rules(p)


def test_obj_and_geojson_footprints(tmp_path):
    obj = tmp_path / "lots.obj"
    obj.write_text("v 0 0 0\nv 10 0 0\nv 10 0 -5\nv 0 0 -5\nf 1 2 3 4\n"
                   "v 20 0 0\nv 20 0 -5\nv 30 0 -5\nv 30 0 0\nf 5 6 7 8\n")
    fps = load_footprints(obj)
    assert len(fps) == 2
    for fp in fps:  # both oriented up, whatever their winding in the file
        from facadeforge.geometry.mesh import polygon_normal

        assert polygon_normal(fp.polygon)[1] == pytest.approx(1.0)
    gj = tmp_path / "lots.geojson"
    gj.write_text(json.dumps({"type": "Feature", "properties": {"height": 7},
                              "geometry": {"type": "Polygon",
                                           "coordinates": [[[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]]}}))
    m = derive(load_rules("attr height = 1\nLot --> extrude(height) X."), gj)[0]
    # feature properties set same-named attributes, as CityEngine's object attributes do
    assert m.stats()["bbox"][1][1] == pytest.approx(7)
    assert m.stats()["bbox"][0][2] == pytest.approx(-3)


def test_bad_footprints(tmp_path):
    p = tmp_path / "x.geojson"
    p.write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        load_footprints(p)
    p.write_text(json.dumps({"type": "Point", "coordinates": [0, 0]}))
    with pytest.raises(InputError, match="expected a GeoJSON Polygon"):
        load_footprints(p)
    (tmp_path / "x.shp").write_text("")
    with pytest.raises(InputError, match=".geojson, .json or .obj"):
        load_footprints(tmp_path / "x.shp")


def test_far_coordinates_are_recentred(tmp_path):
    gj = tmp_path / "utm.geojson"
    x0, y0 = 500000.0, 5400000.0
    ring = [[x0, y0], [x0 + 10, y0], [x0 + 10, y0 + 8], [x0, y0 + 8], [x0, y0]]
    gj.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    fp = load_footprints(gj)[0]
    assert np.abs(fp.polygon).max() < 100
    assert fp.attributes["_origin_offset"] == [x0, 0.0, -y0]


def test_unsafe_member_paths_are_refused(tmp_path):
    import py7zr

    (tmp_path / "evil.cga").write_text("Lot --> X\n")
    rpk = tmp_path / "evil.rpk"
    with py7zr.SevenZipFile(rpk, "w") as z:
        z.write(tmp_path / "evil.cga", arcname="../evil.cga")
    with pytest.raises(InputError, match="unsafe member path"):
        load_rules(rpk)
