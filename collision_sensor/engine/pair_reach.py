"""How far each joint variable can move a pair's two bodies relative to each other: the bounds
the incremental rule sums (paper sec. 4.2, taken further by the clearance; ``cpp/planning.hpp``).

A pair last found apart with a clearance ``c`` (a lower bound of its bodies' distance) is still
apart while ``sum_j |q_j - q_eval_j| (reach[p, j] + reach_ext[p, j] E) < c``, E the sum of the
prismatic joints' |value|: the engine keeps that sum running and re-checks the pair only when
it reaches the clearance. :func:`pair_rows` computes the bounds, once per pair while its bodies
keep their place (:mod:`collision_sensor.engine.scene_layout` keeps them across scene changes;
an attached object moving in its link changes its pairs' lever arms).
"""
from typing import NamedTuple, Tuple

import numpy as np

from collision_sensor.engine.kinematics import (JOINT_FLOATING, JOINT_PLANAR, JOINT_PRISMATIC,
                                                VARIABLE_COUNT, variables)

#: How far a point can move per unit of a floating joint's quaternion component, for the
#: incremental bounds (:func:`pair_rows`): huge, so that any move beyond motion_tolerance forces
#: a re-check (the true bound grows as 1 / |quaternion|; the engine refuses quaternions with a
#: norm below QUATERNION_NORM_MIN, which keeps it below this: see cpp/tolerances.hpp).
#: Finite on purpose: inf * 0 would be NaN.
QUATERNION_REACH = 1e300


class EngineTree(NamedTuple):
    """The engine's kinematic arrays: the robot's links, then each attached object as a link
    on a fixed joint below its own (``T_parent_joint`` its pose in that link's frame)."""

    parent: np.ndarray
    joint_type: np.ndarray
    q_index: np.ndarray
    multiplier: np.ndarray
    T_parent_joint: np.ndarray


def pair_rows(tree: EngineTree, vertex_radius: np.ndarray, pair_a: np.ndarray,
              pair_b: np.ndarray, n_joints: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``path, reach, reach_ext``, each (n, J), for the pairs of bodies
    ``(pair_a[i], pair_b[i])`` (engine body indices; a world object second).

    ``path[i, j]`` is 1 iff variable j drives a joint on the tree path between the two
    bodies (int64). ``reach, reach_ext`` (float64): how far a point of either body can
    move, relative to the other, per unit of variable j: ``reach + reach_ext * E``, where
    E is the sum of |value| of every prismatic joint at the current state (0 off the path).

    A joint k on the path moves the body on its side (relative to the pair's common
    ancestor). Revolute: every point of body x below k stays within the distance from
    k's origin (on its axis) to x's origin, at most the sum of the joint offsets
    ``|t_parent_joint|`` from k down to x plus the extensions of the prismatic joints
    between them (at most E), plus x's vertex radius around its origin. Prismatic: 1.
    Both times |multiplier|, summed over the joints variable j drives. E is taken at the
    new state: moving the prismatic variables first, then the others, is a path from the
    old state along which every bound holds. An attached object is a link on a fixed
    joint whose offset is its pose in its link's frame: it enters the lever arms so.

    Planar and floating joints translate, then rotate about the translated origin (their
    child frame's). Translation variables: 1, as a prismatic joint. Planar theta: as a
    revolute joint about the child frame's origin, so the joint's own translation is not
    in its lever arm, and translation variables do not count in E. Quaternion components:
    QUATERNION_REACH (any move re-checks). A rotating joint k with a planar or floating
    joint between it and x would have that joint's translation in its lever arm; such a
    k gets QUATERNION_REACH too (rare: multi-DOF joints are mostly the root's), so E stays
    the prismatic joints' sum. Below both bodies' common ancestor (a floating base under
    self-collision pairs) a joint moves nothing relative, and is skipped.

    Padding does not enter: a padded pair's clearance is a bound of its surfaces' distance
    minus a constant (the paddings), which moves exactly as much as that distance does.
    """
    n_links = len(tree.parent)
    offset_norm = np.linalg.norm(tree.T_parent_joint[:, :3, 3], axis=1)
    path = np.zeros((len(pair_a), n_joints), dtype=np.int64)
    reach = np.zeros((len(pair_a), n_joints))
    reach_ext = np.zeros((len(pair_a), n_joints))
    for p, (a, b) in enumerate(zip(pair_a, pair_b)):
        chains = {}
        for x in (a, b) if b < n_links else (a,):
            chain, k = [], int(x)
            while k > 0:
                chain.append(k)  # x and its ancestors, up to (excluding) the root
                k = int(tree.parent[k])
            chains[int(x)] = chain
        for x, chain in chains.items():
            other = chains.get(int(b) if x == a else int(a), [])
            for depth, k in enumerate(chain):
                if k in other or tree.q_index[k] < 0:
                    continue  # above the common ancestor, or not driven
                path[p, variables(tree, k)] = 1
                below = chain[:depth]  # from x up to, excluding, k
                m = abs(tree.multiplier[k]) * (1.0 + 1e-9)
                j = tree.q_index[k]
                kind = tree.joint_type[k]
                if kind == JOINT_PRISMATIC:
                    reach[p, j] += m
                    continue
                lever = float(offset_norm[below].sum()) + vertex_radius[x]
                if any(VARIABLE_COUNT[tree.joint_type[c]] > 1 for c in below):
                    lever = QUATERNION_REACH   # a multi-DOF translation in the lever arm
                if kind == JOINT_PLANAR:
                    reach[p, j:j + 2] += m   # x, y
                    j += 2                   # theta: below, as a revolute joint
                elif kind == JOINT_FLOATING:
                    reach[p, j:j + 3] += m   # trans_x, trans_y, trans_z
                    reach[p, j + 3:j + 7] = QUATERNION_REACH
                    continue
                reach[p, j] = min(reach[p, j] + m * lever, QUATERNION_REACH)
                if any(tree.joint_type[c] == JOINT_PRISMATIC for c in below):
                    reach_ext[p, j] += m
    return path, reach, reach_ext
