"""``rules.gml`` from shape trees: ``derive_gml(tree_to_gml(tree))`` gives the tree's leaves back
(labels and rectangles to 1 mm, depths as boxes), as the CGA round trip of
``tests/grammar/test_extract.py`` does for ``rules.cga``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facadeforge.errors import InputError
from facadeforge.gml import derive_gml, load_gml
from facadeforge.gml.extract import tree_to_gml
from facadeforge.model.scope import Scope
from facadeforge.model.shape import INSERT, Shape

TOL = 1e-3  # metres


def _scope(x0, y0, x1, y1):
    return Scope((x0, y0, 0.0), np.eye(3), (x1 - x0, y1 - y0, 0.0))


def _part(symbol, box, axis, index, cluster, label="", **tags):
    s = Shape(symbol, _scope(*box), label=label, operator="split",
              params={"axis": axis, "index": index})
    s.tags = {"cluster": cluster, **tags}
    return s


def _rect(s: Shape):
    o, z = s.scope.origin, s.scope.size
    return np.array([o[0], o[1], o[0] + z[0], o[1] + z[1]])


def _derived_leaves(model):
    """Leaves of a derivation but the voids (gaps, the empty part of a host with inserted
    shapes only); a leaf of no area stays (an empty shape without geometry)."""
    return [s for s in model.root.leaves() if s.tags.get("terminal") != "void"]


def assert_round_trip(tree: Shape) -> list[tuple[Shape, Shape]]:
    """The derived leaves match the tree's one to one: label and x0, y0, x1, y1 to 1 mm; a
    leaf with a depth is a box that deep, behind the facade (recess) or in front (protrusion)."""
    program = tree_to_gml(tree)
    model = derive_gml(program)
    assert not model.warnings, model.warnings
    want, got = list(tree.leaves()), _derived_leaves(model)
    assert len(got) == len(want)
    free = list(range(len(got)))
    pairs = []
    for w in want:
        r = _rect(w)
        k = next((k for k in free if got[k].label == w.label
                  and np.abs(_rect(got[k]) - r).max() < TOL), None)
        assert k is not None, (w.symbol, w.label, r.round(4).tolist())
        free.remove(k)
        g = got[k]
        pairs.append((w, g))
        d = w.tags.get("depth")
        if d is not None and abs(d) >= 1e-4 and w.scope.size[2] == 0:
            assert g.scope.size[2] == pytest.approx(abs(d), abs=TOL)
            assert g.scope.origin[2] == pytest.approx(min(d, 0.0), abs=TOL)
        else:
            assert g.scope.size[2] == pytest.approx(w.scope.size[2], abs=TOL)
            assert g.scope.origin[2] == pytest.approx(w.scope.origin[2], abs=TOL)
    assert not free
    return pairs


def _hand_tree() -> Shape:
    """10 × 7 m: two floors of a wall strip and three window tiles (wall | window column |
    wall, the window recessed 0.25 m); a balcony in front of the upper middle tile, hanging
    0.2 m below the floor line."""
    root = Shape("Facade", _scope(0, 0, 10, 7))
    for fi, (y0, y1) in enumerate([(0, 3), (3, 7)]):
        floor = root.add(_part("Floor", (0, y0, 10, y1), "y", fi, f"F{fi}"))
        for ti, (x0, x1) in enumerate([(0, 1), (1, 4), (4, 7), (7, 10)]):
            if ti == 0:
                floor.add(_part("Tile", (x0, y0, x1, y1), "x", ti, "T0", label="wall"))
                continue
            tile = floor.add(_part("Tile", (x0, y0, x1, y1), "x", ti, "T1"))
            xs = [x0, x0 + 1, x1 - 1, x1]
            for ri in range(3):
                region = tile.add(_part("Region", (xs[ri], y0, xs[ri + 1], y1), "x", ri,
                                        f"T1.{ri}", label="" if ri == 1 else "wall"))
                if ri == 1:
                    ys = [y0, y0 + 1, y1 - 0.5, y1]
                    for k, lab in enumerate(["wall", "window", "wall"]):
                        tags = {"depth": -0.25} if lab == "window" else {}
                        region.add(_part("Region", (xs[1], ys[k], xs[2], ys[k + 1]), "y", k,
                                         f"T1.1.{k}", label=lab, **tags))
            if fi == 1 and ti == 2:
                b = Shape("Region", _scope(x0 + 0.5, y0 - 0.2, x1 - 0.5, y0 + 1.1),
                          label="balcony", operator=INSERT, params={"index": 0})
                b.tags = {"cluster": "T1.p0", "depth": 0.8}
                tile.add(b)
    return root


def test_hand_built_tree_round_trips():
    tree = _hand_tree()
    pairs = assert_round_trip(tree)
    assert len(pairs) == 33
    (balcony,) = [g for w, g in pairs if w.label == "balcony"]
    assert balcony.scope.size[2] == pytest.approx(0.8)         # standing out of the facade
    assert balcony.symbol == "Balcony_T1_p0"
    windows = [g for w, g in pairs if w.label == "window"]
    assert len(windows) == 6 and all(g.scope.origin[2] == pytest.approx(-0.25) for g in windows)


def test_program_reads_like_a_grammar():
    program = tree_to_gml(_hand_tree(), name="hand")
    assert program.splitlines()[0].startswith("% rules.gml - hand")
    lines = program.splitlines()
    assert "ShapeGrammar.Tools.init" in lines and lines[-1] == "finish"
    assert "scope (10,7,0) scale (0,0,0) move Facade" in lines
    defs = [ln.split()[0][1:] for ln in lines if ln.startswith("/")]
    assert len(defs) == len(set(defs))
    # one procedure per cluster; the tile with the balcony is a variant of its cluster
    assert {"Facade", "Floor_F0", "Floor_F1", "Tile_T1", "Tile_T1_v2", "Wall_T0",
            "Window_T1_1_1", "Balcony_T1_p0"} <= set(defs)
    assert sum(d.startswith("Tile_T1") for d in defs) == 2
    assert "[ 3 -1 ] /Y split Floor_F0 Floor_F1" in program
    assert "(0,0,-0.25) move 0.25 extrude /window label terminal-box" in program
    # the derived tree carries the rule names as symbols
    model = derive_gml(load_gml(program))
    assert model.root.symbol == "Facade"
    assert [c.symbol for c in model.root.children] == ["Floor_F0", "Floor_F1"]
    assert tree_to_gml(_hand_tree(), name="hand") == program          # deterministic


def test_gaps_become_voids_and_bad_trees_are_errors():
    root = Shape("Facade", _scope(0, 0, 6, 3))
    root.add(_part("Tile", (0, 0, 2, 3), "x", 0, "A", label="wall"))
    root.add(_part("Tile", (3, 0, 6, 3), "x", 1, "B", label="window"))   # 1 m gap at x = 2
    program = tree_to_gml(root)
    assert "terminal-void" in program
    assert_round_trip(root)

    over = Shape("Facade", _scope(0, 0, 6, 3))
    over.add(_part("Tile", (0, 0, 4, 3), "x", 0, "A", label="wall"))
    over.add(_part("Tile", (3, 0, 6, 3), "x", 1, "B", label="wall"))
    with pytest.raises(InputError, match="overlap"):
        tree_to_gml(over)

    mixed = Shape("Facade", _scope(0, 0, 6, 3))
    mixed.add(_part("Tile", (0, 0, 6, 1), "y", 0, "A", label="wall"))
    mixed.add(_part("Tile", (3, 0, 6, 3), "x", 1, "B", label="wall"))
    with pytest.raises(InputError, match="several axes"):
        tree_to_gml(mixed)

    turned = Shape("Facade", _scope(0, 0, 6, 3))
    c = s_ = np.sqrt(0.5)
    rot = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])         # 45°: not a box
    turned.add(Shape("Tile", Scope((0, 0, 0), rot, (1, 1, 0)), label="wall", operator="split",
                     params={"axis": "x", "index": 0}))
    with pytest.raises(InputError, match="rotate"):
        tree_to_gml(turned)
    # a quarter turn only swaps axes: the same box, written axis-aligned
    quarter = Shape("Facade", _scope(0, 0, 6, 3))
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    quarter.add(Shape("Tile", Scope((6, 0, 0), rot, (3, 6, 0)), label="wall", operator="split",
                      params={"axis": "x", "index": 0}))
    assert "terminal-box" in tree_to_gml(quarter)
    with pytest.raises(InputError):
        tree_to_gml("not a tree")


def _insert(box, label, index, depth):
    s = Shape("Region", _scope(*box), label=label, operator=INSERT, params={"index": index})
    s.tags = {"cluster": f"P.p{index}", "depth": depth}
    return s


def test_inserted_shapes_on_hosts_without_parts_or_area():
    root = Shape("Facade", _scope(0, 0, 6, 3))
    host = root.add(_part("Floor", (0, 0, 6, 3), "y", 0, "F0"))
    host.add(_insert((0.5, 0.2, 2.5, 1.0), "balcony", 0, 0.9))
    host.add(_insert((3.5, 0.2, 5.5, 1.0), "balcony", 1, 0.9))
    program = tree_to_gml(root)
    assert "dup dup [ 0 ] /X split terminal-void" in program
    assert_round_trip(root)
    flat = Shape("Facade", _scope(0, 0, 6, 3))
    flat.add(_part("Floor", (0, 0, 6, 3), "y", 0, "F0", label="wall"))
    line = flat.add(_part("Floor", (0, 3, 6, 3), "y", 1, "F1"))         # no height
    line.add(_part("Tile", (0, 3, 6, 3), "x", 0, "T0", label="wall"))
    line.add(_insert((1, 2.5, 5, 3.5), "cornice", 0, 0.3))
    assert "pop scope (4,1,0) scale (1,2.5,0) move" in tree_to_gml(flat)
    pairs = assert_round_trip(flat)
    assert "cornice" in {w.label for w, _ in pairs}


def test_a_single_leaf_facade():
    root = Shape("Facade", Scope((2.0, 1.0, 0.0), np.eye(3), (5.0, 4.0, 0.0)), label="wall")
    assert "scope (5,4,0) scale (2,1,0) move Facade" in tree_to_gml(root)
    assert_round_trip(root)


@pytest.fixture(scope="module")
def reconstructed(tmp_path_factory):
    from facadeforge.datasets.synthetic import generate
    from facadeforge.reconstruction import reconstruct

    d = tmp_path_factory.mktemp("gml_synth")
    photo = generate(1, seed=11, out_dir=d, size=320, styles=["haussmann"])[0]
    meta = json.loads(photo.with_suffix(".meta.json").read_text())
    return reconstruct(photo, rectified=True, width_m=meta["facade_size_m"][0], model=False)


def test_reconstructed_tree_round_trips(reconstructed):
    tree = reconstructed.tree
    pairs = assert_round_trip(tree)
    labels = {w.label for w, _ in pairs}
    assert {"window", "wall", "balcony"} <= labels
    inserted = [(w, g) for w, g in pairs if w.operator == INSERT]
    assert inserted and all(g.scope.size[2] > 0 and g.scope.origin[2] == 0
                            for _, g in inserted)
    # the floors' clusters are the floors' rules
    program = tree_to_gml(tree)
    floors = {c.tags["cluster"] for c in tree.children}
    assert all(f"/Floor_{f}_v" in program or f"/Floor_{f} " in program for f in floors)


def test_parse_derivation_tree_round_trips():
    from facadeforge.parsing.parse import parse

    rng = np.random.default_rng(0)
    img = np.full((300, 240, 3), (205, 195, 175), np.float64)
    for r in range(30, 220, 48):
        for c in range(20, 230, 46):
            img[r:r + 30, c:c + 22] = (55, 65, 80)
    img[250:] = (90, 60, 50)
    img += rng.normal(0, 8, img.shape)
    p = parse(np.clip(img, 0, 255).astype(np.uint8), rectified=True, budget=60, model=False)
    pairs = assert_round_trip(p.tree)
    assert "window" in {w.label for w, _ in pairs}
