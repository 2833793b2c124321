"""``inline`` (append, recompose, unify) and the Boolean 3D operations: hand-checked answers."""

import numpy as np
import pytest
from cga_helpers import by_symbol, run

from facadeforge import derive, load_rules
from facadeforge.errors import DerivationError, RuleSyntaxError


def tree_symbols(node):
    out = [node.symbol]
    for c in node.children:
        out.extend(tree_symbols(c))
    return out


def test_inline_rule_lets_the_rule_go_on_with_its_result():
    m = run("""Lot --> inline Volumes color(1,0,0) R.
Volumes --> split(x) { '0.5: extrude(2) A | '0.5: extrude(4) B }""")
    assert not m.warnings
    (r,) = m.parts
    # 5 x 8 x 2 box (132 m²) and 5 x 8 x 4 box (184 m²), both red
    assert r.symbol == "R" and r.mesh.area() == pytest.approx(316)
    assert r.material.color == pytest.approx((1, 0, 0))
    assert "Volumes" not in tree_symbols(m.root) and "A" not in tree_symbols(m.root)


def test_without_inline_the_rules_run_side_by_side():
    m = run("""Lot --> Volumes color(1,0,0) R.
Volumes --> split(x) { '0.5: extrude(2) A | '0.5: extrude(4) B }""")
    parts = by_symbol(m)
    assert set(parts) == {"A", "B", "R"}
    assert parts["A"][0].material.color == pytest.approx((1, 1, 1))


def test_a_single_result_is_taken_as_is():
    m = run("Lot --> inline { extrude(3) } comp(f) { top : T. }")
    (t,) = m.parts
    assert t.mesh.area() == pytest.approx(80)
    lo, hi = t.mesh.bounds()
    assert lo[1] == pytest.approx(3) and hi[1] == pytest.approx(3)


def test_inline_of_nothing_leaves_no_geometry():
    m = run("Lot --> inline { NIL } X.")
    assert m.parts == []


def test_recompose_welds_pieces_and_inserts_vertices_on_edges():
    # the F of CityEngine's recomposition page: a 4 m stem and two 2 m arms
    m = run("Lot --> inline(recompose) split(x) { 4: X. | ~1: split(z) { 2: X. | 2: NIL }* } F.")
    (f,) = m.parts
    assert f.mesh.n_faces == 3 and f.mesh.area() == pytest.approx(4 * 8 + 2 * 6 * 2)
    assert len(f.mesh.used_vertices()) == 11
    stem = max(f.mesh.faces, key=len)
    assert len(stem) == 7  # its right edge gets the arms' corners at z = 2, 4, 6


def test_append_keeps_pieces_apart():
    m = run("Lot --> inline split(x) { 4: X. | ~1: split(z) { 2: X. | 2: NIL }* } F.")
    (f,) = m.parts
    assert f.mesh.n_faces == 3 and len(f.mesh.used_vertices()) == 12


def test_unify_is_the_union_volume():
    m = run("Lot --> inline(unify) { [ extrude(2) A. ] [ t(1,0,1) s(10,0,8) extrude(3) B. ] } U.")
    (u,) = m.parts
    assert u.mesh.is_closed()
    # 160 + 240 minus the overlap [1,10] x [0,2] x [1,8] = 126
    assert u.mesh.volume() == pytest.approx(274)


@pytest.mark.parametrize("kind, volume, area", [
    ("union", 320, 2 * 80 + 2 * (40 + 32)),
    ("subtract", 320 - 64, 2 * (80 - 16) + 2 * (40 + 32) + 4 * 16),
    ("intersect", 64, 6 * 16),
])
def test_boolean_operations(kind, volume, area):
    m = run(f"Lot --> {kind} {{ extrude(4) | t(2,0,2) s(4,4,4) primitiveCube }} X.")
    assert not m.warnings
    mesh = m.parts[0].mesh if len(m.parts) == 1 else None
    assert mesh is not None and mesh.is_closed()
    assert mesh.volume() == pytest.approx(volume) and mesh.area() == pytest.approx(area)


def test_boolean_keeps_each_operands_material_and_a_gives_the_shape():
    m = run("""Lot --> subtract { extrude(4) color(1,0,0) set(k, 2) | t(2,-1,2) s(4,6,4)
                                   primitiveCube color(0,0,1) set(k, 3) } report("k", k) S.
attr k = 0""")
    colours = {}
    for p in m.parts:
        colours[tuple(np.round(p.material.color, 3))] = colours.get(
            tuple(np.round(p.material.color, 3)), 0) + p.mesh.area()
    # the hole's four walls come from B (blue), everything else from A (red)
    assert colours[(0.0, 0.0, 1.0)] == pytest.approx(4 * 16)
    assert colours[(1.0, 0.0, 0.0)] == pytest.approx(2 * (80 - 16) + 2 * (40 + 32))
    assert m.reports["k"] == [2]


def test_boolean_result_faces_stay_polygons_where_uncut():
    m = run("Lot --> subtract { extrude(4) | t(2,-1,2) s(4,6,4) primitiveCube } "
            "comp(f) { side : S. | top : T. }")
    sides = by_symbol(m)["S"]
    # four outer walls stay quads; four walls of the hole
    assert len(sides) == 8 and all(p.mesh.face_sizes.tolist() == [4] for p in sides)
    assert sum(p.mesh.area() for p in by_symbol(m)["T"]) == pytest.approx(80 - 16)


@pytest.mark.parametrize("kind, area", [("union", 80), ("subtract", 32), ("intersect", 16)])
def test_booleans_of_polygons_in_one_plane(kind, area):
    m = run(f"Lot --> {kind} {{ split(x) {{ 6 : A | ~1 : NIL }} | split(x) {{ 4 : NIL | ~1 : B }} }} X.")
    assert not m.warnings
    assert sum(p.mesh.area() for p in m.parts) == pytest.approx(area)
    assert all(p.mesh.n_faces == 1 for p in m.parts)


def test_open_surfaces_in_space_are_appended_with_a_warning():
    m = run("Lot --> union { extrude(2) comp(f) { side : S } | extrude(3) } X.")
    assert any("neither closed volumes nor polygons in one plane" in w for w in m.warnings)


def test_reports_inside_inline_are_kept():
    m = run("""Lot --> inline Pieces X.
Pieces --> split(x) { 2 : report("w", scope.sx) P }*""")
    assert m.reports["w"] == [2.0] * 5


def test_inline_recursion_is_capped():
    with pytest.raises(DerivationError, match="inline nested deeper"):
        run("Lot --> inline Lot")


@pytest.mark.parametrize("src, message", [
    ("Lot --> inline(foo) X", "unknown inline merge strategy 'foo'"),
    ("Lot --> inline(append, unify) X", "one merge strategy"),
])
def test_bad_inline_strategies(src, message):
    with pytest.raises(RuleSyntaxError, match=message) as e:
        load_rules(src)
    assert ":1:9" in str(e.value)


@pytest.mark.parametrize("op, volume", [
    ("subtract Hole", 320 - 64),               # CityEngine before 2025.0: current shape is A
    ("subtract { A. | Hole }", 320 - 64),
    ("subtract(swap) Hole", 2 * 16),           # current shape is B: the cube's parts outside
    ("intersect Hole", 64),
])
def test_deprecated_boolean_syntax(op, volume):
    m = run(f"Lot --> extrude(4) {op} X.\nHole --> t(2,-1,2) s(4,6,4) primitiveCube")
    assert not m.warnings
    (x,) = m.parts
    assert x.mesh.volume() == pytest.approx(volume)


def test_union_as_a_name_still_works_elsewhere():
    m = run("""attr union = 2
Lot --> extrude(union) intersect(1)
intersect(h) --> s('1, h, '1) X.""")
    assert m.stats()["bbox"][1][1] == pytest.approx(1)



def test_unify_merges_overlaps_within_one_shape():
    # one shape whose geometry is two overlapping boxes: unify makes it one solid
    m = run("Lot --> inline(unify) { inline { [ extrude(2) A. ] [ t(1,0,1) s(10,0,8) extrude(3) B. ] } } U.")
    (u,) = m.parts
    assert u.mesh.is_closed() and u.mesh.volume() == pytest.approx(274)


def test_boolean_faces_keep_their_first_edge_so_walls_stand_upright():
    m = derive(load_rules("Lot --> subtract { extrude(4) | t(2,-1,2) s(4,6,4) primitiveCube } "
                          "comp(f) { side : S. }"), None, lot_size="10x8", keep_tree=True)[0]

    def scopes(node):
        out = [node.scope] if node.symbol == "S" else []
        for c in node.children:
            out += scopes(c)
        return out
    walls = scopes(m.root)
    assert len(walls) == 8
    # x along the bottom edge, y up, as the walls of an extruded lot are
    assert all(np.allclose(sc.rotation[:, 1], [0, 1, 0], atol=1e-9) for sc in walls)
