"""Engine throughput benchmark (issue 2, item 9).

Derives ``benchmarks/grammars/detailed.cga`` (a facade building with inserted window assets, about
35 000 faces) on 40 footprints through the whole CLI process, as a user would run it, and records
buildings/s, faces/s and peak memory in ``benchmarks/results/engine.json``.

Run: ``make bench`` or ``.venv/bin/python benchmarks/engine.py [--runs 3]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
GRAMMAR = ROOT / "benchmarks" / "grammars" / "detailed.cga"
ASSETS = ROOT / "examples" / "assets"


def footprints(n: int = 40) -> dict:
    """``n`` rectangular and L-shaped lots on a grid, sizes varied deterministically."""
    feats = []
    for i in range(n):
        gx, gy = i % 8, i // 8
        w = 26 + (i * 7) % 9
        d = 14 + (i * 5) % 5
        x0, y0 = gx * 50.0, gy * 40.0
        if i % 4 == 3:  # L-shape
            ring = [[x0, y0], [x0 + w, y0], [x0 + w, y0 + d / 2], [x0 + w / 2, y0 + d / 2],
                    [x0 + w / 2, y0 + d], [x0, y0 + d], [x0, y0]]
        else:
            ring = [[x0, y0], [x0 + w, y0], [x0 + w, y0 + d], [x0, y0 + d], [x0, y0]]
        feats.append({"type": "Feature", "properties": {"name": f"b{i:02d}"},
                      "geometry": {"type": "Polygon", "coordinates": [ring]}})
    return {"type": "FeatureCollection", "features": feats}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--footprints", type=int, default=40)
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "engine.json"))
    args = ap.parse_args()
    exe = Path(sys.executable).with_name("facadeforge")
    with tempfile.TemporaryDirectory() as tmp:
        lots = Path(tmp) / "lots.geojson"
        lots.write_text(json.dumps(footprints(args.footprints)))
        out = Path(tmp) / "city.glb"
        cmd = [str(exe), "derive", str(GRAMMAR), "--footprint", str(lots), "--assets", str(ASSETS),
               "-o", str(out), "--stats"]
        walls, stats = [], None
        for _ in range(args.runs):
            t0 = time.perf_counter()
            res = subprocess.run(cmd, capture_output=True, text=True)
            walls.append(time.perf_counter() - t0)
            if res.returncode != 0:
                print(res.stderr, file=sys.stderr)
                return 1
            stats = json.loads(res.stdout)
        peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    best = min(walls)
    n = args.footprints
    result = {
        "benchmark": "engine", "grammar": str(GRAMMAR.relative_to(ROOT)), "footprints": n,
        "runs": args.runs, "wall_seconds": [round(w, 3) for w in walls],
        "best_wall_seconds": round(best, 3),
        "buildings_per_second": round(n / best, 3),
        "faces": stats["faces"], "faces_per_building": round(stats["faces"] / n),
        "triangles": stats["triangles"], "faces_per_second": round(stats["faces"] / best),
        "peak_memory_mib_per_process": round(peak_kib / 1024, 1),
        "warnings": len(stats["warnings"]),
        **provenance(),
    }
    save_result(result, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
