"""Batches on several threads (``cpp/workers.hpp``): the answers of one thread, bit for bit.

Each robot (Panda in a cell with a table and a post, UR5, go1 on its floating base above a
floor, all from example-robot-data) is built three times, with ``threads`` 1, 2 and 5 (more
than this machine's cores, and chunks of unequal sizes), and every batch form is compared
across them: ``check_batch`` (statuses, the engine's codes and its work counters),
``update_batch``, ``check_path`` and ``check_spline``; the one-thread answers are checked
against single ``check`` calls, the independent oracle here (single calls never use workers).
"""
import os
import threading

import numpy as np
import pytest

from collision_sensor import CollisionChecker, ConfigError, JointStateError
from collision_sensor.engine import array_pack
from collision_sensor.engine.compiled import engine
from collision_sensor.errors import EngineInputError

THREADS = (1, 2, 5)

PANDA_CELL = {'objects': [
    {'name': 'table', 'box': {'size': [1.2, 1.2, 0.04]}, 'pose': {'xyz': [0.8, 0.0, 0.3]}},
    {'name': 'post', 'cylinder': {'radius': 0.05, 'length': 1.0},
     'pose': {'xyz': [0.0, 0.45, 0.5]}},
]}
FLOOR = {'objects': [
    {'name': 'floor', 'box': {'size': [2.0, 2.0, 0.1]}, 'pose': {'xyz': [0.0, 0.0, -0.05]}},
]}
ROBOTS = {
    'panda': ('panda_description/urdf/panda.urdf', 'panda_description/srdf/panda.srdf',
              PANDA_CELL),
    'ur5': ('ur_description/urdf/ur5_robot.urdf', 'ur_description/srdf/ur5.srdf', None),
    'go1': ('go1_description/urdf/go1.urdf', 'go1_description/srdf/go1.srdf', FLOOR),
}


def _build(erd_share, name, threads, **config):
    urdf, srdf, scene = ROBOTS[name]
    robots = os.path.join(erd_share, 'robots')
    return CollisionChecker.from_urdf(
        os.path.join(robots, urdf), srdf=os.path.join(robots, srdf),
        package_paths={'example-robot-data': erd_share}, scene=scene,
        config={'threads': threads, 'min_chunk_us': 0, **config})


@pytest.fixture(scope='module', params=sorted(ROBOTS))
def robot(request, erd_share):
    """(name, {threads: checker})."""
    return request.param, {t: _build(erd_share, request.param, t) for t in THREADS}


def _configurations(checker, n, seed):
    """(n, J) rows within the joint limits; a floating base within 0.4 m of the floor's
    centre, its height from 0.1 to 0.5 m, its quaternion random (not normalised)."""
    rng = np.random.default_rng(seed)
    names = checker.joint_names
    lower = np.array([checker.joint_limits[name][0] for name in names])
    upper = np.array([checker.joint_limits[name][1] for name in names])
    for j, name in enumerate(names):
        if name.endswith(('/trans_x', '/trans_y')):
            lower[j], upper[j] = -0.4, 0.4
        elif name.endswith('/trans_z'):
            lower[j], upper[j] = 0.1, 0.5
    lower = np.where(np.isfinite(lower), lower, -np.pi)
    upper = np.where(np.isfinite(upper), upper, np.pi)
    Q = rng.uniform(lower, upper, size=(n, len(names)))
    rot = [j for j, name in enumerate(names) if name.endswith('/rot_x')]
    for j in rot:
        Q[:, j:j + 4] = rng.normal(size=(n, 4))
    return Q


def _counters(checker):
    return checker.counters.copy()


def test_check_batch_is_one_threads_bit_for_bit(robot):
    """Statuses, pairs re-checked, changed flags (each row's against the row before) and the
    work done (counters) are one thread's, for every thread count; the one-thread rows are
    single checks'; rows in contact and rows apart both occur."""
    name, checkers = robot
    Q = _configurations(checkers[1], 600, seed=1)
    statuses, rechecked, changed, work = {}, {}, {}, {}
    for t, checker in checkers.items():
        before = _counters(checker)
        statuses[t], rechecked[t], changed[t] = checker._batch(Q, full=True)
        work[t] = _counters(checker) - before
    assert changed[1][1:].any() and not changed[1][1:].all()
    for t in THREADS:
        assert np.array_equal(statuses[t], statuses[1]), (name, t)
        assert np.array_equal(rechecked[t], rechecked[1]), (name, t)
        assert np.array_equal(changed[t], changed[1]), (name, t)
        assert np.array_equal(work[t], work[1]), (name, t)
    hits = statuses[1].any(axis=1)
    assert 10 < hits.sum() < len(Q) - 10, name  # both answers occur
    single = checkers[1]
    names = single.checked_pairs
    for q, row in zip(Q[::7], statuses[1][::7]):
        assert tuple(names[p] for p in np.flatnonzero(row)) == single.check(q).colliding_pairs


def test_check_batch_leaves_the_carried_state_as_it_was(robot):
    """A check_batch runs in copies of the state: the positions, the answer and the carried
    incremental state (nothing to re-check at the same positions) stay."""
    _, checkers = robot
    for t, checker in checkers.items():
        start = _configurations(checker, 1, seed=2)[0]
        before = checker.check(start)
        checker.update(start + 1e-3)
        at = checker.positions
        answer = checker.update(start + 1e-3)
        checker.check_batch(_configurations(checker, 50, seed=3))
        assert checker.positions == at, t
        assert checker.update(start + 1e-3).rechecked_pairs == 0, t
        assert checker.update(start + 1e-3).colliding_pairs == answer.colliding_pairs, t
        assert checker.update(start).colliding_pairs == before.colliding_pairs, t


@pytest.mark.parametrize('n', [0, 1, 2, 3, 4])
def test_empty_batches_and_batches_smaller_than_the_thread_count(robot, n):
    name, checkers = robot
    Q = _configurations(checkers[1], n, seed=4 + n)
    expected = checkers[1].check_batch(Q)
    assert expected.shape == (n, len(checkers[1].checked_pairs))
    for t, checker in checkers.items():
        assert np.array_equal(checker.check_batch(Q), expected), (name, t, n)
        checker.check(Q[0] if n else _configurations(checker, 1, seed=9)[0])
        assert np.array_equal(checker.update_batch(Q), expected), (name, t, n)


def test_unusable_rows_raise_the_same_error_and_change_nothing(robot):
    """A NaN (or, on a floating base, a zero quaternion) in any row, in any chunk: the same
    JointStateError naming the row and the joint, for every thread count, and nothing
    changed."""
    name, checkers = robot
    Q = _configurations(checkers[1], 40, seed=6)
    bad_rows = [(0, 0), (17, 1), (39, Q.shape[1] - 1)]
    rot = [j for j, joint in enumerate(checkers[1].joint_names) if joint.endswith('/rot_x')]
    for row, j in bad_rows:
        for values, message in ((np.nan, 'is not finite'), (np.inf, 'is not finite')):
            bad = Q.copy()
            bad[row, j] = values
            errors = set()
            for t, checker in checkers.items():
                start = _configurations(checker, 1, seed=7)[0]
                before = checker.check(start)
                for run in (checker.check_batch, checker.update_batch, checker.check_path):
                    with pytest.raises(JointStateError, match=message) as error:
                        run(bad)
                    errors.add(str(error.value))
                assert np.array_equal(list(checker.positions.values()), start), (name, t)
                assert checker.update(start).rechecked_pairs == 0
                assert checker.check(start) == before
            joint = checkers[1].joint_names[j]
            assert errors == {f'configuration {row}, joint "{joint}": position {values} '
                              'is not finite; send a finite value (nothing was changed)'}
    for j in rot:
        bad = Q.copy()
        bad[23, j:j + 4] = 0.0
        errors = set()
        for checker in checkers.values():
            for run in (checker.check_batch, checker.update_batch):
                with pytest.raises(JointStateError, match='quaternion') as error:
                    run(bad)
                errors.add(str(error.value))
        assert len(errors) == 1 and 'configuration 23' in errors.pop()


def _walk(checker, n, seed, step=0.05):
    """A random walk of n rows from a random configuration (the base's quaternion moves too)."""
    rng = np.random.default_rng(seed)
    q = _configurations(checker, 1, seed)[0]
    rows = [q]
    for _ in range(n - 1):
        q = q + rng.normal(scale=step, size=q.shape)
        rows.append(q)
    return np.array(rows)


def test_update_batch_is_one_threads_and_stands_at_the_last_row(robot):
    """update_batch's statuses are one thread's (and check_batch's) for every thread count;
    afterwards every checker stands at the last row and single updates go on from there with
    the answers of single checks."""
    name, checkers = robot
    path = _walk(checkers[1], 900, seed=8)
    for checker in checkers.values():
        checker.check(path[0])
    expected = checkers[1].update_batch(path)
    assert np.array_equal(expected, checkers[2].check_batch(path))
    assert 0 < expected.any(axis=1).sum(), name
    for t, checker in checkers.items():
        if t > 1:
            assert np.array_equal(checker.update_batch(path), expected), (name, t)
        assert np.array_equal(list(checker.positions.values()), path[-1]), (name, t)
        assert checker.update(path[-1]).rechecked_pairs == 0
        for q in path[::-97]:
            assert checker.update(q).colliding_pairs == checkers[1].check(q).colliding_pairs
        # Chunks are what the threads ran: each later chunk's first row re-checked every pair.
        # (The engine's batch itself: the checker's answer is not settled after it.)
        checker.check(path[0])
        _, rechecked, _ = checker._batch(path, full=False)
        starts = [len(path) * c // t for c in range(1, t)]  # 900 rows: chunks of equal size
        assert all(rechecked[i] == len(checker.checked_pairs) for i in starts), (name, t)
        assert (rechecked[1:] < len(checker.checked_pairs)).sum() > len(path) // 2
        checker.check(path[0])


def test_update_batch_with_a_motion_tolerance_runs_on_one_thread(erd_share):
    """With a motion tolerance, a row's statuses depend on the rows before (they describe the
    last state that moved beyond it): the rows run in turn whatever ``threads`` says, with
    the same work done."""
    checkers = {t: _build(erd_share, 'panda', t, motion_tolerance=0.02) for t in (1, 2)}
    path = _walk(checkers[1], 400, seed=10, step=0.01)
    out = {}
    for t, checker in checkers.items():
        checker.check(path[0])
        before = _counters(checker)
        out[t] = checker._batch(path, full=False)
        out[t] = out[t] + (_counters(checker) - before,)
    for a, b in zip(out[1], out[2]):
        assert np.array_equal(a, b)


def _free_configuration(checker, seed):
    for q in _configurations(checker, 200, seed):
        if not checker.check(q).in_collision:
            return q
    raise AssertionError('no configuration apart found')


def _paths(checker, seed):
    """Waypoint paths: free (small steps about a free configuration), in contact at the last
    segment (the last chunk's), in contact early, and random waypoints."""
    rng = np.random.default_rng(seed)
    free = _free_configuration(checker, seed)
    Q = _configurations(checker, 400, seed + 1)
    statuses = checker.check_batch(Q)
    hit = Q[np.flatnonzero(statuses.any(axis=1))[0]]
    calm = free + rng.normal(scale=0.002, size=(13, len(free)))
    return {
        'free': calm,
        'late': np.vstack([calm, hit]),
        'early': np.vstack([calm[:2], hit, calm]),
        'random': Q[:9],
    }


def test_check_path_is_one_threads(robot):
    name, checkers = robot
    for kind, path in _paths(checkers[1], seed=12).items():
        answers = {t: checker.check_path(path) for t, checker in checkers.items()}
        for t in THREADS:
            assert answers[t] == answers[1], (name, kind, t)
        expected = {'free': None, 'late': len(path) - 2, 'early': 1}.get(kind, ...)
        if expected is not ...:
            assert answers[1].first_invalid_segment == expected, (name, kind)
        assert answers[1] == checkers[1].check_path(path)  # a second call: the same


def _linear_splines(path):
    """The segments of a waypoint path as degree-1 polynomials (S, J, 6)."""
    coef = np.zeros((len(path) - 1, path.shape[1], 6))
    coef[:, :, 0] = path[:-1]
    coef[:, :, 1] = path[1:] - path[:-1]
    return coef


def test_check_spline_is_one_threads(robot):
    """Splines (the base held still: splines cannot move a floating joint) on every thread
    count; cubic segments too."""
    name, checkers = robot
    rot = [j for j, joint in enumerate(checkers[1].joint_names) if '/' in joint]
    for kind, path in _paths(checkers[1], seed=14).items():
        path = path.copy()
        path[:, rot] = path[0, rot]
        coef = _linear_splines(path)
        coef[:, :, 2] = 0.3 * np.sin(np.arange(coef.shape[1]))  # bend each segment
        coef[:, :, 3] = -coef[:, :, 2]
        coef[:, rot, 2:] = 0.0
        answers = {t: checker.check_spline(coef) for t, checker in checkers.items()}
        for t in THREADS:
            assert answers[t] == answers[1], (name, kind, t)


def test_a_batch_on_two_threads_while_another_thread_updates(erd_share):
    """The engine serializes its calls (its lock): a check_batch on two threads and updates
    from another Python thread interleave call by call, each with its own answers, and the
    updates go on from their own last state (check_batch leaves the carried state alone)."""
    checker = _build(erd_share, 'panda', 2)
    reference = _build(erd_share, 'panda', 1)
    Q = _configurations(checker, 2000, seed=16)
    expected = reference.check_batch(Q)
    walk = _walk(checker, 600, seed=17, step=0.02)
    wanted = [reference.check(q).colliding_pairs for q in walk]
    failures = []

    def batches():
        for _ in range(6):
            if not np.array_equal(checker.check_batch(Q), expected):
                failures.append('check_batch')

    worker = threading.Thread(target=batches)
    worker.start()
    got = [checker.update(q).colliding_pairs for q in walk]
    worker.join()
    assert not failures
    assert got == wanted


BASE_PLATE = {'name': 'base_plate', 'box': {'size': [0.6, 0.02, 0.02]},
              'pose': {'xyz': [0.0, 0.0, 0.07]}}  # through the Panda's fixed base


def test_static_pairs_answer_every_row_of_a_batch(erd_share):
    """A pair with no joint between its bodies (the fixed base and a world object) is checked
    once per check_batch, its answer every row's: each row is still a single check's on any
    thread count, before and after the object leaves and comes back (the carried answer then
    stale), and the row-0 changed bit sees the static pair change."""
    robots = os.path.join(erd_share, 'robots')
    urdf, srdf, cell = ROBOTS['panda']
    scene = {'objects': cell['objects'] + [BASE_PLATE]}

    def build(threads):
        return CollisionChecker.from_urdf(
            os.path.join(robots, urdf), srdf=os.path.join(robots, srdf),
            package_paths={'example-robot-data': erd_share}, scene=scene,
            config={'threads': threads, 'min_chunk_us': 0})

    reference = build(1)
    checkers = {t: build(t) for t in (1, 2)}
    Q = _configurations(reference, 120, seed=21)
    names = reference.checked_pairs
    static = ('base_plate', 'panda_link0')
    assert static in names
    away, inside = np.eye(4), np.eye(4)
    away[:3, 3] = (0.0, 0.0, -5.0)
    inside[:3, 3] = BASE_PLATE['pose']['xyz']
    for pose, expected in ((None, True), (away, False), (inside, True)):
        for checker in (reference, *checkers.values()):
            if pose is not None:
                checker.move_object('base_plate', pose)
        wanted = [reference.check(q).colliding_pairs for q in Q]
        for t, checker in checkers.items():
            carried = checker._result.colliding_pairs if checker._result else ()
            statuses, _, changed = checker._batch(Q, full=True)
            got = [tuple(names[p] for p in np.flatnonzero(row)) for row in statuses]
            assert got == wanted, (t, expected)
            assert all((static in pairs) == expected for pairs in got), t
            if (static in carried) != expected:
                assert changed[0], t
    # one row repeated: the static pairs' work is done once, not at every row
    repeated = np.repeat(Q[:1], 40, axis=0)
    single = _counters(checkers[1])
    checkers[1].check(Q[0])
    single = _counters(checkers[1]) - single
    before = _counters(checkers[1])
    checkers[1].check_batch(repeated)
    batch = _counters(checkers[1]) - before
    assert batch.sum() < 40 * single.sum()


def test_the_threads_setting(erd_share):
    """Default: every hardware thread (os.cpu_count()); 1 .. 256 as given; anything else a
    ConfigError naming the setting."""
    assert _build(erd_share, 'ur5', 0).threads == (os.cpu_count() or 1)
    assert _build(erd_share, 'ur5', 3).threads == 3
    robots = os.path.join(erd_share, 'robots')
    default = CollisionChecker.from_urdf(os.path.join(robots, ROBOTS['ur5'][0]),
                                         package_paths={'example-robot-data': erd_share})
    assert default.config.threads == 0 and default.threads == (os.cpu_count() or 1)
    for bad in (-1, 257, 1.5, True, '2', None):
        with pytest.raises(ConfigError, match='setting threads'):
            _build(erd_share, 'ur5', bad)


def test_the_engine_refuses_a_thread_count_out_of_range(erd_share):
    checker = _build(erd_share, 'ur5', 1)
    packed = array_pack.pack(checker._scene.arrays)
    for bad in (-1, 257):
        with pytest.raises(EngineInputError, match='threads: '):
            engine.Engine(packed.F, packed.F_layout, packed.I, packed.I_layout,
                          box_test=engine.BOX_TEST_SAT, expansion=engine.EXPAND_WIDER,
                          motion_tolerance=0.0, threads=bad)


def test_short_batches_run_on_fewer_threads(erd_share):
    """With min_chunk_us, once the engine knows what a row costs, a batch is cut only into
    chunks of that much work: a short update_batch then runs in turn (no full check in its
    middle), a long one in chunks; the answers are the same either way."""
    checker = _build(erd_share, 'panda', 2, min_chunk_us=200.0)
    reference = _build(erd_share, 'panda', 1)
    walk = np.repeat(_configurations(checker, 1, seed=18), 3000, axis=0)
    walk[:, 5] += np.linspace(0.0, 0.5, 3000)  # one wrist joint turns: few pairs re-checked
    pairs = len(checker.checked_pairs)
    checker.check(walk[0])
    _, rechecked, _ = checker._batch(walk, full=False)  # nothing known yet: two chunks
    assert rechecked[1500] == pairs
    for n in (20, 3000):
        checker.check(walk[0])
        reference.check(walk[0])
        statuses, rechecked, _ = checker._batch(walk[:n], full=False)
        assert np.array_equal(statuses, reference.update_batch(walk[:n]))
        middle = rechecked[n // 2] == pairs
        assert middle == (n == 3000), n
    checker.check(walk[0])
    with pytest.raises(ConfigError, match='setting min_chunk_us'):
        _build(erd_share, 'panda', 2, min_chunk_us=-1)
