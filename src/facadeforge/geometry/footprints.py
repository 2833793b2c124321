"""Initial shapes: building footprints from GeoJSON, OBJ or a ``--lot WxD`` rectangle.

GeoJSON (x, y) maps to CGA (x, −z) with y up, as CityEngine does, so a counter-clockwise GeoJSON
ring becomes a polygon whose normal points up.

Coordinates are metres.  GeoJSON as RFC 7946 writes it, in longitude/latitude degrees (OSM
exports, open building footprint datasets), is projected to the UTM zone of its centre, as
CityEngine projects geographic data into a scene's projected coordinate system: a footprint
file is in degrees when its ``crs`` member says so (``EPSG:4326``, ``CRS84``…), or when it has
no ``crs`` member, every coordinate is a valid longitude/latitude and its footprints are
typically smaller than 0.01 (a hundredth of a degree is about a kilometre; no building is a
centimetre across).  A projected ``crs`` member is kept (and recorded; feet become metres).
Far coordinates are moved near the origin (:func:`_center_far_coordinates`).  Each footprint
records what puts it back on the map: ``_origin_offset`` (CGA axes, metres), ``_crs`` (EPSG
code) and, for a CRS in feet, ``_unit`` (metres per foot), which the CityJSON exporter turns
into ``transform`` (in the CRS's units) and ``referenceSystem``.
A third coordinate is the footprint's elevation (CGA y), the mean of its outline's.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..jsonfile import JsonMembers, json_type
from ..model.model import MAX_COORDINATE
from .mesh import EPS, polygon_normal
from .polygon import without_repeats

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
    """A file's ring without its closing point (GeoJSON repeats the first) and repeated points."""
    if len(ring) > 1 and np.allclose(ring[0], ring[-1]):
        ring = ring[:-1]
    return without_repeats(ring)


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
        Unreadable file, unknown format, no polygon, degenerate polygon; for GeoJSON also
        a member of the wrong type (the message names its JSON path, e.g. ``features[0]``),
        coordinates that are not finite or larger than :data:`MAX_COORDINATE`, a file
        larger than :data:`MAX_FOOTPRINT_FILE_BYTES` or nested thousands of levels deep.
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


#: Largest footprint file read (bytes): a city's footprints run to hundreds of megabytes, and
#: parsing takes several times the text in memory.
MAX_FOOTPRINT_FILE_BYTES = 1024 * 2**20


_GEOJSON_FIX = "fix the file (GeoJSON, RFC 7946)"


class _GeoJson(JsonMembers):
    """Typed reads from a parsed GeoJSON document: every member read is checked for its type,
    and a wrong one is an :class:`InputError` naming the file and the member's JSON path
    (``features[3].geometry.coordinates[0][2]``), so a malformed file never reaches numpy or
    shapely as a value of the wrong kind."""

    def __init__(self, p: Path):
        self.p = p

    def error(self, where: str, problem: str) -> InputError:
        at = f" {where}" if where else ""
        return InputError(f"footprint file '{self.p}':{at} {problem}; {_GEOJSON_FIX}")

    def ring(self, ring, where: str) -> np.ndarray:
        """A ring (array of positions) as (k, 2) or (k, 3) finite floats, positions beyond the
        third value dropped."""
        self.array(ring, where)
        if not ring:
            return np.zeros((0, 2))
        try:  # one conversion for the honest case, checked as a whole
            a = np.array(ring)
        except (ValueError, OverflowError):
            a = None
        if (a is not None and a.ndim == 2 and a.dtype.kind in "iuf" and a.shape[1] >= 2
                and not any(type(v) is bool for pos in ring for v in pos)):
            a = a[:, :3].astype(float)
            if np.isfinite(a).all() and np.abs(a).max() <= MAX_COORDINATE:
                return a
        # something is wrong, or the positions mix 2 and 3 values: position by position
        dims = min(len(self.position(pos, f"{where}[{i}]")) for i, pos in enumerate(ring))
        return np.array([pos[:min(dims, 3)] for pos in ring], float)

    def position(self, pos, where: str) -> list:
        """``pos`` when it is an array of at least two finite numbers of magnitude at most
        :data:`MAX_COORDINATE`."""
        self.array(pos, where)
        if len(pos) < 2:
            raise self.error(where, f"a position needs at least 2 numbers, got {len(pos)}")
        for j, v in enumerate(pos):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise self.error(f"{where}[{j}]", f"must be a number, not {json_type(v)}")
            if not abs(v) <= MAX_COORDINATE:  # NaN compares false too
                shown = repr(v) if len(repr(v)) <= 24 else repr(v)[:12] + "…"
                raise self.error(f"{where}[{j}]", f"is {shown}, not a finite number of magnitude "
                                 f"at most {MAX_COORDINATE:.0e}")
        return pos

    def polygon(self, rings, where: str) -> list[np.ndarray]:
        """A Polygon's ``coordinates``: its rings, outline first."""
        self.array(rings, where)
        return [self.ring(r, f"{where}[{j}]") for j, r in enumerate(rings)]

    def features(self, data: dict) -> list[tuple[dict, str, dict]]:
        """``(feature, where, geometry)`` of each feature with a geometry, ``where`` the
        feature's JSON path (empty for the top level)."""
        kind = self.member(data, "type", "", str, "a string")
        if kind == "FeatureCollection":
            feats = self.member(data, "features", "", list, "an array") or []
            where = [f"features[{i}]" for i in range(min(len(feats), MAX_FOOTPRINTS))]
        elif kind == "Feature":
            feats, where = [data], [""]
        elif kind in ("Polygon", "MultiPolygon"):
            return [({}, "", data)]
        else:
            raise self.error("", "expected a GeoJSON Polygon, MultiPolygon, Feature or "
                             f"FeatureCollection, got type {kind!r}")
        out = []
        for f, w in zip(feats, where):
            if f is None:  # tolerated, as a feature without geometry
                continue
            f = self.obj(f, w)
            geom = self.member(f, "geometry", w, dict, "an object or null")
            if geom is not None:
                out.append((f, w, geom))
        return out

    def crs_name(self, data: dict) -> str | None:
        """The ``crs`` member's name (GeoJSON 2008 ``{"type": "name", "properties": {"name":
        "EPSG:25832"}}``), or None."""
        crs = data.get("crs")
        if crs is None:
            return None
        if not isinstance(crs, dict):
            raise self.error("crs", f"must be an object such as {{\"type\": \"name\", "
                             f"\"properties\": {{\"name\": \"EPSG:25832\"}}}}, not "
                             f"{json_type(crs)}")
        props = self.member(crs, "properties", "crs", dict, "an object") or {}
        return self.member(props, "name", "crs.properties", str, "a string")


def _geojson(p: Path) -> list[Footprint]:
    from ..jsonfile import read_json

    data = read_json(p, "footprint file", fix=_GEOJSON_FIX, max_bytes=MAX_FOOTPRINT_FILE_BYTES)
    doc = _GeoJson(p)
    doc.obj(data, "")
    parts = []  # (name, properties, outline (k, 2 or 3), holes)
    for i, (f, fw, geom) in enumerate(doc.features(data)):
        where = f"{fw}.geometry" if fw else ("geometry" if f else "")
        props = doc.member(f, "properties", fw, dict, "an object or null") or {}
        # names are text or numbers (RFC 7946 §3.2: an id is either); anything else is skipped
        names = [v for v in (props.get("name"), props.get("id"), f.get("id"))
                 if v and isinstance(v, (str, int, float)) and not isinstance(v, bool)]
        name = str(names[0]) if names else f"building_{i}"
        gtype = doc.member(geom, "type", where, str, "a string")
        coords = doc.member(geom, "coordinates", where, list, "an array")
        cw = f"{where}.coordinates"
        if gtype == "Polygon":
            polys = [doc.polygon(coords or [], cw)]
        elif gtype == "MultiPolygon":
            polys = [doc.polygon(c, f"{cw}[{k}]") for k, c in enumerate(coords or [])]
        else:
            continue  # points, lines: not footprints
        for k, rings in enumerate(polys):
            if not rings or len(rings[0]) == 0:
                continue
            parts.append((name if len(polys) == 1 else f"{name}_{k}", props, rings[0], rings[1:]))
    crs_name = doc.crs_name(data)
    project, epsg, note, unit = _georeference(p, crs_name, [ring for _, _, ring, _ in parts])
    out = []
    for name, props, ring, holes in parts:
        ring, holes = project(ring), [project(h) for h in holes]
        if not (np.isfinite(ring).all() and all(np.isfinite(h).all() for h in holes)):
            raise InputError(f"footprint file '{p}': footprint '{name}' lies outside the area "
                             f"its crs can be projected from; check its crs and coordinates")
        elevation = float(ring[:, 2].mean()) if ring.shape[1] > 2 else 0.0
        ring = _clean_ring(ring[:, :2])
        if len(ring) < 3:
            continue
        poly = np.column_stack([ring[:, 0], np.full(len(ring), elevation), -ring[:, 1]])
        try:
            poly = _upward(poly)
        except InputError:
            continue
        kept = []
        for h in holes:  # GeoJSON's inner rings: courtyards
            hr = _clean_ring(h[:, :2])
            if len(hr) >= 3:
                kept.append(np.column_stack([hr[:, 0], np.full(len(hr), elevation), -hr[:, 1]]))
        attrs = {k2: v for k2, v in props.items() if isinstance(v, (int, float, str, bool))}
        if epsg is not None:
            attrs["_crs"] = epsg
            if unit != 1.0:  # metres per unit of that CRS: exports write its units back
                attrs["_unit"] = unit
        if note:
            attrs["_projected"] = note
        out.append(Footprint(name, poly, attrs, _usable_holes(ring, kept)))
    if not out:
        raise InputError(f"'{p}' holds no usable polygon")
    _center_far_coordinates(out)
    return out


#: A footprint file is in degrees (without a ``crs`` member saying so) when its footprints are
#: typically smaller than this many units across
DEGREE_EXTENT = 0.01


def _georeference(p: Path, crs_name, outlines: list) -> tuple:
    """``(project, epsg, note, unit)``: a function taking a ring's coordinates to metres (x
    east, y north[, elevation]), the EPSG code of the CRS the file is in or was projected to
    (None when unknown), a note saying what was projected (empty when nothing was), and the
    metres per unit of that CRS (1 but for feet)."""
    def same(ring):
        return ring

    if not outlines:
        return same, None, "", 1.0
    if crs_name is not None:
        from pyproj import CRS
        from pyproj.exceptions import CRSError

        try:
            crs = CRS.from_user_input(str(crs_name))
        except CRSError:
            raise InputError(f"'{p}': unknown crs '{crs_name}'; give an EPSG code such as "
                             "'EPSG:25832', or omit the crs member for longitude/latitude") from None
        if crs.is_geographic:
            return _to_utm(crs, outlines)
        unit = crs.axis_info[0].unit_conversion_factor if crs.axis_info else 1.0
        if abs(unit - 1.0) < 1e-12:
            return same, crs.to_epsg(), "", 1.0

        def scaled(ring):
            return ring * unit
        return scaled, crs.to_epsg(), f"{crs.axis_info[0].unit_name} to metres", unit
    lon = np.concatenate([r[:, 0] for r in outlines])
    lat = np.concatenate([r[:, 1] for r in outlines])
    extent = np.median([float(np.ptp(r[:, :2], axis=0).max()) for r in outlines])
    if np.abs(lon).max() <= 180 and np.abs(lat).max() <= 90 and extent < DEGREE_EXTENT:
        from pyproj import CRS

        return _to_utm(CRS.from_user_input("OGC:CRS84"), outlines)
    return same, None, "", 1.0


def _to_utm(source, outlines: list) -> tuple:
    """Projection from the geographic ``source`` CRS to the WGS 84 UTM zone of the outlines'
    centre (``always_xy``: longitude first, as GeoJSON writes it)."""
    from pyproj import Transformer

    allpts = np.concatenate([r[:, :2] for r in outlines])
    lon, lat = (float(v) for v in (allpts.min(axis=0) + allpts.max(axis=0)) / 2)
    zone = min(int((lon + 180.0) // 6.0) + 1, 60)
    epsg = (32600 if lat >= 0 else 32700) + zone
    transform = Transformer.from_crs(source, f"EPSG:{epsg}", always_xy=True).transform

    def project(ring):
        x, y = transform(ring[:, 0], ring[:, 1])
        return np.column_stack([x, y, ring[:, 2:]])
    hemisphere = "N" if lat >= 0 else "S"
    return project, epsg, f"longitude/latitude to UTM zone {zone}{hemisphere} (EPSG:{epsg})", 1.0


def _center_far_coordinates(fps: list[Footprint]) -> None:
    """Projected coordinates (e.g. UTM, 10⁶ m) lose float precision in geometry ops; CityEngine
    works relative to a scene origin too.  Shift everything so the first footprint sits near 0 and
    record the offset in each footprint's attributes."""
    first = fps[0].polygon[0]
    if np.max(np.abs(first)) < 1e5:
        return
    shift = np.round(first, 0) * [1.0, 0.0, 1.0]  # across the ground only: elevations stay
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
