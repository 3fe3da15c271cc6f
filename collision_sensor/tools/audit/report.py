"""The batch's report: one JSON line per unit as it finishes, then a summary table and a plot.

A line (keys in this order; :func:`~collision_sensor.tools.audit.unit_check.record_keys`)::

    {"source": "fleet/r1/shift2.mcap", "format": "mcap", "frames": 1000,
     "start_time": 1732550400.0, "duration": 9.99, "scene_changes": 0,
     "frames_in_collision": 12, "time_in_collision": 0.12,
     "pairs": [{"link_a": "panda_hand", "link_b": "panda_link5", "first": 3.2, "last": 3.31,
                "frames": 12}],
     "error": null, "settings": "1f2e3d4c5b6a7988"}

``source`` is the path as given (or found under a directory or glob), ``path#episode`` for a
LeRobot episode; ``start_time`` is the first frame's own time (a bag's stamps are wall-clock
seconds), every other time is in seconds from it; ``pairs`` are the link pairs ever in contact
with the first and last time and the frames in contact; with ``--max-distance``,
``closest_approach`` follows ``pairs``. A unit that failed has ``error`` (the reason and the
fix) and nulls for what was not measured. ``settings`` is a digest of the robot and the options
(:meth:`RobotSpec.digest`): ``--resume`` continues only a report written under the same.

Each line is written whole and flushed as its unit finishes, so a report cut short (the
machine went down) holds whole lines; ``--resume`` drops a torn last line and skips every unit
whose source is already there, failed ones included.
"""
import json
import os
from typing import Dict, List, Optional, Sequence, TextIO

from collision_sensor.errors import ConfigError


def read_report(path: str, digest: str) -> List[dict]:
    """Return the lines of an existing report, dropping (and cutting off) a torn last line.

    :raises ConfigError: a line that is not a unit's JSON line, or one written under other
        settings.
    """
    try:
        with open(path, 'rb') as stream:
            data = stream.read()
    except FileNotFoundError:
        return []
    except OSError as err:
        raise ConfigError(f'--report {path}: cannot read: {err.strerror}') from None
    whole = data[:data.rfind(b'\n') + 1]
    if len(whole) != len(data):
        with open(path, 'r+b') as stream:     # a torn last line: the run was cut mid-write
            stream.truncate(len(whole))
    records = []
    for number, line in enumerate(whole.decode('utf-8', 'replace').splitlines(), 1):
        try:
            record = json.loads(line)
        except ValueError:
            record = None
        if not isinstance(record, dict) or 'source' not in record:
            raise ConfigError(f'--report {path}: line {number} is not a unit\'s JSON line; '
                              'give the report this tool wrote, or a new file')
        if record.get('settings') != digest:
            raise ConfigError(
                f'--report {path}: line {number} ({record["source"]}) was written for another '
                'robot or other settings; resume with the same --urdf, --srdf, --scene, '
                '--config and options, or write a new report')
        records.append(record)
    return records


class ReportWriter:
    """Appends lines to the report (or nowhere, with ``path`` None)."""

    def __init__(self, path: Optional[str], resume: bool):
        self.path = path
        self._stream: Optional[TextIO] = None
        if path is None:
            return
        if not resume and os.path.exists(path) and os.path.getsize(path) > 0:
            raise ConfigError(f'--report {path}: exists already; pass --resume to continue it, '
                              'or choose a new file')
        try:
            self._stream = open(path, 'a', encoding='utf-8')
        except OSError as err:
            raise ConfigError(f'--report {path}: cannot write: {err.strerror}') from None

    def write(self, record: dict) -> None:
        if self._stream is not None:
            self._stream.write(json.dumps(record, allow_nan=False) + '\n')
            self._stream.flush()

    def close(self) -> None:
        if self._stream is not None:
            self._stream.close()


def collision_rate(record: dict) -> float:
    """Return the fraction of a checked unit's frames in collision."""
    return record['frames_in_collision'] / record['frames'] if record['frames'] else 0.0


def pair_counts(records: Sequence[dict]) -> List[tuple]:
    """Return ``(units, frames, "a -- b")`` per pair in contact, most units first."""
    counts: Dict[str, List[int]] = {}
    for record in records:
        for pair in record.get('pairs') or ():
            entry = counts.setdefault(f'{pair["link_a"]} -- {pair["link_b"]}', [0, 0])
            entry[0] += 1
            entry[1] += pair['frames']
    return sorted(((units, frames, name) for name, (units, frames) in counts.items()),
                  key=lambda item: (-item[0], -item[1], item[2]))


def summary_lines(records: Sequence[dict], top: int = 10) -> List[str]:
    """Return the table across the batch: totals, the recordings with the highest collision
    rate, the pairs most often in contact, the failed units."""
    checked = [r for r in records if r['error'] is None]
    failed = [r for r in records if r['error'] is not None]
    colliding = [r for r in checked if r['frames_in_collision']]
    frames = sum(r['frames'] for r in checked)
    hit_frames = sum(r['frames_in_collision'] for r in checked)
    lines = [f'units:               {len(records)} ({len(checked)} checked, {len(failed)} '
             f'failed)',
             f'frames:              {frames:,} checked']
    if checked:
        lines += [f'units in collision:  {len(colliding)} of {len(checked)} '
                  f'({100.0 * len(colliding) / len(checked):.1f} %)',
                  f'frames in collision: {hit_frames:,} of {frames:,} '
                  f'({100.0 * hit_frames / max(frames, 1):.2f} %)']
    if colliding:
        ranked = sorted(colliding, key=lambda r: (-collision_rate(r), r['source']))[:top]
        lines += ['', f'highest collision rate ({len(ranked)} of {len(colliding)} units in '
                  'collision):', '    rate    frames  in coll.  pairs  source']
        lines += [f'  {100.0 * collision_rate(r):5.1f} %  {r["frames"]:8d}  '
                  f'{r["frames_in_collision"]:8d}  {len(r["pairs"]):5d}  {r["source"]}'
                  for r in ranked]
        pairs = pair_counts(colliding)
        lines += ['', 'pairs most often in contact:', '   units    frames  pair']
        lines += [f'  {units:6d}  {hits:8d}  {name}' for units, hits, name in pairs[:top]]
        if len(pairs) > top:
            lines.append(f'  ... and {len(pairs) - top} more pairs')
    if failed:
        lines += ['', f'failed units ({len(failed)}):']
        lines += [f'  {r["source"]}: {r["error"]}' for r in failed[:2 * top]]
        if len(failed) > 2 * top:
            lines.append(f'  ... and {len(failed) - 2 * top} more (every one in the report)')
    return lines


def plot_batch(records: Sequence[dict], path: str, top: int = 15) -> None:
    """Draw the batch (PNG): each recording's collision rate, highest first, and the pairs
    most often in contact (units in contact)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    checked = sorted((r for r in records if r['error'] is None),
                     key=lambda r: (-collision_rate(r), r['source']))
    rates = [100.0 * collision_rate(r) for r in checked]
    pairs = pair_counts(checked)[:top]
    figure, (left, right) = plt.subplots(1, 2, figsize=(13.0, 4.8))
    try:
        if len(rates) <= 60:
            left.bar(range(len(rates)), rates, color='tab:red')
            left.set_xticks(range(len(rates)))
            left.set_xticklabels([os.path.basename(r['source']) for r in checked], rotation=90,
                                 fontsize=6)
        else:
            left.plot(range(1, len(rates) + 1), rates, color='tab:red', lw=1.5)
            left.set_xlabel('recordings, highest collision rate first')
        left.set_ylabel('frames in collision [%]')
        failed = len(records) - len(checked)
        left.set_title(f'collision rate per recording ({len(checked)} checked'
                       + (f', {failed} failed)' if failed else ')'))
        left.grid(alpha=0.3)
        if pairs:
            names = [name for _, _, name in pairs][::-1]
            right.barh(range(len(names)), [units for units, _, _ in pairs][::-1],
                       color='tab:orange')
            right.set_yticks(range(len(names)))
            right.set_yticklabels(names, fontsize=7)
            right.set_xlabel('recordings with the pair in contact')
            right.xaxis.set_major_locator(MaxNLocator(integer=True))
        else:
            right.text(0.5, 0.5, 'no pair in contact', ha='center', va='center')
            right.set_axis_off()
        right.set_title('pairs most often in contact')
        figure.tight_layout()
        figure.savefig(path, dpi=100)
    finally:
        plt.close(figure)
