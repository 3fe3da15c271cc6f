"""The ``scene`` input: ``visualization_msgs/MarkerArray`` changing the checker's scene objects.

Every array changes the scene all or nothing (:mod:`collision_sensor.engine.scene_markers` has
the rules; docs/dynamic_scene.md). Arrays are applied in arrival order on a thread of their
own: files are read and trees built there, without holding the sensor, so joint states keep
getting verdicts meanwhile (with the scene as it was); only the swap holds it. Every array is
answered at once: by the ``scene`` status on ``/diagnostics`` (its counts of arrays applied and
rejected), and, once a joint state completes the state, by a verdict (its header: the time and
the root frame) besides those of the joint states. A rejected array changes nothing (its verdict
is the scene as it was) and is named, with the fix, in one log line and in that status.

A new checker (a new robot, or a parameter change that needs one) gets the objects that came
through the topic before it replaces the current one, so no verdict is given without them; if
they do not fit a new robot they are dropped, and the log says so.
"""
import collections
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from collision_sensor.engine.dynamic_scene import SceneChangeError
from collision_sensor.engine.scene_markers import MarkerError, SceneTopic, marker_error
from collision_sensor.errors import SceneError
from collision_sensor.ros.input_source import InputSource, stamp_now
from collision_sensor.ros.work_queue import NewestFirstWorker
from collision_sensor.sensor.model import root_link
from collision_sensor.untrusted_text import listing, printable

#: The scene topic: reliable and transient local (an array published before the node started
#: still arrives, if its publisher is transient local too), the last SCENE_DEPTH arrays kept.
SCENE_DEPTH = 100
SCENE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=SCENE_DEPTH,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Scene arrays that may wait to be applied; more are dropped and counted (each can hold a
#: mesh: the wait must not grow without bound).
MAX_SCENE_BACKLOG = 100


class SceneSource(InputSource):
    """Scene arrays: subscription, conversion and validation, the hand-over to the sensor, the
    ``scene`` status.

    :param node: the node the subscription belongs to (and whose name the status carries).
    :param sensor: the :class:`~collision_sensor.sensor.Sensor` the changes go to.
    :param settings: the node's settings (``scene_limits``, ``package_paths``).
    :param log: the node's :class:`~collision_sensor.ros.node_log.NodeLog`.
    :param markers: the node's :class:`~collision_sensor.ros.markers.MarkerPublisher`, told
        when the objects changed.
    :param diagnostics: the ``/diagnostics`` publisher: each array's status goes out at once.
    """

    name = 'scene'

    def __init__(self, node, sensor, settings, log, markers, diagnostics):
        self._node, self._sensor, self._log, self._markers = node, sensor, log, markers
        self._diagnostics = diagnostics
        self.topic = SceneTopic(settings.scene_limits, settings.package_paths or None)
        self._worker: Optional[NewestFirstWorker] = None
        self.rejection = ''    # the last rejected array's reason, '' once one applied
        self.counts = collections.Counter()

    def start(self) -> None:
        # Arrays published before arrive now (transient local).
        self._worker = NewestFirstWorker(self._apply_batch, 'scene applier', None)
        self._node.create_subscription(
            MarkerArray, 'scene', self._on_scene, SCENE_QOS,
            callback_group=MutuallyExclusiveCallbackGroup(),
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=self._on_incompatible_qos, use_default_callbacks=False))

    def close(self) -> None:
        if self._worker is not None:
            self._worker.stop()
            self._worker = None

    def prepare_model(self, checker):
        """Prepare the topic's objects on ``checker`` (the sensor is held still meanwhile: no
        array is committed to the old checker)."""
        topic = self.topic
        if not topic.objects:
            return None
        try:
            prepared = checker.prepare_scene_changes(topic.readd_changes())
        except SceneError as error:
            reason = printable(error, 1000)

            def drop(notes: list) -> None:
                topic.objects = {}
                self.counts['rejected'] += 1
                notes.append(('error', None, 'the objects from the scene topic do not fit the '
                              f'new robot model and are dropped: {reason}; publish them again'))
            return drop

        def commit(notes: list) -> None:
            checker.commit_scene_changes(prepared)
            notes.append(('info', None, f'{len(topic.objects)} objects from the scene topic '
                          'added to the new checker'))
        return commit

    # -- the executor's thread ----------------------------------------------------------------

    def _on_scene(self, msg: MarkerArray) -> None:
        """Hand an array to the scene thread (nothing slow here)."""
        if self._worker.backlog() >= MAX_SCENE_BACKLOG:
            self.counts['dropped'] += 1
            self._log.warn('scene_dropped', f'scene array dropped: {MAX_SCENE_BACKLOG} arrays '
                           'wait to be applied already (counted as scene_arrays_dropped_total); '
                           'publish scene changes more slowly')
            return
        self._worker.put(msg)

    def _on_incompatible_qos(self, event) -> None:
        self._log.warn(
            'scene_qos', 'a publisher of scene offers a QoS this subscription cannot match '
            f'(policy {event.last_policy_kind}); its arrays are never received. Publish scene '
            'reliable and transient local')

    # -- the scene thread ---------------------------------------------------------------------

    def _apply_batch(self, batch: list, _newest_only: bool) -> None:
        """Apply every array of ``batch`` in order."""
        for msg in batch:
            notes = []
            try:
                self._apply(list(msg.markers), notes)
            except Exception as error:  # noqa: B902 - one array must never stop the node
                if not self._node.context.ok():
                    return
                notes.append(('error', None, 'scene array skipped after an internal error: '
                              f'{printable(repr(error), 300)}'))
            self._log.write(notes)

    def _apply(self, markers: list, notes: list) -> None:
        """Apply one array: convert it and build its trees without holding the sensor's core,
        then have the sensor swap the scene in and answer at once."""
        sensor, topic = self._sensor, self.topic
        stamp = stamp_now(self._node)
        # Changes are prepared and committed in arrival order, none while a new checker is
        # prepared or a trajectory checked (sensor.editing()).
        with sensor.editing() as checker:
            try:
                update = topic.update(markers, checker)
                try:
                    prepared = checker.prepare_scene_changes(update.changes)
                except SceneChangeError as error:
                    raise marker_error(error, update, markers) from None
            except MarkerError as error:
                self._reject(str(error), stamp, notes)
                return
            verdict = sensor.apply_scene_changes(prepared, stamp)
            topic.accept(update)
        self.counts['applied'] += 1
        self.counts['verdicts'] += verdict is not None
        self.rejection = ''
        self._markers.scene_changed = True
        notes.append(('info', 'scene_applied', printable(
            f'scene array of {len(markers)} markers applied: {update.summary}', 500)))
        self._publish_status()

    def _reject(self, reason: str, stamp, notes: list) -> None:
        """Count a rejected array, answer it (the scene as it was) and log it once."""
        text = printable(reason, 1000)
        self.counts['rejected'] += 1
        self.rejection = text
        self.counts['verdicts'] += self._sensor.answer_current(stamp) is not None
        self._publish_status()
        notes.append(('error', None, f'scene array rejected, scene unchanged: {text}'))

    # -- diagnostics --------------------------------------------------------------------------

    def _publish_status(self) -> None:
        """Publish this source's status on /diagnostics now (an array's answer)."""
        now = self._node.get_clock().now().to_msg()
        self._diagnostics.publish(DiagnosticArray(header=Header(stamp=now),
                                                  status=[self.status(0.0)]))

    def status(self, now: float) -> DiagnosticStatus:
        """The ``scene`` status on /diagnostics: the objects, what came through the topic, and
        the last rejected array's reason until one applies."""
        checker, topic, counts = self._sensor.checker, self.topic, self.counts
        names = checker.object_names if checker is not None else ()
        attached = checker.attachments if checker is not None else {}
        from_topic = dict(topic.objects)
        level, message = DiagnosticStatus.OK, f'{len(names)} objects ({len(from_topic)} from ' \
            'the scene topic)'
        if self.rejection:
            level, message = DiagnosticStatus.WARN, f'last array rejected: {self.rejection}'
        values = {
            'objects': listing(names),
            'objects_count': str(len(names)),
            'attached': listing((f'{printable(name)} on {printable(link)}'
                                 for name, (link, _) in attached.items()),
                                total=len(attached), escape=False),
            'topic_objects_count': str(len(from_topic)),
            'topic_triangles': str(sum(item.triangles for item in from_topic.values())),
            'scene_arrays_applied_total': str(counts['applied']),
            'scene_arrays_rejected_total': str(counts['rejected']),
            'scene_arrays_dropped_total': str(counts['dropped']),
            'scene_verdicts_total': str(counts['verdicts']),
            'last_rejection': self.rejection,
        }
        return DiagnosticStatus(
            level=level, name=f'{self._node.get_fully_qualified_name().lstrip("/")}: scene',
            message=printable(message, 1000),
            hardware_id=printable(root_link(checker) if checker is not None else ''),
            values=[KeyValue(key=key, value=value) for key, value in values.items()])
