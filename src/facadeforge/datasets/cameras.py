"""Calibrated cameras of a photo set: VisualSFM's ``cameras_v2.txt`` and what is computed from it.

The RueMonge2014 ``train/cameras.txt`` (``../shared/data/README.md``) is in this layout, one block
per camera after a comment header and the camera count::

    00000005.jpg                          file name of the undistorted image
    /…/IMG_5758.JPG                       original file name (holds the photo's IMG_NNNN id)
    1054.36413574                         focal length f, pixels
    533.5 400                             principal point (cx, cy)
    -2.19 -22.29 -12.38                   translation T (P = K [R T])
    2.00 -0.02 25.52                      camera centre C (P = K [R -RC])
    -1.00 -0.68 -1.18                     rotation, axis-angle
    0.65 -0.44 -0.30 -0.52                rotation, quaternion
    r00 r01 r02                           rotation, 3×3 matrix (three lines)
    r10 r11 r12
    r20 r21 r22
    -0.0185 0                             normalised radial distortion (k·f², then 0)
    0 0 0                                 latitude/longitude/altitude from EXIF (optional)

**Orientation.** The cameras were calibrated on landscape images (principal point 533.5, 400:
1067 × 800) while the shared photos are 800 × 1067 portrait.  Triangulating SIFT matches of
neighbouring photos shows which way they were turned: a photo pixel ``(x, y)`` is the
calibrated image's ``(u, v) = (y, W − 1 − x)`` with ``W`` the photo's width (reprojection
error 0.6–1.3 px median on four pairs along the street, against 20–60 px for the other
rotation and hundreds for none; ``tests/datasets/test_cameras.py`` repeats the check).
:meth:`Camera.project` returns photo pixels, turning them when the photo's shape says so.

**Other formats.** :func:`read_cameras` recognises a camera file by its content and also reads

- VisualSFM's ``.nvm`` (``NVM_V3``; http://ccwu.me/vsfm/doc.html#nvm): one line per camera,
  ``name f qw qx qy qz cx cy cz r 0``, quaternion of world → camera in our convention and the
  centre; the principal point is the image centre (see *image sizes* below);
- Bundler's ``bundle.out`` v0.3 (Bundler user manual, "Output format",
  https://www.cs.cornell.edu/~snavely/bundler/bundler-v0.4-manual.html): per camera
  ``f k1 k2``, the rotation ``R`` and translation ``t`` of ``X_cam = R X + t``; Bundler's camera
  looks down −z with y up and its image coordinates are centred with y up, so ours is
  ``R_ours = diag(1, −1, −1) R``, ``C = −Rᵀ t``, principal point the image centre; cameras with
  ``f = 0`` were not registered and are skipped; names are the first tokens of ``list.txt``
  beside the file (or beside Bundler's own ``bundle/`` folder), else ``camera_NNNN``;
- COLMAP text models (COLMAP documentation, "Output format",
  https://colmap.github.io/format.html): ``cameras.txt`` (``CAMERA_ID MODEL WIDTH HEIGHT
  PARAMS[]``; models SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV) and
  ``images.txt`` (two lines per image, ``IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`` then
  the 2D points, possibly an empty line); COLMAP's rotation is world → camera in our convention
  (x right, y down, looking down +z), ``C = −Rᵀ t``, the id is the image name's stem.

*Image sizes.* Bundler and NVM files do not say how large the images are, yet the principal
point is their centre: the size is read from the image's header (PIL, no decoding) when the
name resolves to a file, else taken from ``image_size=(width, height)`` (or a mapping id →
size), else the read fails naming that argument.  COLMAP gives the size
(:attr:`Camera.image_size`); VisualSFM's ``cameras_v2.txt`` gives the principal point only.

*Conventions passed through unchanged.* Sub-pixel origins differ (COLMAP puts the top-left
pixel's centre at (0.5, 0.5)); principal points are taken as the files give them.  Lens
distortion is kept as the file's own coefficients (``radial``, ``radial2``: VisualSFM's
normalised undistortion of measurements ``k·f²``, Bundler's and COLMAP's distortion of
normalised projections ``k1``, ``k2``) and never applied by :meth:`Camera.project`; writers copy
them without converting between the models.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = [
    "PHOTO_SUFFIXES",
    "Camera",
    "photo_files",
    "read_bundler",
    "read_cameras",
    "read_colmap",
    "read_nvm",
    "read_visualsfm",
    "seen_intervals",
    "street_positions",
    "write_bundler",
    "write_colmap",
    "write_visualsfm",
]

#: Largest camera file read (a text file of a few hundred cameras is a few hundred kB).
MAX_CAMERA_FILE_BYTES = 64 * 1024 * 1024

_ID = re.compile(r"(IMG_\d+)", re.IGNORECASE)


@dataclass(frozen=True, eq=False)
class Camera:
    """One calibrated pinhole camera.

    ``R`` rotates world into camera coordinates (rows: the camera's x, y and viewing axes in
    world coordinates), ``C`` is the centre; ``size`` is the calibrated image's (width, height):
    ``image_size`` when the file said it, else twice the principal point.  ``focal_y`` is the
    vertical focal length where it differs from ``focal``; ``radial`` and ``radial2`` are the
    file's own first two radial distortion coefficients (module docstring; not applied).
    """

    id: str
    file: str
    focal: float
    principal: tuple[float, float]
    R: np.ndarray
    C: np.ndarray
    radial: float = 0.0
    radial2: float = 0.0
    focal_y: float | None = None
    image_size: tuple[int, int] | None = None

    @property
    def size(self) -> tuple[int, int]:
        if self.image_size is not None:
            return int(self.image_size[0]), int(self.image_size[1])
        return round(2 * self.principal[0]), round(2 * self.principal[1])

    @property
    def fy(self) -> float:
        """The vertical focal length (``focal_y`` when set, else ``focal``)."""
        return self.focal if self.focal_y is None else self.focal_y

    @property
    def K(self) -> np.ndarray:
        f, (cx, cy) = self.focal, self.principal
        return np.array([[f, 0.0, cx], [0.0, self.fy, cy], [0.0, 0.0, 1.0]])

    @property
    def P(self) -> np.ndarray:
        """The 3 × 4 projection matrix ``K [R | −R C]`` of the calibrated image."""
        return self.K @ np.hstack([self.R, -(self.R @ self.C)[:, None]])

    def turned(self, photo_shape: tuple[int, int]) -> bool:
        """Whether a photo of ``photo_shape`` (height, width) is the calibrated image turned a
        quarter (see the module docstring)."""
        w, h = self.size
        return (photo_shape[0], photo_shape[1]) == (w, h) and w != h

    def to_photo(self, uv: np.ndarray, photo_shape: tuple[int, int]) -> np.ndarray:
        """Calibrated-image pixels ``(N, 2)`` → pixels of the photo as it is stored."""
        uv = np.asarray(uv, np.float64)
        if not self.turned(photo_shape):
            return uv
        return np.c_[photo_shape[1] - 1 - uv[:, 1], uv[:, 0]]

    def from_photo(self, xy: np.ndarray, photo_shape: tuple[int, int]) -> np.ndarray:
        """Pixels of the stored photo ``(N, 2)`` → calibrated-image pixels."""
        xy = np.asarray(xy, np.float64)
        if not self.turned(photo_shape):
            return xy
        return np.c_[xy[:, 1], photo_shape[1] - 1 - xy[:, 0]]

    def project(self, X: np.ndarray, photo_shape: tuple[int, int] | None = None) -> np.ndarray:
        """World points ``(N, 3)`` → pixels ``(N, 2)`` (of the photo when its shape is given)."""
        X = np.asarray(X, np.float64).reshape(-1, 3)
        x = self.P @ np.c_[X, np.ones(len(X))].T
        uv = (x[:2] / x[2]).T
        return self.to_photo(uv, photo_shape) if photo_shape is not None else uv

    def depth(self, X: np.ndarray) -> np.ndarray:
        """Distance of world points in front of the camera along its viewing axis."""
        return (np.asarray(X, np.float64).reshape(-1, 3) - self.C) @ self.R[2]

    def ray(self, xy: np.ndarray, photo_shape: tuple[int, int] | None = None) -> np.ndarray:
        """Pixels ``(N, 2)`` (of the photo when its shape is given, else of the calibrated
        image) → unit world directions ``(N, 3)`` of the rays from ``C`` through them.

        The inverse of :meth:`project` for the pinhole (distortion ignored):
        ``project(C + t · ray(xy)) == xy`` for every ``t > 0``.
        """
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        uv = self.from_photo(xy, photo_shape) if photo_shape is not None else xy
        d = np.linalg.solve(self.K, np.c_[uv, np.ones(len(uv))].T)
        w = (self.R.T @ d).T
        return w / np.linalg.norm(w, axis=1, keepdims=True)


def _floats(line: str, n: int, where: str,
            layout: str = "VisualSFM's cameras_v2.txt") -> list[float]:
    parts = line.split()
    try:
        values = [float(p) for p in parts[:n]]
    except ValueError:
        values = []
    if len(values) != n or not all(np.isfinite(values)):
        raise InputError(f"{where}: expected {n} numbers, got {line.strip()[:80]!r}; the file "
                         f"is not in {layout} layout")
    return values


def read_visualsfm(path: str | Path) -> dict[str, Camera]:
    """Read a VisualSFM ``cameras_v2.txt`` file.

    Returns
    -------
    dict
        Photo id → :class:`Camera`.  The id is the ``IMG_NNNN`` found in the original file
        name, else that name's stem (the id the photo folders use).

    Raises
    ------
    InputError
        Missing, oversized or malformed file, a rotation that is not one, duplicate ids.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"camera file {path} not found; pass VisualSFM's cameras_v2.txt "
                         "(RueMonge: train/cameras.txt)")
    if path.stat().st_size > MAX_CAMERA_FILE_BYTES:
        raise InputError(f"camera file {path} is larger than {MAX_CAMERA_FILE_BYTES >> 20} MiB; "
                         "it is not a cameras_v2.txt file")
    raw = path.read_text(encoding="utf-8", errors="replace").splitlines()
    lines = [(i + 1, s.strip()) for i, s in enumerate(raw)
             if s.strip() and not s.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"camera file {path} holds no cameras")
    where = f"{path}:{lines[0][0]}"
    count = int(_floats(lines[0][1], 1, where)[0])
    cameras: dict[str, Camera] = {}
    i = 1
    for _ in range(count):
        if i + 11 > len(lines):
            raise InputError(f"{path}:{lines[-1][0]}: the file announces {count} cameras but "
                             f"ends after {len(cameras)}; it is truncated")
        block = lines[i:i + 12]
        at = [f"{path}:{n}" for n, _ in block]
        name, original = block[0][1], block[1][1]
        f = _floats(block[2][1], 1, at[2])[0]
        principal = _floats(block[3][1], 2, at[3])
        C = np.array(_floats(block[5][1], 3, at[5]))
        R = np.array([_floats(block[8 + k][1], 3, at[8 + k]) for k in range(3)])
        radial = _floats(block[11][1], 1, at[11])[0]
        if f <= 0 or not np.allclose(R @ R.T, np.eye(3), atol=1e-4):
            raise InputError(f"{at[2]}: camera {name!r} has a focal length ≤ 0 or a rotation "
                             "matrix that is not orthonormal")
        i += 12
        # an optional EXIF line: three numbers where the next block's file name would be
        if i < len(lines) and len(lines[i][1].split()) == 3 and not _is_name(lines[i][1]):
            i += 1
        m = _ID.search(original) or _ID.search(name)
        cid = m.group(1).upper() if m else Path(original.replace("\\", "/")).stem
        if cid in cameras:
            raise InputError(f"{at[0]}: camera {cid!r} occurs twice in {path}")
        cameras[cid] = Camera(cid, name, float(f), (principal[0], principal[1]), R, C, radial)
    return cameras


def _is_name(line: str) -> bool:
    return bool(re.search(r"\.(jpe?g|png|tiff?)$", line, re.IGNORECASE))


# ------------------------------------------------------------------- other camera formats
_D = np.diag([1.0, -1.0, -1.0])       # Bundler's camera axes (x right, y up, looking down −z) ↔ ours
_FORMATS = ("VisualSFM (cameras_v2.txt or an NVM_V3 .nvm file), Bundler (bundle.out, "
            "'# Bundle file v0.3') or a COLMAP text model (a folder with cameras.txt and "
            "images.txt, or one of its files)")
#: COLMAP camera models read, with their parameter names (COLMAP "Camera models").
_COLMAP_MODELS: dict[str, tuple[str, ...]] = {
    "SIMPLE_PINHOLE": ("f", "cx", "cy"),
    "PINHOLE": ("fx", "fy", "cx", "cy"),
    "SIMPLE_RADIAL": ("f", "cx", "cy", "k"),
    "RADIAL": ("f", "cx", "cy", "k1", "k2"),
    "OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
}
ImageSize = tuple[int, int] | Mapping[str, tuple[int, int]] | None


def _read_lines(path: Path, what: str) -> list[str]:
    """The lines of a camera file, refusing missing and oversized ones."""
    if not path.is_file():
        raise InputError(f"{what} {path} not found")
    if path.stat().st_size > MAX_CAMERA_FILE_BYTES:
        raise InputError(f"{what} {path} is larger than {MAX_CAMERA_FILE_BYTES >> 20} MiB; "
                         "it is not a camera file")
    return path.read_text(encoding="utf-8", errors="replace").splitlines()


def _data_lines(raw: list[str]) -> list[tuple[int, str]]:
    """(line number, stripped text) of the lines that are neither blank nor comments."""
    return [(i + 1, s.strip()) for i, s in enumerate(raw)
            if s.strip() and not s.lstrip().startswith("#")]


def _ints(line: str, n: int, where: str, layout: str) -> list[int]:
    values = _floats(line, n, where, layout)
    if any(v != int(v) or v < 0 for v in values):
        raise InputError(f"{where}: expected {n} counts, got {line.strip()[:80]!r}; the file is "
                         f"not in {layout} layout")
    return [int(v) for v in values]


def _rotation(R: np.ndarray, where: str, name: str) -> np.ndarray:
    if not (np.allclose(R @ R.T, np.eye(3), atol=1e-4) and np.linalg.det(R) > 0):
        raise InputError(f"{where}: camera {name!r} has a rotation matrix that is not "
                         "orthonormal (or is a reflection)")
    return R


def _quaternion_matrix(q: list[float], where: str, name: str) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` (Hamilton, as COLMAP and VisualSFM write it) → R."""
    n = float(np.linalg.norm(q))
    if abs(n - 1.0) > 1e-3:
        raise InputError(f"{where}: camera {name!r} has a rotation quaternion of norm {n:.6g}, "
                         "not a unit quaternion")
    w, x, y, z = np.asarray(q) / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _matrix_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrix → unit quaternion ``(w, x, y, z)`` with ``w ≥ 0``."""
    q = np.empty(4)
    t = np.trace(R)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        q[:] = 0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(max(1.0 + R[i, i] - R[j, j] - R[k, k], 0.0))
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def _stem(name: str) -> str:
    return Path(name.replace("\\", "/")).stem


def _image_size_of(folder: Path, name: str, cid: str, image_size: ImageSize,
                   where: str, layout: str) -> tuple[int, int]:
    """The size of image ``name``: its file's header, else ``image_size``, else an error."""
    image = folder / name.replace("\\", "/")
    if name and image.is_file():
        from PIL import Image
        try:
            with Image.open(image) as im:
                w, h = im.size
        except Exception as e:  # noqa: BLE001 - any unreadable header is the same input error
            raise InputError(f"{where}: cannot read the size of image {image} ({e}); pass "
                             "image_size=(width, height)") from e
        return int(w), int(h)
    size = image_size.get(cid) if isinstance(image_size, Mapping) else image_size
    if size is None:
        raise InputError(
            f"{where}: {layout} puts the principal point at the image centre but does not say "
            f"the size of image {name or cid!r} ({image} is not there); pass "
            "image_size=(width, height) (or a mapping id → size) to read_cameras")
    w, h = size
    if not (int(w) == w and int(h) == h and w > 0 and h > 0):
        raise InputError(f"image_size {size!r} is not a (width, height) of positive integers")
    return int(w), int(h)


def _add(cameras: dict[str, Camera], cam: Camera, where: str, path: Path) -> None:
    if cam.id in cameras:
        raise InputError(f"{where}: camera {cam.id!r} occurs twice in {path}")
    cameras[cam.id] = cam


def _bundler_list(path: Path, count: int) -> tuple[Path, list[str]] | None:
    """The image names of a Bundler file from ``list.txt`` beside it, or one folder up when it
    lies in Bundler's own ``bundle/`` folder."""
    places = [path.parent / "list.txt"]
    if path.parent.name == "bundle":
        places.append(path.parent.parent / "list.txt")
    for lst in places:
        if lst.is_file():
            names = [line.split()[0] for line in _read_lines(lst, "Bundler image list")
                     if line.strip()]
            if len(names) != count:
                raise InputError(f"{lst} names {len(names)} images but {path} holds {count} "
                                 "cameras; the list does not belong to this bundle file")
            return lst.parent, names
    return None


def read_bundler(path: str | Path, *, image_size: ImageSize = None) -> dict[str, Camera]:
    """Read a Bundler ``bundle.out`` (v0.3; Bundler user manual, "Output format").

    Cameras with focal length 0 (photos Bundler did not register) are skipped.  Ids are the
    stems of the names in ``list.txt`` (beside the file, or one folder up from Bundler's
    ``bundle/`` folder; image paths in it are relative to its folder), else ``camera_NNNN`` (the camera's index).  Image sizes: see the
    module docstring.  Points are not read.
    """
    path = Path(path)
    layout = "Bundler's bundle.out v0.3"
    raw = _read_lines(path, "Bundler file")
    if not raw or not raw[0].lstrip().startswith("# Bundle file"):
        raise InputError(f"{path}:1: not a Bundler file (its first line is not "
                         "'# Bundle file v0.3')")
    lines = _data_lines(raw)
    if not lines:
        raise InputError(f"{path}: the Bundler file ends after its header (no camera count)")
    count, _points = _ints(lines[0][1], 2, f"{path}:{lines[0][0]}", layout)
    listed = _bundler_list(path, count)
    cameras: dict[str, Camera] = {}
    for k in range(count):
        block = lines[1 + 5 * k:6 + 5 * k]
        if len(block) < 5:
            raise InputError(f"{path}:{lines[-1][0]}: the file announces {count} cameras but "
                             f"ends in camera {k}; it is truncated")
        at = [f"{path}:{n}" for n, _ in block]
        f, k1, k2 = _floats(block[0][1], 3, at[0], layout)
        Rb = np.array([_floats(block[1 + r][1], 3, at[1 + r], layout) for r in range(3)])
        t = np.array(_floats(block[4][1], 3, at[4], layout))
        if f == 0:
            continue
        name = listed[1][k] if listed else ""
        cid = _stem(name) if name else f"camera_{k:04d}"
        if f < 0:
            raise InputError(f"{at[0]}: camera {cid!r} has a negative focal length")
        _rotation(Rb, at[1], cid)
        w, h = _image_size_of(listed[0] if listed else path.parent, name, cid, image_size,
                              at[0], "Bundler")
        cam = Camera(cid, name or cid, float(f), (w / 2.0, h / 2.0), _D @ Rb, -Rb.T @ t,
                     float(k1), float(k2), image_size=(w, h))
        _add(cameras, cam, at[0], path)
    return cameras


def read_nvm(path: str | Path, *, image_size: ImageSize = None) -> dict[str, Camera]:
    """Read the first model of a VisualSFM ``NVM_V3`` file (http://ccwu.me/vsfm/doc.html#nvm).

    Per camera ``name f qw qx qy qz cx cy cz r 0``: the quaternion is world → camera in our
    convention, ``c`` the centre, ``r`` the radial distortion (stored as ``r·f²``, the
    normalised value ``cameras_v2.txt`` gives).  The principal point is the image centre (image
    sizes: module docstring) unless the header says ``FixedK fx cx fy cy``.  Ids are the stems
    of the names (relative to the file's folder).
    """
    path = Path(path)
    layout = "VisualSFM's NVM_V3"
    lines = _data_lines(_read_lines(path, "NVM file"))
    if not lines:
        raise InputError(f"{path}: the NVM file is empty")
    if lines[0][1].split()[0] != "NVM_V3":
        raise InputError(f"{path}:{lines[0][0]}: not an NVM_V3 file (first line "
                         f"{lines[0][1][:40]!r}); NVM_V3_R9T and other variants are not read")
    head = lines[0][1].split()
    fixed = None
    if len(head) > 1:
        if head[1] != "FixedK" or len(head) != 6:
            raise InputError(f"{path}:{lines[0][0]}: unknown NVM header {lines[0][1][:60]!r}")
        fixed = _floats(" ".join(head[2:]), 4, f"{path}:{lines[0][0]}", layout)
    if len(lines) < 2:
        raise InputError(f"{path}:{lines[0][0]}: the NVM file ends after its header; it is "
                         "truncated")
    count = _ints(lines[1][1], 1, f"{path}:{lines[1][0]}", layout)[0]
    if len(lines) < 2 + count:
        raise InputError(f"{path}:{lines[-1][0]}: the file announces {count} cameras but ends "
                         f"after {len(lines) - 2}; it is truncated")
    cameras: dict[str, Camera] = {}
    for n, line in lines[2:2 + count]:
        where = f"{path}:{n}"
        name, *rest = line.split()
        f, *values = _floats(" ".join(rest), 9, where, layout)
        q, C, r = values[:4], np.array(values[4:7]), values[7]
        cid = _stem(name)
        if f <= 0:
            raise InputError(f"{where}: camera {cid!r} has a focal length ≤ 0")
        R = _quaternion_matrix(q, where, cid)
        if fixed is not None:
            fx, cx, fy, cy = fixed
            cam = Camera(cid, name, float(f), (cx, cy), R, C, r * f * f,
                         focal_y=None if fy == fx else f * fy / fx)
        else:
            w, h = _image_size_of(path.parent, name, cid, image_size, where, "NVM")
            cam = Camera(cid, name, float(f), (w / 2.0, h / 2.0), R, C, r * f * f,
                         image_size=(w, h))
        _add(cameras, cam, where, path)
    return cameras


def _colmap_count(raw: list[str], what: str) -> int | None:
    """The ``# Number of cameras: N`` / ``# Number of images: N`` COLMAP writes, if present."""
    for line in raw:
        if not line.startswith("#"):
            break
        m = re.match(rf"#\s*Number of {what}:\s*(\d+)", line)
        if m:
            return int(m.group(1))
    return None


def _colmap_intrinsics(path: Path) -> dict[int, tuple]:
    layout = "COLMAP's cameras.txt"
    raw = _read_lines(path, "COLMAP cameras file")
    out: dict[int, tuple] = {}
    lines = _data_lines(raw)
    for n, line in lines:
        where = f"{path}:{n}"
        parts = line.split()
        if len(parts) < 4:
            raise InputError(f"{where}: expected 'CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]', got "
                             f"{line[:80]!r}; the file is truncated or not {layout}")
        model = parts[1]
        if model not in _COLMAP_MODELS:
            raise InputError(
                f"{where}: COLMAP camera model {model!r} is not read; supported: "
                f"{', '.join(_COLMAP_MODELS)} (undistort the images first: COLMAP's "
                "image_undistorter writes PINHOLE cameras)")
        cam_id, w, h = _ints(" ".join([parts[0], *parts[2:4]]), 3, where, layout)
        names = _COLMAP_MODELS[model]
        if len(parts) - 4 != len(names):
            raise InputError(f"{where}: a {model} camera has {len(names)} parameters "
                             f"({' '.join(names)}), this line {len(parts) - 4}; the file is "
                             "truncated or malformed")
        p = dict(zip(names, _floats(" ".join(parts[4:]), len(names), where, layout)))
        fx = p.get("fx", p.get("f"))
        fy = p.get("fy", fx)
        if fx <= 0 or fy <= 0 or w <= 0 or h <= 0:
            raise InputError(f"{where}: camera {cam_id} has a focal length or size ≤ 0")
        if cam_id in out:
            raise InputError(f"{where}: camera id {cam_id} occurs twice in {path}")
        out[cam_id] = (fx, fy, p["cx"], p["cy"], p.get("k1", p.get("k", 0.0)),
                       p.get("k2", 0.0), w, h)
    announced = _colmap_count(raw, "cameras")
    if announced is not None and announced != len(out):
        raise InputError(f"{path}:{lines[-1][0] if lines else len(raw)}: the header announces "
                         f"{announced} cameras but the file holds {len(out)}; it is truncated")
    return out


def read_colmap(path: str | Path) -> dict[str, Camera]:
    """Read a COLMAP text model (COLMAP documentation, "Output format"): ``path`` is its folder
    or any file in it; ``cameras.txt`` and ``images.txt`` are read.

    ``images.txt`` holds two lines per image, the second (its 2D points) possibly empty; a file
    without those lines (one line per image) is refused, not misread.  Ids are the stems of the
    image names; ``image_size`` is the camera's WIDTH HEIGHT.
    """
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    cams_file, images_file = folder / "cameras.txt", folder / "images.txt"
    for f in (cams_file, images_file):
        if not f.is_file():
            raise InputError(f"COLMAP model {folder}: {f.name} not found (a COLMAP text model "
                             "holds cameras.txt and images.txt; convert a binary model with "
                             "'colmap model_converter --output_type TXT')")
    intrinsics = _colmap_intrinsics(cams_file)
    layout = "COLMAP's images.txt"
    raw = _read_lines(images_file, "COLMAP images file")
    i = 0
    while i < len(raw) and (not raw[i].strip() or raw[i].lstrip().startswith("#")):
        i += 1
    cameras: dict[str, Camera] = {}
    image_ids: set[int] = set()
    while i < len(raw):
        line = raw[i].strip()
        where = f"{images_file}:{i + 1}"
        if not line:
            if any(s.strip() for s in raw[i:]):
                raise InputError(f"{where}: expected an image line 'IMAGE_ID QW QX QY QZ TX TY "
                                 "TZ CAMERA_ID NAME', got a blank line")
            break
        parts = line.split(maxsplit=9)
        if len(parts) < 10:
            raise InputError(f"{where}: expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME', "
                             f"got {line[:80]!r}; the file is truncated or malformed")
        image_id, cam_id = _ints(f"{parts[0]} {parts[8]}", 2, where, layout)
        values = _floats(" ".join(parts[1:8]), 7, where, layout)
        name = parts[9]
        if i + 1 < len(raw) and len(raw[i + 1].split()) % 3:
            raise InputError(f"{images_file}:{i + 2}: expected the 2D points of image {name!r} "
                             "(X Y POINT3D_ID triples, possibly an empty line), got "
                             f"{raw[i + 1].strip()[:60]!r}; images.txt holds two lines per image")
        if cam_id not in intrinsics:
            raise InputError(f"{where}: image {name!r} refers to camera {cam_id}, which "
                             f"{cams_file} does not hold")
        if image_id in image_ids:
            raise InputError(f"{where}: image id {image_id} occurs twice in {images_file}")
        image_ids.add(image_id)
        cid = _stem(name)
        R = _quaternion_matrix(values[:4], where, cid)
        fx, fy, cx, cy, k1, k2, w, h = intrinsics[cam_id]
        cam = Camera(cid, name, fx, (cx, cy), R, -R.T @ np.array(values[4:]), k1, k2,
                     focal_y=None if fy == fx else fy, image_size=(w, h))
        _add(cameras, cam, where, images_file)
        i += 2
    announced = _colmap_count(raw, "images")
    if announced is not None and announced != len(cameras):
        raise InputError(f"{images_file}:{len(raw)}: the header announces {announced} images "
                         f"but the file holds {len(cameras)}; it is truncated")
    return cameras


def _sniff(path: Path) -> str:
    """``visualsfm``, ``nvm``, ``bundler`` or ``colmap`` from a camera file's first lines."""
    if path.stat().st_size > MAX_CAMERA_FILE_BYTES:
        raise InputError(f"camera file {path} is larger than {MAX_CAMERA_FILE_BYTES >> 20} MiB; "
                         "it is not a camera file")
    with path.open("rb") as fh:
        head = fh.read(64 * 1024)
    if not head.strip():
        raise InputError(f"camera file {path} is empty; expected {_FORMATS}")
    text = head.decode("utf-8", errors="replace")
    lines = text.splitlines()[:-1] if len(head) == 64 * 1024 else text.splitlines()
    first = next((s.strip() for s in lines if s.strip()), "")
    if b"\0" not in head:
        if first.startswith("# Bundle file"):
            return "bundler"
        if first.split()[:1] == ["NVM_V3"]:
            return "nvm"
        comments = " ".join(s for s in lines if s.lstrip().startswith("#"))
        data = [s.split() for s in lines if s.strip() and not s.lstrip().startswith("#")]
        if data:
            t = data[0]
            if len(t) == 1 and t[0].isdigit():
                return "visualsfm"
            if len(t) >= 4 and t[0].isdigit() and re.fullmatch(r"[A-Z][A-Z0-9_]*", t[1]):
                return "colmap"
            if len(t) >= 10 and t[0].isdigit() and t[8].isdigit() and _all_float(t[1:8]):
                return "colmap"
        elif any(h in comments for h in ("Camera list with one line of data per camera",
                                         "Image list with two lines of data per image",
                                         "3D point list with one line of data per point")):
            return "colmap"
    raise InputError(f"{path} is not a camera file read here; expected {_FORMATS}")


def _all_float(tokens: list[str]) -> bool:
    try:
        return all(np.isfinite([float(t) for t in tokens]))
    except ValueError:
        return False


def read_cameras(path: str | Path, *, image_size: ImageSize = None) -> dict[str, Camera]:
    """Read the cameras of a photo set from any of the formats the module docstring lists,
    recognised by content: VisualSFM ``cameras_v2.txt`` (:func:`read_visualsfm`) or ``.nvm``
    (:func:`read_nvm`), Bundler ``bundle.out`` (:func:`read_bundler`), a COLMAP text model
    (:func:`read_colmap`: its folder or any file in it).  A folder is read as a COLMAP model, or
    as the ``bundle.out`` or ``cameras_v2.txt`` in it.

    ``image_size`` — ``(width, height)`` or a mapping id → size — is used only where the file
    does not say it and the image file is not found (Bundler, NVM).

    Raises
    ------
    InputError
        Missing, empty, oversized, truncated or unrecognised files (naming the formats read),
        unsupported COLMAP camera models, rotations that are not ones, duplicate ids.
    """
    path = Path(path)
    if path.is_dir():
        if (path / "images.txt").is_file() or (
                (path / "cameras.txt").is_file() and _sniff(path / "cameras.txt") == "colmap"):
            return read_colmap(path)
        for name in ("bundle.out", "cameras_v2.txt"):
            if (path / name).is_file():
                return read_cameras(path / name, image_size=image_size)
        raise InputError(f"folder {path} holds no camera file; expected {_FORMATS}")
    if not path.is_file():
        raise InputError(f"camera file {path} not found; expected {_FORMATS}")
    kind = _sniff(path)
    if kind == "visualsfm":
        return read_visualsfm(path)
    if kind == "nvm":
        return read_nvm(path, image_size=image_size)
    if kind == "bundler":
        return read_bundler(path, image_size=image_size)
    return read_colmap(path)


# ------------------------------------------------------------------------------- writers
def _cameras_list(cameras: Mapping[str, Camera] | Iterable[Camera]) -> list[Camera]:
    cams = list(cameras.values()) if isinstance(cameras, Mapping) else list(cameras)
    ids = [c.id for c in cams]
    if len(set(ids)) != len(ids):
        raise InputError("cameras to write have duplicate ids")
    return cams


def _name_for(cam: Camera, id_of) -> str:
    """An image name the readers turn back into ``cam.id``: ``cam.file`` when it does, else the
    id with the file's suffix."""
    if cam.file and id_of(cam.file) == cam.id:
        return cam.file
    name = f"{cam.id}{Path(cam.file).suffix or '.jpg'}"
    if "/" in cam.id or "\\" in cam.id or any(c.isspace() for c in cam.id) \
            or id_of(name) != cam.id:
        raise InputError(f"camera id {cam.id!r} cannot be written as an image name the reader "
                         "turns back into it")
    return name


def _single_focal(cam: Camera, layout: str) -> None:
    if cam.focal_y is not None and abs(cam.focal_y - cam.focal) > 1e-9 * abs(cam.focal):
        raise InputError(f"camera {cam.id!r} has fx ≠ fy, which {layout} cannot hold")


def _num(*values: float) -> str:
    return " ".join(repr(float(v)) for v in values)


def _visualsfm_id(name: str) -> str:
    m = _ID.search(name)
    return m.group(1).upper() if m else _stem(name)


def write_visualsfm(cameras: Mapping[str, Camera] | Iterable[Camera], path: str | Path) -> Path:
    """Write VisualSFM's ``cameras_v2.txt`` (the layout of the module docstring); the original
    file name line carries the id.  Image sizes other than twice the principal point are lost."""
    path = Path(path)
    out = ["# Camera parameter file written by facadeforge (VisualSFM cameras_v2.txt layout)",
           "", "# the number of cameras in this reconstruction"]
    cams = _cameras_list(cameras)
    out.append(str(len(cams)))
    for c in cams:
        _single_focal(c, "cameras_v2.txt")
        original = _name_for(c, _visualsfm_id)
        # the reader takes the id from an IMG_NNNN in either name: the image name may hold
        # one only when the original name does
        name = c.file if c.file and (_ID.search(original) or not _ID.search(c.file)) \
            else original
        R = np.asarray(c.R, np.float64)
        q = _matrix_quaternion(R)
        angle = 2.0 * np.arctan2(np.linalg.norm(q[1:]), q[0])
        axis = q[1:] / max(np.linalg.norm(q[1:]), 1e-300)
        out += ["", name, original, _num(c.focal), _num(*c.principal), _num(*(-R @ c.C)),
                _num(*c.C), _num(*(angle * axis)), _num(*q), *(_num(*row) for row in R),
                _num(c.radial, 0), "0 0 0"]
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path


def write_bundler(cameras: Mapping[str, Camera] | Iterable[Camera], path: str | Path) -> Path:
    """Write Bundler's ``bundle.out`` v0.3 with no points and a ``list.txt`` beside it.

    Bundler has a single focal length and the principal point at the image centre: cameras
    with ``fx ≠ fy`` or another principal point are refused.  Reading the file back needs the
    image sizes (the images beside ``list.txt`` or ``image_size=``)."""
    path = Path(path)
    cams = _cameras_list(cameras)
    out = ["# Bundle file v0.3", f"{len(cams)} 0"]
    names = []
    for c in cams:
        _single_focal(c, "Bundler")
        w, h = c.size
        if abs(c.principal[0] - w / 2) > 1e-6 or abs(c.principal[1] - h / 2) > 1e-6:
            raise InputError(f"camera {c.id!r}: principal point {c.principal} is not the centre "
                             f"of its {w} × {h} image, which Bundler cannot hold")
        names.append(_name_for(c, _stem))
        Rb = _D @ np.asarray(c.R, np.float64)
        out += [_num(c.focal, c.radial, c.radial2), *(_num(*row) for row in Rb),
                _num(*(-Rb @ c.C))]
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    (path.parent / "list.txt").write_text("".join(f"{n}\n" for n in names), encoding="utf-8")
    return path


def write_colmap(cameras: Mapping[str, Camera] | Iterable[Camera], folder: str | Path) -> Path:
    """Write a COLMAP text model (``cameras.txt``, ``images.txt``, an empty ``points3D.txt``)
    into ``folder``: one COLMAP camera per image, the simplest model that holds it
    (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL or OPENCV), the size :attr:`Camera.size`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cams = _cameras_list(cameras)
    cam_lines = ["# Camera list with one line of data per camera:",
                 "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
                 f"# Number of cameras: {len(cams)}"]
    img_lines = ["# Image list with two lines of data per image:",
                 "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
                 "#   POINTS2D[] as (X, Y, POINT3D_ID)",
                 f"# Number of images: {len(cams)}, mean observations per image: 0"]
    for k, c in enumerate(cams, 1):
        f, fy, (cx, cy) = c.focal, c.fy, c.principal
        square = fy == f
        if c.radial2:
            model, params = ("RADIAL", (f, cx, cy, c.radial, c.radial2)) if square else \
                ("OPENCV", (f, fy, cx, cy, c.radial, c.radial2, 0, 0))
        elif c.radial:
            model, params = ("SIMPLE_RADIAL", (f, cx, cy, c.radial)) if square else \
                ("OPENCV", (f, fy, cx, cy, c.radial, 0, 0, 0))
        else:
            model, params = ("SIMPLE_PINHOLE", (f, cx, cy)) if square else \
                ("PINHOLE", (f, fy, cx, cy))
        w, h = c.size
        cam_lines.append(f"{k} {model} {w} {h} {_num(*params)}")
        R = np.asarray(c.R, np.float64)
        img_lines += [f"{k} {_num(*_matrix_quaternion(R), *(-R @ c.C))} {k} "
                      f"{_name_for(c, _stem)}", ""]
    (folder / "cameras.txt").write_text("\n".join(cam_lines) + "\n", encoding="utf-8")
    (folder / "images.txt").write_text("\n".join(img_lines) + "\n", encoding="utf-8")
    (folder / "points3D.txt").write_text(
        "# 3D point list with one line of data per point:\n"
        "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
        "# Number of points: 0, mean track length: 0\n", encoding="utf-8")
    return folder


# ------------------------------------------------------------------- place along a street
def _horizontal(v: np.ndarray, up: np.ndarray) -> np.ndarray:
    return v - np.outer(v @ up, up)


def street_positions(cameras: list[Camera]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Arc length of each camera along the path they were taken on, with the path's tangent and
    the world's up direction.

    ``cameras`` are in the order they were taken (sorted ``IMG_`` numbers are neighbouring
    viewpoints).  Up is minus the mean of the photos' downward axis (the calibrated images' x
    axis: they are turned, see the module docstring; for upright images, minus the y axis).
    The tangent at a camera is the horizontal direction from the third camera before it to the
    third after it.
    """
    R = np.array([c.R for c in cameras])
    turned = cameras[0].size[0] > cameras[0].size[1]
    down = R[:, 0] if turned else R[:, 1]
    up = -down.mean(0)
    up /= np.linalg.norm(up)
    C = _horizontal(np.array([c.C for c in cameras]), up)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(C, axis=0), axis=1))]
    n = len(C)
    tangent = np.array([C[min(i + 3, n - 1)] - C[max(i - 3, 0)] for i in range(n)])
    norm = np.linalg.norm(tangent, axis=1)
    tangent = tangent / np.where(norm > 0, norm, 1.0)[:, None]
    return s, tangent, up


def seen_intervals(cameras: list[Camera], depth: float) -> np.ndarray:
    """The stretch of street each photo sees: ``(N, 2)`` arc lengths ``[from, to]``.

    Each photo's left and right frustum edges are cut with a vertical facade plane parallel to
    the camera path at perpendicular distance ``depth`` on the side the camera looks to
    (cameras on a sidewalk photographing the facades across the street).  A ray that runs
    parallel to the facade (never reaches it) reaches infinitely far.
    """
    s, tangent, up = street_positions(cameras)
    out = np.empty((len(cameras), 2))
    for i, cam in enumerate(cameras):
        turned = cam.size[0] > cam.size[1]
        across = cam.R[1] if turned else cam.R[0]          # the photo's horizontal axis
        half = (cam.principal[1] if turned else cam.principal[0]) / cam.focal
        look = _horizontal(cam.R[2][None], up)[0]
        normal = look - (look @ tangent[i]) * tangent[i]
        normal /= max(np.linalg.norm(normal), 1e-12)
        ends = []
        for sign in (-1.0, 1.0):
            ray = _horizontal((cam.R[2] + sign * half * across)[None], up)[0]
            toward = ray @ normal
            along = ray @ tangent[i]
            ends.append(s[i] + depth * along / toward if toward > 1e-6
                        else np.copysign(np.inf, along))
        out[i] = min(ends), max(ends)
    return out


#: Photo suffixes :func:`photo_files` looks at.
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff")


def photo_files(folder: str | Path, cameras: dict[str, Camera], what: str = "photos"
                ) -> dict[str, Path]:
    """The photos of ``folder`` paired with ``cameras``: the file named like the camera's id,
    or like its file (VisualSFM's undistorted name), case aside.  ``what`` names the option in
    messages."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{what} {folder}: not a folder; give the folder of the photos the "
                         "cameras file calibrates")
    files = {p.stem.upper(): p for p in sorted(folder.iterdir())
             if p.suffix.lower() in PHOTO_SUFFIXES and p.is_file()}
    pairs = {}
    for cid, cam in cameras.items():
        hit = files.get(cid.upper()) or files.get(Path(cam.file).stem.upper())
        if hit is not None:
            pairs[cid] = hit
    if not pairs:
        raise InputError(f"{what} {folder}: none of the {len(cameras)} photos the cameras name "
                         f"(e.g. {next(iter(cameras), '?')}) is in it")
    return pairs
