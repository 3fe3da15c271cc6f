"""Units of work: every recording and every dataset episode that the inputs name, once each.

An input is a file (``.csv``, ``.mcap``, ``.db3``), a rosbag2 bag directory (``metadata.yaml``),
a LeRobot dataset directory (``meta/info.json``: one unit per episode), one episode of a
dataset as a report names it (``DATASET#N``), any other directory (searched recursively for all
of these; a bag or dataset found is not searched further), or a glob (``'fleet/**/*.mcap'``,
quoted so the tool expands it, ``**`` crossing directories). Units come out sorted within each
input, inputs in the order given, each source once.
"""
import glob
import os
from dataclasses import dataclass
from typing import Callable, Iterable, List, Optional

from collision_sensor.errors import ConfigError
from collision_sensor.model import lerobot

SEQUENCE_SUFFIXES = ('.csv', '.mcap', '.db3')
_GLOB_CHARS = set('*?[')


@dataclass(frozen=True)
class Unit:
    """One recording or one episode.

    :ivar source: how the report names it: the path, or ``path#episode``.
    :ivar kind: ``csv``, ``bag`` or ``lerobot``.
    :ivar path: the file or directory (a dataset's root for an episode).
    :ivar episode: the episode, for ``lerobot``.
    """

    source: str
    kind: str
    path: str
    episode: Optional[lerobot.Episode] = None

    @property
    def format(self) -> str:
        """The file format, as the report gives it: csv, mcap, sqlite3, lerobot-v2.1, ..."""
        if self.kind == 'lerobot':
            return f'lerobot-{self.episode.version}'
        if self.kind == 'csv':
            return 'csv'
        if os.path.isdir(self.path):
            return 'sqlite3' if glob.glob(os.path.join(self.path, '*.db3')) else 'mcap'
        return 'sqlite3' if self.path.lower().endswith('.db3') else 'mcap'


def _is_bag_dir(path: str) -> bool:
    return os.path.isfile(os.path.join(path, 'metadata.yaml'))


def _file_unit(path: str) -> Unit:
    kind = 'csv' if path.lower().endswith('.csv') else 'bag'
    return Unit(path, kind, path)


def _directory_units(root: str) -> Iterable[Unit]:
    if lerobot.is_dataset(root):
        lerobot.require_pyarrow()
        for episode in lerobot.list_episodes(root):
            yield Unit(episode.source, 'lerobot', episode.root, episode)
        return
    if _is_bag_dir(root):
        yield Unit(root, 'bag', root)
        return
    try:
        entries = sorted(os.scandir(root), key=lambda entry: entry.name)
    except OSError as err:
        raise ConfigError(f'{root}: cannot list: {err.strerror}') from None
    for entry in entries:
        path = os.path.normpath(os.path.join(root, entry.name))
        if entry.is_dir():
            yield from _directory_units(path)
        elif entry.name.lower().endswith(SEQUENCE_SUFFIXES):
            yield _file_unit(path)


def _input_units(path: str) -> List[Unit]:
    if os.path.isdir(path):
        return list(_directory_units(path))
    if not path.lower().endswith(SEQUENCE_SUFFIXES):
        raise ConfigError(f'{path}: unknown recording format; give .csv, .mcap or .db3 files, '
                          'rosbag2 bag directories, LeRobot dataset directories, or '
                          'directories holding them')
    return [_file_unit(path)]


def _episode_unit(value: str) -> Optional[Unit]:
    """The unit of ``DATASET#N`` (an episode as a report names it), or None when ``value`` is
    not of that form.

    :raises ConfigError: a dataset that has no episode N, naming those it has.
    """
    root, mark, index = value.rpartition('#')
    if not mark or not index.isdigit() or not lerobot.is_dataset(root):
        return None
    lerobot.require_pyarrow()
    episodes = lerobot.list_episodes(root)
    for episode in episodes:
        if episode.index == int(index):
            return Unit(episode.source, 'lerobot', episode.root, episode)
    have = (f'episodes {episodes[0].index} to {episodes[-1].index} ({len(episodes)} in all)'
            if episodes else 'no episodes')
    raise ConfigError(f'{value}: the dataset {root} has no episode {int(index)}; it has {have}')


def find_units(inputs: Iterable[str], resolve: Callable[[str], str] = lambda value: value
               ) -> List[Unit]:
    """Return the units of ``inputs`` (see the module docstring).

    :param resolve: maps an input that is not a path to one (bundled sequence names).
    :raises ConfigError: an input that does not exist, matches nothing or holds no recording.
    """
    units, seen = [], set()
    for value in inputs:
        for unit in _value_units(resolve(value)):
            if unit.source not in seen:
                seen.add(unit.source)
                units.append(unit)
    return units


def _value_units(value: str) -> List[Unit]:
    """The units of one input (see :func:`find_units`)."""
    episode = None if os.path.exists(value) else _episode_unit(value)
    if episode is not None:
        return [episode]
    if os.path.exists(value):
        paths = [value]
    elif _GLOB_CHARS & set(value):
        paths = sorted(glob.glob(value, recursive=True))
        if not paths:
            raise ConfigError(f'{value}: no file matches this pattern')
    else:
        raise ConfigError(f'{value}: no such file or directory; check the path')
    found = []
    for path in paths:
        found += _input_units(os.path.normpath(path))
    if not found:
        raise ConfigError(f'{value}: no recordings in it (.csv, .mcap, .db3 files, rosbag2 '
                          'bag directories, LeRobot datasets)')
    return found
