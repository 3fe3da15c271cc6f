"""collision_sensor.testing: the sensor in a test's process, each answer matched to its input.

Every answer is compared with a fresh ``CollisionChecker`` on the same robot and scene (the
oracle), and inputs are sent ahead and their answers read back in reverse order, so an answer
taken as "the next message" would be caught. The ``collision_sensor`` fixture is the
package's own (its pytest11 entry point).
"""
import math
import pathlib
import time

import numpy as np
import pytest
import yaml

pytest.importorskip('rclpy')

from collision_sensor import CollisionChecker, ConfigError  # noqa: E402
from collision_sensor.model.example_robots import example_robot  # noqa: E402
from collision_sensor.ros.scene_messages import delete_markers  # noqa: E402
from collision_sensor.ros.trajectory_source import points_of  # noqa: E402
from collision_sensor.testing import (  # noqa: E402
    NoAnswer, PendingVerdict, joint_trajectory, own_domain, robot_files, running_sensor)

ARM = [f'panda_joint{i}' for i in range(1, 8)]
READY = dict(zip(ARM, [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]), panda_finger_joint1=0.02)
TABLE = {'objects': [{'name': 'table', 'box': {'size': [0.6, 1.0, 0.04]},
                      'pose': {'xyz': [0.55, 0.0, 0.3]}}]}
TOLERANCE = 0.01    # the node's default joint_limit_tolerance
TOOL_MESH = pathlib.Path(__file__).parents[2] / 'meshes' / 'demo_cell' / 'arm_tool_link.stl'


def oracle(scene=None, **config):
    robot = example_robot('panda')
    return CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                      package_paths=robot.package_paths, scene=scene,
                                      config=config or None)


def now_and_on_the_way(verdict):
    """Every pair the verdict names (in contact now, or met on the way from the state
    before): the oracle's pairs at a state reached without moving."""
    return set(verdict.pairs) | set(verdict.met)


@pytest.fixture(scope='module')
def panda():
    return oracle()


def test_joint_states_sent_ahead_get_each_its_own_verdict(collision_sensor, panda):
    """40 random states (some through the table) published at once, their verdicts read
    last first."""
    sensor = collision_sensor('panda', scene=TABLE, parameters={
        'overload_policy': 'every', 'joint_states_qos': 'reliable', 'check_motion': False})
    names = list(sensor.joint_names)
    rng = np.random.default_rng(7)
    lower = np.array([panda.joint_limits[n][0] for n in names])
    upper = np.array([panda.joint_limits[n][1] for n in names])
    states = [dict(zip(names, rng.uniform(lower, upper))) for _ in range(40)]
    pending = [sensor.publish_joint_state(q) for q in states]
    answers = {k: pending[k].result() for k in reversed(range(len(states)))}
    reference = oracle(TABLE)
    expected = [reference.check(q) for q in states]
    assert 8 <= sum(result.in_collision for result in expected) <= 32, 're-seed'
    for k, result in enumerate(expected):
        assert answers[k].contact == result.in_collision, k
        assert set(answers[k].pairs) == set(result.colliding_pairs), k
        assert answers[k].failure == ''
    # A state the node refuses is answered all the same, by its failure entry.
    refused = sensor.send_joint_state(dict(READY, panda_joint1=math.nan))
    assert (refused.failure, refused.contact) == ('joint_state_rejected', True)
    assert 'panda_joint1' in refused.reason


def test_trajectories_in_flight_are_matched_by_digest(collision_sensor):
    sensor = collision_sensor('panda', scene=TABLE, parameters={'stale_timeout': 0.0})
    sensor.send_joint_state(READY)
    through = [(2.0, [0.0, 0.6, 0.0, -1.4, 0.0, 1.9, 0.785])]
    above = [(2.0, [0.8, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])]
    beyond = [(1.0, [0.0, -0.785, 0.0, 0.3, 0.0, 1.571, 0.785])]   # joint4 above its limit
    sent = [through, above, beyond, through]
    pending = [sensor.publish_trajectory(points, ARM) for points in sent]
    outcomes = [pending[k].outcome() for k in reversed(range(len(sent)))][::-1]
    reference = oracle(TABLE)
    for points, outcome in zip(sent, outcomes):
        msg = joint_trajectory(points, ARM)
        result = reference.check_trajectory(ARM, points_of(msg), start=READY,
                                            limit_tolerance=TOLERANCE)
        assert outcome.valid == result.valid and outcome.relayed == result.valid
        assert outcome.first_invalid_segment == result.first_invalid_segment
        if result.time_from_start is not None:
            assert outcome.time_from_start == pytest.approx(result.time_from_start, rel=1e-8)
        assert set(outcome.colliding_pairs) == set(result.colliding_pairs)
    assert [o.kind for o in outcomes] == ['contact', 'valid', 'joint_limits', 'contact']
    assert outcomes[0].digest == outcomes[3].digest == pending[0].digest


def test_scene_arrays_are_answered_applied_or_rejected_with_the_verdict(collision_sensor,
                                                                        tmp_path):
    sensor = collision_sensor('panda', parameters={'stale_timeout': 0.0})
    assert sensor.send_scene(TABLE).verdict is None      # no state checked yet
    sensor.send_joint_state(READY)
    reference = oracle()
    reference.check(READY)
    at = reference.link_poses()['panda_hand'][:3, 3]
    ball = {'objects': [{'name': 'ball', 'sphere': {'radius': 0.05},
                         'pose': {'xyz': [float(v) for v in at]}}]}
    answer = sensor.send_scene(ball)
    assert answer.applied and answer.reason == '' and set(answer.objects) == {'table', 'ball'}
    expected = oracle({'objects': TABLE['objects'] + ball['objects']}).check(READY)
    assert expected.in_collision and answer.verdict.contact
    assert now_and_on_the_way(answer.verdict) == set(expected.colliding_pairs)
    # A mesh from a file goes as its triangles, and checks as the scene file's object does.
    mesh = tmp_path / 'tool.yaml'
    tool = {'objects': [{'name': 'tool', 'mesh': {'filename': str(TOOL_MESH)},
                         'pose': {'xyz': [float(v) for v in at]}}]}
    mesh.write_text(yaml.safe_dump(tool))
    answer = sensor.send_scene(str(mesh))
    expected = oracle({'objects': TABLE['objects'] + ball['objects'] + tool['objects']}
                      ).check(READY)
    assert answer.applied and now_and_on_the_way(answer.verdict) == set(
        expected.colliding_pairs)
    assert any('tool' in pair for pair in expected.colliding_pairs)
    # Rejected: the scene as it was, the reason naming the culprit.
    answer = sensor.send_scene(ball, frame='no_such_link')
    assert not answer.applied and 'no_such_link' in answer.reason
    assert set(answer.objects) == {'table', 'ball', 'tool'}
    answer = sensor.send_scene(markers=delete_markers(['ball', 'tool']))
    assert answer.applied and answer.objects == ('table',)
    assert not answer.verdict.contact and now_and_on_the_way(answer.verdict) == set()


def cloud_near_hand(offset, rng):
    """3000 points in a 6 cm cube ``offset`` beyond the hand along its z axis, at READY."""
    reference = oracle()
    reference.check(READY)
    T = reference.link_poses()['panda_hand']
    return T[:3, 3] + offset * T[:3, 2] + rng.uniform(-0.03, 0.03, (3000, 3))


def test_clouds_are_answered_taken_or_refused(collision_sensor):
    sensor = collision_sensor('panda', parameters={'point_cloud_topics': ['camera/points'],
                                                   'point_cloud_timeout': 0.0,
                                                   'stale_timeout': 0.0})
    sensor.send_joint_state(READY)
    reference = oracle()
    rng = np.random.default_rng(29)
    seen = set()
    for offset in (0.12, 0.5, 0.09, 1.5):
        points = cloud_near_hand(offset, rng)
        answer = sensor.send_cloud(points)
        reference.set_points('camera/points', points, None, positions=READY)
        expected = reference.check(READY)
        assert answer.accepted and answer.verdict.contact == expected.in_collision, offset
        assert now_and_on_the_way(answer.verdict) == set(expected.colliding_pairs), offset
        seen.update(expected.colliding_pairs)
    assert any('cloud/camera/points' in pair for pair in seen)
    refused = sensor.send_cloud(points, frame='no_such_frame')
    assert not refused.accepted and 'no_such_frame' in refused.reason
    with pytest.raises(ConfigError, match='point_cloud_topics'):
        sensor.send_cloud(points, topic='other/points')


def test_a_cloud_after_its_camera_timed_out_gets_its_own_verdict(collision_sensor):
    """The timeout's entry, published by the node's timer, is no answer to the next cloud."""
    sensor = collision_sensor('panda', parameters={'point_cloud_topics': ['camera/points'],
                                                   'point_cloud_timeout': 0.3,
                                                   'stale_timeout': 0.0})
    sensor.send_joint_state(READY)
    time.sleep(0.6)
    assert sensor.send_joint_state(READY).failure == 'point_cloud_timeout'
    answer = sensor.send_cloud(cloud_near_hand(1.5, np.random.default_rng(1)))
    assert answer.accepted and answer.verdict.failure == '' and not answer.verdict.contact


def ball_near_the_hand():
    """A ball 1 to 5 cm from the Panda at READY: clear, and in contact with 5 cm padding."""
    reference = oracle()
    reference.check(READY)
    T = reference.link_poses()['panda_hand']
    for offset in np.linspace(0.1, 0.3, 41):
        ball = {'objects': [{'name': 'ball', 'sphere': {'radius': 0.03}, 'pose': {
            'xyz': [float(v) for v in T[:3, 3] + offset * T[:3, 2]]}}]}
        if not oracle(ball).check(READY).in_collision and \
                oracle(ball, padding=0.05).check(READY).in_collision:
            return ball
    raise AssertionError('no offset puts the ball within 5 cm and clear')


def test_parameter_changes_are_answered_by_their_verdict(collision_sensor):
    ball = ball_near_the_hand()
    sensor = collision_sensor('panda', scene=ball, parameters={'stale_timeout': 0.0})
    assert sensor.set_parameters(warning_distance=0.01) is None     # no state checked yet
    assert not sensor.send_joint_state(READY).contact
    verdict = sensor.set_parameters(padding=0.05)   # the checker is rebuilt: answered after
    padded = oracle(ball, padding=0.05).check(READY)
    assert verdict.contact and verdict.frame == 'panda_link0'
    assert now_and_on_the_way(verdict) == set(padded.colliding_pairs)
    assert sensor.get_parameter('padding') == 0.05
    with pytest.raises(ConfigError, match='padding'):
        sensor.set_parameters(padding=-1.0)


def test_two_sensors_side_by_side_answer_only_their_own_client(collision_sensor):
    first = collision_sensor('panda', scene=TABLE)
    second = collision_sensor('panda')
    assert first.namespace != second.namespace
    assert first.context.get_domain_id() == second.context.get_domain_id() == own_domain()
    touching = dict(READY, panda_joint2=0.6, panda_joint4=-1.4, panda_joint6=1.9)
    a = first.publish_joint_state(touching)
    b = second.publish_joint_state(touching)
    assert a.result().contact and not b.result().contact    # only the first has the table
    with pytest.raises(NoAnswer, match='no verdict'):
        PendingVerdict(first, (1, 2, 'never sent')).result(timeout=0.3)


def test_running_sensor_starts_and_stops_without_pytest_fixtures():
    with running_sensor('panda', parameters={'check_motion': False}) as sensor:
        assert sensor.context.ok() and sensor.node.checker is not None
        assert sensor.send_joint_state(READY).failure == ''
    assert not sensor.context.ok() and sensor.node is None


def test_robots_by_name_or_path():
    urdf, srdf, paths = robot_files('tiago')
    assert urdf.endswith('tiago.urdf') and srdf == '' and paths[0].startswith(
        'example-robot-data=')
    panda = example_robot('panda')
    assert robot_files('panda')[1] == panda.srdf and robot_files('panda', srdf=False)[1] == ''
    assert robot_files(panda.urdf, package_paths={'a': '/b'}) == (panda.urdf, '', ['a=/b'])
    with pytest.raises(ConfigError, match='neither a URDF file nor one example'):
        robot_files('no_such_robot')


def test_a_bad_parameter_fails_the_start_with_the_nodes_reason(collision_sensor):
    with pytest.raises(ConfigError, match='stale_timeout'):
        collision_sensor('panda', parameters={'stale_timeout': -1.0})
    assert math.isfinite(own_domain())
