"""``/diagnostics``: the node's ``collision sensor`` status, once a second (as
diagnostic_updater), and each source's own status (``scene``, ``trajectory``, clouds).

With ``check_motion``: ``motion`` (``off``, ``sweeping``: the next verdict covers the motion
from the last state checked, or ``new_motion: <reason>``: the next state is checked as an
instant), ``motions_swept_total``, ``motion_contacts_on_the_way_total`` (verdicts whose contact
was only on the way) and ``new_motions_<reason>`` (``collision_sensor.sensor.NEW_MOTION_REASONS``).

Levels: OK; WARN while waiting for the robot's first joint states or missing joints, with joints
beyond their limits, after a rejected joint state in the period, or while ``allowed_collisions``
or ``warning_ignore`` names something that is no link or scene object (yet); ERROR without a
robot model, after an engine error until a state is checked again, while joint states are stale
(no accepted one for ``stale_timeout``), and while any other source's data are missing or too
old. Every value is bounded: names come through
:func:`~collision_sensor.untrusted_text.listing` (at most 10 each, escaped), whatever the input.
"""
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from collision_sensor.sensor import NEW_MOTION_REASONS
from collision_sensor.untrusted_text import listing, printable

DIAGNOSTICS_PERIOD = 1.0    # s, as diagnostic_updater
#: The reasons a joint state is rejected (``rejected_<problem>_total`` each).
REJECTION_PROBLEMS = ('length_mismatch', 'duplicate_names', 'not_finite', 'out_of_limits',
                      'engine_range', 'oversized', 'malformed')


def _bound(value) -> str:
    return 'none' if value is None or abs(value) == float('inf') else f'{value:.6g}'


def _pairs(pairs) -> str:
    return listing((f'{a}:{b}' for a, b in pairs), total=len(pairs))


def sensor_status(node, snapshot: dict, elapsed: float) -> DiagnosticStatus:
    """Return the ``collision sensor`` status for the period just closed.

    :param node: the :class:`~collision_sensor.ros.node.CollisionSensorNode`.
    :param snapshot: ``node.sensor.snapshot(reset_period=True)``.
    :param elapsed: the period's length (s).
    """
    settings, totals, joints = node.settings, snapshot['totals'], node.joints
    elapsed = max(elapsed, 1e-9)
    missing, unknown = snapshot['missing'], snapshot['unknown']
    in_collision = snapshot['held'] and snapshot['held_contact']
    level, message = DiagnosticStatus.OK, 'no collision'
    if in_collision:
        message = 'in collision: ' + _pairs(snapshot['held_now'])
        if snapshot['held_met']:
            message += '; met on the way: ' + _pairs(snapshot['held_met'])
    problems = []
    accepted = snapshot['accepted_any']
    if node.checker is None:
        level = DiagnosticStatus.ERROR
        problems.append('no robot model (waiting for robot_description)')
    elif not accepted:
        level = DiagnosticStatus.WARN
        problems.append('waiting for joint states')
    elif settings.require_all_joints and missing:
        level = DiagnosticStatus.WARN
        problems.append('waiting for joints ' + listing(missing))
    out_of_limits = snapshot['out_of_limits']
    if out_of_limits:
        level = max(level, DiagnosticStatus.WARN)
        problems.append('joints out of limits: ' + listing(name for name, *_ in out_of_limits))
    if snapshot['period_rejected']:
        level = max(level, DiagnosticStatus.WARN)
        problems.append(f'{snapshot["period_rejected"]} joint states rejected')
    if snapshot['engine_error']:
        level = DiagnosticStatus.ERROR
        problems.append(f'engine error, no state checked since (on_engine_error '
                        f'{settings.on_engine_error}): {snapshot["engine_error"]}')
    if snapshot['stale']:
        level = DiagnosticStatus.ERROR
        problems.append(f'stale: no joint state for {snapshot["seconds_since_accepted"]:.1f} s '
                        f'(stale_policy {settings.stale_policy})')
    pending = node.pending_names()
    if pending:
        level = max(level, DiagnosticStatus.WARN)
        problems.append('allowed_collisions or warning_ignore name(s) no link or scene object '
                        'has (yet): ' + listing(pending))
    for source in node.sources:
        if getattr(source, 'timed_out', lambda: False)():
            level = DiagnosticStatus.ERROR
            problems.append(f'{source.name}: no data within its timeout')
    if node.rebuilding:
        problems.append('parameters changed: a new checker is being built')
    if problems:
        message = '; '.join(problems + ([message] if in_collision else []))
    checks = snapshot['period_checks']
    mean_ms = 1e3 * snapshot['period_check_time_sum'] / checks if checks else 0.0
    node_totals = node.totals
    skipped = {
        'skipped_rejected': totals.get('rejected', 0),
        'skipped_ignored': totals.get('ignored', 0),
        'skipped_waiting_for_joints': totals.get('waiting_for_joints', 0),
        'skipped_no_model': totals.get('no_model', 0),
        'skipped_engine_error': totals.get('engine_errors', 0),
        'skipped_reader_error': node_totals['reader_errors'],
        'skipped_superseded': totals.get('superseded', 0),
    }
    motion = snapshot['motion_counts']
    values = {
        'state': 'ready' if node.ready else 'loading',
        'joint_states_in': joints.way_in or 'not yet',
        'input_rate_hz': f'{snapshot["period_received"] / elapsed:.1f}',
        'checks': str(checks),
        'check_time_mean_ms': f'{mean_ms:.4f}',
        'check_time_max_ms': f'{1e3 * snapshot["period_check_time_max"]:.4f}',
        'rejected': str(snapshot['period_rejected']),
        'rejected_total': str(totals.get('rejected', 0)),
        'engine_errors_total': str(totals.get('engine_errors', 0)),
        'received_total': str(totals.get('received', 0)),
        'verdicts_total': str(totals.get('verdicts', 0)),
        'failure_answers_total': str(totals.get('failure_answers', 0)),
        'skipped_total': str(sum(skipped.values())),
        **{key: str(value) for key, value in skipped.items()},
        **{f'rejected_{problem}': str(totals.get(f'rejected_{problem}', 0))
           for problem in REJECTION_PROBLEMS},
        'lost_total': str(joints.lost),
        'clamped_total': str(totals.get('clamped', 0)),
        'robot_description_rejected_total': str(node_totals['robot_description_rejected']),
        'unknown_joints': listing(unknown, total=len(unknown)),
        'unknown_joints_count': str(len(unknown)),
        'unknown_joints_not_remembered': str(snapshot['unknown_overflow']),
        'missing_joints': listing(missing),
        'out_of_limit_joints': listing(
            (f'{printable(name)}={value:.6g} [{_bound(lower)}, {_bound(upper)}]'
             for name, value, lower, upper in out_of_limits),
            total=len(out_of_limits), escape=False),
        'joint_limit_policy': settings.joint_limit_policy,
        'stale': str(snapshot['stale']).lower(),
        'stale_episodes_total': str(snapshot['stale_episodes']),
        'seconds_since_joint_state': (f'{snapshot["seconds_since_accepted"]:.3f}'
                                      if accepted else ''),
        'waiting_for_joints': str(bool(settings.require_all_joints and missing)).lower(),
        'in_collision': str(bool(in_collision)).lower(),
        'engine_error': snapshot['engine_error'],
        'on_engine_error': settings.on_engine_error,
        'stale_policy': settings.stale_policy,
        'on_rejected_input': settings.on_rejected_input,
        'model': printable(node.model_source, 300),
        'model_loading': str(node.model_loading).lower(),
        'parameter_changes_applied_total': str(node_totals['parameter_changes']),
        'parameters_pending': str(node.rebuilding).lower(),
        'names_pending': listing(pending, total=len(pending)),
        'check_motion': str(settings.check_motion).lower(),
        'motion': snapshot['motion_state'],
        'motions_swept_total': str(motion.get('swept', 0)),
        'motion_contacts_on_the_way_total': str(motion.get('met_on_the_way', 0)),
        'new_motions_total': str(sum(motion.get(r, 0) for r in NEW_MOTION_REASONS)),
        **{f'new_motions_{reason}': str(motion.get(reason, 0)) for reason in NEW_MOTION_REASONS},
    }
    return DiagnosticStatus(
        level=level, name=f'{node.get_fully_qualified_name().lstrip("/")}: collision sensor',
        message=printable(message, 1000), hardware_id=printable(node.root_frame),
        values=[KeyValue(key=key, value=value) for key, value in values.items()])
