"""The demo's node: ``collision_sensor_node`` of this install in a process of its own, on the
bundled demo cell, with DDS kept on this machine; waiting until it is ready.

No ROS is imported here at module level: the demo's command line loads ROS only to run.
"""
import os
import random
import signal
import subprocess
import sys
import threading
import time
from typing import Dict, List, Optional

from collision_sensor.errors import CollisionSensorError

START_TIMEOUT = None    # s for the node to be ready; None: as long as the node process lives
PROGRESS_PERIOD = 15.0  # s between "still starting" lines while the node starts
READY_MARK = 'ready: checking '   # the node's one line once it subscribes to joint_states
STOP_TIMEOUT = 10.0     # s for the node to exit on SIGINT before it is killed
_POLL = 0.05            # s between checks while waiting


#: Held while a whole line is written to the demo's output: the node's echoed lines (a thread
#: of their own) and the demo's never share a line.
OUTPUT_LOCK = threading.Lock()


class DemoError(CollisionSensorError):
    """The demo could not run: the node did not come up, died, or gave no verdict."""


def set_ros_environment(environ=os.environ) -> List[str]:
    """Keep DDS local: SHM transport, and a random domain unless one is set.

    Changes ``environ`` in place (the node process inherits it) and returns what was chosen
    here, in words.
    """
    notes = []
    if not environ.get('FASTDDS_BUILTIN_TRANSPORTS'):
        environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'SHM'
        notes.append('the SHM transport')
    if not environ.get('ROS_DOMAIN_ID'):
        environ['ROS_DOMAIN_ID'] = str(random.SystemRandom().randint(1, 100))
        notes.append('a random ROS_DOMAIN_ID')
    return notes


def node_command() -> List[str]:
    """Return the command that runs ``collision_sensor_node`` of this very install (venv, pip
    or colcon: :func:`collision_sensor.ros.console_scripts.console_command`), never one that
    happens to be on PATH."""
    from collision_sensor.ros.console_scripts import console_command
    return console_command('collision_sensor_node')


def demo_cell_parameters(motion: bool = False, camera: bool = False) -> Dict[str, object]:
    """Return the node parameters that load the bundled demo cell, with reliable input and
    instant verdicts unless ``motion`` (``check_motion`` off: the demo's summary is compared
    with the offline check's, which checks each frame's instant); ``camera``: the node takes
    the demo camera's clouds (``point_cloud_topics``)."""
    from collision_sensor.model.share import config_path
    parameters = {'urdf_path': config_path('demo_arm.urdf'),
                  'srdf_path': config_path('demo_arm.srdf'),
                  'scene_path': config_path('demo_scene.yaml'),
                  'joint_states_qos': 'reliable', 'check_motion': motion}
    if camera:
        from collision_sensor.tools.demo_camera import CLOUD_TOPIC
        parameters['point_cloud_topics'] = f'[{CLOUD_TOPIC}]'
    return parameters


class NodeProcess:
    """``collision_sensor_node`` in a process of its own; its log lines are echoed, prefixed.

    :param parameters: ``{name: value}`` given as ``-p name:=value``.
    :param namespace: the node's namespace.
    :param echo: where the node's lines go (``None``: kept in :attr:`lines` only).
    """

    def __init__(self, parameters: Dict[str, str], namespace: str, echo=sys.stdout):
        command = node_command() + ['--ros-args', '-r', f'__ns:={namespace}']
        for name, value in parameters.items():
            command += ['-p', f'{name}:={value}']
        env = dict(os.environ)
        env.setdefault('RCUTILS_CONSOLE_OUTPUT_FORMAT', '[{severity}] {message}')
        env.setdefault('PYTHONUNBUFFERED', '1')
        self.lines: List[str] = []
        self.ready = threading.Event()
        self._echo = echo
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, env=env)
        self._reader = threading.Thread(target=self._read, name='node output', daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            line = line.rstrip('\n')
            self.lines.append(line)
            if READY_MARK in line:
                self.ready.set()
            if self._echo is not None:
                with OUTPUT_LOCK:
                    print(f'  node | {line}', file=self._echo, flush=True)

    def exited(self) -> Optional[int]:
        """Return the exit status if the process has ended, else None."""
        return self.process.poll()

    def stop(self) -> int:
        """Stop the node with SIGINT (as Ctrl-C would), killing it if it hangs; return status.

        What the node prints from here on is kept in :attr:`lines` but not echoed.
        """
        self._echo = None
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._reader.join(2.0)
        return self.process.returncode


def wait_until_ready(node, publisher, pairs_sub, timeout: Optional[float], say,
                     progress_period: float = PROGRESS_PERIOD) -> float:
    """Wait until the node is ready and matched both ways; return the seconds it took.

    Ready: the node logged its ``ready:`` line (it subscribes to joint_states only after the
    robot is loaded, its trees built and the query run once), ``publisher`` (joint_states) has
    a subscriber and ``pairs_sub`` (colliding_pairs) a publisher.

    :param node: the :class:`NodeProcess`.
    :param timeout: seconds, or ``None`` to wait as long as the node process lives.
    :param say: prints one line.
    :raises DemoError: the node exited first, or ``timeout`` passed.
    """
    started = time.monotonic()
    next_progress = started + progress_period
    while not (node.ready.is_set() and publisher.get_subscription_count() >= 1
               and pairs_sub.get_publisher_count() >= 1):
        status = node.exited()
        if status is not None:
            raise DemoError(f'collision_sensor_node exited with status {status} before it was '
                            'ready (its output is above)')
        now = time.monotonic()
        if timeout is not None and now - started > timeout:
            raise DemoError(f'collision_sensor_node did not subscribe to '
                            f'{publisher.topic_name} within {timeout:g} s (--timeout); it is '
                            'still starting: wait longer, or leave --timeout out to wait as '
                            'long as it runs')
        if now >= next_progress:
            next_progress += progress_period
            say(f'still waiting for collision_sensor_node to be ready ({now - started:.0f} s; '
                'the first start compiles the engine, which takes a minute or more on a busy '
                'machine) ...')
        time.sleep(_POLL)
    return time.monotonic() - started
