"""Oriented-box / oriented-box overlap: the paper's three-type test (sec. 5) and the 15-axis SAT.

Arguments shared by every test here (coal's convention: ``[R, T] = [R1'R2, R1'(T2 - T1)]``)::

    ha, hb  : (3,) float64     half extents of box A and box B, >= 0; 0 is allowed
                               (a flat box, a segment, a point).
    R       : (3, 3) float64   proper rotation (det = +1) from F_B to F_A: column j is B's
                               j-th axis in F_A, so R = R_A^T R_B with R_A, R_B box-to-world.
    t       : (3,) float64     B's centre in F_A: t = R_A^T (c_B - c_A).

Box A is centred at the origin of F_A and axis-aligned there. Each test returns True iff a
separating plane exists with a clear gap, False when the closed boxes meet (touching counts as
overlap). The tests are C++ (``cpp/box_test.hpp``); the functions here call them for one pair
or many.

Tolerance rule (``tolerances.BOX_EPS_REL``, ``BOX_EPS_PARALLEL``), the same in both tests: with
``s = ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]`` and ``tol = BOX_EPS_REL * s``, the boxes
are separated along a candidate axis L (unnormalised: a face normal has ``|L| = 1``, an
edge-edge axis ``a_i x b_j`` has ``|L| = sin`` of the angle between the edges) iff::

    |t . L| - r_A(L) - r_B(L)  >  tol * (|L| + BOX_EPS_PARALLEL)

i.e. the gap along the unit axis exceeds ``tol * (1 + BOX_EPS_PARALLEL / |L|)``. The floor
``tol * BOX_EPS_PARALLEL`` is what coal's ``|R| + eps`` does: an axis built from two nearly
parallel edges, whose direction is rounding noise, cannot separate. Both tests consider the same
axes: A's and B's face normals, and ``a_i x b_j`` for every i with ``ha[i] > 0`` (a box with no
extent along ``a_i`` has no edges along it, so the paper's hexagon has no such edge and the
axis is not needed: the test stays exact). With that, the paper's type 1 and type 2 checks are
evaluated in the very same floating-point operations as the SAT's six face axes (bit-identical
decisions); the type 3 and the edge-edge checks compute the same quantity in different ways,
so they can disagree only on an input whose edge-edge gap lies within rounding (~1e-15 s) of
the threshold. Input with a NaN or an infinity anywhere is never separated (both tests answer
False: err toward overlap).
"""
import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.engine.tolerances import BOX_EPS_REL

BOX_TEST_PAPER, BOX_TEST_SAT = engine.BOX_TEST_PAPER, engine.BOX_TEST_SAT

# Paper Table 1 (sec. 5.1.3), restated in NOTES.md, as the engine holds it (cpp/box_test.hpp): row
# i is the silhouette hexagon of a box seen along a direction in which vertex i has the smallest
# coordinate; vertices i and 7 - i are hidden. Vertex numbering: bit k of the index selects min (0)
# or max (1) along box axis k, so i and 7 - i are opposite. Consecutive entries differ in exactly
# one bit (they are box edges), and every row runs counter-clockwise seen from the tip of the view
# direction when A's frame is right-handed (test_box_test.py checks both on random rotations).
# Hence, in the view plane coordinates (u, v) with u x v = view axis, the inside of the hexagon is
# on the left of each edge, and the division-free edge function f = alpha * u + beta * v + gamma,
# with alpha = v1 - v0, beta = u0 - u1, gamma = -(alpha * u0 + beta * v0), is > 0 exactly outside.
# The sign is known in advance, so no orientation is computed and a degenerate (zero-area) hexagon
# cannot flip it.
HEXAGON = np.array(engine.HEXAGON, dtype=np.int64)


def box_tolerance(ha, hb) -> float:
    """Return ``BOX_EPS_REL * (sum of the six half extents)``, the box tests' gap tolerance."""
    return BOX_EPS_REL * (float(np.sum(ha)) + float(np.sum(hb)))


def _pairs(ha, hb, R, t):
    """The box pairs as (n, 3), (n, 3), (n, 3, 3), (n, 3) float64 arrays (one pair: n = 1)."""
    ha = np.ascontiguousarray(ha, dtype=np.float64)
    single = ha.ndim == 1
    shape = (1,) if single else ha.shape[:1]
    return single, (ha.reshape(shape + (3,)),
                    np.ascontiguousarray(hb, dtype=np.float64).reshape(shape + (3,)),
                    np.ascontiguousarray(R, dtype=np.float64).reshape(shape + (3, 3)),
                    np.ascontiguousarray(t, dtype=np.float64).reshape(shape + (3,)))


def boxes_disjoint(method: int, ha, hb, R, t):
    """Return True iff boxes A and B are separated, by ``method`` (BOX_TEST_PAPER or _SAT).

    :param ha, hb: (3,) half extents, or (n, 3) for n pairs at once.
    :param R: (3, 3) rotation, column j = B's axis j in F_A (or (n, 3, 3)).
    :param t: (3,) B's centre in F_A (or (n, 3)).
    :return: a bool, or (n,) bool for n pairs.
    """
    single, pairs = _pairs(ha, hb, R, t)
    method = BOX_TEST_PAPER if method == BOX_TEST_PAPER else BOX_TEST_SAT
    answers = engine.boxes_disjoint(method, *pairs)
    return bool(answers[0]) if single else answers


def boxes_disjoint_paper(ha, hb, R, t):
    """Return True iff boxes A and B are separated: the paper's sec. 5 test.

    Type 1: B's 8 vertices in F_A all beyond one of A's six face planes. Type 2: the same with
    A's vertices in F_B. Type 3: with A's vertices in F_B, in the views along B's three axes,
    all 4 corners of B's rectangle strictly outside one edge line of A's silhouette hexagon
    (Table 1). Arguments as :func:`boxes_disjoint`.
    """
    return boxes_disjoint(BOX_TEST_PAPER, ha, hb, R, t)


def boxes_disjoint_sat(ha, hb, R, t):
    """Return True iff boxes A and B are separated: the classical 15-axis separating-axis
    test (axes as the module docstring says). Arguments as :func:`boxes_disjoint`."""
    return boxes_disjoint(BOX_TEST_SAT, ha, hb, R, t)


def separating_axes(ha, hb, R, t) -> np.ndarray:
    """Return, for each of n box pairs, the first axis of the 15-axis test that separates it,
    or -1: 0-2 A's face normals e_k, 3-5 B's face normals b_j, ``6 + 3 i + j`` the edge-edge
    axis e_i x b_j (the order they are tried in)."""
    return engine.separating_axis(*_pairs(ha, hb, R, t)[1])


def separating_axis(ha, hb, R, t) -> int:
    """Return the first axis of the 15-axis test that separates one box pair (ha, hb (3,), R
    (3, 3), t (3,)), or -1 (see :func:`separating_axes`)."""
    return int(separating_axes(ha, hb, R, t)[0])
