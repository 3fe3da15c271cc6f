"""The Python/C++ boundary: one source of truth, the extension's.

* every packed array of a real robot (the Panda, with attached and world objects) has the
  dtype, group and shape the engine's layout tables give, for dimensions counted here from the
  checker's own description (links, bodies, pairs, trees ...), not from the layout;
* every constant a Python module names that the extension exports is the extension's, and no
  module assigns such a name a number of its own (a hand copy);
* the engine checks the layout it is given, and its errors are the package's own.
"""
import ast
import importlib
import pathlib

import numpy as np
import pytest

import collision_sensor
from collision_sensor import CollisionChecker
from collision_sensor.engine import array_pack
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import AddObject
from collision_sensor.errors import EngineBuildError, EngineInputError, JointStateError
from collision_sensor.model.mesh_loading import box_mesh, box_solid
from collision_sensor.model.scene import SceneObject

PACKAGE_DIR = pathlib.Path(collision_sensor.__file__).parent


def _box(name, size, xyz):
    vertices, faces = box_mesh(size)
    T = np.eye(4)
    T[:3, 3] = xyz
    return SceneObject(name=name, source='test', T_world_object=T, vertices=vertices,
                       faces=faces, solid=box_solid(size))


@pytest.fixture(scope='module')
def panda_cell(panda_urdf, panda_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    checker.apply_scene_changes([
        AddObject(_box('table', (0.8, 0.8, 0.05), (0.5, 0.0, -0.1))),
        AddObject(_box('shelf', (0.3, 0.6, 0.02), (0.6, 0.2, 0.6))),
        AddObject(_box('part', (0.04, 0.04, 0.08), (0.0, 0.0, 0.1)), attach_to='panda_hand',
                  touch_links=('panda_leftfinger', 'panda_rightfinger'))])
    checker.check(np.zeros(len(checker.joint_names)))
    return checker


def _dims(checker):
    """The model's dimensions, counted from the checker's own description: its kinematic tree,
    attachments, pairs and forest (and, for the variables' lists, the tree paths)."""
    kin = checker.kinematics
    attachments = checker.attachments
    attached = [name for name in checker.scene_object_names if name in attachments]
    world = [name for name in checker.scene_object_names if name not in attachments]
    links = list(kin.link_names) + attached
    parent = list(kin.parent) + [kin.link_names.index(attachments[n][0]) for n in attached]
    count = {engine.JOINT_FIXED: 0, engine.JOINT_PLANAR: 3, engine.JOINT_FLOATING: 7}
    drives = [set(range(kin.q_index[k], kin.q_index[k] + count.get(kin.joint_type[k], 1)))
              if kin.q_index[k] >= 0 else set() for k in range(len(kin.link_names))]
    drives += [set() for _ in attached]

    def chain(name):   # the body and its ancestors; a world object has none (the world's)
        if name in world:
            return []
        k, out = links.index(name), []
        while k >= 0:
            out.append(k)
            k = parent[k]
        return out

    def variables(ks):
        return set().union(*[drives[k] for k in ks])

    joint_links = sum(len(variables(chain(name))) for name in links)
    joint_pairs = sum(len(variables(set(chain(a)) ^ set(chain(b))))
                      for a, b in checker.checked_pairs)
    forest = checker.forest
    return {'links': len(links), 'bodies': len(links) + len(world),
            'world_objects': len(world), 'joints': len(checker.joint_names),
            'pairs': len(checker.checked_pairs), 'nodes': len(forest.left),
            'triangles': len(forest.tris), 'elements': len(forest.roots),
            'joint_pairs': joint_pairs, 'joint_links': joint_links}


def test_every_packed_array_has_the_engines_dtype_and_shape(panda_cell):
    dims = _dims(panda_cell)
    assert set(dims) == set(array_pack.DIMS)
    assert dims['world_objects'] == 2
    assert dims['links'] == len(panda_cell.kinematics.link_names) + 1
    assert dims['joint_pairs'] > dims['pairs'] > 0 and dims['joint_links'] > dims['links']
    names = [slot.name for slot in array_pack.SLOTS]
    assert len(names) == len(set(names)) == len(engine.FLOAT_SLOTS) + len(engine.INT_SLOTS)
    for slot in array_pack.SLOTS:
        view = panda_cell.packed_array(slot.name)
        assert view.dtype == slot.dtype, slot
        assert view.shape == array_pack.shape_of(slot, dims), slot
        assert slot.group in ('model', 'state', 'work'), slot
    # The shapes the engine names are the checker's, too.
    assert panda_cell.packed_array('T_world_body').shape == (dims['bodies'], 4, 4)
    assert panda_cell.packed_array('boxes').shape == (dims['nodes'], engine.BOX_WIDTH)


def _engine_names():
    return {name for name in dir(engine) if name.isupper()}


def _engine_modules():
    return sorted(path for path in (PACKAGE_DIR / 'engine').glob('*.py'))


def test_every_python_constant_is_the_extensions():
    shared = 0
    for path in _engine_modules():
        module = importlib.import_module(f'collision_sensor.engine.{path.stem}')
        for name in _engine_names() & set(vars(module)):
            value = getattr(module, name)
            if isinstance(value, np.ndarray):
                assert np.array_equal(value, getattr(engine, name)), (path.name, name)
            else:
                assert value == getattr(engine, name), (path.name, name)
            shared += 1
    assert shared >= 30
    from collision_sensor.engine import dynamic_scene
    from collision_sensor.model import mesh_loading
    kinds = {mesh_loading.SOLID_BOX, mesh_loading.SOLID_SPHERE, mesh_loading.SOLID_CYLINDER,
             mesh_loading.SOLID_CLOSED_MESH}
    assert set(dynamic_scene.SOLID_CODES) == kinds
    assert sorted(dynamic_scene.SOLID_CODES.values()) == [
        engine.SOLID_BOX, engine.SOLID_SPHERE, engine.SOLID_CYLINDER, engine.SOLID_CLOSED_MESH]


def _literal(node):
    """True iff node is a number, or a tuple / list of them (a hand-written constant)."""
    if isinstance(node, (ast.Tuple, ast.List)):
        return all(_literal(item) for item in node.elts)
    if isinstance(node, ast.UnaryOp):
        return _literal(node.operand)
    return isinstance(node, ast.Constant) and isinstance(node.value, (int, float))


def test_no_module_writes_an_engine_constant_by_hand():
    """A name the extension exports is never given a number of the package's own (but
    ENGINE_API: the version the Python side expects, compared with the extension's)."""
    exported = _engine_names() - {'ENGINE_API'}
    copies = []
    for path in sorted(PACKAGE_DIR.rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.Assign) or not _literal(node.value):
                continue
            for target in node.targets:
                names = target.elts if isinstance(target, ast.Tuple) else [target]
                copies += [f'{path.relative_to(PACKAGE_DIR)}:{node.lineno} {n.id}'
                           for n in names if isinstance(n, ast.Name) and n.id in exported]
    assert copies == []


def _arrays(checker):
    return {slot.name: checker.packed_array(slot.name).copy() for slot in array_pack.SLOTS}


def _engine_of(arrays, **options):
    """An engine over a packing of ``arrays``, and the views of its buffers."""
    packed = array_pack.pack(arrays)
    settings = dict(box_test=engine.BOX_TEST_SAT, expansion=engine.EXPAND_WIDER,
                    motion_tolerance=0.0)
    settings.update(options)
    return engine.Engine(packed.F, packed.F_layout, packed.I, packed.I_layout,
                         **settings), packed.views


def test_the_engine_refuses_a_layout_that_is_not_its_own(panda_cell):
    arrays = _arrays(panda_cell)
    _engine_of(arrays)   # the checker's own arrays make an engine
    for name, bad, expected in [
            ('reach_ext', arrays['reach_ext'][:, :-1], r"\(pairs, joints\) = \(\d+, 8\)"),
            ('nodes', arrays['nodes'][:-1], "nodes from 'boxes'"),
            ('joint_pairs_start', arrays['joint_pairs_start'][:-1], r"\(joints\+1,\) = \(9,\)"),
            ('query_flags', np.zeros(5), r'\(2,\)')]:
        with pytest.raises(EngineBuildError, match=f"'{name}' has shape .*{expected}"):
            _engine_of({**arrays, name: bad})
    packed = array_pack.pack(arrays)
    packed.F_layout[3, 0] = len(packed.F)   # a slot past the end of its buffer
    with pytest.raises(EngineBuildError, match='outside its buffer'):
        engine.Engine(packed.F, packed.F_layout, packed.I, packed.I_layout, box_test=0,
                      expansion=0, motion_tolerance=0.0)


def test_the_engine_refuses_bad_content_and_options_with_the_packages_errors(panda_cell):
    arrays = _arrays(panda_cell)
    for name, change, message in [
            ('pair_b', lambda a: a.__setitem__(0, 10_000), 'pair_'),
            ('parent', lambda a: a.__setitem__(1, 5), 'parent'),
            ('padding', lambda a: a.__setitem__(0, np.nan), 'padding'),
            ('joint_pairs', lambda a: a.__setitem__(0, -1), 'joint_'),
            # Two elements on one tree: caches keyed by node (the cloud filter's world boxes,
            # written by the element's thread) need each node in one tree.
            ('roots', lambda a: a.__setitem__(1, a[0]), 'two trees share it')]:
        bad = arrays[name].copy()
        change(bad)
        with pytest.raises(EngineInputError, match=message):
            _engine_of({**arrays, name: bad})
    with pytest.raises(EngineInputError, match='box_test'):
        _engine_of(arrays, box_test=7)
    with pytest.raises(EngineInputError, match='motion_tolerance'):
        _engine_of(arrays, motion_tolerance=-1.0)
    with pytest.raises(EngineInputError, match='statuses'):
        _engine_of(arrays)[0].batch(np.zeros((2, len(panda_cell.joint_names))), True,
                                 np.zeros((2, 1), dtype=np.uint8), np.zeros(2, dtype=np.int64),
                                 np.zeros(2, dtype=np.uint8))
    with pytest.raises(EngineInputError, match='points'):
        engine.fit_obb_pca(np.zeros((4, 2)))
    with pytest.raises(JointStateError) as error:
        panda_cell.kinematics._forward(np.full(len(panda_cell.joint_names), np.inf))
    assert 'panda_joint1' in str(error.value)


def test_scene_methods_change_nothing_they_refuse(panda_cell):
    """move_world_body and place_attached_body validate before they write: a refused call
    leaves every packed array as it was."""
    eng, views = _engine_of(_arrays(panda_cell))
    before = {name: view.copy() for name, view in views.items()}
    part = len(panda_cell.kinematics.link_names)   # the attached part: the last link
    world = part + 1                               # the first world object
    bad_pose = np.eye(4)
    bad_pose[0, 0] = 2.0
    far = np.eye(4)
    far[0, 3] = 2 * engine.MAX_COORDINATE
    assert eng.move_world_body(world, bad_pose) is False
    assert eng.move_world_body(world, far) is False
    assert eng.move_world_body(part, np.eye(4)) is False          # not a world object
    assert eng.move_world_body(world, [[1.0]]) is False           # not a (4, 4) float64 array
    J = len(panda_cell.joint_names)
    pairs = np.flatnonzero([part in (a, b) for a, b in zip(views['pair_a'], views['pair_b'])])
    assert len(pairs) > 5
    reach = np.ones((len(pairs), J))
    assert eng.place_attached_body(part, bad_pose, pairs, reach, reach) is False
    assert eng.place_attached_body(world, np.eye(4), pairs, reach, reach) is False
    assert eng.place_attached_body(part, np.eye(4), pairs, -reach, reach) is False
    assert eng.place_attached_body(part, np.eye(4), pairs[:1] * 0 + 10_000,
                                   reach[:1], reach[:1]) is False
    for name, view in views.items():
        np.testing.assert_array_equal(view, before[name], err_msg=name)
    # Accepted, they write: the pose, and the attached part's joint origin and reach rows.
    moved = np.eye(4)
    moved[:3, 3] = (0.1, 0.2, 0.3)
    assert eng.move_world_body(world, moved) is True
    np.testing.assert_array_equal(views['T_world_body'][world], moved)
    assert eng.place_attached_body(part, moved, pairs, reach, 2 * reach) is True
    np.testing.assert_array_equal(views['T_parent_joint'][part], moved)
    np.testing.assert_array_equal(views['reach_ext'][pairs], 2 * reach)
    assert views['stale'][part] == 1 and views['forced'][pairs].all()


def test_every_array_form_of_a_configuration_gets_the_same_answer(panda_cell):
    """The engine reads a configuration in place only when it is C-contiguous, aligned,
    native float64 of the right length; any other form (another byte order or type, a strided
    view, a misaligned buffer, a list) is converted first. Each form gets the answer of the
    plain list, from check and update alike, and the engine's own query refuses the forms it
    cannot read rather than misreading them."""
    checker = panda_cell
    rng = np.random.default_rng(7)
    lower = np.array([checker.joint_limits[n][0] for n in checker.joint_names])
    upper = np.array([checker.joint_limits[n][1] for n in checker.joint_names])
    J = len(lower)
    for _ in range(20):
        q = rng.uniform(lower, upper)
        expected = checker.check(q.tolist())
        wide = np.zeros(2 * J)
        wide[::2] = q
        raw = bytearray(8 * J + 1)
        misaligned = np.frombuffer(raw, dtype=np.float64, count=J, offset=1)
        misaligned[...] = q
        forms = {'native': q.copy(), 'big-endian': q.astype('>f8'), 'strided': wide[::2],
                 'float32 exact': q.astype(np.float32).astype(np.float64),
                 'misaligned': misaligned, 'read-only': q.copy()}
        forms['read-only'].setflags(write=False)
        for name, form in forms.items():
            want = expected if name != 'float32 exact' else checker.check(
                q.astype(np.float32).tolist())
            for method in (checker.check, checker.update):
                got = method(form)
                assert (got.in_collision, got.colliding_pairs) == (
                    want.in_collision, want.colliding_pairs), (name, method.__name__)
            assert [checker.positions[n] for n in checker.joint_names] == \
                np.asarray(form, dtype=np.float64).tolist(), name
        engine_query = checker._engine.query
        for name in ('big-endian', 'strided', 'misaligned'):
            assert engine_query(forms[name], True) is None, name
        for other in (q[:-1].copy(), q.astype(np.float32), q.astype(np.longdouble),
                      q.reshape(1, J), q.tolist()):
            assert engine_query(other, True) is None


def test_batches_and_motions_read_every_array_form_alike(panda_cell):
    """check_batch, check_motion and update_motion on big-endian, strided and misaligned
    arrays answer as on plain ones."""
    checker = panda_cell
    rng = np.random.default_rng(8)
    lower = np.array([checker.joint_limits[n][0] for n in checker.joint_names])
    upper = np.array([checker.joint_limits[n][1] for n in checker.joint_names])
    Q = rng.uniform(lower, upper, (12, len(lower)))
    raw = bytearray(Q.nbytes + 1)
    misaligned = np.frombuffer(raw, dtype=np.float64, count=Q.size, offset=1).reshape(Q.shape)
    misaligned[...] = Q
    wide = np.zeros((12, 2 * len(lower)))
    wide[:, ::2] = Q
    expected = checker.check_batch(Q)
    for form in (Q.astype('>f8'), wide[:, ::2], misaligned):
        np.testing.assert_array_equal(checker.check_batch(form), expected)
        for k in range(len(Q) - 1):
            want = checker.check_motion(Q[k], Q[k + 1])
            got = checker.check_motion(form[k], form[k + 1])
            assert (got.in_collision, got.first_contact, got.colliding_pairs) == (
                want.in_collision, want.first_contact, want.colliding_pairs)
        checker.check(Q[0])
        mine = [checker.update_motion(row) for row in form[1:]]
        checker.check(Q[0])
        plain = [checker.update_motion(row) for row in Q[1:]]
        assert [(r.in_collision, r.first_contact) for r in mine] == \
            [(r.in_collision, r.first_contact) for r in plain]


def test_answers_stay_right_when_another_caller_queries_the_engine_between_calls(panda_cell):
    """Another caller of the same engine (a C++ sensor core runs Engine::query on it between
    the checker's calls) changes the statuses the checker's last answer was made from. Every
    answer of check and update after such queries is a full check's at its positions
    (check_batch: full checks in copies of the state, nothing carried), pair for pair: also
    where the engine's own query finds nothing changed since the other caller's (the same
    positions, the same number of pairs re-checked), which is where an answer kept from the
    checker's last call would be wrong."""
    checker = panda_cell
    rng = np.random.default_rng(11)
    lower = np.array([checker.joint_limits[n][0] for n in checker.joint_names])
    upper = np.array([checker.joint_limits[n][1] for n in checker.joint_names])
    pool = rng.uniform(lower, upper, (600, len(lower)))
    in_contact = checker.check_batch(pool).any(axis=1)
    contact, clear = pool[in_contact][:20], pool[~in_contact][:20]
    assert len(contact) == 20
    configurations = np.empty((40, len(lower)))   # in contact and apart in turn
    configurations[0::2], configurations[1::2] = contact, clear
    statuses = checker.check_batch(configurations)
    names = checker.checked_pairs

    def expected(k):
        return tuple(names[p] for p in np.flatnonzero(statuses[k]))

    engine_query = checker._engine.query   # the engine the checker holds, called directly
    calls = (checker.check, checker.update, checker.update_motion,
             lambda q: checker.proximity(q, 0.0))
    stale = 0
    for k, q in enumerate(configurations):
        o = (k + 1) % len(configurations)
        other = configurations[o]
        calls[k % len(calls)](q)
        kept = checker._result
        for full in (False, True):
            engine_query(other, full)
            for method in (checker.check, checker.update):
                got = method(other)
                assert got.colliding_pairs == expected(o), (k, full, method.__name__)
                assert got.in_collision == bool(expected(o))
                stale += kept.colliding_pairs != got.colliding_pairs
            engine_query(q, full)
            got = checker.update(q)
            assert got.colliding_pairs == expected(k), (k, full)
            kept = got
    assert stale >= 10   # the kept answer was wrong that often: the test can fail


def test_arrays_made_for_the_engine_ask_for_normal_pages_and_numpy_is_left_as_it_was():
    """normal_pages() turns numpy's huge page advice off inside, nested and from threads, and
    gives numpy back its own setting when the last one leaves."""
    import threading
    from collision_sensor.engine import array_pack
    advice = array_pack._HUGE_PAGE_ADVICE
    if advice is None:
        pytest.skip('this numpy has no huge page advice to switch')
    original = advice(True)
    try:
        for setting in (True, False):
            advice(setting)
            inside = []
            entered, release = threading.Barrier(2), threading.Event()

            def hold():
                with array_pack.normal_pages():
                    entered.wait()
                    release.wait()
            thread = threading.Thread(target=hold)
            thread.start()
            with array_pack.normal_pages():
                entered.wait()
                with array_pack.normal_pages():
                    inside.append(advice(False))
                inside.append(advice(False))
            inside.append(advice(False))     # the thread still holds it: still off
            release.set()
            thread.join()
            assert inside == [False, False, False]
            assert advice(setting) is setting    # given back as it was
    finally:
        advice(original)
