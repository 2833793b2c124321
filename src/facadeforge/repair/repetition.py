"""An occluded element painted from its other, unoccluded instances (not in seed ``shang2023``).

Facades repeat their elements: the windows of a floor, of a column, the tiles of a cluster.
Where an occluder hides one instance, the others show what it looks like.  For every box of a
group that holds hole pixels:

1. every *other* instance of the group is resampled to the box's size (``cv2.resize``; area
   averaging when shrinking, bilinear when enlarging), together with its visibility (the
   complement of the hole, resampled the same way — a pixel counts as seen only where its
   whole footprint is unoccluded, so occluder colours never leak in);
2. optionally each instance is re-aligned by a small translation (``±shift`` px in the
   instance's own pixels) maximising the normalised cross-correlation of its grey values with
   the target's *known* pixels — boxes from a detector or a shape tree are often a pixel or two
   off; without enough known target pixels (a wholly hidden window) the box is trusted.
   The default search is ±3 px (relative offsets reach ±4 px;
   ``docs/design-measurements.md``);
3. per pixel, the instances that see it are combined by their median (per channel, weighted by
   visibility); the target's own hole pixels are never read, and a pixel no other instance
   sees stays unfilled;
4. with ``blend`` the painted pixels are merged into their surroundings by a gradient-domain
   (Poisson) solve: the unknowns are the painted hole pixels, the guidance is the gradient of
   the painted estimate inside the box, the boundary values are the known (or already painted)
   pixels next to them, and unfilled hole pixels are a free (Neumann) boundary.  This takes out
   the brightness difference between the instances and the target (shading across a facade;
   a window hidden whole, with little boundary to meet, loses a little:
   ``docs/design-measurements.md``).
   ``cv2.seamlessClone`` was not used: it clamps to every pixel around the mask, occluder
   pixels included, and fails on masks touching the image border.

Boxes where fewer than ``min_cover`` of the hole pixels get a value are left alone.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from facadeforge.errors import InputError

__all__ = ["poisson_blend", "repetition_fill"]

#: Fewest known target pixels (and as a fraction of the box) for the translation search.
MIN_KNOWN_PX = 30
MIN_KNOWN_FRAC = 0.15
#: Context ring (px) around a target box over which the instances are resampled too.
RING = 2


def _resize(a: np.ndarray, w: int, h: int) -> np.ndarray:
    shrink = a.shape[0] > h or a.shape[1] > w
    return cv2.resize(a, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)


def _instance(img: np.ndarray, vis: np.ndarray, box, w: int, h: int):
    x0, y0, x1, y1 = box
    vals = _resize(np.ascontiguousarray(img[y0:y1, x0:x1]), w, h)
    seen = _resize(np.ascontiguousarray(vis[y0:y1, x0:x1]), w, h) > 0.999
    return vals, seen


def _ncc(a: np.ndarray, b: np.ndarray, m: np.ndarray) -> float:
    if m.sum() < MIN_KNOWN_PX:
        return -np.inf
    x, y = a[m], b[m]
    x = x - x.mean()
    y = y - y.mean()
    d = float(np.sqrt((x * x).sum() * (y * y).sum()))
    return float((x * y).sum() / d) if d > 0 else -np.inf


def _weighted_median(vals: np.ndarray, wts: np.ndarray) -> np.ndarray:
    """Per-pixel, per-channel weighted median over axis 0: vals (K, h, w, 3), wts (K, h, w)."""
    order = np.argsort(vals, axis=0, kind="stable")
    v = np.take_along_axis(vals, order, 0)
    wgt = np.take_along_axis(np.broadcast_to(wts[..., None], vals.shape), order, 0)
    cum = np.cumsum(wgt, 0)
    k = np.argmax(cum >= 0.5 * cum[-1:], axis=0)
    return np.take_along_axis(v, k[None], 0)[0]


def poisson_blend(target: np.ndarray, guide: np.ndarray, omega: np.ndarray,
                  known: np.ndarray, guide_ok: np.ndarray | None = None,
                  eps: float = 1e-5) -> np.ndarray:
    """Values on ``omega`` whose gradients follow ``guide`` and which meet ``target`` at the
    ``known`` pixels around them (discrete Poisson equation, 4-neighbours).

    ``target`` and ``guide`` are ``(h, w, C)`` float; ``omega`` the unknowns, ``known`` the
    Dirichlet pixels (neighbours neither known nor in ``omega`` are a Neumann boundary).  The
    guidance of a neighbour pair counts only where ``guide_ok`` holds at both ends (elsewhere
    0).  ``eps`` ties every unknown weakly to ``guide`` so regions without a Dirichlet
    neighbour stay defined.  Returns ``(n, C)``, the values of ``omega``'s pixels in row-major
    order.
    """
    h, w = omega.shape
    if guide_ok is None:
        guide_ok = np.ones((h, w), bool)
    idx = -np.ones((h, w), np.int64)
    ys, xs = np.nonzero(omega)
    n = len(ys)
    idx[ys, xs] = np.arange(n)
    diag = np.full(n, eps)
    rhs = eps * guide[ys, xs].astype(np.float64)
    rows, cols = [], []
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        qy, qx = ys + dy, xs + dx
        inside = (qy >= 0) & (qy < h) & (qx >= 0) & (qx < w)
        qyc, qxc = np.clip(qy, 0, h - 1), np.clip(qx, 0, w - 1)
        inner = inside & omega[qyc, qxc]
        fixed = inside & ~omega[qyc, qxc] & known[qyc, qxc]
        use = inner | fixed
        diag += use
        g_ok = use & guide_ok[ys, xs] & guide_ok[qyc, qxc]
        rhs += np.where(g_ok[:, None], guide[ys, xs] - guide[qyc, qxc], 0.0)
        rhs += np.where(fixed[:, None], target[qyc, qxc], 0.0)
        rows.append(np.nonzero(inner)[0])
        cols.append(idx[qyc[inner], qxc[inner]])
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    a = sp.csc_matrix((np.concatenate([diag, -np.ones(len(r))]),
                       (np.concatenate([np.arange(n), r]), np.concatenate([np.arange(n), c]))),
                      shape=(n, n))
    solve = spla.factorized(a)
    return np.stack([solve(rhs[:, k]) for k in range(rhs.shape[1])], 1)


def _check(rgb, hole, groups):
    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(f"repetition_fill: rgb must be an (H, W, 3) uint8 RGB image, got shape "
                         f"{img.shape} dtype {img.dtype}; convert it with np.asarray(img, np.uint8)")
    m = np.asarray(hole)
    if m.shape != img.shape[:2]:
        raise InputError(f"repetition_fill: hole has shape {m.shape}, the photo {img.shape[:2]}; "
                         "pass an (H, W) bool mask of the photo's size")
    h, w = img.shape[:2]
    out = []
    for g, group in enumerate(groups):
        boxes = []
        for b in group:
            if len(b) != 4:
                raise InputError(f"repetition_fill: group {g} holds {b!r}; boxes are "
                                 "(x0, y0, x1, y1) in rectified pixels, x1/y1 exclusive")
            x0, y0, x1, y1 = (int(round(float(v))) for v in b)
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
            if x1 - x0 >= 2 and y1 - y0 >= 2:
                boxes.append((x0, y0, x1, y1))
        out.append(boxes)
    return img, m.astype(bool), out


def repetition_fill(rgb: np.ndarray, hole: np.ndarray,
                    groups: Sequence[Sequence[tuple[int, int, int, int]]], *,
                    min_cover: float = 0.5, blend: bool = True, shift: int = 3
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Paint the hole pixels of every instance box from the group's other instances.

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The photo.
    hole : (H, W) bool
        Occluded (unknown) pixels.
    groups : sequence of sequences of (x0, y0, x1, y1)
        Each group holds the boxes of one cluster's instances (the same element repeated).
        Boxes are clipped to the image; boxes under 2 px a side are dropped.
    min_cover : float
        Boxes where fewer than this fraction of their hole pixels can be painted (no other
        instance sees them) are left alone.
    blend : bool
        Merge the painted pixels into their surroundings by a Poisson solve
        (:func:`poisson_blend`); False pastes the per-pixel medians.
    shift : int
        Radius of the translation search aligning each instance to the target's known pixels
        (normalised cross-correlation of grey values); 0 trusts the boxes.

    Returns
    -------
    (rgb, filled)
        A repaired copy of ``rgb`` and the ``(H, W)`` bool mask of the hole pixels that got a
        value.  A hole pixel in several boxes takes the value of the last box painted.

    Raises
    ------
    InputError
        Bad image or mask shapes, a box that is not four numbers, ``min_cover`` outside 0–1.
    """
    img, hole, boxes_by_group = _check(rgb, hole, groups)
    if not 0.0 <= min_cover <= 1.0:
        raise InputError(f"repetition_fill: min_cover={min_cover} must lie in [0, 1]")
    h_img, w_img = hole.shape
    vis = (~hole).astype(np.float32)
    src = img.astype(np.float32)
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    out = src.copy()
    filled = np.zeros_like(hole)
    r = max(int(shift), 0)
    for boxes in boxes_by_group:
        for i, (x0, y0, x1, y1) in enumerate(boxes):
            t_hole = hole[y0:y1, x0:x1]
            if not t_hole.any():
                continue
            bw, bh = x1 - x0, y1 - y0
            t_known = ~t_hole
            t_gray = gray[y0:y1, x0:x1]
            search = r > 0 and t_known.sum() >= max(MIN_KNOWN_PX, MIN_KNOWN_FRAC * bw * bh)
            # the estimate covers the box and a ring of RING px (scaled to each instance), so
            # the guidance across the box's edge is the instances' own (frame → wall)
            a0, b0 = max(x0 - RING, 0), max(y0 - RING, 0)
            a1, b1 = min(x1 + RING, w_img), min(y1 + RING, h_img)
            ww, wh = a1 - a0, b1 - b0
            inbox = (slice(y0 - b0, y1 - b0), slice(x0 - a0, x1 - a0))
            vals, wts = [], []
            for j, (u0, v0, u1, v1) in enumerate(boxes):
                if j == i:
                    continue
                dx, dy = 0, 0
                if search:
                    score = -np.inf
                    for sy in range(-r, r + 1):
                        for sx in range(-r, r + 1):
                            bx = (u0 + sx, v0 + sy, u1 + sx, v1 + sy)
                            if bx[0] < 0 or bx[1] < 0 or bx[2] > w_img or bx[3] > h_img:
                                continue
                            g, seen = _instance(gray, vis, bx, bw, bh)
                            sc = _ncc(g, t_gray, seen & t_known)
                            if sc > score + 1e-9:
                                score, dx, dy = sc, sx, sy
                sx_, sy_ = (u1 - u0) / bw, (v1 - v0) / bh          # instance px per target px
                ext = (int(round(u0 + dx - (x0 - a0) * sx_)), int(round(v0 + dy - (y0 - b0) * sy_)),
                       int(round(u1 + dx + (a1 - x1) * sx_)), int(round(v1 + dy + (b1 - y1) * sy_)))
                if ext[0] < 0 or ext[1] < 0 or ext[2] > w_img or ext[3] > h_img:
                    ext = (u0 + dx, v0 + dy, u1 + dx, v1 + dy)     # no ring at the border
                    v, seen = _instance(src, vis, ext, bw, bh)
                    vw = np.zeros((wh, ww, 3), np.float32)
                    sw = np.zeros((wh, ww), bool)
                    vw[inbox], sw[inbox] = v, seen
                    v, seen = vw, sw
                else:
                    v, seen = _instance(src, vis, ext, ww, wh)
                vals.append(v)
                wts.append(seen.astype(np.float32))
            if not vals:
                continue
            wts_a = np.stack(wts)
            seen_any = wts_a.sum(0) > 0
            omega = np.zeros((wh, ww), bool)
            omega[inbox] = t_hole & seen_any[inbox]
            if omega.sum() < min_cover * t_hole.sum() or not omega.any():
                continue
            est = _weighted_median(np.stack(vals), wts_a)
            win = out[b0:b1, a0:a1]
            if blend:
                known = ~hole[b0:b1, a0:a1] | filled[b0:b1, a0:a1]
                guide = np.where(seen_any[..., None], est, win)
                guide_ok = seen_any | known
                oy, ox = np.nonzero(omega)
                win[oy, ox] = poisson_blend(win, guide, omega, known, guide_ok)
            else:
                win[omega] = est[omega]
            filled[b0:b1, a0:a1] |= omega
    return np.clip(np.rint(out), 0, 255).astype(np.uint8), filled
