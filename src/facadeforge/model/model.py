"""What the engine produces and the exporters consume."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..geometry.mesh import Mesh, _take

if TYPE_CHECKING:
    from .shape import Shape

#: Largest coordinate a model may hold, metres from the origin.  Projected coordinates of any
#: place on Earth stay below 2·10⁷ m; beyond 10⁹ m a glTF's float32 is off by more than 60 m
#: and CityJSON's integer vertices overflow at 10¹⁶ m, so larger values mean the rules went
#: wrong (``extrude(1e300)``) and would make files that other tools cannot read.
MAX_COORDINATE = 1e9


def extent_problem(stats: dict) -> str | None:
    """Why a model with these :meth:`Model.stats` cannot be written (coordinates beyond
    :data:`MAX_COORDINATE` or not finite, an area that is not finite), or ``None``."""
    b = np.asarray(stats["bbox"], float)
    if not np.isfinite(b).all():
        return "its geometry has coordinates that are not finite numbers"
    if np.abs(b).max() > MAX_COORDINATE:
        return (f"its geometry reaches {np.abs(b).max():.3g} m from the origin, beyond "
                f"±{MAX_COORDINATE:.0e} m (an absurd size or translation?)")
    if not np.isfinite(stats["area"]):
        return "its surface area is not a finite number (an absurd size?)"
    return None


@dataclass(frozen=True)
class Material:
    """Appearance of a leaf shape (CGA ``material.*`` attributes that exporters understand).

    ``texture`` is a resolved, readable file path (or ``None``); ``color`` is linear-ish sRGB in 0–1.
    """

    name: str = "default"
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    opacity: float = 1.0
    texture: str | None = None
    metallic: float = 0.0
    roughness: float = 0.9

    def key(self) -> tuple:
        """Identity for grouping faces by appearance (rounded so float noise does not split)."""
        k = self.__dict__.get("_key")
        if k is None:
            k = (self.name, tuple(round(c, 4) for c in self.color), round(self.opacity, 4),
                 self.texture, round(self.metallic, 3), round(self.roughness, 3))
            object.__setattr__(self, "_key", k)  # frozen dataclass: cache outside the fields
        return k


@dataclass
class Part:
    """Geometry of one leaf shape, in world coordinates, with its semantics."""

    mesh: Mesh
    label: str = ""
    material: Material = field(default_factory=Material)
    symbol: str = ""
    shape_id: int = 0


@dataclass
class Model:
    """One derived building (or facade): its leaf geometry, its shape tree and what rules reported.

    Parameters
    ----------
    parts : list of Part
        Leaf geometry in world coordinates (metres, y up, CGA convention).
    root : Shape or None
        The derivation tree.
    reports : dict of str to list
        Values collected by ``report(name, value)``.
    warnings : list of str
        CGA warnings (missing assets, runtime problems inside rules) in derivation order.
    name : str
        Identifier of the building, used as object id by exporters.
    """

    parts: list[Part] = field(default_factory=list)
    root: Shape | None = None
    reports: dict[str, list] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    name: str = "building"
    attributes: dict[str, object] = field(default_factory=dict)

    # -- compact pickling (models travel between worker processes) ----------------------------
    def __getstate__(self) -> dict:
        """Pack the parts into a handful of arrays: pickling thousands of small meshes is slow."""
        state = dict(self.__dict__)
        parts = state.pop("parts")
        merged = Mesh.merge(p.mesh for p in parts)
        mats: dict = {}
        state["_packed"] = {
            "vertices": merged.vertices, "corners": merged.corners, "starts": merged.starts,
            "uvs": merged.corner_uvs,
            # face and corner columns (faces with holes, tags, materials of assets…)
            "face_data": merged.face_data, "corner_data": merged.corner_data,
            "faces": np.array([p.mesh.n_faces for p in parts], np.int64),
            "has_uv": np.array([p.mesh.corner_uvs is not None for p in parts], bool),
            "material": [mats.setdefault(p.material, len(mats)) for p in parts],
            "materials": list(mats),
            "meta": [(p.label, p.symbol, p.shape_id) for p in parts],
        }
        return state

    def __setstate__(self, state: dict) -> None:
        packed = state.pop("_packed", None)
        self.__dict__.update(state)
        if packed is None:
            return
        merged = Mesh(packed["vertices"], corners=packed["corners"], starts=packed["starts"],
                      corner_uvs=packed["uvs"])
        face_data, corner_data = packed.get("face_data"), packed.get("corner_data")
        face_end = np.cumsum(packed["faces"])
        parts = []
        for k, (label, symbol, shape_id) in enumerate(packed["meta"]):
            f0, f1 = face_end[k] - packed["faces"][k], face_end[k]
            c0, c1 = merged.starts[f0], merged.starts[f1]
            corners = merged.corners[c0:c1]
            used, local = np.unique(corners, return_inverse=True)
            mesh = Mesh(merged.vertices[used], corners=local.reshape(-1),
                        starts=merged.starts[f0:f1 + 1] - c0,
                        corner_uvs=merged.corner_uvs[c0:c1] if (packed["has_uv"][k] and
                                                                 merged.corner_uvs is not None) else None,
                        face_data=_take(face_data, slice(f0, f1)),
                        corner_data=_take(corner_data, slice(c0, c1)))
            parts.append(Part(mesh, label, packed["materials"][packed["material"][k]], symbol,
                              shape_id))
        self.parts = parts

    # -- statistics used by ``--stats`` and the benchmark --------------------------------------
    def mesh(self) -> Mesh:
        return Mesh.merge(p.mesh for p in self.parts)

    def stats(self) -> dict:
        """Face, triangle and vertex counts, surface area (m²) and bounding box of all parts."""
        mesh = self.mesh()
        if not mesh.n_faces:
            return {"faces": 0, "triangles": 0, "vertices": 0, "area": 0.0,
                    "bbox": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]}
        with np.errstate(all="ignore"):  # absurd coordinates: extent_problem says so
            b = mesh.bounds()
            area = mesh.area()
        return {"faces": mesh.n_faces, "triangles": mesh.triangle_count(),
                "vertices": len(mesh.vertices), "area": area,
                "bbox": [b[0].tolist(), b[1].tolist()]}
