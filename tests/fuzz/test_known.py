"""Failures the fuzzer found, reduced by hand: a strict xfail while the source is not fixed (then
remove the mark and the matching entry of test_fuzz.KNOWN), a regression test once it is.  The oracle's own checks at the end."""

from __future__ import annotations

import json
import struct

import pytest

from . import oracle


def _derive(tmp_path, rules: str, *extra, output="glb"):
    (tmp_path / "r.cga").write_text(rules)
    out = tmp_path / f"o.{output}"
    argv = ["derive", str(tmp_path / "r.cga"), "--lot=8x6", "-o", str(out), "--workers", "1",
            *extra]
    return argv, out


# found by the fuzzer: primitiveSphere(1000, 1000) ran past 100 s under --max-seconds 1 (faces
# built in a Python loop, resolution uncapped); fixed in 7c15c9e (a 100,000-face cap)
@pytest.mark.parametrize("rules", ["Lot --> primitiveSphere(2000, 2000)",
                                   "Lot --> primitiveCylinder(3000000)"])
def test_primitive_resolution_is_bounded(tmp_path, rules, monkeypatch):
    monkeypatch.setattr(oracle, "HANG_SECONDS", 10)   # a 1 s budget: 10 s is generous
    argv, out = _derive(tmp_path, rules + "\n", "--max-seconds", "1")
    outcome = oracle.run_subprocess(argv, tmp_path, [out])
    assert outcome.signature is None, outcome.describe()


# found by the fuzzer: numpy RuntimeWarnings on stderr before the error line; fixed in 7c15c9e
@pytest.mark.parametrize("rules", ["Lot --> s(1e300, 1, 1) extrude(1e300)",
                                   "Lot --> t(0, -(1e300*1e300), 0)"])
def test_overflow_warnings_stay_off_stderr(tmp_path, rules):
    argv, out = _derive(tmp_path, rules + "\n")
    outcome = oracle.run_inprocess(argv, tmp_path, [out])
    assert outcome.rc == 2
    assert outcome.signature is None, outcome.describe()


# found by the fuzzer: pygltflib's "Ignoring chunk 2 with unknown type" UserWarning on
# stderr for a GLB with an extra chunk; fixed in 7c15c9e
def test_unknown_glb_chunk_warns_on_stderr(tmp_path):
    argv, out = _derive(tmp_path, "Lot --> extrude(3)\n")
    assert oracle.run_inprocess(argv, tmp_path, [out]).signature is None
    data = out.read_bytes() + struct.pack("<I4s", 4, b"XTRA") + b"\0" * 4
    bad = tmp_path / "chunk.glb"
    bad.write_bytes(data[:8] + struct.pack("<I", len(data)) + data[12:])
    png = tmp_path / "r.png"
    outcome = oracle.run_inprocess(["render", str(bad), "-o", str(png), "--size", "64x48"],
                                   tmp_path, [png])
    assert outcome.signature is None, outcome.describe()


def test_oracle_sees_a_bad_glb(tmp_path):
    """The oracle itself: a GLB with NaN in its JSON, an error of two lines, exit 3 all fail."""
    argv, out = _derive(tmp_path, "Lot --> extrude(3)\n")
    assert oracle.run_inprocess(argv, tmp_path, [out]).signature is None
    data = out.read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    doc["accessors"][0]["max"][0] = float("nan")
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + data[20 + jlen:]
    out.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
    assert "invalid glb" in oracle.check_file(out)
    judged = oracle.judge(2, "", "facadeforge: error: a\nb\n", 0.1, tmp_path, set(), [])
    assert judged.signature is not None
    judged = oracle.judge(3, "", "facadeforge: internal error: KeyError: 'x' (please …)\n", 0.1,
                          tmp_path, oracle.files_under(tmp_path), [])
    assert judged.signature == "internal error: KeyError"
