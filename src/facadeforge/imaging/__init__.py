"""Image analysis for photo → procedural facade (Müller et al. 2007): rectification
(:mod:`.rectify`, App. A), a street photo cut into its facades (:mod:`.facades`: the planes of a
corner, the houses side by side), repetition detection by mutual information (:mod:`.symmetry`, §2.1–2.3),
floor/tile split lines (:mod:`.splits`, §2.4), groups of similar tiles (:mod:`.clusters`), tile
refinement (:mod:`.refine`, §3), element matching (:mod:`.matching`, §4) and the shape tree of
the result (:mod:`.shape_tree`)."""

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
