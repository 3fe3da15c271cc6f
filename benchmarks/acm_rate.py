"""Sampling rate of the self-collision matrix tool: ``check_batch`` against pinocchio+coal.

``python -m benchmarks.acm_rate [--configurations 2000] [--repeats 3]``

On the Panda with every pair of links checked (no SRDF, no adjacency exception: the raw
matrix), both sides answer every pair for the same random configurations, measured in one
run: our ``check_batch`` (kinematics and all pairs in one compiled call per configuration)
against a Python loop over pinocchio's ``computeCollisions(model, data, geom, gdata, q,
False)`` after ``geom.addAllCollisionPairs()`` (kinematics, placements, every pair, coal).
A second row times the pairs the tool really samples (adjacent pairs left out).

Prints configurations per second, best of ``--repeats``, and the ratio. Not a test: it
asserts nothing. The pair counts differ by construction: pinocchio pairs geometry objects and
skips two objects on the same joint; we pair links (all their elements at once).
"""
import argparse
import time

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.sampling import sampling_bounds, uniform_configurations
from collision_sensor.model.example_robots import example_robot
from collision_sensor.tools.collision_matrix import find_adjacent, pair_checker
from benchmarks.peers import PinocchioPeer


def best_rate(run, n, repeats):
    """Return the best of ``repeats`` rates, ``n`` configurations per call of ``run()``."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return n / best


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--configurations', type=int, default=2000,
                        help='random configurations per measurement (default %(default)s)')
    parser.add_argument('--repeats', type=int, default=3,
                        help='measurements per implementation, the best counts '
                             '(default %(default)s)')
    parser.add_argument('--seed', type=int, default=1)
    args = parser.parse_args(argv)

    robot = example_robot('panda')
    checker = CollisionChecker.from_urdf(robot.urdf, package_paths=robot.package_paths,
                                         config={'ignore_adjacent': False})
    lower, upper = sampling_bounds(checker)
    Q = uniform_configurations(lower, upper, args.configurations,
                              np.random.default_rng(args.seed))
    checker.check_batch(Q[:2])  # compile before timing
    rows = [(f'collision_sensor check_batch, all {len(checker.checked_pairs)} link pairs',
             best_rate(lambda: checker.check_batch(Q), len(Q), args.repeats))]
    adjacent = find_adjacent(checker.model, checker.link_names)
    sampled = pair_checker(checker, [p for p in checker.checked_pairs if p not in adjacent])
    sampled.check_batch(Q[:2])
    sampled_rate = best_rate(lambda: sampled.check_batch(Q), len(Q), args.repeats)

    try:
        peer = PinocchioPeer(robot.urdf, None, robot.package_paths)
    except ImportError:
        peer = None
    if peer is not None:
        qs = [peer.configuration(checker, q) for q in Q]

        def pinocchio_loop():
            for q in qs:
                peer.check(q)
        rows.append((f'pinocchio+coal computeCollisions loop, all {peer.pair_count} '
                     'geometry pairs', best_rate(pinocchio_loop, len(Q), args.repeats)))
    rows.append((f'collision_sensor check_batch, the {len(sampled.checked_pairs)} pairs the '
                 'tool samples (adjacent left out; less work than the rows above)',
                 sampled_rate))
    peer_rate = rows[1][1] if peer is not None else None
    print(f'## Sampling rate on the Panda, raw matrix ({len(Q)} random configurations, '
          f'best of {args.repeats}, one run)\n')
    print('| implementation | configurations / s | rate / pinocchio+coal rate |')
    print('|---|---|---|')
    for label, rate in rows:
        ratio = f'{rate / peer_rate:.2f}x' if peer_rate else 'pinocchio not installed'
        print(f'| {label} | {rate:,.0f} | {ratio} |')
    if peer_rate:
        print(f'\nour check_batch with all pairs runs {rows[0][1] / peer_rate:.2f} times as many '
              'configurations per second as the pinocchio+coal loop')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
