"""2D polygon helpers shared by the operations that cut faces in their plane."""

from __future__ import annotations

import numpy as np


def without_repeats(pts: np.ndarray) -> np.ndarray:
    """The points (k, d) of a closed ring without those repeating the one before (the last
    counting as before the first): a repeated corner would be an edge of no length."""
    step = np.linalg.norm(pts - np.roll(pts, 1, axis=0), axis=1)
    return pts[step > 1e-9] if len(pts) and (step <= 1e-9).any() else pts


def ring_points(ring) -> np.ndarray:
    """A shapely ring's points (k, 2) without the closing point and without repeated points (an
    overlay cut through a vertex can leave it twice in a row)."""
    return without_repeats(np.asarray(ring.coords)[:-1])


def simple_pieces(g) -> list[np.ndarray]:
    """Counter-clockwise rings (k, 2) covering a shapely Polygon: the polygon itself when it has
    no holes, else its constrained Delaunay triangles (our meshes hold simple polygons only).
    Earcut, used before, could cover part of a hole on the bands ``setback`` cuts; the
    constrained triangulation keeps to the polygon."""
    if not g.interiors:
        ext = ring_points(g.exterior)
        if len(ext) < 3:
            return []
        return [ext if g.exterior.is_ccw else ext[::-1]]
    import shapely

    # all triangles at once (a footprint with thousands of courtyards has tens of thousands)
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(g))
    q = shapely.get_coordinates(shapely.get_exterior_ring(tris)).reshape(-1, 4, 2)[:, :3]
    x, y = q[:, :, 0], q[:, :, 1]
    area2 = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    q[area2 < 0] = q[area2 < 0, ::-1]
    return list(q[np.abs(area2) > 1e-12])
