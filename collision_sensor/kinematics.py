"""Forward kinematics of a robot model over flat arrays, compiled with numba.

A :class:`KinematicTree` holds the tree as structure-of-arrays indexed by link (``L`` links,
root first, every parent before its children), and the configuration ``q`` holds one value per
movable, non-mimic joint (``J`` values, URDF document order). Each link ``i`` except the root is
reached through the joint above it::

    value = multiplier[i] * q[q_index[i]] + offset[i]     # mimic chains already composed
    T_world_link[i] = T_world_link[parent[i]] @ T_parent_joint[i] @ M(joint_type[i], value)

    M(FIXED)     = I
    M(REVOLUTE)  = [Rodrigues(axis[i], value), 0; 0, 1]   # continuous joints too
    M(PRISMATIC) = [I, value * axis[i]; 0, 1]

"world" is the root link's frame: ``T_world_link[0]`` is the identity.

:func:`forward_kinematics_kernel` is a plain ``@njit`` function over those arrays so that other
compiled kernels (the collision engine) call it directly; it allocates nothing. Kernels are
cached on disk (``cache=True``): the first process compiles them, later ones load them.
"""
import dataclasses
from dataclasses import dataclass

import numpy as np
from numba import njit

from collision_sensor.errors import JointStateError, RobotDescriptionError
from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.robot_model import RobotModel, resolve_mimics

JOINT_FIXED, JOINT_REVOLUTE, JOINT_PRISMATIC = 0, 1, 2
_JOINT_CODES = {'fixed': JOINT_FIXED, 'revolute': JOINT_REVOLUTE,
                'continuous': JOINT_REVOLUTE, 'prismatic': JOINT_PRISMATIC}


@njit(cache=True, nogil=True, fastmath=False, inline='always')
def set_link_pose(i, q, parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset,
                  T_world_link):
    """Write link ``i``'s world pose from its parent's (already current) pose.

    ``T_world_link[i] = T_world_link[parent[i]] @ T_parent_joint[i] @ motion(value)``, with
    ``value = multiplier[i] * q[q_index[i]] + offset[i]``; the root gets its origin alone.
    Parameters as for :func:`forward_kinematics_kernel`.
    """
    # Plain indexing, no row views: a view costs two atomic reference-count updates, more
    # than the arithmetic of a link.
    J = T_parent_joint
    # M = T_parent_joint @ motion, as 12 scalars (rotation m.., translation t.).
    m00, m01, m02, t0 = J[i, 0, 0], J[i, 0, 1], J[i, 0, 2], J[i, 0, 3]
    m10, m11, m12, t1 = J[i, 1, 0], J[i, 1, 1], J[i, 1, 2], J[i, 1, 3]
    m20, m21, m22, t2 = J[i, 2, 0], J[i, 2, 1], J[i, 2, 2], J[i, 2, 3]
    kind = joint_type[i]
    if kind != 0:
        value = multiplier[i] * q[q_index[i]] + offset[i]
        x, y, z = axis[i, 0], axis[i, 1], axis[i, 2]
        if kind == 1:
            # Rodrigues: R = c I + s [a]x + (1 - c) a a^T; then M.R <- J.R @ R.
            c = np.cos(value)
            s = np.sin(value)
            v = 1.0 - c
            r00, r01, r02 = c + v * x * x, v * x * y - s * z, v * x * z + s * y
            r10, r11, r12 = v * x * y + s * z, c + v * y * y, v * y * z - s * x
            r20, r21, r22 = v * x * z - s * y, v * y * z + s * x, c + v * z * z
            a00 = m00 * r00 + m01 * r10 + m02 * r20
            a01 = m00 * r01 + m01 * r11 + m02 * r21
            a02 = m00 * r02 + m01 * r12 + m02 * r22
            a10 = m10 * r00 + m11 * r10 + m12 * r20
            a11 = m10 * r01 + m11 * r11 + m12 * r21
            a12 = m10 * r02 + m11 * r12 + m12 * r22
            a20 = m20 * r00 + m21 * r10 + m22 * r20
            a21 = m20 * r01 + m21 * r11 + m22 * r21
            a22 = m20 * r02 + m21 * r12 + m22 * r22
            m00, m01, m02 = a00, a01, a02
            m10, m11, m12 = a10, a11, a12
            m20, m21, m22 = a20, a21, a22
        else:
            # Prismatic: the child frame slides by value * axis, in the joint frame.
            t0 += value * (m00 * x + m01 * y + m02 * z)
            t1 += value * (m10 * x + m11 * y + m12 * z)
            t2 += value * (m20 * x + m21 * y + m22 * z)
    T = T_world_link
    p = parent[i]
    if p < 0:
        T[i, 0, 0], T[i, 0, 1], T[i, 0, 2], T[i, 0, 3] = m00, m01, m02, t0
        T[i, 1, 0], T[i, 1, 1], T[i, 1, 2], T[i, 1, 3] = m10, m11, m12, t1
        T[i, 2, 0], T[i, 2, 1], T[i, 2, 2], T[i, 2, 3] = m20, m21, m22, t2
    else:
        for r in range(3):
            p0, p1, p2 = T[p, r, 0], T[p, r, 1], T[p, r, 2]
            T[i, r, 0] = p0 * m00 + p1 * m10 + p2 * m20
            T[i, r, 1] = p0 * m01 + p1 * m11 + p2 * m21
            T[i, r, 2] = p0 * m02 + p1 * m12 + p2 * m22
            T[i, r, 3] = p0 * t0 + p1 * t1 + p2 * t2 + T[p, r, 3]
    T[i, 3, 0] = 0.0
    T[i, 3, 1] = 0.0
    T[i, 3, 2] = 0.0
    T[i, 3, 3] = 1.0


@njit(cache=True, nogil=True, fastmath=False, _nrt=False)
def forward_kinematics_kernel(q, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                              offset, T_world_link):
    """Fill ``T_world_link`` with the pose of every link for configuration ``q``.

    :param q: ``(J,) float64`` joint values.
    :param parent: ``(L,) int64`` parent link index, -1 for the root (index 0).
    :param joint_type: ``(L,) int64`` JOINT_FIXED / JOINT_REVOLUTE / JOINT_PRISMATIC.
    :param T_parent_joint: ``(L, 4, 4) float64`` joint origins.
    :param axis: ``(L, 3) float64`` unit joint axes, in the joint frame.
    :param q_index: ``(L,) int64`` index into ``q`` of the driving value, -1 if fixed.
    :param multiplier: ``(L,) float64`` joint value = multiplier * q[q_index] + offset.
    :param offset: ``(L,) float64``.
    :param T_world_link: ``(L, 4, 4) float64`` output, written in place (rows 3 included).
    """
    for i in range(parent.shape[0]):
        set_link_pose(i, q, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                      offset, T_world_link)


@njit(cache=True, nogil=True, _nrt=False)
def forward_kinematics_batch_kernel(Q, parent, joint_type, T_parent_joint, axis, q_index,
                                    multiplier, offset, T_out):
    """Fill ``T_out[k]`` with :func:`forward_kinematics_kernel` of ``Q[k]`` for every k.

    :param Q: ``(n, J) float64`` configurations.
    :param T_out: ``(n, L, 4, 4) float64`` output, written in place.

    The other parameters are as for :func:`forward_kinematics_kernel`.
    """
    for k in range(Q.shape[0]):
        forward_kinematics_kernel(Q[k], parent, joint_type, T_parent_joint, axis, q_index,
                                  multiplier, offset, T_out[k])


@dataclass(frozen=True, eq=False)
class KinematicTree:
    """The kinematic tree of a :class:`RobotModel` as flat arrays (see the module docstring).

    Per link (``L``): ``parent``, ``joint_type``, ``q_index`` ``(L,) int64``;
    ``T_parent_joint (L, 4, 4)``, ``axis (L, 3)``, ``multiplier``, ``offset (L,) float64``;
    ``link_joint`` the joint above each link (None for the root). Per variable (``J``):
    ``joint_names``, ``lower``, ``upper (J,) float64``.
    """

    link_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    parent: np.ndarray
    joint_type: np.ndarray
    T_parent_joint: np.ndarray
    axis: np.ndarray
    q_index: np.ndarray
    multiplier: np.ndarray
    offset: np.ndarray
    link_joint: tuple[str | None, ...]
    lower: np.ndarray
    upper: np.ndarray

    def forward_kinematics(self, q) -> np.ndarray:
        """Return the pose of every link for one configuration.

        :param q: ``(J,)`` joint values in the order of ``joint_names``.
        :return: ``T_world_link : (L, 4, 4) float64``, world being the root link frame.
        :raises JointStateError: ``q`` has the wrong length.
        """
        # Kept thin on purpose: this wrapper is timed against pinocchio (bench/fk.py).
        q = np.asarray(q, dtype=np.float64)
        if q.shape != self.lower.shape:
            raise JointStateError(self._shape_message(q.shape, '(J,)'))
        T_world_link = np.empty(self.T_parent_joint.shape)
        forward_kinematics_kernel(q, self.parent, self.joint_type, self.T_parent_joint,
                                  self.axis, self.q_index, self.multiplier, self.offset,
                                  T_world_link)
        return T_world_link

    def forward_kinematics_batch(self, Q) -> np.ndarray:
        """Return the pose of every link for many configurations.

        :param Q: ``(n, J)`` joint values, one configuration per row.
        :return: ``(n, L, 4, 4) float64``.
        :raises JointStateError: ``Q`` has the wrong shape.
        """
        Q = np.ascontiguousarray(Q, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != self.lower.shape[0]:
            raise JointStateError(self._shape_message(Q.shape, '(n, J)'))
        T_out = np.empty((Q.shape[0],) + self.T_parent_joint.shape)
        forward_kinematics_batch_kernel(Q, self.parent, self.joint_type, self.T_parent_joint,
                                        self.axis, self.q_index, self.multiplier, self.offset,
                                        T_out)
        return T_out

    def _shape_message(self, shape, expected):
        return (f'joint values of shape {shape}, expected {expected} with J = '
                f'{len(self.joint_names)} values in the order {", ".join(self.joint_names)}')


def build_kinematic_tree(model: RobotModel) -> KinematicTree:
    """Flatten a robot model's tree into the arrays the kernels read.

    :param model: a model from :func:`collision_sensor.robot_model.load_urdf` (links in
        topological order, root first).
    :return: the tree; its ``q`` order is the URDF document order of the movable, non-mimic
        joints.
    :raises RobotDescriptionError: a mimic of an unknown or fixed joint, a mimic cycle, links
        not in topological order, or a planar or floating joint other than a held floating
        base (``model.held_joints``, built as fixed at identity).
    """
    held = set(model.held_joints)
    for joint in model.joints:
        if joint.type in ('planar', 'floating') and joint.name not in held:
            raise RobotDescriptionError(
                f'URDF "{model.source}": joint "{joint.name}" is {joint.type} (variables '
                f'{", ".join(joint.variables)}) between links "{joint.parent}" and '
                f'"{joint.child}"; the kinematics cannot drive planar or floating joints yet '
                '(only a floating base out of a root link without geometry is held at '
                'identity); make the joint fixed, or split the robot at it')
    model_joints = [dataclasses.replace(joint, type='fixed') if joint.name in held else joint
                    for joint in model.joints]
    model = dataclasses.replace(model, joints=tuple(model_joints))
    mimics = resolve_mimics(model.joints, model.source)
    link_index = {name: i for i, name in enumerate(model.links)}
    # model.joints follow their child link; the q vector follows the URDF document instead, which
    # is the order load_urdf read them in and which other tools (yourdfpy) use too.
    joint_names = tuple(joint.name for joint in _document_order(model)
                        if joint.type != 'fixed' and joint.name not in mimics)
    variable = {name: j for j, name in enumerate(joint_names)}
    joints_by_name = {joint.name: joint for joint in model.joints}
    L = len(model.links)
    parent = np.full(L, -1, dtype=np.int64)
    joint_type = np.zeros(L, dtype=np.int64)
    T_parent_joint = np.tile(np.eye(4), (L, 1, 1))
    axis = np.zeros((L, 3))
    axis[:, 0] = 1.0
    q_index = np.full(L, -1, dtype=np.int64)
    multiplier = np.ones(L)
    offset = np.zeros(L)
    link_joint = [None] * L
    for joint in model.joints:
        i = link_index[joint.child]
        parent[i] = link_index[joint.parent]
        if parent[i] >= i:
            raise RobotDescriptionError(
                f'URDF "{model.source}": link "{joint.child}" comes before its parent '
                f'"{joint.parent}" in model.links; build the model with load_urdf')
        joint_type[i] = _JOINT_CODES[joint.type]
        T_parent_joint[i] = joint.T_parent_joint
        axis[i] = joint.axis
        link_joint[i] = joint.name
        if joint.type == 'fixed':
            continue
        source, multiplier[i], offset[i] = mimics.get(joint.name, (joint.name, 1.0, 0.0))
        q_index[i] = variable[source]
    lower = np.array([joints_by_name[name].lower for name in joint_names], dtype=np.float64)
    upper = np.array([joints_by_name[name].upper for name in joint_names], dtype=np.float64)
    return KinematicTree(
        link_names=tuple(model.links), joint_names=joint_names, parent=parent,
        joint_type=joint_type, T_parent_joint=np.ascontiguousarray(T_parent_joint),
        axis=np.ascontiguousarray(axis), q_index=q_index, multiplier=multiplier, offset=offset,
        link_joint=tuple(link_joint), lower=lower, upper=upper)


def _document_order(model):
    order = model.joint_document_order
    if not order:
        return model.joints
    by_name = {joint.name: joint for joint in model.joints}
    return [by_name[name] for name in order]


bind_to_kernel_sources(globals())
