"""share: the data lookup in each layout (source tree, colcon/ament index, pip prefix), its
order, and the error of a broken install, on directories built in tmp_path.

The real installs (a wheel in a venv, a colcon build) are exercised in ``test_packaging``.
"""
import os
import sys

import pytest

from collision_sensor.model import share

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def make_package_data(directory):
    """Create what an install puts in ``share/collision_sensor``; return ``directory``."""
    os.makedirs(os.path.join(directory, 'config'))
    os.makedirs(os.path.join(directory, 'meshes'))
    with open(os.path.join(directory, 'package.xml'), 'w') as stream:
        stream.write('<package format="3"><name>collision_sensor</name></package>\n')
    with open(os.path.join(directory, 'config', 'collision_sensor.yaml'), 'w') as stream:
        stream.write('{}\n')
    return str(directory)


def make_colcon_prefix(prefix, with_data=True):
    """Create a colcon install prefix that registers the package in the ament index."""
    marker = os.path.join(prefix, 'share', 'ament_index', 'resource_index', 'packages')
    os.makedirs(marker)
    open(os.path.join(marker, 'collision_sensor'), 'w').close()
    if with_data:
        make_package_data(os.path.join(prefix, 'share', 'collision_sensor'))
    return str(prefix)


def make_pip_prefix(prefix):
    make_package_data(os.path.join(prefix, 'share', 'collision_sensor'))
    return str(prefix)


@pytest.fixture
def site_packages(tmp_path):
    """An installed package's parent: holds a stray ``config/`` (as some wheels leave) but no
    ``package.xml``, so it must not be taken for a source tree."""
    path = tmp_path / 'site-packages'
    os.makedirs(path / 'config')
    os.makedirs(path / 'collision_sensor')
    return str(path)


def test_this_checkout_is_found_as_the_source_tree():
    if os.path.dirname(os.path.dirname(os.path.abspath(share.__file__))) != \
            os.path.join(REPO, 'collision_sensor'):
        pytest.skip('the package under test is an install (colcon test), not this checkout')
    assert share.SOURCE_ROOT == REPO
    assert share.share_directory() == REPO
    assert os.path.isfile(share.config_path('collision_sensor.yaml'))
    assert share.config_path('demo_arm.urdf') == os.path.join(REPO, 'config', 'demo_arm.urdf')
    assert os.path.isdir(os.path.join(share.mesh_directory(), 'demo_cell'))


def test_source_tree_wins_over_both_installs(tmp_path):
    root = make_package_data(tmp_path / 'repo')
    colcon = make_colcon_prefix(tmp_path / 'install')
    pip = make_pip_prefix(tmp_path / 'venv')
    assert share.find_share_directory(root, colcon, pip) == root


def test_pip_layout_is_found_under_the_prefix(tmp_path, site_packages):
    pip = make_pip_prefix(tmp_path / 'venv')
    found = share.find_share_directory(site_packages, '', pip)
    assert found == os.path.join(pip, 'share', 'collision_sensor')


def test_pip_prefix_defaults_to_sys_prefix(tmp_path, site_packages, monkeypatch):
    pip = make_pip_prefix(tmp_path / 'venv')
    monkeypatch.setattr(sys, 'prefix', pip)
    found = share.find_share_directory(site_packages, '')
    assert found == os.path.join(pip, 'share', 'collision_sensor')


def test_colcon_layout_is_found_through_the_ament_index(tmp_path, site_packages):
    unrelated = tmp_path / 'opt_ros_jazzy'
    os.makedirs(unrelated / 'share' / 'ament_index' / 'resource_index' / 'packages')
    colcon = make_colcon_prefix(tmp_path / 'install' / 'collision_sensor')
    pip = make_pip_prefix(tmp_path / 'venv')
    path = os.pathsep.join(['', str(unrelated), colcon])
    found = share.find_share_directory(site_packages, path, pip)
    # The ament index wins over the pip prefix (here the interpreter's own venv).
    assert found == os.path.join(colcon, 'share', 'collision_sensor')


def test_ament_prefix_path_defaults_to_the_environment(tmp_path, site_packages, monkeypatch):
    colcon = make_colcon_prefix(tmp_path / 'install')
    monkeypatch.setenv('AMENT_PREFIX_PATH', colcon)
    found = share.find_share_directory(site_packages, prefix=str(tmp_path / 'empty'))
    assert found == os.path.join(colcon, 'share', 'collision_sensor')


def test_first_registering_prefix_wins_as_in_ament_index_python(tmp_path):
    overlay = make_colcon_prefix(tmp_path / 'overlay')
    underlay = make_colcon_prefix(tmp_path / 'underlay')
    assert share.ament_share_directory(os.pathsep.join([overlay, underlay])) == \
        os.path.join(overlay, 'share', 'collision_sensor')
    assert share.ament_share_directory(os.pathsep.join([underlay, overlay])) == \
        os.path.join(underlay, 'share', 'collision_sensor')


def test_prefix_without_the_marker_is_not_registered(tmp_path):
    # Data alone does not register a package; the marker file does.
    unregistered = make_pip_prefix(tmp_path / 'prefix')
    assert share.ament_share_directory(unregistered) is None
    assert share.ament_share_directory('') is None


def test_registered_prefix_without_data_falls_through_to_pip(tmp_path, site_packages):
    colcon = make_colcon_prefix(tmp_path / 'install', with_data=False)
    pip = make_pip_prefix(tmp_path / 'venv')
    found = share.find_share_directory(site_packages, colcon, pip)
    assert found == os.path.join(pip, 'share', 'collision_sensor')


def test_config_without_package_xml_does_not_count(tmp_path, site_packages):
    # The stray site-packages/config/ of the fixture, and an install that lost package.xml.
    pip = make_pip_prefix(tmp_path / 'venv')
    os.remove(os.path.join(pip, 'share', 'collision_sensor', 'package.xml'))
    with pytest.raises(FileNotFoundError):
        share.find_share_directory(site_packages, '', pip)


def test_broken_install_names_every_place_looked_and_the_fix(tmp_path, site_packages):
    colcon = make_colcon_prefix(tmp_path / 'install', with_data=False)
    pip = str(tmp_path / 'venv')
    with pytest.raises(FileNotFoundError) as error:
        share.find_share_directory(site_packages, colcon, pip)
    message = str(error.value)
    assert site_packages in message
    assert os.path.join(colcon, 'share', 'collision_sensor') in message
    assert os.path.join(pip, 'share', 'collision_sensor') in message
    assert 'reinstall' in message and 'colcon build' in message


def test_public_functions_raise_on_a_broken_install(tmp_path, site_packages, monkeypatch):
    monkeypatch.setattr(share, 'SOURCE_ROOT', site_packages)
    monkeypatch.setattr(sys, 'prefix', str(tmp_path / 'venv'))
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    for call in (share.share_directory, share.mesh_directory,
                 lambda: share.config_path('collision_sensor.yaml')):
        with pytest.raises(FileNotFoundError, match='collision_sensor: package.xml and config/'):
            call()
