"""Canonical semantic vocabulary shared by the engine, the image analysis and the benchmarks."""

from __future__ import annotations

import re
from enum import StrEnum
from functools import lru_cache


class Labels(StrEnum):
    """Canonical labels (ARCHITECTURE.md, "One data model").

    The value is the lower-case name, so a label serialises as itself in JSON, glTF extras and
    CityJSON attributes.
    """

    BACKGROUND = "background"
    WALL = "wall"
    WINDOW = "window"
    DOOR = "door"
    BALCONY = "balcony"
    SHOP = "shop"
    ROOF = "roof"
    SKY = "sky"
    CORNICE = "cornice"
    SILL = "sill"
    BLIND = "blind"
    DECO = "deco"
    MOLDING = "molding"
    PILLAR = "pillar"
    VEGETATION = "vegetation"
    OTHER = "other"
    GROUND = "ground"
    # Occluders and the street (LabelMeFacade labels them); appended so earlier indices stay.
    CAR = "car"
    PERSON = "person"
    PAVEMENT = "pavement"
    ROAD = "road"


# Words found in rule names written by people (``Window``, ``WindowFrame``, ``GroundFloorDoor``,
# ``RoofTile``…) and the label they most likely mean.  Order matters: the first hit wins, so more
# specific words come first ("balcony" before "floor", "shopwindow" is a shop).  A plain string
# matches anywhere in the lower-cased letters of the name; a compiled pattern must match a whole
# word of it (``CarBody`` → car, ``ParkedCars`` → car, but ``CarriageBay``, ``Cartouche`` and
# ``Broadway`` are no cars or roads, and ``Street`` holds no tree).  The street comes last:
# ``StreetFacade`` and ``StreetFloor`` are wall, only a bare ``Street`` is the road.
_NAME_HINTS: tuple[tuple[str | re.Pattern[str], Labels], ...] = (
    ("shop", Labels.SHOP),
    ("storefront", Labels.SHOP),
    ("door", Labels.DOOR),
    ("entrance", Labels.DOOR),
    (re.compile(r"cars?"), Labels.CAR),
    ("vehicle", Labels.CAR),
    ("pedestrian", Labels.PERSON),
    ("person", Labels.PERSON),
    ("people", Labels.PERSON),
    ("balcon", Labels.BALCONY),
    ("railing", Labels.BALCONY),
    ("window", Labels.WINDOW),
    ("glass", Labels.WINDOW),
    ("win", Labels.WINDOW),
    ("shutter", Labels.BLIND),
    ("blind", Labels.BLIND),
    ("sill", Labels.SILL),
    ("cornice", Labels.CORNICE),
    ("ledge", Labels.CORNICE),
    ("molding", Labels.MOLDING),
    ("moulding", Labels.MOLDING),
    ("pillar", Labels.PILLAR),
    ("column", Labels.PILLAR),
    ("pilaster", Labels.PILLAR),
    ("deco", Labels.DECO),
    ("ornament", Labels.DECO),
    ("roof", Labels.ROOF),
    ("chimney", Labels.ROOF),
    (re.compile(r"tree.*|.*trees?"), Labels.VEGETATION),
    ("plant", Labels.VEGETATION),
    ("pavement", Labels.PAVEMENT),
    ("sidewalk", Labels.PAVEMENT),
    (re.compile(r"roads?|roadway"), Labels.ROAD),
    ("ground", Labels.GROUND),
    ("wall", Labels.WALL),
    ("facade", Labels.WALL),
    ("floor", Labels.WALL),
    ("tile", Labels.WALL),
    ("street", Labels.ROAD),
)

# Words of a name: camel-case humps, upper-case runs and lower-case runs (``CarBody`` → car,
# body; ``GLASS_Car`` → glass, car).
_WORDS = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+")


@lru_cache(maxsize=4096)
def label_for_name(name: str) -> Labels | None:
    """Guess the canonical label of a rule or material name, or ``None`` when nothing fits.

    Parameters
    ----------
    name : str
        A rule name such as ``"WindowFrame"`` or a label string such as ``"window"``.
    """
    key = re.sub(r"[^a-z]", "", name.lower())
    try:
        return Labels(key)
    except ValueError:
        pass
    words: list[str] | None = None
    for hint, label in _NAME_HINTS:
        if isinstance(hint, str):
            if hint in key:
                return label
            continue
        if words is None:
            words = [w.lower() for w in _WORDS.findall(name)]
        if any(hint.fullmatch(w) for w in words):
            return label
    return None
