"""Training the facade U-Net of :mod:`.convnet` with PyTorch, on the CPU.

PyTorch is needed for training only; it comes with the ``train`` extra (``make train-env``
builds ``.venv-train`` with it; elsewhere ``pip install 'facadeforge[train]'``).  The
trained network is exported with batch norm folded into its convolutions and saved like every other classifier,
so using it needs numpy alone.

Recipe (the whole of it; seeded, so a model is reproduced by its command up to the
non-determinism of multi-threaded float sums):

- photos resized to the analysis scale (long side 320 px), as the classifier sees them;
- each step draws ``batch`` photos, scales each by a log-uniform factor in [0.75, 1.33], takes a
  random ``crop`` × ``crop`` window (padding with *ignore* where the photo is smaller), flips it
  left–right with probability ½ and jitters brightness and colour;
- with ``augment="street"`` (the street classifier), before that each photo is first warped by a
  random homography (corners moved by up to 10 % of the side: the perspective of a street
  photo that rectification did not undo), given a random exposure (gamma 0.6–1.6, contrast and
  per-channel gain), with probability 0.3 blurred (σ 0.5–1.5 px) and with probability 0.3
  JPEG-compressed (quality 25–85);
- cross-entropy weighted by class frequency^−½ (the forests' sampling rule, :mod:`.train`),
  unlabelled pixels ignored; photos of datasets whose classes are coarser than the network's
  (``partial``, :mod:`.street`) are scored with the partial-label loss
  ``−log Σ_{c ∈ S(d)} p_c``, weighted by the frequency^−½ of the dataset class ``d``;
- AdamW (weight decay 10⁻⁴), one-cycle learning rate peaking at ``lr``.

Because the network sees the pixel's normalised position in the whole photo, crops carry the
position channels of the photo they come from.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..datasets import IGNORE
from ..errors import InputError
from .convnet import ConvNetClassifier, ConvNetSpec, fold_batchnorm, network_input

__all__ = ["require_torch", "train_convnet"]


def require_torch():
    """The ``torch`` module, or an :class:`InputError` saying how to install it."""
    try:
        import torch
    except ImportError:
        raise InputError("training a convnet classifier needs PyTorch; install the train extra "
                         "('make train-env' in a checkout, then run .venv-train/bin/facadeforge; "
                         "or pip install 'facadeforge[train]')") from None
    return torch


def _build(torch, spec: ConvNetSpec, num_classes: int):
    """The PyTorch network of ``spec``; parameter names follow :meth:`ConvNetSpec.shapes`."""
    nn = torch.nn
    F = torch.nn.functional

    def conv_bn(ci, co, k=3):
        return nn.Sequential(nn.Conv2d(ci, co, k, padding=k // 2, bias=False),
                             nn.BatchNorm2d(co), nn.ReLU(inplace=True))

    class Net(nn.Module):
        def __init__(self):
            super().__init__()
            ch = spec.channels
            self.layers = nn.ModuleDict()
            for i, c in enumerate(ch):
                self.layers[f"enc{i}_0"] = conv_bn(spec.in_channels if i == 0 else ch[i - 1], c)
                self.layers[f"enc{i}_1"] = conv_bn(c, c)
                if i in spec.rowcol:
                    self.layers[f"rc{i}"] = conv_bn(3 * c, c, k=1)
            for i in range(len(ch) - 1):
                self.layers[f"dec{i}_0"] = conv_bn(ch[i + 1] + ch[i], ch[i])
                self.layers[f"dec{i}_1"] = conv_bn(ch[i], ch[i])
            self.head = nn.Conv2d(ch[0], num_classes, 1)

        def forward(self, x):
            L = self.layers
            skips = []
            for i in range(len(spec.channels)):
                if i:
                    x = F.max_pool2d(x, 2)
                x = L[f"enc{i}_1"](L[f"enc{i}_0"](x))
                if i in spec.rowcol:
                    rows = x.mean(3, keepdim=True).expand_as(x)
                    cols = x.mean(2, keepdim=True).expand_as(x)
                    x = L[f"rc{i}"](torch.cat([x, rows, cols], 1))
                skips.append(x)
            for i in range(len(spec.channels) - 2, -1, -1):
                x = F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
                x = L[f"dec{i}_1"](L[f"dec{i}_0"](torch.cat([x, skips[i]], 1)))
            return self.head(x)

    return Net()


def export_weights(net) -> dict[str, np.ndarray]:
    """Folded numpy weights of a trained network (see :func:`~.convnet.fold_batchnorm`)."""
    out = {}
    for name, seq in net.layers.items():
        conv, bn = seq[0], seq[1]
        w = conv.weight.detach().cpu().numpy().transpose(2, 3, 1, 0)
        out[f"{name}_w"], out[f"{name}_b"] = fold_batchnorm(
            w, *(t.detach().cpu().numpy() for t in (bn.weight, bn.bias, bn.running_mean,
                                                     bn.running_var)), eps=bn.eps)
    out["head_w"] = net.head.weight.detach().cpu().numpy().transpose(2, 3, 1, 0)
    out["head_b"] = net.head.bias.detach().cpu().numpy()
    return {k: v.astype(np.float32) for k, v in out.items()}


def _crop(x: np.ndarray, lab: np.ndarray, crop: int, rng: np.random.Generator):
    """One augmented ``crop`` × ``crop`` training window of input ``x`` and labels ``lab``."""
    import cv2

    h, w = lab.shape
    s = math.exp(rng.uniform(math.log(0.75), math.log(1.33)))
    H, W = max(16, round(h * s)), max(16, round(w * s))
    x = cv2.resize(x, (W, H), interpolation=cv2.INTER_LINEAR)
    lab = cv2.resize(lab, (W, H), interpolation=cv2.INTER_NEAREST)
    if H < crop or W < crop:
        ph, pw = max(0, crop - H), max(0, crop - W)
        x = np.pad(x, ((0, ph), (0, pw), (0, 0)))
        lab = np.pad(lab, ((0, ph), (0, pw)), constant_values=IGNORE)
        H, W = lab.shape
    y0 = int(rng.integers(0, H - crop + 1))
    x0 = int(rng.integers(0, W - crop + 1))
    x = x[y0:y0 + crop, x0:x0 + crop].copy()
    lab = lab[y0:y0 + crop, x0:x0 + crop].copy()
    if rng.random() < 0.5:
        x = x[:, ::-1].copy()
        x[:, :, 4] *= -1
        lab = lab[:, ::-1].copy()
    x[:, :, :3] = x[:, :, :3] * rng.uniform(0.8, 1.2) + rng.uniform(-0.2, 0.2, 3)
    return x, lab


def _photometric_and_perspective(rgb: np.ndarray, lab: np.ndarray, rng: np.random.Generator):
    """The ``street`` augmentation of one analysis-scale photo and its labels (module docstring)."""
    import cv2

    h, w = lab.shape
    if rng.random() < 0.7:
        src = np.float32([[0, 0], [w, 0], [w, h], [0, h]])
        dst = src + rng.uniform(-0.1, 0.1, (4, 2)).astype(np.float32) * np.float32([w, h])
        H = cv2.getPerspectiveTransform(src, dst)
        rgb = cv2.warpPerspective(rgb, H, (w, h), flags=cv2.INTER_LINEAR,
                                  borderMode=cv2.BORDER_REFLECT_101)
        lab = cv2.warpPerspective(lab, H, (w, h), flags=cv2.INTER_NEAREST,
                                  borderMode=cv2.BORDER_CONSTANT, borderValue=IGNORE)
    x = rgb.astype(np.float32) / 255.0
    x = x ** math.exp(rng.uniform(math.log(0.6), math.log(1.6)))
    x = (x - 0.5) * rng.uniform(0.7, 1.3) + 0.5 + rng.uniform(-0.1, 0.1)
    x = x * rng.uniform(0.85, 1.15, 3)
    rgb = np.clip(x * 255.0, 0, 255).astype(np.uint8)
    if rng.random() < 0.3:
        rgb = cv2.GaussianBlur(rgb, (0, 0), rng.uniform(0.5, 1.5))
    if rng.random() < 0.3:
        ok, buf = cv2.imencode(".jpg", rgb, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(25, 86))])
        if ok:
            rgb = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return rgb, lab


def _partial_labels(labs, partial, k):
    """Dataset labels → global ids into one stacked table of allowed classes, and that table."""
    tables, offsets, out = [], {}, []
    for lab, table in zip(labs, partial):
        table = np.eye(k, dtype=bool) if table is None else np.asarray(table, bool)
        key = (table.shape, table.tobytes())
        if key not in offsets:
            offsets[key] = sum(len(t) for t in tables)
            tables.append(table)
        n = len(table)
        g = np.where(lab < n, lab.astype(np.int64) + offsets[key], IGNORE)
        out.append(g)
    stacked = np.concatenate(tables)
    if len(stacked) >= IGNORE:
        raise InputError(f"{len(stacked)} dataset classes in all; at most {IGNORE - 1}")
    return [g.astype(np.uint8) for g in out], stacked


def train_convnet(smalls: Sequence[np.ndarray], labels: Sequence[np.ndarray], classes,
                  label_set: str, *, spec: ConvNetSpec | None = None, epochs: int = 40,
                  batch: int = 8, crop: int = 224, lr: float = 3e-3, seed: int = 0,
                  threads: int | None = None, progress=None,
                  partial: Sequence[np.ndarray | None] | None = None, augment: str = "basic",
                  repeat: Sequence[int] | None = None, checkpoint=None,
                  meta: dict[str, Any] | None = None) -> ConvNetClassifier:
    """Train the network on analysis-scale photos ``smalls`` (uint8 RGB) and their ``labels``
    (uint8 class indices; values ≥ K are ignored).  One epoch = ``len(smalls) // batch`` steps.

    ``partial``, one entry per photo: ``None`` (label ``k`` is class ``k``) or an ``(n, K)`` bool
    table, row ``d`` the classes a pixel labelled ``d`` may be (:func:`.street.partial_table`).
    ``augment``: ``"basic"`` (scale, crop, flip, colour) or ``"street"`` (also perspective,
    exposure, blur, JPEG).  ``repeat``: how often each photo is drawn per epoch (default once;
    the street classifier draws the photos of a small dataset more often).  ``checkpoint``: a
    function given the classifier so far after every epoch (e.g. to save it).
    """
    torch = require_torch()
    spec = spec or ConvNetSpec()
    k = len(classes)
    if crop < spec.stride or crop % spec.stride:
        raise InputError(f"crop {crop}: use a multiple of {spec.stride} (the network halves its "
                         f"input {len(spec.channels) - 1} times)")
    if len(smalls) < batch:
        raise InputError(f"training needs at least {batch} labelled photos (one batch), got "
                         f"{len(smalls)}")
    torch.manual_seed(seed)
    if threads:
        torch.set_num_threads(threads)
    rng = np.random.default_rng(seed)
    if augment not in ("basic", "street"):
        raise InputError(f"augment {augment!r}: use basic or street")
    if partial is None:
        partial = [None] * len(smalls)
    if len(partial) != len(smalls):
        raise InputError("partial: one table (or None) per photo")
    labs, table = _partial_labels(labels, partial, k)
    g_count = len(table)
    counts = sum(np.bincount(lab[lab < g_count], minlength=g_count) for lab in labs
                 ).astype(np.float64)
    if (table[counts > 0].sum(0) > 0).sum() < 2:
        raise InputError("the training photos have fewer than two labelled classes")
    freq = np.maximum(counts / counts.sum(), 1e-6)
    weight = freq ** -0.5
    weight /= (weight * freq).sum()
    inputs = [network_input(s) for s in smalls] if augment == "basic" else None

    net = _build(torch, spec, k)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    repeat = [1] * len(smalls) if repeat is None else [int(r) for r in repeat]
    if len(repeat) != len(smalls) or min(repeat) < 1:
        raise InputError("repeat: one count >= 1 per photo")
    pool = np.repeat(np.arange(len(smalls)), repeat)
    per_epoch = len(pool) // batch
    total = max(1, epochs * per_epoch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=total,
                                                pct_start=0.1)
    allowed = torch.from_numpy(np.where(table, 0.0, -np.inf).astype(np.float32))   # (G, K)
    g_weight = torch.tensor(weight, dtype=torch.float32)

    def loss_fn(logits, Y):
        logp = torch.log_softmax(logits, 1).permute(0, 2, 3, 1)             # (B, H, W, K)
        valid = Y != IGNORE
        y = Y[valid]
        picked = torch.logsumexp(logp[valid] + allowed[y], 1)
        w = g_weight[y]
        return -(picked * w).sum() / w.sum().clamp_min(1e-6)

    def example(i):
        if inputs is not None:
            return _crop(inputs[i], labs[i], crop, rng)
        rgb, lab = _photometric_and_perspective(smalls[i], labs[i], rng)
        return _crop(network_input(rgb), lab, crop, rng)

    t0 = time.perf_counter()
    net.train()
    step = 0
    for epoch in range(epochs):
        order = pool[rng.permutation(len(pool))]
        total_loss = 0.0
        for b in range(per_epoch):
            xs, ls = zip(*(example(i) for i in order[b * batch:(b + 1) * batch]))
            X = torch.from_numpy(np.stack(xs)).permute(0, 3, 1, 2).contiguous()
            Y = torch.from_numpy(np.stack(ls).astype(np.int64))
            loss = loss_fn(net(X), Y)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            step += 1
            total_loss += float(loss.detach())
        if progress:
            progress(f"epoch {epoch + 1}/{epochs}: loss {total_loss / per_epoch:.3f} "
                     f"({time.perf_counter() - t0:.0f} s)")
        if checkpoint is not None:
            checkpoint(ConvNetClassifier(spec, export_weights(net), tuple(classes), label_set,
                                         {"kind": "convnet", "label_set": label_set,
                                          "epochs": epoch + 1, **(meta or {})}))
    net.train(False)   # inference mode: batch norm uses its running statistics
    info = {"kind": "convnet", "label_set": label_set, "photos": len(smalls), "epochs": epochs,
            "batch": batch, "crop": crop, "lr": lr, "seed": seed, "steps": step,
            "augment": augment, "partial_labels": bool(any(t is not None for t in partial)),
            "class_weights": [round(float(w), 4) for w in weight],
            "seconds": round(time.perf_counter() - t0, 1), "torch": torch.__version__,
            **(meta or {})}
    return ConvNetClassifier(spec, export_weights(net), tuple(classes), label_set, info)
