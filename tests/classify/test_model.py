"""Classifier files are untrusted: damaged, truncated or oversized ``.npz`` files are refused with
one error naming the file, before any array is allocated."""

from __future__ import annotations

import io
import tracemalloc
import zipfile

import numpy as np
import pytest

from facadeforge.classify import model as model_module
from facadeforge.classify.gmm import GMMClassifier
from facadeforge.classify.model import ClassifierFileError, load_classifier, save_classifier


def _tiny(tmp_path):
    """A valid, tiny classifier file (a two-class colour GMM)."""
    clf = GMMClassifier(weights=[[1.0], [1.0]], means=[[[100, 100, 100]], [[200, 200, 200]]],
                        covariances=np.stack([np.eye(3)[None] * 100] * 2),
                        classes=("wall", "window"), label_set="ecp7")
    return save_classifier(clf, tmp_path / "tiny.npz")


def _npy_header(shape, descr="<f8") -> bytes:
    """A .npy file holding only its header: it declares ``shape`` but has no data."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue()


def test_tiny_model_round_trips(tmp_path):
    clf = load_classifier(_tiny(tmp_path))
    assert clf.classes == ("wall", "window")


@pytest.mark.parametrize("cut", [0, 10, 0.5, -30])
def test_empty_or_truncated_files_are_refused(tmp_path, cut):
    data = _tiny(tmp_path).read_bytes()
    bad = tmp_path / "bad.npz"
    bad.write_bytes(data[:int(len(data) * cut) if isinstance(cut, float) else cut])
    with pytest.raises(ClassifierFileError, match="not a facadeforge classifier") as err:
        load_classifier(bad)
    assert str(bad) in str(err.value)


def test_damaged_member_is_refused(tmp_path):
    # the zip directory intact, a member's compressed data flipped: zlib or CRC errors
    good = _tiny(tmp_path)
    with zipfile.ZipFile(good) as zf:
        info = zf.getinfo("means.npy")
    data = bytearray(good.read_bytes())
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    for i in range(start + 2, start + info.compress_size - 2):
        data[i] ^= 0x5A
    bad = tmp_path / "bad.npz"
    bad.write_bytes(bytes(data))
    with pytest.raises(ClassifierFileError, match=str(bad)):
        load_classifier(bad)


def test_a_declared_giant_array_is_refused_before_allocation(tmp_path):
    # 2**32 float64 declared in 128 bytes: np.load would allocate 32 GiB, then find no data
    bad = tmp_path / "giant.npz"
    with zipfile.ZipFile(bad, "w") as zf:
        zf.writestr("__meta__.npy", _npy_header((3,), "|u1") + b"{} ")
        zf.writestr("x.npy", _npy_header((2**32,)))
    with pytest.raises(ClassifierFileError, match="more than 512 MiB"):
        load_classifier(bad)


def test_a_compressed_zero_bomb_is_refused_in_bounded_memory(tmp_path, monkeypatch):
    # the 7 MB file holding a 4 GiB array of zeros, scaled down: the cap lowered to
    # 1 MiB, a 16 MiB array of zeros (16 KiB compressed)
    monkeypatch.setattr(model_module, "MAX_CLASSIFIER_ARRAY_BYTES", 2**20)
    bomb = tmp_path / "bomb.npz"
    np.savez_compressed(bomb, __meta__=np.zeros(3, np.uint8), x=np.zeros(2**21))
    assert bomb.stat().st_size < 2**20
    tracemalloc.start()
    try:
        with pytest.raises(ClassifierFileError, match="more than 1 MiB"):
            load_classifier(bomb)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2**20  # never near the 16 MiB the array would take


def test_object_and_text_arrays_are_refused(tmp_path):
    for name, value in (("obj", np.array([{"a": 1}], dtype=object)), ("text", np.array(["x"]))):
        bad = tmp_path / f"{name}.npz"
        np.savez(bad, __meta__=np.zeros(3, np.uint8), x=value)
        with pytest.raises(ClassifierFileError, match="not numbers"):
            load_classifier(bad)


def test_foreign_members_are_refused(tmp_path):
    bad = tmp_path / "foreign.npz"
    with zipfile.ZipFile(bad, "w") as zf:
        zf.writestr("readme.txt", "hello")
    with pytest.raises(ClassifierFileError, match="not a .npy array"):
        load_classifier(bad)


def test_deeply_nested_metadata_is_refused(tmp_path):
    bad = tmp_path / "deep.npz"
    meta = ("[" * 100_000 + "]" * 100_000).encode()
    np.savez(bad, __meta__=np.frombuffer(meta, np.uint8))
    with pytest.raises(ClassifierFileError, match="nested too deeply"):
        load_classifier(bad)


def test_ensemble_members_option_reports_a_truncated_member(tmp_path, capsys):
    from facadeforge.cli import main

    data = _tiny(tmp_path).read_bytes()
    bad = tmp_path / "member.npz"
    bad.write_bytes(data[:len(data) // 2])
    code = main(["train-classifier", "--kind", "ensemble", "--members", str(bad),
                 "-o", str(tmp_path / "ens.npz")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("facadeforge: error: classifier") and str(bad) in err
    assert err.count("\n") == 1
