"""Faces with holes stored as pieces (``geometry.holed``): the order their edges are listed in."""

import numpy as np

from facadeforge.geometry.holed import HOLED, edge_corners
from facadeforge.geometry.mesh import Mesh, weld_ids
from facadeforge.grammar.ops.subdivision import component_count
from facadeforge.grammar.state import ShapeState

# a 10 x 4 wall (x right, y up, facing +z) round a 2 x 2 window, as five pieces; the bottom
# edge runs over two pieces, so it has a corner at (3, 0) on a straight run
PIECES = [[(0, 0), (3, 0), (3, 1), (3, 3), (3, 4), (0, 4)],
          [(3, 0), (10, 0), (10, 1), (6, 1), (4, 1), (3, 1)],
          [(3, 3), (4, 3), (6, 3), (10, 3), (10, 4), (3, 4)],
          [(3, 1), (4, 1), (4, 3), (3, 3)],
          [(6, 1), (10, 1), (10, 3), (6, 3)]]


def _wall(pieces=PIECES) -> Mesh:
    polys = [np.array([(x, y, 0.0) for x, y in p]) for p in pieces]
    m = Mesh.from_polygons(polys)
    m.face_data = {HOLED: np.array([7] * len(polys), object)}
    return m


def _ring_points(mesh):
    order = edge_corners(mesh, weld_ids(mesh.vertices))
    return [tuple(mesh.vertices[mesh.corners[c]][:2]) for c in order]


def test_the_outline_starts_at_the_bottom_left_then_the_hole():
    # comp(e) of a wall: its bottom edge first, from where that straight run begins (not at
    # the corner a piece left on it), round the outline, then round the window
    assert _ring_points(_wall()) == [(0, 0), (3, 0), (10, 0), (10, 1), (10, 3), (10, 4),
                                     (3, 4), (0, 4), (4, 1), (4, 3), (6, 3), (6, 1)]


def test_the_comp_fe_count_is_the_number_of_edges_listed():
    # a repeated corner (a zero-length edge) is left out of the rings, and out of the count
    pieces = [list(p) for p in PIECES]
    pieces[1].insert(2, (10, 0))
    mesh = _wall(pieces)
    st = ShapeState.__new__(ShapeState)
    st.geometry, st.context = mesh, {}
    assert component_count(st, "fe") == len(edge_corners(mesh, weld_ids(mesh.vertices))) == 12
