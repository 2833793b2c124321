"""Scratch folders named after their process, and SIGTERM as a normal exit."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest

from facadeforge.scratch import Terminated, owner_tag, remove_stale, scratch_dir, sigterm_as_exit


def dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_scratch_dir_names_its_owner_and_removes_dead_ones(tmp_path):
    host = owner_tag().split("-")[0]
    stale = tmp_path / f"ff-x-{host}-{dead_pid()}-q1"
    stale.mkdir()
    (stale / "big").write_bytes(b"0" * 10)
    not_a_dir = tmp_path / f"ff-x-{host}-{dead_pid()}-q2"
    not_a_dir.write_text("file")
    unrelated = tmp_path / "ff-x-notes"
    unrelated.mkdir()
    new = scratch_dir("ff-x-", tmp_path)
    assert new.name.startswith(f"ff-x-{owner_tag()}-") and new.is_dir()
    assert not stale.exists() and not_a_dir.exists() and unrelated.exists()
    assert remove_stale(tmp_path, "ff-x-") == []        # its own folder is kept


def test_sigterm_raises_and_the_handler_comes_back():
    before = signal.getsignal(signal.SIGTERM)
    if before is not signal.SIG_DFL:
        pytest.skip("the test runner installed its own SIGTERM handler")
    with pytest.raises(Terminated) as info, sigterm_as_exit():
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):       # the handler runs between bytecodes
            pass
    assert info.value.code == 143
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_an_installed_handler_is_left_alone():
    seen = []
    previous = signal.signal(signal.SIGTERM, lambda *a: seen.append(a[0]))
    try:
        with sigterm_as_exit():
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):
                pass
        assert seen == [signal.SIGTERM]
    finally:
        signal.signal(signal.SIGTERM, previous)
