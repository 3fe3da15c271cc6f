"""Sampling: configurations within the limits, and the pairs near wherever the robot goes,
against python-fcl distances on the same configurations (pinocchio's poses)."""
import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.engine.sampling import (
    CONTACT_SAMPLES, NEAR_FRACTION, pairs_in_contact_by_design, pairs_near_everywhere,
    sampling_bounds, uniform_configurations)
from engine_oracles import FclOracle


@pytest.fixture(scope='module')
def ur5(ur5_urdf, ur5_srdf, erd_package_paths):
    return CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf, package_paths=erd_package_paths)


def test_configurations_lie_within_the_limits(ur5):
    lower, upper = sampling_bounds(ur5)
    Q = uniform_configurations(lower, upper, 500, np.random.default_rng(1))
    assert Q.shape == (500, len(ur5.joint_names))
    assert (Q >= lower).all() and (Q <= upper).all()
    assert np.isfinite(lower).all() and np.isfinite(upper).all()   # continuous: [-pi, pi]


@pytest.mark.parametrize('distance, samples', [(0.05, 60), (0.12, 40)])
def test_pairs_near_everywhere_match_fcl_on_the_same_configurations(ur5, ur5_urdf, distance,
                                                                    samples):
    found = pairs_near_everywhere(ur5, distance, samples=samples, seed=3)
    oracle = FclOracle(ur5, ur5_urdf)
    lower, upper = sampling_bounds(ur5)
    Q = np.vstack([ur5.kinematics.neutral()[None, :], uniform_configurations(
        lower, upper, samples, np.random.default_rng(3))])
    near, largest = {}, {}
    for q in Q:
        poses = oracle.poses(q)
        for a, b in ur5.checked_pairs:
            d = max(oracle.pair_distance(poses, a, b), 0.0)
            if d < distance:
                near[a, b] = near.get((a, b), 0) + 1
                largest[a, b] = max(largest.get((a, b), -1.0), d)
    expected = {pair for pair, count in near.items() if count >= NEAR_FRACTION * len(Q)}
    assert {(p.link_a, p.link_b) for p in found} == expected
    assert expected     # the UR5 has such pairs at both distances (issue 28: ee_link, wrist_2)
    for pair in found:
        assert pair.samples == len(Q) and pair.near == near[pair.link_a, pair.link_b]
        assert pair.largest == pytest.approx(largest[pair.link_a, pair.link_b], abs=1e-6)


def test_the_ur5_wrist_pair_is_near_everywhere_and_the_checker_is_reset(ur5):
    found = pairs_near_everywhere(ur5, 0.05)
    assert [(p.link_a, p.link_b) for p in found] == [('ee_link', 'wrist_2_link')]
    assert found[0].largest == pytest.approx(0.0198, abs=1e-4)
    assert ur5.positions == dict(zip(ur5.joint_names, ur5.kinematics.neutral()))
    assert pairs_near_everywhere(ur5, 0.019) == []     # below the pair's distance


def tiago(srdf=None):
    from collision_sensor.model.example_robots import example_robot_files
    robot = next(r for r in example_robot_files() if r.name == 'tiago_description/tiago')
    return robot, CollisionChecker.from_urdf(robot.urdf, srdf=srdf,
                                             package_paths=robot.package_paths)


def test_tiago_without_its_srdf_has_51_pairs_in_contact_at_zero_as_fcl_says():
    robot, checker = tiago()
    before = checker.positions
    found = pairs_in_contact_by_design(checker, samples=30, seed=2)
    assert checker.positions == before      # only check_batch: the carried state stays
    oracle = FclOracle(checker, robot.urdf)
    zero = oracle.poses(checker.kinematics.neutral())
    robot_pairs = [(a, b) for a, b in checker.checked_pairs]
    at_zero = set(oracle.colliding_among(robot_pairs, zero))   # a solid holding a mesh too
    assert set(found.at_zero) == at_zero and len(at_zero) == 51
    assert found.at_home == ()          # TIAGo's zero lies within its limits
    # "mostly": in contact in at least 95 % of the 30 configurations, by fcl.
    lower, upper = sampling_bounds(checker)
    Q = uniform_configurations(lower, upper, 30, np.random.default_rng(2))
    counts = {pair: 0 for pair in robot_pairs}
    for q in Q:
        for pair in oracle.colliding_among(sorted(at_zero | set(found.mostly)),
                                           oracle.poses(q)):
            counts[pair] += 1
    assert set(found.mostly) == {p for p, n in counts.items() if n >= NEAR_FRACTION * 30}
    assert set(found.mostly) <= at_zero and len(found.mostly) >= 40


def test_the_panda_with_its_srdf_has_none(panda_urdf, panda_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    found = pairs_in_contact_by_design(checker)
    assert found.pairs == [] and found.samples == CONTACT_SAMPLES
    # The Panda's zero is outside panda_joint4's limits: home is checked too.
    assert not np.array_equal(np.clip(checker.kinematics.neutral(), *sampling_bounds(checker)),
                              checker.kinematics.neutral())
