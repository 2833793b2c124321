"""Exchange: exporters, importers, label rasters and a CPU preview renderer.

The exporters consume only :class:`~facadeforge.model.Model` (never the grammar engine).  They
are registered by file suffix, the way trimesh does it::

    from facadeforge.exchange import export, load
    export(model, "house.glb")               # EXPORTERS["glb"]
    export([a, b], "block.city.json", reference_system=7415)
    models = load("house.obj")               # IMPORTERS["obj"]

Every write is atomic: files are written under temporary names in the destination directory and
renamed into place only when the whole export succeeded.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from ..model.model import Model, extent_problem
from .cityjson import export_cityjson, export_cityjsonseq, load_cityjson, load_cityjsonseq
from .errors import ExportError, LoadError
from .gltf import export_glb, load_glb
from .obj import export_obj, load_obj
from .raster import (
    LABEL_COLORS,
    LABEL_INDEX,
    export_label_png,
    export_label_svg,
    label_map,
    write_label_png,
    write_label_svg,
)
from .render import render_file, render_preview

__all__ = [
    "EXPORTERS", "IMPORTERS", "LABEL_COLORS", "LABEL_INDEX", "ExportError", "LoadError",
    "export", "export_cityjson", "export_cityjsonseq", "export_glb", "export_obj", "label_map",
    "load", "load_cityjson", "load_cityjsonseq", "load_glb", "load_obj", "render_file", "render_preview", "write_label_png", "write_label_svg",
]

#: File suffix (without the leading dot) → exporter ``f(models, path, **options) -> list[Path]``.
EXPORTERS: dict[str, Callable[..., list[Path]]] = {
    "glb": export_glb,
    "obj": export_obj,
    "city.json": export_cityjson,
    "city.jsonl": export_cityjsonseq,
    "png": export_label_png,
    "svg": export_label_svg,
}

#: File suffix (without the leading dot) → importer ``f(path, **options) -> list[Model]``.
IMPORTERS: dict[str, Callable[..., list[Model]]] = {
    "glb": load_glb,
    "obj": load_obj,
    "city.json": load_cityjson,
    "city.jsonl": load_cityjsonseq,
}


def suffix_of(path: str | os.PathLike, table: dict) -> str | None:
    """The registered suffix ``path`` ends with, longest first (``.city.json`` before ``.json``)."""
    name = Path(path).name.lower()
    for suffix in sorted(table, key=len, reverse=True):
        if name.endswith("." + suffix):
            return suffix
    return None


def _known(table: dict) -> str:
    return ", ".join("." + s for s in table)


def export(models: Model | Sequence[Model], path: str | os.PathLike, **options) -> list[Path]:
    """Write models with the exporter registered for the suffix of ``path``.

    Parameters
    ----------
    models : Model or sequence of Model
        What to write.
    path : path-like
        Destination; its suffix picks the exporter (see :data:`EXPORTERS`), case-insensitively
        and longest suffix first.  Missing parent folders are created.
    **options
        Keyword options of that exporter.

    Returns
    -------
    list of Path
        Every file written (the main file first).

    Raises
    ------
    ExportError
        For an unknown suffix, an option the exporter does not take, or invalid input.
    """
    suffix = suffix_of(path, EXPORTERS)
    if suffix is None:
        raise ExportError(f"cannot export {os.fspath(path)!r}: unknown file type; "
                          f"known suffixes: {_known(EXPORTERS)}")
    exporter = EXPORTERS[suffix]
    _check_options(exporter, options, path)
    return exporter(models, path, **options)


def load(path: str | os.PathLike, **options) -> list[Model]:
    """Read models with the importer registered for the suffix of ``path``.

    Parameters
    ----------
    path : path-like
        A file whose suffix has an importer (see :data:`IMPORTERS`).
    **options
        Keyword options of that importer (``texture_dir`` for ``.glb``).

    Returns
    -------
    list of Model
        The models in the file, with parts carrying label, material and symbol.

    Raises
    ------
    LoadError
        For an unknown suffix or unreadable content.
    FileNotFoundError
        When the file does not exist.
    """
    suffix = suffix_of(path, IMPORTERS)
    if suffix is None:
        raise LoadError(f"cannot load {os.fspath(path)!r}: unknown file type; "
                        f"known suffixes: {_known(IMPORTERS)}")
    importer = IMPORTERS[suffix]
    try:
        inspect.signature(importer).bind(path, **options)
    except TypeError as exc:
        raise LoadError(f"cannot load {os.fspath(path)!r}: {exc}") from exc
    models = importer(path, **options)
    for m in models:
        problem = extent_problem(m.stats())
        if problem is not None:
            raise LoadError(f"cannot load {os.fspath(path)!r}: model '{m.name}': {problem}")
    return models


def _check_options(exporter: Callable, options: dict, path) -> None:
    params = inspect.signature(exporter).parameters
    allowed = [n for n, p in params.items() if p.kind is inspect.Parameter.KEYWORD_ONLY]
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ExportError(f"cannot export {os.fspath(path)!r}: unknown option(s) "
                          f"{', '.join(unknown)}; this exporter takes: "
                          f"{', '.join(allowed) or 'no options'}")
