"""Label rasters (arrays, palette PNG) and label drawings (SVG) of facade layouts."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.exchange import (
    EXPORTERS,
    LABEL_COLORS,
    LABEL_INDEX,
    ExportError,
    export,
    label_map,
    write_label_png,
    write_label_svg,
)
from facadeforge.geometry.mesh import Mesh
from facadeforge.model import Labels, Model, Part, Scope, Shape

# A 4 m × 3 m facade on the side of a building (its x axis runs along world -z), origin offset.
FRAME = Scope.from_axes((10.0, 0.0, 5.0), (0, 0, -1), (0, 1, 0), size=(4, 3, 0))

# label_map of the layout at 2 px/m: wall everywhere, a window, a door and a shop sign.
EXPECTED = np.array([
    [5, 5, 1, 1, 1, 1, 1, 1],
    [1, 1, 1, 1, 1, 1, 1, 1],
    [1, 1, 2, 2, 1, 3, 3, 1],
    [1, 1, 2, 2, 1, 3, 3, 1],
    [1, 1, 1, 1, 1, 3, 3, 1],
    [1, 1, 1, 1, 1, 3, 3, 1],
], np.uint8)


def _quad(x0, y0, x1, y1) -> Mesh:
    local = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], float)
    return Mesh.from_polygons([FRAME.to_world(local)])


def _scope(x0, y0, w, h) -> Scope:
    return Scope(FRAME.to_world(np.array([[x0, y0, 0.0]]))[0], FRAME.rotation, (w, h, 0))


def facade() -> Shape:
    root = Shape("Facade", FRAME.copy())
    root.add(Shape("Wall", _scope(0, 0, 4, 3), _quad(0, 0, 4, 3), label="wall"))
    floor = root.add(Shape("Floor", _scope(0, 0, 4, 3), _quad(0, 0, 4, 3), label="balcony"))
    floor.add(Shape("Window", _scope(1, 1, 1, 1), label="window"))  # scope only, no geometry
    root.add(Shape("Door", _scope(2.5, 0, 1, 2), _quad(2.5, 0, 3.5, 2), label="door"))
    root.add(Shape("ShopSign", _scope(0, 2.5, 1, 0.5), _quad(0, 2.5, 1, 3)))  # label from name
    return root


def test_palette_covers_every_label():
    assert list(LABEL_INDEX) == [label.value for label in Labels]
    assert set(LABEL_COLORS) == set(LABEL_INDEX)
    assert len(set(LABEL_COLORS.values())) == len(LABEL_COLORS)


def test_label_map_of_shape_tree():
    out = label_map(facade(), px_per_m=2)
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, EXPECTED)


def test_label_map_of_model_uses_root_frame():
    root = facade()
    parts = [Part(s.geometry, s.label, symbol=s.symbol) for s in root.leaves()
             if s.geometry is not None]
    out = label_map(Model(parts=parts, root=root), px_per_m=2)
    expected = EXPECTED.copy()
    expected[expected == 2] = 1  # the window has no geometry, hence no part
    np.testing.assert_array_equal(out, expected)


def test_later_shapes_paint_over_earlier():
    root = Shape("Facade", FRAME.copy())
    root.add(Shape("A", geometry=_quad(0, 0, 2, 3), label="window"))
    root.add(Shape("B", geometry=_quad(1, 0, 4, 3), label="balcony"))
    out = label_map(root, px_per_m=1)
    np.testing.assert_array_equal(out, [[2, 4, 4, 4]] * 3)


def test_model_parts_in_front_of_the_facade_paint_last():
    """A balcony the rules insert before the wall behind it (CGA branches come first) still
    shows in a model's label map: parts standing in front of the facade plane paint last."""
    root = Shape("Facade", FRAME.copy())
    local = np.array([[1, 0, 0.9], [3, 0, 0.9], [3, 1, 0.9], [1, 1, 0.9]], float)   # 0.9 m out
    balcony = Part(Mesh.from_polygons([FRAME.to_world(local)]), "balcony", symbol="Balcony")
    wall = Part(_quad(0, 0, 4, 3), "wall", symbol="Wall")
    out = label_map(Model(parts=[balcony, wall], root=root), px_per_m=1)
    np.testing.assert_array_equal(out, [[1, 1, 1, 1], [1, 1, 1, 1], [1, 4, 4, 1]])


def test_a_leaf_with_a_balcony_inserted_in_front_keeps_its_label():
    """A window whose only child is a balcony inserted in front of it (outside any split) is
    still painted as a window, with the balcony over its lower part."""
    from facadeforge.model.shape import INSERT

    root = Shape("Facade", FRAME.copy())
    root.add(Shape("Wall", _scope(0, 0, 4, 3), label="wall"))
    window = root.add(Shape("Window", _scope(1, 0, 2, 3), label="window"))
    window.add(Shape("Balcony", _scope(1, 0, 2, 1), label="balcony", operator=INSERT))
    out = label_map(root, px_per_m=1)
    np.testing.assert_array_equal(out, [[1, 2, 2, 1], [1, 2, 2, 1], [1, 4, 4, 1]])


def test_size_and_resolution():
    assert label_map(facade(), px_per_m=10).shape == (30, 40)
    small = label_map(facade(), size=(3, 4))
    assert small.shape == (3, 4)
    assert small[1, 1] == LABEL_INDEX["window"] and small[0, 3] == LABEL_INDEX["wall"]
    with pytest.raises(ExportError):
        label_map(facade(), px_per_m=0)


def test_write_label_png(tmp_path: Path):
    labels = label_map(facade(), px_per_m=2)
    assert write_label_png(labels, tmp_path / "l.png") == tmp_path / "l.png"
    with Image.open(tmp_path / "l.png") as img:
        assert img.mode == "P"
        np.testing.assert_array_equal(np.array(img), labels)
        palette = np.array(img.getpalette()[:3 * len(LABEL_COLORS)]).reshape(-1, 3)
    assert [tuple(c) for c in palette] == [LABEL_COLORS[k] for k in LABEL_INDEX]
    with pytest.raises(ExportError):
        write_label_png(np.full((2, 2), 99), tmp_path / "bad.png")
    assert not (tmp_path / "bad.png").exists()


def test_write_label_svg(tmp_path: Path):
    write_label_svg(facade(), tmp_path / "l.svg", px_per_m=10)
    root = ET.parse(tmp_path / "l.svg").getroot()
    assert root.get("width") == "40" and root.get("height") == "30"
    polys = [el for el in root if el.tag.endswith("polygon")]
    assert [p.get("data-label") for p in polys] == ["wall", "window", "door", "shop"]
    window = polys[1]
    assert window.get("fill") == "#{:02x}{:02x}{:02x}".format(*LABEL_COLORS["window"])
    xy = np.array([pt.split(",") for pt in window.get("points").split()], float)
    assert xy.min(axis=0) == pytest.approx([10, 10]) and xy.max(axis=0) == pytest.approx([20, 20])


def test_registered_exporters_take_models(tmp_path: Path):
    assert {"png", "svg"} <= set(EXPORTERS)
    flat = [Part(Mesh.from_polygons([np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0.0]])]),
                 "wall"),
            Part(Mesh.from_polygons([np.array([[0.5, 0, 0], [1, 0, 0], [1, 1, 0], [0.5, 1, 0.0]])]),
                 "door")]
    model = Model(parts=flat)  # no root: projected onto the world x/y plane
    assert export(model, tmp_path / "m.png", px_per_m=4) == [tmp_path / "m.png"]
    with Image.open(tmp_path / "m.png") as img:
        arr = np.array(img)
    assert arr.shape == (4, 8)
    np.testing.assert_array_equal(arr[0], [1, 1, 3, 3, 1, 1, 1, 1])
    export(model, tmp_path / "m.svg")
    assert 'data-label="door"' in (tmp_path / "m.svg").read_text()
