"""CityFit's point store (``points/store.py``) against ``scipy.spatial.cKDTree``, same run.

Clouds:

- ``lille``: ``../shared/data/pointclouds/lille_street_small.ply`` (170,610 points of a Lille
  street, Paris-Lille-3D; read with :func:`facadeforge.points.io.read_cloud`, or a small numpy
  reader of the binary PLY when that module is missing);
- ``synthetic``: 1,000,000 points of a 400 m street canyon at UTM-like coordinates (500 000,
  5 400 000, 300): two facades 20 m apart (20 m high, 2 cm noise, a window recess every 3.5 m),
  the road between them, 10 % clutter (cars, poles: boxes up to 3 m high); seed 0.

Both structures index the same positions: the kd-trees are built on the store's fixed-point
positions in metres (``store.xyz()``), so both must return the same sets (checked per query and
reported as ``agree``).  The kd-tree is ``cKDTree(xyz)`` with scipy's defaults (leafsize 16,
balanced median splits); the column query uses a second, 2D kd-tree on the horizontal
coordinates (what a kd-tree user would build for it; its build time is listed apart).

Queries, ``--queries`` (1000) of each, the same for both structures: centres are random cloud
points plus N(0, 0.5 m) jitter (seed 1), put on the fixed-point grid (the store rounds query
positions to it; the kd-tree gets the same rounded centres, so both answer the same question).

- ``box``: cube of side 2 m around the centre.  Store: :meth:`PointStore.box`.  kd-tree: a
  Chebyshev ball (``query_ball_point(c, 1.0, p=inf)``) is exactly the cube; indices sorted.
- ``column``: 2 m × 2 m horizontal square, any height.  Store: :meth:`PointStore.column`.
  kd-tree: Chebyshev ball of radius 1 m on the 2D tree; indices sorted.
- ``radius 0.5 m`` / ``radius 2 m``: ball.  Store: :meth:`PointStore.radius`.  kd-tree:
  ``query_ball_point(c, r, return_sorted=True)`` (a list, not converted to an array).
- ``radius_many``: the 1000 balls in one call: :meth:`PointStore.radius_many` against
  ``query_ball_point(centres, r, return_sorted=True)``; reported per ball.
- ``nearest 8``: :meth:`PointStore.nearest` against ``query(c, k=8)``.
- ``ray``: picking with spheres of 10 cm: the ray starts 15 m from a random cloud point in a
  random direction and aims at it (0.05 rad of noise).  Store: :meth:`PointStore.ray` (the
  Amanatides & Woo walk of the columns).  kd-tree: what a kd-tree user does without a ray query —
  sample the ray every 0.1 m from where it enters the cloud's bounding box, query balls of radius
  √(0.1² + 0.05²) m (they cover the 10 cm tube between samples) 64 samples at a time in ray
  order, test the candidates exactly, and stop when the best hit lies before the chunk's end
  minus the sphere radius.
- ``merge``: near duplicates closer than 2⁻¹³ m: :meth:`PointStore.merge` against
  ``cKDTree.query_pairs(2⁻¹³)`` + connected components (one call each, on the whole cloud).

Times: per query, the mean over the queries, best of ``--repeat`` (3) passes, after one warm-up
pass (numba compiles the store's kernels on first use: ``compile_s``; the compiled kernels are
cached on disk after that).  ``store`` is the default compiled path, ``store_numpy`` the
vectorised numpy reference of the same queries.  One process, one thread (numpy / scipy as they
come; neither parallelises these calls), on a shared 2-core machine.

Run::

    nice -n 19 .venv/bin/python benchmarks/points_store.py [--queries 1000] [--repeat 3]

Writes ``benchmarks/results/points_store.json`` (machine, date, commit, the last commit of
``store.py``, the load average after each cloud, every number) and prints a table.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from facadeforge.evaluation.bench import provenance, save_result
from facadeforge.points.cloud import PointCloud
from facadeforge.points.store import MERGE_RADIUS, PointStore

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "benchmarks" / "results" / "points_store.json"
LILLE = ROOT.parent / "shared" / "data" / "pointclouds" / "lille_street_small.ply"
SPHERE = 0.1


# ------------------------------------------------------------------------------ clouds
def read_lille(path: Path) -> tuple[PointCloud, str]:
    try:
        from facadeforge.points.io import read_cloud
    except ImportError:
        read_cloud = None
    if read_cloud is not None:
        return read_cloud(path), "facadeforge.points.io.read_cloud"
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    n = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    props = [line.split()[2] for line in header if line.startswith("property float")]
    xyz = np.frombuffer(data, "<f4", count=n * len(props), offset=end).reshape(n, len(props))
    return PointCloud(xyz[:, :3].astype(np.float64), source=str(path)), "numpy PLY reader"


def synthetic_street(n: int = 1_000_000, seed: int = 0) -> PointCloud:
    rng = np.random.default_rng(seed)
    kind = rng.choice(4, n, p=[0.35, 0.35, 0.2, 0.1])              # facade L, facade R, road, clutter
    x = rng.uniform(0, 400, n)
    z = rng.uniform(0, 20, n)
    recess = ((x % 3.5) > 2.3) & ((z % 3.2) > 1.0)                  # windows 0.25 m deep
    y = np.where(kind == 0, -10 - 0.25 * recess, 10 + 0.25 * recess) + rng.normal(0, 0.02, n)
    road = kind == 2
    y[road] = rng.uniform(-10, 10, road.sum())
    z[road] = rng.normal(0, 0.01, road.sum())
    clutter = kind == 3
    k = int(clutter.sum())
    centre = rng.integers(0, 120, k)                               # 120 objects along the street
    cx = (centre * 3.3) % 400
    cy = np.where(centre % 2, 7.0, -7.0)
    x[clutter] = cx + rng.uniform(-2, 2, k)
    y[clutter] = cy + rng.uniform(-1, 1, k)
    z[clutter] = rng.uniform(0, 1.5 + (centre % 3), k)
    xyz = np.c_[x, y, z] + [500000.0, 5400000.0, 300.0]
    return PointCloud(xyz, source="synthetic street, 1e6 points")


# ------------------------------------------------------------------------------ kd-tree ray
def kd_ray(kd: cKDTree, xyz: np.ndarray, lo: np.ndarray, hi: np.ndarray, o: np.ndarray,
           d: np.ndarray, rho: float, chunk: int = 64):
    """First sphere (radius rho) entered at t > 0 along o + t d, by ball queries along the ray."""
    d = d / np.linalg.norm(d)
    t0, t1 = 0.0, math.inf
    for a in range(3):
        if d[a] == 0:
            if not lo[a] - rho <= o[a] <= hi[a] + rho:
                return None
            continue
        u, v = (lo[a] - rho - o[a]) / d[a], (hi[a] + rho - o[a]) / d[a]
        t0, t1 = max(t0, min(u, v)), min(t1, max(u, v))
    if t0 > t1:
        return None
    step = rho
    ball = math.hypot(rho, step / 2)
    ts = np.arange(t0, t1 + step, step)
    best_t, best_i = math.inf, -1
    for k in range(0, len(ts), chunk):
        tc = ts[k:k + chunk]
        cand = kd.query_ball_point(o + tc[:, None] * d, ball)
        idx = np.unique(np.concatenate([np.asarray(c, np.int64) for c in cand]))
        if len(idx):
            w = xyz[idx] - o
            tproj = w @ d
            h2 = ((w - tproj[:, None] * d) ** 2).sum(1)
            ok = h2 <= rho * rho
            t = tproj - np.sqrt(np.where(ok, rho * rho - h2, 0.0))
            ok &= t > 0
            if ok.any():
                j = np.lexsort((idx[ok], t[ok]))[0]
                if t[ok][j] < best_t:
                    best_t, best_i = float(t[ok][j]), int(idx[ok][j])
        if best_i >= 0 and best_t < tc[-1] - rho:
            break
    return None if best_i < 0 else (best_i, best_t)


# ------------------------------------------------------------------------------ timing
def best_pass(fn, items, repeat: int) -> tuple[float, list]:
    """Mean seconds per item of the best of ``repeat`` passes (after a warm-up), and results."""
    out = [fn(x) for x in items]                                   # warm-up, results kept
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        for x in items:
            fn(x)
        best = min(best, (time.perf_counter() - t) / len(items))
    return best, out


def best_once(fn, repeat: int) -> tuple[float, object]:
    res = fn()
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best, res


def same(a, b) -> bool:
    return np.array_equal(np.asarray(a, np.int64), np.asarray(b, np.int64))


def run_cloud(name: str, cloud: PointCloud, n_queries: int, repeat: int, notes: dict) -> dict:
    print(f"== {name}: {len(cloud):,} points", flush=True)
    t = time.perf_counter()
    store = PointStore.from_cloud(cloud)
    first_build = time.perf_counter() - t
    build, _ = best_once(lambda: PointStore.from_cloud(cloud), repeat)
    xyz = store.xyz()
    kd_build, kd = best_once(lambda: cKDTree(xyz), repeat)
    ax = list(store.axes)
    kd2_build, kd2 = best_once(lambda: cKDTree(xyz[:, ax]), repeat)
    t = time.perf_counter()
    store.radius(xyz[0], 1.0)
    store.ray(xyz[0] + 5, -np.ones(3))
    store.nearest(xyz[0], 3)
    store.radius_many(xyz[:2], 1.0)
    store.box(xyz[0] - 1, xyz[0] + 1)
    compile_s = time.perf_counter() - t

    rng = np.random.default_rng(1)
    centres = xyz[rng.integers(0, len(xyz), n_queries)] + rng.normal(0, 0.5, (n_queries, 3))
    centres = store.from_fixed(store.to_fixed(centres))           # on the grid, as the store puts them
    u = rng.normal(size=(n_queries, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    targets = xyz[rng.integers(0, len(xyz), n_queries)]
    origins = targets + 15.0 * u
    dirs = (targets - origins) / 15.0 + rng.normal(0, 0.05, (n_queries, 3))
    rays = list(zip(origins, dirs))
    lo, hi = xyz.min(0), xyz.max(0)

    def sorted_list(x):
        return np.sort(np.asarray(x, np.int64))

    single = {
        "box": (lambda c: store.box(c - 1.0, c + 1.0),
                lambda c: sorted_list(kd.query_ball_point(c, 1.0, p=np.inf)), centres),
        "column": (lambda c: store.column(c[ax], 1.0),
                   lambda c: sorted_list(kd2.query_ball_point(c[ax], 1.0, p=np.inf)), centres),
        "radius 0.5 m": (lambda c: store.radius(c, 0.5),
                         lambda c: kd.query_ball_point(c, 0.5, return_sorted=True), centres),
        "radius 2 m": (lambda c: store.radius(c, 2.0),
                       lambda c: kd.query_ball_point(c, 2.0, return_sorted=True), centres),
        "nearest 8": (lambda c: store.nearest(c, 8)[0], lambda c: kd.query(c, k=8)[1], centres),
        "ray": (lambda r: store.ray(r[0], r[1], SPHERE),
                lambda r: kd_ray(kd, xyz, lo, hi, r[0], r[1], SPHERE), rays),
    }
    rows = {}
    for qname, (ours, theirs, items) in single.items():
        t_store, res_store = best_pass(ours, items, repeat)
        store.engine = "numpy"
        t_numpy, res_numpy = best_pass(ours, items, repeat)
        store.engine = "numba"
        t_kd, res_kd = best_pass(theirs, items, repeat)
        if qname == "ray":
            agree = sum((a is None and b is None) or (a is not None and b is not None
                                                        and a.index == b[0])
                        for a, b in zip(res_store, res_kd))
            size = float(np.mean([a is not None for a in res_store]))
            size_key = "hit_fraction"
        elif qname == "nearest 8":
            agree = sum(same(a, b) or np.allclose(store.nearest(c, 8)[1],
                                                   kd.query(c, k=8)[0], atol=1e-12)
                        for a, b, c in zip(res_store, res_kd, items))
            size, size_key = 8.0, "results_mean"
        else:
            agree = sum(same(a, b) for a, b in zip(res_store, res_kd))
            size, size_key = float(np.mean([len(a) for a in res_store])), "results_mean"
        numpy_agree = sum((a is None and b is None) or (a is not None and b is not None and (
            (a.index == b.index) if qname == "ray" else same(a, b)))
            for a, b in zip(res_store, res_numpy))
        rows[qname] = {"store_us": round(t_store * 1e6, 2), "store_numpy_us": round(t_numpy * 1e6, 2),
                       "kdtree_us": round(t_kd * 1e6, 2), size_key: round(size, 3),
                       "agree_with_kdtree": f"{agree}/{len(items)}",
                       "numpy_engine_agrees": f"{numpy_agree}/{len(items)}",
                       "faster": "store" if t_store < t_kd else "kdtree"}
        print(f"  {qname:14s} store {t_store * 1e6:9.1f} µs  numpy {t_numpy * 1e6:9.1f} µs  "
              f"kd {t_kd * 1e6:9.1f} µs  agree {agree}/{len(items)}", flush=True)

    for r in (0.5, 2.0):
        t_store, res_store = best_once(lambda r=r: store.radius_many(centres, r), repeat)
        store.engine = "numpy"
        t_numpy, res_numpy = best_once(lambda r=r: store.radius_many(centres, r), repeat)
        store.engine = "numba"
        t_kd, res_kd = best_once(lambda r=r: kd.query_ball_point(centres, r, return_sorted=True),
                                 repeat)
        agree = sum(same(a, b) for a, b in zip(res_store, res_kd))
        qname = f"radius_many {r:g} m"
        rows[qname] = {"store_us": round(t_store / n_queries * 1e6, 2),
                       "store_numpy_us": round(t_numpy / n_queries * 1e6, 2),
                       "kdtree_us": round(t_kd / n_queries * 1e6, 2),
                       "results_mean": round(float(np.mean([len(a) for a in res_store])), 3),
                       "agree_with_kdtree": f"{agree}/{n_queries}",
                       "numpy_engine_agrees": f"{sum(same(a, b) for a, b in zip(res_store, res_numpy))}/{n_queries}",
                       "faster": "store" if t_store < t_kd else "kdtree"}
        print(f"  {qname:14s} store {rows[qname]['store_us']:9.1f} µs  numpy "
              f"{rows[qname]['store_numpy_us']:9.1f} µs  kd {rows[qname]['kdtree_us']:9.1f} µs  "
              f"agree {agree}/{n_queries}", flush=True)

    def kd_merge():
        pairs = kd.query_pairs(MERGE_RADIUS * (1 - 1e-12), output_type="ndarray")
        g = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(xyz), len(xyz)))
        return connected_components(g, directed=False)[0]

    t_merge, groups = best_once(store.merge, 1)
    t_kdm, n_kd = best_once(kd_merge, 1)
    rows["merge 2^-13 m"] = {"store_s": round(t_merge, 3), "kdtree_s": round(t_kdm, 3),
                             "groups": len(groups.keep), "kdtree_groups": int(n_kd),
                             "faster": "store" if t_merge < t_kdm else "kdtree"}
    print(f"  merge          store {t_merge:.3f} s  kd {t_kdm:.3f} s  groups {len(groups.keep)} "
          f"/ {n_kd}", flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "store.npz"
        t_save, _ = best_once(lambda: store.save(path), 1)
        size = path.stat().st_size
        t_load, _ = best_once(lambda: PointStore.load(path), 1)
    return {
        "load_average_1m": round(os.getloadavg()[0], 2),
        "points": len(store), "cells": store.cells, "quadtree_depth": store.depth,
        "quadtree_nodes": store.nodes, "origin": store.origin.tolist(),
        "points_per_cell_max": int(np.diff(store.offsets).max()),
        "store_memory_mib": round(store.memory_bytes / 2**20, 2),
        "kdtree_data_mib": round((xyz.nbytes + len(xyz) * 8) / 2**20, 2),
        "build_s": {"store": round(build, 3), "store_first": round(first_build, 3),
                    "kdtree_3d": round(kd_build, 3), "kdtree_2d": round(kd2_build, 3)},
        "compile_s": round(compile_s, 2),
        "save_s": round(t_save, 3), "load_s": round(t_load, 3), "file_mib": round(size / 2**20, 2),
        "queries": rows,
    }


def table(result: dict) -> str:
    lines = []
    for name, c in result["clouds"].items():
        b = c["build_s"]
        lines += [f"\n{name}: {c['points']:,} points, {c['cells']} cells, depth "
                  f"{c['quadtree_depth']}; build store {b['store']} s, kd-tree {b['kdtree_3d']} s "
                  f"(2D {b['kdtree_2d']} s); store {c['store_memory_mib']} MiB",
                  "| query | store µs | store (numpy) µs | kd-tree µs | results | agree | faster |",
                  "|---|---|---|---|---|---|---|"]
        for q, r in c["queries"].items():
            if "store_us" not in r:
                lines.append(f"| {q} | {r['store_s']} s | – | {r['kdtree_s']} s | "
                             f"{r['groups']} groups | {r['kdtree_groups']} | {r['faster']} |")
                continue
            size = r.get("results_mean", r.get("hit_fraction"))
            lines.append(f"| {q} | {r['store_us']} | {r['store_numpy_us']} | {r['kdtree_us']} | "
                         f"{size} | {r['agree_with_kdtree']} | {r['faster']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--queries", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--lille", default=str(LILLE))
    ap.add_argument("--points", type=int, default=1_000_000, help="synthetic cloud size")
    ap.add_argument("-o", "--output", default=str(OUTPUT))
    args = ap.parse_args(argv)
    clouds, notes = {}, {}
    lille = Path(args.lille)
    if lille.is_file():
        cloud, how = read_lille(lille)
        notes["lille_reader"] = how
        clouds["lille"] = run_cloud("lille", cloud, args.queries, args.repeat, notes)
    else:
        notes["lille"] = f"{lille} not found: skipped"
    clouds["synthetic"] = run_cloud("synthetic", synthetic_street(args.points), args.queries,
                                    args.repeat, notes)
    import scipy

    store_commit = subprocess.run(
        ["git", "log", "-1", "--format=%h", "--", "src/facadeforge/points/store.py"], cwd=ROOT,
        capture_output=True, text=True).stdout.strip() or None
    result = {"benchmark": "points_store", **provenance(), "store_commit": store_commit,
              "numpy": np.__version__,
              "scipy": scipy.__version__, "queries": args.queries, "repeat": args.repeat,
              "sphere_radius_m": SPHERE, "notes": notes, "clouds": clouds}
    save_result(result, args.output)
    print(table(result))
    print(f"→ {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
