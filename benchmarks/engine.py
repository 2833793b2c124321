"""Engine throughput benchmark (issue 2, item 9).

Derives ``benchmarks/grammars/detailed.cga`` (a facade building with inserted window assets, about
33 000 faces) on 40 footprints through the whole CLI process, as a user would run it, writing
each export format in turn (GLB, the headline number; OBJ; CityJSON), and records buildings/s,
faces/s and peak memory in ``benchmarks/results/engine.json``.

The CLI runs as an installed program does: Python may cache compiled modules
(``PYTHONDONTWRITEBYTECODE`` is dropped), after one untimed warm-up run.  ``--src DIR`` times
another checkout's ``src`` with this environment, for side-by-side comparisons (runs of the two
alternate, as this shared machine drifts between hours).

Run: ``make bench`` or ``.venv/bin/python benchmarks/engine.py [--runs 3] [--src OTHER/src]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
GRAMMAR = ROOT / "benchmarks" / "grammars" / "detailed.cga"
ASSETS = ROOT / "examples" / "assets"


def lot_feature(name: str, x0: float, y0: float, w: float, d: float, l_shape: bool) -> dict:
    """A GeoJSON lot ``w`` × ``d`` at ``x0, y0``: a rectangle, or an L (the upper right
    quarter cut away)."""
    if l_shape:
        ring = [[x0, y0], [x0 + w, y0], [x0 + w, y0 + d / 2], [x0 + w / 2, y0 + d / 2],
                [x0 + w / 2, y0 + d], [x0, y0 + d], [x0, y0]]
    else:
        ring = [[x0, y0], [x0 + w, y0], [x0 + w, y0 + d], [x0, y0 + d], [x0, y0]]
    return {"type": "Feature", "properties": {"name": name},
            "geometry": {"type": "Polygon", "coordinates": [ring]}}


def footprints(n: int = 40) -> dict:
    """``n`` rectangular and L-shaped lots on a grid, sizes varied deterministically."""
    feats = [lot_feature(f"b{i:02d}", (i % 8) * 50.0, (i // 8) * 40.0, 26 + (i * 7) % 9,
                         14 + (i * 5) % 5, i % 4 == 3) for i in range(n)]
    return {"type": "FeatureCollection", "features": feats}


FORMATS = ("glb", "obj", "city.json")


def _shown(path: Path) -> str:
    path = path.resolve()
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def _label(src: Path) -> str:
    """A checkout's name in the results: its commit, else its path."""
    res = subprocess.run(["git", "-C", str(src), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True)
    return f"commit {res.stdout.strip()}" if res.returncode == 0 else str(src)


def _run(cmd: list[str], env: dict) -> tuple[float, dict, int]:
    """Wall seconds, ``--stats`` and peak memory (KiB) of one CLI run."""
    t0 = time.perf_counter()
    res = subprocess.run(["/usr/bin/time", "-f", "%M", *cmd] if Path("/usr/bin/time").exists()
                         else cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise SystemExit(f"benchmark run failed: {res.stderr.strip().splitlines()[-1:]}")
    tail = res.stderr.strip().splitlines()
    peak = int(tail[-1]) if tail and tail[-1].isdigit() else 0
    return wall, json.loads(res.stdout), peak


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--footprints", type=int, default=40)
    ap.add_argument("--grammar", type=Path, default=GRAMMAR,
                    help="rules to derive (default benchmarks/grammars/detailed.cga; "
                         "detailed_varied.cga chooses each window at random)")
    ap.add_argument("--formats", default=",".join(FORMATS),
                    help=f"export formats to time, comma-separated (default {','.join(FORMATS)})")
    ap.add_argument("--src", type=Path, action="append", default=[],
                    help="also time this checkout's src folder (repeatable; alternating runs)")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "engine.json"))
    args = ap.parse_args()
    exe = Path(sys.executable).with_name("facadeforge")
    formats = [f.strip() for f in args.formats.split(",") if f.strip()]
    base_env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    sides = {"this checkout": dict(base_env)}
    for src in args.src:
        sides[_label(src)] = {**base_env, "PYTHONPATH": str(src.resolve())}
    walls = {(side, f): [] for side in sides for f in formats}
    stats, peaks = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        lots = Path(tmp) / "lots.geojson"
        lots.write_text(json.dumps(footprints(args.footprints)))

        def cmd(fmt: str) -> list[str]:
            return [str(exe), "derive", str(args.grammar), "--footprint", str(lots), "--assets",
                    str(ASSETS), "-o", str(Path(tmp) / f"city.{fmt}"), "--stats"]
        for env in sides.values():  # warm-up: compiled modules, the parser cache
            _run(cmd(formats[0]), env)
        for _ in range(args.runs):
            for fmt in formats:
                for side, env in sides.items():
                    wall, st, peak = _run(cmd(fmt), env)
                    walls[(side, fmt)].append(wall)
                    stats[(side, fmt)] = st
                    peaks[(side, fmt)] = max(peaks.get((side, fmt), 0), peak)
    n = args.footprints

    def summary(side: str, fmt: str) -> dict:
        best = min(walls[(side, fmt)])
        st = stats[(side, fmt)]
        return {"wall_seconds": [round(w, 3) for w in walls[(side, fmt)]],
                "best_wall_seconds": round(best, 3), "buildings_per_second": round(n / best, 3),
                "faces_per_second": round(st["faces"] / best),
                "peak_memory_mib_per_process": round(peaks[(side, fmt)] / 1024, 1)}
    main_side = "this checkout"
    head = summary(main_side, formats[0])
    st = stats[(main_side, formats[0])]
    result = {
        "benchmark": "engine", "grammar": _shown(args.grammar), "footprints": n,
        "runs": args.runs, "format": formats[0], **head,
        "faces": st["faces"], "faces_per_building": round(st["faces"] / n),
        "triangles": st["triangles"], "warnings": len(st["warnings"]),
        "formats": {f: summary(main_side, f) for f in formats},
        "python_bytecode_cache": True,
        **provenance(),
    }
    if args.src:
        result["side_by_side"] = {side: {f: summary(side, f) for f in formats}
                                  for side in sides if side != main_side}
    for f in formats:
        line = f"{f:>9}: {result['formats'][f]['buildings_per_second']:.2f} buildings/s"
        for side in result.get("side_by_side", {}):
            line += f" | {side}: {result['side_by_side'][side][f]['buildings_per_second']:.2f}"
        print(line)
    save_result(result, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
