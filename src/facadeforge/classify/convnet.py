"""A small convolutional network for facade pixels, trained here, evaluated with numpy.

The issue asks for "a stronger classifier of your choice trained here" (``simon2011`` §4.3 uses
forests; :mod:`.autocontext` is the forest route).  This is the network route, sized for what
this project has: 240 CMP facades or 90 RueMonge photos, no pretrained weights, two CPU cores.

Architecture (:class:`ConvNetSpec`): a U-Net (Ronneberger et al. 2015) of five levels with
``width · (1, 2, 4, 6, 8)`` channels, two 3 × 3 convolutions (batch norm, ReLU) per level,
2 × 2 max pooling down and bilinear up-sampling with skip connections back.  Two facade-specific
additions:

- **position input**: besides the normalised RGB the network sees the pixel's normalised row and
  column (CoordConv, Liu et al. 2018): sky is on top, shops at the bottom;
- **row/column context** at the two coarsest levels: each feature map is concatenated with its
  means along rows and along columns, then mixed by a 1 × 1 convolution — the network's version of
  the auto-context row and column features (:func:`~.features.context_features`).  A window pixel
  sits in a row and a column of windows; a shop front spans the street level.

Inference (:meth:`ConvNetClassifier.predict_small`) is plain numpy: batch norm is folded into the
convolutions at export (:func:`fold_batchnorm`), and a 3 × 3 convolution is one matrix product
of the nine shifted copies of its input (im2col).  The model file holds only the folded weights (float16) and the spec, like every other
classifier here (:mod:`.model`), so inference needs neither PyTorch nor pickle; training does
(:mod:`.convnet_train`, the ``train`` extra).  The photo is classified at the analysis scale
(:data:`~.features.ANALYSIS_SIDE`) and the probabilities resized back.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import InputError
from .features import analysis_image
from .model import PixelClassifier, register_kind

__all__ = ["ConvNetClassifier", "ConvNetSpec", "fold_batchnorm", "network_input"]

#: Per-channel RGB normalisation of the network input (the usual photo statistics).
RGB_MEAN = np.array([0.485, 0.456, 0.406], np.float32) * 255
RGB_STD = np.array([0.229, 0.224, 0.225], np.float32) * 255

#: Most weights a network may have (the shipped one has 1.0 M).
MAX_PARAMETERS = 20_000_000


@dataclass(frozen=True)
class ConvNetSpec:
    """Shape of the network; stored in the model file's metadata.

    ``width`` is the channel count of the first level, ``multipliers`` of each level;
    ``rowcol`` lists the levels (0 = full resolution) that get row/column context.
    """

    width: int = 16
    multipliers: tuple[int, ...] = (1, 2, 4, 6, 8)
    rowcol: tuple[int, ...] = (3, 4)
    in_channels: int = 5  # normalised RGB + row + column

    def __post_init__(self):
        ok = (1 <= self.width <= 256 and 2 <= len(self.multipliers) <= 7
              and all(1 <= m <= 64 for m in self.multipliers)
              and all(0 <= r < len(self.multipliers) for r in self.rowcol)
              and self.in_channels == 5)
        if not ok:
            raise ValueError(f"unsupported network shape {self}")
        # a model file is untrusted: no spec may ask for more than MAX_PARAMETERS weights
        if sum(int(np.prod(s)) for s in self.shapes(16).values()) > MAX_PARAMETERS:
            raise ValueError(f"network shape {self} has more than {MAX_PARAMETERS} weights")

    @property
    def channels(self) -> tuple[int, ...]:
        return tuple(self.width * m for m in self.multipliers)

    @property
    def stride(self) -> int:
        """Input sides are padded to a multiple of this (one halving per level below the top)."""
        return 2 ** (len(self.multipliers) - 1)

    def shapes(self, num_classes: int) -> dict[str, tuple[int, ...]]:
        """Name → shape of every weight array (convolutions as ``(kh, kw, in, out)``)."""
        ch = self.channels
        out: dict[str, tuple[int, ...]] = {}

        def conv(name, k, ci, co):
            out[f"{name}_w"] = (k, k, ci, co)
            out[f"{name}_b"] = (co,)

        for i, c in enumerate(ch):
            conv(f"enc{i}_0", 3, self.in_channels if i == 0 else ch[i - 1], c)
            conv(f"enc{i}_1", 3, c, c)
            if i in self.rowcol:
                conv(f"rc{i}", 1, 3 * c, c)
        for i in range(len(ch) - 1):
            conv(f"dec{i}_0", 3, ch[i + 1] + ch[i], ch[i])
            conv(f"dec{i}_1", 3, ch[i], ch[i])
        conv("head", 1, ch[0], num_classes)
        return out

    def to_json(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_json(cls, d: Mapping) -> ConvNetSpec:
        return cls(width=int(d["width"]), multipliers=tuple(int(m) for m in d["multipliers"]),
                   rowcol=tuple(int(r) for r in d["rowcol"]),
                   in_channels=int(d.get("in_channels", 5)))


def network_input(rgb: np.ndarray) -> np.ndarray:
    """``(h, w, 5)`` float32 input of an analysis-scale uint8 RGB image: normalised colour, then
    the row and column in [−1, 1] of the whole image."""
    h, w = rgb.shape[:2]
    x = (rgb.astype(np.float32) - RGB_MEAN) / RGB_STD
    yy = ((np.arange(h, dtype=np.float32) + 0.5) / h * 2 - 1)[:, None]
    xx = ((np.arange(w, dtype=np.float32) + 0.5) / w * 2 - 1)[None, :]
    return np.concatenate([x, np.broadcast_to(yy, (h, w))[:, :, None],
                           np.broadcast_to(xx, (h, w))[:, :, None]], axis=2)


def fold_batchnorm(weight: np.ndarray, gamma: np.ndarray, beta: np.ndarray, mean: np.ndarray,
                   var: np.ndarray, eps: float = 1e-5) -> tuple[np.ndarray, np.ndarray]:
    """A bias-free convolution ``(kh, kw, in, out)`` followed by inference-mode batch norm, as one
    convolution with bias."""
    scale = gamma / np.sqrt(var + eps)
    return weight * scale, beta - mean * scale


# ----------------------------------------------------------------------------- numpy layers
# Feature maps are channels-first (C, H, W): the shifted copies of im2col are then whole rows.
def _conv(x: np.ndarray, w: np.ndarray, b: np.ndarray, relu: bool = True) -> np.ndarray:
    """Same-size convolution (zero padding) of ``(Ci, H, W)`` by ``(k, k, Ci, Co)``."""
    k = w.shape[0]
    ci, H, W = x.shape
    co = w.shape[3]
    wm = w.transpose(3, 0, 1, 2).reshape(co, k * k * ci)
    if k == 1:
        out = wm @ x.reshape(ci, H * W)
    else:  # im2col: the k·k shifted copies stacked, then one matrix product
        r = k // 2
        xp = np.zeros((ci, H + 2 * r, W + 2 * r), np.float32)
        xp[:, r:r + H, r:r + W] = x
        cols = np.empty((k * k, ci, H, W), np.float32)
        for dy in range(k):
            for dx in range(k):
                cols[dy * k + dx] = xp[:, dy:dy + H, dx:dx + W]
        out = wm @ cols.reshape(k * k * ci, H * W)
    out += b[:, None]
    if relu:
        np.maximum(out, 0, out=out)
    return out.reshape(co, H, W)


def _pool(x: np.ndarray) -> np.ndarray:
    """2 × 2 max pooling (four strided views: a reduction over interleaved axes is slower)."""
    return np.maximum(np.maximum(x[:, 0::2, 0::2], x[:, 0::2, 1::2]),
                      np.maximum(x[:, 1::2, 0::2], x[:, 1::2, 1::2]))


def _up2(x: np.ndarray) -> np.ndarray:
    """Bilinear ×2 up-sampling of ``(C, H, W)`` with half-pixel centres (PyTorch's
    ``align_corners=False``)."""
    def axis(a, ax):
        n = a.shape[ax]
        prev = np.take(a, np.r_[0, 0:n - 1], axis=ax)
        nxt = np.take(a, np.r_[1:n, n - 1], axis=ax)
        out = np.stack([0.75 * a + 0.25 * prev, 0.75 * a + 0.25 * nxt], axis=ax + 1)
        shape = list(a.shape)
        shape[ax] *= 2
        return out.reshape(shape)
    return axis(axis(x, 1), 2)


def _rowcol(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    rows = np.broadcast_to(x.mean(axis=2, keepdims=True), x.shape)
    cols = np.broadcast_to(x.mean(axis=1, keepdims=True), x.shape)
    return _conv(np.concatenate([x, rows, cols], axis=0), w, b)


def forward(spec: ConvNetSpec, weights: Mapping[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """Class scores ``(H, W, K)`` of input ``x`` ``(H, W, 5)``, sides multiples of the stride."""
    levels = len(spec.channels)
    x = np.ascontiguousarray(x.transpose(2, 0, 1), np.float32)
    skips = []
    for i in range(levels):
        if i:
            x = _pool(x)
        x = _conv(x, weights[f"enc{i}_0_w"], weights[f"enc{i}_0_b"])
        x = _conv(x, weights[f"enc{i}_1_w"], weights[f"enc{i}_1_b"])
        if i in spec.rowcol:
            x = _rowcol(x, weights[f"rc{i}_w"], weights[f"rc{i}_b"])
        skips.append(x)
    for i in range(levels - 2, -1, -1):
        x = np.concatenate([_up2(x), skips[i]], axis=0)
        x = _conv(x, weights[f"dec{i}_0_w"], weights[f"dec{i}_0_b"])
        x = _conv(x, weights[f"dec{i}_1_w"], weights[f"dec{i}_1_b"])
    return _conv(x, weights["head_w"], weights["head_b"], relu=False).transpose(1, 2, 0)


def softmax(scores: np.ndarray) -> np.ndarray:
    e = np.exp(scores - scores.max(axis=2, keepdims=True))
    return e / e.sum(axis=2, keepdims=True)


def pad_to(x: np.ndarray, stride: int) -> np.ndarray:
    """``x`` padded at the bottom and right to sides that are multiples of ``stride``: mirrored
    where the image is larger than the padding, its edge repeated where it is not."""
    h, w = x.shape[:2]
    H, W = -(-h // stride) * stride, -(-w // stride) * stride
    if (H, W) == (h, w):
        return x
    mode = "reflect" if min(h, w) > max(H - h, W - w) else "edge"
    return np.pad(x, ((0, H - h), (0, W - w), (0, 0)), mode=mode)


@register_kind
class ConvNetClassifier(PixelClassifier):
    """The facade U-Net of the module docstring, evaluated with numpy."""

    kind = "convnet"

    def __init__(self, spec: ConvNetSpec, weights: Mapping[str, np.ndarray], classes, label_set,
                 meta=None):
        super().__init__(classes, label_set, meta)
        self.spec = spec
        expected = spec.shapes(len(classes))
        if set(weights) != set(expected) or any(tuple(np.shape(weights[n])) != s
                                                for n, s in expected.items()):
            raise ValueError("network weights do not match the network shape")
        if not all(np.issubdtype(np.asarray(weights[n]).dtype, np.floating) for n in expected):
            raise ValueError("network weights are not floating-point numbers")
        self.weights = {n: np.ascontiguousarray(weights[n], np.float32) for n in expected}
        if not all(np.isfinite(w).all() for w in self.weights.values()):
            raise ValueError("network weights are not finite")
        self.meta["spec"] = spec.to_json()

    def predict_small(self, small: np.ndarray) -> np.ndarray:
        """``(h, w, K)`` probabilities on an analysis-scale uint8 RGB image."""
        if small.ndim != 3 or small.shape[2] != 3:
            raise InputError(f"the convnet classifies RGB images; got an array of shape "
                             f"{small.shape} (convert grey or RGBA photos to RGB first)")
        h, w = small.shape[:2]
        x = pad_to(network_input(small), self.spec.stride)
        return softmax(forward(self.spec, self.weights, x))[:h, :w]

    def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
        return self.predict_small(analysis_image(image))

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {n: w.astype(np.float16) for n, w in self.weights.items()}
        if not all(np.isfinite(w).all() for w in out.values()):
            raise ValueError("network weights overflow float16 (|w| > 65504); the training "
                             "diverged")
        return out

    @classmethod
    def from_arrays(cls, arrays, classes, label_set, meta) -> ConvNetClassifier:
        spec = ConvNetSpec.from_json(meta["spec"])
        names = spec.shapes(len(classes))
        return cls(spec, {n: arrays[n] for n in names}, classes, label_set, meta)
