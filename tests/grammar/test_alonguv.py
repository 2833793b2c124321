"""insertAlongUV: assets cut and bent along the shape's uvs (hand-checked areas and volumes).

On the 10 x 8 lot, ``setupProjection(0, scope.xz, W, 8) projectUV(0)`` gives u = x / W and v = z / 8
(v = 1 on the lot's edge at z = 8).
"""

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.geometry.footprints import Footprint
from facadeforge.geometry.mesh import Mesh
from facadeforge.grammar.ops.alonguv import _inverse_bilinear, _Patch, _vertex_normals

BOX_FACES = "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n"


def box_obj(lo, hi) -> str:
    """An axis-aligned box from ``lo`` to ``hi`` as OBJ text (faces outward)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    corners = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
               (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    return "".join(f"v {x} {y} {z}\n" for x, y, z in corners) + BOX_FACES


# 2 x 1 x 0.5 box: x in [0, 2], y in [0, 1], z in [-0.25, 0.25]
BOX = box_obj((0, 0, -0.25), (2, 1, 0.25))

# a prism along x whose triangular section is 1 high at z = 0 and 0 high at z = 1
WEDGE = """v 0 0 0
v 0 0 1
v 0 1 0
v 1 0 0
v 1 0 1
v 1 1 0
f 1 2 3
f 4 6 5
f 1 3 6 4
f 1 4 5 2
f 2 5 6 3
"""

# a unit cube floating one unit above its origin: y in [1, 2]
SLAB = box_obj((0, 1, 0), (1, 2, 1))

PROJECT = "setupProjection(0, scope.xz, {w}, 8) projectUV(0)"


@pytest.fixture
def assets(tmp_path):
    for name, text in (("box.obj", BOX), ("wedge.obj", WEDGE), ("slab.obj", SLAB)):
        (tmp_path / name).write_text(text)
    return tmp_path


def run(src, assets, lot="10x8", poly=None):
    fp = [Footprint("fp", np.asarray(poly, float))] if poly is not None else None
    return derive(load_rules(src, assets=assets), fp, lot_size=None if fp else lot)[0]


def mesh_of(model, symbol="B"):
    return Mesh.merge(p.mesh for p in model.parts if p.symbol == symbol)


def test_box_spans_the_uv_square(assets):
    # x span → u in [0, 1] (10 m), z span → v (8 m), y span → the height 2
    m = run(f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"box.obj\", 2) B.", assets)
    assert not m.warnings
    g = mesh_of(m)
    assert g.n_faces == 6
    assert g.area() == pytest.approx(2 * (10 * 8 + 10 * 2 + 8 * 2))
    assert g.volume() == pytest.approx(160)  # positive: faces still point outwards
    assert np.allclose(g.bounds(), [[0, 0, 0], [10, 2, 8]])


def test_z_goes_to_minus_v(assets):
    # the wedge's high side (its smallest z) lands at v = 1, i.e. z = 8
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"wedge.obj\", 3) B.", assets))
    assert g.volume() == pytest.approx(10 * 8 * 3 / 2)
    corners = g.vertices[g.corners]
    assert np.allclose(corners[corners[:, 1] > 2.9][:, 2], 8)


def test_u_repeats_and_the_last_copy_is_cut(assets):
    # u in [0, 2]: two 5 m copies, each a closed box
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=5)} insertAlongUV(0, \"box.obj\", 2) B.", assets))
    assert g.n_faces == 12
    assert g.area() == pytest.approx(2 * 2 * (5 * 8 + 5 * 2 + 8 * 2))
    # u in [0, 2.5]: two 4 m copies and half of a third, cut open at x = 10 (no end cap)
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=4)} insertAlongUV(0, \"box.obj\", 2) B.", assets))
    assert g.n_faces == 6 + 6 + 5
    assert g.area() == pytest.approx(2 * 2 * (4 * 8 + 4 * 2 + 8 * 2) + 2 * 16 + 2 * 4 + 16)
    assert np.allclose(g.bounds(), [[0, 0, 0], [10, 2, 8]])


def test_negative_height_hangs_below_and_keeps_faces_outwards(assets):
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"box.obj\", -2) B.", assets))
    assert g.volume() == pytest.approx(160)
    assert np.allclose(g.bounds(), [[0, -2, 0], [10, 0, 8]])


@pytest.mark.parametrize("alignment, y_range", [("alignPosition", [0, 2]), ("keepPosition", [2, 4])])
def test_height_alignment(assets, alignment, y_range):
    # the slab's y is [1, 2]; height 2 scales it by 2: on the faces, or its origin on them
    src = f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"slab.obj\", 2, scope.y, {alignment}) B."
    g = mesh_of(run(src, assets))
    assert np.allclose(g.bounds()[:, 1], y_range)
    assert g.volume() == pytest.approx(160)


def test_triangle_face_cuts_the_asset(assets):
    # uv triangle (0,0), (1,0), (0,1): the box's top and bottom become the 40 m² triangle; of its
    # sides only those on the triangle's legs remain (x = 0: 8 x 2, z = 0: 10 x 2)
    src = "Lot --> setupProjection(0, world.xz, 10, 8) projectUV(0) insertAlongUV(0, \"box.obj\", 2) B."
    for poly in ([[0, 0, 0], [10, 0, 0], [0, 0, 8]], [[0, 0, 0], [0, 0, 8], [10, 0, 0]]):
        g = mesh_of(run(src, assets, poly=poly))
        assert g.n_faces == 4
        assert g.area() == pytest.approx(40 + 40 + 16 + 20)


def test_vertex_normal_direction_on_a_facade(assets):
    # on the front facade the scope's y runs up the wall: the box lies flat in it; along the
    # facade's normal it stands out of the wall
    base = ("Lot --> extrude(6) comp(f) {{ front : setupProjection(0, scope.xy, 10, 6) projectUV(0) "
            "insertAlongUV(0, \"box.obj\", 0.5{extra}) B. | all : NIL }}")
    g = mesh_of(run(base.format(extra=", vertex.normal, alignPosition"), assets))
    assert g.area() == pytest.approx(2 * (10 * 6 + 10 * 0.5 + 6 * 0.5))
    assert g.volume() == pytest.approx(30)
    assert np.ptp(g.bounds(), axis=0) == pytest.approx([10, 6, 0.5])
    flat = mesh_of(run(base.format(extra=""), assets))
    assert flat.volume() == pytest.approx(0)


def test_vertex_normals_average_the_faces_around_a_vertex():
    # a gable: two faces sharing the ridge (y = 1) at 45°, each with its own vertices
    left = [[0, 0, 0], [0, 0, 2], [1, 1, 2], [1, 1, 0]]
    right = [[1, 1, 0], [1, 1, 2], [2, 0, 2], [2, 0, 0]]
    n = _vertex_normals(Mesh.from_polygons([left, right]))
    s = np.sqrt(0.5)
    assert np.allclose(n[0], [-s, s, 0]) and np.allclose(n[2], [0, 1, 0])
    assert np.allclose(n[4], [0, 1, 0]) and np.allclose(n[7], [s, s, 0])


def test_vertex_normals_bend_the_asset_over_a_ridge(assets):
    # the two slopes as one shape (aslant =), so the ridge's vertex normals point straight up
    src = ("Lot --> extrude(4) comp(f) { top : roofGable(45) comp(f) { aslant = "
           "setupProjection(0, world.xz, 10, 8) projectUV(0) "
           "insertAlongUV(0, \"box.obj\", 1, vertex.normal, alignPosition) B. | all : NIL } "
           "| all : NIL }")
    m = run(src, assets)
    g = mesh_of(m)
    assert g.n_faces
    # the ridge of the roof is at y = 4 + 4; the asset's top over it is 1 higher
    assert g.bounds()[1, 1] == pytest.approx(9)


@pytest.mark.parametrize("src, message", [
    ("Lot --> insertAlongUV(0, \"box.obj\", 2) B.", "no texture coordinates"),
    (f"Lot --> {PROJECT.format(w=10)} insertAlongUV(1, \"box.obj\", 2) B.", "only uv set 0"),
    (f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0.5, \"box.obj\", 2) B.", "integer in [0, 9]"),
    (f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"nope.obj\", 2) B.", "not found"),
    (f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"box.obj\", 2, scope.x, alignPosition) B.",
     "heightDirection"),
    (f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"box.obj\", 2, scope.y, center) B.",
     "heightAlignment"),
])
def test_bad_input_is_a_warning_and_leaves_the_shape(assets, src, message):
    m = run(src, assets)
    assert any(message in w for w in m.warnings), m.warnings
    assert mesh_of(m).area() == pytest.approx(80)  # the lot, unchanged


def test_faces_with_more_than_four_corners_get_nothing(assets):
    l_shape = [[0, 0, 0], [0, 0, 4], [10, 0, 4], [10, 0, 2], [3, 0, 2], [3, 0, 0]]
    src = "Lot --> setupProjection(0, world.xz, 10, 4) projectUV(0) insertAlongUV(0, \"box.obj\", 1) B."
    m = run(src, assets, poly=l_shape)
    assert any("more than 4 corners" in w for w in m.warnings)
    assert mesh_of(m).n_faces == 0


def test_asset_uvs_and_builtin_assets(assets):
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"builtin:cube\", 1) B.",
                    assets))
    assert g.volume() == pytest.approx(80)
    assert g.corner_uvs is not None  # the builtin cube's own texture coordinates


def test_instancing_does_not_share_assets_laid_on_different_uvs(assets):
    # two halves of the lot with equal geometry but u in [0, 0.5] and [0.5, 1]: the left one gets
    # the box's left end cap (x = 0), the right one its right end cap (x = 10)
    src = (f"Lot --> {PROJECT.format(w=10)} split(x) {{ ~5 : Half }}*\n"
           "Half --> insertAlongUV(0, \"box.obj\", 2) B.")
    for keep_tree in (True, False):
        m = derive(load_rules(src, assets=assets), lot_size="10x8", keep_tree=keep_tree)[0]
        g = mesh_of(m)
        assert g.area() == pytest.approx(2 * (10 * 8 + 10 * 2 + 8 * 2))
        caps = np.abs(g.face_normals()[:, 0]) > 0.99
        x = sorted(g.vertices[g.face(f)][0, 0] for f in np.flatnonzero(caps))
        assert x == pytest.approx([0, 10])


def test_inverse_bilinear_recovers_quad_parameters():
    q = np.array([[0, 0], [4, 0.5], [3.5, 3], [-0.5, 2]], float)
    rng = np.random.default_rng(1)
    st = rng.random((50, 2))
    s, t = st[:, 0:1], st[:, 1:2]
    p = (1 - s) * (1 - t) * q[0] + s * (1 - t) * q[1] + s * t * q[2] + (1 - s) * t * q[3]
    s2, t2 = _inverse_bilinear(q, p - q[0])
    assert np.allclose(s2, st[:, 0]) and np.allclose(t2, st[:, 1])


def test_quad_patch_bends_bilinearly():
    # a street-like quad: rectangular uvs on a trapezoid, so the map is bilinear, not affine
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    pos = np.array([[0, 0, 0], [10, 0, 0], [8, 0, 4], [2, 0, 4]], float)
    patch = _Patch(uv, pos, np.tile([0.0, 1.0, 0.0], (4, 1)))
    w = patch.weights(np.array([[0.5, 0.5], [0.25, 1.0], [1.0, 0.5]]))
    assert np.allclose(w @ pos, [[5, 0, 2], [3.5, 0, 4], [9, 0, 2]])
    assert patch.orientation() == -1.0  # uv counter-clockwise seen from below: mirrored


def test_zero_height_and_flat_assets_lie_on_the_faces(assets):
    (assets / "decal.obj").write_text("v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nf 1 2 3 4\n")
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=5)} insertAlongUV(0, \"decal.obj\", 3) B.", assets))
    assert g.n_faces == 2 and g.area() == pytest.approx(80)
    assert np.allclose(g.bounds()[:, 1], 0)
    # the box flattened: its top and bottom on the lot, its sides (now without area) dropped
    g = mesh_of(run(f"Lot --> {PROJECT.format(w=10)} insertAlongUV(0, \"box.obj\", 0) B.", assets))
    assert g.n_faces == 2 and g.area() == pytest.approx(160)
