"""Engine benchmark: our checker against pinocchio+coal and python-fcl, measured in one run.

``python -m benchmarks.robot_peers [--robot panda] [--configurations 2000]``

Prints, per robot: time per random configuration (full check including kinematics, the
paper's no-coherence case) for us and the peers with ratios; ``update`` against ``check`` on
streams where one, three or all joints move per step; and the expansion rules and box tests
side by side (time per query, boxes and triangles tested). Not a test: it asserts nothing.
"""
import argparse
import time

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.sampling import random_configurations
from collision_sensor.model.example_robots import example_robot
from benchmarks.peers import FclPeer, PinocchioPeer


def per_call_us(function, items, repeats=3):
    """Best-of-``repeats`` mean time per call of ``function(item)`` over ``items``, in us."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for item in items:
            function(item)
        best = min(best, (time.perf_counter() - start) / len(items))
    return best * 1e6


def stream(checker, n, moving, seed=0, step=0.02, bounds=None, start=None):
    """A coherent stream: ``moving`` joints (random ones each step) move by N(0, ``step``);
    with ``bounds`` ``(lower, upper)`` every state is clipped to them. It starts from
    ``start`` (J,), or from a random configuration within the limits."""
    rng = np.random.default_rng(seed)
    q = random_configurations(checker, 1, seed)[0] if start is None else np.array(start, float)
    frames = []
    for _ in range(n):
        q = q.copy()
        joints = rng.choice(len(q), size=min(moving, len(q)), replace=False)
        q[joints] += rng.normal(0.0, step, len(joints))
        if bounds is not None:
            q = np.clip(q, *bounds)
        frames.append(q)
    return frames


def bench_random(checker, robot, configurations, out):
    ours = per_call_us(checker.check, configurations)
    rows = [('collision_sensor check (FK + all pairs)', ours)]
    try:
        peer = PinocchioPeer(robot.urdf, robot.srdf, robot.package_paths)
        qs = [peer.configuration(checker, q) for q in configurations]
        rows.append((f'pinocchio+coal computeCollisions ({peer.pair_count} pairs)',
                     per_call_us(peer.check, qs)))
    except ImportError:
        rows.append(('pinocchio+coal', None))
    try:
        fcl_peer = FclPeer(checker)
        poses = []
        for q in configurations:
            checker.check(q)
            poses.append(checker.link_poses())
        placed = per_call_us(lambda p: (fcl_peer.place(p), fcl_peer.check()), poses)
        rows.append(('python-fcl, our FK poses (placing + all pairs, FK not counted)', placed))
    except ImportError:
        rows.append(('python-fcl', None))
    out.append(f'\n### {robot.name}: random configurations (no coherence), per configuration\n')
    out.append('| implementation | us / config | ratio to ours |')
    out.append('|---|---|---|')
    for label, value in rows:
        if value is None:
            out.append(f'| {label} | not installed | |')
        else:
            out.append(f'| {label} | {value:.1f} | {value / ours:.2f}x |')


def bench_streams(checker, robot, n, out):
    out.append(f'\n### {robot.name}: coherent streams, per step\n')
    out.append('| joints moving per step | update us | check us | update / check |')
    out.append('|---|---|---|---|')
    for moving in (1, 3, len(checker.joint_names)):
        frames = stream(checker, n, moving)
        check_us = per_call_us(checker.check, frames)

        def run_updates():
            checker.check(frames[0])
            start = time.perf_counter()
            for q in frames:
                checker.update(q)
            return (time.perf_counter() - start) / len(frames) * 1e6
        update_us = min(run_updates() for _ in range(3))
        out.append(f'| {moving} | {update_us:.1f} | {check_us:.1f} | {update_us / check_us:.2f} |')


def bench_rules(robot, configurations, out):
    out.append(f'\n### {robot.name}: expansion rules and box tests (check per configuration)\n')
    out.append('| box test | expansion | us / config | boxes tested / config '
               '| triangles tested / config |')
    out.append('|---|---|---|---|---|')
    for box_test in ('sat', 'paper'):
        for expansion in ('same', 'alternate', 'larger', 'promising', 'wider'):
            checker = CollisionChecker.from_urdf(
                robot.urdf, srdf=robot.srdf, package_paths=robot.package_paths,
                config={'box_test': box_test, 'expansion': expansion})
            checker.check(configurations[0])
            us = per_call_us(checker.check, configurations)
            checker.counters[:] = 0
            for q in configurations:
                checker.check(q)
            boxes, tris = checker.counters / len(configurations)
            out.append(f'| {box_test} | {expansion} | {us:.1f} | {boxes:.0f} | {tris:.0f} |')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--robot', action='append', choices=['panda', 'ur5'],
                        help='robot(s) to measure (default: panda and ur5)')
    parser.add_argument('--configurations', type=int, default=2000)
    parser.add_argument('--no-rules', action='store_true', help='skip the rules table')
    args = parser.parse_args(argv)
    out = ['## Engine benchmark (one run, this machine)']
    for name in args.robot or ['panda', 'ur5']:
        robot = example_robot(name)
        checker = CollisionChecker.from_urdf(robot.urdf, srdf=robot.srdf,
                                             package_paths=robot.package_paths)
        configurations = list(random_configurations(checker, args.configurations, seed=1))
        checker.check(configurations[0])
        bench_random(checker, robot, configurations, out)
        bench_streams(checker, robot, args.configurations, out)
        if not args.no_rules:
            bench_rules(robot, configurations[:max(200, args.configurations // 4)], out)
    print('\n'.join(out))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
