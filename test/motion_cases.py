"""The motion case the sensor's, the node's and the trajectories' tests share: a Panda elbow
move (joint 4 from -2.6 to -0.8 rad) across a 2 mm plate, sampled sparsely (at 0.3, 0.5 and 0.8
of the way) so that every state is clear while the arm crosses the plate between the last two."""
import math
import types

import numpy as np
import pytest

from collision_sensor import CollisionChecker
from collision_sensor.engine.motion import interpolate

PLATE = (0.04, 0.04, 0.002)     # m, edge lengths: a 2 mm plate


def elbow_crossing(panda_urdf, panda_srdf, erd_package_paths):
    """Return ``(q0, q1, T_world_plate)``: the elbow move and the pose of a plate across the
    hand's path two thirds of the way (its normal along the fingertips' motion there)."""
    probe = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                       package_paths=erd_package_paths)
    names = probe.joint_names
    q0 = np.zeros(len(names))
    q0[names.index('panda_joint2')] = 0.3
    q0[names.index('panda_joint4')] = -2.6
    q1 = q0.copy()
    q1[names.index('panda_joint4')] = -0.8
    q_mid, q_next = interpolate(probe.motion_kinds, q0, q1, [2 / 3, 2 / 3 + 1e-3])

    def fingertips(q):
        probe.check(q)
        T = probe.link_poses()['panda_hand']
        return T[:3, 3] + T[:3, :3] @ np.array([0.0, 0.0, 0.1])

    p = fingertips(q_mid)
    z = fingertips(q_next) - p
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = p
    return q0, q1, T


def scene_of(T_world_plate) -> dict:
    """The plate as a scene mapping (``CollisionChecker.from_urdf(scene=...)``)."""
    R = T_world_plate[:3, :3]
    rpy = [math.atan2(R[2, 1], R[2, 2]), -math.asin(R[2, 0]), math.atan2(R[1, 0], R[0, 0])]
    return {'objects': [{'name': 'plate', 'box': {'size': list(PLATE)},
                         'pose': {'xyz': T_world_plate[:3, 3].tolist(), 'rpy': rpy}}]}


@pytest.fixture(scope='module')
def crossing(panda_urdf, panda_srdf, erd_package_paths):
    q0, q1, T = elbow_crossing(panda_urdf, panda_srdf, erd_package_paths)

    def make(**config):
        return CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                          package_paths=erd_package_paths, scene=scene_of(T),
                                          config=config)
    a, b, c = (q0 + t * (q1 - q0) for t in (0.3, 0.5, 0.8))
    oracle = make()
    for q in (a, b, c):
        assert not oracle.check(q).in_collision     # every instant clear
    assert not oracle.check_motion(a, b).in_collision
    assert oracle.check_motion(b, c).in_collision
    return types.SimpleNamespace(q0=a, q_half=b, q1=c, make=make, oracle=oracle)
