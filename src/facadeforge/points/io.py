"""Point cloud files → :class:`~.cloud.PointCloud`: PLY, LAS/LAZ and text (XYZ/TXT/CSV/PTS).

``hohmann2009`` §3 (CityFit) starts from LIDAR "converted from a text based representation into
a binary format"; this module is that first step for the scan formats in use today:

- **PLY** (ascii, binary little and big endian; read and written with ``plyfile``): the
  ``vertex`` element's ``x y z`` (float or double), colours (``red green blue`` / ``r g b``,
  uchar or float 0–1), intensity (``intensity``, ``scalar_intensity``, ``reflectance``…),
  normals (``nx ny nz``), semantic labels (``class``, ``classification``, ``label``…) and
  instances (``instance``, ``object``…); names are matched case-insensitively.  Paris-Lille-3D
  stores the semantic class in ``class`` and the object id in ``label``: when a file has both and
  no instance property, ``label`` is read as the instance.  Every other scalar vertex property
  lands in ``PointCloud.extra``.  A ``comment crs …`` (or ``obj_info crs …``, or any comment
  naming ``EPSG:nnnn``) gives the CRS; :func:`write_ply` also writes ``comment label <i>
  <name>`` lines and ``comment up <axis>`` that the reader restores.
- **LAS / LAZ** (``laspy`` with the ``lazrs`` backend): scaled coordinates as float64,
  intensity, 16-bit colour → 8-bit (the high byte), classification → labels named by the ASPRS
  table :data:`ASPRS_CLASSES` (a file whose points are all class 0, "never classified", gets no
  labels), GPS time and extra-bytes dimensions in ``extra``, CRS from the header's VLRs as
  ``"EPSG:nnnn"`` or WKT.
- **Text** (``.xyz .txt .csv .pts``): whitespace, comma or semicolon separated numbers; without a
  header the columns are ``x y z [intensity] [r g b]`` by count (3, 4, 6 or 7); a header line of
  names (``x y z intensity``, CloudCompare's ``//X,Y,Z,Intensity``) maps columns by name; the
  point count on a ``.pts`` file's first line is skipped.  Parsing is ``np.loadtxt`` (NumPy's
  C parser since 1.23: measured faster here than ``np.array(bytes.split(), float)`` or
  ``np.fromstring``); a line-by-line scan runs only after a failure, to name the bad line.

Units: coordinates in the file's units (metres for every format above), intensity as stored.
Every failure is a :class:`~.cloud.PointCloudError` that names the file and the fix.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .cloud import PointCloud, PointCloudError

__all__ = ["ASPRS_CLASSES", "DEFAULT_UP", "MAX_CLOUD_BYTES", "READERS", "SUPPORTED_SUFFIXES",
           "read_cloud", "read_las", "read_ply", "read_text", "write_ply"]

#: Largest point cloud file read (bytes); larger scans must be tiled first.
MAX_CLOUD_BYTES: int = 4 << 30
#: Vertical axis when the caller names none: z, as in LAS, PLY scans, NUIST and Paris-Lille-3D.
DEFAULT_UP: int = 2

#: ASPRS LAS 1.4 (R15) standard classification codes → label names; 23–63 are reserved and
#: 64–255 user definable (named ``reserved_N`` / ``user_N``).
ASPRS_CLASSES: dict[int, str] = {
    0: "never_classified", 1: "unclassified", 2: "ground", 3: "low_vegetation",
    4: "medium_vegetation", 5: "high_vegetation", 6: "building", 7: "low_point",
    8: "reserved_8", 9: "water", 10: "rail", 11: "road_surface", 12: "reserved_12",
    13: "wire_guard", 14: "wire_conductor", 15: "transmission_tower",
    16: "wire_structure_connector", 17: "bridge_deck", 18: "high_noise",
    19: "overhead_structure", 20: "ignored_ground", 21: "snow", 22: "temporal_exclusion",
}

# Attribute names, lower case, in order of preference.
_INTENSITY = ("intensity", "scalar_intensity", "reflectance", "scalar_reflectance",
              "remission", "scalar_remission", "intensities", "i")
_RGB = (("red", "green", "blue"), ("r", "g", "b"), ("diffuse_red", "diffuse_green", "diffuse_blue"),
        ("scalar_red", "scalar_green", "scalar_blue"))
_NORMALS = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"),
            ("normalx", "normaly", "normalz"), ("scalar_nx", "scalar_ny", "scalar_nz"))
_CLASS = ("classification", "class", "scalar_classification", "scalar_class", "semantic",
          "scalar_semantic", "semantic_label", "scalar_semantic_label", "category")
_LABEL = ("label", "scalar_label", "labels", "scalar_labels")
_INSTANCE = ("instance", "scalar_instance", "instance_id", "scalar_instance_id", "instance_label",
             "object", "scalar_object", "object_id", "scalar_object_id")

_TEXT_LAYOUTS = {3: ("x", "y", "z"), 4: ("x", "y", "z", "intensity"),
                 6: ("x", "y", "z", "r", "g", "b"), 7: ("x", "y", "z", "intensity", "r", "g", "b")}
#: Codes below this become label indices as they are (names ``"0"``…); larger ones are compacted.
_IDENTITY_CODES = 1024
_HEAD_BYTES = 1 << 20


# ---------------------------------------------------------------------------------- helpers
def _resolve_up(up: int | None, source: str, default: int = DEFAULT_UP) -> int:
    if up is None:
        return default
    if up not in (0, 1, 2):
        raise PointCloudError(f"{source}: up axis must be 0 (x), 1 (y) or 2 (z), got {up!r}")
    return int(up)


def _check_file(path: str | os.PathLike, kind: str) -> Path:
    path = Path(path)
    if path.is_dir():
        raise PointCloudError(f"point cloud {path} is a folder; give one {kind} file in it")
    if not path.is_file():
        raise PointCloudError(f"point cloud {path} not found; check the path (supported: "
                              f"{', '.join(SUPPORTED_SUFFIXES)})")
    size = path.stat().st_size
    if size > MAX_CLOUD_BYTES:
        raise PointCloudError(f"point cloud {path} is {size / 2**30:.1f} GiB, over the "
                              f"{MAX_CLOUD_BYTES / 2**30:.1f} GiB limit (MAX_CLOUD_BYTES); tile or "
                              "subsample it first (e.g. CloudCompare, PDAL, lastile)")
    if size == 0:
        raise PointCloudError(f"point cloud {path} is an empty file; it holds no points")
    return path


def _check_count(n: int, max_points: int | None, source: str) -> None:
    if max_points is not None and n > max_points:
        raise PointCloudError(f"{source} holds {n:,} points, more than max_points={max_points:,}; "
                              "subsample or tile the scan, or raise max_points")
    if n == 0:
        raise PointCloudError(f"{source} holds no points; check that it is the scan you meant")


def _finish(xyz: np.ndarray, source: str, up: int, max_points: int | None,
            where: Callable[[int], str] | None = None, **attrs) -> PointCloud:
    """The checked :class:`PointCloud` (empty, max_points and NaN checks named by file)."""
    _check_count(len(xyz), max_points, source)
    bad = ~np.isfinite(xyz).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        at = where(first) if where is not None else f"point {first}"
        raise PointCloudError(f"{source}: {int(bad.sum()):,} points have NaN or infinite "
                              f"coordinates (first at {at}); remove them from the file (e.g. "
                              "CloudCompare 'Filter points by value') and load it again")
    return PointCloud(xyz, up=up, source=source, **attrs)


def _to_uint8(channels: np.ndarray) -> np.ndarray:
    """(N, 3) colour of any type → uint8: 8-bit integers as they are, 16-bit integers by their
    high byte, floats 0–1 scaled by 255 (floats up to 255 taken as they are)."""
    a = np.asarray(channels)
    if a.dtype == np.uint8:
        return a
    if np.issubdtype(a.dtype, np.integer) or a.dtype == np.bool_:
        v = a.astype(np.int64)
        if v.size and v.max() > 255:
            v = v >> 8
        return np.clip(v, 0, 255).astype(np.uint8)
    f = np.nan_to_num(a.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    hi = f.max(initial=0.0)
    if hi <= 1.0:
        f = f * 255.0
    elif hi > 255.0:
        f = f / 256.0
    return np.clip(np.rint(f), 0, 255).astype(np.uint8)


def _codes(values: np.ndarray) -> np.ndarray:
    """Integer codes, −1 for NaN or negative values (float scalar fields of CloudCompare)."""
    a = np.asarray(values)
    if np.issubdtype(a.dtype, np.floating):
        ok = np.isfinite(a)
        a = np.where(ok, np.rint(np.where(ok, a, -1)), -1)
    a = a.astype(np.int64)
    return np.where(a < 0, -1, a)


def _labels_from_codes(values: np.ndarray,
                       names: dict[int, str] | None = None) -> tuple[np.ndarray, tuple[str, ...]]:
    """Label codes → ``(labels, label_names)``.  Codes below 1024 are the indices themselves
    (named from ``names`` or ``"<code>"``); larger codes are numbered in sorted order."""
    codes = _codes(values)
    names = names or {}
    valid = codes >= 0
    if not valid.any():
        return codes.astype(np.int32), ()
    hi = int(codes.max())
    if hi < _IDENTITY_CODES:
        top = max(hi, max(names, default=-1))
        return codes.astype(np.int32), tuple(names.get(c, str(c)) for c in range(top + 1))
    used = np.unique(codes[valid])
    labels = np.where(valid, np.searchsorted(used, codes), -1).astype(np.int32)
    return labels, tuple(names.get(int(c), str(int(c))) for c in used)


def _instances(values: np.ndarray) -> np.ndarray:
    codes = _codes(values)
    if codes.size and codes.max() > np.iinfo(np.int32).max:   # compact huge object ids
        used = np.unique(codes[codes >= 0])
        codes = np.where(codes >= 0, np.searchsorted(used, codes), -1)
    return codes.astype(np.int32)


def _pick(names: dict[str, str], candidates) -> str | None:
    for c in candidates:
        if c in names:
            return names[c]
    return None


def _pick3(names: dict[str, str], candidates) -> tuple[str, str, str] | None:
    for trio in candidates:
        if all(c in names for c in trio):
            return tuple(names[c] for c in trio)
    return None


def _attributes(names: list[str], column: Callable[[str], np.ndarray], source: str,
                label_names: dict[int, str] | None = None) -> tuple[np.ndarray, dict]:
    """Coordinates and the PointCloud keyword attributes of named columns (PLY and text)."""
    lower: dict[str, str] = {}
    for n in names:
        lower.setdefault(n.lower(), n)
    xyz_names = _pick3(lower, (("x", "y", "z"),))
    if xyz_names is None:
        raise PointCloudError(f"{source}: no x, y, z columns (it has {', '.join(names) or 'none'}); "
                              "a point cloud needs coordinates named x, y and z")
    xyz = np.column_stack([np.asarray(column(n), np.float64) for n in xyz_names])
    used = set(xyz_names)
    attrs: dict = {}
    if (n := _pick(lower, _INTENSITY)) is not None:
        attrs["intensity"] = np.asarray(column(n), np.float32)
        used.add(n)
    if (trio := _pick3(lower, _RGB)) is not None:
        attrs["rgb"] = _to_uint8(np.column_stack([column(n) for n in trio]))
        used.update(trio)
    if (trio := _pick3(lower, _NORMALS)) is not None:
        attrs["normals"] = np.column_stack([column(n) for n in trio]).astype(np.float32)
        used.update(trio)
    cls, lab, inst = _pick(lower, _CLASS), _pick(lower, _LABEL), _pick(lower, _INSTANCE)
    if cls is not None and lab is not None and inst is None:
        inst = lab          # Paris-Lille-3D: 'class' is the semantic class, 'label' the object
    semantic = cls if cls is not None else lab
    if semantic is not None:
        attrs["labels"], attrs["label_names"] = _labels_from_codes(column(semantic), label_names)
        used.add(semantic)
    if inst is not None:
        attrs["instance"] = _instances(column(inst))
        used.add(inst)
    extra = {}
    for n in names:
        if n not in used:
            a = np.asarray(column(n))
            extra[n] = a.astype(a.dtype.newbyteorder("=")) if a.dtype.byteorder not in "=|" else a
    attrs["extra"] = extra
    return xyz, attrs


# -------------------------------------------------------------------------------------- PLY
_CRS_LINE = re.compile(r"^\s*(?:crs|srs|coordinate[_ ]reference[_ ]system|spatial[_ ]reference)\b"
                       r"\s*[:=]?\s*(.+?)\s*$", re.IGNORECASE)
_EPSG = re.compile(r"\bEPSG\s*:\s*(\d+)\b", re.IGNORECASE)
_LABEL_LINE = re.compile(r"^\s*label\s+(\d+)\s+(.+?)\s*$")
_UP_LINE = re.compile(r"^\s*up\s+([012])\s*$")


def _ply_crs(lines: list[str]) -> str | None:
    for line in lines:
        if m := _CRS_LINE.match(line):
            return m.group(1)
    for line in lines:
        if m := _EPSG.search(line):
            return f"EPSG:{m.group(1)}"
    return None


def _ply_vertex_count(path: Path) -> int | None:
    """The vertex count from the header, read before the data (None when not found)."""
    with open(path, "rb") as f:
        head = f.read(_HEAD_BYTES)
    if not head.startswith(b"ply"):
        raise PointCloudError(f"{path}: not a PLY file (it does not start with the 'ply' line); "
                              "check the file or rename it to its real format")
    end = head.find(b"end_header")
    for line in head[:end if end >= 0 else None].decode("latin-1").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element" and parts[1].lower() in ("vertex", "vertices"):
            try:
                return int(parts[2])
            except ValueError:
                return None
    return None


def read_ply(path: str | os.PathLike, *, up: int | None = None,
             max_points: int | None = None) -> PointCloud:
    """Read a PLY file (ascii, binary little or big endian).

    Parameters
    ----------
    path : str or Path
        The ``.ply`` file.
    up : {0, 1, 2} or None
        Vertical axis; None: the file's ``comment up`` line, else 2 (z).
    max_points : int or None
        Raise when the file holds more points (checked in the header, before reading).

    Returns
    -------
    PointCloud
        ``xyz`` float64 metres and the attributes the vertex element carries (module docstring).

    Raises
    ------
    PointCloudError
        Missing, oversized, empty or malformed file, no vertex element, no x/y/z, NaN
        coordinates, more than ``max_points`` points.
    """
    import plyfile

    path = _check_file(path, "PLY")
    source = str(path)
    count = _ply_vertex_count(path)
    if count is not None:
        _check_count(count, max_points, source)
    try:
        ply = plyfile.PlyData.read(str(path))
    except Exception as exc:   # plyfile raises struct, value, key… errors on damaged files
        raise PointCloudError(f"{source}: not a readable PLY file ({exc}); check that it was "
                              "written completely (a truncated copy?) and re-export it") from exc
    elements = {e.name.lower(): e for e in ply.elements}
    vertex = elements.get("vertex", elements.get("vertices"))
    if vertex is None:
        raise PointCloudError(f"{source}: the PLY file has no 'vertex' element (elements: "
                              f"{', '.join(e.name for e in ply.elements) or 'none'}); it holds no "
                              "points")
    lines = list(ply.comments) + list(ply.obj_info)
    label_names = {int(m.group(1)): m.group(2) for line in ply.comments
                   if (m := _LABEL_LINE.match(line))}
    file_up = next((int(m.group(1)) for line in ply.comments if (m := _UP_LINE.match(line))), None)
    data = vertex.data
    scalars = [p.name for p in vertex.properties if not isinstance(p, plyfile.PlyListProperty)]
    xyz, attrs = _attributes(scalars, lambda n: data[n], source, label_names)
    return _finish(xyz, source, _resolve_up(up, source, DEFAULT_UP if file_up is None else file_up),
                   max_points, crs=_ply_crs(lines), **attrs)


def write_ply(cloud: PointCloud, path: str | os.PathLike, binary: bool = True) -> Path:
    """Write a cloud as PLY, atomically (a temporary file beside ``path``, then ``os.replace``).

    Coordinates are written as double, intensity and normals as float, colour as uchar
    ``red green blue``, labels and instances as int ``label`` / ``instance``; 1-D numeric
    ``extra`` arrays become properties of their own name.  Comments carry the CRS
    (``crs …``), the label names (``label <i> <name>``) and a non-z up axis (``up <axis>``),
    all of which :func:`read_ply` restores.

    Parameters
    ----------
    cloud : PointCloud
    path : str or Path
        Destination file; its folder must exist.
    binary : bool
        Binary little endian (default) or ascii.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    PointCloudError
        The folder does not exist or cannot be written.
    """
    import plyfile

    path = Path(path)
    if not path.parent.is_dir():
        raise PointCloudError(f"cannot write {path}: folder {path.parent} does not exist; "
                              "create it first")
    fields: list[tuple[str, np.ndarray]] = [("x", cloud.xyz[:, 0]), ("y", cloud.xyz[:, 1]),
                                            ("z", cloud.xyz[:, 2])]
    if cloud.intensity is not None:
        fields.append(("intensity", cloud.intensity.astype(np.float32)))
    if cloud.rgb is not None:
        fields += [(n, cloud.rgb[:, k]) for k, n in enumerate(("red", "green", "blue"))]
    if cloud.normals is not None:
        fields += [(n, cloud.normals[:, k]) for k, n in enumerate(("nx", "ny", "nz"))]
    if cloud.labels is not None:
        fields.append(("label", cloud.labels.astype(np.int32)))
    if cloud.instance is not None:
        fields.append(("instance", cloud.instance.astype(np.int32)))
    taken = {n.lower() for n, _ in fields} | {c for c in _CLASS + _LABEL + _INSTANCE + _INTENSITY}
    taken |= {c for trio in _RGB + _NORMALS for c in trio}
    for key, a in cloud.extra.items():
        a = np.asarray(a)
        if (a.ndim != 1 or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key)
                or key.lower() in taken or a.dtype.kind not in "biuf"):
            warnings.warn(f"write_ply {path}: extra {key!r} ({a.dtype}, shape {a.shape}) is not a "
                          "1-D numeric array with a free property name; not written", stacklevel=2)
            continue
        fields.append((key, a.astype(np.uint8) if a.dtype == np.bool_ else a))
        taken.add(key.lower())
    arr = np.empty(len(cloud), dtype=[(n, a.dtype.newbyteorder("<")) for n, a in fields])
    for n, a in fields:
        arr[n] = a
    comments = ["generated by facadeforge"]
    if cloud.crs:
        comments.append("crs " + " ".join(cloud.crs.split()))
    comments += [f"label {i} {' '.join(name.split())}" for i, name in enumerate(cloud.label_names)]
    if cloud.up != DEFAULT_UP:
        comments.append(f"up {cloud.up}")
    ply = plyfile.PlyData([plyfile.PlyElement.describe(arr, "vertex")], text=not binary,
                          byte_order="<", comments=comments)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise PointCloudError(f"cannot write {path}: {exc}; check the folder's permissions") from exc
    try:
        with os.fdopen(fd, "wb") as f:
            ply.write(f)
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise PointCloudError(f"cannot write {path}: {exc}; check free space and "
                                  "permissions") from exc
        raise
    return path


# ---------------------------------------------------------------------------------- LAS/LAZ
def _las_crs(header, source: str) -> str | None:
    try:
        crs = header.parse_crs()
    except Exception as exc:  # pyproj and laspy raise many types on odd CRS records
        warnings.warn(f"{source}: the CRS records cannot be parsed ({exc}); reading the points "
                      "without a CRS", stacklevel=3)
        return None
    if crs is None:
        return None
    epsg = crs.to_epsg()
    return f"EPSG:{epsg}" if epsg is not None else crs.to_wkt()


def read_las(path: str | os.PathLike, *, up: int | None = None,
             max_points: int | None = None) -> PointCloud:
    """Read a LAS or LAZ file (LAZ through the ``lazrs`` backend).

    Parameters
    ----------
    path : str or Path
        The ``.las`` / ``.laz`` file.
    up : {0, 1, 2} or None
        Vertical axis; None: 2 (z, the LAS convention).
    max_points : int or None
        Raise when the header announces more points (checked before reading them).

    Returns
    -------
    PointCloud
        ``xyz`` float64 (scale and offset applied), intensity (0–65535), rgb when the point
        format has colour (high byte of the 16-bit values), labels from the classification with
        :data:`ASPRS_CLASSES` names, ``extra["gps_time"]`` and extra-bytes dimensions (one named
        like an instance id, ``instance`` / ``object``…, becomes ``instance``), crs.

    Raises
    ------
    PointCloudError
        Missing, oversized, empty or malformed file, LAZ without a backend, NaN coordinates,
        more than ``max_points`` points.
    """
    import laspy

    path = _check_file(path, "LAS/LAZ")
    source = str(path)
    try:
        with laspy.open(str(path), laz_backend=laspy.LazBackend.Lazrs) as reader:
            header = reader.header
            _check_count(int(header.point_count), max_points, source)
            las = reader.read()
    except PointCloudError:
        raise
    except laspy.errors.LazError as exc:
        raise PointCloudError(f"{source}: cannot decompress the LAZ file ({exc}); install the "
                              "lazrs backend (pip install 'laspy[lazrs]') or check the file") from exc
    except Exception as exc:   # laspy raises struct, value, key… errors on damaged files
        raise PointCloudError(f"{source}: not a readable LAS/LAZ file ({exc}); check that it was "
                              "written completely and re-export it") from exc
    xyz = np.column_stack([np.asarray(las.x, np.float64), np.asarray(las.y, np.float64),
                           np.asarray(las.z, np.float64)])
    dims = set(las.point_format.dimension_names)
    attrs: dict = {"intensity": np.asarray(las.intensity, np.float32)}
    if {"red", "green", "blue"} <= dims:
        attrs["rgb"] = _to_uint8(np.column_stack([np.asarray(las[c]) for c in
                                                  ("red", "green", "blue")]).astype(np.uint16))
    cls = np.asarray(las.classification, np.int64)
    if cls.size and cls.any():
        top = int(cls.max())
        attrs["labels"] = cls.astype(np.int32)
        attrs["label_names"] = tuple(ASPRS_CLASSES.get(c, f"reserved_{c}" if c < 64 else f"user_{c}")
                                     for c in range(top + 1))
    extra: dict[str, np.ndarray] = {}
    if "gps_time" in dims:
        extra["gps_time"] = np.asarray(las.gps_time, np.float64)
    extra_names = list(las.point_format.extra_dimension_names)
    inst = _pick({n.lower(): n for n in extra_names}, _INSTANCE)
    for n in extra_names:
        a = np.asarray(las[n])
        if n == inst:
            attrs["instance"] = _instances(a)
        else:
            extra[n] = a.astype(a.dtype.newbyteorder("=")) if a.dtype.byteorder not in "=|" else a
    return _finish(xyz, source, _resolve_up(up, source), max_points,
                   crs=_las_crs(header, source), extra=extra, **attrs)


# ------------------------------------------------------------------------------------- text
def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _split(line: str, delimiter: str | None) -> list[str]:
    if delimiter is None:
        return line.split()
    return [t.strip() for t in line.split(delimiter)]


def _strip_comment(line: str) -> str:
    for mark in ("#", "//"):
        k = line.find(mark)
        if k >= 0:
            line = line[:k]
    return line


def _text_preamble(path: Path) -> tuple[int, int, str | None, list[str] | None, int]:
    """``(skip, data_line, delimiter, names, ncols)``: lines before the data, the first data
    line's number (1-based), the column separator, the header names and the column count."""
    with open(path, "rb") as f:
        head = f.read(_HEAD_BYTES)
    lines = head.decode("latin-1").split("\n")
    if len(head) == _HEAD_BYTES and len(lines) > 1:
        lines = lines[:-1]                                  # the last one may be cut
    header: list[str] | None = None
    comment_names: list[list[str]] = []
    first = True
    for k, raw in enumerate(lines):
        line = raw.strip()
        if not line:
            continue
        is_comment = line.startswith(("#", "//"))
        body = line.lstrip("/#").strip() if is_comment else line
        tokens = [t for t in re.split(r"[,;\s]+", body) if t]
        if first and not is_comment and path.suffix.lower() == ".pts" and len(tokens) == 1 \
                and tokens[0].isdigit():
            first = False
            continue                                        # the .pts point count
        first = False
        if is_comment:
            if {"x", "y", "z"} <= {t.strip("\"'").lower() for t in tokens}:
                comment_names.append(tokens)              # CloudCompare's //X,Y,Z,...
            continue
        if not all(_is_number(t) for t in tokens):
            if header is not None:
                raise PointCloudError(f"{path}:{k + 1}: {line[:60]!r} is not a line of numbers; "
                                      "a text cloud holds one header line at most, then one "
                                      "point per line")
            header = tokens
            continue
        delimiter = "," if "," in line else ";" if ";" in line else None
        ncols = len(_split(_strip_comment(line), delimiter))
        names = header
        if names is None:
            names = next((c for c in reversed(comment_names) if len(c) == ncols), None)
        if names is not None and len(names) != ncols:
            raise PointCloudError(f"{path}: the header names {len(names)} columns "
                                  f"({' '.join(names)}) but line {k + 1} has {ncols}; make them "
                                  "agree")
        return k, k + 1, delimiter, names, ncols
    raise PointCloudError(f"{path}: no line of numbers in its first {len(head):,} bytes; it "
                          "holds no points (expected lines like 'x y z [intensity] [r g b]')")


def _diagnose_text(path: Path, skip: int, delimiter: str | None, ncols: int,
                   data_line: int, row: int | None = None) -> str:
    """After a failed parse (or for ``row``): the message naming the offending line."""
    n = -1
    with open(path, encoding="latin-1", newline=None) as f:
        for lineno, raw in enumerate(f, 1):
            if lineno <= skip:
                continue
            line = _strip_comment(raw).strip()
            if not line:
                continue
            n += 1
            if row is not None:
                if n == row:
                    return f"line {lineno}"
                continue
            tokens = _split(line, delimiter)
            if len(tokens) != ncols:
                return (f"line {lineno} has {len(tokens)} columns where line {data_line} has "
                        f"{ncols}; every point needs the same columns")
            for c, t in enumerate(tokens, 1):
                if not _is_number(t):
                    return (f"line {lineno}, column {c}: {t[:30]!r} is not a number; fix or "
                            "remove that line")
    return ""


def read_text(path: str | os.PathLike, *, up: int | None = None,
              max_points: int | None = None) -> PointCloud:
    """Read a text cloud (``.xyz .txt .csv .pts``): one point per line.

    Parameters
    ----------
    path : str or Path
        The text file.  Columns are separated by whitespace, commas or semicolons; lines
        starting with ``#`` or ``//`` are comments.  Without a header line the columns are
        ``x y z`` (3), ``x y z intensity`` (4), ``x y z r g b`` (6) or ``x y z intensity r g b``
        (7); a header line of names maps columns by name (unknown ones go to ``extra``).
    up : {0, 1, 2} or None
        Vertical axis; None: 2 (z).
    max_points : int or None
        Raise when the file holds more points (reading stops one past the cap).

    Returns
    -------
    PointCloud

    Raises
    ------
    PointCloudError
        Missing, oversized or empty file, ragged or non-numeric lines (with the line number),
        an unknown column count without a header, NaN coordinates, more than ``max_points``.
    """
    path = _check_file(path, "text")
    source = str(path)
    skip, data_line, delimiter, names, ncols = _text_preamble(path)
    if names is None:
        if ncols not in _TEXT_LAYOUTS:
            raise PointCloudError(
                f"{source}: lines have {ncols} columns; without a header line the layouts are "
                "3 (x y z), 4 (x y z intensity), 6 (x y z r g b) and 7 (x y z intensity r g b); "
                "add a first line naming the columns, e.g. 'x y z intensity r g b nx ny nz'")
        names = list(_TEXT_LAYOUTS[ncols])
    names = [n.strip("\"'") for n in names]
    if len({n.lower() for n in names}) != len(names):
        raise PointCloudError(f"{source}: the header repeats a column name ({' '.join(names)}); "
                              "give each column its own name")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)      # "input contained no data"
            table = np.loadtxt(path, dtype=np.float64, delimiter=delimiter, comments=("#", "//"),
                               skiprows=skip, ndmin=2, encoding="latin-1",
                               max_rows=None if max_points is None else max_points + 1)
    except ValueError as exc:
        why = _diagnose_text(path, skip, delimiter, ncols, data_line)
        raise PointCloudError(f"{source}: {why or exc}") from exc
    if table.shape[1] != ncols:                                # only when there is no data row
        table = table.reshape(0, ncols)
    if max_points is not None and len(table) > max_points:
        raise PointCloudError(f"{source} holds more than max_points={max_points:,} points; "
                              "subsample or tile the scan, or raise max_points")
    index = {n: k for k, n in enumerate(names)}
    xyz, attrs = _attributes(names, lambda n: table[:, index[n]], source)

    def where(row: int) -> str:
        return _diagnose_text(path, skip, delimiter, ncols, data_line, row) or f"point {row}"

    return _finish(xyz, source, _resolve_up(up, source), max_points, where=where, **attrs)


# ---------------------------------------------------------------------------------- dispatch
#: Reader of each file suffix (lower case).
READERS: dict[str, Callable[..., PointCloud]] = {
    ".ply": read_ply, ".las": read_las, ".laz": read_las,
    ".xyz": read_text, ".txt": read_text, ".csv": read_text, ".pts": read_text,
}
SUPPORTED_SUFFIXES: tuple[str, ...] = tuple(READERS)


def read_cloud(path: str | os.PathLike, *, up: int | None = None,
               max_points: int | None = None) -> PointCloud:
    """Read a point cloud file of any supported format, chosen by its suffix.

    Parameters
    ----------
    path : str or Path
        ``.ply``, ``.las``, ``.laz``, ``.xyz``, ``.txt``, ``.csv`` or ``.pts`` (any case).
    up : {0, 1, 2} or None
        Index of the vertical axis; None: 2 (z up — LAS, PLY scans, NUIST, Paris-Lille-3D).
    max_points : int or None
        Raise :class:`PointCloudError` when the file holds more points.

    Returns
    -------
    PointCloud
        Coordinates float64 in metres in the file's frame, with the attributes it carries.

    Raises
    ------
    PointCloudError
        Unknown suffix (the supported ones are listed), and every reader's errors.
    """
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    if path.is_dir():
        raise PointCloudError(f"point cloud {path} is a folder; give one file in it "
                              f"({', '.join(SUPPORTED_SUFFIXES)})")
    if reader is None:
        if not path.exists():
            raise PointCloudError(f"point cloud {path} not found; check the path (supported: "
                                  f"{', '.join(SUPPORTED_SUFFIXES)})")
        raise PointCloudError(f"{path}: unknown point cloud format {path.suffix or '(no suffix)'!r}; "
                              f"supported suffixes are {', '.join(SUPPORTED_SUFFIXES)} (convert it, "
                              "e.g. with CloudCompare or PDAL)")
    return reader(path, up=up, max_points=max_points)
