"""Install collision_sensor as an ament_python package (colcon) or a plain pip package.

The engine is C++17 (``cpp/``), compiled here into one extension module,
``collision_sensor.engine._engine``, with pybind11: under ``pip install``, ``make`` and
``colcon build`` alike. pybind11 because it builds from a plain setup.py
(``Pybind11Extension``), which colcon's ament_python runs as it is; nanobind wants CMake.
"""
import hashlib
import os
import sys
from glob import glob

from setuptools import find_packages, setup
from setuptools.command.build_ext import build_ext

try:
    from pybind11.setup_helpers import ParallelCompile, Pybind11Extension
except ImportError:  # colcon and 'python setup.py' run without pip's build isolation
    sys.exit('collision_sensor: building the engine needs pybind11 (>= 2.11): '
             '"pip install pybind11", or "apt install python3-pybind11" in a ROS workspace')

PACKAGE = 'collision_sensor'


def share_tree(folder):
    """Return data_files entries that install ``folder`` under share/collision_sensor."""
    entries = []
    for directory, _, files in sorted(os.walk(folder)):
        paths = [os.path.join(directory, name) for name in sorted(files)]
        if paths:
            entries.append((os.path.join('share', PACKAGE, directory), paths))
    return entries


ENGINE_SOURCES = sorted(glob('cpp/*.cpp'))
ENGINE_HEADERS = sorted(glob('cpp/*.hpp') + glob('cpp/*.h'))


def source_digest(paths):
    """Return the SHA-256 of the engine's sources (checked again at import: compiled.py)."""
    sha = hashlib.sha256()
    for path in paths:
        with open(path, 'rb') as source:
            sha.update(os.path.basename(path).encode() + b'\0' + source.read())
    return sha.hexdigest()


# The engine's translation units (one per concern) compile two at a time: setuptools' own
# parallel build runs whole extensions in parallel, and the engine is one extension.
# NPY_NUM_BUILD_JOBS overrides the count, as for numpy's builds.
ParallelCompile('NPY_NUM_BUILD_JOBS', default=min(2, os.cpu_count() or 1)).install()


class BuildEngine(build_ext):
    """Compile the engine (every time); say what to do without a compiler."""

    def build_extensions(self):
        # Always compile: the sources' digest is baked into the module (a macro, which
        # setuptools' timestamp check does not see), so a stale object would carry an old one.
        self.force = True
        try:
            super().build_extensions()
        except Exception as error:  # CompileError, a missing compiler (OSError), ...
            raise SystemExit(
                f'collision_sensor: the C++ engine did not build ({error}). It needs a C++17 '
                'compiler (g++ >= 8 or clang >= 7): "apt install g++" on Debian/Ubuntu, '
                'then run the install again') from error


ENGINE = Pybind11Extension(
    'collision_sensor.engine._engine', ENGINE_SOURCES, include_dirs=['cpp'], cxx_std=17,
    depends=ENGINE_HEADERS,
    define_macros=[('COLLISION_SENSOR_SOURCE_DIGEST',
                    '"%s"' % source_digest(sorted(ENGINE_SOURCES + ENGINE_HEADERS)))],
    extra_compile_args=['-O3', '-Wall', '-Wextra', '-fno-math-errno'])

#: The ROS packages whose headers the joint-state hop includes (rcl and what its headers pull).
RCL_HEADER_PACKAGES = ('rcl', 'rmw', 'rcutils', 'rosidl_runtime_c', 'rosidl_typesupport_interface',
                       'rosidl_dynamic_typesupport', 'type_description_interfaces',
                       'service_msgs', 'builtin_interfaces', 'rcl_yaml_param_parser',
                       'rcl_interfaces')


def rcl_include_dirs():
    """Return the include directories of rcl's headers, or [] when none are found.

    Looked for where ROS 2 puts them: the prefixes of a sourced ROS install or workspace
    (``AMENT_PREFIX_PATH``, ``/opt/ros/$ROS_DISTRO``, ``/opt/ros/jazzy``) and this Python's own
    prefix (the ROS 2 wheels install their headers into a venv's ``include/``).
    """
    prefixes = [entry for entry in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                if entry]
    distro = os.environ.get('ROS_DISTRO')
    prefixes += ([f'/opt/ros/{distro}'] if distro else []) + ['/opt/ros/jazzy', sys.prefix]
    for prefix in prefixes:
        include = os.path.join(prefix, 'include')
        if os.path.isfile(os.path.join(include, 'rcl', 'rcl', 'rcl.h')):
            return [directory for directory in
                    (os.path.join(include, package) for package in RCL_HEADER_PACKAGES)
                    if os.path.isdir(directory)]
    return []


# The node's joint-state hop (cpp/hop): built where rcl's headers are (a ROS install, or the
# ROS 2 wheels installed before this package, as `make` does); without them the node answers
# joint states through rclpy, and says so when it starts.
HOP_INCLUDES = rcl_include_dirs()
HOP = Pybind11Extension(
    'collision_sensor.ros._joint_state_hop', ['cpp/hop/joint_state_hop.cpp'],
    include_dirs=['cpp'] + HOP_INCLUDES, cxx_std=17, depends=['cpp/sensor_api.h'],
    extra_compile_args=['-O2', '-Wall', '-Wextra'], libraries=['dl'])

setup(
    name=PACKAGE,
    version='0.1.0',
    # The package only: benchmarks/, scripts/ and test/ stay in the source tree.
    packages=find_packages(include=[PACKAGE, PACKAGE + '.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ] + share_tree('config') + share_tree('meshes'),
    python_requires='>=3.10',
    install_requires=[
        'numpy>=1.24',
        'trimesh>=4.0',
        'yourdfpy>=0.0.56',
        'pycollada>=0.8',
        'xacro>=2.0',
        'PyYAML>=6.0',
        'lxml>=4.9',
        'scipy>=1.10',
        'rosbags>=0.10',
        'matplotlib>=3.6',
        'tqdm>=4.60',
    ],
    extras_require={
        'ros': [
            'ros-jazzy-rclpy[fastrtps]',
            'ros-jazzy-common-interfaces',
        ],
        # collision_sensor_check --ray: Ray joins or starts a cluster (never a hard requirement)
        'cluster': ['ray>=2.9'],
        # LeRobot datasets (parquet files) for collision_sensor_check
        'parquet': ['pyarrow>=12'],
        'test': [
            'ray>=2.9',        # the audit's tests run a real local Ray cluster
            'pyarrow>=12',     # ... and write LeRobot datasets as LeRobot does
            'pybind11>=2.11',  # the packaging tests build wheels and colcon installs themselves
            'pytest>=7',
            'pytest-xdist>=3.5',    # make test and make check run on every core
            'python-fcl>=0.7',
            'pin>=3.0',
            'example-robot-data>=4.0',
            'colcon-core>=0.21',
            'colcon-ros>=0.5',
            'wheel',    # the packaging tests build a wheel without build isolation
        ],
    },
    ext_modules=[ENGINE] + ([HOP] if HOP_INCLUDES else []),
    cmdclass={'build_ext': BuildEngine},
    zip_safe=False,
    maintainer='collision_sensor maintainers',
    maintainer_email='maintainers@collision-sensor.invalid',
    description='Virtual collision sensor for ROS 2 robots: OBB hierarchies, incremental checks.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'collision_sensor_node = collision_sensor.ros.main:main',
            'collision_sensor_play = collision_sensor.ros.player:main',
            'collision_sensor_check = collision_sensor.tools.offline_check:main',
            'collision_sensor_acm = collision_sensor.tools.acm:main',
            'collision_sensor_demo = collision_sensor.ros.demo:main',
            'collision_sensor_ctl = collision_sensor.ros.ctl:main',
        ],
        # collision_sensor.testing's fixture for users' own tests (docs/testing.md)
        'pytest11': ['collision_sensor = collision_sensor.testing.plugin'],
    },
)
