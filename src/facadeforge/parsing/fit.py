"""Fitting a parse grammar to class probabilities: layout derivation + energy + search.

:func:`fit_grammar` is the core of grammar-driven parsing (``simon2011`` §4.2): it binds a parse
grammar's procedural space (:func:`~.search.parameters_of`), its fast 2D derivation
(:class:`~.layout.SplitLayout`) and the facade energy (:class:`~.energy.SegmentationEnergy`) into
one objective, and minimises it with the chosen search.  The photo's aspect ratio fixes the
facade rectangle: ``facadeWidth`` × ``facadeWidth · H / W`` metres.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..classify.features import resize_proba
from ..datasets import LabelSet
from ..errors import InputError
from .differentiate import differentiate as differentiate_instances
from .energy import SegmentationEnergy
from .evolution import evolve
from .layout import Layout, ParseGrammarError, SplitLayout
from .search import SearchResult, hill_climb, parameters_of

__all__ = ["DEFAULT_GRAMMAR", "EVIDENCE", "GRAMMARS", "FitResult", "energy_shape", "fit_grammar",
           "grammar_path", "shrink_proba",
           "SEARCH_METHODS"]

GRAMMAR_DIR = Path(__file__).with_name("grammars")
#: Built-in parse grammars by name.
GRAMMARS: dict[str, Path] = {p.stem: p for p in sorted(GRAMMAR_DIR.glob("*.cga"))}
DEFAULT_GRAMMAR = "grid"
#: Long side (pixels) of the probability maps the energy is computed on.
ENERGY_SIDE = 256
#: Nats per pixel the derivation's label is worth against the classifier's evidence in the
#: parse's label map (:meth:`facadeforge.parsing.parse.Parse.labels_input`).  Chosen on 30
#: train photos of each development split (``benchmarks/evidence.py``; every value tried and
#: its scores: ``benchmarks/results/evidence.json``).  On its own training photos a classifier
#: is more right than on new ones, so this choice leans towards the classifier, if anything.
EVIDENCE = 0.25


def grammar_path(grammar: str | Path | None) -> Path:
    """A built-in grammar name (``generic``, ``haussmann``) or a ``.cga`` path."""
    if grammar is None:
        return GRAMMARS[DEFAULT_GRAMMAR]
    if str(grammar) in GRAMMARS:
        return GRAMMARS[str(grammar)]
    p = Path(grammar)
    if not p.is_file():
        raise InputError(f"grammar {grammar}: no such file and not a built-in grammar "
                         f"({', '.join(GRAMMARS)})")
    return p


@dataclass
class FitResult:
    """The best derivation found: parameters, layout, energies and the search trace."""

    attrs: dict[str, Any]
    layout: Layout
    search: SearchResult
    energy_per_pixel: float
    labels: np.ndarray       # (h, w) label-set classes at the energy's resolution
    width_m: float
    height_m: float


def _resize_depth(depth: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A depth map area-averaged to ``shape``, NaN (unmeasured) cells left out of the mean."""
    ok = np.isfinite(depth).astype(np.float32)
    v = np.where(ok > 0, depth, 0).astype(np.float32)
    size = (shape[1], shape[0])
    num = cv2.resize(v, size, interpolation=cv2.INTER_AREA)
    den = cv2.resize(ok, size, interpolation=cv2.INTER_AREA)
    return np.where(den > 0.05, num / np.maximum(den, 1e-6), np.nan)


def energy_shape(h: int, w: int, side: int = ENERGY_SIDE) -> tuple[int, int]:
    """``(h, w)`` of an image of ``h × w`` pixels shrunk to a long side of at most ``side``:
    the frame the energy is computed in."""
    s = min(1.0, side / max(h, w))
    return (h, w) if s >= 1.0 else (max(2, round(h * s)), max(2, round(w * s)))


def shrink_proba(prob: np.ndarray, side: int) -> np.ndarray:
    """Probabilities area-averaged to a long side of at most ``side`` pixels (float32)."""
    shape = energy_shape(*prob.shape[:2], side)
    if shape == prob.shape[:2]:
        return prob.astype(np.float32)
    return resize_proba(prob, shape, interpolation=cv2.INTER_AREA, normalise=False)


def search_method(name: str):
    if name not in SEARCH_METHODS:
        raise InputError(f"unknown search method {name!r}; use one of {', '.join(SEARCH_METHODS)}")
    return SEARCH_METHODS[name]


SEARCH_METHODS: dict[str, Any] = {"hill": hill_climb, "evolution": evolve}


def fit_grammar(prob: np.ndarray, label_set: LabelSet, rules, *, method: str = "hill",
                budget: int = 1500, seed: int = 0, fixed: Mapping[str, Any] | None = None,
                initialiser=None, differentiate: bool = True, depth: np.ndarray | None = None,
                depths: Mapping[str, float] | None = None, **options: Any) -> FitResult:
    """Fit the parse grammar ``rules`` (loaded) to ``(H, W, K)`` probabilities of a rectified
    facade; ``fixed`` pins attributes (e.g. ``facadeWidth`` when the width is known);
    ``initialiser(prob, label_set) -> attrs or None`` measures a starting point that replaces
    the attribute defaults (:mod:`.init`); with ``differentiate`` (and a grammar that declares
    it) each element instance is then fitted on its own (:mod:`.differentiate`).

    ``depth`` (an ``(H', W')`` depth map of the same facade, metres, NaN where unmeasured) and
    ``depths`` (metres per leaf label) add the depth energy of ``simon2011`` §5.3.2
    (:class:`~.energy.DepthEnergy`, eq. 5.9) as a second objective: the search is then the
    evolutionary one with SPEA-II selection and the answer the automatic α's (§5.2.3,
    :func:`~.evolution.auto_alpha`); ``FitResult.search`` holds the Pareto set, α and its
    range."""
    small = shrink_proba(np.asarray(prob), ENERGY_SIDE)
    energy = SegmentationEnergy(small, label_set)
    depth_energy = None
    if depth is not None:
        from .energy import DepthEnergy

        d = np.asarray(depth, np.float32)
        if d.shape != small.shape[:2]:
            d = _resize_depth(d, small.shape[:2])
        depth_energy = DepthEnergy(d, dict(depths or {}))
        method = "evolution"
        options.setdefault("weights", "auto")
    search = search_method(method)
    layout = SplitLayout(rules)
    fixed = dict(fixed or {})
    params = [p for p in parameters_of(rules) if p.name not in fixed]
    start = initialiser(small, label_set) if initialiser is not None else None
    if start:
        params = [replace(p, default=(start[p.name] if p.discrete and start[p.name] in p.choices
                                      else p.clip(start[p.name]) if not p.discrete
                                      else p.default)) if p.name in start else p
                  for p in params]
    if "facadeWidth" not in layout.attr_defs:
        raise ParseGrammarError("a parse grammar needs attr facadeWidth (the width in metres "
                                "the photo spans)")
    if "facadeWidth" not in fixed and all(p.name != "facadeWidth" for p in params):
        fixed["facadeWidth"] = float(layout.attr_value("facadeWidth"))
    aspect = small.shape[0] / small.shape[1]

    def size_of(attrs: Mapping[str, Any]) -> tuple[float, float]:
        w = float(attrs["facadeWidth"])
        return w, w * aspect

    def objective(attrs: Mapping[str, Any]):
        full = {**fixed, **attrs}
        w, h = size_of(full)
        lay = layout.derive(w, h, full)
        if depth_energy is None:
            return energy(lay)
        return np.array([energy(lay), depth_energy(lay, energy.pixel_boxes(lay))])

    result = search(objective, params, budget=budget, seed=seed, **options)
    best = {**fixed, **result.attrs}
    w, h = size_of(best)
    if differentiate and depth_energy is None:   # per-instance fitting is appearance-only
        refined = differentiate_instances(energy, layout, best, w, h, params)
        if refined is not None:
            best = refined
    lay = layout.derive(w, h, best)
    return FitResult(best, lay, result, energy.per_pixel(energy(lay)), energy.rasterize(lay),
                     w, h)
