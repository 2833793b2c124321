"""Mesh clean-up kernels (geometry/cleanup.py) on hand-made meshes with hand-counted answers."""

import numpy as np
import pytest

from facadeforge.geometry import cleanup as k
from facadeforge.geometry.mesh import Mesh


def grid(nx, nz, size=1.0, uv=None):
    """A flat nx × nz grid of unit quads in the xz plane (normal +y), vertices not shared.
    ``uv``: None, "affine" (uv = x, z) or "tiles" (every quad 0..1)."""
    polys, uvs = [], []
    for i in range(nx):
        for j in range(nz):
            q = np.array([[i, 0, j + 1], [i + 1, 0, j + 1], [i + 1, 0, j], [i, 0, j]], float) * size
            polys.append(q)
            if uv == "affine":
                uvs.append(q[:, [0, 2]])
            elif uv == "tiles":
                uvs.append(np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float))
    return Mesh.from_polygons(polys, uvs if uv else None)


def n_used(mesh):
    return len(np.unique(mesh.corners))


# -- weld --------------------------------------------------------------------------------------

def test_weld_merges_identical_vertices_into_the_first():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 1e-9]], float)
    assert k.weld(v, 0.0).tolist() == [0, 1, 0, 1]


def test_weld_tolerance_is_a_distance_in_metres():
    v = np.array([[0, 0, 0], [0.5, 0, 0], [5, 0, 0]], float)
    assert k.weld(v, 0.4).tolist() == [0, 1, 2]
    assert k.weld(v, 0.6).tolist() == [0, 0, 2]


def test_weld_does_not_chain():
    # 0.5 m steps with a 0.6 m tolerance: the third vertex is 1 m from the first, so it stays
    v = np.array([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [1.5, 0, 0]], float)
    assert k.weld(v, 0.6).tolist() == [0, 0, 2, 2]


# -- cleanup -----------------------------------------------------------------------------------

def test_cleanup_all_turns_a_grid_into_one_quad():
    m, src = k.cleanup(grid(2, 1), "all", 0.0)
    assert m.n_faces == 1 and len(m.face(0)) == 4 and n_used(m) == 4
    assert m.area() == pytest.approx(2.0) and m.triangle_count() == 2
    assert src.tolist() == [0]
    assert m.face_normals()[0] == pytest.approx([0, 1, 0])


def test_cleanup_edges_keeps_the_collinear_corners():
    m, _ = k.cleanup(grid(2, 1), "edges", 0.0)
    # the merged hexagon keeps the two vertices where the removed edge met the outline
    assert m.n_faces == 1 and len(m.face(0)) == 6 and m.area() == pytest.approx(2.0)


def test_cleanup_merged_face_starts_with_the_first_edge():
    g = grid(3, 2)
    m, _ = k.cleanup(g, "edges", 0.0)
    assert m.n_faces == 1
    first = g.vertices[g.face(0)[0]]
    assert m.vertices[m.face(0)[0]] == pytest.approx(first)


def test_cleanup_vertices_only_welds_and_keeps_faces():
    m, _ = k.cleanup(grid(3, 2), "vertices", 0.0)
    # 3 x 2 quads share a 4 x 3 lattice; every lattice vertex is a corner of some face
    assert m.n_faces == 6 and n_used(m) == 12 and m.area() == pytest.approx(6.0)


def test_a_hole_is_never_merged_into_a_face():
    # a 3 x 3 ring of quads around a missing middle one
    g = grid(3, 3)
    ring = g.subset([f for f in range(9) if f != 4])
    m, _ = k.cleanup(ring, "edges", 0.0)
    assert m.area() == pytest.approx(8.0)
    assert 1 < m.n_faces < 8
    assert all(len(set(f.tolist())) == len(f) for f in m.faces)


def test_continuous_uvs_merge_and_tiled_uvs_do_not():
    m, _ = k.cleanup(grid(2, 1, uv="affine"), "all", 0.0)
    assert m.n_faces == 1 and len(m.face(0)) == 4
    # the merged face keeps uv = (x, z) at its corners
    assert m.corner_uvs == pytest.approx(m.vertices[m.corners][:, [0, 2]])
    m, _ = k.cleanup(grid(2, 1, uv="tiles"), "all", 0.0)
    assert m.n_faces == 2


def test_groups_keep_faces_apart():
    m, src = k.cleanup(grid(2, 1), "all", 0.0, groups=["glass", "wall"])
    assert m.n_faces == 2 and sorted(src.tolist()) == [0, 1]


def test_faces_drops_duplicates_but_not_back_to_back_pairs():
    q = grid(1, 1)
    twice = Mesh.merge([q, q])
    m, _ = k.cleanup(twice, "faces", 0.0)
    assert m.n_faces == 1
    both_sides = Mesh.merge([q, q.reversed()])
    m, _ = k.cleanup(both_sides, "faces", 0.0)
    assert m.n_faces == 2


def test_faces_drops_degenerate_and_small_faces_by_tolerance():
    flat = Mesh(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float), [[0, 1, 2]])
    small = grid(1, 1, size=0.5)  # 0.25 m²
    big = Mesh.from_polygons([np.array([[3, 0, 1], [4, 0, 1], [4, 0, 0]], float)])  # 0.5 m²
    mesh = Mesh.merge([flat, small, big])
    assert k.cleanup(mesh, "faces", 0.0)[0].n_faces == 2
    assert k.cleanup(mesh, "faces", 0.2)[0].n_faces == 2
    m, src = k.cleanup(mesh, "faces", 0.3)
    assert m.n_faces == 1 and src.tolist() == [2]


def test_welding_by_tolerance_collapses_short_edges():
    # a quad with a 0.05 m notch corner: at 0.1 the two close corners weld, leaving a quad
    p = np.array([[0, 0, 1], [1, 0, 1], [1, 0, 0.05], [1, 0, 0], [0, 0, 0]], float)
    m, _ = k.cleanup(Mesh.from_polygons([p]), "vertices", 0.1)
    assert m.n_faces == 1 and len(m.face(0)) == 4


def test_collinear_vertex_kept_where_a_neighbour_uses_it_as_a_corner():
    # a 2 x 1 face above two 1 x 1 faces: the top face's bottom edge has a T vertex at x = 1
    top = np.array([[0, 0, 2], [2, 0, 2], [2, 0, 1], [1, 0, 1], [0, 0, 1]], float)
    left = np.array([[0, 0, 1], [1, 0, 1], [1, 0, 0], [0, 0, 0]], float)
    right = np.array([[1, 0, 1], [2, 0, 1], [2, 0, 0], [1, 0, 0]], float)
    mesh = Mesh.from_polygons([top, left, right])
    m, _ = k.cleanup(mesh, "vertices", 0.0)
    assert [len(f) for f in m.faces] == [5, 4, 4]
    # a collinear vertex no other face uses goes
    m, _ = k.cleanup(Mesh.from_polygons([top]), "vertices", 0.0)
    assert [len(f) for f in m.faces] == [4]


def test_near_coplanar_faces_merge_only_within_the_angle():
    # two unit quads hinged along x = 1, the second tilted by 5 degrees
    t = np.radians(5)
    a = np.array([[0, 0, 1], [1, 0, 1], [1, 0, 0], [0, 0, 0]], float)
    b = np.array([[1, 0, 1], [1 + np.cos(t), np.sin(t), 1], [1 + np.cos(t), np.sin(t), 0], [1, 0, 0]])
    mesh = Mesh.from_polygons([a, b])
    assert k.cleanup(mesh, "edges", 0.4)[0].n_faces == 2  # 4 degrees
    assert k.cleanup(mesh, "edges", 0.6)[0].n_faces == 1  # 6 degrees


def test_unknown_components_rejected():
    with pytest.raises(ValueError):
        k.cleanup(grid(1, 1), "corners", 0.0)


# -- holes -------------------------------------------------------------------------------------

def test_fill_holes_turns_a_ring_into_its_outline():
    ring = grid(3, 3).subset([f for f in range(9) if f != 4])
    m, src = k.fill_holes(ring)
    assert m.n_faces == 1 and len(m.face(0)) == 12  # the outline keeps its 12 lattice vertices
    assert m.area() == pytest.approx(9.0)
    assert m.face_normals()[0] == pytest.approx([0, 1, 0])
    assert src.tolist() == [0]


def test_fill_holes_leaves_faces_without_holes():
    g = grid(3, 3)
    m, _ = k.fill_holes(g)
    assert m.n_faces == 9 and m.area() == pytest.approx(9.0)


# -- conform -----------------------------------------------------------------------------------

def cube_mesh():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]]
    return Mesh(v, faces)


def test_conform_turns_a_cube_outwards():
    cube = cube_mesh()
    assert cube.volume() == pytest.approx(1.0)
    faces = cube.faces
    faces[2] = faces[2][::-1]  # one face turned in
    bad = Mesh(cube.vertices, faces)
    m, _ = k.conform(bad)
    assert m.volume() == pytest.approx(1.0)
    assert np.allclose(m.face_normals(), cube.face_normals())
    m, _ = k.conform(cube.reversed())
    assert m.volume() == pytest.approx(1.0)


def test_conform_open_surface_favours_up():
    g = grid(2, 2).reversed()
    assert g.face_normals()[:, 1] == pytest.approx([-1] * 4)
    m, _ = k.conform(g)
    assert m.face_normals()[:, 1] == pytest.approx([1] * 4)


# -- reduce ------------------------------------------------------------------------------------

def test_reduce_flat_grid_keeps_outline_and_area():
    g = grid(4, 4)  # 25 lattice vertices
    m, src = k.reduce(g, 0.6)
    assert n_used(m) == 10  # 25 - round(0.6 * 25)
    assert m.area() == pytest.approx(16.0)
    assert np.all(m.face_sizes == 3)
    lo, hi = m.bounds()
    assert lo == pytest.approx([0, 0, 0]) and hi == pytest.approx([4, 0, 4])
    assert set(src.tolist()) <= set(range(16))


def test_reduce_zero_is_unchanged():
    g = grid(2, 2)
    m, _ = k.reduce(g, 0.0)
    assert m.n_faces == 4 and len(m.vertices) == len(g.vertices)
