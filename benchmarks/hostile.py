"""Hostile and careless input (issue 33): what each reproducer costs the user who runs it.

Every case is the whole CLI process on an input of the issue — a rule that never ends, a rule
file of one 8 MB string, a footprint with 4,900 courtyards — and records its exit status, the
last line it printed, its wall time and its peak memory.  The acceptance bound is 60 s and 3 GB
with exit 0 (valid files) or one error line (exit 2).  ``--src DIR`` runs another checkout's
``src`` on the same inputs in the same run, alternating (``--timeout`` bounds each run; a case
that passes it is recorded as ``timeout``).

Run: ``.venv/bin/python benchmarks/hostile.py [--src OTHER/src] [--timeout 120]``.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]


def _square(x0: float, y0: float, w: float) -> list:
    return [[x0, y0], [x0 + w, y0], [x0 + w, y0 + w], [x0, y0 + w], [x0, y0]]


def inputs(tmp: Path) -> dict[str, list[str]]:
    """Case name → CLI arguments, with the files they need written under ``tmp``."""
    files = {
        "fbomb.cga": "f(n) = case n > 0 : f(n - 1) + f(n - 1) else : 1\nLot --> extrude(f(40)) X.\n",
        "bigsplit.cga": "Lot --> extrude(1e7) split(y){1: X.}*\n",
        "inline.cga": "Lot --> inline(append){ split(x){ ~1 : A | ~1 : A } }\n"
                      "A --> split(x){ ~1 : A | ~1 : A }\n",
        "nines.cga": "Lot --> extrude(" + "9" * 30_000 + ") X.\n",
        "strbomb.cga": 'attr s = "ab"\nLot --> A(s)\nA(s) --> A(s + s)\n',
        "longstr.cga": 'Lot --> X("' + "a" * 8_000_000 + '")\n',
        "longcom.cga": "/*" + "a" * 8_000_000 + "*/ Lot --> X.\n",
        "cut.cga": "Lot --> split(x){0.0001: B}*\n",
        "inf.cga": "Lot --> extrude(1e300) X.\n",
        "terms.cga": "Lot --> extrude(" + "+".join(["1"] * 1000) + ") X.\n",
        "slabs.cga": "Lot --> extrude(10) split(x){0.002: comp(f){all: A}}*\n",
        "x.cga": "Lot --> X.\n",
    }
    for name, text in files.items():
        (tmp / name).write_text(text)
    holes = [_square(20 + 28 * i, 20 + 28 * j, 8) for i in range(70) for j in range(70)]
    (tmp / "courtyards.geojson").write_text(json.dumps(
        {"type": "Polygon", "coordinates": [_square(0, 0, 2000), *holes]}))
    import math

    ring = [[500 * math.cos(2 * math.pi * k / 100_000), 500 * math.sin(2 * math.pi * k / 100_000)]
            for k in range(100_000)]
    (tmp / "circle.geojson").write_text(json.dumps(
        {"type": "Polygon", "coordinates": [ring + [ring[0]]]}))

    def derive(rule: str, *extra: str) -> list[str]:
        return ["derive", str(tmp / rule), *extra, "-o", str(tmp / "out.glb")]
    lot = ("--lot", "10x10")
    return {
        "function calling itself twice": derive("fbomb.cga", *lot),
        "repeat of 10^7 pieces": derive("bigsplit.cga", *lot),
        "inlined runaway recursion": derive("inline.cga", *lot),
        "30,000 digits": derive("nines.cga", *lot),
        "string doubling itself": derive("strbomb.cga", *lot),
        "8 MB string": derive("longstr.cga", *lot),
        "8 MB comment": derive("longcom.cga", *lot),
        "repeat cut at the cap": derive("cut.cga", "--lot", "1000x1"),
        "extrude(1e300)": derive("inf.cga", *lot),
        "1,000 terms": derive("terms.cga", *lot),
        "500,000 slabs of a mass": derive("slabs.cga", "--lot", "1000x10"),
        "4,900 courtyards": derive("x.cga", "--footprint", str(tmp / "courtyards.geojson")),
        "100,000-vertex footprint": derive("x.cga", "--footprint", str(tmp / "circle.geojson")),
    }


_PEAK = ("import resource, subprocess, sys\n"
         "r = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
         "sys.stderr.write(r.stderr)\n"
         "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n")


def run_case(argv: list[str], env: dict, timeout: float) -> dict:
    """Exit status, last stderr line, wall seconds and peak memory (MiB) of one CLI run."""
    exe = str(Path(sys.executable).with_name("facadeforge"))
    t0 = time.perf_counter()
    # a session of its own, so that a run past the timeout is killed with the CLI it started
    proc = subprocess.Popen([sys.executable, "-c", _PEAK, exe, *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return {"rc": "timeout", "seconds": round(time.perf_counter() - t0, 1)}
    wall = time.perf_counter() - t0
    rc, peak = (int(x) for x in out.split())
    lines = [ln for ln in err.splitlines() if ln.strip()]
    return {"rc": rc, "seconds": round(wall, 2), "peak_mib": round(peak / 1024),
            "stderr_lines": len(lines), "last_line": lines[-1][:160] if lines else ""}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", type=Path, action="append", default=[],
                    help="also run this checkout's src folder (alternating)")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds a run may take")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "hostile.json"))
    args = ap.parse_args()
    env = dict(os.environ)
    sides = {"this checkout": env}
    for src in args.src:
        sides[str(src)] = {**env, "PYTHONPATH": str(src.resolve())}
    results: dict[str, dict] = {side: {} for side in sides}
    with tempfile.TemporaryDirectory() as tmp:
        cases = inputs(Path(tmp))
        for name, argv in cases.items():
            for side, side_env in sides.items():
                results[side][name] = out = run_case(argv, side_env, args.timeout)
                print(f"{side:>14} | {name:32} | {out}", file=sys.stderr, flush=True)
    ok = {name: (isinstance(r["rc"], int) and r["rc"] in (0, 2) and r["seconds"] <= 60
                 and r["peak_mib"] <= 3072)
          for name, r in results["this checkout"].items()}
    result = {"benchmark": "hostile", "timeout_seconds": args.timeout,
              "within_60s_3GB": ok, "cases": results["this checkout"], **provenance()}
    if args.src:
        result["side_by_side"] = {side: r for side, r in results.items() if side != "this checkout"}
    save_result(result, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
