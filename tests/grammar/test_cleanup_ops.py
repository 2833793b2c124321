"""cleanupGeometry, resetGeometry, deleteHoles, reduceGeometry, setNormals and softenNormals in
rules: hand-counted faces, vertices and areas.  Before these were implemented every one of them
left the shape unchanged, so each golden number below differs from the old result."""

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import DerivationError


def run(src, lot="10x8", strict=False, assets=None, keep_tree=True):
    return derive(load_rules(src, assets=assets), lot_size=lot, strict=strict,
                  keep_tree=keep_tree)[0]


def part(model, symbol="X"):
    (p,) = [p for p in model.parts if p.symbol == symbol]
    return p


def used(mesh):
    return len(np.unique(mesh.corners))


# -- cleanupGeometry ---------------------------------------------------------------------------

def test_cleanup_welds_an_extruded_box():
    before = part(run("Lot --> extrude(4) X."))
    assert used(before.mesh) == 24  # extrude gives every face its own corners
    m = run("Lot --> extrude(4) cleanupGeometry(all, 0) X.")
    mesh = part(m).mesh
    assert not m.warnings
    assert mesh.n_faces == 6 and used(mesh) == 8
    assert mesh.area() == pytest.approx(2 * 80 + 2 * 40 + 2 * 32)
    assert mesh.volume() == pytest.approx(320)


def test_cleanup_welds_a_sphere_without_merging_its_curved_faces():
    m = run("Lot --> primitiveSphere(32, 32, 5) cleanupGeometry(all, 0) X.")
    mesh = part(m).mesh
    # 32 x 32 faces; 31 rings of 32 vertices plus the two poles
    assert mesh.n_faces == 1024 and used(mesh) == 31 * 32 + 2


def test_cleanup_merges_a_triangulated_asset(tmp_path):
    # a 2 x 1 quad exported as two triangles, as CAD tools do: cleanup gives the quad back
    (tmp_path / "tri.obj").write_text(
        "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    src = 'Lot --> s(4, 2, 0) i("tri.obj") cleanupGeometry({c}, 0) X.'
    mesh = part(run(src.format(c="all"), assets=tmp_path)).mesh
    assert mesh.n_faces == 1 and mesh.face_sizes.tolist() == [4]
    assert mesh.area() == pytest.approx(4 * 2)
    assert mesh.triangle_count() == 2
    faces = part(run(src.format(c="faces"), assets=tmp_path)).mesh
    assert faces.n_faces == 2


def test_cleanup_keeps_faces_of_different_materials_apart(tmp_path):
    (tmp_path / "two.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n")
    (tmp_path / "two.obj").write_text(
        "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
        "usemtl red\nf 1 2 3 4\nusemtl blue\nf 2 5 6 3\n")
    m = run('Lot --> i("two.obj") cleanupGeometry(all, 0) X.', assets=tmp_path)
    assert not m.warnings
    colors = sorted(p.material.color for p in m.parts)
    assert colors == [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0)]
    assert all(p.mesh.n_faces == 1 for p in m.parts)


def test_cleanup_keeps_offset_face_kinds_for_comp():
    src = ("Lot --> offset(-1) cleanupGeometry(all, 0) comp(f) { inside : I. | border : B. }")
    m = run(src)
    inside = [p for p in m.parts if p.symbol == "I"]
    border = [p for p in m.parts if p.symbol == "B"]
    assert sum(p.mesh.area() for p in inside) == pytest.approx(48)
    assert sum(p.mesh.area() for p in border) == pytest.approx(32)
    # the four border trapezoids merge as far as they can without closing a hole: two faces,
    # still one ring, so one component (CityEngine's border is one face with a hole)
    assert len(inside) == 1 and len(border) == 1 and border[0].mesh.n_faces == 2


def test_cleanup_edges_on_a_border_ring():
    mesh = part(run("Lot --> offset(-1, border) cleanupGeometry(edges, 0) X.")).mesh
    assert mesh.n_faces == 2 and mesh.area() == pytest.approx(32)


@pytest.mark.parametrize("call, needle", [
    ("cleanupGeometry(corners, 0)", "components must be one of"),
    ("cleanupGeometry(all, 2)", "between 0 and 1"),
    ("cleanupGeometry(all, -0.1)", "between 0 and 1"),
    ("reduceGeometry(1.5)", "between 0 and 1"),
    ("setNormals(smooth)", "mode must be one of"),
    ("softenNormals(-10)", "between 0 and 180"),
])
def test_bad_arguments_warn_and_leave_the_shape(call, needle):
    m = run(f"Lot --> extrude(4) {call} X.")
    assert any(needle in w and call.split("(")[0] in w for w in m.warnings), m.warnings
    assert part(m).mesh.n_faces == 6 and used(part(m).mesh) == 24
    with pytest.raises(DerivationError):
        run(f"Lot --> extrude(4) {call} X.", strict=True)


def test_cleanup_needs_both_arguments():
    from facadeforge.errors import RuleError

    with pytest.raises(RuleError, match="cleanupGeometry\\(\\) takes 2 arguments"):
        load_rules("Lot --> cleanupGeometry(all) X.")


# -- resetGeometry -----------------------------------------------------------------------------

def test_reset_geometry_returns_to_the_lot_and_keeps_attributes():
    src = ('attr h = 1\n'
           'Lot --> color(1, 0, 0) set(h, 7) t(1, 2, 3) s(2, 2, 2) extrude(5) resetGeometry() '
           'report("sx", scope.sx) report("sz", scope.sz) report("h", h) X.')
    m = run(src)
    p = part(m)
    assert p.mesh.n_faces == 1 and p.mesh.area() == pytest.approx(80)
    lo, hi = p.mesh.bounds()
    assert lo == pytest.approx([0, 0, 0]) and hi == pytest.approx([10, 0, 8])
    assert p.material.color == (1.0, 0.0, 0.0)
    assert m.reports == {"sx": [pytest.approx(10)], "sz": [pytest.approx(8)], "h": [7.0]}


def test_reset_geometry_in_repeated_shapes_with_and_without_instancing():
    src = "Lot --> split(x) { 2 : F }*\nF --> resetGeometry() X."
    for keep in (True, False):
        parts = run(src, keep_tree=keep).parts
        assert len(parts) == 5
        for p in parts:
            lo, hi = p.mesh.bounds()
            assert lo == pytest.approx([0, 0, 0]) and hi == pytest.approx([10, 0, 8])


def test_reset_geometry_recursive_setbacks_sum_floor_areas():
    # the reference's example, smaller: every floor is set back from the lot, not from the last
    src = ("Lot --> SetBackRec(0)\n"
           "SetBackRec(i) --> case i < 3 : resetGeometry() "
           "setback(i) { all : NIL | remainder : report(\"a\", geometry.area) SetBackRec(i + 1) } "
           "else : NIL")
    m = run(src, lot="10x8")
    assert m.reports["a"] == pytest.approx([80, 8 * 6, 6 * 4])


# -- deleteHoles -------------------------------------------------------------------------------

def test_delete_holes_fills_an_offset_border():
    mesh = part(run("Lot --> offset(-1, border) deleteHoles() X.")).mesh
    assert mesh.n_faces == 1 and mesh.area() == pytest.approx(80)
    lo, hi = mesh.bounds()
    assert lo == pytest.approx([0, 0, 0]) and hi == pytest.approx([10, 0, 8])
    assert mesh.face_normals()[0] == pytest.approx([0, 1, 0])


def test_delete_holes_leaves_faces_without_holes():
    mesh = part(run("Lot --> extrude(4) deleteHoles() X.")).mesh
    assert mesh.n_faces == 6 and mesh.area() == pytest.approx(304)


# -- reduceGeometry ----------------------------------------------------------------------------

def test_reduce_geometry_halves_the_vertices_of_a_sphere():
    mesh = part(run("Lot --> primitiveSphere(32, 32, 5) reduceGeometry(0.5) X.")).mesh
    n = 31 * 32 + 2
    assert used(mesh) == n - round(0.5 * n)
    assert np.all(mesh.face_sizes == 3)
    before = part(run("Lot --> primitiveSphere(32, 32, 5) X.")).mesh
    assert mesh.area() == pytest.approx(before.area(), rel=0.05)


def test_reduce_geometry_never_empties_a_surface():
    # the lot's 4 corners, half to go: one corner folds onto a neighbour (one triangle left,
    # half the lot); the next collapse would leave nothing, so it is refused
    mesh = part(run("Lot --> reduceGeometry(0.5) X.")).mesh
    assert mesh.n_faces == 1 and used(mesh) == 3 and mesh.area() == pytest.approx(40)


def test_reduce_geometry_zero_changes_nothing():
    mesh = part(run("Lot --> extrude(4) reduceGeometry(0) X.")).mesh
    assert mesh.n_faces == 6 and used(mesh) == 24


# -- normals -----------------------------------------------------------------------------------

def test_set_normals_conform_turns_a_reversed_box_outwards():
    m = run("Lot --> extrude(4) reverseNormals() setNormals(conform) X.")
    assert part(m).mesh.volume() == pytest.approx(320)
    down = part(run("Lot --> reverseNormals() setNormals(conform) X.")).mesh
    assert down.face_normals()[0] == pytest.approx([0, 1, 0])


@pytest.mark.parametrize("call", ["setNormals(hard)", "setNormals(soft)", "setNormals(auto)",
                                  "softenNormals(30)"])
def test_shading_normals_are_accepted_and_leave_faces(call):
    m = run(f"Lot --> extrude(4) {call} X.")
    assert not m.warnings
    mesh = part(m).mesh
    assert mesh.n_faces == 6 and mesh.volume() == pytest.approx(320)
