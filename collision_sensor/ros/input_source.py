"""The node's inputs, one class per kind, as nav2 collision_monitor's sources.

Each source owns its subscription(s), the validation of its messages, its timeout and the data
it hands over; the node (:class:`~collision_sensor.ros.sensor_node.CollisionSensorNode`)
composes them. Today: :class:`~collision_sensor.ros.joint_state_source.JointStateSource` (the
robot's state: every joint state is answered by a verdict),
:class:`~collision_sensor.ros.scene_source.SceneSource` (objects from the ``scene`` topic) and
:class:`~collision_sensor.ros.trajectory_source.TrajectorySource` (planned trajectories, checked
before they run and relayed when valid).

Adding a kind of input (point clouds) is a module with a subclass of
:class:`InputSource` and one line in ``CollisionSensorNode._make_sources``. A source gets the
node's :class:`SourceHost`, and:

- ``start()`` subscribes (called once, when the first robot model is in place);
- its callbacks validate each message and hand the data over under ``host.lock``: the checker
  (``host.checker``) for scene-like data, whose change is answered with
  ``host.answer_current(notes)``; or a state to check with ``host.check(header, positions)``,
  answering an input it cannot take with ``host.refuse(header, kind, reason, notes)``;
- ``poll_timeout(now, notes)`` says, at least every ``TIMEOUT_POLL_PERIOD``, whether its data
  are missing or too old (``Timeout``): the node then fails safe by the policy the source names
  (``contact``: publish contact; ``hold``: keep the verdict; /diagnostics ERROR either way);
  ``timeout_due(now)``, asked first without the lock, keeps the checking thread from waiting on
  a poll that finds nothing;
- ``prepare_model(checker, stack)`` hands its data to a new checker before that checker replaces
  the current one (a new robot_description, or a parameter change that needs a new checker),
  off the checking thread; the commit it returns runs under the lock at the swap;
- ``status(now)`` is its own /diagnostics status (or None), ``apply_settings(settings)``
  takes parameters changed at run time, ``close()`` stops its threads.

Everything a source does under ``host.lock`` must be quick and must not log: it appends log
lines to ``notes`` (see :mod:`collision_sensor.ros.node_log`) and the caller writes them after
releasing the lock.
"""
import contextlib
from dataclasses import dataclass
from typing import Callable, List, Optional

#: s between two looks at the sources' timeouts.
TIMEOUT_POLL_PERIOD = 0.05

#: What a source's ``prepare_model`` returns: called as ``commit(notes)`` under the lock, at the
#: moment the prepared checker replaces the current one.
Commit = Callable[[list], None]


@dataclass(frozen=True)
class Timeout:
    """A source's data went missing or too old.

    :ivar kind: the ``colliding_pairs`` entry's name (e.g. ``joint_states_stale``).
    :ivar reason: one sentence, with the parameter that sets the timeout; text from the
        network in it escaped (:mod:`collision_sensor.untrusted_text`).
    :ivar policy: ``'contact'`` or ``'hold'`` (see ``verdicts.FAIL_SAFE_POLICIES``).
    """

    kind: str
    reason: str
    policy: str


class SourceHost:
    """What the node offers its sources (documentation of the interface; the node is one).

    :ivar lock: held while a source hands data over and while anything is checked.
    :ivar checker_changes: held from preparing a change of the checker's scene, or a new
        checker, until it is committed; and by a reader that must see one scene throughout
        without the lock (a trajectory check). Taken before ``lock``, never while holding it.
    :ivar joints: the :class:`~collision_sensor.ros.joint_state_source.JointStateSource`
        (``start_state``: where the robot is, for a planned trajectory).
    :ivar log: the node's :class:`~collision_sensor.ros.node_log.NodeLog`.
    :ivar settings: the node's :class:`~collision_sensor.ros.node_parameters.NodeSettings`.
    :ivar checker: the :class:`CollisionChecker` in use (None before the first robot).
    :ivar totals: ``collections.Counter`` of counts reported on /diagnostics.
    :ivar failing: ``{source name: Timeout}``, sources whose ``contact`` timeout must answer
        every verdict (``check``) with their failure until they recover (a source whose
        silence does not stop the joint states, such as a camera's); the source sets and
        clears its entry under the lock.
    """

    def check(self, header, positions):
        """Check ``positions`` and publish the verdict for ``header`` (lock held); raise what
        the engine raised, with nothing published."""
        raise NotImplementedError

    def refuse(self, header, kind: str, reason: str, notes: list) -> None:
        """Answer an input that cannot be checked, by ``on_rejected_input`` (lock held);
        ``reason`` with text from the network escaped already."""
        raise NotImplementedError

    def answer_current(self, notes: list) -> None:
        """Check the current state again and publish the verdict (lock held): the scene
        changed."""
        raise NotImplementedError


class InputSource:
    """One kind of input. Subclasses override what they need; see the module docstring.

    :param host: the node.
    :ivar name: the input's name, for logs and /diagnostics.
    """

    name = 'input'

    def __init__(self, host: SourceHost):
        self.host = host

    def start(self) -> None:
        """Subscribe (once the first robot model is in place)."""

    def close(self) -> None:
        """Stop the source's threads (the node is being destroyed)."""

    def prepare_model(self, checker, stack: contextlib.ExitStack) -> Optional[Commit]:
        """Hand this source's data to ``checker`` before it replaces ``host.checker``.

        Runs off the lock, on the thread that built ``checker``; a source that must exclude its
        own changes until the swap enters a lock into ``stack`` (released after the commit).

        :return: the commit to run under the lock at the swap, or None.
        """
        return None

    def timeout_due(self, now: float) -> bool:
        """Return False only when :meth:`poll_timeout` cannot find a timeout now (without the
        lock: reads only). The default, True, always polls: a source with a timeout that does
        not override this is still failed safe on."""
        return True

    def poll_timeout(self, now: float, notes: list) -> Optional[Timeout]:
        """Return a :class:`Timeout` when the data just went missing or too old (once per
        episode), else None (lock held)."""
        return None

    def timed_out(self) -> bool:
        """Return True while the data are missing or too old."""
        return False

    def status(self, now: float, notes: list):
        """Return this source's own /diagnostics status, or None (lock held)."""
        return None

    def apply_settings(self, settings) -> None:
        """Take parameters changed at run time (lock held)."""


def prepare_all(sources: List[InputSource], checker, stack: contextlib.ExitStack
                ) -> List[Commit]:
    """Return the commits of every source's :meth:`InputSource.prepare_model`."""
    return [commit for commit in (source.prepare_model(checker, stack) for source in sources)
            if commit is not None]
