"""GML (Generative Modeling Language) front end: CityFit's stack-language shape grammars.

>>> from facadeforge.gml import derive_gml
>>> model = derive_gml("ShapeGrammar.Tools.init scope (2,1,1) scale terminal-box finish")
>>> len(model.parts)
1

A program that makes its own scope (``scope``, ``cp-scope``) needs nothing else; with
``scope=`` an initial shape (a lot rectangle, a facade) is on the stack when the program starts.
See ``docs/gml.md`` for the dialect.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model.model import Model
from ..model.scope import Scope
from ..model.shape import Shape
from .errors import GmlError, GmlLimitError, GmlRuntimeError, GmlSyntaxError
from .interpreter import Interpreter, Limits
from .polyhedra import Plane, Polyhedron
from .shapegrammar import WORDS, GScope, grammar_of, on_call
from .tokens import Proc, parse, restore_typography

__all__ = ["GmlError", "GmlLimitError", "GmlProgram", "GmlRuntimeError", "GmlSyntaxError",
           "Interpreter", "Limits", "Plane", "Polyhedron", "derive_gml", "load_gml"]

MAX_GML_BYTES = 8 * 1024 * 1024
EXAMPLES = Path(__file__).parent / "examples"


@dataclass
class GmlProgram:
    """A parsed GML program: its items, the path used in messages and the text."""

    program: Proc
    path: str
    source: str


def load_gml(text_or_path, *, restore: bool = True) -> GmlProgram:
    """Parse a ``.gml`` file or GML text.

    Parameters
    ----------
    text_or_path : str or os.PathLike
        A path (a ``Path``, or a one-line string ending in ``.gml``) or the program text.
    restore : bool
        Replace typographic dashes and non-breaking spaces by ASCII first (programs copied out
        of PDFs: ``terminal—box``).
    """
    is_path = isinstance(text_or_path, os.PathLike) or (
        isinstance(text_or_path, str) and "\n" not in text_or_path
        and text_or_path.strip().lower().endswith(".gml"))
    if is_path:
        p = Path(text_or_path)
        if not p.is_file():
            raise InputError(f"GML program '{p}' does not exist")
        if p.stat().st_size > MAX_GML_BYTES:
            raise InputError(f"GML program '{p}' is larger than 8 MiB")
        text, path = p.read_text(encoding="utf-8", errors="replace"), str(p)
    elif isinstance(text_or_path, str):
        text, path = text_or_path, "<gml>"
    else:
        raise InputError(f"a GML program is text or a path, not {type(text_or_path).__name__}")
    if restore:
        text = restore_typography(text)
    return GmlProgram(parse(text, path), path, text)


def derive_gml(program, *, scope: Scope | None = None, limits: Limits | None = None,
               name: str = "building", symbol: str = "Lot") -> Model:
    """Run a GML shape-grammar program and return its :class:`~facadeforge.model.model.Model`.

    Parameters
    ----------
    program : GmlProgram, str or os.PathLike
        From :func:`load_gml`, or what it accepts.
    scope : Scope, optional
        Initial shape (e.g. a lot rectangle with ``size[2] == 0`` or a facade box), pushed on
        the operand stack before the program runs, as a root shape named ``symbol``.  Without
        it the program makes its own scopes (``scope`` is the unit box at the origin).
    limits : Limits, optional
        Bounds of the run (operations, time, stack depths, memory, shapes).
    name : str
        ``Model.name`` (the object id exporters use).

    Raises
    ------
    GmlSyntaxError, GmlRuntimeError, GmlLimitError
        All :class:`GmlError`; each names path:line:column.
    """
    prog = program if isinstance(program, GmlProgram) else load_gml(program)
    it = Interpreter(limits, prog.path, WORDS, on_call)
    gram = grammar_of(it)
    if scope is not None:
        it.push(gram.root(scope.copy(), symbol))
    it.run(prog.program)
    left = sum(isinstance(v, GScope) for v in it.stack)
    if left and not gram.finished:
        gram.warnings.append(f"{left} scope(s) left on the stack were not derived")
    for r in gram.roots:
        for node in r.walk():
            if not node.symbol:
                node.symbol = "Scope"
    if len(gram.roots) == 1:
        root = gram.roots[0]
    else:
        root = Shape("Program", _bounding_scope(gram.roots), operator="gml")
        for r in gram.roots:
            root.add(r)
    return Model(gram.parts, root, {}, gram.warnings, name, {"source": "gml"})


def _bounding_scope(roots: list[Shape]) -> Scope:
    if not roots:
        return Scope(np.zeros(3), np.eye(3), np.zeros(3))
    corners = np.concatenate([r.scope.corners() for r in roots])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    return Scope(lo, np.eye(3), hi - lo)
