"""One facade at a time: a street photo cut into its facade planes and houses.

A street photo often shows a corner (two facade planes) or several houses side by side;
:func:`find_facades` finds them, so that each can be rectified and analysed alone
(``facadeforge reconstruct``'s ``--facades auto``).

1. **Planes.**  Line segments and the vertical vanishing point as in :mod:`.rectify`
   (Müller 2007 App. A); then the horizontal vanishing points by *sequential* RANSAC: the
   best-supported horizontal family first, then, without its inliers, a second one.  The second
   is a facade plane of its own only when it has enough support (:data:`SECOND_PLANE_SUPPORT`,
   :data:`SECOND_PLANE_MIN_INLIERS`), is a different direction (:data:`DISTINCT_DEG`) and lies
   apart: the two planes' horizontal segments are voted along the image's *vertical-line
   coordinate* ``u`` (where the line through the vertical vanishing point and a pixel meets the
   middle row: the column, bent to follow the converging verticals), and the best single cut
   of that 1-D vote must leave :data:`MIN_PLANE_PURITY` of each family's vote on its side.  So a corner view gives two
   ranges of ``u`` split at the corner edge (a line through the vertical vanishing point).
   Each plane is rectified by its own horizontal vanishing point with the common vertical one
   (:func:`.rectify.rectifying_homography` on the plane's part of the photo).
2. **Houses within a plane.**  In the plane's rectified image (at :data:`ANALYSIS_HEIGHT`
   rows) three cues score every column as a boundary between houses: (a) the roof line — the
   lowest row of the uniform (sky) region above the building, per column — steps; (b) the
   floor lines are offset — the row profiles of horizontal edge strength left and right of the
   column correlate less than they do elsewhere in the plane; (c) the material changes — the
   log colour left and right of the column, compared row by row so that a shadow over both
   sides cancels, differs on most rows (:data:`COLOUR_ROWS`).  The cues are summed and a boundary needs most of two
   of them (:data:`SPLIT_SCORE`) and leaves at least :data:`MIN_FACADE_SHARE` of the plane on
   each side: no boundary is better than a wrong one.
3. **Regions.**  Each house of each plane is a :class:`FacadeRegion`: its outline in the photo,
   the homography photo → its rectified crop (the box of its lines, as :func:`.rectify.rectify`
   crops), quality numbers and flags; ``ok`` is false when it cannot be rectified well (too
   few lines, weak vanishing points, too oblique, a narrow sliver).

Conventions as in :mod:`.rectify`: pixel ``(r, c)`` has its centre at ``(c + 0.5, r + 0.5)``,
homographies map photo pixels → rectified pixels.  Everything runs at the size it is given
(``reconstruct`` gives the analysis copy, :func:`facadeforge.photo.analysis_copy`); the line
segment detector is about half of its time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..frames import warp
from .rectify import (
    _families,
    _normalizer,
    _sin_to_vp,
    detect_segments,
    rectifying_homography,
    segment_geometry,
    to_rgb8,
)
from .rectify import (
    _fit_family as _fit_vp_family,
)

__all__ = ["FacadeRegion", "FacadeSplit", "draw_facades", "find_facades"]

# ------------------------------------------------------------------------------- constants
# Chosen by looking at the split of the RueMonge train photos (corner views IMG_5717, 5757,
# 5901-5904, 5927; pairs of houses IMG_5748, 5802, 5813, 5859) and of synthetic corners and
# pairs (tests/imaging/test_facades.py): each is about half-way between what the true planes
# and houses give and what single facades give.

#: Fewest line segments in the photo for any plane to be found.
MIN_SEGMENTS = 8
#: Summed inlier length of the second horizontal family, as a share of the first's, for it to
#: be a second facade plane (the far sides of RueMonge's corners, foreshortened, have 3-33 %;
#: single facades' second families have 1-9 % too, but fail DISTINCT_DEG).
SECOND_PLANE_SUPPORT = 0.03
#: Fewest inlier segments of the second horizontal family.
SECOND_PLANE_MIN_INLIERS = 12
#: Median angle (degrees) between the second family's segments and the direction to the first
#: vanishing point: a smaller one is the same plane's lines bent by the lens (1.7-3.8 degrees
#: on RueMonge's single facades; the two sides of its corners are 10-23 degrees apart).
DISTINCT_DEG = 6.0
#: Share of each plane's length-weighted vote along ``u`` that must lie on its side of the cut
#: (RueMonge's corners 0.86-0.96; 0.68-0.77 where a corner's far side has too few lines).
MIN_PLANE_PURITY = 0.8
#: A plane narrower than this share of the photo's width is a sliver (flag "narrow").
MIN_PLANE_SHARE = 0.12
#: Rows of the rectified plane image the house boundaries are looked for in.
ANALYSIS_HEIGHT = 240
#: Half-width of the comparison windows left and right of a candidate boundary, as a share of
#: the plane's width (about one window column of a Parisian house).
CUE_WINDOW = 0.12
#: Smallest facade a house boundary may leave on either side, as a share of the plane's width
#: (a narrow Parisian house has three window columns in a photo of two or three houses).
MIN_FACADE_SHARE = 0.15
#: How far above the lines' box the house analysis looks for sky (share of the box's height).
SKY_ABOVE = 0.15
#: Share of the plane image's rows both comparison windows must cover for the floor and colour
#: cues (near the photo's edges fewer rows are seen, and their profiles are noise).
MIN_BODY_ROWS = 0.4
#: Roof-line step (share of the plane image's height) that scores the roof cue 1.
ROOF_STEP = 0.05
#: Drop of the floor-profile correlation below the plane's typical value that scores 1.
FLOOR_DROP = 0.45
#: Colour difference (the length of the difference of log R, G, B medians) below which the
#: material cue is 0, and the further difference that scores it 1.
COLOUR_DE0, COLOUR_DE_RANGE = 0.2, 0.25
#: Percentile of the per-row colour differences taken (30: seven rows in ten must differ).
COLOUR_ROWS = 30
#: Summed cue score (three cues of at most 1) a house boundary needs (RueMonge: 1.7-2.4 at the
#: boundaries of IMG_5744, 5748, 5802, 5813, 5833, 5843, 5859; at most 1.3 inside the single
#: houses of IMG_5720, 5758, 5797, 5807, 5927).
SPLIT_SCORE = 1.5
#: Largest ratio of photo pixels per facade area between the best and the worst seen corner of
#: a rectified crop; beyond it the far end is smeared (flag "oblique view").
MAX_STRETCH = 12.0
#: Fewest horizontal / vertical inlier segments inside a facade (flag "few lines").
MIN_FACADE_LINES, MIN_FACADE_VERTICALS = 6, 3
#: Fewest facade lines per area: the summed length of its inlier segments times the photo's
#: shorter side over its area in the photo (RueMonge facades 30-50, LabelMeFacade facades
#: 13-29, trees, roads and sidewalks 5-11).
MIN_LINE_DENSITY = 10.0
#: Share of a facade's near-horizontal segment length its vanishing point must explain
#: (flag "weak rectification").
MIN_LINE_SHARE = 0.3
#: Margin around the lines' box of a crop, as a share of the crop (as :func:`.rectify.rectify`).
CROP_MARGIN = 0.03

_BLOCKING = ("few lines", "weak rectification", "oblique view", "narrow", "no rectification")


# ------------------------------------------------------------------------------- results
@dataclass(eq=False)
class FacadeRegion:
    """One facade of a photo.

    ``id`` counts from 1, left to right; ``plane`` indexes :attr:`FacadeSplit.planes`.
    ``polygon`` (4, 2) is the rectified crop's outline in photo pixels (top-left, top-right,
    bottom-right, bottom-left; it may reach outside the photo where the crop does),
    ``homography`` maps photo pixels → the rectified crop of ``size`` = ``(height, width)``.
    ``quality`` holds the numbers ``flags`` are read from; ``ok`` is false when a flag says it
    cannot be rectified well (:data:`_BLOCKING`).
    """

    id: int
    plane: int
    polygon: np.ndarray
    homography: np.ndarray
    size: tuple[int, int]
    quality: dict = field(default_factory=dict)
    flags: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not any(f.split(" (")[0] in _BLOCKING for f in self.flags)

    def rectified(self, rgb: np.ndarray) -> np.ndarray:
        """The facade's rectified crop of the photo ``rgb`` it was found in."""
        return warp(to_rgb8(rgb), self.homography, self.size)

    def to_dict(self) -> dict:
        return {"id": self.id, "plane": self.plane,
                "polygon": [[round(float(x), 1), round(float(y), 1)] for x, y in self.polygon],
                "ok": self.ok, "flags": list(self.flags),
                "rectified_size": [int(self.size[1]), int(self.size[0])],
                "homography": np.asarray(self.homography).tolist(), "quality": self.quality}


@dataclass
class FacadeSplit:
    """What :func:`find_facades` found: ``regions`` left to right, the ``planes`` (their
    horizontal vanishing points, ``u`` ranges and house boundaries), the common vertical
    vanishing point, the photo's ``segments`` and the time taken."""

    regions: list[FacadeRegion]
    planes: list[dict]
    vp_vertical: np.ndarray | None
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)), repr=False)
    seconds: float = 0.0
    focal: dict = field(default_factory=dict)

    @property
    def usable(self) -> list[FacadeRegion]:
        return [r for r in self.regions if r.ok]

    def to_dict(self) -> dict:
        return {"planes": self.planes, "focal": self.focal,
                "vp_vertical": None if self.vp_vertical is None else self.vp_vertical.tolist(),
                "seconds": round(self.seconds, 4),
                "facades": [r.to_dict() for r in self.regions]}


# ------------------------------------------------------------------------------- helpers
def _apply(H: np.ndarray, pts) -> np.ndarray:
    p = np.asarray(pts, float).reshape(-1, 2)
    q = np.c_[p, np.ones(len(p))] @ np.asarray(H, float).T
    return q[:, :2] / q[:, 2:3]


def _translate(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0, dx], [0, 1.0, dy], [0, 0, 1.0]])


def _u_coord(vp_v: np.ndarray | None, pts: np.ndarray, y_ref: float) -> np.ndarray:
    """Where the line through the vertical vanishing point and each point meets row
    ``y_ref`` (the column, for a vertical vanishing point at infinity)."""
    p = np.asarray(pts, float).reshape(-1, 2)
    if vp_v is None:
        return p[:, 0].copy()
    ph = np.c_[p, np.ones(len(p))]
    lines = np.cross(np.asarray(vp_v, float)[None], ph)
    q = np.cross(lines, np.array([0.0, 1.0, -y_ref])[None])
    w = np.where(np.abs(q[:, 2]) < 1e-12, 1e-12, q[:, 2])
    return q[:, 0] / w


def _fit_family(seg: np.ndarray, mask: np.ndarray, T: np.ndarray, gen) -> tuple:
    """RANSAC vanishing point of the segments ``mask`` selects (rectify's fit): (vp in pixels or
    None, full inlier mask, inlier length)."""
    fit = _fit_vp_family(seg, mask, T, gen)
    return fit.vp, fit.inliers, fit.support


def _angle_to(seg: np.ndarray, vp: np.ndarray | None) -> np.ndarray:
    """Angle (degrees) between each segment and the direction from its midpoint to ``vp``
    (zeros for ``None``)."""
    if len(seg) == 0 or vp is None:
        return np.zeros(len(seg))
    s = _sin_to_vp(np.asarray(seg, float), np.asarray(vp, float)[None])[0]
    return np.degrees(np.arcsin(np.clip(s, 0.0, 1.0)))


def _coverage(u0: np.ndarray, u1: np.ndarray, weight: np.ndarray, lo: float, hi: float,
              bins: int) -> np.ndarray:
    """Length-weighted coverage of the ``u`` intervals ``[u0, u1]`` on ``bins`` bins of
    ``[lo, hi]``."""
    a, b = np.minimum(u0, u1), np.maximum(u0, u1)
    scale = bins / max(hi - lo, 1e-9)
    ia = np.clip(np.floor((a - lo) * scale).astype(int), 0, bins - 1)
    ib = np.clip(np.floor((b - lo) * scale).astype(int), 0, bins - 1)
    dens = weight / (ib - ia + 1)
    diff = np.zeros(bins + 1)
    np.add.at(diff, ia, dens)
    np.add.at(diff, ib + 1, -dens)
    return np.cumsum(diff)[:bins]


def _nanquantile(a: np.ndarray, q: float, axis: int) -> np.ndarray:
    """The ``q`` quantile along ``axis`` ignoring NaN (the nearest lower rank; one sort, where
    ``np.nanpercentile`` loops over the other axis in Python)."""
    a = np.sort(np.moveaxis(a, axis, -1), axis=-1)            # NaN sort last
    n = np.isfinite(a).sum(axis=-1)
    k = np.clip(np.floor(q * (n - 1)).astype(int), 0, a.shape[-1] - 1)
    out = np.take_along_axis(a, k[..., None], axis=-1)[..., 0]
    return np.where(n > 0, out, np.nan)


def _smooth(v: np.ndarray, sigma: float) -> np.ndarray:
    from scipy.ndimage import gaussian_filter1d

    return gaussian_filter1d(np.asarray(v, float), max(sigma, 1e-3), mode="nearest")


# ------------------------------------------------------------------------------- planes
def _planes(seg: np.ndarray, shape: tuple[int, int], gen) -> tuple:
    """The vertical VP, its inliers, the planes (left to right: dicts with the horizontal VP
    ``vp``, its ``inliers`` mask and the ``u`` range) and notes on the second plane."""
    h, w = shape
    T = _normalizer(shape)
    fam_v, fam_h = _families(seg)
    lengths, _ = segment_geometry(seg)
    vp_v, inl_v, _ = _fit_family(seg, fam_v, T, gen)
    vp1, inl1, sup1 = _fit_family(seg, fam_h, T, gen)
    y_ref = h / 2.0
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    uc = _u_coord(vp_v, corners, y_ref)
    u_lo, u_hi = float(min(uc.min(), 0.0)), float(max(uc.max(), w))
    planes = [{"vp": vp1, "inliers": inl1, "support": sup1, "u": (u_lo, u_hi)}]
    notes: list[str] = []
    if vp1 is None:
        return vp_v, inl_v, planes, notes
    rest = fam_h & ~inl1
    vp2, inl2, sup2 = _fit_family(seg, rest, T, gen) if rest.sum() >= 2 else (None, rest, 0.0)
    if vp2 is None:
        return vp_v, inl_v, planes, notes
    share = sup2 / max(sup1, 1e-9)
    if share < SECOND_PLANE_SUPPORT or inl2.sum() < SECOND_PLANE_MIN_INLIERS:
        notes.append(f"second horizontal family too weak ({share:.2f} of the first's length, "
                     f"{int(inl2.sum())} segments)")
        return vp_v, inl_v, planes, notes
    d12 = float(np.median(_angle_to(seg[inl2], vp1)))
    d21 = float(np.median(_angle_to(seg[inl1], vp2)))
    if min(d12, d21) < DISTINCT_DEG:
        notes.append(f"second horizontal family within {min(d12, d21):.1f} degrees of the first")
        return vp_v, inl_v, planes, notes
    # where along u each family lies: one cut must separate them
    bins = 256
    votes = []
    for inl in (inl1, inl2):
        s = seg[inl]
        ua = _u_coord(vp_v, s[:, 0:2], y_ref)
        ub = _u_coord(vp_v, s[:, 2:4], y_ref)
        votes.append(_smooth(_coverage(ua, ub, lengths[inl], u_lo, u_hi, bins), bins * 0.01))
    centre = [float(np.sum(v * np.arange(bins)) / max(v.sum(), 1e-9)) for v in votes]
    left, right = (0, 1) if centre[0] <= centre[1] else (1, 0)
    vl, vr = votes[left], votes[right]
    cl = np.r_[0.0, np.cumsum(vl)] / max(vl.sum(), 1e-9)
    cr = np.r_[0.0, np.cumsum(vr)] / max(vr.sum(), 1e-9)
    # the shares of each family on the wrong side of the cut, each family weighing the same
    # (the second family is often a tenth of the first)
    cost = cr + (1.0 - cl)
    cut = int(np.argmin(cost))
    purity = float(min(1.0 - cr[cut], cl[cut]))
    if purity < MIN_PLANE_PURITY or cut in (0, bins):
        notes.append(f"the two horizontal families overlap along the photo (purity "
                     f"{purity:.2f})")
        return vp_v, inl_v, planes, notes
    u_cut = u_lo + (u_hi - u_lo) * cut / bins
    p2 = {"vp": vp2, "inliers": inl2, "support": sup2}
    both = [planes[0], p2]
    both[left]["u"], both[right]["u"] = (u_lo, u_cut), (u_cut, u_hi)
    for p in both:
        p["purity"] = purity
    notes.append(f"second plane: {share:.2f} of the first's length, {int(inl2.sum())} segments, "
                 f"{min(d12, d21):.1f} degrees apart, purity {purity:.2f}")
    return vp_v, inl_v, [both[left], both[right]], notes


def _plane_homography(vp_v, vp_h, shape, u_range, y_ref) -> np.ndarray:
    """Photo → plane-rectified pixels for the part of the photo in ``u_range`` (its bounding
    box is the image :func:`rectifying_homography` checks the vanishing line against)."""
    h, w = shape
    ua, ub = u_range
    pts = []
    for u in (ua, ub):
        for y in (0.0, float(h)):
            pts.append(_line_point(vp_v, u, y_ref, y))
    pts = np.array(pts)
    x0 = float(np.clip(pts[:, 0].min(), 0, w - 1))
    x1 = float(np.clip(pts[:, 0].max(), x0 + 1, w))
    Tr = _translate(-x0, 0.0)
    sub = (h, max(int(np.ceil(x1 - x0)), 1))
    v = None if vp_v is None else Tr @ vp_v
    return rectifying_homography(v, Tr @ vp_h, sub) @ Tr


def _line_point(vp_v, u: float, y_ref: float, y: float) -> np.ndarray:
    """The point at row ``y`` of the line through the vertical VP and ``(u, y_ref)``."""
    if vp_v is None or abs(vp_v[2]) < 1e-12 * np.linalg.norm(vp_v):
        d = np.array([0.0, 1.0]) if vp_v is None else np.asarray(vp_v[:2], float)
        if abs(d[1]) < 1e-12:
            return np.array([u, y])
        return np.array([u + d[0] / d[1] * (y - y_ref), y])
    vx, vy = vp_v[0] / vp_v[2], vp_v[1] / vp_v[2]
    if abs(vy - y_ref) < 1e-9:
        return np.array([u, y])
    t = (y - y_ref) / (vy - y_ref)
    return np.array([u + t * (vx - u), y])


# ------------------------------------------------------------------------------- houses
def _house_boundaries(img: np.ndarray, valid: np.ndarray, min_share: float = MIN_FACADE_SHARE
                      ) -> tuple[list[int], dict]:
    """Columns of ``img`` (a plane's rectified image, small) where one house ends and the next
    begins, each house at least ``min_share`` of the width, and the cue profiles (for reports
    and tests)."""
    import cv2

    h, w = img.shape[:2]
    win = max(4, int(round(CUE_WINDOW * w)))
    min_w = max(int(np.ceil(max(min_share, MIN_FACADE_SHARE) * w)), win)
    info: dict = {"window_px": win}
    if w < 2 * min_w + 2 or h < 16:
        return [], info
    valid = valid.astype(bool)
    if not valid.all() and valid.any():    # what the photo does not cover: its nearest pixel
        from scipy.ndimage import distance_transform_edt

        _, (iy, ix) = distance_transform_edt(~valid, return_indices=True)
        img = img[iy, ix]
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    g = cv2.GaussianBlur(gray, (3, 3), 0.8)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    inner = cv2.erode(valid.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)

    # (a) roof line: the lowest row of the uniform region hanging from the top of each column
    grad = cv2.blur(np.hypot(gx, gy), (5, 5))
    flat = grad < 12.0
    nonsky = inner & ~flat
    run = nonsky[:-2] & nonsky[1:-1] & nonsky[2:]
    run = np.vstack([run, np.zeros((2, w), bool)])
    first_valid = np.where(inner.any(axis=0), np.argmax(inner, axis=0), h)
    rows = np.arange(h)[:, None]
    run &= rows >= first_valid[None]
    top = np.where(run.any(axis=0), np.argmax(run, axis=0), h).astype(float)
    has_sky = (top - first_valid >= 3) & (top < h)

    # (b) floor lines: row profiles of horizontal edges, left and right of each column
    ey = np.maximum(np.abs(gy) - 0.5 * np.abs(gx), 0.0) * inner
    ey = cv2.GaussianBlur(ey, (0, 0), sigmaX=0.1, sigmaY=1.5)
    # (c) material: log colour, so that a row in shadow on both sides compares as in the sun
    logc = np.log(img.astype(np.float32) + 8.0)

    from numpy.lib.stride_tricks import sliding_window_view

    cs_e = np.concatenate([np.zeros((h, 1), np.float32), np.cumsum(ey, axis=1)], axis=1)
    cs_v = np.concatenate([np.zeros((h, 1)), np.cumsum(inner, axis=1)], axis=1)
    # candidate columns x: the window [x - win, x) on the left, [x, x + win) on the right
    xs = np.arange(min_w, w - min_w + 1)
    a0, b1 = xs - win, xs + win
    full = ((cs_v[:, xs] - cs_v[:, a0]) >= 0.9 * win) & ((cs_v[:, b1] - cs_v[:, xs]) >= 0.9 * win)
    # (a) separated, not just different: chimneys and dormers move a median, not quartiles
    tops = sliding_window_view(np.where(has_sky, top, np.nan), win)      # (w - win + 1, win)
    tl, tr = tops[a0], tops[xs]
    skyed = (np.isfinite(tl).mean(axis=1) > 0.6) & (np.isfinite(tr).mean(axis=1) > 0.6)
    roof = np.zeros(len(xs))
    if skyed.any():
        ql = [_nanquantile(tl[skyed], q, axis=1) for q in (0.25, 0.75)]
        qr = [_nanquantile(tr[skyed], q, axis=1) for q in (0.25, 0.75)]
        roof[skyed] = np.maximum(np.maximum(ql[0] - qr[1], qr[0] - ql[1]), 0.0) / h
    # rows below the roof line on both sides, seen on both sides
    topw = sliding_window_view(top, win)
    below = np.maximum(np.median(topw[a0], axis=1), np.median(topw[xs], axis=1)) + 2
    body = full & (rows > below[None])                                    # (h, K)
    n = body.sum(axis=0)
    seen = n >= max(12, MIN_BODY_ROWS * h)
    # (b) normalised correlation of the two row profiles over the body rows
    L = (cs_e[:, xs] - cs_e[:, a0]) / win
    R = (cs_e[:, b1] - cs_e[:, xs]) / win
    nn = np.maximum(n, 1)
    L = (L - (L * body).sum(axis=0) / nn) * body
    R = (R - (R * body).sum(axis=0) / nn) * body
    den = np.sqrt((L * L).sum(axis=0) * (R * R).sum(axis=0))
    ncc = np.where(seen & (den > 1e-9), (L * R).sum(axis=0) / np.maximum(den, 1e-9), np.nan)
    # (c) per row the windows' median colours; the COLOUR_ROWS percentile over the body rows
    # (on most rows: a shadow's vertical edge crosses some rows only)
    # (every other row: the colour of a wall does not change from one row to the next)
    med = np.median(sliding_window_view(logc[::2], win, axis=1), axis=-1)  # (h/2, w-win+1, 3)
    d = med[:, a0] - med[:, xs]
    dn = np.where(body[::2], np.sqrt((d * d).sum(axis=2)), np.nan)
    colour = np.zeros(len(xs))
    if seen.any():
        colour[seen] = _nanquantile(dn[:, seen], COLOUR_ROWS / 100.0, axis=0)
    s_roof = np.clip(roof / ROOF_STEP, 0, 1)
    ref = float(np.nanpercentile(ncc, 75)) if np.isfinite(ncc).any() else 0.0
    s_floor = np.where(np.isfinite(ncc), np.clip((ref - np.nan_to_num(ncc)) / FLOOR_DROP, 0, 1),
                       0.0)
    s_colour = np.clip((colour - COLOUR_DE0) / COLOUR_DE_RANGE, 0, 1)
    score = _smooth(s_roof, 1.0) + _smooth(s_floor, 1.0) + _smooth(s_colour, 1.0)
    info.update({"columns": xs.tolist(), "roof": s_roof, "floor": s_floor, "colour": s_colour,
                 "score": score, "top": top, "raw": {"roof": roof, "ncc": ncc, "ncc_ref": ref,
                                                     "colour": colour}})
    cuts: list[int] = []
    for k in np.argsort(-score, kind="stable"):
        if score[k] < SPLIT_SCORE:
            break
        x = int(xs[k])
        if all(abs(x - c) >= min_w for c in cuts):
            cuts.append(x)
    return sorted(cuts), info


# ------------------------------------------------------------------------------- regions
def _crop_box(pts: np.ndarray, bounds: tuple[float, float, float, float]
              ) -> tuple[int, int, int, int] | None:
    """Box of ``pts`` grown by :data:`CROP_MARGIN`, clipped to ``bounds`` (x0, y0, x1, y1)."""
    if len(pts) < 2:
        return None
    bx0, by0, bx1, by1 = bounds
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    m = CROP_MARGIN * (hi - lo)
    x0 = int(np.floor(max(bx0, lo[0] - m[0])))
    y0 = int(np.floor(max(by0, lo[1] - m[1])))
    x1 = int(np.ceil(min(bx1, hi[0] + m[0])))
    y1 = int(np.ceil(min(by1, hi[1] + m[1])))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return x0, y0, x1, y1


def _polygon_area_in(poly: np.ndarray, shape: tuple[int, int]) -> float:
    """Area (photo pixels) of the part of ``poly`` inside the photo."""
    import cv2

    h, w = shape
    box = np.array([[0, 0], [w, 0], [w, h], [0, h]], np.float32)
    p = np.asarray(poly, np.float32)
    if cv2.contourArea(p, oriented=True) < 0:
        p = p[::-1].copy()
    area, _ = cv2.intersectConvexConvex(p, box)
    return float(area)


def _leaves_photo(H: np.ndarray, size: tuple[int, int], shape: tuple[int, int]) -> bool:
    """Whether the left or right edge of a rectified crop runs outside the photo for more than
    a fifth of its height: the facade goes on beyond the photo's edge."""
    hh, ww = size
    h, w = shape
    ys = np.linspace(0.0, hh, 21)
    G = np.linalg.inv(H)
    for x in (0.0, float(ww)):
        p = _apply(G, np.c_[np.full_like(ys, x), ys])
        if np.mean((p[:, 0] < 0.5) | (p[:, 0] > w - 0.5)) > 0.2:
            return True
    return False


def _stretch(H: np.ndarray, size: tuple[int, int]) -> float:
    """Photo pixels per rectified pixel at the best corner of the crop over the worst."""
    G = np.linalg.inv(H)
    hh, ww = size
    c = np.array([[0, 0, 1], [ww, 0, 1], [ww, hh, 1], [0, hh, 1]], float) @ G.T
    wz = np.abs(c[:, 2]) / np.linalg.norm(G[2])
    return float((wz.max() / max(wz.min(), 1e-12)) ** 3)


def _viewing_angle(vp_v, vp_h, centre, shape, focal: float) -> float | None:
    """Angle (degrees) between the facade's normal and the ray to its centre, for a camera of
    ``focal`` pixels with the principal point at the photo's centre."""
    h, w = shape
    K = np.array([[focal, 0, w / 2.0], [0, focal, h / 2.0], [0, 0, 1.0]])
    v = np.array([0.0, 1.0, 0.0]) if vp_v is None else np.asarray(vp_v, float)
    line = np.cross(v, np.asarray(vp_h, float))
    n = K.T @ line
    r = np.linalg.solve(K, np.array([centre[0], centre[1], 1.0]))
    c = abs(float(n @ r)) / max(float(np.linalg.norm(n) * np.linalg.norm(r)), 1e-12)
    return float(np.degrees(np.arccos(np.clip(c, 0.0, 1.0))))


def _focal(shape: tuple[int, int]) -> dict:
    """The focal length (pixels) the viewing angles assume: the longer photo side, a
    36 mm-equivalent lens (RueMonge's calibrated cameras have 0.99 of it).  Two horizontal
    vanishing points would give it if the two sides of a corner were at right angles; Paris's
    street corners often are not (IMG_5901 gave 2.3 times the calibrated focal length)."""
    return {"px": float(max(shape)), "source": "assumed: the longer photo side"}


def _whole(shape, flags, segs, seconds, notes=()) -> FacadeSplit:
    h, w = shape
    poly = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    region = FacadeRegion(1, 0, poly, np.eye(3), (h, w), {"segments": int(len(segs))},
                          list(flags))
    return FacadeSplit([region], [{"notes": list(notes)}], None, segs, seconds)


def find_facades(rgb: np.ndarray, *, rng: np.random.Generator | int | None = 0,
                 segments: np.ndarray | None = None, houses: bool = True) -> FacadeSplit:
    """The facades of a street photo: planes by their vanishing points, houses within each
    plane (module docstring).

    Parameters
    ----------
    rgb : (H, W[, C]) image
        The photo (any kind :func:`.rectify.to_rgb8` converts), at the size to analyse.
    rng : seed or Generator
        RANSAC's random numbers.
    segments : (N, 4), optional
        Line segments of ``rgb`` already detected (:func:`.rectify.detect_segments`).
    houses : bool
        Look for house boundaries within each plane (else one facade per plane).

    Returns
    -------
    FacadeSplit
        At least one region.  A photo without enough lines is one region covering it, flagged
        ``"few lines"`` and not ok.
    """
    t0 = time.perf_counter()
    img = to_rgb8(rgb)
    h, w = img.shape[:2]
    gen = np.random.default_rng(rng)
    seg = detect_segments(img) if segments is None else np.asarray(segments, float).reshape(-1, 4)
    if len(seg) < MIN_SEGMENTS:
        return _whole((h, w), [f"few lines ({len(seg)} segments)"], seg,
                      time.perf_counter() - t0)
    vp_v, inl_v, planes, notes = _planes(seg, (h, w), gen)
    if planes[0]["vp"] is None:
        return _whole((h, w), ["few lines (no consistent horizontal lines)"], seg,
                      time.perf_counter() - t0, notes)
    lengths, _ = segment_geometry(seg)
    fam_v, fam_h = _families(seg)
    y_ref = h / 2.0
    mid_u = _u_coord(vp_v, 0.5 * (seg[:, 0:2] + seg[:, 2:4]), y_ref)
    focal = _focal((h, w))
    regions: list[FacadeRegion] = []
    plane_info: list[dict] = []
    for pi, p in enumerate(planes):
        ua, ub = p["u"]
        inside = (mid_u >= ua) & (mid_u < ub)
        own = p["inliers"] & inside
        pinfo = {"vp_horizontal": p["vp"].tolist(), "u_range": [round(ua, 1), round(ub, 1)],
                 "inliers": int(p["inliers"].sum()),
                 "inlier_length_px": round(float(lengths[p["inliers"]].sum()), 1),
                 "houses": [], "notes": notes if pi == 0 else []}
        plane_info.append(pinfo)
        share_w = (min(ub, w) - max(ua, 0.0)) / w
        base_flags: list[str] = []
        if len(planes) > 1 and share_w < MIN_PLANE_SHARE:
            base_flags.append(f"narrow ({share_w:.0%} of the photo's width)")
        try:
            Hp = _plane_homography(vp_v, p["vp"], (h, w), (ua, ub), y_ref)
        except InputError as exc:
            poly = np.array([_line_point(vp_v, ua, y_ref, 0), _line_point(vp_v, ub, y_ref, 0),
                             _line_point(vp_v, ub, y_ref, h), _line_point(vp_v, ua, y_ref, h)])
            regions.append(FacadeRegion(0, pi, poly, np.eye(3), (h, w),
                                        {"reason": str(exc)},
                                        [*base_flags, f"no rectification ({exc})"]))
            continue
        # the plane's part of the photo in its rectified frame
        photo_quad = _apply(Hp, [[0, 0], [w, 0], [w, h], [0, h]])
        # (the cut between two planes is the line u = const: a column in both frames)
        xa = -np.inf if pi == 0 else float(_apply(Hp, [[ua, y_ref]])[0, 0])
        xb = np.inf if pi == len(planes) - 1 else float(_apply(Hp, [[ub, y_ref]])[0, 0])
        bounds = (max(photo_quad[:, 0].min(), xa), max(photo_quad[:, 1].min(), 0.0),
                  min(photo_quad[:, 0].max(), xb), photo_quad[:, 1].max())
        mine = own | (inl_v & inside)
        pts = _apply(Hp, seg[mine].reshape(-1, 2))
        box = _crop_box(pts, bounds)
        if box is None:
            poly = np.array([_line_point(vp_v, ua, y_ref, 0), _line_point(vp_v, ub, y_ref, 0),
                             _line_point(vp_v, ub, y_ref, h), _line_point(vp_v, ua, y_ref, h)])
            regions.append(FacadeRegion(0, pi, poly, np.eye(3), (h, w), {},
                                        [*base_flags, "few lines (none in this part)"]))
            continue
        X0, Y0, X1, Y1 = box
        # houses: in a small copy of the plane's crop
        cuts: list[float] = []
        if houses and not base_flags:
            # from higher up than the lines reach: the sky above the lower roofs
            ya = int(np.floor(max(bounds[1], Y0 - SKY_ABOVE * (Y1 - Y0))))
            s = ANALYSIS_HEIGHT / max(Y1 - ya, 1)
            S = np.diag([s, s, 1.0]) @ _translate(-X0, -ya) @ Hp
            size = (max(int(round((Y1 - ya) * s)), 1), max(int(round((X1 - X0) * s)), 1))
            if size[1] <= 8 * ANALYSIS_HEIGHT:
                small = warp(img, S, size)
                valid = warp(np.ones((h, w), np.uint8), S, size, nearest=True) > 0
                # a house is at least MIN_FACADE_SHARE of its plane and MIN_PLANE_SHARE of
                # the photo (no slivers from a narrow plane)
                cols, cue = _house_boundaries(small, valid, MIN_PLANE_SHARE / max(share_w, 1e-3))
                cuts = [X0 + c / s for c in cols]
                pinfo["houses"] = [round(c, 1) for c in cuts]
                if cols:
                    k = [cue["columns"].index(c) for c in cols]
                    pinfo["boundary_cues"] = [
                        {"roof": round(float(cue["roof"][i]), 2),
                         "floor": round(float(cue["floor"][i]), 2),
                         "colour": round(float(cue["colour"][i]), 2)} for i in k]
        edges = [X0, *cuts, X1]
        rect_mid = _apply(Hp, 0.5 * (seg[:, 0:2] + seg[:, 2:4]))
        for a, b in zip(edges[:-1], edges[1:]):
            sel = mine & (rect_mid[:, 0] >= a) & (rect_mid[:, 0] < b)
            ys = _apply(Hp, seg[sel].reshape(-1, 2))[:, 1] if sel.sum() >= 4 else np.array([Y0, Y1])
            fy0 = int(np.floor(max(Y0, ys.min() - CROP_MARGIN * (ys.max() - ys.min()))))
            fy1 = int(np.ceil(min(Y1, ys.max() + CROP_MARGIN * (ys.max() - ys.min()))))
            fx0, fx1 = int(np.floor(a)), int(np.ceil(b))
            if fy1 - fy0 < 2:
                fy0, fy1 = Y0, Y1
            Hf = _translate(-fx0, -fy0) @ Hp
            Hf = Hf / Hf[2, 2]
            size = (fy1 - fy0, fx1 - fx0)
            poly = _apply(np.linalg.inv(Hf), [[0, 0], [size[1], 0], [size[1], size[0]],
                                              [0, size[0]]])
            hsel = p["inliers"] & sel
            vsel = inl_v & sel
            hall = fam_h & (rect_mid[:, 0] >= a) & (rect_mid[:, 0] < b) & inside
            line_share = float(lengths[hsel].sum() / max(lengths[hall].sum(), 1e-9))
            res = np.r_[_angle_to(seg[hsel], p["vp"]),
                        _angle_to(seg[vsel], vp_v) if vp_v is not None else []]
            centre = poly.mean(axis=0)
            # the length of its lines per area, in units of the photo's shorter side: a tree,
            # a road or the sky has few
            inside_px = _polygon_area_in(poly, (h, w))
            density = float((lengths[hsel].sum() + lengths[vsel].sum()) * min(h, w)
                            / max(inside_px, 1.0))
            stretch = _stretch(Hf, size)
            angle = _viewing_angle(vp_v, p["vp"], centre, (h, w), focal["px"])
            q = {"horizontal_inliers": int(hsel.sum()), "vertical_inliers": int(vsel.sum()),
                 "line_share": round(line_share, 3),
                 "residual_deg": round(float(np.median(res)) if len(res) else 0.0, 3),
                 "stretch": round(stretch, 2),
                 "viewing_angle_deg": None if angle is None else round(angle, 1),
                 "width_share": round(float((b - a) / max(X1 - X0, 1e-9)), 3),
                 "line_density": round(density, 1)}
            flags = list(base_flags)
            if hsel.sum() < MIN_FACADE_LINES or vsel.sum() < MIN_FACADE_VERTICALS:
                flags.append(f"few lines ({int(hsel.sum())} horizontal, {int(vsel.sum())} "
                             "vertical)")
            elif density < MIN_LINE_DENSITY:
                flags.append(f"few lines (line density {density:.1f})")
            elif line_share < MIN_LINE_SHARE:
                flags.append(f"weak rectification (its vanishing point explains "
                             f"{line_share:.0%} of the horizontal lines)")
            if vp_v is None:
                flags.append("weak rectification (no vertical vanishing point)")
            if stretch > MAX_STRETCH:
                flags.append(f"oblique view (the far end {stretch:.0f}x less sharp)")
            if _leaves_photo(Hf, size, (h, w)):
                flags.append("cut by the photo's edge")
            regions.append(FacadeRegion(0, pi, poly, Hf, size, q, flags))
    regions.sort(key=lambda r: (r.plane, float(_u_coord(vp_v, r.polygon, y_ref).mean())))
    for i, r in enumerate(regions, 1):
        r.id = i
    split = FacadeSplit(regions, plane_info, vp_v, seg, time.perf_counter() - t0, focal)
    return split


# ------------------------------------------------------------------------------- pictures
_COLOURS = [(255, 200, 0), (0, 200, 255), (120, 255, 80), (255, 90, 200), (255, 140, 40),
            (160, 120, 255)]


def draw_facades(rgb: np.ndarray, split: FacadeSplit,
                 homography: np.ndarray | None = None) -> np.ndarray:
    """``facades.png``: the photo with each facade's outline and id (usable facades tinted in
    colour, the others red and dashed, with their first flag).  ``homography`` maps the
    split's pixels to ``rgb``'s (the split was found on a downscaled copy)."""
    import cv2

    G = np.eye(3) if homography is None else np.asarray(homography, float)
    out = to_rgb8(rgb).copy()
    h, w = out.shape[:2]
    thick = max(2, round(max(h, w) / 300))
    scale = max(0.6, max(h, w) / 800)
    tint = out.copy()
    for r in split.regions:       # a translucent tint per facade, the others hatched red
        colour = _COLOURS[(r.id - 1) % len(_COLOURS)] if r.ok else (255, 40, 40)
        pts = np.round(np.clip(_apply(G, r.polygon), -4 * max(h, w), 5 * max(h, w))
                       ).astype(np.int32)
        cv2.fillPoly(tint, [pts.reshape(-1, 1, 2)], colour)
    out = (0.72 * out + 0.28 * tint).astype(np.uint8)
    for r in split.regions:
        colour = _COLOURS[(r.id - 1) % len(_COLOURS)] if r.ok else (255, 40, 40)
        poly = np.clip(_apply(G, r.polygon), -4 * max(h, w), 5 * max(h, w))
        pts = np.round(poly).astype(np.int32)
        if r.ok:
            cv2.polylines(out, [pts.reshape(-1, 1, 2)], True, colour, thick, cv2.LINE_AA)
        else:
            for a, b in zip(pts, np.roll(pts, -1, axis=0)):
                n = max(2, int(np.hypot(*(b - a)) / (8 * thick)))
                for k in range(0, n, 2):
                    p0 = a + (b - a) * k / n
                    p1 = a + (b - a) * min(k + 1, n) / n
                    cv2.line(out, tuple(int(v) for v in p0), tuple(int(v) for v in p1), colour,
                             thick, cv2.LINE_AA)
        cx = float(np.clip(poly[:, 0].mean(), 20, w - 20))
        cy = float(np.clip(poly[:, 1].mean(), 30, h - 20))
        text = str(r.id) if r.ok else f"{r.id}: {r.flags[0].split(' (')[0]}"
        org = (int(cx - 10 * scale), int(cy))
        cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thick + 3,
                    cv2.LINE_AA)
        cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thick, cv2.LINE_AA)
    return out
