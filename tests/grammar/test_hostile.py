"""Hostile and careless rule files (issue 33): each test is built from a reproducer that read a
file outside the project, hung, filled the memory, lost data silently or wrote invalid files."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from facadeforge.cli import main
from facadeforge.engine import derive, load_rules
from facadeforge.errors import DerivationError, RuleSyntaxError
from facadeforge.exchange import ExportError, LoadError, export, load
from facadeforge.grammar.interpreter import Limits
from facadeforge.grammar.parser import MAX_BRACKETS, MAX_NESTING, parse_rules

SECRET = "BEGIN PRIVATE KEY do-not-leak"


def _project(home):
    """``home/proj`` a CityEngine project (rules/ beside assets/) and ``home/id_rsa``."""
    (home / "proj" / "rules").mkdir(parents=True)
    (home / "proj" / "assets").mkdir()
    (home / "id_rsa").write_text(SECRET)
    return home / "proj"


def _run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


# -- 1. file functions stay inside the project ---------------------------------------------

@pytest.mark.parametrize("call", [
    'label(readTextFile("../../id_rsa"))',
    'label(readTextFile("{home}/id_rsa"))',
    'label(str(readStringTable("../../id_rsa")))',
    'label(str(fileExists("../../id_rsa")))',
    'label(fileSearch("*id_rsa*"))',
    'texture("../../id_rsa")',
])
def test_rule_text_reads_nothing_above_its_project(tmp_path, capsys, call):
    proj = _project(tmp_path)
    rule = proj / "rules" / "evil.cga"
    rule.write_text(f"Lot --> {call.format(home=tmp_path)} X.\n")
    for out in ("o.city.json", "o.glb"):
        rc, _, err = _run(capsys, "derive", rule, "--lot", "10x10", "-o", tmp_path / out)
        assert rc == 0, err
        data = (tmp_path / out).read_bytes()
        assert SECRET.encode() not in data
        assert b"do-not-leak" not in data


def test_project_files_and_assets_still_resolve(tmp_path):
    proj = _project(tmp_path)
    (proj / "assets" / "name.txt").write_text("from-assets")
    (proj / "data").mkdir()
    (proj / "data" / "t.csv").write_text("a,b\n")
    rule = proj / "rules" / "ok.cga"
    rule.write_text('Lot --> label(readTextFile("name.txt") + readStringTable('
                    f'"/{proj.name}/data/t.csv")[0]) X.\n')
    m = derive(load_rules(rule), lot_size="4x4")[0]
    assert m.parts[0].label == "from-assetsa", m.warnings


def test_hidden_files_are_never_read(tmp_path):
    proj = _project(tmp_path)
    (proj / "assets" / ".env").write_text(SECRET)
    (proj / "assets" / ".git").mkdir()
    (proj / "assets" / ".git" / "config").write_text(SECRET)
    rule = proj / "rules" / "r.cga"
    rule.write_text('Lot --> label(readTextFile(".env") + fileSearch("*")'
                    ' + readTextFile(".git/config")) X.\n')
    m = derive(load_rules(rule), lot_size="4x4")[0]
    assert SECRET not in m.parts[0].label
    assert any("leaves the asset root" in w for w in m.warnings)


def test_rule_in_a_shared_folder_reads_nothing_beside_it(tmp_path, monkeypatch):
    # a rule file lying directly in the temporary folder (or the home folder) must not read
    # other people's files there
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    (tmp_path / "other-user.txt").write_text(SECRET)
    rule = tmp_path / "evil.cga"
    rule.write_text(f'Lot --> label(readTextFile("other-user.txt") + '
                    f'readTextFile("{tmp_path}/other-user.txt")) X.\n')
    m = derive(load_rules(rule), lot_size="4x4")[0]
    assert SECRET not in m.parts[0].label


def test_imports_stay_inside_the_project(tmp_path):
    proj = _project(tmp_path)
    (tmp_path / "outside.cga").write_text("X --> Y.\n")
    rule = proj / "rules" / "r.cga"
    rule.write_text('import o : "../../outside.cga"\nLot --> o.X\n')
    with pytest.raises(Exception, match="outside the rule's project"):
        load_rules(rule)
    # CGA text has no project: it imports nothing by absolute path
    with pytest.raises(Exception, match="outside the rule's project|cannot import"):
        load_rules(f'import o : "{tmp_path}/outside.cga"\nLot --> o.X\n')


# -- 2. hangs: every call and operation draws on the time budget ------------------------------

def test_function_that_calls_itself_twice_meets_the_time_cap():
    rules = load_rules("f(n) = case n > 0 : f(n - 1) + f(n - 1) else : 1\n"
                       "Lot --> extrude(f(40)) X.\n")
    with pytest.raises(DerivationError, match=r"longer than 0.5 s \(while in function 'f'"):
        derive(rules, lot_size="10x10", limits=Limits(max_seconds=0.5))


def test_inlined_runaway_recursion_meets_the_time_cap():
    rules = load_rules("Lot --> inline(append){ split(x){ ~1 : A | ~1 : A } }\n"
                       "A --> split(x){ ~1 : A | ~1 : A }\n")
    with pytest.raises(DerivationError, match="longer than 0.5 s|more than"):
        derive(rules, lot_size="10x10", limits=Limits(max_seconds=0.5))


def test_a_long_split_of_a_mass_meets_the_time_cap():
    # 50,000 slabs of a closed box: minutes inside one operation before it was checked
    rules = load_rules("Lot --> extrude(10) split(x){0.02: comp(f){all: A}}*\n")
    with pytest.raises(DerivationError, match="longer than 0.5 s"):
        derive(rules, lot_size="1000x10", limits=Limits(max_seconds=0.5))


HANG_SCRIPT = textwrap.dedent("""
    import sys
    from facadeforge.grammar.parser import parse_rules
    from facadeforge.errors import RuleSyntaxError
    n = 200_000
    sources = [
        "Lot --> extrude(" + "9" * n + ") X.",             # percentage pattern: quadratic
        "Lot --> A" + " " * n + "B",                         # rule-head lookahead: quadratic
        "Lot --> inline" + " " * n + "(x)",
        'Lot --> X("' + "a" * (40 * n) + '")',              # strings and comments held a
        "/*" + "a" * (40 * n) + "*/ Lot --> X.",            # backtracking state a character
        'Lot --> X("' + "a" * n,
        "/*" + "*" * n,
    ]
    for s in sources:
        try:
            parse_rules(s)
        except RuleSyntaxError:
            pass
    print("done")
""")


def test_lexer_is_linear_on_long_runs():
    # quadratic patterns took 11 s for 20,000 digits (20 min for these); linear ones take
    # well under a second each.  The bound is a hang detector, not a speed target.
    r = subprocess.run([sys.executable, "-c", HANG_SCRIPT], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "done", r.stderr


def test_token_bracket_and_nesting_caps_name_the_position():
    with pytest.raises(RuleSyntaxError, match=f"deeper than {MAX_BRACKETS}") as e:
        parse_rules("Lot --> extrude(" + "(" * 600 + "1" + ")" * 600 + ") X.")
    assert e.value.line == 1 and e.value.column > 100
    with pytest.raises(RuleSyntaxError, match=f"more than {MAX_NESTING:,}") as e:
        parse_rules("Lot --> extrude(" + "+".join(["1"] * 5000) + ") X.")
    assert e.value.line == 1
    with pytest.raises(RuleSyntaxError, match="more than 250,000 tokens"):
        parse_rules("Lot --> " + "a " * 260_000)


def test_an_expression_of_a_thousand_terms_derives():
    m = derive(load_rules("Lot --> extrude(" + "+".join(["0.01"] * 1000) + ") X."),
               lot_size="2x2")[0]
    assert m.stats()["bbox"][1][1] == pytest.approx(10.0)


def test_byte_order_mark_is_accepted(tmp_path):
    p = tmp_path / "bom.cga"
    p.write_bytes(b"\xef\xbb\xbfLot --> extrude(3) X.\n")
    assert derive(load_rules(p), lot_size="2x2")[0].stats()["bbox"][1][1] == 3.0


# -- 3. memory: strings, files and the process's growth ---------------------------------------

def test_string_that_doubles_itself_is_stopped():
    rules = load_rules('attr s = "ab"\nLot --> A(s)\nA(s) --> A(s + s)\n')
    with pytest.raises(DerivationError, match="longer than the 16,777,216"):
        derive(rules, lot_size="2x2")


def test_replace_cannot_grow_a_string_without_end():
    rules = load_rules('Lot --> A("a")\nA(s) --> A(replace(s, "a", "aaaaaaaa"))\n')
    with pytest.raises(DerivationError, match="characters is longer"):
        derive(rules, lot_size="2x2")


def test_large_text_table_and_texture_files_are_refused(tmp_path):
    big = tmp_path / "big.csv"
    with open(big, "wb") as fh:  # sparse: no disk, no time
        fh.truncate(17 * 1024 * 1024)
    tex = tmp_path / "big.png"
    with open(tex, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n")
        fh.truncate(129 * 1024 * 1024)
    rules = load_rules('Lot --> label(readTextFile("big.csv")) A\n'
                       'A --> label(str(readStringTable("big.csv"))) texture("big.png") X.\n',
                       assets=tmp_path)
    m = derive(rules, lot_size="2x2")[0]
    text = " ".join(m.warnings)
    assert "larger than the 16 MiB" in text and "larger than 128 MiB" in text
    assert m.parts[0].material.texture is None


def test_memory_budget_stops_a_derivation_that_grows_past_it():
    rules = load_rules("Lot --> split(x){0.002: A}*\n")
    with pytest.raises(DerivationError, match="more than 40 MiB of memory"):
        derive(rules, lot_size="1000x10", limits=Limits(max_memory_mb=40))


# -- 4. silent data loss ----------------------------------------------------------------------

def test_a_repeat_is_never_cut_short_silently():
    with pytest.raises(DerivationError, match="makes 10,000,000 pieces"):
        derive(load_rules("Lot --> split(x){0.0001: B}*"), lot_size="1000x1")
    with pytest.raises(DerivationError, match="makes 10,000,000 pieces"):
        derive(load_rules("Lot --> extrude(1e7) split(y){1: X.}*"), lot_size="10x10")


@pytest.mark.parametrize("size", ["1e-300", "~1e-9", "'1e-30"])
def test_a_repeat_of_no_length_warns(size):
    m = derive(load_rules(f"Lot --> split(x){{ 2 : A | {{{size}: B}}* }}"), lot_size="10x10")[0]
    assert any("makes no pieces" in w for w in m.warnings)
    assert [p.symbol for p in m.parts] == ["A"]  # the rest of the split is still made


# -- 5. numbers checked before they reach a file ----------------------------------------------

def test_absurd_coordinates_are_refused_before_any_file(tmp_path, capsys):
    rule = tmp_path / "inf.cga"
    rule.write_text("Lot --> extrude(1e300) X.\n")
    for out in ("o.glb", "o.city.json", "o.obj"):
        rc, outtext, err = _run(capsys, "derive", rule, "--lot", "10x10", "-o", tmp_path / out,
                                "--stats")
        assert rc == 2 and err.startswith("facadeforge: error:") and err.count("\n") == 1
        assert "beyond ±1e+09 m" in err
        assert not (tmp_path / out).exists()


def test_exporters_and_loaders_refuse_non_finite_models(tmp_path):
    m = derive(load_rules("Lot --> extrude(3) X."), lot_size="2x2")[0]
    export(m, tmp_path / "ok.glb")
    m.parts[0].mesh.vertices[0, 1] = np.inf
    del m.derived_stats  # the statistics of the derivation, which are now out of date
    for name in ("bad.glb", "bad.city.json", "bad.obj"):
        with pytest.raises(ExportError, match="not finite"):
            export(m, tmp_path / name)
        assert not (tmp_path / name).exists()
    # a GLB written elsewhere with an infinite coordinate: a clear error, not an IndexError
    import pygltflib as gl

    g = gl.GLTF2().load(str(tmp_path / "ok.glb"))
    blob = bytearray(g.binary_blob())
    acc = g.accessors[g.meshes[0].primitives[0].attributes.POSITION]
    off = (g.bufferViews[acc.bufferView].byteOffset or 0) + (acc.byteOffset or 0)
    blob[off:off + 4] = np.float32(np.inf).tobytes()
    g.set_binary_blob(bytes(blob))
    g.save(str(tmp_path / "inf.glb"))
    with pytest.raises(LoadError, match="not finite"):
        load(tmp_path / "inf.glb")


def test_stats_are_json_even_when_reports_are_not_numbers(tmp_path, capsys):
    rule = tmp_path / "nan.cga"
    rule.write_text('Lot --> report("r", 0/0) report("s", 1/0) X.\n')
    rc, out, err = _run(capsys, "derive", rule, "--lot", "4x4", "-o", tmp_path / "o.glb",
                        "--stats")
    assert rc == 0, err
    stats = json.loads(out, parse_constant=lambda c: pytest.fail(f"{c} is not JSON"))
    assert stats["report"] == {"r": [None], "s": [None]}


def test_cli_limits_are_flags(tmp_path, capsys):
    rule = tmp_path / "f.cga"
    rule.write_text("f(n) = case n > 0 : f(n - 1) + f(n - 1) else : 1\nLot --> extrude(f(40)) X.\n")
    rc, _, err = _run(capsys, "derive", rule, "--lot", "4x4", "-o", tmp_path / "o.glb",
                      "--max-seconds", "0.5")
    assert rc == 2 and "longer than 0.5 s" in err and err.count("\n") == 1


@pytest.mark.parametrize("call", ["primitiveSphere(2000, 2000)", "primitiveCylinder(3000000)",
                                  "primitiveCone(1e300)"])
def test_primitive_resolution_is_bounded(call):
    # the faces are built in Python: 2000 x 2000 subdivisions took minutes, unchecked
    m = derive(load_rules(f"Lot --> {call}\n"), lot_size="4x4")[0]
    assert any("more than 100,000 faces" in w for w in m.warnings)


def test_library_warnings_stay_off_the_error_line(tmp_path, capfd):
    # numpy's overflow warnings on absurd sizes used to come before the one error line
    rule = tmp_path / "r.cga"
    rule.write_text("Lot --> s(1e300, 1, 1) extrude(1e300)\n")
    rc = main(["derive", str(rule), "--lot", "4x4", "-o", str(tmp_path / "o.glb")])
    err = capfd.readouterr().err
    assert rc == 2 and err.startswith("facadeforge: error:") and err.count("\n") == 1, err
