"""Initial shapes: building footprints from GeoJSON, OBJ or a ``--lot WxD`` rectangle.

GeoJSON (x, y) maps to CGA (x, −z) with y up, as CityEngine does, so a counter-clockwise GeoJSON
ring becomes a polygon whose normal points up.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .mesh import EPS, polygon_normal

MAX_FOOTPRINTS = 1_000_000


@dataclass
class Footprint:
    """One initial shape: a planar polygon (k, 3) in CGA coordinates, its holes (courtyards,
    each (m, 3)) and its attributes."""

    name: str
    polygon: np.ndarray
    attributes: dict = field(default_factory=dict)
    holes: list = field(default_factory=list)


def _clean_ring(ring: np.ndarray) -> np.ndarray:
    if len(ring) > 1 and np.allclose(ring[0], ring[-1]):
        ring = ring[:-1]
    keep = np.ones(len(ring), bool)
    for i in range(len(ring)):
        if np.linalg.norm(ring[i] - ring[i - 1]) < 1e-9:
            keep[i] = False
    return ring[keep]


def _usable_holes(ring: np.ndarray, holes: list) -> list:
    """The holes that leave some of the polygon ``ring`` (x, y) standing: holes that cover
    it all are dropped (the building keeps its outline), so one bad ring cannot stop a batch."""
    if not holes:
        return holes
    import shapely

    outline = shapely.Polygon(ring).buffer(0)
    rest = outline.difference(shapely.union_all([shapely.Polygon(h[:, [0, 2]] * [1, -1]).buffer(0)
                                                 for h in holes]))
    return holes if rest.area > 1e-9 * max(outline.area, 1.0) else []


def _upward(poly: np.ndarray) -> np.ndarray:
    n = polygon_normal(poly)
    if not n.any():
        raise InputError("a footprint polygon has no area")
    return poly if n[1] >= 0 else poly[::-1]


def lot(spec: str) -> list[Footprint]:
    """``"20x12"`` → a 20 m (x) by 12 m (z) rectangle with its first edge at the street (+z)."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*[xX]\s*([0-9]*\.?[0-9]+)\s*", spec)
    if not m:
        raise InputError(f"--lot '{spec}' is not WIDTHxDEPTH in metres, e.g. --lot 20x12")
    w, d = float(m.group(1)), float(m.group(2))
    if w <= 0 or d <= 0:
        raise InputError(f"--lot '{spec}': width and depth must be positive")
    poly = np.array([[0, 0, d], [w, 0, d], [w, 0, 0], [0, 0, 0]], float)
    return [Footprint("lot", poly, {})]


def load_footprints(path: str | Path) -> list[Footprint]:
    """Footprints from a ``.geojson``/``.json`` or ``.obj`` file.

    Raises
    ------
    InputError
        Unreadable file, unknown format, no polygon, degenerate polygon.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"footprint file '{path}' does not exist")
    suffix = p.suffix.lower()
    if suffix in (".geojson", ".json"):
        return _geojson(p)
    if suffix == ".obj":
        return _obj(p)
    raise InputError(f"footprint file '{path}': use .geojson, .json or .obj")


def _geojson(p: Path) -> list[Footprint]:
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"footprint file '{p}' is not valid JSON: {e}") from None
    feats = []
    if not isinstance(data, dict):
        raise InputError(f"'{p}' is not a GeoJSON object")
    if data.get("type") == "FeatureCollection":
        feats = data.get("features") or []
    elif data.get("type") == "Feature":
        feats = [data]
    elif data.get("type") in ("Polygon", "MultiPolygon"):
        feats = [{"type": "Feature", "geometry": data, "properties": {}}]
    else:
        raise InputError(f"'{p}': expected a GeoJSON Polygon, Feature or FeatureCollection")
    out = []
    for i, f in enumerate(feats[:MAX_FOOTPRINTS]):
        geom = (f or {}).get("geometry") or {}
        props = (f or {}).get("properties") or {}
        name = str(props.get("name") or props.get("id") or f.get("id") or f"building_{i}")
        polys = []
        if geom.get("type") == "Polygon":
            polys = [geom.get("coordinates") or []]
        elif geom.get("type") == "MultiPolygon":
            polys = geom.get("coordinates") or []
        for k, rings in enumerate(polys):
            if not rings:
                continue
            try:
                ring = np.asarray(rings[0], float)[:, :2]
            except (ValueError, IndexError, TypeError):
                raise InputError(f"'{p}': feature {i} has malformed coordinates") from None
            ring = _clean_ring(ring)
            if len(ring) < 3:
                continue
            poly = np.column_stack([ring[:, 0], np.zeros(len(ring)), -ring[:, 1]])
            try:
                poly = _upward(poly)
            except InputError:
                continue
            holes = []
            for h in rings[1:]:  # GeoJSON's inner rings: courtyards
                try:
                    hr = _clean_ring(np.asarray(h, float)[:, :2])
                except (ValueError, IndexError, TypeError):
                    raise InputError(f"'{p}': feature {i} has a malformed hole") from None
                if len(hr) >= 3:
                    holes.append(np.column_stack([hr[:, 0], np.zeros(len(hr)), -hr[:, 1]]))
            holes = _usable_holes(ring, holes)
            out.append(Footprint(name if len(polys) == 1 else f"{name}_{k}", poly,
                                 {k2: v for k2, v in props.items() if isinstance(v, (int, float, str, bool))},
                                 holes))
    if not out:
        raise InputError(f"'{p}' holds no usable polygon")
    _center_far_coordinates(out)
    return out


def _center_far_coordinates(fps: list[Footprint]) -> None:
    """Projected coordinates (e.g. UTM, 10⁶ m) lose float precision in geometry ops; CityEngine
    works relative to a scene origin too.  Shift everything so the first footprint sits near 0 and
    record the offset in each footprint's attributes."""
    first = fps[0].polygon[0]
    if np.max(np.abs(first)) < 1e5:
        return
    shift = np.round(first, 0)
    for f in fps:
        f.polygon = f.polygon - shift
        f.holes = [h - shift for h in f.holes]
        f.attributes["_origin_offset"] = shift.tolist()


def _obj(p: Path) -> list[Footprint]:
    from .assets import load_obj

    asset = load_obj(p)
    out = []
    for i, poly in enumerate(asset.mesh.polygons()):
        poly = _clean_ring(poly)
        if len(poly) < 3:
            continue
        n = polygon_normal(poly)
        if not n.any() or abs(n[1]) < 1 - 1e-3:
            continue  # initial shapes are horizontal polygons
        if np.ptp(poly[:, 1]) > EPS * 1e3:
            continue
        out.append(Footprint(f"{p.stem}_{i}", _upward(poly)))
    if not out:
        raise InputError(f"'{p}' holds no horizontal polygon to use as a footprint")
    return out
