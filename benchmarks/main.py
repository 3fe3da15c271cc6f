"""python -m benchmarks: this package against pinocchio+coal and python-fcl, in one run.

``python -m benchmarks [--quick] [--scenario N ...] [--seed S] [--runs N] [--markdown FILE]
[--plot FILE.png] [--motion-parts LETTERS] [--urdf FILE [--srdf FILE] [--package-path
NAME=DIR ...] [--xacro-arg NAME:=VALUE ...]]``

With ``--urdf`` the robot scenarios (1, 2 and 8) run on that robot instead of the bundled ones,
against pinocchio+coal and python-fcl, both loading the same files (pinocchio reads the URDF
itself; python-fcl gets the triangles our loader read); a peer that cannot load the robot is
reported so, never left out silently.

Every scenario measures our checker and the peers on the same meshes and configurations in
the same process, so the ratios hold on this machine whatever its speed. The markdown
(printed, and written with ``--markdown``) is what docs/performance.md shows;
``--plot`` draws query time against triangle count (scenario 4) and the per-configuration
times of scenario 1. Peers are optional: a missing one is reported as missing.

1. random configurations (Panda, UR5, demo arm in its scene) against pinocchio+coal and
   python-fcl; 2. coherent streams, ``update`` against ``check``; 3. the paper's experiment
   (demo arm into the washer); 4. scale (Panda against 10k, 100k and 1M-triangle meshes);
   5. the parts (box tests, expansion rules, bounding-volume fits, the cost of a call);
   6. heavy contact (a tool mesh among clutter, against python-fcl); 7. large meshes and
   many pairs (example-robot-data robots of 50k triangles and more, against pinocchio+coal);
   8. proximity (distances and nearest points against python-fcl and pinocchio+coal);
   9. the dynamic scene (one of 50 objects moving per step, ``update`` against ``check``; a
   100k-triangle mesh added, against python-fcl's BVH build); 10. motion between states
   (``check_motion`` against dense sampling confirmed by python-fcl on 10,000 segments of
   seven robots in clutter; against pinocchio+coal and ``check_batch`` on the motion
   discretized at 0.01 rad; against python-fcl's ``continuousCollide``; ``update_motion``
   against ``update``); 11. the batches on every core (``check_batch``, ``update_batch``,
   ``check_path`` on one thread against two; every other scenario runs our checker on one
   thread, as its peers run); 12. point clouds (a 640 x 480
   depth camera's organised cloud self-filtered, voxelised and checked, against a pipeline of
   python-fcl, trimesh and numpy); 13. every example-robot-data robot with a collision mesh
   against pinocchio+coal on the same pairs (the distribution of the ratios), and two of its
   meshes in heavy contact (a 200-triangle hand on a free joint against a 2,188-triangle arm
   link) against python-fcl.
"""
import argparse
import dataclasses
import importlib.metadata
import os
import platform
import sys
import tempfile
import time
from typing import List, Optional, Sequence

from collision_sensor.errors import CollisionSensorError, ConfigError
from benchmarks.runs import merge_reports
from benchmarks.scenario_report import Section
from benchmarks.scenario_settings import Settings

SCENARIOS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13)
#: The scenarios that take a robot, run on the user's with --urdf.
ROBOT_SCENARIOS = (1, 2, 8)
PROG = 'python -m benchmarks'
PEERS = (('pinocchio', 'pin'), ('coal', 'coal'), ('python-fcl', 'python-fcl'))


def run_scenarios(numbers: Sequence[int], settings: Settings, log=None,
                  robot: Optional[dict] = None) -> List[Section]:
    """Run the scenarios ``numbers`` in order; return their sections.

    :param robot: the user's robot, ``{urdf, srdf, package_paths, xacro_args}``: the robot
        scenarios run on it alone.
    """
    from benchmarks import (
        scenario_cells, scenario_clouds, scenario_contact, scenario_dynamic, scenario_everyrobot,
        scenario_large, scenario_motion, scenario_paper, scenario_parts, scenario_proximity,
        scenario_random, scenario_scale, scenario_streams, scenario_threads)
    log = log or (lambda message: None)
    sections = []
    with tempfile.TemporaryDirectory(prefix='collision_sensor_benchmarks_') as workdir:
        cells = None
        if robot is not None:
            cells = [scenario_cells.user_cell(workdir=workdir, **robot)]
        for number in numbers:
            log(f'scenario {number} ...')
            start = time.perf_counter()
            if number in (1, 2) and cells is None:
                cells = [scenario_cells.robot_cell('panda'), scenario_cells.robot_cell('ur5'),
                         scenario_cells.demo_arm_cell(workdir)]
            if number == 1:
                section = scenario_random.run(settings, cells)
            elif number == 2:
                section = scenario_streams.run(settings, cells)
            elif number == 3:
                section = scenario_paper.run(
                    settings, scenario_cells.demo_arm_cell(workdir, washer_only=True))
            elif number == 4:
                section = scenario_scale.run(settings)
            elif number == 5:
                section = scenario_parts.run(settings)
            elif number == 6:
                section = scenario_contact.run(settings, workdir)
            elif number == 7:
                section = scenario_large.run(settings)
            elif number == 8:
                section = scenario_proximity.run(settings, cells if robot is not None else None)
            elif number == 9:
                section = scenario_dynamic.run(settings)
            elif number == 10:
                section = scenario_motion.run(settings, workdir)
            elif number == 11:
                section = scenario_threads.run(settings)
            elif number == 13:
                section = scenario_everyrobot.run(settings, workdir)
            else:
                section = scenario_clouds.run(settings)
            section.plot['seconds'] = time.perf_counter() - start
            log(f'scenario {number} done in {section.plot["seconds"]:.0f} s')
            sections.append(section)
    return sections


def _version(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return 'not installed'


def _cpu() -> str:
    try:
        with open('/proc/cpuinfo') as stream:
            for line in stream:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or 'unknown CPU'


def machine() -> str:
    """Return the machine and the software the figures were measured with, in one sentence."""
    from collision_sensor.engine.compiled import engine
    import numpy
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count()
    peers = ', '.join(f'{label} {_version(dist)}' for label, dist in PEERS)
    return (f'{_cpu()} ({cores} cores available); Python {platform.python_version()}, numpy '
            f'{numpy.__version__}, engine C++ {engine.COMPILER}; peers: {peers}')


def header(settings: Settings, numbers: Sequence[int],
           robot: Optional[dict] = None) -> List[str]:
    """Return the report's opening lines: machine, versions, run settings (and the user's
    robot)."""
    return [
        '## Performance (python -m benchmarks)', '',
        f'Machine: {machine()}. Settings: {"--quick, " if settings.quick else ""}seed '
        f'{settings.seed}, scenarios {", ".join(map(str, numbers))}. Every figure is measured '
        'in this run; ratios are ours / peer (below 1: we are faster).',
    ] + ([f'Robot: {robot["urdf"]}' + (f' with {robot["srdf"]}' if robot['srdf'] else
                                       ' (no SRDF: every pair but adjacent links checked)')]
         if robot is not None else [])


def summary(sections: Sequence[Section]) -> List[str]:
    """Return the table of every target with its verdict."""
    lines = ['', '### Targets', '', '| target | measured | verdict |', '|---|---|---|']
    verdicts = [v for s in sections for v in s.verdicts]
    for v in verdicts:
        lines.append(f'| {v.target} | {v.measured} | **{v.word}** |')
    if not verdicts:
        lines.append('| (no scenario with a target was run) | | |')
    return lines


def markdown(settings: Settings, numbers: Sequence[int], sections: Sequence[Section],
             robot: Optional[dict] = None) -> str:
    """Return the whole report as markdown."""
    lines = header(settings, numbers, robot) + summary(sections)
    for section in sections:
        lines += ['', f'### {section.title}', ''] + section.lines
    text = '\n'.join(lines)
    while '\n\n\n' in text:
        text = text.replace('\n\n\n', '\n\n')
    return text.strip() + '\n'


def plot(sections: Sequence[Section], path: str) -> None:
    """Draw scenario 4's query time against triangle count (log x) and scenario 1's bars."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    data = {}
    for section in sections:
        data.update(section.plot)
    panels = [name for name in ('scale', 'random') if data.get(name)]
    figure, axes = plt.subplots(1, max(1, len(panels)), figsize=(6.0 * max(1, len(panels)), 4.5),
                                squeeze=False)
    axes = axes[0]
    if not panels:
        axes[0].text(0.5, 0.5, 'no plotted scenario (1 or 4) was run', ha='center',
                     va='center')
        axes[0].set_axis_off()
    for ax, panel in zip(axes, panels):
        if panel == 'scale':
            points = data['scale']
            n = [p['triangles'] for p in points]
            ax.plot(n, [p['ours_query'] for p in points], 'o-', label='collision_sensor (ours)')
            if all(p.get('fcl_query') is not None for p in points):
                ax.plot(n, [p['fcl_query'] for p in points], 's--', label='python-fcl')
            ax.set_xscale('log')
            ax.set_ylim(bottom=0)
            ax.set_xlabel('scene triangles')
            ax.set_ylabel('us per query (Panda vs terrain)')
            ax.set_title('Scenario 4: query time against scene size')
        else:
            robots = list(data['random'])
            labels = []
            for times in data['random'].values():
                labels += [label for label in times if label not in labels]
            width = 0.8 / len(labels)
            for k, label in enumerate(labels):
                xs = [i + (k - (len(labels) - 1) / 2) * width for i in range(len(robots))]
                ax.bar(xs, [data['random'][r].get(label, 0.0) for r in robots], width,
                       label=label)
            ax.set_xticks(range(len(robots)))
            ax.set_xticklabels(robots)
            ax.set_ylabel('us per random configuration')
            ax.set_title('Scenario 1: full check, random configurations')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the benchmark; print the markdown and write the requested files."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ['audit']:    # checking many recordings: python -m benchmarks audit --help
        from benchmarks import audit
        return audit.main(argv[1:])
    if argv[:1] == ['page']:     # every benchmark into docs/performance.md (make bench)
        from benchmarks import page
        return page.main(argv[1:])
    parser = argparse.ArgumentParser(
        prog=PROG, description=__doc__.split('\n\n')[0],
        epilog='Scenarios: ' + __doc__.split('\n\n')[-1].strip().replace('\n  ', ' ')
        + ' Checking many recordings (collision_sensor_check --jobs, --ray): '
          'python -m benchmarks audit --help. Every benchmark into docs/performance.md: '
          'python -m benchmarks page --help.')
    parser.add_argument('--quick', action='store_true',
                        help='small counts and meshes, for a smoke run (figures are rough)')
    parser.add_argument('--scenario', type=int, action='append', choices=SCENARIOS,
                        metavar='N', help='run scenario N (1-13); repeatable; default: all (with '
                                          '--urdf: 1, 2 and 8)')
    robot = parser.add_argument_group(
        'your robot', 'run the robot scenarios (1 random configurations, 2 coherent streams, '
        '8 proximity) on your robot, against pinocchio+coal and python-fcl')
    robot.add_argument('--urdf', metavar='FILE', help='the robot\'s URDF (or .xacro)')
    robot.add_argument('--srdf', metavar='FILE',
                       help='its SRDF: disable_collisions entries are not checked (by the peers '
                            'either)')
    robot.add_argument('--package-path', metavar='NAME=DIR', action='append', default=[],
                       help='directory of a package named in package:// URIs (repeatable)')
    robot.add_argument('--xacro-arg', metavar='NAME:=VALUE', action='append', default=[],
                       help='argument of a .xacro robot description (repeatable)')
    parser.add_argument('--seed', type=int, default=Settings.seed,
                        help=f'seed of every random input (default {Settings.seed})')
    parser.add_argument('--runs', type=int, default=1, metavar='N',
                        help='run the scenarios N times and report each figure as the median '
                        'run\'s with the range over the runs (default 1)')
    parser.add_argument('--markdown', metavar='FILE', help='also write the table here')
    parser.add_argument('--plot', metavar='FILE.png', help='write the plot here')
    parser.add_argument('--motion-parts', default='ABCD', metavar='LETTERS',
                        help='scenario 10\'s parts to run: A certification, B speed against '
                        'the discretized motion, C python-fcl\'s continuousCollide, D '
                        'update_motion on the streams (default ABCD)')
    args = parser.parse_args(argv)
    try:
        robot = _user_robot(args)
    except CollisionSensorError as err:
        return _error(str(err))
    numbers = sorted(set(args.scenario or (ROBOT_SCENARIOS if robot else SCENARIOS)))
    settings = Settings.for_run(args.quick, args.seed)
    parts = tuple(args.motion_parts.upper())
    if not parts or set(parts) - set('ABCD'):
        return _error(f'--motion-parts {args.motion_parts}: give letters of ABCD, e.g. BD')
    settings = dataclasses.replace(settings, motion_parts=tuple(sorted(set(parts))))

    def log(message):
        print(f'[{PROG}] {message}', file=sys.stderr, flush=True)

    if args.runs < 1:
        return _error(f'--runs {args.runs}: give at least 1')
    reports = []
    try:
        for run in range(args.runs):
            if args.runs > 1:
                log(f'run {run + 1} of {args.runs}')
            sections = run_scenarios(numbers, settings, log, robot)
            reports.append(markdown(settings, numbers, sections, robot))
    except CollisionSensorError as err:   # the user's robot did not load: the file, the fix
        return _error(str(err))
    text = merge_reports(reports)
    print(text)
    if args.markdown:
        with open(args.markdown, 'w', encoding='utf-8') as stream:
            stream.write(text)
    if args.plot:
        plot(sections, args.plot)
    return 0


def _user_robot(args) -> Optional[dict]:
    """Return the user's robot from the options, or None; check the options fit together.

    :raises ConfigError: robot options without --urdf, a scenario without a robot, a missing
        file or a malformed option.
    """
    from collision_sensor.model.mesh_loading import parse_package_paths
    from collision_sensor.model.xacro_expansion import parse_xacro_args
    if args.urdf is None:
        given = [option for option, value in (('--srdf', args.srdf),
                                              ('--package-path', args.package_path),
                                              ('--xacro-arg', args.xacro_arg)) if value]
        if given:
            raise ConfigError(f'{", ".join(given)} describe your robot: add --urdf FILE')
        return None
    other = sorted(set(args.scenario or ()) - set(ROBOT_SCENARIOS))
    if other:
        raise ConfigError(f'--scenario {", ".join(map(str, other))}: with --urdf only the robot '
                          'scenarios 1, 2 and 8 run (on your robot); the others have scenes '
                          'of their own, run them without --urdf')
    for option, path in (('--urdf', args.urdf), ('--srdf', args.srdf)):
        if path is not None and not os.path.isfile(path):
            raise ConfigError(f'{option} "{path}": file not found; give the robot\'s '
                              f'{option[2:].upper()} file')
    return {'urdf': args.urdf, 'srdf': args.srdf,
            'package_paths': parse_package_paths(args.package_path),
            'xacro_args': parse_xacro_args(args.xacro_arg)}


def _error(message: str) -> int:
    print(f'{PROG}: error: {" ".join(message.split())}', file=sys.stderr)
    return 2


if __name__ == '__main__':
    sys.exit(main())
