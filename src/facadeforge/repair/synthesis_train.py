"""Training the label → image network of :mod:`.synthesis` with PyTorch, on the CPU.

PyTorch is needed for training only (the ``train`` extra; ``make train-env`` builds
``.venv-train``).  The trained style encoder and generator are exported as plain float16
arrays named by their PyTorch ``state_dict`` keys plus a JSON document (:func:`export`), read by
:func:`~.synthesis.load_synthesis` with numpy alone.

Objective (eq. 21 of ``shang2023``): hinge GAN loss over two PatchGAN discriminators (full and
half resolution, on the image concatenated with the one-hot labels, instance norm + LReLU),
``λ₁`` feature matching over the discriminators' layers (eq. 24), ``λ₂`` perceptual loss
(eq. 25, see below), ``λ₃`` detail loss (eq. 26–28: L1 of the Gaussian low-pass RGB maps, of the
high-frequency maps grey − low, and of the FFT log-magnitude spectra) and ``λ₄`` regularity loss
(eq. 29: L1 of the differentiable Harris corner maps, eq. 14–18).  All ``λ = 10`` as in the
paper.

Perceptual loss without VGG: no pretrained VGG-16 can be downloaded here.  The features are
those of the repository's own facade segmentation U-Net (``convnet-cmp12.npz``, trained on the
CMP train split), loaded frozen: the outputs of its first three encoder levels (16, 32, 64
channels at 1, 1/2, 1/4 resolution), L1 per level averaged over the elements (eq. 25), the
three levels averaged.  ``perceptual="l1"`` replaces it by an L1 pixel loss, ``"none"`` drops it.

Details of the maps (images in [0, 1] for these losses; the generator works in [−1, 1]):

- low-pass (eq. 12–13): Gaussian σ = 3 px (kernel 19 × 19, reflected borders), per RGB
  channel; high-frequency map: grey − low-pass grey (ITU-R 601 weights);
- spectrum (eq. 19–20): ``log(1 + |FFT(grey)| + 1e-8)`` with the FFT normalised by ``1/(HW)``
  as in eq. 19 — unless ``spectrum_norm="ortho"`` (``1/√(HW)``, see the training log);
- corner map (eq. 14–18): Sobel gradients of the grey image normalised by 1/8, the structure
  tensor smoothed by a 7 × 7 Gaussian of σ = 1, ``R = det − 0.04 · trace²``, ``ω · ReLU(R)``
  with ω = 10⁵.

Discriminators: pix2pixHD's NLayerDiscriminator with 16, 32, 64, 128 channels (paper: 64 …
512) and 4 × 4 kernels, the second on the input average-pooled to half size; no spectral norm.
Optimiser: Adam (β = 0.5, 0.999), learning rates 10⁻³ (encoder + generator) and 4 · 10⁻⁴
(discriminators) — SPADE's 10⁻⁴ / 4 · 10⁻⁴ learn too little in the few thousand steps a CPU
gives; batch 2.  On a CPU shared with other work, run it with ``--threads 1``: PyTorch's
convolutions on these thin feature maps were 5–10 times *slower* with two threads than with one
when the cores were oversubscribed (measured: 8-channel 3 × 3 convolution at 128², 15 ms with
one thread, 96 ms with two).

Data: CMP train facades resized to ``size`` × ``size`` (the network's square), each step a
batch of random ``crop`` × ``crop`` windows after a random scale in [1, 1.25] and a left–right
flip; the style photo is the window itself (the paper's training: the style encoder sees the
ground truth).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import InputError
from .synthesis import BLOCKS, NATIVE_LABEL_SET, UPSAMPLE_BEFORE, SynthesisSpec

__all__ = ["build_networks", "export", "load_into_torch", "train"]

FORMAT = "facadeforge-synthesis"


def require_torch():
    try:
        import torch
    except ImportError:
        raise InputError("training the synthesis network needs PyTorch; install the train "
                         "extra ('make train-env' in a checkout)") from None
    return torch


# ----------------------------------------------------------------------------- networks
def build_networks(torch, spec: SynthesisSpec):
    """``(encoder, generator)`` PyTorch modules of ``spec``."""
    nn = torch.nn
    F = torch.nn.functional
    K, Cs = spec.num_classes, spec.style_dim

    def conv(ci, co, k=3, stride=1, bias=True):
        return nn.Conv2d(ci, co, k, stride=stride, padding=k // 2, bias=bias)

    class StyleEncoder(nn.Module):
        """Three stride-2 conv + LReLU, a stride-2 transposed conv + Tanh (1/4 of the input),
        then region-wise average pooling per class of the style labels: ``(B, K, Cs)``."""

        def __init__(self):
            super().__init__()
            c = spec.enc_channels
            self.conv0 = conv(3, c[0], stride=2)
            self.conv1 = conv(c[0], c[1], stride=2)
            self.conv2 = conv(c[1], c[2], stride=2)
            self.tconv = nn.ConvTranspose2d(c[2], Cs, 3, stride=2, padding=1, output_padding=1)

        def forward(self, img, onehot):
            x = F.leaky_relu(self.conv0(img), 0.2)
            x = F.leaky_relu(self.conv1(x), 0.2)
            x = F.leaky_relu(self.conv2(x), 0.2)
            x = torch.tanh(self.tconv(x))
            m = F.interpolate(onehot, size=x.shape[2:], mode="nearest")
            area = m.sum((2, 3))
            return torch.einsum("bchw,bkhw->bkc", x, m) / area.clamp_min(1.0)[..., None]

    class SEANNorm(nn.Module):
        """Eq. 10–11: parameter-free batch norm, de-normalised by
        ``γ = α_γ γˢ(S) + (1 − α_γ) γᵒ(M)`` (same for β), ``α = sigmoid(trainable)``."""

        def __init__(self, c, hidden, styled):
            super().__init__()
            self.styled = styled
            self.bn = nn.BatchNorm2d(c, affine=False)
            self.shared = conv(K, hidden)
            self.gamma = conv(hidden, c)
            self.beta = conv(hidden, c)
            if styled:
                self.fc_w = nn.Parameter(torch.randn(K, Cs, Cs) / math.sqrt(Cs))
                self.fc_b = nn.Parameter(torch.zeros(K, Cs))
                self.gamma_s = conv(Cs, c, k=spec.style_kernel)
                self.beta_s = conv(Cs, c, k=spec.style_kernel)
                self.alpha_gamma = nn.Parameter(torch.zeros(1))
                self.alpha_beta = nn.Parameter(torch.zeros(1))

        def forward(self, x, onehot, style):
            n = self.bn(x)
            m = F.interpolate(onehot, size=x.shape[2:], mode="nearest")
            a = F.relu(self.shared(m))
            g, b = self.gamma(a), self.beta(a)
            if self.styled:
                v = F.relu(torch.einsum("bkc,kcd->bkd", style, self.fc_w) + self.fc_b)
                smap = torch.einsum("bkd,bkhw->bdhw", v, m)
                ag, ab = torch.sigmoid(self.alpha_gamma), torch.sigmoid(self.alpha_beta)
                g = ag * self.gamma_s(smap) + (1 - ag) * g
                b = ab * self.beta_s(smap) + (1 - ab) * b
            return n * (1 + g) + b

    class Block(nn.Module):
        """SPADE/SEAN residual block: (norm, LReLU, conv) twice, learned shortcut if the
        channel count changes."""

        def __init__(self, fin, fout, hidden, styled):
            super().__init__()
            fmid = min(fin, fout)
            self.learned = fin != fout
            self.norm_0 = SEANNorm(fin, hidden, styled)
            self.conv_0 = conv(fin, fmid)
            self.norm_1 = SEANNorm(fmid, hidden, styled)
            self.conv_1 = conv(fmid, fout)
            if self.learned:
                self.norm_s = SEANNorm(fin, hidden, styled)
                self.conv_s = conv(fin, fout, k=1, bias=False)

        def forward(self, x, onehot, style):
            xs = self.conv_s(self.norm_s(x, onehot, style)) if self.learned else x
            dx = self.conv_0(F.leaky_relu(self.norm_0(x, onehot, style), 0.2))
            dx = self.conv_1(F.leaky_relu(self.norm_1(dx, onehot, style), 0.2))
            return xs + dx

    class Generator(nn.Module):
        def __init__(self):
            super().__init__()
            ch = spec.gen_channels
            self.fc = conv(K, ch[0])
            self.blocks = nn.ModuleDict({
                name: Block(ch[i], ch[i + 1], spec.hidden[i], i < spec.styled)
                for i, name in enumerate(BLOCKS)})
            self.conv_img = conv(ch[-1], 3)

        def forward(self, onehot, style):
            h, w = onehot.shape[2] // spec.stride, onehot.shape[3] // spec.stride
            x = self.fc(F.interpolate(onehot, size=(h, w), mode="nearest"))
            for name, up in zip(BLOCKS, UPSAMPLE_BEFORE):
                if up:
                    x = F.interpolate(x, scale_factor=2, mode="nearest")
                x = self.blocks[name](x, onehot, style)
            return torch.tanh(self.conv_img(F.leaky_relu(x, 0.2)))

    return StyleEncoder(), Generator()


def build_discriminator(torch, in_ch: int, nf: int = 32, layers: int = 3):
    """One PatchGAN (pix2pixHD's NLayerDiscriminator): 4 × 4 convs, stride 2 ``layers`` times,
    instance norm (not on the first) and LReLU; returns every layer's output."""
    nn = torch.nn

    class D(nn.Module):
        def __init__(self):
            super().__init__()
            pad = 2
            seq = [nn.Sequential(nn.Conv2d(in_ch, nf, 4, 2, pad), nn.LeakyReLU(0.2))]
            c = nf
            for i in range(1, layers + 1):
                co = min(c * 2, nf * 8)
                stride = 2 if i < layers else 1
                seq.append(nn.Sequential(nn.Conv2d(c, co, 4, stride, pad),
                                         nn.InstanceNorm2d(co), nn.LeakyReLU(0.2)))
                c = co
            seq.append(nn.Sequential(nn.Conv2d(c, 1, 4, 1, pad)))
            self.seq = nn.ModuleList(seq)

        def forward(self, x):
            out = []
            for m in self.seq:
                x = m(x)
                out.append(x)
            return out

    return D()


# ----------------------------------------------------------------------------- losses
def _gauss1d(torch, sigma: float, radius: int):
    t = torch.arange(-radius, radius + 1, dtype=torch.float32)
    g = torch.exp(-0.5 * (t / sigma) ** 2)
    return g / g.sum()


def _separable(torch, x, g, pad_mode="reflect"):
    """Separable filtering of every channel of ``x`` (B, C, H, W) by the 1-d kernel ``g``."""
    F = torch.nn.functional
    c = x.shape[1]
    r = (len(g) - 1) // 2
    x = F.pad(x, (r, r, r, r), mode=pad_mode)
    kx = g.view(1, 1, 1, -1).repeat(c, 1, 1, 1)
    ky = g.view(1, 1, -1, 1).repeat(c, 1, 1, 1)
    return F.conv2d(F.conv2d(x, kx, groups=c), ky, groups=c)


class Maps:
    """Frequency, spectrum and corner maps of images in [0, 1] (module docstring)."""

    def __init__(self, torch, sigma_low=3.0, spectrum_norm="forward", omega=1e5, k=0.04):
        self.torch = torch
        self.g_low = _gauss1d(torch, sigma_low, int(math.ceil(3 * sigma_low)))
        self.g_win = _gauss1d(torch, 1.0, 3)
        self.spectrum_norm = spectrum_norm
        self.omega, self.k = omega, k
        sx = torch.tensor([[-1., 0., 1.], [-2., 0., 2.], [-1., 0., 1.]]) / 8
        self.sobel = torch.stack([sx, sx.t()])[:, None]        # (2, 1, 3, 3)
        self.grey_w = torch.tensor([0.299, 0.587, 0.114]).view(1, 3, 1, 1)

    def grey(self, x):
        return (x * self.grey_w).sum(1, keepdim=True)

    def low_high(self, x):
        low = _separable(self.torch, x, self.g_low)
        grey = self.grey(x)
        return low, grey - self.grey(low)

    def spectrum(self, x):
        f = self.torch.fft.fft2(self.grey(x), norm=self.spectrum_norm)
        return self.torch.log(1 + self.torch.sqrt(f.real ** 2 + f.imag ** 2 + 1e-8))

    def corners(self, x):
        F = self.torch.nn.functional
        g = F.pad(self.grey(x), (1, 1, 1, 1), mode="replicate")
        d = F.conv2d(g, self.sobel)
        ix, iy = d[:, :1], d[:, 1:]
        m = _separable(self.torch, self.torch.cat([ix * ix, iy * iy, ix * iy], 1), self.g_win)
        xx, yy, xy = m[:, :1], m[:, 1:2], m[:, 2:]
        r = xx * yy - xy * xy - self.k * (xx + yy) ** 2
        return self.omega * F.relu(r)


def unet_features(torch, path=None):
    """The frozen first three encoder levels of the shipped CMP U-Net as a feature function of
    images in [−1, 1] (perceptual loss, module docstring)."""
    from ..classify.convnet import RGB_MEAN, RGB_STD
    from ..classify.model import load_classifier

    F = torch.nn.functional
    if path is None:
        path = Path(__file__).resolve().parents[1] / "data" / "classifiers" / "convnet-cmp12.npz"
    clf = load_classifier(path)
    ws = {n: torch.from_numpy(np.ascontiguousarray(w.transpose(3, 2, 0, 1)))
          if w.ndim == 4 else torch.from_numpy(w) for n, w in clf.weights.items()}
    mean = torch.from_numpy(RGB_MEAN / 255).view(1, 3, 1, 1)
    std = torch.from_numpy(RGB_STD / 255).view(1, 3, 1, 1)

    def features(img):
        b, _, h, w = img.shape
        x = ((img + 1) / 2 - mean) / std
        yy = ((torch.arange(h) + 0.5) / h * 2 - 1).view(1, 1, h, 1).expand(b, 1, h, w)
        xx = ((torch.arange(w) + 0.5) / w * 2 - 1).view(1, 1, 1, w).expand(b, 1, h, w)
        x = torch.cat([x, yy, xx], 1)
        out = []
        for i in range(3):
            if i:
                x = F.max_pool2d(x, 2)
            for j in range(2):
                x = F.relu(F.conv2d(x, ws[f"enc{i}_{j}_w"], ws[f"enc{i}_{j}_b"], padding=1))
            out.append(x)
        return out

    return features


# ----------------------------------------------------------------------------- export
def state_arrays(encoder, generator) -> dict[str, np.ndarray]:
    """Float32 arrays of the encoder (``enc.``) and generator (``gen.``) state, batch-norm
    counters left out."""
    out = {}
    for prefix, net in (("enc.", encoder), ("gen.", generator)):
        for k, v in net.state_dict().items():
            if k.endswith("num_batches_tracked"):
                continue
            out[prefix + k] = v.detach().cpu().numpy().astype(np.float32)
    return out


def export(encoder, generator, spec: SynthesisSpec, path, info: dict) -> Path:
    """Write the weights (float16) and metadata to ``path`` atomically."""
    path = Path(path)
    arrays = {k: v.astype(np.float16) for k, v in state_arrays(encoder, generator).items()}
    if not all(np.isfinite(v).all() for v in arrays.values()):
        raise ValueError("weights overflow float16; the training diverged")
    meta = {"format": FORMAT, "version": 1, "label_set": NATIVE_LABEL_SET,
            "spec": spec.to_json(), "meta": info}
    blob = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".npz", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, __meta__=blob, **arrays)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load_into_torch(torch, spec: SynthesisSpec, arrays) -> tuple:
    """``(encoder, generator)`` in inference mode with the weights ``arrays`` (name → array)."""
    enc, gen = build_networks(torch, spec)
    for prefix, net in (("enc.", enc), ("gen.", gen)):
        state = net.state_dict()
        new = {}
        for k, v in state.items():
            if k.endswith("num_batches_tracked"):
                new[k] = v
            else:
                new[k] = torch.from_numpy(np.asarray(arrays[prefix + k], np.float32))
        net.load_state_dict(new)
        net.train(False)
    return enc, gen


# ----------------------------------------------------------------------------- data
def prepare(samples, size: int):
    """Photos (uint8, size × size × 3) and labels (uint8, size × size) of CMP samples."""
    import cv2

    photos, labels = [], []
    for s in samples:
        photos.append(cv2.resize(s.image(), (size, size), interpolation=cv2.INTER_AREA))
        labels.append(cv2.resize(s.labels(), (size, size), interpolation=cv2.INTER_NEAREST))
    return np.stack(photos), np.stack(labels)


def _window(photo, lab, crop, rng):
    import cv2

    s = math.exp(rng.uniform(0.0, math.log(1.25)))
    n = photo.shape[0]
    m = max(crop, int(round(n * s)))
    if m != n:
        photo = cv2.resize(photo, (m, m), interpolation=cv2.INTER_LINEAR)
        lab = cv2.resize(lab, (m, m), interpolation=cv2.INTER_NEAREST)
    y0, x0 = rng.integers(0, m - crop + 1, 2)
    photo, lab = photo[y0:y0 + crop, x0:x0 + crop], lab[y0:y0 + crop, x0:x0 + crop]
    if rng.random() < 0.5:
        photo, lab = photo[:, ::-1], lab[:, ::-1]
    return np.ascontiguousarray(photo), np.ascontiguousarray(lab)


def one_hot(torch, lab, k):
    """(B, H, W) uint8 class indices → (B, K, H, W) float32; indices ≥ K give zero vectors."""
    lab = torch.from_numpy(np.asarray(lab).astype(np.int64))
    valid = lab < k
    oh = torch.nn.functional.one_hot(torch.where(valid, lab, 0), k).permute(0, 3, 1, 2).float()
    return oh * valid[:, None].float()


# ----------------------------------------------------------------------------- training
def train(photos, labels, out_path, *, spec: SynthesisSpec | None = None, steps: int = 3000,
          minutes: float | None = None, batch: int = 4, crop: int = 128, lr_g: float = 2e-4,
          lr_d: float = 2e-4, lam_fm: float = 10.0, lam_p: float = 10.0, lam_d: float = 10.0,
          lam_r: float = 10.0, perceptual: str = "unet", spectrum_norm: str = "forward",
          d_nf: int = 16, seed: int = 0, threads: int | None = 2, checkpoint_s: float = 240,
          log=print, info: dict | None = None):
    """Train on ``photos`` (N, S, S, 3) uint8 and ``labels`` (N, S, S) uint8 (cmp12 indices,
    255 ignored) and export to ``out_path`` every ``checkpoint_s`` seconds and at the end.
    Stops after ``steps`` steps or ``minutes`` minutes, whichever comes first.  ``lam_d = 0``
    / ``lam_r = 0`` are the ablations of Table 2."""
    torch = require_torch()
    F = torch.nn.functional
    spec = spec or SynthesisSpec()
    if threads:
        torch.set_num_threads(threads)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    K = spec.num_classes
    enc, gen = build_networks(torch, spec)
    ds = [build_discriminator(torch, 3 + K, d_nf) for _ in range(2)]
    opt_g = torch.optim.Adam(list(enc.parameters()) + list(gen.parameters()), lr=lr_g,
                             betas=(0.5, 0.999))
    opt_d = torch.optim.Adam([p for d in ds for p in d.parameters()], lr=lr_d,
                             betas=(0.5, 0.999))
    maps = Maps(torch, spectrum_norm=spectrum_norm)
    feats = unet_features(torch) if perceptual == "unet" else None

    def run_ds(x):
        return [ds[0](x), ds[1](F.avg_pool2d(x, 3, 2, 1, count_include_pad=False))]

    n_g = sum(p.numel() for p in enc.parameters()) + sum(p.numel() for p in gen.parameters())
    n_d = sum(p.numel() for d in ds for p in d.parameters())
    log(f"encoder+generator {n_g} parameters, discriminators {n_d}; spec {spec.to_json()}")
    run = {"spec": spec.to_json(), "batch": batch, "crop": crop, "lr_g": lr_g, "lr_d": lr_d,
           "lambda": {"fm": lam_fm, "perceptual": lam_p, "detail": lam_d,
                      "regularity": lam_r}, "perceptual": perceptual,
           "spectrum_norm": spectrum_norm, "seed": seed, "photos": len(photos),
           "parameters": n_g, **(info or {})}
    t0 = time.perf_counter()
    last_ck = t0
    hist: dict[str, list[float]] = {}
    curve = []
    step = 0
    for step in range(1, steps + 1):
        idx = rng.integers(0, len(photos), batch)
        win = [_window(photos[i], labels[i], crop, rng) for i in idx]
        real = torch.from_numpy(np.stack([w[0] for w in win])).permute(0, 3, 1, 2).float()
        real = real / 127.5 - 1
        oh = one_hot(torch, np.stack([w[1] for w in win]), K)

        # generator step
        for d in ds:
            d.requires_grad_(False)
        fake = gen(oh, enc(real, oh))
        pf = run_ds(torch.cat([fake, oh], 1))
        with torch.no_grad():
            pr = run_ds(torch.cat([real, oh], 1))
        terms = {}
        terms["gan"] = sum(-o[-1].mean() for o in pf)
        terms["fm"] = lam_fm * sum(F.l1_loss(a, b) for of, orr in zip(pf, pr)
                                   for a, b in zip(of[:-1], orr[:-1])) / len(ds)
        if perceptual == "unet":
            with torch.no_grad():
                fr = feats(real)
            ff = feats(fake)
            terms["perc"] = lam_p * sum(F.l1_loss(a, b) for a, b in zip(ff, fr)) / len(ff)
        elif perceptual == "l1":
            terms["perc"] = lam_p * F.l1_loss(fake, real)
        r01, f01 = (real + 1) / 2, (fake + 1) / 2
        if lam_d:
            (lr_, hr), (lf, hf) = maps.low_high(r01), maps.low_high(f01)
            terms["d_low"] = lam_d * F.l1_loss(lf, lr_)
            terms["d_high"] = lam_d * F.l1_loss(hf, hr)
            terms["d_spec"] = lam_d * F.l1_loss(maps.spectrum(f01), maps.spectrum(r01))
        if lam_r:
            terms["reg"] = lam_r * F.l1_loss(maps.corners(f01), maps.corners(r01))
        loss_g = sum(terms.values())
        opt_g.zero_grad()
        loss_g.backward()
        opt_g.step()

        # discriminator step
        for d in ds:
            d.requires_grad_(True)
        pf = run_ds(torch.cat([fake.detach(), oh], 1))
        pr = run_ds(torch.cat([real, oh], 1))
        loss_d = sum(F.relu(1 + a[-1]).mean() + F.relu(1 - b[-1]).mean()
                     for a, b in zip(pf, pr))
        opt_d.zero_grad()
        loss_d.backward()
        opt_d.step()

        terms["D"] = loss_d
        with torch.no_grad():
            terms["l1px"] = F.l1_loss(fake, real) * 127.5
        for k, v in terms.items():
            hist.setdefault(k, []).append(float(v.detach()))
        now = time.perf_counter()
        if step % 10 == 0 or step == 1:
            avg = {k: round(float(np.mean(v[-10:])), 4) for k, v in hist.items()}
            curve.append({"step": step, "s": round(now - t0, 1), **avg})
            log(f"step {step} {now - t0:.0f}s " + " ".join(f"{k} {v:.4g}"
                                                            for k, v in avg.items()))
        done = minutes is not None and now - t0 > 60 * minutes
        if now - last_ck > checkpoint_s or done or step == steps:
            gen.train(False)
            enc.train(False)
            export(enc, gen, spec, out_path, {**run, "steps": step,
                                              "seconds": round(now - t0, 1),
                                              "curve": curve[-200:], "torch": torch.__version__})
            gen.train(True)
            enc.train(True)
            last_ck = now
            log(f"checkpoint {out_path} at step {step}")
        if done:
            break
    return enc, gen


def main(argv=None):
    import argparse

    from ..datasets import cmp_split, load_cmp

    ap = argparse.ArgumentParser(description="train the label → image synthesis network")
    ap.add_argument("--data", default="../shared/data/cmp")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--steps", type=int, default=100000)
    ap.add_argument("--minutes", type=float, default=None)
    ap.add_argument("--batch", type=int, default=2)
    ap.add_argument("--crop", type=int, default=128)
    ap.add_argument("--no-detail", action="store_true")
    ap.add_argument("--no-regularity", action="store_true")
    ap.add_argument("--perceptual", default="unet", choices=["unet", "l1", "none"])
    ap.add_argument("--spectrum-norm", default="ortho", choices=["forward", "ortho"])
    ap.add_argument("--lr-g", type=float, default=2e-4)
    ap.add_argument("--lr-d", type=float, default=2e-4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--checkpoint-s", type=float, default=240)
    args = ap.parse_args(argv)
    spec = SynthesisSpec()
    t = time.perf_counter()
    items = cmp_split(load_cmp(args.data, NATIVE_LABEL_SET), "train")
    photos, labels = prepare(items, spec.size)
    print(f"{len(items)} CMP train facades at {spec.size}² in {time.perf_counter() - t:.0f} s",
          flush=True)
    train(photos, labels, args.output, spec=spec, steps=args.steps, minutes=args.minutes,
          batch=args.batch, crop=args.crop, lr_g=args.lr_g, lr_d=args.lr_d,
          lam_d=0.0 if args.no_detail else 10.0, lam_r=0.0 if args.no_regularity else 10.0,
          perceptual=args.perceptual, spectrum_norm=args.spectrum_norm, seed=args.seed,
          threads=args.threads, checkpoint_s=args.checkpoint_s,
          log=lambda s: print(s, flush=True),
          info={"data": "CMP train split (cmp_split 'train')", "command": " ".join(
              ["python -m facadeforge.repair.synthesis_train", *(argv or __import__(
                  "sys").argv[1:])])})


if __name__ == "__main__":
    main()
