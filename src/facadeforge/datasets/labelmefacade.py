"""LabelMeFacade loader (Fröhlich, Rodner & Denzler, ICPR 2010), street photos with occluders.

Layout::

    DIR/images/<name>.jpg     photo (street level, not rectified)
    DIR/labels/<name>.png     colour label, RGB or RGBA (alpha ignored), in the ``lmf9`` palette:
                              various 0:0:0, building 128:0:0, car 128:0:128, door 128:128:0,
                              pavement 128:128:128, road 128:64:0, sky 0:128:128,
                              vegetation 0:128:0, window 0:0:128
    DIR/train.txt             the training images, one name per line
    DIR/test.txt              the test images

Names in the split files are photo names without extension; names may hold dots
(``…img-10.21op9-p-015t000``).  A folder or an image extension on a line (``images/x.jpg``) is
tolerated, blank lines and lines starting with ``#`` are skipped.  Photos may also be ``.jpeg``
or ``.png``.

Label pixels in colours outside the palette (anti-aliased edges, a re-encoded JPEG label) are
ignored (:data:`~facadeforge.datasets.labelsets.IGNORE`); the sample's
``meta["unknown_color_pixels"]`` counts them once its labels are read, and the first label of a
load that has any raises one :class:`UserWarning`.  Objects are the connected components of each
class (4-connected, as RueMonge), skipping components smaller than 0.01 % of the photo.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import InputError
from .folder import FacadeSample, _check_folder, _list_photos, _unique_ids
from .labelsets import IGNORE, LABEL_SETS, LabelSet, convert, get_label_set

__all__ = ["LABELMEFACADE_SPLITS", "load_labelmefacade", "read_split_file"]

_LMF9 = LABEL_SETS["lmf9"]

#: Splits :func:`load_labelmefacade` reads: a split file each, or every labelled photo.
LABELMEFACADE_SPLITS: tuple[str, ...] = ("train", "test", "all")

_PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png")
_FIX = ("pass the folder holding images/, labels/, train.txt and test.txt "
        "(e.g. --data ../shared/data/labelmefacade)")


def read_split_file(path: str | Path) -> list[str]:
    """Photo names listed in a LabelMeFacade split file, in file order, without duplicates.

    Parameters
    ----------
    path : str or Path
        ``train.txt`` or ``test.txt``: one name per line.

    Returns
    -------
    list of str
        Names without folder and without an image extension (``.jpg .jpeg .png``).

    Raises
    ------
    InputError
        The file is missing, unreadable or not UTF-8 text.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"LabelMeFacade split file {path} does not exist; {_FIX}, or use "
                         "--split all to score every labelled photo")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"LabelMeFacade split file {path} cannot be read ({exc}); it must be "
                         "UTF-8 text, one photo name per line") from exc
    names: dict[str, None] = {}
    for line in text.splitlines():
        name = line.strip().replace("\\", "/").rsplit("/", 1)[-1]
        if not name or name.startswith("#"):
            continue
        if Path(name).suffix.lower() in _PHOTO_SUFFIXES:
            name = name[:-len(Path(name).suffix)]
        names.setdefault(name, None)
    return list(names)


def _photo_of(images: Path, name: str) -> Path | None:
    for suffix in _PHOTO_SUFFIXES + tuple(s.upper() for s in _PHOTO_SUFFIXES):
        p = images / f"{name}{suffix}"
        if p.is_file():
            return p
    return None


def _label_of(labels: Path, name: str) -> Path | None:
    for suffix in (".png", ".PNG"):
        p = labels / f"{name}{suffix}"
        if p.is_file():
            return p
    return None


def load_labelmefacade(root: str | Path, split: str = "all",
                       label_set: LabelSet | str = "lmf9") -> list[FacadeSample]:
    """Load a split of a folder in the LabelMeFacade layout (module docstring).

    Parameters
    ----------
    root : str or Path
        Dataset folder holding ``images/``, ``labels/``, ``train.txt`` and ``test.txt`` (e.g.
        ``../shared/data/labelmefacade``).
    split : {"all", "train", "test"}
        ``train`` / ``test``: the photos listed in ``train.txt`` / ``test.txt``; ``all`` (default):
        every photo in ``images/`` that has a label (photos without one are skipped).
    label_set : LabelSet or str
        ``"lmf9"`` (default), or any set reached through canonical labels (``"cmp6"``: car,
        pavement, road, sky, vegetation and various → background).

    Returns
    -------
    list of FacadeSample
        Sorted by id (the photo's name).  ``labels()`` is ``(H, W)`` uint8, 255 where the colour
        is not in the palette; ``objects()`` are connected components; ``meta`` has
        ``dataset``, ``split``, ``label_path``, ``objects_from`` and, once labels are read,
        ``unknown_color_pixels``.

    Raises
    ------
    InputError
        Missing folder, split file, photo or label of a listed name; an unknown split or label
        set; no labelled photos; a single-channel label image (labels are colour PNGs).
    """
    target = get_label_set(label_set)
    if split not in LABELMEFACADE_SPLITS:
        hint = " (LabelMeFacade has no val split; score the test split)" if split == "val" else ""
        raise InputError(f"unknown LabelMeFacade split {split!r}{hint}; use one of "
                         f"{', '.join(LABELMEFACADE_SPLITS)}")
    root = _check_folder(root, "LabelMeFacade", _FIX)
    images, labels = root / "images", root / "labels"
    for folder in (images, labels):
        if not folder.is_dir():
            raise InputError(f"LabelMeFacade folder {root} has no {folder.name}/ folder; {_FIX}")

    pairs: list[tuple[Path, Path]] = []
    if split == "all":
        photos = _list_photos(images, _PHOTO_SUFFIXES)
        _unique_ids(photos, f"LabelMeFacade folder {images}")
        for photo in photos:
            label = _label_of(labels, photo.stem)
            if label is not None:
                pairs.append((photo, label))
        if not pairs:
            raise InputError(f"LabelMeFacade folder {root} has no photo in images/ with a label "
                             f"labels/<name>.png ({len(photos)} photos); {_FIX}")
    else:
        split_file = root / f"{split}.txt"
        names = read_split_file(split_file)
        if not names:
            raise InputError(f"LabelMeFacade split file {split_file} lists no photos; put one "
                             "photo name per line")
        missing_photo, missing_label = [], []
        for name in names:
            photo = _photo_of(images, name)
            label = _label_of(labels, name)
            if photo is None:
                missing_photo.append(name)
            elif label is None:
                missing_label.append(name)
            else:
                pairs.append((photo, label))
        for missing, where, what in ((missing_photo, images, ".jpg"),
                                     (missing_label, labels, ".png")):
            if missing:
                shown = ", ".join(missing[:3]) + (f" and {len(missing) - 3} more"
                                                  if len(missing) > 3 else "")
                raise InputError(
                    f"LabelMeFacade split file {split_file} lists {len(missing)} of "
                    f"{len(names)} names without {where}/<name>{what}: {shown}; add the files "
                    f"or remove the names from {split_file.name}")
        pairs.sort(key=lambda pair: pair[0].stem)

    warned = [False]

    def make_decode(meta: dict):
        def decode(raw: np.ndarray) -> np.ndarray:
            if raw.ndim != 3:
                raise InputError(
                    f"LabelMeFacade label {meta['label_path']} is a single-channel image; "
                    "labels must be colour PNGs (RGB or RGBA) in the LabelMeFacade palette")
            index = _LMF9.from_color(raw)
            unknown = int(np.count_nonzero(index == IGNORE))
            meta["unknown_color_pixels"] = unknown
            if unknown and not warned[0]:
                warned[0] = True
                bad = np.unique(raw[index == IGNORE].reshape(-1, 3), axis=0)[:3].tolist()
                warnings.warn(
                    f"LabelMeFacade label {meta['label_path']}: {unknown} pixels "
                    f"({100 * unknown / index.size:.2g} %) have colours outside the lmf9 "
                    f"palette (e.g. {bad}); they are ignored (not scored). Further labels of "
                    "this folder are not reported; see sample.meta['unknown_color_pixels']",
                    UserWarning, stacklevel=2)
            return convert(index, _LMF9, target)
        return decode

    samples = []
    for photo, label in pairs:
        meta = {"dataset": "labelmefacade", "split": split, "label_path": str(label),
                "objects_from": "components"}
        samples.append(FacadeSample(
            id=photo.stem, image_path=photo, label_path=label, label_set=target, meta=meta,
            decode=make_decode(meta), label_as_color=True))
    return samples
