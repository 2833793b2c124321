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
- cross-entropy weighted by class frequency^−½ (the forests' sampling rule, :mod:`.train`),
  unlabelled pixels ignored;
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


def train_convnet(smalls: Sequence[np.ndarray], labels: Sequence[np.ndarray], classes,
                  label_set: str, *, spec: ConvNetSpec | None = None, epochs: int = 40,
                  batch: int = 8, crop: int = 224, lr: float = 3e-3, seed: int = 0,
                  threads: int | None = None, progress=None,
                  meta: dict[str, Any] | None = None) -> ConvNetClassifier:
    """Train the network on analysis-scale photos ``smalls`` (uint8 RGB) and their ``labels``
    (uint8 class indices; values ≥ K are ignored).  One epoch = ``len(smalls) // batch`` steps."""
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
    inputs = [network_input(s) for s in smalls]
    labs = [np.where(lab < k, lab, IGNORE).astype(np.uint8) for lab in labels]
    counts = sum(np.bincount(lab[lab < k], minlength=k) for lab in labs).astype(np.float64)
    if (counts > 0).sum() < 2:
        raise InputError("the training photos have fewer than two labelled classes")
    freq = np.maximum(counts / counts.sum(), 1e-6)
    weight = freq ** -0.5
    weight /= (weight * freq).sum()

    net = _build(torch, spec, k)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    per_epoch = len(inputs) // batch
    total = max(1, epochs * per_epoch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=total,
                                                pct_start=0.1)
    loss_fn = torch.nn.CrossEntropyLoss(weight=torch.tensor(weight, dtype=torch.float32),
                                        ignore_index=IGNORE)
    t0 = time.perf_counter()
    net.train()
    step = 0
    for epoch in range(epochs):
        order = rng.permutation(len(inputs))
        total_loss = 0.0
        for b in range(per_epoch):
            xs, ls = zip(*(_crop(inputs[i], labs[i], crop, rng)
                           for i in order[b * batch:(b + 1) * batch]))
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
    net.train(False)   # inference mode: batch norm uses its running statistics
    info = {"kind": "convnet", "label_set": label_set, "photos": len(smalls), "epochs": epochs,
            "batch": batch, "crop": crop, "lr": lr, "seed": seed, "steps": step,
            "class_weights": [round(float(w), 4) for w in weight],
            "seconds": round(time.perf_counter() - t0, 1), "torch": torch.__version__,
            **(meta or {})}
    return ConvNetClassifier(spec, export_weights(net), tuple(classes), label_set, info)
