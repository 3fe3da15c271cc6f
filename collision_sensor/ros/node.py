"""The ROS 2 node: joint states in, a collision verdict out (run it as ``collision_sensor_node``,
:mod:`collision_sensor.ros.main`).

The node is the sensor (:class:`collision_sensor.sensor.Sensor`, no ROS in it: every rule of
what an input is answered with) put on the ROS graph. It composes:

================================ ================================================================
:mod:`.joint_state_source`       ``joint_states``: the compiled hop, or rclpy, into the sensor
:mod:`.scene_source`             ``scene``: objects added, moved, removed at run time
:mod:`.trajectory_source`        ``trajectory``: planned trajectories checked, valid ones relayed
:mod:`.point_cloud_source`       each of ``point_cloud_topics``: obstacles from depth sensors
:mod:`.verdict_topics`           ``contact``, ``colliding_pairs``, ``near``, ``min_distance``,
                                 ``near_pairs``: the answers, as the sensor serialized them
:mod:`.markers`                  ``~/markers``
:mod:`.diagnostics`              ``/diagnostics``
:mod:`.model_loading`            building checkers, swapping a new one in while running
:mod:`.runtime_parameters`       parameters set while the node runs
:mod:`.node_parameters`          the parameters declared on the graph
:mod:`.node_log`, :mod:`.work_queue` throttled logging; the threads of the slow inputs
================================ ================================================================

Each source parses and validates its topic and hands the data to the sensor; the sensor
answers and publishes through the answer topics. The node itself builds the robot, applies
parameters, and asks, on timers, for what nobody sends: timeouts (stale joint states, silent
cameras), ``/diagnostics``, markers.

Threads: joint states are taken and answered on the hop's own thread (C++, no Python: take,
merge, check, serialize, publish), or, without the hop, on a thread of the joint state source;
scene arrays, clouds and trajectories each on a thread of their own source (the latter two at a
lower priority); new checkers are built on the loader thread (joint states are answered
meanwhile); timers and parameters on the executor's thread. The sensor's core holds a mutex for
the short time it answers or a checker change is committed; a long change is prepared without
it. Answers are published, in the order they are made, while it is held.

Start-up: the robot is loaded, all its collision trees built and the query run once before the
node subscribes to ``joint_states``; then it logs one line starting ``ready:``. With the robot
from ``robot_description`` the same happens when the first description has been built.

Failure policy: bad configuration (a bad value, or a parameter the node does not have) raises
:class:`~collision_sensor.ConfigError` (or another :class:`~collision_sensor.CollisionSensorError`)
from the constructor after logging the reason, and ``main`` exits with status 1. Once running,
nothing a message carries stops the node, and nothing goes quiet on "clear" (the sensor's rules:
``cpp/sensor_core.hpp``); a bad ``robot_description`` is rejected with an error and the current
model stays. Names and texts from the network reach logs and ``/diagnostics`` only escaped and
bounded (:mod:`collision_sensor.untrusted_text`, ``cpp/sensor_text.hpp``).
"""
import collections
import contextlib
import os
import threading
import time
from typing import Callable, List, Optional

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import (
    Executor, ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor)
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Header, String

from collision_sensor.errors import CollisionSensorError
from collision_sensor.model.xml_safety import document_bytes
from collision_sensor.ros.diagnostics import DIAGNOSTICS_PERIOD, sensor_status
from collision_sensor.ros.input_source import stamp_now
from collision_sensor.ros.joint_state_source import (  # noqa: F401 - the node's public names
    JOINT_STATES_QOS, RELIABLE_INPUT_QOS, JointStateSource)
from collision_sensor.ros.markers import (  # noqa: F401
    ATTACHED_OBJECT_COLOR, COLLIDING_OBJECT_COLOR, MARKER_COLOR, WORLD_OBJECT_COLOR,
    MarkerPublisher, quaternion_from_matrix)
from collision_sensor.ros.model_loading import (
    MAX_ROBOT_DESCRIPTION_BYTES, MODEL_POLL_PERIOD, ModelLoader, build_checker,
    default_checker_factory)
from collision_sensor.ros.node_log import WARNING_PERIOD, NodeLog  # noqa: F401
from collision_sensor.ros.node_parameters import NodeSettings, declare_node_parameters
from collision_sensor.ros.point_cloud_source import PointCloudSource
from collision_sensor.ros.runtime_parameters import CHECKER_PARAMETERS, RuntimeParameters
from collision_sensor.ros.scene_source import (  # noqa: F401
    MAX_SCENE_BACKLOG, SCENE_DEPTH, SCENE_QOS, SceneSource)
from collision_sensor.ros.trajectory_source import TrajectorySource
from collision_sensor.ros.verdict_topics import (  # noqa: F401
    LATCHED_QOS, VERDICT_DEPTH, VERDICT_QOS, ZONE_TOPICS, VerdictTopics)
from collision_sensor.ros.work_queue import MAX_BACKLOG, MAX_INPUT_RATE  # noqa: F401
from collision_sensor.sensor import Sensor
from collision_sensor.sensor.model import root_link
from collision_sensor.tools.srdf_advice import srdf_advice
from collision_sensor.untrusted_text import printable

CheckerFactory = Callable[..., object]
#: s between two looks at the timeouts (stale joint states, silent cameras), the sensor's log
#: lines and the markers.
POLL_PERIOD = 0.05


class CollisionSensorNode(Node):
    """Check every joint state for collisions and publish the verdict.

    :param node_name: the node's name.
    :param checker_factory: builds a checker, called as ``factory(urdf, srdf=, package_paths=,
        scene=, config=)`` with ``urdf`` a path (from ``urdf_path``) or the document as
        ``bytes`` (from ``robot_description``: never a path); default
        ``CollisionChecker.from_urdf``.
    :param kwargs: passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ...).
    :raises CollisionSensorError: bad configuration (the reason is logged first).
    :ivar sensor: the :class:`~collision_sensor.sensor.Sensor` answering.
    :ivar settings: the parameters applied.
    """

    def __init__(self, node_name: str = 'collision_sensor', *,
                 checker_factory: Optional[CheckerFactory] = None, **kwargs):
        super().__init__(node_name, **kwargs)
        self._factory = checker_factory or default_checker_factory
        self.log = NodeLog(self.get_logger(), self.context.ok, time.monotonic)
        # The node's own state (the robot it loads, the parameters asked for, its counts),
        # between the executor's and the loader's threads. Never held while logging or while
        # the sensor answers.
        self.lock = threading.Lock()
        self.totals = collections.Counter()
        self.model_source = ''
        self.ready = False
        self.rebuilding = False      # a parameter change waits for its new checker
        self.sensor: Optional[Sensor] = None
        self.sources: list = []
        self.joints: Optional[JointStateSource] = None
        self.topics = self.markers = None
        self._loader: Optional[ModelLoader] = None
        self._robot_input = None     # the urdf_path or robot_description the checker is of
        self._new_robot = None       # a robot_description waiting to be built
        self._built_values = {}      # the parameter values the checker in use was built with
        self._period_started = time.monotonic()     # of /diagnostics' period
        try:
            self._configure()
        except Exception as error:  # noqa: B902 - logged, then raised to the caller as it is
            self.get_logger().fatal(f'configuration failed: {printable(error, 2000)}')
            self.destroy_node()
            raise

    @property
    def checker(self):
        """The checker answering (None before the first robot)."""
        return self.sensor.checker if self.sensor is not None else None

    @property
    def root_frame(self) -> str:
        checker = self.checker
        return root_link(checker) if checker is not None else ''

    def _configure(self) -> None:
        self.settings: NodeSettings = declare_node_parameters(self)
        self.requested_settings = settings = self.settings
        self.topics = VerdictTopics(self, settings.warning_distance > 0)
        self.sensor = Sensor(None, settings, publish=self.topics.publish)
        self.markers = MarkerPublisher(self, settings.publish_markers)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.sources = self._make_sources()
        self._loader = ModelLoader(self._build_and_install)
        # Finished builds are taken up from a timer on the executor's thread; not from a guard
        # condition, which rclpy's EventsExecutor (7.1.5) refuses.
        self.create_timer(MODEL_POLL_PERIOD, self._on_model_loaded)
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self.create_timer(POLL_PERIOD, self._poll)
        self._runtime = RuntimeParameters(self)
        self.add_on_set_parameters_callback(self._runtime.on_set)
        if settings.urdf_path:
            notes = []
            checker = build_checker(self._factory, settings.urdf_path, settings, notes)
            self._install(checker, settings.urdf_path, f'urdf_path "{settings.urdf_path}"',
                          settings, notes)
            self.log.write(notes)
            self._start_sources()       # the last step: joint states are answered from here on
        else:
            self.create_subscription(String, 'robot_description', self._on_robot_description,
                                     LATCHED_QOS)
            self.get_logger().info('waiting for the robot on robot_description')

    def _make_sources(self) -> list:
        """The node's inputs (see :mod:`collision_sensor.ros.input_source`): one line each."""
        sensor, settings, log, markers = self.sensor, self.settings, self.log, self.markers
        self.joints = JointStateSource(self, sensor, self.topics, settings, log)
        self.scene = SceneSource(self, sensor, settings, log, markers, self._diagnostics_pub)
        self.trajectories = TrajectorySource(self, sensor, settings, log, markers)
        return [self.joints, self.scene, self.trajectories] + [
            PointCloudSource(self, sensor, topic, settings, log, markers)
            for topic in settings.point_cloud_topics]

    def _start_sources(self) -> None:
        """Subscribe every source (once a model is in place), the joint states last (the hop
        answers them from its start), and announce that the node is up."""
        for source in self.sources[1:] + self.sources[:1]:
            source.start()
        self.ready = True
        joints = self.joints
        way = ('the compiled hop' if joints.way_in == 'compiled'
               else f'rclpy ({joints.rclpy_reason})')
        self.get_logger().info(
            f'ready: checking {joints.topic_name} ({self.settings.joint_states_qos}) for '
            f'{printable(self.model_source, 300)}; verdicts on '
            f'{self.resolve_topic_name("contact")} and '
            f'{self.resolve_topic_name("colliding_pairs")}; joint states taken by {way}')

    # -- the model ----------------------------------------------------------------------------

    def _install(self, checker, robot, source: str, settings: NodeSettings, notes: list) -> None:
        """Make ``checker`` (of ``robot``, built with ``settings``) the one in use: the sources
        hand it their data, then it replaces the current one at once, between two answers; the
        newest parameters are applied at the same moment."""
        sensor = self.sensor
        loaded = []
        # A new robot (not a parameter change's rebuild) whose links are in contact by design:
        # the command that writes its SRDF.
        advice = srdf_advice(checker, robot, settings.srdf_path, settings.package_paths,
                             settings.xacro_args) if robot is not self._robot_input else None
        with sensor.editing():
            commits = [commit for commit in (s.prepare_model(checker) for s in self.sources)
                       if commit is not None]
            with sensor.changing():
                sensor.use_checker(checker)
                for commit in commits:
                    commit(loaded)
                self.markers.forget(root_link(checker))
            with self.lock:
                self._robot_input = robot
                self._built_values = {name: settings.values.get(name)
                                      for name in CHECKER_PARAMETERS}
                self.model_source = source
                newest = self.requested_settings
            # The newest parameters (some may have changed during the build).
            if newest is not self.settings:
                self._apply_settings(newest, loaded)
        summary = (f'{len(checker.joint_names)} joints, {len(checker.link_names)} links with '
                   f'geometry, {len(checker.checked_pairs)} pairs checked')
        notes[:0] = [('info', None, f'robot loaded from {printable(source, 300)}: {summary}')]
        notes.extend(loaded)
        notes.extend([('warning', None, printable(advice, 3000))] if advice else [])

    def _build_and_install(self) -> None:
        """The loader thread: build the newest robot with the newest parameters, install it."""
        with self.lock:
            robot = self._new_robot if self._new_robot is not None else self._robot_input
            settings = self.requested_settings
            new_robot = robot is self._new_robot
        if robot is None:
            return      # no robot yet: its first build takes the parameters
        notes = []
        try:
            checker = build_checker(self._factory, robot, settings, notes)
            self._install(checker, robot, 'robot_description' if isinstance(robot, bytes)
                          else f'urdf_path "{robot}"', settings, notes)
        except Exception as error:  # noqa: B902 - any failure rejects this build
            with self.lock:
                if self._new_robot is robot:
                    self._new_robot = None
            self._loader.results.append((notes, error, new_robot))
            return
        with self.lock:
            if self._new_robot is robot:
                self._new_robot = None
            pending = settings is not self.requested_settings or self._new_robot is not None
            self.rebuilding = self.rebuilding and pending
        self._loader.results.append((notes, None, new_robot))

    def _on_robot_description(self, msg: String) -> None:
        try:
            # Content only: bytes are always parsed as the document, never opened as a path.
            document = document_bytes(msg.data, 'URDF', MAX_ROBOT_DESCRIPTION_BYTES)
        except CollisionSensorError as error:
            with self.lock:
                self.totals['robot_description_rejected'] += 1
            keep = 'the current model stays' if self.checker is not None else 'no robot yet'
            self.log.warn('robot_description', f'robot_description rejected: {error}; {keep}',
                          'error')
            return
        self.get_logger().info(f'robot_description received ({len(document)} bytes); '
                               'loading it while the current model stays in use')
        with self.lock:
            self._new_robot = document
        self._loader.request()

    def _on_model_loaded(self) -> None:
        """Take up finished builds (the executor's thread): log them, subscribe after the first
        model, put parameters back when a new checker for them could not be built."""
        results = self._loader.results if self._loader is not None else ()
        while results:
            notes, error, new_robot = results.popleft()
            self.log.write(notes)
            if error is None:
                if not self.ready:
                    self._start_sources()
                elif not new_robot:
                    self._answer_current()
                continue
            if new_robot:
                with self.lock:
                    self.totals['robot_description_rejected'] += 1
                keep = ('the current model stays' if self.checker is not None
                        else 'still no robot model')
                self.get_logger().error(
                    f'robot_description rejected: {printable(error, 2000)}; {keep}')
            else:
                self._revert_checker_parameters(error)

    def _revert_checker_parameters(self, error: Exception) -> None:
        with self.lock:
            self.rebuilding = False
            built, requested = self._built_values, self.requested_settings.values
        back = [Parameter(name, value=built[name]) for name in CHECKER_PARAMETERS
                if name in built and requested.get(name) != built[name]]
        self.get_logger().error(
            f'parameters {", ".join(p.name for p in back)} could not be applied: no checker '
            f'could be built with them ({printable(error, 1000)}); set back to the values in use')
        if back:
            self.set_parameters(back)

    def pending_names(self) -> List[str]:
        """The names ``allowed_collisions`` and ``warning_ignore`` give that are neither a link
        nor a scene object yet: kept for an object of that name."""
        checker = self.checker
        if checker is None:
            return []
        known = set(checker.kinematics.link_names) | set(checker.object_names)
        names = set(getattr(checker, 'pending_allowed_names', ()))
        names.update(name for pair in self.settings.warning_ignore for name in pair)
        return sorted(names - known)

    # -- parameters set at run time -----------------------------------------------------------

    def change_settings(self, settings: NodeSettings, changed: str) -> None:
        """Take validated parameters (``runtime_parameters``): apply them now, or build a new
        checker with them first."""
        with self.lock:
            current = self.requested_settings
            self.requested_settings = settings
            # Without a robot yet, its first build takes the new values.
            rebuild = (settings.checker_config != current.checker_config
                       and self.checker is not None)
            if rebuild:
                self.rebuilding = True
        if rebuild:
            self.get_logger().info(f'parameters set: {changed}; building a new checker with '
                                   'them, the current one answers meanwhile')
            self._loader.request()
            return
        notes = []
        with self.sensor.editing():
            self._apply_settings(settings, notes)
        self.log.write(notes)
        self.get_logger().info(f'parameters applied: {changed}')
        self._answer_current()

    def _apply_settings(self, settings: NodeSettings, notes: list) -> None:
        """Apply ``settings`` all at once: the warning zone's topics are advertised before the
        sensor answers with them and withdrawn after it stopped."""
        zone = settings.warning_distance > 0
        if zone and not self.topics.zone:
            self.topics.advertise_zone()
            self.joints.bind_publishers()
        self.sensor.configure(settings)
        if not zone and self.topics.zone:
            self.joints.bind_publishers(without=ZONE_TOPICS)
            self.topics.withdraw_zone()
        self.markers.enable(settings.publish_markers)
        for source in self.sources:
            source.apply_settings(settings)
        self.settings = settings
        with self.lock:
            self.totals['parameter_changes'] += 1

    def _answer_current(self) -> None:
        """Answer a change (parameters, a new checker) by a verdict at the current state."""
        self.sensor.answer_current(stamp_now(self))
        self.log.write(self.sensor.notes())

    def count_reader_error(self, error: Exception) -> None:
        """Count and report an input the executor could not take (see :func:`spin`)."""
        with self.lock:
            self.totals['reader_errors'] += 1
        self.log.warn('reader', 'message skipped: it could not be taken from the middleware '
                      f'({printable(repr(error), 300)}); counted as skipped_reader_error')

    # -- timeouts, log lines, markers, diagnostics -----------------------------------------------

    def _poll(self) -> None:
        """Fail safe on inputs gone silent (stale joint states, a camera's timeout), write the
        sensor's log lines, refresh the markers."""
        stamp = stamp_now(self)
        now = time.monotonic()
        try:
            self.sensor.poll(stamp)
            for source in self.sources:
                source.poll_timeout(now, stamp)
            self.joints.poll_events()
            self.markers.refresh(self.sensor)
        except Exception as error:  # noqa: B902 - a timer must never stop the node
            if not self.context.ok():
                return
            self.log.warn('poll', 'timeouts skipped after an internal error: '
                          f'{printable(repr(error), 300)}', 'error')
        self.log.write(self.sensor.notes())

    @property
    def model_loading(self) -> bool:
        return self._loader is not None and (self._loader.loading or bool(self._loader.results))

    def publish_diagnostics(self, statuses: list) -> None:
        """Publish ``statuses`` on /diagnostics now."""
        self._diagnostics_pub.publish(DiagnosticArray(
            header=Header(stamp=self.get_clock().now().to_msg()), status=statuses))

    def _publish_diagnostics(self) -> None:
        try:
            now = time.monotonic()
            snapshot = self.sensor.snapshot(reset_period=True)
            elapsed, self._period_started = now - self._period_started, now
            statuses = [sensor_status(self, snapshot, elapsed)]
            for source in self.sources:
                status = source.status(now)
                if status is not None:
                    statuses.append(status)
            self.publish_diagnostics(statuses)
        except Exception as error:  # noqa: B902 - diagnostics must never stop the node
            self.log.warn('diagnostics', 'diagnostics skipped after an internal error: '
                          f'{printable(repr(error), 300)}')

    def destroy_node(self):
        """Stop the sources (the joint states first: the hop publishes on the node's
        publishers) and the model loader, then destroy the node."""
        for source in self.sources:
            with contextlib.suppress(Exception):
                source.close()
        if self._loader is not None:
            self._loader.close()
            self._loader = None
        if self.sensor is not None:
            self.sensor.set_publish(None)
        return super().destroy_node()


def start(args=None, dds_profile: Optional[str] = None):
    """Initialise rclpy and build the node; return ``(node, None)`` or ``(None, 1)``.

    ``collision_sensor_node`` (:func:`collision_sensor.ros.main.main`) calls this on a start-up
    thread and :func:`spin` on the main thread.

    :param dds_profile: the Fast DDS profile the console script applied (logged), or None.
    """
    rclpy.init(args=args)
    try:
        node = CollisionSensorNode()
        if dds_profile is not None:
            node.get_logger().info(
                f'Fast DDS profile {dds_profile}: readers free each sample once taken '
                '(COLLISION_SENSOR_DDS_PROFILE=off leaves the middleware defaults)')
        return node, None
    except CollisionSensorError:
        rclpy.try_shutdown()
        return None, 1    # the node logged the reason


#: s an executor turn waits at most: a stop is noticed at least this often.
SPIN_PERIOD = 0.1
#: Executors :func:`spin` can use (``COLLISION_SENSOR_EXECUTOR``); the first is the default.
EXECUTORS = ('events', 'single', 'multi')


def make_executor(context, kind: Optional[str] = None) -> Executor:
    """Return the executor the node spins in.

    ``events`` (default): rclpy's ``EventsExecutor`` (``rclpy.experimental``, in rclpy 7.1 and
    later), which takes each message as the middleware signals it, without rebuilding a wait
    set per turn; chosen by measurement (``python -m benchmarks.node_latency --executor``).
    Where it is missing, ``single`` (``SingleThreadedExecutor``) is used.
    ``multi`` is a two-thread ``MultiThreadedExecutor``.

    :param kind: one of :data:`EXECUTORS`; default ``$COLLISION_SENSOR_EXECUTOR`` or ``events``.
    """
    kind = kind or os.environ.get('COLLISION_SENSOR_EXECUTOR') or EXECUTORS[0]
    if kind not in EXECUTORS:
        raise ValueError(f'executor "{kind}" is not one of {", ".join(EXECUTORS)}; '
                         'fix COLLISION_SENSOR_EXECUTOR')
    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:     # rclpy before 7.1
            kind = 'single'
        else:
            return EventsExecutor(context=context)
    if kind == 'multi':
        return MultiThreadedExecutor(num_threads=2, context=context)
    return SingleThreadedExecutor(context=context)


def spin(node, stopped: Callable[[], bool] = lambda: False) -> int:
    """Spin ``node`` until shutdown (rclpy's signal handlers shut the context down); return 0.

    An executor turn that fails while the node runs (a message the middleware cannot hand
    over) is counted as ``skipped_reader_error`` and spinning goes on.

    :param stopped: returns True once a stop was requested (checked before spinning).
    """
    executor = make_executor(node.context)
    try:
        if not stopped():
            executor.add_node(node)
            while node.context.ok() and not stopped():
                try:
                    # spin_once in a loop, as rclpy.spin does: EventsExecutor.spin() (rclpy
                    # 7.1.5) keeps the interpreter lock and ignores a shutdown.
                    executor.spin_once(timeout_sec=SPIN_PERIOD)
                except (KeyboardInterrupt, ExternalShutdownException):
                    break
                except Exception as error:  # noqa: B902
                    # rclpy (Jazzy) can fail to build its next wait set when a signal shuts the
                    # context down in the middle of an executor turn: that is the stop asked
                    # for, not an error.
                    if not node.context.ok() or stopped():
                        break
                    node.count_reader_error(error)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        executor.shutdown()
    return 0
