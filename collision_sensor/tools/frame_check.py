"""One recording checked frame by frame: each frame's answer, its JSON line, the summary and
the contact timeline (``collision_sensor_check`` on one recording, :mod:`offline_check`).

:func:`run_sequence` puts every frame through ``checker.update`` (the incremental check, sec. 4
of the paper), or ``checker.check``, in order, with the recording's scene arrays and point
clouds applied before the frames they precede, as the node applies its topics.
"""
import json
import math
import os
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.scene_markers import SceneTopic
from collision_sensor.model.sequences import JointSequence
from collision_sensor.tools.audit.unit_check import apply_recorded, frame_durations
from collision_sensor.tools.progress import ProgressBar
from collision_sensor.tools.recorded_clouds import CloudReplay, summary_lines

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
