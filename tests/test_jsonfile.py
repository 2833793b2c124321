"""The one reader of users' JSON files: BOM, size cap, nesting and syntax errors named."""

import json

import pytest

from facadeforge.errors import InputError
from facadeforge.exchange.errors import LoadError
from facadeforge.jsonfile import parse_json, read_json

DEEP = "[" * 100_000 + "]" * 100_000


def test_reads_with_and_without_byte_order_mark(tmp_path):
    p = tmp_path / "a.json"
    for encoding in ("utf-8", "utf-8-sig"):
        p.write_text(json.dumps({"é": [1, 2]}), encoding=encoding)
        assert read_json(p) == {"é": [1, 2]}


def test_deep_nesting_is_an_input_error_naming_the_file(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text(DEEP)
    with pytest.raises(InputError, match=r"palette '.*deep.json': JSON nested too deeply"):
        read_json(p, "palette")


def test_syntax_errors_say_where(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"a": 1,\n "b": }')
    with pytest.raises(InputError, match=r"'.*bad.json' is not valid JSON \(line 2, column 7"):
        read_json(p)


def test_size_cap_is_checked_before_reading(tmp_path):
    p = tmp_path / "big.json"
    p.write_text("[" + "0, " * 1000 + "0]")
    assert read_json(p, max_bytes=10_000)[0] == 0
    with pytest.raises(InputError, match="is 3003 bytes, more than the 1000 bytes facadeforge reads"):
        read_json(p, max_bytes=1000)


def test_missing_and_non_utf8_files(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        read_json(tmp_path / "none.json")
    p = tmp_path / "latin1.json"
    p.write_bytes('{"a": "é"}'.encode("latin-1"))
    with pytest.raises(InputError, match="not UTF-8 text"):
        read_json(p)


def test_callers_choose_the_error_type():
    with pytest.raises(LoadError, match="x.obj:3"):
        parse_json(DEEP, "x.obj:3", error=LoadError)
    assert parse_json("\ufeff[1]", "text") == [1]
