"""Evaluate CGA expressions (AST → value).  Interprets the AST only; never calls Python ``eval``."""

from __future__ import annotations

import math
import operator

import numpy as np

from . import arrays
from . import ast as A
from .budget import check_string_length
from .chance import ROUNDINGS as _ROUNDINGS
from .chance import outcome
from .ops import SHAPE_FUNCTIONS as SELECTOR_FUNCTIONS
from .values import (
    CGARuntimeError,
    Floating,
    Relative,
    to_bool,
    to_float,
    to_str,
)


def _arith(op: str, a, b):
    if op == "+" and (isinstance(a, str) or isinstance(b, str)):
        a, b = to_str(a), to_str(b)
        check_string_length(len(a) + len(b))
        return a + b
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return _array_arith(op, a, b)
    x, y = to_float(a, "left operand"), to_float(b, "right operand")
    if op == "+":
        return x + y
    if op == "-":
        return x - y
    if op == "*":
        return x * y
    if op == "/":
        if y == 0:
            return math.nan if x == 0 else math.copysign(math.inf, x) * (1 if y >= 0 else -1)
        return x / y
    if op == "%":
        return math.fmod(x, y) if y != 0 else math.nan
    if op == "^":
        try:
            return float(x ** y) if not (x < 0 and y != int(y)) else math.nan
        except OverflowError:
            return math.inf
        except ZeroDivisionError:  # 0 ^ -1, as IEEE pow gives it
            return math.inf
    raise CGARuntimeError(f"unknown operator {op}")


def _array_arith(op, a, b):
    if op == "+" and ((isinstance(a, np.ndarray) and a.dtype == object) or
                      (isinstance(b, np.ndarray) and b.dtype == object)):
        pairs = [(to_str(x), to_str(y)) for x, y in np.broadcast(a, b)]
        check_string_length(sum(len(x) + len(y) for x, y in pairs))
        return np.array([x + y for x, y in pairs], dtype=object)
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape != b.shape:
        raise CGARuntimeError(f"'{op}' on arrays of different sizes ({a.size} and {b.size})")
    if any(isinstance(x, np.ndarray) and x.dtype == object for x in (a, b)):
        raise CGARuntimeError(f"'{op}' does not apply to string arrays")
    fa = a.astype(float) if isinstance(a, np.ndarray) else to_float(a)
    fb = b.astype(float) if isinstance(b, np.ndarray) else to_float(b)
    with np.errstate(all="ignore"):
        return {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide,
                "%": np.fmod, "^": np.power}[op](fa, fb)


_CMP = {"==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le,
        ">": operator.gt, ">=": operator.ge}


def _compare(op, a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if op in ("==", "!="):
            same = (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
                    and a.shape == b.shape and bool(np.all(a == b)))
            return same if op == "==" else not same
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            raise CGARuntimeError(f"an array and a single value cannot be compared with {op} "
                                  f"(use .{op} to compare element by element)")
        return _CMP[op](arrays.order(a, b), 0)
    if isinstance(a, str) or isinstance(b, str):
        if op in ("==", "!="):
            return _CMP[op](to_str(a), to_str(b))
        return _CMP[op](to_str(a), to_str(b))
    if isinstance(a, bool) and isinstance(b, bool):
        return _CMP[op](a, b)
    return _CMP[op](to_float(a), to_float(b))


class Evaluator:
    """Expression evaluation, mixed into an environment class.

    The environment provides ``lookup(name, node)``, ``call(name, args, node)``,
    ``random_float()`` (the per-shape random stream) and ``comp_function(node)``.  It is a base
    class, not an object holding its environment: an environment and an evaluator pointing at
    each other would be a reference cycle per rule application, left for the cyclic garbage
    collector (see ``interpreter.deriving``).
    """

    __slots__ = ()

    def note_choice(self, kind: str, params, outcome) -> None:
        """A random choice was made (``pct``: a stochastic branch, ``p``: ``p(prob)``,
        ``list``: ``listRandom``): environments that instance subtrees by their choices'
        outcomes record it (``interpreter.Env``); plain evaluators need not."""

    def discrete_rand(self, node):
        """``floor(rand(…))`` (ceil, rint) as one choice among whole numbers, noted for
        instancing by chance; ``NotImplemented`` where the general path evaluates it."""
        return NotImplemented

    def evaluate(self, node):
        """The value of the expression ``node``."""
        return _DISPATCH[type(node)](self, node)

    __call__ = evaluate

    def num(self, node) -> float:
        return to_float(self(node))

    def _num(self, node):
        return node.value

    def _str(self, node):
        return node.value

    def _bool(self, node):
        return node.value

    def _name(self, node):
        return self.lookup(node.name, node)

    def _call(self, node):
        if node.name in _ROUNDINGS and len(node.args) == 1 and type(node.args[0]) is A.Call \
                and node.args[0].name == "rand":
            v = self.discrete_rand(node)
            if v is not NotImplemented:
                return v
        if node.name in SELECTOR_FUNCTIONS:
            # shape queries take selector keywords (``geometry.area(top)``, ``imageInfo(f, sx)``)
            return self.call(node.name, [self._selector(a) for a in node.args], node)
        return self.call(node.name, [self(a) for a in node.args], node)

    def _selector(self, node):
        if type(node) is A.Name:
            try:
                return self.lookup(node.name, node)
            except CGARuntimeError:
                return node.name
        return self(node)

    def _index(self, node):
        target = self(node.target)
        if not isinstance(target, np.ndarray):
            raise CGARuntimeError("only arrays can be indexed")
        return arrays.index(target, [self(i) for i in node.indices])

    def _array(self, node):
        return arrays.build([[self(e) for e in row] for row in node.rows])

    def _colon(self, node):
        return arrays.colon(self(node.start), None if node.step is None else self(node.step),
                            self(node.stop))

    def _unary(self, node):
        v = self(node.operand)
        if node.op == "-":
            if isinstance(v, np.ndarray):
                if v.dtype == object:
                    raise CGARuntimeError("a string array cannot be negated")
                return -v.astype(float)
            return -to_float(v)
        if node.op == "!":
            return not to_bool(v)
        if node.op == ".!":
            return arrays.element_not(v)
        if node.op == "'":
            return Relative(to_float(v))
        return Floating(to_float(v))

    def _binary(self, node):
        op = node.op
        if op == "&&":
            return to_bool(self(node.left)) and to_bool(self(node.right))
        if op == "||":
            return to_bool(self(node.left)) or to_bool(self(node.right))
        a, b = self(node.left), self(node.right)
        if op[0] == ".":
            return arrays.elementwise(op[1:], a, b)
        if op in _CMP:
            return _compare(op, a, b)
        return _arith(op, a, b)

    def _case(self, node):
        for cond, value in node.branches:
            if to_bool(self(cond)):
                return self(value)
        return self(node.otherwise)

    def _comp_function(self, node):
        return self.comp_function(node)

    def _stochastic(self, node):
        pcts = tuple(pct for pct, _ in node.branches)
        k = outcome("pct", self.random_float(), pcts)
        self.note_choice("pct", pcts, k)
        return self(node.branches[k][1] if k < len(pcts) else node.otherwise)


_DISPATCH = {
    A.Num: Evaluator._num, A.Str: Evaluator._str, A.Bool: Evaluator._bool,
    A.Name: Evaluator._name, A.Call: Evaluator._call, A.Index: Evaluator._index,
    A.Array: Evaluator._array, A.Colon: Evaluator._colon, A.Unary: Evaluator._unary, A.Binary: Evaluator._binary,
    A.CaseExpr: Evaluator._case, A.StochasticExpr: Evaluator._stochastic,
    A.CompFunction: Evaluator._comp_function,
}
