"""The mutable state of the shape a rule is working on."""

from __future__ import annotations

from ..geometry.mesh import Mesh
from ..model.scope import Scope

MASK64 = (1 << 64) - 1


def splitmix64(x: int) -> int:
    """One step of SplitMix64: a cheap, well-mixed hash for per-shape random streams."""
    x = (x + 0x9E3779B97F4A7C15) & MASK64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK64
    return x ^ (x >> 31)


class ShapeState:
    """Scope, geometry and attributes of the current shape.

    ``geometry`` is in world coordinates.  ``attrs`` holds values written by ``set(attr, v)`` for
    this shape and its descendants.  ``seed`` drives ``rand`` and stochastic rules: it is derived
    from the initial shape's seed and the shape's path in the tree, so results do not depend on
    the order in which shapes are derived.

    The scope is shared copy-on-write between a state, its copies, its successors and the shape
    tree: read ``scope`` freely, but change it only through ``own_scope()``.  Most shapes never
    move their scope, so most copies never happen.

    ``trim`` holds the trim planes a ``comp(f)`` gave the shape and the ``trim.*`` switches
    (an immutable ``ops.trimming.TrimState``, shared as is; ``None`` until either exists).
    """

    __slots__ = ("_scope", "_own", "geometry", "material", "attrs", "context", "projections",
                 "label", "tags", "seed", "draws", "pivot", "trim")

    def __init__(self, scope: Scope, geometry: Mesh, material=None, attrs=None, context=None,
                 projections=None, label: str = "", tags=None, seed: int = 0, draws: int = 0,
                 pivot: Scope | None = None, trim=None):
        self._scope = scope
        self._own = False
        self.geometry = geometry
        self.material = {} if material is None else material
        self.attrs = {} if attrs is None else attrs
        self.context = {} if context is None else context
        self.projections = {} if projections is None else projections
        self.label = label
        self.tags = {} if tags is None else tags
        self.seed = seed
        self.draws = draws
        self.pivot = pivot
        self.trim = trim

    @property
    def scope(self) -> Scope:
        return self._scope

    @scope.setter
    def scope(self, value: Scope) -> None:
        self._scope = value
        self._own = False  # whoever handed it over may still hold it

    def own_scope(self) -> Scope:
        """The scope, copied first if it may be shared: call before changing it."""
        if not self._own:
            self._scope = self._scope.copy()
            self._own = True
        return self._scope

    def mark_pivot(self) -> None:
        """The current scope becomes the pivot scope (``center`` aligns to it)."""
        self.pivot = self._scope
        self._own = False

    def copy(self) -> ShapeState:
        self._own = False
        return ShapeState(self._scope, self.geometry, dict(self.material), dict(self.attrs),
                          dict(self.context), dict(self.projections), self.label, dict(self.tags),
                          self.seed, 0, self.pivot, self.trim)

    def child(self, index: int) -> ShapeState:
        """Copy for the ``index``-th successor, with its own random stream."""
        c = self.copy()
        c.seed = splitmix64(self.seed ^ ((index + 1) * 0x632BE59BD9B4E019 & MASK64))
        c.pivot = self._scope
        return c

    def random_float(self) -> float:
        self.draws += 1
        return splitmix64(self.seed + self.draws * 0xD1B54A32D192ED03 & MASK64) / 2.0**64

    # -- geometry helpers --------------------------------------------------------------------
    def local_geometry(self) -> Mesh:
        """Geometry in the scope frame."""
        g = self.geometry
        return g.with_vertices(self._scope.to_local(g.vertices)) if g.n_faces else g

    def fit_scope(self) -> None:
        """Scope to the bounding box of the geometry, orientation kept (CGA's default adjust)."""
        if self.geometry.n_faces:
            self.own_scope().fit_to(self.geometry.vertices[self.geometry.corners])
