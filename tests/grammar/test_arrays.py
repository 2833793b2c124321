"""CGA arrays against the examples of CityEngine's reference pages: "array initialization
function", "colon operator", "index operator" and "Array type operators"."""

import pytest
from cga_helpers import run

A = "const array = [1,2,3,4]\nconst array2d = [1,2,3;4,5,6;7,8,9]\n"


def show(expr, pre=""):
    m = run(f"{A}{pre}Lot --> print({expr}) X.")
    assert not m.warnings, m.warnings
    return m.attributes["prints"][0]


@pytest.mark.parametrize("expr, text", [
    # array initialization function
    ('["B", "C", "D"]', "(3)[B,C,D]"),
    ('["A", ["B", "C", "D"], "E"]', "(5)[A,B,C,D,E]"),
    ("[-1 ; -2]", "(2x1)\n   -1\n   -2"),
    ("[0:2 ; 3, 3, 3]", "(2x3)\n   0   1   2\n   3   3   3"),
    ("[[-1 ; -2], [0:2 ; 3, 3, 3] ; [0:2 ; 3, 3, 3], [-1 ; -2]]",
     "(4x4)\n   -1   0   1    2\n   -2   3   3    3\n    0   1   2   -1\n    3   3   3   -2"),
    # colon operator
    ("[2 : 4]", "(3)[2,3,4]"), ("[0.5 : 3]", "(3)[0.5,1.5,2.5]"), ("[4 : 2]", "(0)[]"),
    ("[1 : 0.5 : 3]", "(5)[1,1.5,2,2.5,3]"), ("[4 : -1 : 2]", "(3)[4,3,2]"),
    ("[1 : -0.5 : 2]", "(0)[]"), ("[1 : -0.5 : 1]", "(1)[1]"), ("[1 : 0 : 1]", "(0)[]"),
    ("[0 : 0.15 : 0.5]", "(4)[0,0.15,0.3,0.45]"),
    # index operator
    ("array[0]", "1"), ("array[3]", "4"), ("array2d[1, 1]", "5"),
    ("array[[0,2]]", "(2)[1,3]"), ("array[[1,1]]", "(2)[2,2]"), ("array[3:-1:1]", "(3)[4,3,2]"),
    ("array[[0,1;2,3]]", "(2x2)\n   1   2\n   3   4"), ("array2d[1, [0,2]]", "(2)[4,6]"),
    ("array2d[[0,0,1], 2]", "(3x1)\n   3\n   3\n   6"),
    ("array2d[0:2, [0,2]]", "(3x2)\n   1   3\n   4   6\n   7   9"),
    ("array[[true,false,true]]", "(2)[1,3]"), ("array[array .> 2]", "(2)[3,4]"),
    ("array[array .> 1 .&& array .<= 3]", "(2)[2,3]"),
    ("array2d[[false,true,true], 0]", "(2x1)\n   4\n   7"),
    # an index outside the array gives the default value
    ("array[-1]", "0"), ("array[[false,false,true,true,true]]", "(3)[3,4,0]"),
    ("array2d[[2,3], -1:1]", "(2x3)\n   0   7   8\n   0   0   0"),
    ('["a"][4]', ""), ("[true][1]", "false"),
    # linear indexing of a 2D array runs along the rows
    ("array2d[3]", "4"), ("array2d[0 : size(array2d)-1]", "(9)[1,2,3,4,5,6,7,8,9]"),
    # equality and order
    ("[1,2] == [1,2]", "true"), ('["a","b"] == ["a";"b"]', "false"),
    ("[true,false] == [true,true]", "false"), ("[1,2] != [1;2]", "true"),
    ("[1,2] < [1,3]", "true"), ('["a","b"] < ["a";"b"]', "false"),
    ("[1,2] <= [1,2]", "true"), ('["a";"b"] <= ["a"]', "false"), ("[1,3] > [1,2]", "true"),
    ('["a";"b"] > ["a"]', "true"), ("[1,2,3] >= [1,2]", "true"), ('["a";"b"] >= ["a";"b"]', "true"),
    # element-wise operators
    ("array .+ 1", "(4)[2,3,4,5]"), ("array .* array", "(4)[1,4,9,16]"),
    ("array ./ 2", "(4)[0.5,1,1.5,2]"), ("array .- [1,1,1,1]", "(4)[0,1,2,3]"),
    ("array .^ 2", "(4)[1,4,9,16]"), ("array .% 2", "(4)[1,0,1,0]"),
    ("array .== 2 .|| array .== 3", "(4)[false,true,true,false]"),
    (".!(array .> 2)", "(4)[true,true,false,false]"), ("array2d .> 4",
     "(3x3)\n   false   false   false\n   false    true    true\n    true    true    true"),
    ('["a","b"] .+ "x"', "(2)[ax,bx]"),
    # string concatenation
    ('"v" + array', "v(4)[1,2,3,4]"),
])
def test_reference_examples(expr, text):
    assert show(expr) == text


def test_zip_from_the_transpose_reference():
    # a 1D array is one row: transposed, two of them stand side by side as columns
    pre = "const a = [1,1,1]\nconst b = [2,2,2]\nconst c = [transpose(a), transpose(b)]\n"
    assert show("c", pre) == "(3x2)\n   1   2\n   1   2\n   1   2"
    assert show("c[0 : size(c)-1]", pre) == "(6)[1,2,1,2,1,2]"
    assert show("transpose([a ; b]) == c", pre) == "true"
    assert show("[nRows(a), nColumns(a), nRows(c), nColumns(c)]", pre) == "(4)[1,3,3,2]"


def test_undefined_names_inside_colons_are_load_errors():
    from facadeforge import load_rules
    from facadeforge.errors import RuleError

    with pytest.raises(RuleError, match="unknown attribute or variable 'foo'"):
        load_rules("Lot --> print([0:foo]) X.")


def test_fibonacci_from_the_reference():
    pre = ("fibonacci(n) = case n <= 2 : [0:n-1]\n"
           "               else : fibonacci([0,1], n)\n"
           "fibonacci(a, n) = case size(a) == n : a\n"
           "                  else : fibonacci([a, a[size(a)-2] + a[size(a)-1]], n)\n")
    assert show("fibonacci(10)", pre) == "(10)[0,1,1,2,3,5,8,13,21,34]"


@pytest.mark.parametrize("expr, message", [
    ("array .+ [1,2]", "element-wise '.+' on arrays of different dimensions (4 and 2)"),
    ("[[1;2], 3]", "different numbers of rows (1, 2)"),
    ("[1,2 ; 3]", "the rows of an array have different lengths (1, 2)"),
    ("array < 3", "use .< to compare element by element"),
    ("[0:1e6]", "more than 100000 elements"),
    ("[-1e308 : 1e308 : 1e308]", "more than 100000 elements"),
    ("array2d[[0:999], [0:999]]", "1000 x 1000 elements, more than"),
    ('array[[""]]', "holds numbers or booleans, not strings"),
    ('["a" : "b"]', "colon operator's start must be a number"),
    ("[] + [1,2]", "'+' on arrays of different sizes (0 and 2)"),
    ('-(["a"])', "a string array cannot be negated"),
])
def test_array_misuse_is_a_warning(expr, message):
    m = run(f"{A}Lot --> print({expr}) X.")
    assert any(message in w for w in m.warnings), m.warnings


@pytest.mark.parametrize("content", [b"a;b\n1;2\n", b"a\tb\n1\t2\n", b"a  b\n1 2\n",
                                     "a,b\n1,2\n".encode("utf-16")])
def test_tables_detect_their_delimiter_and_encoding(tmp_path, content):
    from facadeforge import derive, load_rules

    (tmp_path / "t.csv").write_bytes(content)
    m = derive(load_rules('Lot --> print(readStringTable("t.csv")) print(readFloatTable("t.csv")) X.',
                          assets=tmp_path), None, lot_size="4x4")[0]
    assert m.attributes["prints"] == ["(2x2)\n   a   b\n   1   2", "(2x2)\n   nan   nan\n     1     2"]


@pytest.mark.parametrize("expr, text", [
    ("size([1e20:1:1e20])", "1"), ('"a" .== "a"', "true"), ('1 .< "a"', "true"),
    ("0 ^ -1", "inf"), ("sortRowIndices([])", "(0)[]"),
])
def test_edge_values(expr, text):
    assert show(expr) == text


def test_dot_operators_are_not_logical_selectors():
    from facadeforge import load_rules
    from facadeforge.errors import RuleError

    with pytest.raises(RuleError, match="unknown attribute or variable 'left'"):
        load_rules("Lot --> extrude(3) comp(f){ left .|| right : X. }")
