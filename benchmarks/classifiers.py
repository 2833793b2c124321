"""Pixel classifiers compared: the §4.3.1 randomised forest (as in the thesis: 10 trees of depth
18 on 15 × 15 patch tests) against the shipped models (auto-context forest, the ensemble of
convnets and each of its members projected onto the same classes), all trained
on the development train split and scored on the validation split of RueMonge (ecp7, as the
thesis's ECP numbers) and CMP (cmp6).  The forest is trained here on each run; the others are
the shipped files.  Writes ``benchmarks/results/classifiers.json``.

    .venv/bin/python benchmarks/classifiers.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def score(clf, samples) -> dict:
    from facadeforge.evaluation.metrics import ConfusionAccumulator

    ls = samples[0].label_set
    acc = ConfusionAccumulator(ls.num_classes)
    t = time.perf_counter()
    for s in samples:
        acc.add(s.labels(), clf.predict(s.image()))
    seconds = (time.perf_counter() - t) / len(samples)
    d = acc.scores().to_dict(ls.classes)
    return {"pixel_accuracy": round(d["pixel_accuracy"], 4),
            "class_avg_accuracy": round(d["class_avg_accuracy"], 4),
            "miou": round(d["miou"], 4),
            "per_class_accuracy": {c: round(v["accuracy"], 4) for c, v in d["per_class"].items()},
            "seconds_per_image": round(seconds, 3)}


def main() -> int:
    from facadeforge.classify import SHIPPED_KINDS, default_classifier, shipped_model_path
    from facadeforge.classify.ensemble import EnsembleClassifier
    from facadeforge.classify.train import train_classifier
    from facadeforge.evaluation.bench import provenance, save_result, select_samples

    results = {}
    for dataset in ("ruemonge", "cmp"):
        if not (DATA / dataset).is_dir():
            print(f"skipping {dataset}: {DATA / dataset} is absent", file=sys.stderr)
            continue
        val, train, _ = select_samples(dataset, DATA / dataset, "val")
        ls = val[0].label_set
        t = time.perf_counter()
        forest = train_classifier(train, ls, kind="forest")
        train_s = time.perf_counter() - t
        results[dataset] = {
            "label_set": ls.name, "train_images": len(train), "val_images": len(val),
            "forest (§4.3.1)": {**score(forest, val), "train_seconds": round(train_s, 1)},
        }
        for kind in SHIPPED_KINDS:
            if shipped_model_path(ls.name, kind).is_file():
                clf = default_classifier(ls.name, kind)
                results[dataset][f"{kind} (shipped)"] = score(clf, val)
                for m in getattr(clf, "members", ()):   # each member alone, in the same classes
                    results[dataset][f"member {m.kind}-{m.label_set}"] = score(
                        EnsembleClassifier([m], ls.name), val)
        print(dataset, {k: v["class_avg_accuracy"] for k, v in results[dataset].items()
                        if isinstance(v, dict)})
    save_result({"results": results, **provenance()},
                ROOT / "benchmarks" / "results" / "classifiers.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
