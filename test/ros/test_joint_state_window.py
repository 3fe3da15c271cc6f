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
