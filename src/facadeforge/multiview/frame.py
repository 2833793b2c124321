"""The metric, z-up frame a calibrated photo set is reconstructed in.

Structure from motion gives cameras in a frame of its own: any rotation, any scale (the RueMonge
cameras put the facades about 4 units from the camera path, ``datasets.splits.STREET_DEPTH``).
The thesis registers its SfM frame to a cadastral map by a few hand-picked correspondences
(``simon2011`` §5.1); here the frame is found from the photos themselves, so a photo set and
its cameras are enough:

- **up** — street photos are taken upright, without roll: each photo's right axis (as it is
  stored; the quarter turn of RueMonge's portrait photos against their calibrated images is
  :class:`~facadeforge.datasets.cameras.Camera`'s) is horizontal, and so are the normals of the
  walls; up is the direction most nearly perpendicular to all of them (:func:`vertical`; the
  photos' own up leans back by their pitch), then the normal of the ground plane when one lies
  within 20° of it (:meth:`BuildingFrame.refine`);
- **scale** — street photos are taken at eye height: the median height of the camera centres
  above the ground plane is :data:`EYE_HEIGHT` metres (or ``metres_per_unit`` given);
- **axes** — x along the camera path (its principal horizontal direction), z up, y = z × x;
  the origin under the mean camera centre, on the ground.

:class:`BuildingFrame` maps world (SfM) coordinates to the local frame and back; every stage of
:mod:`facadeforge.multiview` after the stereo works in the local frame (metres, z up: what
:mod:`facadeforge.points` expects), and the outputs go back to the cameras' frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..datasets.cameras import Camera
from ..errors import InputError

__all__ = ["EYE_HEIGHT", "BuildingFrame", "initial_frame", "photo_right", "photo_up", "vertical"]

#: Height (m) of a hand-held street camera above the pavement.
EYE_HEIGHT = 1.6
#: Largest angle (degrees) between the photos' up and a plane's normal for it to be the ground.
GROUND_TOL_DEG = 20.0


def photo_up(camera: Camera, photo_shape: tuple[int, int]) -> np.ndarray:
    """The world direction of "up" in a photo as stored: the image column through the centre,
    one pixel up, mapped back through the camera (unit vector).  It leans back by the
    camera's pitch: :func:`vertical` finds the true vertical."""
    return _photo_direction(camera, photo_shape, (0.0, -1.0))


def photo_right(camera: Camera, photo_shape: tuple[int, int]) -> np.ndarray:
    """The world direction of "right" in a photo as stored (unit vector): horizontal for a
    photo taken without roll, whatever its pitch."""
    return _photo_direction(camera, photo_shape, (1.0, 0.0))


def vertical(cameras: dict[str, Camera], shapes: dict[str, tuple[int, int]],
             facade_normals: np.ndarray | None = None) -> np.ndarray:
    """The world's up: the direction most nearly perpendicular to every photo's right axis
    (photos taken upright, without roll) and to the normals of the facade planes (vertical
    walls), signed like the photos' up.  With no facade normal the photos' right axes alone
    leave the pitch open if they are all parallel: then the mean photo up stands in."""
    ups = np.array([photo_up(cameras[k], shapes[k]) for k in cameras])
    mean_up = ups.sum(0)
    mean_up /= np.linalg.norm(mean_up)
    rows = [photo_right(cameras[k], shapes[k]) for k in cameras]
    if facade_normals is not None and len(facade_normals):
        nn = np.asarray(facade_normals, float).reshape(-1, 3)
        rows += list(nn * np.sqrt(len(rows) / len(nn)))
    M = np.array(rows)
    _, s, vt = np.linalg.svd(M, full_matrices=True)
    s3 = np.r_[s, np.zeros(3 - len(s))]
    # one direction is pinned down when the rows span a plane: σ₂ clearly above σ₃
    if s3[1] < 0.15 * s3[0] or s3[2] > 0.5 * s3[1]:
        # the rows do not pin one direction down (all right axes parallel, no wall): take the
        # mean photo up made perpendicular to the right axes
        r = M[: len(cameras)].mean(0)
        up = mean_up - (mean_up @ r) / max(r @ r, 1e-12) * r
        return up / np.linalg.norm(up)
    up = vt[-1]
    return up if up @ mean_up > 0 else -up


def _photo_direction(camera: Camera, photo_shape: tuple[int, int], step) -> np.ndarray:
    h, w = photo_shape[:2]
    xy = np.array([[w / 2.0, h / 2.0], [w / 2.0 + step[0], h / 2.0 + step[1]]])
    uv = camera.from_photo(xy, (h, w))
    d = uv[1] - uv[0]
    v = camera.R.T @ np.array([d[0], d[1], 0.0])
    return v / np.linalg.norm(v)


@dataclass
class BuildingFrame:
    """A similarity: ``local = scale · rotation @ (world − origin)``; rows of ``rotation`` are
    the local x, y, z (up) axes in world coordinates."""

    origin: np.ndarray
    rotation: np.ndarray
    scale: float                 # metres per world unit
    scale_source: str = "eye height"

    def to_local(self, xyz: np.ndarray) -> np.ndarray:
        return self.scale * (np.asarray(xyz, float).reshape(-1, 3) - self.origin) @ self.rotation.T

    def to_world(self, xyz: np.ndarray) -> np.ndarray:
        return np.asarray(xyz, float).reshape(-1, 3) @ self.rotation / self.scale + self.origin

    @property
    def up_world(self) -> np.ndarray:
        return self.rotation[2].copy()

    def matrix(self) -> np.ndarray:
        """The 4 × 4 local → world matrix."""
        m = np.eye(4)
        m[:3, :3] = self.rotation.T / self.scale
        m[:3, 3] = self.origin
        return m

    def to_dict(self) -> dict:
        r = lambda a: [round(float(x), 9) for x in np.ravel(a)]  # noqa: E731
        return {"origin": r(self.origin), "rotation": [r(row) for row in self.rotation],
                "metres_per_unit": round(float(self.scale), 9), "scale_from": self.scale_source,
                "local_to_world": [r(row) for row in self.matrix()]}

    def refine(self, ground_normal_world: np.ndarray | None, ground_point_world: np.ndarray
               | None, centres: np.ndarray, *, metres_per_unit: float | None = None
               ) -> BuildingFrame:
        """A frame whose up is the ground plane's normal (when it is within
        :data:`GROUND_TOL_DEG` of the photos' up) and whose scale puts the cameras at
        :data:`EYE_HEIGHT` above it (unless ``metres_per_unit`` is given)."""
        up = self.up_world
        if ground_normal_world is not None:
            g = np.asarray(ground_normal_world, float)
            g = g / np.linalg.norm(g)
            if g @ up < 0:
                g = -g
            if np.degrees(np.arccos(np.clip(g @ up, -1, 1))) <= GROUND_TOL_DEG:
                up = g
        rot = _axes(centres, up)
        scale, source = self.scale, self.scale_source
        if metres_per_unit is not None:
            scale, source = float(metres_per_unit), "given"
        elif ground_point_world is not None:
            heights = (np.asarray(centres, float) - ground_point_world) @ up
            h = float(np.median(heights))
            if h > 0:
                scale, source = EYE_HEIGHT / h, "eye height above the ground plane"
        # the origin on the ground under the mean camera centre
        c = np.asarray(centres, float).mean(0)
        if ground_point_world is not None:
            c = c - ((c - ground_point_world) @ up) * up
        else:
            c = c - (EYE_HEIGHT / scale) * up
        return BuildingFrame(origin=c, rotation=rot, scale=scale, scale_source=source)


def _axes(centres: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Rows x (along the camera path, horizontal), y = z × x, z = up."""
    up = up / np.linalg.norm(up)
    c = np.asarray(centres, float)
    x = None
    if len(c) >= 2:
        d = c - c.mean(0)
        d = d - np.outer(d @ up, up)
        _, s, vt = np.linalg.svd(d, full_matrices=False)
        if s[0] > 1e-9:
            x = vt[0]
    if x is None:                      # one camera: any horizontal direction
        x = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    x = x - (x @ up) * up
    x /= np.linalg.norm(x)
    y = np.cross(up, x)
    return np.stack([x, y, up])


def initial_frame(cameras: dict[str, Camera], shapes: dict[str, tuple[int, int]], *,
                  metres_per_unit: float | None = None, facade_normals: np.ndarray | None = None
                  ) -> BuildingFrame:
    """The frame from the cameras (and the facade normals when known): up from
    :func:`vertical`, x along the camera path, the scale ``metres_per_unit`` or, until the
    ground is found, 1."""
    if not cameras:
        raise InputError("no camera: give the photos' calibrated cameras")
    ups = np.array([photo_up(cameras[k], shapes[k]) for k in cameras])
    if np.linalg.norm(ups.sum(0)) < 0.5 * len(ups):
        raise InputError("the photos do not agree on which way is up (their cameras point "
                         "every way); give photos of one street taken upright")
    up = vertical(cameras, shapes, facade_normals)
    centres = np.array([cameras[k].C for k in cameras])
    scale = float(metres_per_unit) if metres_per_unit is not None else 1.0
    rot = _axes(centres, up)
    origin = centres.mean(0) - (EYE_HEIGHT / scale) * up
    return BuildingFrame(origin=origin, rotation=rot, scale=scale,
                         scale_source="given" if metres_per_unit is not None else "unknown")
