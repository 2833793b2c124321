"""Scope and pivot operations (alignScopeToGeometryBBox, setPivot, mirrorScope, pivot.*) and
footprint, taper, resetMaterial, copyUV: golden values worked out by hand."""

import math

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.engine import derive_facade
from facadeforge.geometry.footprints import Footprint

# a parallelogram lot whose first edge is its slanted side: x along (1, 2)/sqrt(5)
SLANT = np.array([[4, 0, 0], [5, 0, 2], [1, 0, 2], [0, 0, 0]], float)
# L: a 10 x 2 arm (z in [2, 4]) and a 3 x 2 stub below its left end; total area 26
L_POLY = np.array([[0, 0, 0], [0, 0, 4], [10, 0, 4], [10, 0, 2], [3, 0, 2], [3, 0, 0]], float)[::-1]
R5 = math.sqrt(5)


def run(src, lot="10x8", poly=None, assets=None):
    fp = [Footprint("fp", poly)] if poly is not None else None
    return derive(load_rules(src, assets=assets), fp, lot_size=None if fp else lot)[0]


def prints(model):
    return [float(v) for v in model.attributes["prints"]]


def show(*names):
    return " ".join(f"print({n})" for n in names)


def bounds(model, symbol=None):
    ms = [p.mesh for p in model.parts if symbol is None or p.symbol == symbol]
    b = np.array([m.bounds() for m in ms])
    return b[:, 0].min(axis=0), b[:, 1].max(axis=0)


def warned(model, op, *words):
    """A warning from the real operation (the placeholder only says "not supported yet")."""
    return any(op in w and "not supported" not in w and all(x in w for x in words)
               for w in model.warnings)


def area(model, symbol=None):
    return sum(p.mesh.area() for p in model.parts if symbol is None or p.symbol == symbol)


# ---- alignScopeToGeometryBBox ------------------------------------------------------------------

def test_align_bbox_finds_the_minimum_rectangle_of_a_parallelogram():
    m = run("Lot --> " + show("scope.sx", "scope.sz") + " alignScopeToGeometryBBox(xz) "
            + show("scope.sx", "scope.sz", "scope.ry", "scope.tx", "scope.tz") + " A.", poly=SLANT)
    assert not m.warnings
    # before: the slanted frame, 9/sqrt5 x 8/sqrt5 (area 14.4); after: the axis-aligned 5 x 2
    assert prints(m) == pytest.approx([9 / R5, 8 / R5, 5, 2, 0, 0, 0], abs=1e-6)
    assert area(m) == pytest.approx(8)  # geometry untouched


def test_align_bbox_first_axis_takes_the_longer_side():
    # a 4 (x) by 10 (z) lot: xz turns x onto the 10 m side, zx keeps z there
    # (the pivot turns with the scope, so the turn shows in pivot.oy, and scope.ry, which is
    # relative to the pivot, stays 0)
    m = run("Lot --> alignScopeToGeometryBBox(xz) " + show("scope.sx", "scope.sz", "pivot.oy",
                                                            "scope.ry") + " A.", lot="4x10")
    assert prints(m)[:2] == pytest.approx([10, 4])
    assert abs(prints(m)[2]) == pytest.approx(90) and prints(m)[3] == pytest.approx(0, abs=1e-9)
    m = run("Lot --> alignScopeToGeometryBBox(zx) " + show("scope.sx", "scope.sz", "scope.ry")
            + " A.", lot="4x10")
    assert prints(m) == pytest.approx([4, 10, 0], abs=1e-6)


def test_align_bbox_undoes_rotate_scope():
    # rotateScope turns only the scope (refitted to 10 x 8 seen at 30 degrees); aligning brings
    # back the lot's own rectangle with the pivot on the scope origin
    m = run("Lot --> rotateScope(0, 30, 0) " + show("scope.sx") + " alignScopeToGeometryBBox(xz) "
            + show("scope.sx", "scope.sz", "scope.ry", "pivot.px", "pivot.pz", "pivot.oy") + " A.")
    sx_rot = 10 * math.cos(math.radians(30)) + 8 * math.sin(math.radians(30))
    assert prints(m) == pytest.approx([sx_rot, 10, 8, 0, 0, 0, 0], abs=1e-6)


def test_align_bbox_yx_on_a_facade_puts_y_on_the_long_side():
    m = derive_facade(load_rules("F --> alignScopeToGeometryBBox(yx) report(\"sx\", scope.sx) "
                                 "report(\"sy\", scope.sy) report(\"sz\", scope.sz) A."), 10, 4)
    assert [m.reports[k][0] for k in ("sx", "sy", "sz")] == pytest.approx([4, 10, 0], abs=1e-9)
    assert area(m) == pytest.approx(40)


def test_align_bbox_moves_the_pivot_to_the_scope_origin():
    m = run("Lot --> alignScopeToGeometryBBox(xz) " + show("pivot.px", "pivot.pz", "pivot.oy")
            + " A.", poly=SLANT)
    # the object frame (the initial scope) is turned by -63.43 degrees about y with its origin at
    # (3.2, 0, -1.6), the box corner; the new pivot is the world frame at (0, 0, 0)
    assert prints(m) == pytest.approx([0, 8 / R5, math.degrees(math.atan2(2, 1))], abs=1e-6)


@pytest.mark.parametrize("arg", ["xx", "xw", "x", "world"])
def test_align_bbox_rejects_bad_axes(arg):
    m = run(f"Lot --> alignScopeToGeometryBBox({arg}) A.")
    assert warned(m, "alignScopeToGeometryBBox")


# ---- setPivot ----------------------------------------------------------------------------------

def test_set_pivot_xyz_corner_1_turns_the_scope():
    # corner 1 is (sx, 0, 0): x and z must point inwards, so x runs along old z, z along -old x
    m = run("Lot --> setPivot(xyz, 1) "
            + show("scope.sx", "scope.sz", "pivot.px", "pivot.pz", "pivot.oy")
            + " split(x) { 3 : A | ~1 : B }")
    assert not m.warnings
    assert prints(m) == pytest.approx([8, 10, 10, 0, -90])
    lo, hi = bounds(m, "A")  # the first 3 m along old z, the whole 10 m along old x
    assert lo == pytest.approx([0, 0, 0]) and hi == pytest.approx([10, 0, 3])
    assert area(m) == pytest.approx(80)


def test_set_pivot_keeps_the_frame_at_corner_0_and_permutes_axes():
    m = run("Lot --> setPivot(xyz, 0) " + show("scope.sx", "scope.sz", "pivot.px", "pivot.oy")
            + " A.")
    assert prints(m) == pytest.approx([10, 8, 0, 0])
    # yzx: new x = old z, new y = old x, new z = old y
    m = run("Lot --> setPivot(yzx, 0) " + show("scope.sx", "scope.sy", "scope.sz") + " A.")
    assert prints(m) == pytest.approx([8, 10, 0])
    # zxy: new x = old y, new y = old z, new z = old x; that frame is 90 degrees about x, then
    # 90 degrees about z
    m = run("Lot --> setPivot(zxy, 0) " + show("scope.sx", "scope.sy", "scope.sz", "pivot.ox",
                                               "pivot.oy", "pivot.oz") + " A.")
    assert prints(m) == pytest.approx([0, 8, 10, 90, 0, 90])


def test_set_pivot_far_top_corner_of_a_box():
    # corner 6 of a 10 x 5 x 8 mass is (10, 5, 8): all three axes reversed -> x and z swap
    m = run("Lot --> extrude(5) setPivot(xyz, 6) "
            + show("pivot.px", "pivot.py", "pivot.pz", "scope.sx", "scope.sy", "scope.sz") + " A.")
    assert prints(m) == pytest.approx([10, 5, 8, 8, 5, 10])
    assert run("Lot --> extrude(5) setPivot(xyz, 6) A.").parts[0].mesh.volume() == pytest.approx(400)


def test_pivot_is_inherited_and_defaults_to_the_object_frame():
    m = run("Lot --> " + show("pivot.px", "pivot.ox") + " setPivot(xyz, 2) split(x) { ~1 : A }\n"
            "A --> " + show("pivot.px", "pivot.pz", "pivot.oy"))
    px, ox, *child = prints(m)
    assert (px, ox) == (0, 0)
    # corner 2 = (10, 0, 8): x and z both reversed, a half turn about y
    assert child[:2] == pytest.approx([10, 8])
    assert abs(child[2]) == pytest.approx(180) or child[2] == pytest.approx(0)


@pytest.mark.parametrize("args", ["xzy, 0", "xyz, 8", "xyz, -1", "xyz, 1.5", "abc, 0"])
def test_set_pivot_rejects_bad_arguments(args):
    m = run(f"Lot --> setPivot({args}) " + show("scope.sx", "pivot.px") + " A.")
    assert warned(m, "setPivot")
    assert prints(m) == [10, 0]  # unchanged


# ---- mirrorScope -------------------------------------------------------------------------------

def test_mirror_scope_flips_axes_and_keeps_geometry():
    m = run("Lot --> mirrorScope(true, false, true) " + show("scope.tx", "scope.tz", "scope.sx")
            + " split(x) { 2 : A | ~1 : B }")
    assert prints(m) == pytest.approx([10, 8, 10])
    lo, hi = bounds(m, "A")  # x now runs from world x = 10 backwards
    assert lo == pytest.approx([8, 0, 0]) and hi == pytest.approx([10, 0, 8])
    m = run("Lot --> mirrorScope(false, false, false) " + show("scope.tx") + " A.")
    assert prints(m) == [0]


def test_mirror_scope_single_flip_leaves_geometry():
    m = run("Lot --> extrude(3) mirrorScope(true, false, false) " + show("scope.tx", "scope.sx")
            + " A.")
    assert prints(m) == pytest.approx([10, 10])
    assert m.parts[0].mesh.volume() == pytest.approx(240)


def test_mirror_scope_mirrors_inserted_assets_with_outward_faces(tmp_path):
    # a corner tetrahedron, its right angle at the asset's origin
    (tmp_path / "tet.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
                                      "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    src = 'Lot --> s(4, 2, 2) {} i("tet.obj") A.'
    plain = run(src.format(""), assets=tmp_path).parts[0].mesh
    mirrored = run(src.format("mirrorScope(true, false, false)"), assets=tmp_path).parts[0].mesh
    assert plain.volume() == pytest.approx(16 / 6)
    assert mirrored.volume() == pytest.approx(16 / 6)  # mirrored, not inside out
    top = mirrored.vertices[np.argmax(mirrored.vertices[:, 1])]
    assert top == pytest.approx([4, 2, 0])  # the apex above the right angle, now at x = 4
    assert plain.vertices[np.argmax(plain.vertices[:, 1])] == pytest.approx([0, 2, 0])


# ---- footprint ---------------------------------------------------------------------------------

def test_footprint_of_an_l_mass_is_its_outline():
    m = run("Lot --> extrude(5) footprint() " + show("scope.sy", "geometry.nFaces") + " A.",
            poly=L_POLY)
    assert not m.warnings
    assert prints(m) == [0, 1]
    (part,) = m.parts
    assert part.mesh.area() == pytest.approx(26)
    assert part.mesh.face_normals()[0] == pytest.approx([0, 1, 0])
    assert part.mesh.bounds()[1][1] == pytest.approx(0)


def test_footprint_then_extrude_rebuilds_the_box():
    m = run("Lot --> taper(6) footprint() extrude(3) A.")
    assert not m.warnings
    (part,) = m.parts
    assert part.mesh.volume() == pytest.approx(240)  # the pyramid's footprint is the 10 x 8 lot
    assert part.mesh.bounds()[1] == pytest.approx([10, 3, 8])


def test_footprint_of_a_raised_shape_lies_on_its_scope_floor():
    # the top face of a mass, raised 5 m, then its scope moved up 2 m more: the plane scope.y = 0
    m = run("Lot --> extrude(5) comp(f) { top : Top }\n"
            "Top --> alignScopeToAxes(y) footprint() A.")
    assert not m.warnings
    (part,) = m.parts
    assert part.mesh.area() == pytest.approx(80)
    assert part.mesh.bounds()[:, 1] == pytest.approx([5, 5])


def test_footprint_of_a_hip_roof_is_the_lot():
    m = run("Lot --> roofHip(30) footprint() " + show("geometry.nFaces", "scope.sy") + " A.",
            poly=L_POLY)
    assert not m.warnings
    assert prints(m) == [1, 0]
    assert m.parts[0].mesh.area() == pytest.approx(26)
    assert m.parts[0].mesh.bounds()[:, 1] == pytest.approx([0, 0])


def test_footprint_of_a_wall_is_empty():
    m = derive_facade(load_rules("F --> footprint() A."), 10, 4)
    assert not m.parts and not m.warnings


# ---- taper -------------------------------------------------------------------------------------

def test_taper_makes_a_pyramid_over_the_centre_of_gravity():
    m = run("Lot --> taper(10) " + show("scope.sx", "scope.sy", "scope.sz", "geometry.nFaces")
            + " A.", poly=L_POLY)
    assert not m.warnings
    (part,) = m.parts
    mesh = part.mesh
    assert prints(m) == pytest.approx([4, 10, 10, 7])  # the lot's first edge runs along z
    assert mesh.is_closed()
    assert mesh.volume() == pytest.approx(26 * 10 / 3)
    apex = mesh.vertices[np.argmax(mesh.vertices[:, 1])]
    # L centroid: arm 20 m2 at (5, 3), stub 6 m2 at (1.5, 1)
    assert apex == pytest.approx([109 / 26, 10, 66 / 26])


def test_taper_downwards_has_negative_scope_height():
    m = run("Lot --> taper(-6) " + show("scope.sy", "scope.ty") + " A.")
    assert prints(m) == pytest.approx([-6, 0])
    mesh = m.parts[0].mesh
    assert mesh.volume() == pytest.approx(80 * 6 / 3)  # outward faces: positive volume
    assert mesh.bounds()[0][1] == pytest.approx(-6)


def test_taper_sides_are_comp_faces():
    m = run("Lot --> taper(4) comp(f) { bottom : B | side : S }")
    assert area(m, "B") == pytest.approx(80)
    # two triangles over the 10 m edges (slant height sqrt(16 + 16)) and two over the 8 m edges
    expected = 10 * math.sqrt(32) + 8 * math.sqrt(16 + 25)
    assert area(m, "S") == pytest.approx(expected)


def test_taper_zero_leaves_the_lot():
    m = run("Lot --> taper(0) A.")
    assert not m.warnings
    assert m.parts[0].mesh.n_faces == 1 and area(m) == pytest.approx(80)


# ---- resetMaterial -----------------------------------------------------------------------------

def test_reset_material_drops_rule_colours():
    m = run("Lot --> color(1, 0, 0) set(material.opacity, 0.5) resetMaterial() A.")
    mat = m.parts[0].material
    assert mat.color == (1, 1, 1) and mat.opacity == 1
    m = run("Lot --> color(1, 0, 0) resetMaterial(geometry) A.")
    assert m.parts[0].material.color == (1, 0, 0)
    m = run("Lot --> color(1, 0, 0) resetMaterial(all) A.")
    assert m.parts[0].material.color == (1, 1, 1)


def _plant(tmp_path):
    from PIL import Image

    Image.new("RGB", (4, 4), (20, 160, 20)).save(tmp_path / "leaf.png")
    (tmp_path / "plant.mtl").write_text("newmtl leaf\nKd 0.2 0.8 0.2\nmap_Kd leaf.png\n")
    (tmp_path / "plant.obj").write_text(
        "mtllib plant.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl leaf\nf 1/1 2/2 3/3 4/4\n")


def test_reset_material_shows_the_assets_own_material(tmp_path):
    _plant(tmp_path)
    src = 'Lot --> texture("stones.png") color(0, 0, 1) i("plant.obj") {} A.'
    kept = run(src.format(""), assets=tmp_path).parts[0].material
    assert kept.color == (0, 0, 1) and not str(kept.texture or "").endswith("leaf.png")
    reset = run(src.replace("{}", "resetMaterial()"), assets=tmp_path).parts[0].material
    assert reset.color == pytest.approx((0.2, 0.8, 0.2))
    assert str(reset.texture).endswith("leaf.png")
    plain = run(src.replace("{}", "resetMaterial(all)"), assets=tmp_path).parts[0].material
    assert plain.color == (1, 1, 1) and plain.texture is None
    geo = run('Lot --> i("plant.obj") resetMaterial(geometry) A.', assets=tmp_path)
    assert geo.parts[0].material.color == (1, 1, 1) and geo.parts[0].material.texture is None


def test_reset_material_rejects_a_bad_target():
    m = run("Lot --> color(1, 0, 0) resetMaterial(everything) A.")
    assert warned(m, "resetMaterial")
    assert m.parts[0].material.color == (1, 0, 0)


# ---- copyUV ------------------------------------------------------------------------------------

def test_copy_uv_round_trip_through_another_set():
    m = run("Lot --> setupProjection(0, scope.xz, 2, 4) projectUV(0) copyUV(0, 3) "
            "scaleUV(0, 10, 10) copyUV(3, 0) A.")
    uv = m.parts[0].mesh.corner_uvs
    assert uv.max(axis=0) == pytest.approx([5, 2])


@pytest.mark.parametrize("args", ["1, 0", "0, 10", "-1, 0", "0.5, 1"])
def test_copy_uv_bad_sets_warn(args):
    m = run(f"Lot --> setupProjection(0, scope.xz, 2, 4) projectUV(0) copyUV({args}) A.")
    assert warned(m, "copyUV")
    assert m.parts[0].mesh.corner_uvs.max(axis=0) == pytest.approx([5, 2])


# ---- rectify -----------------------------------------------------------------------------------

# a trapezoid: its right side leans 0.4 m over 8 m, atan(0.05) = 2.86 degrees off the z axis
TRAPEZOID = np.array([[0, 0, 0], [10, 0, 0], [10.4, 0, 8], [0, 0, 8]], float)


def test_rectify_straightens_a_leaning_side():
    m = run("Lot --> rectify(5) " + show("scope.sx", "scope.sz", "geometry.area") + " A.",
            poly=TRAPEZOID)
    assert not m.warnings
    assert prints(m) == pytest.approx([10.2, 8, 81.6])
    corners = m.parts[0].mesh.vertices[m.parts[0].mesh.corners]
    assert sorted(map(tuple, np.round(corners, 9))) == [(0, 0, 0), (0, 0, 8), (10.2, 0, 0),
                                                        (10.2, 0, 8)]


def test_rectify_leaves_edges_beyond_the_angle():
    m = run("Lot --> rectify(2) " + show("scope.sx") + " A.", poly=TRAPEZOID)
    assert not m.warnings
    assert prints(m) == pytest.approx([10.4])
    assert sorted(np.round(m.parts[0].mesh.vertices[:, 0], 9)) == [0, 0, 10, 10.4]


def test_rectify_moves_neighbouring_faces_together():
    # offset leaves one mesh: the inner face and the border quads around it share corners; they
    # must move together, so the faces still tile the straightened 10.2 x 8 outline
    m = run("Lot --> offset(-1) rectify(5) " + show("geometry.nFaces", "scope.sx") + " A.",
            poly=TRAPEZOID)
    # two faces: the inner one and the border ring (one face with a hole, in four pieces)
    assert prints(m) == pytest.approx([2, 10.2])
    assert m.parts[0].mesh.n_faces == 5
    assert m.parts[0].mesh.area() == pytest.approx(81.6)
    # separate shapes straighten on their own: each half of a split leans 0.2 m
    halves = run("Lot --> split(z) { 4 : A | ~1 : A }\nA --> rectify(5) X.", poly=TRAPEZOID)
    assert sorted(round(p.mesh.area(), 9) for p in halves.parts) == [40.4, 41.2]


@pytest.mark.parametrize("arg", ["-1", "46", "90"])
def test_rectify_rejects_angles_outside_0_45(arg):
    m = run(f"Lot --> rectify({arg}) A.", poly=TRAPEZOID)
    assert warned(m, "rectify", "[0, 45]")
    assert m.parts[0].mesh.area() == pytest.approx(81.6)


def test_rectify_refuses_a_volume():
    m = run("Lot --> extrude(3) rectify(10) A.", poly=TRAPEZOID)
    assert warned(m, "rectify", "volume")
    assert m.parts[0].mesh.volume() == pytest.approx(81.6 * 3)


# ---- convert in the pivot frame ----------------------------------------------------------------

def test_convert_uses_the_pivot():
    m = run("Lot --> setPivot(xyz, 1) print(convert(x, world, pivot, pos, 10, 0, 3)) "
            "print(convert(z, world, pivot, pos, 7, 0, 0)) A.")
    # the pivot sits at (10, 0, 0) with x along world z and z along world -x
    assert prints(m) == pytest.approx([3, 3])


# a 10 x 8 lot far from the world origin, 5 m up: CityEngine's scope.t is relative to the
# pivot (the initial shape's frame), scope.elevation is the world height
FAR = np.array([[100, 5, -50], [100, 5, -58], [110, 5, -58], [110, 5, -50]], float)


def test_scope_translation_is_relative_to_the_pivot():
    m = run("Lot --> " + show("scope.tx", "scope.ty", "scope.tz", "scope.rx", "scope.ry",
                              "scope.rz", "scope.elevation")
            + " t(2, 0, 1) " + show("scope.tx", "scope.tz") + " A.", poly=FAR)
    assert prints(m) == pytest.approx([0, 0, 0, 0, 0, 0, 5, 2, 1], abs=1e-9)


def test_set_scope_translation_moves_along_the_pivot_axes():
    m = run("Lot --> set(scope.tx, 3) " + show("scope.tx") + " A.", poly=FAR)
    assert prints(m) == pytest.approx([3])
    (lo, hi) = bounds(m)
    # the lot moved 3 m along its first edge, which points to -z
    assert lo == pytest.approx([100, 5, -61]) and hi == pytest.approx([110, 5, -53])


def test_comp_aligns_the_pivot_with_each_component_scope():
    # zUp (default): pivot and scope are aligned, so the component's scope.t and scope.r are 0
    # relative to it; noAlign keeps the pivot, so the right face's scope sits 10 m along x
    m = run("Lot --> extrude(3) comp(f) { right : " + show("scope.tx", "scope.ry", "pivot.px")
            + " R. }")
    assert prints(m) == pytest.approx([0, 0, 10], abs=1e-9)
    m = run("Lot --> extrude(3) comp(f, noAlign) { right : " + show("scope.tx", "pivot.px")
            + " R. }")
    assert prints(m) == pytest.approx([10, 0], abs=1e-9)


def _scope_of(src, symbol="S"):
    m = derive(load_rules(src), None, lot_size="10x8", keep_tree=True)[0]
    return next(s for s in m.root.walk() if s.symbol == symbol).scope


def test_r_adds_angles_to_the_scope_rotation_in_the_pivot_frame():
    # reference: r "adds the given angles to scope.r" (x, then y, then z about the pivot's axes),
    # so the order of two calls does not matter as long as each turns one axis
    one = _scope_of("Lot --> r(90, 45, 0) S.")
    two = _scope_of("Lot --> r(90, 0, 0) r(0, 45, 0) S.")
    swapped = _scope_of("Lot --> r(0, 45, 0) r(90, 0, 0) S.")
    assert two.rotation == pytest.approx(one.rotation, abs=1e-9)
    assert swapped.rotation == pytest.approx(one.rotation, abs=1e-9)
    out = run("Lot --> r(0, 30, 0) r(0, 0, 20) print(scope.rx) print(scope.ry) print(scope.rz)")
    assert prints(out) == pytest.approx([0, 30, 20])


def test_rotate_abs_sets_and_rel_adds_angles_in_the_named_frame():
    s = _scope_of("Lot --> r(0, 30, 0) rotate(abs, world, 0, 0, 0) S.")
    assert s.rotation == pytest.approx(np.eye(3), abs=1e-9)
    s = _scope_of("Lot --> rotate(rel, world, 0, 30, 0) rotate(rel, world, 0, 15, 0) S.")
    assert s.rotation == pytest.approx(_scope_of("Lot --> r(0, 45, 0) S.").rotation, abs=1e-9)


def test_rotate_scope_turns_about_the_pivot_axes_and_keeps_the_geometry():
    m = run("Lot --> extrude(3) rotateScope(0, 90, 0) X.")
    part = m.parts[0]
    assert part.mesh.bounds() == pytest.approx(np.array([[0, 0, 0], [10, 3, 8]]), abs=1e-9)
    s = _scope_of("Lot --> extrude(3) rotateScope(0, 90, 0) S.")
    assert sorted(np.round(s.size, 9)) == [3, 8, 10]


@pytest.mark.parametrize("turn", ["r(0, 0, 0)", "rotateScope(0, 0, 0)", "r(scopeCenter, 0, 0, 0)"])
def test_turning_a_mirrored_scope_keeps_it_mirrored(turn):
    """After ``mirrorScope`` the scope is a mirror; adding zero angles changes nothing (the
    angles are read back through the mirror, not as if the scope were a proper rotation, which
    turned the mass upside down and inside out)."""
    base = "Lot --> extrude(3) t(20, 0, 0) mirrorScope(true, false, false) {} X."
    plain, turned = run(base.format("")), run(base.format(turn))
    assert np.allclose(np.array(bounds(turned)), np.array(bounds(plain)), atol=1e-9)
    assert sum(p.mesh.volume() for p in turned.parts) == pytest.approx(240.0)
    (leaf,) = [s for s in turned.root.walk() if s.symbol == "X"]
    assert np.linalg.det(leaf.scope.rotation) < 0


def test_rotate_scope_on_a_mirrored_scope_stays_a_mirror():
    m = run("Lot --> extrude(3) mirrorScope(true, false, false) rotateScope(0, 30, 0) X.")
    (leaf,) = [s for s in m.root.walk() if s.symbol == "X"]
    assert np.linalg.det(leaf.scope.rotation) == pytest.approx(-1.0)
