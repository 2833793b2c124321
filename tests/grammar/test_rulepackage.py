"""Rule packages (.rpk): decompression bombs and member counts are refused before extraction,
a listing that understates its sizes is stopped while it is written."""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import py7zr
import pytest

import facadeforge.grammar.rulepackage as R
from facadeforge.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


@pytest.fixture(autouse=True)
def private_tmp(tmp_path, monkeypatch) -> Path:
    """Packages unpack into a temporary folder of the test's own (to see what is left)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    return tmp


def _package(tmp_path: Path, zeros: int, extra: int = 0) -> Path:
    """A package with a rule file, ``zeros`` bytes of zeros (they pack to almost nothing) and
    ``extra`` small files."""
    rpk = tmp_path / "pkg.rpk"
    with py7zr.SevenZipFile(rpk, "w") as z:
        z.writestr("@StartRule\nLot --> extrude(3)\n", "rules/main.cga")
        z.writestr(bytes(zeros), "assets/zeros.bin")
        for k in range(extra):
            z.writestr(b"x", f"assets/x{k}.txt")
    return rpk


def _spy_extraction(monkeypatch) -> list:
    calls: list = []
    real = py7zr.SevenZipFile.extractall

    def extractall(self, *args, **kwargs):
        calls.append(args)
        return real(self, *args, **kwargs)
    monkeypatch.setattr(py7zr.SevenZipFile, "extractall", extractall)
    return calls


def test_a_bomb_is_refused_from_its_listing_before_extraction(tmp_path, monkeypatch,
                                                              private_tmp):
    rpk = _package(tmp_path, 4 * 2**20)
    assert rpk.stat().st_size < 64 * 1024                 # 4 MiB of zeros pack to a few KiB
    monkeypatch.setattr(R, "MAX_UNPACKED_BYTES", 2**20)
    calls = _spy_extraction(monkeypatch)
    with pytest.raises(InputError, match=r"unpacks to 4\.0 MiB, more than the 1\.0 MiB "
                                         r"facadeforge unpacks"):
        R.open_rpk(rpk)
    assert calls == [] and list(private_tmp.iterdir()) == []


def test_a_listing_that_understates_its_sizes_is_stopped_at_the_cap(tmp_path, monkeypatch,
                                                                    private_tmp):
    rpk = _package(tmp_path, 4 * 2**20)
    monkeypatch.setattr(R, "MAX_UNPACKED_BYTES", 2**20)
    real = py7zr.SevenZipFile.list

    def lying(self):
        return [dataclasses.replace(info, uncompressed=0) for info in real(self)]
    monkeypatch.setattr(py7zr.SevenZipFile, "list", lying)
    calls = _spy_extraction(monkeypatch)
    with pytest.raises(InputError, match="more than its listing says"):
        R.open_rpk(rpk)
    assert len(calls) == 1 and list(private_tmp.iterdir()) == []   # partial files removed


def test_members_are_counted_before_extraction(tmp_path, monkeypatch):
    rpk = _package(tmp_path, 10, extra=3)
    monkeypatch.setattr(R, "MAX_MEMBERS", 4)
    calls = _spy_extraction(monkeypatch)
    with pytest.raises(InputError, match="has 5 members, more than the 4 facadeforge unpacks"):
        R.open_rpk(rpk)
    assert calls == []


def test_a_package_larger_than_the_free_space_is_refused(tmp_path, monkeypatch):
    import collections
    import shutil

    rpk = _package(tmp_path, 2**20)
    usage = collections.namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(2**30, 2**30 - 4096, 4096))
    with pytest.raises(InputError, match=r"unpacks to 1\.0 MiB, but the temporary folder .* has "
                                         r"0\.0 MiB free"):
        R.open_rpk(rpk)


def test_packages_under_the_caps_unpack(tmp_path):
    package = R.open_rpk(_package(tmp_path, 2**20, extra=3))
    assert package.main.name == "main.cga"
    assert (package.root / "assets" / "zeros.bin").stat().st_size == 2**20
    real = DATA / "cga" / "candler.rpk"                # 1.1 MB, 28 members
    if real.is_file():
        assert R.open_rpk(real).main.suffix == ".cga"
