"""The multi-view evidence of a facade (eq. 5.4–5.8 in the facade raster), the local frame and the
labels rendered from a model, on a scene built here: a 10 × 8 m facade plane seen by two
street cameras, a window rectangle the classifier of each view finds."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge.datasets import IGNORE, get_label_set
from facadeforge.datasets.cameras import Camera
from facadeforge.datasets.labelsets import CANONICAL_INDEX
from facadeforge.multiview.appearance import ViewEvidence, fuse
from facadeforge.multiview.frame import EYE_HEIGHT, BuildingFrame, initial_frame, photo_up
from facadeforge.multiview.labels import blend, render_labels
from facadeforge.points.maps import FacadeFrame

LS = get_label_set("ecp7")
W, H = 640, 480
FACADE = FacadeFrame(origin=np.array([0.0, 5.0, 0.0]), u=np.array([1.0, 0, 0]),
                     v=np.array([0, 0, 1.0]), n=np.array([0, -1.0, 0]), width=10.0, height=8.0)
WINDOW = (2.0, 3.0, 4.0, 5.0)            # u0, v0, u1, v1 on the facade


def camera(x: float, name: str) -> Camera:
    R = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])      # looking +y, image y down
    return Camera(name, f"{name}.jpg", 500.0, (W / 2, H / 2), R, np.array([x, -5.0, EYE_HEIGHT]))


def facade_uv(cam: Camera) -> np.ndarray:
    """(H, W, 2) facade (u, v) each photo pixel sees on the plane y = 5."""
    xs, ys = np.meshgrid(np.arange(W), np.arange(H))
    d = np.stack([(xs - W / 2) / cam.focal, (ys - H / 2) / cam.focal, np.ones_like(xs, float)],
                 -1) @ cam.R
    t = (5.0 - cam.C[1]) / d[..., 1]
    p = cam.C + t[..., None] * d
    return np.stack([p[..., 0], p[..., 2]], -1)


def window_prob(cam: Camera, confidence: float = 0.8) -> np.ndarray:
    uv = facade_uv(cam)
    inside = ((uv[..., 0] >= WINDOW[0]) & (uv[..., 0] < WINDOW[2]) & (uv[..., 1] >= WINDOW[1])
              & (uv[..., 1] < WINDOW[3]))
    p = np.full((H, W, LS.num_classes), (1 - confidence) / (LS.num_classes - 1), np.float32)
    p[..., LS.index("window")] = np.where(inside, confidence, p[..., 0])
    p[..., LS.index("wall")] = np.where(inside, p[..., 0], confidence)
    return p


def views(depths=(None, None)):
    out = []
    for k, x in enumerate((3.0, 7.0)):
        cam = camera(x, f"v{k}")
        img = np.full((H, W, 3), 100 + 50 * k, np.uint8)
        out.append(ViewEvidence(cam.id, cam, img, window_prob(cam), depth=depths[k]))
    return out


IDENTITY = BuildingFrame(origin=np.zeros(3), rotation=np.eye(3), scale=1.0)


def test_fused_evidence_puts_the_window_where_both_views_see_it():
    ev = fuse(FACADE, (80, 100), 0.1, views(), IDENTITY)
    top = np.argmax(ev.prob, axis=2)
    # cell (row, col) centre: u = (col + .5) / 10, v = 8 − (row + .5) / 10
    assert top[40, 30] == LS.index("window")            # u 3.05, v 3.95
    assert top[40, 70] == LS.index("wall")
    assert (ev.views[40, 30], ev.views[40, 70]) == (2, 2)
    # the coverage of a cell is r² f² cos θ / z²: 25 px straight ahead at 10 m
    assert ev.coverage[60, 30] == pytest.approx(2 * 25 * 0.99, rel=0.05)
    assert ev.rgb[40, 30].tolist() in ([100] * 3, [150] * 3)


def test_cells_no_view_sees_cost_the_average():
    # the top of a 30 m high facade is outside both photos
    tall = FacadeFrame(FACADE.origin, FACADE.u, FACADE.v, FACADE.n, 10.0, 30.0)
    ev = fuse(tall, (300, 100), 0.1, views(), IDENTITY)
    assert ev.views[0, 50] == 0
    assert np.allclose(ev.prob[0, 50], 1 / LS.num_classes)


def test_a_view_that_sees_an_occluder_is_left_out_there():
    # view 0's depth map says something stands 3 m in front of the facade over the window
    near = np.full((H, W), np.inf, np.float32)
    near[:, :] = 10.0                                     # the facade: 10 units deep
    near[60:300, 200:400] = 4.0                           # a tree
    ev = fuse(FACADE, (80, 100), 0.1, views((near, None)), IDENTITY)
    cam = camera(3.0, "v0")
    px = cam.project(np.array([[3.05, 5.0, 3.95]]))[0]
    assert 200 <= px[0] < 400 and 60 <= px[1] < 300       # the cell is behind the tree in view 0
    assert ev.views[40, 30] == 1 and ev.rgb[40, 30].tolist() == [150] * 3


def test_faces_seen_from_behind_are_not_seen():
    back = FacadeFrame(FACADE.origin, -FACADE.u, FACADE.v, -FACADE.n, 10.0, 8.0)
    ev = fuse(back, (80, 100), 0.1, views(), IDENTITY)
    assert ev.views.max() == 0


def test_photo_up_and_the_initial_frame():
    cams = {c.id: c for c in (camera(3.0, "a"), camera(7.0, "b"))}
    shapes = {k: (H, W) for k in cams}
    assert np.allclose(photo_up(cams["a"], (H, W)), [0, 0, 1])
    fr = initial_frame(cams, shapes)
    assert np.allclose(fr.rotation[2], [0, 0, 1])
    assert abs(fr.rotation[0] @ [1, 0, 0]) == pytest.approx(1)   # x along the camera path
    # the ground 0.8 units under the cameras: 2 m per unit
    g = fr.refine(np.array([0, 0, 1.0]), np.array([5.0, 0, EYE_HEIGHT - 0.8]),
                  np.array([c.C for c in cams.values()]))
    assert g.scale == pytest.approx(EYE_HEIGHT / 0.8)
    p = np.array([[1.0, 2.0, 3.0]])
    assert np.allclose(g.to_world(g.to_local(p)), p)
    assert g.to_local(np.array([[5.0, -5.0, EYE_HEIGHT - 0.8]]))[0] == pytest.approx([0, 0, 0])


def test_a_turned_photo_still_points_up():
    # a calibrated landscape image stored as a portrait photo (the RueMonge layout)
    R = np.array([[0, 0, -1.0], [-1.0, 0, 0], [0, 1.0, 0]])  # image x = world down
    cam = Camera("t", "t.jpg", 500.0, (W / 2, H / 2), R, np.zeros(3))
    assert cam.turned((W, H))
    assert np.allclose(photo_up(cam, (W, H)), [0, 0, 1])


def test_labels_rendered_from_the_model():
    cam = camera(3.0, "v0")
    u0, v0, u1, v1 = WINDOW
    a, b, c, d = (FACADE.to_cloud(np.array([[u, v, 0.0]]))[0]
                  for u, v in ((u0, v0), (u1, v0), (u1, v1), (u0, v1)))
    tris = np.array([[a, b, c], [a, c, d]])
    lab, depth = render_labels(tris, np.full(2, CANONICAL_INDEX["window"]), cam, (H, W))
    px = np.rint(cam.project(np.array([[3.0, 5.0, 4.0]]))[0]).astype(int)
    assert lab[px[1], px[0]] == CANONICAL_INDEX["window"]
    assert depth[px[1], px[0]] == pytest.approx(10.0, rel=1e-6)
    assert lab[5, 5] == IGNORE and np.isinf(depth[5, 5])
    # blended with the classifier: the model's window stands, the classifier fills the rest
    out = blend(lab, window_prob(cam), LS, 0.25)
    assert out[px[1], px[0]] == CANONICAL_INDEX["window"]
    assert out[5, 5] == CANONICAL_INDEX["wall"]


def test_bench_groups_cut_at_jumps_and_cap_the_size():
    from facadeforge.multiview.bench import groups

    xs = [0, 1, 2, 3, 4, 5, 6, 7, 30, 31, 32]           # a cross street after the 8th photo
    cams = {f"IMG_{k:04d}": camera(float(x), f"IMG_{k:04d}") for k, x in enumerate(xs)}
    g = groups(list(cams), cams, size=6)
    assert [len(x) for x in g] == [4, 4, 3]
    assert g[2] == ["IMG_0008", "IMG_0009", "IMG_0010"]
    assert sorted(i for x in g for i in x) == sorted(cams)


def test_facades_meeting_at_a_corner_are_one_building():
    from facadeforge.multiview.pipeline import _buildings

    front = FacadeFrame(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]),
                        np.array([0, -1.0, 0]), 10.0, 8.0)
    side = FacadeFrame(np.array([10.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]),
                       np.array([1.0, 0, 0]), 6.0, 8.0)
    far = FacadeFrame(np.array([40.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]),
                      np.array([0, -1.0, 0]), 10.0, 8.0)
    assert _buildings([front, far, side]) == [0, 1, 0]
    assert _buildings([]) == []
