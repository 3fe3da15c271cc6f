"""The robots and scenes the benchmark measures ("cells"), loaded once into plain arrays.

A cell is a robot (URDF, SRDF, package paths) and a static scene. Our checker, pinocchio+coal
and python-fcl are all built from the same cell, and fcl and the scene side of pinocchio from
the very triangles our loader produced, so every implementation checks the same geometry.

Cells:

- ``panda``, ``ur5``: example-robot-data, with their SRDFs, no scene;
- ``demo_arm``: ``config/demo_arm.urdf`` + SRDF in ``config/demo_scene.yaml`` (washer + floor);
- ``demo_arm_washer``: the demo arm and the washer's three parts only (the paper's experiment);
- :func:`terrain_cell`: the Panda and one wavy terrain mesh of a chosen triangle count;
- :func:`user_cell`: the user's robot (``python -m benchmarks --urdf``), no scene.
"""
import os
import re
from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.model.example_robots import example_robot
from collision_sensor.model.robot_model import RobotModel, load_urdf
from collision_sensor.model.scene import SceneObject, load_scene
from collision_sensor.model.share import config_path, share_directory
from collision_sensor.model.srdf import load_srdf

PACKAGE = 'collision_sensor'
WASHER_PARTS = ('washer_cabinet', 'washer_drum', 'washer_door')


@dataclass
class Cell:
    """One robot and its static scene.

    :ivar package_paths: ``{package: directory}`` for our loader.
    :ivar scene: the scene objects (object-frame triangles and ``T_world_object``).
    :ivar pinocchio_package_paths: a mapping whose directories' *parents* hold a folder named
        after each package (what ``pinocchio.buildGeomFromUrdf`` searches), or None if the same
        as ``package_paths``.
    :ivar xacro_args: ``{name: value}`` of a ``.xacro`` URDF.
    :ivar pinocchio_urdf: the URDF pinocchio reads (a ``.xacro`` expanded), or None: ``urdf``.
    """

    name: str
    urdf: str
    srdf: Optional[str]
    package_paths: Dict[str, str]
    scene: Tuple[SceneObject, ...] = ()
    pinocchio_package_paths: Optional[Dict[str, str]] = None
    _model: Optional[RobotModel] = field(default=None, repr=False)
    xacro_args: Optional[Dict[str, str]] = None
    pinocchio_urdf: Optional[str] = None

    def model(self) -> RobotModel:
        """Return the robot model (loaded on first use)."""
        if self._model is None:
            self._model = load_urdf(self.urdf, self.package_paths, xacro_args=self.xacro_args)
        return self._model

    def checker(self, config=None, scene: Optional[Sequence[SceneObject]] = None
                ) -> CollisionChecker:
        """Build a checker on this cell (``scene`` overrides the cell's scene), on one
        thread unless ``config`` says otherwise (its peers run on one core; scenario 11
        measures the threads)."""
        config = {'threads': 1, **dict(config or {})}
        model = self.model()
        srdf = None
        if self.srdf is not None:
            srdf = load_srdf(self.srdf, link_names=model.links,
                             joint_names=[joint.name for joint in model.joints])
        return CollisionChecker(model, srdf, tuple(self.scene if scene is None else scene),
                                config)


def robot_cell(name: str) -> Cell:
    """Return the cell of example robot ``name`` ('panda' or 'ur5'), without a scene."""
    robot = example_robot(name)
    return Cell(name, robot.urdf, robot.srdf, dict(robot.package_paths))


def demo_arm_cell(workdir: str, washer_only: bool = False) -> Cell:
    """Return the demo arm in its scene (or with the washer's parts only).

    pinocchio resolves ``package://collision_sensor/meshes/...`` by looking for a folder named
    ``collision_sensor`` in its package directories; ``workdir`` gets a symlink of that name
    to our share directory.

    :param workdir: an existing temporary directory that outlives the cell.
    """
    link = os.path.join(workdir, PACKAGE)
    if not os.path.lexists(link):
        os.symlink(share_directory(), link)
    scene = load_scene(config_path('demo_scene.yaml'))
    if washer_only:
        scene = tuple(obj for obj in scene if obj.name in WASHER_PARTS)
    return Cell('demo_arm_washer' if washer_only else 'demo_arm',
                config_path('demo_arm.urdf'), config_path('demo_arm.srdf'),
                {PACKAGE: share_directory()}, scene, {PACKAGE: link})


def user_cell(urdf: str, srdf: Optional[str], package_paths: Dict[str, str],
              xacro_args: Optional[Dict[str, str]], workdir: str) -> Cell:
    """Return the user's robot as a cell, loaded (a bad file raises its error here, naming it).

    pinocchio reads the same files: a ``.xacro`` expanded into ``workdir``, and every package
    our loader resolved a ``package://`` mesh in (``package_paths``, the ament index,
    ``ROS_PACKAGE_PATH``, or beside the description) linked as ``workdir/packages/NAME``.

    :param workdir: an existing temporary directory that outlives the cell.
    """
    from collision_sensor.model.xacro_expansion import expand_xacro, is_xacro_path
    cell = Cell(os.path.splitext(os.path.basename(urdf))[0], urdf, srdf, dict(package_paths),
                xacro_args=dict(xacro_args or {}) or None)
    model = cell.model()
    cell.checker()      # the SRDF, checked against the robot now
    cell.name = model.name or cell.name
    if is_xacro_path(urdf):
        cell.pinocchio_urdf = os.path.join(workdir, f'{cell.name}.urdf')
        with open(cell.pinocchio_urdf, 'w', encoding='utf-8') as stream:
            stream.write(expand_xacro(urdf, cell.xacro_args, package_paths))
    cell.pinocchio_package_paths = _linked_packages(model, package_paths, urdf,
                                                    os.path.join(workdir, 'packages'))
    return cell


def _linked_packages(model: RobotModel, package_paths: Dict[str, str], urdf: str,
                     folder: str) -> Dict[str, str]:
    """Link each package our loader found a ``package://`` mesh in as ``folder/NAME``; return
    ``{NAME: link}``."""
    from collision_sensor.model.mesh_loading import resolve_mesh_uri
    base_dir = os.path.dirname(os.path.abspath(urdf))
    links: Dict[str, str] = {}
    for element in model.elements:
        found = re.match(r'mesh (package://([^/\s]+)/(\S+))', element.source)
        if found is None or found.group(2) in links:
            continue
        uri, name, rest = found.groups()
        path = resolve_mesh_uri(uri, package_paths or None, base_dir)
        if not path.endswith(rest):
            continue
        os.makedirs(folder, exist_ok=True)
        links[name] = os.path.join(folder, name)
        if not os.path.lexists(links[name]):
            os.symlink(path[:-len(rest)].rstrip(os.sep) or os.sep, links[name])
    return links


def robot_pair_exceptions(checker: CollisionChecker) -> Tuple[str, ...]:
    """Return ``"a:b"`` for every robot-robot pair ``checker`` checks.

    Given as ``allowed_collisions`` to a checker of the same cell, it leaves only the
    robot-versus-scene pairs.
    """
    scene = set(checker.scene_object_names)
    return tuple(f'{a}:{b}' for a, b in checker.checked_pairs
                 if a not in scene and b not in scene)


def wavy_terrain(triangles: int, x_range=(0.25, 1.0), y_range=(-0.6, 0.6), height=0.3,
                 amplitude=0.08) -> Tuple[np.ndarray, np.ndarray]:
    """Return a wavy height-field grid of about ``triangles`` triangles in the Panda's reach.

    ``z = height + amplitude * sin(9 x) cos(7 y)`` over the rectangle, so that some random
    arm configurations reach through it and others stay above it. The grid starts in front
    of the Panda's base, which it never touches.

    :return: vertices (n, 3) float64 and faces (m, 3) int64, m = 2 k^2 >= ``triangles``.
    """
    k = max(1, int(np.ceil(np.sqrt(triangles / 2.0))))
    x = np.linspace(x_range[0], x_range[1], k + 1)
    y = np.linspace(y_range[0], y_range[1], k + 1)
    X, Y = np.meshgrid(x, y, indexing='ij')
    Z = height + amplitude * np.sin(9.0 * X) * np.cos(7.0 * Y)
    vertices = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    corner = (np.arange(k)[:, None] * (k + 1) + np.arange(k)[None, :]).ravel()
    a, b, c = corner, corner + 1, corner + k + 1
    d = c + 1
    faces = np.concatenate([np.stack([a, c, b], axis=1), np.stack([b, c, d], axis=1)])
    return vertices, faces.astype(np.int64)


def terrain_object(triangles: int, workdir: str) -> SceneObject:
    """Write a wavy terrain to an STL file in ``workdir`` and load it as a scene would.

    The mesh goes through the same loader as a user's scene file (trimesh reading an STL).
    """
    import trimesh
    vertices, faces = wavy_terrain(triangles)
    path = os.path.join(workdir, f'terrain_{len(faces)}.stl')
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    scene = {'objects': [{'name': 'terrain', 'mesh': {'filename': path}}]}
    return load_scene(scene)[0]
