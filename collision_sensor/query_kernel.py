"""One collision query over the whole robot and scene, compiled (paper sec. 2, 4.1, 4.2).

A query takes joint positions and, without returning to the interpreter:

1. decides which joint variables moved (by more than the motion tolerance) since the state
   that the carried statuses describe, and takes their new values into that state;
2. recomputes the world pose of the links below a moved joint (forward kinematics, only where
   needed) and the robot's root volume (a world box around all link boxes, rebuilt from the
   link boxes, never from geometry: paper sec. 2.2);
3. re-checks only the pairs whose relative pose can have changed: those with a moved joint on
   the tree path between their two bodies (sec. 4.2); every other pair keeps its status;
4. checks a pair by culling with the robot root volume (scene pairs), then (incremental
   calls) the pair's last meeting triangle pair, then the two bodies' boxes, then each
   sub-group tree against each (sec. 4.1, :func:`trees_collide`).

Bodies are the robot's links (FK order, world == root link frame) followed by the scene
objects, whose poses never change.

The kernels here and the traversal's leaf and box-test functions compile with ``_nrt=False``
(numba's runtime off: no reference counting). They never allocate, and every array they see is
a view of the checker's two buffers, which the caller holds for the whole call. With the
runtime on, every array passed to a function or made into a view costs an atomic
increment and decrement; that was more than half of a Panda query (4 of 8 us, ``perf``).
"""
import numba
import numpy as np

from collision_sensor.array_pack import view1, view2, view3
from collision_sensor.kinematics import set_link_pose
from collision_sensor.obb_tree import BOX_AXES, BOX_CENTER, BOX_HALF
from collision_sensor.traversal import (
    BOX_TEST_PAPER, box_in_frame, load_box, load_pose, paper_separates, sat_separates,
    spheres_apart, triangle_pair_collides, trees_collide)

WORK_SIZE = 256


@numba.njit(cache=True, inline='always')
def _write_pair_pose(T_world_body, a, b, pose):
    """Write body b's pose in body a's frame into ``pose`` (R_ab row-major, then t_ab).

    ``[R_ab, t_ab] = T_world_a^-1 T_world_b = [Ra' Rb, Ra' (tb - ta)]``.
    """
    for i in range(3):
        for j in range(3):
            pose[3 * i + j] = (T_world_body[a, 0, i] * T_world_body[b, 0, j]
                               + T_world_body[a, 1, i] * T_world_body[b, 1, j]
                               + T_world_body[a, 2, i] * T_world_body[b, 2, j])
        pose[9 + i] = (T_world_body[a, 0, i] * (T_world_body[b, 0, 3] - T_world_body[a, 0, 3])
                       + T_world_body[a, 1, i] * (T_world_body[b, 1, 3] - T_world_body[a, 1, 3])
                       + T_world_body[a, 2, i] * (T_world_body[b, 2, 3] - T_world_body[a, 2, 3]))


@numba.njit(cache=True, _nrt=False)
def _robot_root_box(T_world_body, n_links, body_elem_start, body_elem_end, body_boxes,
                    root_box):
    """Write the world axis-aligned box around every link box (the robot's root volume,
    sec. 2.2) into ``root_box`` (1, BOX_WIDTH): identity axes."""
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    for b in range(n_links):
        if body_elem_end[b] == body_elem_start[b]:
            continue
        for i in range(3):
            c = T_world_body[b, i, 3]
            e = 0.0
            for k in range(3):
                c += T_world_body[b, i, k] * body_boxes[b, BOX_CENTER + k]
                # |row i of R_world_box| . half: the box's half width along world axis i.
                ax = (T_world_body[b, i, 0] * body_boxes[b, BOX_AXES + k]
                      + T_world_body[b, i, 1] * body_boxes[b, BOX_AXES + 3 + k]
                      + T_world_body[b, i, 2] * body_boxes[b, BOX_AXES + 6 + k])
                e += abs(ax) * body_boxes[b, BOX_HALF + k]
            if i == 0:
                lo0, hi0 = min(lo0, c - e), max(hi0, c + e)
            elif i == 1:
                lo1, hi1 = min(lo1, c - e), max(hi1, c + e)
            else:
                lo2, hi2 = min(lo2, c - e), max(hi2, c + e)
    root_box[0, :] = 0.0
    root_box[0, BOX_AXES] = root_box[0, BOX_AXES + 4] = root_box[0, BOX_AXES + 8] = 1.0
    h0, h1, h2 = 0.5 * (hi0 - lo0), 0.5 * (hi1 - lo1), 0.5 * (hi2 - lo2)
    root_box[0, BOX_CENTER], root_box[0, BOX_HALF] = 0.5 * (lo0 + hi0), h0
    root_box[0, BOX_CENTER + 1], root_box[0, BOX_HALF + 1] = 0.5 * (lo1 + hi1), h1
    root_box[0, BOX_CENTER + 2], root_box[0, BOX_HALF + 2] = 0.5 * (lo2 + hi2), h2
    root_box[0, 15] = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)


@numba.njit(cache=True, _nrt=False)
def _boxes_apart(A, B, P, box_method, work):
    """True iff boxes A (a load_box tuple) and B (at pose P in A's body) are apart."""
    if spheres_apart(A, B, P):
        return True
    T = box_in_frame(A, B, P)
    if box_method == BOX_TEST_PAPER:
        return paper_separates(A, B, T, work)
    return sat_separates(A, B, T)


@numba.njit(cache=True, _nrt=False)
def _scene_body_outside_root(T_world_body, s, body_boxes, root_box, box_method, work):
    """True iff scene body ``s``'s box is disjoint from the robot's root volume."""
    T = T_world_body[s]
    P = (T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2], T[2, 0], T[2, 1], T[2, 2],
         T[0, 3], T[1, 3], T[2, 3])
    A = load_box(root_box, 0)
    B = load_box(body_boxes, s)
    return _boxes_apart(A, B, P, box_method, work)


@numba.njit(cache=True, _nrt=False)
def _bodies_apart(body_boxes, a, b, pose, box_method, work):
    """True iff the boxes of bodies a and b (b at ``pose`` in a's frame) are apart."""
    A = load_box(body_boxes, a)
    B = load_box(body_boxes, b)
    P = load_pose(pose)
    return _boxes_apart(A, B, P, box_method, work)


@numba.njit(cache=True, _nrt=False)
def query_kernel(q, q_ref, tolerance, full,
                 parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset,
                 T_world_body, n_links, is_scene, body_elem_start, body_elem_end, body_boxes,
                 roots, boxes, nodes, volume, gain, tris,
                 pair_a, pair_b, pair_path, status, witness,
                 box_method, expansion, moved, body_dirty, scene_culled, root_box, pose,
                 stack, work, tri_work, counters):
    """Bring ``status`` up to date with ``q``; return (pairs re-checked, any status changed).

    Contract in plain Python (``full`` or tolerance 0 makes it exact for the given ``q``)::

        moved = full | (abs(q - q_ref) > tolerance);  q_ref[moved] = q[moved]
        T_world_body[links] = forward_kinematics(q_ref)        # only links below a moved joint
        for p in pairs:
            if full or moved[pair_path[p]].any():
                status[p] = bodies_collide(pair_a[p], pair_b[p])

    Incremental calls (not ``full``) first test the pair's witness, the triangle pair that
    met when the pair last collided: under small motion a colliding pair usually still
    collides there, which then costs one triangle test instead of a descent (the answer is
    the same either way; a witness that no longer meets only costs that test). ``full``
    calls use nothing carried over.

    :param q, q_ref: (J,) float64 requested positions, and the state the statuses describe
        (updated in place).
    :param parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset: the
        :class:`~collision_sensor.kinematics.KinematicTree` arrays of the ``n_links`` links.
    :param T_world_body: (B, 4, 4) body poses, links first, then scene objects (fixed).
    :param is_scene: (B,) int64, 1 for scene objects.
    :param body_elem_start, body_elem_end: (B,) int64, each body's trees are
        ``roots[start:end]``.
    :param body_boxes: (B, BOX_WIDTH) each body's box over all its trees (body frame), see
        :func:`~collision_sensor.obb_tree.box_table`.
    :param boxes, nodes, volume, gain, tris: the forest's tables (see
        :mod:`collision_sensor.traversal`).
    :param pair_a, pair_b: (P,) int64 bodies of each checked pair; a scene body is always b.
    :param pair_path: (P, J) int64, 1 where variable j drives a joint on the pair's tree path.
    :param status: (P,) int64, 1 if the pair collides (updated in place).
    :param witness: (P, 2) int64, rows of ``tris`` that last met for each pair, or -1.
    :param moved, body_dirty: (J,), (B,) int64 work arrays.
    :param scene_culled: (S,) int64, 1 where a scene object is outside the robot's root volume.
    :param root_box: (1, BOX_WIDTH), the robot's root volume (kept between calls).
    :param pose: (POSE_WIDTH,) float64 work: the pair's relative pose.
    :param stack, work, tri_work, counters: see :func:`trees_collide`.
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
    if any_link_moved or full:
        _robot_root_box(T_world_body, n_links, body_elem_start, body_elem_end, body_boxes,
                        root_box)
        for s in range(scene_culled.shape[0]):
            scene_culled[s] = _scene_body_outside_root(T_world_body, n_links + s, body_boxes,
                                                       root_box, box_method, work)
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
        if not (is_scene[b] and scene_culled[b - n_links]):
            _write_pair_pose(T_world_body, a, b, pose)
            if not full and witness[p, 0] >= 0:
                hit = triangle_pair_collides(tris, witness[p, 0], witness[p, 1], pose, tri_work)
            if not hit:
                single = (body_elem_end[a] - body_elem_start[a] == 1
                          and body_elem_end[b] - body_elem_start[b] == 1)
                # A body of one sub-group has its tree's root box as body box: the traversal
                # tests that first, so the body box is only worth testing for several trees.
                if single or not _bodies_apart(body_boxes, a, b, pose, box_method, work):
                    for ea in range(body_elem_start[a], body_elem_end[a]):
                        for eb in range(body_elem_start[b], body_elem_end[b]):
                            hit, ia, ib = trees_collide(
                                roots[ea], roots[eb], pose, boxes, nodes, volume, gain, tris,
                                box_method, expansion, stack, work, tri_work, counters)
                            if hit:
                                witness[p, 0] = ia
                                witness[p, 1] = ib
                                break
                        if hit:
                            break
        if not hit:
            witness[p, 0] = -1
        changed |= status[p] != hit
        status[p] = 1 if hit else 0
    return rechecked, changed


# Slots of the packed buffers (see collision_sensor.array_pack); CollisionChecker adds the
# arrays in exactly this order.
FLOAT_SLOTS = ('q_ref', 'T_parent_joint', 'axis', 'multiplier', 'offset', 'T_world_body',
               'body_boxes', 'boxes', 'volume', 'gain', 'tris', 'root_box', 'pose', 'work',
               'tri_work')
INT_SLOTS = ('parent', 'joint_type', 'q_index', 'is_scene', 'body_elem_start', 'body_elem_end',
             'roots', 'nodes', 'pair_a', 'pair_b', 'pair_path', 'status', 'witness', 'moved',
             'body_dirty', 'scene_culled', 'stack', 'counters')
(F_Q_REF, F_T_PARENT_JOINT, F_AXIS, F_MULTIPLIER, F_OFFSET, F_T_WORLD_BODY, F_BODY_BOXES,
 F_BOXES, F_VOLUME, F_GAIN, F_TRIS, F_ROOT_BOX, F_POSE, F_WORK, F_TRI_WORK) = range(
    len(FLOAT_SLOTS))
(I_PARENT, I_JOINT_TYPE, I_Q_INDEX, I_IS_SCENE, I_BODY_ELEM_START, I_BODY_ELEM_END, I_ROOTS,
 I_NODES, I_PAIR_A, I_PAIR_B, I_PAIR_PATH, I_STATUS, I_WITNESS, I_MOVED, I_BODY_DIRTY,
 I_SCENE_CULLED, I_STACK, I_COUNTERS) = range(len(INT_SLOTS))


@numba.njit(cache=True, _nrt=False)
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
        view2(F, F_layout, F_BODY_BOXES),
        view1(I, I_layout, I_ROOTS), view2(F, F_layout, F_BOXES), view2(I, I_layout, I_NODES),
        view1(F, F_layout, F_VOLUME), view1(F, F_layout, F_GAIN), view3(F, F_layout, F_TRIS),
        view1(I, I_layout, I_PAIR_A), view1(I, I_layout, I_PAIR_B),
        view2(I, I_layout, I_PAIR_PATH), view1(I, I_layout, I_STATUS),
        view2(I, I_layout, I_WITNESS),
        box_method, expansion, view1(I, I_layout, I_MOVED), view1(I, I_layout, I_BODY_DIRTY),
        view1(I, I_layout, I_SCENE_CULLED), view2(F, F_layout, F_ROOT_BOX),
        view1(F, F_layout, F_POSE), view2(I, I_layout, I_STACK),
        view1(F, F_layout, F_WORK), view3(F, F_layout, F_TRI_WORK),
        view1(I, I_layout, I_COUNTERS))
