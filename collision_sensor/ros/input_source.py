"""The node's inputs, one class per kind, as nav2 collision_monitor's sources.

Each source owns its subscription(s), the parsing and validation of its messages, its timeout
and its ``/diagnostics`` status, and hands what it validated to the sensor
(:class:`collision_sensor.sensor.Sensor`), which answers. The node composes the sources and
asks them, on its timers and when a new checker comes, for what only they know; a source never
calls into the node. The sources: :mod:`.joint_state_source`, :mod:`.scene_source`,
:mod:`.trajectory_source`, :mod:`.point_cloud_source`.
"""
from typing import Callable, Optional, Tuple

#: What a source's ``prepare_model`` returns: called as ``commit(notes)`` at the moment the
#: prepared checker replaces the current one, with the sensor's core held.
Commit = Callable[[list], None]


class InputSource:
    """One kind of input; subclasses override what they need.

    :ivar name: the input's name, for logs and /diagnostics.
    """

    name = 'input'

    def start(self) -> None:
        """Subscribe (once the first robot model is in place)."""

    def close(self) -> None:
        """Stop the source's threads (the node is being destroyed)."""

    def prepare_model(self, checker) -> Optional[Commit]:
        """Hand this source's data to ``checker`` before it replaces the sensor's (off the
        core, on the thread that built ``checker``, inside ``sensor.editing()``).

        :return: the commit to run at the swap, or None.
        """
        return None

    def poll_timeout(self, now: float, stamp) -> None:
        """Fail safe if the data went missing or too old (``now``: monotonic seconds;
        ``stamp``: the node's clock, for an answer's header)."""

    def status(self, now: float):
        """Return this source's own /diagnostics status, or None."""
        return None

    def apply_settings(self, settings) -> None:
        """Take parameters changed at run time."""


def stamp_now(node) -> Tuple[int, int]:
    """``node``'s clock now as ``(sec, nanosec)``: the header of an answer no input stamped."""
    return divmod(node.get_clock().now().nanoseconds, 1_000_000_000)
