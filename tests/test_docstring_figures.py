"""Docstrings say what a function does and its units, not how it scored (issue 32): no score
(mIoU, F1, IoU, accuracy, PSNR, SSIM with a measured value, or decibels) in a module, class or
function docstring or a ``#:`` attribute note of the package.  Measurements live in
``benchmarks/results/*.json`` (the docs site's benchmark pages) and, for design choices,
``docs/design-measurements.md``."""

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "facadeforge"
SCORE = re.compile(r"\b(mIoU|F1|PSNR|SSIM|IoU|accuracy|class-average)\b[^\n]{0,25}?\b\d\.\d{2,}"
                   r"|\b\d+(\.\d+)? ?dB\b")
#: Not measurements: a format example.
ALLOWED = {("evaluation/sheet.py", "SheetRow")}


def test_no_scores_in_docstrings():
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        src = path.read_text(encoding="utf-8")
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                doc = ast.get_docstring(node, clean=False) or ""
                name = getattr(node, "name", "<module>")
                if (rel, name) not in ALLOWED and (m := SCORE.search(doc)):
                    found.append(f"{rel} {name}: …{m.group(0)}…")
        for i, line in enumerate(src.splitlines(), 1):
            if line.lstrip().startswith("#:") and (m := SCORE.search(line)):
                found.append(f"{rel}:{i}: …{m.group(0)}…")
    assert not found, "scores in docstrings (move them to docs/ or a results file):\n" + \
        "\n".join(found)
