"""Show what the robot-model layer reads from the Panda of example-robot-data.

A stand-in until the demo cell exists: prints the kinematic tree (indented, with joint types
and limits), the collision elements of every link with their triangle counts, and the poses of
a few links at the SRDF's ``default`` group state. Exits with status 2 when example-robot-data
is not installed.
"""
import os
import sys
import sysconfig

import numpy as np

from collision_sensor.errors import CollisionSensorError

_SHOWN_LINKS = ('panda_link4', 'panda_link7', 'panda_hand', 'panda_hand_tcp',
                'panda_leftfinger')


def find_example_robot_data() -> str | None:
    """Return ``.../share/example-robot-data`` of the installed wheel, or None if absent."""
    # The example-robot-data wheel has no Python module; its files sit in cmeel.prefix.
    share = os.path.join(sysconfig.get_paths()['purelib'], 'cmeel.prefix', 'share',
                         'example-robot-data')
    return share if os.path.isdir(share) else None


def main(argv=None) -> int:
    """Load the Panda and print its tree, collision elements and a few link poses.

    :return: the exit status (the console script passes it to ``sys.exit``): 0 on success,
        2 when example-robot-data is missing, 1 on a description error.
    """
    share = find_example_robot_data()
    if share is None:
        print('collision_sensor demo: example-robot-data is not installed; install it with '
              '`pip install example-robot-data` (or `pip install -e ".[test]"`)',
              file=sys.stderr)
        return 2
    from collision_sensor.kinematics import build_kinematic_tree
    from collision_sensor.robot_model import load_urdf
    from collision_sensor.srdf import load_srdf

    robot_dir = os.path.join(share, 'robots', 'panda_description')
    try:
        model = load_urdf(os.path.join(robot_dir, 'urdf', 'panda.urdf'),
                          {'example-robot-data': share})
        tree = build_kinematic_tree(model)
        srdf = load_srdf(os.path.join(robot_dir, 'srdf', 'panda.srdf'), model.links,
                         [joint.name for joint in model.joints])
    except CollisionSensorError as exc:
        print(f'collision_sensor demo: {exc}', file=sys.stderr)
        return 1

    print(f'robot "{model.name}" from {model.source}')
    print(f'{len(model.links)} links, {len(model.joints)} joints, '
          f'{len(tree.joint_names)} variables: {", ".join(tree.joint_names)}')
    print('\nkinematic tree:')
    _print_tree(model)

    print('\ncollision elements (one sub-group each):')
    for link in model.links:
        elements = [element for element in model.elements if element.link == link]
        if not elements:
            print(f'  {link}: none')
        for element in elements:
            print(f'  {link} [{element.index}] {element.name}: {element.source}, '
                  f'{len(element.faces)} triangles, {len(element.vertices)} vertices')
    total = sum(len(element.faces) for element in model.elements)
    print(f'  {len(model.elements)} elements, {total} triangles in all')

    state = srdf.group_states['default']
    q = np.array([state['joints'].get(name, 0.0) for name in tree.joint_names])
    T_world_link = tree.forward_kinematics(q)
    print(f'\nlink poses at SRDF group_state "default" (group "{state["group"]}"), in the '
          f'frame of "{model.root_link}":')
    print('  q = ' + ', '.join(f'{name}={value:g}' for name, value in zip(tree.joint_names, q)))
    np.set_printoptions(precision=4, suppress=True)
    for link in _SHOWN_LINKS:
        T = T_world_link[tree.link_names.index(link)]
        print(f'  {link}: position {T[:3, 3]}, z axis {T[:3, 2]}')
    print(f'\n{len(srdf.disabled_pairs)} link pairs disabled by the SRDF')
    return 0


def _print_tree(model):
    children = {}
    for joint in model.joints:
        children.setdefault(joint.parent, []).append(joint)

    def show(link, depth):
        for joint in children.get(link, []):
            indent = '  ' * (depth + 1)
            print(f'{indent}{joint.child}  <- {joint.name} ({joint.type}{_limits(joint)})')
            show(joint.child, depth + 1)

    print(f'  {model.root_link}')
    show(model.root_link, 1)


def _limits(joint):
    text = ''
    if joint.type in ('revolute', 'prismatic'):
        text = f' [{joint.lower:g}, {joint.upper:g}]'
    if joint.mimic is not None:
        text += (f', mimics {joint.mimic.joint} x{joint.mimic.multiplier:g} '
                 f'{joint.mimic.offset:+g}')
    return text


if __name__ == '__main__':
    sys.exit(main())
