"""Element detection from the classifier's probabilities, step by step (the ablation behind
:mod:`facadeforge.imaging.detect`): window precision / recall / F1 (IoU ≥ 0.5) on the CMP val
split for the connected components of the argmax map (what the ``classifier`` bench method
scores) and for steps 1–7 of :func:`~facadeforge.imaging.detect.detect_elements` (steps 6–7,
``behind`` and ``covers`` = the label set's ``windows_behind`` and ``windows_covering``, are
what ``reconstruct`` runs on rectified photos), with the shipped ``cmp12`` network ``reconstruct`` detects elements with; the argmax
components are the shipped ``cmp6`` default's.  Neither model has seen these facades.
Writes ``benchmarks/results/detect_cmp.json``.

    .venv/bin/python benchmarks/detect.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"

STEPS = {1: "1. XY-cut of the class mask", 2: "2. + column valley splits",
         3: "3. + fragments dropped (area < 0.3 median)", 4: "4. + weak evidence dropped "
         "(mean p < 0.5)", 5: "5. + row-consistent splits (width >= 1.8 row median) = "
         "detect_elements", 6: "6. + windows extended through the railing below them "
         "(behind=balcony)", 7: "7. + closed shutters counted as window, open ones beside the "
         "glass trimmed off (covers=blind) = what reconstruct runs on rectified photos"}


#: The options of detect_elements that switch steps 2–5 off, in step order.
_OFF = (("dip", 0.0), ("rel_area", 0.0), ("min_score", 0.0), ("row_ratio", float("inf")))


def _steps(k: int, behind: tuple[str, ...], covers: tuple[str, ...]) -> dict[str, object]:
    """Options running only steps 1–``k`` (the defaults for the steps up to ``k``; step 6
    extends windows through ``behind``, step 7 counts ``covers`` as window)."""
    return {**dict(_OFF[k - 1:]), "behind": behind if k >= 6 else (),
            "covers": covers if k >= 7 else ()}


def main() -> int:
    from facadeforge.classify import default_classifier, default_label_set
    from facadeforge.datasets import get_label_set
    from facadeforge.datasets.folder import objects_from_labels
    from facadeforge.evaluation.bench import provenance, save_result, select_samples
    from facadeforge.evaluation.metrics import match_boxes
    from facadeforge.imaging.detect import detect_elements

    if not (DATA / "cmp").is_dir():
        print(f"skipping: {DATA / 'cmp'} is absent", file=sys.stderr)
        return 0
    val, _, _ = select_samples("cmp", DATA / "cmp", "val")
    ls = val[0].label_set
    labeller = default_classifier(ls.name)          # what the bench method classifier scores
    clf = default_classifier(default_label_set(True, elements=True))   # what reconstruct runs
    fine = get_label_set(clf.label_set)
    totals: dict[str, object] = {}
    seconds = {k: 0.0 for k in STEPS}
    for s in val:
        prob = clf.predict_proba(s.image())
        argmax = np.argmax(labeller.predict_proba(s.image()), axis=2).astype(np.uint8)
        truth = np.array([o.as_array() for o in s.objects() if o.label == "window"]
                         ).reshape(-1, 4)
        comps = objects_from_labels(argmax, ls, classes=("window",))
        found = {"components of the argmax map (bench method classifier)":
                 np.array([o.as_array() for o in comps]).reshape(-1, 4)}
        for k, name in STEPS.items():
            t = time.perf_counter()
            els = detect_elements(prob, clf.classes, **_steps(k, fine.windows_behind,
                                                             fine.windows_covering))
            seconds[k] += time.perf_counter() - t
            found[name] = np.array([e.box for e in els if e.label == "window"],
                                   float).reshape(-1, 4)
        for name, boxes in found.items():
            sc = match_boxes(truth, boxes)
            totals[name] = sc if name not in totals else totals[name] + sc
    rows = {name: {"precision": round(sc.precision, 4), "recall": round(sc.recall, 4),
                   "f1": round(sc.f1, 4), "tp": sc.tp, "fp": sc.fp, "fn": sc.fn}
            for name, sc in totals.items()}
    for k, name in STEPS.items():
        rows[name]["ms_per_image"] = round(1000 * seconds[k] / len(val), 1)
    for name, r in rows.items():
        print(f"{name:70s} P {r['precision']:.3f} R {r['recall']:.3f} F1 {r['f1']:.3f}")
    save_result({"dataset": "cmp", "split": "val", "images": len(val), "classifier":
                 f"shipped {clf.kind}-{clf.label_set}", "components_classifier":
                 f"shipped {labeller.kind}-{ls.name}", "window_detection": rows, **provenance()},
                ROOT / "benchmarks" / "results" / "detect_cmp.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
