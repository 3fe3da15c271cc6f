"""Every robot of example-robot-data (69 URDFs, with their SRDFs) loads, and agrees with
python-fcl pair for pair on the same triangles on a few random configurations within limits.

Link poses for fcl come from pinocchio (independent kinematics). Each robot gets the zero
configuration and ``N_CONFIGURATIONS`` seeded random ones. Robots whose load and checks take
more than a few seconds are marked ``slow`` (``pytest -m "not slow"`` skips them).
"""
import os
import warnings

import pytest

from collision_sensor import CollisionChecker, LoadWarning, RobotDescriptionError
from collision_sensor.engine.sampling import random_configurations
from collision_sensor.model.example_robots import example_robot_files

N_CONFIGURATIONS = 4

#: URDFs that are not robots: rejected on purpose, with the reason the loader must give.
REJECTED = {
    'ur_description/ur3': 'no <link> element',   # an empty <robot/> left by xacro
}

#: A line loading must tolerate with a warning (the cases issue 13 names), by robot.
EXPECTED_WARNINGS = {
    'alex_description/alex_psyonic_hands':
        'URDF: joint "Left_index_q2" mimics joint "index_q1", which does not exist',
    'z1_description/z1': 'SRDF: line 11: <chain> skipped: base_link="base" is not a link',
    'romeo_description/romeo': 'SRDF: line 95: <joint name="LToePitch"> skipped',
    'talos_data/talos_full_v2': 'URDF: mesh "package:///example-robot-data/',
}

#: Robots that take long to load or check (over 10 s here: 300k+ triangles); name -> why.
SLOW = {
    'g1_description/g1_29dof_with_hand_rev_1_0': '368,200 triangles',
    'so_arm_description/so101': '398,884 triangles',
}

try:
    ROBOTS = example_robot_files()
except Exception:  # example-robot-data missing: the test below is skipped
    ROBOTS = []


def _params():
    for robot in ROBOTS:
        marks = []
        if robot.name in SLOW:
            marks.append(pytest.mark.slow)
        yield pytest.param(robot, id=robot.name, marks=marks)


def test_every_urdf_is_found():
    assert len(ROBOTS) == 69 and sum(robot.srdf is not None for robot in ROBOTS) == 43


@pytest.mark.slow
@pytest.mark.parametrize('robot', list(_params()))
def test_robot_loads_and_agrees_with_fcl(robot):
    from engine_oracles import FclOracle
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', LoadWarning)   # tolerated oddities, tested elsewhere
        if robot.name in REJECTED:
            with pytest.raises(RobotDescriptionError, match=REJECTED[robot.name]):
                CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                           package_paths=robot.package_paths)
            return
        checker = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                             package_paths=robot.package_paths)
    assert all(line.startswith(('URDF: ', 'SRDF: ')) for line in checker.load_warnings)
    if robot.name in EXPECTED_WARNINGS:
        assert any(line.startswith(EXPECTED_WARNINGS[robot.name])
                   for line in checker.load_warnings), checker.load_warnings
    # Multi-DOF group states (a floating root_joint given 7 numbers) are read, not skipped.
    assert not [line for line in checker.load_warnings if 'numbers, joint' in line]
    if not checker.checked_pairs:
        return   # nothing to compare (no geometry, or every pair excluded)
    oracle = FclOracle(checker, robot.urdf)
    configurations = [checker.kinematics.neutral()] + list(
        random_configurations(checker, N_CONFIGURATIONS, seed=sum(map(ord, robot.name))))
    mismatches = []
    for q in configurations:
        ours = checker.check(q).colliding_pairs
        theirs = oracle.colliding_pairs(q)
        if ours != theirs:
            mismatches.append((list(q), sorted(set(ours) ^ set(theirs))))
    # Failures as literals that can be pasted into a regression test.
    assert not mismatches, (f'{robot.name}: {len(mismatches)} of {len(configurations)} '
                            f'configurations differ (q, pairs differing): {mismatches[:2]}')
