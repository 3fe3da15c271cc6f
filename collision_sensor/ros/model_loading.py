"""Loading the robot: building a checker from ``urdf_path`` or ``robot_description``, and
swapping a new checker in while the node runs.

A checker is built (:func:`build_checker`), its query run once so that nothing compiles on the
first joint state, and, with a warning zone, the pairs near wherever the robot goes named. A new
checker while the node runs (a new ``robot_description``, or a parameter that changes the
checker: ``padding``, ``link_padding``, ``allowed_collisions``) is built on the loader thread
(:class:`ModelLoader`): joint states keep being checked with the current one meanwhile. The
sources then hand it their data (the merged joint state, the scene topic's objects:
:meth:`~collision_sensor.ros.input_source.InputSource.prepare_model`) and it replaces the current
checker under the node's lock, between two checks. Only the newest request waits: a request
made during a build is built next, with the newest robot and parameters.
"""
import collections
import difflib
import threading
import warnings
from typing import Callable, FrozenSet, List, Tuple

from collision_sensor.errors import LoadWarning
from collision_sensor.untrusted_text import printable, quoted

Pair = Tuple[str, str]

#: Largest robot_description accepted (UTF-8 bytes); real URDFs with inline meshes stay far
#: below.
MAX_ROBOT_DESCRIPTION_BYTES = 16 * 1024 * 1024
MODEL_POLL_PERIOD = 0.05    # s between looks for a finished build


def default_checker_factory(urdf, srdf=None, package_paths=None, scene=None, config=None,
                            xacro_args=None):
    from collision_sensor import CollisionChecker
    return CollisionChecker.from_urdf(urdf, srdf=srdf, package_paths=package_paths,
                                      scene=scene, config=config, xacro_args=xacro_args)


def root_link(checker) -> str:
    """Return the frame the checker's world poses are in: the robot's root link."""
    return getattr(getattr(checker, 'model', None), 'root_link', '') or ''


def neutral_positions(checker) -> dict:
    """Every variable at the checker's neutral state: zeros, identity quaternions."""
    kinematics = getattr(checker, 'kinematics', None)
    if kinematics is None or not hasattr(kinematics, 'neutral'):
        return {name: 0.0 for name in checker.joint_names}
    return dict(zip(checker.joint_names, (float(v) for v in kinematics.neutral())))


def build_checker(factory, urdf, settings, notes: list):
    """Build a checker of ``urdf`` (a path, or the document as bytes) with ``settings``
    (:class:`~collision_sensor.ros.node_parameters.NodeSettings`); append its load warnings and
    the warning zone's report to ``notes``.

    :raises CollisionSensorError: the robot cannot be loaded, or a setting does not fit it.

    The loaders' :class:`~collision_sensor.LoadWarning`\\ s are not printed by Python as well:
    the node logs them once, from ``checker.load_warnings``.
    """
    extra = {'xacro_args': settings.xacro_args} if settings.xacro_args else {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always', LoadWarning)
        checker = factory(urdf, srdf=settings.srdf_path,
                          package_paths=settings.package_paths or None,
                          scene=settings.scene_path, config=settings.checker_config, **extra)
    # The LoadWarnings say in one summary what load_warnings says line by line; other warnings
    # are logged as they are.
    lines = list(getattr(checker, 'load_warnings', ())) + [
        str(w.message) for w in caught if not issubclass(w.category, LoadWarning)]
    for line in lines:
        notes.append(('warning', None, f'while loading the robot: {printable(line, 1000)}'))
    notes.extend(pending_name_notes(checker, 'warning_ignore', [
        name for pair in settings.warning_ignore for name in pair]))
    notes.extend(near_everywhere_notes(checker, settings.warning_distance,
                                       settings.warning_ignore))
    # At the state a new checker starts in (every joint at 0, identity quaternions): check
    # then update, so the carried state is the one the first joint state updates from, and
    # the first verdict costs what every later one does.
    start = neutral_positions(checker)
    checker.check(start)
    checker.update(start)
    return checker


def pending_name_notes(checker, parameter: str, names) -> list:
    """Name, with the closest link, each of ``names`` that is neither a link of ``checker``'s
    robot nor one of its scene objects: kept for an object of that name from the scene topic
    (log notes)."""
    links = list(checker.kinematics.link_names)
    known = set(links) | set(checker.object_names)
    notes = []
    for name in sorted(set(names) - known):
        closest = max(links, key=lambda link: difflib.SequenceMatcher(None, name, link).ratio())
        notes.append(('warning', None, (
            f'{parameter} names {quoted(name)}, neither a link of the robot nor a scene object: '
            f'kept for an object of that name from the scene topic (/diagnostics lists it while '
            f'none exists); if you meant the link "{closest}", fix the name')))
    return notes


class ModelLoader:
    """Run :meth:`request`\\ ed builds on a thread of its own, newest request first.

    :param run: called on the loader thread for each request; builds and installs.
    """

    def __init__(self, run: Callable[[], None]):
        self._run_one = run
        self._condition = threading.Condition()
        self._pending = False
        self._closed = False
        self.busy = False
        #: Finished builds' outcomes, for the executor's thread: ``(notes, first model)``.
        self.results = collections.deque()
        self._thread = threading.Thread(target=self._run, name='model loader', daemon=True)
        self._thread.start()

    def request(self) -> None:
        """Build again, with the newest robot and parameters (after the build under way)."""
        with self._condition:
            self._pending = True
            self._condition.notify()

    @property
    def loading(self) -> bool:
        """True while a build runs or waits."""
        return self.busy or self._pending

    def close(self) -> None:
        with self._condition:
            self._closed = True
            self._condition.notify()
        # A build cannot be interrupted; the thread is a daemon and its result is dropped.
        self._thread.join(timeout=0.5)

    def _run(self):
        while True:
            with self._condition:
                while not self._pending and not self._closed:
                    self._condition.wait()
                if self._closed:
                    return
                self._pending = False
                self.busy = True
            try:
                self._run_one()
            finally:
                with self._condition:
                    self.busy = False
                    if self._closed:
                        return


def near_everywhere_notes(checker, distance: float, ignore: FrozenSet[Pair]) -> List[tuple]:
    """Name the pairs nearer than ``distance`` wherever the robot goes, with the fix (log notes,
    see :mod:`collision_sensor.ros.node_log`); nothing when there are none.

    Runs :func:`pairs_near_everywhere` on ``checker``: call it on a checker not in use yet.
    """
    if distance <= 0:
        return []
    # Imported here: sampling brings numpy.random (2 MiB) that a node without a zone never uses.
    from collision_sensor.engine.sampling import (
        NEAR_FRACTION, NEAR_SAMPLES, pairs_near_everywhere)
    found = [pair for pair in pairs_near_everywhere(checker, distance)
             if (pair.link_a, pair.link_b) not in ignore]
    if not found:
        return []
    samples = found[0].samples
    listed = ', '.join(f'{p.link_a}:{p.link_b} ({p.largest:.4f} m at most'
                       + ('' if p.near == p.samples else f', near in {p.near} of {p.samples}')
                       + ')' for p in found)
    entries = ', '.join(f'"{p.link_a}:{p.link_b}"' for p in found)
    return [('warning', None, (
        f'warning zone: {len(found)} pair(s) nearer than warning_distance {distance:g} m '
        f'wherever the robot goes (in at least {NEAR_FRACTION:.0%} of {samples} configurations '
        f'sampled: the neutral one and {NEAR_SAMPLES} uniform within the joint limits), so near '
        f'would be true all the time: {listed}. Leave them out of the zone with the parameter '
        f'warning_ignore: [{entries}], or lower warning_distance below their distance'))]
