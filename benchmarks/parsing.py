"""Grammar parsing benchmark: hill climbing vs the evolutionary search at equal budget.

For the first N validation facades of CMP (rectified) and RueMonge (street photos, rectified
first), both searches fit the default parse grammar to the shipped classifier's probabilities
with the same budget of derivations; the best energy per derivation (normalised per facade by
its final hill-climbing energy) is averaged over facades — the comparison of Fig. 5.8 of
``simon2011``.  Writes ``benchmarks/results/parsing_curves.json`` and
``docs/images/energy_curves.png``.

    .venv/bin/python benchmarks/parsing.py [--n 10] [--budget N (default: parse's)]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
COLORS = {"hill": (30, 60, 200), "evolution": (200, 60, 30)}


def curves(dataset: str, n: int, budget: int) -> dict:
    from facadeforge.classify import default_classifier
    from facadeforge.evaluation.bench import select_samples
    from facadeforge.parsing.parse import parse

    val, _, _ = select_samples(dataset, DATA / dataset, "val")
    clf = default_classifier(val[0].label_set.name)
    out = {"hill": [], "evolution": []}
    energies = {"hill": [], "evolution": []}
    seconds = {"hill": [], "evolution": []}
    for s in val[:n]:
        img = s.image()
        for method in ("hill", "evolution"):
            p = parse(img, classifier=clf, method=method, budget=budget, model=False,
                      rectified=dataset == "cmp")
            seconds[method].append(p.report["timings"]["search"])
            c = np.asarray(p.fit.search.curve, float)
            out[method].append(c)
            energies[method].append(p.fit.energy_per_pixel)
    ref = np.array([c[-1] for c in out["hill"]])
    result = {}
    for method, cs in out.items():
        norm = np.mean([c / r for c, r in zip(cs, ref)], axis=0)
        result[method] = {"mean_curve": [round(float(x), 5) for x in norm[::10]],
                          "final_energy_per_pixel": round(float(np.mean(energies[method])), 5),
                          "search_seconds": round(float(np.mean(seconds[method])), 3)}
    return result


def plot(results: dict, budget: int, path: Path) -> None:
    h, m = 380, 56
    img = np.full((h, 450 * len(results), 3), 255, np.uint8)
    for k, (dataset, res) in enumerate(results.items()):
        x0 = 450 * k
        lo = min(min(r["mean_curve"][-1] for r in res.values()), 1.0) - 0.02
        hi = 1.6
        cv2.rectangle(img, (x0 + m, m), (x0 + 450 - 16, h - m), (0, 0, 0), 1)
        for method, r in res.items():
            c = np.clip(np.asarray(r["mean_curve"]), lo, hi)
            xs = x0 + m + np.arange(len(c)) / max(1, len(c) - 1) * (450 - 16 - m)
            ys = h - m - (c - lo) / (hi - lo) * (h - 2 * m)
            cv2.polylines(img, [np.stack([xs, ys], 1).astype(np.int32)], False,
                          COLORS[method], 2, cv2.LINE_AA)
        cv2.putText(img, f"{dataset}: best energy / final hill energy", (x0 + m, 24),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(img, f"{hi:.2f}", (x0 + 8, m + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        cv2.putText(img, f"{lo:.2f}", (x0 + 8, h - m), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        cv2.putText(img, f"derivations 0..{budget}", (x0 + 160, h - 18),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        for i, method in enumerate(res):
            cv2.putText(img, method, (x0 + 300, 60 + 20 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                        COLORS[method], 1, cv2.LINE_AA)
    cv2.imwrite(str(path), img[:, :, ::-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    from facadeforge.parsing import DEFAULT_BUDGET

    ap.add_argument("--budget", type=int, default=DEFAULT_BUDGET)
    args = ap.parse_args(argv)
    from facadeforge.evaluation.bench import provenance, save_result

    results = {}
    for dataset in ("cmp", "ruemonge"):
        if not (DATA / dataset).is_dir():
            print(f"skipping {dataset}: {DATA / dataset} is absent", file=sys.stderr)
            continue
        results[dataset] = curves(dataset, args.n, args.budget)
        print(dataset, {k: (v["final_energy_per_pixel"], v["search_seconds"])
                        for k, v in results[dataset].items()})
    save_result({"facades_per_dataset": args.n, "budget": args.budget, "results": results,
                 **provenance()}, ROOT / "benchmarks" / "results" / "parsing_curves.json")
    if results:
        plot(results, args.budget, ROOT / "docs" / "images" / "energy_curves.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
