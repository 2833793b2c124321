"""Selectors production rules use: street and world edge selectors (with CityEngine's fallback
to the object frame when the lot has no street widths) and the roof edge selectors."""

import math

import numpy as np
import pytest
from cga_helpers import areas, run


def reports(model, key):
    return sorted(round(v, 4) for v in model.reports.get(key, []))


def test_street_side_setback_of_esris_massmodeling_tutorial():
    # the street is the lot's front (object frame); 3 m of open space along it
    m = run("Lot --> setback(3) { streetSide : Open. | remainder : Sub. }")
    assert not m.warnings
    assert areas(m) == {"Open": pytest.approx(30), "Sub": pytest.approx(50)}
    m = run("Lot --> setback(1) { noStreetSide : Border. | remainder : Rest. }")
    # back and both sides, 1 m wide: the rest is (10 - 2) x (8 - 1), the front kept
    assert areas(m)["Rest"] == pytest.approx(8 * 7)


def test_street_left_and_right_faces():
    m = run("Lot --> extrude(3) comp(f) { street.left : L. | street.right : R. | side : S. }")
    assert not m.warnings
    a = areas(m)
    assert a["L"] == pytest.approx(24) and a["R"] == pytest.approx(24) and a["S"] == pytest.approx(60)


def test_world_selectors_on_setback_edges():
    # a 10 x 8 lot rotated 90° about y: its front edge faces west in the world
    poly = np.array([[0, 0, 0], [0, 0, 10], [8, 0, 10], [8, 0, 0]], float)
    for sel in ("world.north", "world.south", "world.east", "world.west"):
        m = run(f"Lot --> setback(1) {{ {sel} : B. | remainder : R. }}", poly=poly)
        assert not m.warnings, sel
        side = 10 if sel in ("world.east", "world.west") else 8
        assert areas(m)["B"] == pytest.approx(side * 1), sel


def test_roof_edges_of_a_hip_roof():
    m = run("""Lot --> roofHip(30) comp(e) { ridge : R | hip : H | valley : V | eave : E }
R --> report("ridge", scope.sx)
H --> report("hip", scope.sx)
V --> report("valley", scope.sx)
E --> report("eave", scope.sx)""")
    rise = 4 * math.tan(math.radians(30))
    hip = math.sqrt(2 * 4 ** 2 + rise ** 2)
    assert reports(m, "ridge") == [2.0]
    assert reports(m, "hip") == pytest.approx([hip] * 4)
    assert reports(m, "eave") == [8.0, 8.0, 10.0, 10.0]
    assert reports(m, "valley") == []


def test_roof_edges_of_an_l_shaped_roof_have_a_valley():
    L = np.array([[0, 0, 0], [0, 0, 4], [10, 0, 4], [10, 0, 2], [3, 0, 2], [3, 0, 0]], float)[::-1]
    m = run("""Lot --> roofHip(30) comp(e) { valley : V | eave : E }
V --> report("valley", scope.sx)
E --> report("eave", scope.sx)""", poly=L)
    # one valley from the inner corner (3, 2) up at 45° in plan to where the wings' ridges meet
    rise = 1 * math.tan(math.radians(30))
    assert reports(m, "valley") == pytest.approx([math.sqrt(2 + rise ** 2)], abs=1e-3)
    assert sum(reports(m, "eave")) == pytest.approx(28)  # the whole outline


def test_a_selector_may_be_an_attribute_holding_a_face_index():
    m = run("""attr first = 2
Lot --> extrude(3) comp(f) { first = A. | first + 1 = B. | all = R. }""")
    assert not m.warnings
    assert {p.symbol for p in m.parts} == {"A", "B", "R"}
    assert sum(p.mesh.n_faces for p in m.parts if p.symbol == "R") == 4


def test_primitive_with_a_negative_height_reaches_down():
    m = run("Lot --> primitiveCube(2, -3, 2) X.")
    assert not m.warnings
    lo, hi = m.parts[0].mesh.bounds()
    assert lo[1] == pytest.approx(-3) and hi[1] == pytest.approx(0)
    assert hi[0] - lo[0] == pytest.approx(2)


def test_selector_keywords_win_over_attributes_of_the_same_name():
    # Esri's massmodeling tutorial has attr shape = "auto" and shapeL(…) { shape : … }
    m = run("""attr shape = "auto"
attr side = 3
Lot --> shapeL(2, 2) { shape : L. }""")
    assert not m.warnings and {p.symbol for p in m.parts} == {"L"}
