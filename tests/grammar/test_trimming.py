"""Trim planes (CityEngine "trim operation" / "trim attribute" / insert note): comp(f) makes
them, i(), primitives and trim() cut at them, set(trim.*) switches them.

Golden numbers are worked out by hand on a 10 × 10 × 4 m box (lot_size "10x10", extrude(4)):
a 45° plane at each vertical corner keeps, at depth h behind (or in front of) a facade, what
lies at least h from the corner edge (or at most h past it).
"""

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import DerivationError, RuleError
from facadeforge.geometry.mesh import Mesh
from facadeforge.grammar.ops.geometry import extrude_mesh
from facadeforge.grammar.ops.trimming import (
    FacePlanes,
    MeshEdges,
    TrimState,
    apply_trim,
    trim_mesh,
)
from facadeforge.grammar.state import ShapeState
from facadeforge.model.scope import Scope

# an inward box, 1 m deep, on each facade: the four of them meet at the corners
INWARD = "s('1, '1, 1) t(0, 0, -1) {insert} B."


def _model(rules: str, lot: str = "10x10", **kw):
    (m,) = derive(rules + "\n", lot_size=lot, **kw)
    return m


def _boxes(body: str, insert: str = 'i("builtin:cube")'):
    rule = "Lot --> extrude(4) comp(f) { side : " + body.format(insert=insert) + " | all : NIL }"
    m = _model(rule)
    assert not m.warnings
    return m


def _up_area(mesh: Mesh) -> float:
    """Area of the faces looking straight up (the tops of the boxes)."""
    up = mesh.face_normals()[:, 1] > 0.99
    return float(mesh.face_areas()[up].sum())


@pytest.mark.parametrize("insert", ['i("builtin:cube")', "primitiveCube()"])
def test_inserted_boxes_are_mitred_at_the_corners(insert):
    m = _boxes(INWARD, insert)
    assert len(m.parts) == 4
    for p in m.parts:
        # front 10×4, back 8×4, top and bottom trapezoids (10 + 8) / 2 × 1; both ends cut away
        assert p.mesh.n_faces == 4
        assert p.mesh.area() == pytest.approx(40 + 32 + 9 + 9)
        assert _up_area(p.mesh) == pytest.approx(9.0)
    # the four mitred tops tile the 10 × 10 − 8 × 8 ring exactly: no overlap, no gap
    assert sum(_up_area(p.mesh) for p in m.parts) == pytest.approx(36.0)


def test_mitred_box_vertices():
    m = _boxes(INWARD)
    front = next(p.mesh for p in m.parts if p.mesh.vertices[:, 2].min() > 8.5)  # the z = 10 facade
    v = np.round(front.vertices, 9) + 0.0
    back = v[np.abs(v[:, 2] - 9.0) < 1e-9]
    assert sorted(set(back[:, 0].tolist())) == [1.0, 9.0]  # back face runs 1 … 9, not 0 … 10
    face = v[np.abs(v[:, 2] - 10.0) < 1e-9]
    assert sorted(set(face[:, 0].tolist())) == [0.0, 10.0]


def test_trim_vertical_false_keeps_the_whole_asset():
    m = _boxes("set(trim.vertical, false) " + INWARD)
    for p in m.parts:
        assert p.mesh.n_faces == 6
        assert p.mesh.area() == pytest.approx(2 * 40 + 2 * 10 + 2 * 4)


def test_horizontal_planes_only_when_switched_on():
    rule = ("Lot --> extrude(4) comp(f) { front : set(trim.vertical, false) "
            "set(trim.horizontal, true) " + INWARD.format(insert='i("builtin:cube")')
            + " | all : NIL }")
    (p,) = _model(rule).parts
    # cut at 45° along the top edge (roof face) and the bottom edge (floor face): the side
    # profile is a trapezoid 4 m high at the facade, 2 m at the back
    assert p.mesh.n_faces == 4
    assert p.mesh.area() == pytest.approx(10 * 4 + 10 * 2 + 2 * 3)


def test_outward_geometry_is_cut_only_past_the_corner():
    # a slab on the facade, 1 m thick and 1 m wider than the facade at each end
    slab = "s(12, '1, 0) center(x) extrude(1) {trim} B."
    untrimmed = _model("Lot --> extrude(4) comp(f) { front : " + slab.format(trim="")
                       + " | all : NIL }").parts[0].mesh
    assert untrimmed.n_faces == 6 and untrimmed.area() == pytest.approx(128.0)
    (p,) = _model("Lot --> extrude(4) comp(f) { front : " + slab.format(trim="trim()")
                  + " | all : NIL }").parts
    # inner face 10×4, outer face 12×4 untouched, top and bottom trapezoids (10 + 12) / 2 × 1
    assert p.mesh.n_faces == 4
    assert p.mesh.area() == pytest.approx(40 + 48 + 11 + 11)
    lo, hi = p.mesh.bounds()
    assert lo.tolist() == pytest.approx([-1, 0, 10]) and hi.tolist() == pytest.approx([11, 4, 11])


def test_trim_without_comp_does_nothing():
    m = _model("Lot --> extrude(4) trim() B.")
    assert not m.warnings
    assert m.parts[0].mesh.n_faces == 6 and m.parts[0].mesh.area() == pytest.approx(360.0)


def test_split_children_inherit_the_planes():
    m = _boxes("split(x) {{ ~5 : " + INWARD + " }}*")
    assert len(m.parts) == 8
    # each corner piece loses its mitred end, the middle ends stay square
    assert sorted(round(_up_area(p.mesh), 9) for p in m.parts) == [4.5] * 8
    assert sum(_up_area(p.mesh) for p in m.parts) == pytest.approx(36.0)


def test_trim_attributes_read_and_set():
    rule = ('Lot --> report("h", trim.horizontal) report("v", trim.vertical) '
            "set(trim.horizontal, true) set(trim.vertical, 0) "
            'extrude(2) comp(f) { top : report("h2", trim.horizontal) report("v2", trim.vertical) X. '
            "| all : NIL }")
    m = _model(rule)
    assert {k: v[0] for k, v in m.reports.items()} == {"h": False, "v": True, "h2": True,
                                                       "v2": False}


def test_bad_trim_arguments_warn_or_fail():
    m = _model("Lot --> set(trim.diagonal, true) set(trim.vertical, \"no\") X.")
    assert len(m.warnings) == 2
    assert "trim.horizontal or trim.vertical" in m.warnings[0]
    assert "set(trim.vertical, …) takes true or false" in m.warnings[1]
    with pytest.raises(DerivationError, match="trim.diagonal"):
        _model("Lot --> set(trim.diagonal, true) X.", strict=True)
    with pytest.raises(RuleError, match=r"trim\(\) takes 0 arguments"):
        load_rules("Lot --> trim(1) X.\n")


# ---- the planes themselves ----------------------------------------------------------------

def _prism(ring, height=4.0) -> Mesh:
    base = Mesh.from_polygons([np.array([[x, 0.0, z] for x, z in ring])])
    if base.face_normals()[0, 1] < 0:
        base = base.reversed()
    mesh, _ = extrude_mesh(base, lambda n: n, height)
    return mesh


def test_every_plane_keeps_its_face_and_cuts_the_neighbour_on_an_l_shape():
    # an L-shaped footprint has a concave corner, where the plane must lean the other way
    mesh = _prism([(0, 0), (0, 10), (10, 10), (10, 5), (5, 5), (5, 0)])
    edges = MeshEdges(mesh)
    normals = mesh.face_normals()
    sides = np.flatnonzero(np.abs(normals[:, 1]) < 0.5)
    assert len(sides) == 6
    for f in sides:
        origins, planes, vertical = FacePlanes(edges, (f,), np.array([0.0, 1, 0])).planes()
        assert vertical.sum() == 2 and (~vertical).sum() == 2  # two corners, top and bottom
        own = mesh.vertices[mesh.face(f)]
        for o, n in zip(origins, planes):
            assert ((own - o) @ n >= -1e-9).all()
            # the neighbouring face's centre (sharing this edge) lies on the cut side
            centres = np.array([mesh.vertices[mesh.face(g)].mean(axis=0) for g in range(mesh.n_faces)])
            d = (centres - o) @ n
            on_edge = np.array([np.any(np.abs((mesh.vertices[mesh.face(g)] - o) @ n) < 1e-9)
                                for g in range(mesh.n_faces)])
            assert (d[on_edge & (np.arange(mesh.n_faces) != f)] < 0).any()


def test_concave_corner_plane_is_the_45_degree_bisector():
    mesh = _prism([(0, 0), (0, 10), (10, 10), (10, 5), (5, 5), (5, 0)])
    edges = MeshEdges(mesh)
    # the wall at z = 5 from x = 5 to 10 (normal -z after the base is made to face up… find it)
    centres = np.array([mesh.vertices[mesh.face(g)].mean(axis=0) for g in range(mesh.n_faces)])
    f = int(np.flatnonzero(np.isclose(centres[:, 2], 5) & np.isclose(centres[:, 0], 7.5))[0])
    origins, normals, vertical = FacePlanes(edges, (f,), np.array([0.0, 1, 0])).planes()
    at_corner = np.isclose(origins[:, 0], 5) & vertical
    (n,) = normals[at_corner]
    assert np.abs(n).tolist() == pytest.approx([np.sqrt(0.5), 0, np.sqrt(0.5)])


def test_groups_get_planes_only_at_their_border():
    mesh = _prism([(0, 0), (0, 10), (10, 10), (10, 0)])
    sides = tuple(np.flatnonzero(np.abs(mesh.face_normals()[:, 1]) < 0.5).tolist())
    _, _, vertical = FacePlanes(MeshEdges(mesh), sides, np.array([0.0, 1, 0])).planes()
    assert len(vertical) == 8 and not vertical.any()  # 4 top and 4 bottom edges, no corners


def test_hip_roof_planes_classified_against_the_face_pivot():
    # on a hip roof the hips make vertical planes (54.7° to the eave on a 45° roof face), ridge
    # and eaves horizontal ones, as in the reference's pictures
    from facadeforge.grammar.ops.subdivision import face_scope

    (part,) = _model("Lot --> roofHip(45) R.", lot="10x6").parts
    roof = part.mesh
    edges = MeshEdges(roof)
    normals = roof.face_normals()
    kinds = []
    for f in np.flatnonzero(normals[:, 1] > 0.1):
        up = face_scope(roof.vertices[roof.face(f)], normals[f]).rotation[:, 1]
        _, _, vertical = FacePlanes(edges, (f,), up).planes()
        kinds.append((len(roof.face(f)), int(vertical.sum()), int((~vertical).sum())))
    # trapezoids: 2 hips, the ridge and the eave (shared with the bottom face);
    # triangles: 2 hips and the eave
    assert sorted(kinds) == [(3, 2, 1), (3, 2, 1), (4, 2, 2), (4, 2, 2)]
    cut = _model("Lot --> roofHip(45) comp(f) { bottom : NIL | all : "
                 "s('1, '1, 0.3) t(0, 0, -0.3) i(\"builtin:cube\") R. }", lot="10x6")
    whole = _model("Lot --> roofHip(45) comp(f) { bottom : NIL | all : set(trim.vertical, false) "
                   "s('1, '1, 0.3) t(0, 0, -0.3) i(\"builtin:cube\") R. }", lot="10x6")
    assert not cut.warnings
    assert sum(p.mesh.area() for p in cut.parts) < sum(p.mesh.area() for p in whole.parts) - 1.0


# ---- cutting ---------------------------------------------------------------------------------

def test_trim_mesh_interpolates_uvs_and_reports_sources():
    quad = Mesh(np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0.0]]), [[0, 1, 2, 3]],
                [np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])])
    keep = Mesh(np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1.0]]), [[0, 1, 2]])
    mesh = Mesh.merge([keep, quad])
    # keep x <= 1: the triangle (x <= 1) stays whole, the quad loses its far half
    out, source = trim_mesh(mesh, np.array([[-1.0, 0, 0]]), np.array([-1.0]))
    assert source.tolist() == [0, 1] and out.n_faces == 2
    assert out.subset([0]).area() == pytest.approx(0.5)
    cut_quad = out.subset([1])
    assert cut_quad.area() == pytest.approx(2.0)
    uv = cut_quad.corner_uvs
    assert uv[:, 0].max() == pytest.approx(0.5) and uv[:, 0].min() == pytest.approx(0.0)


def test_trim_mesh_leaves_uncut_meshes_alone():
    mesh = _prism([(0, 0), (0, 1), (1, 1), (1, 0)])
    out, source = trim_mesh(mesh, np.array([[-1.0, 0, 0]]), np.array([-5.0]))
    assert out is mesh and source.tolist() == list(range(6))
    out, source = trim_mesh(mesh, np.array([[-1.0, 0, 0]]), np.array([5.0]))
    assert out.n_faces == 0 and len(source) == 0


def test_per_face_materials_follow_their_faces():
    mesh = _prism([(0, 0), (0, 1), (1, 1), (1, 0)])
    st = ShapeState(Scope(np.zeros(3), np.eye(3), np.ones(3)), mesh.with_column("material", range(6)))

    class _Planes(FacePlanes):
        def planes(self):  # x <= 0.5 kept: the +x face goes, the others are halved or kept
            return np.array([[0.5, 0, 0]]), np.array([[-1.0, 0, 0]]), np.array([True])

    st.trim = TrimState(_Planes(None, (), np.array([0.0, 1, 0])))
    assert apply_trim(st)
    fm = st.geometry.column("material")
    normals = st.geometry.face_normals()
    assert len(fm) == st.geometry.n_faces == 5
    original = mesh.face_normals()
    for f in range(5):
        assert normals[f] == pytest.approx(original[fm[f]])


# ---- instancing ----------------------------------------------------------------------------

TILES = """
Lot --> extrude(7) comp(f) { side : Facade | all : NIL }
Facade --> split(y) { ~3.5 : Floor }*
Floor --> split(x) { ~2 : Tile }*
Tile --> s('1, '1, 0.8) t(0, 0, -0.8) i("builtin:cube") Box.
"""


def _faces(m):
    rows = []
    for p in m.parts:
        for q in p.mesh.polygons():
            rows.append(tuple(np.round(np.sort(q, axis=0), 6).reshape(-1).tolist()))
    return sorted(rows)


def test_instanced_derivation_trims_like_the_plain_one():
    rules = load_rules(TILES)
    plain = derive(rules, lot_size="12.5x8.2", keep_tree=True)[0]
    fast = derive(rules, lot_size="12.5x8.2", keep_tree=False)[0]
    assert _faces(plain) == _faces(fast)
    untrimmed = derive(TILES.replace("Tile -->", "Tile --> set(trim.vertical, false)"),
                       lot_size="12.5x8.2")[0]
    # only the boxes in the corner columns lose their mitred ends
    assert sum(p.mesh.area() for p in plain.parts) < sum(p.mesh.area() for p in untrimmed.parts)


def test_switching_trim_planes_inside_an_instanced_subtree():
    # the top row of boxes gets cut by the horizontal plane at the roof edge, the others not
    rules = load_rules(TILES.replace("Tile -->", "Tile --> set(trim.horizontal, true)"))
    plain = derive(rules, lot_size="12.5x8.2", keep_tree=True)[0]
    fast = derive(rules, lot_size="12.5x8.2", keep_tree=False)[0]
    assert _faces(plain) == _faces(fast)
    vertical_only = derive(TILES, lot_size="12.5x8.2")[0]
    assert sum(p.mesh.area() for p in plain.parts) < sum(p.mesh.area()
                                                         for p in vertical_only.parts)


L_RULES = """
Lot --> extrude(6) comp(f) { side : Facade | all : NIL }
Facade --> split(y) { ~3 : split(x) { ~2 : Tile }* }*
Tile --> i("{asset}")
"""


@pytest.mark.parametrize("asset", ["builtin:cube", "slab.obj"])
def test_fitted_assets_meet_at_a_concave_corner_when_instanced(tmp_path, asset):
    from facadeforge.geometry.footprints import Footprint

    # a thin slab (2 × 3 × 0.4) and the cube reach out in front of the facade by their
    # proportions; at the L's inner corner the neighbours' pieces overlap and are mitred
    (tmp_path / "slab.obj").write_text("v 0 0 0\nv 2 0 0\nv 2 3 0\nv 0 3 0\nv 0 0 0.4\nv 2 0 0.4\n"
                                       "v 2 3 0.4\nv 0 3 0.4\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\n"
                                       "f 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")
    ring = [(0, 0), (12, 0), (12, 6), (6, 6), (6, 12), (0, 12)]
    lot = Footprint("L", np.array([[x, 0.0, z] for x, z in ring]))
    rules = load_rules(L_RULES.replace("{asset}", asset), assets=tmp_path)
    plain = derive(rules, [lot], keep_tree=True)[0]
    fast = derive(rules, [lot], keep_tree=False)[0]
    assert not plain.warnings
    assert _faces(plain) == _faces(fast)
    whole = derive(L_RULES.replace("{asset}", asset).replace("Lot -->",
                                                              "Lot --> set(trim.vertical, false)"),
                   [lot], assets=tmp_path)[0]
    assert sum(p.mesh.area() for p in plain.parts) < sum(p.mesh.area() for p in whole.parts) - 0.1


def test_subtree_analysis_for_trim_keys():
    from facadeforge.grammar.instancing import Purity

    rules = load_rules("""
Lot --> comp(f) { all : A }
A --> split(x) { ~1 : B }*
B --> color("#ffffff") i("window.obj")
C --> s('1, '1, 0.3) i("window.obj")
D --> comp(v) { all : i("post.obj") }
E --> extrude(1) trim()
F --> set(trim.horizontal, true) B
""")
    p = Purity(rules.ruleset)
    main = rules.ruleset.main
    info = {name: p.rule(main, name) for name in "ABCDEF"}
    assert info["A"].trims and info["A"].assets == {"window.obj"} and not info["A"].far
    assert info["C"].far and info["D"].far and info["E"].far and info["E"].trims
    assert not info["F"].pure  # switching planes on or off is never replayed
