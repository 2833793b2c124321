"""Split size resolution (CityEngine semantics) and the property that splits tile their parent."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from facadeforge.grammar.ops.subdivision import RepeatItem, SizeItem, resolve_split


def items(*specs):
    out = []
    for s in specs:
        if isinstance(s, list):
            out.append(RepeatItem(items(*s)))
        else:
            kind, v = s
            out.append(SizeItem(kind, v, branch=len(out)))
    return out


def sizes(res):
    return [round(s, 6) for _, _, s in res]


def test_absolute_sizes_truncate_at_the_border():
    # 2+1+1+2+1 on 5: the 2 is cut to 1, the last is not generated (CityEngine doc example)
    res = resolve_split(items(("abs", 2), ("abs", 1), ("abs", 1), ("abs", 2), ("abs", 1)), 5)
    assert sizes(res) == [2, 1, 1, 1]


def test_zero_and_negative_sizes_are_skipped():
    res = resolve_split(items(("abs", 1.5), ("abs", -2), ("abs", 1.5), ("abs", 1.5),
                              ("abs", 0), ("abs", 1.5)), 5)
    assert sizes(res) == [1.5, 1.5, 1.5, 0.5]


def test_floating_fills_rest_and_relative():
    assert sizes(resolve_split(items(("abs", 3), ("float", 1)), 5)) == [3, 2]
    assert sizes(resolve_split(items(("float", 1.5), ("abs", 1), ("float", 1.5)), 5)) == [2, 1, 2]
    assert sizes(resolve_split(items(("rel", 0.25), ("float", 1)), 8)) == [2, 6]
    # nothing left for the float: not generated
    assert sizes(resolve_split(items(("abs", 5), ("float", 1)), 5)) == [5]


def test_repeat_rounds_to_nearest_count():
    assert sizes(resolve_split(items([("abs", 2)]), 10)) == [2] * 5
    assert sizes(resolve_split(items([("float", 2.1)]), 10)) == [2] * 5
    assert sizes(resolve_split(items([("float", 3)]), 10)) == [round(10 / 3, 6)] * 3
    # absolute-only repeats tile and cut the last copy
    assert sizes(resolve_split(items([("abs", 2)]), 5)) == [2, 2, 1]


def test_nested_repeat_between_floats():
    res = resolve_split(items(("float", 1), [("abs", 2), ("float", 1)], ("float", 1)), 10)
    # n = rint(8 / 3) = 3; fixed 6, floats share 4 over 5 nominal units
    assert sizes(res) == [0.8, 2, 0.8, 2, 0.8, 2, 0.8, 0.8]
    res = resolve_split(items(("abs", 4), [("float", 3.5)]), 18)
    assert sizes(res)[0] == 4 and len(res) == 5 and np.isclose(sum(sizes(res)), 18)


size_spec = st.one_of(st.tuples(st.just("abs"), st.floats(0.1, 5)),
                      st.tuples(st.just("rel"), st.floats(0.01, 0.5)),
                      st.tuples(st.just("float"), st.floats(0.1, 5)))


@settings(max_examples=200, deadline=None)
@given(st.lists(size_spec, min_size=1, max_size=5), st.lists(size_spec, min_size=1, max_size=3),
       st.floats(0.5, 60), st.booleans())
def test_pieces_are_contiguous_inside_and_fill_when_floating(top, pattern, total, with_repeat):
    specs = list(top) + ([list(pattern)] if with_repeat else [])
    res = resolve_split(items(*specs), total)
    pos = 0.0
    for _, start, size in res:
        assert size > 0
        assert start == pytest.approx(pos, abs=1e-9)
        pos = start + size
    assert pos <= total + 1e-9
    has_float = any(k == "float" for k, _ in top) or (with_repeat and any(k == "float" for k, _ in pattern))
    fixed = sum(v * (total if k == "rel" else 1) for k, v in top if k != "float")
    if has_float and fixed < total - 1e-6 and res:
        assert pos == pytest.approx(total, rel=1e-9, abs=1e-9)
