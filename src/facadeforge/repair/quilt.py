"""Image quilting with the minimum-error boundary cut (Efros & Freeman 2001; seed ``shang2023`` §3.4).

Alg. 1 of the seed: all ``N×N`` blocks of the source form the set ``S_B``; a random block starts
the output, then blocks are placed in raster order with a step of ``N − v`` (``v`` the overlap
width, 5 px in the paper: offset ``(5, 0)`` in the first row, ``(0, 5)`` in the first column,
``(5, 5)`` elsewhere).  Each new block ``B2`` is chosen by its overlap error with what is
already placed, ``E(B1_ov − B2_ov)²``, among the candidates within ``(1 + t)`` of the best
(Efros–Freeman's tolerance, ``t = 0.1``), and joined along the minimum-error boundary ``l``
through the overlap — the paper's Dijkstra ``D``; on an overlap strip the cheapest 8-connected
top-to-bottom path is found exactly by dynamic programming over the per-pixel squared error.
Blocks of the first row get a vertical cut, blocks of the first column a horizontal one,
interior blocks both (the new block keeps what lies right of the vertical *and* below the
horizontal cut).

Candidate search
    The overlap error of every source position at once is
    ``Σ M|T|² − 2 Σ_c corr(I_c, M·T_c) + corr(|I|², M)`` (``T`` what is placed, ``M`` the mask of
    placed pixels, ``I`` the source), three correlations computed with FFTs of the source done
    once; per block that is one batched forward FFT and one inverse, whatever the mask's shape.
    The FFTs run in single precision (faster; the error is ~1 in sums of ~10⁶, far below
    the 0.5 (of 255²) per overlap pixel of slack added to the tolerance test).  The cost grows
    with the region's and the source's areas (``docs/design-measurements.md``).

Constrained quilting (:func:`quilt`)
    To fill a region of a photo the blocks are laid over the region's bounding box, starting one
    overlap above and left of it so the first blocks overlap the known surroundings.  The mask
    ``M`` holds every pixel of the block that is known or already placed, so a block is chosen
    to agree with the photo around the hole as well as with its neighbours (Efros–Freeman's
    constrained synthesis); the boundary cuts run through the left and top overlap strips as in
    Alg. 1, and only pixels of the region are ever written.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import scipy.fft as sfft

from facadeforge.errors import InputError

__all__ = ["default_block", "default_overlap", "quilt", "quilt_texture"]

#: Fewest wholly-inside source blocks the default block size of :func:`quilt` accepts before it
#: shrinks the block (each shrink ×0.8, down to 6 px).
MIN_CANDIDATES = 64


def default_overlap(block: int) -> int:
    """Overlap width for ``block``: the paper's 5 px for blocks of 15–30 px, ``block // 3`` for
    smaller ones (5 px would leave almost no step), ``round(block / 6)`` for larger ones (5 px
    of a 64 px block is too thin a band for a cut to hide in)."""
    if block < 15:
        return max(1, block // 3)
    if block <= 30:
        return 5
    return int(round(block / 6))


def default_block(source_px: int) -> int:
    """Block side for a source of ``source_px`` pixels: ``clip(round(sqrt(source_px) / 6), 8,
    64)`` — a sixth of the side of the equivalent square (a 300×300 source gives 50 px), large
    enough to carry the texture's structure (bricks, joints) and small enough to leave many
    candidates.  :func:`quilt` shrinks it further while fewer than :data:`MIN_CANDIDATES` blocks
    fit wholly inside the source."""
    return int(np.clip(round(math.sqrt(max(source_px, 1)) / 6), 8, 64))


@numba.njit(cache=True, nogil=True)
def _cut_path(err: np.ndarray) -> np.ndarray:
    """Column of the cheapest 8-connected top-to-bottom path through ``err`` (rows × cols)."""
    h, w = err.shape
    cost = np.empty((h, w))
    back = np.zeros((h, w), np.int64)
    for j in range(w):
        cost[0, j] = err[0, j]
    for i in range(1, h):
        for j in range(w):
            best = cost[i - 1, j]
            arg = j
            if j > 0 and cost[i - 1, j - 1] < best:
                best = cost[i - 1, j - 1]
                arg = j - 1
            if j + 1 < w and cost[i - 1, j + 1] < best:
                best = cost[i - 1, j + 1]
                arg = j + 1
            cost[i, j] = err[i, j] + best
            back[i, j] = arg
    path = np.empty(h, np.int64)
    j = 0
    for k in range(1, w):
        if cost[h - 1, k] < cost[h - 1, j]:
            j = k
    for i in range(h - 1, -1, -1):
        path[i] = j
        j = back[i, j]
    return path


class _Matcher:
    """Overlap error of a masked template at every position of a source, by FFT.

    The template's spectrum is taken separably (rows first, only its ``N`` non-zero rows), the
    ``corr(|I|², M)`` term is cached per mask (quilting on a blank canvas only ever sees three
    masks: left strip, top strip, L), and only the rows of whole-block positions are inverted.
    """

    def __init__(self, src: np.ndarray, block: int):
        self.block = block
        self.h, self.w = src.shape[:2]
        self.shape = (sfft.next_fast_len(self.h, True), sfft.next_fast_len(self.w, True))
        self.mean = src.reshape(-1, 3).mean(0)
        img = src - self.mean                       # centred: smaller sums, less rounding
        self.f_img = sfft.rfft2(np.moveaxis(img, 2, 0).astype(np.float32), s=self.shape)
        self.f_sq = sfft.rfft2((img ** 2).sum(2).astype(np.float32), s=self.shape)
        self._sq_cache: dict[bytes, np.ndarray] = {}

    def _spectrum(self, k: np.ndarray) -> np.ndarray:
        fh, fw = self.shape
        return np.conj(sfft.fft(sfft.rfft(k, n=fw, axis=-1), n=fh, axis=-2))

    def _invert(self, g: np.ndarray) -> np.ndarray:
        n = self.block
        rows = sfft.ifft(g, axis=-2)[..., : self.h - n + 1, :]
        return sfft.irfft(rows, n=self.shape[1], axis=-1)[..., : self.w - n + 1]

    def ssd(self, templ: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """``Σ mask·|templ − src[p:p+N]|²`` for every top-left ``p`` of a whole block."""
        t = templ - self.mean
        m = mask.astype(np.float64)
        key = mask.tobytes()
        sq = self._sq_cache.get(key)
        if sq is None:
            sq = self._invert(self.f_sq * self._spectrum(m.astype(np.float32)))
            if len(self._sq_cache) < 64:
                self._sq_cache[key] = sq
        fk = self._spectrum(np.moveaxis(t * m[:, :, None], 2, 0).astype(np.float32))
        cross = self._invert((self.f_img * fk).sum(0))
        return sq - 2.0 * cross + float((m[:, :, None] * t * t).sum())


def _valid_positions(source: np.ndarray, block: int) -> np.ndarray:
    """Top-left corners of the ``block × block`` windows lying wholly inside ``source``."""
    h, w = source.shape
    if h < block or w < block:
        return np.zeros((max(h - block + 1, 0), max(w - block + 1, 0)), bool)
    bad = np.zeros((h + 1, w + 1), np.int64)
    bad[1:, 1:] = np.cumsum(np.cumsum(~source, 0), 1)
    n = block
    cnt = bad[n:, n:] - bad[:-n, n:] - bad[n:, :-n] + bad[:-n, :-n]
    return cnt == 0


def _run(canvas: np.ndarray, filled: np.ndarray, region: np.ndarray, ys, xs,
         src: np.ndarray, valid: np.ndarray, block: int, overlap: int, tolerance: float,
         rng: np.random.Generator) -> None:
    """Alg. 1 over the block grid ``ys × xs`` (padded canvas coordinates), in place.

    ``filled`` marks pixels already known or placed; only ``region`` pixels are written.
    """
    n, v = block, overlap
    matcher = _Matcher(src, n)
    vy, vx = np.nonzero(valid)
    flat_valid = np.flatnonzero(valid)
    cols = np.arange(n)
    for y in ys:
        for x in xs:
            reg = region[y:y + n, x:x + n]
            have = filled[y:y + n, x:x + n]
            if not (reg & ~have).any():
                continue
            win = canvas[y:y + n, x:x + n]
            n_ov = int(have.sum())
            if n_ov == 0:                                    # Alg. 1 line 3: random B1
                k = int(rng.integers(len(vy)))
            else:                                            # line 5: B2 ← V(B1, S_B)
                err = matcher.ssd(win, have).ravel()[flat_valid]
                best = max(float(err.min()), 0.0)
                # (1 + t) of the best; 0.5 (of 255²) per overlap pixel absorbs FFT rounding
                thr = (1.0 + tolerance) * best if best > 0 else 0.0
                cand = np.flatnonzero(err <= thr + 0.5 * n_ov)
                k = int(cand[rng.integers(len(cand))])
            py, px = int(vy[k]), int(vx[k])
            patch = src[py:py + n, px:px + n]
            take = np.ones((n, n), bool)
            diff = ((patch - win) ** 2).sum(2) * have          # E(B1_ov − B2_ov)², placed only
            if have[:, :v].any():                              # vertical cut, left strip
                path = _cut_path(np.ascontiguousarray(diff[:, :v]))
                take[:, :v] &= cols[None, :v] >= path[:, None]
            if have[:v, :].any():                              # horizontal cut, top strip
                path = _cut_path(np.ascontiguousarray(diff[:v, :].T))
                take[:v, :] &= cols[:v, None] >= path[None, :]
            write = reg & (~have | take)
            win[write] = patch[write]
            have |= write


def _check_rgb(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
        raise InputError(f"{name} must be an (H, W, 3) uint8 RGB image, got shape {a.shape} "
                         f"dtype {a.dtype}; convert it with np.asarray(img, np.uint8)")
    return a


def _check_block(block: int, overlap: int | None, limit: int, where: str) -> tuple[int, int]:
    block = int(block)
    if block < 2:
        raise InputError(f"{where}: block={block} must be at least 2 px")
    if block > limit:
        raise InputError(f"{where}: block={block} is larger than the source ({limit} px on its "
                         "short side); pass a smaller block or a larger source")
    v = default_overlap(block) if overlap is None else int(overlap)
    if not 1 <= v <= block // 2:
        raise InputError(f"{where}: overlap={v} must lie in 1..block/2 ({block // 2}); pass a "
                         "smaller overlap or leave it None for the default")
    return block, v


def _grid(start: int, stop: int, block: int, step: int) -> list[int]:
    """Block origins from ``start`` in steps of ``step`` until a block reaches ``stop``."""
    out = [start]
    while out[-1] + block < stop:
        out.append(out[-1] + step)
    return out


def quilt_texture(source: np.ndarray, out_hw: tuple[int, int], *, block: int = 32,
                  overlap: int | None = None, tolerance: float = 0.1, seed: int = 0
                  ) -> np.ndarray:
    """Synthesize an ``out_hw`` texture from ``source`` by image quilting (Alg. 1).

    Blocks (``block × block``) are sampled from ``source`` and placed in raster order with a step
    of ``block − overlap``; each new block is drawn at random among the candidates whose
    overlap error with what is already placed is within ``(1 + tolerance)`` of the best, and
    joined along the minimum-error boundary cut — vertical in the first row, horizontal in the
    first column, both for interior blocks.

    Parameters
    ----------
    source : (Hs, Ws, 3) uint8
        The texture sample ``S``.
    out_hw : (H, W)
        Output size.
    block : int
        Block side ``N`` in pixels.
    overlap : int or None
        Overlap width ``v``; None → :func:`default_overlap` (5 px for 15–30 px blocks,
        ``block / 6`` for larger ones).
    tolerance : float
        Efros–Freeman's tolerance ``t`` (the paper's 0.1).
    seed : int
        Seed of the random choices (first block, candidate among the tolerated).

    Returns
    -------
    (H, W, 3) uint8

    Raises
    ------
    InputError
        ``source`` not an RGB uint8 image or smaller than ``block``; bad ``out_hw`` or
        ``overlap``; negative ``tolerance``.
    """
    src = _check_rgb(source, "quilt_texture: source")
    h, w = (int(out_hw[0]), int(out_hw[1]))
    if h < 1 or w < 1:
        raise InputError(f"quilt_texture: out_hw={out_hw!r} must be two positive sizes")
    if tolerance < 0:
        raise InputError(f"quilt_texture: tolerance={tolerance} must be >= 0 (0.1 in the paper)")
    n, v = _check_block(block, overlap, min(src.shape[:2]), "quilt_texture")
    step = n - v
    ys, xs = _grid(0, h, n, step), _grid(0, w, n, step)
    hc, wc = ys[-1] + n, xs[-1] + n
    canvas = np.zeros((hc, wc, 3))
    filled = np.zeros((hc, wc), bool)
    region = np.ones((hc, wc), bool)
    valid = np.ones((src.shape[0] - n + 1, src.shape[1] - n + 1), bool)
    _run(canvas, filled, region, ys, xs, src.astype(np.float64), valid, n, v, float(tolerance),
         np.random.default_rng(seed))
    return np.clip(np.rint(canvas[:h, :w]), 0, 255).astype(np.uint8)


def quilt(rgb: np.ndarray, region: np.ndarray, source: np.ndarray, *, block: int | None = None,
          overlap: int | None = None, tolerance: float = 0.1, seed: int = 0,
          known: np.ndarray | None = None) -> np.ndarray:
    """Fill ``region`` of ``rgb`` by constrained quilting from blocks wholly inside ``source``.

    Blocks are laid over the region's bounding box in raster order, starting one overlap above
    and left of it; each block is chosen (within ``1 + tolerance`` of the best) by its error
    over every pixel of its window already known — the photo outside ``region`` as well as the
    blocks placed before — so the fill joins its surroundings, then cut into the left and top
    overlaps along the minimum-error boundary (Alg. 1).  Only ``region`` pixels change.

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The photo.
    region : (H, W) bool
        Pixels to fill.
    source : (H, W) bool
        Pixels blocks may be copied from (unoccluded pixels of the same class, e.g. visible
        wall); ``region`` pixels are never used even if marked here.
    block : int or None
        Block side.  None → :func:`default_block` of the source's pixel count (a sixth of the
        equivalent square's side, 8–64 px), shrunk ×0.8 at a time while fewer than
        :data:`MIN_CANDIDATES` blocks fit wholly inside ``source``.
    overlap : int or None
        Overlap width; None → :func:`default_overlap`: the paper's 5 px for 15–30 px blocks,
        ``block / 6`` for larger blocks, ``block / 3`` for small ones.
    tolerance, seed
        As in :func:`quilt_texture`.
    known : (H, W) bool or None
        Pixels the fill must agree with; None → every pixel outside ``region``.  Pass it when
        other pixels of the photo are unknown too (the rest of an occluder, filled later), so
        they are not matched.

    Returns
    -------
    (H, W, 3) uint8
        A copy of ``rgb`` with ``region`` filled.

    Raises
    ------
    InputError
        Shapes disagree, no block fits inside ``source``, bad ``overlap`` or ``tolerance``.
    """
    img = _check_rgb(rgb, "quilt: rgb")
    hh, ww = img.shape[:2]
    reg = np.asarray(region)
    srcm = np.asarray(source)
    kn = ~reg if known is None else np.asarray(known)
    for name, m in (("region", reg), ("source", srcm), ("known", kn)):
        if m.shape != (hh, ww):
            raise InputError(f"quilt: {name} has shape {m.shape}, the photo {img.shape[:2]}; "
                             f"pass an (H, W) bool mask of the photo's size")
    reg = reg.astype(bool)
    srcm = srcm.astype(bool) & ~reg
    if tolerance < 0:
        raise InputError(f"quilt: tolerance={tolerance} must be >= 0 (0.1 in the paper)")
    out = img.copy()
    if not reg.any():
        return out
    if block is None:
        n = default_block(int(srcm.sum()))
        while n > 6 and _valid_positions(srcm, n).sum() < MIN_CANDIDATES:
            n = max(6, int(n * 0.8))
    else:
        n = int(block)
    valid = _valid_positions(srcm, n) if n >= 2 else np.zeros((0, 0), bool)
    if not valid.any():
        raise InputError(f"quilt: no {n}×{n} block lies wholly inside source "
                         f"({int(srcm.sum())} px); pass a larger source mask or a smaller block")
    n, v = _check_block(n, overlap, min(hh, ww), "quilt")
    iy, ix = np.nonzero(reg)
    y0, y1, x0, x1 = iy.min(), iy.max() + 1, ix.min(), ix.max() + 1
    pad = n + v
    ys = [y + pad for y in _grid(int(y0) - v, int(y1), n, n - v)]
    xs = [x + pad for x in _grid(int(x0) - v, int(x1), n, n - v)]
    hc, wc = hh + 2 * pad + n, ww + 2 * pad + n
    canvas = np.zeros((hc, wc, 3))
    canvas[pad:pad + hh, pad:pad + ww] = img
    filled = np.zeros((hc, wc), bool)
    filled[pad:pad + hh, pad:pad + ww] = kn.astype(bool) & ~reg
    region_c = np.zeros((hc, wc), bool)
    region_c[pad:pad + hh, pad:pad + ww] = reg
    sy, sx = np.nonzero(valid)                      # the source cropped to its blocks
    sy0, sy1, sx0, sx1 = sy.min(), sy.max() + n, sx.min(), sx.max() + n
    src = img[sy0:sy1, sx0:sx1].astype(np.float64)
    outside = ~srcm[sy0:sy1, sx0:sx1]              # never in a block: neutral for the FFTs
    src[outside] = src[~outside].mean(0)
    _run(canvas, filled, region_c, ys, xs, src,
         valid[sy0:sy1 - n + 1, sx0:sx1 - n + 1], n, v, float(tolerance),
         np.random.default_rng(seed))
    res = np.clip(np.rint(canvas[pad:pad + hh, pad:pad + ww]), 0, 255).astype(np.uint8)
    out[reg] = res[reg]
    return out
