"""Output folders: written whole, replaced whole, never over an input or a foreign file."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from facadeforge import outdir
from facadeforge.errors import InputError
from facadeforge.outdir import MARKER, check_outdir, write_outdir
from facadeforge.scratch import owner_tag


def writer(files: dict[str, str]):
    def write(stage: Path) -> None:
        for name, text in files.items():
            (stage / name).parent.mkdir(parents=True, exist_ok=True)
            (stage / name).write_text(text)
    return write


def tree(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def dead_pid() -> int:
    """The pid of a process that has ended."""
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_a_new_folder_gets_the_files_and_a_marker(tmp_path):
    out = tmp_path / "a" / "out"
    written = write_outdir(out, writer({"x.txt": "1", "assets/y.obj": "2"}))
    assert sorted(written) == [out / "assets/y.obj", out / "x.txt"]
    assert tree(out) == {MARKER: (out / MARKER).read_text(), "assets/y.obj": "2", "x.txt": "1"}
    assert json.loads((out / MARKER).read_text())["files"] == ["assets/y.obj", "x.txt"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]   # no staging left


def test_a_rerun_leaves_exactly_its_own_files(tmp_path):
    """The reproducer: a reused OUTDIR kept the previous run's assets/*.obj."""
    out = tmp_path / "out"
    write_outdir(out, writer({"structure.png": "old", "assets/a.obj": "a", "report.json": "1"}))
    write_outdir(out, writer({"report.json": "2"}))
    assert tree(out) == {MARKER: (out / MARKER).read_text(), "report.json": "2"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("exchange", [True, False])
def test_replacing_works_with_and_without_an_atomic_exchange(tmp_path, monkeypatch, exchange):
    if not exchange:
        monkeypatch.setattr(outdir, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    write_outdir(out, writer({"a": "1"}))
    write_outdir(out, writer({"b": "2"}))
    assert set(tree(out)) == {MARKER, "b"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_failed_run_keeps_the_previous_result(tmp_path):
    out = tmp_path / "out"
    write_outdir(out, writer({"a": "1"}))
    before = tree(out)

    def broken(stage: Path) -> None:
        (stage / "a").write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_outdir(out, broken)
    assert tree(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("marked", [True, False])
def test_foreign_files_are_refused_and_kept(tmp_path, marked):
    out = tmp_path / "out"
    if marked:
        write_outdir(out, writer({"a": "1"}))
    else:
        out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match=r"out holds files .*\(notes\.txt\).*new or empty"):
        write_outdir(out, writer({"a": "2"}))
    assert (out / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_foreign_link_is_refused(tmp_path):
    out = tmp_path / "out"
    write_outdir(out, writer({"a": "1"}))
    (tmp_path / "data").mkdir()
    (out / "data").symlink_to(tmp_path / "data", target_is_directory=True)
    with pytest.raises(InputError, match=r"\(data\)"):
        check_outdir(out)


def test_an_input_inside_the_folder_is_refused(tmp_path):
    """The reproducer: ``reconstruct same/texture.jpg -o same`` overwrote the photo."""
    out = tmp_path / "same"
    write_outdir(out, writer({"texture.jpg": "made"}))
    photo = out / "texture.jpg"                 # a previous output given as the input
    with pytest.raises(InputError, match=r"photo .*texture\.jpg is inside the output folder"):
        write_outdir(out, writer({"texture.jpg": "new"}), {"photo": photo})
    assert photo.read_text() == "made"
    with pytest.raises(InputError, match="inside the output folder"):
        check_outdir(tmp_path, [photo])         # any folder above the input too
    check_outdir(tmp_path / "other", {"photo": photo, "--classifier": False, "x": None})


def test_a_file_and_the_current_folder_are_refused(tmp_path, monkeypatch):
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="is an existing file"):
        check_outdir(tmp_path / "f")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match="current folder"):
        check_outdir(".")
    with pytest.raises(InputError, match="current folder"):
        check_outdir(tmp_path.parent)


def test_stale_staging_of_a_dead_run_is_removed(tmp_path):
    """The reproducer: a run killed with SIGKILL left its staging folder for ever."""
    host = owner_tag().split("-")[0]
    stale = tmp_path / f".out.staging-{host}-{dead_pid()}-abc"
    live = tmp_path / f".out.staging-{host}-{os.getppid()}-abc"   # a running process's
    other = tmp_path / f".out.staging-00000000-{dead_pid()}-abc"  # another machine's
    for d in (stale, live, other):
        d.mkdir()
        (d / "model.glb").write_text("half")
    write_outdir(tmp_path / "out", writer({"a": "1"}))
    assert not stale.exists() and live.exists() and other.exists()


def test_a_killed_run_is_cleaned_by_the_next(tmp_path):
    out = tmp_path / "out"
    code = ("import os, signal, sys; from facadeforge.outdir import write_outdir\n"
            "def write(stage):\n"
            "    (stage / 'half').write_text('x'); os.kill(os.getpid(), signal.SIGKILL)\n"
            f"write_outdir({str(out)!r}, write)\n")
    subprocess.run([sys.executable, "-c", code], check=False)
    assert [p.name for p in tmp_path.iterdir() if ".staging-" in p.name]   # what it left
    write_outdir(out, writer({"a": "1"}))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_sigterm_during_a_run_removes_the_staging_folder(tmp_path):
    out = tmp_path / "out"
    code = ("import os, signal; from facadeforge.outdir import write_outdir\n"
            "def write(stage):\n"
            "    (stage / 'half').write_text('x'); os.kill(os.getpid(), signal.SIGTERM)\n"
            f"write_outdir({str(out)!r}, write)\n")
    res = subprocess.run([sys.executable, "-c", code], check=False)
    assert res.returncode == 143
    assert list(tmp_path.iterdir()) == []
