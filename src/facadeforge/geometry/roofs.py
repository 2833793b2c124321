"""CityEngine-style roofs: ``roofHip``, ``roofGable``, ``roofPyramid`` and ``roofShed``.

All functions work in the **local coordinates of the base polygon's plane**: the footprint is given as
``(N, 2)`` points ``(x, y)`` in that plane and every roof face comes back as a ``(k, 3)`` array with
``x, y`` in the plane and ``z`` the height above it, so the caller maps the faces into world space
with the shape's scope / face frame.  Faces are counter-clockwise seen from outside (sloped faces:
normal pointing up; vertical faces: normal pointing away from the building).

Every face carries the index of the footprint edge it belongs to (CityEngine exposes roof faces per
edge: "there is exactly one roof face per edge" for hip, pyramid and shed roofs) and a kind:

``"roof"``
    a sloped roof plane rising from its edge;
``"gable"``
    a vertical gable triangle (or polygon) standing on its edge (:func:`roof_gable`);
``"side"``
    a vertical face closing the roof volume above an edge (:func:`roof_shed`).

Hip and gable roofs are built on the straight skeleton (Aichholzer et al. 1995) computed by the
wavefront algorithm of :mod:`facadeforge.geometry.skeleton` (after Felkel & Obdržálek 1998): lifting
every point of the footprint to ``time * tan(angle)`` gives the roof whose planes all rise at
``angle`` from their eaves.  Gable roofs use the *weighted* straight skeleton with speed 0 for the
gable edges, so their faces become vertical and the ridges run out to them.

Edge indices refer to the footprint as given: edge ``i`` runs from vertex ``i`` to vertex ``i+1``; with
holes, the hole edges follow the outer edges (hole ``h`` edge ``j`` has index
``len(poly) + sum(len(holes[:h])) + j``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .mesh import Mesh
from .skeleton import TOLERANCE, clean_ring, straight_skeleton

__all__ = ["Roof", "roof_hip", "roof_gable", "roof_pyramid", "roof_shed", "gable_edges"]

_COLLINEAR = math.radians(1.0)  # edges turning by less form one straight side (gable detection)
_GABLE_PARALLEL = math.cos(math.radians(45.0))  # gable neighbours must be within 45° of antiparallel


@dataclass
class Roof:
    """Roof faces in the local coordinates of the footprint plane.

    Parameters
    ----------
    faces : list of (k, 3) float arrays
        Face polygons, ``z`` = height above the footprint plane, counter-clockwise seen from outside.
    edge_index : (F,) int
        Footprint edge each face belongs to.
    kind : list of str
        ``"roof"`` (sloped), ``"gable"`` (vertical gable end), ``"side"`` (vertical closing face)
        or ``"side.inner"`` (a closing face along a hole).
    pieces : list of int or None, optional
        Per face, the number of the face with holes it is a piece of (a shed plane round a
        courtyard is triangles of one face), ``None`` for a face of its own.
    """

    faces: list[np.ndarray] = field(default_factory=list)
    edge_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    kind: list[str] = field(default_factory=list)
    pieces: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.faces = [np.asarray(f, float).reshape(-1, 3) for f in self.faces]
        self.edge_index = np.asarray(self.edge_index, np.int64).reshape(-1)
        if len(self.kind) != len(self.faces) or len(self.edge_index) != len(self.faces):
            raise ValueError("Roof: faces, edge_index and kind must have the same length")
        self.pieces = list(self.pieces) or [None] * len(self.faces)

    def __len__(self) -> int:
        return len(self.faces)

    @property
    def height(self) -> float:
        """Highest point of the roof above the footprint plane."""
        return max((float(f[:, 2].max()) for f in self.faces), default=0.0)

    @property
    def vertical(self) -> np.ndarray:
        """Boolean mask of the vertical faces (gables and sides)."""
        return np.array([k != "roof" for k in self.kind], bool)

    def select(self, kind: str) -> Roof:
        """The faces of one kind."""
        idx = [i for i, k in enumerate(self.kind) if k == kind]
        return Roof([self.faces[i] for i in idx], self.edge_index[idx], [kind] * len(idx))

    def mesh(self) -> Mesh:
        """All faces as a :class:`~facadeforge.geometry.mesh.Mesh` (local coordinates)."""
        return Mesh.from_polygons(self.faces)


# ---------------------------------------------------------------------------------------------------
# footprint preparation
# ---------------------------------------------------------------------------------------------------
@dataclass
class _Footprint:
    rings: list[np.ndarray]  # cleaned rings, outer CCW, holes CW
    src: list[np.ndarray]  # per ring edge: input edge index (global)
    n_edges: int  # number of input edges
    scale: float

    @property
    def outer(self) -> np.ndarray:
        return self.rings[0]

    @property
    def holes(self) -> list[np.ndarray]:
        return self.rings[1:]

    @property
    def all_src(self) -> np.ndarray:
        return np.concatenate(self.src)


def _footprint(poly, holes=None) -> _Footprint:
    outer = np.asarray(poly, dtype=float)
    if outer.ndim != 2 or outer.shape[1] != 2:
        raise ValueError(f"roof: footprint must be an (N, 2) array, got shape {outer.shape}")
    rings_in = [outer] + [np.asarray(h, float).reshape(-1, 2) for h in (holes or [])]
    allpts = np.concatenate(rings_in)
    if not np.all(np.isfinite(allpts)):
        raise ValueError("roof: footprint has non-finite coordinates")
    scale = float(np.hypot(*(allpts.max(0) - allpts.min(0))))
    if scale <= 0:
        raise ValueError("roof: degenerate footprint")
    tol = TOLERANCE.distance * scale
    rings, srcs, off = [], [], 0
    for r, pts in enumerate(rings_in):
        n = len(pts)
        keep, src = clean_ring(pts, tol) if n else ([], [])
        if len(keep) < 3:
            raise ValueError("roof: footprint ring with fewer than 3 distinct vertices")
        ring = pts[keep]
        src = np.asarray(src) + off
        area = _signed_area(ring)
        if area == 0:
            raise ValueError("roof: footprint ring with zero area")
        if (area > 0) != (r == 0):
            m = len(ring)
            ring = ring[::-1]
            src = src[[(m - 2 - j) % m for j in range(m)]]
        rings.append(ring)
        srcs.append(src)
        off += n
    return _Footprint(rings, srcs, off, scale)


def _signed_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _tan(angle_deg: float) -> float:
    a = float(angle_deg)
    if not (0.0 <= a < 90.0):
        raise ValueError(f"roof: angle must be in [0, 90) degrees, got {angle_deg}")
    return math.tan(math.radians(a))


def _edge_frames(ring: np.ndarray):
    d = np.roll(ring, -1, axis=0) - ring
    d = d / np.linalg.norm(d, axis=1)[:, None]
    n = np.column_stack([-d[:, 1], d[:, 0]])
    return d, n


def _offset_ring(ring: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Ring with edge ``j`` moved outward by ``dist[j]`` (mitre joins)."""
    _, n = _edge_frames(ring)
    out = np.empty_like(ring)
    m = len(ring)
    for j in range(m):
        a, b = (j - 1) % m, j
        na, nb, wa, wb = n[a], n[b], dist[a], dist[b]
        det = na[0] * nb[1] - na[1] * nb[0]
        if abs(det) < 1e-12:  # collinear edges
            if abs(wa - wb) > 1e-12 * max(1.0, abs(wa)):
                raise ValueError("roof: collinear adjacent edges with different overhangs")
            delta = wa * na
        else:
            delta = np.array([(wa * nb[1] - na[1] * wb) / det, (na[0] * wb - wa * nb[0]) / det])
        out[j] = ring[j] - delta
    return out


# ---------------------------------------------------------------------------------------------------
# hip
# ---------------------------------------------------------------------------------------------------
def roof_hip(poly: np.ndarray, angle_deg: float, overhang: float = 0.0, *,
             holes: Sequence[np.ndarray] | None = None) -> Roof:
    """Hip roof (CGA ``roofHip(angle, overhang)``).

    Every footprint edge gets a roof plane rising at ``angle_deg``; the planes are cut with each other
    along the straight skeleton, so the height of the roof over a point is its skeleton time (its
    distance to the wavefront origin) times ``tan(angle)``.

    Parameters
    ----------
    poly : (N, 2) float
        Footprint in its plane, counter-clockwise (clockwise is accepted).
    angle_deg : float
        Roof slope in degrees, ``0 <= angle < 90``.
    overhang : float
        Eaves overhang, measured horizontally perpendicular to the edges: the roof planes are continued
        outward down to the footprint offset by ``overhang`` with mitre joins, i.e. the eaves lie at
        ``z = -overhang * tan(angle)``.  Large overhangs on concave footprints may overlap.
    holes : list of (M, 2) float, optional
        Courtyards (clockwise).

    Returns
    -------
    Roof
        One sloped face per (non-degenerate) footprint edge.

    Examples
    --------
    >>> r = roof_hip(np.array([[0, 0], [4, 0], [4, 2], [0, 2]], float), 45.0)
    >>> sorted(len(f) for f in r.faces), round(r.height, 6)
    ([3, 3, 4, 4], 1.0)
    """
    tan = _tan(angle_deg)
    fp = _footprint(poly, holes)
    sk = straight_skeleton(fp.outer, fp.holes)
    src = fp.all_src
    z = sk.times * tan
    faces, edges = [], []
    for k, f in enumerate(sk.faces):
        if len(f) < 3:
            continue
        pts = np.column_stack([sk.nodes[f], z[f]])
        if overhang:
            for j in (0, 1):
                pts[j, :2] = sk.nodes[f[j]] - overhang * sk.miter[f[j]]
                pts[j, 2] = -overhang * tan
        faces.append(pts)
        edges.append(src[k])
    return Roof(faces, edges, ["roof"] * len(faces))


# ---------------------------------------------------------------------------------------------------
# gable
# ---------------------------------------------------------------------------------------------------
def _straight_sides(ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge collinear edges: (indices of corner vertices, side id of every ring edge)."""
    d, _ = _edge_frames(ring)
    m = len(ring)
    prev = np.roll(d, 1, axis=0)
    cross = prev[:, 0] * d[:, 1] - prev[:, 1] * d[:, 0]
    dot = np.einsum("ij,ij->i", prev, d)
    flat = (np.abs(cross) < _COLLINEAR) & (dot > 0)
    corners = np.nonzero(~flat)[0]
    if len(corners) < 3:
        raise ValueError("roof: footprint has fewer than 3 corners")
    side = np.empty(m, np.int64)
    for s, c in enumerate(corners):
        end = corners[(s + 1) % len(corners)]
        j = c
        while True:
            side[j] = s
            j = (j + 1) % m
            if j == end:
                break
    return corners, side


def _gable_sides(fp: _Footprint, index: int | None) -> list[np.ndarray]:
    """Per ring: boolean mask over its edges, True for gable edges."""
    merged, sides = [], []
    for ring in fp.rings:
        corners, side = _straight_sides(ring)
        merged.append(ring[corners])
        sides.append(side)
    masks = [np.zeros(len(r), bool) for r in fp.rings]
    if index is not None:
        idx = int(index) % fp.n_edges
        for r, src in enumerate(fp.src):
            hit = np.nonzero(src == idx)[0]
            if len(hit) == 0:
                continue
            s0 = sides[r][hit[0]]
            dm, _ = _edge_frames(merged[r])
            opp = int(np.argmin(dm @ dm[s0]))
            for s in {int(s0), opp}:
                masks[r] |= sides[r] == s
            return masks
        raise ValueError(f"roof_gable: edge index {index} is a zero-length edge")
    try:
        sk = straight_skeleton(merged[0], merged[1:])
    except ValueError:  # straightening the sides broke the footprint: no gables, hip roof
        return masks
    off = 0
    for r, mring in enumerate(merged):
        m = len(mring)
        d, _ = _edge_frames(mring)
        cands = []
        for s in range(m):
            face = sk.faces[off + s]
            p, q = d[(s - 1) % m], d[(s + 1) % m]
            convex = (p[0] * d[s][1] - p[1] * d[s][0] > 0) and (d[s][0] * q[1] - d[s][1] * q[0] > 0)
            if len(face) == 3 and convex and p @ q < -_GABLE_PARALLEL:
                length = float(np.linalg.norm(mring[(s + 1) % m] - mring[s]))
                cands.append((length, s))
        chosen: set[int] = set()
        for _, s in sorted(cands):
            if (s - 1) % m not in chosen and (s + 1) % m not in chosen:
                chosen.add(s)
        masks[r] = np.isin(sides[r], list(chosen))
        off += m
    return masks


def gable_edges(poly: np.ndarray, holes: Sequence[np.ndarray] | None = None, *,
                index: int | None = None) -> np.ndarray:
    """Footprint edges that :func:`roof_gable` turns into vertical gable ends.

    Rule: collinear consecutive edges are merged into straight sides; a side is a gable candidate if
    both its corners are convex, its hip-roof face is a triangle (it caps a ridge) and its two
    neighbouring sides are within 45° of antiparallel.  Candidates are taken shortest first, skipping
    sides adjacent to an already chosen one (so a square gets two opposite gables, a rectangle its two
    short sides, an L or T shape the ends of its wings).  With ``index`` (CGA ``roofGable(..., index)``,
    meant for convex footprints) the gables are the side containing edge ``index`` and the side most
    antiparallel to it.

    Returns
    -------
    (G,) int
        Sorted input edge indices.
    """
    fp = _footprint(poly, holes)
    masks = _gable_sides(fp, index)
    return np.unique(np.concatenate([src[m] for src, m in zip(fp.src, masks)])).astype(np.int64)


def roof_gable(poly: np.ndarray, angle_deg: float, overhang_x: float = 0.0,
               overhang_y: float | None = None, even: bool = False, *, index: int | None = None,
               holes: Sequence[np.ndarray] | None = None) -> Roof:
    """Gable roof (CGA ``roofGable(angle, overhangX, overhangY, even, index)``).

    A hip roof whose end faces are replaced by vertical gables: the gable edges (see
    :func:`gable_edges`) get speed 0 in a weighted straight skeleton, so their faces stand vertically
    on the edge and the ridges run out to them.  For a rectangle this is the textbook gable roof: two
    sloped quads along the long sides and two vertical triangles on the short sides, ridge height
    ``short / 2 * tan(angle)``.  Footprints without a suitable side (e.g. a regular hexagon) get a
    hip roof.

    Parameters
    ----------
    poly : (N, 2) float
        Footprint (counter-clockwise; clockwise is accepted).
    angle_deg : float
        Slope of the sloped faces in degrees, ``0 <= angle < 90``.
    overhang_x : float
        Overhang at the eaves (perpendicular to the ridges), measured horizontally: the eaves lie at
        ``z = -overhang_x * tan(angle)``.
    overhang_y : float, optional
        Overhang at the gable ends (along the ridges): the gables move outward by this distance.
        ``None`` (default) uses ``overhang_x``, as CityEngine does.
    even : bool
        If true, every ridge network is raised to its highest point so that all ridges are horizontal
        (for non-rectangular footprints the faces then become non-planar, as in CityEngine).
    index : int, optional
        Force the gables onto the side containing this edge and the side most antiparallel to it.
    holes : list of (M, 2) float, optional
        Courtyards (clockwise).

    Returns
    -------
    Roof
        Sloped faces (``"roof"``) and vertical gable faces (``"gable"``).

    Notes
    -----
    The gable faces always stand on their footprint edges (they continue the facade below them).
    Overhangs extend only the sloped faces: they are built on the footprint offset outward (eaves by
    ``overhang_x``, gable edges by ``overhang_y``, mitre joins) with the eaves lowered by
    ``overhang_x * tan(angle)``, so they run past the gable walls by ``overhang_y``.  If the offset
    polygon self-intersects the overhang is too large for the footprint and :class:`ValueError` is
    raised.  Should the weighted skeleton fail, a hip roof is returned with a warning.
    """
    tan = _tan(angle_deg)
    fp = _footprint(poly, holes)
    oy = overhang_x if overhang_y is None else overhang_y
    masks = _gable_sides(fp, index)
    if not any(m.any() for m in masks):
        return roof_hip(poly, angle_deg, overhang_x, holes=holes)
    weights = np.concatenate([np.where(m, 0.0, 1.0) for m in masks])
    try:
        sk = straight_skeleton(fp.outer, fp.holes, weights=weights)
        sk_roof, lower = sk, 0.0
        if overhang_x or oy:
            rings = [_offset_ring(r, np.where(m, oy, overhang_x)) for r, m in zip(fp.rings, masks)]
            try:
                sk_roof = straight_skeleton(rings[0], rings[1:], weights=weights)
            except ValueError as exc:
                if "not simple" in str(exc):
                    raise ValueError(
                        f"roof_gable: overhang too large for this footprint ({exc})") from None
                raise
            lower = overhang_x
    except ValueError as exc:
        if str(exc).startswith("roof_gable"):
            raise
        warnings.warn(f"roof_gable: gable skeleton failed ({exc}); building a hip roof", stacklevel=2)
        return roof_hip(poly, angle_deg, overhang_x, holes=holes)
    z_gable = sk.times * tan
    z_roof = (sk_roof.times - lower) * tan
    if even:
        z_gable, z_roof = _even_ridges(sk, z_gable), _even_ridges(sk_roof, z_roof)
    src = fp.all_src
    gable = np.concatenate(masks)
    faces, edges, kinds = [], [], []
    for k in range(len(gable)):
        s, z = (sk, z_gable) if gable[k] else (sk_roof, z_roof)
        f = s.faces[k]
        if len(f) < 3:
            continue
        faces.append(np.column_stack([s.nodes[f], z[f]]))
        edges.append(src[k])
        kinds.append("gable" if gable[k] else "roof")
    return Roof(faces, edges, kinds)


def _even_ridges(sk, z: np.ndarray) -> np.ndarray:
    """Raise every connected network of interior nodes to its highest node."""
    z = z.copy()
    interior = np.zeros(len(sk.nodes), bool)
    interior[sk.n_input:] = True
    parent = np.arange(len(sk.nodes))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in sk.arcs:
        if interior[a] and interior[b]:
            parent[find(a)] = find(b)
    roots = np.array([find(i) for i in range(len(parent))])
    for r in np.unique(roots[interior]):
        sel = interior & (roots == r)
        z[sel] = z[sel].max()
    return z


# ---------------------------------------------------------------------------------------------------
# pyramid and shed
# ---------------------------------------------------------------------------------------------------
def roof_pyramid(poly: np.ndarray, angle_deg: float, *, reference_edge: int | None = None,
                 center: str = "centroid") -> Roof:
    """Pyramid roof (CGA ``roofPyramid(angle)``): one triangle per edge meeting in an apex.

    Parameters
    ----------
    poly : (N, 2) float
        Footprint (counter-clockwise; clockwise is accepted).
    angle_deg : float
        Slope in degrees, ``0 <= angle < 90``.
    reference_edge : int, optional
        Edge whose triangle gets exactly the slope ``angle_deg`` (CityEngine uses the first triangle).
        Default: the edge whose line is nearest to the apex, so no face is steeper than ``angle_deg``.
    center : {"centroid", "vertices"}
        Apex position in plan: the area-weighted centroid (default) or the average of the vertices
        (CityEngine's rule).

    Returns
    -------
    Roof
        One ``"roof"`` triangle per non-degenerate edge; the apex height is
        ``tan(angle) * distance(apex, reference edge line)``.

    Notes
    -----
    Meant for convex (or star-shaped around the apex) footprints; on other footprints triangles
    overlap in plan, exactly like CityEngine's pyramid roof.
    """
    tan = _tan(angle_deg)
    fp = _footprint(poly)
    ring, src = fp.outer, fp.src[0]
    if center == "centroid":
        x, y = ring[:, 0], ring[:, 1]
        x2, y2 = np.roll(x, -1), np.roll(y, -1)
        cr = x * y2 - x2 * y
        a = cr.sum() / 2
        c = np.array([((x + x2) * cr).sum(), ((y + y2) * cr).sum()]) / (6 * a)
    elif center == "vertices":
        c = ring.mean(0)
    else:
        raise ValueError(f"roof_pyramid: center must be 'centroid' or 'vertices', got {center!r}")
    _, n = _edge_frames(ring)
    dist = np.einsum("ij,ij->i", n, c[None, :] - ring)
    if reference_edge is None:
        pos = dist[dist > 0]
        ref = float(pos.min()) if len(pos) else 0.0
    else:
        hit = np.nonzero(src == int(reference_edge) % fp.n_edges)[0]
        if len(hit) == 0:
            raise ValueError(f"roof_pyramid: edge {reference_edge} has zero length")
        ref = float(dist[hit[0]])
    apex = np.array([c[0], c[1], max(ref, 0.0) * tan])
    m = len(ring)
    faces = [np.array([[*ring[j], 0.0], [*ring[(j + 1) % m], 0.0], apex]) for j in range(m)]
    return Roof(faces, src, ["roof"] * m)


def roof_shed(poly: np.ndarray, angle_deg: float, edge_index: int = 0, *,
              holes: Sequence[np.ndarray] | None = None) -> Roof:
    """Shed roof (CGA ``roofShed(angle, index)``): one plane rising from an edge, closed by walls.

    The roof plane contains the line of edge ``edge_index`` and rises at ``angle_deg`` across the
    footprint (``z = tan(angle) * distance to that line``).  If part of the footprint lies behind that
    line (the edge is not on the convex hull) the plane is lifted so that its lowest point touches
    the footprint plane.  The volume under the plane is closed by vertical ``"side"`` faces on every
    other edge (a triangle where one end has zero height).  A footprint with ``holes`` (clockwise
    rings, a courtyard) gets the plane over the face around them and ``"side.inner"`` walls
    along the holes' edges, as CityEngine's ``roof.side.inner`` faces.

    Parameters
    ----------
    poly : (N, 2) float
        Footprint (counter-clockwise; clockwise is accepted).
    angle_deg : float
        Slope in degrees, ``0 <= angle < 90``.
    edge_index : int
        Edge the roof rises from (CityEngine's ``index``, default 0).
    holes : sequence of (M, 2) float, optional
        Holes of the footprint.

    Returns
    -------
    Roof
        The sloped top face or faces (``"roof"``) followed by the ``"side"`` faces.
    """
    tan = _tan(angle_deg)
    fp = _footprint(poly, holes)
    ring, src = fp.outer, fp.src[0]
    hit = np.nonzero(src == int(edge_index) % len(np.asarray(poly)))[0]  # an outer edge
    if len(hit) == 0:
        raise ValueError(f"roof_shed: edge {edge_index} has zero length")
    _, n = _edge_frames(ring)
    normal, s_min = n[hit[0]], float((ring @ n[hit[0]]).min())

    def height(p: np.ndarray) -> np.ndarray:
        return (p @ normal - s_min) * tan

    zero = TOLERANCE.distance * fp.scale * max(tan, 1.0)
    if fp.holes:
        import shapely

        from .polygon import simple_pieces

        region = shapely.Polygon(ring, [h for h in fp.holes])
        tops = [np.column_stack([q, height(q)]) for q in simple_pieces(region)]
    else:
        tops = [np.column_stack([ring, height(ring)])]
    faces, edges, kinds = tops, [int(src[hit[0]])] * len(tops), ["roof"] * len(tops)
    pieces = [0 if fp.holes else None] * len(tops)  # with holes: the plane is one face
    for r, (rg, rsrc) in enumerate(zip(fp.rings, fp.src)):
        z, m = height(rg), len(rg)
        for j in range(m):
            a, b = j, (j + 1) % m
            if z[a] <= zero and z[b] <= zero:
                continue
            pts = [[*rg[a], 0.0], [*rg[b], 0.0]]
            if z[b] > zero:
                pts.append([*rg[b], z[b]])
            if z[a] > zero:
                pts.append([*rg[a], z[a]])
            faces.append(np.array(pts))
            edges.append(int(rsrc[j]))
            kinds.append("side" if r == 0 else "side.inner")
    return Roof(faces, edges, kinds, pieces + [None] * (len(faces) - len(pieces)))
