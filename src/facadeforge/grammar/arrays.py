"""CGA arrays (CityEngine 2019.1–2020.0): initialisation by concatenation, the colon operator,
the index operator with index and logical arrays, element-wise (dot) operators and the ordering
of arrays.  Follows the reference pages "array initialization function", "colon operator",
"index operator" and "Array type operators".

Arrays are numpy arrays: ``float`` (dtype float), ``bool`` (dtype bool) and ``string`` (dtype
object).  An array with one row is one-dimensional, shape ``(n,)`` (CityEngine prints it
``(n)[…]``); others are ``(rows, columns)``.
"""

from __future__ import annotations

import math
import operator

import numpy as np

from .values import CGARuntimeError, from_numpy, make_array, to_bool, to_float, to_str

#: CityEngine's default cap on the size of an array an expression creates.
MAX_ELEMENTS = 100_000


def canonical(a: np.ndarray) -> np.ndarray:
    """One row → one dimension; everything else two."""
    if a.ndim == 2 and a.shape[0] == 1:
        return a.reshape(-1)
    if a.ndim > 2:
        return a.reshape(a.shape[0], -1)
    return a


def _checked(a: np.ndarray) -> np.ndarray:
    if a.size > MAX_ELEMENTS:
        raise CGARuntimeError(f"an array of {a.size} elements is larger than CityEngine's limit "
                              f"of {MAX_ELEMENTS}")
    return a


def colon(start, step, stop) -> np.ndarray:
    """``[start : step : stop]``: start, start + step, … not beyond ``stop`` (empty when
    ``step`` is 0 or points away from ``stop``)."""
    for v, what in ((start, "start"), (step, "increment"), (stop, "limit")):
        if isinstance(v, (str, np.ndarray)):
            raise CGARuntimeError(f"the colon operator's {what} must be a number, not "
                                  f"'{to_str(v)}'")
    a, b = to_float(start, "colon start"), to_float(stop, "colon limit")
    d = 1.0 if step is None else to_float(step, "colon increment")
    if not all(map(math.isfinite, (a, b, d))) or d == 0 or (b - a) * d < 0:
        return np.zeros(0)
    span = (b - a) / d
    if not math.isfinite(span) or span >= MAX_ELEMENTS:
        raise CGARuntimeError(f"[{to_str(a)}:{to_str(d)}:{to_str(b)}] has more than "
                              f"{MAX_ELEMENTS} elements")
    n = int(math.floor(span)) + 1
    # the last element must not pass the limit (the division may round either way)
    if n > 0 and (a + (n - 1) * d - b) * d > 0:
        n -= 1
    elif a + n * d != a + (n - 1) * d and (a + n * d - b) * d <= 0:
        n += 1
    return a + d * np.arange(n, dtype=float)


def _block(v) -> np.ndarray:
    """A value of an array initialisation as a 2D block."""
    if isinstance(v, np.ndarray):
        return v.reshape(1, -1) if v.ndim == 1 else v
    return make_array([v]).reshape(1, 1)


def _common(blocks: list[np.ndarray]) -> list[np.ndarray]:
    """Blocks of one element type: floats and bools stay, a mixture becomes strings."""
    kinds = {b.dtype.kind for b in blocks if b.size}
    if len(kinds) <= 1:
        return blocks
    return [np.vectorize(lambda x: to_str(from_numpy(x)), otypes=[object])(b) if b.size
            else b.astype(object) for b in blocks]


def build(rows: list[list]) -> np.ndarray:
    """``[v, v ; v, v]``: the values of a row (numbers, arrays) side by side, the rows stacked;
    ``["A", a, "E"]`` is a longer 1D array, ``[a, b ; b, a]`` a bigger matrix."""
    stacked = []
    for row in rows:
        blocks = [b for b in (_block(v) for v in row) if b.size]
        if not blocks:
            continue
        heights = {b.shape[0] for b in blocks}
        if len(heights) > 1:
            raise CGARuntimeError("values in one row of an array have different numbers of rows "
                                  f"({', '.join(str(h) for h in sorted(heights))})")
        stacked.append(np.hstack(_common(blocks)))
    if not stacked:
        return np.zeros(0)
    widths = {b.shape[1] for b in stacked}
    if len(widths) > 1:
        raise CGARuntimeError("the rows of an array have different lengths "
                              f"({', '.join(str(w) for w in sorted(widths))})")
    return _checked(canonical(np.vstack(_common(stacked))))


def default_of(a: np.ndarray):
    """What an index outside the array gives: 0, false or ""."""
    return {"b": False, "f": 0.0}.get(a.dtype.kind, "")


def _scalar_position(index, length: int) -> int:
    """A single number's position, -1 when it is outside ``0…length-1``."""
    i = to_float(index, "array index")
    return int(i) if math.isfinite(i) and 0 <= i < length else -1


def _positions(index, length: int) -> tuple[np.ndarray, tuple]:
    """Integer positions an index selects (-1 where it is outside ``0…length-1``) and the shape
    of the result along that axis: ``()`` for one number."""
    if not isinstance(index, np.ndarray):
        return np.array([_scalar_position(index, length)]), ()
    if index.dtype.kind == "b":
        picked = np.flatnonzero(index.reshape(-1))
        return np.where(picked < length, picked, -1), (len(picked),)
    if index.dtype == object:
        raise CGARuntimeError("an index array holds numbers or booleans, not strings")
    flat = index.reshape(-1).astype(float)
    ok = np.isfinite(flat) & (flat >= 0) & (flat < length)
    return np.where(ok, np.nan_to_num(flat).astype(np.int64), -1), index.shape


def _take(flat: np.ndarray, positions: np.ndarray, default) -> np.ndarray:
    out = np.empty(len(positions), dtype=flat.dtype)
    out[:] = default
    ok = positions >= 0
    out[ok] = flat[positions[ok]]
    return out


def index(target, indices: list):
    """``a[i]``, ``a[indices]``, ``a[r, c]``, ``a[rows, columns]`` (numbers, index arrays,
    logical arrays or colon ranges).  An index outside the array gives the default value; the
    result of index arrays has the shape of the index arrays."""
    if not isinstance(target, np.ndarray):
        raise CGARuntimeError("only arrays can be indexed")
    if len(indices) == 1 and type(indices[0]) is float:  # the common case, kept fast
        i = indices[0]
        if 0 <= i < target.size:
            v = target.item(int(i))
            return float(v) if type(v) is int else v
        return default_of(target)
    default = default_of(target)
    if not any(isinstance(i, np.ndarray) for i in indices):
        if len(indices) == 1:
            k = _scalar_position(indices[0], target.size)
            return from_numpy(target.flat[k]) if k >= 0 else default
        if len(indices) == 2:
            rows, cols = target.shape if target.ndim == 2 else (1, target.size)
            r, c = _scalar_position(indices[0], rows), _scalar_position(indices[1], cols)
            return from_numpy(target.flat[r * cols + c]) if r >= 0 and c >= 0 else default
    if len(indices) == 1:
        flat = target.reshape(-1)
        pos, shape = _positions(indices[0], flat.size)
        out = _take(flat, pos, default)
        return from_numpy(out[0]) if shape == () else canonical(out.reshape(shape))
    if len(indices) != 2:
        raise CGARuntimeError(f"arrays have at most 2 indices, not {len(indices)}")
    grid = target.reshape(1, -1) if target.ndim == 1 else target
    rows, rshape = _positions(indices[0], grid.shape[0])
    cols, cshape = _positions(indices[1], grid.shape[1])
    if len(rows) * len(cols) > MAX_ELEMENTS:
        raise CGARuntimeError(f"indexing gives {len(rows)} x {len(cols)} elements, more than "
                              f"CityEngine's limit of {MAX_ELEMENTS}")
    out = np.empty((len(rows), len(cols)), dtype=grid.dtype)
    out[:] = default
    ok = (rows >= 0)[:, None] & (cols >= 0)[None, :]
    r, c = np.nonzero(ok)
    out[r, c] = grid[rows[r], cols[c]]
    if rshape == () and cshape == ():
        return from_numpy(out[0, 0])
    if rshape == ():
        return out[0]
    if cshape == ():
        return canonical(out[:, :1])
    return canonical(out)


_ARITH = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "%": np.fmod,
          "^": np.power}
_CMP = {"==": np.equal, "!=": np.not_equal, "<": np.less, "<=": np.less_equal,
        ">": np.greater, ">=": np.greater_equal}


def elementwise(op: str, a, b):
    """A dot operator (``.+``, ``.==``, ``.&&`` …) element by element: two arrays of the same
    dimensions, or an array and a single value."""
    arrays = [x for x in (a, b) if isinstance(x, np.ndarray)]
    if len(arrays) == 2 and a.shape != b.shape:
        raise CGARuntimeError(f"element-wise '.{op}' on arrays of different dimensions "
                              f"({_dims(a)} and {_dims(b)})")
    shape = arrays[0].shape if arrays else ()
    if op in ("&&", "||"):
        fa, fb = (np.vectorize(to_bool, otypes=[bool])(x) if isinstance(x, np.ndarray)
                  else to_bool(x) for x in (a, b))
        out = np.logical_and(fa, fb) if op == "&&" else np.logical_or(fa, fb)
    elif any(isinstance(x, np.ndarray) and x.dtype == object or isinstance(x, str)
             for x in (a, b)):
        sa, sb = (x.astype(object) if isinstance(x, np.ndarray) else to_str(x) for x in (a, b))
        if op == "+":
            out = np.frompyfunc(lambda x, y: to_str(from_numpy(x)) + to_str(from_numpy(y)),
                                2, 1)(sa, sb)
        elif op in _CMP:
            fn = {"==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le,
                  ">": operator.gt, ">=": operator.ge}[op]
            out = np.asarray(np.frompyfunc(
                lambda x, y: fn(to_str(from_numpy(x)), to_str(from_numpy(y))), 2, 1)(sa, sb),
                dtype=bool)
        else:
            raise CGARuntimeError(f"'.{op}' does not apply to strings")
    else:
        fa, fb = (x.astype(float) if isinstance(x, np.ndarray) else to_float(x) for x in (a, b))
        with np.errstate(all="ignore"):
            out = (_CMP[op] if op in _CMP else _ARITH[op])(fa, fb)
    if not shape:
        return from_numpy(np.asarray(out).reshape(-1)[0])
    return np.asarray(out).reshape(shape)


def element_not(v):
    """``.!a``: every element negated."""
    if isinstance(v, np.ndarray):
        return ~np.vectorize(to_bool, otypes=[bool])(v) if v.size else v.astype(bool)
    return not to_bool(v)


def _dims(a: np.ndarray) -> str:
    return f"{a.shape[0]}x{a.shape[1]}" if a.ndim == 2 else str(a.size)


def order(a: np.ndarray, b: np.ndarray) -> int:
    """-1, 0 or 1: arrays compared element by element, row by row; when those agree the one
    with fewer columns, then the one with fewer rows, is less (the reference's rule)."""
    ga = a.reshape(1, -1) if a.ndim == 1 else a
    gb = b.reshape(1, -1) if b.ndim == 1 else b
    strings = ga.dtype == object or gb.dtype == object
    for r in range(min(ga.shape[0], gb.shape[0])):
        for c in range(min(ga.shape[1], gb.shape[1])):
            x, y = from_numpy(ga[r, c]), from_numpy(gb[r, c])
            if strings:
                x, y = to_str(x), to_str(y)
            else:
                x, y = to_float(x), to_float(y)
            if x < y:
                return -1
            if x > y:
                return 1
    for da, db in ((ga.shape[1], gb.shape[1]), (ga.shape[0], gb.shape[0])):
        if da != db:
            return -1 if da < db else 1
    return 0
