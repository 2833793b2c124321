"""Benchmark harness: ``facadeforge bench`` scores a registered method on a facade dataset.

:func:`run_bench` loads a dataset folder with the loader registered in
:data:`facadeforge.datasets.LOADERS`, picks the facades of a split, fits the method on the
development ``train`` split when it learns from data, runs it on every facade and scores it in the
dataset's own pixel frame.  It writes three files:

- ``RESULT.json`` — every number (keys below), the machine, date, commit and data path;
- ``RESULT.md`` — headline numbers, a per-class table and the row-normalised confusion matrix;
- ``RESULT_sheet.png`` — photo | truth | prediction | error of the 3 best and 3 worst facades by
  per-image mIoU.

Splits
    ``train``, ``val`` and ``all`` follow the fixed development splits of
    :mod:`facadeforge.datasets.splits` (CMP and folders: every 5th sorted id is ``val``;
    RueMonge: by building, from the photos' cameras).  A folder holding none of the development
    val ids is held-out data, scored whole by ``--split val``.  RueMonge: when
    ``DIR/val/img`` exists, ``--split val`` scores all of ``DIR/val`` and fits on all of
    ``DIR/train``; otherwise it scores the development ``val`` part of ``DIR/train`` and fits on
    its ``train`` part.  A split folder given directly (``--data DIR/val --split val``) is scored
    whole; other split names (``test``) score the whole ``DIR/<split>`` folder.  LabelMeFacade
    has its own split files and no ``val``: ``test`` scores the photos of ``DIR/test.txt``,
    ``train`` those of ``DIR/train.txt``, ``all`` every labelled photo of ``DIR/images``.  The
    method is always fitted on the ``train`` split, also when that split (or ``all``) is the one
    scored.
Scoring
    A prediction with a homography is warped into the photo's frame by inverse mapping, nearest
    neighbour at pixel centres; photo pixels the prediction does not cover — and pixels the
    method labels :data:`~facadeforge.datasets.IGNORE` — are *unpredicted*: they count as wrong
    wherever the truth is labelled (a method cannot raise its score by abstaining).  Truth pixels
    labelled :data:`~facadeforge.datasets.IGNORE` are not scored (colour-coded truth in no class's
    colour among them: ``unknown_color_pixels`` counts those of LabelMeFacade).  Scores pool
    pixels over the data set (see :mod:`facadeforge.evaluation.metrics`).  ``confusion`` counts
    predicted classes only; ``unpredicted`` counts the rest of each truth row, and
    ``confusion_percent`` rows are percent of the row's scored pixels, so a row adds up to 100
    minus its unpredicted share.
Windows
    Truth: the sample's object boxes labelled ``window`` (CMP XML rectangles; connected components
    of the label map elsewhere).  Prediction: ``Prediction.windows`` mapped through the homography
    (bounding box of the four mapped corners), or, when the method gives none, the connected
    components of the predicted window class (``windows_from`` counts both).  Matches need
    IoU >= 0.5.
Counts
    ``floor_count_*`` / ``column_count_*`` appear when both the method (``Prediction.floors``)
    and the truth (``sample.meta["floors"]``, ``["columns"]``) give them on some facade.
Cost
    ``seconds_per_image`` is the wall time of the method's ``predict`` call, photo reading
    included, measured untraced (``tracemalloc`` slows pure-Python methods such as grammar
    search about threefold); ``peak_memory_mb`` is the process's peak resident set size
    (``ru_maxrss``) after the calls, the whole process's footprint; fitting is reported as
    ``fit_seconds``.  A method that reconstructs the photos together (``prepare``, e.g.
    ``multiview``) has that time spread evenly over its photos' ``seconds_per_image``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from .. import datasets
from ..datasets import (
    CMP_VAL_IDS,
    IGNORE,
    LABELMEFACADE_SPLITS,
    RUEMONGE_VAL_IDS,
    SPLIT_NAMES,
    FacadeSample,
    LabelSet,
    dev_split,
    get_label_set,
    ruemonge_split,
)
from ..datasets.folder import objects_from_labels
from ..errors import InputError
from ..frames import box_to_image, warp_to_image
from .methods import METHODS, Method, Prediction, get_method
from .metrics import (
    DetectionAccumulator,
    SegmentationScores,
    StructureCountAccumulator,
    confusion_matrix,
    measure,
)
from .sheet import SheetRow, write_sheet

__all__ = ["EXAMPLES", "RESULT_KEYS", "add_parser", "box_to_image", "check_output", "cmd_bench",
           "markdown_summary", "output_paths", "run_bench", "select_samples", "warp_to_image"]

#: Keys every RESULT.json has (``floor_count_*`` / ``column_count_*`` only when available).
RESULT_KEYS: tuple[str, ...] = (
    "method", "dataset", "split", "label_set", "classes", "canonical_classes", "n_images",
    "pixel_accuracy",
    "class_avg_accuracy", "miou", "per_class", "confusion", "confusion_percent", "unpredicted",
    "unpredicted_fraction", "window_precision", "window_recall", "window_f1", "window_tp",
    "window_fp", "window_fn", "windows_from", "seconds_per_image", "peak_memory_mb",
    "fit_images", "fit_seconds", "wall_seconds", "per_image", "best", "worst", "split_rule",
    "machine", "date", "commit", "data", "files",
)

EXAMPLES = """examples:
  facadeforge bench --method rowcol-prior --dataset cmp --data ../shared/data/cmp -o bench.json
  facadeforge bench --method prior --dataset ruemonge --data ../shared/data/ruemonge --split val --labels ecp7 -o prior_rm.json
  facadeforge bench --method rowcol-prior --dataset cmp --data held-out/cmp --split all --limit 20 -o out/result.json
  facadeforge bench --method prior --dataset labelmefacade --data ../shared/data/labelmefacade --split test -o prior_lmf.json
writes RESULT.json, RESULT.md (summary, per-class table, confusion) and RESULT_sheet.png
(photo | truth | prediction | error of the 3 best and 3 worst facades)."""

_BEST = 3
_UMASK = os.umask(0)
os.umask(_UMASK)  # read once: the mode of written files follows the umask


# ---------------------------------------------------------------------------------- samples
def select_samples(dataset: str, data: str | Path, split: str = "val",
                   labels: str | LabelSet | None = None
                   ) -> tuple[list[FacadeSample], list[FacadeSample], str]:
    """The facades to score and the facades to fit on (module docstring, *Splits*).

    Parameters
    ----------
    dataset : str
        Layout name in :data:`facadeforge.datasets.LOADERS` (looked up at call time, so layouts
        registered later plug in).
    data : str or Path
        Dataset folder.
    split : str
        ``train``, ``val``, ``all``, or (RueMonge) the name of a split folder; LabelMeFacade:
        ``train``, ``test``, ``all``.
    labels : str or LabelSet, optional
        Label set to score in; default the layout's own (``cmp6``, ``ecp7``, the palette).

    Returns
    -------
    scored : list of FacadeSample
    fit : list of FacadeSample
        Training facades (may be empty).
    rule : str
        One sentence saying how both were chosen.

    Raises
    ------
    InputError
        Unknown layout, label set or split; loader errors.
    """
    loaders = datasets.LOADERS
    if dataset not in loaders:
        raise InputError(f"unknown dataset {dataset!r}; use one of {', '.join(loaders)}")
    options: dict[str, Any] = {}
    if labels is not None:
        options["label_set"] = get_label_set(labels)
    load = loaders[dataset]
    data = Path(data).expanduser()
    if dataset == "ruemonge":
        return _ruemonge_samples(load, data, split, options)
    if dataset == "labelmefacade":
        return _labelmefacade_samples(load, data, split, options)
    if split not in SPLIT_NAMES:
        raise InputError(f"unknown split {split!r} for dataset {dataset!r}; use one of "
                         f"{', '.join(SPLIT_NAMES)}")
    everything = load(data, **options)
    if split == "val" and dataset == "cmp" and not _has_dev_ids(everything, CMP_VAL_IDS):
        return everything, [], (f"all {len(everything)} facades of {data}: a held-out folder (none "
                                "of the development val ids), scored whole; no training set")
    scored = dev_split(everything, split)
    fit = dev_split(everything, "train")
    rule = (f"development split {split!r} (every 5th sorted id is val) of the {len(everything)} "
            f"facades in {data}; fitted on its train part ({len(fit)})")
    return scored, fit, rule


def _has_dev_ids(samples, dev_ids) -> bool:
    """Whether a folder holds (some of) the shared development data rather than held-out data."""
    ids = {s.id for s in samples}
    return bool(ids & set(dev_ids))


def _ruemonge_samples(load, data: Path, split: str, options: dict[str, Any]):
    def folder(name: str) -> bool:
        return (data / name / "img").is_dir()

    if (data / "img").is_dir() and data.name == split:
        scored = load(data, split=split, **options)
        return scored, [], f"all {len(scored)} photos of the split folder {data}; no training set"
    dedicated = split not in SPLIT_NAMES or (split == "val" and folder("val"))
    if dedicated or (split in ("train", "all") and folder("val")):
        if split == "all":
            scored = load(data, split="train", **options) + load(data, split="val", **options)
        else:
            scored = load(data, split=split, **options)
        fit = load(data, split="train", **options) if folder("train") else []
        return scored, fit, (f"all {len(scored)} photos of {data}/{split if split != 'all' else '{train,val}'}; "
                             f"fitted on all {len(fit)} photos of {data}/train")
    base = load(data, split="train", **options)
    if split == "val" and not _has_dev_ids(base, RUEMONGE_VAL_IDS):
        return base, [], (f"all {len(base)} photos of {data}/train: held-out photos (none of the "
                          "development val ids), scored whole; no training set")
    scored = ruemonge_split(base, split)
    fit = ruemonge_split(base, "train")
    return scored, fit, (f"development split {split!r} by building (val: stretches of the street "
                         f"no training photo sees; datasets.splits) of the {len(base)} photos in "
                         f"{data}/train; fitted on its train part ({len(fit)})")


def _labelmefacade_samples(load, data: Path, split: str, options: dict[str, Any]):
    """LabelMeFacade's own split files: score ``split``, fit on ``train.txt`` (module docstring)."""
    if split not in LABELMEFACADE_SPLITS:
        hint = ("LabelMeFacade has a train and a test split (train.txt, test.txt), no val: use "
                "--split test to score the test photos with the method fitted on train"
                if split == "val" else "LabelMeFacade's splits are its split files")
        raise InputError(f"unknown split {split!r} for dataset 'labelmefacade'; {hint} (splits: "
                         f"{', '.join(LABELMEFACADE_SPLITS)})")
    scored = load(data, split=split, **options)
    if split == "train":
        fit = scored
    elif (data / "train.txt").is_file():
        fit = load(data, split="train", **options)
    else:
        fit = []
    what = {"train": f"{data}/train.txt", "test": f"{data}/test.txt",
            "all": f"{data}/images with a label (train and test)"}[split]
    fitted = (f"fitted on the {len(fit)} photos of {data}/train.txt" if fit
              else f"no training set (no {data}/train.txt)")
    return scored, fit, f"all {len(scored)} photos of {what}; {fitted}"


# ---------------------------------------------------------------------------------- scoring
def _as_prediction(result: Any, where: str) -> Prediction:
    if isinstance(result, Prediction):
        return result
    if isinstance(result, np.ndarray):
        return Prediction(labels=result)
    raise InputError(f"{where}: returned {type(result).__name__}; a method must return a "
                     "Prediction (facadeforge.evaluation.methods)")


def _prediction_in_image(pred: Prediction, method: Method, label_set: LabelSet,
                         shape: tuple[int, int], where: str
                         ) -> tuple[np.ndarray, np.ndarray | None]:
    """(H, W) uint8 class indices (IGNORE = unpredicted) and windows, both in the photo frame."""
    labels = np.asarray(pred.labels)
    if labels.ndim != 2 or labels.dtype.kind not in "iu":
        raise InputError(f"{where}: Prediction.labels must be an (h, w) integer array, got "
                         f"shape {labels.shape} dtype {labels.dtype}")
    if method.label_space == "canonical":
        labels = label_set.from_canonical(labels)
    else:
        bad = (labels < 0) | ((labels >= label_set.num_classes) & (labels != IGNORE))
        if bad.any():
            raise InputError(
                f"{where}: class indices {np.unique(labels[bad])[:8].tolist()} are outside "
                f"0..{label_set.num_classes - 1} of label set {label_set.name!r} (255 = no "
                "prediction); predict in the label set passed to the method, or register it "
                "with label_space='canonical'")
        labels = labels.astype(np.uint8, copy=False)
    windows = None if pred.windows is None else np.asarray(pred.windows, np.float64)
    if windows is not None and windows.size and (windows.ndim != 2 or windows.shape[1] != 4):
        raise InputError(f"{where}: Prediction.windows must be (N, 4) boxes x0, y0, x1, y1, "
                         f"got shape {windows.shape}")
    if pred.homography is None:
        if labels.shape != tuple(shape):
            raise InputError(
                f"{where}: prediction is {labels.shape[1]}x{labels.shape[0]} px but the photo is "
                f"{shape[1]}x{shape[0]}; predict at the photo's size or return the homography "
                "of the prediction frame")
        return labels, None if windows is None else windows.reshape(-1, 4)
    h = pred.homography
    warped = warp_to_image(labels, h, shape)
    return warped, None if windows is None else box_to_image(windows, h, shape)


def _scores(full: np.ndarray, k: int) -> dict[str, Any]:
    """Scores of a (K+1, K+1) matrix whose last column counts unpredicted pixels."""
    s = SegmentationScores.from_confusion(full)
    acc, iou = s.class_accuracies[:k], s.iou[:k]
    return {"pixel_accuracy": s.pixel_accuracy, "class_avg_accuracy": _nanmean(acc),
            "miou": _nanmean(iou), "accuracy": acc, "iou": iou, "support": s.support[:k]}


def _nanmean(a: np.ndarray) -> float:
    ok = ~np.isnan(a)
    return float(a[ok].mean()) if ok.any() else math.nan


def _num(x: Any, digits: int = 6) -> float | None:
    x = float(x)
    return None if math.isnan(x) else round(x, digits)


class _Progress:
    """A one-line progress bar on stderr (a line per 10 % when stderr is not a terminal)."""

    def __init__(self, total: int, label: str, enabled: bool = True, width: int = 24):
        self.total, self.label, self.enabled, self.width = total, label, enabled, width
        self.stream = sys.stderr
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self._last_step = -1

    def update(self, done: int) -> None:
        if not self.enabled or self.total == 0:
            return
        elapsed = time.perf_counter() - self.t0
        rate = elapsed / done if done else 0.0
        eta = rate * (self.total - done)
        text = (f"{self.label} {done}/{self.total} "
                f"[{'#' * (self.width * done // self.total):<{self.width}}] "
                f"{rate:.2f} s/img, {elapsed:.0f} s, ETA {eta:.0f} s")
        if self.tty:
            self.stream.write("\r" + text)
            if done == self.total:
                self.stream.write("\n")
            self.stream.flush()
        else:
            step = 10 * done // self.total
            if step != self._last_step:
                self._last_step = step
                print(text, file=self.stream, flush=True)


# ---------------------------------------------------------------------------------- provenance
def machine_info() -> dict[str, Any]:
    """CPU, cores, memory and Python of this machine, for benchmark provenance."""
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        mem = round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1)
    except (ValueError, OSError, AttributeError):
        mem = None
    return {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": mem,
            "python": platform.python_version(), "platform": platform.platform()}


def provenance() -> dict[str, Any]:
    """``{"machine", "date", "commit"}`` for any benchmark result (STYLE: machine, date, commit)."""
    return {"machine": machine_info(), "date": datetime.now(UTC).isoformat(timespec="seconds"),
            "commit": git_commit()}


def save_result(result: dict, path: str | Path) -> None:
    """Write a benchmark result as indented JSON, atomically, and echo it on stdout."""
    text = json.dumps(result, indent=2) + "\n"
    _write_atomic(Path(path), text)
    print(text, end="")


def git_commit() -> str | None:
    """Short hash of the checked-out commit, or ``None`` outside a git checkout."""
    try:
        res = subprocess.run(["git", "rev-parse", "--short", "HEAD"],
                             cwd=Path(__file__).resolve().parent, capture_output=True, text=True,
                             timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return res.stdout.strip() or None if res.returncode == 0 else None


def _write_atomic(path: Path, data: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(data)
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def output_paths(out: str | Path) -> dict[str, Path]:
    """``json``, ``markdown`` and ``sheet`` paths of a run writing ``out`` (RESULT.json)."""
    out = Path(out)
    return {"json": out, "markdown": out.with_suffix(".md"),
            "sheet": out.with_name(out.stem + "_sheet.png")}


def check_output(out: str | Path, data: str | Path | None = None) -> dict[str, Path]:
    """The :func:`output_paths` of ``-o out``, refused before any work unless ``out`` names a
    ``.json`` file (not a folder) and none of the three files is a folder or lies in the
    dataset folder ``data`` (a result must never overwrite an input)."""
    text = os.fspath(out)
    given = Path(text)
    if text.endswith(("/", os.sep)) or given.is_dir():
        raise InputError(f"-o {text} is a folder; bench writes a result file: give e.g. "
                         f"-o {given / 'result.json'} (RESULT.md and RESULT_sheet.png are "
                         "written beside it)")
    if given.suffix.lower() != ".json":
        raise InputError(f"-o {text} is not a .json file; give the result file, e.g. "
                         f"-o {given.with_name(given.name + '.json')} (RESULT.md and "
                         "RESULT_sheet.png are written beside it)")
    paths = output_paths(given)
    root = Path(data).expanduser().resolve() if data is not None else None
    for p in paths.values():
        if p.is_dir():
            raise InputError(f"{p}, which bench writes beside -o {text}, is a folder; choose "
                             "another result name")
        if root is not None and root in p.resolve().parents:
            raise InputError(f"-o {text} is inside the dataset folder {data}; write the result "
                             "outside it (bench never writes into its input)")
    return paths


# ---------------------------------------------------------------------------------- harness
def run_bench(method: str, dataset: str, data: str | Path, split: str = "val",
              labels: str | None = None, limit: int | None = None, *, out: str | Path,
              progress: bool = True) -> dict[str, Any]:
    """Score a registered method on a dataset folder and write RESULT.json, .md and sheet.

    Parameters
    ----------
    method : str
        Name in :data:`~facadeforge.evaluation.methods.METHODS`.
    dataset : str
        Layout in :data:`facadeforge.datasets.LOADERS` (``cmp``, ``ruemonge``, ``folder``, …).
    data : str or Path
        Dataset folder.
    split : str
        ``val`` (default), ``train``, ``all``, a RueMonge split folder name, or LabelMeFacade's
        ``test`` (module docstring).
    labels : {"cmp6", "cmp12", "ecp7", "lmf9"}, optional
        Label set to score in; default the layout's own.  Results name the classes as the
        dataset does (``classes`` and ``per_class`` keys are the set's ``dataset_names``:
        LabelMeFacade's "building", CMP's "facade"); ``canonical_classes`` gives their canonical
        labels.
    limit : int, optional
        Score only the first ``limit`` facades of the split (sorted by id).
    out : str or Path
        RESULT.json path; ``RESULT.md`` and ``RESULT_sheet.png`` are written beside it.
    progress : bool
        Show a progress bar on stderr.

    Returns
    -------
    dict
        The content of RESULT.json (:data:`RESULT_KEYS`; NaN written as ``null``).

    Raises
    ------
    InputError
        Unknown method, dataset, split or label set; an empty selection; a bad prediction.
    """
    t_start = time.perf_counter()
    paths = check_output(out, data)      # a bad -o fails now, not after the scoring
    m = get_method(method)
    if limit is not None and (isinstance(limit, bool) or int(limit) < 1):
        raise InputError(f"limit {limit!r} must be a positive number of facades")
    scored, fit_set, rule = select_samples(dataset, data, split, labels)
    if limit is not None:
        scored = scored[:int(limit)]
    if not scored:
        raise InputError(f"split {split!r} of {data} holds no facades; pick another split "
                         "(train, val, all) or check the folder")
    label_set = scored[0].label_set
    k = label_set.num_classes
    names = label_set.dataset_names
    if len(set(names)) != len(names):   # a hand-made set with clashing names: canonical ones
        names = label_set.classes

    fit_seconds = 0.0
    if m.fit is not None:
        t0 = time.perf_counter()
        m.fit(list(fit_set), label_set)  # an empty list resets a previous fit
        fit_seconds = time.perf_counter() - t0
    prepare_seconds = 0.0
    if m.prepare is not None:          # multi-view methods reconstruct all photos at once
        t0 = time.perf_counter()
        m.prepare(list(scored), label_set)
        prepare_seconds = time.perf_counter() - t0

    window_class = "window" in label_set.classes
    full = np.zeros((k + 1, k + 1), np.int64)
    detections = DetectionAccumulator(0.5)
    counts = StructureCountAccumulator()
    windows_from = {"method": 0, "label_components": 0}
    per_image: list[dict[str, Any]] = []
    ranks: list[tuple[float, str]] = []  # unrounded per-image mIoU, for best and worst
    kept: list[tuple[float, str, int, np.ndarray]] = []  # their label maps, for the sheet
    bar = _Progress(len(scored), f"bench {method} on {dataset}/{split}", progress)
    for i, sample in enumerate(scored):
        where = f"method {method!r} on {sample.id}"
        result, seconds, peak = measure(m.predict, sample, label_set, trace_memory=False)
        pred = _as_prediction(result, where)
        truth = sample.labels()
        shape = truth.shape
        if ((truth >= k) & (truth != IGNORE)).any():
            raise InputError(f"truth of {sample.id} has class indices outside 0..{k - 1}; "
                             f"check the label set {label_set.name!r}")
        labels_img, boxes = _prediction_in_image(pred, m, label_set, shape, where)
        extended = np.where(labels_img == IGNORE, k, labels_img)
        own = confusion_matrix(truth, extended, k + 1, ignore_index=IGNORE)
        full += own
        one = _scores(own, k)

        truth_boxes = np.array([(o.x0, o.y0, o.x1, o.y1) for o in sample.objects()
                                if o.label == "window"], np.float64).reshape(-1, 4)
        if boxes is None:
            windows_from["label_components"] += 1
            comps = objects_from_labels(labels_img, label_set, classes=("window",)) \
                if window_class else []
            boxes = np.array([(o.x0, o.y0, o.x1, o.y1) for o in comps],
                             np.float64).reshape(-1, 4)
            scores = None
        else:
            windows_from["method"] += 1
            scores = pred.window_scores
        det = detections.add(truth_boxes, boxes, scores)
        counts.add(sample.meta.get("floors"), pred.floors,
                   sample.meta.get("columns"), pred.columns)

        per_image.append({
            "id": sample.id, "miou": _num(one["miou"]),
            "pixel_accuracy": _num(one["pixel_accuracy"]),
            "unpredicted_fraction": _num(own[:, k].sum() / max(own.sum(), 1)),
            "window_tp": det.tp, "window_fp": det.fp, "window_fn": det.fn,
            "seconds": round(seconds, 4), "peak_memory_mb": round(peak / 2**20, 2),
        })
        if not math.isnan(one["miou"]):
            ranks.append((one["miou"], sample.id))
            kept.append((one["miou"], sample.id, i, labels_img))
            kept = _trim(kept)
        bar.update(i + 1)

    seg = _scores(full, k)
    confusion = full[:k, :k]
    row_total = full[:k].sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        percent = np.where(row_total > 0, 100.0 * confusion / np.maximum(row_total, 1), np.nan)
    ranked = sorted(ranks, key=_rank)
    best = [i for _, i in ranked[:_BEST]]
    worst = [i for _, i in ranked[_BEST:][::-1][:_BEST]]
    det = detections.scores
    secs = [r["seconds"] for r in per_image]
    result: dict[str, Any] = {
        "method": method, "method_description": m.description, "dataset": dataset,
        "split": split, "label_set": label_set.name, "classes": list(names),
        "canonical_classes": list(label_set.classes),
        "n_images": len(scored), "limit": limit,
        "pixel_accuracy": _num(seg["pixel_accuracy"]),
        "class_avg_accuracy": _num(seg["class_avg_accuracy"]),
        "miou": _num(seg["miou"]),
        "per_class": {name: {"accuracy": _num(seg["accuracy"][c]), "iou": _num(seg["iou"][c]),
                             "support": int(seg["support"][c])}
                      for c, name in enumerate(names)},
        "confusion": confusion.tolist(),
        "confusion_percent": [[_num(v, 3) for v in row] for row in percent],
        "unpredicted": full[:k, k].tolist(),
        "unpredicted_fraction": _num(full[:k, k].sum() / max(full.sum(), 1)),
        "window_precision": _num(det.precision), "window_recall": _num(det.recall),
        "window_f1": _num(det.f1), "window_tp": det.tp, "window_fp": det.fp,
        "window_fn": det.fn, "windows_from": windows_from,
    }
    for key, value in counts.to_dict().items():
        quantity = key.split("_count_")[0]
        if getattr(counts, quantity + "s").n_images:
            result[key] = value
    unknown = [s.meta["unknown_color_pixels"] for s in scored if "unknown_color_pixels" in s.meta]
    if unknown:   # colour-coded truth (LabelMeFacade): pixels in no class's colour, not scored
        result["unknown_color_pixels"] = int(sum(unknown))
    result.update({
        "seconds_per_image": round(float(np.mean(secs)) + prepare_seconds / len(scored), 5),
        "peak_memory_mb": round(max(r["peak_memory_mb"] for r in per_image), 2),
        "fit_images": len(fit_set) if m.fit is not None else 0,
        "fit_seconds": round(fit_seconds, 3),
        "wall_seconds": None,
        "per_image": per_image, "best": best, "worst": worst, "split_rule": rule,
        "machine": machine_info(), "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "commit": git_commit(), "data": str(Path(data).expanduser().resolve()),
        "files": {name: str(p) for name, p in paths.items()},
    })

    by_id = {s.id: s for s in scored}
    pred_of = {sid: lab for _, sid, _, lab in kept}
    rows = []
    miou_of = {sid: v for v, sid in ranks}
    for tag, ids in (("best", best), ("worst", worst)):
        for n, sid in enumerate(ids, 1):
            sample = by_id[sid]
            miou = miou_of[sid]
            rows.append(SheetRow(title=f"{tag} {n}: {sid}   mIoU {miou:.3f}",
                                 photo=sample.image(), truth=sample.labels(),
                                 prediction=pred_of[sid]))
    _write_results(paths, lambda sheet: write_sheet(
        rows, label_set, sheet,
        title=f"{method} on {dataset} ({split}, {label_set.name}): mIoU "
              f"{_fmt(result['miou'])}, pixel accuracy {_fmt(result['pixel_accuracy'])}"),
        result, t_start)
    return result


def _write_results(paths: dict[str, Path], sheet, result: dict, t_start: float) -> None:
    """The sheet, RESULT.md and RESULT.json, all three or none: each is written under a
    temporary name first, and they are renamed into place only when all three were written
    (RESULT.json last, so a reader that finds it finds the other two of the same run)."""
    parts = {k: p.with_name(f".{p.stem}.{os.getpid()}.part{p.suffix}") for k, p in paths.items()}
    try:
        paths["json"].parent.mkdir(parents=True, exist_ok=True)
        sheet(parts["sheet"])
        result["wall_seconds"] = round(time.perf_counter() - t_start, 3)
        _write_atomic(parts["markdown"], markdown_summary(result))
        _write_atomic(parts["json"], json.dumps(result, indent=2) + "\n")
        for key in ("sheet", "markdown", "json"):
            os.replace(parts[key], paths[key])
    finally:
        for part in parts.values():
            part.unlink(missing_ok=True)


def _trim(kept: list[tuple[float, str, int, np.ndarray]]
          ) -> list[tuple[float, str, int, np.ndarray]]:
    """Keep the label maps of the facades that can still be among the best or worst."""
    if len(kept) <= 2 * _BEST:
        return kept
    ordered = sorted(kept, key=_rank)
    return ordered[:_BEST] + ordered[-_BEST:]


def _rank(item: tuple) -> tuple[float, str]:
    """Total order of facades, best first: higher mIoU, then id (the worst are the last)."""
    return -item[0], item[1]


# ---------------------------------------------------------------------------------- markdown
def _fmt(x: float | None, digits: int = 3) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def markdown_summary(result: dict[str, Any]) -> str:
    """RESULT.md text of a RESULT.json dictionary."""
    r = result
    lines = [
        f"# {r['method']} on {r['dataset']} ({r['split']}, {r['label_set']})",
        "",
        f"{r['n_images']} facades from `{r['data']}`; {r['split_rule']}.",
        f"Measured {r['date'][:10]} at commit `{r['commit']}` on {r['machine']['cores']} cores "
        f"({r['machine']['cpu']}), Python {r['machine']['python']}.",
        *([f"{r['unknown_color_pixels']} truth pixels have colours of no class and are not "
           "scored."] if r.get("unknown_color_pixels") else []),
        "",
        "| score | value |",
        "|---|---|",
        f"| pixel accuracy | {_fmt(r['pixel_accuracy'])} |",
        f"| class-average accuracy | {_fmt(r['class_avg_accuracy'])} |",
        f"| mIoU | {_fmt(r['miou'])} |",
        f"| window precision / recall / F1 (IoU ≥ 0.5) | {_fmt(r['window_precision'])} / "
        f"{_fmt(r['window_recall'])} / {_fmt(r['window_f1'])} "
        f"(tp {r['window_tp']}, fp {r['window_fp']}, fn {r['window_fn']}) |",
    ]
    for what in ("floor", "column"):
        if f"{what}_count_mae" in r:
            lines.append(f"| {what} count MAE / exact | {_fmt(r[f'{what}_count_mae'], 2)} / "
                         f"{_fmt(r[f'{what}_count_exact'], 2)} |")
    lines += [
        f"| unpredicted pixels | {_fmt(100 * (r['unpredicted_fraction'] or 0), 2)} % |",
        f"| seconds / image | {r['seconds_per_image']:.4f} |",
        f"| peak memory (process RSS) | {r['peak_memory_mb']:.1f} MiB |",
        "",
        "## Per class",
        "",
        "| class | IoU | accuracy | truth pixels |",
        "|---|---|---|---|",
    ]
    total = sum(v["support"] for v in r["per_class"].values()) or 1
    for name, v in r["per_class"].items():
        lines.append(f"| {name} | {_fmt(v['iou'])} | {_fmt(v['accuracy'])} | "
                     f"{100 * v['support'] / total:.1f} % |")
    classes = r["classes"]
    unpred = any(r["unpredicted"])
    lines += ["", "## Confusion (% of each truth row; rows truth, columns prediction)", "",
              "| truth \\ predicted | " + " | ".join(classes)
              + (" | unpredicted |" if unpred else " |"),
              "|---" * (len(classes) + 1 + unpred) + "|"]
    for name, row, miss in zip(classes, r["confusion_percent"], r["unpredicted"]):
        cells = [_fmt(v, 1) for v in row]
        if unpred:
            support = r["per_class"][name]["support"]
            cells.append(_fmt(100 * miss / support, 1) if support else "–")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", f"Best: {', '.join(r['best']) or '–'}.  Worst: {', '.join(r['worst']) or '–'}.",
              f"Sheet: `{Path(r['files']['sheet']).name}`.", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------- CLI glue
def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--limit '{text}' must be a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"--limit {value} must be at least 1")
    return value


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``bench`` subcommand to an ``argparse`` subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "bench", help="score a facade-labelling method on a dataset (RESULT.json, .md, sheet)",
        description="Score a registered method on a facade dataset in the dataset's own pixel "
                    "frame; write RESULT.json, RESULT.md and RESULT_sheet.png.",
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--method", required=True, metavar="NAME",
                   help=f"registered method ({', '.join(sorted(METHODS))})")
    p.add_argument("--dataset", required=True,
                   metavar="cmp|ruemonge|labelmefacade|synthetic|folder",
                   help="dataset layout")
    p.add_argument("--data", required=True, metavar="DIR", help="dataset folder")
    p.add_argument("--split", default="val", metavar="S",
                   help="train, val (default) or all: the fixed development split; RueMonge: "
                        "val/ when DIR/val exists, or any split folder name; LabelMeFacade: "
                        "test, train (its split files) or all")
    p.add_argument("--labels", default=None, metavar="cmp6|cmp12|ecp7|lmf9",
                   help="label set to score in (default: cmp6 for cmp, ecp7 for ruemonge, lmf9 "
                        "for labelmefacade, the palette for folder)")
    p.add_argument("--limit", type=_positive_int, default=None, metavar="N",
                   help="score only the first N facades of the split")
    p.add_argument("-o", "--output", required=True, metavar="RESULT.json",
                   help="result file; RESULT.md and RESULT_sheet.png are written beside it")
    return p


def cmd_bench(args: argparse.Namespace) -> int:
    """Run :func:`run_bench` from parsed arguments and print a one-line summary."""
    r = run_bench(args.method, args.dataset, Path(args.data), split=args.split,
                  labels=args.labels, limit=args.limit, out=Path(args.output))
    files = r["files"]
    print(f"{r['method']} on {r['dataset']}/{r['split']} ({r['n_images']} facades, "
          f"{r['label_set']}): pixel acc {_fmt(r['pixel_accuracy'])}, class-avg acc "
          f"{_fmt(r['class_avg_accuracy'])}, mIoU {_fmt(r['miou'])}, window F1 "
          f"{_fmt(r['window_f1'])}, {r['seconds_per_image']:.3f} s/facade → {files['json']} "
          f"(+ {Path(files['markdown']).name}, {Path(files['sheet']).name})")
    if r.get("unknown_color_pixels"):
        print(f"note: {r['unknown_color_pixels']} truth pixels have colours outside the "
              "dataset's palette; they are not scored")
    return 0
