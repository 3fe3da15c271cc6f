"""The ``joint_states`` input: every message handed, serialized, to the sensor core, which
merges, checks and answers it (``cpp/sensor_core.hpp`` has every rule).

Two ways in, the same core and the same answers:

- the compiled hop (``cpp/hop/joint_state_hop.cpp``, the default wherever it was built): an rcl
  subscription of the node's own, waited on by a thread of the hop's own that takes each
  message, has the core answer it and publishes the answer, with no Python on the way;
- rclpy (where the hop was not built, or with ``COLLISION_SENSOR_JOINT_STATES=rclpy``): a raw
  subscription whose callback queues the bytes for a thread of this source's, which hands them
  to the core in batches; the core publishes through rclpy.

Either way, under overload (more than :data:`~collision_sensor.ros.work_queue.MAX_BACKLOG`
messages waiting at once, ``overload_policy: newest``) every message is merged but only the
newest accepted one is answered; the others are counted as ``skipped_superseded``. Losses the
middleware reports (``sensor_data``: best effort) are counted as ``lost_total``.
"""
import os
from typing import Optional

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState

from collision_sensor.engine.compiled import engine as compiled
from collision_sensor.ros.input_source import InputSource
from collision_sensor.ros.work_queue import MAX_BACKLOG, NewestFirstWorker

#: ``joint_states_qos: reliable``: every message checked, none dropped. KEEP_ALL, because a
#: reliable reader acknowledges a message once it is in its history, not once it is taken: with
#: KEEP_LAST depth N a publisher that waits for acknowledgements (``collision_sensor_play
#: --as-fast-as-possible``) still overruns the node whenever the node falls N messages behind.
#: KEEP_ALL makes the writer wait instead (DDS flow control), so replay is lossless.
RELIABLE_INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.VOLATILE)
JOINT_STATES_QOS = {'sensor_data': qos_profile_sensor_data, 'reliable': RELIABLE_INPUT_QOS}
#: How joint states come in (``COLLISION_SENSOR_JOINT_STATES``): ``compiled`` (the default,
#: where the hop was built) or ``rclpy``.
WAYS_IN = ('compiled', 'rclpy')
#: The core's topic numbers, by name.
TOPIC_NUMBERS = {'contact': compiled.TOPIC_CONTACT,
                 'colliding_pairs': compiled.TOPIC_COLLIDING_PAIRS,
                 'near': compiled.TOPIC_NEAR, 'min_distance': compiled.TOPIC_MIN_DISTANCE,
                 'near_pairs': compiled.TOPIC_NEAR_PAIRS}


def load_hop():
    """Return the compiled hop's module, or the reason it cannot be used (a string)."""
    try:
        from collision_sensor.ros import _joint_state_hop
    except ImportError as error:
        return (f'the compiled joint-state hop is not built ({error}): rcl\'s headers were not '
                'found when the package was installed; install it again with ROS 2 sourced, or '
                'after the ROS 2 wheels (make does), for the hop')
    return _joint_state_hop


def type_support(message_type):
    """Return ``message_type``'s C type support (a capsule), imported as rclpy does."""
    message_type.__class__.__import_type_support__()
    return message_type._TYPE_SUPPORT


class JointStateSource(InputSource):
    """Joint states in: the hop, or rclpy's subscription and a thread (see the module
    docstring).

    :param node: the node the subscription belongs to.
    :param sensor: the :class:`~collision_sensor.sensor.Sensor` that answers.
    :param topics: the answer topics (:class:`~collision_sensor.ros.verdict_topics.VerdictTopics`).
    :param settings: the node's settings (``joint_states_qos``, ``overload_policy``).
    :param log: the node's :class:`~collision_sensor.ros.node_log.NodeLog`.
    :ivar way_in: ``compiled`` or ``rclpy``, once started.
    :ivar rclpy_reason: why the hop is not used ('' when it is).
    """

    name = 'joint_states'

    def __init__(self, node, sensor, topics, settings, log):
        self._node, self._sensor, self._topics, self._log = node, sensor, topics, log
        self._settings = settings
        self.way_in = ''
        self.rclpy_reason = ''
        self._hop = None
        self._worker: Optional[NewestFirstWorker] = None
        self.subscription = None
        self.lost = 0            # messages the middleware reported lost
        self.reader_errors = 0   # messages rclpy could not hand over
        self._hop_seen = {'lost': 0, 'incompatible_qos': 0, 'publish_errors': 0,
                          'take_errors': 0}

    def start(self) -> None:
        settings = self._settings
        backlog = -1 if settings.overload_policy == 'every' else MAX_BACKLOG
        wanted = os.environ.get('COLLISION_SENSOR_JOINT_STATES', WAYS_IN[0])
        if wanted not in WAYS_IN:
            raise ValueError(f'COLLISION_SENSOR_JOINT_STATES "{wanted}" is not one of '
                             f'{", ".join(WAYS_IN)}; fix the environment variable')
        hop = load_hop() if wanted == 'compiled' else 'COLLISION_SENSOR_JOINT_STATES=rclpy'
        if isinstance(hop, str):
            self.rclpy_reason = hop
            self._subscribe_through_the_executor(backlog)
            return
        node = self._node
        self._hop = hop.JointStateHop(
            self._sensor.core.api(), node.handle.pointer, node.context.handle.pointer,
            type_support(JointState), 'joint_states', settings.joint_states_qos == 'reliable',
            backlog)
        self.bind_publishers()
        self._hop.start()
        self.way_in = 'compiled'

    def _subscribe_through_the_executor(self, backlog: int) -> None:
        sensor = self._sensor
        self._worker = NewestFirstWorker(
            lambda batch, newest_only: sensor.take_batch(batch, newest_only),
            'joint_states checker', None if backlog < 0 else backlog)
        self.subscription = self._node.create_subscription(
            JointState, 'joint_states', self._worker.put,
            JOINT_STATES_QOS[self._settings.joint_states_qos], raw=True,
            callback_group=MutuallyExclusiveCallbackGroup(),
            event_callbacks=SubscriptionEventCallbacks(
                message_lost=self._on_message_lost, incompatible_qos=self._on_incompatible_qos,
                use_default_callbacks=False))
        self.way_in = 'rclpy'

    @property
    def topic_name(self) -> str:
        if self._hop is not None:
            return self._hop.topic_name
        return self.subscription.topic_name if self.subscription is not None else ''

    def bind_publishers(self, without=()) -> None:
        """Give the hop the answer topics' publishers as they are now, but the topics
        ``without`` (the warning zone's, before they are withdrawn)."""
        if self._hop is None:
            return
        publishers = self._topics.publishers
        for name, number in TOPIC_NUMBERS.items():
            publisher = None if name in without else publishers.get(name)
            self._hop.set_publisher(number, publisher.handle.pointer if publisher else 0)

    def close(self) -> None:
        """Stop taking joint states (before the node's publishers go)."""
        if self._hop is not None:
            self._hop.stop()
            self._hop = None
        if self._worker is not None:
            self._worker.stop()
            self._worker = None

    def backlog(self) -> int:
        return self._worker.backlog() if self._worker is not None else 0

    # -- what the middleware reports ------------------------------------------------------------

    def poll_events(self) -> None:
        """Count and report what the hop saw since the last poll: messages lost, publishers
        whose QoS cannot match, errors (the executor's thread, every timeout poll)."""
        if self._hop is None:
            return
        counts = self._hop.counts()
        seen = self._hop_seen
        lost = counts['lost'] - seen['lost']
        if lost:
            self.lost += lost
            self._log.warn('lost', f'{lost} joint states lost before the node took them '
                           f'({counts["lost"]} in all): the input is faster than the node or the '
                           'subscription queue (joint_states_qos); counted as lost_total')
        if counts['incompatible_qos'] > seen['incompatible_qos']:
            self._warn_incompatible(counts['last_policy_kind'])
        errors = (counts['publish_errors'] - seen['publish_errors']
                  + counts['take_errors'] - seen['take_errors'])
        if errors:
            self._log.warn('hop_error', f'the joint-state hop met {errors} middleware errors '
                           f'(last: {counts["last_error"]})', 'error')
        self._hop_seen = {key: counts[key] for key in seen}

    def hop_counts(self) -> dict:
        return self._hop.counts() if self._hop is not None else {}

    def _on_message_lost(self, info) -> None:
        self.lost += info.total_count_change
        self._log.warn('lost', f'{info.total_count_change} joint states lost before the node '
                       f'took them ({info.total_count} in all): the input is faster than the node '
                       'or the subscription queue (joint_states_qos); counted as lost_total')

    def _on_incompatible_qos(self, event) -> None:
        self._warn_incompatible(event.last_policy_kind)

    def _warn_incompatible(self, policy) -> None:
        self._log.warn(
            'qos', 'a publisher of joint_states offers a QoS this subscription cannot match '
            f'(policy {policy}); its messages are never received. Publish reliable, or set '
            'joint_states_qos: sensor_data')
