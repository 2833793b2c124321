"""``facadeforge multiview`` measured (issue 30): JSON (machine, date, commit) to
``benchmarks/results/multiview.json``.

- **synthetic** (thesis §5.4.2): random three-view buildings (:func:`facadeforge.datasets.views.
  synthetic_view_set`, seeds the defaults never saw), perfect class cues; once with the views'
  exact depth as the cloud (the fit's own error) and once with the stereo's cloud (``--stereo``;
  the whole pipeline).  Eq. 5.11 per class and eq. 5.10 (cm) against the truth models, window
  and door detection (IoU ≥ 0.5), seconds, beside the thesis's Table 5.1;
- **ruemonge** (``--data DIR``): ``bench --method multiview``, its appearance-only ablation
  ``multiview-appearance`` and the single-view ``bench --method grammar`` on the same split in
  the same run (the development val split: stretches of the street no
  training photo sees), class-average accuracy and mIoU of both.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
CLI = str(Path(sys.executable).with_name("facadeforge"))
TABLE_5_1_CM = {"window": 11, "wall": 4, "balcony": 13, "door": 1, "roof": 31, "shop": 27}


def run_synthetic(n: int, seed: int, budget: int, stereo: bool) -> dict:
    from facadeforge.datasets.views import synthetic_view_set
    from facadeforge.multiview.evaluate import exact_cloud, perfect_probabilities, score
    from facadeforge.multiview.pipeline import multiview

    rows = []
    for k in range(n):
        vs = synthetic_view_set(seed + k, n_views=3)
        photos = {c: v.rgb for c, v in zip(vs.cameras, vs.views)}
        t = time.perf_counter()
        r = multiview(photos, vs.cameras, cloud=None if stereo else exact_cloud(vs),
                      probabilities=perfect_probabilities(vs), budget=budget, seed=seed)
        sec = time.perf_counter() - t
        rows.append({"seed": seed + k, "style": vs.meta["style"], "seconds": round(sec, 2),
                     "points": len(r.cloud), **score(r, vs)})
    classes = sorted({c for r in rows for c in r.get("eq_5_11_cm", {}) if c != "all"})
    mean = {c: round(sum(r["eq_5_11_cm"][c]["cm"] for r in rows if c in r.get("eq_5_11_cm", {}))
                     / max(1, sum(c in r.get("eq_5_11_cm", {}) for r in rows)), 2)
            for c in classes}
    det = [r["detection"] for r in rows if "detection" in r]
    tp, pp, tt = (sum(d[k] for d in det) for k in ("tp", "predicted", "truth"))
    p, rc = tp / max(pp, 1), tp / max(tt, 1)
    return {"cloud": "stereo" if stereo else "exact depth", "budget": budget,
            "eq_5_11_cm_mean": mean, "detection": {
                "tp": tp, "predicted": pp, "truth": tt, "precision": round(p, 4),
                "recall": round(rc, 4), "f1": round(2 * p * rc / (p + rc), 4) if p + rc else 0},
            "seconds_mean": round(sum(r["seconds"] for r in rows) / len(rows), 2),
            "buildings": rows}


def run_ruemonge(data: Path, split: str, tmp: Path, keep: Path | None) -> dict:
    """The three methods' bench runs; with ``keep``, their RESULT.json / .md kept there as
    ``bench_METHOD_ruemonge.*`` (the README's labelling table reads them)."""
    import shutil

    out = {}
    for method in ("grammar", "multiview", "multiview-appearance"):
        t = time.perf_counter()
        res = tmp / f"{method}.json"
        run = subprocess.run([CLI, "bench", "--method", method, "--dataset", "ruemonge",
                              "--data", str(data), "--split", split, "-o", str(res)],
                             capture_output=True, text=True)
        if run.returncode:
            raise SystemExit(run.stderr.strip()[-600:])
        d = json.loads(res.read_text())
        if keep is not None:
            for suffix in (".json", ".md"):
                shutil.copyfile(res.with_suffix(suffix), keep / f"bench_{method}_ruemonge{suffix}")
        out[method] = {"class_avg_accuracy": d["class_avg_accuracy"], "miou": d["miou"],
                       "pixel_accuracy": d["pixel_accuracy"], "n_images": d["n_images"],
                       "per_class": d["per_class"], "seconds_per_image": d["seconds_per_image"],
                       "wall_seconds": round(time.perf_counter() - t, 1),
                       "split_rule": d["split_rule"]}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--synthetic", type=int, default=6, help="synthetic buildings (default 6)")
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--budget", type=int, default=1500)
    ap.add_argument("--stereo", action="store_true", help="also the synthetic set with stereo")
    ap.add_argument("--data", type=Path, default=None, help="RueMonge folder (with train/)")
    ap.add_argument("--split", default="val")
    ap.add_argument("--no-keep", action="store_true",
                    help="do not keep the bench results as results/bench_METHOD_ruemonge.*")
    ap.add_argument("-o", "--output",
                    default=str(ROOT / "benchmarks" / "results" / "multiview.json"))
    args = ap.parse_args(argv)
    result = {**provenance(), "thesis_table_5_1_cm": TABLE_5_1_CM}
    if args.synthetic:
        result["synthetic_exact_depth"] = run_synthetic(args.synthetic, args.seed, args.budget,
                                                        stereo=False)
        if args.stereo:
            result["synthetic_stereo"] = run_synthetic(args.synthetic, args.seed, args.budget,
                                                       stereo=True)
    if args.data is not None:
        with tempfile.TemporaryDirectory() as tmp:
            result["ruemonge"] = {"split": args.split,
                                  **run_ruemonge(args.data, args.split, Path(tmp),
                                                 None if args.no_keep else
                                                 Path(args.output).parent)}
    save_result(result, args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
