"""CLI in-process (cjio habit): every command, its one-line errors and exit codes."""

import json
from pathlib import Path

import pytest

from facadeforge.cli import main

GRAMMAR = "Lot --> extrude(6) comp(f) { side : Facade | top : Roof. | bottom : NIL }\n" \
          "Facade --> split(y) { { ~3 : split(x) { { ~2 : Tile }* } }* }\n" \
          "Tile --> report(\"tiles\", 1) color(\"#aa8866\")\n"


@pytest.fixture
def rules(tmp_path):
    p = tmp_path / "b.cga"
    p.write_text(GRAMMAR)
    return p


def test_derive_stats_json(rules, tmp_path, capsys):
    out = tmp_path / "b.glb"
    assert main(["derive", str(rules), "--lot", "10x6", "-o", str(out), "--stats"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["faces"] == len(s["report"]["tiles"]) + 1  # tiles + roof
    assert s["bbox"] == [[0, 0, 0], [10, 6, 6]]
    assert s["area"] == pytest.approx(2 * (10 + 6) * 6 + 60)
    assert out.exists()


def test_derive_geojson_many_footprints_in_parallel(rules, tmp_path, capsys):
    feats = []
    for i in range(5):
        x = i * 20.0
        ring = [[x, 0], [x + 10, 0], [x + 10, 8], [x, 8], [x, 0]]
        feats.append({"type": "Feature", "properties": {"name": f"b{i}"},
                      "geometry": {"type": "Polygon", "coordinates": [ring]}})
    fp = tmp_path / "lots.geojson"
    fp.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    out = tmp_path / "city.city.json"
    assert main(["derive", str(rules), "--footprint", str(fp), "-o", str(out), "--stats",
                 "--workers", "2"]) == 0
    s = json.loads(capsys.readouterr().out)
    # GeoJSON y maps to −z: the lots span z in [−8, 0]
    assert s["bbox"][0][2] == pytest.approx(-8) and s["bbox"][1][2] == pytest.approx(0)
    assert s["bbox"][1][0] == pytest.approx(90)
    city = json.loads(out.read_text())
    assert len([o for o in city["CityObjects"].values() if o["type"] == "Building"]) == 5


@pytest.mark.parametrize("argv,needle", [
    (["derive", "missing.cga", "--lot", "10x6", "-o", "x.glb"], "does not exist"),
    (["derive", "{rules}", "--lot", "10by6", "-o", "x.glb"], "WIDTHxDEPTH"),
    (["derive", "{rules}", "--lot", "10x6", "-o", "x.xyz"], "x.xyz"),
    (["derive", "{rules}", "--lot", "10x6", "--attr", "nope=1", "-o", "x.glb"], "no attribute 'nope'"),
    (["derive", "{bad}", "--lot", "10x6", "-o", "x.glb"], "bad.cga:1:"),
    (["render", "missing.glb", "-o", "x.png"], "missing.glb"),
])
def test_errors_are_one_line(argv, needle, rules, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    bad = tmp_path / "bad.cga"
    bad.write_text("Lot --> split(x) { 1 : A \n")
    argv = [a.format(rules=rules, bad=bad) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("facadeforge: error:") and needle in err[0]
    assert not (tmp_path / "x.glb").exists()


def test_render_and_demo(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert "faces" in out
    for name in ("building.glb", "building.obj", "building.city.json", "preview.png"):
        assert (tmp_path / "demo" / name).stat().st_size > 0
    assert (tmp_path / "demo" / "reconstruction" / "preview.png").is_file()
    assert "staging" not in out and sorted(p.name for p in tmp_path.iterdir()) == ["demo"]
    report = json.loads((tmp_path / "demo" / "reconstruction" / "report.json").read_text())
    assert report["input"]["photo"].startswith(str(tmp_path / "demo" / "synthetic"))
    png = tmp_path / "again.png"
    assert main(["render", str(tmp_path / "demo" / "building.glb"), "-o", str(png),
                 "--size", "320x240"]) == 0
    from PIL import Image

    assert Image.open(png).size == (320, 240)
    # the demo's folder is facadeforge's: a file put there makes the next demo stop at once
    (tmp_path / "demo" / "notes.txt").write_text("mine")
    assert main(["demo", "-o", str(tmp_path / "demo")]) == 2
    assert "notes.txt" in capsys.readouterr().err
    assert (tmp_path / "demo" / "notes.txt").read_text() == "mine"


def _photo(path):
    import numpy as np
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.full((80, 80, 3), 128, np.uint8)).save(path)
    return path


@pytest.mark.parametrize("command", ["reconstruct", "parse"])
def test_an_output_folder_holding_the_photo_is_refused(tmp_path, capsys, command):
    """The reproducer: ``reconstruct same/texture.jpg --rectified -o same`` overwrote the
    photo with the texture it wrote."""
    photo = _photo(tmp_path / "same" / "texture.jpg")
    before = photo.read_bytes()
    assert main([command, str(photo), "--rectified", "-o", str(tmp_path / "same")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is inside the output folder" in err[0] and "-o" in err[0]
    assert photo.read_bytes() == before and [p.name for p in photo.parent.iterdir()] == [
        "texture.jpg"]


def test_a_folder_given_as_the_photo_says_so(tmp_path, capsys):
    photos = tmp_path / "photos"
    _photo(photos / "a.png")
    assert main(["reconstruct", str(photos), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "is a folder, not an image file" in err and str(photos / "a.png") in err
    assert "does not exist" not in err


def test_render_views_from_above(tmp_path):
    """--elevation moves the camera (another picture of the same model); a bad angle is a usage
    error."""
    from pathlib import Path

    import numpy as np
    from PIL import Image

    glb = tmp_path / "b.glb"
    rules = Path(__file__).resolve().parents[1] / "examples" / "grammars" / "building.cga"
    assert main(["derive", str(rules), "--lot", "24x14", "-o", str(glb)]) == 0
    low, high = tmp_path / "low.png", tmp_path / "high.png"
    assert main(["render", str(glb), "-o", str(low), "--size", "200x150"]) == 0
    assert main(["render", str(glb), "-o", str(high), "--size", "200x150", "--elevation", "80"]) == 0
    assert not np.array_equal(np.asarray(Image.open(low)), np.asarray(Image.open(high)))
    with pytest.raises(SystemExit):
        main(["render", str(glb), "-o", str(high), "--elevation", "up"])


def test_derive_does_not_import_the_dataset_and_training_code():
    """``derive`` and ``render`` build only their own parser: the dataset, training and
    benchmark modules (0.7 s of imports) stay unloaded; the full help still lists them all."""
    import subprocess
    import sys

    code = ("import sys; from facadeforge.cli import build_parser; p = build_parser('derive'); "
            "print(sorted(m for m in ('facadeforge.datasets', 'facadeforge.classify.train', "
            "'facadeforge.evaluation.bench') if m in sys.modules)); "
            "print(sorted(build_parser(None)._subparsers._group_actions[0].choices))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    assert out[0] == "[]"
    assert "train-classifier" in out[1] and "synth" in out[1] and "bench" in out[1]


def test_derive_never_writes_over_its_footprints(rules, tmp_path, capsys):
    lots = tmp_path / "lots.obj"
    lots.write_text("v 0 0 0\nv 10 0 0\nv 10 0 6\nv 0 0 6\nf 1 4 3 2\n")
    before = lots.read_bytes()
    assert main(["derive", str(rules), "--footprint", str(lots), "-o", str(lots)]) == 2
    assert "is the --footprint file the run reads" in capsys.readouterr().err
    assert lots.read_bytes() == before


@pytest.mark.parametrize("name, text, message", [
    ("meta", "[" * 100_000 + "]" * 100_000, "synthetic metadata '{p}': JSON nested too deeply"),
    ("objects", '{"label": ', "synthetic objects '{p}' is not valid JSON (line 1"),
])
def test_demo_reads_its_facade_files_through_the_json_reader(tmp_path, monkeypatch, name, text,
                                                             message):
    """Bare json.loads made a damaged file a RecursionError or a bare JSONDecodeError."""
    from facadeforge import cli
    from facadeforge.datasets import synthetic
    from facadeforge.errors import InputError

    def generate(n, seed, out_dir, **options):
        out = Path(out_dir)
        out.mkdir(parents=True)
        for suffix in ("meta", "objects"):
            (out / f"s.{suffix}.json").write_text("{}" if suffix == "meta" else "[]",
                                                  encoding="utf-8-sig")
        (out / f"s.{name}.json").write_text(text)
        return [out / "s.jpg"]

    monkeypatch.setattr(synthetic, "generate", generate)
    with pytest.raises(InputError) as err:
        cli._demo_reconstruct(tmp_path / "stage", tmp_path / "out")
    p = tmp_path / "stage" / "synthetic" / f"s.{name}.json"
    assert message.format(p=p) in str(err.value)
    assert str(err.value).endswith("run facadeforge demo again")
