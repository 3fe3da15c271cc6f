"""Forward kinematics against yourdfpy, pinocchio and a plain numpy product of 4x4 matrices."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from collision_sensor.engine.kinematics import (
    JOINT_FIXED, JOINT_PRISMATIC, JOINT_REVOLUTE, build_kinematic_tree)
from collision_sensor.errors import JointStateError, LoadWarning, RobotDescriptionError
from collision_sensor.model.robot_model import load_urdf, resolve_mimics, transform_from_xyz_rpy

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


@pytest.mark.slow
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


# A tree with a floating root, a revolute arm, and a planar and a floating joint inside it (the
# planar one under a rotated origin, the floating one with a prismatic joint above it).
MULTI_DOF_ROBOT = '''<robot name="multi">
  <link name="world"/> <link name="base"/> <link name="arm"/> <link name="slider"/>
  <link name="cart"/> <link name="tool"/>
  <joint name="root" type="floating"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 0.2 0.1"/></joint>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.5" rpy="0 0.4 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="plane" type="planar"><parent link="arm"/><child link="cart"/>
    <origin xyz="0.4 0 0" rpy="0.5 -0.3 1.0"/><axis xyz="0 0 1"/></joint>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="slider"/>
    <origin xyz="0 0.3 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="free" type="floating"><parent link="slider"/><child link="tool"/>
    <origin xyz="0 0 0.2" rpy="1 0 0"/></joint>
</robot>'''


def _pinocchio_q(pin_model, tree, q):
    """pinocchio's q from ours: floating (x, y, z, qx, qy, qz, qw) with the quaternion
    normalised (pinocchio expects a unit one), planar (x, y, cos theta, sin theta)."""
    values = dict(zip(tree.joint_names, q))
    out = np.zeros(pin_model.nq)
    for joint_id in range(1, pin_model.njoints):
        name, joint = pin_model.names[joint_id], pin_model.joints[joint_id]
        i = joint.idx_q
        if joint.nq == 7:
            quaternion = np.array([values[f'{name}/rot_{a}'] for a in 'xyzw'])
            out[i:i + 3] = [values[f'{name}/trans_{a}'] for a in 'xyz']
            out[i + 3:i + 7] = quaternion / np.linalg.norm(quaternion)
        elif joint.nq == 4:
            theta = values[f'{name}/theta']
            out[i:i + 4] = values[f'{name}/x'], values[f'{name}/y'], np.cos(theta), np.sin(theta)
        else:
            out[i] = values[name]
    return out


def _random_multi_dof(tree, n, rng):
    Q = random_configurations(tree, n, int(rng.integers(1 << 30)))
    for j, name in enumerate(tree.joint_names):
        if '/trans_' in name or name.endswith(('/x', '/y')):
            Q[:, j] = rng.uniform(-3, 3, n)
        elif '/rot_' in name:   # any non-zero quaternion, of any norm
            Q[:, j] = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3, n)
    return Q


def test_planar_and_floating_joints_match_pinocchio(tmp_path):
    import pinocchio as pin
    path = write(tmp_path, MULTI_DOF_ROBOT)
    tree = build_kinematic_tree(load_urdf(path))
    assert tree.joint_names == (
        'root/trans_x', 'root/trans_y', 'root/trans_z', 'root/rot_x', 'root/rot_y',
        'root/rot_z', 'root/rot_w', 'shoulder', 'plane/x', 'plane/y', 'plane/theta', 'slide',
        'free/trans_x', 'free/trans_y', 'free/trans_z', 'free/rot_x', 'free/rot_y',
        'free/rot_z', 'free/rot_w')
    assert list(tree.neutral()) == [0] * 6 + [1] + [0] * 11 + [1]
    assert tree.lower[3] == -1 and tree.upper[6] == 1 and np.isinf(tree.lower[10])
    pin_model = pin.buildModelFromUrdf(path)
    data = pin_model.createData()
    frames = [pin_model.getFrameId(name, pin.FrameType.BODY) for name in tree.link_names]
    Q = _random_multi_dof(tree, 300, np.random.default_rng(7))
    ours = tree.forward_kinematics_batch(Q)
    for q, T in zip(Q, ours):
        pin.framesForwardKinematics(pin_model, data, _pinocchio_q(pin_model, tree, q))
        theirs = np.stack([data.oMf[f].homogeneous for f in frames])
        assert np.abs(T - theirs).max() < TOLERANCE


def test_floating_root_matches_pinocchio_free_flyer_on_a_real_robot(panda_urdf,
                                                                    erd_package_paths):
    """panda under pinocchio's JointModelFreeFlyer, and ours under a URDF floating joint from a
    "world" link added to the same file."""
    import pinocchio as pin
    text = open(panda_urdf).read()
    root = load_urdf(panda_urdf, erd_package_paths).root_link
    start = text.index('>', text.index('<robot')) + 1
    text = (text[:start] + '<link name="fk_world"/><joint name="fk_base" type="floating">'
            f'<parent link="fk_world"/><child link="{root}"/></joint>' + text[start:])
    model = load_urdf(text, erd_package_paths)
    tree = build_kinematic_tree(model)
    mimics = resolve_mimics(model.joints)
    assert tree.joint_names[:7] == tuple(f'fk_base/{v}' for v in (
        'trans_x', 'trans_y', 'trans_z', 'rot_x', 'rot_y', 'rot_z', 'rot_w'))
    pin_model = pin.buildModelFromUrdf(panda_urdf, pin.JointModelFreeFlyer())
    data = pin_model.createData()
    frames = [pin_model.getFrameId(name, pin.FrameType.BODY) for name in tree.link_names[1:]]
    Q = _random_multi_dof(tree, 100, np.random.default_rng(3))
    for q, T in zip(Q, tree.forward_kinematics_batch(Q)):
        values = dict(zip(tree.joint_names, q))
        values.update({name: m * values[source] + o for name, (source, m, o) in mimics.items()})
        pq = pin.neutral(pin_model)
        pq[:3] = q[:3]
        pq[3:7] = q[3:7] / np.linalg.norm(q[3:7])   # pinocchio's order x, y, z, w too
        for joint_id in range(2, pin_model.njoints):
            pq[pin_model.joints[joint_id].idx_q] = values[pin_model.names[joint_id]]
        pin.framesForwardKinematics(pin_model, data, pq)
        theirs = np.stack([data.oMf[f].homogeneous for f in frames])
        assert np.abs(T[1:] - theirs).max() < TOLERANCE


def test_a_planar_axis_other_than_z_is_tolerated_with_a_warning(tmp_path):
    """The plane is the joint frame's x-y plane whatever the axis (MoveIt, pinocchio)."""
    text = MULTI_DOF_ROBOT.replace('<axis xyz="0 0 1"/></joint>', '<axis xyz="1 0 0"/></joint>')
    with pytest.warns(LoadWarning, match='joint "plane" \\(planar\\) has <axis xyz="1 0 0">.*'
                                         'x-y plane'):
        tree = build_kinematic_tree(load_urdf(write(tmp_path, text)))
    reference = build_kinematic_tree(load_urdf(write(tmp_path, MULTI_DOF_ROBOT, 'b.urdf')))
    Q = _random_multi_dof(tree, 20, np.random.default_rng(1))
    assert np.array_equal(tree.forward_kinematics_batch(Q),
                          reference.forward_kinematics_batch(Q))


def test_a_multi_dof_joint_in_a_mimic_is_refused_when_built_by_hand(tmp_path):
    import dataclasses
    from collision_sensor.model.robot_model import Mimic
    model = load_urdf(write(tmp_path, MULTI_DOF_ROBOT))
    joints = tuple(dataclasses.replace(j, mimic=Mimic('shoulder', 1.0, 0.0))
                   if j.name == 'plane' else j for j in model.joints)
    with pytest.raises(RobotDescriptionError, match='joint "plane" \\(planar\\) mimics joint '
                                                    '"shoulder"'):
        build_kinematic_tree(dataclasses.replace(model, joints=joints))
