"""Golden shape-tree dumps per operation, plus targeted checks of CityEngine semantics.

Regenerate the golden files after an intended change with ``UPDATE_GOLDEN=1 pytest tests/grammar``
and review the diff.
"""

import os
from pathlib import Path

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.engine import stats

GOLDEN = Path(__file__).resolve().parents[1] / "data" / "golden"

CASES = {
    "extrude": "Lot --> extrude(10) X.",
    "comp_faces": "Lot --> extrude(6) comp(f) { front : F | side : S | top : T. | bottom : NIL }",
    "comp_merged": "Lot --> extrude(6) comp(f) { side = S | all : O }",
    "split_floors": "Lot --> extrude(11) comp(f) { front : Fa | all : NIL }\n"
                    "Fa --> split(y) { 4 : G | { ~3 : Fl(split.index, split.total) }* }\n"
                    "Fl(i, n) --> split(x) { ~1 : W | { 2 : T | ~1 : W }* }",
    "split_volume": "Lot --> extrude(9) split(y) { ~3 : Floor }*",
    "split_noadjust": "Lot --> extrude(4) comp(f) { front : split(x, noAdjust) { '0.3 : A | ~1 : B } | all : NIL }",
    "transforms": "Lot --> [ t(1, 2, 3) s(2, '0.5, 1) A ] [ r(0, 90, 0) B ] center(xz) C",
    "offset": "Lot --> offset(-2) comp(f) { inside : I | border : B }",
    "insert_builtin": "Lot --> extrude(3) comp(f) { front : split(x) { { 2 : s('0.8, '0.5, 0.3) center(xy) i(\"builtin:cube\") Box }* } | all : NIL }",
    "stochastic_case": "attr h = 7\nLot --> case h > 5 : extrude(h) A else : B\nA --> 50% : X. else : Y.",
    "nested_inline": "Lot --> extrude(5) comp(f) { front : split(y) { 2 : color(\"#ff0000\") Red | ~1 : split(x) { ~1 : L | ~1 : R } } | all : NIL }",
    "convexify": "Lot --> convexify() comp(f) { all : P }",
    "roof_hip": "Lot --> extrude(6) comp(f) { top : roofHip(30) comp(f) { bottom : NIL | horizontal : H | all : R } | all : NIL }",
    "roof_gable": "Lot --> extrude(6) comp(f) { top : roofGable(35) comp(f) { bottom : NIL | vertical : G | all : R } | all : NIL }",
    "comp_edges": "Lot --> comp(e) { front : F | all : E }",
    "setback": "Lot --> setback(2) { front : Yard | remainder : extrude(5) House. }",
    "envelope": "Lot --> envelope(normal, 12, 6, 45) E.",
}


def derive_text(src: str, lot="10x8", **kw):
    return derive(load_rules(src), lot_size=lot, **kw)


@pytest.mark.parametrize("name", sorted(CASES))
def test_golden_dump(name):
    lot = "12x8"
    fp = None
    if name == "convexify":
        from facadeforge.geometry.footprints import Footprint

        poly = np.array([[0, 0, 0], [0, 0, 6], [6, 0, 6], [6, 0, 3], [3, 0, 3], [3, 0, 0]], float)[::-1]
        fp = [Footprint("L", poly)]
    models = derive(load_rules(CASES[name]), fp, lot_size=None if fp else lot)
    text = models[0].root.dump() + "\n"
    path = GOLDEN / f"{name}.txt"
    if os.environ.get("UPDATE_GOLDEN"):
        path.write_text(text)
    assert path.exists(), f"no golden file {path.name}: run with UPDATE_GOLDEN=1 and review it"
    assert text == path.read_text()


def test_lot_scope_and_front_face():
    m = derive_text("Lot --> extrude(10) comp(f) { front : F | all : NIL }", lot="20x12")[0]
    lot = m.root
    assert np.allclose(lot.scope.size, [20, 0, 12])
    front = [s for s in lot.walk() if s.symbol == "F"]
    assert len(front) == 1
    # the first lot edge faces the street (+z): the front facade is 20 m wide, 10 m tall, at z=12
    assert np.allclose(front[0].scope.size, [20, 10, 0])
    assert np.allclose(front[0].scope.rotation[:, 2], [0, 0, 1])
    assert np.allclose(front[0].scope.origin, [0, 0, 12])


def test_split_tiles_parent_area_exactly():
    src = "Lot --> extrude(10) comp(f) { side : Fa | all : NIL }\n" \
          "Fa --> split(y) { ~3 : split(x) { { ~2.2 : T }* } }*"
    m = derive_text(src, lot="17.3x9.1")[0]
    total = sum(p.mesh.area() for p in m.parts)
    assert total == pytest.approx(2 * (17.3 + 9.1) * 10, rel=1e-9)


def test_split_of_closed_volume_keeps_it_closed():
    m = derive_text("Lot --> extrude(9) split(y) { ~3 : Floor. }*")[0]
    vols = [p.mesh.volume() for p in m.parts]
    assert len(vols) == 3 and all(v == pytest.approx(10 * 8 * 3) for v in vols)
    assert all(p.mesh.is_closed() for p in m.parts)


def test_l_shaped_volume_split_caps_nonconvex_section():
    from facadeforge.geometry.footprints import Footprint

    poly = np.array([[0, 0, 0], [0, 0, 6], [6, 0, 6], [6, 0, 3], [3, 0, 3], [3, 0, 0]], float)[::-1]
    m = derive(load_rules("Lot --> extrude(6) split(y) { ~2 : F. }*"), [Footprint("L", poly)])[0]
    assert len(m.parts) == 3
    for p in m.parts:
        assert p.mesh.is_closed()
        assert p.mesh.volume() == pytest.approx(27 * 2)


def test_attributes_overrides_and_set():
    src = "attr h = 5\nattr name = \"a\"\nLot --> extrude(h) A\nA --> set(h, 2) report(\"h\", h) B\nB --> report(\"h2\", h) report(\"n\", name)"
    m = derive(load_rules(src), lot_size="4x4", attrs={"h": "8", "name": "x"})[0]
    assert m.reports == {"h": [2.0], "h2": [2.0], "n": ["x"]}
    assert m.stats()["bbox"][1][1] == pytest.approx(8)


def test_functions_strings_arrays():
    src = '''attr names = "a;b;c;"
f(x) = case x > 2 : "big" else : "small"
g(a, b) = a * b + 1
Lot --> report("s", f(3) + "_" + f(1)) report("g", g(2, 3)) report("n", listSize(names))
        report("item", listItem(names, 1)) report("arr", [4, 5, 6][2]) report("sz", size([1, 2]))
        report("find", find("facade", "a", 1)) report("sub", substring("facade", 1, 3))
        report("mod", 7 % 3) report("pow", 2 ^ 3) report("str", str(2.5) + str(3)) report("rnd", rint(2.5))
'''
    m = derive_text(src)[0]
    r = {k: v[0] for k, v in m.reports.items()}
    assert r == {"s": "big_small", "g": 7.0, "n": 3.0, "item": "b", "arr": 6.0, "sz": 2.0,
                 "find": 3.0, "sub": "ac", "mod": 1.0, "pow": 8.0, "str": "2.53", "rnd": 2.0}


def test_rule_overloading_and_recursion():
    src = "Lot --> A(3)\nA(n) --> case n > 0 : report(\"n\", n) A(n - 1) else : A\nA --> report(\"done\", 1)"
    m = derive_text(src)[0]
    assert m.reports == {"n": [3.0, 2.0, 1.0], "done": [1.0]}


def test_stochastic_is_seeded_and_deterministic():
    src = "Lot --> split(x) { { 1 : T }* }\nT --> 50% : report(\"a\", 1) else : report(\"b\", 1)"
    a = derive_text(src, lot="40x2", seed=1)[0].reports
    b = derive_text(src, lot="40x2", seed=1)[0].reports
    c = derive_text(src, lot="40x2", seed=2)[0].reports
    assert a == b
    assert len(a.get("a", [])) + len(a.get("b", [])) == 40
    assert 8 <= len(a.get("a", [])) <= 32
    assert a != c


def test_consistency_tag_makes_shapes_identical():
    src = ("Lot --> split(x) { { 1 : T }* }\n"
           "T --> consistent(\"tiles\") W\nW --> 50% : report(\"a\", 1) else : report(\"b\", 1)")
    r = derive_text(src, lot="30x2", seed=3)[0].reports
    assert len(r) == 1 and len(next(iter(r.values()))) == 30


def test_runtime_problem_is_warning_and_strict_is_error():
    from facadeforge.errors import DerivationError

    src = 'Lot --> i("missing.obj") X'
    m = derive_text(src)[0]
    assert any("missing.obj" in w for w in m.warnings)
    with pytest.raises(DerivationError, match="--strict"):
        derive_text(src, strict=True)


def test_caps_raise_derivation_error_naming_rule():
    from facadeforge.errors import DerivationError
    from facadeforge.grammar.interpreter import Limits

    with pytest.raises(DerivationError, match="rule 'A'"):
        derive(load_rules("Lot --> A\nA --> B A"), lot_size="2x2", limits=Limits(max_depth=50))
    # a repeat that would pass the cap says so before it makes a piece
    with pytest.raises(DerivationError, match="makes 500 pieces, more than the 100 shapes"):
        derive(load_rules("Lot --> split(x) { { 0.01 : T }* }"), lot_size="5x2",
               limits=Limits(max_shapes=100))
    # shapes made one by one meet the cap too
    with pytest.raises(DerivationError, match="more than 100 shapes"):
        derive(load_rules("Lot --> split(x) { { 0.5 : T }* }\nT --> U U U U U U U U U U U U"),
               lot_size="5x2", limits=Limits(max_shapes=100))


def test_stats_keys():
    models = derive_text("Lot --> extrude(3) report(\"v\", geometry.volume())")
    s = stats(models, 0.1)
    assert set(s) == {"shapes", "faces", "triangles", "vertices", "area", "bbox", "report",
                      "warnings", "seconds"}
    assert s["report"]["v"] == [pytest.approx(240)]
    assert s["faces"] == 6 and s["triangles"] == 12


def test_roof_volumes_are_closed_and_sized():
    m = derive_text("Lot --> extrude(6) comp(f) { top : roofHip(45) Roof. | all : NIL }", lot="12x8")[0]
    (roof,) = m.parts
    assert roof.mesh.is_closed()
    # hip roof over 12 x 8 at 45 degrees: ridge height 4, volume = 4*(12*8/2 - 8*8/6)... exact:
    # V = h * (L*W/2 - W^2/6) with h = W/2 * tan(45)
    assert roof.mesh.volume() == pytest.approx(4 * (12 * 8 / 2 - 8 * 8 / 6))
    assert m.stats()["bbox"][1][1] == pytest.approx(10)


@pytest.mark.parametrize("roof, closed", [
    ("roofHip(byHeight, 3)", True), ("roofHip(byHeight, 3, 1)", False),  # overhangs open it
    ("roofGable(byHeight, 3)", True), ("roofGable(byHeight, 3, 1, 0.5)", False),
    ("roofPyramid(byHeight, 3)", True), ("roofShed(byHeight, 3)", True),
    ("roofShed(byHeight, 3, 1)", True)])
def test_roofs_by_height_reach_that_height(roof, closed):
    m = derive_text(f"Lot --> extrude(6) comp(f) {{ top : {roof} Roof. | all : NIL }}",
                    lot="12x8")[0]
    (part,) = m.parts
    assert part.mesh.is_closed() == closed
    assert m.stats()["bbox"][1][1] == pytest.approx(9)


def test_roofs_by_angle_and_gable_index():
    def top(roof):
        m = derive_text(f"Lot --> extrude(6) comp(f) {{ top : {roof} Roof. | all : NIL }}",
                        lot="12x8")[0]
        return m.stats()["bbox"][1][1] - 6

    assert top("roofGable(byAngle, 45)") == pytest.approx(top("roofGable(45)")) == pytest.approx(4)
    # index 0 makes the 12 m side a gable: the planes rise across 12 m, to 6 m at 45 degrees
    assert top("roofGable(45, 0, 0, false, 0)") == pytest.approx(6)
    assert top("roofGable(45, 0, 0, false, 1)") == pytest.approx(4)
    assert top("roofShed(byAngle, 45, 1)") == pytest.approx(12)
    m = derive_text("Lot --> extrude(6) comp(f) { top : roofHip(byWidth, 3) Roof. | all : NIL }",
                    lot="12x8")[0]
    assert any("roofHip: the first argument is an angle, byAngle or byHeight, not 'byWidth'" in w
               for w in m.warnings)


def test_vertex_and_edge_components_of_a_box():
    def count(src):
        m = derive_text(src, lot="4x3")[0]
        return sum(s.symbol == "C" for s in m.root.walk())

    # v and e: shared ones once; fv and fe: every face's own
    assert count("Lot --> extrude(2) comp(v){ all : C. }") == 8
    assert count("Lot --> extrude(2) comp(fv){ all : C. }") == 24
    assert count("Lot --> extrude(2) comp(e){ all : C. }") == 12
    assert count("Lot --> extrude(2) comp(fe){ all : C. }") == 24
    assert count('Lot --> extrude(2) comp(v){ isTagged("extrude.top", v) : C. }') == 4
    m = derive_text("Lot --> extrude(2) print(geometry.nVertices) print(geometry.nEdges) "
                    "print(geometry.nFaces) print(comp(v){ all : 1 }) X.", lot="4x3")[0]
    assert m.attributes["prints"] == ["8", "12", "6", "(8)[1,1,1,1,1,1,1,1]"]


def test_extrude_scope_follows_the_extrusion():
    src = ("Lot --> extrude(6) comp(f) { front : extrude(0.5) report(\"sy\", scope.sy) "
           "report(\"sz\", scope.sz) comp(f) { top : T. | all : NIL } | all : NIL }")
    m = derive_text(src, lot="10x8")[0]
    assert m.reports == {"sy": [0.5], "sz": [6.0]}
    # the extruded front face of a facade element is its "top" in the new scope
    (top,) = m.parts
    assert top.mesh.face_normals()[0] == pytest.approx([0, 0, 1])


def test_comp_side_includes_every_non_horizontal_face():
    m = derive_text("Lot --> extrude(5) comp(f) { side : S | all : A }", lot="6x4")[0]
    sym = sorted(p.symbol for p in m.parts)
    assert sym == ["A", "A", "S", "S", "S", "S"]


def test_setback_and_edges():
    m = derive_text(CASES["setback"], lot="10x8")[0]
    yard = [p for p in m.parts if p.symbol == "Yard"]
    house = [p for p in m.parts if p.symbol == "House"]
    assert sum(p.mesh.area() for p in yard) == pytest.approx(20)
    assert house[0].mesh.volume() == pytest.approx(10 * 6 * 5)
    e = derive_text("Lot --> comp(e) { all : E }", lot="10x8")[0]
    assert len([s for s in e.root.walk() if s.symbol == "E"]) == 4


def test_uv_projection_and_texture(tmp_path):
    from PIL import Image

    Image.new("RGB", (8, 8), (200, 50, 50)).save(tmp_path / "brick.png")
    src = ("Lot --> extrude(6) comp(f) { front : setupProjection(0, scope.xy, 2, 3) projectUV(0) "
           "texture(\"brick.png\") F. | all : NIL }")
    m = derive(load_rules(src, assets=tmp_path), lot_size="10x8")[0]
    (f,) = m.parts
    uv = f.mesh.corner_uvs
    assert uv[:, 0].max() == pytest.approx(5) and uv[:, 1].max() == pytest.approx(2)
    assert f.material.texture == str(tmp_path / "brick.png")


def test_occlusion_between_masses():
    src = ("Lot --> [ extrude(10) comp(f) { side : A | all : NIL } ] "
           "[ t(4, 0, 0) s(6, 0, '1) extrude(4) comp(f) { side : B | all : NIL } ]\n"
           "B --> report(\"inside\", inside()) report(\"overlaps\", overlaps()) report(\"touches\", touches())")
    m = derive_text(src, lot="10x8")[0]
    r = m.reports
    # the low mass lies within the 10 m one: all its walls touch or lie inside it
    assert all(r["touches"]) and all(r["inside"])
    assert len(r["inside"]) == 4


def test_occlusion_queries_by_bare_name_and_in_attributes():
    """``case inside : …`` calls the query as ``inside()`` does, and so does an attribute's
    value: either way the rules keep their occluders."""
    body = ("Lot --> [ extrude(10) comp(f){ all : W. } ] s('0.5, 0, '0.5) center(xz) "
            "extrude(2) Q\n")
    for q in ("Q --> case inside : In. else : Out.", "Q --> case inside() : In. else : Out."):
        m = derive_text(body + q, lot="10x8")[0]
        assert [p.symbol for p in m.parts if p.symbol in ("In", "Out")] == ["In"], q
    m = derive_text("attr here = inside()\n" + body + "Q --> report(\"in\", here) X.",
                    lot="10x8")[0]
    assert m.reports["in"] == [True]


def test_deep_trees_come_back_from_worker_processes(tmp_path):
    """A worker pickles its model's shape tree after the derivation put Python's recursion
    limit back: a rule recursing 250 levels still comes back, with its tree."""
    import json

    from facadeforge import derive

    fp = tmp_path / "lots.geojson"
    fp.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [
            [[40 * i, 0], [40 * i + 20, 0], [40 * i + 20, 10], [40 * i, 10], [40 * i, 0]]]}}
        for i in range(4)]}))
    rules = tmp_path / "deep.cga"
    rules.write_text("Lot --> R(0)\nR(n) --> case n < 250 : split(x){ 0.02 : A. | ~1 : R(n + 1) }"
                     " else : X.\n")
    models = derive(rules, fp, workers=2)
    assert len(models) == 4
    depth, node = 0, next(s for s in models[0].root.walk() if s.symbol == "X")
    while node.parent is not None:
        depth, node = depth + 1, node.parent
    assert depth > 250


def test_label_layout_export(tmp_path):
    from PIL import Image

    from facadeforge import export

    src = ("Lot --> extrude(6) comp(f) { front : Facade | all : NIL }\n"
           "Facade --> split(x) { ~1 : Wall | 2 : Window | ~1 : Wall }")
    models = derive_text(src, lot="10x8")
    export(models, tmp_path / "labels.png")
    export(models, tmp_path / "labels.svg")
    img = np.asarray(Image.open(tmp_path / "labels.png"))
    assert len(np.unique(img)) >= 2
    assert "window" in (tmp_path / "labels.svg").read_text()


def test_dialect_details_seen_in_production_rules():
    src = """@Handle(shape=Post*, axis=x, repeat=none)
@Range(min=1, max=20)
attr n = 3
const half = n / 2
upMode = case n > 2 : "zUp" else : "yUp"
Lot --> report("a", case n > 2 : "big" else : "small") report("b", half()) report("c", upMode)
        report("d", sel("all")) report("e", 5 % 3) color(40% : "#ffffff" else : "#000000")
        set(scope.sx, 4) report("sx", scope.sx) set(trim.vertical, false) X
"""
    r = load_rules(src)
    assert r.ruleset.parameter_ranges() == {"n": (1.0, 20.0)}
    m = derive(r, lot_size="10x8")[0]
    assert {k: v[0] for k, v in m.reports.items()} == {"a": "big", "b": 1.5, "c": "zUp",
                                                       "d": "all", "e": 2.0, "sx": 4.0}
    assert not m.warnings


def test_import_overrides_with_expressions(tmp_path):
    (tmp_path / "f.cga").write_text('attr w = 1\nFacade --> report("w", w)\n')
    (tmp_path / "m.cga").write_text('attr width = 7\n@Hidden\nimport F : "f.cga" (w = width * 2)\n'
                                    'Lot --> F.Facade\n')
    m = derive(tmp_path / "m.cga", lot_size="4x4")[0]
    assert m.reports == {"w": [14.0]}


def test_uv_split_and_scatter():
    src = ("Lot --> extrude(6) comp(f) { front : setupProjection(0, scope.xy, 2, 2) projectUV(0) "
           "split(u, unitSpace, 0) { 1 : A | ~1 : B } | top : scatter(surface, 25, uniform) { P } "
           "| all : NIL }")
    m = derive_text(src, lot="10x8")[0]
    areas = {p.symbol: p.mesh.area() for p in m.parts if p.symbol in "AB"}
    assert areas == {"A": pytest.approx(6), "B": pytest.approx(54)}
    pts = [s for s in m.root.walk() if s.symbol == "P"]
    assert len(pts) == 25
    y = {round(float(s.scope.origin[1]), 6) for s in pts}
    assert y == {6.0}  # on the roof surface


@pytest.mark.parametrize("src,shape_area,rest_area", [
    ("Lot --> shapeL(3, 2) { shape : S | remainder : R }", 40, 40),
    ("Lot --> shapeU(1, 1, 1) { shape : S | remainder : R }", 24, 56),
    ("Lot --> shapeO(1, 2, 3, 4) { shape : S | remainder : R }", 64, 16),
    ("Lot --> setback(1) { all : S | remainder : R }", 32, 48),
])
def test_shape_letters_and_ring_setbacks(src, shape_area, rest_area):
    m = derive_text(src, lot="10x8")[0]
    area = {k: sum(p.mesh.area() for p in m.parts if p.symbol == k) for k in "SR"}
    assert area == {"S": pytest.approx(shape_area), "R": pytest.approx(rest_area)}


def test_arrays_and_tables(tmp_path):
    (tmp_path / "heights.csv").write_text("name,height\na,10\nb,12.5\n")
    src = """attr xs = [1, 2, 3]
Lot --> report("n", size(xs)) report("sum", sum(xs * 2)) report("i", index(xs, 2))
        report("t", readFloatTable("heights.csv")[2, 1]) report("s", readStringTable("heights.csv")[1, 0])
        report("sorted", sort([3, 1, 2])[0]) report("str", splitString("a;b", ";")[1])
"""
    m = derive(load_rules(src, assets=tmp_path), lot_size="4x4")[0]
    assert {k: v[0] for k, v in m.reports.items()} == {"n": 3.0, "sum": 12.0, "i": 1.0, "t": 12.5,
                                                       "s": "a", "sorted": 1.0, "str": "b"}
    assert not m.warnings


def test_image_ratio_sorting(tmp_path):
    from PIL import Image

    Image.new("RGB", (40, 10), (1, 2, 3)).save(tmp_path / "wide.png")
    Image.new("RGB", (10, 40), (1, 2, 3)).save(tmp_path / "tall.png")
    src = ('Lot --> extrude(8) comp(f) { front : '
           'report("best", listFirst(imagesSortRatio("tall.png;wide.png;", xy))) | all : NIL }')
    m = derive(load_rules(src, assets=tmp_path), lot_size="32x4")[0]
    assert m.reports == {"best": ["wide.png"]}  # a 32 x 8 facade is wide


def test_comp_function():
    src = """Lot --> extrude(4) report("side", sum(comp(f) { side : geometry.area() | top = 1 }))
        report("n", size(comp(e) { all : scope.sx })) report("top", comp(f) { top : "t" }[5])
        comp(f) { top : setback(comp(fe) { front : 2 | all : 0 }[0]) { all : S. | remainder : R. } }
"""
    m = derive_text(src, lot="10x8")[0]
    assert m.reports["side"] == [pytest.approx(2 * (10 + 8) * 4 + 1)]
    assert m.reports["n"] == [12.0] and m.reports["top"] == ["t"]


def test_offset_uv_is_the_2014_name_of_translate_uv():
    """Esri's own 2014 library rules (ESRI.lib Facade_Textures.cga) write offsetUV(0, u, v)."""
    uvs = []
    for op in ("offsetUV", "translateUV"):
        rules = load_rules(f"Lot --> setupProjection(0, scope.xz, 4, 4) projectUV(0) "
                           f"{op}(0, 0.25, -0.5) X.")
        (m,) = derive(rules, lot_size="8x4")
        assert not m.warnings
        uvs.append(m.parts[0].mesh.corner_uvs)
    assert np.array_equal(uvs[0], uvs[1]) and uvs[0][:, 0].min() == pytest.approx(0.25)
