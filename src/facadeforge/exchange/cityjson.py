"""CityJSON 2.0 export (LoD3 with semantic surfaces) and a reader for such files.

Each :class:`~facadeforge.model.Model` becomes one ``Building`` City Object (id ``model.name``,
``attributes`` the scalar entries of ``model.attributes``) with one ``MultiSurface`` geometry of
level of detail ``"3"``: every polygon of every part is one surface ``[[ring]]``, and a face with
holes (pieces sharing a ``holed`` id, see ``geometry.holed``) is one surface ``[[outer], [hole],
…]``, holes turning the other way, as CityJSON wants; the reader turns such surfaces back into
pieces of one face.

Coordinates
    CGA (x, y up, z) maps to CityJSON (x, −z, y): z is up and the map is a rotation, so outward
    counter-clockwise rings stay outward counter-clockwise.  Vertices are integers with the
    mandatory ``transform`` (``scale`` 0.001 by default: millimetres), shared between faces, and
    an optional ``origin`` (in CityJSON axes, e.g. projected coordinates of the model's origin)
    goes into ``translate``.
Semantics
    Each surface gets a Semantic Object ``{"type": ..., "facadeforge_label": label,
    "facadeforge_symbol": symbol}``.  The type comes from :data:`DEFAULT_SEMANTIC_MAP` (only
    standard CityJSON 2.0 Building types are used: windows, shop fronts → ``Window``; doors →
    ``Door``; roofs → ``RoofSurface``; ground → ``GroundSurface``; every other facade element →
    ``WallSurface``), overridable per label with the ``semantic_map`` option.  A label mapped to
    ``None`` gets a ``null`` semantic value.
Appearance
    Materials go to ``appearance.materials`` (theme ``"facadeforge"``: ``diffuseColor``,
    ``transparency``); readable textures are copied into ``textures/`` beside the file and
    referenced with their UVs (theme ``"facadeforge"``).
"""

from __future__ import annotations

import itertools
import json
import os
import secrets
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..geometry.holed import HOLED, face_groups, fresh_ids, plane_polygon, rings
from ..geometry.mesh import Mesh, column_bounds, plane_basis, polygon_normal
from ..jsonfile import parse_json, read_json
from ..model.labels import Labels, label_for_name
from ..model.model import Material, Model, Part
from ._ascii import format_lines
from ._common import (
    Staging,
    corner_uvs,
    face_corners,
    image_extension,
    iter_models,
    jsonable,
    previous_corner,
    ranges_index,
    read_texture,
    safe_name,
    scalar_attributes,
)
from .errors import ExportError, LoadError

__all__ = ["DEFAULT_SEMANTIC_MAP", "SEMANTIC_TYPES", "export_cityjson", "load_cityjson"]

THEME = "facadeforge"

#: Semantic surface types CityJSON 2.0 defines for buildings.
SEMANTIC_TYPES = frozenset({
    "RoofSurface", "GroundSurface", "WallSurface", "ClosureSurface", "OuterCeilingSurface",
    "OuterFloorSurface", "Window", "Door", "InteriorWallSurface", "CeilingSurface",
    "FloorSurface",
})

#: Canonical label → CityJSON semantic surface type (``None``: no semantics).
DEFAULT_SEMANTIC_MAP: dict[str, str | None] = {
    Labels.WALL.value: "WallSurface",
    Labels.WINDOW.value: "Window",
    Labels.DOOR.value: "Door",
    Labels.SHOP.value: "Window",
    Labels.ROOF.value: "RoofSurface",
    Labels.GROUND.value: "GroundSurface",
    Labels.BALCONY.value: "WallSurface",
    Labels.CORNICE.value: "WallSurface",
    Labels.SILL.value: "WallSurface",
    Labels.BLIND.value: "WallSurface",
    Labels.DECO.value: "WallSurface",
    Labels.MOLDING.value: "WallSurface",
    Labels.PILLAR.value: "WallSurface",
    Labels.VEGETATION.value: "WallSurface",
    Labels.OTHER.value: "WallSurface",
    Labels.BACKGROUND.value: "WallSurface",
    Labels.SKY.value: "WallSurface",
    "": "WallSurface",
}

LODS = frozenset({"0", "0.0", "0.1", "0.2", "0.3", "1", "1.0", "1.1", "1.2", "1.3",
                  "2", "2.0", "2.1", "2.2", "2.3", "3", "3.0", "3.1", "3.2", "3.3"})

# CGA (x, y, z) → CityJSON (x, -z, y): a rotation (determinant +1).
_TO_CJ = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


# -- export -----------------------------------------------------------------------------------

def export_cityjson(models: Model | Sequence[Model], path: str | os.PathLike, *,
                    semantic_map: dict[str, str | None] | None = None,
                    reference_system: str | int | None = None, lod: str = "3",
                    scale: float = 0.001, origin: Sequence[float] | None = None,
                    metadata: dict | None = None, textures: bool = True) -> list[Path]:
    """Write models as a CityJSON 2.0 file with LoD3 semantic surfaces.

    Parameters
    ----------
    models : Model, sequence or iterable of Model
        Written as they come (a generator such as ``engine.derive_iter`` keeps memory to a
        few buildings).
        One ``Building`` per model.
    path : path-like
        Destination (``.city.json``); written atomically together with copied textures.
    semantic_map : dict, optional
        Label → semantic surface type, merged over :data:`DEFAULT_SEMANTIC_MAP`.  Values are
        standard types, Extension types (``"+Name"``) or ``None``.
    reference_system : str or int, optional
        CRS of the coordinates: an EPSG code (``7415``, ``"EPSG:7415"``) or an OGC URL; goes to
        ``metadata.referenceSystem``.  By default the first model's footprint CRS
        (``_crs``: the file's ``crs``, or the UTM zone longitude/latitude footprints were
        projected to), if known.
    lod : str
        Level of detail of the geometries (a CityGML/TU Delft LoD such as ``"3"`` or ``"2.2"``).
    scale : float
        Quantisation step of the integer vertices (``transform.scale``).
    origin : (3,) float, optional
        Offset added to every vertex, in CityJSON axes (x east, y north, z up).  By default
        the first model's ``_origin_offset`` (by which its footprint file's far coordinates
        were moved near zero), so the buildings go back to where the footprints were.
    metadata : dict, optional
        Extra ``metadata`` members (``title``, ``identifier``, ``pointOfContact``…).
    textures : bool
        Copy readable textures and write texture coordinates.

    Returns
    -------
    list of Path
        The CityJSON file and every copied texture.
    """
    return _export(models, path, False, semantic_map, reference_system, lod, scale, origin,
                   metadata, textures)


def export_cityjsonseq(models: Model | Sequence[Model], path: str | os.PathLike, *,
                       semantic_map: dict[str, str | None] | None = None,
                       reference_system: str | int | None = None, lod: str = "3",
                       scale: float = 0.001, origin: Sequence[float] | None = None,
                       metadata: dict | None = None, textures: bool = True) -> list[Path]:
    """Write models as CityJSON Text Sequences (``.city.jsonl``, CityJSONSeq 2.0): one line with
    the transform and metadata, then one ``CityJSONFeature`` a line, each building with its own
    vertices and appearance, the form cities are streamed and tiled in.  Options as
    :func:`export_cityjson`; written model by model."""
    return _export(models, path, True, semantic_map, reference_system, lod, scale, origin,
                   metadata, textures)


def _export(models, path, sequence: bool, semantic_map, reference_system, lod, scale, origin,
            metadata, textures) -> list[Path]:
    """Both CityJSON forms: options checked, the file and its textures written atomically."""
    types = _semantic_map(semantic_map)
    if str(lod) not in LODS:
        raise ExportError(f"lod {lod!r} is not a CityJSON level of detail ({sorted(LODS)})")
    if not scale > 0:
        raise ExportError(f"scale must be positive, got {scale}")
    models = iter_models(models)
    first = next(models)  # its footprint's georeference is the file's default
    models = itertools.chain([first], models)
    if origin is None:
        offset = first.attributes.get("_origin_offset")
        origin = _TO_CJ @ np.asarray(offset, float) if offset is not None else np.zeros(3)
    unit = 1.0  # metres per unit of the reference system: the transform is in its units
    if reference_system is None:
        reference_system = first.attributes.get("_crs")
        unit = float(first.attributes.get("_unit", 1.0))
    writer = _CityJsonWriter(types, str(lod), float(scale), np.asarray(origin, float), textures,
                             unit)
    out = Path(path)
    with Staging() as stage:
        final = stage.path(out)
        with open(final, "w", encoding="utf-8", newline="\n") as fh:
            meta = _metadata(reference_system, metadata)
            if sequence:
                writer.write_sequence(fh, models, meta)
            else:
                writer.write(fh, models, meta, spill_dir=final.parent)
        for relative, data in writer.texture_files.items():
            stage.write_bytes(out.parent / relative, data)
    return [out, *(out.parent / r for r in writer.texture_files)]


def _semantic_map(overrides: dict | None) -> dict[str, str | None]:
    types = dict(DEFAULT_SEMANTIC_MAP)
    for label, kind in (overrides or {}).items():
        if kind is not None and kind not in SEMANTIC_TYPES and not str(kind).startswith("+"):
            raise ExportError(f"semantic_map[{label!r}] = {kind!r} is not a CityJSON semantic "
                              f"surface type ({', '.join(sorted(SEMANTIC_TYPES))}, or '+Ext')")
        types[str(label)] = kind
    return types


def _metadata(reference_system: str | int | None, extra: dict | None) -> dict:
    meta = dict(jsonable(extra or {}))
    if reference_system is not None:
        meta["referenceSystem"] = _crs_url(reference_system)
    return meta


def _crs_url(crs: str | int) -> str:
    text = str(crs).strip()
    if text.lower().startswith(("http://", "https://")):
        return text
    code = text.split(":")[-1]
    if not code.isdigit():
        raise ExportError(f"reference_system {crs!r} is neither an EPSG code nor a URL")
    return f"https://www.opengis.net/def/crs/EPSG/0/{code}"


class _Faces:
    """Every surface of a model flattened into rings: corners in CityJSON axes, per-ring
    records (``offsets``, ``has_uv``, ``surface_of``) and per-surface owners (``part_of``)."""

    def __init__(self, model: Model, origin: np.ndarray) -> None:
        pts, uvs, has, sizes, holes, owner = [], [], [], [], [], []
        self.parts = [p for p in model.parts if p.mesh.n_faces]
        for index, part in enumerate(self.parts):
            for ring_pts, ring_uvs, ring_sizes, ring_has, ring_hole in _surface_rings(part.mesh):
                pts.append(ring_pts)
                uvs.append(ring_uvs)
                sizes.append(ring_sizes)
                has.append(ring_has)
                holes.append(ring_hole)
                owner.append(np.full(int(np.count_nonzero(ring_hole == 0)), index, np.int64))
        if not pts:
            pts, uvs, sizes, has, holes, owner = [np.zeros((0, 3))], [np.zeros((0, 2))], \
                [np.zeros(0, np.int64)], [np.zeros(0, bool)], [np.zeros(0, np.int64)], \
                [np.zeros(0, np.int64)]
        self.points = np.concatenate(pts) @ _TO_CJ.T + origin
        # bounds of the corners (the building's extent, the file's translation)
        self.lo, self.hi = column_bounds(self.points) if len(self.points) else (origin, origin)
        self.uv = np.concatenate(uvs)
        self.has_uv = np.concatenate(has).astype(bool)
        self.offsets = np.concatenate([[0], np.cumsum(np.concatenate(sizes))]).astype(np.int64)
        # a ring starts a new surface when it is an outer ring (its hole number is 0)
        self.surface_of = np.cumsum(np.concatenate(holes) == 0) - 1
        self.part_of = np.concatenate(owner)


def _surface_rings(mesh: Mesh):
    """The rings of every surface of ``mesh`` in blocks ``(points (C, 3), uvs (C, 2), sizes
    (R,), has_uv (R,), hole (R,))``, ``hole`` 0 for a surface's outer ring and 1, 2… for its
    holes: each face alone (whole runs of such faces in one block), the pieces of a face with
    holes as one outline with its holes (corner uvs looked up where the pieces have them)."""
    corners, starts = face_corners(mesh)
    uv, has_uv = corner_uvs(mesh)
    if mesh.column(HOLED) is None:  # every face is a surface of its own: one block
        yield _single_faces(mesh, np.arange(mesh.n_faces), corners, starts, uv, has_uv)
        return
    normals = mesh.face_normals()
    run: list[int] = []  # faces alone, waiting to be yielded as one block
    for group in face_groups(mesh):
        f = group[0]
        if len(group) == 1 or not normals[f].any():
            run.extend(group)
            continue
        if run:
            yield _single_faces(mesh, np.asarray(run), corners, starts, uv, has_uv)
            run = []
        p0 = mesh.vertices[corners[starts[f]]]
        basis = plane_basis(normals[f], mesh.vertices[corners[starts[f] + 1]] - p0)
        at = {}
        for g in group:
            for c in range(starts[g], starts[g + 1]):
                at.setdefault(tuple(np.round(mesh.vertices[corners[c]], 6)), uv[c])
        for outer, holes in rings(plane_polygon(mesh, group, p0, basis)):
            for k, ring in enumerate([outer, *holes]):
                pts = p0 + ring @ basis[:, :2].T
                ring_uv = [at.get(tuple(np.round(q, 6))) for q in pts]
                found = has_uv and all(u is not None for u in ring_uv)
                yield (pts, np.array(ring_uv) if found else np.zeros((len(pts), 2)),
                       np.array([len(pts)]), np.array([found]), np.array([k]))
    if run:
        yield _single_faces(mesh, np.asarray(run), corners, starts, uv, has_uv)


def _single_faces(mesh: Mesh, faces: np.ndarray, corners, starts, uv, has_uv):
    """One ``_surface_rings`` block of faces that are surfaces on their own, all at once."""
    sizes = starts[faces + 1] - starts[faces]
    at = ranges_index(starts[faces], sizes)
    return (mesh.vertices[corners[at]], uv[at], sizes, np.full(len(faces), has_uv),
            np.zeros(len(faces), np.int64))


class _CityJsonWriter:
    def __init__(self, types: dict, lod: str, scale: float, origin: np.ndarray,
                 textures: bool, unit: float = 1.0) -> None:
        self.types, self.lod, self.scale, self.origin = types, lod, scale, origin
        self.unit = unit  # metres per unit of the reference system (feet: 0.3048…)
        self.with_textures = textures
        self.materials: dict[tuple, int] = {}
        self.material_list: list[dict] = []
        self.textures: dict[str, int | None] = {}   # source -> index in texture_list
        self.texture_list: list[dict] = []
        self.texture_files: dict[str, bytes] = {}   # relative path -> image bytes (copied)
        self.texture_paths: dict[str, str | None] = {}  # source -> relative path, once
        self.uv_list: list[np.ndarray] = []
        self.uv_count = 0

    def write(self, fh, models, metadata: dict, spill_dir=None) -> None:
        """The document, building by building, so that a city never sits in memory whole:
        the CityObjects first, each with its own vertices (coincident ones once), which wait
        in a temporary file; then the vertices, the transform, the metadata and the
        appearance.  The translation is the first building's lowest corner."""
        translate = None
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        taken: set[str] = set()
        count = 0
        with tempfile.TemporaryFile("w+", encoding="utf-8", dir=spill_dir) as vertices, \
                tempfile.TemporaryFile("w+", encoding="utf-8", dir=spill_dir) as uvs:
            fh.write('{"type":"CityJSON","version":"2.0","CityObjects":{')
            for model in models:
                f = _Faces(model, self.origin)
                vids = np.zeros(0, np.int64)
                if len(f.points):
                    if translate is None:
                        translate = f.lo
                    lo, hi = np.minimum(lo, f.lo), np.maximum(hi, f.hi)
                    uniq, vids = self._quantized(f, translate)
                    vids = vids + count
                    text = _json_rows(uniq).text[1:-1]
                    vertices.write(("," if count else "") + text)
                    count += len(uniq)
                name = _unique_id(model.name, taken)
                taken.add(name)
                fh.write(("," if len(taken) > 1 else "") + json.dumps(name) + ":"
                         + _dumps(self._building(model, f, vids)))
                if self.uv_list:  # the building's texture coordinates wait on disk too
                    text = json.dumps(np.concatenate(self.uv_list).round(6).tolist(),
                                      separators=(",", ":"))[1:-1]
                    uvs.write(("," if uvs.tell() else "") + text)
                    self.uv_list = []
            fh.write('},"vertices":[')
            vertices.seek(0)
            shutil.copyfileobj(vertices, fh, 1 << 20)
            translate = self.origin if translate is None else translate
            if count:
                metadata = {"geographicalExtent": [*(lo / self.unit).tolist(),
                                                   *(hi / self.unit).tolist()], **metadata}
            tail = {"transform": self._transform(translate), "metadata": metadata}
            fh.write("]," + json.dumps(tail, separators=(",", ":"))[1:-1])
            appearance = self._appearance(with_uvs=False)
            if appearance:
                fh.write(',"appearance":' + json.dumps(appearance, separators=(",", ":"))[:-1])
                if self.texture_list and uvs.tell():
                    fh.write(',"vertices-texture":[')
                    uvs.seek(0)
                    shutil.copyfileobj(uvs, fh, 1 << 20)
                    fh.write(']')
                fh.write("}")
            fh.write("}")

    def write_sequence(self, fh, models, metadata: dict) -> None:
        """CityJSON Text Sequences: a first line with the transform (its translation the first
        building's lowest corner) and metadata, then one ``CityJSONFeature`` per line with its
        own vertices and appearance."""
        header_done = False
        taken: set[str] = set()
        translate = self.origin
        for model in models:
            f = _Faces(model, self.origin)
            if not header_done:
                translate = f.lo if len(f.points) else self.origin
                head = {"type": "CityJSON", "version": "2.0",
                        "transform": self._transform(translate),
                        "CityObjects": {}, "vertices": [], "metadata": metadata}
                fh.write(json.dumps(head, separators=(",", ":")) + "\n")
                header_done = True
            self.reset_appearance()
            uniq, vids = self._quantized(f, translate)
            name = _unique_id(model.name, taken)
            taken.add(name)
            feature = {"type": "CityJSONFeature", "id": name,
                       "CityObjects": {name: self._building(model, f, vids)},
                       "vertices": _json_rows(uniq)}
            appearance = self._appearance()
            if appearance:
                feature["appearance"] = appearance
            fh.write(_dumps(feature) + "\n")

    def _transform(self, translate: np.ndarray) -> dict:
        """``transform`` of the integer vertices, which are metres / ``scale`` from
        ``translate`` (metres): in the reference system's units."""
        return {"scale": [self.scale / self.unit] * 3, "translate": (translate / self.unit).tolist()}

    def _quantized(self, f: _Faces, translate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A building's integer vertices (coincident ones once) and each corner's index."""
        if not len(f.points):
            return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
        ints = np.rint((f.points - translate) / self.scale).astype(np.int64)
        return unique_rows(ints)

    def _building(self, model: Model, f: _Faces, vids: np.ndarray) -> dict:
        obj: dict = {"type": "Building", "attributes": scalar_attributes(model.attributes)}
        if len(f.points):
            obj["geographicalExtent"] = [*f.lo.tolist(), *f.hi.tolist()]
            geometry = self._geometry(f, vids)
            if geometry is not None:
                obj["geometry"] = [geometry]
        return obj

    def _geometry(self, f: _Faces, vids: np.ndarray) -> dict | None:
        keep, valid = _clean_rings(vids, f.offsets)
        ring_of = np.repeat(np.arange(len(f.offsets) - 1), np.diff(f.offsets))
        sizes = np.bincount(ring_of[keep], minlength=len(f.offsets) - 1)
        bounds = np.concatenate([[0], np.cumsum(sizes)])
        uv_kept = f.uv[keep]
        # a surface is kept when its outer ring is; its holes when they are
        first = np.r_[True, f.surface_of[1:] != f.surface_of[:-1]]
        outer_ok = np.zeros(len(f.part_of), bool)
        outer_ok[f.surface_of[first & valid]] = True
        kept = np.flatnonzero(valid & outer_ok[f.surface_of])      # rings written, in order
        if not len(kept):  # nothing left to write
            return None
        # the kept rings of one surface are consecutive: split the list where a surface starts
        opens = np.flatnonzero(first[kept]).tolist()
        if len(opens) == len(kept):  # no holes, one ring a surface (the usual case): as text
            lengths = bounds[kept + 1] - bounds[kept]
            at = ranges_index(bounds[kept], lengths)
            text = format_lines("[[", vids[keep][at], np.concatenate([[0], np.cumsum(lengths)]),
                                sep=",", end="]],")
            boundaries = _Raw(b"[" + text[:-1] + b"]")
        else:
            flat = vids[keep].tolist()
            lo, hi = bounds[kept].tolist(), bounds[kept + 1].tolist()
            ring_ids = [flat[a:b] for a, b in zip(lo, hi)]
            ends = opens[1:] + [len(kept)]
            boundaries = [ring_ids[a:b] for a, b in zip(opens, ends)]
        owner = f.part_of[f.surface_of[kept[opens]]]
        surfaces: dict[tuple, int] = {}
        sem = [self._surface(p, surfaces) for p in f.parts]
        mat = [self._material(p.material) for p in f.parts]
        owners = owner.tolist()
        geometry = {"type": "MultiSurface", "lod": self.lod, "boundaries": boundaries,
                    "semantics": {"surfaces": [dict(s) for s in surfaces],
                                  "values": [sem[p] for p in owners]},
                    "material": {THEME: {"values": [mat[p] for p in owners]}}}
        textures = self._texture_values(f, owner, kept, opens, uv_kept, bounds)
        if textures is not None:
            geometry["texture"] = {THEME: {"values": textures}}
        return geometry

    def _texture_values(self, f: _Faces, owner: np.ndarray, kept: np.ndarray, opens: list[int],
                        uv: np.ndarray, bounds: np.ndarray) -> list | None:
        """Per-surface texture references, a ``[tex, uv…]`` per ring (``[[None]]`` without
        texture): a surface is textured when its part's material has a texture and every ring
        of it has texture coordinates."""
        tex = [self._texture_index(p.material.texture) for p in f.parts]
        if all(t is None for t in tex):
            return None
        part_tex = np.array([-1 if t is None else t for t in tex], np.int64)
        surface_ok = (part_tex[owner] >= 0) & np.logical_and.reduceat(f.has_uv[kept], opens)
        ring_ok = np.repeat(surface_ok, np.diff(opens + [len(kept)]))
        textured = kept[ring_ok]
        lengths = bounds[textured + 1] - bounds[textured]
        if len(textured):
            at = ranges_index(bounds[textured], lengths)
            self.uv_list.append(uv[at])
        numbers = range(self.uv_count, self.uv_count + int(lengths.sum()))
        self.uv_count += int(lengths.sum())
        ring_tex = part_tex[np.repeat(owner, np.diff(opens + [len(kept)]))].tolist()
        refs, used = [], 0
        for ok, t, n in zip(ring_ok.tolist(), ring_tex, np.diff(bounds)[kept].tolist()):
            if ok:
                refs.append([t, *numbers[used:used + n]])
                used += n
            else:
                refs.append(None)
        if len(opens) == len(kept):
            return [[r] if r is not None else [[None]] for r in refs]
        ends = opens[1:] + [len(kept)]
        return [refs[a:b] if surface_ok[i] else [[None]]
                for i, (a, b) in enumerate(zip(opens, ends))]

    def _surface(self, part: Part, surfaces: dict[tuple, int]) -> int | None:
        kind = self.types.get(part.label, self.types.get(""))
        if kind is None:
            return None
        key = (("type", kind), ("facadeforge_label", part.label),
               ("facadeforge_symbol", part.symbol))
        return surfaces.setdefault(key, len(surfaces))

    def _material(self, mat: Material) -> int:
        key = mat.key()
        if key not in self.materials:
            self.materials[key] = len(self.material_list)
            self.material_list.append({
                "name": mat.name, "diffuseColor": [float(c) for c in mat.color],
                "transparency": float(1.0 - mat.opacity), "isSmooth": False})
        return self.materials[key]

    def _texture_index(self, source: str | None) -> int | None:
        if not self.with_textures or not source:
            return None
        if source not in self.texture_paths:
            found = read_texture(source)
            relative = None
            if found is not None:
                data, mime = found
                ext = image_extension(mime)
                relative = f"textures/{safe_name(Path(source).stem, 'texture')}{ext}"
                n = 1
                while relative in self.texture_files:
                    n += 1
                    relative = f"textures/{safe_name(Path(source).stem, 'texture')}_{n}{ext}"
                self.texture_files[relative] = data
            self.texture_paths[source] = relative
        if source not in self.textures:
            relative = self.texture_paths[source]
            if relative is None:
                self.textures[source] = None
            else:
                self.textures[source] = len(self.texture_list)
                self.texture_list.append({"type": "JPG" if relative.endswith(".jpg") else "PNG",
                                          "image": relative, "wrapMode": "wrap"})
        return self.textures[source]

    def reset_appearance(self) -> None:
        """Start a new document's materials and textures (each CityJSONFeature has its own);
        texture files already chosen stay."""
        self.materials, self.material_list = {}, []
        self.textures, self.texture_list = {}, []
        self.uv_list, self.uv_count = [], 0

    def _appearance(self, with_uvs: bool = True) -> dict:
        """Materials and textures; the texture coordinates too unless they were written out
        as the buildings came (``with_uvs`` False)."""
        out: dict = {}
        if self.material_list:
            out["materials"] = self.material_list
            out["default-theme-material"] = THEME
        if self.texture_list and self.uv_count:
            out["textures"] = self.texture_list
            if with_uvs:
                out["vertices-texture"] = np.concatenate(self.uv_list).round(6).tolist()
            out["default-theme-texture"] = THEME
        return out


def _clean_rings(vids: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop repeated consecutive vertices (after quantisation) and degenerate faces.

    Returns the corner mask (C,) of what stays and the face mask (F,) of faces that still have
    at least three distinct vertices.
    """
    n_faces = len(starts) - 1
    if n_faces == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    face_of = np.repeat(np.arange(n_faces), np.diff(starts))
    keep = vids != vids[previous_corner(starts)]
    # three distinct vertices: one unlike the face's first, and one unlike both (linear, where
    # counting the distinct ids of every face took a sort of all corners)
    sizes = np.diff(starts)
    first_id = np.full(n_faces, -1, np.int64)
    first_id[sizes > 0] = vids[starts[:-1][sizes > 0]]
    other = vids != first_id[face_of]
    at = np.flatnonzero(other)                     # in order, so grouped by face
    owner = face_of[at]
    lead = np.r_[True, owner[1:] != owner[:-1]] if len(at) else np.zeros(0, bool)
    second_id = np.full(n_faces, -1, np.int64)
    second_id[owner[lead]] = vids[at[lead]]        # each face's first corner unlike its first
    third = other & (vids != second_id[face_of])
    valid = np.bincount(face_of[third], minlength=n_faces) > 0
    return keep & valid[face_of], valid


class _Raw:
    """JSON text that :func:`_dumps` writes as it is (arrays of millions of numbers, which
    :func:`format_lines` writes far faster than ``json`` encodes lists)."""

    __slots__ = ("text",)

    def __init__(self, text: bytes) -> None:
        self.text = text.decode("ascii")

#: Stands for a _Raw in json's output until it is replaced (random: no user text holds it).
_MARK = "\x00raw-" + secrets.token_hex(16)


def _json_rows(ints: np.ndarray) -> _Raw:
    """(N, 3) integers as the JSON array of arrays ``[[x,y,z],…]``."""
    if not len(ints):
        return _Raw(b"[]")
    return _Raw(b"[" + format_lines("[", ints, sep=",", end="],")[:-1] + b"]")


def _dumps(obj) -> str:
    """Compact ``json.dumps`` that writes :class:`_Raw` values as their text."""
    raws: list[str] = []

    def raw(value):
        if isinstance(value, _Raw):
            raws.append(value.text)
            return _MARK
        raise TypeError(f"{type(value).__name__} is not JSON serializable")
    text = json.dumps(obj, separators=(",", ":"), default=raw)
    if not raws:
        return text
    pieces = text.split(json.dumps(_MARK))
    if len(pieces) != len(raws) + 1:  # pragma: no cover - the mark is random
        raise ExportError("internal: raw JSON marker found in the data")
    return "".join(p + r for p, r in zip(pieces, [*raws, ""]))


def unique_rows(ints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(ints, axis=0, return_inverse=True)`` for (N, 3) integers, through one
    integer key per row where the span allows (the row-wise sort was 6 s of a 40-building
    city); the same rows in the same (lexicographic) order."""
    lo, hi = column_bounds(ints)
    span = hi - lo + 1
    if float(span[0]) * float(span[1]) * float(span[2]) >= 2.0 ** 62:
        uniq, inverse = np.unique(ints, axis=0, return_inverse=True)
        return uniq, inverse.reshape(-1)
    shifted = ints - lo
    key = (shifted[:, 0] * span[1] + shifted[:, 1]) * span[2] + shifted[:, 2]
    keys, inverse = np.unique(key, return_inverse=True)
    uniq = np.stack([keys // (span[1] * span[2]), keys // span[2] % span[1], keys % span[2]],
                    axis=1) + lo
    return uniq, inverse.reshape(-1)


def _unique_id(name: str, taken: dict) -> str:
    base = str(name) or "building"
    candidate, n = base, 1
    while candidate in taken:
        n += 1
        candidate = f"{base}-{n}"
    return candidate


# -- import -----------------------------------------------------------------------------------

def load_cityjson(path: str | os.PathLike) -> list[Model]:
    """Read the surface geometry of a CityJSON file back into models.

    One model per City Object with surface geometry (``MultiSurface``, ``CompositeSurface`` or
    ``Solid``; of several geometries the one with the highest LoD), converted back to CGA axes.
    Outer rings only (holes are dropped).  Labels come from the ``facadeforge_label`` attribute
    of the semantic surfaces, or from their type; materials and textures from the first theme.

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist.
    LoadError
        When the file is not CityJSON.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    doc = read_json(path, "CityJSON file", fix="write it again", error=LoadError)
    if not isinstance(doc, dict) or doc.get("type") != "CityJSON":
        raise LoadError(f"{path} is not a CityJSON file")
    reader = _CityJsonReader(doc, path.parent)
    return [m for oid, obj in doc.get("CityObjects", {}).items()
            if (m := reader.model(oid, obj)) is not None]


def load_cityjsonseq(path: str | os.PathLike) -> list[Model]:
    """Read CityJSON Text Sequences (``.city.jsonl``): the first line's transform, then each
    ``CityJSONFeature`` with its vertices and appearance, as :func:`load_cityjson` reads a
    file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    models: list[Model] = []
    head = None
    try:
        with open(path, encoding="utf-8-sig") as fh:
            for number, line in enumerate(fh, 1):
                if not line.strip():
                    continue
                doc = parse_json(line, f"CityJSON sequence '{path}':{number}",
                                 fix="write it again", error=LoadError)
                if head is None:
                    if not isinstance(doc, dict) or doc.get("type") != "CityJSON":
                        raise LoadError(f"{path}: the first line is not a CityJSON object")
                    head = doc
                    continue
                if not isinstance(doc, dict) or doc.get("type") != "CityJSONFeature":
                    raise LoadError(f"{path}:{number}: not a CityJSONFeature")
                part = {"type": "CityJSON", "transform": head.get("transform"),
                        "vertices": doc.get("vertices", []), "appearance": doc.get("appearance"),
                        "CityObjects": doc.get("CityObjects", {})}
                reader = _CityJsonReader(part, path.parent)
                models.extend(m for oid, obj in part["CityObjects"].items()
                              if (m := reader.model(oid, obj)) is not None)
    except UnicodeDecodeError as exc:
        raise LoadError(f"CityJSON sequence '{path}' is not UTF-8 text (byte {exc.start}); "
                        "write it again") from None
    if head is None:
        raise LoadError(f"{path} is empty")
    return models


class _CityJsonReader:
    def __init__(self, doc: dict, folder: Path) -> None:
        tr = doc.get("transform") or {"scale": [1, 1, 1], "translate": [0, 0, 0]}
        verts = np.asarray(doc.get("vertices", []), float).reshape(-1, 3)
        real = verts * np.asarray(tr["scale"], float) + np.asarray(tr["translate"], float)
        self.vertices = real @ _TO_CJ  # inverse rotation: CityJSON → CGA
        app = doc.get("appearance") or {}
        self.materials = app.get("materials", [])
        self.textures = app.get("textures", [])
        self.uvs = np.asarray(app.get("vertices-texture", []), float).reshape(-1, 2)
        self.folder = folder

    def model(self, oid: str, obj: dict) -> Model | None:
        geoms = [g for g in obj.get("geometry", [])
                 if g.get("type") in ("MultiSurface", "CompositeSurface", "Solid")]
        if not geoms:
            return None
        geom = max(geoms, key=lambda g: float(str(g.get("lod", "0"))))
        model = Model(name=oid, attributes=dict(obj.get("attributes") or {}))
        surfaces, sem, mats, texs = _flatten_geometry(geom)
        runs: dict[tuple, list[int]] = {}
        for i, key in enumerate(self._face_keys(geom, sem, mats, texs)):
            runs.setdefault(key, []).append(i)
        for (label, symbol, mat_index, tex_index), idx in runs.items():
            meshes = [self._surface_mesh(surfaces[i], texs[i]) for i in idx]
            model.parts.append(Part(Mesh.merge(meshes), label=label,
                                    material=self._material(mat_index, tex_index),
                                    symbol=symbol))
        return model

    def _surface_mesh(self, ring_ids: list, refs: list) -> Mesh:
        """One surface: a polygon, or, with holes, the pieces of one face with holes."""
        pts = [self.vertices[r] for r in ring_ids]
        uvs = [self._face_uv(refs[k] if k < len(refs) else None) for k in range(len(pts))]
        if len(pts) == 1:
            return Mesh.from_polygons(pts, uvs)
        import shapely

        from ..geometry.polygon import simple_pieces

        n = polygon_normal(pts[0])
        basis = plane_basis(n, pts[0][1] - pts[0][0])
        flat = [(q - pts[0][0]) @ basis[:, :2] for q in pts]
        shape = shapely.Polygon(flat[0], flat[1:]).buffer(0)
        pieces = [q for outer, holes in rings(shape)
                  for q in simple_pieces(shapely.Polygon(outer, holes))]
        lifted = [pts[0][0] + q @ basis[:, :2].T for q in pieces]
        piece_uvs = None
        if all(u is not None for u in uvs):
            at = {tuple(np.round(p, 6)): u for ring, ring_uv in zip(pts, uvs)
                  for p, u in zip(ring, ring_uv)}
            found = [[at.get(tuple(np.round(p, 6))) for p in q] for q in lifted]
            if all(u is not None for q in found for u in q):
                piece_uvs = [np.array(q) for q in found]
        return Mesh.from_polygons(lifted, piece_uvs).with_column(
            HOLED, fresh_ids([0] * len(lifted)))

    @staticmethod
    def _face_keys(geom: dict, sem: list, mats: list, texs: list) -> list[tuple]:
        table = (geom.get("semantics") or {}).get("surfaces", [])
        keys = []
        for s, m, t in zip(sem, mats, texs):
            surface = table[s] if s is not None and s < len(table) else {}
            label = surface.get("facadeforge_label")
            if label is None:
                guess = label_for_name(str(surface.get("type", "")).replace("Surface", ""))
                label = guess.value if guess else ""
            tex = t[0][0] if t and t[0] else None
            keys.append((label, surface.get("facadeforge_symbol", ""), m, tex))
        return keys

    def _material(self, index: int | None, texture: int | None) -> Material:
        path = None
        if texture is not None and texture < len(self.textures):
            candidate = self.folder / self.textures[texture].get("image", "")
            path = str(candidate) if candidate.is_file() else None
        if index is None or index >= len(self.materials):
            return Material(texture=path)
        m = self.materials[index]
        return Material(name=m.get("name", f"material{index}"),
                        color=tuple(float(c) for c in m.get("diffuseColor", (1, 1, 1))),
                        opacity=1.0 - float(m.get("transparency", 0.0)), texture=path)

    def _face_uv(self, ref: list | None) -> np.ndarray | None:
        if not ref or ref[0] is None or len(ref) < 4:
            return None
        return self.uvs[np.asarray(ref[1:], np.int64)]


def _flatten_geometry(geom: dict) -> tuple[list, list, list, list]:
    """Rings (outer first), semantic values, material values and texture refs (one per ring),
    one entry per surface."""
    kind = geom["type"]
    boundaries = geom.get("boundaries", [])
    sem = (geom.get("semantics") or {}).get("values")
    mat = next(iter((geom.get("material") or {}).values()), {})
    tex = next(iter((geom.get("texture") or {}).values()), {}).get("values")
    if kind == "Solid":
        boundaries = [s for shell in boundaries for s in shell]
        sem = None if sem is None else [v for shell in sem for v in (shell or [])]
        tex = None if tex is None else [v for shell in tex for v in shell]
    n = len(boundaries)
    surfaces = [[np.asarray(r, np.int64) for r in surface] for surface in boundaries]
    sem = list(sem) if sem is not None else [None] * n
    if "value" in mat:
        mats = [mat["value"]] * n
    else:
        mats = list(mat.get("values") or [None] * n)
        if kind == "Solid" and mats and isinstance(mats[0], list):
            mats = [v for shell in mats for v in shell]
    texs = [[] if t is None else list(t) for t in tex] if tex is not None else [[]] * n
    return surfaces, sem, mats, texs
