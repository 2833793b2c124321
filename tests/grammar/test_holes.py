"""Faces with holes (courtyard footprints) and setback bands on concave faces."""

import json

import numpy as np
import pytest
import shapely
from cga_helpers import areas, by_symbol, run

from facadeforge import derive, load_rules
from facadeforge.geometry.footprints import load_footprints

# a 30 x 20 block around a 10 x 10 courtyard (GeoJSON: outer ring, then the hole)
BLOCK = {"type": "Polygon", "coordinates": [
    [[0, 0], [30, 0], [30, 20], [0, 20], [0, 0]],
    [[10, 5], [20, 5], [20, 15], [10, 15], [10, 5]]]}


@pytest.fixture
def block(tmp_path):
    p = tmp_path / "block.geojson"
    p.write_text(json.dumps(BLOCK))
    return load_footprints(p)


def derive_on(src, footprints):
    m = derive(load_rules(src), footprints)[0]
    assert not m.warnings, m.warnings
    return m


def test_geojson_holes_are_courtyards(block):
    assert len(block) == 1 and len(block[0].holes) == 1
    m = derive_on("Lot --> print(geometry.nHoles) print(geometry.area) X.", block)
    assert m.attributes["prints"] == ["1", "500"]


def test_a_courtyard_extrudes_to_outer_and_inner_walls(block):
    m = derive_on('Lot --> extrude(10) comp(f){ isTagged("extrude.side.inner") : I. '
                  '| side : O. | top : T. | bottom : B. }', block)
    parts = by_symbol(m)
    assert len(parts["I"]) == 4 and sum(p.mesh.area() for p in parts["I"]) == pytest.approx(400)
    assert sum(p.mesh.area() for p in parts["O"]) == pytest.approx(1000)
    # the top is one face with a hole, so one shape (pieces inside), as in CityEngine
    assert len(parts["T"]) == 1 and parts["T"][0].mesh.area() == pytest.approx(500)


def test_a_hip_roof_runs_round_the_courtyard(block):
    m = derive_on("Lot --> extrude(10) comp(f){ top = roofHip(30) comp(f){ "
                  'isTagged("roof.top") : R. | all : B. } }', block)
    a = areas(m)
    assert a["B"] == pytest.approx(500)                       # the roof's bottom: the block
    assert a["R"] == pytest.approx(500 / np.cos(np.radians(30)))  # planes over it, none over the yard
    top = max(p.mesh.bounds()[1][1] for p in m.parts)
    # the ring is 10 m wide beside the courtyard and 5 m in front of and behind it: the
    # ridge peaks over the wide sides, 5 m from either eave
    assert top == pytest.approx(10 + 5 * np.tan(np.radians(30)))


def test_a_shed_roof_over_a_courtyard_block(block):
    # the plane rises from edge 0 (y = 0) at 45 degrees: 20 m deep, so 20 m high at the back
    m = derive_on("Lot --> roofShed(45) comp(f){ isTagged(\"roof.side.inner\") : I. "
                  "| isTagged(\"roof.side.outer\") : O. | isTagged(\"roof.top\") : T. "
                  "| all : B. }", block)
    parts, a = by_symbol(m), areas(m)
    assert len(parts["T"]) == 1 and a["T"] == pytest.approx(500 * np.sqrt(2))  # one face, holed
    assert len(parts["I"]) == 4                       # the courtyard's walls
    # courtyard walls between heights 5 and 15: two sides 10 m wide, two of 10 m trapezoids
    assert a["I"] == pytest.approx(10 * 5 + 10 * 15 + 2 * 10 * 10)
    assert a["O"] == pytest.approx(30 * 20 + 2 * 20 * 20 / 2)  # the high back, two triangles
    assert a["B"] == pytest.approx(500)
    assert sum(p.mesh.volume() for p in m.parts) == pytest.approx(
        30 * 20 * 10 - 10 * 10 * 10, rel=1e-6)            # mean height 10 over each


def test_geometry_counts_see_a_face_with_holes_as_one_face(block):
    m = derive_on("Lot --> print(geometry.nFaces) print(geometry.nEdges) print(geometry.nVertices) "
                  "extrude(5) print(geometry.nFaces) print(geometry.nEdges) "
                  "print(geometry.nVertices) comp(v){ all : V. }", block)
    # the block: one face, 4 + 4 edges, 8 corners; extruded: 2 caps and 8 walls, 24 edges
    assert m.attributes["prints"] == ["1", "8", "8", "10", "24", "16"]
    assert len(m.parts) == 0 and sum(s.symbol == "V" for s in m.root.walk()) == 16


def test_roofs_that_cannot_take_holes_say_so(block):
    m = derive(load_rules("Lot --> roofPyramid(30) X."), block)[0]
    assert any("has holes" in w and "deleteHoles" in w for w in m.warnings)


def test_offset_and_setback_of_a_face_with_holes(block):
    a = areas(derive_on("Lot --> offset(-1) comp(f){ inside : I. | border : B. }", block))
    assert a["I"] == pytest.approx(28 * 18 - 12 * 12)
    assert a["B"] == pytest.approx(500 - (28 * 18 - 12 * 12))
    parts = by_symbol(derive_on("Lot --> offset(-1) comp(f){ border : B. }", block))
    # the border: a ring along the outline and one round the courtyard, two faces
    assert len(parts["B"]) == 2
    # the band along the front edges: the street front and the courtyard's side facing it,
    # which stops at the courtyard's corners
    a = areas(derive_on("Lot --> setback(2){ front : F. | remainder : R. }", block))
    assert a["F"] == pytest.approx(30 * 2 + 10 * 2) and a["R"] == pytest.approx(500 - 80)


def test_setback_bands_match_a_mitred_offset_on_a_concave_face():
    ell = np.array([[0, 0, -20], [8, 0, -20], [8, 0, -8], [20, 0, -8], [20, 0, 0], [0, 0, 0]],
                   float)
    poly = shapely.Polygon(ell[:, [0, 2]])
    band = poly.area - poly.buffer(-2, join_style="mitre").area
    assert areas(run("Lot --> setback(2){ all : B. | remainder : R. }", poly=ell))["B"] \
        == pytest.approx(band)


def test_a_setback_band_stops_at_reflex_corners():
    # a U whose notch's far edge faces the same way as the prongs' ends: each band is its own
    # edge's, not a strip across the whole U
    u = np.array([[0, 0, 0], [30, 0, 0], [30, 0, -20], [20, 0, -20], [20, 0, -8], [10, 0, -8],
                  [10, 0, -20], [0, 0, -20]], float)[::-1]
    a = areas(run("Lot --> setback(3){ back : B. | remainder : R. }", poly=u))
    assert a["B"] == pytest.approx(3 * 3 * 10)


def test_the_courtyard_example():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    models = derive(load_rules(root / "examples/grammars/courtyard.cga"),
                    root / "examples/footprints/courtyards.geojson", workers=1)
    assert [m.warnings for m in models] == [[], []]
    for m in models:
        court = [p for p in m.parts if p.symbol in ("Plaster", "CourtTile")]
        street = [p for p in m.parts if p.symbol in ("Stone", "Tile", "Shop")]
        assert court and street
        # courtyard facades stand on the hole's edges: all inside the outline's bounds
        lo, hi = np.min([p.mesh.bounds()[0] for p in street], axis=0), \
            np.max([p.mesh.bounds()[1] for p in street], axis=0)
        for p in court:
            b = p.mesh.bounds()
            assert np.all(b[0][[0, 2]] > lo[[0, 2]] + 1) and np.all(b[1][[0, 2]] < hi[[0, 2]] - 1)


def test_a_face_with_holes_is_one_component_with_its_outline_s_scope(block):
    m = derive_on("Lot --> extrude(3) comp(f){ top : print(scope.sx) print(scope.sy) "
                  "split(x){ 12 : A. | ~1 : B. } }", block)
    assert m.attributes["prints"] == ["30", "20"]
    a = areas(m)
    assert a["A"] == pytest.approx(12 * 20 - 2 * 10) and a["B"] == pytest.approx(18 * 20 - 8 * 10)


def test_the_comp_function_index_and_logical_selectors_see_whole_faces(block):
    m = derive_on("Lot --> print(size(comp(f){ all : 1 })) "
                  "print(sum(comp(f){ all : geometry.area })) "
                  "comp(f){ all && geometry.area > 400 : A. | all : B. } "
                  "comp(f){ 0 : I. }", block)
    assert m.attributes["prints"] == ["1", "500"]
    assert areas(m) == pytest.approx({"A": 500, "I": 500})


def test_pieces_that_a_cut_parts_are_faces_of_their_own(block):
    # the middle slab of the block crosses the courtyard: two strips, two faces
    m = derive_on("Lot --> split(x){ 12 : A. | 6 : M | ~1 : C. }\n"
                  "M --> print(size(comp(f){ all : 1 })) comp(f){ all : S. }", block)
    assert m.attributes["prints"] == ["2"] and len(by_symbol(m)["S"]) == 2


def test_a_band_running_on_past_a_convex_corner_stays_on_its_side_of_the_neighbour():
    u = np.array([(0, 0), (20, 0), (20, 16), (14, 16), (14, 6), (6, 6), (6, 16), (0, 16)], float)
    poly = np.column_stack([u[:, 0], np.zeros(len(u)), -u[:, 1]])
    # edge 6 (a prong's outer side) alone: its strip must not reach into the other prong
    a = areas(run("Lot --> setback(comp(fe){ 6 : 2 | all : 0 }){ all : S. | remainder : R. }",
                  poly=poly))
    assert a["S"] == pytest.approx(12) and a["R"] == pytest.approx(228)


def test_corners_between_branches_and_sides_leave_no_notch():
    ell = np.array([[0, 0, -20], [8, 0, -20], [8, 0, -8], [20, 0, -8], [20, 0, 0], [0, 0, 0]],
                   float)[::-1]
    whole = areas(run("Lot --> setback(1){ all : A. | remainder : R. }", poly=ell))
    parts = areas(run("Lot --> setback(1){ front : A. | left : A. | back : A. | right : A. "
                      "| remainder : R. }", poly=ell))
    letter = areas(run("Lot --> shapeO(1, 1, 1, 1){ shape : A. | remainder : R. }", poly=ell))
    assert parts == pytest.approx(whole) and letter == pytest.approx(whole)


def test_edges_inside_a_face_with_holes_are_not_edges(block):
    m = derive_on("Lot --> print(size(comp(e){ all : 1 })) print(size(comp(fe){ all : 1 })) "
                  "extrude(3) print(size(comp(e){ all : 1 })) "
                  "comp(e){ all : print(\"e\") } X.", block)
    prints = m.attributes["prints"]
    # 4 + 4 edges of the block's outline and courtyard; a box round a courtyard has 24
    assert prints[:3] == ["8", "8", "24"] and prints.count("e") == 24


def test_a_face_with_holes_lists_its_edges_ring_by_ring(block):
    """comp(e) and comp(fe) go round the outline from the lot's first corner, then round the
    courtyard from its corner nearest that (here the hole's first), as the rings were given;
    a comp(fe) width array sets back the edge of that index."""
    m = derive_on('Lot --> comp(e){ all : print(scope.sx + "@" + comp.index) E. }', block)
    assert m.attributes["prints"] == [f"{w}@{i}" for i, w in
                                      enumerate([30, 20, 30, 20, 10, 10, 10, 10])]
    bands = []
    for src in ("Lot --> setback(comp(fe){ 5 : 1 | all : 0 }){ all : S. | remainder : R. }",
                "Lot --> comp(e){ 5 : extrude(1) S. }"):
        (s,) = by_symbol(derive_on(src, block))["S"]
        bands.append(s.mesh.bounds())
    # the courtyard's second edge, (10, 15) → (20, 15) in GeoJSON (x, −z in CGA)
    assert bands[0][:, [0, 2]] == pytest.approx(np.array([[10, -16], [20, -15]]))
    assert bands[1][:, [0, 2]] == pytest.approx(np.array([[10, -15], [20, -15]]))


def test_a_boolean_cut_through_a_face_leaves_a_face_with_a_hole():
    m = run("Lot --> subtract { extrude(4) | t(2, -1, 2) s(4, 6, 4) primitiveCube } "
            "print(geometry.nHoles) comp(f){ top : T. | side : S. }")
    assert not m.warnings and m.attributes["prints"] == ["2"]   # through the top and bottom
    parts = by_symbol(m)
    assert len(parts["T"]) == 1 and parts["T"][0].mesh.area() == pytest.approx(80 - 16)


def test_per_edge_setbacks_and_tag_selectors_on_a_face_with_holes(block):
    plain = areas(derive_on("Lot --> setback(2){ front : S. | remainder : R. }", block))
    per_edge = areas(derive_on("Lot --> setback(comp(fe){ front : 2 | all : 0 }){ all : S. "
                               "| remainder : R. }", block))
    assert per_edge == pytest.approx(plain)
    # the remainder's new edges are tagged setback.back: a second setback can pick them
    a = areas(derive_on('Lot --> setback(2){ front : S. | remainder : R }\n'
                        'R --> setback(1){ isTagged("setback.back") : A. | remainder : B. }', block))
    assert a["A"] == pytest.approx(30 * 1 + 10 * 1)
    m = derive_on("Lot --> setback(2){ front : S. | remainder : R }\n"
                  "R --> print(scope.sx) print(scope.sy) print(scope.sz) X.", block)
    assert m.attributes["prints"] == ["30", "0", "18"]  # the lot's scope, y up, fitted


def test_a_setback_line_on_a_face_with_holes_copies_its_edge_s_tags(block):
    a = areas(derive_on('Lot --> tag("P", edges) setback(2){ front : F. | remainder : R }\n'
                        'R --> extrude(1) comp(f){ isTagged("setback.back") && isTagged("P") : '
                        'BP. | isTagged("setback.back") : BN. | all : O. }', block))
    # front: the block's front edge and the courtyard's far one, each with its setback line
    assert a["BP"] == pytest.approx(30 * 1 + 10 * 1) and "BN" not in a


def test_comp_holes_gives_the_courtyards(block):
    m = derive_on("Lot --> print(size(comp(h){ all : 1 })) comp(h){ all : H. }", block)
    assert m.attributes["prints"] == ["1"]
    (hole,) = by_symbol(m)["H"]
    assert hole.mesh.area() == pytest.approx(100)
    assert hole.mesh.face_normals()[0][1] == pytest.approx(1)   # facing up, as the lot does
    m = run("Lot --> comp(h){ all : H. } X.")
    assert "H" not in by_symbol(m)                               # a plain lot has no hole


TWO_YARDS = {"type": "Polygon", "coordinates": [
    [[0, 0], [30, 0], [30, 20], [0, 20], [0, 0]],
    [[4, 4], [10, 4], [10, 10], [4, 10], [4, 4]],
    [[16, 6], [26, 6], [26, 14], [16, 14], [16, 6]]]}


@pytest.mark.parametrize("src", [
    "Lot --> shapeO(1, 2, 0.5, 0.7){ shape : A. | remainder : B. }",
    "Lot --> setback(comp(fe){ front : 5 | all : 2.5 }){ all : A. | remainder : B. }",
    "Lot --> setback(2){ all : A. | remainder : B. }",
])
def test_setback_pieces_tile_a_face_with_two_courtyards(tmp_path, src):
    path = tmp_path / "yards.geojson"
    path.write_text(json.dumps(TWO_YARDS))
    m = derive_on(src, load_footprints(path))
    assert sum(p.mesh.area() for p in m.parts) == pytest.approx(600 - 36 - 80)


def test_a_boolean_keeps_a_face_with_holes_whole(block):
    m = derive_on("Lot --> extrude(6) union { X. | t(40, 0, 0) s(3, 3, 3) primitiveCube } "
                  "comp(f){ top : print(geometry.nHoles) T. }", block)
    assert sorted(m.attributes["prints"]) == ["0", "1"]   # the roof round the yard; the cube


def test_a_wall_with_a_hole_keeps_its_wall_scope():
    for x in (2, 7):
        m = run(f"Lot --> extrude(6) subtract {{ X. | t({x}, 1, -1) s(2, 3, 3) primitiveCube }} "
                "comp(f){ back : print(scope.sx) print(scope.sy) B. }")
        assert m.attributes["prints"][:2] == ["10", "6"]
