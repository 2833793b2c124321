"""Pixel classifiers for grammar-driven parsing (``simon2011`` §4.3) and their shipped models.

- :mod:`.forest` — the randomised forest on patch tests of §4.3.1;
- :mod:`.gmm` — Gaussian mixtures trained from a user's scribbles, §4.3.2;
- :mod:`.autocontext` — auto-context forests, a stronger forest classifier trained here;
- :mod:`.convnet` — a small facade U-Net trained here (:mod:`.convnet_train`, needs PyTorch)
  and evaluated with numpy;
- :mod:`.ensemble` — several classifiers averaged in one label set (the ``cmp6`` default);
- :mod:`.train` — training from a dataset and ``facadeforge train-classifier``;
- :mod:`.model` — the common interface and the pickle-free ``.npz`` file format.

Shipped models (``facadeforge/data/classifiers``, ``KIND-LABELSET.npz``), trained on the
development train splits of the shared data (the exact commands are in their metadata and in
README.md).  The default classifier of a label set is the model :data:`PROJECTED` names for it
when that is shipped — the street network, trained on every labelled dataset at once, with its
probabilities summed into the label set's classes — else the first shipped kind of
:data:`SHIPPED_KINDS`.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from .model import (
    CLASSIFIER_KINDS,
    ClassifierFileError,
    PixelClassifier,
    load_classifier,
    save_classifier,
)

__all__ = ["CLASSIFIER_KINDS", "MODEL_DIR", "PROJECTED", "SHIPPED_KINDS", "ClassifierFileError",
           "PixelClassifier", "default_classifier", "default_label_set", "load_classifier",
           "resolve_classifier", "save_classifier", "shipped_model_path"]

#: Folder of the shipped models.
MODEL_DIR = Path(__file__).resolve().parent.parent / "data" / "classifiers"

#: Kinds of shipped models, best first (CMP val mIoU: ``benchmarks/results/classifiers.json``).
SHIPPED_KINDS: tuple[str, ...] = ("ensemble", "convnet", "autocontext")

#: Label sets served by a shipped model of other classes, projected onto theirs
#: (:meth:`~facadeforge.datasets.LabelSet.project_proba`), when no model of their own is
#: shipped.  The street network ``street12`` (RueMonge, CMP and LabelMeFacade at once,
#: :mod:`.street`) knows LabelMeFacade's classes (lmf9); the auto-context forest trained on
#: LabelMeFacade and synthetic facades (``autocontext-lmf9``) is shipped and served first,
#: and the network serves no other set either: on LabelMeFacade test and on the RueMonge val
#: photos the forests score higher (``benchmarks/results/bench_classifier_*.json``).
PROJECTED: dict[str, str] = {"lmf9": "convnet-street12"}

_LOADED: dict[tuple[str, str | None], PixelClassifier] = {}


def shipped_model_path(label_set: str, kind: str | None = None) -> Path:
    """Path of the shipped model of ``kind`` for ``label_set`` (``cmp6`` or ``ecp7``); without
    ``kind``, of the first kind in :data:`SHIPPED_KINDS` shipped for it (the path may not exist
    when none is)."""
    kinds = (kind,) if kind else SHIPPED_KINDS
    for k in kinds:
        path = MODEL_DIR / f"{k}-{label_set}.npz"
        if path.is_file():
            return path
    return MODEL_DIR / f"{kinds[-1]}-{label_set}.npz"


def default_classifier(label_set: str, kind: str | None = None) -> PixelClassifier:
    """The shipped classifier for ``label_set`` (of ``kind``, else the best shipped), loaded
    once per process."""
    key = (label_set, kind)
    projected = MODEL_DIR / f"{PROJECTED.get(label_set, '')}.npz"
    if (key not in _LOADED and kind is None and label_set in PROJECTED and projected.is_file()
            and not shipped_model_path(label_set).is_file()):
        from .ensemble import EnsembleClassifier

        _LOADED[key] = EnsembleClassifier([load_classifier(projected)], label_set,
                                          {"projected_from": projected.name})
    if key not in _LOADED:
        path = shipped_model_path(label_set, kind)
        if not path.is_file():
            shipped = sorted(p.stem for p in MODEL_DIR.glob("*.npz"))
            raise InputError(f"no shipped {kind + ' ' if kind else ''}classifier for label set "
                             f"{label_set!r} "
                             f"(shipped: {', '.join(shipped) or 'none'}); train one with "
                             "'facadeforge train-classifier' and pass it with --classifier")
        _LOADED[key] = load_classifier(path)
    return _LOADED[key]


def default_label_set(rectified: bool, elements: bool = False) -> str:
    """The shipped model ``parse`` and ``reconstruct`` use when none is given: ``cmp6``
    (trained on rectified facades of many cities, CMP) for photos given as rectified, ``ecp7``
    (trained on Parisian street photos, RueMonge) for street photos: it knows roof and sky, and
    labels railings balcony as RueMonge does; the choice stands on the classes a street
    photo shows, not on the windows alone.

    ``elements``: for element detection (``reconstruct``), rectified photos get CMP's twelve
    classes (``cmp12``), in which a window's glass is apart from its shutters and sills (the
    ``cmp6`` windows take in their shutters).  How each choice scored:
    ``docs/design-measurements.md``."""
    if rectified:
        return "cmp12" if elements else "cmp6"
    return "ecp7"


def resolve_classifier(classifier, label_set: str) -> PixelClassifier:
    """A classifier given as a model, a model file path, or ``None`` (the shipped model of
    ``label_set``)."""
    if isinstance(classifier, PixelClassifier):
        return classifier
    if classifier is None:
        return default_classifier(label_set)
    return load_classifier(classifier)
