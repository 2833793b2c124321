"""The facade found in a photo as a :class:`~facadeforge.model.Shape` tree (Müller 2007, §5).

The same type the engine derives, so rules extraction, rasterising and exporting treat a
photo's analysis and a derivation alike.  Convention (what :mod:`facadeforge.grammar.extract`
reads):

- metres, facade frame: origin at the bottom-left corner, x right, y up, every scope flat
  (``size[2] == 0``); the root ``Facade`` spans ``W × H``;
- every internal node is split along one axis; its split children carry
  ``operator="split"`` and ``params={"axis": "x"|"y", "index": i}`` (plus ``"split"``: the §3.1
  split type, on tile refinements), are ordered by increasing coordinate — floors bottom
  first — and tile the node exactly (the *partition*);
- ``Facade → Floor (axis y) → Tile (axis x) → Region …`` with ``tags["cluster"]`` on every
  node below the root (same cluster = same appearance), ``tags["box_px"]`` the rectified pixel
  box ``[x0, y0, x1, y1]`` (rows down) and ``tags["confidence"]`` where known;
- leaves carry a canonical ``label`` and, for elements, ``tags["element"]`` (library name),
  ``tags["depth"]`` (metres, negative = recessed) and ``tags["asset"]`` (relative OBJ path);
- **protruding elements** (balconies) are not part of the partition.  They are leaf children
  with ``operator="insert"`` (:data:`facadeforge.model.shape.INSERT`) and
  ``params={"index": k}`` (left to right) of the split shape they stand in front of — the tile
  of the window whose foot they hide, or the floor when a balcony band runs in front of
  several tiles — after its split children: ``Region`` leaves with ``tags["cluster"]``
  ``"<host cluster>.p<k>"``, a positive depth and a library balcony.  Their scope may reach
  beyond the host's (a balcony hanging below its floor line).  The partition behind them stays
  whole: the window behind a railing is still a window, as CMP labels it (balcony pixels
  painted over window and wall) and as it is in 3D (Müller 2007 §4–5: the balcony is a
  library element inserted in front of the facade plane, not a wall region).
  :meth:`Shape.painting_order` — hence :func:`facadeforge.exchange.raster.label_map` — puts
  inserted shapes after the partition's leaves, and :mod:`facadeforge.grammar.extract` emits
  them as ``[ t(…) s(…) Balcony_… ]`` branches before the host's split.  (The alternative, a
  balcony band at the bottom of the tile's partition, would cut every window behind a railing
  in two, and give the 3D model a strip of the facade plane labelled balcony instead of a
  balcony standing in front of it.)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..model.scope import Scope
from ..model.shape import INSERT, Shape

__all__ = ["PixelFrame", "build_shape_tree"]

_Y_SPLITS = ("top", "bottom", "dual-y")


@dataclass(frozen=True)
class PixelFrame:
    """Rectified image of ``width × height`` pixels at ``px_per_m`` = ``(mx, my)``."""

    width: int
    height: int
    px_per_m: tuple[float, float]

    @property
    def size_m(self) -> tuple[float, float]:
        return self.width / self.px_per_m[0], self.height / self.px_per_m[1]

    def scope(self, box: Sequence[float]) -> Scope:
        """Facade-frame scope (metres, y up) of a pixel box ``x0, y0, x1, y1`` (rows down)."""
        x0, y0, x1, y1 = (float(v) for v in box)
        mx, my = self.px_per_m
        return Scope((x0 / mx, (self.height - y1) / my, 0.0), np.eye(3),
                     ((x1 - x0) / mx, (y1 - y0) / my, 0.0))


def _node(symbol: str, frame: PixelFrame, box, cluster: str, axis: str, index: int,
          **tags) -> Shape:
    node = Shape(symbol, frame.scope(box), operator="split", params={"axis": axis, "index": index})
    node.tags = {"cluster": cluster, "box_px": [int(v) for v in box], **tags}
    return node


def _attach(parent: Shape, children: list[Shape]) -> None:
    for c in children:
        c.parent = parent
    parent.children = children


def _region_children(frame: PixelFrame, region, cluster: str,
                     leaf_info: Callable[[object, str], dict]) -> list[Shape]:
    kind = region.split
    axis = "y" if kind in _Y_SPLITS else "x"
    subs = list(region.children)
    order = list(reversed(range(len(subs)))) if axis == "y" else list(range(len(subs)))
    out = []
    for index, k in enumerate(order):
        sub = subs[k]
        sub_cluster = f"{cluster}.{k}"
        node = _node("Region", frame, sub.box, sub_cluster, axis, index, split=kind,
                     confidence=round(float(getattr(region, "strength", 0.0)), 4))
        _fill(node, frame, sub, sub_cluster, leaf_info)
        out.append(node)
    return out


def _fill(node: Shape, frame: PixelFrame, region, cluster: str,
          leaf_info: Callable[[object, str], dict]) -> None:
    if region is not None and region.children:
        _attach(node, _region_children(frame, region, cluster, leaf_info))
        return
    info = dict(leaf_info(region, cluster)) if region is not None else {"label": "wall"}
    node.label = info.pop("label", "wall")
    node.tags.update({k: v for k, v in info.items() if v is not None})


def _hang(host: Shape, frame: PixelFrame, fronts: Sequence[object],
          leaf_info: Callable[[object, str], dict]) -> None:
    """Append the protruding element leaves ``fronts`` (left to right) to ``host``."""
    for k, region in enumerate(fronts):
        node = Shape("Region", frame.scope(region.box), operator=INSERT, params={"index": k})
        cluster = f"{host.tags['cluster']}.p{k}"
        node.tags = {"cluster": cluster, "box_px": [int(v) for v in region.box],
                     "confidence": round(float(getattr(region, "strength", 0.0)), 4)}
        _fill(node, frame, region, cluster, leaf_info)
        node.parent = host
        host.children.append(node)


def build_shape_tree(frame: PixelFrame, floors: Sequence[tuple[int, int]],
                     tiles: Sequence[Sequence[tuple[int, int]]], floor_clusters: Sequence[int],
                     tile_clusters: Sequence[Sequence[int]], *,
                     regions: Sequence[Sequence[object]] | None = None,
                     leaf_info: Callable[[object, str], dict] | None = None,
                     floor_confidence: Sequence[float] = (),
                     tile_confidence: Sequence[Sequence[float]] = (),
                     fronts: Sequence[Sequence[tuple[int | None, object]]] = ()) -> Shape:
    """Shape tree of an analysed facade.

    Parameters
    ----------
    frame : PixelFrame
        Rectified image size and scale.
    floors : list of (y0, y1)
        Floor bands, **top to bottom** as found in the image (rows, exclusive ends).
    tiles : list of list of (x0, x1)
        Per floor, its tiles left to right.
    floor_clusters, tile_clusters
        Cluster ids of floors and (per floor) of tiles.
    regions : per floor, per tile, a region tree, optional
        Tile refinements (:func:`facadeforge.imaging.refine.refine_tiles`); ``None`` entries or
        no refinement leave the tile a wall leaf.
    leaf_info : callable ``(region, cluster) -> dict``
        Label and tags of a refinement leaf (``{"label": "window", "element": …, "depth": …}``).
    floor_confidence : one per floor boundary, top to bottom
        Stored on the floor *above* each boundary line as ``tags["confidence"]``.
    tile_confidence : per floor, one per tile boundary
        Stored on the tile left of each boundary.
    fronts : per floor, ``(tile index or None, leaf region)`` pairs, optional
        Protruding elements hung on a tile or (``None``, or a tile that is a leaf) on the
        floor, inserted outside the partition (module docstring;
        :attr:`~.element_layout.ElementLayout.fronts`).  Their labels and tags come from
        ``leaf_info`` too.
    """
    leaf_info = leaf_info or (lambda region, cluster: {"label": getattr(region, "role", "")
                                                       or "wall"})
    root = Shape("Facade", frame.scope((0, 0, frame.width, frame.height)))
    root.tags = {"box_px": [0, 0, int(frame.width), int(frame.height)]}
    floor_nodes = []
    n = len(floors)
    for index, i in enumerate(reversed(range(n))):       # bottom floor first
        y0, y1 = floors[i]
        conf = floor_confidence[i - 1] if 0 < i <= len(floor_confidence) else None
        fnode = _node("Floor", frame, (0, y0, frame.width, y1), f"F{floor_clusters[i]}", "y",
                      index, confidence=conf)
        tnodes = []
        for j, (x0, x1) in enumerate(tiles[i]):
            tconf = tile_confidence[i][j] if i < len(tile_confidence) and j < len(
                tile_confidence[i]) else None
            cluster = f"T{tile_clusters[i][j]}"
            tnode = _node("Tile", frame, (x0, y0, x1, y1), cluster, "x", j, confidence=tconf)
            region = regions[i][j] if regions is not None else None
            _fill(tnode, frame, region, cluster, leaf_info)
            tnodes.append(tnode)
        _attach(fnode, tnodes)
        hung = fronts[i] if i < len(fronts) else ()
        for j, tnode in enumerate(tnodes):
            if tnode.children:        # a leaf tile keeps its label: its fronts go to the floor
                _hang(tnode, frame, [r for k, r in hung if k == j], leaf_info)
        _hang(fnode, frame, [r for k, r in hung
                             if k is None or not 0 <= k < len(tnodes) or not tnodes[k].children],
              leaf_info)
        floor_nodes.append(fnode)
    _attach(root, floor_nodes)
    for node in root.walk():                              # drop unknown confidences
        if node.tags.get("confidence") is None:
            node.tags.pop("confidence", None)
    return root
