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


def child_seed(seed: int, index: int) -> int:
    """The random stream of a shape's ``index``-th successor."""
    return splitmix64(seed ^ ((index + 1) * 0x632BE59BD9B4E019 & MASK64))


def random_value(seed: int, draw: int) -> float:
    """The ``draw``-th (from 1) number in [0, 1) of the stream ``seed``."""
    return splitmix64(seed + draw * 0xD1B54A32D192ED03 & MASK64) / 2.0**64


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
                 "label", "tags", "seed", "draws", "pivot", "trim", "path")

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
        # successor indices from the root of a subtree being recorded for instancing by the
        # outcomes of its stochastic choices (None otherwise): its random stream follows them
        self.path = None

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
        new = ShapeState(self._scope, self.geometry, dict(self.material), dict(self.attrs),
                         dict(self.context), dict(self.projections), self.label, dict(self.tags),
                         self.seed, 0, self.pivot, self.trim)
        new.path = self.path
        return new

    def child(self, index: int) -> ShapeState:
        """Copy for the ``index``-th successor, with its own random stream."""
        c = self.copy()
        c.seed = child_seed(self.seed, index)
        c.pivot = self._scope
        if self.path is not None:
            c.path = (*self.path, index)
        return c

    def random_float(self) -> float:
        self.draws += 1
        return random_value(self.seed, self.draws)

    # -- geometry helpers --------------------------------------------------------------------
    def local_geometry(self) -> Mesh:
        """Geometry in the scope frame."""
        g = self.geometry
        return g.with_vertices(self._scope.to_local(g.vertices)) if g.n_faces else g

    def fit_scope(self) -> None:
        """Scope to the bounding box of the geometry, orientation kept (CGA's default adjust)."""
        if self.geometry.n_faces:
            self.own_scope().fit_to(self.geometry.vertices[self.geometry.corners])
