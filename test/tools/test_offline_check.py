"""collision_sensor_check: per-frame answers against python-fcl on the bundled sequences, the
exit codes, JSON lines, summary, timeline plot and error lines.

The oracle (``FclCell`` of ``test_demo_cell``) reads the same files with yourdfpy, trimesh and
python-fcl and shares no code with the engine.
"""
import json
import os

import fcl
import numpy as np
import pytest
import trimesh

from collision_sensor.model.sequences import JointSequence, read_sequence
from collision_sensor.tools import frame_check, offline_check
from test_demo_cell import CONFIG, FclCell

SEQUENCES = os.path.join(CONFIG, 'sequences')
BUNDLED = ('paper_experiment', 'into_drum_clear', 'random')


@pytest.fixture(scope='module')
def oracle():
    return FclCell()


@pytest.fixture(scope='module')
def checker():
    from collision_sensor import CollisionChecker
    return CollisionChecker.from_urdf(os.path.join(CONFIG, 'demo_arm.urdf'),
                                      srdf=os.path.join(CONFIG, 'demo_arm.srdf'),
                                      scene=os.path.join(CONFIG, 'demo_scene.yaml'))


@pytest.fixture(scope='module')
def oracle_answers(oracle):
    """{sequence: [pairs per frame]} by python-fcl."""
    answers = {}
    for name in BUNDLED:
        seq = read_sequence(os.path.join(SEQUENCES, name + '.csv'),
                            joint_names=oracle.joint_names)
        answers[name] = [oracle.colliding_pairs(q) for q in seq.positions]
    return answers


def _run(capsys, argv):
    status = offline_check.main(argv)
    out, err = capsys.readouterr()
    return status, out, err


# --- the engine against the oracle -------------------------------------------------------------

def test_checked_pairs_match_the_oracles(checker, oracle):
    assert set(checker.checked_pairs) == set(oracle.pairs)


@pytest.mark.slow
@pytest.mark.parametrize('name', BUNDLED)
def test_incremental_answers_match_python_fcl_on_every_frame(checker, oracle_answers, name):
    seq = read_sequence(os.path.join(SEQUENCES, name + '.csv'), joint_names=checker.joint_names)
    results = frame_check.run_sequence(checker, seq, incremental=True)
    mismatches = [(r.index, seq.positions[r.index].tolist(), r.pairs, expected)
                  for r, expected in zip(results, oracle_answers[name]) if r.pairs != expected]
    assert not mismatches, f'{name}: (frame, q, engine, fcl) {mismatches[:3]}'
    full = frame_check.run_sequence(checker, seq, incremental=False)
    assert [r.pairs for r in full] == [r.pairs for r in results]


def test_bundled_sequences_show_what_they_claim(oracle_answers):
    in_collision = {name: sum(bool(p) for p in answers)
                    for name, answers in oracle_answers.items()}
    assert in_collision['into_drum_clear'] == 0
    assert in_collision['paper_experiment'] > 100
    assert 0 < in_collision['random'] < len(oracle_answers['random'])


# --- the command line --------------------------------------------------------------------------

def test_paper_experiment_exits_1_with_json_lines_summary_and_plot(capsys, tmp_path,
                                                                     oracle_answers):
    json_path, plot_path = tmp_path / 'frames.jsonl', tmp_path / 'contacts.png'
    status, out, err = _run(capsys, ['paper_experiment', '--json', str(json_path),
                                     '--plot', str(plot_path), '--progress', 'never'])
    assert status == 1, err
    expected = oracle_answers['paper_experiment']
    lines = [json.loads(line) for line in json_path.read_text().splitlines()]
    assert [line['index'] for line in lines] == list(range(len(expected)))
    assert all(set(line) == {'index', 'time', 'in_collision', 'pairs', 'min_distance',
                             'nearest_pair'} for line in lines)
    assert [tuple(map(tuple, line['pairs'])) for line in lines] == expected
    assert [line['in_collision'] for line in lines] == [bool(p) for p in expected]
    colliding = sum(bool(p) for p in expected)
    assert f'frames in collision: {colliding} of {len(expected)}' in out
    assert 'tool_link -- washer_drum' in out and 'first' in out and 'last' in out
    assert 'check time per frame (incremental update)' in out
    assert out.rstrip().endswith('result: COLLISION')
    assert plot_path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert all(line['min_distance'] == 0.0 for line in lines if line['in_collision'])
    assert 'closest approach while clear: ' in out


def test_into_drum_clear_exits_0(capsys):
    status, out, err = _run(capsys, [os.path.join(SEQUENCES, 'into_drum_clear.csv'),
                                     '--progress', 'never'])
    assert status == 0, err
    assert 'frames in collision: 0 of 411' in out
    assert out.rstrip().endswith('result: clear')


def test_bag_input_gives_the_csv_answers(capsys, tmp_path, oracle_answers):
    status, out, err = _run(capsys, [os.path.join(SEQUENCES, 'paper_experiment'),
                                     '--json', '-', '--progress', 'never'])
    assert status == 1, err
    lines = [json.loads(line) for line in out.splitlines()]
    assert [tuple(map(tuple, line['pairs'])) for line in lines] == \
        oracle_answers['paper_experiment']
    assert 'result: COLLISION' in err     # the summary moves to stderr


def _fcl_min_distance(oracle, q):
    """The smallest distance over the oracle's pairs (None if any collides)."""
    import fcl
    objects = oracle._objects(q, lambda body, i, bvh, mesh: (bvh, np.eye(4)))
    if oracle._hits(objects, oracle.pairs):
        return None
    return min(fcl.distance(x, y, fcl.DistanceRequest(), fcl.DistanceResult())
               for a, b in oracle.pairs for x in objects[a] for y in objects[b])


@pytest.mark.slow
def test_min_distance_per_frame_agrees_with_fcl(capsys, oracle):
    seq = read_sequence(os.path.join(SEQUENCES, 'into_drum_clear.csv'),
                        joint_names=oracle.joint_names)
    status, out, err = _run(capsys, ['into_drum_clear', '--json', '-', '--max-distance', '0.2',
                                     '--progress', 'never'])
    assert status == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    near = 0
    for line, q in list(zip(lines, seq.positions))[::8]:
        theirs = _fcl_min_distance(oracle, q)
        if theirs < 0.2 - 1e-6:
            near += 1
            assert line['min_distance'] == pytest.approx(theirs, abs=1e-6), line
            assert tuple(line['nearest_pair']) in oracle.pairs
        elif theirs > 0.2 + 1e-6:
            assert line['min_distance'] is None and line['nearest_pair'] is None
    assert near > 0
    assert 'closest approach while clear: ' in err and ' m (' in err


def test_max_distance_zero_measures_nothing_and_a_negative_one_is_refused(capsys, tmp_path):
    plot = tmp_path / 'plain.png'
    status, out, err = _run(capsys, ['random', '--max-distance', '0', '--json', '-',
                                     '--plot', str(plot), '--progress', 'never'])
    assert status in (0, 1), err
    assert all(json.loads(line)['min_distance'] is None for line in out.splitlines())
    assert 'closest approach' not in err
    status, _, err = _run(capsys, ['random', '--max-distance', '-1', '--progress', 'never'])
    assert status == 2 and '--max-distance -1.0: expected a finite distance >= 0' in err


def test_help_documents_the_exit_status(capsys):
    status, out, _ = _run(capsys, ['--help'])
    assert status == 0
    assert 'exit status: 0 no frame in collision, 1 collisions found, 2 error' in \
        ' '.join(out.split())


@pytest.mark.parametrize('argv, pattern', [
    (['missing.csv'], 'missing.csv: no such file'),
    (['random', '--package-path', 'nodir'], '--package-path "nodir": expected NAME=DIR'),
    (['random', '--urdf', 'nowhere.urdf'], 'nowhere.urdf'),
    (['random', '--config', '{config}'], 'no_such_setting'),
    (['{bad_csv}'], r"unknown joint column\(s\) \['elbw'\]"),
])
def test_errors_are_one_line_with_status_2(capsys, tmp_path, argv, pattern):
    import re
    config = tmp_path / 'config.yaml'
    config.write_text('no_such_setting: 1\n')
    bad_csv = tmp_path / 'bad.csv'
    bad_csv.write_text('time,shoulder_pan,shoulder_lift,elbw,wrist_roll,wrist_pitch,'
                       'tool_roll\n0,0,0,0,0,0,0\n')
    argv = [a.format(config=config, bad_csv=bad_csv) for a in argv]
    status, out, err = _run(capsys, argv + ['--progress', 'never'])
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('collision_sensor_check: error: '), err
    assert re.search(pattern, lines[0]), lines[0]


def test_usage_errors_exit_2(capsys):
    status, _, err = _run(capsys, ['random', '--no-such-option'])
    assert status == 2
    assert 'collision_sensor_check: error:' in err


# --- summary and spans, on hand-made answers ---------------------------------------------------

def _frames(pairs_per_frame, times):
    return [frame_check.FrameResult(i, t, bool(p), p, 0.001)
            for i, (t, p) in enumerate(zip(times, pairs_per_frame))]


def test_pair_spans_give_first_last_frames_and_duration():
    ab, ac = ('a', 'b'), ('a', 'c')
    results = _frames([(), (ab,), (ab, ac), (), (ab,)], [0.0, 0.1, 0.2, 0.3, 0.5])
    spans = {s.pair: s for s in frame_check.pair_spans(results)}
    assert (spans[ab].first, spans[ab].last, spans[ab].frames) == (0.1, 0.5, 3)
    assert spans[ab].duration == pytest.approx(0.1 + 0.1 + 0.2)   # last frame: previous gap
    assert (spans[ac].first, spans[ac].last, spans[ac].frames) == (0.2, 0.2, 1)


def test_plot_with_distances_draws_gaps_where_none_was_near(tmp_path):
    seq = JointSequence(('a',), np.array([0.0, 1.0, 2.0]), np.zeros((3, 1)), 'near.csv')
    frames = [frame_check.FrameResult(0, 0.0, False, (), 0.001, 0.05, ('a', 'b')),
              frame_check.FrameResult(1, 1.0, False, (), 0.001),
              frame_check.FrameResult(2, 2.0, True, (('a', 'b'),), 0.001, 0.0, ('a', 'b'))]
    path = tmp_path / 'near.png'
    frame_check.plot_timeline(frames, seq, str(path), max_distance=0.1)
    assert path.read_bytes()[:4] == b'\x89PNG'
    line = frame_check.distance_summary(frames, 0.0, 0.1)
    assert line == ('closest approach while clear: 0.050000 m (a -- b) at 0.000 s; 1 clear '
                    'frames with a pair within 0.1 m')


def test_plot_without_contacts_still_draws(tmp_path):
    seq = JointSequence(('a',), np.array([0.0, 1.0]), np.zeros((2, 1)), 'quiet.csv')
    path = tmp_path / 'quiet.png'
    frame_check.plot_timeline(_frames([(), ()], [0.0, 1.0]), seq, str(path))
    assert path.read_bytes()[:4] == b'\x89PNG'


# --- the dynamic scene: moving_part against python-fcl --------------------------------------

def _marker_pose(marker):
    p, o = marker.pose.position, marker.pose.orientation
    T = trimesh.transformations.quaternion_matrix((o.w, o.x, o.y, o.z))
    T[:3, 3] = (p.x, p.y, p.z)
    return T


def _fcl_scene_pairs(oracle, q, objects):
    """The colliding pairs of the robot, the scene file and ``objects`` ({name: (fcl shape,
    link or None, touch links, T)}) by python-fcl, the pairs taken from the rules of
    docs/dynamic_scene.md: each object against every link but its own and its touch links;
    attached objects against the scene file's objects and other objects; world objects never
    against each other."""
    robot = oracle._objects(q, lambda body, index, bvh, mesh: (bvh, np.eye(4)))
    poses = oracle.poses(q)
    placed = {}
    for name, (shape, link, touch, T) in objects.items():
        T_world = T if link is None else poses[link] @ T
        placed[name] = [fcl.CollisionObject(shape, fcl.Transform(T_world[:3, :3],
                                                                 T_world[:3, 3]))]
    bodies = {**robot, **placed}
    pairs = list(oracle.pairs)
    world = [body for body in robot if body not in oracle.links]
    for name, (_, link, touch, _) in objects.items():
        pairs += [tuple(sorted((name, other))) for other in oracle.links
                  if other != link and other not in touch]
        if link is not None:
            pairs += [tuple(sorted((name, other))) for other in world]
            pairs += [tuple(sorted((name, other))) for other, (_, other_link, _, _)
                      in objects.items() if other != name and other_link is None]
    return oracle._hits(bodies, sorted(set(pairs)))


def test_moving_part_replay_matches_python_fcl_on_every_frame(oracle):
    """Scene arrays replayed from the bag (crate on a conveyor, picked up, dropped; a
    fixture placed and moved) against python-fcl with the objects placed by hand here."""
    from collision_sensor import CollisionChecker
    checker = CollisionChecker.from_urdf(os.path.join(CONFIG, 'demo_arm.urdf'),
                                         srdf=os.path.join(CONFIG, 'demo_arm.srdf'),
                                         scene=os.path.join(CONFIG, 'demo_scene.yaml'))
    seq = read_sequence(os.path.join(SEQUENCES, 'moving_part'), joint_names=checker.joint_names)
    results = frame_check.run_sequence(checker, seq, incremental=True)
    objects, mismatches, attached_frames = {}, [], 0
    for index, events in enumerate(seq.scene_before()):
        for marker in (m for event in events for m in event.markers):
            name = marker.ns if marker.id == 0 else f'{marker.ns}/{marker.id}'
            if marker.action == 3:
                objects.clear()
            elif marker.action == 2:
                objects.pop(name, None)
            else:
                s = marker.scale
                shape = (fcl.Box(s.x, s.y, s.z) if marker.type == 1
                         else fcl.Cylinder(s.x / 2.0, s.z))
                objects[name] = (shape, marker.header.frame_id or None,
                                 tuple(marker.text.split()), _marker_pose(marker))
        attached_frames += any(link for _, link, _, _ in objects.values())
        expected = _fcl_scene_pairs(oracle, seq.positions[index], objects)
        if results[index].pairs != expected:
            mismatches.append((index, results[index].pairs, expected))
    assert attached_frames > 50 and any(('crate', 'washer_cabinet') == r.pairs[0]
                                        for r in results if r.pairs)
    assert not mismatches, f'(frame, engine, fcl) {mismatches[:3]} of {len(mismatches)}'


def test_a_recorded_array_the_node_would_reject_stops_the_run(capsys, tmp_path):
    from collision_sensor.model.sequences import SceneEvent, write_sequence
    seq = read_sequence(os.path.join(SEQUENCES, 'moving_part'))
    first = seq.scene[3].markers[0]
    bad = type(first)(**{**{key: getattr(first, key) for key in first.__dataclass_fields__},
                         'header': first.header, 'type': 99})
    events = seq.scene[:5] + (SceneEvent(seq.scene[5].time, (bad,)),)
    write_sequence(JointSequence(seq.joint_names, seq.times, seq.positions, '', events),
                   tmp_path / 'bad.mcap')
    status, _, err = _run(capsys, [str(tmp_path / 'bad.mcap'), '--progress', 'never'])
    assert status == 2
    assert 'marker 0 (ns "crate", id 0): ' in err and 'type 99' in err, err
    assert f'(in the scene array recorded at {seq.scene[5].time:.3f} s)' in err, err


# --- the motion between frames (--motion, issue 25) --------------------------------------------

def _guard_rail_oracle(oracle, seq):
    """python-fcl on the demo cell with the guard rail (the bag's scene array, placed here from
    the generator's constants) at each of ``states``: colliding pairs per state."""
    from scripts.demo_cell import GUARD_RAIL, GUARD_RAIL_AT
    import math
    distance, bearing, height = GUARD_RAIL_AT
    T = np.eye(4)
    T[:3, 3] = (distance * math.cos(bearing), distance * math.sin(bearing), height)
    rail = {'guard_rail': (fcl.Cylinder(GUARD_RAIL[0], GUARD_RAIL[1]), None, (), T)}
    return lambda q: _fcl_scene_pairs(oracle, q, rail)


@pytest.mark.slow
def test_the_5hz_guard_rail_sweep_is_clear_at_every_frame_and_not_between_them(capsys, tmp_path,
                                                                                 oracle):
    """The bundled sparse recording: every recorded state is clear (so the check without
    --motion says clear), the swing between two of them goes through the 1 cm rail; --motion
    finds it, at the time dense sampling of the same straight motion (confirmed by python-fcl)
    finds it first."""
    bag = os.path.join(SEQUENCES, 'guard_rail_5hz')
    status, out, _ = _run(capsys, [bag, '--progress', 'never', '--max-distance', '0'])
    assert status == 0 and 'result: clear' in out
    json_path = tmp_path / 'frames.jsonl'
    plot = tmp_path / 'timeline.png'
    status, out, _ = _run(capsys, [bag, '--motion', '--progress', 'never', '--max-distance', '0',
                                   '--json', str(json_path), '--plot', str(plot)])
    assert status == 1 and 'result: COLLISION' in out
    assert 'between two clear frames (checks of the recorded states alone miss them)' in out
    lines = [json.loads(line) for line in json_path.read_text().splitlines()]
    assert lines[0]['motion'] is None and not any(line['in_collision'] for line in lines)
    met = [line for line in lines if line['motion'] and line['motion']['first_contact'] is not None]
    assert len(met) == 1 and ['guard_rail', 'tool_link'] in met[0]['motion']['pairs']
    assert plot.stat().st_size > 0
    # The oracle: the straight motion between the two frames, sampled at 1e-4 of it.
    seq = read_sequence(bag)
    fcl_pairs = _guard_rail_oracle(oracle, seq)
    i = met[0]['index']
    a, b = seq.positions[i - 1], seq.positions[i]
    fractions = np.linspace(0.0, 1.0, 10001)
    first = next(f for f in fractions if fcl_pairs(a + f * (b - a)))
    t_first = seq.times[i - 1] + first * (seq.times[i] - seq.times[i - 1])
    t_reported = met[0]['motion']['first_contact']
    assert t_reported <= t_first + 1e-12
    assert t_reported >= seq.times[i - 1] + (first - 1e-4) * (seq.times[i] - seq.times[i - 1])
    assert not fcl_pairs(a) and not fcl_pairs(b)
    assert 'frames 8 -> 9: contact at' in out or f'frames {i - 1} -> {i}: contact at' in out


def test_motion_in_a_batch_report(capsys, tmp_path):
    """--motion in the many-recordings mode: the report's ``motion`` key per unit, the
    summary's count of motions that checks of the recorded states miss, exit status 1."""
    report = tmp_path / 'report.jsonl'
    bags = [os.path.join(SEQUENCES, 'guard_rail_5hz'), os.path.join(SEQUENCES, 'into_drum_clear.csv')]
    status, out, _ = _run(capsys, bags + ['--motion', '--report', str(report), '--jobs', '1',
                                          '--progress', 'never'])
    assert status == 1
    records = {os.path.basename(r['source'].rstrip('/')): r
               for r in map(json.loads, report.read_text().splitlines())}
    rail = records['guard_rail_5hz']['motion']
    assert rail['segments'] == records['guard_rail_5hz']['frames'] - 1
    assert rail['segments_in_contact'] == 1 and rail['missed_by_states'] == 1
    assert ['guard_rail', 'tool_link'] in rail['first_contact']['pairs']
    assert records['guard_rail_5hz']['frames_in_collision'] == 0
    clear = records['into_drum_clear.csv']['motion']
    assert clear['segments_in_contact'] == 0 and clear['first_contact'] is None
    assert 'checks of the recorded states alone miss them' in out
