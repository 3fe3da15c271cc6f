"""Finding a package: explicit paths, the ament index, ROS_PACKAGE_PATH, in that order."""
import os

import pytest

from collision_sensor.model.package_lookup import find_package, package_name_of


def manifest(directory, name):
    directory.mkdir(parents=True, exist_ok=True)
    (directory / 'package.xml').write_text(f'<package format="3"><name>{name}</name></package>')
    return str(directory)


@pytest.fixture(autouse=True)
def no_ros_environment(monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.delenv('ROS_PACKAGE_PATH', raising=False)


def test_the_manifest_name_counts_not_the_folder(tmp_path, monkeypatch):
    found = manifest(tmp_path / 'src' / 'renamed_folder', 'arm_description')
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path / 'src'))
    assert find_package('arm_description') == (found, [
        'package_paths (no entry "arm_description")',
        'ament index (AMENT_PREFIX_PATH is not set)'])
    assert find_package('renamed_folder')[0] is None
    assert package_name_of(found) == 'arm_description'


def test_crawl_skips_ignored_folders_and_does_not_enter_packages(tmp_path, monkeypatch):
    manifest(tmp_path / 'src' / 'ignored' / 'hidden_pkg', 'hidden_pkg')
    (tmp_path / 'src' / 'ignored' / 'COLCON_IGNORE').write_text('')
    outer = manifest(tmp_path / 'src' / 'outer', 'outer')
    manifest(tmp_path / 'src' / 'outer' / 'test' / 'inner', 'inner')
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path / 'src'))
    assert find_package('outer')[0] == outer
    directory, places = find_package('hidden_pkg')
    assert directory is None and f'ROS_PACKAGE_PATH entry {tmp_path / "src"}' in places
    assert find_package('inner')[0] is None   # rospack does not look inside a package


def test_an_entry_may_be_the_package_itself(tmp_path, monkeypatch):
    found = manifest(tmp_path / 'only', 'only')
    monkeypatch.setenv('ROS_PACKAGE_PATH', os.pathsep.join([str(tmp_path / 'none'), found]))
    assert find_package('only')[0] == found


def test_explicit_path_wins_and_ament_prefixes_in_order(tmp_path, monkeypatch):
    for prefix in ('overlay', 'underlay'):
        index = tmp_path / prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
        index.mkdir(parents=True)
        (index / 'pkg').write_text('')
    monkeypatch.setenv('AMENT_PREFIX_PATH', os.pathsep.join(
        [str(tmp_path / 'overlay'), str(tmp_path / 'underlay')]))
    assert find_package('pkg', {'pkg': '/explicit'}) == ('/explicit', [])
    assert find_package('pkg')[0] == str(tmp_path / 'overlay' / 'share' / 'pkg')
