"""``/diagnostics``: the node's ``collision sensor`` status, once a second (as
diagnostic_updater), and each source's own status (``scene``).

With ``check_motion``: ``motion`` (``off``, ``sweeping``: the next verdict covers the motion
from the last state checked, or ``new_motion: <reason>``: the next state is checked as an
instant), ``motions_swept_total``, ``motion_contacts_on_the_way_total`` (verdicts whose contact
was only on the way) and ``new_motions_<reason>`` (:mod:`.motion_stream`).

Levels: OK; WARN while waiting for the robot's first joint states or missing joints, with joints
beyond their limits, after a rejected joint state in the period, or while ``allowed_collisions``
or ``warning_ignore`` names something that is no link or scene object (yet); ERROR without a
robot model, after an engine error until a state is checked again, while joint states are stale
(no accepted one for ``stale_timeout``), and while any other source's data are missing or too
old. Every value is bounded: names come through
:func:`~collision_sensor.untrusted_text.listing` (at most 10 each, escaped), whatever the input.
"""
import time

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from collision_sensor.ros.joint_state_merger import Problem
from collision_sensor.ros.motion_stream import NEW_MOTION_REASONS
from collision_sensor.untrusted_text import listing, printable

DIAGNOSTICS_PERIOD = 1.0    # s, as diagnostic_updater


class PeriodStats:
    """Counters of one diagnostics period."""

    def __init__(self):
        self.started = time.monotonic()
        self.received = 0
        self.rejected = 0
        self.checks = 0
        self.check_time_sum = 0.0
        self.check_time_max = 0.0


def _bound(value) -> str:
    return 'none' if value is None else f'{value:.6g}'


def sensor_status(node, joints, period: PeriodStats, now: float) -> DiagnosticStatus:
    """Return the ``collision sensor`` status for the period just closed (lock held).

    :param node: the :class:`~collision_sensor.ros.sensor_node.CollisionSensorNode`.
    :param joints: its :class:`~collision_sensor.ros.joint_state_source.JointStateSource`.
    """
    elapsed = max(now - period.started, 1e-9)
    settings, totals = node.settings, node.totals
    merger = joints.merger
    missing = merger.missing() if merger is not None else []
    unknown = sorted(merger.unknown_names) if merger is not None else []
    overflow = merger.unknown_overflow if merger is not None else 0
    held = node.verdicts.held
    in_collision = bool(held and held[0])
    level, message = DiagnosticStatus.OK, 'no collision'
    if in_collision:
        met = held[2].met
        message = 'in collision: ' + listing((f'{a}:{b}' for a, b in held[1]),
                                             total=len(held[1]))
        if met:
            message += '; met on the way: ' + listing((f'{a}:{b}' for a, b in met),
                                                      total=len(met))
    problems = []
    last_accepted = joints.last_accepted
    if node.checker is None:
        level = DiagnosticStatus.ERROR
        problems.append('no robot model (waiting for robot_description)')
    elif last_accepted is None:
        level = DiagnosticStatus.WARN
        problems.append('waiting for joint states')
    elif settings.require_all_joints and missing:
        level = DiagnosticStatus.WARN
        problems.append('waiting for joints ' + listing(missing))
    if joints.out_of_limits:
        level = max(level, DiagnosticStatus.WARN)
        problems.append('joints out of limits: ' + listing(sorted(joints.out_of_limits)))
    if period.rejected:
        level = max(level, DiagnosticStatus.WARN)
        problems.append(f'{period.rejected} joint states rejected')
    if node.engine_error:
        level = DiagnosticStatus.ERROR
        problems.append(f'engine error, no state checked since (on_engine_error '
                        f'{settings.on_engine_error}): {node.engine_error}')
    if joints.stale:
        level = DiagnosticStatus.ERROR
        problems.append(f'stale: no joint state for {now - last_accepted:.1f} s (stale_policy '
                        f'{settings.stale_policy})')
    pending = node.pending_names()
    if pending:
        level = max(level, DiagnosticStatus.WARN)
        problems.append('allowed_collisions or warning_ignore name(s) no link or scene object '
                        'has (yet): ' + listing(pending))
    for source in node.sources:
        if source is not joints and source.timed_out():
            level = DiagnosticStatus.ERROR
            problems.append(f'{source.name}: no data within its timeout')
    if node.rebuilding:
        problems.append('parameters changed: a new checker is being built')
    if problems:
        message = '; '.join(problems + ([message] if in_collision else []))
    mean_ms = 1e3 * period.check_time_sum / period.checks if period.checks else 0.0
    skipped = {
        'skipped_rejected': totals['rejected'],
        'skipped_ignored': totals['ignored'],
        'skipped_waiting_for_joints': totals['waiting_for_joints'],
        'skipped_no_model': totals['no_model'],
        'skipped_engine_error': totals['engine_errors'],
        'skipped_reader_error': totals['reader_errors'],
        'skipped_superseded': totals['superseded'],
    }
    values = {
        'state': 'ready' if node.ready else 'loading',
        'input_rate_hz': f'{period.received / elapsed:.1f}',
        'checks': str(period.checks),
        'check_time_mean_ms': f'{mean_ms:.4f}',
        'check_time_max_ms': f'{1e3 * period.check_time_max:.4f}',
        'rejected': str(period.rejected),
        'rejected_total': str(totals['rejected']),
        'engine_errors_total': str(totals['engine_errors']),
        'received_total': str(totals['received']),
        'verdicts_total': str(totals['verdicts']),
        'failure_answers_total': str(totals['failure_answers']),
        'skipped_total': str(sum(skipped.values())),
        **{key: str(value) for key, value in skipped.items()},
        **{f'rejected_{problem.name.lower()}': str(totals[f'rejected_{problem.name.lower()}'])
           for problem in Problem},
        'rejected_engine_range': str(totals['rejected_engine_range']),
        'rejected_oversized': str(totals['rejected_oversized']),
        'lost_total': str(totals['lost']),
        'clamped_total': str(totals['clamped']),
        'robot_description_rejected_total': str(totals['robot_description_rejected']),
        'unknown_joints': listing(unknown, total=len(unknown)),
        'unknown_joints_count': str(len(unknown)),
        'unknown_joints_not_remembered': str(overflow),
        'missing_joints': listing(missing),
        'out_of_limit_joints': listing(
            (f'{printable(name)}={value:.6g} [{_bound(lower)}, {_bound(upper)}]'
             for name, (value, lower, upper) in sorted(joints.out_of_limits.items())),
            total=len(joints.out_of_limits), escape=False),
        'joint_limit_policy': settings.joint_limit_policy,
        'stale': str(joints.stale).lower(),
        'stale_episodes_total': str(joints.stale_episodes),
        'seconds_since_joint_state': ('' if last_accepted is None
                                      else f'{now - last_accepted:.3f}'),
        'waiting_for_joints': str(bool(settings.require_all_joints and missing)).lower(),
        'in_collision': str(in_collision).lower(),
        'engine_error': node.engine_error,
        'on_engine_error': settings.on_engine_error,
        'stale_policy': settings.stale_policy,
        'on_rejected_input': settings.on_rejected_input,
        'model': printable(node.model_source, 300),
        'model_loading': str(node.model_loading).lower(),
        'parameter_changes_applied_total': str(totals['parameter_changes']),
        'parameters_pending': str(node.rebuilding).lower(),
        'names_pending': listing(pending, total=len(pending)),
        'check_motion': str(settings.check_motion).lower(),
        'motion': node.motion.state(settings.check_motion),
        'motions_swept_total': str(node.motion.counts['swept']),
        'motion_contacts_on_the_way_total': str(node.motion.counts['met_on_the_way']),
        'new_motions_total': str(sum(node.motion.counts[r] for r in NEW_MOTION_REASONS)),
        **{f'new_motions_{reason}': str(node.motion.counts[reason])
           for reason in NEW_MOTION_REASONS},
    }
    return DiagnosticStatus(
        level=level, name=f'{node.get_fully_qualified_name().lstrip("/")}: collision sensor',
        message=printable(message, 1000), hardware_id=printable(node.root_frame),
        values=[KeyValue(key=key, value=value) for key, value in values.items()])
