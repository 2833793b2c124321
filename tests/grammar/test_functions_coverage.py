"""CityEngine built-in functions that used to be unknown (a load-time error) or stubs: golden
values worked out by hand from the CGA reference's definitions and examples."""

import math

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import DerivationError
from facadeforge.grammar.functions import FUNCTIONS
from facadeforge.grammar.ops.queries import scope_distance
from facadeforge.model.scope import Scope


def call(name, *args):
    return FUNCTIONS[name][0](None, list(args))


def prints(src, lot="10x8", assets=None, **kw):
    """Derive ``src`` on a lot; the printed values, after checking there was no warning."""
    m = derive(load_rules(src, assets=assets), None, lot_size=lot, **kw)[0]
    assert not m.warnings, m.warnings
    return m.attributes["prints"]


def warnings_of(src, lot="10x8", assets=None):
    return derive(load_rules(src, assets=assets), None, lot_size=lot)[0].warnings


# ---- pure functions -------------------------------------------------------------------------

def test_is_null_follows_the_null_encodings():
    assert call("isNull", math.nan) is True
    assert call("isNull", "\ue000") is True
    assert call("isNull", 0.0) is False and call("isNull", "") is False
    assert call("isNull", np.array([1.0, math.nan])).tolist() == [False, True]
    assert call("isNull", np.array(["a", "\ue000"], object)).tolist() == [False, True]


def test_isnan_and_isinf_work_element_wise_on_arrays():
    assert call("isnan", np.array([1.0, math.nan])).tolist() == [False, True]
    assert call("isinf", np.array([math.inf, 2.0])).tolist() == [True, False]
    assert call("isnan", np.array(["nan"], object)).tolist() == [False]
    assert call("isnan", True) is False


@pytest.mark.parametrize("indices, values, expected", [
    (2.0, 1.0, [0, 0, 1, 0, 0, 0]),
    (np.arange(1.0, 5.0), 1.0, [0, 1, 1, 1, 1, 0]),
    (np.array([1.0, 3, 5]), np.array([1.0, 2, 3]), [0, 1, 0, 2, 0, 3]),
    (np.array([5.0, 1, 3]), np.array([1.0, 2, 3]), [0, 2, 0, 3, 0, 1]),
    (np.array([1.0, 1, 1]), np.array([1.0, 2, 3]), [0, 3, 0, 0, 0, 0]),   # repeats override
    (np.array([-1.0, 2]), 7.0, [0, 0, 7, 0, 0, 0]),                      # negatives ignored
])
def test_set_elems_1d_examples_of_the_reference(indices, values, expected):
    assert call("setElems", np.zeros(6), indices, values).tolist() == expected


def test_set_elems_logical_index_and_growing():
    seq = np.arange(1.0, 8.0)
    assert call("setElems", seq, seq > 4, 4.0).tolist() == [1, 2, 3, 4, 4, 4, 4]
    assert call("setElems", seq, seq > 4, np.array([3.0, 2, 1])).tolist() == [1, 2, 3, 4, 3, 2, 1]
    assert call("setElems", np.ones(2), 3.0, 5.0).tolist() == [1, 1, 0, 5]
    assert call("setElems", np.ones(2), 2.0, 2.0, 5.0).tolist() == [[1, 1, 0], [0, 0, 0], [0, 0, 5]]
    grown = call("setElems", np.array(["a"], object), 2.0, "c")
    assert grown.tolist() == ["a", "", "c"]


def test_set_elems_2d():
    z = np.zeros((3, 3))
    assert call("setElems", z, 1.0, 1.0, 5.0).tolist() == [[0, 0, 0], [0, 5, 0], [0, 0, 0]]
    assert call("setElems", z, np.array([0.0, 2]), np.arange(0.0, 3), 1.0).tolist() == \
        [[1, 1, 1], [0, 0, 0], [1, 1, 1]]
    v = np.array([[1.0, 2], [3, 4]])
    assert call("setElems", z, np.array([2.0, 1]), np.array([2.0, 0]), v).tolist() == \
        [[0, 0, 0], [4, 0, 3], [2, 0, 1]]
    assert call("setElems", z, np.array([1.0, 1]), np.array([0.0, 2]), v).tolist() == \
        [[0, 0, 0], [3, 0, 4], [0, 0, 0]]
    assert z.tolist() == np.zeros((3, 3)).tolist()  # a copy, never the argument


@pytest.mark.parametrize("args, message", [
    ((np.zeros(3), np.array([0.0, 1]), np.array([1.0, 2, 3])), "3 values for 2"),
    ((np.zeros(3), 0.0, "x"), "cannot put a string into a float array"),
    ((np.zeros(3), 200_000.0, 1.0), "more than 100000"),
    ((np.zeros(3), np.array(["a"], object), 1.0), "must be numbers or bools"),
])
def test_set_elems_bad_input(args, message):
    from facadeforge.grammar.values import CGARuntimeError

    with pytest.raises(CGARuntimeError, match=message):
        call("setElems", *args)


def test_sort_row_indices_reference_example():
    a = np.array([[4.0, 0, 1], [2, 1, 9], [1, 3, 0], [2, 1, 0]])
    assert call("sortRowIndices", a).tolist() == [2, 3, 1, 0]
    assert call("sortRowIndices", np.array([2.0, 1, 2, 0])).tolist() == [3, 1, 0, 2]  # stable
    assert call("sortRowIndices", np.array(["b", "a"], object)).tolist() == [1, 0]


def test_find_first_on_arrays_and_strings():
    assert call("findFirst", np.array([1.0, 2, 3, 4]), 2.0, 0.0) == 1
    assert call("findFirst", np.array([[1.0, 2, 3], [4, 5, 6]]), 4.0, 0.0) == 3  # row-major
    assert call("findFirst", np.array([6, 8.1, 6, 8.1]), 8.0, 0.5) == 1
    assert call("findFirst", np.array([6, 8.1]), 8.0) == -1
    assert call("findFirst", np.array(["Foliage", "Bark"], object), "Bark") == 1
    assert call("findFirst", "a;b;c", "b") == 2  # the utility library's string version


def test_list_to_and_from_array():
    assert call("listToArray", "a;b;c;").tolist() == ["a", "b", "c"]
    assert call("listToArray", "").tolist() == []
    assert call("listFromArray", np.array([1.0, 2.5])) == "1;2.5;"
    assert call("listFromArray", np.array(["x"], object)) == "x;"


def test_new_functions_load_in_a_rule_file():
    # unknown functions are a load-time error; every one of these must load and derive
    out = prints('''
const a = setElems([0,0,0], 1, 5)
Lot --> print(a) print(isNull(0)) print(sortRowIndices([3,1,2])) print(findFirst(a, 5, 0))
        print(listFromArray(listToArray("p;q;")))''')
    assert out == ["(3)[0,5,0]", "false", "(3)[1,2,0]", "1", "p;q;"]


def test_print_function_prints_and_returns_its_value():
    assert prints('Lot --> extrude(print(2) + 1) print(scope.sy)') == ["2", "3"]


# ---- geometry queries -----------------------------------------------------------------------

def test_boundary_length_of_a_lot_a_box_and_a_face():
    out = prints('''
Lot --> print(geometry.boundaryLength) extrude(5) print(geometry.boundaryLength)
        comp(f) { top : print(geometry.boundaryLength) T. }''')
    assert out == ["36", "0", "36"]  # 2 (10 + 8); closed box; its 10 x 8 top


def test_boundary_length_of_components():
    out = prints('Lot --> extrude(2) comp(f) { top : T | front : F }\n'
                 'T --> print(geometry.boundaryLength)\nF --> print(geometry.boundaryLength)')
    assert sorted(out, key=float) == ["24", "36"]  # front 10 x 2, top 10 x 8


def test_is_concave():
    l_shape = [[0, 0, 0], [0, 0, 4], [10, 0, 4], [10, 0, 2], [3, 0, 2], [3, 0, 0]]
    from facadeforge.geometry.footprints import Footprint

    fp = Footprint("l", np.array(l_shape, float)[::-1])
    m = derive(load_rules("Lot --> print(geometry.isConcave) extrude(3) print(geometry.isConcave)"),
               [fp])[0]
    assert m.attributes["prints"] == ["true", "true"]
    # a rectangle, and a polygon with a straight (180°) corner, are not concave
    assert prints("Lot --> print(geometry.isConcave)") == ["false"]
    fp = Footprint("p", np.array([[0, 0, 0], [0, 0, 4], [5, 0, 4], [10, 0, 4], [10, 0, 0]], float)[::-1])
    m = derive(load_rules("Lot --> print(geometry.isConcave)"), [fp])[0]
    assert m.attributes["prints"] == ["false"]


def test_is_oriented_and_n_holes():
    out = prints('''
Lot --> print(geometry.isOriented(top)) print(geometry.isOriented(front)) print(geometry.nHoles)
        extrude(3) print(geometry.isOriented(front)) print(geometry.isOriented(world.north))
        comp(f) { top : print(geometry.isOriented(front)) print(geometry.isOriented(world.up))
                        print(geometry.isOriented(world.side)) T. }''')
    # a component's scope has z along its normal: the top face is "front" in its own scope
    assert out == ["true", "false", "0", "true", "true", "true", "true", "false"]
    w = warnings_of("Lot --> print(geometry.isOriented(upwards))")
    assert any("unknown face selector 'upwards'" in x for x in w)


def test_n_holes_counts_the_holes_of_pieces_around_them():
    # an offset border is four pieces around one hole; a courtyard cut out of a lot likewise
    out = prints("""Lot --> offset(-2, border) print(geometry.nHoles) deleteHoles() print(geometry.nHoles)
Lot2 --> X""")
    assert out == ["1", "0"]
    out = prints("Lot --> subtract { X. | s('0.5,'1,'0.5) center(xz) Y. } print(geometry.nHoles)")
    assert out == ["1"]


def test_is_instanced_groups_and_materials(tmp_path):
    (tmp_path / "two.mtl").write_text("newmtl Wood\nKd 0.5 0.3 0.1\nnewmtl Bark\nKd 0.2 0.1 0\n")
    (tmp_path / "tree.obj").write_text(
        "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\n"
        "g trunk\nusemtl Wood\nf 1 2 3 4\ng crown\nusemtl Bark\nf 1 2 6 5\n")
    out = prints('''
Lot --> print(geometry.isInstanced) print(geometry.groups)
        i("tree.obj") print(geometry.isInstanced) print(geometry.groups) print(geometry.materials)
        s(2, 2, 2) print(geometry.isInstanced)
        split(x) { '0.5 : print(geometry.isInstanced) A. | ~1 : B. }''', assets=tmp_path)
    # materials in component-split order: comp(m) takes them as the faces first use them
    assert out == ["false", "(1)[lot]", "true", "(2)[trunk,crown]", "(2)[Wood,Bark]", "true", "false"]


# ---- files and assets -----------------------------------------------------------------------

def _box_obj(sx, sy, sz) -> str:
    v = [(x * sx, y * sy, z * sz) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    faces = ["1 2 4 3", "5 7 8 6", "1 5 6 2", "3 4 8 7", "1 3 7 5", "2 6 8 4"]
    return "".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(f"f {f}\n" for f in faces)


@pytest.fixture
def boxes(tmp_path):
    """Assets with sizes (x, y, z): 1 x 1 x 1, 2 x 1 x 1, 4 x 1 x 2, 9 x 1 x 8."""
    for name, size in {"a1": (1, 1, 1), "b2": (2, 1, 1), "c4": (4, 1, 2), "d9": (9, 1, 8)}.items():
        (tmp_path / f"box_{name}.obj").write_text(_box_obj(*size))
    (tmp_path / "readme.txt").write_text("not an asset")
    return tmp_path


def test_files_search_is_an_array(boxes):
    out = prints('Lot --> print(filesSearch("box_*.obj")) print(size(filesSearch("*.none")))',
                 assets=boxes)
    assert out == ["(4)[box_a1.obj,box_b2.obj,box_c4.obj,box_d9.obj]", "0"]


def test_asset_best_and_approx_size(boxes):
    # the 10 x 8 lot: d9 needs 10/9 - 1 = 11 % on x and 8/8 on z; c4 needs 150 % and 300 %
    out = prints('''
Lot --> print(assetBestSize("box_*.obj", "xz")) print(assetBestSize("box_*.obj", "x"))
        s(2, 1, 1) print(assetBestSize("box_*.obj", "x")) print(assetApproxSize("box_*.obj", "x", 1))''',
                 assets=boxes)
    assert out == ["box_d9.obj", "box_d9.obj", "box_b2.obj", "box_b2.obj"]
    picks = set()
    for seed in range(12):
        picks.update(prints('Lot --> s(2, 1, 1) print(assetApproxSize("box_*.obj", "x", 2))',
                            assets=boxes, seed=seed))
    # the two best x fits of 2: b2 (no scaling), c4 (-50 %); a1 would need +100 %
    assert picks == {"box_b2.obj", "box_c4.obj"}


def test_sort_functions_take_string_arrays(boxes):
    out = prints('Lot --> s(2, 1, 1) print(assetsSortSize(filesSearch("box_*.obj"), "x", 0)) '
                 'print(assetsSortSize("box_a1.obj;box_b2.obj;box_c4.obj;", "x", 0.6))',
                 assets=boxes)
    # scaling needed for x = 2: b2 0 %, c4 50 %, a1 100 %, d9 78 %
    assert out == ["box_b2.obj;box_c4.obj;box_d9.obj;box_a1.obj;", "box_b2.obj;box_c4.obj;"]


def test_asset_fit_size(boxes):
    # scope 4 x 0 x 2: within 10 % only c4 (4 x 2) fits; 0 allows every asset
    out = prints('Lot --> s(4, 0, 2) print(assetFitSize("box_*.obj", "xz", 0.1))', assets=boxes)
    assert out == ["box_c4.obj"]
    picks = set()
    for seed in range(20):
        picks.update(prints('Lot --> print(assetFitSize("box_*.obj", "x", 0))', assets=boxes,
                            seed=seed))
    assert picks == {"box_a1.obj", "box_b2.obj", "box_c4.obj", "box_d9.obj"}
    # nothing within 1 %: the best size fit
    out = prints('Lot --> s(3, 1, 1) print(assetFitSize("box_*.obj", "x", 0.01))', assets=boxes)
    assert out == ["box_c4.obj"]  # 3/4 - 1 = 25 % against 3/2 - 1 = 50 %


def test_asset_best_and_approx_ratio(boxes):
    # lot ratio x / z = 10 / 8 = 1.25: d9 (9 / 8 = 1.125) is closest, then a1 and b2... by log
    out = prints('Lot --> print(assetBestRatio("box_*.obj", "xz")) '
                 'print(assetApproxRatio("box_*.obj", "xz", 1)) '
                 's(4, 1, 2) print(assetBestRatio("box_*.obj", "xz"))', assets=boxes)
    assert out == ["box_d9.obj", "box_d9.obj", "box_b2.obj"]  # 4/2 = 2: b2 and c4 tie, b2 first


def test_image_best_ratio(tmp_path):
    from PIL import Image

    Image.new("RGB", (40, 10)).save(tmp_path / "wide.png")
    Image.new("RGB", (10, 20)).save(tmp_path / "tall.png")
    # ratios x / z: 8 (wide 4 is closest), 1/3 (tall 0.5 is closest)
    out = prints('Lot --> s(8, 1, 1) print(imageBestRatio("*.png", "xz")) s(1, 1, 3) '
                 'print(imageBestRatio("*.png", "xz")) print(imageApproxRatio("*.png", "xz", 1))',
                 assets=tmp_path)
    assert out == ["wide.png", "tall.png", "tall.png"]


def test_asset_naming_info_and_metadata(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl Foliage\nnewmtl Bark\n")
    (tmp_path / "t.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                    "o tree\nusemtl Foliage\nf 1 2 3\nusemtl Bark\nf 1 3 2\n")
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    out = prints('''
Lot --> print(assetNamingInfo("t.obj", m)) print(assetNamingInfos("t.obj", g))
        print(assetNamingInfo("plain.obj", g)) print(assetMetadata("t.obj", "height", 7))''',
                 assets=tmp_path)
    assert out == ["Bark;Foliage;", "(1)[tree]", "plain;", "7"]
    w = warnings_of('Lot --> print(assetNamingInfo("t.obj", x))', assets=tmp_path)
    assert any("unknown naming selector 'x'" in x for x in w)
    w = warnings_of('Lot --> print(assetNamingInfo("missing.obj", m))', assets=tmp_path)
    assert any("'missing.obj' not found" in x for x in w)


def test_asset_selector_errors(boxes):
    w = warnings_of('Lot --> print(assetBestSize("box_*.obj", "q"))', assets=boxes)
    assert any('axis selector \'q\'' in x for x in w)
    w = warnings_of('Lot --> print(assetApproxRatio("box_*.obj", "xz", 0))', assets=boxes)
    assert any("n must be an integer >= 1" in x for x in w)


# ---- context queries ------------------------------------------------------------------------

def test_context_count_reference_example():
    # 10 x 8 lot in ~2 tiles: 5 x 4 = 20 labeled shapes, each tile sees all of them
    out = prints('''
Lot --> split(x) { ~2 : Split }*
Split --> split(z) { ~2 : Tile }*
Tile --> label("Tile") Color
Color --> print(contextCount(intra, "Tile")) print(contextCount(all, "Tile"))
          print(contextCount(inter, "Tile")) print(contextCount(intra, "")) print(contextCount(intra, "x"))''')
    assert len(out) == 5 * 20 and set(out[0::5]) == set(out[1::5]) == {"20"}
    assert set(out[2::5]) | set(out[3::5]) | set(out[4::5]) == {"0"}


def test_each_label_operation_is_one_labeled_shape():
    assert prints('Lot --> label("l") print(contextCount(intra, "l")) label("l")') == ["2"]


def test_context_compare_ranks():
    # five strips 2 m wide along x, extruded 1..5 m high (split.index + 1)
    out = prints('''
Lot --> split(x) { 2 : Strip(split.index) }*
Strip(i) --> extrude(i + 1) label("b") Rank(i)
Rank(i) --> print(i + ":" + contextCompare(intra, "b", world.highest) + ","
                  + contextCompare(intra, "b", world.westernmost) + ","
                  + contextCompare(intra, "b", world.lowest) + ","
                  + contextCompare(intra, "b", area.largest))''')
    # highest: strip 4 first; westernmost: strip 0 first; all share the lowest bound (rank 0)
    assert sorted(out) == ["0:4,0,0,4", "1:3,1,0,3", "2:2,2,0,2", "3:1,3,0,1", "4:0,4,0,0"]
    assert prints('Lot --> print(contextCompare(intra, "none", world.highest))') == ["0"]
    w = warnings_of('Lot --> label("b") print(contextCompare(intra, "b", tallest))')
    assert any("unknown comparison 'tallest'" in x for x in w)


def test_minimum_distance_reference_example():
    # 10 x 8 lot in 1 m cells; the cell (5, 4) is labeled; each cell extrudes by 10 - distance
    m = derive(load_rules('''
Lot --> split(x) { ~1 : Lot(split.index) }*
Lot(x) --> split(z) { ~1 : Lot(x, split.index) }*
Lot(x, z) --> [ case x == 5 && z == 4 : label("c") else : NIL ]
              Extrude(minimumDistance(intra, "c"))
Extrude(d) --> extrude(10 - d) X.'''), None, lot_size="10x8")[0]
    assert not m.warnings
    heights = sorted(round(p.mesh.bounds()[1, 1], 6) for p in m.parts)
    # the labeled cell and its 8 neighbours touch it (distance 0); the farthest cell (0, 0)
    # is sqrt(4^2 + 3^2) = 5 away
    assert heights.count(10.0) == 9 and heights[0] == pytest.approx(5.0)
    assert prints('Lot --> print(minimumDistance(intra, "none")) print(minimumDistance(inter, "x"))') \
        == ["inf", "inf"]


def test_scope_distance_between_boxes():
    unit = Scope(np.zeros(3), np.eye(3), np.ones(3))
    far = Scope(np.array([3.0, 0, 0]), np.eye(3), np.ones(3))
    assert scope_distance(unit, far) == pytest.approx(2.0)
    diag = Scope(np.array([2.0, 2, 2]), np.eye(3), np.ones(3))
    assert scope_distance(unit, diag) == pytest.approx(math.sqrt(3))
    inner = Scope(np.array([0.25, 0.25, 0.25]), np.eye(3), np.full(3, 0.5))
    assert scope_distance(unit, inner) == 0.0
    # a box rotated 45° about y whose nearest corner is 1 m from the unit box's x = 1 face
    rot = Scope.from_axes([2.0, 0, 0.5], [1, 0, -1], [0, 1, 0], (1.0, 1.0, 1.0))
    assert scope_distance(unit, rot) == pytest.approx(1.0)
    # two crossing flat boxes (a plus sign): they overlap although no corner is inside the other
    a = Scope(np.array([0.0, 0, 0.4]), np.eye(3), np.array([3.0, 0, 0.2]))
    b = Scope(np.array([1.4, 0, -1.0]), np.eye(3), np.array([0.2, 0, 3.0]))
    assert scope_distance(a, b) == 0.0


def test_context_queries_in_strict_mode_and_first_pass_defaults():
    # in the first pass the query answers 0, so a second label appears; the real pass counts 2
    out = prints('Lot --> label("x") [ case contextCount(intra, "x") == 0 : label("x") else : X. ] '
                 'print(contextCount(intra, "x"))')
    assert out == ["2"]
    with pytest.raises(DerivationError, match="unknown target"):
        derive(load_rules('Lot --> print(contextCount(everywhere, "x"))'), None, lot_size="4x4",
               strict=True)


# ---- edge attributes, geo coordinates -------------------------------------------------------

def test_edge_attributes_have_their_documented_defaults():
    out = prints('Lot --> print(edgeAttr.getFloat("w")) print(edgeAttr.getString("c") + "|") '
                 'print(edgeAttr.getBool("b"))')
    assert out == ["0", "|", "false"]


def test_get_geo_coord():
    out = prints('Lot --> t(3, 0, 2) print(getGeoCoord(X)) print(getGeoCoord(Y))')
    assert out == ["3", "-2"]  # x is east, north is -z
    w = warnings_of("Lot --> print(getGeoCoord(lat))")
    assert any("georeferenced" in x for x in w)
