"""``python -m benchmarks page``: run every benchmark and write docs/performance.md.

``python -m benchmarks page [--runs 3] [--output docs/performance.md] [--only NAME ...]
[--quick]`` (``make bench``) runs each benchmark of :data:`BENCHMARKS` ``--runs`` times, each
in a process of its own, one after the other, and writes one page: the machine, then per
benchmark its command and its figures, each the median run's with the range over the runs in
brackets (:mod:`benchmarks.runs`). A benchmark that reports markdown (the scenarios, the audit)
runs its N runs itself; the others print text, which is run N times and merged line by line.

``--only NAME`` runs those benchmarks alone and replaces their sections of an existing page,
keeping the others as they were. ``--quick`` runs each small, for a smoke test (its figures
say little). The page holds no date and no version of this project: it is the figures of the
code it was run on, regenerated whenever they change.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence

from benchmarks.runs import merge_reports

PROG = 'python -m benchmarks page'
DEFAULT_OUTPUT = os.path.join('docs', 'performance.md')
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@dataclass(frozen=True)
class Benchmark:
    """One section of the page.

    :ivar argv: ``argv(runs, quick, markdown_file)``: the arguments after ``python -m``.
    :ivar merges_runs: the benchmark runs its ``runs`` itself and writes markdown to the file
        (else it prints text, run ``runs`` times and merged here).
    :ivar exit_codes: the exit statuses of a run that measured (1: a target missed).
    :ivar prints_markdown: what it prints is markdown (else it is shown as text).
    """

    name: str
    title: str
    about: str
    argv: Callable[[int, bool, str], List[str]]
    merges_runs: bool = False
    exit_codes: tuple = (0,)
    prints_markdown: bool = False


BENCHMARKS = (
    Benchmark('scenarios', 'The engine against pinocchio+coal and python-fcl',
              'Thirteen scenarios, ours and the peers on the same meshes and configurations '
              'in one process (the list: `python -m benchmarks --help`).',
              lambda runs, quick, out: ['benchmarks', '--runs', str(runs), '--markdown', out]
              + (['--quick'] if quick else []), merges_runs=True),
    Benchmark('audit', 'Checking many recordings',
              '`collision_sensor_check` on many CSV recordings: one process, two, and a local '
              'Ray cluster of two CPUs.',
              lambda runs, quick, out: ['benchmarks', 'audit', '--runs', str(runs),
                                        '--markdown', out]
              + (['--recordings', '6', '--frames', '40', '--no-ray'] if quick else []),
              merges_runs=True),
    Benchmark('audit_dataset', 'Checking a LeRobot dataset of the SO-101',
              '`collision_sensor_check` on 200 SO-101 episodes as LeRobot records them, '
              '`--jobs 1` and `--jobs 2`: time, and the memory of every process.',
              lambda runs, quick, out: ['benchmarks', 'audit', 'dataset', '--runs', str(runs),
                                        '--markdown', out]
              + (['--episodes', '4', '--frames', '60'] if quick else []),
              merges_runs=True),
    Benchmark('audit_cluster', 'Checking many recordings on a Ray cluster',
              '`collision_sensor_check --ray` on a simulated cluster (two one-CPU nodes beside '
              'the driver): throughput against `--jobs 2`, the driver\'s CPU per unit and the '
              'cluster it can feed, nodes killed mid-run.',
              lambda runs, quick, out: ['benchmarks', 'audit', 'cluster', '--runs', str(runs),
                                        '--markdown', out] + (['--quick'] if quick else []),
              merges_runs=True),
    Benchmark('node', 'The node: joint states in, verdicts out',
              '`collision_sensor_node` (Panda) as a process of its own, fed joint states at '
              'rising rates by another; latency from publishing to the verdict.',
              lambda runs, quick, out: ['benchmarks.node_latency']
              + (['--rate', '200', '--duration', '1'] if quick else [])),
    Benchmark('fk', 'Forward kinematics',
              'Every link of the Panda at random configurations: ours (single, batch) '
              'against yourdfpy and pinocchio.',
              lambda runs, quick, out: ['benchmarks.fk'] + (['--configs', '50'] if quick
                                                            else [])),
    Benchmark('acm', 'Exception lists (`collision_sensor_acm`)',
              'Configurations per second sampled for the self-collision matrix: our '
              '`check_batch` against pinocchio+coal.',
              lambda runs, quick, out: ['benchmarks.acm_rate']
              + (['--configurations', '100', '--repeats', '1'] if quick else []),
              prints_markdown=True),
    Benchmark('first_start', 'First start',
              'Import, load the Panda, first verdict: cold caches, a fresh install, warm.',
              lambda runs, quick, out: ['benchmarks.first_start'], exit_codes=(0, 1)),
)
NAMES = tuple(benchmark.name for benchmark in BENCHMARKS)

PAGE_HEADER = '''\
# Performance

What the code costs, measured by `python -m benchmarks page` (`make bench`), each benchmark's
command given in its section: every figure is the median run's, with the range over the runs
in brackets. Ratios are ours / the peer's, measured in the same run (below 1: we are faster).
The machine is shared: read the ranges, not the best figure. Regenerate this page whenever
the figures may have changed (`--only NAME`: one section).

Machine: {machine}.
'''
QUICK_NOTE = ('Measured with `--quick` (small counts and meshes): a smoke run of the page, not '
              'figures to quote; `make bench` measures them.')
BEGIN, END = '<!-- benchmark {} -->', '<!-- end of benchmark {} -->'


def run_once(benchmark: Benchmark, runs: int, quick: bool, log) -> str:
    """Run ``benchmark`` (its ``runs`` itself, or once); return its markdown or its text.

    :raises RuntimeError: it failed (its output in the message).
    """
    with tempfile.TemporaryDirectory(prefix='collision_sensor_page_') as work:
        out = os.path.join(work, 'section.md')
        argv = [sys.executable, '-m'] + benchmark.argv(runs, quick, out)
        env = dict(os.environ)
        env['PYTHONPATH'] = os.pathsep.join(
            [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p] + [ROOT])
        log(f'{benchmark.name}: {" ".join(argv[2:])}')
        proc = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=work)
        if proc.returncode not in benchmark.exit_codes:
            raise RuntimeError(f'{benchmark.name} exited {proc.returncode}:\n{proc.stdout}\n'
                               f'{proc.stderr}')
        if benchmark.merges_runs:
            with open(out, encoding='utf-8') as stream:
                return stream.read()
        return proc.stdout


def section(benchmark: Benchmark, runs: int, quick: bool, log=lambda m: None) -> str:
    """Return ``benchmark``'s section of the page, measured now."""
    if benchmark.merges_runs:
        body = run_once(benchmark, runs, quick, log)
        # its own report's first heading is the section's title here
        body = re.sub(r'\A\s*##[^\n]*\n', '', body).strip()
    else:
        texts = [run_once(benchmark, runs, quick, log) for _ in range(runs)]
        merged = merge_reports(texts).strip()
        note = ''
        if merged.startswith('**'):
            note, _, merged = merged.partition('\n\n')
        if benchmark.prints_markdown:   # its headings below the section's
            merged = re.sub(r'^(#+) ', lambda m: '#' * max(3, len(m.group(1)) + 1) + ' ',
                            merged.strip('\n'), flags=re.M)
        else:
            merged = '```text\n' + merged.strip('\n') + '\n```'
        body = (note + '\n\n' if note else '') + merged
    command = 'python -m ' + ' '.join(benchmark.argv(runs, quick, 'FILE'))
    if not benchmark.merges_runs and runs > 1:
        command += f'` ({runs} runs)'
    else:
        command += '`'
    lines = [BEGIN.format(benchmark.name), f'## {benchmark.title}', '', benchmark.about, '',
             f'`{command}', '']
    if quick:
        lines += [QUICK_NOTE, '']
    return '\n'.join(lines + [body, '', END.format(benchmark.name)])


def sections_of(page: str) -> Dict[str, str]:
    """Return ``{name: section text}`` of an existing page."""
    found = {}
    for name in re.findall(r'<!-- benchmark (\w+) -->', page):
        start = page.index(BEGIN.format(name))
        end = page.index(END.format(name), start) + len(END.format(name))
        found[name] = page[start:end]
    return found


def page(sections: Dict[str, str]) -> str:
    """Return the whole page: the header, then the sections in :data:`BENCHMARKS` order."""
    from benchmarks.main import machine
    text = PAGE_HEADER.format(machine=machine())
    for name in NAMES:
        if name in sections:
            text += '\n' + sections[name] + '\n'
    return text


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the benchmarks; write the page."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split('\n\n')[0])
    parser.add_argument('--runs', type=int, default=3, metavar='N',
                        help='runs of each benchmark (default %(default)s; at least 3 for a '
                             'page others read)')
    parser.add_argument('--output', default=DEFAULT_OUTPUT, metavar='FILE',
                        help='the page (default %(default)s, under the current directory)')
    parser.add_argument('--only', action='append', choices=NAMES, metavar='NAME',
                        help=f'run this benchmark alone and replace its section '
                             f'(repeatable; one of {", ".join(NAMES)})')
    parser.add_argument('--quick', action='store_true',
                        help='each benchmark small: a smoke test of the page, not figures')
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error(f'--runs {args.runs}: give at least 1')

    def log(message):
        print(f'[{PROG}] {message}', file=sys.stderr, flush=True)

    existing = {}
    if args.only and os.path.exists(args.output):
        with open(args.output, encoding='utf-8') as stream:
            existing = sections_of(stream.read())
    chosen = [b for b in BENCHMARKS if not args.only or b.name in args.only]
    try:
        for benchmark in chosen:
            existing[benchmark.name] = section(benchmark, args.runs, args.quick, log)
    except RuntimeError as err:
        print(f'{PROG}: error: {err}', file=sys.stderr)
        return 1
    text = page(existing)
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with open(args.output, 'w', encoding='utf-8') as stream:
        stream.write(text)
    print(args.output)
    return 0


if __name__ == '__main__':
    sys.exit(main())
