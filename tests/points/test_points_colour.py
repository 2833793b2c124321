"""Colouring points from photos: visibility by z-buffer, choice of view, on a synthetic scene.

The scene: a textured facade plane y = 0 (x ∈ [0, 10], z ∈ [0, 6] m) and a box in front of it
(x ∈ [4, 6], y ∈ [2, 3], z ∈ [2, 4]); camera A at (2, 8, 3), camera B at (8, 12, 3), both looking
along −y.  Each photo is ray-cast exactly: plane pixels red in A and green in B, a 1 m checker in
the blue channel (100 on odd cells), box pixels pure blue.  Points of the plane hidden behind the
box in A must take B's green; points both see take the closer A's red.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets.cameras import Camera, read_visualsfm
from facadeforge.points.cloud import PointCloud, PointCloudError
from facadeforge.points.colour import colour_from_photos, point_spacing, visible_in

W, H, F = 320, 240, 250.0
BOX = (np.array([4.0, 2.0, 2.0]), np.array([6.0, 3.0, 4.0]))
CENTRES = {"A": np.array([2.0, 8.0, 3.0]), "B": np.array([8.0, 12.0, 3.0])}
PLANE_RGB = {"A": (255, 0), "B": (0, 255)}            # (red, green) of the plane in each photo


def _camera(name: str, size=(W, H)) -> Camera:
    forward, down = np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, -1.0])
    R = np.array([np.cross(down, forward), down, forward])        # rows: right, down, forward
    return Camera(name, f"{name}.png", F, (size[0] / 2, size[1] / 2), R, CENTRES[name])


def _hit_box(origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Ray parameter of the first box hit (inf where none), slab method."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (BOX[0] - origin) / dirs
        t2 = (BOX[1] - origin) / dirs
    tmin = np.nanmax(np.minimum(t1, t2), axis=1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((tmax >= tmin) & (tmax > 0), np.maximum(tmin, 0), np.inf)


def _checker(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    return ((np.floor(x) + np.floor(z)) % 2).astype(bool)


def _render(name: str) -> np.ndarray:
    cam = _camera(name)
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    rays = np.c_[(u.ravel() - W / 2) / F, (v.ravel() - H / 2) / F, np.ones(u.size)] @ cam.R
    img = np.zeros((H * W, 3), np.uint8)
    t_plane = -cam.C[1] / rays[:, 1]                       # y = 0
    hit = cam.C + t_plane[:, None] * rays
    on_plane = (t_plane > 0) & (hit[:, 0] >= 0) & (hit[:, 0] <= 10) & (hit[:, 2] >= 0) & \
        (hit[:, 2] <= 6)
    r, g = PLANE_RGB[name]
    img[on_plane] = np.c_[np.full(on_plane.sum(), r), np.full(on_plane.sum(), g),
                          np.where(_checker(hit[on_plane, 0], hit[on_plane, 2]), 100, 0)]
    t_box = _hit_box(cam.C, rays)
    img[np.isfinite(t_box) & (t_box < np.where(on_plane, t_plane, np.inf))] = (0, 0, 255)
    return img.reshape(H, W, 3)


def _scene(spacing: float = 0.05) -> tuple[PointCloud, int]:
    x, z = np.meshgrid(np.arange(0, 10 + 1e-9, spacing), np.arange(0, 6 + 1e-9, spacing))
    plane = np.c_[x.ravel(), np.zeros(x.size), z.ravel()]
    lo, hi = BOX
    a, b = np.meshgrid(np.arange(lo[0], hi[0] + 1e-9, spacing),
                       np.arange(lo[2], hi[2] + 1e-9, spacing))
    front = np.c_[a.ravel(), np.full(a.size, hi[1]), b.ravel()]      # the face towards cameras
    back = np.c_[a.ravel(), np.full(a.size, lo[1]), b.ravel()]
    c, d = np.meshgrid(np.arange(lo[1], hi[1] + 1e-9, spacing),
                       np.arange(lo[2], hi[2] + 1e-9, spacing))
    sides = [np.c_[np.full(c.size, xx), c.ravel(), d.ravel()] for xx in (lo[0], hi[0])]
    return PointCloud(np.concatenate([plane, front, back, *sides])), len(plane)


def _occluded(points: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Whether the segment point → camera passes through the box (exact)."""
    dirs = centre - points
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (BOX[0] - points) / dirs
        t2 = (BOX[1] - points) / dirs
    tmin = np.nanmax(np.minimum(t1, t2), axis=1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=1)
    return (tmax >= tmin) & (tmax > 1e-6) & (tmin < 1)


def _in_view(points: np.ndarray, name: str) -> np.ndarray:
    """Inside the photo and off the plane's border (whose pixels round onto the background)."""
    px = _camera(name).project(points, photo_shape=(H, W))
    x, z = points[:, 0], points[:, 2]
    return ((px[:, 0] > 2) & (px[:, 0] < W - 3) & (px[:, 1] > 2) & (px[:, 1] < H - 3)
            & (x > 0.06) & (x < 9.94) & (z > 0.06) & (z < 5.94))


@pytest.fixture(scope="module")
def scene():
    cloud, n_plane = _scene()
    photos = {"A": _render("A"), "B": _render("B")}
    cameras = {k: _camera(k) for k in photos}
    return cloud, n_plane, photos, cameras


def _near_box_shadow_edge(points: np.ndarray, centre: np.ndarray, margin: float = 0.1):
    """Points whose occlusion changes within ``margin`` m in the plane (silhouette edges)."""
    base = _occluded(points, centre)
    edge = np.zeros(len(points), bool)
    for dx in (-margin, 0.0, margin):
        for dz in (-margin, 0.0, margin):
            edge |= _occluded(points + [dx, 0.0, dz], centre) != base
    return edge


def test_hidden_points_take_the_other_view(scene):
    cloud, n_plane, photos, cameras = scene
    out = colour_from_photos(cloud, photos, cameras)
    plane, rgb, coloured = cloud.xyz[:n_plane], out.rgb[:n_plane], out.extra["coloured"][:n_plane]
    hid_a, hid_b = _occluded(plane, CENTRES["A"]), _occluded(plane, CENTRES["B"])
    in_a, in_b = _in_view(plane, "A"), _in_view(plane, "B")
    edge = (_near_box_shadow_edge(plane, CENTRES["A"]) | _near_box_shadow_edge(plane, CENTRES["B"]))
    red = (rgb[:, 0] == 255) & (rgb[:, 1] == 0)
    green = (rgb[:, 0] == 0) & (rgb[:, 1] == 255)
    only_b = hid_a & in_a & ~hid_b & in_b & ~edge          # behind the box in A, seen by B
    assert only_b.sum() > 1000
    assert green[only_b].all() and coloured[only_b].all()
    both = ~hid_a & ~hid_b & in_a & in_b & ~edge           # both see it: the closer A wins
    assert both.sum() > 5000 and red[both].all()
    neither = hid_a & hid_b & ~edge
    assert neither.sum() > 200 and not coloured[neither].any()
    assert (rgb[neither] == 0).all()                        # no colour before: black
    # the checker lands where it belongs: projection and pixel convention agree
    x, z = plane[:, 0], plane[:, 2]
    off_cell_edges = (np.abs(x - np.rint(x)) > 0.06) & (np.abs(z - np.rint(z)) > 0.06)
    sel = coloured & off_cell_edges & ~edge
    np.testing.assert_array_equal(rgb[sel, 2], np.where(_checker(x[sel], z[sel]), 100, 0))
    # the box's front face is blue
    front = np.flatnonzero(np.isclose(cloud.xyz[:, 1], BOX[1][1]))
    assert (out.rgb[front] == (0, 0, 255)).all(axis=1).mean() > 0.98
    # the back face (towards the plane) is seen by neither camera
    back = np.flatnonzero(np.isclose(cloud.xyz[:, 1], BOX[0][1]))
    assert not out.extra["coloured"][back].any()


def test_normals_choose_the_most_frontal_view(scene):
    cloud, n_plane, photos, cameras = scene
    normals = np.zeros((len(cloud), 3))
    normals[:, 1] = 1.0                       # every point faces +y (the box's sides do not,
    cloud = PointCloud(cloud.xyz, normals=normals)          # but only the plane is checked)
    out = colour_from_photos(cloud, photos, cameras)
    plane, rgb = cloud.xyz[:n_plane], out.rgb[:n_plane]
    both = (~_occluded(plane, CENTRES["A"]) & ~_occluded(plane, CENTRES["B"]) & _in_view(plane, "A")
            & _in_view(plane, "B") & ~_near_box_shadow_edge(plane, CENTRES["A"])
            & ~_near_box_shadow_edge(plane, CENTRES["B"]))
    ray = {k: c - plane for k, c in CENTRES.items()}
    cos = {k: np.abs(r[:, 1]) / np.linalg.norm(r, axis=1) for k, r in ray.items()}
    a_wins = both & (cos["A"] > cos["B"] + 1e-3)
    b_wins = both & (cos["B"] > cos["A"] + 1e-3)
    assert a_wins.sum() > 1000 and b_wins.sum() > 1000
    assert (rgb[a_wins, 0] == 255).all() and (rgb[b_wins, 1] == 255).all()


def test_unseen_points_keep_their_colour_and_photo_paths(tmp_path: Path, scene):
    cloud, n_plane, photos, cameras = scene
    start = np.full((len(cloud), 3), 7, np.uint8)
    Image.fromarray(photos["B"]).save(tmp_path / "B.png")
    out = colour_from_photos(PointCloud(cloud.xyz, rgb=start), {"B": tmp_path / "B.png"},
                             cameras)
    seen = out.extra["coloured"]
    assert 0 < seen.sum() < len(cloud)
    assert (out.rgb[~seen] == 7).all()
    assert (out.rgb[seen] != 7).any(axis=1).all()
    np.testing.assert_array_equal(cloud.xyz, out.xyz)


def test_visible_in_points_behind_the_camera_and_outside(scene):
    cloud, _, _, cameras = scene
    behind = np.array([[2.0, 9.0, 3.0], [2.0, 100.0, 3.0]])     # behind camera A
    outside = np.array([[500.0, 0.0, 3.0]])
    xyz = np.concatenate([behind, outside, [[2.0, 0.0, 3.0]]])
    idx, px, depth = visible_in(xyz, cameras["A"], (H, W), point_size=0.1)
    assert idx.tolist() == [3]
    np.testing.assert_array_equal(px, [[W // 2, H // 2]])
    assert depth[0] == pytest.approx(8.0)


def test_point_spacing():
    cloud, _ = _scene(spacing=0.1)
    assert point_spacing(cloud) == pytest.approx(0.1, rel=1e-6)
    assert point_spacing(PointCloud(np.zeros((1, 3)))) == 0.0


def test_errors(scene):
    cloud, _, photos, cameras = scene
    with pytest.raises(PointCloudError, match="no photos"):
        colour_from_photos(cloud, {}, cameras)
    with pytest.raises(PointCloudError, match=r"photos \['C'\] have no camera"):
        colour_from_photos(cloud, {"C": photos["A"]}, cameras)
    with pytest.raises(PointCloudError, match="photo 'A'"):
        colour_from_photos(cloud, {"A": "/nonexistent/a.png"}, cameras)
    with pytest.raises(PointCloudError, match="point_size"):
        colour_from_photos(cloud, photos, cameras, point_size=-1.0)


RUEMONGE = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "ruemonge" / "train"


@pytest.mark.skipif(not (RUEMONGE / "cameras.txt").is_file(),
                    reason=f"RueMonge cameras {RUEMONGE / 'cameras.txt'} absent "
                           "(expected ../shared/data)")
def test_ruemonge_portrait_photos_sample_where_the_camera_projects():
    """A real camera and a portrait-shaped photo: points placed on chosen photo pixels along the
    viewing rays come back with exactly those pixels' colours (the quarter turn is honoured)."""
    cams = read_visualsfm(RUEMONGE / "cameras.txt")
    cam = next(iter(cams.values()))
    w, h = cam.size                                     # calibrated landscape size
    photo_shape = (w, h)                                # stored portrait: H = calibrated W
    rng = np.random.default_rng(0)
    photo = rng.integers(0, 256, (*photo_shape, 3), dtype=np.uint8)
    xy = np.c_[rng.integers(20, photo_shape[1] - 20, 50), rng.integers(20, photo_shape[0] - 20, 50)]
    uv = cam.from_photo(xy, photo_shape)
    rays = np.c_[(uv - np.array(cam.principal)) / cam.focal, np.ones(len(uv))] @ cam.R
    xyz = cam.C + 10.0 * rays                           # R·ray has depth 1: 10 m deep
    out = colour_from_photos(PointCloud(xyz), {cam.id: photo}, {cam.id: cam}, point_size=0.0)
    assert out.extra["coloured"].all()
    np.testing.assert_array_equal(out.rgb, photo[xy[:, 1], xy[:, 0]])
