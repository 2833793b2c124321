"""Exporters take models one at a time (a generator, as ``engine.derive_iter`` gives them), so
a city is written without holding it in memory: the files equal those of a list."""

from __future__ import annotations

import json
import multiprocessing
import os
from pathlib import Path

import numpy as np
import pytest
from tests.cjval import cjval_problems, cjval_reports, needs_cjval

from facadeforge import engine
from facadeforge.exchange import ExportError, export, load
from facadeforge.geometry.footprints import Footprint


def _models(house_factory, texture_png):
    return [house_factory(texture_png if k % 2 else None, name=f"house{k}") for k in range(3)]


def _generator(models):
    yield from models


@pytest.mark.parametrize("suffix", ["glb", "obj"])
def test_a_generator_writes_the_same_file_as_a_list(tmp_path: Path, house_factory, texture_png,
                                                    suffix):
    models = _models(house_factory, texture_png)
    export(models, tmp_path / f"list.{suffix}")
    export(_generator(models), tmp_path / f"gen.{suffix}")
    a, b = (tmp_path / f"list.{suffix}").read_bytes(), (tmp_path / f"gen.{suffix}").read_bytes()
    if suffix == "obj":  # the .mtl name differs with the file name
        a, b = a.replace(b"list.mtl", b"gen.mtl"), b
    assert a == b


def test_cityjson_written_building_by_building(tmp_path: Path, house_factory, texture_png):
    models = _models(house_factory, texture_png)
    export(_generator(models), tmp_path / "out.city.json")
    doc = json.loads((tmp_path / "out.city.json").read_text())
    assert list(doc["CityObjects"]) == ["house0", "house1", "house2"]
    real = np.asarray(doc["vertices"]) * doc["transform"]["scale"] + doc["transform"]["translate"]
    ext = doc["metadata"]["geographicalExtent"]
    assert real.min(axis=0) == pytest.approx(ext[:3], abs=1e-3)
    assert real.max(axis=0) == pytest.approx(ext[3:], abs=1e-3)
    back = load(tmp_path / "out.city.json")
    assert [len(m.parts) > 0 for m in back] == [True] * 3
    area = sum(p.mesh.area() for m in models for p in m.parts)
    assert sum(p.mesh.area() for m in back for p in m.parts) == pytest.approx(area, rel=1e-4)


def test_a_vertex_two_buildings_share_is_written_once(tmp_path: Path):
    """Party-wall corners (and coincident copies) are one vertex of a ``.city.json``, however
    many buildings use them, and every building keeps its own geometry."""
    fps = [Footprint(f"b{k}", np.array([[0, 0, 0], [6, 0, 0], [6, 0, -4], [0, 0, -4]], float)
                     + [6.0 * k, 0, 0]) for k in range(5)]            # a row of terraced houses
    models = engine.derive("Lot --> extrude(6) comp(f){ side : split(y){ 3 : F }* | all : X. }"
                           "\nF --> Y.", fps, workers=1)
    models = models + models[:2]                                      # and two coincident copies
    export(models, tmp_path / "row.city.json")
    doc = json.loads((tmp_path / "row.city.json").read_text())
    verts = np.asarray(doc["vertices"])
    assert len(np.unique(verts, axis=0)) == len(verts)
    used = {v for o in doc["CityObjects"].values() for g in o["geometry"]
            for v in json.dumps(g["boundaries"]).replace("[", " ").replace("]", " ")
            .replace(",", " ").split()}
    assert used == {str(i) for i in range(len(verts))}               # none unused
    back = load(tmp_path / "row.city.json")
    area = sum(p.mesh.area() for m in models for p in m.parts)
    assert sum(p.mesh.area() for m in back for p in m.parts) == pytest.approx(area, rel=1e-4)
    assert len(verts) < sum(len(np.unique(np.rint(np.concatenate(
        [p.mesh.vertices for p in m.parts]) * 1000), axis=0)) for m in models)


@pytest.mark.parametrize("suffix", ["glb", "obj", "city.json"])
def test_an_empty_generator_writes_nothing(tmp_path: Path, suffix):
    with pytest.raises(ExportError, match="nothing to export"):
        export(_generator([]), tmp_path / f"x.{suffix}")
    assert not list(tmp_path.iterdir())


def test_derive_iter_hands_out_models_in_order_from_workers():
    fps = [Footprint(f"b{k}", np.array([[0, 0, 0], [4 + k, 0, 0], [4 + k, 0, -3], [0, 0, -3]],
                                       float) + [20.0 * k, 0, 0]) for k in range(9)]
    rules = "Lot --> extrude(3 + split.index) report(\"w\", scope.sx) X."
    got = engine.derive_iter(rules, fps, workers=2, keep_tree=False)
    assert not isinstance(got, list)
    models = list(got)
    assert [m.name for m in models] == [f"b{k}" for k in range(9)]
    assert [m.reports["w"][0] for m in models] == pytest.approx([4 + k for k in range(9)])
    assert [m.stats()["faces"] for m in models] == [m.stats()["faces"]
                                                    for m in engine.derive(rules, fps, workers=1)]


def test_cityjson_text_sequences(tmp_path: Path, house_factory, texture_png):
    models = _models(house_factory, texture_png)
    export(_generator(models), tmp_path / "out.city.jsonl")
    lines = (tmp_path / "out.city.jsonl").read_text().splitlines()
    head, features = json.loads(lines[0]), [json.loads(x) for x in lines[1:]]
    assert head["type"] == "CityJSON" and head["CityObjects"] == {} and "transform" in head
    assert [f["type"] for f in features] == ["CityJSONFeature"] * 3
    assert [f["id"] for f in features] == ["house0", "house1", "house2"]
    # each feature's vertex indices are its own, and the textured houses carry an appearance
    for f in features:
        used = {i for s in f["CityObjects"][f["id"]]["geometry"][0]["boundaries"]
                for ring in s for i in ring}
        assert used == set(range(len(f["vertices"])))
    assert ["appearance" in f and "textures" in f["appearance"] for f in features] \
        == [False, True, False]
    back = load(tmp_path / "out.city.jsonl")
    area = sum(p.mesh.area() for m in models for p in m.parts)
    assert sum(p.mesh.area() for m in back for p in m.parts) == pytest.approx(area, rel=1e-4)
    assert [m.name for m in back] == ["house0", "house1", "house2"]


def test_cityjson_feature_content_is_valid_cityjson(tmp_path: Path, house_factory, texture_png,
                                                     validator):
    export(_models(house_factory, texture_png), tmp_path / "out.city.jsonl")
    lines = (tmp_path / "out.city.jsonl").read_text().splitlines()
    head = json.loads(lines[0])
    for line in lines[1:]:
        f = json.loads(line)
        doc = {"type": "CityJSON", "version": "2.0", "transform": head["transform"],
               "CityObjects": f["CityObjects"], "vertices": f["vertices"]}
        if "appearance" in f:
            doc["appearance"] = f["appearance"]
        errors = [e.message for e in validator.iter_errors(doc)]
        assert not errors, errors


@needs_cjval
@pytest.mark.parametrize("name", ["out.city.json", "out.city.jsonl"])
def test_cityjson_and_cityjsonseq_pass_cjval(tmp_path: Path, house_factory, texture_png, name):
    """Textured and untextured buildings, with semantics and materials, as the official
    validator reads them: no error and no warning (duplicate or unused vertices)."""
    export(_models(house_factory, texture_png), tmp_path / name)
    reports = cjval_reports(tmp_path / name)
    assert len(reports) == (4 if name.endswith("jsonl") else 1)
    assert cjval_problems(tmp_path / name) == []


def test_shape_ids_do_not_depend_on_which_worker_derived_a_building():
    fps = [Footprint(f"b{k}", np.array([[0, 0, 0], [6, 0, 0], [6, 0, -4], [0, 0, -4]], float)
                     + [10.0 * k, 0, 0]) for k in range(6)]
    rules = "Lot --> extrude(6) comp(f){ side : split(y){ 3 : F }* | all : X. }\nF --> Y."
    ids = [[[p.shape_id for p in m.parts] for m in engine.derive(rules, fps, workers=w)]
           for w in (1, 2)]
    assert ids[0] == ids[1] and ids[0][0] == ids[0][5]


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork",
                    reason="workers inherit the parent's rules only when forked")
def test_forked_workers_do_not_parse_the_rules_again(tmp_path, monkeypatch):
    """The parent loads the rules once; forked workers take them over instead of parsing the
    files again (a large rule set takes a third of a second a process)."""
    from facadeforge import engine
    from facadeforge.geometry.footprints import lot

    calls = tmp_path / "calls"
    real = engine.load_rules

    def counting(*args, **kwargs):
        with open(calls, "a") as fh:
            fh.write(f"{os.getpid()}\n")
        return real(*args, **kwargs)
    monkeypatch.setattr(engine, "load_rules", counting)
    rules = tmp_path / "r.cga"
    rules.write_text("Lot --> extrude(3) X.\n")
    fps = [lot("10x10")[0] for _ in range(4)]
    models = engine.derive(str(rules), fps, workers=2, keep_tree=False)
    assert [m.derived_stats["faces"] for m in models] == [6] * 4
    assert calls.read_text().split() == [str(os.getpid())]   # the parent's load, no other
    assert engine._PRELOADED == {}                          # released with the pool
