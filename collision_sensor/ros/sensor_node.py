"""The ROS 2 node: joint states in, a collision verdict out (run it as ``collision_sensor_node``,
:mod:`collision_sensor.ros.node`).

The node composes its parts and converts messages and parameters; each part is a module of one
concern:

================================ ================================================================
:mod:`.input_source`             the source abstraction: one class per kind of input
:mod:`.joint_state_source`       ``joint_states``: merging, validation, the answer to each
:mod:`.scene_source`             ``scene``: objects added, moved, removed at run time
:mod:`.trajectory_source`        ``trajectory``: planned trajectories checked, valid ones relayed
:mod:`.motion_stream`            ``check_motion``: verdicts on the motion from the state before
:mod:`.verdicts`                 ``contact``, ``colliding_pairs``, the fail-safe answers
:mod:`.warning_zone`             ``near``, ``min_distance``, ``near_pairs``; pairs always near
:mod:`.markers`                  ``~/markers``
:mod:`.diagnostics`              ``/diagnostics``
:mod:`.model_loading`            building checkers, swapping a new one in while running
:mod:`.runtime_parameters`       parameters set while the node runs
:mod:`.node_parameters`          the parameters, validated (no rclpy)
:mod:`.node_log`, :mod:`.work_queue` throttled logging; the checking and scene threads
================================ ================================================================

The checking is :class:`CollisionChecker`'s, the merging of joint states
:mod:`collision_sensor.ros.joint_state_merger`'s.

Topics (relative, so ``-r __ns:=/robot`` moves them):

=================== ==== =================================== ====================================
topic               dir  type                                QoS
=================== ==== =================================== ====================================
joint_states        in   sensor_msgs/JointState              sensor data, or reliable keep-all
robot_description   in   std_msgs/String                     reliable, transient local, depth 1
                                                             (only when ``urdf_path`` is empty)
scene               in   visualization_msgs/MarkerArray      reliable, transient local, depth
                                                             :data:`SCENE_DEPTH`
trajectory          in   trajectory_msgs/JointTrajectory     reliable, depth 100
contact             out  std_msgs/Bool                       reliable, transient local, depth 100
colliding_pairs     out  diagnostic_msgs/DiagnosticArray     reliable, transient local, depth 100
near                out  std_msgs/Bool                       as contact (``warning_distance`` > 0)
min_distance        out  std_msgs/Float64                    as contact (``warning_distance`` > 0)
near_pairs          out  diagnostic_msgs/DiagnosticArray     as contact (``warning_distance`` > 0)
trajectory_result   out  diagnostic_msgs/DiagnosticArray     reliable, volatile, depth 100, one
                                                             per trajectory
trajectory_out      out  trajectory_msgs/JointTrajectory     reliable, depth 10 (valid ones)
~/markers           out  visualization_msgs/MarkerArray      reliable, depth 10 (if enabled)
/diagnostics        out  diagnostic_msgs/DiagnosticArray     reliable, depth 10, once a second
=================== ==== =================================== ====================================

Every joint state is answered by exactly one ``contact`` and then one ``colliding_pairs``
message, in input order; the latter carries the joint state's header (stamp and frame) so a
consumer can tell which input a verdict answers. An accepted joint state that completes the
state gets the verdict of the merged state; one the node refuses or cannot check gets a failure
entry naming the reason, and ``contact`` by the fail-safe policies (:mod:`.verdicts`,
:mod:`.joint_state_source`). With ``warning_distance`` > 0 (the warning zone) the same joint
state then gives one ``near``, one ``min_distance`` and one ``near_pairs`` message
(:mod:`.warning_zone`). No verdict is lost at the documented input rate: the verdict topics keep
the last :data:`VERDICT_DEPTH` (100) messages, 0.1 s at :data:`MAX_INPUT_RATE` (1 kHz), so a
reliable subscriber that keeps its own history at least that deep and falls less than 0.1 s
behind gets every verdict; a late subscriber gets the latest ones. Joint states the node takes
and does not answer (under overload) are counted on ``/diagnostics`` by reason (``skipped_*``),
and so are those the middleware reports lost before the node took them (``lost_total``).

Start-up: the robot is loaded, all its collision trees built and the query run once before
the node subscribes to ``joint_states``; then it logs one line starting ``ready:``. With the
robot from ``robot_description`` the same happens when the first description has been built.
Names and texts from the network reach logs and ``/diagnostics`` only through
:mod:`collision_sensor.untrusted_text` (escaped, bounded), and no log line is written while the
node's lock is held.

Failure policy: bad configuration (a bad value, or a parameter the node does not have) raises
:class:`~collision_sensor.ConfigError` (or another :class:`~collision_sensor.CollisionSensorError`)
from the constructor after logging the reason, and ``main`` exits with status 1. Once running,
nothing a message carries stops the node, and nothing goes quiet on "clear": a bad joint state
is answered as refused (``on_rejected_input``), an engine error as such (``on_engine_error``,
the merge undone, the next state checked from scratch, /diagnostics ERROR until a state is
checked again), silent input as stale (``stale_policy``, /diagnostics ERROR); a bad
``robot_description`` is rejected with an error and the current model stays.

Threads: the executor (:func:`make_executor`: rclpy's ``EventsExecutor`` where available) takes
joint states and hands each to the checking thread, which merges, checks and publishes; scene
arrays are applied on a scene thread; trajectories are checked on a trajectory thread; new
checkers are built on a loader thread (checking goes on meanwhile); everything else runs on the
executor's thread. One lock keeps the model, the merged state and the counters consistent. Only
rclpy's public API is used, but for one read in
:func:`~collision_sensor.ros.node_parameters.unknown_overrides`.

Input QoS: ``joint_states_qos: sensor_data`` (best effort, keep last 5, rclpy's
``qos_profile_sensor_data``) for drivers that publish best effort: under overload the
middleware drops the oldest samples, and what it reports lost is counted as ``lost_total``.
``reliable`` (keep all) for recorded replay and for publishers that must not lose a state:
the publisher is slowed down by flow control rather than losing messages. Either way, once
more than :data:`MAX_BACKLOG` states wait for the checking thread, it answers only the newest
and counts the rest as ``skipped_superseded``: the node stays current instead of answering
states that are already old.
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
from collision_sensor.ros.diagnostics import DIAGNOSTICS_PERIOD, PeriodStats, sensor_status
from collision_sensor.ros.input_source import TIMEOUT_POLL_PERIOD, InputSource, prepare_all
from collision_sensor.ros.joint_state_source import (  # noqa: F401 - the node's public names
    JOINT_STATES_QOS, RELIABLE_INPUT_QOS, JointStateSource)
from collision_sensor.ros.markers import (  # noqa: F401
    ATTACHED_OBJECT_COLOR, COLLIDING_OBJECT_COLOR, MARKER_COLOR, WORLD_OBJECT_COLOR,
    MarkerPublisher, quaternion_from_matrix)
from collision_sensor.ros.model_loading import (
    MAX_ROBOT_DESCRIPTION_BYTES, MODEL_POLL_PERIOD, ModelLoader, build_checker,
    default_checker_factory, root_link)
from collision_sensor.ros.motion_stream import ENGINE_ERROR as MOTION_ENGINE_ERROR
from collision_sensor.ros.motion_stream import MotionStream
from collision_sensor.ros.node_log import WARNING_PERIOD, NodeLog  # noqa: F401
from collision_sensor.ros.node_parameters import (
    CONTACT, NodeSettings, declare_node_parameters)
from collision_sensor.ros.point_cloud_source import PointCloudSource
from collision_sensor.ros.runtime_parameters import CHECKER_PARAMETERS, RuntimeParameters
from collision_sensor.ros.scene_source import (  # noqa: F401
    MAX_SCENE_BACKLOG, SCENE_DEPTH, SCENE_QOS, SceneSource)
from collision_sensor.ros.trajectory_source import TrajectorySource
from collision_sensor.ros.verdicts import (  # noqa: F401
    ENGINE_ERROR, LATCHED_QOS, VERDICT_DEPTH, VERDICT_QOS, VerdictPublisher, failure_status)
from collision_sensor.ros.warning_zone import WarningZone
from collision_sensor.ros.work_queue import (  # noqa: F401
    MAX_BACKLOG, MAX_INPUT_RATE, NewestFirstWorker as _NewestFirstWorker)
from collision_sensor.tools.srdf_advice import srdf_advice
from collision_sensor.untrusted_text import printable

CheckerFactory = Callable[..., object]


class CollisionSensorNode(Node):
    """Check every joint state for collisions and publish the verdict.

    The host of the sources (:class:`~collision_sensor.ros.input_source.SourceHost`).

    :param node_name: the node's name.
    :param checker_factory: builds a checker, called as ``factory(urdf, srdf=, package_paths=,
        scene=, config=)`` with ``urdf`` a path (from ``urdf_path``) or the document as
        ``bytes`` (from ``robot_description``: never a path); default
        ``CollisionChecker.from_urdf``. Tests inject one that adds faults.
    :param kwargs: passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ...).
    :raises CollisionSensorError: bad configuration (the reason is logged first).
    :ivar checker: the checker in use (None before the first robot).
    :ivar settings: the parameters applied.
    :ivar engine_error: the last engine error, '' once a state was checked after it.
    """

    def __init__(self, node_name: str = 'collision_sensor', *,
                 checker_factory: Optional[CheckerFactory] = None, **kwargs):
        super().__init__(node_name, **kwargs)
        self._factory = checker_factory or default_checker_factory
        # Joint states are handled on the checking thread, scene arrays on the scene thread,
        # new checkers installed from the loader thread, the rest on the executor's: this lock
        # keeps the model, the merged state and the counters consistent between them. Nothing
        # is logged while it is held (logging can block on a slow stdout): log lines are
        # collected as notes and written after the lock is released.
        self.lock = threading.Lock()
        # Held from preparing a change of the checker's scene (or a new checker) until it is
        # committed, and by a reader that must see one scene throughout without holding the
        # lock (a trajectory check): taken before the lock, never while holding it.
        self.checker_changes = threading.Lock()
        self.log = NodeLog(self.get_logger(), self.context.ok, time.monotonic)
        self.checker = None
        self.root_frame = ''
        self.model_source = ''
        self.ready = False
        self.totals = collections.Counter()
        self.period = PeriodStats()
        self.engine_error = ''
        self._resync = False     # check the next state from scratch (after an engine error)
        self.motion = MotionStream()     # check_motion: the motion's start
        self.rebuilding = False  # a parameter change waits for its new checker
        self.sources: List[InputSource] = []
        # Sources timed out with the contact policy that must answer every verdict with their
        # failure until they recover ({source name: Timeout}; point clouds: joint states keep
        # coming while a camera is silent).
        self.failing = {}
        self.joints: Optional[JointStateSource] = None
        self.verdicts = self.zone = self.markers = None
        self._loader: Optional[ModelLoader] = None
        self._robot_input = None     # the urdf_path or robot_description the checker is of
        self._new_robot = None       # a robot_description waiting to be built
        self._built_values = {}      # the parameter values the checker in use was built with
        try:
            self._configure()
        except Exception as error:  # noqa: B902 - logged, then raised to the caller as it is
            self.get_logger().fatal(f'configuration failed: {printable(error, 2000)}')
            self.destroy_node()
            raise

    def _make_sources(self) -> List[InputSource]:
        """The node's inputs (see :mod:`collision_sensor.ros.input_source`): one line each."""
        return [self.joints, SceneSource(self), TrajectorySource(self)] + [
            PointCloudSource(self, topic) for topic in self.settings.point_cloud_topics]

    def _configure(self) -> None:
        self.settings: NodeSettings = declare_node_parameters(self)
        self.requested_settings = settings = self.settings
        self.verdicts = VerdictPublisher(self)
        self.zone = WarningZone(self, settings.warning_distance, settings.warning_ignore)
        self.markers = MarkerPublisher(self) if settings.publish_markers else None
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.joints = JointStateSource(self)
        self.sources = self._make_sources()
        self._loader = ModelLoader(self._build_and_install)
        if settings.urdf_path:
            notes = []
            checker = build_checker(self._factory, settings.urdf_path, settings, notes)
            self._install(checker, settings.urdf_path, f'urdf_path "{settings.urdf_path}"',
                          settings, notes)
            self.log.write(notes)
            self._start_sources()
        else:
            self.create_subscription(String, 'robot_description', self._on_robot_description,
                                     LATCHED_QOS)
            self.get_logger().info('waiting for the robot on robot_description')
        # Finished builds are taken up from a timer on the executor's thread; not from a guard
        # condition, which rclpy's EventsExecutor (7.1.5) refuses.
        self.create_timer(MODEL_POLL_PERIOD, self._on_model_loaded)
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self.create_timer(TIMEOUT_POLL_PERIOD, self._poll_timeouts)
        self._runtime = RuntimeParameters(self)
        self.add_on_set_parameters_callback(self._runtime.on_set)

    def _start_sources(self) -> None:
        """Subscribe every source (once a model is in place) and announce that the node is
        up."""
        for source in self.sources:
            source.start()
        self.ready = True
        self.get_logger().info(
            f'ready: checking {self.joints.subscription.topic_name} '
            f'({self.settings.joint_states_qos}) for {printable(self.model_source, 300)}; '
            f'verdicts on {self.resolve_topic_name("contact")} and '
            f'{self.resolve_topic_name("colliding_pairs")}')

    # -- the model ----------------------------------------------------------------------------

    def _install(self, checker, robot, source: str, settings: NodeSettings, notes: list) -> None:
        """Make ``checker`` (of ``robot``, built with ``settings``) the one in use: the sources
        hand it their data, then it replaces the current one under the lock, between two
        checks; the newest parameters are applied at the same moment."""
        advice = srdf_advice(checker, robot, settings.srdf_path, settings.package_paths,
                             settings.xacro_args) if robot is not self._robot_input else None
        with contextlib.ExitStack() as stack:
            stack.enter_context(self.checker_changes)
            commits = prepare_all(self.sources, checker, stack)
            loaded = []
            with self.lock:
                self.motion.replace_checker(self.checker, checker)
                self.checker, self._robot_input = checker, robot
                self._built_values = {name: settings.values.get(name)
                                      for name in CHECKER_PARAMETERS}
                self.model_source = source
                self.root_frame = root = root_link(checker)
                self.verdicts.forget(root)
                self.zone.forget(root)
                if self.markers is not None:
                    self.markers.clear(root)
                    self.markers.scene_changed = True   # the scene file's objects
                for commit in commits:
                    commit(loaded)
                # The newest parameters (some may have changed during the build).
                if self.requested_settings is not self.settings:
                    self._apply_settings(self.requested_settings, loaded)
        summary = (f'{len(checker.joint_names)} joints, {len(checker.link_names)} links with '
                   f'geometry, {len(checker.checked_pairs)} pairs checked')
        notes[:0] = [('info', None, f'robot loaded from {printable(source, 300)}: {summary}')]
        notes.extend([('warning', None, printable(advice, 3000))] if advice else [])
        notes.extend(loaded)

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
                    self._answer_settings_change()
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
        nor a scene object yet: kept for an object of that name (lock held)."""
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
            else:
                notes = []
                self._apply_settings(settings, notes)
        if rebuild:
            self.get_logger().info(f'parameters set: {changed}; building a new checker with '
                                   'them, the current one answers meanwhile')
            self._loader.request()
            return
        self.log.write(notes)
        self.get_logger().info(f'parameters applied: {changed}')
        self._answer_settings_change()

    def _apply_settings(self, settings: NodeSettings, notes: list) -> None:
        """Apply ``settings`` all at once (lock held)."""
        self.settings = settings
        self.zone.configure(settings.warning_distance, settings.warning_ignore)
        self.zone.forget(self.root_frame)
        if settings.publish_markers and self.markers is None:
            self.markers = MarkerPublisher(self)
            self.markers.root_frame = self.root_frame
        elif not settings.publish_markers and self.markers is not None:
            self.markers.close(self)
            self.markers = None
        for source in self.sources:
            source.apply_settings(settings)
        self.totals['parameter_changes'] += 1

    def _answer_settings_change(self) -> None:
        """Answer a parameter change by a verdict at the current state."""
        notes = []
        with self.lock:
            self.answer_current(notes)
        self.log.write(notes)

    # -- checking (the SourceHost interface) --------------------------------------------------

    def check(self, header, positions) -> None:
        """Check ``positions`` and publish the verdict answering ``header`` (lock held); raise
        what the engine raised, with nothing published."""
        checker = self.checker
        started = time.perf_counter()
        result, motion = self.motion.check(checker, positions, self.joints.last_accepted,
                                           self.settings, self._resync)
        elapsed = time.perf_counter() - started
        zone = self.zone
        # Every engine call before anything is published: a failure publishes nothing.
        records = zone.measure(checker, positions) if zone.enabled else None
        if self._resync:
            self._resync = False
            self.engine_error = ''
        period = self.period
        period.checks += 1
        period.check_time_sum += elapsed
        if elapsed > period.check_time_max:
            period.check_time_max = elapsed
        if self.failing:
            timeout = next(iter(self.failing.values()))
            self._publish_failure(header, timeout.kind, timeout.reason, timeout.policy)
            return
        self.verdicts.publish(header, result, motion)
        if records is not None:
            zone.publish(header, records)
        if self.markers is not None:
            self.markers.publish(checker, header.stamp, result.colliding_pairs, records or ())

    def refuse(self, header, kind: str, reason: str, notes: list) -> None:
        """Answer an input that cannot be checked, by ``on_rejected_input`` (lock held)."""
        self._publish_failure(header, kind, reason, self.settings.on_rejected_input)

    def fail(self, header, error: Exception, notes: list) -> None:
        """Answer a state the engine failed on, by ``on_engine_error`` (lock held; the caller
        undid the merge). /diagnostics says ERROR, and the next state is checked from scratch,
        until a state is checked."""
        self.totals['engine_errors'] += 1
        text = printable(error if isinstance(error, CollisionSensorError) else repr(error), 500)
        self.engine_error, self._resync = text, True
        self.motion.restart(MOTION_ENGINE_ERROR)
        policy = self.settings.on_engine_error
        kind = 'engine' if isinstance(error, CollisionSensorError) else 'internal'
        notes.append(('error', kind, f'collision check failed: {text}; the state stays the '
                      f'last one checked, answered by on_engine_error {policy}'))
        try:
            self._publish_failure(header, ENGINE_ERROR, f'engine error: {text}', policy)
        except Exception:  # noqa: B902 - shutting down: the publishers are gone
            if self.context.ok():
                raise

    def _publish_failure(self, header, kind: str, reason: str, policy: str) -> None:
        entry = failure_status(kind, reason, policy, self.root_frame)
        self.verdicts.publish_failure(header, entry, policy)
        if self.zone.enabled:
            self.zone.publish_failure(header, entry, policy)
        self.totals['failure_answers'] += 1

    def answer_held(self, header) -> bool:
        """Publish the verdict of the state held again, answering ``header`` (lock held); False
        when no state was checked yet."""
        if not self.verdicts.publish_held(header):
            return False
        if self.zone.enabled:
            self.zone.publish_held(header)
        return True

    def answer_current(self, notes: list) -> bool:
        """Check the current state again and publish the verdict, its header the time and the
        root frame (lock held); False when there is no state to check yet."""
        positions = self.joints.current_positions() if self.joints is not None else None
        if positions is None or self.checker is None:
            return False
        header = Header(stamp=self.get_clock().now().to_msg(), frame_id=self.root_frame)
        try:
            self.check(header, positions)
        except Exception as error:  # noqa: B902 - any failure is answered as such
            self.fail(header, error, notes)
        return True

    def _on_joint_states(self, batch: list, newest_only: bool) -> None:
        """What the checking thread does with ``batch`` (tests call it to stage a backlog)."""
        self.joints.take_batch(batch, newest_only)

    def stamp_seconds(self, header) -> float:
        """Return ``header.stamp`` in s; a zero stamp (publishers that set none) is now on the
        node's clock."""
        stamp = header.stamp
        if stamp.sec == 0 and stamp.nanosec == 0:
            return self.get_clock().now().nanoseconds * 1e-9
        return stamp.sec + stamp.nanosec * 1e-9

    def scene_changed(self) -> None:
        """The scene's objects changed: the markers show them again (lock held)."""
        if self.markers is not None:
            self.markers.scene_changed = True

    def count_reader_error(self, error: Exception) -> None:
        """Count and report a joint state the executor could not take (see :func:`spin`)."""
        with self.lock:
            self.totals['reader_errors'] += 1
        self.log.warn('reader', 'joint state skipped: it could not be taken from the '
                      f'middleware ({printable(repr(error), 300)}); counted as '
                      'skipped_reader_error')

    # -- timeouts and diagnostics -------------------------------------------------------------

    def _poll_timeouts(self) -> None:
        """Fail safe on a source whose data went missing or too old (by its policy)."""
        if not any(source.timeout_due(time.monotonic()) for source in self.sources):
            return      # the usual case, without waiting for the lock
        notes = []
        with self.lock:
            now = time.monotonic()
            for source in self.sources:
                timeout = source.poll_timeout(now, notes)
                if timeout is not None and timeout.policy == CONTACT:
                    header = Header(stamp=self.get_clock().now().to_msg(),
                                    frame_id=self.root_frame)
                    self._publish_failure(header, timeout.kind, timeout.reason, CONTACT)
        self.log.write(notes)

    @property
    def model_loading(self) -> bool:
        return self._loader is not None and (self._loader.loading or bool(self._loader.results))

    def publish_diagnostics(self, statuses: list) -> None:
        """Publish ``statuses`` on /diagnostics now."""
        self._diagnostics_pub.publish(DiagnosticArray(
            header=Header(stamp=self.get_clock().now().to_msg()), status=statuses))

    def _publish_diagnostics(self) -> None:
        notes = []
        try:
            with self.lock:
                now = time.monotonic()
                period, self.period = self.period, PeriodStats()
                statuses = [sensor_status(self, self.joints, period, now)]
                for source in self.sources:
                    status = source.status(now, notes)
                    if status is not None:
                        statuses.append(status)
                self.publish_diagnostics(statuses)
        except Exception as error:  # noqa: B902 - diagnostics must never stop the node
            notes.append(('warning', 'internal', 'diagnostics skipped after an internal error: '
                          f'{printable(repr(error), 300)}'))
        self.log.write(notes)

    def destroy_node(self):
        """Stop the sources' threads and the model loader, then destroy the node."""
        for source in self.sources:
            source.close()
        if self._loader is not None:
            self._loader.close()
            self._loader = None
        return super().destroy_node()


def start(args=None, dds_profile: Optional[str] = None):
    """Initialise rclpy and build the node; return ``(node, None)`` or ``(None, 1)``.

    ``collision_sensor_node`` (:func:`collision_sensor.ros.node.main`) calls this on a start-up
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
    Where it is missing, ``single`` (``SingleThreadedExecutor``) is used. ``multi`` is a
    two-thread ``MultiThreadedExecutor``.

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

    An executor turn that fails while the node runs (a joint state the middleware cannot hand
    over, such as a string that is not UTF-8) is counted as ``skipped_reader_error`` and
    spinning goes on.

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
