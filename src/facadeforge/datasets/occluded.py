"""Facades with real occluders pasted in front: the held-out data of the texture-repair benchmark.

Occluders are cut out of LabelMeFacade street photos (:func:`occluders_from_labelmefacade`): the
connected components of its ``car`` and ``vegetation`` labels, with their own pixels and an
alpha matte from the label.  :func:`paste_occluders` stands them in front of a rectified facade
the way a street does, and :func:`occluded_cmp` makes the benchmark's samples: CMP **val**
facades (:func:`~facadeforge.datasets.splits.cmp_split`) with occluders from LabelMeFacade
**test** photos, which a classifier trained on LabelMeFacade train has not seen.

Cutting (per component of a class, 8-connected):

- dropped when it touches the photo's left, right or top border (it would be visibly cut off
  in front of the facade); components touching the bottom border are kept (they stand on the
  facade's bottom edge, where the cut is hidden);
- "touching" is coming within :data:`BORDER` (2) pixels of it, as LabelMeFacade labels often
  leave the outermost pixel row unlabelled;
- dropped when smaller than ``min_area`` pixels, thinner than ``min_side`` pixels, more than
  :data:`MAX_ASPECT` times wider than tall or taller than wide (hedges, lamp-post strips),
  filling less than :data:`MIN_SOLIDITY` of their bounding box; cars also when not 1 to
  :data:`MAX_CAR_ASPECT` times wider than tall (rows of parked cars, a car mostly hidden by
  something else); vegetation also when less than :data:`MIN_FOLIAGE` of its pixels have leaf
  colours (the polygon drawn around a bare winter tree holds the sky and houses behind it) or
  when its top rows are cut straight (:data:`MAX_FLAT_TOP`: a crown hanging into the photo);
- LabelMe labels are hand-drawn polygons and run a pixel or two past the object: the alpha is
  the component eroded by 1 px (3 × 3) and feathered inwards (Gaussian σ =
  :data:`FEATHER_SIGMA` px: the outermost pixels of the eroded body are 55–80 % opaque,
  outside it alpha is 0); colours outside the eroded body are not used (the nearest body
  pixel's colour stands there).

Pasting rule (:func:`paste_occluders`), sizes relative to the facade:

- a car is :data:`SIZE_RULES` ``car`` = 20–40 % of the facade's **width** wide, its bottom on the
  facade's bottom edge;
- a tree (``vegetation``) is 25–60 % of the facade's **height** tall, its bottom on the bottom
  edge (it rises from the street);
- any other class is 15–40 % of the facade's height tall, on the bottom edge;
- an occluder is never enlarged more than :data:`MAX_UPSCALE` (3) times (a small cut-out would
  be a blur): one that would be is shrunk to that, or drawn again when that is below its
  class's smallest size;
- the horizontal place is uniform over the positions that keep the object inside the facade;
  an object is never wider than the facade;
- items are added until the mask covers a fraction drawn uniformly from ``coverage`` of the
  image (never more than its upper bound, at most ``max_items`` items); trees are drawn behind
  cars (vegetation first, then other classes, then cars, each group in placement order).

The occluded image is the alpha-composite; its mask is the composite alpha > 0.5, which is
every pixel the paste changed (the matte is feathered inwards only, and is re-made at the
pasted size, so the soft rim stays one pixel wide at any scale).  Every random
choice comes from the ``rng`` passed, so a seed gives the same images on every machine.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy import ndimage

from ..errors import InputError
from .cmp import load_cmp
from .labelmefacade import load_labelmefacade
from .labelsets import CANONICAL_INDEX, IGNORE, LABEL_SETS
from .splits import cmp_split

__all__ = ["BORDER", "DEFAULT_SIZE_RULE", "FEATHER_SIGMA", "MAX_ASPECT", "MAX_CAR_ASPECT",
           "MAX_FLAT_TOP", "MAX_UPSCALE", "MIN_FOLIAGE", "MIN_SOLIDITY", "SIZE_RULES",
           "OccludedSample", "Occluder", "cut_occluders", "occlude_facade", "occluded_cmp",
           "occluders_from_labelmefacade", "paste_occluders", "sample_rng"]

_LMF9 = LABEL_SETS["lmf9"]

#: Size of a pasted occluder: class → (dimension of the facade it is measured against, low,
#: high fraction of that dimension).  ``width`` rules set the object's width, ``height`` rules
#: its height; the other side follows the object's own aspect ratio.
SIZE_RULES: dict[str, tuple[str, float, float]] = {
    "car": ("width", 0.20, 0.40),
    "vegetation": ("height", 0.25, 0.60),
}
#: Rule of classes not in :data:`SIZE_RULES`.
DEFAULT_SIZE_RULE: tuple[str, float, float] = ("height", 0.15, 0.40)

#: Drawing order: lower first (further from the camera).
_DEPTH = {"vegetation": 0, "car": 2}

#: Components whose bounding box is more than this many times wider than tall (or taller than
#: wide) are dropped.
MAX_ASPECT: float = 5.0
#: Cars wider than this many times their height are dropped (a row of parked cars), as are
#: cars taller than wide (a car mostly hidden by something else).
MAX_CAR_ASPECT: float = 3.5
#: Vegetation components with fewer leaf-coloured pixels than this (:func:`_foliage`) are
#: dropped: LabelMe polygons around bare winter trees hold the sky and houses behind them.
MIN_FOLIAGE: float = 0.6
#: Vegetation whose top 5 % of rows span more than this fraction of its width is dropped: a
#: crown hanging into the photo from a tree outside it (its top edge cut straight).
MAX_FLAT_TOP: float = 0.6
#: A component closer than this many pixels to a border touches it (LabelMeFacade labels often
#: leave the outermost pixel row unlabelled).
BORDER: int = 2
#: Components filling less than this fraction of their bounding box are dropped.
MIN_SOLIDITY: float = 0.3
#: Feather of the alpha matte, pixels (Gaussian σ), at the source's and at the pasted size.
FEATHER_SIGMA: float = 0.7

#: Most an occluder is enlarged: candidates that the size rule would blow up more are shrunk
#: to it, and drawn again when that is below the rule's smallest size.
MAX_UPSCALE: float = 3.0

_ATTEMPTS = 24   # candidates drawn per item before taking the best one


@dataclass(frozen=True, eq=False)
class Occluder:
    """An object cut out of a photo, ready to paste.

    Parameters
    ----------
    rgba : (h, w, 4) uint8
        The object's pixels; alpha is its matte (0 outside the object).
    label : str
        LabelMeFacade class name (``"car"``, ``"vegetation"`` …).
    source : str
        Name of the photo it was cut from.
    box : (x0, y0, x1, y1)
        Where it was in the source photo (pixel edges, x1/y1 exclusive).
    """

    rgba: np.ndarray
    label: str
    source: str
    box: tuple[int, int, int, int] = (0, 0, 0, 0)

    def __post_init__(self) -> None:
        rgba = np.asarray(self.rgba)
        if rgba.ndim != 3 or rgba.shape[2] != 4 or rgba.dtype != np.uint8:
            raise InputError(f"occluder from {self.source!r}: rgba must be (h, w, 4) uint8, got "
                             f"{rgba.shape} {rgba.dtype}")

    @property
    def area(self) -> int:
        """Pixels with alpha > 0.5."""
        return int(np.count_nonzero(self.rgba[..., 3] > 127))


@dataclass(eq=False)
class OccludedSample:
    """A facade with occluders pasted in front (:func:`occluded_cmp`).

    Attributes
    ----------
    id : str
        The facade's id (``cmp_b0001``).
    clean, occluded : (H, W, 3) uint8
        The facade photo, and the same with the occluders composited.
    mask : (H, W) bool
        Composite alpha > 0.5: what a repair must fill.
    alpha : (H, W) float32
        The composite alpha (0 off the mask; 0.55–1 on it, below 1 on the objects' 1-px rim).
    labels : (H, W) uint8
        The clean facade's ``cmp12`` class-index map (255 unlabelled).
    occluder_labels : (H, W) uint8
        Canonical index (:data:`~facadeforge.datasets.labelsets.CANONICAL_INDEX`: ``car``,
        ``vegetation`` …) of the top occluder where ``mask``, 255 elsewhere.
    placed : list of dict
        One record per pasted object: ``label``, ``source``, ``box`` (x0, y0, x1, y1 in the
        facade), ``scale``, ``size_rule``.
    meta : dict
        ``coverage`` (mask fraction), ``target_coverage``, ``seed``, ``facade_split``,
        ``occluder_split``.
    """

    id: str
    clean: np.ndarray
    occluded: np.ndarray
    mask: np.ndarray
    alpha: np.ndarray
    labels: np.ndarray
    occluder_labels: np.ndarray
    placed: list[dict[str, Any]] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)


# ------------------------------------------------------------------------------------ cutting
def _feather(hard: np.ndarray) -> np.ndarray:
    """Soft alpha (0–1) of a binary matte, feathered inwards only: Gaussian σ = FEATHER_SIGMA
    on ``hard`` (its rim pixels get 0.55–0.8, the body 1), exactly 0 off it.  So every pixel a
    paste changes is in the mask (alpha > 0.5): a pixel outside it tinted by the object would
    be a halo no method given the mask can remove, and a seed that boundary-driven fills
    (Telea, biharmonic) smear into the hole."""
    g = ndimage.gaussian_filter(hard.astype(np.float32), FEATHER_SIGMA, mode="constant")
    return np.where(hard, np.maximum(g, 0.55), 0.0).astype(np.float32)


def _matte(mask: np.ndarray) -> np.ndarray:
    """Alpha in 0–1 of a binary object mask: eroded 1 px, feathered, limited to the mask."""
    eroded = ndimage.binary_erosion(mask, np.ones((3, 3), bool), border_value=0)
    return np.where(mask, _feather(eroded), 0.0).astype(np.float32)


def cut_occluders(rgb: np.ndarray, index_map: np.ndarray, *, source: str = "",
                  labels: Sequence[str] = ("car", "vegetation"), min_area: int = 1500,
                  min_side: int = 24) -> list[Occluder]:
    """Occluders of one photo and its ``lmf9`` class-index map (rules in the module docstring).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The photo.
    index_map : (H, W) uint8
        ``lmf9`` class indices.
    source : str
        Photo name, kept on each occluder.
    labels : sequence of str
        LabelMeFacade class names to cut.
    min_area, min_side : int
        Least pixels, and least width and height, of a kept component.

    Returns
    -------
    list of Occluder
        In the order of ``labels``, then raster order of the components.
    """
    names = _LMF9.dataset_names
    height, width = index_map.shape
    out = []
    for name in labels:
        if name not in names:
            raise InputError(f"unknown LabelMeFacade class {name!r}; use one of "
                             f"{', '.join(names)}")
        comp, n = ndimage.label(index_map == names.index(name), np.ones((3, 3), bool))
        for k, sl in enumerate(ndimage.find_objects(comp), 1):
            if sl is None:
                continue
            y0, y1, x0, x1 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
            if x0 < BORDER or y0 < BORDER or x1 > width - BORDER:
                continue            # cut by the left, top or right border
            h, w = y1 - y0, x1 - x0
            mask = comp[sl] == k
            area = int(mask.sum())
            if (area < min_area or min(h, w) < min_side or max(h / w, w / h) > MAX_ASPECT
                    or area < MIN_SOLIDITY * h * w):
                continue
            if name == "car" and not 1.0 <= w / h <= MAX_CAR_ASPECT:
                continue
            if name == "vegetation" and (_foliage(rgb[sl][mask]) < MIN_FOLIAGE
                                         or _flat_top(mask) > MAX_FLAT_TOP):
                continue
            alpha = _matte(mask)
            if np.count_nonzero(alpha > 0.5) < min_area // 2:
                continue
            body = ndimage.binary_erosion(mask, np.ones((3, 3), bool), border_value=0)
            patch = rgb[sl].copy()
            patch[~body] = _fill_outside(patch, body)[~body]
            rgba = np.dstack([patch, np.round(alpha * 255).astype(np.uint8)])
            out.append(Occluder(rgba=rgba, label=name, source=source, box=(x0, y0, x1, y1)))
    return out


def _foliage(pixels: np.ndarray) -> float:
    """Fraction of ``(N, 3)`` RGB pixels coloured like leaves: green (2G − R − B > 10), autumn
    yellow to red (blue the lowest channel by 25 or more), or in deep shade (max < 50)."""
    px = pixels.astype(np.int32)
    r, g, b = px[:, 0], px[:, 1], px[:, 2]
    leaf = (2 * g - r - b > 10) | (b + 25 < np.minimum(r, g)) | (px.max(axis=1) < 50)
    return float(leaf.mean()) if len(px) else 0.0


def _flat_top(mask: np.ndarray) -> float:
    """Fraction of the bounding box's width the top 5 % of its rows (at least 2) cover."""
    top = mask[:max(2, mask.shape[0] // 20)]
    return float(top.any(axis=0).mean())


def _fill_outside(patch: np.ndarray, body: np.ndarray) -> np.ndarray:
    """``patch`` with the pixels outside ``body`` set to their nearest body pixel's colour, so
    the feathered rim and any resampling never mix in the source photo's background."""
    if not body.any():
        return patch
    _, (iy, ix) = ndimage.distance_transform_edt(~body, return_indices=True)
    return patch[iy, ix]


@lru_cache(maxsize=8)
def _cached_occluders(root: str, split: str, labels: tuple[str, ...], min_area: int,
                      min_side: int) -> tuple[Occluder, ...]:
    out: list[Occluder] = []
    for sample in load_labelmefacade(root, split=split):
        out += cut_occluders(sample.image(), sample.labels(), source=sample.id, labels=labels,
                             min_area=min_area, min_side=min_side)
    return tuple(out)


def occluders_from_labelmefacade(root: str | Path, split: str = "test",
                                 labels: Iterable[str] = ("car", "vegetation"), *,
                                 min_area: int = 1500, min_side: int = 24,
                                 limit: int | None = None) -> list[Occluder]:
    """Cars, trees (any ``lmf9`` classes) cut out of a LabelMeFacade split.

    Parameters
    ----------
    root : str or Path
        LabelMeFacade folder (``images/``, ``labels/``, ``train.txt``, ``test.txt``).
    split : {"test", "train", "all"}
        Photos to cut from; the benchmark uses ``test`` (the classifier trains on ``train``).
    labels : iterable of str
        LabelMeFacade class names (``car``, ``vegetation``, ``various`` …).
    min_area : int
        Least pixels of a component (1500 ≈ 0.4 % of a 683 × 512 photo).
    min_side : int
        Least width and height of a component, pixels.
    limit : int or None
        Return only the first ``limit`` occluders (photo order, then class, then raster).

    Returns
    -------
    list of Occluder
        Sorted by source photo name; results are cached per folder and options in this process.

    Raises
    ------
    InputError
        Unreadable folder or split (see
        :func:`~facadeforge.datasets.labelmefacade.load_labelmefacade`), unknown class name.
    """
    labels = tuple(labels)
    for name in labels:
        if name not in _LMF9.dataset_names:
            raise InputError(f"unknown LabelMeFacade class {name!r}; use one of "
                             f"{', '.join(_LMF9.dataset_names)}")
    found = _cached_occluders(str(Path(root).expanduser().resolve()), split, labels,
                              int(min_area), int(min_side))
    return list(found[:limit] if limit is not None else found)


# ------------------------------------------------------------------------------------ pasting
def _size_rule(label: str) -> tuple[str, float, float]:
    return SIZE_RULES.get(label, DEFAULT_SIZE_RULE)


def _resize_occluder(occ: Occluder, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """RGB (uint8) and alpha (float32 0–1) of ``occ`` at ``scale``; the matte is re-made at the
    new size (resized alpha > 0.5, feathered) so its rim stays 1 px wide whatever the scale."""
    h, w = occ.rgba.shape[:2]
    nh, nw = max(1, round(h * scale)), max(1, round(w * scale))
    interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    rgb = cv2.resize(occ.rgba[..., :3], (nw, nh), interpolation=interp)
    a = cv2.resize(occ.rgba[..., 3].astype(np.float32) / 255.0, (nw, nh), interpolation=interp)
    return rgb.reshape(nh, nw, 3), _feather(a > 0.5)


def _candidate(occ: Occluder, facade_hw: tuple[int, int], fraction: float
               ) -> tuple[float, int, int]:
    """Scale and pasted size (h, w) of ``occ`` when its rule's dimension is ``fraction`` of the
    facade's, shrunk to fit the facade's width and height."""
    H, W = facade_hw
    h, w = occ.rgba.shape[:2]
    dim = _size_rule(occ.label)[0]
    scale = fraction * (W / w if dim == "width" else H / h)
    scale = min(scale, W / w, H / h)
    return scale, max(1, round(h * scale)), max(1, round(w * scale))


def _union(alpha_total: np.ndarray, a: np.ndarray, y0: int, x0: int) -> np.ndarray:
    out = alpha_total.copy()
    h, w = a.shape
    region = out[y0:y0 + h, x0:x0 + w]
    out[y0:y0 + h, x0:x0 + w] = 1.0 - (1.0 - region) * (1.0 - a)
    return out


def paste_occluders(rgb: np.ndarray, occluders: Sequence[Occluder], *, rng: np.random.Generator,
                    coverage: tuple[float, float] = (0.08, 0.25), max_items: int = 3
                    ) -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """Stand occluders in front of a rectified facade, as a street does (module docstring).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The facade.
    occluders : sequence of Occluder
        Pool to draw from (uniformly).
    rng : numpy.random.Generator
        Source of every random choice: the same generator state gives the same result.
    coverage : (low, high)
        Fraction of the image the mask is to cover; a target is drawn uniformly in it.  The
        upper bound is never passed; the lower one is reached unless ``max_items`` objects of
        the pool cannot cover it (the result's records say how much was covered).
    max_items : int
        Most objects pasted.

    Returns
    -------
    occluded : (H, W, 3) uint8
        The alpha-composite.
    mask : (H, W) bool
        Composite alpha > 0.5.
    placed : list of dict
        Per object, in drawing order: ``label``, ``source``, ``box`` (x0, y0, x1, y1), ``scale``,
        ``size_rule`` (dimension, fraction), ``coverage_after`` (mask fraction once placed, in
        placement order), and, on the first record, ``target_coverage``.

    Raises
    ------
    InputError
        Empty pool, a bad image or coverage.
    """
    occluded, alpha, _, placed = _paste(rgb, occluders, rng=rng, coverage=coverage,
                                        max_items=max_items)
    return occluded, alpha > 0.5, placed


def _paste(rgb: np.ndarray, occluders: Sequence[Occluder], *, rng: np.random.Generator,
           coverage: tuple[float, float], max_items: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """:func:`paste_occluders`, also returning the composite alpha and the canonical index of
    the top occluder of each pixel (255 where the alpha is ≤ 0.5)."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise InputError(f"facade must be (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
    lo, hi = map(float, coverage)
    if not 0.0 <= lo <= hi <= 1.0:
        raise InputError(f"coverage {coverage} must be (low, high) with 0 <= low <= high <= 1")
    if not occluders:
        raise InputError("no occluders to paste; cut some with occluders_from_labelmefacade")
    H, W = rgb.shape[:2]
    target = float(rng.uniform(lo, hi))
    total = np.zeros((H, W), np.float32)
    covered = 0.0
    chosen: list[tuple[Occluder, float, int, int, np.ndarray, np.ndarray, float]] = []
    for slot in range(max_items):
        last = slot == max_items - 1
        best = None
        for _ in range(_ATTEMPTS):
            occ = occluders[int(rng.integers(len(occluders)))]
            dim, f_lo, f_hi = _size_rule(occ.label)
            fraction = float(rng.uniform(f_lo, f_hi))
            scale, h, w = _candidate(occ, (H, W), fraction)
            if scale > MAX_UPSCALE:     # a small cut-out blown up to a blur: as big as it may
                fraction *= MAX_UPSCALE / scale
                if fraction < f_lo:
                    continue
                scale, h, w = _candidate(occ, (H, W), fraction)
            x0 = int(rng.integers(0, W - w + 1))
            y0 = H - h
            rgb_o, a = _resize_occluder(occ, scale)
            new_total = _union(total, a, y0, x0)
            new_cov = float(np.mean(new_total > 0.5))
            if new_cov > hi and new_cov > covered:
                # too big: shrink towards the rule's smallest size so the union lands at the
                # target (area grows with the square of the scale)
                gain = new_cov - covered
                want = max(min(target, hi) - covered, 0.0)
                fraction = max(f_lo, fraction * float(np.sqrt(want / gain)) * 0.97)
                scale, h, w = _candidate(occ, (H, W), fraction)
                x0 = min(x0, W - w)
                y0 = H - h
                rgb_o, a = _resize_occluder(occ, scale)
                new_total = _union(total, a, y0, x0)
                new_cov = float(np.mean(new_total > 0.5))
            if new_cov > hi:
                continue
            cand = (occ, scale, fraction, x0, y0, rgb_o, a, new_total, new_cov)
            good = new_cov > covered and (not last or new_cov >= lo)
            if good:
                best = cand
                break
            if best is None or new_cov > best[-1]:
                best = cand
        if best is None or best[-1] <= covered:
            break
        occ, scale, _fraction, x0, y0, rgb_o, a, total, covered = best
        chosen.append((occ, scale, x0, y0, rgb_o, a, covered))
        if covered >= target:
            break

    out = rgb.astype(np.float32)
    top = np.full((H, W), IGNORE, np.uint8)
    placed: list[dict[str, Any]] = []
    order = sorted(range(len(chosen)), key=lambda i: (_DEPTH.get(chosen[i][0].label, 1), i))
    for i in order:
        occ, scale, x0, y0, rgb_o, a, cov_after = chosen[i]
        h, w = a.shape
        region = out[y0:y0 + h, x0:x0 + w]
        region[:] = region * (1.0 - a[..., None]) + rgb_o.astype(np.float32) * a[..., None]
        top[y0:y0 + h, x0:x0 + w][a > 0.5] = CANONICAL_INDEX.get(occ.label,
                                                                  CANONICAL_INDEX["other"])
        dim = _size_rule(occ.label)[0]
        fraction = w / W if dim == "width" else h / H    # as pasted (after fitting the facade)
        placed.append({"label": occ.label, "source": occ.source,
                       "box": [int(x0), int(y0), int(x0 + w), int(y0 + h)],
                       "scale": round(float(scale), 4),
                       "size_rule": [dim, round(float(fraction), 4)],
                       "coverage_after": round(cov_after, 5)})
    if placed:
        placed[0]["target_coverage"] = round(target, 5)
    occluded = np.clip(np.round(out), 0, 255).astype(np.uint8)
    mask = total > 0.5
    top[~mask] = IGNORE
    return occluded, total, top, placed


# ----------------------------------------------------------------------------- CMP + LMF set
def sample_rng(seed: int, facade_id: str) -> np.random.Generator:
    """The generator of one facade's occluders: from the seed and the facade's id, so a sample
    does not change with ``n`` or with the other facades."""
    return np.random.default_rng([int(seed), zlib.crc32(facade_id.encode("utf-8"))])


def occlude_facade(facade_id: str, clean: np.ndarray, labels: np.ndarray,
                   occluders: Sequence[Occluder], *, seed: int = 0,
                   coverage: tuple[float, float] = (0.08, 0.25), max_items: int = 3
                   ) -> OccludedSample:
    """One :class:`OccludedSample` of a facade and a pool of occluders (``sample_rng``)."""
    rng = sample_rng(seed, facade_id)
    occluded, alpha, occ_labels, placed = _paste(clean, occluders, rng=rng, coverage=coverage,
                                                 max_items=max_items)
    mask = alpha > 0.5
    return OccludedSample(
        id=facade_id, clean=clean, occluded=occluded, mask=mask, alpha=alpha, labels=labels,
        occluder_labels=occ_labels, placed=placed,
        meta={"coverage": round(float(mask.mean()), 5),
              "target_coverage": placed[0]["target_coverage"] if placed else None,
              "seed": int(seed)})


def occluded_cmp(cmp_root: str | Path, lmf_root: str | Path, *, split: str = "val", n: int = 30,
                 seed: int = 0, occluder_split: str = "test",
                 labels: Iterable[str] = ("car", "vegetation"),
                 coverage: tuple[float, float] = (0.08, 0.25), max_items: int = 3
                 ) -> list[OccludedSample]:
    """The repair benchmark's held-out set: CMP facades with LabelMeFacade occluders in front.

    Parameters
    ----------
    cmp_root : str or Path
        CMP folder (``../shared/data/cmp``).
    lmf_root : str or Path
        LabelMeFacade folder (``../shared/data/labelmefacade``).
    split : {"val", "train", "all"}
        CMP development split of the facades (:func:`~facadeforge.datasets.splits.cmp_split`).
    n : int
        Number of facades, spread evenly over the split's sorted ids (ids at
        ``round(linspace(0, len - 1, n))``; all of them when ``n`` ≥ the split's size).
    seed : int
        Seed of the occluders: each facade's generator is ``sample_rng(seed, id)``.
    occluder_split : {"test", "train", "all"}
        LabelMeFacade split the occluders are cut from.
    labels : iterable of str
        LabelMeFacade classes to paste.
    coverage, max_items
        As :func:`paste_occluders`.

    Returns
    -------
    list of OccludedSample
        In id order; ``meta`` also says ``facade_split`` and ``occluder_split``, and each
        ``placed`` record names its LabelMeFacade source photo.
    """
    if n < 1:
        raise InputError(f"n = {n} must be at least 1")
    facades = cmp_split(load_cmp(cmp_root, label_set="cmp12"), split)
    if n < len(facades):
        picks = sorted(set(np.round(np.linspace(0, len(facades) - 1, n)).astype(int).tolist()))
        facades = [facades[i] for i in picks]
    pool = occluders_from_labelmefacade(lmf_root, split=occluder_split, labels=labels)
    if not pool:
        raise InputError(f"LabelMeFacade {occluder_split} split in {lmf_root} has no "
                         f"{'/'.join(labels)} component to cut")
    out = []
    for facade in facades:
        sample = occlude_facade(facade.id, facade.image(), facade.labels(), pool, seed=seed,
                                coverage=coverage, max_items=max_items)
        sample.meta.update(facade_split=split, occluder_split=occluder_split)
        out.append(sample)
    return out
