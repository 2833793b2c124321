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


# Words found in rule names written by people (``Window``, ``WindowFrame``, ``GroundFloorDoor``,
# ``RoofTile``…) and the label they most likely mean.  Order matters: the first hit wins, so more
# specific words come first ("balcony" before "floor", "shopwindow" is a shop).
_NAME_HINTS: tuple[tuple[str, Labels], ...] = (
    ("shop", Labels.SHOP),
    ("storefront", Labels.SHOP),
    ("door", Labels.DOOR),
    ("entrance", Labels.DOOR),
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
    ("tree", Labels.VEGETATION),
    ("plant", Labels.VEGETATION),
    ("ground", Labels.GROUND),
    ("wall", Labels.WALL),
    ("facade", Labels.WALL),
    ("floor", Labels.WALL),
    ("tile", Labels.WALL),
)


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
    for word, label in _NAME_HINTS:
        if word in key:
            return label
    return None
