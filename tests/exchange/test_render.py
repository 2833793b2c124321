"""CPU preview renderer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.exchange import ExportError, export, render_file, render_preview
from facadeforge.model import Material, Model


def _sky_fraction(img: Image.Image) -> float:
    """Share of pixels that look like the sky gradient (light, blue-ish, low saturation)."""
    arr = np.asarray(img.convert("RGB"), float)
    top = arr[0, 0]
    return float(np.mean(np.all(np.abs(arr - top) < 25, axis=2)))


def test_render_returns_image_of_size(house: Model):
    img = render_preview(house, size=(320, 240))
    assert img.size == (320, 240) and img.mode == "RGB"
    arr = np.asarray(img)
    assert len(np.unique(arr.reshape(-1, 3), axis=0)) > 50
    center = arr[80:160, 110:210].reshape(-1, 3).astype(float)
    assert np.abs(center - arr[0, 0]).max() > 60  # the building, not the sky, is in the middle
    assert _sky_fraction(img) < 0.6


def test_material_colours_show(house_factory):
    red = house_factory()
    for part in red.parts:
        part.material = Material("red", (0.9, 0.05, 0.05))
    arr = np.asarray(render_preview(red, size=(200, 150), shadow=False), float)
    reddish = (arr[..., 0] > 1.8 * arr[..., 1]) & (arr[..., 0] > 1.8 * arr[..., 2])
    assert reddish.mean() > 0.2


def test_textures_use_their_mean_colour(house: Model, texture_png: str):
    from facadeforge.exchange._common import mean_texture_color

    assert mean_texture_color(texture_png) == pytest.approx([150 / 255, 75 / 255, 100 / 255])
    render_preview(house, size=(64, 48))


@pytest.mark.parametrize("perspective", [True, False])
@pytest.mark.parametrize("azimuth", [0.0, 40.0, 70.0])
def test_textures_are_sampled_per_pixel_at_their_uvs(tmp_path: Path, perspective: bool,
                                                     azimuth: float):
    """A quad textured red | blue (one texture, UVs 0–1) renders like the same quad built from a
    red and a blue half with plain materials: the colours meet where the quad's 3D middle
    projects, under perspective (UVs interpolated linearly in 3D, not in screen space) and
    orthographic views alike."""
    from facadeforge.geometry.mesh import Mesh
    from facadeforge.model import Part

    arr = np.zeros((16, 16, 3), np.uint8)
    arr[:, :8] = (220, 30, 30)
    arr[:, 8:] = (30, 30, 220)
    tex = tmp_path / "halves.png"
    Image.fromarray(arr).save(tex)
    corners = np.array([[0, 0, 0], [4, 0, 0], [4, 3, 0], [0, 3, 0]], float)
    textured = Model([Part(Mesh(corners, [[0, 1, 2, 3]],
                                uvs=[np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)]),
                           "wall", Material("photo", (1, 1, 1), texture=str(tex)))])
    halves = Model([Part(Mesh(corners * [0.5, 1, 1], [[0, 1, 2, 3]]), "wall",
                         Material("red", (220 / 255, 30 / 255, 30 / 255))),
                    Part(Mesh(corners * [0.5, 1, 1] + [2, 0, 0], [[0, 1, 2, 3]]), "wall",
                         Material("blue", (30 / 255, 30 / 255, 220 / 255)))])

    def boundary(model) -> float:
        img = np.asarray(render_preview(model, size=(240, 160), azimuth=azimuth,
                                        elevation=5.0, shadow=False, outlines=False,
                                        perspective=perspective, supersample=1), float)
        row = img[80]
        red = np.nonzero((row[:, 0] > 1.8 * row[:, 2]) & (row[:, 0] > 40))[0]
        blue = np.nonzero((row[:, 2] > 1.8 * row[:, 0]) & (row[:, 2] > 40))[0]
        assert len(red) > 5 and len(blue) > 5
        assert red.mean() < blue.mean()
        return (red.max() + blue.min()) / 2

    assert abs(boundary(textured) - boundary(halves)) <= 1.5


def test_uvs_beyond_one_repeat_the_texture(tmp_path: Path):
    from facadeforge.geometry.mesh import Mesh
    from facadeforge.model import Part

    arr = np.zeros((16, 16, 3), np.uint8)
    arr[:, :8] = (220, 30, 30)
    arr[:, 8:] = (30, 30, 220)
    tex = tmp_path / "halves.png"
    Image.fromarray(arr).save(tex)
    mesh = Mesh(np.array([[0, 0, 0], [4, 0, 0], [4, 3, 0], [0, 3, 0]], float), [[0, 1, 2, 3]],
                uvs=[np.array([[0, 0], [2, 0], [2, 1], [0, 1]], float)])
    quad = Model([Part(mesh, "wall", Material("photo", (1, 1, 1), texture=str(tex)))])
    img = np.asarray(render_preview(quad, size=(200, 150), azimuth=0.0, elevation=0.0,
                                    shadow=False, outlines=False), float)
    row = img[75]
    colour = np.where(row[:, 0] > 2 * row[:, 2], 1, np.where(row[:, 2] > 2 * row[:, 0], 2, 0))
    stripes = [c for i, c in enumerate(colour) if c and (i == 0 or c != colour[i - 1])]
    assert stripes == [1, 2, 1, 2]


def test_saves_png(tmp_path: Path, house: Model):
    img = render_preview([house], tmp_path / "p.png", size=(160, 120), azimuth=30,
                         elevation=10, perspective=False)
    with Image.open(tmp_path / "p.png") as saved:
        assert saved.size == (160, 120)
        assert np.array_equal(np.asarray(saved.convert("RGB")), np.asarray(img))


@pytest.mark.parametrize("suffix", [".glb", ".obj", ".city.json"])
def test_render_file(tmp_path: Path, house: Model, suffix: str):
    export(house, tmp_path / f"h{suffix}")
    img = render_file(tmp_path / f"h{suffix}", tmp_path / "preview.png", size=(120, 90))
    assert (tmp_path / "preview.png").is_file() and img.size == (120, 90)
    assert _sky_fraction(img) < 0.7


def test_empty_and_invalid():
    img = render_preview(Model(), size=(40, 30))
    assert img.size == (40, 30)
    with pytest.raises(ExportError):
        render_preview(Model(), size=(0, 10))
    # a picture whose buffers would not fit in memory (8000 x 8000 took 3.8 GB)
    with pytest.raises(ExportError, match="too large"):
        render_preview(Model(), size=(8000, 8000))
    with pytest.raises(ExportError, match="too large"):
        render_preview(Model(), size=(60000, 10))


def test_many_faces_render(box):

    from facadeforge.geometry.mesh import Mesh
    from facadeforge.model import Part

    rng = np.random.default_rng(1)
    polys = []
    for x, z, h in zip(rng.uniform(0, 100, 2000), rng.uniform(0, 100, 2000),
                       rng.uniform(2, 20, 2000)):
        polys.extend(box((x, 0, z), (x + 1, h, z + 1)).values())
    model = Model(parts=[Part(Mesh.from_polygons(polys), "wall")])
    img = render_preview(model, size=(400, 300))   # 24 000 triangles
    assert img.size == (400, 300)


def test_zbuffer_keeps_the_nearest_whatever_the_order():
    from facadeforge.exchange._zbuffer import rasterize

    square = np.array([[[0, 0], [10, 0], [10, 10]], [[0, 0], [10, 10], [0, 10]]], float)
    far, near = np.full((2, 3), 1.0), np.full((2, 3), 2.0)
    small = square * 0.5 + 2
    for order in ((0, 1), (1, 0)):
        tris = [square, small][order[0]], [square, small][order[1]]
        depth = [far, near][order[0]], [far, near][order[1]]
        zbuf, ids = rasterize(np.concatenate(tris), np.concatenate(depth), (10, 10))
        grid = ids.reshape(10, 10)
        small_ids = {2, 3} if order == (0, 1) else {0, 1}
        assert {int(i) for i in np.unique(grid[2:7, 2:7])} <= small_ids
        assert (grid >= 0).all() and zbuf.max() == 2.0
    _, cover = rasterize(square[:1], None, (10, 10))
    assert (cover >= 0).sum() == 55  # pixel centres on or under the diagonal of a 10 × 10 square


def test_small_faces_in_front_of_big_ones_are_seen():
    from facadeforge.geometry.mesh import Mesh
    from facadeforge.model import Part

    wall = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], float)
    sign = np.array([[7, 4, 0.05], [9, 4, 0.05], [9, 6, 0.05], [7, 6, 0.05]], float)
    glass = np.array([[1, 4, 0.05], [3, 4, 0.05], [3, 6, 0.05], [1, 6, 0.05]], float)
    model = Model(parts=[
        Part(Mesh.from_polygons([wall]), "wall", Material("w", (0.1, 0.2, 0.9))),
        Part(Mesh.from_polygons([sign]), "shop", Material("s", (0.95, 0.05, 0.05))),
        Part(Mesh.from_polygons([glass]), "window", Material("g", (0.9, 0.9, 0.1), opacity=0.5)),
    ])
    arr = np.asarray(render_preview(model, size=(200, 150), azimuth=0, elevation=0,
                                    shadow=False), float)
    red = (arr[..., 0] > 150) & (arr[..., 1] < 60) & (arr[..., 2] < 60)
    assert red.sum() > 100
    mixed = ((arr > 60) & (arr < 180)).all(axis=2)
    assert mixed[:, :100].sum() > 100  # translucent yellow over blue, on the left


def test_rendering_a_textured_glb_leaves_no_temporary_folder(house: Model, tmp_path: Path,
                                                             monkeypatch):
    """The reproducer: every render of a .glb with embedded images left a folder in /tmp."""
    import tempfile

    glb = tmp_path / "house.glb"
    export(house, glb)                       # the wall texture is embedded in the file
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    img = render_file(glb, tmp_path / "a.png", size=(160, 120))
    assert list(tmp.iterdir()) == []
    from facadeforge.exchange import load

    textures = [p.material.texture for m in load(glb, texture_dir=tmp_path / "t") for p in m.parts
                if p.material.texture]
    assert textures                          # the file does carry a texture to extract
    # and the picture still shows it: same pixels as rendering the model itself
    assert np.array_equal(np.asarray(img), np.asarray(render_preview(
        load(glb, texture_dir=tmp_path / "t"), size=(160, 120))))
