"""Fixes from the review of the CityEngine-coverage work: each test failed before its fix."""

import numpy as np
import pytest
from cga_helpers import areas, run

from facadeforge import derive, load_rules


def test_perimeter_sections_and_remainder_add_up_to_the_face():
    m = run("Lot --> splitAndSetbackPerimeter(0){ ~1 : 1 : A }* { remainder : R }")
    a = areas(m)
    assert a["R"] == pytest.approx(48) and a["A"] + a["R"] == pytest.approx(80)


def test_center_inside_a_boolean_operand_of_the_start_rule():
    # the cut box is centred on the mass, so the courtyard is in the middle: 282 m²
    m = run("Lot --> extrude(3) subtract { A. | s('0.5,'2,'0.5) center(xz) t(0,-1,0) B. } R.")
    assert areas(m)["R"] == pytest.approx(60 + 60 + 108 + 54)


def test_center_inside_a_push_of_the_start_rule():
    m = run("Lot --> [ s('0.5, 0, '0.5) center(xz) C. ]")
    lo, hi = m.parts[0].mesh.bounds()
    assert lo[[0, 2]] == pytest.approx([2.5, 2]) and hi[[0, 2]] == pytest.approx([7.5, 6])


def _colours(models):
    out = {}
    for m in models:
        for p in m.parts:
            key = tuple(np.round(p.material.color, 3))
            out[key] = out.get(key, 0) + 1
    return out


def test_instancing_keeps_the_random_version_of_a_partly_redefined_rule(tmp_path):
    (tmp_path / "y.cga").write_text(
        "Tile --> color(1,0,0) X.\n"
        "Tile(a) --> case rand(0,1) > 0.5 : color(0,1,0) X. else : color(0,0,1) X.\n")
    (tmp_path / "main.cga").write_text(
        'import y : "y.cga"\ny.Tile --> color(1,1,0) X.\n'
        "Lot --> extrude(3) comp(f){ side: F }\nF --> split(x){ ~1: y.Tile(1) }*\n")
    rules = load_rules(tmp_path / "main.cga")
    plain = derive(rules, None, lot_size="10x8", keep_tree=True)
    fast = derive(rules, None, lot_size="10x8", keep_tree=False)
    assert _colours(plain) == _colours(fast)


def test_instancing_does_not_replay_geo_coordinates():
    rules = load_rules("""Lot --> extrude(3) comp(f){ side: F }
F --> split(x){ ~1: Tile }*
Tile --> T
T --> report("g", getGeoCoord(X)) X.""")
    plain = derive(rules, None, lot_size="10x8", keep_tree=True)[0]
    fast = derive(rules, None, lot_size="10x8", keep_tree=False)[0]
    assert sorted(plain.reports["g"]) == pytest.approx(sorted(fast.reports["g"]))


def test_insert_along_uv_refuses_too_many_copies_before_building_them():
    m = run('Lot --> setupProjection(0, scope.xz, 1e-9, 1e-9) projectUV(0) '
            'insertAlongUV(0, "builtin:cube", 1) X.')
    assert any("asset copies" in w for w in m.warnings)


def test_extruding_a_face_with_a_hole_raises_no_inner_walls():
    # the courtyard lot is stored as triangles; its prism has only the outer and courtyard walls
    m = run("Lot --> A\nA --> subtract { X. | s('0.5,'1,'0.5) center(xz) Y. } extrude(3) R.")
    assert areas(m)["R"] == pytest.approx(60 + 60 + 108 + 54)
    assert m.parts[0].mesh.is_closed()


def test_extruding_pieces_that_share_edges_gives_one_volume():
    m = run("Lot --> inline(recompose) split(x) { 4: X. | ~1: split(z) { 2: X. | 2: NIL }* } "
            "extrude(10) M.")
    (mass,) = m.parts
    # the F: 56 m² of caps twice, its 48 m perimeter walls, no wall inside
    assert mass.mesh.area() == pytest.approx(2 * 56 + 48 * 10)
    assert mass.mesh.volume() == pytest.approx(560)


def test_set_elems_ignores_negative_indices_and_their_values():
    m = run('Lot --> print(setElems([1, 2], [-1, 0], [9, 7])) print(setElems([1, 2], -1, 5)) X.')
    assert not m.warnings
    assert m.attributes["prints"] == ["(2)[7,2]", "(2)[1,2]"]


def test_a_boolean_keyword_called_like_an_operation_says_how_to_write_it():
    m = run("Lot --> extrude(2) subtract(foo) B\nB --> X.")
    assert any("write subtract { A | B }" in w for w in m.warnings)


@pytest.mark.parametrize("op", ['splitAndSetbackPerimeter(0, "a"){ 1 : 1 : A }', "taper(0/0)",
                                "extrude(1/0)"])
def test_operations_refuse_numbers_that_are_not_numbers(op):
    m = run(f"Lot --> {op} X.")
    assert any("is nan" in w or "is inf" in w for w in m.warnings), m.warnings


def test_an_offset_border_is_one_component_and_extrudes_like_a_ring():
    # CityEngine's border is one face with a hole: one shape, and its frame has 8 walls, not 16
    m = run('Lot --> offset(-1) comp(f) { inside : I. | border : report("n", comp.total) '
            'extrude(0.5) F. }')
    frames = [p for p in m.parts if p.symbol == "F"]
    assert len(frames) == 1 and m.reports["n"] == [1]
    mesh = frames[0].mesh
    assert mesh.is_closed() and mesh.volume() == pytest.approx((80 - 48) * 0.5)
    # top and bottom rings (4 trapezoids each) plus 4 outer and 4 inner walls
    assert mesh.n_faces == 16 and mesh.triangle_count() == 32


def test_reset_geometry_drops_trim_planes_and_the_pivot():
    # a cube inserted after resetGeometry is not cut by the planes comp(f) left on the wall
    m = run("Lot --> extrude(4) comp(f) { front : resetGeometry() s(2, 2, 2) primitiveCube() C. }")
    (c,) = m.parts
    assert c.mesh.n_faces == 6 and c.mesh.area() == pytest.approx(24)
    m = run("Lot --> setPivot(xyz, 2) resetGeometry() print(pivot.px) X.")
    assert m.attributes["prints"] == ["0"]


def test_copy_uv_sets_do_not_follow_split_pieces():
    m = run("""Lot --> setupProjection(0, scope.xz, scope.sx, scope.sz) projectUV(0) copyUV(0, 1)
        split(x) { 5 : A. | 5 : B }
B --> copyUV(1, 0) X.""")
    assert any("uv set 1 holds no texture coordinates for these faces" in w for w in m.warnings)
