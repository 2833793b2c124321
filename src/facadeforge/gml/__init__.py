"""GML (Generative Modeling Language) front end: CityFit's stack-language shape grammars.

See ``docs/gml.md``.
"""

from __future__ import annotations

from .errors import GmlError, GmlLimitError, GmlRuntimeError, GmlSyntaxError
from .interpreter import Interpreter, Limits

__all__ = ["GmlError", "GmlLimitError", "GmlRuntimeError", "GmlSyntaxError", "Interpreter",
           "Limits"]
