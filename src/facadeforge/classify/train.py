"""Training the forest classifiers from a labelled facade dataset, and the
``facadeforge train-classifier`` command.

Sampling: each training photo is resized to the analysis scale, and a fixed number of its
labelled pixels are drawn with probability ∝ (class frequency in that photo)^-½ — half-way between
uniform sampling (doors and shops, 1–3 % of pixels, would be drowned) and class-balanced sampling
(which overpredicts rare classes).  Seeded, so a model is reproduced bit for bit by its command.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..datasets import FacadeSample, LabelSet, get_label_set
from ..errors import InputError
from .model import PixelClassifier, save_classifier

__all__ = ["TRAINABLE_KINDS", "add_parser", "cmd_train_classifier", "train_classifier"]

#: Kinds trained from a dataset (``gmm`` is trained from a photo's scribbles instead).
TRAINABLE_KINDS: tuple[str, ...] = ("forest", "autocontext", "convnet")


def _small_labels(labels: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    import cv2

    return cv2.resize(labels, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)


def _sample_pixels(labels: np.ndarray, k: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """Flat indices of up to ``n`` labelled pixels, drawn ∝ frequency^-½ of their class."""
    flat = labels.ravel()
    ok = np.flatnonzero(flat < k)
    if ok.size == 0:
        return ok
    counts = np.bincount(flat[ok], minlength=k).astype(np.float64)
    w = counts[flat[ok]] ** -0.5
    n = min(n, ok.size)
    return np.sort(rng.choice(ok, size=n, replace=False, p=w / w.sum()))


def _progress(msg: str, quiet: bool) -> None:
    if not quiet:
        print(msg, file=sys.stderr, flush=True)


def train_classifier(samples: Sequence[FacadeSample], label_set: LabelSet | str, *,
                     kind: str = "autocontext", stages: int = 2, trees: int = 10,
                     max_depth: int | None = None, per_image: int = 3000, folds: int = 2,
                     seed: int = 0, jobs: int = 2, epochs: int = 40, width: int = 16,
                     quiet: bool = True, checkpoint=None,
                     meta: dict[str, Any] | None = None) -> PixelClassifier:
    """Train a ``forest`` (§4.3.1), ``autocontext`` or ``convnet`` classifier on labelled
    ``samples``.

    Parameters
    ----------
    samples : sequence of FacadeSample
        Training photos with label maps in ``label_set``.
    kind : {"forest", "autocontext", "convnet"}
    stages : int
        Auto-context stages (1 = a plain forest on appearance features).
    trees, max_depth : int
        Forest size; ``max_depth=None`` means 18 for ``forest`` (the thesis's depth) and
        unbounded with at most 6000 leaves per tree for ``autocontext``.
    per_image : int
        Pixels sampled per photo.
    folds : int
        Auto-context: stage s + 1 trains on out-of-fold predictions of stage s over this many
        folds of photos.
    epochs, width : int
        Convnet: training epochs and channels of the first level (:mod:`.convnet_train`).
    checkpoint : callable, optional
        Convnet: called with the network so far after every epoch.

    Samples may come from several datasets in different label sets (a convnet only): each
    supervises the classes of ``label_set`` its classes may be (:mod:`.street`).
    """
    from .autocontext import AutoContextClassifier, stage_features
    from .features import analysis_image, appearance_features
    from .forest import ForestClassifier, TreeEnsemble, grow_forest

    label_set = get_label_set(label_set)
    if kind not in TRAINABLE_KINDS:
        raise InputError(f"classifier kind {kind!r} cannot be trained from a dataset; use one of "
                         f"{', '.join(TRAINABLE_KINDS)} (gmm is trained from scribbles)")
    samples = list(samples)
    if len(samples) < max(2, folds):
        raise InputError(f"training needs at least {max(2, folds)} labelled photos, got "
                         f"{len(samples)}; check --data and --split")
    if stages < 1 or trees < 1 or per_image < 10 or epochs < 1 or width < 1:
        raise InputError("stages, trees, epochs and width must be >= 1 and per-image samples "
                         ">= 10")
    if kind == "convnet":  # its shape is checked before any photo is read
        from .convnet import ConvNetSpec

        try:
            spec = ConvNetSpec(width=width)
        except ValueError as exc:
            raise InputError(f"--width {width}: {exc}; use 1-256 (default 16)") from None
    mixed = sorted({s.label_set.name for s in samples if s.label_set.name != label_set.name})
    if mixed and kind != "convnet":
        raise InputError(f"photos labelled in {', '.join(mixed)}, not {label_set.name}: only a "
                         "convnet learns from datasets with different classes")
    k = label_set.num_classes
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    info = {"kind": kind, "label_set": label_set.name, "photos": len(samples),
            "ids": [s.id for s in samples], "trees": trees, "per_image": per_image,
            "seed": seed, "trained": _dt.date.today().isoformat(), **(meta or {})}

    # Analysis-scale photos, labels and the sampled pixels of each, read once.
    smalls, labels, picks = [], [], []
    for s in samples:
        small = analysis_image(s.image())
        lab = _small_labels(s.labels(), small.shape[:2])
        smalls.append(small)
        labels.append(lab)
        if kind != "convnet":       # the network trains on whole crops, not sampled pixels
            picks.append(_sample_pixels(lab, k, per_image, rng))
    if kind == "convnet":
        from .convnet_train import train_convnet
        from .street import partial_table

        info = {k_: v for k_, v in info.items() if k_ not in ("kind", "trees", "per_image")}
        partial = [None if s.label_set.name == label_set.name
                   else partial_table(s.label_set, label_set) for s in samples]
        # several datasets: a small one is drawn more often, by sqrt(largest / its size)
        sizes: dict[str, int] = {}
        for s in samples:
            sizes[s.meta.get("dataset", "")] = sizes.get(s.meta.get("dataset", ""), 0) + 1
        repeat = [max(1, round(math.sqrt(max(sizes.values()) / sizes[s.meta.get("dataset", "")])))
                  for s in samples]
        return train_convnet(smalls, labels, label_set.classes, label_set.name,
                             spec=spec, epochs=epochs, seed=seed, partial=partial,
                             augment="street" if any(t is not None for t in partial)
                             else "basic", repeat=repeat, checkpoint=checkpoint,
                             threads=jobs, progress=None if quiet else
                             (lambda m: _progress(m, False)), meta=info)
    y = np.concatenate([lab.ravel()[p] for lab, p in zip(labels, picks)]).astype(np.int64)
    if len(np.unique(y)) < 2:
        raise InputError("the training photos have fewer than two labelled classes")
    _progress(f"{len(samples)} photos, {y.size} sampled pixels", quiet)

    if kind == "forest":
        tests = ForestClassifier.default_tests(seed)
        X = np.concatenate([ForestClassifier.features(sm, tests).reshape(-1, len(tests))[p]
                            for sm, p in zip(smalls, picks)])
        depth = 18 if max_depth is None else max_depth
        ens = grow_forest(X, y, k, trees=trees, max_depth=depth, seed=seed, jobs=jobs)
        info.update(max_depth=depth, seconds=round(time.perf_counter() - t0, 1))
        return ForestClassifier(ens, tests, label_set.classes, label_set.name, info)

    tests = AutoContextClassifier.default_tests(seed)
    apps = [appearance_features(sm) for sm in smalls]
    opts = dict(trees=trees, max_depth=max_depth, max_leaf_nodes=6000 if max_depth is None
                else None, min_samples_leaf=5, seed=seed, jobs=jobs)
    fold_of = np.arange(len(samples)) % folds
    prev: list[np.ndarray | None] = [None] * len(samples)
    ensembles: list[TreeEnsemble] = []
    for stage in range(stages):
        feats = [stage_features(sm, stage, tests, pv, ap)
                 for sm, pv, ap in zip(smalls, prev, apps)]
        X = np.concatenate([f.reshape(-1, f.shape[2])[p] for f, p in zip(feats, picks)])
        ensembles.append(grow_forest(X, y, k, **opts))
        _progress(f"stage {stage}: {X.shape[1]} features, forest grown "
                  f"({time.perf_counter() - t0:.0f} s)", quiet)
        if stage + 1 == stages:
            break
        # Out-of-fold probabilities of this stage for the next one.
        row_fold = np.concatenate([np.full(len(p), fold_of[i]) for i, p in enumerate(picks)])
        nxt: list[np.ndarray | None] = [None] * len(samples)
        for f_id in range(folds):
            ens = grow_forest(X[row_fold != f_id], y[row_fold != f_id], k, **opts)
            for i in np.flatnonzero(fold_of == f_id):
                h, w = smalls[i].shape[:2]
                nxt[i] = ens.predict_proba(feats[i].reshape(h * w, -1)).reshape(h, w, k)
        prev = nxt
        _progress(f"stage {stage}: out-of-fold maps ({time.perf_counter() - t0:.0f} s)", quiet)
    info.update(stages=stages, folds=folds, seconds=round(time.perf_counter() - t0, 1))
    return AutoContextClassifier(ensembles, tests, label_set.classes, label_set.name, info)


# ------------------------------------------------------------------------------------ CLI
def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "train-classifier",
        help="train a pixel classifier (forest, autocontext, convnet, gmm, ensemble)",
        description="Train a pixel classifier for grammar parsing. forest, autocontext and "
                    "convnet learn from a labelled dataset's train split; gmm learns from one "
                    "photo's scribbles; ensemble averages trained models (--members).",
        epilog="examples:\n"
               "  facadeforge train-classifier --kind autocontext --dataset cmp --data ../shared/data/cmp "
               "-o cmp.npz\n"
               "  facadeforge train-classifier --kind gmm --image photo.jpg "
               "--scribbles strokes.png -o gmm.npz",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--kind", default="autocontext",
                   choices=(*TRAINABLE_KINDS, "gmm", "ensemble"))
    p.add_argument("--dataset",
                   help="dataset layout: cmp, ruemonge, labelmefacade, synthetic or folder "
                        "(forest, autocontext, convnet); several, comma-separated: a convnet "
                        "learns from each the classes it labels (ruemonge,cmp,labelmefacade), "
                        "a forest reads all in --labels (labelmefacade,synthetic --labels lmf9)")
    p.add_argument("--data", help="dataset folder (comma-separated, one per --dataset)")
    p.add_argument("--split", default="train",
                   help="split to train on: train (default, the development train split) or all")
    p.add_argument("--labels", help="label set (default: the dataset's, cmp6 / ecp7)")
    p.add_argument("--image", help="photo the scribbles are drawn on (gmm)")
    p.add_argument("--scribbles", help="scribble PNG (gmm): strokes in the label set's colours")
    p.add_argument("--members", nargs="+", metavar="MODEL",
                   help="ensemble: model files to average (in --labels, default the first's)")
    p.add_argument("--stages", type=int, default=2, help="auto-context stages (default 2)")
    p.add_argument("--trees", type=int, default=10, help="trees per forest (default 10)")
    p.add_argument("--per-image", type=int, default=3000,
                   help="pixels sampled per training photo (default 3000)")
    p.add_argument("--epochs", type=int, default=40, help="convnet: training epochs (default 40)")
    p.add_argument("--width", type=int, default=16,
                   help="convnet: channels of the first level (default 16)")
    p.add_argument("--limit", type=int, help="train on the first N photos only (of each dataset)")
    p.add_argument("--checkpoint", metavar="PATH",
                   help="convnet: save the network so far to PATH (.npz) after every epoch")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-o", "--output", required=True, help="model file to write (.npz)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return p


def cmd_train_classifier(args: argparse.Namespace) -> int:
    out = Path(args.output)
    if out.suffix != ".npz":
        raise InputError(f"-o {out}: a classifier is written as .npz; use e.g. -o model.npz")
    if not out.parent.is_dir():
        raise InputError(f"-o {out}: folder {out.parent} does not exist; create it first")
    command = "facadeforge " + " ".join(sys.argv[1:]) if sys.argv else ""
    if args.kind == "ensemble":
        from .ensemble import EnsembleClassifier
        from .model import load_classifier

        if not args.members:
            raise InputError("--kind ensemble needs --members MODEL.npz MODEL.npz …")
        members = [load_classifier(m) for m in args.members]
        clf = EnsembleClassifier(members, args.labels or members[0].label_set,
                                 {"command": command})
    elif args.kind == "gmm":
        from ..datasets import read_image
        from .gmm import train_gmm

        if not args.image or not args.scribbles:
            raise InputError("--kind gmm needs --image PHOTO and --scribbles PNG")
        clf = train_gmm(read_image(args.image), args.scribbles, label_set=args.labels or "ecp7",
                        seed=args.seed)
        clf.meta["command"] = command
    else:
        if not args.dataset or not args.data:
            raise InputError(f"--kind {args.kind} needs --dataset and --data")
        names, folders = args.dataset.split(","), args.data.split(",")
        if len(names) != len(folders):
            raise InputError(f"--dataset names {len(names)} layouts and --data {len(folders)} "
                             "folders; give one folder per layout, in the same order")
        if len(names) > 1 and args.kind != "convnet" and not args.labels:
            raise InputError(f"--kind {args.kind} learns from several datasets only when all "
                             "are read in one label set: give --labels (e.g. lmf9); only a "
                             "convnet learns from datasets with different classes")
        from ..evaluation.bench import select_samples

        # several datasets: a convnet reads each in its own classes (the network's are
        # --labels); a forest reads all of them in --labels
        own = len(names) > 1 and args.kind == "convnet"
        scored, rules = [], []
        for name, folder in zip(names, folders):
            picked, _fit, rule = select_samples(name, folder, args.split,
                                                None if own else args.labels)
            scored += picked[:args.limit] if args.limit else picked
            rules.append(rule)
        rule = "; ".join(rules)
        label_set = (get_label_set(args.labels) if args.labels and len(names) > 1
                     else scored[0].label_set if scored else get_label_set(args.labels or "ecp7"))
        checkpoint = None
        if args.checkpoint:
            if not args.checkpoint.endswith(".npz"):
                raise InputError(f"--checkpoint {args.checkpoint}: use a .npz path")

            def checkpoint(net, path=Path(args.checkpoint)):
                save_classifier(net, path)
        clf = train_classifier(scored, label_set, kind=args.kind, stages=args.stages,
                               checkpoint=checkpoint,
                               trees=args.trees, per_image=args.per_image, seed=args.seed,
                               epochs=args.epochs, width=args.width, quiet=args.quiet,
                               meta={"command": command, "dataset": args.dataset,
                                     "split": args.split, "split_rule": rule})
    save_classifier(clf, out)
    print(f"{clf.kind} classifier ({', '.join(clf.classes)}) written to {out}")
    return 0
