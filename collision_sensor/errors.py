"""The package's exception family.

Every message names the file, link, joint or object at fault and says how to fix it, e.g.
``link "forearm": mesh "package://arm/forearm.stl" not found; add --package-path arm=DIR``.
"""
import os
import sys
import warnings


class CollisionSensorError(Exception):
    """Base of every error this package raises on purpose."""


class RobotDescriptionError(CollisionSensorError):
    """A URDF that cannot be read, is unsafe, or describes something unsupported."""


class MeshError(RobotDescriptionError):
    """A mesh that cannot be found or read, or has no usable triangles."""


class LoadWarning(UserWarning):
    """Something in a URDF or SRDF that is skipped or tolerated, as ROS tools tolerate it.

    The message names the file, the line or element, and the fix.
    """


class SrdfError(CollisionSensorError):
    """An SRDF that cannot be read or names links the robot does not have."""


class SceneError(CollisionSensorError):
    """A scene file that cannot be read or describes an object badly."""


class ConfigError(CollisionSensorError):
    """A setting with a bad value, or an exception list naming unknown links."""


class JointStateError(CollisionSensorError, ValueError):
    """Joint positions with unknown names or values that are not finite."""


class SequenceError(CollisionSensorError):
    """A recorded joint-state sequence that cannot be read or written."""


class EngineBuildError(CollisionSensorError):
    """The compiled engine is missing, stale or does not match this Python code (its packed
    arrays' layout included)."""


class PointCloudError(CollisionSensorError, ValueError):
    """A point cloud the checker cannot take: not (n, 3) numbers, a frame that is no link of
    the robot nor the world, a bad source name or setting; the message names it and the fix."""


class EngineInputError(CollisionSensorError, ValueError):
    """An argument the compiled engine cannot take: an array of the wrong shape, points that
    are not finite, an index out of range; the message names the argument."""


class EngineWorkerError(CollisionSensorError, RuntimeError):
    """A worker thread of a batch failed (memory ran out in its work areas): the call has no
    answer (``cpp/workers.hpp``)."""


#: Lines of one warning printed at most; the rest are counted (all kept in ``.warnings``).
MAX_WARNING_LINES = 20


def listed_lines(lines) -> str:
    """Return ``lines`` indented one per line, at most :data:`MAX_WARNING_LINES` of them."""
    shown = ['  ' + line for line in lines[:MAX_WARNING_LINES]]
    if len(lines) > MAX_WARNING_LINES:
        shown.append(f'  ... and {len(lines) - MAX_WARNING_LINES} more (all in .warnings)')
    return '\n'.join(shown)


def warn_load(message: str) -> None:
    """Issue ``message`` as a :class:`LoadWarning` attributed to the first caller outside this
    package, so that the printed location is the user's ``load_urdf``/``from_urdf`` line."""
    package = os.path.dirname(os.path.abspath(__file__))
    level, frame = 2, sys._getframe(1)   # stacklevel 2 is the caller of warn_load
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(
            package + os.sep):
        level, frame = level + 1, frame.f_back
    warnings.warn(LoadWarning(message), stacklevel=level)
