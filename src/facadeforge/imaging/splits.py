"""Floor and tile split lines (Müller et al. 2007, §2.4) and the stage-1 driver.

§2.4 — edge functions (eq. 3, ``α = 0.9``)::

    hor = max((1-α)·I_y² − α·I_x², 0)      ver = max((1-α)·I_x² − α·I_y², 0)

interest functions (eq. 4, ``β = 0.1``, Gaussian ``σ = 1 m``)::

    Ver(y) = g_σ * Σ_x ver − β·g_σ * Σ_x hor      Hor(x) = g_σ * Σ_y hor − β·g_σ * Σ_y ver

and the optimal subset of local minima (eq. 5/6): minimise the *mean* interest of the chosen
positions subject to consecutive gaps in ``[min_gap, max_gap]`` (floors 3–5.5 m, tiles 0.5–9 m).

Solving eq. 5/6 exactly
    The objective is a ratio (sum / count), so a plain shortest-path DP does not apply.  We
    instead solve, for *every* subset size ``k``, the minimum-sum chain of ``k`` candidates with
    admissible gaps (DP over ``(k, last candidate)``, ``O(K·m²)`` vectorised in numpy), then take
    the best ``sum/k`` over ``k`` — exact because the optimum has some size ``k`` and for that
    size minimising the sum minimises the mean.  The image borders act as implicit end points:
    with ``borders=True`` the first line must lie within ``max_gap`` of the start and the last
    within ``max_gap`` of the end (no lower bound there: a roof or a plinth may be short).  When
    that is infeasible the border slack is doubled until it is.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .symmetry import SymmetryProfile, dominant_period, mean_period, symmetry_profile

__all__ = ["FLOOR_PRIOR_M", "FLOOR_RANGE_M", "MIN_REPETITION_MI", "TILE_RANGE_M", "FacadeStructure", "edge_maps",
           "floor_and_tile_split", "interest_functions", "local_minima", "optimal_subset",
           "periodic_lines", "split_lines", "to_gray"]

#: Floor heights searched (metres).  The paper uses 3–5.5 m; we go down to 2.5 m because
#: residential storeys (and the synthetic ``residential`` style, 2.6–3.1 m) are lower.
FLOOR_RANGE_M: tuple[float, float] = (2.5, 5.5)
#: Tile widths (metres), §2.2/§2.4.
TILE_RANGE_M: tuple[float, float] = (0.5, 9.0)
#: Storey height assumed when no scale is given (the floor-height prior).
FLOOR_PRIOR_M: float = 3.2
#: Best symmetry S(y, h) (nats) below which no row region repeats: i.i.d. noise reaches about
#: 0.04, a flat wall 0.002, synthetic and CMP facades 0.54–0.86 (16 levels, working copy).
MIN_REPETITION_MI: float = 0.1
#: Working height (pixels) for the symmetry search of :func:`floor_and_tile_split`.
WORK_HEIGHT_PX: int = 400


def to_gray(photo: np.ndarray) -> np.ndarray:
    """``(H, W)`` float64 luminance in ``[0, 1]`` from gray, RGB or RGBA, 8 or 16 bit."""
    a = np.asarray(photo)
    scale = 65535.0 if a.dtype == np.uint16 else 255.0 if a.dtype == np.uint8 else 1.0
    a = a.astype(np.float64) / scale
    if a.ndim == 3:
        if a.shape[2] >= 3:
            a = a[..., 0] * 0.299 + a[..., 1] * 0.587 + a[..., 2] * 0.114
        else:
            a = a[..., 0]
    if a.ndim != 2:
        raise ValueError(f"expected an image, got shape {np.shape(photo)}")
    return a


def edge_maps(gray: np.ndarray, alpha: float = 0.9) -> tuple[np.ndarray, np.ndarray]:
    """``hor, ver`` of eq. 3 (§2.4): dominance of horizontal resp. vertical edges per pixel
    (central differences)."""
    g = np.asarray(gray, dtype=np.float64)
    iy, ix = np.gradient(g)
    iy2, ix2 = iy * iy, ix * ix
    hor = np.maximum((1.0 - alpha) * iy2 - alpha * ix2, 0.0)
    ver = np.maximum((1.0 - alpha) * ix2 - alpha * iy2, 0.0)
    return hor, ver


def interest_functions(hor: np.ndarray, ver: np.ndarray, sigma_px: float,
                       beta: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """``Ver(y), Hor(x)`` of eq. 4 (§2.4) with a normalised 1D Gaussian of ``sigma_px``.

    Horizontal splitting lines go to local minima of ``Ver`` (few vertical edges, many
    horizontal ones), vertical splitting lines to local minima of ``Hor``.
    """
    sig = max(float(sigma_px), 1e-6)
    vy = gaussian_filter1d(ver.sum(axis=1), sig, mode="nearest")
    hy = gaussian_filter1d(hor.sum(axis=1), sig, mode="nearest")
    hx = gaussian_filter1d(hor.sum(axis=0), sig, mode="nearest")
    vx = gaussian_filter1d(ver.sum(axis=0), sig, mode="nearest")
    return vy - beta * hy, hx - beta * vx


def local_minima(f: np.ndarray) -> np.ndarray:
    """Interior local minima of a 1D function (a plateau gives its middle position)."""
    f = np.asarray(f, dtype=np.float64)
    n = f.size
    if n < 3:
        return np.zeros(0, np.int64)
    out = []
    i = 1
    while i < n - 1:
        if f[i] < f[i - 1]:
            j = i
            while j + 1 < n and f[j + 1] == f[i]:
                j += 1
            if j + 1 < n and f[j + 1] > f[i]:
                out.append((i + j) // 2)
            i = j + 1
        else:
            i += 1
    return np.asarray(out, np.int64)


def optimal_subset(positions: np.ndarray, values: np.ndarray, min_gap: float, max_gap: float,
                   start: float | None = None, end: float | None = None) -> np.ndarray:
    """Indices (into ``positions``) of the subset minimising the mean value with consecutive
    gaps in ``[min_gap, max_gap]`` (eq. 5/6), exactly; see the module docstring.

    ``start``/``end``: when given, the first chosen position must be ≤ ``start + max_gap`` and
    the last ≥ ``end − max_gap``.  Ties in the mean prefer more lines.  Empty when infeasible.
    """
    p = np.asarray(positions, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    order = np.argsort(p, kind="stable")
    p, v = p[order], v[order]
    m = p.size
    if m == 0:
        return np.zeros(0, np.int64)
    d = p[None, :] - p[:, None]                          # d[i, j] = p_j - p_i
    allowed = (d >= min_gap) & (d <= max_gap)
    first_ok = np.ones(m, bool) if start is None else p <= start + max_gap
    last_ok = np.ones(m, bool) if end is None else p >= end - max_gap
    inf = np.inf
    best = np.where(first_ok, v, inf)
    back: list[np.ndarray] = []
    best_mean, best_k, best_j = inf, 0, -1
    kmax = m if min_gap <= 0 else min(m, int(math.floor((p[-1] - p[0]) / min_gap)) + 1)
    k = 1
    while True:
        cand = np.where(last_ok, best, inf)
        j = int(np.argmin(cand))
        if np.isfinite(cand[j]) and cand[j] / k <= best_mean + 1e-12 * max(1.0, abs(best_mean)):
            best_mean, best_k, best_j = cand[j] / k, k, j
        if k >= kmax or not np.isfinite(best).any():
            break
        mat = np.where(allowed, best[:, None], inf)      # chain ending at i, extended to j
        arg = np.argmin(mat, axis=0)
        prev = mat[arg, np.arange(m)]
        best = prev + v
        back.append(arg)
        k += 1
    if best_j < 0:
        return np.zeros(0, np.int64)
    chain = [best_j]
    for kk in range(best_k - 1, 0, -1):
        chain.append(int(back[kk - 1][chain[-1]]))
    return np.sort(order[np.asarray(chain[::-1], np.int64)])


def periodic_lines(interest: np.ndarray, period: float, extent: tuple[float, float] | None = None,
                   snap: float = 0.2) -> np.ndarray:
    """Split lines of a repetition with known ``period``: the phase that minimises the mean
    interest of a regular grid over ``extent``, then each grid line snapped to the minimum of
    ``interest`` within ``±snap·period`` (repetitions are nearly, not exactly, regular).

    This is eq. 5/6 with the gap range tightened to the detected period — the irreducible
    facade's repetition made explicit — solved by exhaustive search over the phase, which
    (unlike a free mean-minimising subset) cannot drop weak but regular lines.
    """
    f = np.asarray(interest, dtype=np.float64)
    n = f.size
    p = float(period)
    if not p >= 2 or n < 3:
        return np.zeros(0, np.int64)
    a, b = (0.0, float(n - 1)) if extent is None else (max(0.0, float(extent[0])),
                                                        min(float(n - 1), float(extent[1])))
    r = max(1, int(round(snap * p)))
    # windowed minimum: the best value reachable from each position by snapping
    from scipy.ndimage import minimum_filter1d

    fmin = minimum_filter1d(f, size=2 * r + 1, mode="nearest")
    best_phase, best_score = 0.0, np.inf
    for phase in np.arange(0.0, p, 1.0):
        grid = np.arange(a + phase, b + 1e-9, p)
        if grid.size == 0:
            continue
        score = float(fmin[np.clip(np.rint(grid).astype(np.int64), 0, n - 1)].mean())
        if score < best_score - 1e-12:
            best_phase, best_score = phase, score
    out = []
    for g in np.arange(a + best_phase, b + 1e-9, p):
        c = int(round(g))
        lo, hi = max(1, c - r), min(n - 1, c + r + 1)
        if hi <= lo:
            continue
        y = lo + int(np.argmin(f[lo:hi]))
        if not out or y - out[-1] >= 0.5 * p:
            out.append(y)
    return np.asarray(out, np.int64)


def split_lines(interest: np.ndarray, min_gap_px: float, max_gap_px: float, *,
                candidates: np.ndarray | None = None, borders: bool = True,
                ends: tuple[float, float] | None = None,
                end_slack: float | None = None) -> np.ndarray:
    """Split positions (sorted pixel indices) for an interest function (eq. 5/6, §2.4).

    Candidates are the local minima of ``interest`` (or ``candidates``); the chosen subset
    minimises the mean interest with gaps in ``[min_gap_px, max_gap_px]``
    (:func:`optimal_subset`).  With ``borders`` the image ends ``0`` and ``len-1`` (or
    ``ends``) are implicit end points: the first line lies within ``end_slack`` (default
    ``max_gap_px``) of the start, the last within it of the end; the slack is doubled until the
    problem is feasible.
    """
    f = np.asarray(interest, dtype=np.float64)
    cand = local_minima(f) if candidates is None else np.asarray(candidates, np.int64)
    if cand.size == 0:
        return np.zeros(0, np.int64)
    vals = f[cand]
    if not borders:
        return cand[optimal_subset(cand, vals, min_gap_px, max_gap_px)]
    slack = max(float(max_gap_px if end_slack is None else end_slack), 1.0)
    n = f.size
    a, b = (0.0, float(n - 1)) if ends is None else (float(ends[0]), float(ends[1]))
    while True:
        gap_hi = slack
        p = cand.astype(np.float64)
        first_ok, last_ok = p <= a + gap_hi, p >= b - gap_hi
        if first_ok.any() and last_ok.any():
            # start/end expressed through max_gap: shift so that start + max_gap == a + gap_hi
            idx = optimal_subset(cand, vals, min_gap_px, max_gap_px,
                                 start=a + gap_hi - max_gap_px, end=b - gap_hi + max_gap_px)
            if idx.size:
                return cand[idx]
        if slack >= n:
            return cand[optimal_subset(cand, vals, min_gap_px, max_gap_px)]
        slack *= 2.0


@dataclass
class FacadeStructure:
    """Stage-1 result of :func:`floor_and_tile_split` (pixel rows/columns of the input photo).

    ``floors``: ``(y0, y1)`` bands top to bottom (``y1`` exclusive); ``tiles[i]``: ``(x0, x1)``
    of floor ``i``; ``confidences``: ``{"floors": [one per horizontal split line],
    "tiles": [[one per vertical split line of floor i]]}`` in ``[0, 1]``; ``profile``: the
    vertical :class:`SymmetryProfile` at working scale ``work_scale`` (working pixel = input
    pixel / work_scale); ``floor_period_px`` the dominant floor period in input pixels.
    """

    floors: list[tuple[int, int]]
    tiles: list[list[tuple[int, int]]]
    profile: SymmetryProfile
    confidences: dict[str, list]
    floor_lines: list[int] = field(default_factory=list)
    floor_period_px: float = 0.0
    tile_periods_px: list[float] = field(default_factory=list)
    px_per_m: float = 0.0
    scale_source: str = "prior"
    work_scale: float = 1.0
    timings: dict[str, float] = field(default_factory=dict)


def _resize(gray: np.ndarray, f: float) -> np.ndarray:
    if f == 1.0:
        return gray
    import cv2

    h, w = gray.shape
    size = (max(1, int(round(w / f))), max(1, int(round(h / f))))
    return cv2.resize(gray.astype(np.float32), size, interpolation=cv2.INTER_AREA).astype(
        np.float64)


def _repetitive_extent(profile: SymmetryProfile, f: float, n: int,
                       rel: float = 0.6) -> tuple[float, float]:
    """Rows (input pixels) spanned by the detected repetitions: the union of
    ``[y - h_max, y + h_max)`` over rows with ``S_max ≥ rel·τ_max`` (§2.3's stacking set)."""
    s, hm = profile.s_max, profile.h_max
    ok = np.isfinite(s) & (hm > 0)
    if not ok.any():
        return 0.0, float(n - 1)
    sel = ok & (s >= rel * float(s[ok].max()))
    ys = np.nonzero(sel)[0]
    lo = float(np.min(ys - hm[sel])) * f
    hi = float(np.max(ys + hm[sel])) * f
    return max(0.0, lo), min(float(n - 1), hi)


def _line_confidence(f: np.ndarray, lines: np.ndarray, radius: float,
                     period: float) -> list[float]:
    """Per split line: half the normalised depth of the interest minimum (against the maximum
    within ``radius``), half the agreement of its neighbour gaps with ``period``."""
    f = np.asarray(f, dtype=np.float64)
    rng = float(f.max() - f.min()) or 1.0
    r = max(1, int(round(radius)))
    out = []
    for k, y in enumerate(lines):
        lo, hi = max(0, y - r), min(f.size, y + r + 1)
        depth = float(np.clip((f[lo:hi].max() - f[y]) / rng, 0.0, 1.0))
        gaps = []
        if k > 0:
            gaps.append(y - lines[k - 1])
        if k + 1 < len(lines):
            gaps.append(lines[k + 1] - y)
        if period > 0 and gaps:
            per = max(math.exp(-(((g - period) / (0.15 * period)) ** 2)) for g in gaps)
        else:
            per = 0.0
        out.append(round(0.5 * depth + 0.5 * per, 4))
    return out


def floor_and_tile_split(photo: np.ndarray, metres_per_pixel=None, *, bins: int = 16,
                         floor_range_m: tuple[float, float] = FLOOR_RANGE_M,
                         tile_range_m: tuple[float, float] = TILE_RANGE_M,
                         work_height: int = WORK_HEIGHT_PX,
                         tiles: bool = True, regular: bool = True, sigma_m: float = 1.0,
                         sigma_cap: bool = True,
                         edges: tuple[np.ndarray, np.ndarray] | None = None) -> FacadeStructure:
    """Floors and tiles of a rectified facade photo (§2.2 + §2.4).

    1. Vertical symmetry profile (:func:`symmetry_profile`) on a working copy scaled to about
       ``work_height`` rows; the floor period is :func:`dominant_period` of ``h_max``.
    2. Scale: ``metres_per_pixel`` (a number or ``(mx, my)``) when given, else the floor-height
       prior (the period is one storey of :data:`FLOOR_PRIOR_M`).
    3. Floor lines: :func:`split_lines` on ``Ver(y)`` (σ = ``sigma_m``, capped at period/6 with
       ``sigma_cap``: at ~10 px/m a 1 m Gaussian blurs a 3 m floor period away).  With
       ``regular`` the gaps are restricted to ``[0.8, 1.25]·period`` and the chain must start
       and end within half a period of the rows spanned by the detected repetitions (the §2.3
       stacking set) — the full-image stand-in for splitting the irreducible facade; if that is
       infeasible (unreliable period) the gaps are ``floor_range_m`` alone.
    4. Per floor band: horizontal symmetry period (``axis=1``, 16 bins) and tile lines on
       ``Hor(x)`` with gaps in ``tile_range_m``.

    ``edges`` are :func:`edge_maps` of the photo when the caller has them already.
    """
    t0 = time.perf_counter()
    gray = to_gray(photo)
    H, W = gray.shape
    timings: dict[str, float] = {}
    if metres_per_pixel is not None:
        mpp = np.atleast_1d(np.asarray(metres_per_pixel, dtype=np.float64))
        mx, my = float(mpp[0]), float(mpp[-1])
        if not (mx > 0 and my > 0):
            raise ValueError(f"metres_per_pixel must be positive, got {metres_per_pixel!r}")
    else:
        mx = my = None
    f = max(1.0, H / float(work_height))
    small = _resize(gray, f)
    hs_ = small.shape[0]
    if my is not None:
        lo = floor_range_m[0] / my / f
        hi = floor_range_m[1] / my / f
    else:
        lo, hi = hs_ / 14.0, hs_ / 2.0
    lo = max(2, int(math.floor(lo)))
    hi = max(lo, int(math.ceil(hi)))
    profile = symmetry_profile(small, (lo, hi), axis=0, bins=bins)
    period_s = dominant_period(profile, harmonic=0.9 if my is not None else 1.0)
    if not profile.tau_max >= MIN_REPETITION_MI:
        period_s = 0          # nothing repeats: the facade is its own irreducible facade
    period = period_s * f
    timings["symmetry"] = time.perf_counter() - t0

    if my is not None:
        px_per_m_y, px_per_m_x, source = 1.0 / my, 1.0 / mx, "metres_per_pixel"
    else:
        px_per_m_y = (period / FLOOR_PRIOR_M) if period > 0 else H / (3 * FLOOR_PRIOR_M)
        px_per_m_x, source = px_per_m_y, "prior"

    t1 = time.perf_counter()
    hor, ver = edge_maps(gray) if edges is None else edges
    sigma_y = sigma_m * px_per_m_y
    if period > 0 and sigma_cap:
        sigma_y = min(sigma_y, period / 6.0)
    ver_y, _ = interest_functions(hor, ver, sigma_px=sigma_y)
    gap_lo, gap_hi = floor_range_m[0] * px_per_m_y, floor_range_m[1] * px_per_m_y
    extent = _repetitive_extent(profile, f, H) if period > 0 else (0, H - 1)
    fl = np.zeros(0, np.int64)
    if period > 0 and regular:
        # floors repeat with the period over the rows the repetitions span (§2.3)
        fl = periodic_lines(ver_y, period, extent)
        fl = fl[(fl > 0.15 * period) & (fl < H - 0.15 * period)]
    if fl.size == 0:
        fl = split_lines(ver_y, gap_lo, gap_hi, ends=extent)
    floor_lines = [int(v) for v in fl]
    edges = [0] + floor_lines + [H]
    floors = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]
    conf_f = _line_confidence(ver_y, fl, 0.5 * px_per_m_y, period)
    timings["floors"] = time.perf_counter() - t1

    t2 = time.perf_counter()
    tile_list: list[list[tuple[int, int]]] = []
    conf_t: list[list[float]] = []
    periods: list[float] = []
    tile_period = 0.0
    if tiles:
        # one horizontal period for the facade: window columns align across floors, so the
        # repeated rows together give a far stronger MI signal than any single floor band
        r0, r1 = int(extent[0] / f), max(int(extent[0] / f) + 2, int(math.ceil(extent[1] / f)))
        tlo = max(2, int(tile_range_m[0] * px_per_m_x / f))
        thi = int(math.ceil(tile_range_m[1] * px_per_m_x / f))
        hp = symmetry_profile(small[r0:r1], (tlo, thi), axis=1, bins=16)
        tile_period = mean_period(hp) * f
    for y0, y1 in floors:
        if not tiles or y1 - y0 < 3:
            tile_list.append([(0, W)])
            conf_t.append([])
            periods.append(0.0)
            continue
        sig_x = min(px_per_m_x, tile_period / 6.0 if tile_period > 0 else px_per_m_x)
        _, hor_x = interest_functions(hor[y0:y1], ver[y0:y1], sigma_px=sig_x)
        xl = np.zeros(0, np.int64)
        if tile_period > 0 and regular:
            # Eq. 6's Hor(x) is lowest on the vertical frame edges of windows (its −β·ver
            # term), so a regular grid snapped to it cuts windows; between repeated windows
            # lies wall, the quietest column — split there (all edge energy, smoothed).
            quiet = gaussian_filter1d((hor[y0:y1] + ver[y0:y1]).sum(axis=0), sig_x,
                                      mode="nearest")
            xl = periodic_lines(quiet, tile_period)
            xl = xl[(xl > 0.15 * tile_period) & (xl < W - 0.15 * tile_period)]
        if xl.size == 0:
            xl = split_lines(hor_x, tile_range_m[0] * px_per_m_x, tile_range_m[1] * px_per_m_x)
        periods.append(float(tile_period))
        xs = [0] + [int(v) for v in xl] + [W]
        tile_list.append([(a, b) for a, b in zip(xs[:-1], xs[1:]) if b > a])
        conf_t.append(_line_confidence(hor_x, xl, 0.25 * px_per_m_x, tile_period))
    timings["tiles"] = time.perf_counter() - t2
    return FacadeStructure(floors=floors, tiles=tile_list, profile=profile,
                           confidences={"floors": conf_f, "tiles": conf_t},
                           floor_lines=floor_lines, floor_period_px=float(period),
                           tile_periods_px=periods, px_per_m=float(px_per_m_y),
                           scale_source=source, work_scale=float(f), timings=timings)
