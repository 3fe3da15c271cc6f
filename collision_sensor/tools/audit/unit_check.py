"""The work of one unit: read a recording, check every frame, return its report line.

The process that forks the workers (the driver with ``--jobs``, each Ray node's host), or the
driver itself with ``--jobs 1``, builds a :class:`UnitChecker` once from a :class:`RobotSpec`
(the robot as loaded by the driver: its model, SRDF, scene and settings, plain arrays that
pickle; no path is opened where it is built) and the units are then checked one after the
other with the same checker. :meth:`UnitChecker.check` never
raises for a bad unit: the reason goes in the line's ``error``.

What each unit is checked for is a list of :class:`UnitCheck` classes, by name in
:data:`UNIT_CHECKS`; :func:`checks_for` picks them from the options. Each sees the recording in
stretches of frames under one scene (a bag's scene arrays are applied between them, by the
node's rules) and gives the keys it adds to the report line. **The seam for motion checks**
(``CollisionChecker.check_motion``, issue 25) is :class:`MotionCheck`, chosen with
``CheckOptions.motion`` (``--motion``): it adds the key ``motion``; the report, resume, pools
and Ray carry it as they carry the others.

A bag's point clouds apply between stretches too, as in ``collision_sensor_check`` on one
recording (:mod:`collision_sensor.tools.recorded_clouds`: the node's rules); the line's
``point_clouds`` counts them, applied and refused by reason, with the first refusals' messages
(null for a recording without clouds). A refused cloud is no failure of the unit.
"""
import contextlib
import dataclasses
import hashlib
import os
import pickle
from dataclasses import dataclass
from typing import Dict, List, Mapping, Optional, Tuple, Type

import numpy as np

from collision_sensor.errors import CollisionSensorError, SequenceError
from collision_sensor.engine.dynamic_scene import AddObject, RemoveObject
from collision_sensor.engine.scene_markers import MarkerError, SceneTopic, apply_array
from collision_sensor.model.joint_map import JointMap
from collision_sensor.model import lerobot
from collision_sensor.model.sequences import (
    DEFAULT_TOPIC, SCENE_TOPIC, JointSequence, read_sequence)
from collision_sensor.tools.audit import shipping
from collision_sensor.tools.audit.units import Unit
from collision_sensor.tools.recorded_clouds import CloudOptions, CloudReplay

#: Engine threads a unit is checked on: one, since units run side by side (``--jobs``, Ray
#: actors), each a core; ``--jobs 1`` is then one core too, as its name says.
UNIT_THREADS = 1

DEMO_ARM_HINT = ('these are the joints of the bundled demo arm, the robot checked when no '
                 '--urdf is given: pass --urdf YOUR_ROBOT.urdf (with --srdf and --package-path '
                 'NAME=DIR as it needs) to check your robot')


def with_demo_arm_hint(message: str, demo: bool) -> str:
    """Return ``message``, saying the robot is the demo arm when it is and the message is about
    joints (a recording of another robot checked without ``--urdf``)."""
    if demo and 'joint' in message:
        return f'{message} ({DEMO_ARM_HINT})'
    return message


@dataclass(frozen=True)
class RobotSpec:
    """The robot as the driver loaded it, to build the same checker anywhere.

    :ivar model: the URDF's model (links, joints, collision triangles).
    :ivar srdf: the SRDF's model, or None.
    :ivar scene: the scene file's objects.
    :ivar config: checker settings (a mapping), or None.
    :ivar package_paths: ``{name: dir}`` for ``package://`` meshes of recorded scene arrays.
    :ivar label: what the robot is, for the summary.
    :ivar demo: True for the bundled demo arm (no ``--urdf``).
    """

    model: object
    srdf: object = None
    scene: tuple = ()
    config: Optional[Mapping] = None
    package_paths: Tuple[Tuple[str, str], ...] = ()
    label: str = ''
    demo: bool = False

    @classmethod
    def load(cls, urdf, srdf=None, package_paths=None, scene=None, config=None,
             xacro_args=None, label: str = '', demo: bool = False) -> 'RobotSpec':
        """Load the files as ``CollisionChecker.from_urdf`` does.

        :raises CollisionSensorError: naming the file at fault.
        """
        from collision_sensor.engine.checker_config import CheckerConfig
        from collision_sensor.model.robot_model import load_urdf
        from collision_sensor.model.scene import load_scene
        from collision_sensor.model.srdf import load_srdf_for_model

        settings = CheckerConfig.from_mapping(config)
        model = load_urdf(urdf, package_paths, primitive_sections=settings.primitive_sections,
                          xacro_args=xacro_args)
        srdf_model = load_srdf_for_model(srdf, model) if srdf is not None else None
        objects = load_scene(scene, package_paths,
                             primitive_sections=settings.primitive_sections) \
            if scene is not None else ()
        return cls(model, srdf_model, tuple(objects), dict(config) if config else None,
                   tuple(sorted((package_paths or {}).items())), label or str(urdf), demo)

    def build(self, threads: Optional[int] = None):
        """Return a new :class:`~collision_sensor.CollisionChecker` of this robot (its batch
        calls on ``threads`` threads when given, else as its settings say)."""
        from collision_sensor import CollisionChecker
        config = dict(self.config or {})
        if threads is not None:
            config['threads'] = threads
        return CollisionChecker(self.model, self.srdf, self.scene, config)

    def digest(self, options: 'CheckOptions') -> str:
        """Return 16 hex digits that change with the robot, its settings or the options: a
        report's lines written under other ones are not resumed (``--resume``). What the files
        hold counts, not where they are: the same robot read from a moved checkout or an
        install space resumes the report."""
        data = pickle.dumps((_without_sources(self.model), _without_sources(self.srdf),
                             tuple(_without_sources(o) for o in self.scene),
                             sorted((self.config or {}).items()), options.digest_fields()),
                            protocol=4)
        return hashlib.sha256(data).hexdigest()[:16]


def _without_sources(value):
    """``value`` (a model, an SRDF or a scene object) with the file names it was read from
    (``source`` fields, and the warnings, which name files) left out."""
    if not dataclasses.is_dataclass(value):
        return value
    names = {f.name for f in dataclasses.fields(value)}
    changes = {'source': ''} if 'source' in names else {}
    if 'warnings' in names:
        changes['warnings'] = ()
    if 'elements' in names:
        changes['elements'] = tuple(_without_sources(e) for e in value.elements)
    return dataclasses.replace(value, **changes)


@dataclass(frozen=True)
class CheckOptions:
    """How every unit is checked (the same on every worker).

    :ivar incremental: ``update_batch`` (the default) or ``check_batch`` (``--full``).
    :ivar max_distance: > 0: also each unit's closest approach while clear (m).
    :ivar topic: the JointState topic of bags.
    :ivar scene_topic: the MarkerArray topic of a bag's scene changes.
    :ivar joint_map: how dataset state entries become joints (None: named as the joints).
    :ivar motion: also check the motion between consecutive frames (:class:`MotionCheck`).
    :ivar cloud_topics: the PointCloud2 topics of bags (None: every one; ``()``: none).
    :ivar clouds: the clouds' range and persistence (voxel size, self-filter padding and max
        points are the checker's settings).
    """

    incremental: bool = True
    max_distance: float = 0.0
    topic: str = DEFAULT_TOPIC
    scene_topic: str = SCENE_TOPIC
    joint_map: Optional[JointMap] = None
    motion: bool = False
    cloud_topics: Optional[Tuple[str, ...]] = None
    clouds: CloudOptions = CloudOptions()

    def digest_fields(self) -> tuple:
        fields = (self.incremental, self.max_distance, self.topic, self.scene_topic,
                  self.joint_map, self.motion)
        if self.cloud_topics is None and self.clouds == CloudOptions():
            return fields       # as before clouds: reports of then resume
        return fields + (self.cloud_topics, self.clouds)


class UnitCheck:
    """One kind of check run on every unit (see the module docstring)."""

    #: The report keys it gives, with their value for a unit that failed.
    EMPTY: Dict[str, object] = {}

    def __init__(self, options: CheckOptions, seq: JointSequence):
        self.options, self.seq = options, seq

    def segment(self, checker, start: int, stop: int) -> None:
        """Check frames ``start:stop`` of the sequence; ``checker`` has their scene."""
        raise NotImplementedError

    def result(self) -> Dict[str, object]:
        """Return the keys this check adds to the unit's report line."""
        raise NotImplementedError

    @staticmethod
    def summary_lines(records) -> List[str]:
        """Return this check's lines of the batch's summary (the report's checked lines)."""
        return []


def apply_recorded(topic: SceneTopic, checker, event) -> None:
    """Apply a recorded scene array as the node applies the topic's.

    :raises MarkerError: an array the node would reject, naming the time it was recorded.
    """
    try:
        apply_array(topic, checker, event.markers)
    except MarkerError as error:
        raise MarkerError(error.index, event.markers[error.index],
                          f'{error.reason} (in the scene array recorded at {event.time:.3f} '
                          's)') from None


def frame_durations(times: np.ndarray) -> np.ndarray:
    """How long each frame stands: until the next; the last as long as the one before."""
    if len(times) < 2:
        return np.zeros(len(times))
    gaps = np.diff(times)
    return np.append(gaps, gaps[-1])


class ContactCheck(UnitCheck):
    """Which frames are in collision and which pairs touch, first and last time of each.

    Keys: ``frames_in_collision`` (int), ``time_in_collision`` (s, each frame standing until
    the next), ``pairs``: ``[{"link_a", "link_b", "first", "last", "frames"}]``, times in s
    from the first frame, sorted by first time then names.
    """

    EMPTY = {'frames_in_collision': None, 'time_in_collision': None, 'pairs': []}

    def __init__(self, options: CheckOptions, seq: JointSequence):
        super().__init__(options, seq)
        self.in_collision = np.zeros(len(seq), dtype=bool)
        self.spans: Dict[Tuple[str, str], List[int]] = {}   # pair -> [first, last, frames]

    def segment(self, checker, start: int, stop: int) -> None:
        rows = self.seq.positions[start:stop]
        statuses = checker.update_batch(rows) if self.options.incremental \
            else checker.check_batch(rows)
        self.in_collision[start:stop] = statuses.any(axis=1)
        pairs = checker.checked_pairs
        for column in np.flatnonzero(statuses.any(axis=0)).tolist():
            hits = np.flatnonzero(statuses[:, column])
            first, last = int(hits[0]) + start, int(hits[-1]) + start
            span = self.spans.setdefault(tuple(pairs[column]), [first, last, 0])
            span[1] = last
            span[2] += len(hits)

    def result(self) -> Dict[str, object]:
        times = self.seq.times
        t0 = float(times[0])
        durations = frame_durations(times)
        pairs = sorted(self.spans.items(), key=lambda item: (item[1][0], item[0]))
        return {
            'frames_in_collision': int(self.in_collision.sum()),
            'time_in_collision': float(durations[self.in_collision].sum()),
            'pairs': [{'link_a': a, 'link_b': b, 'first': float(times[first] - t0),
                       'last': float(times[last] - t0), 'frames': frames}
                      for (a, b), (first, last, frames) in pairs],
        }


class ClosestApproach(UnitCheck):
    """The smallest distance between checked pairs while no pair touches (``--max-distance``).

    Key ``closest_approach``: ``{"distance", "link_a", "link_b", "time"}`` (m, s from the first
    frame), or null when no pair came within ``max_distance`` while clear.
    """

    EMPTY = {'closest_approach': None}

    def __init__(self, options: CheckOptions, seq: JointSequence):
        super().__init__(options, seq)
        self.best: Optional[Tuple[float, int, str, str]] = None

    def segment(self, checker, start: int, stop: int) -> None:
        for index in range(start, stop):
            records = checker.proximity(self.seq.positions[index], self.options.max_distance)
            if records and records[0].distance > 0.0 and (
                    self.best is None or records[0].distance < self.best[0]):
                self.best = (records[0].distance, index, records[0].link_a, records[0].link_b)

    @staticmethod
    def summary_lines(records) -> List[str]:
        near = [r for r in records if r.get('closest_approach')]
        if not near:
            return ['', 'closest approach while clear: no pair within --max-distance']
        r = min(near, key=lambda r: (r['closest_approach']['distance'], r['source']))
        c = r['closest_approach']
        return ['', f'closest approach while clear: {c["distance"]:.6f} m ({c["link_a"]} -- '
                f'{c["link_b"]}) at {c["time"]:.3f} s in {r["source"]}; {len(near)} units came '
                'within --max-distance']

    def result(self) -> Dict[str, object]:
        if self.best is None:
            return {'closest_approach': None}
        distance, index, a, b = self.best
        return {'closest_approach': {'distance': float(distance), 'link_a': a, 'link_b': b,
                                     'time': float(self.seq.times[index] - self.seq.times[0])}}


def motion_contacts(checker, rows: np.ndarray) -> List[Tuple[int, float, Tuple]]:
    """Return ``(i, fraction, pairs)`` for every straight motion ``rows[i] -> rows[i + 1]``
    that meets contact (``CollisionChecker.check_path``, run again after each such segment):
    its first contact's fraction of the segment and the pairs in contact there."""
    found = []
    start = 0
    while start < len(rows) - 1:
        path = checker.check_path(rows[start:])
        if path.first_invalid_segment is None:
            break
        i = start + path.first_invalid_segment
        found.append((i, path.motion.first_contact, path.motion.colliding_pairs))
        start = i + 1
    return found


class MotionCheck(UnitCheck):
    """The motion between consecutive frames (``--motion``, issue 25): each straight motion
    from one frame to the next, certified (``CollisionChecker.check_path``), so a contact
    between two recorded states is found even when both are clear. The frames' scene holds:
    a recorded scene array applies from the motion into the frame it precedes.

    Key ``motion``: ``{"segments", "segments_in_contact", "missed_by_states" (segments in
    contact between two clear frames: what checking the recorded states alone misses),
    "first_contact": {"time", "segment", "pairs"} or null}``, times in s from the first frame.
    """

    EMPTY = {'motion': None}

    def __init__(self, options: CheckOptions, seq: JointSequence):
        super().__init__(options, seq)
        self.segments: List[Tuple[int, float, Tuple]] = []
        self.clear = np.ones(len(seq), dtype=bool)

    def segment(self, checker, start: int, stop: int) -> None:
        first = max(start - 1, 0)
        rows = self.seq.positions[first:stop]
        self.clear[start:stop] = ~checker.check_batch(self.seq.positions[start:stop]).any(
            axis=1)
        self.segments += [(first + i, fraction, pairs)
                          for i, fraction, pairs in motion_contacts(checker, rows)]

    def result(self) -> Dict[str, object]:
        times = self.seq.times
        t0 = float(times[0])
        missed = sum(1 for i, _, _ in self.segments if self.clear[i] and self.clear[i + 1])
        first = None
        if self.segments:
            i, fraction, pairs = min(self.segments)
            first = {'time': float(times[i] + fraction * (times[i + 1] - times[i]) - t0),
                     'segment': i, 'pairs': [list(pair) for pair in pairs]}
        return {'motion': {'segments': max(len(self.seq) - 1, 0),
                           'segments_in_contact': len(self.segments),
                           'missed_by_states': missed, 'first_contact': first}}

    @staticmethod
    def summary_lines(records) -> List[str]:
        checked = [r for r in records if r.get('motion')]
        hit = [r for r in checked if r['motion']['segments_in_contact']]
        missed = [r for r in hit if r['motion']['missed_by_states']]
        met = sum(r['motion']['segments_in_contact'] for r in hit)
        lines = ['', f'motion between frames: {met} segments meet contact in {len(hit)} of '
                 f'{len(checked)} units']
        if missed:
            lines.append(f'  {sum(r["motion"]["missed_by_states"] for r in missed)} of them '
                         f'between two clear frames, in {len(missed)} units (checks of the '
                         'recorded states alone miss them)')
        return lines


#: Every kind of check by name.
UNIT_CHECKS: Dict[str, Type[UnitCheck]] = {'contacts': ContactCheck,
                                           'closest': ClosestApproach,
                                           'motion': MotionCheck}


def checks_for(options: CheckOptions) -> List[Type[UnitCheck]]:
    """Return the checks every unit runs under ``options``, in report order."""
    chosen = [UNIT_CHECKS['contacts']]
    if options.max_distance > 0:
        chosen.append(UNIT_CHECKS['closest'])
    if options.motion:
        chosen.append(UNIT_CHECKS['motion'])
    return chosen


def record_keys(options: CheckOptions) -> List[str]:
    """Return a report line's keys, in order, under ``options``."""
    keys = ['source', 'format', 'frames', 'start_time', 'duration', 'scene_changes',
            'point_clouds']
    for check in checks_for(options):
        keys += list(check.EMPTY)
    return keys + ['error']


class UnitChecker:
    """A worker's checker: built once, then one unit after another (see the module doc).

    Built in the process that forks the workers, it is theirs too: a forked worker checks with
    the parent's checker, its trees in pages shared copy-on-write with the parent (the
    engine's queries write only the carried state, and the trees are never written), so N
    workers hold the model once. A unit whose recording changes the scene or brings point
    clouds lays out the engine's arrays anew (a copy of its own in that worker); afterwards
    the scene as loaded is put back (:meth:`restore_scene`), not rebuilt.
    """

    def __init__(self, spec: RobotSpec, options: CheckOptions, checker=None):
        """:param checker: the checker of ``spec`` to use, built with UNIT_THREADS threads
        (None: built here)."""
        self.spec, self.options = spec, options
        self._checker = checker
        if options.joint_map is not None:
            options.joint_map.check_robot(self.checker.joint_names)

    @property
    def checker(self):
        """The checker, with the scene as loaded. A unit is checked on one core
        (UNIT_THREADS): the units are what runs in parallel, so ``--jobs N`` uses N cores, not
        N times the engine's batch threads."""
        if self._checker is None:
            self._checker = self.spec.build(threads=UNIT_THREADS)
        return self._checker

    def restore_scene(self) -> None:
        """Give the checker its scene as loaded again (the spec's objects, no point cloud):
        every object removed and the spec's added back, in one change; the robot's trees are
        kept. A checker that refuses is dropped (the next unit builds a new one)."""
        checker = self._checker
        if checker is None:
            return
        try:
            for source in checker.point_cloud_sources:
                checker.clear_points(source)
            checker.apply_scene_changes([RemoveObject(name) for name in checker.object_names]
                                        + [AddObject(obj) for obj in self.spec.scene])
        except CollisionSensorError:
            self._checker = None

    def check(self, unit: Unit, payload: Optional[shipping.Payload] = None) -> Dict[str, object]:
        """Return ``unit``'s report line (a dict in :func:`record_keys` order); never raises
        for the unit's own faults (the reason is in ``error``).

        :param payload: the unit's files (:func:`shipping.pack`) when this worker cannot read
            ``unit.path``; None to read it.
        """
        record = self.failed_record(unit, self.options, None)
        try:
            record['format'] = unit.format
            with self._local(unit, payload) as local:
                seq = self._read(unit, payload, local)
                record.update(frames=len(seq), start_time=float(seq.times[0]),
                              duration=seq.duration, scene_changes=len(seq.scene))
                results, clouds = self._run(seq)
            record['point_clouds'] = clouds
            for keys in results:
                record.update(keys)
        except CollisionSensorError as err:
            record['error'] = with_demo_arm_hint(' '.join(str(err).split()), self.spec.demo)
        except OSError as err:
            record['error'] = f'{getattr(err, "filename", None) or unit.path}: cannot read: ' \
                f'{err.strerror or err}'
        except Exception as err:     # a fault of ours: reported, and the batch goes on
            record['error'] = f'internal error: {type(err).__name__}: {err}'
        if record['error'] is not None:
            for check in checks_for(self.options):
                record.update(check.EMPTY)
        return record

    @staticmethod
    def failed_record(unit: Unit, options: CheckOptions, error: Optional[str]
                      ) -> Dict[str, object]:
        """Return ``unit``'s report line with nothing measured and ``error``."""
        record: Dict[str, object] = {'source': unit.source, 'format': None, 'frames': None,
                                     'start_time': None, 'duration': None,
                                     'scene_changes': None, 'point_clouds': None}
        for check in checks_for(options):
            record.update(check.EMPTY)
        record['error'] = error
        return record

    @staticmethod
    @contextlib.contextmanager
    def _local(unit: Unit, payload):
        """Yield the path to read ``unit`` from: its own, or its shipped files unpacked here
        (kept while the unit is checked: a bag's clouds are read when applied)."""
        if payload is None or unit.kind == 'lerobot':
            yield unit.path
            return
        with shipping.unpacked(unit, payload) as local:
            try:
                yield local
            except SequenceError as err:
                raise SequenceError(shipping.relabel(str(err), local, unit.path)) from None

    def _read(self, unit: Unit, payload, local: str) -> JointSequence:
        return read_unit(unit, self.options, self.checker.joint_names, payload, local)

    def _run(self, seq: JointSequence):
        """Run every check over the frames, the recorded scene arrays and point clouds
        applied between stretches (:meth:`JointSequence.scene_before`,
        :class:`~collision_sensor.tools.recorded_clouds.CloudReplay`); return the checks'
        keys and the ``point_clouds`` entry."""
        checker = self.checker
        checks = [kind(self.options, seq) for kind in checks_for(self.options)]
        events = seq.scene_before() if seq.scene else [()] * len(seq)
        clouds = CloudReplay(seq, self.options.clouds)
        starts = [0] + ([i for i in range(1, len(seq)) if events[i] or clouds.due(i)]
                        if seq.scene or seq.clouds else []) + [len(seq)]
        topic = SceneTopic(package_paths=dict(self.spec.package_paths) or None)
        try:
            checker.check(seq.positions[0])
            for start, stop in zip(starts[:-1], starts[1:]):
                for event in events[start]:
                    apply_recorded(topic, checker, event)
                if clouds.due(start):
                    clouds.apply_before(checker, start)
                for check in checks:
                    check.segment(checker, start, stop)
            clouds.finish()
        except Exception:
            self.restore_scene()   # whatever state an error left, the next unit starts clean
            raise
        if seq.scene or seq.clouds:
            self.restore_scene()   # the next unit gets the scene as loaded
        return [check.result() for check in checks], (clouds.counts() if seq.clouds else None)


def read_unit(unit: Unit, options: CheckOptions, joint_names, payload=None,
              local: Optional[str] = None) -> JointSequence:
    """Read ``unit``'s frames as positions of ``joint_names``: a dataset episode through
    ``options.joint_map`` (or its entries named as the joints), a recording by the topics of
    ``options``; the sequence's ``source`` is the unit's own path, also when shipped.

    :param payload: an episode's parquet bytes when shipped (:mod:`shipping`), else None.
    :param local: where a shipped recording was unpacked (None: ``unit.path``).
    :raises SequenceError: naming the recording or episode and the fault.
    """
    if unit.kind == 'lerobot':
        joint_map = options.joint_map or JointMap.identity(joint_names)
        return lerobot.read_episode(unit.episode, joint_map, joint_names, data=payload)
    seq = read_sequence(local or unit.path, topic=options.topic, joint_names=joint_names,
                        scene_topic=options.scene_topic, cloud_topics=options.cloud_topics)
    return JointSequence(seq.joint_names, seq.times, seq.positions, unit.path, seq.scene,
                         seq.clouds)


def rss_bytes() -> int:
    """Return this process's resident set size (Linux ``/proc``; 0 elsewhere)."""
    try:
        with open('/proc/self/statm') as stream:
            return int(stream.read().split()[1]) * os.sysconf('SC_PAGE_SIZE')
    except (OSError, ValueError, IndexError):
        return 0
