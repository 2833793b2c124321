"""Label → image synthesis benchmark (``shang2023`` §4, Table 1–2 protocol) on CMP val.

Each of the 60 CMP val facades (``cmp_split(..., "val")``, never seen in training) is painted
by :func:`facadeforge.repair.synthesis.synthesize` from its own cmp12 labels with its own photo
(and labels) as the style, and compared with the photo over the whole image, at the photo's
own size: PSNR (dB, peak 255) and SSIM (scikit-image ``structural_similarity``, 7 × 7 windows,
RGB channels averaged), the mean over the facades; ``network`` is the network's output
(``match_colors=False``), ``matched`` the default output with each class's mean colour matched
to the style photo's.  The sheet (``--sheet``) shows photo | network | matched.

The bar a network must clear is the **class-mean baseline**: every pixel the mean colour of its
class in the style photo — exactly what the per-class style vectors could carry if the network
learnt nothing else.  Also timed: numpy inference of a 256 × 256 and a 1000 × 1000 label map
(best of ``--runs``, weights already loaded).

Results go under ``--label`` (``full``, ``no_detail``, ``no_regularity``, ``no_both`` … for
the ablation of Table 2) in ``benchmarks/results/synthesis.json``, other labels kept.

Run: ``.venv/bin/python benchmarks/synthesis.py --label full``
(``--weights W.npz`` for another weight file).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from facadeforge.datasets import cmp_split, load_cmp
from facadeforge.evaluation.bench import provenance, save_result
from facadeforge.repair.synthesis import DEFAULT_WEIGHTS, load_synthesis, synthesize

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "benchmarks" / "results" / "synthesis.json"
PAPER = {"protocol": "LSAA, whole image, own labels + own photo as style (Table 1)",
         "SPADE": [13.77, 0.291], "SEAN": [16.76, 0.489], "proposed": [17.13, 0.502]}


def class_mean(photo: np.ndarray, labels: np.ndarray) -> np.ndarray:
    out = np.zeros(photo.shape, np.float64)
    for c in np.unique(labels):
        m = labels == c
        out[m] = photo[m].mean(0)
    return np.round(out).astype(np.uint8)


def scores(photo, image):
    return (float(peak_signal_noise_ratio(photo, image, data_range=255)),
            float(structural_similarity(photo, image, channel_axis=2, data_range=255)))


def timing(weights, runs: int) -> dict:
    rng = np.random.default_rng(0)
    out = {}
    for side in (256, 1000):
        lab = np.kron(rng.integers(0, 12, (side // 50 + 1, side // 50 + 1)),
                      np.ones((50, 50), int))[:side, :side].astype(np.uint8)
        rgb = rng.integers(0, 256, (side, side, 3), dtype=np.uint8)
        synthesize(lab, rgb, lab, weights=weights)
        best = float("inf")
        for _ in range(runs):
            t0 = time.perf_counter()
            synthesize(lab, rgb, lab, weights=weights)
            best = min(best, time.perf_counter() - t0)
        out[f"{side}x{side}"] = round(best, 3)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", default="full", help="name of this run (full, no_detail …)")
    ap.add_argument("--weights", default=str(DEFAULT_WEIGHTS))
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "cmp"))
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--limit", type=int, default=None, help="first N val facades only")
    ap.add_argument("--no-baseline", action="store_true")
    ap.add_argument("--sheet", default=None, help="write a picture sheet PNG of 6 facades here")
    ap.add_argument("-o", "--output", default=str(OUTPUT))
    args = ap.parse_args()

    net = load_synthesis(args.weights)
    val = cmp_split(load_cmp(args.data, "cmp12"), "val")[:args.limit]
    per, base, sheet = [], [], []
    t0 = time.perf_counter()
    for i, s in enumerate(val):
        photo, lab = s.image(), s.labels()
        raw = synthesize(lab, photo, lab, weights=args.weights, match_colors=False)
        img = synthesize(lab, photo, lab, weights=args.weights)
        p, q = scores(photo, raw)
        mp, mq = scores(photo, img)
        entry = {"id": s.id, "psnr": round(p, 3), "ssim": round(q, 4),
                 "matched_psnr": round(mp, 3), "matched_ssim": round(mq, 4)}
        if not args.no_baseline:
            bp, bq = scores(photo, class_mean(photo, lab))
            entry.update(baseline_psnr=round(bp, 3), baseline_ssim=round(bq, 4))
            base.append((bp, bq))
        per.append(entry)
        if args.sheet and i % max(1, len(val) // 6) == 0 and len(sheet) < 6:
            sheet.append((photo, raw, img))
    seconds = time.perf_counter() - t0
    def mean(key):
        return float(np.mean([e[key] for e in per]))

    run = {"network": {"psnr": round(mean("psnr"), 3), "ssim": round(mean("ssim"), 4),
                       "what": "synthesize(..., match_colors=False): the network's output"},
           "matched": {"psnr": round(mean("matched_psnr"), 3),
                       "ssim": round(mean("matched_ssim"), 4),
                       "what": "synthesize(...) default: class mean colours matched to the "
                               "style photo's"},
           "facades": len(per), "weights": Path(args.weights).name,
           "trained": {k: net.meta.get(k) for k in ("steps", "seconds", "batch", "crop",
                                                    "lambda", "perceptual", "spectrum_norm")},
           "inference_seconds": timing(args.weights, args.runs),
           "benchmark_seconds": round(seconds, 1), "per_facade": per, **provenance()}
    if base:
        run["baseline_class_mean"] = {"psnr": round(float(np.mean([b[0] for b in base])), 3),
                                      "ssim": round(float(np.mean([b[1] for b in base])), 4)}
    if args.sheet and sheet:
        import cv2

        rows = []
        for images in sheet:
            h = 300
            w = round(images[0].shape[1] * h / images[0].shape[0])
            rows.append(np.concatenate([cv2.resize(x, (w, h)) for x in images], 1))
        width = max(r.shape[1] for r in rows)
        rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0))) for r in rows]
        cv2.imwrite(args.sheet, np.concatenate(rows, 0)[:, :, ::-1])
    path = Path(args.output)
    result = json.loads(path.read_text()) if path.exists() else {}
    result.update(benchmark="synthesis", data="CMP val split (60 facades), cmp12 labels",
                  metric="whole image at the photo's size; PSNR dB (peak 255), SSIM "
                         "(skimage, 7x7, RGB); mean over facades", paper=PAPER)
    result[args.label] = run
    save_result(result, path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
