"""Fixed development splits of the shared facade data, so numbers compare across sessions.

The rule (:data:`SPLITS_DOC`, also the text for ``benchmarks/README.md``): sort the sample ids
present with Python's ``sorted`` (code-point order of the id strings, i.e. the photo file stems);
the ids at positions 0, 5, 10, … (every 5th, starting with the first) are ``val``, all others are
``train``; ``all`` is every id.

- CMP (``../shared/data/cmp``, 300 facades ``cmp_b0001`` … ``cmp_b0378``): 240 train / 60 val,
  :data:`CMP_VAL_IDS`.
- RueMonge2014 ``train/`` folder (113 photos ``IMG_5717`` … ): 90 train / 23 val,
  :data:`RUEMONGE_VAL_IDS`.

The rule depends only on the sorted ids, so it is deterministic; it is applied to whatever ids a
folder holds, so a folder with other facades (held-out data) gets its own every-5th split — pass
``"all"`` to score every facade.  Tests check that the rule reproduces the recorded id lists on
the shared data.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from types import MappingProxyType
from typing import Any, TypeVar

from ..errors import InputError

__all__ = ["CMP_VAL_IDS", "DEV_SPLITS", "RUEMONGE_VAL_IDS", "SPLIT_NAMES", "SPLITS_DOC",
           "cmp_split", "dev_split", "ruemonge_split"]

T = TypeVar("T")

#: Split names every split function accepts.
SPLIT_NAMES: tuple[str, ...] = ("train", "val", "all")

#: Every ``VAL_EVERY``-th sorted id is a validation id.
VAL_EVERY: int = 5

#: The 60 CMP validation ids the rule gives on the shared 300 facades.
CMP_VAL_IDS: tuple[str, ...] = (
    "cmp_b0001", "cmp_b0006", "cmp_b0012", "cmp_b0017", "cmp_b0023", "cmp_b0028", "cmp_b0035",
    "cmp_b0040", "cmp_b0046", "cmp_b0051", "cmp_b0057", "cmp_b0062", "cmp_b0068", "cmp_b0075",
    "cmp_b0080", "cmp_b0085", "cmp_b0091", "cmp_b0099", "cmp_b0104", "cmp_b0110", "cmp_b0119",
    "cmp_b0125", "cmp_b0130", "cmp_b0138", "cmp_b0144", "cmp_b0150", "cmp_b0157", "cmp_b0162",
    "cmp_b0168", "cmp_b0175", "cmp_b0181", "cmp_b0187", "cmp_b0193", "cmp_b0200", "cmp_b0210",
    "cmp_b0216", "cmp_b0222", "cmp_b0229", "cmp_b0236", "cmp_b0241", "cmp_b0247", "cmp_b0252",
    "cmp_b0260", "cmp_b0267", "cmp_b0273", "cmp_b0279", "cmp_b0285", "cmp_b0293", "cmp_b0301",
    "cmp_b0308", "cmp_b0315", "cmp_b0323", "cmp_b0330", "cmp_b0335", "cmp_b0340", "cmp_b0347",
    "cmp_b0353", "cmp_b0359", "cmp_b0367", "cmp_b0373",
)

#: The 23 RueMonge validation ids the rule gives on the shared ``train/`` folder (113 photos).
RUEMONGE_VAL_IDS: tuple[str, ...] = (
    "IMG_5717", "IMG_5722", "IMG_5727", "IMG_5732", "IMG_5738", "IMG_5743", "IMG_5748",
    "IMG_5758", "IMG_5772", "IMG_5779", "IMG_5797", "IMG_5802", "IMG_5811", "IMG_5817",
    "IMG_5827", "IMG_5832", "IMG_5837", "IMG_5842", "IMG_5856", "IMG_5863", "IMG_5901",
    "IMG_5906", "IMG_5925",
)

#: The written-down rule, ready to paste into ``benchmarks/README.md``.
SPLITS_DOC: str = f"""\
Development splits (facadeforge.datasets.splits). Sort the sample ids present (photo file stems,
Python `sorted`, code-point order); ids at positions 0, 5, 10, ... (every {VAL_EVERY}th, starting with
the first) are `val`, all others `train`; `all` is every id.
- CMP (`../shared/data/cmp`, 300 facades): 240 train / 60 val (val starts cmp_b0001, cmp_b0006,
  cmp_b0012, ... cmp_b0373).
- RueMonge2014 `train/` folder (113 photos): 90 train / 23 val (val starts IMG_5717, IMG_5722,
  IMG_5727, ... IMG_5925).
Folders holding other ids get the same rule over their own sorted ids; use `all` to score every one.
"""


def _item_id(item: Any) -> str:
    return item if isinstance(item, str) else str(item.id)


def dev_split(items: Iterable[T], split: str, every: int = VAL_EVERY) -> list[T]:
    """The ``train``, ``val`` or ``all`` part of ``items`` by the every-5th rule.

    Parameters
    ----------
    items : iterable of str or of objects with an ``id`` (e.g. FacadeSample)
        Sample ids or samples, in any order.
    split : {"train", "val", "all"}
        Part to return.
    every : int
        Every ``every``-th sorted id (positions 0, every, 2 every, …) is ``val``.

    Returns
    -------
    list
        The selected items (same kind as given), sorted by id.

    Raises
    ------
    InputError
        Unknown split, or duplicate ids.
    """
    if split not in SPLIT_NAMES:
        raise InputError(f"unknown split {split!r}; use one of {', '.join(SPLIT_NAMES)}")
    ordered = sorted(items, key=_item_id)
    ids = [_item_id(item) for item in ordered]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise InputError(f"split: ids {dup[:5]} occur more than once; each sample needs a "
                         "unique id")
    if split == "all":
        return ordered
    want_val = split == "val"
    return [item for pos, item in enumerate(ordered) if (pos % every == 0) == want_val]


def cmp_split(items: Iterable[T], split: str) -> list[T]:
    """CMP development split (240 train / 60 val on the shared data; see :data:`SPLITS_DOC`).

    Parameters
    ----------
    items : iterable of str or of samples with ``id``
        CMP ids (``"cmp_b0001"`` …) or samples from :func:`~facadeforge.datasets.load_cmp`.
    split : {"train", "val", "all"}

    Returns
    -------
    list
        Selected items, sorted by id.
    """
    return dev_split(items, split)


def ruemonge_split(items: Iterable[T], split: str) -> list[T]:
    """RueMonge development split of the ``train/`` folder (90 / 23; see :data:`SPLITS_DOC`).

    Parameters
    ----------
    items : iterable of str or of samples with ``id``
        Photo ids (``"IMG_5717"`` …) or samples from :func:`~facadeforge.datasets.load_ruemonge`.
    split : {"train", "val", "all"}

    Returns
    -------
    list
        Selected items, sorted by id.
    """
    return dev_split(items, split)


#: Development split function of each dataset, by the name ``facadeforge bench`` uses.
DEV_SPLITS: Mapping[str, Callable[[Iterable[Any], str], list[Any]]] = MappingProxyType(
    {"cmp": cmp_split, "ruemonge": ruemonge_split})
