"""Helpers shared by the exporters and importers: atomic file staging, JSON sanitising, fast
vectorised triangulation and texture access."""

from __future__ import annotations

import io
import logging
import math
import os
import re
import shutil
import tempfile
from collections.abc import Sequence
from enum import Enum
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..geometry.mesh import Mesh
from ..model.model import Model, extent_problem
from .errors import ExportError

log = logging.getLogger("facadeforge.exchange")

_UMASK = os.umask(0)
os.umask(_UMASK)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
JPEG_MAGIC = b"\xff\xd8\xff"


# -- atomic writes ----------------------------------------------------------------------------

class Staging:
    """Write several files under temporary names and move them into place together.

    Use as a context manager: every path handed out by :meth:`path` is a temporary file in the
    directory of its final destination.  On a clean exit the temporary files are renamed onto
    their destinations with :func:`os.replace` (atomic per file); when the block raises, they are
    deleted and no destination is touched, so a failed export never leaves a half-written file.

    Examples
    --------
    >>> with Staging() as stage:                                       # doctest: +SKIP
    ...     stage.write_text(Path("a.obj"), "v 0 0 0\\n")
    """

    def __init__(self) -> None:
        self._pending: list[tuple[Path, Path]] = []
        self._made_dirs: list[Path] = []
        self.finals: list[Path] = []

    def __enter__(self) -> Staging:
        return self

    def path(self, final: str | os.PathLike) -> Path:
        """A fresh temporary path that becomes ``final`` when the block succeeds."""
        final = Path(final)
        try:
            self._make_dir(final.parent)
            fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".part", dir=final.parent)
        except OSError as exc:
            raise ExportError(f"cannot write {final}: {exc}") from exc
        os.close(fd)
        os.chmod(tmp, 0o666 & ~_UMASK)
        self._pending.append((Path(tmp), final))
        self.finals.append(final)
        return Path(tmp)

    def _make_dir(self, folder: Path) -> None:
        missing = []
        while not folder.exists():
            missing.append(folder)
            folder = folder.parent
        for d in reversed(missing):
            d.mkdir()
            self._made_dirs.append(d)

    def write_bytes(self, final: str | os.PathLike, data: bytes) -> None:
        self.path(final).write_bytes(data)

    def write_text(self, final: str | os.PathLike, text: str) -> None:
        with open(self.path(final), "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)

    def copy(self, source: str | os.PathLike, final: str | os.PathLike) -> None:
        shutil.copyfile(source, self.path(final))

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is not None:
            self._discard(self._pending)
            self._remove_made_dirs()
            return False
        for i, (tmp, final) in enumerate(self._pending):
            try:
                os.replace(tmp, final)
            except OSError as err:
                self._discard(self._pending[i:])
                raise ExportError(f"cannot write {final}: {err}") from err
        return False

    def _remove_made_dirs(self) -> None:
        for d in reversed(self._made_dirs):
            try:
                d.rmdir()
            except OSError:
                pass

    @staticmethod
    def _discard(pending: list[tuple[Path, Path]]) -> None:
        for tmp, _ in pending:
            tmp.unlink(missing_ok=True)


# -- JSON -------------------------------------------------------------------------------------

def jsonable(obj: object) -> object:
    """``obj`` turned into plain JSON types (numpy → Python, tuples → lists, NaN → None).

    Unknown objects become their ``str``; enum members their value.
    """
    if isinstance(obj, Enum):
        return jsonable(obj.value)
    if obj is None or isinstance(obj, (str, bool)):
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [jsonable(v) for v in obj]
    return str(obj)


#: a footprint's georeference, as ``geometry.footprints`` records it among the model's attributes
GEOREFERENCE = {"_crs": "crs", "_origin_offset": "origin_offset", "_unit": "unit"}


def split_attributes(attributes: dict) -> tuple[dict, dict]:
    """``(data, georeference)``: the model's attributes without the runtime's own (names starting
    with ``_``), and its georeference under plain names (``crs``, ``origin_offset``, ``unit``),
    which formats without a reference system (glTF extras, OBJ comments) keep apart from the
    data, so that a reloaded model can still be written georeferenced."""
    data = {k: v for k, v in attributes.items() if not str(k).startswith("_")}
    geo = {GEOREFERENCE[k]: v for k, v in attributes.items() if k in GEOREFERENCE}
    return jsonable(data), jsonable(geo)


def joined_attributes(data: dict | None, georeference: dict | None) -> dict:
    """:func:`split_attributes` undone."""
    names = {v: k for k, v in GEOREFERENCE.items()}
    out = dict(data or {})
    out.update({names[k]: v for k, v in (georeference or {}).items() if k in names})
    return out


def scalar_attributes(attributes: dict) -> dict:
    """The entries of ``attributes`` whose values are JSON scalars (str, number, bool, None);
    names starting with ``_`` are the runtime's own (a footprint's georeference), not data."""
    out = {}
    for key, value in attributes.items():
        if str(key).startswith("_"):
            continue
        value = jsonable(value)
        if value is None or isinstance(value, (str, int, float, bool)):
            out[str(key)] = value
    return out


def check_extent(model: Model) -> None:
    """Refuse a model whose coordinates no file could hold as numbers other tools read
    (:func:`~facadeforge.model.model.extent_problem`): every exporter's models pass here
    before anything is written."""
    stats = getattr(model, "derived_stats", None) or model.stats()
    problem = extent_problem(stats)
    if problem is not None:
        raise ExportError(f"cannot export model '{model.name}': {problem}")


def iter_models(models):
    """The ``models`` argument of the exporters that write as they go, one model at a time:
    a ``Model``, a sequence, or any iterable (``engine.derive_iter``'s generator)."""
    items = [models] if isinstance(models, Model) else models
    count = 0
    for m in items:
        if not isinstance(m, Model):
            raise ExportError(f"expected Model objects, got {type(m).__name__}")
        check_extent(m)
        count += 1
        yield m
    if not count:
        raise ExportError("nothing to export: no models given")


def as_models(models: Model | Sequence[Model]) -> list[Model]:
    """Normalise the ``models`` argument of the exporters to a non-empty list of ``Model``."""
    items = [models] if isinstance(models, Model) else list(models)
    if not items:
        raise ExportError("nothing to export: no models given")
    for m in items:
        if not isinstance(m, Model):
            raise ExportError(f"expected Model objects, got {type(m).__name__}")
        check_extent(m)
    return items


def safe_name(name: str, fallback: str) -> str:
    """``name`` with whitespace and ``#`` replaced by ``_`` (OBJ/MTL names are
    whitespace-separated, and ``#`` starts a comment there)."""
    cleaned = re.sub(r"[\s#]+", "_", str(name).strip())
    return cleaned or fallback


# -- mesh access ------------------------------------------------------------------------------
# The mesh stores faces flat: ``corners`` (vertex index of each face corner, face after face),
# ``starts`` (F + 1 offsets) and ``corner_uvs`` ((C, 2) or None).  All exporters go through
# these helpers so that nothing here loops over faces in Python.

def face_corners(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Flattened face corners: vertex index of each corner (C,) and face offsets (F + 1,)."""
    return np.asarray(mesh.corners, np.int64), np.asarray(mesh.starts, np.int64)


def corner_uvs(mesh: Mesh) -> tuple[np.ndarray, bool]:
    """Per-corner UVs (C, 2) (zeros when the mesh has none) and whether the mesh has UVs."""
    if mesh.corner_uvs is None:
        return np.zeros((len(mesh.corners), 2)), False
    return np.asarray(mesh.corner_uvs, float).reshape(-1, 2), True


def triangulate_corners(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of every face, as ``Mesh.triangle_corners`` makes them.

    Returns
    -------
    tri_corners : (T, 3) int
        Indices into the flattened face corners (``mesh.corners``).
    face_of : (T,) int
        Face each triangle comes from.
    """
    tri = np.asarray(mesh.triangle_corners(), np.int64).reshape(-1, 3)
    face_of = np.searchsorted(np.asarray(mesh.starts), tri[:, 0], side="right") - 1
    return tri, face_of


def previous_corner(starts: np.ndarray) -> np.ndarray:
    """Index of the previous corner of the same face for every flattened corner (C,)."""
    prev = np.arange(-1, int(starts[-1]) - 1)
    if len(starts) > 1:
        prev[starts[:-1]] = starts[1:] - 1
    return prev


def mesh_from_flat(vertices: np.ndarray, corners: np.ndarray, starts: np.ndarray,
                   uvs: np.ndarray | None = None) -> Mesh:
    """A mesh from its flat face form."""
    return Mesh(vertices, corners=corners, starts=starts, corner_uvs=uvs)


# -- textures ---------------------------------------------------------------------------------

def read_texture(path: str | os.PathLike | None) -> tuple[bytes, str] | None:
    """Image bytes and MIME type of a texture file, or ``None`` when it cannot be used.

    PNG and JPEG files are returned as they are; other formats Pillow can read are re-encoded as
    PNG.  Missing or unreadable files give ``None`` (and a log message), never an exception.
    """
    if not path:
        return None
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        log.warning("texture %s skipped: %s", path, exc)
        return None
    if data.startswith(PNG_MAGIC):
        return data, "image/png"
    if data.startswith(JPEG_MAGIC):
        return data, "image/jpeg"
    try:
        from PIL import Image

        with Image.open(io.BytesIO(data)) as im:
            buf = io.BytesIO()
            im.convert("RGBA").save(buf, format="PNG")
        return buf.getvalue(), "image/png"
    except Exception as exc:  # any decoder failure means "not a usable image"
        log.warning("texture %s skipped: not a readable image (%s)", path, exc)
        return None


def _file_version(path: str | os.PathLike | None) -> tuple[str, int] | None:
    """``(path, modification time)``, the cache key of a file's contents; ``None`` if absent."""
    if not path:
        return None
    try:
        return str(path), os.stat(path).st_mtime_ns
    except OSError:
        return None


def mean_texture_color(path: str | os.PathLike | None) -> np.ndarray | None:
    """Mean RGB colour (3,) in 0–1 of a texture image, alpha-weighted; ``None`` if unreadable.

    Computed once per file version (cached on path and modification time).
    """
    version = _file_version(path)
    return None if version is None else _mean_color_cached(*version)


@lru_cache(maxsize=256)
def _mean_color_cached(path: str, mtime: int) -> np.ndarray | None:
    from PIL import Image

    try:
        with Image.open(path) as im:
            im.draft("RGB", (64, 64))
            small = im.convert("RGBA").resize((32, 32))
    except Exception:
        return None
    px = np.asarray(small, float).reshape(-1, 4) / 255.0
    weight = px[:, 3]
    if weight.sum() <= 0:
        return None
    return (px[:, :3] * weight[:, None]).sum(axis=0) / weight.sum()


def texture_pixels(path: str | os.PathLike | None, max_side: int = 1024) -> np.ndarray | None:
    """A texture as (H, W, 3) float32 RGB in 0–1 (alpha dropped), at most ``max_side`` pixels
    on its longer side; ``None`` if unreadable.  Cached on path and modification time."""
    version = _file_version(path)
    return None if version is None else _texture_cached(*version, int(max_side))


@lru_cache(maxsize=32)
def _texture_cached(path: str, mtime: int, max_side: int) -> np.ndarray | None:
    from PIL import Image

    try:
        with Image.open(path) as im:
            im.draft("RGB", (max_side, max_side))
            rgb = im.convert("RGB")
            if max(rgb.size) > max_side:
                rgb.thumbnail((max_side, max_side), Image.Resampling.BILINEAR)
            out = np.asarray(rgb, np.float32) / 255.0
    except Exception:
        return None
    out.flags.writeable = False
    return out


def image_extension(mime: str) -> str:
    return ".jpg" if mime == "image/jpeg" else ".png"
