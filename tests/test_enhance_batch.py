"""``facadeforge enhance --batch``: a city of textured mass models enhanced through ``batch``'s
machinery: chunks on Dask, outputs per chunk, a merged report and tileset, resume after a
lost chunk or a SIGKILL, refused reruns (issue 31, item 3)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tests.test_batch import buildings_in_chunks, cityjson_validator, cli_env, kill_when_done

from facadeforge.city import tileset_problems
from facadeforge.cli import main
from facadeforge.datasets.mass_models import box_mass_model
from facadeforge.exchange import export, load
from facadeforge.model.model import Material, Model, Part

PPM = "12"          # unwrapped at 12 px/m: small images, quick reconstructions


@pytest.fixture(scope="module")
def scheduler():
    """A local Dask cluster of 2 worker processes, reached through ``--scheduler``."""
    distributed = pytest.importorskip("distributed")
    import logging

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None,
                                  silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


def street(folder: Path, n: int, name: str = "street.glb", plain: set[int] = frozenset()
           ) -> Path:
    """``n`` box buildings 20 m apart along x, named ``b0``…, their street walls textured at
    8 px/m with one of two facade photos in turn; those in ``plain`` without a texture."""
    blocks = []
    for k, seed in enumerate((21, 22)):
        box, _ = box_mass_model(folder / f"box{k}", textured=(0,), ppm=8, seed=seed)
        blocks += load(box, texture_dir=folder / f"box{k}" / "textures")
    models = []
    for i in range(n):
        parts = []
        for p in blocks[i % 2].parts:
            mat = Material(name="plaster", color=(0.8, 0.75, 0.7)) if i in plain else p.material
            parts.append(Part(p.mesh.with_vertices(p.mesh.vertices + (20.0 * i, 0.0, 0.0)),
                              p.label, mat, p.symbol))
        models.append(Model(parts=parts, name=f"b{i}"))
    path = folder / name
    export(models, path)
    return path


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("enhance-batch-in")
    return street(d, 5, plain={3}), street(d, 2, name="more.glb")


def run(paths, out, scheduler, *extra) -> int:
    return main(["enhance", "--batch", *map(str, paths), "-o", str(out), "--px-per-m", PPM,
                 "--chunk", "2", "--scheduler", scheduler, *extra])


@pytest.fixture(scope="module")
def done(models, scheduler, tmp_path_factory):
    out = tmp_path_factory.mktemp("enhance-batch") / "out"
    assert run(models, out, scheduler) == 0
    return out


def test_every_building_once_with_its_facades_and_report(done):
    out = done
    seen = buildings_in_chunks(out, cityjson_validator())
    # names made unique across the two files; the untextured building is kept as it was
    assert sorted(seen) == ["b0", "b0~2", "b1", "b1~2", "b2", "b3", "b4"]
    assert set(seen.values()) == {1}
    report = json.loads((out / "report.json").read_text())
    assert report["buildings"] == 7 and report["chunks"] == 4 and not report["failed"]
    facades = report["facades"]
    # one textured wall each, but b3's: six facades
    assert sorted(f["building"] for f in facades) == ["b0", "b0~2", "b1", "b1~2", "b2", "b4"]
    assert report["summary"]["windows"] == sum(f["windows"] for f in facades) > 0
    for f in facades:
        assert f["px_per_m"] == pytest.approx(8, rel=0.02) and f["resampled_px_per_m"] == 12
        for name in ("rules.cga", "shape_tree.json", "texture.png"):
            assert (out / f["folder"] / name).is_file(), (f["folder"], name)
        assert f["folder"].startswith(f"facades/{f['chunk']}/")
    rows = list(csv.DictReader((out / "buildings.csv").open()))
    assert len(rows) == 7 and {r["status"] for r in rows} == {"ok"}
    assert tileset_problems(out / "tiles" / "tileset.json") == []
    assert not list((out / ".work").iterdir())


def test_walls_are_replaced_in_the_chunks(done):
    """The enhanced buildings carry many more faces than the boxes (4 walls + roof) did; the
    untextured one keeps its 5 quads (10 triangles, as the GLB stores them)."""
    rows = {r["building"]: r for r in csv.DictReader((done / "buildings.csv").open())}
    assert int(rows["b3"]["faces"]) == 10
    assert min(int(rows[b]["faces"]) for b in rows if b != "b3") > 50
    # each building stays where it stood: b4's box spans x 80–94
    assert float(rows["b4"]["min_x"]) >= 79.9 and float(rows["b4"]["max_x"]) <= 94.6


def test_textures_of_different_chunks_never_overwrite_each_other(done):
    """Every facade's texture is ``texture.jpg`` where it is made: the chunks' CityJSON files
    share one ``textures/`` folder, so they are named by their bytes too."""
    import hashlib

    names = [p.name for p in (done / "chunks" / "textures").iterdir()]
    assert len([n for n in names if n.startswith("texture_")]) >= 2
    for path in (done / "chunks" / "textures").iterdir():
        # each file holds the bytes its name says: none was overwritten by another chunk's
        digest = hashlib.sha256(path.read_bytes()).hexdigest()[:12]
        assert path.stem.rsplit("_", 1)[1] == digest, path.name
    for path in (done / "chunks").glob("*.city.jsonl"):
        for line in path.read_text().splitlines()[1:]:
            for tex in json.loads(line).get("appearance", {}).get("textures", []):
                assert (path.parent / tex["image"]).is_file()


def test_rerun_keeps_finished_chunks_and_redoes_a_lost_one(models, done, scheduler, capsys,
                                                          tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(done, out)
    capsys.readouterr()
    assert run(models, out, scheduler) == 0
    assert "(0 enhanced, 4 kept from an earlier run)" in capsys.readouterr().out
    # a chunk whose worker died before its manifest entry: its files may be there, half new
    (out / "manifest" / "00001.json").unlink()
    stale = out / "facades" / "00001" / "facade_99"
    stale.mkdir()
    before = json.loads((done / "report.json").read_text())["summary"]["windows"]
    assert run(models, out, scheduler) == 0
    assert "(1 enhanced, 3 kept from an earlier run)" in capsys.readouterr().out
    seen = buildings_in_chunks(out)
    assert len(seen) == 7 and set(seen.values()) == {1}
    assert json.loads((out / "report.json").read_text())["summary"]["windows"] == before
    assert not stale.exists()        # the chunk's folder was replaced, not added to
    # a chunk whose facade folders were deleted is not done
    import shutil as _sh

    _sh.rmtree(out / "facades" / "00002")
    assert run(models, out, scheduler) == 0
    assert "(1 enhanced, 3 kept from an earlier run)" in capsys.readouterr().out
    assert (out / "facades" / "00002").is_dir()


def test_other_options_or_command_on_the_outdir_are_refused(models, done, scheduler, capsys,
                                                          tmp_path):
    from tests.test_batch import city

    capsys.readouterr()
    assert run(models, done, scheduler, "--seed", "3") == 2
    err = capsys.readouterr().err
    assert "other options" in err and "--seed was 0, now 3" in err and err.count("\n") == 1
    rules = Path(__file__).resolve().parents[1] / "examples" / "grammars" / "building.cga"
    lots = city(tmp_path / "lots.geojson", 2)
    assert main(["batch", str(rules), "--footprint", str(lots), "-o", str(done)]) == 2
    assert "another command (facadeforge enhance" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--workers", "2"], "--workers is for a batch of buildings: add --batch"),
    (["MORE"], "several models are for a batch of buildings: add --batch"),
])
def test_batch_flags_without_batch_are_refused(models, tmp_path, capsys, argv, message):
    argv = [str(models[1]) if a == "MORE" else a for a in argv]
    assert main(["enhance", str(models[0]), *argv, "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_models_without_textures_are_refused_before_any_work(tmp_path, capsys):
    path = street(tmp_path, 2, plain={0, 1})
    assert main(["enhance", "--batch", str(path), "-o", str(tmp_path / "o")]) == 2
    assert "no textured faces" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_sigkill_midway_then_rerun_gives_every_building_once(tmp_path):
    """The whole run (driver, scheduler, workers) killed with SIGKILL once a chunk is done;
    the same command again finishes the street, each building once."""
    path = street(tmp_path, 6)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "facadeforge.cli", "enhance", "--batch", str(path), "-o",
           str(out), "--px-per-m", PPM, "--chunk", "1", "--workers", "2"]
    env = cli_env()
    kept = kill_when_done(cmd, out, 1, env, 120)
    assert 1 <= kept < 6, "the run was not killed midway"
    assert not (out / "report.json").exists()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"({6 - kept} enhanced, {kept} kept from an earlier run)" in r.stdout
    seen = buildings_in_chunks(out)
    assert sorted(seen) == [f"b{i}" for i in range(6)] and set(seen.values()) == {1}
    report = json.loads((out / "report.json").read_text())
    assert sorted(f["building"] for f in report["facades"]) == sorted(seen)
    assert tileset_problems(out / "tiles" / "tileset.json") == []
    assert np.all([(out / f["folder"] / "rules.cga").is_file() for f in report["facades"]])


def test_a_worker_whose_model_file_differs_fails_the_whole_chunk(models, tmp_path):
    """The chunk raises (no manifest entry: a rerun retries it) rather than recording each
    building as failed from a file that is not the one planned with."""
    from facadeforge.city.batch import Chunk
    from facadeforge.city.enhance_batch import BuildingRef, enhance_chunk
    from facadeforge.errors import InputError

    spec = {"models": [str(models[1])], "model_hashes": ["0" * 64], "up": "y",
            "px_per_m": 12.0, "seed": 0, "rules_hash": None, "options_hash": "x",
            "version": "0", "outdir": str(tmp_path)}
    chunk = Chunk(0, [BuildingRef(0, 0, "b0", (0.0, 0.0))], "h")
    with pytest.raises(InputError, match="not the file the run was planned with"):
        enhance_chunk(spec, chunk)
    assert not (tmp_path / "manifest").exists()
