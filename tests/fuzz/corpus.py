"""Seed inputs, built in code: small valid rules using many CGA operations, GeoJSON and OBJ
footprints, a tiny classifier, a rule package project and a facade photo."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

CGA_SEEDS: dict[str, str] = {
    "split_comp": """version "2019.0"
attr height = 9
attr floorH = 3
@StartRule
Lot --> extrude(height) comp(f) { front : Facade | side : Facade | top : Roof | bottom : NIL }
Facade --> split(y) { ~floorH : Floor }*
Floor --> split(x) { ~1 : Wall | { ~2.5 : Tile }* | ~1 : Wall }
Tile --> split(x) { ~1 : Wall | 1.2 : split(y) { ~1 : Wall | 1.5 : Window | 0.5 : Wall } | ~1 : Wall }
Window --> t(0, 0, -0.2) color("#6f8fa8") report("windows", 1)
Wall --> color("#d8c8a8") report("area", geometry.area())
Roof --> roofHip(30, 0.3) comp(f) { bottom : NIL | all : color("#8a4b3a") }
""",
    "roofs": """attr roof = "gable"
Lot --> extrude(6) comp(f) { top : Roof | side : Wall | bottom : NIL }
Roof -->
    case roof == "gable" : roofGable(35, 0.4) comp(f) { bottom : NIL | vertical : Wall | all : Tiles }
    case roof == "pyramid" : roofPyramid(30) Tiles
    case roof == "shed" : roofShed(15) Tiles
    else : roofHip(30) Tiles
Wall --> color("#e3d7c1")
Tiles --> color("#a0523d")
""",
    "insert_transform": """const d = 0.3
Lot --> extrude(4) comp(f) { side : Side | all : X. }
Side --> [ t(0, scope.sy - 0.5, 0) s('1, 0.5, d) i("builtin:cube") color(1, 0, 0) Cornice. ]
         offset(-0.4) comp(f) { inside : t(0, 0, -d) Glass | border : extrude(0.05) Frame }
Glass --> color("#5c7a93") set(material.opacity, 0.8)
Frame --> r(0, 0, 0) center(xy) s('1, '1, '1) color("#f2efe8")
""",
    "stochastic_functions": """attr n = 3
attr colours = ["#ff0000", "#00ff00", "#0000ff"]
f(x) = x * 2 + 1
g(x) = case x > 2 : "big" else : "small"
Lot --> extrude(f(n)) comp(f) { side : Facade | top : Top | all : NIL }
Facade --> 30% : color(colours[0]) print(g(n))
           30% : color(colours[1]) report("r", rand(0, 1))
           else : split(x) { '0.5 : color(colours[2]) | ~1 : A }
A --> case scope.sx > 2 : split(y) { ~1.5 : B }* else : B
B --> color(0.5, 0.5, 0.5) report("len", len(colours)) report("s", str(floor(3.7)))
Top --> setback(1) { front : color("#111111") | remainder : extrude(1) X. }
""",
    "uv_texture": """Lot --> extrude(5) comp(f) { side : Facade | all : X. }
Facade --> setupProjection(0, scope.xy, 2, 2) projectUV(0) tileUV(0, 1, 1)
           scaleUV(0, 2, 2) translateUV(0, 0.5, 0) rotateUV(0, 10)
           split(y) { 2 : Ground | ~1 : Upper }
Ground --> color("#cccccc") tag("ground")
Upper --> extrude(0.1) comp(f) { front : U | all : NIL }
U --> deleteUV(0) normalizeUV(0, uv, collectiveAllFaces) color("#eeeeee")
""",
    "boolean_inline": """Lot --> inline(recompose) split(x) { '0.5 : W | ~1 : W }
        cleanupGeometry(all, 0) Mass
W --> X.
Mass --> subtract { extrude(6) | t('0.2, -1, '0.2) s('0.3, 8, '0.3) primitiveCube }
         comp(f) { top = Roof | bottom : NIL | side : Facade }
Roof --> color("#8c8f94")
Facade --> case touches(inter) : color("#b9ab95") else : split(x) { ~2 : color("#c9bda8") }*
""",
    "arrays_scoping": """attr widths = [1, 2, 3]
Lot --> alignScopeToAxes(y) extrude(world.up, 3) rotateScope(0, 90, 0)
        comp(f) { side : S | top : T | all : NIL }
S --> split(x) { widths[0] : A | ~widths[1] : B | widths[2] : A }
A --> mirrorScope(true, false, false) taper(0.5) color("#aa0000")
B --> envelope(normal, 3, 1, 45) color("#00aa00")
T --> innerRectangle(scope) { shape : extrude(1) X. | remainder : Y. }
""",
    "modify_tags": """Lot --> extrude(3) tag("mass") modify(f) { top : t(0, 0, 1) }
        comp(e) { all : E } comp(v) { all : V } Mass
Mass --> comp(f) { isTagged("mass") : color(0, 1, 0) | all : deleteTags() color(1, 0, 1) }
E --> label("edge") NIL
V --> NIL
""",
    "empty": "",
    "minimal": "Lot --> X.\n",
}

#: A lot CityEngine style: a rectangle seen from above (x east, z south).
_SQUARE = [[0, 0], [12, 0], [12, 9], [0, 9], [0, 0]]
_HOLED = [[[0, 0], [30, 0], [30, 20], [0, 20], [0, 0]],
          [[8, 6], [8, 14], [22, 14], [22, 6], [8, 6]]]

GEOJSON_SEEDS: dict[str, object] = {
    "polygon": {"type": "Polygon", "coordinates": [_SQUARE]},
    "collection": {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "a", "height": 7},
         "geometry": {"type": "Polygon", "coordinates": [_SQUARE]}},
        {"type": "Feature", "properties": {"name": "courtyard"},
         "geometry": {"type": "Polygon", "coordinates": _HOLED}}]},
    "multipolygon": {"type": "Feature", "properties": None, "geometry": {
        "type": "MultiPolygon", "coordinates": [[_SQUARE], [[[20, 0], [25, 0], [25, 5], [20, 0]]]]}},
    "lonlat": {"type": "FeatureCollection",
               "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}},
               "features": [{"type": "Feature", "properties": {},
                             "geometry": {"type": "Polygon", "coordinates": [[
                                 [2.35, 48.85], [2.3502, 48.85], [2.3502, 48.8501],
                                 [2.35, 48.8501], [2.35, 48.85]]]}}]},
}

OBJ_FOOTPRINT = """# two lots
o lots
v 0 0 0
v 10 0 0
v 10 0 -8
v 0 0 -8
v 12 0 0
v 20 0 0
v 16 0 -6
f 1 2 3 4
f 5 6 7
"""

CUBE_OBJ = """v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nv 0 0 1\nv 2 0 1\nv 2 1 1\nv 0 1 1
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1
f 1/1 4/4 3/3 2/2\nf 5/1 6/2 7/3 8/4\nf 1 2 6 5\nf 4 8 7 3\nf 2 3 7 6\nf 1 5 8 4
"""

RPK_MAIN = """version "2019.0"
import F : "facade.cga"
attr height = 9
@StartRule
Lot --> extrude(height) comp(f) { front : F.Facade | side : Side | all : NIL }
Side --> i("/Proj/assets/box.obj") s('1, '1, 0.2) color("#aabbcc")
"""
RPK_FACADE = """attr floorH = 3
Facade --> split(y) { { ~floorH : Floor }* }
Floor --> report("floors", 1) i("/Proj/assets/box.obj")
"""
RESOLVEMAP = ('<resolvemap><entry key="/Proj/assets/box.obj" value="assets/box.obj"/>'
              '</resolvemap>')


def rpk_members() -> dict[str, bytes]:
    """The files of a small rule package project (archive name → content)."""
    return {"rules/main.cga": RPK_MAIN.encode(), "rules/facade.cga": RPK_FACADE.encode(),
            "bin/main.cgb": b"compiled", "assets/box.obj": CUBE_OBJ.encode(),
            ".resolvemap.xml": RESOLVEMAP.encode()}


def write_rpk(path: Path, members: dict[str, bytes]) -> Path:
    import py7zr

    with py7zr.SevenZipFile(path, "w") as z:
        for name, data in members.items():
            z.writef(io.BytesIO(data), name)
    return path


def classifier_parts() -> tuple[dict, dict[str, np.ndarray]]:
    """The metadata and arrays of a valid, tiny two-class colour GMM classifier."""
    meta = {"format": "facadeforge-classifier", "version": 1, "kind": "gmm",
            "classes": ["wall", "window"], "label_set": "ecp7", "meta": {}}
    arrays = {"weights": np.array([[1.0], [1.0]]),
              "means": np.array([[[200.0, 200, 200]], [[60.0, 60, 60]]]),
              "covariances": np.stack([np.eye(3)[None] * 100.0] * 2)}
    return meta, arrays


def npz_bytes(meta: dict | bytes, arrays: dict[str, np.ndarray], compressed: bool) -> bytes:
    blob = meta if isinstance(meta, bytes) else json.dumps(meta).encode()
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(
        buf, __meta__=np.frombuffer(blob, np.uint8), **arrays)
    return buf.getvalue()


def photo_png(path: Path, width: int = 128, height: int = 96) -> Path:
    """A rectified facade photo: light wall, a grid of dark windows."""
    from PIL import Image

    img = np.full((height, width, 3), 200, np.uint8)
    for y in range(8, height - 20, 28):
        for x in range(10, width - 12, 24):
            img[y:y + 14, x:x + 10] = 60
    img[height - 18:height - 2, width // 2 - 6:width // 2 + 6] = 90
    Image.fromarray(img).save(path)
    return path
