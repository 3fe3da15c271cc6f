"""Packaging: what importing the package loads, what the wheel holds, and that a real pip
install and a real colcon build each find their data from outside the source tree.

Every install is made from a copy of the files a release ships (``SHIPPED``) in tmp_path, so
no test writes ``build/`` or ``*.egg-info`` into the shared checkout.

Each install compiles the C++ engine (``cpp/``) as a user's would, so the runs of
``collision_sensor_check`` from an install exercise the extension that install built.
"""
import ast
import configparser
import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile

import pytest

import collision_sensor
from collision_sensor.ros import console_scripts

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = 'collision_sensor'
# What a release ships: everything setup.py reads, and nothing else of the checkout.
SHIPPED = ('package.xml', 'setup.py', 'setup.cfg', 'pyproject.toml', 'MANIFEST.in', 'resource',
           'collision_sensor', 'cpp', 'config', 'meshes', 'LICENSE', 'README.md', 'docs')
CONSOLE_SCRIPTS = ('collision_sensor_node', 'collision_sensor_play', 'collision_sensor_check',
                   'collision_sensor_acm', 'collision_sensor_demo', 'collision_sensor_ctl')
ROS_FREE_MODULES = ('collision_sensor', 'collision_sensor.engine.checker',
                    'collision_sensor.sensor', 'collision_sensor.model.sequences',
                    'collision_sensor.tools.acm', 'collision_sensor.tools.offline_check',
                    'collision_sensor.ros.demo',
                    # pytest loads the plugin wherever the package is installed; the public
                    # testing names import ROS only when a sensor is made.
                    'collision_sensor.testing', 'collision_sensor.testing.plugin',
                    # The console script's module installs its signal handlers before it
                    # imports ROS or the engine (see its docstring): it must stay light.
                    'collision_sensor.ros.main')
AMENT_MARKER = 'share/ament_index/resource_index/packages/' + PACKAGE
PY = f'python{sys.version_info.major}.{sys.version_info.minor}'
# Prints where the package and its data were found; run from outside the checkout.
WHERE = ('import collision_sensor, collision_sensor.model.share as s\n'
         'print(collision_sensor.__file__)\n'
         'print(s.share_directory())\n')
#: s: the limit of one install step (a wheel build compiles the engine); it only catches a hang,
#: far above what a build takes on a loaded machine.
TIMEOUT = 1800


def clean_env(**extra):
    """Return the environment minus anything that could point at this checkout or a ROS
    workspace (PYTHONPATH, AMENT_PREFIX_PATH, COLCON_*), plus ``extra``. ``PATH`` loses every
    directory that holds a ``collision_sensor_node`` (this checkout's ``.venv/bin`` when it is
    activated): an install must find its own executables, as it must on a user's machine."""
    env = {key: value for key, value in os.environ.items()
           if key not in ('PYTHONPATH', 'PYTHONHOME', 'AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH')
           and not key.startswith('COLCON_')}
    env['PATH'] = os.pathsep.join(
        entry for entry in env.get('PATH', os.defpath).split(os.pathsep)
        if entry and not os.path.exists(os.path.join(entry, 'collision_sensor_node')))
    env['PYTHONNOUSERSITE'] = '1'
    env.update(extra)
    return env


def run(argv, cwd, env, expect=0):
    """Run ``argv``; fail with its output unless it exits with ``expect``."""
    proc = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=TIMEOUT)
    assert proc.returncode == expect, (
        f'{argv} exited {proc.returncode}, expected {expect}\n'
        f'--- stdout\n{proc.stdout}\n--- stderr\n{proc.stderr}')
    return proc


def copy_shipped(destination):
    """Copy the shipped files of the checkout to ``destination``; return it."""
    junk = shutil.ignore_patterns('__pycache__', '*.pyc', '_engine*.so')  # built by each install
    os.makedirs(destination)
    for name in SHIPPED:
        source = os.path.join(REPO, name)
        if os.path.isdir(source):
            shutil.copytree(source, os.path.join(destination, name), ignore=junk)
        else:
            shutil.copy2(source, destination)
    return str(destination)


def same_path(a, b):
    return os.path.realpath(a) == os.path.realpath(b)


def check_summary(proc, share):
    """Assert that ``collision_sensor_check paper_experiment`` read the bundled sequence from
    ``share`` and found the paper's collisions."""
    out = proc.stdout
    sequence = re.search(r'^sequence:\s+(\S+)', out, re.M)
    assert sequence, out
    assert same_path(sequence.group(1),
                     os.path.join(share, 'config', 'sequences', 'paper_experiment.csv')), out
    assert re.search(r'^frames in collision: [1-9]\d* of \d+', out, re.M), out
    assert 'result: COLLISION' in out, out


# --- 1. importing the package stays free of ROS ---------------------------------------------

PROBE = '''
import importlib, json, sys
importlib.import_module(sys.argv[1])
roots = {name.partition('.')[0] for name in sys.modules}
print(json.dumps(sorted(r for r in roots if r == 'rclpy' or r.startswith('rclpy')
                        or r.endswith(('_msgs', '_srvs', '_interfaces')))))
'''


def ros_modules_loaded_by(module):
    """Return the ROS top-level modules (rclpy, *_msgs, *_srvs, *_interfaces) in
    ``sys.modules`` after importing ``module`` in a fresh interpreter."""
    # From where the package under test is imported: this checkout (editable install), or the
    # install space under colcon test, whose source directory has no compiled engine.
    importing_from = os.path.dirname(os.path.dirname(os.path.abspath(collision_sensor.__file__)))
    proc = run([sys.executable, '-c', PROBE, module], cwd=importing_from, env=clean_env())
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize('module', ROS_FREE_MODULES)
def test_import_loads_no_ros(module):
    assert ros_modules_loaded_by(module) == []


def test_import_probe_sees_ros_when_it_is_loaded():
    # The control: the node does import rclpy and message packages, and the probe says so.
    loaded = ros_modules_loaded_by('collision_sensor.ros.node')
    assert 'rclpy' in loaded
    assert 'sensor_msgs' in loaded


# --- 2. the wheel --------------------------------------------------------------------------

@pytest.fixture(scope='module')
def wheel(tmp_path_factory):
    """Build the wheel from a copy of the shipped files; return its path.

    ``--no-build-isolation`` builds with this venv's setuptools, so the test needs no network.
    """
    root = tmp_path_factory.mktemp('wheel')
    source = copy_shipped(root / 'src')
    run([sys.executable, '-m', 'pip', 'wheel', '--no-deps', '--no-build-isolation',
         '--no-index', '-q', '-w', str(root / 'dist'), source], cwd=str(root), env=clean_env())
    wheels = os.listdir(root / 'dist')
    assert len(wheels) == 1 and wheels[0].endswith('.whl'), wheels
    return str(root / 'dist' / wheels[0])


@pytest.mark.packaging
def test_wheel_holds_the_package_the_data_and_the_ament_marker(wheel):
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    data = {m.group(1) for m in map(re.compile(r'^[^/]+\.data/data/(.+)$').match, names) if m}
    share = f'share/{PACKAGE}/'
    for path in ('package.xml', 'config/collision_sensor.yaml', 'config/demo_arm.urdf',
                 'config/demo_arm.srdf', 'config/demo_scene.yaml',
                 'config/sequences/paper_experiment.csv'):
        assert share + path in data, path
    assert AMENT_MARKER in data
    # Every module of the package, subpackages included (find_packages skips a folder that
    # lost its __init__.py).
    for directory, folders, files in os.walk(os.path.join(REPO, PACKAGE)):
        folders[:] = [folder for folder in folders if folder != '__pycache__']
        for name in files:
            if name.endswith('.py'):
                path = os.path.relpath(os.path.join(directory, name), REPO)
                assert path.replace(os.sep, '/') in names, path
    # Every mesh the demo cell refers to, from the URDF (package://) and the scene (relative).
    with open(os.path.join(REPO, 'config', 'demo_arm.urdf')) as stream:
        meshes = re.findall(r'package://collision_sensor/(meshes/[^"]+)', stream.read())
    with open(os.path.join(REPO, 'config', 'demo_scene.yaml')) as stream:
        meshes += re.findall(r'\.\./(meshes/[^\s,}]+)', stream.read())
    meshes = sorted(set(meshes))
    assert len(meshes) >= 10, meshes
    assert all(mesh.startswith('meshes/demo_cell/') and mesh.endswith('.stl') for mesh in meshes)
    assert [mesh for mesh in meshes if share + mesh not in data] == []


@pytest.mark.packaging
def test_wheel_has_an_entry_point_for_every_console_script(wheel):
    with zipfile.ZipFile(wheel) as archive:
        info = [n for n in archive.namelist() if n.endswith('.dist-info/entry_points.txt')]
        assert len(info) == 1
        entry_points = configparser.ConfigParser()
        entry_points.read_string(archive.read(info[0]).decode())
        scripts = dict(entry_points['console_scripts'])
        assert sorted(scripts) == sorted(CONSOLE_SCRIPTS)
        for name, target in scripts.items():
            # Each target names a module of the wheel that defines the function, the module
            # a tool runs with `python -m` where the script is not installed.
            module, _, function = target.strip().partition(':')
            assert console_scripts.MODULES[name] == module, name
            source = archive.read(module.replace('.', '/') + '.py').decode()
            defined = {node.name for node in ast.parse(source).body
                       if isinstance(node, ast.FunctionDef)}
            assert function in defined, f'{name} = {target}'
        # The testing fixture, for users' own tests (docs/testing.md).
        assert dict(entry_points['pytest11']) == {
            'collision_sensor': 'collision_sensor.testing.plugin'}


# --- 3. a real pip install -----------------------------------------------------------------

def plain_venv(prefix):
    """Make a venv at ``prefix`` that has this venv's packages but not its executables; return
    its python. ``--without-pip``, and one ``.pth`` line naming this venv's site-packages (a
    bare path line: this venv's own ``.pth`` hooks, the editable finder of this checkout among
    them, do not run there, so ``collision_sensor`` is not importable from it)."""
    run([sys.executable, '-m', 'venv', '--without-pip', prefix], cwd=REPO, env=clean_env())
    python = os.path.join(prefix, 'bin', 'python')
    purelib = run([python, '-c', 'import sysconfig; print(sysconfig.get_paths()["purelib"])'],
                  cwd=prefix, env=clean_env()).stdout.strip()
    with open(os.path.join(purelib, '_collision_sensor_test_deps.pth'), 'w') as stream:
        stream.write(sysconfig.get_paths()['purelib'] + '\n')
    return python


@pytest.fixture(scope='module')
def pip_venv(wheel, tmp_path_factory):
    """A venv with the wheel installed (not editable); return its prefix.

    The venv is plain (``--without-pip``; this venv's pip installs into it through
    ``--python``). Our dependencies come from one ``.pth`` line naming this venv's
    site-packages: a bare path line only appends that directory to ``sys.path``, so its own
    ``.pth`` hooks, among them the editable finder that maps ``collision_sensor`` to this
    checkout, do not run, and the wheel's copy is the only ``collision_sensor`` there is.
    (``--system-site-packages`` would not do: it shares the base interpreter's site-packages,
    not this venv's.)
    """
    prefix = str(tmp_path_factory.mktemp('pip') / 'venv')
    python = plain_venv(prefix)
    run([sys.executable, '-m', 'pip', '--python', python, 'install', '--no-deps', '--no-index',
         '--no-compile', '-q', wheel], cwd=prefix, env=clean_env())
    return prefix


@pytest.mark.packaging
def test_pip_install_finds_its_data_under_the_prefix(pip_venv, tmp_path):
    proc = run([os.path.join(pip_venv, 'bin', 'python'), '-c', WHERE], cwd=str(tmp_path),
               env=clean_env())
    module, share = proc.stdout.split()
    assert module.startswith(os.path.join(pip_venv, 'lib')), module  # the wheel's copy
    assert same_path(share, os.path.join(pip_venv, 'share', PACKAGE))


@pytest.mark.packaging
def test_pip_installed_check_finds_the_paper_collisions(pip_venv, tmp_path):
    for name in CONSOLE_SCRIPTS:
        assert os.access(os.path.join(pip_venv, 'bin', name), os.X_OK), name
    proc = run([os.path.join(pip_venv, 'bin', 'collision_sensor_check'), 'paper_experiment'],
               cwd=str(tmp_path), env=clean_env(), expect=1)
    check_summary(proc, os.path.join(pip_venv, 'share', PACKAGE))


# Imports every module of the installed package in a fresh interpreter, recording every import
# of a name outside the product (the benchmarks, the scripts, the peers) as it is attempted,
# with the file whose code asked for it, and reads every installed source for such an import
# anywhere (in a function too: imported lazily). A dependency may import a peer on its own
# (trimesh imports python-fcl when it is installed): the package's own files never do.
IMPORT_ALL = '''
import ast, importlib, importlib.util, json, os, pkgutil, sys
OUTSIDE = ('benchmarks', 'scripts', 'fcl', 'pinocchio', 'coal', 'hppfcl')
attempted = []
class Watch:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name.partition('.')[0] in OUTSIDE:
            frame = sys._getframe(1)
            while frame and frame.f_code.co_filename.startswith('<frozen'):
                frame = frame.f_back
            attempted.append([name, os.path.realpath(frame.f_code.co_filename) if frame
                              else '?'])
        return None
sys.meta_path.insert(0, Watch)
import collision_sensor
root = os.path.realpath(os.path.dirname(collision_sensor.__file__))
modules = [info.name for info in pkgutil.walk_packages(collision_sensor.__path__,
                                                       'collision_sensor.')]
for name in modules:
    importlib.import_module(name)
written = []
for directory, _, files in os.walk(root):
    for file in files:
        if file.endswith('.py'):
            path = os.path.join(directory, file)
            for node in ast.walk(ast.parse(open(path).read(), path)):
                names = ([node.module] if isinstance(node, ast.ImportFrom) and node.module
                         and node.level == 0 else [a.name for a in node.names]
                         if isinstance(node, ast.Import) else [])
                written += [f'{path}: {n}' for n in names if n.partition('.')[0] in OUTSIDE]
sys.meta_path.remove(Watch)
print(json.dumps({'root': root, 'modules': modules, 'attempted': attempted,
                  'written': written, 'sources': sum(len(f) for _, _, f in os.walk(root)),
                  'benchmarks': importlib.util.find_spec('benchmarks') is not None}))
'''


@pytest.mark.packaging
def test_pip_install_imports_no_benchmark_and_no_peer(wheel, pip_venv, tmp_path):
    """The wheel holds the product alone: no module of benchmarks/ (nor scripts/), and no
    module of it imports python-fcl, pinocchio or coal (the benchmarks' peers, test extras),
    at import or anywhere in its code. Every module is imported (those on the ROS graph too:
    rclpy is installed here)."""
    proc = run([os.path.join(pip_venv, 'bin', 'python'), '-c', IMPORT_ALL], cwd=str(tmp_path),
               env=clean_env())
    found = json.loads(proc.stdout.strip().splitlines()[-1])
    assert found['root'].startswith(os.path.join(pip_venv, 'lib')), found['root']
    assert 'collision_sensor.ros.node' in found['modules']     # the walk saw them all
    assert len(found['modules']) >= 60, found['modules']
    by_the_package = [(name, importer) for name, importer in found['attempted']
                      if importer.startswith(found['root'] + os.sep)]
    assert by_the_package == [] and found['written'] == [], found
    assert not found['benchmarks']
    with zipfile.ZipFile(wheel) as archive:
        tops = {name.split('/')[0] for name in archive.namelist()}
    assert {top for top in tops if not top.startswith(PACKAGE)} == set(), tops


@pytest.mark.packaging
def test_the_import_check_sees_a_peer_imported_by_the_package(tmp_path):
    """The control: the same probe, on a copy of the package whose one module imports fcl in
    a function, reports it (read) and, when the module imports it at the top, the attempt."""
    copy = tmp_path / 'site'
    shutil.copytree(os.path.dirname(os.path.abspath(collision_sensor.__file__)),
                    copy / PACKAGE, ignore=shutil.ignore_patterns('__pycache__'))
    with open(copy / PACKAGE / 'errors.py', 'a') as stream:
        stream.write('\n\ndef _peer():\n    import fcl\n    return fcl\n')
    with open(copy / PACKAGE / 'untrusted_text.py', 'a') as stream:
        stream.write('\ntry:\n    import pinocchio  # noqa\nexcept ImportError:\n    pass\n')
    proc = run([sys.executable, '-c', IMPORT_ALL], cwd=str(tmp_path),
               env=clean_env(PYTHONPATH=str(copy)))
    found = json.loads(proc.stdout.strip().splitlines()[-1])
    assert found['root'] == os.path.realpath(copy / PACKAGE)
    assert ['pinocchio', os.path.join(found['root'], 'untrusted_text.py')] in found['attempted']
    assert sorted(line.rsplit(': ', 1)[1] for line in found['written']) == ['fcl', 'pinocchio']


def check_demo(script, share, cwd, env):
    """Run ``script`` (collision_sensor_demo of an install) as a user would; assert that it
    started the node of the same install and played the paper's experiment into it."""
    pytest.importorskip('rclpy')
    import uuid
    namespace = f'/packaging_demo_{uuid.uuid4().hex[:8]}'
    proc = run([script, '--as-fast-as-possible', '--namespace', namespace], cwd=cwd, env=env)
    loaded = re.search(r'robot loaded from urdf_path "([^"]+)"', proc.stdout)
    assert loaded, proc.stdout + proc.stderr
    assert same_path(loaded.group(1), os.path.join(share, 'config', 'demo_arm.urdf'))
    assert re.search(r'frames in collision: [1-9]\d* of 571', proc.stdout), proc.stdout
    assert 'result: COLLISION' in proc.stdout and 'Traceback' not in proc.stderr


@pytest.mark.packaging
def test_pip_installed_demo_starts_the_node_of_its_own_install(pip_venv, tmp_path):
    check_demo(os.path.join(pip_venv, 'bin', 'collision_sensor_demo'),
               os.path.join(pip_venv, 'share', PACKAGE), str(tmp_path), clean_env())


# --- 4. a real colcon build ----------------------------------------------------------------

def colcon_available():
    """True if colcon-core and colcon-ros (the ament_python build type) are installed."""
    import importlib.util
    return all(importlib.util.find_spec(name) is not None
               for name in ('colcon_core', 'colcon_ros'))


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    """``colcon build`` of a workspace holding a copy of the package; return the package's
    install prefix (``install/collision_sensor``, colcon's isolated layout).

    colcon runs with the python of a venv of the workspace's own (:func:`plain_venv`), as in
    the workspace recipe (docs/robots.md): the installed scripts name that python, and nothing
    of this checkout's ``.venv/bin`` lies beside it."""
    if not colcon_available():
        pytest.skip('colcon-core and colcon-ros are not installed in this environment '
                    '(pip install -e ".[test]" brings them)')
    workspace = tmp_path_factory.mktemp('colcon')
    copy_shipped(workspace / 'src' / PACKAGE)
    python = plain_venv(str(workspace / 'venv'))
    colcon = [python, '-c', 'import sys; from colcon_core.command import main; sys.exit(main())']
    # COLCON_HOME in the workspace: no user defaults (e.g. --symlink-install) leak in. The
    # ROS prefix a sourced workspace names on AMENT_PREFIX_PATH: this venv's, where the ROS 2
    # wheels put rcl's headers as a ROS install does (include/rcl/rcl/...).
    env = clean_env(COLCON_HOME=str(workspace / 'colcon_home'), AMENT_PREFIX_PATH=sys.prefix)
    # --base-paths keeps discovery to the workspace, so the one package found is ours
    # (--packages-select would need the colcon-package-selection extension).
    proc = run(colcon + ['--log-base', str(workspace / 'log'), 'build',
                '--base-paths', str(workspace / 'src'),
                '--build-base', str(workspace / 'build'),
                '--install-base', str(workspace / 'install'),
                         '--event-handlers', 'console_direct+'], cwd=str(workspace), env=env)
    assert f'Finished <<< {PACKAGE}' in proc.stdout, proc.stdout
    with open(workspace / 'log' / 'latest_build' / 'logger_all.log') as stream:
        assert f"with type 'ros.ament_python' and name '{PACKAGE}'" in stream.read()
    return str(workspace / 'install' / PACKAGE)


def colcon_env(install, **extra):
    """What ``source install/setup.bash`` sets for this package: its prefix on
    AMENT_PREFIX_PATH and its site-packages on PYTHONPATH."""
    return clean_env(AMENT_PREFIX_PATH=install,
                     PYTHONPATH=os.path.join(install, 'lib', PY, 'site-packages'), **extra)


@pytest.mark.packaging
def test_colcon_install_has_what_ros2_run_and_the_ament_index_need(colcon_install):
    # `ros2 run collision_sensor NAME` runs <prefix>/lib/collision_sensor/NAME.
    for name in CONSOLE_SCRIPTS:
        path = os.path.join(colcon_install, 'lib', PACKAGE, name)
        assert os.path.isfile(path) and os.access(path, os.X_OK), path
    share = os.path.join(colcon_install, 'share', PACKAGE)
    for path in ('package.xml', 'config/collision_sensor.yaml', 'config/demo_arm.urdf',
                 'meshes/demo_cell/washer_drum.stl'):
        assert os.path.isfile(os.path.join(share, path)), path
    assert os.path.isfile(os.path.join(colcon_install, AMENT_MARKER))
    assert os.path.isfile(os.path.join(colcon_install, 'lib', PY, 'site-packages', PACKAGE,
                                       'model', 'share.py'))


@pytest.mark.packaging
def test_colcon_build_against_a_ros_prefix_builds_the_joint_state_hop(colcon_install):
    """With rcl's headers in the prefix colcon builds against, the node's compiled joint-state
    hop is built and installed beside the engine."""
    if not os.path.isfile(os.path.join(sys.prefix, 'include', 'rcl', 'rcl', 'rcl.h')):
        pytest.skip('no rcl headers in this environment (the ROS 2 wheels bring them)')
    ros = os.path.join(colcon_install, 'lib', PY, 'site-packages', PACKAGE, 'ros')
    assert [name for name in os.listdir(ros) if name.startswith('_joint_state_hop')], ros


@pytest.mark.packaging
def test_colcon_install_finds_its_data_through_the_ament_index(colcon_install, tmp_path):
    with open(os.path.join(colcon_install, 'lib', PACKAGE, 'collision_sensor_check')) as script:
        python = script.readline()[2:].strip()   # the interpreter colcon wrote into the shebang
    share = os.path.join(colcon_install, 'share', PACKAGE)
    proc = run([python, '-c', WHERE], cwd=str(tmp_path), env=colcon_env(colcon_install))
    module, found = proc.stdout.split()
    assert module.startswith(colcon_install), module  # the install's copy, not this checkout
    assert same_path(found, share)
    # The control: without the ament index entry the install's data is not found.
    env = colcon_env(colcon_install)
    del env['AMENT_PREFIX_PATH']
    proc = subprocess.run([python, '-c', WHERE], cwd=str(tmp_path), env=env,
                          capture_output=True, text=True, timeout=TIMEOUT)
    assert share not in proc.stdout
    if proc.returncode:  # nothing found at all, rather than another copy of the data
        assert 'FileNotFoundError' in proc.stderr, proc.stderr


@pytest.mark.packaging
def test_colcon_installed_demo_runs_as_ros2_run_would(colcon_install, tmp_path):
    """``ros2 run collision_sensor collision_sensor_demo`` runs this script; the node it
    starts is in the same directory, which install/setup.sh does not put on PATH."""
    check_demo(os.path.join(colcon_install, 'lib', PACKAGE, 'collision_sensor_demo'),
               os.path.join(colcon_install, 'share', PACKAGE), str(tmp_path),
               colcon_env(colcon_install))


@pytest.mark.packaging
def test_colcon_installed_check_finds_the_paper_collisions(colcon_install, tmp_path):
    proc = run([os.path.join(colcon_install, 'lib', PACKAGE, 'collision_sensor_check'),
                'paper_experiment'], cwd=str(tmp_path),
               env=colcon_env(colcon_install), expect=1)
    check_summary(proc, os.path.join(colcon_install, 'share', PACKAGE))


# --- 5. the workspace recipe in docs/robots.md ----------------------------------------------

def workspace_recipe():
    """Return the commands of the workspace recipe in docs/robots.md, continuation lines
    joined."""
    with open(os.path.join(REPO, 'docs', 'robots.md'), encoding='utf-8') as stream:
        text = stream.read()
    section = text.split('## In a ROS 2 workspace', 1)[1].split('\n## ', 1)[0]
    block = section.split('```sh\n', 1)[1].split('```', 1)[0]
    return [line.split('  #')[0].strip() for line in block.replace('\\\n', ' ').splitlines()]


def test_the_workspace_recipe_installs_every_requirement():
    """Its pip line names every requirement of setup.py (install_requires, extras ros and
    test), as the installed metadata lists them, and what colcon needs to build and test."""
    import importlib.metadata
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name
    try:
        required = importlib.metadata.requires(PACKAGE)
    except importlib.metadata.PackageNotFoundError:
        pytest.skip('collision_sensor has no installed metadata here')
    pip, = [line for line in workspace_recipe() if line.startswith('pip install')]
    named = {canonicalize_name(Requirement(word.strip('\'"')).name)
             for word in pip.split()[2:]}
    wanted = {canonicalize_name(Requirement(entry).name) for entry in required}
    assert wanted - named == set(), pip
    assert {'colcon-core', 'colcon-ros', 'setuptools', 'wheel', 'pybind11'} <= named


def test_the_workspace_recipe_keeps_colcon_out_of_its_venv_and_dds_local():
    commands = workspace_recipe()
    venv = [line for line in commands if '-m venv' in line]
    assert venv and 'touch venv/COLCON_IGNORE' in venv[0]
    assert any(line.startswith('export FASTDDS_BUILTIN_TRANSPORTS=SHM ROS_DOMAIN_ID=')
               for line in commands)
    order = ['colcon build', '. install/setup.sh',
             'install/collision_sensor/lib/collision_sensor/collision_sensor_demo',
             'colcon test --event-handlers console_direct+', 'colcon test-result --verbose']
    assert [line for line in commands if line in order] == order
