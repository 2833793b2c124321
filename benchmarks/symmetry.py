"""Stage-1 symmetry benchmark (issue 4 target: stage 1 on a 1600×1200 facade ≤ 0.5 s).

Makes one synthetic facade of 1200×1600 pixels (W×H, ``generate(1, seed, dir, size=(1200, 1600))``)
and times

* ``exact_full``: :func:`facadeforge.imaging.symmetry_profile` vertical on the full-resolution
  gray image over the floor range 2.5–5.5 m at the facade's true scale (every y, every h), with
  32 and 16 intensity levels;
* ``stage1``: the symmetry stage of :func:`facadeforge.imaging.floor_and_tile_split` as the
  pipeline runs it (working copy of about 400 rows, 16 levels), with and without the scale;
* ``floor_and_tile_split`` whole (floors + tiles), with the scale.

Best of ``--runs``; JSON (machine, date, commit) to ``benchmarks/results/symmetry.json``.

Run: ``.venv/bin/python benchmarks/symmetry.py [--runs 3] [--seed 7] [--skip-exact]``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from facadeforge.datasets.synthetic import generate
from facadeforge.evaluation.bench import provenance, save_result
from facadeforge.imaging.splits import FLOOR_RANGE_M, floor_and_tile_split, to_gray
from facadeforge.imaging.symmetry import symmetry_profile

ROOT = Path(__file__).resolve().parents[1]


def best_of(fn, runs: int) -> tuple[float, object]:
    best, out = math.inf, None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--skip-exact", action="store_true",
                    help="skip the (slow) full-resolution exact profiles")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" /
                                                   "symmetry.json"))
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        photo_path = generate(1, args.seed, tmp, size=(1200, 1600))[0]
        meta = json.loads(photo_path.with_suffix(".meta.json").read_text())
        photo = np.asarray(Image.open(photo_path).convert("RGB"))
    mpp = meta["metres_per_pixel"]
    gray = to_gray(photo)
    H, W = gray.shape
    h_range = (int(FLOOR_RANGE_M[0] / mpp[1]), int(math.ceil(FLOOR_RANGE_M[1] / mpp[1])))
    res: dict[str, object] = {}

    if not args.skip_exact:
        for bins in (32, 16):
            t, prof = best_of(lambda b=bins: symmetry_profile(gray, h_range, axis=0, bins=b), 1)
            res[f"exact_full_bins{bins}_s"] = round(t, 3)
            res["exact_full_shifts"] = int(prof.hs.size)
            print(f"exact symmetry_profile {W}x{H}, {prof.hs.size} shifts, bins={bins}: {t:.3f} s")

    t, st = best_of(lambda: floor_and_tile_split(photo, mpp, tiles=False), args.runs)
    res["stage1_symmetry_scaled_s"] = round(st.timings["symmetry"], 4)
    res["stage1_work_scale"] = round(st.work_scale, 3)
    res["stage1_work_shifts"] = int(st.profile.hs.size)
    res["floor_period_px"] = st.floor_period_px
    res["true_floor_height_px"] = round(float(meta["attributes"]["floorHeight"]) / mpp[1], 1)
    print(f"stage 1 (symmetry, working copy /{st.work_scale:.2f}, {st.profile.hs.size} shifts): "
          f"{st.timings['symmetry']:.3f} s; floor period {st.floor_period_px:.0f} px "
          f"(true {res['true_floor_height_px']} px)")
    t, st = best_of(lambda: floor_and_tile_split(photo, None, tiles=False), args.runs)
    res["stage1_symmetry_prior_s"] = round(st.timings["symmetry"], 4)
    res["stage1_prior_shifts"] = int(st.profile.hs.size)
    print(f"stage 1 without scale ({st.profile.hs.size} shifts): {st.timings['symmetry']:.3f} s")
    t, st = best_of(lambda: floor_and_tile_split(photo, mpp), args.runs)
    res["floor_and_tile_split_s"] = round(t, 4)
    res["floor_and_tile_split_timings"] = {k: round(v, 4) for k, v in st.timings.items()}
    print(f"floor_and_tile_split (floors + tiles): {t:.3f} s {res['floor_and_tile_split_timings']}")

    result = {
        "benchmark": "symmetry", "image_size": [W, H], "seed": args.seed, "style": meta["style"],
        "metres_per_pixel": mpp, "floor_range_m": list(FLOOR_RANGE_M), "h_range_px": h_range,
        "runs": args.runs, "target_stage1_s": 0.5, **res,
        **provenance(),
    }
    save_result(result, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
