"""Hierarchy-versus-hierarchy traversal of two OBB trees (paper sec. 4.1), compiled.

Two trees, each in its own body frame, are tested from their roots down. When two boxes
overlap, one of them is expanded (its two children are tested against the other box); when
both are leaves, their triangles are tested exactly. Which side is expanded is the paper's
"node expansion consideration"; five rules are offered:

* ``EXPAND_SAME``: always expand the first tree until it reaches a leaf, then the second;
* ``EXPAND_ALTERNATE``: alternate sides with the depth of the descent;
* ``EXPAND_LARGER``: expand the node with the larger box volume;
* ``EXPAND_PROMISING``: expand the node whose volume most exceeds the sum of its children's
  volumes (the paper's "most promising node");
* ``EXPAND_WIDER``: expand the node with the larger half diagonal ``|half|`` (the radius of its
  sphere): unlike the volume, it sees the size of a flat box, as FCL's rule does.

The answer never depends on the rule, only the work done; ``benchmarks`` measures
which rule is fastest on real robots and the checker's default follows that measurement.

Data, as the kernels take it (built by :func:`collision_sensor.engine.obb_tree.box_table` and
:func:`~collision_sensor.engine.obb_tree.node_table` from an
:class:`~collision_sensor.engine.obb_tree.ObbForest`)::

    boxes : (N, BOX_WIDTH) float64   one row per box: centre, axes (row-major, column k is
                                     axis k), half extents, sphere radius (obb_tree.BOX_*)
    nodes : (N, 4) int64             left child (-1 for a leaf), right child, first triangle,
                                     triangle count
    pose  : (POSE_WIDTH,) float64    body b in body a's frame: R_ab row-major, then t_ab

The traversal is C++ (``cpp/traversal.hpp``: ``collide_trees``, ``front_scan``), run inside
each query; this module names its settings and counters for the Python side (the numbers are
the extension's).
"""
import numpy as np

from collision_sensor.engine.compiled import engine

EXPAND_SAME, EXPAND_ALTERNATE, EXPAND_LARGER, EXPAND_PROMISING, EXPAND_WIDER = (
    engine.EXPAND_SAME, engine.EXPAND_ALTERNATE, engine.EXPAND_LARGER, engine.EXPAND_PROMISING,
    engine.EXPAND_WIDER)
EXPANSION_RULES = {
    'same': EXPAND_SAME, 'alternate': EXPAND_ALTERNATE, 'larger': EXPAND_LARGER,
    'promising': EXPAND_PROMISING, 'wider': EXPAND_WIDER,
}

# counters[COUNT_*] (CollisionChecker.counters): work done, for the benchmarks and tests: box
# tests, triangle tests, box pairs skipped by the sphere pre-test, pair re-checks that started
# from a front, front node pairs kept untested, pairs a motion check swept by ray casts
# instead of marching (docs/motion.md) and those casts' GJK iterations, and pairs
# update_motion measured at a step's end instead of marching.
(COUNT_BOX_TESTS, COUNT_TRIANGLE_TESTS, COUNT_SPHERE_SKIPS, COUNT_FRONT_STARTS,
 COUNT_FRONT_UNTESTED, COUNT_SWEEPS, COUNT_SWEEP_STEPS, COUNT_MEASURES) = (
    engine.COUNT_BOX_TESTS, engine.COUNT_TRIANGLE_TESTS, engine.COUNT_SPHERE_SKIPS,
    engine.COUNT_FRONT_STARTS, engine.COUNT_FRONT_UNTESTED, engine.COUNT_SWEEPS,
    engine.COUNT_SWEEP_STEPS, engine.COUNT_MEASURES)
N_COUNTERS = engine.N_COUNTERS

#: Length of a pose vector: R_ab (row-major), then t_ab.
POSE_WIDTH = engine.POSE_WIDTH


def axis_gap(k: int, A, B, P):
    """Return ``(separated, gap)`` along axis k of :func:`box_test.separating_axis` alone, for
    boxes A (a box table row, body a) and B (body b at pose P in body a: R_ab row-major, t_ab).

    ``separated`` is that test's decision for this axis (its arithmetic and tolerance rule, on
    only the entries the axis needs: a front re-check tries one axis per node pair); ``gap`` is
    then the boxes' gap along the unit axis, a lower bound of their distance.
    """
    separated, gap = engine.axis_gap(int(k), np.ascontiguousarray(A, dtype=np.float64),
                                     np.ascontiguousarray(B, dtype=np.float64),
                                     np.ascontiguousarray(P, dtype=np.float64))
    return bool(separated), float(gap)
