"""Occlusion-query benchmark: ``touches``, ``inside`` and ``overlaps`` on a street of buildings.

A row of ``--buildings`` 30 × 20 m lots, 2 m apart except every other pair, which stand wall to
wall; each is extruded to 24 m, its sides split into 3 m floors and 2.5 m tiles.  Every tile
asks ``touches(inter)`` (a wall against the neighbour gets no window), every window box
``inside(intra)`` and ``overlaps(all)``.  That is thousands of queries against thousands of
occluders (each closed leaf box is one), the pattern production rules use to keep windows off
party walls.

Timed: the whole ``facadeforge.derive`` of the row (its first pass that finds the neighbours'
occluders included), best of ``--runs``.  The counts per leaf rule are saved with the time, so a
before/after pair shows the same answers.  Results go under ``--label`` in
``benchmarks/results/occlusion.json`` (other labels kept).

Run: ``.venv/bin/python benchmarks/occlusion.py --label after``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

from facadeforge import derive, load_rules
from facadeforge.evaluation.bench import provenance, save_result
from facadeforge.geometry.footprints import Footprint

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "benchmarks" / "results" / "occlusion.json"

RULES = """
Lot --> extrude(24) comp(f) { side : Facade | top : Roof. }
Facade --> split(y) { ~3 : Floor }*
Floor --> split(x) { ~2.5 : Tile }*
Tile --> case touches(inter) : Party.
         else : split(x) { ~1 : Wall. | 1.2 : t(0, 0, -0.2) extrude(0.5) Box | ~1 : Wall. }
Box --> case overlaps(all) : Clash.
        case inside(intra) : Hidden.
        else : Window.
"""


def street(n: int) -> list[Footprint]:
    """``n`` lots of 30 × 20 m along x; pairs (0, 1), (2, 3)… share a wall, pairs stand 2 m
    apart."""
    out, x = [], 0.0
    for k in range(n):
        out.append(Footprint(f"lot{k}", [[x, 0, 0], [x + 30, 0, 0], [x + 30, 0, -20],
                                         [x, 0, -20]]))
        x += 30 + (0 if k % 2 == 0 else 2)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", default="after", help="name of this measurement (before / after)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--buildings", type=int, default=4)
    ap.add_argument("-o", "--output", default=str(OUTPUT))
    args = ap.parse_args()

    rules, lots = load_rules(RULES), street(args.buildings)
    times, models = [], None
    for _ in range(args.runs):
        t0 = time.perf_counter()
        models = derive(rules, lots, workers=1)
        times.append(time.perf_counter() - t0)
    counts = Counter(p.symbol for m in models for p in m.parts)
    path = Path(args.output)
    result = json.loads(path.read_text()) if path.exists() else {}
    result.update(benchmark="occlusion", buildings=args.buildings, runs=args.runs,
                  timing="seconds, best of runs, facadeforge.derive of the whole row, one process")
    result[args.label] = {"seconds": round(min(times), 3), "leaves": dict(sorted(counts.items())),
                          "faces": sum(p.mesh.n_faces for m in models for p in m.parts),
                          **provenance()}
    if "before" in result and "after" in result:
        result["speedup"] = round(result["before"]["seconds"]
                                  / max(result["after"]["seconds"], 1e-9), 1)
    save_result(result, path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
