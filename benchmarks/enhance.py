"""``facadeforge enhance`` as a user runs it: the whole CLI process on a synthetic textured mass
model (:func:`facadeforge.datasets.mass_models.box_mass_model`: a 14 × 10 × 16 m box whose four
walls carry synthetic Haussmann facade photos, seeds the shipped classifiers never saw), once
with textures of 40 px/m and once with one wall at 8 px/m (Müller Fig. 16: aerial textures a
few pixels a window), and a gable house whose street wall is a pentagon (the facade below
the eaves, plain render in the gable:
:func:`~facadeforge.datasets.mass_models.gable_mass_model`).  Windows found (leaves labelled ``window`` in each facade's tree) against
the windows in the textures (``.objects.json``; slivers under 6 px left out), wall time of the
process.  JSON (machine, date, commit) to ``benchmarks/results/enhance.json``.

With ``../shared/data/cmp`` there, another case puts real photos on the walls: a street of six
box buildings (:func:`~facadeforge.datasets.mass_models.photo_street`) whose street walls carry
the first six CMP validation photos (not trained on; the split's rule chose them, not we), 50
px/m; the truth is CMP's window rectangles (sides of 6 px and more).  These are development
photos (the classifiers' thresholds were chosen on this split), not held out.  The street is
also run through ``enhance --batch`` (one building a chunk, a local cluster of 2 workers): its
windows must be the single process's, and its wall time is beside it.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from facadeforge.datasets.mass_models import box_mass_model, gable_mass_model
from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
CLI = str(Path(sys.executable).with_name("facadeforge"))


def _run(model: Path, out: Path, truth: list[int], extra: tuple[str, ...] = ()) -> dict:
    t0 = time.perf_counter()
    run = subprocess.run([CLI, "enhance", str(model), "-o", str(out), *extra],
                         capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if run.returncode:
        raise SystemExit(run.stderr.strip()[-400:])
    report = json.loads((out / "report.json").read_text())
    found = [f["windows"] for f in report["facades"]]
    return {"wall_seconds": round(wall, 2), "facades": len(found), "windows_found": found,
            "windows_truth": truth, "total_found": sum(found), "total_truth": sum(truth),
            "relative_error": round(sum(found) / max(sum(truth), 1) - 1, 4),
            "source_px_per_m": [f["px_per_m"] for f in report["facades"]]}


def _cmp_street(data: Path, tmp: Path, n: int) -> dict | None:
    from facadeforge.datasets import load_cmp
    from facadeforge.datasets.mass_models import photo_street
    from facadeforge.datasets.splits import cmp_split

    if not (data / "cmp").is_dir():
        return None
    samples = cmp_split(load_cmp(data / "cmp"), "val")[:n]
    truth = [sum(1 for o in s.objects() if o.label == "window"
                 and min(o.x1 - o.x0, o.y1 - o.y0) >= 6) for s in samples]
    model = photo_street(tmp / "street", [s.image_path for s in samples])
    out = _run(model, tmp / "street_out", truth)
    report = json.loads((tmp / "street_out" / "report.json").read_text())
    out["photos"] = [s.id for s in samples]
    out["buildings"] = [f["building"] for f in report["facades"]]
    # the same street through --batch: one building a chunk on a local cluster of 2 workers
    batch = _run(model, tmp / "street_batch", truth,
                 ("--batch", "--workers", "2", "--chunk", "1"))
    report = json.loads((tmp / "street_batch" / "report.json").read_text())
    per = {f["building"]: f["windows"] for f in report["facades"]}
    batch["windows_found"] = [per.get(b) for b in out["buildings"]]
    batch["same_windows_as_one_process"] = batch["windows_found"] == out["windows_found"]
    batch["options"] = "--batch --workers 2 --chunk 1"
    out["through_batch"] = batch
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=21)
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--photos", type=int, default=6, help="CMP photos of the real-photo street")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "enhance.json"))
    args = ap.parse_args(argv)
    cases = {}
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        model, truth = box_mass_model(tmp / "full", seed=args.seed)
        cases["four_walls_40px_per_m"] = _run(model, tmp / "full_out", truth)
        model, truth = box_mass_model(tmp / "low", textured=(0,), ppm=8, seed=args.seed)
        cases["one_wall_8px_per_m"] = _run(model, tmp / "low_out", truth)
        model, truth = gable_mass_model(tmp / "gable", seed=args.seed)
        cases["gable_wall_40px_per_m"] = _run(model, tmp / "gable_out", [truth])
        street = _cmp_street(Path(args.data), tmp, args.photos)
        if street is not None:
            cases["cmp_val_photos_street"] = street
    save_result({**provenance(), "seed": args.seed,
                 "load_average_at_start": [round(v, 2) for v in load],
                 "notes": ["each case is one run of the whole CLI process; the load average "
                           "says whether other work shared the cores (wall times move with "
                           "it; the windows found do not)"],
                 "cases": cases}, args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
