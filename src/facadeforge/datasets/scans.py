"""Synthetic laser scans with exact ground truth: ray-cast terrestrial and mobile scans of models.

What it simulates
    :func:`simulate_scan` casts laser rays at one or more :class:`~facadeforge.model.Model`\\ s
    and returns a :class:`~facadeforge.points.PointCloud` in which every point knows the part
    it came from: its canonical label, its element instance, the scanner that measured it.
    Two acquisition geometries:

    - ``"terrestrial"`` (TLS): one or a few stations standing in the street in front of the
      facades, the optical centre 1.7 m above the ground; rays on a regular azimuth/elevation
      grid (``angular_step_deg``), panoramic but limited to the window of directions that covers
      the scene (the "region of interest" a surveyor frames; the rest of the sphere is sky);
    - ``"mobile"`` (MLS, like Paris-Lille-3D): a 2D profiler on a vehicle driving along the
      street, 2.3 m above the ground, one vertical scan line (a profile perpendicular to the
      travel direction, from straight down to above the roof line, on the facade side) every
      ``line_spacing`` metres of travel, ``angular_step_deg`` between rays within a line.

    Each ray is intersected exactly with the scene's triangles (Möller–Trumbore, two-sided, over
    a bounding volume hierarchy; numba kernels, one core): the nearest hit within ``max_range``
    returns, its range perturbed by Gaussian noise of ``range_noise`` (σ, metres; truncated at
    3.5 σ) along the ray.
    Surfaces behave by material: **glass** (leaves named ``…Glass``, materials with opacity < 1)
    returns with probability ``glass_return``, lets the ray through with probability
    ``glass_pass`` (it then continues to the interior: a wall ``room_depth`` behind the facade,
    label ``other``) and loses the rest; **railings** (``…Railing``) are lattices that return
    half the rays and pass the others to what stands behind; **foliage** (tree crowns) returns
    55 % of the rays it meets, those entering it from up to 0.5 m inside the crown.  Intensity is a plausible
    16-bit value: a reflectance per label and surface (glass: specular, bright only at normal
    incidence), times ``0.2 + 0.8 cos(incidence)``, a range fall-off and noise.  The street is a
    ground plane (label ``ground``) and, with ``occluders=True``, street trees (trunk + crown,
    ``vegetation``) and parked cars (body + cabin with glass windows, ``car``) stand between the
    scanners and the facades (``hohmann2009`` §3: street scans are taken from a car; the facade
    they see is cut by what stands in front of it).

    :func:`facade_building` turns a synthetic facade layout (:func:`~.synthetic.make_facade`:
    the ``haussmann``, ``modern`` and ``residential`` grammars with their random attribute draws)
    into a 3D building: the 2.5D layout (each leaf a rectangle at its depth ``z`` from the wall
    plane: windows and doors set back 0.12–0.25 m, balconies, cornices and sills in front) becomes
    a solid block ``depth`` metres deep whose front relief has real reveals (the embrasures of the
    recesses, labelled ``wall``; the ends of protrusions, labelled as the protrusion), flat roofs
    on top, side walls, and what the layout paints over the partition (balcony slabs, railings,
    shutters, sills, chimneys) as boxes or thin plates in front.  :func:`synthetic_scans` draws
    streets of one to three such buildings and scans them, deterministically from a seed:
    artificial data with exact ground truth for the point-cloud pipeline, as ``simon2011``
    §5.4.2 uses randomly generated buildings to study convergence "on artificial data, for which
    we have a noise-free ground-truth".

Conventions
    Input models are in the CGA world frame: metres, **y up** (x right along the facade, z out of
    the facade towards the street for :func:`facade_building`).  Every output — points,
    ``scanners``, ``trajectory``, element corners, facade planes — is in the **z-up** frame of
    LAS / PLY scans, right-handed, metres: ``(X, Y, Z) = (x, -z, y)`` for a model point
    ``(x, y, z)`` (:data:`Y_UP_TO_Z_UP`, a rotation of +90° about x, the usual glTF → z-up map).
    Read X as east, Y as north, Z as up: a :func:`facade_building` faces south (its outward
    normal is ``(0, -1, 0)``), the street lies at ``Y < 0``.  ``scanners`` and ``trajectory``
    given by the caller are in this output frame.

    Labels are the canonical vocabulary (:class:`~facadeforge.model.Labels`; ``cloud.labels``
    indexes ``cloud.label_names``, which is the whole vocabulary in its canonical order, so index
    1 is always ``wall``): ``wall``, ``window``, ``door``, ``balcony``, ``shop``, ``roof``,
    ``cornice``, ``sill``, ``blind``, ``deco``, ``molding``, ``pillar``, ``ground``,
    ``vegetation``, ``car``, ``other`` (the interiors seen through glass).  ``cloud.instance``
    is one id per element instance, unique over the scan: per window, door, balcony, shop, sill…
    of :func:`facade_building` (a maximal subtree of the shape tree whose leaves share one label,
    as :mod:`.synthetic`'s objects), one per building for its walls and one for its roofs, one
    per tree and per car, one for the ground; −1 for interiors.  For other models the instance
    is the part's ``shape_id`` (a leaf shape), renumbered.  ``cloud.normals`` are the true
    surface normals (facing the scanner), ``cloud.extra`` holds ``scanner`` (station or scan
    line index), ``range`` (m) and ``surface`` (0 opaque, 1 glass, 2 railing, 3 foliage).

Ground truth (:class:`ScanResult`)
    ``elements``: one per window, door, balcony and shop instance: its label, instance id, four
    3D corners (bottom-left, bottom-right, top-right, top-left as seen from the street) on the
    element's own plane (the area-weighted depth of its faces parallel to the facade, so a
    recessed window's corners lie behind the wall plane), ``depth`` (signed offset from the
    facade plane, negative = recessed) and the index of its facade.  ``facade_planes``: per
    building its front (``kind: "front"``), side and back walls as point + outward unit normal
    (+ the horizontal in-plane axis ``u`` to the right seen from outside and the extent).
    :func:`write_scan` writes the cloud as binary PLY (``x y z`` double, ``intensity`` ushort,
    ``label`` and ``instance`` int, ``scanner`` int) and ``truth.json``.

Speed: the kernels compile once (cached on disk); a terrestrial scan of ~300k points of a
five-storey building takes about a second on one core.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..model.labels import Labels
from ..model.model import Material, Model, Part
from ..points.cloud import PointCloud

__all__ = ["ELEMENT_LABELS", "LABEL_NAMES", "ScanResult", "Y_UP_TO_Z_UP", "facade_building",
           "simulate_scan", "synthetic_scans", "write_scan"]

#: Rotation from the CGA world (y up) to the output frame (z up): ``(x, y, z) → (x, -z, y)``.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: The label names of every scan, in canonical order (``cloud.label_names``).
LABEL_NAMES: tuple[str, ...] = tuple(label.value for label in Labels)
_LABEL = {name: i for i, name in enumerate(LABEL_NAMES)}

#: Labels whose instances are listed as ground-truth element rectangles.
ELEMENT_LABELS: tuple[str, ...] = ("window", "door", "balcony", "shop")

#: Surface behaviours (``cloud.extra["surface"]``).
OPAQUE, GLASS, RAILING, FOLIAGE = 0, 1, 2, 3
_SURFACE_NAMES = ("opaque", "glass", "railing", "foliage")

#: Labels that are not geometry of a building (regions of a facade photo).
_VOID_LABELS = frozenset({"sky", "ground", "background"})

#: Diffuse reflectance per label at the laser's wavelength (plausible, not measured).
_REFLECTANCE = {
    "wall": 0.55, "window": 0.45, "door": 0.32, "balcony": 0.28, "shop": 0.4, "roof": 0.3,
    "cornice": 0.6, "sill": 0.62, "blind": 0.45, "deco": 0.6, "molding": 0.6, "pillar": 0.5,
    "vegetation": 0.42, "ground": 0.22, "car": 0.35, "other": 0.3,
}

TLS_HEIGHT = 1.7
MLS_HEIGHT = 2.3
MIN_RANGE = 0.3
#: The range noise is Gaussian truncated at this many σ (no outliers: tests bound the error).
NOISE_CLIP = 3.5
_MAX_INTERACTIONS = 6


# ================================================================================ result
@dataclass
class ScanResult:
    """A simulated scan and its ground truth (everything in the z-up output frame, metres).

    Attributes
    ----------
    cloud : PointCloud
        The points: ``xyz``, ``intensity`` (0–65535), ``labels`` into :data:`LABEL_NAMES`,
        ``instance``, true ``normals``; ``extra``: ``scanner``, ``range``, ``surface``.
    kind : str
        ``"terrestrial"`` or ``"mobile"``.
    scanners : (K, 3) float
        Station positions (TLS) or the scanner's position at each scan line (MLS).
    elements : list of dict
        ``{"instance", "label", "corners" (4×3), "depth", "facade", "width", "height"}`` per
        window, door, balcony and shop instance of the models.
    facade_planes : list of dict
        ``{"point", "normal", "u", "kind", "building", "width", "height"}``.
    instances : dict of int to str
        Label of every instance id.
    meta : dict
        Parameters, counts, seconds.
    """

    cloud: PointCloud
    kind: str
    scanners: np.ndarray
    elements: list[dict[str, Any]] = field(default_factory=list)
    facade_planes: list[dict[str, Any]] = field(default_factory=list)
    instances: dict[int, str] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)

    def label_counts(self) -> dict[str, int]:
        """Points per label name (labels with points only)."""
        counts = np.bincount(self.cloud.labels, minlength=len(LABEL_NAMES))
        return {LABEL_NAMES[i]: int(c) for i, c in enumerate(counts) if c}

    def truth(self) -> dict[str, Any]:
        """The ground truth as a JSON-ready dict (what :func:`write_scan` puts in truth.json)."""
        return {
            "format": "facadeforge synthetic scan truth 1",
            "frame": "z up, right-handed, metres: (X, Y, Z) = (x, -z, y) of the CGA model "
                     "(y up); X east, Y north",
            "kind": self.kind,
            "label_names": list(LABEL_NAMES),
            "scanners": _round(self.scanners),
            "facade_planes": [_jsonable(p) for p in self.facade_planes],
            "elements": [_jsonable(e) for e in self.elements],
            "instances": {str(k): v for k, v in sorted(self.instances.items())},
            "points": len(self.cloud),
            "label_counts": self.label_counts(),
            "meta": _jsonable(self.meta),
        }


def _round(a, nd: int = 6):
    return np.round(np.asarray(a, float), nd).tolist()


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _round(obj) if obj.dtype.kind == "f" else obj.tolist()
    if isinstance(obj, (np.floating, float)):
        return round(float(obj), 6)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


# ================================================================================ kernels
# The kernels are plain functions here, compiled by numba on first use (:func:`_kernels`, cached
# on disk); numba is imported then, not with the module.
_NAMES = ("_k_uniform", "_k_nearest", "_k_build_bvh", "_k_cast")
_COMPILED: list[bool] = []


def _kernels() -> None:
    """Compile the numba kernels in place of the plain functions (once per process)."""
    if _COMPILED:
        return
    import numba

    for name in _NAMES:
        globals()[name] = numba.njit(cache=True, nogil=True, error_model="numpy")(globals()[name])
    _COMPILED.append(True)


def _k_build_bvh(lo, hi, cent, leaf_size):
    n = lo.shape[0]
    order = np.arange(n)
    cap = 2 * n + 1
    bmin = np.empty((cap, 3))
    bmax = np.empty((cap, 3))
    left = np.full(cap, -1, np.int64)
    right = np.full(cap, -1, np.int64)
    start = np.zeros(cap, np.int64)
    count = np.zeros(cap, np.int64)
    stack = np.empty(cap, np.int64)
    count[0] = n
    nodes = 1
    sp = 1
    stack[0] = 0
    while sp > 0:
        sp -= 1
        node = stack[sp]
        s = start[node]
        e = s + count[node]
        for a in range(3):
            bmin[node, a] = np.inf
            bmax[node, a] = -np.inf
        cmin = np.full(3, np.inf)
        cmax = np.full(3, -np.inf)
        for k in range(s, e):
            t = order[k]
            for a in range(3):
                bmin[node, a] = min(bmin[node, a], lo[t, a])
                bmax[node, a] = max(bmax[node, a], hi[t, a])
                cmin[a] = min(cmin[a], cent[t, a])
                cmax[a] = max(cmax[a], cent[t, a])
        if e - s <= leaf_size:
            continue
        axis = 0
        for a in range(1, 3):
            if cmax[a] - cmin[a] > cmax[axis] - cmin[axis]:
                axis = a
        if cmax[axis] - cmin[axis] <= 0.0:
            continue
        seg = order[s:e].copy()
        keys = np.empty(e - s)
        for k in range(e - s):
            keys[k] = cent[seg[k], axis]
        idx = np.argsort(keys, kind="mergesort")
        for k in range(e - s):
            order[s + k] = seg[idx[k]]
        mid = (s + e) // 2
        lnode, rnode = nodes, nodes + 1
        nodes += 2
        start[lnode], count[lnode] = s, mid - s
        start[rnode], count[rnode] = mid, e - mid
        left[node], right[node] = lnode, rnode
        stack[sp] = lnode
        stack[sp + 1] = rnode
        sp += 2
    return order, bmin[:nodes], bmax[:nodes], left[:nodes], right[:nodes], \
        start[:nodes], count[:nodes]

def _k_nearest(ox, oy, oz, dx, dy, dz, tmin, tmax, bmin, bmax, left, right, start, count,
            v0, e1, e2, stack):
    if abs(dx) < 1e-15:
        dx = 1e-15
    if abs(dy) < 1e-15:
        dy = 1e-15
    if abs(dz) < 1e-15:
        dz = 1e-15
    ix, iy, iz = 1.0 / dx, 1.0 / dy, 1.0 / dz
    best = tmax
    hit = -1
    sp = 1
    stack[0] = 0
    while sp > 0:
        sp -= 1
        node = stack[sp]
        t0 = (bmin[node, 0] - ox) * ix
        t1 = (bmax[node, 0] - ox) * ix
        tn, tf = min(t0, t1), max(t0, t1)
        t0 = (bmin[node, 1] - oy) * iy
        t1 = (bmax[node, 1] - oy) * iy
        tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
        t0 = (bmin[node, 2] - oz) * iz
        t1 = (bmax[node, 2] - oz) * iz
        tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
        if tn > tf or tf < tmin or tn > best:
            continue
        if left[node] < 0:
            for k in range(start[node], start[node] + count[node]):
                px = dy * e2[k, 2] - dz * e2[k, 1]
                py = dz * e2[k, 0] - dx * e2[k, 2]
                pz = dx * e2[k, 1] - dy * e2[k, 0]
                det = e1[k, 0] * px + e1[k, 1] * py + e1[k, 2] * pz
                if abs(det) < 1e-14:
                    continue
                inv = 1.0 / det
                sx, sy, sz = ox - v0[k, 0], oy - v0[k, 1], oz - v0[k, 2]
                u = (sx * px + sy * py + sz * pz) * inv
                if u < -1e-9 or u > 1.0 + 1e-9:
                    continue
                qx = sy * e1[k, 2] - sz * e1[k, 1]
                qy = sz * e1[k, 0] - sx * e1[k, 2]
                qz = sx * e1[k, 1] - sy * e1[k, 0]
                v = (dx * qx + dy * qy + dz * qz) * inv
                if v < -1e-9 or u + v > 1.0 + 1e-9:
                    continue
                t = (e2[k, 0] * qx + e2[k, 1] * qy + e2[k, 2] * qz) * inv
                if t > tmin and t < best:
                    best = t
                    hit = k
        else:
            a, b = left[node], right[node]
            # the child nearer along the ray is visited first (pushed last)
            ca = (bmin[a, 0] + bmax[a, 0]) * dx + (bmin[a, 1] + bmax[a, 1]) * dy \
                + (bmin[a, 2] + bmax[a, 2]) * dz
            cb = (bmin[b, 0] + bmax[b, 0]) * dx + (bmin[b, 1] + bmax[b, 1]) * dy \
                + (bmin[b, 2] + bmax[b, 2]) * dz
            if ca < cb:
                a, b = b, a
            stack[sp] = a
            stack[sp + 1] = b
            sp += 2
    return best, hit

def _k_uniform(seed, ray, k):
    z = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) \
        + np.uint64(ray) * np.uint64(0xD1B54A32D192ED03) + np.uint64(k + 1) \
        * np.uint64(0x94D049BB133111EB)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)

def _k_cast(origins, src, dirs, tmin, tmax, bmin, bmax, left, right, start, count, v0, e1, e2,
         surface, p_return, p_pass, seed, max_interactions):
    n = dirs.shape[0]
    out_t = np.full(n, np.nan)
    out_tri = np.full(n, -1, np.int64)
    out_through = np.zeros(n, np.uint8)
    stack = np.empty(256, np.int64)
    for r in range(n):
        o = origins[src[r]]
        dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
        lo = tmin
        for k in range(max_interactions):
            t, tri = _k_nearest(o[0], o[1], o[2], dx, dy, dz, lo, tmax, bmin, bmax, left,
                             right, start, count, v0, e1, e2, stack)
            if tri < 0:
                break
            m = surface[tri]
            if m == 0:
                out_t[r], out_tri[r], out_through[r] = t, tri, k
                break
            u = _k_uniform(seed, r, k)
            if u < p_return[m]:
                out_t[r], out_tri[r], out_through[r] = t, tri, k
                break
            if u < p_return[m] + p_pass[m]:
                lo = t + 1e-4
                continue
            break
    return out_t, out_tri, out_through


# ================================================================================ scene
@dataclass
class _Scene:
    """Triangles in the output frame (z up) with what each one is."""

    tri: np.ndarray  # (T, 3, 3)
    label: np.ndarray  # (T,) int, canonical index
    instance: np.ndarray  # (T,) int
    surface: np.ndarray  # (T,) int8
    reflect: np.ndarray  # (T,) float

    @staticmethod
    def empty() -> _Scene:
        return _Scene(np.zeros((0, 3, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64),
                      np.zeros(0, np.int8), np.zeros(0))

    @staticmethod
    def concat(scenes: Sequence[_Scene]) -> _Scene:
        return _Scene(*(np.concatenate([getattr(s, f) for s in scenes])
                        for f in ("tri", "label", "instance", "surface", "reflect")))


def _canonical_label(label: str, symbol: str = "") -> str:
    from ..exchange.raster import label_index

    return LABEL_NAMES[label_index(label, symbol)]


def _surface_of(part: Part, label: str) -> int:
    name = f"{part.material.name} {part.symbol}".lower()
    if "railing" in name:
        return RAILING
    if label == "vegetation" and "trunk" not in name:
        return FOLIAGE
    if "glass" in name or part.material.opacity < 0.99:
        return GLASS
    return OPAQUE


def _reflectance(label: str, surface: int, instance: int, material: Material) -> float:
    base = _REFLECTANCE.get(label, 0.4)
    if surface == GLASS:
        base = 0.08
    # a per-instance variation (paint, stone, weathering), deterministic in the instance id
    h = (instance * 2654435761 + 12345) % 1000 / 1000.0
    base *= 0.85 + 0.3 * h
    if material.name != "default" and material.color != (1.0, 1.0, 1.0):
        lum = 0.2126 * material.color[0] + 0.7152 * material.color[1] + 0.0722 * material.color[2]
        base *= 0.7 + 0.6 * float(lum)
    return float(min(base, 0.95))


def _model_scene(model: Model, instance_of: dict, next_id: list) -> tuple[_Scene, dict]:
    """A model's triangles in the output frame; instance ids assigned in ``instance_of``."""
    tris, labels, inst, surf, refl = [], [], [], [], []
    names: dict[int, str] = {}
    for part in model.parts:
        mesh = part.mesh
        if mesh is None or not mesh.n_faces:
            continue
        pos = mesh.triangulate()[0].reshape(-1, 3, 3)
        if not len(pos):
            continue
        label = _canonical_label(part.label, part.symbol)
        if part.shape_id is None or int(part.shape_id) < 0:
            iid = -1
        else:
            key = (id(model), int(part.shape_id))
            if key not in instance_of:
                instance_of[key] = next_id[0]
                next_id[0] += 1
            iid = instance_of[key]
            names.setdefault(iid, label)
        s = _surface_of(part, label)
        tris.append(pos @ Y_UP_TO_Z_UP.T)
        n = len(pos)
        labels.append(np.full(n, _LABEL[label]))
        inst.append(np.full(n, iid))
        surf.append(np.full(n, s, np.int8))
        refl.append(np.full(n, _reflectance(label, s, iid, part.material)))
    if not tris:
        return _Scene.empty(), names
    return _Scene(np.concatenate(tris), np.concatenate(labels), np.concatenate(inst),
                  np.concatenate(surf), np.concatenate(refl)), names


def _quads_scene(quads: np.ndarray, label: str, instance: int, surface: int = OPAQUE,
                 reflect: float | None = None) -> _Scene:
    """Quads (Q, 4, 3) in the output frame as triangles."""
    q = np.asarray(quads, float).reshape(-1, 4, 3)
    tri = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    n = len(tri)
    r = _reflectance(label, surface, instance, Material()) if reflect is None else reflect
    return _Scene(tri, np.full(n, _LABEL[label]), np.full(n, instance),
                  np.full(n, surface, np.int8), np.full(n, r))


# -- facade planes and elements of models ------------------------------------------------------
def _plane_dict(point, normal, kind: str, building: str, width: float, height: float) -> dict:
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    up = np.array([0.0, 0.0, 1.0])
    u = np.cross(up, n)
    u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
    return {"point": np.asarray(point, float), "normal": n, "u": u, "kind": kind,
            "building": building, "width": float(width), "height": float(height)}


def _model_planes(model: Model) -> list[dict]:
    """Facade planes of a model in the output frame: those :func:`facade_building` recorded,
    else the large vertical planes of its wall faces (grouped by normal and offset)."""
    given = model.attributes.get("facade_planes") if isinstance(model.attributes, dict) else None
    if given:
        out = []
        for p in given:
            out.append(_plane_dict(Y_UP_TO_Z_UP @ np.asarray(p["point"], float),
                                   Y_UP_TO_Z_UP @ np.asarray(p["normal"], float),
                                   p.get("kind", "front"), model.name, p.get("width", 0.0),
                                   p.get("height", 0.0)))
        return out
    pos, nrm, area = [], [], []
    for part in model.parts:
        if _canonical_label(part.label, part.symbol) != "wall" or not part.mesh.n_faces:
            continue
        t = part.mesh.triangulate()[0].reshape(-1, 3, 3) @ Y_UP_TO_Z_UP.T
        c = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        a = np.linalg.norm(c, axis=1) / 2
        ok = a > 1e-9
        pos.append(t[ok].mean(axis=1))
        nrm.append(c[ok] / (2 * a[ok, None]))
        area.append(a[ok])
    if not pos:
        return []
    pos, nrm, area = np.concatenate(pos), np.concatenate(nrm), np.concatenate(area)
    vertical = np.abs(nrm[:, 2]) < 0.1
    pos, nrm, area = pos[vertical], nrm[vertical], area[vertical]
    if not len(pos):
        return []
    az = np.round(np.degrees(np.arctan2(nrm[:, 1], nrm[:, 0])) / 2.0).astype(np.int64) % 180
    off = np.einsum("ij,ij->i", pos, nrm)
    # clusters: one normal direction (2° bins), offsets closer than 0.15 m in a chain
    order = np.lexsort((off, az))
    az_s, off_s = az[order], off[order]
    new = np.r_[True, (az_s[1:] != az_s[:-1]) | (np.diff(off_s) > 0.15)]
    cluster = np.empty(len(order), np.int64)
    cluster[order] = np.cumsum(new) - 1
    totals = np.bincount(cluster, area)
    out = []
    for k in np.argsort(-totals, kind="stable"):
        if totals[k] < 4.0:
            break
        m = cluster == k
        w = area[m] / totals[k]
        point = (pos[m] * w[:, None]).sum(0)
        plane = _plane_dict(point, (nrm[m] * w[:, None]).sum(0), "wall", model.name, 0.0, 0.0)
        up = np.cross(plane["normal"], plane["u"])
        su, sv = (pos[m] - point) @ plane["u"], (pos[m] - point) @ up
        plane["width"], plane["height"] = float(np.ptp(su)), float(np.ptp(sv))
        plane["area"] = float(totals[k])
        out.append(plane)
    return out


def _elements(scene: _Scene, planes: list[dict], names: dict[int, str]) -> list[dict]:
    """Rectangles of the element instances (labels :data:`ELEMENT_LABELS`) of a scene."""
    if not planes:
        return []
    out = []
    el_ids = sorted(i for i, lab in names.items() if lab in ELEMENT_LABELS)
    if not el_ids:
        return out
    sel = np.isin(scene.instance, el_ids)
    tri, inst = scene.tri[sel], scene.instance[sel]
    order = np.argsort(inst, kind="stable")
    tri, inst = tri[order], inst[order]
    cuts = np.flatnonzero(np.diff(inst)) + 1
    for group, ids in zip(np.split(tri, cuts), np.split(inst, cuts), strict=True):
        iid = int(ids[0])
        c = group.reshape(-1, 3).mean(0)
        dist = [abs(float((c - p["point"]) @ p["normal"])) for p in planes]
        k = int(np.argmin(dist))
        p = planes[k]
        n, u = p["normal"], p["u"]
        up = np.cross(n, u)
        rel = group.reshape(-1, 3) - p["point"]
        su, sv = rel @ u, rel @ up
        cr = np.cross(group[:, 1] - group[:, 0], group[:, 2] - group[:, 0])
        a = np.linalg.norm(cr, axis=1) / 2
        facing = np.abs(cr @ n) > 0.9 * 2 * np.maximum(a, 1e-12)
        d = ((group.mean(1) - p["point"]) @ n)
        depth = float((d[facing] * a[facing]).sum() / a[facing].sum()) if a[facing].sum() > 0 \
            else float(d.mean())
        u0, u1, v0, v1 = su.min(), su.max(), sv.min(), sv.max()
        corners = np.array([p["point"] + uu * u + vv * up + depth * n
                            for uu, vv in ((u0, v0), (u1, v0), (u1, v1), (u0, v1))])
        out.append({"instance": iid, "label": names[iid], "corners": corners,
                    "depth": depth, "facade": k, "width": float(u1 - u0),
                    "height": float(v1 - v0)})
    return out


# -- street: ground and occluders ----------------------------------------------------------------
def _box_quads(lo, hi) -> np.ndarray:
    """The six faces of an axis-aligned box (output frame) as quads (6, 4, 3)."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    return np.array([
        [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],
        [[x1, y1, z0], [x0, y1, z0], [x0, y1, z1], [x1, y1, z1]],
        [[x0, y1, z0], [x0, y0, z0], [x0, y0, z1], [x0, y1, z1]],
        [[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
        [[x0, y1, z0], [x1, y1, z0], [x1, y0, z0], [x0, y0, z0]],
    ], float)


def _oriented_box(centre, u, v, size, z0, z1) -> np.ndarray:
    """Quads of a box centred (horizontally) on ``centre`` with horizontal axes ``u``, ``v`` and
    sizes ``size`` = (along u, along v), from height ``z0`` to ``z1``."""
    local = _box_quads((-size[0] / 2, -size[1] / 2, z0), (size[0] / 2, size[1] / 2, z1))
    c = np.array([centre[0], centre[1], 0.0])
    return (c + local[..., :1] * np.asarray(u, float) + local[..., 1:2] * np.asarray(v, float)
            + local[..., 2:3] * np.array([0.0, 0.0, 1.0]))


def _midpoint(verts: list, cache: dict, a: int, b: int) -> int:
    """Index of the unit vertex halfway between vertices ``a`` and ``b`` (added once)."""
    key = (min(a, b), max(a, b))
    if key not in cache:
        m = verts[a] + verts[b]
        verts.append(m / np.linalg.norm(m))
        cache[key] = len(verts) - 1
    return cache[key]


def _sphere(subdiv: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere vertices (unit) and triangles."""
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = list(f)
    for _ in range(subdiv):
        cache: dict = {}
        new = []
        for a, b, c in faces:
            ab, bc, ca = (_midpoint(verts, cache, i, j) for i, j in ((a, b), (b, c), (c, a)))
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(verts), np.array(faces)


def _tree(base, rng: np.random.Generator, iid: int, max_radius: float) -> _Scene:
    """A street tree at ``base`` (x, y, ground z): a hexagonal trunk and an ellipsoid crown."""
    trunk_h = float(rng.uniform(2.2, 3.4))
    r_trunk = float(rng.uniform(0.1, 0.2))
    crown_r = float(min(max_radius, rng.uniform(1.6, 2.6)))
    crown_h = float(rng.uniform(1.2, 1.6)) * crown_r
    ang = np.arange(7) * (2 * np.pi / 6)
    ring = np.stack([np.cos(ang), np.sin(ang)], 1) * r_trunk
    quads = []
    for k in range(6):
        a, b = ring[k], ring[k + 1]
        quads.append([[a[0], a[1], 0], [b[0], b[1], 0], [b[0], b[1], trunk_h + crown_h * 0.3],
                      [a[0], a[1], trunk_h + crown_h * 0.3]])
    trunk = _quads_scene(np.array(quads) + np.asarray(base, float), "vegetation", iid, OPAQUE,
                         reflect=0.3)
    verts, faces = _sphere(2)
    bumps = np.clip(1 + 0.08 * rng.standard_normal(len(verts)), 0.85, 1.0)  # within r
    centre = np.asarray(base, float) + np.array([0, 0, trunk_h + crown_h * 0.45])
    p = verts * bumps[:, None] * np.array([crown_r, crown_r, crown_h * 0.55]) + centre
    tri = p[faces]
    n = len(tri)
    crown = _Scene(tri, np.full(n, _LABEL["vegetation"]), np.full(n, iid),
                   np.full(n, FOLIAGE, np.int8), np.full(n, _REFLECTANCE["vegetation"]))
    return _Scene.concat([trunk, crown])


def _car(centre, u, v, rng: np.random.Generator, iid: int) -> _Scene:
    """A parked car: body box (0.3 m above the ground) and a cabin with glass sides."""
    length = float(rng.uniform(3.8, 4.7))
    width = float(rng.uniform(1.7, 1.9))
    body_top = float(rng.uniform(0.95, 1.1))
    cabin_top = body_top + float(rng.uniform(0.4, 0.55))
    c = np.asarray(centre, float)
    refl = float(rng.choice([0.15, 0.3, 0.45, 0.6]))
    body = _oriented_box(c, u, v, (length, width), c[2] + 0.3, c[2] + body_top)
    cab = _oriented_box(c + u * float(rng.uniform(-0.3, 0.1)), u, v,
                        (length * 0.55, width * 0.92), c[2] + body_top, c[2] + cabin_top)
    return _Scene.concat([_quads_scene(body, "car", iid, OPAQUE, refl),
                          _quads_scene(cab[4:5], "car", iid, OPAQUE, refl),
                          _quads_scene(cab[:4], "car", iid, GLASS, 0.08)])


# ================================================================================ building
@dataclass
class _Leaf:
    node: Any
    symbol: str
    label: str
    x0: float
    x1: float
    y0: float
    y1: float
    z: float
    element: int = -1


def _layout_leaves(layout) -> list[_Leaf]:
    from .synthetic import _canonical

    tree = layout.tree
    frame = tree.scope
    out = []
    for lf in tree.painting_order():
        s = lf.scope.size
        if not (s[0] > 1e-6 and s[1] > 1e-6):
            continue
        corners = np.array([[0, 0, 0], [s[0], 0, 0], [s[0], s[1], 0], [0, s[1], 0]], float)
        loc = frame.to_local(lf.scope.to_world(corners))
        out.append(_Leaf(lf, lf.symbol.split(".")[-1], _canonical(lf),
                         round(float(loc[:, 0].min()), 6), round(float(loc[:, 0].max()), 6),
                         round(float(loc[:, 1].min()), 6), round(float(loc[:, 1].max()), 6),
                         round(float(loc[:, 2].mean()), 6)))
    return out


def _group_elements(tree, leaves: list[_Leaf]) -> int:
    """Set ``element`` of the leaves: maximal subtrees whose (non-void) leaves share one label
    other than wall and roof.  Returns the number of elements."""
    by_node = {id(lf.node): lf for lf in leaves if lf.label not in _VOID_LABELS}
    labels: dict[int, frozenset] = {}
    order = list(tree.walk())
    for node in reversed(order):
        if node.children:
            s: frozenset = frozenset()
            for c in node.children:
                s = s | labels[id(c)]
            labels[id(node)] = s
        else:
            lf = by_node.get(id(node))
            labels[id(node)] = frozenset((lf.label,)) if lf is not None else frozenset()
    count = 0
    stack = [tree]
    while stack:
        node = stack.pop()
        s = labels[id(node)]
        if len(s) == 1:
            (label,) = s
            if label not in ("wall", "roof"):
                for n in node.walk():
                    lf = by_node.get(id(n))
                    if lf is not None:
                        lf.element = count
                count += 1
            continue
        stack.extend(reversed(node.children))
    return count


def _runs(keys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices of runs of equal consecutive rows of the key columns."""
    n = len(keys[0])
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    change = np.zeros(n, bool)
    change[0] = True
    for k in keys:
        change[1:] |= k[1:] != k[:-1]
    starts = np.flatnonzero(change)
    return starts, np.append(starts[1:], n)


_THIN = ("railing", "balconyglass", "shutter", "hedge")


def facade_building(layout, *, depth: float = 12.0, room_depth: float = 4.0,
                    origin: Sequence[float] = (0.0, 0.0, 0.0), name: str | None = None) -> Model:
    """A 3D building from a synthetic facade layout (:func:`~.synthetic.make_facade`).

    The layout's leaves are rectangles at depths ``z`` from the wall plane; the partition of the
    facade (leaves painted over no other) becomes the front relief of a solid block ``depth``
    metres deep: each leaf one face at its depth, and between neighbouring cells of different
    depth a step face owned by the one in front (window and door reveals are thus ``wall``, the
    ends of cornices and ledges are cornice).  Where the layout is sky, the block ends: a flat
    roof (label ``roof``) closes each column on top, side walls close it left and right.  Leaves
    painted over others (balcony slabs and railings, sills, shutters, chimneys) stand in front
    as boxes back to the surface behind them, railings and shutters as thin plates.  An interior
    wall (label ``other``) stands ``room_depth`` behind the facade, where rays through glass end.
    The street strip at the bottom of the layout is dropped: the building stands on ``y = 0``.

    Parameters
    ----------
    layout : SyntheticFacade
        A layout of :mod:`.synthetic` (its ``tree`` is read, in metres).
    depth : float
        Depth of the building behind its facade plane (m).
    room_depth : float
        Distance of the interior wall behind the facade plane (m).
    origin : (x, y, z)
        Where the facade's bottom-left corner goes (CGA world frame, y up; the facade faces +z).
    name : str, optional
        Model name (default ``building``).

    Returns
    -------
    Model
        Parts in world coordinates (y up); ``shape_id`` is the instance: 0 the walls, 1 the
        roofs, 2… the elements.  ``attributes``: ``facade_planes`` (front, left, right, back:
        point, outward normal, width, height), ``style``, ``layout_attributes``, ``elements``
        (count).
    """
    if not depth > 0.5:
        raise InputError(f"building depth must exceed 0.5 m, got {depth}")
    leaves = _layout_leaves(layout)
    n_el = _group_elements(layout.tree, leaves)
    street = [lf.y1 for lf in leaves if lf.label == "ground" and lf.y0 <= 1e-6]
    y_shift = max(street) if street else 0.0
    for lf in leaves:
        lf.y0, lf.y1 = round(max(lf.y0 - y_shift, 0.0), 6), round(lf.y1 - y_shift, 6)
    leaves = [lf for lf in leaves if lf.y1 > 1e-6 and not (lf.label == "ground")]
    if not leaves:
        raise InputError("the facade layout has no leaf to build")
    xs = np.unique([v for lf in leaves for v in (lf.x0, lf.x1)])
    ys = np.unique([v for lf in leaves for v in (lf.y0, lf.y1)])
    nx, ny = len(xs) - 1, len(ys) - 1
    owner = np.full((nx, ny), -1, np.int64)
    base, overlays = [], []
    spans = []
    for k, lf in enumerate(leaves):
        i0, i1 = np.searchsorted(xs, [lf.x0, lf.x1])
        j0, j1 = np.searchsorted(ys, [lf.y0, lf.y1])
        spans.append((i0, i1, j0, j1))
        if i1 <= i0 or j1 <= j0:
            continue
        if (owner[i0:i1, j0:j1] >= 0).any():
            overlays.append(k)
        else:
            owner[i0:i1, j0:j1] = k
            base.append(k)
    void = np.array([lf.label in _VOID_LABELS for lf in leaves] + [True])
    zs = np.array([lf.z for lf in leaves] + [np.nan])
    own = np.where(owner < 0, len(leaves), owner)
    is_void = void[own]
    back = -float(depth)
    h = np.where(is_void, back, zs[own])

    WALL, ROOF = 0, 1
    inst_of = [WALL if lf.label == "wall" or (lf.element < 0 and lf.label not in ("roof",))
               else ROOF if lf.label == "roof" and lf.element < 0 else 2 + lf.element
               for lf in leaves]
    quads: list[np.ndarray] = []
    meta: list[tuple[str, int, int, str]] = []  # label, instance, surface, symbol

    def surface(lf: _Leaf) -> int:
        s = lf.symbol.lower()
        if "railing" in s:
            return RAILING
        if "glass" in s:
            return GLASS
        return OPAQUE

    # front faces of the partition
    for k in base:
        lf = leaves[k]
        if void[k]:
            continue
        quads.append(np.array([[lf.x0, lf.y0, lf.z], [lf.x1, lf.y0, lf.z], [lf.x1, lf.y1, lf.z],
                               [lf.x0, lf.y1, lf.z]]))
        meta.append((lf.label, inst_of[k], surface(lf), lf.symbol))

    def steps(axis: int) -> None:
        """Step faces across cell edges perpendicular to ``axis`` (0: x edges, 1: y edges)."""
        hh = h if axis == 0 else h.T
        oo = own if axis == 0 else own.T
        vv = is_void if axis == 0 else is_void.T
        edges = xs if axis == 0 else ys
        other = ys if axis == 0 else xs
        m = hh.shape[1]
        pad_h = np.vstack([np.full((1, m), back), hh, np.full((1, m), back)])
        pad_o = np.vstack([np.full((1, m), len(leaves)), oo, np.full((1, m), len(leaves))])
        pad_v = np.vstack([np.ones((1, m), bool), vv, np.ones((1, m), bool)])
        a, b = pad_h[:-1], pad_h[1:]  # (edges, m): cell before and after each edge
        diff = np.abs(a - b) > 1e-9
        e_idx, c_idx = np.nonzero(diff)
        if not len(e_idx):
            return
        ha, hb = a[e_idx, c_idx], b[e_idx, c_idx]
        first = ha > hb  # the cell before the edge is in front: it owns the face
        own_k = np.where(first, pad_o[:-1][e_idx, c_idx], pad_o[1:][e_idx, c_idx])
        nb_void = np.where(first, pad_v[1:][e_idx, c_idx], pad_v[:-1][e_idx, c_idx])
        lo, hi = np.minimum(ha, hb), np.maximum(ha, hb)
        # the bottom of the building stands on the ground: no face along y = 0
        keep = ~((axis == 1) & (e_idx == 0))
        # towards a void beside (x edges) the face is a side wall behind the facade plane, and
        # towards a void above (y edges, the owner below) a roof; in front of the plane it is
        # the end of the owner's protrusion
        outside = nb_void & ((axis == 0) | first)
        cols = [[], [], [], [], [], [], []]
        for sel, plo, phi, flag in ((keep & outside, lo, np.minimum(hi, 0.0), 1),
                                    (keep & outside, np.maximum(lo, 0.0), hi, 0),
                                    (keep & ~outside, lo, hi, 0)):
            sel = sel & (phi - plo > 1e-9)
            for col, val in zip(cols, (e_idx, c_idx, plo, phi, own_k,
                                       np.full(len(e_idx), flag), first), strict=True):
                col.append(val[sel])
        e, c, plo, phi, ok, outer, fr = (np.concatenate(col) for col in cols)
        if not len(e):
            return
        order = np.lexsort((c, outer, e))
        e, c, plo, phi, ok, outer, fr = (x[order] for x in (e, c, plo, phi, ok, outer, fr))
        # merge runs of consecutive cells along the edge with the same face
        starts, stops = _runs([e, outer, np.round(plo, 6), np.round(phi, 6), ok, fr,
                               np.r_[0, np.cumsum(np.diff(c) != 1)]])
        for s0, s1 in zip(starts, stops, strict=True):
            lf = leaves[ok[s0]]
            w = edges[e[s0]]
            c0, c1 = other[c[s0]], other[c[s1 - 1] + 1]
            z0, z1 = plo[s0], phi[s0]
            if axis == 0:
                q = [[w, c0, z0], [w, c1, z0], [w, c1, z1], [w, c0, z1]]
            else:
                q = [[c0, w, z0], [c1, w, z0], [c1, w, z1], [c0, w, z1]]
            quads.append(np.array(q, float))
            if outer[s0]:
                meta.append(("wall" if axis == 0 else "roof", WALL if axis == 0 else ROOF,
                             OPAQUE, "Side" if axis == 0 else "RoofTop"))
            else:
                meta.append((lf.label, inst_of[ok[s0]], OPAQUE, lf.symbol))

    steps(0)
    steps(1)

    # what is painted over the partition
    for k in overlays:
        lf = leaves[k]
        if void[k]:
            continue
        i0, i1, j0, j1 = spans[k]
        under = h[i0:i1, j0:j1][~is_void[i0:i1, j0:j1]]
        thin = any(t in lf.symbol.lower() for t in _THIN)
        x0, x1, y0, y1, z = lf.x0, lf.x1, lf.y0, lf.y1, lf.z
        sym = lf.symbol
        if thin:
            quads.append(np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]))
            meta.append((lf.label, inst_of[k], surface(lf), sym))
            continue
        if len(under) and z > under.min() + 1e-6:
            zb = max(float(under.min()), z - 1.0)
        elif len(under):
            zb = z - 0.05
        else:
            zb = z - min(1.0, x1 - x0)
        for q in _box_quads((x0, y0, zb), (x1, y1, z)):  # an axis-aligned box in any frame
            front = abs(q[:, 2] - z).max() < 1e-9
            quads.append(q)
            meta.append((lf.label, inst_of[k], surface(lf) if front else OPAQUE, sym))

    # the interior wall, behind columns that stand in front of it
    rd = min(float(room_depth), depth - 0.2)
    inside = ~is_void & (h > -rd + 0.3)
    for j in range(ny):
        row = inside[:, j]
        if not row.any():
            continue
        s = np.flatnonzero(np.diff(np.r_[0, row.astype(np.int8), 0]) == 1)
        t = np.flatnonzero(np.diff(np.r_[0, row.astype(np.int8), 0]) == -1)
        for a, b in zip(s, t, strict=True):
            quads.append(np.array([[xs[a], ys[j], -rd], [xs[b], ys[j], -rd],
                                   [xs[b], ys[j + 1], -rd], [xs[a], ys[j + 1], -rd]]))
            meta.append(("other", -1, OPAQUE, "Interior"))

    o = np.asarray(origin, float)
    groups: dict[tuple, list[np.ndarray]] = {}
    for q, key in zip(quads, meta, strict=True):
        groups.setdefault(key, []).append(q + o)
    parts = []
    for (label, iid, surf, sym), qs in groups.items():
        mat = Material(name=_SURFACE_NAMES[surf], opacity=0.3 if surf == GLASS else 1.0)
        parts.append(Part(Mesh.from_polygons(qs), label, mat, sym, iid))
    solid = ~is_void
    width = float(xs[-1] - xs[0])
    top = float(ys[np.flatnonzero(solid.any(axis=0)).max() + 1]) if solid.any() else 0.0
    x_mid = o[0] + (xs[0] + xs[-1]) / 2
    planes = [
        {"point": [x_mid, top / 2, o[2]], "normal": [0, 0, 1], "kind": "front", "width": width,
         "height": top},
        {"point": [o[0] + xs[0], top / 2, o[2] - depth / 2], "normal": [-1, 0, 0],
         "kind": "left", "width": depth, "height": top},
        {"point": [o[0] + xs[-1], top / 2, o[2] - depth / 2], "normal": [1, 0, 0],
         "kind": "right", "width": depth, "height": top},
        {"point": [x_mid, top / 2, o[2] - depth], "normal": [0, 0, -1], "kind": "back",
         "width": width, "height": top},
    ]
    return Model(parts=parts, root=layout.tree, reports=dict(layout.reports),
                 warnings=list(layout.warnings), name=name or "building",
                 attributes={"facade_planes": planes, "style": layout.style,
                             "layout_attributes": dict(layout.attributes),
                             "elements": n_el, "depth": float(depth),
                             "width": width, "height": top})


# ================================================================================ scanning
def _as_models(model_or_models) -> list[Model]:
    if isinstance(model_or_models, Model):
        return [model_or_models]
    models = list(model_or_models)
    if not models or not all(isinstance(m, Model) for m in models):
        raise InputError("simulate_scan needs a Model or a list of Models")
    return models


def _street_frame(planes: list[dict], scene: _Scene):
    """Origin on the main facade (its point), outward normal ``n``, along-street ``u``."""
    if planes:
        fronts = [p for p in planes if p["kind"] == "front"] or planes
        main = max(fronts, key=lambda p: p["width"] * p["height"])
        n, u = main["normal"], main["u"]
        p0 = main["point"].copy()
    else:
        lo, hi = scene.tri.reshape(-1, 3).min(0), scene.tri.reshape(-1, 3).max(0)
        n, u = np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])
        p0 = np.array([(lo[0] + hi[0]) / 2, lo[1], lo[2]])
    pts = scene.tri.reshape(-1, 3)
    su = (pts - p0) @ u
    sv = (pts - p0) @ n
    if planes:
        fronts = [p for p in planes if abs(p["normal"] @ n) > 0.99]
        front_v = max(float((p["point"] - p0) @ n) for p in fronts)
    else:
        front_v = float(sv.max())
    ground = float(pts[:, 2].min())
    p0 = p0 + front_v * n
    p0[2] = ground
    return p0, n, u, (float(su.min()), float(su.max())), float(sv.min() - front_v)


def _to_world(p0, n, u, su, sv, z):
    return p0 + np.outer(su, u) + np.outer(sv, n) + np.outer(z, np.array([0.0, 0.0, 1.0]))


def _street(p0, n, u, urange, vback, occluders: bool, ground: bool, rng, keep_clear,
            next_id: list) -> tuple[_Scene, dict[int, str]]:
    scenes, names = [], {}
    if ground:
        u0, u1 = urange[0] - 30.0, urange[1] + 30.0
        v0, v1 = vback - 2.0, 40.0
        corners = _to_world(p0, n, u, np.array([u0, u1, u1, u0]), np.array([v0, v0, v1, v1]),
                            np.zeros(4))
        gid = next_id[0]
        next_id[0] += 1
        names[gid] = "ground"
        scenes.append(_quads_scene(corners[None], "ground", gid, OPAQUE))
    if occluders:
        length = urange[1] - urange[0]

        clear_pts = (np.zeros((0, 3)) if keep_clear is None
                     else np.asarray(keep_clear, float).reshape(-1, 3))

        def room(pos) -> float:
            """Horizontal distance from ``pos`` to the nearest scanner position."""
            if not len(clear_pts):
                return np.inf
            return float(np.linalg.norm((clear_pts - pos)[:, :2], axis=1).min())

        n_trees = int(rng.integers(0, 2 + int(length // 12)))
        trees: list[float] = []
        for _ in range(min(n_trees, 4)):
            su = float(rng.uniform(urange[0] + 1.0, urange[1] - 1.0))
            sv = float(rng.uniform(2.3, 3.3))
            pos = _to_world(p0, n, u, np.array([su]), np.array([sv]), np.zeros(1))[0]
            r_max = min(sv - 0.4, room(pos) - 0.8)
            sub = np.random.default_rng(rng.integers(0, 2**63))
            if any(abs(su - a) < 5.0 for a in trees) or r_max < 1.2:
                continue
            tid = next_id[0]
            next_id[0] += 1
            names[tid] = "vegetation"
            trees.append(su)
            scenes.append(_tree(pos, sub, tid, r_max))
        n_cars = int(rng.integers(0, 2 + int(length // 10)))
        cars: list[float] = []
        for _ in range(min(n_cars, 4)):
            su = float(rng.uniform(urange[0], urange[1]))
            sv = float(rng.uniform(4.3, 4.9))
            pos = _to_world(p0, n, u, np.array([su]), np.array([sv]), np.zeros(1))[0]
            sub = np.random.default_rng(rng.integers(0, 2**63))
            rel = clear_pts[:, :2] - pos[:2]
            inside = (np.abs(rel @ u[:2]) < 2.35 + 0.6) & (np.abs(rel @ n[:2]) < 0.95 + 0.6)
            if any(abs(su - a) < 5.0 for a in cars) or inside.any():
                continue
            cid = next_id[0]
            next_id[0] += 1
            names[cid] = "car"
            cars.append(su)
            scenes.append(_car(pos, u, n, sub, cid))
    return (_Scene.concat(scenes) if scenes else _Scene.empty()), names


def _tls_rays(station, lo, hi, step_deg):
    """Directions on the azimuth/elevation grid covering the box ``lo``–``hi`` from ``station``."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])]) - station
    inside = (lo[0] <= station[0] <= hi[0]) and (lo[1] <= station[1] <= hi[1])
    az = np.degrees(np.arctan2(corners[:, 1], corners[:, 0]))
    el = np.degrees(np.arctan2(corners[:, 2], np.hypot(corners[:, 0], corners[:, 1])))
    if inside:
        a0, a1 = -180.0, 180.0 - step_deg
    else:
        centre = np.degrees(np.arctan2(*(((lo + hi) / 2 - station)[[1, 0]])))
        rel = (az - centre + 180.0) % 360.0 - 180.0
        a0, a1 = centre + rel.min() - 2.0, centre + rel.max() + 2.0
    e0, e1 = max(el.min() - 3.0, -89.0), min(el.max() + 2.0, 89.5)
    ka = np.arange(math.floor(a0 / step_deg), math.ceil(a1 / step_deg) + 1) * step_deg
    ke = np.arange(math.floor(e0 / step_deg), math.ceil(e1 / step_deg) + 1) * step_deg
    A, E = np.meshgrid(np.radians(ka), np.radians(ke), indexing="ij")
    ce = np.cos(E)
    return np.stack([ce * np.cos(A), ce * np.sin(A), np.sin(E)], -1).reshape(-1, 3)


def _mls_lines(trajectory, spacing):
    """Scanner positions every ``spacing`` metres along a polyline and the travel direction."""
    tr = np.asarray(trajectory, float)
    seg = np.diff(tr, axis=0)
    length = np.linalg.norm(seg, axis=1)
    cum = np.r_[0.0, np.cumsum(length)]
    if cum[-1] <= 0:
        raise InputError("the MLS trajectory has no length")
    s = np.arange(0.0, cum[-1] + 1e-9, spacing)
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    f = (s - cum[k]) / np.where(length[k] > 0, length[k], 1.0)
    pos = tr[k] + seg[k] * f[:, None]
    heading = seg[k] / np.where(length[k] > 0, length[k], 1.0)[:, None]
    return pos, heading


def _mls_rays(pos, heading, lo, hi, step_deg):
    """Per scan line: directions in the vertical plane perpendicular to the travel direction,
    on the side of the scene, from straight down to just above the scene's top."""
    up = np.array([0.0, 0.0, 1.0])
    centre = (lo + hi) / 2
    dirs, src = [], []
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    for i, (p, t) in enumerate(zip(pos, heading, strict=True)):
        t = t - (t @ up) * up
        nt = np.linalg.norm(t)
        t = t / nt if nt > 1e-9 else np.array([1.0, 0.0, 0.0])
        c = np.cross(up, t)
        if (centre - p) @ c < 0:
            c = -c
        rel = corners - p
        theta = np.degrees(np.arctan2(rel @ up, np.maximum(rel @ c, 1e-6)))
        t1 = min(float(theta.max()) + 2.0, 90.0)
        ks = np.arange(math.floor(-90.0 / step_deg), math.floor(t1 / step_deg) + 1) * step_deg
        th = np.radians(ks)
        dirs.append(np.cos(th)[:, None] * c + np.sin(th)[:, None] * up)
        src.append(np.full(len(th), i, np.int64))
    return np.concatenate(dirs), np.concatenate(src)


def simulate_scan(model_or_models, *, kind: str = "terrestrial", scanners=None, trajectory=None,
                  angular_step_deg: float = 0.1, line_spacing: float = 0.1,
                  max_range: float = 60.0, range_noise: float = 0.005,
                  glass_return: float = 0.15, glass_pass: float = 0.35,
                  occluders: bool = True, ground: bool = True, seed: int = 0) -> ScanResult:
    """Ray-cast a laser scan of models (see the module docstring for what is simulated).

    Parameters
    ----------
    model_or_models : Model or list of Model
        The scene, CGA world frame (y up).  :func:`facade_building` models carry their facade
        planes; for others they are estimated from the wall faces.
    kind : {"terrestrial", "mobile"}
        Static stations with a panoramic grid of rays, or a profiler moving along a line.
    scanners : (K, 3) array, optional
        TLS station positions (output frame, z up).  Default: one station per 25 m of street,
        10 m in front of the main facade, 1.7 m above the ground.
    trajectory : (M, 3) array, optional
        MLS path as a polyline (output frame).  Default: a straight line 7 m in front of the
        main facade, 2.3 m above the ground, 5 m beyond the scene at both ends.
    angular_step_deg : float
        Angle between neighbouring rays (TLS: in azimuth and elevation; MLS: within a line).
    line_spacing : float
        MLS: distance travelled between scan lines (m).
    max_range : float
        Farthest return (m).
    range_noise : float
        σ of the Gaussian range noise (m).
    glass_return, glass_pass : float
        Probability that a ray meeting glass returns from it, and that it passes through to what
        is behind (the interior wall); the rest of the rays are lost.
    occluders : bool
        Put street trees and parked cars between the scanners and the facades.
    ground : bool
        Add the street's ground plane.
    seed : int
        Seed of the occluders, the glass/foliage draws and the noise: same seed, same scan.

    Returns
    -------
    ScanResult
    """
    t_start = time.perf_counter()
    if kind not in ("terrestrial", "mobile"):
        raise InputError(f"scan kind must be 'terrestrial' or 'mobile', got {kind!r}")
    for name, v in (("angular_step_deg", angular_step_deg), ("line_spacing", line_spacing),
                    ("max_range", max_range)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    if not (0 <= glass_return <= 1 and 0 <= glass_pass <= 1 and glass_return + glass_pass <= 1):
        raise InputError(f"glass_return ({glass_return}) and glass_pass ({glass_pass}) must be "
                         "probabilities whose sum is at most 1")
    if not range_noise >= 0:
        raise InputError(f"range_noise must be >= 0, got {range_noise}")
    models = _as_models(model_or_models)
    rng = np.random.default_rng(np.random.SeedSequence([abs(int(seed)), int(seed < 0), 0x5CA7]))

    instance_of: dict = {}
    next_id = [0]
    names: dict[int, str] = {}
    scenes, planes = [], []
    for m in models:
        sc, nm = _model_scene(m, instance_of, next_id)
        scenes.append(sc)
        names.update(nm)
        planes += _model_planes(m)
    building = _Scene.concat(scenes)
    if not len(building.tri):
        raise InputError("the models have no geometry to scan")
    elements = _elements(building, planes, names)
    if planes and not any(p["kind"] == "front" for p in planes):
        # the street side of a model without recorded planes: where its doors and shops are,
        # else its largest wall
        doors = np.zeros(len(planes))
        for e in elements:
            doors[e["facade"]] += e["label"] in ("door", "shop")
        area = np.array([p.get("area", 0.0) for p in planes])
        planes[int(np.lexsort((-area, -doors))[0])]["kind"] = "front"
    p0, n, u, urange, vback = _street_frame(planes, building)

    if kind == "terrestrial":
        if scanners is None:
            k = max(1, math.ceil((urange[1] - urange[0]) / 25.0))
            su = urange[0] + (np.arange(k) + 0.5) * (urange[1] - urange[0]) / k
            stations = _to_world(p0, n, u, su, np.full(k, 10.0), np.full(k, TLS_HEIGHT))
        else:
            stations = np.asarray(scanners, float).reshape(-1, 3)
        keep_clear = stations
    else:
        if trajectory is None:
            tr = _to_world(p0, n, u, np.array([urange[0] - 5.0, urange[1] + 5.0]),
                           np.array([7.0, 7.0]), np.full(2, MLS_HEIGHT))
        else:
            tr = np.asarray(trajectory, float).reshape(-1, 3)
            if len(tr) < 2:
                raise InputError("an MLS trajectory needs at least two points")
        stations, heading = _mls_lines(tr, line_spacing)
        keep_clear = stations
    if not np.isfinite(stations).all() or not len(stations):
        raise InputError("scanner positions must be finite (K, 3) coordinates")

    street, street_names = _street(p0, n, u, urange, vback, occluders, ground, rng, keep_clear,
                                   next_id)
    names.update(street_names)
    scene = _Scene.concat([building, street])
    # the scene to aim at: everything but the ground
    solid = scene.tri[scene.label != _LABEL["ground"]].reshape(-1, 3)
    lo, hi = solid.min(0), solid.max(0)
    if kind == "terrestrial":
        parts = [_tls_rays(s, lo, hi, angular_step_deg) for s in stations]
        dirs = np.concatenate(parts)
        src = np.concatenate([np.full(len(p), i, np.int64) for i, p in enumerate(parts)])
    else:
        dirs, src = _mls_rays(stations, heading, lo, hi, angular_step_deg)

    _kernels()
    tri = scene.tri
    v0 = np.ascontiguousarray(tri[:, 0])
    e1 = np.ascontiguousarray(tri[:, 1] - tri[:, 0])
    e2 = np.ascontiguousarray(tri[:, 2] - tri[:, 0])
    order, bmin, bmax, left, right, start, count = _k_build_bvh(
        np.ascontiguousarray(tri.min(1)), np.ascontiguousarray(tri.max(1)),
        np.ascontiguousarray(tri.mean(1)), 4)
    p_return = np.array([1.0, glass_return, 0.5, 0.55])
    p_pass = np.array([0.0, glass_pass, 0.5, 0.45])
    cast_seed = int(rng.integers(0, 2**62))
    t, hit, through = _k_cast(stations, src, np.ascontiguousarray(dirs), MIN_RANGE,
                                float(max_range), bmin, bmax, left, right, start, count,
                                v0[order], e1[order], e2[order],
                                scene.surface[order].astype(np.int64), p_return, p_pass,
                                cast_seed, _MAX_INTERACTIONS)
    ok = hit >= 0
    t, tri_id, src_ok, d_ok = t[ok], order[hit[ok]], src[ok], dirs[ok]
    surf = scene.surface[tri_id]
    # range: noise along the ray; foliage returns come from inside the crown
    rng_noise = np.random.default_rng(cast_seed)
    r = t + np.clip(rng_noise.standard_normal(len(t)), -NOISE_CLIP, NOISE_CLIP) * range_noise
    fol = (surf == FOLIAGE) & (through[ok] == 0)  # entering a crown: returns from inside it
    r[fol] += np.minimum(rng_noise.exponential(0.15, int(fol.sum())), 0.5)
    xyz = stations[src_ok] + d_ok * r[:, None]
    # true normals, facing the scanner, and the incidence
    tri_hit = tri[tri_id]
    nrm = np.cross(tri_hit[:, 1] - tri_hit[:, 0], tri_hit[:, 2] - tri_hit[:, 0])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    cos = np.einsum("ij,ij->i", nrm, d_ok)
    nrm[cos > 0] *= -1
    cos = np.abs(cos)
    refl = scene.reflect[tri_id].copy()
    glass = surf == GLASS
    refl[glass] = 0.06 + 0.85 * cos[glass] ** 40
    fall = 1.0 / np.sqrt(1.0 + (t / 40.0) ** 2)
    inten = 65535.0 * refl * (0.2 + 0.8 * cos) * fall
    inten = inten * (1 + 0.04 * rng_noise.standard_normal(len(t))) \
        + 250.0 * rng_noise.standard_normal(len(t))
    inten = np.clip(np.rint(inten), 0, 65535)

    cloud = PointCloud(xyz, intensity=inten.astype(np.float32), normals=nrm.astype(np.float32),
                       labels=scene.label[tri_id].astype(np.int32), label_names=LABEL_NAMES,
                       instance=scene.instance[tri_id].astype(np.int32), up=2,
                       source=f"<synthetic {kind} scan>",
                       extra={"scanner": src_ok.astype(np.int32),
                              "range": r.astype(np.float32), "surface": surf.astype(np.uint8)})
    names = {k: v for k, v in names.items() if k >= 0}
    meta = {"kind": kind, "seed": int(seed), "angular_step_deg": float(angular_step_deg),
            "line_spacing": float(line_spacing) if kind == "mobile" else None,
            "max_range": float(max_range), "range_noise": float(range_noise),
            "glass_return": float(glass_return), "glass_pass": float(glass_pass),
            "occluders": bool(occluders), "ground": bool(ground), "rays": int(len(dirs)),
            "points": int(len(xyz)), "triangles": int(len(tri)),
            "passed_glass": int((through[ok] > 0).sum()),
            "models": [m.name for m in models],
            "seconds": round(time.perf_counter() - t_start, 3)}
    return ScanResult(cloud, kind, stations, elements, planes, names, meta)


# ================================================================================ generator
def _overrides(rules) -> dict[str, Any]:
    from .synthetic import attribute_space

    space = attribute_space(rules)
    fixed = {"nTrees": 0, "nCars": 0, "hedgeHeight": 0, "neighbourWidth": 0}
    return {k: v for k, v in fixed.items() if k in space}


def synthetic_scans(n: int, seed: int, *, kind: str | None = None,
                    styles: Iterable[str] | None = None, **scan_options) -> list[ScanResult]:
    """``n`` scans of random streets: one to three :func:`facade_building`\\ s in a row.

    Scan ``i`` draws everything from a random stream made of ``(seed, i)`` only: the styles
    (:data:`~.synthetic.STYLES`) and their grammar attributes (:func:`~.synthetic.make_facade`,
    without the grammars' own flat trees and cars: the scan adds 3D ones), building depths and
    set-backs, then scans the street (``kind``: ``None`` alternates terrestrial for even ``i``
    and mobile for odd ``i``).  ``scan_options`` go to :func:`simulate_scan` (``seed`` is drawn).
    ``meta`` of each result gains ``index``, ``street_seed`` and ``buildings`` (style, width,
    height, depth, attributes).
    """
    from .synthetic import STYLES, load_style, make_facade

    if n < 0:
        raise InputError(f"number of scans must be >= 0, got {n}")
    pool = tuple(styles) if styles else STYLES
    for s in pool:
        if s not in STYLES:
            raise InputError(f"unknown facade style {s!r}; use one of {', '.join(STYLES)}")
    if "seed" in scan_options:
        raise InputError("synthetic_scans draws the scan seed itself; pass seed=… positionally")
    out = []
    for i in range(n):
        rng = np.random.default_rng(np.random.SeedSequence([abs(int(seed)), int(seed < 0), i,
                                                            0x5CA75]))
        count = int(rng.choice([1, 2, 3], p=[0.45, 0.35, 0.2]))
        models, info = [], []
        x = 0.0
        for b in range(count):
            style = pool[int(rng.integers(0, len(pool)))]
            layout = make_facade(style, rng, px_per_m=4.0, attrs=_overrides(load_style(style)))
            depth = float(rng.uniform(9.0, 15.0))
            setback = float(rng.choice([0.0, 0.0, -0.4, 0.3])) if b else 0.0
            model = facade_building(layout, depth=depth, origin=(x, 0.0, setback),
                                    name=f"building_{b}")
            models.append(model)
            info.append({"style": style, "width": model.attributes["width"],
                         "height": model.attributes["height"], "depth": depth,
                         "origin": [x, 0.0, setback], "attributes": layout.attributes})
            x += model.attributes["width"]
        k = kind or ("terrestrial" if i % 2 == 0 else "mobile")
        scan_seed = int(rng.integers(0, 2**31 - 1))
        res = simulate_scan(models, kind=k, seed=scan_seed, **scan_options)
        res.meta.update({"index": i, "street_seed": int(seed), "buildings": info})
        out.append(res)
    return out


# ================================================================================ writing
def _atomic_write(path: Path, data: bytes) -> None:
    """Write ``path`` whole or not at all: a temporary file beside it, then a rename."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "xb") as f:  # "x": never another writer's file; the umask applies
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


PLY_DTYPE = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("intensity", "<u2"),
                      ("label", "<i4"), ("instance", "<i4"), ("scanner", "<i4")])


def _ply_bytes(result: ScanResult) -> bytes:
    c = result.cloud
    arr = np.empty(len(c), PLY_DTYPE)
    arr["x"], arr["y"], arr["z"] = c.xyz[:, 0], c.xyz[:, 1], c.xyz[:, 2]
    arr["intensity"] = np.clip(np.rint(c.intensity), 0, 65535).astype(np.uint16)
    arr["label"] = c.labels
    arr["instance"] = c.instance
    arr["scanner"] = c.extra.get("scanner", np.zeros(len(c), np.int32))
    comments = [f"facadeforge synthetic {result.kind} scan, z up, metres",
                "label_names " + " ".join(LABEL_NAMES)]
    try:
        import io

        from plyfile import PlyData, PlyElement
    except ImportError:
        types = {"<f8": "double", "<u2": "ushort", "<i4": "int"}
        head = ["ply", "format binary_little_endian 1.0"] + [f"comment {t}" for t in comments]
        head.append(f"element vertex {len(arr)}")
        head += [f"property {types[PLY_DTYPE[k].str]} {k}" for k in PLY_DTYPE.names]
        head.append("end_header")
        return ("\n".join(head) + "\n").encode("ascii") + arr.tobytes()
    buf = io.BytesIO()
    PlyData([PlyElement.describe(arr, "vertex")], text=False, byte_order="<",
            comments=comments).write(buf)
    return buf.getvalue()


def write_scan(result: ScanResult, folder: str | Path, name: str = "scan") -> tuple[Path, Path]:
    """Write ``folder/NAME.ply`` (binary little-endian: ``x y z`` double, ``intensity`` ushort,
    ``label`` int into :data:`LABEL_NAMES`, ``instance`` int, ``scanner`` int) and
    ``folder/truth.json`` (:meth:`ScanResult.truth`), each whole or not at all (temporary file
    and rename).  Returns both paths."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    ply = out / f"{name}.ply"
    truth = out / "truth.json"
    _atomic_write(ply, _ply_bytes(result))
    text = json.dumps(result.truth(), indent=1, sort_keys=True, allow_nan=False)
    _atomic_write(truth, (text + "\n").encode())
    return ply, truth
