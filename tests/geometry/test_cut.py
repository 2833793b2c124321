"""Plane cuts: slabs tile the mesh exactly, closed meshes stay closed, UVs follow."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from facadeforge.geometry.cut import split_along_axis
from facadeforge.geometry.mesh import Mesh
from facadeforge.geometry.primitives import unit_cube


def box(sx, sy, sz):
    m = unit_cube()
    return m.with_vertices(m.vertices * [sx, sy, sz])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.05, 0.95), min_size=1, max_size=6, unique=True), st.integers(0, 2))
def test_slabs_partition_volume_and_stay_closed(fracs, axis):
    m = box(4.0, 3.0, 2.0)
    ext = [4.0, 3.0, 2.0][axis]
    cuts = np.array([0.0] + sorted(f * ext for f in fracs) + [ext])
    pieces = split_along_axis(m, axis, cuts)
    assert sum(p.volume() for p in pieces) == pytest.approx(24.0)
    for p, lo, hi in zip(pieces, cuts[:-1], cuts[1:]):
        if hi - lo > 1e-6:
            assert p.is_closed()
            assert p.volume() == pytest.approx(24.0 * (hi - lo) / ext)


def test_planar_quad_split_keeps_area_and_uvs():
    q = Mesh(np.array([[0, 0, 0], [10, 0, 0], [10, 4, 0], [0, 4, 0]], float), [[0, 1, 2, 3]],
             [np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)])
    pieces = split_along_axis(q, 0, np.array([0, 2.5, 10]))
    assert [p.area() for p in pieces] == [pytest.approx(10), pytest.approx(30)]
    uv = pieces[0].corner_uvs
    assert uv[:, 0].max() == pytest.approx(0.25)
    assert not pieces[0].is_closed()


def test_nonconvex_face_falls_apart_into_pieces():
    # a U-shaped polygon cut above its notch gives two separate faces
    u = np.array([[0, 0, 0], [6, 0, 0], [6, 4, 0], [4, 4, 0], [4, 1, 0], [2, 1, 0], [2, 4, 0],
                  [0, 4, 0]], float)
    m = Mesh(u, [list(range(8))])
    low, high = split_along_axis(m, 1, np.array([0, 2, 4]))
    assert high.n_faces == 2 and high.area() == pytest.approx(8)
    assert low.area() == pytest.approx(m.area() - 8)
