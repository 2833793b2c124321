"""Shape tree → size-independent CGA rules (Müller et al. 2007, §5 "Editing and Rule Extraction").

The facade found in a photo (:mod:`facadeforge.imaging.shape_tree`) is a tree of splits:
``Facade → Floor (y) → Tile (x) → Region …`` with a cluster id on every node below the root.
:func:`extract_rules` encodes it as CGA in the dialect the engine runs (``split(x|y){…}``,
``{ ~s : R }*`` repeats), one rule per cluster, so the rules carry the hierarchy, the averaged
dimensions and the repetition of the photo and derive on facades of any size:

- a split into floors (or tiles, or regions) turns each run of consecutive same-cluster shapes
  into a repeat ``{ ~s : R }*`` — the longest run at top level, further runs as nested floating
  repeats (the engine shares space between top-level repeats by pattern length, not by count);
  the other shapes get absolute sizes.  Without any repetition the first and last shape are
  absolute and the others floating (two shapes: the smaller absolute, the bigger floating);
- single tile refinements (§3.1 ``left/right/top/bottom``): the smaller part absolute, the
  bigger floating (``~1``); dual ones (``dual-x/dual-y``): the outer parts floating, the centre
  absolute (§5 rule 9);
- sizes of a rule used by several shapes are the averages over the cluster members (§5:
  "averaging the split positions"); members whose sub-hierarchy differs become variants
  (``Tile_T3_v2``) instead of failing;
- leaves: a flat coloured (or photo-textured) rectangle, or, with a depth, the scope set to that
  depth and translated behind the facade plane for recesses (§5 rule 15) with the matched element
  asset or a box inserted; per-class depths are editable ``attr``\\ s (``window_depth``);
- shapes inserted in front of a shape outside its partition (``operator="insert"``: balconies,
  §4's library elements standing before a tile or floor) become branches
  ``[ t('x, y, 0) s('w, h, '1) Balcony_T3_p0 ]`` ahead of the shape's split: ``x`` and ``w``
  fractions of the host's width (a balcony band keeps its share of a wider floor), ``y`` and
  ``h`` metres above the host's bottom, averaged over the cluster members like split sizes.

Rule names start with the leaf's label (``Window_T3_1``, ``Wall_T1``), so the engine's
rule-name label inference gives the derived leaves the photo's labels; where it would not, the
rule sets ``label(…)`` explicitly.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..model.labels import label_for_name
from ..model.shape import INSERT, Shape

__all__ = ["MAX_NODES", "extract_rules"]

#: Largest shape tree extracted (a photo's tree has hundreds of nodes).
MAX_NODES: int = 200_000
#: Largest depth of a leaf in metres (larger values are clamped).
MAX_DEPTH_M: float = 50.0
#: Depths below this (metres) are flat.
FLAT_EPS: float = 1e-4

_SINGLE = ("left", "right", "top", "bottom")
_DUAL = ("dual-x", "dual-y")
_AXES = {"x": 0, "y": 1}
_COLORS = {"window": "#6f8fa8", "door": "#5a3d2b", "balcony": "#a9a9a9", "shop": "#7f9fb0",
           "sill": "#e6e0d4", "cornice": "#efe9dc", "roof": "#8a4b3a", "blind": "#7a8a6a",
           "deco": "#d0c0a0", "molding": "#e0d6c4", "pillar": "#d8d0c0", "sky": "#a8c8e8",
           "vegetation": "#5a8a4a"}
_OTHER_COLOR = "#b8b0a8"
_WALL_COLOR = "#d8c8a8"
_LINE = 100


@dataclass
class _Group:
    """Shapes that become one rule: same symbol, cluster and sub-hierarchy."""

    symbol: str
    cluster: str | None
    members: list[Shape] = field(default_factory=list)
    children: tuple[int, ...] = ()
    axis: str | None = None
    split: str | None = None
    label: str = ""
    asset: str | None = None
    depths: list[float] = field(default_factory=list)
    size_sums: list[float] = field(default_factory=list)   # per child position, over members
    name: str = ""
    inserts: tuple[int, ...] = ()
    insert_sums: list[list[float]] = field(default_factory=list)   # per insert: x, y, w, h

    @property
    def leaf(self) -> bool:
        return not self.children


def extract_rules(tree: Shape, *, texture: str | None = None, name: str = "facade",
                  depths: Mapping[str, float] | None = None) -> str:
    """CGA rules that rebuild the facade ``tree`` and adapt to other facade sizes.

    Parameters
    ----------
    tree : Shape
        The facade shape tree (metres, facade frame x right / y up, ``Facade`` root; see
        :mod:`facadeforge.imaging.shape_tree`).
    texture : str, optional
        Image (path relative to the rules/asset folder) projected onto the facade: the start rule
        sets up projection 0 over the whole facade and every leaf projects its UVs, so the model
        is textured with the rectified photo.
    name : str
        Facade name for the header comment.
    depths : mapping, optional
        Depth in metres (negative = recessed) per label (``"window"``) or cluster id (``"T3.1"``)
        for leaves without ``tags["depth"]``; also the default of the per-class ``attr``\\ s.

    Returns
    -------
    str
        CGA text with ``@StartRule Facade``; derive it with
        :func:`facadeforge.engine.derive_facade` (element assets resolve in its asset folder).

    Raises
    ------
    InputError
        ``tree`` is not a shape tree or is larger than :data:`MAX_NODES`.
    """
    if not isinstance(tree, Shape):
        raise InputError(f"extract_rules needs a facadeforge.model.Shape tree, not "
                         f"{type(tree).__name__}")
    depths = dict(depths or {})
    groups, root_gid = _group(tree, depths)
    _name_groups(groups, root_gid)
    attrs = _depth_attrs(groups, depths)
    return _emit(groups, root_gid, attrs, texture, name)


# -- grouping -------------------------------------------------------------------------------------

def _ordered_children(node: Shape) -> tuple[list[Shape], str]:
    """The partition's children (not the inserted ones) by increasing coordinate along their
    split axis, and that axis."""
    kids = [c for c in node.children if c.operator != INSERT]
    axis = next((c.params.get("axis") for c in kids if c.params.get("axis") in _AXES), None)
    if axis is None:   # infer: children spanning the parent's full width are stacked in y
        w = float(node.scope.size[0])
        axis = "y" if all(abs(float(c.scope.size[0]) - w) <= 1e-6 * max(w, 1.0) for c in kids) \
            else "x"
    k = _AXES[axis]
    kids.sort(key=lambda c: float(c.scope.origin[k]))
    return kids, axis


def _as_depth(value) -> float:
    """``value`` as a depth in metres: clamped, and 0 (flat) when tiny or not a finite number."""
    try:
        d = float(value)
    except (TypeError, ValueError):
        return 0.0
    if not math.isfinite(d) or abs(d) < FLAT_EPS:
        return 0.0
    return max(-MAX_DEPTH_M, min(MAX_DEPTH_M, d))


def _leaf_depth(node: Shape, label: str, depths: Mapping[str, float]) -> float:
    d = node.tags.get("depth")
    if d is None:
        cluster = node.tags.get("cluster")
        d = depths.get(str(cluster)) if cluster is not None else None
        if d is None:
            d = depths.get(label, 0.0)
    return _as_depth(d)


def _inserts(node: Shape) -> list[Shape]:
    """The shapes inserted in front of ``node`` (not in its partition), left to right."""
    found = [c for c in node.children if c.operator == INSERT]
    return sorted(found, key=lambda c: (float(c.scope.origin[0]), float(c.scope.origin[1])))


def _placement(host: Shape, shape: Shape) -> list[float]:
    """``shape``'s rectangle in ``host``: x and width as fractions of the host's width, y (above
    the host's bottom) and height in metres."""
    w = max(float(host.scope.size[0]), 1e-9)
    x0, y0, x1, y1 = _rect(shape) - np.tile(_rect(host)[:2], 2)
    return [x0 / w, y0, (x1 - x0) / w, y1 - y0]


def _rect(shape: Shape) -> np.ndarray:
    """``x0, y0, x1, y1`` of the scope's corners (facade frame)."""
    c = shape.scope.corners()
    return np.array([c[:, 0].min(), c[:, 1].min(), c[:, 0].max(), c[:, 1].max()])


def _group(tree: Shape, depths: Mapping[str, float]) -> tuple[dict[int, _Group], int]:
    """Post-order: every node's group is keyed by its symbol, cluster and the groups of its
    children and inserted shapes, so cluster members with another sub-hierarchy fall into a
    variant group."""
    order: list[tuple[Shape, list[Shape], str | None, list[Shape]]] = []
    for count, node in enumerate(tree.walk(), 1):   # pre-order; processed in reverse = post-order
        if count > MAX_NODES:
            raise InputError(f"shape tree has more than {MAX_NODES} nodes; extract rules from a "
                             "smaller facade")
        kids, axis = _ordered_children(node) if node.children else ([], None)
        order.append((node, kids, axis if kids else None, _inserts(node)))
    gid_of: dict[int, int] = {}
    keys: dict[tuple, int] = {}
    groups: dict[int, _Group] = {}
    for node, kids, axis, inserts in reversed(order):
        cluster = node.tags.get("cluster")
        cluster = None if cluster is None else str(cluster)
        insert_ids = tuple(gid_of[id(c)] for c in inserts)
        if kids:
            child_ids = tuple(gid_of[id(c)] for c in kids)
            split = kids[0].params.get("split")
            split = split if split in _SINGLE + _DUAL else None
            # unclustered internal shapes are one-offs: their sizes are never averaged
            key = ("node", node.symbol, cluster if cluster is not None else f"#{id(node)}",
                   axis, split, child_ids, insert_ids)
            label, asset, depth = "", None, 0.0
        else:
            child_ids, split = (), None
            label = _clean_label(node.label)
            asset = node.tags.get("asset")
            asset = str(asset) if isinstance(asset, str) and asset.strip() else None
            depth = _leaf_depth(node, label, depths)
            sign = 0 if depth == 0.0 else (1 if depth > 0 else -1)
            key = ("leaf", node.symbol, cluster, label, asset, sign, insert_ids)
        gid = keys.get(key)
        if gid is None:
            gid = keys[key] = len(keys)
            groups[gid] = _Group(node.symbol, cluster, children=child_ids, axis=axis,
                                 split=split, label=label, asset=asset,
                                 size_sums=[0.0] * len(kids), inserts=insert_ids,
                                 insert_sums=[[0.0] * 4 for _ in inserts])
        g = groups[gid]
        g.members.append(node)
        if kids:
            k = _AXES[axis]
            for j, c in enumerate(kids):
                g.size_sums[j] += max(float(c.scope.size[k]), 0.0)
        else:
            g.depths.append(depth)
        for sums, c in zip(g.insert_sums, inserts):
            sums[:] = [a + b for a, b in zip(sums, _placement(node, c))]
        gid_of[id(node)] = gid
    return groups, gid_of[id(tree)]


def _depth_attr(label: str) -> str:
    """Name of the class depth ``attr`` (``window_depth``; a CGA name even for ``"3d"``)."""
    return f"{label}_depth" if not label[:1].isdigit() else f"_{label}_depth"


def _clean_label(label: str) -> str:
    s = re.sub(r"[^a-z0-9_]", "", str(label or "").lower())[:32]
    return s or "wall"


# -- names ----------------------------------------------------------------------------------------

def _camel(text: str, default: str) -> str:
    parts = [p for p in re.split(r"[^A-Za-z0-9]+", text) if p]
    s = "".join(p[:1].upper() + p[1:] for p in parts)[:32]
    if not s or not s[0].isalpha():
        s = default + s
    return s


def _ident(text: str) -> str:
    return re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9]", "_", text)).strip("_")[:32]


def _bfs(groups: dict[int, _Group], root: int) -> list[int]:
    out, seen, queue = [], {root}, [root]
    while queue:
        nxt = []
        for gid in queue:
            out.append(gid)
            for c in groups[gid].children + groups[gid].inserts:
                if c not in seen:
                    seen.add(c)
                    nxt.append(c)
        queue = nxt
    return out


def _name_groups(groups: dict[int, _Group], root: int) -> None:
    order = _bfs(groups, root)
    variants: dict[tuple, list[int]] = {}
    for gid in order:
        g = groups[gid]
        if g.cluster is not None:
            variants.setdefault((g.leaf, g.symbol, g.cluster), []).append(gid)
    used = {"Facade"}
    for gid in order:
        g = groups[gid]
        if gid == root:
            g.name = "Facade"
            continue
        prefix = _camel(g.label, "Element") if g.leaf else _camel(g.symbol, "Shape")
        base = prefix
        if g.cluster is not None:
            cid = _ident(g.cluster)
            base = f"{prefix}_{cid}" if cid else prefix
            same = variants[(g.leaf, g.symbol, g.cluster)]
            if len(same) > 1:
                base += f"_v{same.index(gid) + 1}"
        name, k = base, 2
        while name in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
        g.name = name


# -- depths ---------------------------------------------------------------------------------------

def _depth_attrs(groups: dict[int, _Group], depths: Mapping[str, float]) -> dict[str, float]:
    """Per-class depth attributes: the given class depth, else the mean over the class."""
    by_label: dict[str, list[float]] = {}
    for g in groups.values():
        if g.leaf:
            ds = [d for d in g.depths if d != 0.0]
            if ds:
                by_label.setdefault(g.label, []).extend(ds)
    attrs = {}
    for label in sorted(by_label):
        given = _as_depth(depths.get(label))   # members' depths are already clamped
        attrs[label] = given if given != 0.0 else sum(by_label[label]) / len(by_label[label])
    return attrs


# -- sizes ----------------------------------------------------------------------------------------

def _num(v: float, digits: int = 3) -> str:
    s = f"{v:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _items(g: _Group, groups: dict[int, _Group]) -> list[str]:
    """The split pattern of an internal group."""
    sizes = [s / len(g.members) for s in g.size_sums]   # averaged over the cluster members
    names = [groups[c].name for c in g.children]
    n = len(names)
    if g.split in _DUAL and n == 3:
        return [f"~{_num(sizes[0])} : {names[0]}", f"{_num(sizes[1])} : {names[1]}",
                f"~{_num(sizes[2])} : {names[2]}"]
    runs: list[tuple[int, int]] = []           # (start, length) of same-rule runs
    for j in range(n):
        if runs and g.children[runs[-1][0]] == g.children[j]:
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((j, 1))
    repeats = [r for r in runs if r[1] >= 2]
    if n == 2 and (g.split in _SINGLE or not repeats):   # the smaller absolute, the bigger ~1
        small = 0 if sizes[0] <= sizes[1] else 1
        return [f"{_num(sizes[j])} : {names[j]}" if j == small else f"~1 : {names[j]}"
                for j in range(2)]
    if not repeats:
        if n == 1:
            return [f"~1 : {names[0]}"]
        return [f"{'' if j in (0, n - 1) else '~'}{_num(sizes[j])} : {names[j]}"
                for j in range(n)]
    main = max(repeats, key=lambda r: (r[1], sum(sizes[r[0]:r[0] + r[1]])))
    out = []
    for start, length in runs:
        rule = names[start]
        total = sum(sizes[start:start + length])
        if length == 1:
            out.append(f"{_num(total)} : {rule}")
        elif (start, length) == main:
            out.append(f"{{ ~{_num(total / length)} : {rule} }}*")
        else:   # a further repeat: floating, repeating inside (top-level repeats share by size)
            out.append(f"~{_num(total)} : split({g.axis}) {{ {{ ~{_num(total / length)} : "
                       f"{rule} }}* }}")
    return out


def _insert_branches(g: _Group, groups: dict[int, _Group]) -> list[str]:
    """``[ t('x, y, 0) s('w, h, '1) Rule ]`` per inserted shape, sizes averaged over the
    members (module docstring)."""
    out = []
    for gid, sums in zip(g.inserts, g.insert_sums):
        x, y, w, h = (v / len(g.members) for v in sums)
        out.append(f"[ t('{_num(x, 4)}, {_num(y)}, 0) s('{_num(w, 4)}, {_num(h)}, '1) "
                   f"{groups[gid].name} ]")
    return out


# -- text -----------------------------------------------------------------------------------------

def _cga_string(text: str) -> str:
    """A CGA string literal holding ``text`` (escaped; control characters dropped)."""
    text = "".join(ch for ch in str(text) if ch >= " " and ch != "\x7f")[:512]
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _comment(text: str) -> str:
    return re.sub(r"[^\w .,:;()/+=-]", "", str(text))[:80]


def _split_text(axis: str, items: list[str], head: str) -> str:
    one = f"{head}split({axis}) {{ " + " | ".join(items) + " }"
    if len(one) <= _LINE:
        return one
    pad = re.sub(r"\S", " ", head) + " " * len(f"split({axis}) ")
    return (f"{head}split({axis}) {{ " + items[0]
            + "".join(f"\n{pad}| {it}" for it in items[1:]) + " }")


def _leaf_ops(g: _Group, attrs: dict[str, float], textured: bool) -> str:
    ops = []
    hint = label_for_name(g.name)
    if hint is None or hint.value != g.label:
        ops.append(f"label({_cga_string(g.label)})")
    depth = sum(g.depths) / len(g.depths) if g.depths else 0.0
    look = "projectUV(0)" if textured else (
        "color(wall_color)" if g.label == "wall" else
        f"color({_cga_string(_COLORS.get(g.label, _OTHER_COLOR))})")
    if depth == 0.0:
        ops.append(look)
        return " ".join(ops)
    attr = attrs.get(g.label)
    if attr is not None and abs(attr - depth) <= 1e-3:
        var = _depth_attr(g.label)
        ops.append(f"s('1, '1, abs({var})) t(0, 0, min({var}, 0))")
    elif depth < 0:
        ops.append(f"s('1, '1, {_num(-depth)}) t(0, 0, {_num(depth)})")
    else:
        ops.append(f"s('1, '1, {_num(depth)})")
    if g.asset is not None:
        ops.append(f"i({_cga_string(g.asset)})")
        if textured:
            ops.append("projectUV(0)")
    elif depth < 0:     # a recess without an element: an open box (reveals and back)
        ops.append('i("builtin:cube") comp(f) { front : NIL | all = reverseNormals() '
                   f"{look} }}")
    else:
        ops.append(f'i("builtin:cube") {look}')
    return " ".join(ops)


def _emit(groups: dict[int, _Group], root: int, attrs: dict[str, float], texture: str | None,
          name: str) -> str:
    textured = texture is not None
    lines = [f"# Facade rules extracted from a photo: {_comment(name)}",
             "# (Mueller et al. 2007, section 5; facadeforge.grammar.extract).  Sizes in metres,",
             "# averaged over each cluster; repeats and floating sizes adapt to other facade sizes.",
             'version "2019.0"', ""]
    if not textured and any(g.leaf and g.label == "wall" for g in groups.values()):
        lines += ["@Color", f'attr wall_color = "{_WALL_COLOR}"', ""]
    if attrs:
        lines.append("# depth of each element class in metres: < 0 recessed behind the wall, "
                     "> 0 protruding")
        lines += [f"attr {_depth_attr(label)} = {_num(v)}" for label, v in attrs.items()]
        lines.append("")
    for gid in _bfs(groups, root):
        g = groups[gid]
        head = f"{g.name} --> "
        if gid == root:
            lines.append("@StartRule")
            if textured:
                lines.append(f"{g.name} -->")
                lines.append("\tsetupProjection(0, scope.xy, scope.sx, scope.sy) texture("
                             f"{_cga_string(texture)})")
                head = "\t"
        if g.cluster is not None and gid != root:
            extra = f", {len(g.members)} shapes" if len(g.members) > 1 else ""
            lines.append(f"# cluster {_comment(g.cluster)}{extra}")
        branches = _insert_branches(g, groups)
        if branches:                  # one branch a line, then the shape's own operations
            if head != "\t":
                lines.append(f"{g.name} -->")
            lines += ["\t" + b for b in branches]
            head = "\t"
        if g.leaf:
            lines.append(head + _leaf_ops(g, attrs, textured))
        else:
            lines.append(_split_text(g.axis, _items(g, groups), head))
    return "\n".join(lines) + "\n"
