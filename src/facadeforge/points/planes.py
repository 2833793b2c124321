"""Planes in a scan: sequential RANSAC, largest first, then what each plane is (CityFit §3, Fig. 4).

``hohmann2009`` §3: "RANSAC proceeds by removing the largest plane first (principal facade
plane, cf. Fig. 4). Then smaller and smaller planes are identified (note that these planes do
not have to be parallel to the principal plane)."  :func:`detect_planes` does exactly that loop;
what it adds is what makes the loop hold on real street scans:

- **Normal-guided hypotheses** (as Schnabel et al. 2007's efficient RANSAC): a hypothesis is
  one point and its local PCA normal rather than three points, so its probability of being
  right is the inlier share ``w`` instead of ``w³``; a point is an inlier of a plane when it is
  within ``threshold`` of it *and* its own normal is within :data:`NORMAL_TOL_DEG` of the
  plane's — a wall crossing a plane at right angles gives no inliers to it.
- **Preemptive scoring**: :data:`HYPOTHESES` hypotheses at a time are scored on a random sample
  of the remaining points (one matrix product), the winner is refined by least squares on all
  its inliers (three rounds) before it is accepted.
- **Connected pieces**: inliers of an infinite plane can be far apart (two house fronts on the
  same line, a kerb and the road); they are cut into connected pieces on a grid of
  :data:`CONNECT_CELL` in the plane, and each piece of at least ``min_points`` is a plane.
- **A voxel grid first** (:data:`VOXEL`): RANSAC runs on one point per voxel, every point of the
  full cloud then goes to the plane of its voxel's point when it lies within the threshold of
  it (one pass), the rest to the first plane whose piece holds them.  The voxel grid
  evens out the density of a scanner (ten times more points near it than at 30 m), so "largest"
  means largest *area*, as the paper's Fig. 4 intends.

Each plane is then given a **kind** (:func:`classify_planes`): ``ground`` (near-horizontal, at the
bottom of the cloud), ``facade`` (vertical, at least :data:`FACADE_MIN_WIDTH` wide and
:data:`FACADE_MIN_HEIGHT` high), ``protrusion`` (vertical, parallel to a facade, in front of it
within :data:`PROTRUSION_MAX_OFFSET` and overlapping it: a shop sign, a balcony front, a bay),
``recess`` (vertical, parallel to a facade, behind it within that offset: glazing and doors
set back in the wall), ``roof`` (inclined, or horizontal above the ground) or ``other`` (street furniture, small pieces).
A facade's normal points **out** of the building (:func:`outward`).

Units: metres, the cloud's own coordinates; ``up`` is the cloud's vertical axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from .cloud import PointCloud, PointCloudError

__all__ = ["Plane", "classify_planes", "detect_planes", "estimate_normals", "outward",
           "voxel_representatives"]

#: Voxel edge (m) of the grid RANSAC runs on.
VOXEL = 0.06
#: Most voxels RANSAC runs on: beyond, the voxel grows (its area by the excess).
MAX_VOXELS = 100_000
#: Inlier distance (m) to a plane.
THRESHOLD = 0.05
#: Largest angle (degrees) between a point's normal and the plane's for the point to be an inlier.
NORMAL_TOL_DEG = 25.0
#: Hypotheses drawn and scored together, and the sample they are scored on.
HYPOTHESES, SCORE_SAMPLE = 192, 6000
#: Neighbours of the local PCA normal.
NORMAL_K = 12
#: Cell (m) of the in-plane grid that cuts a plane's inliers into connected pieces.
CONNECT_CELL = 0.5
#: Vertical / horizontal tolerance (degrees) of the plane kinds.
VERTICAL_TOL_DEG, HORIZONTAL_TOL_DEG = 12.0, 12.0
#: Size (m) a vertical plane must span to be a facade.
FACADE_MIN_WIDTH, FACADE_MIN_HEIGHT = 3.0, 2.5
#: Offset (m) in front of a facade within which a parallel plane is a protrusion of it.
PROTRUSION_MAX_OFFSET = 2.0
#: Height (m) above the ground below which a horizontal plane is ground (pavement, kerb, road).
GROUND_BAND = 1.0


@dataclass
class Plane:
    """One plane and its points: ``normal · x + offset = 0``, ``normal`` a unit vector."""

    normal: np.ndarray
    offset: float
    inliers: np.ndarray                 # indices into the cloud, sorted
    rms: float = 0.0                    # RMS distance (m) of the inliers to the plane
    kind: str = "other"
    area: float = 0.0                   # m², occupied CONNECT_CELL cells × cell²
    parent: int | None = None           # a protrusion's facade (index into the plane list)
    extra: dict = field(default_factory=dict)

    @property
    def centroid(self) -> np.ndarray:
        return self.extra["centroid"]

    def distance(self, xyz: np.ndarray) -> np.ndarray:
        """Signed distance (m) of points to the plane, positive on the normal's side."""
        return xyz @ self.normal + self.offset

    def to_dict(self) -> dict:
        return {"kind": self.kind, "normal": [round(float(v), 6) for v in self.normal],
                "offset": round(float(self.offset), 6),
                "centroid": [round(float(v), 4) for v in self.centroid],
                "points": int(len(self.inliers)), "rms_m": round(float(self.rms), 4),
                "area_m2": round(float(self.area), 2),
                "parent": self.parent}


# ------------------------------------------------------------------------------- helpers

def _voxel_keys(xyz: np.ndarray, voxel: float) -> np.ndarray:
    q = np.floor((xyz - xyz.min(0)) / voxel).astype(np.int64)
    return (q[:, 0] * 2_097_152 + q[:, 1]) * 2_097_152 + q[:, 2]


def voxel_representatives(xyz: np.ndarray, voxel: float, inverse: bool = False):
    """Index of one point per occupied voxel (the first in file order), sorted; with
    ``inverse``, also the voxel (index into that array) of every point."""
    key = _voxel_keys(xyz, voxel)
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    order = np.argsort(first)
    if not inverse:
        return first[order]
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return first[order], rank[inv.ravel()]


def estimate_normals(xyz: np.ndarray, k: int = NORMAL_K) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals by PCA of the ``k`` nearest neighbours, and the planarity of each fit
    (``1 − λ_min/λ_mid``: 1 on a plane, 0 on a blob)."""
    n = len(xyz)
    k = int(min(k, n))
    if k < 3:
        return np.tile([0.0, 0.0, 1.0], (n, 1)), np.zeros(n)
    _, nb = cKDTree(xyz).query(xyz, k=k, workers=-1)
    p = xyz[nb] - xyz[nb].mean(1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", p, p) / k
    w, v = np.linalg.eigh(cov)
    planarity = 1.0 - w[:, 0] / np.maximum(w[:, 1], 1e-12)
    return v[:, :, 0], planarity


def _fit(xyz: np.ndarray) -> tuple[np.ndarray, float]:
    c = xyz.mean(0)
    _, _, vt = np.linalg.svd(xyz - c, full_matrices=False)
    nrm = vt[2]
    return nrm, -float(nrm @ c)


def _plane_axes(normal: np.ndarray, up: int) -> tuple[np.ndarray, np.ndarray]:
    upv = np.zeros(3)
    upv[up] = 1.0
    a = np.cross(upv, normal)
    if np.linalg.norm(a) < 1e-6:                      # horizontal plane: any in-plane axes
        a = np.cross([1.0, 0.0, 0.0] if up != 0 else [0.0, 1.0, 0.0], normal)
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    return a, b


def _pieces(xyz: np.ndarray, normal: np.ndarray, up: int, cell: float
            ) -> list[tuple[np.ndarray, float]]:
    """Connected pieces of points on a plane: (index array, area m²) per piece, largest first."""
    a, b = _plane_axes(normal, up)
    uv = np.c_[xyz @ a, xyz @ b]
    q = np.floor((uv - uv.min(0)) / cell).astype(np.int64)
    shape = tuple(q.max(0) + 1)
    if shape[0] * shape[1] > 50_000_000:              # absurdly long plane: one piece
        return [(np.arange(len(xyz)), len(np.unique(q, axis=0)) * cell * cell)]
    occ = np.zeros(shape, bool)
    occ[q[:, 0], q[:, 1]] = True
    lab, n = ndimage.label(occ, structure=np.ones((3, 3), bool))
    pid = lab[q[:, 0], q[:, 1]] - 1
    cells = np.bincount(lab.ravel(), minlength=n + 1)[1:]
    order = np.argsort(-np.bincount(pid, minlength=n))
    return [(np.flatnonzero(pid == i), float(cells[i]) * cell * cell) for i in order]


# ------------------------------------------------------------------------------- RANSAC

def detect_planes(cloud: PointCloud, *, threshold: float = THRESHOLD, voxel: float = VOXEL,
                  min_points: int | None = None, max_planes: int = 40, seed: int = 0,
                  normal_tol_deg: float = NORMAL_TOL_DEG) -> list[Plane]:
    """Sequential RANSAC planes of a cloud, largest first; kinds set by :func:`classify_planes`.

    ``min_points`` counts voxels (one point per ``voxel``); default: a plane must cover about
    1 m² (``1 / voxel²`` voxels), or 1 % of the voxels for small clouds.  ``max_planes`` counts
    RANSAC rounds: a round's plane may come out as several connected pieces (a road between
    parked cars), which all count as planes of the result.
    """
    xyz = cloud.xyz
    if len(xyz) < 3:
        raise PointCloudError(f"{cloud.source}: {len(xyz)} points are too few to find planes")
    rng = np.random.default_rng(seed)
    for _ in range(6):                   # a huge or noisy cloud: coarser voxels, bounded cost
        k = np.sort(_voxel_keys(xyz, voxel))
        n_vox = 1 + int(np.count_nonzero(k[1:] != k[:-1]))
        if n_vox <= MAX_VOXELS:
            break
        voxel *= (n_vox / MAX_VOXELS) ** 0.4     # between a surface's ½ and a volume's ⅓
    rep, vox_of = voxel_representatives(xyz, voxel, inverse=True)
    centre = xyz[rep].mean(0)
    sub = xyz[rep] - centre                            # centred: offsets stay small
    normals, planarity = estimate_normals(sub)
    if min_points is None:
        min_points = max(30, min(int(1.0 / voxel ** 2), len(rep) // 100))
    cos_tol = math.cos(math.radians(normal_tol_deg))
    remaining = np.ones(len(sub), bool)
    seeds_ok = planarity > 0.8
    found: list[tuple[np.ndarray, float, np.ndarray, float]] = []
    misses = rounds = 0
    while rounds < max_planes and misses < 3:
        live = np.flatnonzero(remaining)
        if len(live) < min_points:
            break
        cand = live[seeds_ok[live]]
        if len(cand) < 3:
            break
        # drawn with replacement: choice(replace=False) permutes the whole array every round
        h = np.unique(cand[rng.integers(0, len(cand), min(HYPOTHESES, len(cand)))])
        s = live if len(live) <= SCORE_SAMPLE else live[rng.integers(0, len(live), SCORE_SAMPLE)]
        hn = normals[h]                                           # (H, 3)
        hd = -np.einsum("ij,ij->i", hn, sub[h])                    # (H,)
        dist = np.abs(sub[s] @ hn.T + hd)                          # (S, H)
        agree = np.abs(normals[s] @ hn.T) >= cos_tol
        score = ((dist < threshold) & agree).sum(0)
        best = int(np.argmax(score))
        nrm, off = hn[best], float(hd[best])
        for _ in range(3):                                          # least-squares refinement
            d = np.abs(sub[live] @ nrm + off)
            inl = live[(d < threshold) & (np.abs(normals[live] @ nrm) >= cos_tol)]
            if len(inl) < 3:
                break
            nrm, off = _fit(sub[inl])
        d = np.abs(sub[live] @ nrm + off)
        inl = live[(d < threshold) & (np.abs(normals[live] @ nrm) >= cos_tol)]
        if len(inl) < min_points:
            misses += 1
            seeds_ok[h[best]] = False                               # do not draw it again
            continue
        misses = 0
        rounds += 1
        remaining[inl] = False
        for piece, area in _pieces(sub[inl], nrm, cloud.up, CONNECT_CELL):
            if len(piece) < min_points:
                break
            found.append((nrm.copy(), off, inl[piece], area))
    planes = _full_resolution(cloud, centre, found, threshold, vox_of, rep)
    classify_planes(cloud, planes)
    return planes


def _full_resolution(cloud: PointCloud, centre: np.ndarray, found, threshold: float,
                     vox_of: np.ndarray, rep: np.ndarray) -> list[Plane]:
    """Every point of the cloud given to a plane it lies on (within ``threshold``): first the
    plane of its voxel's point (one pass over the cloud), then, for the points left, the first
    plane in detection order whose piece's extent (its occupied in-plane cells, dilated by one)
    holds them — points of a voxel shared by two planes, a wall's foot and the pavement."""
    if not found:
        return []
    xyz = cloud.xyz - centre
    n_vox = int(vox_of.max()) + 1
    plane_of_vox = np.full(n_vox, -1, np.int64)
    for k, (_, _, vox_idx, _) in enumerate(found):
        plane_of_vox[vox_idx] = k
    pid = plane_of_vox[vox_of]
    normals = np.array([f[0] for f in found])
    offsets = np.array([f[1] for f in found])
    on = np.flatnonzero(pid >= 0)
    d_on = np.einsum("ij,ij->i", xyz[on], normals[pid[on]]) + offsets[pid[on]]
    pid[on[np.abs(d_on) >= threshold]] = -1
    free = np.flatnonzero(pid < 0)
    # sorted once along the cloud's longer horizontal axis: a piece's extent is one slice
    horiz = [a for a in range(3) if a != cloud.up]
    ext = np.ptp(xyz[:, horiz], axis=0) if len(xyz) else np.zeros(2)
    ax = horiz[int(np.argmax(ext))]
    free = free[np.argsort(xyz[free, ax], kind="stable")]
    free_ax = xyz[free, ax]
    for k, (nrm, off, vox_idx, _) in enumerate(found):
        piece = xyz[rep[vox_idx]]
        lo3, hi3 = piece.min(0) - CONNECT_CELL, piece.max(0) + CONNECT_CELL
        a0, a1 = np.searchsorted(free_ax, [lo3[ax], hi3[ax]])
        span = free[a0:a1]
        span = span[pid[span] < 0]
        if not len(span):
            continue
        fx = xyz[span]
        cand = span[((fx >= lo3) & (fx <= hi3)).all(1)]
        if not len(cand):
            continue
        d = xyz[cand] @ nrm + off
        cand = cand[np.abs(d) < threshold]
        if not len(cand):
            continue
        a, b = _plane_axes(nrm, cloud.up)
        uv0 = np.c_[piece @ a, piece @ b]
        lo = uv0.min(0)
        q0 = np.floor((uv0 - lo) / CONNECT_CELL).astype(np.int64)
        shape = tuple(q0.max(0) + 3)
        occ = np.zeros(shape, bool)
        occ[q0[:, 0] + 1, q0[:, 1] + 1] = True
        occ = ndimage.binary_dilation(occ, np.ones((3, 3), bool))
        q = np.floor((np.c_[xyz[cand] @ a, xyz[cand] @ b] - lo) / CONNECT_CELL).astype(np.int64) + 1
        ok = (q >= 0).all(1) & (q[:, 0] < shape[0]) & (q[:, 1] < shape[1])
        ok[ok] = occ[q[ok, 0], q[ok, 1]]
        pid[cand[ok]] = k
    on = np.flatnonzero(pid >= 0)
    p = pid[on]
    order = np.argsort(p, kind="stable")
    on, p = on[order], p[order]
    bounds = np.searchsorted(p, np.arange(len(found) + 1))
    planes: list[Plane] = []
    for k, (nrm, off, _, area) in enumerate(found):
        a, b = bounds[k], bounds[k + 1]
        if b - a < 3:
            continue
        inl = np.sort(on[a:b])
        d = xyz[inl] @ nrm + off
        planes.append(Plane(normal=nrm, offset=off - float(nrm @ centre), inliers=inl,
                            rms=float(np.sqrt(np.mean(d ** 2))), area=area,
                            extra={"centroid": cloud.xyz[inl].mean(0)}))
    return planes


# ------------------------------------------------------------------------------- kinds

def outward(cloud: PointCloud, plane: Plane, ground: Plane | None) -> None:
    """Turn a vertical plane's normal to point out of the building, in place.

    Cues, strongest first: (1) the street — the ground a scanner stood on lies in front of a
    facade: the side holding more ground points within 15 m in front of the plane's extent;
    (2) glass and recesses — a scanner sees *behind* a facade only through its openings, and
    in front of it only what stands there: with no ground, the side holding fewer of the
    points that are off the plane but within 0.6 m of it is the front when the points behind
    (window and door recesses) dominate.
    """
    xyz = cloud.xyz
    inl = xyz[plane.inliers]
    a, _ = _plane_axes(plane.normal, cloud.up)
    u = inl @ a
    ulo, uhi = np.percentile(u, [1, 99])
    if ground is not None and len(ground.inliers):
        g = xyz[ground.inliers]
        gu = g @ a
        gd = plane.distance(g)
        near = (gu > ulo) & (gu < uhi) & (np.abs(gd) < 15.0) & (np.abs(gd) > 0.3)
        front, back = int((gd[near] > 0).sum()), int((gd[near] < 0).sum())
        if front + back > 50 and max(front, back) > 1.5 * min(front, back):
            if back > front:
                _flip(plane)
            plane.extra["outward_cue"] = "ground"
            return
    v = xyz[:, cloud.up]
    vlo, vhi = v[plane.inliers].min(), v[plane.inliers].max()
    d = plane.distance(xyz)
    uu = xyz @ a
    box = (uu > ulo) & (uu < uhi) & (v > vlo) & (v < vhi)
    off = box & (np.abs(d) > 2 * THRESHOLD) & (np.abs(d) < 0.6)
    front, back = int((d[off] > 0).sum()), int((d[off] < 0).sum())
    if front > back:
        _flip(plane)
    plane.extra["outward_cue"] = "recesses"


def _flip(plane: Plane) -> None:
    plane.normal = -plane.normal
    plane.offset = -plane.offset


def classify_planes(cloud: PointCloud, planes: list[Plane]) -> list[Plane]:
    """Set each plane's ``kind`` (and a protrusion's ``parent``) in place; see the module doc."""
    if not planes:
        return planes
    up = cloud.up
    upv = np.zeros(3)
    upv[up] = 1.0
    sin_v = math.sin(math.radians(VERTICAL_TOL_DEG))
    cos_h = math.cos(math.radians(HORIZONTAL_TOL_DEG))
    zmin = float(np.percentile(cloud.xyz[:, up], 0.5))
    ground: Plane | None = None
    for p in planes:
        c = abs(float(p.normal @ upv))
        h = float(p.centroid[up])
        if c >= cos_h:
            if p.normal @ upv < 0:
                _flip(p)
            p.kind = "ground" if h - zmin < GROUND_BAND else "roof"
            if p.kind == "ground" and (ground is None or len(p.inliers) > len(ground.inliers)):
                ground = p
        elif c <= sin_v:
            p.kind = "vertical"
        else:
            p.kind = "roof"
    ground_h = float(ground.centroid[up]) if ground is not None else zmin
    # vertical planes: facades when big enough, then protrusions in front of a facade
    verticals = [p for p in planes if p.kind == "vertical"]
    for p in verticals:
        a, _ = _plane_axes(p.normal, up)
        pts = cloud.xyz[p.inliers]
        u = pts @ a
        w = float(np.percentile(u, 99) - np.percentile(u, 1))
        hh = float(np.percentile(pts[:, up], 99) - np.percentile(pts[:, up], 1))
        p.extra["width_m"], p.extra["height_m"] = round(w, 3), round(hh, 3)
        p.kind = "facade" if w >= FACADE_MIN_WIDTH and hh >= FACADE_MIN_HEIGHT else "other"
        if p.kind == "facade" and p.area < 0.3 * w * hh:
            p.kind = "other"                                   # a sparse fence, railings
    facades = [p for p in planes if p.kind == "facade"]
    for p in facades:
        outward(cloud, p, ground)
    index = {id(p): i for i, p in enumerate(planes)}
    for p in verticals:
        if p.kind not in ("facade", "other") or (facades and p is facades[0]):
            continue
        bigger = [f for f in facades if f is not p and len(f.inliers) > len(p.inliers)]
        host, off = _host(cloud, p, bigger)
        if host is None:
            continue
        small = p.extra["height_m"] < 0.8 * host.extra["height_m"] or p.area < 0.3 * host.area
        if off > 0 and (p.kind == "other" or small):
            p.kind = "protrusion"           # a shop sign, balcony front, bay in front
        elif off < 0:
            p.kind = "recess"               # a window, door, shop front set back
        else:
            continue
        p.parent = index[id(host)]
        if p.normal @ host.normal < 0:
            _flip(p)
    for p in planes:
        p.extra["height_above_ground_m"] = round(float(p.centroid[up]) - ground_h, 3)
    return planes


def _host(cloud: PointCloud, p: Plane, facades: list[Plane]) -> tuple[Plane | None, float]:
    """The facade a vertical plane stands in front of or is set back into: parallel, within
    :data:`PROTRUSION_MAX_OFFSET` of it, overlapping it along the facade; with the offset (m,
    positive in front)."""
    cos_par = math.cos(math.radians(10.0))
    pts = cloud.xyz[p.inliers]
    for f in facades:
        if abs(float(p.normal @ f.normal)) < cos_par:
            continue
        off = float(np.median(f.distance(pts)))
        if not (0.05 < abs(off) <= PROTRUSION_MAX_OFFSET):
            continue
        a, _ = _plane_axes(f.normal, cloud.up)
        fu = cloud.xyz[f.inliers] @ a
        pu = pts @ a
        plo, phi = np.percentile(pu, [1, 99])
        flo, fhi = np.percentile(fu, [1, 99])
        if min(fhi, phi) - max(flo, plo) > 0.5 * (phi - plo):
            return f, off
    return None, 0.0
