"""Typed errors of the exchange package."""

from __future__ import annotations


class ExportError(ValueError):
    """A model could not be written: unknown file type, bad option or unwritable destination."""


class LoadError(ValueError):
    """A file could not be read back into models: unknown file type or malformed content."""
