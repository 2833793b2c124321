"""Instancing of 23b2c52: rules analysed for their argument values, slots in recordings by
chance, inserts that leave the replaced geometry out of the key; each must equal a plain
derivation and must actually save rule runs."""

import operator
from pathlib import Path

import numpy as np
import pytest
from test_instancing import _rule_runs, assert_same_parts, signature

from facadeforge import derive, load_rules
from facadeforge.grammar import ast as A
from facadeforge.grammar import instancing, interpreter
from facadeforge.grammar.instancing import UNKNOWN, Purity

ROOT = Path(__file__).resolve().parents[2]
CANDLER = ROOT.parent / "shared" / "data" / "cga"

# tiles of several windows, each window with its own random texture: a tile is one recording
# by chance whose windows are slots each replay fills from its own random streams
SLOTTED = """
Lot --> extrude(18) comp(f) { side : Facade | top : Roof. }
Facade --> setupProjection(0, scope.xy, 2, 2) projectUV(0)
           split(y) { ~3 : split(x) { ~4 : Tile }* }*
Tile --> split(x) { ~0.5 : Wall | ~3 : Windows | ~0.5 : Wall }
Windows --> split(x) { { ~1 : Window | 0.2 : Wall }* | ~1 : Window }
Window --> report("win", scope.sx) split(y) { ~1 : Wall | 1.5 : Asset | ~0.5 : Wall }
Asset --> s('1, '1, 0.1) i("builtin:cube") Tex(floor(rand(0, 3.99)))
Tex(n) --> tileUV(0, '4, '1) translateUV(0, -n / 4, 0) texture("win.jpg") Glass.
Wall --> color("#ccbb99") Wall.
"""

# a case on a parameter (and an attribute no rule sets): the ground branch edits the facade's
# inherited UVs, so Tile(n) as a whole cannot be instanced, Tile(1) can, Tile(0) not
SPECIALISED = """
attr GroundFloors = 1
Lot --> extrude(12) comp(f) { side : Facade | top : Roof. }
Facade --> setupProjection(0, scope.xy, 2, 2) projectUV(0)
           split(y) { 4 : split(x) { ~3 : Tile(0) }* | { ~3 : split(x) { ~3 : Tile(1) }* }* }
Tile(n) --> SubTile(n + 1)
SubTile(n) --> case n > GroundFloors : Windows(n) else : Ground(n)
Windows(n) --> split(x) { ~1 : Wall | 1.2 : split(y) { ~1 : Wall | 1.5 : Glass. | ~0.5 : Wall } | ~1 : Wall }
Ground(n) --> report("shop", n) tileUV(0, 1, 1) translateUV(0, 0.5, 0) Shop.
Wall --> color("#ccbb99") Wall.
"""

# an asset and a primitive inserted on split pieces whose geometry differs (every other tile
# has its normals reversed, its corners in the other order) while their scopes are alike
FRESH = """
Lot --> split(x) { ~2 : split(z) { ~2 : Tile | ~2 : reverseNormals Tile }* }*
Tile --> split(x) { ~1 : Wall. | 1.2 : split(z) { ~1 : Wall. | 1.5 : Win | ~0.5 : Sill } | ~1 : Wall. }
Win --> s('1, '1, 0.1) i("builtin:cube") report("win", 1) comp(f) { front : Glass. | all : Frame. }
Sill --> s('1, 0.1, 0.2) primitiveCube() Sill.
"""

# variants of one key that draw differently (a window, with a texture choice of its own, or a
# plain wall): replays find them one by one, not by the outcomes of one set of draws
MIXED = """
Lot --> split(x) { ~2 : split(z) { ~2 : Cell }* }*
Cell --> 40% : s('0.6, '1, '0.6) center(xz) Win(floor(rand(0, 2.99))) else : Plain
Win(n) --> report("win", n) i("builtin:cube") color(case n > 1 : "#ff0000" else : "#00ff00") Glass.
Plain --> report("plain", 1) color("#ccbb99") Plain.
"""


def _both(monkeypatch, text, lot):
    """Plain and instanced derivations of ``text``, checked equal face for face (positions and
    UVs), in reports, shapes and warnings; the rules each ran, plain and instanced."""
    rules = load_rules(text)
    runs = _rule_runs(monkeypatch)
    plain = derive(rules, lot_size=lot, keep_tree=True)
    plain_runs = list(runs)
    runs.clear()
    fast = derive(rules, lot_size=lot, keep_tree=False)
    assert_same_parts(signature(plain), signature(fast))
    assert len(plain) == len(fast)
    for a, b in zip(plain, fast):
        assert set(a.reports) == set(b.reports)
        for k in a.reports:
            assert np.allclose(sorted(a.reports[k]), sorted(b.reports[k]), atol=1e-6)
        assert a.attributes["shapes"] == b.attributes["shapes"]
        assert a.warnings == b.warnings
    return plain_runs, runs


@pytest.mark.parametrize("text,lot", [(SLOTTED, "40.3x20.1"), (SPECIALISED, "30.3x12.1"),
                                      (FRESH, "30.3x12.1"), (MIXED, "30.3x20.1")],
                         ids=["slots", "special", "fresh", "mixed"])
def test_instanced_equals_plain(monkeypatch, text, lot):
    plain_runs, fast_runs = _both(monkeypatch, text, lot)
    assert len(fast_runs) < len(plain_runs)


def test_tiles_of_randomly_textured_windows_are_one_recording_with_slots(monkeypatch):
    """180 tiles of 3 windows, 4 textures each: without slots every tile derives (its three
    choices have more outcomes together than recordings are kept); with them few do."""
    plain_runs, fast_runs = _both(monkeypatch, SLOTTED, "40.3x20.1")
    tiles = plain_runs.count("Tile")
    assert tiles == 180 and plain_runs.count("Asset") == 3 * tiles
    assert fast_runs.count("Tile") < 0.25 * tiles
    assert fast_runs.count("Window") < 0.15 * plain_runs.count("Window")
    assert fast_runs.count("Asset") < 0.1 * plain_runs.count("Asset")


def test_a_slot_with_a_new_outcome_is_derived_alone(monkeypatch):
    """Ten textures a window: a tile's windows often make a combination whose window variant
    no recording has yet.  The missing window is derived again from its key's first shape with
    the slot's seed (``Derivation._fill``) instead of the whole tile; without that, most tiles
    derive.  Both equal the plain derivation."""
    ten = SLOTTED.replace("rand(0, 3.99)", "rand(0, 9.99)")
    plain_runs, fast_runs = _both(monkeypatch, ten, "40.3x20.1")
    fast_runs = list(fast_runs)  # _both reuses its list
    tiles = plain_runs.count("Tile")
    assert tiles == 180
    assert fast_runs.count("Tile") < 0.1 * tiles
    assert fast_runs.count("Wall") < 0.1 * plain_runs.count("Wall")
    monkeypatch.setattr(interpreter.Derivation, "_fill", lambda self, key, seed: None)
    _, unfilled_runs = _both(monkeypatch, ten, "40.3x20.1")
    assert unfilled_runs.count("Tile") > 4 * fast_runs.count("Tile")


def test_tile_called_with_a_value_is_instanced(monkeypatch):
    """Tile(1) replays recordings although Tile(n) may edit inherited UVs; Tile(0), which
    does, derives every time."""
    plain_runs, fast_runs = _both(monkeypatch, SPECIALISED, "30.3x12.1")
    # _rule_runs keeps only the names: count by what each Tile's SubTile went on to
    assert plain_runs.count("Windows") == 84 and plain_runs.count("Ground") == 28
    # Tile(0) runs once per ground tile still to derive, Tile(1) only to record
    assert fast_runs.count("Tile") - fast_runs.count("Ground") < 0.15 * 84
    assert fast_runs.count("Windows") < 0.15 * 84


def _literal(m, expr, bound):
    """A Derivation-free ``constant`` for :meth:`Purity.specialised`: numbers, parameters
    and arithmetic or comparisons of them."""
    ops = {">": operator.gt, "<": operator.lt, ">=": operator.ge, "==": operator.eq,
           "+": operator.add, "-": operator.sub, "*": operator.mul}
    if isinstance(expr, A.Num):
        return expr.value
    if isinstance(expr, A.Name):
        return bound.get(expr.name, UNKNOWN)
    if isinstance(expr, A.Binary) and expr.op in ops:
        a, b = _literal(m, expr.left, bound), _literal(m, expr.right, bound)
        return UNKNOWN if a is UNKNOWN or b is UNKNOWN else ops[expr.op](a, b)
    return UNKNOWN


def test_specialised_analysis_decides_the_case_on_the_parameter():
    ruleset = load_rules(SPECIALISED.replace("n > GroundFloors", "n > 1")).ruleset
    main = ruleset.main
    purity = Purity(ruleset)
    general = purity.rule(main, "Tile")
    assert general.pure and general.uses_uv  # the ground branch edits inherited UVs
    mod, rdef = main.rule("Tile", 1)
    memo: dict = {}
    upper = purity.specialised(mod, rdef, [1.0], constant=_literal, memo=memo)
    ground = purity.specialised(mod, rdef, [0.0], constant=_literal, memo=memo)
    assert upper.pure and not upper.uses_uv  # SubTile(2) goes to Windows only
    assert ground.uses_uv
    # an unknown value decides nothing: the general analysis
    unknown = purity.specialised(mod, rdef, [1.0], constant=lambda m, e, b: UNKNOWN, memo={})
    assert unknown.uses_uv


def test_inserted_windows_on_differing_pieces_share_one_recording(monkeypatch):
    """Tiles alike but for their corners' order record twice; the window asset and the sill
    primitive inserted on them do not look at that geometry, and record once."""
    _, fast_runs = _both(monkeypatch, FRESH, "30.3x12.1")
    assert fast_runs.count("Tile") >= 2  # the tiles' geometries are told apart
    assert fast_runs.count("Win") == 1 and fast_runs.count("Sill") == 1


def test_fresh_is_an_insert_before_the_geometry_is_read():
    def fresh(body):
        ruleset = load_rules(f"Lot --> A\nA --> {body}\n").ruleset
        return Purity(ruleset).rule(ruleset.main, "A").fresh

    assert fresh('s(1, 1, 1) i("builtin:cube") X.') is True
    assert fresh("t(0, 1, 0) primitiveCube() X.") is True
    assert fresh('extrude(1) i("builtin:cube")') is False  # extrude reads the geometry
    assert fresh("s(geometry.area, 1, 1) primitiveCube() X.") is False
    assert fresh("X.") is False


def test_negative_zero_keys_as_zero():
    assert instancing.rounded(np.array([-0.0]), 6) == instancing.rounded(np.array([0.0]), 6)
    assert instancing.rounded(np.array([-1e-9, 2.0]), 6) == np.array([0.0, 2.0]).tobytes()


@pytest.mark.skipif(not (CANDLER / "candler.rpk").exists(),
                    reason="../shared/data/cga/candler.rpk (Esri's Candler package) is absent")
def test_candler_package_instanced_runs_few_rules(monkeypatch):
    """6108 rule runs before 23b2c52, about 3700 after, 1178 with slots filled alone
    (equality: test_instancing.py)."""
    rules = load_rules(CANDLER / "candler.rpk")
    runs = _rule_runs(monkeypatch)
    derive(rules, CANDLER / "candler_footprint.obj", keep_tree=False, workers=1)
    assert 0 < len(runs) < 1500
