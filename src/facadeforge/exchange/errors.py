"""Typed errors of the exchange package.

Both are ``ValueError`` (bad input) and :class:`~facadeforge.errors.FacadeForgeError` (so the
CLI reports them as one line); their messages name the file and what would be accepted.
"""

from __future__ import annotations

from ..errors import FacadeForgeError


class ExportError(FacadeForgeError, ValueError):
    """A model could not be written: unknown file type, bad option or unwritable destination."""


class LoadError(FacadeForgeError, ValueError):
    """A file could not be read back into models: unknown file type or malformed content."""
