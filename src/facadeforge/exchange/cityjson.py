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

import hashlib
import itertools
import json
import os
import secrets
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..geometry.assets import inside
from ..geometry.holed import HOLED, face_groups, fresh_ids, plane_polygon, rings
from ..geometry.mesh import Mesh, column_bounds, plane_basis, polygon_normal, ranges_index
from ..jsonfile import JsonMembers, json_type, parse_json, read_json
from ..model.labels import Labels, label_for_name
from ..model.model import MAX_COORDINATE, Material, Model, Part
from ._ascii import format_lines
from ._common import (
    Staging,
    corner_uvs,
    face_corners,
    image_extension,
    iter_models,
    jsonable,
    previous_corner,
    read_texture,
    safe_name,
    scalar_attributes,
)
from .errors import ExportError, LoadError

__all__ = ["BY_CONTENT", "DEFAULT_SEMANTIC_MAP", "SEMANTIC_TYPES", "export_cityjson",
           "load_cityjson"]

#: ``textures=BY_CONTENT``: copied textures named by their bytes too (:func:`export_cityjson`).
BY_CONTENT = "by-content"

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
    # occluders as vegetation is, the street as the ground (the label survives in the
    # semantic object's facadeforge_label; None would drop it)
    Labels.CAR.value: "WallSurface",
    Labels.PERSON.value: "WallSurface",
    Labels.PAVEMENT.value: "GroundSurface",
    Labels.ROAD.value: "GroundSurface",
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
    textures : bool or "by-content"
        Copy readable textures and write texture coordinates.  ``"by-content"`` names each
        copied texture by its bytes too (``<stem>_<sha256 prefix>.<ext>``), so that files
        written one after another into one ``textures/`` folder (``batch``'s chunks) share the
        images they have in common and never overwrite another image of the same name.

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
                       metadata: dict | None = None, textures: bool | str = True
                       ) -> list[Path]:
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
        # each corner's uv by its position rounded to the µm (the first corner there wins),
        # rounded all at once: a city's frames and openings have hundreds of thousands
        at: dict = {}
        gc = ranges_index(starts[group], starts[np.asarray(group) + 1] - starts[group])
        for key, c in zip(map(tuple, np.round(mesh.vertices[corners[gc]], 6).tolist()), gc):
            at.setdefault(key, c)
        for outer, holes in rings(plane_polygon(mesh, group, p0, basis)):
            for k, ring in enumerate([outer, *holes]):
                pts = p0 + ring @ basis[:, :2].T
                found_at = [at.get(key) for key in map(tuple, np.round(pts, 6).tolist())]
                found = has_uv and all(c is not None for c in found_at)
                ring_uv = [uv[c] for c in found_at] if found else None
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
        the CityObjects first, each with the vertices no earlier building has (a vertex is
        written once, even on a party wall: cjval warns of duplicates), which wait in a
        temporary file; then the vertices, the transform, the metadata and the
        appearance.  The translation is the first building's lowest corner."""
        translate = None
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        taken: set[str] = set()
        count = 0
        shared = _VertexIndex()
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
                    ids = shared.ids(uniq, count)   # a vertex of an earlier building: its id
                    fresh = ids >= count
                    vids = ids[vids]
                    if fresh.any():
                        text = _json_rows(uniq[fresh]).text[1:-1]
                        vertices.write(("," if count else "") + text)
                        count += int(fresh.sum())
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
                stem = safe_name(Path(source).stem, 'texture')
                if self.with_textures == BY_CONTENT:
                    stem = f"{stem}_{hashlib.sha256(data).hexdigest()[:12]}"
                relative = f"textures/{stem}{ext}"
                n = 1
                while relative in self.texture_files and self.texture_files[relative] != data:
                    n += 1
                    relative = f"textures/{stem}_{n}{ext}"
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


class _VertexIndex:
    """The integer vertices written so far and their ids, so that buildings sharing a corner
    share the vertex.  Sorted runs of 24-byte keys (the three int64, compared bytewise) merged
    as a binary counter does (a log-structured merge): a lookup is a binary search per run,
    and the index costs 32 bytes a vertex, not a Python dict's hundred or more."""

    def __init__(self) -> None:
        self.runs: list[tuple[np.ndarray, np.ndarray]] = []

    @staticmethod
    def _keys(ints: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(ints, dtype=">i8").view("S24").reshape(-1)

    def ids(self, uniq: np.ndarray, next_id: int) -> np.ndarray:
        """Each of the distinct rows ``uniq``'s id: an earlier one's, else a new one counted
        from ``next_id`` in row order (and remembered)."""
        keys = self._keys(uniq)
        ids = np.full(len(keys), -1, np.int64)
        for run_keys, run_ids in self.runs:
            at = np.searchsorted(run_keys, keys).clip(max=len(run_keys) - 1)
            hit = (run_keys[at] == keys) & (ids < 0)
            ids[hit] = run_ids[at[hit]]
        fresh = ids < 0
        ids[fresh] = next_id + np.arange(int(fresh.sum()))
        if fresh.any():
            self._add(keys[fresh], ids[fresh])
        return ids

    def _add(self, keys: np.ndarray, ids: np.ndarray) -> None:
        order = np.argsort(keys, kind="stable")
        run = (keys[order], ids[order])
        while self.runs and len(self.runs[-1][0]) <= len(run[0]):
            k, i = self.runs.pop()
            k, i = np.concatenate([k, run[0]]), np.concatenate([i, run[1]])
            order = np.argsort(k, kind="stable")
            run = (k[order], i[order])
        self.runs.append(run)


def unique_rows(ints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(ints, axis=0, return_inverse=True)`` for (N, 3) integers, through one
    integer key per row where the span allows (faster than the row-wise sort); the same rows
    in the same (lexicographic) order."""
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

_FIX = "fix the file (CityJSON 2.0)"

#: Geometry types read as surfaces (others, such as ``MultiPoint`` or ``GeometryInstance``,
#: are skipped).
_SURFACE_TYPES = ("MultiSurface", "CompositeSurface", "Solid")


def load_cityjson(path: str | os.PathLike) -> list[Model]:
    """Read the surface geometry of a CityJSON file back into models.

    One model per City Object with surface geometry (``MultiSurface``, ``CompositeSurface`` or
    ``Solid``; of several geometries the one with the highest LoD), converted back to CGA axes.
    Labels come from the ``facadeforge_label`` attribute of the semantic surfaces, or from
    their type; materials and textures from the first theme.

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist.
    LoadError
        When the file is not CityJSON, or a member it reads has the wrong type or refers to
        something the file does not hold (a vertex, material, texture or semantic surface): the
        message names its JSON path, e.g. ``CityObjects["b1"].geometry[0].boundaries[3][0][2]``;
        also vertices that are not finite or lie beyond
        :data:`~facadeforge.model.model.MAX_COORDINATE` once transformed.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    doc = read_json(path, "CityJSON file", fix="write it again", error=LoadError)
    check = _Check(f"CityJSON file '{path}'")
    if not isinstance(doc, dict) or doc.get("type") != "CityJSON":
        raise LoadError(f"{path} is not a CityJSON file (no top-level object with \"type\": "
                        "\"CityJSON\")")
    return _CityJsonReader(doc, path.parent, check, check.transform(doc)).models(doc)


def load_cityjsonseq(path: str | os.PathLike) -> list[Model]:
    """Read CityJSON Text Sequences (``.city.jsonl``): the first line's transform, then each
    ``CityJSONFeature`` with its vertices and appearance, as :func:`load_cityjson` reads a
    file (and with its errors, naming the line)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    models: list[Model] = []
    transform = None
    try:
        with open(path, encoding="utf-8-sig") as fh:
            for number, line in enumerate(fh, 1):
                if not line.strip():
                    continue
                source = f"CityJSON sequence '{path}':{number}"
                doc = parse_json(line, source, fix="write it again", error=LoadError)
                check = _Check(source)
                if transform is None:
                    if not isinstance(doc, dict) or doc.get("type") != "CityJSON":
                        raise LoadError(f"{path}: the first line is not a CityJSON object")
                    transform = check.transform(doc)
                    continue
                if not isinstance(doc, dict) or doc.get("type") != "CityJSONFeature":
                    raise LoadError(f"{path}:{number}: not a CityJSONFeature")
                models.extend(_CityJsonReader(doc, path.parent, check, transform).models(doc))
    except UnicodeDecodeError as exc:
        raise LoadError(f"CityJSON sequence '{path}' is not UTF-8 text (byte {exc.start}); "
                        "write it again") from None
    if transform is None:
        raise LoadError(f"{path} is empty")
    return models


def _quoted(key: str) -> str:
    """A City Object id as it appears in a JSON path (``["b1"]``), long ids shortened."""
    return "[" + json.dumps(key if len(key) <= 40 else key[:36] + "…") + "]"


class _Check(JsonMembers):
    """Typed reads from a parsed CityJSON document: every member the reader uses is checked
    for its type (and indices for their range) before numpy or shapely see it, and a wrong one
    is a :class:`LoadError` naming the file (``source``) and the member's JSON path, as
    :class:`~facadeforge.geometry.footprints._GeoJson` does for footprints."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, where: str, problem: str) -> LoadError:
        at = f" {where}" if where else ""
        return LoadError(f"{self.source}:{at} {problem}; {_FIX}")

    def number(self, v, where: str, lo: float = -np.inf, hi: float = np.inf) -> float:
        """``v`` as a float when it is a finite number within ``[lo, hi]``."""
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.error(where, f"must be a number, not {json_type(v)}")
        try:
            f = float(v)
        except OverflowError:  # an integer of hundreds of digits
            f = np.inf
        if not (np.isfinite(f) and lo <= f <= hi):
            shown = repr(v) if len(repr(v)) <= 24 else repr(v)[:12] + "…"
            within = "" if np.isinf(lo) else f" within [{lo:g}, {hi:g}]"
            raise self.error(where, f"is {shown}, not a finite number{within}")
        return f

    def numbers(self, v, where: str, n: int, lo: float = -np.inf,
                hi: float = np.inf) -> np.ndarray:
        """An array of exactly ``n`` finite numbers."""
        self.array(v, where)
        if len(v) != n:
            raise self.error(where, f"must hold {n} numbers, not {len(v)}")
        return np.array([self.number(x, f"{where}[{j}]", lo, hi) for j, x in enumerate(v)])

    def rows(self, v, where: str, width: int, limit: float = np.inf) -> np.ndarray:
        """An array of arrays of ``width`` finite numbers (vertices, texture vertices) as an
        (N, width) float array."""
        if v is None:
            return np.zeros((0, width))
        self.array(v, where)
        if not v:
            return np.zeros((0, width))
        try:  # one conversion for the honest case, checked as a whole
            a = np.array(v)
        except (ValueError, OverflowError):
            a = None
        if (a is not None and a.ndim == 2 and a.shape[1] == width and a.dtype.kind in "iuf"
                and not any(type(x) is bool for row in v for x in row)):
            a = a.astype(float)
            if np.isfinite(a).all() and (np.abs(a) <= limit).all():
                return a
        # something is wrong: row by row, for the message
        for i, row in enumerate(v):
            self.numbers(row, f"{where}[{i}]", width, -limit, limit)
        return np.array(v, float)  # pragma: no cover - the loop above found every problem

    def indices(self, v, where: str, count: int, what: str, at_least: int = 0) -> np.ndarray:
        """An array of at least ``at_least`` integers in ``[0, count)`` (``what``: what they
        index, for the message)."""
        self.array(v, where)
        if len(v) < at_least:
            raise self.error(where, f"must hold at least {at_least} indices, not {len(v)}")
        if all(type(x) is int for x in v) and (not v or (min(v) >= 0 and max(v) < count)):
            return np.array(v, np.int64)
        for j, x in enumerate(v):
            self.index(x, f"{where}[{j}]", count, what, null=False)
        raise AssertionError("unreachable")  # pragma: no cover

    def index(self, v, where: str, count: int, what: str, null: bool = True) -> int | None:
        """An integer in ``[0, count)`` (or null when ``null``)."""
        if v is None and null:
            return None
        if type(v) is not int:
            kind = "an integer or null" if null else "an integer"
            raise self.error(where, f"must be {kind}, not {json_type(v)}")
        if not 0 <= v < count:
            shown = str(v) if len(str(v)) <= 24 else str(v)[:12] + "…"
            raise self.error(where, f"is {shown}, but the file has {count} {what}")
        return v

    def transform(self, doc: dict) -> tuple[np.ndarray, np.ndarray]:
        """``(scale, translate)`` of the document's ``transform`` (none: identity)."""
        tr = self.member(doc, "transform", "", dict, "an object")
        if tr is None:
            return np.ones(3), np.zeros(3)
        scale = self.numbers(tr.get("scale"), "transform.scale", 3)
        if not scale.all():
            raise self.error("transform.scale", "must not hold 0")
        return scale, self.numbers(tr.get("translate"), "transform.translate", 3)

    def lod(self, geom: dict, where: str) -> float:
        """A geometry's level of detail (a string such as ``"2.2"`` or a number) as a float."""
        lod = geom.get("lod", "0")
        if isinstance(lod, str):
            try:
                value = float(lod)
            except ValueError:
                value = np.nan
        elif isinstance(lod, (int, float)) and not isinstance(lod, bool):
            return self.number(lod, f"{where}.lod")
        else:
            raise self.error(f"{where}.lod", f"must be a string such as \"2.2\", not "
                             f"{json_type(lod)}")
        if not np.isfinite(value):
            raise self.error(f"{where}.lod", f"is {lod!r}, not a level of detail such as \"2.2\"")
        return value


class _CityJsonReader:
    """Models from one CityJSON document (or one CityJSONFeature of a sequence): its vertices,
    appearance and City Objects, every member checked as it is read (:class:`_Check`)."""

    def __init__(self, doc: dict, folder: Path, check: _Check,
                 transform: tuple[np.ndarray, np.ndarray]) -> None:
        self.check = c = check
        scale, translate = transform
        with np.errstate(over="ignore", invalid="ignore"):  # checked just below
            real = c.rows(doc.get("vertices"), "vertices", 3) * scale + translate
        far = ~(np.abs(real) <= MAX_COORDINATE).all(axis=1)
        if far.any():
            i = int(np.argmax(far))
            raise c.error(f"vertices[{i}]", f"lies at {real[i].tolist()} once transformed: not "
                          f"finite or beyond ±{MAX_COORDINATE:.0e}")
        self.vertices = real @ _TO_CJ  # inverse rotation: CityJSON → CGA
        app = c.member(doc, "appearance", "", dict, "an object") or {}
        w = "appearance.materials"
        self.materials = [self._material_entry(m, f"{w}[{i}]")
                          for i, m in enumerate(c.member(app, "materials", "appearance", list,
                                                         "an array") or [])]
        w = "appearance.textures"
        self.textures = [c.member(c.obj(t, f"{w}[{i}]"), "image", f"{w}[{i}]", str, "a string")
                         for i, t in enumerate(c.member(app, "textures", "appearance", list,
                                                        "an array") or [])]
        self.uvs = c.rows(app.get("vertices-texture"), "appearance.vertices-texture", 2,
                          MAX_COORDINATE)
        self.folder = folder

    def _material_entry(self, m, where: str) -> tuple[str | None, tuple, float]:
        """``(name, diffuse colour, transparency)`` of an ``appearance.materials`` entry."""
        c = self.check
        c.obj(m, where)
        name = c.member(m, "name", where, str, "a string")
        color = m.get("diffuseColor")
        color = (1.0, 1.0, 1.0) if color is None else tuple(
            c.numbers(color, f"{where}.diffuseColor", 3, 0.0, 1.0).tolist())
        transparency = m.get("transparency")
        transparency = 0.0 if transparency is None else c.number(
            transparency, f"{where}.transparency", 0.0, 1.0)
        return name, color, transparency

    def models(self, doc: dict) -> list[Model]:
        objects = self.check.member(doc, "CityObjects", "", dict, "an object") or {}
        return [m for oid, obj in objects.items() if (m := self.model(oid, obj)) is not None]

    def model(self, oid: str, obj) -> Model | None:
        c = self.check
        where = f"CityObjects{_quoted(oid)}"
        c.obj(obj, where)
        geoms = []
        for i, g in enumerate(c.member(obj, "geometry", where, list, "an array") or []):
            gw = f"{where}.geometry[{i}]"
            c.obj(g, gw)
            if c.member(g, "type", gw, str, "a string") in _SURFACE_TYPES:
                geoms.append((c.lod(g, gw), g, gw))
        attributes = c.member(obj, "attributes", where, dict, "an object")
        if not geoms:
            return None
        _, geom, gw = max(geoms, key=lambda t: t[0])  # the first of the highest LoD
        model = Model(name=oid, attributes=dict(attributes or {}))
        surfaces, sem, mats, texs, table = self._flatten(geom, gw)
        runs: dict[tuple, list[int]] = {}
        for i, key in enumerate(self._face_keys(table, sem, mats, texs)):
            runs.setdefault(key, []).append(i)
        for (label, symbol, mat_index, tex_index), idx in runs.items():
            meshes = [self._surface_mesh(surfaces[i], texs[i]) for i in idx]
            model.parts.append(Part(Mesh.merge(meshes), label=label,
                                    material=self._material(mat_index, tex_index),
                                    symbol=symbol))
        return model

    def _flatten(self, geom: dict, where: str) -> tuple[list, list, list, list, list]:
        """Checked rings (outer first), semantic values, material values and texture refs (one
        entry per surface, a Solid's shells flattened), and the semantic surfaces table."""
        c = self.check
        bw = f"{where}.boundaries"
        boundaries = c.member(geom, "boundaries", where, list, "an array") or []
        if geom["type"] == "Solid":
            shells = [len(c.array(shell, f"{bw}[{s}]")) for s, shell in enumerate(boundaries)]
            raw = [(surface, f"{bw}[{s}][{k}]") for s, shell in enumerate(boundaries)
                   for k, surface in enumerate(shell)]
        else:
            shells, raw = None, [(surface, f"{bw}[{k}]") for k, surface in enumerate(boundaries)]
        surfaces = [self._surface(s, w) for s, w in raw]
        n = len(surfaces)

        sw = f"{where}.semantics"
        semantics = c.member(geom, "semantics", where, dict, "an object") or {}
        table = [self._semantic_surface(s, f"{sw}.surfaces[{i}]") for i, s in
                 enumerate(c.member(semantics, "surfaces", sw, list, "an array") or [])]
        sem = self._values(semantics.get("values"), f"{sw}.values", shells, n,
                           lambda v, w, k: c.index(v, w, len(table), "semantic surfaces"))

        def material_index(v, w, k):
            return c.index(v, w, len(self.materials), "materials")
        mats: list = [None] * n
        themes = c.member(geom, "material", where, dict, "an object") or {}
        if themes:  # the first theme
            theme, mat = next(iter(themes.items()))
            mw = f"{where}.material{_quoted(theme)}"
            c.obj(mat, mw)
            if "value" in mat:
                mats = [material_index(mat["value"], f"{mw}.value", 0)] * n
            else:
                mats = self._values(mat.get("values"), f"{mw}.values", shells, n, material_index)
        texs: list = [[]] * n
        themes = c.member(geom, "texture", where, dict, "an object") or {}
        if themes:
            theme, tex = next(iter(themes.items()))
            tw = f"{where}.texture{_quoted(theme)}"
            c.obj(tex, tw)
            texs = self._values(tex.get("values"), f"{tw}.values", shells, n,
                                lambda v, w, k: self._texture_refs(v, w, surfaces[k]))
        return surfaces, sem, mats, texs, table

    def _surface(self, surface, where: str) -> list[np.ndarray]:
        """A surface: an array of rings (outer first), each of at least 3 vertex indices."""
        self.check.array(surface, where)
        if not surface:
            raise self.check.error(where, "a surface needs at least one ring")
        return [self.check.indices(ring, f"{where}[{r}]", len(self.vertices), "vertices", 3)
                for r, ring in enumerate(surface)]

    def _semantic_surface(self, s, where: str) -> dict:
        c = self.check
        c.obj(s, where)
        return {key: c.member(s, key, where, str, "a string")
                for key in ("type", "facadeforge_label", "facadeforge_symbol")}

    def _values(self, values, where: str, shells: list[int] | None, n: int, item) -> list:
        """One checked value per surface (``item(value, where, surface index)``) from a
        geometry's ``values`` array, nested per shell for a Solid (a null shell: null values);
        null for every surface when there is none."""
        c = self.check
        if values is None:
            return [item(None, "", k) for k in range(n)]
        c.array(values, where)
        if shells is None:
            if len(values) != n:
                raise c.error(where, f"has {len(values)} values for {n} surfaces")
            return [item(v, f"{where}[{k}]", k) for k, v in enumerate(values)]
        if len(values) != len(shells):
            raise c.error(where, f"has {len(values)} shells of values for {len(shells)} shells")
        out: list = []
        for s, (shell, size) in enumerate(zip(values, shells)):
            if shell is None:
                out += [item(None, "", len(out) + j) for j in range(size)]
                continue
            c.array(shell, f"{where}[{s}]")
            if len(shell) != size:
                raise c.error(f"{where}[{s}]", f"has {len(shell)} values for {size} surfaces")
            out += [item(v, f"{where}[{s}][{j}]", len(out) + j) for j, v in enumerate(shell)]
        return out

    def _texture_refs(self, refs, where: str, rings: list[np.ndarray]) -> list:
        """A surface's texture references, one ``[texture, uv…]`` per ring (``[null]``: none),
        as ``(texture, uv indices)`` or None per ring."""
        c = self.check
        if refs is None:
            return []
        c.array(refs, where)
        if len(refs) > len(rings):
            raise c.error(where, f"has {len(refs)} ring references for a surface of "
                          f"{len(rings)} rings")
        out = []
        for r, ref in enumerate(refs):
            rw = f"{where}[{r}]"
            c.array(ref, rw)
            if not ref or ref[0] is None:
                out.append(None)
                continue
            texture = c.index(ref[0], f"{rw}[0]", len(self.textures), "textures", null=False)
            if len(ref) - 1 != len(rings[r]):
                raise c.error(rw, f"has {len(ref) - 1} texture vertices for a ring of "
                              f"{len(rings[r])} vertices")
            for j, u in enumerate(ref[1:], 1):
                if type(u) is not int or not 0 <= u < len(self.uvs):
                    c.index(u, f"{rw}[{j}]", len(self.uvs), "texture vertices", null=False)
            out.append((texture, np.array(ref[1:], np.int64)))
        return out

    def _surface_mesh(self, pts_ids: list, refs: list) -> Mesh:
        """One surface: a polygon, or, with holes, the pieces of one face with holes."""
        pts = [self.vertices[r] for r in pts_ids]
        uvs = [self._face_uv(refs[k] if k < len(refs) else None) for k in range(len(pts))]
        if len(pts) == 1:
            return Mesh.from_polygons(pts, uvs)
        n = polygon_normal(pts[0])
        if not n.any():  # an outline without area has no plane to cut its holes in
            return Mesh.from_polygons(pts[:1], uvs[:1])
        import shapely

        from ..geometry.polygon import simple_pieces

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
    def _face_keys(table: list, sem: list, mats: list, texs: list) -> list[tuple]:
        keys = []
        for s, m, t in zip(sem, mats, texs):
            surface = table[s] if s is not None else {}
            label = surface.get("facadeforge_label")
            if label is None:
                guess = label_for_name(str(surface.get("type") or "").replace("Surface", ""))
                label = guess.value if guess else ""
            tex = t[0][0] if t and t[0] is not None else None
            keys.append((label, surface.get("facadeforge_symbol") or "", m, tex))
        return keys

    def _material(self, index: int | None, texture: int | None) -> Material:
        path = None
        if texture is not None and self.textures[texture]:
            # a texture is read only from the file's folder or below (SECURITY.md), like a
            # glTF's images: a downloaded model must not show the pictures of the reader's disk
            candidate = (self.folder / self.textures[texture]).resolve()
            path = (str(candidate) if inside(self.folder.resolve(), candidate)
                    and candidate.is_file() else None)
        if index is None:
            return Material(texture=path)
        name, color, transparency = self.materials[index]
        return Material(name=name or f"material{index}", color=color,
                        opacity=1.0 - transparency, texture=path)

    def _face_uv(self, ref: tuple | None) -> np.ndarray | None:
        return None if ref is None else self.uvs[ref[1]]
