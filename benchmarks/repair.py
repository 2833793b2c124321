"""Facade texture repair benchmark: real cars and trees pasted onto held-out facades, removed again.

Data (:func:`facadeforge.datasets.occluded.occluded_cmp`): ``-n`` (30) CMP **val** facades, spread
evenly over the split's sorted ids, each with 1–3 cars and trees cut out of LabelMeFacade **test**
photos pasted in front as a street stands them (cars 20–40 % of the facade's width, trees 25–60 %
of its height, on the bottom edge) until they cover 8–25 % of the image; the mask is the
composite alpha > 0.5.  Occluders from LabelMeFacade test: a classifier trained on its train
photos has not seen them.  ``--seed`` fixes every placement.

Methods (:data:`METHODS`; ``name -> callable(sample) -> (repaired rgb, labels or None)``):

- ``none``: the occluded photo itself (what doing nothing scores);
- ``telea``, ``ns``: ``cv2.inpaint`` (Telea 2004 / Navier–Stokes) with the **true** mask,
  inpainting radius 5 px;
- ``biharmonic``: ``skimage.restoration.inpaint_biharmonic`` with the true mask (smooth
  interpolation, not a patch method);
- ``patchmatch-rgb``: ``patchmatch_cython.inpaint_pyramid`` (PyPI ``patchmatch-cython``, BSD:
  pyramid PatchMatch with EM voting, 5 × 5 patches, seed 0) with the true mask — run only when
  that package is installed;
- ``repair-mask``: ``facadeforge.repair.pipeline.repair_photo(occluded, mask=true mask,
  rectified=True, seed=0)``; ``repair``: the same with ``mask=None`` (it finds the occluders
  itself; the mask it found is scored by IoU, precision and recall against the true one).  Both
  are reported as missing, not run, while that module is not there;
- ``synthesis-*``: hooks for the label → image synthesis variants (:func:`synthesis_hook`), missing
  until the pipeline takes a ``synthesis=`` variant.

Scores per facade and method, on uint8 RGB against the clean facade:

- **masked PSNR**: 10 log10(255² / MSE) with the MSE over the mask's pixels (all 3 channels);
- **masked SSIM**: ``skimage.metrics.structural_similarity(clean, repaired, full=True,
  channel_axis=2, data_range=255)``, the mean of its SSIM map over the mask's pixels (and channels);
- whole-image **PSNR** and **SSIM** (the mean of the same map);
- **label accuracy** inside the mask, where a method returns labels (canonical index map): its
  labels in ``cmp12`` and in the merged ``cmp6`` against the clean facade's CMP labels, over the
  mask's labelled pixels;
- seconds per image (wall clock of the method's call, one process, nothing else timed).

Means are over the facades a method ran on.  The paper's Table 1 (Shang et al. 2023) is kept as a
separate ``paper`` block: whole-image PSNR/SSIM of label → image *synthesis* on their LSAA
facades, a different protocol (no occluders, no mask), for reference only.

Run::

    .venv/bin/python benchmarks/repair.py --cmp ../shared/data/cmp \\
        --lmf ../shared/data/labelmefacade -n 30 --methods telea,ns,biharmonic,patchmatch-rgb

Writes ``benchmarks/results/repair.json`` (per-method means, per-facade values, timings,
provenance) and the picture sheet ``docs/images/repair.jpg`` (rows: ``--sheet-rows`` facades;
columns: clean, occluded, each method run).  ``--methods all`` runs every available method.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from PIL import Image, ImageDraw
from skimage.metrics import structural_similarity

from facadeforge.datasets.labelsets import IGNORE, LABEL_SETS, convert
from facadeforge.datasets.occluded import OccludedSample, occluded_cmp
from facadeforge.evaluation.bench import provenance, save_result

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "benchmarks" / "results" / "repair.json"
SHEET = ROOT / "docs" / "images" / "repair.jpg"

#: Shang et al. 2023, Table 1: whole-image PSNR / SSIM of label → image synthesis on LSAA.
PAPER_TABLE1 = {
    "source": "Shang et al. 2023, Table 1 (arXiv:2303.17418)",
    "protocol": "whole-image PSNR/SSIM of label -> image synthesis on their LSAA facades, "
                "from each facade's own labels with its photo as style; no occluders, no mask. "
                "Not the protocol of this benchmark: for reference only.",
    "dataset": "LSAA",
    "methods": {"SPADE": {"psnr": 13.77, "ssim": 0.291},
                "SEAN": {"psnr": 16.76, "ssim": 0.489},
                "proposed": {"psnr": 17.13, "ssim": 0.502}},
}

Output = tuple  # (repaired rgb, labels or None[, extras dict with "mask", "report"])


@dataclass(frozen=True)
class Method:
    """A repair method of the benchmark.

    ``run(sample)`` returns ``(repaired (H, W, 3) uint8, labels (H, W) canonical index map or
    None)``, optionally with a third item, a dict that may hold ``mask`` (the mask the method
    found) and ``report``.  ``available()`` returns ``None`` when the method can run, else why
    it cannot.
    """

    name: str
    run: Callable[[OccludedSample], Output]
    description: str
    uses_true_mask: bool
    available: Callable[[], str | None] = lambda: None


METHODS: dict[str, Method] = {}


def register(method: Method) -> Method:
    """Add a method to :data:`METHODS` (the registry later variants join)."""
    METHODS[method.name] = method
    return method


# ------------------------------------------------------------------------------ baselines
def _mask8(sample: OccludedSample) -> np.ndarray:
    return sample.mask.astype(np.uint8) * 255


def _cv2(flag: int) -> Callable[[OccludedSample], Output]:
    def run(sample: OccludedSample) -> Output:
        return cv2.inpaint(sample.occluded, _mask8(sample), 5, flag), None
    return run


def _biharmonic(sample: OccludedSample) -> Output:
    from skimage.restoration import inpaint_biharmonic
    out = inpaint_biharmonic(sample.occluded, sample.mask, channel_axis=-1)
    return np.clip(np.round(out * 255), 0, 255).astype(np.uint8), None


def _has_module(name: str, what: str) -> Callable[[], str | None]:
    def check() -> str | None:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            return f"{what} is not installed ({exc})"
        return None
    return check


def _patchmatch(sample: OccludedSample) -> Output:
    from patchmatch_cython import inpaint_pyramid
    return inpaint_pyramid(sample.occluded, sample.mask, seed=0), None


register(Method("none", lambda s: (s.occluded, None),
                "the occluded photo, unrepaired (floor of every score)", False))
register(Method("telea", _cv2(cv2.INPAINT_TELEA),
                "cv2.inpaint INPAINT_TELEA, true mask, radius 5 px", True))
register(Method("ns", _cv2(cv2.INPAINT_NS),
                "cv2.inpaint INPAINT_NS (Navier-Stokes), true mask, radius 5 px", True))
register(Method("biharmonic", _biharmonic,
                "skimage.restoration.inpaint_biharmonic, true mask (smooth interpolation, not "
                "a patch method)", True))
register(Method("patchmatch-rgb", _patchmatch,
                "patchmatch_cython.inpaint_pyramid (PyPI patchmatch-cython, BSD), true mask, "
                "5x5 patches, seed 0, package defaults otherwise", True,
                _has_module("patchmatch_cython", "PyPI package patchmatch-cython")))


# ---------------------------------------------------------------------------- the pipeline
def _pipeline() -> Any:
    return importlib.import_module("facadeforge.repair.pipeline").repair_photo


def _pipeline_missing() -> str | None:
    try:
        _pipeline()
    except (ImportError, AttributeError) as exc:
        return f"facadeforge.repair.pipeline.repair_photo is not there yet ({exc})"
    return None


def _repair(with_mask: bool, **options: Any) -> Callable[[OccludedSample], Output]:
    def run(sample: OccludedSample) -> Output:
        res = _pipeline()(sample.occluded, mask=sample.mask if with_mask else None,
                          rectified=True, seed=0, **options)
        return (np.asarray(res.repaired), None if res.labels is None else np.asarray(res.labels),
                {"mask": None if res.mask is None else np.asarray(res.mask, bool),
                 "report": getattr(res, "report", None)})
    return run


register(Method("repair-mask", _repair(True),
                "facadeforge.repair.pipeline.repair_photo(mask=true mask, rectified=True, "
                "seed=0)", True, _pipeline_missing))
register(Method("repair-mask-texture", _repair(True, fill="texture"),
                "facadeforge.repair.pipeline.repair_photo(mask=true mask, rectified=True, "
                "fill='texture', seed=0): the texture fill alone (repetition, quilting, "
                "label-guided PatchMatch), no expected colour", True, _pipeline_missing))
register(Method("repair", _repair(False),
                "facadeforge.repair.pipeline.repair_photo(mask=None, rectified=True, seed=0): "
                "finds the occluders itself", False, _pipeline_missing))


def synthesis_hook(variant: str, description: str) -> Method:
    """A ``synthesis-VARIANT`` method: ``repair_photo(..., mask=true mask, synthesis=VARIANT)``
    (``"spade"``: no style encoder; ``"sean"``: without the detail and regularity losses).  It is
    missing until the pipeline takes the keyword; register another callable under the same name
    to measure a variant some other way."""
    def missing() -> str | None:
        why = _pipeline_missing()
        if why:
            return why
        import inspect
        params = inspect.signature(_pipeline()).parameters
        if "synthesis" not in params and not any(p.kind is p.VAR_KEYWORD
                                                 for p in params.values()):
            return "repair_photo takes no synthesis= variant yet"
        return None
    return register(Method(f"synthesis-{variant}", _repair(True, synthesis=variant), description,
                           True, missing))


synthesis_hook("spade", "repair_photo(mask=true mask, synthesis='spade'): label -> image "
                        "synthesis without the style encoder (SPADE-like)")
synthesis_hook("sean", "repair_photo(mask=true mask, synthesis='sean'): SEAN synthesis without "
                       "the detail and regularity losses")


# --------------------------------------------------------------------------------- scores
def psnr(mse: float) -> float:
    return float("inf") if mse <= 0 else float(10.0 * np.log10(255.0 ** 2 / mse))


def scores(sample: OccludedSample, repaired: np.ndarray, labels: np.ndarray | None,
           found: np.ndarray | None) -> dict[str, float | None]:
    """Masked and whole-image PSNR/SSIM, label accuracy in the mask, mask IoU (module doc)."""
    clean = sample.clean
    if repaired.shape != clean.shape or repaired.dtype != np.uint8:
        raise ValueError(f"repaired image is {repaired.shape} {repaired.dtype}, the facade "
                         f"{clean.shape} uint8")
    mask = sample.mask
    err = (repaired.astype(np.float64) - clean.astype(np.float64)) ** 2
    _, ssim_map = structural_similarity(clean, repaired, full=True, channel_axis=2,
                                        data_range=255)
    out: dict[str, float | None] = {
        "masked_psnr": psnr(float(err[mask].mean())),
        "masked_ssim": float(ssim_map[mask].mean()),
        "psnr": psnr(float(err.mean())),
        "ssim": float(ssim_map.mean()),
        "label_acc_cmp12": None, "label_acc_cmp6": None,
    }
    if labels is not None:
        pred12 = LABEL_SETS["cmp12"].from_canonical(np.asarray(labels))
        truth12 = sample.labels
        scored = mask & (truth12 != IGNORE)
        if scored.any():
            out["label_acc_cmp12"] = float(np.mean(pred12[scored] == truth12[scored]))
            out["label_acc_cmp6"] = float(np.mean(convert(pred12, "cmp12", "cmp6")[scored]
                                                  == convert(truth12, "cmp12", "cmp6")[scored]))
    if found is not None:
        inter = float(np.count_nonzero(found & mask))
        union = float(np.count_nonzero(found | mask))
        out["mask_iou"] = inter / union if union else 1.0
        out["mask_precision"] = inter / max(np.count_nonzero(found), 1)
        out["mask_recall"] = inter / max(np.count_nonzero(mask), 1)
    return out


def _round(v: Any, digits: int = 4) -> Any:
    """Rounded floats; an infinite PSNR (a perfect copy) is written as null."""
    if isinstance(v, float):
        return round(v, digits) if np.isfinite(v) else None
    return v


def _mean(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None and np.isfinite(v)]
    return round(float(np.mean(vals)), 4) if vals else None


# ---------------------------------------------------------------------------------- sheet
def write_sheet(rows: list[tuple[OccludedSample, dict[str, np.ndarray]]], path: Path,
                height: int = 200, quality: int = 80) -> None:
    """JPEG sheet: one row per facade (clean, occluded, each method), tiles ``height`` px tall
    at the facade's aspect, a caption above each; the file is kept under 400 KB."""
    if not rows:
        return
    cap, gap = 14, 4
    lines = []
    for sample, images in rows:
        named = [(f"{sample.id} clean", sample.clean), ("occluded", sample.occluded),
                 *images.items()]
        tiles = []
        for name, im in named:
            h, w = im.shape[:2]
            tw = max(1, round(w * height / h))
            tiles.append((name, Image.fromarray(im).resize((tw, height), Image.LANCZOS)))
        lines.append(tiles)
    width = max(sum(t.width for _, t in tiles) + gap * (len(tiles) - 1) for tiles in lines)
    sheet = Image.new("RGB", (width, len(lines) * (height + cap)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for r, tiles in enumerate(lines):
        x, y = 0, r * (height + cap)
        for name, tile in tiles:
            sheet.paste(tile, (x, y + cap))
            draw.text((x + 2, y + 1), name, fill=(0, 0, 0))
            x += tile.width + gap
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path, "JPEG", quality=quality, optimize=True)
    while path.stat().st_size > 400_000 and quality > 40:   # keep the repo light
        quality -= 10
        sheet.save(path, "JPEG", quality=quality, optimize=True)


# ------------------------------------------------------------------------------------ main
def _method_list(text: str) -> list[str]:
    names = list(METHODS) if text == "all" else [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise SystemExit(f"unknown method(s) {', '.join(unknown)}; use any of "
                         f"{', '.join(METHODS)} or 'all'")
    return names


def _keep_old(path: Path, methods: dict[str, Any], per_sample: list[dict[str, Any]],
              args: argparse.Namespace) -> None:
    """``--keep``: the earlier result's methods that were not run now, with when they were
    measured (only when it scored the same facades with the same placement seed)."""
    import json

    old = json.loads(path.read_text())
    same = (old.get("protocol", {}).get("seed") == args.seed
            and [r["id"] for r in old.get("per_sample", [])] == [r["id"] for r in per_sample])
    if not same:
        print(f"--keep: {path} scored other facades or another seed; nothing kept",
              file=sys.stderr)
        return
    by_id = {r["id"]: r for r in old["per_sample"]}
    for name, entry in old.get("methods", {}).items():
        if name in methods or "mean" not in entry:
            continue
        methods[name] = {**entry, "measured": entry.get("measured") or {
            "commit": old.get("commit"), "date": old.get("date")}}
        for rec in per_sample:
            if name in by_id[rec["id"]]["methods"]:
                rec["methods"][name] = by_id[rec["id"]]["methods"][name]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cmp", default=str(ROOT.parent / "shared" / "data" / "cmp"),
                    help="CMP folder")
    ap.add_argument("--lmf", default=str(ROOT.parent / "shared" / "data" / "labelmefacade"),
                    help="LabelMeFacade folder")
    ap.add_argument("-n", type=int, default=30, help="number of CMP val facades")
    ap.add_argument("--seed", type=int, default=0, help="seed of the occluder placement")
    ap.add_argument("--methods", default="none,telea,ns,biharmonic,patchmatch-rgb,repair-mask,"
                                         "repair",
                    help=f"comma-separated, or 'all' ({', '.join(METHODS)})")
    ap.add_argument("--sheet-rows", type=int, default=4, help="facades on the picture sheet")
    ap.add_argument("-o", "--output", default=str(OUTPUT))
    ap.add_argument("--sheet", default=str(SHEET))
    ap.add_argument("--keep", action="store_true",
                    help="keep the methods of the existing result that this run does not run "
                         "(same -n and --seed), each with the commit and date it was measured "
                         "at; the slow peers need not be rerun after a change of ours")
    args = ap.parse_args(argv)

    names = _method_list(args.methods)
    missing = {n: why for n in names if (why := METHODS[n].available())}
    running = [n for n in names if n not in missing]
    for n, why in missing.items():
        print(f"method {n}: missing, not run: {why}", file=sys.stderr)

    t0 = time.perf_counter()
    samples = occluded_cmp(args.cmp, args.lmf, split="val", n=args.n, seed=args.seed,
                           occluder_split="test")
    data_seconds = time.perf_counter() - t0
    sheet_ids = {s.id for s in samples[::max(1, len(samples) // max(args.sheet_rows, 1))]
                 [:args.sheet_rows]}
    per_sample: list[dict[str, Any]] = []
    sheet_rows: list[tuple[OccludedSample, dict[str, np.ndarray]]] = []
    errors: dict[str, list[str]] = {}
    for i, sample in enumerate(samples):
        record: dict[str, Any] = {
            "id": sample.id, "size": list(sample.clean.shape[:2]),
            "coverage": sample.meta["coverage"],
            "occluders": [{"label": p["label"], "source": p["source"], "box": p["box"]}
                          for p in sample.placed],
            "methods": {}}
        images: dict[str, np.ndarray] = {}
        for name in running:
            t = time.perf_counter()
            try:
                out = METHODS[name].run(sample)
            except Exception as exc:  # a method's failure is a result, not a crash
                errors.setdefault(name, []).append(f"{sample.id}: {type(exc).__name__}: {exc}")
                print(f"[{i + 1}/{len(samples)}] {sample.id} {name}: FAILED {exc}",
                      file=sys.stderr)
                continue
            seconds = time.perf_counter() - t
            repaired, labels = np.asarray(out[0]), out[1]
            extras = out[2] if len(out) > 2 else {}
            s = scores(sample, repaired, labels, extras.get("mask"))
            s["seconds"] = seconds
            record["methods"][name] = {k: _round(v) for k, v in s.items()}
            if sample.id in sheet_ids and name != "none":   # "occluded" shows it already
                images[name] = repaired
            print(f"[{i + 1}/{len(samples)}] {sample.id} {name}: masked PSNR "
                  f"{s['masked_psnr']:.2f} SSIM {s['masked_ssim']:.3f}, whole {s['psnr']:.2f} / "
                  f"{s['ssim']:.3f}, {seconds:.1f} s", file=sys.stderr, flush=True)
        per_sample.append(record)
        if sample.id in sheet_ids:
            sheet_rows.append((sample, images))

    keys = ("masked_psnr", "masked_ssim", "psnr", "ssim", "label_acc_cmp12", "label_acc_cmp6",
            "mask_iou", "mask_precision", "mask_recall", "seconds")
    methods: dict[str, Any] = {}
    for name in names:
        m = METHODS[name]
        entry: dict[str, Any] = {"description": m.description, "uses_true_mask": m.uses_true_mask}
        if name in missing:
            entry["missing"] = missing[name]
        else:
            runs = [r["methods"][name] for r in per_sample if name in r["methods"]]
            entry["n"] = len(runs)
            entry["mean"] = {k: _mean([r.get(k) for r in runs]) for k in keys
                             if any(r.get(k) is not None for r in runs)}
            if name in errors:
                entry["errors"] = errors[name]
        methods[name] = entry

    if args.keep and Path(args.output).is_file():
        _keep_old(Path(args.output), methods, per_sample, args)

    result = {
        "benchmark": "repair",
        "protocol": {
            "facades": f"CMP val (cmp_split), {len(samples)} of 60 spread over the sorted ids",
            "occluders": "LabelMeFacade test split: car and vegetation components "
                         "(facadeforge.datasets.occluded)",
            "placement": "cars 20-40 % of facade width, trees 25-60 % of its height, bottom "
                         "edge; 8-25 % of the image covered; at most 3 objects; mask = alpha > "
                         "0.5",
            "seed": args.seed,
            "metrics": "masked PSNR over mask pixels; masked SSIM = mean of the SSIM map "
                       "(skimage, full=True, channel_axis=2, data_range=255) over the mask; "
                       "whole-image PSNR / SSIM; label accuracy inside the mask (cmp12, "
                       "cmp6) where a method returns labels; mask IoU / precision / recall "
                       "where it finds its own mask",
            "timing": "seconds per image, wall clock of the method's call, one process",
            "mean_coverage": _mean([r["coverage"] for r in per_sample]),
            "data_seconds": round(data_seconds, 2),
        },
        "methods": methods,
        "paper": PAPER_TABLE1,
        "per_sample": per_sample,
        "sheet": str(Path(args.sheet).resolve().relative_to(ROOT))
        if Path(args.sheet).resolve().is_relative_to(ROOT) else args.sheet,
        **provenance(),
    }
    write_sheet(sheet_rows, Path(args.sheet))
    save_result(result, args.output)
    for name, entry in methods.items():
        mean = entry.get("mean")
        if mean:
            print(f"{name:16s} masked PSNR {mean['masked_psnr']:6.2f}  SSIM "
                  f"{mean['masked_ssim']:.3f}   whole PSNR {mean['psnr']:6.2f}  SSIM "
                  f"{mean['ssim']:.3f}   {mean['seconds']:.2f} s/image", file=sys.stderr)
        else:
            print(f"{name:16s} {entry.get('missing', 'no run')}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
