"""Edits of a facade shape tree, as Müller et al.'s GUI makes them (§5, Fig. 12; §7 "Practical
modeling"): move a split line, set a cluster's depth, change an element, reverse or retype a
tile's split, add or remove a floor or a column.

An edit is a JSON object (what the page's ``window.facadeforge.apply(edit)`` sends):

=================  ==========================================================================
``op``             fields
=================  ==========================================================================
``move_split``     ``path``, ``index`` K, ``delta`` metres: the boundary between partition
                   children K−1 and K of the shape at ``path`` moves by ``delta`` along the
                   split axis (x right, y up)
``set_depth``      ``path`` of a leaf, ``depth`` metres (< 0 recessed, > 0 protruding)
``set_label``      ``path`` of a leaf, ``label`` (a canonical label: ``window``, ``door``…)
``set_element``    ``path`` of a leaf, ``element``: a library element's name, or ``null`` for
                   a plain box
``set_split``      ``path`` of a shape, ``split``: ``left right dual-x`` (x) or
                   ``top bottom dual-y`` (y), how its parts adapt to other sizes
``reverse_split``  ``path``: its partition children in the opposite order
``add``            ``path`` of a partition child: a copy of it beside it (a floor, a column);
                   its siblings shrink to make room
``remove``         ``path`` of a partition child: it goes, its siblings grow into its place
``reanalyse``      ``path``: the photo analysis run again inside that shape only, all else
                   held as the user left it (:mod:`.reanalyse`; needs the photo, so only
                   through :class:`~facadeforge.editor.session.EditSession`)
=================  ==========================================================================

A shape is addressed by ``path``, the child indices from the root (``[]`` is the facade,
``[0]`` its first child, as listed in ``shape_tree.json``).  Every edit applies to the shape's
whole *cluster* — the shapes of the same symbol and cluster id, which become one rule — as
split synchronisation does (§3.1): moving one window column's boundary moves it in every tile
of the cluster.  Sizes below a shape that changes size are laid out again the way its rules
let them adapt: the outer parts of a dual split take the change, a single split's bigger part,
otherwise all parts in proportion; shapes inserted in front (balconies) keep their height above
their host's bottom and their share of its width.

Edits check everything before they change anything: a bad edit raises :class:`EditError` (an
:class:`~facadeforge.errors.InputError`) that names the field and the fix, and leaves the tree
as it was.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping

import numpy as np

from ..errors import InputError
from ..model.labels import Labels
from ..model.shape import INSERT, Shape

__all__ = ["EDIT_OPS", "MAX_DELTA_M", "MAX_DEPTH_M", "MIN_PART_M", "EditError", "apply_edit",
           "cluster_of", "node_at", "partition", "update_boxes"]

#: Smallest size (metres) a part keeps along its split axis after an edit.
MIN_PART_M: float = 0.05
#: Largest split-line move of one edit (metres).
MAX_DELTA_M: float = 200.0
#: Largest depth (metres, either way), as ``--depths`` allows.
MAX_DEPTH_M: float = 20.0
#: Deepest path accepted (a facade tree is a handful of levels deep).
MAX_PATH: int = 64
_AXES = {"x": 0, "y": 1}
_SPLITS = {"x": ("left", "right", "dual-x"), "y": ("top", "bottom", "dual-y")}
_MIRROR = {"left": "right", "right": "left", "top": "bottom", "bottom": "top"}


class EditError(InputError):
    """An edit that cannot apply: the message names the field and what would work."""


EDIT_OPS = ("move_split", "set_depth", "set_label", "set_element", "set_split",
            "reverse_split", "add", "remove", "reanalyse")


# -- addressing -----------------------------------------------------------------------------------

def _path(edit: Mapping, key: str = "path") -> list[int]:
    p = edit.get(key)
    if not isinstance(p, list) or len(p) > MAX_PATH or not all(
            isinstance(i, int) and not isinstance(i, bool) for i in p):
        raise EditError(f"edit {key!r} must be a list of child indices such as [0, 2] "
                        f"(at most {MAX_PATH}), not {p!r}")
    return p


def node_at(tree: Shape, path: list[int]) -> Shape:
    """The shape at ``path`` (child indices from ``tree``)."""
    node = tree
    for depth, i in enumerate(path):
        if not 0 <= i < len(node.children):
            raise EditError(f"path {path}: shape {path[:depth]} has {len(node.children)} "
                            f"children, no child {i}")
        node = node.children[i]
    return node


def partition(node: Shape) -> tuple[list[Shape], str | None]:
    """The children of ``node``'s split (not those inserted in front), in increasing coordinate
    along the split axis, and that axis (``None`` for a leaf)."""
    kids = [c for c in node.children if c.operator != INSERT]
    if not kids:
        return [], None
    axis = next((c.params.get("axis") for c in kids if c.params.get("axis") in _AXES), None)
    if axis is None:   # stacked in y when every child spans the parent's width
        w = float(node.scope.size[0])
        axis = "y" if all(abs(float(c.scope.size[0]) - w) <= 1e-6 * max(w, 1.0)
                          for c in kids) else "x"
    k = _AXES[axis]
    return sorted(kids, key=lambda c: float(c.scope.origin[k])), axis


def cluster_of(tree: Shape, node: Shape) -> list[Shape]:
    """The shapes that share ``node``'s rule: same symbol and cluster id (``node`` alone when it
    has none); for shapes with children, also the same number of parts on the same axis."""
    cid = node.tags.get("cluster")
    if cid is None:
        return [node]
    kids, axis = partition(node)
    out = []
    for s in tree.walk():
        if s.symbol != node.symbol or s.tags.get("cluster") != cid:
            continue
        if node.children:
            k2, a2 = partition(s)
            if len(k2) != len(kids) or a2 != axis:
                continue
        out.append(s)
    return out


# -- layout ---------------------------------------------------------------------------------------

def _absorb(node: Shape, kids: list[Shape], k: int, change: float) -> list[float]:
    """New sizes along axis ``k`` of ``kids`` when ``node`` changes size by ``change``."""
    sizes = [float(c.scope.size[k]) for c in kids]
    total = sum(sizes) + change
    split = kids[0].params.get("split") or kids[0].tags.get("split")
    n = len(kids)
    if split in ("dual-x", "dual-y") and n == 3:
        takers = [0, 2]
    elif split in _MIRROR and n == 2:
        takers = [int(np.argmax(sizes))]
    else:
        takers = list(range(n))
    share = sum(sizes[j] for j in takers)
    new = list(sizes)
    for j in takers:
        new[j] += change * (sizes[j] / share if share > 0 else 1.0 / len(takers))
    if min(new) < MIN_PART_M * 0.999 or total <= 0:   # the takers cannot give it: all scale
        f = total / max(sum(sizes), 1e-12)
        new = [s * f for s in sizes]
    return new


def relayout(node: Shape, k: int, lo: float, hi: float) -> None:
    """Give ``node`` the extent ``[lo, hi]`` along axis ``k`` and lay its subtree out again."""
    old_lo, old_size = float(node.scope.origin[k]), float(node.scope.size[k])
    size = hi - lo
    node.scope.origin[k] = lo
    node.scope.size[k] = size
    kids, axis = partition(node)
    if kids:
        if _AXES[axis] == k:
            pos = lo
            for c, s in zip(kids, _absorb(node, kids, k, size - old_size)):
                relayout(c, k, pos, pos + s)
                pos += s
        else:
            for c in kids:
                relayout(c, k, lo, hi)
    for c in node.children:
        if c.operator != INSERT:
            continue
        c_lo, c_size = float(c.scope.origin[k]), float(c.scope.size[k])
        if k == 0:   # a share of the host's width
            f = size / old_size if old_size > 0 else 1.0
            relayout(c, k, lo + (c_lo - old_lo) * f, lo + (c_lo - old_lo + c_size) * f)
        else:        # metres above the host's bottom, kept inside the host
            c_size = min(c_size, size)
            start = min(lo + (c_lo - old_lo), hi - c_size)
            relayout(c, k, start, start + c_size)


def update_boxes(tree: Shape) -> None:
    """Recompute every ``box_px`` tag from the scopes (the root's box gives the pixel frame:
    x right, y down from the facade's top)."""
    box = tree.tags.get("box_px")
    if not box:
        return
    x0, y0, x1, y1 = (float(v) for v in box)
    w, h = float(tree.scope.size[0]), float(tree.scope.size[1])
    if w <= 0 or h <= 0:
        return
    sx, sy = (x1 - x0) / w, (y1 - y0) / h
    ox, oy = float(tree.scope.origin[0]), float(tree.scope.origin[1])
    for s in tree.walk():
        if "box_px" not in s.tags:
            continue
        a, b = float(s.scope.origin[0]) - ox, float(s.scope.origin[1]) - oy
        s.tags["box_px"] = [int(round(x0 + a * sx)), int(round(y1 - (b + s.scope.size[1]) * sy)),
                            int(round(x0 + (a + s.scope.size[0]) * sx)), int(round(y1 - b * sy))]


def _relabel_indices(node: Shape) -> None:
    kids, _ = partition(node)
    for j, c in enumerate(kids):
        if "index" in c.params:
            c.params["index"] = j


# -- the edits ------------------------------------------------------------------------------------

def _number(edit: Mapping, key: str, limit: float) -> float:
    v = edit.get(key)
    try:
        ok = not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
    except OverflowError:         # an integer of hundreds of digits
        ok = False
    if not ok:
        raise EditError(f"edit {key!r} must be a number of metres, not {str(v)[:40]!r}")
    if abs(v) > limit:
        raise EditError(f"edit {key!r} = {v} m is beyond ±{limit:g} m")
    return float(v)


def _leaf(tree: Shape, edit: Mapping) -> tuple[Shape, list[Shape]]:
    node = node_at(tree, _path(edit))
    if any(c.operator != INSERT for c in node.children):
        raise EditError(f"path {edit['path']} is a {node.symbol} split into parts, not an "
                        "element; give the path of a leaf (an element or a wall piece)")
    return node, [s for s in cluster_of(tree, node) if not any(
        c.operator != INSERT for c in s.children)]


def _move_split(tree: Shape, edit: Mapping) -> dict:
    node = node_at(tree, _path(edit))
    kids, axis = partition(node)
    index = edit.get("index")
    if isinstance(index, bool) or not isinstance(index, int) or not 1 <= index < len(kids):
        raise EditError(f"edit 'index' must be a boundary 1..{len(kids) - 1} between the "
                        f"{len(kids)} parts of shape {edit['path']}, not {index!r}"
                        if len(kids) > 1 else
                        f"shape {edit['path']} ({node.symbol}) has no split line to move")
    delta = _number(edit, "delta", MAX_DELTA_M)
    k = _AXES[axis]
    members = cluster_of(tree, node)
    lo_room = min(float(partition(m)[0][index - 1].scope.size[k]) for m in members) - MIN_PART_M
    hi_room = min(float(partition(m)[0][index].scope.size[k]) for m in members) - MIN_PART_M
    applied = max(-max(lo_room, 0.0), min(delta, max(hi_room, 0.0)))
    for m in members:
        mk, _ = partition(m)
        a, b = mk[index - 1], mk[index]
        a_lo, b_hi = float(a.scope.origin[k]), float(b.scope.origin[k] + b.scope.size[k])
        cut = float(b.scope.origin[k]) + applied
        relayout(a, k, a_lo, cut)
        relayout(b, k, cut, b_hi)
    return {"axis": axis, "applied_delta": round(applied, 6), "shapes": len(members)}


def _set_depth(tree: Shape, edit: Mapping) -> dict:
    node, members = _leaf(tree, edit)
    depth = _number(edit, "depth", MAX_DEPTH_M)
    before = node.tags.get("depth")
    for s in members:
        s.tags["depth"] = depth
    return {"shapes": len(members), "before": before}


def _set_label(tree: Shape, edit: Mapping) -> dict:
    node, members = _leaf(tree, edit)
    label = edit.get("label")
    known = [m.value for m in Labels]
    if label not in known:
        raise EditError(f"edit 'label' must be one of {', '.join(known)}, not {label!r}")
    before = node.label
    for s in members:
        s.label = label
        if label == "wall":
            s.tags.pop("element", None)
            s.tags.pop("asset", None)
            s.tags.pop("depth", None)
    return {"shapes": len(members), "before": before}


def _set_element(tree: Shape, edit: Mapping) -> dict:
    from ..elements.library import element_library

    node, members = _leaf(tree, edit)
    name = edit.get("element")
    before = node.tags.get("element")
    if name is None:
        for s in members:
            s.tags.pop("element", None)
            s.tags.pop("asset", None)
        return {"shapes": len(members), "before": before}
    specs = {s.name: s for s in element_library()}
    if name not in specs:
        raise EditError(f"edit 'element' {name!r} is not in the element library; choose one "
                        f"of {len(specs)} such as {', '.join(sorted(specs)[:4])}, or null")
    spec = specs[name]
    for s in members:
        s.tags["element"] = name
        s.tags["asset"] = f"assets/{name}.obj"
        s.label = spec.kind
        if "depth" not in s.tags or (s.tags["depth"] < 0) != (spec.mount == "recess"):
            s.tags["depth"] = -spec.default_depth if spec.mount == "recess" \
                else spec.default_depth
    return {"shapes": len(members), "before": before, "label": spec.kind}


def _split_members(tree: Shape, edit: Mapping) -> tuple[Shape, str, list[Shape]]:
    node = node_at(tree, _path(edit))
    kids, axis = partition(node)
    if len(kids) < 2:
        raise EditError(f"shape {edit['path']} ({node.symbol}) is not split into parts")
    return node, axis, cluster_of(tree, node)


def _set_split(tree: Shape, edit: Mapping) -> dict:
    node, axis, members = _split_members(tree, edit)
    split = edit.get("split")
    n = len(partition(node)[0])
    allowed = [s for s in _SPLITS[axis] if (n == 3) == s.startswith("dual")]
    if split not in allowed:
        raise EditError(f"edit 'split' for the {n} parts of shape {edit['path']} (split in "
                        f"{axis}) must be one of {', '.join(allowed) or 'none'}, not {split!r}")
    before = partition(node)[0][0].params.get("split") or partition(node)[0][0].tags.get("split")
    for m in members:
        for c in partition(m)[0]:
            c.params["split"] = split
            c.tags["split"] = split
    return {"shapes": len(members), "before": before}


def _reverse_split(tree: Shape, edit: Mapping) -> dict:
    node, axis, members = _split_members(tree, edit)
    k = _AXES[axis]
    for m in members:
        kids, _ = partition(m)
        lo = float(m.scope.origin[k])
        pos = lo
        for c in reversed(kids):
            s = float(c.scope.size[k])
            relayout(c, k, pos, pos + s)
            pos += s
            for d in (c.params, c.tags):
                if d.get("split") in _MIRROR:
                    d["split"] = _MIRROR[d["split"]]
        inserts = [c for c in m.children if c.operator == INSERT]
        m.children[:] = list(reversed(kids)) + inserts
        _relabel_indices(m)
    return {"shapes": len(members)}


def _child_edit(tree: Shape, edit: Mapping) -> tuple[Shape, int, str, list[Shape]]:
    path = _path(edit)
    if not path:
        raise EditError("edit 'path' [] is the facade itself; give the path of a floor or a "
                        "column (a part of a split)")
    parent = node_at(tree, path[:-1])
    node = node_at(tree, path)
    if node.operator == INSERT:
        raise EditError(f"path {path} is a shape inserted in front ({node.symbol}), not a part "
                        "of a split")
    kids, axis = partition(parent)
    return parent, kids.index(node), axis, cluster_of(tree, parent)


def _fit(parent: Shape, kids: list[Shape], k: int) -> None:
    """Lay ``kids`` out over ``parent`` along ``k``, scaled in proportion to fill it."""
    lo, size = float(parent.scope.origin[k]), float(parent.scope.size[k])
    total = sum(float(c.scope.size[k]) for c in kids)
    pos = lo
    for c in kids:
        s = float(c.scope.size[k]) * size / total
        relayout(c, k, pos, pos + s)
        pos += s


def _add(tree: Shape, edit: Mapping) -> dict:
    parent, j, axis, members = _child_edit(tree, edit)
    k = _AXES[axis]
    for m in members:
        kids, _ = partition(m)
        twin = Shape.from_dict(kids[j].to_dict())   # same clusters: the copy repeats the rule
        kids.insert(j + 1, twin)                    # it keeps its size, then all shrink to fit
        inserts = [c for c in m.children if c.operator == INSERT]
        m.children[:] = []
        for c in kids + inserts:
            m.add(c)
        _fit(m, kids, k)
        _relabel_indices(m)
        if min(float(c.scope.size[k]) for c in kids) < MIN_PART_M:
            raise EditError(f"no room for another {twin.symbol} in shape {edit['path'][:-1]}")
    return {"shapes": len(members), "parts": len(partition(parent)[0])}


def _remove(tree: Shape, edit: Mapping) -> dict:
    parent, j, axis, members = _child_edit(tree, edit)
    k = _AXES[axis]
    kids, _ = partition(parent)
    if len(kids) < 2:
        raise EditError(f"shape {edit['path']} is the only part of its parent; remove the "
                        "parent's split instead")
    for m in members:
        kids, _ = partition(m)
        gone = kids.pop(j)
        m.children.remove(gone)
        _fit(m, kids, k)
        _relabel_indices(m)
    return {"shapes": len(members), "parts": len(kids)}


_OPS = {"move_split": _move_split, "set_depth": _set_depth, "set_label": _set_label,
        "set_element": _set_element, "set_split": _set_split, "reverse_split": _reverse_split,
        "add": _add, "remove": _remove}


def apply_edit(tree: Shape, edit: Mapping) -> dict:
    """Apply ``edit`` (module docstring) to ``tree`` in place; returns what it did (the shapes
    it changed, the delta applied after clamping, the value before).  A bad edit raises
    :class:`EditError` and changes nothing (it is tried on a copy first)."""
    if not isinstance(edit, Mapping):
        raise EditError(f"an edit is an object such as {{\"op\": \"set_depth\", \"path\": [0, 1], "
                        f"\"depth\": -0.3}}, not {type(edit).__name__}")
    op = edit.get("op")
    if op == "reanalyse":
        raise EditError("edit 'reanalyse' needs the facade's photo: apply it through "
                        "facadeforge.editor.session.EditSession (the editor's page does)")
    if op not in _OPS:
        raise EditError(f"edit 'op' {op!r} is unknown; use one of {', '.join(EDIT_OPS)}")
    trial = copy.deepcopy(tree)
    _OPS[op](trial, edit)                  # raises before the real tree is touched
    done = _OPS[op](tree, edit)
    update_boxes(tree)
    return done
