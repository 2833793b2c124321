"""Materials as string arrays: setMaterial, getMaterial, readMaterial (CityEngine 2021.0+),
checked against the examples of their reference pages."""

from PIL import Image

from facadeforge import derive, load_rules


def prints(src, assets=None):
    m = derive(load_rules(src, assets=assets), None, lot_size="4x4")[0]
    assert not m.warnings, m.warnings
    return m.attributes["prints"], m


def test_get_material_after_setting_colour_as_in_the_reference():
    out, _ = prints("Lot --> color(0.5, 0.6, 0.7) print(getMaterial(used, changed)) X.")
    assert out == ["(3x2)\n   color.b   0.7\n   color.g   0.6\n   color.r   0.5"]


def test_set_material_from_pairs_sets_each_attribute():
    src = ('myMaterial = [ "color.r", "1.0", "color.g", "0.0", "color.b", "0.0",\n'
           '               "opacitymap", "builtin:default" ]\n'
           'Lot --> texture("x.png") setMaterial(myMaterial) print(material.color.g) '
           'setMaterial(["colormap", "builtin:default"]) print(material.colormap) X.')
    out, m = prints(src)
    assert out == ["0", ""]
    assert m.parts[0].material.color == (1.0, 0.0, 0.0) and m.parts[0].material.texture is None


def test_get_material_round_trips_through_set_material():
    src = ("Lot --> color(0.2, 0.4, 0.6) set(material.opacity, 0.5) A\n"
           "A --> setMaterial(getMaterial(shape, all)) print(getMaterial()) X.")
    out, m = prints(src)
    # every attribute getMaterial(…, all) gave is now set on the shape, so "changed" lists them
    rows = [r.split() for r in out[0].splitlines()[1:]]
    assert ["opacity", "0.5"] in rows and ["color.r", "0.2"] in rows and len(rows) > 10
    assert m.parts[0].material.color == (0.2, 0.4, 0.6) and m.parts[0].material.opacity == 0.5


def test_read_material_from_mtl_and_from_a_table(tmp_path):
    Image.new("RGB", (2, 2), (200, 100, 50)).save(tmp_path / "brick.png")
    (tmp_path / "brick.mtl").write_text("newmtl brick\nKd 0.6 0.3 0.2\nd 0.9\nmap_Kd brick.png\n"
                                        "newmtl other\nKd 0 0 1\n")
    (tmp_path / "red.csv").write_text("color.r,1\ncolor.g,0.5\ncolor.b,0\n")
    out, m = prints('Lot --> setMaterial(readMaterial("brick.mtl")) print(material.name) A\n'
                    'A --> setMaterial(readStringTable("red.csv")) X.', assets=tmp_path)
    assert out == ["brick"]
    mat = m.parts[0].material
    assert mat.color == (1.0, 0.5, 0.0) and mat.opacity == 0.9
    assert mat.texture == str((tmp_path / "brick.png").resolve())


def test_material_misuse_is_a_warning(tmp_path):
    (tmp_path / "x.txt").write_text("a")
    for src, message in [
        ('Lot --> setMaterial(["color.r"]) X.', "a name without a value"),
        ('Lot --> setMaterial([1,2,3;4,5,6]) X.', "two columns (name, value), not 3"),
        ('Lot --> print(getMaterial(nothing)) X.', "getMaterial(used|shape|geometry"),
        ('Lot --> print(readMaterial("x.txt")) X.', "reads .mtl and .cgamat files"),
        ('Lot --> print(readMaterial("none.mtl")) X.', "'none.mtl' not found"),
    ]:
        m = derive(load_rules(src, assets=tmp_path), None, lot_size="4x4")[0]
        assert any(message in w for w in m.warnings), (src, m.warnings)
