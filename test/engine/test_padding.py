"""Link padding (``padding``, ``link_padding``) against python-fcl distances on the same meshes.

A padded pair is in contact iff fcl's distance between the unpadded meshes is at most the sum
of the two paddings (or the meshes meet, or one lies in the other's solid primitive);
``proximity`` reports fcl's distance minus that sum, with points on the padded surfaces. The
incremental check with padding must equal a fresh check at every step of a coherent walk.
"""
import math

import numpy as np
import pytest

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.errors import ConfigError
from engine_oracles import FclOracle, distance_to_body

N_CONFIGURATIONS = 120
#: Distances agree with fcl's to this (m); pairs this near their padding sum are not judged.
FCL_TOLERANCE = 1e-6
SCENE = {'objects': [
    {'name': 'table', 'box': {'size': [0.8, 1.2, 0.04]},
     'pose': {'xyz': [0.55, 0.0, 0.3], 'rpy': [0.1, 0.0, 0.2]}},
    {'name': 'ball', 'sphere': {'radius': 0.12}, 'pose': {'xyz': [0.3, -0.3, 0.7]}},
]}
PANDA_PADDING = {'padding': 0.01, 'link_padding': {'panda_hand': 0.03, 'panda_link7': 0.0,
                                                   'panda_link3': 0.05}}
UR5_PADDING = {'padding': 0.02, 'link_padding': {'wrist_3_link': 0.04}}


def _paddings(checker):
    """{body: metres} from the configuration alone (scene objects 0), to check
    ``checker.paddings`` against."""
    link_padding = dict(checker.config.link_padding)
    return {name: (0.0 if name in checker.scene_object_names
                   else link_padding.get(name, checker.config.padding))
            for name in checker.link_names + checker.scene_object_names}


@pytest.fixture(scope='module')
def panda_builder(panda_urdf, panda_srdf, erd_package_paths):
    return lambda: CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                              package_paths=erd_package_paths, scene=SCENE,
                                              config=PANDA_PADDING)


@pytest.fixture(scope='module')
def ur5_builder(ur5_urdf, ur5_srdf, erd_package_paths):
    return lambda: CollisionChecker.from_urdf(ur5_urdf, srdf=ur5_srdf,
                                              package_paths=erd_package_paths,
                                              config=UR5_PADDING)


@pytest.fixture(scope='module')
def panda(panda_builder, panda_urdf):
    checker = panda_builder()
    return checker, FclOracle(checker, panda_urdf)


@pytest.fixture(scope='module')
def ur5(ur5_builder, ur5_urdf):
    checker = ur5_builder()
    return checker, FclOracle(checker, ur5_urdf)


def _agree_with_fcl(checker, oracle, seed):
    """Contact iff fcl distance <= padding sum; proximity == fcl distance - padding sum."""
    padding = _paddings(checker)
    assert checker.paddings == padding
    judged = padded_only = 0
    for k, q in enumerate(random_configurations(checker, N_CONFIGURATIONS, seed)):
        colliding = set(checker.check(q).colliding_pairs)
        records = {(r.link_a, r.link_b): r for r in checker.proximity(q, math.inf)}
        assert {pair for pair, r in records.items() if r.distance <= 0} == colliding, k
        poses = oracle.poses(q)
        for a, b in checker.checked_pairs:
            pad = padding[a] + padding[b]
            theirs = oracle.pair_distance(poses, a, b)
            if theirs <= 0 or oracle.contains(poses, a, b):
                assert (a, b) in colliding, (k, a, b)   # the meshes meet, or one is inside
                continue
            if abs(theirs - pad) < FCL_TOLERANCE:
                continue   # at the padding's edge: either answer is within rounding
            judged += 1
            assert ((a, b) in colliding) == (theirs < pad), (k, a, b, theirs, pad)
            padded_only += theirs < pad
            r = records[a, b]
            assert r.distance == pytest.approx(theirs - pad, abs=FCL_TOLERANCE), (k, a, b)
            _assert_padded_points(checker, r, padding)
    assert judged > 0 and padded_only > 0


def _assert_padded_points(checker, r, padding):
    """Apart: points on the padded surfaces, ``distance`` apart. In contact: one point, within
    each body's padding of it."""
    pad_a, pad_b = padding[r.link_a], padding[r.link_b]
    to_a = distance_to_body(checker, r.point_a, r.link_a)
    to_b = distance_to_body(checker, r.point_b, r.link_b)
    if r.distance > 0:
        assert np.linalg.norm(r.point_b - r.point_a) == pytest.approx(r.distance, abs=1e-9)
        assert to_a == pytest.approx(pad_a, abs=1e-9) and to_b == pytest.approx(pad_b, abs=1e-9)
    else:
        np.testing.assert_array_equal(r.point_a, r.point_b)
        assert to_a <= pad_a + 1e-9 and to_b <= pad_b + 1e-9, r


@pytest.mark.slow
def test_panda_padded_contact_and_distances_agree_with_fcl(panda):
    _agree_with_fcl(*panda, seed=21)


@pytest.mark.slow
def test_ur5_padded_contact_and_distances_agree_with_fcl(ur5):
    _agree_with_fcl(*ur5, seed=22)


@pytest.mark.parametrize('robot, seed', [('panda', 23), ('ur5', 24)])
def test_incremental_update_equals_a_fresh_check_with_padding(robot, seed, request):
    """A coherent walk (small steps, some joints at a time) through padded near-contacts:
    ``update`` carries clearances and fronts measured against the padded distance; every step
    must answer as a second checker that checks from scratch."""
    build = request.getfixturevalue(f'{robot}_builder')
    incremental, fresh = build(), build()
    lower, upper = sampling_bounds(incremental)
    rng = np.random.default_rng(seed)
    q = random_configurations(incremental, 1, seed)[0]
    contacts = 0
    for step in range(1500):
        moving = rng.random(len(q)) < 0.5
        q = np.clip(q + moving * rng.normal(scale=0.03, size=len(q)), lower, upper)
        pairs = incremental.update(q).colliding_pairs
        assert pairs == fresh.check(q).colliding_pairs, step
        contacts += bool(pairs)
        if step % 100 == 99:   # now and then a jump, as a replay's seek
            q = random_configurations(incremental, 1, seed + step)[0]
    assert contacts > 0
    assert incremental.counters[3] > 0   # re-checks started from fronts: the carried state


def test_padding_grows_the_boxes_by_the_padding(panda, panda_urdf, panda_srdf,
                                                 erd_package_paths):
    checker, _ = panda
    bare = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths=erd_package_paths, scene=SCENE)
    padding = _paddings(checker)
    names = list(checker.link_names) + list(checker.scene_object_names)
    for (name, _, half), (_, _, bare_half) in zip(checker.collision_boxes(names),
                                                  bare.collision_boxes(names)):
        np.testing.assert_allclose(half, bare_half + padding[name], atol=1e-12)


def test_zero_padding_is_no_padding(panda_urdf, panda_srdf, erd_package_paths):
    kwargs = dict(srdf=panda_srdf, package_paths=erd_package_paths)
    bare = CollisionChecker.from_urdf(panda_urdf, **kwargs)
    zero = CollisionChecker.from_urdf(panda_urdf, config={'padding': 0.0}, **kwargs)
    for q in random_configurations(bare, 40, 25):
        assert bare.check(q) == zero.check(q)
        ours, theirs = bare.proximity(q, math.inf), zero.proximity(q, math.inf)
        assert [r[:3] for r in ours] == [r[:3] for r in theirs]


@pytest.mark.parametrize('config, message', [
    ({'padding': -0.01}, 'setting padding'),
    ({'padding': math.nan}, 'setting padding'),
    ({'padding': True}, 'setting padding'),
    ({'link_padding': ['panda_hand']}, 'expected a mapping'),
    ({'link_padding': {'panda_hand': -1.0}}, 'link_padding[panda_hand]'),
    ({'link_padding': {'panda_hand': math.inf}}, 'link_padding[panda_hand]'),
    ({'link_padding': {'no_such_link': 0.01}}, '"no_such_link" is not a link of robot'),
    ({'link_padding': {'table': 0.01}}, 'is a scene object'),
])
def test_bad_padding_is_refused_naming_the_setting(config, message, panda_urdf, panda_srdf,
                                                   erd_package_paths):
    with pytest.raises(ConfigError) as error:
        CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf, package_paths=erd_package_paths,
                                   scene=SCENE, config=config)
    assert message in str(error.value)
