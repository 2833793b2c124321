"""``Shape``: a node of a derivation tree — and of a shape tree found in a photo."""

from __future__ import annotations

import itertools
import weakref
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from ..geometry.mesh import Mesh
from .model import Material
from .scope import Scope

_ids = itertools.count(1)

#: ``Shape.operator`` of a shape inserted in front of its parent outside the parent's split
#: partition — a balcony before the tile or floor it stands on (see
#: :mod:`facadeforge.imaging.shape_tree`).  Rasterised after the partition's leaves.
INSERT: str = "insert"


@dataclass(eq=False)
class Shape:
    """Node of a shape tree.

    Parameters
    ----------
    symbol : str
        Rule name (``"Facade"``) or, for analysed photos, the element kind.
    scope : Scope
        Oriented box of the shape.
    geometry : Mesh or None
        World-space polygons; ``None`` while the shape is only a scope.
    label : str
        Canonical semantic label (``Labels`` value) or ``""`` when unknown.
    material : Material
        Appearance set by ``color``/``texture``/``set(material…)``.
    tags : dict
        Free attributes: consistency/differentiation tags, cluster ids, confidence…
    rule, operator, params
        How the shape was made: the rule that ran on its parent and the operation and arguments
        that produced it (``"split"``, ``{"axis": "y", "index": 2}``).
    """

    symbol: str
    scope: Scope = field(default_factory=Scope)
    geometry: Mesh | None = None
    label: str = ""
    material: Material = field(default_factory=Material)
    tags: dict = field(default_factory=dict)
    children: list[Shape] = field(default_factory=list)
    rule: str = ""
    operator: str = ""
    params: dict = field(default_factory=dict)
    id: int = field(default_factory=lambda: next(_ids))
    _parent: weakref.ref | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def parent(self) -> Shape | None:
        """The shape this one was made from; ``None`` for a root.  Held weakly, so that a tree
        has no reference cycle and is freed as soon as its root is dropped (a subtree kept
        alone loses its parent then)."""
        return None if self._parent is None else self._parent()

    @parent.setter
    def parent(self, shape: Shape | None) -> None:
        self._parent = None if shape is None else weakref.ref(shape)

    def __getstate__(self) -> dict:  # pickling and deep copies: parents come back from children
        state = self.__dict__.copy()
        state["_parent"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        for child in self.children:  # already rebuilt: pickle sets a node's state after theirs
            if child._parent is None:  # not a shallow copy's, which shares the original's
                child._parent = weakref.ref(self)

    def add(self, child: Shape) -> Shape:
        """Append ``child`` and make this shape its parent."""
        self.children.append(child)
        child._parent = weakref.ref(self)
        return child

    def walk(self) -> Iterator[Shape]:
        """Pre-order traversal (iterative: derivation trees can be deep)."""
        stack = [self]
        while stack:
            node = stack.pop()
            yield node
            stack.extend(reversed(node.children))

    def leaves(self) -> Iterator[Shape]:
        return (s for s in self.walk() if not s.children)

    def painting_order(self) -> list[Shape]:
        """The leaves, those below an :data:`INSERT`-ed shape after all others (each group in
        :meth:`walk` order): what stands in front of the partition is drawn over it.  A shape
        whose only children are inserted ones is a leaf of the partition too (drawn behind
        them)."""
        behind: list[Shape] = []
        front: list[Shape] = []
        stack: list[tuple[Shape, bool]] = [(self, False)]
        while stack:
            node, inserted = stack.pop()
            inserted = inserted or node.operator == INSERT
            kids = node.children
            if not kids or all(c.operator == INSERT for c in kids):
                (front if inserted else behind).append(node)
            stack.extend((c, inserted) for c in reversed(kids))
        return behind + front

    def dump(self, precision: int = 3) -> str:
        """Stable indented text form, for golden tests and debugging."""
        lines: list[str] = []
        stack: list[tuple[Shape, int]] = [(self, 0)]
        while stack:
            node, depth = stack.pop()
            sc = node.scope
            fmt = f"{{:.{precision}f}}"
            o = " ".join(fmt.format(v + 0.0) for v in np.round(sc.origin, precision))
            s = " ".join(fmt.format(v + 0.0) for v in np.round(sc.size, precision))
            extra = ""
            if node.operator:
                extra += f" <{node.operator}"
                if node.params:
                    extra += " " + ",".join(f"{k}={node.params[k]}" for k in sorted(node.params))
                extra += ">"
            if node.label:
                extra += f" [{node.label}]"
            if node.geometry is not None and not node.children:
                extra += f" faces={len(node.geometry.faces)} area={node.geometry.area():.{precision}f}"
            lines.append(f"{'  ' * depth}{node.symbol} o=({o}) s=({s}){extra}")
            stack.extend((c, depth + 1) for c in reversed(node.children))
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready nested dict (geometry omitted; scope, semantics and provenance kept)."""
        return {
            "symbol": self.symbol,
            "label": self.label,
            "scope": {"origin": self.scope.origin.tolist(), "rotation": self.scope.rotation.tolist(),
                      "size": self.scope.size.tolist(), "unit": self.scope.unit},
            "operator": self.operator,
            "params": self.params,
            "tags": self.tags,
            "children": [c.to_dict() for c in self.children],
        }

    @staticmethod
    def from_dict(d: dict) -> Shape:
        sc = d["scope"]
        node = Shape(d["symbol"], Scope(sc["origin"], sc["rotation"], sc["size"], sc.get("unit", "m")),
                     label=d.get("label", ""), tags=dict(d.get("tags", {})),
                     operator=d.get("operator", ""), params=dict(d.get("params", {})))
        for c in d.get("children", []):
            node.add(Shape.from_dict(c))
        return node
