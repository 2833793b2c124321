"""The official CityJSON validator (``cjval``, a Rust crate) for the tests that check our
CityJSON and CityJSONSeq files with it.  ``make test`` builds it into .tools/cjval when cargo is
there (``make cjval``); without cargo these tests skip, saying so."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

CJVAL = Path(__file__).resolve().parents[1] / ".tools" / "cjval" / "bin" / "cjval"


def cjval_exe() -> str | None:
    return str(CJVAL) if CJVAL.is_file() else shutil.which("cjval")


needs_cjval = pytest.mark.skipif(
    cjval_exe() is None,
    reason="cjval (the official CityJSON validator) is not installed: `make cjval` builds it "
           "into .tools/cjval with cargo (https://rustup.rs), about a minute")


def cjval_reports(path: Path) -> list[dict]:
    """cjval's ``--report`` records for a CityJSON file, or for a CityJSONSeq stream
    (``.jsonl``, given on stdin as cjval reads them): one record per document."""
    exe = cjval_exe()
    assert exe is not None
    if path.suffix == ".jsonl":
        with path.open("rb") as fh:
            r = subprocess.run([exe, "--report"], stdin=fh, capture_output=True, text=True,
                               timeout=300)
    else:
        r = subprocess.run([exe, "--report", str(path)], capture_output=True, text=True,
                           timeout=300, stdin=subprocess.DEVNULL)
    decoder, text, reports, i = json.JSONDecoder(), r.stdout, [], 0
    while True:   # pretty-printed for a file, one line per document for a stream
        while i < len(text) and text[i].isspace():
            i += 1
        if i == len(text):
            break
        record, i = decoder.raw_decode(text, i)
        reports.append(record)
    assert r.returncode == 0 and reports, (path.name, r.stdout[-500:], r.stderr[-500:])
    return reports


def _failed(checks: dict) -> dict:
    return {name: c["errors"][:2] for group in checks.values() if isinstance(group, dict)
            for name, c in group.items() if isinstance(c, dict) and c.get("valid") is False}


def cjval_problems(path: Path) -> list[tuple]:
    """What cjval finds wrong in ``path``, errors and warnings alike (duplicate or unused
    vertices, extra root properties): an empty list when every document is clean."""
    return [(x.get("file"), _failed(x["checks"])) for x in cjval_reports(path)
            if not x["valid"] or x.get("has_warnings")]
