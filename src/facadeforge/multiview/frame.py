"""The metric, z-up frame a calibrated photo set is reconstructed in.

Structure from motion gives cameras in a frame of its own: any rotation, any scale (the RueMonge
cameras put the facades about 4 units from the camera path, ``datasets.splits.STREET_DEPTH``).
The thesis registers its SfM frame to a cadastral map by a few hand-picked correspondences
(``simon2011`` §5.1); here the frame is found from the photos themselves, so a photo set and
its cameras are enough:

- **up** — the mean, over the photos, of the direction that points up in the photo as it is
  stored (street photos are taken upright; the quarter turn of RueMonge's portrait photos
  against their calibrated images is :class:`~facadeforge.datasets.cameras.Camera`'s), then,
  once a dense cloud exists, the normal of its ground plane when one lies within 20° of it
  (:meth:`BuildingFrame.refine`);
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

__all__ = ["EYE_HEIGHT", "BuildingFrame", "photo_up", "initial_frame"]

#: Height (m) of a hand-held street camera above the pavement.
EYE_HEIGHT = 1.6
#: Largest angle (degrees) between the photos' up and a plane's normal for it to be the ground.
GROUND_TOL_DEG = 20.0


def photo_up(camera: Camera, photo_shape: tuple[int, int]) -> np.ndarray:
    """The world direction of "up" in a photo as stored: the image column through the centre,
    one pixel up, mapped back through the camera (unit vector)."""
    h, w = photo_shape[:2]
    xy = np.array([[w / 2.0, h / 2.0], [w / 2.0, h / 2.0 - 1.0]])
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
                  metres_per_unit: float | None = None) -> BuildingFrame:
    """The frame from the cameras alone: up from the photos, x along the camera path, the
    scale ``metres_per_unit`` or, until the ground is found, 1."""
    if not cameras:
        raise InputError("no camera: give the photos' calibrated cameras")
    ups = np.array([photo_up(cameras[k], shapes[k]) for k in cameras])
    up = ups.sum(0)
    if np.linalg.norm(up) < 0.5 * len(ups):
        raise InputError("the photos do not agree on which way is up (their cameras point "
                         "every way); give photos of one street taken upright")
    up /= np.linalg.norm(up)
    centres = np.array([cameras[k].C for k in cameras])
    scale = float(metres_per_unit) if metres_per_unit is not None else 1.0
    rot = _axes(centres, up)
    origin = centres.mean(0) - (EYE_HEIGHT / scale) * up
    return BuildingFrame(origin=origin, rotation=rot, scale=scale,
                         scale_source="given" if metres_per_unit is not None else "unknown")
