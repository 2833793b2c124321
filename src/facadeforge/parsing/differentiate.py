"""Differentiation: each element instance fitted on its own after the consistent search.

``simon2011`` §3.2.3 separates *consistency* (instances of a rule share their choices: every
window of a facade the same size, columns aligned) from *differentiation* (instances may
differ).  The consistent search (§4.1.1, :mod:`.fit`) finds the facade's grid — floors, window
columns, one window size — which is what makes grammar parsing robust to a noisy classifier.
Real facades then differ per instance: a window a little wider, a missing one, a balcony in
front of some windows only, a running balcony that stops short of the corners.  The oracle
experiment (truth as the classifier) shows how much the consistent space leaves behind, and on
the CMP facades the consistent fit loses most to the classifier on windows and balconies.

A grammar opts in by declaring the array attributes of :data:`DIFFERENTIATION_ATTRIBUTES`
(``grammars/grid.cga`` explains which entry moves which edge).  With the consistent attributes fixed, the
energy of §4.2.2 separates over instances: moving one window's edges only changes the pixels
between its old and new box.  So each instance is fitted exactly and cheaply on the integral
image of its cost change ``−log p(new label) + log p(current label)``:

1. **running balcony bands** (per floor): top edge and the wall left and right of the band,
   or no band — and a band on a floor the consistent fit gave none, where the photo has one;
2. **window openings** (per floor and column): their four edges by coordinate descent within
   their cell — half-way to the neighbouring openings and inside their floor — or no window;
3. **balconies in front of openings**: a balcony from below the window's bottom up into it, at
   least as wide as the window (the grammar's guard, now per instance and wider than its
   window where the photo says so).  A floor with a running band is fitted both ways — with
   its band, and with a balcony per window instead — and keeps the one whose rows have the
   lower energy (a band is often better than bare wall where the photo shows separate
   balconies).

Which instance a leaf of the derived layout is — which floor and column a window, which
column an arcade opening — is asked of the grammar itself (:func:`_instances`): each instance
is widened by its own tiny amount and the layout derived once more.  Matching leaves to
instances by the rank of their positions failed whenever a placeholder derived nothing (a
column run off the facade, a floor of zero height): 13 of the 60 CMP validation facades were
then not differentiated at all.

On the ground floor: the door's attributes polished on the derived energy and each shop's
wall beside and above it; in an arcade, each opening's edges, height and kind (shop, door,
window or none).

The results are written into the grammar's own attributes, derived by the same layout code as
the search (and by the engine for the model), and kept only if the derived layout's energy is
lower than before the stage.  It costs a small part of the consistent search's time
(``docs/design-measurements.md``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .energy import SegmentationEnergy
from .layout import Layout, SplitLayout
from .search import Objective, Parameter, coordinate_sweep

__all__ = ["DIFFERENTIATION_ATTRIBUTES", "differentiate", "supports_differentiation"]

#: Attributes a grammar declares to be differentiated (``grid.cga``).
DIFFERENTIATION_ATTRIBUTES = frozenset({"differentiated", "windowCells", "bandCells",
                                        "shopCells", "archCells"})
#: Values per window opening and per band in ``windowCells`` / ``bandCells``.
WINDOW_VALUES, BAND_VALUES, SHOP_VALUES, ARCH_VALUES = 7, 3, 3, 4
#: Kinds an arcade opening may take, by their code in ``archCells`` (4 = wall, no opening).
ARCH_KINDS = {1: "shop", 2: "door", 3: "window"}
#: Derivations the door's polish may spend.
DOOR_BUDGET = 80
#: How far (fraction of its size) an edge may move in one direction.
SPAN = 0.7
#: Coordinate-descent rounds over an instance's edges.
ROUNDS = 3
#: Width changes (in units of the instance's width) that tell instances apart, tried in turn
#: (:func:`_instances`).
PROBES = (1e-4, 1e-7)
_EPS = 1e-6


def supports_differentiation(layout: SplitLayout) -> bool:
    return DIFFERENTIATION_ATTRIBUTES <= set(layout.attr_defs)


def _grid_size(layout: SplitLayout) -> tuple[int, int]:
    """``(upper floor placeholders, column placeholders)`` the grammar declares."""
    names = layout.attr_defs
    floors = 1 + sum(1 for n in names if n.startswith("floor") and n[5:].isdigit())
    columns = sum(1 for n in names if n.startswith("column") and n[6:].isdigit())
    return floors, columns


class _Frame:
    """Layout metres ↔ energy pixels (x right, y up from the bottom ↔ rows down from the top)."""

    def __init__(self, energy: SegmentationEnergy, width: float, height: float):
        self.h, self.w = energy.shape
        self.sx = self.w / width
        self.sy = self.h / height
        self.height = height

    def box(self, b) -> tuple[float, float, float, float]:
        """Float pixel box ``r0, c0, r1, c1`` of a layout box ``x0, y0, x1, y1``."""
        x0, y0, x1, y1 = b
        return ((self.height - y1) * self.sy, x0 * self.sx, (self.height - y0) * self.sy,
                x1 * self.sx)


def _integral(d: np.ndarray) -> np.ndarray:
    s = np.zeros((d.shape[0] + 1, d.shape[1] + 1))
    s[1:, 1:] = d.cumsum(0).cumsum(1)
    return s


def _box_sum(s: np.ndarray, r0: int, c0: int, r1: int, c1: int) -> float:
    return float(s[r1, c1] - s[r0, c1] - s[r1, c0] + s[r0, c0])


def _box_sums(s: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    r0, c0, r1, c1 = boxes.T
    return s[r1, c1] - s[r0, c1] - s[r1, c0] + s[r0, c0]


def _descend(s: np.ndarray, box: list[int], bounds: tuple[int, int, int, int],
             movable: tuple[bool, bool, bool, bool], span: tuple[int, int]
             ) -> tuple[list[int], float]:
    """Coordinate descent of a box's edges on integral image ``s`` (minimum cost): each edge
    in turn to its best position within ``span`` (rows, columns) of where it started and
    inside ``bounds``, until no edge moves."""
    start = list(box)
    best = _box_sum(s, *box)
    for _ in range(ROUNDS):
        moved = False
        for i in range(4):
            if not movable[i]:
                continue
            d = span[i % 2]
            lo = max(start[i] - d, bounds[i % 2])
            hi = min(start[i] + d, bounds[2 + i % 2])
            if hi < lo:
                continue
            cand = np.tile(np.asarray(box, np.intp), (hi - lo + 1, 1))
            cand[:, i] = np.arange(lo, hi + 1)
            e = _box_sums(s, cand)
            e[(cand[:, 2] - cand[:, 0] < 1) | (cand[:, 3] - cand[:, 1] < 1)] = np.inf
            k = int(np.argmin(e))
            if e[k] < best - 1e-9:
                best, box, moved = float(e[k]), [int(v) for v in cand[k]], True
        if not moved:
            break
    return box, best


def _in_region(box, region) -> list[int]:
    """A global pixel box in the coordinates of ``region`` (r0, c0, r1, c1), clipped to it."""
    h, w = region[2] - region[0], region[3] - region[1]
    return [min(max(box[0] - region[0], 0), h), min(max(box[1] - region[1], 0), w),
            min(max(box[2] - region[0], 0), h), min(max(box[3] - region[1], 0), w)]


def _gain(cost: np.ndarray, raster: np.ndarray, channel: int, region) -> np.ndarray:
    """Integral image, over ``region`` (r0, c0, r1, c1), of what labelling a pixel ``channel``
    instead of its label in ``raster`` changes the energy by."""
    r0, c0, r1, c1 = region
    c = cost[r0:r1, c0:c1]
    cur = np.take_along_axis(c, raster[r0:r1, c0:c1, None].astype(np.intp), 2)[..., 0]
    return _integral(c[..., channel] - cur)


def _openings(lay: Layout, ground_top_m: float) -> list[tuple[int, np.ndarray, float]]:
    """Upper-floor window openings: ``(leaf index, box, balcony share)`` — a window leaf together
    with the balcony leaf directly below it over the same width (the grammar's guard)."""
    boxes, labels = lay.boxes, lay.labels
    balconies = [b for b, lab in zip(boxes, labels) if lab == "balcony"]
    out = []
    for i, (b, lab) in enumerate(zip(boxes, labels)):
        if (lab != "window" or b[1] < ground_top_m - _EPS or b[2] - b[0] <= _EPS
                or b[3] - b[1] <= _EPS):
            continue
        box = b.copy()
        for g in balconies:
            if (abs(g[0] - b[0]) < _EPS and abs(g[2] - b[2]) < _EPS
                    and abs(g[3] - b[1]) < _EPS):
                box[1] = g[1]
                break
        out.append((i, box, float((b[1] - box[1]) / max(box[3] - box[1], _EPS))))
    return out


def _instances(layout: SplitLayout, width: float, height: float, attrs: Mapping[str, Any],
               lay: Layout, name: str, stride: int, unit_m: float) -> dict[int, int]:
    """Which instance of the array attribute ``name`` (``stride`` values each, value 1 widening
    the instance by that many units of ``unit_m`` metres) each leaf of ``lay`` is: leaf index →
    instance index.

    The grammar itself is asked: every instance is widened by its own tiny amount
    (``probe`` × (index + 1) units, ``probe`` from :data:`PROBES`) and the layout derived once
    more; a leaf whose width grew by such an amount belongs to that instance.  Placeholders that
    derive empty, columns that overlap or run off the facade and floors of zero height are then
    no obstacle — which matching leaves to instances by their rank among the positions could
    not handle (a fifth of the CMP validation facades).  Leaves clipped by their split (the
    width change is not a whole multiple) are left out.  Widening can make a sliver of wall
    beside the instances vanish (the split drops pieces of 1e-9 m and less), which changes the
    leaves: the next, smaller amount is then tried, and ``{}`` returned when none keeps them.
    The instance's width must grow by exactly value 1 × ``unit_m`` (a window without insets,
    as before stage 2 writes them)."""
    cells = np.array(attrs[name], dtype=float)
    n = cells.size // stride
    if n == 0 or unit_m <= _EPS:
        return {}
    for probe in PROBES:
        widened = cells.copy()
        widened[1::stride] += probe * (1.0 + np.arange(n))
        grown = layout.derive(width, height, {**attrs, name: widened})
        if list(grown.labels) == list(lay.labels):
            break
    else:
        return {}
    grow = ((grown.boxes[:, 2] - grown.boxes[:, 0]) - (lay.boxes[:, 2] - lay.boxes[:, 0])) / (
        probe * unit_m)
    out = {}
    for i, d in enumerate(grow):
        k = int(round(d))
        if 1 <= k <= n and abs(d - k) < 0.05:
            out[i] = k - 1
    return out


def _cells(layout: SplitLayout, width: float, height: float, attrs: Mapping[str, Any],
           lay: Layout, ground_top_m: float, unit_m: float, known: list | None = None
           ) -> tuple[list[tuple[tuple[int, int], np.ndarray, float]], list]:
    """The upper-floor openings of ``lay`` as ``((floor, column), box, balcony share)``, indices
    from 0, each told apart by the grammar (:func:`_instances` on ``windowCells``), and the
    instances of all of ``lay``'s openings in order (``None`` where unknown).  ``known``: those
    of an earlier layout of the same grid (other bands or balconies, the same windows in the
    same order), used instead of asking the grammar again when the counts agree."""
    found = _openings(lay, ground_top_m)
    if known is None or len(known) != len(found):
        n_columns = _grid_size(layout)[1]
        which = _instances(layout, width, height, attrs, lay, "windowCells", WINDOW_VALUES,
                           unit_m)
        known = [divmod(which[i], n_columns) if i in which else None for i, _, _ in found]
    return [(fj, b, g) for fj, (_, b, g) in zip(known, found) if fj is not None], known


def differentiate(energy: SegmentationEnergy, layout: SplitLayout, attrs: Mapping[str, Any],
                  width: float, height: float, params: Sequence[Parameter] = ()
                  ) -> dict[str, Any] | None:
    """Attributes of the consistent fit ``attrs`` plus per-instance ``windowCells``,
    ``bandCells``, ``shopCells`` and ``archCells`` fitted to ``energy`` (module docstring), or
    ``None`` when the grammar does not declare them or nothing is gained; ``params`` are the
    searched parameters (the door's are polished among them).  Each stage is kept only if the
    derived layout's energy is lower than before it."""
    if not supports_differentiation(layout):
        return None
    n_floors, n_columns = _grid_size(layout)
    base = {**attrs, "differentiated": True,
            "windowCells": np.zeros(n_floors * n_columns * WINDOW_VALUES),
            "bandCells": np.zeros(n_floors * BAND_VALUES), "shopCells": np.zeros(2 * SHOP_VALUES),
            "archCells": np.zeros(n_columns * ARCH_VALUES)}
    for f in range(n_floors):   # the consistent guards, per instance
        if attrs.get(f"guard{f + 1}"):
            base["windowCells"][f * n_columns * WINDOW_VALUES + 4::WINDOW_VALUES][:n_columns] = \
                float(attrs["guardFrac"])
    consistent = layout.derive(width, height, attrs)
    lay = layout.derive(width, height, base)
    if len(lay.labels) != len(consistent.labels) or not np.allclose(lay.boxes, consistent.boxes,
                                                                     atol=1e-6):
        return None   # the grammar's differentiated form does not start from the consistent one
    e_start = e_best = energy(consistent)
    best = base
    for stage in (_upper_floors, _ground_floor, _arcade):
        cand = stage(energy, layout, best, width, height, n_columns, params)
        if cand is None:
            continue
        e = energy(layout.derive(width, height, cand))
        if e < e_best - 1e-9:
            best, e_best = cand, e
    return best if e_best < e_start - 1e-9 else None


def _upper_floors(energy: SegmentationEnergy, layout: SplitLayout, base: dict[str, Any],
                  width: float, height: float, n_columns: int, params=()
                  ) -> dict[str, Any] | None:
    """Stages 1–3 of the module docstring: bands, window openings and their balconies.

    A floor with a running band is fitted twice: with its band, and with the band removed and
    a balcony in front of each window instead (where a band is better than bare wall but the
    photo shows separate balconies); per floor the one with the lower energy over the floor's
    rows is kept."""
    found = _bands(energy, layout, base, width, height)
    if found is None:
        return None
    banded, known = found
    with_bands = _windows(energy, layout, banded, width, height, n_columns, known)
    cells = banded["bandCells"]
    ground_top = float(base["groundTop"]) * height
    frac = float(base["balconyFrac"])
    floors = sorted(f for f in range(cells.size // BAND_VALUES)
                    if frac * (float(base.get(f"balcony{f + 1}", False)) + cells[f * BAND_VALUES])
                    > _EPS)
    if not floors:
        return with_bands
    bare_cells = cells.copy()
    bare_cells[[f * BAND_VALUES for f in floors]] = -1.0
    bare = {**banded, "bandCells": bare_cells}
    spans = _floor_rows(energy, layout, bare, width, height, ground_top, known)
    without = _windows(energy, layout, bare, width, height, n_columns, known)
    row_a = _row_energy(energy, layout.derive(width, height, with_bands))
    row_b = _row_energy(energy, layout.derive(width, height, without))
    best = {**with_bands, "windowCells": with_bands["windowCells"].copy(),
            "bandCells": with_bands["bandCells"].copy()}
    per_floor = n_columns * WINDOW_VALUES
    for f in floors:
        if f not in spans:
            continue
        r0, r1 = spans[f]
        if row_b[r0:r1].sum() < row_a[r0:r1].sum() - 1e-9:
            best["bandCells"][f * BAND_VALUES:(f + 1) * BAND_VALUES] = \
                without["bandCells"][f * BAND_VALUES:(f + 1) * BAND_VALUES]
            best["windowCells"][f * per_floor:(f + 1) * per_floor] = \
                without["windowCells"][f * per_floor:(f + 1) * per_floor]
    return best


def _row_energy(energy: SegmentationEnergy, lay: Layout) -> np.ndarray:
    """The energy of ``lay`` summed over each pixel row."""
    raster = energy.rasterize(lay)
    return np.take_along_axis(energy.cost, raster[..., None].astype(np.intp), 2)[..., 0].sum(1)


def _floor_rows(energy: SegmentationEnergy, layout: SplitLayout, attrs: Mapping[str, Any],
                width: float, height: float, ground_top: float, known: list | None = None
                ) -> dict[int, tuple[int, int]]:
    """Pixel rows ``[r0, r1)`` of each upper floor without a band (its body is the floor),
    from its openings (``known``: as for :func:`_cells`)."""
    lay = layout.derive(width, height, attrs)
    frame = _Frame(energy, width, height)
    openings, _ = _cells(layout, width, height, attrs, lay, ground_top,
                         float(attrs["windowWidth"]) * width, known)
    out = {}
    for f, (bottom, fb_h) in _bodies(attrs, openings).items():
        r0, _, r1, _ = frame.box((0.0, bottom, width, bottom + fb_h))
        out[f] = (max(0, round(r0)), min(frame.h, round(r1)))
    return out


def _bodies(attrs: Mapping[str, Any], openings) -> dict[int, tuple[float, float]]:
    """Floor index → ``(bottom, height)`` in metres of the floor body holding its openings (as
    :func:`_cells` gives them, before their own edges are fitted): an opening is
    ``windowHeight`` of its body, ``sillHeight`` above its foot."""
    sill, wh = float(attrs["sillHeight"]), float(attrs["windowHeight"])
    out = {}
    for (f, _), b, _ in openings:
        fb_h = (b[3] - b[1]) / max(wh, _EPS)
        out[f] = (b[1] - sill * fb_h, fb_h)
    return out


def _working_copy(layout: SplitLayout, base: dict[str, Any], name: str, width: float,
                  height: float) -> tuple[dict[str, Any], np.ndarray, Layout]:
    """A stage's working attributes: ``base`` with its own copy of the array attribute
    ``name`` (which the stage fills in), that copy, and the layout they derive."""
    cells = np.array(base[name], dtype=float)
    base = {**base, name: cells}
    return base, cells, layout.derive(width, height, base)


def _bands(energy: SegmentationEnergy, layout: SplitLayout, base: dict[str, Any],
           width: float, height: float) -> tuple[dict[str, Any], list] | None:
    """Stage 1: each floor's running balcony band (``bandCells``) and the instances of the
    openings (as for :func:`_cells`), or ``None`` without openings to place the floors by."""
    attrs = base
    base, band_cells, lay = _working_copy(layout, base, "bandCells", width, height)
    frame = _Frame(energy, width, height)
    cost = energy.cost
    ground_top = float(attrs["groundTop"]) * height

    # 1. running balcony bands
    window_m = float(attrs["windowWidth"]) * width
    openings, known = _cells(layout, width, height, base, lay, ground_top, window_m)
    if not openings:
        return None
    body = _bodies(attrs, openings)   # the band, where there is one, is below the body
    raster = energy.rasterize(lay)
    x_lo = float(attrs.get("leftMargin", 0.0)) * width
    x_hi = (1.0 - float(attrs.get("rightMargin", 0.0))) * width
    wall = energy.label_set.index("wall")
    bal = energy.label_set.index("balcony")
    bands = {}   # floor index → its band's box (metres)
    for b, lab in zip(lay.boxes, lay.labels):
        if (lab == "balcony" and abs(b[0] - x_lo) < _EPS and abs(b[2] - x_hi) < _EPS
                and b[3] - b[1] > _EPS):
            f = next((k for k, (y, _) in body.items() if abs(y - b[3]) < 1e-5), None)
            if f is not None:
                bands[f] = b
    frac = float(attrs["balconyFrac"])
    for f, (bottom, fb_h) in sorted(body.items()):
        if f in bands:
            b = bands[f]
            unit = (b[3] - b[1]) / max(frac, _EPS)   # the floor's height: the band's unit
        else:   # a band the consistent fit did not choose, as tall as the others would be,
            unit = fb_h   # from the bottom of the floor (all body without one) upwards
            b = np.array([x_lo, bottom, x_hi, bottom + frac * unit])
            if frac * unit <= _EPS:
                continue
        r0f, c0f, r1f, c1f = frame.box(b)
        box = [round(r0f), round(c0f), round(r1f), round(c1f)]
        if box[0] < 0 or box[2] > frame.h or box[2] - box[0] < 1 or box[3] - box[1] < 1:
            continue
        under = raster.copy()
        if f in bands:
            under[box[0]:box[2], box[1]:box[3]] = wall
        s = _gain(cost, under, bal, (0, 0, frame.h, frame.w))
        span = (max(1, int(SPAN * (box[2] - box[0]))), max(1, int(SPAN * (box[3] - box[1]))))
        new, e = _descend(s, box, (0, box[1], box[2], box[3]), (True, True, False, True), span)
        k = f * BAND_VALUES
        unit_px = frac * unit * frame.sy
        if e >= 0:   # no band is better
            if f in bands:
                band_cells[k] = -1.0
            continue
        band_cells[k] = (new[2] - new[0]) / max(unit_px, _EPS) - (1.0 if f in bands else 0.0)
        band_cells[k + 1] = max(0.0, (new[1] - c0f) / max(c1f - c0f, _EPS))
        band_cells[k + 2] = max(0.0, (c1f - new[3]) / max(c1f - c0f, _EPS))
    return base, known


def _windows(energy: SegmentationEnergy, layout: SplitLayout, base: dict[str, Any],
             width: float, height: float, n_columns: int, known: list | None = None
             ) -> dict[str, Any]:
    """Stages 2–3: each window opening's edges, or no window, and the balcony in front of it
    (``windowCells``; ``known``: as for :func:`_cells`)."""
    attrs = base
    base, window_cells, lay = _working_copy(layout, base, "windowCells", width, height)
    frame = _Frame(energy, width, height)
    cost = energy.cost
    ground_top = float(attrs["groundTop"]) * height
    openings, _ = _cells(layout, width, height, base, lay, ground_top,
                         float(attrs["windowWidth"]) * width, known)
    sill, wh = float(attrs["sillHeight"]), float(attrs["windowHeight"])
    x_lo = float(attrs.get("leftMargin", 0.0)) * width
    x_hi = (1.0 - float(attrs.get("rightMargin", 0.0))) * width
    wall = energy.label_set.index("wall")
    bal = energy.label_set.index("balcony")
    win = energy.label_set.index("window")
    raster = energy.rasterize(lay)
    by_floor: dict[int, list] = {}
    for (f, j), b, g in openings:
        by_floor.setdefault(f, []).append((b, g, j))
    for f, row in by_floor.items():
        row.sort(key=lambda o: o[0][0])
        for i, (b, g, j) in enumerate(row):
            r0f, c0f, r1f, c1f = frame.box(b)
            o_w, o_h = c1f - c0f, r1f - r0f
            fb_h = o_h / max(wh, _EPS)
            body_top = r1f + sill * fb_h - fb_h   # the floor body holding the opening (rows)
            body_bot = r1f + sill * fb_h
            left = c0f - 0.5 * (c0f - frame.box(row[i - 1][0])[3]) if i else x_lo * frame.sx
            right = (c1f + 0.5 * (frame.box(row[i + 1][0])[1] - c1f) if i + 1 < len(row)
                     else x_hi * frame.sx)
            bounds = (max(0, int(np.ceil(body_top - 1e-6))), max(0, int(np.ceil(left - 1e-6))),
                      min(frame.h, int(body_bot + 1e-6)), min(frame.w, int(right + 1e-6)))
            if bounds[2] - bounds[0] < 2 or bounds[3] - bounds[1] < 2:
                continue
            # everything below in the cell's own pixels: local integral images
            oy, ox = bounds[0], bounds[1]
            local = (0, 0, bounds[2] - oy, bounds[3] - ox)

            box = [round(r0f), round(c0f), round(r1f), round(c1f)]
            under = raster.copy()
            under[box[0]:box[2], box[1]:box[3]] = wall
            # the window part of the opening, refined as a window against what lies under it
            s_win = _gain(cost, under, win, bounds)
            wbox = _in_region([box[0], box[1], round(r1f - g * o_h), box[3]], bounds)
            span = (max(1, int(SPAN * max(wbox[2] - wbox[0], 1))), max(1, int(SPAN * o_w)))
            if wbox[2] - wbox[0] < 1 or wbox[3] - wbox[1] < 1:
                wbox = _in_region(box, bounds)
                e_win = _box_sum(s_win, *wbox)
            else:
                wbox, e_win = _descend(s_win, wbox, local, (True, True, True, True), span)
            k = ((f * n_columns) + j) * WINDOW_VALUES
            if e_win >= 0 or wbox[2] - wbox[0] < 1 or wbox[3] - wbox[1] < 1:   # no window here
                window_cells[k:k + WINDOW_VALUES] = (0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
                raster = under
                continue
            wr0, wc0, wr1, wc1 = wbox
            painted = under.copy()
            painted[wr0 + oy:wr1 + oy, wc0 + ox:wc1 + ox] = win
            # a balcony from below the window's bottom up into it, at least as wide as the window
            s_bal = _gain(cost, painted, bal, bounds)
            h_w = wr1 - wr0
            below = np.arange(0, max(0, min(local[2] - wr1, int(0.6 * h_w))) + 1)
            above = np.arange(0, int(0.8 * h_w) + 1)
            lower = s_bal[wr1 + below, wc1] - s_bal[wr1 + below, wc0]
            upper = s_bal[wr1 - above, wc1] - s_bal[wr1 - above, wc0]
            sums = lower[:, None] - upper[None, :]
            sums[0, 0] = np.inf
            kb, ka = np.unravel_index(int(np.argmin(sums)), sums.shape)
            bbox = None
            if sums[kb, ka] < 0:
                bbox, _ = _descend(s_bal, [wr1 - int(above[ka]), wc0, wr1 + int(below[kb]), wc1],
                                   (wr0 + 1, 0, local[2], local[3]), (True, True, True, True),
                                   (max(1, int(SPAN * h_w)), max(1, int(SPAN * (wc1 - wc0)))))
                # the balcony spans the whole opening: never narrower than the window
                bbox = [bbox[0], min(bbox[1], wc0), max(bbox[2], wr1), max(bbox[3], wc1)]
            top = wr0
            if bbox is None:
                bottom, oc0, oc1, share = wr1, wc0, wc1, 0.0
            else:
                bottom, oc0, oc1 = bbox[2], bbox[1], bbox[3]
                share = (bottom - bbox[0]) / max(bottom - top, 1)
            window_cells[k] = (oc0 + ox - c0f) / max(o_w, _EPS)
            window_cells[k + 1] = (oc1 + ox - c1f) / max(o_w, _EPS)
            window_cells[k + 2] = (r1f - bottom - oy) / max(o_h, _EPS)   # y up: bottom edge
            window_cells[k + 3] = (r0f - top - oy) / max(o_h, _EPS)
            window_cells[k + 4] = share
            window_cells[k + 5] = (wc0 - oc0) / max(oc1 - oc0, 1)
            window_cells[k + 6] = (oc1 - wc1) / max(oc1 - oc0, 1)
            if bbox is not None:
                painted[wr0 + oy:bbox[0] + oy, oc0 + ox:oc1 + ox] = wall
                painted[wr0 + oy:bbox[0] + oy, wc0 + ox:wc1 + ox] = win
                painted[bbox[0] + oy:bbox[2] + oy, oc0 + ox:oc1 + ox] = bal
            raster = painted
    return base


def _ground_floor(energy: SegmentationEnergy, layout: SplitLayout, attrs: dict[str, Any],
                  width: float, height: float, n_columns: int,
                  params: Sequence[Parameter] = ()) -> dict[str, Any] | None:
    """The ground floor's one door (its consistent attributes, polished on the derived energy)
    and, on a shops ground floor, the wall beside and above each shop."""
    if attrs.get("groundKind") not in ("shops", "wall"):
        return None
    door_params = [p for p in params if p.name in ("doorPosition", "doorWidth", "doorHeight")]
    out = dict(attrs)
    if door_params:
        obj = Objective(lambda a: energy(layout.derive(width, height, {**out, **a})), DOOR_BUDGET)
        cur = {p.name: out[p.name] for p in door_params}
        e = obj(cur)
        rng = np.random.default_rng(0)
        for span in (0.1, 0.03, 0.01):
            if obj.left <= 0:
                break
            cur, e = coordinate_sweep(obj, door_params, cur, e, span, 9, rng)
        out.update(cur)
    if out.get("groundKind") != "shops":
        return out
    lay = layout.derive(width, height, out)
    frame = _Frame(energy, width, height)
    ground = float(out["groundTop"]) * height
    doors = [b for b, lab in zip(lay.boxes, lay.labels) if lab == "door" and b[3] <= ground + _EPS]
    door_x = 0.5 * (doors[0][0] + doors[0][2]) if doors else 0.5 * width
    raster = energy.rasterize(lay)
    cost = energy.cost
    wall = energy.label_set.index("wall")
    shop = energy.label_set.index("shop")
    cells = np.zeros(2 * SHOP_VALUES)
    for b, lab in zip(lay.boxes, lay.labels):
        if lab != "shop" or b[3] > ground + _EPS or b[2] - b[0] <= _EPS:
            continue
        i = 0 if 0.5 * (b[0] + b[2]) < door_x else 1
        r0f, c0f, r1f, c1f = frame.box(b)
        box = [round(r0f), round(c0f), round(r1f), round(c1f)]
        if box[2] - box[0] < 2 or box[3] - box[1] < 2:
            continue
        under = raster.copy()
        under[box[0]:box[2], box[1]:box[3]] = wall
        s_shop = _integral(cost[..., shop] - cost[..., wall])
        span = (max(1, int(SPAN * (box[2] - box[0]))), max(1, int(SPAN * (box[3] - box[1]))))
        new, e = _descend(s_shop, box, tuple(box), (True, True, False, True), span)
        k = i * SHOP_VALUES
        if e >= 0:   # wall, not a shop
            cells[k + 2] = 1.0
            continue
        cells[k] = max(0.0, (new[1] - c0f) / max(c1f - c0f, _EPS))
        cells[k + 1] = max(0.0, (c1f - new[3]) / max(c1f - c0f, _EPS))
        cells[k + 2] = max(0.0, (new[0] - r0f) / max(r1f - r0f, _EPS))
    out["shopCells"] = cells
    return out


def _arcade(energy: SegmentationEnergy, layout: SplitLayout, attrs: dict[str, Any],
            width: float, height: float, n_columns: int,
            params: Sequence[Parameter] = ()) -> dict[str, Any] | None:
    """Each opening of an arcade ground floor: its left, right and top edges inside its cell
    and its kind — the shop, door or window that explains its pixels best, or wall."""
    if attrs.get("groundKind") != "arcade":
        return None
    lay = layout.derive(width, height, attrs)
    frame = _Frame(energy, width, height)
    ground = float(attrs["groundTop"]) * height
    kinds = set(ARCH_KINDS.values())
    which = _instances(layout, width, height, attrs, lay, "archCells", ARCH_VALUES,
                       float(attrs["arcadeWidth"]) * width)
    arches = sorted(((lay.boxes[i], j) for i, j in which.items()
                     if lay.labels[i] in kinds and lay.boxes[i][3] <= ground + _EPS
                     and lay.boxes[i][2] - lay.boxes[i][0] > _EPS
                     and lay.boxes[i][3] - lay.boxes[i][1] > _EPS), key=lambda o: o[0][0])
    if not arches:
        return None
    cost = energy.cost
    wall = energy.label_set.index("wall")
    raster = energy.rasterize(lay)
    x_lo = float(attrs.get("leftMargin", 0.0)) * width * frame.sx
    x_hi = (1.0 - float(attrs.get("rightMargin", 0.0))) * width * frame.sx
    top_row = max(0, int(np.ceil((height - ground) * frame.sy - 1e-6)))
    cells = np.zeros(n_columns * ARCH_VALUES)
    pixel = [frame.box(b) for b, _ in arches]
    for i, (r0f, c0f, r1f, c1f) in enumerate(pixel):
        j = arches[i][1]
        left = 0.5 * (pixel[i - 1][3] + c0f) if i else x_lo
        right = 0.5 * (c1f + pixel[i + 1][1]) if i + 1 < len(pixel) else x_hi
        bounds = (top_row, max(0, int(np.ceil(left - 1e-6))), min(frame.h, round(r1f)),
                  min(frame.w, int(right + 1e-6)))
        if bounds[2] - bounds[0] < 2 or bounds[3] - bounds[1] < 2:
            continue
        box = [round(r0f), round(c0f), round(r1f), round(c1f)]
        under = raster.copy()
        under[box[0]:box[2], box[1]:box[3]] = wall
        start = _in_region(box, bounds)
        if start[2] - start[0] < 1 or start[3] - start[1] < 1:
            continue
        span = (max(1, int(SPAN * (start[2] - start[0]))), max(1, int(SPAN * (start[3] -
                                                                          start[1]))))
        best = (0.0, 4, start)   # wall: no opening
        for code, name in ARCH_KINDS.items():
            s_k = _gain(cost, under, energy.label_set.index(name), bounds)
            new, e = _descend(s_k, start, (0, 0, bounds[2] - bounds[0], bounds[3] - bounds[1]),
                              (True, True, False, True), span)
            if e < best[0] - 1e-9:
                best = (e, code, new)
        _, code, new = best
        k = j * ARCH_VALUES
        cells[k + 3] = code
        raster = under
        if code == 4:
            continue
        oy, ox = bounds[0], bounds[1]
        cells[k] = (new[1] + ox - c0f) / max(c1f - c0f, _EPS)
        cells[k + 1] = (new[3] + ox - c1f) / max(c1f - c0f, _EPS)
        cells[k + 2] = (r1f - (new[0] + oy)) / max(r1f - r0f, _EPS) - 1.0
        raster[new[0] + oy:new[2] + oy, new[1] + ox:new[3] + ox] = \
            energy.label_set.index(ARCH_KINDS[code])
    return {**attrs, "archCells": cells}
