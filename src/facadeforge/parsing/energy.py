"""The image-based facade energy of ``simon2011`` §4.2.2, through integral images.

A layout (the leaf rectangles of one derivation, :class:`~.layout.Layout`) segments the image
into regions R_i with labels c_i; its energy is the negative log-likelihood of that segmentation
under the pixel classifier (eq. 4.5–4.7)::

    E(π) = − Σ_i Σ_{x ∈ R_i} log p(c_i | f_x)

One integral image per class of ``−log p`` makes each rectangle's term four lookups (the thesis
cites Viola & Jones for exactly this), so a layout of n leaves costs O(n) whatever the image size.
Pixels no leaf covers are charged as ``wall`` (the facade plane a split grammar leaves behind).

:class:`DepthEnergy` is the second objective of ``simon2011`` §5.3.2 (eq. 5.9) on a facade's
depth map from a scan (:mod:`facadeforge.points.maps`): the same leaf rectangles, each at the
depth of its label, against the measured depths, up to the mean gap.
A leaf's canonical label picks the classifier channel through the label set's fallback chain
(:attr:`~facadeforge.datasets.LabelSet.canonical_map`): a ``cornice`` leaf is scored as ``wall``
by a ``cmp6`` classifier, a ``roof`` leaf as ``background``.
"""

from __future__ import annotations

import numpy as np

from ..datasets import LabelSet
from ..errors import InputError
from .layout import Layout

__all__ = ["DepthEnergy", "SegmentationEnergy"]


class SegmentationEnergy:
    """Energy of layouts against one facade's class probabilities.

    Parameters
    ----------
    prob : (H, W, K) float
        Class probabilities in the (rectified) facade frame; row 0 is the top of the facade.
    label_set : LabelSet
        The classifier's label set: its classes name the K channels.
    eps : float
        Probabilities are clipped to ``[eps, 1]`` before the logarithm.
    """

    def __init__(self, prob: np.ndarray, label_set: LabelSet, eps: float = 1e-3):
        prob = np.asarray(prob)
        if prob.ndim != 3 or prob.shape[2] != label_set.num_classes or min(prob.shape[:2]) < 2:
            raise InputError(f"probabilities of shape {prob.shape} do not match label set "
                             f"{label_set.name!r} ({label_set.num_classes} classes)")
        self.label_set = label_set
        self.shape = prob.shape[:2]
        cost = -np.log(np.clip(prob, eps, 1.0)).astype(np.float64)
        self.cost = cost   # (H, W, K) per-pixel −log p
        h, w, k = cost.shape
        integral = np.zeros((k, h + 1, w + 1), np.float64)
        integral[:, 1:, 1:] = cost.transpose(2, 0, 1).cumsum(axis=1).cumsum(axis=2)
        self.integral = integral
        self._wall = label_set.index("wall")
        self._wall_total = self.box_cost(self._wall, 0, 0, h, w)
        self._channels: dict[str, int] = {}

    def channel(self, label: str) -> int:
        """Classifier channel a canonical leaf label is scored with."""
        c = self._channels.get(label)
        if c is None:
            c = self._channels[label] = self.label_set.index(label)
        return c

    def pixel_boxes(self, layout: Layout) -> np.ndarray:
        """``(n, 4)`` int pixel boxes ``r0, c0, r1, c1`` (exclusive ends) of the layout's leaves;
        the layout's ``width`` × ``height`` spans the whole image."""
        return _pixel_boxes(layout, self.shape)

    def __call__(self, layout: Layout) -> float:
        """Energy (eq. 4.7) of ``layout``; uncovered pixels are charged as wall."""
        if not len(layout.labels):
            return self._wall_total
        px = self.pixel_boxes(layout)
        ch = np.fromiter((self.channel(lab) for lab in layout.labels), np.int64,
                         len(layout.labels))
        S = self.integral
        r0, c0, r1, c1 = px.T
        costs = S[ch, r1, c1] - S[ch, r0, c1] - S[ch, r1, c0] + S[ch, r0, c0]
        ok = (r1 > r0) & (c1 > c0)
        W = self._wall
        wall_covered = S[W, r1, c1] - S[W, r0, c1] - S[W, r1, c0] + S[W, r0, c0]
        # Split leaves never overlap, so the uncovered rest costs the facade's wall total minus
        # the wall cost of the covered boxes.
        rest = self._wall_total - float(wall_covered[ok].sum())
        return float(costs[ok].sum()) + max(rest, 0.0)

    def box_cost(self, channel: int, r0: int, c0: int, r1: int, c1: int) -> float:
        S = self.integral[channel]
        return float(S[r1, c1] - S[r0, c1] - S[r1, c0] + S[r0, c0])

    def per_pixel(self, energy: float) -> float:
        """Mean ``−log p`` per pixel: energies comparable across image sizes."""
        return energy / (self.shape[0] * self.shape[1])

    def rasterize(self, layout: Layout) -> np.ndarray:
        """``(H, W)`` uint8 label-set class map of the layout (uncovered pixels: wall)."""
        out = np.full(self.shape, self._wall, np.uint8)
        for (r0, c0, r1, c1), lab in zip(self.pixel_boxes(layout), layout.labels):
            out[r0:r1, c0:c1] = self.channel(lab)
        return out


class DepthEnergy:
    """Eq. 5.9: ``E_d(M) = Σ_x (D_M(x) − D_ref(x) − d̄)²`` over the pixels with a measured depth.

    ``D_M`` is the layout's depth map — each leaf at the depth of its label (``depths``, metres,
    negative = recessed; labels not given and uncovered pixels at 0, the wall) — and ``d̄`` the
    mean of ``D_M − D_ref`` ("the goal … is not to have a model with the exact same depth
    profiles as the reference but simply that they match up to a constant gap").  With
    integral images of the valid mask, ``D_ref`` and ``D_ref²`` a leaf of depth ``m`` costs four
    lookups each: ``Σ (m − D)² = m² n − 2 m S₁ + S₂``.  Leaves are taken as a partition (an
    inserted balcony's rectangle counts at the balcony's depth over what it hides).

    Parameters
    ----------
    depth : (H, W) float
        Measured depth per pixel (metres, the facade frame's sign), NaN where nothing was
        measured; row 0 is the top of the facade, the frame of :class:`SegmentationEnergy`.
    depths : mapping
        Depth (m) of each canonical leaf label.
    """

    def __init__(self, depth: np.ndarray, depths: dict[str, float]):
        d = np.asarray(depth, np.float64)
        if d.ndim != 2 or min(d.shape) < 2:
            raise InputError(f"a depth map must be a 2-D array, got shape {d.shape}")
        ok = np.isfinite(d)
        v = np.where(ok, d, 0.0)
        self.shape = d.shape
        self.depths = {str(k): float(x) for k, x in depths.items()}
        h, w = d.shape
        stack = np.stack([ok.astype(np.float64), v, v * v])
        integral = np.zeros((3, h + 1, w + 1))
        integral[:, 1:, 1:] = stack.cumsum(axis=1).cumsum(axis=2)
        self.integral = integral
        self.n_total = float(ok.sum())
        self.s1_total = float(v.sum())
        self.s2_total = float((v * v).sum())

    def __call__(self, layout: Layout, pixel_boxes: np.ndarray | None = None) -> float:
        if self.n_total == 0:
            return 0.0
        if pixel_boxes is None:
            pixel_boxes = _pixel_boxes(layout, self.shape)
        m = np.array([self.depths.get(lab, 0.0) for lab in layout.labels], float)
        if len(m):
            r0, c0, r1, c1 = pixel_boxes.T
            S = self.integral
            n = S[0, r1, c1] - S[0, r0, c1] - S[0, r1, c0] + S[0, r0, c0]
            s1 = S[1, r1, c1] - S[1, r0, c1] - S[1, r1, c0] + S[1, r0, c0]
            good = (r1 > r0) & (c1 > c0) & (m != 0.0)
            m, n, s1 = m[good], n[good], s1[good]
            # every pixel starts at the wall (m = 0): Σ D²; a leaf at m changes it by m² n − 2 m S₁
            sq = self.s2_total + float((m * m * n - 2 * m * s1).sum())
            gap = float((m * n).sum() - self.s1_total) / self.n_total
        else:
            sq, gap = self.s2_total, -self.s1_total / self.n_total
        # Σ (e − d̄)² = Σ e² − N d̄² with e = D_M − D_ref
        return max(sq - self.n_total * gap * gap, 0.0)

    def rasterize(self, layout: Layout) -> np.ndarray:
        """``D_M``: the layout's depth map (metres) in this frame."""
        out = np.zeros(self.shape)
        for (r0, c0, r1, c1), lab in zip(_pixel_boxes(layout, self.shape), layout.labels):
            out[r0:r1, c0:c1] = self.depths.get(lab, 0.0)
        return out


def _pixel_boxes(layout: Layout, shape: tuple[int, int]) -> np.ndarray:
    h, w = shape
    b = layout.boxes
    if not len(b):
        return np.zeros((0, 4), np.int64)
    sx, sy = w / layout.width, h / layout.height
    c0 = np.clip(np.rint(b[:, 0] * sx), 0, w).astype(np.int64)
    c1 = np.clip(np.rint(b[:, 2] * sx), 0, w).astype(np.int64)
    r0 = np.clip(np.rint((layout.height - b[:, 3]) * sy), 0, h).astype(np.int64)
    r1 = np.clip(np.rint((layout.height - b[:, 1]) * sy), 0, h).astype(np.int64)
    return np.stack([r0, c0, r1, c1], axis=1)
