"""Re-running the analysis on part of a facade, with everything the user fixed held constant.

The edit ``{"op": "reanalyse", "path": P}`` takes the shape at ``P`` (a floor, a tile, a run of
the facade the user finds wrong) and runs the photo analysis of ``facadeforge reconstruct``
(:func:`facadeforge.reconstruction.reconstruct`: classifier, floors, tiles, refinement, element
matching) on that shape's rectangle of the rectified photo only.  The shape keeps its place and
size, every shape outside it stays as the user left it (split lines moved, depths set…); its
children are replaced by what the analysis finds inside it, mapped from the crop's pixels onto
the shape's rectangle.  The new shapes get cluster ids of their own (``R1.T3``), so they form
rules of their own and never merge with clusters outside.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import FacadeForgeError
from ..model.shape import Shape
from .edits import EditError, _path, node_at, update_boxes

__all__ = ["MIN_REANALYSE_PX", "reanalyse"]

#: Smallest side (pixels of the rectified photo) of a region that is analysed again.
MIN_REANALYSE_PX: int = 24


def _box(tree: Shape, node: Shape, image_hw: tuple[int, int]) -> tuple[int, int, int, int]:
    """``node``'s rectangle in the photo's pixels (from the scopes: ``box_px`` may be stale)."""
    h_px, w_px = image_hw
    if tree.tags.get("box_px"):
        x0, y0, x1, y1 = (float(v) for v in tree.tags["box_px"])
    else:
        x0, y0, x1, y1 = 0.0, 0.0, float(w_px), float(h_px)
    sx = (x1 - x0) / float(tree.scope.size[0])
    sy = (y1 - y0) / float(tree.scope.size[1])
    a = float(node.scope.origin[0] - tree.scope.origin[0])
    b = float(node.scope.origin[1] - tree.scope.origin[1])
    box = (x0 + a * sx, y1 - (b + float(node.scope.size[1])) * sy,
           x0 + (a + float(node.scope.size[0])) * sx, y1 - b * sy)
    return (max(0, int(round(box[0]))), max(0, int(round(box[1]))),
            min(w_px, int(round(box[2]))), min(h_px, int(round(box[3]))))


def reanalyse(tree: Shape, edit: Mapping, rgb: np.ndarray, *, counter: int = 1) -> dict:
    """Apply a ``reanalyse`` edit (module docstring) to ``tree`` in place, on the rectified
    photo ``rgb`` the tree was found in; returns what it found.  Raises :class:`EditError` for
    a region too small or one the analysis cannot model (the tree is unchanged then)."""
    path = _path(edit)
    node = node_at(tree, path)
    x0, y0, x1, y1 = _box(tree, node, rgb.shape[:2])
    if min(x1 - x0, y1 - y0) < MIN_REANALYSE_PX:
        raise EditError(f"shape {path} is {x1 - x0}x{y1 - y0} px of the photo; reanalyse a "
                        f"region at least {MIN_REANALYSE_PX} px on each side")
    from ..reconstruction import reconstruct

    crop = np.ascontiguousarray(rgb[y0:y1, x0:x1])
    try:
        rec = reconstruct(crop, rectified=True, width_m=float(node.scope.size[0]),
                          height_m=float(node.scope.size[1]), model=False, repair=False)
    except (FacadeForgeError, ValueError) as e:
        raise EditError(f"reanalyse {path}: the analysis found no facade structure there "
                        f"({str(e).splitlines()[0]}); select a larger region") from None
    sub = rec.tree
    sb = sub.tags.get("box_px")
    if not sb or not sub.children:
        raise EditError(f"reanalyse {path}: the analysis found nothing to lay out there")
    while len(sub.children) == 1 and sub.children[0].children:   # a lone floor: its parts
        sub.children[0].tags["box_px"] = sb
        sub = sub.children[0]
    bx0, by0, bx1, by1 = (float(v) for v in sb)
    ox, oy = float(node.scope.origin[0]), float(node.scope.origin[1])
    sx = float(node.scope.size[0]) / max(bx1 - bx0, 1e-9)
    sy = float(node.scope.size[1]) / max(by1 - by0, 1e-9)
    prefix = f"R{counter}."
    for s in sub.walk():
        b = s.tags.get("box_px")
        if b is None:
            raise EditError(f"reanalyse {path}: the analysis returned a shape without a box")
        u0, v0, u1, v1 = (float(v) for v in b)
        s.scope.origin[0] = ox + (u0 - bx0) * sx
        s.scope.origin[1] = oy + (by1 - v1) * sy
        s.scope.size[0] = (u1 - u0) * sx
        s.scope.size[1] = (v1 - v0) * sy
        if "cluster" in s.tags:
            s.tags["cluster"] = prefix + str(s.tags["cluster"])
        s.tags["box_px"] = [0, 0, 0, 0]            # recomputed from the scopes below
    node.children[:] = []
    for c in sub.children:
        node.add(c)
    node.tags["reanalysed"] = True
    update_boxes(tree)
    found = {}
    for s in node.leaves():
        if s.label and s.label != "wall":
            found[s.label] = found.get(s.label, 0) + 1
    return {"shapes": sum(1 for _ in node.walk()) - 1, "elements": found,
            "region_px": [x0, y0, x1, y1]}

