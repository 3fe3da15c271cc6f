"""Reading static scenes from YAML, and every kind of badly described object."""
import numpy as np
import pytest
import trimesh
import yaml

from collision_sensor.errors import SceneError
from collision_sensor.model.robot_model import transform_from_xyz_rpy
from collision_sensor.model.scene import load_scene

EXAMPLE = """
objects:
  - name: table                       # unique; used as the pair name in results
    box: {size: [1.0, 0.8, 0.05]}
    pose: {xyz: [0.5, 0.0, -0.025], rpy: [0.0, 0.0, 0.0]}
  - name: post
    cylinder: {radius: 0.05, length: 0.5}
  - name: ball
    sphere: {radius: 0.1}
    pose: {rpy: [0.1, 0.2, 0.3]}
  - name: washer
    mesh: {filename: ../meshes/demo_cell/washer.stl, scale: [1, 2, 1]}
"""


@pytest.fixture
def scene_file(tmp_path):
    (tmp_path / 'meshes' / 'demo_cell').mkdir(parents=True)
    (tmp_path / 'config').mkdir()
    trimesh.creation.annulus(0.02, 0.05, 0.01).export(
        str(tmp_path / 'meshes' / 'demo_cell' / 'washer.stl'))
    path = tmp_path / 'config' / 'scene.yaml'
    path.write_text(EXAMPLE)
    return path


def write_scene(tmp_path, objects):
    path = tmp_path / 'scene.yaml'
    path.write_text(yaml.safe_dump({'objects': objects}))
    return str(path)


def test_the_documented_example(scene_file):
    table, post, ball, washer = load_scene(scene_file, primitive_sections=16)
    assert [table.name, post.name, ball.name, washer.name] == ['table', 'post', 'ball', 'washer']
    assert table.source == 'box 1 0.8 0.05' and len(table.faces) == 12
    np.testing.assert_allclose(table.T_world_object[:3, 3], [0.5, 0.0, -0.025])
    assert post.source == 'cylinder 0.05 0.5' and len(post.vertices) == 34
    np.testing.assert_array_equal(post.T_world_object, np.eye(4))
    np.testing.assert_allclose(ball.T_world_object, transform_from_xyz_rpy([0, 0, 0],
                                                                           [0.1, 0.2, 0.3]))
    assert washer.source == 'mesh ../meshes/demo_cell/washer.stl'
    np.testing.assert_allclose(washer.vertices[:, 1].max(), 0.1)    # scale applied
    for item in (table, post, ball, washer):
        assert item.vertices.dtype == np.float64 and item.faces.dtype == np.int64


def test_a_parsed_dict_and_an_empty_scene(tmp_path):
    objects = load_scene({'objects': [{'name': 'b', 'sphere': {'radius': 1}}]})
    assert objects[0].name == 'b'
    assert load_scene({'objects': []}) == ()
    assert load_scene(write_scene(tmp_path, [])) == ()


def test_mesh_scale_may_be_one_number(scene_file, tmp_path):
    mesh = str(scene_file.parent.parent / 'meshes' / 'demo_cell' / 'washer.stl')
    (item,) = load_scene({'objects': [{'name': 'w', 'mesh': {'filename': mesh, 'scale': 2}}]})
    np.testing.assert_allclose(item.vertices[:, 0].max(), 0.1)


@pytest.mark.parametrize('objects, culprit', [
    ([{'box': {'size': [1, 1, 1]}}], r'object #0 has no name'),
    ([{'name': 'a', 'sphere': {'radius': 1}}, {'name': 'a', 'sphere': {'radius': 2}}],
     'object name "a" is used twice'),
    ([{'name': 'a', 'sphere': {'radius': 1}, 'box': {'size': [1, 1, 1]}}],
     r'object "a": needs exactly one shape key.*found box, sphere'),
    ([{'name': 'a'}], r'object "a": needs exactly one shape key.*found none'),
    ([{'name': 'a', 'box': {'size': [1, 0, 1]}}], r'object "a": box size .* three positive'),
    ([{'name': 'a', 'box': {'size': [1, 1]}}], r'object "a": box size is \[1, 1\], not 3'),
    ([{'name': 'a', 'box': {'size': [1, 1, 1]}, 'colour': 'red'}],
     'object "a": unknown key.*colour'),
    ([{'name': 'a', 'box': {'size': [1, 1, 1], 'center': [0, 0, 0]}}],
     'object "a": box has unknown key.*center'),
    ([{'name': 'a', 'cylinder': {'radius': 1}}], 'object "a": cylinder length is None'),
    ([{'name': 'a', 'sphere': {'radius': True}}], 'object "a": sphere radius'),
    ([{'name': 'a', 'sphere': {'radius': 1}, 'pose': {'xyz': [0, 0, float('nan')]}}],
     'object "a": pose xyz'),
    ([{'name': 'a', 'sphere': {'radius': 1}, 'pose': {'quat': [0, 0, 0, 1]}}],
     'object "a": pose has unknown key.*quat'),
    ([{'name': 'a', 'mesh': {'scale': 1}}], 'object "a": mesh has no filename'),
])
def test_bad_objects_are_named(tmp_path, objects, culprit):
    path = write_scene(tmp_path, objects)
    with pytest.raises(SceneError, match=culprit) as raised:
        load_scene(path)
    assert str(path) in str(raised.value)


def test_missing_mesh_names_file_object_and_places(tmp_path):
    path = write_scene(tmp_path, [{'name': 'washer', 'mesh': {'filename': 'gone.stl'}}])
    with pytest.raises(SceneError) as raised:
        load_scene(path)
    message = str(raised.value)
    assert f'scene "{path}", object "washer": mesh "gone.stl" not found' in message
    assert str(tmp_path / 'gone.stl') in message
    with pytest.raises(SceneError, match='object "w".*package_paths=.*"nope"'):
        load_scene(write_scene(tmp_path, [{'name': 'w', 'mesh': {
            'filename': 'package://nope/w.stl'}}]))


def test_bad_files_are_named(tmp_path):
    with pytest.raises(SceneError, match='missing.yaml.*cannot read'):
        load_scene(str(tmp_path / 'missing.yaml'))
    broken = tmp_path / 'broken.yaml'
    broken.write_text('objects:\n  - name: [unclosed\n')
    with pytest.raises(SceneError, match='broken.yaml.*broken YAML at line'):
        load_scene(str(broken))
    other = tmp_path / 'other.yaml'
    other.write_text('things: []\n')
    with pytest.raises(SceneError, match='other.yaml.*no top-level "objects"'):
        load_scene(str(other))
    with pytest.raises(SceneError, match='unknown top-level key.*extra'):
        load_scene({'objects': [], 'extra': 1})
