"""LeRobot datasets: list their episodes and read one episode's joint positions.

A LeRobot dataset is a directory with ``meta/info.json`` (``codebase_version``, ``fps``,
``features``, ``data_path``, ``chunks_size``) and parquet files of frames, one row per frame
with ``timestamp`` (seconds from the episode's start), ``frame_index``, ``episode_index``,
``index``, ``task_index`` and one column per feature (``observation.state``: a list of
float32, one entry per motor, named by ``features[...]["names"]``). Two layouts, as LeRobot
writes them:

v2.0 / v2.1
    one parquet file per episode, at ``data_path.format(episode_chunk=i // chunks_size,
    episode_index=i)`` (``data/chunk-000/episode_000000.parquet``); the episodes and their
    lengths in ``meta/episodes.jsonl`` (``{"episode_index": 0, "tasks": [...], "length":
    N}``, one line each).
v3.0
    many episodes per parquet file, at ``data_path.format(chunk_index=c, file_index=f)``
    (``data/chunk-000/file-000.parquet``); the episodes in ``meta/episodes/chunk-*/file-*.parquet``
    (columns ``episode_index``, ``length``, ``data/chunk_index``, ``data/file_index``,
    ``dataset_from_index``, ``dataset_to_index``, ...). An episode is its rows of that file
    (LeRobot writes each episode as row groups of its own; only those are read).

Reading parquet needs pyarrow, an optional extra (``pip install 'collision_sensor[parquet]'``);
:func:`require_pyarrow` says so. The joint positions come from the state vector through a
:class:`~collision_sensor.model.joint_map.JointMap` (entries -> URDF joints, scale, offset).
Errors are :class:`~collision_sensor.errors.SequenceError` naming the dataset, the episode and
the fix.
"""
import glob
import json
import math
import os
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from collision_sensor.errors import ConfigError, SequenceError
from collision_sensor.model.joint_map import JointMap
from collision_sensor.model.sequences import JointSequence

INFO = os.path.join('meta', 'info.json')
EPISODES_V2 = os.path.join('meta', 'episodes.jsonl')
EPISODES_V3 = os.path.join('meta', 'episodes')
INSTALL_HINT = ('reading LeRobot datasets (parquet files) needs pyarrow: pip install '
                '"collision_sensor[parquet]" (or pip install pyarrow)')


@dataclass(frozen=True)
class Episode:
    """One episode of a dataset: what reading it needs, without opening the dataset again.

    :ivar root: the dataset directory.
    :ivar index: its ``episode_index``.
    :ivar length: frames, as the dataset's metadata says.
    :ivar data_file: the parquet file holding its rows, relative to ``root``.
    :ivar version: ``codebase_version`` (``v2.1``, ``v3.0``, ...).
    :ivar fps: frames per second (times when the data has no ``timestamp``).
    :ivar names: ``(feature, entry names or None)`` of the vector features in ``info.json``.
    """

    root: str
    index: int
    length: int
    data_file: str
    version: str
    fps: float
    names: Tuple[Tuple[str, Optional[Tuple[str, ...]]], ...] = ()

    @property
    def source(self) -> str:
        """``root#index``: how reports name the episode."""
        return f'{self.root}#{self.index}'

    def feature_names(self, feature: str) -> Optional[Tuple[str, ...]]:
        """Return the entry names of ``feature`` (None when info.json names none).

        :raises SequenceError: if the dataset has no such feature.
        """
        for name, entries in self.names:
            if name == feature:
                return entries
        raise SequenceError(
            f'{self.source}: the dataset has no feature "{feature}"; its vector features: '
            f'{[name for name, _ in self.names]}; set "feature:" in the joint map')


def require_pyarrow():
    """Return ``pyarrow.parquet``, or raise ConfigError saying how to install it."""
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise ConfigError(INSTALL_HINT) from None
    return pq


def is_dataset(path) -> bool:
    """Return whether ``path`` is a LeRobot dataset directory (holds ``meta/info.json``)."""
    return os.path.isfile(os.path.join(os.fspath(path), INFO))


def _entry_names(feature: dict) -> Optional[Tuple[str, ...]]:
    """The names of a 1-D feature's entries: a list, or ``{"motors": [...]}`` (v2.0)."""
    names = feature.get('names')
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and all(isinstance(name, str) for name in names):
        return tuple(names)
    return None


def read_info(root: str) -> dict:
    """Read and check ``meta/info.json``.

    :raises SequenceError: unreadable, or a layout this reader does not know.
    """
    path = os.path.join(root, INFO)
    try:
        with open(path, encoding='utf-8') as stream:
            info = json.load(stream)
    except (OSError, ValueError) as err:
        raise SequenceError(f'{path}: cannot read: {getattr(err, "strerror", None) or err}; '
                            'a LeRobot dataset needs a readable meta/info.json') from None
    version = str(info.get('codebase_version', '')) if isinstance(info, dict) else ''
    if not version.startswith(('v2.', 'v3.')):
        raise SequenceError(
            f'{path}: codebase_version "{version}" is not a layout this reader knows (v2.0, '
            'v2.1, v3.0); convert the dataset with LeRobot\'s conversion script')
    fps = info.get('fps')
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not fps > 0 \
            or not math.isfinite(fps) or not isinstance(info.get('data_path'), str) \
            or not isinstance(info.get('features'), dict):
        raise SequenceError(f'{path}: expected "fps" > 0, a "data_path" template and '
                            '"features"; is this a LeRobot dataset?')
    return info


def list_episodes(root) -> List[Episode]:
    """Return the dataset's episodes in ``episode_index`` order.

    :raises SequenceError: unreadable metadata; ConfigError without pyarrow (v3 keeps its
        episode list in parquet).
    """
    root = os.path.normpath(os.fspath(root))
    info = read_info(root)
    version = info['codebase_version']
    names = tuple((key, _entry_names(feature)) for key, feature in info['features'].items()
                  if isinstance(feature, dict) and len(feature.get('shape') or ()) == 1)
    template = info['data_path']
    if version.startswith('v2.'):
        rows = _episodes_v2(root)
        chunks_size = info.get('chunks_size') or 1000
        files = [_data_file(root, template, episode_chunk=index // chunks_size,
                            episode_index=index, total_episodes=info.get('total_episodes'))
                 for index, _ in rows]
    else:
        rows3 = _episodes_v3(root)
        rows = [(index, length) for index, length, _, _ in rows3]
        files = [_data_file(root, template, chunk_index=chunk, file_index=file)
                 for _, _, chunk, file in rows3]
    return [Episode(root, index, length, data_file, version, float(info['fps']), names)
            for (index, length), data_file in zip(rows, files)]


def _data_file(root: str, template: str, **fields) -> str:
    try:
        return template.format(**fields)
    except (KeyError, IndexError, ValueError) as err:
        raise SequenceError(f'{os.path.join(root, INFO)}: data_path "{template}" needs a field '
                            f'this reader does not know ({err}); expected LeRobot\'s '
                            'templates') from None


def _episodes_v2(root: str) -> List[Tuple[int, int]]:
    path = os.path.join(root, EPISODES_V2)
    rows = []
    try:
        with open(path, encoding='utf-8') as stream:
            for number, line in enumerate(stream, 1):
                if not line.strip():
                    continue
                try:
                    entry = json.loads(line)
                    rows.append((int(entry['episode_index']), int(entry['length'])))
                except (ValueError, KeyError, TypeError):
                    raise SequenceError(f'{path}: line {number}: expected {{"episode_index": '
                                        'N, "length": N, ...}') from None
    except OSError as err:
        raise SequenceError(f'{path}: cannot read: {err.strerror}; a v2 LeRobot dataset lists '
                            'its episodes there') from None
    return sorted(rows)


def _episodes_v3(root: str) -> List[Tuple[int, int, int, int]]:
    pq = require_pyarrow()
    files = sorted(glob.glob(os.path.join(root, EPISODES_V3, 'chunk-*', 'file-*.parquet')))
    if not files:
        raise SequenceError(f'{os.path.join(root, EPISODES_V3)}: no chunk-*/file-*.parquet; a '
                            'v3 LeRobot dataset lists its episodes there')
    columns = ['episode_index', 'length', 'data/chunk_index', 'data/file_index']
    rows = []
    for path in files:
        try:
            table = pq.read_table(path, columns=columns)
        except Exception as err:  # pyarrow raises several families for broken files
            raise SequenceError(f'{path}: cannot read the episode list: {err}') from None
        values = [table.column(name).to_pylist() for name in columns]
        rows += [tuple(int(v) for v in row) for row in zip(*values)]
    return sorted(rows)


def _state_matrix(column, where: str, feature: str) -> np.ndarray:
    """(n, K) float64 from a list or fixed-size-list column (every row K entries, no nulls)."""
    import pyarrow as pa

    array = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    if array.null_count:
        raise SequenceError(f'{where}: "{feature}" is missing in some rows; every frame needs '
                            'a state')
    if pa.types.is_fixed_size_list(array.type):
        width = array.type.list_size
    elif pa.types.is_list(array.type) or pa.types.is_large_list(array.type):
        lengths = array.value_lengths().to_numpy(zero_copy_only=False)
        width = int(lengths[0]) if len(lengths) else 0
        if np.any(lengths != width):
            row = int(np.argmax(lengths != width))
            raise SequenceError(f'{where}: row {row}: "{feature}" has {lengths[row]} entries, '
                                f'the first row {width}')
    else:
        raise SequenceError(f'{where}: "{feature}" is a {array.type} column, not a vector of '
                            'numbers')
    values = array.flatten().to_numpy(zero_copy_only=False).astype(np.float64)
    return values.reshape(len(array), width)


def read_episode(episode: Episode, joint_map: JointMap, joint_names: Sequence[str],
                 data: Union[bytes, str, None] = None) -> JointSequence:
    """Read one episode's frames as joint positions.

    :param joint_map: which state entries are which joints (:meth:`JointMap.identity` when
        the entries are named as the joints).
    :param joint_names: the robot's joints, the sequence's columns.
    :param data: the data file's bytes or the path of a copy of it (shipped to a worker that
        cannot read the dataset), or None to read ``episode.root / episode.data_file``.
    :return: the sequence, ``source`` ``root#index``; times from ``timestamp``.
    :raises SequenceError: a missing or unreadable file, missing rows, NaN values.
    """
    pq = require_pyarrow()
    import pyarrow as pa

    where = episode.source
    feature = joint_map.feature
    names = episode.feature_names(feature)
    path = os.path.join(episode.root, episode.data_file)
    try:
        parquet = pq.ParquetFile(pa.BufferReader(data) if isinstance(data, bytes) else
                                 data or path)
        schema = parquet.schema_arrow.names
        missing = [c for c in ('episode_index', feature) if c not in schema]
        if missing:
            raise SequenceError(f'{where}: {episode.data_file} has no column(s) {missing}; '
                                f'it has {schema}')
        groups = _row_groups_of(parquet, schema.index('episode_index'), episode.index)
        columns = ['episode_index', feature] + [c for c in ('timestamp',) if c in schema]
        table = parquet.read_row_groups(groups, columns=columns)
    except SequenceError:
        raise
    except FileNotFoundError:
        raise SequenceError(f'{where}: data file {episode.data_file} not found; the dataset is '
                            'incomplete (download every data file)') from None
    except Exception as err:  # pyarrow: ArrowInvalid, OSError, ... for a broken file
        raise SequenceError(f'{where}: cannot read {episode.data_file}: {err}; check the file '
                            'is a complete parquet file') from None
    rows = table.column('episode_index').to_numpy(zero_copy_only=False) == episode.index
    table = table.filter(pa.array(rows))
    if table.num_rows != episode.length:
        raise SequenceError(
            f'{where}: {episode.data_file} holds {table.num_rows} rows of the episode, its '
            f'metadata says {episode.length}; the file is truncated or rewritten')
    if table.num_rows == 0:
        raise SequenceError(f'{where}: the episode has no frames')
    state = _state_matrix(table.column(feature), where, feature)
    bad = ~np.isfinite(state)
    if bad.any():
        row, entry = (int(i) for i in np.argwhere(bad)[0])
        raise SequenceError(f'{where}: frame {row}: "{feature}" entry {entry} is '
                            f'{state[row, entry]}, not a finite number; drop or repair the '
                            'episode')
    if 'timestamp' in table.column_names:
        times = table.column('timestamp').to_numpy(zero_copy_only=False).astype(np.float64)
    else:
        times = np.arange(table.num_rows) / episode.fps
    positions = joint_map.positions(state, names, joint_names, where)
    return JointSequence(tuple(joint_names), times, positions, where)


def _row_groups_of(parquet, column: int, index: int) -> List[int]:
    """The row groups that may hold ``episode_index == index`` (by their statistics)."""
    groups = []
    for group in range(parquet.metadata.num_row_groups):
        stats = parquet.metadata.row_group(group).column(column).statistics
        if stats is None or not stats.has_min_max or stats.min <= index <= stats.max:
            groups.append(group)
    return groups
