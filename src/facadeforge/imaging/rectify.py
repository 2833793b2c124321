"""Facade rectification: line segments → two vanishing points → fronto-parallel homography.

This is the rectification of Müller et al. 2007, Appendix A ("a variant of the algorithm
presented by Liebowitz and Zisserman [1998]"): image gradients give local edges, edges give
straight lines, RANSAC finds the two dominant vanishing points (the vertical and the horizontal
direction of the facade plane), and the 2D projective transformation that sends both vanishing
points to infinity rectifies the image (Liebowitz, D. and Zisserman, A. 1998, *Metric
rectification for perspective images of planes*, CVPR, 482–488: the "affine" stage maps the
imaged line at infinity ``l = v_v × v_h`` back to ``(0, 0, 1)``; the two known directions then
fix the remaining affinity up to the aspect ratio).

Differences from the paper: lines come from OpenCV's LSD line segment detector (a gradient-based
detector; probabilistic Hough on Canny edges when the installed OpenCV lacks LSD) rather than a
global Hough transform, RANSAC scores hypotheses by the summed length of consistent segments, and
each vanishing point is refined by weighted least squares on its inliers.

Conventions
    Pixel coordinates are ``(x, y)`` with pixel ``(r, c)`` centred at ``(c + 0.5, r + 0.5)``, as
    in :mod:`facadeforge.datasets.synthetic`; y points down.  Vanishing points are homogeneous
    3-vectors of unit norm in these coordinates (``w = 0`` for a point at infinity, i.e.
    parallel image lines).  A homography ``H`` returned here maps **input photo pixels →
    rectified pixels** (``x_rect ~ H @ [x, y, 1]``); :attr:`Rectification.inverse` maps back.

The aspect ratio of the rectified facade is not observable from two vanishing points alone; the
affine correction keeps lengths along both facade directions at the image centre (where the
projective part has the identity Jacobian), which is exact for a fronto-parallel camera and a
first-order estimate otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..frames import warp

__all__ = ["Rectification", "detect_segments", "rectify", "rectifying_homography",
           "segment_geometry", "to_rgb8", "vanishing_points", "warped_bounds"]

#: Inlier threshold: angle (degrees) between a segment and the direction to the vanishing point.
INLIER_ANGLE_DEG = 2.0
#: Segments within this angle (degrees) of the image vertical are vertical candidates; the rest
#: within this angle of the image horizontal are horizontal candidates.
FAMILY_ANGLE_DEG = 40.0
#: Fewest inlier segments for a vanishing point to count as found.
MIN_INLIERS = 4
#: Smallest image side (pixels) rectification attempts.
MIN_SIDE = 16


# ================================================================================ helpers
def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - dependency is declared
        raise InputError("rectification needs OpenCV: install opencv-python-headless") from exc
    return cv2


def to_rgb8(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 from gray, RGB, RGBA, 16-bit or float images."""
    a = np.asarray(image)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise InputError(f"expected an (H, W), (H, W, 3) or (H, W, 4) image, got shape {a.shape}")
    if a.shape[2] in (2, 4):  # drop alpha
        a = a[:, :, :-1]
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    if a.dtype == np.bool_:
        return a.astype(np.uint8) * 255
    if np.issubdtype(a.dtype, np.integer):
        hi = 65535.0 if a.dtype.itemsize >= 2 and a.max(initial=0) > 255 else 255.0
        return np.clip(a.astype(np.float64) * (255.0 / hi), 0, 255).round().astype(np.uint8)
    f = a.astype(np.float64)
    if not np.all(np.isfinite(f)):
        raise InputError("image has NaN or infinite values")
    if f.max(initial=0.0) <= 1.0:
        f = f * 255.0
    return np.clip(f, 0, 255).round().astype(np.uint8)


def _to_gray_u8(gray: np.ndarray) -> np.ndarray:
    a = np.asarray(gray)
    if a.ndim == 3:
        rgb = to_rgb8(a).astype(np.float32)
        return (rgb @ np.array([0.299, 0.587, 0.114], np.float32)).round().astype(np.uint8)
    if a.ndim != 2:
        raise InputError(f"expected a 2D grayscale image, got shape {a.shape}")
    return to_rgb8(a)[:, :, 0]


def segment_geometry(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lengths and orientations of ``(N, 4)`` segments ``x1, y1, x2, y2``.

    Orientations are in radians in ``[0, π)``, measured from the image x axis (y down), so
    ``π/2`` is vertical.
    """
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    d = s[:, 2:4] - s[:, 0:2]
    return np.hypot(d[:, 0], d[:, 1]), np.mod(np.arctan2(d[:, 1], d[:, 0]), np.pi)


# ================================================================================ segments
def detect_segments(gray: np.ndarray, min_length: float | None = None) -> np.ndarray:
    """Straight line segments of an image, ``(N, 4)`` float ``x1, y1, x2, y2``, longest first.

    Uses OpenCV's LSD (``createLineSegmentDetector``, gradient orientation and magnitude per
    pixel, as in Müller 2007 App. A) when the build has it, else probabilistic Hough on Canny
    edges.  Coordinates follow the module convention (pixel centres at ``+0.5``).  Segments
    shorter than ``min_length`` (default 3 % of the smaller image side, at least 8 px) are
    dropped.  Lengths and orientations: :func:`segment_geometry`.
    """
    cv2 = _cv2()
    g = _to_gray_u8(gray)
    h, w = g.shape
    if min_length is None:
        min_length = max(8.0, 0.03 * min(h, w))
    if min(h, w) < 4:
        return np.zeros((0, 4))
    segs = None
    try:
        lsd = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD)
        found = lsd.detect(g)[0]
        segs = np.zeros((0, 4)) if found is None else found.reshape(-1, 4).astype(np.float64)
    except (AttributeError, cv2.error):
        segs = None
    if segs is None:  # Hough fallback
        edges = cv2.Canny(cv2.GaussianBlur(g, (5, 5), 1.2), 50, 150)
        found = cv2.HoughLinesP(edges, 1, np.pi / 360, threshold=20,
                                minLineLength=int(min_length), maxLineGap=3)
        segs = np.zeros((0, 4)) if found is None else found.reshape(-1, 4).astype(np.float64)
    segs = segs + 0.5  # OpenCV puts pixel centres at integers
    lengths, _ = segment_geometry(segs)
    keep = lengths >= min_length
    segs, lengths = segs[keep], lengths[keep]
    return segs[np.argsort(-lengths, kind="stable")]


# ================================================================================ vanishing points
@dataclass
class _VPFit:
    vp: np.ndarray | None          # unit homogeneous 3-vector (pixels) or None
    inliers: np.ndarray            # bool mask over the family's segments
    support: float                 # summed inlier length


def _normalizer(shape: tuple[int, int]) -> np.ndarray:
    """T: pixels → centred coordinates in about [-1, 1]."""
    h, w = shape[:2]
    s = 2.0 / max(h, w, 1)
    return np.array([[s, 0, -s * w / 2], [0, s, -s * h / 2], [0, 0, 1.0]])


def _lines(seg_n: np.ndarray) -> np.ndarray:
    """Homogeneous lines through normalised segments, scaled so that a² + b² = 1."""
    p = np.c_[seg_n[:, 0:2], np.ones(len(seg_n))]
    q = np.c_[seg_n[:, 2:4], np.ones(len(seg_n))]
    ln = np.cross(p, q)
    return ln / np.maximum(np.hypot(ln[:, 0], ln[:, 1]), 1e-12)[:, None]


def _sin_to_vp(seg_n: np.ndarray, vps: np.ndarray) -> np.ndarray:
    """|sin| of the angle between each segment and the direction from its midpoint to each VP.

    ``vps`` (K, 3) homogeneous; returns (K, N).  Works for VPs at infinity (w = 0).
    """
    mid = 0.5 * (seg_n[:, 0:2] + seg_n[:, 2:4])                       # (N, 2)
    d = seg_n[:, 2:4] - seg_n[:, 0:2]
    d = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    # direction to vp: v_xy - w * mid   (K, N, 2)
    to = vps[:, None, 0:2] - vps[:, None, 2:3] * mid[None]
    norm = np.maximum(np.hypot(to[..., 0], to[..., 1]), 1e-12)
    cross = d[None, :, 0] * to[..., 1] - d[None, :, 1] * to[..., 0]
    return np.abs(cross) / norm


def _refine(lines: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Least-squares VP: unit v minimising Σ wᵢ (lᵢ·v)², the smallest eigenvector."""
    m = (lines * weights[:, None]).T @ lines
    _, vecs = np.linalg.eigh(m)
    return vecs[:, 0]


def _ransac_vp(seg_n: np.ndarray, rng: np.random.Generator, iterations: int = 400,
               angle_deg: float = INLIER_ANGLE_DEG) -> _VPFit:
    n = len(seg_n)
    empty = _VPFit(None, np.zeros(n, bool), 0.0)
    if n < 2:
        return empty
    lengths, _ = segment_geometry(seg_n)
    lines = _lines(seg_n)
    thr = np.sin(np.radians(angle_deg))
    p = lengths / lengths.sum()
    i = rng.choice(n, size=iterations, p=p)
    j = rng.choice(n, size=iterations, p=p)
    ok = i != j
    i, j = i[ok], j[ok]
    if len(i) == 0:
        return empty
    vps = np.cross(lines[i], lines[j])
    nv = np.linalg.norm(vps, axis=1)
    good = nv > 1e-12
    vps = vps[good] / nv[good, None]
    if len(vps) == 0:
        return empty
    inl = _sin_to_vp(seg_n, vps) < thr                                 # (K, N)
    score = inl.astype(np.float64) @ lengths
    best = int(np.argmax(score))
    mask = inl[best]
    vp = vps[best]
    for _ in range(3):  # refine on inliers, re-select inliers
        if mask.sum() < 2:
            break
        vp = _refine(lines[mask], lengths[mask])
        new = _sin_to_vp(seg_n, vp[None])[0] < thr
        if new.sum() < 2 or np.array_equal(new, mask):
            mask = new if new.sum() >= 2 else mask
            break
        mask = new
    if mask.sum() < MIN_INLIERS:
        return _VPFit(None, mask, float(lengths[mask].sum()))
    return _VPFit(vp, mask, float(lengths[mask].sum()))


def _families(segments: np.ndarray, family_deg: float = FAMILY_ANGLE_DEG):
    _, ang = segment_geometry(segments)
    from_vertical = np.abs(ang - np.pi / 2)
    from_horizontal = np.minimum(ang, np.pi - ang)
    t = np.radians(family_deg)
    return from_vertical < t, (from_horizontal < t) & ~(from_vertical < t)


def _fit_family(seg: np.ndarray, mask: np.ndarray, T: np.ndarray, rng) -> _VPFit:
    """RANSAC vanishing point of the segments ``mask`` selects, in normalised coordinates
    (:func:`_normalizer` ``T``), returned in pixels with the inlier mask over all of ``seg``."""
    seg_n = np.c_[seg[:, 0:2] * T[0, 0] + T[0:2, 2], seg[:, 2:4] * T[0, 0] + T[0:2, 2]]
    fit = _ransac_vp(seg_n[mask], rng)
    full = np.zeros(len(seg), bool)
    full[np.flatnonzero(mask)] = fit.inliers
    vp = None
    if fit.vp is not None:
        vp = np.linalg.inv(T) @ fit.vp
        vp = vp / np.linalg.norm(vp)
    return _VPFit(vp, full, fit.support)


def _fit_both(segments: np.ndarray, shape: tuple[int, int], rng: np.random.Generator):
    T = _normalizer(shape)
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    fam_v, fam_h = _families(seg)
    return _fit_family(seg, fam_v, T, rng), _fit_family(seg, fam_h, T, rng)


def vanishing_points(segments: np.ndarray, image_shape: tuple[int, ...] | None = None,
                     rng: np.random.Generator | int | None = 0):
    """The vertical and horizontal vanishing points of a facade, ``(vp_vertical, vp_horizontal)``.

    RANSAC (Müller 2007 App. A) on near-vertical and near-horizontal segments separately
    (:data:`FAMILY_ANGLE_DEG`): a hypothesis is the intersection ``lᵢ × lⱼ`` of two segment lines
    drawn with probability proportional to length; a segment supports it when the angle
    between the segment and the direction from its midpoint to the point is below
    :data:`INLIER_ANGLE_DEG`; the best-supported hypothesis (summed inlier length) is refined
    by weighted least squares on its inliers.  Parallel segments give a point at infinity
    (``w ≈ 0``), which is handled like any other.

    Returns unit homogeneous 3-vectors in pixels (module convention), or ``None`` for a
    family with fewer than :data:`MIN_INLIERS` consistent segments.  ``image_shape`` only
    conditions the computation (default: the segments' bounding box).
    """
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    if image_shape is None:
        hi = seg.reshape(-1, 2).max(axis=0) if len(seg) else np.array([1.0, 1.0])
        image_shape = (max(int(np.ceil(hi[1])), 1), max(int(np.ceil(hi[0])), 1))
    fv, fh = _fit_both(seg, tuple(image_shape[:2]), np.random.default_rng(rng))
    return fv.vp, fh.vp


# ================================================================================ homography
def rectifying_homography(vp_v, vp_h, image_shape: tuple[int, ...],
                          max_scale: float = 4.0) -> np.ndarray:
    """3×3 homography, input photo pixels → rectified pixels, sending both VPs to infinity.

    ``H = S · A · P · T`` with ``T`` normalising pixels to the centred square ``[-1, 1]``;
    ``P = [[1, 0, 0], [0, 1, 0], l]`` where ``l = T⁻ᵀ (vp_v × vp_h)`` is the imaged line at
    infinity scaled to ``l₃ = 1`` (Liebowitz & Zisserman 1998), so both vanishing points map to
    points at infinity and P has the identity Jacobian at the image centre; ``A`` is the affinity
    mapping the two facade directions to the x axis (horizontal, pointing right) and the y axis
    (vertical, pointing down), keeping unit length along each at the centre, so the result has
    positive orientation (no mirror); ``S`` scales and translates so that the warped input
    quadrilateral has about the input's area (at most ``max_scale``² times larger in any case)
    and its bounding box starts at ``(0, 0)``.  The output size is :func:`warped_bounds`.
    ``None`` for a VP means the image axis direction (a point at infinity).

    Raises :class:`InputError` when the vanishing line crosses the image or the two directions
    are (nearly) parallel.
    """
    h, w = int(image_shape[0]), int(image_shape[1])
    T = _normalizer((h, w))
    v = np.array([0.0, 1.0, 0.0]) if vp_v is None else np.asarray(vp_v, float)
    u = np.array([1.0, 0.0, 0.0]) if vp_h is None else np.asarray(vp_h, float)
    vn, un = T @ v, T @ u
    vn, un = vn / np.linalg.norm(vn), un / np.linalg.norm(un)
    line = np.cross(vn, un)
    corners = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], float)
    cn = (T @ corners.T).T
    if abs(line[2]) < 1e-9 * np.linalg.norm(line):
        raise InputError("the vanishing line passes through the image centre; cannot rectify")
    line = line / line[2]
    side = cn @ line
    if np.any(side < 0.05):
        raise InputError("the vanishing line crosses the image; the facade view is too oblique")
    P = np.array([[1.0, 0, 0], [0, 1.0, 0], line])
    dv, dh = vn[:2].copy(), un[:2].copy()
    dv /= np.linalg.norm(dv)
    dh /= np.linalg.norm(dh)
    if dv[1] < 0:
        dv = -dv
    if dh[0] < 0:
        dh = -dh
    M = np.c_[dh, dv]
    if abs(np.linalg.det(M)) < 0.1:
        raise InputError("vertical and horizontal vanishing directions are nearly parallel")
    A = np.eye(3)
    A[:2, :2] = np.linalg.inv(M)
    if np.linalg.det(A[:2, :2]) < 0:  # cannot happen with the sign choices above; be safe
        A[0, :2] *= -1
    G = A @ P @ T
    q = (G @ corners.T).T
    q = q[:, :2] / q[:, 2:3]
    x, y = q[:, 0], q[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    s = np.sqrt(w * h / max(area, 1e-12))
    lo, hi = q.min(axis=0), q.max(axis=0)
    span = np.maximum((hi - lo) * s, 1e-9)
    limit = max_scale * np.array([w, h], float)
    s *= min(1.0, float(np.min(limit / span)) if np.all(span > 0) else 1.0)
    S = np.array([[s, 0, -s * lo[0]], [0, s, -s * lo[1]], [0, 0, 1.0]])
    H = S @ G
    return H / H[2, 2]


def _apply(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.c_[np.asarray(pts, float).reshape(-1, 2), np.ones(len(np.asarray(pts).reshape(-1, 2)))]
    q = p @ H.T
    return q[:, :2] / q[:, 2:3]


def warped_bounds(H: np.ndarray, image_shape: tuple[int, ...]) -> tuple[int, int]:
    """``(height, width)`` of the bounding box (from 0) of the input image warped by ``H``."""
    h, w = int(image_shape[0]), int(image_shape[1])
    q = _apply(H, [[0, 0], [w, 0], [w, h], [0, h]])
    return max(int(np.ceil(q[:, 1].max())), 1), max(int(np.ceil(q[:, 0].max())), 1)


# ================================================================================ rectify
@dataclass
class Rectification:
    """A rectified facade image and the homography that made it.

    ``homography`` maps input photo pixels → pixels of ``image`` (crop included), ``inverse``
    maps back (pixel centres at ``+0.5``).  ``vanishing_points`` are the vertical and
    horizontal VPs in input pixels (``None`` when not found).  ``confidence`` in ``[0, 1]``:
    the product, over both families, of ``min(1, inliers / 12)``, times the square root of the
    fraction of all segment length the two VPs explain.  A failed estimate is falsy, keeps the
    input image and the identity, and says why in ``reason``.
    """

    image: np.ndarray
    homography: np.ndarray
    inverse: np.ndarray
    vanishing_points: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
    confidence: float = 0.0
    reason: str = ""
    ok: bool = True
    crop: tuple[int, int, int, int] | None = None   # x0, y0, x1, y1 in the uncropped frame
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)), repr=False)

    def __bool__(self) -> bool:
        return self.ok

    @classmethod
    def failed(cls, reason: str, image: np.ndarray | None = None, **kw) -> Rectification:
        img = np.zeros((0, 0, 3), np.uint8) if image is None else image
        return cls(image=img, homography=np.eye(3), inverse=np.eye(3), confidence=0.0,
                   reason=reason, ok=False, **kw)

    def to_rectified(self, pts) -> np.ndarray:
        """Map ``(N, 2)`` input pixels to rectified pixels."""
        return _apply(self.homography, pts)

    def to_input(self, pts) -> np.ndarray:
        """Map ``(N, 2)`` rectified pixels to input pixels."""
        return _apply(self.inverse, pts)


def rectify(image: np.ndarray, *, crop: bool = True, rng: np.random.Generator | int | None = 0,
            min_segments: int = 8) -> Rectification:
    """Rectify a facade photo to a fronto-parallel view (Müller 2007 App. A).

    Steps: :func:`detect_segments` → :func:`vanishing_points` (RANSAC) →
    :func:`rectifying_homography` → ``cv2.warpPerspective``.  With ``crop`` the result is cut to
    the dominant facade, kept simple: the bounding box of the endpoints of the segments that
    support either vanishing point, in the rectified frame, grown by 3 % of the output size
    on each side and clipped to the warped input's bounding box.  Grayscale, RGBA, 16-bit and
    float images are converted to 8-bit RGB first.

    Returns a falsy :meth:`Rectification.failed` (identity, input image, ``reason``) when there
    is too little evidence: fewer than ``min_segments`` segments, or neither vanishing point
    found.  When only one is found the other is taken as the image axis (at infinity), with
    half the confidence and a note in ``reason``.  Raises :class:`InputError` for images that
    are not images (wrong shape, NaN values).
    """
    rgb = to_rgb8(image)
    h, w = rgb.shape[:2]
    if min(h, w) < MIN_SIDE:
        return Rectification.failed(f"image too small ({w}x{h}); need at least {MIN_SIDE} px "
                                    "per side", rgb)
    gen = np.random.default_rng(rng)
    segs = detect_segments(rgb)
    if len(segs) < min_segments:
        return Rectification.failed(f"not enough line segments ({len(segs)} < {min_segments})",
                                    rgb, segments=segs)
    fv, fh = _fit_both(segs, (h, w), gen)
    if fv.vp is None and fh.vp is None:
        return Rectification.failed("no consistent vertical or horizontal lines", rgb,
                                    segments=segs)
    notes = []
    if fv.vp is None:
        notes.append("no vertical vanishing point; assumed image vertical")
    if fh.vp is None:
        notes.append("no horizontal vanishing point; assumed image horizontal")
    try:
        H = rectifying_homography(fv.vp, fh.vp, (h, w))
    except InputError as exc:
        return Rectification.failed(str(exc), rgb, vanishing_points=(fv.vp, fh.vp),
                                    segments=segs)
    out_h, out_w = warped_bounds(H, (h, w))
    box = (0, 0, out_w, out_h)
    inl = fv.inliers | fh.inliers
    if crop and inl.sum() >= 2:
        pts = _apply(H, segs[inl].reshape(-1, 2))
        mx, my = 0.03 * out_w, 0.03 * out_h
        x0 = int(np.clip(np.floor(pts[:, 0].min() - mx), 0, out_w - 1))
        y0 = int(np.clip(np.floor(pts[:, 1].min() - my), 0, out_h - 1))
        x1 = int(np.clip(np.ceil(pts[:, 0].max() + mx), x0 + 1, out_w))
        y1 = int(np.clip(np.ceil(pts[:, 1].max() + my), y0 + 1, out_h))
        box = (x0, y0, x1, y1)
        H = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1.0]]) @ H
        out_w, out_h = x1 - x0, y1 - y0
    warped = warp(rgb, H, (out_h, out_w))
    lengths, _ = segment_geometry(segs)
    frac = float(lengths[inl].sum() / max(lengths.sum(), 1e-12))
    conf = np.sqrt(frac)
    for f in (fv, fh):
        conf *= 0.5 if f.vp is None else min(1.0, f.inliers.sum() / 12.0)
    return Rectification(image=warped, homography=H, inverse=np.linalg.inv(H),
                         vanishing_points=(fv.vp, fh.vp), confidence=float(conf),
                         reason="; ".join(notes), ok=True, crop=box, segments=segs)
