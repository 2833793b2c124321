"""Laser scans → facades: detection of windows and doors, eq. 5.11 per class, time per scan.

Clouds (each run through :func:`facadeforge.points.pipeline.points` in this process, and the
whole ``facadeforge points`` CLI process timed on the same file):

- ``nuist``: ``../shared/data/pointclouds/nuist/building_1/facade_1`` — the labelled
  terrestrial scan of a shop-street facade (54,864 points).  The element thresholds were
  chosen looking at this facade: its figures are **development** figures, not held-out ones.
- ``synthetic_dev``: ``--dev-n`` scans of ``--dev-seed`` 0, on which the detector was tuned
  (development figures); ``synthetic``: ``-n`` simulated scans of ``--seed`` 1, never looked at
  while tuning (held out), also with ``--fit grammar`` (``synthetic_grammar``); each of our own
  derived buildings
  (:mod:`facadeforge.datasets.scans`, terrestrial and mobile, glass mostly without return,
  occluders, every point labelled) when that module is there.  Truth: the exact element
  rectangles of the scan; a shop front's panes (touching shop rectangles along a row) are one
  door, as NUIST labels shop fronts, and strips narrower than 0.3 m are left out.
- ``lille``: ``../shared/data/pointclouds/lille_street_small.ply`` (170,610 points, a real mobile
  scan of a street, no labels): planes found by kind, time.
- ``million``: the Lille scan with every point repeated six times with 1 cm jitter — 1,023,660
  points of a real street — for the time a million points take;
- ``street``: the Lille scan laid six times along its street — a 230 m street of a million
  points and about fifteen houses.

Scores:

- **detection**: windows and doors (IoU ≥ 0.5 in the facade plane, one-to-one, the label must
  match; ``any_label``: localisation only) of the elements the model has (``elements.json``);
- **eq. 5.11** (``simon2011`` §5.4.3): per class, the mean distance (cm, capped at 1 m) from
  points sampled on the model's surfaces of that class to the nearest scan point of the class,
  beside the thesis's Table 5.1 (its multi-view models against hand-made ground truth, a
  different protocol: for reference);
- seconds: the in-process stages and the whole CLI process.

Run: ``.venv/bin/python benchmarks/points.py [-n 6] [-o benchmarks/results/points.json]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "pointclouds"
NUIST = DATA / "nuist" / "building_1" / "facade_1"
LILLE = DATA / "lille_street_small.ply"
#: Truth rectangles narrower than this (m) are strips (mullions, frames), not elements.
MIN_TRUTH_SIDE = 0.3


def _cli(path: Path) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        subprocess.run([str(ROOT / ".venv" / "bin" / "facadeforge"), "points", str(path), "-o",
                        str(Path(tmp) / "out")], check=True, capture_output=True)
        return round(time.perf_counter() - t, 3)


def _scan_truth(scan, frame) -> list[dict]:
    """A synthetic scan's exact element rectangles on this facade, in its frame (shops count as
    doors: the detector calls every opening at the facade's foot a door, as NUIST labels shop
    fronts)."""
    out, shops = [], []
    for e in scan.elements:
        if e["label"] not in ("window", "door", "shop", "balcony"):
            continue
        f = frame.to_facade(np.asarray(e["corners"], float))
        if np.abs(f[:, 2]).max() > 1.5 or f[:, 0].max() < 0 or f[:, 0].min() > frame.width:
            continue
        box = [float(f[:, 0].min()), float(f[:, 1].min()), float(f[:, 0].max()),
               float(f[:, 1].max())]
        if e["label"] == "shop":
            shops.append(box)
        elif min(box[2] - box[0], box[3] - box[1]) >= MIN_TRUTH_SIDE:
            out.append({"label": e["label"], "box_m": tuple(box)})
    # the panes and mullion strips of one shop front are one opening (NUIST labels a shop
    # front as one door): shop boxes that touch along a row are merged
    shops.sort()
    merged: list[list[float]] = []
    for b in shops:
        m = merged[-1] if merged else None
        if m is not None and b[0] <= m[2] + 0.25 and abs(b[1] - m[1]) < 0.3 and abs(b[3] - m[3]) < 0.3:
            m[2], m[1], m[3] = max(m[2], b[2]), min(m[1], b[1]), max(m[3], b[3])
        else:
            merged.append(list(b))
    out += [{"label": "door", "box_m": tuple(b)} for b in merged
            if min(b[2] - b[0], b[3] - b[1]) >= MIN_TRUTH_SIDE]
    return out


def _shops_as_doors(cloud):
    """The scan with its ``shop`` points labelled ``door``, as its truth rectangles are (the
    detector calls a shop front a door), so that eq. 5.11 compares like with like."""
    if cloud.labels is None or "shop" not in cloud.label_names or "door" not in cloud.label_names:
        return cloud
    from dataclasses import replace

    labels = cloud.labels.copy()
    labels[labels == cloud.label_names.index("shop")] = cloud.label_names.index("door")
    return replace(cloud, labels=labels)


def _score(cloud, result, truth_of=None) -> dict:
    from facadeforge.points.evaluate import (
        class_distances,
        match,
        model_distance,
        model_triangles,
        sample_model,
        truth_boxes,
    )

    det_pred, det_truth, tree_pred = [], [], []
    for i, w in enumerate(result.whole):       # per facade plane, in the plane's own frame
        truth = truth_of(w.frame) if truth_of is not None else truth_boxes(cloud, w.frame)
        det_truth += [{**t, "facade": i} for t in truth]
        det_pred += [{**e.to_dict(), "facade": i} for e in w.elements]
        tree_pred += [{**e.to_dict(), "facade": i} for e in result.plane_elements(i)]

    def per_facade(pred):
        # boxes of different planes are in different frames: match plane by plane, sum
        out = {"tp": 0, "predicted": 0, "truth": 0}
        for i in range(len(result.whole)):
            r = match([p for p in pred if p["facade"] == i],
                      [t for t in det_truth if t["facade"] == i])
            for k in out:
                out[k] += r[k]
        p = out["tp"] / out["predicted"] if out["predicted"] else 0.0
        r = out["tp"] / out["truth"] if out["truth"] else 0.0
        out.update(precision=round(p, 4), recall=round(r, 4),
                   f1=round(2 * p * r / (p + r), 4) if p + r else 0.0)
        return out

    res = {"model": per_facade(tree_pred), "detected": per_facade(det_pred)}
    if len(result.whole) == 1:
        res["model_detail"] = match([e.to_dict() for e in result.plane_elements(0)],
                                    truth_boxes(cloud, result.whole[0].frame))
    tris, labels = model_triangles(result.models(), result.origin)
    if len(tris):
        pts, lab = sample_model(tris, labels)
        res["eq_5_11_cm"] = class_distances(pts, lab, cloud,
                                            classes=("wall", "window", "door", "balcony"))
        res["eq_5_10_cm"] = model_distance(pts, cloud.xyz)
    return res


def run_nuist(fit: str = "elements") -> dict:
    from facadeforge.datasets.nuist import load_facade
    from facadeforge.points.pipeline import points

    cloud = load_facade(NUIST)
    t = time.perf_counter()
    r = points(cloud, fit=fit)
    secs = time.perf_counter() - t
    return {"points": len(cloud), "facades": len(r.facades), "seconds": round(secs, 3),
            "timings": {k: round(v, 3) for k, v in r.report["timings"].items()},
            "structure": [f.source for f in r.facades],
            "fit": [f.report.get("fit") for f in r.facades], **_score(cloud, r)}


def run_synthetic(n: int, seed: int, fit: str = "elements") -> dict:
    try:
        from facadeforge.datasets.scans import synthetic_scans
    except ImportError:
        return {"missing": "facadeforge.datasets.scans is not there"}
    from facadeforge.points.pipeline import points

    rows = []
    for k, scan in enumerate(synthetic_scans(n, seed)):
        cloud = _shops_as_doors(scan.cloud)
        t = time.perf_counter()
        r = points(cloud, seed=seed, fit=fit)
        rows.append({"scan": k, "kind": getattr(scan, "kind", None), "points": len(cloud),
                     "structure": [f.source for f in r.facades],
                     "facades_true": len(scan.facade_planes), "facades_found": len(r.facades),
                     "seconds": round(time.perf_counter() - t, 3),
                     **_score(cloud, r, lambda fr, scan=scan: _scan_truth(scan, fr))})
        print(" ", k, rows[-1]["kind"], rows[-1]["points"], rows[-1]["model"],
              rows[-1].get("eq_5_11_cm", {}).get("all"), rows[-1]["seconds"])
    tot = {key: sum(row["model"][key] for row in rows) for key in ("tp", "predicted", "truth")}
    p = tot["tp"] / tot["predicted"] if tot["predicted"] else 0.0
    rc = tot["tp"] / tot["truth"] if tot["truth"] else 0.0
    mean = {}
    for c in ("wall", "window", "door", "balcony"):
        v = [row["eq_5_11_cm"][c]["cm"] for row in rows if c in row.get("eq_5_11_cm", {})]
        if v:
            mean[c] = round(float(np.mean(v)), 2)
    chosen = [f for row in rows for f in row.get("structure", [])]
    return {"scans": rows, "structure_chosen": {c: chosen.count(c) for c in set(chosen)},
            "model": {**tot, "precision": round(p, 4), "recall": round(rc, 4),
                                     "f1": round(2 * p * rc / (p + rc), 4) if p + rc else 0.0},
            "eq_5_11_cm_mean": mean}


def run_lille() -> dict:
    from facadeforge.points.io import read_cloud
    from facadeforge.points.pipeline import points

    cloud = read_cloud(LILLE)
    t = time.perf_counter()
    r = points(cloud)
    secs = time.perf_counter() - t
    kinds: dict[str, int] = {}
    for p in r.report["planes"]:        # a street front's houses listed one by one
        kinds[p["kind"]] = kinds.get(p["kind"], 0) + 1
    return {"points": len(cloud), "planes": kinds, "facades": len(r.facades),
            "elements": len(r.elements()), "seconds": round(secs, 3),
            "timings": {k: round(v, 3) for k, v in r.report["timings"].items()},
            "cli_seconds": _cli(LILLE)}


def run_million(tmp: Path) -> dict:
    from facadeforge.points.cloud import PointCloud
    from facadeforge.points.io import read_cloud, write_ply

    base = read_cloud(LILLE)
    rng = np.random.default_rng(0)
    xyz = np.concatenate([base.xyz] + [base.xyz + rng.normal(0, 0.01, base.xyz.shape)
                                       for _ in range(5)])
    path = tmp / "million.ply"
    write_ply(PointCloud(xyz, source="million"), path)
    return {"points": len(xyz), "cli_seconds": _cli(path)}


def run_street(tmp: Path) -> dict:
    """The Lille scan laid six times along its own street (38 m apart): a 230 m street of about
    fifteen houses, a million points, for the time a street of that size takes."""
    from facadeforge.points.cloud import PointCloud
    from facadeforge.points.io import read_cloud, write_ply

    base = read_cloud(LILLE)
    along = np.array([0.255, 0.966, 0.0])          # the street's direction in this scan
    xyz = np.concatenate([base.xyz + k * 38.0 * along for k in range(6)])
    path = tmp / "street.ply"
    write_ply(PointCloud(xyz, source="street"), path)
    out = {"points": len(xyz), "cli_seconds": _cli(path)}
    from facadeforge.points.pipeline import points

    r = points(PointCloud(xyz, source="street"), model=False)
    out["facades"] = len(r.facades)
    out["facade_planes"] = sum(p["kind"] == "facade" for p in r.report["planes"])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=6, help="held-out synthetic scans")
    ap.add_argument("--seed", type=int, default=1, help="seed of the held-out synthetic scans")
    ap.add_argument("--dev-n", type=int, default=4, help="development synthetic scans")
    ap.add_argument("--dev-seed", type=int, default=0,
                    help="seed of the synthetic scans the detector was tuned on")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "points.json"))
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from facadeforge.evaluation.bench import provenance
    from facadeforge.points.evaluate import THESIS_TABLE_5_1_CM

    out = {**provenance(), "thesis_table_5_1_cm": THESIS_TABLE_5_1_CM}
    if NUIST.is_dir():
        out["nuist"] = run_nuist()
        print("nuist", json.dumps({k: out["nuist"][k] for k in ("model", "seconds")}))
    for key, n, seed, fit in (("synthetic_dev", args.dev_n, args.dev_seed, "elements"),
                              ("synthetic", args.n, args.seed, "elements"),
                              ("synthetic_grammar", args.n, args.seed, "grammar")):
        out[key] = {"seed": seed, "fit": fit, **run_synthetic(n, seed, fit)}
        print(key, json.dumps(out[key].get("model")), out[key].get("eq_5_11_cm_mean"))
    if NUIST.is_dir():
        out["nuist_grammar"] = run_nuist(fit="grammar")
        print("nuist --fit grammar", json.dumps(out["nuist_grammar"]["model"]))
    if LILLE.is_file():
        out["lille"] = run_lille()
        print("lille", json.dumps({k: out["lille"][k] for k in ("planes", "seconds",
                                                                "cli_seconds")}))
        with tempfile.TemporaryDirectory() as tmp:
            out["million"] = run_million(Path(tmp))
            out["street"] = run_street(Path(tmp))
        print("million", out["million"], "street", out["street"])
    Path(args.output).write_text(json.dumps(out, indent=1) + "\n")
    print("→", args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
