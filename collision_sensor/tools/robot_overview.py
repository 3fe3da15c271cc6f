"""``collision_sensor_demo --describe-panda``: the Panda's kinematic tree, collision elements
and a few link poses, as this package reads them (needs example-robot-data).
"""
import sys

import numpy as np

from collision_sensor.errors import CollisionSensorError

_SHOWN_LINKS = ('panda_link4', 'panda_link7', 'panda_hand', 'panda_hand_tcp',
                'panda_leftfinger')


def describe_panda(prog: str = 'collision_sensor_demo') -> int:
    """Load the Panda and print its tree, collision elements and a few link poses.

    :param prog: the command's name, in its error lines.

    :return: the exit status: 0 on success, 2 when example-robot-data is missing, 1 on a
        description error.
    """
    from collision_sensor.engine.kinematics import build_kinematic_tree
    from collision_sensor.model.example_robots import example_robot
    from collision_sensor.model.robot_model import load_urdf
    from collision_sensor.model.srdf import load_srdf_for_model

    try:
        panda = example_robot('panda')
    except CollisionSensorError as exc:  # example-robot-data is not installed
        print(f'{prog}: {exc} (or `pip install -e ".[test]"`)', file=sys.stderr)
        return 2
    try:
        model = load_urdf(panda.urdf, panda.package_paths)
        tree = build_kinematic_tree(model)
        srdf = load_srdf_for_model(panda.srdf, model)
    except CollisionSensorError as exc:
        print(f'{prog}: {exc}', file=sys.stderr)
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
