"""The ROS 2 node: joint states in, a collision verdict out (run it as ``collision_sensor_node``,
:mod:`collision_sensor.ros.node`).

The node only converts messages and parameters; the checking is :class:`CollisionChecker`'s,
the merging and validation of joint states :mod:`collision_sensor.ros.joint_state_merger`'s, the
parameters :mod:`collision_sensor.ros.node_parameters`'s.

Topics (relative, so ``-r __ns:=/robot`` moves them):

=================== ==== =================================== ====================================
topic               dir  type                                QoS
=================== ==== =================================== ====================================
joint_states        in   sensor_msgs/JointState              sensor data, or reliable keep-all
robot_description   in   std_msgs/String                     reliable, transient local, depth 1
                                                             (only when ``urdf_path`` is empty)
scene               in   visualization_msgs/MarkerArray      reliable, transient local, depth
                                                             :data:`SCENE_DEPTH`
contact             out  std_msgs/Bool                       reliable, transient local, depth 100
colliding_pairs     out  diagnostic_msgs/DiagnosticArray     reliable, transient local, depth 100
near                out  std_msgs/Bool                       as contact (``warning_distance`` > 0)
min_distance        out  std_msgs/Float64                    as contact (``warning_distance`` > 0)
near_pairs          out  diagnostic_msgs/DiagnosticArray     as contact (``warning_distance`` > 0)
~/markers           out  visualization_msgs/MarkerArray      reliable, depth 10 (if enabled)
/diagnostics        out  diagnostic_msgs/DiagnosticArray     reliable, depth 10, once a second
=================== ==== =================================== ====================================

Every accepted joint state that completes the state (see ``require_all_joints``) gives exactly
one ``contact`` and then one ``colliding_pairs`` message, in input order; the latter carries the
joint state's header (stamp and frame) so a consumer can tell which input a verdict answers.
With ``warning_distance`` > 0 (the warning zone, as nav2's collision monitor slows down before
it stops) the same joint state then gives one ``near`` (some checked pair is nearer than
``warning_distance``), one ``min_distance`` (the smallest padded distance of those pairs, <= 0
in contact; ``inf`` when no pair is that near) and one ``near_pairs`` message (the joint
state's header; one status per such pair, nearest first: level ERROR in contact, else WARN;
name ``link_a:link_b``; values ``link_a``, ``link_b``, ``distance`` (m) and ``point_a``,
``point_b``, the nearest points as "x y z" in metres in the robot's root link frame, also its
``hardware_id``): :meth:`CollisionChecker.proximity` at ``max_distance = warning_distance``.
No verdict is lost at the documented input rate: the verdict topics keep the last
:data:`VERDICT_DEPTH` (100) messages, 0.1 s at :data:`MAX_INPUT_RATE` (1 kHz), so a reliable
subscriber that keeps its own history at least that deep and falls less than 0.1 s behind gets
every verdict; a late subscriber gets the latest ones. Every joint state the node takes and does
not answer is counted on ``/diagnostics`` by reason (``skipped_*``), and so are those the
middleware reports lost before the node took them (``lost_total``).

Start-up: the robot is loaded, all its collision trees built and the query run once before
the node subscribes to ``joint_states``; then it logs one line starting ``ready:``. With the
robot from ``robot_description`` the same happens when the first description has been built.
Names and texts from the network reach logs and ``/diagnostics`` only through
:mod:`collision_sensor.untrusted_text` (escaped, bounded), and no log line is written while the
node's lock is held.

Failure policy: bad configuration raises :class:`~collision_sensor.ConfigError` (or another
:class:`~collision_sensor.CollisionSensorError`) from the constructor after logging the reason,
and ``main`` exits with status 1. Once running, nothing a message carries stops the node: bad
joint states are rejected with a throttled warning, a bad ``robot_description`` is rejected with
an error and the current model stays, and engine errors are logged.

Threads: the executor (:func:`make_executor`: rclpy's ``EventsExecutor`` where available)
takes joint states and hands each to the checking thread (:class:`_NewestFirstWorker`), which
merges, checks and publishes; robot descriptions are built on a loader thread
(:class:`_ModelLoader`, so checking goes on meanwhile); everything else runs on the
executor's thread. One lock keeps the model, the merged state and the counters consistent.
Only rclpy's public API is used.

Scene: every array on ``scene`` changes the scene all or nothing
(:mod:`collision_sensor.engine.scene_markers` has the rules; README, "Dynamic scene"). Arrays are
applied in arrival order on a thread of their own: files are read and trees built there,
without the lock, so joint states keep getting verdicts meanwhile (with the scene as it was);
only the swap takes the lock. The order of arrays and joint states is the order the node
applies and checks them, not the order of publishing (two topics): a replay that must keep a
recorded order waits for each answer (``collision_sensor_play --as-fast-as-possible`` does).
Every array is answered at once: by the ``scene`` status on ``/diagnostics`` (its counts of
arrays applied and rejected), and, once a joint state completes the state, by a verdict (its
header: the time and the root frame) besides those of the joint states. A rejected array
changes nothing (its verdict is the scene as it was) and is named, with the fix, in one log
line and in that status. A new robot from ``robot_description`` gets the objects that came
through the topic again.

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
import math
import os
import queue
import threading
import time
from typing import Callable, Dict, Optional

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import (
    Executor, ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor)
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data)
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, ColorRGBA, Float64, Header, String
from visualization_msgs.msg import Marker, MarkerArray

from collision_sensor.engine.dynamic_scene import SceneChangeError
from collision_sensor.engine.scene_markers import MarkerError, SceneTopic, marker_error
from collision_sensor.errors import CollisionSensorError, JointStateError, SceneError
from collision_sensor.model.mesh_loading import SOLID_BOX, SOLID_CYLINDER, SOLID_SPHERE
from collision_sensor.model.xml_safety import document_bytes
from collision_sensor.ros.joint_state_merger import JointStateMerger, Problem, joints_out_of_limits
from collision_sensor.ros.node_parameters import NodeSettings, declare_node_parameters
from collision_sensor.untrusted_text import listing, printable, quoted

#: Verdicts and the robot description: late joiners get the latest message.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``joint_states_qos: reliable``: every message checked, none dropped. KEEP_ALL, because a
#: reliable reader acknowledges a message once it is in its history, not once it is taken: with
#: KEEP_LAST depth N a publisher that waits for acknowledgements (``collision_sensor_play
#: --as-fast-as-possible``) still overruns the node whenever the node falls N messages behind.
#: KEEP_ALL makes the writer wait instead (DDS flow control), so replay is lossless.
RELIABLE_INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.VOLATILE)
JOINT_STATES_QOS = {'sensor_data': qos_profile_sensor_data, 'reliable': RELIABLE_INPUT_QOS}
#: The input rate the node is specified for (Hz), and the verdict history that covers 0.1 s of
#: it: a reliable subscriber 0.1 s behind still gets every verdict.
MAX_INPUT_RATE = 1000.0
VERDICT_DEPTH = 100
VERDICT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=VERDICT_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Largest robot_description accepted (UTF-8 bytes); real URDFs with inline meshes stay far
#: below.
MAX_ROBOT_DESCRIPTION_BYTES = 16 * 1024 * 1024

DIAGNOSTICS_PERIOD = 1.0    # s, as diagnostic_updater
MODEL_POLL_PERIOD = 0.05    # s between looks for a finished robot_description build
WARNING_PERIOD = 1.0        # s between two warnings of one kind
MARKER_PERIOD = 0.1         # s between marker updates while the colliding set stays the same
MARKER_COLOR = ColorRGBA(r=1.0, g=0.0, b=0.0, a=0.6)
NEAR_COLOR = ColorRGBA(r=1.0, g=0.55, b=0.0, a=0.9)   # nearest-point segments
TEXT_COLOR = ColorRGBA(r=1.0, g=1.0, b=1.0, a=0.9)
SEGMENT_WIDTH = 0.004       # m, line width of the nearest-point segments
CONTACT_DIAMETER = 0.02     # m, the contact points' spheres
TEXT_HEIGHT = 0.02          # m
#: Scene objects on ~/markers: fixed in the world, attached to a link, colliding.
WORLD_OBJECT_COLOR = ColorRGBA(r=0.6, g=0.6, b=0.65, a=0.8)
ATTACHED_OBJECT_COLOR = ColorRGBA(r=0.2, g=0.8, b=0.3, a=0.8)
COLLIDING_OBJECT_COLOR = ColorRGBA(r=1.0, g=0.1, b=0.1, a=0.9)
#: A mesh object with more triangles is drawn as its box on ~/markers.
MARKER_MAX_TRIANGLES = 20_000
#: The scene topic: reliable and transient local (an array published before the node started
#: still arrives, if its publisher is transient local too), the last SCENE_DEPTH arrays kept.
SCENE_DEPTH = 100
SCENE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=SCENE_DEPTH,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Scene arrays that may wait to be applied; more are dropped and counted (each can hold a
#: mesh: the wait must not grow without bound).
MAX_SCENE_BACKLOG = 100
#: Put on the scene thread's queue: add the topic's objects to a new robot model.
_READD_SCENE = object()
#: Joint states that may wait for the checking thread before it answers only the newest (see
#: :class:`_NewestFirstWorker`): 0.1 s at :data:`MAX_INPUT_RATE`, as the verdict history.
MAX_BACKLOG = 100

CheckerFactory = Callable[..., object]


class _Throttle:
    """Let one message per key through per period, and count the ones held back."""

    def __init__(self, period: float):
        self.period = period
        self._last: Dict[str, float] = {}
        self._held = collections.Counter()
        self._lock = threading.Lock()   # used from the reader and the executor's thread

    def admit(self, key: str, now: float) -> Optional[int]:
        """Return how many were held back since the last one, or None to hold this one."""
        with self._lock:
            last = self._last.get(key)
            if last is not None and now - last < self.period:
                self._held[key] += 1
                return None
            self._last[key] = now
            return self._held.pop(key, 0)


class _PeriodStats:
    """Counters of one diagnostics period."""

    def __init__(self):
        self.started = time.monotonic()
        self.received = 0
        self.rejected = 0
        self.checks = 0
        self.check_time_sum = 0.0
        self.check_time_max = 0.0


class _ModelLoader:
    """Build checkers from ``robot_description`` texts on a worker thread.

    Joint states keep being checked with the current model meanwhile; each finished build (a
    checker, or the error) is queued and ``notify`` is called, from the worker thread; the
    node installs it on the executor's thread. Texts that arrive during a build wait; only the
    newest waiting one is built.
    """

    def __init__(self, build: Callable[[bytes], object], notify: Callable[[], None]):
        self._build = build
        self._notify = notify
        self._condition = threading.Condition()
        self._pending: Optional[str] = None
        self._closed = False
        self.busy = False
        self.results = collections.deque()    # (text, checker or None, error or None)
        self._thread = threading.Thread(target=self._run, name='robot_description loader',
                                        daemon=True)
        self._thread.start()

    def submit(self, text: bytes) -> None:
        with self._condition:
            self._pending = text
            self._condition.notify()

    def close(self) -> None:
        with self._condition:
            self._closed = True
            self._condition.notify()
        # A build cannot be interrupted; the thread is a daemon and its result is dropped.
        self._thread.join(timeout=0.5)

    def _run(self):
        while True:
            with self._condition:
                while self._pending is None and not self._closed:
                    self._condition.wait()
                if self._closed:
                    return
                text, self._pending = self._pending, None
                self.busy = True
            try:
                checker, error = self._build(text), None
            except Exception as caught:  # noqa: B902 - any failure rejects this description
                checker, error = None, caught
            with self._condition:
                self.busy = False
                if self._closed:
                    return
                self.results.append((text, checker, error))
            self._notify()


class _Oversized:
    """A joint_states message above ``max_joint_state_bytes``, left undecoded.

    :ivar size: its serialized size in bytes.
    """

    __slots__ = ('size',)

    def __init__(self, size: int):
        self.size = size


def _joint_state_taker(put: Callable[[object], None], max_bytes: int) -> Callable[[bytes], None]:
    """Return the raw joint_states callback: decode a message of at most ``max_bytes`` and
    ``put`` it, or ``put`` an :class:`_Oversized` in its place (so it is counted, in order).

    Taking the serialized bytes keeps a flood of huge messages (10^4 names each) from being
    decoded into Python objects at all; the check is one ``len``.
    """
    def take(data: bytes) -> None:
        size = len(data)
        put(_Oversized(size) if size > max_bytes else deserialize_message(data, JointState))
    return take


class _NewestFirstWorker:
    """Check joint states on a thread of the node's own, handed over by the subscription's
    callback; under overload answer the newest state instead of queueing old ones.

    The executor's callback only puts each message on a queue (a C-level ``SimpleQueue``: no
    lock in Python, no allocation beyond the queue's slot), so the executor goes back to taking
    the next message at once. This thread wakes on the first message and takes every message
    waiting, in order:

    - at most :data:`MAX_BACKLOG` waiting (the node keeps up; the usual case, one message per
      wake-up): each is merged, checked and answered, in input order, as before;
    - more than that (the input is faster than the node): every one is still merged (validated,
      and a subset publisher's joints kept), but only the newest is checked and answered; the
      others are counted as ``skipped_superseded`` on ``/diagnostics``. The node stays within
      :data:`MAX_BACKLOG` messages of the input instead of drifting behind it.

    :param handle: called with ``(messages, newest_only)`` on this thread.
    :param name: the thread's name.
    """

    _STOP = object()

    def __init__(self, handle: Callable[[list, bool], None], name: str,
                 max_backlog: Optional[int] = MAX_BACKLOG):
        self._handle = handle
        self._max_backlog = max_backlog     # None: answer every state, however many wait
        self._queue = queue.SimpleQueue()
        self.put = self._queue.put      # the subscription's callback
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        get, get_nowait, stop = self._queue.get, self._queue.get_nowait, self._STOP
        while True:
            batch = [get()]
            try:
                while True:
                    batch.append(get_nowait())
            except queue.Empty:
                pass
            if any(item is stop for item in batch):
                return
            limit = self._max_backlog
            self._handle(batch, limit is not None and len(batch) > limit)

    def backlog(self) -> int:
        """Return how many messages wait (approximately: another thread may be taking one)."""
        return self._queue.qsize()

    def stop(self) -> None:
        """Stop the thread and wait for it (the messages being checked are finished first)."""
        self._queue.put(self._STOP)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)


def quaternion_from_matrix(R) -> tuple:
    """Return the unit quaternion ``(x, y, z, w)`` of a rotation matrix (Shepperd's method).

    :param R: (3, 3) float, a rotation matrix.
    """
    trace = R[0][0] + R[1][1] + R[2][2]
    # Branch on the largest of w, x, y, z so the square root is of a value >= 1/4 (stable).
    if trace > max(R[0][0], R[1][1], R[2][2]):
        s = 2.0 * math.sqrt(1.0 + trace)
        return ((R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s,
                0.25 * s)
    if R[0][0] >= R[1][1] and R[0][0] >= R[2][2]:
        s = 2.0 * math.sqrt(1.0 + R[0][0] - R[1][1] - R[2][2])
        return (0.25 * s, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s,
                (R[2][1] - R[1][2]) / s)
    if R[1][1] >= R[2][2]:
        s = 2.0 * math.sqrt(1.0 + R[1][1] - R[0][0] - R[2][2])
        return ((R[0][1] + R[1][0]) / s, 0.25 * s, (R[1][2] + R[2][1]) / s,
                (R[0][2] - R[2][0]) / s)
    s = 2.0 * math.sqrt(1.0 + R[2][2] - R[0][0] - R[1][1])
    return ((R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, 0.25 * s,
            (R[1][0] - R[0][1]) / s)


def _root_link(checker) -> str:
    """Return the frame the checker's world poses are in: the robot's root link."""
    return getattr(getattr(checker, 'model', None), 'root_link', '') or ''


def _mimic_joints(checker) -> frozenset:
    """Return the names of the checker's mimic joints (published by drivers, never needed)."""
    joints = getattr(getattr(checker, 'model', None), 'joints', ())
    return frozenset(joint.name for joint in joints if getattr(joint, 'mimic', None) is not None)


def _neutral_positions(checker) -> dict:
    """Every variable at the checker's neutral state: zeros, identity quaternions."""
    kinematics = getattr(checker, 'kinematics', None)
    if kinematics is None or not hasattr(kinematics, 'neutral'):
        return {name: 0.0 for name in checker.joint_names}
    return dict(zip(checker.joint_names, (float(v) for v in kinematics.neutral())))


def _base_variables(checker) -> dict:
    """The variables of planar and floating joints (a mobile or floating base, an SRDF virtual
    joint) at their neutral values. Robots rarely publish them in joint_states (MoveIt takes
    them from TF): the node starts them at the world origin instead of waiting for them."""
    kinematics = getattr(checker, 'kinematics', None)
    if kinematics is None or not hasattr(kinematics, 'neutral'):
        return {}
    from collision_sensor.engine.kinematics import JOINT_FLOATING, JOINT_PLANAR
    sizes = {JOINT_PLANAR: 3, JOINT_FLOATING: 7}
    neutral = kinematics.neutral()
    out = {}
    for kind, first in zip(kinematics.joint_type, kinematics.q_index):
        for j in range(int(first), int(first) + sizes.get(int(kind), 0)):
            out[checker.joint_names[j]] = float(neutral[j])
    return out


def _default_checker_factory(urdf, srdf=None, package_paths=None, scene=None, config=None,
                             xacro_args=None):
    from collision_sensor import CollisionChecker
    return CollisionChecker.from_urdf(urdf, srdf=srdf, package_paths=package_paths,
                                      scene=scene, config=config, xacro_args=xacro_args)


class CollisionSensorNode(Node):
    """Check every joint state for collisions and publish the verdict.

    :param node_name: the node's name.
    :param checker_factory: builds a checker, called as ``factory(urdf, srdf=, package_paths=,
        scene=, config=)`` with ``urdf`` a path (from ``urdf_path``) or the document as
        ``bytes`` (from ``robot_description``: never a path); default
        ``CollisionChecker.from_urdf``. Tests inject one that adds faults.
    :param kwargs: passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ...).
    :raises CollisionSensorError: bad configuration (the reason is logged first).
    """

    def __init__(self, node_name: str = 'collision_sensor', *,
                 checker_factory: Optional[CheckerFactory] = None, **kwargs):
        super().__init__(node_name, **kwargs)
        self._factory = checker_factory or _default_checker_factory
        self._checker = None
        self._merger: Optional[JointStateMerger] = None
        self._limits: Dict[str, tuple] = {}
        self._root_frame = ''
        self._model_source = ''
        self._loader: Optional[_ModelLoader] = None
        self._worker: Optional[_NewestFirstWorker] = None
        self.ready = False
        # Joint states are handled on the checking thread, the rest on the executor's: this lock
        # keeps the model, the merged state and the counters consistent between them. Nothing
        # is logged while it is held (logging can block on a slow stdout): log lines are
        # collected as notes and written after the lock is released.
        self._lock = threading.Lock()
        self._throttle = _Throttle(WARNING_PERIOD)
        self._period = _PeriodStats()
        self._totals = collections.Counter()
        self._out_of_limits: Dict[str, tuple] = {}
        self._last_accepted: Optional[float] = None   # time.monotonic() of the last update
        self._stale = False
        self._announced_waiting = False
        self._last_pairs = None
        # The verdict messages, reused: the pair statuses are rebuilt only when the colliding
        # set changes, the header is the joint state's.
        self._contact_msgs = (Bool(data=False), Bool(data=True))
        self._pairs_msg = DiagnosticArray()
        self._unchecked = []    # outcomes merged but superseded since the last check
        self._in_collision: Optional[bool] = None
        self._marker_content = ()    # (colliding links, near pairs) the markers show
        self._near_msgs = (Bool(data=False), Bool(data=True))
        self._marker_time = 0.0
        self._marker_shapes: Dict[str, tuple] = {}   # object: (its SceneObject, its marker)
        self._scene_topic: Optional[SceneTopic] = None
        self._scene_worker: Optional[_NewestFirstWorker] = None
        self._scene_rejection = ''   # the last rejected array's reason, '' once one applied
        self._scene_changed = False
        try:
            self._configure()
        except Exception as error:  # noqa: B902 - logged, then raised to the caller as it is
            self.get_logger().fatal(f'configuration failed: {printable(error, 2000)}')
            self.destroy_node()
            raise

    def _configure(self) -> None:
        self._settings: NodeSettings = declare_node_parameters(self)
        settings = self._settings
        if settings.urdf_path:
            checker = self._build(settings.urdf_path)
            self._log_notes(self._install_model(checker, f'urdf_path "{settings.urdf_path}"'))
        self._contact_pub = self.create_publisher(Bool, 'contact', VERDICT_QOS)
        self._pairs_pub = self.create_publisher(DiagnosticArray, 'colliding_pairs', VERDICT_QOS)
        self._markers_pub = (self.create_publisher(MarkerArray, '~/markers', 10)
                             if settings.publish_markers else None)
        self._near_pub = self._min_distance_pub = self._near_pairs_pub = None
        if settings.warning_distance > 0:
            self._near_pub = self.create_publisher(Bool, 'near', VERDICT_QOS)
            self._min_distance_pub = self.create_publisher(Float64, 'min_distance', VERDICT_QOS)
            self._near_pairs_pub = self.create_publisher(DiagnosticArray, 'near_pairs',
                                                         VERDICT_QOS)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        if settings.urdf_path:
            self._subscribe_joint_states()
        else:
            # Finished builds are installed from a timer on the executor's thread; not from a
            # guard condition, which rclpy's EventsExecutor (7.1.5) refuses.
            self._loader = _ModelLoader(self._build, lambda: None)
            self.create_timer(MODEL_POLL_PERIOD, self._on_model_loaded)
            self.create_subscription(String, 'robot_description', self._on_robot_description,
                                     LATCHED_QOS)
            self.get_logger().info('waiting for the robot on robot_description')

    def _subscribe_joint_states(self) -> None:
        """Subscribe joint_states (once a model is in place) and announce that the node is up."""
        settings = self._settings
        qos = JOINT_STATES_QOS[settings.joint_states_qos]
        # Public rclpy only: the executor takes each message and the callback hands it to the
        # checking thread (_NewestFirstWorker); the group of its own lets a multi-threaded
        # executor take joint states while the diagnostics timer or a model install runs.
        # Middleware-reported losses are counted, and a publisher that can never be heard is
        # named.
        # The scene topic, once there is a model to apply it to; arrays published before
        # arrive now (transient local).
        self._scene_topic = SceneTopic(settings.scene_limits, settings.package_paths or None)
        self._scene_worker = _NewestFirstWorker(self._on_scene_arrays, 'scene applier', None)
        self.create_subscription(
            MarkerArray, 'scene', self._on_scene, SCENE_QOS,
            callback_group=MutuallyExclusiveCallbackGroup(),
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=self._on_incompatible_scene_qos, use_default_callbacks=False))
        self._worker = _NewestFirstWorker(
            self._on_joint_states, 'joint_states checker',
            None if settings.overload_policy == 'every' else MAX_BACKLOG)
        joint_states = self.create_subscription(
            JointState, 'joint_states',
            _joint_state_taker(self._worker.put, settings.max_joint_state_bytes), qos, raw=True,
            callback_group=MutuallyExclusiveCallbackGroup(),
            event_callbacks=SubscriptionEventCallbacks(
                message_lost=self._on_message_lost, incompatible_qos=self._on_incompatible_qos,
                use_default_callbacks=False))
        self.ready = True
        self.get_logger().info(
            f'ready: checking {joint_states.topic_name} ({settings.joint_states_qos}) for '
            f'{printable(self._model_source, 300)}; verdicts on '
            f'{self.resolve_topic_name("contact")} and '
            f'{self.resolve_topic_name("colliding_pairs")}')

    # -- model --------------------------------------------------------------------------------

    def _build(self, urdf):
        """Build a checker and run its query once, so that nothing compiles on the first state.

        Runs on the main thread (``urdf_path``) or the loader thread (``robot_description``).
        """
        settings = self._settings
        extra = {'xacro_args': settings.xacro_args} if settings.xacro_args else {}
        checker = self._factory(urdf, srdf=settings.srdf_path,
                                package_paths=settings.package_paths or None,
                                scene=settings.scene_path, config=settings.checker_config,
                                **extra)
        # At the state a new checker starts in (every joint at 0, identity quaternions):
        # check then update, so the carried state is the one the first joint state updates
        # from, and the first verdict costs what every later one does.
        start = _neutral_positions(checker)
        checker.check(start)
        checker.update(start)
        return checker

    def _install_model(self, checker, source: str) -> list:
        """Make ``checker`` the model (call with the lock held); return the notes to log."""
        # Everything is derived first, so that a checker that fails here changes nothing.
        derived = _mimic_joints(checker)
        limits = dict(checker.joint_limits)
        settings = self._settings
        if self._merger is not None:
            merger = self._merger.carry_over(checker.joint_names, derived, limits=limits)
        else:
            merger = JointStateMerger(checker.joint_names, derived, limits=limits,
                                      limit_policy=settings.joint_limit_policy,
                                      limit_tolerance=settings.joint_limit_tolerance,
                                      max_unknown_names=settings.max_unknown_joints)
        for name, value in _base_variables(checker).items():
            merger.set_default(name, value)  # not waited for: see _base_variables
        out_of_limits = {name: rest for name, *rest
                         in joints_out_of_limits(merger.positions, limits)}
        summary = (f'{len(checker.joint_names)} joints, {len(checker.link_names)} links with '
                   f'geometry, {len(checker.checked_pairs)} pairs checked')
        self._clear_markers()
        self._scene_changed = True      # the scene file's objects, on ~/markers
        self._checker, self._merger, self._limits = checker, merger, limits
        self._out_of_limits = out_of_limits
        self._model_source = source
        self._root_frame = _root_link(checker)
        self._last_pairs = None
        self._unchecked = []
        self._announced_waiting = False
        notes = [('info', None, f'robot loaded from {printable(source, 300)}: {summary}')]
        for line in getattr(checker, 'load_warnings', ()):
            notes.append(('warning', None, f'while loading the robot: {printable(line, 1000)}'))
        return notes

    def _on_robot_description(self, msg: String) -> None:
        try:
            # Content only: bytes are always parsed as the document, never opened as a path.
            document = document_bytes(msg.data, 'URDF', MAX_ROBOT_DESCRIPTION_BYTES)
        except CollisionSensorError as error:
            self._totals['robot_description_rejected'] += 1
            keep = 'the current model stays' if self._checker is not None else 'no robot yet'
            self._warn('robot_description', f'robot_description rejected: {error}; {keep}',
                       'error')
            return
        self.get_logger().info(f'robot_description received ({len(document)} bytes); '
                               'loading it while the current model stays in use')
        self._loader.submit(document)

    def _on_model_loaded(self) -> None:
        loader = self._loader
        while loader is not None and loader.results:
            _, checker, error = loader.results.popleft()
            if error is not None:
                self._totals['robot_description_rejected'] += 1
                keep = ('the current model stays' if self._checker is not None
                        else 'still no robot model')
                self.get_logger().error(
                    f'robot_description rejected: {printable(error, 2000)}; {keep}')
                continue
            try:
                with self._lock:
                    notes = self._install_model(checker, 'robot_description')
            except Exception as caught:  # noqa: B902 - a broken checker must not stop the node
                self.get_logger().error(f'robot_description rejected: {printable(repr(caught))}')
                continue
            self._log_notes(notes)
            if self._worker is None:
                self._subscribe_joint_states()
            elif self._scene_topic is not None and self._scene_topic.objects:
                self._scene_worker.put(_READD_SCENE)

    # -- joint states -------------------------------------------------------------------------

    def _log(self, level: str, text: str) -> None:
        if not self.context.ok():
            return      # shutting down: rosout is gone, and the lines would only be noise
        # One call site per severity: rclpy ties each call site to one severity.
        logger = self.get_logger()
        if level == 'info':
            logger.info(text)
        elif level == 'error':
            logger.error(text)
        else:
            logger.warning(text)

    def _warn(self, kind: str, text: str, level: str = 'warning') -> None:
        held = self._throttle.admit(kind, time.monotonic())
        if held is not None:
            more = f' ({held} more like this in the last {WARNING_PERIOD:g} s)' if held else ''
            self._log(level, text + more)

    def _log_notes(self, notes) -> None:
        """Write the log lines collected under the lock: ``(level, throttle kind, text)``."""
        for level, kind, text in notes:
            if kind is None:
                self._log(level, text)
            else:
                self._warn(kind, text, level)

    def _on_message_lost(self, info) -> None:
        with self._lock:
            self._totals['lost'] += info.total_count_change
        self._warn('lost', f'{info.total_count_change} joint states lost before the node took '
                   f'them ({info.total_count} in all): the input is faster than the node or '
                   'the subscription queue (joint_states_qos); counted as lost_total')

    def _on_incompatible_qos(self, event) -> None:
        self._warn('qos', 'a publisher of joint_states offers a QoS this subscription cannot '
                   f'match (policy {event.last_policy_kind}); its messages are never received. '
                   'Publish reliable, or set joint_states_qos: sensor_data')

    def count_reader_error(self, error: Exception) -> None:
        """Count and report a joint state the executor could not take (see :func:`spin`)."""
        with self._lock:
            self._totals['reader_errors'] += 1
        self._warn('reader', 'joint state skipped: it could not be taken from the middleware '
                   f'({printable(repr(error), 300)}); counted as skipped_reader_error')

    def _on_joint_states(self, batch: list, newest_only: bool) -> None:
        """Merge every message of ``batch`` in order; check and answer each accepted one, or
        with ``newest_only`` the last (see :class:`_NewestFirstWorker`)."""
        notes = []
        with self._lock:
            last = len(batch) - 1
            for index, msg in enumerate(batch):
                try:
                    self._process(msg, notes, check=not newest_only or index == last)
                    if index == last and self._unchecked:
                        # The newest message was not accepted: answer the newest that was.
                        self._totals['superseded'] -= 1
                        msg, outcome = self._unchecked.pop()
                        self._check(msg, outcome, notes)
                except Exception as error:  # noqa: B902 - one message must never stop the node
                    if not self.context.ok():
                        return      # shutting down: the publishers are gone, nothing to report
                    self._totals['engine_errors'] += 1
                    notes.append(('warning', 'internal', 'joint state skipped after an internal '
                                  f'error: {printable(repr(error), 300)}'))
        self._log_notes(notes)

    def _process(self, msg: JointState, notes: list, check: bool = True) -> None:
        period, totals = self._period, self._totals
        period.received += 1
        totals['received'] += 1
        merger = self._merger
        if merger is None:
            totals['no_model'] += 1
            notes.append(('warning', 'no_model', 'joint state ignored: no robot model yet '
                          '(waiting for robot_description)'))
            return
        if isinstance(msg, _Oversized):
            period.rejected += 1
            totals['rejected'] += 1
            totals['rejected_oversized'] += 1
            notes.append(('warning', 'OVERSIZED', (
                f'joint state rejected before decoding, state unchanged: {msg.size} bytes, '
                f'above max_joint_state_bytes ({self._settings.max_joint_state_bytes}); raise '
                'the parameter if the robot\'s joint states are really that large')))
            return
        outcome = merger.merge(msg.name, msg.position)
        if outcome.problem is not None:
            period.rejected += 1
            totals['rejected'] += 1
            totals['rejected_' + outcome.problem.name.lower()] += 1
            notes.append(('warning', outcome.problem.name,
                          f'joint state rejected, state unchanged: {outcome.reason}'))
            return
        if outcome.new_unknown or outcome.unremembered:
            remembered = len(merger.unknown_names)
            notes.append(('warning', 'unknown', (
                f'ignoring {len(outcome.unknown)} joint name(s) in joint_states that the robot '
                'model does not move: '
                + listing(outcome.unknown, max_items=5, limit=300)
                + f'; {remembered} distinct unknown names remembered (at most '
                f'{merger.max_unknown_names}), {merger.unknown_overflow} not remembered; '
                '/diagnostics lists them')))
        if outcome.clamped:
            totals['clamped'] += 1
            notes.append(('warning', 'clamped', 'joints beyond their limits clamped to them '
                          '(joint_limit_policy clamp): ' + listing(outcome.clamped, max_items=5)))
        if not outcome.accepted:
            totals['ignored'] += 1
            return
        totals['accepted'] += 1
        now = time.monotonic()
        self._last_accepted = now
        if self._stale:
            self._stale = False
            notes.append(('info', None, 'joint states resumed'))
        positions = merger.positions
        self._update_limits(outcome.updated, positions, notes)
        if self._settings.require_all_joints and not merger.complete:
            totals['waiting_for_joints'] += 1
            if not self._announced_waiting:
                self._announced_waiting = True
                notes.append(('info', None, 'waiting for joints '
                              f'{listing(merger.missing(), max_items=20)} before the first '
                              'verdict (require_all_joints)'))
            return
        if not check:
            # Overloaded: a newer state waits; this one is merged but not checked.
            self._unchecked.append((msg, outcome))
            totals['superseded'] += 1
            return
        self._check(msg, outcome, notes)

    def _check(self, msg: JointState, outcome, notes: list) -> None:
        """Check the merged state ``msg`` completed and publish the verdict; on a state the
        engine refuses, roll back ``outcome`` and the superseded ones merged before it."""
        period, totals, merger = self._period, self._totals, self._merger
        started = time.perf_counter()
        try:
            # Every joint known: the array in checker.joint_names order, the engine's fast path;
            # otherwise the dict (joints not heard yet keep the checker's value).
            positions = merger.array if merger.complete else merger.positions
            result = self._checker.update(positions)
        except JointStateError as error:
            # The engine refuses a value it cannot honour (a slider beyond its range, a zero
            # quaternion): the message is rejected after all, the state stays as it was, the
            # one the last verdict describes (superseded states merged since are rolled back
            # with it and counted as rejected instead).
            undone = [outcome] + [each for _, each in reversed(self._unchecked)]
            for each in undone:
                merger.undo(each)
            totals['superseded'] -= len(self._unchecked)
            self._unchecked = []
            period.rejected += len(undone)
            totals['rejected'] += len(undone)
            totals['rejected_engine_range'] += len(undone)
            notes.append(('warning', 'ENGINE_RANGE',
                          f'joint state rejected, state unchanged: {printable(error, 500)}'))
            return
        except CollisionSensorError as error:
            self._unchecked = []
            totals['engine_errors'] += 1
            notes.append(('warning', 'engine',
                          f'collision check failed: {printable(error, 500)}'))
            return
        self._unchecked = []
        elapsed = time.perf_counter() - started
        period.checks += 1
        period.check_time_sum += elapsed
        if elapsed > period.check_time_max:
            period.check_time_max = elapsed
        self._answer(msg, result, positions)
        totals['verdicts'] += 1

    def _answer(self, msg: JointState, result, positions) -> None:
        """Publish the verdict answering ``msg``, then (when enabled) the warning zone's
        outputs and the markers."""
        self._publish_verdict(msg, result)
        records = self._publish_proximity(msg, positions) if self._near_pub is not None else ()
        if self._markers_pub is not None:
            self._publish_markers(msg, result.colliding_pairs, records)

    def _update_limits(self, updated, positions, notes) -> None:
        for name in updated:
            self._out_of_limits.pop(name, None)
        for name, value, lower, upper in joints_out_of_limits(positions, self._limits, updated):
            self._out_of_limits[name] = (value, lower, upper)
            notes.append(('warning', 'limits',
                          f'joint {quoted(name)} at {value:.6g} is outside its limits '
                          f'[{_bound(lower)}, {_bound(upper)}]; checked as given '
                          f'(joint_limit_policy {self._settings.joint_limit_policy})'))

    def _publish_verdict(self, msg: JointState, result) -> None:
        pairs = result.colliding_pairs
        self._in_collision = bool(result.in_collision)
        self._contact_pub.publish(self._contact_msgs[self._in_collision])
        verdict = self._pairs_msg
        if pairs != self._last_pairs:
            self._last_pairs = pairs
            verdict.status = [
                DiagnosticStatus(level=DiagnosticStatus.ERROR, name=f'{a}:{b}',
                                 message=f'{a} collides with {b}',
                                 hardware_id=self._root_frame,
                                 values=[KeyValue(key='link_a', value=a),
                                         KeyValue(key='link_b', value=b)])
                for a, b in pairs]
        verdict.header = msg.header
        self._pairs_pub.publish(verdict)

    # -- proximity (warning_distance > 0) -------------------------------------------------------

    def _publish_proximity(self, msg: JointState, positions) -> list:
        """Measure the pairs nearer than ``warning_distance`` at the state just checked and
        publish ``near``, ``min_distance`` and ``near_pairs``; return the records."""
        # The state is the one update() just checked: proximity re-checks nothing, it measures.
        records = self._checker.proximity(positions, self._settings.warning_distance)
        self._near_pub.publish(self._near_msgs[bool(records)])
        self._min_distance_pub.publish(
            Float64(data=float(records[0].distance) if records else math.inf))
        self._near_pairs_pub.publish(DiagnosticArray(
            header=msg.header, status=[self._near_status(r) for r in records]))
        return records

    def _near_status(self, record) -> DiagnosticStatus:
        """One ``near_pairs`` entry (see the module docstring)."""
        a, b, distance = record.link_a, record.link_b, float(record.distance)
        message = (f'{a} is in contact with {b} ({distance:.4f} m)' if distance <= 0
                   else f'{a} is {distance:.4f} m from {b}')
        return DiagnosticStatus(
            level=DiagnosticStatus.ERROR if distance <= 0 else DiagnosticStatus.WARN,
            name=f'{a}:{b}', message=message, hardware_id=self._root_frame,
            values=[KeyValue(key='link_a', value=a), KeyValue(key='link_b', value=b),
                    KeyValue(key='distance', value=repr(distance)),
                    KeyValue(key='point_a', value=_xyz(record.point_a)),
                    KeyValue(key='point_b', value=_xyz(record.point_b))])

    # -- the scene topic ----------------------------------------------------------------------

    def _on_scene(self, msg: MarkerArray) -> None:
        """Hand an array to the scene thread (the executor's thread: nothing slow here)."""
        if self._scene_worker.backlog() >= MAX_SCENE_BACKLOG:
            with self._lock:
                self._totals['scene_dropped'] += 1
            self._warn('scene_dropped', f'scene array dropped: {MAX_SCENE_BACKLOG} arrays wait '
                       'to be applied already (counted as scene_arrays_dropped_total); publish '
                       'scene changes more slowly')
            return
        self._scene_worker.put(msg)

    def _on_incompatible_scene_qos(self, event) -> None:
        self._warn('scene_qos', 'a publisher of scene offers a QoS this subscription cannot '
                   f'match (policy {event.last_policy_kind}); its arrays are never received. '
                   'Publish scene reliable and transient local')

    def _on_scene_arrays(self, batch: list, _newest_only: bool) -> None:
        """Apply every array of ``batch`` in order (the scene thread)."""
        for msg in batch:
            notes = []
            try:
                if msg is _READD_SCENE:
                    self._readd_scene(notes)
                else:
                    self._apply_scene(list(msg.markers), notes)
            except Exception as error:  # noqa: B902 - one array must never stop the node
                if not self.context.ok():
                    return
                notes.append(('error', None, 'scene array skipped after an internal error: '
                              f'{printable(repr(error), 300)}'))
            self._log_notes(notes)

    def _apply_scene(self, markers: list, notes: list) -> None:
        """Apply one array: convert it and build its trees without the lock, then swap the
        scene in and answer at once under the lock. A model installed meanwhile is taken and
        the array prepared again for it."""
        while True:
            checker, topic = self._checker, self._scene_topic
            try:
                update = topic.update(markers, checker)
                try:
                    prepared = checker.prepare_scene_changes(update.changes)
                except SceneChangeError as error:
                    raise marker_error(error, update, markers) from None
            except MarkerError as error:
                self._reject_scene(str(error), notes)
                return
            with self._lock:
                if self._checker is not checker:
                    continue    # a new robot model: prepare the array for it
                checker.commit_scene_changes(prepared)
                topic.accept(update)
                self._scene_applied(f'scene array of {len(markers)} markers applied: '
                                    f'{update.summary}', notes)
            return

    def _readd_scene(self, notes: list) -> None:
        """Give a new robot model the objects that came through the topic."""
        while True:
            checker, topic = self._checker, self._scene_topic
            try:
                prepared = checker.prepare_scene_changes(topic.readd_changes())
            except SceneError as error:
                with self._lock:
                    topic.objects = {}
                    self._totals['scene_rejected'] += 1
                notes.append(('error', None, 'the objects from the scene topic do not fit the '
                              f'new robot model and are dropped: {printable(error, 1000)}; '
                              'publish them again'))
                return
            with self._lock:
                if self._checker is not checker:
                    continue
                checker.commit_scene_changes(prepared)
                self._scene_applied(f'{len(topic.objects)} objects from the scene topic added '
                                    'to the new robot model', notes)
            return

    def _scene_applied(self, text: str, notes: list) -> None:
        """Count an applied change, answer it and publish the scene status at once (call with
        the lock held)."""
        self._totals['scene_applied'] += 1
        self._scene_rejection = ''
        self._scene_changed = True
        notes.append(('info', 'scene_applied', printable(text, 500)))   # at most 1 a second
        self._answer_scene(notes)
        self._diagnostics_pub.publish(DiagnosticArray(
            header=Header(stamp=self.get_clock().now().to_msg()), status=[self.scene_status()]))

    def _answer_scene(self, notes: list) -> None:
        """Publish the verdict at the current joint state, its header the time and the root
        frame (call with the lock held); nothing before a joint state completes the state."""
        merger = self._merger
        if merger is None or self._last_accepted is None or (
                self._settings.require_all_joints and not merger.complete):
            return      # no joint state to answer yet
        positions = merger.array if merger.complete else merger.positions
        try:
            result = self._checker.update(positions)
        except CollisionSensorError as error:
            self._totals['engine_errors'] += 1
            notes.append(('warning', 'engine', f'collision check failed: {printable(error, 500)}'))
            return
        header = Header(stamp=self.get_clock().now().to_msg(), frame_id=self._root_frame)
        self._answer(JointState(header=header), result, positions)
        self._totals['scene_verdicts'] += 1

    def _reject_scene(self, reason: str, notes: list) -> None:
        """Count a rejected array, log it once and publish the scene status at once."""
        text = printable(reason, 1000)
        with self._lock:
            self._totals['scene_rejected'] += 1
            self._scene_rejection = text
            status = self.scene_status()
            self._answer_scene(notes)    # the scene as it was: every array is answered
        notes.append(('error', None, f'scene array rejected, scene unchanged: {text}'))
        self._diagnostics_pub.publish(DiagnosticArray(
            header=Header(stamp=self.get_clock().now().to_msg()), status=[status]))

    def scene_status(self) -> DiagnosticStatus:
        """The ``scene`` status on /diagnostics (call with the lock held): the objects, what
        came through the topic, and the last rejected array's reason until one applies."""
        checker, topic, totals = self._checker, self._scene_topic, self._totals
        names = checker.object_names if checker is not None else ()
        attached = checker.attachments if checker is not None else {}
        from_topic = topic.objects if topic is not None else {}
        level, message = DiagnosticStatus.OK, f'{len(names)} objects ({len(from_topic)} from ' \
            'the scene topic)'
        if self._scene_rejection:
            level, message = DiagnosticStatus.WARN, f'last array rejected: {self._scene_rejection}'
        values = {
            'objects': listing(names),
            'objects_count': str(len(names)),
            'attached': listing((f'{printable(name)} on {printable(link)}'
                                 for name, (link, _) in attached.items()),
                                total=len(attached), escape=False),
            'topic_objects_count': str(len(from_topic)),
            'topic_triangles': str(sum(item.triangles for item in from_topic.values())),
            'scene_arrays_applied_total': str(totals['scene_applied']),
            'scene_arrays_rejected_total': str(totals['scene_rejected']),
            'scene_arrays_dropped_total': str(totals['scene_dropped']),
            'scene_verdicts_total': str(totals['scene_verdicts']),
            'last_rejection': self._scene_rejection,
        }
        return DiagnosticStatus(
            level=level, name=f'{self.get_fully_qualified_name().lstrip("/")}: scene',
            message=printable(message, 1000), hardware_id=printable(self._root_frame),
            values=[KeyValue(key=key, value=value) for key, value in values.items()])

    # -- markers ------------------------------------------------------------------------------

    def _publish_markers(self, msg: JointState, pairs, records=()) -> None:
        """Publish the boxes of the colliding bodies, the scene objects and, with
        ``warning_distance``, the near pairs' nearest points (call with the lock held): when
        any of them changes, and at most every MARKER_PERIOD while something collides or is
        near, or an attached object moves with the robot."""
        colliding = tuple(sorted({name for pair in pairs for name in pair}))
        near = tuple((r.link_a, r.link_b) for r in records)
        checker = self._checker
        objects = checker.object_names
        if not colliding and not near and not objects:
            self._clear_markers()
            return
        now = time.monotonic()
        moving = colliding or near or checker.attachments
        content = (colliding, near)
        if not self._scene_changed and content == self._marker_content and (
                not moving or now - self._marker_time < MARKER_PERIOD):
            return
        self._marker_content, self._marker_time, self._scene_changed = content, now, False
        # DELETEALL first: bodies that stopped colliding lose their boxes in the same message.
        stamp = msg.header.stamp
        markers = [Marker(action=Marker.DELETEALL)]
        for index, (name, T_world_box, half) in enumerate(checker.collision_boxes(colliding)):
            marker = self._marker(name, index, Marker.CUBE, T_world_box, stamp, MARKER_COLOR)
            marker.scale.x, marker.scale.y, marker.scale.z = (2.0 * float(h) for h in half)
            markers.append(marker)
        attached = checker.attachments
        for index, obj in enumerate(checker.scene_objects):
            color = (COLLIDING_OBJECT_COLOR if obj.name in colliding else
                     ATTACHED_OBJECT_COLOR if obj.name in attached else WORLD_OBJECT_COLOR)
            markers.append(self._object_marker(obj, index, stamp, color))
        markers.extend(self._proximity_markers(stamp, records))
        self._markers_pub.publish(MarkerArray(markers=markers))

    def _proximity_markers(self, stamp, records) -> list:
        """The near pairs: nearest points joined (LINE_LIST, apart pairs), the contact points
        (SPHERE_LIST) and each pair's distance as text, with the padding it includes."""
        identity = np.eye(4)
        segments = self._marker('proximity', 0, Marker.LINE_LIST, identity, stamp, NEAR_COLOR)
        segments.scale.x = SEGMENT_WIDTH
        contacts = self._marker('proximity', 1, Marker.SPHERE_LIST, identity, stamp,
                                MARKER_COLOR)
        contacts.scale.x = contacts.scale.y = contacts.scale.z = CONTACT_DIAMETER
        labels = []
        paddings = self._checker.paddings
        for index, r in enumerate(records):
            a, b = _point(r.point_a), _point(r.point_b)
            if r.distance > 0:
                segments.points.extend((a, b))
            else:
                contacts.points.append(a)
            padding = paddings.get(r.link_a, 0.0) + paddings.get(r.link_b, 0.0)
            at = np.eye(4)
            at[:3, 3] = 0.5 * (r.point_a + r.point_b)
            label = self._marker('proximity/distance', index, Marker.TEXT_VIEW_FACING, at,
                                 stamp, TEXT_COLOR)
            label.scale.z = TEXT_HEIGHT
            label.text = (f'{r.link_a}:{r.link_b} {1e3 * r.distance:.1f} mm'
                          + (f' (padding {1e3 * padding:g} mm)' if padding > 0 else ''))
            labels.append(label)
        return [m for m in (segments, contacts) if m.points] + labels
    def _marker(self, ns: str, index: int, kind: int, T_world, stamp, color) -> Marker:
        x, y, z, w = quaternion_from_matrix(T_world[:3, :3])
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T_world[:3, 3])
        pose.orientation.x, pose.orientation.y = x, y
        pose.orientation.z, pose.orientation.w = z, w
        marker = Marker(ns=ns, id=index, type=kind, action=Marker.ADD, pose=pose, color=color,
                        frame_locked=False)
        marker.header.frame_id = self._root_frame
        marker.header.stamp = stamp
        return marker

    def _object_marker(self, obj, index: int, stamp, color) -> Marker:
        """A scene object's marker (ns ``scene_objects``): its primitive, its triangles, or for
        a mesh of more than MARKER_MAX_TRIANGLES its box."""
        cached = self._marker_shapes.get(obj.name)
        if cached is None or cached[0] is not obj.vertices:
            solid, size = obj.solid, (1.0, 1.0, 1.0)
            kind, points, T_object_shape = Marker.TRIANGLE_LIST, [], np.eye(4)
            if solid is not None and solid.kind in (SOLID_BOX, SOLID_SPHERE, SOLID_CYLINDER):
                h = solid.size
                kind, size = {SOLID_BOX: (Marker.CUBE, (2 * h[0], 2 * h[1], 2 * h[2])),
                              SOLID_SPHERE: (Marker.SPHERE, (2 * h[0],) * 3),
                              SOLID_CYLINDER: (Marker.CYLINDER, (2 * h[0], 2 * h[0], 2 * h[1]))
                              }[solid.kind]
            elif len(obj.faces) <= MARKER_MAX_TRIANGLES:
                points = [Point(x=x, y=y, z=z)
                          for x, y, z in obj.vertices[obj.faces.ravel()].tolist()]
            else:
                _, T_world_box, half = self._checker.collision_boxes([obj.name])[0]
                kind, size = Marker.CUBE, tuple(2.0 * float(v) for v in half)
                T_object_shape = np.linalg.inv(obj.T_world_object) @ T_world_box
            cached = (obj.vertices, kind, size, points, T_object_shape)
            self._marker_shapes[obj.name] = cached
        _, kind, size, points, T_object_shape = cached
        marker = self._marker('scene_objects', index, kind, obj.T_world_object @ T_object_shape,
                              stamp, color)
        marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in size)
        marker.points = points
        marker.text = obj.name
        return marker

    def _clear_markers(self) -> None:
        if (self._marker_content or self._marker_shapes) and getattr(
                self, '_markers_pub', None) is not None:
            marker = Marker(action=Marker.DELETEALL)
            marker.header.frame_id = self._root_frame
            self._markers_pub.publish(MarkerArray(markers=[marker]))
        self._marker_content = ()
        self._marker_shapes = {}

    # -- diagnostics --------------------------------------------------------------------------

    def _publish_diagnostics(self) -> None:
        notes = []
        try:
            with self._lock:
                status = [self.diagnostics_status(notes), self.scene_status()]
            self._diagnostics_pub.publish(DiagnosticArray(
                header=Header(stamp=self.get_clock().now().to_msg()), status=status))
        except Exception as error:  # noqa: B902 - diagnostics must never stop the node
            notes.append(('warning', 'internal', 'diagnostics skipped after an internal error: '
                          f'{printable(repr(error), 300)}'))
        self._log_notes(notes)

    def diagnostics_status(self, notes: Optional[list] = None) -> DiagnosticStatus:
        """Close the current diagnostics period and return its status (call with the lock held).

        Every value is bounded: names come through :func:`~collision_sensor.untrusted_text.listing`
        (at most 10 each, escaped), whatever the input.

        :param notes: log lines to write once the lock is released are appended here.
        """
        notes = [] if notes is None else notes
        now = time.monotonic()
        period, self._period = self._period, _PeriodStats()
        elapsed = max(now - period.started, 1e-9)
        settings = self._settings
        if (settings.stale_timeout > 0 and self._last_accepted is not None
                and now - self._last_accepted > settings.stale_timeout):
            if not self._stale:
                self._stale = True
                notes.append(('warning', None,
                              f'joint states stale: none accepted for '
                              f'{now - self._last_accepted:.1f} s (stale_timeout '
                              f'{settings.stale_timeout:g} s)'))
        merger = self._merger
        missing = merger.missing() if merger is not None else []
        unknown = sorted(merger.unknown_names) if merger is not None else []
        overflow = merger.unknown_overflow if merger is not None else 0
        level, message = DiagnosticStatus.OK, 'no collision'
        if self._in_collision:
            message = 'in collision: ' + listing(
                (f'{a}:{b}' for a, b in self._last_pairs), total=len(self._last_pairs))
        problems = []
        if self._checker is None:
            level = DiagnosticStatus.ERROR
            problems.append('no robot model (waiting for robot_description)')
        elif self._last_accepted is None:
            level = DiagnosticStatus.WARN
            problems.append('waiting for joint states')
        elif settings.require_all_joints and missing:
            level = DiagnosticStatus.WARN
            problems.append('waiting for joints ' + listing(missing))
        if self._out_of_limits:
            level = max(level, DiagnosticStatus.WARN)
            problems.append('joints out of limits: ' + listing(sorted(self._out_of_limits)))
        if period.rejected:
            level = max(level, DiagnosticStatus.WARN)
            problems.append(f'{period.rejected} joint states rejected')
        if self._stale:
            level = DiagnosticStatus.STALE
            problems.append(f'stale: no joint state for {now - self._last_accepted:.1f} s')
        if problems:
            message = '; '.join(problems + ([message] if self._in_collision else []))
        mean_ms = 1e3 * period.check_time_sum / period.checks if period.checks else 0.0
        totals = self._totals
        skipped = {
            'skipped_rejected': totals['rejected'],
            'skipped_ignored': totals['ignored'],
            'skipped_waiting_for_joints': totals['waiting_for_joints'],
            'skipped_no_model': totals['no_model'],
            'skipped_engine_error': totals['engine_errors'],
            'skipped_reader_error': totals['reader_errors'],
            'skipped_superseded': totals['superseded'],
        }
        values = {
            'state': 'ready' if self.ready else 'loading',
            'input_rate_hz': f'{period.received / elapsed:.1f}',
            'checks': str(period.checks),
            'check_time_mean_ms': f'{mean_ms:.4f}',
            'check_time_max_ms': f'{1e3 * period.check_time_max:.4f}',
            'rejected': str(period.rejected),
            'rejected_total': str(totals['rejected']),
            'engine_errors_total': str(totals['engine_errors']),
            'received_total': str(totals['received']),
            'verdicts_total': str(totals['verdicts']),
            'skipped_total': str(sum(skipped.values())),
            **{key: str(value) for key, value in skipped.items()},
            **{f'rejected_{problem.name.lower()}': str(totals[f'rejected_{problem.name.lower()}'])
               for problem in Problem},
            'rejected_engine_range': str(totals['rejected_engine_range']),
            'rejected_oversized': str(totals['rejected_oversized']),
            'lost_total': str(totals['lost']),
            'clamped_total': str(totals['clamped']),
            'robot_description_rejected_total': str(totals['robot_description_rejected']),
            'unknown_joints': listing(unknown, total=len(unknown)),
            'unknown_joints_count': str(len(unknown)),
            'unknown_joints_not_remembered': str(overflow),
            'missing_joints': listing(missing),
            'out_of_limit_joints': listing(
                (f'{printable(name)}={value:.6g} [{_bound(lower)}, {_bound(upper)}]'
                 for name, (value, lower, upper) in sorted(self._out_of_limits.items())),
                total=len(self._out_of_limits), escape=False),
            'joint_limit_policy': settings.joint_limit_policy,
            'stale': str(self._stale).lower(),
            'seconds_since_joint_state': ('' if self._last_accepted is None
                                          else f'{now - self._last_accepted:.3f}'),
            'waiting_for_joints': str(bool(settings.require_all_joints and missing)).lower(),
            'in_collision': str(bool(self._in_collision)).lower(),
            'model': printable(self._model_source, 300),
            'model_loading': str(bool(self._loader and (self._loader.busy
                                                        or self._loader.results))).lower(),
        }
        return DiagnosticStatus(
            level=level, name=f'{self.get_fully_qualified_name().lstrip("/")}: collision sensor',
            message=printable(message, 1000),
            hardware_id=printable(self._root_frame),
            values=[KeyValue(key=key, value=value) for key, value in values.items()])

    def destroy_node(self):
        """Stop the joint-state thread and the model loader, then destroy the node."""
        for worker in (self._worker, self._scene_worker):
            if worker is not None:
                worker.stop()
        self._worker = self._scene_worker = None
        if self._loader is not None:
            self._loader.close()
            self._loader = None
        return super().destroy_node()


def _xyz(point) -> str:
    """A point as "x y z" (metres, 9 significant digits)."""
    return ' '.join(f'{float(v):.9g}' for v in point)


def _point(point) -> Point:
    return Point(x=float(point[0]), y=float(point[1]), z=float(point[2]))


def _bound(value) -> str:
    return 'none' if value is None else f'{value:.6g}'


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
    set per turn; chosen by measurement (``collision_sensor.ros.node_latency``, README).
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
