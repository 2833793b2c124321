"""The all-slabs-at-once split (``cut._slabs_of_prism``) gives what Sutherland–Hodgman slab by
slab (``cut._clip_py``) gives: the same slabs, corners in the same order, the same UVs."""

import numpy as np
import pytest

from facadeforge.geometry import cut
from facadeforge.geometry.mesh import Mesh


def _face(kind: int, w: float, h: float, rng) -> np.ndarray:
    if kind == 0:
        pts = [[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]]
    elif kind == 1:
        pts = [[0, 0, 0], [w, 0, 0], [w, h, 0]]
    else:  # a trapezoid, and a pentagon with a corner off the two end planes (general path)
        pts = [[0, 0, 0], [w, 0, 0], [w, h, 0], [0.3 * w, h, 0]] if kind == 2 else \
            [[0, 0, 0], [w, 0, 0], [w, h, 0], [0.3 * w, h, 0], [0, 0.5 * h, 0]]
    pts = np.array(pts, float)
    if rng.random() < 0.5:
        pts = pts[::-1].copy()
    return np.roll(pts, int(rng.integers(0, len(pts))), axis=0)


def _plain(monkeypatch, mesh, axis, cuts):
    with monkeypatch.context() as m:
        m.setattr(cut, "_slabs_of_prism", lambda *a: None)
        return cut._split_single_face(mesh, axis, cuts)


@pytest.mark.parametrize("seed", range(4))
def test_all_slabs_at_once_equal_slab_by_slab(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    fast = 0
    for _ in range(300):
        axis = int(rng.integers(0, 2))
        w, h = rng.uniform(0.5, 5, 2)
        pts = _face(int(rng.integers(0, 4)), w, h, rng)
        mesh = Mesh(pts, corners=np.arange(len(pts)), starts=np.array([0, len(pts)]),
                    corner_uvs=pts[:, :2] * 0.37 + 0.1, closed=False)
        length = float(pts[:, axis].max())
        inner = np.sort(rng.uniform(0.01, length - 0.01, int(rng.integers(1, 9))))
        cuts = np.concatenate([[0.0], inner, [length]])
        fast += cut._slabs_of_prism(pts, mesh.corner_uvs, axis, cuts, None) is not None
        want, got = _plain(monkeypatch, mesh, axis, cuts), cut._split_single_face(mesh, axis, cuts)
        assert (want is None) == (got is None)
        if want is None:
            continue
        assert [m.n_faces for m in want] == [m.n_faces for m in got]
        for a, b in zip(want, got):
            if a.n_faces:
                assert a.vertices.shape == b.vertices.shape
                assert np.allclose(a.vertices, b.vertices, atol=1e-12)
                assert np.allclose(a.corner_uvs, b.corner_uvs, atol=1e-12)
    assert fast > 100  # the fast path was taken on most rectangles, triangles and trapezoids


def test_cuts_on_a_corner_plane_or_too_close_take_the_general_path():
    pts = np.array([[0, 0, 0], [4, 0, 0], [4, 3, 0], [0, 3, 0]], float)
    uv = pts[:, :2]
    assert cut._slabs_of_prism(pts, uv, 0, np.array([0.0, 1.0, 2.0, 4.0]), None) is not None
    assert cut._slabs_of_prism(pts, uv, 0, np.array([0.0, 1.0, 1.0, 4.0]), None) is None
    assert cut._slabs_of_prism(pts, uv, 0, np.array([0.0, 4.0, 4.0]), None) is None
    assert cut._slabs_of_prism(pts, uv, 0, np.array([0.5, 2.0, 4.0]), None) is None
