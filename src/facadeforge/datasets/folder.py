"""Facade samples, image and label reading, and the generic folder layout.

Every loader returns a list of :class:`FacadeSample` sorted by id.  A sample reads nothing until
asked: :meth:`FacadeSample.image` gives the photo, :meth:`FacadeSample.labels` the class-index map
in the sample's label set (:data:`~facadeforge.datasets.labelsets.IGNORE` = 255 where not
scored), :meth:`FacadeSample.objects` the object rectangles (:class:`ObjectBox`).

Generic folder layout (:func:`load_folder`)
-------------------------------------------
::

    DIR/
      palette.json        what the label pixels mean (optional when label_set= is given)
      a.jpg  a.png        photo + label PNG with the same stem, or
      b.png  b_label.png  photo + ``<stem>_label.png``

Photos are ``.jpg .jpeg .png .bmp .tif .tiff .webp``.  A file is a label, not a photo, when its
stem ends in ``_label``, or when it is a ``.png`` beside a non-PNG photo of the same stem.

``palette.json``::

    {
      "name": "my-street",                        optional; default: the folder's name
      "classes": ["background", "wall", "window"],   canonical labels in class-index order
                                                   (names such as "facade" are guessed)
      "ids": [0, 1, [2, 3]],                      optional: pixel value(s) of each class in
                                                   single-channel label PNGs; default 0..K-1
      "colors": [[0, 0, 0], [255, 255, 0], [255, 0, 0]],
                                                   optional: RGB of each class, decodes RGB label
                                                   PNGs and is the display colour
      "ignore": 255                               optional: id, or [r, g, b] colour, of
                                                   unlabelled pixels (not scored)
    }

Single-channel label PNGs (``L``, 16-bit, or palette ``P`` images read by index) are decoded with
``ids``; RGB(A) label PNGs with ``colors``.  When ``colors`` is given and ``ids`` is not, palette
PNGs are decoded by their colours too.  Pixels matching no class are ignored.  Objects are the
connected components of each class in the label map (:func:`objects_from_labels`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, UnidentifiedImageError
from scipy import ndimage

from ..errors import InputError
from .labelsets import IGNORE, LabelSet, convert, get_label_set

__all__ = ["IMAGE_SUFFIXES", "FacadeSample", "ObjectBox", "load_folder", "load_palette",
           "objects_from_labels", "palette_label_set", "read_image", "read_label_image"]

#: File suffixes read as photos.
IMAGE_SUFFIXES: tuple[str, ...] = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")

#: Connected components smaller than this fraction of the image are not objects (0.01 %).
MIN_OBJECT_FRACTION: float = 1e-4

_PIL_ERRORS = (OSError, UnidentifiedImageError, Image.DecompressionBombError, SyntaxError,
               ValueError)


@dataclass(frozen=True)
class ObjectBox:
    """An axis-aligned object rectangle in image pixels.

    Coordinates are pixel *edges*: ``(0, 0)`` is the top-left corner of the top-left pixel and
    ``x1, y1`` are exclusive, so a box covering pixel columns 2–4 has ``x0 = 2, x1 = 5``.

    Parameters
    ----------
    label : str
        Canonical label (:class:`~facadeforge.model.Labels` value).
    x0, y0, x1, y1 : float
        Left, top, right, bottom edges in pixels.
    """

    label: str
    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def width(self) -> float:
        """Width in pixels."""
        return self.x1 - self.x0

    @property
    def height(self) -> float:
        """Height in pixels."""
        return self.y1 - self.y0

    @property
    def area(self) -> float:
        """Area in square pixels."""
        return max(self.width, 0.0) * max(self.height, 0.0)

    def as_array(self) -> np.ndarray:
        """(4,) float64 ``[x0, y0, x1, y1]``."""
        return np.array([self.x0, self.y0, self.x1, self.y1], np.float64)


@dataclass(eq=False)
class FacadeSample:
    """One labelled facade photo of a dataset; files are read on demand, never cached.

    Parameters
    ----------
    id : str
        Identifier, unique in its dataset (the photo's file stem, e.g. ``"cmp_b0001"``).
    image_path : Path
        The photo.
    label_path : Path
        The label image.
    label_set : LabelSet
        The classes :meth:`labels` are expressed in.
    meta : dict
        Dataset name, split, source paths and other facts about the sample.
    decode : callable
        Raw label array (:func:`read_label_image`) → ``(H, W)`` uint8 class-index map.
    boxes : callable or None
        ``boxes(sample) -> list[ObjectBox]``; ``None`` means connected components of
        :meth:`labels` (:func:`objects_from_labels`).
    label_as_color : bool
        Read palette label PNGs by colour instead of by index.
    """

    id: str
    image_path: Path
    label_path: Path
    label_set: LabelSet
    meta: dict[str, Any] = field(default_factory=dict)
    decode: Callable[[np.ndarray], np.ndarray] | None = field(default=None, repr=False)
    boxes: Callable[[FacadeSample], list[ObjectBox]] | None = field(default=None, repr=False)
    label_as_color: bool = field(default=False, repr=False)

    def image(self) -> np.ndarray:
        """The photo, ``(H, W, 3)`` uint8 RGB (grey, alpha, palette, 16-bit converted)."""
        return read_image(self.image_path)

    def image_shape(self) -> tuple[int, int]:
        """``(H, W)`` of the photo, from its header only."""
        width, height = _image_size(self.image_path)
        return height, width

    def labels(self) -> np.ndarray:
        """Class-index map ``(H, W)`` uint8 in :attr:`label_set`; 255 where ignored.

        Raises
        ------
        InputError
            The label image is unreadable or its size differs from the photo's.
        """
        raw = read_label_image(self.label_path, palette_as_color=self.label_as_color)
        height, width = self.image_shape()
        if raw.shape[:2] != (height, width):
            raise InputError(
                f"label {self.label_path} is {raw.shape[1]}x{raw.shape[0]} px but its photo "
                f"{self.image_path} is {width}x{height}; labels must cover the photo pixel for "
                "pixel (re-export the label at the photo's size)")
        if self.decode is not None:
            return self.decode(raw)
        if raw.ndim == 3:
            return self.label_set.from_color(raw)
        return self.label_set.from_dataset(raw)

    def objects(self) -> list[ObjectBox]:
        """Object rectangles in pixels, canonical labels (see the loader for their source)."""
        if self.boxes is not None:
            return self.boxes(self)
        return objects_from_labels(self.labels(), self.label_set)


# ---------------------------------------------------------------------------------- reading
def _open(path: Path, what: str) -> Image.Image:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what} {path} does not exist; check the dataset folder")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                im.load()  # decode now so truncated files fail here, not later
    except _PIL_ERRORS as exc:
        raise InputError(f"{what} {path} cannot be read ({exc}); re-export it as PNG or JPEG, "
                         "or remove it from the folder") from exc
    return im


def _image_size(path: Path) -> tuple[int, int]:
    """``(width, height)`` from the file header."""
    try:
        with Image.open(path) as im:
            return im.size
    except FileNotFoundError as exc:
        raise InputError(f"photo {path} does not exist; check the dataset folder") from exc
    except _PIL_ERRORS as exc:
        raise InputError(f"photo {path} cannot be read ({exc}); re-export it as PNG or JPEG, "
                         "or remove it from the folder") from exc


def read_image(path: str | Path) -> np.ndarray:
    """Read a photo as RGB.

    Parameters
    ----------
    path : str or Path
        Any image Pillow reads.  Grey, grey+alpha, palette, CMYK and RGBA images become RGB
        (alpha dropped); 16-bit and 32-bit integer images are scaled from 0–65535, float images
        from 0–1 (or clipped to 0–255 when larger).  EXIF orientation is *not* applied: label
        images are drawn in the stored pixel frame.

    Returns
    -------
    (H, W, 3) uint8

    Raises
    ------
    InputError
        The file is missing or not a readable image.
    """
    im = _open(Path(path), "photo")
    if im.mode in ("I", "I;16", "I;16B", "I;16L", "I;16N", "F"):
        arr = np.asarray(im).astype(np.float64)
        if im.mode == "F":
            arr = arr * 255.0 if arr.size and arr.max() <= 1.0 else arr
        else:
            arr = arr / 257.0
        grey = np.clip(np.rint(arr), 0, 255).astype(np.uint8)
        return np.repeat(grey[..., None], 3, axis=2)
    if im.mode == "P":  # palette transparency is only honoured through RGBA
        im = im.convert("RGBA")
    if im.mode != "RGB":
        im = im.convert("RGB")
    return np.asarray(im, dtype=np.uint8).copy()


def read_label_image(path: str | Path, palette_as_color: bool = False) -> np.ndarray:
    """Read a label image without interpreting it.

    Parameters
    ----------
    path : str or Path
        Label PNG.
    palette_as_color : bool
        Return palette (``P``) images as their RGB colours instead of their indices.

    Returns
    -------
    (H, W) int or (H, W, 3) uint8
        Pixel values of single-channel images (palette images: the palette index; 16-bit images
        keep their values), or RGB of colour images (alpha dropped).

    Raises
    ------
    InputError
        The file is missing or not a readable image.
    """
    im = _open(Path(path), "label image")
    if im.mode == "P" and palette_as_color:
        im = im.convert("RGB")
    if im.mode in ("RGB", "RGBA", "RGBX", "CMYK", "YCbCr", "LAB", "HSV"):
        return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
    if im.mode in ("LA", "PA"):
        im = im.getchannel(0)
    if im.mode == "1":
        return np.asarray(im, dtype=np.uint8).copy()
    if im.mode == "F":
        raise InputError(f"label image {path} holds floats; save labels as 8/16-bit integer PNG")
    return np.asarray(im).copy()


def objects_from_labels(index_map: np.ndarray, label_set: LabelSet,
                        min_fraction: float = MIN_OBJECT_FRACTION,
                        classes: tuple[str, ...] | None = None) -> list[ObjectBox]:
    """Object rectangles of the connected components of each class in a class-index map.

    Parameters
    ----------
    index_map : (H, W) uint8
        Class indices of ``label_set``; :data:`IGNORE` pixels belong to no object.
    label_set : LabelSet
        Gives each class its canonical label.
    min_fraction : float
        Components smaller than this fraction of the ``H * W`` pixels are skipped (default
        0.01 %).
    classes : tuple of str, optional
        Canonical labels to keep (default: every class).

    Returns
    -------
    list of ObjectBox
        Grouped by class index, then in raster order of each component's first pixel.
        Components are 4-connected.
    """
    index_map = np.asarray(index_map)
    if index_map.ndim != 2:
        raise InputError(f"objects_from_labels: index_map must be (H, W), got {index_map.shape}")
    min_pixels = min_fraction * index_map.size
    boxes: list[ObjectBox] = []
    present = np.unique(index_map)
    for k in present[present != IGNORE].tolist():
        if k >= label_set.num_classes:
            continue
        label = label_set.classes[k]
        if classes is not None and label not in classes:
            continue
        components, n = ndimage.label(index_map == k)
        if n == 0:
            continue
        sizes = np.bincount(components.ravel(), minlength=n + 1)[1:]
        for size, sl in zip(sizes.tolist(), ndimage.find_objects(components)):
            if sl is None or size < min_pixels:
                continue
            rows, cols = sl
            boxes.append(ObjectBox(label, float(cols.start), float(rows.start),
                                   float(cols.stop), float(rows.stop)))
    return boxes


def _check_folder(root: str | Path, what: str, fix: str) -> Path:
    """``root`` as a Path, or :class:`InputError` when it is not an existing folder."""
    path = Path(root).expanduser()
    if not path.exists():
        raise InputError(f"{what} folder {path} does not exist; {fix}")
    if not path.is_dir():
        raise InputError(f"{what} folder {path} is a file, not a folder; {fix}")
    return path


def _list_photos(folder: Path, suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> list[Path]:
    """Image files directly in ``folder`` with one of ``suffixes`` (any case), sorted by name."""
    return sorted((p for p in folder.iterdir()
                   if p.is_file() and p.suffix.lower() in suffixes and not p.name.startswith(".")),
                  key=lambda p: p.name)


def _unique_ids(photos: list[Path], what: str) -> None:
    """Raise :class:`InputError` when two photos share a stem (their sample ids would clash)."""
    stems: dict[str, Path] = {}
    for p in photos:
        if p.stem in stems:
            raise InputError(f"{what}: {stems[p.stem].name} and {p.name} have the same id "
                             f"{p.stem!r}; keep one photo per stem")
        stems[p.stem] = p


# ---------------------------------------------------------------------------------- palette
def palette_label_set(spec: dict[str, Any], name: str = "folder",
                      source: str = "palette.json") -> tuple[LabelSet, bool]:
    """Build a label set from a ``palette.json`` dictionary (format: module docstring).

    Parameters
    ----------
    spec : dict
        Parsed ``palette.json``.
    name : str
        Name used when ``spec`` has none.
    source : str
        Where ``spec`` came from, for error messages.

    Returns
    -------
    label_set : LabelSet
    by_color : bool
        True when palette label images should be decoded by colour (``colors`` without ``ids``).
    """
    fix = "see the palette.json format in facadeforge.datasets.folder"
    if not isinstance(spec, dict) or not isinstance(spec.get("classes"), list) \
            or not spec["classes"]:
        raise InputError(f"{source}: needs a non-empty \"classes\" list of canonical labels; {fix}")
    classes = spec["classes"]
    k = len(classes)
    ids = spec.get("ids")
    colors = spec.get("colors")
    if ids is None:
        ids = list(range(k))
    if not isinstance(ids, list) or len(ids) != k:
        raise InputError(f"{source}: \"ids\" must list one id (or a list of ids) per class, "
                         f"{k} in all; {fix}")
    id_map: dict[int, int] = {}
    for cls, entry in enumerate(ids):
        for value in entry if isinstance(entry, list) else [entry]:
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InputError(f"{source}: id {value!r} of class {classes[cls]!r} is not a "
                                 f"non-negative integer; {fix}")
            if value in id_map:
                raise InputError(f"{source}: id {value} is given to two classes; {fix}")
            id_map[value] = cls
    if colors is None:
        from ..exchange.raster import LABEL_COLORS  # display colours of canonical labels
        from ..model.labels import label_for_name

        guessed = [label_for_name(str(c)) for c in classes]
        colors = [LABEL_COLORS.get(g.value if g else "other", (128, 128, 128)) for g in guessed]
    try:
        arr = np.asarray(colors)
    except ValueError:  # rows of different lengths
        arr = np.zeros((0, 0))
    if arr.shape != (k, 3) or arr.dtype.kind not in "iu" or arr.min() < 0 or arr.max() > 255:
        raise InputError(f"{source}: \"colors\" must be {k} [r, g, b] triples of integers 0–255; "
                         f"{fix}")
    ignore = spec.get("ignore")
    ignore_index = ignore_color = None
    if isinstance(ignore, list) and len(ignore) == 3 and all(
            isinstance(c, int) and 0 <= c <= 255 for c in ignore):
        ignore_color = tuple(ignore)
    elif isinstance(ignore, int) and not isinstance(ignore, bool) and ignore >= 0:
        ignore_index = ignore
    elif ignore is not None:
        raise InputError(f"{source}: \"ignore\" must be an id or an [r, g, b] colour; {fix}")
    label_set = LabelSet(name=str(spec.get("name", name)), classes=tuple(map(str, classes)),
                         colors=arr.astype(np.uint8), id_map=id_map, ignore_index=ignore_index,
                         dataset_names=tuple(map(str, classes)), ignore_color=ignore_color)
    return label_set, "colors" in spec and "ids" not in spec


#: Largest palette.json read (bytes): a palette lists a few dozen classes.
MAX_PALETTE_BYTES = 2**20


def _read_palette(path: Path) -> tuple[LabelSet, bool]:
    from ..jsonfile import read_json

    if not path.is_file():
        raise InputError(f"palette {path} does not exist; write one (format in "
                         "facadeforge.datasets.folder) or pass a label set")
    spec = read_json(path, "palette", max_bytes=MAX_PALETTE_BYTES,
                     fix="fix the file (format in facadeforge.datasets.folder)")
    return palette_label_set(spec, name=path.parent.name, source=str(path))


def load_palette(path: str | Path) -> LabelSet:
    """Read a ``palette.json`` file into a :class:`LabelSet` (format: module docstring)."""
    return _read_palette(Path(path))[0]


# ---------------------------------------------------------------------------------- loader
def _label_for(photo: Path, by_stem: dict[str, list[Path]]) -> Path | None:
    for candidate in by_stem.get(photo.stem + "_label", []):
        if candidate.suffix.lower() == ".png":
            return candidate
    if photo.suffix.lower() != ".png":
        for candidate in by_stem.get(photo.stem, []):
            if candidate.suffix.lower() == ".png":
                return candidate
    return None


def load_folder(root: str | Path, label_set: LabelSet | str | None = None,
                palette: str | Path | None = None) -> list[FacadeSample]:
    """Load a generic folder of photos, label PNGs and ``palette.json`` (module docstring).

    Parameters
    ----------
    root : str or Path
        The folder.
    label_set : LabelSet or str, optional
        Classes to return labels in.  With a palette, labels are converted into it through
        canonical labels; without one, label PNGs are read as this set's dataset ids (or colours
        for RGB PNGs).  Default: the palette's own set.
    palette : str or Path, optional
        Palette file; default ``root / "palette.json"`` when it exists.

    Returns
    -------
    list of FacadeSample
        Sorted by id (the photo's stem); ``objects()`` are connected components per class.

    Raises
    ------
    InputError
        Missing folder, no photos, a photo without a label, no palette and no label set, a bad
        palette, or an unknown label set.
    """
    root = _check_folder(root, "image", "pass the folder that holds the photos and label PNGs")
    palette_path = Path(palette) if palette is not None else root / "palette.json"
    native: LabelSet | None = None
    by_color = False
    if palette is not None or palette_path.is_file():
        native, by_color = _read_palette(palette_path)
    if native is None and label_set is None:
        raise InputError(f"folder {root} has no palette.json and no label set was given; write "
                         "a palette.json (format in facadeforge.datasets.folder) or pass "
                         "label_set='cmp12'|'cmp6'|'ecp7'")
    target = get_label_set(label_set) if label_set is not None else native
    assert target is not None
    source = native if native is not None else target

    files = _list_photos(root)
    by_stem: dict[str, list[Path]] = {}
    for p in files:
        by_stem.setdefault(p.stem, []).append(p)
    label_files = set()
    for p in files:
        if p.stem.endswith("_label"):
            label_files.add(p)
        elif p.suffix.lower() == ".png" and any(q.suffix.lower() != ".png"
                                                for q in by_stem[p.stem]):
            label_files.add(p)
    photos = [p for p in files if p not in label_files]
    if not photos:
        raise InputError(f"folder {root} has no photos ({', '.join(IMAGE_SUFFIXES)}) besides "
                         "label PNGs; pass the folder that holds the photos")
    _unique_ids(photos, f"folder {root}")

    def decode(raw: np.ndarray) -> np.ndarray:
        index = source.from_color(raw) if raw.ndim == 3 else source.from_dataset(raw)
        return convert(index, source, target)

    samples = []
    for photo in photos:
        label = _label_for(photo, by_stem)
        if label is None:
            tried = [f"{photo.stem}_label.png"]
            if photo.suffix.lower() != ".png":
                tried.append(f"{photo.stem}.png")
            raise InputError(f"photo {photo} has no label image (looked for {', '.join(tried)}); "
                             "add the label PNG or move the photo out of the folder")
        samples.append(FacadeSample(
            id=photo.stem, image_path=photo, label_path=label, label_set=target,
            meta={"dataset": "folder", "root": str(root), "label_path": str(label),
                  "source_label_set": source.name, "objects_from": "components"},
            decode=decode, label_as_color=by_color))
    return samples
