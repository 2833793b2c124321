"""facadeforge derive PROGRAM.gml: GML programs through the same engine entry and exporters."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from facadeforge import derive
from facadeforge.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "src" / "facadeforge" / "gml" / "examples"


@pytest.mark.skipif(not (EXAMPLES / "fig13.gml").is_file(), reason="GML examples not there")
def test_derive_gml_program_cli(tmp_path, capsys):
    out = tmp_path / "fig13.city.json"
    assert main(["derive", str(EXAMPLES / "fig13.gml"), "-o", str(out), "--stats"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["faces"] == 120 and s["shapes"] > 20          # Fig. 13: 20 boxes of 6 faces
    assert json.loads(out.read_text())["type"] == "CityJSON"
    # with a lot, the program runs once per initial shape, the lot's scope on the stack
    assert main(["derive", str(EXAMPLES / "fig14_arch.gml"), "--lot", "10x8",
                 "-o", str(tmp_path / "arch.glb")]) == 0
    models = derive(str(EXAMPLES / "fig13.gml"))
    assert len(models) == 1 and len(models[0].parts) > 0


def test_derive_gml_errors(tmp_path, capsys):
    bad = tmp_path / "bad.gml"
    bad.write_text("ShapeGrammar.Tools.init scope { 1 2 add\n")
    assert main(["derive", str(bad), "-o", str(tmp_path / "x.glb")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("facadeforge: error:") and "bad.gml" in err and "\n" not in err
    assert not (tmp_path / "x.glb").exists()
    assert main(["derive", str(bad), "--attr", "a=1", "-o", str(tmp_path / "x.glb")]) == 2
    assert "--attr" in capsys.readouterr().err
    # CGA rules still need an initial shape
    cga = tmp_path / "r.cga"
    cga.write_text("Lot --> extrude(3)\n")
    assert main(["derive", str(cga), "-o", str(tmp_path / "y.glb")]) == 2
    assert "--lot" in capsys.readouterr().err
