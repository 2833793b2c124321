"""Label → image synthesis in the style of a photo (``shang2023`` §3.3), evaluated with numpy.

:func:`synthesize` paints a facade texture from a class-index label map, in the style of a
photo whose labels are known: the paper's "missing texture" case (a user draws the labels) and
the texture of a repaired region.  The network is the paper's, scaled to what trains on two CPU
cores (:mod:`.synthesis_train` trains it with PyTorch; this module needs numpy and OpenCV only):

- **style encoder**: three stride-2 3 × 3 convolutions with LReLU (16, 32, 64 channels), a
  stride-2 transposed convolution and Tanh (32 channels, 1/4 of the input side), then
  region-wise average pooling over each class of the style photo's labels → one 32-d style
  vector per class (paper: 512-d);
- **generator** (SPADE/SEAN, Park et al. 2019, Zhu et al. 2020): a 3 × 3 convolution of the
  label map at 1/32 of the side, seven SEAN ResBlks (head_0, middle_0, middle_1, up_0 … up_3,
  nearest ×2 up-sampling before all but the first and third — SPADE's five up-samplings), LReLU,
  a 3 × 3 convolution to RGB and Tanh.  Channels 64 (first convolution), then 64, 64, 64, 32,
  16, 8, 8 out of the seven blocks (paper: 1024 ×4, 512, 256, 128, 64); SPADE branch 32, 32,
  32, 32, 16, 8, 8 hidden channels (paper: 128).  0.93 M weights; a training step of
  two 128² images took 0.3–1 s on one thread of the shared CPU here (:mod:`.synthesis_train`);
- **SEAN normalisation** (eq. 10–11): parameter-free batch norm (running statistics), then
  ``x̂ · (1 + γ) + β`` with ``γ = α_γ γˢ(S) + (1 − α_γ) γᵒ(M)`` (same for β): ``γᵒ, βᵒ`` are
  3 × 3 convolutions of a ReLU 3 × 3 convolution of the one-hot label map (SPADE), ``γˢ, βˢ``
  1 × 1 convolutions (paper: 3 × 3) of the style map — each class's style vector through its own
  fully connected layer and ReLU, broadcast over the class's region; ``α = sigmoid(a)`` with
  ``a`` trained.  The style enters the first six blocks, the last one is SPADE only.

The network runs on a fixed :attr:`SynthesisSpec.size` × ``size`` square (128 px): the labels
(nearest), the style photo (area) and its labels (nearest) are resized to it, whatever their
aspect, as in training, and the result is resized back to the label map's size (bilinear).  It
is therefore a 128-px texture: fine detail (brick joints, mullions under ~1/128 of the facade)
is not reproduced.

**Class colour matching** (not in the paper; ``synthesize(match_colors=True)``, the default):
the painted texture is shifted, class by class, so that each class's mean colour is the style
photo's mean colour of that class — what the per-class style vectors are meant to carry, made
exact at full resolution.  ``benchmarks/synthesis.py`` reports the network with and without it.

Shipped weights (``sean-cmp12.npz``): 4307 steps of batch 2 in 55 min on one shared CPU
thread.  How they score on CMP val, with and without colour matching, against painting each
class its mean colour and against the paper: ``benchmarks/results/synthesis.json`` (a weak
network — blurry, with generic window and cornice structure).

Weights ship as float16 arrays in ``data/synthesis/*.npz`` named by the PyTorch ``state_dict``
keys, with a JSON document ``__meta__`` (format, spec, how it was trained); they are read with
``allow_pickle=False`` and checked against the spec's shapes (:func:`spec_shapes`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["DEFAULT_WEIGHTS", "SynthesisNetwork", "SynthesisSpec", "load_synthesis",
           "match_class_colors", "spec_shapes", "synthesize"]

#: The shipped weights (trained on the CMP train split, :mod:`.synthesis_train`).
DEFAULT_WEIGHTS = Path(__file__).resolve().parents[1] / "data" / "synthesis" / "sean-cmp12.npz"
FORMAT = "facadeforge-synthesis"

#: Label set the shipped network was trained in.
NATIVE_LABEL_SET = "cmp12"


@dataclass(frozen=True)
class SynthesisSpec:
    """Shape of the network; stored in the weight file's metadata.

    ``gen_channels``: the channels after the generator's first 3 × 3 convolution and after each
    of its seven SEAN ResBlks (head_0, middle_0, middle_1, up_0 … up_3); ``hidden``: the
    channels of the label-map convolution of each block's SPADE branch; ``style_dim``: the
    length of one class's style vector; ``enc_channels``: the style encoder's three
    down-sampling convolutions; ``styled``: how many blocks (the first ones) get the style.
    ``size``: the side of the square the network runs at.
    """

    num_classes: int = 12
    size: int = 128
    gen_channels: tuple[int, ...] = (64, 64, 64, 64, 32, 16, 8, 8)
    hidden: tuple[int, ...] = (32, 32, 32, 32, 16, 8, 8)
    style_dim: int = 32
    enc_channels: tuple[int, ...] = (16, 32, 64)
    styled: int = 6
    style_kernel: int = 1

    #: the generator starts from the label map at 1/32 of the side (SPADE's 5 up-samplings)
    stride: int = 32

    def __post_init__(self):
        ok = (2 <= self.num_classes <= 64 and len(self.gen_channels) == 8
              and len(self.hidden) == 7 and len(self.enc_channels) == 3
              and 0 <= self.styled <= 7 and 1 <= self.style_dim <= 512
              and all(1 <= c <= 1024 for c in (*self.gen_channels, *self.hidden,
                                               *self.enc_channels))
              and self.size % self.stride == 0 and 32 <= self.size <= 2048
              and self.stride == 32 and self.style_kernel in (1, 3))
        if not ok:
            raise ValueError(f"unsupported synthesis network shape {self}")

    def to_json(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_json(cls, d: Mapping) -> SynthesisSpec:
        def tup(key):
            return tuple(int(v) for v in d[key])
        return cls(num_classes=int(d["num_classes"]), size=int(d["size"]),
                   gen_channels=tup("gen_channels"), hidden=tup("hidden"),
                   style_dim=int(d["style_dim"]), enc_channels=tup("enc_channels"),
                   styled=int(d["styled"]), style_kernel=int(d["style_kernel"]))


#: The generator's blocks in order, and whether the feature map is doubled before each.
BLOCKS = ("head_0", "middle_0", "middle_1", "up_0", "up_1", "up_2", "up_3")
UPSAMPLE_BEFORE = (False, True, False, True, True, True, True)


def _block_channels(spec: SynthesisSpec, i: int) -> tuple[int, int, int]:
    """``(fin, fmid, fout)`` of block ``i``."""
    fin, fout = spec.gen_channels[i], spec.gen_channels[i + 1]
    return fin, min(fin, fout), fout


def spec_shapes(spec: SynthesisSpec) -> dict[str, tuple[int, ...]]:
    """Name → shape of every array of a weight file of ``spec`` (PyTorch layouts: convolutions
    ``(out, in, k, k)``, the transposed one ``(in, out, k, k)``)."""
    K, Cs = spec.num_classes, spec.style_dim
    out: dict[str, tuple[int, ...]] = {}

    def conv(name, co, ci, k=3, bias=True):
        out[f"{name}.weight"] = (co, ci, k, k)
        if bias:
            out[f"{name}.bias"] = (co,)

    c = spec.enc_channels
    conv("enc.conv0", c[0], 3)
    conv("enc.conv1", c[1], c[0])
    conv("enc.conv2", c[2], c[1])
    out["enc.tconv.weight"] = (c[2], Cs, 3, 3)
    out["enc.tconv.bias"] = (Cs,)
    conv("gen.fc", spec.gen_channels[0], K)

    def norm(name, ch, hidden, styled):
        out[f"{name}.bn.running_mean"] = (ch,)
        out[f"{name}.bn.running_var"] = (ch,)
        conv(f"{name}.shared", hidden, K)
        conv(f"{name}.gamma", ch, hidden)
        conv(f"{name}.beta", ch, hidden)
        if styled:
            out[f"{name}.fc_w"] = (K, Cs, Cs)
            out[f"{name}.fc_b"] = (K, Cs)
            conv(f"{name}.gamma_s", ch, Cs, spec.style_kernel)
            conv(f"{name}.beta_s", ch, Cs, spec.style_kernel)
            out[f"{name}.alpha_gamma"] = (1,)
            out[f"{name}.alpha_beta"] = (1,)

    for i, name in enumerate(BLOCKS):
        fin, fmid, fout = _block_channels(spec, i)
        b, hidden, styled = f"gen.blocks.{name}", spec.hidden[i], i < spec.styled
        norm(f"{b}.norm_0", fin, hidden, styled)
        conv(f"{b}.conv_0", fmid, fin)
        norm(f"{b}.norm_1", fmid, hidden, styled)
        conv(f"{b}.conv_1", fout, fmid)
        if fin != fout:
            norm(f"{b}.norm_s", fin, hidden, styled)
            conv(f"{b}.conv_s", fout, fin, 1, bias=False)
    conv("gen.conv_img", 3, spec.gen_channels[-1])
    return out


# ----------------------------------------------------------------------------- numpy layers
# Feature maps are channels-first (C, H, W), float32.
def _conv(x: np.ndarray, w: np.ndarray, b: np.ndarray | None, stride: int = 1) -> np.ndarray:
    """Convolution of ``(Ci, H, W)`` by ``w`` ``(Co, Ci, k, k)`` with zero padding ``k // 2``
    (PyTorch's ``Conv2d(padding=k // 2)``), as one matrix product of the shifted copies."""
    co, ci, k, _ = w.shape
    _, H, W = x.shape
    wm = w.transpose(0, 2, 3, 1).reshape(co, k * k * ci)
    if k == 1 and stride == 1:
        out = wm @ x.reshape(ci, H * W)
        Ho, Wo = H, W
    else:
        r = k // 2
        Ho, Wo = (H + 2 * r - k) // stride + 1, (W + 2 * r - k) // stride + 1
        xp = np.zeros((ci, H + 2 * r, W + 2 * r), np.float32)
        xp[:, r:r + H, r:r + W] = x
        cols = np.empty((k, k, ci, Ho, Wo), np.float32)
        for dy in range(k):
            for dx in range(k):
                cols[dy, dx] = xp[:, dy:dy + stride * (Ho - 1) + 1:stride,
                                  dx:dx + stride * (Wo - 1) + 1:stride]
        out = wm @ cols.reshape(k * k * ci, Ho * Wo)
    if b is not None:
        out += b[:, None]
    return out.reshape(co, Ho, Wo)


def _tconv2(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``ConvTranspose2d(k=3, stride=2, padding=1, output_padding=1)`` of ``(Ci, H, W)``, ``w``
    ``(Ci, Co, 3, 3)``: zeros inserted between the pixels, then the flipped kernel."""
    ci, H, W = x.shape
    xd = np.zeros((ci, 2 * H, 2 * W), np.float32)   # dilated, with the one output padding row
    xd[:, 0::2, 0::2] = x
    # padding k-1-p = 1 before, 1 + output_padding after; _conv pads 1 on both sides of the
    # dilated map of side 2H, which is the same as 1 before and 2 after of the side 2H-1
    wf = np.ascontiguousarray(w[:, :, ::-1, ::-1].transpose(1, 0, 2, 3))
    return _conv(xd, wf, b)


def _lrelu(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, np.float32(0.2) * x)


def _up2(x: np.ndarray) -> np.ndarray:
    """Nearest ×2 up-sampling of ``(C, H, W)``."""
    return x.repeat(2, axis=1).repeat(2, axis=2)


class _Labels:
    """The label map at every resolution the network needs: class indices (−1: none) and one-hot
    ``(K, h, w)`` maps, by nearest down-sampling (PyTorch's ``interpolate(mode="nearest")``
    at integer factors: pixel ``i·f``)."""

    def __init__(self, lab: np.ndarray, k: int):
        self.lab, self.k = lab, k
        self._cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def at(self, h: int) -> tuple[np.ndarray, np.ndarray]:
        if h not in self._cache:
            f = self.lab.shape[0] // h
            idx = self.lab[::f, ::f]
            oh = (idx[None] == np.arange(self.k)[:, None, None]).astype(np.float32)
            self._cache[h] = idx, oh
        return self._cache[h]


def _style_vectors(spec: SynthesisSpec, wts: Mapping[str, np.ndarray], rgb: np.ndarray,
                   labels: _Labels) -> np.ndarray:
    """``(K, Cs)`` style vectors of a ``size`` × ``size`` float RGB image in [−1, 1]
    ``(3, S, S)``: encoder, then the mean over each class's pixels (zero for absent
    classes)."""
    x = _lrelu(_conv(rgb, wts["enc.conv0.weight"], wts["enc.conv0.bias"], stride=2))
    x = _lrelu(_conv(x, wts["enc.conv1.weight"], wts["enc.conv1.bias"], stride=2))
    x = _lrelu(_conv(x, wts["enc.conv2.weight"], wts["enc.conv2.bias"], stride=2))
    x = np.tanh(_tconv2(x, wts["enc.tconv.weight"], wts["enc.tconv.bias"]))
    _, oh = labels.at(x.shape[1])
    area = oh.sum((1, 2))
    s = oh.reshape(spec.num_classes, -1) @ x.reshape(x.shape[0], -1).T
    return (s / np.maximum(area, 1.0)[:, None]).astype(np.float32)


def _sean_norm(spec, wts, name, x, labels: _Labels, style, styled):
    idx, oh = labels.at(x.shape[1])
    n = (x - wts[f"{name}.bn.running_mean"][:, None, None]) / np.sqrt(
        wts[f"{name}.bn.running_var"][:, None, None] + np.float32(1e-5))
    a = np.maximum(_conv(oh, wts[f"{name}.shared.weight"], wts[f"{name}.shared.bias"]), 0)
    g = _conv(a, wts[f"{name}.gamma.weight"], wts[f"{name}.gamma.bias"])
    b = _conv(a, wts[f"{name}.beta.weight"], wts[f"{name}.beta.bias"])
    if styled:
        # each class's vector through its own fully connected layer, ReLU (K, Cs)
        v = np.maximum(np.einsum("kc,kcd->kd", style, wts[f"{name}.fc_w"])
                       + wts[f"{name}.fc_b"], 0)
        if spec.style_kernel == 1:   # a 1 × 1 convolution of a broadcast map: per class
            gs_k = v @ wts[f"{name}.gamma_s.weight"][:, :, 0, 0].T   # (K, C)
            bs_k = v @ wts[f"{name}.beta_s.weight"][:, :, 0, 0].T
            gs_k = np.concatenate([gs_k, np.zeros((1, gs_k.shape[1]), np.float32)])
            bs_k = np.concatenate([bs_k, np.zeros((1, bs_k.shape[1]), np.float32)])
            sel = np.where(idx < spec.num_classes, idx, spec.num_classes)
            gs = gs_k[sel].transpose(2, 0, 1) + wts[f"{name}.gamma_s.bias"][:, None, None]
            bs = bs_k[sel].transpose(2, 0, 1) + wts[f"{name}.beta_s.bias"][:, None, None]
        else:
            smap = np.einsum("kd,khw->dhw", v, oh)
            gs = _conv(smap, wts[f"{name}.gamma_s.weight"], wts[f"{name}.gamma_s.bias"])
            bs = _conv(smap, wts[f"{name}.beta_s.weight"], wts[f"{name}.beta_s.bias"])
        ag = 1 / (1 + np.exp(-wts[f"{name}.alpha_gamma"][0]))
        ab = 1 / (1 + np.exp(-wts[f"{name}.alpha_beta"][0]))
        g = ag * gs + (1 - ag) * g
        b = ab * bs + (1 - ab) * b
    return n * (1 + g) + b


def forward(spec: SynthesisSpec, wts: Mapping[str, np.ndarray], labels: np.ndarray,
            style_rgb: np.ndarray, style_labels: np.ndarray) -> np.ndarray:
    """The network on ``size`` × ``size`` inputs: ``labels`` and ``style_labels`` class indices
    (values ≥ K: no class), ``style_rgb`` float32 ``(S, S, 3)`` in [−1, 1]; returns
    ``(S, S, 3)`` float32 in [−1, 1]."""
    K = spec.num_classes
    lab = _Labels(np.asarray(labels), K)
    style = _style_vectors(spec, wts, np.ascontiguousarray(style_rgb.transpose(2, 0, 1),
                                                           np.float32),
                           _Labels(np.asarray(style_labels), K))
    side = lab.lab.shape[0] // spec.stride
    if lab.lab.shape != (side * spec.stride,) * 2:
        raise ValueError(f"the network runs on squares whose side is a multiple of "
                         f"{spec.stride}; got labels of shape {lab.lab.shape}")
    _, oh = lab.at(side)
    x = _conv(oh, wts["gen.fc.weight"], wts["gen.fc.bias"])
    for i, (name, up) in enumerate(zip(BLOCKS, UPSAMPLE_BEFORE)):
        if up:
            x = _up2(x)
        b, styled = f"gen.blocks.{name}", i < spec.styled
        fin, _, fout = _block_channels(spec, i)
        if fin != fout:
            xs = _conv(_sean_norm(spec, wts, f"{b}.norm_s", x, lab, style, styled),
                       wts[f"{b}.conv_s.weight"], None)
        else:
            xs = x
        dx = _conv(_lrelu(_sean_norm(spec, wts, f"{b}.norm_0", x, lab, style, styled)),
                   wts[f"{b}.conv_0.weight"], wts[f"{b}.conv_0.bias"])
        dx = _conv(_lrelu(_sean_norm(spec, wts, f"{b}.norm_1", dx, lab, style, styled)),
                   wts[f"{b}.conv_1.weight"], wts[f"{b}.conv_1.bias"])
        x = xs + dx
    x = np.tanh(_conv(_lrelu(x), wts["gen.conv_img.weight"], wts["gen.conv_img.bias"]))
    return x.transpose(1, 2, 0)


class SynthesisNetwork:
    """A trained label → image network: :attr:`spec`, float32 :attr:`weights`, :attr:`meta`
    (how it was trained)."""

    def __init__(self, spec: SynthesisSpec, weights: Mapping[str, np.ndarray], meta=None,
                 label_set: str = NATIVE_LABEL_SET):
        expected = spec_shapes(spec)
        if set(weights) != set(expected) or any(tuple(np.shape(weights[n])) != s
                                                for n, s in expected.items()):
            raise ValueError("synthesis weights do not match the network shape")
        self.weights = {n: np.ascontiguousarray(weights[n], np.float32) for n in expected}
        if not all(np.isfinite(w).all() for w in self.weights.values()):
            raise ValueError("synthesis weights are not finite")
        self.spec, self.meta, self.label_set = spec, dict(meta or {}), label_set

    def run(self, labels: np.ndarray, style_rgb: np.ndarray,
            style_labels: np.ndarray) -> np.ndarray:
        """:func:`forward` with these weights."""
        return forward(self.spec, self.weights, labels, style_rgb, style_labels)


def load_synthesis(path: str | Path = DEFAULT_WEIGHTS) -> SynthesisNetwork:
    """Read a weight file written by :func:`.synthesis_train.export` (numbers and one JSON
    document; no pickle).

    Raises
    ------
    InputError
        Missing, damaged or foreign file, or weights that do not fit their spec.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"synthesis weights {path}: no such file; train them with "
                         "'python -m facadeforge.repair.synthesis_train -o FILE.npz'")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays.pop("__meta__").tobytes().decode())
        if meta.get("format") != FORMAT:
            raise ValueError("not a facadeforge synthesis file")
        if int(meta.get("version", 0)) > 1:
            raise ValueError(f"format version {meta['version']} is newer than this reads (1)")
        spec = SynthesisSpec.from_json(meta["spec"])
        return SynthesisNetwork(spec, arrays, meta.get("meta", {}),
                                meta.get("label_set", NATIVE_LABEL_SET))
    except (OSError, ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise InputError(f"synthesis weights {path}: unusable ({exc}); train them again with "
                         "'python -m facadeforge.repair.synthesis_train'") from None


@lru_cache(maxsize=2)
def _cached(path: str) -> SynthesisNetwork:
    return load_synthesis(path)


def _as_labels(labels, name: str, label_set: str) -> np.ndarray:
    """A 2-d class-index map of ``label_set`` as cmp12 indices (255: no class)."""
    from ..datasets import IGNORE, convert, get_label_set

    arr = np.asarray(labels)
    if arr.ndim != 2 or min(arr.shape) < 1:
        raise InputError(f"{name}: a 2-d class-index map (H, W) is needed; got an array of "
                         f"shape {arr.shape}")
    source = get_label_set(label_set)
    source.check_indices(arr)
    out = convert(arr, source, NATIVE_LABEL_SET)
    out[out == IGNORE] = 255
    return out


def _as_rgb(rgb, name: str) -> np.ndarray:
    arr = np.asarray(rgb)
    if arr.ndim != 3 or arr.shape[2] != 3 or min(arr.shape[:2]) < 1:
        raise InputError(f"{name}: an RGB image (H, W, 3) is needed; got an array of shape "
                         f"{arr.shape} (convert grey or RGBA photos to RGB first)")
    if arr.dtype != np.uint8:
        if arr.dtype.kind not in "iuf" or not np.isfinite(arr).all():
            raise InputError(f"{name}: uint8 RGB values are needed; got dtype {arr.dtype}")
        if arr.min() < 0 or arr.max() > 255:
            raise InputError(f"{name}: RGB values must lie in 0..255; got "
                             f"{arr.min()}..{arr.max()}")
        arr = np.round(arr).astype(np.uint8)
    return arr


def match_class_colors(image: np.ndarray, labels: np.ndarray, style_rgb: np.ndarray,
                       style_labels: np.ndarray) -> np.ndarray:
    """``image`` (float, labels' size) shifted per class so that each class's mean colour is
    that class's mean colour in the style photo (classes absent from the style: unchanged)."""
    out = image.astype(np.float32).copy()
    k = int(max(labels.max(), style_labels.max())) + 1
    flat_s, flat_l = style_labels.ravel(), labels.ravel()
    n_s = np.bincount(flat_s, minlength=k)
    n_l = np.bincount(flat_l, minlength=k)
    shift = np.zeros((k, 3), np.float32)
    for ch in range(3):
        mean_s = np.bincount(flat_s, style_rgb[..., ch].ravel().astype(np.float64), k)
        mean_l = np.bincount(flat_l, out[..., ch].ravel().astype(np.float64), k)
        ok = (n_s > 0) & (n_l > 0)
        shift[ok, ch] = mean_s[ok] / n_s[ok] - mean_l[ok] / n_l[ok]
    shift[255:] = 0            # unlabelled pixels are left as painted
    return out + shift[labels]


def synthesize(labels: np.ndarray, style_rgb: np.ndarray, style_labels: np.ndarray | None = None,
               *, label_set: str = "cmp12", weights: str | Path | None = None,
               match_colors: bool = True) -> np.ndarray:
    """Paint a facade texture for the label map ``labels`` in the style of the photo
    ``style_rgb`` (``shang2023`` §3.3).

    Parameters
    ----------
    labels : (H, W) int array
        Class indices of ``label_set`` (:data:`~facadeforge.datasets.IGNORE` = no class) — what
        to paint where.  Any size and aspect: the network runs on a 128 × 128 square (module
        docstring) and the result is resized back to ``(H, W)``.
    style_rgb : (Hs, Ws, 3) uint8 array
        The photo whose style (one vector per class, averaged over that class's pixels) is
        used.  Classes of ``labels`` absent from it get the network's default for the class.
    style_labels : (Hs, Ws) int array, optional
        The class indices of ``style_rgb`` in ``label_set``.  When omitted the photo is
        labelled by the shipped CMP convnet classifier (slower, and its mistakes carry over).
    label_set : str
        Label set of ``labels`` and ``style_labels`` (``cmp12``, the network's own; ``cmp6``,
        ``ecp7`` … are converted to ``cmp12`` through canonical labels, so a coarse class such
        as ``wall`` is painted as CMP's plain facade).
    weights : path, optional
        A weight file of :mod:`.synthesis_train`; the shipped ``sean-cmp12.npz`` by default.
    match_colors : bool
        Shift each class's painted pixels so that their mean colour is the class's mean colour
        in the style photo (:func:`match_class_colors`; not in the paper, see the module
        docstring for what it adds).  ``False`` returns the network's output as it is.

    Returns
    -------
    (H, W, 3) uint8 array
        The synthesised texture.

    Raises
    ------
    InputError
        Labels not a 2-d integer map of the label set, ``style_rgb`` not an RGB image,
        ``style_labels`` of another size than ``style_rgb``, unknown label set, or unusable
        weights.
    """
    import cv2

    lab = _as_labels(labels, "labels", label_set)
    style = _as_rgb(style_rgb, "style_rgb")
    if style_labels is None:
        from ..classify.model import load_classifier

        clf = load_classifier(Path(__file__).resolve().parents[1] / "data" / "classifiers"
                              / "convnet-cmp12.npz")
        slab = np.argmax(clf.predict_proba(style), axis=2).astype(np.uint8)
    else:
        slab = _as_labels(style_labels, "style_labels", label_set)
        if slab.shape != style.shape[:2]:
            raise InputError(f"style_labels: shape {slab.shape} differs from the style photo's "
                             f"{style.shape[:2]}; give the labels of that photo")
    net = _cached(str(weights if weights is not None else DEFAULT_WEIGHTS))
    s = net.spec.size
    lab_s = cv2.resize(lab, (s, s), interpolation=cv2.INTER_NEAREST)
    rgb_s = cv2.resize(style, (s, s), interpolation=cv2.INTER_AREA)
    slab_s = cv2.resize(slab, (s, s), interpolation=cv2.INTER_NEAREST)
    out = net.run(lab_s, rgb_s.astype(np.float32) / np.float32(127.5) - 1, slab_s)
    out = np.clip((out + 1) * 127.5, 0, 255)
    h, w = lab.shape
    out = cv2.resize(out, (w, h), interpolation=cv2.INTER_LINEAR)
    if match_colors:
        out = match_class_colors(out, lab, style, slab)
    return np.round(np.clip(out, 0, 255)).astype(np.uint8)
