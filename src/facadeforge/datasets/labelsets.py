"""Named label sets: the classes a dataset is scored in, and how they map to canonical labels.

A :class:`LabelSet` turns three kinds of input into one *class-index map* — an ``(H, W)`` uint8
array whose value ``k`` means ``classes[k]`` and :data:`IGNORE` (255) means "not scored":

- dataset ids, the pixel values of a dataset's label PNG (:meth:`LabelSet.from_dataset`);
- colour-coded label images, RGB (:meth:`LabelSet.from_color`);
- canonical labels (:class:`~facadeforge.model.Labels`), as names or as canonical indices in
  the enum order, the order of ``facadeforge.exchange.raster.LABEL_INDEX``
  (:meth:`LabelSet.from_canonical`).  That is how a prediction in canonical labels, such as a
  shape tree rasterised with canonical labels, is scored in any set.

Built-in sets (:data:`LABEL_SETS`):

``cmp12``
    CMP Facade Database, ids 1–12: background, facade (canonical ``wall``), window, door, cornice,
    sill, balcony, blind, deco, molding, pillar, shop.  Colours are the CMP palette.
``cmp6``
    The merged CMP set used in benchmarks: background | wall (facade, cornice, sill, deco,
    molding, pillar) | window (window, blind) | door | balcony | shop.  It reads CMP ids.
``ecp7``
    Ecole Centrale Paris / RueMonge2014, ids 1–7: window, wall, balcony, door, roof, sky, shop;
    id 0 is unlabelled and ignored.  Colours are the RueMonge ``label_color`` palette.
``lmf9``
    LabelMeFacade (Fröhlich, Rodner & Denzler 2010), street photos with their occluders:
    various (canonical ``other``), building (canonical ``wall``), car, door, pavement, road, sky,
    vegetation, window.  The dataset's names are the ``dataset_names`` (the class names of bench
    results); its labels are colour PNGs in its palette (various 0:0:0, building 128:0:0, car
    128:0:128, door 128:128:0, pavement 128:128:128, road 128:64:0, sky 0:128:128, vegetation
    0:128:0, window 0:0:128), single-channel ids 0–8 follow the class order.  "building" is the
    whole facade around windows and doors, so balconies, shop fronts, roofs and the facade parts
    are building; people are various; CMP's ``background`` is sky (see below).  Read in a set
    without ``other`` (``cmp6``, ``ecp7``), various is ``wall`` like any ``other``.

Canonical labels a set has no class for fall back along a fixed chain (:data:`CANONICAL_FALLBACK`),
first match wins:

- facade parts (cornice, sill, deco, molding, pillar) and ``other`` (an unlabelled leaf of a shape
  tree, nearly always a piece of facade) → ``wall``;
- ``blind`` (shutters, roller blinds) → ``window``;
- things that are not the building (roof, sky, vegetation, ground, car, person, pavement, road)
  → ``background``; in ``ecp7``, which has no background, ``background`` → ``sky`` and
  vegetation, car, person, ground, pavement and road → ``wall`` (they stand in front of the
  facade; the street is unlabelled, hence ignored, in RueMonge truth);
- the street: ``ground`` → ``pavement`` → ``road`` and back (the ground in front of a facade is
  its pavement first); ``car`` and ``person`` → ``other`` where there is no background
  (``lmf9``: people are "various");
- ``lmf9`` overrides the chain for ``roof`` → building (LabelMeFacade draws roofs as building);
  its ``background`` → ``sky``: a ``cmp6``/``cmp12`` background prediction is, on a rectified
  facade, mostly the sky above the roofline, and on LabelMeFacade's street photos the shipped
  ``cmp6`` classifier's background pixels were sky 32 %, road 31 %, building 21 %, vegetation
  5 %, pavement 4 %, various 4 % (20 test photos) — sky is the least wrong class, "various"
  would be right almost nowhere and only blur that class;
- a label whose chain finds nothing → class 0.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..errors import InputError
from ..model.labels import Labels, label_for_name

__all__ = ["CANONICAL_FALLBACK", "CANONICAL_INDEX", "IGNORE", "LABEL_SETS", "LabelSet",
           "convert", "get_label_set"]

#: Value of an ignored (unlabelled, not scored) pixel in every class-index map.
IGNORE: int = 255

#: Index of each canonical label in a canonical label map: the order of :class:`Labels`
#: (the same numbering as ``facadeforge.exchange.raster.LABEL_INDEX``).
CANONICAL_INDEX: Mapping[str, int] = MappingProxyType(
    {label.value: i for i, label in enumerate(Labels)})

_CANONICAL_NAMES: tuple[str, ...] = tuple(label.value for label in Labels)

#: For each canonical label, the classes to try, in order, when a label set has no class of that
#: name.  The label itself is always tried first.
CANONICAL_FALLBACK: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "background": ("sky", "other", "wall"),
    "wall": ("other", "background"),
    "window": ("wall",),
    "door": ("wall",),
    "balcony": ("wall",),
    "shop": ("wall",),
    "roof": ("background", "sky", "wall"),
    "sky": ("background", "roof", "wall"),
    "cornice": ("wall",),
    "sill": ("wall",),
    "blind": ("window", "wall"),
    "deco": ("wall",),
    "molding": ("wall",),
    "pillar": ("wall",),
    "vegetation": ("background", "wall"),
    "other": ("wall", "background"),
    "ground": ("pavement", "road", "background", "wall"),
    "car": ("background", "other", "wall"),
    "person": ("background", "other", "wall"),
    "pavement": ("ground", "road", "background", "wall"),
    "road": ("ground", "pavement", "background", "wall"),
})


def _canonical_name(name: str, where: str) -> str:
    """The canonical label value for ``name`` (exact, or guessed from its words)."""
    label = label_for_name(str(name))
    if label is None:
        raise InputError(
            f"{where}: {name!r} is not a canonical label; use one of "
            f"{', '.join(_CANONICAL_NAMES)} (facadeforge.model.Labels)")
    return label.value


@dataclass(frozen=True, eq=False)
class LabelSet:
    """A named set of classes, with its dataset ids, colours and canonical mapping.

    Parameters
    ----------
    name : str
        Short name, e.g. ``"cmp6"``.
    classes : tuple of str, length K
        Canonical label name of each class, in class-index order.  Distinct.
    colors : (K, 3) uint8
        RGB colour of each class: the dataset's own colour coding where it has one (decoded by
        :meth:`from_color`), else a display colour.
    id_map : mapping int -> int
        Dataset id (pixel value in the dataset's label PNG) → class index.  Several ids may share a
        class (merged sets).
    ignore_index : int or None
        Dataset id of unlabelled pixels (``0`` in ``ecp7``), or ``None``.  It maps to
        :data:`IGNORE` in class-index maps, as does every id absent from ``id_map``.
    dataset_names : tuple of str, length K
        The dataset's own name of each class (``"facade"`` for CMP's wall); defaults to
        ``classes``.
    canonical_map : mapping str -> int
        Class index of every canonical label (all :class:`Labels` members).  Filled from
        :data:`CANONICAL_FALLBACK` when not given; entries given override it.
    ignore_color : tuple of 3 int or None
        RGB colour of unlabelled pixels in colour-coded label images.
    windows_behind : tuple of str
        Classes the dataset draws *in front of* windows that it still annotates whole behind
        them: CMP's window rectangles run down behind the balcony railing (12 % of its windows
        overlap a balcony box, by a median 39 % of their area), RueMonge's windows stop at it.
        Element detection extends windows through them
        (:func:`~facadeforge.imaging.detect.detect_elements` ``behind``).
    windows_covering : tuple of str
        Classes that cover a window in its frame and that the dataset annotates as part of the
        window's rectangle: CMP's closed shutters (``blind``) lie inside its window rectangles.
        Element detection counts them as window, and trims off those open beside a window's
        glass (:func:`~facadeforge.imaging.detect.detect_elements` ``covers``).

    Notes
    -----
    Instances are immutable: arrays are read-only and mappings are read-only views.
    """

    name: str
    classes: tuple[str, ...]
    colors: np.ndarray
    id_map: Mapping[int, int]
    ignore_index: int | None = None
    dataset_names: tuple[str, ...] = ()
    canonical_map: Mapping[str, int] = field(default_factory=dict)
    ignore_color: tuple[int, int, int] | None = None
    windows_behind: tuple[str, ...] = ()
    windows_covering: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = f"label set {self.name!r}"
        classes = tuple(_canonical_name(c, where) for c in self.classes)
        if not classes:
            raise InputError(f"{where}: no classes; list at least one canonical label")
        if len(classes) >= IGNORE:
            raise InputError(f"{where}: {len(classes)} classes; at most {IGNORE - 1} fit uint8 "
                             f"maps with {IGNORE} reserved for ignored pixels")
        if len(set(classes)) != len(classes):
            dup = sorted({c for c in classes if classes.count(c) > 1})
            raise InputError(f"{where}: classes {dup} appear more than once; merge them into one "
                             "class and give it several dataset ids")
        colors = np.asarray(self.colors)
        if colors.shape != (len(classes), 3) or (colors.size and (
                colors.min() < 0 or colors.max() > 255)):
            raise InputError(f"{where}: colors must be {len(classes)} RGB triples in 0–255, "
                             f"got shape {colors.shape}")
        colors = colors.astype(np.uint8)
        colors.flags.writeable = False
        id_map = {int(k): int(v) for k, v in dict(self.id_map).items()}
        bad = {k: v for k, v in id_map.items() if not 0 <= v < len(classes)}
        if bad:
            raise InputError(f"{where}: dataset ids {sorted(bad)} map to class indices outside "
                             f"0..{len(classes) - 1}")
        if any(k < 0 for k in id_map):
            raise InputError(f"{where}: dataset ids must be >= 0, got {sorted(id_map)}")
        if self.ignore_index is not None and int(self.ignore_index) in id_map:
            raise InputError(f"{where}: ignore id {self.ignore_index} is also a class id; "
                             "drop it from the ids or from ignore")
        names = tuple(self.dataset_names) or classes
        if len(names) != len(classes):
            raise InputError(f"{where}: {len(names)} dataset_names for {len(classes)} classes")
        index = {c: i for i, c in enumerate(classes)}
        canonical = {}
        for label in _CANONICAL_NAMES:
            chain = (label, *CANONICAL_FALLBACK.get(label, ()))
            canonical[label] = next((index[c] for c in chain if c in index), 0)
        for label, k in dict(self.canonical_map).items():
            canonical[_canonical_name(label, where)] = int(k)
        set_ = object.__setattr__
        set_(self, "classes", classes)
        set_(self, "colors", colors)
        set_(self, "id_map", MappingProxyType(id_map))
        set_(self, "dataset_names", names)
        set_(self, "canonical_map", MappingProxyType(canonical))
        if self.ignore_color is not None:
            set_(self, "ignore_color", tuple(int(c) for c in self.ignore_color))
        for conv in ("windows_behind", "windows_covering"):
            named = tuple(_canonical_name(c, where) for c in getattr(self, conv))
            if not set(named) <= set(classes):
                raise InputError(f"{where}: {conv} {list(named)} names classes outside "
                                 f"{list(classes)}")
            set_(self, conv, named)

    # ------------------------------------------------------------------ lookups
    @property
    def num_classes(self) -> int:
        """Number of classes K."""
        return len(self.classes)

    def index(self, label: str) -> int:
        """Class index of a canonical label (or a name guessed to one), via the fallback chain."""
        return self.canonical_map[_canonical_name(label, f"label set {self.name!r}")]

    def _id_table(self) -> np.ndarray:
        """(max id + 1,) uint8 lookup table dataset id → class index (:data:`IGNORE` if none)."""
        table = np.full(max(self.id_map, default=0) + 1, IGNORE, np.uint8)
        for k, v in self.id_map.items():
            table[k] = v
        return table

    # ------------------------------------------------------------------ conversions
    def from_dataset(self, ids: np.ndarray, strict: bool = False) -> np.ndarray:
        """Class-index map of a dataset-id map.

        Parameters
        ----------
        ids : (H, W) int
            Pixel values of the dataset's label image (any shape works).
        strict : bool
            Raise :class:`InputError` on ids that are neither a class nor ``ignore_index``;
            otherwise they become :data:`IGNORE`.

        Returns
        -------
        (H, W) uint8
            Class indices, :data:`IGNORE` where ignored.
        """
        ids = np.asarray(ids)
        if ids.dtype.kind == "b" or ids.dtype.kind not in "iu":
            raise InputError(f"label set {self.name!r}: dataset ids must be integers, got "
                             f"dtype {ids.dtype}; read label PNGs as 8/16-bit index images")
        out = np.full(ids.shape, IGNORE, np.uint8)
        if ids.size == 0:
            return out
        table = self._id_table()
        valid = (ids >= 0) & (ids < len(table))
        out[valid] = table[ids[valid]]
        if strict:
            known = set(self.id_map) | ({self.ignore_index} - {None})
            unknown = sorted(set(np.unique(ids).tolist()) - known)
            if unknown:
                raise InputError(
                    f"label set {self.name!r}: dataset ids {unknown[:10]} are not classes "
                    f"(known ids {sorted(self.id_map)}); pick the label set the data was labelled "
                    "in, or pass strict=False to ignore them")
        return out

    def from_color(self, rgb: np.ndarray, strict: bool = False) -> np.ndarray:
        """Class-index map of a colour-coded label image.

        Parameters
        ----------
        rgb : (H, W, 3) uint8
            Label image whose colours are ``colors`` (and ``ignore_color``); an alpha channel,
            if present as a 4th channel, is dropped.
        strict : bool
            Raise :class:`InputError` on colours that are neither a class nor ``ignore_color``;
            otherwise they become :data:`IGNORE`.

        Returns
        -------
        (H, W) uint8
        """
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[-1] not in (3, 4):
            raise InputError(f"label set {self.name!r}: colour label image must be (H, W, 3), "
                             f"got shape {rgb.shape}")
        key = _pack_rgb(rgb[..., :3])
        palette = _pack_rgb(self.colors)
        order = np.argsort(palette, kind="stable")
        sorted_keys = palette[order]
        pos = np.clip(np.searchsorted(sorted_keys, key), 0, len(sorted_keys) - 1)
        hit = sorted_keys[pos] == key
        out = np.where(hit, order[pos], IGNORE).astype(np.uint8)
        if strict:
            miss = ~hit
            if self.ignore_color is not None:
                miss &= key != _pack_rgb(np.asarray(self.ignore_color))
            if miss.any():
                bad = np.unique(rgb[..., :3][miss].reshape(-1, 3), axis=0)[:5].tolist()
                raise InputError(
                    f"label set {self.name!r}: colours {bad} are not class colours "
                    f"({self.colors.tolist()}); save labels with exact colours (PNG, no "
                    "anti-aliasing) or pass strict=False to ignore them")
        return out

    def from_canonical(self, labels: np.ndarray | Iterable[str]) -> np.ndarray:
        """Class-index map of canonical labels.

        Parameters
        ----------
        labels : (H, W) str or (H, W) int
            Canonical label names (any shape; names such as ``"facade"`` are guessed to a label
            with :func:`~facadeforge.model.labels.label_for_name`), or canonical indices in
            :class:`Labels` order (:data:`CANONICAL_INDEX`), where :data:`IGNORE` stays ignored.

        Returns
        -------
        (H, W) uint8
            Class indices of this set; labels without a class of their own follow
            :data:`CANONICAL_FALLBACK`.
        """
        arr = np.asarray(labels)
        if arr.size == 0:
            return np.zeros(arr.shape, np.uint8)
        table = np.full(256, IGNORE, np.uint8)
        table[:len(_CANONICAL_NAMES)] = [self.canonical_map[c] for c in _CANONICAL_NAMES]
        if arr.dtype.kind in ("U", "O", "S"):
            uniq, inverse = np.unique(arr.astype(str), return_inverse=True)
            where = f"label set {self.name!r}"
            mapped = np.array([self.canonical_map[_canonical_name(u, where)] for u in uniq],
                              np.uint8)
            return mapped[inverse].reshape(arr.shape)
        if arr.dtype.kind not in "iu":
            raise InputError(f"label set {self.name!r}: canonical labels must be names or "
                             f"integer indices, got dtype {arr.dtype}")
        bad = ((arr < 0) | (arr > IGNORE)
               | ((arr >= len(_CANONICAL_NAMES)) & (arr != IGNORE)))
        if bad.any():
            raise InputError(
                f"label set {self.name!r}: canonical indices {np.unique(arr[bad])[:10].tolist()} "
                f"are out of range 0..{len(_CANONICAL_NAMES) - 1} (or {IGNORE}); index labels "
                "in facadeforge.model.Labels order")
        return table[arr.astype(np.intp)]

    def project_proba(self, prob: np.ndarray, classes: Iterable[str], floor: float = 1e-3
                      ) -> np.ndarray:
        """Class probabilities over ``classes`` (canonical labels, e.g. a ``cmp12`` classifier's
        or the few a scribble GMM was trained on) as probabilities over this set's classes.

        Each source channel adds into the class its label maps to (:meth:`index`, through
        :data:`CANONICAL_FALLBACK`): ``cmp12``'s blind into ``cmp6``'s window, its cornice, sill,
        deco, molding and pillar into wall — the probability of a merged class is the sum of
        its parts, as in the merged truth.  Every class then gets ``floor`` more and the rows
        are renormalised, so a class no source channel reaches is unlikely, not impossible.
        Probabilities already over this set's classes are returned as they are.

        Parameters
        ----------
        prob : (H, W, K) float
        classes : K canonical labels naming the channels of ``prob``

        Returns
        -------
        (H, W, num_classes) float32
        """
        classes = tuple(classes)
        prob = np.asarray(prob)
        if prob.ndim != 3 or prob.shape[2] != len(classes):
            raise InputError(f"label set {self.name!r}: probabilities of shape {prob.shape} do "
                             f"not hold one channel per class of {list(classes)}")
        if classes == self.classes:
            return prob.astype(np.float32, copy=False)
        out = np.full((*prob.shape[:2], self.num_classes), floor, np.float32)
        for ch, name in enumerate(classes):
            out[:, :, self.index(name)] += prob[:, :, ch]
        out /= out.sum(axis=2, keepdims=True)
        return out

    def to_canonical(self, index_map: np.ndarray) -> np.ndarray:
        """Canonical-index map (:data:`CANONICAL_INDEX`) of a class-index map.

        Parameters
        ----------
        index_map : (H, W) uint8
            Class indices of this set; :data:`IGNORE` stays :data:`IGNORE`.

        Returns
        -------
        (H, W) uint8
        """
        table = np.full(256, IGNORE, np.uint8)
        table[:self.num_classes] = [CANONICAL_INDEX[c] for c in self.classes]
        return table[self.check_indices(index_map)]

    def to_color(self, index_map: np.ndarray) -> np.ndarray:
        """Colour picture of a class-index map.

        Parameters
        ----------
        index_map : (H, W) int
            Class indices of this set; :data:`IGNORE` is drawn black (or ``ignore_color``).

        Returns
        -------
        (H, W, 3) uint8
        """
        table = np.zeros((256, 3), np.uint8)
        table[:self.num_classes] = self.colors
        if self.ignore_color is not None:
            table[IGNORE] = self.ignore_color
        return table[self.check_indices(index_map)]

    def check_indices(self, index_map: np.ndarray) -> np.ndarray:
        """``index_map`` as intp class indices; :class:`InputError` for non-integers or values
        that are neither a class index nor :data:`IGNORE`."""
        arr = np.asarray(index_map)
        if arr.dtype.kind not in "iu":
            raise InputError(f"label set {self.name!r}: class-index maps must be integers, got "
                             f"dtype {arr.dtype}")
        bad = (arr < 0) | ((arr >= self.num_classes) & (arr != IGNORE))
        if bad.any():
            raise InputError(
                f"label set {self.name!r}: class indices {np.unique(arr[bad])[:10].tolist()} are "
                f"out of range 0..{self.num_classes - 1} (or {IGNORE} for ignored); was the map "
                "made in another label set?  Convert it with facadeforge.datasets.convert")
        return arr.astype(np.intp)

    def __repr__(self) -> str:
        return f"LabelSet({self.name!r}, classes={self.classes!r})"


def _pack_rgb(rgb: np.ndarray) -> np.ndarray:
    """(…, 3) colours → (…) int64 keys ``r << 16 | g << 8 | b``."""
    rgb = np.asarray(rgb).astype(np.int64)
    return (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]


def convert(index_map: np.ndarray, source: LabelSet | str, target: LabelSet | str) -> np.ndarray:
    """Re-express a class-index map of one label set in another, through canonical labels.

    Parameters
    ----------
    index_map : (H, W) int
        Class indices of ``source``; :data:`IGNORE` stays ignored.
    source, target : LabelSet or str
        Label sets (or names in :data:`LABEL_SETS`).

    Returns
    -------
    (H, W) uint8
        Class indices of ``target``.  ``cmp12`` → ``cmp6`` gives the benchmark merge.
    """
    source, target = get_label_set(source), get_label_set(target)
    if source is target:
        return np.asarray(index_map).astype(np.uint8)
    table = np.full(256, IGNORE, np.uint8)
    table[:source.num_classes] = [target.canonical_map[c] for c in source.classes]
    return table[source.check_indices(index_map)]


# CMP palette (label PNGs are palette images; index = class id).
_CMP_COLORS = {
    1: (0, 0, 170), 2: (0, 0, 255), 3: (0, 85, 255), 4: (0, 170, 255), 5: (0, 255, 255),
    6: (85, 255, 170), 7: (170, 255, 85), 8: (255, 255, 0), 9: (255, 170, 0), 10: (255, 85, 0),
    11: (255, 0, 0), 12: (170, 0, 0),
}
_CMP_NAMES = ("background", "facade", "window", "door", "cornice", "sill", "balcony", "blind",
              "deco", "molding", "pillar", "shop")

_CMP12 = LabelSet(
    name="cmp12",
    classes=("background", "wall", "window", "door", "cornice", "sill", "balcony", "blind",
             "deco", "molding", "pillar", "shop"),
    colors=np.array([_CMP_COLORS[i] for i in range(1, 13)], np.uint8),
    id_map={i: i - 1 for i in range(1, 13)},
    dataset_names=_CMP_NAMES,
    windows_behind=("balcony",),
    windows_covering=("blind",),
)

# cmp6 class of each CMP id.
_CMP6_OF_ID = {1: 0, 2: 1, 3: 2, 4: 3, 5: 1, 6: 1, 7: 4, 8: 2, 9: 1, 10: 1, 11: 1, 12: 5}
_CMP6 = LabelSet(
    name="cmp6",
    classes=("background", "wall", "window", "door", "balcony", "shop"),
    colors=np.array([_CMP_COLORS[i] for i in (1, 2, 3, 4, 7, 12)], np.uint8),
    id_map=_CMP6_OF_ID,
    windows_behind=("balcony",),
)

_ECP7 = LabelSet(
    name="ecp7",
    classes=("window", "wall", "balcony", "door", "roof", "sky", "shop"),
    colors=np.array([(255, 0, 0), (255, 255, 0), (128, 0, 255), (255, 128, 0), (0, 0, 255),
                     (128, 255, 255), (0, 255, 0)], np.uint8),
    id_map={i: i - 1 for i in range(1, 8)},
    ignore_index=0,
    ignore_color=(0, 0, 0),
)

# The street classifier's classes (facadeforge.classify.street): the union of what RueMonge, CMP
# and LabelMeFacade label; display colours are the canonical ones (exchange.raster.LABEL_COLORS).
_STREET12 = LabelSet(
    name="street12",
    classes=("wall", "window", "door", "balcony", "shop", "roof", "sky", "vegetation", "car",
             "pavement", "road", "other"),
    colors=np.array([(214, 196, 160), (31, 119, 180), (140, 86, 75), (255, 127, 14),
                     (227, 119, 194), (214, 39, 40), (158, 218, 229), (44, 160, 44),
                     (255, 152, 150), (199, 199, 199), (52, 52, 60), (197, 176, 213)], np.uint8),
    id_map={i: i for i in range(12)},
    canonical_map={"ground": 9, "background": 6, "person": 11},
)

# LabelMeFacade: dataset name, canonical label and colour of each class, in class-index order.
_LMF9_CLASSES = (
    ("various", "other", (0, 0, 0)),
    ("building", "wall", (128, 0, 0)),
    ("car", "car", (128, 0, 128)),
    ("door", "door", (128, 128, 0)),
    ("pavement", "pavement", (128, 128, 128)),
    ("road", "road", (128, 64, 0)),
    ("sky", "sky", (0, 128, 128)),
    ("vegetation", "vegetation", (0, 128, 0)),
    ("window", "window", (0, 0, 128)),
)
_LMF9 = LabelSet(
    name="lmf9",
    classes=tuple(c for _, c, _ in _LMF9_CLASSES),
    colors=np.array([rgb for _, _, rgb in _LMF9_CLASSES], np.uint8),
    id_map={i: i for i in range(len(_LMF9_CLASSES))},
    dataset_names=tuple(n for n, _, _ in _LMF9_CLASSES),
    canonical_map={"roof": 1},    # roofs are drawn as building
)

#: The built-in label sets by name.
LABEL_SETS: Mapping[str, LabelSet] = MappingProxyType(
    {"cmp12": _CMP12, "cmp6": _CMP6, "ecp7": _ECP7, "lmf9": _LMF9, "street12": _STREET12})


def get_label_set(name: LabelSet | str) -> LabelSet:
    """The label set called ``name`` (a :class:`LabelSet` passes through).

    Raises
    ------
    InputError
        ``name`` is not in :data:`LABEL_SETS`; the message lists the names.
    """
    if isinstance(name, LabelSet):
        return name
    try:
        return LABEL_SETS[str(name).lower()]
    except KeyError:
        raise InputError(f"unknown label set {name!r}; use one of "
                         f"{', '.join(LABEL_SETS)}") from None
