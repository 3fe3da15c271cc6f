"""``collision_sensor_acm``: find the pairs of links that need no collision check.

The self-collision matrix of a robot, as the MoveIt Setup Assistant computes it, from the URDF
alone::

    collision_sensor_acm panda.urdf --package-path example-robot-data=DIR --output panda.srdf
    collision_sensor_acm arm.urdf --srdf arm.srdf --in-place --never --yaml acm.yaml
    collision_sensor_acm ur5.urdf --srdf ur5.srdf --warning-distance 0.05 --yaml ur5_acm.yaml

Each pair of links with geometry gets at most one reason, the first that applies:

``Adjacent``
    a link and its nearest ancestor with geometry (parent and child, also across links
    without geometry): they touch by design. Found from the tree, no sampling.
``Default``
    in collision in the default pose: all joints at zero, or a ``group_state`` of the SRDF
    (``--default-state``; joints it does not name stay at zero).
``Always``
    in collision in at least ``--always-fraction`` of random configurations. Sampled in
    rounds of ``--samples-per-round``; the counts add up over rounds, and sampling stops
    after a round that neither adds a pair to the list nor drops one (at least two rounds:
    the first sets the list, the next must confirm it; at most ``--max-rounds``).
``Never`` (only with ``--never``)
    no collision in ``--never-samples`` random configurations (the samples of the Always
    rounds count, more are drawn up to the number). Sampling is not proof: a pair that never
    collided in N samples can still collide in a configuration that was not drawn.

Configurations are uniform within the joint limits (continuous joints in [-pi, pi]); the
random generator is seeded (``--seed``), so a run can be repeated exactly. The sampling checks
the raw matrix: no SRDF pairs and no adjacency exceptions, only the pairs not yet explained by
an earlier reason are sampled, with :meth:`CollisionChecker.check_batch`.

With ``--clearance``, each Never pair's smallest distance is measured by the engine
(:meth:`CollisionChecker.proximity`, the triangles' distance), over a subset of the samples
(``--clearance-samples``); the output says over how many.

The warning zone (``--warning-distance D``): the pairs that stay checked (neither found above
nor disabled by ``--srdf``) whose distance is below ``D`` in every one of
``--warning-samples`` random configurations (the default pose first), measured by the engine
as the node measures its ``warning_distance``. Such a pair, e.g. the UR5's ``ee_link`` and
``wrist_2_link`` (0.0198 m apart wherever the arm goes), would keep the node's warning zone on
for good; the list goes to the node's ``warning_ignore`` parameter (``link_a:link_b`` strings:
printed, and in ``--yaml``). Distances are the links' surfaces', unpadded: the node subtracts
both links' paddings, so with padding give ``D`` plus the two paddings. Sampling is not proof:
a pair listed may still move farther apart in a configuration that was not drawn.

Exit status 0 on success, 2 on error (one line on stderr: ``collision_sensor_acm: error:
...``).
"""
import argparse
import math
import os
import sys
import time
from typing import Optional, Sequence

from collision_sensor.errors import ConfigError
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.model.xacro_expansion import parse_xacro_args
from collision_sensor.tools.collision_matrix import (
    DEFAULT_ALWAYS_FRACTION, DEFAULT_CLEARANCE_SAMPLES, DEFAULT_MAX_ROUNDS,
    DEFAULT_NEVER_SAMPLES, DEFAULT_SAMPLES_PER_ROUND, DEFAULT_WARNING_SAMPLES, compute_matrix)
from collision_sensor.tools.collision_matrix_report import (
    PROG, allowed_collisions, params_yaml, provenance, report, srdf_entries)
from collision_sensor.tools.command_line import run_command
from collision_sensor.tools.progress import MODES

EXIT_OK, EXIT_ERROR = 0, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, as every other error of the tool
        self.exit(EXIT_ERROR, f'{PROG}: error: {message} (see --help)\n')


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f'"{text}" is not a fraction in (0, 1], e.g. 0.95')
    return value


def _distance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f'"{text}" is not a distance in metres > 0, e.g. 0.05')
    return value


def _at_least(least: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'"{text}" is not a whole number') from None
        if value < least:
            raise argparse.ArgumentTypeError(f'{value} is less than {least}')
        return value
    return parse


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = _Parser(
        prog=PROG,
        description='Compute the self-collision matrix of a robot: the pairs of links that '
                    'need no collision check (Adjacent, Default, Always and, with --never, '
                    'Never), as SRDF <disable_collisions> entries and as the '
                    'allowed_collisions list of collision_sensor_node.',
        epilog='Sampling is not proof: "Always" and "Never" come from random configurations '
               '(uniform within the joint limits, continuous joints in [-pi, pi]), and a '
               'configuration that was not drawn can behave otherwise; check a Never list '
               'before you trust it. The default pose is all joints at zero (even where zero '
               'lies outside a joint\'s limits), or --default-state. Exit status: 0 success, '
               '2 error.')
    parser.add_argument('urdf', metavar='URDF', help='robot description file')
    parser.add_argument('--package-path', metavar='NAME=DIR', action='append', default=[],
                        help='directory of a package named in package:// URIs (repeatable)')
    parser.add_argument('--xacro-arg', metavar='NAME:=VALUE', action='append', default=[],
                        help='argument of a .xacro robot description (repeatable)')
    parser.add_argument('--srdf', metavar='EXISTING',
                        help='existing SRDF: its group_states for --default-state, and the '
                             'document --in-place merges into (or --output copies merged); its '
                             'disable_collisions entries are kept, never used for sampling')
    parser.add_argument('--default-state', metavar='NAME',
                        help='group_state of --srdf used as the default pose (default: zero)')
    parser.add_argument('--always-fraction', type=_fraction, default=DEFAULT_ALWAYS_FRACTION,
                        metavar='F', help='a pair colliding in at least this fraction of the '
                                          'samples is "Always" (default %(default)s)')
    parser.add_argument('--samples-per-round', type=_at_least(1), metavar='N',
                        default=DEFAULT_SAMPLES_PER_ROUND,
                        help='random configurations per Always round (default %(default)s)')
    parser.add_argument('--max-rounds', type=_at_least(2), default=DEFAULT_MAX_ROUNDS,
                        metavar='N', help='stop the Always rounds here even if the list still '
                                          'changes, with a warning (default %(default)s)')
    parser.add_argument('--never', action='store_true',
                        help='also list "Never" pairs: no collision in --never-samples random '
                             'configurations (not proof that they cannot collide)')
    parser.add_argument('--never-samples', type=_at_least(1), default=DEFAULT_NEVER_SAMPLES,
                        metavar='N', help='samples a Never pair must stay clear in, the Always '
                                          'rounds\' included (default %(default)s)')
    parser.add_argument('--clearance', action='store_true',
                        help='with --never: measure each Never pair\'s smallest distance (the '
                             'engine\'s proximity query) over --clearance-samples of the '
                             'samples')
    parser.add_argument('--clearance-samples', type=_at_least(1),
                        default=DEFAULT_CLEARANCE_SAMPLES, metavar='N',
                        help='samples the clearance is measured over (default %(default)s)')
    parser.add_argument('--warning-distance', type=_distance, metavar='D',
                        help='also list the pairs that stay checked yet are nearer than D '
                             'metres in every sample (the node\'s warning zone would be on for '
                             'good): printed and written to --yaml as the node\'s '
                             'warning_ignore; surfaces unpadded, with padding add the two '
                             'links\' paddings to D')
    parser.add_argument('--warning-samples', type=_at_least(1), default=DEFAULT_WARNING_SAMPLES,
                        metavar='N', help='configurations a pair must stay nearer than D in, '
                                          'the default pose first (default %(default)s)')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the random configurations (default %(default)s)')
    written = parser.add_mutually_exclusive_group()
    written.add_argument('--output', metavar='FILE.srdf',
                         help='write an SRDF: a new one, or with --srdf a copy of it with the new '
                              'entries merged in')
    written.add_argument('--in-place', action='store_true',
                         help='merge the new entries into the --srdf file itself; entries '
                              'already there are kept as they are, every other byte stays')
    parser.add_argument('--yaml', metavar='FILE',
                        help='write a ros2 params file setting allowed_collisions to every '
                             'pair found (and warning_ignore, with --warning-distance)')
    parser.add_argument('--progress', choices=MODES, default='auto',
                        help='progress bar on stderr: auto (on a terminal), always, never')
    return parser


def _write(path: str, data: bytes) -> None:
    try:
        with open(path, 'wb') as stream:
            stream.write(data)
    except OSError as err:
        raise ConfigError(f'cannot write "{path}": {err.strerror}; check the directory and '
                          'permissions') from None


def _run(args, argv: Sequence[str], start: float) -> int:
    from collision_sensor.engine.checker import CollisionChecker
    from collision_sensor.model.srdf import load_srdf_for_model
    from collision_sensor.model.srdf_merge import merge_disable_collisions, new_srdf

    if args.in_place and not args.srdf:
        raise ConfigError('--in-place merges into the --srdf file; add --srdf FILE, or write a '
                          'new file with --output')
    if args.clearance and not args.never:
        raise ConfigError('--clearance measures Never pairs; add --never')
    if not os.path.isfile(args.urdf):
        raise ConfigError(f'URDF "{args.urdf}" not found; give the path of the robot\'s URDF '
                          '(or .xacro) file')
    base = CollisionChecker.from_urdf(args.urdf,
                                      package_paths=parse_package_paths(args.package_path) or None,
                                      config={'ignore_adjacent': False},
                                      xacro_args=parse_xacro_args(args.xacro_arg) or None)
    srdf = original = None
    if args.srdf:
        srdf = load_srdf_for_model(args.srdf, base.model)
        with open(args.srdf, 'rb') as stream:
            original = stream.read()
    elif args.default_state:
        raise ConfigError(f'--default-state "{args.default_state}" needs the SRDF that defines '
                          'it; add --srdf FILE')

    matrix = compute_matrix(
        base, srdf=srdf, default_state=args.default_state, always_fraction=args.always_fraction,
        samples_per_round=args.samples_per_round, max_rounds=args.max_rounds, never=args.never,
        never_samples=args.never_samples, clearance=args.clearance,
        clearance_samples=args.clearance_samples, seed=args.seed,
        warning_distance=args.warning_distance, warning_samples=args.warning_samples,
        progress=args.progress)

    command = ' '.join([PROG] + list(argv))
    outcome = []
    entries = srdf_entries(matrix)
    if original is not None and (args.output or args.in_place):
        merged, added = merge_disable_collisions(original, entries, source=args.srdf)
        target = args.srdf if args.in_place else args.output
        _write(target, merged)
        outcome.append(f'SRDF: {target}: kept the {len(srdf.disabled_pairs)} entries of '
                       f'{args.srdf}, added {len(added)} new')
    elif args.output:
        _write(args.output, new_srdf(matrix.robot_name, entries,
                                     f'generated by {command}; {provenance(matrix)}')
               .encode('utf-8'))
        outcome.append(f'SRDF: {args.output}: {len(entries)} entries')
    if args.yaml:
        _write(args.yaml, params_yaml(matrix, command).encode('utf-8'))
        outcome.append(f'params file: {args.yaml}')

    print(report(matrix))
    print('allowed_collisions: [' + ', '.join(f'"{e}"' for e in allowed_collisions(matrix))
          + ']')
    if matrix.warning_zone is not None:
        print('warning_ignore: [' + ', '.join(f'"{e}"' for e in
                                              matrix.warning_zone.warning_ignore()) + ']')
    for line in outcome:
        print(line)
    print(f'took {time.monotonic() - start:.1f} s')
    return EXIT_OK


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the tool; return the exit status (0 success, 2 error)."""
    start = time.monotonic()
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_command(PROG, build_parser(), lambda args: _run(args, argv, start), argv)


if __name__ == '__main__':
    sys.exit(main())
