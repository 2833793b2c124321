"""RANSAC planes: facadeforge's :func:`~facadeforge.points.planes.detect_planes` beside Open3D.

The same clouds, in the same process, on the same machine:

- ``nuist``: ``../shared/data/pointclouds/nuist/building_1/facade_1`` (54,864 points, a
  terrestrial scan of one shop-street facade, every point labelled wall / window / door);
- ``lille``: ``../shared/data/pointclouds/lille_street_small.ply`` (170,610 points, a real mobile
  scan of a street, no labels);
- ``million``: the Lille scan and five copies of it with 1 cm Gaussian jitter (seed 0) —
  1,023,660 points, the cloud ``benchmarks/points.py`` builds for its million-point time.

Methods, all with the 0.05 m inlier distance:

- ``facadeforge``: ``detect_planes(cloud)`` with its defaults (normal-guided RANSAC on a
  0.06 m voxel grid, connected pieces, every point then given to the first plane it lies on
  within the piece's extent; the time includes the plane kinds).
- ``open3d``: the loop Open3D's users write (its tutorial's ``segment_plane`` then
  ``select_by_index(inliers, invert=True)``, again on the rest), ``distance_threshold=0.05,
  ransac_n=3, num_iterations=1000``, ``o3d.utility.random.seed(0)`` before each run.  Two
  stops: ``k=ff`` — as many planes as facadeforge found on that cloud; ``until`` — until a plane
  holds fewer points than facadeforge's smallest plane size (its ``min_points`` voxels, about
  1 m², as points at the cloud's mean points per voxel) or 40 planes (facadeforge's
  ``max_planes``).  Both stops are read off one loop: the ``k=ff`` loop is the ``until`` loop
  stopped earlier (or later), same seed, same calls, its time the time at its last plane.
- ``open3d-voxel``: the same loop on ``pcd.voxel_down_sample(0.06)`` (what users do for speed,
  and facadeforge's own grid), then every point of the full cloud given to the first plane (in
  detection order) within 0.05 m of it, so that the scores below count the same points; the
  time includes the down-sampling and that assignment (``open3d_seconds`` without it).

Scores (the same code for every method, from each plane's normal, offset and point indices):

- planes, the inliers of the largest 5, the share of the cloud's points on some plane, the RMS
  point-to-plane distance of all inliers (pooled) and of the largest plane's;
- ``connected_share``: the share of a plane's inliers in its largest connected piece (0.5 m
  cells in the plane, 8-connected), over all planes — descriptive, not a verdict: facadeforge
  cuts planes into such pieces by design, Open3D's planes are infinite;
- ``nuist``: the largest plane's purity (share of its points labelled wall), the share of all
  wall points on it, and the purity of all planes together (each plane counted as its majority
  label: how well planes keep to one element);
- ``lille`` / ``million``: vertical planes (``|n_z| < 0.2``) with more than 2,000 inliers
  (12,000 for the million: the same area at six times the points), the angles between the
  normals of the three largest vertical planes (folded into 0–90°), the largest horizontal
  plane (``|n_z| > 0.95``, the road); and the vertical planes whose largest connected piece alone
  holds more than those 2,000 (12,000) inliers (a wall, not points scattered along a line).

Seconds: best of ``--runs`` (default 3), runs of all methods alternating; a method whose first
run takes longer than ``--long`` seconds (default 150) is run once (``runs`` says how often).
The scores are those of the first run; Open3D's RANSAC runs on several threads and is not
repeatable to the point even with its seed set (``largest_5_per_run`` shows by how much).

Run: ``make bench-env`` (Open3D, large, in ``.venv-bench``), then
``.venv-bench/bin/python benchmarks/planes.py [--runs 3] [--clouds nuist,lille,million]``
→ ``benchmarks/results/planes.json`` and a table on stdout.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "pointclouds"
NUIST = DATA / "nuist" / "building_1" / "facade_1"
LILLE = DATA / "lille_street_small.ply"
THRESHOLD = 0.05
VOXEL = 0.06
MAX_PLANES = 40
VERTICAL_NZ, HORIZONTAL_NZ = 0.2, 0.95
BIG_VERTICAL = 2000          # inliers, at the Lille scan's density
CELL = 0.5                   # m, the in-plane grid of the connected-piece score


# ------------------------------------------------------------------------------- clouds

def load_clouds(names: list[str]) -> dict:
    from facadeforge.datasets.nuist import load_facade
    from facadeforge.points.cloud import PointCloud
    from facadeforge.points.io import read_cloud

    out = {}
    if "nuist" in names:
        out["nuist"] = load_facade(NUIST)
    if "lille" in names or "million" in names:
        lille = read_cloud(LILLE)
        if "lille" in names:
            out["lille"] = lille
        if "million" in names:        # as benchmarks/points.py: the scan and 5 jittered copies
            rng = np.random.default_rng(0)
            xyz = np.concatenate([lille.xyz] + [lille.xyz + rng.normal(0, 0.01, lille.xyz.shape)
                                                for _ in range(5)])
            out["million"] = PointCloud(xyz, source="million")
    return out


def ff_min_points(xyz: np.ndarray) -> tuple[int, int]:
    """facadeforge's default smallest plane (voxels) and its voxel count, as detect_planes
    computes them (the voxel grows past MAX_VOXELS)."""
    from facadeforge.points import planes as ffp

    voxel = ffp.VOXEL
    n = len(ffp.voxel_representatives(xyz, voxel))
    if n > ffp.MAX_VOXELS:
        voxel *= math.sqrt(n / ffp.MAX_VOXELS)
        n = len(ffp.voxel_representatives(xyz, voxel))
    return max(30, min(int(1.0 / voxel ** 2), n // 100)), n


# ------------------------------------------------------------------------------- methods
# Each returns a list of planes (unit normal (3,), offset, sorted point indices into the cloud),
# in detection order, and a dict of times.

def run_facadeforge(cloud) -> tuple[list, dict]:
    from facadeforge.points.planes import detect_planes

    t = time.perf_counter()
    found = detect_planes(cloud)
    secs = time.perf_counter() - t
    return [(p.normal, float(p.offset), p.inliers) for p in found], {"seconds": secs}


def o3d_loop(o3d, xyz: np.ndarray, floor: int, k: int) -> tuple[list, list[float], int | None]:
    """Open3D users' loop: segment_plane, keep the inliers, go on with the rest.

    Runs until both stops are met: ``k`` planes, and a plane under ``floor`` points (or 40
    planes).  Returns every plane found, the time (s) at the end of each, and the index of the
    first plane under ``floor`` (None: never).
    """
    o3d.utility.random.seed(0)
    t0 = time.perf_counter()
    rest = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
    idx = np.arange(len(xyz))
    planes, times, small_at = [], [], None
    while len(planes) < max(k, MAX_PLANES if small_at is None else 0):
        if len(idx) < 3:
            break
        model, inl = rest.segment_plane(distance_threshold=THRESHOLD, ransac_n=3,
                                        num_iterations=1000)
        inl = np.asarray(inl, np.int64)
        nrm = np.asarray(model[:3], float)
        scale = float(np.linalg.norm(nrm))
        planes.append((nrm / scale, float(model[3]) / scale, np.sort(idx[inl])))
        if small_at is None and len(inl) < floor:
            small_at = len(planes) - 1
        keep = np.ones(len(idx), bool)
        keep[inl] = False
        rest = rest.select_by_index(inl.tolist(), invert=True)
        idx = idx[keep]
        times.append(time.perf_counter() - t0)
        if small_at is not None and len(planes) >= k:
            break
    return planes, times, small_at


def assign_full(xyz: np.ndarray, planes: list) -> list:
    """Every point to the first plane (detection order) within THRESHOLD of it."""
    free = np.ones(len(xyz), bool)
    out = []
    for nrm, off, _ in planes:
        inl = np.flatnonzero(free & (np.abs(xyz @ nrm + off) < THRESHOLD))
        free[inl] = False
        out.append((nrm, off, inl))
    return out


def run_open3d(o3d, cloud, k: int, floor_pts: int, floor_vox_ratio: float, voxel: bool
               ) -> dict[str, tuple[list, dict]]:
    """Both stops (``k=ff``, ``until``) of the loop on the full cloud or on its voxel grid."""
    xyz = cloud.xyz
    t0 = time.perf_counter()
    if voxel:
        down = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz)).voxel_down_sample(VOXEL)
        work = np.asarray(down.points)
        floor = max(3, int(round(floor_vox_ratio * len(work))))
    else:
        work, floor = xyz, floor_pts
    t_prep = time.perf_counter() - t0
    planes, times, small_at = o3d_loop(o3d, work, floor, k)
    n_until = min(small_at if small_at is not None else len(planes), MAX_PLANES)
    stops = {"k=ff": (k, min(k, len(planes)) - 1),
             "until": (n_until, n_until - 1 if small_at is None else small_at)}
    out = {}
    for stop, (n, last) in stops.items():
        chosen = planes[:n]
        o3d_secs = t_prep + (times[last] if last >= 0 else 0.0)
        info = {"open3d_seconds": o3d_secs, "voxels": len(work) if voxel else None,
                "floor": floor}
        if voxel:
            t = time.perf_counter()
            chosen = assign_full(xyz, chosen)
            info["assign_seconds"] = time.perf_counter() - t
            info["seconds"] = o3d_secs + info["assign_seconds"]
        else:
            info["seconds"] = o3d_secs
        out[stop] = (chosen, info)
    return out


# ------------------------------------------------------------------------------- scores

def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return round(math.degrees(math.acos(min(1.0, abs(float(a @ b))))), 2)


def largest_piece(xyz: np.ndarray, normal: np.ndarray, up: int, cell: float = CELL) -> int:
    """Points of the largest connected piece of a plane's inliers: occupied ``cell`` squares in
    the plane, 8-connected."""
    from scipy import ndimage

    if len(xyz) == 0:
        return 0
    upv = np.zeros(3)
    upv[up] = 1.0
    a = np.cross(upv, normal)
    if np.linalg.norm(a) < 1e-6:
        a = np.cross([1.0, 0.0, 0.0] if up != 0 else [0.0, 1.0, 0.0], normal)
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    uv = np.c_[xyz @ a, xyz @ b]
    q = np.floor((uv - uv.min(0)) / cell).astype(np.int64)
    shape = tuple(q.max(0) + 1)
    if shape[0] * shape[1] > 50_000_000:
        return len(xyz)
    occ = np.zeros(shape, bool)
    occ[q[:, 0], q[:, 1]] = True
    lab, _ = ndimage.label(occ, structure=np.ones((3, 3), bool))
    return int(np.bincount(lab[q[:, 0], q[:, 1]]).max())


def score(cloud, planes: list, name: str) -> dict:
    xyz = cloud.xyz
    n = len(xyz)
    sizes = [len(p[2]) for p in planes]
    order = np.argsort(sizes)[::-1]
    assigned = np.zeros(n, bool)
    sq, cnt = 0.0, 0
    for nrm, off, inl in planes:
        assigned[inl] = True
        d = xyz[inl] @ nrm + off
        sq += float(d @ d)
        cnt += len(inl)
    out = {"planes": len(planes), "largest_5": [int(sizes[i]) for i in order[:5]],
           "assigned_share": round(float(assigned.mean()), 4),
           "rms_m": round(math.sqrt(sq / cnt), 4) if cnt else None}
    if not planes:
        return out
    pieces = [largest_piece(xyz[p[2]], p[0], cloud.up) for p in planes]
    out["connected_share"] = round(sum(pieces) / max(cnt, 1), 4)
    big = planes[int(order[0])]
    d = xyz[big[2]] @ big[0] + big[1]
    out["largest_rms_m"] = round(float(np.sqrt(np.mean(d ** 2))), 4)
    out["largest_normal"] = [round(float(v), 4) for v in big[0]]
    up = cloud.up
    if name == "nuist" and cloud.labels is not None:
        wall = cloud.label_names.index("wall")
        lab = cloud.labels
        on = lab[big[2]]
        out["largest_wall_purity"] = round(float((on == wall).mean()), 4)
        out["wall_share_on_largest"] = round(float((on == wall).sum() / (lab == wall).sum()), 4)
        major = sum(int(np.bincount(lab[p[2]]).max()) for p in planes if len(p[2]))
        out["purity_all_planes"] = round(major / max(cnt, 1), 4)
    else:
        floor = BIG_VERTICAL * n / 170_610
        vert = [i for i in order if abs(planes[i][0][up]) < VERTICAL_NZ]
        out["vertical_planes_big"] = sum(1 for i in vert if sizes[i] > floor)
        out["vertical_planes_big_connected"] = sum(1 for i in vert if pieces[i] > floor)
        out["vertical_big_floor"] = int(round(floor))
        top = vert[:3]
        out["vertical_top3_sizes"] = [int(sizes[i]) for i in top]
        out["vertical_top3_angles_deg"] = {f"{a + 1}-{b + 1}": _angle(planes[top[a]][0],
                                                                      planes[top[b]][0])
                                           for a, b in itertools.combinations(range(len(top)), 2)}
        hor = [i for i in order if abs(planes[i][0][up]) > HORIZONTAL_NZ]
        out["largest_horizontal"] = int(sizes[hor[0]]) if hor else 0
    return out


# ------------------------------------------------------------------------------- main

def bench_cloud(o3d, name: str, cloud, runs: int, long_s: float) -> dict:
    xyz = cloud.xyz
    min_vox, n_vox = ff_min_points(xyz)
    per_vox = len(xyz) / n_vox                      # mean points per facadeforge voxel
    floor_pts = int(round(min_vox * per_vox))
    floor_vox_ratio = min_vox / n_vox               # the same share, on Open3D's grid
    meth = ["facadeforge", "open3d", "open3d-voxel"]
    best: dict[str, dict] = {}
    first: dict[str, dict] = {}
    counts: dict[str, list] = {}
    slow: dict[str, bool] = {}
    k = None
    for r in range(runs):
        for m in meth:
            if r > 0 and slow[m]:
                continue
            t = time.perf_counter()
            if m == "facadeforge":
                planes, info = run_facadeforge(cloud)
                res = {"": (planes, info)}
                k = len(planes)
            else:
                res = run_open3d(o3d, cloud, k, floor_pts, floor_vox_ratio, m == "open3d-voxel")
            wall = time.perf_counter() - t
            for stop, (planes, info) in res.items():
                key = m if not stop else f"{m} {stop}"
                counts.setdefault(key, []).append(
                    (len(planes), sorted((len(p[2]) for p in planes), reverse=True)[:5]))
                if key not in best or info["seconds"] < best[key]["seconds"]:
                    best[key] = info
                if r == 0:
                    first[key] = {"planes": planes}
            if r == 0:
                slow[m] = wall > long_s
            print(f"  {name} run {r + 1} {m}: {wall:.1f} s", flush=True)
    out = {"points": len(xyz), "facadeforge_voxels": n_vox,
           "facadeforge_min_points_voxels": min_vox, "open3d_until_floor_points": floor_pts,
           "methods": {}}
    for key, info in best.items():
        m = key.split()[0]
        sc = score(cloud, first[key]["planes"], name)
        out["methods"][key] = {
            "seconds": round(info["seconds"], 3), "runs": len(counts[key]),
            "planes_per_run": [c[0] for c in counts[key]],
            "largest_5_per_run": [c[1] for c in counts[key]], **sc,
            **{k2: (round(v, 3) if isinstance(v, float) else v) for k2, v in info.items()
               if k2 != "seconds"}}
        if m == "open3d-voxel":
            out["methods"][key]["voxel_m"] = VOXEL
    return out


def table(result: dict) -> str:
    lines = []
    for name, c in result["clouds"].items():
        lines.append(f"\n{name} ({c['points']:,} points)")
        extra = ("wall purity / wall share / all-plane purity" if name == "nuist"
                 else f"vertical >{c['methods']['facadeforge']['vertical_big_floor']} "
                      "(connected) / angles top-3 / largest horizontal")
        lines.append(f"{'method':<22}{'s':>8}{'planes':>7}  {'largest 5':<36}{'share':>6}"
                     f"{'rms cm':>7}{'conn':>6}  {extra}")
        for key, s in c["methods"].items():
            if name == "nuist":
                q = (f"{s.get('largest_wall_purity', 0):.3f} / "
                     f"{s.get('wall_share_on_largest', 0):.3f} / {s.get('purity_all_planes', 0):.3f}")
            else:
                ang = ", ".join(f"{v:g}" for v in s.get("vertical_top3_angles_deg", {}).values())
                q = (f"{s.get('vertical_planes_big', 0)} ({s.get('vertical_planes_big_connected', 0)})"
                     f" / {ang} / {s.get('largest_horizontal', 0)}")
            rms = "–" if s["rms_m"] is None else f"{100 * s['rms_m']:.2f}"
            lines.append(f"{key:<22}{s['seconds']:>8.2f}{s['planes']:>7}  "
                         f"{str(s['largest_5']):<36}{s['assigned_share']:>6.3f}{rms:>7}"
                         f"{s.get('connected_share', 0):>6.2f}  {q}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--long", type=float, default=150.0,
                    help="a method whose first run takes longer (s) is run once")
    ap.add_argument("--clouds", default="nuist,lille,million")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "planes.json"))
    args = ap.parse_args(argv)
    try:
        import open3d as o3d
    except ImportError as e:
        sys.exit(f"open3d is not importable ({e}); build its environment with `make bench-env` "
                 "and run .venv-bench/bin/python benchmarks/planes.py (Open3D's wheel also needs "
                 "the system's libusb-1.0: apt-get install libusb-1.0-0)")
    from facadeforge.evaluation.bench import provenance

    names = [s.strip() for s in args.clouds.split(",") if s.strip()]
    result = {**provenance(), "open3d": o3d.__version__, "numpy": np.__version__,
              "threshold_m": THRESHOLD, "runs": args.runs, "long_s": args.long, "clouds": {}}
    for name, cloud in load_clouds(names).items():
        print(f"{name}: {len(cloud):,} points", flush=True)
        load = os.getloadavg()[0]
        result["clouds"][name] = bench_cloud(o3d, name, cloud, args.runs, args.long)
        # other work on the machine slows every method: the 1-minute load before and after
        result["clouds"][name]["load_average_1min"] = [round(load, 2),
                                                       round(os.getloadavg()[0], 2)]
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.part")
    tmp.write_text(json.dumps(result, indent=1) + "\n")
    os.replace(tmp, out)
    print(table(result))
    print("→", out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
