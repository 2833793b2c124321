"""Reading JSON that users give us: one place that turns every way a file can be bad into an error
naming the file.

:func:`read_json` is used for every JSON file a user points the toolkit at (footprints, a
dataset's ``palette.json``, glTF and CityJSON models, depths); :func:`parse_json` for JSON text
embedded in another file (the ``attributes`` lines of our OBJ files).  Both:

- decode UTF-8 and accept a byte-order mark (editors on Windows write one; RFC 8259 §8.1 lets a
  parser ignore it), so a BOM is not reported as "invalid JSON";
- refuse a file larger than a cap *before* reading it, since Python's parser needs several times
  the file's size in memory;
- turn ``RecursionError`` into that error too: the C parser recurses once per level, so
  ``[[[[…]]]]`` 100,000 deep exceeds the recursion limit (it does so before the C stack runs
  out, also under the raised limit derivations run with,
  :data:`~facadeforge.grammar.interpreter.PYTHON_RECURSION_LIMIT`; no format we read nests more
  than a dozen levels, so a limit-deep file is never honest);
- raise ``error`` (:class:`~facadeforge.errors.InputError` unless the caller names a subclass
  of :class:`~facadeforge.errors.FacadeForgeError`) whose message names the file, the line and
  column, and how to fix it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .errors import FacadeForgeError, InputError

__all__ = ["MAX_JSON_BYTES", "json_type", "parse_json", "read_json"]

#: Largest JSON file read by default (bytes).  Parsing costs about five to ten times the text
#: in memory; callers that read bigger honest files (a city's footprints) pass their own cap.
MAX_JSON_BYTES = 256 * 2**20


class JsonMembers:
    """Typed reads from a parsed JSON document: each member read is checked for its type, and a
    wrong one raises the error :meth:`error` makes, naming the member's JSON path
    (``features[3].geometry``), so a malformed file never reaches numpy as a value of the wrong
    kind.  Subclasses say which file and which error type (footprints, CityJSON)."""

    def error(self, where: str, problem: str) -> Exception:
        """The exception for ``problem`` at JSON path ``where``."""
        raise NotImplementedError

    def obj(self, v, where: str) -> dict:
        """``v`` when it is an object."""
        if not isinstance(v, dict):
            raise self.error(where or "the top level", f"must be an object, not {json_type(v)}")
        return v

    def array(self, v, where: str) -> list:
        """``v`` when it is an array."""
        if not isinstance(v, list):
            raise self.error(where, f"must be an array, not {json_type(v)}")
        return v

    def member(self, obj: dict, key: str, where: str, kind: type, kind_name: str):
        """``obj[key]`` when it is a ``kind`` (None when absent or null)."""
        v = obj.get(key)
        if v is None or (isinstance(v, kind) and not isinstance(v, bool)):
            return v
        raise self.error(f"{where}.{key}" if where else key,
                         f"must be {kind_name}, not {json_type(v)}")


def json_type(v: Any) -> str:
    """The JSON name of a parsed value's type (``"an array"``, ``"null"``…), for messages
    saying a member has the wrong type."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, (int, float)):
        return "a number"
    if isinstance(v, str):
        return "a string"
    return "an array" if isinstance(v, list) else "an object"


def _size(n: int) -> str:
    return f"{n / 2**20:.0f} MiB" if n >= 2**20 else f"{n} bytes"


def parse_json(text: str, source: str, *, fix: str = "fix the file",
               error: type[FacadeForgeError] = InputError) -> Any:
    """Parse the JSON ``text`` read from ``source`` (a file name, ``file:line``…).

    Parameters
    ----------
    text : str
        JSON text (a leading byte-order mark is ignored).
    source : str
        Where the text comes from, for messages.
    fix : str
        How to fix a bad file, ending the message.
    error : type
        The exception to raise (a :class:`~facadeforge.errors.FacadeForgeError`).

    Returns
    -------
    Any
        The parsed value.

    Raises
    ------
    InputError
        (or ``error``) The text is not JSON or nests too deeply to parse.
    """
    text = text.removeprefix("\ufeff")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{source} is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg}); {fix}") from None
    except RecursionError:
        raise error(f"{source}: JSON nested too deeply (thousands of levels) to be a real "
                    f"file; {fix}") from None


def read_json(path: str | Path, what: str = "file", *, fix: str = "fix the file",
              max_bytes: int = MAX_JSON_BYTES,
              error: type[FacadeForgeError] = InputError) -> Any:
    """Read the user's JSON file ``path`` (module docstring: BOM, size cap, nesting cap).

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, starting messages (``"footprint file"``, ``"palette"``).
    fix : str
        How to fix a bad file, ending the message.
    max_bytes : int
        Largest file accepted; default :data:`MAX_JSON_BYTES`.
    error : type
        The exception to raise (a :class:`~facadeforge.errors.FacadeForgeError`).

    Returns
    -------
    Any
        The parsed value.

    Raises
    ------
    InputError
        (or ``error``) Missing or unreadable file, larger than ``max_bytes``, not UTF-8, not
        JSON, or nested too deeply.
    """
    p = Path(path)
    source = f"{what} '{p}'"
    try:
        size = p.stat().st_size
        if size > max_bytes:
            raise error(f"{source} is {_size(size)}, more than the {_size(max_bytes)} "
                        "facadeforge reads; split it into smaller files")
        data = p.read_bytes()
    except FileNotFoundError:
        raise error(f"{source} does not exist; check the path") from None
    except OSError as exc:
        raise error(f"{source} cannot be read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{source} is not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    return parse_json(text, source, fix=fix, error=error)
