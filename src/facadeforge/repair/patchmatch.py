"""Direction-guided PatchMatch (seed ``shang2023`` §3.2): label-map completion and a label-guided
fill of the photo.

§3.2 completes the void region of a semantic label map with a coarse-to-fine PatchMatch (Barnes
et al. 2009) whose patch distance (eq. 3) is

``E(p, v) = E_a(p, v) + λ1 E_p(p, v) + λ2 E_d(v)``,  λ1 = 5e-4, λ2 = 0.5,

- ``E_a`` (eq. 4): a Gaussian-weighted sum of absolute differences between the target patch
  ``T(p)`` and the source patch ``S(p, v) = T(p + v)``, W = 7.  On a label map the per-pixel
  difference is class disagreement (0/1), what the paper's difference of colour-coded labels
  measures.  Only pixels known in the target patch count at first; once the hole holds an estimate
  (after the first pass, and at every finer level) its pixels count too, with confidence
  ``ESTIMATE_CONFIDENCE`` — the usual PatchMatch-inpainting iteration (Wexler et al. 2007).  The
  sum is normalised by the weight that counted, so ``E_a`` is a mean difference in [0, 1] (a
  colour difference is the mean over channels of ``|Δ| / 255``).
- ``E_p`` (eq. 5): ``||v||² / (σ_d(p)² + σ_c²)``, σ_d(p) the distance from p to the hole boundary
  (Euclidean distance transform), ``σ_c = max(w, h) / 8``.
- ``E_d`` (eq. 6) over Θ = {π/2, π}.  The text writes ``min_θ cos(θ_v − θ)``, which as printed is
  smallest (−1) for an offset *opposite* to θ and 0 for one perpendicular to it — it would reward
  diagonals as much as anything.  The intent stated beside it (facade components are distributed
  horizontally and vertically, so horizontal and vertical offsets are preferred) is implemented:
  ``E_d(v) = min_θ (1 − |cos(θ_v − θ)|) = 1 − ||v||_∞ / ||v||_2``, 0 for horizontal or vertical
  offsets, growing to 1 − 1/√2 ≈ 0.29 at 45° (:func:`direction_cost`).

**w, h.**  The paper borrows ``σ_c = max(w, h)/8`` and the initial search radius ``max(w, h)``
from Zhu et al. (2021b) without defining w, h.  Here they are the width and height of the image
at the current pyramid level, as in Huang et al. (2014), where eq. 5 comes from, and as Barnes et
al.'s search radius.  The hole's bounding box was tried as the alternative, with small
differences; with a shallow pyramid (see :func:`_level_count`) the hole's box as σ_c was
clearly worse: for a small hole it makes the proximity cost strong enough to prefer the
nearest wall over the repetition (figures: ``docs/design-measurements.md``).

**Search** (§3.2.2).  A pyramid (labels and guide downsampled ×2 by the mode of each 2 × 2 block,
colour by its mean, the hole by "any pixel unknown"); at each level ``iterations`` passes, each
visiting every target pixel (one whose patch overlaps the hole) and comparing ``E(p, N(p))`` with

1. ``E(p, N(q))`` for its four neighbours q (propagation; passes alternate forward and backward
   scanline order, so good offsets travel both ways);
2. one random candidate for each radius r = max(w, h), r/2, …, 1, drawn with equal chance from
   R(p) — a pixel of the known region within r of p inside the rectangular buffer of half-width
   ``W // 2`` along the horizontal or the vertical line through p (the directions Θ, as in Zhu
   et al. 2021b) — or as a Barnes refinement around the current match, from a rectangle of
   length 2r along one of Θ and width ``2·min(r, W // 2) + 1`` across it.  (Drawing both at every
   radius costs more time for no clear gain: ``docs/design-measurements.md``.)

Sources are known pixels whose whole W × W patch is known and lies inside the image (when no such
patch exists, any known centre whose patch fits; hole pixels of such a patch never vote).  The
coarsest level is initialised with random sources and visits the pixels first in order of their
distance to the hole boundary ("onion peel"), each pixel taking its match's centre as the estimate
at once, so the interior of the hole is matched against the estimate grown from the boundary
rather than against nothing.  A finer level starts from the coarse NNF upsampled ×2 (``N(p) =
2 N(⌊p/2⌋)``, re-drawn where the source is not valid there).

**Output.**  Each pass ends with a vote: every hole pixel q takes, over the target patches that
cover it, the source pixel ``q + N(p)``, weighted by the Gaussian weight of q in the patch of p
and by ``exp(−E(p)/τ)`` (τ the median cost of the hole's patches) — Wexler et al.'s similarity-
weighted vote.  Labels take the weighted majority, colours the weighted mean.  The vote is kept
for the output rather than the best patch's centre: where the NNF is coherent (a region copied with
one offset, which is what propagation produces) every vote agrees and the vote *is* the centre
copy, sharp; where neighbouring offsets disagree, the centre copy leaves seams and isolated wrong
pixels, while the vote settles on the majority (labels) or blends the seam (colour).  The
Gaussian weight favours the patch centred on q, so the blend stays narrow.  The two hardly
differ in practice (``docs/design-measurements.md``): the NNF is coherent almost
everywhere, and the vote is the EM step of every pass anyway.

The inner loops are numba kernels (``@njit(cache=True)``); numba is imported on first use, not with
the module (its import alone takes over a second).  Each kernel is a plain Python function,
registered in ``_KERNELS``, which :func:`_jit` compiles; the plain functions are the reference
implementation that the tests compare the compiled ones against.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["ESTIMATE_CONFIDENCE", "PatchMatchResult", "complete_labels", "direction_cost",
           "fill_guided", "patchmatch"]

#: Weight of a hole pixel's current estimate in the appearance cost (known pixels weigh 1).
ESTIMATE_CONFIDENCE = 0.5
#: σ of the isotropic Gaussian patch weight w_i of eq. 4, as a fraction of the patch size.
GAUSS_SIGMA = 0.25
#: The coarsest pyramid level's smaller side is at least this many pixels.
MIN_LEVEL_SIZE = 32

# ---------------------------------------------------------------------------------------------
# kernels: plain Python, compiled on first use by _jit()

_KERNELS: dict[str, Callable] = {}
# the kernels' random numbers: a 63-bit LCG (Knuth's MMIX multiplier), the same in Python integers
# and in numba's wrapping int64, so that the plain functions reproduce the compiled ones exactly
_LCG_A = 6364136223846793005
_LCG_C = 1442695040888963407
_MASK63 = (1 << 63) - 1


def _kernel(fn: Callable) -> Callable:
    _KERNELS[fn.__name__] = fn
    return fn


@_kernel
def _direction_cost(vy, vx):  # pragma: no cover - compiled
    """Eq. 6 as intended: ``1 − ||v||_∞ / ||v||_2`` (0 on the axes Θ, 1 − 1/√2 at 45°)."""
    ay = abs(vy)
    ax = abs(vx)
    if ay == 0 or ax == 0:
        return 0.0
    return 1.0 - max(ay, ax) / math.sqrt(ay * ay + ax * ax)


@_kernel
def _appearance(col, lab, gde, conf, wk, py, px, sy, sx, inv_nc, gw_n, lab_w,
                budget):  # pragma: no cover - compiled
    """Eq. 4 of the target patch at (py, px) against the source patch at (sy, sx).

    ``conf``-weighted colour (sum over channels of ``|Δ|``, channels pre-scaled so that it is a
    mean) and label (``lab_w`` × disagreement) differences, normalised by ``inv_nc`` = 1 / Σ w c;
    plus the guide disagreement over the whole patch × ``gw_n`` (= guide weight / Σ w).  Target
    pixels outside the image are skipped; the source patch lies inside it.  Stops as soon as the
    sum passes ``budget`` (the caller only wants to know it lost)."""
    h, w = lab.shape
    nch = col.shape[2]
    r = wk.shape[0] // 2
    total = 0.0
    for j in range(2 * r + 1):
        # rows from the centre out (0, 1, −1, 2, …): the heavy rows first, so a losing
        # candidate passes the budget sooner
        dy = (j + 1) // 2 if j % 2 else -(j // 2)
        ty = py + dy
        if ty < 0 or ty >= h:
            continue
        ry = sy + dy
        row = 0.0
        for dx in range(-r, r + 1):
            tx = px + dx
            if tx < 0 or tx >= w:
                continue
            rx = sx + dx
            d = 0.0
            c = conf[ty, tx]
            if c > 0.0:
                e = 0.0
                for k in range(nch):
                    e += abs(np.float64(col[ty, tx, k]) - np.float64(col[ry, rx, k]))
                if lab[ty, tx] != lab[ry, rx]:
                    e += lab_w
                d = c * inv_nc * e
            if gde[ty, tx] != gde[ry, rx]:
                d += gw_n
            row += wk[dy + r, dx + r] * d
        total += row
        if total > budget:
            return total
    return total


@_kernel
def _energy(col, lab, gde, conf, wk, py, px, vy, vx, inv_nc, gw_n, lab_w, lam_p, lam_d, denom,
            budget):  # pragma: no cover - compiled
    """Eq. 3, ``E_a + λ1 E_p + λ2 E_d``, of offset (vy, vx) at (py, px); ``denom`` = σ_d² + σ_c².
    Returns a value above ``budget`` as soon as it is sure to exceed it."""
    extra = lam_p * (vy * vy + vx * vx) / denom + lam_d * _direction_cost(vy, vx)
    if extra > budget:
        return extra
    return extra + _appearance(col, lab, gde, conf, wk, py, px, py + vy, px + vx, inv_nc, gw_n,
                               lab_w, budget - extra)


@_kernel
def _sweep(col, lab, gde, conf, valid, hole, tmask, wk, ty, tx, nnf, cost, sigd2, sigc2, lab_w,
           gw, lam_p, lam_d, radius, band, scan, c_est, seed):  # pragma: no cover - compiled
    """One PatchMatch pass over the targets (ty[k], tx[k]) in the given order.

    Propagation compares the offsets of the four neighbours (§3.2.2: N4(p); in scanline order
    two of them were just visited, which is what makes good offsets travel).  ``scan`` = 0
    marks the onion-peel pass: each hole pixel takes its match's centre as its estimate
    (confidence ``c_est``) right after it is visited.  Updates ``nnf`` (H, W, 2) offsets and
    ``cost`` in place."""
    state = seed & _MASK63
    h, w = lab.shape
    nch = col.shape[2]
    r = wk.shape[0] // 2
    inf = np.inf
    for k in range(ty.shape[0]):
        py = ty[k]
        px = tx[k]
        nw = 0.0
        nc = 0.0
        for dy in range(-r, r + 1):
            yy = py + dy
            if yy < 0 or yy >= h:
                continue
            for dx in range(-r, r + 1):
                xx = px + dx
                if xx < 0 or xx >= w:
                    continue
                nw += wk[dy + r, dx + r]
                nc += wk[dy + r, dx + r] * conf[yy, xx]
        inv_nc = 1.0 / nc if nc > 0.0 else 0.0
        gw_n = gw / nw
        denom = sigd2[py, px] + sigc2
        by = nnf[py, px, 0]
        bx = nnf[py, px, 1]
        best = _energy(col, lab, gde, conf, wk, py, px, by, bx, inv_nc, gw_n, lab_w, lam_p,
                       lam_d, denom, inf)
        # propagation: the offsets of the four neighbours
        for j in range(4):
            qy = py + (-1, 0, 1, 0)[j]
            qx = px + (0, -1, 0, 1)[j]
            if qy < 0 or qy >= h or qx < 0 or qx >= w or not tmask[qy, qx]:
                continue
            vy = nnf[qy, qx, 0]
            vx = nnf[qy, qx, 1]
            if vy == by and vx == bx:
                continue
            sy = py + vy
            sx = px + vx
            if sy < 0 or sy >= h or sx < 0 or sx >= w or not valid[sy, sx]:
                continue
            e = _energy(col, lab, gde, conf, wk, py, px, vy, vx, inv_nc, gw_n, lab_w, lam_p,
                        lam_d, denom, best)
            if e < best:
                best = e
                by = vy
                bx = vx
        # random expansion inside the buffers along Θ, radius halving to 1
        rr = radius
        while rr >= 1:
            for _ in range(1):
                # one LCG step gives three draws: 31 high bits → t, u and the axis
                state = (state * _LCG_A + _LCG_C) & _MASK63
                bits = state >> 32
                t = ((bits & 0x3FFF) * (2 * rr + 1) >> 14) - rr
                if (bits >> 29) & 1:  # R(p): around p, within the band along the horizontal/vertical
                    s = band
                    oy = 0
                    ox = 0
                else:  # refinement around the current match
                    s = min(rr, band)
                    oy = by
                    ox = bx
                u = (((bits >> 14) & 0x3FFF) * (2 * s + 1) >> 14) - s
                if bits >> 30:
                    vy = oy + t
                    vx = ox + u
                else:
                    vy = oy + u
                    vx = ox + t
                if (vy == by and vx == bx) or (vy == 0 and vx == 0):
                    continue
                sy = py + vy
                sx = px + vx
                if sy < 0 or sy >= h or sx < 0 or sx >= w or not valid[sy, sx]:
                    continue
                e = _energy(col, lab, gde, conf, wk, py, px, vy, vx, inv_nc, gw_n, lab_w, lam_p,
                            lam_d, denom, best)
                if e < best:
                    best = e
                    by = vy
                    bx = vx
            rr //= 2
        nnf[py, px, 0] = by
        nnf[py, px, 1] = bx
        cost[py, px] = best
        if scan == 0 and hole[py, px]:
            sy = py + by
            sx = px + bx
            for c in range(nch):
                col[py, px, c] = col[sy, sx, c]
            lab[py, px] = lab[sy, sx]
            conf[py, px] = c_est


@_kernel
def _vote(col, lab, hole, wk, hy, hx, nnf, omega, n_lab):  # pragma: no cover - compiled
    """Wexler vote, in place: each hole pixel q (hy[k], hx[k]) becomes the weighted mean colour
    and the weighted majority label of the source pixels ``q + N(p)`` of the target patches p
    covering it, weight ``wk[q − p] · omega[p]``.  Sources are never hole pixels (a source
    patch's hole pixels, possible only when no fully known patch exists, do not vote; a pixel
    without a vote keeps its estimate), so writing in place reads no new value."""
    h, w = lab.shape
    nch = col.shape[2]
    r = wk.shape[0] // 2
    acc = np.zeros(max(nch, 1))
    hist = np.zeros(n_lab)
    for k in range(hy.shape[0]):
        qy = hy[k]
        qx = hx[k]
        acc[:] = 0.0
        if n_lab > 1:
            hist[:] = 0.0
        wsum = 0.0
        for dy in range(-r, r + 1):
            py = qy - dy
            if py < 0 or py >= h:
                continue
            for dx in range(-r, r + 1):
                px = qx - dx
                if px < 0 or px >= w:
                    continue
                # every p within r of a hole pixel is a target
                sy = qy + nnf[py, px, 0]
                sx = qx + nnf[py, px, 1]
                if hole[sy, sx]:
                    continue
                wt = wk[dy + r, dx + r] * omega[py, px]
                wsum += wt
                for c in range(nch):
                    acc[c] += wt * col[sy, sx, c]
                if n_lab > 1:
                    hist[lab[sy, sx]] += wt
        if wsum > 0.0:
            for c in range(nch):
                col[qy, qx, c] = acc[c] / wsum
            if n_lab > 1:
                best = 0
                for i in range(1, n_lab):
                    if hist[i] > hist[best]:
                        best = i
                lab[qy, qx] = best


@functools.cache
def _jit() -> None:
    """Compile the kernels (numba imported here, not with the module) and bind them in place of
    the plain functions, so that kernels calling kernels call the compiled ones."""
    import numba

    for name, fn in _KERNELS.items():
        globals()[name] = numba.njit(cache=True, nogil=True)(fn)


# ---------------------------------------------------------------------------------------------
# costs, vectorised (documentation and tests; the kernels inline them)

def direction_cost(offsets: np.ndarray) -> np.ndarray:
    """Direction cost of eq. 6 as intended: ``min over θ ∈ {π/2, π} of 1 − |cos(θ_v − θ)|``.

    Parameters
    ----------
    offsets : (..., 2) number
        Offsets ``v = (dy, dx)``.

    Returns
    -------
    (...) float64
        ``1 − ||v||_∞ / ||v||_2``: 0 for horizontal and vertical offsets (and v = 0), largest,
        1 − 1/√2, on the diagonals.
    """
    v = np.abs(np.asarray(offsets, np.float64))
    n = np.hypot(v[..., 0], v[..., 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        out = 1.0 - np.maximum(v[..., 0], v[..., 1]) / n
    return np.where(n > 0, out, 0.0)


# ---------------------------------------------------------------------------------------------
# pyramid

def _even(a: np.ndarray) -> np.ndarray:
    """Pad rows and columns by edge replication to even sizes."""
    ph, pw = a.shape[0] % 2, a.shape[1] % 2
    if ph or pw:
        pad = [(0, ph), (0, pw)] + [(0, 0)] * (a.ndim - 2)
        a = np.pad(a, pad, mode="edge")
    return a


def _blocks(a: np.ndarray) -> tuple[np.ndarray, ...]:
    a = _even(a)
    return a[0::2, 0::2], a[0::2, 1::2], a[1::2, 0::2], a[1::2, 1::2]


def _down_hole(hole: np.ndarray) -> np.ndarray:
    a, b, c, d = _blocks(hole)
    return a | b | c | d


def _down_mode(lab: np.ndarray) -> np.ndarray:
    """Mode of each 2 × 2 block (ties: the first of the block in raster order)."""
    b = np.stack(_blocks(lab))
    counts = (b[:, None] == b[None, :]).sum(axis=1)
    return np.take_along_axis(b, counts.argmax(axis=0)[None], axis=0)[0]


def _down_mean(col: np.ndarray) -> np.ndarray:
    a, b, c, d = _blocks(col)
    return ((a + b + c + d) * 0.25).astype(np.float32)


def _sources(hole: np.ndarray, patch: int) -> np.ndarray:
    """Valid source centres: the whole patch inside the image and known; when there is none, a
    known centre with the patch inside the image."""
    from scipy import ndimage

    r = patch // 2
    inner = np.zeros(hole.shape, bool)
    if hole.shape[0] > 2 * r and hole.shape[1] > 2 * r:
        inner[r:hole.shape[0] - r, r:hole.shape[1] - r] = True
    full = inner & ~ndimage.maximum_filter(hole, size=patch, mode="constant", cval=False)
    return full if full.any() else inner & ~hole


def _level_count(hole: np.ndarray, patch: int, levels: int | None) -> int:
    """Pyramid levels: as asked (``levels``), or automatically as many as fit; never a level
    smaller than ``MIN_LEVEL_SIZE`` px or one without a valid source.

    Deep pyramids pay even for small holes: the coarse levels are what sees the facade's
    repetition (a 7 × 7 patch at 1/8 scale spans 56 px), and a hidden window's extent is decided
    there.  On a window grid, stopping once the hole is two patches wide instead lost 10–40 % of
    inside-hole label accuracy on holes hiding whole windows."""
    n = 1
    h = hole
    while levels is None or n < levels:
        h2 = _down_hole(h)
        if min(h2.shape) < max(MIN_LEVEL_SIZE, patch) or h2.all() or not _sources(h2, patch).any():
            break
        n += 1
        h = h2
    return n


# ---------------------------------------------------------------------------------------------
# the search

@dataclass(frozen=True)
class PatchMatchResult:
    """What :func:`patchmatch` found at the finest level.

    Attributes
    ----------
    colour : (H, W, C) float32
        The colour features with hole pixels replaced by the vote.
    labels : (H, W) int32
        The label features with hole pixels replaced by the vote (majority).
    offsets : (H, W, 2) int32
        The NNF ``N(p) = (dy, dx)`` for target pixels (those whose patch overlaps the hole),
        zero elsewhere; ``p + N(p)`` is a valid source.
    cost : (H, W) float32
        ``E(p, N(p))`` for target pixels, 0 elsewhere.
    levels : int
        Pyramid levels used.
    """

    colour: np.ndarray
    labels: np.ndarray
    offsets: np.ndarray
    cost: np.ndarray
    levels: int


@dataclass
class _Level:
    col: np.ndarray   # (H, W, C) float32, hole pixels = current estimate
    lab: np.ndarray   # (H, W) int32
    gde: np.ndarray   # (H, W) int32
    hole: np.ndarray  # (H, W) bool


def _gauss(patch: int) -> np.ndarray:
    r = patch // 2
    y = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (y / (GAUSS_SIGMA * patch)) ** 2)
    k = np.outer(g, g)
    return (k / k.sum()).astype(np.float64)


def _vote_into(lv: _Level, wk, ty, tx, hy, hx, nnf, cost, n_lab: int) -> None:
    """Replace the hole's estimate by the similarity-weighted vote of the target patches,
    ``omega = exp(−E / τ)``, τ the median cost of the targets (Wexler et al. 2007)."""
    c = cost[ty, tx]
    tau = max(float(np.median(c)), 1e-3)
    omega = np.zeros(cost.shape, np.float64)
    omega[ty, tx] = np.exp(-c / tau)
    _vote(lv.col, lv.lab, lv.hole, wk, hy, hx, nnf, omega, n_lab)


def _boundary_distance2(hole: np.ndarray, hy: np.ndarray, hx: np.ndarray) -> np.ndarray:
    """σ_d(p)² of eq. 5: squared distance from each hole pixel to the nearest known pixel (0
    outside the hole), computed on the hole's bounding box grown by one pixel (the ring around it
    is known wherever it lies inside the image, so nothing nearer lies outside the box)."""
    from scipy import ndimage

    h, w = hole.shape
    y0, y1 = max(int(hy.min()) - 1, 0), min(int(hy.max()) + 2, h)
    x0, x1 = max(int(hx.min()) - 1, 0), min(int(hx.max()) + 2, w)
    out = np.zeros(hole.shape, np.float64)
    d = ndimage.distance_transform_edt(hole[y0:y1, x0:x1])
    out[y0:y1, x0:x1] = d * d
    return out


def _random_sources(valid: np.ndarray, n: int, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``n`` valid source centres drawn uniformly (by rejection, then from the list of valid
    centres for the few left: listing them all is what large images with small holes can't
    afford)."""
    h, w = valid.shape
    sy = np.zeros(n, np.int64)
    sx = np.zeros(n, np.int64)
    todo = np.arange(n)
    for _ in range(8):
        if not todo.size:
            return sy, sx
        y = rng.integers(0, h, todo.size)
        x = rng.integers(0, w, todo.size)
        ok = valid[y, x]
        sy[todo[ok]], sx[todo[ok]] = y[ok], x[ok]
        todo = todo[~ok]
    if todo.size:
        vy, vx = np.nonzero(valid)
        pick = rng.integers(0, vy.size, todo.size)
        sy[todo], sx[todo] = vy[pick], vx[pick]
    return sy, sx


def _targets(hole: np.ndarray, patch: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from scipy import ndimage

    tmask = ndimage.maximum_filter(hole, size=patch, mode="constant", cval=False)
    ty, tx = np.nonzero(tmask)
    return tmask, ty.astype(np.int32), tx.astype(np.int32)


def patchmatch(colour: np.ndarray, labels: np.ndarray, guide: np.ndarray, hole: np.ndarray, *,
               label_weight: float, guide_weight: float, patch: int = 7,
               lambda_p: float = 5e-4, lambda_d: float = 0.5, iterations: int = 5,
               levels: int | None = None, seed: int = 0) -> PatchMatchResult:
    """Coarse-to-fine direction-guided PatchMatch (§3.2) on generic features; the core of
    :func:`complete_labels` and :func:`fill_guided`.

    Parameters
    ----------
    colour : (H, W, C) float32
        Colour features, C ≥ 0 (C = 0: none), scaled so that the sum over channels of ``|Δ|`` is
        the per-pixel difference (e.g. RGB / (255 · 3)).  Hole pixels are ignored.
    labels : (H, W) int32
        Compact class indices 0 … K − 1 compared 0/1 with weight ``label_weight`` where known
        (or estimated).  Hole pixels are ignored.
    guide : (H, W) int32
        Class indices known everywhere, compared 0/1 over the whole patch with weight
        ``guide_weight``.
    hole : (H, W) bool
        True = unknown; some pixel must be known.
    patch, lambda_p, lambda_d, iterations, levels, seed
        As in :func:`complete_labels`.

    Returns
    -------
    PatchMatchResult
    """
    hole = np.asarray(hole)
    if colour.ndim != 3 or not (colour.shape[:2] == labels.shape == guide.shape == hole.shape):
        raise InputError(f"patchmatch: colour {colour.shape}, labels {labels.shape}, guide "
                         f"{guide.shape} and hole {hole.shape} must share (H, W); pass arrays "
                         f"of the same image")
    _check_common(hole, labels.shape, patch, lambda_p, lambda_d, iterations, levels)
    fine = _Level(np.ascontiguousarray(colour, np.float32).copy(),
                  np.ascontiguousarray(labels, np.int32).copy(),
                  np.ascontiguousarray(guide, np.int32), hole)
    if not hole.any():
        zero = np.zeros(hole.shape, np.float32)
        return PatchMatchResult(fine.col, fine.lab, np.zeros(hole.shape + (2,), np.int32), zero, 1)
    if fine.lab[~hole].min() < 0:
        raise InputError("labels: class indices must be ≥ 0 (renumber them, e.g. with "
                         "np.unique(..., return_inverse=True))")
    n_lab = int(fine.lab[~hole].max()) + 1
    _jit()
    n_levels = _level_count(hole, patch, levels)
    pyramid = [fine]
    for _ in range(n_levels - 1):
        lv = pyramid[-1]
        pyramid.append(_Level(_down_mean(lv.col), _down_mode(lv.lab), _down_mode(lv.gde),
                              _down_hole(lv.hole)))
    rng = np.random.default_rng(seed)
    wk = _gauss(patch)
    r = patch // 2
    band = max(1, r)
    nnf = cost = None
    prev = None
    for li in range(n_levels - 1, -1, -1):
        lv = pyramid[li]
        h, w = lv.hole.shape
        valid = _sources(lv.hole, patch)
        if not valid.any():
            raise InputError(f"hole: it leaves no {patch} × {patch} patch of known pixels inside "
                             f"the image to copy from; use a smaller patch or a smaller hole")
        tmask, ty, tx = _targets(lv.hole, patch)
        hy, hx = (a.astype(np.int32) for a in np.nonzero(lv.hole))
        sigd2 = _boundary_distance2(lv.hole, hy, hx)
        # w, h of eq. 5 and §3.2.2: the image's width and height at this level (module docstring)
        sigc2 = (max(h, w) / 8.0) ** 2
        radius = max(h, w)
        # initial NNF: random valid sources, or the coarser level's offsets ×2 where still valid
        sy, sx = _random_sources(valid, ty.size, rng)
        vy, vx = sy - ty, sx - tx
        conf = np.where(lv.hole, 0.0, 1.0).astype(np.float64)
        if prev is not None:
            pnnf, ptmask = prev
            cy, cx = ty // 2, tx // 2
            has = ptmask[cy, cx]
            uy = 2 * pnnf[cy, cx, 0]
            ux = 2 * pnnf[cy, cx, 1]
            sy, sx = ty + uy, tx + ux
            ok = has & (sy >= 0) & (sy < h) & (sx >= 0) & (sx < w)
            ok[ok] = valid[sy[ok], sx[ok]]
            vy = np.where(ok, uy, vy)
            vx = np.where(ok, ux, vx)
        nnf = np.zeros((h, w, 2), np.int32)
        nnf[ty, tx, 0] = vy
        nnf[ty, tx, 1] = vx
        cost = np.zeros((h, w), np.float64)
        gw = float(guide_weight)
        lw = float(label_weight)
        args = (valid, lv.hole, tmask, wk)
        common = (sigd2, sigc2, lw, gw, float(lambda_p), float(lambda_d), radius, band)
        if prev is not None:
            # the estimate: the vote of the upsampled NNF, scored on known pixels only
            _score(lv, conf, wk, ty, tx, nnf, cost, common)
            _vote_into(lv, wk, ty, tx, hy, hx, nnf, cost, n_lab)
            conf[lv.hole] = ESTIMATE_CONFIDENCE
        for it in range(iterations):
            if prev is None and it == 0:
                scan, order = 0, np.lexsort((tx, ty, sigd2[ty, tx]))
            elif it % 2 == 0:
                scan, order = 1, slice(None)
            else:
                scan, order = -1, slice(None, None, -1)
            oy = np.ascontiguousarray(ty[order])
            ox = np.ascontiguousarray(tx[order])
            _sweep(lv.col, lv.lab, lv.gde, conf, *args, oy, ox, nnf, cost, *common, scan,
                   ESTIMATE_CONFIDENCE, int(rng.integers(0, 2**31 - 1)))
            _vote_into(lv, wk, ty, tx, hy, hx, nnf, cost, n_lab)
            conf[lv.hole] = ESTIMATE_CONFIDENCE
        prev = (nnf, tmask)
    return PatchMatchResult(fine.col, fine.lab, nnf, cost.astype(np.float32), n_levels)


def _score(lv: _Level, conf, wk, ty, tx, nnf, cost, common) -> None:
    """``cost`` of the current NNF (a pass with no candidates: radius 0, and no propagation)."""
    sigd2, sigc2, lw, gw, lam_p, lam_d, _, band = common
    tmask = np.zeros(lv.hole.shape, bool)  # no neighbours: nothing propagates
    _sweep(lv.col, lv.lab, lv.gde, conf, np.zeros(lv.hole.shape, bool), lv.hole, tmask, wk, ty,
           tx, nnf, cost, sigd2, sigc2, lw, gw, lam_p, lam_d, 0, band, 1, 0.0, 0)


# ---------------------------------------------------------------------------------------------
# public entry points

def _check_common(hole: np.ndarray, shape: tuple[int, int], patch: int, lambda_p: float,
                  lambda_d: float, iterations: int, levels: int | None) -> None:
    if not isinstance(hole, np.ndarray) or hole.dtype != bool:
        raise InputError("hole: expected a boolean (H, W) array (True = unknown); convert a "
                         "0/255 mask with mask > 0")
    if hole.shape != shape:
        raise InputError(f"hole: shape {hole.shape} differs from the image's {shape}; pass the "
                         f"mask of the same image")
    if isinstance(patch, bool) or not isinstance(patch, int | np.integer) or patch < 3 \
            or patch % 2 == 0:
        raise InputError(f"patch {patch!r}: use an odd integer ≥ 3 (the paper's W = 7)")
    if min(shape) < patch:
        raise InputError(f"image {shape}: smaller than a {patch} × {patch} patch; use a smaller "
                         f"patch or a larger image")
    for name, value in (("lambda_p", lambda_p), ("lambda_d", lambda_d)):
        if not (np.isfinite(value) and value >= 0):
            raise InputError(f"{name} {value!r}: use a finite weight ≥ 0")
    if isinstance(iterations, bool) or not isinstance(iterations, int | np.integer) \
            or iterations < 1:
        raise InputError(f"iterations {iterations!r}: use an integer ≥ 1")
    if levels is not None and (isinstance(levels, bool)
                               or not isinstance(levels, int | np.integer) or levels < 1):
        raise InputError(f"levels {levels!r}: use None (automatic) or an integer ≥ 1")
    if hole.all():
        raise InputError("hole: covers the whole image, so there is nothing to copy from; "
                         "leave some pixels known")


def _check_labels(name: str, labels: object) -> np.ndarray:
    if not isinstance(labels, np.ndarray) or labels.ndim != 2 \
            or not np.issubdtype(labels.dtype, np.integer):
        got = (f"{labels.dtype} array of shape {labels.shape}"
               if isinstance(labels, np.ndarray) else type(labels).__name__)
        raise InputError(f"{name}: expected an (H, W) integer array of class indices, got {got}")
    return labels


#: Known class indices in [0, _DIRECT_CLASSES) are used as they are, others renumbered first.
_DIRECT_CLASSES = 1024


def complete_labels(labels: np.ndarray, hole: np.ndarray, *, patch: int = 7,
                    lambda_p: float = 5e-4, lambda_d: float = 0.5, iterations: int = 5,
                    levels: int | None = None, seed: int = 0) -> np.ndarray:
    """Fill the hole of a class-index label map by direction-guided PatchMatch (§3.2).

    Parameters
    ----------
    labels : (H, W) integer
        Class indices, any integer dtype; values under the hole are ignored.
    hole : (H, W) bool
        True = unknown.
    patch : int
        Patch size W (odd), 7 in the paper.
    lambda_p, lambda_d : float
        λ1 (proximity, eq. 5) and λ2 (direction, eq. 6) of eq. 3.
    iterations : int
        PatchMatch passes per pyramid level.
    levels : int or None
        Pyramid levels (1 = none); None chooses them from the hole's size.  Fewer are used when a
        coarser level would be smaller than four patches or have nothing to copy from.
    seed : int
        Seed of the random initialisation and search; the result is deterministic for a seed.

    Returns
    -------
    (H, W) same dtype as ``labels``
        A copy with hole pixels set to classes of the known region; other pixels unchanged.

    Raises
    ------
    InputError
        Wrong dims or dtypes, a shape mismatch, a hole covering everything, a hole that leaves no
        patch of known pixels, or a bad parameter.
    """
    labels = _check_labels("labels", labels)
    _check_common(hole, labels.shape, patch, lambda_p, lambda_d, iterations, levels)
    out = labels.copy()
    if not hole.any():
        return out
    known = labels[~hole]
    lo, hi = int(known.min()), int(known.max())
    if 0 <= lo and hi < _DIRECT_CLASSES:  # class indices as they are: the vote's histogram
        lab = np.where(hole, 0, labels).astype(np.int32)
        classes = None
    else:
        classes, compact = np.unique(known, return_inverse=True)
        lab = np.zeros(labels.shape, np.int32)
        lab[~hole] = compact.reshape(-1).astype(np.int32)
    h, w = labels.shape
    res = patchmatch(np.zeros((h, w, 0), np.float32), lab, np.zeros((h, w), np.int32), hole,
                     label_weight=1.0, guide_weight=0.0, patch=patch, lambda_p=lambda_p,
                     lambda_d=lambda_d, iterations=iterations, levels=levels, seed=seed)
    filled = res.labels[hole]
    out[hole] = filled if classes is None else classes[filled]
    return out


#: Default weight of the guide's label disagreement against the colour difference (both means
#: in [0, 1] over the patch): a patch straddling the wrong class boundary loses to any colour.
GUIDE_WEIGHT = 1.0


def fill_guided(rgb: np.ndarray, hole: np.ndarray, guide: np.ndarray, *, patch: int = 7,
                lambda_p: float = 5e-4, lambda_d: float = 0.5, guide_weight: float = GUIDE_WEIGHT,
                iterations: int = 5, levels: int | None = None, seed: int = 0) -> np.ndarray:
    """Label-guided PatchMatch fill of a photo (our extension of §3.2 to colour).

    Patch distance: mean colour difference over the target patch's known (later: estimated)
    pixels + ``guide_weight`` × label disagreement over the whole patch + the proximity and
    direction costs of eqs. 5–6; coarse-to-fine; the output pixel is the similarity-weighted vote
    of the overlapping source patches (Wexler et al. 2007; why, in the module docstring).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The photo; hole pixels are unknown.
    hole : (H, W) bool
        True = unknown.
    guide : (H, W) integer
        A label map known everywhere (the completed labels).
    guide_weight : float
        Weight of the guide disagreement (``GUIDE_WEIGHT``).
    patch, lambda_p, lambda_d, iterations, levels, seed
        As in :func:`complete_labels`.

    Returns
    -------
    (H, W, 3) uint8
        A copy with only hole pixels changed, each from pixels outside the hole.

    Raises
    ------
    InputError
        As :func:`complete_labels`, and for an ``rgb`` that is not (H, W, 3) uint8.
    """
    if not isinstance(rgb, np.ndarray) or rgb.ndim != 3 or rgb.shape[2] != 3 \
            or rgb.dtype != np.uint8:
        got = (f"{rgb.dtype} array of shape {rgb.shape}" if isinstance(rgb, np.ndarray)
               else type(rgb).__name__)
        raise InputError(f"rgb: expected an (H, W, 3) uint8 image, got {got}; convert with "
                         f"np.clip(x, 0, 255).astype(np.uint8)")
    guide = _check_labels("guide", guide)
    if guide.shape != rgb.shape[:2]:
        raise InputError(f"guide: shape {guide.shape} differs from the image's {rgb.shape[:2]}; "
                         f"pass the label map of the same image")
    _check_common(hole, rgb.shape[:2], patch, lambda_p, lambda_d, iterations, levels)
    if not (np.isfinite(guide_weight) and guide_weight >= 0):
        raise InputError(f"guide_weight {guide_weight!r}: use a finite weight ≥ 0")
    out = rgb.copy()
    if not hole.any():
        return out
    h, w = hole.shape
    if guide.dtype.itemsize <= 4 and guide.dtype != np.uint32:
        gde = guide.astype(np.int32)  # only equality counts: no need to renumber
    else:
        gde = np.unique(guide, return_inverse=True)[1].reshape(h, w)
    col = rgb.astype(np.float32) * np.float32(1.0 / (255.0 * 3.0))
    res = patchmatch(col, np.zeros((h, w), np.int32), gde.astype(np.int32), hole,
                     label_weight=0.0, guide_weight=guide_weight, patch=patch, lambda_p=lambda_p,
                     lambda_d=lambda_d, iterations=iterations, levels=levels, seed=seed)
    filled = np.clip(np.rint(res.colour[hole] * (255.0 * 3.0)), 0, 255).astype(np.uint8)
    out[hole] = filled
    return out
