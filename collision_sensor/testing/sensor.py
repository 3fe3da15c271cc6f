"""The sensor under test: ``collision_sensor_node`` in this process, and a client that talks to
it over its topics and waits for the answer that belongs to what it sent.

:func:`running_sensor` (a context manager) and the ``collision_sensor`` pytest fixture
(:mod:`collision_sensor.testing.plugin`) start a :class:`SensorUnderTest`: the node
(:class:`~collision_sensor.ros.node.CollisionSensorNode`, its public constructor only)
on a robot, a scene and parameters, in an rclpy Context of its own, a DDS domain of its own and
a namespace of its own, spun on a thread of its own with the client's node. Everything goes
through the node's topics and parameter services, as a planner or a driver would talk to it,
and every answer is matched to its input, never taken as "the next message":

- a joint state by its header (the client stamps each one uniquely): the ``colliding_pairs``
  with that header, and the ``contact`` published with it (the node publishes one ``contact``
  then one ``colliding_pairs`` per verdict, in order);
- a trajectory by ``trajectory_digest`` (docs/node.md), in the order sent when the same one is
  sent twice; ``relayed`` by the digest of what came out on ``trajectory_out``;
- a scene array by the ``scene`` status on ``/diagnostics`` whose count of arrays handled
  reaches it (the client is the only publisher in its namespace), and the verdict the node gave
  on it (published just before that status, under the node's lock);
- a cloud by the verdict the node gives when it takes it (or its status's count, when refused);
- a parameter change by the verdict the node gives on it (once a state was checked).

Scene arrays, clouds and parameter changes are sent one at a time (each call returns with its
answer); joint states and trajectories can also be sent ahead (:meth:`publish_joint_state`,
:meth:`publish_trajectory`) and their answers awaited later.
"""
import os
import tempfile
import threading
import time
import uuid
from typing import Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import rclpy
import yaml
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import (
    DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data)
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import Bool
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from collision_sensor.errors import ConfigError
from collision_sensor.model.point_cloud_message import cdr_from_points
from collision_sensor.ros.answers import (
    CLOUD_COUNTS, SCENE_COUNTS, Verdict, handled_total, status_values, trajectory_answer_from,
    verdict_from)
from collision_sensor.ros.node import make_executor
from collision_sensor.ros.scene_messages import absolute_mesh_paths, scene_markers
from collision_sensor.ros.trajectory_source import trajectory_digest
from collision_sensor.testing.messages import joint_trajectory
from collision_sensor.testing.outcomes import (
    TIMEOUT, CloudAnswer, NoAnswer, PendingTrajectory, PendingVerdict, SceneAnswer,
    TrajectoryOutcome)
from collision_sensor.testing.robots import robot_files

#: Domains :func:`own_domain` picks from (above the 0 a robot usually uses; 232 is Fast DDS's
#: last with its default ports).
DOMAINS = range(101, 233)

_KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
_KEEP_ALL_LATCHED = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                               reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.TRANSIENT_LOCAL)
_SCENE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
_STALE = 'joint_states_stale'
_CLOUD_TIMEOUT = 'point_cloud_timeout'


def own_domain() -> int:
    """Return the DDS domain sensors of this process use: ``$COLLISION_SENSOR_TEST_DOMAIN``, or
    one picked from the process id in :data:`DOMAINS` (not a robot's usual domain 0)."""
    chosen = os.environ.get('COLLISION_SENSOR_TEST_DOMAIN', '').strip()
    if chosen:
        return int(chosen)
    return DOMAINS[os.getpid() % len(DOMAINS)]


class SensorUnderTest:
    """The node running on a robot in this process, and its client (see the module docstring).

    :param robot: a URDF path, or an example-robot-data robot's name (:func:`robot_files`).
    :param srdf: the SRDF's path (an example robot's own by default; ``False``: none).
    :param package_paths: ``{package: directory}`` or ``["package=directory", ...]`` for
        ``package://`` URIs.
    :param scene: the fixed scene: a scene file's path, or the dict it parses to.
    :param parameters: more of the node's parameters (``{name: value}``).
    :param domain_id: the DDS domain (default :func:`own_domain`).
    :param namespace: the node's namespace (default: a fresh one).
    """

    def __init__(self, robot: Union[str, os.PathLike] = 'panda', *, srdf=None,
                 package_paths=None, scene=None, parameters: Optional[Mapping] = None,
                 domain_id: Optional[int] = None, namespace: Optional[str] = None):
        self.urdf, self.srdf, self.package_paths = robot_files(robot, srdf, package_paths)
        self.domain_id = own_domain() if domain_id is None else int(domain_id)
        self.namespace = namespace or f'/collision_sensor_test_{uuid.uuid4().hex[:8]}'
        self._values = {'urdf_path': self.urdf, 'srdf_path': self.srdf,
                        'package_paths': self.package_paths}
        self._scene_dir = None
        if scene is not None:
            self._values['scene_path'] = self._scene_path(scene)
        self._values.update(dict(parameters or {}))
        self.context = self.node = self.client = None
        self._executor = self._spinner = None
        self._stop = threading.Event()
        self._condition = threading.Condition()
        self._contacts: List[bool] = []
        self._pairs: List[DiagnosticArray] = []
        self._by_header: Dict[Tuple[int, int, str], int] = {}
        self._sent_headers = set()
        self._statuses: List[Tuple[Tuple[int, int], str, Dict[str, str]]] = []
        self._waiting_trajectories: Dict[str, List[PendingTrajectory]] = {}
        self._relays: Dict[str, int] = {}
        self._valid_answers: Dict[str, int] = {}
        self._answers_seen = 0      # the highest answer_index received on trajectory_result
        self._last_stamp = 0
        self._scenes_sent = self._scenes_applied = self._scene_verdicts = 0
        self._clouds_sent: Dict[str, int] = {}
        self._clouds_accepted: Dict[str, int] = {}
        self._cloud_publishers = {}
        self._parameters_client = None
        self._checked = False   # a state was checked: the node answers scene and parameters

    # -- start and stop -----------------------------------------------------------------------

    def _scene_path(self, scene) -> str:
        if not isinstance(scene, Mapping):
            return os.path.abspath(os.fspath(scene))
        self._scene_dir = tempfile.TemporaryDirectory(prefix='collision_sensor_scene_')
        path = os.path.join(self._scene_dir.name, 'scene.yaml')
        with open(path, 'w', encoding='utf-8') as stream:
            yaml.safe_dump(absolute_mesh_paths(dict(scene), os.getcwd()), stream)
        return path

    def start(self, timeout: float = TIMEOUT) -> 'SensorUnderTest':
        """Start the node and its client; return self once every topic is matched.

        :raises CollisionSensorError: the node refused its configuration (the reason named).
        """
        from collision_sensor.ros.node import CollisionSensorNode
        # Discovery stays on this machine unless the caller configured it.
        if not os.environ.get('ROS_LOCALHOST_ONLY'):
            os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, domain_id=self.domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        try:
            self.node = CollisionSensorNode(
                context=self.context, namespace=self.namespace,
                parameter_overrides=[Parameter(name, value=value)
                                     for name, value in self._values.items()])
            self.client = Node('collision_sensor_test_client', namespace=self.namespace,
                               context=self.context)
            self._connect()
            # the executor the console script spins (COLLISION_SENSOR_EXECUTOR, else events)
            self._executor = make_executor(self.context)
            self._executor.add_node(self.node)
            self._executor.add_node(self.client)
            self._spinner = threading.Thread(target=self._spin, name='sensor under test',
                                             daemon=True)
            self._spinner.start()
            self.wait(self._matched, timeout, 'the node\'s topics were not matched')
        except BaseException:
            self.close()
            raise
        return self

    def _connect(self) -> None:
        client = self.client
        self._subscriptions = [
            client.create_subscription(Bool, 'contact', self._on_contact, _KEEP_ALL_LATCHED),
            client.create_subscription(DiagnosticArray, 'colliding_pairs', self._on_pairs,
                                       _KEEP_ALL_LATCHED),
            client.create_subscription(DiagnosticArray, 'trajectory_result', self._on_result,
                                       _KEEP_ALL_LATCHED),
            client.create_subscription(JointTrajectory, 'trajectory_out', self._on_relay,
                                       _KEEP_ALL)]
        client.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                   _KEEP_ALL)
        self._joint_states = client.create_publisher(JointState, 'joint_states', _KEEP_ALL)
        self._trajectories = client.create_publisher(JointTrajectory, 'trajectory', _KEEP_ALL)
        self._scene = client.create_publisher(MarkerArray, 'scene', _SCENE_QOS)
        self._status_prefix = f'{self.node.get_fully_qualified_name().lstrip("/")}: '

    def _matched(self) -> bool:
        """Every publisher matched by the node, every subscription by the node's publisher
        (relays on trajectory_out are volatile: none may go before)."""
        return (self._joint_states.get_subscription_count() > 0
                and self._trajectories.get_subscription_count() > 0
                and self._scene.get_subscription_count() > 0
                and all(sub.get_publisher_count() > 0 for sub in self._subscriptions))

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: B902 - a shutdown under the executor ends spinning
                if self._stop.is_set() or not self.context.ok():
                    return
                raise

    def close(self) -> None:
        """Stop spinning, destroy the node and the client, shut the context down."""
        self._stop.set()
        if self._spinner is not None:
            self._spinner.join(10.0)
            self._spinner = None
        for node in (self.client, self.node):
            if node is not None:
                if self._executor is not None:
                    self._executor.remove_node(node)
                node.destroy_node()
        self.client = self.node = None
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None
        if self.context is not None:
            rclpy.try_shutdown(context=self.context)
        if self._scene_dir is not None:
            self._scene_dir.cleanup()
            self._scene_dir = None

    def __enter__(self) -> 'SensorUnderTest':
        return self if self.node is not None else self.start()

    def __exit__(self, *_exc) -> None:
        self.close()

    # -- what the node says, taken on the spinning thread --------------------------------------

    def _on_contact(self, msg: Bool) -> None:
        with self._condition:
            self._contacts.append(msg.data)
            self._condition.notify_all()

    def _on_pairs(self, msg: DiagnosticArray) -> None:
        stamp = msg.header.stamp
        key = (stamp.sec, stamp.nanosec, msg.header.frame_id)
        with self._condition:
            self._by_header.setdefault(key, len(self._pairs))
            self._pairs.append(msg)
            self._condition.notify_all()

    def _on_result(self, msg: DiagnosticArray) -> None:
        try:
            answer = trajectory_answer_from(msg)
        except ValueError:
            return
        with self._condition:
            self._answers_seen = max(self._answers_seen, answer.index)
            if answer.digest:   # by its digest, first sent first
                pending = next((p for p in self._waiting_trajectories.get(answer.digest, ())
                                if answer.index > p.answered_before), None)
            else:   # answered undecoded: by its header, first sent first
                pending = next((p for waiting in self._waiting_trajectories.values()
                                for p in waiting if (p.msg.header.stamp.sec,
                                                     p.msg.header.stamp.nanosec) == answer.stamp
                                and p.msg.header.frame_id == answer.frame
                                and answer.index > p.answered_before), None)
            if pending is None:     # not one of this client's
                return
            self._waiting_trajectories[pending.digest].remove(pending)
            if answer.valid:
                count = self._valid_answers.get(pending.digest, 0) + 1
                self._valid_answers[pending.digest] = pending.relay_rank = count
            pending.answer = answer
            self._condition.notify_all()

    def _on_relay(self, msg: JointTrajectory) -> None:
        digest = trajectory_digest(msg)
        with self._condition:
            self._relays[digest] = self._relays.get(digest, 0) + 1
            self._condition.notify_all()

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        mine = [(status.name[len(self._status_prefix):], status_values(status))
                for status in msg.status if status.name.startswith(self._status_prefix)]
        if mine:
            with self._condition:
                self._statuses.extend((stamp, which, values) for which, values in mine)
                self._condition.notify_all()

    def wait(self, ready, timeout: float, what: str):
        """Wait until ``ready()`` (under the lock) returns something true; return it."""
        deadline = time.monotonic() + timeout
        with self._condition:
            while True:
                found = ready()
                if found:
                    return found
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (self._spinner is not None and
                                      not self._spinner.is_alive()):
                    raise NoAnswer(f'{what} within {timeout:g} s (node {self.namespace}/'
                                   'collision_sensor: its log lines above say why)')
                self._condition.wait(min(remaining, 0.1))

    def _verdict_at(self, index: int) -> Optional[Verdict]:
        if index >= len(self._contacts):
            return None
        return verdict_from(self._contacts[index], self._pairs[index])

    def _own_verdicts(self, since: int, latest_stamp=None, timed_out: str = '') -> List[int]:
        """Indices of the verdicts from ``since`` on that answer none of the client's joint
        states (the node's verdicts on a scene array, a cloud, a parameter change), without
        the entries its timers publish on their own (stale joint states; with ``timed_out``,
        that cloud topic's timeout); with ``latest_stamp``, only those stamped no later."""
        found = []
        for index in range(since, len(self._pairs)):
            msg = self._pairs[index]
            stamp = msg.header.stamp
            key = (stamp.sec, stamp.nanosec, msg.header.frame_id)
            if key in self._sent_headers or any(
                    s.name == _STALE or (timed_out and s.name == _CLOUD_TIMEOUT
                                         and s.message.startswith(f'point cloud {timed_out}:'))
                    for s in msg.status):
                continue
            if latest_stamp is not None and (stamp.sec, stamp.nanosec) > latest_stamp:
                continue
            found.append(index)
        return found

    # -- joint states ---------------------------------------------------------------------------

    @property
    def joint_names(self) -> Tuple[str, ...]:
        """The robot's joint names (the checker's order)."""
        return tuple(self.node.checker.joint_names)

    def _stamp(self) -> Time:
        """A stamp now, later than every stamp sent before (the client's clock)."""
        now = max(self.client.get_clock().now().nanoseconds, self._last_stamp + 1)
        self._last_stamp = now
        return Time(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000)

    def publish_joint_state(self, positions=None, names: Optional[Sequence[str]] = None,
                            **joints) -> PendingVerdict:
        """Publish a joint state; return its :class:`PendingVerdict`.

        :param positions: ``{joint: value}``, or values in the order of ``names`` (default
            :attr:`joint_names`), or a ``sensor_msgs/JointState`` (sent with a fresh stamp).
        :param joints: more ``joint=value``.
        """
        if isinstance(positions, JointState):
            msg = positions
        else:
            if positions is None:
                positions = {}
            if not isinstance(positions, Mapping):
                positions = dict(zip(names or self.joint_names, positions))
            positions = {**positions, **joints}
            msg = JointState(name=list(positions),
                             position=[float(v) for v in positions.values()])
        msg.header.stamp = self._stamp()
        key = (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id)
        with self._condition:
            self._sent_headers.add(key)
        self._joint_states.publish(msg)
        return PendingVerdict(self, key)

    def send_joint_state(self, positions=None, names: Optional[Sequence[str]] = None,
                         timeout: float = TIMEOUT, **joints) -> Verdict:
        """Publish a joint state and return its verdict (see :meth:`publish_joint_state`)."""
        return self.publish_joint_state(positions, names, **joints).result(timeout)

    def verdict_for(self, key, timeout: float) -> Verdict:
        def answered():
            index = self._by_header.get(key)
            return None if index is None else self._verdict_at(index)
        verdict = self.wait(answered, timeout, f'no verdict on the joint state stamped '
                            f'{key[0]}.{key[1]:09d}')
        if not verdict.failure:
            self._checked = True
        return verdict

    # -- trajectories ---------------------------------------------------------------------------

    def publish_trajectory(self, trajectory, joint_names: Optional[Sequence[str]] = None
                           ) -> PendingTrajectory:
        """Publish a trajectory; return its :class:`PendingTrajectory`.

        :param trajectory: a ``JointTrajectory``, or points as :func:`joint_trajectory` takes
            them.
        """
        msg = trajectory if isinstance(trajectory, JointTrajectory) else \
            joint_trajectory(trajectory, joint_names)
        pending = PendingTrajectory(self, msg)
        with self._condition:
            self._waiting_trajectories.setdefault(pending.digest, []).append(pending)
            pending.answered_before = self._answers_seen
        self._trajectories.publish(msg)
        return pending

    def send_trajectory(self, trajectory, joint_names: Optional[Sequence[str]] = None,
                        timeout: float = TIMEOUT) -> 'TrajectoryOutcome':
        """Publish a trajectory and return its answer, with ``relayed`` (see
        :meth:`publish_trajectory`)."""
        return self.publish_trajectory(trajectory, joint_names).outcome(timeout)

    def trajectory_answer(self, pending: PendingTrajectory, timeout: float):
        return self.wait(lambda: pending.answer, timeout,
                         f'no answer on trajectory_result for the trajectory of '
                         f'{len(pending.msg.points)} points (digest {pending.digest[:12]})')

    def relays_of(self, digest: str) -> int:
        """Return how many trajectories of ``digest`` came out on ``trajectory_out`` so far."""
        with self._condition:
            return self._relays.get(digest, 0)

    def is_relayed(self, pending: PendingTrajectory) -> bool:
        with self._condition:
            return bool(pending.relay_rank) and \
                self._relays.get(pending.digest, 0) >= pending.relay_rank

    # -- the scene, clouds, parameters: one at a time -------------------------------------------

    def _status(self, which: str, since: int, done) -> Optional[tuple]:
        for stamp, name, values in self._statuses[since:]:
            if name == which and done(values):
                return stamp, values
        return None

    def send_scene(self, scene=None, *, markers: Sequence[Marker] = (), frame: str = '',
                   touch: Sequence[str] = (), timeout: float = TIMEOUT) -> SceneAnswer:
        """Send one scene array and return the node's answer.

        :param scene: a scene file's path or the dict it parses to: its objects are added (or
            replaced), attached to ``frame`` if given, allowed to touch ``touch``.
        :param markers: markers to send (after the scene's): moves, ``DELETE``, ``DELETEALL``.
        """
        array = MarkerArray(markers=(scene_markers(scene, dict(
            entry.split('=', 1) for entry in self.package_paths), frame, touch)
            if scene is not None else []) + list(markers))
        with self._condition:
            since_status, since_verdict = len(self._statuses), len(self._pairs)
            self._scenes_sent += 1
            count = self._scenes_sent
        self._scene.publish(array)
        stamp, values = self.wait(
            lambda: self._status('scene', since_status,
                                 lambda v: (handled_total(v, SCENE_COUNTS) or 0) >= count),
            timeout, f'no scene status counting scene array {count}')
        applied = int(values['scene_arrays_applied_total'])
        answered = int(values.get('scene_verdicts_total', '0'))
        with self._condition:
            verdict_given = answered > self._scene_verdicts
            before, self._scenes_applied, self._scene_verdicts = (
                self._scenes_applied, applied, answered)
        verdict = None
        if verdict_given:
            index = self.wait(lambda: (self._own_verdicts(since_verdict, stamp) or [None])[-1],
                              timeout, f'no verdict on scene array {count}')
            verdict = self._verdict_at(index)
        objects = tuple(filter(None, values.get('objects', '').split(', ')))
        return SceneAnswer(applied > before, '' if applied > before else
                           values.get('last_rejection', ''), objects, verdict)

    def send_cloud(self, points, frame: Optional[str] = None, topic: Optional[str] = None,
                   timeout: float = TIMEOUT) -> CloudAnswer:
        """Publish one point cloud and return the node's answer.

        :param points: ``(n, 3) float`` in ``frame``.
        :param frame: a link of the robot (default: its root link).
        :param topic: one of the node's ``point_cloud_topics`` (default: the first).
        """
        topics = list(self._values.get('point_cloud_topics') or ())
        topic = topic or (topics[0] if topics else '')
        if topic not in topics:
            raise ConfigError(f'cloud topic "{topic}" is not one of the node\'s '
                              f'point_cloud_topics {topics}; start the sensor with '
                              'parameters={"point_cloud_topics": ["' +
                              (topic or 'camera/points') + '"]}')
        publisher = self._cloud_publishers.get(topic)
        if publisher is None:
            publisher = self.client.create_publisher(PointCloud2, topic, qos_profile_sensor_data)
            self._cloud_publishers[topic] = publisher
            self.wait(lambda: publisher.get_subscription_count() > 0, timeout,
                      f'the node did not subscribe to {topic}')
        frame = frame if frame is not None else self.node.checker.model.root_link
        stamp = self._stamp()
        data = cdr_from_points(np.asarray(points, dtype=np.float64).reshape(-1, 3),
                               stamp.sec, stamp.nanosec, frame)
        with self._condition:
            since_status, since_verdict = len(self._statuses), len(self._pairs)
            self._clouds_sent[topic] = count = self._clouds_sent.get(topic, 0) + 1
            accepted_before = self._clouds_accepted.get(topic, 0)
        publisher.publish(data)
        status_name = f'point cloud {topic}'

        def answered():     # a verdict when the node takes it; its status counts it anyway
            own = self._own_verdicts(since_verdict, timed_out=topic)
            if own:
                return 'verdict', own[0]
            found = self._status(status_name, since_status,
                                 lambda v: (handled_total(v, CLOUD_COUNTS) or 0) >= count)
            return found and ('status', found[1])
        how, found = self.wait(answered, timeout, f'no answer to cloud {count} on {topic}')
        if how == 'verdict':
            self._clouds_accepted[topic] = accepted_before + 1
            return CloudAnswer(True, '', self._verdict_at(found))
        self._clouds_accepted[topic] = int(found['clouds_accepted_total'])
        if self._clouds_accepted[topic] == accepted_before:
            return CloudAnswer(False, found.get('last_rejection', ''), None)
        verdict = None
        if self._checked:       # taken with a state checked: its verdict is on the way
            index = self.wait(lambda: (self._own_verdicts(since_verdict, timed_out=topic)
                                       or [None])[0],
                              timeout, f'no verdict on cloud {count} on {topic}')
            verdict = self._verdict_at(index)
        return CloudAnswer(True, '', verdict)

    def set_parameters(self, timeout: float = TIMEOUT, **values) -> Optional[Verdict]:
        """Set parameters through the node's parameter service, as ``ros2 param set`` does;
        return the verdict the node gives on the change (None before a state was checked:
        pass parameters that rebuild the checker, such as ``padding``, at start instead).

        :raises ConfigError: the node refused a value (its reason).
        """
        client = self._parameters()
        with self._condition:
            since_verdict = len(self._pairs)
        future = client.set_parameters([Parameter(name, value=value)
                                        for name, value in values.items()])
        self.wait(future.done, timeout, 'no answer from the parameter service')
        refused = [f'{name}: {result.reason}' for name, result
                   in zip(values, future.result().results) if not result.successful]
        if refused:
            raise ConfigError('the node refused ' + '; '.join(refused))
        if not self._checked:
            return None
        index = self.wait(lambda: (self._own_verdicts(since_verdict) or [None])[0], timeout,
                          f'no verdict on the parameter change {", ".join(values)}')
        return self._verdict_at(index)

    def get_parameter(self, name: str, timeout: float = TIMEOUT):
        """Return a parameter's value from the node's parameter service."""
        future = self._parameters().get_parameters([name])
        self.wait(future.done, timeout, 'no answer from the parameter service')
        return parameter_value_to_python(future.result().values[0])

    def _parameters(self) -> AsyncParameterClient:
        if self._parameters_client is None:
            client = AsyncParameterClient(self.client, self.node.get_fully_qualified_name())
            self.wait(client.services_are_ready, TIMEOUT, 'the parameter services did not '
                      'come up')
            self._parameters_client = client
        return self._parameters_client


def running_sensor(robot: Union[str, os.PathLike] = 'panda', **options) -> SensorUnderTest:
    """Return a sensor to use in a ``with`` block: started on entry, stopped on exit.

    ``with running_sensor('panda', scene='table.yaml') as sensor: ...``; the options are
    :class:`SensorUnderTest`'s.
    """
    return SensorUnderTest(robot, **options)
