"""``repair_photo``: a facade photo with what stands in front of it removed (seed ``shang2023``).

Stages, each on arrays (ARCHITECTURE.md: repair never imports the engine):

1. ``frame`` — the photo as given (``rectified``) or rectified here (Müller App. A); the
   repair runs on the fronto-parallel facade, where repetition is horizontal and vertical
   (Shang §3.2's direction prior assumes "corrected orthophotos"), and is mapped back.
2. ``labels`` — the facade's labels: given (``labels``), or the shipped facade classifier's.
3. ``mask`` — what to repair: given (``mask``), or the occluder pixels of the given labels, or
   found: the occluder classifier's vegetation / car / person probability, raised where an
   element breaks its cluster's repetition (:func:`~.masks.repetition_breaks`), cleaned and
   grown (:func:`~.masks.clean_mask`).
4. ``complete`` — the labels under the mask: the facade grid first (a hidden window of a
   row and column of windows, :func:`~.structure.complete_labels_structure`), the rest by
   direction-guided PatchMatch on the label map (§3.2, :func:`~.patchmatch.complete_labels`).
5. ``fill`` — a texture by region: an element of a cluster from its unoccluded instances
   (:func:`~.repetition.repetition_fill`); wall by image quilting from the visible wall
   (§3.4, :func:`~.quilt.quilt`); everything else by label-guided PatchMatch
   (:func:`~.patchmatch.fill_guided`).  ``report["filled"]`` counts the pixels of each.
   With ``fill="expected"`` (the default) the hole gets the expected colour
   (:func:`~.smooth.expected_fill`: normalised convolution and the facade's periods) plus
   :data:`DETAIL` of that texture's fine detail (its difference from a σ = 3 px blur); with
   ``fill="texture"`` the texture as it is.  A texture paints *a* plausible facade; where
   the hidden facade is not predictable its details fall in the wrong place, which is why
   the blend is the default (``repair-mask`` against ``repair-mask-texture`` in
   ``benchmarks/results/repair.json``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..model.labels import Labels
from .masks import (
    OCCLUDERS,
    clean_mask,
    mask_from_labels,
    occluder_probability,
    read_mask,
    repetition_breaks,
)

__all__ = ["DETAIL", "ELEMENTS", "FILLS", "FILL_METHODS", "Repair", "repair_photo"]

_INDEX = {label.value: i for i, label in enumerate(Labels)}
#: Canonical labels of elements that repeat (filled from their siblings when one is hidden).
ELEMENTS: tuple[str, ...] = ("window", "door", "balcony", "shop", "blind")
#: How a pixel was filled, in ``Repair.methods`` (0 = not repaired).
FILL_METHODS: tuple[str, ...] = ("repetition", "quilting", "patchmatch")
#: Occluder probability above which a pixel is occluded; lowered to ``_WEAK`` where the pixel
#: also breaks its cluster's repetition.
_STRONG, _WEAK = 0.5, 0.25
#: Least visible wall (pixels) to quilt from; smaller walls are filled by PatchMatch.
_QUILT_SOURCE = 48 * 48
#: ``fill="expected"``: the share of the texture's fine detail added to the expected colour
#: (chosen on CMP train facades, ``docs/design-measurements.md``: a little detail costs little
#: masked PSNR and keeps the repaired wall from looking smeared).
DETAIL: float = 0.3
FILLS: tuple[str, ...] = ("expected", "texture")
#: Longest side the fill runs at (:func:`_fill_scaled`).
FILL_SIDE: int = 800


@dataclass
class Repair:
    """What :func:`repair_photo` made, in the input photo's own size and frame.

    ``repaired`` (H, W, 3) uint8; ``mask`` (H, W) bool, the pixels repaired; ``labels`` (H, W)
    canonical label indices (``facadeforge.exchange.raster.LABEL_INDEX``) with the masked
    pixels completed; ``methods`` (H, W) uint8: 0 untouched, ``1 + FILL_METHODS.index(m)``
    where method ``m`` filled it; ``report`` what was found and done, JSON-ready.
    """

    photo: np.ndarray
    repaired: np.ndarray
    mask: np.ndarray
    labels: np.ndarray
    methods: np.ndarray
    report: dict[str, Any] = field(default_factory=dict)
    inputs: dict[str, Any] = field(default_factory=dict, repr=False)

    def save(self, out_dir: str | os.PathLike) -> list[Path]:
        """Write ``repaired.png``, ``mask.png``, ``labels_completed.png`` and ``report.json``
        into ``out_dir``, atomically (one staging folder, swapped in whole)."""
        from PIL import Image

        from ..exchange.raster import write_label_png
        from ..outdir import write_json, write_outdir

        def write(stage: Path) -> None:
            Image.fromarray(self.repaired).save(stage / "repaired.png", compress_level=1)
            Image.fromarray(self.mask.astype(np.uint8) * 255).save(stage / "mask.png")
            write_label_png(self.labels, stage / "labels_completed.png")
            write_json(stage / "report.json", self.report)

        return write_outdir(Path(out_dir), write, self.inputs)


def _canonical_labels(labels, shape: tuple[int, int]) -> np.ndarray:
    arr = np.asarray(labels)
    if arr.dtype == object or arr.ndim != 2 or arr.dtype.kind not in "iub":
        raise InputError(f"labels: expected an (H, W) integer map of canonical label indices, "
                         f"got {arr.dtype} of shape {arr.shape}; read a label PNG with its label "
                         "set first (facadeforge repair --labels PNG --label-set NAME)")
    if arr.shape != tuple(shape):
        raise InputError(f"labels are {arr.shape[1]}x{arr.shape[0]} px but the photo is "
                         f"{shape[1]}x{shape[0]}; give the label map of this photo")
    if arr.size and (arr.min() < 0 or arr.max() >= len(_INDEX)):
        raise InputError(f"labels hold values outside 0..{len(_INDEX) - 1} (canonical label "
                         "indices); convert them with their label set first")
    return arr.astype(np.int64)


def _classify(rgb: np.ndarray, classifier, label_set: str) -> tuple[np.ndarray, np.ndarray,
                                                                    tuple[str, ...]]:
    """Canonical label map, probabilities and their class names from a classifier."""
    from ..classify import resolve_classifier

    clf = resolve_classifier(classifier, label_set)
    prob = clf.predict_proba(rgb)
    lut = np.array([_INDEX.get(c, _INDEX["other"]) for c in clf.classes], np.int64)
    return lut[prob.argmax(axis=2)], prob, tuple(clf.classes)


def _groups_from_labels(labels: np.ndarray, hole: np.ndarray):
    from .structure import element_groups

    classes = [_INDEX[c] for c in ELEMENTS]
    return element_groups(labels, classes, hole=hole)


def _complete(labels: np.ndarray, hole: np.ndarray, completion: str, seed: int
              ) -> tuple[np.ndarray, dict[str, int]]:
    """Stage ``complete``: the structure's guess first, PatchMatch for the rest."""
    out = labels.copy()
    counts = {"structure": 0, "patchmatch": 0}
    rest = hole.copy()
    if completion in ("auto", "structure"):
        from .structure import complete_labels_structure

        out, decided = complete_labels_structure(
            out, hole, element_classes=[_INDEX[c] for c in ELEMENTS], wall=_INDEX["wall"])
        decided &= hole
        counts["structure"] = int(decided.sum())
        rest &= ~decided
    if rest.any() and (~hole).any():
        from .patchmatch import complete_labels

        # the structure's pixels are known now: PatchMatch completes around them
        out = complete_labels(out, rest, seed=seed)
        counts["patchmatch"] = int(rest.sum())
    return out, counts


def _fill(rgb: np.ndarray, hole: np.ndarray, labels: np.ndarray, groups, wall: str, seed: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """Stage ``fill``: returns the repaired image and the method map (``FILL_METHODS``)."""
    out = rgb.copy()
    methods = np.zeros(hole.shape, np.uint8)
    todo = hole.copy()
    if groups:
        from .repetition import repetition_fill

        out, got = repetition_fill(out, todo, groups)
        got &= todo
        methods[got] = 1 + FILL_METHODS.index("repetition")
        todo &= ~got
    wall_i = _INDEX["wall"]
    wall_todo = todo & (labels == wall_i)
    source = ~hole & (labels == wall_i)
    if wall == "quilt" and wall_todo.any() and source.sum() >= _QUILT_SOURCE:
        from .quilt import quilt

        # blocks agree with what is known or filled already, never with occluder pixels
        out = quilt(out, wall_todo, source, seed=seed, known=~todo)
        methods[wall_todo] = 1 + FILL_METHODS.index("quilting")
        todo &= ~wall_todo
    if todo.any():
        from .patchmatch import fill_guided

        out = fill_guided(out, todo, labels, seed=seed)
        methods[todo] = 1 + FILL_METHODS.index("patchmatch")
    return out, methods


def _fill_scaled(rgb: np.ndarray, hole: np.ndarray, labels: np.ndarray, groups, wall: str,
                 fill: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Stage ``fill`` at most :data:`FILL_SIDE` pixels on the long side: a larger facade is
    filled on a downscaled copy and the fill upsampled into its hole (the expected colour is
    smooth, and a texture fill's detail is mostly what costs accuracy), so a 1600 px facade
    costs what an 800 px one does; pixels outside the hole keep their full resolution."""
    import cv2

    h, w = hole.shape
    f = min(1.0, FILL_SIDE / max(h, w))
    if f < 1.0:
        sw, sh = max(1, round(w * f)), max(1, round(h * f))
        small = cv2.resize(rgb, (sw, sh), interpolation=cv2.INTER_AREA)
        shole = cv2.resize(hole.astype(np.uint8), (sw, sh), interpolation=cv2.INTER_AREA) > 0
        slab = cv2.resize(labels.astype(np.uint8), (sw, sh), interpolation=cv2.INTER_NEAREST)
        sgroups = [[(int(x0 * f), int(y0 * f), max(int(x0 * f) + 1, int(round(x1 * f))),
                     max(int(y0 * f) + 1, int(round(y1 * f)))) for x0, y0, x1, y1 in g]
                   for g in (groups or [])]
    else:
        small, shole, slab, sgroups = rgb, hole, labels.astype(np.int64), groups
    if not shole.any() or shole.all():
        return rgb.copy(), np.zeros(hole.shape, np.uint8)
    fixed, methods = _fill(small, shole, slab.astype(np.int64), sgroups, wall, seed)
    if fill == "expected":
        fixed = _expected(small, shole, fixed)
    if f < 1.0:
        up = cv2.resize(fixed, (w, h), interpolation=cv2.INTER_LINEAR)
        fixed = rgb.copy()
        fixed[hole] = up[hole]
        methods = cv2.resize(methods, (w, h), interpolation=cv2.INTER_NEAREST)
        methods[~hole] = 0
        # a hole pixel the small copy did not see (a sliver under the area filter) gets the
        # expected colour at full size
        missed = hole & (methods == 0)
        if missed.any():
            from .smooth import normalized_fill

            fixed[missed] = np.clip(normalized_fill(fixed, missed)[missed], 0, 255)
            methods[missed] = 1 + FILL_METHODS.index("patchmatch")
    return fixed, methods


def _expected(rgb: np.ndarray, hole: np.ndarray, texture: np.ndarray) -> np.ndarray:
    """The expected colour of the hole plus :data:`DETAIL` of ``texture``'s fine detail."""
    import cv2

    from .smooth import expected_fill

    tex = texture.astype(np.float32)
    detail = tex - cv2.GaussianBlur(tex, (0, 0), 3)
    out = rgb.copy()
    out[hole] = np.clip(expected_fill(rgb, hole)[hole] + DETAIL * detail[hole], 0,
                        255).astype(np.uint8)
    return out


def repair_photo(photo, *, mask=None, labels=None, rectified: bool = True, classifier=None,
                 occluder_classifier=None,
                 groups: Sequence[Sequence[tuple[int, int, int, int]]] | None = None,
                 completion: str = "auto", wall: str = "quilt", fill: str = "expected",
                 seed: int = 0,
                 out_dir: str | os.PathLike | None = None) -> Repair:
    """Remove occluders (trees, cars, people) from a facade photo.

    Parameters
    ----------
    photo : path or (H, W, 3) array
    mask : path or (H, W) array, optional
        What to repair (non-zero = occluded).  Default: found (stage ``mask``).
    labels : (H, W) int array, optional
        Canonical label indices of the photo (the truth, or a user's drawing); their occluder
        pixels are the mask when no mask is given.  Default: the facade classifier's.
    rectified : bool
        The photo is a fronto-parallel facade; otherwise it is rectified here, repaired on the
        facade and mapped back (pixels outside the rectified facade are never changed).
    classifier, occluder_classifier : model, path or None
        The facade classifier (default the shipped ``cmp12`` model) and the one that finds
        occluders (default the shipped ``lmf9`` model, trained on LabelMeFacade street photos).
    groups : boxes ``(x0, y0, x1, y1)`` of the instances of each repeated element, in the
        repair frame (a shape tree's clusters, as ``reconstruct`` has them); default from the
        completed labels.
    completion : "auto" (structure, then PatchMatch) or "patchmatch" (§3.2 alone)
    wall : "quilt" (§3.4 on wall regions) or "patchmatch"
    fill : "expected" (the expected colour with some of the texture's detail, the default) or
        "texture" (the texture fill as it is; module docstring, stage ``fill``)
    out_dir : write the results there (:meth:`Repair.save`)

    Returns
    -------
    Repair
    """
    from ..photo import analysis_copy, as_rgb, check_size

    if completion not in ("auto", "structure", "patchmatch"):
        raise InputError(f"completion {completion!r}: use 'auto' or 'patchmatch'")
    if wall not in ("quilt", "patchmatch"):
        raise InputError(f"wall {wall!r}: use 'quilt' or 'patchmatch'")
    if fill not in FILLS:
        raise InputError(f"fill {fill!r}: use {' or '.join(FILLS)}")
    timings: dict[str, float] = {}
    t = time.perf_counter()
    inputs = {"photo": photo, "--mask": mask, "--classifier": classifier}
    if out_dir is not None:
        from ..outdir import check_outdir

        check_outdir(out_dir, inputs)
    rgb, name = as_rgb(photo)
    check_size(rgb, name)
    shape = rgb.shape[:2]
    user_mask = None if mask is None else read_mask(mask, shape)
    user_labels = None if labels is None else _canonical_labels(labels, shape)
    timings["load"] = time.perf_counter() - t

    # stage frame: the analysis copy, rectified unless given rectified
    t = time.perf_counter()
    work, to_work = analysis_copy(rgb)
    H = to_work
    rect_info: dict[str, Any] = {"applied": False}
    if not rectified:
        from ..imaging.rectify import rectify

        r = rectify(work, rng=seed)
        rect_info = {"applied": True, "ok": bool(r), "confidence": round(float(r.confidence), 4),
                     "reason": r.reason}
        if r:
            work, H = r.image, r.homography @ to_work
    from ..frames import warp

    fshape = work.shape[:2]
    same = np.allclose(H, np.eye(3))
    covered = np.ones(fshape, bool) if same else warp(
        np.ones(shape, np.uint8), H, fshape, nearest=True).astype(bool)

    def to_frame(a: np.ndarray) -> np.ndarray:
        return a if same else warp(a, H, fshape, nearest=True)

    timings["frame"] = time.perf_counter() - t

    # stage labels
    t = time.perf_counter()
    from ..classify import default_label_set

    if user_labels is not None:
        lab = to_frame(user_labels.astype(np.uint8)).astype(np.int64)
        label_source = "given"
    else:
        lab, _, _ = _classify(work, classifier, default_label_set(True, elements=True))
        label_source = "classifier"
    timings["labels"] = time.perf_counter() - t

    # stage mask
    t = time.perf_counter()
    occ_ids = [_INDEX[c] for c in OCCLUDERS]
    if user_mask is not None:
        hole = to_frame(user_mask.astype(np.uint8)).astype(bool)
        mask_source = "given"
    elif user_labels is not None and mask_from_labels(user_labels, occ_ids).any():
        hole = mask_from_labels(lab, occ_ids)
        mask_source = "labels"
    else:
        _, oprob, oclasses = _classify(work, occluder_classifier, "lmf9")
        p = occluder_probability(oprob, oclasses)
        breaks = repetition_breaks(work, groups if groups is not None
                                   else _groups_from_labels(lab, p > _STRONG))
        hole = clean_mask((p > _STRONG) | ((p > _WEAK) & breaks))
        mask_source = "classifier"
    hole &= covered
    timings["mask"] = time.perf_counter() - t

    # stage complete
    t = time.perf_counter()
    occluder_lab = np.isin(lab, occ_ids) & ~hole     # occluder labels outside the mask: keep
    completed, ccounts = _complete(lab, hole, completion, seed) if hole.any() and (
        ~hole).any() else (lab, {"structure": 0, "patchmatch": 0})
    timings["complete"] = time.perf_counter() - t

    # stage fill
    t = time.perf_counter()
    if hole.any() and (~hole).any():
        grp = groups if groups is not None else _groups_from_labels(completed, hole)
        fixed, methods_f = _fill_scaled(work, hole, completed, grp, wall, fill, seed)
    else:
        fixed, methods_f = work.copy(), np.zeros(fshape, np.uint8)
    timings["fill"] = time.perf_counter() - t

    # back to the photo's frame: only masked pixels change
    t = time.perf_counter()
    if same:
        repaired, methods, labels_out, mask_out = fixed, methods_f, completed, hole
    else:
        inv = np.linalg.inv(H)
        mask_out = warp(hole.astype(np.uint8), inv, shape, nearest=True).astype(bool)
        back = warp(fixed, inv, shape)
        repaired = rgb.copy()
        repaired[mask_out] = back[mask_out]
        methods = warp(methods_f, inv, shape, nearest=True)
        methods[~mask_out] = 0
        labels_out = user_labels.copy() if user_labels is not None else warp(
            completed.astype(np.uint8), inv, shape, nearest=True).astype(np.int64)
        labels_out[mask_out] = warp(completed.astype(np.uint8), inv, shape,
                                    nearest=True)[mask_out]
    timings["map_back"] = time.perf_counter() - t
    timings["total"] = sum(timings.values())
    report = {
        "input": {"photo": name, "width_px": int(shape[1]), "height_px": int(shape[0])},
        "rectification": rect_info,
        "labels": label_source,
        "mask": {"source": mask_source, "pixels": int(mask_out.sum()),
                 "fraction": round(float(mask_out.mean()), 5)},
        "fill": fill,
        "completed": ccounts,
        "occluder_labels_kept": int(occluder_lab.sum()),
        "filled": {m: int((methods == i + 1).sum()) for i, m in enumerate(FILL_METHODS)},
        "timings": {k: round(v, 4) for k, v in timings.items()},
    }
    rep = Repair(photo=rgb, repaired=repaired, mask=mask_out,
                 labels=labels_out.astype(np.uint8), methods=methods, report=report,
                 inputs=inputs)
    if out_dir is not None:
        rep.save(out_dir)
    return rep
