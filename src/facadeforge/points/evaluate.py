"""How good a point-cloud reconstruction is: element detection in the facade plane, and the
geometric accuracy per class of ``simon2011`` §5.4.3 (eq. 5.10–5.11).

- :func:`truth_boxes` — the ground-truth rectangle of each labelled element instance of a cloud
  (windows, doors, balconies…): the extent of its points in the facade frame.
- :func:`match` — detections against truth at IoU ≥ 0.5 *in the facade plane*, one-to-one
  (greedy by IoU), per class and over the classes asked for; a detection must carry the
  truth's label to count.
- :func:`class_distances` — eq. 5.11: for each class ``c``, the mean over points ``x`` of the
  model's surface of class ``c`` of the distance to the nearest reference point of that class
  (eq. 5.10 restricted to a class; the thesis compares a derived model with a hand-made one,
  we compare with the labelled scan itself, the stricter reference).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from .cloud import PointCloud
from .maps import FacadeFrame

__all__ = ["box_iou", "class_distances", "match", "model_distance", "model_triangles",
           "sample_model", "truth_boxes"]

#: Thesis Table 5.1 (cm): geometric accuracy of its multi-view reconstructions, eq. 5.11.
THESIS_TABLE_5_1_CM = {"window": 11, "wall": 4, "balcony": 13, "door": 1, "roof": 31, "shop": 27}


def truth_boxes(cloud: PointCloud, frame: FacadeFrame, labels: Sequence[str] = ("window", "door",
                                                                              "balcony")
                ) -> list[dict]:
    """``[{"label", "box_m": (u0, v0, u1, v1), "points"}]`` for each labelled instance of the
    given classes whose points lie on this facade (its frame's rectangle)."""
    if cloud.labels is None or cloud.instance is None:
        return []
    f = frame.to_facade(cloud.xyz)
    inside = (f[:, 0] > -0.5) & (f[:, 0] < frame.width + 0.5) & (np.abs(f[:, 2]) < 3.0)
    out = []
    for name in labels:
        if name not in cloud.label_names:
            continue
        sel = inside & (cloud.labels == cloud.label_names.index(name))
        for inst in np.unique(cloud.instance[sel]):
            if inst < 0:
                continue
            p = f[sel & (cloud.instance == inst)]
            if len(p) < 20:
                continue
            u0, v0 = p[:, 0].min(), p[:, 1].min()
            u1, v1 = p[:, 0].max(), p[:, 1].max()
            out.append({"label": name, "box_m": (float(u0), float(v0), float(u1), float(v1)),
                        "points": int(len(p)), "instance": int(inst)})
    return out


def box_iou(a, b) -> float:
    """Intersection over union of two rectangles ``(u0, v0, u1, v1)``."""
    iw = min(a[2], b[2]) - max(a[0], b[0])
    ih = min(a[3], b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    inter = iw * ih
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def match(pred: Sequence[dict], truth: Sequence[dict], *, iou: float = 0.5,
          classes: Sequence[str] = ("window", "door")) -> dict:
    """Precision, recall, F1 per class and over ``classes`` (micro); items carry ``label`` and
    ``box_m``.  Also ``any_label``: the same with labels ignored (localisation only)."""

    def run(p_items, t_items, same_label: bool):
        pairs = []
        for i, p in enumerate(p_items):
            for j, t in enumerate(t_items):
                if same_label and p["label"] != t["label"]:
                    continue
                v = box_iou(p["box_m"], t["box_m"])
                if v >= iou:
                    pairs.append((v, i, j))
        used_p, used_t, ious = set(), set(), []
        for v, i, j in sorted(pairs, reverse=True):
            if i in used_p or j in used_t:
                continue
            used_p.add(i)
            used_t.add(j)
            ious.append(v)
        tp = len(ious)
        prec = tp / len(p_items) if p_items else 0.0
        rec = tp / len(t_items) if t_items else 0.0
        f1 = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
        return {"tp": tp, "predicted": len(p_items), "truth": len(t_items),
                "precision": round(prec, 4), "recall": round(rec, 4), "f1": round(f1, 4),
                "mean_iou": round(float(np.mean(ious)), 4) if ious else 0.0}

    p_all = [p for p in pred if p["label"] in classes]
    t_all = [t for t in truth if t["label"] in classes]
    out = {"iou": iou, "classes": list(classes), **run(p_all, t_all, True),
           "any_label": run(p_all, t_all, False)}
    out["per_class"] = {c: run([p for p in p_all if p["label"] == c],
                               [t for t in t_all if t["label"] == c], True) for c in classes}
    return out


def model_triangles(models, origin) -> tuple[np.ndarray, list[str]]:
    """Triangles ``(T, 3, 3)`` of placed models (CGA axes relative to ``origin``, as
    :func:`~.pipeline.points` writes them) back in the cloud's coordinates (z up), and the
    label of each."""
    tris, labels = [], []
    for m in models:
        for p in m.parts:
            pos = p.mesh.triangulate()[0].reshape(-1, 3, 3)
            # CGA (x, y up, z) → cloud (x, −z, y)
            tris.append(np.stack([pos[..., 0], -pos[..., 2], pos[..., 1]], -1) + origin)
            labels += [p.label] * len(pos)
    if not tris:
        return np.zeros((0, 3, 3)), []
    return np.concatenate(tris), labels


def sample_model(triangles: np.ndarray, labels: Sequence[str], spacing: float = 0.05,
                 rng: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Points on a triangle soup, about one per ``spacing``² m² (the thesis's "fine point
    clouds derived from both models"): ``(points (M, 3), label per point)``."""
    tri = np.asarray(triangles, float)
    if not len(tri):
        return np.zeros((0, 3)), np.zeros(0, dtype=object)
    gen = np.random.default_rng(rng)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    n = gen.poisson(area / spacing ** 2)
    idx = np.repeat(np.arange(len(tri)), n)
    r1, r2 = gen.random(len(idx)), gen.random(len(idx))
    s = np.sqrt(r1)
    a, b, c = tri[idx, 0], tri[idx, 1], tri[idx, 2]
    pts = (1 - s)[:, None] * a + (s * (1 - r2))[:, None] * b + (s * r2)[:, None] * c
    return pts, np.asarray(labels, dtype=object)[idx]


def class_distances(model_pts: np.ndarray, model_labels: np.ndarray, cloud: PointCloud,
                    classes: Sequence[str] | None = None, cap: float = 1.0) -> dict:
    """Eq. 5.11 per class (cm): mean distance of the model's points of class ``c`` to the
    nearest reference point of class ``c``; distances are capped at ``cap`` m (a model element
    where the scan has none would otherwise dominate the mean) and the share of capped points is
    reported.  ``all``: the same over every class the two share, each model point against the
    scan points of its own class (eq. 5.10, class-agnostic, is :func:`model_distance`)."""
    if cloud.labels is None:
        return {}
    names = list(cloud.label_names)
    classes = [c for c in (classes or names) if c in names]
    out: dict = {}
    all_d = []
    for c in classes:
        ref = cloud.xyz[cloud.labels == names.index(c)]
        pts = model_pts[model_labels == c]
        if not len(ref) or not len(pts):
            continue
        d, _ = cKDTree(ref).query(pts, workers=-1)
        all_d.append(np.minimum(d, cap))
        out[c] = {"cm": round(float(np.minimum(d, cap).mean()) * 100, 2),
                  "median_cm": round(float(np.median(d)) * 100, 2),
                  "capped_share": round(float((d > cap).mean()), 4), "points": int(len(pts))}
    if all_d:
        out["all"] = {"cm": round(float(np.concatenate(all_d).mean()) * 100, 2)}
    return out


def model_distance(model_pts: np.ndarray, reference: np.ndarray, cap: float = 1.0) -> dict:
    """Eq. 5.10 (cm): the mean distance from the model's points to the nearest reference point
    of any class (capped at ``cap`` m, the capped share reported)."""
    if not len(model_pts) or not len(reference):
        return {}
    d, _ = cKDTree(reference).query(model_pts, workers=-1)
    return {"cm": round(float(np.minimum(d, cap).mean()) * 100, 2),
            "median_cm": round(float(np.median(d)) * 100, 2),
            "capped_share": round(float((d > cap).mean()), 4), "points": int(len(model_pts))}
