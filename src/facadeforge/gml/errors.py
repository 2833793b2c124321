"""Typed errors of the GML front end: each carries the program's path, line and column."""

from __future__ import annotations

from ..errors import DerivationError, FacadeForgeError, RuleError, RuleSyntaxError


class GmlError(FacadeForgeError):
    """Base of every error a GML program can cause (syntax, runtime, limits)."""

    path: str = "<gml>"
    line: int = 0
    column: int = 0


class GmlSyntaxError(GmlError, RuleSyntaxError):
    """The text does not tokenize or its brackets do not balance."""


class GmlRuntimeError(GmlError, RuleError):
    """The program parses but fails while it runs.  ``kind`` names the failure:
    ``"name"`` (unknown name), ``"underflow"`` (too few operands), ``"type"`` (an operand of the
    wrong type), ``"zero"`` (division by zero), ``"range"`` (index or value out of range),
    ``"grammar"`` (a shape-grammar word used wrongly)."""

    def __init__(self, message: str, path: str = "<gml>", line: int = 0, column: int = 0,
                 kind: str = "runtime"):
        self.kind, self.reason = kind, message
        super().__init__(message, path, line, column)


class GmlLimitError(GmlError, DerivationError):
    """The program ran into one of :class:`facadeforge.gml.interpreter.Limits`."""

    def __init__(self, message: str, path: str = "<gml>", line: int = 0, column: int = 0,
                 limit: str = ""):
        self.path, self.line, self.column, self.limit, self.reason = path, line, column, limit, message
        where = f"{path}:{line}:{column}: " if line else f"{path}: "
        super().__init__(where + message)
