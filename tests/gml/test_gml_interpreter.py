"""The GML interpreter: tokens, operators, variables, control, errors with line:column, limits."""

from __future__ import annotations

import pytest

from facadeforge.errors import FacadeForgeError
from facadeforge.gml.errors import GmlLimitError, GmlRuntimeError, GmlSyntaxError
from facadeforge.gml.interpreter import Interpreter, Limits, Name, Point
from facadeforge.gml.tokens import parse, restore_typography, tokenize


def run(text: str, limits: Limits | None = None) -> list:
    it = Interpreter(limits)
    it.run(parse(text))
    return it.stack


def test_tokens_kinds_and_positions():
    toks = tokenize("1 -0.5 /X !w :w (1,2,3) [ ] split-r % comment\n  ShapeGrammar.Tools.init")
    kinds = [t.kind for t in toks]
    assert kinds == ["number", "number", "literal", "bind", "get", "point", "[", "]", "name",
                     "name"]
    assert toks[0].value == 1 and type(toks[0].value) is int and toks[1].value == -0.5
    assert toks[5].value == (1.0, 2.0, 3.0)
    assert (toks[-1].line, toks[-1].column) == (2, 3)
    assert tokenize("(1,2)")[0].value == (1.0, 2.0, 0.0)


def test_restore_typography():
    assert restore_typography("terminal\u2014box") == "terminal-box"


def test_arithmetic_and_comparisons():
    assert run("1 2 add 3 mul 4 sub 2 div") == [2.5]
    assert run("7 2 mod 7 2 idiv -3 abs 9 sqrt 2.5 floor 2.5 ceil 1 2 min 1 2 max 5 neg") == [
        1, 3, 3, 3.0, 2, 3, 1, 2, -5]
    assert run("1 2 lt 2 2 le 1 2 gt 2 2 ge 1 1 eq 1 2 ne") == [True, True, False, True, True,
                                                                   True]
    assert run("true false and true false or true not") == [False, True, False]
    assert run("90 sin 0 cos 1 1 atan") == [1.0, 1.0, 45.0]


def test_points():
    assert run("(1,2,3) (1,1,1) add 2 mul") == [Point((4, 6, 8))]
    assert run("(1,2,3) (1,1,1) mul") == [6.0]  # point · point: the dot product
    assert run("(1,2,3) dup getx exch gety") == [1.0, 2.0]
    assert run("(1,0,0) (0,1,0) cross 1 2 3 vector3 getz") == [Point((0, 0, 1)), 3.0]
    assert run("(1,2,3) neg (2,4,6) 2 div") == [Point((-1, -2, -3)), Point((1, 2, 3))]


def test_stack_ops():
    assert run("1 2 exch") == [2, 1]
    assert run("1 2 3 2 copy") == [1, 2, 3, 2, 3]
    assert run("1 2 3 2 index") == [1, 2, 3, 1]
    assert run("1 2 3 3 1 roll") == [3, 1, 2]
    assert run("1 2 pop dup clear 5 count") == [5, 1]


def test_arrays_and_dicts():
    assert run("[ 1 2 3 ] length") == [3]
    assert run("[ 1 2 1 1 add ] 2 get") == [2]
    assert run("3 array dup 1 9 put") == [[0, 9, 0]]
    assert run("[ 4 5 ] aload pop add") == [9]
    assert run("dict begin /a 3 def a end") == [3]
    assert run("/a 1 def dict begin /a 2 def a end a") == [2, 1]


def test_variables_as_in_fig16():
    assert run("1.2 !window-width :window-width 2 mul") == [2.4]
    # :name pushes a procedure without running it; the bare name runs it
    assert len(run("/f { 1 2 add } def :f")) == 1
    assert run("/f { 1 2 add } def f") == [3]


def test_control():
    assert run("1 2 lt { 10 } if 1 2 gt { 20 } if") == [10]
    assert run("false { 1 } { 2 } ifelse") == [2]
    assert run("0 5 { 1 add } repeat") == [5]
    assert run("0 1 1 4 { add } for") == [10]
    assert run("0 [ 1 2 3 ] { add } forall") == [6]
    assert run("0 { 1 add dup 7 eq { exit } if } loop") == [7]
    assert run("/x { 1 add } def 1 /x exec { 2 mul } exec") == [4]
    assert run("/Name 2 def /Name") == [Name("Name")]


def test_recursion_by_name():
    # factorial, recursive through the dictionary
    assert run("/fact { dup 1 le { pop 1 } { dup 1 sub fact mul } ifelse } def 10 fact") == [
        3628800]


@pytest.mark.parametrize("text, kind, line, col", [
    ("1 2 ad", "name", 1, 5),
    ("1 add", "underflow", 1, 3),
    ("1 /x add", "type", 1, 6),
    ("1 0 div", "zero", 1, 5),
    ("[ 1 2 ] 5 get", "range", 1, 11),
    ("\n  exit", "range", 2, 3),
    ("-1 sqrt", "range", 1, 4),
])
def test_runtime_errors_have_kind_and_position(text, kind, line, col):
    with pytest.raises(GmlRuntimeError) as e:
        run(text)
    assert (e.value.kind, e.value.line, e.value.column) == (kind, line, col)
    assert f":{line}:{col}:" in str(e.value)


def test_did_you_mean():
    with pytest.raises(GmlRuntimeError, match="did you mean 'window-width'"):
        run("1 !window-width window-widht")


@pytest.mark.parametrize("text, line, col", [
    ("{ 1 2", 1, 1), ("1 }", 1, 3), ("[ 1", 1, 1), ("1 ]", 1, 3), ("{ [ }", 1, 5),
    ("(1,2", 1, 1), ("(a,b,c)", 1, 1), ("/ x", 1, 1), ("1 ! 2", 1, 3),
])
def test_syntax_errors(text, line, col):
    with pytest.raises(GmlSyntaxError) as e:
        parse(text)
    assert (e.value.line, e.value.column) == (line, col)


@pytest.mark.parametrize("text, limit, limits", [
    ("{ 1 } loop", "max_stack", Limits(max_stack=1000)),
    ("{ } loop", "max_operations", Limits(max_operations=10_000)),
    ("1000000000 { } repeat", "max_operations", Limits(max_operations=10_000)),
    ("0 1 1000000000 { pop } for", "max_operations", Limits(max_operations=10_000)),
    ("1000 array { pop } forall", "max_operations", Limits(max_operations=500)),
    ("/f { f 1 } def f", "max_call_depth", Limits(max_call_depth=100)),
    ("/f { 1 f } def f", "max_stack", Limits(max_stack=1000)),  # tail call: no nesting
    ("1000 array", "max_array", Limits(max_array=100)),
    ("{ 100 array pop } loop", "max_cells", Limits(max_cells=10_000)),
    ("{ dict begin } loop", "max_dict_stack", Limits(max_dict_stack=50)),
    ("{ 1 pop } loop", "max_seconds", Limits(max_seconds=0.2)),
])
def test_limits(text, limit, limits):
    with pytest.raises(GmlLimitError) as e:
        run(text, limits)
    assert e.value.limit == limit and f"Limits({limit}=" in str(e.value)
    assert isinstance(e.value, FacadeForgeError)


def test_limits_validate():
    with pytest.raises(ValueError):
        Limits(max_operations=0)
