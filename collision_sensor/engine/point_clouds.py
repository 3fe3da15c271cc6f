"""Obstacles from depth sensors: point clouds in, the robot's own points filtered out, the rest
checked like any world object.

A *source* (a camera, a lidar: any name) gives clouds one after another through
:meth:`CollisionChecker.set_points`; each becomes the world object ``cloud/<source>``, checked
against every robot link and attached object (pairs named in sorted order, as every pair),
with proximity, padding, the exception list and the motion checks, as any world object. What a cloud becomes
(``cpp/cloud_filter.hpp``, in C++ with the interpreter released):

* rows with a NaN or infinite coordinate are dropped (organised clouds have holes), and rows
  beyond ``max_range`` of the sensor's origin; more than ``max_points`` rows: every k-th row is
  taken (k = ceil(rows / max_points)), the others counted as capped;
* the *self-filter* removes every point within ``self_filter_padding`` of the robot's collision
  geometry (its links and attached objects, at the joint values given: the cloud's own state),
  or inside a solid of it (primitives; closed meshes with ``mesh_containment``);
* the rest are grouped into the cubes of a world-aligned grid of ``voxel_size``: the obstacle is
  the occupied cubes, solid.

What a cloud can tell. The self-filter removes whatever lies within its padding of the robot,
so an object pressed against a link loses the points that touch it: the cloud sees the object
only from the padding outwards. Contact with ``cloud/<source>`` means that an occupied voxel's
cube reaches a link's (padded) geometry; a voxel is occupied by any point in it, so the cube
can reach up to a voxel's diagonal nearer the link than its points: the resolution of a cloud's
verdict is the filter's padding plus a voxel. An object closer to a link than the padding
shows as no contact, or through its points farther out; for clouds the warning zone
(``proximity``, the node's ``near`` and ``min_distance``) is the main output, exact for the
voxels (the distance from the link to the nearest occupied cube), within one voxel's diagonal
of the distance to the points.

The obstacle is updated in place: the next cloud of a source is built into a second grid
while the checker answers queries, then swapped in; only the cloud's pairs are re-checked
(``cpp/voxel_cloud.hpp``). A source's first cloud adds its object (a scene change, the pairs laid
out once); :meth:`CollisionChecker.clear_points` removes it.
"""
import math
from dataclasses import dataclass
from typing import NamedTuple, Optional, Tuple

import numpy as np

from collision_sensor.engine.checker_config import MAX_THREADS
from collision_sensor.engine.dynamic_scene import CLOUD_PREFIX  # noqa: F401 - also ours
from collision_sensor.errors import PointCloudError
#: Longest source name (characters).
MAX_SOURCE_LENGTH = 256


class PointCloudStats(NamedTuple):
    """What became of a cloud's rows (``points = capped + invalid + out_of_range +
    self_filtered + kept_points``).

    :ivar points: rows given.
    :ivar capped: rows left out by ``max_points`` (every k-th row taken).
    :ivar invalid: rows with a NaN or infinite coordinate.
    :ivar out_of_range: rows beyond ``max_range`` of the sensor, or beyond the voxel grid's
        reach (2^20 voxels from the world origin).
    :ivar self_filtered: points within the self-filter's padding of the robot.
    :ivar kept_points: points kept.
    :ivar voxels: occupied voxels of the obstacle (what ``set_points`` returns).
    :ivar persisted: of them, voxels kept from earlier clouds (``persistence``).
    """

    points: int
    capped: int
    invalid: int
    out_of_range: int
    self_filtered: int
    kept_points: int
    voxels: int
    persisted: int


#: Before any cloud.
NO_STATS = PointCloudStats(0, 0, 0, 0, 0, 0, 0, 0)


@dataclass(frozen=True, eq=False)
class PreparedPoints:
    """A cloud filtered and voxelised, not yet the obstacle
    (:meth:`CollisionChecker.prepare_points`; :meth:`CollisionChecker.commit_points` makes it
    so).

    :ivar source: the source's name.
    :ivar stats: what became of its rows.
    :ivar kept: (m, 3) float32 the points kept, world frame (``keep_points``), else None.
    """

    checker: object
    source: str
    cloud: object
    ticket: int
    stats: PointCloudStats
    kept: Optional[np.ndarray]


def cloud_name(source: str) -> str:
    """Return the object name of ``source``'s cloud, ``cloud/<source>``.

    :raises PointCloudError: a source that is not a non-empty printable string of at most
        :data:`MAX_SOURCE_LENGTH` characters.
    """
    if not isinstance(source, str) or not source or len(source) > MAX_SOURCE_LENGTH or (
            not source.isprintable()):
        raise PointCloudError(f'point cloud source {source!r:.80}: give a non-empty printable name '
                          f'of at most {MAX_SOURCE_LENGTH} characters (the sensor\'s topic)')
    return CLOUD_PREFIX + source


def is_cloud_name(name: str) -> bool:
    """True iff ``name`` is a cloud's object name."""
    return isinstance(name, str) and name.startswith(CLOUD_PREFIX)


def points_array(points) -> np.ndarray:
    """Return ``points`` as the engine reads them: an (n, 3) float32 or float64 array (any row
    stride: a view of a PointCloud2's x, y, z fields is read in place), converting only what
    is not.

    :raises PointCloudError: not an (n, 3) array of numbers.
    """
    array = points if isinstance(points, np.ndarray) else None
    if array is None or array.dtype not in (np.float32, np.float64) or (
            not array.dtype.isnative):
        try:
            array = np.asarray(points, dtype=np.float64)
        except (TypeError, ValueError):
            raise PointCloudError(f'points must be an (n, 3) array of numbers, got '
                             f'{type(points).__name__}') from None
    if array.ndim != 2 or array.shape[1] != 3:
        if array.size == 0:
            return np.zeros((0, 3))
        raise PointCloudError(f'points must have shape (n, 3), got {array.shape}; give one row x, y, '
                         'z per point')
    return array


def cloud_threads(threads) -> int:
    """Return the ``threads`` a cloud's filter may use, as an int (0: every core).

    :raises PointCloudError: not an integer from 0 to 256.
    """
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or \
            not 0 <= threads <= MAX_THREADS:
        raise PointCloudError(f'threads {threads!r}: give an integer from 0 (every core) to '
                              f'{MAX_THREADS} (1: the calling thread alone)')
    return int(threads)


def cloud_arguments(max_range, persistence, stamp) -> Tuple[float, float, float]:
    """Return ``max_range`` (m), ``persistence`` (s) and ``stamp`` (s) of a cloud as floats.

    :raises PointCloudError: a range that is not > 0, a persistence that is not a finite
        number >= 0, a stamp that is not finite.
    """
    try:
        max_range, persistence, stamp = float(max_range), float(persistence), float(stamp)
    except (TypeError, ValueError):
        raise PointCloudError('max_range, persistence and stamp must be numbers') from None
    if not max_range > 0.0:
        raise PointCloudError(f'max_range {max_range!r}: give a distance > 0 m (inf: none)')
    if not 0.0 <= persistence < math.inf:
        raise PointCloudError(f'persistence {persistence!r}: give a finite number of seconds '
                              '>= 0 (0: only the latest cloud counts)')
    if not math.isfinite(stamp):
        raise PointCloudError(f'stamp {stamp!r}: give a finite time in seconds')
    return max_range, persistence, stamp
