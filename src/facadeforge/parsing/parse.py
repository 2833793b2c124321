"""Photo → grammar derivation: ``facadeforge parse`` and :func:`parse` (``simon2011`` ch. 4–5).

Stages (``report.json`` times each):

1. **load** the photo (any format Pillow reads; gray, RGBA and 16-bit are converted);
2. **classify**: the pixel classifier's probabilities (§4.2.1) at the scale it works at — a
   model file (``--classifier``) or the shipped model (``cmp6`` for rectified photos, ``ecp7``,
   trained on Parisian street photos, otherwise;
   :func:`~facadeforge.classify.default_classifier`);
3. **rectify** (unless ``--rectified``): vanishing points → homography (Müller 2007 App. A, as
   ``reconstruct`` does), found while the classifier runs in a second thread; the
   probabilities are warped straight into the rectified frame at the energy's scale;
4. **search**: the parse grammar's parameters minimising the §4.2.2 energy (hill climbing or the
   evolutionary search) within a budget of derivations, then each element instance fitted on
   its own where the grammar allows it (:mod:`.differentiate`, §3.2.3);
5. **derive**: the engine derives the fitted rules into the shape tree and the 3D model.

OUTDIR: ``labels.png`` (the derivation, rectified frame) and ``labels_input.png`` (photo frame:
the derivation *checked against the evidence*, :meth:`Parse.labels_input`), ``shape_tree.json``, ``rules.cga`` (the grammar
with the fitted values as attribute defaults, so it derives the same layout on its own),
``rules.gml`` (the derivation as a GML program), ``model.glb``, ``model.obj``, ``model.city.json``, ``rectified.png``, ``energy.png`` (the
search's best energy per derivation) and ``report.json``.
"""

from __future__ import annotations

import functools
import json
import os
import re
import time
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..datasets import IGNORE, get_label_set
from ..errors import InputError
from ..model import Model, Shape
from . import DEFAULT_BUDGET
from .fit import (
    ENERGY_SIDE,
    EVIDENCE,
    FitResult,
    energy_shape,
    fit_grammar,
    grammar_path,
    shrink_proba,
)

__all__ = ["DEFAULT_BUDGET", "Parse", "parse", "write_fitted_rules"]


@dataclass
class Parse:
    """What :func:`parse` found: see the module docstring for the fields' files."""

    photo: np.ndarray
    rectified: np.ndarray
    homography: np.ndarray        # photo pixels → rectified pixels
    inverse: np.ndarray
    fit: FitResult
    tree: Shape
    labels: np.ndarray            # canonical label indices, rectified frame
    fallback: np.ndarray          # canonical labels of the classifier alone, photo frame
    rules: str
    report: dict
    model: Model | None = None
    width_m: float = 0.0
    height_m: float = 0.0
    _files: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)   # the input files: save() never writes over them
    prob: np.ndarray | None = None        # the classifier's probabilities, photo frame (coarse)
    label_set: str | None = None          # ... in these classes
    evidence: float = 0.0                 # see labels_input

    def labels_derived(self) -> np.ndarray:
        """Canonical labels in the photo frame: the derivation inside the rectified facade, the
        classifier's argmax outside it."""
        from ..frames import warp_to_image

        warped = warp_to_image(self.labels, self.inverse, self.photo.shape[:2])
        return np.where(warped == IGNORE, self.fallback, warped).astype(np.uint8)

    def labels_input(self, evidence: float | None = None) -> np.ndarray:
        """Canonical labels in the photo frame: the derivation where the classifier's evidence
        does not clearly contradict it.

        A pixel keeps the derived label ``g`` unless the classifier finds another class ``c``
        more than ``exp(evidence)`` times as likely as ``g`` (``log p_c − log p_g > evidence``):
        the grammar is a prior worth ``evidence`` nats per pixel.  That handles what the
        grammar cannot draw (sky above the roof line, a tree or a car in front of the facade:
        classes the derivation lacks), and moves element boundaries the coarse fit left a few
        pixels off to where the photo puts them, while the repetition the grammar imposes
        stands wherever the classifier is unsure.  ``evidence=inf`` is the derivation alone
        (:meth:`labels_derived`), ``0`` the classifier alone.  The default,
        :data:`~facadeforge.parsing.fit.EVIDENCE`, was chosen on the development train splits.
        """
        import cv2

        derived = self.labels_derived()
        evidence = self.evidence if evidence is None else float(evidence)
        if self.prob is None or not np.isfinite(evidence):
            return derived
        ls = get_label_set(self.label_set)
        h, w = derived.shape
        logp = np.log(np.maximum(cv2.resize(self.prob, (w, h), interpolation=cv2.INTER_LINEAR)
                                 .reshape(h, w, -1), 1e-6))
        g = ls.from_canonical(derived)                      # derived labels in the set's classes
        best = np.argmax(logp, axis=2)
        gain = np.take_along_axis(logp, best[..., None], 2)[..., 0] - np.take_along_axis(
            logp, np.where(g == IGNORE, best, g)[..., None].astype(np.int64), 2)[..., 0]
        override = (gain > evidence) | (g == IGNORE)
        top = ls.to_canonical(best.astype(np.uint8))
        return np.where(override, top, derived).astype(np.uint8)

    def save(self, out_dir: str | os.PathLike) -> list[Path]:
        """Write OUTDIR atomically: a staging folder beside it, swapped in for it at the end (the
        files of an earlier run there are replaced; a folder with other files, or holding an
        input, is refused: :mod:`facadeforge.outdir`)."""
        return _save(self, Path(out_dir))


def _warp_prob(prob: np.ndarray, H: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Probabilities warped by pixel homography ``H`` into an image of ``shape``; pixels from
    outside the photo get a uniform distribution."""
    from ..frames import warp

    out = warp(prob.astype(np.float32, copy=False), H, shape)
    s = out.sum(axis=2, keepdims=True)
    return np.where(s > 1e-6, out / np.maximum(s, 1e-6), 1.0 / prob.shape[2]).astype(np.float32)


def _literal(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, np.ndarray | list | tuple):   # a 1-D array attribute
        return "[" + ", ".join(_literal(x) for x in np.ravel(v).tolist()) + "]"
    f = float(v)
    return str(int(f)) if f.is_integer() else repr(f)   # exact: rules.cga derives the same


def write_fitted_rules(source: str, attrs: Mapping[str, Any]) -> str:
    """The grammar text with each fitted attribute's default replaced by its value."""
    out = source
    for name, value in attrs.items():
        pattern = re.compile(rf"^(\s*(?:@\w+(?:\([^)]*\))?\s*)*attr\s+{re.escape(name)}\s*=\s*)"
                             r"([^\n#]*?)(\s*(#.*)?)$", re.M)
        text = _literal(value)
        out, n = pattern.subn(lambda m, t=text: m.group(1) + t + m.group(3), out, count=1)
        if n != 1:
            raise InputError(f"cannot write fitted value of attr {name}: its declaration is not "
                             "on one line in the grammar")
    return out


def _stamp(path: Path) -> tuple[int, int]:
    st = Path(path).stat()
    return st.st_mtime_ns, st.st_size


@functools.lru_cache(maxsize=8)
def _load_grammar(path: str, mtime_ns: int, size: int):
    """``(rules, text)`` of a parse grammar, loaded once per file version (parsing its text
    costs ~0.1 s); the rules are only read, never changed, by a parse."""
    from ..engine import load_rules

    return load_rules(path), Path(path).read_text()


def parse(photo, *, grammar: str | os.PathLike | None = None, classifier=None,
          method: str = "evolution", budget: int = DEFAULT_BUDGET, rectified: bool = False,
          width_m: float | None = None, seed: int = 0, model: bool = True) -> Parse:
    """Parse a facade photo with a grammar (module docstring).

    Parameters
    ----------
    photo : path or (H, W[, C]) array
    grammar : built-in name (``grid``, ``haussmann``, ``generic``) or ``.cga`` path, optional
        Default ``grid`` (on the RueMonge validation photos it fits as well as ``haussmann``
        and its search stalls less often).
    classifier : PixelClassifier or path to a model file, optional
        Default: the shipped model (``cmp6`` if ``rectified`` else ``ecp7``).
    method : {"hill", "evolution"}
    budget : int
        Derivations the search may evaluate.
    width_m : float, optional
        Facade width in metres (scales the model; default the grammar's ``facadeWidth``).
    """
    from ..classify import default_label_set, resolve_classifier
    from ..engine import derive_facade
    from ..exchange.raster import label_map
    from ..photo import analysis_copy, as_rgb, check_facade_size, check_size

    timings: dict[str, float] = {}
    t_start = time.perf_counter()
    t = time.perf_counter()
    check_facade_size(width_m, None)
    if not isinstance(budget, int) or budget < 1:
        raise InputError(f"--budget {budget}: give a positive number of derivations")
    rgb, name = as_rgb(photo)
    check_size(rgb, name)
    clf = resolve_classifier(classifier, default_label_set(rectified))
    label_set = get_label_set(clf.label_set)
    gpath = grammar_path(grammar)
    gpath = Path(gpath).resolve()
    rules, grammar_text = _load_grammar(str(gpath), *_stamp(gpath))
    timings["load"] = time.perf_counter() - t

    def classify() -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Probabilities at the classifier's own scale (the energy shrinks them to
        ENERGY_SIDE anyway), the photo → probability pixel scaling, and the classifier's
        labels in the photo frame."""
        import cv2

        t = time.perf_counter()
        # area-averaged first when a classifier works at the photo's resolution (forest, GMM):
        # the warp below samples bilinearly
        prob = shrink_proba(label_set.project_proba(clf.predict_proba_coarse(rgb), clf.classes),
                            2 * ENERGY_SIDE)
        h, w = rgb.shape[:2]
        to_prob = np.diag([prob.shape[1] / w, prob.shape[0] / h, 1.0])
        top = label_set.to_canonical(np.argmax(prob, axis=2).astype(np.uint8))
        fallback = cv2.resize(top, (w, h), interpolation=cv2.INTER_NEAREST)
        return prob, to_prob, fallback, time.perf_counter() - t

    # The classifier and the rectification do not depend on each other: the classifier runs
    # in a second thread (its filters and tree loop release the GIL) while the main thread
    # finds the vanishing points.
    with ThreadPoolExecutor(max_workers=1) as pool:
        job = pool.submit(classify)
        t = time.perf_counter()
        work, to_work = analysis_copy(rgb)
        rect_note = "photo given as rectified"
        if rectified:
            rect_img, H = work, to_work
        else:
            from ..imaging.rectify import rectify

            r = rectify(work, rng=seed)
            rect_note = r.reason or "rectified"
            rect_img, H = (r.image, r.homography @ to_work) if r else (work, to_work)
        rectify_s = time.perf_counter() - t
        prob, to_prob, fallback, timings["classify"] = job.result()
    t = time.perf_counter()
    # straight into the energy's frame: the rectified facade at ENERGY_SIDE pixels
    rh, rw = rect_img.shape[:2]
    eh, ew = energy_shape(rh, rw)
    to_energy = np.diag([ew / rw, eh / rh, 1.0])
    rect_prob = _warp_prob(prob, to_energy @ H @ np.linalg.inv(to_prob), (eh, ew))
    timings["rectify"] = rectify_s + time.perf_counter() - t

    t = time.perf_counter()
    from .init import initialiser_for, pinned_for

    fixed = pinned_for(rules, label_set)
    if width_m is not None:
        fixed["facadeWidth"] = float(width_m)

    fit = fit_grammar(rect_prob, label_set, rules, method=method, budget=budget, seed=seed,
                      fixed=fixed, initialiser=initialiser_for(rules, one_facade=rectified))
    timings["search"] = time.perf_counter() - t

    t = time.perf_counter()
    text = write_fitted_rules(grammar_text, fit.attrs)
    # the fitted values as attribute overrides derive what rules.cga (text) derives on its own
    derived = derive_facade(rules, fit.width_m, fit.height_m, attrs=fit.attrs, name="facade")
    tree = derived.root
    labels = label_map(tree, size=rect_img.shape[:2]).astype(np.uint8)
    timings["derive"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t_start  # wall time: classify overlaps rectify

    counts = {lab: int(sum(1 for s in tree.leaves() if s.label == lab))
              for lab in ("window", "door", "balcony", "shop")}
    report = {
        "photo": name, "grammar": str(gpath), "method": fit.search.method,
        "budget": budget, "derivations": fit.search.derivations, "seed": seed,
        "energy_per_pixel": round(fit.energy_per_pixel, 6),
        "classifier": {"kind": clf.kind, "label_set": clf.label_set,
                       "trained": clf.meta.get("trained"), "photos": clf.meta.get("photos")},
        "rectification": rect_note, "facade_m": [round(fit.width_m, 3), round(fit.height_m, 3)],
        "attrs": fit.attrs, "elements": counts,
        "timings": {k: round(v, 4) for k, v in timings.items()},
    }
    return Parse(rgb, rect_img, H, np.linalg.inv(H), fit, tree, labels, fallback, text, report,
                 derived if model else None, fit.width_m, fit.height_m,
                 inputs={"photo": photo, "--grammar": grammar, "--classifier": classifier},
                 prob=prob, label_set=label_set.name, evidence=EVIDENCE)


def _energy_png(curve: list[float], path: Path, title: str) -> None:
    """Best energy per derivation, drawn with OpenCV (no plotting library needed)."""
    import cv2

    w, h, m = 640, 360, 48
    img = np.full((h, w, 3), 255, np.uint8)
    c = np.asarray(curve, float)
    c = c[np.isfinite(c)]
    if len(c) >= 2:
        lo, hi = float(c.min()), float(c.max()) or 1.0
        xs = m + (np.arange(len(c)) / (len(c) - 1)) * (w - 2 * m)
        ys = h - m - (c - lo) / max(hi - lo, 1e-12) * (h - 2 * m)
        pts = np.stack([xs, ys], 1).astype(np.int32)
        cv2.polylines(img, [pts], False, (200, 60, 30), 2, cv2.LINE_AA)
        cv2.putText(img, f"{hi:.4g}", (4, m), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        cv2.putText(img, f"{lo:.4g}", (4, h - m), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    cv2.rectangle(img, (m, m), (w - m, h - m), (0, 0, 0), 1)
    cv2.putText(img, title, (m, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, f"derivations (0..{len(curve)})", (w // 2 - 70, h - 12),
                cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.imwrite(str(path), img[:, :, ::-1])


def _save(p: Parse, out: Path) -> list[Path]:
    from PIL import Image

    from ..exchange import export
    from ..exchange.raster import write_label_png
    from ..outdir import write_json, write_outdir

    def write(stage: Path) -> None:
        Image.fromarray(p.rectified).save(stage / "rectified.png", compress_level=1)
        write_label_png(p.labels, stage / "labels.png")
        write_label_png(p.labels_input(), stage / "labels_input.png")
        write_json(stage / "shape_tree.json", p.tree.to_dict(), indent=1)
        (stage / "rules.cga").write_text(p.rules)
        from ..reconstruction import _write_gml

        _write_gml(p.tree, stage / "rules.gml", p.report)
        _energy_png(p.fit.search.curve, stage / "energy.png",
                    f"{p.fit.search.method}: best energy per derivation")
        if p.model is not None:
            for suffix in ("glb", "obj", "city.json"):
                export(p.model, stage / f"model.{suffix}")
        write_json(stage / "report.json", p.report)

    return write_outdir(out, write, p.inputs)
