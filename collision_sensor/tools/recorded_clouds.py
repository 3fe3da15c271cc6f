"""A recording's point clouds applied to a checker as the node applies its point cloud topics
(issue 29, item 3): the offline checker's and the batch audit's, one rule for both.

Each cloud of a bag (:class:`~collision_sensor.model.sequences.CloudEvent`) applies before the
first frame at or after its time, after the scene arrays due there (an attached object filters
points), in time order; its points are self-filtered with the robot's state at the cloud's time,
interpolated between the frames around it (:meth:`JointSequence.positions_at`: what the node's
joint-state window gives once the joint state after the stamp has come, as it has when a camera's
clouds come with the usual delay), and stamped with that time (``persistence``). What a cloud
becomes is the node's: :func:`~collision_sensor.model.point_cloud_message.cloud_rows` reads it,
:func:`~collision_sensor.model.point_cloud_message.cloud_frame` takes its ``header.frame_id``
(a link of the robot or its world frame), ``CollisionChecker.prepare_points`` filters and
voxelises it with the checker's ``voxel_size``, ``self_filter_padding`` and ``max_points``
and :class:`CloudOptions`' ``max_range`` and ``persistence`` (the node's ``point_cloud_*``
parameters), and a cloud whose every point is NaN is refused. A cloud that cannot be taken is
counted with its reason and changes nothing (the last good cloud of its source stays the
obstacle, as in the node); the check goes on. Clouds stamped before the first frame are
dropped (the node has no joint state to filter them with yet), those after the last frame are
not checked by any frame; both are counted.

The points are read from the bag when their turn comes, one cloud at a time
(:func:`~collision_sensor.model.sequences.iter_cloud_messages`).
"""
import math
from collections import Counter
from dataclasses import dataclass
from typing import Dict, List, Optional

from collision_sensor.errors import JointStateError, PointCloudError
from collision_sensor.model.point_cloud_message import (
    CloudMessageError, cloud_frame, cloud_rows, require_some_valid)
from collision_sensor.model.sequences import CloudEvent, JointSequence, iter_cloud_messages
from collision_sensor.untrusted_text import printable

#: Reasons a cloud is not applied, besides the parser's kinds (``empty``, ``fields``,
#: ``layout``), ``frame`` and ``invalid``.
UNREADABLE, ENGINE = 'unreadable', 'engine'
BEFORE_FIRST, AFTER_LAST = 'before_first_frame', 'after_last_frame'
#: Rejection messages kept in full per run (the rest are counted).
MAX_MESSAGES = 20


@dataclass(frozen=True)
class CloudOptions:
    """The node's ``point_cloud_*`` parameters that are no checker setting (``voxel_size``,
    ``self_filter_padding`` and ``max_points`` are: the checker's config).

    :ivar max_range: points farther than this (m) from the cloud frame's origin are dropped.
    :ivar persistence: seconds a voxel of an earlier cloud of the source stays (0: only the
        latest cloud counts).
    """

    max_range: float = math.inf
    persistence: float = 0.0


@dataclass(frozen=True)
class CloudOutcome:
    """What became of one recorded cloud.

    :ivar event: the cloud.
    :ivar voxels: occupied voxels kept when applied, else None.
    :ivar reason: '' when applied, else the rejection's kind (``fields``, ``frame``, ...).
    :ivar message: why, naming the cloud and the fix ('' when applied).
    """

    event: CloudEvent
    voxels: Optional[int]
    reason: str = ''
    message: str = ''

    def as_json(self) -> dict:
        """Return the outcome as a JSON line's entry: ``{"source", "time", "frame", "voxels"}``,
        and ``"error"`` when not applied."""
        entry = {'source': self.event.source, 'time': self.event.time,
                 'frame': printable(self.event.frame, 200), 'voxels': self.voxels}
        if self.reason:
            entry['error'] = self.message
        return entry


class CloudReplay:
    """Applies a sequence's clouds to a checker, frame by frame (module docstring).

    :param seq: the sequence (its ``clouds``).
    :param path: the bag to read the points from (default: the events' own).
    :ivar outcomes: every cloud's :class:`CloudOutcome` so far, in time order.
    """

    def __init__(self, seq: JointSequence, options: CloudOptions = CloudOptions(),
                 path: Optional[str] = None):
        self.seq, self.options = seq, options
        self.schedule = seq.cloud_schedule()
        applied = [event for events in self.schedule.per_frame for event in events]
        self._messages = iter_cloud_messages(applied, path) if applied else iter(())
        self.outcomes: List[CloudOutcome] = [
            CloudOutcome(event, None, BEFORE_FIRST, f'{_name(event)}: stamped before the first '
                         'joint state; dropped, as the node drops a cloud it cannot self-filter '
                         f'yet{_at(event)}') for event in self.schedule.before_first]

    def __len__(self) -> int:
        return len(self.seq.clouds)

    def due(self, index: int) -> bool:
        """True iff clouds apply before frame ``index``."""
        return bool(self.schedule.per_frame[index]) if self.schedule.per_frame else False

    def apply_before(self, checker, index: int) -> List[CloudOutcome]:
        """Apply the clouds due before frame ``index``; return their outcomes.

        :raises SequenceError: the bag cannot be read again.
        """
        out = []
        for event in self.schedule.per_frame[index]:
            _, msg = next(self._messages)
            out.append(self._apply(checker, event, msg))
        self.outcomes += out
        return out

    def finish(self) -> None:
        """Count the clouds after the last frame; close the bag."""
        self.outcomes += [CloudOutcome(event, None, AFTER_LAST, f'{_name(event)}: stamped after '
                                       f'the last joint state; no frame checks it{_at(event)}')
                          for event in self.schedule.after_last]
        close = getattr(self._messages, 'close', None)
        if close is not None:
            close()

    def _apply(self, checker, event: CloudEvent, msg) -> CloudOutcome:
        name = _name(event)
        if msg is None:
            return CloudOutcome(event, None, UNREADABLE, f'{name}: {event.error}{_at(event)}')
        try:
            rows = cloud_rows(msg, name)
            frame = cloud_frame(rows.frame, checker.kinematics.link_names,
                                checker.world_frames, name)
            prepared = checker.prepare_points(
                event.source, rows.points, frame,
                positions=self.seq.positions_at(event.time), stamp=event.time,
                persistence=self.options.persistence, max_range=self.options.max_range)
            require_some_valid(prepared.stats, name)
        except CloudMessageError as error:
            return CloudOutcome(event, None, error.kind, f'{error}{_at(event)}')
        except (PointCloudError, JointStateError) as error:
            return CloudOutcome(event, None, ENGINE,
                                f'{name}: {printable(error, 500)}{_at(event)}')
        return CloudOutcome(event, checker.commit_points(prepared))

    def counts(self) -> Dict[str, object]:
        """Return the report's ``point_clouds`` entry: ``{"clouds", "applied", "rejected":
        {reason: count}, "messages": [the first rejections' messages], "sources"}``."""
        rejected = Counter(outcome.reason for outcome in self.outcomes if outcome.reason)
        messages = [outcome.message for outcome in self.outcomes if outcome.reason]
        return {'clouds': len(self.seq.clouds),
                'applied': sum(1 for outcome in self.outcomes if not outcome.reason),
                'rejected': dict(sorted(rejected.items())),
                'messages': messages[:MAX_MESSAGES],
                'sources': sorted({event.source for event in self.seq.clouds})}


def _name(event: CloudEvent) -> str:
    return f'point cloud {printable(event.source, 200)}'


def _at(event: CloudEvent) -> str:
    return f' (the cloud at {event.time:.3f} s)'


def summary_lines(counts: Dict[str, object]) -> List[str]:
    """Return the summary's lines on a recording's clouds (:meth:`CloudReplay.counts`)."""
    if not counts or not counts['clouds']:
        return []
    lines = [f'point clouds:        {counts["applied"]} of {counts["clouds"]} applied '
             f'({", ".join(printable(source, 200) for source in counts["sources"])})']
    rejected = counts['rejected']
    if rejected:
        lines.append('  not applied: ' + ', '.join(f'{count} {reason}'
                                                   for reason, count in rejected.items()))
        for message in counts['messages'][:5]:
            lines.append(f'  {message}')
    return lines


def cloud_summary_lines(records) -> List[str]:
    """Return a batch summary's lines on the units' clouds (their ``point_clouds`` entries)."""
    with_clouds = [r for r in records if r.get('point_clouds')]
    if not with_clouds:
        return []
    total = sum(r['point_clouds']['clouds'] for r in with_clouds)
    applied = sum(r['point_clouds']['applied'] for r in with_clouds)
    refused = [r for r in with_clouds if r['point_clouds']['rejected']]
    lines = ['', f'point clouds: {applied} of {total} applied in {len(with_clouds)} units']
    if refused:
        reasons = Counter()
        for r in refused:
            reasons.update(r['point_clouds']['rejected'])
        lines.append(f'  not applied in {len(refused)} units: ' + ', '.join(
            f'{count} {reason}' for reason, count in sorted(reasons.items()))
            + ' (each line\'s point_clouds.messages says why)')
    return lines
