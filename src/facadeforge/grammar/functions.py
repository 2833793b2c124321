"""Built-in CGA functions: math, strings, arrays, conversion and randomness.

Functions that read the current shape (``geometry.area``, ``scope.*``) live in the interpreter,
which owns the shape state; this module holds the pure ones.  Each entry is
``name: (callable(env, args) -> value, min_args, max_args)``.
"""

from __future__ import annotations

import math

import numpy as np

from .budget import check_string_length
from .chance import outcome, rand_value
from .values import (
    CGARuntimeError,
    from_numpy,
    make_array,
    to_bool,
    to_float,
    to_str,
    type_name,
)

FUNCTIONS: dict[str, tuple] = {}


def bare_call(name: str) -> bool:
    """Whether a bare name calls a built-in function: one that takes no arguments, which CGA
    calls without parentheses as it does user functions (``~(rand)`` in Esri's rules)."""
    entry = FUNCTIONS.get(name)
    return entry is not None and entry[1] == 0


def builtin(name: str, min_args: int, max_args: int | None = None):
    def deco(fn):
        FUNCTIONS[name] = (fn, min_args, min_args if max_args is None else max_args)
        return fn
    return deco


def _math1(name, f):
    def fn(env, a):
        x = to_float(a[0], f"{name}() argument")
        if isinstance(a[0], np.ndarray):
            return f(a[0].astype(float))
        try:
            return float(f(x))
        except (ValueError, OverflowError):
            return math.nan
    FUNCTIONS[name] = (fn, 1, 1)


for _n, _f in {"sin": lambda x: np.sin(np.radians(x)), "cos": lambda x: np.cos(np.radians(x)),
               "tan": lambda x: np.tan(np.radians(x)),
               "asin": lambda x: np.degrees(np.arcsin(x)), "acos": lambda x: np.degrees(np.arccos(x)),
               "atan": lambda x: np.degrees(np.arctan(x)), "sqrt": np.sqrt, "exp": np.exp,
               "ln": np.log, "log10": np.log10, "abs": np.abs, "floor": np.floor, "ceil": np.ceil,
               "rint": np.rint, "sign": np.sign}.items():
    _math1(_n, lambda x, _f=_f: _f(x) if not isinstance(x, np.ndarray) else _f(x))


@builtin("atan2", 2)
def _atan2(env, a):
    return float(math.degrees(math.atan2(to_float(a[0]), to_float(a[1]))))


@builtin("pow", 2)
def _pow(env, a):
    try:
        return float(to_float(a[0]) ** to_float(a[1]))
    except (ValueError, OverflowError, ZeroDivisionError):
        return math.nan


@builtin("min", 1, 64)
def _min(env, a):
    if len(a) == 1 and isinstance(a[0], np.ndarray):
        return float(np.min(a[0])) if a[0].size else math.nan
    return min(to_float(x) for x in a)


@builtin("max", 1, 64)
def _max(env, a):
    if len(a) == 1 and isinstance(a[0], np.ndarray):
        return float(np.max(a[0])) if a[0].size else math.nan
    return max(to_float(x) for x in a)


def _float_test(a, test):
    """``isnan``/``isinf`` on a float, or element-wise on a float array (CGA 2021.0 on): strings
    and bools are never NaN or infinite."""
    v = a[0]
    if isinstance(v, np.ndarray):
        if v.dtype.kind != "f":
            return np.zeros(v.shape, bool)
        return test(v)
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(test(v))


@builtin("isnan", 1)
def _isnan(env, a):
    return _float_test(a, np.isnan)


@builtin("isinf", 1)
def _isinf(env, a):
    return _float_test(a, np.isinf)


#: CityEngine's NULL string (a missing layer attribute); NULL floats are NaN.
NULL_STRING = "\ue000"


@builtin("isNull", 1)
def _is_null(env, a):
    """``isNull(value)``: whether a float is NULL (NaN) or a string is NULL ("\\ue000"),
    element-wise on arrays (reference: func_isnull.html, "isNull")."""
    v = a[0]
    if isinstance(v, np.ndarray):
        if v.dtype.kind == "f":
            return np.isnan(v)
        return np.array([x == NULL_STRING for x in v.reshape(-1)], bool).reshape(v.shape)
    if isinstance(v, str):
        return v == NULL_STRING
    return isinstance(v, float) and math.isnan(v)


@builtin("float", 1)
def _float(env, a):
    if isinstance(a[0], np.ndarray):
        return np.array([to_float(from_numpy(x)) for x in a[0].reshape(-1)]).reshape(a[0].shape)
    return to_float(a[0])


@builtin("str", 1)
def _str(env, a):
    return to_str(a[0])


@builtin("sel", 1)
def _sel(env, a):
    """A selector given as a string (``inside(sel(mode))``)."""
    return to_str(a[0])


@builtin("bool", 1)
def _bool(env, a):
    return to_bool(a[0])


@builtin("print", 1)
def _print(env, a):
    """``print(value)`` inside an expression: prints the value and returns it (func_print.html;
    the ``print`` operation is the statement form)."""
    derivation = getattr(env, "derivation", None)
    if derivation is not None:
        derivation.prints.append(to_str(a[0]))
    return a[0]


@builtin("rand", 0, 2)
def _rand(env, a):
    return rand_value(env.random_float(), rand_bounds(a))


def rand_bounds(a) -> tuple[float, float]:
    """``(lo, hi)`` of ``rand()``, ``rand(hi)``, ``rand(lo, hi)``."""
    return (0.0, 1.0) if not a else ((0.0, to_float(a[0])) if len(a) == 1 else
                                     (to_float(a[0]), to_float(a[1])))


@builtin("p", 1)
def _p(env, a):
    prob = to_float(a[0])
    got = outcome("p", env.random_float(), prob)
    env.note_choice("p", prob, got)
    return got


# ---- strings ------------------------------------------------------------------------------

@builtin("len", 1)
def _len(env, a):
    return float(len(to_str(a[0])))


@builtin("find", 2, 3)
def _find(env, a):
    s, sub = to_str(a[0]), to_str(a[1])
    n = int(to_float(a[2])) if len(a) > 2 else 0
    pos = -1
    for _ in range(n + 1):
        pos = s.find(sub, pos + 1)
        if pos < 0:
            return -1.0
    return float(pos)


@builtin("findFirst", 2, 3)
def _find_first(env, a):
    """``findFirst(string, sub)`` (utility library) or ``findFirst(array, value[, epsilon])``
    (built-in, func_findFirst.html): index of the first match, -1 when there is none.  Arrays are
    searched in row-major order; float values match within ``epsilon`` (0 when left out)."""
    if not isinstance(a[0], np.ndarray):
        if len(a) > 2:
            raise CGARuntimeError("findFirst(string, sub) takes 2 arguments; the third "
                                  "(epsilon) is only for arrays")
        return float(to_str(a[0]).find(to_str(a[1])))
    flat = a[0].reshape(-1)
    if flat.dtype.kind == "f":
        eps = to_float(a[2], "findFirst epsilon") if len(a) > 2 else 0.0
        hits = np.flatnonzero(np.abs(flat - to_float(a[1], "findFirst value")) <= eps)
    else:
        hits = [i for i, x in enumerate(flat) if from_numpy(x) == a[1]]
    return float(hits[0]) if len(hits) else -1.0


@builtin("findLast", 2)
def _find_last(env, a):
    return float(to_str(a[0]).rfind(to_str(a[1])))


@builtin("count", 2)
def _count(env, a):
    if isinstance(a[0], np.ndarray):
        return float(sum(1 for x in a[0].reshape(-1) if from_numpy(x) == a[1]))
    sub = to_str(a[1])
    return float(to_str(a[0]).count(sub)) if sub else 0.0


@builtin("replace", 3)
def _replace(env, a):
    text, old, new = to_str(a[0]), to_str(a[1]), to_str(a[2])
    if not old:
        return text
    check_string_length(len(text) + text.count(old) * (len(new) - len(old)))
    return text.replace(old, new)


@builtin("substring", 3)
def _substring(env, a):
    s = to_str(a[0])
    i, j = int(max(0, to_float(a[1]))), int(max(0, to_float(a[2])))
    return s[i:j]


@builtin("toUpper", 1)
def _upper(env, a):
    return to_str(a[0]).upper()


@builtin("toLower", 1)
def _lower(env, a):
    return to_str(a[0]).lower()


@builtin("strip", 1)
def _strip(env, a):
    return to_str(a[0]).strip()


def _list_items(s: str) -> list[str]:
    """CGA string lists are ``;``-terminated: ``"a;b;c;"``."""
    parts = s.split(";")
    if parts and parts[-1] == "":
        parts.pop()
    return parts


@builtin("listSize", 1)
def _list_size(env, a):
    return float(len(_list_items(to_str(a[0]))))


@builtin("listItem", 2)
def _list_item(env, a):
    items = _list_items(to_str(a[0]))
    i = int(to_float(a[1]))
    return items[i] if 0 <= i < len(items) else ""


@builtin("listFirst", 1)
def _list_first(env, a):
    items = _list_items(to_str(a[0]))
    return items[0] if items else ""


@builtin("listLast", 1)
def _list_last(env, a):
    items = _list_items(to_str(a[0]))
    return items[-1] if items else ""


@builtin("listRange", 3)
def _list_range(env, a):
    items = _list_items(to_str(a[0]))
    i, j = int(to_float(a[1])), int(to_float(a[2]))
    return "".join(x + ";" for x in items[max(i, 0):max(j, 0)])


@builtin("listIndex", 2)
def _list_index(env, a):
    items = _list_items(to_str(a[0]))
    s = to_str(a[1])
    return float(items.index(s)) if s in items else -1.0


@builtin("listAdd", 2)
def _list_add(env, a):
    head, item = to_str(a[0]), to_str(a[1])
    check_string_length(len(head) + len(item) + 1)
    return head + item + ";"


@builtin("listRandom", 1)
def _list_random(env, a):
    items = _list_items(to_str(a[0]))
    if not items:
        return ""
    k = outcome("list", env.random_float(), len(items))
    env.note_choice("list", len(items), k)
    return items[k]


@builtin("listToArray", 1)
def _list_to_array(env, a):
    """``listToArray(stringList)``: the items of a ``;``-terminated string list as a string
    array (celib/listToArray.html)."""
    return np.array(_list_items(to_str(a[0])), dtype=object)


@builtin("listFromArray", 1)
def _list_from_array(env, a):
    """``listFromArray(array)``: a ``;``-terminated string list of the array's elements, in
    row-major order (celib/listFromArray.html)."""
    return "".join(to_str(from_numpy(x)) + ";" for x in _arr(a[0], "listFromArray argument").reshape(-1))


@builtin("listClean", 1)
def _list_clean(env, a):
    return "".join(x + ";" for x in _list_items(to_str(a[0])) if x)


# ---- arrays -------------------------------------------------------------------------------

def _arr(v, what="argument") -> np.ndarray:
    if not isinstance(v, np.ndarray):
        raise CGARuntimeError(f"{what} must be an array, got {type_name(v)}")
    return v


@builtin("size", 1)
def _size(env, a):
    v = a[0]
    if isinstance(v, np.ndarray):
        return float(v.size)
    if isinstance(v, str):
        return float(len(v))
    return 1.0


@builtin("nRows", 1)
def _nrows(env, a):
    """Rows: a 1D array is one row (``[transpose(a), transpose(b)]`` of two 1D arrays is the
    reference's two-column example)."""
    v = _arr(a[0])
    return float(v.shape[0]) if v.ndim == 2 else (1.0 if v.size else 0.0)


@builtin("nColumns", 1)
def _ncols(env, a):
    v = _arr(a[0])
    return float(v.shape[1]) if v.ndim == 2 else float(v.size)


@builtin("floatArray", 0, 1)
def _float_array(env, a):
    return np.zeros(0) if not a else np.asarray(_arr(a[0]), float).copy()


@builtin("stringArray", 0, 1)
def _string_array(env, a):
    return np.zeros(0, object) if not a else np.array([to_str(from_numpy(x)) for x in _arr(a[0]).reshape(-1)], object)


@builtin("boolArray", 0, 1)
def _bool_array(env, a):
    return np.zeros(0, bool) if not a else np.array([to_bool(from_numpy(x)) for x in _arr(a[0]).reshape(-1)], bool)


@builtin("index", 2)
def _index(env, a):
    arr = _arr(a[0]).reshape(-1)
    for i, x in enumerate(arr):
        if from_numpy(x) == a[1]:
            return float(i)
    return -1.0


@builtin("sortIndices", 1)
def _sort_indices(env, a):
    arr = _arr(a[0]).reshape(-1)
    return np.argsort(arr, kind="stable").astype(float)


@builtin("sort", 1)
def _sort(env, a):
    return np.sort(_arr(a[0]).reshape(-1), kind="stable")


@builtin("reverse", 1)
def _reverse(env, a):
    return _arr(a[0])[::-1].copy()


@builtin("transpose", 1)
def _transpose(env, a):
    """Rows become columns: a 1D array (one row) becomes a column, a column a 1D array."""
    from .arrays import canonical

    v = _arr(a[0])
    return v.reshape(-1, 1).copy() if v.ndim == 1 and v.size else canonical(v.T.copy())


@builtin("sortRowIndices", 1)
def _sort_row_indices(env, a):
    """Indices of the rows of ``array`` in lexicographic order; equal rows keep their order
    (func_sortRowIndices.html).  A 1D array's elements are its rows."""
    arr = _arr(a[0], "sortRowIndices argument")
    if not arr.size:
        return np.zeros(0)
    rows = arr.reshape(len(arr), -1) if arr.ndim else arr.reshape(0, 1)
    keys = [tuple(from_numpy(x) for x in r) for r in rows]
    return np.array(sorted(range(len(keys)), key=keys.__getitem__), float)


#: The largest array ``setElems`` builds (CityEngine's default procedural-runtime limit).
MAX_ARRAY_SIZE = 100_000


def _selected(index, length: int, what: str) -> list[int]:
    """Positions an index argument selects: one index, an index array or a logical array.
    Negative indices stay in the list (their values must still be counted); the callers skip
    them, as ``setElems`` ignores them."""
    if isinstance(index, np.ndarray):
        flat = index.reshape(-1)
        if flat.dtype.kind == "b":
            if len(flat) > length:
                raise CGARuntimeError(f"setElems: the logical {what} array has {len(flat)} "
                                      f"elements, more than the {length} it selects from")
            picked = np.flatnonzero(flat)
        elif flat.dtype.kind == "f":
            picked = flat
        else:
            raise CGARuntimeError(f"setElems: {what} must be numbers or bools, got {type_name(index)}")
    else:
        picked = [to_float(index, f"setElems {what}")]
    return [int(i) for i in picked]


def _element_of(arr: np.ndarray, value):
    """``value`` as an element of ``arr``'s type; a mismatch is an error as in CGA."""
    kind = {"f": "float", "b": "bool"}.get(arr.dtype.kind, "string")
    if type_name(value) != kind:
        raise CGARuntimeError(f"setElems: cannot put a {type_name(value)} into a {kind} array")
    return value


def _values_for(arr: np.ndarray, values, count: int) -> list:
    if isinstance(values, np.ndarray):
        flat = [from_numpy(x) for x in values.reshape(-1)]
        if len(flat) != count:
            raise CGARuntimeError(f"setElems: {len(flat)} values for {count} selected elements; "
                                  "give one value or exactly one per selected element")
        return [_element_of(arr, v) for v in flat]
    return [_element_of(arr, values)] * count


def _grown(arr: np.ndarray, shape: tuple) -> np.ndarray:
    if int(np.prod(shape)) > MAX_ARRAY_SIZE:
        raise CGARuntimeError(f"setElems: the array would grow to {int(np.prod(shape))} elements, "
                              f"more than {MAX_ARRAY_SIZE}")
    out = np.full(shape, "" if arr.dtype == object else 0, dtype=arr.dtype)
    out[tuple(slice(0, n) for n in arr.shape)] = arr
    return out


@builtin("setElems", 3, 4)
def _set_elems(env, a):
    """``setElems(array, indices, values)`` / ``setElems(array, rows, cols, values)``: a copy of
    ``array`` with the selected elements set (func_setElems.html).  Indices are numbers, index
    arrays or logical arrays; negative ones are ignored, larger ones grow the array with default
    values (0, "", false); repeated indices take the last value.  A 1D array is one row for 2D
    indexing; 1D indexing of a 2D array counts in row-major order within its size."""
    arr = _arr(a[0], "setElems array")
    if len(a) == 3:
        flat = arr.reshape(-1)
        chosen = _selected(a[1], len(flat), "indices")
        pairs = [(i, v) for i, v in zip(chosen, _values_for(arr, a[2], len(chosen))) if i >= 0]
        idx = [i for i, _ in pairs]
        vals = [v for _, v in pairs]
        if arr.ndim == 2 and any(i >= flat.size for i in idx):
            raise CGARuntimeError("setElems: an index past the end of a 2D array; use "
                                  "setElems(array, rows, cols, values) to grow it")
        out = _grown(flat, (max([flat.size] + [i + 1 for i in idx]),))
        for i, v in zip(idx, vals):
            out[i] = v
        return out.reshape(arr.shape) if arr.ndim == 2 else out
    grid = arr.reshape(1, -1) if arr.ndim == 1 else arr
    rows = _selected(a[1], grid.shape[0], "row indices")
    cols = _selected(a[2], grid.shape[1], "column indices")
    vals = _values_for(arr, a[3], len(rows) * len(cols))
    cells = [((r, c), v) for ((r, c), v) in zip(((r, c) for r in rows for c in cols), vals)
             if r >= 0 and c >= 0]
    shape = (max([grid.shape[0]] + [r + 1 for (r, _), _ in cells]),
             max([grid.shape[1]] + [c + 1 for (_, c), _ in cells]))
    out = _grown(grid, shape)
    for (r, c), v in cells:
        out[r, c] = v
    return out


@builtin("splitString", 2)
def _split_string(env, a):
    sep = to_str(a[1])
    s = to_str(a[0])
    return np.array(s.split(sep) if sep else list(s), dtype=object)


@builtin("concatenate", 1, 16)
def _concatenate(env, a):
    parts = [x.reshape(-1) if isinstance(x, np.ndarray) else make_array([x]) for x in a]
    return make_array([from_numpy(x) for p in parts for x in p])


@builtin("slice", 2, 3)
def _slice(env, a):
    arr = _arr(a[0])
    i = int(to_float(a[1]))
    j = int(to_float(a[2])) if len(a) > 2 else arr.shape[0]
    return arr[i:j].copy()


@builtin("item", 2)
def _item(env, a):
    arr = _arr(a[0]).reshape(-1)
    i = int(to_float(a[1]))
    if not 0 <= i < len(arr):
        raise CGARuntimeError(f"index {i} out of range for an array of size {len(arr)}")
    return from_numpy(arr[i])


@builtin("sum", 1)
def _sum(env, a):
    return float(np.sum(_arr(a[0]).astype(float)))


@builtin("uniqueValues", 1)
def _unique(env, a):
    seen, out = set(), []
    for x in _arr(a[0]).reshape(-1):
        v = from_numpy(x)
        if v not in seen:
            seen.add(v)
            out.append(v)
    return make_array(out) if out else _arr(a[0])[:0]


# ---- CityEngine's standard function library (ce.lib), written anew ------------------------
# CityEngine makes these available to every rule file; their behaviour follows the CGA
# reference's descriptions and examples.

@builtin("getPrefix", 2)
def _get_prefix(env, a):
    s, m = to_str(a[0]), to_str(a[1])
    i = s.find(m) if m else -1
    return s[:i] if i >= 0 else s


@builtin("getSuffix", 2)
def _get_suffix(env, a):
    s, m = to_str(a[0]), to_str(a[1])
    i = s.rfind(m) if m else -1
    return s[i + len(m):] if i >= 0 else s


@builtin("getRange", 3)
def _get_range(env, a):
    s, left, right = to_str(a[0]), to_str(a[1]), to_str(a[2])
    i = s.find(left) if left else -1
    j = s.rfind(right) if right else -1
    start = i + len(left) if i >= 0 else 0
    end = j if j >= 0 else len(s)
    if i < 0 and j < 0:
        return s
    return s[start:end] if end >= start else ""


@builtin("listTerminate", 1)
def _list_terminate(env, a):
    s = to_str(a[0])
    return s + ";" if s and not s.endswith(";") else s


@builtin("listCount", 2)
def _list_count(env, a):
    return float(_list_items(to_str(a[0])).count(to_str(a[1])))


@builtin("listRemove", 2)
def _list_remove(env, a):
    items = _list_items(to_str(a[0]))
    s = to_str(a[1])
    if s in items:
        items.remove(s)
    return "".join(x + ";" for x in items)


@builtin("listRemoveAll", 2)
def _list_remove_all(env, a):
    drop = set(_list_items(to_str(a[1]))) | {to_str(a[1])}
    return "".join(x + ";" for x in _list_items(to_str(a[0])) if x not in drop)


@builtin("listRetainAll", 2)
def _list_retain_all(env, a):
    keep = set(_list_items(to_str(a[1]))) | {to_str(a[1])}
    return "".join(x + ";" for x in _list_items(to_str(a[0])) if x in keep)


def _file_name(path: str) -> str:
    return path.replace("\\", "/").rsplit("/", 1)[-1]


@builtin("fileName", 1)
def _fn_file_name(env, a):
    return _file_name(to_str(a[0]))


@builtin("fileExtension", 1)
def _fn_file_extension(env, a):
    name = to_str(a[0])
    return name.rsplit(".", 1)[-1] if "." in name else ""


@builtin("fileBasename", 1)
def _fn_file_basename(env, a):
    name = _file_name(to_str(a[0]))
    return name.rsplit(".", 1)[0] if "." in name else name


@builtin("fileDirectory", 1)
def _fn_file_directory(env, a):
    path = to_str(a[0]).replace("\\", "/")
    return path.rsplit("/", 1)[0] + "/" if "/" in path else ""


@builtin("clamp", 3)
def _clamp(env, a):
    x, lo, hi = to_float(a[0]), to_float(a[1]), to_float(a[2])
    return lo if x < lo else (hi if x > hi else x)


def _hex2(x: float) -> str:
    return f"{int(round(min(max(x, 0.0), 1.0) * 255)):02x}"


@builtin("colorRGBToHex", 3)
def _rgb_to_hex(env, a):
    return "#" + "".join(_hex2(to_float(v)) for v in a)


@builtin("colorRGBOToHex", 4)
def _rgbo_to_hex(env, a):
    return "#" + "".join(_hex2(to_float(v)) for v in a)


def _hex_channel(text: str, k: int) -> float:
    h = to_str(text).lstrip("#")
    try:
        return min(max(int(h[2 * k:2 * k + 2], 16) / 255.0, 0.0), 1.0)
    except ValueError:
        return 0.0


for _k, _n in enumerate("RGBO"):
    FUNCTIONS[f"colorHexTo{_n}"] = (lambda env, a, _k=_k: _hex_channel(a[0], _k), 1, 1)


def _hsv_to_rgb(h: float, s: float, v: float) -> tuple[float, float, float]:
    import colorsys

    return colorsys.hsv_to_rgb((h % 360.0) / 360.0, min(max(s, 0.0), 1.0), min(max(v, 0.0), 1.0))


@builtin("colorHSVToHex", 3)
def _hsv_to_hex(env, a):
    return "#" + "".join(_hex2(c) for c in _hsv_to_rgb(*(to_float(x) for x in a)))


@builtin("colorHSVOToHex", 4)
def _hsvo_to_hex(env, a):
    rgb = _hsv_to_rgb(*(to_float(x) for x in a[:3]))
    return "#" + "".join(_hex2(c) for c in (*rgb, to_float(a[3])))


def _hex_to_hsv(text) -> tuple[float, float, float]:
    import colorsys

    h, s, v = colorsys.rgb_to_hsv(*(_hex_channel(text, k) for k in range(3)))
    return h * 360.0, s, v


for _k, _n in enumerate("HSV"):
    FUNCTIONS[f"colorHexTo{_n}"] = (lambda env, a, _k=_k: float(_hex_to_hsv(a[0])[_k]), 1, 1)


@builtin("colorRamp", 2)
def _color_ramp(env, a):
    """``colorRamp(gradient, value)``: named ramps from blue over green to red (value in 0–1)."""
    v = min(max(to_float(a[1]), 0.0), 1.0)
    name = to_str(a[0]).lower()
    stops = {"redtoblue": ["#ff0000", "#ffffff", "#0000ff"],
             "bluetored": ["#0000ff", "#ffffff", "#ff0000"],
             "greentored": ["#00ff00", "#ffff00", "#ff0000"]}.get(
        name, ["#2c7bb6", "#abd9e9", "#ffffbf", "#fdae61", "#d7191c"])
    pos = v * (len(stops) - 1)
    i = min(int(pos), len(stops) - 2)
    t = pos - i
    c0 = [_hex_channel(stops[i], k) for k in range(3)]
    c1 = [_hex_channel(stops[i + 1], k) for k in range(3)]
    return "#" + "".join(_hex2(x + t * (y - x)) for x, y in zip(c0, c1))
