"""Certified motion checks: is any configuration between two states in contact?

The compiled engine (``cpp/motion.hpp``) proves a motion free, or finds its first contact,
from distance lower bounds and bounds on how far any point of each link can move over a
sub-interval (Schwarzer, Saha & Latombe's adaptive dynamic collision checking); nothing is
sampled. This module holds what the answers look like and how each joint variable moves::

    result = checker.check_motion(q_from, q_to)
    result.in_collision, result.first_contact, result.colliding_pairs

Interpolation (the rules MoveIt's ``JointModel::interpolate`` follows): revolute and prismatic
variables move linearly; continuous joints and a planar joint's ``theta`` the shorter way
round; a planar joint's ``x``, ``y`` and a floating joint's translation linearly; a floating
joint's quaternion along the shorter arc (slerp). Mimic joints follow their source.
"""
from typing import NamedTuple, Optional, Tuple

import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.model.robot_model import RobotModel

Pair = Tuple[str, str]

#: A reported first contact's state is in contact, or its padded distance is at most this (m).
TOUCH_TOLERANCE: float = engine.MOTION_TOUCH_TOLERANCE


class MotionResult(NamedTuple):
    """The answer of a motion check.

    :ivar in_collision: True iff some state of the motion (its two ends included) is in
        contact.
    :ivar first_contact: the fraction of the motion in [0, 1] at its first contact (``None``
        when free): the state there is in contact, or within :data:`TOUCH_TOLERANCE` of it,
        and no earlier state is in contact beyond that tolerance.
    :ivar colliding_pairs: sorted ``(a, b)`` pairs in contact (or within the tolerance) at
        ``first_contact``; ``()`` when free.
    """

    in_collision: bool
    first_contact: Optional[float]
    colliding_pairs: Tuple[Pair, ...]


#: The answer for a motion proven free.
FREE = MotionResult(False, None, ())


class PathResult(NamedTuple):
    """The answer of :meth:`CollisionChecker.check_path`.

    :ivar first_invalid_segment: the index ``i`` of the first motion ``Q[i] -> Q[i + 1]``
        that is not free (``None`` when the whole path is free; 0 for a single waypoint in
        contact).
    :ivar motion: that segment's :class:`MotionResult` (:data:`FREE` when the path is free).
    """

    first_invalid_segment: Optional[int]
    motion: MotionResult

    @property
    def in_collision(self) -> bool:
        """True iff some state along the path is in contact."""
        return self.first_invalid_segment is not None


def motion_kinds(model: RobotModel, joint_names) -> np.ndarray:
    """Return how each variable of ``joint_names`` moves along a straight motion.

    :return: ``(J,) int64``: ``MOTION_WRAP`` for continuous joints and planar ``theta``,
        ``MOTION_QUATERNION`` for a floating joint's ``rot_x`` and ``MOTION_QUATERNION_REST``
        for its ``rot_y``, ``rot_z``, ``rot_w``, ``MOTION_LINEAR`` for everything else.
    """
    by_variable = {variable: joint for joint in model.joints for variable in joint.variables}
    kinds = np.full(len(joint_names), engine.MOTION_LINEAR, dtype=np.int64)
    for j, name in enumerate(joint_names):
        joint = by_variable[name]
        if joint.type == 'continuous' or (joint.type == 'planar' and name.endswith('/theta')):
            kinds[j] = engine.MOTION_WRAP
        elif joint.type == 'floating' and name.endswith('/rot_x'):
            kinds[j] = engine.MOTION_QUATERNION
        elif joint.type == 'floating' and name.rsplit('/', 1)[-1] in ('rot_y', 'rot_z', 'rot_w'):
            kinds[j] = engine.MOTION_QUATERNION_REST
    return kinds


def interpolate(kinds: np.ndarray, q_from: np.ndarray, q_to: np.ndarray,
                t: np.ndarray) -> np.ndarray:
    """Return the states of the straight motion ``q_from -> q_to`` at fractions ``t``, by the
    rules in :func:`motion_kinds`: the engine's own interpolation (``cpp/motion.hpp``:
    StraightPath), for tests and tools that sample a motion.

    :param kinds: ``(J,) int64`` from :func:`motion_kinds`.
    :param t: ``(n,) float`` fractions in [0, 1].
    :return: ``(n, J) float64``.
    :raises JointStateError: a floating joint's quaternion at an end is zero or not finite.
    """
    return engine.interpolate(np.ascontiguousarray(kinds, dtype=np.int64),
                              np.ascontiguousarray(q_from, dtype=np.float64),
                              np.ascontiguousarray(q_to, dtype=np.float64),
                              np.ascontiguousarray(t, dtype=np.float64).reshape(-1))
