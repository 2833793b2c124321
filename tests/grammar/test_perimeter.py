"""splitAndSetbackPerimeter: sections along the perimeter set back by their depths (hand-checked).

The 10 x 8 lot's perimeter (36 m) runs, from its first edge on: e0 along z = 8 (x 0 → 10), e1 along
x = 10 (z 8 → 0), e2 along z = 0 (x 10 → 0), e3 along x = 0 (z 0 → 8).
"""

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import RuleError
from facadeforge.geometry.footprints import Footprint

# L: a 10 x 2 arm (z in [2, 4]) and a 3 x 2 stub below its left end; total area 26.  Edges: e0
# x = 0 (4 m), e1 z = 4 (x 0 → 10), e2 x = 10 (2 m), e3 z = 2 (x 10 → 3), e4 x = 3 (z 2 → 0, its
# start the reflex corner), e5 z = 0 (3 m)
L_POLY = np.array([[0, 0, 0], [0, 0, 4], [10, 0, 4], [10, 0, 2], [3, 0, 2], [3, 0, 0]], float)[::-1]


def run(src, lot="10x8", poly=None):
    fp = [Footprint("fp", poly)] if poly is not None else None
    return derive(load_rules(src), fp, lot_size=None if fp else lot)[0]


def parts(model, symbol):
    return [p for p in model.parts if p.symbol == symbol]


def area(model, symbol):
    return sum(p.mesh.area() for p in parts(model, symbol))


def test_repeated_pattern_around_the_whole_perimeter():
    # {5 : 2 : A | ~1 : 1 : B}* on 36 m: six A of 5 m, six B of 1 m; corners are divided along
    # their bisectors, so an A band next to a corner loses (or gains) a 2 x 2 / 2 triangle
    m = run("Lot --> splitAndSetbackPerimeter(0) { 5 : 2 : A | ~1 : 1 : B }* { remainder : C }")
    assert not m.warnings
    a = [p.mesh.area() for p in parts(m, "A")]
    b = [p.mesh.area() for p in parts(m, "B")]
    assert a == pytest.approx([8, 6.5, 9.5, 8, 6.5, 9.5])
    assert b == pytest.approx([1, 1, 0.5, 1, 1, 0.5])
    assert area(m, "C") == pytest.approx(27)
    assert sum(a) + sum(b) + area(m, "C") == pytest.approx(80)
    # the first section lies on the first edge, from its start
    lo, hi = parts(m, "A")[0].mesh.bounds()
    assert np.allclose([lo[0], lo[2], hi[0], hi[2]], [0, 6, 5, 8])


def test_one_long_section_is_the_ring_of_a_setback():
    m = run("Lot --> splitAndSetbackPerimeter(0) { 50 : 1 : A } { remainder : C }")
    assert area(m, "A") == pytest.approx(80 - 8 * 6)
    assert area(m, "C") == pytest.approx(48)


@pytest.mark.parametrize("args", ["'0.5", "18", "0, 2", "0, -2", "0, 6"])
def test_offset_and_first_edge_move_the_pattern(args):
    # 18 m (half the perimeter) along the chain, or the chain starting at e2: a 5 x 2 band on
    # z = 0 from x = 10 with the corner triangle of e1 cut off at the bisector
    m = run(f"Lot --> splitAndSetbackPerimeter({args}) {{ 5 : 2 : A }} {{ remainder : C }}")
    (a,) = parts(m, "A")
    assert a.mesh.area() == pytest.approx(8)
    lo, hi = a.mesh.bounds()
    assert np.allclose([lo[0], lo[2], hi[0], hi[2]], [5, 0, 10, 2])
    assert area(m, "C") == pytest.approx(72)


def test_offset_wraps_a_section_over_the_chain_start():
    # 34 m on: the section covers e3 z 6 → 8 and e0 x 0 → 3, one band round the corner (the
    # 1 x 1 corner square counted once)
    m = run("Lot --> splitAndSetbackPerimeter(34) { 5 : 1 : A } { remainder : C }")
    (a,) = parts(m, "A")
    assert a.mesh.area() == pytest.approx(2 + 3 - 1)
    assert area(m, "C") == pytest.approx(76)


def test_mask_restricts_the_chain_and_bands_run_to_the_border():
    # only e1 of the L (10 m, both corners convex; missing mask values are false): the band
    # spans the whole top edge
    m = run("Lot --> splitAndSetbackPerimeter(0, 1, [false, true]) "
            "{ ~1 : 1 : A } { remainder : C }", poly=L_POLY)
    assert not m.warnings
    assert area(m, "A") == pytest.approx(10)
    assert area(m, "C") == pytest.approx(16)
    lo, hi = parts(m, "A")[0].mesh.bounds()
    assert np.allclose([lo[0], lo[2], hi[0], hi[2]], [0, 3, 10, 4])


def test_reflex_corner_is_divided_along_its_bisector():
    # all edges of the L at depth 0.5: the ring of a mitred inward offset (inner L of 4 + 9)
    m = run("Lot --> splitAndSetbackPerimeter(0) { ~1 : 0.5 : A } { remainder : C }", poly=L_POLY)
    assert area(m, "A") == pytest.approx(13)
    assert area(m, "C") == pytest.approx(13)
    # two sections meeting at the reflex corner (3, 2): e3 (7 m) then e4 (2 m); each loses a
    # 0.5 x 0.5 / 2 triangle at its convex corner and gains one at the reflex corner
    m = run("Lot --> splitAndSetbackPerimeter(0, 3) { 7 : 0.5 : B | 2 : 0.5 : A } "
            "{ remainder : C }", poly=L_POLY)
    assert area(m, "B") == pytest.approx(7 * 0.5 - 0.125 + 0.125)
    assert area(m, "A") == pytest.approx(2 * 0.5 + 0.125 - 0.125)
    lo, hi = parts(m, "A")[0].mesh.bounds()
    assert np.allclose([lo[0], lo[2], hi[0], hi[2]], [2.5, 0, 3, 2.5])


def test_sections_get_split_index_and_total():
    m = run("Lot --> splitAndSetbackPerimeter(0) { ~9 : 1 : report(\"i\", split.index) "
            "report(\"n\", split.total) A }*")
    assert m.reports["i"] == [0, 1, 2, 3]
    assert m.reports["n"] == [4, 4, 4, 4]
    assert not parts(m, "C")


def test_zero_depth_makes_no_shape():
    m = run("Lot --> splitAndSetbackPerimeter(0) { 4 : 0 : A | 2 : 3 : B } { remainder : C }")
    assert not parts(m, "A")
    assert area(m, "B") == pytest.approx(6)
    assert area(m, "C") == pytest.approx(74)


@pytest.mark.parametrize("src, message", [
    ("Lot --> splitAndSetbackPerimeter(0) { 4 : -1 : A } { remainder : C }", "depth must be"),
    ("Lot --> splitAndSetbackPerimeter(0) { 4 : 1 : A } { front : C }", "only 'remainder"),
    ("Lot --> splitAndSetbackPerimeter(0, 1, 3) { 4 : 1 : A }", "selectedEdgesMask"),
    ("Lot --> extrude(3) splitAndSetbackPerimeter(0) { 4 : 1 : A }", "single planar face"),
])
def test_bad_input_is_a_warning_and_leaves_the_shape(src, message):
    m = run(src)
    assert any(message in w and "splitAndSetbackPerimeter" in w for w in m.warnings)
    assert not parts(m, "A")


def test_depth_names_are_checked_when_loading():
    assert load_rules("attr d = 2\nLot --> splitAndSetbackPerimeter(0) { 5 : d : A } "
                      "{ remainder : C }")
    with pytest.raises(RuleError, match="dpeth"):
        load_rules("Lot --> splitAndSetbackPerimeter(0) { 5 : dpeth : A } { remainder : C }")


def test_depth_expression_is_evaluated_per_section():
    m = run("attr d = 1\nLot --> splitAndSetbackPerimeter(0) { 18 : d * 2 : A | ~1 : d : B }")
    # A: e0 whole (20 less its first corner's triangle 2), e1 below it (6 m, less 2 at its end)
    assert area(m, "A") == pytest.approx(10 * 2 - 2 + 6 * 2 - 2)
    assert area(m, "B") == pytest.approx(10 * 1 - 0.5 + 7 * 1 - 0.5)


def test_section_lengths_are_expressions_not_selectors():
    assert load_rules("attr w = 5\nLot --> splitAndSetbackPerimeter(0) { w : 1 : A }")
    with pytest.raises(RuleError, match="lenght"):
        load_rules("Lot --> splitAndSetbackPerimeter(0) { lenght : 1 : A } { remainder : C }")


def test_no_selected_edge_leaves_all_to_the_remainder():
    m = run("Lot --> splitAndSetbackPerimeter(0, 0, [false, false, false, false]) { 5 : 1 : A } "
            "{ remainder : C }")
    assert not parts(m, "A")
    assert area(m, "C") == pytest.approx(80)
