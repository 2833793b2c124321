"""Parser: AST shape, positions, the bad-snippet table, and fuzzing (only RuleSyntaxError escapes)."""

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from facadeforge.errors import RuleError, RuleSyntaxError
from facadeforge.grammar import ast as A
from facadeforge.grammar.parser import parse_rules


def test_rule_with_split_repeat_and_positions():
    rf = parse_rules('A --> split(y) { 4 : G | { ~3.5 : F(split.index) }* }\n', "x.cga")
    (rule,) = rf.rules
    assert rule.name == "A" and rule.line == 1 and rule.column == 1
    (op,) = rule.body
    assert isinstance(op, A.BodyOp) and op.name == "split" and not op.repeat
    first, group = op.branches
    assert first.selector == A.Num(4.0) and first.ops[0].name == "G"
    assert isinstance(group, A.RepeatGroup)
    inner = group.branches[0]
    assert inner.selector == A.Unary("~", A.Num(3.5))
    assert inner.ops[0].args == (A.Name("split.index"),)


def test_floating_applies_to_whole_expression():
    rf = parse_rules("A --> split(x) { ~w * 1.5 : B }\nattr w = 2\n")
    sel = rf.rules[0].body[0].branches[0].selector
    assert isinstance(sel, A.Unary) and sel.op == "~" and isinstance(sel.operand, A.Binary)


def test_declarations_annotations_imports():
    src = '''version "2019.0"
import F : "facade.cga"
@Range(min=1, max=10) @Group("B", 1)
attr height = 10
const c = case height > 5 : 1 else : 2
f(x, float y) = x + y ^ 2
@StartRule
Lot --> extrude(height) F.Facade X.
R(float a, string b) --> 30% : A 20% : [ t(0, 0, '0.5) B ] else : NIL
'''
    rf = parse_rules(src)
    assert rf.version == "2019.0"
    assert rf.imports[0].alias == "F" and rf.imports[0].path == "facade.cga"
    h = rf.attrs[0]
    assert h.name == "height" and [a.name for a in h.annotations] == ["Range", "Group"]
    assert rf.attrs[1].const and isinstance(rf.attrs[1].value, A.CaseExpr)
    assert rf.functions[0].params[1] == A.Param("y", "float")
    lot = rf.rules[0]
    assert lot.annotations[0].name == "StartRule"
    assert [type(o).__name__ for o in lot.body] == ["Successor", "Successor", "Leaf"]
    stoch = rf.rules[1].body[0]
    assert isinstance(stoch, A.StochasticOps) and [p for p, _ in stoch.branches] == [30.0, 20.0]


def test_comments_and_arrays():
    src = '''// line
# hash
/* block
   comment */
attr a = [1, 2, 3]
attr m = [1, 2; 3, 4]
A --> B(a[1], m[1, 0])
'''
    rf = parse_rules(src)
    assert rf.attrs[1].value.rows[1] == (A.Num(3.0), A.Num(4.0))


BAD = [
    ("A --> split(x) { 1 : B ", "unexpected end of file"),
    ("A --> B(1,)", "unexpected ')'"),
    ("A --> case x : B", "unexpected end of file"),
    ("attr = 3", "unexpected '='"),
    ("A --> B }", "unexpected '}'"),
    ("A --> B $", "unexpected character '$'"),
    ('A --> color("#fff)', "unexpected character"),
    ("A -> B", "unexpected"),
]


@pytest.mark.parametrize("src,message", BAD)
def test_bad_snippets(src, message):
    with pytest.raises(RuleSyntaxError) as e:
        parse_rules(src, "bad.cga")
    assert message in str(e.value)
    assert str(e.value).startswith("bad.cga:1:")
    assert "^" in str(e.value)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(alphabet=st.sampled_from(list("AB(){}[]|:=*~'.,;0123456789 \n-+/%!&<>\"#xyzsplitcomp")),
               max_size=80))
def test_fuzz_only_syntax_errors_escape(text):
    try:
        parse_rules(text, "fuzz.cga")
    except RuleSyntaxError:
        pass


@settings(max_examples=150, deadline=None)
@given(st.text(max_size=60))
def test_fuzz_unicode(text):
    try:
        parse_rules(text, "fuzz.cga")
    except RuleSyntaxError:
        pass


def test_a_misspelt_rule_of_an_import_gets_a_suggestion(tmp_path):
    from facadeforge import derive, load_rules

    (tmp_path / "lib.cga").write_text('Facade --> color("#ff0000") X.\nRoof --> Y.\n')
    (tmp_path / "main.cga").write_text(
        'import SU : "lib.cga"\nimport Deep : "mid.cga"\n'
        'Lot --> extrude(5) comp(f){ side: SU.Facde | top: Deep.Sx.Roof }\n')
    (tmp_path / "mid.cga").write_text('import SU : "lib.cga"\nM --> X.\n')
    m = derive(load_rules(tmp_path / "main.cga"), None, lot_size="10x8")[0]
    assert sorted(m.warnings) == [
        "rule 'Deep.Sx.Roof' is not defined (no such import: 'Deep.Sx'; did you mean "
        "'Deep.SU.Roof'?); the shape is a leaf",
        "rule 'SU.Facde' is not defined (no such rule there: 'SU'; did you mean "
        "'SU.Facade'?); the shape is a leaf"]


def test_semantic_errors_name_file_line_and_suggest():
    from facadeforge import derive, load_rules

    with pytest.raises(RuleError) as e:
        load_rules("attr height = 10\nLot --> extrude(heigth) X\n")
    assert "<rules>:2:17" in str(e.value) and "did you mean 'height'" in str(e.value)
    with pytest.raises(RuleError, match="unknown function 'flor'"):
        load_rules("Lot --> extrude(flor(2.5)) X\n")
    # a rule of an import that is not there is an undefined rule, a leaf, as in CityEngine
    # ("not necessarily a problem"), with a warning when derived
    m = derive(load_rules("Lot --> G.Facade\n"), None, lot_size="10x8")[0]
    assert m.warnings == ["rule 'G.Facade' is not defined (no such import: 'G'); the shape is "
                          "a leaf"] and [p.symbol for p in m.parts] == ["G.Facade"]
    with pytest.raises(RuleError, match=r"setback\(\) needs a \{ … \} body"):
        load_rules("Lot --> setback(3) X\n")
    with pytest.raises(RuleError, match="unknown built-in 'geometry.lowerheight'; did you mean "
                                        "'geometry.height'"):
        load_rules("Lot --> extrude(geometry.lowerheight) X\n")
    with pytest.raises(RuleError, match="start rule 'Lto' is not defined; did you mean 'Lot'"):
        load_rules("Lot --> X\n", start="Lto")
    with pytest.raises(RuleError, match="extrude\\(\\) takes 1 to 2 arguments, got 3"):
        load_rules("Lot --> extrude(1, 2, 3)\n")
    # a call no version of a rule takes is a leaf, with a warning when derived (CityEngine's
    # own rules contain such calls on rarely taken branches)
    m = derive(load_rules("Lot --> F(1, 2)\nF(a) --> X\n"), None, lot_size="4x4")[0]
    assert any("no overload with 2 parameters" in w for w in m.warnings)


def test_parser_tables_are_cached_in_the_users_folder(tmp_path, monkeypatch):
    """The LALR tables are kept in the user's private cache; a broken cache file is rebuilt."""
    from facadeforge.grammar import parser as P

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    P._parser.cache_clear()
    try:
        P._parser()
        (cached,) = (tmp_path / "facadeforge" / "parser").glob("cga-*.pickle")
        assert (cached.parent.stat().st_mode & 0o777) == 0o700
        cached.write_bytes(b"not a pickle")
        P._parser.cache_clear()
        rules = parse_rules("A --> B\n")
        assert [r.name for r in rules.rules] == ["A"]
        assert cached.read_bytes() != b"not a pickle"  # rewritten
    finally:
        P._parser.cache_clear()
