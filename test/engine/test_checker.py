"""Whole-robot answers of CollisionChecker against independent oracles.

* python-fcl on the same triangles, with pinocchio's kinematics, on the Panda and the UR5 from
  example-robot-data with their SRDFs: 10,000 seeded random configurations each;
* brute force over all triangle pairs on small generated robots and scenes;
* ``update`` against a from-scratch ``check`` along long random walks.
"""

import numpy as np
import pytest

from collision_sensor import CollisionChecker, ConfigError, JointStateError
from collision_sensor.engine.pair_reach import pair_rows
from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.model.mesh_loading import SOLID_BOX, SOLID_SPHERE, box_mesh
from collision_sensor.model.scene import SceneObject
from engine_kernels import triangles_intersect
from engine_oracles import FclOracle
from small_robot import SMALL_ROBOT, SMALL_SCENE

N_FCL_CONFIGURATIONS = 10_000


@pytest.fixture(scope='module')
def panda(panda_urdf, panda_srdf, erd_package_paths):
    return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths=erd_package_paths)


@pytest.fixture(scope='module')
def ur5(ur5_urdf, ur5_srdf, erd_package_paths):
    return CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf, package_paths=erd_package_paths)


def _agree_with_fcl(checker, urdf, seed):
    oracle = FclOracle(checker, urdf)
    configurations = random_configurations(checker, N_FCL_CONFIGURATIONS, seed)
    mismatches = []
    colliding = 0
    for q in configurations:
        ours = checker.check(q).colliding_pairs
        theirs = oracle.colliding_pairs(q)
        colliding += bool(theirs)
        if ours != theirs:
            mismatches.append((list(q), ours, theirs))
    # Print failures as literals that can be pasted into a regression test.
    assert not mismatches, f'{len(mismatches)} mismatches, first: {mismatches[:3]}'
    return colliding


@pytest.mark.slow
def test_panda_matches_fcl_on_random_configurations(panda, panda_urdf):
    colliding = _agree_with_fcl(panda, panda_urdf, seed=1)
    # The comparison means something only if both answers occur often.
    assert 200 < colliding < N_FCL_CONFIGURATIONS - 200


@pytest.mark.slow
def test_ur5_matches_fcl_on_random_configurations(ur5, ur5_urdf):
    colliding = _agree_with_fcl(ur5, ur5_urdf, seed=2)
    assert 200 < colliding < N_FCL_CONFIGURATIONS - 200


def test_every_box_test_and_expansion_rule_gives_the_same_answers(
        panda_urdf, panda_srdf, erd_package_paths, panda):
    configurations = random_configurations(panda, 300, seed=3)
    expected = [panda.check(q).colliding_pairs for q in configurations]
    for box_test in ('sat', 'paper'):
        for expansion in ('same', 'alternate', 'larger', 'promising', 'wider'):
            checker = CollisionChecker.from_urdf(
                panda_urdf, srdf=panda_srdf, package_paths=erd_package_paths,
                config={'box_test': box_test, 'expansion': expansion})
            got = [checker.check(q).colliding_pairs for q in configurations]
            assert got == expected, (box_test, expansion)


# ---------------------------------------------------------------- brute force, small robots

def _any_triangle_pair_meets(A, B, chunk=200_000):
    """Return True iff some triangle of A (n, 3, 3) meets some triangle of B (m, 3, 3): all
    n * m pairs through the batch test, at most about ``chunk`` pairs at a time."""
    n, m = A.shape[0], B.shape[0]
    if n == 0 or m == 0:
        return False
    rows = max(1, chunk // m)
    for i in range(0, n, rows):
        a = A[i:i + rows]
        P = np.repeat(a, m, axis=0)                   # pairs (i, j), j fastest
        Q = np.tile(B, (a.shape[0], 1, 1))
        if triangles_intersect(P, Q).any():
            return True
    return False


def _world_triangles(checker):
    poses = checker.link_poses()
    out = {}
    for element in checker.model.elements:
        T = poses[element.link] @ element.T_link_element
        tris = element.vertices[element.faces] @ T[:3, :3].T + T[:3, 3]
        out.setdefault(element.link, []).append(tris)
    f = checker.forest
    for name in checker.scene_object_names:
        b = checker._scene.body_index[name]
        T = poses[name]
        for e in range(checker._scene.elem_start[b], checker._scene.elem_end[b]):
            tris = FclOracle._tris_of_tree(f, f.roots[e])
            out.setdefault(name, []).append(tris @ T[:3, :3].T + T[:3, 3])
    return {name: np.ascontiguousarray(np.concatenate(parts)) for name, parts in out.items()}


def _world_solids(checker):
    """{body: [(solid, T_world_element, one vertex of each element in the world)]}."""
    poses = checker.link_poses()
    out = {}
    for element in checker.model.elements:
        T = poses[element.link] @ element.T_link_element
        out.setdefault(element.link, []).append((element.solid, T,
                                                 element.vertices[0] @ T[:3, :3].T + T[:3, 3]))
    for name, obj in zip(checker.scene_object_names, checker.scene_objects):
        T = poses[name]
        out.setdefault(name, []).append((obj.solid, T, obj.vertices[0] @ T[:3, :3].T + T[:3, 3]))
    return out


def _inside(solid, T, x):
    """x (world) inside the true primitive ``solid`` placed at T (boundary included)."""
    if solid is None:
        return False
    p = T[:3, :3].T @ (x - T[:3, 3])
    h = solid.size
    if solid.kind == SOLID_BOX:
        return bool(np.all(np.abs(p) <= h))
    if solid.kind == SOLID_SPHERE:
        return bool(p @ p <= h[0] ** 2)
    return bool(p[0] ** 2 + p[1] ** 2 <= h[0] ** 2 and abs(p[2]) <= h[1])


def _brute_force_pairs(checker):
    """Pairs whose triangles meet (all triangle pairs), or with a part of one body wholly
    inside a primitive of the other (one vertex of each element decides, once no triangles
    meet): the contact rule, docs/engine.md "Contact rule"."""
    tris = _world_triangles(checker)
    solids = _world_solids(checker)

    def contained(a, b):
        return any(_inside(solid, T, vertex) for solid, T, _ in solids[a]
                   for _, _, vertex in solids[b])

    return tuple(pair for pair in checker.checked_pairs
                 if _any_triangle_pair_meets(tris[pair[0]], tris[pair[1]])
                 or contained(*pair) or contained(pair[1], pair[0]))


@pytest.mark.slow
@pytest.mark.parametrize('leaf_size', [1, 3])
def test_small_robot_and_scene_match_brute_force(leaf_size):
    checker = CollisionChecker.from_urdf(
        SMALL_ROBOT, scene=SMALL_SCENE,
        config={'primitive_sections': 10, 'leaf_size': leaf_size, 'ignore_adjacent': False})
    configurations = random_configurations(checker, 400, seed=4)
    seen = set()
    for q in configurations:
        result = checker.check(q)
        expected = _brute_force_pairs(checker)
        assert result.colliding_pairs == expected, list(q)
        seen.update(expected)
    # Self pairs and scene pairs both occur, so both paths of the engine were exercised.
    assert any('pillar' in pair or 'shelf' in pair or 'ball' in pair for pair in seen)
    assert any(set(pair) <= {'base', 'upper', 'lower', 'tool'} for pair in seen)


# ---------------------------------------------------------------- incremental == from scratch

def _walk(checker, steps, rng, mode):
    q = random_configurations(checker, 1, seed=int(rng.integers(1 << 30)))[0]
    lower, upper = sampling_bounds(checker)
    for _ in range(steps):
        step = np.zeros_like(q)
        if mode == 'one':
            j = rng.integers(len(q))
            step[j] = rng.normal(0.0, 0.05)
        elif mode == 'many':
            step = rng.normal(0.0, 0.03, len(q))
        elif mode == 'jumps':
            step = rng.uniform(-1.0, 1.0, len(q)) * (upper - lower)
        elif mode == 'mixed':
            choice = rng.integers(4)
            if choice == 0:
                pass  # nothing moves
            elif choice == 1:
                step[rng.integers(len(q))] = rng.normal(0.0, 0.1)
            elif choice == 2:
                step = rng.normal(0.0, 0.05, len(q))
            else:
                step = rng.uniform(-1.0, 1.0, len(q)) * (upper - lower)
        q = np.clip(q + step, lower, upper)
        yield q


@pytest.mark.parametrize('mode', ['one', 'many', 'jumps', 'mixed'])
def test_update_equals_check_along_random_walks(panda_urdf, panda_srdf, erd_package_paths,
                                                mode):
    scene = {'objects': [
        {'name': 'table', 'box': {'size': [1.2, 1.2, 0.04]},
         'pose': {'xyz': [0.5, 0.0, 0.3]}},
        {'name': 'post', 'cylinder': {'radius': 0.05, 'length': 1.0},
         'pose': {'xyz': [0.0, 0.45, 0.5]}},
    ]}
    incremental = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                             package_paths=erd_package_paths, scene=scene)
    scratch = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=scene)
    rng = np.random.default_rng({'one': 5, 'many': 6, 'jumps': 7, 'mixed': 8}[mode])
    changes = 0
    previous = None
    skipped = 0
    for q in _walk(incremental, 1500, rng, mode):
        got = incremental.update(q)
        expected = scratch.check(q)
        assert got.colliding_pairs == expected.colliding_pairs, list(q)
        changes += got.colliding_pairs != previous
        skipped += got.rechecked_pairs < len(incremental.checked_pairs)
        previous = got.colliding_pairs
    assert changes > 5  # the walk went in and out of contact
    if mode in ('one', 'mixed'):
        assert skipped > 100  # and the incremental path really skipped work


def _panda_with_scene(panda_urdf, panda_srdf, erd_package_paths):
    scene = {'objects': [
        {'name': 'table', 'box': {'size': [1.2, 1.2, 0.04]},
         'pose': {'xyz': [0.5, 0.0, 0.3]}},
        {'name': 'post', 'cylinder': {'radius': 0.05, 'length': 1.0},
         'pose': {'xyz': [0.0, 0.45, 0.5]}},
    ]}
    return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths=erd_package_paths, scene=scene)


@pytest.mark.parametrize('mode', ['one', 'mixed'])
def test_update_batch_equals_check_on_every_row(panda_urdf, panda_srdf, erd_package_paths,
                                                mode):
    """A path checked incrementally in one call gives, row by row, the from-scratch answers;
    afterwards the checker stands at the last row, with its poses (computed lazily by
    update) equal to pinocchio's, and single updates go on from there."""
    incremental = _panda_with_scene(panda_urdf, panda_srdf, erd_package_paths)
    scratch = _panda_with_scene(panda_urdf, panda_srdf, erd_package_paths)
    rng = np.random.default_rng({'one': 5, 'mixed': 8}[mode])
    path = np.array(list(_walk(incremental, 1500, rng, mode)))
    incremental.check(path[0])
    statuses = incremental.update_batch(path)
    assert statuses.shape == (len(path), len(incremental.checked_pairs))
    names = incremental.checked_pairs
    for q, row in zip(path, statuses):
        expected = scratch.check(q).colliding_pairs
        assert tuple(names[p] for p in np.flatnonzero(row)) == expected, list(q)
    assert 5 < len({tuple(row) for row in statuses})  # the path went in and out of contact
    assert np.array_equal(list(incremental.positions.values()), path[-1])
    assert incremental.update(path[-1]).rechecked_pairs == 0
    assert incremental.update(path[-1]).colliding_pairs == scratch.check(path[-1]).colliding_pairs
    oracle = FclOracle(incremental, panda_urdf)
    poses, expected_poses = incremental.link_poses(), oracle.poses(path[-1])
    for name in incremental.link_names:
        assert np.allclose(poses[name], expected_poses[name], atol=1e-9), name
    for q in path[::-50]:  # single calls carry on from the batch's state
        assert incremental.update(q).colliding_pairs == scratch.check(q).colliding_pairs


def test_check_batch_equals_check_and_restores_the_state(panda):
    configurations = random_configurations(panda, 300, seed=23)
    start = random_configurations(panda, 1, seed=24)[0]
    before = panda.check(start)
    statuses = panda.check_batch(configurations)
    for q, row in zip(configurations, statuses):
        hits = tuple(panda.checked_pairs[p] for p in np.flatnonzero(row))
        assert hits == panda.check(q).colliding_pairs
    panda.check(start)
    panda.check_batch(configurations)
    assert np.array_equal(list(panda.positions.values()), start)
    assert panda.update(start).colliding_pairs == before.colliding_pairs
    assert 5 < statuses.any(axis=1).sum() < 295  # both answers occur


def test_a_check_tries_each_pairs_last_witness_first(panda):
    """A full check tests first the two triangles that met at a pair's last check: after a
    clear state (no witnesses), a colliding state costs more box tests than the same state
    checked again (a nudge of 1e-9 rad: witnesses from the first), and the answers are one
    another's and those of a check without witnesses (check_batch's rows)."""
    from collision_sensor.engine.traversal import COUNT_BOX_TESTS
    configurations = random_configurations(panda, 200, seed=29)
    rows = panda.check_batch(configurations)
    colliding = [q for q, row in zip(configurations, rows) if row.any()]
    clear = next(q for q, row in zip(configurations, rows) if not row.any())
    assert len(colliding) >= 5
    cold = warm = 0
    for q in colliding[:5]:
        panda.check(clear)
        before = panda.counters[COUNT_BOX_TESTS]
        first = panda.check(q).colliding_pairs
        cold += panda.counters[COUNT_BOX_TESTS] - before
        before = panda.counters[COUNT_BOX_TESTS]
        again = panda.check(q + 1e-9).colliding_pairs
        warm += panda.counters[COUNT_BOX_TESTS] - before
        batch = panda.check_batch(q[None])[0]
        assert again == first == tuple(panda.checked_pairs[p] for p in np.flatnonzero(batch))
    assert warm < cold


def test_batches_reject_non_finite_values_and_change_nothing(panda):
    start = random_configurations(panda, 1, seed=25)[0]
    before = panda.check(start)
    path = random_configurations(panda, 5, seed=26)
    path[3, 2] = np.nan
    for run in (panda.update_batch, panda.check_batch):
        with pytest.raises(JointStateError, match=r'configuration 3, joint "panda_joint3"'):
            run(path)
        with pytest.raises(JointStateError, match=r'shape \(n, 8\)'):
            run(path[:, :3])
    assert np.array_equal(list(panda.positions.values()), start)
    assert panda.update(start).rechecked_pairs == 0
    assert panda.check(start) == before


def test_running_travel_sums_equal_the_sums_recomputed_from_scratch(panda):
    """update keeps each skipped pair's motion bound as a running sum over the moved joints'
    terms; after a long walk it must equal the sum computed afresh from q_eval (and the
    prismatic finger joint moving in between changes every coefficient)."""
    from collision_sensor.engine.kinematics import JOINT_PRISMATIC

    def slot(name, shape=None):
        view = panda.packed_array(name)
        return view if shape is None else view.reshape(shape)

    n_pairs, n_joints = len(panda.checked_pairs), len(panda.joint_names)
    rng = np.random.default_rng(27)
    walk = list(_walk(panda, 3000, rng, 'one'))
    panda.check(walk[0])
    tracked = 0
    for k, q in enumerate(walk):
        panda.update(q)
        if k % 500 == 499:
            clearance, travel = slot('clearance'), slot('travel', (n_pairs, 2))
            q_ref, q_eval = slot('q_ref'), slot('q_eval', (n_pairs, n_joints))
            moved = np.abs(q_ref - q_eval)
            fixed = (moved * slot('reach', (n_pairs, n_joints))).sum(axis=1)
            ext = (moved * slot('reach_ext', (n_pairs, n_joints))).sum(axis=1)
            on = clearance > 0
            assert np.allclose(travel[on, 0], fixed[on], rtol=1e-9, atol=1e-12)
            assert np.allclose(travel[on, 1], ext[on], rtol=1e-9, atol=1e-12)
            kin = panda.kinematics  # E: how far the sliders (the two fingers) are out
            sliders = np.flatnonzero(kin.joint_type == JOINT_PRISMATIC)
            extension = np.abs(kin.multiplier[sliders] * q_ref[kin.q_index[sliders]]
                               + kin.offset[sliders]).sum()
            assert len(sliders) == 2
            assert panda.packed_array('extension')[0] == pytest.approx(extension, abs=1e-12)
            exact = fixed + extension * ext
            assert np.all(exact[on] < clearance[on])  # skipped pairs are still apart
            tracked += int(on.sum())
    assert tracked > 20


def test_update_with_nothing_moving_rechecks_nothing(panda):
    q = random_configurations(panda, 1, seed=9)[0]
    first = panda.check(q)
    again = panda.update(q)
    assert again.rechecked_pairs == 0
    assert again.colliding_pairs == first.colliding_pairs


def test_motion_tolerance_skips_small_motions_and_catches_drift(
        panda_urdf, panda_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths,
                                         config={'motion_tolerance': 0.01})
    q = random_configurations(checker, 1, seed=10)[0]
    checker.check(q)
    q2 = q.copy()
    q2[3] += 0.005
    assert checker.update(q2).rechecked_pairs == 0
    q3 = q2.copy()
    q3[3] += 0.006  # 0.011 from the state the statuses describe: counts as motion
    assert checker.update(q3).rechecked_pairs > 0


def test_pairs_below_an_unmoved_joint_are_not_rechecked(panda):
    q = random_configurations(panda, 1, seed=11)[0]
    panda.check(q)
    q2 = q.copy()
    j = panda.joint_names.index('panda_joint7')
    q2[j] += 0.1
    rechecked = panda.update(q2).rechecked_pairs
    # Only pairs with link7's subtree on one side and the rest on the other can change.
    below = {'panda_link7', 'panda_hand', 'panda_leftfinger', 'panda_rightfinger'}
    expected = sum((a in below) != (b in below) for a, b in panda.checked_pairs)
    assert rechecked == expected


# ---------------------------------------------------------------- API edge

def test_unknown_joint_and_nan_raise_and_change_nothing(panda):
    q = random_configurations(panda, 1, seed=12)[0]
    before = panda.check(q)
    positions = panda.positions
    with pytest.raises(JointStateError, match='wrist_99'):
        panda.update({'wrist_99': 0.3, 'panda_joint1': 0.2})
    with pytest.raises(JointStateError, match='panda_joint2.*not finite'):
        panda.update({'panda_joint1': 0.2, 'panda_joint2': float('nan')})
    with pytest.raises(JointStateError, match='not finite'):
        panda.update(np.full(len(panda.joint_names), np.inf))
    assert panda.positions == positions
    assert panda.update(positions).colliding_pairs == before.colliding_pairs


# The states of the report that found update() wrong after absurd values (Panda, joint_names
# order): the third moved a finger by 1.7e308 m and, before the fix, the fourth was reported
# clear by update() while colliding.
ABSURD_SEQUENCE = [
    [2.8489, 0.3706, -2.1638, -1.8272, 1.2051, 0.0048, -0.3367, -5.0],
    [0.2178, 0.7639, -1.8830, -1.9483, -2.6116, 0.0535, -1.1751, 0.0294],
    [1.3175, 1.6472, -0.1179, -2.2271, -9.223372036854776e18, 1e9, 0.9292,
     1.7976931348623157e308],
    [-0.6752, 1.7359, -0.7879, -2.9622, -0.8937, 0.9992, -1.0743, 0.0113],
]


def test_absurd_values_are_refused_and_leave_update_equal_to_check(panda_urdf, panda_srdf,
                                                                   erd_package_paths):
    incremental = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                             package_paths=erd_package_paths)
    scratch = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    for k, q in enumerate(ABSURD_SEQUENCE):
        if k == 2:
            before = incremental.positions
            with pytest.raises(JointStateError, match='panda_finger_joint1.*range'):
                incremental.update(q)
            assert incremental.positions == before
            continue
        assert incremental.update(q).colliding_pairs == scratch.check(q).colliding_pairs
    assert scratch.check(ABSURD_SEQUENCE[3]).colliding_pairs == (('panda_link1', 'panda_link5'),)


def _hostile_walk(checker, n, rng):
    """Random configurations and small steps, with huge, tiny and non-finite values mixed in:
    revolute joints get values up to +-1.8e308 (their cos and sin stay exact), and sliders
    values beyond any range the engine takes."""
    values = [1e9, -1e9, 9.2e18, -9.2e18, 1.7976931348623157e308, -1.7976931348623157e308,
              1e300, 1e-300, 5e-324, -0.0, 1e15, np.nan, np.inf, -np.inf]
    start = random_configurations(checker, 200, seed=int(rng.integers(1 << 30)))
    q = start[0]
    for _ in range(n):
        u = rng.random()
        if u < 0.25:
            q = start[rng.integers(len(start))].copy()
        else:
            q = q + rng.normal(0.0, 0.03, len(q))
        if rng.random() < 0.2:
            q = q.copy()
            for j in rng.choice(len(q), int(rng.integers(1, 4)), replace=False):
                q[j] = values[rng.integers(len(values))]
        yield q


@pytest.mark.parametrize('seed', [1, 2])
def test_update_equals_check_after_any_hostile_sequence(panda_urdf, panda_srdf,
                                                        erd_package_paths, seed):
    """Whatever values arrive, update() after them equals a fresh check(): both refuse the
    same states (nothing changes then), and both give the same pairs for every other state,
    absurd ones included. Before the fix, a NaN in a pair's travel bound (an infinite motion
    times a zero reach) let the pair through unchecked, and a huge motion added to a running
    sum and taken away again cancelled the small terms beside it."""
    incremental = _panda_with_scene(panda_urdf, panda_srdf, erd_package_paths)
    scratch = _panda_with_scene(panda_urdf, panda_srdf, erd_package_paths)
    rng = np.random.default_rng(seed)
    refused = accepted_absurd = 0
    for q in _hostile_walk(incremental, 3000, rng):
        before = incremental.positions
        try:
            got = incremental.update(q).colliding_pairs
        except JointStateError:
            got = None
            assert incremental.positions == before
        try:
            expected = scratch.check(q).colliding_pairs
        except JointStateError:
            expected = None
        assert got == expected, list(q)
        refused += got is None
        accepted_absurd += got is not None and not np.all(np.abs(q) < 1e3)
    assert refused > 100 and accepted_absurd > 100


def test_joints_not_given_keep_their_last_value(panda):
    panda.check({name: 0.0 for name in panda.joint_names})
    panda.update({'panda_joint4': -2.0})
    panda.update({'panda_joint2': 0.5})
    assert panda.positions['panda_joint4'] == -2.0
    assert panda.positions['panda_joint2'] == 0.5


def test_exception_list_from_srdf_adjacency_and_config(panda_urdf, panda_srdf,
                                                       erd_package_paths):
    plain = CollisionChecker.from_urdf(panda_urdf, package_paths=erd_package_paths)
    # Adjacent through a link without geometry: link7 -> link8 (none) -> hand.
    assert plain.excluded_pairs[('panda_hand', 'panda_link7')] == 'adjacent'
    assert ('panda_hand', 'panda_link7') not in plain.checked_pairs
    assert ('panda_leftfinger', 'panda_rightfinger') in plain.checked_pairs
    with_srdf = CollisionChecker.from_urdf(
        panda_urdf, srdf=panda_srdf, package_paths=erd_package_paths,
        config={'allowed_collisions': ['panda_link0:panda_link6']})
    assert ('panda_leftfinger', 'panda_rightfinger') not in with_srdf.checked_pairs
    assert with_srdf.excluded_pairs[('panda_link0', 'panda_link6')] == 'allowed_collisions'
    no_adjacent = CollisionChecker.from_urdf(panda_urdf, package_paths=erd_package_paths,
                                             config={'ignore_adjacent': False})
    assert ('panda_hand', 'panda_link7') in no_adjacent.checked_pairs
    assert list(with_srdf.checked_pairs) == sorted(with_srdf.checked_pairs)
    assert all(a < b for a, b in with_srdf.checked_pairs)


def test_unknown_name_in_allowed_collisions_is_kept_for_an_object_to_come(
        panda_urdf, erd_package_paths):
    """Issue 28: allowed_collisions may name a scene object that arrives later; the name is
    kept, warned about (with the closest link: a typo shows) and listed until it exists."""
    from collision_sensor import LoadWarning
    with pytest.warns(LoadWarning, match='"table" is neither a link of robot .* if you meant '
                      'the link "panda_'):
        checker = CollisionChecker.from_urdf(
            panda_urdf, package_paths=erd_package_paths,
            config={'allowed_collisions': ['panda_link0:table', 'panda_link1:table']})
    assert checker.pending_allowed_names == ('table',)
    assert any('"table"' in line for line in checker.load_warnings)
    table = SceneObject('table', 'box', np.eye(4), *box_mesh(np.array([1.0, 1.0, 0.1])))
    checker.add_object(table)
    assert checker.pending_allowed_names == ()
    assert ('panda_link0', 'table') not in checker.checked_pairs
    assert ('panda_link1', 'table') not in checker.checked_pairs
    assert ('panda_link2', 'table') in checker.checked_pairs
    with pytest.raises(ConfigError, match='link_a:link_b'):
        CollisionChecker.from_urdf(panda_urdf, package_paths=erd_package_paths,
                                   config={'allowed_collisions': ['panda_link1']})


def test_bad_settings_are_errors_naming_the_setting(panda_urdf, erd_package_paths):
    for config, culprit in [({'box_test': 'fast'}, 'box_test'),
                            ({'expansion': 'random'}, 'expansion'),
                            ({'motion_tolerance': -1}, 'motion_tolerance'),
                            ({'leaf_size': 0}, 'leaf_size'),
                            ({'colour': 'red'}, 'colour')]:
        with pytest.raises(ConfigError, match=culprit):
            CollisionChecker.from_urdf(panda_urdf, package_paths=erd_package_paths,
                                       config=config)


def test_collision_boxes_contain_their_geometry(panda):
    q = random_configurations(panda, 1, seed=13)[0]
    panda.check(q)
    poses = panda.link_poses()
    boxes = panda.collision_boxes(['panda_link3', 'panda_leftfinger', 'no_such_link'])
    assert len(boxes) == 1 + 4
    elements = [e for e in panda.model.elements
                if e.link in ('panda_link3', 'panda_leftfinger')]
    for (name, T_world_box, half), element in zip(boxes, elements):
        T = poses[element.link] @ element.T_link_element
        world = element.vertices @ T[:3, :3].T + T[:3, 3]
        local = (world - T_world_box[:3, 3]) @ T_world_box[:3, :3]
        assert np.all(np.abs(local) <= half + 1e-9)


# ---------------------------------------------------------------- clearance skip (update)

def _clearances(checker):
    return checker.packed_array('clearance')


def test_clearance_bounds_never_exceed_the_true_distance(panda, panda_urdf):
    """update skips a pair while its motion bound stays below the clearance it recorded; that
    is exact only if the clearance is a lower bound of the distance (python-fcl distance)."""
    import fcl
    oracle = FclOracle(panda, panda_urdf)
    clearance = _clearances(panda)
    compared = 0
    for q in random_configurations(panda, 150, seed=14):
        panda.check(q + 0.01)
        panda.update(q)  # re-checks incrementally, recording clearances
        poses = oracle.poses(q)
        for p, (a, b) in enumerate(panda.checked_pairs):
            if clearance[p] <= 0.0:
                continue
            distance = np.inf
            for ma in oracle.models[a]:
                for mb in oracle.models[b]:
                    objects = [fcl.CollisionObject(m, fcl.Transform(poses[n][:3, :3],
                                                                    poses[n][:3, 3]))
                               for m, n in ((ma, a), (mb, b))]
                    distance = min(distance, fcl.distance(
                        objects[0], objects[1], fcl.DistanceRequest(), fcl.DistanceResult()))
            assert clearance[p] <= distance + 1e-9, (list(q), a, b, clearance[p], distance)
            compared += 1
    assert compared > 500


def test_small_motions_skip_pairs_that_stay_apart(panda):
    rechecked, pairs = 0, 0
    for q in random_configurations(panda, 20, seed=15):
        panda.check(q)
        q = q + 1e-3
        panda.update(q)  # records clearances for every re-checked pair
        for k in range(1, 10):
            result = panda.update(q + k * 1e-5)
            # A colliding pair is always re-checked (its witness first); most others are not.
            assert result.rechecked_pairs >= len(result.colliding_pairs)
            rechecked += result.rechecked_pairs
            pairs += len(panda.checked_pairs)
    assert rechecked < 0.25 * pairs


@pytest.mark.slow
def test_subtree_volumes_cull_scene_objects_without_changing_answers(
        panda_urdf, panda_srdf, erd_package_paths):
    """Volumes spanning several links (each link's subtree) cull scene objects before any pair
    is looked at; the answers must stay python-fcl's."""
    scene = {'objects': [
        {'name': 'pedestal', 'box': {'size': [0.3, 0.3, 0.3]}, 'pose': {'xyz': [0.25, 0.0, 0.1]}},
        {'name': 'shelf', 'box': {'size': [0.4, 0.8, 0.03]}, 'pose': {'xyz': [0.55, 0.0, 0.5]}},
    ]}
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths, scene=scene)
    oracle = FclOracle(checker, panda_urdf)
    culled = checker.packed_array('scene_culled')
    below_root_only = 0
    for q in random_configurations(checker, 1500, seed=16):
        assert checker.check(q).colliding_pairs == oracle.colliding_pairs(q), list(q)
        # The root volume meets the object, yet some subtree's volume misses it.
        below_root_only += int(((culled[:, 0] == 0)[:, None] & (culled[:, 1:] == 1)).any())
    assert below_root_only > 100


@pytest.mark.slow
@pytest.mark.parametrize('box_test', ['sat', 'paper'])
def test_update_from_fronts_equals_check_in_near_contact(tmp_path, box_test):
    """Pairs hovering in near contact are re-checked from their fronts (the node pairs where
    their last proof stopped, each kept untested while the motion since cannot have closed
    its gap). The demo arm's benchmark stream (seed 1998) starts folded, its shoulder and
    wrist hubs parallel and a few mm apart, and the washer is near; two more streams follow
    without a full check between, so fronts recorded in one place are used in another.
    Every row must equal the from-scratch answer, and fronts must really have been used."""
    from collision_sensor.engine.traversal import COUNT_FRONT_STARTS, COUNT_FRONT_UNTESTED
    from benchmarks.robot_peers import stream
    from benchmarks.scenario_cells import demo_arm_cell
    cell = demo_arm_cell(str(tmp_path))
    incremental = cell.checker(config={'box_test': box_test})
    scratch = cell.checker(config={'box_test': box_test})
    path = np.vstack([stream(incremental, 2000, 1, 1998), stream(incremental, 600, 1, 1),
                      stream(incremental, 600, 3, 3)])
    incremental.check(path[0])
    incremental.counters[:] = 0
    got = incremental.update_batch(path)
    expected = scratch.check_batch(path)
    wrong = np.flatnonzero((got != expected).any(axis=1))
    assert not len(wrong), f'{len(wrong)} rows differ, first {wrong[:5]}: {list(path[wrong[0]])}'
    assert 5 < len({tuple(row) for row in expected})  # in and out of contact
    assert incremental.counters[COUNT_FRONT_STARTS] > 200
    assert incremental.counters[COUNT_FRONT_UNTESTED] > 10_000


# ---------------------------------------------------------------- SRDF virtual joints

def _virtual_srdf(kind, parent='odom'):
    return (f'<robot name="small"><virtual_joint name="base_joint" type="{kind}" '
            f'parent_frame="{parent}" child_link="base"/></robot>')


def _small_on_a_base(kind, **config):
    settings = {'primitive_sections': 10, 'ignore_adjacent': False}
    settings.update(config)
    return CollisionChecker.from_urdf(SMALL_ROBOT, srdf=_virtual_srdf(kind), scene=SMALL_SCENE,
                                      config=settings)


def _base_configurations(checker, n, rng):
    """Random configurations whose base variables place the robot around the scene: any
    heading, quaternions of any norm."""
    Q = random_configurations(checker, n, seed=int(rng.integers(1 << 30)))
    for j, name in enumerate(checker.joint_names):
        if name.endswith(('/x', '/y', '/trans_x', '/trans_y')):
            Q[:, j] = rng.uniform(-0.5, 0.5, n)
        elif name.endswith('/trans_z'):
            Q[:, j] = rng.uniform(-0.2, 0.3, n)
        elif '/rot_' in name:
            Q[:, j] = rng.normal(size=n) * (0.05 if name.endswith(('rot_x', 'rot_y')) else 1.0)
        elif name.endswith('/theta'):
            Q[:, j] = rng.uniform(-4, 4, n)
    return Q


@pytest.mark.parametrize('kind, variables', [
    ('floating', ('trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w')),
    ('planar', ('x', 'y', 'theta'))])
def test_a_virtual_joint_places_the_robot_in_the_world(kind, variables):
    checker = _small_on_a_base(kind)
    assert checker.joint_names[:len(variables)] == tuple(f'base_joint/{v}' for v in variables)
    assert checker.kinematics.link_names[:2] == ('odom', 'base')
    assert checker.model.root_link == 'odom' and 'odom' not in checker.link_names
    # Self-collision pairs do not depend on the base, robot-vs-scene pairs do.
    scene = checker._scene
    path = pair_rows(scene.tree(), scene.radius, scene.pair_a, scene.pair_b,
                     len(checker.joint_names))[0]
    for p, pair in enumerate(checker.checked_pairs):
        on_scene = bool(set(pair) & set(checker.scene_object_names))
        assert path[p, :len(variables)].all() == on_scene, pair
    # Neutral start: the quaternion is the identity, so a partial mapping is usable.
    assert checker.positions.get('base_joint/rot_w', 1.0) == 1.0
    checker.check({'shoulder': 0.1})


@pytest.mark.parametrize('kind', ['floating', 'planar'])
def test_robot_on_a_moving_base_matches_fcl_and_pinocchio(kind, tmp_path):
    """Link poses against pinocchio with its own root joint (free flyer, planar), verdicts
    against python-fcl on the same triangles placed by pinocchio, the scene in the world."""
    checker = _small_on_a_base(kind)
    urdf = tmp_path / 'small.urdf'
    urdf.write_text(SMALL_ROBOT)
    oracle = FclOracle(checker, str(urdf))
    assert oracle.pin_model.joints[1].nq == {'floating': 7, 'planar': 4}[kind]
    rng = np.random.default_rng(11)
    seen_scene_hits = set()
    for q in _base_configurations(checker, 300, rng):
        result = checker.check(q)
        poses, theirs = checker.link_poses(), oracle.poses(q)
        for link in checker.link_names:
            assert np.abs(poses[link] - theirs[link]).max() < 1e-9, (link, list(q))
        assert result.colliding_pairs == oracle.colliding_pairs(q), list(q)
        seen_scene_hits.update(pair for pair in result.colliding_pairs
                               if set(pair) & set(checker.scene_object_names))
    assert len(seen_scene_hits) >= 3   # the base really took the robot into the scene


@pytest.mark.parametrize('kind', ['floating', 'planar'])
@pytest.mark.parametrize('mode', ['base', 'mixed'])
def test_update_equals_check_when_the_base_moves(kind, mode):
    incremental = _small_on_a_base(kind)
    scratch = _small_on_a_base(kind)
    rng = np.random.default_rng(21 + len(mode) + len(kind))
    n_base = 7 if kind == 'floating' else 3
    q = _base_configurations(incremental, 1, rng)[0]
    changes, skipped, previous = 0, 0, None
    n_self = sum(not set(pair) & set(incremental.scene_object_names)
                 for pair in incremental.checked_pairs)
    for step in range(2000):
        choice = rng.integers(5)
        if mode == 'base' or choice == 0:      # one base variable, small or large
            j = rng.integers(n_base)
            q[j] += rng.normal(0.0, 0.02 if rng.random() < 0.8 else 0.5)
        elif choice == 1:
            q = _base_configurations(incremental, 1, rng)[0]   # a jump
        elif choice == 2:
            q[n_base + rng.integers(len(q) - n_base)] += rng.normal(0.0, 0.05)
        elif choice == 3:
            q[:n_base] += rng.normal(0.0, 0.01, n_base)
        q[:2] = np.clip(q[:2], -0.6, 0.6)   # x, y: the base stays around the scene
        if kind == 'floating':
            q[2] = np.clip(q[2], -0.3, 0.4)
            if not np.any(q[3:7]):
                q[6] = 1.0
        got = incremental.update(q)
        expected = scratch.check(q)
        assert got.colliding_pairs == expected.colliding_pairs, (step, list(q))
        changes += got.colliding_pairs != previous
        if mode == 'base' and step > 0:
            # a base motion re-checks robot-vs-scene pairs only
            assert got.rechecked_pairs <= len(incremental.checked_pairs) - n_self
        skipped += got.rechecked_pairs < len(incremental.checked_pairs)
        previous = got.colliding_pairs
    assert changes > 5 and skipped > 100


def test_a_zero_quaternion_is_refused_and_changes_nothing():
    checker = _small_on_a_base('floating')
    q = checker.kinematics.neutral()
    q[0] = 0.3
    before = checker.check(q)
    for bad in ([0.0, 0.0, 0.0, 0.0], [1e-120, 0.0, -1e-120, 0.0]):
        q_bad = q.copy()
        q_bad[3:7] = bad
        for call in (checker.check, checker.update):
            with pytest.raises(JointStateError, match='floating joint "base_joint": quaternion '
                                                      r'\(rot_x, rot_y, rot_z, rot_w\) = .* is '
                                                      'zero .*send a unit quaternion'):
                call(q_bad)
        with pytest.raises(JointStateError, match='configuration 1, floating joint '
                                                  '"base_joint": quaternion'):
            checker.check_batch(np.stack([q, q_bad]))
    with pytest.raises(JointStateError, match='joint "base_joint/trans_y": position 2000000.0 '
                                              'moves a joint out of the engine'):
        checker.update({'base_joint/trans_y': 2e6})
    assert checker.positions == dict(zip(checker.joint_names, q))
    assert checker.update(q) == before._replace(rechecked_pairs=0)
    # Any non-zero quaternion is normalised: a scaled one gives the same poses.
    q[3:7] = [0.1, -0.2, 0.3, 0.9]
    checker.check(q)
    poses = checker.link_poses()
    q[3:7] *= 1e-50
    checker.check(q)
    for name, T in checker.link_poses().items():
        assert np.allclose(T, poses[name], atol=1e-12), name


def test_a_fixed_virtual_joint_changes_nothing():
    plain = CollisionChecker.from_urdf(SMALL_ROBOT, scene=SMALL_SCENE)
    fixed = CollisionChecker.from_urdf(SMALL_ROBOT, srdf=_virtual_srdf('fixed', 'world'),
                                       scene=SMALL_SCENE)
    assert fixed.joint_names == plain.joint_names
    assert fixed.kinematics.link_names == plain.kinematics.link_names


def test_a_virtual_joint_parent_frame_that_is_a_link_is_an_error():
    from collision_sensor import SrdfError
    with pytest.raises(SrdfError, match='parent_frame "upper", which is a link of the robot'):
        CollisionChecker.from_urdf(SMALL_ROBOT, srdf=_virtual_srdf('planar', 'upper'))


MID_TREE_MULTI_DOF = SMALL_ROBOT.replace(
    '<joint name="extend" type="prismatic">', '<joint name="extend" type="floating">').replace(
    '<joint name="elbow" type="continuous">', '<joint name="elbow" type="planar">')


@pytest.mark.filterwarnings('ignore::collision_sensor.errors.LoadWarning')   # elbow's axis
@pytest.mark.parametrize('urdf, srdf', [
    (SMALL_ROBOT, _virtual_srdf('floating')), (SMALL_ROBOT, _virtual_srdf('planar')),
    (MID_TREE_MULTI_DOF, None), (MID_TREE_MULTI_DOF, _virtual_srdf('planar'))])
def test_reach_bounds_how_far_each_variable_moves_a_pair(urdf, srdf):
    """pair_reach.pair_rows: moving variable j by d moves no vertex of either body by more than
    |d| (reach + reach_ext E) relative to the other, measured on the triangles."""
    checker = CollisionChecker.from_urdf(urdf, srdf=srdf, scene=SMALL_SCENE,
                                         config={'primitive_sections': 8,
                                                 'ignore_adjacent': False})
    reach, reach_ext = checker.packed_array('reach'), checker.packed_array('reach_ext')
    kin = checker.kinematics
    vertices = {}
    for element in checker.model.elements:
        T = element.T_link_element
        vertices.setdefault(element.link, []).append(element.vertices @ T[:3, :3].T + T[:3, 3])
    vertices = {name: np.concatenate(v) for name, v in vertices.items()}
    rng = np.random.default_rng(5)
    for q in _base_configurations(checker, 30, rng):
        extension = sum(abs(q[kin.q_index[i]]) for i in range(len(kin.link_names))
                        if kin.joint_type[i] == 2)
        T0 = checker.kinematics.forward_kinematics(q)
        for j in range(len(q)):
            d = rng.choice([1e-3, -0.05, 0.3])
            moved = q.copy()
            moved[j] += d
            T1 = checker.kinematics.forward_kinematics(moved)
            for p, (a, b) in enumerate(checker.checked_pairs):
                if b in checker.scene_object_names or a in checker.scene_object_names:
                    link = a if b in checker.scene_object_names else b
                    i = kin.link_names.index(link)
                    rel0, rel1, points = T0[i], T1[i], vertices[link]
                    shift = np.linalg.norm((points @ (rel1 - rel0)[:3, :3].T
                                            + (rel1 - rel0)[:3, 3]), axis=1).max()
                else:   # both bodies' vertices, in their common ancestor's frame
                    ia, ib = kin.link_names.index(a), kin.link_names.index(b)
                    above = _ancestors(kin, ia)
                    common = next(k for k in _ancestors(kin, ib) if k in above)
                    shift = 0.0
                    for x in (a, b):
                        ix = kin.link_names.index(x)
                        delta = (np.linalg.inv(T1[common]) @ T1[ix]
                                 - np.linalg.inv(T0[common]) @ T0[ix])
                        shift += np.linalg.norm(
                            vertices[x] @ delta[:3, :3].T + delta[:3, 3], axis=1).max()
                bound = abs(d) * (reach[p, j] + reach_ext[p, j] * extension)
                assert shift <= bound + 1e-9, (checker.checked_pairs[p], kin.joint_names[j],
                                               shift, bound)
    assert np.isfinite(reach).all()   # never inf: inf * 0 would be NaN
    assert (reach.max() == 1e300) == any('/rot_' in name for name in kin.joint_names)


def _ancestors(kin, i):
    chain = [i]
    while kin.parent[chain[-1]] >= 0:
        chain.append(int(kin.parent[chain[-1]]))
    return chain


@pytest.mark.filterwarnings('ignore::collision_sensor.errors.LoadWarning')   # elbow's axis
def test_update_equals_check_with_multi_dof_joints_inside_the_tree():
    """A planar elbow under a revolute shoulder, a floating joint under it: every variable
    moves, one at a time, several at once, or by jumps."""
    settings = {'primitive_sections': 8, 'ignore_adjacent': False}
    incremental, scratch = (CollisionChecker.from_urdf(MID_TREE_MULTI_DOF, scene=SMALL_SCENE,
                                                       config=settings) for _ in range(2))
    names = incremental.joint_names
    rng = np.random.default_rng(17)
    q = incremental.kinematics.neutral()
    changes, skipped, previous = 0, 0, None
    for step in range(2000):
        choice = rng.integers(3)
        if choice == 0:
            q[rng.integers(len(q))] += rng.normal(0.0, 0.03)
        elif choice == 1:
            q += rng.normal(0.0, 0.01, len(q))
        else:
            q = rng.uniform(-0.3, 0.3, len(q))
            q[names.index('shoulder')] = rng.uniform(-2.5, 2.5)
            q[names.index('elbow/theta')] = rng.uniform(-4, 4)
        translations = [j for j, name in enumerate(names) if '/trans_' in name
                        or name.endswith(('/x', '/y'))]
        q[translations] = np.clip(q[translations], -0.3, 0.3)
        if not np.any(q[names.index('extend/rot_x'):names.index('extend/rot_w') + 1]):
            q[names.index('extend/rot_w')] = 1.0
        got, expected = incremental.update(q), scratch.check(q)
        assert got.colliding_pairs == expected.colliding_pairs, (step, list(q))
        changes += got.colliding_pairs != previous
        skipped += got.rechecked_pairs < len(incremental.checked_pairs)
        previous = got.colliding_pairs
    assert changes > 5 and skipped > 100
