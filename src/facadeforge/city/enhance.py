"""``enhance``: a textured building mass model made procedural, facade by facade (Müller et
al. 2007 §1: "enhance simple textured building mass models"; Fig. 2, the pipeline from a
facade image to a 3D model; Fig. 16, low-resolution aerial facade textures turned into
detailed facades).

A textured mass model (``.obj`` with its ``.mtl`` and textures, or ``.glb``; y up, metres) is
read with :func:`facadeforge.exchange.load`.  For every building:

1. its *facade faces*: faces of parts whose material has a texture image, whose normal is
   within ~17° of a vertical wall (``|n_y| <``
   :data:`~facadeforge.repair.model_textures.FACADE_NORMAL_UP`) and whose UVs lie inside the
   image (0–1: a UV range beyond it is a tiled material, not a facade's own image), as
   :mod:`facadeforge.repair.model_textures` finds them;
2. its *walls*: those faces grouped by texture and plane (horizontal normals within
   :data:`PLANE_ANGLE_DEG`, plane offsets within :data:`PLANE_OFFSET_M`).  A wall's frame is
   ``n`` its horizontal outward normal, ``v = (0, 1, 0)`` up and ``u = v × n`` (a wall facing
   +z has ``u = +x``); its rectangle is the bounding box of its vertices in ``(u, v)``.  A
   wall whose faces cover less than :data:`RECTANGLE_COVER` of that rectangle (a gable end,
   a stepped wall) is modelled in the largest axis-aligned rectangle inside its faces (on a
   grid of 0.1 m), and the rest of it keeps its texture;
3. each wall's texture *unwrapped*: the affine map ``(u, v) → texture pixel`` is fitted to its
   corners' UVs (least squares; the v texture axis points up, row ``(1 - v) · H``) and the
   wall rectangle resampled into a rectified facade image at ``px_per_m`` or more
   (``cv2.warpAffine``, bicubic when upsampling: aerial textures have a few pixels per window,
   Fig. 16; the report gives the source resolution);
4. the image *reconstructed* (:func:`facadeforge.reconstruction.reconstruct` with
   ``rectified=True`` and the wall's size in metres) and its facade model placed on the wall:
   a facade-frame point ``(x, y, z)`` goes to ``O + x·u + y·v + z·n``, ``O`` the rectangle's
   bottom-left corner on the wall plane.  When the classifier crops the image to the facade
   it sees (sky or street in the texture), the crop is reconstructed again at its own size
   and placed where it lies on the wall; the wall around it keeps the original texture
   (``WallMargin`` faces: the wall's outline less the region modelled, triangulated).

The wall's original faces are replaced by the procedural facade; every other face (roofs,
ground, untextured walls, walls that were skipped, with the reason in the report) is kept as
it was.  A model without any textured face is refused (:class:`~facadeforge.errors.InputError`).

The OUTDIR (written whole, :mod:`facadeforge.outdir`): ``model.glb``, ``model.city.json``,
``facade_NN/`` per facade (``rules.cga``, ``shape_tree.json``, ``texture.png`` the unwrapped
image) and ``report.json``.
"""

from __future__ import annotations

import math
import os
import shutil
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..model.model import Material, Model, Part

__all__ = ["FORMATS", "MIN_WALL_M", "PLANE_ANGLE_DEG", "PLANE_OFFSET_M", "RECTANGLE_COVER",
           "EnhanceResult", "EnhancedFacade", "WallFrame", "enhance"]

#: Model formats ``enhance`` reads (textured: OBJ with its .mtl, GLB with embedded images).
FORMATS: tuple[str, ...] = ("obj", "glb")
#: Faces of one wall: horizontal normals within this angle…
PLANE_ANGLE_DEG: float = 2.0
#: …and plane offsets within this distance (metres).
PLANE_OFFSET_M: float = 0.05
#: Walls smaller than this (metres) on a side are skipped: no facade to reconstruct.
MIN_WALL_M: float = 2.0
#: A wall whose faces cover less of its bounding rectangle than this is not a rectangle (a
#: gable end, a stepped wall): the largest rectangle in it is modelled, the rest keeps its
#: texture.
RECTANGLE_COVER: float = 0.98
#: A crop of the image by the classifier smaller than this share of a side is ignored.
_CROP_SHARE = 0.97
#: Largest resampling resolution, as a multiple of ``px_per_m`` (a dense texture keeps its
#: detail up to there).
_MAX_UPSCALE = 2.0
_UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class WallFrame:
    """A wall's plane frame: ``origin`` (the rectangle's bottom-left corner on the plane),
    ``u`` right, ``v`` up, ``n`` out of the wall; ``size_m`` its rectangle (width, height)."""

    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    n: np.ndarray
    size_m: tuple[float, float]

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Wall-frame points ``(x, y, z)`` (metres from ``origin``) in world coordinates."""
        p = np.asarray(points, float).reshape(-1, 3)
        return self.origin + p @ np.c_[self.u, self.v, self.n].T


@dataclass
class EnhancedFacade:
    """One reconstructed wall: its frame, the unwrapped image, the reconstruction and the
    facade's parts in world coordinates."""

    building: str
    wall: int
    folder: str
    frame: WallFrame
    image: np.ndarray
    reconstruction: Any
    parts: list[Part]
    record: dict


@dataclass
class EnhanceResult:
    """What :func:`enhance` made: the enhanced ``models`` (one per building of the input),
    the reconstructed ``facades``, the ``skipped`` walls (why) and the ``report``."""

    models: list[Model]
    facades: list[EnhancedFacade] = field(default_factory=list)
    skipped: list[dict] = field(default_factory=list)
    report: dict = field(default_factory=dict)
    written: list[Path] = field(default_factory=list)


# ---------------------------------------------------------------------------------- input
def _check_path(path: Path) -> str:
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise InputError(f"MODEL {path}: enhance reads a textured .obj (with its .mtl and "
                         "texture files) or .glb (embedded textures); convert the model to one "
                         "of them first")
    if not path.is_file():
        raise InputError(f"MODEL {path}: no such file; give a textured mass model (.obj with "
                         "its .mtl and textures, or .glb)")
    return suffix


def _check_px_per_m(px_per_m) -> float:
    try:
        value = float(px_per_m)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and 10.0 <= value <= 400.0):
        raise InputError(f"--px-per-m {px_per_m!r}: give the resampling resolution of the "
                         "unwrapped facades in pixels per metre, 10 to 400 (default 40)")
    return value


# ---------------------------------------------------------------------------------- walls
@dataclass
class _Wall:
    texture: str
    n: np.ndarray                    # horizontal unit normal
    offset: float
    faces: list[tuple[int, int]] = field(default_factory=list)  # (part index, face index)
    weight: float = 0.0


def _facade_faces(mesh) -> np.ndarray:
    """Indices of the faces of ``mesh`` that are facade faces (module docstring, step 1)."""
    from ..repair.model_textures import _UV_TOLERANCE, FACADE_NORMAL_UP

    if mesh.corner_uvs is None or not mesh.n_faces:
        return np.zeros(0, np.int64)
    sizes = np.diff(mesh.starts)
    normals = mesh.face_normals()
    ok = (sizes >= 3) & (np.abs(normals[:, 1]) < FACADE_NORMAL_UP) & (mesh.face_areas() > 1e-9)
    if not ok.any():
        return np.zeros(0, np.int64)
    uv = np.asarray(mesh.corner_uvs, float)
    full = sizes > 0
    lo = np.full((mesh.n_faces, 2), np.inf)
    hi = np.full((mesh.n_faces, 2), -np.inf)
    lo[full] = np.minimum.reduceat(uv, mesh.starts[:-1][full], axis=0)
    hi[full] = np.maximum.reduceat(uv, mesh.starts[:-1][full], axis=0)
    inside = (lo >= -_UV_TOLERANCE).all(axis=1) & (hi <= 1 + _UV_TOLERANCE).all(axis=1)
    return np.flatnonzero(ok & inside)


def _group_walls(parts: list[Part]) -> list[_Wall]:
    """The facade faces of one building's parts grouped by texture and plane."""
    cos_tol = math.cos(math.radians(PLANE_ANGLE_DEG))
    walls: list[_Wall] = []
    for pi, part in enumerate(parts):
        tex = part.material.texture
        if not tex or not part.mesh.n_faces:
            continue
        mesh = part.mesh
        idx = _facade_faces(mesh)
        if not len(idx):
            continue
        normals = mesh.face_normals()[idx]
        areas = mesh.face_areas()[idx]
        for f, nrm, area in zip(idx.tolist(), normals, areas):
            h = np.array([nrm[0], 0.0, nrm[2]])
            h /= np.linalg.norm(h)
            pts = mesh.vertices[mesh.corners[mesh.starts[f]:mesh.starts[f + 1]]]
            d = float((pts @ h).mean())
            for w in walls:
                if w.texture == tex and w.n @ h >= cos_tol and abs(w.offset - d) <= PLANE_OFFSET_M:
                    w.faces.append((pi, f))
                    total = w.weight + area
                    n = w.n * w.weight + h * area
                    w.n = n / np.linalg.norm(n)
                    w.offset = (w.offset * w.weight + d * area) / total
                    w.weight = total
                    break
            else:
                walls.append(_Wall(tex, h, d, [(pi, f)], float(area)))
    return walls


def _wall_corners(parts: list[Part], wall: _Wall) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) positions and (k, 2) UVs of every corner of the wall's faces."""
    pos, uvs = [], []
    for pi, f in wall.faces:
        mesh = parts[pi].mesh
        a, b = mesh.starts[f], mesh.starts[f + 1]
        pos.append(mesh.vertices[mesh.corners[a:b]])
        uvs.append(np.asarray(mesh.corner_uvs[a:b], float))
    return np.concatenate(pos), np.concatenate(uvs)


def _frame(wall: _Wall, pos: np.ndarray) -> WallFrame:
    n = wall.n
    u = np.cross(_UP, n)
    u /= np.linalg.norm(u)
    v = _UP.copy()
    uu, vv = pos @ u, pos @ v
    u0, v0 = float(uu.min()), float(vv.min())
    d = float((pos @ n).mean())
    origin = u0 * u + v0 * v + d * n
    return WallFrame(origin, u, v, n, (float(uu.max()) - u0, float(vv.max()) - v0))


def _fit_affine(frame: WallFrame, pos: np.ndarray, uvs: np.ndarray, shape) -> tuple[
        np.ndarray, float]:
    """The (2, 3) affine map from wall-frame ``(x, y, 1)`` (metres) to texture pixels
    ``(col, row)`` fitted to the corners, and its RMS residual in pixels."""
    h, w = shape[:2]
    rel = pos - frame.origin
    x, y = rel @ frame.u, rel @ frame.v
    design = np.c_[x, y, np.ones(len(x))]
    target = np.c_[uvs[:, 0] * w, (1.0 - uvs[:, 1]) * h]
    if np.linalg.matrix_rank(design[:, :2] - design[:, :2].mean(axis=0), tol=1e-6) < 2:
        return np.zeros((2, 3)), math.inf
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    resid = design @ coef - target
    return coef.T, float(np.sqrt((resid ** 2).sum(axis=1).mean()))


def _unwrap(pixels: np.ndarray, affine: np.ndarray, size_m, out_ppm: float, upsample: bool
            ) -> np.ndarray:
    """The wall rectangle resampled from the texture: row 0 at the top of the wall."""
    import cv2

    w_m, h_m = size_m
    out_w, out_h = max(1, round(w_m * out_ppm)), max(1, round(h_m * out_ppm))
    su, sv = w_m / out_w, h_m / out_h
    a = affine
    # output pixel (c, r) centre → wall (x, y) = ((c + .5) su, h_m - (r + .5) sv) → texture;
    # texture pixel coordinates put pixel k's centre at k + .5, OpenCV's at k
    m = np.array([[a[0, 0] * su, -a[0, 1] * sv,
                   a[0, 0] * 0.5 * su + a[0, 1] * (h_m - 0.5 * sv) + a[0, 2] - 0.5],
                  [a[1, 0] * su, -a[1, 1] * sv,
                   a[1, 0] * 0.5 * su + a[1, 1] * (h_m - 0.5 * sv) + a[1, 2] - 0.5]])
    rgb = np.ascontiguousarray(pixels[..., :3])
    flags = (cv2.INTER_CUBIC if upsample else cv2.INTER_LINEAR) | cv2.WARP_INVERSE_MAP
    return cv2.warpAffine(rgb, m, (out_w, out_h), flags=flags, borderMode=cv2.BORDER_REPLICATE)


def _wall_polygon(parts: list[Part], wall: _Wall, frame: WallFrame):
    """The union of the wall's faces in wall metres ``(x, y)`` from the rectangle's corner: a
    shapely geometry."""
    import shapely

    pieces = []
    basis = np.c_[frame.u, frame.v]
    for pi, f in wall.faces:
        mesh = parts[pi].mesh
        xy = (mesh.vertices[mesh.face(f)] - frame.origin) @ basis
        g = shapely.Polygon(xy)
        if g.area > 1e-9:
            pieces.append(g if g.is_valid else g.buffer(0))
    return shapely.union_all(pieces).buffer(0) if pieces else shapely.Polygon()


def _largest_rectangle(polygon, size_m, step: float) -> tuple[float, float, float, float]:
    """The largest axis-aligned rectangle ``(x0, y0, x1, y1)`` inside ``polygon`` (wall metres),
    on a grid of ``step`` metres: cells whose four corners are inside, then the largest
    rectangle of such cells (one pass of the histogram-and-stack method a row)."""
    import shapely

    w_m, h_m = size_m
    nx, ny = max(1, math.ceil(w_m / step)), max(1, math.ceil(h_m / step))
    xs, ys = np.linspace(0.0, w_m, nx + 1), np.linspace(0.0, h_m, ny + 1)
    gx, gy = np.meshgrid(xs, ys)
    # (ny + 1, nx + 1) grid corners inside or on the boundary
    corner = shapely.contains_xy(polygon.buffer(1e-6), gx, gy)
    cells = corner[:-1, :-1] & corner[1:, :-1] & corner[:-1, 1:] & corner[1:, 1:]
    best, box = 0, (0, 0, 0, 0)
    heights = np.zeros(nx, np.int64)
    for r in range(ny):                    # rows from y = 0 up; heights: cells reaching down
        heights = np.where(cells[r], heights + 1, 0)
        stack: list[int] = []
        for c in range(nx + 1):
            hc = heights[c] if c < nx else 0
            while stack and heights[stack[-1]] >= hc:
                top = stack.pop()
                left = stack[-1] + 1 if stack else 0
                area = int(heights[top]) * (c - left)
                if area > best:
                    best, box = area, (left, r + 1 - int(heights[top]), c, r + 1)
            stack.append(c)
    c0, r0, c1, r1 = box
    return (float(xs[c0]), float(ys[r0]), float(xs[c1]), float(ys[r1]))


def _kept_texture(frame: WallFrame, polygon, inner: tuple[float, float, float, float],
                  affine: np.ndarray, shape, material: Material) -> list[Part]:
    """The wall outside ``inner = (x0, y0, x1, y1)`` (wall metres), with its original texture:
    what the classifier left out of the facade (sky, street), and the parts of a wall that is
    not a rectangle (a gable, a step) beyond the rectangle modelled.  ``polygon``: the wall's
    faces in wall metres."""
    import mapbox_earcut as earcut
    import shapely

    from ..geometry.holed import rings
    from ..geometry.mesh import Mesh

    rest = polygon.difference(shapely.box(*inner))
    h, w = shape[:2]
    parts = []
    for outer, holes in rings(rest):
        loops = [outer, *holes]
        xy = np.concatenate(loops)
        if shapely.Polygon(outer, holes).area < 1e-4:
            continue
        ends = np.cumsum([len(r) for r in loops]).astype(np.uint32)
        tri = np.asarray(earcut.triangulate_float64(xy, ends), np.int64).reshape(-1, 3)
        if not len(tri):
            continue
        local = np.c_[xy, np.zeros(len(xy))]
        px = xy @ affine[:, :2].T + affine[:, 2]
        uv = np.c_[px[:, 0] / w, 1.0 - px[:, 1] / h]
        faces = list(tri)
        mesh = Mesh(frame.to_world(local), faces=faces, uvs=[uv[t] for t in tri])
        parts.append(Part(mesh, label="wall", material=material, symbol="WallMargin"))
    return parts


def _cut(image: np.ndarray, rect, size_m) -> np.ndarray:
    """The part ``rect = (x0, y0, x1, y1)`` (wall metres, y up) of the unwrapped wall image."""
    h, w = image.shape[:2]
    sx, sy = w / size_m[0], h / size_m[1]
    c0, c1 = round(rect[0] * sx), round(rect[2] * sx)
    r0, r1 = round(h - rect[3] * sy), round(h - rect[1] * sy)
    return np.ascontiguousarray(image[max(r0, 0):min(r1, h), max(c0, 0):min(c1, w)])


def _crop_region(rec, size_px, size_m) -> tuple[float, float, float, float] | None:
    """The wall-metre rectangle ``(x0, y0, x1, y1)`` of the classifier's crop, or ``None``
    when it keeps (nearly) the whole image."""
    crop = rec.report.get("facade_crop")
    if not crop:
        return None
    cx0, cy0, cx1, cy1 = crop["box"]
    out_w, out_h = size_px
    if (cx1 - cx0) >= _CROP_SHARE * out_w and (cy1 - cy0) >= _CROP_SHARE * out_h:
        return None
    sx, sy = out_w / size_m[0], out_h / size_m[1]
    return (cx0 / sx, (out_h - cy1) / sy, cx1 / sx, (out_h - cy0) / sy)


def _place(model: Model, frame: WallFrame, region, size_m) -> list[Part]:
    """The facade model (facade frame, ``size_m`` big) into ``region`` of the wall (wall
    metres), then into world coordinates."""
    x0, y0, x1, y1 = region
    fx = (x1 - x0) / size_m[0] if size_m[0] > 0 else 1.0
    fy = (y1 - y0) / size_m[1] if size_m[1] > 0 else 1.0
    basis = np.c_[frame.u, frame.v, frame.n]
    matrix = basis @ np.diag([fx, fy, 1.0])
    offset = frame.origin + x0 * frame.u + y0 * frame.v
    out = []
    for p in model.parts:
        out.append(Part(p.mesh.transformed(matrix, offset), p.label, p.material, p.symbol,
                        p.shape_id))
    return out


def _windows(tree) -> int:
    return sum(1 for s in tree.leaves() if s.label == "window")


def _reconstruct(image, size_m, seed):
    """Reconstruct the unwrapped wall; a classifier crop (sky, street) is reconstructed again
    at its own size.  Returns (reconstruction, region on the wall in metres, notes)."""
    from ..reconstruction import reconstruct

    w_m, h_m = size_m
    rec = reconstruct(image, rectified=True, width_m=w_m, height_m=h_m, seed=seed)
    region = _crop_region(rec, (image.shape[1], image.shape[0]), size_m)
    notes = []
    if region is None:
        return rec, (0.0, 0.0, w_m, h_m), rec.report.get("facade", {}).get(
            "width_m", w_m), rec.report.get("facade", {}).get("height_m", h_m), notes
    cx0, cy0, cx1, cy1 = rec.report["facade_crop"]["box"]
    cw, ch = region[2] - region[0], region[3] - region[1]
    notes.append(f"the classifier sees the facade in {cx1 - cx0}x{cy1 - cy0} px of the "
                 f"{image.shape[1]}x{image.shape[0]} px texture (sky or street around it): "
                 f"that part ({cw:.2f} x {ch:.2f} m) is modelled, the rest of the wall keeps "
                 "its texture")
    if min(cw, ch) >= MIN_WALL_M:
        crop = np.ascontiguousarray(image[cy0:cy1, cx0:cx1])
        try:
            again = reconstruct(crop, rectified=True, width_m=cw, height_m=ch, seed=seed)
        except InputError:
            again = None
        if again is not None:
            inner = _crop_region(again, (crop.shape[1], crop.shape[0]), (cw, ch))
            if inner is not None:
                region = (region[0] + inner[0], region[1] + inner[1],
                          region[0] + inner[2], region[1] + inner[3])
            rec = again
    # the model spans the facade the reconstruction analysed (its crop, at the scale given)
    fac = rec.report.get("facade", {})
    return rec, region, fac.get("width_m", cw), fac.get("height_m", ch), notes


@dataclass
class BuildingResult:
    """One building enhanced: its new ``model`` (walls replaced, every other face kept), the
    reconstructed ``facades``, the ``skipped`` walls and the number of faces kept."""

    model: Model
    facades: list[EnhancedFacade]
    skipped: list[dict]
    kept_faces: int


def enhance_building(model: Model, building: str, ppm: float, seed: int, textures: dict,
                     first: int = 0) -> BuildingResult:
    """Steps 1–4 of the module docstring on one building of a mass model: every textured wall
    unwrapped, reconstructed and replaced.  ``textures``: a cache (texture path → pixels or
    the problem reading them) shared by the buildings of one model; ``first``: the number of
    the first facade's folder (``facade_NN``)."""
    from ..repair.model_textures import _read_texture

    facades: list[EnhancedFacade] = []
    skipped: list[dict] = []
    parts = model.parts
    removed: dict[int, set[int]] = {}
    added: list[Part] = []
    for wi, wall in enumerate(_group_walls(parts)):
        entry: dict[str, Any] = {"building": building, "wall": wi,
                                 "texture": Path(wall.texture).name,
                                 "faces": len(wall.faces)}
        if wall.texture not in textures:
            textures[wall.texture] = _read_texture(wall.texture)
        pixels, problem = textures[wall.texture]
        pos, uvs = _wall_corners(parts, wall)
        frame = _frame(wall, pos)
        w_m, h_m = frame.size_m
        entry.update(width_m=round(w_m, 3), height_m=round(h_m, 3),
                     normal=[round(float(c), 4) for c in wall.n])
        if pixels is None:
            skipped.append({**entry, "reason": f"texture {entry['texture']}: {problem}"})
            continue
        if min(w_m, h_m) < MIN_WALL_M:
            skipped.append({**entry, "reason": f"wall of {w_m:.2f} x {h_m:.2f} m, "
                            f"smaller than {MIN_WALL_M:g} m a side"})
            continue
        affine, rms = _fit_affine(frame, pos, uvs, pixels.shape)
        tex_px = max(pixels.shape[:2])
        if not math.isfinite(rms) or rms > max(2.0, 0.02 * tex_px):
            skipped.append({**entry, "reason": "the UVs are not one affine image of "
                            f"the wall (residual {rms:.1f} px): not a facade texture"})
            continue
        along_u = float(np.linalg.norm(affine[:, 0]))
        along_v = float(np.linalg.norm(affine[:, 1]))
        src_ppm = float(math.sqrt(abs(np.linalg.det(affine[:, :2]))))
        if src_ppm <= 0:
            skipped.append({**entry, "reason": "the texture is degenerate on the wall "
                            "(zero pixels per metre)"})
            continue
        out_ppm = max(ppm, min(src_ppm, _MAX_UPSCALE * ppm))
        t = time.perf_counter()
        polygon = _wall_polygon(parts, wall, frame)
        cover = polygon.area / (w_m * h_m)
        rect = (0.0, 0.0, w_m, h_m)
        if cover < RECTANGLE_COVER:
            rect = _largest_rectangle(polygon, frame.size_m, min(0.1, min(w_m, h_m) / 50))
            rw, rh = rect[2] - rect[0], rect[3] - rect[1]
            entry.update(wall_cover=round(cover, 3), rectangle_m=[round(c, 3) for c in rect])
            if min(rw, rh) < MIN_WALL_M:
                skipped.append({**entry, "reason": f"the wall is not a rectangle ({cover:.0%} "
                                "of its bounding rectangle) and the largest rectangle in it, "
                                f"{rw:.2f} x {rh:.2f} m, is smaller than {MIN_WALL_M:g} m a "
                                "side"})
                continue
        image = _unwrap(pixels, affine, frame.size_m, out_ppm, src_ppm < out_ppm)
        entry.update(px_per_m=round(src_ppm, 3),
                     px_per_m_uv=[round(along_u, 3), round(along_v, 3)],
                     resampled_px_per_m=round(out_ppm, 3),
                     upsampled=round(out_ppm / src_ppm, 3),
                     image_px=[int(image.shape[1]), int(image.shape[0])])
        rect_size = (rect[2] - rect[0], rect[3] - rect[1])
        if rect != (0.0, 0.0, w_m, h_m):
            image = _cut(image, rect, frame.size_m)
        try:
            rec, region, fw, fh, notes = _reconstruct(image, rect_size, seed)
        except InputError as exc:
            skipped.append({**entry, "reason": f"reconstruction refused the unwrapped "
                            f"texture: {exc}"})
            continue
        if rec.model is None:
            skipped.append({**entry, "reason": "the reconstruction made no model"})
            continue
        region = (rect[0] + region[0], rect[1] + region[1], rect[0] + region[2],
                  rect[1] + region[3])
        if rect != (0.0, 0.0, w_m, h_m):
            notes.insert(0, f"the wall is not a rectangle (its faces cover {cover:.0%} of "
                         f"its {w_m:.2f} x {h_m:.2f} m bounding rectangle: a gable, a step): "
                         f"the largest rectangle in it, {rect_size[0]:.2f} x "
                         f"{rect_size[1]:.2f} m, is modelled, the rest keeps its texture")
        placed = _place(rec.model, frame, region, (fw, fh))
        if region != (0.0, 0.0, w_m, h_m):
            src_part = parts[wall.faces[0][0]]
            placed += _kept_texture(frame, polygon, region, affine, pixels.shape,
                                    src_part.material)
        for pi, f in wall.faces:
            removed.setdefault(pi, set()).add(f)
        added += placed
        folder = f"facade_{first + len(facades):02d}"
        entry.update(folder=folder, windows=_windows(rec.tree),
                     floors=rec.report.get("floors"), flags=list(rec.report.get(
                         "flags", [])), needs_review=bool(rec.report.get("needs_review")),
                     region_m=[round(float(c), 3) for c in region],
                     origin=[round(float(c), 4) for c in frame.origin],
                     u=[round(float(c), 4) for c in frame.u], notes=notes,
                     uv_residual_px=round(rms, 3),
                     seconds=round(time.perf_counter() - t, 3))
        if src_ppm < 0.75 * ppm:
            entry["notes"].append(f"source texture {src_ppm:.1f} px/m upsampled to "
                                  f"{out_ppm:g} px/m (bicubic): details below "
                                  f"{2 / src_ppm:.2f} m are guessed")
        facades.append(EnhancedFacade(building, wi, folder, frame, image, rec, placed,
                                      entry))
    kept = []
    for pi, part in enumerate(parts):
        gone = removed.get(pi)
        if not gone:
            kept.append(part)
            continue
        keep = [f for f in range(part.mesh.n_faces) if f not in gone]
        if keep:
            kept.append(Part(part.mesh.subset(keep), part.label, part.material,
                             part.symbol, part.shape_id))
    return BuildingResult(Model(parts=kept + added, name=building,
                                attributes=dict(model.attributes)), facades, skipped,
                          sum(p.mesh.n_faces for p in kept))


# ---------------------------------------------------------------------------------- main
#: z-up coordinates (x, y, z) to facadeforge's y-up frame (x, z, -y): a rotation, so faces
#: keep their orientation
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def _turned(model: Model, rotation: np.ndarray) -> Model:
    """``model`` with every part's vertices rotated (``v @ rotation.T``)."""
    parts = [Part(p.mesh.with_vertices(p.mesh.vertices @ rotation.T), p.label, p.material,
                  p.symbol, p.shape_id) for p in model.parts]
    return Model(parts=parts, name=model.name, attributes=dict(model.attributes))


def _check_up(up: str) -> None:
    if up not in ("y", "z"):
        raise InputError(f"--up {up!r}: use y (glTF, facadeforge's models) or z (most city "
                         "models)")


def load_mass_model(path: Path, up: str, texture_dir: Path) -> list[Model]:
    """The buildings of a mass model file (``.obj``/``.glb``, checked by the caller) in
    facadeforge's y-up frame; a GLB's embedded textures are written into ``texture_dir``."""
    from ..exchange import load

    models = load(path, texture_dir=texture_dir) if _check_path(path) == "glb" else load(path)
    if up == "z":
        models = [_turned(m, Z_UP_TO_Y_UP) for m in models]
    return models


def _textured(models: list[Model]) -> bool:
    return any(p.material.texture and p.mesh.n_faces for m in models for p in m.parts)


def write_facade(folder: Path, facade: EnhancedFacade) -> None:
    """A reconstructed facade's files: ``rules.cga``, ``shape_tree.json`` and ``texture.png``
    (the unwrapped wall image)."""
    from PIL import Image

    from ..outdir import write_json

    folder.mkdir(parents=True)
    (folder / "rules.cga").write_text(facade.reconstruction.rules, encoding="utf-8")
    write_json(folder / "shape_tree.json", facade.reconstruction.tree.to_dict(), indent=1)
    Image.fromarray(facade.image).save(folder / "texture.png", compress_level=1)


def enhance(model_path: str | os.PathLike, out_dir: str | os.PathLike | None = None, *,
            px_per_m: float = 40, seed: int = 0, up: str = "y") -> EnhanceResult:
    """Replace every textured facade of a mass model by its procedural facade (module
    docstring).

    Parameters
    ----------
    model_path : path-like
        The textured mass model, ``.obj`` (its ``.mtl`` and textures beside it) or ``.glb``;
        y up, metres.
    out_dir : path-like, optional
        Write the OUTDIR (``model.glb``, ``model.city.json``, ``facade_NN/``, ``report.json``)
        there, atomically.
    px_per_m : float
        Resolution of the unwrapped facade images (pixels per metre, at least; a denser
        texture is kept up to twice this).  Textures coarser than this are upsampled
        bicubically.
    seed : int
        Seed of the reconstructions.
    up : {"y", "z"}
        The model's up axis.  A z-up model (city models from GIS and photogrammetry tools) is
        turned into the y-up frame facadeforge works in (``x, z, -y``) as it is read: the
        outputs are y-up (``model.glb``, as glTF has it) and z-up (``model.city.json``, as
        CityJSON has it), and the report's origins, directions and normals are in the y-up
        frame.

    Returns
    -------
    EnhanceResult

    Raises
    ------
    InputError
        Not an ``.obj``/``.glb`` file, a missing file, a bad ``px_per_m``, a model without
        textured faces, an OUTDIR that may not be replaced.
    """
    from ..exchange import export
    from ..scratch import scratch_dir

    t_start = time.perf_counter()
    path = Path(model_path)
    ppm = _check_px_per_m(px_per_m)
    _check_path(path)
    _check_up(up)
    inputs = {"MODEL": path}
    if out_dir is not None:
        from ..outdir import check_outdir

        check_outdir(out_dir, inputs)

    work = scratch_dir("facadeforge-enhance-")
    try:
        t = time.perf_counter()
        models = load_mass_model(path, up, work / "textures")
        load_s = time.perf_counter() - t
        if not _textured(models):
            raise InputError(f"MODEL {path} has no textured faces (no material with a texture "
                             "image), so there is no facade image to reconstruct; give a "
                             "textured mass model (.obj with its .mtl and textures, or .glb)")
        textures: dict = {}
        facades: list[EnhancedFacade] = []
        skipped: list[dict] = []
        out_models: list[Model] = []
        kept_faces = 0
        for mi, model in enumerate(models):
            b = enhance_building(model, model.name or f"building_{mi}", ppm, seed, textures,
                                 first=len(facades))
            facades += b.facades
            skipped += b.skipped
            kept_faces += b.kept_faces
            out_models.append(b.model)
        seconds = {"load": round(load_s, 3),
                   "facades": round(sum(f.record["seconds"] for f in facades), 3)}
        report = {
            "input": str(path),
            "px_per_m": ppm,
            "seed": seed,
            "buildings": len(models),
            "facades": [f.record for f in facades],
            "skipped": skipped,
            "summary": {"facades": len(facades), "skipped": len(skipped),
                        "windows": sum(f.record["windows"] for f in facades),
                        "kept_faces": kept_faces,
                        "seconds": seconds},
        }
        result = EnhanceResult(out_models, facades, skipped, report)
        if out_dir is not None:
            from ..outdir import write_outdir

            def write(stage: Path) -> None:
                from ..outdir import write_json

                t = time.perf_counter()
                export(out_models, stage / "model.glb")
                export(out_models, stage / "model.city.json")
                for f in facades:
                    write_facade(stage / f.folder, f)
                seconds["export"] = round(time.perf_counter() - t, 3)
                seconds["total"] = round(time.perf_counter() - t_start, 3)
                write_json(stage / "report.json", report)

            result.written = write_outdir(out_dir, write, inputs)
        else:
            seconds["total"] = round(time.perf_counter() - t_start, 3)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    # the kept parts' textures live in ``work`` as long as the result does
    weakref.finalize(result, shutil.rmtree, work, True)
    return result
