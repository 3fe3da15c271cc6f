"""A recorded sequence in memory: joint positions over time (:class:`JointSequence`), with the
scene's changes (:class:`SceneEvent`) and the point clouds (:class:`CloudEvent`) recorded
meanwhile. Reading and writing files: :mod:`collision_sensor.model.sequences`.
"""
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from collision_sensor.errors import SequenceError


@dataclass(frozen=True)
class SceneEvent:
    """One recorded change of the scene: a ``scene`` array, applied before the frames at or
    after ``time``.

    :ivar time: seconds, on the frames' clock.
    :ivar markers: the array's markers (objects with the fields of visualization_msgs/Marker).
    """

    time: float
    markers: tuple


@dataclass(frozen=True)
class CloudEvent:
    """One recorded point cloud, its points left in the bag (:func:`iter_cloud_messages`).

    :ivar time: seconds on the frames' clock: ``header.stamp``, or the log time when that is
        zero.
    :ivar source: the topic as recorded without its leading ``/`` (the source's name as the
        node's ``point_cloud_topics`` gives it; the obstacle is ``cloud/<source>``).
    :ivar frame: ``header.frame_id`` (untrusted text: escape it before printing).
    :ivar bag: the bag it is read from.
    :ivar ordinal: its place among the bag's cloud messages as the bag yields them.
    :ivar size: bytes of the serialized message.
    :ivar error: why the message could not be deserialized ('' when it could).
    :ivar log_time: seconds, when the bag received it (the player publishes it then).
    """

    time: float
    source: str
    frame: str
    bag: str
    ordinal: int
    size: int = 0
    error: str = ''
    log_time: float = 0.0


@dataclass(frozen=True)
class CloudSchedule:
    """When a sequence's clouds apply (:meth:`JointSequence.cloud_schedule`).

    :ivar before_first: clouds stamped before the first frame (the node drops them: no joint
        state to self-filter them with yet).
    :ivar per_frame: n lists: the clouds applied before frame i, those with a time in
        ``(times[i - 1], times[i]]`` (for frame 0, at its time).
    :ivar after_last: clouds stamped after the last frame (no frame checks them).
    """

    before_first: tuple
    per_frame: tuple
    after_last: tuple


@dataclass(frozen=True)
class JointSequence:
    """Joint positions over time, and the scene's changes meanwhile.

    :ivar joint_names: (J,) joint names, the column order of ``positions``.
    :ivar times: (n,) float64 seconds, strictly increasing.
    :ivar positions: (n, J) float64 joint positions.
    :ivar source: where the sequence came from (a file name), for messages.
    :ivar scene: :class:`SceneEvent` in time order (equal times in recorded order).
    :ivar clouds: :class:`CloudEvent` in time order (equal times in recorded order).
    """

    joint_names: tuple
    times: np.ndarray
    positions: np.ndarray
    source: str = ''
    scene: tuple = ()
    clouds: tuple = ()

    def __post_init__(self):
        names = tuple(str(name) for name in self.joint_names)
        times = np.ascontiguousarray(self.times, dtype=np.float64)
        positions = np.ascontiguousarray(self.positions, dtype=np.float64)
        if positions.ndim == 1 and len(names) == 0:
            positions = positions.reshape(len(times), 0)
        where = self.source or 'sequence'
        if times.ndim != 1 or positions.shape != (len(times), len(names)):
            raise SequenceError(
                f'{where}: positions have shape {positions.shape}, expected '
                f'({len(times)}, {len(names)}) for {len(times)} times and {len(names)} joints')
        if len(set(names)) != len(names):
            raise SequenceError(f'{where}: joint names repeat: {list(names)}')
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(positions))):
            raise SequenceError(f'{where}: times and positions must be finite numbers')
        if np.any(np.diff(times) <= 0.0):
            row = int(np.argmax(np.diff(times) <= 0.0)) + 1
            raise SequenceError(
                f'{where}: frame {row}: time {times[row]!r} is not after {times[row - 1]!r}; '
                'times must strictly increase')
        event_times = [event.time for event in self.scene]
        if not all(math.isfinite(t) for t in event_times) or event_times != sorted(event_times):
            raise SequenceError(f'{where}: scene event times must be finite and in order')
        cloud_times = [event.time for event in self.clouds]
        if not all(math.isfinite(t) for t in cloud_times) or cloud_times != sorted(cloud_times):
            raise SequenceError(f'{where}: cloud times must be finite and in order')
        times.setflags(write=False)
        positions.setflags(write=False)
        object.__setattr__(self, 'joint_names', names)
        object.__setattr__(self, 'times', times)
        object.__setattr__(self, 'positions', positions)
        object.__setattr__(self, 'scene', tuple(self.scene))
        object.__setattr__(self, 'clouds', tuple(self.clouds))

    def __len__(self) -> int:
        return len(self.times)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame (0 for fewer than two frames)."""
        return float(self.times[-1] - self.times[0]) if len(self.times) else 0.0

    def select(self, joint_names: Sequence[str]) -> 'JointSequence':
        """Return the sequence with columns reordered to ``joint_names``.

        :raises SequenceError: if a name is not a column of this sequence.
        """
        missing = [name for name in joint_names if name not in self.joint_names]
        if missing:
            raise SequenceError(
                f'{self.source or "sequence"}: no column for joint(s) {missing}; '
                f'it has {list(self.joint_names)}')
        columns = [self.joint_names.index(name) for name in joint_names]
        return JointSequence(tuple(joint_names), self.times, self.positions[:, columns],
                             self.source, self.scene, self.clouds)

    def scene_before(self) -> list:
        """Return, for each frame i, the scene events to apply before it: those with a time
        up to ``times[i]`` not yet applied; the events after the last frame go with it.

        :return: n lists of :class:`SceneEvent`.
        """
        out, k = [], 0
        for i, t in enumerate(self.times.tolist()):
            start = k
            while k < len(self.scene) and (self.scene[k].time <= t or i == len(self) - 1):
                k += 1
            out.append(list(self.scene[start:k]))
        return out

    def cloud_schedule(self) -> CloudSchedule:
        """Return when each cloud applies: before the first frame at or after its time (as a
        scene array), the robot's state at its time known then (:meth:`positions_at`)."""
        times = self.times
        if not self.clouds:
            return CloudSchedule((), ((),) * len(times), ())
        cloud_times = np.array([event.time for event in self.clouds], dtype=np.float64)
        # frame index of the first frame at or after each cloud's time (n: after the last)
        frame = np.searchsorted(times, cloud_times, side='left')
        early = cloud_times < times[0] if len(times) else np.ones(len(cloud_times), bool)
        per_frame = [[] for _ in range(len(times))]
        before, after = [], []
        for event, i, is_early in zip(self.clouds, frame.tolist(), early.tolist()):
            if is_early:
                before.append(event)
            elif i >= len(times):
                after.append(event)
            else:
                per_frame[i].append(event)
        return CloudSchedule(tuple(before), tuple(tuple(f) for f in per_frame), tuple(after))

    def positions_at(self, t: float) -> np.ndarray:
        """Return the joint positions at time ``t``: linear between the two frames around it
        (as the sensor's window of recent states, ``Sensor.positions_at``, with every frame
        kept); the first or last frame outside them.

        :return: (J,) float64.
        """
        times = self.times
        k = int(np.searchsorted(times, t, side='right'))     # times[k - 1] <= t < times[k]
        if k == 0:
            return self.positions[0].copy()
        if k >= len(times):
            return self.positions[-1].copy()
        t0, t1 = float(times[k - 1]), float(times[k])
        s = (t - t0) / (t1 - t0)
        return (1.0 - s) * self.positions[k - 1] + s * self.positions[k]

    def __eq__(self, other):
        if not isinstance(other, JointSequence):
            return NotImplemented
        return (self.joint_names == other.joint_names
                and np.array_equal(self.times, other.times)
                and np.array_equal(self.positions, other.positions))

    __hash__ = None
