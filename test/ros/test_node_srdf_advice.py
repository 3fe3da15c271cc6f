"""The node on a robot whose links are in contact by design warns once, with the command that
writes the SRDF (TIAGo without its SRDF); not on a parameter change that rebuilds the checker,
and not for the Panda with its SRDF."""
import pytest

pytest.importorskip('rclpy')

from collision_sensor.testing import robot_files  # noqa: E402

ADVICE = 'pairs of its own links are in contact by design'


def stderr_now():
    """What this process wrote to stderr so far (capfd's file, read through a descriptor of
    its own: rcutils writes the node's log lines there)."""
    with open('/proc/self/fd/2', 'rb') as stream:
        return stream.read().decode(errors='replace')


def test_tiago_without_its_srdf_is_warned_once_with_the_command(collision_sensor, capfd):
    urdf, _, packages = robot_files('tiago', srdf=False)
    sensor = collision_sensor('tiago', srdf=False, parameters={'stale_timeout': 0.0})
    log = stderr_now()
    assert log.count(ADVICE) == 1 and 'robot "tiago": 51 pairs' in log
    assert f'collision_sensor_acm {urdf} --package-path {packages[0]} --output tiago.srdf' \
        in log
    # Parts in contact at zero are reported so, as the warning says.
    verdict = sensor.send_joint_state(dict.fromkeys(sensor.joint_names, 0.0))
    assert verdict.contact and len(verdict.pairs) == 51
    sensor.set_parameters(padding=0.001)     # a new checker of the same robot: no new warning
    assert stderr_now().count(ADVICE) == 1


def test_the_panda_with_its_srdf_is_not_warned(collision_sensor, capfd):
    collision_sensor('panda')
    assert ADVICE not in stderr_now()
