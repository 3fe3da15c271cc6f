"""The advice for a robot whose links are in contact by design: TIAGo from example-robot-data
without its SRDF (51 pairs in contact at zero), and the command it names run as given, whose
SRDF leaves nothing to advise; the Panda with its SRDF needs none."""
import os
import shlex

import pytest

from collision_sensor import CollisionChecker
from collision_sensor.model.example_robots import example_robot_files
from collision_sensor.tools import acm
from collision_sensor.tools.srdf_advice import acm_command, srdf_advice


@pytest.fixture(scope='module')
def tiago():
    robot = next(r for r in example_robot_files() if r.name == 'tiago_description/tiago')
    return robot, [f'{name}={directory}' for name, directory in robot.package_paths.items()]


def test_tiago_without_an_srdf_gets_the_command_that_writes_one(tiago, tmp_path,
                                                                monkeypatch):
    robot, packages = tiago
    checker = CollisionChecker.from_urdf(robot.urdf, package_paths=robot.package_paths)
    advice = srdf_advice(checker, robot.urdf, package_paths=packages)
    assert advice.startswith('robot "tiago": 51 pairs of its own links are in contact by design '
                             '(51 at its zero configuration; ')
    assert ' and 46 more. No SRDF disables them' in advice
    command = advice.split('(a few seconds): ')[1].split('; then start')[0]
    assert command == (f'collision_sensor_acm {shlex.quote(robot.urdf)} --package-path '
                       f'{shlex.quote(packages[0])} --output tiago.srdf')
    assert advice.endswith('srdf_path:=tiago.srdf (or list the pairs in allowed_collisions)')
    # The command as printed, run where the user would: its SRDF leaves nothing to advise.
    monkeypatch.chdir(tmp_path)
    words = shlex.split(command)
    assert words[0] == acm.PROG and acm.main(words[1:] + ['--progress', 'never']) == 0
    fixed = CollisionChecker.from_urdf(robot.urdf, srdf=str(tmp_path / 'tiago.srdf'),
                                       package_paths=robot.package_paths)
    assert srdf_advice(fixed, robot.urdf, str(tmp_path / 'tiago.srdf'), packages) is None


def test_the_panda_with_its_srdf_needs_no_advice(panda_urdf, panda_srdf, erd_package_paths):
    checker = CollisionChecker.from_urdf(panda_urdf, srdf=panda_srdf,
                                         package_paths=erd_package_paths)
    assert srdf_advice(checker, panda_urdf, panda_srdf) is None


def test_the_command_for_an_srdf_to_complete_and_a_description_from_the_topic():
    command, written = acm_command('/robots/my arm.urdf.xacro', '/robots/arm.srdf',
                                   ['arm=/robots/arm description'], ['prefix:=left_'])
    assert written == 'arm_acm.srdf'
    assert shlex.split(command) == [
        'collision_sensor_acm', '/robots/my arm.urdf.xacro', '--package-path',
        'arm=/robots/arm description', '--xacro-arg', 'prefix:=left_', '--srdf',
        '/robots/arm.srdf', '--output', 'arm_acm.srdf']
    command, written = acm_command(b'<robot name="r"/>')
    assert (command, written) == ('collision_sensor_acm robot.urdf --output robot.srdf',
                                  'robot.srdf')
    assert acm_command('a.urdf', package_paths={'p': '/d'}, xacro_args={'x': '1'})[0] == \
        'collision_sensor_acm a.urdf --package-path p=/d --xacro-arg x:=1 --output a.srdf'
    assert os.path.basename(written) == written
