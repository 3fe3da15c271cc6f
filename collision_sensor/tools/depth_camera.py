"""A simulated depth camera: what a sensor in the cell would see, by ray casting a checker's
trees (:meth:`CollisionChecker.cast_rays`, ``cpp/ray_cast.hpp``).

For the demo cell's camera (``collision_sensor_demo --camera``), the point-cloud benchmark and
the tests: an organised cloud, one point per pixel, in the camera's optical frame (ROS's
convention: z along the view, x right, y down), NaN where no surface is within range, as a
depth camera's driver publishes it. The scene it sees is the checker's at its last checked
state: a checker of its own, with objects the sensor's checker does not know, shows them.
"""
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass(frozen=True)
class DepthCamera:
    """A pinhole depth camera.

    :ivar width, height: pixels.
    :ivar fov: horizontal field of view (rad); square pixels.
    :ivar max_range: farthest surface seen (m).
    :ivar noise: standard deviation (m) of the depth's noise, along each pixel's ray.
    """

    width: int = 640
    height: int = 480
    fov: float = math.radians(70.0)
    max_range: float = 4.0
    noise: float = 0.0

    @property
    def focal(self) -> float:
        """Focal length in pixels."""
        return 0.5 * self.width / math.tan(0.5 * self.fov)

    def rays(self) -> np.ndarray:
        """(H W, 3) unit ray directions in the optical frame, row by row."""
        f = self.focal
        u = (np.arange(self.width) + 0.5 - 0.5 * self.width) / f
        v = (np.arange(self.height) + 0.5 - 0.5 * self.height) / f
        uu, vv = np.meshgrid(u, v)
        d = np.stack([uu, vv, np.ones_like(uu)], axis=-1).reshape(-1, 3)
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def points(self, checker, T_world_camera: np.ndarray,
               rng: Optional[np.random.Generator] = None) -> np.ndarray:
        """Render ``checker``'s scene at its last checked state from the optical frame
        ``T_world_camera`` (4, 4).

        :return: (H W, 3) float32 points in the optical frame, NaN rows where no surface is
            within ``max_range`` (an organised cloud, row by row).
        """
        rays = self.rays()
        directions = rays @ T_world_camera[:3, :3].T
        t = checker.cast_rays(T_world_camera[:3, 3], directions, self.max_range)
        if self.noise > 0.0 and rng is not None:
            t = t + rng.normal(0.0, self.noise, t.shape)
        points = (rays * t[:, None]).astype(np.float32)
        points[~np.isfinite(t)] = np.nan
        return points


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Return the optical frame (4, 4) at ``eye`` looking at ``target`` (z forward, x right,
    y down, with ``up`` up in the picture)."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T
