"""Shape tree → a GML program (``rules.gml``) that derives the same facade (CityFit: grammars
are generated automatically; Hohmann et al. 2009 §5).

:func:`tree_to_gml` writes the shape tree of a photo (:mod:`facadeforge.imaging.shape_tree`:
``Facade → Floor (split y) → Tile (split x) → Region …``, metres, facade frame) — or any tree
of axis-aligned splits, such as a derivation tree — as a program in the dialect of
``docs/gml.md``; :func:`facadeforge.gml.derive_gml` of that program gives the same leaves (labels
and rectangles) as the tree.  The mapping:

- **rules**: one named procedure per cluster (``tags["cluster"]``), named after the symbol, or
  for a leaf after its label, and the cluster: ``/Floor_F1 { … } def``, ``/Window_T3_1 { … }
  def`` (dots become ``_``).  Members of a cluster with the same sub-hierarchy, sizes and
  labels share the procedure; members that differ get variants (``Tile_T3_v2``).  Calling the
  procedure names the derived shape after it (the dialect's rule-name heuristic), so the
  derived tree reads ``Facade → Floor_F1 → Tile_T3 → …``.  Shapes without a cluster (a
  derivation tree's) share a procedure per symbol and body the same way; the root is the
  procedure named after its symbol (``Facade``).
- **root scope**: ``scope (W,H,D) scale (x,y,z) move Facade`` — the unit box scaled to the root's
  size (``D = 0``: the facade rectangle) and moved to its origin.  GML has no ``rotate`` of
  scopes: a rotated root is written in its own frame (its axes become x, y, z); a scope whose
  axes are only swapped or turned against the root's (after CGA's ``extrude``) is written as the
  same box, axis-aligned.
- **splits**: a node whose children carry ``operator="split"`` (``params["axis"]`` ``x``/``y``/
  ``z``) becomes ``[s1 … sn] /X split C1 … Cn`` with the children's sizes in metres along the
  axis, absolute (> 0) except the largest, which is relative (``-1``: the rest, so the parts
  fill the scope exactly whatever the rounding); the parts are consumed first one first, as
  the dialect pushes them (first part on top).  A gap between children (a partition that does
  not tile its node) becomes a ``terminal-void`` part; overlapping children are an error.
- **leaves**: ``/window label terminal-box`` — a flat labelled rectangle (wall, a flat
  window).  With ``tags["depth"]`` d (|d| ≥ 0.1 mm, clamped to 50 m) the leaf is a box: a
  recess (d < 0) ``(0,0,d) move -d extrude`` — d deep behind the facade plane —, a
  protrusion (d > 0) ``d extrude`` — standing d in front of it.  A leaf whose own scope is
  already a box (a derivation tree's) keeps its box.  ``tags["terminal"] == "void"`` gives
  ``terminal-void``.  Labels that are not GML names are left to the rule-name heuristic.
- **inserted shapes** (``operator="insert"``: balconies in front of a tile or floor, outside the
  partition) and any other child that is not a split part: the host is ``dup``\\ ed before its
  split; after the split parts, each copy is ``(dx,dy,dz) move (fx,fy,1) scale`` to the
  inserted shape's rectangle (which may reach beyond the host's: a balcony hanging below its
  floor) — once the host has been split, the dialect makes those changes on a new child — and
  its procedure extrudes it by its depth: a box standing out of the facade.  A host without
  split parts and several such children is first split into one empty part (``[ 0 ] /X split
  terminal-void``, an empty void leaf) so that the copies become children; a host with just
  one (a derivation tree's chain of ``t(…)``, ``s(…)``) is changed in place — the chain
  becomes one derived shape, named after the first rule.  A host of width or height 0 cannot be scaled to the shape:
  the shape is then a new root scope at its place (``pop scope … scale … move``).
- **fit**: where a part as the split makes it differs from the tree's shape in the other axes
  (a derivation tree that moved or scaled a part), the call site moves, scales or extrudes it
  first (``(dx,dy,dz) move (fx,fy,1) scale``), so every derived scope equals the tree's.

Every node's scope must have the root's orientation (axis-aligned trees: GML has no
``rotate``); other trees raise :class:`~facadeforge.errors.InputError`.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import InputError
from ..model.shape import Shape

__all__ = ["MAX_NODES", "tree_to_gml"]

#: Largest shape tree written (a photo's tree has hundreds of nodes).
MAX_NODES: int = 200_000
#: Deepest shape tree written (the writer recurses).
MAX_LEVELS: int = 400
#: Largest leaf depth in metres (larger values are clamped).
MAX_DEPTH_M: float = 50.0
#: Depths below this (metres) are flat.
FLAT_EPS: float = 1e-4
#: Tolerance (metres) of gaps, overlaps and fits.
EPS: float = 1e-7

_AXES = {"x": 0, "y": 1, "z": 2}
_NAME_OK = re.compile(r"^[A-Za-z][A-Za-z0-9_.\-]*$")


def _num(v: float) -> str:
    v = float(v)
    if abs(v) < 5e-13:
        return "0"
    s = format(round(v, 9), ".12g")
    return "0" if s in ("-0", "0") else s


def _point(v) -> str:
    return "(" + ",".join(_num(c) for c in v) + ")"


def _ident(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_]", "_", str(text)).strip("_")
    if not s or not s[0].isalpha():
        s = "R" + s
    return s[:1].upper() + s[1:]


class _Writer:
    def __init__(self, root: Shape):
        self.o0 = np.asarray(root.scope.origin, float)
        self.r0 = np.asarray(root.scope.rotation, float)
        #: where the root goes in the program: its origin, or its own frame when rotated
        self.at = self.o0 if np.allclose(self.r0, np.eye(3), atol=1e-9) else np.zeros(3)
        self.procs: dict[str, str] = {}          # name → body, in definition order
        self.by_body: dict[tuple[str, str], str] = {}
        self.used: set[str] = set()
        self.notes: list[str] = []

    # -- geometry in the root's frame
    def box(self, s: Shape) -> tuple[np.ndarray, np.ndarray]:
        sc = s.scope
        rot = np.asarray(sc.rotation, float)
        lo = self.r0.T @ (np.asarray(sc.origin, float) - self.o0)
        if np.allclose(rot, self.r0, atol=1e-9):
            return lo, np.asarray(sc.size, float).copy()
        m = self.r0.T @ rot
        if not (np.allclose(np.abs(m).sum(0), 1, atol=1e-9)
                and np.allclose(np.abs(m).sum(1), 1, atol=1e-9)
                and np.allclose(np.abs(m), np.round(np.abs(m)), atol=1e-9)):
            raise InputError(f"shape '{s.symbol}' is rotated against the root: GML has no "
                             "'rotate' of scopes, so only axis-aligned trees are written")
        # axes only swapped or turned (CGA's extrude turns a scope's y onto the extrusion):
        # the same box, axis-aligned in the root's frame
        size = np.asarray(sc.size, float)
        corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)]) * size
        pts = lo + corners @ m.T
        return pts.min(0), pts.max(0) - pts.min(0)

    def fit(self, have: tuple[np.ndarray, np.ndarray], want: tuple[np.ndarray, np.ndarray]
            ) -> str:
        """Words that turn the scope ``have`` (on top of the stack) into ``want``."""
        (ho, hs), (wo, ws) = have, want
        words = []
        d = wo - ho
        if np.abs(d).max() > EPS:
            words.append(f"{_point(d)} move")
        f = [1.0, 1.0, 1.0]
        for k in (0, 1):
            if abs(ws[k] - hs[k]) > EPS:
                if hs[k] <= 0:
                    raise ValueError("zero extent")
                f[k] = ws[k] / hs[k]
        if f != [1.0, 1.0, 1.0]:
            words.append(f"{_point(f)} scale")
        if abs(ws[2] - hs[2]) > EPS:
            words.append(f"{_num(max(ws[2], 0.0))} extrude")
        return " ".join(words)

    def name_for(self, s: Shape, body: str) -> str:
        cluster = s.tags.get("cluster")
        base = (s.label if not s.children and s.label else s.symbol) or "Shape"
        key = (str(cluster) if cluster is not None else f"#{s.symbol}", body)
        if s.parent is not None and key in self.by_body:
            return self.by_body[key]
        if cluster is not None:
            stem = f"{_ident(base)}_{_ident(cluster)}" if str(cluster) else _ident(base)
        elif s.parent is None:
            stem = _ident(s.symbol or "Facade")
        else:
            stem = _ident(base)
        name, v = stem, 1
        while name in self.used:
            v += 1
            name = f"{stem}_v{v}"
        self.used.add(name)
        self.by_body[key] = name
        self.procs[name] = body
        return name

    # -- rules
    def leaf_body(self, s: Shape) -> str:
        words = []
        _, size = self.box(s)
        depth = s.tags.get("depth")
        if (isinstance(depth, (int, float)) and math.isfinite(depth) and abs(depth) >= FLAT_EPS
                and size[2] <= EPS):
            d = max(min(float(depth), MAX_DEPTH_M), -MAX_DEPTH_M)
            if d < 0:
                words.append(f"(0,0,{_num(d)}) move {_num(-d)} extrude")
            else:
                words.append(f"{_num(d)} extrude")
        if s.label and _NAME_OK.match(s.label):
            words.append(f"/{s.label} label")
        words.append("terminal-void" if s.tags.get("terminal") == "void" else "terminal-box")
        return " ".join(words)

    def rule(self, s: Shape, level: int) -> str:
        """Define the procedure of ``s`` (and its subtree); return its name."""
        if level > MAX_LEVELS:
            raise InputError(f"the shape tree is deeper than {MAX_LEVELS} levels")
        if not s.children:
            return self.name_for(s, self.leaf_body(s))
        lo, size = self.box(s)
        parts = [c for c in s.children if c.operator == "split"
                 and str(c.params.get("axis", "")).lower() in _AXES]
        others = [c for c in s.children if c not in parts]
        words = ["dup"] * len(others)
        if parts:
            axes = {str(c.params["axis"]).lower() for c in parts}
            if len(axes) != 1:
                raise InputError(f"shape '{s.symbol}' is split along several axes {sorted(axes)}")
            k = _AXES[axes.pop()]
            words.append(self.split(s, (lo, size), parts, k, level))
        elif len(others) == 1:           # a chain (a derivation's t(…), s(…)): in place
            c = others[0]
            name = self.rule(c, level + 1)
            try:
                fit = self.fit((lo, size), self.box(c))
            except ValueError:
                raise InputError(f"shape '{c.symbol}' cannot be scaled from its parent "
                                 f"'{s.symbol}', which has no area") from None
            return self.name_for(s, f"{fit} {name}".strip())
        elif others:
            words.append("[ 0 ] /X split terminal-void")
        for c in others:
            want = self.box(c)
            name = self.rule(c, level + 1)
            try:
                words.append(f"{self.fit((lo, size), want) or '(0,0,0) move'} {name}")
            except ValueError:           # a host of width or height 0: a new root scope
                self.notes.append(f"'{name}' is a new root scope (its host has no area)")
                wo, ws = want
                words.append(f"pop scope {_point(ws)} scale {_point(wo + self.at)} move {name}")
        return self.name_for(s, " ".join(words))

    def split(self, s: Shape, host, parts: list[Shape], k: int, level: int) -> str:
        ho, hs = host
        boxes = [self.box(c) for c in parts]
        order = sorted(range(len(parts)), key=lambda i: boxes[i][0][k])
        extent = float(hs[k])
        sizes: list[float] = []
        calls: list[str] = []
        pos = 0.0
        for i in order:
            c, (co, cs) = parts[i], boxes[i]
            start = float(co[k] - ho[k])
            if start < pos - 1e-6:
                raise InputError(f"the parts of shape '{s.symbol}' overlap along "
                                 f"{'xyz'[k]} (at {start:.6g} m)")
            if start > pos + EPS:
                sizes.append(start - pos)
                calls.append("terminal-void")
            length = max(float(cs[k]), 0.0)
            # the scope this split gives the part, then what the tree's part is
            go, gs = ho.copy(), hs.copy()
            go[k], gs[k] = ho[k] + start, length
            name = self.rule(c, level + 1)
            fit = self.fit((go, gs), (co, cs))
            sizes.append(length)
            calls.append(f"{fit} {name}".strip())
            pos = start + length
        if pos < extent - EPS:
            sizes.append(extent - pos)
            calls.append("terminal-void")
        big = max(range(len(sizes)), key=lambda i: sizes[i]) if sizes else -1
        items = []
        for i, v in enumerate(sizes):
            if i == big and pos <= extent + 1e-6:
                items.append("-1")
            elif v > 0:
                items.append(_num(v))
            else:
                items.append("0")
        return f"[ {' '.join(items)} ] /{'XYZ'[k]} split " + " ".join(calls)


def tree_to_gml(tree: Shape, *, name: str = "facade") -> str:
    """A GML program (``rules.gml``) that derives the leaves of ``tree``.

    Parameters
    ----------
    tree : Shape
        A shape tree of axis-aligned splits — the photo's (:mod:`facadeforge.imaging.
        shape_tree`) or a derivation's — in metres.
    name : str
        Written in the program's header comment (the facade's name).

    Returns
    -------
    str
        The program text: ``ShapeGrammar.Tools.init``, one procedure per cluster, the root scope
        and its call, ``finish``.  ``derive_gml(tree_to_gml(tree))`` gives leaves with the
        tree's labels and rectangles (see the module docstring for the mapping).

    Raises
    ------
    InputError
        Not a shape tree, too large or deep, rotated scopes or overlapping split parts.
    """
    if not isinstance(tree, Shape):
        raise InputError(f"tree_to_gml needs a Shape tree, not {type(tree).__name__}")
    n = sum(1 for _ in tree.walk())
    if n > MAX_NODES:
        raise InputError(f"the shape tree has {n:,} nodes (more than {MAX_NODES:,})")
    w = _Writer(tree)
    top = w.rule(tree, 0)
    size = np.asarray(tree.scope.size, float)
    label = re.sub(r"[\r\n]+", " ", str(name))
    lines = [f"% rules.gml - {label}: the shape tree as a GML shape grammar, written by "
             "facadeforge.gml.extract.tree_to_gml",
             "% (metres; x along the facade, y up, z out of it; see docs/gml.md)",
             "ShapeGrammar.Tools.init", ""]
    if w.at is not w.o0:
        w.notes.append("the root is rotated: the program is written in its own frame")
    for note in w.notes:
        lines.append(f"% note: {note}")
    for proc, body in w.procs.items():
        lines.append(f"/{proc} {{ {body} }} def")
    lines += ["", f"scope {_point(size)} scale {_point(w.at)} move "
              f"{top}", "finish", ""]
    return "\n".join(lines)
