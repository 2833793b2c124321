"""Colour laser points from calibrated photos, each point from a photo that sees it.

``hohmann2009`` §3 (CityFit): "The color of a point is determined by selecting a suitable
photograph where the point is visible ... and back-projecting the point into the image."
CityFit picks the photo by the scanner's timestamp; here visibility is computed from the cloud
itself, so any set of calibrated photos (VisualSFM cameras, :mod:`facadeforge.datasets.cameras`)
colours any cloud in the same frame:

1. **Z-buffer per photo.**  Every point in front of the camera (depth > ``near``) is projected
   with :meth:`~facadeforge.datasets.cameras.Camera.project` into the photo *as stored* (the
   portrait turn of RueMonge photos is applied by ``Camera``; pixel ``(x, y)`` is column, row,
   integers at pixel centres).  Its depth is splatted over a disc of radius
   ``½ f · point_size / depth`` pixels (the pixels whose centres lie within that radius + ½) (a point covers about its spacing on the surface, so the
   splats close the gaps between neighbouring points and a nearer surface hides what lies
   behind it), keeping the minimum per pixel (``np.minimum.at``).
2. **Visibility.**  A point is visible in the photo when it falls inside the image and its
   depth is within ``max(rel_tolerance · depth, abs_tolerance)`` of the z-buffer at its pixel.
3. **Choice.**  Among the photos that see a point, the most frontal one when the cloud has
   normals (largest ``|cos|`` between normal and the ray to the camera centre), else the
   closest (smallest distance to the camera centre).  The colour is the photo's pixel there.

Points that no photo sees keep their colour (black when the cloud had none);
``extra["coloured"]`` says which points got one.  Units: metres (depth, tolerances,
``point_size``), pixels (radii).  Vectorised: the only loops are over photos and splat offsets.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ..datasets.cameras import Camera
from .cloud import PointCloud, PointCloudError

__all__ = ["colour_from_photos", "point_spacing", "visible_in"]

#: Largest splat radius (pixels): a point nearer than this allows is splatted at it.
MAX_SPLAT_RADIUS = 6


def point_spacing(cloud: PointCloud, sample: int = 20000, seed: int = 0) -> float:
    """Median distance (metres) from a point to its nearest neighbour, over a seeded sample.

    Returns 0.0 for clouds of fewer than two points.
    """
    from scipy.spatial import cKDTree

    xyz = cloud.xyz
    if len(xyz) < 2:
        return 0.0
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(xyz), size=min(sample, len(xyz)), replace=False)
    dist, _ = cKDTree(xyz).query(xyz[pick], k=2)
    return float(np.median(dist[:, 1]))


def visible_in(xyz: np.ndarray, camera: Camera, photo_shape: tuple[int, int], *,
               point_size: float, near: float = 0.1, rel_tolerance: float = 0.02,
               abs_tolerance: float = 0.05,
               max_radius: int = MAX_SPLAT_RADIUS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which points a photo sees, by a z-buffer of the points themselves.

    Parameters
    ----------
    xyz : (N, 3) float64
        Points, metres, in the cameras' frame.
    camera : Camera
    photo_shape : (H, W)
        The stored photo's shape (its pixels are returned).
    point_size : float
        Diameter of a point's splat on the surface, metres (about twice the point spacing).
    near : float
        Points nearer than this along the viewing axis are ignored, metres.
    rel_tolerance, abs_tolerance : float
        A point is visible when its depth exceeds the nearest depth at its pixel by at most
        ``max(rel_tolerance · depth, abs_tolerance)`` (fraction, metres).
    max_radius : int
        Cap of the splat radius, pixels.

    Returns
    -------
    index : (M,) int64
        The visible points.
    pixels : (M, 2) int64
        Their photo pixels (column, row).
    depth : (M,) float64
        Their depth along the camera's viewing axis, metres.
    """
    h, w = int(photo_shape[0]), int(photo_shape[1])
    depth = camera.depth(xyz)
    front = np.flatnonzero(depth > near)
    px = np.rint(camera.project(xyz[front], photo_shape=(h, w)))
    inside = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
    idx, px = front[inside], px[inside].astype(np.int64)
    d = depth[idx].astype(np.float32)
    # a disc of radius ρ covers the pixels whose centres lie within ρ + ½ of its centre
    reach = np.minimum(0.5 * camera.focal * point_size / d.astype(np.float64) + 0.5,
                       max_radius + 0.5)
    order = np.argsort(-reach, kind="stable")            # largest splats first: prefixes below
    col, row, dd, r2 = px[order, 0], px[order, 1], d[order], reach[order] ** 2
    zbuf = np.full(h * w, np.inf, np.float32)
    top = int(np.floor(reach.max(initial=0.0)))
    for dy in range(-top, top + 1):
        for dx in range(-top, top + 1):
            o2 = dx * dx + dy * dy
            if len(r2) == 0 or o2 > r2[0]:
                continue
            k = int(np.searchsorted(-r2, -o2, side="right"))   # points with reach² ≥ o²
            c, r = col[:k] + dx, row[:k] + dy
            ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
            np.minimum.at(zbuf, r[ok] * w + c[ok], dd[:k][ok])
    tol = np.maximum(np.float32(rel_tolerance) * d, np.float32(abs_tolerance))
    seen = d <= zbuf[px[:, 1] * w + px[:, 0]] + tol
    return idx[seen], px[seen], depth[idx[seen]]


def colour_from_photos(cloud: PointCloud, photos: Mapping[str, str | os.PathLike | np.ndarray],
                       cameras: Mapping[str, Camera], *, point_size: float | None = None,
                       near: float = 0.1, rel_tolerance: float = 0.02,
                       abs_tolerance: float = 0.05,
                       max_radius: int = MAX_SPLAT_RADIUS) -> PointCloud:
    """Give each point the colour of the photo that sees it best (module docstring).

    Parameters
    ----------
    cloud : PointCloud
        Points in the cameras' frame (metres).  With ``normals`` the most frontal photo is
        chosen, else the closest.
    photos : dict
        Photo name → image path or (H, W[, C]) array as stored (any dtype
        :func:`facadeforge.photo.as_rgb` takes).
    cameras : dict
        Photo name → :class:`~facadeforge.datasets.cameras.Camera`; every photo needs one
        (extra cameras are ignored).
    point_size : float or None
        Splat diameter on the surface, metres; None: twice :func:`point_spacing`.
    near, rel_tolerance, abs_tolerance, max_radius
        As in :func:`visible_in`.

    Returns
    -------
    PointCloud
        A copy with ``rgb`` (N, 3) uint8 and ``extra["coloured"]`` (N,) bool; points no photo
        sees keep their colour (black when there was none).

    Raises
    ------
    PointCloudError
        No photos, a photo without a camera, an unreadable photo, bad parameters.
    """
    from ..errors import InputError
    from ..photo import as_rgb

    if not photos:
        raise PointCloudError(f"{cloud.source}: no photos to colour the points from; pass "
                              "{name: path or image array}")
    missing = sorted(set(photos) - set(cameras))
    if missing:
        raise PointCloudError(f"photos {missing[:5]} have no camera (cameras: "
                              f"{sorted(cameras)[:5]}…); pass a camera under each photo's name")
    if rel_tolerance < 0 or abs_tolerance < 0 or max_radius < 0:
        raise PointCloudError("rel_tolerance, abs_tolerance and max_radius must be ≥ 0")
    if point_size is None:
        point_size = 2.0 * point_spacing(cloud)
    if not np.isfinite(point_size) or point_size < 0:
        raise PointCloudError(f"point_size must be a finite size ≥ 0 in metres, got {point_size}")
    n = len(cloud)
    rgb = (np.zeros((n, 3), np.uint8) if cloud.rgb is None else cloud.rgb.copy())
    best = np.full(n, -np.inf)
    coloured = np.zeros(n, bool)
    normals = cloud.normals
    for name in sorted(photos):
        try:
            image, _ = as_rgb(photos[name])
        except InputError as exc:
            raise PointCloudError(f"photo {name!r}: {exc}") from exc
        cam = cameras[name]
        idx, px, _ = visible_in(cloud.xyz, cam, image.shape[:2], point_size=point_size,
                                near=near, rel_tolerance=rel_tolerance,
                                abs_tolerance=abs_tolerance, max_radius=max_radius)
        if not len(idx):
            continue
        ray = np.asarray(cam.C, np.float64) - cloud.xyz[idx]
        dist = np.linalg.norm(ray, axis=1)
        if normals is not None:
            score = np.abs(np.einsum("ij,ij->i", normals[idx], ray)) / np.maximum(dist, 1e-12)
        else:
            score = -dist
        better = score > best[idx]
        sel = idx[better]
        best[sel] = score[better]
        rgb[sel] = image[px[better, 1], px[better, 0]]
        coloured[sel] = True
    return replace(cloud, rgb=rgb, extra={**cloud.extra, "coloured": coloured})
