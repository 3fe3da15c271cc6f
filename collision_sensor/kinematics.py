"""Forward kinematics of a robot model over flat arrays (computed in C++).

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

:func:`forward_kinematics_kernel` runs ``cpp/kinematics.hpp``, the code the query engine
itself runs for each link it needs (lazily, inside a query).
"""
import dataclasses
from dataclasses import dataclass

import numpy as np
from collision_sensor.compiled import engine
from collision_sensor.errors import JointStateError, RobotDescriptionError
from collision_sensor.robot_model import RobotModel, resolve_mimics

JOINT_FIXED, JOINT_REVOLUTE, JOINT_PRISMATIC = 0, 1, 2
_JOINT_CODES = {'fixed': JOINT_FIXED, 'revolute': JOINT_REVOLUTE,
                'continuous': JOINT_REVOLUTE, 'prismatic': JOINT_PRISMATIC}


def forward_kinematics_kernel(q, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                              offset, T_world_link):
    """Fill ``T_world_link`` with the pose of every link for configuration ``q`` (C++:
    ``cpp/kinematics.hpp``, the same code the query engine runs).

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
    engine.forward_kinematics(q, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                              offset, T_world_link)


def forward_kinematics_batch_kernel(Q, parent, joint_type, T_parent_joint, axis, q_index,
                                    multiplier, offset, T_out):
    """Fill ``T_out[k]`` with :func:`forward_kinematics_kernel` of ``Q[k]`` for every k.

    :param Q: ``(n, J) float64`` configurations.
    :param T_out: ``(n, L, 4, 4) float64`` output, written in place.
    """
    engine.forward_kinematics(Q, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                              offset, T_out)


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

