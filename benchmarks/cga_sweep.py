"""Robustness sweep: every ``.cga`` file under a folder, on odd footprints, with every choice.

The compatibility survey (``cga_survey.py``) derives each file once, with its defaults, on one
rectangle.  Production rules hide most of their code behind ``@Enum`` choices (a roof form, a
building form, a representation) and behind the shape of the lot.  This sweep derives each file
that loads on seven footprints (a rectangle, an L, a U, a courtyard block, a triangle, a thin
strip, a large rotated concave block) with its defaults, then with each ``@Enum`` value and each
``@Range`` end of its main-file attributes, one attribute at a time.

What it counts are *runtime failures*: a derivation that raises, and warnings saying an
operation "failed on this shape" (a Python error inside an operation, turned into a warning so
that the derivation goes on).  CityEngine has no such failures, so each one is a bug of ours.
CGA warnings a rule earns (missing assets, misuse) are tallied by cause but are not failures.

Run: ``.venv/bin/python benchmarks/cga_sweep.py RULES_DIR [-o benchmarks/results/cga_sweep.json]``
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from cga_survey import cause, run_isolated  # noqa: E402 - the sibling benchmark script

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
MAX_VARIANTS = 40  # attribute settings per file (defaults first)


def _ring(points) -> list:
    pts = [list(map(float, p)) for p in points]
    return pts + [pts[0]]


def footprints() -> dict:
    """Seven initial shapes as a GeoJSON FeatureCollection (x east, y north, metres)."""
    c, s = math.cos(math.radians(27)), math.sin(math.radians(27))
    concave = [(0, 0), (60, 0), (60, 45), (35, 45), (35, 20), (20, 20), (20, 45), (0, 45)]
    rotated = [(100 + x * c - y * s, 100 + x * s + y * c) for x, y in concave]
    shapes = {
        "rectangle": [[(0, 0), (20, 0), (20, 15), (0, 15)]],
        "l_shape": [[(0, 0), (30, 0), (30, 12), (12, 12), (12, 28), (0, 28)]],
        "u_shape": [[(0, 0), (36, 0), (36, 24), (26, 24), (26, 10), (10, 10), (10, 24), (0, 24)]],
        "courtyard": [[(0, 0), (40, 0), (40, 30), (0, 30)], [(12, 10), (12, 20), (28, 20), (28, 10)]],
        "triangle": [[(0, 0), (25, 0), (8, 18)]],
        "strip": [[(0, 0), (40, 0), (40, 3), (0, 3)]],
        "rotated_block": [rotated],
    }
    return {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": name},
         "geometry": {"type": "Polygon", "coordinates": [_ring(r) for r in rings]}}
        for name, rings in shapes.items()]}


_WORKER = r"""
import json, sys
from facadeforge import load_rules
from facadeforge.engine import derive
from facadeforge.geometry.footprints import load_footprints
from facadeforge.grammar.parameters import ParameterError, _literal
path, fp_path, max_variants = sys.argv[1], sys.argv[2], int(sys.argv[3])
out = {"file": path, "runs": 0, "failures": [], "warnings": []}
try:
    rules = load_rules(path)
except Exception as e:
    out["error"] = "load: " + f"{type(e).__name__}: {e}".splitlines()[0]
    print(json.dumps(out)); sys.exit()
def literal(n):
    try:
        return _literal(n)
    except ParameterError:
        return None
variants = [{}]
for adef in rules.ruleset.main.attrs.values():
    if adef.const:
        continue
    for ann in adef.annotations:
        vals = [v for v in (literal(a) for a in ann.args) if v is not None]
        if ann.name == "Enum":
            variants += [{adef.name: v} for v in vals]
        elif ann.name == "Range" and len(vals) >= 2 and all(isinstance(v, float) for v in vals[:2]):
            variants += [{adef.name: vals[0]}, {adef.name: vals[1]}]
variants = variants[:max_variants]
out["variants"] = len(variants)
fps = load_footprints(fp_path)
seen = set()
for attrs in variants:
    try:
        models = derive(rules, fps, attrs=attrs or None, workers=1, keep_tree=False)
    except Exception as e:
        out["failures"].append({"attrs": attrs, "error": f"{type(e).__name__}: {e}".splitlines()[0]})
        continue
    for fp, m in zip(fps, models):
        out["runs"] += 1
        for w in m.warnings:
            if "failed on this shape" in w:
                out["failures"].append({"attrs": attrs, "footprint": fp.name, "warning": w})
            elif w not in seen:
                seen.add(w)
                out["warnings"].append(w)
print(json.dumps(out))
"""


def run_on_lots(worker: str, rules_dir: Path, extra: tuple, jobs: int, timeout: float) -> list:
    """``worker`` (see :func:`cga_survey.run_isolated`) on every ``.cga`` file under
    ``rules_dir``, given the seven lots (a GeoJSON file) and ``extra`` as arguments, ``jobs``
    files at a time; each result's ``file`` relative to ``rules_dir``."""
    files = sorted(rules_dir.rglob("*.cga"))
    fd, name = tempfile.mkstemp(suffix=".geojson")
    tmp = Path(name)
    with os.fdopen(fd, "w") as f:
        json.dump(footprints(), f)
    try:
        with ThreadPoolExecutor(jobs) as pool:
            results = list(pool.map(
                lambda p: run_isolated(worker, p, (tmp, *extra), timeout), files))
    finally:
        tmp.unlink()
    root = str(rules_dir.resolve()) + "/"
    for r in results:
        r["file"] = r["file"].replace(str(rules_dir) + "/", "").replace(root, "")
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rules_dir", type=Path)
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "benchmarks/results/cga_sweep.json")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per file")
    ap.add_argument("--max-variants", type=int, default=MAX_VARIANTS)
    args = ap.parse_args()
    results = run_on_lots(_WORKER, args.rules_dir, (args.max_variants,), args.jobs, args.timeout)
    root = str(args.rules_dir.resolve()) + "/"
    for r in results:
        r["warnings"] = [w.replace(root, "") for w in r.get("warnings", [])]
        for f in r.get("failures", []):
            for k in ("warning", "error"):
                if k in f:
                    f[k] = f[k].replace(root, "")
    failures = Counter(cause(f.get("warning") or f.get("error", "")) for r in results
                       for f in r.get("failures", []))
    warnings = Counter(cause(w) for r in results for w in r.get("warnings", []))
    swept = [r for r in results if "error" not in r]  # the files that load
    result = {
        "benchmark": "cga_sweep",
        "files": len(results),
        "swept": len(swept),
        "footprints": [f["properties"]["name"] for f in footprints()["features"]],
        "derivations": sum(r["runs"] for r in swept),
        "files_with_failures": sum(1 for r in swept if r["failures"]),
        "failures": sum(len(r["failures"]) for r in swept),
        "failure_causes": dict(failures.most_common()),
        "warning_causes": dict(warnings.most_common(30)),
        "per_file": results,
        **provenance(),
    }
    save_result(result, args.output)



if __name__ == "__main__":
    main()
