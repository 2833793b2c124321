"""Training one classifier on several datasets that label different things (issue 24).

RueMonge labels roofs and shops but not the street; CMP calls everything that is not the
facade "background"; LabelMeFacade labels cars, vegetation, pavement and road but calls the
whole facade minus windows and doors "building".  A network trained on all three predicts the
union of their classes (the ``street12`` label set) and each dataset supervises only what it
says: a pixel of dataset class ``d`` is scored by the probability that its class is *any* of
the classes ``d`` may be, ``−log Σ_{c ∈ S(d)} p_c`` (the partial-label loss; a plain
cross-entropy where ``S(d)`` is one class).

:func:`partial_table` gives ``S`` for every class of a dataset's label set: the class itself
when ``street12`` has it, else where ``street12``'s canonical mapping sends it (a CMP cornice is
wall), except for the umbrella classes listed in :data:`UMBRELLA`.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from ..datasets.labelsets import LabelSet, get_label_set

__all__ = ["STREET_CLASSES", "UMBRELLA", "partial_table"]

#: Classes of the street classifier (canonical label names), the ``street12`` label set.
STREET_CLASSES: tuple[str, ...] = ("wall", "window", "door", "balcony", "shop", "roof", "sky",
                                   "vegetation", "car", "pavement", "road", "other")

# CMP: "background" is whatever is not the facade: sky, roofs, trees, cars, street, people
_CMP_BACKGROUND = {"background": ("sky", "roof", "vegetation", "car", "pavement", "road", "other")}

#: Dataset classes that stand for several street classes: label set → dataset class name →
#: the street classes it may be.
UMBRELLA: Mapping[str, Mapping[str, tuple[str, ...]]] = MappingProxyType({
    "cmp12": _CMP_BACKGROUND,
    "cmp6": _CMP_BACKGROUND,
    # LabelMeFacade: "building" is the facade around the windows and doors labelled, with its
    # balconies, shop fronts, roofs, and the many windows and doors nobody outlined; "various"
    # is whatever was left unlabelled (trucks, hedges, fire escapes, poles, people): anything
    # but the sky, which is always outlined
    "lmf9": {"building": ("wall", "window", "door", "balcony", "shop", "roof"),
             "various": ("wall", "window", "door", "balcony", "shop", "roof", "vegetation",
                         "car", "pavement", "road", "other")},
})


def partial_table(label_set: LabelSet | str, target: LabelSet | str = "street12") -> np.ndarray:
    """``(n, K)`` bool: which of the ``K`` classes of ``target`` each of the ``n`` classes of
    ``label_set`` may be.

    Raises
    ------
    ValueError
        A dataset class that may be none of ``classes``.
    """
    ls, target = get_label_set(label_set), get_label_set(target)
    classes = target.classes
    index = {c: k for k, c in enumerate(classes)}
    umbrella = UMBRELLA.get(ls.name, {})
    table = np.zeros((ls.num_classes, len(classes)), bool)
    for j, name in enumerate(ls.dataset_names):
        canonical = ls.classes[j]
        if name in umbrella:
            targets = umbrella[name]
        elif canonical in index:
            targets = (canonical,)
        else:   # a finer class (cornice, blind…): where the canonical fallback chain sends it
            targets = (classes[target.canonical_map[canonical]],)
        for t in targets:
            if t in index:
                table[j, index[t]] = True
        if not table[j].any():
            raise ValueError(f"class {name!r} of label set {ls.name!r} may be none of "
                             f"{', '.join(classes)}")
    return table
