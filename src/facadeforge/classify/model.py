"""Pixel classifiers: the common interface, and one safe file format for all of them.

A pixel classifier gives every pixel of a facade photo a probability per class — the *image
support* of grammar-driven parsing (``simon2011`` §4.2.1, eq. 4.4).  Every kind (the randomised
forest of §4.3.1, the scribble GMM of §4.3.2, the auto-context forest, the convnet, an
ensemble) implements :class:`PixelClassifier`'s ``predict_proba_coarse(image) -> (h, w, K)
float32`` at the scale it works at (the photo's aspect ratio), and gets ``predict_proba(image)
-> (H, W, K)`` in the photo's own pixel frame from it; rows sum to one, and ``classes`` names
the K channels by canonical label (:class:`~facadeforge.model.Labels`) in the order of the label
set it was trained in.

File format (``.npz``, written by :func:`save_classifier`, read by :func:`load_classifier`): plain
numeric arrays plus one JSON document in the array ``__meta__`` (kind, classes, label set, how the
model was trained).  It is read with ``allow_pickle=False``: a model file holds numbers and text,
never code, so loading one from a stranger executes nothing.  Nor can one exhaust memory: every
array's ``.npy`` header (shape and type) is read before any data, and a file declaring more than
:data:`MAX_CLASSIFIER_ARRAY_BYTES` in all is refused (a 7 MB file can hold a 4 GiB array of
zeros).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import zipfile
import zlib
from abc import ABC, abstractmethod
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..errors import InputError

__all__ = ["CLASSIFIER_KINDS", "ClassifierFileError", "PixelClassifier", "load_classifier",
           "register_kind", "save_classifier"]

FORMAT_VERSION = 1

#: Most bytes of array data a classifier file may hold, all arrays together.  The shipped models
#: hold 2.0 (convnet-cmp12) to 9.4 MB (autocontext-cmp6, three stages of ten trees); 512 MiB,
#: some 50 times that, leaves room for forests of hundreds of trees, and bounds what loading
#: a file can cost in memory.
MAX_CLASSIFIER_ARRAY_BYTES = 512 * 2**20

#: Most arrays a classifier file may hold (the shipped ensemble: 85).
MAX_CLASSIFIER_ARRAYS = 4096

_RETRAIN = "train one with 'facadeforge train-classifier'"


class ClassifierFileError(InputError, ValueError):
    """A classifier file is missing, not a facadeforge model, or of an unknown kind/version."""


class PixelClassifier(ABC):
    """Per-pixel class probabilities for a facade photo.

    Attributes
    ----------
    kind : str
        Registry key of the implementation (``forest``, ``autocontext``, ``gmm``).
    classes : tuple of str
        Canonical label of each output channel.
    label_set : str
        Name of the label set the classes come from (``cmp6``, ``ecp7``, or ``scribbles``).
    meta : dict
        JSON-able provenance: training data, ids, command, date, parameters.
    """

    kind: ClassVar[str] = ""

    def __init__(self, classes: tuple[str, ...], label_set: str, meta: Mapping[str, Any] | None):
        self.classes = tuple(classes)
        self.label_set = str(label_set)
        self.meta = dict(meta or {})

    @property
    def num_classes(self) -> int:
        return len(self.classes)

    @abstractmethod
    def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
        """Class probabilities of an ``(H, W, 3)`` uint8 RGB photo at the scale the classifier
        works at: ``(h, w, K)`` float32 of the photo's aspect ratio (the analysis scale for the
        forests and networks, the photo's own for a GMM).  Callers that shrink them again
        (grammar parsing scores layouts on 256 pixels) skip the resize of K full-resolution
        channels."""

    def predict_proba(self, image: np.ndarray) -> np.ndarray:
        """``(H, W, K)`` float32 class probabilities in the photo's own pixel frame."""
        from .features import resize_proba

        p = self.predict_proba_coarse(image)
        return p if p.shape[:2] == image.shape[:2] else resize_proba(p, image.shape[:2])

    def predict(self, image: np.ndarray) -> np.ndarray:
        """``(H, W)`` uint8 most probable class index (classifier-only labelling)."""
        return np.argmax(self.predict_proba(image), axis=2).astype(np.uint8)

    @abstractmethod
    def to_arrays(self) -> dict[str, np.ndarray]:
        """The model's parameters as named numeric arrays (see the module docstring)."""

    @classmethod
    @abstractmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], classes: tuple[str, ...],
                    label_set: str, meta: Mapping[str, Any]) -> PixelClassifier:
        """Rebuild a classifier from :meth:`to_arrays` output."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(classes={self.classes!r}, label_set={self.label_set!r})"


#: Classifier implementations by kind.
CLASSIFIER_KINDS: dict[str, type[PixelClassifier]] = {}


def register_kind(cls: type[PixelClassifier]) -> type[PixelClassifier]:
    """Class decorator adding ``cls`` to :data:`CLASSIFIER_KINDS` under ``cls.kind``."""
    if not cls.kind:
        raise TypeError(f"{cls.__name__} has no kind")
    CLASSIFIER_KINDS[cls.kind] = cls
    return cls


def save_classifier(clf: PixelClassifier, path: str | Path) -> Path:
    """Write ``clf`` to ``path`` (``.npz``) atomically: a temporary file in the same folder is
    renamed into place, so a failed write never leaves a half-written model."""
    path = Path(path)
    if path.suffix != ".npz":
        raise InputError(f"classifier output {path}: use a .npz file name")
    if not path.parent.is_dir():
        raise InputError(f"classifier output {path}: folder {path.parent} does not exist; "
                         "create it first")
    meta = {"format": "facadeforge-classifier", "version": FORMAT_VERSION, "kind": clf.kind,
            "classes": list(clf.classes), "label_set": clf.label_set, "meta": clf.meta}
    arrays = clf.to_arrays()
    if "__meta__" in arrays:
        raise ValueError("array name __meta__ is reserved")
    blob = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".npz", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, __meta__=blob, **arrays)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; a model file is for sharing
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load_classifier(path: str | Path) -> PixelClassifier:
    """Read a classifier written by :func:`save_classifier` (no pickle, see module docstring).

    Raises
    ------
    ClassifierFileError
        Missing file, not an ``.npz`` facadeforge model, unknown kind or newer format version.
    """
    path = Path(path)
    if not path.is_file():
        raise ClassifierFileError(f"classifier {path}: no such file; train one with "
                                  "'facadeforge train-classifier' or omit --classifier")
    arrays = _read_arrays(path)
    from ..jsonfile import parse_json

    try:
        text = arrays.pop("__meta__").tobytes().decode()
        meta = parse_json(text, f"classifier {path}: its metadata", fix=_RETRAIN,
                          error=ClassifierFileError)
        if not isinstance(meta, dict):
            raise ValueError("metadata is not an object")
        version = int(meta.get("version", 0))
    except (ValueError, KeyError, TypeError, OverflowError, UnicodeDecodeError) as exc:
        if isinstance(exc, ClassifierFileError):
            raise
        raise ClassifierFileError(f"classifier {path}: not a facadeforge classifier file "
                                  f"({exc.__class__.__name__}); {_RETRAIN}") from None
    if meta.get("format") != "facadeforge-classifier":
        raise ClassifierFileError(f"classifier {path}: not a facadeforge classifier file")
    if version > FORMAT_VERSION:
        raise ClassifierFileError(f"classifier {path}: format version {meta.get('version')} is "
                                  f"newer than this facadeforge reads ({FORMAT_VERSION}); "
                                  "upgrade facadeforge")
    kind = meta.get("kind")
    _load_kinds(kind)
    if kind not in CLASSIFIER_KINDS:
        raise ClassifierFileError(f"classifier {path}: unknown kind {kind!r}; this facadeforge "
                                  f"reads {', '.join(sorted(CLASSIFIER_KINDS))}")
    try:
        classes = tuple(str(c) for c in meta["classes"])
        return CLASSIFIER_KINDS[kind].from_arrays(arrays, classes, str(meta["label_set"]),
                                                  meta.get("meta", {}))
    except (KeyError, ValueError, TypeError, IndexError, OverflowError, MemoryError,
            InputError) as exc:
        raise ClassifierFileError(f"classifier {path}: damaged or inconsistent model file "
                                  f"({exc}); train it again with 'facadeforge "
                                  "train-classifier'") from None


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` file ``path`` by name, read only after every array's ``.npy``
    header has been checked: numeric types only (no objects: no pickles, no strings) and no more
    than :data:`MAX_CLASSIFIER_ARRAY_BYTES` of data in all.  ``np.load`` would allocate what a
    header declares before reading it.

    Raises
    ------
    ClassifierFileError
        Not a zip of ``.npy`` arrays (empty, truncated, damaged), too many or too big arrays,
        or arrays of a type a model never holds.
    """
    from numpy.lib import format as npy

    def refuse(problem: str) -> ClassifierFileError:
        return ClassifierFileError(f"classifier {path}: {problem}; {_RETRAIN}")

    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
            if len(infos) > MAX_CLASSIFIER_ARRAYS:
                raise refuse(f"{len(infos)} arrays, more than the {MAX_CLASSIFIER_ARRAYS} a "
                             "model file may hold")
            total = 0
            for info in infos:
                if not info.filename.endswith(".npy"):
                    raise refuse(f"member {info.filename!r} is not a .npy array")
                with zf.open(info) as f:
                    version = npy.read_magic(f)
                    if version == (1, 0):
                        shape, _, dtype = npy.read_array_header_1_0(f)
                    elif version == (2, 0):
                        shape, _, dtype = npy.read_array_header_2_0(f)
                    else:  # 3.0 is for non-Latin-1 field names: a model has no fields
                        raise refuse(f"array {info.filename!r} is in .npy format {version}")
                if dtype.hasobject or dtype.kind not in "biuf":
                    raise refuse(f"array {info.filename!r} holds {dtype} values, not numbers")
                if any(n < 0 for n in shape):
                    raise refuse(f"array {info.filename!r} has the shape {shape}")
                total += math.prod(shape) * dtype.itemsize
                if total > MAX_CLASSIFIER_ARRAY_BYTES:
                    raise refuse(f"its arrays hold more than {MAX_CLASSIFIER_ARRAY_BYTES >> 20} "
                                 "MiB (the most a model file may hold)")
            arrays = {}
            for info in infos:
                with zf.open(info) as f:
                    arrays[info.filename[:-len(".npy")]] = npy.read_array(f, allow_pickle=False)
            return arrays
    except ClassifierFileError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, OSError, ValueError, zlib.error,
            NotImplementedError, RuntimeError, OverflowError, MemoryError) as exc:
        # damaged zip structure or compressed data, a member cut short (ValueError "EOF"),
        # an unsupported compression method or an encrypted member (NotImplementedError,
        # RuntimeError), a malformed .npy header (ValueError)
        raise refuse(f"not a facadeforge classifier file, or a damaged one "
                     f"({exc.__class__.__name__}: {exc})") from None


#: The module implementing each kind (imported on demand: the forests need numba, whose import
#: alone takes 1.4–1.8 s, which a command using a network should not pay).
_KIND_MODULES: dict[str, str] = {"forest": "forest", "autocontext": "autocontext",
                                 "convnet": "convnet", "ensemble": "ensemble", "gmm": "gmm"}


def _load_kinds(kind: object = None) -> None:
    """Import the implementation of ``kind`` (every one when it is not a known kind) so that it
    registers itself."""
    import importlib

    known = isinstance(kind, str) and kind in _KIND_MODULES
    names = [_KIND_MODULES[kind]] if known else list(_KIND_MODULES.values())
    for name in names:
        importlib.import_module(f"{__package__}.{name}")
