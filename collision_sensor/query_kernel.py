"""One collision query over the whole robot and scene, compiled (paper sec. 2, 4.1, 4.2).

A query takes joint positions and, without returning to the interpreter:

1. decides which joint variables moved (by more than the motion tolerance) since the state
   that the carried statuses describe, and takes their new values into that state;
2. recomputes the world pose of the links below a moved joint (forward kinematics, only where
   needed) and the robot's root volume (a world box around all link boxes, rebuilt from the
   link boxes, never from geometry: paper sec. 2.2);
3. re-checks only the pairs whose relative pose can have changed: those with a moved joint on
   the tree path between their two bodies (sec. 4.2); every other pair keeps its status;
4. checks a pair by culling with the robot root volume (scene pairs), then the two bodies'
   boxes, then each sub-group tree against each (sec. 4.1, :func:`trees_collide`).

Bodies are the robot's links (FK order, world == root link frame) followed by the scene
objects, whose poses never change.
"""
import numba
import numpy as np

from collision_sensor.array_pack import view1, view2, view3
from collision_sensor.box_test import boxes_disjoint
from collision_sensor.kinematics import set_link_pose
from collision_sensor.traversal import COUNT_BOX_TESTS, relative_box, spheres_apart, trees_collide

WORK_SIZE = 256


@numba.njit(cache=True, inline='always')
def _pair_pose(T_world_body, a, b, R_ab, t_ab):
    """Body b's pose in body a's frame: [R_ab, t_ab] = T_world_a^-1 T_world_b."""
    for i in range(3):
        for j in range(3):
            R_ab[i, j] = (T_world_body[a, 0, i] * T_world_body[b, 0, j]
                          + T_world_body[a, 1, i] * T_world_body[b, 1, j]
                          + T_world_body[a, 2, i] * T_world_body[b, 2, j])
        t_ab[i] = (T_world_body[a, 0, i] * (T_world_body[b, 0, 3] - T_world_body[a, 0, 3])
                   + T_world_body[a, 1, i] * (T_world_body[b, 1, 3] - T_world_body[a, 1, 3])
                   + T_world_body[a, 2, i] * (T_world_body[b, 2, 3] - T_world_body[a, 2, 3]))


@numba.njit(cache=True)
def _robot_root_box(T_world_body, n_links, body_elem_start, body_elem_end, body_center,
                    body_axes, body_half, root_center, root_half):
    """World axis-aligned box around every link box (the robot's root volume, sec. 2.2)."""
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    for b in range(n_links):
        if body_elem_end[b] == body_elem_start[b]:
            continue
        for i in range(3):
            c = T_world_body[b, i, 3]
            e = 0.0
            for k in range(3):
                c += T_world_body[b, i, k] * body_center[b, k]
                # |row i of R_world_box| . half: the box's half width along world axis i.
                ax = (T_world_body[b, i, 0] * body_axes[b, 0, k]
                      + T_world_body[b, i, 1] * body_axes[b, 1, k]
                      + T_world_body[b, i, 2] * body_axes[b, 2, k])
                e += abs(ax) * body_half[b, k]
            if i == 0:
                lo0, hi0 = min(lo0, c - e), max(hi0, c + e)
            elif i == 1:
                lo1, hi1 = min(lo1, c - e), max(hi1, c + e)
            else:
                lo2, hi2 = min(lo2, c - e), max(hi2, c + e)
    root_center[0], root_half[0] = 0.5 * (lo0 + hi0), 0.5 * (hi0 - lo0)
    root_center[1], root_half[1] = 0.5 * (lo1 + hi1), 0.5 * (hi1 - lo1)
    root_center[2], root_half[2] = 0.5 * (lo2 + hi2), 0.5 * (hi2 - lo2)


@numba.njit(cache=True)
def _scene_body_outside_root(T_world_body, s, body_center, body_axes, body_half, root_center,
                             root_half, box_method, work):
    """True iff scene body ``s``'s box is disjoint from the robot's root volume."""
    R = work[0:9].reshape(3, 3)
    t = work[9:12]
    scratch = work[16:80]
    for i in range(3):
        for j in range(3):
            R[i, j] = (T_world_body[s, i, 0] * body_axes[s, 0, j]
                       + T_world_body[s, i, 1] * body_axes[s, 1, j]
                       + T_world_body[s, i, 2] * body_axes[s, 2, j])
        t[i] = (T_world_body[s, i, 0] * body_center[s, 0] + T_world_body[s, i, 1] * body_center[s, 1]
                + T_world_body[s, i, 2] * body_center[s, 2] + T_world_body[s, i, 3]
                - root_center[i])
    return boxes_disjoint(box_method, root_half, body_half[s], R, t, scratch)


@numba.njit(cache=True)
def query_kernel(q, q_ref, tolerance, full,
                 parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset,
                 T_world_body, n_links, is_scene, body_elem_start, body_elem_end,
                 body_center, body_axes, body_half, body_radius,
                 roots, center, axes, half, radius, volume, gain, left, right, first, count, tris,
                 pair_a, pair_b, pair_path, status,
                 box_method, expansion, moved, body_dirty, scene_culled, stack, work, counters):
    """Bring ``status`` up to date with ``q``; return (pairs re-checked, any status changed).

    Contract in plain Python (``full`` or tolerance 0 makes it exact for the given ``q``)::

        moved = full | (abs(q - q_ref) > tolerance);  q_ref[moved] = q[moved]
        T_world_body[links] = forward_kinematics(q_ref)        # only links below a moved joint
        for p in pairs:
            if full or moved[pair_path[p]].any():
                status[p] = bodies_collide(pair_a[p], pair_b[p])

    :param q, q_ref: (J,) float64 requested positions, and the state the statuses describe
        (updated in place).
    :param parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset: the
        :class:`~collision_sensor.kinematics.KinematicTree` arrays of the ``n_links`` links.
    :param T_world_body: (B, 4, 4) body poses, links first, then scene objects (fixed).
    :param is_scene: (B,) int64, 1 for scene objects.
    :param body_elem_start, body_elem_end: (B,) int64, each body's trees are
        ``roots[start:end]``.
    :param body_center, body_axes, body_half, body_radius: each body's box over all its trees
        (body frame), and the radius of the sphere around it.
    :param pair_a, pair_b: (P,) int64 bodies of each checked pair; a scene body is always b.
    :param pair_path: (P, J) int64, 1 where variable j drives a joint on the pair's tree path.
    :param status: (P,) int64, 1 if the pair collides (updated in place).
    :param moved, body_dirty: (J,), (B,) int64 work arrays.
    :param scene_culled: (S,) int64, 1 where a scene object is outside the robot's root volume.
    :param stack, counters: see :func:`trees_collide`.
    :param work: (WORK_SIZE,) float64, kept between calls (it holds the root volume).
    """
    n_joints = q.shape[0]
    any_moved = False
    for j in range(n_joints):
        if full or abs(q[j] - q_ref[j]) > tolerance:
            moved[j] = 1
            q_ref[j] = q[j]
            any_moved = True
        else:
            moved[j] = 0
    if not any_moved and not full:
        return 0, False
    # work layout: [0, 100) trees_collide, [112, 118) robot root box, [120, 132) pair pose,
    # [136, 236) body-level box tests.
    any_link_moved = False
    for i in range(n_links):
        dirty = full
        k = q_index[i]
        if k >= 0 and moved[k]:
            dirty = True
        elif parent[i] >= 0 and body_dirty[parent[i]]:
            dirty = True
        body_dirty[i] = dirty
        if dirty:
            set_link_pose(i, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                          multiplier, offset, T_world_body)
            any_link_moved = True
    root_center = work[112:115]
    root_half = work[115:118]
    R_ab = work[120:129].reshape(3, 3)
    t_ab = work[129:132]
    box_work = work[136:236]
    if any_link_moved or full:
        _robot_root_box(T_world_body, n_links, body_elem_start, body_elem_end, body_center,
                        body_axes, body_half, root_center, root_half)
        for s in range(scene_culled.shape[0]):
            scene_culled[s] = _scene_body_outside_root(
                T_world_body, n_links + s, body_center, body_axes, body_half, root_center,
                root_half, box_method, box_work)
    rechecked = 0
    changed = False
    for p in range(pair_a.shape[0]):
        if not full:
            affected = False
            for j in range(n_joints):
                if moved[j] and pair_path[p, j]:
                    affected = True
                    break
            if not affected:
                continue
        rechecked += 1
        a = pair_a[p]
        b = pair_b[p]
        hit = False
        if is_scene[b] and scene_culled[b - n_links]:
            changed |= status[p] != 0
            status[p] = 0
            continue
        _pair_pose(T_world_body, a, b, R_ab, t_ab)
        if spheres_apart(body_center, body_radius, a, b, R_ab, t_ab):
            changed |= status[p] != 0
            status[p] = 0
            continue
        single = (body_elem_end[a] - body_elem_start[a] == 1
                  and body_elem_end[b] - body_elem_start[b] == 1)
        if not single:
            # A body of one sub-group has its tree's root box as body box: tested below.
            R = box_work[0:9].reshape(3, 3)
            t = box_work[9:12]
            relative_box(body_center, body_axes, a, b, R_ab, t_ab, R, t)
            counters[COUNT_BOX_TESTS] += 1
            if boxes_disjoint(box_method, body_half[a], body_half[b], R, t, box_work[16:80]):
                changed |= status[p] != 0
                status[p] = 0
                continue
        for ea in range(body_elem_start[a], body_elem_end[a]):
            for eb in range(body_elem_start[b], body_elem_end[b]):
                if trees_collide(roots[ea], roots[eb], R_ab, t_ab, center, axes, half, radius,
                                 volume, gain, left, right, first, count, tris, box_method,
                                 expansion, stack, work[0:100], counters):
                    hit = True
                    break
            if hit:
                break
        changed |= status[p] != hit
        status[p] = 1 if hit else 0
    return rechecked, changed


# Slots of the packed buffers (see collision_sensor.array_pack); CollisionChecker adds the
# arrays in exactly this order.
FLOAT_SLOTS = ('q_ref', 'T_parent_joint', 'axis', 'multiplier', 'offset', 'T_world_body',
               'body_center', 'body_axes', 'body_half', 'body_radius', 'center', 'axes', 'half',
               'radius', 'volume', 'gain', 'tris', 'work')
INT_SLOTS = ('parent', 'joint_type', 'q_index', 'is_scene', 'body_elem_start', 'body_elem_end',
             'roots', 'left', 'right', 'first', 'count', 'pair_a', 'pair_b', 'pair_path',
             'status', 'moved', 'body_dirty', 'scene_culled', 'stack', 'counters')
(F_Q_REF, F_T_PARENT_JOINT, F_AXIS, F_MULTIPLIER, F_OFFSET, F_T_WORLD_BODY, F_BODY_CENTER,
 F_BODY_AXES, F_BODY_HALF, F_BODY_RADIUS, F_CENTER, F_AXES, F_HALF, F_RADIUS, F_VOLUME, F_GAIN,
 F_TRIS, F_WORK) = range(len(FLOAT_SLOTS))
(I_PARENT, I_JOINT_TYPE, I_Q_INDEX, I_IS_SCENE, I_BODY_ELEM_START, I_BODY_ELEM_END, I_ROOTS,
 I_LEFT, I_RIGHT, I_FIRST, I_COUNT, I_PAIR_A, I_PAIR_B, I_PAIR_PATH, I_STATUS, I_MOVED,
 I_BODY_DIRTY, I_SCENE_CULLED, I_STACK, I_COUNTERS) = range(len(INT_SLOTS))


@numba.njit(cache=True)
def packed_query(q, full, tolerance, box_method, expansion, n_links, F, F_layout, I, I_layout):
    """Validate ``q``, then run :func:`query_kernel` on the packed buffers.

    :return: ``(rechecked, changed)``; ``rechecked = -1 - j`` and nothing changed when
        ``q[j]`` is not finite.
    """
    for j in range(q.shape[0]):
        if not np.isfinite(q[j]):
            return -1 - j, False
    return query_kernel(
        q, view1(F, F_layout, F_Q_REF), tolerance, full,
        view1(I, I_layout, I_PARENT), view1(I, I_layout, I_JOINT_TYPE),
        view3(F, F_layout, F_T_PARENT_JOINT), view2(F, F_layout, F_AXIS),
        view1(I, I_layout, I_Q_INDEX), view1(F, F_layout, F_MULTIPLIER),
        view1(F, F_layout, F_OFFSET),
        view3(F, F_layout, F_T_WORLD_BODY), n_links, view1(I, I_layout, I_IS_SCENE),
        view1(I, I_layout, I_BODY_ELEM_START), view1(I, I_layout, I_BODY_ELEM_END),
        view2(F, F_layout, F_BODY_CENTER), view3(F, F_layout, F_BODY_AXES),
        view2(F, F_layout, F_BODY_HALF), view1(F, F_layout, F_BODY_RADIUS),
        view1(I, I_layout, I_ROOTS), view2(F, F_layout, F_CENTER), view3(F, F_layout, F_AXES),
        view2(F, F_layout, F_HALF), view1(F, F_layout, F_RADIUS), view1(F, F_layout, F_VOLUME),
        view1(F, F_layout, F_GAIN),
        view1(I, I_layout, I_LEFT), view1(I, I_layout, I_RIGHT), view1(I, I_layout, I_FIRST),
        view1(I, I_layout, I_COUNT), view3(F, F_layout, F_TRIS),
        view1(I, I_layout, I_PAIR_A), view1(I, I_layout, I_PAIR_B),
        view2(I, I_layout, I_PAIR_PATH), view1(I, I_layout, I_STATUS),
        box_method, expansion, view1(I, I_layout, I_MOVED), view1(I, I_layout, I_BODY_DIRTY),
        view1(I, I_layout, I_SCENE_CULLED), view2(I, I_layout, I_STACK),
        view1(F, F_layout, F_WORK), view1(I, I_layout, I_COUNTERS))
