"""Several pixel classifiers averaged, in one label set: the shipped ``cmp6`` default.

Averaging the probabilities of models trained differently is the cheapest accuracy there is
(Dietterich 2000): their errors are partly independent.  The shipped ``ensemble-cmp6`` averages
two facade U-Nets (:mod:`.convnet`) trained on the same CMP facades, one in the merged ``cmp6``
classes and one in CMP's twelve (``cmp12``: it must tell shutters from glass and sills from
wall).  A member's probabilities are first projected onto the ensemble's label set
(:meth:`~facadeforge.datasets.LabelSet.project_proba`: ``cmp12``'s blind adds into ``cmp6``'s
window, its sill into wall).  The members' and the ensemble's scores are in
``benchmarks/results/classifiers.json`` (the docs site's benchmark pages).

Members are stored whole inside the ensemble's ``.npz`` (their arrays under ``m0.``, ``m1.``…,
their kinds, classes and provenance in the metadata), so the file is as safe to load as any
other model (:mod:`.model`).  ``facadeforge train-classifier --kind ensemble --members A.npz
B.npz`` builds one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..datasets import get_label_set
from ..errors import InputError
from .features import resize_proba
from .model import CLASSIFIER_KINDS, PixelClassifier, _load_kinds, register_kind

__all__ = ["EnsembleClassifier", "MAX_MEMBERS"]

#: Most members an ensemble may hold (each costs one classifier's time per photo).
MAX_MEMBERS = 8


@register_kind
class EnsembleClassifier(PixelClassifier):
    """The mean of ``members``' probabilities, each projected onto ``label_set``'s classes."""

    kind = "ensemble"

    def __init__(self, members: Sequence[PixelClassifier], label_set: str,
                 meta: Mapping[str, Any] | None = None):
        members = list(members)
        if not 1 <= len(members) <= MAX_MEMBERS:
            raise InputError(f"an ensemble holds 1 to {MAX_MEMBERS} classifiers, got "
                             f"{len(members)}")
        if any(isinstance(m, EnsembleClassifier) for m in members):
            raise InputError("an ensemble cannot hold another ensemble; list its members")
        target = get_label_set(label_set)
        for i, m in enumerate(members):
            _check_member(i, m, target)
        super().__init__(target.classes, target.name, {**dict(meta or {}), "members": [
            {"kind": m.kind, "classes": list(m.classes), "label_set": m.label_set,
             "meta": dict(m.meta)} for m in members]})
        self.members = members
        self._target = target

    def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
        """The members' probabilities at their working scale (the first member's size),
        projected and averaged."""
        out = None
        for m in self.members:
            p = self._target.project_proba(m.predict_proba_coarse(image), m.classes)
            if out is None:
                out = p.astype(np.float32, copy=True)
            else:
                out += p if p.shape == out.shape else resize_proba(p, out.shape[:2])
        return out / len(self.members)

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {}
        for i, m in enumerate(self.members):
            out.update({f"m{i}.{name}": a for name, a in m.to_arrays().items()})
        return out

    @classmethod
    def from_arrays(cls, arrays, classes, label_set, meta) -> EnsembleClassifier:
        infos = meta["members"]
        if not isinstance(infos, list) or not 1 <= len(infos) <= MAX_MEMBERS:
            raise ValueError(f"members must list 1 to {MAX_MEMBERS} models")
        members = []
        for i, info in enumerate(infos):
            kind = info["kind"]
            _load_kinds(kind)
            if kind not in CLASSIFIER_KINDS or kind == cls.kind:
                raise ValueError(f"member {i} has kind {kind!r}")
            prefix = f"m{i}."
            sub = {k[len(prefix):]: a for k, a in arrays.items() if k.startswith(prefix)}
            members.append(CLASSIFIER_KINDS[kind].from_arrays(
                sub, tuple(str(c) for c in info["classes"]), str(info["label_set"]),
                info.get("meta", {})))
        clf = cls(members, label_set, meta)
        if clf.classes != tuple(classes):
            raise ValueError(f"classes {list(classes)} are not those of label set {label_set}")
        return clf


def _check_member(i: int, m: PixelClassifier, target) -> None:
    """A member's channels must be distinct canonical labels (each lands in a class of the
    ensemble's set), classes of its own label set in that set's order when it is a known one
    (a scribble GMM has only the classes stroked)."""
    from ..datasets import LABEL_SETS

    where = f"ensemble member {i} ({m.kind}, {m.label_set})"
    if len(set(m.classes)) != len(m.classes) or not m.classes:
        raise InputError(f"{where}: its classes {list(m.classes)} are empty or repeated")
    for c in m.classes:
        target.index(c)                      # InputError naming a non-canonical class
    known = LABEL_SETS.get(m.label_set)
    if known is not None and [c for c in known.classes if c in m.classes] != list(m.classes):
        raise InputError(f"{where}: its classes {list(m.classes)} are not label set "
                         f"{m.label_set}'s {list(known.classes)}")
