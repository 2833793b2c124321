"""CMP Facade Database loader (Tyleček & Šára, GCPR 2013).

Layout: one folder of ``<id>.jpg`` photo, ``<id>.png`` label and ``<id>.xml`` objects per facade
(``cmp_b0001.jpg/.png/.xml`` …); other files (``label_names.txt``, ``readme.txt``) are ignored.

- The label PNG is a palette image whose pixel *index* is the CMP class id 1–12 (see
  :data:`~facadeforge.datasets.labelsets.LABEL_SETS` ``cmp12``); an RGB label image in the CMP
  colours is accepted too.
- The XML holds one ``<object>`` per rectangle, with no root element and ``\\r`` line breaks::

      <object><points><x>0.104</x><x>0.140</x><y>0.233</y><y>0.292</y></points>
      <label>3</label><labelname>window</labelname><flag>1</flag></object>

  ``<x>`` are left/right and ``<y>`` top/bottom, normalised to 0–1 of the photo's width/height.

Objects keep the finest canonical label (CMP's ``facade`` is ``wall``, ``blind`` stays ``blind``
even in ``cmp6``), so window detection scores ``label == "window"`` boxes.  A facade without XML
gets the connected components of its label map instead (``meta["objects_from"]``).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model.labels import label_for_name
from .folder import FacadeSample, ObjectBox, _check_folder, _list_photos, _unique_ids
from .labelsets import LABEL_SETS, LabelSet, convert, get_label_set

__all__ = ["load_cmp", "read_cmp_xml"]

_CMP12 = LABEL_SETS["cmp12"]


def read_cmp_xml(path: str | Path, width: int, height: int) -> list[ObjectBox]:
    """Object rectangles of a CMP annotation file, in pixels.

    Parameters
    ----------
    path : str or Path
        ``cmp_bNNNN.xml``.
    width, height : int
        Size of the photo in pixels (the XML is normalised to 0–1; its ``<x>`` pair is the
        vertical extent, ``<y>`` the horizontal one).

    Returns
    -------
    list of ObjectBox
        In file order; canonical labels from the CMP class id (``facade`` → ``wall``), or guessed
        from ``<labelname>`` for ids outside 1–12; rectangles clipped to the photo.

    Raises
    ------
    InputError
        The file is missing or malformed.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"CMP annotation {path} cannot be read ({exc}); check the file") from exc
    # The files are a bare sequence of <object> elements: give them a root to parse.
    text = re.sub(r"<\?xml[^>]*\?>", "", text)
    try:
        root = ET.fromstring(f"<annotation>{text}</annotation>")
    except ET.ParseError as exc:
        raise InputError(f"CMP annotation {path} is not valid XML ({exc}); restore it from the "
                         "CMP distribution or delete it to use label-map components") from exc
    boxes = []
    for i, obj in enumerate(root.iter("object")):
        try:
            xs = [float(x.text or "") for x in obj.iterfind("points/x")]
            ys = [float(y.text or "") for y in obj.iterfind("points/y")]
            if len(xs) < 2 or len(ys) < 2:
                raise ValueError("needs two <x> and two <y>")
        except ValueError as exc:
            raise InputError(f"CMP annotation {path}: object {i} has bad <points> ({exc}); "
                             "fix or delete that object") from exc
        label = _object_label(obj.findtext("label"), obj.findtext("labelname"))
        # CMP's <x> runs down the rows and <y> across the columns (checked against the label
        # PNGs: window boxes read this way cover 57–92 % window pixels, read the other way
        # 0–20 %), although the names suggest the opposite.
        y0, y1 = np.clip([min(xs), max(xs)], 0.0, 1.0) * height
        x0, x1 = np.clip([min(ys), max(ys)], 0.0, 1.0) * width
        boxes.append(ObjectBox(label, float(x0), float(y0), float(x1), float(y1)))
    return boxes


def _object_label(label_id: str | None, name: str | None) -> str:
    try:
        k = int((label_id or "").strip())
    except ValueError:
        k = -1
    if k in _CMP12.id_map:
        return _CMP12.classes[_CMP12.id_map[k]]
    guess = label_for_name((name or "").strip())
    return guess.value if guess is not None else "other"


def _cmp_boxes(sample: FacadeSample) -> list[ObjectBox]:
    height, width = sample.image_shape()
    return read_cmp_xml(sample.meta["xml_path"], width, height)


def load_cmp(root: str | Path, label_set: LabelSet | str = "cmp6") -> list[FacadeSample]:
    """Load a folder in the CMP base layout.

    Parameters
    ----------
    root : str or Path
        Folder of ``<id>.jpg`` + ``<id>.png`` (+ ``<id>.xml``), e.g. ``../shared/data/cmp``.
    label_set : LabelSet or str
        ``"cmp6"`` (benchmark merge, default), ``"cmp12"``, or any set reached through
        canonical labels (``"ecp7"``).

    Returns
    -------
    list of FacadeSample
        Sorted by id.  ``labels()`` is ``(H, W)`` uint8 in ``label_set`` (ids outside 1–12 →
        255); ``objects()`` are the XML rectangles; ``meta`` has ``dataset``, ``label_path``,
        ``xml_path`` (or None) and ``objects_from`` (``"xml"`` or ``"components"``).

    Raises
    ------
    InputError
        Missing folder, no ``.jpg`` photos, a photo without its ``.png`` label, unknown label set.
    """
    target = get_label_set(label_set)
    root = _check_folder(root, "CMP", "pass the folder of cmp_bNNNN.jpg/.png/.xml files "
                         "(e.g. --data ../shared/data/cmp)")
    photos = _list_photos(root, (".jpg", ".jpeg"))
    if not photos:
        raise InputError(f"CMP folder {root} has no .jpg photos; expected cmp_bNNNN.jpg with "
                         ".png labels and .xml objects beside them")
    _unique_ids(photos, f"CMP folder {root}")

    def decode(raw: np.ndarray) -> np.ndarray:
        if raw.ndim == 3:
            index = _CMP12.from_color(raw)
        else:
            index = _CMP12.from_dataset(raw)
        return convert(index, _CMP12, target)

    samples = []
    for photo in photos:
        label = photo.with_suffix(".png")
        if not label.is_file():
            raise InputError(f"CMP photo {photo} has no label {label.name}; add it or move the "
                             "photo out of the folder")
        xml = photo.with_suffix(".xml")
        has_xml = xml.is_file()
        samples.append(FacadeSample(
            id=photo.stem, image_path=photo, label_path=label, label_set=target,
            meta={"dataset": "cmp", "label_path": str(label),
                  "xml_path": str(xml) if has_xml else None,
                  "objects_from": "xml" if has_xml else "components"},
            decode=decode, boxes=_cmp_boxes if has_xml else None))
    return samples
