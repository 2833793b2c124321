"""The GML interpreter: an operand stack, a dictionary stack and an explicit execution stack.

GML (Havemann 2005) is PostScript-like: every token is data that goes onto the operand stack
or a name that is looked up through the dictionary stack (then the built-in operators) and
executed.  A name bound to an executable array ``{ … }`` runs it.  The program is user text:
it is interpreted here, never handed to Python, and it cannot reach files, the network or the
system.  Every run is bounded by :class:`Limits`.

The interpreter is iterative (no Python recursion per GML call), so recursion depth is a
counted limit, never a ``RecursionError``.
"""

from __future__ import annotations

import difflib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, fields

from .errors import GmlLimitError, GmlRuntimeError
from .tokens import Proc, Token

# ----------------------------------------------------------------------------------- values


class Name(str):
    """A literal name (``/X``) on the operand stack."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "/" + str(self)


class Point(tuple):
    """A 3D point or vector ``(x,y,z)``."""

    __slots__ = ()

    def __new__(cls, xyz):
        return tuple.__new__(cls, (float(xyz[0]), float(xyz[1]), float(xyz[2])))

    def __repr__(self) -> str:
        return "(" + ",".join(f"{v:g}" for v in self) + ")"


class GDict(dict):
    """A GML dictionary (``dict``, ``begin``/``end``)."""

    __hash__ = object.__hash__  # dictionaries compare by identity, as in PostScript

    def __eq__(self, other) -> bool:
        return self is other


class _Mark:
    __slots__ = ()

    def __repr__(self) -> str:
        return "-mark-"


MARK = _Mark()
_MAX_EXACT_INT = 2 ** 53


def type_name(v) -> str:
    """The GML type of a value, for error messages."""
    if type(v) is bool:
        return "boolean"
    if type(v) in (int, float):
        return "number"
    for cls, name in ((Name, "name"), (Point, "point"), (Proc, "executable array"),
                      (list, "array"), (GDict, "dictionary"), (_Mark, "mark")):
        if isinstance(v, cls):
            return name
    return getattr(v, "gml_type", type(v).__name__)


def is_number(v) -> bool:
    return type(v) in (int, float)


# ----------------------------------------------------------------------------------- limits


@dataclass(frozen=True)
class Limits:
    """Bounds of one GML run; reaching one raises :class:`GmlLimitError` naming it.

    Parameters
    ----------
    max_operations : tokens executed (every number, name and operator counts one).
    max_seconds : wall-clock time of the run.
    max_stack : operand-stack depth.
    max_dict_stack : dictionary-stack depth (``begin``).
    max_call_depth : nested calls of executable arrays and loops (recursion).
    max_array : elements of one array (``array``, ``[ … ]``).
    max_cells : array elements, dictionary entries, points and scopes made in all (memory).
    max_shapes : shapes (scopes) made by the shape-grammar words.
    max_planes : planes of one convex polyhedron.
    """

    max_operations: int = 10_000_000
    max_seconds: float = 30.0
    max_stack: int = 100_000
    max_dict_stack: int = 256
    max_call_depth: int = 1_000
    max_array: int = 100_000
    max_cells: int = 10_000_000
    max_shapes: int = 1_000_000
    max_planes: int = 256

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, int | float) or isinstance(v, bool) or not v > 0:
                raise ValueError(f"Limits.{f.name} must be a positive number, not {v!r}")


# ----------------------------------------------------------------------------------- frames


class _Frame:
    __slots__ = ("items", "i", "loop", "a", "b", "c")

    def __init__(self, items, loop: str = "", a=None, b=None, c=None):
        self.items, self.i, self.loop, self.a, self.b, self.c = items, 0, loop, a, b, c


Operator = Callable[["Interpreter"], None]
OPERATORS: dict[str, Operator] = {}


def operator(*names: str):
    """Register a built-in operator under one or more names."""

    def deco(fn: Operator) -> Operator:
        for n in names:
            OPERATORS[n] = fn
        return fn

    return deco


class Interpreter:
    """Runs GML programs.  ``words`` adds operators (the shape-grammar library) on top of the
    built-in ones; ``on_call(interp, name)`` is told of every executable array called by name."""

    def __init__(self, limits: Limits | None = None, path: str = "<gml>",
                 words: dict[str, Operator] | None = None,
                 on_call: Callable[[Interpreter, str], None] | None = None):
        self.limits = limits or Limits()
        self.path = path
        self.system: dict[str, Operator] = dict(OPERATORS)
        if words:
            self.system.update(words)
        self.on_call = on_call
        self.stack: list = []
        self.dicts: list[GDict] = [GDict()]
        self.frames: list[_Frame] = []
        self.ops = 0
        self.cells = 0
        self.token: Token | Proc | None = None
        self.deadline = 0.0
        self.finished = False

    # -- errors --------------------------------------------------------------------------------
    def where(self) -> tuple[int, int]:
        t = self.token
        return (t.line, t.column) if t is not None else (0, 0)

    def current_word(self) -> str:
        t = self.token
        if isinstance(t, Token):
            return {"bind": "!", "get": ":", "literal": "/"}.get(t.kind, "") + str(t.value)
        return "{"

    def error(self, message: str, kind: str = "runtime") -> GmlRuntimeError:
        line, col = self.where()
        return GmlRuntimeError(f"'{self.current_word()}': {message}", self.path, line, col, kind)

    def limit(self, name: str, what: str) -> GmlLimitError:
        line, col = self.where()
        value = getattr(self.limits, name)
        return GmlLimitError(
            f"{what} (limit {name}={value:,}; raise it with limits=Limits({name}=…))",
            self.path, line, col, name)

    # -- the operand stack ----------------------------------------------------------------------
    def push(self, v) -> None:
        if len(self.stack) >= self.limits.max_stack:
            raise self.limit("max_stack", "the operand stack grew too deep")
        self.stack.append(v)

    def pop(self):
        if not self.stack:
            raise self.error("stack underflow (needs an operand, the stack is empty)", "underflow")
        return self.stack.pop()

    def need(self, n: int) -> None:
        if len(self.stack) < n:
            raise self.error(f"stack underflow (needs {n} operands, the stack holds "
                             f"{len(self.stack)})", "underflow")

    def pop_type(self, check: Callable[[object], bool], what: str):
        v = self.pop()
        if not check(v):
            raise self.error(f"expects {what}, got {type_name(v)} {_show(v)}", "type")
        return v

    def pop_num(self) -> float:
        return self.pop_type(is_number, "a number")

    def pop_int(self) -> int:
        v = self.pop_num()
        if type(v) is float:
            if not v.is_integer():
                raise self.error(f"expects an integer, got {v:g}", "type")
            v = int(v)
        return v

    def pop_bool(self) -> bool:
        return self.pop_type(lambda v: type(v) is bool, "a boolean")

    def pop_proc(self) -> Proc:
        return self.pop_type(lambda v: isinstance(v, Proc), "an executable array { … }")

    def pop_array(self) -> list:
        return self.pop_type(lambda v: type(v) is list, "an array [ … ]")

    def pop_name(self) -> Name:
        return self.pop_type(lambda v: isinstance(v, Name), "a literal name (/X)")

    def pop_point(self) -> Point:
        return self.pop_type(lambda v: isinstance(v, Point), "a point (x,y,z)")

    def count_cells(self, n: int) -> None:
        self.cells += n
        if self.cells > self.limits.max_cells:
            raise self.limit("max_cells", "the program made too many values (memory)")

    def check_array(self, n: int) -> None:
        if n > self.limits.max_array:
            raise self.limit("max_array", f"an array of {n:,} elements is too large")
        self.count_cells(n)

    # -- names ----------------------------------------------------------------------------------
    def lookup(self, name: str):
        for d in reversed(self.dicts):
            if name in d:
                return d[name]
        if name in self.system:
            return self.system[name]
        raise self.unknown(name)

    def variable(self, name: str):
        """The value bound to ``name`` in the dictionary stack (``:name``), never executed."""
        for d in reversed(self.dicts):
            if name in d:
                return d[name]
        if name in self.system:
            raise self.error(f"'{name}' is an operator, not a variable (bind one with "
                             f"!{name} or /{name} … def)", "name")
        raise self.unknown(name)

    def unknown(self, name: str) -> GmlRuntimeError:
        known = set(self.system)
        for d in self.dicts:
            known.update(k for k in d if isinstance(k, str))
        close = difflib.get_close_matches(name, sorted(known), n=1, cutoff=0.6)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        line, col = self.where()
        return GmlRuntimeError(f"unknown name '{name}'{hint}", self.path, line, col, "name")

    def define(self, key, value) -> None:
        d = self.dicts[-1]
        if key not in d:
            self.count_cells(1)
        d[key] = value

    def call(self, proc: Proc, loop: str = "", a=None, b=None, c=None) -> None:
        if len(self.frames) >= self.limits.max_call_depth:
            raise self.limit("max_call_depth", "calls nested too deeply (runaway recursion?)")
        self.frames.append(_Frame(proc.items if not loop else proc, loop, a, b, c))

    def execute(self, value, name: str = "") -> None:
        """Execute ``value`` as if met by name: procs run, operators apply, data is pushed."""
        if isinstance(value, Proc):
            if name and self.on_call is not None:
                self.on_call(self, name)
            self.call(value)
        elif callable(value) and not isinstance(value, list | GDict | str | tuple):
            value(self)
        else:
            self.push(value)

    # -- running --------------------------------------------------------------------------------
    def run(self, program: Proc) -> None:
        """Run a parsed program (see :func:`facadeforge.gml.tokens.parse`)."""
        self.deadline = time.monotonic() + self.limits.max_seconds
        self.call(program)
        try:
            self._loop()
        except (ArithmeticError, ValueError) as e:  # math domain, float → int of inf/nan
            if isinstance(e, GmlRuntimeError | GmlLimitError):
                raise
            raise self.error(f"arithmetic failed ({e})", "range") from None

    def _loop(self) -> None:
        frames = self.frames
        max_ops = self.limits.max_operations
        while frames:
            f = frames[-1]
            loop = f.loop
            if not loop:
                items = f.items
                if f.i >= len(items):
                    frames.pop()
                    continue
                item = items[f.i]
                f.i += 1
                if f.i >= len(items):
                    frames.pop()  # tail call: a procedure ending in a call does not nest
                self.token = item
                self.ops += 1
                if self.ops > max_ops:
                    raise self.limit("max_operations", "the program executed too many operations")
                if not self.ops & 1023 and time.monotonic() > self.deadline:
                    raise self.limit("max_seconds", "the program ran too long")
                self._step(item)
                if self.finished:
                    return
                continue
            self.ops += 1  # every turn of a loop costs one, even with an empty body
            if self.ops > max_ops:
                raise self.limit("max_operations", "the program executed too many operations")
            if not self.ops & 1023 and time.monotonic() > self.deadline:
                raise self.limit("max_seconds", "the program ran too long")
            if loop == "repeat":  # a: proc, b: remaining
                if f.b <= 0:
                    frames.pop()
                    continue
                f.b -= 1
                self.call(f.items)
            elif loop == "for":  # a: current, b: step, c: limit
                if (f.b > 0 and f.a > f.c) or (f.b < 0 and f.a < f.c):
                    frames.pop()
                    continue
                self.push(f.a)
                f.a = _norm(f.a + f.b)
                self.call(f.items)
            elif loop == "forall":  # a: the elements
                if f.i >= len(f.a):
                    frames.pop()
                    continue
                v = f.a[f.i]
                f.i += 1
                if isinstance(v, tuple) and type(f.a) is not list:
                    self.push(v[0])
                    self.push(v[1])
                else:
                    self.push(v)
                self.call(f.items)
            else:  # "loop"
                self.call(f.items)

    def _step(self, item) -> None:
        if type(item) is Proc:
            self.push(item)
            return
        kind = item.kind
        if kind == "number":
            self.push(item.value)
        elif kind == "name":
            self.execute(self.lookup(item.value), item.value)
        elif kind == "literal":
            self.push(Name(item.value))
        elif kind == "point":
            self.count_cells(1)
            self.push(Point(item.value))
        elif kind == "bind":
            self.define(item.value, self.pop())
        elif kind == "get":
            self.push(self.variable(item.value))
        elif kind == "[":
            self.push(MARK)
        elif kind == "]":
            _close_array(self)
        else:  # pragma: no cover - the reader makes no other tokens
            raise self.error(f"unexpected token {kind}")


def _show(v) -> str:
    if type(v) is list:
        return f"[…{len(v)}]"
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "…"


def _norm(v):
    """Keep integers exact while small; beyond 2**53 they become floats (no huge ints)."""
    if type(v) is int and not -_MAX_EXACT_INT <= v <= _MAX_EXACT_INT:
        return float(v)
    return v


def _close_array(it: Interpreter) -> None:
    st = it.stack
    for k in range(len(st) - 1, -1, -1):
        if st[k] is MARK:
            items = st[k + 1:]
            it.check_array(len(items))
            del st[k:]
            st.append(items)
            return
    raise it.error("']' without a matching '[' on the stack", "range")


# ----------------------------------------------------------------------------- operators


@operator("add")
def _add(it: Interpreter) -> None:
    it.need(2)
    b, a = it.pop(), it.pop()
    if is_number(a) and is_number(b):
        it.push(_norm(a + b))
    elif isinstance(a, Point) and isinstance(b, Point):
        it.push(Point((a[0] + b[0], a[1] + b[1], a[2] + b[2])))
    else:
        raise it.error(f"adds two numbers or two points, not {type_name(a)} and {type_name(b)}",
                       "type")


@operator("sub")
def _sub(it: Interpreter) -> None:
    it.need(2)
    b, a = it.pop(), it.pop()
    if is_number(a) and is_number(b):
        it.push(_norm(a - b))
    elif isinstance(a, Point) and isinstance(b, Point):
        it.push(Point((a[0] - b[0], a[1] - b[1], a[2] - b[2])))
    else:
        raise it.error(f"subtracts two numbers or two points, not {type_name(a)} and "
                       f"{type_name(b)}", "type")


@operator("mul")
def _mul(it: Interpreter) -> None:
    it.need(2)
    b, a = it.pop(), it.pop()
    if is_number(a) and is_number(b):
        it.push(_norm(a * b))
    elif isinstance(a, Point) and is_number(b):
        it.push(Point((a[0] * b, a[1] * b, a[2] * b)))
    elif is_number(a) and isinstance(b, Point):
        it.push(Point((b[0] * a, b[1] * a, b[2] * a)))
    elif isinstance(a, Point) and isinstance(b, Point):
        it.push(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
    else:
        raise it.error(f"multiplies numbers and points, not {type_name(a)} and {type_name(b)}",
                       "type")


@operator("div")
def _div(it: Interpreter) -> None:
    it.need(2)
    b, a = it.pop(), it.pop()
    if not is_number(b) or not (is_number(a) or isinstance(a, Point)):
        raise it.error(f"divides a number or point by a number, not {type_name(a)} by "
                       f"{type_name(b)}", "type")
    if b == 0:
        raise it.error("division by zero", "zero")
    if isinstance(a, Point):
        it.push(Point((a[0] / b, a[1] / b, a[2] / b)))
    else:
        it.push(a / b)


@operator("idiv", "mod")
def _idiv(it: Interpreter) -> None:
    b, a = it.pop_int(), it.pop_int()
    if b == 0:
        raise it.error("division by zero", "zero")
    it.push(a % b if it.current_word() == "mod" else int(a / b))


def _unary(name: str, fn, domain: Callable[[float], bool] | None = None, why: str = ""):
    def op(it: Interpreter) -> None:
        v = it.pop_num()
        if domain is not None and not domain(v):
            raise it.error(f"{why}, got {v:g}", "range")
        it.push(_norm(fn(v)))

    OPERATORS[name] = op


_unary("abs", abs)
_unary("sqrt", math.sqrt, lambda v: v >= 0, "takes a number ≥ 0")
_unary("floor", lambda v: v if type(v) is int else _int_or_float(math.floor, v))
_unary("ceil", lambda v: v if type(v) is int else _int_or_float(math.ceil, v))
_unary("round", lambda v: v if type(v) is int else _int_or_float(lambda x: math.floor(x + 0.5), v))
_unary("truncate", lambda v: v if type(v) is int else _int_or_float(math.trunc, v))
_unary("sin", lambda v: math.sin(math.radians(v)), math.isfinite, "takes a finite angle")
_unary("cos", lambda v: math.cos(math.radians(v)), math.isfinite, "takes a finite angle")
_unary("ln", math.log, lambda v: v > 0, "takes a number > 0")
_unary("exp", lambda v: math.exp(min(v, 700.0)))


def _int_or_float(fn, v: float):
    return fn(v) if math.isfinite(v) and abs(v) < _MAX_EXACT_INT else v


@operator("neg")
def _neg(it: Interpreter) -> None:
    v = it.pop()
    if is_number(v):
        it.push(-v)
    elif isinstance(v, Point):
        it.push(Point((-v[0], -v[1], -v[2])))
    else:
        raise it.error(f"negates a number or a point, not {type_name(v)}", "type")


@operator("min", "max")
def _minmax(it: Interpreter) -> None:
    b, a = it.pop_num(), it.pop_num()
    it.push(min(a, b) if it.current_word() == "min" else max(a, b))


@operator("atan")
def _atan(it: Interpreter) -> None:
    x, y = it.pop_num(), it.pop_num()
    it.push(math.degrees(math.atan2(y, x)))


@operator("pow")
def _pow(it: Interpreter) -> None:
    e, b = float(it.pop_num()), float(it.pop_num())
    if b == 0 and e < 0:
        raise it.error("division by zero (0 to a negative power)", "zero")
    if b < 0 and not e.is_integer():
        raise it.error("a negative number to a fractional power", "range")
    try:
        it.push(b ** e)
    except OverflowError:
        it.push(math.inf)


# -- comparisons and logic


@operator("eq", "ne")
def _eq(it: Interpreter) -> None:
    it.need(2)
    b, a = it.pop(), it.pop()
    same = a is b if type(a) is list or type(b) is list or isinstance(a, Proc) else (
        type(a) is bool) == (type(b) is bool) and a == b
    it.push(same if it.current_word() == "eq" else not same)


def _compare(name: str, fn):
    def op(it: Interpreter) -> None:
        b, a = it.pop_num(), it.pop_num()
        it.push(fn(a, b))

    OPERATORS[name] = op


_compare("lt", lambda a, b: a < b)
_compare("le", lambda a, b: a <= b)
_compare("gt", lambda a, b: a > b)
_compare("ge", lambda a, b: a >= b)


@operator("and", "or")
def _andor(it: Interpreter) -> None:
    b, a = it.pop_bool(), it.pop_bool()
    it.push((a and b) if it.current_word() == "and" else (a or b))


@operator("not")
def _not(it: Interpreter) -> None:
    it.push(not it.pop_bool())


@operator("true")
def _true(it: Interpreter) -> None:
    it.push(True)


@operator("false")
def _false(it: Interpreter) -> None:
    it.push(False)


# -- the stack


@operator("pop")
def _pop(it: Interpreter) -> None:
    it.pop()


@operator("dup")
def _dup(it: Interpreter) -> None:
    v = it.pop()
    it.push(v)
    it.push(v)


@operator("exch")
def _exch(it: Interpreter) -> None:
    it.need(2)
    st = it.stack
    st[-1], st[-2] = st[-2], st[-1]


@operator("copy")
def _copy(it: Interpreter) -> None:
    n = it.pop_int()
    if n < 0:
        raise it.error(f"copies n ≥ 0 elements, got {n}", "range")
    it.need(n)
    if len(it.stack) + n > it.limits.max_stack:
        raise it.limit("max_stack", "the operand stack grew too deep")
    it.count_cells(n)
    if n:
        it.stack.extend(it.stack[-n:])


@operator("index")
def _index(it: Interpreter) -> None:
    n = it.pop_int()
    if n < 0:
        raise it.error(f"takes an index ≥ 0, got {n}", "range")
    it.need(n + 1)
    it.push(it.stack[-1 - n])


@operator("roll")
def _roll(it: Interpreter) -> None:
    j, n = it.pop_int(), it.pop_int()
    if n < 0:
        raise it.error(f"rolls n ≥ 0 elements, got {n}", "range")
    it.need(n)
    if n:
        j %= n
        top = it.stack[len(it.stack) - n:]
        it.stack[len(it.stack) - n:] = top[n - j:] + top[:n - j]


@operator("clear")
def _clear(it: Interpreter) -> None:
    it.stack.clear()


@operator("count")
def _count(it: Interpreter) -> None:
    it.push(len(it.stack))


@operator("mark")
def _mark(it: Interpreter) -> None:
    it.push(MARK)


# -- arrays and dictionaries


@operator("length")
def _length(it: Interpreter) -> None:
    v = it.pop()
    if type(v) is list or isinstance(v, GDict):
        it.push(len(v))
    elif isinstance(v, Proc):
        it.push(len(v.items))
    elif isinstance(v, Point):
        it.push(3)
    else:
        raise it.error(f"takes an array or dictionary, not {type_name(v)}", "type")


def _index_of(it: Interpreter, seq_len: int, i) -> int:
    if not is_number(i) or (type(i) is float and not i.is_integer()):
        raise it.error(f"takes an integer index, got {type_name(i)} {_show(i)}", "type")
    i = int(i)
    if not 0 <= i < seq_len:
        raise it.error(f"index {i} is out of range 0…{seq_len - 1}", "range")
    return i


@operator("get")
def _get(it: Interpreter) -> None:
    it.need(2)
    k, v = it.pop(), it.pop()
    if type(v) is list or isinstance(v, Point):
        it.push(v[_index_of(it, len(v), k)])
    elif isinstance(v, Proc):
        raise it.error("cannot index an executable array", "type")
    elif isinstance(v, GDict):
        key = str(k) if isinstance(k, Name) else k
        if not isinstance(key, str) or key not in v:
            raise it.error(f"key {_show(k)} is not in the dictionary", "range")
        it.push(v[key])
    else:
        raise it.error(f"takes an array or dictionary, not {type_name(v)}", "type")


@operator("put")
def _put(it: Interpreter) -> None:
    it.need(3)
    x, k, v = it.pop(), it.pop(), it.pop()
    if type(v) is list:
        v[_index_of(it, len(v), k)] = x
    elif isinstance(v, GDict):
        if not isinstance(k, Name):
            raise it.error(f"dictionary keys are names (/key), not {type_name(k)}", "type")
        if str(k) not in v:
            it.count_cells(1)
        v[str(k)] = x
    else:
        raise it.error(f"takes an array or dictionary, not {type_name(v)}", "type")


@operator("aload")
def _aload(it: Interpreter) -> None:
    a = it.pop_array()
    if len(it.stack) + len(a) + 1 > it.limits.max_stack:
        raise it.limit("max_stack", "the operand stack grew too deep")
    it.stack.extend(a)
    it.stack.append(a)


@operator("array")
def _array(it: Interpreter) -> None:
    n = it.pop_int()
    if n < 0:
        raise it.error(f"takes a size ≥ 0, got {n}", "range")
    it.check_array(n)
    it.push([0] * n)


@operator("append")
def _append(it: Interpreter) -> None:
    it.need(2)
    x = it.pop()
    a = it.pop_array()
    it.check_array(len(a) + 1)
    a.append(x)
    it.push(a)


@operator("dict")
def _dict(it: Interpreter) -> None:
    it.count_cells(1)
    it.push(GDict())


@operator("begin")
def _begin(it: Interpreter) -> None:
    d = it.pop_type(lambda v: isinstance(v, GDict), "a dictionary")
    if len(it.dicts) >= it.limits.max_dict_stack:
        raise it.limit("max_dict_stack", "too many dictionaries begun")
    it.dicts.append(d)


@operator("end")
def _end(it: Interpreter) -> None:
    if len(it.dicts) <= 1:
        raise it.error("'end' without 'begin'", "range")
    it.dicts.pop()


@operator("def")
def _def(it: Interpreter) -> None:
    it.need(2)
    v = it.pop()
    k = it.pop_name()
    it.define(str(k), v)


@operator("load")
def _load(it: Interpreter) -> None:
    it.push(it.lookup(str(it.pop_name())))


@operator("known")
def _known(it: Interpreter) -> None:
    k = it.pop_name()
    d = it.pop_type(lambda v: isinstance(v, GDict), "a dictionary")
    it.push(str(k) in d)


# -- control


@operator("if")
def _if(it: Interpreter) -> None:
    p = it.pop_proc()
    if it.pop_bool():
        it.call(p)


@operator("ifelse")
def _ifelse(it: Interpreter) -> None:
    no, yes = it.pop_proc(), it.pop_proc()
    it.call(yes if it.pop_bool() else no)


def control_repeat(it: Interpreter) -> None:
    """``n { … } repeat``: run the procedure n times."""
    p = it.pop_proc()
    n = it.pop_int()
    if n < 0:
        raise it.error(f"repeats n ≥ 0 times, got {n}", "range")
    it.call(p, "repeat", b=n)


OPERATORS["repeat"] = control_repeat


@operator("for")
def _for(it: Interpreter) -> None:
    p = it.pop_proc()
    limit, step, start = it.pop_num(), it.pop_num(), it.pop_num()
    if step == 0:
        raise it.error("step 0 would loop for ever", "range")
    if not all(math.isfinite(v) for v in (limit, step, start)):
        raise it.error("start, step and limit must be finite", "range")
    it.call(p, "for", a=start, b=step, c=limit)


@operator("forall")
def _forall(it: Interpreter) -> None:
    p = it.pop_proc()
    v = it.pop()
    if type(v) is list or isinstance(v, Point):
        seq = list(v)
    elif isinstance(v, GDict):
        seq = list(v.items())
        it.count_cells(len(seq))
        it.call(p, "forall", a=tuple(seq))
        return
    else:
        raise it.error(f"iterates over an array or dictionary, not {type_name(v)}", "type")
    it.count_cells(len(seq))
    it.call(p, "forall", a=seq)


@operator("loop")
def _loop(it: Interpreter) -> None:
    it.call(it.pop_proc(), "loop")


@operator("exit")
def _exit(it: Interpreter) -> None:
    frames = it.frames
    for k in range(len(frames) - 1, -1, -1):
        if frames[k].loop:
            del frames[k:]
            return
    raise it.error("'exit' outside a loop (repeat, for, forall, loop)", "range")


@operator("exec")
def _exec(it: Interpreter) -> None:
    v = it.pop()
    if isinstance(v, Name):
        it.execute(it.lookup(str(v)), str(v))
    elif isinstance(v, Proc):
        it.call(v)
    else:
        it.push(v)


# -- points


def _coord(i: int):
    def op(it: Interpreter) -> None:
        it.push(it.pop_point()[i])

    return op


OPERATORS["getx"], OPERATORS["gety"], OPERATORS["getz"] = _coord(0), _coord(1), _coord(2)


@operator("vector3")
def _vector3(it: Interpreter) -> None:
    z, y, x = it.pop_num(), it.pop_num(), it.pop_num()
    it.count_cells(1)
    it.push(Point((x, y, z)))


@operator("vector2")
def _vector2(it: Interpreter) -> None:
    y, x = it.pop_num(), it.pop_num()
    it.count_cells(1)
    it.push(Point((x, y, 0.0)))


@operator("dot")
def _dot(it: Interpreter) -> None:
    b, a = it.pop_point(), it.pop_point()
    it.push(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


@operator("cross")
def _cross(it: Interpreter) -> None:
    b, a = it.pop_point(), it.pop_point()
    it.push(Point((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                   a[0] * b[1] - a[1] * b[0])))


@operator("norm")
def _normop(it: Interpreter) -> None:
    it.push(math.hypot(*it.pop_point()))


@operator("normalize")
def _normalize(it: Interpreter) -> None:
    p = it.pop_point()
    n = math.hypot(*p)
    if n == 0 or not math.isfinite(n):
        raise it.error("cannot normalize a zero or infinite vector", "zero")
    it.push(Point((p[0] / n, p[1] / n, p[2] / n)))


@operator("dist")
def _dist(it: Interpreter) -> None:
    b, a = it.pop_point(), it.pop_point()
    it.push(math.dist(a, b))
