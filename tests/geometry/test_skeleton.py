"""Straight skeleton: known answers, invariants on random footprints, degenerate inputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import MultiPolygon, Polygon, box
from shapely.ops import unary_union

from facadeforge.geometry.skeleton import Skeleton, SkeletonTolerance, straight_skeleton

SETTINGS = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


def rect(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


L_SHAPE = np.array([[0, 0], [6, 0], [6, 2], [2, 2], [2, 5], [0, 5]], float)
T_SHAPE = np.array([[0, 0], [2, 0], [2, 3], [4, 3], [4, 5], [-2, 5], [-2, 3], [0, 3]], float)
U_SHAPE = np.array([[0, 0], [6, 0], [6, 5], [4, 5], [4, 2], [2, 2], [2, 5], [0, 5]], float)
H_SHAPE = np.array([[0, 0], [2, 0], [2, 2], [4, 2], [4, 0], [6, 0], [6, 6], [4, 6], [4, 4], [2, 4],
                    [2, 6], [0, 6]], float)
PLUS = np.array([[1, 0], [2, 0], [2, 1], [3, 1], [3, 2], [2, 2], [2, 3], [1, 3], [1, 2], [0, 2],
                 [0, 1], [1, 1]], float)


def circle(n, r=1.0, radii=None):
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = r if radii is None else radii
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def check_skeleton(sk: Skeleton, outer, holes=None, rel=1e-6):
    """Faces tile the polygon, are simple, CCW, planar (time = distance to the edge line)."""
    poly = Polygon(outer, holes or [])
    area = poly.area
    scale = float(np.ptp(np.concatenate([outer] + list(holes or [])), axis=0).max())
    face_polys = []
    for k, f in enumerate(sk.faces):
        assert len(f) >= 3, f"face {k} empty"
        pts = sk.nodes[f]
        a, b = sk.nodes[sk.edges[k]]
        # the face starts with its own polygon edge
        assert {int(f[0]), int(f[1])} == {int(i) for i in sk.edges[k]}
        d = (b - a) / np.linalg.norm(b - a)
        dist = (pts - a) @ np.array([-d[1], d[0]])
        np.testing.assert_allclose(dist, sk.times[f], atol=1e-7 * scale, err_msg=f"face {k}")
        fp = Polygon(pts)
        assert fp.is_valid, f"face {k} not simple"
        assert sk.face_area(k) > -1e-12
        face_polys.append(fp)
    total = sum(sk.face_area(k) for k in range(len(sk.faces)))
    assert total == pytest.approx(area, rel=rel)
    assert unary_union(face_polys).area == pytest.approx(area, rel=rel)  # no overlaps
    assert np.all(sk.times >= -1e-12)


# --------------------------------------------------------------------------- known answers
def test_square_four_triangles_meet_in_centre():
    sk = straight_skeleton(rect(0, 0, 2, 2))
    assert len(sk.nodes) == 5
    assert [len(f) for f in sk.faces] == [3, 3, 3, 3]
    np.testing.assert_allclose(sk.nodes[4], [1, 1], atol=1e-12)
    assert sk.times[4] == pytest.approx(1.0)
    assert all(f[2] == 4 for f in sk.faces)
    check_skeleton(sk, rect(0, 0, 2, 2))


def test_rectangle_ridge():
    sk = straight_skeleton(rect(0, 0, 10, 4))
    sizes = [len(f) for f in sk.faces]
    assert sizes == [4, 3, 4, 3]
    inner = sk.nodes[4:]
    assert len(inner) == 2
    np.testing.assert_allclose(sorted(inner[:, 0]), [2, 8], atol=1e-12)
    np.testing.assert_allclose(inner[:, 1], [2, 2], atol=1e-12)
    np.testing.assert_allclose(sk.times[4:], [2, 2], atol=1e-12)
    ridge = np.linalg.norm(inner[0] - inner[1])
    assert ridge == pytest.approx(10 - 4)
    assert sk.arcs.shape == (5, 2)  # ridge + 4 hips
    check_skeleton(sk, rect(0, 0, 10, 4))


def test_l_shape_faces_and_area():
    sk = straight_skeleton(L_SHAPE)
    check_skeleton(sk, L_SHAPE, rel=1e-12)
    assert sk.times.max() == pytest.approx(1.0)
    # arm ends are triangles
    assert len(sk.faces[1]) == 3 and len(sk.faces[4]) == 3


@pytest.mark.parametrize("shape", [T_SHAPE, U_SHAPE, H_SHAPE, PLUS], ids=["T", "U", "H", "plus"])
def test_building_shapes(shape):
    check_skeleton(straight_skeleton(shape), shape, rel=1e-12)


def test_plus_collapses_to_one_centre_node():
    sk = straight_skeleton(PLUS)
    top = sk.nodes[sk.times == sk.times.max()]
    assert sk.times.max() == pytest.approx(0.5)
    assert np.any(np.all(np.isclose(top, [1.5, 1.5]), axis=1))


def test_regular_polygons_single_apex():
    for n in (3, 5, 6, 8, 12):
        p = circle(n, 3.0)
        sk = straight_skeleton(p)
        assert len(sk.nodes) == n + 1
        assert sk.times[-1] == pytest.approx(3.0 * np.cos(np.pi / n))
        check_skeleton(sk, p)


def test_64gon_terminates():
    # termination is guaranteed by the iteration bound; speed is measured in benchmarks, not here
    p = circle(64, 10.0)
    check_skeleton(straight_skeleton(p), p)
    rng = np.random.default_rng(3)
    p = circle(64, radii=rng.uniform(5, 10, 64))
    check_skeleton(straight_skeleton(p), p)


def test_courtyard_holes():
    outer = rect(0, 0, 10, 10)
    hole = rect(3, 3, 7, 7)[::-1]
    sk = straight_skeleton(outer, [hole])
    check_skeleton(sk, outer, [hole])
    assert len(sk.faces) == 8
    assert sk.times.max() == pytest.approx(1.5)
    holes = [rect(1, 1, 4, 4)[::-1], rect(6, 6, 9, 9)[::-1], rect(6, 1, 9, 4)[::-1]]
    check_skeleton(straight_skeleton(outer, holes), outer, holes)
    off = [rect(2, 3, 7, 8)[::-1]]
    check_skeleton(straight_skeleton(outer, off), outer, off)


def test_collinear_and_duplicate_vertices():
    p = np.array([[0, 0], [2, 0], [5, 0], [10, 0], [10, 4], [10, 4], [4, 4], [0, 4], [0, 0]], float)
    sk = straight_skeleton(p)
    assert len(sk.faces) == len(p)
    assert len(sk.faces[4]) == 0 and len(sk.faces[8]) == 0  # zero-length input edges
    np.testing.assert_allclose(sk.nodes[: len(p)], p)
    good = [k for k, f in enumerate(sk.faces) if len(f)]
    total = sum(sk.face_area(k) for k in good)
    assert total == pytest.approx(40.0)
    for k in good:
        assert sk.face_area(k) > 0
    assert sk.times.max() == pytest.approx(2.0)


@pytest.mark.parametrize("noise", [1e-12, 1e-9, 1e-7, 1e-4])
def test_nearly_collinear_vertices(noise):
    rng = np.random.default_rng(7)
    for shape in (rect(0, 0, 10, 4), L_SHAPE, H_SHAPE):
        pts = []
        n = len(shape)
        for i in range(n):
            a, b = shape[i], shape[(i + 1) % n]
            for t in (0.0, 0.3, 0.55, 0.8):
                q = a + t * (b - a)
                pts.append(q if t == 0 else q + rng.normal(size=2) * noise)
        pts = np.array(pts)
        check_skeleton(straight_skeleton(pts), pts, rel=1e-6)


def test_clockwise_input_keeps_edge_numbering():
    cw = L_SHAPE[::-1].copy()
    sk = straight_skeleton(cw)
    check_skeleton(sk, cw[::-1])
    n = len(cw)
    for k, f in enumerate(sk.faces):
        assert {int(f[0]), int(f[1])} == {k, (k + 1) % n}


def test_large_coordinates():
    p = L_SHAPE * 3 + np.array([512_345.0, 5_412_345.0])
    sk = straight_skeleton(p)
    check_skeleton(sk, p, rel=1e-9)
    assert sk.times.max() == pytest.approx(3.0)


def test_height_at_matches_distance():
    sk = straight_skeleton(rect(0, 0, 10, 4))
    assert sk.height_at([1.0, 1.5]) == pytest.approx(1.0)
    assert sk.height_at([5.0, 2.0]) == pytest.approx(2.0)
    assert np.isnan(sk.height_at([20.0, 2.0]))


def test_weighted_skeleton_gable_rectangle():
    sk = straight_skeleton(rect(0, 0, 4, 2), weights=[1, 0, 1, 0])
    assert [len(f) for f in sk.faces] == [4, 3, 4, 3]
    inner = sk.nodes[4:]
    np.testing.assert_allclose(sorted(inner[:, 0]), [0, 4], atol=1e-12)
    np.testing.assert_allclose(inner[:, 1], [1, 1], atol=1e-12)


# --------------------------------------------------------------------------- errors
def test_invalid_inputs_raise():
    with pytest.raises(ValueError, match="not simple"):
        straight_skeleton(np.array([[0, 0], [4, 3], [4, 0], [0, 1]], float))  # bow tie
    with pytest.raises(ValueError, match="fewer than 3"):
        straight_skeleton(np.array([[0, 0], [1, 1], [0, 0]], float))
    with pytest.raises(ValueError, match="zero area"):
        straight_skeleton(np.array([[0, 0], [1, 1], [2, 2]], float))
    with pytest.raises(ValueError, match="shape"):
        straight_skeleton(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        straight_skeleton(np.array([[0, 0], [1, np.nan], [0, 1]], float))
    with pytest.raises(ValueError, match="weights"):
        straight_skeleton(rect(0, 0, 1, 1), weights=[1, 1])


def test_iteration_bound_raises_instead_of_looping():
    tight = SkeletonTolerance(iterations_per_edge=0)
    with pytest.raises(ValueError, match="no convergence"):
        straight_skeleton(circle(200, radii=np.random.default_rng(0).uniform(1, 2, 200)),
                          tolerance=tight)


# --------------------------------------------------------------------------- random footprints
@st.composite
def rect_unions(draw, with_holes=True):
    k = draw(st.integers(1, 6))
    boxes = []
    for _ in range(k):
        x0 = draw(st.integers(0, 10))
        y0 = draw(st.integers(0, 10))
        w = draw(st.integers(1, 6))
        h = draw(st.integers(1, 6))
        boxes.append(box(x0, y0, x0 + w, y0 + h))
    u = unary_union(boxes)
    if isinstance(u, MultiPolygon):
        u = max(u.geoms, key=lambda g: g.area)
    u = u.simplify(0)
    outer = np.array(u.exterior.coords)[:-1]
    holes = [np.array(r.coords)[:-1] for r in u.interiors] if with_holes else []
    angle = draw(st.sampled_from([0.0, 0.0, 17.0, 45.0, 123.4]))
    c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))
    rot = np.array([[c, -s], [s, c]])
    return outer @ rot.T, [h @ rot.T for h in holes]


@SETTINGS
@given(rect_unions())
def test_random_rectilinear_unions(poly):
    outer, holes = poly
    sk = straight_skeleton(outer, holes or None)
    check_skeleton(sk, outer, holes)


@st.composite
def convex_polygons(draw):
    n = draw(st.integers(3, 24))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    from shapely.geometry import MultiPoint

    hull = MultiPoint(rng.normal(size=(n + 3, 2)) * rng.uniform(1, 20)).convex_hull
    return np.array(hull.exterior.coords)[:-1][::-1]  # shapely hulls are clockwise


@SETTINGS
@given(convex_polygons())
def test_random_convex_height_is_distance_to_nearest_edge_line(p):
    if Polygon(p).exterior.is_ccw is False:
        p = p[::-1]
    sk = straight_skeleton(p)
    check_skeleton(sk, p)
    rng = np.random.default_rng(0)
    poly = Polygon(p)
    x0, y0, x1, y1 = poly.bounds
    d = np.roll(p, -1, axis=0) - p
    d /= np.linalg.norm(d, axis=1)[:, None]
    normals = np.column_stack([-d[:, 1], d[:, 0]])
    from shapely.geometry import Point

    checked = 0
    for q in rng.uniform([x0, y0], [x1, y1], size=(60, 2)):
        if not poly.contains(Point(q)):
            continue
        expected = np.min(np.einsum("ij,ij->i", normals, q - p))
        assert sk.height_at(q) == pytest.approx(expected, abs=1e-9 * (x1 - x0 + y1 - y0))
        checked += 1
    assert checked > 0


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.integers(4, 60), st.integers(0, 2**31 - 1))
def test_random_star_polygons(n, seed):
    rng = np.random.default_rng(seed)
    a = np.sort(rng.uniform(0, 2 * np.pi, n))
    if len(np.unique(np.round(a, 6))) < n:
        return
    p = np.column_stack([np.cos(a), np.sin(a)]) * rng.uniform(0.3, 1.0, n)[:, None] * 10
    if not Polygon(p).is_valid:
        return
    check_skeleton(straight_skeleton(p), p)
