"""Recordings sent to workers that do not share the driver's file system (a Ray cluster).

A unit's files (a CSV file, a bag's storage files and ``metadata.yaml``, an episode's parquet
file) are known by their stamp (:func:`stamp`: path, size and modification time of each): a
node that sees the same stamp reads them in place (a shared file system, or one machine). Else
they are read on the driver's machine (:func:`pack`) and their bytes travel; the worker writes
CSV and bag files into a private temporary directory (:func:`unpacked`; rosbags reads only
paths) and reads them there, an episode's parquet from memory or a copy. Messages that name
the temporary copy are rewritten to name the original path (:func:`relabel`), so a report says
the same on a cluster as on one machine.
"""
import contextlib
import os
import shutil
import tempfile
from typing import Dict, Iterator, List, Tuple, Union

from collision_sensor.tools.audit.units import Unit

Payload = Union[bytes, Dict[str, bytes]]


def _read(path: str) -> bytes:
    with open(path, 'rb') as stream:
        return stream.read()


def files(unit: Unit) -> List[str]:
    """Return the paths of the files ``unit`` reads (an episode: its data file)."""
    if unit.kind == 'lerobot':
        return [os.path.join(unit.episode.root, unit.episode.data_file)]
    if os.path.isdir(unit.path):
        return [os.path.join(unit.path, name) for name in sorted(os.listdir(unit.path))
                if os.path.isfile(os.path.join(unit.path, name))]
    return [unit.path]


def stamp(paths: List[str]) -> Tuple[Tuple[str, int, int], ...]:
    """Return ``(path, size, modification time in ns)`` of each of ``paths`` (a file that
    cannot be read: size -1)."""
    out = []
    for path in paths:
        try:
            status = os.stat(path)
            out.append((path, status.st_size, status.st_mtime_ns))
        except OSError:
            out.append((path, -1, 0))
    return tuple(out)


def sees(stamped: Tuple[Tuple[str, int, int], ...]) -> bool:
    """True iff this machine has the very files of ``stamped`` (:func:`stamp` on the
    driver's): each at its path, with its size and modification time."""
    return bool(stamped) and all(size >= 0 for _, size, _ in stamped) and \
        stamp([path for path, _, _ in stamped]) == stamped


def pack(unit: Unit) -> Payload:
    """Return the bytes of the files ``unit`` needs: ``{name: bytes}``, or an episode's parquet
    file as bytes.

    :raises OSError: a file that cannot be read (the unit fails with it).
    """
    if unit.kind == 'lerobot':
        return _read(os.path.join(unit.episode.root, unit.episode.data_file))
    if os.path.isdir(unit.path):
        return {name: _read(os.path.join(unit.path, name))
                for name in sorted(os.listdir(unit.path))
                if os.path.isfile(os.path.join(unit.path, name))}
    return {os.path.basename(unit.path): _read(unit.path)}


@contextlib.contextmanager
def unpacked(unit: Unit, files: Dict[str, bytes]) -> Iterator[str]:
    """Write ``files`` (from :func:`pack`) to a temporary directory; yield the path that stands
    for ``unit.path`` there; remove it all afterwards."""
    scratch = tempfile.mkdtemp(prefix='collision_sensor_unit_')
    try:
        base = os.path.basename(os.path.normpath(unit.path)) or 'recording'
        directory = os.path.isdir(unit.path) or len(files) > 1 or base not in files
        target = os.path.join(scratch, base)
        if directory:
            os.mkdir(target)
        for name, data in files.items():
            with open(os.path.join(target if directory else scratch,
                                   os.path.basename(name)), 'wb') as stream:
                stream.write(data)
        yield target
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def relabel(message: str, local: str, original: str) -> str:
    """Return ``message`` naming ``original`` where it named the temporary ``local``."""
    return message.replace(local, original)
