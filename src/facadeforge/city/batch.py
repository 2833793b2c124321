"""Batch derivation of a city on Dask distributed, resumable after killed workers or a killed run.

The footprints are cut into chunks (per footprint file, in Morton order of their centres, so a
chunk is a compact block of the city and a good 3D tile).  Each chunk is one Dask task: the
worker loads the rules itself (the task carries the rule file's path, not parsed rules),
derives the chunk's buildings, writes the chunk's files itself and returns only a small
summary, so the driver never holds the city's geometry.

Output folder
-------------
::

    OUTDIR/
      batch.json                  the run's inputs: rules and footprint hashes, options, chunk size
      manifest/NNNNN.json         one per finished chunk (written last, atomically)
      chunks/NNNNN.city.jsonl     CityJSON Text Sequences of the chunk's buildings
      chunks/NNNNN.buildings.csv  the chunk's per-building statistics
      chunks/textures/            textures the CityJSON files refer to (if the rules texture),
                                  named by their bytes too: the chunks share the folder
      tiles/NNNNN.glb             the chunk's glTF: the content of its 3D tile
      tiles/tileset.json          3D Tiles 1.1 (written once every chunk is done)
      buildings.csv               every building's statistics (merged once every chunk is done)

A task writes its chunk into a private scratch folder ``OUTDIR/.work/chunk-<host>-<pid>-…``,
then renames each file into place (``os.replace``: atomic) and the manifest entry last.  So a
chunk is done exactly when its manifest entry exists; a file under its final name is always
whole; a chunk whose worker died before its manifest entry is derived again and its files
replaced, never appended to: every building is in exactly one ``.city.jsonl`` line.

Resuming and changed inputs
---------------------------
A rerun of the same command skips the chunks whose manifest entry matches the chunk's input
hash, the rules hash, the options and the tool version, and derives the others.  A rerun with
other rules, options, chunk size or footprints on an existing OUTDIR is refused with an
:class:`~facadeforge.errors.InputError` naming what changed (give a new ``-o``, or delete
OUTDIR to start over): mixing two cities' chunks in one folder would be silently wrong.  The
rules hash covers what a derivation reads (:func:`rules_hash`): the rule file's bytes (or the
``.rpk``'s, assets and all), every rule file it imports, and the listing of the asset folders
(``--assets``; for a ``.cga``, its project's folders too): each file's name, size and
modification time.  Scratch folders of dead processes of this host are removed at the start; one
``batch`` at a time may write an OUTDIR (a lock file, released by the system however the
driver ends).

A building that fails to derive (a cap, a ``--strict`` warning, a bad footprint) is recorded as
failed, with its message, in the manifest entry and the statistics; the batch goes on.

``enhance --batch`` (:mod:`facadeforge.city.enhance_batch`) runs through the same machinery
with its own task: :func:`plan_chunks`, :func:`write_chunk`, the manifest, the resume checks,
the cluster and the merge are these.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FacadeForgeError, InputError, RuleError

__all__ = ["BATCH_FILE", "STATS_COLUMNS", "BatchResult", "Chunk", "batch", "derive_chunk",
           "plan_chunks"]

#: The run description in OUTDIR.
BATCH_FILE = "batch.json"
#: Version of the OUTDIR's layout, in ``batch.json``: an OUTDIR of another layout is not
#: resumed (2: textures named by their bytes, chunk halos, ``enhance --batch``).
LAYOUT = 2
_LOCK = ".batch.lock"
_WORK = ".work"
_SCRATCH = "chunk-"

#: Columns of ``buildings.csv`` (bounds in the models' axes: x, y up, z; metres).
STATS_COLUMNS = ("chunk", "building", "status", "error", "seconds", "shapes", "faces",
                 "triangles", "vertices", "area_m2", "height_m", "warnings",
                 "min_x", "min_y", "min_z", "max_x", "max_y", "max_z")


@dataclass
class Chunk:
    """A task's footprints: ``id`` (its files are ``f"{id:05d}"``…), the footprints, and the
    hash of what was read of them; ``halo``: the footprints of other chunks near them, whose
    occluders the ``inter`` occlusion queries of the chunk's buildings see (not derived into
    the chunk's outputs)."""

    id: int
    footprints: list
    input_hash: str
    width: int = 5
    halo: list = field(default_factory=list)

    @property
    def name(self) -> str:
        return f"{self.id:0{self.width}d}"


@dataclass
class BatchResult:
    """What :func:`batch` did: chunk counts, buildings, failures and the files it wrote."""

    outdir: Path
    chunks: int
    skipped: int
    derived: int
    buildings: int
    failed: list = field(default_factory=list)   # (chunk, building, message)
    seconds: float = 0.0
    files: list = field(default_factory=list)
    notes: list = field(default_factory=list)    # (chunk, message)


# -- planning ---------------------------------------------------------------------------------

def _morton(xy: np.ndarray) -> np.ndarray:
    """Z-order keys of (n, 2) points: near points get near keys (16 bits an axis)."""
    if not len(xy):
        return np.zeros(0, np.uint64)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    q = ((xy - lo) / np.maximum(hi - lo, 1e-9) * 65535).astype(np.uint64)
    key = np.zeros(len(xy), np.uint64)
    for bit in range(16):
        for axis in range(2):
            key |= ((q[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(2 * bit + axis)
    return key


def _footprint_hash(h, fp) -> None:
    h.update(fp.name.encode("utf-8", "replace") + b"\0")
    h.update(np.ascontiguousarray(fp.polygon, np.float64).tobytes())
    for hole in fp.holes:
        h.update(b"hole" + np.ascontiguousarray(hole, np.float64).tobytes())
    h.update(json.dumps(fp.attributes, sort_keys=True, default=str).encode())


def _footprint_centre(fp) -> np.ndarray:
    return np.asarray(fp.polygon, float).mean(axis=0)[[0, 2]]


def _renamed_footprint(fp, name: str):
    import dataclasses

    return dataclasses.replace(fp, name=name)


def _footprint_box(fp) -> np.ndarray:
    xz = np.asarray(fp.polygon, float)[:, [0, 2]]
    return np.r_[xz.min(axis=0), xz.max(axis=0)]


#: Footprints of other chunks within this many metres (between footprint bounds) of a chunk's
#: are its halo when the rules query their neighbours (``inter`` occlusion): their occluders
#: are derived with the chunk's, so that a building at a chunk's edge sees its neighbour across
#: it as ``derive`` would.  A building whose model reaches more than half of it past its
#: footprint is reported (a note in its chunk's manifest entry and on stderr).
HALO_M = 10.0


def _halos(boxes: np.ndarray, size: int, margin: float) -> list[np.ndarray]:
    """For consecutive slices of ``size`` items with bounds ``boxes`` (n, 4: x0, z0, x1, z1),
    the indices of the other items within ``margin`` of one of the slice's."""
    out = []
    n = len(boxes)
    for k in range(0, n, size):
        mine = boxes[k:k + size]
        lo, hi = mine[:, :2].min(axis=0) - margin, mine[:, 2:].max(axis=0) + margin
        cand = np.flatnonzero(np.all(boxes[:, :2] <= hi, axis=1)
                              & np.all(boxes[:, 2:] >= lo, axis=1))
        cand = cand[(cand < k) | (cand >= k + size)]
        if len(cand):
            c = boxes[cand]
            gap = np.maximum(0.0, np.maximum(c[None, :, :2] - mine[:, None, 2:],
                                             mine[:, None, :2] - c[None, :, 2:]))
            cand = cand[(np.hypot(gap[..., 0], gap[..., 1]) <= margin).any(axis=0)]
        out.append(cand)
    return out


def plan_chunks(item_sets: Sequence[list], size: int, *, centre=_footprint_centre,
                renamed=_renamed_footprint, digest=_footprint_hash,
                halo_m: float | None = None) -> list[Chunk]:
    """Cut items (footprints; for ``enhance``, the buildings of mass models) into chunks of at
    most ``size``: per input file (a file's items share its origin), in Morton order of their
    centres (``centre(item)``: x and z), names made unique across files (``name~2``…, with
    ``renamed(item, name)``), as each becomes a CityJSON id; a chunk's input hash is the sha256
    of what ``digest(h, item)`` feeds it for its items (and its halo's).  With ``halo_m``
    (footprints), each chunk's halo: the footprints of the same file in other chunks within
    that distance of one of its own."""
    if size < 1:
        raise InputError(f"--chunk {size}: give a positive number of buildings a chunk")
    chunks, seen, cid = [], {}, 0
    total = sum(len(s) for s in item_sets)
    width = max(5, len(str(max(total // size, 1))))
    for items in item_sets:
        centres = np.array([centre(it) for it in items]).reshape(-1, 2)
        order = np.argsort(_morton(centres), kind="stable")
        ordered = []
        for i in order:
            it = items[i]
            n = seen.get(it.name, 0)
            seen[it.name] = n + 1
            if n:
                it = renamed(it, f"{it.name}~{n + 1}")
            ordered.append(it)
        halos = None
        if halo_m is not None and ordered:
            halos = _halos(np.array([_footprint_box(it) for it in ordered]), size, halo_m)
        for k in range(0, len(ordered), size):
            part = ordered[k:k + size]
            halo = [ordered[i] for i in halos[k // size]] if halos is not None else []
            h = hashlib.sha256()
            for it in part:
                digest(h, it)
            for it in halo:
                h.update(b"halo\0")
                digest(h, it)
            chunks.append(Chunk(cid, part, h.hexdigest(), width, halo))
            cid += 1
    return chunks


#: Most asset files :func:`rules_hash` lists (a project folder holding far more is listed up
#: to this many files, in name order: the hash stays bounded in time and still deterministic).
MAX_LISTED_FILES = 50_000


def rules_hash(rules_path: Path, loaded, assets=None, skip: Path | None = None) -> str:
    """sha256 of what deriving ``loaded`` (the rules read from ``rules_path``) can read: the
    rule file's (or ``.rpk``'s) bytes, every imported rule file's bytes, and the other files of
    the asset folders by name, size and modification time (``--assets``; for a ``.cga``, also the
    folders its assets resolve against; a package's own folders are its bytes).  A rerun after
    an imported rule or an asset changed then redoes the city instead of keeping chunks made
    from the old ones.  ``skip``: a folder left out of the listing (the OUTDIR, when it lies
    in the rules' folder: its files change as the run writes them)."""
    h = hashlib.sha256(_file_hash(rules_path).encode())
    skip = skip.resolve() if skip is not None else None
    package = getattr(loaded, "package", None)
    main = Path(str(loaded.ruleset.main.path))
    for m in sorted({str(m.path) for m in loaded.ruleset.main.all_modules()}):
        f = Path(m)
        if f != main and f.is_file():
            h.update(f"import {f.name}\0{_file_hash(f)}\0".encode())
    roots = [Path(assets).resolve()] if assets else []
    if package is None:
        roots += [Path(r) for r in loaded.assets.roots]
    listed = 0
    for root in dict.fromkeys(roots):
        if not root.is_dir():
            continue
        for dirpath, dirs, files in os.walk(root):
            if listed >= MAX_LISTED_FILES:
                break  # bounded: a huge project folder is not walked to its end
            dirs[:] = sorted(d for d in dirs if skip is None or Path(dirpath, d).resolve() != skip)
            for name in sorted(files):
                if listed >= MAX_LISTED_FILES:
                    break
                if name.lower().endswith(".cga"):  # rule files count by their bytes, above
                    continue
                f = Path(dirpath) / name
                try:
                    st = f.stat()
                except OSError:
                    continue
                h.update(f"{f.relative_to(root)}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
                listed += 1
    return h.hexdigest()


def _file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# -- the task (runs on a worker) --------------------------------------------------------------

_RULES: dict = {}


def _worker_rules(spec: dict):
    """The rules of ``spec``, loaded once per worker process (and rules hash)."""
    key = (spec["rules"], spec["rules_hash"], spec["rule"], spec["assets"], spec["start"],
           spec["style"])
    if key not in _RULES:
        import threadpoolctl

        from ..engine import load_rules
        from ..grammar.interpreter import PYTHON_RECURSION_LIMIT

        # one BLAS thread: the workers already use the cores; deep trees need the frames
        threadpoolctl.threadpool_limits(1)
        sys.setrecursionlimit(max(sys.getrecursionlimit(), PYTHON_RECURSION_LIMIT))
        _RULES.clear()
        _RULES[key] = load_rules(spec["rules"], rule=spec["rule"], assets=spec["assets"],
                                 start=spec["start"], style=spec["style"])
    return _RULES[key]


def _message(exc: BaseException) -> str:
    if type(exc).__name__ == "KilledWorker":
        # Dask gave the chunk to a new worker allowed-failures times, and each died
        return ("every worker that took it died (out of memory? see the workers' logs; a "
                "smaller --chunk helps when a few buildings are very large)")
    if isinstance(exc, FacadeForgeError):
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return f"internal error: {type(exc).__name__}: {exc}"


def _row(chunk: str, name: str, model=None, error: str = "") -> dict:
    row = dict.fromkeys(STATS_COLUMNS, "")
    row.update(chunk=chunk, building=name, status="failed" if model is None else "ok",
               error=error)
    if model is not None:
        s = model.derived_stats
        lo, hi = np.asarray(s["bbox"][0], float), np.asarray(s["bbox"][1], float)
        row.update(seconds=round(float(model.attributes.get("seconds", 0.0)), 4),
                   shapes=int(model.attributes.get("shapes", 0)), faces=s["faces"],
                   triangles=s["triangles"], vertices=s["vertices"],
                   area_m2=round(float(s["area"]), 3),
                   height_m=round(float(hi[1] - lo[1]), 3) if s["faces"] else 0.0,
                   warnings=len(model.warnings))
        if s["faces"]:
            for axis, k in zip("xyz", range(3)):
                row[f"min_{axis}"] = round(float(lo[k]), 3)
                row[f"max_{axis}"] = round(float(hi[k]), 3)
    return row


def _csv_text(rows: list[dict], header: bool = True) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=STATS_COLUMNS, lineterminator="\n")
    if header:
        w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def derive_chunk(spec: dict, chunk: Chunk) -> dict:
    """Derive one chunk and write its files into ``spec["outdir"]`` (module docstring); the
    Dask task.  Returns the chunk's manifest entry (counts, bounds, failures: no geometry)."""
    from ..engine import _queries_neighbours, derive_footprint, neighbour_occluders

    t0 = time.perf_counter()
    rules = _worker_rules(spec)
    out = Path(spec["outdir"])
    name = chunk.name

    def one(fp, around=None, tree=False):
        return derive_footprint(rules, fp, attrs=spec["attrs"], seed=spec["seed"],
                                strict=spec["strict"], start=spec["start"],
                                limits=spec["limits"], keep_tree=tree, neighbours=around)

    around = [None] * len(chunk.footprints)
    notes = []
    neighbours = _queries_neighbours(rules)
    if (len(chunk.footprints) > 1 or chunk.halo) and neighbours:
        # ``inter`` occlusion: the occluders of the neighbours in the chunk and in its halo
        # (module docstring)
        from ..engine import _occluders_only
        from ..model.model import Model

        firsts = []
        for fp in [*chunk.footprints, *chunk.halo]:
            try:
                firsts.append(_occluders_only(one(fp)))
            except Exception:  # noqa: BLE001 - reported by the second pass
                firsts.append(Model([], None, {}, [], fp.name))
        around = neighbour_occluders(firsts)[:len(chunk.footprints)]
    models, rows, failed = [], [], []
    for fp, near in zip(chunk.footprints, around):
        try:
            m = one(fp, near)
        except Exception as exc:  # noqa: BLE001 - one building's failure is recorded, not fatal
            msg = _message(exc)
            failed.append({"building": fp.name, "error": msg})
            rows.append(_row(name, fp.name, error=msg))
            continue
        models.append(m)
        rows.append(_row(name, fp.name, m))
        reach = _reach(fp, m) if neighbours else 0.0
        if reach > HALO_M / 2:
            # two buildings whose models each reach r past their footprints meet across a gap
            # of 2 r: past half the halo, a pair may be missed (one of them is named)
            notes.append(f"building {fp.name}: its model reaches {reach:.1f} m beyond its "
                         f"footprint, more than half the {HALO_M:g} m halo of the chunks: "
                         "the inter occlusion queries of buildings of other chunks may not "
                         "see it, nor it theirs")
    seconds = time.perf_counter() - t0

    bbox = chunk_bounds(models)
    first = models[0].attributes if models else (chunk.footprints[0].attributes
                                                 if chunk.footprints else {})
    entry = {"chunk": chunk.id, "name": name, "input_hash": chunk.input_hash,
             "rules_hash": spec["rules_hash"], "options_hash": spec["options_hash"],
             "version": spec["version"], "footprints": [fp.name for fp in chunk.footprints],
             "buildings": len(chunk.footprints), "derived": len(models), "failed": failed,
             "faces": int(sum(m.derived_stats["faces"] for m in models)),
             "triangles": int(sum(m.derived_stats["triangles"] for m in models)),
             "bbox": bbox,
             "origin_offset": first.get("_origin_offset"), "crs": first.get("_crs"),
             "unit": first.get("_unit"), "seconds": round(seconds, 3),
             "write_seconds": None,
             "worker": f"{os.uname().nodename}:{os.getpid()}", "files": {},
             "halo": [fp.name for fp in chunk.halo], "notes": notes}
    return write_chunk(out, entry, models, rows)


def _reach(fp, model) -> float:
    """How far (metres, horizontally) ``model`` reaches beyond the bounds of its footprint
    ``fp`` (its occluders lie within the model)."""
    s = model.derived_stats
    if not s["faces"]:
        return 0.0
    lo, hi = np.asarray(s["bbox"][0], float)[[0, 2]], np.asarray(s["bbox"][1], float)[[0, 2]]
    box = _footprint_box(fp)
    return float(max(0.0, *(box[:2] - lo), *(hi - box[2:])))


def write_chunk(out: Path, entry: dict, models: list, rows: list[dict], extra=None) -> dict:
    """Write a chunk's files into OUTDIR (module docstring): CityJSONSeq and glTF of
    ``models`` (when they have faces), the statistics ``rows``, whatever ``extra(work)``
    writes into the scratch folder (it returns ``(scratch path, path relative to OUTDIR)``
    pairs: files, or folders that replace the folder there), each renamed into place, and the
    manifest ``entry`` last.  Returns ``entry`` with its ``files``."""
    from ..exchange import export_cityjsonseq, export_glb
    from ..exchange.cityjson import BY_CONTENT
    from ..scratch import scratch_dir

    t0 = time.perf_counter()
    name = entry["name"]
    has_geometry = entry["bbox"] is not None
    (out / _WORK).mkdir(exist_ok=True)
    work = scratch_dir(_SCRATCH, out / _WORK)
    try:
        finals: list[tuple[Path, str]] = []   # (scratch file, final path relative to OUTDIR)
        if has_geometry:
            # textures named by their bytes: the chunks share one textures/ folder
            for path in export_cityjsonseq(models, work / f"{name}.city.jsonl",
                                           textures=BY_CONTENT):
                rel = path.relative_to(work).as_posix()
                finals.append((path, f"chunks/{rel}"))
            export_glb(models, work / f"{name}.glb")
            finals.append((work / f"{name}.glb", f"tiles/{name}.glb"))
        (work / f"{name}.buildings.csv").write_text(_csv_text(rows), encoding="utf-8")
        finals.append((work / f"{name}.buildings.csv", f"chunks/{name}.buildings.csv"))
        if extra is not None:
            finals += extra(work)
        # textures first, the chunk's own files next, the manifest entry last: a chunk is
        # done exactly when its entry exists (module docstring)
        finals.sort(key=lambda f: not f[1].startswith("chunks/textures/"))
        for src, rel in finals:
            dest = out / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            if src.is_dir() and dest.is_dir() and not dest.is_symlink():
                # a folder left by a worker that died before its manifest entry: replaced
                shutil.rmtree(dest)
            os.replace(src, dest)
        entry["write_seconds"] = round(time.perf_counter() - t0, 3)
        entry["files"] = {"cityjsonseq": f"chunks/{name}.city.jsonl" if has_geometry else None,
                          "glb": f"tiles/{name}.glb" if has_geometry else None,
                          "stats": f"chunks/{name}.buildings.csv",
                          **{k: v for k, v in entry.get("files", {}).items()}}
        tmp = work / "manifest.json"
        tmp.write_text(json.dumps(entry, indent=1) + "\n", encoding="utf-8")
        (out / "manifest").mkdir(exist_ok=True)
        os.replace(tmp, out / "manifest" / f"{name}.json")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return entry


def chunk_bounds(models: list) -> list | None:
    """``[lo, hi]`` of the models' ``derived_stats`` boxes, ``None`` when none has a face."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for m in models:
        s = m.derived_stats
        if s["faces"]:
            lo = np.minimum(lo, s["bbox"][0])
            hi = np.maximum(hi, s["bbox"][1])
    return [lo.tolist(), hi.tolist()] if np.isfinite(lo).all() else None


# -- the driver -------------------------------------------------------------------------------

class _Progress:
    """Buildings a second and ETA on stderr: one updating line on a terminal, else a plain
    line every few seconds."""

    def __init__(self, total: int, stream=None, every: float = 5.0, label: str = "batch"):
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.total, self.every = total, every
        self.t0 = time.perf_counter()
        self.last = -math.inf
        self.done = 0

    def update(self, buildings: int, chunks_done: int, chunks: int) -> None:
        self.done += buildings
        now = time.perf_counter()
        finished = self.done >= self.total
        if not self.tty and not finished and now - self.last < self.every:
            return
        self.last = now
        elapsed = now - self.t0
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else math.inf
        eta_text = f"ETA {_duration(eta)}" if math.isfinite(eta) else "ETA ?"
        pct = 100.0 * self.done / self.total if self.total else 100.0
        text = (f"{self.label}: {self.done}/{self.total} buildings ({pct:.0f} %), chunk {chunks_done}/"
                f"{chunks}, {rate:.1f} buildings/s, {eta_text}")
        if self.tty:
            self.stream.write("\r" + text.ljust(78) + ("\n" if finished else ""))
            self.stream.flush()
        else:
            print(text, file=self.stream, flush=True)

    def close(self) -> None:
        if self.tty and self.done < self.total:
            self.stream.write("\n")
            self.stream.flush()


def _duration(s: float) -> str:
    s = int(round(s))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


def _lock(out: Path):
    """Hold ``OUTDIR/.batch.lock`` (``flock``: released when the process ends, however)."""
    import fcntl

    fh = open(out / _LOCK, "a+")
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        fh.close()
        raise InputError(f"output folder {out} is being written by another facadeforge batch; "
                         "wait for it to finish, or give another -o folder") from None
    return fh


def _prepare_outdir(out: Path, config: dict, inputs: list[tuple[str, Path]]):
    """Refuse an OUTDIR this batch may not write (module docstring), lock it, write
    ``batch.json``; returns the lock (an open file: close it to release)."""
    if out.exists() and not out.is_dir():
        raise InputError(f"output folder {out} is an existing file; choose a folder name")
    real = out.resolve()
    for what, p in inputs:
        rp = p.resolve()
        if rp == real or real in rp.parents:
            raise InputError(f"{what} {p} is inside the output folder {out}; keep inputs "
                             f"outside it, e.g. -o {out.parent / (out.name + '-batch')}")
    previous = out / BATCH_FILE
    if out.is_dir() and not previous.is_file():
        # a driver killed before its batch.json leaves only its lock and scratch
        foreign = sorted(p.name for p in out.iterdir() if p.name not in (_LOCK, _WORK)
                         and not p.name.startswith(f".{BATCH_FILE}."))
        if foreign:
            raise InputError(f"output folder {out} holds files and no {BATCH_FILE} of a "
                             f"facadeforge batch ({', '.join(foreign[:3])}…); give a new or "
                             "empty folder")
    for sub in ("manifest", "chunks", "tiles", "facades", _WORK):
        p = out / sub
        if p.is_symlink() or (p.exists() and not p.is_dir()):
            raise InputError(f"{p} is not a folder facadeforge made (a link or a file); "
                             "give a new -o folder")
    out.mkdir(parents=True, exist_ok=True)
    lock = _lock(out)
    try:
        _check_config(out, config)
    except BaseException:
        lock.close()
        raise
    return lock


def _check_config(out: Path, config: dict) -> None:
    """Compare an existing ``batch.json`` with this run's; write this run's."""
    previous = out / BATCH_FILE
    if previous.is_file():
        try:
            old = json.loads(previous.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"{previous} is unreadable ({exc}); give a new -o folder, or "
                             f"delete {out} to start over") from None
        changed = _changed(old, config)
        if changed:
            raise InputError(f"output folder {out} holds a batch made with {changed}; a rerun "
                             "resumes only the same command: give a new -o folder, or delete "
                             f"{out} to start over")
    tmp = out / f".{BATCH_FILE}.{os.getpid()}.part"
    tmp.write_text(json.dumps(config, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, out / BATCH_FILE)


def _changed(old: dict, new: dict) -> str | None:
    """What differs between an OUTDIR's ``batch.json`` and this run, in the user's words."""
    if old.get("written_by") != new["written_by"]:
        return f"another command ({old.get('written_by')}; this is {new['written_by']})"
    if old.get("layout", 1) != new["layout"]:
        return (f"an older facadeforge whose folders have layout {old.get('layout', 1)} (this "
                f"one writes layout {new['layout']})")
    if old.get("rules_hash") != new["rules_hash"]:
        return (f"other rules (was {old.get('rules')}, sha256 {str(old.get('rules_hash'))[:12]}"
                f"…; now {new['rules']}, {new['rules_hash'][:12]}…)")
    was, now = old.get("options") or {}, new["options"]
    diff = [k for k in now if was.get(k) != now[k]]
    if diff:
        flag = {"attrs": "--attr"}
        return "other options (" + ", ".join(
            f"{flag.get(k, '--' + k.replace('_', '-'))} was {was.get(k)!r}, now {now[k]!r}"
            for k in diff) + ")"
    if old.get("input_hash") != new["input_hash"]:
        what = "models" if "models" in new else "footprints"
        return (f"other {what} (was {', '.join(map(str, old.get(what) or []))}; "
                "these files or their contents differ)")
    if old.get("version") != new["version"]:
        return f"another facadeforge version ({old.get('version')}; this is {new['version']})"
    return None


def _done(out: Path, chunk: Chunk, spec: dict) -> dict | None:
    """The chunk's manifest entry when it is finished with these inputs and its files exist."""
    try:
        entry = json.loads((out / "manifest" / f"{chunk.name}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    ok = (isinstance(entry, dict) and entry.get("input_hash") == chunk.input_hash
          and entry.get("rules_hash") == spec["rules_hash"]
          and entry.get("options_hash") == spec["options_hash"]
          and entry.get("version") == spec["version"])
    if not ok:
        return None
    files = entry.get("files") or {}
    for rel in files.values():
        if rel is not None and not (out / rel).is_file():
            return None
    for rel in entry.get("folders") or []:
        if not (out / rel).is_dir():
            return None
    return entry


def _client(scheduler: str | None, workers: int | None):
    """A Dask client: of the cluster at ``scheduler``, else of a local cluster of processes on
    127.0.0.1 (one thread each, no dashboard).  Returns ``(client, cluster or None)``."""
    import logging

    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:   # pragma: no cover - a dependency
        raise InputError(f"batch needs dask.distributed ({exc}); run `make env`") from None
    logging.getLogger("distributed").setLevel(logging.ERROR)
    if scheduler:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler ({exc}); "
                             "start one with `dask scheduler` and workers with `dask worker "
                             f"{scheduler}`, or leave --scheduler out for a local cluster"
                             ) from None
    n = workers if workers is not None else (os.cpu_count() or 1)
    if n < 1:
        raise InputError(f"--workers {n}: give at least 1")
    # no dashboard; the scheduler's HTTP server (health and metrics routes, which it always
    # starts, on 8787 unless told) on a free port of the loopback: runs side by side never fight
    # and no statistical profiler in the workers: it walks the deep stacks of a derivation
    # every 10 ms (docs/city.md: the figures, and how to do the same on a cluster)
    import dask

    with dask.config.set({"distributed.worker.profile.enabled": False}):
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None, scheduler_port=0,
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                               silence_logs=logging.ERROR)
    return Client(cluster), cluster


def batch(rules, footprints: Sequence[str | os.PathLike], outdir: str | os.PathLike, *,
          scheduler: str | None = None, workers: int | None = None, chunk: int = 50,
          attrs: dict | None = None, seed: int = 0, style: str | None = None,
          assets=None, start: str | None = None, rule: str | None = None,
          strict: bool = False, limits=None,
          progress: bool = True) -> BatchResult:
    """Derive CGA rules on a city's footprints on a Dask cluster, into a resumable output folder
    (module docstring).

    Parameters
    ----------
    rules : path
        ``.cga`` file or ``.rpk`` package; every worker must be able to read it at this path.
    footprints : sequence of path
        GeoJSON/OBJ footprint files.
    outdir : path
        Output folder (made if missing; resumed when it holds this batch).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); by default a local cluster.
    workers : int, optional
        Worker processes of the local cluster (default: all cores).
    chunk : int
        Buildings a task (and a 3D tile).
    attrs, seed, style, assets, start, rule, strict, limits
        As for :func:`facadeforge.derive`.
    progress : bool
        Buildings/s and ETA on stderr.

    Returns
    -------
    BatchResult

    Raises
    ------
    InputError, RuleError, RuleSyntaxError
        Unusable inputs or OUTDIR (before any work); a chunk that could not be written (its
        message names it; a rerun retries it).
    """
    from .. import __version__
    from ..engine import _queries_neighbours, load_rules
    from ..geometry.footprints import load_footprints
    from ..grammar.interpreter import Limits

    t0 = time.perf_counter()
    out = Path(outdir)
    rules_path = Path(rules)
    if not footprints:
        raise InputError("give footprints: --footprint FILE (one or more files)")
    check_cluster(scheduler, workers, chunk, "derive")
    # loaded here once too: bad rules or attributes fail at once, with the CLI's message
    loaded = load_rules(rules_path, rule=rule, assets=assets, start=start, style=style)
    known = set(loaded.ruleset.main.attrs)
    for k in (attrs or {}):
        if "." not in k and k not in known and k != "seed":
            raise RuleError(f"--attr {k}: the rules have no attribute '{k}' (it has: "
                            f"{', '.join(sorted(known)[:8]) or 'none'})")
    read_hash = rules_hash(rules_path, loaded, assets, skip=out)
    halo = HALO_M if _queries_neighbours(loaded) else None
    del loaded
    paths = [Path(f) for f in footprints]
    sets = [load_footprints(p) for p in paths]
    chunks = plan_chunks(sets, chunk, halo_m=halo)
    del sets
    limits = limits or Limits()
    options = {"attrs": dict(attrs or {}), "seed": int(seed), "style": style, "start": start,
               "rule": rule, "strict": bool(strict), "chunk": int(chunk)}
    options_hash = hashlib.sha256(json.dumps(options, sort_keys=True, default=str).encode()
                                  ).hexdigest()
    input_hash = hashlib.sha256("".join(c.input_hash for c in chunks).encode()).hexdigest()
    config = {"written_by": "facadeforge batch", "layout": LAYOUT, "version": __version__,
              "rules": str(rules_path), "rules_hash": read_hash,
              "footprints": [str(p) for p in paths], "input_hash": input_hash,
              "options": options, "chunks": len(chunks),
              "buildings": sum(len(c.footprints) for c in chunks)}
    inputs = [("rules", rules_path), *(("--footprint", p) for p in paths)]
    if assets:
        inputs.append(("--assets", Path(assets)))
    spec = {"rules": str(rules_path.resolve()), "rules_hash": config["rules_hash"],
            "rule": rule, "assets": str(Path(assets).resolve()) if assets else None,
            "start": start, "style": style, "attrs": dict(attrs or {}), "seed": int(seed),
            "strict": bool(strict), "limits": limits, "options_hash": options_hash,
            "version": __version__, "outdir": str(out.resolve())}
    result, _ = run_chunks(out, config, inputs, spec, chunks, scheduler, workers, progress)
    result.seconds = time.perf_counter() - t0
    return result


def check_cluster(scheduler: str | None, workers: int | None, chunk: int, what: str) -> None:
    """Refuse cluster options that cannot work, before any input is read."""
    if scheduler and workers is not None:
        raise InputError(f"--workers sizes the local cluster; with --scheduler {scheduler} the "
                         f"cluster's own workers {what} (start more with `dask worker "
                         f"{scheduler}`): leave --workers out")
    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers}: give at least 1")
    if chunk < 1:
        raise InputError(f"--chunk {chunk}: give a positive number of buildings a chunk")


def run_chunks(out: Path, config: dict, inputs, spec: dict, chunks: list[Chunk], scheduler,
               workers, progress, task=None, label: str = "batch"
               ) -> tuple[BatchResult, list[dict]]:
    """The driver both ``batch`` and ``enhance --batch`` run: lock and check the OUTDIR
    (``config`` against its ``batch.json``), keep the chunks whose manifest entries match,
    run ``task`` (:func:`derive_chunk` by default) for the others on the cluster, then merge
    ``buildings.csv`` and the tileset.  Returns the result and the chunks' manifest entries in
    chunk order."""
    lock = _prepare_outdir(out, config, inputs)
    try:
        from ..scratch import remove_stale

        remove_stale(out / _WORK, _SCRATCH)      # chunks of a killed run's dead workers
        entries: dict[int, dict] = {}
        todo = []
        for c in chunks:
            e = _done(out, c, spec)
            if e is not None:
                entries[c.id] = e
            else:
                todo.append(c)
        skipped = len(entries)
        errors = []
        if todo:
            errors = _run(spec, todo, entries, scheduler, workers, progress, len(chunks),
                          task or derive_chunk, label)
        result = BatchResult(out, len(chunks), skipped, len(todo) - len(errors),
                             sum(e["buildings"] for e in entries.values()))
        result.failed = [(e["name"], f["building"], f["error"])
                         for _, e in sorted(entries.items()) for f in e["failed"]]
        result.notes = [(e["name"], n) for _, e in sorted(entries.items())
                        for n in e.get("notes", [])]
        if errors:
            shown = "; ".join(errors[:2]) + (f" and {len(errors) - 2} more" if len(errors) > 2
                                             else "")
            raise InputError(f"{len(errors)} of {len(chunks)} chunks failed ({shown}); the "
                             "others are kept: run the same command again to retry them")
        ordered = [entries[c.id] for c in chunks]
        result.files = _merge(out, ordered)
        return result, ordered
    finally:
        lock.close()


def _run(spec, todo: list[Chunk], entries: dict, scheduler, workers, progress,
         n_chunks: int, task=derive_chunk, label: str = "batch") -> list[str]:
    """Run ``task(spec, chunk)`` for the chunks ``todo`` on the cluster (:func:`derive_chunk`;
    ``enhance``'s own task); fill ``entries``; return one message per failed chunk."""
    from distributed import as_completed

    n_local = min(workers or os.cpu_count() or 1, len(todo))
    client, cluster = _client(scheduler, None if scheduler else n_local)
    bar = _Progress(sum(len(c.footprints) for c in todo), label=label) if progress else None
    errors = []
    try:
        futures = {client.submit(task, spec, c, key=f"facadeforge-{label}-{c.name}-"
                                 f"{c.input_hash[:12]}", pure=False): c for c in todo}
        done = len(entries)
        for fut in as_completed(futures):
            c = futures[fut]
            try:
                entry = fut.result()
            except Exception as exc:  # noqa: BLE001 - a chunk's failure, the others go on
                errors.append(f"chunk {c.name}: {_message(exc)}")
                continue
            finally:
                done += 1
            entries[c.id] = entry
            if bar is not None:
                bar.update(entry["buildings"], done, n_chunks)
    finally:
        if bar is not None:
            bar.close()
        client.close()
        if cluster is not None:
            cluster.close()
    return errors


def _building_bounds(stats_text: str) -> np.ndarray:
    """(N, 2, 3) bounds of the buildings a chunk made (the text of its ``buildings.csv``;
    models' axes), for the coarse blocks of the tileset's parents."""
    rows = csv.DictReader(io.StringIO(stats_text))
    out = []
    for r in rows:
        try:
            lo = [float(r[f"min_{a}"]) for a in "xyz"]
            hi = [float(r[f"max_{a}"]) for a in "xyz"]
        except (KeyError, TypeError, ValueError):  # a failed building: no bounds
            continue
        out.append((lo, hi))
    return np.asarray(out, float).reshape(-1, 2, 3)


def _merge(out: Path, entries: list[dict]) -> list[Path]:
    """``buildings.csv`` from the chunks' rows and ``tiles/tileset.json`` from their glTFs, each
    written to a temporary name and renamed into place."""
    from .tileset import ContentTile, enu_transform, write_tileset

    tmp = out / f".buildings.csv.{os.getpid()}.part"
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(STATS_COLUMNS) + "\n")
        stats = {}
        for e in entries:
            text = stats[e["chunk"]] = (out / e["files"]["stats"]).read_text(encoding="utf-8")
            fh.write(text.split("\n", 1)[1] if "\n" in text else "")
    os.replace(tmp, out / "buildings.csv")
    files = [out / "buildings.csv"]
    with_glb = [e for e in entries if e["files"].get("glb")]
    if with_glb:
        base = np.asarray(with_glb[0].get("origin_offset") or [0.0, 0.0, 0.0], float)
        tiles = []
        for e in with_glb:
            off = np.asarray(e.get("origin_offset") or [0.0, 0.0, 0.0], float) - base
            tiles.append(ContentTile(Path(e["files"]["glb"]).name, e["bbox"][0], e["bbox"][1],
                                     (off[0], -off[2], off[1]),
                                     buildings=_building_bounds(stats[e["chunk"]])))
        transform = None
        crs, unit = with_glb[0].get("crs"), with_glb[0].get("unit")
        if crs is not None and unit in (None, 1, 1.0):
            try:
                transform = enu_transform(base[0], -base[2], base[1], int(crs))
            except (ValueError, TypeError):
                transform = None    # stays in local coordinates (docs/city.md)
        files.append(write_tileset(out / "tiles" / "tileset.json", tiles, transform=transform))
    return files
