"""The robot's recent states, by time: what a sensor's data stamped a moment ago must be placed
with (issue 29, item 2: a cloud is self-filtered with the robot's pose at its stamp).

Pure Python and numpy, no rclpy: the joint state source records each complete state it accepts
with its stamp; a point cloud source asks for the state at its cloud's stamp. Contract::

    window.record(t, q)          # q (J,) float, t in s; t below the newest restarts the window
    window.at(t) -> (J,) | None
        t >= newest stamp        -> the newest state (nothing newer is known)
        oldest <= t < newest     -> linear interpolation between the two states around t
        t < oldest kept          -> None: older than the window, not placed with a wrong pose

States older than ``window`` seconds before the newest are forgotten. Between two states the
robot moves as a straight motion does (:func:`collision_sensor.engine.motion.interpolate`, when
the window is given the variables' ``kinds``): revolute and prismatic joints linearly, a
continuous joint the shorter way round (a driver that wraps its angle at +-pi is not swung
through the other side), a floating joint's rotation along the shortest arc; without
``kinds``, every value linearly.
"""
import bisect
from typing import List, Optional

import numpy as np

from collision_sensor.engine.motion import interpolate


class JointStateWindow:
    """The states of the last ``window`` seconds.

    :param window: seconds of history kept (> 0).
    :param capacity: states kept at most (a 1 kHz stream over 1 s: 1000), whatever the window.
    :ivar kinds: the variables' motion kinds (``CollisionChecker.motion_kinds``), or None.
    """

    def __init__(self, window: float = 1.0, capacity: int = 4096, kinds=None):
        self.window = float(window)
        self.capacity = int(capacity)
        self.kinds = kinds
        self._times: List[float] = []
        self._states: List[np.ndarray] = []

    def __len__(self) -> int:
        return len(self._times)

    def clear(self) -> None:
        """Forget every state (a new robot)."""
        self._times.clear()
        self._states.clear()

    def record(self, t: float, q: np.ndarray) -> None:
        """Keep state ``q`` (copied) at time ``t`` (s)."""
        times, states = self._times, self._states
        if times and t < times[-1]:
            self.clear()            # time went back (a bag restarted, sim time reset)
        elif times and t == times[-1]:
            states[-1] = np.array(q, dtype=np.float64)
            return
        times.append(t)
        states.append(np.array(q, dtype=np.float64))
        # Forget what left the window (amortised: in chunks, not one pop per state).
        horizon = t - self.window
        if times[0] < horizon or len(times) > self.capacity:
            first = max(bisect.bisect_left(times, horizon) - 1, len(times) - self.capacity, 0)
            if first > 0:
                del times[:first]
                del states[:first]

    @property
    def oldest(self) -> Optional[float]:
        """The oldest stamp kept, or None."""
        return self._times[0] if self._times else None

    @property
    def newest(self) -> Optional[float]:
        """The newest stamp kept, or None."""
        return self._times[-1] if self._times else None

    def at(self, t: float) -> Optional[np.ndarray]:
        """Return the state at time ``t`` (see the module docstring), or None when ``t`` is
        older than every state kept, or nothing is kept."""
        times = self._times
        if not times or t < times[0]:
            return None
        if t >= times[-1]:
            return self._states[-1].copy()
        k = bisect.bisect_right(times, t)       # times[k - 1] <= t < times[k]
        t0, t1 = times[k - 1], times[k]
        s = (t - t0) / (t1 - t0)
        if self.kinds is not None:
            return interpolate(self.kinds, self._states[k - 1], self._states[k], [s])[0]
        return (1.0 - s) * self._states[k - 1] + s * self._states[k]
