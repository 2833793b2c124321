"""Scoring a multi-view reconstruction against a synthetic building whose truth is exact
(``simon2011`` §5.4.2, §5.4.3): eq. 5.10–5.11 distances and window/door detection.

- :func:`exact_cloud` — the points the views' exact depth maps see (the stereo's ideal), for
  separating the fit's error from the stereo's;
- :func:`perfect_probabilities` — each view's truth labels as probabilities: "the
  classification cues are perfect: the probability is either 1 or 0" (§5.4.2);
- :func:`score` — eq. 5.11 per class and eq. 5.10 (cm; the model sampled every 5 cm, against
  the truth models sampled alike, class ``c`` against class ``c``, capped at 1 m as
  :mod:`facadeforge.points.evaluate` does), and detection P/R/F1 of windows and doors (IoU ≥ 0.5
  in the truth facade's plane).
"""

from __future__ import annotations

import numpy as np

from ..datasets import IGNORE, get_label_set
from ..points.cloud import PointCloud
from ..points.evaluate import class_distances, match, model_distance, sample_model
from .pipeline import MultiviewResult, model_triangles_local

__all__ = ["exact_cloud", "perfect_probabilities", "score"]

#: ecp7 names of the model's part labels.
_ECP7 = {"window": "window", "door": "door", "balcony": "balcony", "shop": "shop",
         "roof": "roof", "wall": "wall"}


def exact_cloud(view_set, step: int = 2) -> PointCloud:
    """Points of every ``step``-th pixel of every view at its exact depth (world frame)."""
    pts, cols = [], []
    for v in view_set.views:
        h, w = v.depth.shape
        ys, xs = np.mgrid[0:h:step, 0:w:step]
        d = v.depth[ys, xs]
        ok = np.isfinite(d)
        cam = v.camera
        ray = np.stack([(xs + 0.5 - cam.principal[0]) / cam.focal,
                        (ys + 0.5 - cam.principal[1]) / cam.focal,
                        np.ones(xs.shape)], -1) @ cam.R
        pts.append((cam.C + d[..., None] * ray)[ok])
        cols.append(v.rgb[ys, xs][ok])
    return PointCloud(np.concatenate(pts), rgb=np.concatenate(cols).astype(np.uint8), up=1,
                      source="exact depth of the synthetic views")


def perfect_probabilities(view_set, floor: float = 0.02) -> dict[str, np.ndarray]:
    """Each view's truth as ``ecp7`` probabilities (``1 − floor`` on its class); the street
    (unlabelled) alike for every class."""
    ls = get_label_set("ecp7")
    k = ls.num_classes
    out = {}
    for cid, v in zip(view_set.cameras, view_set.views):
        p = np.full(v.labels.shape + (k,), floor / (k - 1), np.float32)
        lab = v.labels
        ok = lab != IGNORE
        p[ok] = floor / (k - 1)
        rows, cols = np.nonzero(ok)
        p[rows, cols, lab[ok]] = 1.0 - floor
        p[~ok] = 1.0 / k
        out[cid] = p
    return out


def _truth_triangles(view_set) -> tuple[np.ndarray, list[str]]:
    tris, labels = [], []
    for m in view_set.models:
        for part in m.parts:
            lab = _ECP7.get(part.label or "wall")
            if lab is None:
                continue
            pos = part.mesh.triangulate()[0].reshape(-1, 3, 3)
            tris.append(pos)
            labels += [lab] * len(pos)
    return np.concatenate(tris), labels


def score(result: MultiviewResult, view_set, spacing: float = 0.05) -> dict:
    """Eq. 5.10–5.11 and detection of ``result`` against the synthetic ``view_set``."""
    tris, names = model_triangles_local(result.models())
    out: dict = {"facades_found": len(result.facades),
                 "facades_true": len(view_set.truth["facades"])}
    if not len(tris):
        return out
    world = result.frame.to_world(tris.reshape(-1, 3)).reshape(-1, 3, 3)
    names = [_ECP7.get(n or "wall", "wall") for n in names]
    pts, labs = sample_model(world, names, spacing)
    t_tris, t_names = _truth_triangles(view_set)
    t_pts, t_labs = sample_model(t_tris, t_names, spacing)
    classes = sorted(set(t_names) | set(names))
    ref = PointCloud(t_pts, labels=np.array([classes.index(c) for c in t_labs], np.int32),
                     label_names=tuple(classes), up=1, source="truth")
    out["eq_5_11_cm"] = class_distances(pts, np.asarray(labs), ref)
    out["eq_5_10_cm"] = model_distance(pts, t_pts)
    out["detection"] = _detection(result, view_set)
    return out


def _detection(result: MultiviewResult, view_set) -> dict:
    """Windows and doors of the model against the truth rectangles, in each truth facade's own
    (u, v) metres: a predicted leaf belongs to the truth facade whose plane its centre lies on."""
    truth, pred = [], []
    frames = []
    for k, f in enumerate(view_set.truth["facades"]):
        o = np.array(f["origin"], float)
        u, v, n = (np.array(f[a], float) for a in ("u_axis", "up_axis", "normal"))
        frames.append((o, u, v, n))
        for e in f["elements"]:
            if e["ecp7"] in ("window", "door"):
                truth.append({"label": e["ecp7"], "box_m": tuple(e["rect"]), "facade": k})
    for f in result.facades:
        if f.tree is None:
            continue
        for leaf in f.tree.leaves():
            if leaf.label not in ("window", "door"):
                continue
            o, s = leaf.scope.origin, leaf.scope.size
            corners = f.frame.to_cloud(np.array([[o[0], o[1], 0.0],
                                                 [o[0] + s[0], o[1] + s[1], 0.0]]))
            cw = result.frame.to_world(corners)
            best = min(range(len(frames)), key=lambda k: abs((cw.mean(0) - frames[k][0])
                                                             @ frames[k][3]))
            fo, fu, fv, _ = frames[best]
            uv = np.c_[(cw - fo) @ fu, (cw - fo) @ fv]
            pred.append({"label": leaf.label, "facade": best,
                         "box_m": (float(uv[:, 0].min()), float(uv[:, 1].min()),
                                   float(uv[:, 0].max()), float(uv[:, 1].max()))})
    per = [match([p for p in pred if p["facade"] == k], [t for t in truth if t["facade"] == k])
           for k in range(len(frames))]
    tp = sum(m["tp"] for m in per)
    n_p, n_t = len(pred), len(truth)
    prec = tp / n_p if n_p else 0.0
    rec = tp / n_t if n_t else 0.0
    return {"tp": tp, "predicted": n_p, "truth": n_t, "precision": round(prec, 4),
            "recall": round(rec, 4),
            "f1": round(2 * prec * rec / (prec + rec), 4) if prec + rec else 0.0}
