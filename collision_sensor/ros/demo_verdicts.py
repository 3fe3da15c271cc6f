"""What the demo hears from the node (verdicts on ``colliding_pairs``, check times on
``/diagnostics``) and the lines it prints about them: changes of the colliding pairs, scene
changes, motions beside instants, the summaries.
"""
import threading
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

Pair = Tuple[str, str]


def stamp_nanoseconds(seconds: float) -> int:
    """Return a recorded time (s) as the nanoseconds of the header stamp the player gives it
    (rounded to the nearest, as :mod:`collision_sensor.ros.player` rounds)."""
    return int(round(seconds * 1e9))


@dataclass
class CheckTime:
    """The node's check times summed over /diagnostics periods."""

    checks: int = 0
    total_ms: float = 0.0
    max_ms: float = 0.0

    def add(self, values: Dict[str, str]) -> None:
        checks = int(values.get('checks', '0') or 0)
        if checks:
            self.checks += checks
            self.total_ms += checks * float(values.get('check_time_mean_ms', '0') or 0.0)
            self.max_ms = max(self.max_ms, float(values.get('check_time_max_ms', '0') or 0.0))


@dataclass
class Verdicts:
    """Verdicts and check times received by the listener, shared with the main thread.

    ``pairs`` holds the verdicts on frames (their header is the frame's, frame_id empty): the
    pairs in contact at the frame, and (with ``check_motion``) ``met`` those met on the way into
    it, with the fraction of the motion where (``first_contact``; ``None`` when none);
    ``scene_verdicts`` counts those the node gives on applying a scene array or a cloud
    (header frame_id: the robot's root frame), whose pairs are in ``root_pairs``. A failure
    entry (no pair: ``kind`` names it, e.g. ``point_cloud_timeout``) is not a pair: each
    verdict's are counted in ``failures``; a verdict of failures only on the root frame (a
    source timed out) is no answer to a scene array or cloud.
    ``cloud_status``: the values of the node's /diagnostics status named ``cloud_status_name``
    (a point cloud source), the last period's.
    """

    status_name: str
    cloud_status_name: str = ''
    pairs: List[Tuple[int, Tuple[Pair, ...]]] = field(default_factory=list)
    met: List[Tuple[Tuple[Pair, ...], Optional[float]]] = field(default_factory=list)
    scene_verdicts: int = 0
    root_pairs: List[Tuple[Pair, ...]] = field(default_factory=list)
    failures: Dict[str, int] = field(default_factory=dict)
    check_time: CheckTime = field(default_factory=CheckTime)
    cloud_status: Dict[str, str] = field(default_factory=dict)
    condition: threading.Condition = field(default_factory=threading.Condition)

    def on_colliding_pairs(self, msg) -> None:
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        now, met, at, failed = [], [], None, []
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if ':' not in status.name:
                failed.append(status.name)
                continue
            pair = tuple(status.name.split(':', 1))
            if 'first_contact' in values:
                met.append(pair)
                at = float(values['first_contact'])
            else:
                now.append(pair)
        with self.condition:
            for kind in failed:
                self.failures[kind] = self.failures.get(kind, 0) + 1
            if msg.header.frame_id:
                if now or not failed:
                    self.scene_verdicts += 1
                    self.root_pairs.append(tuple(now))
            else:
                self.pairs.append((stamp_ns, tuple(now)))
                self.met.append((tuple(met), at))
            self.condition.notify_all()

    def on_diagnostics(self, msg) -> None:
        for status in msg.status:
            if status.name == self.status_name:
                with self.condition:
                    self.check_time.add({kv.key: kv.value for kv in status.values})
                    self.condition.notify_all()
            elif self.cloud_status_name and status.name == self.cloud_status_name:
                with self.condition:
                    self.cloud_status = {kv.key: kv.value for kv in status.values}
                    self.condition.notify_all()

    def wait(self, predicate, timeout: float) -> bool:
        """Wait until ``predicate()`` holds (under the lock); False after ``timeout`` s."""
        with self.condition:
            return self.condition.wait_for(predicate, timeout)


def scene_lines(t: float, markers, shown: Dict[str, str]) -> List[str]:
    """Return the lines for one scene array at time ``t`` (s): what it changed, one per object
    that appears, is attached, dropped or removed. ``shown`` maps each object to its last
    state printed (updated); plain moves print nothing."""
    lines = []
    for marker in markers:
        name = marker.ns if marker.id == 0 else f'{marker.ns}/{marker.id}'
        if marker.action == 3:      # DELETEALL
            state, name = 'removed with everything from the topic', '*'
            shown.clear()
        elif marker.action == 2:
            state = 'removed'
            shown.pop(name, None)
        else:
            frame = marker.header.frame_id
            touch = f', may touch {marker.text}' if frame and marker.text else ''
            state = (f'attached to {frame}{touch}' if frame
                     else 'dropped in the world' if shown.get(name, '').startswith('attached')
                     else 'in the world')
            if shown.get(name) == state:
                continue
            shown[name] = state
        lines.append(f'  {t:7.3f} s  scene    {name}: {state}')
    return lines


def pairs_text(pairs: Sequence[Pair]) -> str:
    return ', '.join(f'{a} -- {b}' for a, b in pairs)


def change_lines(t: float, before: Sequence[Pair], after: Sequence[Pair]) -> List[str]:
    """Return the lines for a change of the colliding set at time ``t`` (s): one per pair."""
    entering = [pair for pair in after if pair not in before]
    leaving = [pair for pair in before if pair not in after]
    if not before and after:
        state = 'CONTACT'
    elif before and not after:
        state = 'clear'
    else:
        state = ''
    lines = []
    for sign, pair in [('+', p) for p in entering] + [('-', p) for p in leaving]:
        lines.append(f'  {t:7.3f} s  {state:<8} {sign} {pair[0]} -- {pair[1]}')
        state = ''
    return lines


def motion_line(t: float, now: Sequence[Pair], met: Sequence[Pair],
                first_contact: Optional[float]) -> str:
    """One frame side by side: the pairs in contact at it (what an instant check reports),
    then what the motion into it met on the way (``check_motion``)."""
    instant = f'CONTACT {pairs_text(now)}' if now else 'clear'
    if met:
        motion = f'CONTACT {pairs_text(met)} at {first_contact:.2f} of the way'
    else:
        motion = 'CONTACT (in contact at the frame)' if now else 'clear'
    return f'  {t:7.3f} s  {instant:<26} {motion}'


def motion_summary_lines(seq, verdicts: Verdicts) -> List[str]:
    """The motion summary: motions in contact, and those between two clear frames (which
    checks of the recorded states alone miss)."""
    n = len(seq)
    t0 = float(seq.times[0]) if n else 0.0
    frames = [pairs for _, pairs in verdicts.pairs[:n]]
    met = verdicts.met[:n]
    missed = [i for i in range(1, n) if met[i][0] and not frames[i - 1] and not frames[i]]
    lines = [f'summary of {seq.source}',
             f'  frames:                 {n}; in contact at the frame (instant checks): '
             f'{sum(bool(p) for p in frames)}',
             f'  motions between frames: {max(n - 1, 0)}; meeting contact on the way: '
             f'{sum(bool(m) for m, _ in met[1:])}, of which between two clear frames: '
             f'{len(missed)}']
    for i in missed:
        pairs, at = met[i]
        when = seq.times[i - 1] - t0 + at * (seq.times[i] - seq.times[i - 1])
        lines.append(f'    frames {i - 1} -> {i}: {pairs_text(pairs)} at {when:.3f} s '
                     '(missed by instant checks)')
    contact = any(frames) or any(m for m, _ in met)
    lines.append('  result: ' + ('COLLISION' if contact else 'clear')
                 + (' (on the way only)' if contact and not any(frames) else ''))
    return lines


def summary_lines(seq, verdicts: Sequence[Tuple[Pair, ...]], played: float,
                  check_time: CheckTime) -> List[str]:
    """Return the summary: frames, frames in collision, each pair's span, the node's check time.

    :param verdicts: the colliding pairs the node reported, one tuple per frame of ``seq``.
    :param played: seconds the playing took.
    """
    from collision_sensor.tools.offline_check import FrameResult, pair_spans

    n = len(seq)
    t0 = float(seq.times[0]) if n else 0.0
    results = [FrameResult(i, float(seq.times[i]), bool(pairs), tuple(pairs), 0.0)
               for i, pairs in enumerate(verdicts)]
    colliding = sum(r.in_collision for r in results)
    lines = [f'summary of {seq.source}',
             f'  frames:              {n} played in {played:.2f} s, {len(results)} verdicts',
             f'  frames in collision: {colliding} of {n}'
             + (f' ({100.0 * colliding / n:.1f} %)' if n else '')]
    spans = pair_spans(results)
    if spans:
        width = max(len(f'{a} -- {b}') for a, b in (s.pair for s in spans))
        lines.append('  pairs in contact (times from the first frame):')
        for s in spans:
            name = f'{s.pair[0]} -- {s.pair[1]}'
            lines.append(f'    {name:<{width}}  first {s.first - t0:7.3f} s  '
                         f'last {s.last - t0:7.3f} s  {s.frames:4d} frames')
    else:
        lines.append('  pairs in contact:    none')
    if check_time.checks:
        lines.append(f'  node check time (/diagnostics): mean '
                     f'{check_time.total_ms / check_time.checks:.3f} ms, max '
                     f'{check_time.max_ms:.3f} ms over {check_time.checks} checks')
    else:
        lines.append('  node check time: no /diagnostics report received')
    lines.append('  result: ' + ('COLLISION' if colliding else 'clear'))
    return lines
