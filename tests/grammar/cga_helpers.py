"""Small helpers the grammar tests share: derive rule text on a lot or a polygon, and sum the
result by rule name."""

from facadeforge import derive, load_rules
from facadeforge.geometry.footprints import Footprint


def run(src, lot="10x8", poly=None):
    """The model of ``src`` derived on a ``lot`` (``"WxD"``) or on the polygon ``poly``."""
    fp = [Footprint("fp", poly)] if poly is not None else None
    return derive(load_rules(src), fp, lot_size=None if fp else lot)[0]


def areas(model) -> dict:
    """Total area per leaf rule name."""
    out = {}
    for p in model.parts:
        out[p.symbol] = out.get(p.symbol, 0.0) + p.mesh.area()
    return out


def by_symbol(model) -> dict:
    """The parts per leaf rule name."""
    out = {}
    for p in model.parts:
        out.setdefault(p.symbol, []).append(p)
    return out
