"""Starting points for the search, read from the classifier's window map.

The thesis seeds its hill climbing with "customised average values … from expert assessments"
(§4.2.4) and notes that a random start is less robust.  On facades of many styles one expert
seed is far from most photos, and a local search from it stalls in the wrong basin (seen on CMP:
window columns and floors counted wrong).  The classifier already sees most windows, so the seed
here is measured: the connected components of its window class are grouped into columns (by
their horizontal extent) and rows (by their vertical extent), and the grid's lines, window size,
sill height, roof line and ground floor follow.  The search then refines this seed like any other
(it replaces the expert seed; random layouts are still drawn and compete with it).

:func:`initialiser_for` picks the seed by the attributes a grammar declares (the grid
placeholders of ``grid.cga`` and ``haussmann.cga``); other grammars start from their defaults.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from ..datasets import LabelSet
from ..imaging.runs import runs as runs_of

__all__ = ["GRID_ATTRIBUTES", "SURROUNDING_ATTRIBUTES", "grid_seed", "initialiser_for",
           "pinned_for", "window_boxes"]


def window_boxes(prob: np.ndarray, label_set: LabelSet, one_facade: bool = False
                 ) -> np.ndarray:
    """``(n, 4)`` boxes ``x0, y0, x1, y1`` (pixels, exclusive ends, row 0 on top) of the
    windows :func:`~facadeforge.imaging.detect.detect_elements` finds in the classifier's
    probabilities: it separates windows that touch in the class map and drops fragments and
    faint blobs (such as the uniform probabilities outside a warped photo).

    ``one_facade``: the photo is one facade, cropped (given ``--rectified``, as CMP's), so its
    windows stand in rows across the whole image and the detector starts from its XY-cut.
    Otherwise (street photos show neighbouring houses whose floors are offset, which the
    XY-cut's whole-image rows would chop) it starts from connected components of the pixels
    whose window probability is above 0.35 (so the uniform probabilities outside the warped
    photo, whose argmax is arbitrary, never join a window), and keeps windows of weaker
    evidence (mean probability 0.35), as balcony railings in front of Paris windows lower it."""
    from ..imaging.detect import detect_elements

    street = {} if one_facade else {"xy_tol": None, "min_score": 0.35, "min_prob": 0.35}
    els = detect_elements(prob, label_set.classes, labels=("window",), **street)
    return np.array([e.box for e in els], float).reshape(-1, 4)


def _groups(lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
    """Indices grouped by the centres of 1-D intervals [lo, hi): sorted centres split where two
    neighbours are further apart than half the median interval length.  (Grouping overlapping
    intervals instead chains everything together through a few tall or wide fragments.)"""
    centre = (lo + hi) / 2
    order = np.argsort(centre)
    gap = 0.5 * float(np.median(hi - lo))
    groups, cur = [], [order[0]]
    for a, b in zip(order[:-1], order[1:]):
        if centre[b] - centre[a] > gap:
            groups.append(np.array(cur))
            cur = []
        cur.append(b)
    groups.append(np.array(cur))
    return groups


def _supported(groups: list[np.ndarray], min_count: int) -> list[np.ndarray]:
    """Keep groups with at least ``min_count`` members (a column needs windows on several
    floors, a row windows in several columns)."""
    return [g for g in groups if len(g) >= min_count]


def _leading(mask: np.ndarray) -> int:
    """Length of the run of True at the start of a 1-D mask."""
    return int(np.argmin(mask)) if not mask.all() else mask.size


def _surroundings(labels: np.ndarray, label_set: LabelSet, boxes: np.ndarray
                  ) -> tuple[float, float, float]:
    """``(left, right, street)``: the shares of the facade's width and height that the
    classifier's ``labels`` (argmax map) show as background (not the building) at its left and
    right sides and at its bottom.  A side margin is a run of columns, from the border
    inwards, that are mostly background and hold no window; the street a run of such rows,
    measured between the margins.  Zero for label sets without a background class (``ecp7``:
    its photos' neighbours are labelled as facade)."""
    if "background" not in label_set.classes:
        return 0.0, 0.0, 0.0
    h, w = labels.shape
    bg = labels == label_set.index("background")
    occupied_x = np.zeros(w, bool)
    occupied_y = np.zeros(h, bool)
    for x0, y0, x1, y1 in boxes.astype(int):
        occupied_x[x0:x1] = True
        occupied_y[y0:y1] = True
    free_x = (bg.mean(axis=0) > 0.6) & ~occupied_x
    left = min(_leading(free_x), int(0.35 * w))
    right = min(_leading(free_x[::-1]), int(0.35 * w))
    # the street is measured between the margins, which would count towards every row
    free_y = (bg[:, left:max(w - right, left + 1)].mean(axis=1) > 0.6) & ~occupied_y
    street = _leading(free_y[::-1])
    return left / w, right / w, street / h


def _attic(labels: np.ndarray, label_set: LabelSet, roof_line: float, roof_frac: float = 0.03
           ) -> float:
    """Height (share of the facade) of the wall band between the top floor's windows and the
    roof: from the roof line up to the first of the top rows the classifier's ``labels`` show
    as background (less ``grid.cga``'s default roof band), so the top floor is not stretched
    to the top of the facade.  Zero without a background class (:func:`pinned_for`)."""
    if "background" not in label_set.classes:
        return 0.0
    top = (labels == label_set.index("background")).mean(axis=1) > 0.6
    return float(np.clip(1 - _leading(top) / top.size - roof_line - roof_frac, 0, 0.3))


def _arcade_seed(band: np.ndarray, label_set: LabelSet, left: list[float], win_w: float,
                 w: int, kind: str) -> dict[str, Any]:
    """``grid.cga``'s arcade attributes read from the classifier's labels ``band`` of the
    ground floor (between the margins, above the street; ``left`` are the window columns'
    left edges in that band, as fractions of the facade width ``w``): under each window
    column, the run of band columns that are mostly openings (shop, door or window) gives the
    opening's width and height; the arcade's kind is the most common opening class, its door
    the column whose opening is mostly door.  Only when two or more distinct openings stand
    apart (piers that are not opening between them) is ``groundKind`` ``"arcade"`` and are
    the arcade's attributes returned; otherwise ``{"groundKind": kind}``."""
    kinds = [c for c in ("shop", "door", "window") if c in label_set.classes]
    if band.shape[0] < 2 or band.shape[1] < 2 or not kinds:
        return {}
    ids = [label_set.index(c) for c in kinds]
    opening = np.isin(band, ids)
    share = opening.mean(axis=0)
    bw = band.shape[1]
    runs: dict[tuple[int, int], int] = {}       # (x0, x1) → the first column standing on it
    door_share = [0.0] * len(left)
    open_runs = runs_of(share >= 0.4)
    for j, x in enumerate(left):
        cx = int(round((x + win_w / 2) * w))
        if not 0 <= cx < bw or share[cx] < 0.4:
            continue
        x0, x1 = next((a, b) for a, b in open_runs if a <= cx < b)
        runs.setdefault((x0, x1), j)
        n_open = max(1, int(opening[:, x0:x1].sum()))   # the door's share of the opening
        if "door" in kinds:
            door_share[j] = float((band[:, x0:x1] == label_set.index("door")).sum()) / n_open
    widths = [(x1 - x0) / w for x0, x1 in runs]
    apart = len(runs) >= 2 and float(share.mean()) < 0.7 and sum(widths) < 0.8
    if not apart:
        return {"groundKind": kind}
    heights = [float((opening[:, x0:x1].mean(axis=1) > 0.5).sum()) / band.shape[0]
               for x0, x1 in runs]
    counts = [sum(int((band[:, x0:x1] == i).sum()) for x0, x1 in runs) for i in ids]
    spacing = min(np.diff(sorted(left)), default=1.0)    # openings must not overlap
    return {
        "groundKind": "arcade",
        "arcadeWidth": float(np.clip(min(np.median(widths), spacing), 0.01, 0.3)),
        "arcadeHeight": float(np.clip(np.median(heights), 0.2, 1)),
        "arcadeKind": kinds[int(np.argmax(counts))],
        "doorColumn": float(1 + int(np.argmax(door_share))) if max(door_share) > 0.5 else 0.0,
    }


def _door_beside(door: np.ndarray, row: np.ndarray) -> bool:
    """Whether a door stands beside a row of window boxes ``(x0, y0, x1, y1)`` (pixels, rows
    down): a door component, more than a speck, reaching from below the windows' foot up past
    half their height — the row is then the ground floor's, not a floor above it."""
    top = int(np.median(row[:, 1]))
    hh = int(np.median(row[:, 3])) - top
    n, _, stats, _ = cv2.connectedComponentsWithStats(door[top:].astype(np.uint8),
                                                      connectivity=4)
    return any(y < hh / 2 and y + dh > hh and dw * dh >= 0.06 * hh * hh
               for _x, y, dw, dh, _a in stats[1:n])


def grid_seed(prob: np.ndarray, label_set: LabelSet, max_floors: int = 10,
              max_columns: int = 12, surroundings: bool = True, one_facade: bool = False
              ) -> dict[str, Any] | None:
    """Attributes of ``grid.cga`` read from the window map, or ``None`` with too few windows.
    ``surroundings``: the grammar has background margins (``leftMargin``, ``rightMargin``,
    ``streetFrac``) and its ground floor spans the building between them; ``one_facade``: see
    :func:`window_boxes`."""
    h, w = prob.shape[:2]
    boxes = window_boxes(prob, label_set, one_facade)
    if len(boxes) < 2:
        return None
    area = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    boxes = boxes[area >= 0.25 * np.median(area)]       # drop fragments
    if len(boxes) < 2:
        return None
    # A grid: rows need windows in a good share of the columns and columns in a good share of
    # the rows, so a neighbouring building's windows (other floor heights) or stray detections
    # do not add rows or columns of their own.
    cols = _supported(_groups(boxes[:, 0], boxes[:, 2]), 2)
    rows = _supported(_groups(boxes[:, 1], boxes[:, 3]), max(2, math.ceil(0.5 * len(cols))))
    if rows:
        boxes = boxes[np.concatenate(rows)]
        cols = _supported(_groups(boxes[:, 0], boxes[:, 2]), max(2, math.ceil(0.5 * len(rows))))
        rows = _supported(_groups(boxes[:, 1], boxes[:, 3]), max(2, math.ceil(0.5 * len(cols))))
    if not cols or not rows:
        return None
    cols = sorted(cols, key=lambda g: np.median(boxes[g, 0]))[:max_columns]
    rows = sorted(rows, key=lambda g: -np.median(boxes[g, 3]))[:max_floors]   # bottom first
    labels = np.argmax(prob, axis=2)
    if len(rows) >= 2 and "door" in label_set.classes and _door_beside(
            labels == label_set.index("door"), boxes[rows[0]]):
        rows = rows[1:]     # the lowest windows stand beside a door: they are the ground floor's
        if len(rows) == 1:  # one floor above it: its windows alone are the columns (the door's
            upper = rows[0]  # column has a window above it only, and is a column all the same)
            cols = [upper[g] for g in _groups(boxes[upper, 0], boxes[upper, 2])][:max_columns]
            cols = sorted(cols, key=lambda g: np.median(boxes[g, 0]))
    left_m, right_m, street = (_surroundings(labels, label_set, boxes) if surroundings
                               else (0.0, 0.0, 0.0))
    inner_w = w * max(0.05, 1 - left_m - right_m)    # the building between the side margins
    win_w = float(np.median([np.median(boxes[g, 2] - boxes[g, 0]) for g in cols])) / w
    left = [float(np.median(boxes[g, 0])) / w for g in cols]
    # rows in facade coordinates (fractions, y up): window bottom a, top b
    a = [1.0 - float(np.median(boxes[g, 3])) / h for g in rows]
    b = [1.0 - float(np.median(boxes[g, 1])) / h for g in rows]
    heights = [bi - ai for ai, bi in zip(a, b)]
    gaps = [a[i + 1] - b[i] for i in range(len(rows) - 1)]
    gap = float(np.median(gaps)) if gaps else 0.5 * float(np.median(heights))
    lines = sorted([a[0] - gap / 2] + [(b[i] + a[i + 1]) / 2 for i in range(len(rows) - 1)])
    roof = b[-1] + gap / 2
    floor_h = [(lines[i + 1] if i + 1 < len(lines) else roof) - lines[i]
               for i in range(len(lines))]
    fh = float(np.median(floor_h))
    seed: dict[str, Any] = {
        "nColumns": float(len(cols)), "windowWidth": float(np.clip(win_w, 0.01, 0.3)),
        "nFloors": float(len(rows)), "groundTop": float(np.clip(lines[0], 0, 0.6)),
        "roofLine": float(np.clip(roof, 0.1, 1)),
        "windowHeight": float(np.clip(np.median(heights) / fh, 0.1, 0.95)),
        "sillHeight": float(np.clip((gap / 2) / fh, 0, 0.6)),
        "leftMargin": left_m, "rightMargin": right_m,
        "streetFrac": float(np.clip(min(street, lines[0]), 0, 0.3)),
        "atticFrac": _attic(labels, label_set, roof),
    }
    for j, x in enumerate(left, start=1):
        seed[f"column{j}"] = float(np.clip(x, 0, 1))
    for i, y in enumerate(lines[1:], start=2):
        seed[f"floor{i}"] = float(np.clip(y, 0, 1))
    # the ground floor: between the first floor line and the street, between the margins
    ground_row = int(round((1 - seed["groundTop"]) * h))
    street_row = max(ground_row, h - int(round(seed["streetFrac"] * h)))
    x_in = int(round(left_m * w))
    x_out = max(x_in + 1, w - int(round(right_m * w)))
    band = prob[ground_row:street_row, x_in:x_out]
    # shops where the band below the first floor line is mostly shop
    if band.size and "shop" in label_set.classes:
        shop = band[:, :, label_set.index("shop")].mean()
        seed["groundKind"] = "shops" if shop > 0.25 else "wall"
    if surroundings:
        seed.update(_arcade_seed(labels[ground_row:street_row, x_in:x_out], label_set,
                                 [x - x_in / w for x in left], win_w, w,
                                 seed.get("groundKind", "wall")))
    # the door: the largest door component of the ground floor band
    if "door" in label_set.classes and street_row > ground_row:
        door = (labels[ground_row:street_row, x_in:x_out] == label_set.index("door"))
        n, _, stats, _ = cv2.connectedComponentsWithStats(door.astype(np.uint8), connectivity=4)
        if n > 1:
            x, y, dw, dh, _ = stats[1 + int(np.argmax(stats[1:, 4]))]
            band_h = street_row - ground_row
            seed["doorWidth"] = float(np.clip(dw / inner_w, 0, 0.25))
            seed["doorPosition"] = float(np.clip(x / max(inner_w - dw, 1), 0, 1))
            seed["doorHeight"] = float(np.clip((band_h - y) / band_h, 0.3, 1))
        else:
            seed["doorWidth"] = 0.0
    # running balconies: floors whose lowest part is balcony across most of the width
    if "balcony" in label_set.classes:
        bal = labels == label_set.index("balcony")
        tops = lines[1:] + [roof]
        fracs = []
        for i, (lo, hi) in enumerate(zip(lines, tops), start=1):
            r1 = int(round((1 - lo) * h))
            r0 = int(round((1 - (lo + 0.35 * (hi - lo))) * h))
            share = bal[max(r0, 0):max(r1, r0 + 1)].mean(axis=1) if r1 > r0 else np.zeros(1)
            running = bool(share.max(initial=0) > 0.5)
            seed[f"balcony{i}"] = seed[f"running{i}"] = running
            if running:
                fracs.append(float((share > 0.5).sum()) / max(r1 - r0, 1) * 0.35)
        if fracs:
            seed["balconyFrac"] = float(np.clip(np.median(fracs), 0.02, 0.35))
        # balcony guards: the share of a window's rows that are mostly balcony (at its foot)
        def guard_share(box: np.ndarray) -> float:
            x0, y0, x1, y1 = box.astype(int)
            lo = min(h, y1 + max(1, (y1 - y0) // 3))
            rows_bal = bal[y0:lo, x0:x1].mean(axis=1) > 0.5
            return float(rows_bal.sum()) / max(y1 - y0, 1)

        # guards per floor (grid.cga): the floor's windows mostly stand behind a guard; the
        # guard's height is the median share over the guarded floors' windows
        guarded: list[float] = []
        for i, g in enumerate(rows, start=1):
            floor_shares = [guard_share(boxes[j]) for j in g]
            seed[f"guard{i}"] = bool(np.median(floor_shares) > 0.05)
            if seed[f"guard{i}"]:
                guarded += floor_shares
        seed["guardFrac"] = float(np.clip(np.median(guarded), 0, 0.5)) if guarded else 0.0
    return seed


#: Attributes a grammar must declare for :func:`grid_seed` to apply (grid.cga, haussmann.cga).
GRID_ATTRIBUTES = frozenset({"groundTop", "nFloors", "roofLine", "nColumns", "column1",
                             "windowWidth", "windowHeight", "sillHeight"})

#: Background margins, street band and attic of ``grid.cga``, seeded when a grammar declares
#: them all.
SURROUNDING_ATTRIBUTES = frozenset({"leftMargin", "rightMargin", "streetFrac", "atticFrac"})


def pinned_for(rules, label_set: LabelSet) -> dict[str, Any]:
    """Attributes the search must leave alone for this classifier: without a background class
    (``ecp7``), the margins and street band would be scored as sky, which street photos never
    show beside or below a facade, and the top of the facade is the roof band's (an attic wall
    band would be read off the mansard roof), so they stay at zero rather than widen the
    search."""
    names = set(rules.ruleset.main.attrs)
    if SURROUNDING_ATTRIBUTES <= names and "background" not in label_set.classes:
        return dict.fromkeys(sorted(SURROUNDING_ATTRIBUTES), 0.0)
    return {}


def initialiser_for(rules, one_facade: bool = False
                    ) -> Callable[[np.ndarray, LabelSet], dict[str, Any] | None] | None:
    """The seed function for a loaded parse grammar, chosen by the attributes it declares (so a
    renamed or edited copy of a built-in grammar is seeded too), or ``None``; ``one_facade``
    as in :func:`window_boxes` (``parse`` passes whether the photo was given rectified)."""
    names = set(rules.ruleset.main.attrs)
    if not GRID_ATTRIBUTES <= names:
        return None
    columns = sum(1 for n in names if re.fullmatch(r"column\d+", n))
    floors = 1 + sum(1 for n in names if re.fullmatch(r"floor\d+", n))
    surroundings = SURROUNDING_ATTRIBUTES <= names

    def seed(prob: np.ndarray, label_set: LabelSet) -> dict[str, Any] | None:
        return grid_seed(prob, label_set, max_floors=floors, max_columns=columns,
                         surroundings=surroundings, one_facade=one_facade)

    return seed
