"""A facade plane's own frame and its rasters: depth map, density, intensity, orthophoto (CityFit §3).

``hohmann2009`` §3: the depth information a photo misses "can be retrieved from the point cloud
by using it to compute a depth map for the orthofotos"; ``simon2011`` §5.3.2 extracts its depth
maps "from the Z-buffer of virtual orthographic cameras. For each visible facade of the
building, a camera of this sort faces the facade."  :func:`facade_frame` is that camera for one
plane of :mod:`.planes`, :func:`rasterize` its images.

Frame (:class:`FacadeFrame`): ``origin`` the facade's bottom-left corner on the plane as seen
from the street, ``u`` to the right (horizontal), ``v`` up, ``n`` out of the building; a point
``p`` has facade coordinates ``((p−o)·u, (p−o)·v, (p−o)·n)`` in metres: the third is its
**signed depth**, positive in front of the wall (balconies, signs), negative behind it (window
and door recesses, what is seen through glass).  Rasters have rows down (row 0 = top), one cell
per ``resolution`` metres, like the rectified photos of the image pipeline, so the same
analysis can read them.

Maps (:class:`FacadeMaps`), NaN or 0 where a cell holds no point:

- ``depth`` — median signed depth of the cell's points (m): the median, not the front-most,
  so that a stray point in front does not make a wall a balcony;
- ``front`` — the front-most depth (m), for protrusions;
- ``back`` — the back-most depth (m): what lies behind a railing, a tree or a car in front of a
  window — a solid wall has nothing behind it, an opening does;
- ``count`` / ``density`` — points per cell and per m²;
- ``intensity`` — mean laser intensity, ``rgb`` — mean colour (when the cloud has them);
- ``wall`` — the share of the cell's points within ``threshold`` of the plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cloud import PointCloud, PointCloudError
from .planes import Plane

__all__ = ["FacadeFrame", "FacadeMaps", "facade_frame", "facade_points", "rasterize",
           "DEPTH_BEHIND", "DEPTH_FRONT", "RESOLUTION"]

#: Cell size (m) of the facade rasters.
RESOLUTION = 0.05
#: Depth range (m) of the points that belong to a facade: behind the plane (recesses, what
#: glass lets through) and in front of it (balconies, signs, awnings).
DEPTH_BEHIND, DEPTH_FRONT = 1.0, 1.6
#: Margin (m) added around a facade plane's inliers along the facade and at its top.
MARGIN = 0.3


@dataclass(frozen=True)
class FacadeFrame:
    """The orthographic camera facing one facade (see the module docstring)."""

    origin: np.ndarray      # (3,) bottom-left corner, cloud coordinates
    u: np.ndarray           # (3,) right, unit
    v: np.ndarray           # (3,) up, unit
    n: np.ndarray           # (3,) out of the building, unit
    width: float            # m along u
    height: float           # m along v

    def to_facade(self, xyz: np.ndarray) -> np.ndarray:
        """Cloud coordinates → facade coordinates (u, v, depth), metres."""
        d = np.asarray(xyz, float) - self.origin
        return np.c_[d @ self.u, d @ self.v, d @ self.n]

    def to_cloud(self, uvd: np.ndarray) -> np.ndarray:
        """Facade coordinates (u, v[, depth]) → cloud coordinates."""
        uvd = np.atleast_2d(np.asarray(uvd, float))
        dep = uvd[:, 2:3] if uvd.shape[1] > 2 else 0.0
        return self.origin + uvd[:, :1] * self.u + uvd[:, 1:2] * self.v + dep * self.n

    def rectangle(self, u0: float, v0: float, u1: float, v1: float, depth: float = 0.0
                  ) -> np.ndarray:
        """The four cloud-frame corners of a facade rectangle (bottom-left, bottom-right,
        top-right, top-left) at a depth."""
        return self.to_cloud(np.array([[u0, v0, depth], [u1, v0, depth], [u1, v1, depth],
                                       [u0, v1, depth]]))

    def to_dict(self) -> dict:
        r = lambda a: [round(float(x), 6) for x in a]  # noqa: E731
        return {"origin": r(self.origin), "u": r(self.u), "v": r(self.v), "n": r(self.n),
                "width_m": round(self.width, 4), "height_m": round(self.height, 4)}


@dataclass
class FacadeMaps:
    """The rasters of one facade (rows down); see the module docstring."""

    frame: FacadeFrame
    resolution: float
    depth: np.ndarray
    front: np.ndarray
    count: np.ndarray
    wall: np.ndarray
    back: np.ndarray | None = None
    intensity: np.ndarray | None = None
    rgb: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.count.shape

    @property
    def density(self) -> np.ndarray:
        return self.count / self.resolution ** 2

    def cell_of(self, uv: np.ndarray) -> np.ndarray:
        """(row, col) of facade points (u, v) in the rasters."""
        uv = np.atleast_2d(uv)
        h = self.shape[0]
        col = np.floor(uv[:, 0] / self.resolution).astype(np.int64)
        row = h - 1 - np.floor(uv[:, 1] / self.resolution).astype(np.int64)
        return np.c_[row, col]

    def crop(self, x0: int, x1: int, top: int) -> FacadeMaps:
        """Columns ``x0:x1`` and rows ``top:`` (down to the foot) as a facade of their own: the
        frame moves along ``u`` by ``x0`` cells, its foot stays."""
        h = self.shape[0]
        f = self.frame
        r = self.resolution
        frame = FacadeFrame(origin=f.origin + x0 * r * f.u, u=f.u, v=f.v, n=f.n,
                            width=(x1 - x0) * r, height=(h - top) * r)
        sl = (slice(top, h), slice(x0, x1))
        pick = lambda a: None if a is None else a[sl]  # noqa: E731
        return FacadeMaps(frame=frame, resolution=r, depth=self.depth[sl], front=self.front[sl],
                          count=self.count[sl], wall=self.wall[sl], intensity=pick(self.intensity),
                          rgb=pick(self.rgb), back=pick(self.back))

    def box_m(self, box_px) -> tuple[float, float, float, float]:
        """A raster box ``(x0, y0, x1, y1)`` (columns, rows down, end exclusive) in facade
        metres ``(u0, v0, u1, v1)``."""
        x0, y0, x1, y1 = box_px
        h, r = self.shape[0], self.resolution
        return x0 * r, (h - y1) * r, x1 * r, (h - y0) * r


def _horizontal(vec: np.ndarray, up: int) -> np.ndarray:
    v = np.array(vec, float)
    v[up] = 0.0
    n = np.linalg.norm(v)
    if n < 1e-9:
        raise PointCloudError("a horizontal plane has no facade frame")
    return v / n


def facade_frame(cloud: PointCloud, plane: Plane, ground_level: float | None = None
                 ) -> FacadeFrame:
    """The frame of a vertical plane: its inliers' extent along the facade (1st–99th
    percentile plus :data:`MARGIN`), from the ground (``ground_level``, the up coordinate of
    the ground plane, when known; else the lowest inlier) to the top inlier plus the margin."""
    up = cloud.up
    upv = np.zeros(3)
    upv[up] = 1.0
    n = _horizontal(plane.normal, up)
    u = np.cross(upv, n)
    u /= np.linalg.norm(u)
    pts = cloud.xyz[plane.inliers]
    pu = pts @ u
    pv = pts[:, up]
    ulo, uhi = np.percentile(pu, [1, 99])
    ulo, uhi = ulo - MARGIN, uhi + MARGIN
    vlo = float(pv.min()) if ground_level is None else float(min(ground_level, pv.min()))
    vhi = float(pv.max()) + MARGIN
    # a point of the plane at (ulo, vlo): the plane is n·x = c with c from its inliers
    c = float(np.median(pts @ n))
    origin = ulo * u + vlo * upv + (c - (ulo * u + vlo * upv) @ n) * n
    return FacadeFrame(origin=origin, u=u, v=upv, n=n, width=float(uhi - ulo),
                       height=float(vhi - vlo))


def facade_box(frame: FacadeFrame, behind: float = DEPTH_BEHIND, front: float = DEPTH_FRONT
               ) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned box (cloud coordinates) around a facade's box: for a spatial query."""
    corners = np.array([[u, v, d] for u in (0, frame.width) for v in (0, frame.height)
                        for d in (-behind, front)])
    pts = frame.to_cloud(corners)
    return pts.min(0), pts.max(0)


def facade_points(cloud: PointCloud, frame: FacadeFrame, behind: float = DEPTH_BEHIND,
                  front: float = DEPTH_FRONT, exclude: np.ndarray | None = None,
                  candidates: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the cloud's points in the facade's box (its rectangle, ``behind`` m behind
    to ``front`` m in front) and their facade coordinates; ``exclude`` (a boolean mask over
    the cloud: the ground's points, which run under the facade's foot) leaves points out;
    ``candidates`` (indices, e.g. a store's box query around :func:`facade_box`) limits the
    points looked at."""
    cand = np.arange(len(cloud)) if candidates is None else np.asarray(candidates, np.int64)
    f = frame.to_facade(cloud.xyz[cand])
    keep = ((f[:, 0] >= 0) & (f[:, 0] < frame.width) & (f[:, 1] >= 0) & (f[:, 1] < frame.height)
            & (f[:, 2] >= -behind) & (f[:, 2] <= front))
    if exclude is not None:
        keep &= ~exclude[cand]
    sel = np.flatnonzero(keep)
    return cand[sel], f[sel]


def rasterize(cloud: PointCloud, frame: FacadeFrame, *, resolution: float = RESOLUTION,
              threshold: float = 0.05, index: np.ndarray | None = None,
              uvd: np.ndarray | None = None) -> FacadeMaps:
    """The facade's rasters at ``resolution`` m per cell (see the module docstring)."""
    if resolution <= 0:
        raise PointCloudError(f"resolution must be > 0 m, got {resolution}")
    if index is None or uvd is None:
        index, uvd = facade_points(cloud, frame)
    w = max(1, int(np.ceil(frame.width / resolution)))
    h = max(1, int(np.ceil(frame.height / resolution)))
    if w * h > 64_000_000:
        raise PointCloudError(f"{cloud.source}: a {frame.width:.0f} × {frame.height:.0f} m "
                              f"facade at {resolution} m per cell is {w}×{h} cells; pass a "
                              "coarser resolution")
    col = np.clip((uvd[:, 0] / resolution).astype(np.int64), 0, w - 1)
    row = np.clip(h - 1 - (uvd[:, 1] / resolution).astype(np.int64), 0, h - 1)
    cell = row * w + col
    d = uvd[:, 2]
    count = np.bincount(cell, minlength=w * h)
    depth = np.full(w * h, np.nan)
    frontm = np.full(w * h, np.nan)
    backm = np.full(w * h, np.nan)
    if len(cell):
        order = np.lexsort((d, cell))
        cs, ds = cell[order], d[order]
        starts = np.flatnonzero(np.r_[True, cs[1:] != cs[:-1]])
        ends = np.r_[starts[1:], len(cs)]
        cells = cs[starts]
        lo_mid, hi_mid = starts + (ends - starts - 1) // 2, starts + (ends - starts) // 2
        depth[cells] = 0.5 * (ds[lo_mid] + ds[hi_mid])
        frontm[cells] = ds[ends - 1]
        backm[cells] = ds[starts]
    on = np.bincount(cell, weights=(np.abs(d) < threshold).astype(float), minlength=w * h)
    wall = np.divide(on, count, out=np.zeros(w * h), where=count > 0)
    inten = None
    if cloud.intensity is not None:
        s = np.bincount(cell, weights=cloud.intensity[index].astype(float), minlength=w * h)
        inten = np.divide(s, count, out=np.full(w * h, np.nan), where=count > 0).reshape(h, w)
    rgb = None
    if cloud.rgb is not None:
        rgb = np.stack([np.bincount(cell, weights=cloud.rgb[index, k].astype(float),
                                    minlength=w * h) for k in range(3)], -1)
        rgb = np.divide(rgb, count[:, None], out=np.zeros_like(rgb), where=count[:, None] > 0)
        rgb = rgb.reshape(h, w, 3)
    return FacadeMaps(frame=frame, resolution=resolution, depth=depth.reshape(h, w),
                      front=frontm.reshape(h, w), count=count.reshape(h, w),
                      wall=wall.reshape(h, w), intensity=inten, rgb=rgb,
                      back=backm.reshape(h, w))
