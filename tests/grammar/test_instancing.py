"""Instancing replays repeated pure subtrees: the result must equal a plain derivation."""

from pathlib import Path

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.grammar.instancing import Purity

ROOT = Path(__file__).resolve().parents[2]

TEXTURED = """
Lot --> extrude(13) comp(f) { side : Facade | top : Roof | bottom : NIL }
Facade --> setupProjection(0, scope.xy, 3, 2) projectUV(0)
           split(y) { 4 : Ground | { ~3 : Floor }* }
Ground --> split(x) { ~1 : Wall | { ~3 : split(x) { ~1 : Wall | 1.5 : Shop | ~1 : Wall } }* }
Floor --> split(x) { ~0.5 : Wall | { ~2.5 : Tile }* | ~0.5 : Wall }
Tile --> split(x) { ~1 : Wall | 1.2 : split(y) { ~1 : Wall | 1.6 : Window | ~0.5 : Wall } | ~1 : Wall }
Window --> report("w", split.index) offset(-0.1) comp(f) { inside : t(0, 0, -0.1) Glass | border : extrude(0.05) Frame }
Shop --> report("shop", scope.sx) extrude(-0.2) comp(f) { back : Glass | all : Frame }
Roof --> roofHip(30) comp(f) { bottom : NIL | all : Tiles }
Wall --> color("#ccbb99") translateUV(0, 0.25, 0) WallUV
"""


def signature(models):
    """Faces (not parts: instancing merges alike parts) grouped by rule, label and material,
    with their exact corner positions and UVs."""
    groups = {}
    for m in models:
        for p in m.parts:
            mesh = p.mesh
            uvs = mesh.corner_uvs
            for f in range(mesh.n_faces):
                c0, c1 = mesh.starts[f], mesh.starts[f + 1]
                v = mesh.vertices[mesh.corners[c0:c1]]
                uv = uvs[c0:c1] if uvs is not None else np.zeros((len(v), 2))
                groups.setdefault((p.symbol, p.label, p.material.key(), len(v)), []).append((v, uv))
    return groups


def assert_same_parts(a, b):
    """Every face of ``a`` has its own face in ``b`` with the same corners (1e-6 m) and UVs;
    faces are paired by their centroids with a tree, so no rounding grid can split a pair."""
    from scipy.spatial import cKDTree

    assert sorted(a) == sorted(b) and all(len(a[k]) == len(b[k]) for k in a)
    for key, faces_a in a.items():
        faces_b = b[key]
        tree = cKDTree(np.array([v.mean(axis=0) for v, _ in faces_b]))
        used = set()
        for v, uv in faces_a:
            hits = [j for j in tree.query_ball_point(v.mean(axis=0), r=1e-6) if j not in used]
            match = next((j for j in hits if np.allclose(faces_b[j][0], v, atol=1e-6)
                          and np.allclose(faces_b[j][1], uv, atol=1e-6)), None)
            assert match is not None, f"{key[0]}: no matching face for {np.round(v, 4).tolist()}"
            used.add(match)


@pytest.mark.parametrize("grammar,lot,assets", [
    (TEXTURED, "23.7x11.3", None),
    (ROOT / "src" / "facadeforge" / "data" / "building.cga", "24x14", None),
    (ROOT / "benchmarks" / "grammars" / "detailed.cga", "30x16", ROOT / "examples" / "assets"),
    (ROOT / "examples" / "grammars" / "courtyard.cga", "42x30", None),   # geometry tags
    # stochastic choices: tiles replayed by the outcome of their windows' choice
    (ROOT / "benchmarks" / "grammars" / "detailed_varied.cga", "30x16", ROOT / "examples" / "assets"),
    (TEXTURED.replace("Window --> report", "Window --> 30% : X. 25% : Y. else : report")
     .replace("Tile --> split(x)", "Tile --> 40% : color(\"#ff0000\") TileBody else : TileBody\n"
              "TileBody --> split(x)"),
     "23.7x11.3", None),
    # p(), listRandom and stochastic expressions are choices too
    ("Lot --> extrude(9) comp(f){ side : F }\n"
     "F --> split(y){ ~3 : split(x){ ~2 : T }* }*\n"
     "T --> case p(0.3) : split(x){ ~1 : A. | 0.5 : B. | ~1 : A. }\n"
     "      else : s('1, 50% : '0.5 else : '0.8, '1) color(listRandom(\"#ff0000;#00ff00;#0000ff\")) C.",
     "24x12", None),
    # tiles alike but for a tag: each must see its own tags, not a replay of the other's
    ("Lot --> extrude(6) comp(f){ side : F }\n"
     "F --> split(x){ ~3 : tag(\"odd\") T | ~3 : T }*\n"
     "T --> split(y){ ~3 : comp(f){ isTagged(\"odd\") : A. | all : B. } }*", "24x12", None),
    # tiles alike but for their edges' tags: an end tile keeps the facade's tagged side edge
    ("Lot --> extrude(6) comp(f){ side : F }\n"
     "F --> tag(\"rim\", edges) split(x){ ~3 : T }*\n"
     "T --> extrude(0.2) comp(f){ isTagged(\"rim\") : A. | all : B. }", "24x12", None),
    # tiles alike but for their heading: selectors of the world's and the lot's frame must
    # keep the facades apart (scope-frame words may share one recording across facades)
    ("Lot --> extrude(6) comp(f){ side : F }\n"
     "F --> split(x){ ~3 : T }*\n"
     "T --> extrude(0.5) comp(f){ world.south : S. | object.left : L. | front : F. | all : A. }",
     "24x12", None),
    ("Lot --> extrude(6) comp(f){ side : F }\n"
     "F --> split(x){ ~3 : T }*\n"
     "T --> alignScopeToAxes(y) extrude(0.5) comp(f){ left : L. | all : A. }", "24x12", None),
])
def test_instanced_derivation_equals_plain(grammar, lot, assets):
    rules = load_rules(grammar, assets=assets)
    plain = derive(rules, lot_size=lot, keep_tree=True)
    fast = derive(rules, lot_size=lot, keep_tree=False)
    assert_same_parts(signature(plain), signature(fast))
    for a, b in zip(plain, fast):
        assert set(a.reports) == set(b.reports)
        for k in a.reports:  # shapes equal to 1e-6 share one instance: values agree to that
            assert np.allclose(sorted(a.reports[k]), sorted(b.reports[k]), atol=1e-6)
        assert a.attributes["shapes"] == b.attributes["shapes"]
        assert a.warnings == b.warnings


def test_purity_analysis():
    src = """attr h = 3
f(x) = x * 2
g = rand(0, 1)
Lot --> A B C D E
A --> split(x) { ~f(1) : A2 }*
A2 --> report("i", split.index)
B --> t(0, scope.ty, 0) X
C --> report("r", g)
D --> 50% : X else : Y
E --> report("in", inside())
"""
    r = load_rules(src).ruleset
    p = Purity(r)
    info = {name: p.rule(r.main, name) for name in ("A", "A2", "B", "C", "D", "E", "Lot")}
    assert info["A"].pure and info["A2"].pure and info["A"].reads == {"split.index"}
    assert not info["B"].pure and not info["C"].pure and not info["D"].pure
    assert not info["E"].pure and p.uses_occlusion
    assert not info["Lot"].pure


def test_a_bare_rand_is_impure_but_a_parameter_named_like_a_function_is_not():
    """``~(rand)`` calls ``rand``; a parameter ``p`` (or ``convert``) is a value, not a call of
    the one-argument built-in of that name, and keeps its rule instanceable."""
    src = """Lot --> T(1) R
T(p) --> s(p, 1, 1) X.
R --> split(x){ ~(rand) : X. }
"""
    r = load_rules(src).ruleset
    p = Purity(r)
    assert p.rule(r.main, "T").pure
    assert not p.rule(r.main, "R").pure


def test_inside_as_a_keyword_or_selector_is_no_occlusion_query():
    """``offset(-1, inside)`` and the ``inside`` selector of comp are keywords: the rules stay
    instanceable and keep no occluders; ``case inside : …`` is the query."""
    src = """Lot --> offset(-1, inside) comp(f){ inside : In. | border : B. } W
W --> offset(-1) comp(f){ inside : In. | all : B. }
"""
    r = load_rules(src).ruleset
    p = Purity(r)
    assert p.rule(r.main, "W").pure and not p.uses_occlusion
    r = load_rules(src + "Q --> case inside : In. else : Out.\n").ruleset
    assert Purity(r).uses_occlusion


def test_stochastic_tiles_are_replayed_by_the_outcome_of_their_choice(monkeypatch):
    """The varied benchmark building chooses each window at random: its tiles are pure but for
    that choice, so later tiles replay the recording whose choice their own random stream
    repeats (and derive, and are recorded, when it does not)."""
    import facadeforge.grammar.interpreter as interp

    outcomes = []
    real = interp.Derivation._variant

    def counting(self, key, seed):
        got = real(self, key, seed)
        outcomes.append(got is not None)
        return got
    monkeypatch.setattr(interp.Derivation, "_variant", counting)
    rules = load_rules(ROOT / "benchmarks" / "grammars" / "detailed_varied.cga",
                       assets=ROOT / "examples" / "assets")
    chance = Purity(rules.ruleset, chance=True)
    tile = chance.rule(rules.ruleset.main, "Tile")
    assert tile.pure and tile.chance and not Purity(rules.ruleset).rule(rules.ruleset.main,
                                                                        "Tile").pure
    derive(rules, lot_size="30x16", keep_tree=False)
    assert sum(outcomes) > 100 and not all(outcomes)


def test_choice_outcomes():
    from facadeforge.grammar.chance import outcome

    assert [outcome("pct", r, (30.0, 20.0)) for r in (0.0, 0.299, 0.3, 0.499, 0.5, 0.999)] == \
        [0, 0, 1, 1, 2, 2]
    assert outcome("p", 0.2, 0.25) is True and outcome("p", 0.25, 0.25) is False
    assert [outcome("list", r, 3) for r in (0.0, 0.34, 0.67, 0.999999)] == [0, 1, 2, 2]


# Window tiles as Esri's Candler building writes them: a facade-wide projection that a
# projectUV below the tile uses, a window texture chosen by floor(rand(…)), a center() in a
# callee, and a branch on an attribute (never set) that would edit the inherited UVs
CANDLER_LIKE = """
attr Mode = "Visualization"
Lot --> extrude(18) comp(f) { side : Facade | top : Roof. }
Facade --> setupProjection(0, scope.xy, 2, 2) projectUV(0)
           split(y) { ~3 : split(x) { ~2.5 : Tile }* }*
Tile --> split(x) { ~1 : Wall | 1.2 : split(y) { ~1 : Wall | 1.5 : Window | ~0.5 : Wall } | ~1 : Wall }
Window --> Sill Opening t(0, 0, -0.2) Asset
Sill --> s(scope.sx + 0.2, 0.1, 0.1) center(x) t(0, -0.1, 0) i("builtin:cube") Sill.
Opening --> extrude(-0.2) comp(f) { front : reverseNormals Back. | side = Reveal }
Reveal --> reverseNormals projectUV(0) Wall
Asset --> case Mode != "3DPrint" : s('1, '1, 0.1) i("builtin:cube") Tex(floor(rand(0, 3.99)))
          else : Tex(0)
Tex(n) --> tileUV(0, '4, '1) translateUV(0, -n / 4, 0) texture("win.jpg") Glass.
Wall --> color("#ccbb99") Wall.
"""


def _rule_runs(monkeypatch):
    import facadeforge.grammar.interpreter as interp

    runs = []
    real = interp.Derivation._run_rule

    def counting(self, *a):
        runs.append(a[3])
        return real(self, *a)
    monkeypatch.setattr(interp.Derivation, "_run_rule", counting)
    return runs


def test_candler_like_windows_are_instanced_and_equal_plain(monkeypatch):
    rules = load_rules(CANDLER_LIKE)
    runs = _rule_runs(monkeypatch)
    plain = derive(rules, lot_size="40.3x20.1", keep_tree=True)
    plain_runs, windows = len(runs), runs.count("Window")
    runs.clear()
    fast = derive(rules, lot_size="40.3x20.1", keep_tree=False)
    assert_same_parts(signature(plain), signature(fast))
    assert plain[0].attributes["shapes"] == fast[0].attributes["shapes"]
    assert windows > 40
    # windows replay recordings (a few per size and texture choice): their rules mostly do
    # not run again
    assert runs.count("Asset") < 0.5 * windows and len(runs) < 0.6 * plain_runs


def test_uv_flow_centers_and_folded_cases():
    rules = load_rules(CANDLER_LIKE)
    pur = Purity(rules.ruleset, chance=True)
    main = rules.ruleset.main
    # tileUV after an insert works on the asset's UVs; the else branch's on the inherited ones
    assert pur.rule(main, "Tex").uses_uv and pur.rule(main, "Asset").uses_uv
    assert not pur.rule(main, "Sill").uses_uv
    # Sill's center() aligns to the scope Window had when calling it: Window does not centre
    assert pur.rule(main, "Sill").centers and not pur.rule(main, "Window").centers
    assert pur.rule(main, "Asset").chance  # floor(rand(…)) is a choice among whole numbers
    # with Mode known not to be "3DPrint" (no rule sets it), the else branch does not count
    folded = Purity(rules.ruleset, chance=True, fold=lambda m, c, p: True)
    assert not folded.rule(main, "Asset").uses_uv and not folded.rule(main, "Window").uses_uv


@pytest.mark.skipif(not (ROOT.parent / "shared" / "data" / "cga" / "candler.rpk").exists(),
                    reason="../shared/data/cga/candler.rpk (Esri's Candler package) is absent")
def test_candler_package_instanced_equals_plain():
    rules = load_rules(ROOT.parent / "shared" / "data" / "cga" / "candler.rpk")
    fp = ROOT.parent / "shared" / "data" / "cga" / "candler_footprint.obj"
    plain = derive(rules, fp, keep_tree=True, workers=1)
    fast = derive(rules, fp, keep_tree=False, workers=1)
    assert_same_parts(signature(plain), signature(fast))
    assert plain[0].attributes["shapes"] == fast[0].attributes["shapes"]
    assert plain[0].warnings == fast[0].warnings
    for k in plain[0].reports:
        assert np.allclose(sorted(plain[0].reports[k]), sorted(fast[0].reports[k]), atol=1e-6)
