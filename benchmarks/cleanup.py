"""``cleanupGeometry`` benchmark: merging big coplanar regions.

Times the kernel of ``cleanupGeometry(all, 0.1)`` (:func:`facadeforge.geometry.cleanup.cleanup`)
on three inputs, best of ``--runs``:

* ``grid``: a flat 60 × 40 grid of 1 m quads (2 400 faces, vertices not shared, uv = position),
  which merges into one quad;
* ``grid_triangulated``: the same grid with every tile cut into two triangles (4 800 faces);
* ``grid_large``: a 120 × 80 grid (9 600 faces), to see how the time grows with the region;
* ``building``: a 60 × 40 m lot extruded by 30 m, its sides split into floors and tiles and
  recomposed with ``inline(recompose)`` (about 1 000 faces), which merges into the six sides of
  the box; timed on its inlined mesh and as the whole derivation of the rule with and without
  ``cleanupGeometry(all, 0.1)``.

``kernel_seconds`` is the whole clean-up (weld, degenerate and duplicate faces, coplanar merge,
collinear corners); ``merge_seconds`` the part spent in ``merge_coplanar``, in the same runs.

The result is saved under the label ``--label`` (``before`` / ``after`` a change) in
``benchmarks/results/cleanup.json``; the other labels already in the file are kept, so one file
holds both sides of a comparison, each with its machine, date and commit.

Run: ``.venv/bin/python benchmarks/cleanup.py --label after``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from facadeforge import derive, load_rules
from facadeforge.evaluation.bench import provenance, save_result
from facadeforge.geometry import cleanup as kernel
from facadeforge.geometry.mesh import Mesh

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "benchmarks" / "results" / "cleanup.json"

BUILDING = """
Lot --> extrude(30) Mass
Mass --> inline(recompose) comp(f) { side : Facade | all : X. } {cleanup}Done.
Facade --> split(y) { ~3 : Floor }*
Floor --> split(x) { ~2 : T }*
T --> X.
"""
BUILDING_LOT = "60x40"


def grid(nx: int = 60, nz: int = 40, triangulated: bool = False) -> Mesh:
    """A flat ``nx`` × ``nz`` grid of unit quads in the xz plane, uv = (x, z), vertices not
    shared; with ``triangulated`` every quad is two triangles."""
    polys = []
    for i in range(nx):
        for j in range(nz):
            q = np.array([[i, 0, j + 1], [i + 1, 0, j + 1], [i + 1, 0, j], [i, 0, j]], float)
            polys.extend([q[[0, 1, 2]], q[[0, 2, 3]]] if triangulated else [q])
    return Mesh.from_polygons(polys, [p[:, [0, 2]] for p in polys])


def building_rule(with_cleanup: bool):
    cleanup = "cleanupGeometry(all, 0.1) " if with_cleanup else ""
    return load_rules(BUILDING.replace("{cleanup}", cleanup))


class MergeTimer:
    """Adds up the time spent in ``kernel.merge_coplanar`` while it is installed."""

    def __init__(self):
        self.seconds = 0.0
        self.merge = kernel.merge_coplanar

    def __call__(self, *args):
        t0 = time.perf_counter()
        try:
            return self.merge(*args)
        finally:
            self.seconds += time.perf_counter() - t0


def clean(mesh: Mesh) -> tuple[Mesh, float]:
    """``cleanupGeometry(all, 0.1)`` of ``mesh`` and the seconds its coplanar merge took."""
    timer = MergeTimer()
    kernel.merge_coplanar = timer
    try:
        out, _ = kernel.cleanup(mesh, "all", 0.1)
    finally:
        kernel.merge_coplanar = timer.merge
    return out, timer.seconds


def best_of(runs: int, fn) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", default="after", help="name of this measurement (before / after)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("-o", "--output", default=str(OUTPUT))
    args = ap.parse_args()

    plain = building_rule(False)
    inlined = derive(plain, None, lot_size=BUILDING_LOT)[0].parts[0].mesh
    meshes = {"grid": grid(), "grid_triangulated": grid(triangulated=True),
              "grid_large": grid(120, 80), "building": inlined}
    cases = {}
    for name, mesh in meshes.items():
        runs = [best_of(1, lambda m=mesh: clean(m)) for _ in range(args.runs)]
        seconds = min(t for t, _ in runs)
        merge = min(m for _, (_, m) in runs)
        out = runs[0][1][0]
        cases[name] = {"faces_in": mesh.n_faces, "faces_out": out.n_faces,
                       "corners_out": int(out.face_sizes.sum()),
                       "area_out": round(out.area(), 6), "kernel_seconds": round(seconds, 4),
                       "merge_seconds": round(merge, 4)}
    cleaned = building_rule(True)
    with_s, model = best_of(args.runs, lambda: derive(cleaned, None, lot_size=BUILDING_LOT)[0])
    without_s, _ = best_of(args.runs, lambda: derive(plain, None, lot_size=BUILDING_LOT)[0])
    cases["building"].update(derive_seconds_with_cleanup=round(with_s, 4),
                             derive_seconds_without_cleanup=round(without_s, 4),
                             derived_faces_out=model.parts[0].mesh.n_faces)

    path = Path(args.output)
    result = json.loads(path.read_text()) if path.exists() else {}
    result.update(benchmark="cleanup", operation="cleanupGeometry(all, 0.1)", runs=args.runs,
                  timing="seconds, best of runs: kernel geometry.cleanup.cleanup unless named derive")
    result[args.label] = {"cases": cases, **provenance()}
    if "before" in result and "after" in result:
        b, a = result["before"]["cases"], result["after"]["cases"]
        result["speedup"] = {
            k: {key: round(b[k][key] / max(a[k][key], 1e-9), 1)
                for key in ("kernel_seconds", "merge_seconds") if key in b[k] and key in a[k]}
            for k in a if k in b}
    save_result(result, path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
