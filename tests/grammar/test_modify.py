"""modify(f|e|v): components edited and put back into the shape (reference, "modify
operation" and "Shape Recomposition")."""

import numpy as np
import pytest
from cga_helpers import run


def only_part(src, lot="10x8"):
    m = run(src, lot)
    assert not m.warnings, m.warnings
    assert len(m.parts) == 1
    return m.parts[0].mesh


def test_a_scaled_top_face_tapers_the_mass():
    mesh = only_part("Lot --> extrude(5) modify(f){ top : s('0.5, '0.5, '1) center(xy) X. } M.")
    assert mesh.n_faces == 6 and mesh.is_closed()
    # the top face scope: x, y in its plane; a frustum from 10 x 8 to 5 x 4 over 5 m, the
    # sides followed the top's vertices
    assert abs(mesh.volume()) == pytest.approx(5 / 3 * (80 + 20 + np.sqrt(80 * 20)))
    top = mesh.vertices[mesh.vertices[:, 1] > 4.9]
    assert np.ptp(top[:, 0]) == pytest.approx(5) and np.ptp(top[:, 2]) == pytest.approx(4)


def test_moving_a_ridge_edge_drags_the_roof_planes():
    before = only_part("Lot --> roofHip(40) R.", "12x8")
    # the reference's "Modified Roof Ridge": t(0, 2, 0) moves the ridge "2 meters to the side"
    # (an edge's scope: x along it, z the mean normal of its faces, so y is level on a ridge)
    after = only_part("Lot --> roofHip(40) modify(e){ ridge : t(0, 2, 0) X. } R.", "12x8")
    assert after.n_faces == before.n_faces == 5 and after.is_closed()
    ridge = before.vertices[:, 1] > before.vertices[:, 1].max() - 1e-6
    moved = after.vertices[ridge] - before.vertices[ridge]
    assert np.linalg.norm(moved, axis=1) == pytest.approx([2] * int(ridge.sum()))
    assert moved[:, 1] == pytest.approx([0] * int(ridge.sum()), abs=1e-9)  # sideways
    assert np.ptp(moved, axis=0) == pytest.approx([0, 0, 0], abs=1e-9)   # one rigid shift
    rest = ~ridge & (before.vertices[:, 1] < 1e-9)
    assert after.vertices[rest] == pytest.approx(before.vertices[rest])     # eaves stay


def test_moving_a_vertex():
    mesh = only_part("Lot --> modify(v){ 0 : t(0, 3, 0) X. } X.")
    assert mesh.bounds()[1][1] == pytest.approx(3)
    assert int((np.abs(mesh.vertices[:, 1] - 3) < 1e-9).sum()) == 1


def test_faces_rebuilt_by_a_branch_are_recomposed_with_the_rest():
    m = run("Lot --> extrude(5) modify(f){ top : split(x){ '0.5 : extrude(2) A. | ~1 : B. } } "
            "print(geometry.nFaces) M.")
    assert not m.warnings and m.attributes["prints"] == ["12"]
    assert [p.symbol for p in m.parts] == ["M"]           # modify adds no shapes
    assert m.parts[0].mesh.area() == pytest.approx(260 + 40 + 40 + 40 + 2 * (5 + 8) * 2)


def test_modify_goes_on_with_the_shape_and_unselected_parts_stay():
    m = run("Lot --> extrude(5) modify(f){ bottom : t(0, 0, 0) X. } comp(f){ top : T. }")
    assert [p.symbol for p in m.parts] == ["T"] and m.parts[0].mesh.area() == pytest.approx(80)
    mesh = only_part("Lot --> extrude(5) modify(e){ isTagged(\"nothing\") : t(0, 9, 0) X. } M.")
    assert mesh.bounds()[1][1] == pytest.approx(5)


def test_moving_the_top_along_its_normal_raises_the_mass():
    mesh = only_part("Lot --> extrude(4) modify(f) { top : t(0, 0, 2) } X.")
    assert mesh.bounds()[1] == pytest.approx([10, 6, 8]) and mesh.volume() == pytest.approx(480)


def test_modify_keeps_the_tags_and_materials_its_branches_give():
    m = run('Lot --> extrude(3) modify(f){ top : tag("Roof") color(1, 0, 0) } '
            'comp(f){ isTagged("Roof") : R. | all : O. }')
    assert not m.warnings
    roof = [p for p in m.parts if p.symbol == "R"]
    assert len(roof) == 1 and roof[0].mesh.area() == pytest.approx(80)
    assert roof[0].material.color == pytest.approx((1, 0, 0))
    m = run("Lot --> extrude(3) modify(f){ top : split(x){ ~1 : color(0, 0, 1) X. }* } X.")
    blue = [p for p in m.parts if p.material.color == pytest.approx((0, 0, 1))]
    assert sum(p.mesh.area() for p in blue) == pytest.approx(80)
