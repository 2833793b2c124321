"""Geometry tags: queries, tag/deleteTags, isTagged selectors, auto-tags and propagation
(reference: "Geometry Tagging: Essential Knowledge", cga_componentTags.html)."""

import numpy as np
import pytest
from cga_helpers import areas, by_symbol, run

from facadeforge.geometry.mesh import Mesh
from facadeforge.grammar.ops.tagging import TagIndex, clean_tag, matches


def prints(src, lot="10x8"):
    m = run(src, lot)
    assert not m.warnings, m.warnings
    return m.attributes["prints"]


@pytest.mark.parametrize("query, tag, hit", [
    ("Facade", "Facade", True),
    ("Facade", "Facade.Front", True),          # a query matches the leading subtags
    ("Facade", "Facade.TypeA.Side.Left", True),
    ("Face", "Facade", False),                 # whole subtags, not string prefixes
    ("Front", "Facade.Front", False),          # anchored at the start
    ("?.Front", "Facade.Front", True),
    ("?.Front", "Facade.A.Front", False),      # ? is exactly one subtag
    ("Facade.*.Left", "Facade.TypeA.Side.Left", True),   # * is one or more
    ("Facade.*.Left", "Facade.Left", False),
    ("Facade.*", "Facade", False),
    ("extrude.side", "extrude.side.inner", True),
    ("", "anything.at.all", True),
    ("a.b", "a.bc", False),
])
def test_tag_queries(query, tag, hit):
    assert matches(query, tag) is hit


def test_tag_names_lose_wildcards_and_empty_subtags():
    assert clean_tag("a*.?b..c") == "a.b.c"


def test_extrude_auto_tags_select_bottom_sides_and_top():
    a = areas(run('Lot --> extrude(4) comp(f){ isTagged("extrude.bottom") : B. '
                  '| isTagged("extrude.side.outer") : S. | isTagged("extrude.top") : T. }'))
    assert a == pytest.approx({"B": 80, "S": 144, "T": 80})


def test_extrude_sides_from_a_hole_are_inner():
    # a courtyard cut out of a slab: the top is a holed face (pieces) whose extrusion has
    # 4 outer and 4 inner walls
    a = areas(run('''Lot --> subtract { s(10,1,8) primitiveCube | t(3,0,3) s(4,1,2) primitiveCube }
                     comp(f){ top = F }
                     F --> extrude(3) comp(f){ isTagged("extrude.side.inner") : I.
                                             | isTagged("extrude.side.outer") : O. | all : R. }'''))
    assert a["I"] == pytest.approx(2 * (4 + 2) * 3)
    assert a["O"] == pytest.approx(2 * (10 + 8) * 3)


def test_an_operation_replaces_only_its_own_auto_tags():
    out = prints("Lot --> roofGable(30) extrude(1) print(geometry.tags) extrude(1) "
                 'print(geometry.tags("roof")) print(geometry.tags("extrude.side")) X.')
    assert out[0] == "(6)[extrude.bottom,extrude.side.outer,extrude.top,roof.bottom,roof.side,roof.top]"
    assert out[1] == "(3)[roof.bottom,roof.side,roof.top]"
    assert out[2] == "(1)[extrude.side.outer]"


def test_logical_selectors_combine_tags_and_words():
    a = areas(run('Lot --> extrude(4) comp(f){ isTagged("extrude.side") && front : F. '
                  '| !isTagged("extrude.side") : NS. | side || back : O. }'))
    assert a == pytest.approx({"F": 40, "NS": 160, "O": 104})


def test_comp_sel_of_a_logical_selector():
    out = prints('Lot --> extrude(4) comp(f){ isTagged("extrude.top") || bottom : print(comp.sel) X. }')
    assert out == ['isTagged("extrude.top") || bottom'] * 2


def test_boolean_auto_tags_and_operand_tags_survive():
    a = areas(run('Lot --> subtract { extrude(4) | t(2,-1,2) s(4,6,4) primitiveCube } '
                  'comp(f){ isTagged("extrude.top") && isTagged("bool.A") : AT. '
                  '| isTagged("bool.B") : B. | isTagged("bool.A") : A. }'))
    assert a["AT"] == pytest.approx(80 - 16)      # the holed top
    assert a["B"] == pytest.approx(4 * 4 * 4)     # the hole's walls come from operand B
    assert a["A"] == pytest.approx(80 - 16 + 2 * 4 * (10 + 8))


def test_boolean_cut_edges_and_tagged_materials():
    out = prints('Lot --> subtract { extrude(4) | t(2,-1,2) s(4,6,4) primitiveCube } '
                 'comp(e){ isTagged("bool.cut") : print("cut") }')
    assert out == ["cut"] * 8            # the hole's rims, where B's walls meet A's faces
    a = areas(run('Lot --> subtract { extrude(4) color(1,0,0) | t(2,-1,2) s(4,6,4) primitiveCube '
                  'color(0,0,1) } comp(m){ isTagged("bool.B") : B. | all : A. }'))
    assert a["B"] == pytest.approx(64)


def test_roof_auto_tags():
    a = areas(run('Lot --> roofGable(30) comp(f){ isTagged("roof.side") : S. '
                  '| isTagged("roof.top") : T. | isTagged("roof.bottom") : B. }'))
    assert a["B"] == pytest.approx(80)
    assert a["T"] == pytest.approx(80 / np.cos(np.radians(30)))
    assert a["S"] == pytest.approx(8 * 4 * np.tan(np.radians(30)))  # two gables, 8 m wide


def test_taper_and_envelope_auto_tags():
    out = prints('Lot --> taper(3) print(geometry.tags) X.')
    assert out == ["(2)[taper.bottom,taper.side]"]
    a = areas(run('Lot --> envelope(normal, 10, 4, 45) comp(f){ isTagged("envelope.side.base") : W. '
                  '| isTagged("envelope.side.slope") : S. | isTagged("envelope.bottom") : B. }'))
    assert a["W"] == pytest.approx(4 * 36) and a["B"] == pytest.approx(80)


def test_split_keeps_tags_and_new_cap_faces_have_none():
    a = areas(run('Lot --> extrude(4) tag("T") split(y){ 2 : comp(f){ isTagged("T") : K. '
                  '| all : Cap. } | ~1 : X. }'))
    assert a["Cap"] == pytest.approx(80)             # the cut's cap face: new, untagged
    assert a["K"] == pytest.approx(80 + 2 * 36)      # bottom and walls keep the tag


def test_edge_tags_follow_split_and_rise_into_extruded_sides():
    out = prints('Lot --> tag("C", edges) split(x){ 4 : S | ~1 : S }\n'
                 'S --> comp(e){ isTagged("C") : print("tagged") | all : print("cut") }')
    assert out.count("tagged") == 6 and out.count("cut") == 2   # the cut edges are new
    a = areas(run('Lot --> tag("C", edges) extrude(2) comp(f){ isTagged("C") : CC. | all : Z. }'))
    assert a["CC"] == pytest.approx(2 * 2 * (10 + 8))   # walls rising from tagged edges


def test_edges_and_faces_see_their_neighbours_tags():
    out = prints('Lot --> extrude(3) comp(e){ isTagged("extrude.top") : print("e") }')
    assert len(out) == 4           # an edge counts as tagged when a face next to it is
    a = areas(run('Lot --> extrude(3) comp(f){ isTagged("extrude.top", e) : N. | all : R. }'))
    assert a["N"] == pytest.approx(80 + 2 * 3 * (10 + 8))   # the top and the faces it touches
    assert a["R"] == pytest.approx(80)


def test_tag_index_vertices_in_comp_v_order():
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    mesh = mesh.with_corner_column("vertex_tags", [("v",), None, None, None])
    ix = TagIndex(mesh)
    assert ix.vertices("v").tolist() == [True, False, False, False]
    assert ix.edges("v", "v").tolist() == [True, False, False, True]
    assert ix.faces("v").tolist() == [False] and ix.faces("v", "v").tolist() == [True]


def test_setback_edge_auto_tags():
    out = prints('''Lot --> setback(2){ front : F | remainder : R }
        F --> comp(e){ isTagged("setback.front") : print("front") | isTagged("setback.back") : print("back")
                     | isTagged("setback.side") : print("side") }''')
    assert sorted(out) == ["back", "front", "side", "side"]
    a = areas(run('''Lot --> setback(2){ front : F. | remainder : R }
        R --> extrude(3) comp(f){ isTagged("setback.back") : B. | isTagged("setback.remainder") : W. | all : O. }'''))
    assert a["B"] == pytest.approx(10 * 3) and a["W"] == pytest.approx((6 + 6 + 10) * 3)


def test_setback_selects_tagged_edges_and_copies_their_tags_to_the_setback_edge():
    a = areas(run('''Lot --> setback(2){ front : F. | remainder : R }
        R --> setback(1){ isTagged("setback.back") : A. | remainder : B. }'''))
    assert a["A"] == pytest.approx(10 * 1) and a["B"] == pytest.approx(10 * 5)
    a = areas(run('''Lot --> tag("P", edges) setback(2){ front : F. | remainder : R }
        R --> extrude(1) comp(f){ isTagged("setback.back") && isTagged("P") : BP.
                                | isTagged("setback.back") : BN. | all : O. }'''))
    assert a["BP"] == pytest.approx(10 * 1) and "BN" not in a


def test_deleting_and_listing_tags():
    out = prints('Lot --> tag("v.A", edges) tag("v.B", edges) tag("F") '
                 'print(geometry.tags) print(geometry.hasTags("v", faces)) '
                 'deleteTags("v", edges) print(geometry.tags) deleteTags() '
                 'print(geometry.hasTags()) X.')
    assert out == ["(3)[F,v.A,v.B]", "false", "(1)[F]", "false"]


def test_cleanup_does_not_merge_faces_with_different_tags():
    src = ("Lot --> inline split(x){ '0.5 : {T} N. | '0.5 : N. } cleanupGeometry(all, 0) "
           "comp(f){ all : F. }")
    assert len(by_symbol(run(src.replace("{T}", "")))["F"]) == 1
    assert len(by_symbol(run(src.replace("{T}", 'tag("A")')))["F"]) == 2


def test_operations_without_tag_support_clear_them():
    out = prints('Lot --> tag("A") reduceGeometry(0.5) print(geometry.hasTags()) '
                 'tag("A") primitiveCube() print(geometry.hasTags()) X.')
    assert out == ["false", "false"]


def test_the_comp_function_sees_tags():
    out = prints('Lot --> extrude(4) print(sum(comp(f){ isTagged("extrude.side") : geometry.area })) X.')
    assert float(out[0]) == pytest.approx(144)


@pytest.mark.parametrize("src, message", [
    ('Lot --> case isTagged("a") : X. else : Y.', "geometry.hasTags"),
    ('Lot --> tag("a", corners) X.', "components must be one of"),
    ('Lot --> extrude(1) comp(f){ isTagged("a", f) : X. }', "subcomponent is e or v"),
    ('Lot --> print(geometry.tags("a", sides)) X.', "components must be one of"),
])
def test_tag_misuse_is_a_warning_naming_the_fix(src, message):
    m = run(src)
    assert any(message in w for w in m.warnings), m.warnings


def test_logical_selectors_read_the_component_s_own_shape():
    a = areas(run("Lot --> extrude(6) comp(f){ side && scope.sx > 9 : Long. | side : Short. }"))
    assert a == pytest.approx({"Long": 2 * 60, "Short": 2 * 48})
    out = prints('Lot --> extrude(6) comp(e){ horizontal && scope.sx > 9 : print("long") } X.')
    assert out == ["long"] * 4


def test_edges_rising_from_tagged_vertices_take_their_tags():
    out = prints('Lot --> tag("corner", vertices) extrude(3) '
                 'comp(e){ vertical && isTagged("corner") : print("v") } X.')
    assert out == ["v"] * 4
    out = prints('Lot --> extrude(3) comp(e){ vertical && isTagged("corner") : print("v") } X.')
    assert out == []


def test_cleanup_keeps_edge_tags_of_merged_faces():
    out = prints('Lot --> inline(recompose) split(x){ 5 : X. | ~1 : tag("B", edges) X. } '
                 'cleanupGeometry(all, 0) print(geometry.nFaces) '
                 'comp(e){ isTagged("B") : print("b") } X.')
    # one face again; the right half's three outer edges keep B (the merged bottom and top
    # edges start in the left half, whose pieces were not tagged)
    assert out[0] == "1" and out.count("b") >= 1


def test_offset_and_taper_faces_take_the_tags_of_the_edges_they_rise_from():
    a = areas(run('Lot --> setback(2){ front : S | remainder : R. }\n'
                  'S --> offset(-0.5, border) comp(f){ isTagged("setback.front") : F. | all : O. }'))
    # the border is one face (a ring) rising from every edge, so it has the street edge's tag
    assert a["F"] == pytest.approx(10 * 2 - 9 * 1) and "O" not in a
    a = areas(run('Lot --> setback(2){ front : S | remainder : R. }\n'
                  'S --> taper(3) comp(f){ isTagged("setback.front") : F. | all : O. }'))
    assert a["F"] > 0


def test_a_roof_plane_takes_the_tags_of_its_eave_edge():
    a = areas(run('Lot --> setback(2){ front : S. | remainder : R }\n'
                  'R --> roofHip(30) comp(f){ isTagged("setback.back") : F. | all : O. }'))
    # the plane over the remainder's new front edge (10 m long, 6 m deep lot: a trapezoid
    # rising 3 m inwards at 30 degrees)
    assert a["F"] == pytest.approx((10 + 4) / 2 * 3 / np.cos(np.radians(30)))
