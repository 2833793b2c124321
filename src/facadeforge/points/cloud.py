"""One point cloud in memory: coordinates and the per-point attributes scanners record.

Every reader (:mod:`.io`) returns a :class:`PointCloud`; every later stage (the fixed-point
store, RANSAC planes, depth maps) reads one.  Coordinates stay in the cloud's own frame and
units (metres), as float64 — a georeferenced scan (UTM, Lambert-93) has coordinates of 10⁵–10⁶ m
which float32 cannot hold to the millimetre (``hohmann2009`` §3: 0.5 mm spacing already at
4.2 km).  The fixed-point store (:mod:`.store`) works relative to a stored origin.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError

__all__ = ["PointCloud", "PointCloudError"]


class PointCloudError(InputError):
    """A point cloud file cannot be read or holds no usable point."""


@dataclass(eq=False)
class PointCloud:
    """Points and their attributes; every per-point array has ``len(xyz)`` rows.

    Parameters
    ----------
    xyz : (N, 3) float64
        Coordinates in metres, in the cloud's own frame.  Which axis is up is given by ``up``.
    intensity : (N,) float32 or None
        Laser return intensity as the file stores it (scanner units; 0–65535 for LAS).
    rgb : (N, 3) uint8 or None
        Colour per point.
    normals : (N, 3) float32 or None
        Unit normals when the file carries them.
    labels : (N,) int32 or None
        Semantic label index per point into ``label_names``; −1 = unlabelled.
    label_names : tuple of str
        Names of the label indices (e.g. ``("wall", "window", "door")``).
    instance : (N,) int32 or None
        Element instance id per point (−1 = none); unique over the whole cloud.
    crs : str or None
        Coordinate reference system when the file names one (``"EPSG:2154"``, a WKT string).
    up : int
        Index of the vertical axis (2 for z-up scans, the LAS / PLY convention).
    source : str
        Where the points came from (a path), for messages.
    """

    xyz: np.ndarray
    intensity: np.ndarray | None = None
    rgb: np.ndarray | None = None
    normals: np.ndarray | None = None
    labels: np.ndarray | None = None
    label_names: tuple[str, ...] = ()
    instance: np.ndarray | None = None
    crs: str | None = None
    up: int = 2
    source: str = "<memory>"
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    _PER_POINT = ("intensity", "rgb", "normals", "labels", "instance")

    def __post_init__(self) -> None:
        xyz = np.asarray(self.xyz, dtype=np.float64)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise PointCloudError(f"{self.source}: coordinates must be an (N, 3) array, "
                                  f"got shape {xyz.shape}")
        if not np.isfinite(xyz).all():
            raise PointCloudError(f"{self.source}: {int((~np.isfinite(xyz)).any(1).sum())} points "
                                  "have NaN or infinite coordinates; drop them before loading")
        self.xyz = xyz
        n = len(xyz)
        dtypes = {"intensity": np.float32, "rgb": np.uint8, "normals": np.float32,
                  "labels": np.int32, "instance": np.int32}
        for name in self._PER_POINT:
            a = getattr(self, name)
            if a is None:
                continue
            a = np.asarray(a, dtype=dtypes[name])
            if len(a) != n:
                raise PointCloudError(f"{self.source}: {name} has {len(a)} rows for {n} points")
            setattr(self, name, a)
        for k, a in self.extra.items():
            if len(a) != n:
                raise PointCloudError(f"{self.source}: {k} has {len(a)} rows for {n} points")
        if self.up not in (0, 1, 2):
            raise PointCloudError(f"{self.source}: up axis must be 0, 1 or 2, got {self.up}")

    def __len__(self) -> int:
        return len(self.xyz)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box ``(min, max)`` of the coordinates (raises when empty)."""
        if not len(self):
            raise PointCloudError(f"{self.source}: the cloud is empty")
        return self.xyz.min(0), self.xyz.max(0)

    def subset(self, index) -> PointCloud:
        """The points selected by a boolean mask or an index array, attributes carried along."""
        idx = np.asarray(index)
        kw = {name: (None if getattr(self, name) is None else getattr(self, name)[idx])
              for name in self._PER_POINT}
        return replace(self, xyz=self.xyz[idx], extra={k: v[idx] for k, v in self.extra.items()},
                       **kw)

    def label_of(self, name: str) -> int:
        """Index of a label name (raises a clear error when the cloud has no such label)."""
        try:
            return self.label_names.index(name)
        except ValueError:
            raise PointCloudError(f"{self.source}: no label {name!r}; labels are "
                                  f"{list(self.label_names) or 'none'}") from None

    @staticmethod
    def concat(clouds: list[PointCloud], source: str = "<concat>") -> PointCloud:
        """Several clouds as one; attributes kept where every cloud has them, labels re-indexed."""
        if not clouds:
            raise PointCloudError(f"{source}: no clouds to concatenate")
        names: list[str] = []
        for c in clouds:
            names += [n for n in c.label_names if n not in names]
        kw: dict = {}
        for name in ("intensity", "rgb", "normals", "instance"):
            arrs = [getattr(c, name) for c in clouds]
            kw[name] = None if any(a is None for a in arrs) else np.concatenate(arrs)
        if all(c.labels is not None for c in clouds):
            parts = []
            for c in clouds:
                lut = np.array([names.index(n) for n in c.label_names] + [-1], np.int32)
                parts.append(lut[np.where(c.labels < 0, len(c.label_names), c.labels)])
            kw["labels"] = np.concatenate(parts)
        return PointCloud(np.concatenate([c.xyz for c in clouds]), label_names=tuple(names),
                          crs=clouds[0].crs, up=clouds[0].up, source=source, **kw)
