"""What ``facadeforge view`` shows: every file we write, as layers of one scene.

Each file becomes a :class:`Layer` the page loads with three.js: glTF (``.glb``) as it is; OBJ
with its ``.mtl`` and textures (the page's OBJLoader reads them from the file's folder);
CityJSON (``.city.json``) and CityJSONSeq (``.city.jsonl``) read back into models
(:func:`facadeforge.exchange.cityjson.load_cityjson`) and sent as glTF; a 3D Tiles
``tileset.json`` as the list of its glTF contents with their transforms; point clouds (``.ply``,
``.las``, ``.laz``, ``.xyz`` …, :func:`facadeforge.points.io.read_cloud`) as packed float32
positions and uint8 colours (their own colours, else intensity, labels or height), thinned to
:data:`MAX_VIEW_POINTS`.

All layers share one frame, y up as glTF: a cloud's point ``p`` is drawn at
``TO_CGA @ (p - O)``, the axes ``facadeforge points`` gives its models, so a model of
``points`` lies over its cloud.  ``O`` is the ``origin`` in the ``report.json`` beside a
``points`` model, else the first cloud's centre.
"""

from __future__ import annotations

import io
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["MAX_VIEW_POINTS", "VIEW_SUFFIXES", "Layer", "Scene", "load_scene"]

#: Most points sent to the page per cloud (a random subset beyond it, said in the legend).
MAX_VIEW_POINTS: int = 2_000_000
#: Largest model file read for viewing.
MAX_VIEW_BYTES: int = 2**31
#: facadeforge's model axes from a z-up cloud's (x, y, z) (as :mod:`facadeforge.points`).
TO_CGA = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
_CLOUD = (".ply", ".las", ".laz", ".xyz", ".txt", ".csv", ".pts")
VIEW_SUFFIXES = (".glb", ".obj", ".city.json", ".city.jsonl", "tileset.json") + _CLOUD


@dataclass
class Layer:
    """One file of the scene: ``kind`` is ``gltf``, ``obj``, ``tiles`` or ``points``."""

    name: str
    kind: str
    path: Path
    offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    info: dict = field(default_factory=dict)
    payload: bytes | None = None      # glTF or packed points made here; None: the file itself

    def public(self, index: int) -> dict:
        return {"index": index, "name": self.name, "kind": self.kind, "offset": self.offset,
                "info": self.info}


@dataclass
class Scene:
    layers: list[Layer]
    origin: list[float] | None

    def public(self) -> dict:
        return {"layers": [la.public(i) for i, la in enumerate(self.layers)],
                "origin": self.origin}


def view_axes(up: int = 2) -> np.ndarray:
    """Cloud axes → the scene's (y up), as :func:`facadeforge.points.pipeline._place` turns a
    cloud whose vertical axis is ``up`` (a y- or x-up cloud is rotated, never mirrored)."""
    return TO_CGA @ np.roll(np.eye(3), 2 - up, axis=0)


def _suffix(path: Path) -> str:
    name = path.name.lower()
    for s in (".city.jsonl", ".city.json"):
        if name.endswith(s):
            return s
    if name == "tileset.json" or name.endswith(".tileset.json"):
        return "tileset.json"
    return path.suffix.lower()


def _points_frame(path: Path) -> tuple[np.ndarray, int] | None:
    """``(origin, up)`` of the ``facadeforge points`` OUTDIR holding ``path``: its cloud origin
    (the cloud's coordinates) and vertical axis; ``None`` for any other file."""
    rep = path.parent / "report.json"
    if not (rep.is_file() and (path.parent / "planes.json").is_file()):
        return None
    try:
        doc = json.loads(rep.read_text(encoding="utf-8"))
        o = np.asarray(doc.get("origin"), float).reshape(3)
        up = (doc.get("input") or {}).get("up", 2)
    except (OSError, ValueError, TypeError, AttributeError):
        return None
    return (o, up if up in (0, 1, 2) else 2) if np.isfinite(o).all() else None


def load_scene(paths) -> Scene:
    """The layers of ``paths`` (module docstring); raises :class:`InputError` naming a file
    that is missing, too large or of a kind the viewer does not show."""
    files = [Path(p) for p in paths]
    if not files:
        raise InputError("view: give at least one file (a model .glb/.obj/.city.json, a "
                         "tileset.json or a point cloud .ply/.las)")
    for f in files:
        if not f.is_file():
            raise InputError(f"view: {f} is not a file; give a model, a tileset.json or a "
                             "point cloud")
        if _suffix(f) not in VIEW_SUFFIXES:
            raise InputError(f"view: {f} is not a file the viewer shows; give one of "
                             f"{', '.join(VIEW_SUFFIXES)}")
        if f.stat().st_size > MAX_VIEW_BYTES:
            raise InputError(f"view: {f} is larger than {MAX_VIEW_BYTES >> 30} GiB")
    frames = {f: _points_frame(f) for f in files}
    first = next((fr for fr in frames.values() if fr is not None), None)
    origin = None if first is None else first[0]
    layers: list[Layer] = []
    for f in files:
        kind = _suffix(f)
        if kind in _CLOUD:
            layer, centre = _cloud_layer(f, origin)
            origin = centre if origin is None else origin
        elif kind == ".glb":
            layer = Layer(f.name, "gltf", f)
        elif kind == ".obj":
            layer = Layer(f.name, "obj", f)
        elif kind == "tileset.json":
            layer = _tiles_layer(f)
        else:
            layer = _cityjson_layer(f, kind)
        layers.append(layer)
    axes = view_axes(2 if first is None else first[1])
    world = None if origin is None else axes @ origin
    for la in layers:
        if la.kind in ("gltf", "obj") and world is not None:
            own = frames.get(la.path)     # a points model: relative to its cloud origin
            if own is not None:
                la.offset = [float(v) for v in axes @ own[0] - world]
        elif la.kind == "cityjson-gltf":
            la.kind = "gltf"
            if world is not None:       # world coordinates in CGA axes
                la.offset = [float(v) for v in -world]
            else:
                la.offset = [float(-v) for v in la.info.pop("_centre")]
        la.info.pop("_centre", None)
    return Scene(layers, None if origin is None else [float(v) for v in origin])


def _cloud_layer(path: Path, origin: np.ndarray | None) -> tuple[Layer, np.ndarray]:
    from ..exchange.raster import PALETTE
    from ..points.io import read_cloud

    cloud = read_cloud(path)
    xyz = cloud.xyz
    n = len(xyz)
    keep = np.arange(n)
    if n > MAX_VIEW_POINTS:
        keep = np.sort(np.random.default_rng(0).choice(n, MAX_VIEW_POINTS, replace=False))
    centre = (xyz.min(0) + xyz.max(0)) / 2 if n else np.zeros(3)
    base = origin if origin is not None else centre
    p = (xyz[keep] - base) @ view_axes(int(getattr(cloud, "up", 2))).T
    if cloud.rgb is not None:
        rgb, colour = cloud.rgb[keep], "rgb"
    elif cloud.labels is not None:
        lab = np.clip(cloud.labels[keep], 0, len(PALETTE) - 1)
        rgb, colour = PALETTE[lab].astype(np.uint8), "labels"
    elif cloud.intensity is not None:
        v = cloud.intensity[keep].astype(np.float64)
        lo, hi = np.percentile(v, [2, 98]) if len(v) else (0, 1)
        g = np.clip((v - lo) / max(hi - lo, 1e-9) * 255, 0, 255).astype(np.uint8)
        rgb, colour = np.stack([g, g, g], 1), "intensity"
    else:
        h = p[:, 1]
        t = (h - h.min()) / max(float(np.ptp(h)), 1e-9) if len(h) else h
        rgb = np.stack([60 + 195 * t, 120 + 80 * (1 - abs(2 * t - 1)), 255 - 195 * t], 1)
        rgb, colour = rgb.astype(np.uint8), "height"
    buf = io.BytesIO()
    buf.write(struct.pack("<I", len(keep)))
    buf.write(np.ascontiguousarray(p, np.float32).tobytes())
    buf.write(np.ascontiguousarray(rgb, np.uint8).tobytes())
    info = {"points": int(n), "shown": int(len(keep)), "colour": colour}
    return Layer(path.name, "points", path, info=info, payload=buf.getvalue()), base


def _cityjson_layer(path: Path, kind: str) -> Layer:
    from ..exchange import export
    from ..exchange.cityjson import load_cityjson, load_cityjsonseq
    from ..scratch import scratch_dir

    models = load_cityjson(path) if kind == ".city.json" else load_cityjsonseq(path)
    if not models:
        raise InputError(f"view: {path} holds no City Object with surfaces")
    work = scratch_dir("facadeforge-view-")
    try:
        out = work / "layer.glb"
        for m in models:   # drawn where the file puts them; the scene's origin is subtracted
            m.attributes.pop("_origin_offset", None)
        export(models, out)
        payload = out.read_bytes()
    finally:
        import shutil

        shutil.rmtree(work, ignore_errors=True)
    boxes = [m.stats()["bbox"] for m in models if m.parts]
    lo, hi = np.min([b[0] for b in boxes], 0), np.max([b[1] for b in boxes], 0)
    return Layer(path.name, "cityjson-gltf", path, payload=payload,
                 info={"buildings": len(models), "_centre": ((lo + hi) / 2).tolist()})


def _tiles_layer(path: Path) -> Layer:
    """The glTF contents of a 3D Tiles tileset, each with the product of the transforms above
    it: the most detailed view (every level of ``refine: ADD`` tiles; a ``refine: REPLACE``
    tile's content only where it has no children, which replace it when fully refined)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        root = doc["root"]
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(f"view: {path} is not a 3D Tiles tileset (no \"root\" tile)") from None
    contents: list[dict] = []
    stack = [(root, np.eye(4))]
    while stack and len(contents) < 100_000:
        tile, parent = stack.pop()
        if not isinstance(tile, dict):
            continue
        m = parent
        t = tile.get("transform")
        if isinstance(t, list) and len(t) == 16:
            m = parent @ np.asarray(t, float).reshape(4, 4).T
        items = [tile["content"]] if isinstance(tile.get("content"), dict) else []
        items += [c for c in tile.get("contents", []) if isinstance(c, dict)]
        if tile.get("refine") == "REPLACE" and tile.get("children"):
            items = []    # a coarse level of detail (our blocks): its children replace it
        for c in items:
            uri = c.get("uri") or c.get("url")
            if isinstance(uri, str) and uri.lower().endswith((".glb", ".gltf")):
                contents.append({"uri": uri, "matrix": m.T.reshape(-1).tolist()})
        stack.extend((k, m) for k in tile.get("children", []) or [])
    if not contents:
        raise InputError(f"view: {path} lists no glTF content")
    # the root's transform places the tileset on the globe: drawn in its local frame
    rt = root.get("transform")
    if isinstance(rt, list) and len(rt) == 16:
        inv = np.linalg.inv(np.asarray(rt, float).reshape(4, 4).T)
        for c in contents:
            c["matrix"] = (inv @ np.asarray(c["matrix"]).reshape(4, 4).T).T.reshape(-1).tolist()
    # glTF content is y up, tiles z up (3D Tiles §glTF up-axis): drawn y up again
    y2z = np.eye(4)
    y2z[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    z2y = y2z.T
    for c in contents:
        m = z2y @ np.asarray(c["matrix"]).reshape(4, 4).T @ y2z
        c["matrix"] = m.T.reshape(-1).tolist()     # column-major, as three.js Matrix4.fromArray
    return Layer(path.name, "tiles", path, info={"contents": contents, "tiles": len(contents)})
