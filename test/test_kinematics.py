"""Forward kinematics against yourdfpy, pinocchio and a plain numpy product of 4x4 matrices."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from collision_sensor.errors import JointStateError, LoadWarning, RobotDescriptionError
from collision_sensor.kinematics import (
    JOINT_FIXED, JOINT_PRISMATIC, JOINT_REVOLUTE, build_kinematic_tree, forward_kinematics_kernel)
from collision_sensor.robot_model import load_urdf, transform_from_xyz_rpy

N_CONFIGS = 1000
TOLERANCE = 1e-9


def random_configurations(tree, n, seed):
    """Return (n, J) configurations drawn uniformly within limits (continuous: [-2 pi, 2 pi])."""
    rng = np.random.default_rng(seed)
    lower = np.where(np.isfinite(tree.lower), tree.lower, -2 * np.pi)
    upper = np.where(np.isfinite(tree.upper), tree.upper, 2 * np.pi)
    return rng.uniform(lower, upper, size=(n, len(lower)))


def load_yourdfpy(path):
    import yourdfpy
    return yourdfpy.URDF.load(path, build_collision_scene_graph=False, load_meshes=False,
                              build_scene_graph=True)


def yourdfpy_poses(robot, tree, q):
    robot.update_cfg(dict(zip(tree.joint_names, q)))
    root = tree.link_names[0]
    return np.stack([robot.get_transform(link, root) for link in tree.link_names])


def write(tmp_path, text, name='robot.urdf'):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


# --- the real robots --------------------------------------------------------------------------

@pytest.fixture(scope='module', params=['panda', 'ur5'])
def real_robot(request):
    urdf = request.getfixturevalue(f'{request.param}_urdf')
    model = load_urdf(urdf, request.getfixturevalue('erd_package_paths'))
    return urdf, model, build_kinematic_tree(model)


def test_fk_matches_yourdfpy_on_real_robots(real_robot):
    urdf, _, tree = real_robot
    robot = load_yourdfpy(urdf)
    assert tuple(robot.actuated_joint_names) == tree.joint_names
    Q = random_configurations(tree, N_CONFIGS, seed=1)
    batch = tree.forward_kinematics_batch(Q)
    for k, q in enumerate(Q):
        expected = yourdfpy_poses(robot, tree, q)
        single = tree.forward_kinematics(q)
        np.testing.assert_allclose(single, expected, rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(batch[k], expected, rtol=0, atol=TOLERANCE)


def test_fk_matches_pinocchio_on_real_robots(real_robot):
    import pinocchio as pin
    urdf, model, tree = real_robot
    pin_model = pin.buildModelFromUrdf(urdf)
    data = pin_model.createData()
    mimics = {joint.name: joint.mimic for joint in model.joints if joint.mimic is not None}
    frame_ids = [pin_model.getFrameId(link) for link in tree.link_names]
    assert all(frame_id < pin_model.nframes for frame_id in frame_ids)
    Q = random_configurations(tree, N_CONFIGS, seed=2)
    batch = tree.forward_kinematics_batch(Q)
    for k, q in enumerate(Q):
        values = dict(zip(tree.joint_names, q))
        # pinocchio loads a mimic joint as an independent one: give it the mimicked value.
        for name, mimic in mimics.items():
            values[name] = mimic.multiplier * values[mimic.joint] + mimic.offset
        pin_q = pin.neutral(pin_model)
        for joint_id in range(1, pin_model.njoints):  # pinocchio's order differs: map by name
            value = values[pin_model.names[joint_id]]
            index, nq = pin_model.joints[joint_id].idx_q, pin_model.joints[joint_id].nq
            pin_q[index:index + nq] = [value] if nq == 1 else [np.cos(value), np.sin(value)]
        pin.forwardKinematics(pin_model, data, pin_q)
        pin.updateFramePlacements(pin_model, data)
        T_root = data.oMf[frame_ids[0]].homogeneous
        expected = np.stack([np.linalg.solve(T_root, data.oMf[f].homogeneous)
                             for f in frame_ids])
        np.testing.assert_allclose(tree.forward_kinematics(q), expected, rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(batch[k], expected, rtol=0, atol=TOLERANCE)


def test_panda_tree_arrays(real_robot):
    _, model, tree = real_robot
    assert tree.link_names == model.links
    assert tree.parent[0] == -1 and tree.joint_type[0] == JOINT_FIXED
    assert all(tree.parent[i] < i for i in range(1, len(tree.link_names)))
    if model.name == 'panda':
        assert tree.joint_names == tuple(f'panda_joint{i}' for i in range(1, 8)) + (
            'panda_finger_joint1',)
        right = tree.link_names.index('panda_rightfinger')
        left = tree.link_names.index('panda_leftfinger')
        assert tree.q_index[right] == tree.q_index[left] == 7
        assert tree.joint_type[right] == JOINT_PRISMATIC
        assert tree.link_joint[right] == 'panda_finger_joint2'


# --- small robots written here, against an independent product of matrices -------------------

CHAIN_URDF = """<?xml version="1.0"?>
<robot name="chain">
  <link name="base"/> <link name="a"/> <link name="b"/> <link name="c"/> <link name="d"/>
  <link name="e"/> <link name="f"/> <link name="tool"/>
  <!-- document order differs from the depth-first link order on purpose -->
  <joint name="j_e" type="revolute">
    <parent link="base"/> <child link="e"/>
    <origin xyz="0 0.3 0.1" rpy="0.2 0 0"/> <axis xyz="1 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="j_a" type="continuous">
    <parent link="base"/> <child link="a"/>
    <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.1"/> <axis xyz="0 0 2"/>
  </joint>
  <joint name="j_b" type="prismatic">
    <parent link="a"/> <child link="b"/>
    <origin xyz="0 0 0.5" rpy="0 1.0 0"/> <axis xyz="0.6 0.8 0"/>
    <limit lower="-0.2" upper="0.4" effort="1" velocity="1"/>
  </joint>
  <joint name="j_c" type="revolute">
    <parent link="b"/> <child link="c"/>
    <origin xyz="0.2 0 0" rpy="-0.4 0.5 2.0"/> <axis xyz="0.3 -0.5 0.8"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
    <mimic joint="j_a" multiplier="-1.5" offset="0.25"/>
  </joint>
  <joint name="j_d" type="revolute">
    <parent link="c"/> <child link="d"/>
    <origin xyz="0 0.1 0" rpy="0 0 0"/> <axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
    <mimic joint="j_c" multiplier="0.5" offset="-0.1"/>
  </joint>
  <joint name="j_f" type="prismatic">
    <parent link="e"/> <child link="f"/>
    <origin xyz="0.05 0 0" rpy="0 0 0.7"/> <axis xyz="0 0 1"/>
    <limit lower="0" upper="0.3" effort="1" velocity="1"/>
    <mimic joint="j_d" multiplier="2.0" offset="0.05"/>
  </joint>
  <joint name="j_tool" type="fixed">
    <parent link="d"/> <child link="tool"/>
    <origin xyz="0 0 0.15" rpy="0.1 0.2 0.3"/>
  </joint>
</robot>
"""


def oracle_chain(q):
    """Poses of CHAIN_URDF's links written out by hand: (j_e, j_a, j_b) = q."""
    j_e, j_a, j_b = q
    j_c = -1.5 * j_a + 0.25
    j_d = 0.5 * j_c - 0.1
    j_f = 2.0 * j_d + 0.05

    def rot(axis, angle):
        T = np.eye(4)
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        T[:3, :3] = Rotation.from_rotvec(axis * angle).as_matrix()
        return T

    def slide(axis, d):
        T = np.eye(4)
        T[:3, 3] = np.asarray(axis, float) / np.linalg.norm(axis) * d
        return T

    O = transform_from_xyz_rpy
    base = np.eye(4)
    a = base @ O([0.1, 0.2, 0.3], [0.3, -0.2, 0.1]) @ rot([0, 0, 1], j_a)
    b = a @ O([0, 0, 0.5], [0, 1.0, 0]) @ slide([0.6, 0.8, 0], j_b)
    c = b @ O([0.2, 0, 0], [-0.4, 0.5, 2.0]) @ rot([0.3, -0.5, 0.8], j_c)
    d = c @ O([0, 0.1, 0], [0, 0, 0]) @ rot([0, 1, 0], j_d)
    tool = d @ O([0, 0, 0.15], [0.1, 0.2, 0.3])
    e = base @ O([0, 0.3, 0.1], [0.2, 0, 0]) @ rot([1, 1, 0], j_e)
    f = e @ O([0.05, 0, 0], [0, 0, 0.7]) @ slide([0, 0, 1], j_f)
    return {'base': base, 'a': a, 'b': b, 'c': c, 'd': d, 'tool': tool, 'e': e, 'f': f}


def test_transform_from_xyz_rpy_matches_scipy():
    rng = np.random.default_rng(3)
    for _ in range(100):
        xyz, rpy = rng.normal(size=3), rng.uniform(-np.pi, np.pi, size=3)
        T = transform_from_xyz_rpy(xyz, rpy)
        np.testing.assert_allclose(T[:3, :3], Rotation.from_euler('xyz', rpy).as_matrix(),
                                   atol=1e-14)
        np.testing.assert_allclose(T[:3, 3], xyz)


def test_chain_tree_layout(tmp_path):
    tree = build_kinematic_tree(load_urdf(write(tmp_path, CHAIN_URDF)))
    assert tree.link_names == ('base', 'e', 'f', 'a', 'b', 'c', 'd', 'tool')
    assert tree.joint_names == ('j_e', 'j_a', 'j_b')   # document order, mimics left out
    index = {name: i for i, name in enumerate(tree.link_names)}
    # j_f mimics j_d mimics j_c mimics j_a: 2 (0.5 (-1.5 q + 0.25) - 0.1) + 0.05
    assert tree.q_index[index['f']] == 1
    assert tree.multiplier[index['f']] == pytest.approx(-1.5)
    assert tree.offset[index['f']] == pytest.approx(2 * (0.5 * 0.25 - 0.1) + 0.05)
    assert tree.joint_type[index['a']] == JOINT_REVOLUTE
    assert tree.joint_type[index['tool']] == JOINT_FIXED
    assert tree.lower[1] == -np.inf and tree.upper[1] == np.inf


def test_chain_fk_matches_matrix_product(tmp_path):
    tree = build_kinematic_tree(load_urdf(write(tmp_path, CHAIN_URDF)))
    Q = random_configurations(tree, N_CONFIGS, seed=4)
    batch = tree.forward_kinematics_batch(Q)
    for k, q in enumerate(Q):
        oracle = oracle_chain(q)
        expected = np.stack([oracle[link] for link in tree.link_names])
        np.testing.assert_allclose(tree.forward_kinematics(q), expected, rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(batch[k], expected, rtol=0, atol=TOLERANCE)


def test_single_level_mimic_matches_yourdfpy(tmp_path):
    # yourdfpy resolves one level of mimic (not chains): cut the chain after j_c.
    text = CHAIN_URDF.replace('<mimic joint="j_c" multiplier="0.5" offset="-0.1"/>', '')
    text = text.replace('<mimic joint="j_d" multiplier="2.0" offset="0.05"/>',
                        '<mimic joint="j_b" multiplier="2.0" offset="0.05"/>')
    path = write(tmp_path, text)
    tree = build_kinematic_tree(load_urdf(path))
    assert tree.joint_names == ('j_e', 'j_a', 'j_b', 'j_d')
    robot = load_yourdfpy(path)
    for q in random_configurations(tree, 200, seed=5):
        np.testing.assert_allclose(tree.forward_kinematics(q), yourdfpy_poses(robot, tree, q),
                                   rtol=0, atol=TOLERANCE)


def test_kernel_fills_the_callers_buffer(tmp_path):
    # The kernel writes into a buffer the caller owns (the query engine's way of calling it).
    tree = build_kinematic_tree(load_urdf(write(tmp_path, CHAIN_URDF)))
    q = np.array([0.3, -0.7, 0.1])
    scratch = np.empty((len(tree.link_names), 4, 4))
    forward_kinematics_kernel(q, tree.parent, tree.joint_type, tree.T_parent_joint, tree.axis,
                              tree.q_index, tree.multiplier, tree.offset, scratch)
    position = scratch[-1, :3, 3].copy()
    np.testing.assert_allclose(position, tree.forward_kinematics(q)[-1, :3, 3])


def test_single_link_robot(tmp_path):
    tree = build_kinematic_tree(load_urdf(write(
        tmp_path, '<robot name="r"><link name="only"/></robot>')))
    assert tree.joint_names == ()
    np.testing.assert_array_equal(tree.forward_kinematics([]), np.eye(4)[None])
    assert tree.forward_kinematics_batch(np.zeros((3, 0))).shape == (3, 1, 4, 4)


def test_wrong_q_shape_names_the_joints(tmp_path):
    tree = build_kinematic_tree(load_urdf(write(tmp_path, CHAIN_URDF)))
    with pytest.raises(JointStateError, match='j_e, j_a, j_b'):
        tree.forward_kinematics([0.0, 1.0])
    with pytest.raises(JointStateError, match=r'\(n, J\)'):
        tree.forward_kinematics_batch(np.zeros(3))


def test_mimic_cycle_is_refused(tmp_path):
    # j_c mimics j_a; make j_a mimic j_d, closing a cycle.
    text = CHAIN_URDF.replace('<axis xyz="0 0 2"/>', '<axis xyz="0 0 2"/><mimic joint="j_d"/>')
    with pytest.raises(RobotDescriptionError, match='mimic cycle') as raised:
        load_urdf(write(tmp_path, text))
    assert 'j_a' in str(raised.value)


@pytest.mark.parametrize('mimic, culprit', [
    ('<mimic joint="nowhere"/>', '"nowhere", which does not exist'),
    ('<mimic joint="j_tool"/>', '"j_tool" \\(fixed\\), which has another number of variables'),
])
def test_mimic_of_a_missing_or_fixed_joint_leaves_the_joint_independent(tmp_path, mimic,
                                                                         culprit):
    # As MoveIt: the mimic is ignored with a warning, j_a keeps its own variable.
    text = CHAIN_URDF.replace('<axis xyz="0 0 2"/>', '<axis xyz="0 0 2"/>' + mimic)
    with pytest.warns(LoadWarning, match=f'joint "j_a" .*{culprit}'):
        model = load_urdf(write(tmp_path, text))
    assert 'j_a' in build_kinematic_tree(model).joint_names
