"""Writing an output folder atomically: everything goes to a staging folder inside it first and
is moved into place only when every file was written, so a failure never leaves a half-written
result next to an older complete one."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from .errors import InputError

__all__ = ["write_json", "write_outdir"]


def write_outdir(out: str | os.PathLike, write: Callable[[Path], None]) -> list[Path]:
    """Create ``out``, call ``write(stage)`` to fill a staging folder, then move its files into
    ``out`` (sub-folders kept); returns the written paths.  The staging folder is removed
    whatever happens."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"output folder {out} is an existing file; choose a folder name")
    out.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".staging-", dir=out))
    try:
        write(stage)
        written = []
        for src in sorted(stage.rglob("*")):
            if src.is_file():
                dst = out / src.relative_to(stage)
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, dst)
                written.append(dst)
        return written
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def write_json(path: str | os.PathLike, obj, indent: int = 2) -> None:
    """``obj`` as indented JSON at ``path`` (NaN and infinities become null); inside
    :func:`write_outdir`'s staging folder, which makes the whole folder atomic."""
    from .exchange._common import jsonable

    Path(path).write_text(json.dumps(jsonable(obj), indent=indent))
