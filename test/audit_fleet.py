"""A fleet of recordings for the audit's tests, and what python-fcl says each report line holds.

The demo cell's bundled paths, written as every format the audit reads: CSV, bare mcap and
sqlite3 files, a bag directory with scene changes (``moving_part``), LeRobot v2.1 and v3.0
datasets (degrees, an offset, and a gripper entry the URDF lacks, through a joint map), plus
broken units (a truncated bag, a CSV of another robot's joints, a CSV with a NaN row).
"""
import math
import os
import shutil

import numpy as np

from collision_sensor.model.sequences import JointSequence, read_sequence, write_sequence
from test_demo_cell import CONFIG

SEQUENCES = os.path.join(CONFIG, 'sequences')
JOINTS = ('shoulder_pan', 'shoulder_lift', 'elbow', 'wrist_roll', 'wrist_pitch', 'tool_roll')
STATE_NAMES = tuple(f'{name}.pos' for name in JOINTS) + ('gripper.pos',)
OFFSET = 0.25   # rad, on elbow: the map adds it, the dataset holds degrees without it
JOINT_MAP = ('joints:\n' + ''.join(
    f'  {name}.pos: {{joint: {name}, scale: degrees'
    + (f', offset: {OFFSET}' if name == 'elbow' else '') + '}\n' for name in JOINTS))


def bundled(name: str) -> JointSequence:
    return read_sequence(os.path.join(SEQUENCES, name + '.csv'), joint_names=JOINTS)


def dataset_states(seq: JointSequence) -> np.ndarray:
    """(n, 7) float32: each joint in degrees (elbow without the offset), then a gripper."""
    degrees = np.degrees(seq.positions.copy())
    degrees[:, JOINTS.index('elbow')] = np.degrees(seq.positions[:, 2] - OFFSET)
    return np.column_stack([degrees, np.full(len(seq), 12.5)]).astype(np.float32)


def dataset_positions(states: np.ndarray) -> np.ndarray:
    """The joint positions the joint map gives for ``states`` (float32), computed here."""
    q = states[:, :len(JOINTS)].astype(np.float64) * (math.pi / 180.0)
    q[:, JOINTS.index('elbow')] += OFFSET
    return q


def build(root: str) -> dict:
    """Write the fleet under ``root``; return ``{source: (times, positions) or None}`` for the
    good units (None: moving_part, whose scene the oracle does not place) and the broken ones
    under ``'broken'``."""
    from lerobot_writer import write_v21, write_v30

    paper, drum, random = bundled('paper_experiment'), bundled('into_drum_clear'), \
        bundled('random')
    os.makedirs(os.path.join(root, 'a'))
    os.makedirs(os.path.join(root, 'b'))
    os.makedirs(os.path.join(root, 'bad'))
    shutil.copy(os.path.join(SEQUENCES, 'paper_experiment.csv'), os.path.join(root, 'a'))
    write_sequence(random, os.path.join(root, 'a', 'random.mcap'))
    write_sequence(drum, os.path.join(root, 'b', 'into_drum_clear.db3'))
    shutil.copytree(os.path.join(SEQUENCES, 'moving_part'), os.path.join(root, 'b', 'moving'))
    episodes = [paper.positions[::3], random.positions[::2]]
    fps = {'v21': 50, 'v3': 25}
    states = [dataset_states(JointSequence(JOINTS, np.arange(len(q)), q)) for q in episodes]
    write_v21(os.path.join(root, 'ds_v21'), STATE_NAMES, states, fps=fps['v21'])
    write_v30(os.path.join(root, 'ds_v3'), STATE_NAMES, states[::-1], fps=fps['v3'],
              per_file=1)
    with open(os.path.join(root, 'joint_map.yaml'), 'w') as stream:
        stream.write(JOINT_MAP)

    good = {os.path.join(root, 'a', 'paper_experiment.csv'): (paper.times, paper.positions),
            os.path.join(root, 'a', 'random.mcap'): (random.times, random.positions),
            os.path.join(root, 'b', 'into_drum_clear.db3'): (drum.times, drum.positions),
            os.path.join(root, 'b', 'moving'): None}
    for name, ordered in (('v21', states), ('v3', states[::-1])):
        for index, episode in enumerate(ordered):
            times = (np.arange(len(episode)) / fps[name]).astype(np.float32).astype(float)
            good[f'{os.path.join(root, "ds_" + name)}#{index}'] = (
                times, dataset_positions(episode))

    corrupt = os.path.join(root, 'bad', 'corrupt.mcap')
    write_sequence(random, corrupt)
    with open(corrupt, 'r+b') as stream:
        stream.truncate(os.path.getsize(corrupt) // 2)
    with open(os.path.join(root, 'bad', 'nan_rows.csv'), 'w') as stream:
        stream.write('time,' + ','.join(JOINTS) + '\n0,0,0,0,0,0,0\n0.1,0,0,nan,0,0,0\n')
    with open(os.path.join(root, 'bad', 'panda.csv'), 'w') as stream:
        stream.write('time,' + ','.join(f'panda_joint{i}' for i in range(1, 8)) + '\n'
                     '0,0,0,0,0,0,0,0\n')
    broken = {os.path.join(root, 'bad', 'corrupt.mcap'): 'cannot read the bag',
              os.path.join(root, 'bad', 'nan_rows.csv'): 'nan is not a finite number',
              os.path.join(root, 'bad', 'panda.csv'): 'unknown joint column(s)'}
    return {'good': good, 'broken': broken}


def expected_keys(times: np.ndarray, pairs_per_frame) -> dict:
    """The contact keys of a report line, from the oracle's pairs per frame."""
    times = np.asarray(times, dtype=np.float64)
    hit = np.array([bool(pairs) for pairs in pairs_per_frame])
    spans = {}
    for index, pairs in enumerate(pairs_per_frame):
        for pair in pairs:
            span = spans.setdefault(pair, [index, index, 0])
            span[1] = index
            span[2] += 1
    t0 = times[0]
    gaps = np.diff(times)
    durations = np.append(gaps, gaps[-1])   # each frame stands until the next
    return {'frames': len(times), 'frames_in_collision': int(hit.sum()),
            'time_in_collision': float(durations[hit].sum()),
            'pairs': [{'link_a': a, 'link_b': b, 'first': float(times[first] - t0),
                       'last': float(times[last] - t0), 'frames': frames}
                      for (a, b), (first, last, frames)
                      in sorted(spans.items(), key=lambda item: (item[1][0], item[0]))]}


def by_source(records) -> dict:
    return {record['source']: record for record in records}


def urdf_limits(path: str) -> dict:
    """``{joint: (lower, upper)}`` read straight from a URDF file's ``<limit>`` tags."""
    import xml.etree.ElementTree as ElementTree
    return {joint.get('name'): (float(joint.find('limit').get('lower')),
                                float(joint.find('limit').get('upper')))
            for joint in ElementTree.parse(path).getroot().iter('joint')
            if joint.find('limit') is not None}


#: A LeRobot arm's recording: body joints -100..100 over their range (elbow counted the other
#: way), as the joint map below says.
NORMALISED_MAP = 'joints:\n' + ''.join(
    f'  {name}.pos: {{joint: {name}, range: [{bounds}]}}\n'
    for name, bounds in ((name, '100, -100' if name == 'elbow' else '-100, 100')
                         for name in JOINTS))


def write_normalised(root: str, limits: dict) -> dict:
    """Write a v2.1 dataset of the bundled paths in -100..100 units (as LeRobot's SO-101 body
    joints) and its joint map; return ``{source: (times, positions)}``, the positions computed
    here from the float32 values and ``limits``."""
    from lerobot_writer import write_v21

    fps = 30
    episodes = [bundled('paper_experiment').positions[::4], bundled('random').positions[::3]]
    lower = np.array([limits[name][0] for name in JOINTS])
    upper = np.array([limits[name][1] for name in JOINTS])
    flip = np.array([name == 'elbow' for name in JOINTS])
    states = []
    for q in episodes:
        values = -100.0 + 200.0 * (q - lower) / (upper - lower)
        values[:, flip] *= -1.0
        states.append(np.column_stack([values, np.full(len(q), 50.0)]).astype(np.float32))
    dataset = os.path.join(root, 'normalised')
    write_v21(dataset, STATE_NAMES, states, fps=fps)
    with open(os.path.join(root, 'normalised.yaml'), 'w') as stream:
        stream.write(NORMALISED_MAP)
    out = {}
    for index, episode in enumerate(states):
        values = episode[:, :len(JOINTS)].astype(np.float64)
        values[:, flip] *= -1.0
        times = (np.arange(len(episode)) / fps).astype(np.float32).astype(float)
        out[f'{dataset}#{index}'] = (times, lower + (values + 100.0) / 200.0 * (upper - lower))
    return out
