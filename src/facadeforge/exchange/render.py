"""CPU preview renderer: a shaded 3/4 view of models as a PIL image, no display and no GPU.

Faces are drawn as polygons with Pillow, back to front (painter's algorithm on face centroid
depth), with flat Lambert shading from a sun plus sky ambient, material colours (a texture is
approximated by its mean colour, computed once per file), thin darker outlines on faces large
enough to show them, a soft ground shadow and a sky gradient.  The picture is drawn at
``supersample`` times the size and reduced, which anti-aliases edges.  All geometry work is
vectorised with numpy; the per-face cost is one Pillow call, so a few hundred thousand faces
render in seconds.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ..model.model import Model
from ._common import Staging, as_models, face_corners, mean_texture_color
from .errors import ExportError

__all__ = ["render_file", "render_preview"]

_SKY_TOP = np.array([158.0, 194.0, 230.0])
_SKY_HORIZON = np.array([236.0, 241.0, 246.0])
_GROUND = (226, 226, 218)
_SHADOW = (150, 152, 160)


@dataclass
class _Faces:
    """All faces of the scene flattened: corners (C, 3), face offsets (F + 1,), colours (F, 4)."""

    corners: np.ndarray
    offsets: np.ndarray
    rgba: np.ndarray

    @property
    def count(self) -> int:
        return len(self.offsets) - 1

    def sums(self, values: np.ndarray) -> np.ndarray:
        """Per-face sums of a per-corner quantity."""
        return np.add.reduceat(values, self.offsets[:-1], axis=0)


@dataclass
class _Camera:
    eye: np.ndarray
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray
    perspective: bool

    def view(self, points: np.ndarray) -> np.ndarray:
        """World points (N, 3) → camera coordinates (N, 3): x right, y up, z depth."""
        rel = points - self.eye
        return np.column_stack([rel @ self.right, rel @ self.up, rel @ self.forward])

    def project(self, points: np.ndarray) -> np.ndarray:
        v = self.view(points)
        if not self.perspective:
            return v[:, :2]
        return v[:, :2] / np.maximum(v[:, 2:3], 1e-9)


# -- public -----------------------------------------------------------------------------------

def render_preview(models: Model | Sequence[Model], path: str | os.PathLike | None = None,
                   size: tuple[int, int] = (1200, 900), azimuth: float = -35.0,
                   elevation: float = 25.0, *, perspective: bool = True, fov: float = 35.0,
                   outlines: bool = True, shadow: bool = True, supersample: int = 2,
                   ) -> Image.Image:
    """Render a 3/4 preview of models.

    Parameters
    ----------
    models : Model or sequence of Model
        What to draw (all parts of all models).
    path : path-like or None
        Where to save the picture as PNG (atomically); ``None`` to only return it.
    size : (width, height)
        Picture size in pixels.
    azimuth, elevation : float
        Viewing direction in degrees: the camera sits at ``azimuth`` around the vertical axis,
        measured from +z (the front) towards +x, and ``elevation`` above the horizon.  The
        default looks from the front-left, above.
    perspective : bool
        Perspective (``fov`` degrees) or orthographic projection.
    outlines : bool
        Draw thin darker outlines around faces that are large on screen.
    shadow : bool
        Draw the ground and the sun shadow of the models on it.
    supersample : int
        Drawing scale factor for anti-aliasing.

    Returns
    -------
    PIL.Image.Image
        RGB picture of ``size``; the camera is fitted to the models' bounding box.
    """
    width, height = (int(v) for v in size)
    if width < 1 or height < 1 or supersample < 1:
        raise ExportError(f"invalid picture size {size} or supersample {supersample}")
    faces = _scene_faces(as_models(models))
    ss = int(supersample)
    image = _sky(width * ss, height * ss)
    if faces.count:
        _draw_scene(image, faces, azimuth, elevation, perspective, fov, outlines, shadow)
    if ss > 1:
        image = image.reduce(ss)
    if path is not None:
        buf = io.BytesIO()
        image.save(buf, format="PNG")
        with Staging() as stage:
            stage.write_bytes(path, buf.getvalue())
    return image


def render_file(model_path: str | os.PathLike, out_png: str | os.PathLike,
                **options) -> Image.Image:
    """Load a model file with the registered importers and render its preview to ``out_png``.

    Parameters
    ----------
    model_path : path-like
        A file with a registered importer (``.glb``, ``.obj``, ``.city.json``).
    out_png : path-like
        Destination PNG.
    **options
        Passed to :func:`render_preview` (``size``, ``azimuth``, ``elevation``…).
    """
    from . import load

    return render_preview(load(model_path), out_png, **options)


# -- scene ------------------------------------------------------------------------------------

def _scene_faces(models: list[Model]) -> _Faces:
    corners, offsets, colors = [], [0], []
    for model in models:
        for part in model.parts:
            flat, starts = face_corners(part.mesh)
            sizes = np.diff(starts)
            good = sizes >= 3
            if not good.any():
                continue
            corners.append(part.mesh.vertices[flat[np.repeat(good, sizes)]])
            offsets.extend((np.cumsum(sizes[good]) + offsets[-1]).tolist())
            colors.append(np.tile(_part_rgba(part.material), (int(good.sum()), 1)))
    if len(offsets) == 1:
        return _Faces(np.zeros((0, 3)), np.zeros(1, np.int64), np.zeros((0, 4)))
    return _Faces(np.concatenate(corners), np.asarray(offsets, np.int64), np.concatenate(colors))


def _part_rgba(material) -> np.ndarray:
    rgb = np.clip(np.asarray(material.color, float), 0.0, 1.0)
    tex = mean_texture_color(material.texture)
    if tex is not None:
        rgb = rgb * tex
    return np.array([*rgb, np.clip(material.opacity, 0.0, 1.0)])


def _camera(lo: np.ndarray, hi: np.ndarray, azimuth: float, elevation: float,
            perspective: bool, fov: float) -> _Camera:
    center = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
    az, el = np.radians(azimuth), np.radians(np.clip(elevation, -89.0, 89.0))
    back = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    forward = -back
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    dist = radius / np.sin(np.radians(fov) / 2) * 1.05 if perspective else radius * 4
    return _Camera(center + back * dist, right, up, forward, perspective)


def _sun(azimuth: float) -> np.ndarray:
    """Sun direction (towards the sun): 60° to the right of the camera, 50° high."""
    az, el = np.radians(azimuth + 60.0), np.radians(50.0)
    return np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])


def _normals(faces: _Faces) -> np.ndarray:
    """Unit face normals (F, 3) by Newell's method on the flattened corners."""
    p = faces.corners
    nxt = np.arange(1, len(p) + 1)
    nxt[faces.offsets[1:] - 1] = faces.offsets[:-1]
    q = p[nxt]
    terms = np.column_stack([(p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2]),
                             (p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0]),
                             (p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1])])
    n = faces.sums(terms)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def _shade(faces: _Faces, cam: _Camera, sun: np.ndarray) -> np.ndarray:
    """RGBA fill colours (F, 4) in 0–255: sky ambient plus Lambert sun, both sides lit."""
    n = _normals(faces)
    sizes = np.diff(faces.offsets)[:, None]
    centroid = faces.sums(faces.corners) / sizes
    to_eye = cam.eye - centroid if cam.perspective else -cam.forward[None, :]
    n = np.where(np.sum(n * to_eye, axis=1, keepdims=True) < 0, -n, n)
    light = 0.5 + 0.1 * n[:, 1] + 0.5 * np.clip(n @ sun, 0.0, None)
    rgb = np.clip(faces.rgba[:, :3] * light[:, None], 0.0, 1.0) * 255
    return np.column_stack([rgb, faces.rgba[:, 3] * 255]).round().astype(np.int64)


# -- drawing ----------------------------------------------------------------------------------

def _sky(width: int, height: int) -> Image.Image:
    t = np.linspace(0.0, 1.0, height)[:, None] ** 0.7
    rows = (_SKY_TOP * (1 - t) + _SKY_HORIZON * t).astype(np.uint8)
    return Image.fromarray(np.repeat(rows[:, None, :], width, axis=1))


def _draw_scene(image: Image.Image, faces: _Faces, azimuth: float, elevation: float,
                perspective: bool, fov: float, outlines: bool, shadow: bool) -> None:
    lo, hi = faces.corners.min(axis=0), faces.corners.max(axis=0)
    cam = _camera(lo, hi, azimuth, elevation, perspective, fov)
    sun = _sun(azimuth)
    shadow_pts = _shadow_points(faces.corners, sun, lo[1]) if shadow else None
    fit_pts = faces.corners if shadow_pts is None else np.concatenate([faces.corners, shadow_pts])
    to_screen = _fit(cam, fit_pts, image.size)
    if shadow:
        _draw_ground(image, cam, to_screen, lo, hi)
        _draw_shadow(image, faces, to_screen(shadow_pts))
    screen = to_screen(faces.corners)
    order = _paint_order(faces, cam)
    _draw_faces(image, faces, screen, _shade(faces, cam, sun), order, outlines)


def _paint_order(faces: _Faces, cam: _Camera) -> np.ndarray:
    """Back-to-front face order: by farthest corner, then by mean depth.

    Sorting on the farthest corner draws a large face (a wall) before the small faces lying on
    or just in front of it (windows, sills, signs), which sorting on centroids gets wrong.
    """
    depth = cam.view(faces.corners)[:, 2]
    far = np.maximum.reduceat(depth, faces.offsets[:-1])
    mean = faces.sums(depth) / np.diff(faces.offsets)
    return np.lexsort((-mean, -far))


def _fit(cam: _Camera, points: np.ndarray, size: tuple[int, int], margin: float = 0.06):
    """A function mapping world points to pixel coordinates that frames ``points``."""
    xy = cam.project(points)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = np.maximum(hi - lo, 1e-9)
    w, h = size
    scale = min(w * (1 - 2 * margin) / span[0], h * (1 - 2 * margin) / span[1])
    mid = (lo + hi) / 2

    def to_screen(p: np.ndarray) -> np.ndarray:
        q = (cam.project(p) - mid) * scale
        return np.column_stack([w / 2 + q[:, 0], h / 2 - q[:, 1]])

    return to_screen


def _shadow_points(points: np.ndarray, sun: np.ndarray, ground: float) -> np.ndarray:
    """Points pushed along the sun direction onto the plane ``y = ground``."""
    return points - sun[None, :] * ((points[:, 1] - ground) / sun[1])[:, None]


def _draw_ground(image: Image.Image, cam: _Camera, to_screen, lo: np.ndarray,
                 hi: np.ndarray) -> None:
    """A soft-edged ground disc under the models."""
    center = (lo + hi) / 2
    radius = max(hi[0] - lo[0], hi[2] - lo[2]) * 0.9 + 0.5 * (hi[1] - lo[1])
    mask = Image.new("L", image.size, 0)
    draw = ImageDraw.Draw(mask)
    for scale in np.linspace(1.6, 0.8, 9):
        value = int(255 * (1.6 - scale) / 0.8)
        ang = np.linspace(0, 2 * np.pi, 96, endpoint=False)
        ring = np.column_stack([center[0] + scale * radius * np.cos(ang),
                                np.full_like(ang, lo[1]),
                                center[2] + scale * radius * np.sin(ang)])
        if np.any(cam.view(ring)[:, 2] <= 1e-6):
            continue
        draw.polygon(to_screen(ring).ravel().tolist(), fill=value)
    image.paste(Image.new("RGB", image.size, _GROUND), mask=mask)


def _draw_shadow(image: Image.Image, faces: _Faces, screen: np.ndarray) -> None:
    mask = Image.new("L", image.size, 0)
    draw = ImageDraw.Draw(mask)
    flat = screen.ravel().tolist()
    off = (faces.offsets * 2).tolist()
    for i in range(faces.count):
        draw.polygon(flat[off[i]:off[i + 1]], fill=255)
    mask = mask.point(lambda v: v * 140 // 255)
    image.paste(Image.new("RGB", image.size, _SHADOW), mask=mask)


def _draw_faces(image: Image.Image, faces: _Faces, screen: np.ndarray, rgba: np.ndarray,
                order: np.ndarray, outlines: bool) -> None:
    draw = ImageDraw.Draw(image, "RGBA")
    flat = screen.ravel().tolist()
    off = (faces.offsets * 2).tolist()
    fills = [tuple(c) for c in rgba.tolist()]
    lines = _outline_colors(faces, screen, rgba, image.size) if outlines else None
    for i in order.tolist():
        coords = flat[off[i]:off[i + 1]]
        outline = None if lines is None else lines[i]
        draw.polygon(coords, fill=fills[i], outline=outline)


def _outline_colors(faces: _Faces, screen: np.ndarray, rgba: np.ndarray,
                    size: tuple[int, int]) -> list:
    """Darker edge colour for faces big enough on screen, ``None`` for the others."""
    lo = np.minimum.reduceat(screen, faces.offsets[:-1], axis=0)
    hi = np.maximum.reduceat(screen, faces.offsets[:-1], axis=0)
    extent = hi - lo
    min_side = max(size) / 250
    big = (extent.min(axis=1) > min_side) & (rgba[:, 3] > 0)
    dark = rgba.copy()
    dark[:, :3] = (rgba[:, :3] * 0.62).astype(np.int64)
    dark[:, 3] = np.maximum(rgba[:, 3], 160)
    return [tuple(c) if b else None for c, b in zip(dark.tolist(), big.tolist())]
