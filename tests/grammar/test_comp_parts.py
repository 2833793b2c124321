"""comp(m|g|h) and comp's noAlign scope alignment."""

import numpy as np
import pytest
from cga_helpers import by_symbol, run

from facadeforge import derive, load_rules


def test_comp_materials_of_a_shape_with_per_face_materials():
    # a Boolean result keeps both operands' materials: comp(m) gives one shape per material
    m = run("""Lot --> subtract { extrude(4) color(1,0,0) | t(2,-1,2) s(4,6,4) primitiveCube
                                  color(0,0,1) } comp(m) { 0 : A. | 1 : B. }""")
    parts = by_symbol(m)
    assert sum(p.mesh.area() for p in parts["A"]) == pytest.approx(2 * 64 + 2 * 72)
    assert sum(p.mesh.area() for p in parts["B"]) == pytest.approx(64)
    assert parts["B"][0].material.color == pytest.approx((0, 0, 1))


def test_comp_materials_groups_and_holes_of_a_plain_shape():
    m = run("Lot --> extrude(3) comp(m) { all : M. } X. "
            "comp(g) { all : G. } comp(h) { all : H. }")
    parts = by_symbol(m)
    assert len(parts["M"]) == 1 and parts["M"][0].mesh.n_faces == 6
    assert len(parts["G"]) == 1 and "H" not in parts


def test_comp_no_align_keeps_the_scope_orientation():
    m = derive(load_rules("Lot --> extrude(3) comp(f, noAlign) { right : F. }"), None,
               lot_size="10x8", keep_tree=True)[0]

    def find(node):
        if node.symbol == "F":
            return node
        for c in node.children:
            hit = find(c)
            if hit is not None:
                return hit
    f = find(m.root)
    assert f.scope.rotation == pytest.approx(np.eye(3))


def test_comp_faces_keep_the_per_face_materials_of_an_inline():
    m = run("Lot --> extrude(1) inline { split(x){ '0.5: color(1,0,0) A | '0.5: color(0,0,1) A } } "
            "comp(f){ all : X. }")
    colours = {}
    for p in m.parts:
        key = tuple(np.round(p.material.color, 3))
        colours[key] = colours.get(key, 0.0) + p.mesh.area()
    # two 5 x 8 x 1 boxes: 106 m² each, red and blue, through the component split
    assert colours == {(1.0, 0.0, 0.0): pytest.approx(106), (0.0, 0.0, 1.0): pytest.approx(106)}


def test_comp_groups_of_an_inserted_asset(tmp_path):
    (tmp_path / "tree.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\n"
        "g trunk\nf 1 2 3 4\ng crown\nf 1 2 6 5\nf 2 7 6\n")
    m = derive(load_rules('Lot --> s(2, 2, 2) i("tree.obj") split(x){ ~1 : P }*\n'
                          'P --> comp(g){ 0 : T. | 1 : C. }', assets=tmp_path),
               None, lot_size="10x8")[0]
    assert not m.warnings
    parts = by_symbol(m)
    # split pieces keep their faces' groups; the trunk is one quad, the crown a quad and a triangle
    assert sum(p.mesh.area() for p in parts["T"]) == pytest.approx(4)
    assert sum(p.mesh.area() for p in parts["C"]) == pytest.approx(4 + 2)


def test_comp_face_edges_are_every_face_s_own():
    out = run('Lot --> extrude(2) print(size(comp(fe){ all : 1 })) print(size(comp(e){ all : 1 })) '
              'comp(fe){ isTagged("extrude.top") : print("top edge") } X.').attributes["prints"]
    # a box: 6 quads have 24 face edges, 12 edges; 4 edges touch the top face, but as face
    # edges each is seen twice (from the top and from its wall), so 8 face edges
    assert out[:2] == ["24", "12"] and out.count("top edge") == 8


def test_comp_connected_operator_gives_one_shape_per_connected_piece():
    # CityEngine 2025.0's =: : the selected faces, one shape per connected piece of them
    src = """Lot --> extrude(10) inline split(x){ 2 : A | 2 : NIL | 2 : A | ~1 : NIL } B
             B --> comp(f){ side =: S | top = T | all : R }
             S --> report("side", comp.index + "/" + comp.total) X."""
    m = run(src, lot="10x10")
    parts = by_symbol(m)
    # two separate boxes: their 8 sides are two pieces of 4 faces, as two shapes
    assert len(parts["X"]) == 2 and [p.mesh.n_faces for p in parts["X"]] == [4, 4]
    assert sorted(m.reports["side"]) == ["0/2", "1/2"]
    # = keeps everything selected in one shape, connected or not
    assert len(parts["T"]) == 1 and parts["T"][0].mesh.n_faces == 2


def test_comp_connected_operator_on_a_connected_mesh_is_one_shape():
    m = run("Lot --> extrude(6) comp(f){ side =: S. }", poly=np.array(
        [[0, 0, 0], [12, 0, 0], [12, 0, -4], [4, 0, -4], [4, 0, -10], [0, 0, -10]], float))
    parts = by_symbol(m)
    assert len(parts["S"]) == 1 and parts["S"][0].mesh.n_faces == 6


def test_comp_connected_operator_joins_components_and_never_splits_one():
    """``=:`` on materials: connected components join, a component is one shape even when its
    own faces do not touch (one material on two separate boxes)."""
    two_boxes = "Lot --> extrude(10) inline split(x){ 2 : A | 2 : NIL | 2 : A | ~1 : NIL } B\n"
    m = run(two_boxes + 'A --> color("#ff0000")\nB --> comp(m){ all =: X. }', lot="10x10")
    assert [p.mesh.n_faces for p in by_symbol(m)["X"]] == [12]
    # two materials on one box touch: one shape; on two boxes apart: two
    m = run('Lot --> extrude(10) inline comp(f){ top : color("#ff0000") F. | all : F. } B\n'
            'B --> comp(m){ all =: X }\nX --> report("total", comp.total) Y.', lot="10x10")
    assert m.reports["total"] == [1.0] and sum(p.mesh.n_faces for p in m.parts) == 6
    apart = ("Lot --> extrude(10) inline split(x){ 2 : A | 2 : NIL | 2 : C | ~1 : NIL } B\n"
             'A --> color("#ff0000")\nC --> color("#0000ff")\nB --> comp(m){ all =: X. }')
    assert sorted(p.mesh.n_faces for p in by_symbol(run(apart, lot="10x10"))["X"]) == [6, 6]


def test_comp_function_with_the_connected_operator():
    src = """Lot --> extrude(10) inline split(x){ 2 : A | 2 : NIL | 2 : A | ~1 : NIL } B
             B --> report("pieces", str(comp(f){ side =: comp.index | all : -1 })) X."""
    m = run(src, lot="10x10")
    values = m.reports["pieces"][0].split("]")[0].split("[")[1].split(",")
    assert sorted(values) == ["-1"] * 4 + ["0"] * 4 + ["1"] * 4


def test_edge_scope_has_the_face_normal_as_z_axis():
    # comp's default zUp alignment: x along the edge, z the face's normal, y into the face
    m = derive(load_rules("Lot --> comp(e) { all : E. }"), None, lot_size="10x8",
               keep_tree=True)[0]
    edges = [s for s in m.root.walk() if s.symbol == "E"]
    assert len(edges) == 4
    for e in edges:
        x, y, z = e.scope.rotation.T
        assert z == pytest.approx([0, 1, 0], abs=1e-9)
        centre = np.mean([d.scope.origin for d in edges], axis=0)  # the lot's centre
        middle = e.scope.origin + x * e.scope.size[0] / 2
        assert np.linalg.norm(middle + y - centre) < np.linalg.norm(middle - centre)


def test_esri_fence_pattern_on_edges_stands_on_the_ground():
    # ESRI.lib Fence_On_Polygon_Simple: "rotate so that x is along edge, z is front to back",
    # then a footprint quad extruded up; a tree turned by r(90, 0, yaw) stands upright
    m = run("""Lot --> comp(e) { all : Edge Tree }
               Edge --> rotateScope(90, 0, 180) s(scope.sx + 0.2, 0, 0.1) center(xz)
                        primitiveQuad extrude(world.up, 1.5) Post.
               Tree --> s(0, 5, 0) r(90, 0, 30) primitiveCube T.""")
    parts = by_symbol(m)
    for p in parts["Post"]:
        assert p.mesh.vertices[:, 1].min() == pytest.approx(0, abs=1e-9)
        assert p.mesh.vertices[:, 1].max() == pytest.approx(1.5)
    for p in parts["T"]:  # upright: 5 m tall, on the ground
        assert np.ptp(p.mesh.vertices[:, 1]) == pytest.approx(5)


def test_edge_shapes_extrude_into_walls_facing_out():
    # extrude reference: "Edges can also be extruded, e.g., when working on shapes created from
    # comp(e|fe)"; default direction: the edge's normal (its face's), here up
    m = run("Lot --> comp(e) { all : extrude(3) W. }", lot="10x6")
    walls = by_symbol(m)["W"]
    assert len(walls) == 4 and sum(w.mesh.area() for w in walls) == pytest.approx(96)
    centre = np.array([5.0, 0.0, 3.0])
    for w in walls:
        v = w.mesh.vertices
        assert v[:, 1].min() == pytest.approx(0) and v[:, 1].max() == pytest.approx(3)
        n = w.mesh.face_normals()[0]
        assert n @ (v.mean(axis=0) - centre) > 0  # away from the lot
        assert w.mesh.triangle_count() == 2


def test_edge_and_vertex_shapes_count_their_own_components_and_split_into_edges():
    m = run("""Lot --> comp(e) { 0 : E } comp(v) { 0 : V }
               E --> report("e", str(geometry.nFaces) + str(geometry.nEdges) + str(geometry.nVertices))
                     split(x) { 4 : P }*
               P --> report("p", geometry.nEdges) extrude(world.up, 1) report("pf", geometry.nFaces)
               V --> report("v", str(geometry.nEdges) + str(geometry.nVertices))""", lot="10x6")
    assert m.reports["e"] == ["012"] and m.reports["v"] == ["01"]
    assert m.reports["p"] == [1, 1, 1] and m.reports["pf"] == [1, 1, 1]
