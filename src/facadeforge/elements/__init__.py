"""Parametric 3D architectural elements and their front renders (Müller et al. 2007, §4)."""

from .library import (
    LABEL_INDEX,
    MATERIALS,
    ElementSpec,
    element_library,
    element_model,
    element_spec,
    render_front,
)

__all__ = ["LABEL_INDEX", "MATERIALS", "ElementSpec", "element_library", "element_model",
           "element_spec", "render_front"]
