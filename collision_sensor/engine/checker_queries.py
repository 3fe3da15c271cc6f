"""The checker's queries (a room of :class:`~collision_sensor.engine.checker.CollisionChecker`):
``check``, ``update``, their batches and ``proximity``, and how the engine's answers become the
checker's.

Every query is one call into the compiled engine (``cpp/engine.hpp``: ``Engine::query``, its
answer a ``QueryResult`` read by field name). The engine gives the same answer object again for
an answer with the same fields, and counts the queries that changed a status
(``status_version``): the checker keeps its last answer while either says nothing changed.
"""
import math
from typing import List, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.errors import JointStateError

Pair = Tuple[str, str]
#: CollisionChecker._answer before any: no answer of the engine is this object.
_NO_ANSWER = object()
#: numpy's float64 (one object: an identity test is cheaper than ``==``, which converts).
_FLOAT64 = np.dtype(np.float64)
#: Distinct colliding-pair sets whose answer tuples are kept for reuse (a robot in use meets
#: few of them; the bound keeps a random stream from growing the cache without end).
RESULT_CACHE_SIZE = 4096
Positions = Union[Mapping[str, float], Sequence[float], np.ndarray]


class CheckResult(NamedTuple):
    """The answer of one check.

    :ivar in_collision: True iff at least one checked pair collides.
    :ivar colliding_pairs: sorted tuple of ``(a, b)`` with ``a < b``.
    :ivar rechecked_pairs: how many pairs this call actually re-checked (all for ``check``).
    """

    in_collision: bool
    colliding_pairs: Tuple[Pair, ...]
    rechecked_pairs: int


class ProximityRecord(NamedTuple):
    """One checked pair nearer than the ``max_distance`` of :meth:`CollisionChecker.proximity`.

    :ivar link_a: the pair's first name (``link_a < link_b``, as in ``checked_pairs``).
    :ivar link_b: the second name (a link or a scene object).
    :ivar distance: the distance between the two bodies' triangle surfaces minus their two
        paddings (m; without padding, the surfaces' distance); <= 0 exactly when the pair is
        in contact: 0 when the surfaces meet, without padding (no penetration depth is
        computed); with padding, the surfaces' distance minus the paddings (-padding when
        they meet, or when a body lies inside a solid primitive).
    :ivar point_a: (3,) float, a nearest point of ``link_a``'s padded geometry (on its
        surface, moved towards ``point_b`` by its padding), in the world (root link) frame;
        in contact, one point of both padded bodies: where the surfaces meet (or a vertex
        inside a solid primitive), or, padded, the point between the surfaces' nearest points
        that splits their segment in the ratio of the two paddings.
    :ivar point_b: (3,) float, the nearest point of ``link_b``'s padded geometry
        (``point_a`` in contact). Apart, ``|point_b - point_a| == distance``.
    """

    link_a: str
    link_b: str
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray



class CheckerQueries:
    """:class:`~collision_sensor.engine.checker.CollisionChecker`'s queries: the checks, their
    batches and proximity at the carried state, and the answers' cache."""

    def _merged(self, positions: Positions) -> np.ndarray:
        """Return the current joint vector with ``positions`` applied.

        Finiteness (and what else the engine cannot honour) is checked by the engine, before it
        changes anything.
        """
        if (isinstance(positions, np.ndarray) and positions.dtype is _FLOAT64
                and positions.shape == self._q.shape):
            # As the engine reads in place (a misaligned or strided one is copied); the engine
            # copies it before keeping it. flags.carray is the cheap test (np.require costs
            # its argument parsing even when it returns the array unchanged).
            if positions.flags.carray:
                return positions
            return np.require(positions, requirements=['C_CONTIGUOUS', 'ALIGNED'])
        q = self._q.copy()
        if isinstance(positions, Mapping):
            unknown = [name for name in positions
                       if name not in self._joints.index and name not in self._joints.derived]
            if unknown:
                raise JointStateError(
                    f'unknown joint name(s) {", ".join(map(str, unknown))} for robot '
                    f'"{self.model.name}"; movable joints are {", ".join(self.joint_names)}')
            for name, value in positions.items():
                try:
                    number = float(value)
                except (TypeError, ValueError):
                    raise JointStateError(
                        f'joint "{name}": position {value!r} is not a number') from None
                if not math.isfinite(number):
                    raise JointStateError(f'joint "{name}": position {number} is not finite; '
                                          'send a finite value (nothing was changed)')
                j = self._joints.index.get(name)
                if j is not None:  # a mimic joint follows its source; its own value is unused
                    q[j] = number
            return q
        try:
            values = np.asarray(positions, dtype=np.float64)
        except (TypeError, ValueError):
            raise JointStateError(f'positions must be a mapping joint -> value or a sequence of '
                                  f'{len(q)} numbers, got {type(positions).__name__}') from None
        if values.shape != q.shape:
            raise JointStateError(
                f'expected {len(q)} positions in the order of joint_names '
                f'({", ".join(self.joint_names)}), got shape {values.shape}')
        return np.ascontiguousarray(values)

    def _run(self, q: np.ndarray, full: bool) -> CheckResult:
        """Run the query on ``q`` (an array the engine reads as it is: :meth:`_merged`)."""
        try:
            answer = self._query(q, full)
        except JointStateError as error:
            raise self._refused(error, q) from None
        return self._settle(answer, q, full)

    def _settle(self, answer, positions: Positions, full: bool) -> CheckResult:
        """Return the answer for the engine's ``answer`` (``cpp/engine.hpp``: QueryResult;
        None: ``positions`` is no array the engine reads as it is, converted here first).

        The answer is looked up (by the statuses' bytes) or made only when the statuses are
        not those ``_result`` was made from: the engine's status_version moved on (a status
        changed, in this query or in one another caller ran on the engine in between).
        """
        if answer is None:
            return self._run(self._merged(positions), full)
        self._answer = answer
        if answer.status_version != self._version:
            self._version = answer.status_version
            result = self._results.get(self._status.tobytes())
            if result is None or result.rechecked_pairs != answer.rechecked:
                result = self._result_from_status(answer.rechecked)
            self._result = result
            return result
        if answer.rechecked != self._result.rechecked_pairs:
            result = self._result
            self._result = CheckResult(result.in_collision, result.colliding_pairs,
                                       answer.rechecked)
        return self._result

    def _refused(self, error: JointStateError, q: np.ndarray,
                 row: Optional[int] = None) -> JointStateError:
        """The error naming the joint for a value the engine refused (``error.variable``)."""
        return JointStateError(self._unusable_message(error.variable, q, row))

    def _unusable_message(self, j: int, q: np.ndarray, row: Optional[int] = None) -> str:
        """The message for variable j of ``q``, which the engine refused (not finite, or
        moving a prismatic joint beyond the engine's range)."""
        where = f'configuration {row}, ' if row is not None else ''
        value = q[j]
        name = self.joint_names[j]
        if math.isfinite(value) and name.endswith('/rot_x'):
            joint = name[:-len('/rot_x')]
            values = ', '.join(f'{v:g}' for v in q[j:j + 4])
            return (f'{where}floating joint "{joint}": quaternion (rot_x, rot_y, rot_z, rot_w) '
                    f'= ({values}) is zero (norm below {engine.QUATERNION_NORM_MIN:g}); send a '
                    'unit quaternion, (0, 0, 0, 1) for no rotation (nothing was changed)')
        if math.isfinite(value):
            why = (f'moves a joint out of the engine\'s range (a prismatic joint, or a planar or '
                   f'floating joint\'s translation, by more than '
                   f'{engine.PRISMATIC_VALUE_MAX:g} m, or a value that overflows); send a '
                   'value within the joint\'s limits')
        else:
            why = 'is not finite; send a finite value'
        return (f'{where}joint "{self.joint_names[j]}": position {value} {why} '
                '(nothing was changed)')

    def check(self, positions: Positions) -> CheckResult:
        """Check every pair from scratch at ``positions``; trust nothing carried over.

        :param positions: ``{joint: value}`` (joints not given keep their last value, zero at
            start; mimic joints' values are ignored, they follow their source), or an array
            in the order of :attr:`joint_names`.
        :raises JointStateError: on unknown names or non-finite values; nothing changes then.
        """
        try:
            answer = self._query(positions, True)
        except JointStateError as error:
            raise self._refused(error, positions) from None
        if answer is self._answer:
            return self._result  # the last answer's fields: its statuses (see _settle)
        return self._settle(answer, positions, True)

    def update(self, positions: Positions) -> CheckResult:
        """Check incrementally: re-check only pairs whose relative pose can have changed.

        A pair is re-checked only if a joint on the tree path between its two bodies moved by
        more than ``motion_tolerance`` since the state its status describes; every other
        status, and every pose not below a moved joint, carries over (paper sec. 4.2). A pair
        last found apart by ``update`` with a known clearance is not re-checked either while
        the joints on its path have not moved far enough, summed, to close that gap (see
        ``cpp/planning.hpp``).
        Same arguments and errors as :meth:`check`.
        """
        try:
            answer = self._query(positions, False)
        except JointStateError as error:
            raise self._refused(error, positions) from None
        if answer is self._answer:
            return self._result  # the last answer's fields: its statuses (see _settle)
        return self._settle(answer, positions, False)

    def check_batch(self, configurations: np.ndarray) -> np.ndarray:
        """Check many configurations from scratch, in one compiled call; return (n, P) bool
        statuses, columns in the order of :attr:`checked_pairs`.

        The rows run on :attr:`threads` threads (contiguous chunks of at least the setting
        ``min_chunk_us`` of work; the answers those of one thread), each in a copy of the
        carried state: the carried state is left as it was,
        and the next :meth:`update` goes on from the positions of the last single call.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: on a wrong shape or a value that is not finite (naming the
            row and joint); nothing changes then.
        :raises EngineWorkerError: a worker thread failed (memory); nothing changes then.
        """
        return self._batch(configurations, full=True)[0]

    def update_batch(self, configurations: np.ndarray) -> np.ndarray:
        """Run :meth:`update` on each row in turn, in one compiled call: a recorded path
        checked incrementally, without the interpreter between steps. Return (n, P) bool
        statuses after each row, columns in the order of :attr:`checked_pairs`.

        The state carries over as with single calls: afterwards the checker stands at the
        last row (``update`` goes on from there, :attr:`positions` is that row).

        On :attr:`threads` threads when ``motion_tolerance`` is 0 (then a row's statuses are
        a full check's at that row, whatever the rows before): the first chunk of rows goes
        on from the carried state, each later chunk starts with a full check at its first row.
        The statuses are one thread's; what differs is the work (each later chunk's first
        row re-checks every pair) and so :attr:`CheckResult.rechecked_pairs` of the next
        answers. With a motion tolerance the rows run in turn on the calling thread.

        :param configurations: (n, J) float, rows in the order of :attr:`joint_names`.
        :raises JointStateError: as :meth:`check_batch`; nothing changes then.
        :raises EngineWorkerError: a worker thread failed (memory); the state is then at some
            row of the batch (``check`` sets it anew).
        """
        statuses, rechecked, _ = self._batch(configurations, full=False)
        if len(rechecked):
            self._version = self._engine.status_version
            self._answer = _NO_ANSWER
            self._result = self._result_from_status(int(rechecked[-1]))
        return statuses

    @property
    def threads(self) -> int:
        """Threads :meth:`check_batch`, :meth:`update_batch`, :meth:`check_path` and
        :meth:`check_spline` run on: the setting ``threads`` resolved (0 there: the machine's
        hardware threads)."""
        return self._engine.threads

    def _batch(self, configurations,
               full: bool) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run the rows through the engine; return each row's answer: (n, P) bool statuses,
        (n,) pairs re-checked and (n,) bool changed (against the row before)."""
        Q = np.ascontiguousarray(configurations, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != len(self.joint_names):
            raise JointStateError(f'expected configurations of shape (n, {len(self.joint_names)})'
                                  f' in the order of joint_names, got {Q.shape}')
        statuses = np.zeros((len(Q), len(self.checked_pairs)), dtype=np.uint8)
        rechecked = np.zeros(len(Q), dtype=np.int64)
        changed = np.zeros(len(Q), dtype=np.uint8)
        try:  # the engine validates every row before it runs any
            self._engine.batch(Q, full, statuses, rechecked, changed)
        except JointStateError as error:
            raise self._refused(error, Q[error.row], error.row) from None
        return statuses.view(bool), rechecked, changed.view(bool)

    def proximity(self, positions: Positions,
                  max_distance: float = 0.1) -> List[ProximityRecord]:
        """Run :meth:`update` at ``positions``, then measure every checked pair nearer than
        ``max_distance``; return their records sorted by distance (pairs in contact first,
        distance <= 0).

        Same hierarchy and exception list as :meth:`check`; the engine descends both bodies'
        OBB trees with distance lower bounds (the boxes', and each node's extent along the
        nearest points' direction) and stops a pair once its bound reaches ``max_distance``
        or the best distance found, starting from the triangles that were nearest at the last
        call (``cpp/distance.hpp``). Distances are padded (see :class:`ProximityRecord`); a
        pair in contact (exactly the pairs :meth:`update` reports) has distance <= 0 and a
        point in both padded bodies; penetration depth is not computed.

        :param positions: as for :meth:`check`.
        :param max_distance: only pairs closer than this (m; ``math.inf``: every pair).
        :raises JointStateError: as :meth:`check`.
        :raises ValueError: ``max_distance`` is NaN.
        """
        max_distance = float(max_distance)
        if math.isnan(max_distance):
            raise ValueError('max_distance is NaN; give a distance in metres (inf: all pairs)')
        q = self._merged(positions)
        n_pairs = len(self.checked_pairs)
        distance = np.empty(n_pairs)
        points = np.empty((n_pairs, 6))
        try:
            answer = self._engine.proximity(q, max_distance, distance, points)
        except JointStateError as error:
            raise self._refused(error, q) from None
        self._settle(answer, q, False)
        return self._proximity_records(distance, points)


    def _proximity_records(self, distance: np.ndarray,
                           points: np.ndarray) -> List[ProximityRecord]:
        """Records for the pairs with a finite distance, sorted; points as named."""
        records = []
        body_a, body_index = self._scene.pair_a, self._scene.body_index
        for p in np.flatnonzero(np.isfinite(distance)):
            a, b = self.checked_pairs[p]
            row = points[p]
            if body_index[a] == body_a[p]:
                point_a, point_b = row[:3].copy(), row[3:].copy()
            else:  # the engine keeps a scene object second
                point_a, point_b = row[3:].copy(), row[:3].copy()
            records.append(ProximityRecord(a, b, float(distance[p]), point_a, point_b))
        records.sort(key=lambda r: (r.distance, r.link_a, r.link_b))
        return records

    def _result_from_status(self, rechecked: int) -> CheckResult:
        """The answer for the current statuses. Answers are kept for reuse, by statuses: the
        same pair set comes back again and again (mostly none, one or two pairs), and every
        ``check`` re-checks the same number of pairs, so its answer object itself recurs."""
        key = self._status.tobytes()
        known = self._results.get(key)
        if known is not None:
            return CheckResult(known.in_collision, known.colliding_pairs, rechecked)
        names = self.checked_pairs
        hits = tuple([names[p] for p in np.flatnonzero(self._status)])
        result = CheckResult(bool(hits), hits, rechecked)
        if len(self._results) < RESULT_CACHE_SIZE:
            self._results[key] = result
        return result

    def cast_rays(self, origin, directions, max_range: float = math.inf) -> np.ndarray:
        """Cast rays against the robot and the scene objects at the last checked state (a
        simulated depth sensor: point clouds are not seen): ``origin + t directions[i]``.

        :param origin: (3,) world frame.
        :param directions: (n, 3) unit vectors, world frame.
        :return: (n,) the nearest hit's t (m), ``inf`` when nothing is hit within
            ``max_range``.
        """
        origin = np.ascontiguousarray(origin, dtype=np.float64)
        directions = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
        return self._engine.cast_rays(origin, directions, float(max_range))

