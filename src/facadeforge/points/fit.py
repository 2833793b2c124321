"""A parse grammar fitted to a scanned facade with appearance and depth energies (``simon2011``
§5.3, §5.2.3), and the choice between it and the element layout.

The thesis fits its grammar in 3D with two energies: an **appearance** energy (§5.3.1, a GMM per
class on colours the user marked with strokes) and a **depth** energy against a point cloud
(§5.3.2, eq. 5.9), minimised together by SPEA-II, the answer taken at the automatic α of the
Pareto set (§5.2.3).  On a laser scan both come from the facade's own rasters
(:mod:`.maps`):

- **appearance** — the detector's boxes themselves as class probabilities
  (:func:`detection_proba`: trusted at 0.7, blurred by 15 cm), the detector playing the
  thesis's pixel classifier (§4.3).  Tried and removed: per cell the laser intensity and the log
  point density, a Gaussian per class fitted on the cells the detector put in windows, doors and
  wall (the detector's boxes standing in for the user's strokes, §5.3.1) — on the development
  synthetic scans ``--fit grammar`` scored lower with it than with the boxes
  (``docs/design-measurements.md``).  Cells outside the facade's silhouette get every class at the same probability:
  the scan says nothing there;
- **depth** — :class:`~facadeforge.parsing.energy.DepthEnergy` on the depth map measured from the
  wall around each cell (:func:`~.elements.wall_depth`), each leaf at its class's **measured**
  depth (the median over the detected elements of the class).

:func:`fit_facade` runs :func:`~facadeforge.parsing.fit.fit_grammar` with both (the ``grid``
grammar by default: floors, window columns, an arcade ground floor of doors and shops), then
scores the element layout that the detector and the photo pipeline built (:mod:`.pipeline`) with
the same two energies, and adds it to the Pareto set before the automatic α picks: the grammar's
derivation is kept only where it explains the scan better by the thesis's own criterion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..datasets import get_label_set
from .elements import Element, wall_depth
from .maps import FacadeMaps

__all__ = ["DepthFit", "detection_proba", "fit_facade", "tree_layout"]

#: Derivations of the grammar search.
BUDGET = 600


@dataclass
class DepthFit:
    """What :func:`fit_facade` found."""

    chosen: str                     # "grammar" or "elements"
    fit: object                     # parsing.fit.FitResult of the grammar
    energies: dict                  # {"grammar": [E_a, E_d], "elements": [E_a, E_d]}
    alpha: float
    alpha_range: tuple[float, float]
    depths: dict
    front: list


def detection_proba(maps: FacadeMaps, elements: list[Element], sigma_m: float = 0.15,
                    trust: float = 0.7) -> np.ndarray:
    """``(H, W, 7)`` ecp7 probabilities from the detector's boxes: each element's class at
    ``trust`` inside its box, blurred by ``sigma_m`` (box edges are uncertain by a few cells),
    the rest shared evenly; outside the facade's outline every class alike."""
    ls = get_label_set("ecp7")
    h, w = maps.shape
    onehot = np.zeros((h, w, ls.num_classes), np.float32)
    onehot[:, :, ls.index("wall")] = 1.0
    for e in elements:
        if e.label in ("window", "door"):
            x0, y0, x1, y1 = e.box_px
            onehot[y0:y1, x0:x1] = 0.0
            onehot[y0:y1, x0:x1, ls.index(e.label)] = 1.0
    s = max(sigma_m / maps.resolution, 0.5)
    soft = np.stack([ndimage.gaussian_filter(onehot[..., k], s) for k in range(ls.num_classes)],
                    -1)
    prob = trust * soft + (1 - trust) / ls.num_classes
    occupied = maps.count > 0
    inside = ndimage.binary_fill_holes(ndimage.binary_closing(occupied, np.ones((9, 9)),
                                                              border_value=0))
    prob[~inside] = 1.0 / ls.num_classes
    return prob / prob.sum(-1, keepdims=True)


def tree_layout(tree, width: float, height: float):
    """A shape tree's leaves as a :class:`~facadeforge.parsing.layout.Layout` (metres, y up),
    for scoring it with the parse energies."""
    from ..parsing.layout import Layout

    boxes, labels = [], []
    for leaf in tree.leaves():
        o, s = leaf.scope.origin, leaf.scope.size
        boxes.append((o[0], o[1], o[0] + s[0], o[1] + s[1]))
        labels.append(leaf.label or "wall")
    return Layout(np.array(boxes, float).reshape(-1, 4), tuple(labels), float(width),
                  float(height))


def class_depths(maps: FacadeMaps, elements: list[Element]) -> dict[str, float]:
    """The measured depth (m) of each class: the median over its detected elements."""
    out: dict[str, float] = {}
    for lab in ("window", "door", "balcony"):
        d = [e.depth for e in elements if e.label == lab]
        if d:
            out[lab] = float(np.median(d))
    if "door" in out:
        out.setdefault("shop", out["door"])
    return out


def fit_facade(maps: FacadeMaps, elements: list[Element], element_tree=None, *,
               grammar: str = "grid", budget: int = BUDGET, seed: int = 0) -> DepthFit:
    """Fit ``grammar`` to a facade's rasters with E_a and E_d (module docstring), and choose
    between its derivation and ``element_tree`` (the element layout's shape tree, facade
    metres) by the automatic α on the Pareto set of both."""
    from ..parsing.energy import DepthEnergy, SegmentationEnergy
    from ..parsing.evolution import auto_alpha, pareto_mask
    from ..parsing.fit import ENERGY_SIDE, _resize_depth, fit_grammar, grammar_path, shrink_proba
    from ..parsing.init import initialiser_for, pinned_for
    from ..parsing.parse import _load_grammar, _stamp

    ls = get_label_set("ecp7")
    prob = detection_proba(maps, elements)
    rel = maps.depth - wall_depth(maps)[None, :]
    depths = class_depths(maps, elements)
    gpath = grammar_path(grammar)
    rules, _ = _load_grammar(str(gpath), *_stamp(gpath))
    width = maps.shape[1] * maps.resolution
    fixed = {**pinned_for(rules, ls), "facadeWidth": width}
    fit = fit_grammar(prob, ls, rules, method="evolution", budget=budget, seed=seed, fixed=fixed,
                      initialiser=initialiser_for(rules, one_facade=True), depth=rel,
                      depths=depths)
    small = shrink_proba(prob, ENERGY_SIDE)
    ea = SegmentationEnergy(small, ls)
    ed = DepthEnergy(_resize_depth(rel.astype(np.float32), small.shape[:2]), depths)
    e_grammar = [ea(fit.layout), ed(fit.layout)]
    energies = {"grammar": e_grammar}
    front = [list(map(float, v)) for v in fit.search.front]
    rows = front + [e_grammar]
    if element_tree is not None:
        lay = tree_layout(element_tree, width, maps.shape[0] * maps.resolution)
        e_el = [ea(lay), ed(lay)]
        energies["elements"] = e_el
        rows.append(e_el)
    F = np.array(rows, float)
    k, alpha, rng = auto_alpha(F)
    chosen = "grammar"
    if element_tree is not None:
        e = alpha * F[:, 0] + (1 - alpha) * F[:, 1]
        keep = pareto_mask(F)
        # the measured layout wins ties: the grammar must explain the scan strictly better
        chosen = "elements" if keep[-1] and e[-1] <= np.min(e[keep]) + 1e-9 * abs(e[-1]) \
            else "grammar"
    return DepthFit(chosen=chosen, fit=fit, energies=energies, alpha=alpha, alpha_range=rng,
                    depths=depths, front=front)
