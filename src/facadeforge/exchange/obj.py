"""Wavefront OBJ + MTL export and import.

Layout of an exported file
--------------------------
::

    mtllib house.mtl
    o house                               # one object per Model
    # facadeforge attributes {"height": 12.0}
    g Window                              # one group per Part, named after its symbol
    # facadeforge label=window shape=42   # the Part's label (and shape id)
    usemtl glass
    v ... / vt ...
    f 1/1 2/2 3/3 4/4                     # polygons stay polygons

The ``.mtl`` beside it has ``Kd``, ``d``/``Tr``, ``Pr``/``Pm`` (PBR extension) and ``map_Kd``;
texture files are copied into a ``textures/`` folder beside the ``.obj`` and referenced by
relative paths.  Whitespace in object, group and material names is replaced by ``_``.

:func:`load_obj` reads this back (labels from the comments, or guessed from group names with
:func:`~facadeforge.model.label_for_name` for files from other tools).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

from ..geometry.mesh import Mesh
from ..jsonfile import parse_json
from ..model.labels import label_for_name
from ..model.model import MAX_COORDINATE, Material, Model, Part
from ._ascii import format_lines
from ._common import (
    Staging,
    corner_uvs,
    face_corners,
    iter_models,
    joined_attributes,
    log,
    mesh_from_flat,
    safe_name,
    split_attributes,
)
from .errors import LoadError

__all__ = ["export_obj", "load_obj"]

_TAG = "# facadeforge"


# -- export -----------------------------------------------------------------------------------

def export_obj(models: Model | Sequence[Model], path: str | os.PathLike, *,
               texture_folder: str = "textures", precision: int = 6) -> list[Path]:
    """Write models as OBJ with an MTL material library and copied textures.

    Parameters
    ----------
    models : Model, sequence or iterable of Model
        Written as they come (a generator such as ``engine.derive_iter`` keeps memory to a
        few buildings).
        One ``o`` object per model, one ``g`` group per part.
    path : path-like
        Destination ``.obj``; the ``.mtl`` gets the same stem.  All files are written
        atomically and together: on failure none of them is created.
    texture_folder : str
        Folder beside the ``.obj`` that receives the texture files.
    precision : int
        Decimals of coordinates and texture coordinates.

    Returns
    -------
    list of Path
        The ``.obj``, the ``.mtl`` and every copied texture.
    """
    path = Path(path)
    mtl_path = path.with_suffix(".mtl")
    with Staging() as stage:
        library = _MaterialLibrary(path.parent, texture_folder, stage)
        with open(stage.path(path), "wb") as out:
            # model by model: a city never sits in memory whole
            _write_obj(out, iter_models(models), library, mtl_path.name, precision)
        stage.write_text(mtl_path, library.mtl_text())
    copied = [path.parent / rel for rel in library.textures.values() if rel is not None]
    return [path, mtl_path, *copied]


class _MaterialLibrary:
    """Unique MTL names for materials and relative names for their texture files."""

    def __init__(self, folder: Path, texture_folder: str, stage=None) -> None:
        self.folder = folder
        self.texture_folder = texture_folder
        # textures are copied as they are first met: a rule package's unpacked files last only
        # as long as the derivation that streams its models here (``derive`` of an .rpk)
        self.stage = stage
        self.names: dict[tuple, str] = {}
        self.materials: dict[str, Material] = {}
        self.textures: dict[str, str | None] = {}

    def name(self, mat: Material) -> str:
        key = mat.key()
        if key not in self.names:
            base = safe_name(mat.name, "material")
            name, n = base, 1
            while name in self.materials:
                n += 1
                name = f"{base}_{n}"
            self.names[key] = name
            self.materials[name] = mat
            if mat.texture:
                self._texture(mat.texture)
        return self.names[key]

    def _texture(self, source: str) -> None:
        if source in self.textures:
            return
        if not os.access(source, os.R_OK) or not Path(source).is_file():
            log.warning("texture %s skipped: not a readable file", source)
            self.textures[source] = None
            return
        stem, suffix = Path(source).stem, Path(source).suffix
        taken = set(self.textures.values())
        relative, n = f"{self.texture_folder}/{safe_name(stem, 'texture')}{suffix}", 1
        while relative in taken:
            n += 1
            relative = f"{self.texture_folder}/{safe_name(stem, 'texture')}_{n}{suffix}"
        self.textures[source] = relative
        if self.stage is not None:
            self.stage.copy(source, self.folder / relative)

    def mtl_text(self) -> str:
        lines = ["# facadeforge MTL export"]
        for name, mat in self.materials.items():
            r, g, b = (float(c) for c in mat.color)
            lines += [f"newmtl {name}", "Ka 0 0 0", f"Kd {r:.6g} {g:.6g} {b:.6g}", "Ks 0 0 0",
                      f"d {mat.opacity:.6g}", f"Tr {1.0 - mat.opacity:.6g}",
                      f"Pr {mat.roughness:.6g}", f"Pm {mat.metallic:.6g}", "illum 1"]
            relative = self.textures.get(mat.texture) if mat.texture else None
            if relative:
                lines.append(f"map_Kd {relative}")
            lines.append("")
        return "\n".join(lines) + "\n"


def _text(out: BinaryIO, line: str) -> None:
    out.write(line.encode("utf-8"))


def _write_obj(out: BinaryIO, models, library: _MaterialLibrary, mtl_name: str,
               precision: int) -> None:
    _text(out, f"{_TAG} OBJ export\nmtllib {mtl_name}\n")
    counters = [0, 0]  # vertices and texture vertices written so far
    for i, model in enumerate(models):
        _text(out, f"o {safe_name(model.name, f'model{i}')}\n")
        data, geo = split_attributes(model.attributes)
        if data:
            _text(out, f"{_TAG} attributes {json.dumps(data)}\n")
        if geo:
            _text(out, f"{_TAG} georeference {json.dumps(geo)}\n")
        for j, part in enumerate(model.parts):
            if part.mesh.n_faces:
                _write_part(out, part, library.name(part.material), j, counters, precision)


def _write_part(out: BinaryIO, part: Part, material: str, index: int, counters: list[int],
                precision: int) -> None:
    mesh = part.mesh
    corners, starts = face_corners(mesh)
    uv, has_uv = corner_uvs(mesh)
    _text(out, f"g {safe_name(part.symbol, f'part{index}')}\n")
    _text(out, f"{_TAG} label={safe_name(part.label, '-')} shape={int(part.shape_id)}\n")
    _text(out, f"usemtl {material}\n")
    # every number of the part at once (np.savetxt formatted row by row: 15 s a city)
    out.write(format_lines("v ", mesh.vertices, precision=precision))
    # faces of fewer than three corners are not written (an OBJ face needs three)
    sizes = np.diff(starts)
    kept = sizes >= 3
    take = np.repeat(kept, sizes)
    vidx = corners[take] + counters[0] + 1
    line_starts = np.concatenate([[0], np.cumsum(sizes[kept])])
    if has_uv:
        out.write(format_lines("vt ", uv, precision=precision))
        tidx = np.arange(counters[1] + 1, counters[1] + 1 + len(corners))[take]
        counters[1] += len(corners)
        tokens = np.stack([vidx, tidx], axis=1).reshape(-1)
        seps = np.tile(np.array([ord(" "), ord("/")], np.uint8), len(vidx))
        out.write(format_lines("f ", tokens, 2 * line_starts, seps))
    else:
        out.write(format_lines("f ", vidx, line_starts))
    counters[0] += len(mesh.vertices)


# -- import -----------------------------------------------------------------------------------

@dataclass
class _PartBuilder:
    symbol: str
    label: str
    material: str
    shape_id: int
    faces: list[list[int]] = field(default_factory=list)
    tex: list[list[int] | None] = field(default_factory=list)


@dataclass
class _ObjState:
    folder: Path
    verts: list[list[float]] = field(default_factory=list)
    tverts: list[list[float]] = field(default_factory=list)
    models: list[tuple[Model, list[_PartBuilder]]] = field(default_factory=list)
    materials: dict[str, Material] = field(default_factory=dict)
    group: str = ""
    label: str = ""
    shape_id: int = 0
    material: str = ""
    current: _PartBuilder | None = None


def load_obj(path: str | os.PathLike) -> list[Model]:
    """Read an OBJ file (and its MTL libraries) into models.

    Parameters
    ----------
    path : path-like
        The ``.obj`` file.

    Returns
    -------
    list of Model
        One model per ``o`` object (a single model named after the file when there is none),
        one part per run of faces sharing group, label and material.  Polygons are kept.

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist.
    LoadError
        When a line cannot be parsed (a vertex with fewer than three numbers, a number that is
        not finite or larger than :data:`~facadeforge.model.model.MAX_COORDINATE`, a face
        without vertices) or a face refers to a missing vertex.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    state = _ObjState(folder=path.parent)
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            try:
                _parse_line(state, line.strip(), path.stem)
            except (ValueError, IndexError) as exc:
                shown = line.strip() if len(line) <= 80 else line.strip()[:60] + "…"
                raise LoadError(f"{path}:{number}: cannot parse {shown!r} ({exc})") from exc
    return _finish(state, path)


def _parse_line(state: _ObjState, line: str, default_name: str) -> None:
    if not line:
        return
    if line.startswith(_TAG):
        _parse_tag(state, line[len(_TAG):].strip())
        return
    if line.startswith("#"):
        return
    key, _, rest = line.partition(" ")
    rest = rest.strip()
    if key == "v":
        state.verts.append(_numbers(rest.split()[:3], 3, MAX_COORDINATE))
    elif key == "vt":
        state.tverts.append(_numbers((rest.split() + ["0"])[:2], 2, MAX_COORDINATE))
    elif key == "f":
        _parse_face(state, rest.split(), default_name)
    elif key == "o":
        state.models.append((Model(name=rest or default_name), []))
        state.current, state.group, state.label = None, "", ""
    elif key == "g":
        state.current, state.group, state.label, state.shape_id = None, rest, "", 0
    elif key == "usemtl":
        state.current, state.material = None, rest
    elif key == "mtllib":
        for name in rest.split():
            state.materials.update(_read_mtl(state.folder / name))


def _numbers(tokens: list[str], n: int, limit: float) -> list[float]:
    """``n`` finite numbers of magnitude at most ``limit``; ``ValueError`` (which
    :func:`load_obj` reports with the file and line) otherwise: ``float`` reads ``nan`` and
    ``1e999`` without complaint, and such a vertex would reach every exporter and renderer."""
    if len(tokens) < n:
        raise ValueError(f"{n} numbers needed, got {len(tokens)}")
    values = [float(x) for x in tokens]
    for v in values:
        if not abs(v) <= limit:  # NaN compares false too
            raise ValueError(f"{v} is not a finite number of magnitude at most {limit:.0e}")
    return values


def _tag_object(text: str) -> dict:
    """The JSON object of an ``attributes``/``georeference`` tag line; ``ValueError`` (which
    :func:`load_obj` reports with the file and line) when the text is not one."""
    value = parse_json(text, "the tag", error=LoadError)  # a LoadError is a ValueError
    if not isinstance(value, dict):
        raise ValueError("the tag's JSON is not an object")
    return value


def _parse_tag(state: _ObjState, text: str) -> None:
    if text.startswith("attributes ") and state.models:
        state.models[-1][0].attributes.update(_tag_object(text[len("attributes "):]))
    elif text.startswith("georeference ") and state.models:
        state.models[-1][0].attributes.update(
            joined_attributes(None, _tag_object(text[len("georeference "):])))
    elif text.startswith("label="):
        fields = dict(item.split("=", 1) for item in text.split() if "=" in item)
        state.current = None
        state.label = "" if fields.get("label") == "-" else fields.get("label", "")
        state.shape_id = int(fields.get("shape", 0))


def _parse_face(state: _ObjState, tokens: list[str], default_name: str) -> None:
    if not state.models:
        state.models.append((Model(name=default_name), []))
    if state.current is None:
        label = state.label or (label_for_name(state.group) or "")
        state.current = _PartBuilder(state.group, str(label), state.material, state.shape_id)
        state.models[-1][1].append(state.current)
    if not tokens:
        raise ValueError("a face needs the numbers of its vertices")
    vi, ti = [], []
    for token in tokens:
        parts = token.split("/")
        vi.append(_resolve(int(parts[0]), len(state.verts)))
        ti.append(_resolve(int(parts[1]), len(state.tverts)) if len(parts) > 1 and parts[1] else -1)
    state.current.faces.append(vi)
    state.current.tex.append(None if min(ti) < 0 else ti)


def _resolve(index: int, count: int) -> int:
    """0-based index of a 1-based (or negative, relative) OBJ index."""
    i = index - 1 if index > 0 else count + index
    if not 0 <= i < count:
        raise IndexError(f"index {index} refers to none of the {count} defined above the line")
    return i


def _finish(state: _ObjState, path: Path) -> list[Model]:
    verts = np.asarray(state.verts, float).reshape(-1, 3)
    tverts = np.asarray(state.tverts, float).reshape(-1, 2)
    models = []
    for model, builders in state.models:
        for b in builders:
            material = state.materials.get(b.material) or Material(name=b.material or "default")
            model.parts.append(Part(_builder_mesh(b, verts, tverts), label=b.label,
                                    material=material, symbol=b.symbol, shape_id=b.shape_id))
        models.append(model)
    return models


def _builder_mesh(b: _PartBuilder, verts: np.ndarray, tverts: np.ndarray) -> Mesh:
    """Mesh of a part with only the vertices its faces use, renumbered."""
    lengths = np.fromiter((len(f) for f in b.faces), np.int64, len(b.faces))
    flat = np.fromiter((v for f in b.faces for v in f), np.int64, int(lengths.sum()))
    used, corners = np.unique(flat, return_inverse=True)
    starts = np.concatenate([[0], np.cumsum(lengths)])
    uvs = None
    if any(t is not None for t in b.tex):
        tex = np.concatenate([np.full(n, -1) if t is None else np.asarray(t, np.int64)
                              for t, n in zip(b.tex, lengths)])
        uvs = np.where((tex >= 0)[:, None], tverts[np.maximum(tex, 0)], 0.0)
    return mesh_from_flat(verts[used], corners.reshape(-1), starts, uvs)


def _read_mtl(path: Path) -> dict[str, Material]:
    """Materials of an MTL file (missing file: none, with a log message)."""
    from ..geometry.assets import read_mtl

    try:
        found = read_mtl(path)
    except OSError as exc:
        log.warning("material library %s not read: %s", path, exc)
        return {}
    keys = ("name", "color", "opacity", "metallic", "roughness")
    return {name: Material(**{k: m[k] for k in keys if k in m}, texture=m.get("colormap"))
            for name, m in found.items()}
