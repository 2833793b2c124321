"""``inter`` occlusion queries: buildings see their neighbours' occluders (a first pass over all
initial shapes finds them, as CityEngine's runtime generates occluders before the models)."""

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.geometry.footprints import Footprint

RULES = """Lot --> extrude(6) comp(f) {{ side : Facade | top : Roof. }}
Facade --> split(x) {{ ~2 : Tile }}*
Tile --> case touches({target}) : Wall. else : Window.
"""


def lot(x0, x1, z0=0.0, z1=8.0):
    return np.array([[x0, 0, z1], [x1, 0, z1], [x1, 0, z0], [x0, 0, z0]], float)


def wall_area(models):
    return sum(p.mesh.area() for m in models for p in m.parts if p.symbol == "Wall")


@pytest.mark.parametrize("target, walls", [("inter", 2 * 8 * 6), ("all", 2 * 8 * 6), ("intra", 0)])
@pytest.mark.parametrize("workers", [1, 2])
def test_party_walls_see_the_neighbour(target, walls, workers):
    fps = [Footprint("a", lot(0, 10)), Footprint("b", lot(10, 20)), Footprint("c", lot(40, 50)),
           Footprint("d", lot(60, 70))]
    rules = RULES.format(target=target)
    # rule text, not loaded rules: with workers=2 the worker processes load it (both passes)
    models = derive(rules, fps, workers=workers)
    assert not any(m.warnings for m in models)
    # a and b share the 8 m x 6 m wall at x = 10: its tiles on both sides become walls
    assert wall_area(models) == pytest.approx(walls)
    assert wall_area(models[2:]) == 0


def test_a_lone_building_has_no_neighbours():
    models = derive(load_rules(RULES.format(target="inter")), [Footprint("a", lot(0, 10))])
    assert wall_area(models) == 0


def test_closed_leaf_shapes_are_occluders():
    # a 6 m block left as one closed leaf beside a 12 m tower: the tower's two lower floors on
    # the shared wall touch it over their area; the third only along its lower edge
    rules = """attr kind = "tower"
Lot --> case kind == "block" : extrude(6) Mass.
        else : extrude(12) comp(f) { side : Facade | top : Roof. }
Facade --> split(y) { ~3 : Floor }*
Floor --> split(x) { ~2 : Tile }*
Tile --> case touches(inter) : Wall. else : Window.
"""
    fps = [Footprint("a", lot(0, 10), {"kind": "block"}), Footprint("b", lot(10, 20))]
    models = derive(load_rules(rules), fps, workers=1)
    assert not any(m.warnings for m in models)
    assert wall_area(models) == pytest.approx(8 * 6)


def test_bad_occlusion_target_is_a_warning():
    m = derive(load_rules(RULES.format(target="neighbours")), None, lot_size="10x8")[0]
    assert any("occlusion target 'neighbours'" in w for w in m.warnings)


def test_the_modern_example_on_its_pair_of_lots():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    models = derive(load_rules(root / "examples/grammars/modern.cga"),
                    root / "examples/footprints/pair.geojson", workers=1)
    assert [m.warnings for m in models] == [[], []]
    tall, low = models
    # the tall building's party wall below the low roof (3 floors) is wall where they touch
    party = [p for p in tall.parts if p.symbol == "Wall"
             and np.allclose(p.mesh.bounds()[:, 0], 36.0) and p.mesh.bounds()[1, 1] <= 9.6 + 1e-6]
    assert sum(p.mesh.area() for p in party) > 0
    assert not [p for p in tall.parts if p.symbol == "Glass" and p.mesh.bounds()[0, 0] > 35.8
                and p.mesh.bounds()[1, 1] < 9.6 and not -15.6 < p.mesh.bounds()[0, 2] < -8.4]


@pytest.mark.parametrize("query, first_pass", [
    ("touches(intra)", False), ('touches("intra")', False), ("touches(inter)", True),
    ("touches(all)", True), ("touches()", True), ("touches(where)", True)])
def test_only_queries_that_may_reach_the_neighbours_derive_them_first(query, first_pass,
                                                                      monkeypatch):
    """``intra`` queries never look at other buildings: no first pass over the footprints for
    their occluders, and the same models either way."""
    from facadeforge import engine

    text = RULES.format(target="@").replace("touches(@)", query)
    rules = load_rules('attr where = "intra"\n' + text)
    assert engine._queries_neighbours(rules) is first_pass
    fps = [Footprint("a", lot(0, 10)), Footprint("b", lot(10, 20))]
    got = derive(rules, fps, workers=1)
    if not first_pass:
        monkeypatch.setattr(engine, "_queries_neighbours", lambda r: True)
        both = derive(rules, fps, workers=1)
        assert [m.stats() for m in got] == [m.stats() for m in both]
        assert wall_area(got) == 0
