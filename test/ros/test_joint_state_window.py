"""The window of recent joint states (collision_sensor.ros.joint_state_window) against a
brute-force reading of its contract."""
import numpy as np

from collision_sensor.ros.joint_state_window import JointStateWindow


def test_interpolates_inside_and_answers_the_newest_after():
    rng = np.random.default_rng(0)
    window = JointStateWindow(window=1.0)
    times = np.cumsum(rng.uniform(0.0005, 0.002, 3000))
    states = rng.normal(size=(3000, 4))
    for t, q in zip(times, states):
        window.record(float(t), q)
    newest = times[-1]
    assert window.newest == newest
    assert newest - 1.0 - 0.002 <= window.oldest <= newest - 1.0
    for t in rng.uniform(newest - 0.99, newest, 200):
        k = np.searchsorted(times, t, side='right')
        s = (t - times[k - 1]) / (times[k] - times[k - 1])
        np.testing.assert_allclose(window.at(t), (1 - s) * states[k - 1] + s * states[k])
    np.testing.assert_array_equal(window.at(newest + 5.0), states[-1])
    np.testing.assert_array_equal(window.at(times[-2]), states[-2])
    assert window.at(newest - 1.5) is None


def test_time_going_back_restarts_and_equal_stamps_replace():
    window = JointStateWindow(window=1.0)
    assert window.at(0.0) is None
    window.record(10.0, [1.0])
    window.record(10.0, [2.0])
    assert len(window) == 1 and window.at(10.0)[0] == 2.0
    window.record(5.0, [3.0])       # a bag restarted
    assert len(window) == 1 and window.at(5.0)[0] == 3.0 and window.at(4.0) is None


def test_capacity_bounds_memory():
    window = JointStateWindow(window=100.0, capacity=50)
    for k in range(1000):
        window.record(k * 0.001, [float(k)])
    assert len(window) <= 51
    assert window.at(0.999)[0] == 999.0


def test_with_kinds_a_continuous_joint_goes_the_short_way_and_a_rotation_along_the_arc():
    """A driver wrapping a continuous joint at +-pi: between 3.1 and -3.1 the state passes
    pi, not 0; a floating joint's quaternion moves along the shortest arc (slerp, sign
    flips taken the short way), against the rotation computed here from the angle."""
    import math
    from collision_sensor.engine.compiled import engine
    kinds = np.array([engine.MOTION_LINEAR, engine.MOTION_WRAP, engine.MOTION_QUATERNION,
                      engine.MOTION_QUATERNION_REST, engine.MOTION_QUATERNION_REST,
                      engine.MOTION_QUATERNION_REST])
    window = JointStateWindow(window=1.0, kinds=kinds)
    angle = 2.0     # about z, from the identity
    q0 = [0.0, 3.1, 0.0, 0.0, 0.0, 1.0]
    # the same end rotation with the quaternion's sign flipped (-q is q's rotation)
    q1 = [1.0, -3.1, 0.0, 0.0, -math.sin(angle / 2), -math.cos(angle / 2)]
    window.record(0.0, q0)
    window.record(1.0, q1)
    for s in (0.25, 0.5, 0.75):
        q = window.at(s)
        assert q[0] == s
        wrapped = 3.1 + s * (2 * math.pi - 6.2)        # through pi
        assert abs(math.remainder(q[1] - wrapped, 2 * math.pi)) < 1e-12
        assert abs(q[1]) > 3.0
        half = s * angle / 2      # the shortest arc from the identity: rotation s * angle
        expected = np.array([0.0, 0.0, math.sin(half), math.cos(half)])
        np.testing.assert_allclose(q[2:], expected, atol=1e-12)
    plain = JointStateWindow(window=1.0)
    plain.record(0.0, q0)
    plain.record(1.0, q1)
    assert abs(plain.at(0.5)[1]) < 1e-12       # without kinds: componentwise, through 0
