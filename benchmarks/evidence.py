"""How much the derivation should trust the classifier: EVIDENCE chosen on the train splits.

``facadeforge parse`` labels a pixel with the derivation unless the classifier finds another
class more than ``exp(EVIDENCE)`` times as likely (``Parse.labels_input``).  This runs the
``grammar`` bench's parse (evolutionary search, the default budget, the shipped classifiers) once
per photo of the development **train** splits and scores the label map for a range of
``EVIDENCE`` values; the value that maximises the mean of the datasets' mIoU is the default.
Val photos are never looked at, so the val figures of the grammar bench stay held-out figures.

    .venv/bin/python benchmarks/evidence.py [--data ../shared/data] [--limit 30]
        [-o benchmarks/results/evidence.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from facadeforge.classify import default_classifier
from facadeforge.evaluation.bench import provenance, select_samples
from facadeforge.evaluation.methods import is_rectified
from facadeforge.evaluation.metrics import (
    class_average_accuracy,
    confusion_matrix,
    mean_iou,
    pixel_accuracy,
)
from facadeforge.parsing.parse import parse

VALUES = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, float("inf"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="../shared/data")
    ap.add_argument("--limit", type=int, default=30, help="train photos per dataset (every k-th)")
    ap.add_argument("-o", "--output", default="benchmarks/results/evidence.json")
    args = ap.parse_args()
    data = Path(args.data)
    out: dict = {"benchmark": "evidence", **provenance(),
                 "values": [v if np.isfinite(v) else "inf" for v in VALUES], "datasets": {}}
    t0 = time.perf_counter()
    for dataset in ("ruemonge", "cmp"):
        samples, _fit, rule = select_samples(dataset, data / dataset, "train")
        step = max(1, len(samples) // args.limit)
        samples = samples[::step][:args.limit]
        label_set = samples[0].label_set
        clf = default_classifier(label_set.name)
        conf = {v: np.zeros((label_set.num_classes,) * 2, np.int64) for v in VALUES}
        for s in samples:
            result = parse(s.image(), classifier=clf, method="evolution", model=False,
                           rectified=is_rectified(s))
            truth = s.labels()
            for v in VALUES:
                pred = label_set.from_canonical(result.labels_input(v))
                conf[v] += confusion_matrix(truth, pred, label_set.num_classes)
        rows = {("inf" if not np.isfinite(v) else v): {
            "pixel_accuracy": round(pixel_accuracy(c), 4),
            "class_avg_accuracy": round(class_average_accuracy(c), 4),
            "miou": round(mean_iou(c), 4)} for v, c in conf.items()}
        out["datasets"][dataset] = {"label_set": label_set.name, "photos": len(samples),
                                    "ids": [s.id for s in samples], "split_rule": rule,
                                    "classifier": default_classifier(label_set.name).meta.get(
                                        "projected_from", default_classifier(label_set.name).kind),
                                    "scores": rows}
        print(dataset, json.dumps(rows))
    mean = {k: float(np.mean([d["scores"][k]["miou"] for d in out["datasets"].values()]))
            for k in next(iter(out["datasets"].values()))["scores"]}
    best = max(mean, key=mean.get)
    out["mean_miou"] = {str(k): round(v, 4) for k, v in mean.items()}
    out["best"] = best
    out["seconds"] = round(time.perf_counter() - t0, 1)
    Path(args.output).write_text(json.dumps(out, indent=1) + "\n")
    print(f"best EVIDENCE {best} (mean mIoU {mean[best]:.4f}); written to {args.output}")


if __name__ == "__main__":
    main()
