"""The exception list: pairs of bodies that are never checked (paper sec. 4).

Three sources, merged:

* adjacent links: a link with geometry and its nearest ancestor with geometry (parent and
  child, also through links without geometry), unless ``ignore_adjacent`` is off;
* the SRDF's ``<disable_collisions>`` entries (only pairs of links with geometry matter);
* pairs from the configuration, as strings ``"link_a:link_b"`` (scene objects by name too).

Pairs are stored once, as two names in sorted order. Unknown names are an error naming them,
or, for a checker whose scene grows later, kept for an object of that name.
"""
from typing import Iterable, Mapping, Optional, Sequence, Tuple

from collision_sensor.errors import ConfigError

Pair = Tuple[str, str]


def sorted_pair(a: str, b: str) -> Pair:
    """Return the pair as ``(a, b)`` with ``a < b``."""
    return (a, b) if a < b else (b, a)


def adjacent_pairs(parents: Mapping[str, Optional[str]], with_geometry: Iterable[str]) -> set:
    """Return each link with geometry paired with its nearest ancestor that has geometry.

    :param parents: ``{link: parent link or None}`` for every link of the robot.
    :param with_geometry: the links that have collision geometry.
    """
    geometric = set(with_geometry)
    pairs = set()
    for link in geometric:
        ancestor = parents.get(link)
        while ancestor is not None and ancestor not in geometric:
            ancestor = parents.get(ancestor)
        if ancestor is not None:
            pairs.add(sorted_pair(link, ancestor))
    return pairs


def parse_pair_strings(entries: Sequence[str], known: Iterable[str],
                       what: str = 'allowed_collisions', pending: Optional[set] = None) -> set:
    """Parse ``"link_a:link_b"`` strings into sorted pairs, checking every name.

    :param entries: the strings; blank entries are skipped.
    :param known: every name the robot and scene have (links with or without geometry).
    :param what: the setting's name, for messages.
    :param pending: when given, names that are not known are added to it (objects still to
        come) instead of being an error.
    :raises ConfigError: on a malformed entry or names that are not known, naming them all.
    """
    known = set(known)
    pairs = set()
    unknown = []
    for entry in entries:
        if not str(entry).strip():
            continue
        parts = [part.strip() for part in str(entry).split(':')]
        if len(parts) != 2 or not all(parts):
            raise ConfigError(
                f'{what}: entry "{entry}" is not of the form "link_a:link_b"; write two link '
                'or scene object names separated by one colon')
        if parts[0] == parts[1]:
            raise ConfigError(f'{what}: entry "{entry}" pairs "{parts[0]}" with itself; '
                              'a body is never checked against itself, remove the entry')
        unknown.extend(name for name in parts if name not in known)
        pairs.add(sorted_pair(*parts))
    if unknown and pending is not None:
        pending.update(unknown)
    elif unknown:
        names = ', '.join(f'"{name}"' for name in sorted(set(unknown)))
        raise ConfigError(
            f'{what}: unknown link or scene object name(s) {names}; use names of the robot\'s '
            f'links or the scene\'s objects (known: {", ".join(sorted(known))})')
    return pairs
