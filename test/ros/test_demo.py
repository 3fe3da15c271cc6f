"""``collision_sensor_demo`` (``make demo``) as a user runs it: a subprocess from its console
script, which starts ``collision_sensor_node`` as a process of its own, in a random domain over
shared memory. Its summary must agree with ``collision_sensor_check`` on the same sequence.
"""
import json
import os
import random
import re
import subprocess
import threading
import time

import pytest

from collision_sensor.model.sequences import read_sequence
from collision_sensor.ros import demo_node_process
from collision_sensor.ros.console_scripts import console_command
from collision_sensor.tools import offline_check

pytest.importorskip('rclpy')

DEMO = console_command('collision_sensor_demo')


def run_demo(*args, timeout=300):
    env = dict(os.environ, FASTDDS_BUILTIN_TRANSPORTS='SHM',
               ROS_DOMAIN_ID=str(random.SystemRandom().randint(1, 100)))
    return subprocess.run([*DEMO, *args], capture_output=True, text=True, env=env,
                          timeout=timeout)


def offline(name, tmp_path, capsys):
    """Return the frames and pair spans ``collision_sensor_check NAME --json`` reports."""
    path = tmp_path / f'{name}.jsonl'
    offline_check.main([name, '--json', str(path), '--progress', 'never'])
    capsys.readouterr()
    frames = [json.loads(line) for line in path.read_text().splitlines()]
    results = [offline_check.FrameResult(f['index'], f['time'], f['in_collision'],
                                         tuple(tuple(p) for p in f['pairs']), 0.0)
               for f in frames]
    return frames, offline_check.pair_spans(results)


def assert_summary_lists(out, frames, spans):
    """The demo's summary has the offline check's frames in collision and pair spans."""
    n, hits = len(frames), sum(f['in_collision'] for f in frames)
    assert re.search(rf'frames in collision: {hits} of {n}\b', out), out
    for span in spans:
        name = f'{span.pair[0]} -- {span.pair[1]}'
        assert re.search(rf'{re.escape(name)}\s+first\s+{span.first - frames[0]["time"]:.3f} s'
                         rf'\s+last\s+{span.last - frames[0]["time"]:.3f} s\s+{span.frames} '
                         'frames', out), name


@pytest.mark.demo
def test_make_demo_reports_the_contacts_of_the_offline_check(tmp_path, capsys):
    run = run_demo()    # what `make demo` runs: the paper's experiment at its recorded timing
    assert run.returncode == 0, run.stdout + run.stderr
    out = run.stdout
    frames, spans = offline('paper_experiment', tmp_path, capsys)
    n = len(frames)

    assert 'robot loaded from urdf_path' in out    # the node's own log line, echoed
    # The node said it was ready (trees built, query run once) before the demo played.
    ready = out.index('node | [INFO] ready: checking /collision_sensor_demo/joint_states')
    assert out.index('robot loaded from urdf_path') < ready < out.index('node up after')
    assert 'Traceback' not in out + run.stderr
    # Contacts as they happen: each pair enters (+) as often as it leaves (-), first at its
    # first frame.
    changes = re.findall(r'^\s+(\d+\.\d+) s\s+(?:CONTACT|clear)?\s*([+-]) (\S+) -- (\S+)$',
                         out, re.MULTILINE)
    assert changes, out
    for span in spans:
        entered = [float(t) for t, sign, a, b in changes if sign == '+' and (a, b) == span.pair]
        left = [t for t, sign, a, b in changes if sign == '-' and (a, b) == span.pair]
        assert entered and len(entered) == len(left), span.pair
        assert entered[0] == pytest.approx(span.first - frames[0]['time'], abs=1e-3)
    # The summary.
    assert f'frames:              {n} played' in out and f'{n} verdicts' in out
    assert_summary_lists(out, frames, spans)
    assert re.search(r'node check time \(/diagnostics\): mean \d+\.\d+ ms', out), out
    assert 'result: COLLISION' in out


@pytest.mark.demo
def test_a_clear_sequence_played_as_fast_as_possible(tmp_path, capsys):
    run = run_demo('--sequence', 'into_drum_clear', '--as-fast-as-possible')
    assert run.returncode == 0, run.stdout + run.stderr
    frames, _ = offline('into_drum_clear', tmp_path, capsys)
    assert f'frames in collision: 0 of {len(frames)}' in run.stdout
    assert 'pairs in contact:    none' in run.stdout and 'result: clear' in run.stdout


@pytest.mark.demo
def test_the_dynamic_scene_reports_the_contacts_of_the_offline_check(tmp_path, capsys):
    """``make demo DEMO_ARGS=--dynamic``: objects come, are attached, dropped and removed
    through the node's scene topic, in order with the frames."""
    run = run_demo('--dynamic', '--as-fast-as-possible')
    assert run.returncode == 0, run.stdout + run.stderr
    out = run.stdout
    frames, spans = offline('moving_part', tmp_path, capsys)
    assert_summary_lists(out, frames, spans)
    assert {span.pair for span in spans} >= {('crate', 'tool_link'), ('crate', 'washer_cabinet')}
    for line in ('crate: attached to tool_link, may touch wrist_pitch_link',
                 'crate: dropped in the world', 'fixture: in the world',
                 '*: removed with everything from the topic'):
        assert line in out, line
    # Every array after the first frame is answered by a verdict of its own.
    seq = read_sequence(offline_check.bundled_sequence_path('moving_part'))
    after_first = sum(len(events) for events in seq.scene_before()[1:])
    assert 0 < after_first < len(seq.scene)
    assert re.search(rf'scene arrays:\s+{len(seq.scene)} published, {after_first} answered by '
                     'a verdict at once', out), out


@pytest.mark.demo
def test_a_node_that_does_not_come_up_in_time_is_a_clear_error():
    run = run_demo('--timeout', '0.01')
    assert run.returncode == 1, run.stdout + run.stderr
    assert re.search(r'collision_sensor_demo: error: collision_sensor_node did not subscribe '
                     r'to /collision_sensor_demo/joint_states within 0\.01 s \(--timeout\)',
                     run.stderr)
    assert 'Traceback' not in run.stdout + run.stderr


class FakeNode:
    """A node process that becomes ready, or exits, after some seconds."""

    def __init__(self, ready_after=None, exit_after=None, status=1):
        self.ready = threading.Event()
        self._started = time.monotonic()
        self._ready_after, self._exit_after, self._status = ready_after, exit_after, status
        if ready_after is not None:
            threading.Timer(ready_after, self.ready.set).start()

    def exited(self):
        if self._exit_after is not None and time.monotonic() - self._started > self._exit_after:
            return self._status
        return None


class Matched:
    def get_subscription_count(self):
        return 1

    def get_publisher_count(self):
        return 1

    topic_name = '/demo/joint_states'


def test_a_slow_start_is_waited_for_with_progress_lines():
    said = []
    seconds = demo_node_process.wait_until_ready(FakeNode(ready_after=2.0), Matched(), Matched(), None,
                                    said.append, progress_period=0.1)
    assert seconds >= 2.0 and len(said) >= 2
    assert all(line.startswith('still waiting for collision_sensor_node to be ready')
               for line in said)


def test_a_node_that_exits_while_starting_is_a_clear_error():
    with pytest.raises(demo_node_process.DemoError, match='exited with status 1 before it was ready'):
        demo_node_process.wait_until_ready(FakeNode(exit_after=0.1), Matched(), Matched(), None,
                              lambda line: None)


@pytest.mark.demo
def test_a_bad_sequence_fails_before_ros_starts(tmp_path):
    run = run_demo('--sequence', str(tmp_path / 'missing.csv'))
    assert run.returncode == 2
    assert run.stderr.startswith('collision_sensor_demo: error: ') and 'missing.csv' in run.stderr
    assert 'starting collision_sensor_node' not in run.stdout


@pytest.mark.demo
def test_the_motion_demo_shows_what_instant_checks_miss(tmp_path, capsys):
    """``make demo DEMO_ARGS=--motion``: every frame of guard_rail_5hz is clear, the node
    with check_motion reports the motion through the guard rail, as the offline checker's
    ``--motion`` does (each frame side by side: the instant, then the motion into it)."""
    run = run_demo('--motion', '--as-fast-as-possible')
    assert run.returncode == 0, run.stdout + run.stderr
    out = run.stdout
    path = tmp_path / 'motion.jsonl'
    offline_check.main(['guard_rail_5hz', '--motion', '--json', str(path), '--progress',
                        'never'])
    capsys.readouterr()
    frames = [json.loads(line) for line in path.read_text().splitlines()]
    rows = re.findall(r'^\s+(\d+\.\d+) s  (clear|CONTACT[^\n]*?)\s{2,}(clear|CONTACT[^\n]*)$',
                      out, re.MULTILINE)
    assert len(rows) == len(frames), out
    t0 = frames[0]['time']
    missed = []
    for (t, instant, motion), frame in zip(rows, frames):
        assert float(t) == pytest.approx(frame['time'] - t0, abs=1e-3)
        assert instant == 'clear' and not frame['in_collision']
        met = (frame['motion'] or {}).get('pairs', [])   # none into the first frame
        assert (motion != 'clear') == bool(met), (t, motion, frame)
        for a, b in met:
            assert f'{a} -- {b}' in motion
            missed.append(frame['index'])
    assert missed, 'the recording should hold a motion through the guard rail'
    assert (f'meeting contact on the way: {len(missed)}, of which between two clear frames: '
            f'{len(missed)}') in out
    for index in missed:
        assert f'frames {index - 1} -> {index}: ' in out
    assert 'result: COLLISION (on the way only)' in out


@pytest.mark.demo
def test_the_camera_demo_sees_the_person_and_keeps_the_arm_out_of_its_cloud():
    """``make demo DEMO_ARGS=--camera``: a camera on a link of the arm renders the cell with a
    person in no scene file; the node reports contact with the cloud when the arm reaches the
    person, never while the arm is away. Oracle: python-fcl's distance from each link to the
    person at every frame (yourdfpy's poses of the URDF's meshes)."""
    import math

    import fcl
    import numpy as np
    import trimesh
    import yourdfpy

    from collision_sensor.model.share import config_path, share_directory
    from collision_sensor.tools.demo_camera import CLOUD_TOPIC
    from scripts import demo_cell

    run = run_demo('--camera', '--as-fast-as-possible')
    assert run.returncode == 0, run.stdout + run.stderr
    out = run.stdout
    assert 'Traceback' not in out + run.stderr and 'no verdict within' not in out
    source = f'cloud/{CLOUD_TOPIC}'

    # The oracle: each link's distance to the person at every frame.
    robot = yourdfpy.URDF.load(config_path('demo_arm.urdf'), load_meshes=False,
                               build_collision_scene_graph=False,
                               filename_handler=lambda uri: os.path.join(
                                   share_directory(), uri[len('package://collision_sensor/'):]))
    models = {}
    for link in robot.robot.links:
        for collision in link.collisions:
            mesh = trimesh.load(robot._filename_handler(collision.geometry.mesh.filename),
                                force='mesh')
            model = fcl.BVHModel()
            model.beginModel(len(mesh.vertices), len(mesh.faces))
            model.addSubModel(np.asarray(mesh.vertices, dtype=np.float64),
                              np.asarray(mesh.faces, dtype=np.int32))
            model.endModel()
            models[link.name] = model
    radius, height = demo_cell.PERSON
    T = demo_cell.person_pose()
    person = fcl.CollisionObject(fcl.Cylinder(radius, height), fcl.Transform(T[:3, :3], T[:3, 3]))
    seq = demo_cell.person_in_path()

    def distances(q):
        robot.update_cfg(dict(zip(seq.joint_names, q)))
        out = {}
        for link, model in models.items():
            P = robot.get_transform(link)
            obj = fcl.CollisionObject(model, fcl.Transform(P[:3, :3], P[:3, 3]))
            hit = fcl.collide(obj, person, fcl.CollisionRequest(), fcl.CollisionResult())
            out[link] = 0.0 if hit else fcl.distance(obj, person, fcl.DistanceRequest(),
                                                     fcl.DistanceResult())
        return out
    truth = [distances(q) for q in seq.positions]

    # What the node reported, frame by frame: every set of pairs it reported at the frame's
    # state (the frame's verdict, then the verdicts on the clouds sent after it). Each change
    # starts with a line saying whose verdict it is.
    groups = []     # (time, 'frame' or 'cloud', [(sign, pair)])
    for t, sign, a, b, by in re.findall(r'^\s+(\d+\.\d+) s\s+(?:CONTACT|clear)?\s*([+-]) '
                                        r'(\S+) -- (\S+)(?:\s+\((frame|cloud)[^)]*\))?$',
                                        out, re.MULTILINE):
        if by:
            groups.append((float(t), by, []))
        assert groups and groups[-1][0] == float(t), out
        groups[-1][2].append((sign, (a, b)))
    assert groups, out
    reported, current, k = [], set(), 0
    for t in seq.times - seq.times[0]:
        sets = []
        if not (k < len(groups) and abs(groups[k][0] - t) < 5e-4 and groups[k][1] == 'frame'):
            sets.append(set(current))       # the frame's verdict changed nothing
        while k < len(groups) and groups[k][0] <= t + 5e-4:
            for sign, pair in groups[k][2]:
                (current.add if sign == '+' else current.discard)(pair)
            sets.append(set(current))
            k += 1
        reported.append(set().union(*sets))
    assert k == len(groups)
    diagonal = math.sqrt(3.0) * 0.02       # a voxel's reach beyond its points
    cloud_links = [{a if b == source else b for a, b in pairs if source in (a, b)}
                   for pairs in reported]
    # Every link in contact with the cloud is within a voxel's diagonal of the person: the
    # cloud's voxels are the person's (the arm keeps 7 cm from the washer throughout).
    for links, distance, t in zip(cloud_links, truth, seq.times):
        for link in links:
            assert distance[link] <= diagonal + 1e-3, (t, link, distance[link])
    # Away from the person, no contact at all (the arm's own points never reach the node).
    away = [i for i, d in enumerate(truth) if min(d.values()) > diagonal + 1e-3]
    assert len(away) > 300 and not any(reported[i] for i in away)
    # In the person: the sensor says so.
    inside = [i for i, d in enumerate(truth) if min(d.values()) == 0.0]
    assert inside and sum(bool(cloud_links[i]) for i in inside) >= len(inside) // 2
    first = next(i for i, links in enumerate(cloud_links) if links)
    assert min(truth[first].values()) <= diagonal
    # Only the cloud is ever in contact (the scene file does not hold the person).
    assert all(source in pair for pairs in reported for pair in pairs)

    # The summary.
    clouds = re.search(r'clouds:\s+(\d+) rendered by ray casting .* sent, (\d+) answered by a '
                       r'verdict at once', out)
    assert clouds and clouds.group(1) == clouds.group(2) and int(clouds.group(1)) > 100, out
    assert re.search(rf'first contact with the cloud: {seq.times[first] - seq.times[0]:.3f} s '
                     rf'\((?:a frame|cloud \d+)\'s verdict\), {re.escape(source)} -- \w+', out)
    assert re.search(r'from the person: \d+ frame and \d+ cloud verdicts, 0 of them with contact '
                     r'with the cloud: the self-filter kept the arm\'s own points out', out), out
    assert re.search(r'the node\'s filter \(/diagnostics, .*: \d+ points in, \d+ NaN, '
                     r'[1-9]\d* self-filtered', out), out
    assert 'result: COLLISION (with the camera\'s cloud only' in out
