"""The vectorised number formatting of the text exporters against Python's ``%`` formatting."""

import re

import numpy as np
import pytest

from facadeforge.exchange._ascii import _reference, format_lines


def _same_text(got: bytes, want: bytes) -> None:
    # the one documented difference: a value that rounds to zero has no sign
    assert got == re.sub(rb"-(0(\.0+)?)(?=[\s/])", rb"\1", want)


@pytest.mark.parametrize("precision", [0, 1, 3, 6])
@pytest.mark.parametrize("magnitude", [1e-3, 1.0, 30.0, 5e3, 1e6])
def test_rows_match_python_formatting(precision, magnitude):
    rng = np.random.default_rng(7)
    # off the rounding ties, where the documented last-place difference could show
    values = np.round(rng.normal(size=(200, 3)) * magnitude, precision + 3) + 10.0 ** -(precision + 4)
    values[:3] = [[0.0, 1.0, -1.0], [9.5, -0.25, 123.0], [-1e-12, 0.0, 10.0]]
    got = format_lines("v ", values, precision=precision)
    want = _reference(b"v ", values.ravel(), np.arange(0, values.size + 1, 3), None, precision)
    _same_text(got, want)


def test_faces_with_separators_and_varying_lengths():
    tokens = np.arange(1, 12)
    starts = np.array([0, 6, 11])
    seps = np.array([0, 47, 32, 47, 32, 47, 0, 47, 32, 47, 32], np.uint8)
    assert format_lines("f ", tokens, starts, seps) == b"f 1/2 3/4 5/6\nf 7/8 9/10 11\n"


def test_large_indices_and_blocks(monkeypatch):
    import facadeforge.exchange._ascii as ascii_

    monkeypatch.setattr(ascii_, "_BLOCK", 7)  # many blocks, lines never split across them
    idx = np.array([1, 22, 333, 4444, 55555, 666666, 7777777, 2**40, 9, 10, 99, 100])
    starts = np.array([0, 3, 4, 8, 12])
    want = _reference(b"f ", idx, starts, None, 0)
    assert format_lines("f ", idx, starts) == want
    assert format_lines("f ", idx, starts).count(b"\n") == 4


def test_values_fixed_point_cannot_hold_fall_back_to_python():
    values = np.array([[np.nan, np.inf, 1e300]])
    assert format_lines("v ", values, precision=2) == b"v nan inf " + b"%.2f\n" % 1e300


def test_empty_and_bad_input():
    assert format_lines("v ", np.zeros((0, 3)), precision=6) == b""
    with pytest.raises(ValueError, match="line_starts"):
        format_lines("f ", np.arange(3))
    with pytest.raises(ValueError, match="at least one number"):
        format_lines("f ", np.arange(3), np.array([0, 0, 3]))


def test_json_arrays():
    import json

    ints = np.array([[1, -2, 3], [40, 0, -600], [7, 8, 9]])
    text = b"[" + format_lines("[", ints, sep=",", end="],")[:-1] + b"]"
    assert json.loads(text) == ints.tolist()
    rings = np.array([5, 6, 7, 8, 9, 10, 11])
    text = format_lines("[[", rings, np.array([0, 4, 7]), sep=",", end="]],")
    assert text == b"[[5,6,7,8]],[[9,10,11]],"
    assert format_lines("", np.array([[1, 2]]), sep=",", end=";") == b"1,2;"
