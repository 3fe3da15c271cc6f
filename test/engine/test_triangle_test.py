"""Triangle contact: an LP oracle on seeded random pairs, hand-built touching/degenerate cases."""
import itertools

import numpy as np
import pytest
from scipy.optimize import linprog

from collision_sensor.engine.tolerances import TRIANGLE_EPS_REL
from engine_kernels import triangles_intersect


def tri(*rows):
    return np.array(rows, dtype=np.float64)


def literal(P, Q):
    return f'P={np.asarray(P).tolist()!r}, Q={np.asarray(Q).tolist()!r}'


def lp_chebyshev_distance(P, Q):
    """Return min over x in P, y in Q of |x - y|_inf, by LP over barycentric coordinates.

    Variables (lambda_0..2, mu_0..2, tau): lambda, mu >= 0, each summing to 1, and
    -tau <= (P^T lambda - Q^T mu)_k <= tau. Independent of the code under test; the Euclidean
    distance lies between tau* and sqrt(3) tau*.
    """
    A_ub, b_ub = [], []
    for k in range(3):
        row = np.concatenate([P[:, k], -Q[:, k], [-1.0]])
        A_ub.append(row)
        b_ub.append(0.0)
        row = np.concatenate([-P[:, k], Q[:, k], [-1.0]])
        A_ub.append(row)
        b_ub.append(0.0)
    A_eq = [[1, 1, 1, 0, 0, 0, 0], [0, 0, 0, 1, 1, 1, 0]]
    res = linprog(np.array([0, 0, 0, 0, 0, 0, 1.0]), A_ub=np.array(A_ub), b_ub=b_ub,
                  A_eq=np.array(A_eq, dtype=float), b_eq=[1.0, 1.0],
                  bounds=[(0, None)] * 7, method='highs')
    assert res.status == 0, res.message
    return res.fun


def all_orders(P, Q):
    """Yield the pair with each triangle's vertices rotated/reversed, and with P, Q swapped."""
    perms = [(0, 1, 2), (1, 2, 0), (2, 0, 1), (0, 2, 1)]
    for a, b in itertools.product(perms, perms):
        yield P[list(a)], Q[list(b)]
        yield Q[list(b)], P[list(a)]


@pytest.mark.slow
def test_random_pairs_agree_with_lp_oracle():
    rng = np.random.default_rng(42)
    counts = {True: 0, False: 0}
    bad = []
    for _ in range(2500):
        P = rng.uniform(-1, 1, size=(3, 3))
        c = P.mean(axis=0) + rng.uniform(-0.6, 0.6, size=3)
        Q = c + rng.uniform(-0.8, 0.8, size=(3, 3))
        if rng.random() < 0.2:              # a coplanar pair: flatten both onto z = 0.3
            P[:, 2] = 0.3
            Q[:, 2] = 0.3
        tau = lp_chebyshev_distance(P, Q)
        if 1e-9 < tau <= 1e-6:              # too close to call for the LP's own tolerances
            continue
        expected = tau <= 1e-9
        counts[expected] += 1
        if triangles_intersect(P, Q) != expected:
            bad.append(f'tau={tau!r}: {literal(P, Q)}')
    assert not bad, '\n'.join(bad[:10])
    assert counts[True] > 400 and counts[False] > 400, counts


def test_random_touching_pairs_are_contact_and_separated_by_a_hair_are_not():
    rng = np.random.default_rng(7)
    for _ in range(500):
        P = rng.uniform(-1, 1, size=(3, 3))
        n = np.cross(P[1] - P[0], P[2] - P[0])
        n /= np.linalg.norm(n)
        w = rng.dirichlet([1, 1, 1])
        X = w @ P                                         # a point of P
        up = rng.uniform(0.1, 1.0, size=2)
        side = rng.normal(size=(2, 3))
        side -= np.outer(side @ n, n)                     # in-plane offsets
        Q = np.array([X, X + side[0] + up[0] * n, X + side[1] + up[1] * n])
        assert triangles_intersect(P, Q), literal(P, Q)   # vertex on P: touching
        assert not triangles_intersect(P, Q + 1e-6 * n), literal(P, Q + 1e-6 * n)


# Hand-built cases in the plane z = 0 around P0 (legs 2 along x and y).
P0 = tri((0, 0, 0), (2, 0, 0), (0, 2, 0))
HAND_BUILT = [
    ('crossing', P0, tri((0.5, 0.5, -1), (0.5, 0.5, 1), (3, 3, 0)), True),
    ('parallel planes', P0, P0 + [0, 0, 1], False),
    ('shared vertex', P0, tri((0, 0, 0), (-1, 0, 1), (0, -1, 1)), True),
    ('shared edge', P0, tri((0, 0, 0), (2, 0, 0), (1, -1, 1)), True),
    ('vertex on face', P0, tri((0.5, 0.5, 0), (0.5, 0.5, 1), (1, 0.5, 1)), True),
    ('vertex 1e-6 above face', P0, tri((0.5, 0.5, 1e-6), (0.5, 0.5, 1), (1, 0.5, 1)), False),
    ('edge touching edge', P0, tri((1, -1, 1), (1, 1, -1), (1, -1, -1)), True),
    ('edge 1e-6 off edge', P0, tri((1, -1 - 1e-6, 1), (1, 1 - 1e-6, -1), (1, -1 - 1e-6, -1)),
     False),
    ('coplanar overlapping', P0, tri((0.5, 0.5, 0), (3, 0.5, 0), (0.5, 3, 0)), True),
    ('coplanar crossing (star)', P0, tri((-0.5, 1.5, 0), (1.5, -0.5, 0), (1.5, 1.5, 0)), True),
    ('coplanar vertex on edge', P0, tri((1, 1, 0), (3, 1, 0), (1, 3, 0)), True),
    ('coplanar 1e-6 apart', P0, tri((1 + 1e-6, 1 + 1e-6, 0), (3, 1, 0), (1, 3, 0)), False),
    ('coplanar shared edge', P0, tri((0, 0, 0), (2, 0, 0), (1, -1, 0)), True),
    ('coplanar disjoint', P0, P0 + [3, 0, 0], False),
    ('coplanar contained', P0, tri((0.2, 0.2, 0), (0.5, 0.2, 0), (0.2, 0.5, 0)), True),
    ('identical', P0, P0.copy(), True),
    ('segment piercing face', P0, tri((0.5, 0.5, -1), (0.5, 0.5, 0), (0.5, 0.5, 1)), True),
    ('segment above face', P0, tri((0.5, 0.5, 1), (0.5, 0.5, 2), (0.5, 0.5, 3)), False),
    ('segment in plane crossing an edge', P0, tri((1, 1, 0), (2, 2, 0), (1.5, 1.5, 0)), True),
    ('segment in plane, outside', P0, tri((1.5, 1.5, 0), (2, 2, 0), (3, 3, 0)), False),
    ('point on face', P0, tri((0.5, 0.5, 0), (0.5, 0.5, 0), (0.5, 0.5, 0)), True),
    ('point on vertex', P0, tri((2, 0, 0), (2, 0, 0), (2, 0, 0)), True),
    ('point 1e-6 above face', P0, tri((0.5, 0.5, 1e-6), (0.5, 0.5, 1e-6), (0.5, 0.5, 1e-6)),
     False),
    ('segments crossing', tri((0, 0, 0), (2, 0, 0), (1, 0, 0)),
     tri((1, -1, 0), (1, 1, 0), (1, 1, 0)), True),
    ('segments collinear, overlapping', tri((0, 0, 0), (2, 0, 0), (2, 0, 0)),
     tri((1, 0, 0), (3, 0, 0), (3, 0, 0)), True),
    ('segments collinear, end to end', tri((0, 0, 0), (2, 0, 0), (2, 0, 0)),
     tri((2, 0, 0), (3, 0, 0), (3, 0, 0)), True),
    ('segments collinear, apart', tri((0, 0, 0), (2, 0, 0), (2, 0, 0)),
     tri((2 + 1e-6, 0, 0), (3, 0, 0), (3, 0, 0)), False),
    ('segments skew, apart', tri((0, 0, 0), (2, 0, 0), (2, 0, 0)),
     tri((1, -1, 1e-6), (1, 1, 1e-6), (1, 1, 1e-6)), False),
    ('points equal', tri((1, 2, 3), (1, 2, 3), (1, 2, 3)), tri((1, 2, 3), (1, 2, 3), (1, 2, 3)),
     True),
    ('points apart', tri((1, 2, 3), (1, 2, 3), (1, 2, 3)), tri((1, 2, 4), (1, 2, 4), (1, 2, 4)),
     False),
    ('sliver (1e-14 thin) pierced', P0,
     tri((0.5, 0.5, -1), (0.5, 0.5, 1), (0.5 + 1e-14, 0.5, 0)), True),
    ('far from the origin, touching', P0 + 1e4, tri((0.5, 0.5, 0), (0.5, 0.5, 1), (1, 0.5, 1))
     + 1e4, True),
    ('far from the origin, 1e-6 apart', P0 + 1e4,
     tri((0.5, 0.5, 1e-6), (0.5, 0.5, 1), (1, 0.5, 1)) + 1e4, False),
    ('tiny, touching', P0 * 1e-6, tri((0.5, 0.5, 0), (0.5, 0.5, 1), (1, 0.5, 1)) * 1e-6, True),
    ('tiny, 1e-12 apart', P0 * 1e-6, tri((0.5, 0.5, 1e-6), (0.5, 0.5, 1), (1, 0.5, 1)) * 1e-6,
     False),
]


@pytest.mark.parametrize('name, P, Q, expected', HAND_BUILT, ids=[c[0] for c in HAND_BUILT])
def test_hand_built_pair_in_every_vertex_order(name, P, Q, expected):
    for A, B in all_orders(P, Q):
        assert triangles_intersect(A, B) == expected, f'{name}: {literal(A, B)}'


def test_batch_answers_are_the_one_pair_answers():
    # triangles_intersect on (n, 3, 3) arrays (the brute-force oracle of test_checker.py uses
    # it) answers row by row exactly as the one-pair call does.
    pairs = [order for _, P, Q, _ in HAND_BUILT for order in all_orders(P, Q)]
    rng = np.random.default_rng(3)
    P = rng.uniform(-1, 1, size=(2000, 3, 3))
    Q = P.mean(axis=1, keepdims=True) + rng.uniform(-0.8, 0.8, size=(2000, 3, 3))
    pairs += list(zip(P, Q))
    P, Q = (np.array(x, dtype=np.float64) for x in zip(*pairs))
    got = triangles_intersect(P, Q)
    assert got.shape == (len(pairs),) and got.dtype == bool
    assert got.tolist() == [bool(triangles_intersect(a, b)) for a, b in pairs]
    assert 0 < got.sum() < len(pairs)
    expected = [e for _, P, Q, e in HAND_BUILT for _ in all_orders(P, Q)]
    assert got[:len(expected)].tolist() == expected
    assert triangles_intersect(np.empty((0, 3, 3)), np.empty((0, 3, 3))).shape == (0,)


def test_tolerance_is_relative_to_the_coordinates():
    for scale in (1e-4, 1.0, 1e4):
        P = P0 * scale
        tol = TRIANGLE_EPS_REL * 2.0 * scale
        for gap, expected in ((0.5 * tol, True), (2.0 * tol, False)):
            Q = tri((0.5, 0.5, 0), (0.5, 0.5, 1), (1, 0.5, 1)) * scale + [0, 0, gap]
            assert triangles_intersect(P, Q) == expected, (scale, gap)


def test_nan_or_infinite_input_counts_as_contact():
    Q = P0 + [5.0, 5.0, 5.0]
    for bad in (np.nan, np.inf):
        R = Q.copy()
        R[1, 2] = bad
        assert triangles_intersect(P0, R)
        assert triangles_intersect(R, P0)


def test_skew_edges_within_and_beyond_the_tolerance():
    # Closest features two edges, neither plane separating the triangles: the case the
    # nine edge-edge axes decide. P lies below n . (x - X) = 0, Q above n . (x - X) = h, and
    # X, X + h n are on their edges, so the distance is h by construction.
    rng = np.random.default_rng(11)
    for k in range(400):
        u, v, n = np.linalg.qr(rng.normal(size=(3, 3)))[0].T
        X = rng.uniform(-1, 1, size=3) * (1e3 if k % 4 == 0 else 1.0)
        a, b, s, w = rng.uniform(0.2, 1.0, size=(4, 2))
        P = np.array([X - a[0] * u, X + b[0] * u, X + s[0] * v - w[0] * n])
        tol = TRIANGLE_EPS_REL * np.abs(np.vstack([P, P + n])).max()
        for h, expected in ((0.3 * tol, True), (4.0 * tol, False), (1e-9, False)):
            Y = X + h * n
            Q = np.array([Y - a[1] * v, Y + b[1] * v, Y + s[1] * u + w[1] * n])
            assert triangles_intersect(P, Q) == expected, f'h={h!r}: {literal(P, Q)}'
            assert triangles_intersect(Q, P) == expected, f'h={h!r}: {literal(Q, P)}'
