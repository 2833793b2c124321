"""Output folders (OUTDIR of ``reconstruct``, ``parse``, ``demo``): written whole, replaced whole.

A run writes its files into a staging folder *beside* OUTDIR
(``.NAME.staging-<host>-<pid>-<random>``) and, once every file is written, swaps it in for
OUTDIR (one atomic ``renameat2(RENAME_EXCHANGE)`` on Linux; elsewhere two renames), then deletes
the previous contents.  So OUTDIR holds exactly one run's files: a failed or interrupted run
leaves the previous result untouched, a new one leaves no file of the previous run behind.

Policy for an existing OUTDIR
-----------------------------
* A marker file :data:`MARKER` in OUTDIR lists the files facadeforge wrote there.
* OUTDIR may be replaced when it is empty, or when every file in it is listed in its marker
  (files the user deleted since are fine).
* Any other file (no marker: a folder facadeforge did not make, or made before markers
  existed; or a file added after the run) makes the run stop with an :class:`InputError` that
  names it, before any work: facadeforge never deletes a file it did not write.
* An input of the run (the photo, a classifier, a depths file…) inside OUTDIR is refused too:
  replacing OUTDIR would delete it, and an output could overwrite it.
* OUTDIR may not be the current folder or one of its parents (it is renamed).

Staging folders of runs that were killed (SIGKILL, power loss) are recognised by the process id
in their names and removed by the next run writing beside them (:mod:`facadeforge.scratch`);
SIGTERM during a run is turned into a normal exit, which removes the staging folder at once.
"""

from __future__ import annotations

import ctypes
import errno
import json
import os
import shutil
import sys
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from .errors import InputError
from .scratch import remove_stale, scratch_dir, sigterm_as_exit

__all__ = ["MARKER", "check_outdir", "check_output_file", "write_json", "write_outdir"]

#: Name of the file listing what facadeforge wrote in an output folder.
MARKER = ".facadeforge-outdir.json"

_UMASK = os.umask(0)
os.umask(_UMASK)

Inputs = Mapping[str, object] | Iterable[object] | None


def _input_paths(inputs: Inputs) -> list[tuple[str, Path]]:
    """``(what, path)`` of the inputs that are paths (arrays and ``None`` are skipped)."""
    if inputs is None:
        return []
    items = inputs.items() if isinstance(inputs, Mapping) else (("input", v) for v in inputs)
    return [(what, Path(v)) for what, v in items if isinstance(v, str | os.PathLike)]


def _entries(folder: Path) -> list[str]:
    """Relative POSIX paths of every file and link under ``folder`` (links not followed), less
    the marker and the ``.staging-*`` folders that versions before the marker left inside."""
    out = []
    for dirpath, dirnames, filenames in os.walk(folder):
        rel = Path(dirpath).relative_to(folder)
        if rel == Path("."):
            dirnames[:] = [d for d in dirnames if not d.startswith(".staging-")]
        for name in dirnames:
            if os.path.islink(os.path.join(dirpath, name)):   # os.walk does not enter them
                out.append((rel / name).as_posix())
        out += [(rel / name).as_posix() for name in filenames]
    return sorted(p for p in out if p != MARKER)


def _listed(folder: Path) -> set[str] | None:
    """The files the marker of ``folder`` lists; ``None`` without a readable marker."""
    try:
        data = json.loads((folder / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("written_by") != "facadeforge":
        return None
    files = data.get("files")
    return {str(f) for f in files} if isinstance(files, list) else None


def _foreign(folder: Path) -> tuple[list[str], bool]:
    """The files in ``folder`` facadeforge did not write there, and whether it has a marker."""
    entries = _entries(folder)
    listed = _listed(folder)
    return ([e for e in entries if listed is None or e not in listed]), listed is not None


def check_outdir(out: str | os.PathLike, inputs: Inputs = None, *,
                 foreign_ok: bool = False) -> Path:
    """Refuse an output folder a run may not replace (module docstring); returns its resolved
    path.  Cheap: commands call it before their work so a bad ``-o`` fails at once.

    Parameters
    ----------
    out : path-like
        The output folder (need not exist).
    inputs : mapping of str to path, or iterable of paths, optional
        The run's input files (``{"photo": path, "--depths": path}``: the keys name them in
        messages); values that are not paths are ignored.

    Raises
    ------
    InputError
        ``out`` is a file, the current folder or above it, holds an input, or holds files
        facadeforge did not write.
    """
    given = Path(out)
    if given.exists() and not given.is_dir():
        raise InputError(f"output folder {given} is an existing file; choose a folder name")
    real = given.resolve()
    cwd = Path.cwd().resolve()
    if real == cwd or real in cwd.parents:
        raise InputError(f"output folder {given} is the current folder or holds it; a run "
                         f"replaces its output folder, so give a sub-folder such as {given / 'out'}")
    for what, path in _input_paths(inputs):
        p = path.resolve()
        if p == real or real in p.parents:
            raise InputError(f"{what} {path} is inside the output folder {given}, which the run "
                             "replaces (an output could overwrite it); choose another output "
                             f"folder, e.g. -o {given.parent / (given.name + '-out')}")
    if real.is_dir() and not foreign_ok:
        foreign, marked = _foreign(real)
        if foreign:
            shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3
                                              else "")
            why = ("files facadeforge did not write there" if marked else
                   f"files and no {MARKER} marker of an earlier facadeforge run")
            raise InputError(f"output folder {given} holds {why} ({shown}); a run replaces its "
                             "output folder whole, so give a new or empty folder, or move "
                             "those files away")
    return real


def check_output_file(out: str | os.PathLike, inputs: Inputs = None) -> None:
    """Refuse an output *file* that is one of the run's inputs (``derive lots.obj --footprint
    lots.obj -o lots.obj`` would replace the footprints it read).

    Raises
    ------
    InputError
        ``out`` names the same file as an input.
    """
    real = Path(out).resolve()
    for what, path in _input_paths(inputs):
        if path.resolve() == real:
            raise InputError(f"-o {out} is the {what} file the run reads; write the result to "
                             "another file")


def write_outdir(out: str | os.PathLike, write: Callable[[Path], None],
                 inputs: Inputs = None, *, carry_foreign: bool = False) -> list[Path]:
    """Fill a staging folder with ``write(stage)``, then swap it in for ``out`` (module
    docstring); returns the written paths (under ``out``).

    Parameters
    ----------
    out : path-like
        The output folder; made if missing, replaced whole if it exists.
    write : callable
        Writes every output file into the folder it is given (sub-folders allowed).
    inputs : optional
        The run's input files, as for :func:`check_outdir`.
    carry_foreign : bool
        For a ``write`` that copies the current OUTDIR into the stage first (``facadeforge
        edit``'s save): files facadeforge did not write are allowed, carried over by ``write``
        and left out of the marker; one that appears while ``write`` runs stops the swap.

    Raises
    ------
    InputError
        As :func:`check_outdir`.
    """
    given = Path(out)
    real = check_outdir(given, inputs, foreign_ok=carry_foreign)
    foreign_before = set(_foreign(real)[0]) if carry_foreign and real.is_dir() else set()
    real.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(real.parent, f".{real.name}.old-")
    stage = scratch_dir(f".{real.name}.staging-", real.parent)
    try:
        with sigterm_as_exit():
            write(stage)
            # after write(): mkdtemp's 0700 (or a copytree's copied mode) would become OUTDIR's
            os.chmod(stage, 0o777 & ~_UMASK)
            files = [f for f in _entries(stage) if f not in foreign_before]
            (stage / MARKER).write_text(json.dumps(
                {"written_by": "facadeforge", "files": files}, indent=1) + "\n")
            if carry_foreign:    # a file added while we worked would be lost by the swap
                added = set(_foreign(real)[0]) - foreign_before if real.is_dir() else set()
                if added:
                    raise InputError(f"{given} gained {', '.join(sorted(added)[:3])} while it "
                                     "was being written; nothing was changed, save again")
            else:
                check_outdir(given, inputs)   # unchanged while we worked? (never delete foreign)
            _swap(stage, real)
        return [given / f for f in files]
    finally:
        # after an exchange the stage holds the previous contents; after a failure, this run's
        shutil.rmtree(stage, ignore_errors=True)


def _swap(stage: Path, real: Path) -> None:
    """Put ``stage`` in the place of ``real``; the previous ``real`` ends up at ``stage`` (or
    is deleted)."""
    if not real.exists():
        try:
            os.rename(stage, real)
            return
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):  # made meanwhile: exchange
                raise
    if _exchange(stage, real):
        return
    old = scratch_dir(f".{real.name}.old-", real.parent)
    os.rmdir(old)                          # only its (unique, recognisable) name is wanted
    os.rename(real, old)
    try:
        os.rename(stage, real)
    except BaseException:
        os.rename(old, real)
        raise
    shutil.rmtree(old, ignore_errors=True)


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2(RENAME_EXCHANGE)``); ``False`` where the
    system or the file system cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    if fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.EPERM):
        return False
    raise OSError(err, os.strerror(err), str(b))


def write_json(path: str | os.PathLike, obj, indent: int = 2) -> None:
    """``obj`` as indented JSON at ``path`` (NaN and infinities become null); inside
    :func:`write_outdir`'s staging folder, which makes the whole folder atomic."""
    from .exchange._common import jsonable

    Path(path).write_text(json.dumps(jsonable(obj), indent=indent))
