"""Pure tests of joint-state merging and validation (no ROS)."""
import math
import random

import pytest

from collision_sensor.ros.joint_state_merger import (
    JointStateMerger, Problem, Verdict, joints_out_of_limits)

ARM = ('j1', 'j2', 'j3')
GRIPPER = ('finger',)
JOINTS = ARM + GRIPPER


def merger_with(positions=None):
    merger = JointStateMerger(JOINTS, derived_names={'finger_mimic'})
    if positions:
        assert merger.merge(list(positions), list(positions.values())).accepted
    return merger


def test_partial_states_merge_into_one():
    merger = merger_with()
    assert not merger.complete and merger.missing() == list(JOINTS)
    outcome = merger.merge(list(ARM), [0.1, 0.2, 0.3])
    assert outcome.verdict is Verdict.ACCEPTED and outcome.updated == ARM
    assert not merger.complete and merger.missing() == ['finger']
    assert merger.merge(['finger'], [0.04]).accepted
    assert merger.complete and merger.missing() == []
    assert merger.positions == {'j1': 0.1, 'j2': 0.2, 'j3': 0.3, 'finger': 0.04}
    # A later arm message leaves the gripper's value alone, and the other way round.
    merger.merge(['j2'], [-1.0])
    assert merger.positions == {'j1': 0.1, 'j2': -1.0, 'j3': 0.3, 'finger': 0.04}


def test_order_of_names_does_not_matter():
    merger = merger_with()
    merger.merge(['finger', 'j3', 'j1', 'j2'], [4.0, 3.0, 1.0, 2.0])
    assert merger.positions == {'j1': 1.0, 'j2': 2.0, 'j3': 3.0, 'finger': 4.0}


@pytest.mark.parametrize('names, positions, problem, words', [
    (['j1', 'j2'], [0.0], Problem.LENGTH_MISMATCH, ['2 names', '1 positions']),
    (['j1'], [0.0, 1.0], Problem.LENGTH_MISMATCH, ['1 names', '2 positions']),
    (['j1', 'j2', 'j1'], [0.0, 1.0, 2.0], Problem.DUPLICATE_NAMES, ['"j1"']),
    (['unknown', 'unknown'], [0.0, 1.0], Problem.DUPLICATE_NAMES, ['"unknown"']),
    (['j1', 'j2'], [0.0, math.nan], Problem.NOT_FINITE, ['"j2"=nan']),
    (['j1', 'j2'], [math.inf, 0.0], Problem.NOT_FINITE, ['"j1"=inf']),
    (['j1', 'ghost'], [0.0, -math.inf], Problem.NOT_FINITE, ['"ghost"=-inf']),
])
def test_malformed_message_is_rejected_whole(names, positions, problem, words):
    merger = merger_with({'j1': 0.5, 'j2': 0.6, 'j3': 0.7, 'finger': 0.01})
    before = dict(merger.positions)
    outcome = merger.merge(names, positions)
    assert outcome.verdict is Verdict.REJECTED and outcome.problem is problem
    assert not outcome.accepted and outcome.updated == ()
    for word in words:
        assert word in outcome.reason
    assert merger.positions == before
    assert merger.unknown_names == set()


def test_velocity_only_and_empty_messages_change_nothing():
    merger = merger_with({'j1': 0.5})
    for names in (['j1', 'j2'], []):
        outcome = merger.merge(names, [])
        assert outcome.verdict is Verdict.IGNORED and outcome.problem is None
    assert merger.positions == {'j1': 0.5}


def test_unknown_names_are_ignored_and_reported_once():
    merger = merger_with()
    first = merger.merge(['j1', 'ghost', 'other'], [1.0, 2.0, 3.0])
    assert first.accepted and first.updated == ('j1',)
    assert first.unknown == ('ghost', 'other') and first.new_unknown == ('ghost', 'other')
    second = merger.merge(['ghost', 'j2', 'third'], [0.0, 2.0, 0.0])
    assert second.unknown == ('ghost', 'third') and second.new_unknown == ('third',)
    assert merger.positions == {'j1': 1.0, 'j2': 2.0}
    assert merger.unknown_names == {'ghost', 'other', 'third'}
    only_unknown = merger.merge(['ghost'], [5.0])
    assert only_unknown.verdict is Verdict.IGNORED and only_unknown.new_unknown == ()


def test_derived_joints_are_skipped_silently():
    merger = merger_with()
    outcome = merger.merge(['finger', 'finger_mimic'], [0.02, 0.02])
    assert outcome.accepted and outcome.updated == ('finger',)
    assert outcome.unknown == () and merger.unknown_names == set()
    assert merger.merge(['finger_mimic'], [0.03]).verdict is Verdict.IGNORED
    assert merger.positions == {'finger': 0.02}


def test_carry_over_keeps_shared_joints_and_forgets_unknown_names():
    merger = merger_with({'j1': 1.0, 'j2': 2.0, 'j3': 3.0, 'finger': 0.0})
    merger.merge(['ghost'], [0.0])
    new = merger.carry_over(('j1', 'j2', 'k9'), derived_names=('j3',))
    assert new.positions == {'j1': 1.0, 'j2': 2.0}
    assert new.missing() == ['k9'] and new.unknown_names == set()
    assert new.merge(['j3'], [0.0]).verdict is Verdict.IGNORED


def test_rejection_rules_against_a_brute_force_oracle():
    """Seeded random messages: the merger agrees with a literal reading of the rules."""
    rng = random.Random(7)
    pool = list(JOINTS) + ['ghost', 'finger_mimic']
    values = [0.0, 1.5, -2.0, math.nan, math.inf, -math.inf]
    merger = merger_with()
    for _ in range(2000):
        names = [rng.choice(pool) for _ in range(rng.randint(0, 5))]
        positions = [rng.choice(values) if rng.random() < 0.1 else rng.uniform(-3, 3)
                     for _ in range(len(names) + rng.choice([0, 0, 0, 0, -1, 1]))]
        if rng.random() < 0.05:
            positions = []
        before = dict(merger.positions)
        outcome = merger.merge(names, positions)
        if not positions:
            expected = Verdict.IGNORED
        elif (len(names) != len(positions) or len(set(names)) != len(names)
              or not all(math.isfinite(p) for p in positions)):
            expected = Verdict.REJECTED
        elif set(names) & set(JOINTS):
            expected = Verdict.ACCEPTED
        else:
            expected = Verdict.IGNORED
        assert outcome.verdict is expected, (names, positions)
        if expected is Verdict.ACCEPTED:
            given = dict(zip(names, positions))
            before.update({n: v for n, v in given.items() if n in JOINTS})
        assert merger.positions == before


def test_out_of_limits_inclusive_bounds_and_unlimited_joints():
    limits = {'j1': (-1.0, 1.0), 'j2': (0.0, 0.04), 'j3': (-math.inf, math.inf)}
    positions = {'j1': 1.0, 'j2': 0.05, 'j3': 1e9, 'finger': 7.0}
    assert joints_out_of_limits(positions, limits) == [('j2', 0.05, 0.0, 0.04)]
    positions['j1'] = -1.0000001
    assert [entry[0] for entry in joints_out_of_limits(positions, limits)] == ['j1', 'j2']
    assert joints_out_of_limits(positions, limits, names=['j2']) == [('j2', 0.05, 0.0, 0.04)]
    assert joints_out_of_limits(positions, limits, names=['absent']) == []


def test_merger_rejects_initial_positions_of_unknown_joints():
    with pytest.raises(ValueError, match='ghost'):
        JointStateMerger(JOINTS, positions={'ghost': 0.0})


def test_importing_the_merger_does_not_import_rclpy():
    import subprocess
    import sys
    code = ('import sys, collision_sensor.ros.joint_state_merger; '
            'sys.exit(1 if "rclpy" in sys.modules else 0)')
    assert subprocess.run([sys.executable, '-c', code]).returncode == 0


# -- joint limits (rule 5) ------------------------------------------------------------------------

LIMITS = {'j1': (-1.0, 1.0), 'j2': (0.0, 0.5), 'j3': (None, None), 'finger': (0.0, math.inf)}


def limited(policy='reject', tolerance=0.01):
    merger = JointStateMerger(JOINTS, limits=LIMITS, limit_policy=policy,
                              limit_tolerance=tolerance)
    assert merger.merge(list(JOINTS), [0.0, 0.1, 0.0, 0.02]).accepted
    return merger


@pytest.mark.parametrize('value', [1.0101, -1.02, 1e9, 9.2e18, 1.7e308, -1.7e308])
def test_values_beyond_the_limits_are_rejected_whole_by_default(value):
    merger = limited()
    before = dict(merger.positions)
    outcome = merger.merge(['j2', 'j1'], [0.2, value])
    assert outcome.verdict is Verdict.REJECTED and outcome.problem is Problem.OUT_OF_LIMITS
    assert merger.positions == before     # j2 is not taken either
    assert f'joint "j1" at {value:.6g} outside its limits [-1, 1]' in outcome.reason
    assert 'joint_limit_tolerance 0.01' in outcome.reason   # the node's parameter (issue 28)
    assert 'joint_limit_policy' in outcome.reason


@pytest.mark.parametrize('value', [1.0, 1.01, -1.0099, 0.3])
def test_values_within_the_tolerance_are_taken_as_given(value):
    merger = limited()
    assert merger.merge(['j1'], [value]).accepted and merger.positions['j1'] == value


def test_joints_without_limits_take_any_finite_value():
    merger = limited()
    assert merger.merge(['j3', 'finger'], [1e300, 1e300]).accepted
    assert merger.positions['j3'] == 1e300 and merger.positions['finger'] == 1e300
    assert merger.merge(['finger'], [-0.5]).verdict is Verdict.REJECTED   # the lower bound holds


def test_clamp_and_accept_policies():
    merger = limited('clamp')
    outcome = merger.merge(['j1', 'j2'], [9.2e18, -3.0])
    assert outcome.accepted and outcome.clamped == ('j1', 'j2')
    assert merger.positions['j1'] == 1.0 and merger.positions['j2'] == 0.0
    outcome = merger.merge(['j1'], [1.005])     # within the tolerance: as given
    assert outcome.clamped == () and merger.positions['j1'] == 1.005
    merger = limited('accept')
    outcome = merger.merge(['j1'], [1.7e308])
    assert outcome.accepted and merger.positions['j1'] == 1.7e308


def test_limit_settings_are_validated_and_carried_over():
    with pytest.raises(ValueError, match='limit_policy'):
        JointStateMerger(JOINTS, limit_policy='wrap')
    with pytest.raises(ValueError, match='limit_tolerance'):
        JointStateMerger(JOINTS, limit_tolerance=-1.0)
    carried = limited('clamp', 0.2).carry_over(JOINTS, limits={'j1': (0.0, 0.1)})
    assert carried.limit_policy == 'clamp' and carried.limit_tolerance == 0.2
    carried.merge(['j1'], [5.0])
    assert carried.positions['j1'] == 0.1


# -- unknown names: bounded memory ----------------------------------------------------------------

def test_unknown_names_are_remembered_up_to_a_cap_and_counted_beyond():
    merger = JointStateMerger(JOINTS, max_unknown_names=50)
    flood = [f'ghost_{i}' for i in range(10_000)]
    outcome = merger.merge(['j1'] + flood, [0.0] * 10_001)
    assert outcome.accepted and len(outcome.unknown) == 10_000
    assert outcome.new_unknown == tuple(flood[:50]) and outcome.unremembered == 9_950
    assert len(merger.unknown_names) == 50 and merger.unknown_overflow == 9_950
    outcome = merger.merge(flood[:60], [0.0] * 60)    # seen ones are not new, the rest counted
    assert outcome.new_unknown == () and outcome.unremembered == 10
    assert len(merger.unknown_names) == 50 and merger.unknown_overflow == 9_960


def test_reasons_escape_names_that_could_forge_log_lines():
    merger = JointStateMerger(JOINTS)
    forged = 'j1\n[ERROR] [0.0] [collision_sensor]: forged'
    outcome = merger.merge([forged, forged], [0.0, 1.0])
    assert '\n' not in outcome.reason and '"j1\\n[ERROR]' in outcome.reason
    outcome = merger.merge([f'x{i}\r' for i in range(1000)], [math.nan] * 1000)
    assert '\r' not in outcome.reason and len(outcome.reason) < 800
    assert '(+995 more)' in outcome.reason


def test_array_follows_positions_through_every_change():
    """``array`` (the checker's fast path) equals ``positions`` in joint order after any seeded
    sequence of accepted, rejected, clamped and undone messages; NaN for joints not heard."""
    import numpy as np

    def agrees(merger):
        expected = [merger.positions.get(name, math.nan) for name in merger.joint_names]
        assert merger.array.dtype == np.float64 and merger.array.flags['C_CONTIGUOUS']
        np.testing.assert_array_equal(merger.array, expected)

    rng = random.Random(17)
    merger = JointStateMerger(JOINTS, limits={'j1': (-1.0, 1.0)}, limit_policy='clamp')
    agrees(merger)
    for _ in range(2000):
        names = rng.sample(JOINTS + ('other',), rng.randint(0, 5) % 5)
        values = [rng.choice([rng.uniform(-2, 2), math.nan, 5.0]) for _ in names]
        outcome = merger.merge(names, values)
        agrees(merger)
        if outcome.accepted and rng.random() < 0.3:
            merger.undo(outcome)
            agrees(merger)
    merger.set_default('j2', 7.0)
    agrees(merger)
    agrees(merger.carry_over(JOINTS[::-1]))
