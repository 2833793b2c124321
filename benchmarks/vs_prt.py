"""facadeforge against Esri's runtime (PyPRT) on the same rule package and initial shapes.

The same ``.rpk`` and the same OBJ initial shapes (default: ``candler.rpk`` on 40 copies of
``candler_footprint.obj`` laid on a grid, 60 m apart), each engine as a whole process writing
GLB, the runs alternating (PRT, facadeforge, PRT, …) on the same machine:

- facadeforge: ``facadeforge derive RPK --footprint SHAPES.obj -o OUT.glb`` (the console
  script of this environment: start-up, imports, loading, derivation, export);
- PRT: ``benchmarks/prt_generate.py`` under ``.venv-prt`` (``make prt-env``: PyPRT alone,
  never a dependency of facadeforge), its glTF encoder writing to a folder.

Reported: wall seconds of each run, buildings per second from the best run of each, the
ratio facadeforge / PRT, the peak memory of each process, and what each made (faces and
area: facadeforge's ``--stats``, PRT's Python encoder in one more untimed run).  JSON
(machine, date, commit) to ``benchmarks/results/vs_prt.json``.

    make prt-env
    .venv/bin/python benchmarks/vs_prt.py [--runs 3] [--copies 40] [--data ../shared/data]
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

from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
CLI = str(Path(sys.executable).with_name("facadeforge"))
PRT_PY = ROOT / ".venv-prt" / "bin" / "python"


def grid_of_copies(obj: Path, copies: int, spacing: float, out: Path) -> Path:
    """``copies`` translated copies of every face of ``obj`` on a grid of 8 columns."""
    lines = obj.read_text().splitlines()
    verts = [[float(x) for x in ln.split()[1:4]] for ln in lines if ln.startswith("v ")]
    faces = [[int(p.split("/")[0]) for p in ln.split()[1:]] for ln in lines
             if ln.startswith("f ")]
    vs, fs = [], []
    for k in range(copies):
        dx, dz = (k % 8) * spacing, (k // 8) * spacing
        base = len(vs)
        vs.extend(f"v {x + dx:.6f} {y:.6f} {z + dz:.6f}" for x, y, z in verts)
        fs.extend("f " + " ".join(str(base + i) for i in f) for f in faces)
    out.write_text("\n".join(vs + fs) + "\n")
    return out


def _run(cmd: list[str]) -> tuple[float, int, str]:
    """Wall seconds, peak resident MiB of the process (the largest of it and the children it
    waited for: facadeforge's worker pool), stdout."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
        _, status, usage = os.wait4(proc.pid, 0)
        dt = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode:
            raise SystemExit(f"{' '.join(cmd)} failed: {err.read().strip()[-600:]}")
        return dt, usage.ru_maxrss // 1024, out.read()


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--copies", type=int, default=40)
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "vs_prt.json"))
    args = ap.parse_args(argv)
    rpk = Path(args.data) / "cga" / "candler.rpk"
    footprint = Path(args.data) / "cga" / "candler_footprint.obj"
    if not rpk.exists():
        raise SystemExit(f"{rpk} not found: give --data, the folder holding cga/candler.rpk")
    if not PRT_PY.exists():
        raise SystemExit(f"{PRT_PY} not found: run `make prt-env` first")
    with tempfile.TemporaryDirectory(prefix="vs_prt_") as tmp:
        tmp = Path(tmp)
        shapes = grid_of_copies(footprint, args.copies, 60.0, tmp / "shapes.obj")
        prt_cmd = [str(PRT_PY), str(ROOT / "benchmarks" / "prt_generate.py"), str(shapes),
                   str(rpk)]
        ff_cmd = [CLI, "derive", str(rpk), "--footprint", str(shapes), "--stats"]
        times: dict[str, list[float]] = {"prt": [], "facadeforge": []}
        peaks: dict[str, int] = {"prt": 0, "facadeforge": 0}
        ff_stats = None
        for i in range(args.runs):
            dt, peak, _ = _run([*prt_cmd, str(tmp / f"prt{i}")])
            times["prt"].append(round(dt, 2))
            peaks["prt"] = max(peaks["prt"], peak)
            print(f"run {i + 1}: prt {dt:.1f} s", file=sys.stderr)
            dt, peak, out = _run([*ff_cmd, "-o", str(tmp / f"ff{i}.glb")])
            times["facadeforge"].append(round(dt, 2))
            peaks["facadeforge"] = max(peaks["facadeforge"], peak)
            ff_stats = json.loads(out.strip().splitlines()[-1])
            print(f"run {i + 1}: facadeforge {dt:.1f} s", file=sys.stderr)
            for p in tmp.glob("prt*/*.glb"):
                os.unlink(p)
            for p in tmp.glob("ff*.glb"):
                os.unlink(p)
        _, _, prt_out = _run([*prt_cmd, str(tmp / "count"), "--count"])
        prt_stats = json.loads(prt_out.strip().splitlines()[-1])
    rate = {k: round(args.copies / min(v), 3) for k, v in times.items()}
    result = {
        **provenance(),
        "rules": rpk.name, "initial_shapes": f"{args.copies} copies of {footprint.name}",
        "runs": args.runs, "wall_seconds": times,
        "buildings_per_second": rate,
        "ratio": round(rate["facadeforge"] / rate["prt"], 3),
        "peak_memory_mib": peaks,
        "made": {
            "prt": {"faces": prt_stats["faces"], "area": prt_stats["area"]},
            "facadeforge": {"faces": ff_stats["faces"], "area": round(ff_stats["area"], 1),
                            "warnings": len(ff_stats.get("warnings", []))},
        },
        "notes": "whole processes, alternating, GLB out; PRT through PyPRT's glTF encoder; "
                 "faces/area of PRT from its Python encoder (untimed run); ratio from the "
                 "best run of each",
    }
    save_result(result, args.out)


if __name__ == "__main__":
    main()
