"""``facadeforge batch`` on Dask: outputs, resume after a lost chunk, refused reruns, failed
buildings, and a real SIGKILL of the whole run (issue 31)."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pygltflib
import pytest
from tests.cjval import cjval_problems, cjval_reports, needs_cjval

from facadeforge.city import plan_chunks, tileset_problems
from facadeforge.cli import main
from facadeforge.geometry.footprints import load_footprints
from facadeforge.scratch import owner_tag

RULES = """version "2019.0"
attr height = 10
@StartRule
Lot --> extrude(height) Mass
Mass --> comp(f) { side : Wall | top : Roof | bottom : NIL }
Wall --> split(y) { ~3 : Floor }*
Floor --> split(x) { ~3 : Tile }*
Tile --> color("#b0a090") Tile.
Roof --> color("#803020") Roof.
"""


def city(path: Path, n: int, tall: set[int] = frozenset()) -> Path:
    """``n`` rectangular lots on a grid; those in ``tall`` far too high to derive."""
    side = int(n ** 0.5) + 1
    feats = []
    for i in range(n):
        x, y = (i % side) * 30.0, (i // side) * 24.0
        w, d = 12 + i % 5, 9 + i % 3
        props = {"name": f"b{i:04d}"}
        if i in tall:
            props["height"] = 1e12
        feats.append({"type": "Feature", "properties": props, "geometry": {
            "type": "Polygon",
            "coordinates": [[[x, y], [x + w, y], [x + w, y + d], [x, y + d], [x, y]]]}})
    path.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    return path


@pytest.fixture(scope="module")
def scheduler():
    """One local Dask cluster (2 worker processes) for the in-process runs: they go through
    ``--scheduler``, the multi-machine path; the SIGKILL test starts its own."""
    distributed = pytest.importorskip("distributed")
    import logging

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None,
                                  silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch-inputs")
    (d / "tiny.cga").write_text(RULES)
    return d / "tiny.cga", city(d / "city.geojson", 30)


def run(rules, fps, out, scheduler, *extra) -> int:
    return main(["batch", str(rules), "--footprint", *map(str, fps), "-o", str(out),
                 "--chunk", "5", "--scheduler", scheduler, *extra])


SCHEMAS = Path(__file__).resolve().parent / "data" / "cityjson-2.0"


def cityjson_validator():
    """The CityJSON 2.0 schema (tests/data/cityjson-2.0) as a jsonschema validator."""
    import jsonschema
    from referencing import Registry, Resource

    resources = []
    for file in sorted(SCHEMAS.glob("*.schema.json")):
        schema = json.loads(file.read_text())
        resources.append((schema["$id"], Resource.from_contents(schema)))
    root = json.loads((SCHEMAS / "cityjson.schema.json").read_text())
    return jsonschema.Draft7Validator(root, registry=Registry().with_resources(resources))


def buildings_in_chunks(out: Path, schema=None) -> Counter:
    """How many times each building is in the CityJSONSeq chunks; checks each line too (with
    ``schema``: each feature, with its file's first line, as a CityJSON 2.0 document)."""
    seen: Counter = Counter()
    for path in sorted((out / "chunks").glob("*.city.jsonl")):
        lines = path.read_text(encoding="utf-8").splitlines()
        head = json.loads(lines[0])
        assert head["type"] == "CityJSON" and head["version"] == "2.0"
        assert head["CityObjects"] == {} and head["vertices"] == []
        assert len(head["transform"]["scale"]) == 3
        for line in lines[1:]:
            f = json.loads(line)
            assert f["type"] == "CityJSONFeature"
            assert f["id"] in f["CityObjects"]
            assert f["CityObjects"][f["id"]]["type"] == "Building"
            assert isinstance(f["vertices"], list) and f["vertices"]
            n = len(f["vertices"])
            for obj in f["CityObjects"].values():
                for g in obj["geometry"]:
                    flat = json.dumps(g["boundaries"]).replace("[", " ").replace("]", " ")
                    assert max(int(v) for v in flat.replace(",", " ").split()) < n
            seen[f["id"]] += 1
            if schema is not None:
                doc = {**head, "CityObjects": f["CityObjects"], "vertices": f["vertices"]}
                if "appearance" in f:
                    doc["appearance"] = f["appearance"]
                problems = [e.message for e in schema.iter_errors(doc)]
                assert not problems, (path.name, f["id"], problems[:3])
    return seen


def test_batch_writes_chunks_tiles_and_table(inputs, scheduler, tmp_path, capsys):
    rules, fps = inputs
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    assert "30 building(s) in 6 chunk(s) (6 derived, 0 kept" in capsys.readouterr().out
    seen = buildings_in_chunks(out, cityjson_validator())
    assert sorted(seen) == [f"b{i:04d}" for i in range(30)] and set(seen.values()) == {1}
    entries = [json.loads(p.read_text()) for p in sorted((out / "manifest").glob("*.json"))]
    assert [e["name"] for e in entries] == [f"{k:05d}" for k in range(6)]
    assert all(len(e["input_hash"]) == 64 and len(e["rules_hash"]) == 64 for e in entries)
    assert all(e["version"] and e["derived"] == 5 and not e["failed"] for e in entries)
    rows = list(csv.DictReader((out / "buildings.csv").open(encoding="utf-8")))
    assert len(rows) == 30 and {r["status"] for r in rows} == {"ok"}
    assert all(float(r["height_m"]) == pytest.approx(10) for r in rows)
    for e in entries:
        glb = pygltflib.GLTF2().load(str(out / e["files"]["glb"]))
        assert len(glb.meshes) == 5 and glb.asset.version == "2.0"
    assert tileset_problems(out / "tiles" / "tileset.json") == []
    # from afar the city's 30 buildings are blocks (6 chunk tiles: one parent, the root)
    root = json.loads((out / "tiles" / "tileset.json").read_text())["root"]
    assert root["refine"] == "REPLACE" and root["content"]["uri"] == "coarse_00000.glb"
    blocks = pygltflib.GLTF2().load(str(out / "tiles" / "coarse_00000.glb"))
    pos = blocks.accessors[blocks.meshes[0].primitives[0].attributes.POSITION]
    assert pos.count == 30 * 24  # 6 faces of 4 corners a block
    assert not list((out / ".work").iterdir())


def test_rerun_redoes_only_the_chunk_without_manifest(inputs, scheduler, tmp_path, capsys):
    rules, fps = inputs
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    stamps = {p.name: p.stat().st_mtime_ns for p in (out / "manifest").glob("*.json")}
    # as a worker killed while writing chunk 2 leaves it: no manifest entry, its scratch
    # folder half written (a dead process's), an old jsonl under its final name
    (out / "manifest" / "00002.json").unlink()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = out / ".work" / f"chunk-{owner_tag().rsplit('-', 1)[0]}-{dead}-x1y2"
    stale.mkdir()
    (stale / ".00002.glb.abc.part").write_bytes(b"glTF half")
    capsys.readouterr()
    assert run(rules, [fps], out, scheduler) == 0
    assert "(1 derived, 5 kept from an earlier run)" in capsys.readouterr().out
    assert not stale.exists()
    now = {p.name: p.stat().st_mtime_ns for p in (out / "manifest").glob("*.json")}
    assert set(now) == set(stamps)
    assert [k for k in now if now[k] != stamps[k]] == ["00002.json"]
    seen = buildings_in_chunks(out)
    assert len(seen) == 30 and set(seen.values()) == {1}
    assert len(list(csv.DictReader((out / "buildings.csv").open()))) == 30
    assert tileset_problems(out / "tiles" / "tileset.json") == []


def test_other_options_on_the_same_outdir_are_refused(inputs, scheduler, tmp_path, capsys):
    rules, fps = inputs
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    capsys.readouterr()
    assert run(rules, [fps], out, scheduler, "--attr", "height=4") == 2
    err = capsys.readouterr().err
    assert err.startswith("facadeforge: error: output folder") and err.count("\n") == 1
    assert "--attr was {}" in err and "give a new -o folder" in err
    other = rules.with_name("other.cga")
    other.write_text(RULES.replace("height = 10", "height = 12"))
    assert run(other, [fps], out, scheduler) == 2
    assert "other rules" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--attr", "heigth=3"], "--attr heigth: the rules have no attribute 'heigth'"),
    (["--chunk", "0"], "--chunk 0: give a positive number"),
    (["--workers", "3"], "--workers sizes the local cluster"),
])
def test_bad_arguments_are_one_line(inputs, scheduler, tmp_path, capsys, argv, message):
    rules, fps = inputs
    assert main(["batch", str(rules), "--footprint", str(fps), "-o", str(tmp_path / "o"),
                 "--scheduler", scheduler, *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("facadeforge: error: ") and message in err and err.count("\n") == 1


def test_foreign_outdir_and_input_inside_are_refused(inputs, tmp_path, capsys):
    rules, fps = inputs
    (tmp_path / "mine.txt").write_text("keep me")
    assert main(["batch", str(rules), "--footprint", str(fps), "-o", str(tmp_path)]) == 2
    assert "holds files and no batch.json" in capsys.readouterr().err
    inside = tmp_path / "o"
    inside.mkdir()
    local = city(inside / "c.geojson", 2)
    assert main(["batch", str(rules), "--footprint", str(local), "-o", str(inside)]) == 2
    assert "is inside the output folder" in capsys.readouterr().err


def test_a_failing_building_is_recorded_not_fatal(inputs, scheduler, tmp_path, capsys):
    rules, _ = inputs
    fps = city(tmp_path / "c.geojson", 7, tall={3})
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    r = capsys.readouterr()
    assert "1 failed" in r.out and "b0003" in r.err
    rows = {row["building"]: row for row in csv.DictReader((out / "buildings.csv").open())}
    assert rows["b0003"]["status"] == "failed" and rows["b0003"]["error"]
    assert sum(row["status"] == "ok" for row in rows.values()) == 6
    failed = [f for p in (out / "manifest").glob("*.json")
              for f in json.loads(p.read_text())["failed"]]
    assert [f["building"] for f in failed] == ["b0003"]
    assert set(buildings_in_chunks(out)) == set(rows) - {"b0003"}


@needs_cjval
def test_chunks_pass_cjval(inputs, scheduler, tmp_path):
    rules, fps = inputs
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    chunks = sorted((out / "chunks").glob("*.city.jsonl"))
    assert chunks
    for path in chunks:   # the metadata line and one record per building of the chunk
        assert len(cjval_reports(path)) == 6, path.name
        assert cjval_problems(path) == [], path.name


def test_lon_lat_footprints_put_the_tileset_on_the_globe(inputs, scheduler, tmp_path):
    import numpy as np

    rules, _ = inputs
    feats = []
    for i in range(3):   # three lots in Stuttgart, lon/lat (projected to UTM 32N on reading)
        x, y = 9.18 + i * 0.0003, 48.78
        ring = [[x, y], [x + 0.0002, y], [x + 0.0002, y + 0.0001], [x, y + 0.0001], [x, y]]
        feats.append({"type": "Feature", "properties": {"name": f"s{i}"},
                      "geometry": {"type": "Polygon", "coordinates": [ring]}})
    fps = tmp_path / "stuttgart.geojson"
    fps.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    doc = json.loads((out / "tiles" / "tileset.json").read_text())
    m = np.array(doc["root"]["transform"]).reshape(4, 4).T
    assert 6.35e6 < np.linalg.norm(m[:3, 3]) < 6.40e6
    assert tileset_problems(out / "tiles" / "tileset.json") == []
    head = json.loads((out / "chunks" / "00000.city.jsonl").open().readline())
    assert head["metadata"]["referenceSystem"].endswith("/EPSG/0/32632")


def test_progress_is_one_updating_line_on_a_terminal_and_plain_lines_elsewhere():
    import io

    from facadeforge.city.batch import _Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty, log = Tty(), io.StringIO()
    for stream in (tty, log):
        bar = _Progress(10, stream, every=0.0)
        bar.update(5, 1, 2)
        bar.update(5, 2, 2)
    text = tty.getvalue()   # the line rewritten in place, ended once the last chunk is in
    assert text.count("\r") == 2 and text.count("\n") == 1 and text.endswith("\n")
    assert text.rstrip().endswith("ETA 0:00")
    lines = log.getvalue().splitlines()
    assert len(lines) == 2 and "\r" not in log.getvalue()
    assert lines[0].startswith("batch: 5/10 buildings (50 %), chunk 1/2, ")
    assert "buildings/s, ETA " in lines[0] and lines[1].endswith("ETA 0:00")


def test_chunks_are_compact_and_names_unique_across_files(tmp_path):
    a = load_footprints(city(tmp_path / "a.geojson", 16))
    b = load_footprints(city(tmp_path / "b.geojson", 3))
    chunks = plan_chunks([a, b], 4)
    assert [len(c.footprints) for c in chunks] == [4, 4, 4, 4, 3]
    names = [fp.name for c in chunks for fp in c.footprints]
    assert len(set(names)) == 19 and "b0000~2" in names
    assert plan_chunks([a, b], 4)[2].input_hash == chunks[2].input_hash   # deterministic


def cli_env() -> dict:
    return {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}


def kill_when_done(cmd: list[str], out: Path, chunks: int, env: dict, wait_s: float) -> int:
    """Run ``cmd`` in its own process group, SIGKILL the whole group once ``chunks`` manifest
    entries exist in ``out`` (or after ``wait_s``); returns the entries there then."""
    p = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, env=env)
    try:
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and p.poll() is None:
            if len(list((out / "manifest").glob("*.json"))) >= chunks:
                break
            time.sleep(0.02)
        os.killpg(p.pid, signal.SIGKILL)
    finally:
        p.wait(timeout=30)
    return len(list((out / "manifest").glob("*.json")))


def test_sigkill_midway_then_rerun_gives_every_building_once(inputs, tmp_path):
    """The whole run (driver, scheduler, workers: its process group) killed with SIGKILL once
    the first chunks are done; the same command again finishes the city."""
    rules, _ = inputs
    fps = city(tmp_path / "big.geojson", 200)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "facadeforge.cli", "batch", str(rules), "--footprint",
           str(fps), "-o", str(out), "--chunk", "5", "--workers", "2"]
    env = cli_env()
    kept = kill_when_done(cmd, out, 2, env, 60)
    assert 2 <= kept < 40, "the run was not killed midway"
    assert not (out / "tiles" / "tileset.json").exists()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert f"({40 - kept} derived, {kept} kept from an earlier run)" in r.stdout
    seen = buildings_in_chunks(out)
    assert len(seen) == 200 and set(seen.values()) == {1}
    assert len(list(csv.DictReader((out / "buildings.csv").open()))) == 200
    assert tileset_problems(out / "tiles" / "tileset.json") == []
    assert not list((out / ".work").iterdir())


def test_a_changed_import_or_asset_is_other_rules(scheduler, tmp_path, capsys):
    """The rules hash covers imported rule files and the asset folder, not only the main
    file: a rerun after either changed is refused as other rules (its chunks would mix old and
    new buildings).  An OUTDIR inside the rules' folder does not count as an asset."""
    d = tmp_path / "project"
    d.mkdir()
    (d / "lib.cga").write_text('Tile --> color("#b0a090") Tile.\n')
    main_rules = d / "main.cga"
    main_rules.write_text(RULES.replace("Tile --> color(\"#b0a090\") Tile.\n", "")
                          .replace('version "2019.0"\n', 'version "2019.0"\nimport lib : "lib.cga"\n')
                          .replace(": Tile }*", ": lib.Tile }*"))
    assets = tmp_path / "assets"
    assets.mkdir()
    (assets / "tex.png").write_bytes(b"not read by these rules")
    fps = city(tmp_path / "city.geojson", 6)
    out = d / "out"
    argv = (main_rules, [fps], out, scheduler, "--assets", str(assets))
    assert run(*argv) == 0
    capsys.readouterr()
    assert run(*argv) == 0  # the same inputs (its own outputs inside the folder): resumed
    assert "(0 derived, 2 kept from an earlier run)" in capsys.readouterr().out  # chunks
    (d / "lib.cga").write_text('Tile --> color("#102030") Tile.\n')
    assert run(*argv) == 2
    assert "other rules" in capsys.readouterr().err
    (d / "lib.cga").write_text('Tile --> color("#b0a090") Tile.\n')
    os.utime(d / "lib.cga")
    assert run(*argv) == 0  # the import as it was: the same rules again
    capsys.readouterr()
    (assets / "tex.png").write_bytes(b"another texture, another size")
    assert run(*argv) == 2
    assert "other rules" in capsys.readouterr().err


PARTY = """Lot --> extrude(6) comp(f) { side : Facade | top : Roof. }
Facade --> split(x) { ~2 : Tile }*
Tile --> case touches(inter) : Wall. else : Window.
"""


def walls_per_building(out: Path) -> dict:
    """Surfaces with the ``Wall`` symbol in each building of the CityJSONSeq chunks."""
    walls = {}
    for path in sorted((out / "chunks").glob("*.city.jsonl")):
        for line in path.read_text(encoding="utf-8").splitlines()[1:]:
            f = json.loads(line)
            n = 0
            for obj in f["CityObjects"].values():
                for g in obj.get("geometry", []):
                    sem = g.get("semantics")
                    if sem:
                        wall = [i for i, s in enumerate(sem["surfaces"])
                                if s.get("facadeforge_symbol") == "Wall"]
                        n += sum(v in wall for v in sem["values"])
            walls[f["id"]] = n
    return walls


def row_of_lots(path: Path, spans) -> Path:
    feats = [{"type": "Feature", "properties": {"name": f"p{i}"}, "geometry": {
        "type": "Polygon", "coordinates": [[[x0, 0], [x1, 0], [x1, 8], [x0, 8], [x0, 0]]]}}
        for i, (x0, x1) in enumerate(spans)]
    path.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    return path


def test_inter_occlusion_sees_neighbours_across_chunks(scheduler, tmp_path):
    """Party walls between lots of different chunks are walls, as within one chunk and as
    ``derive`` makes them: each chunk derives its halo's occluders too."""
    from facadeforge import derive

    (tmp_path / "party.cga").write_text(PARTY)
    fps = row_of_lots(tmp_path / "row.geojson", [(0, 10), (10, 20), (20, 30), (40, 50)])
    per_chunk = {}
    for size in (1, 10):
        out = tmp_path / f"c{size}"
        assert main(["batch", str(tmp_path / "party.cga"), "--footprint", str(fps), "-o",
                     str(out), "--chunk", str(size), "--scheduler", scheduler]) == 0
        per_chunk[size] = walls_per_building(out)
    # the 8 m x 6 m party wall is 4 tiles a side; the lone p3 has none
    assert per_chunk[1] == per_chunk[10] == {"p0": 4, "p1": 8, "p2": 4, "p3": 0}
    models = derive(str(tmp_path / "party.cga"), fps, workers=1)
    walls = {m.name: sum(p.mesh.n_faces for p in m.parts if p.symbol == "Wall")
             for m in models}
    assert walls == per_chunk[1]
    halo = json.loads((tmp_path / "c1" / "manifest" / "00001.json").read_text())["halo"]
    assert sorted(halo) == ["p0", "p2"]


def test_halo_holds_near_footprints_of_other_chunks_only(tmp_path):
    fps = load_footprints(row_of_lots(tmp_path / "row.geojson",
                                      [(0, 10), (10, 20), (25, 30), (60, 70)]))
    chunks = plan_chunks([fps], 1, halo_m=10.0)
    halos = {c.footprints[0].name: sorted(fp.name for fp in c.halo) for c in chunks}
    # p2 is 5 m from p1 and 15 m from p0; p3 is 30 m from p2
    assert halos == {"p0": ["p1"], "p1": ["p0", "p2"], "p2": ["p1"], "p3": []}
    # the halo is part of what a chunk is made from
    plain = {c.footprints[0].name: c.input_hash for c in plan_chunks([fps], 1)}
    assert all(plain[c.footprints[0].name] != c.input_hash for c in chunks if c.halo)


def test_occluders_beyond_the_halo_are_reported(scheduler, tmp_path, capsys):
    rules = PARTY.replace("extrude(6) comp(f)", "extrude(6) t(14, 0, 0) comp(f)")
    (tmp_path / "far.cga").write_text(rules)
    fps = row_of_lots(tmp_path / "row.geojson", [(0, 10), (30, 40)])
    capsys.readouterr()
    assert main(["batch", str(tmp_path / "far.cga"), "--footprint", str(fps), "-o",
                 str(tmp_path / "o"), "--chunk", "1", "--scheduler", scheduler]) == 0
    err = capsys.readouterr().err
    assert "note: chunk 00000: building p0: its model reaches 14.0 m beyond its footprint" \
        in err and "note: chunk 00001: building p1" in err


def test_an_outdir_of_an_older_layout_is_not_resumed(inputs, scheduler, tmp_path, capsys):
    rules, fps = inputs
    out = tmp_path / "out"
    assert run(rules, [fps], out, scheduler) == 0
    cfg = json.loads((out / "batch.json").read_text())
    del cfg["layout"]                        # as the batches before layout 2 wrote it
    (out / "batch.json").write_text(json.dumps(cfg))
    capsys.readouterr()
    assert run(rules, [fps], out, scheduler) == 2
    assert "older facadeforge whose folders have layout 1" in capsys.readouterr().err
