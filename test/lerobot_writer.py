"""Write LeRobot datasets as LeRobot itself writes them, for the tests (no lerobot install).

From LeRobot's sources (``lerobot/datasets``): ``info.json`` as ``create_empty_dataset_info``
fills it; every frame row carries the features then ``timestamp`` (float32), ``frame_index``,
``episode_index``, ``index``, ``task_index`` (int64), vector features as HF ``Sequence(length=K,
Value('float32'))``, that is arrow ``fixed_size_list<float>[K]``, with the ``huggingface``
schema metadata ``datasets`` adds.

- v2.1: one file per episode at ``data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}
  .parquet`` (``Dataset.to_parquet``: row groups of 1000 rows); ``meta/episodes.jsonl``,
  ``meta/tasks.jsonl``, ``meta/episodes_stats.jsonl``.
- v3.0: episodes appended to ``data/chunk-000/file-{f:03d}.parquet`` by one
  ``pq.ParquetWriter(..., compression="snappy", use_dictionary=True)`` per file, one
  ``write_table`` per episode; ``meta/episodes/chunk-000/file-000.parquet`` with
  ``episode_index``, ``tasks``, ``length``, ``data/chunk_index``, ``data/file_index``,
  ``dataset_from_index``, ``dataset_to_index``, ``meta/episodes/chunk_index``,
  ``meta/episodes/file_index`` and ``stats/...`` columns; ``meta/tasks.parquet``.
"""
import json
import os
from typing import List, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

TASK = 'pick the cube'


def _features(names: Sequence[str]) -> dict:
    k = len(names)
    return {
        'action': {'dtype': 'float32', 'shape': [k], 'names': list(names)},
        'observation.state': {'dtype': 'float32', 'shape': [k], 'names': list(names)},
        'timestamp': {'dtype': 'float32', 'shape': [1], 'names': None},
        'frame_index': {'dtype': 'int64', 'shape': [1], 'names': None},
        'episode_index': {'dtype': 'int64', 'shape': [1], 'names': None},
        'index': {'dtype': 'int64', 'shape': [1], 'names': None},
        'task_index': {'dtype': 'int64', 'shape': [1], 'names': None},
    }


def _hf_metadata(k: int) -> dict:
    vector = {'feature': {'dtype': 'float32', '_type': 'Value'}, 'length': k,
              '_type': 'Sequence'}
    scalar = {name: {'dtype': dtype, '_type': 'Value'} for name, dtype in (
        ('timestamp', 'float32'), ('frame_index', 'int64'), ('episode_index', 'int64'),
        ('index', 'int64'), ('task_index', 'int64'))}
    return {b'huggingface': json.dumps({'info': {'features': {
        'action': vector, 'observation.state': vector, **scalar}}}).encode()}


def _schema(k: int) -> pa.Schema:
    vector = pa.list_(pa.float32(), k)
    return pa.schema([('action', vector), ('observation.state', vector),
                      ('timestamp', pa.float32()), ('frame_index', pa.int64()),
                      ('episode_index', pa.int64()), ('index', pa.int64()),
                      ('task_index', pa.int64())], metadata=_hf_metadata(k))


def episode_table(states: np.ndarray, fps: int, episode: int, first_index: int) -> pa.Table:
    """The rows of one episode: ``states`` (n, K) float32, actions equal to the next state."""
    states = np.asarray(states, dtype=np.float32)
    n, k = states.shape
    actions = np.vstack([states[1:], states[-1:]])
    vector = pa.list_(pa.float32(), k)
    return pa.table({
        'action': pa.FixedSizeListArray.from_arrays(pa.array(actions.ravel()), k).cast(vector),
        'observation.state': pa.FixedSizeListArray.from_arrays(pa.array(states.ravel()), k),
        'timestamp': pa.array((np.arange(n) / fps).astype(np.float32)),
        'frame_index': pa.array(np.arange(n, dtype=np.int64)),
        'episode_index': pa.array(np.full(n, episode, dtype=np.int64)),
        'index': pa.array(np.arange(first_index, first_index + n, dtype=np.int64)),
        'task_index': pa.array(np.zeros(n, dtype=np.int64)),
    }, schema=_schema(k))


def _info(version: str, fps: int, names, episodes: List[np.ndarray], data_path: str) -> dict:
    info = {'codebase_version': version, 'robot_type': 'so101_follower',
            'total_episodes': len(episodes), 'total_frames': int(sum(map(len, episodes))),
            'total_tasks': 1}
    if version.startswith('v2'):
        info.update(total_videos=0, total_chunks=1, chunks_size=1000)
    else:
        info.update(chunks_size=1000, data_files_size_in_mb=100, video_files_size_in_mb=200)
    info.update(fps=fps, splits={'train': f'0:{len(episodes)}'}, data_path=data_path,
                video_path=None, features=_features(names))
    return info


def _write_json(path: str, data) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, 'w') as stream:
        json.dump(data, stream, indent=4, ensure_ascii=False)


def write_v21(root: str, names: Sequence[str], episodes: List[np.ndarray], fps: int = 50) -> None:
    """Write a v2.1 dataset of ``episodes`` ((n_i, K) states each)."""
    template = 'data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet'
    _write_json(os.path.join(root, 'meta', 'info.json'),
                _info('v2.1', fps, names, episodes, template))
    first = 0
    for index, states in enumerate(episodes):
        path = os.path.join(root, template.format(episode_chunk=0, episode_index=index))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        pq.write_table(episode_table(states, fps, index, first), path, row_group_size=1000)
        first += len(states)
    with open(os.path.join(root, 'meta', 'episodes.jsonl'), 'w') as stream:
        for index, states in enumerate(episodes):
            stream.write(json.dumps({'episode_index': index, 'tasks': [TASK],
                                     'length': len(states)}) + '\n')
    with open(os.path.join(root, 'meta', 'tasks.jsonl'), 'w') as stream:
        stream.write(json.dumps({'task_index': 0, 'task': TASK}) + '\n')
    with open(os.path.join(root, 'meta', 'episodes_stats.jsonl'), 'w') as stream:
        for index, states in enumerate(episodes):
            stats = {'observation.state': {'min': states.min(0).tolist(),
                                           'max': states.max(0).tolist()}}
            stream.write(json.dumps({'episode_index': index, 'stats': stats}) + '\n')


def write_v30(root: str, names: Sequence[str], episodes: List[np.ndarray], fps: int = 50,
              per_file: int = 2) -> None:
    """Write a v3.0 dataset, ``per_file`` episodes per data file."""
    template = 'data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet'
    _write_json(os.path.join(root, 'meta', 'info.json'),
                _info('v3.0', fps, names, episodes, template))
    k = len(names)
    rows, first, writer = [], 0, None
    for index, states in enumerate(episodes):
        file_index = index // per_file
        if index % per_file == 0:
            if writer is not None:
                writer.close()
            path = os.path.join(root, template.format(chunk_index=0, file_index=file_index))
            os.makedirs(os.path.dirname(path), exist_ok=True)
            writer = pq.ParquetWriter(path, schema=_schema(k), compression='snappy',
                                      use_dictionary=True)
        writer.write_table(episode_table(states, fps, index, first))
        rows.append({'episode_index': index, 'tasks': [TASK], 'length': len(states),
                     'data/chunk_index': 0, 'data/file_index': file_index,
                     'dataset_from_index': first, 'dataset_to_index': first + len(states),
                     'meta/episodes/chunk_index': 0, 'meta/episodes/file_index': 0,
                     'stats/observation.state/min': states.min(0).astype(float).tolist(),
                     'stats/observation.state/max': states.max(0).astype(float).tolist()})
        first += len(states)
    writer.close()
    path = os.path.join(root, 'meta', 'episodes', 'chunk-000', 'file-000.parquet')
    os.makedirs(os.path.dirname(path), exist_ok=True)
    pq.write_table(pa.Table.from_pylist(rows), path)
    pq.write_table(pa.table({'task_index': [0], '__index_level_0__': [TASK]}),
                   os.path.join(root, 'meta', 'tasks.parquet'))


#: LeRobot's SO-101 follower: its state entries, and the joint map that reads them onto the
#: URDF of example-robot-data (``so_arm_description/urdf/so101.urdf``): body joints -100..100
#: over the calibrated range, wrist_roll calibrated over a full turn, the gripper 0..100.
SO101_NAMES = ('shoulder_pan.pos', 'shoulder_lift.pos', 'elbow_flex.pos', 'wrist_flex.pos',
               'wrist_roll.pos', 'gripper.pos')
SO101_MAP = ('joints:\n'
             '  shoulder_pan.pos: {joint: shoulder_pan, range: [-100, 100]}\n'
             '  shoulder_lift.pos: {joint: shoulder_lift, range: [-100, 100]}\n'
             '  elbow_flex.pos: {joint: elbow_flex, range: [-100, 100]}\n'
             '  wrist_flex.pos: {joint: wrist_flex, range: [-100, 100]}\n'
             '  wrist_roll.pos: {joint: wrist_roll, scale: 0.031415926535897934}\n'
             '  gripper.pos: {joint: gripper, range: [0, 100]}\n')
#: The SO-101's rest pose (folded, as LeRobot's arms start and end an episode), in the
#: recorded units.
SO101_REST = (0.0, -95.0, 90.0, 70.0, 0.0, 1.0)


def so101_episodes(count: int, frames: int, seed: int, fps: int = 30) -> List[np.ndarray]:
    """``count`` SO-101 episodes of ``frames`` states each (float32, the recorded units of
    SO101_NAMES), as a pick-and-place records them: from the rest pose through random poses
    and back, each move a minimum-jerk profile of 1 to 2.5 s, the gripper opening and closing
    on the way."""
    rng = np.random.default_rng(seed)
    rest = np.array(SO101_REST)
    episodes = []
    for _ in range(count):
        points = [rest]
        while len(points) * 1.75 * fps < frames:
            points.append(np.array([rng.uniform(-90, 90), rng.uniform(-90, 60),
                                    rng.uniform(-80, 95), rng.uniform(-90, 90),
                                    rng.uniform(-60, 60), rng.uniform(0, 100)]))
        points.append(rest)
        path = [rest]
        for a, b in zip(points, points[1:]):
            steps = int(rng.uniform(1.0, 2.5) * fps)
            s = np.linspace(0.0, 1.0, steps + 1)[1:, None]
            path.append(a + (b - a) * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5))
        states = np.vstack(path)
        if len(states) < frames:
            states = np.vstack([states, np.repeat(rest[None], frames - len(states), axis=0)])
        episodes.append(states[:frames].astype(np.float32))
    return episodes


def so101_positions(states: np.ndarray, limits: dict) -> np.ndarray:
    """The URDF joint positions (rad) SO101_MAP gives for ``states``, computed here from the
    float32 values and ``{joint: (lower, upper)}``; columns in SO101_NAMES order."""
    values = np.asarray(states, dtype=np.float64)
    out = np.empty_like(values)
    for k, name in enumerate(SO101_NAMES):
        joint = name[:-len('.pos')]
        lower, upper = limits[joint]
        if joint == 'wrist_roll':
            out[:, k] = values[:, k] * (np.pi / 100.0)
        elif joint == 'gripper':
            out[:, k] = lower + values[:, k] / 100.0 * (upper - lower)
        else:
            out[:, k] = lower + (values[:, k] + 100.0) / 200.0 * (upper - lower)
    return out
