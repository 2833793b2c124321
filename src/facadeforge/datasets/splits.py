"""Fixed development splits of the shared facade data, so numbers compare across sessions.

**CMP** (``../shared/data/cmp``, 300 rectified facades of many cities, one building each): sort
the ids (Python ``sorted``, code-point order of the photo file stems); the ids at positions 0,
5, 10, … are ``val`` (60), all others ``train`` (240), :data:`CMP_VAL_IDS`.  The same every-5th
rule (:func:`dev_split`) splits other folders of independent facades.

**RueMonge2014** (113 photos of one street, neighbouring photos show the same houses): split by
building (:func:`street_split`, :data:`SPLITS_DOC`).  Each photo's place along the street comes
from its calibrated camera (``train/cameras.txt``, :mod:`.cameras`): the stretch of facade it sees
is where its left and right frustum edges meet a facade plane :data:`STREET_DEPTH` away.  Photos
whose seen stretches overlap in a chain form a *run*; runs are separated by cross streets and
by the parts of the sequence that are not in the folder.  The shortest runs are ``val`` until
val holds :data:`VAL_SHARE` of the photos; a photo outside val whose stretch, widened by
:data:`STREET_GAP` at both ends, still meets a val photo's stretch is ``gap`` (in neither part;
``all`` has it); the rest are ``train``.  On the shared folder that gives 80 train, 5 gap and 28
val photos (:data:`RUEMONGE_VAL_IDS`, :data:`RUEMONGE_GAP_IDS`): three stretches of the street
(IMG_5757–5761, IMG_5771–5782 and IMG_5901–5927) whose buildings no training photo shows.

The splits before 2026-12-02 took every 5th RueMonge photo as val; those val photos showed the
buildings of training photos, and their figures were not held-out numbers (issue 24).  Tests
check that the rules reproduce the recorded id lists on the shared data.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from types import MappingProxyType
from typing import Any, TypeVar

from ..errors import InputError
from .cameras import Camera, seen_intervals

__all__ = ["CMP_VAL_IDS", "DEV_SPLITS", "RUEMONGE_GAP_IDS", "RUEMONGE_VAL_IDS", "SPLIT_NAMES",
           "SPLITS_DOC", "STREET_DEPTH", "STREET_GAP", "VAL_SHARE", "cmp_split", "dev_split",
           "ruemonge_split", "street_split"]

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

#: The 28 RueMonge validation ids :func:`street_split` gives on the shared ``train/`` folder.
RUEMONGE_VAL_IDS: tuple[str, ...] = (
    "IMG_5757", "IMG_5758", "IMG_5759", "IMG_5760", "IMG_5761", "IMG_5771", "IMG_5772",
    "IMG_5773", "IMG_5774", "IMG_5775", "IMG_5778", "IMG_5779", "IMG_5780", "IMG_5781",
    "IMG_5782", "IMG_5901", "IMG_5902", "IMG_5903", "IMG_5904", "IMG_5905", "IMG_5906",
    "IMG_5907", "IMG_5917", "IMG_5918", "IMG_5924", "IMG_5925", "IMG_5926", "IMG_5927",
)

#: The 5 shared RueMonge photos in neither part: they see buildings next to val's.
RUEMONGE_GAP_IDS: tuple[str, ...] = ("IMG_5748", "IMG_5749", "IMG_5750", "IMG_5751", "IMG_5796")

#: Distance of the facades from the camera path, in the units of the RueMonge reconstruction:
#: triangulated SIFT matches of neighbouring photos lie at a median depth of 3.46–3.64 at four
#: places along the street (10th–90th percentiles 3.0–4.0 on the plain stretches).
STREET_DEPTH: float = 4.0

#: How much further (same units, about a third of a building's width) a val photo's stretch
#: must stay from every train photo's.
STREET_GAP: float = 1.0

#: Least share of the photos that :func:`street_split` puts in val.
VAL_SHARE: float = 0.2

#: The written-down rule, ready to paste into ``benchmarks/README.md``.
SPLITS_DOC: str = f"""\
Development splits (facadeforge.datasets.splits); `all` is every photo.
- CMP (`../shared/data/cmp`, 300 facades, one building each): sort the ids (photo file stems,
  Python `sorted`); ids at positions 0, 5, 10, ... (every {VAL_EVERY}th) are `val`, the others
  `train`: 240 train / 60 val (val starts cmp_b0001, cmp_b0006, cmp_b0012, ... cmp_b0373).
  Folders of other independent facades get the same rule over their own ids.
- RueMonge2014 `train/` folder (113 photos of one street): split by building with the calibrated
  cameras (`train/cameras.txt`).  A photo sees the stretch of street between its frustum edges
  on a facade plane {STREET_DEPTH:g} units away; photos whose stretches overlap in a chain form a run;
  the shortest runs are `val` until val holds {VAL_SHARE:.0%} of the photos; other photos whose
  stretch, widened by {STREET_GAP:g} at both ends, meets a val stretch are `gap` (in neither part).
  80 train / 5 gap / 28 val: val is IMG_5757-5761, IMG_5771-5782 and IMG_5901-5927, gap
  IMG_5748-5751 and IMG_5796.  No training photo shows a val photo's buildings.  (Until
  2026-12-02 every 5th photo was val; those val photos showed training photos' buildings.)
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


def street_split(cameras: Mapping[str, Camera], ids: Iterable[str], *,
                 depth: float = STREET_DEPTH, gap: float = STREET_GAP,
                 val_share: float = VAL_SHARE) -> dict[str, str]:
    """Split photos of one street by building (the rule of the module docstring).

    Parameters
    ----------
    cameras : mapping id -> Camera
        Calibrated cameras (:func:`~.cameras.read_visualsfm`); sorted ids are consecutive
        viewpoints along the street.
    ids : iterable of str
        The photos to split; each needs a camera.

    Returns
    -------
    dict
        Photo id → ``"train"``, ``"val"`` or ``"gap"``.

    Raises
    ------
    InputError
        A photo without a camera, or fewer than two runs (a street seen as one unbroken run
        cannot be split by building).
    """
    ordered = sorted(set(ids))
    missing = [i for i in ordered if i not in cameras]
    if missing:
        raise InputError(f"street split: photos {missing[:5]} have no camera in the camera file; "
                         "every photo needs one (or split without cameras)")
    iv = seen_intervals([cameras[i] for i in ordered], depth)
    runs: list[list[int]] = []
    for k in range(len(ordered)):
        if runs and iv[k, 0] <= iv[k - 1, 1] and iv[k - 1, 0] <= iv[k, 1]:
            runs[-1].append(k)
        else:
            runs.append([k])
    if len(runs) < 2:
        raise InputError(f"street split: the {len(ordered)} photos see one unbroken stretch of "
                         "street; there is no building boundary to split them at")
    val: set[int] = set()
    for run in sorted(runs, key=len):              # stable: equal lengths in street order
        if len(val) >= val_share * len(ordered) or len(val) + len(run) == len(ordered):
            break
        val |= set(run)
    lo, hi = iv[:, 0] - gap, iv[:, 1] + gap
    vals = sorted(val)
    parts = {}
    for k, pid in enumerate(ordered):
        if k in val:
            parts[pid] = "val"
        elif any(lo[k] <= iv[j, 1] and iv[j, 0] <= hi[k] for j in vals):
            parts[pid] = "gap"
        else:
            parts[pid] = "train"
    return parts


def ruemonge_split(items: Iterable[T], split: str,
                   cameras: Mapping[str, Camera] | None = None) -> list[T]:
    """RueMonge development split by building (80 train / 28 val / 5 gap on the shared folder).

    Parameters
    ----------
    items : iterable of str or of samples with ``id``
        Photo ids (``"IMG_5717"`` …) or samples from :func:`~facadeforge.datasets.load_ruemonge`.
    split : {"train", "val", "all"}
    cameras : mapping id -> Camera, optional
        The photos' cameras (``train/cameras.txt``): the split is computed from them
        (:func:`street_split`).  Without them the recorded split of the shared folder is used
        (:data:`RUEMONGE_VAL_IDS`, :data:`RUEMONGE_GAP_IDS`); a folder with none of those ids
        has no development split: ``train`` and ``all`` are every photo, ``val`` none.

    Returns
    -------
    list
        Selected items, sorted by id.
    """
    if split not in SPLIT_NAMES:
        raise InputError(f"unknown split {split!r}; use one of {', '.join(SPLIT_NAMES)}")
    ordered = dev_split(items, "all")        # sorted, duplicates refused
    if split == "all":
        return ordered
    ids = [_item_id(item) for item in ordered]
    if cameras is not None:
        parts = street_split(cameras, ids)
    else:
        val, gap = set(RUEMONGE_VAL_IDS), set(RUEMONGE_GAP_IDS)
        parts = {i: "val" if i in val else "gap" if i in gap else "train" for i in ids}
    return [item for item, i in zip(ordered, ids) if parts[i] == split]


#: Development split function of each dataset, by the name ``facadeforge bench`` uses.
DEV_SPLITS: Mapping[str, Callable[[Iterable[Any], str], list[Any]]] = MappingProxyType(
    {"cmp": cmp_split, "ruemonge": ruemonge_split})
