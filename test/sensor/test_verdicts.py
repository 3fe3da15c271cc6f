"""The sensor's verdicts, without ROS, against a fresh checker: every pair in contact at a state
reported as in contact now, whatever made it (a joint state, a scene edit, an attached object, a
cloud), with and without ``check_motion``; only pairs met on the way and not in contact now carry
``first_contact``; every verdict the one a from-scratch check gives."""
import math
import random

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.engine.dynamic_scene import AddObject, MoveObject, RemoveObject
from collision_sensor.engine.motion import interpolate
from collision_sensor.model.mesh_loading import box_mesh, sphere_mesh
from collision_sensor.model.scene import SceneObject
from collision_sensor.sensor import Sensor
from small_robot import SMALL_ROBOT, SMALL_SCENE


def small_checker(scene=SMALL_SCENE):
    return CollisionChecker.from_urdf(SMALL_ROBOT, scene=scene)


def pose(xyz):
    T = np.eye(4)
    T[:3, 3] = xyz
    return T


def ball(name, radius, xyz):
    vertices, faces = sphere_mesh(radius)
    return SceneObject(name, 'test', pose(xyz), vertices, faces)


def assert_labels(verdict, oracle, q, q_before, motion: bool):
    """The verdict's pairs are the state's own (the oracle's full check: a checker of its own
    given every change the sensor's was), and the pairs met on the way are the motion's
    (check_motion from the state before) that are not in contact now."""
    now = oracle.check(q).colliding_pairs
    assert verdict.failure is None
    assert verdict.colliding_pairs == now
    assert all(a < b for a, b in now)
    if not motion or q_before is None:
        assert verdict.met_on_the_way == () and verdict.first_contact is None
        assert verdict.contact == bool(now)
        return
    on_the_way = oracle.check_motion(q_before, q)
    met = tuple(pair for pair in on_the_way.colliding_pairs if pair not in now)
    assert set(verdict.met_on_the_way) <= set(on_the_way.colliding_pairs)
    assert not set(verdict.met_on_the_way) & set(now)
    if verdict.met_on_the_way:
        assert verdict.first_contact is not None and 0.0 <= verdict.first_contact <= 1.0
    else:
        assert verdict.first_contact is None
    assert verdict.contact == (bool(now) or on_the_way.in_collision or bool(met))


@pytest.mark.parametrize('motion', [True, False])
def test_every_pair_kind_and_trigger_labelled_as_a_fresh_check_says(motion):
    """A seeded random run of every trigger (joint states, world objects added, moved and
    removed, objects attached to links and carried, clouds set and cleared), each on every pair
    kind (link-link, link-object, link-attached, link-cloud): 0 mislabelled pairs."""
    rng = random.Random(11 if motion else 12)
    checker, oracle = small_checker(), small_checker()
    sensor = Sensor(checker, {'check_motion': motion, 'stale_timeout': 0.0})
    names = checker.joint_names
    lower = np.array([max(checker.joint_limits[n][0], -3.0) for n in names])
    upper = np.array([min(checker.joint_limits[n][1], 3.0) for n in names])
    q = (lower + upper) / 2
    verdict = sensor.step(names, q)
    assert_labels(verdict, oracle, q, None, motion)
    q_before = q
    kinds_seen = set()
    objects = []
    for step in range(400):
        trigger = rng.random()
        if trigger < 0.45:                      # a joint state: a step or a jump
            scale = 0.05 if rng.random() < 0.8 else 1.0
            q = np.clip(q + rng.gauss(0, 1) * scale * (upper - lower) *
                        np.array([rng.random() for _ in names]), lower, upper)
            verdict = sensor.step(names, q)
            assert_labels(verdict, oracle, q, q_before, motion)
            q_before = q
        else:
            with sensor.editing():
                if trigger < 0.65 or not objects:   # a world object at a link, or away
                    name = f'ball{step}'
                    poses = checker.link_poses()
                    link = rng.choice(list(checker.link_names))
                    at = poses[link][:3, 3] + np.array([rng.uniform(-0.15, 0.15)
                                                        for _ in range(3)])
                    changes = [AddObject(ball(name, rng.uniform(0.02, 0.1), at))]
                    objects.append(name)
                elif trigger < 0.75:                # an object attached to a link
                    name = f'held{step}'
                    link = rng.choice(['tool', 'lower', 'upper'])
                    vertices, faces = box_mesh([0.05, 0.05, rng.uniform(0.1, 0.5)])
                    held = SceneObject(name, 'test', pose([0, 0, 0.1]), vertices, faces)
                    changes = [AddObject(held, attach_to=link)]
                    objects.append(name)
                elif trigger < 0.85:                # a move or a removal
                    name = rng.choice(objects)
                    placed_on = checker.attachments.get(name)
                    if rng.random() < 0.5 or placed_on is not None:
                        changes = [RemoveObject(name)]
                        objects.remove(name)
                    else:
                        changes = [MoveObject(name, pose([rng.uniform(-0.5, 0.5)
                                                          for _ in range(3)]))]
                else:                               # a cloud at the robot, or its removal
                    if rng.random() < 0.7:
                        poses = checker.link_poses()
                        link = rng.choice(list(checker.link_names))
                        centre = poses[link][:3, 3]
                        points = centre + np.random.default_rng(step).normal(0, 0.08, (300, 3))
                        prepared = checker.prepare_points('camera', points, positions=q)
                        verdict = sensor.commit_points(prepared)
                        oracle.set_points('camera', points, positions=q)
                    else:
                        verdict = sensor.clear_points('camera')
                        oracle.clear_points('camera')
                    changes = None
                if changes is not None:
                    prepared = checker.prepare_scene_changes(changes)
                    verdict = sensor.apply_scene_changes(prepared)
                    oracle.apply_scene_changes(changes)
            # A scene change is answered at the state where the robot stands: in contact now,
            # never "met on the way" (the robot did not move).
            assert_labels(verdict, oracle, q, q, motion)
        for a, b in verdict.colliding_pairs:
            kinds_seen.add('cloud' if b.startswith('cloud/') or a.startswith('cloud/') else
                           'attached' if a.startswith('held') or b.startswith('held') else
                           'object' if a in SMALL_NAMES or b in SMALL_NAMES or 'ball' in a + b
                           else 'link')
    assert kinds_seen == {'cloud', 'attached', 'object', 'link'}


SMALL_NAMES = {obj['name'] for obj in SMALL_SCENE['objects']}


def test_an_object_added_at_the_tool_of_a_standing_robot_is_in_contact_now():
    """The case a user met: a scene object added at the tool while the robot stands still,
    with check_motion on, is "collides with", not "met on the way at 0"; so is every verdict
    after it while the robot stands."""
    checker, oracle = small_checker(scene=None), small_checker(scene=None)
    sensor = Sensor(checker, {'check_motion': True})
    names = checker.joint_names
    q = np.array([0.3, -0.4, 0.0, 0.2])
    assert sensor.step(names, q).colliding_pairs == ()
    oracle.check(q)
    tip = (oracle.link_poses()['tool'] @ [0.0, 0.0, 0.06, 1.0])[:3]   # in the tool, near its end
    changes = [AddObject(ball('ball', 0.02, tip))]
    with sensor.editing():
        verdict = sensor.apply_scene_changes(checker.prepare_scene_changes(changes))
    oracle.apply_scene_changes(changes)
    assert verdict.colliding_pairs == oracle.check(q).colliding_pairs == (('ball', 'tool'),)
    assert verdict.met_on_the_way == () and verdict.first_contact is None
    statuses = [status for topic, data in verdict.messages if topic == 'colliding_pairs'
                for status in decode_pairs(data)]
    assert statuses == [('ball:tool', 'ball collides with tool', ('link_a', 'link_b'))]
    for _ in range(3):
        verdict = sensor.step(names, q)
        assert verdict.colliding_pairs == (('ball', 'tool'),) and verdict.met_on_the_way == ()


def test_a_motion_through_an_object_between_two_clear_states_is_met_on_the_way():
    checker = small_checker(scene=None)
    sensor = Sensor(checker, {'check_motion': True})
    names = checker.joint_names
    q0 = np.array([-1.2, 0.0, 0.0, 0.0])
    q1 = np.array([1.2, 0.0, 0.0, 0.0])
    mid = interpolate(checker.motion_kinds, q0, q1, [0.5])[0]
    sensor.step(names, mid)
    top = checker.link_poses()['upper'][:3, 3] + [0.0, 0.0, 0.45]
    with sensor.editing():
        sensor.apply_scene_changes(checker.prepare_scene_changes(
            [AddObject(ball('ball', 0.02, top + [0.0, 0.3, 0.0]))]))
        sensor.apply_scene_changes(checker.prepare_scene_changes(
            [MoveObject('ball', pose(top))]))
    assert sensor.step(names, q0).colliding_pairs == ()
    verdict = sensor.step(names, q1)
    assert verdict.colliding_pairs == () and verdict.contact
    assert ('ball', 'upper') in verdict.met_on_the_way or ('ball', 'lower') in \
        verdict.met_on_the_way
    assert 0.3 < verdict.first_contact < 0.7
    statuses = [status for topic, data in verdict.messages if topic == 'colliding_pairs'
                for status in decode_pairs(data)]
    assert statuses and all('on the way, at' in message and 'first_contact' in keys
                            for _, message, keys in statuses)


def decode_pairs(data):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message
    message = deserialize_message(data, DiagnosticArray)
    return [(s.name, s.message, tuple(kv.key for kv in s.values)) for s in message.status]


def test_verdicts_along_a_random_walk_equal_a_fresh_checkers(panda_urdf, panda_srdf,
                                                            erd_package_paths):
    """The Panda in clutter, 300 states of a walk with jumps: every verdict's pairs equal a
    separate checker's full check, and the motion's contact equals its check_motion."""
    scene = {'objects': [
        {'name': f'box{k}', 'box': {'size': [0.2, 0.2, 0.2]},
         'pose': {'xyz': [0.45 * math.cos(k), 0.45 * math.sin(k), 0.2 + 0.15 * k]}}
        for k in range(5)]}

    def make():
        return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                          package_paths=erd_package_paths, scene=scene)
    checker, oracle = make(), make()
    sensor = Sensor(checker, {'check_motion': True, 'stale_timeout': 0.0,
                              'joint_limit_policy': 'clamp'})
    names = checker.joint_names
    lower = np.array([checker.joint_limits[n][0] for n in names])
    upper = np.array([checker.joint_limits[n][1] for n in names])
    rng = np.random.default_rng(5)
    q = (lower + upper) / 2
    previous = None
    met_seen = now_seen = 0
    for step in range(300):
        if step % 25 == 24:
            q = rng.uniform(lower, upper)
        else:
            q = np.clip(q + rng.normal(0, 0.08, q.shape), lower, upper)
        verdict = sensor.step(names, q)
        now = oracle.check(q).colliding_pairs
        assert verdict.colliding_pairs == now
        if previous is not None:
            motion = oracle.check_motion(previous, q)
            assert verdict.contact == (motion.in_collision or bool(now))
            assert set(verdict.met_on_the_way) == set(motion.colliding_pairs) - set(now) \
                if motion.in_collision else verdict.met_on_the_way == ()
        met_seen += bool(verdict.met_on_the_way)
        now_seen += bool(now)
        previous = q
    assert met_seen and now_seen


def test_the_warning_zone_equals_proximity(panda_urdf, panda_srdf, erd_package_paths):
    scene = {'objects': [{'name': 'wall', 'box': {'size': [0.05, 1.0, 1.0]},
                          'pose': {'xyz': [0.55, 0.0, 0.5]}}]}
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=scene)
    oracle = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                        package_paths=erd_package_paths, scene=scene)
    sensor = Sensor(checker, {'warning_distance': 0.1,
                              'warning_ignore': ['panda_link0:panda_link1']})
    names = checker.joint_names
    rng = np.random.default_rng(3)
    lower = np.array([checker.joint_limits[n][0] for n in names])
    upper = np.array([checker.joint_limits[n][1] for n in names])
    near_seen = 0
    for _ in range(60):
        q = rng.uniform(lower, upper)
        zone = sensor.step(names, q).zone
        records = [r for r in oracle.proximity(q, 0.1)
                   if (r.link_a, r.link_b) != ('panda_link0', 'panda_link1')]
        assert [(p.link_a, p.link_b) for p in zone.pairs] == \
            [(r.link_a, r.link_b) for r in records]
        for p, r in zip(zone.pairs, records):
            assert p.distance == pytest.approx(r.distance, abs=1e-12)
            assert np.allclose(p.point_a, r.point_a) and np.allclose(p.point_b, r.point_b)
        assert zone.near == bool(records)
        assert zone.min_distance == (records[0].distance if records else math.inf)
        near_seen += zone.near
    assert near_seen
