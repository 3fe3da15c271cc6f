"""``python -m benchmarks audit dataset``: a LeRobot dataset of the SO-101 audited by
``collision_sensor_check`` with ``--jobs 1`` and ``--jobs 2``, as a user runs it.

``python -m benchmarks audit dataset [--episodes 200] [--frames 900] [--runs 3]
[--markdown FILE]``

Writes a LeRobot v3.0 dataset (``test/lerobot_writer.py``: as LeRobot writes it) of
``--episodes`` SO-101 pick-and-place episodes of ``--frames`` states at 30 fps (50 episodes a
data file), in the units LeRobot records (body joints -100..100, the gripper 0..100), and the
joint map that reads them onto example-robot-data's ``so101.urdf`` (398,884 triangles). Then
runs the command on it ``--runs`` times each way, ``--jobs 1`` and ``--jobs 2`` alternated (the
first of each round changes), and reports: the wall time as the user waits for it, the
checking after the model is loaded (the summary's "this run"), and the memory of every process
of the run, sampled every 0.1 s from ``/proc`` (resident, proportional, and its own: pages no
other process shares): the model is built once, by the command, and its workers share it.

Targets (issue 45): ``--jobs 2`` at least 1.5x ``--jobs 1``; the memory of each extra worker
under 10 % of the first's (the command's own with ``--jobs 1``).
"""
import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from typing import Dict, List, Optional, Sequence

from benchmarks.audit import quiet_sample, spread
from benchmarks.audit_cluster import lerobot_writer
from collision_sensor.model.example_robots import example_robot_data_dir

SPEED_TARGET = 1.5
MEMORY_TARGET = 0.10


def _smaps(pid: int) -> Optional[Dict[str, int]]:
    """``{Rss, Pss, Private}`` of process ``pid`` in bytes, or None if it is gone."""
    out = {'Rss': 0, 'Pss': 0, 'Private': 0}
    try:
        with open(f'/proc/{pid}/smaps_rollup') as stream:
            for line in stream:
                name, _, value = line.partition(':')
                if name in ('Rss', 'Pss'):
                    out[name] = int(value.split()[0]) * 1024
                elif name in ('Private_Clean', 'Private_Dirty'):
                    out['Private'] += int(value.split()[0]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return out


def _children(pid: int) -> List[int]:
    try:
        with open(f'/proc/{pid}/task/{pid}/children') as stream:
            return [int(child) for child in stream.read().split()]
    except OSError:
        return []


class MemorySampler:
    """The largest figures of a process and its children, sampled every 0.1 s."""

    def __init__(self, pid: int):
        self.pid = pid
        self.peak: Dict[int, Dict[str, int]] = {}
        self.total_pss = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            pss = 0
            for pid in [self.pid] + _children(self.pid):
                figures = _smaps(pid)
                if figures is None:
                    continue
                pss += figures['Pss']
                peak = self.peak.setdefault(pid, dict(figures))
                for key, value in figures.items():
                    peak[key] = max(peak[key], value)
            self.total_pss = max(self.total_pss, pss)
            self._stop.wait(0.1)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def write_dataset(directory: str, episodes: int, frames: int, seed: int) -> tuple:
    """The SO-101 dataset and its joint map; return (dataset, joint map file)."""
    writer = lerobot_writer()
    dataset = os.path.join(directory, 'so101_pick_place')
    states = writer.so101_episodes(episodes, frames, seed)
    writer.write_v30(dataset, writer.SO101_NAMES, states, fps=30, per_file=50)
    joint_map = os.path.join(directory, 'so101.yaml')
    with open(joint_map, 'w') as stream:
        stream.write(writer.SO101_MAP)
    return dataset, joint_map


def audit(dataset: str, joint_map: str, jobs: int, report: str) -> dict:
    """Run the command once; return its wall time, checking time and memory."""
    share = example_robot_data_dir()
    urdf = os.path.join(share, 'robots', 'so_arm_description', 'urdf', 'so101.urdf')
    if os.path.exists(report):
        os.remove(report)
    argv = [sys.executable, '-m', 'collision_sensor.tools.offline_check', dataset, '--urdf',
            urdf, '--package-path', f'example-robot-data={share}', '--joint-map', joint_map,
            '--report', report, '--jobs', str(jobs), '--progress', 'never']
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=os.path.dirname(report))
    sampler = MemorySampler(process.pid)
    out, err = process.communicate()
    wall = time.perf_counter() - start
    sampler.stop()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)   # the command and its workers
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    if process.returncode not in (0, 1):
        raise RuntimeError(f'collision_sensor_check --jobs {jobs} failed: {err}')
    checking = float(re.search(r'this run: .* in ([\d.]+) s', out).group(1))
    driver = sampler.peak.get(process.pid, {'Rss': 0, 'Pss': 0, 'Private': 0})
    workers = [figures for pid, figures in sampler.peak.items() if pid != process.pid]
    with open(report) as stream:
        lines = stream.read()
    return {'wall': wall, 'checking': checking, 'driver': driver, 'workers': workers,
            'cpu': cpu,
            'pss': sampler.total_pss, 'lines': lines,
            'frames_in_collision': sum(int(m) for m in re.findall(
                r'"frames_in_collision": (\d+)', lines))}


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m benchmarks audit dataset',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--episodes', type=int, default=200)
    parser.add_argument('--frames', type=int, default=900)
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--seed', type=int, default=45)
    parser.add_argument('--markdown', metavar='FILE', help='also write the table here')
    args = parser.parse_args(argv)
    text = run(args.episodes, args.frames, args.runs, args.seed,
               log=lambda m: print(f'[python -m benchmarks audit dataset] {m}',
                                   file=sys.stderr, flush=True))
    print(text)
    if args.markdown:
        with open(args.markdown, 'w', encoding='utf-8') as stream:
            stream.write(text)
    return 0


def run(episodes: int, frames: int, runs: int, seed: int, log) -> str:
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory(prefix='collision_sensor_dataset_bench_') as directory:
        log(f'writing an SO-101 dataset of {episodes} episodes of {frames} frames ...')
        dataset, joint_map = write_dataset(directory, episodes, frames, seed)
        size = sum(os.path.getsize(os.path.join(root, name))
                   for root, _, names in os.walk(dataset) for name in names)
        others = quiet_sample(3.0, cores)
        load_before = os.getloadavg()
        results: Dict[int, List[dict]] = {1: [], 2: []}
        for round_index in range(runs):
            for jobs in ((1, 2) if round_index % 2 == 0 else (2, 1)):
                log(f'run {round_index + 1}/{runs}: --jobs {jobs} ...')
                results[jobs].append(audit(dataset, joint_map, jobs,
                                           os.path.join(directory, f'jobs{jobs}.jsonl')))
        load_after = os.getloadavg()
    # each line as the command wrote it, in whatever order its workers finished
    same = len({tuple(sorted(r['lines'].splitlines())) for rs in results.values()
                for r in rs}) == 1
    mib = 2 ** 20
    speed = [a['wall'] / b['wall'] for a, b in zip(results[1], results[2])]
    # the summary gives tenths of a second: a run of tiny units may say 0.0 s
    speed_checking = [a['checking'] / b['checking'] if b['checking'] else float('nan')
                      for a, b in zip(results[1], results[2])]
    # an extra worker's own memory over the --jobs 1 process's, round by round (a worker that
    # lives less than the sampling period may never be seen: tiny datasets)
    share = [max(w['Private'] for w in two['workers']) / one['driver']['Rss']
             for one, two in zip(results[1], results[2]) if two['workers']]
    memory = (f'{spread([100 * x for x in share], "{:.1f}")} % | '
              f'**{"PASS" if max(share) < MEMORY_TARGET else "MISS"}**' if share else
              'not sampled: the workers lived less than the 0.1 s between samples | **n/a**')
    lines = ['## An SO-101 dataset audited (python -m benchmarks audit dataset)', '',
             f'{episodes} episodes of '
             f'{frames} frames at 30 fps ({episodes * frames:,} frames, {size / mib:.1f} MiB of '
             f'parquet; {results[1][0]["frames_in_collision"]:,} frames in collision), LeRobot '
             'v3.0, the SO-101 of example-robot-data (398,884 triangles); '
             f'{runs} runs each way, alternated. Machine: {cores} cores'
             + (f'; {others:.2f} cores busy with others\' work before the runs'
                if others is not None else '')
             + f'; load average {load_before[0]:.2f} before, {load_after[0]:.2f} after. Every '
             f'run gave the same report lines: {"yes" if same else "NO"}.', '',
             '| run | wall s, as the user waits | checking s (after the model is loaded) | '
             'the command\'s process: resident MiB | each worker: resident MiB, of it its own '
             '| all processes: proportional MiB (PSS) | all processes: CPU s (cores used) |',
             '|---|---|---|---|---|---|---|']
    for jobs in (1, 2):
        rows = results[jobs]
        workers = [w for r in rows for w in r['workers']]
        worker_text = (f'{spread([w["Rss"] / mib for w in workers], "{:.0f}")}, '
                       f'{spread([w["Private"] / mib for w in workers], "{:.1f}")}'
                       if workers else '(none: the command checks)')
        lines.append(f'| --jobs {jobs} | {spread([r["wall"] for r in rows])} | '
                     f'{spread([r["checking"] for r in rows])} | '
                     f'{spread([r["driver"]["Rss"] / mib for r in rows], "{:.0f}")} | '
                     f'{worker_text} | {spread([r["pss"] / mib for r in rows], "{:.0f}")} | '
                     f'{spread([r["cpu"] for r in rows])} '
                     f'({statistics.median(r["cpu"] / r["wall"] for r in rows):.2f}) |')
    lines += ['', '| target | measured (min / median / max) | verdict |', '|---|---|---|',
              f'| --jobs 2 >= {SPEED_TARGET}x --jobs 1, as the user waits | {spread(speed)}x | '
              f'**{"PASS" if statistics.median(speed) >= SPEED_TARGET else "MISS"}** |',
              f'| --jobs 2 >= {SPEED_TARGET}x --jobs 1, the checking | '
              f'{spread(speed_checking)}x | '
              f'**{"PASS" if statistics.median(speed_checking) >= SPEED_TARGET else "MISS"}** |',
              f'| an extra worker\'s own memory < {MEMORY_TARGET:.0%} of the first\'s (--jobs '
              f'1\'s process) | {memory} |']
    return '\n'.join(lines) + '\n'
