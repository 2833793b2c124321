"""RueMonge2014 loader (Riemenschneider et al. 2014), Ecole Centrale Paris classes.

Layout::

    DIR/<split>/img/<id>.jpg           photo (street level, not rectified)
    DIR/<split>/label/<id>.png         8-bit class index: 0 unlabelled (ignored), 1 window,
                                       2 wall, 3 balcony, 4 door, 5 roof, 6 sky, 7 shop
    DIR/<split>/label_color/<id>.png   the same in colours (used only when label/ lacks the id)

``root`` may also be the split folder itself (the one holding ``img/``).  Objects are the
connected components of each class in the label map (4-connected), skipping components smaller
than 0.01 % of the photo.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .folder import FacadeSample, _check_folder, _list_photos, _unique_ids
from .labelsets import LABEL_SETS, LabelSet, convert, get_label_set

__all__ = ["load_ruemonge"]

_ECP7 = LABEL_SETS["ecp7"]


def _split_folder(root: Path, split: str) -> Path:
    if (root / split / "img").is_dir():
        return root / split
    if (root / "img").is_dir() and (split == root.name or not (root / split).exists()):
        return root
    found = sorted(p.name for p in root.iterdir() if (p / "img").is_dir()) if root.is_dir() else []
    hint = f"splits found: {', '.join(found)}" if found else "no <split>/img folders found"
    raise InputError(f"RueMonge folder {root} has no {split}/img folder ({hint}); pass the "
                     "dataset folder (with <split>/img and <split>/label) and a split it has")


def _decode(raw: np.ndarray, target: LabelSet) -> np.ndarray:
    index = _ECP7.from_color(raw) if raw.ndim == 3 else _ECP7.from_dataset(raw)
    return convert(index, _ECP7, target)


def load_ruemonge(root: str | Path, split: str = "train",
                  label_set: LabelSet | str = "ecp7") -> list[FacadeSample]:
    """Load a split of a folder in the RueMonge2014 layout.

    Parameters
    ----------
    root : str or Path
        Dataset folder holding ``<split>/img`` and ``<split>/label`` (e.g.
        ``../shared/data/ruemonge``), or the split folder itself.
    split : str
        Sub-folder to read (``"train"``, ``"val"``, ``"test"`` …).  The fixed development split
        of the shared train folder is :func:`facadeforge.datasets.splits.ruemonge_split`.
    label_set : LabelSet or str
        ``"ecp7"`` (default), or any set reached through canonical labels (``"cmp6"``: roof and
        sky → background).

    Returns
    -------
    list of FacadeSample
        Sorted by id.  ``labels()`` is ``(H, W)`` uint8 (id 0 → 255, ignored); ``objects()`` are
        connected components; ``meta`` has ``dataset``, ``split``, ``label_path``.

    Raises
    ------
    InputError
        Missing folder or split, no photos, a photo without a label, unknown label set.
    """
    target = get_label_set(label_set)
    root = _check_folder(root, "RueMonge", "pass the folder holding <split>/img and "
                         "<split>/label (e.g. --data ../shared/data/ruemonge)")
    base = _split_folder(root, split)
    photos = _list_photos(base / "img", (".jpg", ".jpeg", ".png"))
    if not photos:
        raise InputError(f"RueMonge folder {base / 'img'} has no photos (.jpg/.png); put the "
                         "split's photos there")
    _unique_ids(photos, f"RueMonge folder {base / 'img'}")

    def decode(raw: np.ndarray) -> np.ndarray:
        return _decode(raw, target)

    samples = []
    for photo in photos:
        label = base / "label" / f"{photo.stem}.png"
        if not label.is_file():
            label = base / "label_color" / f"{photo.stem}.png"
        if not label.is_file():
            raise InputError(f"RueMonge photo {photo} has no label "
                             f"({base / 'label' / (photo.stem + '.png')}); add it or move the "
                             "photo out of img/")
        samples.append(FacadeSample(
            id=photo.stem, image_path=photo, label_path=label, label_set=target,
            meta={"dataset": "ruemonge", "split": split, "label_path": str(label),
                  "objects_from": "components"},
            decode=decode))
    return samples
