"""What Esri's own Candler building showed our runtime doing differently from PRT: convexify's
split lines, the repeats of floating sizes, and ``convexify`` written without parentheses."""

import numpy as np
import pytest

from facadeforge import derive, load_rules
from facadeforge.geometry.footprints import Footprint
from facadeforge.grammar.ops.geometry import convex_parts
from facadeforge.grammar.ops.subdivision import RepeatItem, SizeItem, resolve_split

CANDLER = np.array([[-15.25, 0, 17.5], [4.25, 0, 17.5], [15.25, 0, -12.7], [5.75, 0, -16.2],
                    [-2.05, 0, 5.5], [-5.25, 0, 5.5], [-5.25, 0, -17.5], [-15.25, 0, -17.5]])


def _area(p):
    x, z = p[:, 0], p[:, 2]
    return 0.5 * abs(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1)))


@pytest.mark.parametrize("ring", [CANDLER, CANDLER[::-1]])
def test_convexify_cuts_along_the_edges_of_concave_corners(ring):
    parts = convex_parts(ring)
    assert len(parts) == 3
    assert sum(_area(p) for p in parts) == pytest.approx(_area(ring))
    boxes = [np.round(np.r_[p[:, [0, 2]].min(0), p[:, [0, 2]].max(0)], 6).tolist() for p in parts]
    # the notch's edge carried on to the outline: the lower left block is a rectangle
    assert [-15.25, -17.5, -5.25, 5.5] in boxes


def test_convexify_max_length_leaves_longer_lines_uncut():
    assert len(convex_parts(CANDLER, 5.0)) == 1
    assert len(convex_parts(CANDLER, 10.5)) == 2  # only the 10 m line of the inner corner


def _items(spec):
    out = []
    for s in spec:
        if isinstance(s, list):
            out.append(RepeatItem(_items(s)))
        else:
            kind, v = s
            out.append(SizeItem(kind, v, kind + str(v)))
    return out


def test_two_alike_floating_repeats_share_the_copies_the_floats_fit_best():
    # Candler's wide floor: 1 | 3.55 | {~3.55}* | 3.55 | {~3.55}* | 3.55 | 1 on 23 m: three
    # floating tiles (3.45 m each) fit better than two (5.18 m), one before the middle tile
    items = _items([("abs", 1), ("abs", 3.55), [("float", 3.55)], ("abs", 3.55),
                    [("float", 3.55)], ("abs", 3.55), ("abs", 1)])
    pieces = resolve_split(items, 23.0)
    sizes = [round(w, 3) for _, _, w in pieces]
    assert len(pieces) == 8
    assert sizes[2] == sizes[4] == sizes[5] == pytest.approx(10.35 / 3, abs=1e-3)
    assert [b for b, _, _ in pieces].count("float3.55") == 3


@pytest.mark.parametrize("n, windows", [(1, 1), (2, 2), (3, 3)])
def test_window_bay_holds_the_windows_it_asks_for(n, windows):
    # Windows(n) --> split(x){ { ~scope.sx/n : Window | 0.25 : Wall }* | ~scope.sx/n : Window }
    w = 2.15 / n
    items = _items([[("float", w), ("abs", 0.25)], ("float", w)])
    pieces = resolve_split(items, 2.15)
    assert sum(1 for b, _, _ in pieces if b.startswith("float")) == windows


def test_bare_convexify_is_the_operation():
    (m,) = derive(load_rules("Lot --> convexify comp(f){ all : P. }"), [Footprint("c", CANDLER)])
    assert sorted(p.symbol for p in m.parts) == ["P", "P", "P"]
