"""``clip_convex_faces``: many convex polygons clipped at once, point for point what the
per-polygon Sutherland–Hodgman (``_clip_halfspace``) gives, dropped polygons included."""

import numpy as np
import pytest

from facadeforge.geometry.cut import _clip_halfspace, clip_convex_faces


def _polygons(seed=0, count=300):
    rng = np.random.default_rng(seed)
    polys = []
    for k in range(count):
        n = int(rng.integers(3, 9))
        a = np.sort(rng.uniform(0, 2 * np.pi, n))
        c = rng.normal(size=3)
        r = rng.uniform(0.2, 2)
        p = np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a), np.full(n, c[2])])
        if k % 7 == 0:
            p[:2, 1] = 0.0  # corners on the plane: kept, snapped, no crossing point
        if k % 11 == 0:
            p[:, 1] = np.abs(p[:, 1]) + 0.5  # wholly on one side
        polys.append(p)
    return polys


@pytest.mark.parametrize("keep_below", [True, False])
def test_clip_convex_faces_equals_one_at_a_time(keep_below):
    polys = _polygons()
    p = np.concatenate(polys)
    uv = p[:, :2] * 0.3
    starts = np.concatenate([[0], np.cumsum([len(q) for q in polys])])
    q, quv, out_starts, left = clip_convex_faces(p, uv, starts, 1, 0.0, keep_below)
    ref = [(i, *_clip_halfspace(x, x[:, :2] * 0.3, 1, 0.0, keep_below))
           for i, x in enumerate(polys)]
    ref = [r for r in ref if r[1] is not None]
    assert 0 < len(ref) < len(polys)  # some polygons vanish, some stay
    assert list(left) == [i for i, *_ in ref]
    assert out_starts[-1] == len(q) == len(quv)
    for j, (_, rq, ruv) in enumerate(ref):
        a, b = out_starts[j], out_starts[j + 1]
        np.testing.assert_allclose(q[a:b], rq, atol=1e-12)
        np.testing.assert_allclose(quv[a:b], ruv, atol=1e-12)
    side = q[:, 1] if keep_below else -q[:, 1]
    assert side.max() <= 1e-9


def test_clip_convex_faces_without_uvs():
    polys = _polygons(1, 20)
    p = np.concatenate(polys)
    starts = np.concatenate([[0], np.cumsum([len(q) for q in polys])])
    q, quv, out_starts, left = clip_convex_faces(p, None, starts, 1, 0.0, False)
    assert quv is None and len(out_starts) == len(left) + 1


def test_plane_basis_is_right_handed_and_orthonormal():
    """``plane_basis`` on plain floats: columns u, v in the plane and the normal itself, a
    right-handed orthonormal frame, u along helper × n (x, or y near x) as numpy's version."""
    from facadeforge.geometry.mesh import plane_basis

    rng = np.random.default_rng(2)
    normals = [np.array(v, float) for v in ((1, 0, 0), (0, 0, -1), (0, 1, 0), (0.95, 0.1, 0.3))]
    normals += list(rng.normal(size=(200, 3)))
    for n in normals:
        n = n / np.linalg.norm(n)
        b = plane_basis(n)
        np.testing.assert_allclose(b.T @ b, np.eye(3), atol=1e-12)
        assert np.linalg.det(b) > 0.999999
        np.testing.assert_array_equal(b[:, 2], n)
        helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        u = np.cross(helper, n)
        np.testing.assert_allclose(b[:, 0], u / np.linalg.norm(u), atol=1e-14)
    assert np.isnan(plane_basis(np.zeros(3))[:, :2]).all()
