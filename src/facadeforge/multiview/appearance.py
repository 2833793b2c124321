"""The multi-view appearance evidence of one facade (``simon2011`` §5.3.1, eq. 5.4–5.8), in the
facade's own raster.

The thesis scores a 3D derivation by projecting it into every view and summing, over every
pixel of every image, the negative log-likelihood of the pixel under the class of the voxel it
sees (eq. 5.4, 5.5, 5.7); pixels the model does not explain cost the average over the classes
(eq. 5.6, 5.8), so a model cannot shrink away from what it should explain.  A facade is a plane,
and the grammar's leaves are rectangles on it, so the same sum can be computed once, before the
search, in the facade's orthographic raster (the "virtual orthographic camera" the thesis uses
for depth, §5.3.2):

- every raster cell is mapped into every photo (its centre on the facade plane → the world →
  :meth:`~facadeforge.datasets.cameras.Camera.project`);
- it is **seen** by a photo when it falls inside it, the photo looks at the facade's front, and,
  where the photo has a depth map from the stereo, nothing stands in front of the facade there
  (a tree, a car, a lamp post: the depth map is nearer than the plane by more than
  :data:`OCCLUDER_GAP` metres and :data:`OCCLUDER_SHARE` of the distance);
- a cell covers ``a_k = r² f² cos θ / z²`` pixels of photo ``k`` (``r`` the cell size, ``z``
  the depth, ``θ`` the angle between the ray and the facade's normal), so eq. 5.7's sum over
  pixels becomes, per cell and class ``c``, ``Σ_k a_k · −log p_k(c)``;
- :func:`fuse` returns, per cell, the distribution whose negative log is that weighted sum up to
  a constant per cell (``softmax(Σ_k a_k log p_k / ā)``, ``ā`` the mean coverage of the seen cells):
  :class:`~facadeforge.parsing.energy.SegmentationEnergy` on it is eq. 5.7 restricted to the
  facade, up to a constant that no layout changes;
- cells no photo sees get every class alike: the average cost of eq. 5.6.

The same pass picks, per cell, the photo that sees it largest and unoccluded, and samples its
colour: the facade's texture (an orthophoto from the photos, where a tree in one view is seen
past in another).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..datasets.cameras import Camera
from ..points.maps import FacadeFrame
from .frame import BuildingFrame

__all__ = ["OCCLUDER_GAP", "OCCLUDER_SHARE", "FacadeEvidence", "ViewEvidence", "cell_centres",
           "fuse"]

#: A depth-map pixel nearer than the facade plane by more than this (m) *and* ...
OCCLUDER_GAP = 1.8
#: ... this share of the distance hides the facade there.
OCCLUDER_SHARE = 0.12
#: Weights of one cell are clipped to this many times the mean.
MAX_WEIGHT = 3.0


@dataclass
class ViewEvidence:
    """One calibrated photo with its classifier probabilities (and stereo depth)."""

    id: str
    camera: Camera
    image: np.ndarray                  # (H, W, 3) uint8, as stored
    prob: np.ndarray                   # (h, w, K) class probabilities, any resolution
    depth: np.ndarray | None = None    # (h', w') stereo depth along the viewing axis, world units
    #: depth-map pixels per photo pixel (x, y) when the depth map is smaller than the photo
    depth_scale: tuple[float, float] = (1.0, 1.0)

    @property
    def shape(self) -> tuple[int, int]:
        return self.image.shape[:2]


@dataclass
class FacadeEvidence:
    """What the photos say about one facade's raster cells (rows down)."""

    prob: np.ndarray                   # (h, w, K) fused distribution (module docstring)
    coverage: np.ndarray               # (h, w) photo pixels per cell, all photos
    views: np.ndarray                  # (h, w) number of photos that see the cell
    rgb: np.ndarray                    # (h, w, 3) uint8 texture from the best photo
    best: np.ndarray                   # (h, w) index of that photo, −1 where none sees it
    occluded: np.ndarray               # (h, w) cells every photo looking there sees an occluder in front of


def cell_centres(frame: FacadeFrame, shape: tuple[int, int], resolution: float) -> np.ndarray:
    """Local-frame points ``(h·w, 3)`` of the raster's cell centres on the facade plane (row-major,
    rows down from the top)."""
    h, w = shape
    u = (np.arange(w) + 0.5) * resolution
    v = (h - 1 - np.arange(h) + 0.5) * resolution
    uu, vv = np.meshgrid(u, v)
    return frame.to_cloud(np.c_[uu.ravel(), vv.ravel(), np.zeros(uu.size)])


def _sample(img: np.ndarray, x: np.ndarray, y: np.ndarray, interp=cv2.INTER_LINEAR) -> np.ndarray:
    """Values of ``img`` at continuous pixel coordinates (pixel ``(c, r)`` covers
    ``[c, c + 1) × [r, r + 1)``, :meth:`Camera.project`'s convention): ``(N,)`` or ``(N, C)``."""
    n = int(np.size(x))
    src = img if img.dtype != np.float64 else img.astype(np.float32)
    if src.ndim == 3 and src.shape[2] > 4:      # remap takes at most 4 channels at once
        return np.concatenate([_sample(np.ascontiguousarray(src[..., k:k + 4]), x, y, interp)
                               .reshape(n, -1) for k in range(0, src.shape[2], 4)], axis=-1)
    cols = 4096                                  # remap's maps must stay under 32767 a side
    rows = max(1, -(-n // cols))
    mx = np.full(rows * cols, -1e6, np.float32)
    my = np.full(rows * cols, -1e6, np.float32)
    mx[:n] = np.ravel(x) - 0.5
    my[:n] = np.ravel(y) - 0.5
    out = cv2.remap(src, mx.reshape(rows, cols), my.reshape(rows, cols), interp,
                    borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(rows * cols, -1)[:n] if out.ndim == 3 else out.reshape(-1)[:n]


def fuse(frame: FacadeFrame, shape: tuple[int, int], resolution: float,
         views: list[ViewEvidence], world: BuildingFrame) -> FacadeEvidence:
    """Fuse the photos' class probabilities and colours into one facade's raster (module
    docstring).  ``frame`` is in the local frame of ``world``."""
    h, w = shape
    k = views[0].prob.shape[2] if views else 1
    local = cell_centres(frame, shape, resolution)
    pts = world.to_world(local)
    n_world = frame.n @ world.rotation           # local → world direction (rotation rows)
    logsum = np.zeros((h * w, k))
    cover = np.zeros(h * w)
    nviews = np.zeros(h * w, np.int32)
    best_a = np.zeros(h * w)
    best = np.full(h * w, -1, np.int32)
    rgb = np.zeros((h * w, 3), np.uint8)
    occluded = np.zeros(h * w, bool)
    for vi, view in enumerate(views):
        cam = view.camera
        ph, pw = view.shape
        z = cam.depth(pts)
        ray = pts - cam.C
        dist = np.linalg.norm(ray, axis=1)
        cos = -(ray @ n_world) / np.maximum(dist, 1e-12)
        front = (z > 1e-6) & (cos > 0.05)
        if not front.any():
            continue
        xy = np.full((h * w, 2), -1.0)
        xy[front] = cam.project(pts[front], (ph, pw))
        inside = front & (xy[:, 0] >= 0) & (xy[:, 0] < pw) & (xy[:, 1] >= 0) & (xy[:, 1] < ph)
        idx = np.flatnonzero(inside)
        if not len(idx):
            continue
        if view.depth is not None:
            sx, sy = view.depth_scale
            dz = _sample(view.depth.astype(np.float32), xy[idx, 0] * sx, xy[idx, 1] * sy,
                         cv2.INTER_NEAREST)
            gap = (z[idx] - dz) * world.scale                       # metres
            hidden = np.isfinite(dz) & (dz > 0) & (gap > OCCLUDER_GAP) \
                & (gap > OCCLUDER_SHARE * z[idx] * world.scale)
            occluded[idx[hidden]] = True
            idx = idx[~hidden]
            if not len(idx):
                continue
        a = (cam.focal * resolution / (z[idx] * world.scale)) ** 2 * cos[idx]
        qh, qw = view.prob.shape[:2]
        p = _sample(view.prob.astype(np.float32), xy[idx, 0] * qw / pw, xy[idx, 1] * qh / ph)
        logsum[idx] += a[:, None] * np.log(np.maximum(p.reshape(len(idx), k), 1e-4))
        cover[idx] += a
        nviews[idx] += 1
        better = a > best_a[idx]
        sel = idx[better]
        best_a[sel] = a[better]
        best[sel] = vi
        rgb[sel] = np.clip(_sample(view.image, xy[sel, 0], xy[sel, 1]), 0, 255).astype(np.uint8)
    seen = cover > 0
    prob = np.full((h * w, k), 1.0 / k)
    if seen.any():
        mean_a = float(cover[seen].mean())
        wgt = np.minimum(cover[seen] / mean_a, MAX_WEIGHT)
        mean_log = logsum[seen] / cover[seen, None]
        z = wgt[:, None] * mean_log
        z -= z.max(1, keepdims=True)
        e = np.exp(z)
        prob[seen] = e / e.sum(1, keepdims=True)
    occluded &= ~seen
    return FacadeEvidence(prob=prob.reshape(h, w, k).astype(np.float32),
                          coverage=cover.reshape(h, w), views=nviews.reshape(h, w),
                          rgb=rgb.reshape(h, w, 3), best=best.reshape(h, w),
                          occluded=occluded.reshape(h, w))
