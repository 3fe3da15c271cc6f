"""Forward kinematics of a robot model over flat arrays (computed in C++).

A :class:`KinematicTree` holds the tree as structure-of-arrays indexed by link (``L`` links,
root first, every parent before its children), and the configuration ``q`` holds the variables
of the movable, non-mimic joints (``J`` values, URDF document order): one per revolute,
continuous or prismatic joint, MoveIt's three ``<joint>/x``, ``/y``, ``/theta`` per planar joint
and seven ``<joint>/trans_x``, ``/trans_y``, ``/trans_z``, ``/rot_x``, ``/rot_y``, ``/rot_z``,
``/rot_w`` per floating joint, consecutive. Each link ``i`` except the root is reached through
the joint above it::

    value = multiplier[i] * q[q_index[i]] + offset[i]     # mimic chains already composed
    v = q[q_index[i]:q_index[i] + 3 or 7]                 # a multi-DOF joint's variables
    T_world_link[i] = T_world_link[parent[i]] @ T_parent_joint[i] @ M(joint_type[i], ...)

    M(FIXED)     = I
    M(REVOLUTE)  = [Rodrigues(axis[i], value), 0; 0, 1]   # continuous joints too
    M(PRISMATIC) = [I, value * axis[i]; 0, 1]
    M(PLANAR)    = [Rz(v[2]), (v[0], v[1], 0); 0, 1]      # the joint frame's x-y plane
    M(FLOATING)  = [R(v[3:7] / |v[3:7]|), v[0:3]; 0, 1]   # quaternion x, y, z, w

A planar joint moves in its joint frame's x-y plane whatever its URDF ``<axis>`` (MoveIt's
PlanarJointModel does the same; :func:`collision_sensor.model.robot_model.load_urdf` warns about an
axis other than z). A multi-DOF joint is never a mimic (the loader makes such a mimic
independent), so its multiplier and offset are 1 and 0. :meth:`KinematicTree.neutral` is the
zero configuration with every quaternion the identity (rot_w = 1).

"world" is the root link's frame: ``T_world_link[0]`` is the identity.

:meth:`KinematicTree.forward_kinematics` runs ``cpp/kinematics.hpp``, the code the query
engine itself runs for each link it needs (lazily, inside a query).
"""
from dataclasses import dataclass

import numpy as np
from collision_sensor.engine.compiled import engine
from collision_sensor.errors import JointStateError, RobotDescriptionError
from collision_sensor.model.robot_model import RobotModel, resolve_mimics

JOINT_FIXED, JOINT_REVOLUTE, JOINT_PRISMATIC, JOINT_PLANAR, JOINT_FLOATING = (
    engine.JOINT_FIXED, engine.JOINT_REVOLUTE, engine.JOINT_PRISMATIC, engine.JOINT_PLANAR,
    engine.JOINT_FLOATING)
#: How many consecutive variables of q a joint of each type reads (the engine's).
VARIABLE_COUNT = dict(enumerate(engine.JOINT_VARIABLES))
_JOINT_CODES = {'fixed': JOINT_FIXED, 'revolute': JOINT_REVOLUTE,
                'continuous': JOINT_REVOLUTE, 'prismatic': JOINT_PRISMATIC,
                'planar': JOINT_PLANAR, 'floating': JOINT_FLOATING}
#: Each multi-DOF variable suffix: (lower, upper) bounds, as MoveIt gives them.
_VARIABLE_BOUNDS = {'x': (-np.inf, np.inf), 'y': (-np.inf, np.inf), 'theta': (-np.inf, np.inf),
                    'trans_x': (-np.inf, np.inf), 'trans_y': (-np.inf, np.inf),
                    'trans_z': (-np.inf, np.inf), 'rot_x': (-1.0, 1.0), 'rot_y': (-1.0, 1.0),
                    'rot_z': (-1.0, 1.0), 'rot_w': (-1.0, 1.0)}


@dataclass(frozen=True, eq=False)
class KinematicTree:
    """The kinematic tree of a :class:`RobotModel` as flat arrays (see the module docstring).

    Per link (``L``): ``parent``, ``joint_type``, ``q_index`` ``(L,) int64``;
    ``T_parent_joint (L, 4, 4)``, ``axis (L, 3)``, ``multiplier``, ``offset (L,) float64``;
    ``link_joint`` the joint above each link (None for the root). Per variable (``J``):
    ``joint_names`` (MoveIt's variable names for multi-DOF joints), ``lower``, ``upper (J,)
    float64``.
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

    def neutral(self) -> np.ndarray:
        """Return the zero configuration with every floating joint's quaternion the identity.

        :return: ``(J,) float64``.
        """
        q = np.zeros(len(self.joint_names))
        q[[j for j, name in enumerate(self.joint_names)
           if name.endswith('/rot_w') and self._is_floating_variable(j)]] = 1.0
        return q

    def _is_floating_variable(self, j) -> bool:
        first = j - 6   # rot_w is a floating joint's seventh variable
        return bool(np.any((self.joint_type == JOINT_FLOATING) & (self.q_index == first)))

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
        return self._forward(q)

    def forward_kinematics_batch(self, Q) -> np.ndarray:
        """Return the pose of every link for many configurations.

        :param Q: ``(n, J)`` joint values, one configuration per row.
        :return: ``(n, L, 4, 4) float64``.
        :raises JointStateError: ``Q`` has the wrong shape.
        """
        Q = np.ascontiguousarray(Q, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != self.lower.shape[0]:
            raise JointStateError(self._shape_message(Q.shape, '(n, J)'))
        if len(Q) == 0:
            return np.empty((0,) + self.T_parent_joint.shape)
        return self._forward(Q)

    def _forward(self, q: np.ndarray) -> np.ndarray:
        compiled = self.__dict__.get('_compiled')
        if compiled is None:  # the arrays checked and held by the engine, once
            compiled = engine.Kinematics(self.parent, self.joint_type, self.T_parent_joint,
                                         self.axis, self.q_index, self.multiplier, self.offset,
                                         len(self.joint_names))
            object.__setattr__(self, '_compiled', compiled)
        try:
            return compiled.forward(np.ascontiguousarray(q))
        except JointStateError as error:  # the engine's, naming the row and the variable
            raise JointStateError(
                f'joint variable "{self.joint_names[error.variable]}": a value the kinematics '
                f'cannot honour ({error}: not finite, a translation beyond '
                f'{engine.PRISMATIC_VALUE_MAX:g} m or a zero quaternion); send a usable '
                'value') from None

    def _shape_message(self, shape, expected):
        return (f'joint values of shape {shape}, expected {expected} with J = '
                f'{len(self.joint_names)} values in the order {", ".join(self.joint_names)}')


def variables(tree, k: int) -> slice:
    """Return the variables of q that the joint above link k reads (consecutive).

    :param tree: a :class:`KinematicTree`, or any tree with its ``q_index`` and
        ``joint_type`` arrays; link k's joint must be movable.
    """
    j = int(tree.q_index[k])
    return slice(j, j + VARIABLE_COUNT[int(tree.joint_type[k])])


def build_kinematic_tree(model: RobotModel) -> KinematicTree:
    """Flatten a robot model's tree into the arrays the kernels read.

    :param model: a model from :func:`collision_sensor.model.robot_model.load_urdf` (links in
        topological order, root first).
    :return: the tree; its ``q`` order is the URDF document order of the movable, non-mimic
        joints, a multi-DOF joint giving its MoveIt variables in MoveIt's order.
    :raises RobotDescriptionError: a mimic of an unknown or fixed joint, a mimic cycle, a
        multi-DOF joint in a mimic relation, or links not in topological order.
    """
    mimics = resolve_mimics(model.joints, model.source)
    by_name = {joint.name: joint for joint in model.joints}
    for name, (source, _, _) in mimics.items():
        if len(by_name[name].variables) != 1 or len(by_name[source].variables) != 1:
            raise RobotDescriptionError(
                f'URDF "{model.source}": joint "{name}" ({by_name[name].type}) mimics joint '
                f'"{source}" ({by_name[source].type}); a planar or floating joint can neither '
                'mimic nor be mimicked; remove the <mimic>')
    link_index = {name: i for i, name in enumerate(model.links)}
    # model.joints follow their child link; the q vector follows the URDF document instead, which
    # is the order load_urdf read them in and which other tools (yourdfpy) use too.
    joint_names = tuple(variable for joint in _document_order(model) if joint.name not in mimics
                        for variable in joint.variables)
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
        q_index[i] = variable[joints_by_name[source].variables[0]]
    bounds = []
    for joint in _document_order(model):
        if joint.name in mimics:
            continue
        if len(joint.variables) == 1:
            bounds.append((joint.lower, joint.upper))
        else:
            bounds.extend(_VARIABLE_BOUNDS[v.rsplit('/', 1)[1]] for v in joint.variables)
    lower = np.array([b[0] for b in bounds], dtype=np.float64).reshape(-1)
    upper = np.array([b[1] for b in bounds], dtype=np.float64).reshape(-1)
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

