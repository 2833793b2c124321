"""Behaviours real CityEngine rule files rely on (found by running public .cga files): the shape
goes on after a split or component split, bare zero-argument operations, primitive arguments as
the CGA reference documents them."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge import RuleError, derive, load_rules
from facadeforge.geometry.footprints import Footprint


def _parts(rules: str, lot: str = "10x10"):
    (m,) = derive(rules + "\n", lot_size=lot)
    return m


def _bbox(m):
    v = np.concatenate([p.mesh.vertices for p in m.parts])
    return np.round(v.min(axis=0), 3).tolist(), np.round(v.max(axis=0), 3).tolist()


def test_operations_after_a_component_split_work_on_the_shape():
    m = _parts("Lot --> extrude(9) comp(f){ top : Roof } color(1, 0, 0) Mass")
    assert not m.warnings
    by = {p.symbol: p for p in m.parts}
    assert by["Roof"].mesh.n_faces == 1
    assert by["Mass"].mesh.n_faces == 6 and by["Mass"].material.color == (1.0, 0.0, 0.0)
    # after a split too; the split's own pieces are unchanged
    m = _parts("Lot --> split(x){ 4 : A | ~1 : B } Whole")
    assert sorted(p.symbol for p in m.parts) == ["A", "B", "Whole"]
    whole = next(p for p in m.parts if p.symbol == "Whole")
    assert np.ptp(whole.mesh.vertices[:, 0]) == pytest.approx(10.0)
    # a split alone leaves no copy of the shape behind
    assert sorted(p.symbol for p in _parts("Lot --> split(x){ 4 : A | ~1 : B }").parts) == [
        "A", "B"]


def test_zero_argument_operations_without_parentheses():
    m = _parts("Lot --> s(2, 0, 2) primitiveQuad extrude(1)")
    assert sum(p.mesh.n_faces for p in m.parts) == 6          # a box, not an undefined rule
    # a rule of the same name wins, as a rule call
    m = _parts("Lot --> primitiveQuad\nprimitiveQuad --> color(0, 0, 1) X")
    assert [p.symbol for p in m.parts] == ["X"]


@pytest.mark.parametrize("rule, lo, hi, faces", [
    # sides, radius, height: centred in the scope's xz, standing on y = 0
    ("primitiveCylinder(24, 0.3, 3.5)", [4.7, 0, 4.7], [5.3, 3.5, 5.3], 26),
    ("primitiveCone(8, 1, 2)", [4.0, 0, 4.0], [6.0, 2.0, 6.0], 9),
    ("primitiveDisk(8, 1)", [4.0, 0, 4.0], [6.0, 0, 6.0], 1),
    ("primitiveCube(2, 3, 4)", [4.0, 0, 3.0], [6.0, 3.0, 7.0], 6),
    ("primitiveQuad(4, 2)", [3.0, 0, 4.0], [7.0, 0, 6.0], 1),
    # without arguments: fitted to the scope; a lot's quad lies in the lot
    ("primitiveQuad()", [0, 0, 0], [10, 0, 10], 1),
])
def test_primitive_arguments(rule, lo, hi, faces):
    m = _parts(f"Lot --> {rule}")
    assert not m.warnings
    got_lo, got_hi = _bbox(m)
    assert got_lo == pytest.approx(lo, abs=1e-3) and got_hi == pytest.approx(hi, abs=1e-3)
    assert sum(p.mesh.n_faces for p in m.parts) == faces


def test_quad_has_texture_coordinates_for_uv_splits():
    m = _parts("Lot --> extrude(5) comp(f){ front : F }\n"
               "F --> primitiveQuad() split(u, unitSpace, 0){ ~1 : A | ~1 : B }")
    assert not m.warnings
    assert sorted(p.symbol for p in m.parts) == ["A", "B"]
    widths = sorted(float(np.ptp(p.mesh.vertices[:, 0])) for p in m.parts)
    assert widths == pytest.approx([5.0, 5.0])


def test_primitive_with_wrong_argument_count_is_a_warning():
    m = _parts("Lot --> primitiveCylinder(8, 1)")
    assert any("primitiveCylinder" in w for w in m.warnings)


def test_split_group_without_repeat_is_inlined_once():
    m = _parts("Lot --> split(x){ { 1 : A } | { ~3 : B }* }")
    widths = sorted((p.symbol, round(float(np.ptp(p.mesh.vertices[:, 0])), 3)) for p in m.parts)
    assert widths == [("A", 1.0), ("B", 3.0), ("B", 3.0), ("B", 3.0)]
    m = _parts("Lot --> split(x){ { 1 : A | 2 : C } | ~1 : B }")
    assert sorted((p.symbol, round(float(np.ptp(p.mesh.vertices[:, 0])), 3))
                  for p in m.parts) == [("A", 1.0), ("B", 7.0), ("C", 2.0)]


def test_setback_pieces_keep_the_lot_scope():
    """Esri's International City splits setback pieces along z, reads their scope.sz and turns
    the remainder about y: the pieces keep the lot's scope (y up), fitted to them."""
    m = _parts("Lot --> setback(30){ front : Row | remainder : rotateScope(0, 180, 0) Row }\n"
               "Row --> print(scope.sz) split(z){ '0.5 : A | ~1 : B }", lot="90x70")
    assert not m.warnings and m.attributes["prints"] == ["30", "40"]
    depths = sorted(round(float(np.ptp(p.mesh.vertices[:, 2])), 3) for p in m.parts)
    assert depths == [15.0, 15.0, 20.0, 20.0]
    # the turned remainder splits from its far side: its A half lies next to the front band
    (a,) = [p for p in m.parts if p.symbol == "A" and p.mesh.vertices[:, 2].max() < 45]
    assert a.mesh.vertices[:, 2].min() == pytest.approx(20.0)


def test_setback_with_one_width_per_edge():
    """``setback(comp(fe){…})``: the front band 4 m deep, the others 1 m (on a 20 × 10 lot)."""
    m = _parts("Lot --> setback(comp(fe){ front : 4 | all : 1 }){ all : A | remainder : B }",
               lot="20x10")
    assert not m.warnings
    rest = next(p for p in m.parts if p.symbol == "B")
    lo, hi = rest.mesh.vertices.min(axis=0), rest.mesh.vertices.max(axis=0)
    assert (hi - lo)[[0, 2]] == pytest.approx([18.0, 5.0])
    # street selectors fall back to the shape's own directions, in the comp function too
    m = _parts("Lot --> setback(comp(fe){ street.front : 4 | all : 0 }){ street.front : A "
               "| remainder : B }", lot="20x10")
    assert not m.warnings
    band = next(p for p in m.parts if p.symbol == "A")
    assert np.ptp(band.mesh.vertices[:, 2]) == pytest.approx(4.0)
    # reference: a short array sets back only the face edges it reaches; extra values are
    # ignored (FHNW's rules pass a fixed-length array to lots of any shape)
    def area(src, symbol):
        m = _parts(src, lot="20x10")
        assert not m.warnings
        return sum(p.mesh.area() for p in m.parts if p.symbol == symbol)

    rest = area("Lot --> setback([1, 2]){ all : A | remainder : B }", "B")
    assert rest == pytest.approx(19 * 8) or rest == pytest.approx(18 * 9)
    assert area("Lot --> setback([1, 2]){ all : A | remainder : B }", "A") == pytest.approx(200 - rest)
    four = area("Lot --> setback([1, 2, 1, 2]){ all : A | remainder : B }", "B")
    assert four == pytest.approx(16 * 8) or four == pytest.approx(18 * 6)
    assert area("Lot --> setback([1, 2, 1, 2, 5, 5]){ all : A | remainder : B }", "B") == \
        pytest.approx(four)


def test_setback_operator_puts_each_polygon_in_a_shape_or_combines_them():
    """Reference (setback's operator): ``:`` puts each polygon into a new shape, ``=`` combines
    all polygons of the selector into one.  Bands along the two short sides of a 20 × 10 lot are
    two polygons."""
    widths = "comp(fe){ left : 2 | right : 2 | all : 0 }"  # the short sides only
    both = _parts(f"Lot --> setback({widths}){{ all : A | remainder : B }}", lot="20x10")
    sides = [p for p in both.parts if p.symbol == "A"]
    assert len(sides) == 2 and sum(p.mesh.area() for p in sides) == pytest.approx(40.0)
    one = _parts(f"Lot --> setback({widths}){{ all = A | remainder : B }}", lot="20x10")
    (combined,) = [p for p in one.parts if p.symbol == "A"]
    assert combined.mesh.n_faces == 2 and combined.mesh.area() == pytest.approx(40.0)


def test_setback_works_on_every_face_of_a_shape():
    """A shape of four wall faces (``comp(f){ side = … }``): each face gets its band, and a
    width array runs in face-edge order over all of them (reference: "the first element is the
    distance of the first edge of the first face…")."""
    rules = ("Lot --> extrude(10) comp(f){ side = Walls }\n"
             "Walls --> setback(1){ top {op} Cornice | remainder = Wall }")
    m = _parts(rules.replace("{op}", ":"), lot="20x10")
    assert not m.warnings
    cornices = [p for p in m.parts if p.symbol == "Cornice"]
    assert len(cornices) == 4
    assert sum(p.mesh.area() for p in cornices) == pytest.approx(60.0)  # perimeter 60 × 1 m
    (wall,) = [p for p in m.parts if p.symbol == "Wall"]
    assert wall.mesh.area() == pytest.approx(60.0 * 9)
    assert np.ptp(wall.mesh.vertices[:, 1]) == pytest.approx(9.0)
    m = _parts(rules.replace("{op}", "="), lot="20x10")
    assert [p.symbol for p in m.parts].count("Cornice") == 1
    # widths for the first face's four edges only: the other faces are not set back
    m = _parts("Lot --> extrude(10) comp(f){ side = Walls }\n"
               "Walls --> setback([1, 1, 1, 1]){ top : Cornice | remainder = Wall }", lot="20x10")
    assert len([p for p in m.parts if p.symbol == "Cornice"]) == 1


@pytest.mark.parametrize("edge, sx, sy", [("world.lowest", 10.0, 20.0), ("longest", 20.0, 10.0),
                                          ("world.highest", 10.0, 20.0)])
def test_align_scope_to_geometry_edge_selectors(edge, sx, sy):
    """A 10 m wide, 20 m tall facade: x along its bottom (or top) edge, or its longest (a side)."""
    (m,) = derive("Lot --> extrude(20) comp(f){ front : F }\n"
                  f"F --> alignScopeToGeometry(zUp, any, {edge}) print(scope.sx) "
                  "print(scope.sy) X\n", lot_size="10x10")
    assert [float(v) for v in m.attributes["prints"]] == pytest.approx([sx, sy])


@pytest.mark.parametrize("rule, lo, hi", [
    ("primitiveQuad(2, 3)", [4.0, 3.5, 10.0], [6.0, 6.5, 10.0]),
    ("primitiveDisk(8, 1)", [4.0, 4.0, 10.0], [6.0, 6.0, 10.0]),
    ("primitiveQuad()", [0.0, 0.0, 10.0], [10.0, 10.0, 10.0]),
])
def test_flat_primitives_lie_in_a_facade(rule, lo, hi):
    """On a facade (scope sz = 0) a quad or disk lies in the facade, centred in it, and faces
    out as the facade does."""
    m = _parts(f"Lot --> extrude(10) comp(f){{ front : F }}\nF --> {rule}")
    got_lo, got_hi = _bbox(m)
    assert got_lo == pytest.approx(lo, abs=1e-3) and got_hi == pytest.approx(hi, abs=1e-3)
    facade = _parts("Lot --> extrude(10) comp(f){ front : F }").parts[0].mesh.face_normals()[0]
    normals = np.concatenate([p.mesh.face_normals() for p in m.parts])
    assert normals @ facade == pytest.approx(np.ones(len(normals)), abs=1e-6)


@pytest.mark.parametrize("rule", ["primitiveQuad()", "primitiveDisk(8, 1)"])
def test_flat_primitives_on_a_lot_face_up(rule):
    m = _parts(f"Lot --> {rule}")
    normals = np.concatenate([p.mesh.face_normals() for p in m.parts])
    assert normals[:, 1] == pytest.approx(np.ones(len(normals)), abs=1e-6)


def test_bare_names_of_other_operations_stay_leaves():
    m = _parts("Lot --> extrude(5) comp(f){ side : Wall | top : trim }")
    assert "trim" in {p.symbol for p in m.parts} and not m.warnings


def test_occlusion_after_a_component_split_ignores_the_shape_itself():
    m = _parts("Lot --> extrude(10) comp(f){ top : Roof } Mass\n"
               "Mass --> s('0.5, '0.5, '0.5) center(xyz) Inner\n"
               "Inner --> case inside() : In else : Out")
    assert "Out" in {p.symbol for p in m.parts}


def test_setback_per_edge_evaluates_the_distance_on_each_edge():
    """setbackPerEdge(d) is setback(comp(fe){ all : d }): ``scope.sx`` is each edge's length,
    so on a 20 × 10 lot the long edges get 2 m and the short ones 1 m."""
    m = _parts("Lot --> setbackPerEdge(scope.sx / 10){ all = A | remainder : B }", lot="20x10")
    assert not m.warnings
    rest = next(p for p in m.parts if p.symbol == "B")
    assert np.ptp(rest.mesh.vertices, axis=0)[[0, 2]] == pytest.approx([18.0, 6.0])
    m = _parts("const dists = [4, 1, 1, 1]\ndist = dists[comp.index]\n"
               "Lot --> setbackPerEdge(dist){ all = A | remainder : B }", lot="20x10")
    rest = next(p for p in m.parts if p.symbol == "B")
    assert sorted(np.ptp(rest.mesh.vertices, axis=0)[[0, 2]]) == pytest.approx([5.0, 18.0])


@pytest.mark.parametrize("rule, symbol, area", [
    # the documented examples: a 400 m² square set back to a 100 m² remainder, and to 300 m²
    # of setback bands; only the front and left edges move (still a 100 m² remainder)
    ("setbackToArea(100){ all = NIL | remainder = X }", "X", 100.0),
    ("setbackToArea(geometry.area - 300){ all = G }", "G", 300.0),
    ("setbackToArea(100){ front = B | left = C | remainder = X }", "X", 100.0),
    # minimum distances raised by a common offset: the front keeps 4 m more than the others
    ("setbackToArea(100, [4, 0, 0, 0]){ all = G | remainder = X }", "X", 100.0),
])
def test_setback_to_area(rule, symbol, area):
    m = _parts(f"Lot --> {rule}", lot="20x20")
    assert not m.warnings
    got = sum(float(p.mesh.face_areas().sum()) for p in m.parts if p.symbol == symbol)
    assert got == pytest.approx(area, rel=1e-3)


def _remainder_margins(rule: str) -> list[float]:
    """Distances from the 20 × 20 lot's four sides to the remainder X, sorted."""
    m = _parts(f"Lot --> {rule}", lot="20x20")
    lot = np.concatenate([p.mesh.vertices for p in m.parts])
    rest = np.concatenate([p.mesh.vertices for p in m.parts if p.symbol == "X"])
    lo, hi = lot.min(axis=0)[[0, 2]], lot.max(axis=0)[[0, 2]]
    return sorted(np.concatenate([rest.min(axis=0)[[0, 2]] - lo, hi - rest.max(axis=0)[[0, 2]]]))


def test_setback_to_area_moves_the_selected_edges_only():
    """Only the front and left edges move (10 m each, for a 10 × 10 remainder); with minimum
    distances [4, 0, 0, 0] the front keeps 4 m more than the other three edges."""
    margins = _remainder_margins("setbackToArea(100){ front = B | left = C | remainder = X }")
    assert margins == pytest.approx([0.0, 0.0, 10.0, 10.0], abs=1e-3)
    margins = _remainder_margins("setbackToArea(100, [4, 0, 0, 0]){ all = G | remainder = X }")
    d = margins[0]
    assert margins == pytest.approx([d, d, d, d + 4], abs=1e-3)
    assert (20 - 2 * d) * (20 - 2 * d - 4) == pytest.approx(100, rel=1e-3)
    # one number is the minimum of every edge: 6 m each already leaves less than 100 m²
    margins = _remainder_margins("setbackToArea(100, 6){ all = G | remainder = X }")
    assert margins == pytest.approx([6.0] * 4, abs=1e-3)


def test_setback_shortcuts_without_a_body_are_named():
    for op in ("setbackPerEdge(3)", "setbackToArea(100)"):
        with pytest.raises(RuleError, match=r"needs a \{ … \} body"):
            load_rules(f"Lot --> {op} X\n")


def test_setback_to_area_out_of_reach_keeps_the_closest():
    m = _parts("Lot --> setbackToArea(1000){ all = G | remainder = X }", lot="20x20")
    assert sum(float(p.mesh.face_areas().sum()) for p in m.parts if p.symbol == "X") == \
        pytest.approx(400.0)


def test_cuts_through_a_vertex_leave_no_repeated_corner():
    """A split of a concave lot through its corners (done in the plane by an overlay) gives
    pieces without zero-length edges; edge keywords of alignScopeToGeometry skip such edges
    anyway (Esri's Facade_Textures aligns every facade with world.lowest)."""
    c, s = np.cos(np.radians(27)), np.sin(np.radians(27))
    concave = [(0, 0), (60, 0), (60, 45), (35, 45), (35, 20), (20, 20), (20, 45), (0, 45)]
    block = np.array([[x * c - y * s, 0, -(x * s + y * c)] for x, y in concave])
    m = derive(load_rules("Lot --> split(x){ ~7 : A. }*"), [Footprint("b", block)])[0]
    assert len(m.parts) == 9
    for p in m.parts:
        for f in range(p.mesh.n_faces):
            poly = p.mesh.vertices[p.mesh.face(f)]
            assert np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1).min() > 1e-6
    # a wall standing on a corner that is there twice: the lowest real edge is chosen
    wall = np.array([[0, 0, 0], [0, 0, 0], [4, 6, 0], [-4, 6, 0]], float)
    m = derive(load_rules("Lot --> alignScopeToGeometry(zUp, 0, world.lowest) X."),
               [Footprint("w", wall)])[0]
    assert not m.warnings


def test_functions_may_recurse_a_thousand_calls_deep():
    """Rules walk lists by recursion (Esri's Plant_Distributor sums a 127-plant list so): a
    chain of 990 calls derives, a runaway one stops with a warning at 1,000 calls."""
    src = "f(n) = case n <= 0 : 0 else : 1 + f(n - 1)\nLot --> print(f({n})) X."
    m = derive(load_rules(src.format(n=990)), None, lot_size="4x4")[0]
    assert m.attributes["prints"] == ["990"] and not m.warnings
    m = derive(load_rules(src.format(n=10**6)), None, lot_size="4x4")[0]
    assert m.warnings == ["<rules>:2:9: function 'f' recurses deeper than 1000 calls (in rule Lot)"]


def test_esri_international_city_idioms(tmp_path):
    """Three things Esri's International City relies on: ``rand`` without parentheses, a
    scatter whose count comes out 0 (nothing, no warning), and transposed ratio axes."""
    m = derive(load_rules("Lot --> split(x){ ~(rand) : A. | ~(rand) : B. }"), None,
               lot_size="10x8")[0]
    widths = sorted(float(np.ptp(p.mesh.vertices[:, 0])) for p in m.parts)
    assert not m.warnings and len(widths) == 2 and sum(widths) == pytest.approx(10)
    assert widths[0] != pytest.approx(5)  # two different draws, not 1 and 1
    m = derive(load_rules("Lot --> scatter(surface, floor(geometry.area / 400), uniform){ T. }"),
               None, lot_size="10x8")[0]
    assert not m.warnings and not m.parts
    from PIL import Image

    (tmp_path / "t").mkdir()
    Image.new("RGB", (100, 50)).save(tmp_path / "t" / "wide.png")
    Image.new("RGB", (50, 100)).save(tmp_path / "t" / "tall.png")
    rules = tmp_path / "r.cga"
    rules.write_text('Lot --> extrude(6) comp(f){ front : F }\n'
                     'F --> print(imageBestRatio("t/*.png", "xy")) '
                     'print(imageBestRatio("t/*.png", "yx")) X.\n')
    m = derive(load_rules(rules), None, lot_size="10x8")[0]  # the wall: 10 wide, 6 high
    assert not m.warnings and m.attributes["prints"] == ["t/wide.png", "t/tall.png"]
