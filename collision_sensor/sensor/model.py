"""What the sensor core needs to know of a checker: its engine, joints, limits and pairs.

The core (``cpp/sensor_core.hpp``) answers with the checker's compiled engine directly; this
module reads, once per checker (and once per scene change that lays out a new engine), the
names and tables it answers with.
"""
import math
from typing import Dict, List, Tuple

from collision_sensor.engine.compiled import engine as compiled


def joint_limits(checker) -> Tuple[List[float], List[float]]:
    """Return each variable's ``(lower, upper)`` limits in ``checker.joint_names`` order
    (``inf`` where a side has none)."""
    lower, upper = [], []
    for name in checker.joint_names:
        lo, hi = checker.joint_limits.get(name, (-math.inf, math.inf))
        lower.append(-math.inf if lo is None or not math.isfinite(lo) else float(lo))
        upper.append(math.inf if hi is None or not math.isfinite(hi) else float(hi))
    return lower, upper


def base_defaults(checker) -> List[Tuple[int, float]]:
    """The variables of planar and floating joints (a mobile or floating base, an SRDF virtual
    joint) at their neutral values, as ``(index, value)``. Robots rarely publish them in
    joint_states (MoveIt takes them from TF): the sensor starts them at the world origin
    instead of waiting for them."""
    kinematics = checker.kinematics
    neutral = kinematics.neutral()
    multi = {int(compiled.JOINT_PLANAR), int(compiled.JOINT_FLOATING)}
    out = []
    for kind, first in zip(kinematics.joint_type, kinematics.q_index):
        if int(kind) in multi:
            count = compiled.JOINT_VARIABLES[int(kind)]
            out.extend((j, float(neutral[j])) for j in range(int(first), int(first) + count))
    return out


def pair_sides(checker) -> List[int]:
    """Return, per checked pair, 1 when the engine keeps the pair's second name as its first
    body (a scene object is always the engine's second body), else 0: which way round the
    engine's nearest points come."""
    scene = checker._scene
    return [int(scene.body_index[a] != int(body_a))
            for (a, _), body_a in zip(checker.checked_pairs, scene.pair_a)]


def model_arguments(checker) -> Dict[str, object]:
    """Return the keyword arguments of ``SensorCore.use_model`` for ``checker``."""
    lower, upper = joint_limits(checker)
    return dict(
        engine=checker._engine, joint_names=list(checker.joint_names),
        derived=sorted(checker._joints.derived), lower=lower, upper=upper,
        defaults=base_defaults(checker), motion_kinds=[int(k) for k in checker.motion_kinds],
        pairs=[tuple(pair) for pair in checker.checked_pairs], root_frame=root_link(checker),
        swapped=pair_sides(checker))


def engine_arguments(checker) -> Dict[str, object]:
    """Return the keyword arguments of ``SensorCore.set_engine`` for ``checker``'s engine."""
    return dict(engine=checker._engine,
                pairs=[tuple(pair) for pair in checker.checked_pairs],
                root_frame=root_link(checker), swapped=pair_sides(checker))


def root_link(checker) -> str:
    """Return the frame the checker's world poses are in: the robot's root link."""
    return getattr(getattr(checker, 'model', None), 'root_link', '') or ''
