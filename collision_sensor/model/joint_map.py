"""A joint map: which entry of a dataset's state vector is which URDF joint, in what units.

Robot-learning datasets (LeRobot) store one state vector per frame, ``observation.state``, whose
entries are named in ``meta/info.json`` (``"names": ["shoulder_pan.pos", ...]``) and often hold
degrees or normalised motor ticks rather than radians. A joint map, a small YAML file, says for
each entry used the URDF joint and how a value becomes a joint position: a scale and an offset
(``q = scale * value + offset``), or a range that maps onto the joint's URDF limits::

    feature: observation.state        # the state feature (this is the default)
    joints:                           # entry (its name, or its index in the vector) -> joint
      shoulder_pan.pos: {joint: shoulder_pan, scale: degrees}
      shoulder_lift.pos: {joint: shoulder_lift, scale: degrees, offset: -1.5708}
      elbow_flex.pos: elbow_flex      # short form: scale 1, offset 0
      wrist_flex.pos: {joint: wrist_flex, range: [-100, 100]}
      5: {joint: gripper, range: [0, 100]}
    fixed:                            # robot joints the dataset does not hold: a constant
      panda_finger_joint1: 0.04

``scale`` is a number or ``degrees`` (pi / 180); ``offset`` is in the joint's unit (rad or m)
after scaling. ``range: [a, b]`` says the value runs from ``a`` at the joint's lower URDF limit
to ``b`` at its upper one, linearly (``q = lower + (value - a) / (b - a) * (upper - lower)``;
``a > b`` for a joint that counts the other way): how LeRobot's SO-100, SO-101 and Koch arms
record body joints (-100..100 over the calibrated range) and grippers (0..100). It needs the
robot's limits, so a map with ranges is made ready for a robot by :meth:`JointMap.for_robot`;
a joint without finite limits (continuous) cannot take one.

Entries not named are ignored (a gripper the URDF does not model). Every movable joint of the
robot must be mapped or fixed (:meth:`JointMap.check_robot`): a joint left out would silently
stand at zero, and a collision check of a pose the robot never had says nothing.

Without a joint map (:meth:`JointMap.identity`) the state's entry names must be the robot's
joint names, in rad or m.
"""
import dataclasses
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
    """One state entry: its name or index, the URDF joint, and ``q = scale * value + offset``.

    ``range`` is the ``(a, b)`` of a ``range:`` entry (the values at the joint's lower and upper
    limit); its scale and offset are NaN until :meth:`JointMap.for_robot` computes them.
    """

    key: Key
    joint: str
    scale: float = 1.0
    offset: float = 0.0
    range: Optional[Tuple[float, float]] = None

    def on_limits(self, lower: float, upper: float) -> 'JointMapEntry':
        """Return this ``range:`` entry with the scale and offset that map its range onto
        ``[lower, upper]``."""
        a, b = self.range
        scale = (upper - lower) / (b - a)
        return JointMapEntry(self.key, self.joint, scale, lower - scale * a, self.range)

    def __getstate__(self):
        # An entry without a range pickles as its four fields alone: the settings digest of a
        # report (``--resume``) is a hash of the pickled options, and stays the same for it.
        state = dict(self.__dict__)
        if state['range'] is None:
            del state['range']
        return state

    def __setstate__(self, state):
        for name, value in dict({'range': None}, **state).items():
            object.__setattr__(self, name, value)


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

    def for_robot(self, joint_names: Sequence[str],
                  limits: Mapping[str, Tuple[float, float]]) -> 'JointMap':
        """Return the map checked against the robot (:meth:`check_robot`), its ``range:``
        entries mapped onto the joints' limits.

        :param limits: ``{joint: (lower, upper)}`` (rad or m; infinite for a continuous
            joint), as ``CollisionChecker.joint_limits`` gives them.
        :raises ConfigError: a range on a joint without finite limits, naming it and the fix.
        """
        self.check_robot(joint_names)
        entries = []
        for entry in self.entries:
            if entry.range is not None and entry.joint in limits:
                lower, upper = limits[entry.joint]
                if not (math.isfinite(lower) and math.isfinite(upper) and upper > lower):
                    raise ConfigError(
                        f'{self.source or "joint map"}: joints: {entry.key}: joint '
                        f'"{entry.joint}" has no finite limits in the URDF (lower {lower:g}, '
                        f'upper {upper:g}: a continuous joint), so range: cannot map onto '
                        'them; give scale: and offset: instead (e.g. {joint: '
                        f'{entry.joint}, scale: 0.0314159}} turns -100..100 into a full turn)')
                entry = entry.on_limits(lower, upper)
            entries.append(entry)
        return dataclasses.replace(self, entries=tuple(entries))

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
        unready = [entry.joint for entry in self.entries
                   if entry.range is not None and math.isnan(entry.scale)]
        if unready:
            raise ConfigError(f'{self.source}: joint(s) {unready} map a range: call '
                              'JointMap.for_robot first, which reads their limits')
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
                          'optionally "scale" and "offset", or "range"), e.g. {joint: elbow, '
                          'scale: degrees} or {joint: elbow, range: [-100, 100]}')
    extra = sorted(set(value) - {'joint', 'scale', 'offset', 'range'})
    if extra:
        raise ConfigError(f'{here}: unknown key(s) {extra}; use joint, scale, offset, range')
    if 'range' in value:
        return _range_entry(key, value, here)
    scale = _number(value.get('scale', 1.0), 'scale', here)
    if scale == 0.0:
        raise ConfigError(f'{here}: scale 0 would hold the joint at its offset; use fixed: '
                          'for a constant joint')
    return JointMapEntry(key, value['joint'], scale, _number(value.get('offset', 0.0),
                                                             'offset', here))


def _range_entry(key, value, here: str) -> JointMapEntry:
    both = sorted({'scale', 'offset'} & set(value))
    if both:
        raise ConfigError(f'{here}: range: and {", ".join(both)}: both given; a range sets the '
                          'scale and offset from the joint\'s URDF limits: give one or the other')
    bounds = value['range']
    if not isinstance(bounds, Sequence) or isinstance(bounds, str) or len(bounds) != 2:
        raise ConfigError(f'{here}: range {bounds!r}: expected two numbers [a, b], the values '
                          'at the joint\'s lower and upper limit, e.g. [-100, 100]')
    a, b = (_number(bound, 'range bound', here) for bound in bounds)
    if a == b:
        raise ConfigError(f'{here}: range [{a:g}, {b:g}] is empty; give the values at the '
                          'joint\'s lower and upper limit, e.g. [-100, 100] (or [0, 100] for a '
                          'gripper)')
    return JointMapEntry(key, value['joint'], math.nan, math.nan, (a, b))


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
