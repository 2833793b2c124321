"""Synthetic calibrated photo sets: exact depth, labels against the truth rectangles, determinism,
the written folder read back by read_visualsfm and the RueMonge loader."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facadeforge.datasets import IGNORE, get_label_set
from facadeforge.datasets import views as V
from facadeforge.datasets.cameras import Camera, read_visualsfm
from facadeforge.datasets.ruemonge import load_ruemonge
from facadeforge.errors import InputError
from facadeforge.geometry.mesh import Mesh
from facadeforge.model.model import Model, Part

ECP7 = get_label_set("ecp7")
WINDOW, WALL, SKY = ECP7.index("window"), ECP7.index("wall"), ECP7.index("sky")
SIZE = (320, 240)


@pytest.fixture(scope="module")
def vs() -> V.ViewSet:
    return V.synthetic_view_set(5, size=SIZE, style="haussmann", px_per_m=20.0)


def _box() -> Model:
    # x 0..10, y 0..6, z -8..0: the front face z = 0 faces +z (the street)
    x0, y0, z0, x1, y1, z1 = 0.0, 0.0, -8.0, 10.0, 6.0, 0.0
    faces = [[[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
             [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],
             [[x1, y0, z1], [x1, y0, z0], [x1, y1, z0], [x1, y1, z1]],
             [[x0, y1, z1], [x1, y1, z1], [x1, y1, z0], [x0, y1, z0]]]
    part = Part(Mesh.from_polygons([np.array(f, float) for f in faces]), "wall", symbol="Wall")
    return Model(parts=[part], name="box")


def _camera(C, target, focal=300.0, size=SIZE) -> Camera:
    C = np.asarray(C, float)
    return Camera("IMG_0001", "IMG_0001.png", focal, (size[0] / 2, size[1] / 2),
                  V._look_at(C, np.asarray(target, float)), C)


def test_box_depth_exact_and_corner():
    cam = _camera([4.0, 1.6, 11.0], [5.0, 3.0, 0.0], focal=220.0)
    view = V.render_view(_box(), cam, SIZE)
    assert view.rgb.shape == (240, 320, 3) and view.rgb.dtype == np.uint8
    assert view.depth.shape == (240, 320) and view.depth.dtype == np.float32
    hit = np.isfinite(view.depth)
    assert 0.2 < hit.mean() < 0.95
    X = view.points()[hit]
    # every seen point lies on a face of the box; from here only the front face is visible
    assert np.abs(X[:, 2]).max() < 1e-4
    assert (X[:, 0] > -1e-4).all() and (X[:, 0] < 10 + 1e-4).all()
    # against the ray intersected directly with the plane z = 0
    rays = view.rays()[hit]
    direct = (0.0 - cam.C[2]) / rays[:, 2]
    assert np.abs(view.depth[hit] - direct).max() < 1e-4
    assert (view.labels[hit] == WALL).all() and (view.labels[~hit] == SKY).all()
    # the box's top-left front corner: inside (down-right) the box, outside (up-left) sky
    corner = np.array([0.0, 6.0, 0.0])
    x, y = cam.project(corner)[0]
    c, r = int(np.floor(x)), int(np.floor(y))
    assert view.labels[r + 2, c + 2] == WALL and view.labels[r - 2, c - 2] == SKY
    assert np.isinf(view.depth[r - 2, c - 2])
    assert abs(view.depth[r + 2, c + 2] - cam.depth(corner)[0]) < 0.1
    # the rasteriser's pixel convention: pixel floor(x), floor(y) sees the projected point
    p = np.array([4.0, 2.0, 0.0])
    x, y = cam.project(p)[0]
    assert abs(view.depth[int(y), int(x)] - cam.depth(p)[0]) < 0.05


def test_near_plane_drop_and_behind():
    # a camera facing away from the box sees nothing
    cam = _camera([5.0, 1.6, 9.0], [5.0, 1.6, 20.0])
    view = V.render_view(_box(), cam, SIZE)
    assert np.isinf(view.depth).all() and (view.labels == SKY).all()


def test_view_set_depth_on_facade_wall(vs):
    assert len(vs.views) == 3 and set(vs.cameras) == {"IMG_0001", "IMG_0002", "IMG_0003"}
    for view in vs.views:
        hit = np.isfinite(view.depth)
        X = view.points()
        front = view.normals[..., 2] > 0.999
        wall = hit & front & (view.labels == WALL) & (np.abs(X[..., 2]) < 0.02)
        assert wall.sum() > 500
        rays = view.rays()[wall]
        direct = (0.0 - view.camera.C[2]) / rays[:, 2]
        assert np.abs(view.depth[wall] - direct).max() < 1e-4
        assert np.abs(X[wall][:, 2]).max() < 1e-4
        # the street is ignored, nothing else is
        ground = view.labels == IGNORE
        assert ground.any() and np.abs(X[ground][:, 1]).max() < 1e-4


def test_cameras_on_the_street(vs):
    C = np.array([c.C for c in vs.cameras.values()])
    assert np.allclose(C[:, 1], V.EYE_HEIGHT)
    assert (C[:, 2] >= 8.0 - 1e-9).all() and (C[:, 2] <= 15.0 + 1e-9).all()
    gaps = np.diff(C[:, 0])
    assert ((gaps >= 1.5 - 1e-9) & (gaps <= 3.0 + 1e-9)).all()
    for cam in vs.cameras.values():
        assert np.allclose(cam.R @ cam.R.T, np.eye(3), atol=1e-12)
        assert abs(cam.R[0, 1]) < 1e-12          # upright: the x axis is horizontal
        assert cam.R[2, 2] < -0.5                 # looking towards the facade (−z)
        assert cam.principal == (SIZE[0] / 2, SIZE[1] / 2)
    # the whole facade is in view of every camera
    fd = vs.truth["facades"][0]
    corners = np.array([[0, 0, 0], [fd["width"], 0, 0], [fd["width"], fd["height"], 0],
                        [0, fd["height"], 0]], float)
    for cam in vs.cameras.values():
        xy = cam.project(corners)
        assert ((xy >= 0) & (xy <= SIZE)).all()


def _element_pixels(view, fd, label):
    """Pixels of the centres of ``label`` elements not covered by an element in front."""
    out = []
    els = fd["elements"]
    o, u, up, n = (np.asarray(fd[k]) for k in ("origin", "u_axis", "up_axis", "normal"))
    for e in els:
        if e["label"] != label:
            continue
        u0, v0, u1, v1 = e["rect"]
        uc, vc = (u0 + u1) / 2, (v0 + v1) / 2
        covered = any(f is not e and f["depth"] > e["depth"] + 1e-6
                      and f["rect"][0] < uc < f["rect"][2] and f["rect"][1] < vc < f["rect"][3]
                      for f in els)
        if covered:
            continue
        X = o + uc * u + vc * up + e["depth"] * n
        x, y = view.camera.project(X)[0]
        if 0 <= x < view.depth.shape[1] and 0 <= y < view.depth.shape[0]:
            out.append((int(y), int(x), X))
    return out


def test_labels_match_truth_rectangles(vs):
    fd = vs.truth["facades"][0]
    assert fd["normal"] == [0.0, 0.0, 1.0] and fd["style"] == "haussmann"
    labels = {e["label"] for e in fd["elements"]}
    assert "window" in labels
    for view in vs.views:
        wins = _element_pixels(view, fd, "window")
        assert len(wins) >= 5
        seen = 0
        P = view.points()
        for r, c, X in wins:
            d = view.camera.depth(X)[0]
            if view.depth[r, c] < d - 0.05:
                # a balcony railing in front of it, seen from below (parallax): the point seen
                # lies in the rectangle of a truth element of the label seen
                u, v = P[r, c, 0], P[r, c, 1]
                names = {e["ecp7"] for e in fd["elements"]
                         if e["rect"][0] - 1e-3 <= u <= e["rect"][2] + 1e-3
                         and e["rect"][1] - 1e-3 <= v <= e["rect"][3] + 1e-3}
                assert ECP7.classes[view.labels[r, c]] in names
                continue
            assert view.labels[r, c] == WINDOW
            assert abs(view.depth[r, c] - d) < 0.05
            seen += 1
        assert seen >= 5
    # the instance ids are those of facade_building's parts
    ids = {p.shape_id for p in vs.models[0].parts if p.shape_id >= 2}
    assert {e["instance"] for e in fd["elements"]} == ids


def test_textured_and_lit(vs):
    view = vs.views[0]
    wall = view.labels == WALL
    # texture: the facade has structure (stereo can match it), the sky is smooth
    g = view.rgb.astype(float).mean(axis=2)
    assert g[wall].std() > 5.0
    # the photo's colour is what the wall shows: compare the mean colour of wall pixels
    tex = vs.textures[0]
    assert np.abs(view.rgb[wall].mean(0) / 255.0 - tex.image.reshape(-1, 3).mean(0)).max() < 0.25


def test_reproducible(vs):
    again = V.synthetic_view_set(5, size=SIZE, style="haussmann", px_per_m=20.0)
    for a, b in zip(vs.views, again.views, strict=True):
        assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.labels, b.labels)
        assert np.array_equal(a.depth, b.depth)
        assert np.array_equal(a.camera.R, b.camera.R) and np.array_equal(a.camera.C, b.camera.C)
    assert again.truth == vs.truth


def test_write_read_back(vs, tmp_path):
    folder = V.write_view_set(vs, tmp_path / "train")
    cams = read_visualsfm(folder / "cameras.txt")
    assert set(cams) == set(vs.cameras)
    fd = vs.truth["facades"][0]
    corners = np.array([[0, 0, 0], [fd["width"], 0, 0], [fd["width"], fd["height"], 0],
                        [0, fd["height"], 0]], float)
    for cid, cam in vs.cameras.items():
        back = cams[cid]
        assert back.file == f"{cid}.png" and back.principal == cam.principal
        assert np.abs(back.project(corners) - cam.project(corners)).max() < 1e-6
        assert np.abs(back.depth(corners) - cam.depth(corners)).max() < 1e-9
    for view in vs.views:
        d = np.load(folder / "depth" / f"{view.id}.npy")
        assert np.array_equal(d, view.depth)
    samples = load_ruemonge(tmp_path, "train")
    assert [s.id for s in samples] == sorted(vs.cameras)
    for s, view in zip(samples, vs.views, strict=True):
        assert np.array_equal(s.image(), view.rgb)
        assert np.array_equal(s.labels(), view.labels)        # street: 0 on disk → IGNORE
    truth = json.loads((folder / "truth.json").read_text())
    assert truth["label_names"] == list(ECP7.classes) and set(truth["cameras"]) == set(cams)
    assert truth["facades"][0]["elements"] == fd["elements"]


def test_corner_building():
    vs = V.synthetic_view_set(3, n_views=2, size=SIZE, style="residential", px_per_m=20.0,
                              n_facades=2)
    assert len(vs.truth["facades"]) == 2 and len(vs.layouts) == 2
    f1 = vs.truth["facades"][1]
    assert np.allclose(f1["normal"], [1, 0, 0]) and np.allclose(f1["u_axis"], [0, 0, -1])
    for view in vs.views:
        for fd in vs.truth["facades"]:
            wins = _element_pixels(view, fd, "window")
            assert wins
            hits = [view.labels[r, c] == WINDOW for r, c, _ in wins]
            assert np.mean(hits) > 0.8
        # points on the second facade's wall plane x = W lie on it exactly
        X = view.points()
        W = vs.truth["facades"][0]["width"]
        on = (view.labels == WALL) & (np.abs(X[..., 0] - W) < 0.02) & (view.normals[..., 0] > 0.999)
        assert on.sum() > 100 and np.abs(X[on][:, 0] - W).max() < 1e-4


def test_bad_arguments():
    with pytest.raises(InputError):
        V.synthetic_view_set(1, n_views=0)
    with pytest.raises(InputError):
        V.synthetic_view_set(1, style="gothic")
    with pytest.raises(InputError):
        V.synthetic_view_set(1, n_facades=3)
    with pytest.raises(InputError):
        V.render_view(_box(), _camera([0, 1, 9], [0, 1, 0]), (0, 10))
