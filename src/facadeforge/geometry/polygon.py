"""2D polygon helpers shared by the operations that cut faces in their plane."""

from __future__ import annotations

import numpy as np


def simple_pieces(g) -> list[np.ndarray]:
    """Counter-clockwise rings (k, 2) covering a shapely Polygon: the polygon itself when it has
    no holes, else its earcut triangles (our meshes hold simple polygons only)."""
    ext = np.asarray(g.exterior.coords)[:-1]
    if not g.interiors:
        return [ext if g.exterior.is_ccw else ext[::-1]]
    import mapbox_earcut as earcut

    rings = [ext] + [np.asarray(r.coords)[:-1] for r in g.interiors]
    flat = np.concatenate(rings)
    ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
    tri = np.asarray(earcut.triangulate_float64(flat, ends), np.int64).reshape(-1, 3)
    out = []
    for t in tri:
        q = flat[t]
        x, y = q[:, 0], q[:, 1]
        out.append(q if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0 else q[::-1])
    return out
