"""Pixel classifiers for grammar-driven parsing (``simon2011`` §4.3) and their shipped models.

- :mod:`.forest` — the randomised forest on patch tests of §4.3.1;
- :mod:`.gmm` — Gaussian mixtures trained from a user's scribbles, §4.3.2;
- :mod:`.autocontext` — auto-context forests, the stronger classifier trained here;
- :mod:`.train` — training from a dataset and ``facadeforge train-classifier``;
- :mod:`.model` — the common interface and the pickle-free ``.npz`` file format.

Shipped models (``facadeforge/data/classifiers``), trained on the development train splits of
the shared data (the exact commands are in their metadata and in README.md):
``autocontext-cmp6.npz`` and ``autocontext-ecp7.npz``.
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

__all__ = ["CLASSIFIER_KINDS", "MODEL_DIR", "ClassifierFileError", "PixelClassifier",
           "default_classifier", "default_label_set", "load_classifier", "resolve_classifier",
           "save_classifier", "shipped_model_path"]

#: Folder of the shipped models.
MODEL_DIR = Path(__file__).resolve().parent.parent / "data" / "classifiers"

_LOADED: dict[str, PixelClassifier] = {}


def shipped_model_path(label_set: str) -> Path:
    """Path of the shipped auto-context model for ``label_set`` (``cmp6`` or ``ecp7``)."""
    return MODEL_DIR / f"autocontext-{label_set}.npz"


def default_classifier(label_set: str) -> PixelClassifier:
    """The shipped classifier for ``label_set``, loaded once per process."""
    if label_set not in _LOADED:
        path = shipped_model_path(label_set)
        if not path.is_file():
            shipped = sorted(p.stem.split("-", 1)[1] for p in MODEL_DIR.glob("autocontext-*.npz"))
            raise InputError(f"no shipped classifier for label set {label_set!r} (shipped: "
                             f"{', '.join(shipped) or 'none'}); train one with 'facadeforge "
                             "train-classifier' and pass it with --classifier")
        _LOADED[label_set] = load_classifier(path)
    return _LOADED[label_set]


def default_label_set(rectified: bool) -> str:
    """The shipped model ``parse`` and ``reconstruct`` use when none is given: ``cmp6``
    (trained on rectified facades of many cities, CMP) for photos given as rectified, ``ecp7``
    (trained on Parisian street photos, RueMonge) for street photos.  On the RueMonge
    validation photos ``reconstruct`` scores window F1 0.54 with ``ecp7`` against 0.17 with
    ``cmp6``, whose windows take in the railings in front of them."""
    return "cmp6" if rectified else "ecp7"


def resolve_classifier(classifier, label_set: str) -> PixelClassifier:
    """A classifier given as a model, a model file path, or ``None`` (the shipped model of
    ``label_set``)."""
    if isinstance(classifier, PixelClassifier):
        return classifier
    if classifier is None:
        return default_classifier(label_set)
    return load_classifier(classifier)
