"""Footprint files of the wrong shape are refused with the file and the JSON path named; honest
but big ones (thousands of courtyards, 100,000 corners) are read, and derive, in bounded work."""

import json

import numpy as np
import pytest

from facadeforge.cli import main
from facadeforge.errors import InputError
from facadeforge.geometry.footprints import load_footprints

SQUARE = [[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]


def _polygon(coordinates, **feature):
    return {"type": "Feature", "properties": {},
            "geometry": {"type": "Polygon", "coordinates": coordinates}, **feature}


def _write(tmp_path, doc, name="f.geojson"):
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


# the reproducers of the hostile-input issue, and their kin: (document, the message's JSON
# path and problem)
MALFORMED = [
    ({"type": "FeatureCollection", "features": [5]}, r"features\[0\] must be an object"),
    ({"type": "FeatureCollection", "features": 5}, "features must be an array"),
    ({"type": "Feature", "geometry": [1, 2], "properties": {}}, "geometry must be an object"),
    (_polygon([SQUARE], properties=[1]), "properties must be an object"),
    ({"type": "FeatureCollection", "crs": "EPSG:25832", "features": []}, "crs must be an object"),
    ({"type": "FeatureCollection", "crs": {"properties": {"name": 25832}}, "features": []},
     "crs.properties.name must be a string"),
    (_polygon({"a": 1}), "geometry.coordinates must be an array"),
    (_polygon([5]), r"geometry.coordinates\[0\] must be an array"),
    (_polygon([[[0, 0], [4, 0], [4, "3"], [0, 0]]]),
     r"geometry.coordinates\[0\]\[2\]\[1\] must be a number, not a string"),
    (_polygon([[[0, 0], [4, 0], [4, True], [0, 0]]]), r"\[2\]\[1\] must be a number, not a bool"),
    (_polygon([[[0, 0], [4, 0], [4, {"x": 1}], [0, 0]]]), r"\[2\]\[1\] must be a number"),
    (_polygon([[[0, 0], [4], [4, 3], [0, 0]]]), r"\[0\]\[1\] a position needs at least 2"),
    (_polygon([[[0, 0], [4, 0], [4, 1e12], [0, 0]]]), r"\[2\]\[1\] is 1000000000000.0, not a "
     "finite number"),
    (_polygon([[[0, 0], [4, 0], [4, 10**400], [0, 0]]]), r"\[2\]\[1\] is 1000.*not a finite"),
    ({"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "MultiPolygon",
                                         "coordinates": [[SQUARE], 7]}}]},
     r"features\[0\].geometry.coordinates\[1\] must be an array"),
    ({"type": 5}, "type must be a string"),
    ([1, 2], "the top level must be an object"),
]


@pytest.mark.parametrize("doc, message", MALFORMED)
def test_malformed_geojson_names_the_file_and_member(tmp_path, doc, message):
    p = _write(tmp_path, doc)
    with pytest.raises(InputError, match=message) as err:
        load_footprints(p)
    assert str(p) in str(err.value)


def test_non_finite_coordinates_are_refused(tmp_path):
    # Python's json reads NaN and Infinity, which RFC 8259 does not allow
    for literal in ("NaN", "Infinity", "-Infinity"):
        p = _write(tmp_path, '{"type": "Polygon", "coordinates": [[[0, 0], [4, 0], '
                   f'[4, {literal}], [0, 0]]]}}')
        with pytest.raises(InputError, match=r"coordinates\[0\]\[2\]\[1\] is .*not a finite"):
            load_footprints(p)


def test_deeply_nested_json_is_an_input_error(tmp_path):
    p = _write(tmp_path, "[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError, match="nested too deeply") as err:
        load_footprints(p)
    assert str(p) in str(err.value)


def test_byte_order_mark_is_accepted(tmp_path):
    p = tmp_path / "bom.geojson"
    p.write_text(json.dumps(_polygon([SQUARE])), encoding="utf-8-sig")
    assert p.read_bytes().startswith(b"\xef\xbb\xbf")
    (fp,) = load_footprints(p)
    assert len(fp.polygon) == 4


def test_honest_variants_still_read(tmp_path):
    # null features and geometries are skipped, positions may mix 2 and 3 values, names must
    # be text or numbers
    doc = {"type": "FeatureCollection", "features": [
        None, {"type": "Feature", "geometry": None},
        {"type": "Feature", "properties": {"name": ["not", "a", "name"], "id": 7},
         "geometry": {"type": "Polygon",
                      "coordinates": [[[0, 0, 1], [4, 0], [4, 3, 1], [0, 3], [0, 0, 1]]]}}]}
    (fp,) = load_footprints(_write(tmp_path, doc))
    assert fp.name == "7"
    assert fp.polygon.shape == (4, 3)


def test_cli_reports_malformed_footprints_in_one_line(tmp_path, capsys):
    rules = tmp_path / "x.cga"
    rules.write_text("Lot --> X.\n")
    p = _write(tmp_path, {"type": "FeatureCollection", "features": [5]})
    code = main(["derive", str(rules), "--footprint", str(p), "-o", str(tmp_path / "o.glb")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("facadeforge: error: footprint file") and "features[0]" in err
    assert "\n" not in err


@pytest.mark.parametrize("text, message", [
    ("v 1 2 0\nf 1 2 3\n", "vertex that does not exist"),
    ("v 1 2\nf 1 2 3\n", "a vertex needs 3 numbers, this one has 2"),
    ("v 0 0 0\nv a b c\n", "malformed OBJ line"),
    ("", "no faces"),
    ("v 0 0 0\nv 1 0 0\nv 1 0 1\nf 1 2 9\n", "vertex that does not exist"),
])
def test_garbage_obj_footprints_are_input_errors(tmp_path, text, message):
    p = tmp_path / "f.obj"
    p.write_text(text)
    with pytest.raises(InputError, match=message):
        load_footprints(p)


@pytest.mark.parametrize("value, message", [
    ("nan", "f.obj:3: coordinate nan is not a finite number of magnitude at most 1e+09"),
    ("1e300", "f.obj:3: coordinate 1e+300 is not a finite number of magnitude at most 1e+09"),
    ("-2e9", "f.obj:3: coordinate -2e+09 is not a finite number"),
])
def test_obj_footprints_with_absurd_numbers_say_so(tmp_path, value, message):
    """The reproducer: such a vertex made the footprint 'hold no horizontal polygon'."""
    p = tmp_path / "f.obj"
    p.write_text(f"v 0 0 0\nv 4 0 0\nv {value} 0 3\nv 0 0 3\nf 1 2 3 4\n")
    with pytest.raises(InputError) as err:
        load_footprints(p)
    assert message in str(err.value) and "horizontal" not in str(err.value)


def test_cli_derive_reports_a_non_finite_obj_footprint(tmp_path, capsys):
    rules = tmp_path / "x.cga"
    rules.write_text("Lot --> X.\n")
    p = tmp_path / "lots.obj"
    p.write_text("v 0 0 0\nv 4 0 0\nv NaN 0 3\nf 1 2 3\n")
    code = main(["derive", str(rules), "--footprint", str(p), "-o", str(tmp_path / "o.glb")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "lots.obj:3: coordinate nan is not a finite number" in err


def test_obj_texture_vertices_with_one_number_still_read(tmp_path):
    p = tmp_path / "f.obj"
    p.write_text("v 0 0 0\nv 4 0 0\nv 4 0 -3\nvt 0.5\nvt 1\nvt 0\nf 1/1 2/2 3/3\n")
    (fp,) = load_footprints(p)
    assert len(fp.polygon) == 3


def _holed_square(n: int = 40, size: float = 400.0, hole: float = 2.0) -> dict:
    """A square lot with an n × n grid of square courtyards (holes)."""
    step = size / (n + 1)
    holes = [[[x, y], [x, y + hole], [x + hole, y + hole], [x + hole, y], [x, y]]
             for x in step * np.arange(1, n + 1) for y in step * np.arange(1, n + 1)]
    outer = [[0, 0], [size, 0], [size, size], [0, size], [0, 0]]
    return {"type": "Polygon", "coordinates": [outer, *[[list(map(float, q)) for q in h]
                                                       for h in holes]]}


def test_many_courtyards_derive_into_one_holed_lot(tmp_path):
    # one overlay for all the holes (engine._holed_face): 1,600 courtyards, each kept
    from facadeforge import derive, load_rules
    from facadeforge.geometry.holed import HOLED

    p = _write(tmp_path, _holed_square())
    (fp,) = load_footprints(p)
    assert len(fp.holes) == 1600
    (model,) = derive(load_rules("Lot --> X."), p)
    mesh = model.parts[0].mesh
    assert mesh.area() == pytest.approx(400.0**2 - 1600 * 4.0)
    assert len(set(mesh.column(HOLED))) == 1  # the pieces of one face


def test_large_round_outline_triangulates_completely(tmp_path):
    # above EARCUT_MAX_CORNERS the GEOS triangulation serves (earcut took 12 s on 100,000
    # corners): k - 2 triangles, facing as the polygon does, covering it exactly
    from facadeforge.geometry.mesh import EARCUT_MAX_CORNERS, polygon_area, triangulate_polygon

    k = 3 * EARCUT_MAX_CORNERS
    t = np.arange(k) * 2 * np.pi / k
    poly = np.column_stack([100 * np.cos(t), np.zeros(k), -100 * np.sin(t)])
    tris = triangulate_polygon(poly)
    assert tris.shape == (k - 2, 3)
    e1, e2 = poly[tris[:, 1]] - poly[tris[:, 0]], poly[tris[:, 2]] - poly[tris[:, 0]]
    normals = np.cross(e1, e2)
    assert (normals[:, 1] > 0).all()  # all facing as the polygon does (up)
    assert 0.5 * normals[:, 1].sum() == pytest.approx(polygon_area(poly))
