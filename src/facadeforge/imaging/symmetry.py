"""Repetition detection by mutual information (Müller et al. 2007, §2.1–2.3).

§2.1 — the similarity of two image regions is the mutual information (eq. 1) of the intensities
at corresponding positions, from their normalised joint and marginal histograms.

§2.2 — the similarity of adjacent regions ``R_{y,h}`` (rows ``[y, y+h)``) and ``R_{y-h,h}``
(rows ``[y-h, y)``) is ``S(y, h) = MI(I(R_{y,h}), I(R_{y-h,h}))`` (eq. 2), evaluated for *every*
``y`` and every ``h`` of a range; ``S_max(y) = max_h S(y, h)`` and ``h_max(y) = argmax_h``.

Least work for all ``(y, h)``
    Intensities are quantised once to ``bins`` levels.  For a shift ``h`` the pixel pairs of the
    two regions are exactly the row pairs ``(y', y'-h)`` for ``y'`` in ``[y, y+h)``, so the joint
    histogram of ``S(y, h)`` is the sum of per-row-pair joint histograms ``J_h[y']``.  We build
    all ``J_h`` with one ``np.bincount`` per ``h`` (each pixel pair visited once per shift), take
    cumulative sums along ``y`` and read every window as a difference of two rows, so each
    ``S(y, h)`` costs ``O(bins²)`` and is vectorised over ``y``.  The marginals come from one
    table of per-row histograms (cumulative sums again).  With ``Σ c log c`` from a lookup table
    and ``N = h·W`` pairs per window::

        MI = log N + (Σ_ab c_ab log c_ab − Σ_a c_a log c_a − Σ_b c_b log c_b) / N

    Total cost ``O(n_h · (H·W + H·bins²))`` instead of ``O(n_h · H · h · W)`` for rebuilding the
    histograms of every window.

§2.3 — :func:`irreducible_facade` collapses the detected repetitions into index stacks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SymmetryProfile", "collapse", "dominant_period", "irreducible_facade",
           "irreducible_facade_2d", "mutual_information",
           "quantise", "symmetry_profile"]


@dataclass
class SymmetryProfile:
    """Result of :func:`symmetry_profile` (§2.2).

    ``S[y, i]`` is ``S(y, hs[i])`` (NaN where ``R_{y-h,h}`` or ``R_{y,h}`` leaves the image);
    ``s_max[y]`` / ``h_max[y]`` the best value and its ``h`` (NaN / -1 where undefined).  ``axis``
    is 0 for the vertical direction (rows) and 1 for the horizontal one (columns).
    """

    S: np.ndarray
    hs: np.ndarray
    s_max: np.ndarray
    h_max: np.ndarray
    axis: int = 0
    bins: int = 32

    @property
    def tau_max(self) -> float:
        """The best similarity score (``τ_max`` of §2.3)."""
        ok = np.isfinite(self.s_max)
        return float(self.s_max[ok].max()) if ok.any() else 0.0


def quantise(x: np.ndarray, bins: int = 32) -> np.ndarray:
    """Intensities → ``int32`` levels ``0 … bins-1`` (uniform over the array's range)."""
    x = np.asarray(x, dtype=np.float64)
    if x.size == 0:
        return np.zeros(x.shape, np.int32)
    lo, hi = float(np.nanmin(x)), float(np.nanmax(x))
    if not hi > lo:
        return np.zeros(x.shape, np.int32)
    q = np.floor((x - lo) * (bins / (hi - lo)))
    return np.clip(np.nan_to_num(q), 0, bins - 1).astype(np.int32)


def mutual_information(a: np.ndarray, b: np.ndarray, bins: int = 32) -> float:
    """Mutual information (eq. 1, §2.1, in nats) of the values at corresponding positions of
    ``a`` and ``b`` (same shape).

    Integer arrays are taken as levels in ``[0, bins)``; float arrays are quantised to ``bins``
    levels over their own range (:func:`quantise`).  The distributions are the normalised joint
    and marginal histograms of the pairs.
    """
    a = np.asarray(a)
    b = np.asarray(b)
    if a.shape != b.shape:
        raise ValueError(f"shapes differ: {a.shape} vs {b.shape}")
    if a.size == 0:
        return 0.0
    qa = a.astype(np.int64) if np.issubdtype(a.dtype, np.integer) else quantise(a, bins)
    qb = b.astype(np.int64) if np.issubdtype(b.dtype, np.integer) else quantise(b, bins)
    if qa.min() < 0 or qb.min() < 0 or qa.max() >= bins or qb.max() >= bins:
        raise ValueError(f"integer levels must lie in [0, {bins})")
    joint = np.bincount((qa.ravel() * bins + qb.ravel()).astype(np.int64),
                        minlength=bins * bins).reshape(bins, bins).astype(np.float64)
    p = joint / joint.sum()
    pa = p.sum(axis=1, keepdims=True)
    pb = p.sum(axis=0, keepdims=True)
    nz = p > 0
    return float(np.sum(p[nz] * np.log(p[nz] / (pa @ pb)[nz])))


def _clogc_table(n: int) -> np.ndarray:
    c = np.arange(n + 1, dtype=np.float64)
    t = np.zeros(n + 1)
    t[1:] = c[1:] * np.log(c[1:])
    return t


def symmetry_profile(gray: np.ndarray, h_range: tuple[int, int], axis: int = 0,
                     bins: int = 32) -> SymmetryProfile:
    """``S(y, h)`` of eq. 2 (§2.2) for every position and every ``h`` in ``h_range`` (pixels,
    inclusive).

    ``axis=0`` compares regions of rows (vertical repetition of floors); ``axis=1`` the same on
    the transposed image (horizontal repetition of tiles; pass a floor band).  See the module
    docstring for the cumulative-sum scheme.  ``h`` is clipped to ``[1, n // 2]``.
    """
    g = np.asarray(gray, dtype=np.float64)
    if g.ndim != 2:
        raise ValueError(f"expected a 2D grayscale image, got shape {g.shape}")
    if axis == 1:
        g = g.T
    elif axis != 0:
        raise ValueError("axis must be 0 or 1")
    n, w = g.shape
    hmin = max(1, int(h_range[0]))
    hmax = min(int(h_range[1]), n // 2)
    hs = np.arange(hmin, hmax + 1, dtype=np.int64)
    S = np.full((n, hs.size), np.nan)
    if hs.size == 0 or w == 0:
        return SymmetryProfile(S, hs, np.full(n, np.nan), np.full(n, -1, np.int64), axis, bins)

    q = quantise(g, bins)
    nb2 = bins * bins
    table = _clogc_table(int(hmax) * w)
    # marginals: per-row histograms, cumulative along y; Σ c log c of every window [y, y+h)
    rows = np.arange(n, dtype=np.int64)[:, None]
    row_hist = np.bincount((rows * bins + q).ravel(), minlength=n * bins).reshape(n, bins)
    cum_m = np.zeros((n + 1, bins), np.int64)
    np.cumsum(row_hist, axis=0, out=cum_m[1:])
    qb = q * bins                                        # row y' level (a) times bins
    offsets = (np.arange(n, dtype=np.int32) * nb2)[:, None]
    for i, h in enumerate(hs):
        h = int(h)
        m = n - h                                        # row pairs (y', y'-h), y' = h … n-1
        idx = qb[h:] + q[:m]
        idx += offsets[:m]
        joint_rows = np.bincount(idx.ravel(), minlength=m * nb2).reshape(m, nb2)
        cum_j = np.empty((m + 1, nb2), np.int32)
        cum_j[0] = 0
        np.cumsum(joint_rows, axis=0, out=cum_j[1:])
        # y = h … n-h; pair index j = y'-h ∈ [y-h, y)
        nv = n - 2 * h + 1
        win = cum_j[h:h + nv] - cum_j[:nv]
        s_joint = table[win].sum(axis=1)
        marg = table[cum_m[h:] - cum_m[:-h]].sum(axis=1)  # window starting at y, y = 0 … n-h
        s_a = marg[h:h + nv]                              # R_{y,h}
        s_b = marg[:nv]                                   # R_{y-h,h}
        N = float(h * w)
        S[h:h + nv, i] = np.log(N) + (s_joint - s_a - s_b) / N
    finite = np.isfinite(S)
    Sf = np.where(finite, S, -np.inf)
    arg = Sf.argmax(axis=1)
    s_max = Sf[np.arange(n), arg]
    has = finite.any(axis=1)
    s_max = np.where(has, s_max, np.nan)
    h_max = np.where(has, hs[arg], -1)
    return SymmetryProfile(S, hs, s_max, h_max, axis, bins)


def dominant_period(profile: SymmetryProfile, rel: float = 0.75, smooth: int = 2,
                    harmonic: float = 0.9) -> int:
    """The dominant repetition period (pixels) of a profile: the mode of ``h_max(y)`` over the
    rows with ``S_max(y) ≥ rel·τ_max``, each row weighted by ``S_max``, histogram smoothed over
    ``±smooth`` pixels (§2.2 notes ``h_max`` is fairly constant).  Ties and harmonics: among
    the peaks within ``harmonic`` (fraction) of the best, the shortest period wins
    (``harmonic=1``: the best peak).  0 when undefined.
    """
    s, hm = profile.s_max, profile.h_max
    ok = np.isfinite(s) & (hm > 0)
    if not ok.any():
        return 0
    tau = float(s[ok].max())
    sel = ok & (s >= rel * tau)
    hs = profile.hs
    w = np.bincount(hm[sel] - hs[0], weights=s[sel], minlength=hs.size)
    if smooth > 0:
        k = np.ones(2 * smooth + 1)
        w = np.convolve(w, k, mode="same")
    best = w.max()
    # local maxima within 90 % of the best; the shortest
    peaks = [i for i in range(w.size)
             if w[i] >= harmonic * best and (i == 0 or w[i] >= w[i - 1])
             and (i == w.size - 1 or w[i] >= w[i + 1])]
    i = peaks[0] if peaks else int(w.argmax())
    # centre of mass of the unsmoothed weights around the peak
    raw = np.bincount(hm[sel] - hs[0], weights=s[sel], minlength=hs.size)
    lo, hi = max(0, i - smooth), min(hs.size, i + smooth + 1)
    if raw[lo:hi].sum() > 0:
        return int(round(float(np.average(hs[lo:hi], weights=raw[lo:hi]))))
    return int(hs[i])


def irreducible_facade(profile: SymmetryProfile, threshold: float = 0.75,
                       max_iter: int | None = None) -> list[list[int]]:
    """The irreducible facade along one axis (§2.3) as reversible index stacks.

    Start with one stack per original row (column for ``axis=1``).  Repeatedly take
    ``y = argmax S_max(y)`` with ``h = h_max(y)``, shift the region ``R_{y-h,h}`` over
    ``R_{y,h}`` (stack ``k`` of the upper region joins stack ``k`` of the lower one; the upper
    region is removed) and set ``S_max`` of the merged positions to the minimum of the two.
    Stop when no ``S_max`` exceeds ``threshold·τ_max`` (τ_max the best score).  Positions whose
    ``h_max`` no longer fits the shrunken image are skipped.

    Returns the list of stacks, one per IF row in order; each lists the original row indices
    that collapse onto it (sorted).  Every original row appears exactly once.
    """
    n = profile.s_max.size
    groups: list[list[int]] = [[i] for i in range(n)]
    s = np.where(np.isfinite(profile.s_max), profile.s_max, -np.inf).astype(np.float64)
    hm = profile.h_max.astype(np.int64).copy()
    tau = profile.tau_max
    if not np.isfinite(s).any() or tau <= 0:
        return groups
    limit = threshold * tau
    active = s.copy()                       # candidates; skipped ones are set to -inf
    it = 0
    while True:
        if max_iter is not None and it >= max_iter:
            break
        y = int(np.argmax(active))
        if not active[y] > limit:
            break
        h = int(hm[y])
        cur = len(groups)
        if h <= 0 or y - h < 0 or y + h > cur:
            active[y] = -np.inf
            continue
        it += 1
        for k in range(h):
            groups[y + k] = sorted(groups[y - h + k] + groups[y + k])
        merged = np.minimum(s[y - h:y], s[y:y + h])
        merged_active = np.minimum(active[y - h:y], active[y:y + h])
        s[y:y + h] = merged
        active[y:y + h] = merged_active
        del groups[y - h:y]
        s = np.delete(s, np.s_[y - h:y])
        active = np.delete(active, np.s_[y - h:y])
        hm = np.delete(hm, np.s_[y - h:y])
    return groups


def collapse(gray: np.ndarray, groups: list[list[int]], axis: int = 0) -> np.ndarray:
    """The IF image for display/analysis: the mean of each stack (§2.3, Fig. 6 shows the
    average colour).  ``axis=0`` collapses rows, ``axis=1`` columns."""
    g = np.asarray(gray, dtype=np.float64)
    if axis == 1:
        return collapse(g.T, groups, 0).T
    return np.stack([g[idx].mean(axis=0) for idx in groups]) if groups else g[:0]


def irreducible_facade_2d(gray: np.ndarray, v_range: tuple[int, int], h_range: tuple[int, int],
                          bins: int = 32, threshold: float = 0.75
                          ) -> tuple[list[list[int]], list[list[int]]]:
    """Vertical then horizontal irreducible facade (§2.3): row stacks from the vertical profile
    of ``gray``, then column stacks from the horizontal profile of the vertically collapsed
    image (mean per row stack).  Returns ``(row_groups, col_groups)`` of original indices."""
    rows = irreducible_facade(symmetry_profile(gray, v_range, axis=0, bins=bins), threshold)
    small = collapse(gray, rows, axis=0)
    cols = irreducible_facade(symmetry_profile(small, h_range, axis=1, bins=bins), threshold)
    return rows, cols


def mean_period(profile: SymmetryProfile, harmonic: float = 0.8) -> int:
    """The repetition period (pixels) from the *average* symmetry ``m(h) = mean_y S(y, h)``.

    Neighbouring rows (columns) are alike, so ``S`` is high for small ``h`` whatever the facade:
    :func:`dominant_period` then returns the smallest ``h`` allowed when the range starts
    below the correlation length (tiles: 0.5 m).  Here the trivial decay is discounted: each
    local maximum of ``m`` is scored by its topographic prominence (as ``scipy.signal.peak_prominences`` defines it; computed
    here because importing ``scipy.signal`` costs two seconds),
    and among peaks within ``harmonic`` of the best prominence the shortest period wins (multiples
    of the period are peaks too).  0 when ``m`` has no interior peak.
    """
    S = profile.S
    with np.errstate(invalid="ignore"):
        cnt = np.isfinite(S).sum(axis=0)
        m = np.where(cnt > 0, np.nansum(np.where(np.isfinite(S), S, 0.0), axis=0)
                     / np.maximum(cnt, 1), np.nan)
    ok = np.isfinite(m)
    if ok.sum() < 3:
        return 0
    m = np.where(ok, m, np.nanmin(m))
    peaks, proms = _peak_prominences(m)
    if peaks.size == 0:
        return 0
    keep = proms >= harmonic * proms.max()
    return int(profile.hs[peaks[keep][0]])


def _peak_prominences(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Strict interior local maxima of ``m`` (plateaus: their first sample) and their
    topographic prominences: height above the higher of the two lowest points reachable on each
    side before a higher sample."""
    n = m.size
    peaks, proms = [], []
    for i in range(1, n - 1):
        if not (m[i] > m[i - 1] and m[i] >= m[i + 1]):
            continue
        j = i - 1
        left = m[i]
        while j >= 0 and m[j] <= m[i]:
            left = min(left, m[j])
            j -= 1
        k = i + 1
        right = m[i]
        while k < n and m[k] <= m[i]:
            right = min(right, m[k])
            k += 1
        prom = m[i] - max(left, right)
        if prom > 0:
            peaks.append(i)
            proms.append(prom)
    return np.asarray(peaks, np.int64), np.asarray(proms, np.float64)
