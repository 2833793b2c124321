"""What a user waits for: ``facadeforge reconstruct`` and ``parse`` as whole CLI processes.

Issue 24 item 7: ``reconstruct`` of a 1600×1200 photo ≤ 3 s, ``parse`` ≤ 2.5 s, from the shell
(interpreter start-up, imports, model loading and any compilation included).  Photos:

- ``synthetic``: a 1600×1200 synthetic facade photo with perspective (``facadeforge synth
  --perspective --width-px 1600``, cropped to 1600×1200);
- ``ruemonge``: a RueMonge street photo (``IMG_5760``, a val photo) scaled to 1200×1600 —
  written to a temporary folder, never into the repository; skipped when the shared data is
  absent.

Each command runs ``--runs`` times in a fresh process (every OUTDIR file written, into a new
folder each time); the first run is reported apart (cold: the OS file cache, the user cache of
parser tables), the figure is the median of the rest.  ``start-up`` is ``facadeforge --help``'s
process: the floor under every command.  JSON (machine, date, commit) to
``benchmarks/results/cli_speed.json``.

    .venv/bin/python benchmarks/cli_speed.py [--runs 4] [--data ../shared/data] [--src OTHER/src]

``--src OTHER/src`` times another checkout side by side (its package first on ``PYTHONPATH``,
same interpreter and libraries), runs alternating with this checkout's.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
#: The console script a user runs (beside the interpreter of the environment).
CLI = [str(Path(sys.executable).with_name("facadeforge"))]


def _time(cmd: list[str], src: str | None = None) -> float:
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = src
    t0 = time.perf_counter()
    run = subprocess.run(cmd, capture_output=True, text=True, env=env)
    dt = time.perf_counter() - t0
    if run.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed: {run.stderr.strip()[-400:]}")
    return dt


def _photos(tmp: Path, data: Path) -> dict[str, Path]:
    photos = {}
    synth = tmp / "synth"
    subprocess.run([*CLI, "synth", "-n", "1", "--seed", "3", "--perspective", "--width-px",
                    "1600", "-o", str(synth)], check=True, capture_output=True)
    img = np.asarray(Image.open(next(synth.glob("*.jpg"))).convert("RGB"))
    h = img.shape[0]
    if h < 1200:
        img = np.asarray(Image.fromarray(img).resize((1600, 1200)))
    else:
        y0 = (h - 1200) // 2
        img = img[y0:y0 + 1200, :1600]
    photos["synthetic"] = tmp / "synthetic_1600x1200.jpg"
    Image.fromarray(img).save(photos["synthetic"], quality=92)
    street = data / "ruemonge" / "train" / "img" / "IMG_5760.jpg"
    if street.is_file():
        photos["ruemonge"] = tmp / "IMG_5760_1200x1600.jpg"
        Image.open(street).convert("RGB").resize((1200, 1600), Image.LANCZOS).save(
            photos["ruemonge"], quality=92)
    return photos


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--src", help="another checkout's src/ to time side by side")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" /
                                                   "cli_speed.json"))
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        startup = [_time([*CLI, "--help"]) for _ in range(args.runs)]
        rows.append({"command": "facadeforge --help", "photo": None,
                     "first_s": round(startup[0], 3),
                     "median_s": round(statistics.median(startup[1:] or startup), 3)})
        for name, photo in _photos(tmpd, Path(args.data)).items():
            for command in ("reconstruct", "parse"):
                times, other = [], []
                for r in range(args.runs):
                    times.append(_time([*CLI, command, str(photo), "-o",
                                        str(tmpd / f"{command}{name}{r}")]))
                    if args.src:
                        other.append(_time([*CLI, command, str(photo), "-o",
                                            str(tmpd / f"{command}{name}{r}o")], args.src))
                row = {"command": f"facadeforge {command}", "photo": name,
                       "pixels": "x".join(map(str, Image.open(photo).size)),
                       "first_s": round(times[0], 3),
                       "median_s": round(statistics.median(times[1:] or times), 3),
                       "runs_s": [round(t, 3) for t in times]}
                if args.src:
                    row["other_median_s"] = round(statistics.median(other[1:] or other), 3)
                    row["other_runs_s"] = [round(t, 3) for t in other]
                rows.append(row)
                print(f"{command} {name} {row['pixels']}: median {row['median_s']} s "
                      f"(first {row['first_s']} s)"
                      + (f"; other checkout {row['other_median_s']} s" if args.src else ""))
    result = {"benchmark": "cli_speed", **provenance(), "runs": args.runs, "rows": rows,
              "other_src": args.src,
              "targets_s": {"reconstruct": 3.0, "parse": 2.5}}
    save_result(result, args.output)
    print(f"→ {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
