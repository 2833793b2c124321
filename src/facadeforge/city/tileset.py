"""3D Tiles 1.1 tilesets: one glTF (``.glb``) tile per chunk of a city, under a tree of
bounding boxes.

Axes
    facadeforge's models are y-up (CGA, glTF).  3D Tiles is z-up and turns glTF content y-up →
    z-up on loading (a rotation of +90° about x: glTF ``(x, y, z)`` → tiles ``(x, −z, y)``), so
    the boxes here are in tiles axes: x east, y north, z up, metres.
Tree
    The content tiles are grouped, in the order given (a batch gives them in space-filling-curve
    order, so neighbours share a parent), by at most :data:`FANOUT` under parent tiles up to one
    root.  A leaf's ``geometricError`` is 0 (its glTF is all there is).  When the tiles say
    where their buildings are (``ContentTile.buildings``), every parent holds a coarse level
    of detail (hierarchical LoD, ``coarse_NNNNN.glb``, ``refine: REPLACE``: the children take
    its place when a viewer comes close): a parent of content tiles shows every building
    beneath it as its bounding block (LoD1), with ``geometricError`` :data:`COARSE_ERROR`
    (the details the blocks leave out); a higher parent shows the :data:`MAX_BLOCKS` largest
    blocks beneath it, with the diagonal of the largest one it leaves out as its error (at
    least its children's).  So a city seen from afar shows its large buildings, then more of
    them, then every block, then the detailed tiles.  Without the buildings' bounds, parents
    have no content, ``refine: ADD`` and the diagonal of their box as their error, so a viewer
    opens them once they cover enough of the screen.
Georeference
    ``transform`` (column-major 4×4) on the root places the local frame on the globe (ECEF,
    EPSG:4978), see :func:`enu_transform`; without it the tileset is in local coordinates.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["COARSE_ERROR", "FANOUT", "MAX_BLOCKS", "ContentTile", "box_volume", "enu_transform",
           "tileset_dict", "tileset_problems", "write_tileset"]

#: Children a parent tile has at most.
FANOUT = 8
#: Geometric error (m) of a parent's LoD1 blocks against the detailed buildings they stand for:
#: roofs, cornices, balconies and recesses of a few metres.
COARSE_ERROR = 8.0
#: Blocks a parent above the first level of parents shows at most: the largest buildings of
#: those beneath it (a tile's content stays small however large the city).
MAX_BLOCKS = 1024

# CGA / glTF (x, y up, z) → 3D Tiles (x, -z, y)
_TO_TILES = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


@dataclass
class ContentTile:
    """A tile with glTF content.

    Parameters
    ----------
    uri : str
        Content URI relative to ``tileset.json`` (``"00003.glb"``).
    lo, hi : (3,) float
        Bounds of the content in glTF axes (y up), metres.
    offset : (3,) float
        Where the content's origin lies in the root's frame, tiles axes (footprint files with
        different origins); zero for one origin.
    """

    uri: str
    lo: Sequence[float]
    hi: Sequence[float]
    offset: Sequence[float] = field(default_factory=lambda: (0.0, 0.0, 0.0))
    #: (N, 2, 3) bounds of each building of the content, glTF axes, the content's frame; with
    #: them the tile's parent shows the buildings as blocks from afar (module docstring)
    buildings: Sequence | None = None


def _tiles_bounds(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """glTF-axes bounds → tiles-axes bounds."""
    corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1])
                        for c in (lo[2], hi[2])], float) @ _TO_TILES.T
    return corners.min(axis=0), corners.max(axis=0)


def box_volume(lo, hi, pad: float = 0.0) -> list[float]:
    """An axis-aligned ``boundingVolume.box`` (12 numbers: centre, then the x, y and z half-axes)
    of tiles-axes bounds ``lo``..``hi``, each side grown by ``pad`` (and kept above zero: a
    flat tile still has a box)."""
    lo, hi = np.asarray(lo, float) - pad, np.asarray(hi, float) + pad
    c, h = (lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-3)
    c, h = np.round(c, 6), np.round(h + 1e-6, 6)   # short numbers, still around the content
    return [*map(float, c), float(h[0]), 0.0, 0.0, 0.0, float(h[1]), 0.0, 0.0, 0.0, float(h[2])]


def tileset_dict(tiles: Sequence[ContentTile], *, transform: Sequence[float] | None = None,
                 generator: str = "facadeforge") -> dict:
    """The ``tileset.json`` object of ``tiles`` (module docstring).

    Raises
    ------
    ValueError
        No tiles, or bounds that are not finite.
    """
    return _tree(tiles, transform, generator)[0]


def _tree(tiles, transform, generator) -> tuple[dict, list[tuple[str, np.ndarray]]]:
    """The tileset object and the coarse contents it names: ``(uri, blocks)`` with ``blocks``
    (N, 2, 3) building bounds in glTF axes of the root's frame."""
    if not tiles:
        raise ValueError("a tileset needs at least one tile with content")
    level = []
    for t in tiles:
        off = np.asarray(t.offset, float)
        if not (np.isfinite(np.asarray(t.lo, float)).all()
                and np.isfinite(np.asarray(t.hi, float)).all() and np.isfinite(off).all()):
            raise ValueError(f"tile {t.uri}: bounds are not finite")
        lo, hi = _tiles_bounds(t.lo, t.hi)
        node = {"boundingVolume": {"box": box_volume(lo, hi)}, "geometricError": 0.0,
                "refine": "ADD", "content": {"uri": t.uri}}
        if off.any():
            # a tile's box is in its own frame, which its transform moves into the parent's
            node["transform"] = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, *map(float, off), 1.0]
        level.append((node, lo + off, hi + off))
    coarse: list[tuple[str, np.ndarray]] = []
    # (node, lo, hi, diagonal, the blocks of every building beneath or None, error)
    level = [(n, lo, hi, 0.0, b, 0.0) for (n, lo, hi), b in
             zip(level, (_blocks([t]) for t in tiles))]
    first = True  # the level above the content tiles (even a single one needs a parent)
    while len(level) > 1 or first:
        parents = []
        for k in range(0, len(level), FANOUT):
            group = level[k:k + FANOUT]
            lo = np.min([g[1] for g in group], axis=0)
            hi = np.max([g[2] for g in group], axis=0)
            diagonal = _diagonal(lo, hi)
            node = {"boundingVolume": {"box": box_volume(lo, hi, pad=0.01)},
                    "geometricError": diagonal, "refine": "ADD",
                    "children": [g[0] for g in group]}
            below = [g[4] for g in group]
            blocks = None if any(b is None for b in below) else np.concatenate(below)
            error = diagonal
            if blocks is not None and len(blocks):
                shown, left_out = _coarse(blocks, first)
                uri = f"coarse_{len(coarse):05d}.glb"
                coarse.append((uri, shown))
                # what the blocks leave out: the buildings' details, the blocks not shown, and
                # whatever the children's contents leave out
                error = min(max(COARSE_ERROR, left_out, *(g[5] for g in group)), diagonal)
                node.update(content={"uri": uri}, refine="REPLACE", geometricError=error)
            parents.append((node, lo - 0.01, hi + 0.01, diagonal, blocks, error))
        level = parents
        first = False
    root = level[0][0]
    if transform is not None:
        root["transform"] = [float(v) for v in transform]
    # the error of showing nothing: the city's diagonal (above the root's blocks, if it has any)
    doc = {"asset": {"version": "1.1", "generator": generator},
           "geometricError": level[0][3], "root": root}
    return doc, coarse


def _blocks(tiles: Sequence[ContentTile]) -> np.ndarray | None:
    """The buildings of ``tiles`` as (N, 2, 3) glTF-axes bounds in their parent's frame (each
    tile's offset, tiles axes ``(x, -z, y)`` of glTF, applied); ``None`` when a tile does not
    say where its buildings are."""
    out = []
    for t in tiles:
        if t.buildings is None:
            return None
        b = np.asarray(t.buildings, float).reshape(-1, 2, 3)
        off = np.asarray(t.offset, float)
        out.append(b + np.array([off[0], off[2], -off[1]]))
    blocks = np.concatenate(out) if out else np.zeros((0, 2, 3))
    return blocks[np.isfinite(blocks).all(axis=(1, 2)) & (blocks[:, 1] > blocks[:, 0]).all(1)]


def _coarse(blocks: np.ndarray, every: bool) -> tuple[np.ndarray, float]:
    """The blocks a parent shows: all of them above the content tiles (``every``), else at
    most :data:`MAX_BLOCKS`, the largest (by diagonal); and the diagonal of the largest block
    left out (0 when none is)."""
    if every or len(blocks) <= MAX_BLOCKS:
        return blocks, 0.0
    size = np.linalg.norm(blocks[:, 1] - blocks[:, 0], axis=1)
    order = np.argsort(-size, kind="stable")
    keep = np.sort(order[:MAX_BLOCKS])
    return blocks[keep], round(float(size[order[MAX_BLOCKS]]), 3)


def _diagonal(lo, hi) -> float:
    return round(float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))), 3)


def write_tileset(path: str | os.PathLike, tiles: Sequence[ContentTile], *,
                  transform: Sequence[float] | None = None) -> Path:
    """Write ``tileset.json`` atomically (a temporary file beside it, then a rename), after
    the coarse blocks of its parents (``coarse_NNNNN.glb``, each written the same way); the
    content files are the caller's and must lie beside it under their URIs."""
    path = Path(path)
    doc, coarse = _tree(tiles, transform, "facadeforge")
    for uri, blocks in coarse:
        _write_blocks(path.parent / uri, blocks)
    text = json.dumps(doc, indent=1) + "\n"
    tmp = path.with_name(f".{path.name}.{os.getpid()}.part")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path


def _write_blocks(path: Path, blocks: np.ndarray) -> None:
    """A GLB of one block per building (the unit cube stretched over its bounds, glTF axes),
    written atomically."""
    from ..exchange import export_glb
    from ..geometry.mesh import Mesh
    from ..geometry.primitives import unit_cube
    from ..model.model import Material, Model, Part

    cube = unit_cube()
    lo, ext = blocks[:, 0], blocks[:, 1] - blocks[:, 0]
    mesh = Mesh.merge(cube.with_vertices(cube.vertices * e + o) for o, e in zip(lo, ext))
    model = Model(parts=[Part(mesh.with_uvs(None), label="building",
                              material=Material(name="block", color=(0.78, 0.76, 0.72)),
                              symbol="Block")], name=path.stem)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.part")
    export_glb([model], tmp)
    os.replace(tmp, path)


def enu_transform(easting: float, northing: float, height: float, epsg: int) -> list[float]:
    """The column-major 4×4 that places a local east-north-up frame whose origin is at
    (``easting``, ``northing``, ``height``) in EPSG:``epsg`` on the globe (ECEF, EPSG:4978), for
    a tileset root's ``transform``.  The local frame is taken as the CRS's own grid axes, which
    differ from true east-north by the grid convergence (under a degree or two in UTM).

    Raises
    ------
    ValueError
        pyproj cannot transform from that CRS.
    """
    from pyproj import Transformer

    try:
        lon, lat, h = Transformer.from_crs(f"EPSG:{epsg}", "EPSG:4979", always_xy=True
                                           ).transform(easting, northing, height)
        x, y, z = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True
                                       ).transform(lon, lat, h)
    except Exception as exc:  # pyproj raises its own types
        raise ValueError(f"cannot place EPSG:{epsg} on the globe: {exc}") from exc
    if not all(math.isfinite(v) for v in (lon, lat, x, y, z)):
        raise ValueError(f"cannot place EPSG:{epsg} coordinates {easting}, {northing} on the "
                         "globe")
    lo, la = math.radians(lon), math.radians(lat)
    east = [-math.sin(lo), math.cos(lo), 0.0]
    north = [-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)]
    up = [math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)]
    return [*east, 0.0, *north, 0.0, *up, 0.0, x, y, z, 1.0]


# -- checks -----------------------------------------------------------------------------------

def tileset_problems(path: str | os.PathLike) -> list[str]:
    """What is wrong with a tileset by the 3D Tiles 1.1 rules that can be checked without a
    viewer (an empty list when nothing is): ``asset.version``; every tile's ``boundingVolume``
    (a box of 12 finite numbers), ``geometricError`` (≥ 0, not above its parent's), ``refine``;
    content URIs that are relative and name existing files beside the tileset; and each
    child's box inside its parent's (both in the parent's frame, child ``transform``
    translations applied)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return [f"{path}: unreadable: {exc}"]
    problems = []
    if not isinstance(doc, dict) or doc.get("asset", {}).get("version") not in ("1.0", "1.1"):
        problems.append("asset.version must be '1.0' or '1.1'")
    if not isinstance(doc.get("geometricError"), int | float) or doc["geometricError"] < 0:
        problems.append("geometricError must be a number ≥ 0")
    root = doc.get("root") if isinstance(doc, dict) else None
    if not isinstance(root, dict):
        return problems + ["root tile missing"]
    if "refine" not in root:
        problems.append("root: refine must be given on the root")
    base = path.parent.resolve()

    def walk(tile, where, parent_box, parent_error):
        box = tile.get("boundingVolume", {}).get("box")
        if not (isinstance(box, list) and len(box) == 12
                and all(isinstance(v, int | float) and math.isfinite(v) for v in box)):
            problems.append(f"{where}: boundingVolume.box must be 12 finite numbers")
            return
        err = tile.get("geometricError")
        if not isinstance(err, int | float) or err < 0:
            problems.append(f"{where}: geometricError must be a number ≥ 0")
        elif parent_error is not None and err > parent_error:
            problems.append(f"{where}: geometricError {err} above its parent's {parent_error}")
        if tile.get("refine", "ADD") not in ("ADD", "REPLACE"):
            problems.append(f"{where}: refine must be ADD or REPLACE")
        lo, hi = _box_bounds(box)
        t = tile.get("transform")
        if t is not None:
            lo, hi = lo + np.asarray(t[12:15], float), hi + np.asarray(t[12:15], float)
        if parent_box is not None:
            plo, phi = parent_box
            if (lo < plo - 1e-6).any() or (hi > phi + 1e-6).any():
                problems.append(f"{where}: bounding volume not inside its parent's")
        content = tile.get("content")
        if content is not None:
            uri = content.get("uri") if isinstance(content, dict) else None
            if not isinstance(uri, str) or "://" in uri or uri.startswith("/"):
                problems.append(f"{where}: content.uri must be a relative URI")
            elif not (base / uri).resolve().is_file():
                problems.append(f"{where}: content {uri} does not exist")
        for k, child in enumerate(tile.get("children", [])):
            # a child's transform is relative to this tile's frame, the one its box is in
            walk(child, f"{where}.children[{k}]", _box_bounds(box), err)

    walk(root, "root", None, doc.get("geometricError"))
    return problems


def _box_bounds(box) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds of an oriented ``box`` (12 numbers)."""
    c = np.asarray(box[:3], float)
    axes = np.abs(np.asarray(box[3:], float).reshape(3, 3))
    ext = axes.sum(axis=0)
    return c - ext, c + ext
