"""Synthetic laser scans: exact ray casting, labels of the part hit, recesses, glass, determinism,
the output frame, mobile scan lines, files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facadeforge.datasets import scans as S
from facadeforge.datasets.synthetic import load_style, make_facade
from facadeforge.errors import InputError
from facadeforge.geometry.mesh import Mesh
from facadeforge.model.model import Model, Part

SIGMA = 0.005
# a box in the CGA frame (y up): x 0..10, y 0..6, z -8..0; in the output frame (z up)
# X 0..10, Y 0..8, Z 0..6, its front face Y = 0 facing -Y
LO, HI = np.array([0.0, 0.0, 0.0]), np.array([10.0, 8.0, 6.0])


def _box_faces():
    x0, y0, z0, x1, y1, z1 = 0.0, 0.0, -8.0, 10.0, 6.0, 0.0
    return {
        "front": [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
        "back": [[x1, y0, z0], [x0, y0, z0], [x0, y1, z0], [x1, y1, z0]],
        "left": [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],
        "right": [[x1, y0, z1], [x1, y0, z0], [x1, y1, z0], [x1, y1, z1]],
        "top": [[x0, y1, z1], [x1, y1, z1], [x1, y1, z0], [x0, y1, z0]],
    }


def _box_model(front_label: str = "wall") -> Model:
    faces = _box_faces()
    front = Part(Mesh.from_polygons([np.array(faces.pop("front"), float)]), front_label,
                 symbol="Front", shape_id=7)
    rest = Part(Mesh.from_polygons([np.array(f, float) for f in faces.values()]), "wall",
                symbol="Wall", shape_id=3)
    return Model(parts=[front, rest], name="box")


def _box_distance(p: np.ndarray) -> np.ndarray:
    """Unsigned distance of points to the surface of the box LO–HI."""
    q = np.abs(p - (LO + HI) / 2) - (HI - LO) / 2
    outside = np.linalg.norm(np.maximum(q, 0), axis=1)
    inside = np.minimum(q.max(axis=1), 0)
    return np.abs(outside + inside)


STATIONS = [[5.0, -9.0, 1.7], [16.0, -6.0, 1.7]]


def _box_scan(**kw):
    opts = dict(scanners=STATIONS, angular_step_deg=0.4, occluders=False, ground=False, seed=1)
    opts.update(kw)
    return S.simulate_scan(_box_model(), **opts)


def test_box_points_lie_on_its_faces():
    res = _box_scan()
    c = res.cloud
    assert len(c) > 5000 and c.up == 2
    assert _box_distance(c.xyz).max() <= 4 * SIGMA
    # the front (Y = 0) from both stations, the right side (X = 10) from the second only
    on_front = np.abs(c.xyz[:, 1]) < 4 * SIGMA
    on_right = np.abs(c.xyz[:, 0] - 10) < 4 * SIGMA
    assert (on_front | on_right).all() and on_front.sum() > 1000 and on_right.sum() > 500
    assert (c.extra["scanner"][on_right & ~on_front] == 1).all()
    # true normals face the scanner: the front's is -Y, the right side's +X
    assert np.allclose(c.normals[on_front & ~on_right], [0, -1, 0], atol=1e-6)
    assert np.allclose(c.normals[on_right & ~on_front], [1, 0, 0], atol=1e-6)
    # the range is the distance to the station, within the noise
    d = np.linalg.norm(c.xyz - res.scanners[c.extra["scanner"]], axis=1)
    assert np.allclose(d, c.extra["range"], atol=1e-4)
    assert c.intensity.min() >= 0 and c.intensity.max() <= 65535 and c.intensity.std() > 0


def test_noise_free_scan_is_exact_and_labels_are_the_part_hit():
    res = S.simulate_scan(_box_model("door"), scanners=STATIONS, angular_step_deg=0.4,
                          occluders=False, ground=False, range_noise=0.0)
    c = res.cloud
    assert _box_distance(c.xyz).max() < 1e-9
    names = np.array(c.label_names)[c.labels]
    front = np.abs(c.xyz[:, 1]) < 1e-9
    right = np.abs(c.xyz[:, 0] - 10) < 1e-9
    assert (names[front & ~right] == "door").all()
    assert (names[right & ~front] == "wall").all()
    # one instance per part, renumbered from 0, named in `instances`
    ids = {int(i) for i in np.unique(c.instance)}
    assert ids == {0, 1} and res.instances == {0: "door", 1: "wall"}
    assert set(np.unique(c.instance[front & ~right])) == {0}


def test_frame_is_z_up_right_handed():
    m = S.Y_UP_TO_Z_UP
    assert np.allclose(m @ m.T, np.eye(3)) and np.isclose(np.linalg.det(m), 1.0)
    assert np.allclose(m @ [0, 1, 0], [0, 0, 1]) and np.allclose(m @ [0, 0, 1], [0, -1, 0])


@pytest.fixture(scope="module")
def building():
    rng = np.random.default_rng(11)
    layout = make_facade("modern", rng, px_per_m=4.0,
                         attrs={**S._overrides(load_style("modern")), "nFloors": 2,
                                "facadeWidth": 14.0, "windowKind": "punched",
                                "balconyKind": "none", "penthouse": False})
    return S.facade_building(layout, depth=10.0)


def _scan(model, **kw):
    opts = dict(angular_step_deg=0.3, occluders=False, seed=5)
    opts.update(kw)
    return S.simulate_scan(model, **opts)


def _depths(res):
    front = next(p for p in res.facade_planes if p["kind"] == "front")
    return (res.cloud.xyz - front["point"]) @ front["normal"], front


def test_window_recesses_are_behind_the_wall_plane(building):
    res = _scan(building)
    c = res.cloud
    names = np.array(c.label_names)[c.labels]
    d, front = _depths(res)
    assert np.allclose(front["normal"], [0, -1, 0])
    win = names == "window"
    assert win.sum() > 500
    assert d[win].max() < -0.08 and np.median(d[win]) < -0.1
    wall = (names == "wall") & (np.abs(d) < 0.5)
    assert np.mean(np.abs(d[wall]) < 4 * SIGMA) > 0.5  # spandrels and panels stand off it
    assert {"wall", "window", "door", "ground", "roof"} <= set(names)
    # the element rectangles: windows set back, their points inside their rectangle
    wins = [e for e in res.elements if e["label"] == "window"]
    assert len(wins) >= 4
    u, n = front["u"], front["normal"]
    v = np.cross(n, u)
    for e in wins:
        corners = np.asarray(e["corners"])
        assert e["depth"] < -0.1
        assert np.allclose((corners - front["point"]) @ n, e["depth"])
        mine = c.instance == e["instance"]
        if not mine.any():
            continue
        pu, pv = (c.xyz[mine] - corners[0]) @ u, (c.xyz[mine] - corners[0]) @ v
        assert pu.min() > -0.02 and pu.max() < e["width"] + 0.02
        assert pv.min() > -0.02 and pv.max() < e["height"] + 0.02


def test_glass_returns_pass_through_and_losses(building):
    none = _scan(building, glass_return=0.0)
    surf = none.cloud.extra["surface"]
    assert not (surf == S.GLASS).any()
    names = np.array(none.cloud.label_names)[none.cloud.labels]
    d, _ = _depths(none)
    assert (names == "other").sum() > 50 and d[names == "other"].max() < -3.0
    opaque_glass = _scan(building, glass_return=1.0, glass_pass=0.0)
    s2 = opaque_glass.cloud.extra["surface"]
    names2 = np.array(opaque_glass.cloud.label_names)[opaque_glass.cloud.labels]
    assert (s2 == S.GLASS).sum() > 200 and "other" not in set(names2)
    assert set(names2[s2 == S.GLASS]) <= {"window", "door", "shop"}
    lost = _scan(building, glass_return=0.0, glass_pass=0.0)
    assert len(lost.cloud) < len(opaque_glass.cloud)
    with pytest.raises(InputError):
        _scan(building, glass_return=0.8, glass_pass=0.5)


def test_same_seed_same_scan_other_seed_other_noise(building):
    a = _scan(building, occluders=True, seed=3)
    b = _scan(building, occluders=True, seed=3)
    for name in ("xyz", "intensity", "labels", "instance"):
        assert np.array_equal(getattr(a.cloud, name), getattr(b.cloud, name))
    c = _scan(building, occluders=True, seed=4)
    assert len(c.cloud) != len(a.cloud) or not np.array_equal(c.cloud.xyz, a.cloud.xyz)


def test_mobile_scan_lines_are_profiles_across_the_street(building):
    res = _scan(building, kind="mobile", angular_step_deg=0.5, line_spacing=0.25)
    st = res.scanners
    assert len(st) > 20
    assert np.allclose(np.linalg.norm(np.diff(st, axis=0), axis=1), 0.25)
    heading = (st[-1] - st[0]) / np.linalg.norm(st[-1] - st[0])
    c = res.cloud
    along = (c.xyz - st[c.extra["scanner"]]) @ heading
    assert np.abs(along).max() < 1e-6
    names = set(np.array(c.label_names)[c.labels])
    assert {"wall", "window", "ground"} <= names


def test_occluders_stand_in_the_street(building):
    res = _scan(building, occluders=True, seed=0, kind="mobile", line_spacing=0.3,
                angular_step_deg=0.4)
    assert {"ground", "vegetation", "car"} <= set(res.instances.values())
    d, _ = _depths(res)
    names = np.array(res.cloud.label_names)[res.cloud.labels]
    for label in ("vegetation", "car"):  # between the facade and the scanner line, 7 m out
        occ = names == label
        assert occ.sum() > 200 and d[occ].min() > 0.0 and d[occ].max() < 7.0
    none = _scan(building, occluders=False, seed=0, kind="mobile", line_spacing=0.3,
                 angular_step_deg=0.4)
    assert set(none.instances.values()) & {"vegetation", "car"} == set()


def test_write_scan_round_trip(tmp_path, building):
    res = _scan(building, angular_step_deg=0.6)
    ply, truth = S.write_scan(res, tmp_path / "out")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["scan.ply", "truth.json"]
    head = ply.read_bytes()[:600].decode("ascii", "replace")
    assert head.startswith("ply\nformat binary_little_endian 1.0")
    for prop in ("double x", "double y", "double z", "ushort intensity", "int label",
                 "int instance"):
        assert f"property {prop}" in head
    end = ply.read_bytes().index(b"end_header\n") + len(b"end_header\n")
    data = np.frombuffer(ply.read_bytes()[end:], S.PLY_DTYPE)
    assert len(data) == len(res.cloud)
    assert np.array_equal(data["x"], res.cloud.xyz[:, 0])
    assert np.array_equal(data["label"], res.cloud.labels)
    t = json.loads(truth.read_text())
    assert t["label_names"][1] == "wall" and t["points"] == len(res.cloud)
    assert len(t["elements"]) == len(res.elements)
    assert all(len(e["corners"]) == 4 for e in t["elements"])
    assert any(p["kind"] == "front" for p in t["facade_planes"])


def test_synthetic_scans_are_deterministic_and_varied():
    a = S.synthetic_scans(2, 7, angular_step_deg=0.6, line_spacing=0.4)
    b = S.synthetic_scans(2, 7, angular_step_deg=0.6, line_spacing=0.4)
    assert [r.kind for r in a] == ["terrestrial", "mobile"]
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.cloud.xyz, y.cloud.xyz)
        assert x.meta["buildings"] == y.meta["buildings"]
        assert {"wall", "window", "ground"} <= set(x.label_counts())
        assert x.elements and all(e["label"] in S.ELEMENT_LABELS for e in x.elements)


def test_bad_arguments():
    with pytest.raises(InputError):
        S.simulate_scan(_box_model(), kind="airborne")
    with pytest.raises(InputError):
        S.simulate_scan([], kind="terrestrial")
    with pytest.raises(InputError):
        S.simulate_scan(_box_model(), kind="mobile", trajectory=[[0, 0, 0]])
    with pytest.raises(InputError):
        S.simulate_scan(_box_model(), angular_step_deg=0)
