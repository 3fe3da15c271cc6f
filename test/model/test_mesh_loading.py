"""Mesh URIs, mesh files and tessellated primitives."""
import os
import re

import numpy as np
import pytest
import trimesh

from collision_sensor.errors import ConfigError, MeshError, SceneError
from collision_sensor.model import mesh_loading
from collision_sensor.model.mesh_loading import (
    box_mesh, cylinder_mesh, load_mesh_file, resolve_mesh_uri, sphere_mesh)


def check_arrays(vertices, faces):
    assert vertices.dtype == np.float64 and vertices.flags.c_contiguous and vertices.shape[1] == 3
    assert faces.dtype == np.int64 and faces.flags.c_contiguous and faces.shape[1] == 3
    assert faces.min() >= 0 and faces.max() < len(vertices)


def closed_volume(vertices, faces):
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    return mesh.volume


# --- primitives -------------------------------------------------------------------------------

def test_box():
    vertices, faces = box_mesh([1.0, 2.0, 3.0])
    check_arrays(vertices, faces)
    assert faces.shape == (12, 3)
    np.testing.assert_array_equal(np.abs(vertices), np.tile([0.5, 1.0, 1.5], (8, 1)))
    assert closed_volume(vertices, faces) == pytest.approx(6.0)   # positive: outward winding


@pytest.mark.parametrize('sections', [3, 7, 32])
def test_cylinder_is_inscribed(sections):
    vertices, faces = cylinder_mesh(0.5, 2.0, sections)
    check_arrays(vertices, faces)
    assert vertices.shape == (2 * sections + 2, 3) and faces.shape == (4 * sections, 3)
    rim = vertices[:2 * sections]
    np.testing.assert_allclose(np.hypot(rim[:, 0], rim[:, 1]), 0.5)
    np.testing.assert_allclose(np.abs(vertices[:, 2]), 1.0)
    polygon_area = 0.5 * sections * 0.25 * np.sin(2 * np.pi / sections)
    assert closed_volume(vertices, faces) == pytest.approx(polygon_area * 2.0)


@pytest.mark.parametrize('sections, count', [(3, 5), (4, 6), (32, 482)])
def test_sphere_is_inscribed(sections, count):
    vertices, faces = sphere_mesh(0.3, sections)
    check_arrays(vertices, faces)
    stacks = max(2, sections // 2)
    assert len(vertices) == count == sections * (stacks - 1) + 2
    assert len(faces) == 2 * sections * (stacks - 1)
    np.testing.assert_allclose(np.linalg.norm(vertices, axis=1), 0.3)
    volume = closed_volume(vertices, faces)
    assert 0 < volume < 4 / 3 * np.pi * 0.3 ** 3


def test_too_few_sections_is_refused():
    with pytest.raises(ConfigError, match='at least 3'):
        cylinder_mesh(1.0, 1.0, 2)


# --- files ------------------------------------------------------------------------------------

@pytest.fixture
def tetra_files(tmp_path):
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                           [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=False)
    paths = {}
    for extension in ('stl', 'obj', 'ply', 'dae'):
        paths[extension] = str(tmp_path / f'tetra.{extension}')
        mesh.export(paths[extension])
    return paths


@pytest.mark.parametrize('extension', ['stl', 'obj', 'ply', 'dae'])
def test_every_format_loads_with_scale(tetra_files, extension):
    vertices, faces = load_mesh_file(tetra_files[extension], [2.0, 3.0, 4.0])
    check_arrays(vertices, faces)
    assert len(faces) == 4
    np.testing.assert_allclose(vertices.max(axis=0), [2.0, 3.0, 4.0])


def write_two_box_dae(path):
    """Write a COLLADA file with one box geometry placed twice: at the origin and at x = 10."""
    import collada
    box = trimesh.creation.box([1, 1, 1])
    document = collada.Collada()
    source = collada.source.FloatSource('box-vertices', box.vertices.ravel(), ('X', 'Y', 'Z'))
    geometry = collada.geometry.Geometry(document, 'box', 'box', [source])
    inputs = collada.source.InputList()
    inputs.addInput(0, 'VERTEX', '#box-vertices')
    geometry.primitives.append(geometry.createTriangleSet(box.faces.ravel(), inputs, 'none'))
    document.geometries.append(geometry)
    nodes = [collada.scene.Node('a', [collada.scene.GeometryNode(geometry, [])]),
             collada.scene.Node('b', [collada.scene.GeometryNode(geometry, [])],
                                transforms=[collada.scene.TranslateTransform(10, 0, 0)])]
    document.scenes.append(collada.scene.Scene('scene', nodes))
    document.scene = document.scenes[0]
    document.write(path)


def test_scene_files_are_flattened_with_their_transforms(tmp_path):
    path = str(tmp_path / 'two.dae')
    write_two_box_dae(path)
    vertices, faces = load_mesh_file(path)
    assert len(faces) == 24
    np.testing.assert_allclose([vertices[:, 0].min(), vertices[:, 0].max()], [-0.5, 10.5])


def test_collada_units_are_applied(tetra_files, tmp_path):
    with open(tetra_files['dae']) as stream:
        text = stream.read()
    text = re.sub(r'<unit[^>]*/>', '', text)
    millimetres = tmp_path / 'tetra_mm.dae'
    millimetres.write_text(re.sub(r'<asset>', '<asset><unit meter="0.001" name="millimeter"/>',
                                  text, count=1))
    vertices, _ = load_mesh_file(str(millimetres), [2.0, 1.0, 1.0])
    np.testing.assert_allclose(vertices.max(axis=0), [0.002, 0.001, 0.001])


@pytest.mark.parametrize('axis', ['X_UP', 'Y_UP', 'Z_UP'])
def test_collada_up_axis_is_not_applied_as_in_ros_tools(tetra_files, tmp_path, axis):
    # assimp puts the up-axis rotation in the root node transform, which MoveIt
    # (geometric_shapes) and RViz reset: vertices are used in the file's own axes.
    with open(tetra_files['dae']) as stream:
        text = re.sub(r'<up_axis>[^<]*</up_axis>', '', stream.read())
    path = tmp_path / f'tetra_{axis}.dae'
    path.write_text(text.replace('</asset>', f'<up_axis>{axis}</up_axis></asset>', 1))
    vertices, _ = load_mesh_file(str(path), [2.0, 3.0, 4.0])
    np.testing.assert_allclose(vertices.max(axis=0), [2.0, 3.0, 4.0])


def test_real_y_up_collada_stays_in_the_link_frame(erd_share):
    # go1's trunk.dae declares Y_UP but is authored in the link frame (x forward, z up), like
    # 87 of the example-robot-data DAE files: turning it to Z-up would stand the trunk on end.
    path = os.path.join(erd_share, 'robots', 'go1_description', 'meshes', 'trunk.dae')
    with open(path) as stream:
        assert '<up_axis>Y_UP</up_axis>' in stream.read()
    vertices, _ = load_mesh_file(path)
    extent = vertices.max(axis=0) - vertices.min(axis=0)
    assert extent[0] > 0.4 and extent[2] < 0.15   # long along x, flat along z


def test_degenerate_triangles_are_kept(tmp_path):
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]],
                           [[0, 1, 2], [0, 1, 3]], process=False)   # the second has zero area
    path = str(tmp_path / 'flat.stl')
    mesh.export(path)
    assert len(load_mesh_file(path)[1]) == 2


def test_results_are_fresh_arrays(tetra_files):
    first, _ = load_mesh_file(tetra_files['stl'])
    first[:] = 99.0
    second, _ = load_mesh_file(tetra_files['stl'])
    assert second.max() == 1.0


def test_unreadable_and_empty_meshes_are_refused(tmp_path):
    garbage = tmp_path / 'garbage.dae'
    garbage.write_bytes(b'not a collada document')
    with pytest.raises(MeshError, match='link "l".*garbage.dae.*cannot be read.*valid DAE'):
        load_mesh_file(str(garbage), owner='link "l"')
    points = tmp_path / 'points.ply'
    trimesh.PointCloud([[0, 0, 0], [1, 0, 0]]).export(str(points))
    with pytest.raises(MeshError, match='points.ply.*no triangles'):
        load_mesh_file(str(points))
    empty = tmp_path / 'empty.stl'
    empty.write_bytes(b'\x00' * 10)
    with pytest.raises(MeshError, match='empty.stl.*no triangles'):
        load_mesh_file(str(empty))
    with pytest.raises(SceneError, match='"part.step".*convert it to STL'):
        load_mesh_file(str(tmp_path / 'part.step'), uri='part.step', error=SceneError)


# --- URIs -------------------------------------------------------------------------------------

@pytest.fixture
def package_tree(tmp_path):
    """``<tmp>/ws/my_robot/{urdf/r.urdf, meshes/m.stl}``, the example-robot-data layout."""
    root = tmp_path / 'ws' / 'my_robot'
    (root / 'urdf').mkdir(parents=True)
    (root / 'meshes').mkdir()
    (root / 'meshes' / 'm.stl').write_bytes(b'')
    return root


def test_explicit_package_path_comes_first(package_tree, tmp_path):
    other = tmp_path / 'other'
    (other / 'meshes').mkdir(parents=True)
    (other / 'meshes' / 'm.stl').write_bytes(b'')
    found = resolve_mesh_uri('package://my_robot/meshes/m.stl', {'my_robot': str(other)},
                             str(package_tree / 'urdf'))
    assert found == os.path.join(str(other), 'meshes/m.stl')


def test_package_uri_found_by_walking_up_from_the_urdf(package_tree):
    base = str(package_tree / 'urdf')
    assert resolve_mesh_uri('package://my_robot/meshes/m.stl', None, base) == str(
        package_tree / 'meshes' / 'm.stl')
    # example-robot-data style: the URI repeats the directory above the package.
    assert resolve_mesh_uri('package://ws/my_robot/meshes/m.stl', None, base) == os.path.join(
        str(package_tree.parent), 'my_robot/meshes/m.stl')


def test_package_uri_of_this_package_uses_the_share_directory(monkeypatch, tmp_path):
    (tmp_path / 'meshes').mkdir()
    (tmp_path / 'meshes' / 'x.stl').write_bytes(b'')
    monkeypatch.setattr('collision_sensor.model.share.share_directory', lambda: str(tmp_path))
    for variable in ('AMENT_PREFIX_PATH', 'ROS_PACKAGE_PATH'):  # no install found first
        monkeypatch.delenv(variable, raising=False)
    assert resolve_mesh_uri('package://collision_sensor/meshes/x.stl') == os.path.join(
        str(tmp_path), 'meshes/x.stl')


def _ament_prefix(prefix, name):
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True, exist_ok=True)
    (index / name).write_text('')
    (prefix / 'share' / name).mkdir(parents=True, exist_ok=True)
    (prefix / 'share' / name / 'x.stl').write_bytes(b'')
    return prefix / 'share' / name / 'x.stl'


def _source_package(root, name):
    (root / name).mkdir(parents=True)
    (root / name / 'package.xml').write_text(f'<package format="3"><name>{name}</name></package>')
    (root / name / 'x.stl').write_bytes(b'')
    return root / name / 'x.stl'


def test_package_uri_order_explicit_then_ament_then_ros_package_path(monkeypatch, tmp_path):
    first = _ament_prefix(tmp_path / 'overlay', 'pkg')
    second = _ament_prefix(tmp_path / 'underlay', 'pkg')
    crawled = _source_package(tmp_path / 'src' / 'deep', 'pkg')
    monkeypatch.setenv('AMENT_PREFIX_PATH', f'{tmp_path / "overlay"}:{tmp_path / "underlay"}')
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path / 'src'))
    explicit = tmp_path / 'explicit'
    explicit.mkdir()
    (explicit / 'x.stl').write_bytes(b'')
    assert resolve_mesh_uri('package://pkg/x.stl', {'pkg': str(explicit)}) == str(
        explicit / 'x.stl')
    assert resolve_mesh_uri('package://pkg/x.stl') == str(first)   # the overlay first
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'underlay'))
    assert resolve_mesh_uri('package://pkg/x.stl') == str(second)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'nothing'))
    # rospack: the package.xml <name> counts, found at any depth below the entry.
    assert resolve_mesh_uri('package://pkg/x.stl') == str(crawled)


def test_unresolved_package_names_the_package_and_every_place(monkeypatch, tmp_path):
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'prefix'))
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path / 'src'))
    with pytest.raises(MeshError) as raised:
        resolve_mesh_uri('package://lost/x.stl', None, None, owner='link "a"')
    message = str(raised.value)
    assert 'of package "lost" not found' in message
    assert 'package_paths (no entry "lost")' in message
    assert f'ament index {tmp_path}/prefix/share/ament_index/resource_index/packages/lost' in (
        message)
    assert f'ROS_PACKAGE_PATH entry {tmp_path}/src' in message
    assert '--package-path lost=DIR' in message


def test_file_and_relative_uris(package_tree, monkeypatch):
    mesh = str(package_tree / 'meshes' / 'm.stl')
    assert resolve_mesh_uri('file://' + mesh) == mesh
    assert resolve_mesh_uri('../meshes/m.stl', None, str(package_tree / 'urdf')) == mesh
    monkeypatch.chdir(package_tree)
    assert resolve_mesh_uri('meshes/m.stl') == mesh   # XML text: the current directory


def test_missing_package_mesh_names_owner_uri_places_and_fix(package_tree):
    with pytest.raises(MeshError) as raised:
        resolve_mesh_uri('package://lost/meshes/gone.stl', {'lost': '/nowhere'},
                         str(package_tree / 'urdf'), owner='link "forearm"')
    message = str(raised.value)
    assert 'link "forearm"' in message and '"package://lost/meshes/gone.stl"' in message
    assert '/nowhere/meshes/gone.stl' in message
    assert os.path.join(str(package_tree / 'urdf'), 'meshes/gone.stl') in message
    assert os.path.join(str(package_tree), 'meshes/gone.stl') in message
    assert 'package_paths={"lost": DIR}' in message and '--package-path lost=DIR' in message


def test_unresolved_package_gives_the_fix_for_every_place_that_takes_package_paths(
        monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.delenv('ROS_PACKAGE_PATH', raising=False)
    with pytest.raises(MeshError) as raised:
        resolve_mesh_uri('package://lost/x.stl', None, None, owner='link "a"')
    message = str(raised.value)
    assert '--package-path lost=DIR (command line)' in message
    assert 'package_paths: ["lost=DIR"] (node parameter)' in message
    assert 'package_paths={"lost": DIR} (Python)' in message


@pytest.fixture
def forearm_package(tmp_path):
    root = tmp_path / 'arm'
    (root / 'meshes' / 'collision').mkdir(parents=True)
    for name in ('forearm.stl', 'upper_arm.stl', 'Wrist.STL'):
        (root / 'meshes' / 'collision' / name).write_bytes(b'')
    return root


@pytest.mark.parametrize('rest, close', [
    ('meshes/collision/forarm.stl', 'meshes/collision/forearm.stl'),       # a letter lost
    ('mesh/collision/forearm.stl', 'meshes/collision/forearm.stl'),        # the folder
    ('meshes/collison/upperarm.stl', 'meshes/collision/upper_arm.stl'),    # both
    ('meshes/collision/wrist.stl', 'meshes/collision/Wrist.STL'),          # case only
    ('meshes/collision/gripper.stl', None),                                # nothing close
    ('nothing/here/at_all.stl', None),
])
def test_closest_file_replaces_each_missing_component(forearm_package, rest, close):
    assert mesh_loading.closest_file(str(forearm_package), rest) == close


def test_a_misspelt_mesh_in_a_found_package_names_the_file_not_package_paths(forearm_package):
    """The package was found: giving its directory again cannot help, so the message does not
    say to (it ended with package_paths syntax before)."""
    with pytest.raises(MeshError) as raised:
        resolve_mesh_uri('package://arm/meshes/collision/forarm.stl',
                         {'arm': str(forearm_package)}, None, owner='link "forearm"')
    message = str(raised.value)
    assert message.startswith('link "forearm": mesh "package://arm/meshes/collision/forarm.stl" '
                              f'not found: package "arm" is at {forearm_package} and has no '
                              'file meshes/collision/forarm.stl'), message
    assert message.endswith('did you mean "package://arm/meshes/collision/forearm.stl"? Fix '
                            'the file name in the description'), message
    assert 'package_paths' not in message and '--package-path' not in message
    with pytest.raises(MeshError) as raised:
        resolve_mesh_uri('package://arm/meshes/collision/gripper.stl',
                         {'arm': str(forearm_package)}, None, owner='link "hand"')
    assert str(raised.value).endswith(
        'check the file name, and that package "arm" installs its meshes (look in '
        f'{forearm_package}/meshes/collision)')


def test_a_misspelt_mesh_of_a_real_robot_from_the_command_line(erd_share, tmp_path):
    """As a user meets it: the UR5 of example-robot-data with one mesh name misspelt, through
    collision_sensor_acm in a process of its own."""
    import subprocess
    from collision_sensor.ros.console_scripts import console_command
    source = os.path.join(erd_share, 'robots', 'ur_description', 'urdf', 'ur5_robot.urdf')
    with open(source) as stream:
        text = stream.read()
    good = 'ur_description/meshes/ur5/collision/forearm.stl'
    assert good in text
    urdf = tmp_path / 'ur5_typo.urdf'
    urdf.write_text(text.replace(good, good.replace('forearm', 'forarm')))
    run = subprocess.run(console_command('collision_sensor_acm') + [
        str(urdf), '--package-path', f'example-robot-data={erd_share}', '--progress', 'never'],
        capture_output=True, text=True, timeout=120, cwd=str(tmp_path))
    assert run.returncode == 2, run.stdout + run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('collision_sensor_acm: error: '), run.stderr
    assert 'link "forearm_link"' in lines[0]
    assert lines[0].endswith('did you mean "package://example-robot-data/robots/ur_description/'
                             'meshes/ur5/collision/forearm.stl"? Fix the file name in the '
                             'description'), lines[0]


def test_missing_mesh_of_text_description_says_what_was_searched():
    with pytest.raises(MeshError, match='XML text'):
        resolve_mesh_uri('package://lost/m.stl', None, None, owner='link "a"')
    with pytest.raises(MeshError, match='current directory'):
        resolve_mesh_uri('not/here.stl', None, None, owner='link "a"')


def test_only_regular_files_are_read_as_meshes(tmp_path):
    """A description from the ROS graph names its meshes: a device or a FIFO is refused at
    once (never read, never waited on)."""
    import os
    fifo = tmp_path / 'pipe.stl'
    os.mkfifo(fifo)
    zero = tmp_path / 'zero.stl'
    os.symlink('/dev/zero', zero)
    for path in (str(zero), str(fifo)):
        with pytest.raises(MeshError, match='not a regular file'):
            load_mesh_file(path)
