"""The advice a robot needs when its own links are in contact by design: how many pairs, a few
of them, and the ``collision_sensor_acm`` command that writes the SRDF disabling them.

A URDF alone checks every pair of links but a parent and its child. Many robots' links overlap
where they are mounted together (TIAGo: 51 pairs in contact at zero, among 1,770), so without
an SRDF that disables those pairs the sensor reports contact wherever the robot stands. The
node warns once per robot loaded (:func:`srdf_advice`, found by
:func:`~collision_sensor.engine.sampling.pairs_in_contact_by_design`); the command it prints
is the one to run, with the robot's own paths in it.
"""
import os
import shlex
from typing import Mapping, Optional, Sequence, Union

from collision_sensor.engine.sampling import pairs_in_contact_by_design

PROG = 'collision_sensor_acm'
#: Pairs named in the advice (the count says how many there are).
SHOWN = 5


def acm_command(urdf: Union[str, bytes], srdf: str = '',
                package_paths: Union[Mapping[str, str], Sequence[str]] = (),
                xacro_args: Union[Mapping[str, str], Sequence[str]] = ()) -> tuple:
    """Return ``(command, srdf_written)``: the ``collision_sensor_acm`` command line that
    writes an SRDF for ``urdf`` (merging an existing ``srdf``'s entries), and the file it
    writes.

    :param urdf: the URDF's path, or the document (``robot_description``): then ``robot.urdf``
        stands for it, saved to a file.
    :param package_paths: ``{name: dir}``, or ``name=dir`` entries as the node's parameter.
    :param xacro_args: ``{name: value}``, or ``name:=value`` entries as the node's parameter.
    """
    if isinstance(package_paths, Mapping):
        package_paths = [f'{name}={directory}' for name, directory in package_paths.items()]
    if isinstance(xacro_args, Mapping):
        xacro_args = [f'{name}:={value}' for name, value in xacro_args.items()]
    path = urdf if isinstance(urdf, str) else 'robot.urdf'
    stem = os.path.splitext(os.path.basename(srdf or path))[0].removesuffix('.urdf')
    written = f'{stem}_acm.srdf' if srdf else f'{stem}.srdf'
    words = [PROG, path]
    for entry in package_paths:
        words += ['--package-path', entry]
    for entry in xacro_args:
        words += ['--xacro-arg', entry]
    if srdf:
        words += ['--srdf', srdf]
    words += ['--output', written]
    return ' '.join(shlex.quote(word) for word in words), written


def srdf_advice(checker, urdf: Union[str, bytes], srdf: str = '', package_paths=(),
                xacro_args=()) -> Optional[str]:
    """Return the warning for ``checker``'s robot when pairs of its links are in contact at
    zero, at home or in most sampled configurations; None when none are.

    ``checker`` is only read (:meth:`CollisionChecker.check_batch`: its carried state stays).
    The other arguments are what the robot was loaded from (as the node's parameters, or
    their parsed dicts), for the command (:func:`acm_command`).
    """
    found = pairs_in_contact_by_design(checker)
    pairs = found.pairs
    if not pairs:
        return None
    where = []
    if found.at_zero:
        where.append(f'{len(found.at_zero)} at its zero configuration')
    if found.at_home:
        where.append(f'{len(found.at_home)} at home (zero within the joint limits)')
    if found.mostly:
        where.append(f'{len(found.mostly)} in at least {found.fraction:.0%} of '
                     f'{found.samples} random configurations')
    shown = ', '.join(f'{a}:{b}' for a, b in pairs[:SHOWN])
    more = f' and {len(pairs) - SHOWN} more' if len(pairs) > SHOWN else ''
    command, written = acm_command(urdf, srdf, package_paths, xacro_args)
    source = '' if isinstance(urdf, str) else (
        ' (robot.urdf: the robot_description received, saved to a file)')
    disabled_by = f'the SRDF "{srdf}" does not disable them' if srdf else \
        'no SRDF disables them'
    return (f'robot "{checker.model.name}": {len(pairs)} pairs of its own links are in contact '
            f'by design ({"; ".join(where)}): {shown}{more}. {disabled_by[0].upper()}'
            f'{disabled_by[1:]}, so they are reported in contact wherever the robot stands. '
            f'Write the SRDF that does (a few seconds): {command}{source}; then start the node '
            f'with srdf_path:={written} (or list the pairs in allowed_collisions)')
