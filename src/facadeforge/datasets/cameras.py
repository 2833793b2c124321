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
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["Camera", "read_visualsfm", "seen_intervals", "street_positions"]

#: Largest camera file read (a text file of a few hundred cameras is a few hundred kB).
MAX_CAMERA_FILE_BYTES = 64 * 1024 * 1024

_ID = re.compile(r"(IMG_\d+)", re.IGNORECASE)


@dataclass(frozen=True, eq=False)
class Camera:
    """One calibrated pinhole camera.

    ``R`` rotates world into camera coordinates (rows: the camera's x, y and viewing axes in
    world coordinates), ``C`` is the centre; ``size`` is the calibrated image's (width, height),
    twice the principal point.
    """

    id: str
    file: str
    focal: float
    principal: tuple[float, float]
    R: np.ndarray
    C: np.ndarray
    radial: float = 0.0

    @property
    def size(self) -> tuple[int, int]:
        return round(2 * self.principal[0]), round(2 * self.principal[1])

    @property
    def K(self) -> np.ndarray:
        f, (cx, cy) = self.focal, self.principal
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

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


def _floats(line: str, n: int, where: str) -> list[float]:
    parts = line.split()
    try:
        values = [float(p) for p in parts[:n]]
    except ValueError:
        values = []
    if len(values) != n or not all(np.isfinite(values)):
        raise InputError(f"{where}: expected {n} numbers, got {line.strip()[:80]!r}; the file "
                         "is not in VisualSFM's cameras_v2.txt layout")
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
            raise InputError(f"{path}: the file announces {count} cameras but ends after "
                             f"{len(cameras)}; it is truncated")
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
