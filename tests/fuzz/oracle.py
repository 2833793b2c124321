"""The oracle: run the command line on a fuzz case and judge what it did.

A run passes when it exits 0 and every file it wrote is valid (GLB, OBJ, CityJSON, PNG, SVG,
JSON, CGA), or exits 2 with ``facadeforge: error: …`` as the one last line of stderr and no file
left behind.  Exit 3 (``facadeforge: internal error``), a traceback, another exit status, an
invalid file, a run past its time bound or over its memory bound fail.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import resource
import signal
import struct
import subprocess
import sys
import time
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

ERROR_PREFIX = "facadeforge: error: "
#: The acceptance's bounds on every input: seconds and bytes of address space (the short run
#: lowers the seconds: its derivations have a 5 s budget).
HANG_SECONDS = 60
MEMORY_BYTES = 3 * 2**30


@dataclass
class Outcome:
    rc: int
    stdout: str
    stderr: str
    seconds: float
    maxrss_mb: float | None = None
    problems: list[str] = field(default_factory=list)

    @property
    def signature(self) -> str | None:
        """What went wrong, in a few words that stay the same while a case is reduced (``None``
        when the run passed)."""
        return self.problems[0] if self.problems else None

    def describe(self) -> str:
        tail = "\n".join(self.stderr.rstrip().splitlines()[-6:])
        return (f"rc={self.rc} in {self.seconds:.1f} s"
                + (f", max RSS {self.maxrss_mb:.0f} MiB" if self.maxrss_mb else "")
                + f"; problems: {'; '.join(self.problems)}\n    stderr tail: {tail!r}")


# -- validators ------------------------------------------------------------------------------

def _no_constant(name):
    raise ValueError(f"non-standard JSON constant {name}")


def strict_json(text: str | bytes):
    return json.loads(text, parse_constant=_no_constant)


def _finite(values, what: str) -> None:
    a = np.asarray(values, float)
    if a.size and not np.isfinite(a).all():
        raise ValueError(f"{what}: not finite")


GLTF_COMPONENTS = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
GLTF_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def check_glb(path: Path) -> None:
    import pygltflib

    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data)
    if magic != b"glTF" or version != 2 or length != len(data):
        raise ValueError("bad GLB header")
    jlen, jtype = struct.unpack_from("<II", data, 12)
    if jtype != 0x4E4F534A:
        raise ValueError("first chunk is not JSON")
    doc = strict_json(data[20:20 + jlen])
    blob = b""
    if 20 + jlen < len(data):
        blen, btype = struct.unpack_from("<II", data, 20 + jlen)
        blob = data[28 + jlen:28 + jlen + blen]
        if btype != 0x004E4942 or len(blob) != blen:
            raise ValueError("bad BIN chunk")
    pygltflib.GLTF2.load_from_bytes(data)
    views = doc.get("bufferViews", [])
    accessors = doc.get("accessors", [])

    def values(acc):
        view = views[acc["bufferView"]]
        dtype = np.dtype(GLTF_COMPONENTS[acc["componentType"]])
        n = GLTF_SIZES[acc["type"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        stride = view.get("byteStride") or dtype.itemsize * n
        end = start + stride * (acc["count"] - 1) + dtype.itemsize * n if acc["count"] else start
        if end > view.get("byteOffset", 0) + view["byteLength"] or end > len(blob):
            raise ValueError("accessor runs past its buffer view")
        if view.get("buffer", 0) != 0:
            return None
        raw = np.frombuffer(blob, np.uint8, end - start, start)
        rows = np.lib.stride_tricks.as_strided(raw, (acc["count"], dtype.itemsize * n), (stride, 1))
        return np.ascontiguousarray(rows).view(dtype).reshape(acc["count"], n)

    for i, acc in enumerate(accessors):
        for k in ("min", "max"):
            if k in acc:
                _finite(acc[k], f"accessor {i} {k}")
        if "bufferView" in acc:
            v = values(acc)
            if v is not None and acc["componentType"] == 5126:
                _finite(v, f"accessor {i} data")
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            count = accessors[prim["attributes"]["POSITION"]]["count"]
            if "indices" in prim:
                idx = values(accessors[prim["indices"]])
                if idx is not None and idx.size and int(idx.max()) >= count:
                    raise ValueError("an index past the vertices")
    for node in doc.get("nodes", []):
        for k in ("matrix", "translation", "rotation", "scale"):
            if k in node:
                _finite(node[k], f"node {k}")


def check_obj(path: Path) -> None:
    counts = {"v": 0, "vt": 0, "vn": 0}
    faces = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        head = parts[0]
        if head in counts:
            counts[head] += 1
            nums = [float(x) for x in parts[1:]]
            if not nums or not all(math.isfinite(x) for x in nums):
                raise ValueError(f"line {n}: {line[:80]!r} has a number that is not finite")
        elif head in ("f", "l", "p"):
            faces.append((n, parts[1:]))
        elif head == "mtllib":
            if not (path.parent / " ".join(parts[1:])).is_file():
                raise ValueError(f"line {n}: mtllib {parts[1:]} is missing")
    for n, refs in faces:
        for ref in refs:
            for kind, x in zip(("v", "vt", "vn"), ref.split("/")):
                if x:
                    i = int(x)
                    if not (1 <= i <= counts[kind] or -counts[kind] <= i <= -1):
                        raise ValueError(f"line {n}: index {i} of {counts[kind]} {kind}")


@lru_cache(maxsize=1)
def cityjson_validator():
    from referencing import Registry, Resource

    schemas = Path(__file__).resolve().parents[1] / "data" / "cityjson-2.0"
    resources = []
    for file in sorted(schemas.glob("*.schema.json")):
        schema = json.loads(file.read_text())
        resources.append((schema["$id"], Resource.from_contents(schema)))
    root = json.loads((schemas / "cityjson.schema.json").read_text())
    import jsonschema

    return jsonschema.Draft7Validator(root, registry=Registry().with_resources(resources))


def _max_index(boundaries) -> int:
    if isinstance(boundaries, int):
        return boundaries
    return max((_max_index(b) for b in boundaries), default=-1)


def _check_city_objects(doc, where: str) -> None:
    verts = doc.get("vertices", [])
    if not all(len(v) == 3 and all(isinstance(c, int) for c in v) for v in verts):
        raise ValueError(f"{where}: vertices are not integer triples")
    for name, obj in doc.get("CityObjects", {}).items():
        for g in obj.get("geometry", []):
            if _max_index(g.get("boundaries", [])) >= len(verts):
                raise ValueError(f"{where}: {name} refers to a vertex past the list")


def check_cityjson(path: Path) -> None:
    doc = strict_json(path.read_text(encoding="utf-8"))
    errors = sorted(cityjson_validator().iter_errors(doc), key=str)
    if errors:
        raise ValueError(f"schema: {errors[0].message[:200]}")
    _finite(doc["transform"]["scale"] + doc["transform"]["translate"], "transform")
    _check_city_objects(doc, "CityJSON")


def check_cityjsonl(path: Path) -> None:
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines:
        raise ValueError("empty CityJSONL")
    head = strict_json(lines[0])
    if head.get("type") != "CityJSON":
        raise ValueError("first line is not a CityJSON header")
    _finite(head["transform"]["scale"] + head["transform"]["translate"], "transform")
    for i, line in enumerate(lines[1:], 2):
        feat = strict_json(line)
        if feat.get("type") != "CityJSONFeature":
            raise ValueError(f"line {i} is not a CityJSONFeature")
        _check_city_objects(feat, f"line {i}")


def check_image(path: Path) -> None:
    from PIL import Image

    with Image.open(path) as im:
        im.verify()
    with Image.open(path) as im:
        im.load()
        if im.width < 1 or im.height < 1:
            raise ValueError("empty image")


_NONFINITE = re.compile(r"(?i)(?<![a-z])(nan|inf|infinity)(?![a-z])")


def check_svg(path: Path) -> None:
    root = ET.fromstring(path.read_bytes())
    for el in root.iter():
        for k, v in el.attrib.items():
            if _NONFINITE.search(v):
                raise ValueError(f"SVG attribute {k}={v[:60]!r}")


def check_cga(path: Path) -> None:
    from facadeforge.grammar.parser import parse_rules

    parse_rules(path.read_text(encoding="utf-8"), str(path))


CHECKS = {".glb": check_glb, ".obj": check_obj, ".city.json": check_cityjson,
          ".city.jsonl": check_cityjsonl, ".png": check_image, ".jpg": check_image,
          ".jpeg": check_image, ".svg": check_svg, ".json": lambda p: strict_json(p.read_bytes()),
          ".cga": check_cga}


def check_file(path: Path) -> str | None:
    """A problem with one output file, or ``None``."""
    name = path.name.lower()
    for suffix in (".city.jsonl", ".city.json"):
        if name.endswith(suffix):
            check = CHECKS[suffix]
            break
    else:
        check = CHECKS.get(path.suffix.lower())
    if check is None:
        return None
    try:
        check(path)
    except Exception as e:  # noqa: BLE001 - any failure makes the file invalid
        return f"invalid {name.rsplit('.', 1)[-1] if '.' in name else name} output: " \
               f"{type(e).__name__}: {str(e)[:160]}"
    return None


def files_under(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if p.is_file()}


# -- judging ---------------------------------------------------------------------------------

def judge(rc: int, stdout: str, stderr: str, seconds: float, workdir: Path, before: set[Path],
          expected: list[Path], stats: bool = False, maxrss_mb: float | None = None) -> Outcome:
    out = Outcome(rc, stdout, stderr, seconds, maxrss_mb)
    new = sorted(files_under(workdir) - before)
    if "Traceback (most recent call last)" in stderr:
        exc = re.findall(r"^(\w+(?:\.\w+)*(?:Error|Exception|Exit|Interrupt)\b)", stderr, re.M)
        out.problems.append(f"traceback: {exc[-1] if exc else '?'}")
    if rc == 0:
        for p in expected:
            if not p.exists():
                out.problems.append(f"exit 0 without {p.name}")
        for p in new:
            problem = check_file(p)
            if problem:
                out.problems.append(problem)
        if stats:
            try:
                strict_json(stdout.strip().splitlines()[-1])
            except Exception as e:  # noqa: BLE001
                out.problems.append(f"--stats is not strict JSON: {type(e).__name__}")
    elif rc == 2:
        lines = [ln for ln in stderr.rstrip("\n").splitlines()
                 if not re.match(r"^\S+:\d+: \w+Warning: |^  ", ln)]   # counted above
        if not lines or not lines[-1].startswith(ERROR_PREFIX):
            out.problems.append("exit 2 without a final 'facadeforge: error:' line")
        elif len(lines) > 1 and not all(ln.startswith(("print: ", "warning: ", "footprints "))
                                        for ln in lines[:-1]):
            out.problems.append("the error takes more than one line")
        leftovers = [p.name for p in new]
        if leftovers:
            out.problems.append("a failed run left files behind")
    elif rc == 3:
        m = re.search(r"internal error: (\w+)", stderr)
        out.problems.append(f"internal error: {m.group(1) if m else '?'}")
    elif rc == -1:
        out.problems.append("no end within the time bound")
    else:
        out.problems.append(f"exit {rc}")
    warned = re.findall(r"^(\S+):(\d+): (\w+Warning): ", stderr, re.M)
    if warned:
        where, line, category = warned[0]
        out.problems.append(f"a Python {category} on stderr ({Path(where).name}:{line})")
    if maxrss_mb is not None and maxrss_mb * 2**20 > MEMORY_BYTES:
        out.problems.append(f"memory over {MEMORY_BYTES >> 30} GiB")
    return out


def _show_warning(message, category, filename, lineno, file=None, line=None):
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


class _Hang(BaseException):
    """Raised by the alarm in an in-process run past :data:`HANG_SECONDS`."""


def run_inprocess(argv: list[str], workdir: Path, expected: list[Path], stats=False) -> Outcome:
    from facadeforge.cli import main

    before = files_under(workdir)
    out, err = io.StringIO(), io.StringIO()

    def alarm(signum, frame):
        raise _Hang()

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(HANG_SECONDS)
    t0 = time.perf_counter()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
                warnings.catch_warnings():
            warnings.simplefilter("default")   # as a fresh process shows them, to stderr
            warnings.showwarning = _show_warning
            try:
                rc = main(argv)
            except _Hang:
                rc = -1
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else 1
                err.write(f"\n[fuzz] SystemExit({e.code!r}) escaped main()\n")
            except Exception as e:  # noqa: BLE001 - an exception escaping main is a failure
                import traceback

                traceback.print_exc(file=err)
                rc = 99
                err.write(f"[fuzz] {type(e).__name__} escaped main()\n")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    return judge(rc, out.getvalue(), err.getvalue(), time.perf_counter() - t0, workdir, before,
                 expected, stats)


def _limit_memory():  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))


def run_subprocess(argv: list[str], workdir: Path, expected: list[Path], stats=False) -> Outcome:
    """``facadeforge ARGV`` in a child bounded to :data:`HANG_SECONDS` and :data:`MEMORY_BYTES`
    of address space (its worker processes inherit the bound); its peak RSS from ``wait4``."""
    before = files_under(workdir)
    with open(workdir / ".fuzz-stdout", "w+b") as so, open(workdir / ".fuzz-stderr", "w+b") as se:
        before |= {workdir / ".fuzz-stdout", workdir / ".fuzz-stderr"}
        env = dict(os.environ, PYTHONFAULTHANDLER="1")
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "facadeforge.cli", *argv], stdout=so,
                                stderr=se, stdin=subprocess.DEVNULL, cwd=workdir, env=env,
                                preexec_fn=_limit_memory, start_new_session=True)
        rc, rss = None, None
        while rc is None:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                rc = os.waitstatus_to_exitcode(status)
                rss = usage.ru_maxrss / 1024
                proc.returncode = rc
            elif time.perf_counter() - t0 > HANG_SECONDS:
                os.killpg(proc.pid, signal.SIGKILL)
                _, status, usage = os.wait4(proc.pid, 0)
                proc.returncode = rc = -1
                rss = usage.ru_maxrss / 1024
            else:
                time.sleep(0.02)
        seconds = time.perf_counter() - t0
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)   # workers left behind by a killed run
        so.seek(0)
        se.seek(0)
        stdout = so.read().decode("utf-8", "replace")
        stderr = se.read().decode("utf-8", "replace")
    if rc < 0 and rc != -1:
        stderr += f"\n[fuzz] killed by signal {-rc}"
    outcome = judge(rc, stdout, stderr, seconds, workdir, before, expected, stats, rss)
    return outcome


def run_forked(argv: list[str], workdir: Path, expected: list[Path], stats=False) -> Outcome:
    """``main(argv)`` in a forked child (imports already warm): bounded to
    :data:`HANG_SECONDS` and, above what the parent holds, to the address space a fresh
    command has under :data:`MEMORY_BYTES` (2 GiB: it starts near 1 GiB); killed past them."""
    before = files_under(workdir)
    so_path, se_path = workdir / ".fuzz-stdout", workdir / ".fuzz-stderr"
    before |= {so_path, se_path}
    sys.stdout.flush()
    sys.stderr.flush()
    vsz = _vm_size()
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        code = 98
        try:
            os.setsid()
            resource.setrlimit(resource.RLIMIT_AS, (vsz + MEMORY_BYTES - 2**30,) * 2)
            with open(so_path, "w") as so, open(se_path, "w") as se:
                os.dup2(so.fileno(), 1)
                os.dup2(se.fileno(), 2)
                sys.stdout, sys.stderr = so, se
                try:
                    from facadeforge.cli import main

                    code = main(argv)
                except SystemExit as e:
                    code = e.code if isinstance(e.code, int) else 1
                    se.write(f"\n[fuzz] SystemExit({e.code!r}) escaped main()\n")
                except BaseException:  # noqa: BLE001
                    import traceback

                    traceback.print_exc(file=se)
                    code = 99
                so.flush()
                se.flush()
        finally:
            os._exit(code & 0xFF if code >= 0 else 97)
    rc = None
    while rc is None:
        wpid, status, usage = os.wait4(pid, os.WNOHANG)
        if wpid:
            rc = os.waitstatus_to_exitcode(status)
        elif time.perf_counter() - t0 > HANG_SECONDS:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGKILL)
            _, status, usage = os.wait4(pid, 0)
            rc = -1
        else:
            time.sleep(0.01)
    seconds = time.perf_counter() - t0
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, signal.SIGKILL)   # workers a killed run left behind
    stdout = so_path.read_text("utf-8", "replace") if so_path.exists() else ""
    stderr = se_path.read_text("utf-8", "replace") if se_path.exists() else ""
    if rc < 0 and rc != -1:
        stderr += f"\n[fuzz] killed by signal {-rc}"
    return judge(rc, stdout, stderr, seconds, workdir, before, expected, stats,
                 usage.ru_maxrss / 1024)


def _vm_size() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


# -- reducing --------------------------------------------------------------------------------

def ddmin(items: list, fails, budget: list[int]) -> list:
    """The classic delta-debugging minimisation of ``items`` under ``fails`` (True while the
    failure persists); ``budget[0]``: oracle calls left, decremented."""
    n = 2
    while len(items) >= 2 and budget[0] > 0:
        chunk = max(1, len(items) // n)
        parts = [items[i:i + chunk] for i in range(0, len(items), chunk)]
        reduced = False
        for i in range(len(parts)):
            if budget[0] <= 0:
                break
            rest = [x for j, p in enumerate(parts) if j != i for x in p]
            budget[0] -= 1
            if fails(rest):
                items, n, reduced = rest, max(n - 1, 2), True
                break
        if not reduced:
            if n >= len(items):
                break
            n = min(len(items), n * 2)
    if len(items) == 1 and budget[0] > 0:
        budget[0] -= 1
        if fails([]):
            return []
    return items
