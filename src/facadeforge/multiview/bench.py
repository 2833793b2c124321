"""``bench --method multiview``: the photos to score reconstructed in 3D, a few neighbouring
views at a time, and each photo's labels rendered from its model.

The photos of a split are a stretch of a street, not one building.  They are taken in order
(sorted ids: ``IMG_`` numbers follow the camera along the street), cut where two consecutive
camera centres stand more than :data:`BREAK_FACTOR` times the median step apart
(a cross street, a part of the sequence that is not in the folder), and each run is cut again
into groups of at most :data:`MULTIVIEW_GROUP` consecutive views of about equal size — the
views that see the same one or two buildings.  Each group is one :func:`~.pipeline.multiview`
run; every photo is labelled by its own group's model.  Nothing here reads a photo's truth.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["BREAK_FACTOR", "MULTIVIEW_GROUP", "camera_file_of", "groups", "reconstruct_groups"]

#: Most views reconstructed together.
MULTIVIEW_GROUP = 6
#: A step along the street this many times the median step starts a new run.
BREAK_FACTOR = 4.0


def camera_file_of(sample) -> Path:
    """``cameras.txt`` beside the photo's ``img/`` folder (the RueMonge layout)."""
    p = Path(sample.image_path).parent.parent / "cameras.txt"
    if not p.is_file():
        raise InputError(f"multiview: {p} not found; the split folder must hold the photos' "
                         "calibrated cameras as cameras.txt beside img/")
    return p


def groups(ids: Sequence[str], cameras: dict, size: int = MULTIVIEW_GROUP) -> list[list[str]]:
    """Groups of neighbouring views (module docstring), in street order."""
    ids = sorted(ids)
    if len(ids) <= 1:
        return [list(ids)] if ids else []
    centres = np.array([cameras[i].C for i in ids], float)
    step = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    med = float(np.median(step)) if len(step) else 0.0
    runs, cur = [], [ids[0]]
    for k in range(1, len(ids)):
        if med > 0 and step[k - 1] > BREAK_FACTOR * med:
            runs.append(cur)
            cur = []
        cur.append(ids[k])
    runs.append(cur)
    out = []
    for run in runs:
        n = math.ceil(len(run) / size)
        bounds = np.linspace(0, len(run), n + 1).round().astype(int)
        out += [run[a:b] for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    return out


def reconstruct_groups(samples, *, budget: int | None = None, progress: bool = True,
                       depth_energy: bool = True) -> tuple[dict[str, np.ndarray], list[dict]]:
    """Canonical labels of every sample that has a camera, and one report per group."""
    from ..datasets.cameras import read_cameras
    from .pipeline import BUDGET, multiview

    by_file: dict[Path, list] = {}
    for s in samples:
        by_file.setdefault(camera_file_of(s), []).append(s)
    labels: dict[str, np.ndarray] = {}
    reports: list[dict] = []
    for path, group_samples in by_file.items():
        cams = read_cameras(path)
        by_id = {s.id: s for s in group_samples if s.id in cams}
        for g in groups(list(by_id), cams):
            photos = {i: by_id[i].image_path for i in g}
            try:
                if len(g) < 2:
                    raise InputError("one view of its stretch: no stereo")
                r = multiview(photos, {i: cams[i] for i in g},
                              budget=BUDGET if budget is None else budget,
                              depth_energy=depth_energy)
            except InputError as e:     # scored on the classifier alone, and said so
                reports.append({"photos": g, "error": str(e), "labels": "classifier"})
                if progress:
                    print(f"multiview {g[0]}…{g[-1]}: {e}; classifier labels", file=sys.stderr)
                labels.update({i: _classifier_labels(by_id[i]) for i in g})
                continue
            labels.update({i: r.labels[i] for i in g})
            reports.append({"photos": g, "facades": len(r.facades),
                            "timings": r.report["timings"]})
    return labels, reports


def _classifier_labels(sample) -> np.ndarray:
    """The shipped street classifier's canonical labels of one photo (the ``classifier``
    method's)."""
    from ..datasets import get_label_set
    from ..evaluation.methods import ClassifierMethod

    ls = get_label_set("ecp7")
    return ls.to_canonical(ClassifierMethod()(sample, ls).labels)
