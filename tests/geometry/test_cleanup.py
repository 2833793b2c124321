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


# -- merging coplanar faces ---------------------------------------------------------------------

def corners_xz(mesh, f=0):
    """The corners of face ``f`` as (x, z) tuples, in order."""
    return [tuple(p) for p in mesh.vertices[mesh.face(f)][:, [0, 2]].tolist()]


def grid_outline(nx, nz):
    """Lattice points on the border of an nx × nz grid, in the order of its merged face: from
    (0, 1) up the x = 0 side, along z = nz, down x = nx, back along z = 0."""
    up = [(0, z) for z in range(1, nz + 1)]
    top = [(x, nz) for x in range(1, nx + 1)]
    down = [(nx, z) for z in range(nz - 1, -1, -1)]
    back = [(x, 0) for x in range(nx - 1, -1, -1)]
    return [(float(x), float(z)) for x, z in up + top + down + back]


def triangulated(mesh):
    """Every quad of ``mesh`` cut into triangles (0, 1, 2) and (0, 2, 3), uvs kept."""
    polys, uvs = [], []
    for face, uv in zip(mesh.faces, mesh.uvs):
        for t in ([0, 1, 2], [0, 2, 3]):
            polys.append(mesh.vertices[face[t]])
            uvs.append(None if uv is None else uv[t])
    return Mesh.from_polygons(polys, uvs if mesh.corner_uvs is not None else None)


@pytest.mark.parametrize("cut", [False, True], ids=["quads", "triangles"])
def test_merge_of_a_grid_is_its_outline_from_the_first_vertex(cut):
    g = grid(6, 4, uv="affine")
    g = triangulated(g) if cut else g
    m, src = k.cleanup(g, "edges", 0.0)
    assert m.n_faces == 1 and src.tolist() == [0]
    assert corners_xz(m) == grid_outline(6, 4)
    assert m.corner_uvs == pytest.approx(m.vertices[m.corners][:, [0, 2]])


def test_merge_of_a_big_grid_never_rebuilds_the_outline(monkeypatch):
    # face by face the outline is updated in place: the full rebuild (time proportional to the
    # outline, quadratic over a region) is only for odd faces, which a grid does not have
    def rebuild(outline, p):
        raise AssertionError("outline rebuilt")

    monkeypatch.setattr(k, "_grow_general", rebuild)
    m, _ = k.cleanup(grid(60, 40), "edges", 0.0)
    assert m.n_faces == 1 and corners_xz(m) == grid_outline(60, 40)


def test_merge_leaves_out_the_face_that_would_close_a_ring():
    # the 3 x 3 ring of test_a_hole_is_never_merged_into_a_face, face by face: from tile (0, 0)
    # the region grows depth first along z = 0, up x = 2, back along z = 2 and down to tile
    # (0, 1), which would close the ring around the hole: it stays a face of its own
    ring = grid(3, 3).subset([f for f in range(9) if f != 4])
    m, src = k.cleanup(ring, "edges", 0.0)
    assert src.tolist() == [0, 1]
    assert corners_xz(m, 0) == [(0, 1), (1, 1), (2, 1), (2, 2), (1, 2), (0, 2), (0, 3), (1, 3),
                                (2, 3), (3, 3), (3, 2), (3, 1), (3, 0), (2, 0), (1, 0), (0, 0)]
    assert corners_xz(m, 1) == [(0, 2), (1, 2), (1, 1), (0, 1)]
    assert m.area() == pytest.approx(8.0)


def test_merge_stops_at_a_uv_seam():
    # three tiles in a row, uv = (x, z) shifted by 0.5 on the last two: the first tile stays,
    # the other two merge, keeping their shifted uvs
    g = grid(3, 1, uv="affine")
    cuv = g.corner_uvs.copy()
    cuv[4:] += 0.5
    m, src = k.cleanup(g.with_uvs(cuv), "edges", 0.0)
    assert src.tolist() == [0, 1]
    assert corners_xz(m, 0) == [(0, 1), (1, 1), (1, 0), (0, 0)]
    assert corners_xz(m, 1) == [(1, 1), (2, 1), (3, 1), (3, 0), (2, 0), (1, 0)]
    assert m.uvs[1] == pytest.approx(np.array(corners_xz(m, 1)) + 0.5)


def test_merge_keeps_two_groups_apart():
    m, src = k.cleanup(grid(4, 1), "edges", 0.0, groups=["wall", "wall", "glass", "glass"])
    assert src.tolist() == [0, 2]
    assert corners_xz(m, 0) == [(0, 1), (1, 1), (2, 1), (2, 0), (1, 0), (0, 0)]
    assert corners_xz(m, 1) == [(2, 1), (3, 1), (4, 1), (4, 0), (3, 0), (2, 0)]
    # alternating groups: nothing merges
    m, _ = k.cleanup(grid(4, 1), "edges", 0.0, groups=["wall", "glass"] * 2)
    assert m.n_faces == 4


def loop(verts):
    """An outline ``vertex -> (next vertex, uv)`` around ``verts``, uv = (vertex, 0)."""
    return {a: (b, np.array([a, 0.0])) for a, b in zip(verts, verts[1:] + verts[:1])}


def same_outline(a, b):
    """Both ``None``, or the same entries in the same order."""
    if a is None or b is None:
        return a is None and b is None
    return list(a) == list(b) and all(a[v][0] == b[v][0] and np.array_equal(a[v][1], b[v][1])
                                      for v in a)


@pytest.mark.parametrize("outline, face, accepted", [
    ([0, 1, 2, 3], [1, 0, 4, 5], True),  # one shared edge
    ([0, 1, 2, 3, 4], [2, 1, 0, 5], True),  # two shared edges in a row
    ([0, 1, 2, 3, 4, 5], [1, 0, 6, 3], False),  # a corner off the shared edge is on it
    ([0, 1, 2, 3, 4, 5], [1, 0, 6, 4, 3, 7], False),  # two runs: a ring around a hole
    ([0, 1, 2], [2, 1, 0], False),  # every edge shared: nothing left
    ([0, 1, 2, 3], [4, 5, 6], False),  # apart
    ([9, 0, 8], [9, 0, 8], True),  # the outline itself again: the rebuild takes it (new uvs)
    ([7, 1, 8, 3, 5, 0, 4, 9, 6], [6, 9, 1, 7, 4, 0], True),  # three runs, one loop (not flat)
    ([0, 1, 2, 3], [1, 0, 4, 4, 5], True),  # a repeated corner: edge 4 -> 4 cancels itself
], ids=["one-edge", "two-edges", "corner-contact", "ring", "all-shared", "apart",
        "same-loop", "three-runs", "repeated-corner"])
def test_grow_is_the_rebuilt_outline(outline, face, accepted):
    # _grow updates the outline in place, in time of the face; _grow_general rebuilds it whole
    uvs = np.array([[v, 1.0] for v in face])
    want = k._grow_general(loop(outline), k.Poly(face, uvs, 0))
    got = k._grow(loop(outline), k.Poly(face, uvs, 0))
    assert (want is not None) == accepted
    assert same_outline(got, want)


def test_grow_is_the_rebuilt_outline_on_random_loops():
    rng = np.random.default_rng(3)
    accepted = 0
    for _ in range(3000):
        outline = rng.permutation(9)[:rng.integers(3, 9)].tolist()
        face = rng.permutation(11)[:rng.integers(3, 7)].tolist()
        uvs = rng.random((len(face), 2))
        want = k._grow_general(loop(outline), k.Poly(face, uvs, 0))
        assert same_outline(k._grow(loop(outline), k.Poly(face, uvs, 0)), want)
        accepted += want is not None
    assert accepted > 100


def varied_meshes():
    """Flat grids with missing tiles (holes, corner contacts), tiles cut into triangles or fans,
    turned over, repeated, with uv seams, two groups, shuffled faces and first corners; and
    soups of random lattice polygons (overlaps, edges of three faces, repeated corners)."""
    rng = np.random.default_rng(7)
    for case in range(300):
        polys, uvs = [], []
        if case % 3 == 2:  # a soup
            for _ in range(rng.integers(2, 12)):
                p = rng.integers(0, 3, size=(rng.integers(3, 6), 2))
                polys.append(np.insert(p, 1, 0, axis=1).astype(float))
        else:
            nx, nz = rng.integers(1, 7, size=2)
            for i in range(nx):
                for j in range(nz):
                    if rng.random() < 0.2:
                        continue
                    q = grid(1, 1).vertices + [i, 0, j]
                    r = rng.random()
                    if r < 0.25:
                        polys += [q[[0, 1, 2]], q[[0, 2, 3]]]
                    elif r < 0.35:  # a fan around the middle
                        c = q.mean(axis=0)
                        polys += [np.array([c, q[e], q[(e + 1) % 4]]) for e in range(4)]
                    elif r < 0.4:
                        polys.append(q[::-1])
                    elif r < 0.45:
                        polys += [q, q]
                    else:
                        polys.append(q)
        polys = [np.roll(p, -rng.integers(len(p)), axis=0) for p in polys]
        polys = [polys[f] for f in rng.permutation(len(polys))]
        uvs = [p[:, [0, 2]] + (0.5 if rng.random() < 0.15 else 0.0) for p in polys]
        groups = rng.integers(0, 2 if rng.random() < 0.3 else 1, size=len(polys)).tolist()
        yield Mesh.from_polygons(polys, uvs if case % 2 else None), groups


def merged(mesh, groups):
    polys = [p for p in k.to_polys(mesh, k.weld(mesh.vertices, 0.0)) if len(p.verts) >= 3]
    return k.merge_coplanar(mesh.vertices, polys, 0.0, groups)


def test_merge_gives_what_rebuilding_the_outline_face_by_face_gives(monkeypatch):
    # _grow_general is the former algorithm's step (the outline of region + face rebuilt and
    # walked); with it in place of _grow, merge_coplanar is the former algorithm
    fast = [merged(m, g) for m, g in varied_meshes()]
    monkeypatch.setattr(k, "_grow", k._grow_general)
    slow = [merged(m, g) for m, g in varied_meshes()]
    assert sum(len(a) for a in fast) < sum(m.n_faces for m, _ in varied_meshes())  # some merge
    for a, b in zip(fast, slow):
        assert [(p.verts, p.src) for p in a] == [(p.verts, p.src) for p in b]
        for p, q in zip(a, b):
            assert (p.uvs is None and q.uvs is None) or np.array_equal(p.uvs, q.uvs)


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
