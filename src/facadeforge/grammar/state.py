"""The mutable state of the shape a rule is working on."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.mesh import Mesh
from ..model.scope import Scope

MASK64 = (1 << 64) - 1


def splitmix64(x: int) -> int:
    """One step of SplitMix64: a cheap, well-mixed hash for per-shape random streams."""
    x = (x + 0x9E3779B97F4A7C15) & MASK64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK64
    return x ^ (x >> 31)


@dataclass
class ShapeState:
    """Scope, geometry and attributes of the current shape.

    ``geometry`` is in world coordinates.  ``attrs`` holds values written by ``set(attr, v)`` for
    this shape and its descendants.  ``seed`` drives ``rand`` and stochastic rules: it is derived
    from the initial shape's seed and the shape's path in the tree, so results do not depend on
    the order in which shapes are derived.
    """

    scope: Scope
    geometry: Mesh
    material: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)
    context: dict = field(default_factory=dict)  # split.index, comp.sel, …
    projections: dict = field(default_factory=dict)  # uv set -> (origin, u axis, v axis, w, h)
    label: str = ""
    tags: dict = field(default_factory=dict)
    seed: int = 0
    draws: int = 0
    pivot: Scope | None = None  # scope of the predecessor (for ``center``)

    def copy(self) -> ShapeState:
        return ShapeState(self.scope.copy(), self.geometry, dict(self.material), dict(self.attrs),
                          dict(self.context), dict(self.projections), self.label, dict(self.tags),
                          self.seed, 0, self.pivot)

    def child(self, index: int) -> ShapeState:
        """Copy for the ``index``-th successor, with its own random stream."""
        c = self.copy()
        c.seed = splitmix64(self.seed ^ ((index + 1) * 0x632BE59BD9B4E019 & MASK64))
        c.pivot = self.scope.copy()
        return c

    def random_float(self) -> float:
        self.draws += 1
        return splitmix64(self.seed + self.draws * 0xD1B54A32D192ED03 & MASK64) / 2.0**64

    # -- geometry helpers --------------------------------------------------------------------
    def local_geometry(self) -> Mesh:
        """Geometry in the scope frame."""
        g = self.geometry
        return g.with_vertices(self.scope.to_local(g.vertices)) if g.n_faces else g

    def set_local_geometry(self, mesh: Mesh) -> None:
        self.geometry = mesh.with_vertices(self.scope.to_world(mesh.vertices)) if mesh.n_faces else mesh

    def fit_scope(self) -> None:
        """Scope to the bounding box of the geometry, orientation kept (CGA's default adjust)."""
        if self.geometry.n_faces:
            self.scope.fit_to(self.geometry.vertices[self.geometry.corners])

    def world_size(self) -> np.ndarray:
        return self.scope.size
