"""``collision_sensor_check``: run the collision checker over a recorded sequence, without ROS.

Every frame goes through ``checker.update`` (the incremental check, sec. 4 of the paper) in
order; ``--full`` uses ``checker.check`` instead. The robot defaults to the bundled demo cell
(``config/demo_arm.urdf`` with its SRDF and ``config/demo_scene.yaml``)::

    collision_sensor_check paper_experiment --plot contacts.png
    collision_sensor_check run.mcap --urdf my_robot.urdf --package-path my_robot=~/ws/src/my_robot

A bag's scene changes (``visualization_msgs/MarkerArray`` on ``/scene``, ``--scene-topic``)
are applied before the frames they precede, by the node's rules
(:mod:`collision_sensor.engine.scene_markers`): objects added, moved, attached and removed
while the robot moves. A recorded array the node would reject stops the run with its reason (status 2).

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

One episode of a LeRobot dataset, as a report names it (``DATASET#N``), is one recording too
(``--json``, ``--plot``; its joints through ``--joint-map``).

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
import math
import os
import sys
from typing import Optional, Sequence, TextIO, Tuple

from collision_sensor.errors import ConfigError, SequenceError
from collision_sensor.engine.checker_config import CheckerConfig
from collision_sensor.engine.scene_markers import SceneTopic
from collision_sensor.model.joint_map import load_joint_map
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.model.sequences import DEFAULT_TOPIC, SCENE_TOPIC
from collision_sensor.model.xacro_expansion import parse_xacro_args
from collision_sensor.tools.audit.batch import (
    default_jobs, make_runner, print_summary, run_batch)
from collision_sensor.tools.audit.ray_pool import require_ray
from collision_sensor.tools.audit.report import plot_batch
from collision_sensor.tools.audit.unit_check import (
    UNIT_THREADS, CheckOptions, RobotSpec, read_unit, with_demo_arm_hint)
from collision_sensor.tools.audit.units import find_units
from collision_sensor.tools.command_line import run_command
# FrameResult and pair_spans are the command's frame answers, imported from here by its users.
from collision_sensor.tools.frame_check import (  # noqa: F401
    FrameResult, json_line, motion_met, pair_spans, plot_timeline, run_sequence, summary)
from collision_sensor.tools.progress import MODES, ProgressBar
from collision_sensor.tools.recorded_clouds import CloudOptions, CloudReplay

PROG = 'collision_sensor_check'
_ENGINE = CheckerConfig()
DEFAULT_MAX_DISTANCE = 0.1
EXIT_CLEAR, EXIT_COLLISION, EXIT_ERROR = 0, 1, 2
EXIT_INTERRUPTED = 130   # as a shell reports a process stopped by SIGINT
BUNDLED_SEQUENCES = ('paper_experiment', 'into_drum_clear', 'random', 'moving_part',
                     'guard_rail_5hz')


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
                             'directory or one of its episodes (DATASET#N, as a report names '
                             'it), a directory holding any of these (searched '
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
                             'joint, with a scale and an offset or a range over the joint\'s '
                             'limits (see docs/offline.md); without it the entries must be named '
                             'as the joints, in rad or m')
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
    batch = len(units) > 1 or any(getattr(args, name) for name in BATCH_OPTIONS)
    if batch and args.json:
        raise ConfigError('--json writes one recording\'s frames; for many recordings use '
                          '--report FILE (one line per recording), or check the one the '
                          f'report names alone: {PROG} "{units[0].source}" --json FILE')
    if args.ray is not None:
        require_ray()    # before the robot loads: say at once how to install it
    spec = _robot(args)
    # Many units: this checker is the workers' too (forked), on one thread each.
    checker = spec.build(threads=UNIT_THREADS if batch else None)
    joint_map = load_joint_map(args.joint_map) if args.joint_map else None
    if joint_map is not None:
        joint_map = joint_map.for_robot(checker.joint_names, checker.joint_limits)
    if max_distance is None:
        max_distance = 0.0 if batch else DEFAULT_MAX_DISTANCE
    options = CheckOptions(incremental=not args.full, max_distance=max_distance,
                           topic=args.topic, scene_topic=args.scene_topic, joint_map=joint_map,
                           motion=args.motion, cloud_topics=cloud_topics(args),
                           clouds=cloud_options(args))
    if batch:
        return _run_batch(args, units, spec, checker, options)
    return _run_one(args, units[0], spec, checker, options)


def _run_batch(args, units, spec, checker, options: CheckOptions) -> int:
    runner = make_runner(spec, options, args.jobs, args.ray, checker)
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


def _run_one(args, unit, spec, checker, options: CheckOptions) -> int:
    """Check one recording or one dataset episode frame by frame (``--json``, ``--plot``)."""
    try:
        seq = read_unit(unit, options, checker.joint_names)
    except SequenceError as err:
        raise SequenceError(with_demo_arm_hint(str(err), spec.demo)) from None

    label = os.path.basename(os.path.normpath(seq.source))
    clouds = CloudReplay(seq, options.clouds)
    with ProgressBar(len(seq), label=label, mode=args.progress) as progress:
        results = run_sequence(checker, seq, incremental=options.incremental,
                               progress=progress, max_distance=options.max_distance,
                               scene=SceneTopic(package_paths=dict(spec.package_paths) or None),
                               motion=options.motion, clouds=clouds)

    to_stdout = args.json == '-'
    if args.json:
        stream: TextIO = sys.stdout if to_stdout else open(args.json, 'w', encoding='utf-8')
        try:
            for result in results:
                stream.write(json_line(result, options.motion, bool(seq.clouds)) + '\n')
        finally:
            if not to_stdout:
                stream.close()
    if args.plot:
        plot_timeline(results, seq, args.plot, max_distance=options.max_distance)
    print(summary(results, seq, checker, incremental=options.incremental,
                  max_distance=options.max_distance, clouds=clouds if seq.clouds else None),
          file=sys.stderr if to_stdout else sys.stdout)
    met = any(r.in_collision for r in results) or motion_met(results)
    return EXIT_COLLISION if met else EXIT_CLEAR


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the tool; return the exit status (0 clear, 1 collisions, 2 error)."""
    return run_command(PROG, build_parser(), _run, argv)


if __name__ == '__main__':
    sys.exit(main())
