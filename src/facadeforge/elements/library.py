"""A parametric library of 3D architectural elements (Müller et al. 2007, §4).

§4 matches the rectangular regions of the facade subdivision against "3D objects in a library"
through their fronto-parallel 2D projections ``p(e_i)`` (the paper renders them in Maya; Fig. 11
shows 18 of 150).  This module is that library, generated from a handful of parametric builders
(windows, doors, balconies, sills/cornices, shop fronts) instead of hand-modelled assets, plus the
front renderer that produces ``p(e_i)``.

Geometry convention (the rule generator relies on it)
    Every element lives in the UNIT box: ``x, y ∈ [0, 1]`` over the element's rectangle (``y``
    up) and ``z ∈ [0, 1]``.  It is built in metres at a nominal size (``params`` ``width`` /
    ``height``) and then scaled, so frame widths keep realistic proportions.

    * ``mount == "recess"`` (windows, doors, shops): ``z = 1`` is the facade plane.  The element
      covers its whole rectangle at ``z = 1`` or through the opening, so inserting it into a
      rectangular hole of the wall leaves no gap: it includes the *reveal* (the side walls of the
      opening, label ``wall``) from ``z = 1`` back to the frame, the glass / door leaf at
      ``z ≈ 0.2``, frames and glazing bars as thin boxes in front of the glass, and *flush* parts
      (sill band, lintel, pediment, open shutters, arch spandrels) whose front face lies in the
      facade plane.  Nothing protrudes in front of ``z = 1``.
    * ``mount == "protrude"`` (balconies, sills, cornices): ``z = 0`` is the facade plane and
      ``z = 1`` the outermost point.

    Faces are wound counter-clockwise seen from outside (from the side their normal points to).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..model.labels import Labels
from ..model.model import Material, Model, Part

__all__ = ["ElementSpec", "LABEL_INDEX", "MATERIALS", "element_library", "element_model",
           "element_spec", "render_front"]

#: Canonical label index (the order of :class:`Labels`; identical to
#: ``facadeforge.exchange.raster.LABEL_INDEX`` and ``facadeforge.datasets.CANONICAL_INDEX``, which
#: are not imported because those packages are slow to import; a test keeps the three equal).
LABEL_INDEX: dict[str, int] = {label.value: i for i, label in enumerate(Labels)}

#: The materials of the library by name.
MATERIALS: dict[str, Material] = {m.name: m for m in (
    Material("glass", (0.30, 0.35, 0.42), 1.0, None, 0.35, 0.06),
    Material("frame_white", (0.93, 0.93, 0.90), 1.0, None, 0.0, 0.55),
    Material("frame_wood", (0.56, 0.37, 0.21), 1.0, None, 0.0, 0.7),
    Material("frame_metal", (0.22, 0.23, 0.25), 1.0, None, 0.8, 0.35),
    Material("door_wood", (0.52, 0.33, 0.18), 1.0, None, 0.0, 0.65),
    Material("door_green", (0.22, 0.40, 0.32), 1.0, None, 0.0, 0.5),
    Material("wall", (0.80, 0.74, 0.64), 1.0, None, 0.0, 0.95),
    Material("stone", (0.88, 0.85, 0.78), 1.0, None, 0.0, 0.9),
    Material("concrete", (0.66, 0.66, 0.64), 1.0, None, 0.0, 0.95),
    Material("shutter", (0.30, 0.45, 0.34), 1.0, None, 0.0, 0.7),
    Material("blind", (0.70, 0.68, 0.62), 1.0, None, 0.1, 0.6),
    Material("metal_dark", (0.10, 0.10, 0.11), 1.0, None, 0.85, 0.4),
    Material("sign", (0.55, 0.10, 0.09), 1.0, None, 0.0, 0.5),
)}


@dataclass(frozen=True)
class ElementSpec:
    """One variant of the library.

    Parameters
    ----------
    name : str
        Unique identifier, e.g. ``"window_mullion_2x2"``.
    kind : str
        Canonical label of the element (``window``, ``door``, ``balcony``, ``sill``, ``cornice``,
        ``shop``).
    mount : str
        ``"recess"`` (sits in an opening behind the facade plane) or ``"protrude"``.
    default_depth : float
        Recess depth or protrusion in metres (the extent that ``z ∈ [0, 1]`` stands for).
    params : tuple of (str, value)
        Generator parameters (hashable values), including the nominal ``width`` / ``height``.
    """

    name: str
    kind: str
    mount: str
    default_depth: float
    params: tuple = ()

    def param(self, key: str, default=None):
        for k, v in self.params:
            if k == key:
                return v
        return default

    @property
    def size(self) -> tuple[float, float]:
        """Nominal ``(width, height)`` in metres."""
        return float(self.param("width", 1.0)), float(self.param("height", 1.0))


# --------------------------------------------------------------------------------------------
# geometry helpers (metres in x, y; unit z)
# --------------------------------------------------------------------------------------------

def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _ccw(poly) -> np.ndarray:
    p = np.asarray(poly, float).reshape(-1, 2)
    return p if _signed_area(p) >= 0 else p[::-1]


def _prism(poly_xy, z0: float, z1: float, caps: bool = True) -> list[np.ndarray]:
    """Closed prism of a simple polygon extruded along ``z`` from ``z0`` to ``z1`` (outward
    faces, counter-clockwise seen from outside)."""
    p = _ccw(poly_xy)
    n = len(p)
    out = []
    if caps:
        out.append(np.column_stack([p, np.full(n, z1)]))  # front, normal +z
        out.append(np.column_stack([p[::-1], np.full(n, z0)]))  # back, normal -z
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        if np.allclose(a, b):
            continue
        # normal (dy, -dx, 0): outward for a counter-clockwise outline
        out.append(np.array([[a[0], a[1], z0], [b[0], b[1], z0], [b[0], b[1], z1],
                             [a[0], a[1], z1]]))
    return out


def _box(x0, x1, y0, y1, z0, z1) -> list[np.ndarray]:
    return _prism([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], z0, z1)


def _front(poly_xy, z: float) -> list[np.ndarray]:
    """One face at depth ``z`` facing +z."""
    p = _ccw(poly_xy)
    return [np.column_stack([p, np.full(len(p), z)])]


def _rect(x0, x1, y0, y1) -> list[tuple[float, float]]:
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def _tube_inward(outline: np.ndarray, z0: float, z1: float) -> list[np.ndarray]:
    """The reveal: side walls of an opening (counter-clockwise ``outline``) facing inwards (the
    side walls of :func:`_prism`, wound the other way)."""
    return [q[::-1] for q in _prism(outline, z0, z1, caps=False)]


def _extrude_x(profile_zy, x0: float, x1: float) -> list[np.ndarray]:
    """Prism of a profile given in the ``(z, y)`` plane, extruded along ``x``."""
    polys = _prism(profile_zy, x0, x1)  # in (u=z, v=y, w=x)
    # (u, v, w) -> (x=w, y=v, z=u) is a reflection: reverse the winding to keep faces outward
    return [p[::-1][:, [2, 1, 0]] for p in polys]


@dataclass(frozen=True)
class _Opening:
    """A rectangular opening with an optional round or segmental arch on top."""

    x0: float
    x1: float
    y0: float
    y1: float
    arch: str = "none"
    rise: float = 0.0
    nseg: int = 12

    @property
    def cx(self) -> float:
        return 0.5 * (self.x0 + self.x1)

    def _circle(self, inset: float) -> tuple[float, float, float]:
        """Centre y, radius, half angle of the arch at ``inset``."""
        r = 0.5 * (self.x1 - self.x0)
        if self.arch == "round":
            return self.y1 - r, r - inset, math.pi / 2
        s = self.rise
        big = (r * r + s * s) / (2 * s)
        ri = big - inset
        return self.y1 - big, ri, math.asin(min(1.0, (r - inset) / ri))

    def spring(self, inset: float = 0.0) -> float:
        if self.arch == "none":
            return self.y1 - inset
        cy, ri, th = self._circle(inset)
        return cy + ri * math.cos(th)

    def top_at(self, x: float, inset: float = 0.0) -> float:
        if self.arch == "none":
            return self.y1 - inset
        cy, ri, _ = self._circle(inset)
        return cy + math.sqrt(max(ri * ri - (x - self.cx) ** 2, 0.0))

    def outline(self, inset: float = 0.0) -> np.ndarray:
        """Counter-clockwise outline; same vertex count for every inset (for frame bands)."""
        x0, x1, y0 = self.x0 + inset, self.x1 - inset, self.y0 + inset
        pts = [(x0, y0), (x1, y0)]
        if self.arch == "none":
            pts += [(x1, self.y1 - inset), (x0, self.y1 - inset)]
        else:
            cy, ri, th = self._circle(inset)
            for a in np.linspace(math.pi / 2 - th, math.pi / 2 + th, self.nseg + 1):
                pts.append((self.cx + ri * math.cos(a), cy + ri * math.sin(a)))
            pts[2] = (x1, pts[2][1])  # exact side coordinates (no float drift)
            pts[-1] = (x0, pts[-1][1])
        return np.array(pts, float)


def _band(outer: np.ndarray, inner: np.ndarray, z0: float, z1: float) -> list[np.ndarray]:
    """A frame following an outline: one small prism per outline edge (mitred corners)."""
    out = []
    n = len(outer)
    for k in range(n):
        q = np.array([outer[k], outer[(k + 1) % n], inner[(k + 1) % n], inner[k]])
        if abs(_signed_area(q)) < 1e-12:
            continue
        out += _prism(q, z0, z1)
    return out


def _fill_above(arc: np.ndarray, top: float) -> list[np.ndarray]:
    """Wall fill at the facade plane between an arch (points left → right) and ``top``: two
    faces split at the apex, so neither pinches where the apex touches ``top``."""
    k = int(np.argmax(arc[:, 1]))
    out = []
    left = np.vstack([[(arc[0, 0], top)], arc[:k + 1], [(arc[k, 0], top)]])
    right = np.vstack([arc[k:], [(arc[-1, 0], top)], [(arc[k, 0], top)]])
    for poly in (left, right):
        poly = _dedupe(poly)
        if len(poly) >= 3 and abs(_signed_area(poly)) > 1e-10:
            out += _front(poly, 1.0)
    return out


def _spandrels(op: _Opening, top: float) -> list[np.ndarray]:
    """Wall fill at the facade plane between an arch and the rectangle's top edge."""
    if op.arch == "none":
        return []
    return _fill_above(op.outline(0.0)[2:][::-1], top)


def _clip_x(poly: np.ndarray, a: float, b: float) -> np.ndarray:
    """A convex polygon clipped to ``a <= x <= b`` (Sutherland–Hodgman)."""
    for sign, lim in ((1.0, a), (-1.0, b)):
        out = []
        n = len(poly)
        for i in range(n):
            p, q = poly[i], poly[(i + 1) % n]
            dp, dq = sign * (p[0] - lim), sign * (q[0] - lim)
            if dp >= 0:
                out.append(p)
            if dp * dq < 0:
                t = dp / (dp - dq)
                out.append(p + t * (q - p))
        poly = np.array(out)
    return _dedupe(poly)


def _slats(x0, x1, y0, y1, z0, z1, n: int, thick: float) -> list[np.ndarray]:
    out = []
    for k in range(1, n + 1):
        yc = y0 + (y1 - y0) * k / (n + 1)
        out += _box(x0, x1, yc - thick / 2, yc + thick / 2, z0, z1)
    return out


def _grid(op: _Opening, inset: float, cols: int, rows: int, bar: float, z0: float,
          z1: float) -> list[np.ndarray]:
    """Glazing bars (mullions and transoms) inside the frame of ``op``."""
    out = []
    ix0, ix1, iy0 = op.x0 + inset, op.x1 - inset, op.y0 + inset
    spring = op.spring(inset)
    for k in range(1, cols):
        x = ix0 + (ix1 - ix0) * k / cols
        out += _box(x - bar / 2, x + bar / 2, iy0, op.top_at(x, inset), z0, z1)
    for k in range(1, rows):
        y = iy0 + (spring - iy0) * k / rows
        out += _box(ix0, ix1, y - bar / 2, y + bar / 2, z0, z1)
    if op.arch != "none" and (cols > 1 or rows > 1):
        out += _box(ix0, ix1, spring - bar / 2, spring + bar / 2, z0, z1)  # fanlight transom
    return out


# --------------------------------------------------------------------------------------------
# builders: each returns (W, H, parts) with parts = list of (role, label, material, polys)
# --------------------------------------------------------------------------------------------

_Z_BACK, _Z_GLASS, _Z_BAR0, _Z_BAR1, _Z_FRAME1 = 0.10, 0.20, 0.18, 0.32, 0.40


def _window(spec: ElementSpec, kind: str = "window"):
    W, H = spec.size
    p = spec.param
    frame = float(p("frame", 0.06))
    cols, rows = int(p("cols", 1)), int(p("rows", 1))
    fmat = str(p("frame_material", "frame_white"))
    shutters, blind = str(p("shutters", "none")), float(p("blind", 0.0))
    head = str(p("head", "none"))
    sill = bool(p("sill", False))
    parts = []
    ox0, ox1 = 0.0, W
    if shutters == "open":
        ox0, ox1 = W / 4, 3 * W / 4
    oy0 = 0.09 if sill else 0.0
    head_h = {"none": 0.0, "lintel": 0.16, "pediment": 0.32, "segmental": 0.30}[head]
    oy1 = H - head_h
    arch = str(p("arch", "none"))
    rise = float(p("rise", 0.0)) or 0.18 * (ox1 - ox0)
    op = _Opening(ox0, ox1, oy0, oy1, arch, rise)
    outer, inner = op.outline(0.0), op.outline(frame)
    parts.append(("reveal", "wall", "wall", _tube_inward(outer, _Z_BACK, 1.0)))
    parts.append(("glass", kind, "glass", _front(inner, _Z_GLASS)))
    parts.append(("frame", kind, fmat, _band(outer, inner, _Z_BACK, _Z_FRAME1)))
    if cols > 1 or rows > 1 or (arch != "none" and p("fanlight", False)):
        parts.append(("bars", kind, fmat,
                      _grid(op, frame, cols, rows, 0.55 * frame, _Z_BAR0, _Z_BAR1)))
    parts.append(("spandrel", "wall", "wall", _spandrels(op, oy1)))
    if sill:
        parts.append(("sill", "sill", "stone", _box(0.0, W, 0.0, oy0, _Z_BACK, 1.0)))
    if head == "lintel":
        parts.append(("lintel", "molding", "stone", _box(0.0, W, oy1, H, 0.8, 1.0)))
    elif head in ("pediment", "segmental"):
        base = oy1 + 0.07
        parts.append(("lintel", "molding", "stone", _box(0.0, W, oy1, base, 0.8, 1.0)))
        if head == "pediment":
            ped = np.array([(0.0, base), (W, base), (W / 2, H)])
            fill = [f for c in ([(0.0, base), (W / 2, H), (0.0, H)],
                                [(W, base), (W, H), (W / 2, H)]) for f in _front(c, 1.0)]
        else:  # segmental pediment: an arc over the lintel
            arc = _Opening(0.0, W, base, H, "segmental", H - base, 10).outline(0.0)[2:]
            ped = arc  # right → apex → left, closed along the base line
            fill = _fill_above(arc[::-1], H)
        parts.append(("pediment", "molding", "stone", _prism(ped, 0.8, 1.0)))
        parts.append(("spandrel", "wall", "wall", fill))
    if shutters == "open":
        t = 0.025  # stile width of a shutter leaf (metres)
        for sx0, sx1 in ((0.0, ox0), (ox1, W)):
            polys = _box(sx0, sx1, oy0, oy1, 0.85, 0.95)
            for bx0, bx1, by0, by1 in ((sx0, sx0 + t, oy0, oy1), (sx1 - t, sx1, oy0, oy1),
                                       (sx0, sx1, oy0, oy0 + t), (sx0, sx1, oy1 - t, oy1)):
                polys += _box(bx0, bx1, by0, by1, 0.85, 1.0)
            polys += _slats(sx0 + t, sx1 - t, oy0 + t, oy1 - t, 0.9, 1.0,
                            int((oy1 - oy0) / 0.09), 0.02)
            parts.append(("shutter", "blind", "shutter", polys))
    elif shutters == "closed":
        polys = []
        top = op.spring(0.0)
        for sx0, sx1 in ((ox0, op.cx - 0.005), (op.cx + 0.005, ox1)):
            polys += _box(sx0, sx1, oy0, top, 0.55, 0.62)
            polys += _slats(sx0 + 0.04, sx1 - 0.04, oy0 + 0.05, top - 0.05, 0.62, 0.66,
                            int((top - oy0) / 0.09), 0.022)
        parts.append(("shutter", "blind", "shutter", polys))
    if blind > 0:
        top = op.spring(0.0)
        y = top - blind * (top - oy0)
        polys = _box(ox0, ox1, y, top, 0.50, 0.54)
        polys += _box(ox0, ox1, y - 0.03, y, 0.49, 0.56)  # bottom bar of the blind
        polys += _slats(ox0, ox1, y, top, 0.54, 0.56, int((top - y) / 0.06), 0.008)
        parts.append(("blind", "blind", "blind", polys))
    return W, H, parts


def _door(spec: ElementSpec):
    W, H = spec.size
    p = spec.param
    frame = float(p("frame", 0.08))
    leaves, panel_rows = int(p("leaves", 1)), int(p("panels", 2))
    glazed, transom = bool(p("glazed", False)), bool(p("transom", False))
    arch = str(p("arch", "none"))
    mat = str(p("material", "door_wood"))
    fmat = str(p("frame_material", "stone"))  # door case
    op = _Opening(0.0, W, 0.0, H, arch, float(p("rise", 0.0)) or 0.15 * W)
    outer, inner = op.outline(0.0), op.outline(frame)
    parts = [("reveal", "wall", "wall", _tube_inward(outer, _Z_BACK, 1.0)),
             ("frame", "door", fmat, _band(outer, inner, _Z_BACK, _Z_FRAME1)),
             ("spandrel", "wall", "wall", _spandrels(op, H))]
    ix0, ix1, iy0 = frame, W - frame, 0.0
    leaf_top = op.spring(frame)
    glass = []
    if transom:
        th = 0.35 if arch == "none" else 0.0
        leaf_top = leaf_top - th - frame
        parts.append(("transom", "door", fmat,
                      _box(ix0, ix1, leaf_top, leaf_top + frame, _Z_BACK, _Z_FRAME1)))
        light = _Opening(ix0, ix1, leaf_top + frame, op.top_at(op.cx, frame), arch,
                         op.rise) if arch != "none" else None
        glass += (_front(light.outline(0.0), _Z_GLASS) if light is not None else
                  _front(_rect(ix0, ix1, leaf_top + frame, H - frame), _Z_GLASS))
        if light is None:
            n = 3 if leaves == 1 else 5
            bars = []
            for k in range(1, n):
                x = ix0 + (ix1 - ix0) * k / n
                bars += _box(x - 0.015, x + 0.015, leaf_top + frame, H - frame, _Z_BAR0, _Z_BAR1)
            parts.append(("bars", "door", fmat, bars))
    leaf_polys, panel_polys = [], []
    z0, z1 = _Z_BACK + 0.05, _Z_GLASS + 0.05
    gap = 0.006
    edges = np.linspace(ix0, ix1, leaves + 1)
    for li in range(leaves):
        lx0, lx1 = edges[li] + (gap if li else 0.0), edges[li + 1] - (gap if li < leaves - 1 else 0)
        if arch != "none" and not transom:
            leaf = _clip_x(inner, lx0, lx1)  # the arched inner outline, this leaf's share
        else:
            leaf = np.array(_rect(lx0, lx1, iy0, leaf_top))
        leaf_polys += _prism(leaf, z0, z1)
        # raised panels (two columns per single leaf, one per leaf of a double door)
        pc = 2 if leaves == 1 else 1
        m = 0.09
        top = leaf_top if (transom or arch == "none") else op.spring(frame)
        py_edges = np.linspace(iy0 + m, top - m, panel_rows + 1)
        px_edges = np.linspace(lx0 + m, lx1 - m, pc + 1)
        for r in range(panel_rows):
            for c in range(pc):
                a0, a1 = px_edges[c] + m / 2 * (c > 0), px_edges[c + 1] - m / 2 * (c < pc - 1)
                b0, b1 = py_edges[r] + m / 2 * (r > 0), py_edges[r + 1] - m / 2 * (r < panel_rows - 1)
                if glazed and r == panel_rows - 1:
                    glass += _front(_rect(a0, a1, b0, b1), z1 + 0.005)
                else:
                    panel_polys += _box(a0 + 0.02, a1 - 0.02, b0 + 0.02, b1 - 0.02, z1, z1 + 0.1)
    parts.append(("leaf", "door", mat, leaf_polys))
    parts.append(("panels", "door", mat, panel_polys))
    if glass:
        parts.append(("glass", "door", "glass", glass))
    return W, H, parts


def _dedupe(poly: np.ndarray) -> np.ndarray:
    keep = [0] + [i for i in range(1, len(poly)) if not np.allclose(poly[i], poly[i - 1])]
    poly = poly[keep]
    if len(poly) > 1 and np.allclose(poly[0], poly[-1]):
        poly = poly[:-1]
    return poly


def _shop(spec: ElementSpec):
    W, H = spec.size
    p = spec.param
    sign = float(p("sign", 0.6))
    bays = int(p("bays", 3))
    door_bay = int(p("door_bay", -1))
    riser = float(p("riser", 0.0))
    arch = str(p("arch", "none"))
    fmat = str(p("frame_material", "frame_metal"))
    frame = 0.07
    oy1 = H - sign
    op = _Opening(0.0, W, 0.0, oy1, arch, 0.12 * W, 14)
    outer, inner = op.outline(0.0), op.outline(frame)
    parts = [("reveal", "wall", "wall", _tube_inward(outer, _Z_BACK, 1.0)),
             ("frame", "shop", fmat, _band(outer, inner, _Z_BACK, _Z_FRAME1)),
             ("spandrel", "wall", "wall", _spandrels(op, oy1))]
    if sign > 0:
        parts.append(("sign", "shop", "sign", _box(0.0, W, oy1, H, 0.85, 1.0)))
        # a pale lettering strip on the sign board, flush with the facade
        parts.append(("lettering", "shop", "stone",
                      _front(_rect(0.2 * W, 0.8 * W, oy1 + 0.3 * sign, oy1 + 0.7 * sign), 1.0)))
    ix0, ix1, iy0 = frame, W - frame, frame
    edges = np.linspace(ix0, ix1, bays + 1)
    bars, glass, riser_polys, door = [], [], [], []
    glass.append(_front(inner, _Z_GLASS)[0])
    for k in range(1, bays):
        x = edges[k]
        bars += _box(x - 0.04, x + 0.04, iy0, op.top_at(x, frame), _Z_BAR0, _Z_BAR1)
    spring = op.spring(frame)
    if arch != "none":
        bars += _box(ix0, ix1, spring - 0.04, spring + 0.04, _Z_BAR0, _Z_BAR1)
    transom_y = min(spring, 2.3) if arch == "none" else spring
    if arch == "none" and spring - iy0 > 2.6:
        bars += _box(ix0, ix1, transom_y - 0.04, transom_y + 0.04, _Z_BAR0, _Z_BAR1)
    for k in range(bays):
        if k == door_bay:
            a0, a1 = edges[k] + 0.04, edges[k + 1] - 0.04
            dtop = transom_y - 0.04 if arch == "none" else spring - 0.04
            door += _box(a0, a1, iy0, dtop, 0.23, 0.27)
            door += _box(a0 + 0.02, a0 + 0.06, 0.9, 1.1, 0.27, 0.3)  # handle
            glass += _front(_rect(a0 + 0.12, a1 - 0.12, 0.5, dtop - 0.12), 0.28)
        elif riser > 0:
            riser_polys += _box(edges[k] + 0.04, edges[k + 1] - 0.04, iy0, iy0 + riser,
                                0.22, 0.3)
    parts += [("glass", "shop", "glass", glass), ("bars", "shop", fmat, bars)]
    if riser_polys:
        parts.append(("riser", "shop", "stone", riser_polys))
    if door:
        parts.append(("door", "door", "frame_metal", door))
    return W, H, parts


def _balcony(spec: ElementSpec):
    W, H = spec.size
    D = spec.default_depth
    p = spec.param
    style = str(p("railing", "bars"))
    slab = float(p("slab", 0.15))
    spacing = float(p("spacing", 0.12))
    rail_t = 0.045 / D  # rail thickness in unit z
    parts = []
    y0 = 0.0
    if slab > 0:
        parts.append(("slab", "balcony", "concrete", _box(0.0, W, 0.0, slab, 0.0, 1.0)))
        y0 = slab
    mat = "metal_dark"
    polys = []
    top = H
    # top and bottom rails along the front and the two sides
    for ya, yb in ((top - 0.05, top), (y0, y0 + 0.04)):
        polys += _box(0.0, W, ya, yb, 1.0 - rail_t, 1.0)
        if D > 0.3:
            polys += _box(0.0, 0.04, ya, yb, 0.0, 1.0 - rail_t)
            polys += _box(W - 0.04, W, ya, yb, 0.0, 1.0 - rail_t)
    for x in (0.0, W - 0.05):
        polys += _box(x, x + 0.05, y0, top, 1.0 - rail_t, 1.0)  # corner posts
        if D <= 0.3:
            polys += _box(x, x + 0.05, top - 0.05, top, 0.0, 1.0 - rail_t)  # wall fixing
    if style == "solid":
        parts.append(("parapet", "balcony", "concrete",
                      _box(0.05, W - 0.05, y0 + 0.04, top - 0.05, 1.0 - 0.6 * rail_t, 1.0)))
        if D > 0.3:
            for x in (0.0, W - 0.04):
                parts[-1][3].extend(_box(x, x + 0.04, y0 + 0.04, top - 0.05, 0.0, 1.0 - rail_t))
    else:
        width = 0.018 if style == "bars" else 0.07
        n = max(int((W - 0.1) / spacing), 2)
        for k in range(1, n):
            x = 0.05 + (W - 0.1) * k / n
            polys += _box(x - width / 2, x + width / 2, y0 + 0.04, top - 0.05,
                          1.0 - rail_t * 0.8, 1.0 - rail_t * 0.2)
            if style == "balusters":  # a bulge in the middle of each baluster
                ym = y0 + 0.4 * (top - y0)
                polys += _box(x - width * 0.75, x + width * 0.75, ym - 0.12, ym + 0.12,
                              1.0 - rail_t, 1.0)
        if D > 0.3:
            m = max(int(D / spacing), 2)
            for k in range(1, m):
                z = k / m * (1.0 - rail_t)
                dz = 0.5 * width / D
                for x in (0.0, W - 0.04):
                    polys += _box(x + 0.01, x + 0.03, y0 + 0.04, top - 0.05, z - dz, z + dz)
    if style == "balusters":
        mat = "stone"
    parts.append(("railing", "balcony", mat, polys))
    return W, H, parts


def _profile(spec: ElementSpec):
    """Sills, ledges and cornices: a profile in the (z, y) plane extruded along x (unit z)."""
    W, H = spec.size
    p = spec.param
    shape = str(p("profile", "plain"))
    kind = spec.kind
    mat = "stone"
    if shape == "plain":
        prof = [(0, 0), (1, 0), (1, 0.7 * H), (0.8, H), (0, H)]  # chamfered top edge
    elif shape == "drip":  # sill with a sloped top and a drip groove
        prof = [(0, 0), (0.9, 0), (0.9, 0.25 * H), (1, 0.25 * H), (1, 0.8 * H), (0, H)]
    elif shape == "band":
        prof = [(0, 0), (0.7, 0), (1, 0.3 * H), (1, 0.75 * H), (0.6, H), (0, H)]
    elif shape == "stepped":
        prof = [(0, 0), (0.3, 0), (0.3, 0.25 * H), (0.6, 0.25 * H), (0.6, 0.5 * H),
                (1, 0.5 * H), (1, H), (0, H)]
    elif shape == "cove":
        prof = [(0, 0), (0.25, 0), (0.25, 0.15 * H)]
        for a in np.linspace(0, math.pi / 2, 9)[1:]:
            prof.append((0.25 + 0.6 * (1 - math.cos(a)), 0.15 * H + 0.6 * H * math.sin(a)))
        prof += [(1, 0.75 * H), (1, H), (0, H)]
    elif shape == "dentil":
        prof = [(0, 0), (0.25, 0), (0.25, 0.45 * H), (1, 0.6 * H), (1, H), (0, H)]
    else:
        raise InputError(f"unknown profile {shape!r} in element {spec.name!r}")
    # profile coordinates: u = z (unit), v = y (metres)
    prof = [(float(z), float(y)) for z, y in prof]
    parts = [("profile", kind, mat, _extrude_x(prof, 0.0, W))]
    if shape == "dentil":
        dent = []
        n = int(W / 0.12)
        for k in range(n):
            x0 = (k + 0.25) * W / n
            dent += _box(x0, x0 + 0.5 * W / n, 0.25 * H, 0.45 * H, 0.25, 0.5)
        parts.append(("dentils", kind, mat, dent))
    return W, H, parts


_BUILDERS = {"window": _window, "door": _door, "shop": _shop, "balcony": _balcony,
             "sill": _profile, "cornice": _profile}


# --------------------------------------------------------------------------------------------
# the library
# --------------------------------------------------------------------------------------------

def _spec(name: str, kind: str, mount: str, depth: float, **params) -> ElementSpec:
    return ElementSpec(name, kind, mount, depth, tuple(sorted(params.items())))


def _variants() -> Iterable[ElementSpec]:
    win = dict(width=1.2, height=1.6)

    def w(name, depth=0.25, **kw):
        return _spec(name, "window", "recess", depth, **{**win, **kw})

    yield w("window_plain")
    yield w("window_frame_thin", frame=0.035)
    yield w("window_frame_wide", frame=0.11, frame_material="frame_wood")
    yield w("window_mullion_2x1", cols=2, rows=1)
    yield w("window_mullion_1x2", cols=1, rows=2)
    yield w("window_mullion_2x2", cols=2, rows=2)
    yield w("window_mullion_2x3", cols=2, rows=3)
    yield w("window_mullion_3x3", cols=3, rows=3, width=1.4)
    yield w("window_wood_2x3", cols=2, rows=3, frame_material="frame_wood", frame=0.08)
    yield w("window_small_square", width=0.8, height=0.8)
    yield w("window_arched_round", arch="round", height=1.9, fanlight=True)
    yield w("window_arched_round_2x2", arch="round", height=2.0, cols=2, rows=2)
    yield w("window_arched_segmental", arch="segmental", height=1.7)
    yield w("window_arched_segmental_2x3", arch="segmental", height=1.8, cols=2, rows=3)
    yield w("window_sill_2x2", cols=2, rows=2, sill=True, height=1.7)
    yield w("window_lintel_2x2", cols=2, rows=2, sill=True, head="lintel", height=1.9)
    yield w("window_pediment_2x3", cols=2, rows=3, sill=True, head="pediment", height=2.2,
            width=1.3)
    yield w("window_pediment_segmental_2x2", cols=2, rows=2, sill=True, head="segmental",
            height=2.1, width=1.3)
    yield w("window_shutters_open", shutters="open", cols=2, rows=3, width=2.4)
    yield w("window_shutters_open_wood", shutters="open", cols=2, rows=2, width=2.4, frame_material="frame_wood")
    yield w("window_shutters_closed", shutters="closed", cols=2, rows=2)
    yield w("window_blind_half", cols=2, rows=2, blind=0.5)
    yield w("window_blind_quarter", cols=1, rows=1, blind=0.25)
    yield w("window_french", cols=2, rows=3, height=2.4, depth=0.3)
    yield w("window_french_4", cols=2, rows=4, height=2.6, depth=0.3, frame_material="frame_wood")
    yield w("window_french_shutters_open", shutters="open", cols=2, rows=3, height=2.4, width=2.4, depth=0.3)

    def d(name, **kw):
        return _spec(name, "door", "recess", 0.3, **{**dict(width=1.1, height=2.3), **kw})

    yield d("door_single_panel", panels=3)
    yield d("door_double", leaves=2, width=1.8, height=2.5, panels=3, material="door_green")
    yield d("door_glazed", panels=2, glazed=True)
    yield d("door_double_glazed", leaves=2, width=1.8, height=2.6, panels=3, glazed=True)
    yield d("door_arched", arch="round", width=1.3, height=2.8, panels=3)
    yield d("door_transom", transom=True, height=2.8, panels=2)
    yield d("door_double_transom", leaves=2, transom=True, width=1.8, height=3.1, panels=3,
            material="door_green")

    def b(name, depth=1.0, **kw):
        return _spec(name, "balcony", "protrude", depth, **{**dict(width=3.0, height=1.15), **kw})

    yield b("balcony_bars")
    yield b("balcony_solid", railing="solid")
    yield b("balcony_balusters", railing="balusters", spacing=0.2)
    yield b("balcony_french", depth=0.15, slab=0.0, width=1.3, height=1.0)

    yield _spec("sill_plain", "sill", "protrude", 0.06, width=1.4, height=0.07, profile="plain")
    yield _spec("sill_drip", "sill", "protrude", 0.1, width=1.4, height=0.12, profile="drip")
    yield _spec("ledge_band", "cornice", "protrude", 0.1, width=3.0, height=0.22,
                profile="band")
    yield _spec("cornice_stepped", "cornice", "protrude", 0.3, width=3.0, height=0.4,
                profile="stepped")
    yield _spec("cornice_cove", "cornice", "protrude", 0.35, width=3.0, height=0.45,
                profile="cove")
    yield _spec("cornice_dentil", "cornice", "protrude", 0.35, width=3.0, height=0.5,
                profile="dentil")

    def s(name, **kw):
        return _spec(name, "shop", "recess", 0.3, **{**dict(width=4.0, height=3.2), **kw})

    yield s("shop_sign", bays=3)
    yield s("shop_sign_door", bays=3, door_bay=1)
    yield s("shop_riser_door", bays=4, door_bay=0, riser=0.5, frame_material="frame_wood")
    yield s("shop_arched", bays=3, door_bay=1, arch="segmental", sign=0.0, width=3.2,
            height=3.6)


@lru_cache(maxsize=1)
def _library() -> tuple[ElementSpec, ...]:
    specs = tuple(_variants())
    names = [sp.name for sp in specs]
    assert len(set(names)) == len(names), "duplicate element names"
    return specs


@lru_cache(maxsize=1)
def _by_name() -> dict[str, ElementSpec]:
    return {sp.name: sp for sp in _library()}


def element_library() -> list[ElementSpec]:
    """All variants of the library (§4's ``{e_i}``), in a stable order."""
    return list(_library())


def element_spec(name: str) -> ElementSpec:
    """The variant called ``name``; :class:`~facadeforge.errors.InputError` naming close matches
    when there is none."""
    try:
        return _by_name()[name]
    except KeyError:
        close = difflib.get_close_matches(str(name), list(_by_name()), n=5, cutoff=0.4)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise InputError(f"no element {name!r} in the element library{hint} "
                         f"(see facadeforge.elements.element_library())") from None


def _build(spec: ElementSpec) -> list[tuple[str, str, str, list[np.ndarray]]]:
    try:
        builder = _BUILDERS[spec.kind]
    except KeyError:
        raise InputError(f"element {spec.name!r}: no builder for kind {spec.kind!r} "
                         f"(known: {', '.join(sorted(_BUILDERS))})") from None
    W, H, parts = builder(spec)
    scale = np.array([1.0 / W, 1.0 / H, 1.0])
    out = []
    for role, label, mat, polys in parts:
        if not polys:
            continue
        polys = [np.clip(np.asarray(q, float) * scale, 0.0, 1.0) for q in polys]
        out.append((role, label, mat, polys))
    return out


@lru_cache(maxsize=256)
def _cached_parts(spec: ElementSpec):
    return tuple((role, label, mat, Mesh.from_polygons(polys))
                 for role, label, mat, polys in _build(spec))


def element_model(spec: ElementSpec | str) -> Model:
    """The element's geometry in the unit box as a :class:`Model` (one labelled part per role:
    glass, frame, bars, reveal, sill, shutter, railing …, each with its material)."""
    if isinstance(spec, str):
        spec = element_spec(spec)
    parts = [Part(mesh.copy(), label, MATERIALS[mat], f"{spec.name}.{role}")
             for role, label, mat, mesh in _cached_parts(spec)]
    return Model(parts=parts, name=spec.name,
                 attributes={"kind": spec.kind, "mount": spec.mount,
                             "depth": spec.default_depth, "width": spec.size[0],
                             "height": spec.size[1]})


# --------------------------------------------------------------------------------------------
# front renders p(e_i)
# --------------------------------------------------------------------------------------------

_LIGHT = np.array([-0.3, 0.55, 0.9]) / np.linalg.norm([-0.3, 0.55, 0.9])  # towards the sun
_AMBIENT = 0.35
_SHADOW = 0.6  # factor on a shadowed pixel


def _luma(c) -> float:
    return 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]


#: Gray value of the facade around an element (the render background).
WALL_GRAY = _luma(MATERIALS["wall"].color) * (_AMBIENT + (1 - _AMBIENT) * _LIGHT[2])


def render_front(spec: ElementSpec | str, width_px: int, height_px: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Orthographic front view ``p(e_i)`` (looking along −z) of an element, §4 / Fig. 11.

    Painter's algorithm over the faces that face the viewer (sorted far to near, filled with
    sub-pixel precision at a supersampled size, then area-downsampled).  Each face is shaded
    with Lambert from a fixed sun times the material's luminance, darkened with the depth behind
    the facade plane; cast shadows (reveals on the frame, panels on the door leaf, balconies and
    cornices on the wall) come from marching the sun direction over the painted depth map.  The
    surroundings are the facade plane (``z = 1`` for recessed, ``z = 0`` for protruding
    elements) in the wall colour.

    Returns
    -------
    gray : (height_px, width_px) float32 in 0..1 (read-only, cached per element and size)
    labels : (height_px, width_px) uint8 canonical label indices (:data:`LABEL_INDEX`, the order
        of :class:`Labels`); pixels not covered by the element are ``wall``.
    """
    if isinstance(spec, str):
        spec = element_spec(spec)
    w, h = int(width_px), int(height_px)
    if w < 1 or h < 1:
        raise InputError(f"render size must be positive, got {width_px}x{height_px}")
    return _render(spec, w, h)


def _cast_shadows(height: np.ndarray, background: float, metres_per_px: tuple[float, float]
                  ) -> np.ndarray:
    """Pixels of a height field (metres towards the viewer) that the sun does not reach."""
    lxy = _LIGHT[:2]
    run = float(np.linalg.norm(lxy))
    rise = float(_LIGHT[2]) / run  # metres of height gained per metre along the image plane
    span = float(max(height.max(), background) - min(height.min(), background))
    if span <= 1e-9:
        return np.zeros(height.shape, bool)
    tmax = span / rise
    mx, my = metres_per_px
    pad_x, pad_y = int(math.ceil(tmax / mx)) + 1, int(math.ceil(tmax / my)) + 1
    padded = np.pad(height, ((pad_y, pad_y), (pad_x, pad_x)), constant_values=background)
    steps = int(min(max(math.ceil(tmax / min(mx, my)), 1), 48))
    shadow = np.zeros(height.shape, bool)
    H, W = height.shape
    for t in np.linspace(tmax / steps, tmax, steps):
        dx = int(round(t * lxy[0] / run / mx))
        dy = int(round(-t * lxy[1] / run / my))  # rows grow downwards
        seen = padded[pad_y + dy:pad_y + dy + H, pad_x + dx:pad_x + dx + W]
        shadow |= seen > height + t * rise + 1e-4
    return shadow


@lru_cache(maxsize=4096)
def _render(spec: ElementSpec, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    import cv2

    ss = min(max(2, int(math.ceil(128 / min(w, h)))), 8)
    W, H = w * ss, h * ss
    depth = spec.default_depth
    background = depth if spec.mount == "recess" else 0.0  # height of the facade plane
    gray = np.full((H, W), WALL_GRAY, np.float32)
    lab = np.full((H, W), LABEL_INDEX["wall"], np.uint8)
    zbuf = np.full((H, W), background, np.float32)
    faces = []
    for _role, label, mat, mesh in _cached_parts(spec):
        if not mesh.n_faces:
            continue
        normals = mesh.face_normals()
        albedo = _luma(MATERIALS[mat].color)
        for fi, poly in enumerate(mesh.polygons()):
            n = normals[fi]
            if n[2] <= 1e-6:
                continue  # back-facing or edge-on
            zc = float(poly[:, 2].mean())
            shade = _AMBIENT + (1 - _AMBIENT) * max(float(n @ _LIGHT), 0.0)
            if spec.mount == "recess":
                below = (1.0 - zc) * depth  # metres behind the facade plane
                shade *= 1.0 - 0.25 * min(below / 0.3, 1.0)
            else:  # a little ambient occlusion near the wall
                shade *= 0.8 + 0.2 * zc
            faces.append((zc, albedo * shade, LABEL_INDEX.get(label, LABEL_INDEX["other"]),
                          poly))
    faces.sort(key=lambda f: f[0])
    shift = 4
    scale = float(1 << shift)
    for zc, g, li, poly in faces:
        px = (poly[:, 0] * W - 0.5) * scale
        py = ((1.0 - poly[:, 1]) * H - 0.5) * scale
        pts = [np.round(np.column_stack([px, py])).astype(np.int32).reshape(-1, 1, 2)]
        cv2.fillPoly(gray, pts, float(g), lineType=cv2.LINE_8, shift=shift)
        cv2.fillPoly(lab, pts, int(li), lineType=cv2.LINE_8, shift=shift)
        cv2.fillPoly(zbuf, pts, float(zc * depth), lineType=cv2.LINE_8, shift=shift)
    wm, hm = spec.size
    gray[_cast_shadows(zbuf, background, (wm / W, hm / H))] *= _SHADOW
    out = cv2.resize(gray, (w, h), interpolation=cv2.INTER_AREA)
    out = np.clip(out, 0.0, 1.0).astype(np.float32)
    labels = np.ascontiguousarray(lab[ss // 2::ss, ss // 2::ss][:h, :w])
    out.flags.writeable = False
    labels.flags.writeable = False
    return out, labels
