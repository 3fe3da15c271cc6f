"""One collision query over the whole robot and scene, compiled (paper sec. 2, 4.1, 4.2).

A query takes joint positions and, without returning to the interpreter:

1. decides which joint variables moved (by more than the motion tolerance) since the state
   that the carried statuses describe, and takes their new values into that state
   (:func:`plan_update`; :func:`plan_full` takes them all);
2. lists only the pairs whose relative pose can have changed: those with a moved joint on
   the tree path between their two bodies (sec. 4.2), minus those whose recorded clearance
   the motion cannot have closed; every other pair keeps its status;
3. re-checks the listed pairs (:func:`recheck_pairs`): (full checks) culling with the
   volumes spanning several links (scene pairs), (incremental calls) the pair's last
   meeting triangle pair, then the two bodies' boxes, then each sub-group tree against
   each (sec. 4.1, :func:`trees_collide`); an incremental call starts a pair in near contact
   from its front, the node pairs where its last proof stopped (:func:`_trees_of_pair`).

Poses follow the joints lazily: a moved joint marks the links below it stale, and a link's
world pose (forward kinematics) is recomputed only when a pair being re-checked needs it,
or when Python asks for the poses (:func:`packed_poses`). A step that re-checks nothing
costs the pairs on the moved joints' lists, not the kinematics. Full checks rebuild the
volumes spanning several links (for each link a world box around its subtree's link boxes,
the root's being the robot's root volume, from the link boxes, never from geometry: paper
sec. 2.2) and cull scene pairs with them first.

Bodies are the robot's links (FK order, parents first, world == root link frame) followed by
the scene objects, whose poses never change.

The kernels here and the traversal's leaf and box-test functions compile with ``_nrt=False``
(numba's runtime off: no reference counting). They never allocate, and every array they see is
a view of the checker's two buffers, which the caller holds for the whole call. With the
runtime on, every array passed to a function or made into a view costs an atomic
increment and decrement; that was more than half of a Panda query (4 of 8 us, ``perf``).

numba's on-disk cache keys kernels on their own file only; :mod:`kernel_cache` binds every
kernel module's cache to a digest of all of them, so editing any one recompiles them all.
"""
import numba
import numpy as np

from collision_sensor.array_pack import LAYOUT_WIDTH, view1, view2, view3, view_at2
from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.kinematics import JOINT_PRISMATIC, set_link_pose
from collision_sensor.obb_tree import BOX_AXES, BOX_CENTER, BOX_HALF, BOX_RADIUS
from collision_sensor.traversal import (
    BOX_TEST_PAPER, box_in_frame, box_pair_gap, load_box, load_pose, paper_separates,
    COUNT_BOX_TESTS, COUNT_SPHERE_SKIPS, COUNT_TRIANGLE_TESTS, front_scan, sat_separates,
    spheres_apart, triangle_pair_collides, trees_collide)

WORK_SIZE = 256
#: A pair's clearance is rounded down by this fraction of the pair's coordinate scale (its
#: body boxes' reach plus their distance): it covers the triangle test's contact tolerance
#: (``tolerances.TRIANGLE_EPS_REL`` of the largest coordinate, 1000 times over), boxes that
#: hold their triangles only up to rounding, and the rounding of the gaps and of FK.
CLEARANCE_EPS_REL = 1e-9
#: A skipped pair's running travel sum is replaced by the exact sum once it reaches this
#: fraction of the pair's clearance (see :func:`plan_update`).
TRAVEL_GUARD = 1.0 - 1e-6
#: ... and every tracked pair's, at least once in this many incremental calls: each call
#: adds at most a few ulps of the clearance of rounding, far below 1 - TRAVEL_GUARD even then.
TRAVEL_RESYNC_CALLS = 1 << 24
#: Rows of all pairs' fronts together, and the bounds of one pair's (a front larger than its
#: rows is not kept: that pair descends from the roots every time, as a full check does).
FRONT_POOL_ROWS = 1 << 16
#: A pair keeps a front only while its clearance is at most this fraction of its size (the
#: sum of its two body boxes' radii): below that, the clearance skips almost no step.
FRONT_GAP_REL = 1e-3
FRONT_ROWS_MIN, FRONT_ROWS_MAX = 64, 1024


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
def _refresh_pose(i, q_ref, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                  offset, T_world_body, stale, chain):
    """Bring body i's world pose up to date with ``q_ref``: it and its stale ancestors, top
    down (``chain``: (L,) int64 work). Scene bodies are never stale."""
    n = 0
    k = i
    while k >= 0 and stale[k]:
        chain[n] = k
        n += 1
        k = parent[k]
    for t in range(n - 1, -1, -1):
        k = chain[t]
        set_link_pose(k, q_ref, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                      offset, T_world_body)
        stale[k] = 0


@numba.njit(cache=True, _nrt=False)
def _refresh_all_poses(n_links, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                       multiplier, offset, T_world_body, stale):
    """Bring every stale link pose up to date (links come parents first)."""
    for i in range(n_links):
        if stale[i]:
            set_link_pose(i, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                          multiplier, offset, T_world_body)
            stale[i] = 0


@numba.njit(cache=True, _nrt=False)
def _refresh_culling(T_world_body, parent, n_links, body_elem_start, body_elem_end, body_boxes,
                     subtree_boxes, scene_culled, box_method, work):
    """First culling against the scene by the volumes spanning several links, top down: link
    k is culled for object s when its subtree's volume, or an ancestor's, misses s's box.
    Every link pose must be current."""
    _subtree_boxes(T_world_body, parent, n_links, body_elem_start, body_elem_end, body_boxes,
                   subtree_boxes)
    for s in range(scene_culled.shape[0]):
        for k in range(n_links):
            if parent[k] >= 0 and scene_culled[s, parent[k]]:
                scene_culled[s, k] = 1
            else:
                scene_culled[s, k] = _scene_body_outside(
                    T_world_body, n_links + s, body_boxes, subtree_boxes, k, box_method, work)


@numba.njit(cache=True, _nrt=False)
def _extension(q_ref, n_links, joint_type, q_index, multiplier, offset):
    """E: the sum of |value| of the prismatic joints at ``q_ref`` (see :func:`plan_update`)."""
    extension = 0.0
    for i in range(n_links):
        if joint_type[i] == JOINT_PRISMATIC:
            extension += abs(multiplier[i] * q_ref[q_index[i]] + offset[i])
    return extension


@numba.njit(cache=True, _nrt=False)
def _resync_travel(p, q_ref, q_eval, reach, reach_ext, travel):
    """Recompute pair p's two travel sums from scratch: over variables j,
    ``|q_ref[j] - q_eval[p, j]|`` times ``reach[p, j]`` and times ``reach_ext[p, j]`` (both
    0 off the pair's path)."""
    fixed = 0.0
    ext = 0.0
    for j in range(q_ref.shape[0]):
        d = abs(q_ref[j] - q_eval[p, j])
        fixed += d * reach[p, j]
        ext += d * reach_ext[p, j]
    travel[p, 0] = fixed
    travel[p, 1] = ext


@numba.njit(cache=True, _nrt=False)
def plan_full(q, q_ref, n_links, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
              offset, T_world_body, stale, scalars):
    """Start a full check: take all of ``q``, recompute every link pose and E."""
    for j in range(q.shape[0]):
        q_ref[j] = q[j]
    for i in range(n_links):
        stale[i] = 1
    _refresh_all_poses(n_links, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                       multiplier, offset, T_world_body, stale)
    scalars[S_EXTENSION] = _extension(q_ref, n_links, joint_type, q_index, multiplier, offset)


@numba.njit(cache=True, inline='always')
def _add_travel(p, j, old, new, q_eval, reach, reach_ext, travel):
    """Move pair p's travel sums by variable j's terms going from ``old`` to ``new``."""
    e = q_eval[p, j]
    d = abs(new - e) - abs(old - e)
    travel[p, 0] += d * reach[p, j]
    travel[p, 1] += d * reach_ext[p, j]


@numba.njit(cache=True, inline='always')
def _needs_recheck(p, status, clearance, travel, q_ref, q_eval, reach, reach_ext, extension):
    """False iff pair p is known to be still apart: its travel is below its clearance."""
    if status[p] != 0 or clearance[p] <= 0.0:
        return True
    if travel[p, 0] + extension * travel[p, 1] < TRAVEL_GUARD * clearance[p]:
        return False
    _resync_travel(p, q_ref, q_eval, reach, reach_ext, travel)  # exact near the edge
    return travel[p, 0] + extension * travel[p, 1] >= clearance[p]


# Inlined into packed_query: passing its 25 arrays to a call cost 25 ns of a 150 ns step.
@numba.njit(cache=True, _nrt=False, inline='always')
def plan_update(q, q_ref, tolerance, moved, n_links, joint_type, q_index, multiplier, offset,
                joint_links_start, joint_links, joint_prismatic, stale, joint_pairs_start,
                joint_pairs, status, clearance, q_eval, reach, reach_ext, travel, pending, todo,
                scalars, header):
    """Take the joints of ``q`` that moved into ``q_ref``; list the pairs to re-check.

    Contract in plain Python (paper sec. 4.2, taken further by the clearance)::

        moved = abs(q - q_ref) > tolerance;  q_ref[moved] = q[moved]
        stale[links below a moved joint] = 1          # poses follow on demand
        todo = [p for p in pairs if moved[path(p)].any()
                and not (status[p] == 0 and travel(p) < clearance[p])]

    A pair re-checked incrementally and found apart keeps ``clearance[p]``, a lower bound of
    the distance between its two bodies' triangles, and ``q_eval[p] = q_ref`` then (full
    checks record none: ``clearance[p] = 0``). Moving variable j by dq moves no point of
    either body by more than ``|dq| * (reach[p, j] + reach_ext[p, j] * E)`` relative to the
    other (E: the sum of the prismatic joints' |value| at ``q_ref``), so while the sum of
    these, ``travel(p)`` from ``q_eval[p]`` to ``q_ref``, stays below ``clearance[p]`` the
    pair is still apart. Each pair keeps the two sums of ``|dq|`` times ``reach`` and times
    ``reach_ext`` (``travel[p] = (fixed, ext)``, ``travel(p) = fixed + E * ext``), so a
    slider moving changes E without touching any sum. Only the pairs on a moved variable's
    list are visited, and their sums move by that variable's terms alone, so a step costs
    the pairs it touches, not pairs times joints (one pass when one variable moved). The
    running sums are recomputed exactly when a pair's travel comes within ``TRAVEL_GUARD``
    of its clearance, and every ``TRAVEL_RESYNC_CALLS`` calls: every term stays below the
    clearance while a pair is skipped, so the rounding drift (a few ulps of the clearance
    per call) stays far below the guard.

    :param moved: (J,) int64 work: the moved variables.
    :param joint_links_start, joint_links, joint_prismatic: variable j's links (those whose
        pose depends on it: the links it drives and all below them) are
        ``joint_links[joint_links_start[j]:joint_links_start[j + 1]]``; ``joint_prismatic[j]``
        is 1 if j drives a prismatic joint (E depends on it).
    :param stale: (B,) int64, 1 where a link's pose is behind ``q_ref`` (kept between calls).
    :param joint_pairs_start, joint_pairs: variable j's pairs (those with j on their path)
        are ``joint_pairs[joint_pairs_start[j]:joint_pairs_start[j + 1]]``.
    :param travel: (P, 2) float64, each tracked pair's running sums (kept between calls).
    :param pending, todo: (P,) int64 work; ``pending`` is all 0 between calls.
    :param scalars, header: the float scalars (E) and the int header (resync count).
    :return: the number of pairs written to ``todo``.
    """
    n_moved = 0
    prismatic = False
    for j in range(q.shape[0]):
        if abs(q[j] - q_ref[j]) > tolerance:
            moved[n_moved] = j
            n_moved += 1
            prismatic |= joint_prismatic[j] != 0
    if n_moved == 0:
        return 0
    for m in range(n_moved):
        j = moved[m]
        for t in range(joint_links_start[j], joint_links_start[j + 1]):
            stale[joint_links[t]] = 1
    header[H_RESYNC_COUNTDOWN] -= 1
    resync = header[H_RESYNC_COUNTDOWN] <= 0
    extension = scalars[S_EXTENSION]
    n = 0
    if n_moved == 1 and not resync:
        j = moved[0]
        old = q_ref[j]
        new = q_ref[j] = q[j]
        if prismatic:
            scalars[S_EXTENSION] = extension = _extension(q_ref, n_links, joint_type, q_index,
                                                          multiplier, offset)
        for t in range(joint_pairs_start[j], joint_pairs_start[j + 1]):
            p = joint_pairs[t]
            if clearance[p] > 0.0:
                _add_travel(p, j, old, new, q_eval, reach, reach_ext, travel)
            if _needs_recheck(p, status, clearance, travel, q_ref, q_eval, reach, reach_ext,
                              extension):
                todo[n] = p
                n += 1
        return n
    for m in range(n_moved):
        j = moved[m]
        old = q_ref[j]
        new = q_ref[j] = q[j]
        for t in range(joint_pairs_start[j], joint_pairs_start[j + 1]):
            p = joint_pairs[t]
            if clearance[p] > 0.0 and not resync:
                _add_travel(p, j, old, new, q_eval, reach, reach_ext, travel)
            if not pending[p]:
                pending[p] = 1
                todo[n] = p
                n += 1
    if prismatic:
        scalars[S_EXTENSION] = extension = _extension(q_ref, n_links, joint_type, q_index,
                                                      multiplier, offset)
    if resync:
        header[H_RESYNC_COUNTDOWN] = TRAVEL_RESYNC_CALLS
        for p in range(clearance.shape[0]):
            if clearance[p] > 0.0:
                _resync_travel(p, q_ref, q_eval, reach, reach_ext, travel)
    kept = 0
    for t in range(n):
        p = todo[t]
        pending[p] = 0
        if _needs_recheck(p, status, clearance, travel, q_ref, q_eval, reach, reach_ext,
                          extension):
            todo[kept] = p
            kept += 1
    return kept


@numba.njit(cache=True, inline='always')
def _trees_of_pair(p, track, status, scale, travel, margin, first_a, end_a, first_b, end_b,
                   roots, pose, boxes, nodes, volume, gain, tris, box_method, expansion, stack,
                   work, tri_work, counters, wa, wb, front, front_until, front_state):

    """Test every sub-group tree of pair p's body a against every one of body b's.

    A full check descends from the roots. An incremental one starts from the pair's front
    when it has one (:func:`~collision_sensor.traversal.front_scan`): the node pairs where
    its last descent that found it apart stopped. A front covers every pair of triangles
    whatever the poses, so it never goes stale, only costlier: it lies where the pair's
    last proofs went, and no node pair on it is ever merged back into its parent. So it is
    kept while a re-check from it tests at most as many node pairs and triangle pairs as the
    last descent from the roots did; else the next re-check descends from the roots again
    and records a fresh one. Only a pair that was
    apart starts from its front: one that collided is likely to still collide, and a descent
    from the roots towards its last meeting triangles stops at the first that meet, where a
    front would be tried in full first. And only a pair whose clearance is tiny
    (``FRONT_GAP_REL``) keeps one: a pair with a real clearance is skipped for whole steps,
    and the finer node pairs of a front would only make that clearance smaller.

    :param front, front_until: ((P + 1) * F, 3) int64 and ((P + 1) * F,) float64: pair p's
        front in rows ``p * F`` on, the node pairs and their ``until`` (see
        :func:`~collision_sensor.traversal.front_scan`); the last F rows are work, where a
        front is recorded.
    :param front_state: (P, 2) int64, each pair's front length (0: none) and the tests its
        last descent from the roots made.
    :param travel, margin: the pair's travel (``front_travel``) and rounding margin.
    :return: ``(hit, ia, ib, gap)`` as :func:`~collision_sensor.traversal.trees_collide`.
    """
    n_old = front_state[p, 0] if track and status[p] == 0 else 0
    capacity = start = done = 0
    if track:
        capacity = front.shape[0] // (front_state.shape[0] + 1)
        start = p * capacity
        done = (counters[COUNT_BOX_TESTS] + counters[COUNT_SPHERE_SKIPS]
                + counters[COUNT_TRIANGLE_TESTS])
    new = front_state.shape[0] * capacity  # the work rows (none needed by a full check)
    front_new = front[new:]
    front_new_until = front_until[new:]
    if n_old > 0:
        n_seeds, n_front, gap = front_scan(
            front[start:start + n_old], front_until[start:start + n_old], n_old, pose, boxes,
            travel, margin, stack, front_new, front_new_until, counters)
    else:
        n_seeds = 0
        for ea in range(first_a, end_a):
            for eb in range(first_b, end_b):
                stack[n_seeds, 0], stack[n_seeds, 1], stack[n_seeds, 2] = roots[ea], roots[eb], 0
                n_seeds += 1
        n_front = 0 if track else -1
        gap = np.inf
    hit, ia, ib, tree_gap, n_front = trees_collide(
        n_seeds, pose, boxes, nodes, volume, gain, tris, box_method, expansion, stack, work,
        tri_work, counters, track, wa, wb, front_new, front_new_until, n_front, travel - margin)
    if hit:
        return hit, ia, ib, 0.0
    gap = min(gap, tree_gap)
    if n_front < 0 or gap > FRONT_GAP_REL * scale:
        # A full check, a front too large to keep, or a pair with a clearance that can skip
        # whole steps: a front's many finer node pairs would only make it smaller.
        if track:
            front_state[p, 0] = 0
        return False, -1, -1, gap
    done = (counters[COUNT_BOX_TESTS] + counters[COUNT_SPHERE_SKIPS]
            + counters[COUNT_TRIANGLE_TESTS] - done)
    if n_old == 0:
        front_state[p, 1] = done
    if done <= front_state[p, 1]:
        for e in range(n_front):
            for c in range(3):
                front[start + e, c] = front_new[e, c]
            front_until[start + e] = front_new_until[e]
        front_state[p, 0] = n_front
    else:
        front_state[p, 0] = 0
    return False, -1, -1, gap


@numba.njit(cache=True, _nrt=False)
def recheck_pairs(n, full, todo, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                  multiplier, offset, T_world_body, n_links, is_scene, body_elem_start,
                  body_elem_end, body_boxes, roots, boxes, nodes, volume, gain, tris,
                  pair_a, pair_b, status, witness, clearance, q_eval, travel, box_method,
                  expansion, stale, chain, scene_culled, subtree_boxes, pose, stack, work,
                  tri_work, counters, front, front_until, front_state, front_travel, reach,
                  reach_ext, extension):
    """Re-check pairs ``todo[:n]`` (all pairs if ``full``); return (re-checked, any changed).

    A full check first rebuilds the volumes spanning several links and culls scene pairs
    with them; it uses nothing carried over and records no clearance. An incremental call
    brings the two bodies' poses up to date (only those) and tests first the pair's witness,
    the triangle pair that met when the pair last collided: under small motion a colliding
    pair usually still collides there, which then costs one triangle test instead of a
    descent (the answer is the same either way; a witness that no longer meets only costs
    that test). It skips the culling: a pair it re-checks is one whose own clearance ran
    out, and its own boxes give the next clearance, where a culling volume would only give
    a looser one. Then the two bodies' boxes, then each sub-group tree against each
    (sec. 4.1, :func:`trees_collide`), or, incrementally, the pair's front
    (:func:`_trees_of_pair`); an incremental call records the clearance of each pair found
    apart (see :func:`plan_update`), and adds the pair's travel since its last incremental
    re-check to ``front_travel``.

    Bodies are the robot's links (FK order, world == root link frame) followed by the scene
    objects, whose poses never change. Parameters are those of :func:`plan_update` and the
    :class:`~collision_sensor.kinematics.KinematicTree` arrays, plus:

    :param T_world_body: (B, 4, 4) body poses, links first, then scene objects (fixed).
    :param is_scene: (B,) int64, 1 for scene objects.
    :param body_elem_start, body_elem_end: (B,) int64, each body's trees are
        ``roots[start:end]``.
    :param body_boxes: (B, BOX_WIDTH) each body's box over all its trees (body frame), see
        :func:`~collision_sensor.obb_tree.box_table`.
    :param boxes, nodes, volume, gain, tris: the forest's tables (see
        :mod:`collision_sensor.traversal`).
    :param pair_a, pair_b: (P,) int64 bodies of each checked pair; a scene body is always b.
    :param status: (P,) int64, 1 if the pair collides (updated in place).
    :param witness: (P, 2) int64, rows of ``tris`` that last met for each pair, or -1.
    :param scene_culled: (S, L) int64, 1 where scene object s is outside the volume of link
        k's subtree or of one of its ancestors' (row 0: the robot's root volume).
    :param subtree_boxes: (L, BOX_WIDTH), each link's subtree volume (kept between calls).
    :param pose: (POSE_WIDTH,) float64 work: the pair's relative pose.
    :param stack, work, tri_work, counters: see :func:`trees_collide`.
    :param front, front_until, front_state: each pair's front, see :func:`_trees_of_pair`.
    :param front_travel: (P,) float64, each pair's travel: the sum, over its incremental
        re-checks, of its travel bound (:func:`plan_update`) from the previous one.
    :param reach, reach_ext, extension: see :func:`plan_update`.
    """
    track = not full
    if full:  # a full check uses nothing carried over; fronts are recorded afresh after it
        for p in range(front_state.shape[0]):
            front_state[p, 0] = 0
    if full and scene_culled.shape[0] > 0:
        _refresh_culling(T_world_body, parent, n_links, body_elem_start, body_elem_end,
                         body_boxes, subtree_boxes, scene_culled, box_method, work)
    changed = False
    for t in range(n):
        p = t if full else todo[t]
        a = pair_a[p]
        b = pair_b[p]
        if track:
            _refresh_pose(a, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                          multiplier, offset, T_world_body, stale, chain)
            _refresh_pose(b, q_ref, parent, joint_type, T_parent_joint, axis, q_index,
                          multiplier, offset, T_world_body, stale, chain)
            # The pair's travel since its last incremental re-check joins its running sum.
            _resync_travel(p, q_ref, q_eval, reach, reach_ext, travel)
            front_travel[p] += travel[p, 0] + extension * travel[p, 1]
            for j in range(q_ref.shape[0]):
                q_eval[p, j] = q_ref[j]
        hit = False
        gap = 0.0
        if track or not (is_scene[b] and scene_culled[b - n_links, a]):
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
                    margin = _clearance_margin(body_boxes, a, b, pose) if track else 0.0
                    hit, ia, ib, gap = _trees_of_pair(
                        p, track, status, body_boxes[a, BOX_RADIUS] + body_boxes[b, BOX_RADIUS],
                        front_travel[p], margin,
                        body_elem_start[a], body_elem_end[a], body_elem_start[b],
                        body_elem_end[b], roots, pose, boxes, nodes, volume, gain, tris,
                        box_method, expansion, stack, work, tri_work, counters, wa, wb, front,
                        front_until, front_state)
                    if hit:
                        witness[p, 0] = ia
                        witness[p, 1] = ib
                elif track:
                    gap = _bodies_gap(body_boxes, a, b, pose)
                if track and not hit:
                    gap -= _clearance_margin(body_boxes, a, b, pose)
        if not hit:
            witness[p, 0] = -1
        clearance[p] = gap if track and not hit and gap > 0.0 else 0.0
        if clearance[p] > 0.0:
            travel[p, 0] = 0.0
            travel[p, 1] = 0.0
        changed |= status[p] != hit
        status[p] = 1 if hit else 0
    return n, changed


# Slots of the packed buffers (see collision_sensor.array_pack); CollisionChecker adds the
# arrays in exactly this order. The first int slot, ``header``, holds the scalars and both
# layout tables, so that a call passes three arrays and a flag (numba types every argument
# on every call); the first float slot holds the float scalars.
FLOAT_SLOTS = ('scalars', 'q_last', 'q_ref', 'T_parent_joint', 'axis', 'multiplier', 'offset',
               'T_world_body', 'body_boxes', 'boxes', 'volume', 'gain', 'tris', 'subtree_boxes',
               'pose', 'work', 'tri_work', 'clearance', 'q_eval', 'reach', 'reach_ext',
               'travel', 'front_until', 'front_travel')
INT_SLOTS = ('header', 'parent', 'joint_type', 'q_index', 'is_scene', 'body_elem_start',
             'body_elem_end', 'roots', 'nodes', 'pair_a', 'pair_b', 'joint_pairs_start',
             'joint_pairs', 'joint_links_start', 'joint_links', 'joint_prismatic', 'status',
             'witness', 'moved', 'stale', 'chain', 'pending', 'todo', 'scene_culled', 'stack',
             'counters', 'front', 'front_state')
(F_SCALARS, F_Q_LAST, F_Q_REF, F_T_PARENT_JOINT, F_AXIS, F_MULTIPLIER, F_OFFSET,
 F_T_WORLD_BODY, F_BODY_BOXES, F_BOXES, F_VOLUME, F_GAIN, F_TRIS, F_SUBTREE_BOXES, F_POSE, F_WORK,
 F_TRI_WORK, F_CLEARANCE, F_Q_EVAL, F_REACH, F_REACH_EXT, F_TRAVEL, F_FRONT_UNTIL,
 F_FRONT_TRAVEL) = range(len(FLOAT_SLOTS))
(I_HEADER, I_PARENT, I_JOINT_TYPE, I_Q_INDEX, I_IS_SCENE, I_BODY_ELEM_START, I_BODY_ELEM_END,
 I_ROOTS, I_NODES, I_PAIR_A, I_PAIR_B, I_JOINT_PAIRS_START, I_JOINT_PAIRS, I_JOINT_LINKS_START,
 I_JOINT_LINKS, I_JOINT_PRISMATIC, I_STATUS, I_WITNESS, I_MOVED, I_STALE, I_CHAIN, I_PENDING,
 I_TODO, I_SCENE_CULLED, I_STACK, I_COUNTERS, I_FRONT, I_FRONT_STATE) = range(len(INT_SLOTS))
# scalars[S_*] (float slot 0, at offset 0 of the float buffer).
S_TOLERANCE, S_EXTENSION = range(2)
N_SCALARS = 2
# header[H_*] (int slot 0, at offset 0 of the int buffer), then the float buffer's layout
# (len(FLOAT_SLOTS), LAYOUT_WIDTH), then the int buffer's.
H_N_LINKS, H_BOX_METHOD, H_EXPANSION, H_CHECKED_ONCE, H_RESYNC_COUNTDOWN = range(5)
H_LAYOUTS = 5
H_I_LAYOUT = H_LAYOUTS + len(FLOAT_SLOTS) * LAYOUT_WIDTH
HEADER_SIZE = H_I_LAYOUT + len(INT_SLOTS) * LAYOUT_WIDTH


def write_header(I, F_layout, I_layout, n_links, box_method, expansion):
    """Fill the int buffer's header (``I[:HEADER_SIZE]``) once, after packing."""
    I[H_N_LINKS], I[H_BOX_METHOD], I[H_EXPANSION], I[H_CHECKED_ONCE] = (
        n_links, box_method, expansion, 0)
    I[H_RESYNC_COUNTDOWN] = TRAVEL_RESYNC_CALLS
    I[H_LAYOUTS:H_I_LAYOUT] = F_layout.ravel()
    I[H_I_LAYOUT:HEADER_SIZE] = I_layout.ravel()


@numba.njit(cache=True, _nrt=False)
def packed_query(q, full, F, I):
    """Validate ``q``, copy it to the ``q_last`` slot, bring the statuses up to date with it.

    A full check runs :func:`plan_full` then :func:`recheck_pairs` on every pair; an
    incremental one runs :func:`plan_update` and stops there when it lists no pair, having
    cut only the views that needs. The caller passes its own array (no copy): it is only
    read, before anything changes. The first call always checks in full
    (``header[H_CHECKED_ONCE]`` is 0 until then).

    :return: ``2 * rechecked + changed`` (pairs re-checked, any status changed), or
        ``-1 - j`` when ``q[j]`` is not finite; nothing changed then.
    """
    for j in range(q.shape[0]):
        if not np.isfinite(q[j]):
            return -1 - j
    F_layout = view_at2(I, H_LAYOUTS, (len(FLOAT_SLOTS), LAYOUT_WIDTH))
    I_layout = view_at2(I, H_I_LAYOUT, (len(INT_SLOTS), LAYOUT_WIDTH))
    q_last = view1(F, F_layout, F_Q_LAST)
    q_ref = view1(F, F_layout, F_Q_REF)
    full = full or I[H_CHECKED_ONCE] == 0
    any_moved = full
    for j in range(q.shape[0]):
        q_last[j] = q[j]
        if abs(q[j] - q_ref[j]) > F[S_TOLERANCE]:
            any_moved = True
    if not any_moved:
        return 0
    I[H_CHECKED_ONCE] = 1
    n_links = I[H_N_LINKS]
    parent, joint_type = view1(I, I_layout, I_PARENT), view1(I, I_layout, I_JOINT_TYPE)
    q_index, multiplier = view1(I, I_layout, I_Q_INDEX), view1(F, F_layout, F_MULTIPLIER)
    offset, stale = view1(F, F_layout, F_OFFSET), view1(I, I_layout, I_STALE)
    T_parent_joint, axis = view3(F, F_layout, F_T_PARENT_JOINT), view2(F, F_layout, F_AXIS)
    T_world_body = view3(F, F_layout, F_T_WORLD_BODY)
    status, clearance = view1(I, I_layout, I_STATUS), view1(F, F_layout, F_CLEARANCE)
    q_eval, travel = view2(F, F_layout, F_Q_EVAL), view2(F, F_layout, F_TRAVEL)
    todo = view1(I, I_layout, I_TODO)
    if full:
        plan_full(q_last, q_ref, n_links, parent, joint_type, T_parent_joint, axis, q_index,
                  multiplier, offset, T_world_body, stale, F)
        n = status.shape[0]
    else:
        n = plan_update(
            q_last, q_ref, F[S_TOLERANCE], view1(I, I_layout, I_MOVED), n_links, joint_type,
            q_index, multiplier, offset, view1(I, I_layout, I_JOINT_LINKS_START),
            view1(I, I_layout, I_JOINT_LINKS), view1(I, I_layout, I_JOINT_PRISMATIC), stale,
            view1(I, I_layout, I_JOINT_PAIRS_START), view1(I, I_layout, I_JOINT_PAIRS), status,
            clearance, q_eval, view2(F, F_layout, F_REACH), view2(F, F_layout, F_REACH_EXT),
            travel, view1(I, I_layout, I_PENDING), todo, F, I)
        if n == 0:
            return 0
    rechecked, changed = recheck_pairs(
        n, full, todo, q_ref, parent, joint_type, T_parent_joint, axis, q_index, multiplier,
        offset, T_world_body, n_links, view1(I, I_layout, I_IS_SCENE),
        view1(I, I_layout, I_BODY_ELEM_START), view1(I, I_layout, I_BODY_ELEM_END),
        view2(F, F_layout, F_BODY_BOXES), view1(I, I_layout, I_ROOTS),
        view2(F, F_layout, F_BOXES), view2(I, I_layout, I_NODES), view1(F, F_layout, F_VOLUME),
        view1(F, F_layout, F_GAIN), view3(F, F_layout, F_TRIS), view1(I, I_layout, I_PAIR_A),
        view1(I, I_layout, I_PAIR_B), status, view2(I, I_layout, I_WITNESS), clearance, q_eval,
        travel, I[H_BOX_METHOD], I[H_EXPANSION], stale, view1(I, I_layout, I_CHAIN),
        view2(I, I_layout, I_SCENE_CULLED), view2(F, F_layout, F_SUBTREE_BOXES),
        view1(F, F_layout, F_POSE), view2(I, I_layout, I_STACK), view1(F, F_layout, F_WORK),
        view3(F, F_layout, F_TRI_WORK), view1(I, I_layout, I_COUNTERS),
        view2(I, I_layout, I_FRONT), view1(F, F_layout, F_FRONT_UNTIL),
        view2(I, I_layout, I_FRONT_STATE), view1(F, F_layout, F_FRONT_TRAVEL),
        view2(F, F_layout, F_REACH), view2(F, F_layout, F_REACH_EXT), F[S_EXTENSION])
    return 2 * rechecked + (1 if changed else 0)


@numba.njit(cache=True, _nrt=False)
def packed_batch(Q, full, F, I, statuses, codes):
    """Run :func:`packed_query` on each row of ``Q`` in turn, in one call from Python.

    :param statuses, codes: (n, P) uint8 and (n,) int64 out: the pair statuses after each
        row, and :func:`packed_query`'s answer for it.
    :return: the number of rows done: ``n``, or the first row with a value that is not
        finite (that row changed nothing).
    """
    I_layout = view_at2(I, H_I_LAYOUT, (len(INT_SLOTS), LAYOUT_WIDTH))
    status = view1(I, I_layout, I_STATUS)
    for i in range(Q.shape[0]):
        codes[i] = packed_query(Q[i], full, F, I)
        if codes[i] < 0:
            return i
        for p in range(status.shape[0]):
            statuses[i, p] = status[p]
    return Q.shape[0]


@numba.njit(cache=True, _nrt=False)
def packed_poses(F, I):
    """Bring every link pose up to date (incremental calls compute them only on demand)."""
    F_layout = view_at2(I, H_LAYOUTS, (len(FLOAT_SLOTS), LAYOUT_WIDTH))
    I_layout = view_at2(I, H_I_LAYOUT, (len(INT_SLOTS), LAYOUT_WIDTH))
    _refresh_all_poses(I[H_N_LINKS], view1(F, F_layout, F_Q_REF), view1(I, I_layout, I_PARENT),
                       view1(I, I_layout, I_JOINT_TYPE), view3(F, F_layout, F_T_PARENT_JOINT),
                       view2(F, F_layout, F_AXIS), view1(I, I_layout, I_Q_INDEX),
                       view1(F, F_layout, F_MULTIPLIER), view1(F, F_layout, F_OFFSET),
                       view3(F, F_layout, F_T_WORLD_BODY), view1(I, I_layout, I_STALE))


bind_to_kernel_sources(globals())
