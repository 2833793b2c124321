"""CityFit's four grammar problems (Hohmann et al. 2009, §4, Fig. 11), each modelled by an example
grammar in CGA and in GML (``examples/grammars/cityfit/``): the tests check the property each
problem is about on the derived models, and that both languages give the same parts."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from facadeforge.engine import derive_facade
from facadeforge.gml import derive_gml
from facadeforge.model.scope import Scope

CITYFIT = Path(__file__).resolve().parents[2] / "examples" / "grammars" / "cityfit"
SIZES = {"overlap": (10, 6), "split_order": (15, 9), "neighbours": (15, 9.3), "exceptional": (10, 9)}
EPS = 1e-6


def cga(name, attrs=None, size=None):
    w, h = size or SIZES[name]
    return derive_facade(CITYFIT / f"{name}.cga", w, h, attrs=attrs)


def gml(name, replace=None, size=None):
    """The GML example on its facade rectangle; ``replace`` = (old, new) edits the program."""
    w, h = size or SIZES[name]
    program = (CITYFIT / f"{name}.gml").read_text()
    if replace:
        assert program.count(replace[0]) == 1
        program = program.replace(*replace)
    return derive_gml(program, scope=Scope(np.zeros(3), np.eye(3), np.array([w, h, 0.0])),
                      symbol="Facade")


def both(name, **kw):
    return {"cga": cga(name, **kw), "gml": gml(name)}


def labelled(model) -> Counter:
    return Counter((p.symbol, p.label) for p in model.parts)


def shapes(model, symbol):
    return [s for s in model.root.walk() if s.symbol == symbol]


def x_range(obj):
    if hasattr(obj, "mesh"):
        lo, hi = obj.mesh.bounds()
    else:
        c = obj.scope.corners()
        lo, hi = c.min(axis=0), c.max(axis=0)
    return float(lo[0]), float(hi[0])


def bounds(part):
    lo, hi = part.mesh.bounds()
    return np.asarray(lo, float), np.asarray(hi, float)


@pytest.mark.parametrize("name", sorted(SIZES))
def test_both_languages_give_the_same_labelled_parts(name):
    m = both(name)
    assert not m["cga"].warnings and not m["gml"].warnings
    assert labelled(m["cga"]) == labelled(m["gml"])
    # and the same geometry, part for part (sorted by their boxes)
    boxes = {k: sorted(tuple(np.round(np.concatenate(bounds(p)), 6)) for p in v.parts)
             for k, v in m.items()}
    assert boxes["cga"] == boxes["gml"]


# ------------------------------------------------------------------ 1. overlapping elements

@pytest.mark.parametrize("lang", ["cga", "gml"])
def test_overlap_sill_reaches_beyond_its_window_and_the_tiles_stay_a_partition(lang):
    m = both("overlap")[lang]
    overhang, width, depth = 0.15, 1.2, 0.12
    sills = [p for p in m.parts if p.label == "sill"]
    windows = [p for p in m.parts if p.label == "window"]
    assert len(sills) == len(windows) == 8  # 2 floors x 4 tiles
    tiles = shapes(m, "Tile")
    assert len(tiles) == 8
    walls = [p for p in m.parts if p.label == "wall"]
    for sill in sills:
        lo, hi = bounds(sill)
        # the window right above the sill
        win = min(windows, key=lambda w: abs(bounds(w)[0][0] - lo[0] - overhang)
                  + abs(bounds(w)[0][1] - hi[1]))
        wx0, wx1 = x_range(win)
        assert wx1 - wx0 == pytest.approx(width)
        assert lo[0] == pytest.approx(wx0 - overhang) and hi[0] == pytest.approx(wx1 + overhang)
        assert hi[2] - lo[2] == pytest.approx(depth)
        # it reaches into the neighbouring wall pieces of its tile, left and right
        tile = next(t for t in tiles if x_range(t)[0] - EPS <= wx0 and wx1 <= x_range(t)[1] + EPS)
        left, right = tile.children[0], tile.children[-1]
        assert x_range(left)[1] == pytest.approx(wx0) and x_range(right)[0] == pytest.approx(wx1)
        assert lo[0] < x_range(left)[1] - 0.1 and hi[0] > x_range(right)[0] + 0.1
    for tile in tiles:
        # wall | window column | wall: consecutive, no gap, no overlap, covering the tile
        xs = [x_range(c) for c in tile.children]
        assert len(xs) == 3
        assert xs[0][0] == pytest.approx(x_range(tile)[0])
        assert xs[-1][1] == pytest.approx(x_range(tile)[1])
        assert all(a[1] == pytest.approx(b[0]) for a, b in zip(xs, xs[1:]))
    # the flat pieces (walls, the slots behind the sills, windows) cover the facade exactly once
    flat = walls + windows
    assert sum(p.mesh.area() for p in flat) == pytest.approx(10 * 6)
    assert all(bounds(p)[0][0] >= -EPS and bounds(p)[1][0] <= 10 + EPS for p in flat)


def test_overlap_follows_the_overhang():
    m = cga("overlap", attrs={"overhang": 0.3})
    m2 = gml("overlap", replace=("0.15 !overhang", "0.3 !overhang"))
    for model in (m, m2):
        widths = {round(np.ptp(p.mesh.vertices[:, 0]), 6) for p in model.parts if p.label == "sill"}
        assert widths == {1.8}


# ------------------------------------------------------------------ 2. split order

@pytest.mark.parametrize("lang", ["cga", "gml"])
def test_split_order_resalit_spans_all_floors_as_one_shape(lang):
    m = both("split_order")[lang]
    (resalit,) = shapes(m, "Resalit")
    c = resalit.scope.corners()
    assert c[:, 1].min() == pytest.approx(0) and c[:, 1].max() == pytest.approx(9)
    assert x_range(resalit) == pytest.approx((5, 10))
    # it is split first (vertically, at the top): the facade's children are wing | resalit | wing
    assert [s.symbol for s in m.root.children] == ["Wing", "Resalit", "Wing"]
    # floors are split inside it and around it, in the wings, at the same heights
    inside = shapes(m, "ResalitFloor")
    around = shapes(m, "Floor")
    assert len(inside) == 3 and len(around) == 6
    assert all(f in resalit.walk() for f in inside)
    assert not any(f in resalit.walk() for f in around)

    def levels(fs):
        return Counter((round(float(f.scope.corners()[:, 1].min()), 6),
                        round(float(f.scope.corners()[:, 1].max()), 6)) for f in fs)

    assert set(levels(inside)) == set(levels(around)) == {(0, 3), (3, 6), (6, 9)}
    assert all(n == 2 for n in levels(around).values())  # one floor each side per level
    # the resalit steps out of the facade: its windows at z = resalit depth, the others at 0
    for p in m.parts:
        z = bounds(p)[0][2]
        in_resalit = 5 - EPS <= bounds(p)[0][0] and bounds(p)[1][0] <= 10 + EPS
        assert z == pytest.approx(0.4 if in_resalit else 0.0)
    assert sum(p.label == "window" for p in m.parts) == 18


# ------------------------------------------------------------------ 3. unknown neighbours

def ledges(model):
    return sorted((p for p in model.parts if p.label == "cornice"), key=lambda p: x_range(p)[0])


@pytest.mark.parametrize("lang", ["cga", "gml"])
def test_neighbours_every_ledge_piece_has_the_depth_set_at_the_top(lang):
    m = both("neighbours")[lang]
    pieces = ledges(m)
    assert len(pieces) == 3  # cut by the resalit: left wing, resalit, right wing
    # in three different subtrees of the facade (neighbours that do not know of each other)
    ledge_shapes = shapes(m, "Ledge")
    assert len(ledge_shapes) == 3
    owners = [[i for i, c in enumerate(m.root.children) if s in c.walk()] for s in ledge_shapes]
    assert sorted(owners) == [[0], [1], [2]]
    depth = 0.02 * 15  # ledgeRatio times the facade width, set once in Facade
    for p in pieces:
        lo, hi = bounds(p)
        assert hi[2] - lo[2] == pytest.approx(depth)
        assert (lo[1], hi[1]) == pytest.approx((3.0, 3.3))
    # the resalit's piece stands out from the resalit, the wings' from the wall
    assert [round(float(bounds(p)[0][2]), 6) for p in pieces] == [0, 0.4, 0]
    # the pieces join up into one ledge over the whole facade
    xs = [x_range(p) for p in pieces]
    assert xs[0][0] == pytest.approx(0) and xs[-1][1] == pytest.approx(15)
    assert all(a[1] == pytest.approx(b[0]) for a, b in zip(xs, xs[1:]))


def test_neighbours_one_value_changes_every_piece():
    for model in (cga("neighbours", attrs={"ledgeRatio": 0.01}),
                  gml("neighbours", replace=("0.02 !ledge-ratio", "0.01 !ledge-ratio"))):
        assert {round(float(np.ptp(p.mesh.vertices[:, 2])), 6) for p in ledges(model)} == {0.15}
    # the depth follows the facade width: it is computed at the top, not a constant below
    for model in (cga("neighbours", size=(20, 9.3)), gml("neighbours", size=(20, 9.3))):
        assert {round(float(np.ptp(p.mesh.vertices[:, 2])), 6) for p in ledges(model)} == {0.4}


# ------------------------------------------------------------------ 4. exceptional elements

def grid_position(part, tile=2.5, floor=3.0):
    lo, _ = bounds(part)
    return int(lo[1] // floor), int(lo[0] // tile)


@pytest.mark.parametrize("lang", ["cga", "gml"])
def test_exceptional_exactly_one_blind_window_in_the_grid(lang):
    m = both("exceptional")[lang]
    blind = [p for p in m.parts if p.label == "blind"]
    windows = [p for p in m.parts if p.label == "window"]
    assert len(blind) == 1 and len(windows) == 11  # 3 floors x 4 tiles
    assert blind[0].symbol == "BlindWindow" and {p.symbol for p in windows} == {"Window"}
    # tile 6, row by row from the bottom left: floor 1, column 2
    assert grid_position(blind[0]) == (1, 2)
    cells = {grid_position(p) for p in blind + windows}
    assert cells == {(f, c) for f in range(3) for c in range(4)}
    # the blind window has the window's size and place in its tile
    assert np.allclose(np.ptp(blind[0].mesh.vertices, axis=0), np.ptp(windows[0].mesh.vertices, axis=0))
    # the regular rules are not duplicated: one Floor and one Tile rule for every floor/tile
    assert len(shapes(m, "Floor")) == 3 and len(shapes(m, "Tile")) == 12


@pytest.mark.parametrize("k", [0, 3, 9, 11])
def test_exceptional_one_value_moves_the_blind_window(k):
    for model in (cga("exceptional", attrs={"blindWindow": k}),
                  gml("exceptional", replace=("6 !blind-window", f"{k} !blind-window"))):
        blind = [p for p in model.parts if p.label == "blind"]
        assert len(blind) == 1 and grid_position(blind[0]) == divmod(k, 4)
        assert sum(p.label == "window" for p in model.parts) == 11
