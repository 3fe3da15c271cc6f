"""Planned trajectories checked before they run, along the path a controller will follow.

A trajectory is what ``trajectory_msgs/JointTrajectory`` carries (joint names, then points
with ``time_from_start``, positions and optional velocities and accelerations); this module
takes it as plain values (the ROS source converts the message) and turns it into the path
``joint_trajectory_controller`` (ros2_controllers, Jazzy) executes with its default spline
interpolation::

    result = check_trajectory(checker, joint_names, points, start=checker_positions)
    result.valid, result.first_invalid_segment, result.time_from_start, result.reason

Segment 0 runs from the start state (the current joint state, at rest) to the first point,
over the first point's ``time_from_start``; segment i (i >= 1) from point i - 1 to point i.
Between two points each joint follows, as the controller's ``interpolate_between_points``:
a straight line when the two points carry positions only, a cubic (positions and velocities
at both ends) when they carry velocities, a quintic when they carry velocities and
accelerations. Segment 0 starts at rest (velocity and acceleration 0, as the controller takes
a start state without them) and a continuous joint starts from the value nearest the first
point (the controller's wrap-around). A first point at ``time_from_start`` 0 is reached by a
jump: its motion is checked as a straight line. Joints the trajectory does not name keep
their start values. Splines can leave the straight segment between two points and overshoot
joint limits: both are checked (the limits at the spline's extremes, the path certified by the
engine, ``cpp/motion.hpp``: SplinePath).
"""
import math
from typing import NamedTuple, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.engine.motion import FREE, MotionResult, PathResult
from collision_sensor.errors import JointStateError

Pair = Tuple[str, str]
#: At most this many points per trajectory (a trajectory from the ROS graph is untrusted).
MAX_POINTS = 100_000


class TrajectoryPoint(NamedTuple):
    """One point: ``time_from_start`` (s), positions (one per joint name), and optionally
    velocities and accelerations (empty, or one per joint name)."""

    time_from_start: float
    positions: Sequence[float]
    velocities: Sequence[float] = ()
    accelerations: Sequence[float] = ()


class TrajectoryResult(NamedTuple):
    """The answer of :func:`check_trajectory`.

    :ivar valid: True iff the trajectory is well formed, within the joint limits all along
        and free of contact all along.
    :ivar first_invalid_segment: the first segment not free of contact or leaving the limits
        (0: start -> point 0; i: point i - 1 -> point i); ``None`` when valid or malformed.
    :ivar time_from_start: the trajectory time (s) of the first contact or limit violation;
        ``None`` when there is none.
    :ivar colliding_pairs: the pairs in contact there (sorted ``(a, b)``), ``()`` if none.
    :ivar reason: why it is invalid, naming the joint, point or pair and the fix; ``''`` when
        valid.
    """

    valid: bool
    first_invalid_segment: Optional[int]
    time_from_start: Optional[float]
    colliding_pairs: Tuple[Pair, ...]
    reason: str


class TrajectoryError(JointStateError):
    """A trajectory that is malformed: it names the point or joint and the fix."""


def _fraction_of(start: float, duration: float, u: float) -> float:
    return float(start + u * duration)


def spline_coefficients(p0, v0, a0, p1, v1, a1, duration, kind) -> np.ndarray:
    """Return ``(..., n, 6)`` coefficients of the controller's splines from (p0, v0, a0) to
    (p1, v1, a1) over ``duration`` seconds, rescaled to t = time / duration in [0, 1]
    (``kind``: ``linear``, ``cubic`` or ``quintic``; as ros2_controllers'
    ``Trajectory::interpolate_between_points``). A zero duration is a straight jump. The ends
    are ``(..., n)`` arrays, ``duration`` and ``kind`` one per leading index (many segments at
    once) or scalars."""
    p0, v0, a0, p1, v1, a1 = (np.asarray(x, dtype=np.float64) for x in (p0, v0, a0, p1, v1, a1))
    T = np.asarray(duration, dtype=np.float64)[..., None]
    kind = np.asarray(kind)[..., None]
    linear = (kind == 'linear') | (T == 0.0)
    cubic = (kind == 'cubic') & ~linear
    quintic = ~linear & ~cubic
    T2 = T * T
    c = np.zeros(np.broadcast(p0, p1, T).shape + (6,))
    c[..., 0] = p0
    c[..., 1] = np.where(linear, p1 - p0, v0 * T)
    c[..., 2] = np.where(cubic, -3.0 * p0 + 3.0 * p1 - 2.0 * v0 * T - v1 * T,
                         np.where(quintic, 0.5 * a0 * T2, 0.0))
    c[..., 3] = np.where(cubic, 2.0 * p0 - 2.0 * p1 + v0 * T + v1 * T,
                         np.where(quintic, (-20.0 * p0 + 20.0 * p1 - 3.0 * a0 * T2 + a1 * T2
                                            - 12.0 * v0 * T - 8.0 * v1 * T) / 2.0, 0.0))
    c[..., 4] = np.where(quintic, (30.0 * p0 - 30.0 * p1 + 3.0 * a0 * T2 - 2.0 * a1 * T2
                                   + 16.0 * v0 * T + 14.0 * v1 * T) / 2.0, 0.0)
    c[..., 5] = np.where(quintic, (-12.0 * p0 + 12.0 * p1 - a0 * T2 + a1 * T2 - 6.0 * v0 * T
                                   - 6.0 * v1 * T) / 2.0, 0.0)
    return c


def polynomial_extremes(c: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(lowest, t_lowest, highest, t_highest)`` of each polynomial
    ``sum_k c[..., k] t^k`` on [0, 1] (``c``: ``(..., 6)`` coefficients, degree at most 5): the
    values at the ends and at the real roots of the derivative inside (0, 1), the roots as
    eigenvalues of the derivative's companion matrices, all polynomials of one degree at once
    (one numpy call each, not one per polynomial)."""
    c = np.asarray(c, dtype=np.float64)
    shape = c.shape[:-1]
    c = c.reshape(-1, c.shape[-1])
    n, width = c.shape
    derivative = c[:, 1:] * np.arange(1, width)                       # (n, width - 1)
    nonzero = derivative != 0.0
    degree = np.where(nonzero.any(axis=1),
                      width - 2 - np.argmax(nonzero[:, ::-1], axis=1), 0)
    candidates = np.full((n, width), np.nan)                           # ends + interior roots
    candidates[:, 0], candidates[:, 1] = 0.0, 1.0
    for d in range(1, width - 1):
        rows = np.flatnonzero(degree == d)
        if not len(rows):
            continue
        companion = np.zeros((len(rows), d, d))
        companion[:, np.arange(1, d), np.arange(d - 1)] = 1.0
        companion[:, :, -1] = -derivative[rows, :d] / derivative[rows, d:d + 1]
        roots = np.linalg.eigvals(companion[:, ::-1, ::-1])
        inside = (np.abs(roots.imag) < 1e-12) & (roots.real > 0.0) & (roots.real < 1.0)
        candidates[rows, 2:2 + d] = np.where(inside, roots.real, np.nan)
    powers = candidates[:, :, None] ** np.arange(width)                # (n, width, width)
    values = np.einsum('nck,nk->nc', np.nan_to_num(powers), c)
    values = np.where(np.isnan(candidates), np.nan, values)
    low, high = np.nanargmin(values, axis=1), np.nanargmax(values, axis=1)
    at = np.arange(n)
    return (values[at, low].reshape(shape), candidates[at, low].reshape(shape),
            values[at, high].reshape(shape), candidates[at, high].reshape(shape))


def _numbers(values, what: str, count: int) -> np.ndarray:
    try:
        array = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise TrajectoryError(f'{what}: not numbers') from None
    if len(array) not in (0, count):
        raise TrajectoryError(f'{what}: {len(array)} values for {count} joint names; give one '
                              'per joint name (or none)')
    if not np.all(np.isfinite(array)):
        raise TrajectoryError(f'{what}: {array.tolist()} holds NaN or inf; send finite values')
    return array


def _stacked(points: Sequence[TrajectoryPoint], count: int):
    """Every point's numbers at once, ``(positions, velocities, accelerations)`` as
    ``(S, count)`` arrays (zeros where a point gives none) and ``(has_v, has_a)`` per point,
    when every point gives ``count`` finite positions and velocities and accelerations alike
    (all or none); else None, and the points are read one by one, naming the first bad one."""
    try:
        P, V, A = (np.array([getattr(point, field) for point in points], dtype=np.float64)
                   for field in ('positions', 'velocities', 'accelerations'))
    except (TypeError, ValueError):
        return None
    S = len(points)
    if (P.shape != (S, count) or V.ndim != 2 or A.ndim != 2 or V.shape[1] not in (0, count)
            or A.shape[1] not in (0, count) or (A.shape[1] and not V.shape[1])):
        return None
    if not (np.isfinite(P).all() and np.isfinite(V).all() and np.isfinite(A).all()):
        return None
    has_v, has_a = np.full(S, V.shape[1] > 0), np.full(S, A.shape[1] > 0)
    return (P, V if V.shape[1] else np.zeros((S, count)),
            A if A.shape[1] else np.zeros((S, count)), has_v, has_a)


def build_segments(checker, joint_names: Sequence[str], points: Sequence[TrajectoryPoint],
                   start: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Return the controller's path: ``coef (S, J, 6)`` (``J``: the checker's variables; one
    segment per point, see the module) and ``times (S + 1,)``, the segments' start and end
    times (s).

    :raises TrajectoryError: on a malformed trajectory, naming the point or joint and the fix.
    """
    names = list(joint_names)
    if not points:
        raise TrajectoryError('the trajectory has no points; send at least one')
    if len(points) > MAX_POINTS:
        raise TrajectoryError(f'the trajectory has {len(points)} points, more than '
                              f'{MAX_POINTS}; split it')
    if not names:
        raise TrajectoryError('the trajectory names no joints')
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise TrajectoryError(f'joint name(s) {", ".join(twice)} given twice; name each once')
    index = checker._joints.index
    unknown = [n for n in names if n not in index]
    if unknown:
        mimic = [n for n in unknown if n in checker._joints.derived]
        why = (f' ({", ".join(mimic)}: mimic joints follow their source; leave them out)'
               if mimic else '')
        raise TrajectoryError(
            f'unknown joint name(s) {", ".join(map(str, unknown))}{why}; the robot\'s joints '
            f'are {", ".join(checker.joint_names)}')
    columns = [index[n] for n in names]
    J, K = len(checker.joint_names), len(names)
    stacked = _stacked(points, K)
    times = [0.0]
    states = []
    for i, point in enumerate(points):
        where = f'point {i}'
        t = float(point.time_from_start)
        if not math.isfinite(t) or t < 0.0:
            raise TrajectoryError(f'{where}: time_from_start {t} is not a finite time >= 0')
        if i > 0 and not t > times[-1]:
            raise TrajectoryError(
                f'{where}: time_from_start {t} s does not increase (point {i - 1} is at '
                f'{times[-1]} s); make time_from_start strictly increasing')
        times.append(t)
        if stacked is not None:
            continue
        positions = _numbers(point.positions, f'{where} positions', K)
        if len(positions) == 0:
            raise TrajectoryError(f'{where}: no positions; every point needs positions '
                                  '(velocity-only points are not checked)')
        velocities = _numbers(point.velocities, f'{where} velocities', K)
        accelerations = _numbers(point.accelerations, f'{where} accelerations', K)
        if len(accelerations) and not len(velocities):
            raise TrajectoryError(f'{where}: accelerations without velocities (the controller '
                                  'then has no spline); give velocities too, or neither')
        states.append((positions, velocities, accelerations))
    S = len(points)
    if stacked is not None:
        positions, velocities, accelerations, has_v, has_a = stacked
    else:
        positions = np.array([state[0] for state in states])              # (S, K)
        has_v = np.array([len(state[1]) > 0 for state in states])
        has_a = np.array([len(state[2]) > 0 for state in states])
        velocities = np.zeros((S, K))
        accelerations = np.zeros((S, K))
        for i, (_, v, a) in enumerate(states):
            if has_v[i]:
                velocities[i] = v
            if has_a[i]:
                accelerations[i] = a
    start = np.asarray(start, dtype=np.float64)
    kinds = checker.motion_kinds
    wrap = np.array([kinds[j] == engine.MOTION_WRAP for j in columns])  # continuous joints
    # The controller's wrap-around: a continuous joint starts from the value nearest the
    # first point.
    previous = start[columns]
    shortest = np.remainder(positions[0] - previous + math.pi, 2.0 * math.pi) - math.pi
    previous = np.where(wrap, positions[0] - shortest, previous)
    # Segment i runs from point i - 1 (the start for i = 0, at rest, taking the first point's
    # velocities and accelerations as given or not) to point i.
    p0 = np.vstack([previous[None], positions[:-1]])
    v0 = np.vstack([np.zeros((1, K)), velocities[:-1]])
    a0 = np.vstack([np.zeros((1, K)), accelerations[:-1]])
    from_v = np.concatenate([has_v[:1], has_v[:-1]])
    from_a = np.concatenate([has_a[:1], has_a[:-1]])
    spline_v = from_v & has_v
    spline_a = spline_v & from_a & has_a
    kind = np.where(spline_a, 'quintic', np.where(spline_v, 'cubic', 'linear'))
    coef = np.zeros((S, J, 6))
    coef[:, :, 0] = start
    coef[:, columns] = spline_coefficients(p0, v0, a0, positions, velocities, accelerations,
                                           np.diff(times), kind)
    return coef, np.asarray(times)


def _first_contact(checker, coef: np.ndarray, per_call: Optional[int]) -> PathResult:
    """``checker.check_spline(coef)``, ``per_call`` segments at a time (segments are checked in
    turn until one is not free, each on its own: the first met is the same)."""
    if not per_call:
        return checker.check_spline(coef)
    for first in range(0, len(coef), per_call):
        path = checker.check_spline(coef[first:first + per_call])
        if path.first_invalid_segment is not None:
            return PathResult(first + path.first_invalid_segment, path.motion)
    return PathResult(None, FREE)


def check_trajectory(checker, joint_names: Sequence[str], points: Sequence[TrajectoryPoint],
                     start=None, limit_tolerance: float = 0.0,
                     segments_per_call: Optional[int] = None) -> TrajectoryResult:
    """Check a planned trajectory along the path the controller will follow (see the module).

    :param joint_names: the trajectory's joints (a subset of ``checker.joint_names``).
    :param points: its points, :class:`TrajectoryPoint` (or 4-tuples alike).
    :param start: the state it starts from, as ``positions`` of ``checker.check`` (default:
        the checker's current positions); joints not named keep these values.
    :param limit_tolerance: rad or m beyond a joint limit still accepted.
    :param segments_per_call: check the segments this many at a time (the engine is free for
        other queries between two calls: the sensor answers joint states meanwhile); None: all
        in one call. The answer is the same.
    :return: a :class:`TrajectoryResult`; a malformed trajectory is invalid with its reason
        (no exception). Nothing in the checker changes.
    """
    points = [TrajectoryPoint(*p) if not isinstance(p, TrajectoryPoint) else p for p in points]
    try:
        q_start = checker._merged(checker.positions if start is None else start)
        coef, times = build_segments(checker, joint_names, points, q_start)
    except JointStateError as error:
        return TrajectoryResult(False, None, None, (), str(error))
    # The limits along the way: each named joint's extremes on each segment, the first
    # segment beyond a limit (in it, the first joint named; its low before its high).
    columns = [checker._joints.index[name] for name in joint_names]
    limits = np.array([checker.joint_limits[name] for name in joint_names], dtype=np.float64)
    bounded = np.isfinite(limits).any(axis=1)
    if bounded.any():
        low, t_low, high, t_high = polynomial_extremes(coef[:, columns])   # (S, K) each
        below = (low < limits[:, 0] - limit_tolerance) & bounded
        above = (high > limits[:, 1] + limit_tolerance) & bounded
        bad = below | above
        if bad.any():
            i = int(np.argmax(bad.any(axis=1)))
            k = int(np.argmax(bad[i]))
            name, (lower, upper) = joint_names[k], limits[k]
            value, u = (low[i, k], t_low[i, k]) if below[i, k] else (high[i, k], t_high[i, k])
            at = _fraction_of(times[i], times[i + 1] - times[i], u)
            where = 'from the start to point 0' if i == 0 else f'between points {i - 1} and {i}'
            return TrajectoryResult(
                False, i, at, (),
                f'joint "{name}" reaches {value:.6g} at time_from_start {at:.6g} s '
                f'({where}), beyond its limits [{lower:.6g}, {upper:.6g}] (tolerance '
                f'{limit_tolerance:g}); slow the trajectory down or move the point '
                'away from the limit')
    path = _first_contact(checker, coef, segments_per_call)
    if path.first_invalid_segment is None:
        return TrajectoryResult(True, None, None, (), '')
    i = path.first_invalid_segment
    motion: MotionResult = path.motion
    at = _fraction_of(times[i], times[i + 1] - times[i], motion.first_contact)
    pairs = motion.colliding_pairs
    names = ', '.join(f'{a} -- {b}' for a, b in pairs)
    where = 'from the start to point 0' if i == 0 else f'between points {i - 1} and {i}'
    return TrajectoryResult(False, i, at, pairs,
                            f'contact at time_from_start {at:.6g} s ({where}): {names}')
