"""``collision_sensor_node``: the console script, which stops cleanly on a signal at any moment.

The node itself is :class:`collision_sensor.ros.node.CollisionSensorNode`. This module stays
light on purpose: the console script imports it before ``main`` runs, while importing the node
pulls in rclpy, the engine and the message packages (about a second).

How a stop works, in every phase, with exit status 0, no traceback and no core dump:

- ``main`` first makes SIGINT and SIGTERM set a flag (:class:`StopRequest`). The handler
  raises nothing: an exception thrown from a signal handler lands wherever the main thread
  happens to be, and inside a finaliser or an import lock callback Python prints it as
  "Exception ignored" and swallows it, so the stop would be lost.
- Start-up (importing rclpy and the engine, ``rclpy.init``, loading the robot, building its trees,
  running the query once) runs on a thread of its own, which nothing can interrupt; the main
  thread only waits for it or for the flag. A stop during start-up ends the process there, with
  ``os._exit(0)`` after flushing the output: nothing has been published, and tearing the
  interpreter down under a thread in the middle of C code (a build, a compile) could crash.
- Once up, the main thread spins. rclpy's own handlers (installed by ``rclpy.init``, chained to
  ours) shut the context down, the executor wakes up within milliseconds and the node is
  destroyed in order. Work left on other threads (a robot_description being built) is dropped
  the same way as during start-up.

A signal in the first ~0.1 s, while the interpreter itself starts and before any line of this
package runs, takes the signal's default action: no Python program can handle it.
"""
import os
import signal
import sys
import threading
import traceback
from typing import Optional

_POLL = 0.02    # s between looks at the flag while start-up runs


class StopRequest:
    """Remember the first SIGINT or SIGTERM; raise nothing.

    :ivar signal_name: the signal that asked to stop (``None`` before).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.signal_name = None

    def install(self) -> 'StopRequest':
        """Install the handlers (main thread only); return self."""
        for signum in self.SIGNALS:
            signal.signal(signum, self._handle)
        return self

    def _handle(self, signum, frame):
        if self.signal_name is None:
            self.signal_name = signal.Signals(signum).name


#: Environment variables by which a user configures Fast DDS profiles already.
_FAST_DDS_CONFIGURED = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE',
                        'RMW_FASTRTPS_USE_QOS_FROM_XML', 'RMW_FASTRTPS_PUBLICATION_MODE')
#: Profile files Fast DDS loads from the working directory on its own.
_FAST_DDS_LOCAL_FILES = ('DEFAULT_FASTRTPS_PROFILES.xml', 'DEFAULT_FASTDDS_PROFILES.xml')


def apply_dds_profile(environ=os.environ) -> Optional[str]:
    """Point Fast DDS at ``config/fastdds_node.xml`` (its comment says why); return its path.

    Only for this process, before rclpy starts, and only when the middleware is Fast DDS
    (Jazzy's default), no Fast DDS profile is configured already (environment or working
    directory) and ``COLLISION_SENSOR_DDS_PROFILE`` is not ``off``; else return None and change
    nothing.
    """
    if environ.get('COLLISION_SENSOR_DDS_PROFILE', 'on').strip().lower() in ('off', '0', 'false',
                                                                             'no'):
        return None
    if environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp') not in (
            'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp', ''):
        return None
    if any(environ.get(name) for name in _FAST_DDS_CONFIGURED) or \
            any(os.path.exists(name) for name in _FAST_DDS_LOCAL_FILES):
        return None
    from collision_sensor.model.share import config_path
    try:
        profile = config_path('fastdds_node.xml')
    except FileNotFoundError:   # a broken install: the node itself says so
        return None
    if not os.path.isfile(profile):
        return None
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = profile
    environ['RMW_FASTRTPS_USE_QOS_FROM_XML'] = '1'
    return profile


class _StartUp(threading.Thread):
    """Import the node, initialise rclpy and build the node, off the main thread."""

    def __init__(self, args, dds_profile: Optional[str] = None):
        super().__init__(name='start-up', daemon=True)
        self._args = args
        self._dds_profile = dds_profile
        self.node = None
        self.status = None     # 1: configuration failed (logged by the node)
        self.error = None      # anything else start-up raised

    def run(self):
        try:
            from collision_sensor.ros import node
            self.node, self.status = node.start(self._args, self._dds_profile)
        except BaseException as error:  # noqa: B902 - reported by main, or moot after a stop
            # A stop shuts rclpy's context down under the constructor, which then fails
            # somewhere: main decides whether that is worth a word.
            self.error = error


def _exit_now(status: int) -> None:
    sys.stdout.flush()
    sys.stderr.flush()
    try:    # the C streams too: rcutils logs through them, and os._exit flushes nothing
        import ctypes
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass
    os._exit(status)


def _background_threads_busy() -> bool:
    return any(thread.is_alive() and thread.daemon for thread in threading.enumerate()
               if thread is not threading.current_thread())


def main(args=None) -> int:
    """Run the node until SIGINT, SIGTERM or shutdown; return 1 when configuration fails."""
    stop = StopRequest()
    if threading.current_thread() is threading.main_thread():
        stop.install()
    start_up = _StartUp(args, apply_dds_profile())
    start_up.start()
    while start_up.is_alive() and stop.signal_name is None:
        start_up.join(_POLL)
    if stop.signal_name is not None and start_up.node is None:
        _exit_now(0)        # during start-up: see the module docstring
    if start_up.error is not None:
        traceback.print_exception(start_up.error)
        return 1
    if start_up.node is None:
        return start_up.status
    from collision_sensor.ros import node
    status = node.spin(start_up.node, stopped=lambda: stop.signal_name is not None)
    if _background_threads_busy():
        _exit_now(status)
    return status


if __name__ == '__main__':
    raise SystemExit(main())
