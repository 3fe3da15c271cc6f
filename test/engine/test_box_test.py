"""Box tests: Table 1, paper test == SAT on 10^7 seeded pairs, both == an LP oracle, by hand."""
import math

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from collision_sensor.engine.box_test import (
    BOX_TEST_PAPER, BOX_TEST_SAT, HEXAGON, box_tolerance, boxes_disjoint, boxes_disjoint_paper,
    boxes_disjoint_sat, separating_axis, separating_axes)
from collision_sensor.engine.obb_tree import BOX_AXES, BOX_CENTER, BOX_HALF, BOX_RADIUS, BOX_WIDTH
from collision_sensor.engine.traversal import axis_gap
from benchmarks.box_tests import (
    CAT_NEAR, CAT_RANDOM, CAT_TOUCHING, contact_distance, mixed_pairs)


def box_vertices(h):
    """Return (8, 3) vertices of a box centred at 0; bit k of the index selects +h_k."""
    return np.array([[h[k] if (i >> k) & 1 else -h[k] for k in range(3)] for i in range(8)])


def both(ha, hb, R, t):
    ha, hb, R, t = (np.asarray(x, dtype=np.float64) for x in (ha, hb, R, t))
    return (boxes_disjoint_paper(ha, hb, R, t),
            boxes_disjoint_sat(ha, hb, R, t))


def literal(ha, hb, R, t):
    """Return the pair as Python literals that can be pasted into a regression test."""
    return (f'ha={np.asarray(ha).tolist()!r}, hb={np.asarray(hb).tolist()!r}, '
            f'R={np.asarray(R).tolist()!r}, t={np.asarray(t).tolist()!r}')


def rot(axis, angle):
    """Return the rotation by ``angle`` about ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# --- Table 1 ------------------------------------------------------------------------------

def test_table1_rows_are_box_edges_and_complementary_rows_reverse():
    for i in range(8):
        row = list(HEXAGON[i])
        assert sorted(row + [i, 7 - i]) == list(range(8))
        for m in range(6):
            diff = row[m] ^ row[(m + 1) % 6]
            assert diff in (1, 2, 4), (i, row)
        rev = list(HEXAGON[7 - i])[::-1]
        k = rev.index(row[0])
        assert rev[k:] + rev[:k] == row


def test_table1_is_the_ccw_silhouette_for_random_rotations():
    # For a right-handed box frame W seen along +z, the vertex with minimal z selects the row;
    # the six listed vertices must be the convex hull of the 8 projections, counter-clockwise
    # in (x, y) (so f = alpha u + beta v + gamma > 0 is outside), and the hidden two inside.
    rng = np.random.default_rng(1)
    for trial in range(2000):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        w, x, y, z = q
        W = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        h = rng.uniform(0.1, 2.0, size=3)
        P = box_vertices(h) @ W.T
        i = int(np.argmin(P[:, 2]))
        row = list(HEXAGON[i])
        uv = P[:, :2]
        hull = ConvexHull(uv)
        cyc = list(hull.vertices)          # scipy: counter-clockwise for 2-D hulls
        k = cyc.index(row[0])
        assert cyc[k:] + cyc[:k] == row, (trial, row, cyc)
        for hidden in (i, 7 - i):
            assert hidden not in hull.vertices
        # and the signed edge functions: negative at the hidden vertices (inside)
        for m in range(6):
            (u0, v0), (u1, v1) = uv[row[m]], uv[row[(m + 1) % 6]]
            alpha, beta = v1 - v0, u0 - u1
            gamma = -(alpha * u0 + beta * v0)
            for hidden in (i, 7 - i):
                assert alpha * uv[hidden, 0] + beta * uv[hidden, 1] + gamma < 0


# --- paper test == SAT on 10^7 seeded pairs -----------------------------------------------

def _count_disagreements(n, seed, n_cases=20, chunk=1_000_000):
    """Test n mixed pairs (:func:`mixed_pairs`, generated ``chunk`` at a time) with both tests.

    Return (stats, cases): stats[0] = disagreements, stats[1] = separated (paper),
    stats[2 + c] = pairs of category c, stats[5] = touching pairs reported separated by either
    test; cases the first ``n_cases`` disagreeing pairs as (ha, hb, R, t).
    """
    rng = np.random.default_rng(seed)
    stats = np.zeros(6, dtype=np.int64)
    cases = []
    for start in range(0, n, chunk):
        ha, hb, R, t, category = mixed_pairs(min(chunk, n - start), rng)
        a = boxes_disjoint(BOX_TEST_PAPER, ha, hb, R, t)
        b = boxes_disjoint(BOX_TEST_SAT, ha, hb, R, t)
        differ = np.flatnonzero(a != b)
        stats[0] += differ.size
        stats[1] += np.count_nonzero(a)
        stats[2:5] += np.bincount(category, minlength=3)[:3]
        stats[5] += np.count_nonzero((category == CAT_TOUCHING) & (a | b))
        cases += [(ha[p], hb[p], R[p], t[p]) for p in differ[:n_cases - len(cases)]]
    return stats, cases


@pytest.mark.slow
def test_paper_test_agrees_with_sat_on_ten_million_seeded_pairs():
    n = 10_000_000
    stats, cases = _count_disagreements(n, 20240601)
    bad = [literal(*case) for case in cases]
    assert stats[0] == 0, f'{stats[0]} disagreements; first ones:\n' + '\n'.join(bad)
    # The mix is meaningful: plenty of both answers, and every touching pair overlaps.
    assert 0.2 * n < stats[1] < 0.6 * n
    assert (stats[2 + CAT_RANDOM] > 0.15 * n and stats[2 + CAT_TOUCHING] > 0.35 * n
            and stats[2 + CAT_NEAR] > 0.35 * n)
    assert stats[5] == 0


# --- both against an LP oracle -------------------------------------------------------------

def lp_inflation(ha, hb, R, t):
    """Return sigma*: the least growth of every half extent of both boxes that makes them meet.

    LP over (x, sigma): minimise sigma s.t. |x_k| <= ha_k + sigma, |b_j . (x - t)| <= hb_j +
    sigma. sigma* > 0 iff the boxes are disjoint; it is a gap measure independent of both tests.
    """
    A, b = [], []
    for k in range(3):
        for sgn in (1.0, -1.0):
            row = np.zeros(4)
            row[k], row[3] = sgn, -1.0
            A.append(row)
            b.append(ha[k])
    for j in range(3):
        for sgn in (1.0, -1.0):
            row = np.zeros(4)
            row[:3], row[3] = sgn * R[:, j], -1.0
            A.append(row)
            b.append(hb[j] + sgn * R[:, j] @ t)
    res = linprog(np.array([0, 0, 0, 1.0]), A_ub=np.array(A), b_ub=np.array(b),
                  bounds=[(None, None)] * 4, method='highs')
    assert res.status == 0, res.message
    return res.fun


def _lp_pairs(n, seed):
    """Return n mixed pairs as H (n, 2, 3) (ha, hb), RR (n, 3, 3), TT (n, 3)."""
    ha, hb, RR, TT, _ = mixed_pairs(n, np.random.default_rng(seed))
    return np.stack([ha, hb], axis=1), RR, TT


@pytest.mark.slow
def test_both_tests_agree_with_lp_oracle_when_the_gap_is_clear():
    n = 4000
    H, RR, TT = _lp_pairs(n, 7)
    checked = {True: 0, False: 0}
    bad = []
    for p in range(n):
        ha, hb, R, t = H[p, 0], H[p, 1], RR[p], TT[p]
        s = ha.sum() + hb.sum()
        if s == 0.0:
            continue
        sigma = lp_inflation(ha / s, hb / s, R, t / s)     # scale-free: HiGHS tolerances
        if abs(sigma) <= 1e-7:
            continue
        expected = sigma > 0.0
        got = both(ha, hb, R, t)
        checked[expected] += 1
        if got != (expected, expected):
            bad.append(f'sigma={sigma!r}: {literal(ha, hb, R, t)} -> {got}')
    assert not bad, '\n'.join(bad[:10])
    assert checked[True] > 800 and checked[False] > 600, checked


# --- hand-built cases ----------------------------------------------------------------------

I3 = np.eye(3)
RZ45 = rot([0, 0, 1], math.pi / 4)
RZ90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
RX90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
PERM = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])   # det +1
ONE = [1.0, 1.0, 1.0]
R2 = math.sqrt(2.0)

HAND_BUILT = [
    # name, ha, hb, R, t, separated
    ('identical boxes', [1, 2, 3], [1, 2, 3], I3, [0, 0, 0], False),
    ('identical axes, inside', [2, 2, 2], [1, 0.5, 0.25], I3, [0.3, -0.2, 0.1], False),
    ('faces touching', ONE, ONE, I3, [2, 0, 0], False),
    ('faces 1e-6 apart', ONE, ONE, I3, [2 + 1e-6, 0, 0], True),
    ('faces 1e-6 deep', ONE, ONE, I3, [2 - 1e-6, 0, 0], False),
    ('edges touching', ONE, ONE, I3, [2, 2, 0.5], False),
    ('edges 1e-6 apart', ONE, ONE, I3, [2, 2 + 1e-6, 0.5], True),
    ('vertices touching', ONE, ONE, I3, [2, 2, 2], False),
    ('vertices 1e-6 apart', ONE, ONE, I3, [2, 2, 2 + 1e-6], True),
    # PERM: b_0 = -y, b_1 = +z, b_2 = -x, so B reaches 2 along z.
    ('permuted axes, faces touching', [1, 2, 3], [1, 2, 3], PERM, [0, 0, 3 + 2], False),
    ('permuted axes, 1e-6 apart', [1, 2, 3], [1, 2, 3], PERM, [0, 0, 5 + 1e-6], True),
    ('permuted axes, crossing', [3, 0.1, 0.1], [3, 0.1, 0.1], PERM, [0, 0, 0], False),
    ('B edge on A face (45 deg)', ONE, ONE, RZ45, [1 + R2, 0, 0], False),
    ('B edge 1e-6 off A face', ONE, ONE, RZ45, [1 + R2 + 1e-6, 0, 0], True),
    ('flat squares coplanar, overlapping', [1, 1, 0], [1, 1, 0], I3, [1.5, 0, 0], False),
    ('flat squares coplanar, edges touching', [1, 1, 0], [1, 1, 0], I3, [2, 0, 0], False),
    ('flat squares coplanar, 1e-6 apart', [1, 1, 0], [1, 1, 0], I3, [2 + 1e-6, 0, 0], True),
    ('flat squares in parallel planes', [1, 1, 0], [1, 1, 0], I3, [0, 0, 1e-6], True),
    ('flat squares crossing at right angles', [1, 1, 0], [1, 1, 0], RX90, [0, 0, 0], False),
    ('flat square and segment through it', [1, 1, 0], [0, 0, 1], I3, [0.5, 0.5, 0], False),
    ('flat square and segment beside it', [1, 1, 0], [0, 0, 1], I3, [1 + 1e-6, 0.5, 0], True),
    ('segments crossing', [1, 0, 0], [1, 0, 0], RZ90, [0, 0, 0], False),
    ('segments crossing at ends', [1, 0, 0], [1, 0, 0], RZ90, [1, 1, 0], False),
    ('skew segments 1e-6 apart (edge-edge axis only)', [1, 0, 0], [1, 0, 0],
     rot([1, 0, 0], math.pi / 4) @ RZ90, [0, -1e-6 / R2, 1e-6 / R2], True),
    ('skew segments touching', [1, 0, 0], [1, 0, 0], rot([1, 0, 0], math.pi / 4) @ RZ90,
     [0, 0, 0], False),
    ('point at point', [0, 0, 0], [0, 0, 0], I3, [0, 0, 0], False),
    ('point off point', [0, 0, 0], [0, 0, 0], I3, [0, 1e-300, 0], True),
    ('point in box', [0, 0, 0], ONE, RZ45, [0.1, 0.2, 0.3], False),
    ('point on box face', [0, 0, 0], ONE, I3, [1, 0.2, 0.3], False),
    ('point off box face', [0, 0, 0], ONE, I3, [1 + 1e-6, 0.2, 0.3], True),
    ('huge and tiny, touching', [1e4] * 3, [1e-4] * 3, I3, [1e4 + 1e-4, 0, 0], False),
    ('huge and tiny, apart', [1e4] * 3, [1e-4] * 3, I3, [1e4 + 1e-3, 0, 0], True),
    ('tiny boxes, touching', [1e-6] * 3, [1e-6] * 3, RZ45, [1e-6 * (1 + R2), 0, 0], False),
    ('tiny boxes, 1e-12 apart', [1e-6] * 3, [1e-6] * 3, RZ45, [1e-6 * (1 + R2) + 1e-12, 0, 0],
     True),
]


@pytest.mark.parametrize('name, ha, hb, R, t, separated', HAND_BUILT,
                         ids=[c[0] for c in HAND_BUILT])
def test_hand_built_pair(name, ha, hb, R, t, separated):
    got = both(ha, hb, R, t)
    assert got == (separated, separated), f'{name}: {literal(ha, hb, R, t)} -> {got}'
    # And the same with A and B exchanged: R -> R^T, t -> -R^T t.
    R, t = np.asarray(R, dtype=float), np.asarray(t, dtype=float)
    got = both(hb, ha, R.T, -R.T @ t)
    assert got == (separated, separated), f'{name}, swapped -> {got}'


def test_edge_edge_contact_is_overlap_and_any_clear_gap_separates():
    # A rotation with nice numbers, approached along an edge-edge axis to exact contact.
    ha, hb = np.array([1.0, 0.5, 0.25]), np.array([0.75, 1.0, 0.5])
    R = rot([1, 2, 3], 0.7)
    w = np.cross([1.0, 0, 0], R[:, 1])
    w /= np.linalg.norm(w)
    lam = contact_distance(ha, hb, R, w)
    assert both(ha, hb, R, lam * w) == (False, False)
    s = ha.sum() + hb.sum()
    assert both(ha, hb, R, (lam + 1e-6 * s) * w) == (True, True)
    assert both(ha, hb, R, (lam - 1e-6 * s) * w) == (False, False)


def test_tolerance_is_relative_to_the_boxes():
    ha, hb = np.array([1.0, 2.0, 3.0]), np.array([0.5, 0.5, 0.5])
    tol = box_tolerance(ha, hb)
    assert tol == pytest.approx(1e-9 * 7.5)
    for scale in (1e-4, 1.0, 1e4):
        assert both(ha * scale, hb * scale, I3, [1.5 * scale + 0.5 * tol * scale, 0, 0]) == (
            False, False)
        assert both(ha * scale, hb * scale, I3, [1.5 * scale + 3.0 * tol * scale, 0, 0]) == (
            True, True)


def test_nan_input_counts_as_overlap():
    R = I3.copy()
    R[0, 0] = np.nan
    assert both(ONE, ONE, R, [5.0, 0, 0]) == (False, False)
    assert both(ONE, ONE, I3, [np.nan, 0, 0]) == (False, False)


def test_dispatcher_selects_the_method():
    args = (np.array(ONE), np.array(ONE), I3, np.array([3.0, 0, 0]))
    assert boxes_disjoint(BOX_TEST_PAPER, *args) and boxes_disjoint(BOX_TEST_SAT, *args)
    args = (np.array(ONE), np.array(ONE), I3, np.array([1.0, 0, 0]))
    assert not boxes_disjoint(BOX_TEST_PAPER, *args)
    assert not boxes_disjoint(BOX_TEST_SAT, *args)


# --- one axis alone (the incremental front re-check) ---------------------------------------

def _box_row(centre, axes, half):
    row = np.zeros(BOX_WIDTH)
    row[BOX_CENTER:BOX_CENTER + 3] = centre
    row[BOX_AXES:BOX_AXES + 9] = axes.ravel()
    row[BOX_HALF:BOX_HALF + 3] = half
    row[BOX_RADIUS] = np.linalg.norm(half)
    return tuple(row)


def _fcl_distance(ha, hb, R, t):
    import fcl
    a = fcl.CollisionObject(fcl.Box(*(2.0 * ha)), fcl.Transform())
    b = fcl.CollisionObject(fcl.Box(*(2.0 * hb)), fcl.Transform(R, t))
    return fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())


@pytest.mark.slow
def test_one_axis_alone_agrees_with_the_whole_test_and_its_gap_is_a_lower_bound():
    """axis_gap(k) is what a front re-check tries: the axis the 15-axis test found last
    time. For every axis it never separates boxes the whole test (and the LP oracle) calls
    overlapping; on the axis the whole test names, it separates too; and the gap it gives
    is at most the boxes' distance (python-fcl). The boxes sit in their own frames inside two
    bodies, so the entries of R and t it computes on its own are exercised."""
    n = 3000
    H, RR, TT = _lp_pairs(n, 11)
    first_axis = separating_axes(H[:, 0], H[:, 1], RR, TT)
    rng = np.random.default_rng(12)
    named = claimed = measured = 0
    for p in range(n):
        ha, hb, R, t = H[p, 0], H[p, 1], RR[p], TT[p]
        s = ha.sum() + hb.sum()
        if s == 0.0:
            continue
        # Box frames Ea, Eb in bodies a, b, and body b's pose such that Ea' R_ab Eb = R and
        # Ea' (R_ab cb + t_ab - ca) = t.
        Ea, Eb = rot(rng.normal(size=3), rng.uniform(0, 3)), rot(rng.normal(size=3), 1.0)
        ca, cb = rng.normal(size=3) * s, rng.normal(size=3) * s
        R_ab = Ea @ R @ Eb.T
        t_ab = Ea @ t + ca - R_ab @ cb
        A, B = _box_row(ca, Ea, ha), _box_row(cb, Eb, hb)
        P = tuple(R_ab.ravel()) + tuple(t_ab)
        k = int(first_axis[p])
        assert separating_axis(ha, hb, R, t) == k      # one pair == the batch
        if k >= 0:
            named += 1
            assert axis_gap(k, A, B, P)[0], (k, literal(ha, hb, R, t))
        distance = None
        for axis in range(15):
            separated, gap = axis_gap(axis, A, B, P)
            if not separated:
                continue
            claimed += 1
            assert k >= 0, (axis, literal(ha, hb, R, t))
            # HiGHS answers to ~1e-7 of the scale (see the LP test above).
            assert lp_inflation(ha / s, hb / s, R, t / s) > -1e-7, (axis, literal(ha, hb, R, t))
            if min(ha.min(), hb.min()) > 1e-3 * s:  # fcl's GJK on solid boxes
                if distance is None:
                    distance = _fcl_distance(ha, hb, R, t)
                measured += 1
                assert gap <= distance + 1e-6 * s, (axis, gap, distance, literal(ha, hb, R, t))
    assert named > 500 and claimed > 2000 and measured > 1000  # each part ran often
