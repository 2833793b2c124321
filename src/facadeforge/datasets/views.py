"""Synthetic calibrated photo sets of derived buildings, with exact depth and labels.

``simon2011`` §5.4.2 tests the multi-view grammar fit on artificial data: "we randomly generate a
building and visualize it from 3 cameras".  :func:`synthetic_view_set` does that with the
buildings of :func:`~.scans.facade_building` (a random layout of a :data:`~.synthetic.STYLES`
grammar, made 3D with recessed windows, balcony boxes and reveals) and :func:`render_view`
photographs it with a pinhole :class:`~.cameras.Camera`: a textured colour image, the exact depth
of every pixel and its ``ecp7`` label.  :func:`write_view_set` writes the set as a RueMonge-like
folder with a VisualSFM ``cameras.txt`` (read back by :func:`~.cameras.read_visualsfm` and
:func:`~.ruemonge.load_ruemonge`).

World frame
    The models' own frame, the CGA world of :func:`~.scans.facade_building`: metres, right-handed,
    **y up**; the (first) facade lies in the plane ``z = 0`` with its bottom-left corner at the
    origin, ``x`` runs along it to the right as seen from the street, its outward normal is
    ``+z`` (the street is ``z > 0``, the building's block ``z < 0``), the ground is ``y = 0``.
    A recessed window has ``z < 0``, a balcony ``z > 0``.  With ``n_facades=2`` the second
    facade is a second building turned +90° about ``y`` whose facade starts at the first one's
    right edge ``(W, 0, 0)``: it lies in the plane ``x = W``, faces ``+x`` and runs along ``-z``.

Cameras
    :class:`~.cameras.Camera` as VisualSFM writes them: ``R`` rotates world into camera
    coordinates, its rows the camera's x (right), y (down) and viewing axes; ``C`` the centre;
    one focal length; principal point ``(w / 2, h / 2)``.  :meth:`~.cameras.Camera.project`
    gives continuous pixel coordinates in which pixel ``(col, row)`` covers
    ``[col, col + 1) × [row, row + 1)`` (its centre is ``(col + .5, row + .5)``), the convention
    of :func:`~facadeforge.exchange._zbuffer.rasterize`: a world point projecting to ``(x, y)``
    is seen in pixel ``(floor(x), floor(y))``.

What a view holds (:class:`View`)
    ``depth`` is the distance along the camera's viewing axis (``z`` in camera coordinates, the
    quantity :meth:`~.cameras.Camera.depth` returns) of the surface seen at each pixel centre,
    ``np.inf`` where nothing is hit.  It is exact: the ray through the pixel centre intersected
    in float64 with the plane of the triangle the z-buffer found there, so ``C + depth · ray``
    (``ray = R.T @ ((x − cx) / f, (y − cy) / f, 1)``) lies on that face.  ``labels`` are ``ecp7``
    class indices (:func:`~.labelsets.get_label_set`: 0 window, 1 wall, 2 balcony, 3 door,
    4 roof, 5 sky, 6 shop), the part's canonical label (``scans._canonical_label``) through the
    set's canonical map (blinds and shutters → window; cornices, sills, the interior wall →
    wall); pixels that see nothing are ``sky``; the street (parts labelled ``ground``,
    ``pavement``, ``road``) is :data:`~facadeforge.datasets.IGNORE` (255), as RueMonge leaves the
    street unlabelled (written as 0 by :func:`write_view_set`).

Rendering
    Every triangle of the models is projected and z-buffered (nearness ``1 / z``).  Triangles with
    a corner nearer than :data:`NEAR` metres along the viewing axis are dropped, not clipped:
    street cameras stand in front of everything they see, so only geometry behind or beside the
    camera goes (the ground plane is cut in tiles so that its tiles in front of the camera stay).
    Colour is view-independent (Lambertian) so that stereo can match it: the facade's own
    surfaces (every part of a building except its side walls ``Side``, flat roof tops
    ``RoofTop`` and the interior wall ``Interior``) sample the facade photo that
    :func:`~.synthetic.render_photo` paints for the layout, at the seen point's facade-plane
    coordinates (``u`` along the facade, ``v`` up, metres → photo pixels with the layout's
    resolution; bilinear), so window reveals and balcony tops carry stretched texture; the other
    surfaces and the street get a plain colour per label with fixed-seed value noise, mapped on
    the face's plane.  A mild Lambert term on the face normal (a fixed sun above, left, in front)
    is multiplied in, normalised to 1 on the facade plane, so recesses read.  Sky pixels are a
    gradient of the ray's elevation.  No antialiasing, no noise: each pixel is its centre.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from ..errors import InputError
from ..exchange._common import jsonable
from ..geometry.mesh import Mesh
from ..model.model import Model, Part
from .cameras import Camera
from .labelsets import IGNORE, get_label_set

__all__ = ["NEAR", "FacadeTexture", "View", "ViewSet", "facade_truth", "render_view",
           "synthetic_view_set", "write_view_set", "write_visualsfm"]

#: Triangles with a corner nearer than this (m, along the viewing axis) are not drawn.
NEAR = 0.05
#: Eye height of the synthetic cameras above the ground (m).
EYE_HEIGHT = 1.6
#: Direction towards the sun (world frame, y up): above, to the left, in front of the facade.
SUN = np.array([-0.45, 0.7, 0.55]) / np.linalg.norm([-0.45, 0.7, 0.55])

_ECP7 = get_label_set("ecp7")
_SKY = _ECP7.index("sky")
_STREET_LABELS = frozenset({"ground", "pavement", "road"})
#: Parts of a building that are not its facade: they get the plain noisy texture.
_OFF_FACADE = frozenset({"Side", "RoofTop", "Interior"})
#: Plain colours (sRGB 0..1) of surfaces that are not textured by the facade photo.
_PLAIN = {"wall": (0.72, 0.66, 0.58), "roof": (0.42, 0.42, 0.45), "other": (0.35, 0.30, 0.27),
          "ground": (0.50, 0.49, 0.47)}
_NOISE_TILE = 512          # texels of the noise tile (it repeats)
_NOISE_TEXEL = 0.025       # metres per texel of the noise tile


# ================================================================================ data
@dataclass
class FacadeTexture:
    """A facade photo and where it lies in the world.

    A world point ``X`` has facade coordinates ``u = (X − origin) · u_axis``,
    ``v = (X − origin) · up_axis`` (metres) and photo coordinates ``col = u · px_per_m[0]``,
    ``row = (top − v) · px_per_m[1]`` (continuous, pixel ``(c, r)`` centred at ``(c + .5, r + .5)``).
    """

    image: np.ndarray            # (H, W, 3) float 0..1
    origin: np.ndarray           # world point of u = v = 0 (the facade's bottom-left corner)
    u_axis: np.ndarray
    up_axis: np.ndarray
    px_per_m: tuple[float, float]
    top: float                   # v (m) of the photo's top edge

    @staticmethod
    def from_layout(layout, image: np.ndarray, *, origin=(0.0, 0.0, 0.0), u_axis=(1.0, 0.0, 0.0),
                    up_axis=(0.0, 1.0, 0.0)) -> FacadeTexture:
        """The texture of :func:`~.scans.facade_building`\\ ``(layout, origin=…)``: its street
        strip is cut off, so ``v = 0`` is the layout's ``y`` of the top of its street."""
        sx = layout.width_px / float(layout.tree.scope.size[0])
        sy = layout.height_px / float(layout.tree.scope.size[1])
        top = float(layout.tree.scope.size[1]) - _street_top(layout)
        img = np.asarray(image)
        img = (img / np.float32(255.0) if np.issubdtype(img.dtype, np.integer) else img)
        img = np.asarray(img, np.float32)
        return FacadeTexture(img, np.asarray(origin, float), np.asarray(u_axis, float),
                             np.asarray(up_axis, float), (sx, sy), top)


@dataclass
class View:
    """One rendered photo: colour, exact depth along the viewing axis (``inf`` where nothing is
    hit), ``ecp7`` class index per pixel (:data:`IGNORE` on the street), its camera, and the
    unit normal (world frame, towards the camera; 0 where nothing is hit) of the face seen."""

    rgb: np.ndarray        # (h, w, 3) uint8
    depth: np.ndarray      # (h, w) float32
    labels: np.ndarray     # (h, w) uint8
    camera: Camera
    normals: np.ndarray | None = None   # (h, w, 3) float32 world unit normals, facing the camera

    @property
    def id(self) -> str:
        return self.camera.id

    def rays(self) -> np.ndarray:
        """World directions (h, w, 3) of the pixel-centre rays, scaled to unit viewing-axis
        component: ``camera.C + depth[..., None] * rays()`` are the seen points."""
        h, w = self.depth.shape
        return _pixel_rays(self.camera, (w, h)).reshape(h, w, 3)

    def points(self) -> np.ndarray:
        """World points (h, w, 3) seen at the pixel centres (``nan`` where nothing is hit)."""
        d = np.where(np.isfinite(self.depth), self.depth.astype(np.float64), np.nan)
        return self.camera.C + d[..., None] * self.rays()


@dataclass
class ViewSet:
    """A random building photographed from a few street cameras, and its truth.

    ``truth``: ``frame`` (text), ``facades`` (:func:`facade_truth` per facade: origin, u axis, up
    axis, normal, width, height, element rectangles in facade metres), ``label_names`` (ecp7).
    """

    models: list[Model]
    layout: Any                                  # the (first) facade's SyntheticFacade
    views: list[View]
    cameras: dict[str, Camera]
    truth: dict[str, Any]
    meta: dict[str, Any] = field(default_factory=dict)
    layouts: list[Any] = field(default_factory=list)   # every facade's layout
    textures: list[FacadeTexture | None] = field(default_factory=list)


# ================================================================================ geometry
def _street_top(layout) -> float:
    """Layout ``y`` (m) of the top of the street strip that :func:`facade_building` drops."""
    from .scans import _layout_leaves

    street = [lf.y1 for lf in _layout_leaves(layout) if lf.label == "ground" and lf.y0 <= 1e-6]
    return max(street) if street else 0.0


def facade_truth(layout, *, origin=(0.0, 0.0, 0.0), u_axis=(1.0, 0.0, 0.0),
                 up_axis=(0.0, 1.0, 0.0), model: Model | None = None) -> dict[str, Any]:
    """The facade frame and element rectangles of ``facade_building(layout, origin=…)`` (turned
    so that the layout's x is ``u_axis``).

    Elements are what :func:`~.scans.facade_building` makes instances of (maximal subtrees whose
    leaves share one label other than wall and roof, ``scans._group_elements``): ``instance``
    (the part's ``shape_id``), canonical ``label``, ``ecp7`` class name, ``rect``
    ``[u0, v0, u1, v1]`` (m, facade frame: ``v = 0`` on the ground) and ``depth`` (area-weighted
    offset of its leaves from the facade plane, negative = recessed).
    """
    from .scans import _group_elements, _layout_leaves

    leaves = _layout_leaves(layout)
    _group_elements(layout.tree, leaves)
    shift = _street_top(layout)
    groups: dict[int, list] = {}
    for lf in leaves:
        y0, y1 = max(lf.y0 - shift, 0.0), lf.y1 - shift
        if lf.element < 0 or y1 <= 1e-6 or lf.label == "ground":
            continue
        groups.setdefault(lf.element, []).append((lf, y0, y1))
    elements = []
    for k in sorted(groups):
        members = groups[k]
        label = members[0][0].label
        area = np.array([(m.x1 - m.x0) * (y1 - y0) for m, y0, y1 in members])
        zs = np.array([m.z for m, _, _ in members])
        rect = [min(m.x0 for m, _, _ in members), min(y0 for _, y0, _ in members),
                max(m.x1 for m, _, _ in members), max(y1 for _, _, y1 in members)]
        elements.append({
            "instance": 2 + k, "label": label, "ecp7": _ECP7.classes[_ECP7.canonical_map[label]],
            "rect": [round(float(v), 6) for v in rect],
            "depth": round(float((zs * area).sum() / max(area.sum(), 1e-12)), 6)})
    u, up = np.asarray(u_axis, float), np.asarray(up_axis, float)
    width = float(model.attributes["width"]) if model is not None else float(layout.width_m)
    height = float(model.attributes["height"]) if model is not None else \
        float(layout.tree.scope.size[1]) - shift
    return {"origin": np.asarray(origin, float).tolist(), "u_axis": u.tolist(),
            "up_axis": up.tolist(), "normal": np.cross(u, up).tolist(), "width": width,
            "height": height, "style": layout.style, "elements": elements}


def _look_at(centre: np.ndarray, target: np.ndarray, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Rotation world → camera (rows x right, y down, viewing axis) of an upright camera."""
    z = np.asarray(target, float) - centre
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.array([x, y, z])


def _pixel_rays(camera: Camera, size: tuple[int, int]) -> np.ndarray:
    """World ray directions (h · w, 3) through the pixel centres, viewing-axis component 1."""
    w, h = size
    cx, cy = camera.principal
    xs = (np.arange(w) + 0.5 - cx) / camera.focal
    ys = (np.arange(h) + 0.5 - cy) / camera.focal
    d = np.empty((h, w, 3))
    d[..., 0] = xs[None, :]
    d[..., 1] = ys[:, None]
    d[..., 2] = 1.0
    return d.reshape(-1, 3) @ np.asarray(camera.R, float)


# ================================================================================ scene
@dataclass
class _Tris:
    tri: np.ndarray        # (T, 3, 3) world
    label: np.ndarray      # (T,) ecp7 index or IGNORE
    texture: np.ndarray    # (T,) index into the textures, -1 plain
    plain: np.ndarray      # (T, 3) plain colour


def _part_label(part: Part) -> tuple[int, str]:
    from .scans import _canonical_label

    name = _canonical_label(part.label, part.symbol)
    if name in _STREET_LABELS:
        return IGNORE, "ground"
    return int(_ECP7.canonical_map[name]), name


def _scene(models: Sequence[Model], textured: Sequence[bool]) -> _Tris:
    tris, labels, tex, plain = [], [], [], []
    for m_idx, model in enumerate(models):
        for part in model.parts:
            mesh = part.mesh
            if mesh is None or not mesh.n_faces:
                continue
            pos = np.asarray(mesh.triangulate()[0], float).reshape(-1, 3, 3)
            if not len(pos):
                continue
            lab, name = _part_label(part)
            on_facade = textured[m_idx] and part.symbol not in _OFF_FACADE and name != "ground"
            colour = _PLAIN.get(name if name in _PLAIN else "wall")
            if name == "wall" and part.symbol == "Interior":
                colour = _PLAIN["other"]
            n = len(pos)
            tris.append(pos)
            labels.append(np.full(n, lab, np.int64))
            tex.append(np.full(n, m_idx if on_facade else -1, np.int64))
            plain.append(np.tile(np.asarray(colour, float), (n, 1)))
    if not tris:
        return _Tris(np.zeros((0, 3, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64),
                     np.zeros((0, 3)))
    return _Tris(np.concatenate(tris), np.concatenate(labels), np.concatenate(tex),
                 np.concatenate(plain))


@cache
def _noise_tile() -> np.ndarray:
    """A fixed-seed, tileable value-noise texture (512², values about 0 ± 1): three octaves of
    value noise (smoothstep interpolation) on periodic lattices."""
    rng = np.random.default_rng(0x7E57)
    n = _NOISE_TILE
    out = np.zeros((n, n), np.float32)
    for cells, amp in ((8, 0.5), (32, 0.3), (128, 0.25), (512, 0.15)):
        grid = rng.standard_normal((cells, cells)).astype(np.float32)
        t = np.arange(n) * cells / n
        i0 = np.floor(t).astype(np.int64)
        f = (t - i0).astype(np.float32)
        f = f * f * (3 - 2 * f)
        i1 = (i0 + 1) % cells
        a = grid[i0][:, i0] * (1 - f)[None, :] + grid[i0][:, i1] * f[None, :]
        b = grid[i1][:, i0] * (1 - f)[None, :] + grid[i1][:, i1] * f[None, :]
        out += amp * (a * (1 - f)[:, None] + b * f[:, None])
    return out / out.std()


def _bilinear(img: np.ndarray, col: np.ndarray, row: np.ndarray, wrap: bool = False) -> np.ndarray:
    """Sample ``img`` (H, W[, C]) at continuous pixel-centre coordinates (centre of pixel ``i``
    at ``i``): clamped to the border, or periodic when ``wrap``."""
    h, w = img.shape[:2]
    c0 = np.floor(col).astype(np.int64)
    r0 = np.floor(row).astype(np.int64)
    fc, fr = (col - c0).astype(np.float32), (row - r0).astype(np.float32)
    if wrap:
        c0, r0 = c0 % w, r0 % h
        c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    else:
        c1, r1 = np.clip(c0 + 1, 0, w - 1), np.clip(r0 + 1, 0, h - 1)
        c0, r0 = np.clip(c0, 0, w - 1), np.clip(r0, 0, h - 1)
    if img.ndim == 3:
        fc, fr = fc[:, None], fr[:, None]
    top = img[r0, c0] * (1 - fc) + img[r0, c1] * fc
    bot = img[r1, c0] * (1 - fc) + img[r1, c1] * fc
    return top * (1 - fr) + bot * fr


def _lambert(n: np.ndarray) -> np.ndarray:
    return 0.6 + 0.4 * np.clip(n @ SUN, 0.0, None)


# ================================================================================ render
def render_view(models: Model | Sequence[Model], camera: Camera, size: tuple[int, int] = (640, 480),
                *, texture: FacadeTexture | Sequence[FacadeTexture | None] | None = None) -> View:
    """Photograph ``models`` with ``camera``: colour, exact depth and ``ecp7`` labels.

    Parameters
    ----------
    models : Model or sequence of Model
        World frame as in the module docstring (any frame works for depth and labels).
    camera : Camera
        Pinhole camera; its principal point is normally ``(w / 2, h / 2)``.
    size : (w, h)
        Image size in pixels.
    texture : FacadeTexture or sequence, optional
        The facade photo of each model (``None`` entries: plain); one texture alone goes with the
        first model.  Without textures every surface is plain noisy colour.

    Returns
    -------
    View
        See the module docstring; ``depth`` is ``inf`` where nothing is hit.
    """
    models = [models] if isinstance(models, Model) else list(models)
    if not all(isinstance(m, Model) for m in models):
        raise InputError("render_view needs a Model or a list of Models")
    w, h = (int(v) for v in size)
    if w < 1 or h < 1 or w * h > 4096 * 4096:
        raise InputError(f"image size {w}x{h} is out of range (1 .. 4096² pixels)")
    if texture is None or isinstance(texture, FacadeTexture):
        textures: list[FacadeTexture | None] = [texture] + [None] * (len(models) - 1)
    else:
        textures = list(texture) + [None] * max(0, len(models) - len(texture))
    scene = _scene(models, [t is not None for t in textures[:len(models)]])
    R = np.asarray(camera.R, float)
    C = np.asarray(camera.C, float)
    f, (cx, cy) = float(camera.focal), camera.principal

    cam = (scene.tri - C) @ R.T                                     # (T, 3, 3)
    z = cam[..., 2]
    keep = (z >= NEAR).all(axis=1)
    xy = f * cam[..., :2] / np.where(z > 0, z, 1.0)[..., None] + np.array([cx, cy])
    keep &= (xy[..., 0].max(1) >= 0) & (xy[..., 0].min(1) <= w) \
        & (xy[..., 1].max(1) >= 0) & (xy[..., 1].min(1) <= h)
    normal = np.cross(scene.tri[:, 1] - scene.tri[:, 0], scene.tri[:, 2] - scene.tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    keep &= length > 1e-12
    idx = np.flatnonzero(keep)

    from ..exchange._zbuffer import rasterize

    zbuf, ids = rasterize(xy[idx], 1.0 / z[idx], (w, h))
    hit = ids >= 0
    tri_of = idx[ids[hit]]
    rays = _pixel_rays(camera, (w, h))
    depth = np.full(w * h, np.inf)
    n_hit = normal[tri_of] / length[tri_of, None]
    r_hit = rays[hit]
    denom = np.einsum("ij,ij->i", n_hit, r_hit)
    num = np.einsum("ij,ij->i", n_hit, scene.tri[tri_of, 0] - C)
    grazing = np.abs(denom) < 1e-12
    d = np.where(grazing, 1.0 / np.where(zbuf[hit] > 0, zbuf[hit], 1.0),
                 num / np.where(grazing, 1.0, denom))
    depth[hit] = d
    labels = np.full(w * h, _SKY, np.uint8)
    labels[hit] = scene.label[tri_of].astype(np.uint8)

    # colour
    rgb = np.empty((w * h, 3), np.float32)
    dirs = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    elev = np.clip(dirs[:, 1], -1.0, 1.0)
    horizon, zenith = np.array([0.80, 0.86, 0.92]), np.array([0.38, 0.55, 0.80])
    t = np.clip(elev, 0.0, 1.0)[:, None] ** 0.7
    rgb[:] = horizon * (1 - t) + zenith * t
    X = C + d[:, None] * r_hit                                      # seen world points
    facing = np.where((np.einsum("ij,ij->i", n_hit, C - X) >= 0)[:, None], n_hit, -n_hit)
    light = _lambert(facing)
    col = np.empty((len(tri_of), 3), np.float32)
    tex_of = scene.texture[tri_of]
    plain = tex_of < 0
    for k, tx in enumerate(textures[:len(models)]):
        sel = tex_of == k
        if tx is None or not sel.any():
            plain |= sel
            continue
        rel = X[sel] - tx.origin
        u, v = rel @ tx.u_axis, rel @ tx.up_axis
        ccol = u * tx.px_per_m[0] - 0.5
        crow = (tx.top - v) * tx.px_per_m[1] - 0.5
        front = np.cross(tx.u_axis, tx.up_axis)
        col[sel] = _bilinear(tx.image, ccol, crow) * (light[sel] / _lambert(front[None])[0])[:, None]
    if plain.any():
        n = np.abs(facing[plain])
        axis = np.argmax(n, axis=1)                                 # drop the dominant axis
        pa = np.where(axis == 0, X[plain, 2], X[plain, 0])
        pb = np.where(axis == 1, X[plain, 2], X[plain, 1])
        noise = _bilinear(_noise_tile(), pa / _NOISE_TEXEL, pb / _NOISE_TEXEL, wrap=True)
        base = scene.plain[tri_of[plain]]
        col[plain] = np.clip(base * (1 + 0.14 * noise[:, None]), 0, 1) * light[plain, None]
    rgb[hit] = col
    out = np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8).reshape(h, w, 3)
    normals = np.zeros((w * h, 3), np.float32)
    normals[hit] = facing
    return View(out, depth.astype(np.float32).reshape(h, w), labels.reshape(h, w), camera,
                normals.reshape(h, w, 3))


# ================================================================================ view sets
def _ground_model(lo: np.ndarray, hi: np.ndarray, tile: float = 2.0) -> Model:
    """The street: a grid of ``tile``-metre squares on ``y = 0`` over x/z range ``lo..hi`` (tiles,
    so that those in front of a camera survive the near-plane drop of those under it)."""
    xs = np.arange(lo[0], hi[0] + 1e-9, tile)
    zs = np.arange(lo[1], hi[1] + 1e-9, tile)
    gx, gz = np.meshgrid(xs[:-1], zs[:-1], indexing="ij")
    gx, gz = gx.ravel(), gz.ravel()
    zero = np.zeros_like(gx)
    quads = np.stack([np.c_[gx, zero, gz + tile], np.c_[gx + tile, zero, gz + tile],
                      np.c_[gx + tile, zero, gz], np.c_[gx, zero, gz]], axis=1)
    part = Part(Mesh.from_polygons(list(quads)), "ground", symbol="Pavement", shape_id=-1)
    return Model(parts=[part], name="ground")


def _turned(model: Model, rot: np.ndarray, offset: np.ndarray, drop_side_at: float,
            name: str) -> Model:
    """``model`` turned by ``rot`` and moved by ``offset``, without the side-wall faces of its
    left edge (local ``x = drop_side_at``), which the neighbouring facade covers."""
    parts = []
    for p in model.parts:
        mesh = p.mesh
        if p.symbol == "Side":
            mesh = _without_faces_at(mesh, 0, drop_side_at)
            if mesh is None:
                continue
        parts.append(Part(mesh.transformed(rot, offset), p.label, p.material, p.symbol,
                          p.shape_id))
    attrs = dict(model.attributes)
    attrs.pop("facade_planes", None)
    return Model(parts=parts, root=model.root, reports=model.reports, warnings=model.warnings,
                 name=name, attributes=attrs)


def _without_faces_at(mesh: Mesh, axis: int, value: float) -> Mesh | None:
    """The faces of ``mesh`` not lying in the plane ``coord[axis] = value`` (None if none)."""
    starts = np.asarray(mesh.starts, np.int64)
    corners = np.asarray(mesh.corners, np.int64)
    v = np.asarray(mesh.vertices, float)
    polys = [v[corners[a:b]] for a, b in zip(starts[:-1], starts[1:], strict=True)]
    kept = [p for p in polys if not np.all(np.abs(p[:, axis] - value) < 1e-6)]
    return Mesh.from_polygons(kept) if kept else None


def _fit_focal(cameras: list[tuple[np.ndarray, np.ndarray]], points: np.ndarray,
               size: tuple[int, int], fill: float) -> float:
    """The largest focal length with which every camera sees all ``points`` within ``fill`` of
    its half-image (from the centre)."""
    w, h = size
    best = np.inf
    for R, C in cameras:
        cam = (points - C) @ R.T
        z = np.maximum(cam[:, 2], 1e-3)
        sx = np.abs(cam[:, 0] / z).max()
        sy = np.abs(cam[:, 1] / z).max()
        best = min(best, fill * (w / 2) / max(sx, 1e-9), fill * (h / 2) / max(sy, 1e-9))
    return float(best)


def synthetic_view_set(seed: int, *, n_views: int = 3, size: tuple[int, int] = (640, 480),
                       style: str | None = None, n_facades: int = 1, px_per_m: float = 40.0,
                       ground: bool = True, distance: tuple[float, float] = (8.0, 15.0),
                       baseline: tuple[float, float] = (1.5, 3.0), fill: float = 0.92
                       ) -> ViewSet:
    """A random building photographed from ``n_views`` street cameras.

    Everything is a function of ``seed`` (and the arguments): the style (``style`` or one of
    :data:`~.synthetic.STYLES`), its grammar attributes (drawn as :func:`~.scans.synthetic_scans`
    does: no flat trees, cars, hedges or neighbour walls), the building depth, the facade photo
    (:func:`~.synthetic.render_photo` at ``px_per_m``), the cameras.

    Cameras stand on the street at eye height (:data:`EYE_HEIGHT`), a distance drawn in
    ``distance`` in front of the facade (at least 0.55 × its height, so tall facades are seen
    whole), in a row parallel to it with neighbours ``baseline`` metres apart, the row centred
    within ±15 % of the facade's width of its middle; each looks along the mean of the unit directions
    to the facade's corners, jittered by about 1° (so: a slight yaw towards the facade's middle
    and an upward pitch), upright (no roll).  All share
    one focal length: the largest with which every camera sees the whole facade within ``fill``
    of its half-image.  With ``n_facades=2`` the building is a corner (module docstring): the
    cameras stand on the diagonal in front of the corner and look at its edge.  With ``ground``
    a street plane (label :data:`IGNORE`) is added to the models.
    """
    from .scans import _overrides, facade_building
    from .synthetic import STYLES, load_style, make_facade, render_photo

    if n_views < 1:
        raise InputError(f"n_views must be >= 1, got {n_views}")
    if n_facades not in (1, 2):
        raise InputError(f"n_facades must be 1 or 2, got {n_facades}")
    if style is not None and style not in STYLES:
        raise InputError(f"unknown facade style {style!r}; use one of {', '.join(STYLES)}")
    if not (0 < distance[0] <= distance[1]) or not (0 < baseline[0] <= baseline[1]):
        raise InputError("distance and baseline must be positive (lo, hi) ranges")
    rng = np.random.default_rng(np.random.SeedSequence([abs(int(seed)), int(seed < 0), 0x71E35]))
    style = style or STYLES[int(rng.integers(0, len(STYLES)))]
    rules = load_style(style)
    layouts, models, textures, facades = [], [], [], []
    for k in range(n_facades):
        layout = make_facade(style, rng, px_per_m=float(px_per_m), attrs=_overrides(rules))
        photo = render_photo(layout, rng)
        depth = float(rng.uniform(9.0, 15.0))
        model = facade_building(layout, depth=depth, name=f"building_{k}")
        if k == 0:
            origin, u_axis = np.zeros(3), np.array([1.0, 0.0, 0.0])
            if n_facades == 2:   # its right side wall lies on the second facade's plane
                w0 = model.attributes["width"]
                model = _turned(model, np.eye(3), np.zeros(3), w0, model.name)
        else:
            # turned +90° about y: local (x, y, z) → (z, y, −x), moved to the first's right edge
            rot = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
            origin = np.array([float(models[0].attributes["width"]), 0.0, 0.0])
            u_axis = rot @ np.array([1.0, 0.0, 0.0])
            model = _turned(model, rot, origin, 0.0, model.name)
        up = np.array([0.0, 1.0, 0.0])
        tex = FacadeTexture.from_layout(layout, photo, origin=origin, u_axis=u_axis, up_axis=up)
        layouts.append(layout)
        models.append(model)
        textures.append(tex)
        facades.append(facade_truth(layout, origin=origin, u_axis=u_axis, up_axis=up,
                                    model=model) | {"building_depth": depth})

    # the street line the cameras stand on
    f0 = facades[0]
    W0, H = f0["width"], max(f["height"] for f in facades)
    corners = []
    for fd in facades:
        o, u = np.asarray(fd["origin"]), np.asarray(fd["u_axis"])
        for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
            corners.append(o + a * fd["width"] * u + b * fd["height"] * up)
    corners = np.array(corners)
    lo_d = min(max(distance[0], 0.55 * H), distance[1])
    dist = float(rng.uniform(lo_d, distance[1]))
    if n_facades == 1:
        normal, along = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
        anchor = np.array([W0 / 2 + float(rng.uniform(-0.15, 0.15)) * W0, 0.0, 0.0])
    else:
        normal = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
        along = np.array([1.0, 0.0, -1.0]) / math.sqrt(2.0)
        anchor = np.array([W0, 0.0, 0.0])
    gaps = rng.uniform(baseline[0], baseline[1], size=max(n_views - 1, 0))
    s = np.r_[0.0, np.cumsum(gaps)]
    s -= s.mean()
    poses = []
    for i in range(n_views):
        C = anchor + s[i] * along + dist * normal + EYE_HEIGHT * up
        # the mean direction to the facade's corners halves its angular extent both ways
        rays = corners - C
        look = (rays / np.linalg.norm(rays, axis=1, keepdims=True)).mean(0)
        look = look / np.linalg.norm(look) + rng.uniform(-0.02, 0.02, 3) * (along + up)
        poses.append((_look_at(C, C + look), C))
    w, h = (int(v) for v in size)
    focal = _fit_focal(poses, corners, (w, h), fill)
    cameras: dict[str, Camera] = {}
    views = []
    scene_models = list(models)
    if ground:
        lo = corners[:, [0, 2]].min(0) - 30.0
        hi = corners[:, [0, 2]].max(0) + 30.0 + dist
        scene_models.append(_ground_model(np.floor(lo), np.ceil(hi)))
    for i, (R, C) in enumerate(poses):
        cid = f"IMG_{i + 1:04d}"
        cam = Camera(cid, f"{cid}.png", focal, (w / 2.0, h / 2.0), R, C)
        cameras[cid] = cam
        views.append(render_view(scene_models, cam, (w, h), texture=textures))
    truth = {
        "format": "facadeforge synthetic view set truth 1",
        "frame": "CGA world of facade_building: metres, right-handed, y up; the first facade in "
                 "z = 0, bottom-left corner at the origin, x along it, outward normal +z (the "
                 "street is z > 0), ground y = 0",
        "label_set": "ecp7", "label_names": list(_ECP7.classes),
        "label_file_ids": "0 unlabelled (the street), 1 window, 2 wall, 3 balcony, 4 door, "
                          "5 roof, 6 sky, 7 shop",
        "depth": "distance along the viewing axis (m), inf where nothing is hit",
        "facades": facades,
        "sun": SUN.tolist(),
    }
    meta = {"seed": int(seed), "style": style, "n_views": n_views, "n_facades": n_facades,
            "size": [w, h], "px_per_m": float(px_per_m), "distance": dist, "focal": focal,
            "baselines": gaps.tolist(), "ground": bool(ground),
            "attributes": [lay.attributes for lay in layouts]}
    return ViewSet(scene_models, layouts[0], views, cameras, truth, meta, layouts, textures)


# ================================================================================ writing
def _quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def _camera_block(cam: Camera) -> list[str]:
    from scipy.spatial.transform import Rotation

    R, C = np.asarray(cam.R, float), np.asarray(cam.C, float)
    T = -R @ C

    def row(v) -> str:
        return " ".join(f"{float(x) + 0.0:.17g}" for x in v)

    return [cam.file, cam.file, f"{cam.focal:.17g}", row(cam.principal), row(T), row(C),
            row(Rotation.from_matrix(R).as_rotvec()), row(_quaternion(R)),
            row(R[0]), row(R[1]), row(R[2]), f"{cam.radial:.17g} 0"]


def write_visualsfm(cameras: Sequence[Camera] | Mapping[str, Camera], path: str | Path) -> Path:
    """Write cameras in VisualSFM's ``cameras_v2.txt`` layout (12 lines a camera, no EXIF
    line), as :func:`~.cameras.read_visualsfm` reads it; each camera's ``file`` is written as both
    its image name and its original name (name it ``IMG_NNNN.…`` to keep the id)."""
    cams = list(cameras.values()) if isinstance(cameras, Mapping) else list(cameras)
    lines = ["# Camera parameter file.",
             "# written by facadeforge.datasets.views (VisualSFM cameras_v2.txt layout)",
             "# file name; original name; focal length; principal point; translation T; "
             "camera centre C; axis-angle; quaternion (w x y z); rotation matrix (3 lines); "
             "normalised radial distortion, 0",
             "", str(len(cams))]
    for cam in cams:
        lines += [""] + _camera_block(cam)
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def write_view_set(view_set: ViewSet, folder: str | Path) -> Path:
    """Write a view set as a RueMonge-like folder (readable by
    :func:`~.ruemonge.load_ruemonge` with ``split`` the folder's name or absent)::

        folder/img/ID.png       the photo (RGB)
        folder/label/ID.png     8-bit ecp7 ids: 0 unlabelled (the street), 1 window, 2 wall,
                                3 balcony, 4 door, 5 roof, 6 sky, 7 shop
        folder/depth/ID.npy     float32 depth along the viewing axis (m), inf where nothing
        folder/cameras.txt      VisualSFM cameras_v2 layout (:func:`write_visualsfm`)
        folder/truth.json       the set's truth and meta, the cameras (K, R, C)

    ``ID`` is the camera id (``IMG_0001`` …).  Returns the folder.
    """
    folder = Path(folder)
    for sub in ("img", "label", "depth"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    for view in view_set.views:
        cid = view.camera.id
        Image.fromarray(view.rgb, "RGB").save(folder / "img" / f"{cid}.png")
        ids = np.where(view.labels == IGNORE, 0, view.labels.astype(np.int64) + 1)
        Image.fromarray(ids.astype(np.uint8), "L").save(folder / "label" / f"{cid}.png")
        np.save(folder / "depth" / f"{cid}.npy", view.depth.astype(np.float32))
    write_visualsfm([v.camera for v in view_set.views], folder / "cameras.txt")
    truth = dict(view_set.truth)
    truth["cameras"] = {cid: {"file": c.file, "focal": c.focal, "principal": list(c.principal),
                              "R": np.asarray(c.R).tolist(), "C": np.asarray(c.C).tolist()}
                        for cid, c in view_set.cameras.items()}
    truth["meta"] = view_set.meta
    (folder / "truth.json").write_text(json.dumps(jsonable(truth), indent=1), encoding="utf-8")
    return folder

