"""The 3D model's labels seen from each calibrated photo (``simon2011`` §5.4.3: "the
classification induced by the 3D semantic layout").

The derived model's triangles (world coordinates, each with its canonical label) are projected
by the photo's camera and z-buffered (:func:`facadeforge.exchange._zbuffer.rasterize`, nearness
``1/z`` as a perspective view needs); a pixel takes the label of the nearest triangle it sees.
Pixels the model does not cover keep the classifier's label of that photo, as the single-view
``parse`` does outside its rectified facade (:meth:`~facadeforge.parsing.parse.Parse.labels_input`),
so single- and multi-view labels are scored on the same pixels; :func:`blend` also lets the
classifier override the model where it is sure, by the same evidence rule.
"""

from __future__ import annotations

import numpy as np

from ..datasets import IGNORE
from ..datasets.cameras import Camera
from ..datasets.labelsets import CANONICAL_INDEX
from ..exchange._zbuffer import rasterize

__all__ = ["blend", "render_labels"]

#: Triangles with a corner nearer than this (world units along the viewing axis) are dropped.
NEAR = 1e-3


def render_labels(triangles: np.ndarray, labels: np.ndarray, camera: Camera,
                  photo_shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Canonical labels ``(H, W)`` uint8 (:data:`IGNORE` where no triangle is seen) and depth
    along the viewing axis (``inf`` there) of triangles ``(T, 3, 3)`` (world) whose canonical
    label indices are ``labels`` ``(T,)``, seen by ``camera`` in a photo of ``photo_shape``."""
    h, w = photo_shape[:2]
    tri = np.asarray(triangles, float).reshape(-1, 3, 3)
    lab = np.asarray(labels, np.uint8).reshape(-1)
    out = np.full(h * w, IGNORE, np.uint8)
    depth = np.full(h * w, np.inf)
    if len(tri):
        z = camera.depth(tri.reshape(-1, 3)).reshape(-1, 3)
        keep = (z > NEAR).all(1)
        tri, z, lab = tri[keep], z[keep], lab[keep]
    if len(tri):
        # Camera.project's pixel (c, r) covers [c, c + 1) × [r, r + 1), as rasterize takes it
        xy = camera.project(tri.reshape(-1, 3), (h, w)).reshape(-1, 3, 2)
        # triangles wholly outside the photo need no rasterising
        lo, hi = xy.min(1), xy.max(1)
        on = (hi[:, 0] >= 0) & (lo[:, 0] <= w) & (hi[:, 1] >= 0) & (lo[:, 1] <= h)
        xy, z, lab = xy[on], z[on], lab[on]
        zbuf, ids = rasterize(xy, 1.0 / z, (w, h))
        hit = ids >= 0
        out[hit] = lab[ids[hit]]
        depth[hit] = 1.0 / zbuf[hit]
    return out.reshape(h, w), depth.reshape(h, w)


def model_label_indices(names) -> np.ndarray:
    """Canonical indices of part label names (unknown names are ``wall``)."""
    return np.array([CANONICAL_INDEX.get(n or "wall", CANONICAL_INDEX["wall"]) for n in names],
                    np.uint8)


def blend(model_labels: np.ndarray, prob: np.ndarray, label_set, evidence: float) -> np.ndarray:
    """The model's canonical labels where the classifier's evidence (``prob``, the photo's
    class probabilities in ``label_set``, any resolution) does not clearly contradict them,
    the classifier's labels where the model is silent (:data:`IGNORE`): the rule of
    :meth:`~facadeforge.parsing.parse.Parse.labels_input`."""
    import cv2

    h, w = model_labels.shape
    p = cv2.resize(prob.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)
    logp = np.log(np.maximum(p.reshape(h, w, -1), 1e-6))
    g = label_set.from_canonical(model_labels)
    best = np.argmax(logp, axis=2)
    own = np.where(g == IGNORE, best, g).astype(np.int64)
    gain = np.take_along_axis(logp, best[..., None], 2)[..., 0] \
        - np.take_along_axis(logp, own[..., None], 2)[..., 0]
    override = (gain > evidence) | (g == IGNORE)
    top = label_set.to_canonical(best.astype(np.uint8))
    return np.where(override, top, model_labels).astype(np.uint8)
