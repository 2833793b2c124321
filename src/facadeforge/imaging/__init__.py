"""Image analysis for photo → procedural facade (Müller et al. 2007, §2): repetition detection by
mutual information (:mod:`.symmetry`) and floor/tile split lines (:mod:`.splits`)."""

from .splits import (
           FacadeStructure,
           edge_maps,
           floor_and_tile_split,
           interest_functions,
           split_lines,
)
from .symmetry import SymmetryProfile, irreducible_facade, mutual_information, symmetry_profile

__all__ = ["FacadeStructure", "SymmetryProfile", "edge_maps", "floor_and_tile_split",
           "interest_functions", "irreducible_facade", "mutual_information", "split_lines",
           "symmetry_profile"]
