"""CityEngine-style roofs built on the straight skeleton."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import MultiPoint, MultiPolygon, Point, Polygon, box
from shapely.ops import unary_union

from facadeforge.geometry.mesh import Mesh
from facadeforge.geometry.roofs import (
    Roof,
    gable_edges,
    roof_gable,
    roof_hip,
    roof_pyramid,
    roof_shed,
)

SETTINGS = settings(max_examples=30, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


def rect(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


L_SHAPE = np.array([[0, 0], [6, 0], [6, 2], [2, 2], [2, 5], [0, 5]], float)
T_SHAPE = np.array([[0, 0], [2, 0], [2, 3], [4, 3], [4, 5], [-2, 5], [-2, 3], [0, 3]], float)
U_SHAPE = np.array([[0, 0], [6, 0], [6, 5], [4, 5], [4, 2], [2, 2], [2, 5], [0, 5]], float)


def normal(f):
    """Unit Newell normal of a (k, 3) polygon."""
    n = np.zeros(3)
    for a, b in zip(f, np.roll(f, -1, axis=0)):
        n += [(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1])]
    return n / np.linalg.norm(n)


def edge_of(poly, holes, k):
    rings = [poly] + list(holes or [])
    for r in rings:
        if k < len(r):
            return r[k], r[(k + 1) % len(r)]
        k -= len(r)
    raise IndexError(k)


def check_roof(roof: Roof, poly, angle, holes=None, rel=1e-6):
    """Sloped faces tile the footprint, lie in their edge's roof plane and face up; vertical faces
    stand on their edge and face outward."""
    tan = math.tan(math.radians(angle))
    footprint = Polygon(poly, holes or [])
    scale = float(np.ptp(poly, axis=0).max())
    sloped = []
    for f, k, kind in zip(roof.faces, roof.edge_index, roof.kind):
        a, b = edge_of(poly, holes, int(k))
        d = (b - a) / np.linalg.norm(b - a)
        inward = np.array([-d[1], d[0]])
        if Polygon(poly).exterior.is_ccw is False and k < len(poly):
            inward = -inward
        n = normal(f)
        if kind == "roof":
            assert n[2] > 1e-9, f"face of edge {k} does not face up"
            # the plane rising from edge k at the roof angle
            np.testing.assert_allclose(f[:, 2], tan * ((f[:, :2] - a) @ inward), atol=1e-7 * scale)
            pf = Polygon(f[:, :2])
            assert pf.is_valid
            sloped.append(pf)
            # the face contains its footprint edge
            assert any(np.allclose(p[:2], a) and p[2] == pytest.approx(0, abs=1e-12) for p in f)
            assert any(np.allclose(p[:2], b) for p in f)
        else:
            assert abs(n[2]) < 1e-9, f"{kind} face of edge {k} is not vertical"
            assert n[:2] @ inward < 0, f"{kind} face of edge {k} faces inward"
            dist = (f[:, :2] - a) @ inward
            np.testing.assert_allclose(dist, 0, atol=1e-7 * scale)
    area = sum(p.area for p in sloped)
    assert area == pytest.approx(footprint.area, rel=rel)
    assert unary_union(sloped).area == pytest.approx(footprint.area, rel=rel)


def z_at(roof: Roof, q):
    """Height of the sloped roof over plan point q."""
    for f, kind in zip(roof.faces, roof.kind):
        if kind != "roof" or not Polygon(f[:, :2]).buffer(1e-9).contains(Point(q)):
            continue
        n = normal(f)
        return float(f[0, 2] - ((q[0] - f[0, 0]) * n[0] + (q[1] - f[0, 1]) * n[1]) / n[2])
    return math.nan


# --------------------------------------------------------------------------- hip
def test_hip_square_four_triangles_at_centre():
    roof = roof_hip(rect(0, 0, 6, 6), 30.0)
    assert len(roof) == 4 and all(len(f) == 3 for f in roof.faces)
    apexes = np.array([f[2] for f in roof.faces])
    np.testing.assert_allclose(apexes, [[3, 3, 3 * math.tan(math.radians(30))]] * 4, atol=1e-12)
    assert roof.height == pytest.approx(3 * math.tan(math.radians(30)))
    assert list(roof.edge_index) == [0, 1, 2, 3]
    check_roof(roof, rect(0, 0, 6, 6), 30.0)


def test_hip_rectangle_trapezoids_triangles_and_ridge():
    L, W, angle = 10.0, 4.0, 40.0
    tan = math.tan(math.radians(angle))
    roof = roof_hip(rect(0, 0, L, W), angle)
    assert [len(f) for f in roof.faces] == [4, 3, 4, 3]
    ridge = roof.faces[0][2:]
    assert np.linalg.norm(ridge[0] - ridge[1]) == pytest.approx(L - W)
    np.testing.assert_allclose(ridge[:, 2], W / 2 * tan)
    check_roof(roof, rect(0, 0, L, W), angle)
    base = np.column_stack([rect(0, 0, L, W)[::-1], np.zeros(4)])
    volume = Mesh.from_polygons(roof.faces + [base]).volume()
    assert volume == pytest.approx(tan * W**2 * (3 * L - W) / 12)


def test_hip_l_shape_area_and_edges():
    roof = roof_hip(L_SHAPE, 45.0)
    assert list(roof.edge_index) == list(range(6))
    assert sum(Polygon(f[:, :2]).area for f in roof.faces) == pytest.approx(Polygon(L_SHAPE).area,
                                                                             rel=1e-12)
    for k, f in enumerate(roof.faces):  # every face starts with its own polygon edge at z = 0
        np.testing.assert_allclose(f[0], [*L_SHAPE[k], 0.0])
        np.testing.assert_allclose(f[1], [*L_SHAPE[(k + 1) % 6], 0.0])
    check_roof(roof, L_SHAPE, 45.0)


@pytest.mark.parametrize("shape", [T_SHAPE, U_SHAPE], ids=["T", "U"])
def test_hip_building_shapes(shape):
    check_roof(roof_hip(shape, 35.0), shape, 35.0)


def test_hip_courtyard():
    outer, hole = rect(0, 0, 10, 10), rect(3, 3, 7, 7)[::-1]
    roof = roof_hip(outer, 30.0, holes=[hole])
    assert len(roof) == 8
    assert roof.height == pytest.approx(1.5 * math.tan(math.radians(30)))
    check_roof(roof, outer, 30.0, holes=[hole])


def test_hip_overhang_extends_planes_below_eaves():
    angle, o = 30.0, 0.5
    tan = math.tan(math.radians(angle))
    base = roof_hip(rect(0, 0, 8, 4), angle)
    roof = roof_hip(rect(0, 0, 8, 4), angle, overhang=o)
    eaves = np.concatenate([f[:2] for f in roof.faces])
    np.testing.assert_allclose(eaves[:, 2], -o * tan)
    assert Polygon(roof.faces[0][:, :2]).area > Polygon(base.faces[0][:, :2]).area
    total = sum(Polygon(f[:, :2]).area for f in roof.faces)
    assert total == pytest.approx((8 + 2 * o) * (4 + 2 * o))
    for f, g in zip(roof.faces, base.faces):  # same planes, same ridge
        assert normal(f) == pytest.approx(normal(g))
        np.testing.assert_allclose(f[2:], g[2:])


def test_hip_clockwise_input_reports_input_edges():
    cw = L_SHAPE[::-1].copy()
    roof = roof_hip(cw, 45.0)
    assert sorted(roof.edge_index) == list(range(6))
    for f, k in zip(roof.faces, roof.edge_index):
        ends = {tuple(cw[k]), tuple(cw[(k + 1) % 6])}
        assert {tuple(f[0, :2]), tuple(f[1, :2])} == ends
        assert normal(f)[2] > 0


@SETTINGS
@given(st.integers(3, 20), st.integers(0, 2**31 - 1), st.floats(5.0, 70.0))
def test_hip_convex_height_is_min_distance_times_tan(n, seed, angle):
    rng = np.random.default_rng(seed)
    hull = MultiPoint(rng.normal(size=(n + 3, 2)) * rng.uniform(1, 15)).convex_hull
    p = np.array(hull.exterior.coords)[:-1]
    roof = roof_hip(p, angle)
    check_roof(roof, p, angle)
    if not Polygon(p).exterior.is_ccw:
        p = p[::-1]
    d = np.roll(p, -1, axis=0) - p
    d /= np.linalg.norm(d, axis=1)[:, None]
    inward = np.column_stack([-d[:, 1], d[:, 0]])
    poly = Polygon(p)
    x0, y0, x1, y1 = poly.bounds
    tan = math.tan(math.radians(angle))
    for q in rng.uniform([x0, y0], [x1, y1], size=(40, 2)):
        if not poly.contains(Point(q)):
            continue
        expected = tan * np.min(np.einsum("ij,ij->i", inward, q - p))
        assert z_at(roof, q) == pytest.approx(expected, abs=1e-8 * (1 + x1 - x0))


@st.composite
def rect_unions(draw):
    boxes = []
    for _ in range(draw(st.integers(1, 6))):
        x0, y0 = draw(st.integers(0, 10)), draw(st.integers(0, 10))
        boxes.append(box(x0, y0, x0 + draw(st.integers(1, 6)), y0 + draw(st.integers(1, 6))))
    u = unary_union(boxes)
    if isinstance(u, MultiPolygon):
        u = max(u.geoms, key=lambda g: g.area)
    u = u.simplify(0)
    return np.array(u.exterior.coords)[:-1], [np.array(r.coords)[:-1] for r in u.interiors]


@SETTINGS
@given(rect_unions(), st.floats(10.0, 60.0))
def test_random_rectilinear_hip_and_gable_tile_footprint(poly, angle):
    outer, holes = poly
    check_roof(roof_hip(outer, angle, holes=holes or None), outer, angle, holes)
    gable = roof_gable(outer, angle, holes=holes or None)
    check_roof(gable, outer, angle, holes)
    # at most one gable face per gable edge, none on adjacent edges
    g = sorted(int(k) for k, kind in zip(gable.edge_index, gable.kind) if kind == "gable")
    assert len(set(g)) == len(g)


# --------------------------------------------------------------------------- gable
@pytest.mark.parametrize("w_along_x", [True, False])
def test_gable_rectangle_textbook(w_along_x):
    angle = 35.0
    tan = math.tan(math.radians(angle))
    poly = rect(0, 0, 12, 5) if w_along_x else rect(0, 0, 5, 12)
    roof = roof_gable(poly, angle)
    kinds = sorted(zip(roof.kind, [len(f) for f in roof.faces]))
    assert kinds == [("gable", 3), ("gable", 3), ("roof", 4), ("roof", 4)]
    short = {1, 3} if w_along_x else {0, 2}
    assert {int(k) for k, kind in zip(roof.edge_index, roof.kind) if kind == "gable"} == short
    ridge = np.unique(np.round(np.concatenate([f[f[:, 2] > 1e-9] for f in roof.faces]), 9), axis=0)
    assert len(ridge) == 2
    np.testing.assert_allclose(ridge[:, 2], 2.5 * tan)
    axis = 0 if w_along_x else 1
    assert abs(ridge[1, axis] - ridge[0, axis]) == pytest.approx(12.0)  # ridge along the long side
    np.testing.assert_allclose(ridge[:, 1 - axis], 2.5)
    check_roof(roof, poly, angle)
    mesh = roof.mesh()
    base = np.column_stack([poly[::-1], np.zeros(4)])
    volume = Mesh.merge([mesh, Mesh.from_polygons([base])]).volume()
    assert volume == pytest.approx(12 * 5**2 * tan / 4)


def test_gable_square_gets_two_opposite_gables():
    roof = roof_gable(rect(0, 0, 4, 4), 45.0)
    g = sorted(int(k) for k, kind in zip(roof.edge_index, roof.kind) if kind == "gable")
    assert g in ([0, 2], [1, 3])
    assert roof.height == pytest.approx(2.0)
    check_roof(roof, rect(0, 0, 4, 4), 45.0)


def test_gable_l_and_t_shapes_put_gables_on_wing_ends():
    assert list(gable_edges(L_SHAPE)) == [1, 4]
    assert list(gable_edges(T_SHAPE)) == [0, 3, 5]
    for shape in (L_SHAPE, T_SHAPE, U_SHAPE):
        roof = roof_gable(shape, 40.0)
        check_roof(roof, shape, 40.0)
        assert "gable" in roof.kind


def test_gable_collinear_vertex_on_short_side():
    poly = np.array([[0, 0], [10, 0], [10, 2], [10, 4], [0, 4]], float)
    assert list(gable_edges(poly)) == [1, 2, 4]
    roof = roof_gable(poly, 30.0)
    check_roof(roof, poly, 30.0)
    assert roof.height == pytest.approx(2 * math.tan(math.radians(30)))


def test_gable_index_selects_ridge_direction():
    roof = roof_gable(rect(0, 0, 10, 4), 45.0, index=0)
    assert sorted(int(k) for k, kind in zip(roof.edge_index, roof.kind) if kind == "gable") == [0, 2]
    assert roof.height == pytest.approx(5.0)
    check_roof(roof, rect(0, 0, 10, 4), 45.0)


def test_gable_overhangs():
    angle, ox, oy = 45.0, 0.5, 0.25
    roof = roof_gable(rect(0, 0, 8, 4), angle, ox, oy)
    sloped = [f for f, k in zip(roof.faces, roof.kind) if k == "roof"]
    gables = [f for f, k in zip(roof.faces, roof.kind) if k == "gable"]
    pts = np.concatenate(sloped)
    np.testing.assert_allclose(pts[:, 0].min(), -oy)
    np.testing.assert_allclose(pts[:, 0].max(), 8 + oy)
    np.testing.assert_allclose(pts[:, 1].min(), -ox)
    np.testing.assert_allclose(pts[:, 2].min(), -ox)  # eaves lowered by ox * tan(45)
    np.testing.assert_allclose(pts[:, 2].max(), 2.0)
    for g in gables:  # gable walls stay on the footprint edges
        assert set(np.round(g[:, 0], 9)) <= {0.0, 8.0}
        assert g[:, 2].min() == pytest.approx(0.0)
    default = roof_gable(rect(0, 0, 8, 4), angle, ox)  # overhang_y defaults to overhang_x
    assert np.concatenate(default.faces)[:, 0].min() == pytest.approx(-ox)


def test_gable_even_makes_ridge_horizontal():
    trap = np.array([[0, 0], [10, 0], [10, 5], [0, 3]], float)
    plain = roof_gable(trap, 30.0)
    even = roof_gable(trap, 30.0, even=True)
    top = lambda r: np.concatenate([f[f[:, 2] > 1e-9] for f in r.faces])  # noqa: E731
    assert np.ptp(top(plain)[:, 2]) > 0.1
    assert np.ptp(top(even)[:, 2]) == pytest.approx(0.0, abs=1e-12)


def test_gable_without_candidates_is_hip():
    a = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    hexagon = np.column_stack([np.cos(a), np.sin(a)]) * 5
    roof = roof_gable(hexagon, 30.0)
    assert roof.kind == ["roof"] * 6
    check_roof(roof, hexagon, 30.0)


# --------------------------------------------------------------------------- pyramid, shed
def test_pyramid_square_and_rectangle():
    tan = math.tan(math.radians(30))
    roof = roof_pyramid(rect(0, 0, 4, 4), 30.0)
    assert len(roof) == 4 and all(len(f) == 3 for f in roof.faces)
    np.testing.assert_allclose(roof.faces[0][2], [2, 2, 2 * tan])
    for f in roof.faces:
        assert normal(f)[2] > 0
    r = roof_pyramid(rect(0, 0, 10, 4), 30.0)
    np.testing.assert_allclose(r.faces[0][2], [5, 2, 2 * tan])  # nearest edge line: 2 away
    r1 = roof_pyramid(rect(0, 0, 10, 4), 30.0, reference_edge=1)
    np.testing.assert_allclose(r1.faces[0][2], [5, 2, 5 * tan])
    tri = np.array([[0, 0], [6, 0], [0, 6]], float)
    np.testing.assert_allclose(roof_pyramid(tri, 45.0, center="vertices").faces[0][2, :2], [2, 2])


def test_shed_rectangle_closed_volume():
    angle = 20.0
    tan = math.tan(math.radians(angle))
    poly = rect(0, 0, 6, 3)
    roof = roof_shed(poly, angle, edge_index=0)
    assert roof.kind[0] == "roof" and roof.edge_index[0] == 0
    np.testing.assert_allclose(roof.faces[0][:, 2], [0, 0, 3 * tan, 3 * tan])
    assert sorted(roof.kind[1:]) == ["side"] * 3
    assert sorted(int(k) for k in roof.edge_index[1:]) == [1, 2, 3]
    check_roof(roof, poly, angle)
    base = np.column_stack([poly[::-1], np.zeros(4)])
    mesh = Mesh.merge([roof.mesh(), Mesh.from_polygons([base])])
    assert mesh.volume() == pytest.approx(6 * 3 * 3 * tan / 2)
    other = roof_shed(poly, angle, edge_index=1)
    np.testing.assert_allclose(other.faces[0][:, 2], [6 * tan, 0, 0, 6 * tan])


def test_shed_l_shape_sides_are_vertical_and_outward():
    roof = roof_shed(L_SHAPE, 15.0, edge_index=0)
    check_roof(roof, L_SHAPE, 15.0)
    assert len(roof) == 1 + 5


def test_angle_validation_and_roof_container():
    with pytest.raises(ValueError, match="angle"):
        roof_hip(rect(0, 0, 1, 1), 90.0)
    with pytest.raises(ValueError, match="angle"):
        roof_gable(rect(0, 0, 1, 1), -5.0)
    flat = roof_hip(rect(0, 0, 2, 1), 0.0)
    assert flat.height == 0.0
    with pytest.raises(ValueError):
        Roof([np.zeros((3, 3))], [0, 1], ["roof"])
    r = roof_gable(rect(0, 0, 4, 2), 30.0)
    assert len(r.select("gable")) == 2 and r.vertical.sum() == 2
    assert r.mesh().n_faces == 4
