"""The node's answers read as values: built here as the node builds them (its VerdictPublisher
and failure entries; a trajectory status as trajectory_source writes it)."""
import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402

from collision_sensor.ros.answers import (  # noqa: E402
    SCENE_COUNTS, handled_total, trajectory_answer_from, verdict_from)


def status(name, **values):
    return DiagnosticStatus(level=DiagnosticStatus.ERROR, name=name, message='m',
                            values=[KeyValue(key=k, value=v) for k, v in values.items()])


def test_pairs_now_pairs_on_the_way_and_failures():
    msg = DiagnosticArray(status=[
        status('cloud/camera/points:panda_hand', link_a='cloud/camera/points',
               link_b='panda_hand'),
        status('ball:panda_link7', link_a='ball', link_b='panda_link7', first_contact='0.25')])
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = 3, 4, 'f'
    verdict = verdict_from(True, msg)
    assert verdict.pairs == (('cloud/camera/points', 'panda_hand'),)
    assert verdict.met == (('ball', 'panda_link7'),) and verdict.first_contact == 0.25
    assert (verdict.failure, verdict.stamp, verdict.frame) == ('', (3, 4), 'f')
    assert verdict.contact and verdict.in_contact_now
    held = verdict_from(True, DiagnosticArray(status=[
        status('joint_states_stale', kind='joint_states_stale', reason='why', policy='hold'),
        status('a:b', link_a='a', link_b='b')]))
    assert (held.failure, held.reason, held.pairs) == ('joint_states_stale', 'why',
                                                       (('a', 'b'),))
    clear = verdict_from(False, DiagnosticArray())
    assert not clear.contact and not clear.in_contact_now and clear.pairs == ()


def test_a_trajectory_answer_with_its_pairs_listed_and_cut():
    values = dict(valid='false', kind='contact', first_invalid_segment='2',
                  time_from_start='1.5', link_a='a', link_b='b',
                  colliding_pairs='a:b, c/d:e (+9 more)', reason='contact at ...', points='3',
                  joints='7', trajectory_digest='ab' * 32)
    msg = DiagnosticArray(status=[status('robot1/collision_sensor: trajectory', **values)])
    answer = trajectory_answer_from(msg)
    assert (answer.valid, answer.kind, answer.first_invalid_segment) == (False, 'contact', 2)
    assert answer.time_from_start == 1.5 and answer.colliding_pairs == (('a', 'b'),
                                                                        ('c/d', 'e'))
    assert (answer.points, answer.joints, answer.digest) == (3, 7, 'ab' * 32)
    valid = trajectory_answer_from(DiagnosticArray(status=[status(
        'n: trajectory', valid='true', kind='valid', first_invalid_segment='',
        time_from_start='', colliding_pairs='', reason='')]))
    assert valid.valid and valid.first_invalid_segment is None and valid.colliding_pairs == ()
    with pytest.raises(ValueError, match='not an answer to a trajectory'):
        trajectory_answer_from(DiagnosticArray(status=[status('n: scene')]))


def test_handled_totals():
    values = dict(zip(SCENE_COUNTS, ('3', '1', '0')))
    assert handled_total(values, SCENE_COUNTS) == 4
    assert handled_total({}, SCENE_COUNTS) is None
