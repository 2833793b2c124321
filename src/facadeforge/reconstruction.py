"""Photo → procedural facade: the whole of Müller et al. 2007 in one call.

``reconstruct(photo)`` runs, in order (each stage timed in ``report["timings"]``):

1. ``load`` — read and normalise the photo (gray/RGBA/16-bit → RGB); huge photos are analysed
   at :data:`~facadeforge.photo.MAX_ANALYSIS_SIDE` and mapped back;
2. ``rectify`` — vanishing points → homography (App. A), skipped with ``rectified=True``;
3. ``symmetry`` / ``splits`` — MI repetition detection and floor/tile split lines (§2);
4. ``classify`` / ``detect`` — better than the paper: the shipped pixel classifier
   (``simon2011`` §4.3; ``classifier=``; ``cmp12`` for photos given as rectified, ``ecp7``
   for street photos) runs on the rectified photo, which is cropped to the
   facade it finds (:func:`_facade_extent`: sky and neighbours around it become background),
   and its elements become boxes (:mod:`.imaging.detect`);
   when it finds at least :data:`MIN_ELEMENTS`, floors, tiles and tile refinements are laid
   around them (:mod:`.imaging.element_layout`) instead of steps 3's lines and 6 (the
   ``structure`` against the ``structure-edges`` benchmark rows); balconies
   become boxes too and are hung, outside the partition, on the tile or floor they stand in
   front of (:mod:`.imaging.shape_tree`);
5. ``cluster`` — groups of similar floors and tiles (§2.3's groups);
6. ``refine`` — tile refinement with split synchronisation (§3), on the paper's path
   (``classifier=False``, or too few elements detected);
7. ``match`` — element matching per cluster by MI against the element library (§4), among the
   library elements of the detected class when the classifier gave one (balconies among the
   library's balconies, per cluster of the tile or floor they hang on);
8. ``tree`` / ``rules`` — the shape tree and its size-independent CGA rules (§5);
9. ``model`` — the rules derived by our engine on the facade rectangle, textured with the
   cluster-averaged rectified photo (§4: "backprojection of the original textures").

Confidence (not in the paper): every floor and tile split carries a score and the facade gets a
``needs_review`` flag with reasons (:func:`review_flags`).

One facade at a time (not in the paper): :func:`reconstruct_facades`, which ``facadeforge
reconstruct`` calls, first cuts a street photo into its facades
(:func:`~facadeforge.imaging.facades.find_facades`, stage ``facades``: the two planes of a
corner, houses side by side), then runs stages 3–9 on each usable facade's own rectified crop
(:func:`_analyse`, the one entry point after ``rectify`` for a whole photo and for a facade of
it) and writes a folder per facade; with one facade its OUTDIR is :func:`reconstruct`'s.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import time
import weakref
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .model.model import Model
from .model.shape import INSERT, Shape
from .photo import MAX_ANALYSIS_SIDE, MIN_SIDE, analysis_copy, as_rgb, check_facade_size, check_size

__all__ = ["DEFAULT_DEPTHS", "FACADE_MODES", "MAX_ANALYSIS_SIDE", "MIN_ELEMENTS", "MIN_SIDE",
           "PhotoReconstruction", "Reconstruction", "draw_structure", "load_depths",
           "reconstruct", "reconstruct_facades", "review_flags", "structure_image",
           "write_element_assets"]

#: Default depth per class in metres: negative = recessed behind the wall plane (§5 rule 15).
DEFAULT_DEPTHS: dict[str, float] = {"window": -0.25, "door": -0.35, "shop": -0.3,
                                    "balcony": 0.9, "sill": 0.08, "cornice": 0.3, "wall": 0.0}
#: Element kinds matched on ground floors and on the floors above (§4 restricted per floor).
GROUND_KINDS: frozenset[str] = frozenset({"window", "door", "shop"})
UPPER_KINDS: frozenset[str] = frozenset({"window"})
#: Fewest classifier-detected elements laid out as the facade's structure (fewer: the paper's
#: edge-based path, which also handles facades the classifier does not recognise).
MIN_ELEMENTS: int = 2
#: Geometric tolerance of a cluster, as a fraction of the larger image side: members of one
#: rule differ by at most this much in size and element position.
CLUSTER_TOLERANCE: float = 0.005


@dataclass
class Reconstruction:
    """Everything :func:`reconstruct` found and made.

    ``rectified`` is the analysed RGB image; ``homography`` maps input-photo pixels to it and
    ``inverse`` back.  ``tree`` is the facade's :class:`~facadeforge.model.Shape` tree (metres),
    ``rules`` its CGA text, ``model`` the derived 3D model (``None`` with ``model=False``),
    ``labels`` the canonical label map in the rectified frame and ``report`` what goes to
    ``report.json``.
    """

    photo: np.ndarray
    rectified: np.ndarray
    homography: np.ndarray
    inverse: np.ndarray
    tree: Shape
    rules: str
    labels: np.ndarray
    report: dict
    texture: np.ndarray
    model: Model | None = None
    structure: object = None
    regions: list = field(default_factory=list)
    workdir: Path | None = None     # texture.jpg, rules.cga, assets/ the model was derived from
    inputs: dict = field(default_factory=dict)   # the input files: save() never writes over them

    def labels_input(self) -> np.ndarray:
        """The label map warped back into the input photo's pixel frame (nearest neighbour;
        0 = background outside the rectified facade)."""
        from .frames import warp

        return warp(self.labels, self.inverse, self.photo.shape[:2], nearest=True)

    def windows(self, label: str = "window", frame: str = "rectified") -> list[list[float]]:
        """Boxes ``[x0, y0, x1, y1]`` of the leaves labelled ``label``: rectified pixels, or
        with ``frame="input"`` the bounding boxes of their corners in the input photo."""
        boxes = [list(map(float, s.tags["box_px"])) for s in self.tree.leaves()
                 if s.label == label and "box_px" in s.tags]
        if frame == "rectified":
            return boxes
        if frame != "input":
            raise InputError(f"frame {frame!r}: use 'rectified' or 'input'")
        from .frames import box_to_image

        return box_to_image(np.array(boxes, float).reshape(-1, 4), self.inverse,
                            self.photo.shape[:2]).tolist()

    def save(self, out_dir: str | os.PathLike) -> list[Path]:
        """Write the OUTDIR files (see :func:`reconstruct`) atomically: everything is written
        into a staging folder beside ``out_dir`` and swapped in for it at the end
        (:mod:`facadeforge.outdir`: the files of an earlier run there are replaced; a folder
        with other files, or holding an input, is refused)."""
        return _save(self, Path(out_dir))


# ================================================================================ input
#: Largest ``--depths`` file read: a label or cluster a line, a few hundred bytes honestly.
MAX_DEPTHS_BYTES = 2**20
#: Largest depth accepted (metres, either way): a balcony sticks out a metre or two.
MAX_DEPTH = 20.0
#: Cluster ids ``--depths`` may name besides labels: tiles ``T3`` (``T3.1``…) and floors ``F2``.
_CLUSTER_ID = re.compile(r"[TF][0-9]+(\.[0-9]+)*")

_DEPTHS_FIX = 'write an object such as {"window": -0.3, "balcony": 1.2}'


def load_depths(path: str | os.PathLike | None) -> dict[str, float]:
    """Per-class depths: :data:`DEFAULT_DEPTHS` updated from a JSON object ``{label: metres}``
    (keys may also be cluster ids such as ``"T3"``).

    Raises
    ------
    InputError
        The file is missing, larger than :data:`MAX_DEPTHS_BYTES`, not JSON (or nested
        thousands of levels deep), not an object; a key is neither a label
        (:class:`~facadeforge.model.labels.Labels`) nor a cluster id (``T3``, ``T3.1``,
        ``F2``); a value is not a finite number of metres within ±:data:`MAX_DEPTH`.
    """
    from .jsonfile import json_type, read_json
    from .model.labels import Labels

    depths = dict(DEFAULT_DEPTHS)
    if path is None:
        return depths
    p = Path(path)
    data = read_json(p, "--depths file", max_bytes=MAX_DEPTHS_BYTES, fix=_DEPTHS_FIX)
    if not isinstance(data, dict):
        raise InputError(f"--depths file '{p}' holds {json_type(data)}, not an object "
                         f"{{label: metres}}; {_DEPTHS_FIX}")
    labels = {label.value for label in Labels}
    for k, v in data.items():
        shown = k if len(k) <= 40 else k[:36] + "…"
        if k not in labels and not _CLUSTER_ID.fullmatch(k):
            raise InputError(f"--depths file '{p}': '{shown}' is neither a label "
                             f"({', '.join(sorted(labels))}) nor a cluster id such as 'T3'; "
                             f"{_DEPTHS_FIX}")
        # abs(v) <= MAX_DEPTH: false for NaN and infinities, exact for integers of any size
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not abs(v) <= MAX_DEPTH:
            value = repr(v) if len(repr(v)) <= 24 else repr(v)[:20] + "…"
            raise InputError(f"--depths file '{p}': depth of '{shown}' must be a number of "
                             f"metres within ±{MAX_DEPTH:g}, got {value}; {_DEPTHS_FIX}")
        depths[k] = float(v)
    return depths


# ================================================================================ stages
def _scale(width_m, height_m, shape) -> tuple[float, float] | None:
    """Metres per pixel ``(mx, my)`` of the rectified image, or ``None`` (floor prior)."""
    h, w = shape[:2]
    if width_m is not None and height_m is not None:
        return width_m / w, height_m / h
    if width_m is not None:
        return (width_m / w,) * 2
    if height_m is not None:
        return (height_m / h,) * 2
    return None


def _tile_boxes(structure) -> tuple[list, list]:
    """Pixel boxes of all tiles and their ``(floor, tile)`` indices."""
    boxes, owner = [], []
    for i, (y0, y1) in enumerate(structure.floors):
        for j, (x0, x1) in enumerate(structure.tiles[i]):
            boxes.append((x0, y0, x1, y1))
            owner.append((i, j))
    return boxes, owner


def _clusters(gray, structure):
    from .imaging.clusters import cluster_regions

    w = gray.shape[1]
    fboxes = [(0, y0, w, y1) for y0, y1 in structure.floors]
    counts = np.array([len(t) for t in structure.tiles])
    floor_c = cluster_regions(gray, fboxes, size=(16, 96),
                              must_differ=counts[:, None] != counts[None, :])
    boxes, owner = _tile_boxes(structure)
    flat = cluster_regions(gray, boxes)
    tile_c: list[list[int]] = [[0] * len(t) for t in structure.tiles]
    for (i, j), c in zip(owner, flat):
        tile_c[i][j] = int(c)
    return floor_c.tolist(), tile_c, boxes, owner


def _area(r) -> int:
    x0, y0, x1, y1 = r.box
    return max(0, x1 - x0) * max(0, y1 - y0)


def _collapse_elements(region) -> None:
    """One element leaf per element found by the refinement (§4 matches whole regions).

    A maximal all-element subtree is either one element with strips beside it (a window and
    its sill: one leaf holds most of the area — it stays the element, the strips become wall)
    or an element split into parts (panes, mullions: no dominant leaf — the subtree becomes a
    single element leaf; the library element supplies the parts)."""
    from .imaging.refine import elements, leaves

    for sub in elements(region):
        parts = leaves(sub)
        big = max(parts, key=_area)
        if len(parts) > 1 and _area(big) >= 0.6 * _area(sub):
            for leaf in parts:
                leaf.role = "element" if leaf is big else "wall"
        else:
            sub.children, sub.split, sub.role = [], "none", "element"
    # Müller's tiles hold one element each (§2: a tile is the repeated unit around a window):
    # keep the largest, most central sizeable candidate; shutters, railing bars and sills
    # beside it become wall.
    x0, y0, x1, y1 = region.box
    tw, th = max(1, x1 - x0), max(1, y1 - y0)

    def score(r) -> float:
        rx0, ry0, rx1, ry1 = r.box
        if (rx1 - rx0) < 0.15 * tw or (ry1 - ry0) < 0.2 * th:
            return -1.0
        off = abs((rx0 + rx1) / 2 - (x0 + x1) / 2) / tw
        return _area(r) * max(0.0, 1.0 - 2.0 * off)

    cands = [r for r in leaves(region) if r.role == "element"]
    best = max(cands, key=score, default=None)
    for r in cands:
        if r is not best or score(r) <= 0:
            r.role = "wall"


def _refine(gray, structure, tile_c, owner, boxes):
    from .imaging.refine import Tile, refine_tiles

    tiles = [Tile(box=tuple(int(v) for v in b), cluster=tile_c[i][j], row=i, col=j)
             for b, (i, j) in zip(boxes, owner)]
    out = refine_tiles(gray, tiles)
    regions: list[list] = [[None] * len(t) for t in structure.tiles]
    for (i, j), r in zip(owner, out):
        _collapse_elements(r)
        regions[i][j] = r
    return regions


def _match(gray, regions, tile_c, floor_c, fronts=()):
    """Element type per element-leaf cluster (§4 eq. 8), kinds restricted per floor; protruding
    elements (balconies, ``fronts`` as in :attr:`~.imaging.element_layout.ElementLayout.fronts`)
    per cluster of the tile or floor they hang on."""
    from .imaging.matching import match_elements
    from .imaging.refine import element_leaves

    groups: dict[tuple[str, str, str], list] = {}
    for i, row in enumerate(regions):
        for j, region in enumerate(row):
            for leaf in element_leaves(region):
                key = ("G" if i == len(regions) - 1 else "U", leaf.label, f"T{tile_c[i][j]}")
                groups.setdefault(key, []).append(leaf)
    for i, hung in enumerate(fronts):
        for j, leaf in hung:
            host = f"F{floor_c[i]}" if j is None else f"T{tile_c[i][j]}"
            groups.setdefault(("P", leaf.label, host), []).append(leaf)
    chosen: dict[int, str] = {}
    # one matching per floor kind and known label: an element the classifier called a door is
    # matched among the library's doors (a balcony among its balconies); unlabelled ones (edge
    # path) among the floor's kinds
    for kind, label in sorted({k[:2] for k in groups}):
        sel = sorted(k for k in groups if k[:2] == (kind, label))
        kinds = {label} if label else GROUND_KINDS if kind == "G" else UPPER_KINDS
        boxes, cl = [], []
        for ci, k in enumerate(sel):
            for leaf in groups[k]:
                boxes.append(leaf.box)
                cl.append(ci)
        res = match_elements(gray, np.array(boxes), np.array(cl), kinds=kinds)
        for ci, k in enumerate(sel):
            if ci in res:
                for leaf in groups[k]:
                    chosen[id(leaf)] = res[ci].element
    return chosen


def _leaf_info(chosen: Mapping[int, str], depths: Mapping[str, float]):
    from .elements.library import element_spec

    def info(region, cluster: str) -> dict:
        if region is None or region.role != "element":
            return {"label": "wall"}
        name = chosen.get(id(region))
        if name is None:
            label = region.label or "window"
            return {"label": label, "depth": depths.get(cluster, depths.get(label, -0.25))}
        spec = element_spec(name)
        depth = depths.get(cluster, depths.get(spec.kind, spec.default_depth))
        return {"label": spec.kind, "element": name, "asset": f"assets/{name}.obj",
                "depth": float(depth)}

    return info


def cluster_averaged_texture(rgb: np.ndarray, tree: Shape,
                             valid: np.ndarray | None = None,
                             occluded: np.ndarray | None = None) -> np.ndarray:
    """The rectified photo with every tile replaced by the mean of its cluster (§4: the IF keeps
    the intensities of all repetitions, so each tile is textured with their average —
    occluders and noise present in few tiles fade).

    ``valid`` (H, W) bool marks the pixels the photo covers (a rectified street photo leaves
    wedges outside it): the means weigh valid pixels only, so a tile partly outside the photo
    is completed from its repetitions, and the pixels no repetition covers take the colour of
    the nearest valid pixel.  ``occluded`` (H, W) bool marks valid pixels whose colour was
    repaired (:mod:`facadeforge.repair`): they are kept where no repetition covers them, but
    the means weigh only what the camera saw.
    """
    import cv2

    out = rgb.copy()
    filled = np.ones(rgb.shape[:2], bool) if valid is None else np.asarray(valid, bool)
    ok = filled if occluded is None else filled & ~np.asarray(occluded, bool)
    filled = filled.copy()
    groups: dict[str, list[list[int]]] = {}
    for node in tree.walk():
        if node.symbol == "Tile":
            groups.setdefault(node.tags["cluster"], []).append(node.tags["box_px"])
    for members in groups.values():
        if len(members) < 2:
            continue
        ws = int(np.median([b[2] - b[0] for b in members]))
        hs = int(np.median([b[3] - b[1] for b in members]))
        if ws < 2 or hs < 2:
            continue
        acc = np.zeros((hs, ws, 3), np.float64)
        wsum = np.zeros((hs, ws, 1), np.float64)
        for x0, y0, x1, y1 in members:
            m = ok[y0:y1, x0:x1].astype(np.float32)[:, :, None]
            acc += cv2.resize(rgb[y0:y1, x0:x1] * m, (ws, hs), interpolation=cv2.INTER_AREA)
            wsum += cv2.resize(m, (ws, hs), interpolation=cv2.INTER_AREA).reshape(hs, ws, 1)
        seen = wsum[:, :, 0] > 1e-3
        mean = (acc / np.maximum(wsum, 1e-3)).astype(np.float32)
        for x0, y0, x1, y1 in members:
            size = (x1 - x0, y1 - y0)
            out[y0:y1, x0:x1] = np.clip(cv2.resize(mean, size, interpolation=cv2.INTER_LINEAR),
                                        0, 255)
            filled[y0:y1, x0:x1] |= cv2.resize(seen.astype(np.uint8), size,
                                               interpolation=cv2.INTER_NEAREST).astype(bool)
    if not filled.all() and filled.any():
        from scipy.ndimage import distance_transform_edt

        _, (iy, ix) = distance_transform_edt(~filled, return_indices=True)
        out = out[iy, ix]
    return out


def _covered(photo_shape, homography: np.ndarray, shape) -> np.ndarray | None:
    """(H, W) bool: the rectified pixels the input photo covers (``None``: all of them)."""
    from .frames import warp

    covered = warp(np.ones(photo_shape[:2], np.uint8), homography, shape, nearest=True) > 0
    return None if covered.all() else covered


def review_flags(structure, tree: Shape, rect_ok: bool, rect_reason: str,
                 floor_conf: list[float]) -> list[str]:
    """Reasons a person should look at the result (empty = none found)."""
    flags = []
    if not rect_ok:
        flags.append(f"rectification failed ({rect_reason}); analysed the photo as it is")
    if structure.floor_period_px <= 0:
        flags.append("no vertical repetition: the facade is its own irreducible facade")
    floors = [c for c in tree.children if c.symbol == "Floor"]
    if len(floors) <= 1:
        flags.append("one floor found")
    if floor_conf and float(np.median(floor_conf)) < 0.35:
        flags.append(f"weak floor split lines (median confidence {np.median(floor_conf):.2f})")
    if len(floors) >= 3:
        ground = floors[0]
        upper = Counter(f.tags["cluster"] for f in floors[1:])
        if ground.tags["cluster"] not in upper:
            flags.append("irregular ground floor (unlike every upper floor)")
    # balconies (inserted in front) are not openings: a facade of railings alone is flagged
    n_el = sum(1 for s in tree.leaves() if s.label not in ("wall", "balcony"))
    if n_el == 0:
        flags.append("no windows or doors found")
    return flags


def _classifier(classifier, rectified: bool):
    """The pixel classifier to detect elements with, or ``None`` (``classifier=False``)."""
    if classifier is False:
        return None
    from .classify import default_label_set, resolve_classifier
    from .imaging.detect import DETECTED_LABELS

    clf = resolve_classifier(classifier, default_label_set(rectified, elements=True))
    if not set(DETECTED_LABELS) & set(clf.classes):
        raise InputError(f"classifier {clf!r} has none of the classes "
                         f"{', '.join(DETECTED_LABELS)}; pass one that labels windows")
    return clf


def _facade_extent(prob: np.ndarray, classes, min_keep: float = 0.5
                   ) -> tuple[int, int, int, int] | None:
    """The rectangle ``(x0, y0, x1, y1)`` of the rectified photo the facade fills, or ``None``
    (all of it): the longest run of columns, then of rows within them, whose probability of
    not being facade (background, sky) averages below one half.  A crop that would keep less
    than ``min_keep`` of a side is not trusted."""
    outside = [list(classes).index(c) for c in ("background", "sky") if c in classes]
    if not outside:
        return None
    from scipy.ndimage import uniform_filter1d

    from .imaging.runs import longest_run

    bg = prob[:, :, outside].sum(axis=2, dtype=np.float32)
    h, w = bg.shape

    def run(profile: np.ndarray) -> tuple[int, int]:
        profile = uniform_filter1d(profile, max(1, profile.size // 100), mode="nearest")
        return longest_run(profile < 0.5)

    x0, x1 = run(bg.mean(axis=0))
    if x1 - x0 < min_keep * w:
        return None
    y0, y1 = run(bg[:, x0:x1].mean(axis=1))
    if y1 - y0 < min_keep * h or (x0, y0, x1, y1) == (0, 0, w, h) \
            or min(x1 - x0, y1 - y0) < MIN_SIDE:
        return None
    return x0, y0, x1, y1


def _detect(prob, clf, gray, px_per_m, edges):
    """Elements from the classifier's probabilities and the layout around them (``None`` with
    fewer than :data:`MIN_ELEMENTS`), and what goes to ``report["detection"]``."""
    if prob is None:
        return None, {"source": "edges", "classifier": None, "found": 0}
    from .datasets import LABEL_SETS
    from .imaging.detect import DETECTED_LABELS, detect_elements, detect_protruding
    from .imaging.element_layout import element_layout

    known = LABEL_SETS.get(clf.label_set)     # a scribble GMM's classes follow no dataset
    if hasattr(clf, "detected_elements"):      # elements found otherwise (a scan's depth map)
        elements, fronts = clf.detected_elements()
    else:
        elements = detect_elements(prob, clf.classes,
                                   behind=known.windows_behind if known is not None else (),
                                   covers=known.windows_covering if known is not None else ())
        fronts = detect_protruding(prob, clf.classes)
    info = {"classifier": {"kind": clf.kind, "label_set": clf.label_set},
            "found": len(elements), "protruding": len(fronts),
            "by_label": dict(Counter(e.label for e in elements + fronts))}
    if len(elements) < MIN_ELEMENTS:
        return None, {"source": "edges", **info}
    detected = [c for c in DETECTED_LABELS if c in clf.classes]
    occupancy = prob[:, :, [clf.classes.index(c) for c in detected]].sum(axis=2)
    layout = element_layout(elements, gray, occupancy, float(px_per_m[1]), edges, fronts)
    return layout, {"source": "classifier", **info}


# ================================================================================ pipeline
def reconstruct(photo, *, rectified: bool = False, width_m: float | None = None,
                height_m: float | None = None, depths: Mapping[str, float] | str | None = None,
                out_dir: str | os.PathLike | None = None, model: bool = True,
                refine: bool = True, classifier=None, repair: bool = True,
                seed: int = 0) -> Reconstruction:
    """Reconstruct a procedural facade from one photo (Müller et al. 2007, all sections).

    Parameters
    ----------
    photo : path or (H, W[, C]) array
        The facade photo (any image Pillow reads; gray, RGBA, 16-bit are converted).
    rectified : bool
        The photo is already fronto-parallel: skip rectification.
    width_m, height_m : float, optional
        Size in metres of the facade analysed — the rectified photo, cropped to the facade when
        the classifier sees sky or neighbours around it (``report["facade_crop"]``); otherwise
        the floor-height prior sets the scale.
    depths : mapping or path to JSON, optional
        Depth per class or per cluster id (metres, negative = recessed); see
        :data:`DEFAULT_DEPTHS`.
    out_dir : path, optional
        Write ``rectified.png, structure.png, labels.png, labels_input.png, shape_tree.json,
        rules.cga, rules.gml, assets/, texture.jpg, model.glb, model.obj (+ .mtl, textures/),
        model.city.json, report.json`` there (atomically; the folder is replaced whole, and
        refused when it holds an input or files facadeforge did not write: see
        :mod:`facadeforge.outdir`).
    model : bool
        Derive the 3D model (the benchmark harness only needs the tree).
    refine : bool
        Run tile refinement (§3) on the paper's path; without it tiles stay wall leaves.
    classifier : PixelClassifier, path to a model file, None or False
        Pixel classifier whose elements structure the facade (module docstring, step 4);
        ``None``: the shipped model (``cmp12`` with ``rectified``, else ``ecp7``:
        :func:`facadeforge.classify.default_label_set`); ``False``: the paper's edge-based
        path only.
    repair : bool
        Texture the model with the facade repaired (:mod:`facadeforge.repair`: trees, cars
        and people in front of it found and filled, ``report["repair"]`` says what); ``False``
        keeps the photo as it is.

    Raises
    ------
    InputError
        Unreadable, corrupt or too small photos; bad sizes or depths.
    """
    loaded = _load(photo, rectified=rectified, width_m=width_m, height_m=height_m,
                   depths=depths, out_dir=out_dir, classifier=classifier)
    t = time.perf_counter()
    rect_img, H, rect = _rectify_whole(loaded.work, rectified, seed)
    loaded.timings["rectify"] = time.perf_counter() - t
    rec = _analyse(loaded, rect_img, H @ loaded.to_work, rect, applied=not rectified,
                   width_m=width_m, height_m=height_m, model=model, refine=refine,
                   repair=repair)
    if out_dir is not None:
        rec.save(out_dir)         # adds the export time to the report it writes last
    return rec


@dataclass
class _Loaded:
    """A photo read and checked, with what every facade of it is analysed with."""

    rgb: np.ndarray
    name: str
    work: np.ndarray            # the analysis copy
    to_work: np.ndarray         # photo pixels -> analysis copy pixels
    clf: object
    depth_map: dict
    inputs: dict
    timings: dict


def _load(photo, *, rectified: bool, width_m, height_m, depths, out_dir, classifier) -> _Loaded:
    """Stage ``load``: the checks that fail before any analysis, the photo and its analysis
    copy, the depths and the classifier."""
    t = time.perf_counter()
    check_facade_size(width_m, height_m)
    inputs = {"photo": photo, "--classifier": classifier, "--depths": depths}
    if out_dir is not None:     # a bad -o fails before the analysis, not after it
        from .outdir import check_outdir

        check_outdir(out_dir, inputs)
    rgb, name = as_rgb(photo)
    check_size(rgb, name)
    depth_map = load_depths(depths) if not isinstance(depths, Mapping) else {**DEFAULT_DEPTHS,
                                                                            **depths}
    work, to_work = analysis_copy(rgb)
    clf = _classifier(classifier, rectified)   # a bad model file fails before any analysis
    return _Loaded(rgb, name, work, to_work, clf, depth_map, inputs,
                   {"load": time.perf_counter() - t})


def _rectify_whole(work: np.ndarray, rectified: bool, seed: int):
    """Stage ``rectify`` for the photo as one facade: the rectified image, the homography from
    the analysis copy to it, and ``(ok, reason, confidence)``."""
    rect_ok, rect_reason, rect_conf = True, "", 1.0
    if rectified:
        rect_img, H = work, np.eye(3)
    else:
        from .imaging.rectify import rectify

        r = rectify(work, rng=seed)
        rect_ok, rect_reason, rect_conf = bool(r), r.reason, float(r.confidence)
        rect_img, H = (r.image, r.homography) if r else (work, np.eye(3))
    if min(rect_img.shape[:2]) < MIN_SIDE:    # a degenerate crop: analyse the photo itself
        rect_ok, rect_reason = False, "rectified crop too small"
        rect_img, H = work, np.eye(3)
    return rect_img, H, (rect_ok, rect_reason, rect_conf)


def _repair(rect_img: np.ndarray, tree: Shape, labels: np.ndarray, covered):
    """Stage ``repair`` (seed ``shang2023``): occluders in front of the facade found and
    filled before the texture is made — the tiles of each cluster are the repetition groups,
    the shape tree's labels the facade's.  Returns the :class:`~facadeforge.repair.Repair`
    (``None`` when nothing was found) and what goes to ``report["repair"]``."""
    from .repair.pipeline import repair_photo

    if min(rect_img.shape[:2]) < MIN_SIDE:
        return None, {"mask": {"source": None, "pixels": 0, "fraction": 0.0}, "filled": {},
                      "completed": {}, "seconds": 0.0, "note": "facade too small to repair"}
    groups: dict[str, list] = {}
    for node in tree.walk():
        if node.symbol == "Tile":
            groups.setdefault(node.tags["cluster"], []).append(tuple(node.tags["box_px"]))
    rep = repair_photo(rect_img, rectified=True, labels=labels,
                       groups=[g for g in groups.values() if len(g) >= 2])
    if covered is not None:
        rep.mask &= covered
    r = rep.report
    summary = {"mask": r["mask"], "filled": r["filled"], "completed": r["completed"],
               "seconds": r["timings"]["total"]}
    return (rep if rep.mask.any() else None), summary


def _analyse(loaded: _Loaded, rect_img: np.ndarray, homography: np.ndarray, rect, *,
             applied: bool, width_m=None, height_m=None, model: bool = True,
             refine: bool = True, repair: bool = True, timings: dict | None = None
             ) -> Reconstruction:
    """Stages ``classify`` to ``model`` on one rectified facade: ``rect_img`` and the
    ``homography`` from photo pixels to it; ``rect`` is ``(ok, reason, confidence)`` of its
    rectification (``applied``: it was rectified here)."""
    rgb, name, clf, depth_map = loaded.rgb, loaded.name, loaded.clf, loaded.depth_map
    timings = dict(loaded.timings) if timings is None else timings
    rect_ok, rect_reason, rect_conf = rect
    t = time.perf_counter()
    prob = clf.predict_proba(rect_img) if clf is not None else None
    crop = _facade_extent(prob, clf.classes) if prob is not None else None
    uncropped = rect_img.shape[:2]
    if crop is not None:     # the facade only: sky and neighbours around it are background
        x0, y0, x1, y1 = crop
        rect_img, prob = rect_img[y0:y1, x0:x1], prob[y0:y1, x0:x1]
        homography = np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1.0]]) @ homography
    timings["classify"] = time.perf_counter() - t

    from .imaging.splits import FLOOR_PRIOR_M, edge_maps, floor_and_tile_split, to_gray

    t = time.perf_counter()
    gray = to_gray(rect_img)
    edges = edge_maps(gray)                      # eq. 3, shared by stage 1 and the layout
    t_edges = time.perf_counter() - t
    mpp = _scale(width_m, height_m, rect_img.shape)
    # stage 1; its tile lines only matter on the edge path (the classifier path lays its own)
    structure = floor_and_tile_split(gray, metres_per_pixel=mpp, tiles=clf is None, edges=edges)
    timings["symmetry"] = structure.timings.get("symmetry", 0.0)
    timings["splits"] = t_edges + structure.timings.get("floors", 0.0) + structure.timings.get(
        "tiles", 0.0)
    px_per_m = (1.0 / mpp[0], 1.0 / mpp[1]) if mpp else (structure.px_per_m, structure.px_per_m)

    t = time.perf_counter()
    layout, detection = _detect(prob, clf, gray, px_per_m, edges)
    if layout is None and clf is not None:       # too few elements: the edge path after all
        structure = floor_and_tile_split(gray, metres_per_pixel=mpp, edges=edges)
    if layout is not None:
        # the floors laid around the elements replace stage 1's, and so does the floor period
        # they measure (stage 1's MI period is often a half or double storey on real photos)
        period = layout.floor_period_px or structure.floor_period_px
        structure = dataclasses.replace(
            structure, floors=layout.floors, tiles=layout.tiles,
            confidences=layout.confidences, floor_period_px=period,
            floor_lines=[b for _, b in layout.floors[:-1]],
            px_per_m=period / FLOOR_PRIOR_M if period > 0 else structure.px_per_m)
        if not mpp:
            px_per_m = (structure.px_per_m, structure.px_per_m)
    timings["detect"] = time.perf_counter() - t

    t = time.perf_counter()
    floor_c, tile_c, boxes, owner = _clusters(gray, structure)
    timings["cluster"] = time.perf_counter() - t

    t = time.perf_counter()
    if layout is not None:
        regions = layout.regions
    else:
        regions = _refine(gray, structure, tile_c, owner, boxes) if refine else None
    # appearance clusters split by geometry: the rules (one per cluster, sizes averaged) then
    # derive every element back within CLUSTER_TOLERANCE of where it was found
    from .imaging.element_layout import refine_clusters

    fronts = layout.fronts if layout is not None else []
    floor_c, tile_c = refine_clusters(structure.floors, structure.tiles, regions, floor_c, tile_c,
                                      tol=CLUSTER_TOLERANCE * max(gray.shape), fronts=fronts)
    timings["refine"] = time.perf_counter() - t

    t = time.perf_counter()
    chosen = _match(gray, regions, tile_c, floor_c, fronts) if regions else {}
    timings["match"] = time.perf_counter() - t

    t = time.perf_counter()
    from .imaging.shape_tree import PixelFrame, build_shape_tree

    frame = PixelFrame(rect_img.shape[1], rect_img.shape[0], px_per_m)
    tree = build_shape_tree(frame, structure.floors, structure.tiles, floor_c, tile_c,
                            regions=regions, leaf_info=_leaf_info(chosen, depth_map),
                            floor_confidence=structure.confidences["floors"],
                            tile_confidence=structure.confidences["tiles"], fronts=fronts)
    from .exchange.raster import label_map

    labels = label_map(tree, size=rect_img.shape[:2])
    timings["tree"] = time.perf_counter() - t

    t = time.perf_counter()
    from .grammar.extract import extract_rules

    rules = extract_rules(tree, texture="texture.jpg", depths=depth_map)
    timings["rules"] = time.perf_counter() - t

    covered = _covered(rgb.shape, homography, rect_img.shape)
    t = time.perf_counter()
    repaired, repair_report = _repair(rect_img, tree, labels, covered) if repair else (
        None, None)
    if repair:
        timings["repair"] = time.perf_counter() - t
    texture = cluster_averaged_texture(rect_img if repaired is None else repaired.repaired, tree,
                                       covered, None if repaired is None else repaired.mask)
    flags = review_flags(structure, tree, rect_ok, rect_reason, structure.confidences["floors"])
    notes = [] if mpp else ["scale from the floor-height prior: give --width-m for true metres"]
    if clf is not None and layout is None:
        notes.append(f"the classifier found {detection['found']} element(s), fewer than "
                     f"{MIN_ELEMENTS}: floors, tiles and elements from image edges (§2–3)")
    w_m, h_m = frame.size_m
    report = {
        "input": {"photo": name, "width_px": int(rgb.shape[1]), "height_px": int(rgb.shape[0])},
        "rectification": {"applied": applied, "ok": rect_ok, "confidence": round(rect_conf, 4),
                          "reason": rect_reason, "homography": homography.tolist()},
        # the facade's box in the rectified photo before the crop (None: all of it)
        "facade_crop": None if crop is None else {
            "box": [int(v) for v in crop], "of": [int(uncropped[1]), int(uncropped[0])]},
        "facade": {"width_m": round(w_m, 3), "height_m": round(h_m, 3),
                   "px_per_m": [round(v, 4) for v in px_per_m],
                   "scale_source": "given" if mpp else structure.scale_source,
                   "floor_period_m": round(structure.floor_period_px / px_per_m[1], 3)},
        "floors": len(structure.floors),
        "tiles": int(sum(len(t) for t in structure.tiles)),
        "floor_clusters": len(set(floor_c)),
        "tile_clusters": len({c for row in tile_c for c in row}),
        "elements": dict(Counter(s.label for s in tree.leaves() if s.label != "wall")),
        "detection": detection,
        "confidences": structure.confidences,
        "needs_review": bool(flags),
        "flags": flags,
        "notes": notes,
        "repair": repair_report,
        "timings": timings,
    }
    rec = Reconstruction(photo=rgb, rectified=rect_img, homography=homography,
                         inverse=np.linalg.inv(homography), tree=tree, rules=rules, labels=labels,
                         report=report, texture=texture, structure=structure,
                         regions=regions or [], inputs=loaded.inputs)
    if model:
        t = time.perf_counter()
        rec.model, rec.workdir = _derive_model(rec, frame)
        timings["model"] = time.perf_counter() - t
    report["timings"]["total"] = sum(v for k, v in timings.items() if k != "total")
    return rec


# ================================================================================ facades
#: ``--facades`` choices: ``auto`` finds the facades of a street photo
#: (:func:`~facadeforge.imaging.facades.find_facades`), ``one`` models the photo as one.
FACADE_MODES = ("auto", "one")


@dataclass
class PhotoReconstruction:
    """What :func:`reconstruct_facades` made of a photo: one :class:`Reconstruction` per
    modelled facade (``facades``, with their regions in ``regions``), the split of the photo
    (``split``, ``None`` for ``--facades one`` and rectified photos) and the top-level
    ``report``.  With one facade modelled, ``single`` is it and :meth:`save` writes the OUTDIR
    of one facade; with several, a folder per facade (see :func:`reconstruct_facades`).
    """

    photo: np.ndarray
    facades: list[Reconstruction]
    regions: list = field(default_factory=list)      # the FacadeRegion of each facade
    split: object = None
    report: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    to_work: np.ndarray = field(default_factory=lambda: np.eye(3))   # photo -> split's pixels
    layout: str = "one"                              # "one" facade's OUTDIR, or "facades"

    @property
    def single(self) -> Reconstruction | None:
        """The one facade modelled, when the OUTDIR is a single facade's."""
        return self.facades[0] if self.layout == "one" else None

    def folders(self) -> list[str]:
        return [f"facade_{r.id:02d}" for r in self.regions]

    def labels_input(self) -> np.ndarray:
        """Every facade's labels mapped back into the photo, each inside its own outline."""
        import cv2

        if self.single is not None:
            return self.single.labels_input()
        out = np.zeros(self.photo.shape[:2], np.uint8)
        back = np.linalg.inv(self.to_work)
        for rec, region in zip(self.facades, self.regions):
            lab = rec.labels_input()
            mask = np.zeros(out.shape, np.uint8)
            poly = _apply_h(back, region.polygon)
            poly = np.clip(poly, -4 * max(out.shape), 5 * max(out.shape))
            cv2.fillPoly(mask, [np.round(poly).astype(np.int32).reshape(-1, 1, 2)], 1)
            put = (mask > 0) & (lab > 0)
            out[put] = lab[put]
        return out

    def facades_image(self) -> np.ndarray:
        """``facades.png``: the photo with each facade's outline and id."""
        from .imaging.facades import draw_facades

        if self.split is None:
            return self.photo
        return draw_facades(self.photo, self.split, np.linalg.inv(self.to_work))

    def save(self, out_dir: str | os.PathLike) -> list[Path]:
        """Write the OUTDIR atomically (one staging folder for all of it)."""
        if self.single is not None:
            return self.single.save(out_dir)
        from PIL import Image

        from .exchange.raster import write_label_png
        from .outdir import write_json, write_outdir

        def write(stage: Path) -> None:
            t0 = time.perf_counter()
            for rec, folder in zip(self.facades, self.folders()):
                (stage / folder).mkdir()
                _write_files(rec, stage / folder)
            Image.fromarray(self.facades_image()).save(stage / "facades.png", compress_level=1)
            write_label_png(self.labels_input(), stage / "labels_input.png")
            timings = self.report["timings"]
            timings["export"] = time.perf_counter() - t0
            timings.pop("total", None)
            timings["total"] = sum(timings.values())
            write_json(stage / "report.json", self.report)

        return write_outdir(Path(out_dir), write, self.inputs)


def _apply_h(H: np.ndarray, pts) -> np.ndarray:
    p = np.asarray(pts, float).reshape(-1, 2)
    q = np.c_[p, np.ones(len(p))] @ np.asarray(H, float).T
    return q[:, :2] / q[:, 2:3]


def _region_entry(region, to_work: np.ndarray, folder: str | None, rec=None,
                  reason: str | None = None) -> dict:
    """A facade of ``report["facades"]``: where it is (photo pixels), whether and where it
    was modelled, its flags, quality and the summary of its reconstruction."""
    entry = region.to_dict()
    back = np.linalg.inv(to_work)
    entry["polygon"] = [[round(float(x), 1), round(float(y), 1)]
                        for x, y in _apply_h(back, region.polygon)]
    entry["homography"] = (np.asarray(region.homography) @ to_work).tolist()
    entry["folder"] = folder
    if reason:
        entry["flags"] = [*entry["flags"], reason]
        entry["ok"] = False
    if rec is not None:
        r = rec.report
        entry["summary"] = {"width_m": r["facade"]["width_m"], "height_m": r["facade"]["height_m"],
                            "floors": r["floors"], "tiles": r["tiles"], "elements": r["elements"],
                            "needs_review": r["needs_review"], "flags": r["flags"]}
    return entry


def _region_confidence(q: dict) -> float:
    """As :attr:`~.imaging.rectify.Rectification.confidence`: inlier counts and the share of
    the lines the vanishing points explain."""
    c = np.sqrt(max(0.0, min(1.0, float(q.get("line_share", 0.0)))))
    for key in ("horizontal_inliers", "vertical_inliers"):
        c *= min(1.0, q.get(key, 0) / 12.0)
    return float(c)


def reconstruct_facades(photo, *, facades: str = "auto", rectified: bool = False,
                        width_m: float | None = None, height_m: float | None = None,
                        depths: Mapping[str, float] | str | None = None,
                        out_dir: str | os.PathLike | None = None, model: bool = True,
                        refine: bool = True, classifier=None, repair: bool = True,
                        seed: int = 0) -> PhotoReconstruction:
    """A street photo → one reconstruction per facade it shows (``facadeforge reconstruct``).

    ``facades="auto"`` (the default) cuts the photo into its facades first
    (:func:`facadeforge.imaging.facades.find_facades`: the planes of a corner view, the houses
    side by side) and reconstructs each usable one alone from its own rectified crop
    (:func:`reconstruct`'s stages after ``rectify``); ``"one"`` is :func:`reconstruct` itself.
    Photos given as ``rectified`` are one facade.  Other parameters as :func:`reconstruct`;
    ``width_m`` / ``height_m`` describe one facade, so with several they are not applied (a
    note in the report says so).

    OUTDIR (``out_dir``):

    * one facade usable (or none, or ``"one"``): the files of :func:`reconstruct`, exactly as
      for one facade; a split photo's ``report.json`` also lists every facade found
      (``facades``) and the one modelled (``folder`` ``"."``);
    * several: ``facade_01/``, ``facade_02/``, … (left to right; each the files of
      :func:`reconstruct`, its ``report.json`` with its ``region``), and at the top
      ``facades.png`` (the photo with each facade's outline and id; those not modelled red
      and dashed, with their first flag), ``labels_input.png`` (every facade's labels in the
      photo) and ``report.json``: ``facades``, a list of ``id``, ``plane``, ``polygon`` (photo
      pixels), ``folder`` (``None``: not modelled), ``ok``, ``flags``, ``quality`` and the
      modelled facade's ``summary``; ``split`` (planes, vanishing points, focal length) and
      ``timings``.

    A facade that cannot be rectified well (``ok`` false: few lines, weak vanishing points,
    too oblique, a narrow sliver) is listed with its flags and no model.
    """
    if facades not in FACADE_MODES:
        raise InputError(f"--facades {facades!r}: use {' or '.join(FACADE_MODES)}")
    options = {"width_m": width_m, "height_m": height_m, "model": model, "refine": refine,
               "repair": repair}
    if facades == "one" or rectified:
        rec = reconstruct(photo, rectified=rectified, depths=depths, out_dir=out_dir,
                          classifier=classifier, seed=seed, **options)
        return PhotoReconstruction(rec.photo, [rec], inputs=rec.inputs)
    loaded = _load(photo, rectified=False, width_m=width_m, height_m=height_m, depths=depths,
                   out_dir=out_dir, classifier=classifier)
    from .imaging.facades import find_facades

    t = time.perf_counter()
    split = find_facades(loaded.work, rng=seed)
    loaded.timings["facades"] = time.perf_counter() - t
    small = [r for r in split.regions if r.ok and min(r.size) < MIN_SIDE]
    usable = [r for r in split.regions if r.ok and min(r.size) >= MIN_SIDE]
    too_small = {id(r): f"too small ({r.size[1]}x{r.size[0]} px rectified)" for r in small}
    to_work = loaded.to_work

    if len(split.regions) == 1 or not usable:
        # one facade (or none usable): the photo as one facade, rectified as a whole
        t = time.perf_counter()
        rect_img, H, rect = _rectify_whole(loaded.work, False, seed)
        loaded.timings["rectify"] = time.perf_counter() - t
        rec = _analyse(loaded, rect_img, H @ to_work, rect, applied=True, **options)
        rec.report["facades"] = [_region_entry(r, to_work, "." if len(split.regions) == 1
                                               else None, rec if len(split.regions) == 1
                                               else None, too_small.get(id(r)))
                                 for r in split.regions]
        if len(split.regions) > 1:
            rec.report["flags"].append(f"none of the {len(split.regions)} facades found could "
                                       "be rectified well: the photo is modelled as one")
            rec.report["needs_review"] = True
        result = PhotoReconstruction(rec.photo, [rec], split=split, inputs=loaded.inputs,
                                     to_work=to_work)
    else:
        several = len(usable) > 1
        if several and (width_m is not None or height_m is not None):
            options.update(width_m=None, height_m=None)
        folder = {id(r): (f"facade_{r.id:02d}" if several else ".") for r in usable}
        recs = []
        for region in usable:
            t = time.perf_counter()
            rect_img = region.rectified(loaded.work)
            # several facades: each report times its own stages, the top-level one the rest
            timings = {} if several else dict(loaded.timings)
            timings["rectify"] = time.perf_counter() - t
            rect = (True, "", _region_confidence(region.quality))
            rec = _analyse(loaded, rect_img, region.homography @ to_work, rect, applied=True,
                           timings=timings, **options)
            rec.report["region"] = _region_entry(region, to_work, folder[id(region)])
            recs.append(rec)
        rec_of = {id(r): rec for r, rec in zip(usable, recs)}
        entries = [_region_entry(r, to_work, folder.get(id(r)), rec_of.get(id(r)),
                                 too_small.get(id(r))) for r in split.regions]
        notes = []
        if several and (width_m is not None or height_m is not None):
            notes.append(f"--width-m/--height-m describe one facade; the photo has "
                         f"{len(usable)}, so the floor-height prior sets each one's scale "
                         "(give --facades one to model the photo as one facade of that size)")
        if not several:
            rec = recs[0]
            rec.report["facades"] = entries
            others = [e for e in entries if e["folder"] is None]
            rec.report["notes"].append(
                f"the photo shows {len(entries)} facades; facade {usable[0].id} is modelled, "
                + ", ".join(f"{e['id']} not ({e['flags'][0]})" for e in others))
            result = PhotoReconstruction(rec.photo, recs, regions=usable, split=split,
                                         inputs=loaded.inputs, to_work=to_work)
        else:
            timings = {"load": loaded.timings["load"], "facades": loaded.timings["facades"]}
            for r, rec in zip(usable, recs):
                timings[f"facade_{r.id:02d}"] = rec.report["timings"]["total"]
            report = {
                "input": recs[0].report["input"],
                "facades": entries,
                "split": {k: v for k, v in split.to_dict().items() if k != "facades"},
                "notes": notes,
                "timings": timings,
            }
            result = PhotoReconstruction(recs[0].photo, recs, regions=usable, split=split,
                                         report=report, inputs=loaded.inputs, to_work=to_work,
                                         layout="facades")
    if out_dir is not None:
        result.save(out_dir)
    return result


def _write_workdir(rec: Reconstruction, work: Path) -> None:
    """``texture.jpg``, ``rules.cga`` and the matched library elements as ``assets/*.obj``."""
    from PIL import Image

    Image.fromarray(rec.texture).save(work / "texture.jpg", quality=90)
    (work / "rules.cga").write_text(rec.rules)
    write_element_assets(rec.tree, work)


def write_element_assets(tree: Shape, folder: Path) -> None:
    """``folder/assets/NAME.obj`` for every library element a leaf of ``tree`` names (those
    already there are kept: the rules' ``i("assets/NAME.obj")`` finds them)."""
    from .elements.library import element_model, element_spec
    from .exchange.obj import export_obj

    for name in sorted({s.tags["element"] for s in tree.leaves() if "element" in s.tags}):
        target = folder / "assets" / f"{name}.obj"
        if not target.is_file():
            export_obj(element_model(element_spec(name)), target)


def _derive_model(rec: Reconstruction, frame) -> tuple[Model, Path]:
    """Derive ``rec.rules`` on the facade rectangle in a scratch folder holding the texture and
    the element assets (the model's materials point at files there until exported)."""
    from .engine import derive_facade
    from .scratch import scratch_dir

    # named after this process: a killed run's folder is removed by the next run's scratch_dir
    work = scratch_dir("facadeforge-model-")
    _write_workdir(rec, work)
    w_m, h_m = frame.size_m
    m = derive_facade(work / "rules.cga", w_m, h_m, assets=work, name="facade")
    weakref.finalize(rec, shutil.rmtree, work, True)   # texture files live as long as the result
    return m, work


def structure_image(rec: Reconstruction) -> np.ndarray:
    """``structure.png``: the rectified photo with floors and tiles drawn, a translucent colour
    per tile cluster and the elements outlined (blue; balconies and other inserted elements
    orange)."""
    return draw_structure(rec.rectified, rec.tree)


def draw_structure(rectified: np.ndarray, tree: Shape) -> np.ndarray:
    """:func:`structure_image` of a photo and a shape tree with ``box_px`` tags (also what
    ``facadeforge edit`` writes after an edit)."""
    import cv2

    img = rectified.astype(np.float32).copy()
    rng = np.random.default_rng(7)
    palette: dict[str, np.ndarray] = {}
    overlay = img.copy()
    for node in tree.walk():
        if node.symbol == "Tile" and "box_px" in node.tags:
            c = palette.setdefault(node.tags["cluster"], rng.uniform(40, 255, 3))
            x0, y0, x1, y1 = node.tags["box_px"]
            overlay[y0:y1, x0:x1] = c
    img = 0.65 * img + 0.35 * overlay
    out = np.clip(img, 0, 255).astype(np.uint8)
    thick = max(1, round(max(out.shape[:2]) / 500))
    for node in tree.walk():
        x0, y0, x1, y1 = node.tags.get("box_px", (0, 0, 0, 0))
        if node.symbol == "Floor":
            cv2.rectangle(out, (x0, y0), (x1 - 1, y1 - 1), (255, 40, 40), 2 * thick)
        elif node.symbol == "Tile":
            cv2.rectangle(out, (x0, y0), (x1 - 1, y1 - 1), (255, 210, 0), thick)
        elif not node.children and node.label not in ("", "wall"):
            colour = (255, 140, 0) if node.operator == INSERT else (40, 120, 255)
            cv2.rectangle(out, (x0, y0), (x1 - 1, y1 - 1), colour, thick)
    return out


def _save(rec: Reconstruction, out: Path) -> list[Path]:
    from .outdir import write_outdir

    return write_outdir(out, lambda stage: _write_files(rec, stage), rec.inputs)


def _write_gml(tree: Shape, path: Path, report: dict) -> None:
    """``rules.gml``: the shape tree as a GML program (CityFit §5: grammars written out
    automatically; :func:`facadeforge.gml.extract.tree_to_gml`).  A tree GML cannot say (a
    rotated scope) leaves a note in the report instead of failing the OUTDIR."""
    from .gml.extract import tree_to_gml

    try:
        path.write_text(tree_to_gml(tree), encoding="utf-8")
    except InputError as e:
        report.setdefault("notes", []).append(f"rules.gml not written: {e}")


def _write_files(rec: Reconstruction, stage: Path) -> None:
    """The OUTDIR files of one facade, into the folder ``stage`` (of :func:`write_outdir`)."""
    from PIL import Image

    from .exchange import export
    from .exchange.raster import write_label_png
    from .outdir import write_json

    t0 = time.perf_counter()
    # photo-sized RGB PNGs: zlib level 1 writes them ~4x faster than the
    # default 6 for 17 % more bytes (measured on a 1600x1200 synthetic facade)
    Image.fromarray(rec.rectified).save(stage / "rectified.png", compress_level=1)
    Image.fromarray(structure_image(rec)).save(stage / "structure.png", compress_level=1)
    write_label_png(rec.labels, stage / "labels.png")
    write_label_png(rec.labels_input(), stage / "labels_input.png")
    write_json(stage / "shape_tree.json", rec.tree.to_dict(), indent=1)
    _write_gml(rec.tree, stage / "rules.gml", rec.report)
    if rec.workdir is not None and rec.workdir.is_dir():   # written once, copied here
        mode = stage.stat().st_mode
        shutil.copytree(rec.workdir, stage, dirs_exist_ok=True)
        os.chmod(stage, mode)       # not the scratch folder's 0700 (a facade_NN/ folder)
    else:
        _write_workdir(rec, stage)
    if rec.model is not None:
        for suffix in ("glb", "obj", "city.json"):
            export(rec.model, stage / f"model.{suffix}")
    timings = rec.report["timings"]     # the report, written last, carries the export time
    timings["export"] = time.perf_counter() - t0
    timings.pop("total", None)                  # the total goes last again
    timings["total"] = sum(timings.values())
    write_json(stage / "report.json", rec.report)
