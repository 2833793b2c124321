"""CGA runtime values: float, str, bool, arrays (numpy), and the size markers of ``split``/``s``."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class CGARuntimeError(Exception):
    """A problem inside a rule while deriving (CityEngine reports these as warnings)."""


@dataclass(frozen=True)
class Relative:
    """``'v``: a fraction of the scope size along the axis where it is used."""

    value: float


@dataclass(frozen=True)
class Floating:
    """``~v``: a nominal size that stretches to fill what fixed sizes leave."""

    value: float


def to_float(v, what: str = "value") -> float:
    if isinstance(v, bool):
        return 1.0 if v else 0.0
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, (Relative, Floating)):
        return float(v.value)
    if isinstance(v, str):
        try:
            return float(v)
        except ValueError:
            return math.nan
    if isinstance(v, np.ndarray) and v.size == 1:
        return float(v.reshape(-1)[0])
    raise CGARuntimeError(f"{what} must be a number, got {type_name(v)}")


def to_bool(v) -> bool:
    if isinstance(v, bool):
        return v
    if isinstance(v, (int, float)):
        return v != 0 and not math.isnan(v)
    if isinstance(v, str):
        return v.strip().lower() in ("true", "1", "yes")
    raise CGARuntimeError(f"expected a bool, got {type_name(v)}")


def format_float(v: float) -> str:
    """CGA's ``str(float)``: integers without a decimal point, others with up to 10 digits."""
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    return format(v, ".10g")


def to_str(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return format_float(float(v))
    if isinstance(v, np.ndarray):
        return format_array(v)
    if isinstance(v, (Relative, Floating)):
        return to_str(v.value)
    return str(v)


def format_array(a: np.ndarray) -> str:
    """CityEngine's text of an array: ``(3)[1,2,3]``, or for rows, ``(2x3)`` then each row
    with its columns right-aligned, three spaces apart (as ``print`` shows a table)."""
    cells = [to_str(from_numpy(x)) for x in a.reshape(-1)]
    if a.ndim < 2:
        return f"({len(cells)})[{','.join(cells)}]"
    rows, cols = a.shape
    widths = [max((len(cells[r * cols + c]) for r in range(rows)), default=0) for c in range(cols)]
    lines = ["".join("   " + cells[r * cols + c].rjust(widths[c]) for c in range(cols))
             for r in range(rows)]
    return "\n".join([f"({rows}x{cols})", *lines])


def type_name(v) -> str:
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, (int, float)):
        return "float"
    if isinstance(v, str):
        return "string"
    if isinstance(v, np.ndarray):
        return {"f": "float[]", "b": "bool[]"}.get(v.dtype.kind, "string[]")
    return type(v).__name__


def make_array(values: list) -> np.ndarray:
    if all(isinstance(x, bool) for x in values):
        return np.array(values, dtype=bool)
    if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in values):
        return np.array(values, dtype=float)
    return np.array([to_str(x) for x in values], dtype=object)


def from_numpy(x):
    """Scalar from a numpy element (keeps CGA's three scalar types)."""
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.floating, np.integer, int, float)):
        return float(x)
    return str(x)
