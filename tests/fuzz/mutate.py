"""Mutators: each takes a ``random.Random`` and the input and returns a new input.  A fuzz case
is a seed plus a list of ``(mutator name, sub-seed)`` steps, so that it replays exactly and the
reducer can drop steps (oracle.reduce)."""

from __future__ import annotations

import json
import random
import re

# -- dictionaries --------------------------------------------------------------------------

NUMBERS = ["0", "-0", "1", "-1", "0.5", "1e300", "-1e300", "1e308", "1e-300", "1e9", "1e10",
           "1e999", "99999999999999999999999", "2147483648", "1e6", "100000", "0.000001",
           "nan", "inf", "-inf", "NaN", "3.4028235e38", "5e-324", "1/0", "0/0", "-(1e300*1e300)"]

CGA_TOKENS = [
    # structure
    "-->", "{", "}", "(", ")", "[", "]", "|", ":", "*", "~", "'", ",", ".", "=", "=:", ";",
    "NIL", "case", "else", "30%", "50%", "else :", "attr", "const", "import", "version",
    "style", "extends", "@StartRule", "@Hidden", "@Range(min=0, max=1e300)", "inline",
    "union", "subtract", "intersect", "extension", "true", "false", '"x"', '""',
    '"' + "s" * 300 + '"', "x", "Lot", "X.", "A", "B", "Rec", "scope.sx", "scope.sy",
    "split.index", "split.total", "comp.index", "geometry.area()", "initialShape.origin.px",
    # operators
    "+", "-", "/", "%", "^", "==", "!=", "<", ">=", "&&", "||", "!", ".+", ".*", ".==",
    # operations
    "extrude(1e300)", "extrude(-1e300)", "extrude(0)", "extrude(nan)", "s(0, 0, 0)",
    "s(1e300, 1e300, 1e300)", "s('0, '0, '0)", "t(1e300, 0, 0)", "t(1e10, 1e10, 1e10)",
    "r(90, 45, 1e300)", "r(scopeCenter, 0, 720, 0)", "center(xyz)", "split(x) { ~1 : X }*",
    "split(x) { 0.0000001 : Rec }*", "split(y) { '0.5 : A | ~1 : B }", "split(z) {}",
    "split(x) { 1e-300 : X }*", "comp(f) { all : A }", "comp(e) { all : A }",
    "comp(v) { all : A }", "comp(f) { top : NIL }", "offset(-1e300)", "offset(1e9)",
    "offset(-0.5) comp(f) { inside : A | border : B }", "roofHip(89.9999)", "roofHip(90)",
    "roofGable(1e300)", "roofPyramid(-30)", "roofShed(0)", "setback(1e300) { all : A }",
    "setback(-1) { front : A | remainder : B }", 'i("builtin:cube")', 'i("nope.obj")',
    'i("../../../../etc/passwd")', 'i("/etc/passwd")', 'i("builtin:cube") s(1e300, 1, 1)',
    'readTextFile("/etc/passwd")', 'fileSearch("/*")', 'fileExists("../x")',
    'texture("../../x.png")', 'color("#zzzzzz")', "color(nan, 1e300, -1)", "color(1, 0, 0)",
    'set(material.opacity, nan)', 'set(material.color.r, 1e300)', 'report("r", 1e300)',
    'report("n", 0/0)', 'print(1e300)', 'tag("t")', 'deleteTags()', 'label("l")',
    "primitiveCube", "primitiveCube(1e300, 1, 1)", "primitiveSphere(1000, 1000)",
    "primitiveCylinder(100000)", "primitiveQuad", "taper(1e300)", "envelope(normal, 1e300, 1, 45)",
    "innerRectangle(scope) { shape : A | remainder : B }", "splitArea(x) { 1e-9 : A }*",
    "scatter(surface, 1e9, uniform) { A }", "scatter(surface, 100000000, gaussian) { X. }",
    "alignScopeToAxes()", "alignScopeToGeometry(yUp, 0)", "rotateScope(0, 1e300, 0)",
    "mirrorScope(true, true, true)", "cleanupGeometry(all, 1e300)", "reduceGeometry(all, 1)",
    "convexify()", "convexify(1e-300)", "footprint()", "trim()", "modify(f) { all : t(0, 1e300, 0) }",
    "setupProjection(0, scope.xy, 0, 0)", "projectUV(0)", "tileUV(0, 0, 0)", "scaleUV(0, 1e300, 0)",
    "insertAlongUV(0, \"builtin:cube\", 1e-300)", "softenNormals(nan)", "deleteHoles()",
    "splitAndSetbackPerimeter(0) { 1 : 1e300 : A }* { remainder : B }",
    "rand(0, 1e300)", "floor(1e300)", "pow(10, 400)", "sqrt(-1)", "log(0)", "exp(1e300)",
    "len(\"x\")", "str(nan)", "float(\"nan\")", "float(\"1e999\")", "bool(\"x\")",
    "[1e300, nan]", "[1, 2; 3, 4]", "[1:1e9]", "[0:1e-300:1]", "[]", "[[]]",
    "Rec --> Rec Rec", "Rec --> split(x) { ~0.01 : Rec }*", "f(x) = f(x)", "f(x) = f(x - 1) + f(x - 2)",
    "(" * 200, ")" * 200, "[" * 200, "{" * 200, "-" * 500 + "1", "!" * 500 + "true",
    "\x00", "\ufeff", "\u00e9", "\U0001f600", "\r", "\t", "/*", "*/", "#", "//", "\\",
]

IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
NUMBER = re.compile(r"(?<![A-Za-z_#])\d+(\.\d*)?([eE][+-]?\d+)?")
TOKEN = re.compile(r"\s+|[A-Za-z_][A-Za-z0-9_.]*|\d+(\.\d*)?([eE][+-]?\d+)?|\"[^\"]*\"|-->|.",
                   re.S)

MAX_SIZE = 512 * 1024  # mutants are kept below this many bytes (or characters)


def _cap(data):
    return data[:MAX_SIZE]


# -- bytes ---------------------------------------------------------------------------------

def flip_bits(rng: random.Random, data: bytes) -> bytes:
    if not data:
        return bytes([rng.randrange(256)])
    b = bytearray(data)
    for _ in range(rng.choice([1, 1, 2, 4, 16])):
        i = rng.randrange(len(b))
        b[i] ^= 1 << rng.randrange(8)
    return bytes(b)


def set_bytes(rng: random.Random, data: bytes) -> bytes:
    if not data:
        return b"\xff"
    b = bytearray(data)
    i = rng.randrange(len(b))
    n = rng.choice([1, 2, 4, 8])
    value = rng.choice([b"\x00", b"\xff", b"\x7f", b"\x80"]) * n
    b[i:i + n] = value[:max(0, len(b) - i)]
    return bytes(b)


def truncate(rng: random.Random, data):
    return data[:rng.randrange(len(data) + 1)] if data else data


def delete_span(rng: random.Random, data):
    if len(data) < 2:
        return data
    i = rng.randrange(len(data))
    j = min(len(data), i + rng.choice([1, 2, 8, 64, 512]))
    return data[:i] + data[j:]


def duplicate_span(rng: random.Random, data):
    if not data:
        return data
    i = rng.randrange(len(data))
    j = min(len(data), i + rng.choice([1, 4, 16, 128]))
    times = rng.choice([1, 2, 10, 100, 1000])
    at = rng.randrange(len(data) + 1)
    return _cap(data[:at] + data[i:j] * times + data[at:])


def insert_random(rng: random.Random, data: bytes) -> bytes:
    at = rng.randrange(len(data) + 1)
    return data[:at] + bytes(rng.randrange(256) for _ in range(rng.choice([1, 4, 32]))) + data[at:]


BYTE_MUTATORS = {"flip_bits": flip_bits, "set_bytes": set_bytes, "truncate": truncate,
                 "delete_span": delete_span, "duplicate_span": duplicate_span,
                 "insert_random": insert_random}


# -- text ----------------------------------------------------------------------------------

def _tokens(text: str) -> list[str]:
    return [m.group(0) for m in TOKEN.finditer(text)]


def insert_token(rng: random.Random, text: str, words=CGA_TOKENS) -> str:
    toks = _tokens(text)
    at = rng.randrange(len(toks) + 1)
    toks[at:at] = [" ", rng.choice(words), " "]
    return "".join(toks)


def replace_token(rng: random.Random, text: str, words=CGA_TOKENS) -> str:
    toks = _tokens(text)
    solid = [i for i, t in enumerate(toks) if not t.isspace()]
    if not solid:
        return insert_token(rng, text, words)
    toks[rng.choice(solid)] = rng.choice(words)
    return "".join(toks)


def delete_token(rng: random.Random, text: str) -> str:
    toks = _tokens(text)
    solid = [i for i, t in enumerate(toks) if not t.isspace()]
    if not solid:
        return text
    del toks[rng.choice(solid)]
    return "".join(toks)


def swap_tokens(rng: random.Random, text: str) -> str:
    toks = _tokens(text)
    solid = [i for i, t in enumerate(toks) if not t.isspace()]
    if len(solid) < 2:
        return text
    i, j = rng.sample(solid, 2)
    toks[i], toks[j] = toks[j], toks[i]
    return "".join(toks)


def replace_number(rng: random.Random, text: str) -> str:
    spans = [m.span() for m in NUMBER.finditer(text)]
    if not spans:
        return insert_token(rng, text, NUMBERS)
    i, j = rng.choice(spans)
    new = rng.choice(EXPRESSIONS) if rng.random() < 0.25 else rng.choice(NUMBERS)
    return text[:i] + new + text[j:]


def replace_identifier(rng: random.Random, text: str) -> str:
    spans = [m.span() for m in IDENT.finditer(text)]
    if not spans:
        return text
    names = sorted({text[i:j] for i, j in spans}) + ["Lot", "NIL", "X", "attr", "case", "scope"]
    i, j = rng.choice(spans)
    return text[:i] + rng.choice(names) + text[j:]


def line_edit(rng: random.Random, text: str) -> str:
    lines = text.splitlines(keepends=True)
    if not lines:
        return text
    i = rng.randrange(len(lines))
    kind = rng.randrange(4)
    if kind == 0:
        del lines[i]
    elif kind == 1:
        lines[i:i] = [lines[rng.randrange(len(lines))]] * rng.choice([1, 2, 50])
    elif kind == 2:
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    else:
        lines[i] = lines[i].rstrip("\n") * rng.choice([2, 20]) + "\n"
    return _cap("".join(lines))


def deep_nesting(rng: random.Random, text: str) -> str:
    depth = rng.choice([50, 200, 1000, 5000])
    left, right = rng.choice([("(", ")"), ("[", "]"), ("{ ~1 : ", " }"), ("[ ", " ]"),
                              ("split(x) { ~1 : ", " }"), ("-", ""), ("f(", ")")])
    at = rng.randrange(len(text) + 1)
    core = rng.choice(["1", "X", "A", ""])
    return _cap(text[:at] + left * depth + core + right * depth + text[at:])


def many_rules(rng: random.Random, text: str) -> str:
    n = rng.choice([10, 500, 5000])
    kind = rng.randrange(3)
    if kind == 0:  # a chain of rules, each calling the next
        extra = "".join(f"R{i} --> R{i + 1}\n" for i in range(n))
        text = text.replace("-->", "--> R0 ", 1) if "-->" in text else text
    elif kind == 1:  # doubling: 2**n shapes asked for
        extra = "".join(f"D{i} --> D{i + 1} D{i + 1}\n" for i in range(min(n, 64)))
        text = text.replace("-->", "--> D0 ", 1) if "-->" in text else text
    else:
        extra = "".join(f"attr a{i} = a{i - 1} + 1\n" if i else "attr a0 = 1\n" for i in range(n))
    return _cap(text + "\n" + extra)


_OP_NAMES = {"extrude", "s", "t", "r", "center", "split", "comp", "offset", "roofHip", "roofGable",
             "roofPyramid", "roofShed", "setback", "i", "texture", "color", "set", "report",
             "print", "tag", "deleteTags", "label", "primitiveCube", "primitiveSphere",
             "primitiveCylinder", "taper", "envelope", "innerRectangle", "splitArea", "scatter",
             "alignScopeToAxes", "alignScopeToGeometry", "rotateScope", "mirrorScope",
             "cleanupGeometry", "reduceGeometry", "convexify", "footprint", "trim", "modify",
             "setupProjection", "projectUV", "tileUV", "scaleUV", "insertAlongUV",
             "softenNormals", "deleteHoles", "splitAndSetbackPerimeter"}
OPERATIONS = [t for t in CGA_TOKENS if t.split("(")[0] in _OP_NAMES] + [
    "primitiveQuad", "NIL", "X.", "[ t(0, 1, 0) X. ]", "Rec", "A B"]
EXPRESSIONS = [t for t in CGA_TOKENS if re.match(r"(rand|floor|pow|sqrt|log|exp|len|str|float|"
                                                  r"bool|readTextFile|fileSearch|fileExists)\(", t)
               or t.startswith("[") and t.endswith("]") and len(t) < 40] + [
    "scope.sx * 1e300", "split.index", "1 / 0", "0 / 0", "-1e300 * 10", "f(1)"]


def insert_operation(rng: random.Random, text: str) -> str:
    """An operation after a rule's arrow or after an operation: the rules still parse."""
    spots, depth = [], 0
    for m in re.finditer(r"-->|[()]", text):
        if m.group(0) == "(":
            depth += 1
        elif m.group(0) == ")":
            depth = max(0, depth - 1)
            if depth == 0 and text[m.end():m.end() + 1].isspace():
                spots.append(m.end())
        else:
            depth = 0
            spots.append(m.end())
    if not spots:
        return insert_token(rng, text, OPERATIONS)
    at = rng.choice(spots)
    return text[:at] + " " + rng.choice(OPERATIONS) + " " + text[at:]


TEXT_MUTATORS = {"insert_token": insert_token, "replace_token": replace_token,
                 "delete_token": delete_token, "swap_tokens": swap_tokens,
                 "replace_number": replace_number, "replace_identifier": replace_identifier,
                 "line_edit": line_edit, "truncate": truncate, "delete_span": delete_span,
                 "duplicate_span": duplicate_span}
CGA_MUTATORS = {**TEXT_MUTATORS, "deep_nesting": deep_nesting, "many_rules": many_rules,
                "insert_operation": insert_operation}
#: Mutators that mostly keep the rules parseable (so that they reach the derivation), drawn
#: more often than those that mostly break the syntax.
CGA_WEIGHTS = {"insert_operation": 10, "replace_number": 8, "replace_identifier": 2,
               "many_rules": 2, "line_edit": 2}

OBJ_WORDS = ["v", "vt", "vn", "f", "o", "g", "s", "l", "p", "usemtl x", "mtllib ../../etc/passwd",
             "mtllib missing.mtl", "f 1 2", "f 0 0 0", "f -1 -2 -3", "f 99999999 1 2",
             "f 1/1/1 2/2/2 3/3/3", "f 1//1 2//2", "f a b c", "v 1e300 0 0", "v nan 0 0",
             "v inf inf inf", "v 1 2", "v 1 2 3 4 5 6 7", "v 1e9 0 1e9", "\\", "#", "\x00",
             *NUMBERS]


def obj_insert(rng: random.Random, text: str) -> str:
    return insert_token(rng, text, OBJ_WORDS)


def obj_line(rng: random.Random, text: str) -> str:
    lines = text.splitlines(keepends=True)
    at = rng.randrange(len(lines) + 1)
    lines.insert(at, rng.choice(OBJ_WORDS[:22]) + "\n")
    return "".join(lines)


OBJ_MUTATORS = {**TEXT_MUTATORS, "obj_insert": obj_insert, "obj_line": obj_line}


# -- JSON ----------------------------------------------------------------------------------

def _paths(value, limit: int = 20000, depth: int = 40):
    """Paths into a JSON document (breadth first; at most ``limit``, ``depth`` deep)."""
    todo, n = [((), value)], 0
    while todo and n < limit:
        nxt = []
        for path, v in todo:
            yield path
            n += 1
            if len(path) < depth:
                items = v.items() if isinstance(v, dict) else enumerate(v) \
                    if isinstance(v, list) else ()
                nxt.extend(((*path, k), x) for k, x in items)
        todo = nxt


def _get(value, path):
    for p in path:
        value = value[p]
    return value


def _set(root, path, new):
    if not path:
        return new
    _get(root, path[:-1])[path[-1]] = new
    return root


def _nested(depth, leaf):
    for _ in range(depth):
        leaf = [leaf]
    return leaf


JSON_VALUES = [None, True, False, 0, -1, 1, 0.5, 1e300, -1e300, 1e9 + 1, 5e-324, 2**64,
               float("nan"), float("inf"), -float("inf"), "", "x", "Polygon", "MultiPolygon",
               "Feature", "FeatureCollection", "Point", "LineString", "GeometryCollection",
               [], {}, [[]], [[[]]], [0, 0], [[0, 0], [1, 1]], {"type": "Polygon"},
               "urn:ogc:def:crs:EPSG::4326", "urn:ogc:def:crs:EPSG::99999", "EPSG:3857"]


def json_swap(rng: random.Random, doc):
    path = rng.choice(list(_paths(doc)))
    choice = rng.randrange(10)
    if choice < 6:
        new = rng.choice(JSON_VALUES)
        new = json.loads(json.dumps(new))
    elif choice == 6:
        new = _nested(rng.choice([10, 100, 400]), rng.choice([0, [0, 0]]))
    elif choice == 7:
        new = [rng.choice([[0, 0], [1e-9, 1e-9], [1, 0]])] * rng.choice([3, 1000, 20000])
    elif choice == 8:
        new = "s" * rng.choice([1000, 100000])
    else:  # another part of the document
        new = json.loads(json.dumps(_get(doc, rng.choice(list(_paths(doc))))))
    return _set(doc, path, new)


def json_delete(rng: random.Random, doc):
    paths = [p for p in _paths(doc) if p]
    if not paths:
        return doc
    path = rng.choice(paths)
    parent = _get(doc, path[:-1])
    del parent[path[-1]]
    return doc


def json_duplicate(rng: random.Random, doc):
    lists = [p for p in _paths(doc) if isinstance(_get(doc, p), list) and _get(doc, p)]
    if not lists:
        return doc
    lst = _get(doc, rng.choice(lists))
    item = rng.choice(lst)
    for _ in range(rng.choice([1, 2, 100])):
        lst.insert(rng.randrange(len(lst) + 1), json.loads(json.dumps(item)))
    return doc


def json_number(rng: random.Random, doc):
    nums = [p for p in _paths(doc) if isinstance(_get(doc, p), (int, float))
            and not isinstance(_get(doc, p), bool)]
    if not nums:
        return json_swap(rng, doc)
    path = rng.choice(nums)
    old = _get(doc, path)
    new = rng.choice([old * 1e300, old + 1e-12, -old, 0, float("nan"), float("inf"), 1e9 + 1,
                      old * 1e6, 181.0, -91.0, old + rng.uniform(-50, 50)])
    return _set(doc, path, new)


def json_ring(rng: random.Random, doc):
    """Rings: reversed, shortened, self-intersecting, collapsed, with repeated points."""
    rings = [p for p in _paths(doc) if isinstance(_get(doc, p), list) and _get(doc, p)
             and all(isinstance(q, list) and len(q) >= 2 and all(
                 isinstance(c, (int, float)) for c in q) for q in _get(doc, p))]
    if not rings:
        return json_swap(rng, doc)
    ring = _get(doc, rng.choice(rings))
    kind = rng.randrange(6)
    if kind == 0:
        ring.reverse()
    elif kind == 1:
        del ring[rng.randrange(len(ring)):]
    elif kind == 2 and len(ring) > 2:
        i, j = rng.sample(range(len(ring)), 2)
        ring[i], ring[j] = ring[j], ring[i]
    elif kind == 3:
        ring[:] = [list(ring[0])] * len(ring)
    elif kind == 4:
        ring.insert(rng.randrange(len(ring)), list(rng.choice(ring)))
    else:
        p = ring[rng.randrange(len(ring))]
        p.append(rng.choice([0, 1e300, float("nan"), "x"]))
    return doc


def json_deep_text(rng: random.Random, text: str) -> str:
    """A value nested deeper than any parser's recursion, written as text."""
    spots = [m.end() for m in re.finditer(r":\s*", text)] or [len(text)]
    at = rng.choice(spots)
    depth = rng.choice([1000, 100000])
    closing = "]" * depth if rng.random() < 0.5 else ""
    return text[:at] + "[" * depth + "0" + closing + text[at:]


JSON_MUTATORS = {"json_swap": json_swap, "json_delete": json_delete,
                 "json_duplicate": json_duplicate, "json_number": json_number,
                 "json_ring": json_ring}


def dumps(doc) -> str:
    """JSON text, NaN and Infinity included as the non-standard literals many tools write."""
    return json.dumps(doc, allow_nan=True)
