"""Benchmark: the paper's box test (sec. 5) against the 15-axis SAT, in the same run.

Run ``python -m benchmarks.box_tests [--pairs N] [--repeat K] [--seed S]``. Each
figure is the time of one C++ batch call over pre-generated pairs
(``engine.boxes_disjoint(method, ha, hb, R, t)``: the loop over the pairs is in C++) divided by
the number of tests, so no interpreter overhead is counted. Pair sets: random poses (about half
overlap), and near-touching pairs placed 1e-6 of the boxes' size inside or outside contact.

The pair generators (vectorised numpy, one seeded ``numpy.random.Generator``; n pairs at once
as ``ha, hb (n, 3)``, ``R (n, 3, 3)``, ``t (n, 3)``) are also the random input of
``test/test_box_test.py`` (:func:`mixed_pairs`).
"""
import argparse
import time

import numpy as np

from collision_sensor.engine.box_test import BOX_TEST_PAPER, BOX_TEST_SAT
from collision_sensor.engine.compiled import engine

# Placement kinds for generate_pairs.
PLACE_RANDOM = 0          # t = w * lambda* * U(0, 2): anything from deep overlap to far apart
PLACE_AT = 1              # t = w * (lambda* + gap): gap given by the caller

# Placement categories of mixed_pairs.
CAT_RANDOM, CAT_TOUCHING, CAT_NEAR = 0, 1, 2


def _sign(rng, n):
    """Return (n,) random signs +-1.0."""
    return np.where(rng.random(n) < 0.5, 1.0, -1.0)


def random_rotation(rng, n):
    """Return (n, 3, 3) uniformly random rotations (normalised Gaussian quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.sqrt(np.einsum('ij,ij->i', q, q))[:, None]
    w, x, y, z = q.T
    R = np.empty((n, 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - z * w)
    R[:, 0, 2] = 2 * (x * z + y * w)
    R[:, 1, 0] = 2 * (x * y + z * w)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - x * w)
    R[:, 2, 0] = 2 * (x * z - y * w)
    R[:, 2, 1] = 2 * (y * z + x * w)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def random_signed_permutation(rng, n):
    """Return (n, 3, 3) random axis permutations with sign flips, det = +1 (exact 0 / +-1)."""
    rows = np.arange(n)
    a = rng.integers(0, 3, size=n)
    b = (a + 1 + rng.integers(0, 2, size=n)) % 3
    R = np.zeros((n, 3, 3))
    R[rows, a, 0] = _sign(rng, n)
    R[rows, b, 1] = _sign(rng, n)
    # Column 2 = column 0 x column 1 keeps det = +1 (exact: products of 0 and +-1).
    R[:, :, 2] = np.cross(R[:, :, 0], R[:, :, 1])
    return R


def random_unit(rng, n):
    """Return (n, 3) uniformly random unit vectors."""
    w = rng.normal(size=(n, 3))
    norm = np.sqrt(np.einsum('ij,ij->i', w, w))
    redo = norm < 1e-12
    while redo.any():                              # (practically never)
        w[redo] = rng.normal(size=(int(redo.sum()), 3))
        norm[redo] = np.sqrt(np.einsum('ij,ij->i', w[redo], w[redo]))
        redo = norm < 1e-12
    return w / norm[:, None]


def random_tilt(rng, R, low=-12.0, high=-3.0):
    """Return R (n, 3, 3) turned by 10^U(low, high) rad about random axes: R @ S (Rodrigues)."""
    n = R.shape[0]
    k = random_unit(rng, n)
    angle = 10.0 ** rng.uniform(low, high, size=n)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -k[:, 2], k[:, 1]
    K[:, 1, 0], K[:, 1, 2] = k[:, 2], -k[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -k[:, 1], k[:, 0]
    S = (np.eye(3) + np.sin(angle)[:, None, None] * K
         + (1.0 - np.cos(angle))[:, None, None] * (K @ K))
    return R @ S


def random_extents(rng, scale, zero_pattern=None):
    """Return (n, 3) half extents ``scale * U(0.02, 1)`` per axis, scale (n,); bit k of
    zero_pattern (n,) int zeroes axis k (a flat box, a segment, a point)."""
    scale = np.asarray(scale, dtype=np.float64)
    h = scale[:, None] * (0.02 + 0.98 * rng.random((scale.shape[0], 3)))
    if zero_pattern is not None:
        zero = ((np.asarray(zero_pattern)[:, None] >> np.arange(3)) & 1).astype(bool)
        h[zero] = 0.0
    return h


def _ratio(num, den, best):
    """min(best, num / den) where den > 1e-300 (elementwise)."""
    ok = den > 1e-300
    return np.where(ok, np.minimum(best, num / np.where(ok, den, 1.0)), best)


def contact_distance(ha, hb, R, w):
    """Return lambda* such that B centred at lambda * w (w a unit vector in F_A) touches A.

    ha, hb, w (n, 3) and R (n, 3, 3) give (n,); one pair ((3,), (3, 3)) gives a float.
    For every candidate axis L the projections separate once lambda |w . L| > r_A(L) + r_B(L);
    the 15 axes are complete, so contact is the smallest such lambda (exact in exact
    arithmetic, independent of both tests under study). Edge axes with |L| < 1e-10 are skipped
    (the face axes decide those configurations to within 1e-10 of the boxes' size).
    """
    ha, hb, R, w = (np.asarray(x, dtype=np.float64) for x in (ha, hb, R, w))
    single = ha.ndim == 1
    if single:
        ha, hb, R, w = ha[None], hb[None], R[None], w[None]
    # Component-major copies: ha[k], R[k, j], ... are contiguous (n,) rows.
    ha, hb, w = (np.ascontiguousarray(x.T) for x in (ha, hb, w))
    R = np.ascontiguousarray(np.moveaxis(R, 0, -1))
    aR = np.abs(R)
    best = np.full(ha.shape[1], np.inf)
    for k in range(3):                             # A's face normals e_k
        rb = aR[k, 0] * hb[0] + aR[k, 1] * hb[1] + aR[k, 2] * hb[2]
        best = _ratio(ha[k] + rb, np.abs(w[k]), best)
    for j in range(3):                             # B's face normals b_j
        ra = aR[0, j] * ha[0] + aR[1, j] * ha[1] + aR[2, j] * ha[2]
        wb = R[0, j] * w[0] + R[1, j] * w[1] + R[2, j] * w[2]
        best = _ratio(ra + hb[j], np.abs(wb), best)
    for i in range(3):                             # L = e_i x b_j: L_i = 0, L_p = -R[q, j] s
        p, q = (i + 1) % 3, (i + 2) % 3            # and L_q = R[p, j] s, (i, p, q) cyclic
        for j in range(3):
            Lp, Lq = -R[q, j], R[p, j]
            ra = ha[p] * aR[q, j] + ha[q] * aR[p, j]
            rb = sum(hb[k] * np.abs(R[p, k] * Lp + R[q, k] * Lq) for k in range(3))
            den = np.abs(w[p] * Lp + w[q] * Lq)
            den[Lp * Lp + Lq * Lq < 1e-20] = 0.0   # skipped: near-parallel edges
            best = _ratio(ra + rb, den, best)
    return float(best[0]) if single else best


def place(ha, hb, R, w, gap_rel):
    """Return B's centres t (n, 3) at (lambda* + gap_rel * s) * w, s the sum of the half
    extents (gap_rel a number or (n,))."""
    s = ha.sum(axis=-1) + hb.sum(axis=-1)
    lam = contact_distance(ha, hb, R, w) + gap_rel * s
    return lam[:, None] * w


def generate_pairs(n, seed, placement, gap_rel=0.0):
    """Return n random pairs ``ha, hb (n, 3), R (n, 3, 3), t (n, 3)`` for the benchmark.

    Uniform rotations; box sizes 10^U(-1, 1) with aspect U(0.02, 1); direction uniform.
    placement PLACE_RANDOM: t = w * lambda* * U(0, 2); PLACE_AT: gap_rel of the boxes' size.
    """
    rng = np.random.default_rng(seed)
    ha = random_extents(rng, 10.0 ** rng.uniform(-1.0, 1.0, size=n))
    hb = random_extents(rng, 10.0 ** rng.uniform(-1.0, 1.0, size=n))
    R = random_rotation(rng, n)
    w = random_unit(rng, n)
    if placement == PLACE_RANDOM:
        lam = contact_distance(ha, hb, R, w) * 2.0 * rng.random(n)
        t = lam[:, None] * w
    else:
        t = place(ha, hb, R, w, gap_rel)
    return ha, hb, R, t


def mixed_pairs(n, rng):
    """Return n pairs of the property tests and their placement categories:
    ``ha, hb (n, 3), R (n, 3, 3), t (n, 3), category (n,) int`` (CAT_*).

    Rotations: 80 % uniform, 10 % signed axis permutations (parallel / identical axes, exact 0
    and +-1), 10 % permutations tilted by 10^U(-12, -3) rad. Sizes 10^U(-4, 4) for A; B the
    same, or A's size times 10^U(-1, 1) (half each); 15 % of the boxes have 1 to 3 zero
    extents (flat, segment, point). Direction of approach w: 50 % uniform, 25 % along an
    edge-edge axis e_i x b_j (edge-edge contacts; uniform when that axis is < 1e-6), 25 % a face
    normal +-b_j. Placement: 20 % CAT_RANDOM (t = w lambda* U(0, 2)); 40 % CAT_TOUCHING (gap 0,
    or +-10^U(-16, -11) of the size, far below the tolerance); 40 % CAT_NEAR (gap
    +-10^U(-7.5, -2) of the size).
    """
    rows = np.arange(n)
    u = rng.random(n)
    R = random_rotation(rng, n)
    permuted = u >= 0.8
    R[permuted] = random_signed_permutation(rng, int(permuted.sum()))
    tilted = u >= 0.9
    R[tilted] = random_tilt(rng, R[tilted])

    sa = 10.0 ** rng.uniform(-4.0, 4.0, size=n)
    sb = np.where(rng.random(n) < 0.5, 10.0 ** rng.uniform(-4.0, 4.0, size=n),
                  sa * 10.0 ** rng.uniform(-1.0, 1.0, size=n))
    za = np.where(rng.random(n) < 0.15, rng.integers(1, 8, size=n), 0)
    zb = np.where(rng.random(n) < 0.15, rng.integers(1, 8, size=n), 0)
    ha = random_extents(rng, sa, za)
    hb = random_extents(rng, sb, zb)

    u = rng.random(n)
    w = random_unit(rng, n)
    j = rng.integers(0, 3, size=n)
    b = R[rows, :, j]                              # (n, 3): B's axis j in F_A
    sgn = _sign(rng, n)[:, None]
    edge = (u >= 0.5) & (u < 0.75)
    e = np.zeros((n, 3))
    e[rows, rng.integers(0, 3, size=n)] = 1.0
    axis = np.cross(e, b)                          # e_i x b_j
    norm = np.sqrt(np.einsum('ij,ij->i', axis, axis))
    edge_ok = edge & (norm >= 1e-6)
    w[edge_ok] = sgn[edge_ok] * axis[edge_ok] / norm[edge_ok, None]
    face = u >= 0.75
    w[face] = sgn[face] * b[face]

    u = rng.random(n)
    category = np.where(u < 0.2, CAT_RANDOM, np.where(u < 0.6, CAT_TOUCHING, CAT_NEAR))
    sgn = _sign(rng, n)
    touching_gap = np.where(rng.random(n) < 0.1, 0.0,
                            sgn * 10.0 ** rng.uniform(-16.0, -11.0, size=n))
    near_gap = sgn * 10.0 ** rng.uniform(-7.5, -2.0, size=n)
    lam = contact_distance(ha, hb, R, w)
    s = ha.sum(axis=1) + hb.sum(axis=1)
    lam = np.where(category == CAT_RANDOM, lam * 2.0 * rng.random(n),
                   lam + np.where(category == CAT_TOUCHING, touching_gap, near_gap) * s)
    t = lam[:, None] * w
    return ha, hb, R, t, category


def _time_batch(method, HA, HB, RR, TT, repeat):
    """Run the C++ batch test ``repeat`` times over all pairs; return (seconds, answers)."""
    start = time.perf_counter()
    for _ in range(repeat):
        answers = engine.boxes_disjoint(method, HA, HB, RR, TT)
    return time.perf_counter() - start, answers


def measure(n_pairs=100_000, repeat=10, seed=1998, rounds=3):
    """Return rows (set name, ns/paper test, ns/SAT test, fraction separated) for each set."""
    sets = [('random poses', PLACE_RANDOM, 0.0),
            ('near-touching, overlapping (-1e-6)', PLACE_AT, -1e-6),
            ('near-touching, separated (+1e-6)', PLACE_AT, 1e-6)]
    methods = (BOX_TEST_PAPER, BOX_TEST_SAT)
    rows = []
    for k, (name, placement, gap) in enumerate(sets):
        pairs = [np.ascontiguousarray(x)
                 for x in generate_pairs(n_pairs, seed + k, placement, gap)]
        for method in methods:                       # warm up (caches, page faults)
            _time_batch(method, *(x[:1000] for x in pairs), 1)
        best = [np.inf, np.inf]
        answers = [None, None]
        for _ in range(rounds):                      # interleaved, best of `rounds`
            for m, method in enumerate(methods):
                elapsed, answers[m] = _time_batch(method, *pairs, repeat)
                best[m] = min(best[m], elapsed)
        disagree = int(np.count_nonzero(answers[0] != answers[1]))
        if disagree:
            raise AssertionError(f'{name}: paper and SAT disagree on {disagree} pairs '
                                 f'({int(answers[0].sum())} vs {int(answers[1].sum())} '
                                 'separated)')
        n_tests = n_pairs * repeat
        rows.append((name, 1e9 * best[0] / n_tests, 1e9 * best[1] / n_tests,
                     float(answers[0].mean()) if n_pairs else 0.0))
    return rows


def main(argv=None):
    """Print ns per test for both box tests and their ratio."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--pairs', type=int, default=100_000)
    parser.add_argument('--repeat', type=int, default=10)
    parser.add_argument('--seed', type=int, default=1998)
    args = parser.parse_args(argv)
    rows = measure(args.pairs, args.repeat, args.seed)
    print(f'{"pair set":38s} {"paper ns":>9s} {"SAT ns":>9s} {"paper/SAT":>10s} '
          f'{"separated":>10s}')
    for name, paper, sat, frac in rows:
        print(f'{name:38s} {paper:9.1f} {sat:9.1f} {paper / sat:10.2f} {frac:10.1%}')
    total_paper = sum(r[1] for r in rows)
    total_sat = sum(r[2] for r in rows)
    faster = 'SAT' if total_sat < total_paper else 'paper'
    print(f'faster overall: {faster} (mean over the sets: paper {total_paper / len(rows):.1f} ns, '
          f'SAT {total_sat / len(rows):.1f} ns)')


if __name__ == '__main__':
    main()
