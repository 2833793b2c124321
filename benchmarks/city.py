"""City benchmark (issue 31, item 4): ``facadeforge batch`` on a synthetic city on the local Dask
cluster, against the plain ``facadeforge derive`` of the same footprints.

A synthetic city of ``--n`` footprints (default 10,000: rectangles and L-shapes of varied sizes
on a grid of blocks) is derived with ``examples/grammars/building.cga`` (the largest rule of
``examples/grammars``: textured facades, shop ground floor, window tiles, cornice, hip roof;
about 2,500 faces a building) three times, each as a whole CLI process:

1. ``derive`` to one CityJSONSeq file (its process pool of ``--workers`` processes);
2. ``batch`` (``--workers`` processes, ``--chunk`` buildings a task): buildings/s, the driver's
   and the largest worker's peak memory (``VmHWM`` of each process, read while it runs);
3. ``batch`` again into a new folder, one worker process killed with SIGKILL once
   ``--kill-at`` of the chunks are done: its nanny starts a new one, Dask gives the chunk in
   flight to a worker again; the time lost is this run's time less run 2's.  Afterwards
   every building must be in the CityJSONSeq chunks exactly once.  ``--no-killed-run`` leaves
   this run out (a large city in less time).

Then the finished batch is run again (everything kept: the cost of a resume check).
Results go to ``benchmarks/results/city.json`` with the machine, date and commit.

Run: ``.venv/bin/python benchmarks/city.py [--n 10000] [--workers 2] [--chunk 50]``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from engine import lot_feature  # benchmarks/engine.py, beside this file

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
RULES = ROOT / "examples" / "grammars" / "building.cga"
CLI = [sys.executable, "-m", "facadeforge.cli"]


def city(n: int) -> dict:
    """``n`` lots in blocks of 4 × 4 along streets: rectangles, every fourth an L, sizes varied
    deterministically (8–20 m wide, 9–15 m deep)."""
    feats = []
    side = max(1, int(n ** 0.5))
    for i in range(n):
        gx, gy = i % side, i // side
        x0 = gx * 24.0 + (gx // 4) * 16.0        # a 16 m street every fourth lot
        y0 = gy * 20.0 + (gy // 4) * 16.0
        w, d = 8 + (i * 7) % 13, 9 + (i * 5) % 7
        feats.append(lot_feature(f"b{i:06d}", x0, y0, w, d, i % 4 == 3))
    return {"type": "FeatureCollection", "features": feats}


def _hwm_kib(pid: int) -> int | None:
    """Peak resident memory (``VmHWM``) of a running process, KiB."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except (OSError, ValueError):
        return None
    return None


def _children(pid: int) -> list[int]:
    """Every descendant of ``pid`` (children of any of its threads: Dask's nannies start the
    workers from the cluster's event-loop thread)."""
    kids = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids += [int(k) for k in (task / "children").read_text().split()]
        except OSError:
            pass
    return kids + [g for k in kids for g in _children(k)]


def timed(cmd: list[str], *, watch_manifests: Path | None = None, kill_at: int | None = None,
          log: Path) -> dict:
    """Run ``cmd``; its wall time and the peak memory of the process and of its largest
    descendant; with ``kill_at``, SIGKILL one worker process once that many manifest entries
    exist."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    t0 = time.perf_counter()
    with open(log, "w") as err:
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, env=env, text=True)
        peak_main, peak_child, killed = 0, 0, None
        while p.poll() is None:
            peak_main = max(peak_main, _hwm_kib(p.pid) or 0)
            kids = _children(p.pid)
            for k in kids:
                peak_child = max(peak_child, _hwm_kib(k) or 0)
            if kill_at is not None and killed is None and watch_manifests is not None:
                done = len(list(watch_manifests.glob("*.json"))) if watch_manifests.is_dir() else 0
                workers = [k for k in kids if b"spawn_main" in _cmdline(k)]
                if done >= kill_at and workers:
                    victim = workers[0]
                    os.kill(victim, signal.SIGKILL)
                    killed = {"pid": victim, "at_s": round(time.perf_counter() - t0, 2),
                              "chunks_done": done}
            time.sleep(0.1)
        out = p.stdout.read()
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}); see {log}")
    return {"seconds": round(wall, 2), "driver_peak_mib": round(peak_main / 1024, 1),
            "largest_child_peak_mib": round(peak_child / 1024, 1), "stdout": out.strip(),
            "killed_worker": killed}


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


_ID = re.compile(r'"id":\s*"([^"]*)"')


def once_each(out: Path) -> tuple[int, int]:
    """(distinct buildings, largest count) over the CityJSONSeq chunks of a batch."""
    seen: Counter = Counter()
    for path in (out / "chunks").glob("*.city.jsonl"):
        with open(path, encoding="utf-8") as fh:
            next(fh)
            for line in fh:
                # the id is near the start of each line: no need to parse the geometry
                seen[_ID.search(line, 0, 400).group(1)] += 1
    return len(seen), max(seen.values(), default=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000, help="footprints (default 10000)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--chunk", type=int, default=50)
    ap.add_argument("--kill-at", type=float, default=0.4,
                    help="share of the chunks done when a worker is killed (default 0.4)")
    ap.add_argument("--no-killed-run", action="store_true",
                    help="leave out run 3 (a worker killed midway): a large city in less time")
    ap.add_argument("--note", default="", help="added to the JSON's notes")
    ap.add_argument("-o", "--output", default=str(ROOT / "benchmarks" / "results" / "city.json"))
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="facadeforge-city-") as tmp:
        tmp = Path(tmp)
        fps = tmp / "city.geojson"
        fps.write_text(json.dumps(city(args.n)))
        n_chunks = -(-args.n // args.chunk)
        load = os.getloadavg()
        runs = {}
        print(f"derive: {args.n} footprints, {args.workers} workers …", file=sys.stderr)
        runs["derive"] = timed([*CLI, "derive", str(RULES), "--footprint", str(fps), "-o",
                                str(tmp / "derive.city.jsonl"), "--workers",
                                str(args.workers)], log=tmp / "derive.log")
        (tmp / "derive.city.jsonl").unlink()
        batch = [*CLI, "batch", str(RULES), "--footprint", str(fps), "--workers",
                 str(args.workers), "--chunk", str(args.chunk), "-o"]
        print("batch …", file=sys.stderr)
        runs["batch"] = timed([*batch, str(tmp / "b1")], log=tmp / "b1.log")
        runs["batch"]["once_each"] = once_each(tmp / "b1")
        print("batch again (all kept) …", file=sys.stderr)
        runs["batch_resume_all_kept"] = timed([*batch, str(tmp / "b1")], log=tmp / "b1r.log")
        du = sum(f.stat().st_size for f in (tmp / "b1").rglob("*") if f.is_file())
        if not args.no_killed_run:
            shutil.rmtree(tmp / "b1")
            print("batch with a worker killed …", file=sys.stderr)
            runs["batch_killed_worker"] = timed(
                [*batch, str(tmp / "b2")], watch_manifests=tmp / "b2" / "manifest",
                kill_at=max(1, int(args.kill_at * n_chunks)), log=tmp / "b2.log")
            runs["batch_killed_worker"]["once_each"] = once_each(tmp / "b2")

    b, d = runs["batch"], runs["derive"]
    k = runs.get("batch_killed_worker")
    result = {
        **provenance(),
        "benchmark": "city: facadeforge batch (Dask LocalCluster) against facadeforge derive",
        "rules": str(RULES.relative_to(ROOT)), "footprints": args.n, "workers": args.workers,
        "chunk": args.chunk, "chunks": n_chunks,
        "load_average_at_start": [round(v, 2) for v in load],
        "buildings_per_s": {"batch": round(args.n / b["seconds"], 2),
                            "batch_killed_worker": round(args.n / k["seconds"], 2) if k else None,
                            "derive": round(args.n / d["seconds"], 2)},
        "seconds": {"batch": b["seconds"], "batch_killed_worker": k["seconds"] if k else None,
                    "derive": d["seconds"],
                    "batch_resume_all_kept": runs["batch_resume_all_kept"]["seconds"]},
        "time_lost_to_killed_worker_s": round(k["seconds"] - b["seconds"], 2) if k else None,
        "killed_worker": k["killed_worker"] if k else None,
        "peak_memory_mib": {"batch_driver": b["driver_peak_mib"],
                            "batch_largest_worker": b["largest_child_peak_mib"],
                            "derive_main": d["driver_peak_mib"],
                            "derive_largest_worker": d["largest_child_peak_mib"]},
        "every_building_once": {"batch": tuple(b["once_each"]) == (args.n, 1),
                                "batch_killed_worker": tuple(k["once_each"]) == (args.n, 1)
                                if k else None},
        "batch_output_mib": round(du / 2**20, 1),
        "stdout": {name: r["stdout"] for name, r in runs.items()},
        "notes": [
            "each figure is one run of a whole CLI process (Python start, footprint reading, "
            "cluster start and stop included); derive writes one CityJSONSeq file, batch "
            "writes CityJSONSeq and glb per chunk, per-building CSV rows, manifest entries, "
            "buildings.csv and tiles/tileset.json",
            "the CPU is shared with other work (load average at start above): runs drift by "
            "tens of per cent, so the time lost to a killed worker is within that noise "
            "unless it is large",
            "peak memory: VmHWM of the process (batch: the driver, which holds the local "
            "cluster's scheduler and nannies; derive: the main process) and of its largest "
            "descendant (a Dask worker; a derive pool worker), read every 0.1 s",
            *(["run 3 (a worker killed midway) left out: --no-killed-run"]
              if args.no_killed_run else []),
            *([args.note] if args.note else []),
        ],
    }
    save_result(result, args.output)


if __name__ == "__main__":
    main()
