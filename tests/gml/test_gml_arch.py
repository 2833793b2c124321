"""Fig. 14 of Hohmann et al. 2009: an arch from a box split into convex polyhedra."""

from __future__ import annotations

import math

import numpy as np

from facadeforge.gml import EXAMPLES, derive_gml


def mesh_is_convex(mesh, tol: float = 1e-6) -> bool:
    v = mesh.vertices
    for face, n in zip(mesh.faces, mesh.face_normals()):
        d = (v - v[face[0]]) @ n
        if d.max() > tol:
            return False
    return True


def test_arch_derives_into_convex_pieces():
    m = derive_gml(EXAMPLES / "fig14_arch.gml")
    assert not m.warnings
    symbols = [p.symbol for p in m.parts]
    assert symbols.count("Stone") == 2 and symbols.count("Voussoir") == 6
    for p in m.parts:
        assert p.mesh.is_closed() and mesh_is_convex(p.mesh) and p.mesh.volume() > 0
    # the stone is the wall less the opening: a 2 × 2 rectangle and a 6-sided half polygon
    w, h, d, spring, r, n = 3.0, 4.0, 0.3, 2.0, 1.0, 6
    opening = 2 * r * spring + n * 0.5 * r * r * math.sin(math.pi / n)
    assert np.isclose(sum(p.mesh.volume() for p in m.parts), d * (w * h - opening), atol=1e-4)
    voids = [s for s in m.root.walk() if s.tags.get("terminal") == "void"]
    assert len(voids) == 1 + n  # the rectangle below the arch and one triangle per wedge
    assert {p.label for p in m.parts} == {"wall", "molding"}


def test_arch_voussoir_count_is_a_parameter():
    text = (EXAMPLES / "fig14_arch.gml").read_text().replace("6 !n", "9 !n")
    m = derive_gml(text)
    assert sum(p.symbol == "Voussoir" for p in m.parts) == 9
