"""One collision query over the whole robot and scene, compiled (paper sec. 2, 4.1, 4.2).

A query takes joint positions and, without returning to the interpreter:

1. decides which joint variables moved (by more than the motion tolerance) since the state
   that the carried statuses describe, and takes their new values into that state;
2. recomputes the world pose of the links below a moved joint (forward kinematics, only where
   needed) and, with a scene, the volumes spanning several links: for each link a world box
   around its subtree's link boxes (the root's is the robot's root volume), rebuilt from the
   link boxes, never from geometry (paper sec. 2.2);
3. re-checks only the pairs whose relative pose can have changed: those with a moved joint on
   the tree path between their two bodies (sec. 4.2); every other pair keeps its status;
4. checks a pair by culling with those volumes (scene pairs), then (incremental
   calls) the pair's last meeting triangle pair, then the two bodies' boxes, then each
   sub-group tree against each (sec. 4.1, :func:`trees_collide`).

Bodies are the robot's links (FK order, world == root link frame) followed by the scene
objects, whose poses never change.

The kernels here and the traversal's leaf and box-test functions compile with ``_nrt=False``
(numba's runtime off: no reference counting). They never allocate, and every array they see is
a view of the checker's two buffers, which the caller holds for the whole call. With the
runtime on, every array passed to a function or made into a view costs an atomic
increment and decrement; that was more than half of a Panda query (4 of 8 us, ``perf``).

numba's on-disk cache (``cache=True``) keys these kernels on a hash of this file only: the
traversal, box, triangle and kinematics functions they inline are compiled into them, and
a change there alone leaves the stale kernel in ``__pycache__``. After editing those modules,
delete ``collision_sensor/__pycache__/query_kernel.*`` (or set ``NUMBA_CACHE_DIR``).
"""
import numba
import numpy as np

from collision_sensor.array_pack import LAYOUT_WIDTH, reshape2, view1, view2, view3
from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.kinematics import JOINT_PRISMATIC, set_link_pose
from collision_sensor.obb_tree import BOX_AXES, BOX_CENTER, BOX_HALF, BOX_RADIUS
from collision_sensor.traversal import (
    BOX_TEST_PAPER, box_in_frame, box_pair_gap, load_box, load_pose, paper_separates,
    sat_separates, spheres_apart, triangle_pair_collides, trees_collide)

WORK_SIZE = 256
#: A pair's clearance is rounded down by this fraction of the pair's coordinate scale (its
#: body boxes' reach plus their distance): it covers the triangle test's contact tolerance
#: (``tolerances.TRIANGLE_EPS_REL`` of the largest coordinate, 1000 times over), boxes that
#: hold their triangles only up to rounding, and the rounding of the gaps and of FK.
CLEARANCE_EPS_REL = 1e-9


@numba.njit(cache=True, inline='always')
def _clearance_margin(body_boxes, a, b, pose):
    """Return CLEARANCE_EPS_REL times a bound of every coordinate the pair's tests see."""
    ca = np.sqrt(body_boxes[a, BOX_CENTER] ** 2 + body_boxes[a, BOX_CENTER + 1] ** 2
                 + body_boxes[a, BOX_CENTER + 2] ** 2)
    cb = np.sqrt(body_boxes[b, BOX_CENTER] ** 2 + body_boxes[b, BOX_CENTER + 1] ** 2
                 + body_boxes[b, BOX_CENTER + 2] ** 2)
    t = np.sqrt(pose[9] * pose[9] + pose[10] * pose[10] + pose[11] * pose[11])
    return CLEARANCE_EPS_REL * (t + ca + cb + body_boxes[a, BOX_RADIUS]
                                + body_boxes[b, BOX_RADIUS])


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
def _subtree_boxes(T_world_body, parent, n_links, body_elem_start, body_elem_end, body_boxes,
                   subtree_boxes):
    """Write, for every link k, the world axis-aligned box around the boxes of all links in
    k's subtree into ``subtree_boxes[k]`` (identity axes): the volumes spanning several links
    (paper sec. 2.2), rebuilt from the link boxes, never from geometry. Row 0 (the root) is
    the robot's root volume. A subtree without geometry gets half extents -1 (empty).
    """
    for k in range(n_links):
        for c in range(6):
            subtree_boxes[k, c] = np.inf if c < 3 else -np.inf  # lo[0:3], hi[3:6] for now
    for b in range(n_links - 1, -1, -1):  # children before parents
        if body_elem_end[b] > body_elem_start[b]:
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
                subtree_boxes[b, i] = min(subtree_boxes[b, i], c - e)
                subtree_boxes[b, 3 + i] = max(subtree_boxes[b, 3 + i], c + e)
        p = parent[b]
        if p >= 0:
            for i in range(3):
                subtree_boxes[p, i] = min(subtree_boxes[p, i], subtree_boxes[b, i])
                subtree_boxes[p, 3 + i] = max(subtree_boxes[p, 3 + i], subtree_boxes[b, 3 + i])
    for k in range(n_links):  # lo/hi -> a box row
        lo0, lo1, lo2 = subtree_boxes[k, 0], subtree_boxes[k, 1], subtree_boxes[k, 2]
        hi0, hi1, hi2 = subtree_boxes[k, 3], subtree_boxes[k, 4], subtree_boxes[k, 5]
        for c in range(subtree_boxes.shape[1]):
            subtree_boxes[k, c] = 0.0
        subtree_boxes[k, BOX_AXES] = 1.0
        subtree_boxes[k, BOX_AXES + 4] = 1.0
        subtree_boxes[k, BOX_AXES + 8] = 1.0
        if not lo0 <= hi0:
            subtree_boxes[k, BOX_HALF] = -1.0  # no geometry below k
            continue
        h0, h1, h2 = 0.5 * (hi0 - lo0), 0.5 * (hi1 - lo1), 0.5 * (hi2 - lo2)
        subtree_boxes[k, BOX_CENTER], subtree_boxes[k, BOX_HALF] = 0.5 * (lo0 + hi0), h0
        subtree_boxes[k, BOX_CENTER + 1], subtree_boxes[k, BOX_HALF + 1] = 0.5 * (lo1 + hi1), h1
        subtree_boxes[k, BOX_CENTER + 2], subtree_boxes[k, BOX_HALF + 2] = 0.5 * (lo2 + hi2), h2
        subtree_boxes[k, BOX_RADIUS] = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)


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
def _scene_body_outside(T_world_body, s, body_boxes, subtree_boxes, k, box_method, work):
    """True iff scene body ``s``'s box is disjoint from the volume of link k's subtree."""
    if subtree_boxes[k, BOX_HALF] < 0.0:
        return True  # nothing with geometry below k
    T = T_world_body[s]
    P = (T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2], T[2, 0], T[2, 1], T[2, 2],
         T[0, 3], T[1, 3], T[2, 3])
    A = load_box(subtree_boxes, k)
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
def _bodies_gap(body_boxes, a, b, pose):
    """Return a lower bound of the distance between the boxes of bodies a and b."""
    return box_pair_gap(load_box(body_boxes, a), load_box(body_boxes, b), load_pose(pose))


@numba.njit(cache=True, _nrt=False)
def query_kernel(q, q_ref, tolerance, full,
                 parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset,
                 T_world_body, n_links, is_scene, body_elem_start, body_elem_end, body_boxes,
                 roots, boxes, nodes, volume, gain, tris,
                 pair_a, pair_b, pair_path, status, witness, clearance, q_eval, reach,
                 reach_ext, box_method, expansion, moved, body_dirty, scene_culled,
                 subtree_boxes, pose, stack, work, tri_work, counters):
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

    Incremental calls also skip a separated pair that cannot have closed its gap (sec. 4.2
    taken further): a pair re-checked by an incremental call and found apart keeps
    ``clearance[p]``, a lower bound of the distance between its two bodies' triangles, and
    ``q_eval[p] = q_ref`` then. Moving variable j by dq moves no point of either body by more
    than ``|dq| * (reach[p, j] + reach_ext[p, j] * E)`` relative to the other (E: the sum of
    the prismatic joints' |value| at ``q_ref``), so while the sum of these over j, with
    ``dq = q_ref[j] - q_eval[p, j]``, is below ``clearance[p]`` the pair is still apart and
    is not re-checked. Full checks record no clearance (``clearance[p] = 0``).

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
    :param clearance, q_eval: (P,), (P, J) float64, carried (see above); ``reach``,
        ``reach_ext``: (P, J) float64, 0 off the pair's path (``CollisionChecker``).
    :param moved, body_dirty: (J,), (B,) int64 work arrays.
    :param scene_culled: (S, L) int64, 1 where scene object s is outside the volume of link
        k's subtree or of one of its ancestors' (row 0: the robot's root volume).
    :param subtree_boxes: (L, BOX_WIDTH), each link's subtree volume (kept between calls).
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
    if (any_link_moved or full) and scene_culled.shape[0] > 0:
        # First culling against the scene by the volumes spanning several links, top down: a
        # link is culled for an object when its subtree's volume, or an ancestor's, misses it.
        _subtree_boxes(T_world_body, parent, n_links, body_elem_start, body_elem_end,
                       body_boxes, subtree_boxes)
        for s in range(scene_culled.shape[0]):
            for k in range(n_links):
                if parent[k] >= 0 and scene_culled[s, parent[k]]:
                    scene_culled[s, k] = 1
                else:
                    scene_culled[s, k] = _scene_body_outside(
                        T_world_body, n_links + s, body_boxes, subtree_boxes, k, box_method, work)
    rechecked = 0
    changed = False
    track = not full
    extension = 0.0  # E: how far the prismatic joints are out, at q_ref
    if track:
        for i in range(n_links):
            if joint_type[i] == JOINT_PRISMATIC:
                extension += abs(multiplier[i] * q_ref[q_index[i]] + offset[i])
    for p in range(pair_a.shape[0]):
        if track:
            affected = False
            travel = 0.0
            for j in range(n_joints):
                if pair_path[p, j]:
                    affected |= moved[j] != 0
                    dq = q_ref[j] - q_eval[p, j]
                    if dq != 0.0:
                        travel += abs(dq) * (reach[p, j] + reach_ext[p, j] * extension)
            if not affected:
                continue
            if status[p] == 0 and travel < clearance[p]:
                continue  # still apart: nothing moved far enough to close the gap
        rechecked += 1
        a = pair_a[p]
        b = pair_b[p]
        hit = False
        gap = 0.0
        if not (is_scene[b] and scene_culled[b - n_links, a]):
            _write_pair_pose(T_world_body, a, b, pose)
            wa = witness[p, 0] if track else -1
            wb = witness[p, 1] if track else -1
            single = (body_elem_end[a] - body_elem_start[a] == 1
                      and body_elem_end[b] - body_elem_start[b] == 1)
            if wa >= 0:
                hit = triangle_pair_collides(tris, wa, wb, pose, tri_work)
            if not hit:
                # A body of one sub-group has its tree's root box as body box: the traversal
                # tests that first, so the body box is only worth testing for several trees.
                if single or not _bodies_apart(body_boxes, a, b, pose, box_method, work):
                    gap = np.inf
                    for ea in range(body_elem_start[a], body_elem_end[a]):
                        for eb in range(body_elem_start[b], body_elem_end[b]):
                            hit, ia, ib, tree_gap = trees_collide(
                                roots[ea], roots[eb], pose, boxes, nodes, volume, gain, tris,
                                box_method, expansion, stack, work, tri_work, counters, track,
                                wa, wb)
                            if hit:
                                witness[p, 0] = ia
                                witness[p, 1] = ib
                                break
                            gap = min(gap, tree_gap)
                        if hit:
                            break
                elif track:
                    gap = _bodies_gap(body_boxes, a, b, pose)
                if track and not hit:
                    gap -= _clearance_margin(body_boxes, a, b, pose)
        if not hit:
            witness[p, 0] = -1
        clearance[p] = gap if track and not hit and gap > 0.0 else 0.0
        if clearance[p] > 0.0:
            for j in range(n_joints):
                q_eval[p, j] = q_ref[j]
        changed |= status[p] != hit
        status[p] = 1 if hit else 0
    return rechecked, changed


# Slots of the packed buffers (see collision_sensor.array_pack); CollisionChecker adds the
# arrays in exactly this order. The first int slot, ``header``, holds the scalars and both
# layout tables, so that a call passes three arrays and a flag (numba types every argument
# on every call); the first float slot holds the float scalars.
FLOAT_SLOTS = ('scalars', 'q_last', 'q_ref', 'T_parent_joint', 'axis', 'multiplier', 'offset',
               'T_world_body', 'body_boxes', 'boxes', 'volume', 'gain', 'tris', 'subtree_boxes',
               'pose', 'work', 'tri_work', 'clearance', 'q_eval', 'reach', 'reach_ext')
INT_SLOTS = ('header', 'parent', 'joint_type', 'q_index', 'is_scene', 'body_elem_start',
             'body_elem_end', 'roots', 'nodes', 'pair_a', 'pair_b', 'pair_path', 'status',
             'witness', 'moved', 'body_dirty', 'scene_culled', 'stack', 'counters')
(F_SCALARS, F_Q_LAST, F_Q_REF, F_T_PARENT_JOINT, F_AXIS, F_MULTIPLIER, F_OFFSET,
 F_T_WORLD_BODY, F_BODY_BOXES, F_BOXES, F_VOLUME, F_GAIN, F_TRIS, F_SUBTREE_BOXES, F_POSE, F_WORK,
 F_TRI_WORK, F_CLEARANCE, F_Q_EVAL, F_REACH, F_REACH_EXT) = range(len(FLOAT_SLOTS))
(I_HEADER, I_PARENT, I_JOINT_TYPE, I_Q_INDEX, I_IS_SCENE, I_BODY_ELEM_START, I_BODY_ELEM_END,
 I_ROOTS, I_NODES, I_PAIR_A, I_PAIR_B, I_PAIR_PATH, I_STATUS, I_WITNESS, I_MOVED,
 I_BODY_DIRTY, I_SCENE_CULLED, I_STACK, I_COUNTERS) = range(len(INT_SLOTS))
# scalars[S_*] (float slot 0, at offset 0 of the float buffer).
S_TOLERANCE = 0
N_SCALARS = 1
# header[H_*] (int slot 0, at offset 0 of the int buffer), then the float buffer's layout
# (len(FLOAT_SLOTS), LAYOUT_WIDTH), then the int buffer's.
H_N_LINKS, H_BOX_METHOD, H_EXPANSION, H_CHECKED_ONCE = range(4)
H_LAYOUTS = 4
H_I_LAYOUT = H_LAYOUTS + len(FLOAT_SLOTS) * LAYOUT_WIDTH
HEADER_SIZE = H_I_LAYOUT + len(INT_SLOTS) * LAYOUT_WIDTH


def write_header(I, F_layout, I_layout, n_links, box_method, expansion):
    """Fill the int buffer's header (``I[:HEADER_SIZE]``) once, after packing."""
    I[H_N_LINKS], I[H_BOX_METHOD], I[H_EXPANSION], I[H_CHECKED_ONCE] = (
        n_links, box_method, expansion, 0)
    I[H_LAYOUTS:H_I_LAYOUT] = F_layout.ravel()
    I[H_I_LAYOUT:HEADER_SIZE] = I_layout.ravel()


@numba.njit(cache=True, _nrt=False)
def packed_query(q, full, F, I):
    """Validate ``q``, copy it to the ``q_last`` slot, run :func:`query_kernel` on the buffers.

    The caller passes its own array (no copy): it is only read, before anything changes.
    The first call always checks in full (``header[H_CHECKED_ONCE]`` is 0 until then).

    :return: ``2 * rechecked + changed`` (pairs re-checked, any status changed), or
        ``-1 - j`` when ``q[j]`` is not finite; nothing changed then.
    """
    for j in range(q.shape[0]):
        if not np.isfinite(q[j]):
            return -1 - j
    F_layout = reshape2(I[H_LAYOUTS:H_I_LAYOUT], (len(FLOAT_SLOTS), LAYOUT_WIDTH))
    I_layout = reshape2(I[H_I_LAYOUT:HEADER_SIZE], (len(INT_SLOTS), LAYOUT_WIDTH))
    q_last = view1(F, F_layout, F_Q_LAST)
    q_ref = view1(F, F_layout, F_Q_REF)
    full = full or I[H_CHECKED_ONCE] == 0
    any_moved = full
    for j in range(q.shape[0]):
        q_last[j] = q[j]
        if abs(q[j] - q_ref[j]) > F[S_TOLERANCE]:
            any_moved = True
    if not any_moved:
        return 0  # as query_kernel would, without cutting its forty views first
    I[H_CHECKED_ONCE] = 1
    rechecked, changed = query_kernel(
        q_last, q_ref, F[S_TOLERANCE], full,
        view1(I, I_layout, I_PARENT), view1(I, I_layout, I_JOINT_TYPE),
        view3(F, F_layout, F_T_PARENT_JOINT), view2(F, F_layout, F_AXIS),
        view1(I, I_layout, I_Q_INDEX), view1(F, F_layout, F_MULTIPLIER),
        view1(F, F_layout, F_OFFSET),
        view3(F, F_layout, F_T_WORLD_BODY), I[H_N_LINKS], view1(I, I_layout, I_IS_SCENE),
        view1(I, I_layout, I_BODY_ELEM_START), view1(I, I_layout, I_BODY_ELEM_END),
        view2(F, F_layout, F_BODY_BOXES),
        view1(I, I_layout, I_ROOTS), view2(F, F_layout, F_BOXES), view2(I, I_layout, I_NODES),
        view1(F, F_layout, F_VOLUME), view1(F, F_layout, F_GAIN), view3(F, F_layout, F_TRIS),
        view1(I, I_layout, I_PAIR_A), view1(I, I_layout, I_PAIR_B),
        view2(I, I_layout, I_PAIR_PATH), view1(I, I_layout, I_STATUS),
        view2(I, I_layout, I_WITNESS), view1(F, F_layout, F_CLEARANCE),
        view2(F, F_layout, F_Q_EVAL), view2(F, F_layout, F_REACH),
        view2(F, F_layout, F_REACH_EXT), I[H_BOX_METHOD], I[H_EXPANSION],
        view1(I, I_layout, I_MOVED),
        view1(I, I_layout, I_BODY_DIRTY),
        view2(I, I_layout, I_SCENE_CULLED), view2(F, F_layout, F_SUBTREE_BOXES),
        view1(F, F_layout, F_POSE), view2(I, I_layout, I_STACK),
        view1(F, F_layout, F_WORK), view3(F, F_layout, F_TRI_WORK),
        view1(I, I_layout, I_COUNTERS))
    return 2 * rechecked + (1 if changed else 0)


bind_to_kernel_sources(globals())
