"""CityEngine operations this runtime does not implement (yet).

Loaded after every other op module (a name is registered here only if no module implements it).
Rules using these still load and derive; each use is a warning (see docs/cga-dialect.md, "Not yet
supported").
"""

from __future__ import annotations

from ..values import CGARuntimeError
from . import OPERATIONS, operation


def _unsupported(name: str):
    def fn(call):
        raise CGARuntimeError(f"{name}() is not supported yet; the shape is left unchanged")
    return fn


def _boolean_form(name: str):
    def fn(call):
        raise CGARuntimeError(f"{name}(…) is not a Boolean operation form; write {name} {{ A | B }}, "
                              f"{name} Rule or {name}(swap) Rule")
    return fn


for _name in ("union", "subtract", "intersect"):  # the Boolean forms are syntax (cga.lark)
    if _name not in OPERATIONS:
        operation(_name, 0, 16, selectors=tuple(range(16)))(_boolean_form(_name))

# edge attributes of initial shapes are not read (docs/cga-dialect.md)
for _name in ("setTagsFromEdgeAttrs",):
    if _name not in OPERATIONS:
        operation(_name, 0, 16, selectors=tuple(range(16)))(_unsupported(_name))
