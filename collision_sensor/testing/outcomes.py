"""What a test gets back from the sensor under test: answers, and inputs still waiting for one."""
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Optional, Tuple

from trajectory_msgs.msg import JointTrajectory

from collision_sensor.ros.answers import TrajectoryAnswer, Verdict
from collision_sensor.ros.trajectory_source import trajectory_digest

if TYPE_CHECKING:
    from collision_sensor.testing.sensor import SensorUnderTest

#: s an answer is awaited by default (generous: CI machines are shared).
TIMEOUT = 30.0


class NoAnswer(AssertionError):
    """The node gave no answer to something sent, within the time allowed."""


@dataclass(frozen=True)
class SceneAnswer:
    """The node's answer to a scene array.

    :ivar applied: the array was applied (else rejected, and the scene is as it was).
    :ivar reason: why it was rejected ('' when applied).
    :ivar objects: the scene's objects after it (the ``scene`` status's list, at most 10).
    :ivar verdict: the verdict at the current state with the new scene (None before a state
        was checked).
    """

    applied: bool
    reason: str
    objects: Tuple[str, ...]
    verdict: Optional[Verdict]


@dataclass(frozen=True)
class CloudAnswer:
    """The node's answer to a point cloud.

    :ivar accepted: the cloud is the obstacle ``cloud/<topic>`` now (else refused, and the last
        good one stays).
    :ivar reason: why it was refused ('' when accepted).
    :ivar verdict: the verdict at the current state with it (None when refused, or before a
        state was checked).
    """

    accepted: bool
    reason: str
    verdict: Optional[Verdict]


@dataclass(frozen=True)
class TrajectoryOutcome(TrajectoryAnswer):
    """A trajectory's answer, and whether it came out on ``trajectory_out``.

    :ivar relayed: the trajectory was relayed (a valid one; an invalid one never is).
    """

    relayed: bool = False


class PendingVerdict:
    """A joint state sent; :meth:`result` waits for its verdict."""

    def __init__(self, sensor: 'SensorUnderTest', key: Tuple[int, int, str]):
        self._sensor, self.key = sensor, key

    def result(self, timeout: float = TIMEOUT) -> Verdict:
        """Return the verdict answering this joint state.

        :raises NoAnswer: none within ``timeout`` s (refused states are answered too; only a
            state the node skipped under overload is not: ``overload_policy: every``).
        """
        return self._sensor.verdict_for(self.key, timeout)


class PendingTrajectory:
    """A trajectory sent; :meth:`result` waits for its answer."""

    def __init__(self, sensor: 'SensorUnderTest', msg: JointTrajectory):
        self._sensor, self.msg = sensor, msg
        self.digest = trajectory_digest(msg)
        self.answer: Optional[TrajectoryAnswer] = None
        self.answered_before = 0    # the node's answers this client had when it was sent
        self.relay_rank = 0     # the n-th valid answer to this digest: the n-th relay of it

    def result(self, timeout: float = TIMEOUT) -> TrajectoryAnswer:
        """Return the node's answer.

        :raises NoAnswer: none within ``timeout`` s.
        """
        return self._sensor.trajectory_answer(self, timeout)

    def outcome(self, timeout: float = TIMEOUT) -> 'TrajectoryOutcome':
        """Return the node's answer and whether the trajectory was relayed (a valid one: once
        it came out on ``trajectory_out``)."""
        answer = self.result(timeout)
        relayed = answer.valid and self._sensor.wait(
            lambda: self.relayed, timeout, 'a valid trajectory was not relayed on trajectory_out')
        return TrajectoryOutcome(**{f.name: getattr(answer, f.name) for f in fields(answer)},
                                 relayed=relayed)

    @property
    def relayed(self) -> bool:
        """True once the trajectory came out on ``trajectory_out`` (after a valid answer)."""
        return self._sensor.is_relayed(self)
