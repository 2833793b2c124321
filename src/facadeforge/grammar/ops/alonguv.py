"""``insertAlongUV``: an asset cut and bent along the shape's texture coordinates.

Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-insert-along-uv.htm
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry.mesh import EPS, Mesh, cross3, polygon_area, weld_ids
from ..values import CGARuntimeError
from . import operation
from .geometry import apply_asset_material, load_asset
from .subdivision import _clip_generic

_NAME = "insertAlongUV"
#: The most asset copies (u tiles summed over the faces) one call may lay.
MAX_TILES = 100_000
#: The most faces one call may make.
MAX_FACES = 2_000_000
_DIRECTIONS = ("scope.y", "vertex.normal")
_ALIGNMENTS = ("alignPosition", "keepPosition")


@operation(_NAME, 3, 5, selectors=(3, 4))
def op_insert_along_uv(call):
    """``insertAlongUV(uvSet, filePath, height[, heightDirection, heightAlignment])``.

    As the reference describes: the asset's x span is mapped to u in [0, 1] and repeated along
    u, its z span to -v (z's largest value at v = 0, its smallest at v = 1), its y span to
    ``height`` (world units, may be 0 or negative) along the scope's y axis (``scope.y``,
    default) or along the shape's vertex normals, computed from its welded faces and
    interpolated (``vertex.normal``).  ``alignPosition`` (default) puts the asset's bottom on the
    faces; ``keepPosition`` keeps its height relative to its origin (y scaled by the same
    factor).  The asset is cut at the borders of each face in uv space and bent onto it: an
    affine map on triangles, a bilinear one on quads; the reference maps assets onto triangles
    and quads only, so larger faces get nothing (a warning says so).

    Where the reference is silent: asset parts outside v in [0, 1] of a face get nothing (only u
    repeats); a flat asset (no z span) lies at v = 0.5; new faces keep the asset's own texture
    coordinates and materials; the scope is fitted to the new geometry, its orientation kept.
    Only uv set 0 is stored by this runtime, so another set is an error.
    """
    st = call.state
    height, keep_position, along_normals = _options(call)
    mesh, asset = load_asset(call, call.text(1))
    shape = st.geometry
    if not shape.n_faces:
        return
    if shape.corner_uvs is None:
        raise CGARuntimeError(f"{_NAME}: the shape has no texture coordinates; set them up first "
                              "(setupProjection(0, …) projectUV(0))")
    source = _AssetInUV(mesh, height, keep_position)
    normals = _vertex_normals(shape) if along_normals else None
    patches, skipped = _patches(shape, normals, st.scope.rotation[:, 1])
    if skipped:
        call.derivation.warn(f"{_NAME}: {skipped} face(s) with more than 4 corners get no asset "
                             "(it is mapped onto triangles and quads only)")
    polys, uvs, faces = _lay(source, patches)
    st.geometry = Mesh.from_polygons(polys, uvs if mesh.corner_uvs is not None else None)
    if st.geometry.n_faces:
        st.fit_scope()
    if asset is not None:
        fm = asset.face_material
        apply_asset_material(st, asset, None if fm is None else fm[np.asarray(faces, int)])


def _options(call) -> tuple[float, bool, bool]:
    """The checked arguments: height, keepPosition?, along vertex normals?"""
    uv_set = call.num(0)
    if not math.isfinite(uv_set) or uv_set != int(uv_set) or not 0 <= uv_set <= 9:
        raise CGARuntimeError(f"{_NAME}: uvSet must be an integer in [0, 9], got {uv_set:g}")
    if uv_set != 0:
        raise CGARuntimeError(f"{_NAME}: only uv set 0 is kept by this runtime; set up uv set 0 "
                              "(setupProjection(0, …) projectUV(0)) and insert along it")
    direction, alignment = call.sel(3, "scope.y"), call.sel(4, "alignPosition")
    if direction not in _DIRECTIONS:
        raise CGARuntimeError(f"{_NAME}: heightDirection is scope.y or vertex.normal, "
                              f"not '{direction}'")
    if alignment not in _ALIGNMENTS:
        raise CGARuntimeError(f"{_NAME}: heightAlignment is alignPosition or keepPosition, "
                              f"not '{alignment}'")
    height = call.num(2)
    if not math.isfinite(height):
        raise CGARuntimeError(f"{_NAME}: height must be a finite number")
    return height, alignment == "keepPosition", direction == "vertex.normal"


class _AssetInUV:
    """The asset's corners in (u, v, h) of the first tile, its texture coordinates, and each
    face's u/v bounding box."""

    def __init__(self, mesh: Mesh, height: float, keep_position: bool):
        if not mesh.n_faces:
            raise CGARuntimeError(f"{_NAME}: the asset has no faces")
        p = mesh.vertices[mesh.corners]
        lo, hi = p.min(axis=0), p.max(axis=0)
        ext = hi - lo
        if ext[0] <= EPS:
            raise CGARuntimeError(f"{_NAME}: the asset has no width along x, so it cannot be "
                                  "laid along u; turn it (its x runs along u)")
        u = (p[:, 0] - lo[0]) / ext[0]
        v = (hi[2] - p[:, 2]) / ext[2] if ext[2] > EPS else np.full(len(p), 0.5)
        base = 0.0 if keep_position else lo[1]
        if ext[1] > EPS:
            h = (p[:, 1] - base) * (height / ext[1])
        else:                                  # a flat asset: on the faces, or at its own y
            h = p[:, 1] - base
        self.uvh = np.column_stack([u, v, h])
        self.tex = mesh.corner_uvs
        self.starts = mesh.starts
        first = mesh.starts[:-1]
        self.box_lo = np.minimum.reduceat(self.uvh[:, :2], first, axis=0)
        self.box_hi = np.maximum.reduceat(self.uvh[:, :2], first, axis=0)
        self.flips = height < 0

    def rows(self, face: int) -> np.ndarray:
        """(k, 3 or 5) corner rows of a face: u, v, h and the texture coordinates if any."""
        c0, c1 = self.starts[face], self.starts[face + 1]
        if self.tex is None:
            return self.uvh[c0:c1]
        return np.column_stack([self.uvh[c0:c1], self.tex[c0:c1]])


def _vertex_normals(shape: Mesh) -> np.ndarray:
    """(C, 3) unit normal per corner: the area-weighted face normals around each welded
    vertex (the reference computes them from the shape's geometry, merging duplicates)."""
    w = weld_ids(shape.vertices)[shape.corners]
    face_of = np.repeat(np.arange(shape.n_faces), shape.face_sizes)
    newell = shape._newell()
    acc = np.zeros((w.max() + 1, 3))
    np.add.at(acc, w, newell[face_of])
    n = acc[w]
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > EPS, n / np.maximum(length, EPS), 0.0)


class _Patch:
    """A triangle or convex quad of the shape in uv space with its corners' positions and
    height directions: maps (u, v) inside it to points and directions on the surface."""

    def __init__(self, uv, pos, dirs):
        self.uv, self.pos, self.dirs = uv, pos, dirs
        e = np.roll(uv, -1, axis=0) - uv
        area2 = float(np.sum(uv[:, 0] * np.roll(uv[:, 1], -1) - np.roll(uv[:, 0], -1) * uv[:, 1]))
        sign = 1.0 if area2 > 0 else -1.0
        # inside: a·u + b·v + c >= 0 for every edge (left of it when counter-clockwise)
        self.halfplanes = np.column_stack([-e[:, 1] * sign, e[:, 0] * sign,
                                           (e[:, 1] * uv[:, 0] - e[:, 0] * uv[:, 1]) * sign])
        self.lo, self.hi = uv.min(axis=0), uv.max(axis=0)
        self.area = abs(area2) / 2
        self.size = max(float((self.hi - self.lo).max()), EPS)

    def weights(self, p: np.ndarray) -> np.ndarray:
        """(N, k) corner weights of uv points ``p`` (N, 2): barycentric or inverse bilinear."""
        q = self.uv
        h = p - q[0]
        if len(q) == 3:
            m = np.column_stack([q[1] - q[0], q[2] - q[0]])
            s, t = np.linalg.solve(m, h.T)
            return np.column_stack([1 - s - t, s, t])
        s, t = _inverse_bilinear(q, h)
        return np.column_stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t])

    def orientation(self) -> float:
        """+1 where the asset keeps its handedness on this patch (x → u, y → height direction,
        z → -v), -1 where it is mirrored (uv wound the other way round)."""
        c = self.uv.mean(axis=0)[None]
        eps = 1e-4 * max(float(np.ptp(self.uv, axis=0).max()), EPS)
        d = [(self.weights(c + [eps, 0]) - self.weights(c)) @ self.pos,
             (self.weights(c + [0, eps]) - self.weights(c)) @ self.pos]
        up = self.weights(c) @ self.dirs
        det = float(np.dot(cross3(d[0][0], up[0]), -d[1][0]))
        return -1.0 if det < 0 else 1.0


def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _inverse_bilinear(q: np.ndarray, h: np.ndarray):
    """(s, t) with q0 + s·e + t·f + s·t·g = q0 + h for a quad q (4, 2), points h (N, 2)."""
    e, f, g = q[1] - q[0], q[3] - q[0], q[0] - q[1] + q[2] - q[3]
    k2 = _cross2(g, f)
    k1 = _cross2(e, f) + _cross2(h, g)
    k0 = _cross2(h, e)
    if abs(k2) < 1e-12 * max(abs(_cross2(e, f)), EPS):
        t = -k0 / k1
    else:
        w = np.sqrt(np.maximum(k1 * k1 - 4 * k0 * k2, 0.0))
        t1, t2 = (-k1 - w) / (2 * k2), (-k1 + w) / (2 * k2)
        t = np.where(np.abs(t1 - 0.5) <= np.abs(t2 - 0.5), t1, t2)
    d = e + g * t[:, None]
    s = np.einsum("ij,ij->i", h - f * t[:, None], d) / np.maximum(np.einsum("ij,ij->i", d, d), EPS)
    return s, t


def _patches(shape: Mesh, normals, scope_y):
    """Patches of the shape's triangles and quads (a quad not convex in uv: two triangles),
    and how many larger faces were skipped."""
    out, skipped = [], 0
    for f in range(shape.n_faces):
        c0, c1 = shape.starts[f], shape.starts[f + 1]
        if c1 - c0 > 4:
            skipped += 1
            continue
        uv = shape.corner_uvs[c0:c1]
        pos = shape.vertices[shape.corners[c0:c1]]
        dirs = normals[c0:c1] if normals is not None else np.tile(scope_y, (c1 - c0, 1))
        corners = [list(range(c1 - c0))]
        if c1 - c0 == 4 and not _convex(uv):
            corners = [[0, 1, 2], [0, 2, 3]]
        for idx in corners:
            patch = _Patch(uv[idx], pos[idx], dirs[idx])
            if patch.area > 1e-12:
                out.append(patch)
    return out, skipped


def _convex(uv: np.ndarray) -> bool:
    e = np.roll(uv, -1, axis=0) - uv
    turn = _cross2(e, np.roll(e, -1, axis=0))
    return bool(np.all(turn > EPS) or np.all(turn < -EPS))


def _lay(source: _AssetInUV, patches):
    """The asset's faces laid on every patch, u tile by u tile: (polygons, uvs, asset faces)."""
    spans = [(math.floor(p.lo[0]), max(math.ceil(p.hi[0]), math.floor(p.lo[0]) + 1))
             for p in patches]
    count = sum(b - a for a, b in spans)   # counted before any list is built
    if count > MAX_TILES:
        raise CGARuntimeError(f"{_NAME}: the shape's u range holds {count} asset copies "
                              f"(more than {MAX_TILES}); scale the uvs down (scaleUV, normalizeUV)")
    tiles = [(p, k) for p, (a, b) in zip(patches, spans) for k in range(a, b)]
    polys, uvs, faces = [], [], []
    flips = {id(p): p.orientation() * (-1.0 if source.flips else 1.0) < 0 for p in patches}
    for patch, k in tiles:
        flip = flips[id(patch)]
        tol = 1e-9 * patch.size
        near = np.flatnonzero((source.box_lo[:, 0] + k <= patch.hi[0] + tol)
                              & (source.box_hi[:, 0] + k >= patch.lo[0] - tol)
                              & (source.box_lo[:, 1] <= patch.hi[1] + tol)
                              & (source.box_hi[:, 1] >= patch.lo[1] - tol))
        for f in near:
            rows = source.rows(f).copy()
            rows[:, 0] += k
            piece = _clip_to_patch(rows, patch)
            if piece is None or not _owns(patch, piece, k):
                continue
            w = patch.weights(piece[:, :2])
            pts = w @ patch.pos + piece[:, 2:3] * _unit_rows(w @ patch.dirs)
            if polygon_area(pts) <= 1e-12:     # flattened (height 0) or squeezed to nothing
                continue
            if len(polys) >= MAX_FACES:
                raise CGARuntimeError(f"{_NAME}: more than {MAX_FACES} faces; use a simpler "
                                      "asset or fewer copies")
            tex = piece[:, 3:5] if piece.shape[1] >= 5 else None
            if flip:
                pts, tex = pts[::-1], None if tex is None else tex[::-1]
            polys.append(pts)
            uvs.append(tex)
            faces.append(int(f))
    return polys, uvs, faces


def _clip_to_patch(rows: np.ndarray, patch: _Patch):
    """The part of an asset face (rows of u, v, h[, tu, tv]) inside the patch, or None when
    nothing with an area (in u, v, h) is left."""
    a, b, c = patch.halfplanes.T
    dist = rows[:, 0:1] * a + rows[:, 1:2] * b + c
    tol = 1e-9 * patch.size
    if np.any(np.all(dist < -tol, axis=0)):
        return None
    piece = rows
    if not np.all(dist >= -tol):
        width = rows.shape[1]
        pts = np.column_stack([rows, dist]).tolist()
        for j in range(len(a)):
            pts = _clip_generic(pts, width + j, 0.0, keep_below=False)
            if len(pts) < 3:
                return None
        piece = np.array(pts)[:, :width]
    return piece if polygon_area(piece[:, :3]) > 1e-12 * patch.size else None


def _owns(patch: _Patch, piece: np.ndarray, k: int) -> bool:
    """Whether the patch takes a piece: always for one with an area in uv; a vertical one (a
    line in uv, which may lie on the border two patches share) only when its middle, nudged
    towards its asset copy's centre, is inside (so exactly one patch takes it)."""
    uv = piece[:, :2]
    if abs(_cross2(uv, np.roll(uv, -1, axis=0)).sum()) > 1e-12 * patch.size ** 2:
        return True
    mid = uv.mean(axis=0)
    nudged = mid + 1e-6 * patch.size * (np.array([k + 0.5, 0.5]) - mid) + 1e-9 * patch.size * np.array([1.0, 1.618])
    a, b, c = patch.halfplanes.T
    return bool(np.all(nudged[0] * a + nudged[1] * b + c >= 0))


def _unit_rows(d: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(length > EPS, d / np.maximum(length, EPS), 0.0)
