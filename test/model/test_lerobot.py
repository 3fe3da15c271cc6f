"""LeRobot datasets (v2.1 and v3.0, written as LeRobot writes them) read as joint positions
through a joint map; the errors of broken datasets; the message without pyarrow."""
import json
import math
import os
import sys

import numpy as np
import pytest

pytest.importorskip('pyarrow')

from collision_sensor.errors import ConfigError, SequenceError  # noqa: E402
from collision_sensor.model import lerobot  # noqa: E402
from collision_sensor.model.joint_map import JointMap, joint_map_from_mapping  # noqa: E402
from lerobot_writer import write_v21, write_v30  # noqa: E402

NAMES = ('shoulder_pan.pos', 'elbow.pos', 'gripper.pos')
JOINTS = ('shoulder_pan', 'elbow')
MAP = {'joints': {'shoulder_pan.pos': {'joint': 'shoulder_pan', 'scale': 'degrees'},
                  'elbow.pos': {'joint': 'elbow', 'scale': 0.01, 'offset': -0.5}}}


def _episodes(seed=3, lengths=(40, 25, 31)):
    rng = np.random.default_rng(seed)
    return [rng.uniform(-90, 90, size=(n, len(NAMES))).astype(np.float32) for n in lengths]


def _expected(states):
    """The joint positions the map gives, computed here from the float32 values."""
    values = states.astype(np.float64)
    return np.column_stack([values[:, 0] * (math.pi / 180.0), 0.01 * values[:, 1] - 0.5])


@pytest.mark.parametrize('writer, version', [(write_v21, 'v2.1'), (write_v30, 'v3.0')])
def test_every_episode_reads_back_through_the_joint_map(tmp_path, writer, version):
    episodes = _episodes()
    writer(str(tmp_path / 'ds'), NAMES, episodes, fps=30)
    listed = lerobot.list_episodes(tmp_path / 'ds')
    assert [(e.index, e.length, e.version) for e in listed] == \
        [(i, len(s), version) for i, s in enumerate(episodes)]
    joint_map = joint_map_from_mapping(MAP, 'map.yaml')
    for episode, states in zip(listed, episodes):
        seq = lerobot.read_episode(episode, joint_map, JOINTS)
        assert seq.source == f'{os.path.normpath(tmp_path / "ds")}#{episode.index}'
        assert seq.joint_names == JOINTS
        np.testing.assert_array_equal(seq.positions, _expected(states))
        np.testing.assert_array_equal(
            seq.times, (np.arange(len(states)) / 30).astype(np.float32).astype(np.float64))


def test_v3_episodes_share_files_and_only_their_rows_are_read(tmp_path):
    episodes = _episodes(lengths=(10, 20, 30, 40, 50))
    write_v30(str(tmp_path / 'ds'), NAMES, episodes, per_file=2)
    listed = lerobot.list_episodes(tmp_path / 'ds')
    assert [e.data_file for e in listed] == [
        'data/chunk-000/file-000.parquet'] * 2 + ['data/chunk-000/file-001.parquet'] * 2 + [
        'data/chunk-000/file-002.parquet']
    import pyarrow.parquet as pq
    parquet = pq.ParquetFile(tmp_path / 'ds' / listed[3].data_file)
    assert lerobot._row_groups_of(parquet, parquet.schema_arrow.names.index('episode_index'),
                                  3) == [1]      # LeRobot writes one row group per episode
    data = (tmp_path / 'ds' / listed[3].data_file).read_bytes()
    shipped = lerobot.read_episode(listed[3], joint_map_from_mapping(MAP, 'm'), JOINTS, data)
    np.testing.assert_array_equal(shipped.positions, _expected(episodes[3]))


def test_identity_map_needs_the_joints_names(tmp_path):
    write_v21(str(tmp_path / 'ds'), ('shoulder_pan', 'elbow', 'gripper'), _episodes())
    episode = lerobot.list_episodes(tmp_path / 'ds')[0]
    seq = lerobot.read_episode(episode, JointMap.identity(JOINTS), JOINTS)
    assert seq.positions.shape == (40, 2)
    with pytest.raises(SequenceError, match=r'has no entry "wrist".*give --joint-map FILE'):
        lerobot.read_episode(episode, JointMap.identity(JOINTS + ('wrist',)),
                             JOINTS + ('wrist',))


def _rewrite_info(root, **changes):
    path = root / 'meta' / 'info.json'
    info = json.loads(path.read_text())
    info.update(changes)
    path.write_text(json.dumps(info))


def test_broken_datasets_name_the_episode_and_the_fault(tmp_path):
    joint_map = joint_map_from_mapping(MAP, 'm')
    root = tmp_path / 'ds'
    episodes = _episodes()
    episodes[1][7, 1] = np.nan
    write_v21(str(root), NAMES, episodes)
    listed = lerobot.list_episodes(root)
    with pytest.raises(SequenceError, match=r'#1: frame 7: "observation.state" entry 1 is nan'):
        lerobot.read_episode(listed[1], joint_map, JOINTS)
    os.remove(root / listed[2].data_file)
    with pytest.raises(SequenceError, match=r'#2: data file .*episode_000002.parquet not found'):
        lerobot.read_episode(listed[2], joint_map, JOINTS)
    path = root / listed[0].data_file
    path.write_bytes(path.read_bytes()[:300])
    with pytest.raises(SequenceError, match=r'#0: cannot read .*complete parquet file'):
        lerobot.read_episode(listed[0], joint_map, JOINTS)
    lines = (root / 'meta' / 'episodes.jsonl').read_text().splitlines()
    (root / 'meta' / 'episodes.jsonl').write_text('\n'.join(
        [lines[0].replace('"length": 40', '"length": 41')] + lines[1:]) + '\n')
    write_v21(str(tmp_path / 'ok'), NAMES, _episodes())
    (tmp_path / 'ok' / 'meta' / 'episodes.jsonl').write_text(
        (root / 'meta' / 'episodes.jsonl').read_text())
    with pytest.raises(SequenceError, match=r'holds 40 rows of the episode, its metadata says '
                                            r'41; the file is truncated'):
        lerobot.read_episode(lerobot.list_episodes(tmp_path / 'ok')[0], joint_map, JOINTS)
    with pytest.raises(SequenceError, match=r'no feature "observation.joints"'):
        lerobot.read_episode(listed[1], joint_map_from_mapping(
            {**MAP, 'feature': 'observation.joints'}, 'm'), JOINTS)
    _rewrite_info(root, codebase_version='v1.6')
    with pytest.raises(SequenceError, match=r'codebase_version "v1.6" is not a layout'):
        lerobot.list_episodes(root)


def test_without_pyarrow_the_message_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, 'pyarrow', None)
    monkeypatch.setitem(sys.modules, 'pyarrow.parquet', None)
    with pytest.raises(ConfigError, match=r'pip install "collision_sensor\[parquet\]"'):
        lerobot.require_pyarrow()


def test_v20_names_under_motors_read_as_entry_names(tmp_path):
    """v2.0 datasets ported from older LeRobot name a vector's entries {"motors": [...]}."""
    root = tmp_path / 'ds'
    episodes = _episodes(lengths=(12,))
    write_v21(str(root), NAMES, episodes)
    info = json.loads((root / 'meta' / 'info.json').read_text())
    info['features']['observation.state']['names'] = {'motors': list(NAMES)}
    _rewrite_info(root, codebase_version='v2.0', features=info['features'])
    (episode,) = lerobot.list_episodes(root)
    assert episode.version == 'v2.0' and episode.feature_names('observation.state') == NAMES
    seq = lerobot.read_episode(episode, joint_map_from_mapping(MAP, 'm'), JOINTS)
    np.testing.assert_array_equal(seq.positions, _expected(episodes[0]))
