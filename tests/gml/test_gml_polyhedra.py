"""Convex polyhedra: cp-plane in 16.16 fixed point, cp-shell, splits, polyhedral scopes."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.gml import GmlRuntimeError, derive_gml
from facadeforge.gml.polyhedra import FIXED, Plane, Polyhedron


def test_plane_rounds_to_fixed_point():
    p = Plane.from_points((0, 0, 1e-7), (1, 0, 1e-7), (0, 1, 1e-7))
    assert np.allclose(p.normal, [0, 0, 1]) and p.offset == 0.0  # 1e-7 < 1/65536 rounds to 0
    q = Plane.from_points((0, 0, 0.3), (1, 0, 0.3), (0, 1, 0.3))
    assert q.offset == round(0.3 * FIXED) / FIXED
    assert Plane.from_points((0, 0, 0), (1, 1, 1), (2, 2, 2)) is None


def test_box_split_into_two_convex_pieces():
    b = Polyhedron.box((0, 0, 0), (2, 1, 1))
    inside, outside = b.split(Plane.from_points((0, 0, 0), (0, 1, 0), (1, 0, 1)))
    assert inside.is_convex() and outside.is_convex()
    assert np.isclose(inside.volume() + outside.volume(), 2.0)
    assert np.isclose(inside.volume(), 0.5)
    for piece in (inside, outside):
        mesh = piece.to_mesh()
        assert mesh.is_closed() and np.isclose(mesh.volume(), piece.volume())


def test_split_missing_the_polyhedron():
    b = Polyhedron.box((0, 0, 0), (1, 1, 1))
    inside, outside = b.split(Plane.through((5, 0, 0), (1, 0, 0)))
    assert inside is b and outside.empty
    inside, outside = b.split(Plane.through((1, 0, 0), (1, 0, 0)))  # touching a face
    assert not inside.empty and outside.empty


def test_shell_tetrahedron_and_unbounded():
    planes = [Plane.through((0, 0, 0), n) for n in ((-1, 0, 0), (0, -1, 0), (0, 0, -1))]
    t = Polyhedron.shell(planes + [Plane.through((1, 0, 0), (1, 1, 1))])
    assert len(t.vertices()) == 4 and np.isclose(t.volume(), 1 / 6) and t.is_convex()
    with pytest.raises(ValueError, match="bounded"):
        Polyhedron.shell(planes)


def test_gml_shell_and_split_plane():
    m = derive_gml("""[
        (0,0,0) (0,0,1) (0,1,0) cp-plane   % x >= 0
        (0,0,0) (1,0,0) (0,0,1) cp-plane   % y >= 0
        (0,0,0) (0,1,0) (1,0,0) cp-plane   % z >= 0
        (1,0,0) (0,1,0) (0,0,1) cp-plane   % x + y + z <= 1
    ] cp-shell cp-scope terminal-box""")
    assert len(m.parts) == 1
    mesh = m.parts[0].mesh
    assert mesh.n_faces == 4 and np.isclose(mesh.volume(), 1 / 6)


def test_axis_split_of_a_polyhedral_scope():
    # a wedge: the unit cube cut by x + y <= 1, then split along x into halves
    m = derive_gml("scope (1,0,0) (0,1,0) (1,0,1) cp-plane chop [ -1 -1 ] /X split "
                   "terminal-box terminal-box")
    vols = sorted(p.mesh.volume() for p in m.parts)
    assert np.allclose(vols, [0.125, 0.375])


def test_open_shell_is_a_gml_error():
    with pytest.raises(GmlRuntimeError, match="bounded"):
        derive_gml("[ (0,0,0) (0,0,1) (0,1,0) cp-plane ] cp-shell")
