"""innerRectangle, roofRidge and splitArea: hand-checked answers."""

import math

import numpy as np
import pytest
from cga_helpers import areas, run

# L: a 10 x 2 arm (z in [2, 4]) and a 3 x 2 stub below its left end; total area 26
L_POLY = np.array([[0, 0, 0], [0, 0, 4], [10, 0, 4], [10, 0, 2], [3, 0, 2], [3, 0, 0]], float)[::-1]






INNER = "Lot --> innerRectangle({m}) {{ shape : S. | remainder : R. }}"


@pytest.mark.parametrize("mode", ["scope", "edge"])
def test_inner_rectangle_of_a_rectangle_is_the_whole_lot(mode):
    m = run(INNER.format(m=mode))
    assert not m.warnings
    assert areas(m) == {"S": pytest.approx(80)}


@pytest.mark.parametrize("mode", ["scope", "edge"])
def test_inner_rectangle_of_an_l_is_its_larger_arm(mode):
    m = run(INNER.format(m=mode), poly=L_POLY)
    a = areas(m)
    # arms: 10 x 2 = 20 and 3 x 4 = 12, so the rectangle is the long arm; the rest is 3 x 2
    assert a["S"] == pytest.approx(20) and a["R"] == pytest.approx(6)
    (s,) = [p for p in m.parts if p.symbol == "S"]
    lo, hi = s.mesh.bounds()
    assert lo == pytest.approx([0, 0, 2]) and hi == pytest.approx([10, 0, 4])


def test_inner_rectangle_of_a_right_triangle():
    # legs 4 and 4: the largest axis-aligned inscribed rectangle is 2 x 2
    tri = np.array([[0, 0, 0], [0, 0, 4], [4, 0, 0]], float)[::-1]
    a = areas(run(INNER.format(m="scope"), poly=tri))
    assert a["S"] == pytest.approx(4, rel=1e-6) and a["R"] == pytest.approx(4, rel=1e-6)


def test_inner_rectangle_of_a_trapezoid():
    # symmetric trapezoid, base 10, top 4, height 6: a rectangle h high is 10 - h wide, so the
    # largest is 5 x 5 (slanted sides: found on the grid, then pushed to the edges)
    trap = np.array([[0, 0, 0], [10, 0, 0], [7, 0, -6], [3, 0, -6]], float)
    a = areas(run(INNER.format(m="scope"), poly=trap))
    assert a["S"] == pytest.approx(25, rel=2e-3) and a["S"] + a["R"] == pytest.approx(42)


def test_inner_rectangle_of_a_rectilinear_u_is_exact():
    # U of a 12 x 3 base and two 3 x 5 arms: the base (36) beats an arm with its base below (24)
    u = np.array([[0, 0, 0], [12, 0, 0], [12, 0, -8], [9, 0, -8], [9, 0, -3], [3, 0, -3],
                  [3, 0, -8], [0, 0, -8]], float)
    m = run(INNER.format(m="scope"), poly=u)
    assert areas(m)["S"] == 36.0
    (s,) = [p for p in m.parts if p.symbol == "S"]
    assert s.mesh.bounds()[0].tolist() == [0, 0, -3] and s.mesh.bounds()[1].tolist() == [12, 0, 0]


def test_roof_ridge_by_angle():
    m = run("Lot --> roofRidge(byAngle, 30) R.", lot="12x8")
    (roof,) = m.parts
    h = 4 * math.tan(math.radians(30))  # half of the 8 m width across the x-parallel ridge
    assert roof.mesh.is_closed()
    assert m.stats()["bbox"][1][1] == pytest.approx(h)
    assert roof.mesh.volume() == pytest.approx(12 * 8 * h / 2)  # tent: base area x h / 2
    g = run("Lot --> roofRidge(byAngle, 30) comp(f) { bottom : NIL | vertical : G | all : P }",
            lot="12x8")
    a = areas(g)
    assert a["G"] == pytest.approx(2 * 8 * h / 2)  # two triangular gables
    assert a["P"] == pytest.approx(2 * 12 * math.hypot(4, h))


def test_roof_ridge_by_height_on_top_face_follows_scope_x():
    # scope x runs along the 6 m side, so the ridge does too: half width 5 m across z
    m = run("Lot --> extrude(3) comp(f) { top : roofRidge(byHeight, 2) R. | all : NIL }", lot="6x10")
    (roof,) = m.parts
    assert roof.mesh.is_closed()
    assert roof.mesh.volume() == pytest.approx(6 * 10 * 2 / 2)
    assert m.stats()["bbox"][1][1] == pytest.approx(5)


def test_split_area():
    m = run("Lot --> splitArea(x) { 20 : A | ~1 : B }")
    assert areas(m) == {"A": pytest.approx(20), "B": pytest.approx(60)}
    (a,) = [p for p in m.parts if p.symbol == "A"]
    assert a.mesh.bounds()[1][0] == pytest.approx(2.5)  # 20 m² of an 8 m deep lot


def test_split_area_on_a_triangle_and_repeat():
    # right triangle, legs 4 (z) and 4 (x); its first edge starts at (4, 0, 0) and the scope z
    # runs from there towards -x, so the area within t of that corner is t² / 2: t = 2 for 2 m²
    tri = np.array([[0, 0, 0], [0, 0, 4], [4, 0, 0]], float)[::-1]
    m = run("Lot --> splitArea(z) { 2 : A | ~1 : B }", poly=tri)
    assert areas(m) == {"A": pytest.approx(2), "B": pytest.approx(6)}
    (a,) = [p for p in m.parts if p.symbol == "A"]
    lo, hi = a.mesh.bounds()
    assert lo[0] == pytest.approx(2) and hi[0] == pytest.approx(4) and hi[2] == pytest.approx(2)
    r = run("Lot --> splitArea(x) { { 20 : A }* }")
    assert [p.mesh.area() for p in r.parts] == pytest.approx([20] * 4)
