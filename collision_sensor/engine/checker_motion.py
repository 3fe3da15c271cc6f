"""The checker's motion checks (a room of
:class:`~collision_sensor.engine.checker.CollisionChecker`): ``check_motion``, ``update_motion``,
``check_path``, ``check_spline`` and ``check_trajectory``, each one call into the compiled
engine (``cpp/motion.hpp``); what the answers mean is :mod:`collision_sensor.engine.motion`'s.
"""

import numpy as np

from collision_sensor.engine.checker_queries import Positions
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.motion import MotionResult, PathResult
from collision_sensor.engine.trajectory import TrajectoryResult, check_trajectory
from collision_sensor.errors import JointStateError


class CheckerMotion:
    """:class:`~collision_sensor.engine.checker.CollisionChecker`'s motion checks: between two
    states, along the stream of states, paths, splines and planned trajectories."""

    @property
    def motion_kinds(self) -> np.ndarray:
        """(J,) int64: how each variable of :attr:`joint_names` moves along a motion
        (``engine.MOTION_*``; see :func:`collision_sensor.engine.motion.interpolate`)."""
        return self._joints.motion_kind

    def _check_motion(self, q_from: Positions, q_to: Positions) -> MotionResult:
        """Check the straight motion from ``q_from`` to ``q_to``: certified, never sampled.

        Revolute and prismatic joints move linearly, continuous joints (and a planar joint's
        theta) the shorter way round, planar and floating joints their translation linearly
        and their rotation along the shorter arc; mimic joints follow (MoveIt's
        interpolation, :mod:`collision_sensor.engine.motion`). A motion reported free has no
        state in contact; a reported ``first_contact`` t is in contact or within
        :data:`~collision_sensor.engine.motion.TOUCH_TOLERANCE` of it, and no earlier state is
        in contact. Padding, the exception list, world and attached objects count as in
        :meth:`check`. The carried incremental state is left as it was.

        :param q_from: the start, as ``positions`` of :meth:`check` (joints not given keep
            their current value).
        :param q_to: the end, the same way.
        :raises JointStateError: as :meth:`check`, naming the end at fault; nothing changes.
        """
        # check_motion (below the class) answers arrays the engine reads as they are in one
        # compiled call; it comes here for anything else (other sequences, mappings) and for
        # the values the engine refuses, which are named here.
        try:
            answer = self._motion(q_from, q_to)
        except JointStateError as error:
            raise self._refused_end(error, q_from, q_to) from None
        if answer is not None:
            return answer
        ends = []
        for end, positions in (('q_from', q_from), ('q_to', q_to)):
            try:
                ends.append(self._merged(positions))
            except JointStateError as error:
                raise JointStateError(f'{end}: {error}') from None
        try:
            return self._motion(*ends)
        except JointStateError as error:
            raise self._refused_end(error, *ends) from None

    def _refused_end(self, error: JointStateError, q_from: np.ndarray,
                     q_to: np.ndarray) -> JointStateError:
        """The error naming the end and joint of a motion the engine refused (``error.row``
        0: ``q_from``, 1: ``q_to``; ``error.variable``)."""
        end, q = ('q_from', q_from) if error.row == 0 else ('q_to', q_to)
        return JointStateError(f'{end}: ' + self._unusable_message(error.variable, q))

    def update_motion(self, positions: Positions) -> MotionResult:
        """Check the motion from the current state to ``positions`` (as :meth:`check_motion`),
        then move the state there as :meth:`update` does: what a stream of joint states
        needs, at about the cost of :meth:`update` (pairs its clearance keeps apart at both
        ends are apart all along). Before any state was checked there is no motion: the
        answer is ``positions``' own instant.

        :raises JointStateError: as :meth:`check`; nothing changes then.
        """
        try:
            step = self._query_motion(positions)
        except JointStateError as error:
            raise self._refused(error, positions) from None
        if step is not self._answer:   # else the same answer as last time (see _settle)
            if step is None:
                return self.update_motion(self._merged(positions))
            if (step.status_version != self._version
                    or step.rechecked != self._result.rechecked_pairs):
                self._settle(step, positions, False)
            self._answer = step
        return step.motion

    def check_path(self, configurations: np.ndarray) -> PathResult:
        """Check the straight motions between consecutive waypoints, in one compiled call,
        until one is not free (a single waypoint: its instant). The carried state is left as
        it was. The segments run on :attr:`threads` threads in contiguous chunks (a chunk
        stops once an earlier one met contact); the answer is one thread's.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape or an unusable value (naming the row and
            joint); nothing changes then.
        """
        Q = np.ascontiguousarray(configurations, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != len(self.joint_names) or not len(Q):
            raise JointStateError(f'expected waypoints of shape (n, {len(self.joint_names)}), '
                                  f'n >= 1, in the order of joint_names, got {Q.shape}')
        try:
            answer = self._engine.path(Q)
        except JointStateError as error:
            raise self._refused(error, Q[error.row], error.row) from None
        return PathResult(answer.segment if answer.segment >= 0 else None, answer.motion)

    def check_spline(self, coefficients: np.ndarray) -> PathResult:
        """Check polynomial path segments in turn, in one compiled call, until one is not free:
        segment i is ``q_j(t) = sum_k coefficients[i, j, k] t^k`` for t in [0, 1] (degree at
        most 5; planar and floating joints constant). ``first_contact`` is a fraction of the
        segment. The carried state is left as it was; segments run on :attr:`threads` threads
        as in :meth:`check_path`.

        :param coefficients: (S, J, 6) float, variables in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape, or a segment the engine cannot take (not
            finite, moving a planar or floating joint, or an unusable value at an end).
        """
        coef = np.ascontiguousarray(coefficients, dtype=np.float64)
        if coef.ndim != 3 or coef.shape[1:] != (len(self.joint_names), 6):
            raise JointStateError(f'expected coefficients of shape (S, {len(self.joint_names)},'
                                  f' 6), got {coef.shape}')
        try:
            answer = self._engine.spline(coef)
        except JointStateError as error:
            raise JointStateError(
                f'segment {error.row}: a coefficient is not finite, a planar or floating joint '
                'moves, or an end is beyond the engine\'s range; give finite polynomials of '
                'the 1-DOF joints') from None
        return PathResult(answer.segment if answer.segment >= 0 else None, answer.motion)

    def check_trajectory(self, joint_names, points, start=None,
                         limit_tolerance: float = 0.0) -> TrajectoryResult:
        """Check a planned trajectory (``trajectory_msgs/JointTrajectory``'s joint names and
        points) along the path joint_trajectory_controller will follow, from ``start``
        (default: the current positions): see :mod:`collision_sensor.engine.trajectory`.
        A malformed trajectory is invalid with its reason; nothing changes in the checker."""
        return check_trajectory(self, joint_names, points, start, limit_tolerance)



#: check_motion: a method of the class in the compiled engine's fast calling convention
#: (bind_engine.cpp: checker_check_motion), which answers from the checker's engine in one call
#: and leaves everything else to _check_motion (whose docstring it carries).
CheckerMotion.check_motion = engine.checker_motion_method(
    CheckerMotion, 'check_motion($self, q_from, q_to)\n--\n\n' + CheckerMotion._check_motion.__doc__)
