"""Install collision_sensor as an ament_python package (colcon) or a plain pip package."""
import os
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'collision_sensor'


def share_tree(folder):
    """Return data_files entries that install ``folder`` under share/collision_sensor."""
    entries = []
    for directory, _, files in sorted(os.walk(folder)):
        paths = [os.path.join(directory, name) for name in sorted(files)]
        if paths:
            entries.append((os.path.join('share', PACKAGE, directory), paths))
    return entries


setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ] + share_tree('config') + share_tree('meshes'),
    python_requires='>=3.10',
    install_requires=[
        'numpy>=1.24',
        'numba>=0.59',
        'trimesh>=4.0',
        'yourdfpy>=0.0.56',
        'pycollada>=0.8',
        'PyYAML>=6.0',
        'lxml>=4.9',
        'scipy>=1.10',
        'rosbags>=0.10',
        'matplotlib>=3.6',
    ],
    extras_require={
        'ros': [
            'ros-jazzy-rclpy[fastrtps]',
            'ros-jazzy-common-interfaces',
        ],
        'test': [
            'pytest>=7',
            'python-fcl>=0.7',
            'pin>=3.0',
            'example-robot-data>=4.0',
            'colcon-core>=0.21',
            'colcon-ros>=0.5',
        ],
    },
    zip_safe=False,
    maintainer='collision_sensor maintainers',
    maintainer_email='maintainers@collision-sensor.invalid',
    description='Virtual collision sensor for ROS 2 robots: OBB hierarchies, incremental checks.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'collision_sensor_node = collision_sensor.node:main',
            'collision_sensor_play = collision_sensor.player:main',
            'collision_sensor_check = collision_sensor.offline_check:main',
            'collision_sensor_bench = collision_sensor.bench.main:main',
            'collision_sensor_acm = collision_sensor.acm:main',
            'collision_sensor_demo = collision_sensor.demo:main',
        ],
    },
)
