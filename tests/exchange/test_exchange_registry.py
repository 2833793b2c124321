"""The suffix registry, typed errors and atomic writes."""

from __future__ import annotations

from pathlib import Path

import pytest

from facadeforge.exchange import EXPORTERS, IMPORTERS, ExportError, LoadError, export, load
from facadeforge.exchange._common import Staging
from facadeforge.model import Model


def test_suffixes():
    assert set(EXPORTERS) == {"glb", "obj", "city.json", "city.jsonl", "png", "svg"}
    assert {"glb", "obj"} <= set(IMPORTERS)


def test_unknown_suffix_names_path_and_known_suffixes(tmp_path: Path, house: Model):
    with pytest.raises(ExportError) as err:
        export(house, tmp_path / "house.json")  # .json alone is not .city.json
    message = str(err.value)
    assert "house.json" in message
    for suffix in (".glb", ".obj", ".city.json", ".png", ".svg"):
        assert suffix in message
    with pytest.raises(LoadError, match="known suffixes"):
        load(tmp_path / "house.fbx")
    assert isinstance(err.value, ValueError)


def test_suffix_is_case_insensitive(tmp_path: Path, house: Model):
    assert export(house, tmp_path / "HOUSE.GLB") == [tmp_path / "HOUSE.GLB"]
    assert load(tmp_path / "HOUSE.GLB")[0].name == "house"


def test_unknown_option(tmp_path: Path, house: Model):
    with pytest.raises(ExportError, match="unknown option.*colour"):
        export(house, tmp_path / "h.glb", colour="red")


def test_bad_models_argument(tmp_path: Path):
    with pytest.raises(ExportError, match="no models"):
        export([], tmp_path / "h.glb")
    with pytest.raises(ExportError, match="Model"):
        export(["not a model"], tmp_path / "h.glb")


def test_failing_exporter_leaves_no_file(tmp_path: Path, house: Model, monkeypatch):
    def broken(models, path):
        with Staging() as stage:
            stage.write_bytes(path, b"half")
            stage.write_bytes(Path(path).with_suffix(".side"), b"x")
            raise RuntimeError("disk on fire")

    monkeypatch.setitem(EXPORTERS, "glb", broken)
    with pytest.raises(RuntimeError):
        export(house, tmp_path / "h.glb")
    assert list(tmp_path.iterdir()) == [tmp_path / "src"]  # only the fixture's texture folder


def test_failed_export_keeps_previous_files(tmp_path: Path, house: Model, monkeypatch):
    target = tmp_path / "out" / "h.obj"
    target.parent.mkdir()
    target.write_text("old\n")

    def boom(self):
        raise OSError("no space left")

    monkeypatch.setattr("facadeforge.exchange.obj._MaterialLibrary.mtl_text", boom)
    with pytest.raises(OSError):
        export(house, target)
    assert [p.name for p in target.parent.rglob("*")] == ["h.obj"]
    assert target.read_text() == "old\n"
