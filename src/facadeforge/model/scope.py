"""Oriented bounding box in which shape operations are expressed."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _identity() -> np.ndarray:
    return np.eye(3)


@dataclass
class Scope:
    """Oriented box: ``origin`` (3,), ``rotation`` (3, 3) whose *columns* are the scope's x, y, z
    axes in world coordinates, and ``size`` (3,) along those axes.

    A facade rectangle is a scope with ``size[2] == 0``.  Image-space layouts use the same type with
    ``unit="px"``.
    """

    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=_identity)
    size: np.ndarray = field(default_factory=lambda: np.zeros(3))
    unit: str = "m"

    def __post_init__(self) -> None:
        self.origin = np.asarray(self.origin, dtype=float).reshape(3)
        self.rotation = np.asarray(self.rotation, dtype=float).reshape(3, 3)
        self.size = np.asarray(self.size, dtype=float).reshape(3)

    @staticmethod
    def trusted(origin: np.ndarray, rotation: np.ndarray, size: np.ndarray, unit: str = "m") -> Scope:
        """Scope from arrays that are already float (3,), (3, 3), (3,): no conversion (hot path).

        Scopes never change their arrays in place, so ``rotation`` may be shared.
        """
        new = object.__new__(Scope)
        new.origin, new.rotation, new.size, new.unit = origin, rotation, size, unit
        return new

    def copy(self) -> Scope:
        new = object.__new__(Scope)  # skip __post_init__'s conversions: this is a hot path
        new.origin, new.rotation, new.size, new.unit = (self.origin.copy(), self.rotation.copy(),
                                                        self.size.copy(), self.unit)
        return new

    # -- frames -------------------------------------------------------------------------------
    def to_local(self, points: np.ndarray) -> np.ndarray:
        """World points (N, 3) → coordinates in the scope frame (N, 3)."""
        return (np.asarray(points, float) - self.origin) @ self.rotation

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Scope-frame points (N, 3) → world coordinates (N, 3)."""
        return np.asarray(points, float) @ self.rotation.T + self.origin

    def fit_to(self, points: np.ndarray) -> None:
        """Keep the orientation, set origin and size to the bounding box of ``points`` (N, 3)."""
        if len(points) == 0:
            self.size = np.zeros(3)
            return
        local = self.to_local(points)
        lo, hi = local.min(axis=0), local.max(axis=0)
        self.origin = self.to_world(lo[None])[0]
        self.size = hi - lo

    @property
    def center(self) -> np.ndarray:
        return self.to_world((self.size / 2)[None])[0]

    def corners(self) -> np.ndarray:
        """The 8 corners (8, 3) in world coordinates."""
        unit = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
        return self.to_world(unit * self.size)

    @staticmethod
    def from_axes(origin, x_axis, y_axis, size=(0.0, 0.0, 0.0)) -> Scope:
        """Right-handed scope from an x axis and an approximate y axis (orthogonalised)."""
        x = np.asarray(x_axis, float)
        x = x / np.linalg.norm(x)
        y = np.asarray(y_axis, float)
        y = y - x * (y @ x)
        y = y / np.linalg.norm(y)
        z = np.cross(x, y)
        return Scope(np.asarray(origin, float), np.column_stack([x, y, z]), np.asarray(size, float))

    def __repr__(self) -> str:
        o = ", ".join(f"{v:.3f}" for v in self.origin)
        s = ", ".join(f"{v:.3f}" for v in self.size)
        return f"Scope(origin=({o}), size=({s}), unit={self.unit!r})"
