"""The one data model: ``Scope``, ``Shape``, ``Labels``, ``Model`` (see ARCHITECTURE.md)."""

from .labels import Labels, label_for_name
from .model import Material, Model, Part
from .scope import Scope
from .shape import Shape

__all__ = ["Labels", "Material", "Model", "Part", "Scope", "Shape", "label_for_name"]
