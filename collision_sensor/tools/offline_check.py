"""``collision_sensor_check``: run the collision checker over a recorded sequence, without ROS.

Every frame goes through ``checker.update`` (the incremental check, sec. 4 of the paper) in
order; ``--full`` uses ``checker.check`` instead. The robot defaults to the bundled demo cell
(``config/demo_arm.urdf`` with its SRDF and ``config/demo_scene.yaml``)::

    collision_sensor_check paper_experiment --plot contacts.png
    collision_sensor_check run.mcap --urdf my_robot.urdf --package-path my_robot=~/ws/src/my_robot

A bag's scene changes (``visualization_msgs/MarkerArray`` on ``/scene``, ``--scene-topic``)
are applied before the frames they precede, by the node's rules
(:mod:`collision_sensor.engine.scene_markers`): objects added, moved, attached and removed while the
robot moves. A recorded array the node would reject stops the run with its reason (status 2).

A bag's point clouds (``sensor_msgs/PointCloud2``: every topic of that type, or the topics of
``--cloud-topic``; ``--no-clouds`` for none) are applied as the node applies its
``point_cloud_topics`` (:mod:`collision_sensor.tools.recorded_clouds`): each before the first
frame at or after its stamp, self-filtered with the robot's state at its stamp, voxelised with
``--cloud-voxel-size``, ``--cloud-self-filter-padding``, ``--cloud-max-points``,
``--cloud-max-range`` and ``--cloud-persistence`` (the node's ``point_cloud_*`` parameters and
defaults); contacts with ``cloud/<topic>`` are pairs like any other. A cloud that cannot be
taken (bad fields or steps, every point NaN, a frame that is no link) is counted and named in
the summary and in the JSON lines' ``clouds``; the check goes on.

With ``--max-distance D`` (default 0.1 m; 0 turns it off) each frame also gets the smallest
distance between the checked pairs nearer than D (``CollisionChecker.proximity``: <= 0 in
collision), in the JSON lines, the summary and under the timeline of ``--plot``. Padding is a
checker setting (``--config`` with ``padding: 0.01`` and ``link_padding: {panda_hand: 0.02}``):
contact then means within the paddings, and distances are the padded ones (negative in
contact, by how far the surfaces are inside the paddings).

With ``--motion`` the motion from each frame to the next is checked too
(``CollisionChecker.update_motion``: certified, not sampled; revolute and prismatic joints
move linearly between frames, continuous ones the shorter way): a contact between two recorded
states is reported even when both are clear, as sparse recordings (a planner's waypoints, a
driver at 5 Hz) make happen. The JSON lines gain ``motion`` (the first contact on the way into
the frame, or null), the summary counts the segments in contact and those between two clear
frames, the plot marks them, and a motion in contact makes the exit status 1.

Exit status: 0 no frame in collision, 1 at least one frame in collision, 2 error (the error is
one line on stderr: ``collision_sensor_check: error: ...``).

Many recordings at once (:mod:`collision_sensor.tools.audit`): several inputs, directories
(searched recursively), globs, LeRobot datasets (one unit per episode, ``--joint-map``), or
any of ``--report``, ``--jobs``, ``--ray``, ``--resume``::

    collision_sensor_check fleet/ 'extra/**/*.mcap' --urdf panda.urdf --report audit.jsonl \
        --plot audit.png --jobs 8
    collision_sensor_check ~/datasets/so101_pick --urdf so101.urdf --joint-map so101.yaml \
        --ray auto --report so101.jsonl

Each unit gets one JSON line in ``--report`` as it finishes; then a summary table across the
batch (and ``--plot``: collision rate per recording, pairs most often in contact). Exit status
then: 0 every unit clear, 1 some unit in collision, 3 some unit failed (its line says why; the
batch went on), 2 the run itself could not start.
"""
import argparse
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, TextIO, Tuple

import numpy as np

from collision_sensor.errors import ConfigError, SequenceError
from collision_sensor.engine.checker_config import CheckerConfig
from collision_sensor.engine.scene_markers import SceneTopic
from collision_sensor.model.joint_map import load_joint_map
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.model.sequences import (
    DEFAULT_TOPIC, SCENE_TOPIC, JointSequence, read_sequence)
from collision_sensor.model.xacro_expansion import parse_xacro_args
from collision_sensor.tools.audit.batch import (
    default_jobs, make_runner, print_summary, run_batch)
from collision_sensor.tools.audit.ray_pool import require_ray
from collision_sensor.tools.audit.report import plot_batch
from collision_sensor.tools.audit.unit_check import (
    CheckOptions, RobotSpec, apply_recorded, frame_durations, with_demo_arm_hint)
from collision_sensor.tools.audit.units import find_units
from collision_sensor.tools.command_line import run_command
from collision_sensor.tools.progress import MODES, ProgressBar
from collision_sensor.tools.recorded_clouds import CloudOptions, CloudReplay, summary_lines

PROG = 'collision_sensor_check'
_ENGINE = CheckerConfig()
DEFAULT_MAX_DISTANCE = 0.1
EXIT_CLEAR, EXIT_COLLISION, EXIT_ERROR = 0, 1, 2
EXIT_INTERRUPTED = 130   # as a shell reports a process stopped by SIGINT
BUNDLED_SEQUENCES = ('paper_experiment', 'into_drum_clear', 'random', 'moving_part',
                     'guard_rail_5hz')

Pair = Tuple[str, str]


@dataclass(frozen=True)
class FrameResult:
    """One frame's answer and how long the check took.

    ``min_distance`` is the smallest distance of a checked pair (0 in collision) when some
    pair was nearer than the run's max_distance, else None (also when not measured);
    ``nearest_pair`` is that pair. The distance is measured after ``seconds`` was taken.
    ``motion`` (with ``--motion``) is the motion from the previous frame into this one.
    ``clouds`` are the recorded clouds applied (or refused) before the frame
    (:class:`~collision_sensor.tools.recorded_clouds.CloudOutcome`).
    """

    index: int
    time: float
    in_collision: bool
    pairs: Tuple[Pair, ...]
    seconds: float
    min_distance: Optional[float] = None
    nearest_pair: Optional[Pair] = None
    motion: Optional['MotionAnswer'] = None
    clouds: tuple = ()


@dataclass(frozen=True)
class MotionAnswer:
    """The motion from the previous frame into this one (``--motion``): ``first_contact`` its
    time (s, on the recording's clock) or None when free, and the pairs in contact there."""

    first_contact: Optional[float]
    pairs: Tuple[Pair, ...] = ()


@dataclass(frozen=True)
class PairSpan:
    """A pair's contact over a sequence: first and last frame time, frame count, duration."""

    pair: Pair
    first: float
    last: float
    frames: int
    duration: float


def run_sequence(checker, seq: JointSequence, incremental: bool = True,
                 progress: Optional[ProgressBar] = None,
                 max_distance: float = 0.0,
                 scene: Optional[SceneTopic] = None,
                 motion: bool = False,
                 clouds: Optional[CloudReplay] = None) -> List[FrameResult]:
    """Check every frame of ``seq`` in order, its scene events applied as they come.

    The first frame is checked once from scratch before timing starts, so the per-frame times
    measure the steady state (not one-off compilation). The scene events due before a frame
    (``seq.scene_before``) are applied to ``checker`` before it, outside the timed check, as
    the node applies ``scene`` arrays (:func:`~collision_sensor.engine.scene_markers.apply_array`).
    :param seq: columns in ``checker.joint_names`` order.
    :param max_distance: with a value > 0, each frame's nearest pair closer than this (m) is
        measured too (``checker.proximity``, outside the timed check).
    :param scene: the topic state the events go through (default: a new one, default caps).
    :param motion: also check the motion from each frame to the next (``update_motion``, or
        ``check_motion`` with ``incremental`` False), in the timed check; its scene is the
        frame's (the events due before it applied first).
    :param clouds: the sequence's clouds, applied before the frames they precede after the
        scene events, outside the timed check (default: every cloud of ``seq``, by the node's
        defaults); :meth:`CloudReplay.finish` is called at the end.
    :raises MarkerError: a recorded array the node would reject (naming its time).
    """
    check = checker.update if incremental else checker.check
    scene = scene if scene is not None else SceneTopic()
    events = seq.scene_before()
    clouds = clouds if clouds is not None else CloudReplay(seq)
    if len(seq):
        checker.check(seq.positions[0])
    results = []
    times = seq.times.tolist()
    for index, (t, q) in enumerate(zip(times, seq.positions)):
        for event in events[index]:
            apply_recorded(scene, checker, event)
        applied = tuple(clouds.apply_before(checker, index)) if clouds.due(index) else ()
        start = time.perf_counter()
        answer = None
        if motion and index > 0:
            moved = (checker.update_motion(q) if incremental
                     else checker.check_motion(seq.positions[index - 1], q))
            answer = MotionAnswer(
                None if not moved.in_collision else
                times[index - 1] + moved.first_contact * (t - times[index - 1]),
                tuple(tuple(pair) for pair in moved.colliding_pairs))
        result = check(q)   # after update_motion: nothing moved, its answer as it stands
        elapsed = time.perf_counter() - start
        nearest, distance = None, None
        if max_distance > 0:
            records = checker.proximity(q, max_distance)  # the state is q already: no re-check
            if records:
                nearest, distance = (records[0].link_a, records[0].link_b), records[0].distance
        results.append(FrameResult(index, t, bool(result.in_collision),
                                   tuple(tuple(pair) for pair in result.colliding_pairs),
                                   elapsed, distance, nearest, answer, applied))
        if progress is not None:
            progress.update(index + 1)
    clouds.finish()
    return results


def pair_spans(results: Sequence[FrameResult]) -> List[PairSpan]:
    """Return each pair ever in contact with its first and last time, sorted by first time."""
    durations = frame_durations(np.array([r.time for r in results]))
    seen: Dict[Pair, list] = {}
    for result, duration in zip(results, durations):
        for pair in result.pairs:
            span = seen.setdefault(pair, [result.time, result.time, 0, 0.0])
            span[1] = result.time
            span[2] += 1
            span[3] += duration
    spans = [PairSpan(pair, first, last, frames, duration)
             for pair, (first, last, frames, duration) in seen.items()]
    return sorted(spans, key=lambda s: (s.first, s.pair))


def json_line(result: FrameResult, motion: bool = False, clouds: bool = False) -> str:
    """Return the frame's JSON line: ``{"index", "time", "in_collision", "pairs",
    "min_distance", "nearest_pair"}`` (the last two null when no pair was within the
    max distance), and with ``motion`` ``"motion": {"first_contact", "pairs"}`` (the motion
    into the frame: its first contact's time and pairs; null for the first frame, and
    ``first_contact`` null when the motion is free), and with ``clouds`` (a recording with
    point clouds) ``"clouds": [{"source", "time", "frame", "voxels"}]``, the clouds applied
    before the frame (``voxels`` null and ``"error"`` the reason for one refused)."""
    line = {'index': result.index, 'time': result.time, 'in_collision': result.in_collision,
            'pairs': [list(pair) for pair in result.pairs],
            'min_distance': result.min_distance,
            'nearest_pair': list(result.nearest_pair) if result.nearest_pair else None}
    if motion:
        line['motion'] = None if result.motion is None else {
            'first_contact': result.motion.first_contact,
            'pairs': [list(pair) for pair in result.motion.pairs]}
    if clouds:
        line['clouds'] = [outcome.as_json() for outcome in result.clouds]
    return json.dumps(line)


def motion_summary(results: Sequence[FrameResult], t0: float) -> List[str]:
    """Return the summary's lines on the motion between frames: the segments in contact, those
    between two clear frames (what checking the recorded states alone misses), the first."""
    hits = [(previous, r) for previous, r in zip(results, results[1:])
            if r.motion is not None and r.motion.first_contact is not None]
    lines = [f'motion between frames: {len(hits)} of {max(len(results) - 1, 0)} segments meet '
             'contact']
    missed = [(p, r) for p, r in hits if not p.in_collision and not r.in_collision]
    if missed:
        lines.append(f'  {len(missed)} of them between two clear frames (checks of the '
                     'recorded states alone miss them):')
        for previous, r in missed[:10]:
            pairs = ', '.join(f'{a} -- {b}' for a, b in r.motion.pairs)
            lines.append(f'  frames {previous.index} -> {r.index}: contact at '
                         f'{r.motion.first_contact - t0:.3f} s ({pairs})')
        if len(missed) > 10:
            lines.append(f'  ... and {len(missed) - 10} more')
    return lines


def distance_summary(results: Sequence[FrameResult], t0: float, max_distance: float) -> str:
    """Return the summary's distance line: the closest approach while clear, and where."""
    clear = [r for r in results if not r.in_collision and r.min_distance is not None]
    if not clear:
        return f'closest approach while clear: no pair within {max_distance:g} m'
    r = min(clear, key=lambda r: r.min_distance)
    a, b = r.nearest_pair
    return (f'closest approach while clear: {r.min_distance:.6f} m ({a} -- {b}) at '
            f'{r.time - t0:.3f} s; {len(clear)} clear frames with a pair within '
            f'{max_distance:g} m')


def summary(results: Sequence[FrameResult], seq: JointSequence, checker,
            incremental: bool = True, max_distance: float = 0.0,
            clouds: Optional[CloudReplay] = None) -> str:
    """Return the human summary: frames and time in collision, pairs, check time."""
    n = len(results)
    t0 = float(seq.times[0]) if n else 0.0
    durations = frame_durations(seq.times)
    colliding = [r for r in results if r.in_collision]
    in_contact = float(sum(d for r, d in zip(results, durations) if r.in_collision))
    lines = [f'sequence:  {seq.source} ({n} frames, {seq.duration:.2f} s)',
             f'robot:     {len(checker.joint_names)} joints, {len(checker.link_names)} links, '
             f'{len(checker.checked_pairs)} pairs checked',
             f'frames in collision: {len(colliding)} of {n}'
             + (f' ({100.0 * len(colliding) / n:.1f} %)' if n else ''),
             f'time in collision:   {in_contact:.3f} s of {seq.duration:.3f} s']
    if seq.scene:
        lines.append(f'scene changes:       {len(seq.scene)} arrays replayed, '
                     f'{len(checker.object_names)} objects at the end (the scene file\'s '
                     'included)')
    if clouds is not None:
        lines += summary_lines(clouds.counts())
    spans = pair_spans(results)
    if spans:
        width = max(len(f'{a} -- {b}') for a, b in (s.pair for s in spans))
        lines.append('pairs in contact (times from the first frame):')
        for s in spans:
            name = f'{s.pair[0]} -- {s.pair[1]}'
            lines.append(f'  {name:<{width}}  first {s.first - t0:8.3f} s  '
                         f'last {s.last - t0:8.3f} s  {s.frames:5d} frames  '
                         f'{s.duration:7.3f} s')
    if max_distance > 0:
        lines.append(distance_summary(results, t0, max_distance))
    motion = any(r.motion is not None for r in results)
    if motion:
        lines += motion_summary(results, t0)
    if n:
        ms = np.array([r.seconds for r in results]) * 1e3
        mode = 'incremental update' if incremental else 'full check'
        lines.append(f'check time per frame ({mode}): mean {ms.mean():.3f} ms, '
                     f'median {np.median(ms):.3f} ms, max {ms.max():.3f} ms')
    result = 'COLLISION' if colliding or motion_met(results) else 'clear'
    if clouds is not None and clouds.counts()['rejected']:
        refused = sum(clouds.counts()['rejected'].values())
        result += f' ({refused} of {len(clouds)} point clouds not applied: see above)'
    lines.append('result: ' + result)
    return '\n'.join(lines)


def motion_met(results: Sequence[FrameResult]) -> bool:
    """True iff some motion between frames met contact (``--motion``)."""
    return any(r.motion is not None and r.motion.first_contact is not None for r in results)


def plot_timeline(results: Sequence[FrameResult], seq: JointSequence, path: str,
                  max_distance: float = 0.0) -> None:
    """Draw the contact timeline to ``path`` (PNG): one row per pair, bars where in contact;
    with ``max_distance`` > 0, below it each frame's minimum distance (gaps where no pair was
    within ``max_distance``)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    times = np.array([r.time for r in results])
    t0 = float(times[0]) if len(times) else 0.0
    durations = frame_durations(times)
    spans = pair_spans(results)
    rows = ['any pair'] + [f'{a} -- {b}' for a, b in (s.pair for s in spans)]
    height = 1.2 + 0.35 * len(rows)
    if max_distance > 0:
        fig, (ax, ax_d) = plt.subplots(2, 1, sharex=True, figsize=(10.0, height + 2.2),
                                       gridspec_kw={'height_ratios': [height, 2.2]})
    else:
        fig, ax = plt.subplots(figsize=(10.0, height))
    try:
        def stretches(flags):
            """Yield (start, width) in seconds of runs of True frames."""
            index = 0
            while index < len(flags):
                if flags[index]:
                    end = index
                    while end + 1 < len(flags) and flags[end + 1]:
                        end += 1
                    yield times[index] - t0, times[end] - times[index] + durations[end]
                    index = end + 1
                else:
                    index += 1
        flags = [[r.in_collision for r in results]]
        flags += [[s.pair in r.pairs for r in results] for s in spans]
        for row, row_flags in enumerate(flags):
            y = len(rows) - 1 - row
            ax.broken_barh(list(stretches(row_flags)), (y - 0.35, 0.7),
                           facecolors='tab:red' if row == 0 else 'tab:orange')
        met = [r.motion.first_contact - t0 for r in results
               if r.motion is not None and r.motion.first_contact is not None]
        if met:   # the motion between frames: its first contacts, on the "any pair" row
            ax.plot(met, [len(rows) - 1] * len(met), 'kv', markersize=7,
                    label='contact on the way between frames (--motion)')
            ax.legend(loc='lower right', fontsize=8)
        ax.set_yticks(range(len(rows)))
        ax.set_yticklabels(rows[::-1])
        end = (times[-1] - t0 + durations[-1]) if len(times) else 1.0
        ax.set_xlim(0.0, end if end > 0 else 1.0)
        ax.set_ylim(-0.6, len(rows) - 0.4)
        ax.grid(axis='x', alpha=0.3)
        if max_distance > 0:
            distance = [math.nan if r.min_distance is None else r.min_distance for r in results]
            ax_d.plot(times - t0, distance, color='tab:blue', lw=1.2)
            lowest = min([0.0] + [d for d in distance if d < 0])   # padded contact: < 0
            ax_d.set_ylim(1.05 * lowest, max_distance * 1.05)
            ax_d.set_ylabel('min distance [m]')
            ax_d.grid(alpha=0.3)
            ax_d.set_xlabel('time from the first frame [s]')
        else:
            ax.set_xlabel('time from the first frame [s]')
        title = f'contacts: {os.path.basename(seq.source)}'
        if not spans:
            title += ' (no contact)'
        ax.set_title(title)
        fig.tight_layout()
        fig.savefig(path, dpi=100)
    finally:
        plt.close(fig)


def _load_config(path: Optional[str]):
    if path is None:
        return None
    import yaml
    try:
        with open(path, encoding='utf-8') as stream:
            config = yaml.safe_load(stream)
    except OSError as err:
        raise ConfigError(f'--config {path}: cannot read: {err.strerror}') from None
    except yaml.YAMLError as err:
        raise ConfigError(f'--config {path}: not valid YAML: {err}') from None
    if config is None:
        return {}
    if not isinstance(config, dict):
        raise ConfigError(f'--config {path}: expected a mapping of settings, e.g. '
                          '"motion_tolerance: 0.001"')
    return config


def bundled_sequence_path(value: str) -> str:
    """Return ``value``, or the bundled sequence it names (``paper_experiment``, ...)."""
    if os.path.exists(value) or os.sep in value:
        return value
    from collision_sensor.model.share import config_path
    for candidate in (config_path('sequences', value + '.csv'), config_path('sequences', value)):
        if os.path.exists(candidate):
            return candidate
    return value


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Check a recorded joint-state sequence for collisions, frame by frame, '
                    'with the incremental checker; no ROS needed.',
        epilog='exit status: 0 no frame in collision, 1 collisions found, 2 error; with many '
               'recordings also 3: some recording failed (its --report line says why). '
               f'Bundled sequences: {", ".join(BUNDLED_SEQUENCES)}. '
               'Without --urdf the robot is the demo cell (demo_arm.urdf, its SRDF, '
               'demo_scene.yaml); with --urdf, --srdf and --scene default to none.',
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('inputs', metavar='INPUT', nargs='+',
                        help='CSV file, rosbag2 bag (directory, .mcap or .db3), LeRobot dataset '
                             'directory, a directory holding any of these (searched '
                             'recursively), a glob (quoted: \'bags/**/*.mcap\'), or the name '
                             'of a bundled sequence')
    parser.add_argument('--urdf', help='robot description (default: the demo arm)')
    parser.add_argument('--srdf', help='SRDF with disable_collisions pairs')
    parser.add_argument('--package-path', metavar='NAME=DIR', action='append', default=[],
                        help='directory of a package named in package:// URIs (repeatable)')
    parser.add_argument('--xacro-arg', metavar='NAME:=VALUE', action='append', default=[],
                        help='argument of a .xacro robot description (repeatable)')
    parser.add_argument('--scene', help='scene YAML file (default with the demo arm: the '
                                        'demo washer)')
    parser.add_argument('--no-scene', action='store_true', help='check the robot alone')
    parser.add_argument('--config', metavar='YAML', help='YAML mapping of checker settings')
    parser.add_argument('--topic', default=DEFAULT_TOPIC,
                        help='JointState topic in a bag (default %(default)s)')
    parser.add_argument('--scene-topic', default=SCENE_TOPIC,
                        help='MarkerArray topic of scene changes in a bag, replayed as the '
                             'node applies its scene topic (default %(default)s)')
    clouds = parser.add_argument_group(
        'point clouds (bags with sensor_msgs/PointCloud2; as the node\'s point_cloud_* '
        'parameters)')
    clouds.add_argument('--cloud-topic', metavar='TOPIC', action='append',
                        help='PointCloud2 topic in a bag whose clouds are obstacles '
                             'cloud/<topic> (repeatable; default: every PointCloud2 topic)')
    clouds.add_argument('--no-clouds', action='store_true',
                        help='ignore the bag\'s point clouds')
    clouds.add_argument('--cloud-voxel-size', metavar='M', type=float,
                        help=f'voxel edge (default {_ENGINE.voxel_size:g}, or voxel_size in '
                             '--config)')
    clouds.add_argument('--cloud-self-filter-padding', metavar='M', type=float,
                        help='points within this of the robot are its own (default '
                             f'{_ENGINE.self_filter_padding:g}, or self_filter_padding in '
                             '--config)')
    clouds.add_argument('--cloud-max-points', metavar='N', type=int,
                        help=f'most points taken from one cloud (default {_ENGINE.max_points}, '
                             'or max_points in --config)')
    clouds.add_argument('--cloud-max-range', metavar='M', type=float, default=0.0,
                        help='drop points farther than this from the cloud frame\'s origin '
                             '(default 0: no limit)')
    clouds.add_argument('--cloud-persistence', metavar='S', type=float, default=0.0,
                        help='seconds an earlier cloud\'s voxel stays an obstacle (default 0: '
                             'only the latest cloud)')
    parser.add_argument('--joint-map', metavar='YAML',
                        help='LeRobot datasets: which entry of the state vector is which URDF '
                             'joint, with a scale and an offset (see docs/offline.md); without it '
                             'the entries must be named as the joints, in rad or m')
    parser.add_argument('--report', metavar='FILE',
                        help='many recordings: write one JSON line per recording or episode as '
                             'it finishes (source, frames, frames_in_collision, pairs with '
                             'first and last time, error, ...)')
    parser.add_argument('--resume', action='store_true',
                        help='continue --report FILE: skip the units it holds already')
    parser.add_argument('--jobs', metavar='N', type=int,
                        help='check recordings in N worker processes (default: all cores)')
    parser.add_argument('--ray', metavar='ADDRESS',
                        help='check recordings on Ray: "auto" joins the cluster running here, '
                             '"local" starts one, or a cluster address; needs pip install '
                             '"collision_sensor[cluster]"')
    parser.add_argument('--json', metavar='FILE',
                        help='write one JSON line per frame: {"index", "time", '
                             '"in_collision", "pairs", "min_distance", "nearest_pair"} (the '
                             'last two null when no pair is within --max-distance); "-" for '
                             'stdout (the summary then goes to stderr)')
    parser.add_argument('--plot', metavar='FILE.png',
                        help='draw the contact timeline (and the minimum distance below it); '
                             'for many recordings, the collision rate per recording and the '
                             'pairs most often in contact')
    parser.add_argument('--max-distance', metavar='M', type=float,
                        help='measure each frame\'s smallest pair distance below M metres '
                             f'(default {DEFAULT_MAX_DISTANCE} for one recording, 0 for many; '
                             '0: do not measure)')
    parser.add_argument('--motion', action='store_true',
                        help='also check the motion from each frame to the next (certified, '
                             'not sampled): contact between two recorded states')
    parser.add_argument('--full', action='store_true',
                        help='check every frame from scratch instead of incrementally')
    parser.add_argument('--progress', choices=MODES, default='auto',
                        help='progress bar on stderr: auto (on a terminal), always, never')
    return parser


BATCH_OPTIONS = ('report', 'jobs', 'ray', 'resume')
#: The cloud options that are checker settings, by config key.
CLOUD_SETTINGS = {'voxel_size': 'cloud_voxel_size',
                  'self_filter_padding': 'cloud_self_filter_padding',
                  'max_points': 'cloud_max_points'}


def cloud_topics(args) -> Optional[Tuple[str, ...]]:
    """Return the bag's cloud topics to read: None for every PointCloud2 topic, () for
    none."""
    if args.no_clouds:
        if args.cloud_topic:
            raise ConfigError('--no-clouds and --cloud-topic contradict each other; give one')
        return ()
    return tuple(args.cloud_topic) if args.cloud_topic else None


def cloud_options(args) -> CloudOptions:
    """Return ``--cloud-max-range`` and ``--cloud-persistence`` checked."""
    max_range, persistence = args.cloud_max_range, args.cloud_persistence
    if not (max_range >= 0.0 and math.isfinite(max_range)):
        raise ConfigError(f'--cloud-max-range {max_range}: expected a finite distance >= 0 '
                          '(metres; 0: no limit)')
    if not (persistence >= 0.0 and math.isfinite(persistence)):
        raise ConfigError(f'--cloud-persistence {persistence}: expected a finite number of '
                          'seconds >= 0 (0: only the latest cloud counts)')
    return CloudOptions(max_range=max_range if max_range > 0.0 else math.inf,
                        persistence=persistence)


def _with_cloud_settings(config, args):
    """Return ``config`` with the cloud options that are checker settings (they win)."""
    chosen = {key: getattr(args, option) for key, option in CLOUD_SETTINGS.items()
              if getattr(args, option) is not None}
    if not chosen:
        return config
    merged = dict(config or {}, **chosen)
    try:
        CheckerConfig.from_mapping(merged)
    except ConfigError as error:
        text = str(error)
        for key, option in CLOUD_SETTINGS.items():
            text = text.replace(f'setting {key}', '--' + option.replace('_', '-'))
        raise ConfigError(text) from None
    return merged


def _robot(args) -> RobotSpec:
    """Load the robot of ``--urdf`` (or the demo cell) as the workers will build it."""
    from collision_sensor.model.share import config_path

    package_paths = parse_package_paths(args.package_path)
    if args.urdf is None:
        urdf, srdf = config_path('demo_arm.urdf'), args.srdf or config_path('demo_arm.srdf')
        scene = args.scene or config_path('demo_scene.yaml')
        label = 'the bundled demo arm (no --urdf given)'
    else:
        urdf, srdf, scene, label = args.urdf, args.srdf, args.scene, args.urdf
    if args.no_scene:
        scene = None
    return RobotSpec.load(urdf, srdf=srdf, package_paths=package_paths or None, scene=scene,
                          config=_with_cloud_settings(_load_config(args.config), args),
                          xacro_args=parse_xacro_args(args.xacro_arg) or None, label=label,
                          demo=args.urdf is None)


def _run(args) -> int:
    max_distance = args.max_distance
    if max_distance is not None and not (max_distance >= 0 and math.isfinite(max_distance)):
        raise ConfigError(f'--max-distance {max_distance}: expected a finite distance >= 0 '
                          '(metres; 0: do not measure)')
    if args.jobs is not None and args.jobs < 1:
        raise ConfigError(f'--jobs {args.jobs}: expected 1 or more worker processes')
    if args.resume and not args.report:
        raise ConfigError('--resume continues a report: give --report FILE too')
    units = find_units(args.inputs, bundled_sequence_path)
    batch = len(units) > 1 or units[0].kind == 'lerobot' or any(
        getattr(args, name) for name in BATCH_OPTIONS)
    if batch and args.json:
        raise ConfigError('--json writes one recording\'s frames; for many recordings use '
                          '--report FILE (one line per recording)')
    if args.ray is not None:
        require_ray()    # before the robot loads: say at once how to install it
    spec = _robot(args)
    checker = spec.build()
    joint_map = load_joint_map(args.joint_map) if args.joint_map else None
    if joint_map is not None:
        joint_map.check_robot(checker.joint_names)
    if batch:
        return _run_batch(args, units, spec, checker, joint_map,
                          0.0 if max_distance is None else max_distance)
    return _run_one(args, units[0], spec, checker,
                    DEFAULT_MAX_DISTANCE if max_distance is None else max_distance)


def _run_batch(args, units, spec, checker, joint_map, max_distance) -> int:
    options = CheckOptions(incremental=not args.full, max_distance=max_distance,
                           topic=args.topic, scene_topic=args.scene_topic, joint_map=joint_map,
                           motion=args.motion, cloud_topics=cloud_topics(args),
                           clouds=cloud_options(args))
    runner = make_runner(spec, options, args.jobs, args.ray)
    label = (f'Ray ({args.ray})' if args.ray else
             f'{args.jobs or default_jobs()} local worker processes'
             if (args.jobs or default_jobs()) > 1 else 'this process')
    try:
        result = run_batch(units, spec, options, runner, report_path=args.report,
                           resume=args.resume, progress=args.progress)
    except KeyboardInterrupt:
        where = (f'; the report {args.report} holds every unit finished, --resume continues '
                 'it') if args.report else ''
        print(f'{PROG}: stopped{where}', file=sys.stderr)
        return EXIT_INTERRUPTED
    if args.plot:
        plot_batch(result.records, args.plot)
    print_summary(result, spec, checker, options, label)
    return result.status


def _run_one(args, unit, spec, checker, max_distance) -> int:
    options = cloud_options(args)
    try:
        seq = read_sequence(unit.path, topic=args.topic, joint_names=checker.joint_names,
                            scene_topic=args.scene_topic, cloud_topics=cloud_topics(args))
    except SequenceError as err:
        raise SequenceError(with_demo_arm_hint(str(err), spec.demo)) from None

    label = os.path.basename(os.path.normpath(seq.source))
    clouds = CloudReplay(seq, options)
    with ProgressBar(len(seq), label=label, mode=args.progress) as progress:
        results = run_sequence(checker, seq, incremental=not args.full, progress=progress,
                               max_distance=max_distance,
                               scene=SceneTopic(package_paths=dict(spec.package_paths) or None),
                               motion=args.motion, clouds=clouds)

    to_stdout = args.json == '-'
    if args.json:
        stream: TextIO = sys.stdout if to_stdout else open(args.json, 'w', encoding='utf-8')
        try:
            for result in results:
                stream.write(json_line(result, args.motion, bool(seq.clouds)) + '\n')
        finally:
            if not to_stdout:
                stream.close()
    if args.plot:
        plot_timeline(results, seq, args.plot, max_distance=max_distance)
    print(summary(results, seq, checker, incremental=not args.full,
                  max_distance=max_distance, clouds=clouds if seq.clouds else None),
          file=sys.stderr if to_stdout else sys.stdout)
    met = any(r.in_collision for r in results) or motion_met(results)
    return EXIT_COLLISION if met else EXIT_CLEAR


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the tool; return the exit status (0 clear, 1 collisions, 2 error)."""
    return run_command(PROG, build_parser(), _run, argv)


if __name__ == '__main__':
    sys.exit(main())
