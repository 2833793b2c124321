"""CityEngine compatibility survey: load and derive every ``.cga`` file under a folder.

Each rule file is loaded (parse, imports, name checks) and derived on a 20 × 15 m lot with its
default start rule, in its own process with a time limit, as CityEngine users' rule collections
would be.  The result counts files that load, derive, derive without warnings, and derive with
no warning except missing assets (texture and OBJ files the collection does not ship), and
tallies the warnings and errors by cause, so that gaps in the runtime show up ranked.

The rule files themselves stay where they are: the survey records only names and counts.

Run: ``.venv/bin/python benchmarks/cga_survey.py RULES_DIR [-o benchmarks/results/cga_survey.json]``.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]

_WORKER = r"""
import json, sys
from facadeforge import derive, load_rules
out = {"file": sys.argv[1]}
try:
    rules = load_rules(sys.argv[1])
    out["load_ok"] = True
    model = derive(rules, None, lot_size="20x15")[0]
    out["derive_ok"] = True
    out["warnings"] = list(model.warnings)
except Exception as e:  # noqa: BLE001 - the survey records every failure
    out["error"] = f"{type(e).__name__}: {e}".splitlines()[0]
print(json.dumps(out))
"""


def run_isolated(worker: str, path: Path, args: tuple, timeout: float) -> dict:
    """Run ``worker`` (Python source printing one JSON line) on rule file ``path`` in its own
    process with a time limit: the JSON, or ``{"file", "error"}`` on a timeout or crash."""
    try:
        res = subprocess.run([sys.executable, "-c", worker, str(path), *map(str, args)],
                             capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"file": str(path), "error": f"timeout after {timeout:.0f} s"}
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("{")]
    if not lines:
        tail = (res.stderr.strip().splitlines() or ["no output"])[-1]
        return {"file": str(path), "error": f"crash: {tail}"}
    return json.loads(lines[-1])


def cause(message: str) -> str:
    """A message without its location and quoted names: what the failure is."""
    text = re.sub(r"^.*?:\d+:\d+: ", "", message)
    text = re.sub(r"/\S+\.(cga|rpk)\b", "FILE", text)
    text = re.sub(r"'[^']*'", "'…'", text)
    text = re.sub(r"under \S+", "under …", text)
    return re.sub(r" \(in rule [^)]*\)", "", text)[:120]


def summarise(results: list[dict]) -> dict:
    missing = re.compile(r"(asset|texture) '.*' not found")
    loaded = [r for r in results if r.get("load_ok")]
    derived = [r for r in results if r.get("derive_ok")]
    causes: Counter = Counter()
    for r in results:
        if "error" in r:
            causes["error: " + cause(r["error"])] += 1
        for w in set(cause(w) for w in r.get("warnings", [])):
            causes["warning: " + w] += 1
    return {
        "files": len(results), "load": len(loaded), "derive": len(derived),
        "derive_without_warnings": sum(1 for r in derived if not r["warnings"]),
        "derive_without_warnings_except_missing_assets": sum(
            1 for r in derived if not [w for w in r["warnings"] if not missing.search(w)]),
        "causes": dict(causes.most_common()),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rules", type=Path, help="folder searched for .cga files")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "cga_survey.json"))
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per file")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    files = sorted(args.rules.rglob("*.cga"))
    if not files:
        print(f"no .cga files under {args.rules}", file=sys.stderr)
        return 2
    with ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda p: run_isolated(_WORKER, p, (), args.timeout), files))
    for r in results:
        r["file"] = str(Path(r["file"]).relative_to(args.rules))
    summary = summarise(results)
    save_result({"benchmark": "cga_survey", **summary, "per_file": results, **provenance()},
                args.output)
    print(json.dumps({k: v for k, v in summary.items() if k != "causes"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
