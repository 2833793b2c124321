"""Vectorised triangle rasteriser with a depth buffer (numpy only).

Triangles are scan-converted row by row without a Python loop: every triangle is expanded into
the pixel rows it crosses, every row into the pixel centres between its left and right edge, so
work is proportional to the pixels actually covered.  Rows and pixels of many triangles are
processed together in chunks of a few million.  Depth is compared on a "nearness" value that is
linear in screen space (``1/z`` under perspective, ``-z`` for an orthographic view); larger is
nearer.
"""

from __future__ import annotations

import numpy as np

_ROWS = 1_000_000  # rows per chunk
_PIXELS = 3_000_000  # pixels per chunk


def _ranges(counts: np.ndarray, budget: int):
    """Consecutive index ranges whose counts add up to about ``budget`` (at least one item)."""
    total = np.cumsum(counts)
    start = 0
    while start < len(counts):
        base = total[start - 1] if start else 0
        stop = max(int(np.searchsorted(total, base + budget, side="right")), start + 1)
        yield start, stop
        start = stop


def _expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For items repeated ``counts`` times: the item of each copy and the copy's rank."""
    owner = np.repeat(np.arange(len(counts)), counts)
    rank = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
    return owner, rank


def _depth_planes(xy: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Coefficients (T, 3) of nearness as ``a * x + b * y + c`` over each triangle's plane."""
    p0, p1, p2 = xy[:, 0], xy[:, 1], xy[:, 2]
    e1, e2 = p1 - p0, p2 - p0
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    inv = np.where(np.abs(det) > 1e-12, 1.0 / np.where(det == 0, 1.0, det), 0.0)
    d1, d2 = near[:, 1] - near[:, 0], near[:, 2] - near[:, 0]
    a = (d1 * e2[:, 1] - d2 * e1[:, 1]) * inv
    b = (d2 * e1[:, 0] - d1 * e2[:, 0]) * inv
    return np.stack([a, b, near[:, 0] - a * p0[:, 0] - b * p0[:, 1]], axis=1)


def rasterize(xy: np.ndarray, near: np.ndarray | None, size: tuple[int, int], *,
              zbuf: np.ndarray | None = None, ids: np.ndarray | None = None,
              in_front_of: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rasterise triangles into a depth buffer and a triangle-index buffer.

    Parameters
    ----------
    xy : (T, 3, 2) float
        Screen coordinates in pixels (pixel ``(i, j)`` has its centre at ``(i + .5, j + .5)``).
    near : (T, 3) float or None
        Nearness per corner (larger is nearer); ``None`` for plain coverage.
    size : (width, height)
    zbuf, ids : (H * W,) arrays, optional
        Buffers to continue (new ones otherwise: ``-inf`` and ``-1``).
    in_front_of : (H * W,) float, optional
        Only samples nearer than this per-pixel value count.

    Returns
    -------
    zbuf : (H * W,) float
        Nearness of the nearest sample per pixel (``-inf`` where none).
    ids : (H * W,) int
        Index of the triangle seen at each pixel, ``-1`` where none; of equally near samples
        the later triangle wins.
    """
    width, height = size
    zbuf = np.full(width * height, -np.inf) if zbuf is None else zbuf
    ids = np.full(width * height, -1, np.int64) if ids is None else ids
    xy = np.asarray(xy, float).reshape(-1, 3, 2)
    if len(xy) == 0:
        return zbuf, ids
    planes = _depth_planes(xy, np.zeros((len(xy), 3)) if near is None else np.asarray(near, float))
    ylo, yhi = xy[:, :, 1].min(axis=1), xy[:, :, 1].max(axis=1)
    r0 = np.clip(np.ceil(ylo - 0.5), 0, height).astype(np.int64)
    r1 = np.clip(np.floor(yhi - 0.5), -1, height - 1).astype(np.int64)
    nrows = np.maximum(r1 - r0 + 1, 0)
    edges = _edges(xy)
    for start, stop in _ranges(nrows, _ROWS):
        tri, rank = _expand(nrows[start:stop])
        tri += start
        _rows(edges, planes, tri, r0[tri] + rank, size, zbuf, ids, in_front_of)
    return zbuf, ids


def _edges(xy: np.ndarray) -> np.ndarray:
    """Per triangle (T, 8): y of top, middle and bottom vertex, x of top and middle, and the
    slopes dx/dy of the edges top→bottom, top→middle and middle→bottom."""
    order = np.argsort(xy[:, :, 1], axis=1)
    v = np.take_along_axis(xy, order[:, :, None], axis=1)
    top, mid, bot = v[:, 0], v[:, 1], v[:, 2]

    def slope(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        dy = q[:, 1] - p[:, 1]
        return np.where(dy > 0, (q[:, 0] - p[:, 0]) / np.where(dy > 0, dy, 1.0), 0.0)

    return np.stack([top[:, 1], mid[:, 1], bot[:, 1], top[:, 0], mid[:, 0],
                     slope(top, bot), slope(top, mid), slope(mid, bot)], axis=1)


def _rows(edges, planes, tri, row, size, zbuf, ids, in_front_of) -> None:
    """Fill the pixel rows ``row`` of triangles ``tri``."""
    width = size[0]
    yc = row + 0.5
    e = edges[tri]
    x_long = e[:, 3] + (yc - e[:, 0]) * e[:, 5]
    upper = yc < e[:, 1]
    x_short = np.where(upper, e[:, 3] + (yc - e[:, 0]) * e[:, 6],
                       e[:, 4] + (yc - e[:, 1]) * e[:, 7])
    c0 = np.clip(np.ceil(np.minimum(x_long, x_short) - 0.5), 0, width).astype(np.int64)
    c1 = np.clip(np.floor(np.maximum(x_long, x_short) - 0.5), -1, width - 1).astype(np.int64)
    count = np.maximum(c1 - c0 + 1, 0)
    for start, stop in _ranges(count, _PIXELS):
        seg, rank = _expand(count[start:stop])
        seg += start
        _pixels(planes, tri[seg], c0[seg] + rank, row[seg], width, zbuf, ids, in_front_of)


def _pixels(planes, tri, px, py, width, zbuf, ids, in_front_of) -> None:
    """Depth-test pixel samples and record the winners."""
    pid = py * width + px
    depth = planes[tri, 0] * (px + 0.5) + planes[tri, 1] * (py + 0.5) + planes[tri, 2]
    if in_front_of is not None:
        keep = depth > in_front_of[pid]
        tri, pid, depth = tri[keep], pid[keep], depth[keep]
    np.maximum.at(zbuf, pid, depth)
    win = depth >= zbuf[pid]
    ids[pid[win]] = tri[win]
