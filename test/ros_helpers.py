"""Real rclpy in the test process, without launch: a Context, an executor, a namespace.

Each test gets a :class:`RosHarness` of its own (``ros`` fixture in ``ros/node_harness.py``), so no
test sees another's topics or parameters, and everything is torn down even when it fails.
DDS stays in shared memory, in this run's domain (``test/conftest.py``).
"""
import re
import threading
import time
import uuid
from typing import Callable, List

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

#: s: the limit of a wait that ends on what it waits for (a message, a status, a process
#: exiting). Far above what any takes on a quiet machine, so that a loaded one (CI shares its
#: machine) never fails a test; a wait that succeeds returns as soon as its condition holds.
WAIT = 300.0


class Recorder:
    """Keep every message a probe subscription receives, in arrival order."""

    def __init__(self):
        self.messages: List = []

    def __call__(self, msg) -> None:
        self.messages.append(msg)

    def __len__(self) -> int:
        return len(self.messages)

    @property
    def last(self):
        return self.messages[-1] if self.messages else None


class RosHarness:
    """A Context of its own with a probe node and a single-threaded executor.

    :param name: a label for the namespace (a test's name); made unique with a random suffix.
    """

    def __init__(self, name: str):
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context)
        label = re.sub(r'[^0-9a-zA-Z_]', '_', name)[:40].strip('_') or 'test'
        self.namespace = f'/{label}_{uuid.uuid4().hex[:8]}'
        self.executor = SingleThreadedExecutor(context=self.context)
        self._nodes: List[Node] = []
        # What the sensor nodes logged as an internal error: a bug, unless a test provokes one
        # (it then sets internal_errors_expected).
        self.internal_errors: List[str] = []
        self.internal_errors_expected = False
        self.probe = self.add(Node('probe', namespace=self.namespace, context=self.context))

    def add(self, node: Node) -> Node:
        """Spin ``node`` with this harness's executor and destroy it at :meth:`close`."""
        self.executor.add_node(node)
        self._nodes.append(node)
        log = getattr(node, 'log', None)
        if log is not None and hasattr(log, 'write'):
            self._watch_internal_errors(log)
        return node

    def _watch_internal_errors(self, log) -> None:
        logged = log.log

        def log_and_keep(level: str, text: str) -> None:
            if 'internal error' in text:
                self.internal_errors.append(text)
            logged(level, text)
        log.log = log_and_keep

    def remove(self, node: Node) -> None:
        """Stop spinning ``node`` and destroy it now."""
        self.executor.remove_node(node)
        self._nodes.remove(node)
        node.destroy_node()

    def record(self, msg_type, topic: str, qos) -> Recorder:
        """Subscribe the probe to ``topic`` (relative to the namespace) and record messages."""
        recorder = Recorder()
        self.probe.create_subscription(msg_type, topic, recorder, qos)
        return recorder

    def publisher(self, msg_type, topic: str, qos=10):
        """Return a probe publisher on ``topic`` (relative to the namespace)."""
        return self.probe.create_publisher(msg_type, topic, qos)

    def spin_until(self, condition: Callable[[], bool], timeout: float = WAIT) -> bool:
        """Spin until ``condition()`` is true; return False if ``timeout`` seconds pass first."""
        deadline = time.monotonic() + timeout
        while not condition():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self.executor.spin_once(timeout_sec=min(remaining, 0.05))
        return True

    def spin_for(self, seconds: float) -> None:
        """Spin for ``seconds``, whatever happens (to show that nothing arrives)."""
        self.spin_until(lambda: False, seconds)

    def wait_for_subscribers(self, publisher, count: int = 1, timeout: float = WAIT) -> bool:
        """Spin until ``publisher`` is matched by ``count`` subscriptions."""
        return self.spin_until(lambda: publisher.get_subscription_count() >= count, timeout)

    def close(self) -> None:
        """Destroy every node, the executor and the context."""
        for node in reversed(self._nodes):
            self.executor.remove_node(node)
            node.destroy_node()
        self._nodes.clear()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)
        assert self.internal_errors_expected or not self.internal_errors, \
            f'the node logged internal errors: {self.internal_errors[:3]}'


def node_status(ros: RosHarness, diagnostics: Recorder, which: str, condition,
                timeout: float = WAIT):
    """Spin until the node ``collision_sensor``'s /diagnostics status ``which`` (``collision
    sensor``, ``scene``, ``trajectory``) satisfies ``condition(status, values)``; return the
    newest that does, as ``(status, {key: value})``.

    :param diagnostics: the probe's recorder of /diagnostics.
    """
    name = f'{ros.namespace.strip("/")}/collision_sensor: {which}'
    found = []

    def ready():
        for msg in diagnostics.messages:
            for status in msg.status:
                values = {kv.key: kv.value for kv in status.values}
                if status.name == name and condition(status, values):
                    found.append((status, values))
        return bool(found)

    assert ros.spin_until(ready, timeout), f'no matching {which} status'
    return found[-1]


def reliable(depth: int = 10, latched: bool = False) -> QoSProfile:
    """Return a reliable profile; ``latched`` adds transient-local durability."""
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                  else DurabilityPolicy.VOLATILE))


class PlayerThread:
    """``collision_sensor.ros.player.main(argv)`` in a thread, with an rclpy Context of its own."""

    def __init__(self, argv):
        from collision_sensor.ros import player
        self.context = rclpy.Context()
        self.status = None
        self.thread = threading.Thread(
            target=lambda: setattr(self, 'status', player.main(argv, context=self.context)),
            daemon=True)
        self.thread.start()

    def join(self, timeout=WAIT):
        """Wait for the player to finish; return its exit status (None if still running)."""
        self.thread.join(timeout)
        return self.status

    def stop(self, timeout=WAIT):
        """Shut the player's context down and wait for it; return its exit status."""
        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout)
        return self.status
