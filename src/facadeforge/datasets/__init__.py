"""Facade datasets: loaders, label sets and fixed development splits.

Loaders return lists of :class:`FacadeSample` (lazy photo, class-index map, object rectangles),
sorted by id:

>>> from facadeforge.datasets import load_cmp, cmp_split          # doctest: +SKIP
>>> val = cmp_split(load_cmp("../shared/data/cmp", label_set="cmp6"), "val")
>>> val[0].image().shape, val[0].labels().dtype                    # (H, W, 3), uint8

Label maps are ``(H, W)`` uint8 class indices of a :class:`LabelSet` (``cmp12``, ``cmp6``,
``ecp7``, ``lmf9`` or a ``palette.json`` set), with :data:`IGNORE` (255) where not scored.
Predictions in canonical labels are scored in any set with :meth:`LabelSet.from_canonical`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from ..errors import InputError
from .cmp import load_cmp, read_cmp_xml
from .folder import (
    IMAGE_SUFFIXES,
    FacadeSample,
    ObjectBox,
    load_folder,
    load_palette,
    objects_from_labels,
    palette_label_set,
    read_image,
    read_label_image,
)
from .labelmefacade import LABELMEFACADE_SPLITS, load_labelmefacade
from .labelsets import (
    CANONICAL_FALLBACK,
    CANONICAL_INDEX,
    IGNORE,
    LABEL_SETS,
    LabelSet,
    convert,
    get_label_set,
)
from .ruemonge import load_ruemonge
from .splits import (
    CMP_VAL_IDS,
    DEV_SPLITS,
    RUEMONGE_VAL_IDS,
    SPLIT_NAMES,
    SPLITS_DOC,
    cmp_split,
    dev_split,
    ruemonge_split,
)
from .synthetic import load_synthetic

__all__ = [
    "CANONICAL_FALLBACK", "CANONICAL_INDEX", "CMP_VAL_IDS", "DEFAULT_LABEL_SETS", "DEV_SPLITS",
    "IGNORE", "IMAGE_SUFFIXES", "LABELMEFACADE_SPLITS", "LABEL_SETS", "LOADERS",
    "RUEMONGE_VAL_IDS", "SPLITS_DOC", "SPLIT_NAMES", "FacadeSample", "LabelSet", "ObjectBox",
    "cmp_split", "convert", "dev_split", "get_label_set", "load_cmp", "load_dataset",
    "load_folder", "load_labelmefacade", "load_palette", "load_ruemonge", "load_synthetic",
    "objects_from_labels", "palette_label_set", "read_cmp_xml", "read_image", "read_label_image",
    "ruemonge_split",
]

#: Loader of each dataset layout: ``LOADERS[name](root, **options) -> list[FacadeSample]``.
LOADERS: Mapping[str, Callable[..., list[FacadeSample]]] = MappingProxyType({
    "cmp": load_cmp,
    "ruemonge": load_ruemonge,
    "labelmefacade": load_labelmefacade,
    "folder": load_folder,
    "synthetic": load_synthetic,
})

#: Label set each layout is scored in by default.
DEFAULT_LABEL_SETS: Mapping[str, str | None] = MappingProxyType({
    "cmp": "cmp6", "ruemonge": "ecp7", "labelmefacade": "lmf9", "folder": None,
    "synthetic": "cmp6"})


def load_dataset(name: str, root: str | Path, **options: Any) -> list[FacadeSample]:
    """Load a dataset folder with the loader registered as ``name``.

    Parameters
    ----------
    name : {"cmp", "ruemonge", "labelmefacade", "folder", "synthetic"}
        Layout (:data:`LOADERS`).
    root : str or Path
        Dataset folder.
    **options
        Passed to the loader (``label_set=``, ``split=`` for RueMonge and LabelMeFacade,
        ``palette=``…).

    Returns
    -------
    list of FacadeSample

    Raises
    ------
    InputError
        Unknown layout name, or any loader error.
    """
    try:
        loader = LOADERS[name]
    except KeyError:
        raise InputError(f"unknown dataset layout {name!r}; use one of "
                         f"{', '.join(LOADERS)}") from None
    return loader(root, **options)
