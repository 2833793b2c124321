"""Synthetic facades with exact ground truth: random CGA layouts rendered as photo-like images.

:func:`generate` draws, for facade ``i`` of a run, a deterministic random stream from
``(seed, i)``; the stream picks a style (a parametric facade grammar in ``grammars/``), draws its
``@Range``/``@Enum`` attributes, derives the layout with
:func:`facadeforge.engine.derive_facade`, and renders a photo from the shape tree.  Everything is
a function of ``(seed, i)``: the same seed writes the same bytes.

Styles (``grammars/*.cga``, in our CGA dialect)
    ``haussmann`` — Parisian stone apartment block: shop ground floor and carriage door,
    optional mezzanine, French windows with balconettes or continuous balconies, cornice, zinc
    mansard with dormers, chimneys.  ``modern`` — grid of punched or ribbon windows or a curtain
    wall, external blinds, glass balconies, glazed storefront, flat roof behind a parapet.
    ``residential`` — plaster or brick house row: shutters, roller blinds, sills, door and
    garage, eaves, tiled roof with dormers.  Every style has irregularities driven by attributes
    and stochastic rules (missing and shifted windows, blinds, mezzanine, a distinct ground
    floor) and occluders (``occluders.cga``: street trees ``vegetation``, parked cars
    ``car``).  See the head of each grammar for its conventions.

Output layout (one set of files per facade, ``NAME = synth_<seed>_<i:04d>``)::

    DIR/NAME.jpg           the photo (RGB JPEG, quality 70-92)
    DIR/NAME.png           label map: palette PNG whose pixel value is the canonical label index
                           (facadeforge.exchange.raster.LABEL_INDEX, the order of
                           facadeforge.model.Labels: 0 background, 1 wall, 2 window, 3 door,
                           4 balcony, 5 shop, 6 roof, 7 sky, 8 cornice, 9 sill, 10 blind, 11 deco,
                           12 molding, 13 pillar, 14 vegetation, 15 other, 16 ground, 17 car);
                           colours are raster.LABEL_COLORS.  Aligned with the photo (warped with it when the
                           photo has perspective).
    DIR/NAME.tree.json     the shape tree, ``Shape.to_dict()`` (metres, x right, y up, z out)
    DIR/NAME.objects.json  one rectangle per element (a maximal subtree whose visible leaves all
                           carry one label; walls, roof, sky and ground are not objects):
                           ``{"label", "symbol", "box": [x0, y0, x1, y1] photo pixels,
                           "rectified_box": …, "rect_m": [x0, y0, x1, y1] metres, "depth_m"}``
    DIR/NAME.meta.json     style, attributes, seeds, size, metres per pixel, homography, counts

Boxes use pixel edges (``x1``/``y1`` exclusive, :class:`~facadeforge.datasets.ObjectBox`).  The
label map *before* perspective is exactly ``raster.label_map(tree, size=(H, W))`` of the saved
tree; with perspective, ``meta["homography"]`` maps rectified pixel coordinates to photo pixel
coordinates (pixel ``(r, c)`` has its centre at ``(c + 0.5, r + 0.5)``) and the label PNG is the
rectified map resampled by nearest neighbour (:func:`warp_labels`); photo pixels outside the
facade are ``background``.

The renderer (numpy, vectorised per shape) simulates: procedural wall materials (plaster with
low-frequency noise and grime, limestone ashlar, rusticated stone, brick, concrete panels), glass
with a sky-reflection gradient, streaks, interiors and curtains, frames and glazing bars,
louvred shutters, roller blinds, panelled doors, shop signs, wrought-iron and glass railings,
zinc and tiled roofs, a sky gradient with clouds, trees and cars; shading and cast shadows from
element depth (the ``z`` of each leaf: recessed windows get a shadow band along their top and
sun-side edges, balconies and cornices cast shadows below), ambient occlusion, sometimes the
shadow of the building across the street; then optional perspective, lens blur, vignetting,
white balance and exposure, sensor noise and JPEG artefacts.

:func:`load_synthetic` reads such a folder (registered as ``"synthetic"`` in
:data:`facadeforge.datasets.LOADERS`); ``meta`` of each sample carries ``floors`` (storeys
from the ground floor up to the last one under the roof: a mezzanine and a penthouse count,
dormers do not; each style's storey rules ``report("floors", 1)``) and ``columns`` (the most
window elements in one storey band) for the benchmark's count errors.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import os
import shutil
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from scipy import ndimage

from ..errors import InputError
from ..jsonfile import read_json
from ..model.shape import Shape
from ..scratch import scratch_dir
from .folder import FacadeSample, ObjectBox, _check_folder
from .labelsets import CANONICAL_INDEX, LabelSet, get_label_set

__all__ = ["OBJECT_LABELS", "STYLES", "SyntheticFacade", "add_parser", "cmd_synth",
           "draw_attributes", "generate", "grammar_path", "homography_from_points",
           "leaf_rects", "load_style", "load_synthetic", "make_facade", "render_photo",
           "warp_labels"]

#: The facade styles, one grammar each in ``grammars/<style>.cga``.
STYLES: tuple[str, ...] = ("haussmann", "modern", "residential")

#: Canonical labels written as objects (walls, roof, sky, ground and background are regions).
OBJECT_LABELS: tuple[str, ...] = ("window", "door", "balcony", "shop", "cornice", "sill", "blind",
                                  "deco", "molding", "pillar", "vegetation", "car", "other")

GRAMMAR_DIR = Path(__file__).resolve().parent / "grammars"
DEFAULT_WIDTH_PX = 480
_MEASURE_RULE = "Measure"


# ================================================================================ grammars
def grammar_path(style: str) -> Path:
    """The ``.cga`` file of a style (:data:`STYLES`)."""
    if style not in STYLES:
        raise InputError(f"unknown facade style {style!r}; use one of {', '.join(STYLES)}")
    return GRAMMAR_DIR / f"{style}.cga"


@cache
def load_style(style: str):
    """The loaded rules (:class:`facadeforge.engine.Rules`) of a style, cached."""
    from ..engine import load_rules

    return load_rules(grammar_path(style))


def attribute_space(rules) -> dict[str, tuple]:
    """Randomised attributes of a rule set: ``{name: ("range", lo, hi, step) | ("enum", values)}``.

    ``@Range(min, max[, stepsize])`` on a numeric attribute draws uniformly in ``[min, max]``
    (on the step grid when a step is given); ``@Enum(v1, v2, …)`` draws one value uniformly.
    Attributes without either keep their default.
    """
    from ..grammar import ast as A

    space: dict[str, tuple] = {}
    for a in rules.ruleset.main.attrs.values():
        if a.const:
            continue
        for ann in a.annotations:
            args = ann.args
            if ann.name == "Range" and len(args) >= 2 and all(isinstance(x, A.Num)
                                                               for x in args[:3]):
                step = args[2].value if len(args) >= 3 else 0.0
                space[a.name] = ("range", float(args[0].value), float(args[1].value), float(step))
            elif ann.name == "Enum" and args:
                values = [x.value for x in args if isinstance(x, (A.Num, A.Str, A.Bool))]
                if values:
                    space[a.name] = ("enum", tuple(values))
    return space


def draw_attributes(rules, rng: np.random.Generator) -> dict[str, Any]:
    """One random draw of every ``@Range``/``@Enum`` attribute (see :func:`attribute_space`),
    in declaration order; floats are rounded to 4 decimals, stepped ranges give whole steps."""
    out: dict[str, Any] = {}
    for name, spec in attribute_space(rules).items():
        if spec[0] == "range":
            _, lo, hi, step = spec
            if step > 0:
                k = int(rng.integers(0, int(math.floor((hi - lo) / step + 1e-9)) + 1))
                value = lo + k * step
                out[name] = int(value) if float(value).is_integer() else round(value, 4)
            else:
                out[name] = round(float(rng.uniform(lo, hi)), 4)
        else:
            values = spec[1]
            v = values[int(rng.integers(0, len(values)))]
            out[name] = v if isinstance(v, (bool, str)) else float(v)
    return out


# ================================================================================ layout
@dataclass
class LeafRect:
    """A visible leaf of the shape tree in pixels: rows ``r0:r1``, columns ``c0:c1``."""

    node: Shape
    symbol: str
    label: str
    r0: int
    r1: int
    c0: int
    c1: int
    depth: float
    element: int = -1


@dataclass
class SyntheticFacade:
    """A derived facade layout, sized in pixels, with its visible leaves and elements."""

    style: str
    attributes: dict[str, Any]
    cga_seed: int
    width_m: float
    height_m: float
    width_px: int
    height_px: int
    tree: Shape
    warnings: list[str]
    reports: dict[str, list]
    leaves: list[LeafRect] = field(default_factory=list)
    elements: list[dict[str, Any]] = field(default_factory=list)

    @property
    def px_per_m(self) -> float:
        return self.width_px / self.width_m

    def label_map(self) -> np.ndarray:
        """The label map of the tree, ``raster.label_map(tree, size=(H, W))``."""
        from ..exchange.raster import label_map

        return label_map(self.tree, size=(self.height_px, self.width_px))


def _canonical(leaf: Shape) -> str:
    from ..exchange.raster import LABEL_INDEX, label_index

    names = list(LABEL_INDEX)
    return names[label_index(leaf.label, leaf.symbol)]


def leaf_rects(tree: Shape, height_px: int, width_px: int) -> list[LeafRect]:
    """Pixel rectangles of the leaves that cover pixels, in painting order.

    A pixel belongs to a leaf when its centre lies in the leaf's rectangle, with the same
    arithmetic as :func:`facadeforge.exchange.raster.label_map` (rectangle ``[x0, x1) × [y0, y1)``
    in pixel units), so painting these rectangles in order reproduces the label map.
    """
    frame = tree.scope
    w_m = max(float(frame.size[0]), 1e-12)
    h_m = max(float(frame.size[1]), 1e-12)
    ymax = float(frame.size[1])
    sx, sy = width_px / w_m, height_px / h_m
    cols = np.arange(width_px) + 0.5
    rows = np.arange(height_px) + 0.5
    out = []
    for leaf in tree.leaves():
        size = leaf.scope.size
        if not (size[0] > 0 and size[1] > 0):
            continue
        corners = np.array([[0, 0, 0], [size[0], 0, 0], [size[0], size[1], 0],
                            [0, size[1], 0]], float)
        local = frame.to_local(leaf.scope.to_world(corners))
        px = (local[:, 0] - 0.0) * sx
        py = (ymax - local[:, 1]) * sy
        c0, c1 = np.searchsorted(cols, [px.min(), px.max()], side="left")
        r0, r1 = np.searchsorted(rows, [py.min(), py.max()], side="left")
        if c1 <= c0 or r1 <= r0:
            continue
        out.append(LeafRect(leaf, leaf.symbol.split(".")[-1], _canonical(leaf), int(r0),
                            int(r1), int(c0), int(c1), float(local[:, 2].mean())))
    return out


def _elements(tree: Shape, rects: list[LeafRect], height_px: int, width_px: int
              ) -> list[dict[str, Any]]:
    """Group visible leaves into elements: maximal subtrees whose visible leaves share a label.

    Sets ``LeafRect.element``; returns one dict per element (label, symbol, pixel box in the
    rectified frame, metre rectangle, mean depth).
    """
    by_node = {id(r.node): r for r in rects}
    labels: dict[int, frozenset] = {}
    order: list[Shape] = []
    stack = [tree]
    while stack:  # pre-order; reversed it is a valid post-order for the label sets
        node = stack.pop()
        order.append(node)
        stack.extend(node.children)
    for node in reversed(order):
        if node.children:
            s: frozenset = frozenset()
            for c in node.children:
                s = s | labels[id(c)]
            labels[id(node)] = s
        else:
            r = by_node.get(id(node))
            labels[id(node)] = frozenset((r.label,)) if r is not None else frozenset()
    elements: list[dict[str, Any]] = []
    frame_h = float(tree.scope.size[1])
    sx, sy = width_px / max(float(tree.scope.size[0]), 1e-12), height_px / max(frame_h, 1e-12)
    stack2: list[tuple[Shape, bool]] = [(tree, False)]
    while stack2:
        node, inside = stack2.pop()
        s = labels[id(node)]
        if not inside and len(s) == 1:
            members = [by_node[id(n)] for n in node.walk() if id(n) in by_node]
            k = len(elements)
            for m in members:
                m.element = k
            (label,) = s
            r0 = min(m.r0 for m in members)
            r1 = max(m.r1 for m in members)
            c0 = min(m.c0 for m in members)
            c1 = max(m.c1 for m in members)
            area = sum((m.r1 - m.r0) * (m.c1 - m.c0) for m in members)
            depth = sum(m.depth * (m.r1 - m.r0) * (m.c1 - m.c0) for m in members) / area
            elements.append({
                "label": label, "symbol": node.symbol.split(".")[-1],
                "rectified_box": [float(c0), float(r0), float(c1), float(r1)],
                "rect_m": [round(c0 / sx, 4), round(frame_h - r1 / sy, 4), round(c1 / sx, 4),
                           round(frame_h - r0 / sy, 4)],
                "depth_m": round(depth, 4)})
            continue
        for c in reversed(node.children):
            stack2.append((c, inside))
    return elements


def _measure(rules, attrs: dict[str, Any], seed: int) -> float:
    from ..engine import derive_facade

    m = derive_facade(rules, 10.0, 10.0, start=_MEASURE_RULE, attrs=attrs, seed=seed)
    try:
        return float(m.reports["contentHeight"][0])
    except (KeyError, IndexError):
        raise InputError(f"grammar {rules.source} reports no contentHeight in rule "
                         f"{_MEASURE_RULE}") from None


def make_facade(style: str, rng: np.random.Generator, *,
                size: tuple[int, int] | int | None = None,
                px_per_m: float | None = None, width_px: int | None = None,
                attrs: dict[str, Any] | None = None) -> SyntheticFacade:
    """Draw attributes of ``style`` with ``rng`` and derive a facade layout sized in pixels.

    Parameters
    ----------
    style : str
        One of :data:`STYLES`.
    rng : numpy.random.Generator
        Source of every random choice (attributes, CGA seed).
    size : (W, H) or int, optional
        Exact image size (the facade width follows from the height of its content plus the
        sky band), or the image width in pixels.
    px_per_m : float, optional
        Resolution; the image size follows from the drawn facade size.
    width_px : int, optional
        Image width (default 480 when neither ``size`` nor ``px_per_m`` is given).
    attrs : dict, optional
        Attribute values that override the drawn ones.
    """
    from ..engine import derive_facade

    if isinstance(size, (int, np.integer)):
        width_px, size = int(size), None
    rules = load_style(style)
    drawn = draw_attributes(rules, rng)
    drawn.update(attrs or {})
    cga_seed = int(rng.integers(0, 2**31 - 1))
    content = _measure(rules, drawn, cga_seed)
    width_m = float(drawn.get("facadeWidth", 16.0))
    total_m = content + float(drawn.get("skyHeight", 1.0))
    if size is not None:
        w_px, h_px = (int(v) for v in size)
        if w_px < 8 or h_px < 8:
            raise InputError(f"image size {w_px}x{h_px} is too small; use at least 8x8 pixels")
        ppm = h_px / total_m
        width_m = w_px / ppm
    else:
        if px_per_m is not None:
            if not px_per_m > 0:
                raise InputError(f"px_per_m must be positive, got {px_per_m}")
            ppm = float(px_per_m)
            w_px = max(8, int(round(width_m * ppm)))
        else:
            w_px = int(width_px or DEFAULT_WIDTH_PX)
            if w_px < 8:
                raise InputError(f"image width {w_px} px is too small; use at least 8 pixels")
            ppm = w_px / width_m
        width_m = w_px / ppm
        h_px = max(8, int(round(total_m * ppm)))
    height_m = h_px / ppm
    model = derive_facade(rules, width_m, height_m, attrs=drawn, seed=cga_seed)
    # the tree as it is saved (to_dict drops geometry): labels, render and objects all use it
    tree = Shape.from_dict(json.loads(json.dumps(model.root.to_dict())))
    rects = leaf_rects(tree, h_px, w_px)
    layout = SyntheticFacade(style, drawn, cga_seed, width_m, height_m, w_px, h_px, tree,
                             list(model.warnings), dict(model.reports), rects)
    layout.elements = _elements(tree, rects, h_px, w_px)
    return layout


def _counts(layout: SyntheticFacade) -> tuple[int, int]:
    """Storeys (``report("floors", 1)`` per storey) and window columns (most window elements
    whose centres share a storey band)."""
    floors = len(layout.reports.get("floors", []))
    centres = sorted(((e["rectified_box"][1] + e["rectified_box"][3]) / 2,
                      (e["rectified_box"][0] + e["rectified_box"][2]) / 2)
                     for e in layout.elements if e["label"] == "window")
    columns = 0
    if centres:
        tol = 0.8 * layout.px_per_m
        band: list[float] = []
        y_ref = None
        for y, x in centres:
            if y_ref is None or y - y_ref > tol:
                columns = max(columns, len(band))
                band, y_ref = [], y
            band.append(x)
        columns = max(columns, len(band))
    return floors, columns


# ================================================================================ rendering
def _srgb(hex_or_rgb) -> np.ndarray:
    if isinstance(hex_or_rgb, str):
        h = hex_or_rgb.lstrip("#")
        return np.array([int(h[k:k + 2], 16) for k in (0, 2, 4)], np.float32) / 255.0
    return np.asarray(hex_or_rgb, np.float32)


def _pick(rng: np.random.Generator, palette: Sequence[str], jitter: float = 0.03) -> np.ndarray:
    c = _srgb(palette[int(rng.integers(0, len(palette)))])
    return np.clip(c * (1 + rng.uniform(-jitter, jitter)) + rng.uniform(-jitter, jitter, 3) * 0.5,
                   0, 1).astype(np.float32)


# Per-style palettes (sRGB hex).  Materials named by grammar attributes win where given.
_LOOKS: dict[str, dict[str, Any]] = {
    "haussmann": {
        "wall": ("#d9ccb2", "#e0d4bc", "#cfc0a2", "#d6c9b0", "#e3d9c6", "#c9b89a"),
        "material": "ashlar",
        "frame": ("#ece8df", "#e6e1d6", "#d9d4ca", "#c9c4ba", "#8f8a80"),
        "shutter": ("#c9c7bf", "#8a9a9f", "#e4e2dc", "#6f7f74", "#b8b2a2"),
        "roof": ("#7d8a94", "#6f7a84", "#8a949b", "#5f6b74"),
        "door": ("#2f3b33", "#3b2a20", "#1f2a3a", "#4a3a2c", "#2a2a2a"),
        "iron": ("#1b1d1f", "#24272a", "#2c2a27"),
    },
    "modern": {
        "wall": ("#bdbab4", "#d8d6d0", "#a9a7a2", "#e7e4dc", "#8e8b86", "#c8beae", "#9a9ea3"),
        "material": "panels",
        "frame": ("#3a3d40", "#55595d", "#2a2b2d", "#a6aaae", "#e9e9e6"),
        "shutter": ("#9ea3a7", "#5c6165", "#c9ccce", "#3f4347"),
        "roof": ("#5d6166", "#75797e"),
        "door": ("#3a3d40", "#2a2b2d", "#6a6e72"),
        "iron": ("#2a2c2f", "#5d6166", "#aeb2b5"),
    },
    "residential": {
        "wall": ("#efe6cf", "#e8d6a8", "#f1eee6", "#d9c3a0", "#e9c9a4", "#cfd8d3", "#e6d3c2",
                 "#f3e3b7"),
        "material": "plaster",
        "frame": ("#f2f0ea", "#ebe7dd", "#6b4a32", "#4a3b30", "#d9d6cf"),
        "shutter": ("#4f6b4a", "#35566b", "#7a4e35", "#8c9496", "#efece4", "#5d7f86", "#8a3b2e"),
        "roof": ("#8c4a36", "#7a3f2f", "#9a5a40", "#4a4b4e", "#6a5248"),
        "door": ("#5a3a26", "#2f4a3a", "#1f3550", "#6e2f2a", "#3a3a3a", "#7a6a55"),
        "iron": ("#222324", "#3a3a3a"),
    },
}

_BRICK = ("#9a4a35", "#8a3f2e", "#a65b3f", "#7d3a2b", "#b0704f", "#c9a37a", "#8c5a46")
_GLASS_TINT = ("#3d4a55", "#2f3c44", "#44525a", "#37403d", "#2e3540")
_SIGN = ("#1f3b2d", "#7a1f24", "#1d2f55", "#1a1a1a", "#e9e4d8", "#5a2a4a", "#b5892e", "#2f6f6a")
_CAR = ("#e8e8e6", "#b9bcbf", "#1c1d20", "#7a1c1c", "#24395e", "#5b5f63", "#cfcac0", "#2f4a36")
_LEAF = ("#4c6b2f", "#3e5d2a", "#5c7a35", "#4a6438", "#667b33")


def _value_noise(rng: np.random.Generator, h: int, w: int, cell: float) -> np.ndarray:
    """Smooth noise in about [-1, 1] with features ``cell`` pixels wide (cubic upsampling)."""
    cell = max(float(cell), 1.0)
    gh, gw = int(math.ceil(h / cell)) + 3, int(math.ceil(w / cell)) + 3
    grid = rng.standard_normal((gh, gw)).astype(np.float32)
    up = ndimage.zoom(grid, cell, order=3, mode="reflect", grid_mode=True)
    oy = int(rng.integers(0, max(1, up.shape[0] - h)))
    ox = int(rng.integers(0, max(1, up.shape[1] - w)))
    out = up[oy:oy + h, ox:ox + w]
    if out.shape != (h, w):
        out = np.pad(out, ((0, h - out.shape[0]), (0, w - out.shape[1])), mode="edge")
    return np.clip(out, -2.5, 2.5) / 1.2


def _smooth_line(dist_px: np.ndarray, width_px: float) -> np.ndarray:
    """Coverage (0..1) of a line of ``width_px`` at distance ``dist_px`` (antialiased)."""
    return np.clip(width_px / 2 + 0.5 - np.abs(dist_px), 0.0, 1.0)


class _Painter:
    """Renders a :class:`SyntheticFacade` into a linear-ish RGB float image (0..1)."""

    def __init__(self, layout: SyntheticFacade, rng: np.random.Generator):
        self.L = layout
        self.rng = rng
        self.h, self.w = layout.height_px, layout.width_px
        self.ppm = layout.px_per_m
        look = _LOOKS[layout.style]
        a = layout.attributes
        self.material = str(a.get("wallMaterial", look["material"]))
        self.wall = _pick(rng, _BRICK if self.material == "brick" else look["wall"])
        self.stone = np.clip(self.wall * 1.06 + 0.03, 0, 1) if self.material != "brick" else \
            _pick(rng, ("#e6e0d2", "#d8d2c4", "#ece7dc"))
        self.frame = _pick(rng, look["frame"])
        self.shutter = _pick(rng, look["shutter"])
        self.roof = _pick(rng, look["roof"])
        self.door = _pick(rng, look["door"])
        self.iron = _pick(rng, look["iron"], 0.0)
        self.blind = _pick(rng, ("#d9d4c8", "#b9b6ae", "#8f9294", "#e8e1cf", "#6d7073"))
        self.glass_tint = _pick(rng, _GLASS_TINT)
        self.leaf_green = _pick(rng, _LEAF, 0.05)
        # sky: clear, hazy or overcast
        kind = rng.choice(["clear", "hazy", "overcast"], p=[0.45, 0.3, 0.25])
        self.sky_kind = str(kind)
        if kind == "clear":
            self.sky_top, self.sky_low = _srgb("#4f86c6"), _srgb("#b9d3ea")
        elif kind == "hazy":
            self.sky_top, self.sky_low = _srgb("#8fb0d0"), _srgb("#dfe7ee")
        else:
            self.sky_top, self.sky_low = _srgb("#a9adb2"), _srgb("#dcdde0")
        self.sky_top = np.clip(self.sky_top * rng.uniform(0.9, 1.08), 0, 1)
        # element-level random numbers
        self.erand = rng.random((max(1, len(layout.elements)), 8)).astype(np.float32)
        # global fields
        h, w, ppm = self.h, self.w, self.ppm
        self.n_lo = _value_noise(rng, h, w, 2.5 * ppm)
        self.n_mid = _value_noise(rng, h, w, 0.5 * ppm)
        self.n_px = rng.standard_normal((h, w)).astype(np.float32)
        # grime: streaks running down the wall (noise stretched vertically)
        small = _value_noise(rng, max(2, h // 8), w, 0.3 * ppm)
        self.n_streak = np.repeat(small, 8, axis=0)[:h]
        if self.n_streak.shape[0] < h:
            self.n_streak = np.pad(self.n_streak, ((0, h - self.n_streak.shape[0]), (0, 0)),
                                   mode="edge")
        sky_rows = [r.r1 for r in layout.leaves if r.label == "sky"]
        self.sky_bottom = max(sky_rows) if sky_rows else max(1, h // 8)
        self.xm = ((np.arange(w, dtype=np.float32) + 0.5) / ppm)[None, :]
        self.ym = ((h - np.arange(h, dtype=np.float32) - 0.5) / ppm)[:, None]
        self.px = 1.0 / ppm  # metres per pixel
        self.img = np.zeros((h, w, 3), np.float32)
        self.depth = np.zeros((h, w), np.float32)
        self.emissive = np.zeros((h, w), bool)
        self.wall_tex = self._wall_texture(self.material, self.wall)
        self._rustic = None

    # -- global textures -------------------------------------------------------------------
    def _tone(self, base: np.ndarray, amount: float, *fields: np.ndarray) -> np.ndarray:
        f = sum(fields) if fields else 0
        return np.clip(base[None, None, :] * (1 + amount * f)[..., None], 0, 1)

    def _block_tone(self, course: np.ndarray, block: np.ndarray, spread: float) -> np.ndarray:
        table = self.rng.uniform(-spread, spread, 4096).astype(np.float32)
        return table[(course * 733 + block * 97) % 4096]

    def _wall_texture(self, material: str, base: np.ndarray) -> np.ndarray:
        xm, ym, ppm = self.xm, self.ym, self.ppm
        noise = 0.035 * self.n_lo + 0.025 * self.n_mid + 0.018 * self.n_px
        grime = np.clip(self.n_streak - 0.3, 0, None) * 0.05 + np.clip(0.8 - ym, 0, None) * 0.04
        if material == "brick":
            ch, bl = 0.075, 0.24
            course = np.floor(ym / ch).astype(np.int64)
            shift = (course % 2) * (bl / 2)
            xs = xm + shift
            block = np.floor(xs / bl).astype(np.int64)
            tone = self._block_tone(course, block, 0.12)
            dy = (ym - course * ch) * ppm
            dx = (xs - block * bl) * ppm
            mortar = np.maximum(_smooth_line(dy, 0.012 * ppm), _smooth_line(dx, 0.012 * ppm))
            tex = base[None, None, :] * (1 + tone + noise - grime)[..., None]
            mortar_col = np.array([0.72, 0.69, 0.64], np.float32)
            tex = tex * (1 - mortar[..., None]) + mortar_col * mortar[..., None] * (1 - grime)[..., None]
            return np.clip(tex, 0, 1)
        if material in ("ashlar", "stone"):
            ch = float(self.rng.uniform(0.4, 0.55))
            bl = float(self.rng.uniform(0.9, 1.4))
            course = np.floor(ym / ch).astype(np.int64)
            xs = xm + (course % 2) * bl * 0.5
            block = np.floor(xs / bl).astype(np.int64)
            tone = self._block_tone(course, block, 0.035)
            dy = (ym - course * ch) * ppm
            dx = (xs - block * bl) * ppm
            joint = np.maximum(_smooth_line(dy, 0.01 * ppm), _smooth_line(dx, 0.01 * ppm))
            tex = base[None, None, :] * (1 + tone + noise - grime - 0.12 * joint)[..., None]
            return np.clip(tex, 0, 1)
        if material in ("panels", "concrete"):
            pw = float(self.L.attributes.get("tileWidth", 2.4))
            ph = float(self.L.attributes.get("floorHeight", 3.2)) / 2
            col = np.floor(xm / pw).astype(np.int64)
            row = np.floor(ym / ph).astype(np.int64)
            tone = self._block_tone(row, col, 0.04 if material == "panels" else 0.02)
            dy = (ym - row * ph) * ppm
            dx = (xm - col * pw) * ppm
            joint = np.maximum(_smooth_line(dy, 0.015 * ppm), _smooth_line(dx, 0.015 * ppm))
            tex = base[None, None, :] * (1 + tone + noise * 1.2 - grime - 0.25 * joint)[..., None]
            return np.clip(tex, 0, 1)
        # plaster
        tex = base[None, None, :] * (1 + noise - grime)[..., None]
        return np.clip(tex, 0, 1)

    def rustic(self) -> np.ndarray:
        if self._rustic is None:
            ch = 0.45
            ym, ppm = self.ym, self.ppm
            course = np.floor(ym / ch)
            dy = (ym - course * ch) * ppm  # pixels above the groove
            groove = _smooth_line(dy - 0.02 * ppm, 0.04 * ppm)
            light = _smooth_line(dy - 0.07 * ppm, 0.04 * ppm)
            base = self.stone * 0.97
            noise = 0.06 * self.n_lo + 0.04 * self.n_mid + 0.02 * self.n_px
            tone = self._block_tone(course.astype(np.int64), np.zeros_like(course, np.int64), 0.03)
            f = 1 + noise + tone - 0.45 * groove + 0.08 * light
            self._rustic = np.clip(base[None, None, :] * f[..., None], 0, 1)
        return self._rustic

    # -- helpers ---------------------------------------------------------------------------
    def _local(self, r: LeafRect, box: Sequence[float] | None = None):
        """Normalised coordinates (u right, v down) of the leaf's pixels in ``box``."""
        x0, y0, x1, y1 = box if box is not None else (r.c0, r.r0, r.c1, r.r1)
        cols = np.arange(r.c0, r.c1, dtype=np.float32) + 0.5
        rows = np.arange(r.r0, r.r1, dtype=np.float32) + 0.5
        u = ((cols - x0) / max(x1 - x0, 1e-6))[None, :]
        v = ((rows - y0) / max(y1 - y0, 1e-6))[:, None]
        return u, v

    def _ebox(self, r: LeafRect) -> list[float]:
        if r.element >= 0:
            return self.L.elements[r.element]["rectified_box"]
        return [r.c0, r.r0, r.c1, r.r1]

    def _er(self, r: LeafRect) -> np.ndarray:
        return self.erand[r.element] if r.element >= 0 else self.erand[0]

    def _fill(self, r: LeafRect, color: np.ndarray, noise: float = 0.03) -> np.ndarray:
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        f = 1 + noise * (self.n_mid[sl] + 0.5 * self.n_px[sl])
        return np.clip(color[None, None, :] * f[..., None], 0, 1)

    def _put(self, r: LeafRect, rgb: np.ndarray, alpha: np.ndarray | None = None,
             depth: bool = True) -> None:
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        if alpha is None:
            self.img[sl] = rgb
            if depth:
                self.depth[sl] = r.depth
        else:
            a = alpha[..., None] if alpha.ndim == 2 else alpha
            self.img[sl] = self.img[sl] * (1 - a) + rgb * a
            if depth:
                self.depth[sl] = np.where(alpha > 0.5, r.depth, self.depth[sl])

    # -- materials -------------------------------------------------------------------------
    def paint(self, r: LeafRect) -> None:
        s = r.symbol
        fn = getattr(self, "p_" + s, None)
        if fn is None:
            fn = getattr(self, "l_" + r.label, self.l_other)
        fn(r)

    # walls
    def p_WallStone(self, r):
        self._put(r, self.wall_tex[r.r0:r.r1, r.c0:r.c1])

    p_Wall = p_WallStone
    p_WallPanel = p_WallStone

    def p_WallRustic(self, r):
        self._put(r, self.rustic()[r.r0:r.r1, r.c0:r.c1])

    def p_WallPlinth(self, r):
        self._put(r, np.clip(self.rustic()[r.r0:r.r1, r.c0:r.c1] * 0.8, 0, 1))

    def p_WallSpandrel(self, r):
        tone = self.stone * 0.96 if self.material != "brick" else self.wall
        self._put(r, self._fill(r, tone, 0.05))

    def p_WallNeighbour(self, r):
        e = self._er(r)
        col = _srgb(_LOOKS["residential"]["wall"][int(e[0] * 8) % 8]) * (0.7 + 0.2 * e[1])
        base = self._fill(r, col.astype(np.float32), 0.05)
        # the neighbour's own windows: a dark grid
        pitch_x = (1.8 + 1.2 * e[2]) * self.ppm
        pitch_y = (2.6 + 0.6 * e[3]) * self.ppm
        gx = ((np.arange(r.c0, r.c1) + e[4] * pitch_x) % pitch_x)[None, :] / pitch_x
        gy = ((np.arange(r.r0, r.r1) + e[5] * pitch_y) % pitch_y)[:, None] / pitch_y
        win = (np.abs(gx - 0.5) < 0.22) & (np.abs(gy - 0.45) < 0.25)
        base = np.where(win[..., None], np.array([0.18, 0.2, 0.23], np.float32), base)
        self._put(r, base)

    def l_wall(self, r):
        self.p_WallStone(r)

    # glass
    def _glass(self, r, interior_scale: float = 1.0, reflect_scale: float = 1.0):
        e = self._er(r)
        u, v = self._local(r, self._ebox(r))
        refl = (0.25 + 0.5 * e[0]) * reflect_scale
        sky = self.sky_low[None, None, :] * (1 - v[..., None]) * 0.9 + \
            self.sky_top[None, None, :] * 0.5 * v[..., None]
        streak_pos = (u + 0.6 * v) * 0.9 + e[1]
        streak = np.exp(-(((streak_pos % 1.0) - 0.5) / 0.12) ** 2) * 0.25 * e[2]
        interior = self.glass_tint * (0.35 + 0.6 * e[3]) * interior_scale
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        interior = interior[None, None, :] * (1 + 0.25 * self.n_mid[sl])[..., None]
        rgb = interior * (1 - refl) + refl * (sky * (0.6 + 0.4 * (1 - v[..., None]))) + streak[..., None]
        if e[4] < 0.45:  # curtains behind the glass
            width = 0.2 + 0.3 * e[5]
            cur = ((u < width) | (u > 1 - width)) if e[4] < 0.3 else np.ones_like(u, bool)
            cur = cur & (v > 0.02)
            col = np.array([0.86, 0.84, 0.8], np.float32) * (0.8 + 0.2 * e[6])
            a = 0.55 * (1 - refl) * cur
            rgb = rgb * (1 - a[..., None]) + col * a[..., None]
        if e[7] > 0.96:  # lights on
            rgb = rgb * 0.6 + np.array([0.95, 0.8, 0.55], np.float32) * 0.45
        return np.clip(rgb, 0, 1)

    def p_WindowGlass(self, r):
        self._put(r, self._glass(r))

    p_CurtainGlass = p_WindowGlass

    def p_DoorGlass(self, r):
        self._put(r, self._glass(r, 0.6, 0.6))

    def p_ShopGlass(self, r):
        e = self._er(r)
        u, v = self._local(r, self._ebox(r))
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        # the shop's interior: dark, with shelves (horizontal bands) and lit displays
        shelves = ((v * 5 + e[2]) % 1.0) < 0.12
        goods = np.clip(self.n_px[sl] * 0.25 + self.n_mid[sl] * 0.4, -0.3, 0.6) + 0.3
        warm = np.array([0.5, 0.44, 0.36], np.float32) * (0.5 + 0.5 * e[0])
        dark = np.array([0.09, 0.09, 0.1], np.float32)
        rgb = dark + (goods * (v > 0.3))[..., None] * warm * 0.6
        rgb = np.where(shelves[..., None], rgb * 0.6 + 0.12, rgb)
        refl = 0.2 + 0.25 * e[1]
        sky = self.sky_low[None, None, :] * (1 - 0.6 * v[..., None])
        streak = np.exp(-((((u + 0.5 * v) * 0.8 + e[3]) % 1.0 - 0.5) / 0.1) ** 2) * 0.2
        rgb = rgb * (1 - refl) + sky * refl + streak[..., None]
        self._put(r, np.clip(rgb, 0, 1))

    def p_ShopDoor(self, r):
        u, v = self._local(r)
        base = self._glass(r, 0.4, 0.6)
        bar = (_smooth_line((u - 0.85) * (r.c1 - r.c0), 1.2) * (np.abs(v - 0.5) < 0.08))
        self._put(r, base * (1 - bar[..., None]) + 0.75 * bar[..., None])

    def l_window(self, r):
        self.p_WindowGlass(r)

    # frames
    def p_WindowFrame(self, r):
        self._put(r, self._fill(r, self.frame, 0.03))

    p_WindowMullion = p_WindowFrame

    def p_DoorFrame(self, r):
        self._put(r, self._fill(r, np.clip(self.door * 0.85, 0, 1), 0.04))

    def p_ShopFrame(self, r):
        e = self._er(r)
        col = _srgb(_SIGN[int(e[0] * len(_SIGN))]) if e[1] < 0.5 else np.array([0.16, 0.16, 0.17], np.float32)
        self._put(r, self._fill(r, col.astype(np.float32) * 0.9, 0.03))

    def p_ShopPanel(self, r):
        self.p_ShopFrame(r)

    def p_ShopSign(self, r):
        e = self._er(r)
        base = _srgb(_SIGN[int(e[0] * len(_SIGN))])
        u, v = self._local(r)
        rgb = np.broadcast_to(base, (r.r1 - r.r0, r.c1 - r.c0, 3)).copy()
        # "lettering": a row of glyph-like blobs in a contrasting colour
        ink = np.array([0.95, 0.93, 0.85], np.float32) if base.mean() < 0.5 else \
            np.array([0.1, 0.1, 0.1], np.float32)
        n = max(3, int((r.c1 - r.c0) / max(2.0, 0.35 * self.ppm)))
        gx = (u * n) % 1.0
        letters = (np.abs(v - 0.5) < 0.22) & (gx > 0.15) & (gx < 0.75) & (u > 0.12) & (u < 0.88)
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        letters = letters & (self.n_px[sl] > -1.2)
        rgb[letters] = ink
        edge = (v < 0.08) | (v > 0.92)
        rgb[np.broadcast_to(edge, rgb.shape[:2])] *= 0.75
        self._put(r, np.clip(rgb, 0, 1))

    def p_ShopAwning(self, r):
        e = self._er(r)
        u, v = self._local(r)
        a = _srgb(_SIGN[int(e[0] * len(_SIGN))])
        stripes = ((u * (r.c1 - r.c0) / max(1.0, 0.25 * self.ppm)) % 2.0) < 1.0
        rgb = np.where(stripes[..., None], a, np.array([0.92, 0.9, 0.85], np.float32))
        rgb = rgb * (0.75 + 0.35 * (1 - v))[..., None]
        self._put(r, np.clip(rgb, 0, 1))

    def l_shop(self, r):
        self.p_ShopGlass(r)

    # doors
    def p_DoorLeaf(self, r):
        u, v = self._local(r)
        w, h = r.c1 - r.c0, r.r1 - r.r0
        # raised panels: two columns of stacked panels with bevelled outlines
        pu = (u * 1.0) % 1.0
        pv = (v * 3.0) % 1.0
        inset = 0.12
        edge_u = np.minimum(np.abs(pu - inset), np.abs(pu - (1 - inset))) * w
        edge_v = np.minimum(np.abs(pv - inset), np.abs(pv - (1 - inset))) * h / 3
        inside = (pu > inset) & (pu < 1 - inset) & (pv > inset) & (pv < 1 - inset)
        line = np.maximum(_smooth_line(edge_u, 1.2) * ((pv > inset) & (pv < 1 - inset)),
                          _smooth_line(edge_v, 1.2) * ((pu > inset) & (pu < 1 - inset)))
        base = self._fill(r, self.door, 0.05)
        f = 1 + 0.06 * inside - 0.35 * line
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_DoorGarage(self, r):
        u, v = self._local(r)
        h = r.r1 - r.r0
        ribs = _smooth_line(((v * h) % max(2.0, 0.12 * self.ppm)), 1.0)
        base = self._fill(r, np.clip(self.frame * 0.95, 0, 1), 0.03)
        self._put(r, np.clip(base * (1 - 0.25 * ribs)[..., None], 0, 1))

    def l_door(self, r):
        self.p_DoorLeaf(r)

    # stone work
    def _stonework(self, r, col, top_light=0.08, bottom_dark=0.2):
        u, v = self._local(r)
        base = self._fill(r, col, 0.04)
        f = 1 + top_light * (v < 0.2) - bottom_dark * (v > 0.75)
        return np.clip(base * f[..., None], 0, 1)

    def p_Molding(self, r):
        self._put(r, self._stonework(r, self.stone, 0.05, 0.08))

    def p_Sill(self, r):
        self._put(r, self._stonework(r, self.stone * 1.02, 0.1, 0.35))

    def p_Ledge(self, r):
        self._put(r, self._stonework(r, self.stone, 0.1, 0.3))

    def p_CorniceBand(self, r):
        self._put(r, self._stonework(r, self.stone * 0.98, 0.05, 0.2))

    def p_CorniceTop(self, r):
        u, v = self._local(r)
        base = self._fill(r, self.stone, 0.04)
        f = 0.7 + 0.45 * (1 - v) ** 0.7  # the overhang: bright top edge, its soffit in shade
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_CorniceDentil(self, r):
        self._put(r, self._stonework(r, self.stone * 1.03, 0.0, 0.15))

    def p_CorniceGap(self, r):
        self._put(r, self._fill(r, self.stone * 0.6, 0.03))

    def p_CorniceCoping(self, r):
        self._put(r, self._stonework(r, np.array([0.62, 0.64, 0.66], np.float32), 0.15, 0.25))

    def p_CorniceEaves(self, r):
        u, v = self._local(r)
        base = self._fill(r, np.clip(self.frame * 0.9, 0, 1), 0.03)
        f = 0.55 + 0.4 * (1 - v)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def l_cornice(self, r):
        self._put(r, self._stonework(r, self.stone, 0.1, 0.2))

    def p_DecoPediment(self, r):
        u, v = self._local(r)
        base = self._fill(r, self.stone * 1.02, 0.04)
        # a triangular pediment drawn in relief on its rectangle
        tri = np.abs(u - 0.5) * 2 < (v * 1.6)
        f = np.where(tri, 1.04, 0.9) - 0.15 * (v > 0.85)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_DecoKeystone(self, r):
        self._put(r, self._stonework(r, self.stone * 1.04, 0.06, 0.15))

    def l_deco(self, r):
        self._put(r, self._stonework(r, self.stone * 1.02, 0.08, 0.12))

    def l_molding(self, r):
        self.p_Molding(r)

    def l_sill(self, r):
        self.p_Sill(r)

    def l_pillar(self, r):
        u, v = self._local(r)
        base = self._fill(r, self.stone, 0.04)
        f = 0.9 + 0.15 * np.sin(np.pi * u)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    # balconies
    def p_BalconySlab(self, r):
        self._put(r, self._stonework(r, self.stone, 0.12, 0.45))

    def p_BalconyRailing(self, r):
        u, v = self._local(r)
        w, h = r.c1 - r.c0, r.r1 - r.r0
        xpx = u * w
        pitch = max(2.5, 0.11 * self.ppm)
        bars = _smooth_line((xpx % pitch) - pitch / 2, max(0.6, 0.022 * self.ppm))
        rail_top = _smooth_line((v - 0.04) * h, max(1.0, 0.05 * self.ppm))
        rail_low = _smooth_line((v - 0.9) * h, max(0.8, 0.03 * self.ppm))
        # wrought-iron scrolls: a sine band between the rails
        wave = _smooth_line((v - 0.5 - 0.18 * np.sin(2 * np.pi * xpx / (2 * pitch))) * h,
                            max(0.6, 0.02 * self.ppm))
        alpha = np.clip(np.maximum(np.maximum(bars, rail_top), np.maximum(rail_low, wave * 0.8)),
                        0, 1)
        alpha = np.broadcast_to(alpha, (h, w))
        self._put(r, np.broadcast_to(self.iron, (h, w, 3)), alpha)

    def p_BalconyGlass(self, r):
        u, v = self._local(r)
        h, w = r.r1 - r.r0, r.c1 - r.c0
        tint = np.clip(self.sky_low * 0.8 + 0.1, 0, 1)
        rail = _smooth_line((v - 0.03) * h, max(1.0, 0.05 * self.ppm))
        posts = _smooth_line((u * w) % max(4.0, 1.2 * self.ppm), max(0.8, 0.04 * self.ppm))
        alpha = np.clip(0.2 + 0.12 * (1 - v) + rail + posts, 0, 1)
        col = np.where((rail + posts)[..., None] > 0.5, self.iron * 1.5, tint)
        self._put(r, np.clip(col, 0, 1), np.broadcast_to(alpha, (h, w)))

    def l_balcony(self, r):
        self.p_BalconySlab(r)

    # blinds
    def p_Shutter(self, r):
        u, v = self._local(r)
        h = r.r1 - r.r0
        slat = max(1.5, 0.06 * self.ppm)
        phase = ((v * h) % slat) / slat
        f = 0.82 + 0.3 * phase
        border = (u < 0.08) | (u > 0.92) | (v < 0.04) | (v > 0.96)
        f = np.where(border, 0.92, f)
        base = self._fill(r, self.shutter, 0.04)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_RollerBlind(self, r):
        u, v = self._local(r)
        h = r.r1 - r.r0
        slat = max(1.5, 0.035 * self.ppm)
        f = 0.92 + 0.1 * (((v * h) % slat) / slat)
        f = f - 0.3 * (v > 0.93)
        base = self._fill(r, self.blind, 0.03)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    p_Blind = p_RollerBlind

    def p_BlindVenetian(self, r):
        u, v = self._local(r)
        h = r.r1 - r.r0
        slat = max(1.5, 0.08 * self.ppm)
        f = 0.75 + 0.35 * (((v * h) % slat) / slat)
        base = self._fill(r, self.blind, 0.02)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def l_blind(self, r):
        self.p_Shutter(r)

    # roofs, sky, street
    def p_RoofZinc(self, r):
        u, v = self._local(r)
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        seams = _smooth_line((self.xm[:, r.c0:r.c1] % 0.5) * self.ppm, max(0.7, 0.02 * self.ppm))
        base = self.roof[None, None, :] * (1 + 0.05 * self.n_lo[sl] + 0.03 * self.n_px[sl])[..., None]
        f = 1 + 0.12 * seams + 0.12 * (self.ym[r.r0:r.r1] / max(self.L.height_m, 1) - 0.5)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_RoofTiles(self, r):
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        ym = self.ym[r.r0:r.r1]
        row = np.floor(ym / 0.32)
        dy = (ym - row * 0.32) * self.ppm
        shade = _smooth_line(dy, max(0.8, 0.04 * self.ppm))
        xs = self.xm[:, r.c0:r.c1] + (row % 2) * 0.12
        tile = _smooth_line((xs % 0.24) * self.ppm, max(0.5, 0.015 * self.ppm))
        base = self.roof[None, None, :] * (1 + 0.08 * self.n_lo[sl] + 0.05 * self.n_mid[sl]
                                           + 0.04 * self.n_px[sl])[..., None]
        f = 1 - 0.35 * shade - 0.12 * tile
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_RoofFlat(self, r):
        self._put(r, self._fill(r, self.roof, 0.05))

    def p_RoofDormerCheek(self, r):
        self._put(r, self._fill(r, np.clip(self.roof * 1.05, 0, 1), 0.04))

    def p_RoofDormerHood(self, r):
        u, v = self._local(r)
        base = self._fill(r, np.clip(self.roof * 1.1, 0, 1), 0.04)
        self._put(r, np.clip(base * (0.8 + 0.3 * (1 - v))[..., None], 0, 1))

    def p_Chimney(self, r):
        u, v = self._local(r)
        col = self.wall if self.material != "brick" else _srgb("#8a4a35")
        base = self._fill(r, col * 0.92, 0.06)
        f = 1 - 0.35 * (v < 0.12) - 0.15 * (u > 0.7)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def l_roof(self, r):
        if self.L.style == "haussmann":
            self.p_RoofZinc(r)
        else:
            self.p_RoofTiles(r)

    def p_Sky(self, r):
        rows = np.arange(r.r0, r.r1, dtype=np.float32)[:, None] + 0.5
        t = np.clip(rows / max(1.0, float(self.sky_bottom)), 0, 1) ** 0.8
        rgb = self.sky_top[None, None, :] * (1 - t[..., None]) + self.sky_low[None, None, :] * t[..., None]
        rgb = np.broadcast_to(rgb, (r.r1 - r.r0, r.c1 - r.c0, 3)).copy()
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        cloud_amt = {"clear": 0.25, "hazy": 0.5, "overcast": 0.9}[self.sky_kind]
        clouds = np.clip(self.n_lo[sl] * 0.8 + self.n_mid[sl] * 0.3 + (cloud_amt - 0.6), 0, 1)
        rgb = rgb * (1 - clouds[..., None] * 0.7) + np.array([0.93, 0.94, 0.95]) * clouds[..., None] * 0.7
        self._put(r, np.clip(rgb, 0, 1))
        self.depth[sl] = -5.0
        self.emissive[sl] = True

    def l_sky(self, r):
        self.p_Sky(r)

    def p_Pavement(self, r):
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        col = np.array([0.5, 0.5, 0.49], np.float32)
        slabs = _smooth_line((self.xm[:, r.c0:r.c1] % 0.6) * self.ppm, 0.8)
        rgb = col[None, None, :] * (1 + 0.08 * self.n_mid[sl] + 0.06 * self.n_px[sl] - 0.15 * slabs)[..., None]
        self._put(r, np.clip(rgb, 0, 1))

    def l_ground(self, r):
        self.p_Pavement(r)

    def l_background(self, r):
        self.p_WallNeighbour(r)

    # occluders
    def p_TreeLeaves(self, r):
        sl = (slice(r.r0, r.r1), slice(r.c0, r.c1))
        clumps = self.n_mid[sl] * 0.6 + self.n_px[sl] * 0.35
        shade = np.clip(0.75 + 0.45 * clumps, 0.25, 1.3)
        holes = clumps < -0.75
        rgb = self.leaf_green[None, None, :] * shade[..., None]
        rgb = np.where(holes[..., None], rgb * 0.45, rgb)
        self._put(r, np.clip(rgb, 0, 1))

    p_PlantHedge = p_TreeLeaves

    def p_TreeTrunk(self, r):
        self._put(r, self._fill(r, np.array([0.3, 0.26, 0.22], np.float32), 0.12))

    def l_vegetation(self, r):
        self.p_TreeLeaves(r)

    def p_CarBody(self, r):
        e = self._er(r)
        col = _srgb(_CAR[int(e[0] * len(_CAR))])
        y0, y1 = self._ebox(r)[1], self._ebox(r)[3]
        v = (np.arange(r.r0, r.r1, dtype=np.float32)[:, None] + 0.5 - y0) / max(y1 - y0, 1)
        base = self._fill(r, col, 0.02)
        f = 1.0 + 0.25 * np.exp(-((v - 0.45) / 0.04) ** 2) - 0.3 * (v > 0.82)
        self._put(r, np.clip(base * f[..., None], 0, 1))

    def p_CarGlass(self, r):
        u, v = self._local(r)
        rgb = np.array([0.16, 0.19, 0.22], np.float32)[None, None, :] + \
            (0.25 * (1 - v) * (u > 0.3))[..., None] * self.sky_low
        self._put(r, np.clip(np.broadcast_to(rgb, (r.r1 - r.r0, r.c1 - r.c0, 3)), 0, 1))

    def p_CarWheel(self, r):
        u, v = self._local(r)
        d = np.sqrt((u - 0.5) ** 2 + (v - 0.35) ** 2)
        rgb = np.where((d < 0.22)[..., None], np.array([0.5, 0.5, 0.52], np.float32),
                       np.array([0.07, 0.07, 0.08], np.float32))
        self._put(r, np.broadcast_to(rgb, (r.r1 - r.r0, r.c1 - r.c0, 3)).copy())

    def l_other(self, r):
        self._put(r, self._fill(r, np.array([0.35, 0.35, 0.36], np.float32), 0.08))

    # -- lighting --------------------------------------------------------------------------
    def shade(self) -> np.ndarray:
        rng, ppm = self.rng, self.ppm
        sunny = self.sky_kind != "overcast" and rng.random() < 0.8
        depth = np.clip(self.depth, -1.0, 1.5)
        facade = ~self.emissive
        shadow = np.zeros((self.h, self.w), np.float32)
        if sunny:
            lx = float(rng.uniform(-0.8, 0.8))
            ly = float(rng.uniform(0.6, 1.3))
            step = 1.0 / (ppm * max(abs(lx), ly))
            dmax = float(depth[facade].max() - depth[facade].min()) if facade.any() else 0.0
            # a pixel is in shadow when a part nearer the viewer by at least t stands t * (lx,
            # ly) metres towards the sun from it
            shifted = np.empty_like(depth)
            t = step
            while t <= dmax + 1e-6:
                dx, dy = int(round(t * lx * ppm)), int(round(t * ly * ppm))
                if abs(dx) >= self.w or dy >= self.h:
                    break
                shifted.fill(-10.0)
                shifted[dy:, max(dx, 0):self.w + min(dx, 0)] = \
                    depth[:self.h - dy, max(-dx, 0):self.w - max(dx, 0)]
                shadow = np.maximum(shadow, (shifted - depth >= t - 1e-4).astype(np.float32))
                t += step
            # the shadow of the building across the street
            if rng.random() < 0.3:
                slope = float(rng.uniform(-0.35, 0.35))
                y_line = self.h * float(rng.uniform(0.45, 0.9)) + \
                    slope * (np.arange(self.w)[None, :] - self.w / 2)
                rows = np.arange(self.h)[:, None]
                shadow = np.maximum(shadow, (rows > y_line).astype(np.float32))
            shadow = ndimage.gaussian_filter(shadow, 0.6 + 0.02 * ppm)
            direct, ambient = float(rng.uniform(0.55, 0.75)), float(rng.uniform(0.4, 0.55))
        else:
            direct, ambient = 0.15, float(rng.uniform(0.85, 1.0))
        ao = np.clip(ndimage.gaussian_filter(depth, 0.15 * ppm) - depth, 0, 0.6) / 0.6
        ao = ao * facade
        warm = np.array([1.0, 0.96, 0.88], np.float32)
        cool = np.array([0.92, 0.96, 1.04], np.float32)
        light = (ambient * cool[None, None, :] + direct * (1 - shadow)[..., None] * warm) * \
            (1 - 0.55 * ao)[..., None]
        out = np.where(facade[..., None], self.img * light, self.img)
        return np.clip(out, 0, 1)


def render_photo(layout: SyntheticFacade, rng: np.random.Generator) -> np.ndarray:
    """Photo-like float RGB image (H, W, 3) in 0..1 of a layout, before perspective and camera
    effects: materials per leaf (vectorised per shape), then shading from the depth map."""
    p = _Painter(layout, rng)
    for r in layout.leaves:
        p.paint(r)
    return p.shade()


# ================================================================================ camera
def homography_from_points(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The 3×3 homography mapping four points ``src`` (4, 2) onto ``dst`` (4, 2), ``H[2, 2] = 1``."""
    a, b = [], []
    for (x, y), (u, v) in zip(np.asarray(src, float), np.asarray(dst, float)):
        a.append([x, y, 1, 0, 0, 0, -u * x, -u * y])
        b.append(u)
        a.append([0, 0, 0, x, y, 1, -v * x, -v * y])
        b.append(v)
    h = np.linalg.solve(np.array(a), np.array(b))
    return np.append(h, 1.0).reshape(3, 3)


def _random_homography(rng: np.random.Generator, w: int, h: int) -> np.ndarray:
    """A mild street-level view: keystone (looking up), yaw, roll and zoom."""
    src = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    dst = src.copy()
    k = rng.uniform(0.0, 0.12) * w  # looking up: the top is narrower
    dst[0, 0] += k
    dst[1, 0] -= k
    yaw = rng.uniform(-0.08, 0.08) * h  # one side nearer than the other
    if yaw > 0:
        dst[0, 1] += yaw
        dst[3, 1] -= yaw * 0.4
    else:
        dst[1, 1] -= yaw
        dst[2, 1] += yaw * 0.4
    ang = math.radians(rng.uniform(-2.0, 2.0))
    scale = rng.uniform(0.92, 1.08)
    c = np.array([w / 2, h / 2])
    rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    dst = (dst - c) @ rot.T * scale + c + rng.uniform(-0.03, 0.03, 2) * [w, h]
    return homography_from_points(src, dst)


def _inverse_coords(homography: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Source coordinates (pixel-edge convention) of every output pixel centre."""
    h, w = shape
    inv = np.linalg.inv(homography)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    pts = np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    src = inv @ pts
    return (src[0] / src[2]).reshape(h, w), (src[1] / src[2]).reshape(h, w)


def warp_labels(labels: np.ndarray, homography: np.ndarray, shape: tuple[int, int] | None = None,
                fill: int = 0) -> np.ndarray:
    """Resample a label map through ``homography`` (source → output pixel coordinates), nearest
    neighbour at output pixel centres; output pixels that map outside the source get ``fill``."""
    labels = np.asarray(labels)
    shape = labels.shape[:2] if shape is None else shape
    sx, sy = _inverse_coords(homography, shape)
    ix, iy = np.floor(sx).astype(np.int64), np.floor(sy).astype(np.int64)
    inside = (ix >= 0) & (ix < labels.shape[1]) & (iy >= 0) & (iy < labels.shape[0])
    out = np.full(shape, fill, labels.dtype)
    out[inside] = labels[iy[inside], ix[inside]]
    return out


def _warp_photo(img: np.ndarray, homography: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    h, w = img.shape[:2]
    sx, sy = _inverse_coords(homography, (h, w))
    # above the facade: more of the top row (the sky band), not a mirror image of the facade
    coords = [np.maximum(sy, 0.5) - 0.5, sx - 0.5]
    out = np.stack([ndimage.map_coordinates(img[..., k], coords, order=1, mode="mirror")
                    for k in range(3)], axis=-1)
    # beyond the facade: neighbouring buildings (mirrored, re-tinted) and the street below
    side = (sx < 0) | (sx >= w)
    tint = rng.uniform(0.8, 1.1, 3).astype(np.float32)
    out = np.where(side[..., None], out * tint, out)
    below = sy >= h
    street = np.array([0.42, 0.42, 0.41], np.float32) * (1 + 0.05 * rng.standard_normal((h, w, 1)))
    out = np.where(below[..., None], street, out)
    return np.clip(out, 0, 1).astype(np.float32)


def _camera(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Lens blur, vignetting, white balance and exposure, sensor noise; returns uint8."""
    h, w = img.shape[:2]
    sigma = float(rng.uniform(0.3, 0.8)) * max(1.0, w / 640)
    img = np.stack([ndimage.gaussian_filter(img[..., k], sigma) for k in range(3)], axis=-1)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((xx - w / 2) / (w / 2)) ** 2 + ((yy - h / 2) / (h / 2)) ** 2
    img = img * (1 - float(rng.uniform(0.08, 0.3)) * r2 / 2)[..., None]
    wb = np.array([rng.uniform(0.94, 1.06), 1.0, rng.uniform(0.92, 1.06)], np.float32)
    img = img * wb * float(rng.uniform(0.88, 1.12))
    img = np.clip(img, 0, 1) ** float(rng.uniform(0.9, 1.1))
    noise = float(rng.uniform(0.006, 0.025))
    img = img + rng.standard_normal(img.shape).astype(np.float32) * noise * (0.5 + img)
    return np.clip(np.rint(img * 255), 0, 255).astype(np.uint8)


def _jpeg_bytes(img: np.ndarray, quality: int) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(img, "RGB").save(buf, format="JPEG", quality=int(quality), subsampling=2,
                                     optimize=False, progressive=False)
    return buf.getvalue()


# ================================================================================ generator
def _rng(seed: int, index: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([abs(int(seed)), int(seed < 0),
                                                         int(index)]))


def _warp_box(box: Sequence[float], hmat: np.ndarray, w: int, h: int) -> list[float] | None:
    x0, y0, x1, y1 = box
    pts = np.array([[x0, y0, 1], [x1, y0, 1], [x1, y1, 1], [x0, y1, 1]], float) @ hmat.T
    xy = pts[:, :2] / pts[:, 2:3]
    bx0, by0 = np.clip(xy.min(axis=0), 0, [w, h])
    bx1, by1 = np.clip(xy.max(axis=0), 0, [w, h])
    if bx1 - bx0 < 1e-6 or by1 - by0 < 1e-6:
        return None
    return [round(float(bx0), 3), round(float(by0), 3), round(float(bx1), 3), round(float(by1), 3)]


#: Prefix of the folder a run of :func:`generate` writes its files into before renaming each
#: into place (``.facadeforge-synth-<host>-<pid>-<random>``, :func:`~facadeforge.scratch.scratch_dir`).
STAGE_PREFIX = ".facadeforge-synth-"


def _write(stage: Path, path: Path, data: bytes) -> None:
    """Write ``path`` whole or not at all: the bytes go to a file in this run's ``stage``
    folder (beside ``path``: same file system), which is then renamed onto ``path``."""
    tmp = stage / path.name
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _json_bytes(obj: Any, indent: int | None = None) -> bytes:
    # compact by default: the C encoder only runs without indentation (trees are large)
    text = json.dumps(obj, indent=indent, sort_keys=True, allow_nan=False,
                      separators=(",", ":") if indent is None else None)
    return (text + "\n").encode()


def generate(n: int, seed: int, out_dir: str | Path, size: tuple[int, int] | int | None = None,
             px_per_m: float | None = None, perspective: bool = False,
             styles: Iterable[str] | None = None, start: int = 0) -> list[Path]:
    """Write ``n`` synthetic facades (photo, label PNG, tree, objects, metadata) to ``out_dir``.

    Parameters
    ----------
    n : int
        Number of facades.
    seed : int
        Run seed; facade ``i`` uses a random stream made from ``(seed, i)`` only, so runs are
        reproducible byte for byte and ``generate(5, s)`` writes the first 5 of
        ``generate(10, s)``.
    out_dir : str or Path
        Output folder (created).
    size : (W, H) or int, optional
        Exact image size, or the image width in pixels (the height follows from the facade).
        Default: 480 pixels wide, unless ``px_per_m`` is given.
    px_per_m : float, optional
        Resolution in pixels per metre (the image size follows from the facade size).
    perspective : bool
        Apply a random homography to photo and labels (recorded in the metadata).
    styles : iterable of str, optional
        Styles to draw from (default: all of :data:`STYLES`).
    start : int
        Index of the first facade (``NAME`` numbering and random streams).

    Returns
    -------
    list of Path
        The photos (``NAME.jpg``), in order.
    """
    if n < 0:
        raise InputError(f"number of facades must be >= 0, got {n}")
    pool = tuple(styles) if styles else STYLES
    for s in pool:
        grammar_path(s)
    if size is not None and not isinstance(size, (int, np.integer)):
        size = (int(size[0]), int(size[1]))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # every file is written in a folder of this run's own and renamed into place whole: a run
    # that is killed leaves no half-written file under a final name nor a temporary name that
    # the next run would reuse; the folder goes at the end, on an error or SIGTERM (the CLI
    # makes it an exit), and after a SIGKILL with the next run (scratch_dir removes the
    # folders of dead processes)
    stage = scratch_dir(STAGE_PREFIX, dir=out)
    try:
        return _generate(n, seed, out, stage, size, px_per_m, perspective, pool, start)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _generate(n: int, seed: int, out: Path, stage: Path, size, px_per_m, perspective: bool,
              pool: tuple, start: int) -> list[Path]:
    """:func:`generate`'s facades, each file written through ``stage``."""
    from ..exchange.raster import LABEL_INDEX, write_label_png

    written = []
    for i in range(start, start + n):
        rng = _rng(seed, i)
        style = pool[int(rng.integers(0, len(pool)))]
        layout = make_facade(style, rng, size=size, px_per_m=px_per_m)
        h, w = layout.height_px, layout.width_px
        labels = layout.label_map()
        photo = render_photo(layout, rng)
        hmat = None
        if perspective:
            hmat = _random_homography(rng, w, h)
            photo = _warp_photo(photo, hmat, rng)
            labels = warp_labels(labels, hmat, (h, w), fill=LABEL_INDEX["background"])
        img = _camera(photo, rng)
        quality = int(rng.integers(70, 93))
        name = f"synth_{seed}_{i:04d}"
        objects = []
        for e in layout.elements:
            if e["label"] not in OBJECT_LABELS:
                continue
            box = e["rectified_box"] if hmat is None else _warp_box(e["rectified_box"], hmat, w, h)
            if box is None:
                continue
            objects.append({**e, "box": box})
        floors, columns = _counts(layout)
        meta = {
            "name": name, "style": style, "seed": int(seed), "index": int(i),
            "cga_seed": layout.cga_seed, "grammar": f"{style}.cga",
            "attributes": layout.attributes,
            "facade_size_m": [round(layout.width_m, 6), round(layout.height_m, 6)],
            "image_size": [w, h], "metres_per_pixel": [layout.width_m / w, layout.height_m / h],
            "px_per_m": layout.px_per_m,
            "homography": None if hmat is None else [[float(v) for v in row] for row in hmat],
            "homography_maps": "rectified pixel (x, y) -> photo pixel (x, y), pixel centres at "
                               "+0.5" if hmat is not None else None,
            "label_encoding": "canonical", "classes": list(LABEL_INDEX),
            "jpeg_quality": quality, "floors": floors, "columns": columns,
            "n_objects": len(objects), "warnings": layout.warnings,
        }
        _write(stage, out / f"{name}.jpg", _jpeg_bytes(img, quality))
        write_label_png(labels, stage / f"{name}.png")
        os.replace(stage / f"{name}.png", out / f"{name}.png")
        _write(stage, out / f"{name}.tree.json", _json_bytes(layout.tree.to_dict()))
        _write(stage, out / f"{name}.objects.json", _json_bytes(objects))
        _write(stage, out / f"{name}.meta.json", _json_bytes(meta, indent=1))
        written.append(out / f"{name}.jpg")
    return written


# ================================================================================ loader
def _synthetic_boxes(sample: FacadeSample) -> list[ObjectBox]:
    path = Path(sample.meta["objects_path"])
    fix = "regenerate the facade with facadeforge synth"
    data = read_json(path, "synthetic objects", fix=fix)
    try:
        boxes = [(str(o["label"]), [float(v) for v in o["box"]]) for o in data]
    except (KeyError, TypeError, ValueError, OverflowError):
        boxes = None
    if boxes is None or any(len(b) != 4 for _, b in boxes):
        raise InputError(f"synthetic objects {path} must list {{\"label\", \"box\": [x0, y0, x1, "
                         f"y1]}} objects; {fix}")
    return [ObjectBox(label, *box) for label, box in boxes]


def load_synthetic(root: str | Path, label_set: LabelSet | str = "cmp6") -> list[FacadeSample]:
    """Load a folder written by :func:`generate` (``facadeforge synth``).

    Parameters
    ----------
    root : str or Path
        The folder of ``NAME.jpg``, ``NAME.png``, ``NAME.objects.json``, ``NAME.meta.json``.
    label_set : LabelSet or str
        Classes to return labels in (default ``cmp6``); the canonical label PNG is mapped through
        :meth:`LabelSet.from_canonical`.

    Returns
    -------
    list of FacadeSample
        Sorted by id (``NAME``); ``objects()`` are the element rectangles from
        ``NAME.objects.json`` (canonical labels, photo pixels); ``meta`` has ``dataset``,
        ``style``, ``floors``, ``columns``, ``homography``, ``rectified`` (no homography: the
        photo is front-on, as CMP's are), ``metres_per_pixel`` and the paths.

    Raises
    ------
    InputError
        Missing folder, no facades, a photo without its label PNG or metadata.
    """
    target = get_label_set(label_set)
    root = _check_folder(root, "synthetic", "pass the folder written by facadeforge synth -o DIR")
    photos = sorted(p for p in root.glob("*.jpg") if p.is_file())
    if not photos:
        raise InputError(f"synthetic folder {root} has no .jpg photos; write some with "
                         f"'facadeforge synth -n N --seed S -o {root}'")

    def decode(raw: np.ndarray) -> np.ndarray:
        if raw.ndim == 3:
            from ..exchange.raster import LABEL_INDEX, PALETTE

            canon = get_label_set(LabelSet("canonical", tuple(LABEL_INDEX), PALETTE,
                                           {i: i for i in range(len(LABEL_INDEX))}))
            return target.from_canonical(canon.from_color(raw))
        return target.from_canonical(
            np.where(raw < len(CANONICAL_INDEX), raw, 255).astype(np.uint8))

    samples = []
    for photo in photos:
        stem = photo.stem
        label = photo.with_suffix(".png")
        meta_path = root / f"{stem}.meta.json"
        objects_path = root / f"{stem}.objects.json"
        for p, what in ((label, "label PNG"), (meta_path, "metadata")):
            if not p.is_file():
                raise InputError(f"synthetic photo {photo} has no {what} {p.name}; regenerate "
                                 "the folder with facadeforge synth")
        meta = read_json(meta_path, "synthetic metadata",
                         fix="regenerate the folder with facadeforge synth")
        if not isinstance(meta, dict):
            raise InputError(f"synthetic metadata {meta_path} must hold a JSON object; "
                             "regenerate the folder with facadeforge synth")
        info = {"dataset": "synthetic", "label_path": str(label), "meta_path": str(meta_path),
                "objects_path": str(objects_path) if objects_path.is_file() else None,
                "objects_from": "tree" if objects_path.is_file() else "components",
                "style": meta.get("style"), "floors": meta.get("floors"),
                "columns": meta.get("columns"), "homography": meta.get("homography"),
                # rendered front-on unless written with --perspective: methods must treat the
                # photo as rectified (CMP's conventions), not as a street photo to rectify
                "rectified": meta.get("homography") is None,
                "metres_per_pixel": meta.get("metres_per_pixel")}
        samples.append(FacadeSample(
            id=stem, image_path=photo, label_path=label, label_set=target, meta=info,
            decode=decode, boxes=_synthetic_boxes if objects_path.is_file() else None))
    return samples


# ================================================================================ CLI
EXAMPLES = """examples:
  facadeforge synth -n 20 --seed 1 -o synth/
  facadeforge synth -n 8 --seed 7 --style haussmann --style modern --width-px 640 -o synth/
  facadeforge synth -n 50 --seed 3 --perspective -o synth-persp/
  facadeforge bench --method prior --dataset synthetic --data synth/ -o result.json"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``synth`` subcommand to an ``argparse`` subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "synth", help="write synthetic facade photos with exact ground truth",
        description="Derive random facade layouts from parametric CGA facade grammars and render "
                    "photo-like images; per facade NAME.jpg, NAME.png (canonical label indices), "
                    "NAME.tree.json, NAME.objects.json, NAME.meta.json.",
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-n", type=int, default=10, metavar="N", help="number of facades (default 10)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="run seed (default 0)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    p.add_argument("--perspective", action="store_true",
                   help="random homography on photo and labels (stored in NAME.meta.json)")
    p.add_argument("--style", action="append", choices=STYLES, default=None, metavar="NAME",
                   help=f"style to draw from, repeatable ({', '.join(STYLES)}; default all)")
    p.add_argument("--width-px", type=int, default=DEFAULT_WIDTH_PX, metavar="W",
                   help=f"image width in pixels (default {DEFAULT_WIDTH_PX})")
    return p


def cmd_synth(args: argparse.Namespace) -> int:
    """Run :func:`generate` from parsed arguments and print a one-line summary."""
    t0 = time.perf_counter()
    if args.n < 0:
        raise InputError(f"-n must be >= 0, got {args.n}")
    if args.width_px < 8:
        raise InputError(f"--width-px must be at least 8, got {args.width_px}")
    paths = generate(args.n, args.seed, args.output, size=args.width_px,
                     perspective=args.perspective, styles=args.style)
    counts: dict[str, int] = {}
    for p in paths:
        style = json.loads(p.with_suffix(".meta.json").read_text())["style"]
        counts[style] = counts.get(style, 0) + 1
    mix = ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) or "none"
    print(f"wrote {len(paths)} synthetic facades ({mix}; seed {args.seed}"
          f"{', perspective' if args.perspective else ''}) to {args.output} in "
          f"{time.perf_counter() - t0:.1f} s")
    return 0
