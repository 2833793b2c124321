"""Label rasters and label drawings of 2D facade layouts.

A layout is projected into the x/y frame of its root scope (the facade plane: x to the right,
y up), or into the world x/y plane when there is no root.  :func:`label_map` samples each pixel
at its centre and paints leaf shapes in order (of a shape tree: :meth:`Shape.painting_order`,
inserted shapes such as balconies over the partition; of a model: its parts, those standing in
front of the root scope's plane last), later shapes over earlier ones, with the
index of their canonical label (:data:`LABEL_INDEX`, the order of
:class:`~facadeforge.model.Labels`).  Unlabelled leaves get the label guessed from their symbol,
else ``other``.  Row 0 of the array is the top of the facade.
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..model.labels import Labels, label_for_name
from ..model.model import Model
from ..model.scope import Scope
from ..model.shape import Shape
from ._common import Staging, as_models
from .errors import ExportError

__all__ = ["LABEL_COLORS", "LABEL_INDEX", "PALETTE", "export_label_png", "export_label_svg",
           "label_index", "label_map", "write_label_png", "write_label_svg"]

#: Index of each canonical label in a label map (``background`` is 0).
LABEL_INDEX: dict[str, int] = {label.value: i for i, label in enumerate(Labels)}

#: Fixed display colour (RGB, 0–255) of each canonical label.
LABEL_COLORS: dict[str, tuple[int, int, int]] = {
    "background": (0, 0, 0),
    "wall": (214, 196, 160),
    "window": (31, 119, 180),
    "door": (140, 86, 75),
    "balcony": (255, 127, 14),
    "shop": (227, 119, 194),
    "roof": (214, 39, 40),
    "sky": (158, 218, 229),
    "cornice": (188, 189, 34),
    "sill": (255, 187, 120),
    "blind": (148, 103, 189),
    "deco": (23, 190, 207),
    "molding": (219, 219, 141),
    "pillar": (127, 127, 127),
    "vegetation": (44, 160, 44),
    "other": (197, 176, 213),
    "ground": (90, 90, 90),
    "car": (255, 152, 150),
    "person": (196, 156, 148),
    "pavement": (199, 199, 199),
    "road": (52, 52, 60),
}

_LABEL_NAMES = list(LABEL_INDEX)

#: (N, 3) uint8 palette: row ``LABEL_INDEX[label]`` is ``LABEL_COLORS[label]``.
PALETTE = np.array([LABEL_COLORS[label.value] for label in Labels], np.uint8)

Source = Shape | Model | Sequence[Model]


@dataclass
class _Item:
    label: str
    symbol: str
    polygons: list[np.ndarray]  # (k, 2) in the layout frame


@dataclass
class _Layout:
    items: list[_Item]
    extent: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax


def label_index(label: str, symbol: str = "") -> int:
    """Label-map index of ``label``; guessed from ``label`` or ``symbol`` words, else ``other``."""
    if label in LABEL_INDEX:
        return LABEL_INDEX[label]
    guess = label_for_name(label) if label else None
    guess = guess or (label_for_name(symbol) if symbol else None)
    return LABEL_INDEX[(guess or Labels.OTHER).value]


# -- layout ------------------------------------------------------------------------------------

def _layout(source: Source) -> _Layout:
    if isinstance(source, Shape):
        frame, items = source.scope, _shape_items(source)
    else:
        models = as_models(source)
        root = models[0].root
        frame = root.scope if root is not None else None
        parts = [p for m in models for p in m.parts]
        # what stands in front of the frame's plane (balconies on a facade) is painted over
        # what lies in it, whatever the rules' order: a stable partition
        parts.sort(key=lambda p: _protrudes(frame, p.mesh.vertices))
        items = [_Item(p.label, p.symbol, [_project(frame, poly) for poly in p.mesh.polygons()])
                 for p in parts]
    return _Layout(items, _extent(frame, items))


def _shape_items(root: Shape) -> list[_Item]:
    items = []
    for leaf in root.painting_order():          # inserted shapes (balconies) in front
        if leaf.geometry is not None and leaf.geometry.n_faces:
            polys = leaf.geometry.polygons()
        elif leaf.scope.size[0] > 0 and leaf.scope.size[1] > 0:
            sx, sy = leaf.scope.size[:2]
            polys = [leaf.scope.to_world(np.array([[0, 0, 0], [sx, 0, 0], [sx, sy, 0],
                                                   [0, sy, 0]], float))]
        else:
            continue
        items.append(_Item(leaf.label, leaf.symbol, [_project(root.scope, p) for p in polys]))
    return items


def _protrudes(frame: Scope | None, vertices: np.ndarray) -> bool:
    """Whether any of ``vertices`` lies in front of ``frame``'s x/y plane (local z > 1 mm)."""
    v = np.asarray(vertices, float).reshape(-1, 3)
    if frame is None or not len(v):
        return False
    return bool(frame.to_local(v)[:, 2].max() > 1e-3)


def _project(frame: Scope | None, points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, float)
    return (points if frame is None else frame.to_local(points))[:, :2]


def _extent(frame: Scope | None, items: list[_Item]) -> tuple[float, float, float, float]:
    if frame is not None and frame.size[0] > 0 and frame.size[1] > 0:
        return 0.0, 0.0, float(frame.size[0]), float(frame.size[1])
    pts = [p for it in items for p in it.polygons if len(p)]
    if not pts:
        raise ExportError("the layout is empty: nothing to rasterise")
    allpts = np.concatenate(pts)
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


# -- raster ------------------------------------------------------------------------------------

def label_map(source: Source, px_per_m: float = 20.0,
              size: tuple[int, int] | None = None) -> np.ndarray:
    """Rasterise a layout into a label-index image.

    Parameters
    ----------
    source : Shape, Model or sequence of Model
        A shape tree (its leaves, with geometry or else their scope rectangle) or models (their
        parts; the frame is the first model's root scope, or world x/y without a root).
    px_per_m : float
        Resolution in pixels per unit of the frame (metres, or pixels for ``unit="px"`` layouts).
    size : (H, W), optional
        Exact output size; the layout extent is stretched to fill it.

    Returns
    -------
    (H, W) uint8
        :data:`LABEL_INDEX` values; 0 (background) where no shape covers a pixel centre.
    """
    layout = _layout(source)
    xmin, ymin, xmax, ymax = layout.extent
    w_m, h_m = max(xmax - xmin, 1e-12), max(ymax - ymin, 1e-12)
    if size is None:
        if not px_per_m > 0:
            raise ExportError(f"px_per_m must be positive, got {px_per_m}")
        height = max(1, math.ceil(round(h_m * px_per_m, 6)))
        width = max(1, math.ceil(round(w_m * px_per_m, 6)))
    else:
        height, width = (int(v) for v in size)
        if height < 1 or width < 1:
            raise ExportError(f"size must be positive, got {size}")
    sx, sy = width / w_m, height / h_m
    out = np.zeros((height, width), np.uint8)
    for item in layout.items:
        value = label_index(item.label, item.symbol)
        for poly in item.polygons:
            pix = np.column_stack([(poly[:, 0] - xmin) * sx, (ymax - poly[:, 1]) * sy])
            _fill(out, pix, value)
    return out


def _fill(out: np.ndarray, poly: np.ndarray, value: int) -> None:
    """Set the pixels of ``out`` whose centres lie inside ``poly`` (pixel coordinates, even-odd)."""
    if len(poly) < 3:
        return
    h, w = out.shape
    c0 = max(0, math.floor(poly[:, 0].min() - 0.5))
    c1 = min(w - 1, math.ceil(poly[:, 0].max() - 0.5))
    r0 = max(0, math.floor(poly[:, 1].min() - 0.5))
    r1 = min(h - 1, math.ceil(poly[:, 1].max() - 0.5))
    if c0 > c1 or r0 > r1:
        return
    px = np.arange(c0, c1 + 1) + 0.5
    xi, yi = poly[:, 0], poly[:, 1]
    xj, yj = np.roll(xi, -1), np.roll(yi, -1)
    step = max(1, 4_000_000 // (len(px) * len(poly)))
    for start in range(r0, r1 + 1, step):
        py = np.arange(start, min(r1 + 1, start + step)) + 0.5
        crosses = (yi > py[:, None]) != (yj > py[:, None])
        with np.errstate(divide="ignore", invalid="ignore"):
            xint = xi + (py[:, None] - yi) * (xj - xi) / (yj - yi)
        hits = (px[None, :, None] < xint[:, None, :]) & crosses[:, None, :]
        inside = (hits.sum(axis=2) & 1).astype(bool)
        block = out[start:start + len(py), c0:c1 + 1]
        block[inside] = value


def write_label_png(labels: np.ndarray, path: str | os.PathLike) -> Path:
    """Write a label map as a palette PNG whose colours are :data:`LABEL_COLORS`.

    Parameters
    ----------
    labels : (H, W) integer array
        Label indices (see :func:`label_map`).
    path : path-like
        Destination, written atomically.
    """
    from PIL import Image

    arr = np.asarray(labels)
    if arr.ndim != 2 or arr.size == 0:
        raise ExportError(f"a label map is a non-empty (H, W) array, got shape {arr.shape}")
    if arr.min() < 0 or arr.max() >= len(PALETTE):
        raise ExportError(f"label indices must lie in 0..{len(PALETTE) - 1}")
    img = Image.frombytes("P", (arr.shape[1], arr.shape[0]), arr.astype(np.uint8).tobytes())
    img.putpalette(PALETTE.reshape(-1).tolist())
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=True)
    with Staging() as stage:
        stage.write_bytes(path, buf.getvalue())
    return Path(path)


def write_label_svg(source: Source, path: str | os.PathLike, px_per_m: float = 20.0) -> Path:
    """Write a layout as SVG polygons filled with label colours.

    Each polygon carries ``data-label`` (canonical label) and ``data-symbol`` attributes; the
    drawing is ``px_per_m`` pixels per unit, y pointing down as SVG wants.
    """
    layout = _layout(source)
    xmin, ymin, xmax, ymax = layout.extent
    width, height = (xmax - xmin) * px_per_m, (ymax - ymin) * px_per_m
    bg = _hex(LABEL_COLORS["background"])
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.6g}" height="{height:.6g}" '
             f'viewBox="0 0 {width:.6g} {height:.6g}">',
             f'<rect x="0" y="0" width="{width:.6g}" height="{height:.6g}" fill="{bg}" '
             f'data-label="background"/>']
    for item in layout.items:
        label = _LABEL_NAMES[label_index(item.label, item.symbol)]
        for poly in item.polygons:
            if len(poly) < 3 or _area2(poly) < 1e-12:
                continue
            pts = " ".join(f"{(x - xmin) * px_per_m:.3f},{(ymax - y) * px_per_m:.3f}"
                           for x, y in poly)
            lines.append(f'<polygon points="{pts}" fill="{_hex(LABEL_COLORS[label])}" '
                         f'data-label="{label}" data-symbol={quoteattr(item.symbol)}/>')
    lines.append("</svg>")
    with Staging() as stage:
        stage.write_text(path, "\n".join(lines) + "\n")
    return Path(path)


def _area2(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _hex(rgb: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


# -- registry adapters -------------------------------------------------------------------------

def export_label_png(models: Model | Sequence[Model], path: str | os.PathLike, *,
                     px_per_m: float = 20.0, size: tuple[int, int] | None = None) -> list[Path]:
    """Exporter for ``.png``: the label map of the models' layout as a palette PNG."""
    return [write_label_png(label_map(as_models(models), px_per_m=px_per_m, size=size), path)]


def export_label_svg(models: Model | Sequence[Model], path: str | os.PathLike, *,
                     px_per_m: float = 20.0) -> list[Path]:
    """Exporter for ``.svg``: the models' layout as labelled SVG polygons."""
    return [write_label_svg(as_models(models), path, px_per_m=px_per_m)]
