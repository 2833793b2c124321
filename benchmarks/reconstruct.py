"""Whole-reconstruction benchmark (issue 4 target: ``reconstruct`` ≤ 3 s on a 1600×1200 facade,
stage 1 ≤ 0.5 s, on the 2-core machine).

Makes synthetic facades of 1600×1200 pixels (W×H; one per style) and times
:func:`facadeforge.reconstruct` with ``out_dir`` (every OUTDIR file, the 3D model and its three
exports included) — in-process, warm (a first untimed run imports the libraries).  Best of
``--runs`` per facade; per-stage timings of that run; window precision/recall/F1 against the
synthetic truth.  JSON (machine, date, commit) to ``benchmarks/results/reconstruct.json``.

Run: ``.venv/bin/python benchmarks/reconstruct.py [--runs 3] [--seed 5]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from facadeforge.datasets.synthetic import STYLES, generate
from facadeforge.evaluation.bench import provenance, save_result
from facadeforge.evaluation.metrics import match_boxes
from facadeforge.reconstruction import reconstruct

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" /
                                                   "reconstruct.json"))
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        for k, style in enumerate(STYLES):
            photo = generate(1, args.seed, tmpd / style, size=(1600, 1200), styles=[style],
                             start=k)[0]
            meta = json.loads(photo.with_suffix(".meta.json").read_text())
            objects = json.loads(photo.with_suffix(".objects.json").read_text())
            truth = [o["box"] for o in objects if o["label"] == "window"]
            if k == 0:
                reconstruct(photo, rectified=True, out_dir=tmpd / "warm")
            best, best_rec = float("inf"), None
            for r in range(args.runs):
                t0 = time.perf_counter()
                rec = reconstruct(photo, rectified=True, width_m=meta["facade_size_m"][0],
                                  out_dir=tmpd / f"out{k}_{r}")
                dt = time.perf_counter() - t0
                if dt < best:
                    best, best_rec = dt, rec
            sc = match_boxes(truth, best_rec.windows(frame="input"))
            row = {"style": style, "size": meta["image_size"], "seconds": round(best, 3),
                   "timings": {s: round(v, 4) for s, v in best_rec.report["timings"].items()},
                   "floors": best_rec.report["floors"], "tiles": best_rec.report["tiles"],
                   "windows_true": len(truth), "window_precision": round(sc.precision, 3),
                   "window_recall": round(sc.recall, 3), "window_f1": round(sc.f1, 3),
                   "flags": best_rec.report["flags"]}
            rows.append(row)
            print(f"{style} {meta['image_size']}: {best:.2f} s (symmetry "
                  f"{row['timings']['symmetry']:.3f} s), windows F1 {sc.f1:.2f}")
    result = {"benchmark": "reconstruct", **provenance(), "runs": args.runs, "facades": rows,
              "max_seconds": max(r["seconds"] for r in rows),
              "max_symmetry_seconds": max(r["timings"]["symmetry"] for r in rows)}
    save_result(result, args.output)
    print(f"→ {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
