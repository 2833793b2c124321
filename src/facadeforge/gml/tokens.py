"""GML tokenizer and reader: text → nested items with line and column.

Tokens: numbers (``1``, ``-0.625``, ``1e-3``), names (``split-r``, ``ShapeGrammar.Tools.init``),
literal names (``/X``), variable binds and reads (``!name``, ``:name``), points ``(x,y,z)`` or
``(x,y)``, the brackets ``[ ] { }`` and comments from ``%`` to the end of the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from .errors import GmlSyntaxError

#: Largest program text accepted (characters), number of tokens and bracket nesting.
MAX_SOURCE_CHARS = 8 * 1024 * 1024
MAX_TOKENS = 250_000
MAX_NESTING = 100

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_INT = re.compile(r"[+-]?\d+\Z")
_DELIMS = set("[]{}()%/")
# Typographic characters that text extraction (PDF → text) puts where a program had ASCII.
_RESTORE = {"\u2014": "-", "\u2013": "-", "\u2212": "-", "\u2010": "-", "\u2011": "-",
            "\u00a0": " ", "\u201c": '"', "\u201d": '"'}


@dataclass(frozen=True, slots=True)
class Token:
    """One token.  ``kind``: ``number``, ``name``, ``literal``, ``bind``, ``get``, ``point``,
    ``[``, ``]``; ``value``: the number, the name text or the point's coordinates."""

    kind: str
    value: object
    line: int
    column: int


@dataclass(eq=False, slots=True)
class Proc:
    """An executable array ``{ … }``: its items (tokens and nested procs) and where it starts."""

    items: list = field(default_factory=list)
    line: int = 0
    column: int = 0

    def __repr__(self) -> str:
        return f"{{…{len(self.items)} items}}"


def restore_typography(text: str) -> str:
    """Replace the dashes and spaces that PDF text extraction substitutes (``terminal—box``)."""
    return text.translate(str.maketrans(_RESTORE))


def tokenize(text: str, path: str = "<gml>") -> list[Token]:
    """Split GML text into tokens; a malformed token is a :class:`GmlSyntaxError`."""
    if len(text) > MAX_SOURCE_CHARS:
        raise GmlSyntaxError(f"program is longer than {MAX_SOURCE_CHARS} characters", path, 1, 1)
    lines = text.split("\n")
    out: list[Token] = []

    def fail(msg: str, ln: int, col: int) -> None:
        src = lines[ln - 1] if 0 < ln <= len(lines) else ""
        raise GmlSyntaxError(msg, path, ln, col, src[:200])

    for ln, row in enumerate(lines, 1):
        i, n = 0, len(row)
        while i < n:
            c = row[i]
            col = i + 1
            if c.isspace():
                i += 1
                continue
            if c == "%":
                break
            if c in "[]{}":
                out.append(Token(c, c, ln, col))
                i += 1
            elif c == "(":
                j = row.find(")", i)
                if j < 0:
                    fail("point '(' is not closed by ')' on the same line", ln, col)
                parts = row[i + 1:j].split(",")
                if len(parts) not in (2, 3) or not all(_NUMBER.match(p.strip()) for p in parts):
                    fail(f"a point is (x,y,z) or (x,y) of numbers, not '{row[i:j + 1][:40]}'", ln, col)
                xyz = [float(p) for p in parts] + ([0.0] if len(parts) == 2 else [])
                out.append(Token("point", tuple(xyz), ln, col))
                i = j + 1
            elif c == ")":
                fail("')' without '('", ln, col)
            else:
                j = i + 1
                while j < n and not row[j].isspace() and row[j] not in _DELIMS:
                    j += 1
                word = row[i:j]
                if c == "/":
                    while j < n and not row[j].isspace() and row[j] not in _DELIMS:
                        j += 1
                    word = row[i + 1:j]
                    if not word:
                        fail("'/' must be followed by a name (/X)", ln, col)
                    out.append(Token("literal", word, ln, col))
                elif c in "!:" and len(word) > 1:
                    out.append(Token("bind" if c == "!" else "get", word[1:], ln, col))
                elif _NUMBER.match(word):
                    value: float | int = int(word) if _INT.match(word) else float(word)
                    out.append(Token("number", value, ln, col))
                elif c in "!:":
                    fail(f"'{c}' must be followed by a variable name ({c}window-width)", ln, col)
                else:
                    out.append(Token("name", word, ln, col))
                i = j
            if len(out) > MAX_TOKENS:
                fail(f"program has more than {MAX_TOKENS} tokens", ln, col)
    return out


def parse(text: str, path: str = "<gml>") -> Proc:
    """Tokens → the program as one :class:`Proc` (``{ }`` nested as procs; ``[ ]`` stay tokens,
    checked for balance within each procedure)."""
    lines = text.split("\n")
    root = Proc([], 1, 1)
    stack: list[tuple[Proc, list[Token]]] = [(root, [])]  # proc, open '[' tokens in it
    for tok in tokenize(text, path):
        proc, brackets = stack[-1]
        if tok.kind == "{":
            if len(stack) + sum(len(b) for _, b in stack) > MAX_NESTING:
                raise GmlSyntaxError(f"brackets nested deeper than {MAX_NESTING}", path, tok.line,
                                     tok.column, lines[tok.line - 1][:200])
            new = Proc([], tok.line, tok.column)
            proc.items.append(new)
            stack.append((new, []))
        elif tok.kind == "}":
            if brackets:
                b = brackets[-1]
                raise GmlSyntaxError(f"'[' at {b.line}:{b.column} is not closed before '}}'", path,
                                     tok.line, tok.column, lines[tok.line - 1][:200])
            if len(stack) == 1:
                raise GmlSyntaxError("'}' without '{'", path, tok.line, tok.column,
                                     lines[tok.line - 1][:200])
            stack.pop()
        else:
            if tok.kind == "[":
                if len(stack) + sum(len(b) for _, b in stack) > MAX_NESTING:
                    raise GmlSyntaxError(f"brackets nested deeper than {MAX_NESTING}", path,
                                         tok.line, tok.column, lines[tok.line - 1][:200])
                brackets.append(tok)
            elif tok.kind == "]":
                if not brackets:
                    raise GmlSyntaxError("']' without '['", path, tok.line, tok.column,
                                         lines[tok.line - 1][:200])
                brackets.pop()
            proc.items.append(tok)
    proc, brackets = stack[-1]
    if brackets:
        b = brackets[-1]
        raise GmlSyntaxError("'[' is not closed by ']'", path, b.line, b.column, lines[b.line - 1][:200])
    if len(stack) > 1:
        raise GmlSyntaxError("'{' is not closed by '}'", path, proc.line, proc.column,
                             lines[proc.line - 1][:200])
    return root
