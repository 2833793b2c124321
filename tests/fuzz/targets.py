"""Fuzz targets: for each kind of input, how a case is drawn, how its files are written and
which command runs on them."""

from __future__ import annotations

import io
import json
import random
import struct
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import corpus
from . import mutate as M

OUTPUTS = ["glb", "obj", "city.json", "city.jsonl", "png", "svg"]
LOTS = ["12x9", "10x6", "1x1", "0.01x0.01", "1e-9x1", "1000x3", "1e6x1e6", "1e9x1", "1e300x1",
        "0x5", "-3x4", "nanx1", "infxinf", "3x", "x", "12 x 9", "1e309x2"]
ATTR_VALUES = ["1e300", "-1e300", "nan", "inf", "0", "-1", "1e9", "", '"x"', "true", "1e-300",
               "[1,2]", "abc", "1" * 400]


@dataclass
class Case:
    target: str
    seed: str
    steps: list[tuple[str, int]]
    options: dict = field(default_factory=dict)
    literal: str | bytes | None = None   # the final input itself (set while reducing text)

    def __repr__(self) -> str:
        lit = "" if self.literal is None else f", literal={self.literal!r}"[:2000]
        return (f"Case({self.target!r}, seed={self.seed!r}, steps={self.steps!r}, "
                f"options={self.options!r}{lit})")


def _steps(rng: random.Random, names, lo=1, hi=4) -> list[tuple[str, int]]:
    return [(rng.choice(names), rng.randrange(2**31)) for _ in range(rng.randint(lo, hi))]


def _bytes_step(name, mutator):
    """A byte mutator applied to text through its UTF-8 bytes (invalid UTF-8 survives)."""
    def step(rng, text):
        data = mutator(rng, text.encode("utf-8", "surrogateescape"))
        return data.decode("utf-8", "surrogateescape")
    step.__name__ = name
    return step


TEXT_BYTE_STEPS = {f"bytes_{k}": _bytes_step(k, M.BYTE_MUTATORS[k])
                   for k in ("flip_bits", "set_bytes", "insert_random")}


def _write_text(path: Path, text: str) -> Path:
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    return path


class Target:
    name = ""
    text = False            # its main input is text that the reducer may cut line by line
    defaults: dict = {}     # options the reducer tries in place of drawn ones

    def generate(self, rng: random.Random) -> Case:
        raise NotImplementedError

    def build(self, case: Case):
        """The case's main input, after its steps (or its literal)."""
        raise NotImplementedError

    def materialize(self, case: Case, work: Path, limits=(), forks=False
                    ) -> tuple[list[str], list[Path], bool]:
        """Write the case's files into ``work``; the command line (``limits``: extra derive
        options; ``forks``: worker processes allowed), the files a success must have written,
        and whether stdout is ``--stats`` JSON."""
        raise NotImplementedError

    def _apply(self, value, steps, table):
        for name, s in steps:
            value = table[name](random.Random(s), value)
        return value


def _derive_options(rng: random.Random, options: dict) -> dict:
    options.setdefault("output", rng.choice(OUTPUTS))
    if rng.random() < 0.2:
        options["stats"] = True
    if rng.random() < 0.15:
        options["seed"] = rng.choice([0, 1, -1, 2**63, 2**70])
    if rng.random() < 0.1:
        options["strict"] = True
    return options


def _derive_argv(rules: Path, work: Path, options: dict, limits, forks: bool):
    out = work / f"out.{options['output']}"
    argv = ["derive", str(rules), "-o", str(out), *limits]
    if "footprint" in options:
        argv += ["--footprint", str(options["footprint"])]
    else:
        argv.append(f"--lot={options.get('lot', '12x9')}")   # "=": a lot may start with "-"
    for k, v in options.get("attrs", []):
        argv.append(f"--attr={k}={v}")
    if options.get("start"):
        argv.append(f"--start={options['start']}")
    if options.get("stats"):
        argv.append("--stats")
    if options.get("strict"):
        argv.append("--strict")
    if "seed" in options:
        argv.append(f"--seed={options['seed']}")
    if "rule" in options:
        argv.append(f"--rule={options['rule']}")
    # an in-process run forks no worker pool: more than one worker only in a child process
    argv += ["--workers", str(options.get("workers", 1) if forks else 1)]
    return argv, [out], bool(options.get("stats"))


class CGA(Target):
    name = "cga"
    text = True
    defaults = {"output": "glb", "lot": "12x9"}
    table = {**M.CGA_MUTATORS, **TEXT_BYTE_STEPS}

    def generate(self, rng):
        seed = rng.choice(sorted(corpus.CGA_SEEDS))
        names = [k for k in sorted(M.CGA_MUTATORS) for _ in range(M.CGA_WEIGHTS.get(k, 1))]
        names += sorted(TEXT_BYTE_STEPS) if rng.random() < 0.1 else []
        options = _derive_options(rng, {"lot": rng.choice(LOTS) if rng.random() < 0.1 else "12x9"})
        if rng.random() < 0.2:
            options["attrs"] = [(rng.choice(["height", "floorH", "n", "roof", "widths", "nope",
                                             "F.x", ""]), rng.choice(ATTR_VALUES))]
        if rng.random() < 0.1:
            options["start"] = rng.choice(["Lot", "Facade", "Nope", "Roof"])
        return Case(self.name, seed, _steps(rng, names, 1, rng.choice([1, 2, 3, 5])), options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        return self._apply(corpus.CGA_SEEDS[case.seed], case.steps, self.table)

    def materialize(self, case, work, limits=(), forks=False):
        rules = _write_text(work / "rules.cga", self.build(case))
        return _derive_argv(rules, work, case.options, limits, forks)


GML_EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "facadeforge" / "gml" / "examples"
#: Words of the GML dialect the token mutators insert (docs/gml.md).
GML_TOKENS = ["ShapeGrammar.Tools.init", "scope", "move", "scale", "extrude", "split", "split-r",
              "repeat", "subdivide", "terminal-box", "terminal-void", "label", "finish", "dup",
              "exch", "pop", "roll", "index", "add", "sub", "mul", "div", "if", "ifelse", "for",
              "forall", "loop", "exit", "exec", "def", "begin", "end", "cp-plane", "cp-shell",
              "/X", "/Y", "/Z", "[", "]", "{", "}", "(1,2,3)", "(0,0,-1e300)", "-1", "1e9",
              "!x", ":x", "/window", "0", "-0.5", "1e-12"]


def _gml_steps():
    import functools

    steps = {**M.TEXT_MUTATORS, **TEXT_BYTE_STEPS}
    steps["insert_token"] = functools.partial(M.insert_token, words=GML_TOKENS)
    steps["replace_token"] = functools.partial(M.replace_token, words=GML_TOKENS)
    return steps


class GML(Target):
    """GML programs (CityFit §5) through ``facadeforge derive PROGRAM.gml``: the examples,
    mutated token by token and byte by byte."""

    name = "gml"
    text = True
    defaults = {"output": "glb"}
    table = _gml_steps()

    def generate(self, rng):
        seeds = sorted(p.name for p in GML_EXAMPLES.glob("*.gml"))
        names = sorted(M.TEXT_MUTATORS) * 3 + sorted(TEXT_BYTE_STEPS)
        options = _derive_options(rng, {})
        if rng.random() < 0.3:
            options["lot"] = rng.choice(LOTS)
        return Case(self.name, rng.choice(seeds), _steps(rng, names, 1, 5), options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        text = (GML_EXAMPLES / case.seed).read_text(encoding="utf-8")
        return self._apply(text, case.steps, self.table)

    def materialize(self, case, work, limits=(), forks=False):
        program = _write_text(work / "program.gml", self.build(case))
        argv, outs, stats = _derive_argv(program, work, case.options, limits, forks)
        if "lot" not in case.options:                    # a program that makes its own scope
            argv = [a for a in argv if not a.startswith("--lot=")]
        return argv, outs, stats


FAST_RULES = """Lot --> extrude(4) comp(f) { top : roofHip(30) R | side : split(x) { ~3 : W }* | all : NIL }
R --> color("#884433")
W --> color("#ddccbb") report("w", scope.sx)
"""


class GeoJSON(Target):
    name = "geojson"
    text = True
    defaults = {"output": "glb"}
    table = {**M.JSON_MUTATORS, **M.TEXT_MUTATORS, **TEXT_BYTE_STEPS,
             "json_deep_text": M.json_deep_text}

    def generate(self, rng):
        seed = rng.choice(sorted(corpus.GEOJSON_SEEDS))
        steps = _steps(rng, sorted(M.JSON_MUTATORS), 1, 4)
        if rng.random() < 0.3:
            steps += _steps(rng, sorted(M.TEXT_MUTATORS) + sorted(TEXT_BYTE_STEPS)
                            + ["json_deep_text"], 1, 2)
        options = _derive_options(rng, {})
        if rng.random() < 0.2:
            options["workers"] = 2
        options["suffix"] = rng.choice([".geojson"] * 4 + [".json"])
        return Case(self.name, seed, steps, options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        value = json.loads(json.dumps(corpus.GEOJSON_SEEDS[case.seed]))
        for name, s in case.steps:
            f = self.table[name]
            if name in M.JSON_MUTATORS:
                if isinstance(value, str):
                    try:
                        value = json.loads(value)
                    except ValueError:
                        continue
            elif not isinstance(value, str):
                value = M.dumps(value)
            value = f(random.Random(s), value)
        return value if isinstance(value, str) else M.dumps(value)

    def materialize(self, case, work, limits=(), forks=False):
        rules = _write_text(work / "rules.cga", FAST_RULES)
        fp = _write_text(work / f"lots{case.options.get('suffix', '.geojson')}", self.build(case))
        return _derive_argv(rules, work, {**case.options, "footprint": fp}, limits, forks)


class OBJFootprint(Target):
    name = "obj"
    text = True
    defaults = {"output": "glb"}
    table = {**M.OBJ_MUTATORS, **TEXT_BYTE_STEPS}

    def generate(self, rng):
        names = sorted(M.OBJ_MUTATORS) * 3 + sorted(TEXT_BYTE_STEPS)
        options = _derive_options(rng, {})
        if rng.random() < 0.3:
            options["mtl"] = rng.choice(["newmtl x\nKd 1 0 0\n", "newmtl x\nKd nan 1e300\nmap_Kd ../../etc/passwd\n",
                                         "\x00\xff", "newmtl\n" * 100])
        return Case(self.name, "lots", _steps(rng, names, 1, 5), options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        return self._apply(corpus.OBJ_FOOTPRINT, case.steps, self.table)

    def materialize(self, case, work, limits=(), forks=False):
        rules = _write_text(work / "rules.cga", FAST_RULES)
        text = self.build(case)
        if "mtl" in case.options:
            text = "mtllib lots.mtl\nusemtl x\n" + text
            _write_text(work / "lots.mtl", case.options["mtl"])
        fp = _write_text(work / "lots.obj", text)
        return _derive_argv(rules, work, {**case.options, "footprint": fp}, limits, forks)


# -- classifier files ------------------------------------------------------------------------

def _meta_json(rng, value):
    meta, arrays, comp = value
    if isinstance(meta, bytes):
        return value
    meta = rng.choice(list(M.JSON_MUTATORS.values()))(rng, json.loads(json.dumps(meta)))
    return meta, arrays, comp


def _meta_kind(rng, value):
    meta, arrays, comp = value
    if isinstance(meta, dict):
        meta = {**meta, rng.choice(["kind", "label_set", "version", "format"]): rng.choice(
            ["forest", "autocontext", "convnet", "ensemble", "gmm", "nope", "cmp6", "cmp12", 2, 0,
             None, 1e300, "ecp7"])}
    return meta, arrays, comp


def _meta_text(rng, value):
    meta, arrays, comp = value
    text = meta.decode("utf-8", "replace") if isinstance(meta, bytes) else json.dumps(meta)
    mutator = rng.choice([M.truncate, M.delete_span, M.duplicate_span, M.insert_token])
    if mutator is M.insert_token:
        text = M.insert_token(rng, text, ["NaN", "Infinity", "[" * 5000, "{", "}", ",", '"', "\\u0000", "1e999"])
    else:
        text = mutator(rng, text)
    return text.encode(), arrays, comp


def _array_edit(rng, value):
    meta, arrays, comp = value
    arrays = dict(arrays)
    names = sorted(arrays)
    kind = rng.randrange(7)
    if kind == 0 and names:
        arrays.pop(rng.choice(names))
    elif kind == 1 and names:  # not finite
        k = rng.choice(names)
        a = arrays[k].astype(float).copy()
        if a.size:
            a.flat[rng.randrange(a.size)] = rng.choice([np.nan, np.inf, -np.inf, 1e300, 0.0, -1.0])
        arrays[k] = a
    elif kind == 2 and names:  # another shape
        k = rng.choice(names)
        arrays[k] = rng.choice([np.zeros(0), np.zeros((0, 3)), np.ones((2, 5)), np.ones(3),
                                np.ones((1, 1, 1, 1)), np.float64(1.0), np.ones((3, 1, 3))])
    elif kind == 3 and names:  # another dtype
        k = rng.choice(names)
        arrays[k] = arrays[k].astype(rng.choice([np.int8, np.float16, np.complex128, np.bool_,
                                                 np.uint64, ">f8"]))
    elif kind == 4:
        arrays[rng.choice(["extra", "weights", "means", "trees", "__meta__x"])] = np.arange(4.0)
    elif kind == 5 and names:  # singular or negative covariances, zero weights
        k = rng.choice(names)
        arrays[k] = arrays[k] * rng.choice([0.0, -1.0, 1e-300, 1e300])
    elif names:
        k = rng.choice(names)
        arrays[k] = np.repeat(arrays[k], rng.choice([2, 50]), axis=0)
    return meta, arrays, comp


def _giant_header(rng, value):
    """A member whose .npy header declares far more data than there is."""
    data = _npz(value)
    buf = io.BytesIO()
    try:
        zin = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        return data   # an earlier step broke the archive: nothing to rewrite
    with zin, zipfile.ZipFile(buf, "w") as zout:
        names = zin.namelist()
        victim = rng.choice(names)
        for n in names:
            if n == victim:
                h = io.BytesIO()
                shape = rng.choice([(2**32,), (2**20, 2**20), (10**6, 3), (-1,), (0, 2**62)])
                try:
                    np.lib.format.write_array_header_1_0(
                        h, {"descr": rng.choice(["<f8", "|u1", "|O", "<U10"]),
                            "fortran_order": False, "shape": shape})
                except ValueError:
                    h.write(b"\x93NUMPY\x01\x00\x10\x00{'shape': (-1,)}  \n")
                zout.writestr(n, h.getvalue() + _read(zin, n)[128:][:64])
            else:
                zout.writestr(n, _read(zin, n))
    return buf.getvalue()


def _read(z: zipfile.ZipFile, name: str) -> bytes:
    try:
        return z.read(name)
    except Exception:  # noqa: BLE001 - a damaged member: its bytes as they are
        return b""


def _npz(value) -> bytes:
    if isinstance(value, bytes):
        return value
    meta, arrays, comp = value
    return corpus.npz_bytes(meta, arrays, comp)


def _on_bytes(mutator):
    return lambda rng, value: mutator(rng, _npz(value))


NPZ_STRUCTURE = {"meta_json": _meta_json, "meta_kind": _meta_kind, "meta_text": _meta_text,
                 "array_edit": _array_edit}
NPZ_BYTES = {"giant_header": _giant_header,
             **{f"npz_{k}": _on_bytes(v) for k, v in M.BYTE_MUTATORS.items()}}


class Classifier(Target):
    name = "npz"
    defaults = {"command": "reconstruct"}
    table = {**NPZ_STRUCTURE, **NPZ_BYTES}

    def generate(self, rng):
        steps = _steps(rng, sorted(NPZ_STRUCTURE), 0, 2)
        if rng.random() < 0.4 or not steps:
            steps += _steps(rng, sorted(NPZ_BYTES), 1, 2)
        options = {"compressed": rng.random() < 0.5,
                   "command": "parse" if rng.random() < 0.05 else "reconstruct"}
        return Case(self.name, "gmm", steps, options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        meta, arrays = corpus.classifier_parts()
        value = (meta, arrays, case.options.get("compressed", False))
        for name, s in case.steps:
            if isinstance(value, bytes) and name in NPZ_STRUCTURE:
                continue
            value = self.table[name](random.Random(s), value)
        return _npz(value)

    def materialize(self, case, work, limits=(), forks=False):
        photo = corpus.photo_png(work / "photo.png")
        npz = work / "model.npz"
        npz.write_bytes(self.build(case))
        out = work / "out"
        if case.options.get("command") == "parse":
            argv = ["parse", str(photo), "--rectified", "--classifier", str(npz), "--budget", "3",
                    "-o", str(out)]
        else:
            argv = ["reconstruct", str(photo), "--rectified", "--classifier", str(npz), "-o",
                    str(out)]
        return argv, [out], False


# -- rule packages ---------------------------------------------------------------------------

UNSAFE_NAMES = ["../evil.cga", "/abs/main.cga", "rules\\win.cga", "rules/" + "d/" * 60 + "x.cga",
                "rules/.hidden.cga", "rules/ünï©ødé.cga", "rules/main.cga/x", "", ".", "rules/",
                "a" * 250 + ".cga", "rules/../rules/main.cga", "C:\\x.cga", "rules/ma\x00in.cga"]
XML_SPECIALS = [
    '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">'
    '<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;"><!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">]>'
    '<resolvemap><entry key="&d;" value="assets/box.obj"/></resolvemap>',
    '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
    '<resolvemap><entry key="/Proj/assets/box.obj" value="&x;"/></resolvemap>',
    '<resolvemap><entry key="/Proj/assets/box.obj" value="../../../etc/passwd"/></resolvemap>',
    '<resolvemap><entry key="/Proj/assets/box.obj" value="/etc/passwd"/></resolvemap>',
    '<resolvemap><entry key="/Proj/assets/box.obj" value="rules/main.cga"/></resolvemap>',
    '<resolvemap>' + '<entry key="k" value="assets/box.obj"/>' * 10000 + '</resolvemap>',
    '<resolvemap><entry', '', '\x00\xff', '<' * 100000]


def _member_edit(kind):
    def step(rng, members):
        members = dict(members)
        names = sorted(members)
        if kind == "cga":
            k = rng.choice([n for n in names if n.endswith(".cga")] or names)
            text = members[k].decode("utf-8", "surrogateescape")
            for _ in range(rng.randint(1, 3)):
                text = rng.choice(list(M.CGA_MUTATORS.values()))(rng, text)
            members[k] = text.encode("utf-8", "surrogateescape")
        elif kind == "obj":
            k = "assets/box.obj" if "assets/box.obj" in members else rng.choice(names)
            text = members[k].decode("utf-8", "surrogateescape")
            members[k] = rng.choice(list(M.OBJ_MUTATORS.values()))(rng, text).encode(
                "utf-8", "surrogateescape")
        elif kind == "resolvemap":
            members[".resolvemap.xml"] = rng.choice(XML_SPECIALS).encode("utf-8", "surrogateescape")
        elif kind == "rename":
            k = rng.choice(names)
            members[rng.choice(UNSAFE_NAMES)] = members.pop(k)
        elif kind == "drop":
            members.pop(rng.choice(names))
        elif kind == "many":
            for i in range(rng.choice([50, 2000])):
                members[f"rules/gen{i}.cga"] = f"R{i} --> X.\n".encode()
        elif kind == "big":
            members["assets/big.obj"] = b"v 0 0 0\n" * rng.choice([10_000, 1_000_000])
        return members
    return step


def _pack(value) -> bytes:
    if isinstance(value, bytes):
        return value
    import py7zr

    buf = io.BytesIO()
    with py7zr.SevenZipFile(buf, "w") as z:
        for name, data in value.items():
            try:
                z.writef(io.BytesIO(data), name)
            except Exception:  # noqa: BLE001 - a name py7zr will not write: leave it out
                pass
    return buf.getvalue()


RPK_STRUCTURE = {f"member_{k}": _member_edit(k)
                 for k in ("cga", "cga", "obj", "resolvemap", "rename", "drop", "many", "big")}
RPK_BYTES = {f"rpk_{k}": (lambda m: lambda rng, v: m(rng, _pack(v)))(v)
             for k, v in M.BYTE_MUTATORS.items()}


class RulePackage(Target):
    name = "rpk"
    defaults = {"output": "glb"}
    table = {**RPK_STRUCTURE, **RPK_BYTES}

    def generate(self, rng):
        steps = _steps(rng, sorted(RPK_STRUCTURE), 1, 3)
        if rng.random() < 0.35:
            steps += _steps(rng, sorted(RPK_BYTES), 1, 2)
        options = _derive_options(rng, {})
        if rng.random() < 0.2:
            options["rule"] = rng.choice(["rules/main.cga", "rules/facade.cga", "../x.cga",
                                          "/etc/passwd", "rules", "nope.cga"])
        return Case(self.name, "project", steps, options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        value = corpus.rpk_members()
        for name, s in case.steps:
            if isinstance(value, bytes) and name in RPK_STRUCTURE:
                continue
            value = self.table[name](random.Random(s), value)
        return _pack(value)

    def materialize(self, case, work, limits=(), forks=False):
        rpk = work / "rules.rpk"
        rpk.write_bytes(self.build(case))
        return _derive_argv(rpk, work, {**case.options, "lot": "10x6"}, limits, forks)


# -- models to render ------------------------------------------------------------------------

def _glb_parts(data: bytes):
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    rest = data[20 + jlen:]
    return doc, rest


def _glb_join(doc, rest: bytes) -> bytes:
    text = M.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _glb_json(rng, data: bytes) -> bytes:
    try:
        doc, rest = _glb_parts(data)
    except Exception:  # noqa: BLE001 - already broken: leave it
        return data
    for _ in range(rng.randint(1, 3)):
        doc = rng.choice([M.json_swap, M.json_number, M.json_delete, M.json_duplicate])(rng, doc)
    return _glb_join(doc, rest)


def _glb_accessor(rng, data: bytes) -> bytes:
    """Accessor counts, offsets, component types and buffer sizes that lie."""
    try:
        doc, rest = _glb_parts(data)
    except Exception:  # noqa: BLE001
        return data
    where = rng.choice(["accessors", "bufferViews", "buffers", "images", "textures", "nodes"])
    items = doc.get(where) or [{}]
    item = rng.choice(items)
    key = rng.choice(sorted(item) or ["count"])
    item[key] = rng.choice([0, -1, 2**31, 2**53, 10**12, 1e300, 5126, 5125, 5121, 1, "VEC3",
                            "MAT4", None, [], "data:application/octet-stream;base64,AAAA",
                            "../../etc/passwd", "file:///etc/passwd"])
    return _glb_join(doc, rest)


GLB_STEPS = {"glb_json": _glb_json, "glb_accessor": _glb_accessor, **M.BYTE_MUTATORS}
MODEL_OBJ_STEPS = {**M.OBJ_MUTATORS, **TEXT_BYTE_STEPS}
SIZES = ["64x48", "64x48", "1x1", "0x0", "-5x5", "100000x100000", "64x0", "3x2000"]


class Render(Target):
    name = "render"
    defaults = {"size": "64x48"}
    seeds: dict[str, bytes | str] = {}   # filled by prepare()

    def prepare(self, folder: Path) -> None:
        """Seed models: a building derived once, written as GLB and OBJ."""
        if self.seeds:
            return
        from facadeforge import derive, export

        rules = _write_text(folder / "seed.cga", corpus.CGA_SEEDS["insert_transform"])
        models = derive(rules, lot_size="8x6")
        export(models, folder / "seed.glb")
        export(models, folder / "seed.obj")
        self.seeds = {"glb": (folder / "seed.glb").read_bytes(),
                      "obj": (folder / "seed.obj").read_text()}
        self.extra = {p.name: p.read_bytes() for p in folder.iterdir()
                      if p.is_file() and not p.name.startswith("seed.")}
        self.extra.update({p.name: p.read_bytes() for p in folder.glob("seed.*")
                           if p.suffix not in (".cga", ".glb", ".obj")})

    def generate(self, rng):
        kind = rng.choice(["glb", "glb", "obj"])
        names = sorted(GLB_STEPS) + ["glb_json", "glb_accessor"] * 2 if kind == "glb" \
            else sorted(MODEL_OBJ_STEPS)
        options = {"size": rng.choice(SIZES) if rng.random() < 0.2 else "64x48"}
        if rng.random() < 0.15:
            options["elevation"] = rng.choice(["89", "-89", "0", "1e-300"])
            options["azimuth"] = rng.choice(["1e300", "-720", "0"])
        return Case(self.name, kind, _steps(rng, names, 1, 3), options)

    def build(self, case):
        if case.literal is not None:
            return case.literal
        table = GLB_STEPS if case.seed == "glb" else MODEL_OBJ_STEPS
        return self._apply(self.seeds[case.seed], case.steps, table)

    def materialize(self, case, work, limits=(), forks=False):
        data = self.build(case)
        model = work / f"model.{case.seed}"
        if isinstance(data, bytes):
            model.write_bytes(data)
        else:
            _write_text(model, data)
        if case.seed == "obj":   # the material and texture the seed OBJ refers to
            for name, content in self.extra.items():
                (work / name).write_bytes(content)
        out = work / "render.png"
        argv = ["render", str(model), "-o", str(out), f"--size={case.options.get('size', '64x48')}"]
        for k in ("elevation", "azimuth"):
            if k in case.options:
                argv.append(f"--{k}={case.options[k]}")
        return argv, [out], False

    extra: dict[str, bytes] = {}


TARGETS = {t.name: t for t in (CGA(), GeoJSON(), OBJFootprint(), Classifier(), RulePackage(),
                               Render(), GML())}
