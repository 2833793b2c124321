"""Every kind of GLB facadeforge writes passes the Khronos glTF validator (no error, no
warning): a derived city with inserted assets, a textured building (images embedded), a GML
model, a 3D Tiles content tile from ``batch``'s exporter, and Esri's Candler package when the
shared data is there.  A GLB broken on purpose must fail, or the check would prove nothing.

The validator is npm's ``gltf-validator`` run by Node.js (``make gltf-validator``, which
``make test`` runs: it installs into ``tests/gltf/node_modules``)."""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.engine import derive, load_rules
from facadeforge.exchange import export_glb

ROOT = Path(__file__).resolve().parents[2]
HERE = ROOT / "tests" / "gltf"
NODE = shutil.which("node")
INSTALLED = (HERE / "node_modules" / "gltf-validator" / "package.json").is_file()
CANDLER = ROOT.parent / "shared" / "data" / "cga"

pytestmark = pytest.mark.skipif(
    NODE is None or not INSTALLED,
    reason="the Khronos glTF validator is not installed: `make gltf-validator` (needs Node.js "
           "and npm) puts it into tests/gltf/node_modules")


def validate(*paths: Path) -> list[dict]:
    run = subprocess.run([NODE, str(HERE / "validate.mjs"), *map(str, paths)],
                         capture_output=True, text=True, timeout=300, check=True)
    return json.loads(run.stdout)


def assert_valid(*paths: Path) -> None:
    for r in validate(*paths):
        assert r["errors"] == 0 and r["warnings"] == 0, r


def test_derived_city_with_assets_is_valid(tmp_path):
    rules = load_rules(ROOT / "examples" / "grammars" / "building.cga",
                       assets=ROOT / "examples" / "assets")
    models = derive(rules, ROOT / "examples" / "footprints" / "block.geojson", workers=1)
    export_glb(models, tmp_path / "city.glb")
    assert_valid(tmp_path / "city.glb")


def test_textured_building_is_valid(tmp_path):
    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 255, (48, 80, 3), dtype=np.uint8)).save(tmp_path / "b.png")
    Image.fromarray(rng.integers(0, 255, (32, 32, 3), dtype=np.uint8)).save(tmp_path / "r.jpg")
    text = ('Lot --> extrude(9) comp(f) { side : Wall | top : Roof }\n'
            'Wall --> setupProjection(0, scope.xy, 3, 3) projectUV(0) texture("b.png") '
            'split(x) { ~2 : Bay }*\n'
            'Bay --> split(y) { ~1 : X. | 1.2 : s(\'0.6, \'1, 0.2) center(x) '
            'i("builtin:cube") color("#334455") Glass. | ~1 : X. }\n'
            'Roof --> setupProjection(0, scope.xy, 5, 5) projectUV(0) texture("r.jpg") Roof.\n')
    models = derive(load_rules(text, assets=tmp_path), lot_size="14x9", workers=1)
    export_glb(models, tmp_path / "textured.glb")
    assert_valid(tmp_path / "textured.glb")


def test_gml_model_is_valid(tmp_path):
    from facadeforge.gml import derive_gml
    from facadeforge.model.scope import Scope

    model = derive_gml(ROOT / "examples" / "grammars" / "cityfit" / "split_order.gml",
                       scope=Scope(np.zeros(3), np.eye(3), np.array([12.0, 9.0, 0.0])))
    assert model.stats()["faces"] > 0
    export_glb([model], tmp_path / "gml.glb")
    assert_valid(tmp_path / "gml.glb")


def test_empty_model_is_valid(tmp_path):
    """A rule that deletes everything: a GLB of nodes and no geometry (glTF allows no empty
    ``buffers`` array)."""
    models = derive("Lot --> NIL\n", lot_size="10x10", workers=1)
    export_glb(models, tmp_path / "empty.glb")
    assert_valid(tmp_path / "empty.glb")


def test_batch_tile_content_is_valid(tmp_path):
    """A chunk's tile as ``facadeforge batch`` writes it (``city/batch.py``: ``export_glb`` of
    the chunk's models, every building one node)."""
    models = derive("Lot --> extrude(8) comp(f) { side : Wall. | top : Roof. }\n",
                    lot_size="12x9", workers=1) * 3
    export_glb(models, tmp_path / "00000.glb")
    assert_valid(tmp_path / "00000.glb")


def test_coarse_blocks_of_a_tileset_are_valid(tmp_path):
    """The LoD1 blocks a tileset's parents show from afar (``city/tileset.py``)."""
    from facadeforge.city.tileset import ContentTile, write_tileset

    (tmp_path / "00000.glb").write_bytes(b"")
    tile = ContentTile("00000.glb", (0, 0, -20), (30, 12, 0),
                       buildings=[((0, 0, -20), (12, 9, -8)), ((15, 0, -14), (30, 12, 0))])
    write_tileset(tmp_path / "tileset.json", [tile])
    assert_valid(tmp_path / "coarse_00000.glb")


@pytest.mark.skipif(not (CANDLER / "candler.rpk").exists(),
                    reason="../shared/data/cga/candler.rpk (Esri's Candler package) is absent")
def test_candler_package_is_valid(tmp_path):
    models = derive(load_rules(CANDLER / "candler.rpk"), CANDLER / "candler_footprint.obj",
                    workers=1, keep_tree=False)
    export_glb(models, tmp_path / "candler.glb")
    assert_valid(tmp_path / "candler.glb")


def test_a_broken_glb_fails(tmp_path):
    """An accessor that claims more vertices than its buffer view holds: the validator must
    report errors (this test fails if it reports none)."""
    models = derive("Lot --> extrude(3) Mass.\n", lot_size="4x4", workers=1)
    good = tmp_path / "good.glb"
    export_glb(models, good)
    data = good.read_bytes()
    (json_len,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20:20 + json_len])
    doc["accessors"][0]["count"] *= 1000
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + json_len:]
    bad = tmp_path / "bad.glb"
    bad.write_bytes(struct.pack("<III", 0x46546C67, 2, 20 + len(text) + len(rest))
                    + struct.pack("<II", len(text), 0x4E4F534A) + text + rest)
    good_report, bad_report = validate(good, bad)
    assert good_report["errors"] == 0
    assert bad_report["errors"] > 0 and bad_report["messages"]
