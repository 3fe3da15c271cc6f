"""Scene files as scene-topic markers: the node, given the markers, holds the scene the file
describes. The oracle is the scene file loaded as the node's scene_path: both checkers answer
alike on random configurations of the small robot (every primitive, a mesh read here, a
package:// mesh, rotated poses)."""
import math
import os

import numpy as np
import pytest
import trimesh
import yaml

pytest.importorskip('rclpy')

from visualization_msgs.msg import Marker  # noqa: E402

from collision_sensor import CollisionChecker, SceneError  # noqa: E402
from collision_sensor.engine.sampling import random_configurations  # noqa: E402
from collision_sensor.engine.scene_markers import SceneTopic  # noqa: E402
from collision_sensor.ros.scene_messages import (  # noqa: E402
    absolute_mesh_paths, delete_all_marker, delete_markers, scene_markers)
from small_robot import SMALL_ROBOT  # noqa: E402


@pytest.fixture
def cell(tmp_path):
    (tmp_path / 'meshes').mkdir()
    trimesh.creation.icosphere(2, 0.12).export(str(tmp_path / 'meshes' / 'ball.stl'))
    trimesh.creation.box((0.1, 0.3, 0.05)).export(str(tmp_path / 'meshes' / 'plate.stl'))
    (tmp_path / 'robot.urdf').write_text(SMALL_ROBOT)
    scene = {'objects': [
        {'name': 'table', 'box': {'size': [0.6, 0.4, 0.05]},
         'pose': {'xyz': [0.3, 0.1, 0.4], 'rpy': [0.1, 0.2, 0.3]}},
        {'name': 'post', 'cylinder': {'radius': 0.05, 'length': 0.5},
         'pose': {'xyz': [-0.3, 0.0, 0.6], 'rpy': [math.pi / 2, 0.0, 0.4]}},
        {'name': 'ball', 'sphere': {'radius': 0.1}, 'pose': {'xyz': [0.0, 0.3, 0.8]}},
        {'name': 'part', 'mesh': {'filename': 'meshes/ball.stl', 'scale': [1.0, 2.0, 1.0]},
         'pose': {'xyz': [0.2, -0.3, 0.7]}},
        {'name': 'plate', 'mesh': {'filename': 'package://cell/meshes/plate.stl', 'scale': 2},
         'pose': {'xyz': [0.0, -0.1, 1.0], 'rpy': [0.0, 0.5, 0.0]}},
    ]}
    path = tmp_path / 'scene.yaml'
    path.write_text(yaml.safe_dump(scene))
    return tmp_path, path


def test_markers_give_the_node_the_scene_of_the_file(cell):
    directory, path = cell
    urdf, packages = str(directory / 'robot.urdf'), {'cell': str(directory)}
    markers = scene_markers(str(path), packages)
    assert [m.type for m in markers] == [Marker.CUBE, Marker.CYLINDER, Marker.SPHERE,
                                         Marker.TRIANGLE_LIST, Marker.MESH_RESOURCE]
    assert [m.ns for m in markers] == ['table', 'post', 'ball', 'part', 'plate']
    from_file = CollisionChecker.from_urdf(urdf, scene=str(path), package_paths=packages)
    from_topic = CollisionChecker.from_urdf(urdf, package_paths=packages)
    topic = SceneTopic(package_paths=packages)
    from_topic.apply_scene_changes(topic.update(markers, from_topic).changes)
    assert sorted(from_topic.object_names) == sorted(from_file.object_names)
    # The columns (pairs) are the same, each pair in each configuration answered alike.
    assert from_topic.checked_pairs == from_file.checked_pairs
    Q = random_configurations(from_file, 300, seed=3)
    expected = from_file.check_batch(Q)
    assert 20 < expected.any(axis=1).sum() < 280, 'the scene should touch the robot sometimes'
    assert np.array_equal(from_topic.check_batch(Q), expected)


def test_attached_objects_and_the_links_they_may_touch(cell):
    _, path = cell
    markers = scene_markers(str(path), {'cell': str(path.parent)}, frame='tool',
                            touch=['tool', 'lower'])
    assert {m.header.frame_id for m in markers} == {'tool'}
    assert {m.text for m in markers} == {'tool lower'}


def test_a_dict_resolves_meshes_from_the_current_directory(cell, monkeypatch):
    directory, path = cell
    document = yaml.safe_load(path.read_text())
    monkeypatch.chdir(directory)
    markers = scene_markers(document, {'cell': str(directory)})
    assert markers[3].type == Marker.TRIANGLE_LIST and len(markers[3].points) % 3 == 0
    moved = absolute_mesh_paths(document, str(directory))
    assert moved['objects'][3]['mesh']['filename'] == os.path.join(str(directory),
                                                                   'meshes/ball.stl')
    assert moved['objects'][4] == document['objects'][4]     # package:// stays


def test_a_bad_file_is_refused_before_anything_is_sent(cell):
    directory, path = cell
    bad = directory / 'bad.yaml'
    bad.write_text('objects:\n  - {name: x, box: {size: [1, 0, 1]}}\n')
    with pytest.raises(SceneError, match='bad.yaml.*"x".*size'):
        scene_markers(str(bad))
    with pytest.raises(SceneError, match='cannot read'):
        scene_markers(str(directory / 'missing.yaml'))


def test_delete_markers():
    assert [(m.ns, m.id, m.action) for m in delete_markers(['a', 'b'])] == [
        ('a', 0, Marker.DELETE), ('b', 0, Marker.DELETE)]
    assert delete_all_marker().action == Marker.DELETEALL
