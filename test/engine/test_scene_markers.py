"""The scene topic's rules (collision_sensor.engine.scene_markers), without ROS: markers are plain
objects with the fields of visualization_msgs/Marker."""
import os
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from collision_sensor import CollisionChecker
from collision_sensor.engine.dynamic_scene import AddObject, MoveObject, RemoveObject
from collision_sensor.engine.dynamic_scene import SceneChangeError
from collision_sensor.engine.scene_markers import (
    ADD, CUBE, CYLINDER, DELETE, DELETEALL, MESH_RESOURCE, SPHERE, TRIANGLE_LIST, MarkerError,
    SceneLimits, SceneTopic, apply_array, marker_error)
from collision_sensor.model.mesh_loading import SOLID_BOX, SOLID_CYLINDER, SOLID_SPHERE
from small_robot import SMALL_ROBOT

ROBOT_LINKS = ('base', 'upper', 'lower', 'slider', 'tool')


def xyz(x=0.0, y=0.0, z=0.0):
    return SimpleNamespace(x=x, y=y, z=z)


def marker(ns='obj', ident=0, kind=CUBE, action=ADD, frame='', position=(0.0, 0.0, 0.0),
           orientation=(0.0, 0.0, 0.0, 1.0), scale=(0.1, 0.1, 0.1), points=(), mesh='',
           text=''):
    return SimpleNamespace(
        ns=ns, id=ident, type=kind, action=action, header=SimpleNamespace(frame_id=frame),
        pose=SimpleNamespace(position=xyz(*position),
                             orientation=SimpleNamespace(x=orientation[0], y=orientation[1],
                                                         z=orientation[2], w=orientation[3])),
        scale=xyz(*scale), points=[xyz(*p) for p in points], mesh_resource=mesh, text=text)


@pytest.fixture(scope='module')
def robot():
    return CollisionChecker.from_urdf(SMALL_ROBOT, config={'primitive_sections': 8})


@pytest.fixture
def checker(robot):
    """A fresh scene on the module's robot (a new checker shares nothing with it)."""
    return CollisionChecker(robot.model, config=robot.config)


def apply(topic, checker, markers):
    return apply_array(topic, checker, markers)


def test_shapes_names_and_poses(checker, tmp_path):
    mesh_dir = tmp_path / 'pkg' / 'meshes'
    mesh_dir.mkdir(parents=True)
    trimesh.creation.icosphere(1, 0.5).export(str(mesh_dir / 'ball.stl'))
    topic = SceneTopic(package_paths={'pkg': str(tmp_path / 'pkg')})
    triangles = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (0, 1, 1)]
    update = apply(topic, checker, [
        marker('box', 0, CUBE, scale=(0.1, 0.2, 0.3), position=(1, 2, 3),
               orientation=(0, 0, 2, 0)),                   # normalised: 180 deg about z
        marker('parts', 7, SPHERE, scale=(0.4, 0.4, 0.4)),
        marker('post', 0, CYLINDER, scale=(0.2, 0.2, 1.0)),
        marker('ball', 0, MESH_RESOURCE, scale=(2, 2, 2), mesh='package://pkg/meshes/ball.stl'),
        marker('soup', 0, TRIANGLE_LIST, scale=(1, 2, 3), points=triangles),
    ])
    assert checker.object_names == ('box', 'parts/7', 'post', 'ball', 'soup')
    objects = {obj.name: obj for obj in checker.scene_objects}
    box = objects['box']
    assert box.solid.kind == SOLID_BOX and np.allclose(box.solid.size, (0.05, 0.1, 0.15))
    np.testing.assert_allclose(box.T_world_object[:3, 3], (1, 2, 3))
    np.testing.assert_allclose(box.T_world_object[:3, :3], np.diag([-1.0, -1.0, 1.0]),
                               atol=1e-15)
    assert objects['parts/7'].solid.kind == SOLID_SPHERE and objects['parts/7'].solid.size[
        0] == pytest.approx(0.2)
    assert objects['post'].solid.kind == SOLID_CYLINDER and np.allclose(
        objects['post'].solid.size[:2], (0.1, 0.5))
    assert objects['ball'].solid is None
    assert np.abs(objects['ball'].vertices).max() == pytest.approx(1.0)   # radius 0.5, x 2
    np.testing.assert_allclose(objects['soup'].vertices[4], (1, 0, 3))
    assert len(objects['soup'].faces) == 2
    assert update.summary.startswith('5 added or replaced, 0 moved, 0 removed')


def test_add_with_the_same_shape_only_moves(checker):
    topic = SceneTopic()
    apply(topic, checker, [marker('box', scale=(0.1, 0.2, 0.3))])
    update = topic.update([marker('box', scale=(0.1, 0.2, 0.3), position=(0.5, 0, 0))], checker)
    assert [type(change) for change in update.changes] == [MoveObject]
    checker.apply_scene_changes(update.changes)
    topic.accept(update)
    # Another size, another frame or other touch links: replaced.
    for changed in (marker('box', scale=(0.1, 0.2, 0.4)), marker('box', frame='tool'),
                    marker('box', kind=SPHERE, scale=(0.3,) * 3)):
        update = topic.update([changed], checker)
        assert [type(change) for change in update.changes] == [AddObject]


def test_frames_attach_and_touch_links(checker):
    topic = SceneTopic()
    apply(topic, checker, [marker('a', frame='base'), marker('b', frame='tool',
                                                             text='lower  slider'),
                           marker('c', frame='upper')])
    assert checker.attachments == {'b': ('tool', ('lower', 'slider')), 'c': ('upper', ())}
    assert 'a' not in checker.attachments     # the root link is the world
    with pytest.raises(MarkerError, match=r'marker 0 \(ns "d", id 0\): frame "map"'):
        topic.update([marker('d', frame='map')], checker)
    with pytest.raises(MarkerError, match='touch link "gripper"'):
        topic.update([marker('d', frame='tool', text='gripper')], checker)


def test_delete_and_deleteall_keep_the_scene_files_objects(robot):
    checker = CollisionChecker(robot.model, config=robot.config)
    from collision_sensor.model.scene import load_scene
    checker.apply_scene_changes([AddObject(obj) for obj in load_scene(
        {'objects': [{'name': 'wall', 'box': {'size': [0.1, 1, 1]}}]})])
    topic = SceneTopic()
    apply(topic, checker, [marker('a'), marker('b', 3), marker('c')])
    apply(topic, checker, [marker('b', 3, action=DELETE), marker('nothing', action=DELETE)])
    assert checker.object_names == ('wall', 'a', 'c')
    update = apply(topic, checker, [marker(action=DELETEALL), marker('d')])
    assert checker.object_names == ('wall', 'd')
    assert [type(change) for change in update.changes] == [RemoveObject, RemoveObject, AddObject]
    # The topic may move (replace) the scene file's object: it came through the topic then.
    apply(topic, checker, [marker('wall', position=(1, 0, 0))])
    apply(topic, checker, [marker(action=DELETEALL)])
    assert checker.object_names == ()


BAD = [
    (marker('x', kind=4), 'type 4'),                                   # LINE_STRIP
    (marker('x', action=1), 'action 1'),
    (marker('x', frame='nowhere'), 'frame "nowhere"'),
    (marker('x', position=(float('nan'), 0, 0)), 'not finite'),
    (marker('x', orientation=(0, 0, 0, 0)), 'quaternion'),
    (marker('x', scale=(0.1, 0.0, 0.1)), 'zero scale'),
    (marker('x', scale=(0.1, float('inf'), 0.1)), 'scale'),
    (marker('x', kind=SPHERE, scale=(0.1, 0.2, 0.1)), 'SPHERE needs'),
    (marker('x', kind=CYLINDER, scale=(0.1, 0.2, 0.1)), 'CYLINDER needs'),
    (marker('x', kind=TRIANGLE_LIST, points=[(0, 0, 0)] * 4), '4 points'),
    (marker('x', kind=TRIANGLE_LIST, points=[(0, 0, float('nan'))] * 3), 'finite'),
    (marker('x', kind=MESH_RESOURCE, mesh='/etc/passwd'), 'outside'),
    (marker('x', kind=MESH_RESOURCE, mesh='package://nosuchpkg/m.stl'), 'package not found'),
    (marker('x', kind=MESH_RESOURCE, mesh='http://example.com/m.stl'), 'not package://'),
    (marker('x', kind=MESH_RESOURCE, mesh='relative/m.stl'), 'not package://'),
    (marker('', 0), 'object name ""'),
    (marker('a:b'), 'without ":"'),
    (marker('line\nbreak'), 'printable'),
    (marker('tool'), 'name of a link'),                  # judged by the checker
    (marker('x', frame='tool', text='base tool nolink'), 'touch link "nolink"'),
]


@pytest.mark.parametrize('bad, words', BAD, ids=[words for _, words in BAD])
def test_one_bad_marker_rejects_the_whole_array(checker, bad, words):
    topic = SceneTopic()
    apply(topic, checker, [marker('keep')])
    before = (checker.object_names, checker.checked_pairs)
    with pytest.raises(MarkerError) as caught:
        apply(topic, checker, [marker('new'), marker('keep', position=(1, 0, 0)), bad])
    assert caught.value.index == 2 and words in str(caught.value)
    assert str(caught.value).startswith('marker 2 (')
    assert (checker.object_names, checker.checked_pairs) == before
    assert set(topic.objects) == {'keep'}
    np.testing.assert_array_equal(checker.object_pose('keep'), np.eye(4))


def test_caps(checker, tmp_path):
    limits = SceneLimits(max_objects=2, max_triangles=20, max_total_triangles=30,
                         max_mesh_bytes=2000, mesh_roots=(str(tmp_path),))
    topic = SceneTopic(limits)
    soup = [(0, 0, 0), (1, 0, 0), (0, 1, 0)] * 20
    apply(topic, checker, [marker('a'), marker('b')])
    with pytest.raises(MarkerError, match='scene_max_objects 2'):
        topic.update([marker('c')], checker)
    apply(topic, checker, [marker('b', action=DELETE), marker('s', kind=TRIANGLE_LIST,
                                                              points=soup[:36])])
    with pytest.raises(MarkerError, match='scene_max_total_triangles 30'):
        topic.update([marker('a', action=DELETE), marker('t', kind=TRIANGLE_LIST,
                                                        points=soup[:57])], checker)
    with pytest.raises(MarkerError, match='scene_max_triangles 20'):
        topic.update([marker('u', kind=TRIANGLE_LIST, points=soup * 2)], checker)
    big = tmp_path / 'big.stl'
    trimesh.creation.icosphere(2).export(str(big))
    assert os.path.getsize(big) > 2000
    with pytest.raises(MarkerError, match='scene_max_mesh_bytes 2000'):
        topic.update([marker('a', action=DELETE), marker('m', kind=MESH_RESOURCE,
                                                        mesh=f'file://{big}')], checker)
    small = tmp_path / 'tri.stl'
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).export(str(small))
    apply(topic, checker, [marker('a', action=DELETE), marker('m', kind=MESH_RESOURCE,
                                                             mesh=str(small))])
    assert checker.object_triangles('m') == 1
    outside = tmp_path.parent / 'outside.stl'
    outside.write_bytes(small.read_bytes())
    escape = f'{tmp_path}/../outside.stl'         # .. leaves the root: refused
    with pytest.raises(MarkerError, match='outside'):
        topic.update([marker('n', kind=MESH_RESOURCE, mesh=escape)], checker)
    link = tmp_path / 'link.stl'
    link.symlink_to(outside)                      # so does a link out of it
    with pytest.raises(MarkerError, match='outside'):
        topic.update([marker('n', kind=MESH_RESOURCE, mesh=str(link))], checker)
    fifo = tmp_path / 'fifo.stl'
    os.mkfifo(fifo)
    with pytest.raises(MarkerError, match='regular file'):
        topic.update([marker('n', kind=MESH_RESOURCE, mesh=str(fifo))], checker)


def test_readd_gives_a_new_checker_the_topics_objects(robot, checker):
    topic = SceneTopic()
    apply(topic, checker, [marker('a', position=(0.3, 0, 0)), marker('b', frame='tool',
                                                                     text='lower')])
    fresh = CollisionChecker(robot.model, config=robot.config)
    fresh.apply_scene_changes(topic.readd_changes())
    assert fresh.object_names == checker.object_names
    assert fresh.attachments == checker.attachments
    np.testing.assert_array_equal(fresh.object_pose('a'), checker.object_pose('a'))
