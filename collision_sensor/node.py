"""``collision_sensor_node``: the console script, which stops cleanly on a signal at any moment.

The node itself is :class:`collision_sensor.sensor_node.CollisionSensorNode` (also importable
from here). This module stays light on purpose: the console script imports it before ``main``
runs, and importing the node pulls in rclpy, numba and the message packages (about a second).
``main`` therefore first turns SIGINT and SIGTERM into a stop request, and only then imports
the rest, loads the robot and spins; a signal in any phase (importing, loading the robot,
building its trees, compiling the query, checking) ends the process with exit status 0, no
traceback and no core dump.

How: the first SIGINT or SIGTERM raises :class:`KeyboardInterrupt` in the main thread (where
all loading and spinning happen; rclpy, once initialised, chains its own handler to this one and
wakes the executor); later signals are ignored, so that a second Ctrl-C cannot interrupt the
clean-up. Work left on other threads (a robot_description being built) is abandoned: the
process ends with ``os._exit`` after the clean-up, so no interpreter teardown races it.
"""
import os
import signal
import sys
import threading

_EXPORTED = ('CollisionSensorNode', 'LATCHED_QOS', 'VERDICT_QOS', 'JOINT_STATES_QOS',
             'RELIABLE_INPUT_QOS', 'quaternion_from_matrix')


def __getattr__(name):
    if name in _EXPORTED:
        from collision_sensor import sensor_node
        return getattr(sensor_node, name)
    raise AttributeError(f'module "collision_sensor.node" has no attribute "{name}"')


class StopOnSignal:
    """Turn the first SIGINT or SIGTERM into a :class:`KeyboardInterrupt`; ignore later ones.

    :ivar signal_name: the signal that asked to stop (``None`` before).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.signal_name = None

    def install(self) -> 'StopOnSignal':
        """Install the handlers (main thread only); return self."""
        for signum in self.SIGNALS:
            signal.signal(signum, self._handle)
        return self

    def _handle(self, signum, frame):
        if self.signal_name is not None:
            return
        self.signal_name = signal.Signals(signum).name
        raise KeyboardInterrupt(self.signal_name)


def _finish(status: int) -> int:
    """Return ``status``, or end the process now if a background thread still works."""
    busy = [thread for thread in threading.enumerate()
            if thread is not threading.main_thread() and thread.is_alive() and thread.daemon]
    if busy:
        # A robot_description build (C code, numba) cannot be interrupted; tearing the
        # interpreter down under it may crash. Everything that matters is closed already.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


def main(args=None) -> int:
    """Run the node until SIGINT, SIGTERM or shutdown; return 1 when configuration fails."""
    stop = StopOnSignal()
    if threading.current_thread() is threading.main_thread():
        stop.install()
    status = 0
    try:
        from collision_sensor.sensor_node import run
        status = run(args)
    except KeyboardInterrupt:
        status = 0
    return _finish(status)


if __name__ == '__main__':
    raise SystemExit(main())
