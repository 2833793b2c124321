"""cleanupGeometry's one-face fast path gives what the general path gives, array for array."""

import numpy as np
import pytest

import facadeforge.geometry.cleanup as K
from facadeforge.geometry.mesh import Mesh


def _random_face(rng) -> Mesh:
    k = int(rng.integers(3, 8))
    ang = np.sort(rng.uniform(0, 2 * np.pi, k))
    r = rng.uniform(0.001, 3)
    pts = np.stack([np.cos(ang) * r, np.sin(ang) * r, np.zeros(k)], 1)
    kind = rng.integers(0, 6)
    if kind == 1:  # a corner on a straight edge
        pts = np.insert(pts, 1, (pts[0] + pts[1]) / 2, axis=0)
    elif kind == 2:  # two vertices a few millimetres apart
        pts = np.insert(pts, 1, pts[0] + rng.normal(size=3) * 0.005, axis=0)
    elif kind == 3:  # a rectangle on a centimetre grid
        w, h = rng.uniform(0.001, 2, 2).round(2)
        pts = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], float)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    pts = pts @ rot.T + rng.normal(size=3) * 10
    n = len(pts)
    verts, order = pts, np.arange(n)
    if rng.random() < 0.3:  # stored out of order, with a vertex no face uses
        perm = rng.permutation(n)
        verts = np.concatenate([pts[perm], rng.normal(size=(1, 3))])
        order = np.argsort(perm)
    uv = None
    if rng.random() < 0.5:
        uv = pts @ rng.normal(size=(3, 2)) if rng.random() < 0.5 else rng.normal(size=(n, 2))
    return Mesh(verts, corners=order.astype(np.int64), starts=np.array([0, n]), corner_uvs=uv)


def test_fast_path_equals_general_path(monkeypatch):
    rng = np.random.default_rng(11)
    fast = 0
    for trial in range(1500):
        mesh = _random_face(rng)
        comp = K.COMPONENTS[trial % 4]
        tol = [0.0, 1e-7, 0.01, 0.1, 0.5, 1.0][int(rng.integers(0, 6))]
        fast += K._untouched_face(mesh, comp, tol) is not None
        monkeypatch.setattr(K, "_SMALL", 12)
        a, sa = K.cleanup(mesh, comp, tol)
        monkeypatch.setattr(K, "_SMALL", 0)  # the general path only
        b, sb = K.cleanup(mesh, comp, tol)
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.corners, b.corners)
        assert np.array_equal(a.starts, b.starts) and np.array_equal(sa, sb)
        assert (a.corner_uvs is None) == (b.corner_uvs is None)
        if a.corner_uvs is not None:
            assert np.array_equal(a.corner_uvs, b.corner_uvs)
    assert 500 < fast < 1400  # both paths are exercised


@pytest.mark.parametrize("comp", K.COMPONENTS)
def test_close_calls_go_the_general_way(comp):
    """A corner on a straight edge, vertices within the tolerance, a face below the area
    limit: the fast path declines, whatever the components."""
    straight = Mesh(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], float),
                    [[0, 1, 2, 3, 4]])
    close = Mesh(np.array([[0, 0, 0], [1, 0, 0], [1.005, 0, 0], [1, 1, 0]], float),
                 [[0, 1, 2, 3]])
    tiny = Mesh(np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]], float),
                [[0, 1, 2, 3]])
    assert K._untouched_face(close, comp, 0.01) is None
    if comp in ("vertices", "all"):
        assert K._untouched_face(straight, comp, 0.0) is None
    if comp in ("faces", "all"):
        assert K._untouched_face(tiny, comp, 0.5) is None
    plain = Mesh(np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], float), [[0, 1, 2, 3]])
    assert K._untouched_face(plain, comp, 0.01) is not None
