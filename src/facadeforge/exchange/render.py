"""CPU preview renderer: a shaded 3/4 view of models as a PIL image, no display and no GPU.

Faces are triangulated and rasterised with a numpy depth buffer (:mod:`._zbuffer`, no Python
loop over triangles or pixels), shaded flat with a sun (Lambert) plus sky ambient, in their
material colours; textured faces are sampled per pixel at their perspective-correct UVs (nearest
texel, UVs wrap), so a reconstructed facade shows its photo.
Translucent materials are blended over the nearest opaque surface.  Thin darker outlines follow
face boundaries, a soft ground disc receives the sun shadow of the models, and the sky is a
gradient.  The picture is computed at ``supersample`` times the size and reduced, which
anti-aliases edges.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageDraw

from ..model.model import Model
from ._common import (
    Staging,
    as_models,
    corner_uvs,
    face_corners,
    mean_texture_color,
    texture_pixels,
    triangulate_corners,
)
from ._zbuffer import rasterize
from .errors import ExportError

__all__ = ["render_file", "render_preview"]

#: Textured pixels processed per chunk (about 200 bytes of temporaries each).
_TEXEL_CHUNK = 1_000_000
_SKY_TOP = np.array([158.0, 194.0, 230.0])
_SKY_HORIZON = np.array([236.0, 241.0, 246.0])
_GROUND = (226, 226, 218)
_SHADOW = (150, 152, 160)


@dataclass
class _Faces:
    """The scene flattened.

    ``corners`` (C, 3) lists face corners face after face, ``offsets`` (F + 1,) where each face
    starts, ``rgba`` (F, 4) its colour in 0–1 (a textured face: times its texture's mean);
    ``tris`` (T, 3) are triangles as corner indices and ``tri_face`` (T,) the face of each.
    ``uvs`` (C, 2) are the corners' texture coordinates, ``texture`` (F,) the index of each
    face's image in ``images`` (-1: untextured) and ``base`` (F, 3) the material colour the
    texture is multiplied with.
    """

    corners: np.ndarray
    offsets: np.ndarray
    rgba: np.ndarray
    tris: np.ndarray
    tri_face: np.ndarray
    closed: np.ndarray  # (F,) face of a closed, opaque part: its back side is never seen
    uvs: np.ndarray | None = None
    texture: np.ndarray | None = None
    base: np.ndarray | None = None
    images: tuple = ()

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

#: Largest side and area of a rendered picture: the drawing buffers take about 60 bytes a
#: pixel (an 8000 x 8000 picture took 3.8 GB), so 4096² stays near 1 GB.
MAX_PICTURE_SIDE = 8192
MAX_PICTURE_PIXELS = 4096 * 4096

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
        Darken the pixels along face boundaries.
    shadow : bool
        Draw the ground and the sun shadow of the models on it.
    supersample : int
        Drawing scale factor for anti-aliasing; lowered automatically for scenes so large that
        it would cost more than about 30 million covered pixels.

    Returns
    -------
    PIL.Image.Image
        RGB picture of ``size``; the camera is fitted to the models' bounding box.
    """
    width, height = (int(v) for v in size)
    if width < 1 or height < 1 or supersample < 1:
        raise ExportError(f"invalid picture size {size} or supersample {supersample}")
    if max(width, height) > MAX_PICTURE_SIDE or width * height > MAX_PICTURE_PIXELS:
        raise ExportError(f"picture size {width}x{height} is too large: at most "
                          f"{MAX_PICTURE_SIDE} pixels a side and {MAX_PICTURE_PIXELS:,} pixels "
                          "(4096x4096)")
    faces = _scene_faces(as_models(models))
    if len(faces.tris):
        view = _View(faces, (width, height), azimuth, elevation, perspective, fov, shadow)
        ss = view.supersample(int(supersample))
        image = _draw_scene(_sky(width * ss, height * ss), faces, view, ss, outlines)
    else:
        ss = int(supersample)
        image = _sky(width * ss, height * ss)
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
    import shutil

    from ..scratch import scratch_dir
    from . import IMPORTERS, load, suffix_of

    if suffix_of(model_path, IMPORTERS) != "glb":
        return render_preview(load(model_path), out_png, **options)
    # a .glb's embedded images become files only for the time of the render (the picture
    # holds their pixels), not a temporary folder left behind by every call; named after the
    # process, so the next render removes the folder of one that was killed
    textures = scratch_dir("facadeforge-render-")
    try:
        return render_preview(load(model_path, texture_dir=textures), out_png, **options)
    finally:
        shutil.rmtree(textures, ignore_errors=True)


# -- scene ------------------------------------------------------------------------------------

def _scene_faces(models: list[Model]) -> _Faces:
    corners, offsets, colors, tris, owners, closed = [], [0], [], [], [], []
    uvs, tex_ids, bases = [], [], []
    images: list[np.ndarray] = []
    image_of: dict[str, int] = {}
    n_faces = 0
    for part in (p for m in models for p in m.parts):
        flat, starts = face_corners(part.mesh)
        sizes = np.diff(starts)
        good = sizes >= 3
        if not good.any():
            continue
        keep = np.repeat(good, sizes)
        renumber = np.cumsum(keep) - 1 + offsets[-1]
        tri, face_of = triangulate_corners(part.mesh)
        face_renumber = np.cumsum(good) - 1 + n_faces
        rgba = _part_rgba(part.material)
        n_good = int(good.sum())
        corners.append(part.mesh.vertices[flat[keep]])
        offsets.extend((np.cumsum(sizes[good]) + offsets[-1]).tolist())
        colors.append(np.tile(rgba, (n_good, 1)))
        tris.append(renumber[tri])
        owners.append(face_renumber[face_of])
        solid = rgba[3] >= 0.999 and part.mesh.is_closed()
        closed.append(np.full(n_good, solid))
        part_uvs, has_uvs = corner_uvs(part.mesh)
        uvs.append(part_uvs[keep])
        tex = part.material.texture if has_uvs else None
        if tex and str(tex) not in image_of and (img := texture_pixels(tex)) is not None:
            image_of[str(tex)] = len(images)
            images.append(img)
        tex_ids.append(np.full(n_good, image_of.get(str(tex), -1) if tex else -1))
        bases.append(np.tile(np.clip(np.asarray(part.material.color, float), 0, 1), (n_good, 1)))
        n_faces += n_good
    if not corners:
        empty = np.zeros(0, np.int64)
        return _Faces(np.zeros((0, 3)), np.zeros(1, np.int64), np.zeros((0, 4)),
                      empty.reshape(0, 3), empty, np.zeros(0, bool))
    return _Faces(np.concatenate(corners), np.asarray(offsets, np.int64), np.concatenate(colors),
                  np.concatenate(tris), np.concatenate(owners), np.concatenate(closed),
                  uvs=np.concatenate(uvs), texture=np.concatenate(tex_ids),
                  base=np.concatenate(bases), images=tuple(images))


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


def _light(normals: np.ndarray, facing: np.ndarray, sun: np.ndarray) -> np.ndarray:
    """Light factor (F,) per face: sky ambient plus Lambert sun, both sides of a face lit."""
    n = np.where(facing[:, None], normals, -normals)
    return 0.5 + 0.1 * n[:, 1] + 0.5 * np.clip(n @ sun, 0.0, None)


def _shade(faces: _Faces, light: np.ndarray) -> np.ndarray:
    """Flat RGB colours (F, 3) in 0–1."""
    return np.clip(faces.rgba[:, :3] * light[:, None], 0.0, 1.0)


class _View:
    """Camera, sun and framing of a scene, and which triangles can be seen at all."""

    _SAMPLE_BUDGET = 30_000_000

    def __init__(self, faces: _Faces, size: tuple[int, int], azimuth: float, elevation: float,
                 perspective: bool, fov: float, shadow: bool) -> None:
        self.lo, self.hi = faces.corners.min(axis=0), faces.corners.max(axis=0)
        self.cam = _camera(self.lo, self.hi, azimuth, elevation, perspective, fov)
        self.sun = _sun(azimuth)
        self.shadow = _shadow_points(faces.corners, self.sun, self.lo[1]) if shadow else None
        fit = faces.corners if self.shadow is None else np.concatenate([faces.corners,
                                                                         self.shadow])
        self.to_screen = _fit(self.cam, fit, size)
        self.size = size
        self.normals = _normals(faces)
        centroid = faces.sums(faces.corners) / np.diff(faces.offsets)[:, None]
        to_eye = self.cam.eye - centroid if perspective else -self.cam.forward[None, :]
        self.facing = np.sum(self.normals * to_eye, axis=1) >= 0
        visible = self.facing | ~faces.closed
        self.tris = np.nonzero(visible[faces.tri_face])[0]
        self.screen = self.to_screen(faces.corners)
        view_z = self.cam.view(faces.corners)[:, 2]
        self.near = 1.0 / np.maximum(view_z, 1e-9) if perspective else -view_z
        self.faces = faces

    def supersample(self, wanted: int) -> int:
        """The largest factor up to ``wanted`` whose covered-pixel count fits the budget."""
        xy = self.screen[self.faces.tris[self.tris]]
        e1, e2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
        covered = float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() / 2)
        ss = wanted
        w, h = self.size
        # covered pixels bound the drawing time, the whole picture its buffers' memory
        while ss > 1 and max(covered, w * h) * ss * ss > self._SAMPLE_BUDGET:
            ss -= 1
        return ss


# -- drawing ----------------------------------------------------------------------------------

def _sky(width: int, height: int) -> Image.Image:
    t = np.linspace(0.0, 1.0, height)[:, None] ** 0.7
    rows = (_SKY_TOP * (1 - t) + _SKY_HORIZON * t).astype(np.uint8)
    return Image.fromarray(np.repeat(rows[:, None, :], width, axis=1))


def _draw_scene(image: Image.Image, faces: _Faces, view: _View, ss: int,
                outlines: bool) -> Image.Image:
    def to_screen(points: np.ndarray) -> np.ndarray:
        return view.to_screen(points) * ss

    if view.shadow is not None:
        _draw_ground(image, view.cam, to_screen, view.lo, view.hi)
        _draw_shadow(image, faces, to_screen(view.shadow))
    tris = faces.tris[view.tris]
    xy = (view.screen * ss)[tris]
    sub = _Faces(faces.corners, faces.offsets, faces.rgba, tris, faces.tri_face[view.tris],
                 faces.closed)
    near = view.near[tris]
    opaque, clear, zbuf, opaque_tri = _visible_faces(sub, xy, near, image.size)
    light = _light(view.normals, view.facing, view.sun)
    shade = _shade(faces, light)
    width, height = image.size
    out = np.array(image, np.uint8).reshape(-1, 3)
    hit = np.nonzero(opaque >= 0)[0]
    out[hit] = (shade * 255 + 0.5).astype(np.uint8)[opaque[hit]]
    if faces.images:
        _texture(out, width, faces, light, opaque, opaque_tri, tris, xy,
                 near if view.cam.perspective else None)
    _blend_glass(out, faces, shade, clear)
    if outlines:
        top = np.where(clear >= 0, clear, opaque).reshape(height, width)
        edge = _edges(top, shade, zbuf.reshape(height, width))
        out[edge] = (out[edge] * 0.72).astype(np.uint8)
    return Image.fromarray(out.reshape(height, width, 3))


def _visible_faces(faces: _Faces, xy: np.ndarray, near: np.ndarray, size: tuple[int, int]
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel: the nearest opaque face, the nearest translucent face in front of it, the
    nearness of the opaque one and its triangle (index into ``faces.tris``; -1: none)."""
    alpha = faces.rgba[faces.tri_face, 3]
    solid = np.nonzero(alpha >= 0.999)[0]
    glass = np.nonzero((alpha < 0.999) & (alpha > 0.0))[0]
    zbuf, opaque = rasterize(xy[solid], near[solid], size)
    _, clear = rasterize(xy[glass], near[glass], size, in_front_of=zbuf)
    opaque_tri = np.where(opaque >= 0, solid[np.maximum(opaque, 0)], -1)
    return (_face_of(opaque, faces.tri_face[solid]), _face_of(clear, faces.tri_face[glass]),
            zbuf, opaque_tri)


def _texture(out: np.ndarray, width: int, faces: _Faces, light: np.ndarray,
             opaque: np.ndarray, opaque_tri: np.ndarray, tris: np.ndarray, xy: np.ndarray,
             near: np.ndarray | None) -> None:
    """Repaint the pixels of textured opaque faces with their texels: barycentric UVs of the
    pixel centre, perspective-correct under perspective (``near`` = 1/z: weighting the
    screen-space barycentrics by it interpolates UVs linearly in 3D; ``None`` for an
    orthographic view, where screen space is affine to 3D), nearest texel, wrapped; times the
    material colour and half the face's light.  Pixels are processed in chunks (memory stays
    bounded on large supersampled renders)."""
    pix_all = np.nonzero(opaque >= 0)[0]
    pix_all = pix_all[faces.texture[opaque[pix_all]] >= 0]
    for start in range(0, len(pix_all), _TEXEL_CHUNK):
        pix = pix_all[start:start + _TEXEL_CHUNK]
        face = opaque[pix]
        tex = faces.texture[face]
        t = opaque_tri[pix]
        px = (pix % width) + 0.5
        py = (pix // width) + 0.5
        a, b, c = xy[t, 0], xy[t, 1], xy[t, 2]
        det = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
               - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
        det = np.where(np.abs(det) > 1e-12, det, 1e-12)
        l1 = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (py - a[:, 1]) * (c[:, 0] - a[:, 0])) / det
        l2 = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (b[:, 1] - a[:, 1]) * (px - a[:, 0])) / det
        wgt = np.clip(np.column_stack([1.0 - l1 - l2, l1, l2]), 0.0, 1.0)
        if near is not None:
            wgt *= near[t]
        wgt /= np.maximum(wgt.sum(axis=1, keepdims=True), 1e-12)
        uv = np.einsum("nk,nkd->nd", wgt, faces.uvs[tris[t]])
        uv -= np.floor(uv)
        colour = np.empty((len(pix), 3), np.float32)
        for k in np.unique(tex):
            m = tex == k
            img = faces.images[k]
            h, w = img.shape[:2]
            col = np.minimum((uv[m, 0] * w).astype(np.int64), w - 1)
            row = np.minimum(((1.0 - uv[m, 1]) * h).astype(np.int64), h - 1)
            colour[m] = img[row, col]
        # a photo texture carries its own light: the sun only modulates it, by half as much
        colour *= faces.base[face] * (0.5 + 0.5 * light[face])[:, None]
        out[pix] = (np.clip(colour, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)


def _face_of(tri_ids: np.ndarray, tri_face: np.ndarray) -> np.ndarray:
    """Map a triangle-index buffer to face indices (``-1`` stays ``-1``)."""
    out = np.full(len(tri_ids), -1, np.int64)
    hit = tri_ids >= 0
    out[hit] = tri_face[tri_ids[hit]]
    return out


def _blend_glass(out: np.ndarray, faces: _Faces, shade: np.ndarray, clear: np.ndarray) -> None:
    """Blend the nearest translucent face of each pixel over the flat (W*H, 3) buffer."""
    seen = np.nonzero(clear >= 0)[0]
    if len(seen):
        a = faces.rgba[clear[seen], 3:4].astype(np.float32)
        mixed = a * shade[clear[seen]].astype(np.float32) * 255 + (1 - a) * out[seen]
        out[seen] = (mixed + 0.5).astype(np.uint8)


def _edges(ids: np.ndarray, shade: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Flat indices of pixels on a visible boundary: the face changes and so does the colour or
    the depth, or a face meets the background.  Coplanar faces of one colour (tiles, triangles
    of one polygon) get no line."""
    h, w = ids.shape
    flat_ids, flat_near = ids.reshape(-1), near.reshape(-1)
    found = []
    for step, change in ((1, ids[:, 1:] != ids[:, :-1]), (w, ids[1:, :] != ids[:-1, :])):
        r, c = np.nonzero(change)
        pb = r * w + c
        pa = pb + step
        ia, ib = flat_ids[pa], flat_ids[pb]
        background = (ia < 0) | (ib < 0)
        colour = np.abs(shade[ia] - shade[ib]).max(axis=1) > 0.04
        za, zb = flat_near[pa], flat_near[pb]
        with np.errstate(invalid="ignore"):
            depth = np.abs(za - zb) > 0.01 * np.maximum(np.abs(za), np.abs(zb))
        line = background | colour | depth
        found.append(pa[line & (ia >= 0)])
        found.append(pb[line & (ib >= 0) & (ia < 0)])
    return np.unique(np.concatenate(found))


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
    """Darken the ground where the models' sun shadow falls (polygon fills: order is moot)."""
    mask = Image.new("L", image.size, 0)
    draw = ImageDraw.Draw(mask)
    flat = screen.ravel().tolist()
    off = (faces.offsets * 2).tolist()
    for i in range(faces.count):
        draw.polygon(flat[off[i]:off[i + 1]], fill=140)
    image.paste(Image.new("RGB", image.size, _SHADOW), mask=mask)
