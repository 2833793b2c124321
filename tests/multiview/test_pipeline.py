"""``multiview`` end to end on a synthetic three-view building (thesis §5.4.2): the views' exact
depth as the cloud and their truth as perfect class cues, so what is measured is the frame, the
planes, the evidence, the fit and the outputs, not the stereo."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from facadeforge.cli import main
from facadeforge.datasets.views import synthetic_view_set, write_view_set
from facadeforge.errors import InputError
from facadeforge.multiview.evaluate import exact_cloud, perfect_probabilities, score
from facadeforge.multiview.pipeline import multiview
from facadeforge.points.io import write_ply


@pytest.fixture(scope="module")
def scene():
    vs = synthetic_view_set(1, n_views=3)
    photos = {k: v.rgb for k, v in zip(vs.cameras, vs.views)}
    r = multiview(photos, vs.cameras, cloud=exact_cloud(vs),
                  probabilities=perfect_probabilities(vs), budget=300)
    return vs, r


def test_frame_is_metric_and_upright(scene):
    vs, r = scene
    # the views' world is y up, in metres, cameras at 1.6 m above the ground y = 0
    assert r.frame.up_world == pytest.approx([0, 1, 0], abs=0.02)
    assert r.frame.scale == pytest.approx(1.0, rel=0.03)
    assert r.frame.scale_source.startswith("eye height")


def test_the_facade_plane_is_found_where_it_is(scene):
    vs, r = scene
    assert r.facades, r.report.get("notes")
    f = max(r.facades, key=lambda f: f.frame.width)
    n_world = f.frame.n @ r.frame.rotation
    assert n_world == pytest.approx([0, 0, 1], abs=0.03)          # facing the street
    on_plane = r.frame.to_world(f.frame.origin[None])[0]
    assert abs(on_plane[2]) < 0.1                                  # the plane z = 0
    truth = vs.truth["facades"][0]
    assert f.frame.width == pytest.approx(truth["width"], abs=1.0)


def test_the_model_lies_on_the_building(scene):
    vs, r = scene
    s = score(r, vs)
    assert s["eq_5_10_cm"]["cm"] < 15                    # every class: within 15 cm on average
    assert s["eq_5_11_cm"]["wall"]["cm"] < 8
    assert s["detection"]["tp"] > 0
    fit = r.facades[0].report["fit"]
    lo, hi = fit["alpha_range"]
    assert lo <= fit["alpha"] <= hi and fit["strength"] == pytest.approx(hi - lo, abs=1e-6)
    assert len(fit["pareto"]) >= 1 and len(fit["energies"]) == 2


def test_labels_seen_from_each_photo_match_the_truth(scene):
    vs, r = scene
    from facadeforge.datasets import get_label_set

    ls = get_label_set("ecp7")
    for cid, v in zip(vs.cameras, vs.views):
        pred = ls.from_canonical(r.labels[cid])
        ok = v.labels != 255
        assert (pred[ok] == v.labels[ok]).mean() > 0.8


def test_cli_writes_the_outdir(tmp_path, capsys):
    vs = synthetic_view_set(2, n_views=3, size=(320, 240))
    folder = write_view_set(vs, tmp_path / "set")
    write_ply(exact_cloud(vs), tmp_path / "cloud.ply")
    out = tmp_path / "out"
    rc = main(["multiview", str(folder / "img"), "--cameras", str(folder / "cameras.txt"),
               "--cloud", str(tmp_path / "cloud.ply"), "--budget", "60", "-o", str(out)])
    assert rc == 0, capsys.readouterr().err
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert "3 photos" in line and "facade" in line
    for name in ("model.glb", "model.obj", "model.city.json", "cloud.ply", "pareto.png",
                 "report.json"):
        assert (out / name).is_file(), name
    report = json.loads((out / "report.json").read_text())
    assert report["frame"]["metres_per_unit"] > 0 and report["facades"]
    for cid in vs.cameras:
        lab = np.array(Image.open(out / "labels" / f"{cid}.png"))
        assert lab.shape == vs.views[0].labels.shape and lab.max() <= 7
    assert "attr nFloors" in (out / "facade_00" / "rules.cga").read_text()
    assert (out / "facade_00" / "structure.png").is_file()


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    vs = synthetic_view_set(2, n_views=2, size=(160, 120))
    folder = write_view_set(vs, tmp_path / "set")
    with pytest.raises(InputError, match="at least two"):
        multiview({"IMG_0001": vs.views[0].rgb}, vs.cameras)
    with pytest.raises(InputError, match="no camera of that name"):
        multiview({"nope": vs.views[0].rgb, "IMG_0001": vs.views[0].rgb}, vs.cameras)
    rc = main(["multiview", str(tmp_path), "--cameras", str(folder / "cameras.txt"),
               "-o", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("facadeforge: error:")
    assert not (tmp_path / "o").exists()
