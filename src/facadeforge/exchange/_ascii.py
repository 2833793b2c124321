"""Numbers to text for the text formats (OBJ), vectorised.

A city's OBJ holds millions of ``v``, ``vt`` and ``f`` lines; ``np.savetxt`` formats them one
row at a time in Python (slow: ``docs/benchmarks.md``).  :func:`format_lines` writes every
digit of a block of lines with a few numpy passes over all numbers at once instead, into one
byte buffer: each number is rounded to fixed point, its digits are peeled off one decimal place
per pass, and separators, signs and decimal points are placed by offset arithmetic.

The text equals Python's ``"%.{p}f"`` of each number, except that a value which rounds to zero
prints without a sign (``0.000000``, never ``-0.000000``) and that rounding is of ``x · 10^p``
to the nearest integer (ties to even) rather than of the exact binary value; the two differ at
most by one unit in the last printed place, in rare near-tie cases.
"""

from __future__ import annotations

import numpy as np

#: Numbers formatted per block: bounds the temporary arrays (a few hundred bytes per number).
_BLOCK = 1 << 20
#: Above this magnitude (× 10^precision) fixed point would overflow int64: Python formats.
_LIMIT = 2.0 ** 62


def format_lines(head: str, values: np.ndarray, line_starts: np.ndarray | None = None,
                 separators: np.ndarray | None = None, precision: int = 0, *, sep: str = " ",
                 end: str = "\n") -> bytes:
    """Lines of numbers as ASCII bytes: ``head``, the line's numbers, ``end``.

    Besides OBJ lines (``v 1.5 2 3\\n``) this writes JSON arrays of numbers: with
    ``head="["``, ``sep=","`` and ``end="],"`` each line is one array (CityJSON vertices).

    Parameters
    ----------
    head : str
        Start of every line, e.g. ``"v "`` or ``"f "`` (ASCII; written before the first number).
    values : (N,) or (L, K) array
        The numbers.  Two-dimensional: one line per row.  One-dimensional: ``line_starts``
        says where each line begins.
    line_starts : (L + 1,) int, optional
        Offsets of the lines in a one-dimensional ``values`` (increasing, ``line_starts[-1] ==
        N``; no empty lines).
    separators : (N,) uint8, optional
        Byte written before each number that does not start its line (default ``sep``; OBJ
        faces use ``/`` between a vertex and its texture vertex).
    precision : int
        Digits after the decimal point; 0 writes integers (values are rounded).
    sep, end : str
        The separator between numbers (one ASCII character) and what ends each line.

    Returns
    -------
    bytes
        ``L`` lines, each ending in ``end``.
    """
    values = np.asarray(values)
    if values.ndim == 2:
        n_lines, k = values.shape
        flat = values.reshape(-1)
        line_starts = np.arange(0, n_lines * k + 1, k) if k else np.zeros(n_lines + 1, np.int64)
    else:
        flat = values
        if line_starts is None:
            raise ValueError("format_lines: one-dimensional values need line_starts")
    if not head and not end:
        raise ValueError("format_lines: give a head or an end (lines must be told apart)")
    line_starts = np.asarray(line_starts, np.int64)
    if len(line_starts) < 2:
        return b""
    if np.any(np.diff(line_starts) <= 0):
        raise ValueError("format_lines: every line needs at least one number")
    parts = []
    lines_per_block = max(1, _BLOCK // max(1, int(line_starts[-1]) // (len(line_starts) - 1)))
    for a in range(0, len(line_starts) - 1, lines_per_block):
        b = min(a + lines_per_block, len(line_starts) - 1)
        lo, hi = int(line_starts[a]), int(line_starts[b])
        seps = None if separators is None else separators[lo:hi]
        parts.append(_block(head.encode("ascii"), flat[lo:hi], line_starts[a:b + 1] - lo,
                            seps, precision, ord(sep), end.encode("ascii")))
    return b"".join(parts)


def _block(head: bytes, x: np.ndarray, line_starts: np.ndarray, seps, precision: int,
           sep: int, end: bytes) -> bytes:
    scale = 10.0 ** precision
    scaled = np.asarray(x, np.float64) * scale
    if not np.all(np.abs(scaled) < _LIMIT):  # NaN, inf or huge: Python's own formatting
        return _reference(head, x, line_starts, seps, precision, sep, end)
    q = np.rint(scaled).astype(np.int64)
    neg = q < 0
    mag = np.abs(q)
    # digits of each number, at least precision + 1 (a leading "0." for fractions)
    n_digits = np.ones(len(mag), np.int8)
    power = 10
    while power <= int(mag.max(initial=0)):
        n_digits += mag >= power
        power *= 10
    n_digits = np.maximum(n_digits, precision + 1)
    if power <= 2 ** 32:  # 32-bit division is about twice as fast (libdivide)
        mag = mag.astype(np.uint32)
    width = int(n_digits.max(initial=1))
    # one fixed-width row per number, right-aligned: prefix | sign | digits (with the point);
    # the bytes a number does not use are masked out and the rows compacted, in order
    hl, el = len(head), len(end)
    pw = el + hl                           # the line before's end + head before a first number
    point = 1 if precision else 0
    cols = pw + 1 + width + point
    # built column by column (contiguous writes), transposed once for the compaction
    rows = np.empty((cols, len(x)), np.uint8)
    keep = np.zeros((cols, len(x)), bool)
    first = line_starts[:-1]
    rows[pw - 1] = sep if seps is None else np.asarray(seps, np.uint8)
    keep[pw - 1] = True
    for i, c in enumerate(end + head):
        rows[i, first] = c
    keep[:pw, first] = False               # a first number: the prefix instead, that is
    keep[el:pw, first] = True              # the head,
    keep[:el, first[1:]] = True            # after the end of the line before
    rows[pw] = ord("-")
    keep[pw] = neg
    for place in range(width):
        col = cols - 1 - place - (point if place >= precision else 0)
        np.add(mag % 10, 48, out=rows[col], casting="unsafe")
        mag //= 10
        np.greater(n_digits, place, out=keep[col])
    if point:
        rows[cols - 1 - precision] = ord(".")
        keep[cols - 1 - precision] = True
    return rows.T[keep.T].tobytes() + end


def _reference(head: bytes, x, line_starts, seps, precision: int, sep: int = 32,
               end: bytes = b"\n") -> bytes:
    """The same lines through Python's ``%`` formatting (the plain implementation the tests
    compare against, and the path for values fixed point cannot hold)."""
    fmt = f"%.{precision}f" if precision else "%d"
    out = []
    values = np.asarray(x, np.float64).tolist() if precision else np.rint(x).astype(np.int64).tolist()
    seps = [chr(sep)] * len(values) if seps is None else [chr(s) for s in np.asarray(seps).tolist()]
    for a, b in zip(line_starts[:-1].tolist(), line_starts[1:].tolist()):
        parts = [head.decode("ascii") + fmt % values[a]]
        parts += [seps[i] + fmt % values[i] for i in range(a + 1, b)]
        out.append("".join(parts) + end.decode("ascii"))
    return "".join(out).encode("ascii")
