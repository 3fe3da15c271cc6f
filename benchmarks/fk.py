"""Time forward kinematics of the Panda: ours (single and batch) against yourdfpy and pinocchio.

Run ``python -m benchmarks.fk [--configs N] [--robot panda|ur5]``. Every library
computes the pose of every link of the same seeded random configurations within limits, in one
run, so the ratios compare like with like:

- ours, single: :meth:`KinematicTree.forward_kinematics` called from Python per configuration
  (the wrapper's overhead included: array checks, output allocation, the call into the C++ engine);
- ours, batch: :meth:`KinematicTree.forward_kinematics_batch` over all, per configuration;
- yourdfpy: ``update_cfg`` then ``get_transform(link, root)`` for every link;
- pinocchio: ``forwardKinematics`` + ``updateFramePlacements`` (all frames, from Python).

Also reported: the first call in this process (the engine is compiled at install time, so
this is the cost of a first call, not of a compilation).
"""
import argparse
import time

import numpy as np

from collision_sensor.model.example_robots import example_robot


def _per_call(function, repeats):
    """Return the best mean time per call over a few rounds of ``repeats`` calls, seconds."""
    best = float('inf')
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(repeats):
            function()
        best = min(best, (time.perf_counter() - start) / repeats)
    return best


def main(argv=None):
    """Run the benchmark and print a table of microseconds per configuration and ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--robot', choices=('panda', 'ur5'), default='panda')
    parser.add_argument('--configs', type=int, default=1000)
    args = parser.parse_args(argv)

    import pinocchio as pin
    import yourdfpy

    from collision_sensor.engine.kinematics import build_kinematic_tree
    from collision_sensor.model.robot_model import load_urdf

    robot = example_robot(args.robot)
    urdf, package_paths = robot.urdf, robot.package_paths
    model = load_urdf(urdf, package_paths)
    tree = build_kinematic_tree(model)
    rng = np.random.default_rng(0)
    lower = np.where(np.isfinite(tree.lower), tree.lower, -np.pi)
    upper = np.where(np.isfinite(tree.upper), tree.upper, np.pi)
    Q = rng.uniform(lower, upper, size=(args.configs, len(lower)))

    start = time.perf_counter()
    tree.forward_kinematics(Q[0])
    tree.forward_kinematics_batch(Q[:2])
    first_call = time.perf_counter() - start

    n = len(Q)
    def ours_single_all():
        forward_kinematics = tree.forward_kinematics
        for q in Q:
            forward_kinematics(q)
    ours_single = _per_call(ours_single_all, 1) / n
    ours_batch = _per_call(lambda: tree.forward_kinematics_batch(Q), 1) / n

    pin_model = pin.buildModelFromUrdf(urdf)
    pin_data = pin_model.createData()
    pin_Q = np.empty((n, pin_model.nq))
    mimics = {joint.name: joint.mimic for joint in model.joints if joint.mimic is not None}
    for k, q in enumerate(Q):
        values = dict(zip(tree.joint_names, q))
        values.update({name: m.multiplier * values[m.joint] + m.offset
                       for name, m in mimics.items()})
        pin_Q[k] = [values[pin_model.names[j]] for j in range(1, pin_model.njoints)]

    def pinocchio_all():
        for q in pin_Q:
            pin.forwardKinematics(pin_model, pin_data, q)
            pin.updateFramePlacements(pin_model, pin_data)
    pinocchio = _per_call(pinocchio_all, 1) / n

    robot = yourdfpy.URDF.load(urdf, build_collision_scene_graph=False, load_meshes=False)
    root = tree.link_names[0]
    few = Q[:max(1, n // 10)]

    def yourdfpy_all():
        for q in few:
            robot.update_cfg(q)
            for link in tree.link_names:
                robot.get_transform(link, root)
    yourdfpy_time = _per_call(yourdfpy_all, 1) / len(few)

    print(f'forward kinematics of {model.name}: {len(tree.link_names)} links, '
          f'{len(tree.joint_names)} variables, {n} random configurations')
    print(f'first call in this process: {first_call * 1e3:.1f} ms')
    print(f'{"":34s}{"us/config":>12s}{"ours single is":>18s}')
    rows = [('ours, single (Python wrapper)', ours_single),
            ('ours, batch (per config)', ours_batch),
            ('pinocchio fk+updateFramePlacements', pinocchio),
            ('yourdfpy update_cfg+get_transform', yourdfpy_time)]
    for label, seconds in rows:
        ratio = seconds / ours_single
        relation = f'{ratio:.1f}x faster' if ratio >= 1 else f'{1 / ratio:.1f}x slower'
        print(f'{label:34s}{seconds * 1e6:12.2f}{"" if seconds is ours_single else relation:>18s}')


if __name__ == '__main__':
    main()
