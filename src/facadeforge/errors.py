"""Typed errors: each names the input and the fix (STYLE.md rule 6)."""

from __future__ import annotations


class FacadeForgeError(Exception):
    """Base of every error the toolkit raises on purpose."""


class RuleSyntaxError(FacadeForgeError):
    """A .cga file does not parse.  Carries ``path``, ``line``, ``column`` and the source line."""

    def __init__(self, message: str, path: str = "<rules>", line: int = 0, column: int = 0,
                 source_line: str = ""):
        self.path, self.line, self.column, self.source_line = path, line, column, source_line
        self.reason = message
        text = f"{path}:{line}:{column}: {message}"
        if source_line:
            text += f"\n    {source_line}\n    {' ' * max(column - 1, 0)}^"
        super().__init__(text)


class RuleError(FacadeForgeError):
    """Rules parse but are wrong: unknown rule, attribute, function, bad argument types…"""

    def __init__(self, message: str, path: str = "", line: int = 0, column: int = 0):
        self.path, self.line, self.column = path, line, column
        where = f"{path}:{line}:{column}: " if line else f"{path}: " if path else ""
        super().__init__(where + message)


class DerivationError(FacadeForgeError):
    """A derivation exceeded a cap (depth, shapes, time) or failed in ``--strict`` mode."""


class InputError(FacadeForgeError):
    """A footprint, asset, rule package or other input file is unusable."""
