"""``enhance --batch``: the textured mass models of a city made procedural through
:mod:`facadeforge.city.batch`'s machinery (Müller et al. 2007 §1, Fig. 16: the textured mass
models of whole cities upgraded).

Each building of the model files is enhanced as :func:`facadeforge.city.enhance.enhance_building`
does it for one model (its textured walls unwrapped, reconstructed and replaced), but the
buildings are cut into chunks (per model file, in Morton order of their centres: a chunk is a
compact block and a good 3D tile) and each chunk is one Dask task.  The task carries the model
file's path and the buildings' numbers in it, not their geometry: a worker reads the file itself
(once per worker process, GLB textures into a scratch folder of that process), enhances its
buildings and writes the chunk's files itself, as ``batch`` does (temporary names, atomic
renames, the manifest entry last).  A rerun of the same command resumes: finished chunks are
kept, a chunk whose worker died is done again; other inputs or options on an existing OUTDIR
are refused.

OUTDIR::

    batch.json                   the run's inputs (model hashes, options, chunk size)
    manifest/NNNNN.json          one per finished chunk
    chunks/NNNNN.city.jsonl      CityJSON Text Sequences of the chunk's enhanced buildings
    chunks/NNNNN.buildings.csv   per-building statistics (faces, area, bounds)
    chunks/NNNNN.report.json     the chunk's facade records, skipped walls, failed buildings
    chunks/textures/             the textures the CityJSON files refer to
    facades/NNNNN/facade_NN/     rules.cga, shape_tree.json, texture.png of each facade
    tiles/NNNNN.glb, tiles/tileset.json   3D Tiles 1.1 of the enhanced city
    buildings.csv, report.json   merged once every chunk is done

``report.json`` has the records of the single-model ``enhance`` (``building``, ``wall``,
``windows``, ``floors``, ``flags``, …), each with the ``chunk`` and its ``folder`` under
``facades/``.  A building whose enhancement fails is recorded as failed, with its message; the
batch goes on.

The driver reads each model file once to plan the chunks (the buildings' names and centres)
and lets the geometry go before the workers start; it holds only the chunks' small summaries
afterwards.  The model files are hashed by their bytes (an OBJ with its material libraries'
bytes and its textures' names, sizes and modification times); a worker whose copy of a file
hashes otherwise fails its chunk, which a rerun retries.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from .batch import (
    LAYOUT,
    BatchResult,
    Chunk,
    _file_hash,
    _message,
    _row,
    check_cluster,
    chunk_bounds,
    plan_chunks,
    run_chunks,
    write_chunk,
)
from .enhance import (
    _check_path,
    _check_px_per_m,
    _check_up,
    _textured,
    enhance_building,
    load_mass_model,
    write_facade,
)

__all__ = ["BuildingRef", "DEFAULT_CHUNK", "enhance_batch", "enhance_chunk"]

#: Buildings a task by default: a building takes seconds (its facades are reconstructed), so
#: chunks are smaller than ``batch``'s.
DEFAULT_CHUNK = 8


@dataclass(frozen=True)
class BuildingRef:
    """A building of a model file: the file (its number in the run), the building's number in
    the file (load order) and its name in the outputs (unique in the run)."""

    file: int
    index: int
    name: str
    centre: tuple[float, float]


def _ref_hash(h, ref: BuildingRef) -> None:
    h.update(f"{ref.file}\0{ref.index}\0{ref.name}\0".encode("utf-8", "replace"))


def _model_hash(path: Path, models) -> str:
    """sha256 of the model file's bytes; for an OBJ also its material libraries' bytes
    (``mtllib``) and its textures' names, sizes and times (a GLB's are in its bytes)."""
    import re

    h = hashlib.sha256(_file_hash(path).encode())
    if path.suffix.lower() == ".obj":
        with open(path, "rb") as fh:
            libs = re.findall(rb"^[ \t]*mtllib[ \t]+(.+?)[ \t]*\r?$", fh.read(), re.M)
        for lib in libs:
            f = path.parent / os.fsdecode(lib)
            digest = _file_hash(f) if f.is_file() else "missing"
            h.update(f"mtllib {os.fsdecode(lib)}\0{digest}\0".encode("utf-8", "replace"))
        for tex in sorted({str(p.material.texture) for m in models for p in m.parts
                           if p.material.texture}):
            try:
                st = os.stat(tex)
                h.update(f"{tex}\0{st.st_size}\0{st.st_mtime_ns}\0".encode("utf-8", "replace"))
            except OSError:
                h.update(f"{tex}\0missing\0".encode("utf-8", "replace"))
    return h.hexdigest()


def _plan(paths: list[Path], up: str, size: int) -> tuple[list[Chunk], list[str], int]:
    """Read each model file once: its buildings as :class:`BuildingRef` and its hash; cut them
    into chunks.  Returns ``(chunks, file hashes, textured buildings)``."""
    from ..scratch import scratch_dir

    sets, hashes, textured = [], [], 0
    for fi, path in enumerate(paths):
        work = scratch_dir("facadeforge-enhance-plan-")
        try:
            models = load_mass_model(path, up, work / "textures")
            hashes.append(_model_hash(path, models))
            refs = []
            for bi, m in enumerate(models):
                verts = [p.mesh.vertices for p in m.parts if len(p.mesh.vertices)]
                c = np.concatenate(verts).mean(axis=0) if verts else np.zeros(3)
                refs.append(BuildingRef(fi, bi, m.name or f"building_{bi}",
                                        (float(c[0]), float(c[2]))))
                textured += _textured([m])
            sets.append(refs)
            del models
        finally:
            shutil.rmtree(work, ignore_errors=True)
    chunks = plan_chunks(sets, size, centre=lambda r: np.asarray(r.centre),
                                renamed=lambda r, n: replace(r, name=n), digest=_ref_hash)
    return chunks, hashes, textured


# -- the task (runs on a worker) --------------------------------------------------------------

_MODELS: dict = {}
_MODELS_LOCK = threading.Lock()
#: A worker's scratch folders (a GLB's textures) in the system's temporary folder, removed when
#: the worker process exits; a worker that is killed leaves them until the driver's end or the
#: next run (:mod:`facadeforge.scratch`).
_WORKER_SCRATCH = "facadeforge-enhance-worker-"


def _worker_models(spec: dict, file: int):
    """The buildings of model file ``file``, read once per worker process (the last file read
    is kept in memory; its GLB textures stay on disk until the process ends, so a thread still
    enhancing an older file's buildings keeps its textures).  Raises :class:`InputError` when
    the file this worker reads is not the one the driver planned with (another copy, changed
    since): the chunk fails as a whole and a rerun plans again."""
    key = (spec["models"][file], spec["model_hashes"][file], spec["up"])
    with _MODELS_LOCK:
        if key in _MODELS:
            return _MODELS[key]
        import cv2
        import threadpoolctl

        from ..scratch import scratch_dir

        # one thread for BLAS and OpenCV: the workers already use the cores
        threadpoolctl.threadpool_limits(1)
        cv2.setNumThreads(1)
        path = Path(key[0])
        work = scratch_dir(_WORKER_SCRATCH)
        atexit.register(shutil.rmtree, work, True)
        models = load_mass_model(path, spec["up"], work / "textures")
        if _model_hash(path, models) != key[1]:
            raise InputError(f"MODEL {path} on worker {os.uname().nodename} is not the file "
                             "the run was planned with (another copy, or changed since): give "
                             "every worker the same file, then run the same command again")
        _MODELS.clear()
        _MODELS[key] = models
        return models


def _stats_row(chunk: str, name: str, model, seconds: float) -> dict:
    model.derived_stats = model.stats()
    model.attributes.setdefault("seconds", seconds)
    return _row(chunk, name, model)


def enhance_chunk(spec: dict, chunk: Chunk) -> dict:
    """Enhance one chunk's buildings and write its files into ``spec["outdir"]`` (module
    docstring); the Dask task.  Returns the chunk's manifest entry (no geometry)."""
    t0 = time.perf_counter()
    out = Path(spec["outdir"])
    name = chunk.name
    textures: dict = {}
    models, rows, failed, facades, skipped = [], [], [], [], []
    # read outside the buildings' try: a file the worker cannot read fails the whole chunk
    # (no manifest entry: a rerun retries it), not each building
    files = {ref.file: _worker_models(spec, ref.file) for ref in chunk.footprints}
    for ref in chunk.footprints:
        t = time.perf_counter()
        try:
            building = files[ref.file][ref.index]
            b = enhance_building(building, ref.name, spec["px_per_m"], spec["seed"], textures,
                                 first=len(facades))
        except Exception as exc:  # noqa: BLE001 - one building's failure is recorded, not fatal
            msg = _message(exc)
            failed.append({"building": ref.name, "error": msg})
            rows.append(_row(name, ref.name, error=msg))
            continue
        models.append(b.model)
        facades += b.facades
        skipped += [{**s, "chunk": name} for s in b.skipped]
        rows.append(_stats_row(name, ref.name, b.model, time.perf_counter() - t))
    textures.clear()
    seconds = time.perf_counter() - t0
    records = []
    for f in facades:
        records.append({**f.record, "chunk": name, "folder": f"facades/{name}/{f.folder}"})
    report = {"chunk": name, "buildings": [r.name for r in chunk.footprints],
              "facades": records, "skipped": skipped, "failed": failed}
    entry = {"chunk": chunk.id, "name": name, "input_hash": chunk.input_hash,
             "rules_hash": None, "options_hash": spec["options_hash"],
             "version": spec["version"], "footprints": [r.name for r in chunk.footprints],
             "buildings": len(chunk.footprints), "derived": len(models), "failed": failed,
             "facades": len(facades), "windows": int(sum(r["windows"] for r in records)),
             "faces": int(sum(m.derived_stats["faces"] for m in models)),
             "triangles": int(sum(m.derived_stats["triangles"] for m in models)),
             "bbox": chunk_bounds(models), "origin_offset": None, "crs": None,
             "unit": None, "seconds": round(seconds, 3), "write_seconds": None,
             "worker": f"{os.uname().nodename}:{os.getpid()}",
             "files": {"report": f"chunks/{name}.report.json"},
             "folders": [f"facades/{name}"]}

    def extra(work: Path) -> list[tuple[Path, str]]:
        (work / "report.json").write_text(json.dumps(report, indent=1) + "\n",
                                          encoding="utf-8")
        # the chunk's facades folder, even empty: it replaces whatever a worker that died
        # before its manifest entry left there
        (work / "facades").mkdir()
        for f in facades:
            write_facade(work / "facades" / f.folder, f)
        return [(work / "report.json", f"chunks/{name}.report.json"),
                (work / "facades", f"facades/{name}")]

    return write_chunk(out, entry, models, rows, extra)


# -- the driver -------------------------------------------------------------------------------

def enhance_batch(models: Sequence[str | os.PathLike], outdir: str | os.PathLike, *,
                  px_per_m: float = 40, seed: int = 0, up: str = "y",
                  scheduler: str | None = None, workers: int | None = None,
                  chunk: int = DEFAULT_CHUNK, progress: bool = True) -> BatchResult:
    """Enhance every building of the mass model files ``models`` on a Dask cluster, into a
    resumable OUTDIR (module docstring).

    Parameters
    ----------
    models : sequence of path
        Textured mass models (``.obj`` with its ``.mtl`` and textures, or ``.glb``); every
        worker must be able to read them at these paths.
    outdir : path
        Output folder (made if missing; resumed when it holds this run).
    px_per_m, seed, up
        As for :func:`facadeforge.city.enhance.enhance`.
    scheduler, workers, chunk, progress
        As for :func:`facadeforge.city.batch.batch` (``chunk``: buildings a task).

    Returns
    -------
    BatchResult
        ``files`` lists ``buildings.csv``, ``tiles/tileset.json`` (when any building has
        faces) and ``report.json``.

    Raises
    ------
    InputError
        Unusable models, options or OUTDIR (before any work); no textured face in any model;
        chunks that failed as a whole (the others are kept: a rerun retries them).
    """
    from .. import __version__

    t0 = time.perf_counter()
    out = Path(outdir)
    if not models:
        raise InputError("give a textured mass model: facadeforge enhance MODEL -o OUTDIR")
    ppm = _check_px_per_m(px_per_m)
    _check_up(up)
    paths = [Path(m) for m in models]
    for p in paths:
        _check_path(p)
    check_cluster(scheduler, workers, chunk, "enhance")
    chunks, hashes, textured = _plan(paths, up, chunk)
    if not textured:
        raise InputError(f"MODEL {', '.join(map(str, paths))}: no textured faces (no material "
                         "with a texture image), so there is no facade image to reconstruct; "
                         "give textured mass models (.obj with its .mtl and textures, or .glb)")
    options = {"px_per_m": ppm, "seed": int(seed), "up": up, "chunk": int(chunk)}
    options_hash = hashlib.sha256(json.dumps(options, sort_keys=True).encode()).hexdigest()
    input_hash = hashlib.sha256("".join(hashes + [c.input_hash for c in chunks]).encode()
                                ).hexdigest()
    config = {"written_by": "facadeforge enhance", "layout": LAYOUT, "version": __version__,
              "rules": None, "rules_hash": None, "models": [str(p) for p in paths],
              "input_hash": input_hash, "options": options, "chunks": len(chunks),
              "buildings": sum(len(c.footprints) for c in chunks)}
    spec = {"models": [str(p.resolve()) for p in paths], "model_hashes": hashes,
            "up": up, "px_per_m": ppm, "seed": int(seed), "rules_hash": None,
            "options_hash": options_hash, "version": __version__,
            "outdir": str(out.resolve())}
    try:
        result, entries = run_chunks(out, config, [("MODEL", p) for p in paths], spec, chunks,
                                     scheduler, workers, progress, enhance_chunk, "enhance")
        result.files.append(_merge_report(out, entries, config, t0))
        result.seconds = time.perf_counter() - t0
        return result
    finally:
        from ..scratch import remove_stale

        remove_stale(tempfile.gettempdir(), _WORKER_SCRATCH)   # the local cluster's, now gone


def _merge_report(out: Path, entries: list[dict], config: dict, t0: float) -> Path:
    """``report.json``: every chunk's facade records, skipped walls and failed buildings."""
    facades, skipped, failed = [], [], []
    for e in entries:
        part = json.loads((out / e["files"]["report"]).read_text(encoding="utf-8"))
        facades += part["facades"]
        skipped += part["skipped"]
        failed += [{**f, "chunk": e["name"]} for f in part["failed"]]
    report = {"input": config["models"], **config["options"],
              "buildings": config["buildings"], "chunks": config["chunks"],
              "facades": facades, "skipped": skipped, "failed": failed,
              "summary": {"facades": len(facades), "skipped": len(skipped),
                          "failed": len(failed),
                          "windows": int(sum(f["windows"] for f in facades)),
                          "seconds": {"total": round(time.perf_counter() - t0, 3),
                                      "facades": round(sum(f["seconds"] for f in facades),
                                                       3)}}}
    tmp = out / f".report.json.{os.getpid()}.part"
    tmp.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, out / "report.json")
    return out / "report.json"
