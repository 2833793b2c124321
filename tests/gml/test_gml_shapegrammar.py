"""ShapeGrammar.Tools: Fig. 13 of Hohmann et al. 2009 and the split, repeat, subdivide words."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from facadeforge.exchange import export
from facadeforge.gml import EXAMPLES, GmlRuntimeError, derive_gml, load_gml
from facadeforge.model.model import Model
from facadeforge.model.scope import Scope


def sizes(model: Model) -> Counter:
    out = Counter()
    for p in model.parts:
        lo, hi = p.mesh.bounds()
        out[tuple(round(float(v), 6) for v in hi - lo)] += 1
    return out


def test_fig13_twenty_terminal_boxes_of_the_right_sizes():
    m = derive_gml(EXAMPLES / "fig13.gml")
    assert len(m.parts) == 20 and not m.warnings
    # 2 × 1 × 1 box at (0,0,-2), every split [0.1 -1 0.1]: the edges and corners of a frame
    assert sizes(m) == {(0.1, 0.1, 0.1): 8, (0.1, 0.1, 0.8): 4, (0.1, 0.8, 0.1): 4,
                        (1.8, 0.1, 0.1): 4}
    assert all(p.symbol == "A" and p.mesh.n_faces == 6 and p.mesh.is_closed() for p in m.parts)
    assert np.allclose(m.stats()["bbox"], [[0, 0, -2], [2, 1, -1]])
    root = m.root
    assert root.symbol == "C" and [c.symbol for c in root.children] == ["E", "D", "E"]
    assert [c.symbol for c in root.children[1].children] == ["F", "B", "F"]
    voids = [s for s in root.walk() if s.tags.get("terminal") == "void"]
    assert len(voids) == 5 and all(s.symbol == "B" for s in voids)
    assert {s.symbol for s in root.leaves()} == {"A", "B"}


def test_fig13_as_extracted_with_em_dashes_loads():
    text = (EXAMPLES / "fig13.gml").read_text().replace("terminal-", "terminal\u2014")
    assert len(derive_gml(text).parts) == 20


@pytest.mark.parametrize("suffix", [".glb", ".obj", ".city.json"])
def test_export_unchanged(tmp_path, suffix):
    m = derive_gml(EXAMPLES / "fig13.gml")
    paths = export(m, tmp_path / f"fig13{suffix}")
    assert paths and all(p.stat().st_size > 0 for p in paths)


def run_parts(text: str, **kw) -> Model:
    return derive_gml("ShapeGrammar.Tools.init\n" + text + "\nfinish", **kw)


def widths(m: Model, axis: int = 0) -> list[float]:
    out = []
    for p in sorted(m.parts, key=lambda p: tuple(p.mesh.bounds()[0])):
        lo, hi = p.mesh.bounds()
        out.append(round(float(hi[axis] - lo[axis]), 6))
    return out


def test_split_absolute_relative_and_order():
    m = run_parts("scope (10,1,1) scale [ 2 -1 -3 1 ] /X split "
                  "/first label terminal-box terminal-box terminal-box terminal-box")
    assert widths(m) == [2.0, 1.75, 5.25, 1.0]
    first = [p for p in m.parts if p.label == "first"]
    assert len(first) == 1 and np.isclose(first[0].mesh.bounds()[0][0], 0.0)  # first on top


def test_split_cuts_what_does_not_fit():
    m = run_parts("scope (3,1,1) scale [ 2 2 2 ] /X split terminal-box terminal-box terminal-box")
    assert widths(m) == [2.0, 1.0]  # the third part has length 0: no geometry
    assert any(s.tags.get("empty") for s in m.root.walk())


def test_split_r_rescales():
    m = run_parts("scope (1,18,1) scale [ 2.85 0.15 3.0 3.0 ] /Y split-r terminal-box pop pop pop")
    lo, hi = m.parts[0].mesh.bounds()
    assert np.isclose(hi[1] - lo[1], 2.85 * 2)  # y is up; split-r fills the scope exactly


def test_repeat_then_loop_repeat():
    m = run_parts("scope (6,3,1) scale 4 /X repeat { terminal-box } repeat")
    assert widths(m) == [1.5] * 4


def test_subdivide_smin_and_weights():
    m = run_parts("scope (10,1,1) scale 3 /X subdivide { terminal-box } repeat")
    assert widths(m) == [round(10 / 3, 6)] * 3
    m = run_parts("scope (6,1,1) scale [ 1 2 2 1 ] /X subdivide { terminal-box } repeat")
    assert widths(m) == [1.0, 2.0, 2.0, 1.0]


def test_labels_colours_and_names():
    m = run_parts("/Window { /window label (0,0,1) color terminal-box } def "
                  "/Wall { terminal-box } def "
                  "scope (2,3,0) scale [ -1 -1 ] /X split Window Wall")
    by = {p.symbol: p for p in m.parts}
    assert by["Window"].label == "window" and by["Window"].material.color == (0.0, 0.0, 1.0)
    assert by["Wall"].label == "wall"  # guessed from the rule name, as CGA does
    assert by["Wall"].mesh.n_faces == 1  # a zero-depth scope is a rectangle


def test_initial_scope_is_on_the_stack():
    lot = Scope(np.array([5.0, 0, 0]), np.eye(3), np.array([4.0, 3.0, 0.0]))
    m = derive_gml("ShapeGrammar.Tools.init [ -1 -1 ] /X split terminal-box terminal-box finish",
                   scope=lot)
    assert m.root.symbol == "Lot" and len(m.parts) == 2
    assert np.allclose(m.stats()["bbox"], [[5, 0, 0], [9, 3, 0]])


def test_move_after_split_makes_a_child_and_scale_multiplies():
    m = run_parts("scope dup [ -1 ] /X split pop (1,0,0) move (2,2,2) scale terminal-box")
    assert np.allclose(m.stats()["bbox"], [[1, 0, 0], [3, 2, 2]])


def test_left_over_scopes_warn():
    m = run_parts("scope [ -1 -1 ] /X split terminal-box")
    assert any("left on the stack" in w for w in m.warnings)


@pytest.mark.parametrize("text, message", [
    ("1 [ 1 ] /X split", "expects a scope"),
    ("scope [ 1 ] /W split", "/X, /Y or /Z"),
    ("scope [ 1 /a ] /X split", "must be numbers"),
    ("scope (1,-1,1) scale", "≥ 0"),
    ("scope 0 /X subdivide", "> 0"),
    ("(0,0,0) (1,1,1) (2,2,2) cp-plane", "collinear"),
])
def test_grammar_errors(text, message):
    with pytest.raises(GmlRuntimeError, match=message):
        run_parts(text)


def test_load_gml_from_path_and_text(tmp_path):
    p = tmp_path / "x.gml"
    p.write_text("scope terminal-box")
    assert load_gml(p).path == str(p) and load_gml(str(p)).path == str(p)
    assert load_gml("scope terminal-box").path == "<gml>"
    with pytest.raises(Exception, match="does not exist"):
        load_gml(tmp_path / "missing.gml")


def test_engine_initial_shapes_as_scopes():
    from facadeforge.engine import facade_state, initial_state
    from facadeforge.geometry.footprints import lot

    # a lot (scope y up, size y 0): split it along x and z, extrude nothing
    m = derive_gml("[ -1 -1 ] /X split terminal-box terminal-box",
                   scope=initial_state(lot("20x12")[0]).scope)
    assert len(m.parts) == 2 and np.isclose(sum(p.mesh.area() for p in m.parts), 240.0)
    # a facade rectangle (x right, y up): floors along Y
    m = derive_gml("3 /Y repeat { terminal-box } repeat", scope=facade_state(10, 9).scope)
    assert sorted(round(float(p.mesh.bounds()[0][1]), 6) for p in m.parts) == [0.0, 3.0, 6.0]
