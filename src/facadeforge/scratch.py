"""Scratch folders that a killed run cannot leak for long, and SIGTERM as a normal exit.

A scratch folder's name says who made it: ``PREFIX<host>-<pid>-<random>`` (``host`` a short
hash of the machine's name, so that a ``/tmp`` shared by several machines or containers never
mistakes another machine's live process for a dead one).  :func:`remove_stale` removes the
folders of this host whose process no longer runs; :func:`scratch_dir` calls it before it makes
a new one, so a run killed with SIGKILL leaves its folder only until the next run.

:func:`sigterm_as_exit` turns SIGTERM into :class:`Terminated` (a :class:`SystemExit` with
status 143), so that ``finally`` blocks, context managers and ``weakref.finalize`` clean up when
a run is stopped politely (``kill``, a job scheduler, ``timeout``), as they do for Ctrl-C.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import signal
import socket
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

__all__ = ["Terminated", "owner_tag", "remove_stale", "scratch_dir", "sigterm_as_exit"]


class Terminated(SystemExit):
    """Raised in the main thread on SIGTERM inside :func:`sigterm_as_exit` (status 143)."""


def _host() -> str:
    return hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:8]


def owner_tag() -> str:
    """``<host>-<pid>``: what a scratch folder's name carries after its prefix."""
    return f"{_host()}-{os.getpid()}"


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs; ``True`` when that cannot be told (keep, don't delete)."""
    if pid <= 0:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:       # PermissionError: it runs, as another user
        return True
    return True


def remove_stale(folder: str | os.PathLike, prefix: str) -> list[Path]:
    """Remove the folders ``folder/PREFIX<host>-<pid>-*`` made on this host by processes that
    no longer run; returns what was removed.  Other names, other hosts' folders, live
    processes' folders and anything not a real folder are left alone."""
    host, me = _host(), os.getpid()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    removed = []
    for entry in entries:
        if not entry.name.startswith(prefix):
            continue
        parts = entry.name[len(prefix):].split("-", 2)
        if len(parts) != 3 or parts[0] != host or not parts[1].isdigit():
            continue
        pid = int(parts[1])
        # our own pid: this process's folder (another thread's), or a dead one's with a reused
        # pid; either way not provably stale
        if pid == me or _alive(pid):
            continue
        try:
            if not entry.is_dir(follow_symlinks=False):
                continue
        except OSError:
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
        removed.append(Path(entry.path))
    return removed


def scratch_dir(prefix: str, dir: str | os.PathLike | None = None) -> Path:
    """A new private folder ``dir/PREFIX<host>-<pid>-<random>`` (``dir``: the system's
    temporary folder by default), after removing the stale ones of dead processes."""
    base = Path(dir) if dir is not None else Path(tempfile.gettempdir())
    remove_stale(base, prefix)
    return Path(tempfile.mkdtemp(prefix=f"{prefix}{owner_tag()}-", dir=base))


@contextlib.contextmanager
def sigterm_as_exit() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` in the main thread; the previous
    handler is restored afterwards.

    Does nothing outside the main thread (Python delivers signals there only) and when a handler
    other than the default is already installed (the application chose one; an outer
    ``sigterm_as_exit`` is already in force).  A process forked inside the block (a worker)
    gets the default behaviour back: SIGTERM ends it at once, as its parent expects.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    try:
        previous = signal.getsignal(signal.SIGTERM)
    except (AttributeError, ValueError):
        previous = None
    if previous is not signal.SIG_DFL:
        yield
        return
    owner = os.getpid()

    def handler(signum, frame):
        if os.getpid() != owner:        # a forked worker: die as the default would
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        raise Terminated(128 + signum)

    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
