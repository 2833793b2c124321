"""CGA styles: ``style Name [extends Base]`` sections replace the base style's declarations;
the Default style (everything before the first ``style``) is derived unless another is chosen."""

from __future__ import annotations

import numpy as np
import pytest

from facadeforge import RuleError, RuleSyntaxError, derive
from facadeforge.cli import main

RULES = """version "2023.0"
attr height = 10
attr tint = "#ff0000"
@StartRule
Lot --> extrude(height) Mass
Mass --> color(tint) Paint
Paint --> X.

style Night
attr height = 20
attr tint = "#000000"

style Storm extends Night
Mass --> split(y) { 5 : Band | ~1 : Paint }
Band --> color("#0000ff")
"""


def _top_and_colours(style=None):
    (m,) = derive(RULES, lot_size="10x10", style=style)
    top = max(float(p.mesh.vertices[:, 1].max()) for p in m.parts)
    colours = sorted({tuple(np.round(p.material.color, 2)) for p in m.parts})
    return top, colours


def test_default_style_ignores_the_style_sections():
    top, colours = _top_and_colours()
    assert top == pytest.approx(10.0) and colours == [(1.0, 0.0, 0.0)]
    assert _top_and_colours("Default") == (top, colours)


def test_a_style_replaces_attributes_and_an_extending_style_rules():
    top, colours = _top_and_colours("Night")
    assert top == pytest.approx(20.0) and colours == [(0.0, 0.0, 0.0)]
    # Night's height, Storm's own Mass rule (a blue band, the rest uncoloured: white)
    top, colours = _top_and_colours("Storm")
    assert top == pytest.approx(20.0)
    assert colours == [(0.0, 0.0, 1.0), (1.0, 1.0, 1.0)]


@pytest.mark.parametrize("text, style, exc, message", [
    (RULES, "Day", RuleError, "unknown style 'Day'.*Default, Night, Storm"),
    (RULES + "style Fog extends Haze\nLot --> X.\n", "Fog", RuleError,
     "style 'Fog' extends unknown style 'Haze'"),
    (RULES + "style A extends B\nstyle B extends A\n", "A", RuleError, "extends itself"),
    (RULES + "style Night\n", None, RuleSyntaxError, "style 'Night' is declared twice"),
])
def test_style_errors(text, style, exc, message):
    with pytest.raises(exc, match=message):
        derive(text, lot_size="10x10", style=style)


def test_cli_style(tmp_path, capsys):
    rules = tmp_path / "styled.cga"
    rules.write_text(RULES)
    out = tmp_path / "m.obj"
    assert main(["derive", str(rules), "--lot", "10x10", "--style", "Night", "-o", str(out),
                 "--stats"]) == 0
    import json

    stats = json.loads(capsys.readouterr().out)
    assert stats["bbox"][1][1] == pytest.approx(20.0)
    assert main(["derive", str(rules), "--lot", "10x10", "--style", "Day", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown style 'Day'" in err[0]


def test_the_chosen_styles_start_rule_comes_first():
    rules = ('@StartRule\nLot --> extrude(5) A\nA --> X.\n'
             'style Tall\n@StartRule\nOther --> extrude(30) B\nB --> Y.\n')
    (m,) = derive(rules, lot_size="10x10")
    assert {p.symbol for p in m.parts} == {"X"}
    (m,) = derive(rules, lot_size="10x10", style="Tall")
    assert {p.symbol for p in m.parts} == {"Y"}


def test_style_belongs_to_loading():
    from facadeforge import InputError, load_rules

    with pytest.raises(InputError, match="load_rules"):
        derive(load_rules(RULES), lot_size="10x10", style="Night")
    (m,) = derive(load_rules(RULES, style="Night"), lot_size="10x10")
    assert max(float(p.mesh.vertices[:, 1].max()) for p in m.parts) == pytest.approx(20.0)
