"""The answer topics: ``contact`` and ``colliding_pairs`` always, ``near``, ``min_distance`` and
``near_pairs`` with the warning zone (``warning_distance`` > 0).

The sensor core makes each answer as serialized messages and hands them over in order (what
they hold: ``cpp/sensor_answer.hpp``); they go out on these publishers as they are, either
through the joint-state hop (rcl, no Python) or through rclpy (``publish``). The zone's
publishers exist only while the zone is on: turned on, they are advertised before the core
makes zone answers; turned off, they are withdrawn after it stopped.
"""
from typing import Dict

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, Float64

from collision_sensor.ros.work_queue import MAX_INPUT_RATE

#: The robot description: late joiners get the latest message.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: The answers' history covers 0.1 s of input at ``MAX_INPUT_RATE``: a reliable subscriber
#: 0.1 s behind still gets every answer; a late joiner gets the latest ones.
VERDICT_DEPTH = int(0.1 * MAX_INPUT_RATE)
VERDICT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=VERDICT_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

#: The warning zone's topics.
ZONE_TOPICS = ('near', 'min_distance', 'near_pairs')


class VerdictTopics:
    """The answer topics' publishers.

    :param node: the node that owns them.
    :param zone: advertise the warning zone's topics too.
    """

    def __init__(self, node, zone: bool):
        self._node = node
        self.publishers: Dict[str, object] = {
            'contact': node.create_publisher(Bool, 'contact', VERDICT_QOS),
            'colliding_pairs': node.create_publisher(DiagnosticArray, 'colliding_pairs',
                                                     VERDICT_QOS)}
        if zone:
            self.advertise_zone()

    @property
    def zone(self) -> bool:
        return 'near' in self.publishers

    def advertise_zone(self) -> None:
        if 'near' in self.publishers:
            return
        node = self._node
        self.publishers.update(
            near=node.create_publisher(Bool, 'near', VERDICT_QOS),
            min_distance=node.create_publisher(Float64, 'min_distance', VERDICT_QOS),
            near_pairs=node.create_publisher(DiagnosticArray, 'near_pairs', VERDICT_QOS))

    def withdraw_zone(self) -> None:
        for name in ZONE_TOPICS:
            publisher = self.publishers.pop(name, None)
            if publisher is not None:
                self._node.destroy_publisher(publisher)

    def publish(self, topic: str, message: bytes) -> None:
        """Publish one serialized message of an answer (rclpy's way)."""
        publisher = self.publishers.get(topic)
        if publisher is not None:
            publisher.publish(message)

