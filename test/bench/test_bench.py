"""Smoke tests of ``python -m benchmarks``: it runs, writes its table and plot; no timing
checks."""
import re
import sys

import numpy as np
import pytest

from benchmark_process import run_benchmark
from benchmarks import main as bench
from benchmarks.scenario_cells import wavy_terrain
from benchmarks.scenario_scale import growth_fits

HEADERS = ('### Scenario 1: random configurations', '### Scenario 2: coherent streams',
           "### Scenario 3: the paper's experiment", '### Scenario 4: scale',
           '### Scenario 5: the parts', '### Scenario 9: the dynamic scene',
           '### Scenario 10: motion between states',
           '### Scenario 12: point clouds from a depth camera')


def _installed(module):
    import importlib.util
    return importlib.util.find_spec(module) is not None


@pytest.mark.slow
def test_quick_run_writes_every_scenario_and_a_png(tmp_path, capsys):
    """Every scenario but 13, whose quick form still loads all 69 robots twice (ours and
    pinocchio's: about a minute); its test below runs it on a few."""
    table, png = tmp_path / 'bench.md', tmp_path / 'bench.png'
    scenarios = [arg for n in bench.SCENARIOS if n != 13 for arg in ('--scenario', str(n))]
    assert bench.main(['--quick', *scenarios, '--markdown', str(table), '--plot', str(png)]) == 0
    text = table.read_text()
    for header in HEADERS:
        assert header in text, header
    assert '### Targets' in text
    assert capsys.readouterr().out.strip() == text.strip()     # printed as written
    for word in ('PASS', 'MISS'):                 # every verdict is one of the two words
        text = text.replace(f'**{word}**', '')
    if _installed('fcl') and _installed('pinocchio'):
        assert '**n/a**' not in text              # with every peer installed, all are judged
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.slow
def test_missing_peers_are_reported_not_faked(tmp_path, monkeypatch):
    pytest.importorskip('fcl')
    for module in ('fcl', 'pinocchio', 'coal'):
        monkeypatch.setitem(sys.modules, module, None)    # import raises ImportError
    table = tmp_path / 'bench.md'
    assert bench.main(['--quick', '--scenario', '3', '--scenario', '4',
                       '--markdown', str(table), '--plot', str(tmp_path / 'p.png')]) == 0
    text = table.read_text()
    assert 'not installed (fcl)' in text
    assert 'not installed (coal)' in text
    targets = text.split('### Targets')[1].split('### Scenario')[0]
    assert '| S3 paper experiment: ours <= 0.5x python-fcl per check | python-fcl not ' \
        'installed (fcl) | **n/a** |' in targets  # a target against a missing peer: not judged


def test_runs_are_merged_figure_by_figure_with_their_range():
    """--runs N: each figure the median run's with the range; other differences side by side;
    words, times, dates and names with digits untouched."""
    from benchmarks.runs import merge_line, merge_reports
    rows = ['| S1 panda_link0 at 11:10 | 0.07x (2.32 vs 1,033.5 us) | **PASS** |',
            '| S1 panda_link0 at 11:10 | 0.09x (2.41 vs 1,031.5 us) | **PASS** |',
            '| S1 panda_link0 at 11:10 | 0.08x (2.30 vs 1,033.9 us) | **PASS** |']
    assert merge_line(rows) == ('| S1 panda_link0 at 11:10 | 0.08x [0.07x-0.09x] (2.32 '
                                '[2.30-2.41] vs 1,033.5 [1,031.5-1,033.9] us) | **PASS** |')
    verdicts = [row.replace('PASS', word) for row, word in zip(rows, ('PASS', 'MISS', 'PASS'))]
    assert merge_line(verdicts).endswith('| **PASS** / **MISS** / **PASS** |')
    assert merge_line([rows[0]] * 3) == rows[0]
    reports = ['# R\n\nMachine: cpu; x.\n\n' + row + '\n' for row in rows]
    merged = merge_reports(reports)
    assert merged.startswith('# R\n\nMachine: cpu; x.\n\n**3 runs**')
    assert '0.08x [0.07x-0.09x]' in merged
    uneven = merge_reports([reports[0], reports[1] + 'more\n'])
    assert '#### Run 1' in uneven and '#### Run 2' in uneven and 'more' in uneven
    assert merge_reports(['a 1\n', 'a 2\n', 'a 3\n']).startswith('**3 runs**')


@pytest.mark.slow
def test_several_runs_make_one_report(tmp_path):
    table = tmp_path / 'bench.md'
    assert bench.main(['--quick', '--scenario', '3', '--runs', '2', '--markdown', str(table)]) == 0
    text = table.read_text()
    assert '**2 runs**' in text and text.count(HEADERS[2]) == 1


@pytest.mark.slow
def test_scenario_selection_runs_only_those(tmp_path):
    table = tmp_path / 'bench.md'
    bench.main(['--quick', '--scenario', '5', '--markdown', str(table)])
    text = table.read_text()
    assert HEADERS[4] in text
    assert not any(header in text for header in HEADERS[:4])


def test_wavy_terrain_is_a_closed_grid_of_the_requested_size():
    vertices, faces = wavy_terrain(10_000)
    assert len(faces) >= 10_000 and len(faces) < 10_500
    assert faces.min() == 0 and faces.max() == len(vertices) - 1
    areas = np.linalg.norm(np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]],
                                    vertices[faces[:, 2]] - vertices[faces[:, 0]]), axis=1)
    assert areas.min() > 0.0                      # no degenerate triangles


def test_growth_fits_tell_log_from_linear():
    n = [1e4, 1e5, 1e6]
    log = growth_fits(n, [10.0 + 3.0 * np.log10(x) for x in n])
    assert log['residual'] < 1e-9 and log['first'] == pytest.approx(log['last'])
    linear = growth_fits(n, [1e-3 * x for x in n])
    assert linear['k'] == pytest.approx(1.0) and linear['last'] > linear['first']


@pytest.mark.slow
def test_proximity_scenario_measures_both_robots_against_fcl():
    from benchmarks import scenario_proximity
    from benchmarks.scenario_settings import Settings
    section = scenario_proximity.run(Settings.for_run(quick=True, seed=3))
    rows = [line for line in section.lines if line.startswith('| panda') or
            line.startswith('| ur5')]
    assert len(rows) == 4   # the peers' table, then the warning zone's
    assert all(line.rstrip(' |').endswith('30/30') for line in rows[:2]), rows  # min distances
    assert all(line.rstrip(' |').endswith('x') for line in rows[2:]), rows
    assert len(section.verdicts) == 4 and all(v.passed is not None for v in section.verdicts)


@pytest.mark.slow
def test_the_warning_zone_walk_stays_within_the_limits_in_small_steps():
    from collision_sensor.engine.sampling import sampling_bounds
    from benchmarks.scenario_cells import robot_cell
    from benchmarks.robot_peers import stream
    from benchmarks.scenario_proximity import WALK_STEP
    panda_checker = robot_cell('panda').checker()
    lower, upper = sampling_bounds(panda_checker)

    def coherent_walk(checker, n, seed):    # as scenario 8 makes its walk
        return np.array(stream(checker, n, len(checker.joint_names), seed, step=WALK_STEP,
                               bounds=(lower, upper)))
    walk = coherent_walk(panda_checker, 500, seed=4)
    assert walk.shape == (500, len(panda_checker.joint_names))
    assert np.all(walk >= lower) and np.all(walk <= upper)
    steps = np.abs(np.diff(walk, axis=0))
    assert 0 < steps.max() <= 6 * WALK_STEP and np.all(np.ptp(walk, axis=0) > WALK_STEP)
    assert np.array_equal(walk, coherent_walk(panda_checker, 500, seed=4))


@pytest.mark.slow
def test_dynamic_scene_scenario_judges_both_targets():
    pytest.importorskip('fcl')
    from benchmarks import scenario_dynamic
    from benchmarks.scenario_settings import Settings
    section = scenario_dynamic.run(Settings.for_run(quick=True, seed=3))
    assert [v.target.split(':')[0] for v in section.verdicts] == [
        'S9 50 objects, one moving per step',
        "S9 adding a 10,000-triangle mesh <= python-fcl's BVH build"]
    assert all(v.passed is not None for v in section.verdicts)
    assert any('`update` and `check` agreed at every step' in line for line in section.lines)


@pytest.mark.slow
def test_every_robot_scenario_has_a_row_per_robot_and_agrees_with_its_peers(tmp_path):
    """Scenario 13 in its quick form on a few robots: a row per robot with a mesh (one without
    a checked pair says so), a row for the URDF neither loader reads, the robot without a
    mesh named; the distribution and every target judged; colliding pair sets equal to
    pinocchio+coal's on every configuration, and python-fcl's answer on every pose of the two
    real meshes, most of them in contact."""
    pytest.importorskip('pinocchio')
    pytest.importorskip('fcl')
    from benchmarks import scenario_everyrobot
    from benchmarks.scenario_settings import Settings
    timed = ['panda_description/panda', 'talos_data/talos_left_arm', 'ur_description/ur5_robot']
    names = timed + ['ur_description/ur3', 'human_description/human',
                     'hector_description/quadrotor_base']
    section = scenario_everyrobot.run(Settings.for_run(quick=True, seed=3), str(tmp_path),
                                      robots=names)
    rows = {line.split(' | ')[0][2:]: line.strip('| ').split(' | ') for line in section.lines
            if line.startswith('| ') and line.split(' | ')[0][2:] in names}
    assert sorted(rows) == sorted(set(names) - {'human_description/human'})
    for name in timed:
        configurations, equal = rows[name][4], rows[name][-1]
        assert equal == f'{configurations}/{configurations}', rows[name]
        assert rows[name][7].endswith('x')                   # ours / pinocchio measured
    assert rows['hector_description/quadrotor_base'][-1] == 'no pair to check'
    unloaded = rows['ur_description/ur3'][-1]
    assert 'not loaded by collision_sensor (RobotDescriptionError' in unloaded
    assert 'no <link> element' in unloaded and 'pinocchio+coal: could not load' in unloaded
    assert any('Without a collision mesh' in line and 'human_description/human (no collision '
               'element)' in line for line in section.lines)
    header = section.lines.index('| robots | min | first quartile | median | third quartile | '
                                 'max | over 0.5x | over 0.2x |')
    assert section.lines[header + 2].startswith('| 3 | ')      # the three timed robots
    assert [v.target for v in section.verdicts] == [
        'S13 every robot: `check` <= 0.5x pinocchio+coal',
        'S13 the median robot: `check` <= 0.2x pinocchio+coal',
        'S13 real meshes more than half the poses collide',
        'S13 real meshes heavy contact: `check` <= 0.5x python-fcl `collide`']
    assert all(v.passed is not None for v in section.verdicts)
    assert section.verdicts[2].passed                          # heavy contact indeed
    fcl_row = [line for line in section.lines if line.startswith('| python-fcl `collide`')]
    assert len(fcl_row) == 1 and fcl_row[0].endswith('| 500/500 |')
    split = [line.strip('| ').split(' | ') for line in section.lines
             if re.match(r'\| \d+ poses (in contact|apart) \|', line)]
    assert len(split) == 2 and sum(int(row[0].split()[0]) for row in split) == 500
    assert all(row[-1] == f'{row[0].split()[0]}/{row[0].split()[0]}' for row in split), split


def test_every_robot_scenario_enumerates_every_urdf_of_the_package():
    from benchmarks.scenario_everyrobot import every_robot_cells
    cells = every_robot_cells()
    assert len(cells) == 69 and sum(cell.srdf is not None for cell in cells) == 43
    with pytest.raises(ValueError, match='not in example-robot-data: no/such'):
        every_robot_cells(['no/such'])


@pytest.mark.slow
def test_motion_scenario_judges_every_target_and_its_oracle_finds_no_miss(tmp_path):
    """Scenario 10 in its quick form: every target judged; the correctness ones (nothing
    missed or false against sampling and python-fcl, check_path as its segments one by one,
    continuousCollide's right answers, the mesh cases fcl misses) hold; update_motion
    answered as check_motion at every step."""
    pytest.importorskip('fcl')
    pytest.importorskip('pinocchio')
    from benchmarks import scenario_motion
    from benchmarks.scenario_settings import Settings
    section = scenario_motion.run(Settings.for_run(quick=True, seed=3), str(tmp_path))
    names = [v.target.split(':')[0] for v in section.verdicts]
    assert names == ['S10 certified'] * 2 + ['S10 paths'] + ['S10 panda segments'] * 2 + [
        'S10 panda trajectory'] * 2 + ['S10 ur5 segments'] * 2 + ['S10 primitives'] * 2 + [
        'S10 panda alone', 'S10 panda cluttered', 'S10 ur5 alone', 'S10 ur5 cluttered']
    assert all(v.passed is not None for v in section.verdicts)
    missed, false, paths = section.verdicts[:3]
    primitives = section.verdicts[9]
    assert missed.passed and false.passed and paths.passed and primitives.passed, (
        missed, false, paths, primitives)
    text = '\n'.join(section.lines)
    mesh_rows = [line for line in text.splitlines() if line.startswith('| BVH box')
                 or line.startswith('| Panda hand')]
    assert len(mesh_rows) == 4 and all(row.split(' | ')[-1].startswith('contact at')
                                       for row in mesh_rows), mesh_rows
    walk_rows = [line for line in text.splitlines() if '| S8 walk' in line or '| S2 stream' in
                 line]
    assert len(walk_rows) == 16 and all('| yes |' in row for row in walk_rows), walk_rows


def test_motion_cells_segments_and_path_are_as_drawn():
    """The inputs of scenario 10: segments from clear starts, of the drawn length, within
    the bounds; discretized motions with steps of at most the step; the trajectory's steps
    0.01 to 0.03 rad, within the bounds, every motion free."""
    from benchmarks.motion_cells import (
        discretized, discretized_path, motion_cells, random_segments, smooth_path)
    cell = motion_cells(seed=5, names=['panda'])[0]
    checker = cell.checker
    assert len(checker.scene_objects) == 14
    rng = np.random.default_rng(0)
    for q0, q1 in random_segments(checker, cell.lower, cell.upper, 20, rng, 0.2, 2.0):
        assert not checker.check(q0).in_collision
        assert 0.2 <= np.linalg.norm(q1 - q0) <= 2.0
        assert np.all((cell.lower <= q1) & (q1 <= cell.upper))
        states = discretized(checker, q0, q1, 0.01)
        assert np.abs(np.diff(states, axis=0)).max() <= 0.01 + 1e-12
        np.testing.assert_allclose(states[[0, -1]], [q0, q1], atol=1e-12)
    path = smooth_path(checker, cell.lower, cell.upper, 40, rng)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.min() >= 0.01 - 1e-12 and steps.max() <= 0.03 + 1e-12
    assert np.all((cell.lower <= path) & (path <= cell.upper))
    assert checker.check_path(path).first_invalid_segment is None
    assert not checker.check_batch(discretized_path(checker, path, 1e-3)).any()


@pytest.mark.parametrize('args, line', [
    (['--rate', '200,400', '--duration', '1'], 'highest rate without drops:'),
    (['--soak', '--rate', '200', '--duration', '2', '--window', '1'], 'soak total: 2 s at 200 Hz'),
    # check_motion on a walk, every verdict against check_motion here, trajectories meanwhile
    (['--rate', '200', '--duration', '2', '--walk', '0.01', '--seed', '2', '--check-motion',
      'true', '--trajectories', '1', '--trajectory-points', '20'],
     'trajectories sent 2 answered 2'),
    # a depth camera's clouds beside the joint states: runs without, then with
    (['--rate', '200', '--duration', '1', '--clouds', '10', '--cloud-size', '64x48',
      '--cloud-renders', '4'], 'with / without'),
], ids=['rates', 'soak', 'motion', 'clouds'])
@pytest.mark.node_process
def test_node_latency_drives_the_console_script_from_another_process(args, line, tmp_path):
    """The node as a process of its own; the figures printed, the node's counters read back."""
    pytest.importorskip('rclpy')
    # cwd: not the source directory, whose package has no engine under colcon test
    run = run_benchmark('benchmarks.node_latency', *args, cwd=tmp_path, timeout=600)
    out = run.stdout + run.stderr
    assert run.returncode == 0, out
    assert line in run.stdout and 'node RSS' in run.stdout, out
    assert 'node counters: received_total' in run.stdout and 'exited with' not in out, out
    assert re.search(r'wrong\s+0\b', run.stdout) and not re.search(r'wrong\s+[1-9]', run.stdout)


@pytest.mark.slow
@pytest.mark.parametrize('robot', ['tiago_pro', 'kinova'])
def test_the_pinocchio_peer_places_the_links_where_our_kinematics_does(robot):
    """The peer's configurations must put every link where ours do, continuous joints (held by
    pinocchio as cosine and sine) included; before that was so, scaled rotations made coal
    report wheels half a metre apart in contact."""
    pytest.importorskip('pinocchio')
    from collision_sensor.engine.sampling import random_configurations
    from benchmarks.peers import PinocchioPeer
    from benchmarks.scenario_large import large_cells
    cells = [cell for cell in large_cells() if cell.name == robot]
    if not cells:
        pytest.skip(f'{robot} is not in this example-robot-data')
    cell = cells[0]
    checker = cell.checker()
    peer = PinocchioPeer(cell.urdf, cell.srdf, cell.package_paths)
    pin, model = peer.pin, peer.model
    continuous = [model.names[j] for j in range(1, model.njoints)
                  if model.joints[j].nq == 2 and model.joints[j].nv == 1]
    assert continuous                                       # the case this test is about
    for q in random_configurations(checker, 5, seed=7):
        checker.check(q)
        ours = checker.link_poses()
        pin.framesForwardKinematics(model, peer.data, peer.configuration(checker, q))
        for link in checker.model.links:
            frame = model.getFrameId(link, pin.FrameType.BODY)
            if frame < model.nframes and link in ours:
                np.testing.assert_allclose(peer.data.oMf[frame].homogeneous, ours[link],
                                           atol=1e-9, err_msg=link)


# --- the user's robot: --urdf, --srdf, --package-path -------------------------------------------

def _bench(*args, cwd):
    return run_benchmark('benchmarks', *args, cwd=cwd)


@pytest.mark.slow
def test_urdf_runs_the_robot_scenarios_on_the_users_robot_against_both_peers(erd_share,
                                                                             tmp_path):
    """As a user runs it, on the UR5 moved into a package of the user's own naming (pinocchio
    needs a folder named after the package: the bench makes one)."""
    pytest.importorskip('fcl')
    pytest.importorskip('pinocchio')
    import os
    robots = os.path.join(erd_share, 'robots', 'ur_description')
    with open(os.path.join(robots, 'urdf', 'ur5_robot.urdf')) as stream:
        text = stream.read().replace('package://example-robot-data/robots/ur_description/',
                                     'package://my_ur/')
    urdf = tmp_path / 'my_ur5.urdf'
    urdf.write_text(text)
    run = _bench('--quick', '--urdf', str(urdf), '--srdf', os.path.join(robots, 'srdf', 'ur5.srdf'),
                 '--package-path', f'my_ur={robots}', '--markdown', str(tmp_path / 'b.md'),
                 cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    out = run.stdout
    assert f'Robot: {urdf} with ' in out
    headers = re.findall(r'^### (Scenario \d)', out, re.M)
    assert headers == ['Scenario 1', 'Scenario 2', 'Scenario 8'], headers
    assert '#### ur5' in out and '#### panda' not in out and 'demo_arm' not in out
    # Both peers loaded the robot and agree with us on every configuration.
    s1 = out.split('### Scenario 1')[1].split('### Scenario 2')[0]
    for row in ('| pinocchio+coal `computeCollisions` | pinocchio | 17 (17 geometry pairs) |',
                '| python-fcl, one `collide` per pair | pinocchio (counted) | 17 |'):
        assert row in s1, s1
    assert re.findall(r'\| (\d+)/\1 \|$', s1, re.M) and not re.search(r'\| (\d+)/(?!\1)\d+ \|$',
                                                                        s1, re.M), s1
    s8 = out.split('### Scenario 8')[1]
    assert re.search(r'^\| ur5 \| 17 \|.*\| 30/30 \|$', s8, re.M), s8
    targets = out.split('### Targets')[1].split('### Scenario')[0]
    assert targets.count('| S1 ur5') == 1 and targets.count('| S8 ur5') == 2
    assert '**n/a**' not in targets, targets           # every peer measured
    assert 'could not load' not in out and 'not installed' not in out


REGEX = r'python -m benchmarks: error: '


@pytest.mark.parametrize('args, words', [
    (['--srdf', 'x.srdf'], '--srdf describe your robot: add --urdf FILE'),
    (['--urdf', 'URDF', '--scenario', '3'], '--scenario 3: with --urdf only the robot '
                                            'scenarios 1, 2 and 8 run'),
    (['--urdf', 'missing.urdf'], '--urdf "missing.urdf": file not found'),
    (['--urdf', 'URDF', '--package-path', 'nodir'], 'expected NAME=DIR'),
    (['--scenario', '10', '--motion-parts', 'BX'], '--motion-parts BX: give letters of ABCD'),
    (['--urdf', 'TYPO', '--package-path', 'ERD'], 'did you mean "package://example-robot-data/robots/ur_description/'
                         'meshes/ur5/collision/forearm.stl"'),
])
@pytest.mark.slow
def test_urdf_errors_are_one_line_naming_the_fix(erd_share, tmp_path, args, words):
    import os
    source = os.path.join(erd_share, 'robots', 'ur_description', 'urdf', 'ur5_robot.urdf')
    typo = tmp_path / 'typo.urdf'
    with open(source) as stream:
        typo.write_text(stream.read().replace('collision/forearm.stl', 'collision/forarm.stl'))
    args = [{'URDF': source, 'TYPO': str(typo), 'ERD': f'example-robot-data={erd_share}'}
            .get(arg, arg) for arg in args]
    run = _bench('--quick', *args, cwd=tmp_path)
    assert run.returncode == 2, run.stdout + run.stderr
    lines = [line for line in run.stderr.splitlines() if not line.startswith('[')]
    assert len(lines) == 1 and re.match(REGEX, lines[0]), run.stderr
    assert words in lines[0], lines[0]


@pytest.mark.slow
def test_motion_parts_run_only_the_parts_asked(tmp_path):
    """--motion-parts D: scenario 10 runs its streams part alone, on the arms' cells."""
    import dataclasses

    from benchmarks import scenario_motion
    from benchmarks.scenario_settings import Settings
    settings = dataclasses.replace(Settings.for_run(True, 1998), motion_parts=('D',))
    section = scenario_motion.run(settings, str(tmp_path))
    text = '\n'.join(section.lines)
    assert '#### D.' in text
    assert not any(f'#### {part}.' in text for part in 'ABC')
    assert {v.target.split()[1] for v in section.verdicts} == {'panda', 'ur5'}
