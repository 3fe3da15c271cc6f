"""Benchmark: the paper's box test (sec. 5) against the 15-axis SAT, in the same run.

Run ``python -m collision_sensor.bench.box_tests [--pairs N] [--repeat K] [--seed S]``. Each
figure is the time of a compiled loop over pre-generated pairs divided by the number of tests,
so no interpreter overhead is counted. Pair sets: random poses (about half overlap), and
near-touching pairs placed 1e-6 of the boxes' size inside or outside contact.

The pair generators are also the random input of ``test/test_box_test.py``.
"""
import argparse
import math
import time

import numba
import numpy as np

from collision_sensor.box_test import boxes_disjoint_paper, boxes_disjoint_sat

# Placement kinds for random_box_pair.
PLACE_RANDOM = 0          # t = w * lambda* * U(0, 2): anything from deep overlap to far apart
PLACE_AT = 1              # t = w * (lambda* + gap): gap given by the caller


@numba.njit(cache=True)
def random_rotation(R):
    """Fill R (3, 3) with a uniformly random rotation (normalised Gaussian quaternion)."""
    w, x, y, z = np.random.normal(), np.random.normal(), np.random.normal(), np.random.normal()
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - z * w)
    R[0, 2] = 2 * (x * z + y * w)
    R[1, 0] = 2 * (x * y + z * w)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - x * w)
    R[2, 0] = 2 * (x * z - y * w)
    R[2, 1] = 2 * (y * z + x * w)
    R[2, 2] = 1 - 2 * (x * x + y * y)


@numba.njit(cache=True)
def random_signed_permutation(R):
    """Fill R (3, 3) with a random axis permutation with sign flips, det = +1 (exact 0 / +-1)."""
    R[:, :] = 0.0
    a = np.random.randint(0, 3)
    b = (a + 1 + np.random.randint(0, 2)) % 3
    c = 3 - a - b
    sa = 1.0 if np.random.random() < 0.5 else -1.0
    sb = 1.0 if np.random.random() < 0.5 else -1.0
    R[a, 0] = sa
    R[b, 1] = sb
    # Column 2 = column 0 x column 1 keeps det = +1.
    R[0, 2] = R[1, 0] * R[2, 1] - R[2, 0] * R[1, 1]
    R[1, 2] = R[2, 0] * R[0, 1] - R[0, 0] * R[2, 1]
    R[2, 2] = R[0, 0] * R[1, 1] - R[1, 0] * R[0, 1]
    return c


@numba.njit(cache=True)
def _ratio(num, den, best):
    if den > 1e-300:
        r = num / den
        if r < best:
            return r
    return best


@numba.njit(cache=True)
def contact_distance(ha, hb, R, w):
    """Return lambda* such that B centred at lambda * w (w a unit vector in F_A) touches A.

    For every candidate axis L the projections separate once lambda |w . L| > r_A(L) + r_B(L);
    the 15 axes are complete, so contact is the smallest such lambda (exact in exact
    arithmetic, independent of both tests under study). Edge axes with |L| < 1e-10 are skipped
    (the face axes decide those configurations to within 1e-10 of the boxes' size).
    """
    best = np.inf
    for k in range(3):
        rb = abs(R[k, 0]) * hb[0] + abs(R[k, 1]) * hb[1] + abs(R[k, 2]) * hb[2]
        best = _ratio(ha[k] + rb, abs(w[k]), best)
    for j in range(3):
        ra = abs(R[0, j]) * ha[0] + abs(R[1, j]) * ha[1] + abs(R[2, j]) * ha[2]
        wb = R[0, j] * w[0] + R[1, j] * w[1] + R[2, j] * w[2]
        best = _ratio(ra + hb[j], abs(wb), best)
    for i in range(3):
        for j in range(3):
            # L = e_i x b_j
            L0 = 0.0
            L1 = 0.0
            L2 = 0.0
            if i == 0:
                L1, L2 = -R[2, j], R[1, j]
            elif i == 1:
                L0, L2 = R[2, j], -R[0, j]
            else:
                L0, L1 = -R[1, j], R[0, j]
            if L0 * L0 + L1 * L1 + L2 * L2 < 1e-20:
                continue
            ra = ha[0] * abs(L0) + ha[1] * abs(L1) + ha[2] * abs(L2)
            rb = 0.0
            for k in range(3):
                rb += hb[k] * abs(R[0, k] * L0 + R[1, k] * L1 + R[2, k] * L2)
            best = _ratio(ra + rb, abs(w[0] * L0 + w[1] * L1 + w[2] * L2), best)
    return best


@numba.njit(cache=True)
def random_unit(w):
    """Fill w (3,) with a uniformly random unit vector."""
    n = 0.0
    while n < 1e-12:
        w[0], w[1], w[2] = np.random.normal(), np.random.normal(), np.random.normal()
        n = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    w[0] /= n
    w[1] /= n
    w[2] /= n


@numba.njit(cache=True)
def random_extents(h, scale, zero_pattern):
    """Fill h (3,) with ``scale * U(0.02, 1)`` per axis; bit k of zero_pattern zeroes axis k."""
    for k in range(3):
        h[k] = 0.0 if (zero_pattern >> k) & 1 else scale * (0.02 + 0.98 * np.random.random())


@numba.njit(cache=True)
def place(ha, hb, R, w, gap_rel, t):
    """Put B's centre t at (lambda* + gap_rel * s) * w, s the sum of the half extents."""
    s = ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]
    lam = contact_distance(ha, hb, R, w) + gap_rel * s
    t[0] = lam * w[0]
    t[1] = lam * w[1]
    t[2] = lam * w[2]


@numba.njit(cache=True)
def generate_pairs(n, seed, placement, gap_rel, HA, HB, RR, TT):
    """Fill n random pairs (HA, HB (n, 3); RR (n, 3, 3); TT (n, 3)) for the benchmark.

    Uniform rotations; box sizes 10^U(-1, 1) with aspect U(0.02, 1); direction uniform.
    placement PLACE_RANDOM: t = w * lambda* * U(0, 2); PLACE_AT: gap_rel of the boxes' size.
    """
    np.random.seed(seed)
    w = np.empty(3)
    for p in range(n):
        random_extents(HA[p], 10.0 ** np.random.uniform(-1.0, 1.0), 0)
        random_extents(HB[p], 10.0 ** np.random.uniform(-1.0, 1.0), 0)
        random_rotation(RR[p])
        random_unit(w)
        if placement == PLACE_RANDOM:
            lam = contact_distance(HA[p], HB[p], RR[p], w) * 2.0 * np.random.random()
            TT[p, 0], TT[p, 1], TT[p, 2] = lam * w[0], lam * w[1], lam * w[2]
        else:
            place(HA[p], HB[p], RR[p], w, gap_rel, TT[p])


@numba.njit(cache=True)
def _time_loop(method, HA, HB, RR, TT, repeat, scratch):
    # The count of separated pairs is returned so the work cannot be optimised away.
    separated = 0
    for _ in range(repeat):
        for p in range(HA.shape[0]):
            if method == 0:
                separated += boxes_disjoint_paper(HA[p], HB[p], RR[p], TT[p], scratch)
            else:
                separated += boxes_disjoint_sat(HA[p], HB[p], RR[p], TT[p], scratch)
    return separated


def measure(n_pairs=100_000, repeat=10, seed=1998, rounds=3):
    """Return rows (set name, ns/paper test, ns/SAT test, fraction separated) for each set."""
    sets = [('random poses', PLACE_RANDOM, 0.0),
            ('near-touching, overlapping (-1e-6)', PLACE_AT, -1e-6),
            ('near-touching, separated (+1e-6)', PLACE_AT, 1e-6)]
    scratch = np.zeros(64)
    rows = []
    for k, (name, placement, gap) in enumerate(sets):
        HA, HB = np.empty((n_pairs, 3)), np.empty((n_pairs, 3))
        RR, TT = np.empty((n_pairs, 3, 3)), np.empty((n_pairs, 3))
        generate_pairs(n_pairs, seed + k, placement, gap, HA, HB, RR, TT)
        for method in (0, 1):                        # compile and warm up
            _time_loop(method, HA[:100], HB[:100], RR[:100], TT[:100], 1, scratch)
        best = [np.inf, np.inf]
        counts = [0, 0]
        for _ in range(rounds):                      # interleaved, best of `rounds`
            for method in (0, 1):
                start = time.perf_counter()
                counts[method] = _time_loop(method, HA, HB, RR, TT, repeat, scratch)
                best[method] = min(best[method], time.perf_counter() - start)
        if counts[0] != counts[1]:
            raise AssertionError(f'{name}: paper and SAT disagree ({counts[0]} vs {counts[1]})')
        n_tests = n_pairs * repeat
        rows.append((name, 1e9 * best[0] / n_tests, 1e9 * best[1] / n_tests,
                     counts[0] / n_tests))
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
