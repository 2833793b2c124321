"""Parse grammars: 2D layout derivation = engine derivation, integral-image energy = direct sum,
hill climbing recovers a known layout."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.datasets import get_label_set
from facadeforge.engine import derive_facade, load_rules
from facadeforge.grammar.parameters import ParameterError
from facadeforge.parsing.energy import SegmentationEnergy
from facadeforge.parsing.fit import fit_grammar, grammar_path
from facadeforge.parsing.layout import ParseGrammarError, SplitLayout
from facadeforge.parsing.search import hill_climb, parameters_of

ECP7 = get_label_set("ecp7")


@pytest.fixture(scope="module")
def generic():
    return load_rules(grammar_path("generic"))


def _engine_boxes(rules, w, h, attrs):
    model = derive_facade(rules, w, h, attrs=attrs)
    rows = []
    for leaf in model.root.leaves():
        if leaf.geometry is None or leaf.geometry.n_faces == 0:
            continue
        v = leaf.geometry.vertices
        rows.append((round(v[:, 0].min(), 6), round(v[:, 1].min(), 6), round(v[:, 0].max(), 6),
                     round(v[:, 1].max(), 6), leaf.label))
    return sorted(rows)


@pytest.mark.parametrize("name", ["generic", "grid", "haussmann"])
@pytest.mark.parametrize("seed", range(4))
def test_layout_matches_engine(name, seed):
    rules = load_rules(grammar_path(name))
    rng = np.random.default_rng(seed)
    params = parameters_of(rules)
    attrs = {p.name: (p.choices[rng.integers(len(p.choices))] if p.discrete else
                      p.clip(rng.uniform(p.lo, p.hi))) for p in params}
    w = rng.uniform(8, 30)
    h = w * rng.uniform(0.8, 1.6)
    lay = SplitLayout(rules).derive(w, h, attrs)
    ours = sorted((round(b[0], 6), round(b[1], 6), round(b[2], 6), round(b[3], 6), lab)
                  for b, lab in zip(lay.boxes.tolist(), lay.labels))
    theirs = _engine_boxes(rules, w, h, attrs)
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs):
        assert a[4] == b[4]
        np.testing.assert_allclose(a[:4], b[:4], atol=1e-4)


@pytest.mark.parametrize("name", ["grid", "haussmann"])
def test_memo_across_derivations_changes_nothing(name):
    """One SplitLayout deriving a sequence of nearby layouts (as a search does: its memo keeps
    rule results keyed by the attributes they read) gives each the layout a fresh one gives."""
    rules = load_rules(grammar_path(name))
    params = parameters_of(rules)
    rng = np.random.default_rng(7)
    base = {p.name: (p.choices[rng.integers(len(p.choices))] if p.discrete else
                     p.clip(rng.uniform(p.lo, p.hi))) for p in params}
    shared = SplitLayout(rules)
    for _ in range(25):
        attrs = dict(base)
        for p in rng.choice(params, 2):
            attrs[p.name] = (p.choices[rng.integers(len(p.choices))] if p.discrete else
                             p.clip(rng.uniform(p.lo, p.hi)))
        a = shared.derive(15.0, 21.0, attrs)
        b = SplitLayout(rules).derive(15.0, 21.0, attrs)
        assert a.labels == b.labels
        # the memo keys scope sizes rounded to 1e-9 m: a hit may differ in the last bits
        np.testing.assert_allclose(a.boxes, b.boxes, rtol=0, atol=1e-9)


_HEADER = 'version "2019.0"\nattr facadeWidth = 10\n'


def test_memo_keys_tell_values_of_other_types_apart():
    """True, 1 and 1.0 are equal Python keys; a CGA str() tells them apart."""
    lay = SplitLayout(load_rules(_HEADER + 'attr flag = 1\n@StartRule\nFacade --> split(x) '
                                 '{ ~1 : A }\nA --> case str(flag) == "true" : Window '
                                 'else : Wall\n'))
    assert lay.derive(10, 10, {"flag": 1.0}).labels == ("wall",)
    assert lay.derive(10, 10, {"flag": True}).labels == ("window",)
    assert lay.derive(10, 10, {"flag": 1.0}).labels == ("wall",)


def test_memo_follows_functions_and_attribute_defaults():
    """A split size read through a function (which sees the scope) and an attribute default
    that reads another attribute: each change reaches the key, so a shared layout still gives
    what a fresh one gives."""
    rules = load_rules(_HEADER + "attr base = 2\nattr w = base * 1.5\nsz(k) = k * w / scope.sx\n"
                       "@StartRule\nFacade --> split(y) { ~1 : Row | ~1 : Row }\n"
                       "Row --> split(x) { 'sz(1) : Window | ~1 : Wall }\n")
    shared = SplitLayout(rules)
    for attrs, size in [({}, (10, 10)), ({"base": 1.0}, (10, 10)), ({}, (20, 10)),
                        ({"w": 5.0}, (20, 10)), ({}, (10, 10))]:
        a = shared.derive(*size, attrs)
        b = SplitLayout(rules).derive(*size, attrs)
        np.testing.assert_array_equal(a.boxes, b.boxes)
        assert a.labels == b.labels


def test_an_attribute_the_derivation_does_not_read_may_fail():
    """The memo key holds every attribute a rule could read; one that cannot be evaluated
    (rand in a parse grammar) only matters on the branch that reads it."""
    rules = load_rules(_HEADER + "attr useBad = false\nattr bad = rand(0, 1)\n@StartRule\n"
                       "Facade --> case useBad : split(x) { 'bad : Window | ~1 : Wall } "
                       "else : Wall\n")
    lay = SplitLayout(rules)
    assert lay.derive(10, 10, {}).labels == ("wall",)
    with pytest.raises(ParseGrammarError, match="deterministic"):
        lay.derive(10, 10, {"useBad": True})


def test_depth_limit_does_not_depend_on_earlier_derivations():
    rules = load_rules(_HEADER + "attr deep = false\n@StartRule\n"
                       "Facade --> case deep : Chain(62) else : R(3)\n"
                       "Chain(n) --> case n > 0 : Chain(n - 1) else : R(3)\n"
                       "R(k) --> case k > 0 : split(x) { ~1 : R(k - 1) | ~1 : Wall } "
                       "else : Window\n")
    warm = SplitLayout(rules)
    assert len(warm.derive(10, 10, {}).labels) == 4
    for lay in (warm, SplitLayout(rules)):
        with pytest.raises(ParseGrammarError, match="nests deeper"):
            lay.derive(10, 10, {"deep": True})


def test_guards_put_balconies_at_the_foot_of_a_floors_windows():
    rules = load_rules(grammar_path("grid"))
    attrs = {"nFloors": 2.0, "groundTop": 0.2, "floor2": 0.55, "roofLine": 0.9, "nColumns": 2.0,
             "column1": 0.2, "column2": 0.6, "windowWidth": 0.15, "windowHeight": 0.6,
             "sillHeight": 0.1, "guardFrac": 0.25, "guard1": True, "guard2": False,
             "balcony1": False, "balcony2": False}
    lay = SplitLayout(rules).derive(10.0, 10.0, attrs)
    windows = lay.boxes[[lab == "window" for lab in lay.labels]]
    guards = lay.boxes[[lab == "balcony" for lab in lay.labels]]
    assert len(windows) == 4 and len(guards) == 2
    for g in guards:  # each guard sits right under a window of the first floor, as wide
        above = windows[np.isclose(windows[:, 1], g[3]) & np.isclose(windows[:, 0], g[0])]
        assert len(above) == 1 and np.isclose(above[0, 2], g[2])
        assert g[3] < 5.5   # first floor (below floor2 = 5.5 m)


def test_unsupported_operation_is_named(tmp_path):
    g = tmp_path / "g.cga"
    g.write_text('version "2019.0"\n@Range(5, 20) attr facadeWidth = 10\n@StartRule\n'
                 'Facade --> comp(f) { all : Wall }\n')
    with pytest.raises(ParseGrammarError, match="comp"):
        SplitLayout(load_rules(g)).derive(10, 10)
    g.write_text('version "2019.0"\nattr facadeWidth = 10\n@StartRule\n'
                 'Facade --> split(x) { rand(1, 2) : Wall }*\n')
    with pytest.raises(ParseGrammarError, match="deterministic"):
        SplitLayout(load_rules(g)).derive(10, 10)
    with pytest.raises(ParameterError, match="@Range"):
        parameters_of(load_rules(g))


def test_energy_equals_direct_sum(generic):
    rng = np.random.default_rng(3)
    prob = rng.dirichlet(np.ones(7), size=(60, 45)).astype(np.float32)
    energy = SegmentationEnergy(prob, ECP7)
    lay = SplitLayout(generic).derive(15, 20)
    labels = energy.rasterize(lay)
    direct = -np.log(np.clip(np.take_along_axis(prob, labels[:, :, None].astype(int), 2),
                             1e-3, 1)).sum()
    assert energy(lay) == pytest.approx(direct, rel=1e-9)


def test_hill_climbing_recovers_a_known_layout(known_layout):
    generic, prob, truth = known_layout
    fit = fit_grammar(prob, ECP7, generic, budget=2500, seed=1)
    assert fit.search.derivations == 2500
    assert all(b <= a for a, b in zip(fit.search.curve, fit.search.curve[1:]))  # best-so-far
    agree = (fit.labels == truth).mean()
    assert agree > 0.85, agree


def test_hill_climb_is_deterministic_and_bounded():
    from facadeforge.parsing.search import Parameter

    params = [Parameter("a", 0.0, -5, 5), Parameter("b", "x", choices=("x", "y"))]

    def f(at):
        return (at["a"] - 2.0) ** 2 + (0 if at["b"] == "y" else 1)

    r1 = hill_climb(f, params, budget=300, seed=4)
    r2 = hill_climb(f, params, budget=300, seed=4)
    assert r1.attrs == r2.attrs and r1.derivations == 300
    assert abs(r1.attrs["a"] - 2) < 0.1 and r1.attrs["b"] == "y"


def test_margins_frame_the_building_and_arcade_openings_sit_under_the_columns():
    """grid.cga's surroundings (background beside and below the building) and its arcade
    ground floor: column positions stay fractions of the whole facade, so a margin does not
    move the windows, and each opening is centred under its window column."""
    rules = load_rules(grammar_path("grid"))
    attrs = {"nFloors": 1.0, "groundTop": 0.3, "roofLine": 0.9, "roofFrac": 0.0,
             "nColumns": 2.0, "column1": 0.3, "column2": 0.6, "windowWidth": 0.1,
             "windowHeight": 0.5, "sillHeight": 0.2, "balcony1": False, "guard1": False,
             "leftMargin": 0.1, "rightMargin": 0.2, "streetFrac": 0.05,
             "groundKind": "arcade", "arcadeKind": "shop", "arcadeWidth": 0.16,
             "arcadeHeight": 0.75, "doorColumn": 2.0}
    lay = SplitLayout(rules).derive(10.0, 10.0, attrs)
    by = {lab: lay.boxes[[x == lab for x in lay.labels]] for lab in set(lay.labels)}
    bg = by["background"]
    assert np.isclose(bg[:, 0].min(), 0) and np.isclose(bg[:, 2].max(), 10)
    sides = bg[np.isclose(bg[:, 3] - bg[:, 1], 10)]          # full-height margins
    np.testing.assert_allclose(sorted((sides[:, 2] - sides[:, 0]).tolist()), [1.0, 2.0])
    street = bg[np.isclose(bg[:, 1], 0) & (bg[:, 3] < 1)]
    assert len(street) == 1 and np.isclose(street[0, 3], 0.5)
    windows = by["window"]
    np.testing.assert_allclose(sorted(windows[:, 0].tolist()), [3.0, 6.0])   # not shifted
    np.testing.assert_allclose(windows[:, 2] - windows[:, 0], 1.0)
    shop, door = by["shop"], by["door"]
    assert len(shop) == 1 and len(door) == 1          # column 2's opening is the door
    np.testing.assert_allclose((shop[0, 0] + shop[0, 2]) / 2, 3.5)   # under column 1
    np.testing.assert_allclose((door[0, 0] + door[0, 2]) / 2, 6.5)
    np.testing.assert_allclose(shop[0, 2] - shop[0, 0], 1.6)
    np.testing.assert_allclose([shop[0, 1], shop[0, 3]], [0.5, 0.5 + 0.75 * 2.5])


@pytest.mark.parametrize("seed", range(3))
def test_arcade_with_overlapping_openings_matches_engine(seed):
    """Openings wider than the column spacing push the later ones along; the 2D layout must
    still be what the engine derives."""
    rules = load_rules(grammar_path("grid"))
    rng = np.random.default_rng(seed)
    attrs = {p.name: (p.choices[rng.integers(len(p.choices))] if p.discrete else
                      p.clip(rng.uniform(p.lo, p.hi))) for p in parameters_of(rules)}
    attrs.update({"groundKind": "arcade", "nColumns": 12.0, "arcadeWidth": 0.3,
                  "doorColumn": float(rng.integers(0, 13))})
    attrs.update({f"column{j}": 0.05 + 0.07 * (j - 1) for j in range(1, 13)})
    lay = SplitLayout(rules).derive(14.0, 18.0, attrs)
    ours = sorted((round(b[0], 6), round(b[1], 6), round(b[2], 6), round(b[3], 6), lab)
                  for b, lab in zip(lay.boxes.tolist(), lay.labels))
    theirs = _engine_boxes(rules, 14.0, 18.0, attrs)
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs):
        assert a[4] == b[4]
        np.testing.assert_allclose(a[:4], b[:4], atol=1e-4)
