"""Scene changes while the checker runs (collision_sensor.engine.dynamic_scene), against oracles.

* random sequences of scene edits (world and attached objects of every shape: added,
  replaced, moved, attached, detached, removed) mixed with joint motion: every ``update``
  equals a checker built from scratch with the final scene, and python-fcl (with pinocchio's
  kinematics and each object's own triangles and primitive) on pairs derived here from the
  rules, independently of the checker;
* the costs the module promises: a move re-checks that object's pairs only, an add builds
  only its own tree;
* all or nothing: a batch with one bad change leaves the checker as it was.
"""
import numpy as np
import pytest

import collision_sensor.engine.dynamic_scene as dynamic_scene
from collision_sensor import CollisionChecker
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import (
    AddObject, MoveObject, RemoveObject, checked_pose, transform_from_xyz_quaternion)
from collision_sensor.engine.sampling import random_configurations, sampling_bounds
from collision_sensor.errors import SceneError
from collision_sensor.model.mesh_loading import (
    box_mesh, box_solid, cylinder_mesh, cylinder_solid, sphere_mesh, sphere_solid)
from collision_sensor.model.robot_model import load_urdf, transform_from_xyz_rpy
from collision_sensor.model.scene import SceneObject
from engine_oracles import FclOracle, SceneOracle
from small_robot import SMALL_ROBOT

SETTINGS = {'primitive_sections': 8, 'ignore_adjacent': False}


def _random_pose(rng, spread):
    rpy = rng.uniform(-np.pi, np.pi, 3)
    return transform_from_xyz_rpy(rng.uniform(-spread, spread, 3), rpy)


def _random_object(rng, name):
    """An object of a random kind: box, sphere, cylinder (solid primitives), a closed mesh
    without a solid (a surface) or a soup of loose triangles."""
    kind = rng.integers(5)
    size = rng.uniform(0.03, 0.25, 3)
    if kind == 0:
        (vertices, faces), solid = box_mesh(size), box_solid(size)
    elif kind == 1:
        (vertices, faces), solid = sphere_mesh(size[0], 8), sphere_solid(size[0])
    elif kind == 2:
        (vertices, faces), solid = (cylinder_mesh(size[0], 2 * size[1], 8),
                                    cylinder_solid(size[0], 2 * size[1]))
    elif kind == 3:
        (vertices, faces), solid = sphere_mesh(size[0], 6), None
    else:
        n = int(rng.integers(1, 12))
        vertices = rng.uniform(-0.2, 0.2, (3 * n, 3))
        faces, solid = np.arange(3 * n).reshape(-1, 3), None
    return SceneObject(name=name, source='test', T_world_object=np.eye(4),
                       vertices=np.ascontiguousarray(vertices, dtype=np.float64),
                       faces=np.asarray(faces, dtype=np.int64), solid=solid)


def _from_scratch(model, oracle, q):
    checker = CollisionChecker(model, config=SETTINGS)
    checker.apply_scene_changes(oracle.changes_from_scratch())
    return checker.check(q)


def _random_edit(rng, oracle, links, counter):
    """One random change the scene can take (or a batch of a few)."""
    names = list(oracle.objects)
    choice = rng.integers(8) if names else 0
    if choice <= 1 or len(names) < 2:
        counter[0] += 1
        attach = rng.random() < 0.4
        link = links[rng.integers(len(links))] if attach else None
        # Touch links for world objects too (a table under the base).
        touch = tuple(str(t) for t in rng.choice(links, size=int(rng.integers(3)),
                                                 replace=False))
        return AddObject(_random_object(rng, f'obj{counter[0]}'), link, touch,
                         _random_pose(rng, 0.25 if attach else 0.7))
    name = names[rng.integers(len(names))]
    obj, link, touch, pose = oracle.objects[name]
    if choice == 2:
        return RemoveObject(name)
    if choice == 3:  # replaced: another shape under the same name
        return AddObject(_random_object(rng, name), link, touch, pose)
    if choice == 4:  # the same geometry again: only a move
        return AddObject(obj, link, touch, _random_pose(rng, 0.7 if link is None else 0.25))
    if choice == 5:  # attached, or detached, or moved to another link
        new_link = None if link is not None and rng.random() < 0.5 else links[
            rng.integers(len(links))]
        return AddObject(obj, new_link, (), _random_pose(rng, 0.25 if new_link else 0.7))
    small = pose.copy()   # a small move: the pairs stay near where they were
    small[:3, 3] += rng.normal(0.0, 0.02, 3)
    return MoveObject(name, small if choice == 6 else _random_pose(
        rng, 0.7 if link is None else 0.25))


# Seeds 5 and 11 failed before the test vertex was the element's own (it was the first of the
# tree's order, which moved with the box fit) and before root boxes held the true solids.
@pytest.mark.slow
@pytest.mark.parametrize('seed', [1, 2, 5, 11])
def test_random_scene_edits_and_motion_match_scratch_and_fcl(seed):
    model = load_urdf(SMALL_ROBOT, primitive_sections=SETTINGS['primitive_sections'])
    checker = CollisionChecker(model, config=SETTINGS)
    oracle = SceneOracle(SMALL_ROBOT, SETTINGS)
    # Links with and without geometry; the root link is the world (objects on it are fixed).
    links = list(checker.kinematics.link_names[1:])
    lower, upper = sampling_bounds(checker)
    rng = np.random.default_rng(seed)
    q = random_configurations(checker, 1, seed)[0]
    counter = [0]
    seen_attached, seen_world, changes = set(), set(), 0
    previous = None
    for step in range(250):
        edits = []
        for _ in range(int(rng.integers(1, 4))):   # a batch, applied in order
            edits.append(_random_edit(rng, oracle, links, counter))
            oracle.apply(edits[-1])
        if len(edits) == 1 and isinstance(edits[0], MoveObject):
            checker.move_object(edits[0].name, edits[0].pose)    # its own way, in one call
        else:
            checker.apply_scene_changes(edits)
        if rng.random() < 0.7:
            q = np.clip(q + rng.normal(0.0, 0.05, len(q)) * (rng.random() < 0.6), lower, upper)
        got = checker.check(q) if rng.random() < 0.1 else checker.update(q)
        assert checker.checked_pairs == oracle.pairs(), step
        expected = oracle.colliding_pairs(q)
        assert got.colliding_pairs == expected, (step, list(q), edits)
        assert _from_scratch(model, oracle, q).colliding_pairs == expected, step
        for a, b in expected:
            for name in (a, b):
                if name in oracle.objects:
                    (seen_attached if oracle.objects[name][1] else seen_world).add(name)
        changes += got.colliding_pairs != previous
        previous = got.colliding_pairs
    # Both kinds of object collided, and the verdict changed often.
    assert len(seen_attached) > 3 and len(seen_world) > 3 and changes > 30


@pytest.fixture(scope='module')
def panda_model(panda_urdf, panda_srdf, erd_package_paths):
    return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                      package_paths=erd_package_paths)


def test_panda_walk_with_moving_and_attached_objects_matches_fcl(panda_model, panda_urdf,
                                                                 panda_srdf, erd_package_paths):
    """The Panda walks while a part is picked up (attached to the hand, touching the
    fingers), carried through a moving obstacle and dropped; every step against fcl."""
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    oracle = SceneOracle.__new__(SceneOracle)
    oracle.robot, oracle.fcl, oracle.objects = panda_model, FclOracle(panda_model,
                                                                      panda_urdf), {}
    rng = np.random.default_rng(3)
    part = SceneObject('part', 'test', np.eye(4), *box_mesh([0.15, 0.15, 0.15]),
                       box_solid([0.15, 0.15, 0.15]))
    obstacle = SceneObject('obstacle', 'test', np.eye(4), *box_mesh([0.3, 0.05, 0.6]),
                           box_solid([0.3, 0.05, 0.6]))
    table = SceneObject('table', 'test', transform_from_xyz_rpy([0.5, 0, 0.2], [0, 0, 0]),
                        *box_mesh([0.6, 1.0, 0.04]), box_solid([0.6, 1.0, 0.04]))
    lower, upper = sampling_bounds(checker)
    q = random_configurations(checker, 1, 3)[0]
    hits = set()
    for step in range(300):
        edits = []
        if step == 0:
            edits = [AddObject(table), AddObject(obstacle, pose=transform_from_xyz_rpy(
                [0.4, 0.3, 0.4], [0, 0, 0])), AddObject(part, pose=transform_from_xyz_rpy(
                    [0.5, 0.0, 0.25], [0, 0, 0]))]
        elif step == 60:   # picked up: held in the hand, touching the fingers
            edits = [AddObject(part, 'panda_hand', ('panda_leftfinger', 'panda_rightfinger'),
                               transform_from_xyz_rpy([0, 0, 0.1], [0, 0, 0]))]
        elif step == 61:
            assert {('panda_hand', 'part'), ('panda_leftfinger', 'part')} <= set(
                checker.excluded_pairs)
        elif step == 220:  # dropped where it is
            T = checker.link_poses()['part']
            edits = [AddObject(part, pose=T)]
        if step % 3 == 0:  # the obstacle sweeps back and forth
            edits.append(MoveObject('obstacle', transform_from_xyz_rpy(
                [0.4, 0.3 * np.cos(step / 20), 0.4], [0, 0, step / 30])))
        for edit in edits:
            oracle.apply(edit)
        checker.apply_scene_changes(edits)
        q = np.clip(q + rng.normal(0.0, 0.08, len(q)), lower, upper)
        got = checker.update(q)
        assert checker.checked_pairs == oracle.pairs()
        assert got.colliding_pairs == oracle.colliding_pairs(q), (step, list(q))
        hits.update(got.colliding_pairs)
    # The held part met the table (attached vs world), the arm (attached vs robot) and the
    # moving obstacle; the obstacle met the arm.
    assert {('part', 'table'), ('obstacle', 'part'), ('obstacle', 'panda_link5')} <= hits
    assert {('panda_link5', 'part'), ('panda_link6', 'part')} & hits


def _small_cell():
    checker = CollisionChecker.from_urdf(SMALL_ROBOT, config=SETTINGS)
    oracle = SceneOracle(SMALL_ROBOT, SETTINGS)
    return checker, oracle


def _apply(checker, oracle, changes):
    for change in changes:
        oracle.apply(change)
    checker.apply_scene_changes(changes)


def test_attach_and_detach_while_in_contact():
    """A block overlapping the tool: reported as a world object; attached to the tool it is
    no longer checked against it (but still against the other links); detached again at
    its world pose it is reported again; every verdict against fcl."""
    checker, oracle = _small_cell()
    q = np.zeros(len(checker.joint_names))
    checker.check(q)
    T_tool = checker.link_poses()['tool']
    block = SceneObject('block', 'test', T_tool, *box_mesh([0.08, 0.08, 0.08]),
                        box_solid([0.08, 0.08, 0.08]))
    _apply(checker, oracle, [AddObject(block)])
    got = checker.update(q)
    assert ('block', 'tool') in got.colliding_pairs
    assert got.colliding_pairs == oracle.colliding_pairs(q)
    # Attached in contact: the pair (block, tool) is excluded, not reported.
    _apply(checker, oracle, [AddObject(block, 'tool', pose=np.eye(4))])
    got = checker.update(q)
    assert ('block', 'tool') not in checker.checked_pairs
    assert checker.excluded_pairs[('block', 'tool')] == 'attached to tool'
    assert got.colliding_pairs == oracle.colliding_pairs(q)
    assert ('block', 'tool') not in got.colliding_pairs
    # It moves with the tool into the lower link's way, and into a world object.
    wall = SceneObject('wall', 'test', np.eye(4), *box_mesh([0.05, 1.0, 2.0]),
                       box_solid([0.05, 1.0, 2.0]))
    _apply(checker, oracle, [AddObject(wall, pose=transform_from_xyz_rpy([0.6, 0, 0.5],
                                                                          [0, 0, 0]))])
    for shoulder in np.linspace(0.0, 1.0, 50):
        q[checker.joint_names.index('shoulder')] = shoulder
        got = checker.update(q)
        assert got.colliding_pairs == oracle.colliding_pairs(q), shoulder
        if ('block', 'wall') in got.colliding_pairs:
            break
    assert ('block', 'wall') in got.colliding_pairs
    # Detached while touching the wall: world objects are not checked against each other.
    T_block = checker.link_poses()['block']
    _apply(checker, oracle, [AddObject(block, pose=T_block)])
    got = checker.update(q)
    assert ('block', 'wall') not in checker.checked_pairs
    assert ('block', 'tool') in got.colliding_pairs   # the tool still holds it: contact
    assert got.colliding_pairs == oracle.colliding_pairs(q)
    assert got.colliding_pairs == _scratch_of(checker, q).colliding_pairs


def test_a_move_rechecks_that_objects_pairs_only():
    checker, _ = _small_cell()
    rng = np.random.default_rng(4)
    for k in range(6):
        checker.add_object(_random_object(rng, f'o{k}'), pose=_random_pose(rng, 0.6))
    q = random_configurations(checker, 1, 4)[0]
    checker.check(q)
    assert checker.update(q).rechecked_pairs == 0
    checker.move_object('o3', _random_pose(rng, 0.6))
    own = sum('o3' in pair for pair in checker.checked_pairs)
    assert own == len(checker.link_names)
    assert checker.update(q).rechecked_pairs == own
    assert checker.update(q).rechecked_pairs == 0   # done once
    # A move and a joint motion together: the object's pairs and the joint's, once each.
    checker.move_object('o3', _random_pose(rng, 0.6))
    q2 = q.copy()
    q2[checker.joint_names.index('wrist')] += 0.5
    checker.move_object('o1', _random_pose(rng, 0.6))
    result = checker.update(q2)
    tool_pairs = {pair for pair in checker.checked_pairs if 'tool' in pair}
    expected = tool_pairs | {pair for pair in checker.checked_pairs if {'o1', 'o3'} & set(pair)}
    assert result.rechecked_pairs <= len(expected)
    assert result.colliding_pairs == _scratch_of(checker, q2).colliding_pairs


def _scratch_of(checker, q):
    """A new checker with the same robot and scene, checked from scratch."""
    fresh = CollisionChecker(checker.model, config=checker.config)
    fresh.apply_scene_changes([
        AddObject(obj, link[0] if link else None, link[1] if link else (),
                  checker.object_pose(obj.name))
        for obj, link in ((obj, checker.attachments.get(obj.name))
                          for obj in checker.scene_objects)])
    return fresh.check(q)


def test_adding_builds_only_the_new_objects_tree(monkeypatch, panda_urdf, panda_srdf,
                                                  erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    robot_boxes = checker.forest.center.copy()
    built = []
    original = dynamic_scene.build_forest

    def counting(meshes, **kwargs):
        built.append(sum(len(faces) for _, faces in meshes))
        return original(meshes, **kwargs)

    monkeypatch.setattr(dynamic_scene, 'build_forest', counting)
    vertices, faces = sphere_mesh(0.1, 16)
    checker.add_object(SceneObject('ball', 'test', np.eye(4), vertices, faces))
    assert built == [len(faces)]
    # The robot's nodes come first, unchanged; the new tree after them.
    np.testing.assert_array_equal(checker.forest.center[:len(robot_boxes)], robot_boxes)
    checker.move_object('ball', transform_from_xyz_rpy([0.3, 0, 0.3], [0, 0, 0]))
    checker.remove_object('ball')
    assert built == [len(faces)]   # moves and removals build nothing
    np.testing.assert_array_equal(checker.forest.center, robot_boxes)


def test_a_bad_batch_changes_nothing():
    checker, oracle = _small_cell()
    rng = np.random.default_rng(6)
    good = [AddObject(_random_object(rng, 'a'), pose=_random_pose(rng, 0.5)),
            AddObject(_random_object(rng, 'b'), 'tool', ('lower',), _random_pose(rng, 0.2))]
    _apply(checker, oracle, good)
    q = random_configurations(checker, 1, 6)[0]
    before = checker.update(q)
    pairs, names = checker.checked_pairs, checker.object_names
    pose_a = checker.object_pose('a')
    bad_batches = [
        [MoveObject('a', _random_pose(rng, 0.5)), AddObject(_random_object(rng, 'c'), 'nolink')],
        [RemoveObject('a'), RemoveObject('a')],
        [MoveObject('b', np.full((4, 4), np.nan))],
        [AddObject(_random_object(rng, 'tool'))],       # a link's name
        [AddObject(_random_object(rng, 'c'), 'tool', ('nolink',))],
        [AddObject(SceneObject('c', 't', np.eye(4), np.zeros((3, 3)),
                               np.zeros((0, 3), dtype=np.int64)))],
        [AddObject(SceneObject('c', 't', np.eye(4), np.full((3, 3), 1e9),
                               np.array([[0, 1, 2]])))],
        [MoveObject('a', np.diag([2.0, 1.0, 1.0, 1.0]))],   # not a rotation
        ['not a change'],
    ]
    for batch in bad_batches:
        with pytest.raises(SceneError):
            checker.apply_scene_changes(batch)
        assert checker.checked_pairs == pairs and checker.object_names == names
        np.testing.assert_array_equal(checker.object_pose('a'), pose_a)
        assert checker.update(q).colliding_pairs == before.colliding_pairs
    assert checker.update(q).colliding_pairs == oracle.colliding_pairs(q)


def test_prepared_changes_are_refused_once_the_scene_changed():
    checker, _ = _small_cell()
    rng = np.random.default_rng(7)
    prepared = checker.prepare_scene_changes([AddObject(_random_object(rng, 'a'))])
    assert checker.object_names == ()   # preparing changes nothing
    checker.add_object(_random_object(rng, 'b'))
    with pytest.raises(SceneError, match='prepare them again'):
        checker.commit_scene_changes(prepared)
    assert checker.object_names == ('b',)
    other, _ = _small_cell()
    with pytest.raises(SceneError):
        other.commit_scene_changes(checker.prepare_scene_changes([RemoveObject('b')]))
    # A move is a change too.
    prepared = checker.prepare_scene_changes([AddObject(_random_object(rng, 'c'))])
    checker.move_object('b', _random_pose(rng, 0.5))
    with pytest.raises(SceneError, match='prepare them again'):
        checker.commit_scene_changes(prepared)
    assert checker.object_names == ('b',)


@pytest.mark.parametrize('attached', [False, True])
def test_a_bad_move_is_named_as_checked_pose_names_it_and_changes_nothing(attached):
    """``move_object`` checks a world object's pose in the engine, an attached one's in
    Python: either way the message is :func:`checked_pose`'s and the scene stays."""
    checker, oracle = _small_cell()
    rng = np.random.default_rng(11)
    obj = _random_object(rng, 'box')
    change = AddObject(obj, 'tool' if attached else None, (), _random_pose(rng, 0.3))
    checker.apply_scene_changes([change])
    oracle.apply(change)
    q = random_configurations(checker, 1, 11)[0]
    expected = checker.check(q).colliding_pairs
    pose = checker.object_pose('box').copy()
    rotated = _random_pose(rng, 0.1)
    bad = [np.full((4, 4), np.nan), np.diag([2.0, 1.0, 1.0, 1.0]), np.eye(3), 'pose',
           [[1, 0, 0, 2e6], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
           np.vstack([rotated[:3], [0.0, 0.0, 0.1, 1.0]]),
           rotated @ np.diag([1.0, 1.0, -1.0, 1.0])]              # a reflection
    for value in bad:
        try:
            checked_pose(value, 'object "box"')
        except SceneError as error:
            message = str(error)
        else:
            raise AssertionError(f'checked_pose accepts {value!r}')
        with pytest.raises(SceneError) as raised:
            checker.move_object('box', value)
        assert str(raised.value) == message
        np.testing.assert_array_equal(checker.object_pose('box'), pose)
        assert checker.update(q).colliding_pairs == expected
    # Good poses in any array form: lists, other dtypes, views that are not contiguous.
    for value in (rotated.tolist(), rotated.astype(np.float32).astype(np.float64),
                  np.asfortranarray(rotated), np.hstack([rotated, rotated])[:, :4]):
        checker.move_object('box', value)
        np.testing.assert_allclose(checker.object_pose('box'), rotated)
    oracle.apply(MoveObject('box', rotated))
    assert checker.update(q).colliding_pairs == oracle.colliding_pairs(q)


def _ancestors(checker, link):
    kin = checker.kinematics
    chain = [kin.link_names.index(link)]
    while kin.parent[chain[-1]] >= 0:
        chain.append(int(kin.parent[chain[-1]]))
    return [kin.link_names[i] for i in chain]


def test_reach_bounds_hold_for_attached_objects():
    """Moving variable j by d moves the vertices of a pair with an attached object, both
    bodies summed, by no more than |d| (reach + reach_ext E) relative to each other: in
    their common ancestor's frame (the world for a world object; see pair_reach.pair_rows)."""
    checker, _ = _small_cell()
    rng = np.random.default_rng(8)
    held = _random_object(rng, 'held')
    other_held = _random_object(rng, 'other')
    checker.add_object(held, 'tool', (), transform_from_xyz_rpy([0.3, 0.1, 0.2], [0.3, 0, 1]))
    checker.add_object(other_held, 'upper', (), transform_from_xyz_rpy([0, 0.2, 0], [0, 1, 0]))
    checker.add_object(_random_object(rng, 'post'), pose=_random_pose(rng, 0.5))
    vertices = {'held': held.vertices, 'other': other_held.vertices}
    for element in checker.model.elements:
        T = element.T_link_element
        vertices.setdefault(element.link, np.zeros((0, 3)))
        vertices[element.link] = np.concatenate(
            [vertices[element.link], element.vertices @ T[:3, :3].T + T[:3, 3]])
    hosts = {'held': 'tool', 'other': 'upper'}
    extend = checker.joint_names.index('extend')
    reach, reach_ext = checker.packed_array('reach'), checker.packed_array('reach_ext')
    seen = 0
    for q in random_configurations(checker, 20, 8):
        checker.check(q)
        T0 = checker.link_poses()
        for j in range(len(q)):
            moved = q.copy()
            moved[j] += rng.choice([1e-3, -0.05, 0.3])
            checker.check(moved)
            T1 = checker.link_poses()
            extension = max(abs(q[extend]), abs(moved[extend]))
            for p, (a, b) in enumerate(checker.checked_pairs):
                if not {'held', 'other'} & {a, b}:
                    continue
                if 'post' in (a, b):
                    frame = None    # the world
                else:
                    chains = [_ancestors(checker, hosts.get(x, x)) for x in (a, b)]
                    frame = next(k for k in chains[1] if k in chains[0])
                shift = 0.0
                for x in (a, b):
                    if x == 'post':
                        continue
                    rel = [T[x] if frame is None else np.linalg.inv(T[frame]) @ T[x]
                           for T in (T0, T1)]
                    delta = rel[1] - rel[0]
                    shift += np.linalg.norm(vertices[x] @ delta[:3, :3].T + delta[:3, 3],
                                            axis=1).max()
                bound = abs(moved[j] - q[j]) * (reach[p, j] + reach_ext[p, j] * extension)
                assert shift <= bound + 1e-9, (a, b, checker.joint_names[j], shift, bound)
                seen += shift > 0
    assert seen > 100


def test_poses_are_checked_and_quaternions_normalised():
    T = transform_from_xyz_quaternion([1, 2, 3], [0, 0, 2, 0])   # 180 deg about z, scaled
    np.testing.assert_allclose(T[:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-15)
    assert checked_pose(T, 'o').flags.writeable is False
    for bad in ([0, 0, 0, 0], [np.nan, 0, 0, 1], [0, 0, 0, 1e-101]):
        with pytest.raises(SceneError, match='quaternion|finite'):
            transform_from_xyz_quaternion([0, 0, 0], bad)
    # Zero is the engine's rule for a floating joint's quaternion (QUATERNION_NORM_MIN, the
    # norm taken scaled): a tiny one has a direction, and no square of it underflows.
    tiny = transform_from_xyz_quaternion([0, 0, 0], [0, 0, 2e-100, 0])
    np.testing.assert_allclose(tiny, np.diag([-1.0, -1.0, 1.0, 1.0]), atol=1e-15)
    with pytest.raises(SceneError, match='finite'):
        transform_from_xyz_quaternion([np.inf, 0, 0], [0, 0, 0, 1])
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(SceneError, match='determinant'):
        checked_pose(mirror, 'o')
    far = np.eye(4)
    far[0, 3] = 1e7
    with pytest.raises(SceneError, match='within'):
        checked_pose(far, 'o')


def test_an_added_objects_tree_is_held_once_by_the_engines_buffers():
    """After a commit, the object's tree lives only in the engine's buffers: the arrays its
    block was built with are freed (scenario 4 measures the memory this saves)."""
    import gc
    import weakref
    checker, _ = _small_cell()
    prepared = checker.prepare_scene_changes(
        [AddObject(_random_object(np.random.default_rng(3), 'ball'))])
    built = prepared.objects['ball'].block
    freed = [weakref.ref(array) for array in (built.tris, built.boxes, built.volume)]
    checker.commit_scene_changes(prepared)
    del prepared, built
    gc.collect()
    assert [ref() for ref in freed] == [None, None, None]
    block = checker._scene.objects['ball'].block
    assert np.shares_memory(block.tris, checker.packed_array('tris'))
    assert np.shares_memory(block.boxes, checker.packed_array('boxes'))


def _true_surface(row, rng, n=4000):
    """Points on the true primitive of a solid row (its body's frame): box, sphere or
    cylinder, corners and rims included."""
    kind, size = int(row[0]), row[1:4]
    R, t = row[4:13].reshape(3, 3), row[13:16]
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    if kind == engine.SOLID_BOX:
        local = np.sign(u) * size
    elif kind == engine.SOLID_SPHERE:
        local = u * size[0]
    else:  # the rims of a cylinder's end discs
        angle = rng.uniform(0, 2 * np.pi, n)
        local = np.stack([size[0] * np.cos(angle), size[0] * np.sin(angle),
                          size[1] * np.sign(u[:, 2])], axis=1)
    return local @ R.T + t


def _inside(points, box, slack=1e-12):
    local = (points - box[engine.BOX_CENTER:engine.BOX_CENTER + 3]) @ box[
        engine.BOX_AXES:engine.BOX_AXES + 9].reshape(3, 3)
    return np.all(np.abs(local) <= box[engine.BOX_HALF:engine.BOX_HALF + 3] + slack)


@pytest.mark.parametrize('fit', ['refined', 'pca'])
def test_root_and_body_boxes_hold_the_true_solids_and_rows_name_the_first_vertex(fit):
    # A tessellated sphere or cylinder is inscribed in its true shape, which counts for
    # containment: boxes fitted to the triangles alone can leave the sliver between them out,
    # and a box test would then prove apart a vertex that lies in the solid.
    config = dict(SETTINGS, obb_fit=fit)
    model = load_urdf(SMALL_ROBOT, primitive_sections=config['primitive_sections'])
    checker = CollisionChecker(model, config=config)
    rng = np.random.default_rng(4)
    objects = [_random_object(rng, f'obj{i}') for i in range(12)]
    checker.apply_scene_changes([AddObject(obj, None, (), _random_pose(rng, 0.7))
                                 for obj in objects])
    arrays = checker._scene.arrays
    solids = 0
    for b in range(len(checker._scene.body_names)):
        for e in range(checker._scene.elem_start[b], checker._scene.elem_end[b]):
            row = arrays['elem_solid'][e]
            if int(row[0]) in (engine.SOLID_BOX, engine.SOLID_SPHERE, engine.SOLID_CYLINDER):
                points = _true_surface(row, rng)
                assert _inside(points, arrays['boxes'][arrays['roots'][e]]), (b, e)
                assert _inside(points, arrays['body_boxes'][b]), (b, e)
                solids += 1
    assert solids >= 6
    # The test vertex of each element: its mesh's first vertex, in the body's frame (a link's
    # elements in the model's order).
    for b, link in enumerate(checker._scene.body_names):
        elements = [element for element in model.elements if element.link == link]
        for e, element in zip(range(checker._scene.elem_start[b], checker._scene.elem_end[b]),
                              elements):
            T = element.T_link_element
            np.testing.assert_allclose(
                arrays['elem_solid'][e][engine.SOLID_PROBE:engine.SOLID_PROBE + 3],
                T[:3, :3] @ element.vertices[element.faces[0, 0]] + T[:3, 3], atol=1e-15)
    for obj in objects:
        b = checker._scene.body_index[obj.name]
        e = checker._scene.elem_start[b]
        np.testing.assert_array_equal(
            arrays['elem_solid'][e][engine.SOLID_PROBE:engine.SOLID_PROBE + 3],
            obj.vertices[obj.faces[0, 0]])
