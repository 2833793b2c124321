"""Method registry of the benchmark harness, and two honest baselines.

A *method* labels one facade photo: ``predict(sample, label_set) -> Prediction``.  Register one
with :func:`register_method`; ``facadeforge bench --method NAME`` looks it up in :data:`METHODS`::

    @register_method("my-parser", "label_set", description="my facade parser")
    def my_parser(sample: FacadeSample, label_set: LabelSet) -> Prediction:
        photo = sample.image()                       # (H, W, 3) uint8
        ...
        return Prediction(labels=index_map, windows=boxes)

A method that learns from data also has a ``fit(train_samples, label_set)`` attribute (register a
callable object, as :class:`RowColPrior` does); the harness calls it once per run with the
dataset's development ``train`` split before predicting.  A method must not read the truth of the
sample it predicts (``sample.labels()``, ``sample.objects()``): only ``sample.image()``,
``sample.image_shape()`` and ``sample.id``.

Label spaces (``label_space`` of :func:`register_method`):

``"label_set"``
    ``Prediction.labels`` holds class indices of the label set the harness passes in (0..K-1).
``"canonical"``
    ``Prediction.labels`` holds canonical label indices (:data:`~facadeforge.datasets.CANONICAL_INDEX`,
    the order of :class:`~facadeforge.model.Labels`), such as a rasterised shape tree; the harness
    converts them with :meth:`LabelSet.from_canonical`.

In both, :data:`~facadeforge.datasets.IGNORE` (255) means "no prediction here"; the harness scores
such pixels as wrong wherever the truth is labelled.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..datasets import FacadeSample, LabelSet
from ..errors import InputError
from ..parsing import DEFAULT_BUDGET

__all__ = ["LABEL_SPACES", "METHODS", "ClassifierMethod", "Method", "Prediction", "PriorBaseline",
           "GrammarMethod", "MultiviewMethod", "RowColPrior", "StructureMethod", "get_method",
           "is_rectified", "register_method"]

#: Label spaces a method may predict in (see the module docstring).
LABEL_SPACES: tuple[str, ...] = ("label_set", "canonical")


@dataclass(frozen=True, eq=False)
class Prediction:
    """What a method says about one facade photo.

    Parameters
    ----------
    labels : (h, w) uint8
        Class indices (in the method's label space), :data:`IGNORE` where it makes no prediction.
        In the photo's own pixel frame, or in any frame (e.g. rectified) given a ``homography``.
    homography : (3, 3) float, optional
        Maps prediction-frame pixel coordinates to the photo's pixel coordinates, both with the
        pixel-edge convention of :class:`~facadeforge.datasets.ObjectBox` (pixel ``(r, c)`` covers
        ``[c, c+1) x [r, r+1)``, its centre is ``(c + 0.5, r + 0.5)``).  ``None``: same frame,
        so ``labels`` must have the photo's shape.
    windows : (N, 4) float, optional
        Window boxes ``x0, y0, x1, y1`` in prediction-frame pixels (``x1``/``y1`` exclusive).
        ``None``: the harness takes the connected components of the window class of ``labels``.
    window_scores : (N,) float, optional
        Confidence of each window box (matching order, see
        :func:`~facadeforge.evaluation.greedy_match`).
    floors, columns : int, optional
        Estimated number of floors and window columns.
    """

    labels: np.ndarray
    homography: np.ndarray | None = None
    windows: np.ndarray | None = None
    window_scores: np.ndarray | None = None
    floors: int | None = None
    columns: int | None = None


@dataclass(frozen=True)
class Method:
    """A registered method.

    Attributes
    ----------
    name : str
        Registry key, the ``--method`` value.
    predict : callable
        ``predict(sample, label_set) -> Prediction``.
    label_space : {"label_set", "canonical"}
        What ``Prediction.labels`` holds.
    fit : callable or None
        ``fit(train_samples, label_set) -> None`` for methods that learn from data.
    prepare : callable or None
        ``prepare(scored_samples, label_set) -> None`` for methods that see several photos at
        once (``multiview``: the calibrated photos of one building): called with the photos to
        be scored before the first ``predict``; it may read their photos and cameras, never
        their truth.
    description : str
        One line for listings and reports.
    """

    name: str
    predict: Callable[[FacadeSample, LabelSet], Prediction]
    label_space: str = "label_set"
    fit: Callable[[Sequence[FacadeSample], LabelSet], Any] | None = None
    description: str = ""
    prepare: Callable[[Sequence[FacadeSample], LabelSet], Any] | None = None


#: Datasets whose photos are rectified already (methods skip rectification, as ``--rectified``).
RECTIFIED_DATASETS = frozenset({"cmp"})


def is_rectified(sample: FacadeSample) -> bool:
    """Whether ``sample``'s photo is rectified already, so a method skips rectification and
    uses the rectified-photo classifier (``cmp12``, CMP's conventions: neighbours, roof and sky
    are background) rather than the street-photo one (``ecp7``, RueMonge's: no background).

    ``sample.meta["rectified"]`` decides where the loader sets it (synthetic facades: rectified
    unless written with ``--perspective``); else the dataset, :data:`RECTIFIED_DATASETS`.
    """
    flag = sample.meta.get("rectified")
    if flag is not None:
        return bool(flag)
    return sample.meta.get("dataset") in RECTIFIED_DATASETS

#: Registered methods by name (``facadeforge bench --method NAME``).
METHODS: dict[str, Method] = {}


def register_method(name: str, label_space: str = "label_set", *, description: str = "",
                    replace: bool = False) -> Callable[[Any], Any]:
    """Decorator registering ``predict(sample, label_set) -> Prediction`` as method ``name``.

    Parameters
    ----------
    name : str
        Registry key (``--method`` value).
    label_space : {"label_set", "canonical"}
        What the method's ``Prediction.labels`` holds (module docstring).
    description : str
        One line; default: the first line of the callable's docstring.
    replace : bool
        Allow replacing an already registered method of that name.

    Returns
    -------
    callable
        The decorator; it registers its argument and returns it unchanged.  A ``fit`` attribute
        of the argument, when callable, becomes :attr:`Method.fit`.

    Raises
    ------
    InputError
        Empty name, unknown label space, or a name already taken (without ``replace``).
    """
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"register_method: method name {name!r} must be a non-empty string")
    if label_space not in LABEL_SPACES:
        raise InputError(f"register_method({name!r}): unknown label space {label_space!r}; use "
                         f"one of {', '.join(LABEL_SPACES)}")

    def decorate(fn: Any) -> Any:
        if not callable(fn):
            raise InputError(f"register_method({name!r}): {fn!r} is not callable; register "
                             "predict(sample, label_set) -> Prediction")
        if name in METHODS and not replace:
            raise InputError(f"method {name!r} is already registered; pick another name or "
                             "pass replace=True")
        fit = getattr(fn, "fit", None)
        prepare = getattr(fn, "prepare", None)
        doc = (getattr(fn, "__doc__", None) or "").strip()
        METHODS[name] = Method(name=name, predict=fn, label_space=label_space,
                               fit=fit if callable(fit) else None,
                               prepare=prepare if callable(prepare) else None,
                               description=description or (doc.splitlines()[0] if doc else ""))
        return fn

    return decorate


def get_method(name: str) -> Method:
    """The registered method ``name``.

    Raises
    ------
    InputError
        No such method; the message lists the registered ones.
    """
    try:
        return METHODS[name]
    except KeyError:
        raise InputError(f"unknown method {name!r}; use one of "
                         f"{', '.join(sorted(METHODS)) or '(none registered)'}") from None


# ---------------------------------------------------------------------------------- baselines
def _fit_key(train: Sequence[FacadeSample], label_set: LabelSet) -> tuple:
    return (label_set.name, label_set.classes,
            tuple((s.id, str(s.label_path)) for s in train))


class _Cache:
    """Fitted parameters by training set, so repeated runs in one process fit once."""

    def __init__(self, size: int = 8):
        self.size = size
        self._items: dict[tuple, Any] = {}

    def get(self, key: tuple) -> Any:
        return self._items.get(key)

    def put(self, key: tuple, value: Any) -> None:
        self._items.pop(key, None)
        self._items[key] = value
        while len(self._items) > self.size:
            self._items.pop(next(iter(self._items)))


def _class_counts(labels: np.ndarray, k: int) -> np.ndarray:
    flat = labels.ravel()
    return np.bincount(flat[flat < k], minlength=k)[:k].astype(np.int64)


class PriorBaseline:
    """Baseline, not a method: every pixel gets the most frequent training class (wall).

    ``fit`` counts the class pixels of the training split; without a fit the label set's ``wall``
    class (through the canonical fallback) is used.  It predicts no windows.
    """

    def __init__(self) -> None:
        self._cache = _Cache()
        self._fitted: dict[tuple, int] = {}

    def fit(self, train: Sequence[FacadeSample], label_set: LabelSet) -> int:
        """Learn the most frequent class of ``train`` in ``label_set``; returns its index."""
        key = _fit_key(train, label_set)
        cls = self._cache.get(key)
        if cls is None:
            counts = np.zeros(label_set.num_classes, np.int64)
            for s in train:
                counts += _class_counts(s.labels(), label_set.num_classes)
            cls = int(np.argmax(counts)) if counts.any() else label_set.index("wall")
            self._cache.put(key, cls)
        self._fitted[(label_set.name, label_set.classes)] = cls
        return cls

    def __call__(self, sample: FacadeSample, label_set: LabelSet) -> Prediction:
        cls = self._fitted.get((label_set.name, label_set.classes), label_set.index("wall"))
        return Prediction(labels=np.full(sample.image_shape(), cls, np.uint8),
                          windows=np.zeros((0, 4)))


class RowColPrior:
    """Baseline, not a method: per pixel, the most frequent training class at its place.

    ``fit`` learns a ``grid x grid`` (32 x 32) spatial prior: for each cell of the photo's
    normalised (row, column) position, the class seen most often there in the training label maps
    (cells never seen take the overall most frequent class).  ``predict`` looks each pixel's cell
    up.  It uses no pixel of the photo, only its size: a yardstick any real method must beat.
    Windows are left to the harness (connected components of the predicted window class).
    """

    def __init__(self, grid: int = 32) -> None:
        self.grid = int(grid)
        self._cache = _Cache()
        self._fitted: dict[tuple, np.ndarray] = {}

    def fit(self, train: Sequence[FacadeSample], label_set: LabelSet) -> np.ndarray:
        """Learn the ``(grid, grid)`` uint8 prior map of ``train``; returns it."""
        key = _fit_key(train, label_set)
        prior = self._cache.get(key)
        if prior is None:
            g, k = self.grid, label_set.num_classes
            counts = np.zeros((g * g, k), np.int64)
            for s in train:
                labels = s.labels()
                h, w = labels.shape
                cell = ((np.arange(h) * g // h)[:, None] * g + (np.arange(w) * g // w)[None, :])
                ok = labels < k
                counts += np.bincount(cell[ok] * k + labels[ok], minlength=g * g * k
                                      ).reshape(g * g, k)
            total = counts.sum(axis=0)
            fallback = int(np.argmax(total)) if total.any() else label_set.index("wall")
            prior = np.where(counts.any(axis=1), np.argmax(counts, axis=1), fallback)
            prior = prior.reshape(g, g).astype(np.uint8)
            prior.flags.writeable = False
            self._cache.put(key, prior)
        self._fitted[(label_set.name, label_set.classes)] = prior
        return prior

    def __call__(self, sample: FacadeSample, label_set: LabelSet) -> Prediction:
        prior = self._fitted.get((label_set.name, label_set.classes))
        h, w = sample.image_shape()
        if prior is None:  # never fitted: a flat wall prior
            return Prediction(labels=np.full((h, w), label_set.index("wall"), np.uint8))
        g = prior.shape[0]
        rows = np.arange(h) * g // h
        cols = np.arange(w) * g // w
        return Prediction(labels=prior[rows[:, None], cols[None, :]].copy())


register_method("prior", "label_set",
                description="baseline: every pixel the most frequent training class (wall); "
                            "no windows")(PriorBaseline())
register_method("rowcol-prior", "label_set",
                description="baseline: most frequent training class at each normalised "
                            "(row, column) of a 32x32 grid")(RowColPrior())


class StructureMethod:
    """Müller et al. 2007 end to end (:func:`facadeforge.reconstruct`, no 3D model, its default
    path: elements detected by the shipped classifier — ``cmp6`` on rectified CMP, ``ecp7`` on
    street photos — structure the shape tree): windows
    are the shape tree's window leaves, labels its rasterised leaves (canonical labels), mapped
    back to the photo through the rectifying homography.  Rectified photos (CMP, synthetic
    facades without perspective: :func:`is_rectified`) skip rectification, as ``--rectified``
    does on the command line.  ``structure-edges`` is
    the paper's edge-only path (``--no-classifier``)."""

    def __init__(self, classifier: bool = True) -> None:
        self.classifier = classifier

    def __call__(self, sample: FacadeSample, label_set: LabelSet) -> Prediction:
        from ..reconstruction import reconstruct

        rec = reconstruct(sample.image(), model=False,
                          rectified=is_rectified(sample),
                          classifier=None if self.classifier else False)
        floors = rec.report["floors"]
        windows = np.array(rec.windows(frame="input"), np.float64).reshape(-1, 4)
        crop = rec.report.get("facade_crop")
        labels = rec.labels
        homography = rec.inverse
        if crop is not None:          # the rectified frame before the crop: background around
            x0, y0, x1, y1 = crop["box"]
            w0, h0 = crop["of"]
            labels = np.zeros((h0, w0), np.uint8)
            labels[y0:y1, x0:x1] = rec.labels
            homography = rec.inverse @ np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1.0]])
        from ..frames import warp_to_image

        return Prediction(labels=warp_to_image(labels, homography, sample.image_shape()),
                          windows=windows, floors=floors)


register_method("structure", "canonical",
                description="Müller 2007 with classifier-detected elements: floors, tiles and "
                            "refinements around them, element matching → shape tree"
                )(StructureMethod())
register_method("structure-edges", "canonical",
                description="Müller 2007 as published: repetition detection, edge-based tile "
                            "refinement, element matching → shape tree"
                )(StructureMethod(classifier=False))


class ClassifierMethod:
    """Baseline of ``simon2011`` §4.4.1: the pixel classifier alone, each pixel its most
    probable class (the shipped model of the dataset's label set, :func:`default_classifier`);
    with ``smoothness > 0``, the MRF-Potts segmentation of the same probabilities (eq. 4.14,
    alpha-expansion graph cuts).  The models are trained on the development train split, so
    ``fit`` does nothing; held-out data is scored with the same shipped models."""

    def __init__(self, smoothness: float = 0.0) -> None:
        self.smoothness = float(smoothness)

    def __call__(self, sample: FacadeSample, label_set: LabelSet) -> Prediction:
        from ..classify import default_classifier

        clf = default_classifier(label_set.name)
        if clf.classes != label_set.classes:
            raise InputError(f"the shipped {label_set.name} classifier's classes {clf.classes} "
                             f"differ from the label set's {label_set.classes}")
        prob = clf.predict_proba(sample.image())
        if self.smoothness > 0:
            from ..parsing.mrf import potts_labels

            return Prediction(labels=potts_labels(prob, self.smoothness))
        return Prediction(labels=np.argmax(prob, axis=2).astype(np.uint8))


register_method("classifier", "label_set",
                description="baseline (simon2011 §4.4.1): the shipped pixel classifier, "
                            "argmax per pixel")(ClassifierMethod())
register_method("mrf", "label_set",
                description="baseline (simon2011 §4.4.1): MRF-Potts (λ = 1) on the classifier's "
                            "probabilities, alpha-expansion")(ClassifierMethod(smoothness=1.0))


class GrammarMethod:
    """Grammar-driven parsing (``simon2011`` ch. 4–5, :func:`facadeforge.parsing.parse.parse`):
    the shipped classifier of the dataset's label set, the default parse grammar (``grid``)
    seeded from the classifier's window grid and fitted by ``search`` within ``budget`` derivations; labels are the derived
    layout mapped back to the photo (the classifier's labels outside the rectified facade).  Rectified
    photos (:func:`is_rectified`) are not rectified again, as ``--rectified`` says on the command
    line."""

    def __init__(self, search: str = "hill", budget: int | None = None) -> None:
        self.search = search
        self.budget = DEFAULT_BUDGET if budget is None else budget

    def __call__(self, sample: FacadeSample, label_set: LabelSet) -> Prediction:
        from ..classify import default_classifier
        from ..parsing.parse import parse

        result = parse(sample.image(), classifier=default_classifier(label_set.name),
                       method=self.search, budget=self.budget, model=False,
                       rectified=is_rectified(sample))
        return Prediction(labels=result.labels_input())


register_method("grammar-hill", "canonical",
                description="simon2011 §4.2: grid parse grammar fitted by hill "
                            f"climbing ({DEFAULT_BUDGET} derivations) to the shipped classifier"
                )(GrammarMethod())
register_method("grammar-evo", "canonical",
                description="simon2011 §5.2: grid parse grammar fitted by the "
                            f"evolutionary search ({DEFAULT_BUDGET} derivations)")(GrammarMethod("evolution"))
register_method("grammar", "canonical",
                description="grammar parsing, best default = grammar-evo: evolutionary search, "
                            f"{DEFAULT_BUDGET} derivations")(GrammarMethod("evolution"))


class MultiviewMethod:
    """``simon2011`` ch. 5: the photos to score, with their calibrated cameras (``cameras.txt``
    beside the split's ``img/`` folder), cut into runs of neighbouring views along the street
    (:data:`MULTIVIEW_GROUP` photos each, by camera position); each run reconstructed in 3D by
    :func:`facadeforge.multiview.multiview` (stereo, planes, the grid grammar fitted over all
    its views with E_a and E_d); each photo's labels are the 3D model's seen from its camera
    (the classifier's outside the model, as ``grammar`` does outside its facade)."""

    def __init__(self, budget: int | None = None, depth_energy: bool = True) -> None:
        self.budget = budget
        self.depth_energy = depth_energy
        self._labels: dict[str, np.ndarray] = {}
        self.reports: list[dict] = []

    def prepare(self, samples: Sequence[FacadeSample], label_set: LabelSet) -> None:
        from ..multiview.bench import reconstruct_groups

        self._labels, self.reports = reconstruct_groups(samples, budget=self.budget,
                                                        depth_energy=self.depth_energy)

    def __call__(self, sample: FacadeSample, label_set: LabelSet) -> Prediction:
        if sample.id not in self._labels:
            raise InputError(f"multiview: photo {sample.id} has no calibrated camera in its "
                             "split's cameras.txt, or was not prepared; give the split's "
                             "cameras beside its img/ folder")
        return Prediction(labels=self._labels[sample.id])


register_method("multiview", "canonical",
                description="simon2011 ch. 5: calibrated views → stereo cloud, planes, grid "
                            "grammar fitted in 3D over all views (E_a, E_d, SPEA-II)"
                )(MultiviewMethod())
register_method("multiview-appearance", "canonical",
                description="multiview with the appearance energy alone (the E_d ablation)"
                )(MultiviewMethod(depth_energy=False))
