"""Geometry kernel: polygon meshes, plane cuts, triangulation, roofs, assets, UVs."""

from .mesh import Mesh

__all__ = ["Mesh"]
