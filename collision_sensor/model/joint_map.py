"""A joint map: which entry of a dataset's state vector is which URDF joint, in what units.

Robot-learning datasets (LeRobot) store one state vector per frame, ``observation.state``, whose
entries are named in ``meta/info.json`` (``"names": ["shoulder_pan.pos", ...]``) and often hold
degrees or normalised motor ticks rather than radians. A joint map, a small YAML file, says for
each entry used the URDF joint, a scale and an offset (``q = scale * value + offset``)::

    feature: observation.state        # the state feature (this is the default)
    joints:                           # entry (its name, or its index in the vector) -> joint
      shoulder_pan.pos: {joint: shoulder_pan, scale: degrees}
      shoulder_lift.pos: {joint: shoulder_lift, scale: degrees, offset: -1.5708}
      elbow_flex.pos: elbow_flex      # short form: scale 1, offset 0
      5: {joint: gripper, scale: 0.0174533}
    fixed:                            # robot joints the dataset does not hold: a constant
      panda_finger_joint1: 0.04

``scale`` is a number or ``degrees`` (pi / 180); ``offset`` is in the joint's unit (rad or m)
after scaling. Entries not named are ignored (a gripper the URDF does not model). Every movable
joint of the robot must be mapped or fixed (:meth:`JointMap.check_robot`): a joint left out
would silently stand at zero, and a collision check of a pose the robot never had says
nothing.

Without a joint map (:meth:`JointMap.identity`) the state's entry names must be the robot's
joint names, in rad or m.
"""
import math
import os
from dataclasses import dataclass
from typing import Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from collision_sensor.errors import ConfigError, SequenceError

DEFAULT_FEATURE = 'observation.state'
_SCALE_WORDS = {'degrees': math.pi / 180.0, 'deg': math.pi / 180.0}

Key = Union[str, int]


@dataclass(frozen=True)
class JointMapEntry:
    """One state entry: its name or index, the URDF joint, and ``q = scale * value + offset``."""

    key: Key
    joint: str
    scale: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class JointMap:
    """State entries to URDF joints (see the module docstring).

    :ivar feature: the dataset feature holding the state vector.
    :ivar entries: the mapped entries, in file order.
    :ivar fixed: ``{joint: value}`` for robot joints the dataset does not hold.
    :ivar source: the file it came from ('' for :meth:`identity`), for messages.
    """

    feature: str = DEFAULT_FEATURE
    entries: Tuple[JointMapEntry, ...] = ()
    fixed: Tuple[Tuple[str, float], ...] = ()
    source: str = ''

    @classmethod
    def identity(cls, joint_names: Sequence[str], feature: str = DEFAULT_FEATURE) -> 'JointMap':
        """Return the map of a dataset whose state entries are named as the robot's joints."""
        return cls(feature, tuple(JointMapEntry(name, name) for name in joint_names))

    def check_robot(self, joint_names: Sequence[str]) -> None:
        """Check that the map names only ``joint_names``, each once, and covers them all.

        :raises ConfigError: naming the joint and the fix.
        """
        where = self.source or 'joint map'
        known = set(joint_names)
        mapped = [entry.joint for entry in self.entries] + [name for name, _ in self.fixed]
        unknown = [name for name in mapped if name not in known]
        if unknown:
            raise ConfigError(f'{where}: joint(s) {unknown} are not joints of the robot; its '
                              f'joints are {list(joint_names)}')
        twice = sorted({name for name in mapped if mapped.count(name) > 1})
        if twice:
            raise ConfigError(f'{where}: joint(s) {twice} are mapped more than once; map each '
                              'joint from one state entry (or hold it under fixed:)')
        missing = [name for name in joint_names if name not in mapped]
        if missing and self.source:
            raise ConfigError(
                f'{where}: robot joint(s) {missing} are not in the joint map; map each from a '
                'state entry under joints:, or hold it at a constant under fixed: (e.g. '
                f'"fixed: {{{missing[0]}: 0.0}}")')

    def positions(self, state: np.ndarray, names: Optional[Sequence[str]],
                  joint_names: Sequence[str], where: str) -> np.ndarray:
        """Return the joint positions of every frame.

        :param state: (n, K) float, the state vectors.
        :param names: the K entry names from the dataset's ``info.json``, or None.
        :param joint_names: (J,) the robot's joints, the order of the returned columns.
        :param where: the dataset and episode, for messages.
        :return: (n, J) float64.
        :raises SequenceError: an entry the state does not have, naming the names it has.
        """
        state = np.asarray(state, dtype=np.float64)
        n, width = state.shape
        column = {name: j for j, name in enumerate(joint_names)}
        out = np.full((n, len(joint_names)), np.nan)
        for name, value in self.fixed:
            out[:, column[name]] = value
        for entry in self.entries:
            if entry.joint not in column:
                continue    # identity maps may name more than the state holds: checked below
            if isinstance(entry.key, int):
                if not 0 <= entry.key < width:
                    raise SequenceError(
                        f'{where}: state entry {entry.key} (for joint "{entry.joint}") is out of '
                        f'range: "{self.feature}" has {width} entries')
                index = entry.key
            else:
                if names is None or entry.key not in names:
                    have = list(names) if names is not None else 'no names in info.json'
                    fix = ('map entries by index' if names is None else
                           'name entries as info.json does') if self.source else \
                        'give --joint-map FILE to map state entries to the robot\'s joints'
                    raise SequenceError(
                        f'{where}: "{self.feature}" has no entry "{entry.key}" (for joint '
                        f'"{entry.joint}"); its entries: {have}; {fix}')
                index = list(names).index(entry.key)
            out[:, column[entry.joint]] = entry.scale * state[:, index] + entry.offset
        return out


def _number(value, what: str, where: str) -> float:
    if isinstance(value, str) and value.strip().lower() in _SCALE_WORDS and what == 'scale':
        return _SCALE_WORDS[value.strip().lower()]
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(float(value)):
        extra = ' or "degrees"' if what == 'scale' else ''
        raise ConfigError(f'{where}: {what} {value!r} is not a finite number{extra}')
    return float(value)


def _entry(key, value, where: str) -> JointMapEntry:
    if isinstance(key, bool) or not isinstance(key, (str, int)) or (
            isinstance(key, int) and key < 0):
        raise ConfigError(f'{where}: key {key!r} under joints: must be a state entry\'s name or '
                          'its index (0, 1, ...)')
    here = f'{where}: joints: {key}'
    if isinstance(value, str):
        return JointMapEntry(key, value)
    if not isinstance(value, Mapping) or not isinstance(value.get('joint'), str):
        raise ConfigError(f'{here}: expected a joint name, or a mapping with "joint" (and '
                          'optionally "scale", "offset"), e.g. {joint: elbow, scale: degrees}')
    extra = sorted(set(value) - {'joint', 'scale', 'offset'})
    if extra:
        raise ConfigError(f'{here}: unknown key(s) {extra}; use joint, scale, offset')
    scale = _number(value.get('scale', 1.0), 'scale', here)
    if scale == 0.0:
        raise ConfigError(f'{here}: scale 0 would hold the joint at its offset; use fixed: '
                          'for a constant joint')
    return JointMapEntry(key, value['joint'], scale, _number(value.get('offset', 0.0),
                                                             'offset', here))


def load_joint_map(path) -> JointMap:
    """Read a joint map YAML file (see the module docstring).

    :raises ConfigError: naming the file, the key and the fix.
    """
    import yaml

    path = os.fspath(path)
    try:
        with open(path, encoding='utf-8') as stream:
            document = yaml.safe_load(stream)
    except OSError as err:
        raise ConfigError(f'--joint-map {path}: cannot read: {err.strerror}') from None
    except yaml.YAMLError as err:
        raise ConfigError(f'--joint-map {path}: not valid YAML: {err}') from None
    return joint_map_from_mapping(document, path)


def joint_map_from_mapping(document, where: str) -> JointMap:
    """Build a :class:`JointMap` from a parsed YAML document (``where`` names it)."""
    if not isinstance(document, Mapping) or not isinstance(document.get('joints'), Mapping) \
            or not document['joints']:
        raise ConfigError(f'{where}: expected a mapping with "joints:" (state entry -> URDF '
                          'joint), e.g. "joints: {shoulder_pan.pos: {joint: shoulder_pan, '
                          'scale: degrees}}"')
    extra = sorted(set(document) - {'feature', 'joints', 'fixed'})
    if extra:
        raise ConfigError(f'{where}: unknown key(s) {extra}; use feature, joints, fixed')
    feature = document.get('feature', DEFAULT_FEATURE)
    if not isinstance(feature, str) or not feature:
        raise ConfigError(f'{where}: feature must be a feature name such as '
                          f'"{DEFAULT_FEATURE}"')
    entries = tuple(_entry(key, value, where) for key, value in document['joints'].items())
    fixed: Dict[str, float] = {}
    raw_fixed = document.get('fixed') or {}
    if not isinstance(raw_fixed, Mapping):
        raise ConfigError(f'{where}: fixed: must map joint names to values, e.g. '
                          '"fixed: {panda_finger_joint1: 0.04}"')
    for name, value in raw_fixed.items():
        fixed[str(name)] = _number(value, 'value', f'{where}: fixed: {name}')
    return JointMap(feature, entries, tuple(fixed.items()), where)
