"""CityJSON 2.0 export, schema validation and reading back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from facadeforge.exchange import EXPORTERS, ExportError, export, load
from facadeforge.exchange.cityjson import DEFAULT_SEMANTIC_MAP, SEMANTIC_TYPES, export_cityjson
from facadeforge.model import Labels, Model


def _errors(validator, doc) -> list[str]:
    return [f"{list(e.absolute_path)}: {e.message}" for e in validator.iter_errors(doc)]


def _export(tmp_path: Path, models, **options) -> dict:
    export(models, tmp_path / "out.city.json", **options)
    return json.loads((tmp_path / "out.city.json").read_text())


def _real_vertices(doc: dict) -> np.ndarray:
    tr = doc["transform"]
    return np.asarray(doc["vertices"]) * tr["scale"] + tr["translate"]


def test_registered_and_suffix(tmp_path: Path, house: Model):
    assert EXPORTERS["city.json"] is export_cityjson
    assert export(house, tmp_path / "a.city.json") == [tmp_path / "a.city.json",
                                                        tmp_path / "textures" / "brick.png"]


def test_schema_valid(tmp_path: Path, house: Model, house_factory, validator):
    doc = _export(tmp_path, [house, house_factory(name="other"), Model(name="empty")],
                  reference_system="EPSG:7415",
                  metadata={"title": "test", "pointOfContact": {
                      "contactName": "Ada", "emailAddress": "ada@example.org"}})
    assert _errors(validator, doc) == []
    assert doc["version"] == "2.0"
    assert doc["metadata"]["referenceSystem"] == "https://www.opengis.net/def/crs/EPSG/0/7415"
    assert set(doc["CityObjects"]) == {"house", "other", "empty"}
    assert "geometry" not in doc["CityObjects"]["empty"]


def test_schema_rejects_broken_files(tmp_path: Path, house: Model, validator):
    doc = _export(tmp_path, house)
    broken = json.loads(json.dumps(doc))
    del broken["transform"]
    assert _errors(validator, broken)
    broken = json.loads(json.dumps(doc))
    broken["CityObjects"]["house"]["geometry"][0]["lod"] = "7"
    assert _errors(validator, broken)
    broken = json.loads(json.dumps(doc))
    broken["CityObjects"]["house"]["geometry"][0]["semantics"]["surfaces"][0]["type"] = "Roof"
    assert _errors(validator, broken)


def test_geometry_semantics_and_axes(tmp_path: Path, house: Model):
    doc = _export(tmp_path, house)
    assert doc["transform"]["scale"] == [0.001] * 3
    assert all(isinstance(v, int) for row in doc["vertices"] for v in row)
    obj = doc["CityObjects"]["house"]
    assert obj["type"] == "Building"
    assert obj["attributes"] == {"height": 6.0, "floors": 2, "style": "test"}
    (geom,) = obj["geometry"]
    assert geom["type"] == "MultiSurface" and geom["lod"] == "3"
    n_faces = sum(p.mesh.n_faces for p in house.parts)
    assert len(geom["boundaries"]) == len(geom["semantics"]["values"]) == n_faces
    surfaces = geom["semantics"]["surfaces"]
    kinds = {s["facadeforge_label"]: s["type"] for s in surfaces}
    assert kinds == {"wall": "WallSurface", "roof": "RoofSurface", "ground": "GroundSurface",
                     "window": "Window", "door": "Door", "deco": "WallSurface"}
    real = _real_vertices(doc)
    # CGA y (height 6 m) is CityJSON z; CGA z (depth 4 m) is CityJSON -y.
    assert real[:, 2].max() == pytest.approx(6.0)
    assert real[:, 1].min() == pytest.approx(-4.01) and real[:, 1].max() == pytest.approx(0.0)
    # rings stay counter-clockwise seen from outside: the roof's normal points up
    roof = next(i for i, v in enumerate(geom["semantics"]["values"])
                if surfaces[v]["type"] == "RoofSurface")
    ring = real[geom["boundaries"][roof][0]]
    assert np.cross(ring[1] - ring[0], ring[2] - ring[1])[2] > 0
    area = sum(np.linalg.norm(sum(np.cross(p[i], p[(i + 1) % len(p)]) for i in range(len(p)))) / 2
               for p in (real[s[0]] for s in geom["boundaries"]))
    assert area == pytest.approx(house.mesh().area(), abs=1e-3)


def test_appearance(tmp_path: Path, house: Model):
    doc = _export(tmp_path, house)
    app = doc["appearance"]
    glass = next(m for m in app["materials"] if m["name"] == "glass")
    assert glass["diffuseColor"] == pytest.approx([0.2, 0.4, 0.6])
    assert glass["transparency"] == pytest.approx(0.5)
    assert app["textures"] == [{"type": "PNG", "image": "textures/brick.png", "wrapMode": "wrap"}]
    geom = doc["CityObjects"]["house"]["geometry"][0]
    textured = [v for v in geom["texture"]["facadeforge"]["values"] if v != [[None]]]
    assert len(textured) == 4 and all(len(v[0]) == 5 for v in textured)
    assert len(app["vertices-texture"]) == 16


def test_semantic_map_option(tmp_path: Path, house: Model, validator):
    doc = _export(tmp_path, house, semantic_map={"deco": "+Ornament", "ground": None})
    assert _errors(validator, doc) == []
    geom = doc["CityObjects"]["house"]["geometry"][0]
    types = {s["type"] for s in geom["semantics"]["surfaces"]}
    assert "+Ornament" in types and "GroundSurface" not in types
    assert None in geom["semantics"]["values"]
    with pytest.raises(ExportError, match="semantic surface type"):
        export(house, tmp_path / "x.city.json", semantic_map={"deco": "Ornament"})
    assert not (tmp_path / "x.city.json").exists()


def test_default_map_covers_every_label():
    assert {label.value for label in Labels} <= set(DEFAULT_SEMANTIC_MAP)
    assert set(DEFAULT_SEMANTIC_MAP.values()) <= SEMANTIC_TYPES


def test_origin_and_options(tmp_path: Path, house: Model, validator):
    doc = _export(tmp_path, house, origin=(85000.0, 446000.0, -2.0), scale=0.01, lod="2.2",
                  textures=False)
    assert _errors(validator, doc) == []
    real = _real_vertices(doc)
    assert real[:, 0].min() == pytest.approx(85000.0) and real[:, 2].min() == pytest.approx(-2.0)
    assert "textures" not in doc["appearance"]
    with pytest.raises(ExportError, match="level of detail"):
        export(house, tmp_path / "y.city.json", lod="5")
    with pytest.raises(ExportError, match="EPSG"):
        export(house, tmp_path / "y.city.json", reference_system="wgs84")


def test_read_back(tmp_path: Path, house: Model):
    export(house, tmp_path / "h.city.json")
    (back,) = load(tmp_path / "h.city.json")
    assert back.name == "house"
    assert back.mesh().area() == pytest.approx(house.mesh().area(), abs=1e-3)
    assert sum(p.mesh.n_faces for p in back.parts) == sum(p.mesh.n_faces for p in house.parts)
    colors = {p.label: p.material.color for p in back.parts}
    assert colors["roof"] == pytest.approx((0.6, 0.2, 0.1))
    wall = next(p for p in back.parts if p.label == "wall")
    assert Path(wall.material.texture) == tmp_path / "textures" / "brick.png"
    assert np.allclose(back.mesh().bounds(), house.mesh().bounds(), atol=1e-3)


def test_faces_with_holes_are_surfaces_with_inner_rings(tmp_path: Path, validator):
    """A courtyard block's top and bottom are one surface each, outline and hole, the hole
    turning the other way; read back they are again pieces of one face with a hole."""
    from facadeforge import derive, load_rules
    from facadeforge.geometry.footprints import load_footprints
    from facadeforge.geometry.mesh import polygon_normal

    geo = tmp_path / "block.geojson"
    geo.write_text(json.dumps({"type": "Polygon", "coordinates": [
        [[0, 0], [30, 0], [30, 20], [0, 20], [0, 0]],
        [[10, 5], [10, 15], [20, 15], [20, 5], [10, 5]]]}))
    (model,) = derive(load_rules("Lot --> extrude(10) color(0.8, 0.7, 0.6) X."),
                      load_footprints(geo))
    doc = _export(tmp_path, model)
    assert _errors(validator, doc) == []
    surfaces = next(iter(doc["CityObjects"].values()))["geometry"][0]["boundaries"]
    holed = [s for s in surfaces if len(s) > 1]
    assert len(surfaces) == 10 and len(holed) == 2       # 8 walls, the top and the bottom
    verts = _real_vertices(doc)
    for outer, hole in holed:
        n_outer, n_hole = polygon_normal(verts[outer]), polygon_normal(verts[hole])
        assert n_outer @ n_hole == pytest.approx(-1)      # the hole turns the other way
    (back,) = load(tmp_path / "out.city.json")
    assert back.mesh().area() == pytest.approx(model.mesh().area(), abs=1e-3)
    assert back.mesh().area() == pytest.approx(2 * (600 - 100) + 10 * (100 + 40))
    (part,) = back.parts
    assert len({h for h in part.mesh.column("holed") if h is not None}) == 2  # top, bottom


def test_textures_on_faces_with_holes_and_beside_plain_surfaces(tmp_path: Path, validator):
    """A textured courtyard roof references texture vertices for its outline and its hole; the
    plain bottom and the upper walls are ``[[None]]``; every reference has one texture vertex
    per ring corner, numbered in order."""
    from PIL import Image

    from facadeforge import derive, load_rules
    from facadeforge.geometry.footprints import load_footprints

    Image.new("RGB", (8, 8), (200, 100, 50)).save(tmp_path / "brick.png")
    geo = tmp_path / "block.geojson"
    geo.write_text(json.dumps({"type": "Polygon", "coordinates": [
        [[0, 0], [30, 0], [30, 20], [0, 20], [0, 0]],
        [[10, 5], [10, 15], [20, 15], [20, 5], [10, 5]]]}))
    rules = load_rules(
        'Lot --> extrude(9) comp(f) { top : Top | bottom : color("#888888") X. | side : Side }\n'
        'Top --> setupProjection(0, scope.xy, 4, 4) projectUV(0) texture("brick.png")\n'
        'Side --> split(y) { 3 : setupProjection(0, scope.xy, 2, 2) projectUV(0) '
        'texture("brick.png") | ~1 : color("#aa0000") X. }\n', assets=tmp_path)
    (model,) = derive(rules, load_footprints(geo))
    doc = _export(tmp_path, model)
    assert _errors(validator, doc) == []
    geom = next(iter(doc["CityObjects"].values()))["geometry"][0]
    values = geom["texture"]["facadeforge"]["values"]
    assert len(values) == len(geom["boundaries"]) == 18       # top, bottom, 8 × 2 wall bands
    numbers = []
    for surface, refs in zip(geom["boundaries"], values):
        if refs == [[None]]:
            continue
        assert len(refs) == len(surface)
        for ring, ref in zip(surface, refs):
            assert ref[0] == 0 and len(ref) == len(ring) + 1
            numbers += ref[1:]
    holed = [refs for s, refs in zip(geom["boundaries"], values) if len(s) == 2]
    assert len(holed) == 2 and sum(r != [[None]] for r in holed) == 1  # the top only
    assert sum(r != [[None]] for r in values) == 9                   # top and 8 lower bands
    assert numbers == list(range(len(numbers))) == list(range(len(doc["appearance"]
                                                                   ["vertices-texture"])))


def test_hostile_json_is_a_load_error(tmp_path: Path):
    # both readers parse through facadeforge.jsonfile: deep nesting names the file (and line)
    from facadeforge.exchange.errors import LoadError

    deep = "[" * 100_000 + "]" * 100_000
    (tmp_path / "d.city.json").write_text(deep)
    with pytest.raises(LoadError, match="d.city.json': JSON nested too deeply"):
        load(tmp_path / "d.city.json")
    head = json.dumps({"type": "CityJSON", "version": "2.0", "CityObjects": {}, "vertices": []})
    (tmp_path / "d.city.jsonl").write_text(head + "\n" + deep + "\n")
    with pytest.raises(LoadError, match=r"d.city.jsonl':2: JSON nested too deeply"):
        load(tmp_path / "d.city.jsonl")
    (tmp_path / "b.city.json").write_text(head, encoding="utf-8-sig")
    assert load(tmp_path / "b.city.json") == []


# -- hostile and careless files: every member read is checked ------------------------------

def _doc() -> dict:
    """A tiny CityJSON document: one square MultiSurface with semantics, a material, a texture
    (unit scale, so the vertex indices are the coordinates)."""
    return {"type": "CityJSON", "version": "2.0",
            "transform": {"scale": [1, 1, 1], "translate": [0, 0, 0]},
            "vertices": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
            "appearance": {"materials": [{"name": "m", "diffuseColor": [1, 0, 0]}],
                           "textures": [{"type": "PNG", "image": "t.png"}],
                           "vertices-texture": [[0, 0], [1, 0], [1, 1], [0, 1]]},
            "CityObjects": {"b": {"type": "Building", "geometry": [{
                "type": "MultiSurface", "lod": "2", "boundaries": [[[0, 1, 2, 3]]],
                "semantics": {"surfaces": [{"type": "RoofSurface"}], "values": [0]},
                "material": {"t": {"values": [0]}},
                "texture": {"t": {"values": [[[0, 0, 1, 2, 3]]]}}}]}}}


def _load_doc(tmp_path: Path, doc) -> list[Model]:
    (tmp_path / "x.city.json").write_text(json.dumps(doc))
    return load(tmp_path / "x.city.json")


def _set(doc: dict, path: tuple, value) -> dict:
    target = doc
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return doc


def test_tiny_document_reads(tmp_path: Path):
    (model,) = _load_doc(tmp_path, _doc())
    (part,) = model.parts
    assert part.label == "roof" and part.material.color == (1.0, 0.0, 0.0)
    assert part.mesh.area() == pytest.approx(1.0)


G = ("CityObjects", "b", "geometry", 0)


@pytest.mark.parametrize("path, value, where", [
    (("CityObjects",), 5, "CityObjects must be an object, not a number"),  # the reproducer
    (("CityObjects", "b"), [], 'CityObjects["b"] must be an object, not an array'),
    (("CityObjects", "b", "geometry"), {}, 'CityObjects["b"].geometry must be an array'),
    (G, 5, 'CityObjects["b"].geometry[0] must be an object'),
    ((*G, "lod"), [2], ".lod must be a string"),
    ((*G, "boundaries"), 5, ".boundaries must be an array"),
    ((*G, "boundaries", 0), [], ".boundaries[0] a surface needs at least one ring"),
    ((*G, "boundaries", 0, 0), [0, 1], ".boundaries[0][0] must hold at least 3 indices"),
    ((*G, "boundaries", 0, 0, 2), 99, ".boundaries[0][0][2] is 99, but the file has 4 vertices"),
    ((*G, "boundaries", 0, 0, 2), -1, ".boundaries[0][0][2] is -1"),
    ((*G, "boundaries", 0, 0, 2), 1.5, ".boundaries[0][0][2] must be an integer"),
    ((*G, "boundaries", 0, 0, 2), True, ".boundaries[0][0][2] must be an integer"),
    ((*G, "semantics", "values", 0), 3, ".semantics.values[0] is 3, but the file has 1 semantic"),
    ((*G, "semantics", "values"), [0, 0], ".semantics.values has 2 values for 1 surfaces"),
    ((*G, "semantics", "surfaces", 0), "Roof", ".semantics.surfaces[0] must be an object"),
    ((*G, "semantics", "surfaces", 0, "type"), 7, ".semantics.surfaces[0].type must be a string"),
    ((*G, "material", "t", "values", 0), 1, 'material["t"].values[0] is 1, but the file has 1'),
    ((*G, "material", "t"), 0, 'material["t"] must be an object'),
    ((*G, "texture", "t", "values", 0, 0, 0), 2, 'texture["t"].values[0][0][0] is 2'),
    ((*G, "texture", "t", "values", 0, 0), [0, 0, 1], "has 2 texture vertices for a ring of 4"),
    ((*G, "texture", "t", "values", 0, 0, 4), 9, "values[0][0][4] is 9, but the file has 4 "
                                                  "texture vertices"),
    (("vertices",), {"a": 1}, "vertices must be an array"),
    (("vertices", 1), [1, 0], "vertices[1] must hold 3 numbers, not 2"),
    (("vertices", 1, 0), "1", "vertices[1][0] must be a number, not a string"),
    (("vertices", 1, 0), float("nan"), "vertices[1][0] is nan, not a finite number"),
    (("vertices", 1, 0), 10**400, "vertices[1][0] is 100000000000…, not a finite number"),
    (("vertices", 1, 0), 10**10, "vertices[1] lies at [10000000000.0, 0.0, 0.0] once transformed"),
    (("transform",), [1], "transform must be an object"),
    (("transform", "scale"), [1, 1], "transform.scale must hold 3 numbers, not 2"),
    (("transform", "scale", 0), 0, "transform.scale must not hold 0"),
    (("transform", "translate", 2), None, "transform.translate[2] must be a number"),
    (("transform", "scale", 0), 1e300, "vertices[1] lies at [1e+300"),
    (("appearance",), [], "appearance must be an object"),
    (("appearance", "materials", 0, "diffuseColor"), [2, 0, 0],
     "diffuseColor[0] is 2, not a finite number within [0, 1]"),
    (("appearance", "materials", 0, "transparency"), "clear", "transparency must be a number"),
    (("appearance", "textures", 0, "image"), 5, "textures[0].image must be a string"),
    (("appearance", "vertices-texture", 2), [1, float("inf")],
     "vertices-texture[2][1] is inf"),
])
def test_malformed_members_are_load_errors_naming_their_json_path(tmp_path: Path, path,
                                                                  value, where):
    from facadeforge.exchange.errors import LoadError

    with pytest.raises(LoadError) as err:
        _load_doc(tmp_path, _set(_doc(), path, value))
    message = str(err.value)
    assert where in message
    assert message.startswith(f"CityJSON file '{tmp_path / 'x.city.json'}': ")
    assert message.endswith("fix the file (CityJSON 2.0)") and len(message) < 400


def test_solid_values_are_checked_per_shell(tmp_path: Path):
    from facadeforge.exchange.errors import LoadError

    doc = _doc()
    geom = doc["CityObjects"]["b"]["geometry"][0]
    geom.update(type="Solid", boundaries=[geom["boundaries"]], semantics={
        "surfaces": [{"type": "RoofSurface"}], "values": [None]},
        material={"t": {"values": [[0]]}}, texture={"t": {"values": [[[[0, 0, 1, 2, 3]]]]}})
    (model,) = _load_doc(tmp_path, doc)        # a null shell of semantics: no semantics
    assert model.parts[0].mesh.area() == pytest.approx(1.0)
    geom["material"]["t"]["values"] = [[0, 0]]
    with pytest.raises(LoadError, match=r'material\["t"\].values\[0\] has 2 values for 1 '):
        _load_doc(tmp_path, doc)


def test_a_surface_with_holes_and_a_flat_outline_reads(tmp_path: Path):
    doc = _doc()
    doc["vertices"] += [[0, 0, 0], [2, 2, 0]]
    _set(doc, (*G, "boundaries"), [[[0, 1, 2, 3], [4, 4, 5]]])   # the hole has no area
    _set(doc, (*G, "texture", "t", "values"), [[[0, 0, 1, 2, 3]]])
    (model,) = _load_doc(tmp_path, doc)
    assert model.parts[0].mesh.area() == pytest.approx(1.0)
    _set(doc, (*G, "boundaries"), [[[0, 1, 0], [1, 2, 3]]])     # the outline has no area
    _set(doc, (*G, "texture", "t", "values"), [[[None]]])
    (model,) = _load_doc(tmp_path, doc)
    assert model.parts[0].mesh.area() == pytest.approx(0.0)


def test_sequence_features_are_checked_naming_the_line(tmp_path: Path):
    from facadeforge.exchange.errors import LoadError

    head = {"type": "CityJSON", "version": "2.0", "CityObjects": {}, "vertices": [],
            "transform": {"scale": [1, 1, 1], "translate": [0, 0, 0]}}
    feature = {"type": "CityJSONFeature", "id": "b", "CityObjects": 5, "vertices": []}
    p = tmp_path / "x.city.jsonl"
    p.write_text(json.dumps(head) + "\n" + json.dumps(feature) + "\n")
    with pytest.raises(LoadError, match=r"x.city.jsonl':2: CityObjects must be an object"):
        load(p)
    doc = _doc()
    feature.update(CityObjects=doc["CityObjects"], vertices=doc["vertices"][:3],
                   appearance=doc["appearance"])
    p.write_text(json.dumps(head) + "\n" + json.dumps(feature) + "\n")
    with pytest.raises(LoadError, match=r"jsonl':2: CityObjects\[\"b\"\].geometry\[0\]"
                                        r".boundaries\[0\]\[0\]\[3\] is 3, but the file has 3"):
        load(p)
    head["transform"]["scale"] = "1"
    p.write_text(json.dumps(head) + "\n")
    with pytest.raises(LoadError, match=r"jsonl':1: transform.scale must be an array"):
        load(p)


def test_cli_render_reports_a_malformed_cityjson_in_one_line(tmp_path: Path, capsys):
    from facadeforge.cli import main

    p = tmp_path / "x.city.json"
    p.write_text('{"type":"CityJSON","CityObjects":5}')
    assert main(["render", str(p), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("facadeforge: error: CityJSON file") and "CityObjects" in err
    assert "\n" not in err and not (tmp_path / "x.png").exists()


def test_texture_paths_stay_beside_the_file(tmp_path: Path):
    """A CityJSON file naming ``../secret.png`` as a texture must not make a reader (render)
    read pictures from elsewhere on the disk; textures beside the file still load."""
    from PIL import Image

    from facadeforge import derive, load_rules
    from facadeforge.exchange import load_cityjson

    Image.new("RGB", (8, 8), (200, 100, 50)).save(tmp_path / "brick.png")
    rules = load_rules('Lot --> setupProjection(0, scope.xz, 4, 4) projectUV(0) '
                       'texture("brick.png")\n', assets=tmp_path)
    (model,) = derive(rules, lot_size="4x4")
    out = tmp_path / "out"
    out.mkdir()
    export(model, out / "m.city.json")
    (loaded,) = load_cityjson(out / "m.city.json")
    assert loaded.parts[0].material.texture is not None
    doc = json.loads((out / "m.city.json").read_text())
    doc["appearance"]["textures"][0]["image"] = "../brick.png"
    (out / "m.city.json").write_text(json.dumps(doc))
    (loaded,) = load_cityjson(out / "m.city.json")
    assert loaded.parts[0].material.texture is None
