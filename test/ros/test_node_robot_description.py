"""The robot from the ``robot_description`` topic: a good description loads, a bad one is
refused, a hostile one is never read as a path; floating bases; load warnings in the log.
"""
import os
import time

import numpy as np
import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.ros.node import LATCHED_QOS, CollisionSensorNode  # noqa: E402
from node_harness import (  # noqa: E402,F401 - the fixtures of the node's tests
    Probe, SLIDER_URDF, expected, frames, joint_state, logged, pairs_of, panda, poses, ros,
    start_node)
from ros_helpers import WAIT, reliable  # noqa: E402


def test_robot_from_topic_and_bad_description_rejected(ros, panda_urdf, erd_share, poses,
                                                       capfd):
    # No SRDF here: it would name Panda links that the second robot does not have. Instants
    # (check_motion off): the poses jump.
    start_node(ros, [Parameter('package_paths', value=[f'example-robot-data={erd_share}']),
                     Parameter('joint_states_qos', value='reliable'),
                     Parameter('check_motion', value=False)])
    description = ros.publisher(String, 'robot_description', LATCHED_QOS)
    with open(panda_urdf) as stream:
        urdf_text = stream.read()
    description.publish(String(data=urdf_text))
    # The node subscribes joint_states only once it has a robot.
    probe = Probe(ros, timeout=60.0)
    # The reference: the same text, no SRDF.
    bare = CollisionChecker.from_urdf(urdf_text, package_paths={'example-robot-data': erd_share})

    def reference(state):
        result = bare.check(state)
        return result.in_collision, tuple(result.colliding_pairs)

    def verdict_for(state, timeout=WAIT):
        count = len(probe.pairs)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:    # the node ignores joint states until loaded
            probe.joint_states.publish(joint_state(state))
            if ros.spin_until(lambda: len(probe.pairs) > count, 0.2):
                return probe.contact.last.data, pairs_of(probe.pairs.last)
        raise AssertionError('no verdict')

    panda_free = verdict_for(poses['free'])
    panda_hit = verdict_for(poses['hit'])
    assert panda_free == reference(poses['free']) and panda_hit == reference(poses['hit'])
    assert panda_hit[0] and set(poses['hit_pairs']) <= set(panda_hit[1])

    description.publish(String(data='<robot name="broken"><link name="a"></robot>'))
    seen = []
    assert ros.spin_until(lambda: seen.append(capfd.readouterr().err) or
                          'robot_description rejected' in ''.join(seen), 30.0)
    assert 'the current model stays' in ''.join(seen)
    assert verdict_for(poses['hit']) == panda_hit and verdict_for(poses['free']) == panda_free

    description.publish(String(data=SLIDER_URDF))
    # Until the slider has loaded, its joint is an unknown name to the Panda, whose verdict
    # answers it (the state held); wait for the slider.
    loaded = 'robot loaded from robot_description: 1 joints'
    assert loaded in logged(ros, capfd, loaded, 60.0)
    assert verdict_for({'slide': -0.95}) == (True, (('anchor', 'carriage'),))
    assert verdict_for({'slide': 0.0}) == (False, ())
    # The Panda's joints are now unknown names, ignored: answered by the state held.
    assert probe.send(joint_state(poses['free'])) == (False, ())


def test_robot_description_is_content_never_a_path(ros, tmp_path, panda_urdf, erd_share, capfd):
    def factory(urdf, **kwargs):
        opened.append(urdf)
        return CollisionChecker.from_urdf(urdf, **kwargs)

    opened = []
    fifo = tmp_path / 'fifo'
    os.mkfifo(fifo)      # reading it would block the loader for ever
    ros.add(CollisionSensorNode(
        namespace=ros.namespace, context=ros.context, checker_factory=factory,
        parameter_overrides=[Parameter('package_paths',
                                       value=[f'example-robot-data={erd_share}'])]))
    description = ros.publisher(String, 'robot_description', LATCHED_QOS)
    diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
    texts = ('/etc/passwd', '/dev/zero', str(fifo), panda_urdf, 'x\n[ERROR] forged')
    for count, text in enumerate(texts, 1):
        description.publish(String(data=text))

        def rejected():
            for msg in diagnostics.messages:
                for status in msg.status:
                    values = {kv.key: kv.value for kv in status.values}
                    if values.get('robot_description_rejected_total') == str(count):
                        return True
            return False
        assert ros.spin_until(rejected, 5.0), text
    err = logged(ros, capfd, '')
    # Throttled: the first rejection is logged, the others counted.
    assert 'robot_description rejected: robot_description: not URDF XML text (it starts with ' \
           '"/etc/passwd")' in err and 'give a path with the urdf_path parameter' in err
    assert opened == []     # nothing reached the loader, let alone a file
    description.publish(String(data=SLIDER_URDF))
    assert 'ready: checking' in logged(ros, capfd, 'ready: checking', timeout=60.0)
    assert opened == [SLIDER_URDF.encode()]    # as bytes: parsed as the document, never a path


def test_floating_base_robot_from_the_topic_needs_no_base_variables(ros, erd_share, capfd):
    """a1 (example-robot-data): URDF from robot_description, its SRDF's floating virtual joint
    "root_joint". The node does not wait for root_joint/* (robots rarely publish them in
    joint_states): the base sits at the world origin until a joint state names them, and the
    verdict is the reference checker's for that state."""
    robots = os.path.join(erd_share, 'robots', 'a1_description')
    urdf, srdf = os.path.join(robots, 'urdf', 'a1.urdf'), os.path.join(robots, 'srdf', 'a1.srdf')
    start_node(ros, [Parameter('package_paths', value=[f'example-robot-data={erd_share}']),
                     Parameter('srdf_path', value=srdf),
                     Parameter('joint_states_qos', value='reliable'),
                     Parameter('check_motion', value=False)])    # instants: the poses jump
    description = ros.publisher(String, 'robot_description', LATCHED_QOS)
    with open(urdf) as stream:
        description.publish(String(data=stream.read()))
    reference = CollisionChecker.from_urdf(urdf, srdf=srdf,
                                           package_paths={'example-robot-data': erd_share})
    assert reference.joint_names[:7] == tuple(f'root_joint/{v}' for v in (
        'trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w'))
    probe = Probe(ros, timeout=60.0)
    legs = reference.joint_names[7:]
    rng = np.random.default_rng(9)
    base = dict(zip(reference.joint_names, reference.kinematics.neutral()))
    for _ in range(5):
        state = {name: float(rng.uniform(*reference.joint_limits[name])) for name in legs}
        count = len(probe.pairs)
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and len(probe.pairs) == count:
            probe.joint_states.publish(joint_state(state))   # until the model has loaded
            ros.spin_until(lambda: len(probe.pairs) > count, 0.3)
        expected = reference.check(dict(base, **state))
        assert (probe.contact.last.data, pairs_of(probe.pairs.last)) == (
            expected.in_collision, tuple(expected.colliding_pairs))
    # The base named in a joint state moves the robot: lifted 10 m, nothing changes inside.
    lifted = dict(state, **{'root_joint/trans_z': 10.0})
    assert probe.send(joint_state(lifted)) == (
        reference.check(dict(base, **lifted)).in_collision,
        tuple(reference.check(dict(base, **lifted)).colliding_pairs))


def test_load_warnings_reach_the_node_log(ros, erd_share, capfd):
    """z1's SRDF names a link "base" that this URDF lacks: loaded with the entry skipped, and
    the warning (file, line, element, fix) is logged by the node, not lost on stderr alone."""
    robots = os.path.join(erd_share, 'robots', 'z1_description')
    start_node(ros, [Parameter('urdf_path', value=os.path.join(robots, 'urdf', 'z1.urdf')),
                     Parameter('srdf_path', value=os.path.join(robots, 'srdf', 'z1.srdf')),
                     Parameter('package_paths', value=[f'example-robot-data={erd_share}'])])
    seen = []
    assert ros.spin_until(lambda: seen.append(capfd.readouterr().err) or
                          'while loading the robot' in ''.join(seen), 30.0), ''.join(seen)
    text = ''.join(seen)
    assert 'WARN' in text and 'base' in text and 'skipped' in text
