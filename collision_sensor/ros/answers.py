"""The node's answers read as plain values: verdicts, trajectory answers, the scene and cloud
statuses of ``/diagnostics``.

What a client of the node (``collision_sensor_ctl``, :mod:`collision_sensor.testing`) reads from
the topics, by the formats ``docs/node.md`` gives: a verdict is one ``contact``
(``std_msgs/Bool``) and one ``colliding_pairs`` (``diagnostic_msgs/DiagnosticArray``) whose
statuses are pairs in contact at the state (``link_a:link_b``, values ``link_a``, ``link_b``),
pairs met on the way (the same, with ``first_contact``) or one failure entry (a name without
``:``, values ``kind``, ``reason``, ``policy``); a trajectory's answer is one status on
``trajectory_result``. Pairs are read from the ``link_a`` and ``link_b`` values, never by
splitting a name (object and cloud names may hold ``/``).
"""
import re
from dataclasses import dataclass
from typing import Dict, Optional, Tuple

Pair = Tuple[str, str]


def status_values(status) -> Dict[str, str]:
    """Return a ``diagnostic_msgs/DiagnosticStatus``'s key/values as a dict."""
    return {item.key: item.value for item in status.values}


@dataclass(frozen=True)
class Verdict:
    """One verdict: what ``contact`` and ``colliding_pairs`` say about one input.

    :ivar contact: the ``contact`` flag (with the fail-safe policy ``contact``, true for a
        failure entry).
    :ivar pairs: the pairs in contact at the state, as the node names them.
    :ivar met: the pairs met on the way from the state before (``check_motion``) and not in
        contact now.
    :ivar first_contact: where on the way they met (fraction of the motion), None without
        such pairs.
    :ivar failure: the failure entry's kind (``joint_state_rejected``, ``waiting_for_joints``,
        ``engine_error``, ``joint_states_stale``, ``point_cloud_timeout``, ...), '' for a
        checked state.
    :ivar reason: the failure entry's reason ('' for a checked state).
    :ivar stamp: ``colliding_pairs``' header stamp, ``(sec, nanosec)``.
    :ivar frame: its header frame (the joint state's, or the root link for a verdict the node
        gives on its own: a scene array, a cloud, a parameter change).
    """

    contact: bool
    pairs: Tuple[Pair, ...]
    met: Tuple[Pair, ...]
    first_contact: Optional[float]
    failure: str
    reason: str
    stamp: Tuple[int, int]
    frame: str

    @property
    def in_contact_now(self) -> bool:
        """True iff some pair is in contact at the state itself."""
        return bool(self.pairs)


def verdict_from(contact: bool, msg) -> Verdict:
    """Read a verdict: ``contact`` (the Bool's value) and ``msg`` (its ``colliding_pairs``)."""
    pairs, met, first_contact, failure, reason = [], [], None, '', ''
    for status in msg.status:
        values = status_values(status)
        if 'link_a' in values and 'link_b' in values:
            pair = (values['link_a'], values['link_b'])
            if 'first_contact' in values:
                met.append(pair)
                first_contact = float(values['first_contact'])
            else:
                pairs.append(pair)
        elif not failure:
            failure, reason = values.get('kind', status.name), values.get('reason',
                                                                          status.message)
    stamp = msg.header.stamp
    return Verdict(bool(contact), tuple(pairs), tuple(met), first_contact, failure, reason,
                   (stamp.sec, stamp.nanosec), msg.header.frame_id)


@dataclass(frozen=True)
class TrajectoryAnswer:
    """The node's answer to one trajectory (one status on ``trajectory_result``).

    :ivar valid: the trajectory is free and within limits (then relayed on ``trajectory_out``).
    :ivar kind: ``valid``, ``contact``, ``joint_limits``, ``malformed``, ``no_start``,
        ``oversized``, ``dropped`` or ``engine_error``.
    :ivar reason: why not valid, naming the joint, point or pair ('' when valid).
    :ivar first_invalid_segment: 0 from the start to point 0, i from point i - 1 to point i;
        None when none.
    :ivar time_from_start: s, of the first contact or limit violation; None when none.
    :ivar colliding_pairs: the pairs in contact there (the node lists at most 10).
    :ivar digest: ``trajectory_digest`` ('' for one answered undecoded).
    :ivar stamp: the trajectory's header stamp, echoed, ``(sec, nanosec)``.
    :ivar frame: the trajectory's header frame, echoed.
    :ivar index: ``answer_index``: 1 for the node's first answer, then one more for each (0 when
        the answer carries none).
    """

    valid: bool
    kind: str
    reason: str
    first_invalid_segment: Optional[int]
    time_from_start: Optional[float]
    colliding_pairs: Tuple[Pair, ...]
    points: int
    joints: int
    digest: str
    stamp: Tuple[int, int]
    frame: str
    index: int = 0


def answers_it(answer: TrajectoryAnswer, digest: str, answered_before: int,
               header=None) -> bool:
    """Return whether ``answer`` answers the trajectory of ``digest`` that its client published
    when the node had given ``answered_before`` answers (its trajectory status's
    ``trajectories_total``): older answers to the same trajectory, which a subscription receives
    when it joins (``trajectory_result`` is transient local), are not its.

    :param header: the trajectory's ``std_msgs/Header``: then an answer given undecoded
        (``oversized``, ``dropped``: no digest) is its when it carries that header.
    """
    if answer.index <= answered_before:
        return False
    if answer.digest:
        return answer.digest == digest
    return header is not None and answer.stamp == (header.stamp.sec, header.stamp.nanosec) \
        and answer.frame == header.frame_id


def trajectory_answer_from(msg) -> TrajectoryAnswer:
    """Read one ``trajectory_result`` message.

    :raises ValueError: it holds no trajectory status.
    """
    if len(msg.status) != 1 or not msg.status[0].name.endswith(': trajectory'):
        raise ValueError('not an answer to a trajectory: trajectory_result carries one status '
                         'named "<node>: trajectory"')
    values = status_values(msg.status[0])
    listed = re.sub(r' \(\+\d+ more\)$', '', values.get('colliding_pairs', ''))
    pairs = tuple(tuple(entry.split(':', 1)) for entry in listed.split(', ') if ':' in entry)
    segment, at = values.get('first_invalid_segment', ''), values.get('time_from_start', '')
    stamp = msg.header.stamp
    return TrajectoryAnswer(
        valid=values.get('valid') == 'true', kind=values.get('kind', ''),
        reason=values.get('reason', ''),
        first_invalid_segment=int(segment) if segment else None,
        time_from_start=float(at) if at else None, colliding_pairs=pairs,
        points=int(values.get('points', '0') or 0), joints=int(values.get('joints', '0') or 0),
        digest=values.get('trajectory_digest', ''), stamp=(stamp.sec, stamp.nanosec),
        frame=msg.header.frame_id, index=_integer(values.get('answer_index', '')))


def _integer(text: str) -> int:
    """``text`` as a non-negative integer; 0 when it is not one."""
    return int(text) if text.isdigit() else 0


#: The ``scene`` status's counts that together count the arrays the node has handled.
SCENE_COUNTS = ('scene_arrays_applied_total', 'scene_arrays_rejected_total',
                'scene_arrays_dropped_total')
#: A point cloud status's counts that together count the clouds the node is done with.
CLOUD_COUNTS = ('clouds_accepted_total', 'clouds_rejected_total', 'clouds_superseded_total',
                'clouds_dropped_total')


def handled_total(values: Dict[str, str], keys) -> Optional[int]:
    """Return the sum of the counts ``keys`` of a status's values (None if one is missing)."""
    try:
        return sum(int(values[key]) for key in keys)
    except (KeyError, ValueError):
        return None
