"""Dense multi-view stereo on a synthetic scene: a textured wall with a recessed window seen by
four turned cameras (the RueMonge layout: portrait photos of landscape calibrations)."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
import pytest

from facadeforge.datasets.cameras import Camera
from facadeforge.errors import InputError
from facadeforge.multiview.mvs import (
    dense_cloud,
    depth_range,
    fuse,
    make_view,
    neighbours,
    photo_camera,
    photo_projection,
    plane_sweep,
)

F, CX, CY = 300.0, 160.0, 120.0          # calibrated 320 × 240; photos stored 240 × 320 (turned)
PHOTO = (320, 240)                        # stored (height, width)
WALL_Z, WINDOW_Z = 10.0, 10.6             # the window pane 0.6 behind the wall
HOLE = (-1.5, 1.5, -1.2, 1.2)             # the window opening in the wall, x0 x1 y0 y1
# world: x right, y down, z away from the cameras; Q turns the photo frame into the calibration's
Q = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _yaw(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])


def _camera(name: str, C, yaw: float = 0.0, turned: bool = True) -> Camera:
    R_photo = _yaw(yaw)                    # rows: photo x-right, y-down, viewing axis
    if turned:
        return Camera(name, f"{name}.jpg", F, (CX, CY), Q.T @ R_photo, np.asarray(C, float))
    return Camera(name, f"{name}.jpg", F, (CY, CX), R_photo, np.asarray(C, float))


def _texture(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    out = np.zeros(shape, np.float32)
    for sigma, weight in ((1.2, 1.0), (4.0, 1.5), (12.0, 2.0)):
        n = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), sigma)
        out += weight * n / n.std()
    out = (out - out.min()) / (out.max() - out.min())
    rgb = np.stack([out, 0.6 * out + 0.2, 1.0 - 0.5 * out], axis=2)
    return (rgb * 255).astype(np.uint8)


def _plane_warp(cam: Camera, z: float, extent, tex_shape) -> np.ndarray:
    """Homography texture → stored photo of the plane ``z`` spanning ``extent``."""
    x0, x1, y0, y1 = extent
    corners = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])
    th, tw = tex_shape
    src = np.float32([[-0.5, -0.5], [tw - 0.5, -0.5], [tw - 0.5, th - 0.5], [-0.5, th - 0.5]])
    dst = cam.project(corners, PHOTO).astype(np.float32)
    return cv2.getPerspectiveTransform(src, dst)


@lru_cache(maxsize=1)
def _scene():
    rng = np.random.default_rng(7)
    wall_ext, win_ext = (-8.0, 8.0, -7.0, 7.0), (-2.5, 2.5, -2.0, 2.0)
    wall_tex = _texture(rng, (14 * 36, 16 * 36))
    win_tex = _texture(rng, (4 * 36, 5 * 36))
    alpha = np.full(wall_tex.shape[:2], 255, np.uint8)
    px = 36.0
    alpha[int((HOLE[2] - wall_ext[2]) * px):int((HOLE[3] - wall_ext[2]) * px),
          int((HOLE[0] - wall_ext[0]) * px):int((HOLE[1] - wall_ext[0]) * px)] = 0
    cams = {"A": _camera("A", [-1.0, 0.0, 0.0], 4.0), "B": _camera("B", [0.0, 0.0, 0.0]),
            "C": _camera("C", [1.0, 0.0, 0.0], -4.0), "D": _camera("D", [0.3, -0.8, 0.5], -2.0)}
    images = {}
    size = (PHOTO[1], PHOTO[0])
    for n, cam in cams.items():
        far = cv2.warpPerspective(win_tex, _plane_warp(cam, WINDOW_Z, win_ext, win_tex.shape[:2]),
                                  size, flags=cv2.INTER_LINEAR)
        Hw = _plane_warp(cam, WALL_Z, wall_ext, wall_tex.shape[:2])
        near = cv2.warpPerspective(wall_tex, Hw, size, flags=cv2.INTER_LINEAR)
        a = cv2.warpPerspective(alpha, Hw, size, flags=cv2.INTER_LINEAR)[:, :, None] / 255.0
        images[n] = np.clip(a * near + (1 - a) * far, 0, 255).astype(np.uint8)
    return images, cams


def _truth(cam: Camera, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """True depth per pixel of a working-scale (``shape``) photo, and the window mask."""
    h, w = shape
    sx, sy = w / PHOTO[1], h / PHOTO[0]
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    full = np.c_[(xs.ravel() + 0.5) / sx - 0.5, (ys.ravel() + 0.5) / sy - 0.5]
    uv = cam.from_photo(full, PHOTO)
    rays = (np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(cam.K).T) @ cam.R   # z-component: depth
    t_wall = (WALL_Z - cam.C[2]) / rays[:, 2]
    X = cam.C + t_wall[:, None] * rays
    hole = (X[:, 0] > HOLE[0]) & (X[:, 0] < HOLE[1]) & (X[:, 1] > HOLE[2]) & (X[:, 1] < HOLE[3])
    t_win = (WINDOW_Z - cam.C[2]) / rays[:, 2]
    # the rays are K⁻¹ [u v 1] turned to world: unit length along the viewing axis, so t = depth
    return np.where(hole, t_win, t_wall).reshape(h, w), hole.reshape(h, w)


@lru_cache(maxsize=1)
def _result():
    images, cams = _scene()
    return dense_cloud(images, cams, max_side=None)


def test_photo_projection_matches_camera_project():
    rng = np.random.default_rng(0)
    X = rng.uniform([-3, -3, 8], [3, 3, 12], (20, 3))
    for turned in (True, False):
        cam = _camera("A", [0.2, -0.1, 0.3], 5.0, turned)
        assert cam.turned(PHOTO) == turned
        shape = PHOTO
        P = photo_projection(cam, shape)
        x = np.c_[X, np.ones(len(X))] @ P.T
        assert np.allclose(x[:, :2] / x[:, 2:], cam.project(X, shape), atol=1e-6)
        assert np.allclose(x[:, 2], cam.depth(X))
        # resampled: pixel centres map as cv2.resize maps them
        K, _ = photo_camera(cam, shape, (shape[0] // 2, shape[1] // 2))
        Kf, _ = photo_camera(cam, shape)
        assert np.allclose(K[:2, 2], (Kf[:2, 2] + 0.5) / 2 - 0.5)
        assert np.allclose(K[0, 0], Kf[0, 0] / 2)
        v = make_view("A", np.zeros((*shape, 3), np.uint8), cam, max_side=None)
        uv, z = v.project(X)
        assert np.allclose(v.backproject(uv, z), X)


def test_neighbours_rule():
    cams = {f"V{i}": _camera(f"V{i}", [0.5 * i, 0, 0]) for i in range(6)}
    cams["dup"] = _camera("dup", [0.01, 0, 0])                   # no parallax with V0
    cams["back"] = _camera("back", [0.5, 0, 0], 180.0)           # looks the other way
    cams["turn"] = _camera("turn", [1.0, 0, 0], 40.0)            # beyond 30°
    nb = neighbours(cams, k=3)
    assert nb["V2"][:2] == ["V1", "V3"] and len(nb["V2"]) == 3
    assert "dup" not in nb["V0"] and "back" not in nb["V1"] and "turn" not in nb["V2"]
    assert nb["back"] == []
    assert neighbours({"V0": cams["V0"]}) == {"V0": []}


def test_depth_range_brackets_the_scene():
    images, cams = _scene()
    ref, other = (make_view(n, images[n], cams[n], max_side=None) for n in ("B", "C"))
    near, far = depth_range(ref, other)
    assert 7.0 < near < WALL_Z and WINDOW_Z < far < 14.0


def test_plane_sweep_depth_and_recess():
    res = _result()
    images, cams = _scene()
    assert set(res.depths) == set(images) and not res.skipped
    depth, conf = res.depths["B"], res.confidences["B"]
    truth, hole = _truth(cams["B"], depth.shape)
    inner = cv2.erode(hole.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    wall = ~cv2.dilate(hole.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    ok = np.isfinite(depth) & (conf > 0.15)
    assert ok[wall].mean() > 0.8
    rel = np.abs(depth - truth) / truth
    assert np.median(rel[wall & ok]) < 0.01
    assert (inner & ok).sum() > 200
    recess = np.median(depth[inner & ok]) - np.median(depth[wall & ok])
    assert recess == pytest.approx(WINDOW_Z - WALL_Z, rel=0.2)


def test_fused_points_lie_on_the_planes():
    res = _result()
    cloud = res.cloud
    assert len(cloud) > 5000 and cloud.rgb is not None and cloud.up == 1
    assert np.allclose(res.up_vector, [0, -1, 0], atol=0.05)
    X = cloud.xyz
    z = X[:, 2]
    inside = (X[:, 0] > HOLE[0] + 0.1) & (X[:, 0] < HOLE[1] - 0.1) \
        & (X[:, 1] > HOLE[2] + 0.1) & (X[:, 1] < HOLE[3] - 0.1)
    err = np.minimum(np.abs(z - WINDOW_Z), np.abs(z - WALL_Z))
    assert np.quantile(err, 0.95) < 0.05 and np.median(err) < 0.01      # 0.5 %, 0.1 % of depth
    on_pane = inside & (np.abs(z - WINDOW_Z) < 0.05)
    assert on_pane.sum() > 300 and on_pane.sum() > 0.9 * inside.sum()
    assert res.counts["points"] == len(cloud)
    assert set(res.timings["views"]) == set(res.depths) and res.timings["total"] > 0


def test_fuse_function_and_determinism():
    res = _result()
    images, cams = _scene()
    cloud = fuse(res.depths, cams, images, confidences=res.confidences)
    assert len(cloud) == len(res.cloud)
    assert np.array_equal(cloud.xyz, res.cloud.xyz)
    loose = fuse(res.depths, cams, images, confidences=res.confidences, min_agree=0, voxel=0)
    assert len(loose) > len(cloud)


def test_views_without_overlap_give_an_empty_cloud():
    images, cams = _scene()
    back = _camera("E", [0.0, 0.0, 0.0], 180.0)
    res = dense_cloud({"B": images["B"], "E": images["A"]}, {"B": cams["B"], "E": back},
                      max_side=None)
    assert len(res.cloud) == 0 and set(res.skipped) == {"B", "E"}
    # same direction, far apart: the photos show different walls (no matches)
    rng = np.random.default_rng(3)
    other = _texture(rng, PHOTO)
    far = _camera("G", [40.0, 0.0, 0.0])
    res = dense_cloud({"B": images["B"], "G": other}, {"B": cams["B"], "G": far},
                      max_side=None)
    assert len(res.cloud) == 0


def test_plane_sweep_without_neighbours():
    images, cams = _scene()
    v = make_view("B", images["B"], cams["B"], max_side=None)
    d, c = plane_sweep(v, [], 5.0, 20.0)
    assert np.isnan(d).all() and not c.any()


def test_bad_inputs():
    images, cams = _scene()
    with pytest.raises(InputError, match="no camera"):
        dense_cloud({"B": images["B"], "Z": images["A"]}, cams)
    with pytest.raises(InputError, match="calibrated on 320 × 240"):
        dense_cloud({"B": images["B"][:200]}, cams)
    with pytest.raises(InputError, match="uint8"):
        dense_cloud({"B": images["B"].astype(np.float32)}, cams)
    with pytest.raises(InputError, match="no photos"):
        dense_cloud({}, cams)
    with pytest.raises(InputError, match="depth range"):
        dense_cloud(images, cams, depth_range=(5.0, 2.0))
    with pytest.raises(InputError, match="not among"):
        dense_cloud(images, cams, views=["Q"])
    with pytest.raises(InputError, match="scale"):
        dense_cloud(images, cams, scale=2.0)
