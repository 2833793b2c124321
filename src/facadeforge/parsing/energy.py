"""The image-based facade energy of ``simon2011`` §4.2.2, through integral images.

A layout (the leaf rectangles of one derivation, :class:`~.layout.Layout`) segments the image
into regions R_i with labels c_i; its energy is the negative log-likelihood of that segmentation
under the pixel classifier (eq. 4.5–4.7)::

    E(π) = − Σ_i Σ_{x ∈ R_i} log p(c_i | f_x)

One integral image per class of ``−log p`` makes each rectangle's term four lookups (the thesis
cites Viola & Jones for exactly this), so a layout of n leaves costs O(n) whatever the image size.
Pixels no leaf covers are charged as ``wall`` (the facade plane a split grammar leaves behind).
A leaf's canonical label picks the classifier channel through the label set's fallback chain
(:attr:`~facadeforge.datasets.LabelSet.canonical_map`): a ``cornice`` leaf is scored as ``wall``
by a ``cmp6`` classifier, a ``roof`` leaf as ``background``.
"""

from __future__ import annotations

import numpy as np

from ..datasets import LabelSet
from ..errors import InputError
from .layout import Layout

__all__ = ["SegmentationEnergy"]


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
        h, w = self.shape
        b = layout.boxes
        sx = w / layout.width
        sy = h / layout.height
        c0 = np.clip(np.rint(b[:, 0] * sx), 0, w).astype(np.int64)
        c1 = np.clip(np.rint(b[:, 2] * sx), 0, w).astype(np.int64)
        r0 = np.clip(np.rint((layout.height - b[:, 3]) * sy), 0, h).astype(np.int64)
        r1 = np.clip(np.rint((layout.height - b[:, 1]) * sy), 0, h).astype(np.int64)
        return np.stack([r0, c0, r1, c1], axis=1)

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
