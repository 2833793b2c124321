"""The user's private cache folder (``$XDG_CACHE_HOME/facadeforge`` or ``~/.cache/facadeforge``).

Only for what can be rebuilt at any time: the compiled CGA parser tables, embedded asset
textures.  A folder another user owns, or a link, is never used: a cache is read back (the
parser tables are a pickle), so it must not be a place someone else could have planted files in,
as a shared ``/tmp`` is.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def cache_root() -> Path:
    """``$XDG_CACHE_HOME/facadeforge``, else ``~/.cache/facadeforge`` (a per-user temporary
    folder's name when there is no home folder)."""
    base = os.environ.get("XDG_CACHE_HOME")
    try:
        return Path(base or Path.home() / ".cache") / "facadeforge"
    except RuntimeError:  # no home folder
        return Path(tempfile.gettempdir()) / f"facadeforge-{os.getuid()}"


def private_folder(name: str) -> Path | None:
    """``cache_root() / name``, made if need be (mode 0700); ``None`` when it cannot be made or is
    not the user's own folder (callers then work without a cache)."""
    folder = cache_root() / name
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        if folder.is_symlink() or folder.stat().st_uid != os.getuid():
            return None
    except OSError:
        return None
    return folder
