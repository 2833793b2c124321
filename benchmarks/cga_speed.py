"""Derivation speed on other people's rules: every ``.cga`` file under a folder, on seven lots.

``engine.py`` times one detailed building of our own.  Production rules spend their time
differently (many small inserts, ``comp`` and ``split`` chains, occlusion queries, cleanup
operations), so this benchmark times each corpus file that loads, with its defaults, on the
robustness sweep's seven footprints (``cga_sweep.footprints``): in its own process, one warm-up
derivation (assets and caches load), then the best of ``--runs`` timed derivations of all seven
lots, one process, one core.  It reports per file the faces made and the seconds, and over the
files that make at least ``--min-faces`` faces the faces per second (total faces / total
seconds), which is the figure to set beside CityEngine's runtime on the same rules.

Run: ``.venv/bin/python benchmarks/cga_speed.py RULES_DIR [-o benchmarks/results/cga_speed.json]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cga_sweep import footprints, run_on_lots  # noqa: E402 - the sibling benchmark script

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]

_WORKER = r"""
import json, sys, time
from facadeforge import load_rules
from facadeforge.engine import derive
from facadeforge.geometry.footprints import load_footprints
path, fp_path, runs = sys.argv[1], sys.argv[2], int(sys.argv[3])
out = {"file": path}
try:
    rules = load_rules(path)
    fps = load_footprints(fp_path)
    models = derive(rules, fps, workers=1, keep_tree=False)  # warm-up
    best = float("inf")
    for _ in range(runs):
        del models  # the last run's models are freed before the clock starts, not inside it
        t = time.perf_counter()
        models = derive(rules, fps, workers=1, keep_tree=False)
        best = min(best, time.perf_counter() - t)
    stats = [m.derived_stats for m in models]  # computed as each model was derived
    out.update(seconds=round(best, 4), faces=sum(s["faces"] for s in stats),
               triangles=sum(s["triangles"] for s in stats), lots=len(fps))
except Exception as e:  # noqa: BLE001 - files that do not load are the survey's business
    out["error"] = f"{type(e).__name__}: {e}".splitlines()[0]
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rules_dir", type=Path)
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "benchmarks/results/cga_speed.json")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=1, help="files timed at once (1: no contention)")
    ap.add_argument("--min-faces", type=int, default=1000,
                    help="files making at least this many faces count in the summary")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per file")
    args = ap.parse_args()
    results = run_on_lots(_WORKER, args.rules_dir, (args.runs,), args.jobs, args.timeout)
    timed = []
    for r in results:
        if "seconds" in r:
            r["faces_per_second"] = round(r["faces"] / r["seconds"]) if r["seconds"] else None
            timed.append(r)
    detailed = [r for r in timed if r["faces"] >= args.min_faces]
    faces = sum(r["faces"] for r in detailed)
    seconds = sum(r["seconds"] for r in detailed)
    summary = {
        "files_timed": len(timed),
        "detailed_files": len(detailed),
        "min_faces": args.min_faces,
        "detailed_faces": faces,
        "detailed_seconds": round(seconds, 3),
        "detailed_faces_per_second": round(faces / seconds) if seconds else None,
        "all_seconds": round(sum(r["seconds"] for r in timed), 3),
    }
    timed.sort(key=lambda r: -r["seconds"])
    save_result({"benchmark": "cga_speed", "lots": [f["properties"]["name"] for f in
                                                   footprints()["features"]],
                 "runs": args.runs, **summary, "per_file": timed, **provenance()}, args.output)
    print(json.dumps(summary))
    for r in timed[:12]:
        print(f"{r['seconds']:8.3f} s {r['faces']:8d} faces {r['faces_per_second'] or 0:8d}/s  "
              f"{r['file']}")


if __name__ == "__main__":
    main()
