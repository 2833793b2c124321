"""Small generated models shared by the exchange tests (as fixtures: test modules never import
this file, whose module name ``conftest`` is not unique in the test tree)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.geometry.mesh import Mesh
from facadeforge.model import Material, Model, Part

WIDTH, HEIGHT, DEPTH = 6.0, 6.0, 4.0
UNIT_SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)


def box_faces(lo, hi) -> dict[str, np.ndarray]:
    """The six quads of an axis-aligned box, counter-clockwise seen from outside."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    quads = {
        "front": [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
        "back": [(x1, y0, z0), (x0, y0, z0), (x0, y1, z0), (x1, y1, z0)],
        "left": [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
        "right": [(x1, y0, z1), (x1, y0, z0), (x1, y1, z0), (x1, y1, z1)],
        "top": [(x0, y1, z1), (x1, y1, z1), (x1, y1, z0), (x0, y1, z0)],
        "bottom": [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
    }
    return {k: np.array(v, float) for k, v in quads.items()}


def make_house(texture: str | None = None, name: str = "house") -> Model:
    """A 6 × 6 × 4 m box: textured walls, roof, ground, two windows, a door and a pentagon."""
    box = box_faces((0, 0, 0), (WIDTH, HEIGHT, DEPTH))
    walls = [box[k] for k in ("front", "back", "left", "right")]
    z = DEPTH + 0.01

    def window(x0: float, y0: float) -> np.ndarray:
        return np.array([(x0, y0, z), (x0 + 1, y0, z), (x0 + 1, y0 + 1.5, z), (x0, y0 + 1.5, z)])

    gable = np.array([(1, 4.5, z), (5, 4.5, z), (5, 5.2, z), (3, 5.8, z), (1, 5.2, z)])
    parts = [
        Part(Mesh.from_polygons(walls, [UNIT_SQUARE] * 4), "wall",
             Material("plaster", (0.8, 0.7, 0.5), texture=texture), "Wall", 1),
        Part(Mesh.from_polygons([box["top"]]), "roof", Material("tiles", (0.6, 0.2, 0.1)),
             "Roof", 2),
        Part(Mesh.from_polygons([box["bottom"]]), "ground", Material("slab", (0.3, 0.3, 0.3)),
             "Ground", 3),
        Part(Mesh.from_polygons([window(1, 2), window(4, 2)]), "window",
             Material("glass", (0.2, 0.4, 0.6), opacity=0.5), "Window", 4),
        Part(Mesh.from_polygons([np.array([(2.5, 0, z), (3.5, 0, z), (3.5, 2, z), (2.5, 2, z)])]),
             "door", Material("wood", (0.4, 0.25, 0.1)), "Door", 5),
        Part(Mesh.from_polygons([gable]), "deco", Material("stucco", (0.9, 0.9, 0.85)),
             "Ornament", 6),
    ]
    return Model(parts=parts, name=name, attributes={"height": HEIGHT, "floors": 2,
                                                    "style": "test"})


@pytest.fixture
def texture_png(tmp_path: Path) -> str:
    """An 8 × 8 RGB PNG with a known mean colour."""
    arr = np.zeros((8, 8, 3), np.uint8)
    arr[:, :4] = (200, 100, 50)
    arr[:, 4:] = (100, 50, 150)
    path = tmp_path / "src" / "brick.png"
    path.parent.mkdir()
    Image.fromarray(arr).save(path)
    return str(path)


@pytest.fixture
def house(texture_png: str) -> Model:
    return make_house(texture_png)


@pytest.fixture
def house_factory():
    """``make_house(texture=None, name="house")``: build more houses in a test."""
    return make_house


@pytest.fixture
def box():
    """``box_faces(lo, hi)``: the six outward quads of an axis-aligned box."""
    return box_faces


def _by_label(models: list[Model]) -> dict:
    out: dict[str, dict] = {}
    for m in models:
        for p in m.parts:
            d = out.setdefault(p.label, {"area": 0.0, "faces": 0, "material": p.material,
                                         "symbols": set()})
            d["area"] += p.mesh.area()
            d["faces"] += p.mesh.n_faces
            d["symbols"].add(p.symbol)
    return out


@pytest.fixture
def by_label():
    """``f(models) -> {label: {"area", "faces", "material", "symbols"}}`` for round-trip checks."""
    return _by_label


SCHEMAS = Path(__file__).resolve().parents[1] / "data" / "cityjson-2.0"


@pytest.fixture(scope="session")
def validator():
    """The CityJSON 2.0 schema (tests/data/cityjson-2.0) as a jsonschema validator."""
    import json

    import jsonschema
    from referencing import Registry, Resource

    resources = []
    for file in sorted(SCHEMAS.glob("*.schema.json")):
        schema = json.loads(file.read_text())
        resources.append((schema["$id"], Resource.from_contents(schema)))
    registry = Registry().with_resources(resources)
    root = json.loads((SCHEMAS / "cityjson.schema.json").read_text())
    return jsonschema.Draft7Validator(root, registry=registry)
