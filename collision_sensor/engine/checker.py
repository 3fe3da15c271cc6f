"""The collision checker: a robot and a static scene, checked on every joint-state update.

This is the API the node, the command-line tools and the benchmarks build on::

    checker = CollisionChecker.from_urdf(urdf, srdf=None, package_paths=None, scene=None,
                                         config=None)
    result = checker.check(positions)    # full check, trusts nothing carried over
    result = checker.update(positions)   # incremental: re-checks only what the motion changed
    result.in_collision, result.colliding_pairs

Everything between ``positions`` and the pair statuses runs in one call into the compiled
engine (``cpp/engine.hpp``: ``Engine::query``, C++17); this module turns files into flat arrays
once, and names back into answers.
"""
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.array_pack import normal_pages
from collision_sensor.engine.checker_clouds import CheckerClouds
from collision_sensor.engine.checker_config import CheckerConfig
from collision_sensor.engine.checker_motion import CheckerMotion
from collision_sensor.engine.checker_queries import (
    _NO_ANSWER, RESULT_CACHE_SIZE, CheckResult, CheckerQueries, Pair, Positions,
    ProximityRecord)
from collision_sensor.engine.checker_scene import CheckerScene
from collision_sensor.engine.dynamic_scene import AddObject, SceneChangeError
from collision_sensor.engine.kinematics import KinematicTree, build_kinematic_tree
from collision_sensor.engine.point_clouds import PointCloudStats
from collision_sensor.engine.robot_block import (
    allowed_names_to_come, build_robot_block, joint_tables, with_virtual_joint, world_frames)
from collision_sensor.engine.scene_layout import SceneLayout
from collision_sensor.errors import SceneError, warn_load
from collision_sensor.model.robot_model import RobotModel, load_urdf
from collision_sensor.model.scene import SceneObject, load_scene
from collision_sensor.model.srdf import Srdf, load_srdf_for_model

__all__ = ['RESULT_CACHE_SIZE', 'CheckResult', 'CollisionChecker', 'Pair', 'Positions',
           'ProximityRecord']


class CollisionChecker(CheckerQueries, CheckerScene, CheckerClouds, CheckerMotion):
    """Self-collision and robot-versus-scene checking for one robot.

    Bodies are the robot's links and the scene objects. The world frame, in which scene poses
    are given, is the root link's frame; with an SRDF whose ``virtual_joint`` is planar or
    floating, it is the virtual joint's ``parent_frame`` (added as a link without geometry above
    the URDF root), and the robot stands where the joint's variables place it. Pairs
    are every two bodies with geometry, robot-robot and robot-scene, minus the exception list
    (adjacent links, SRDF ``disable_collisions``, ``allowed_collisions``). Contact means the
    two bodies' triangle surfaces share a point (touching counts); a body wholly inside another
    without touching its surface is not reported (see docs/engine.md, "Contact rule"). With padding
    (``padding``, ``link_padding`` in the config), each link's geometry is grown by its padding
    (a sphere swept over it): contact means the surfaces come within the two paddings' sum.

    Its methods live in rooms of one concern each: the queries
    (:mod:`~collision_sensor.engine.checker_queries`), the scene
    (:mod:`~collision_sensor.engine.checker_scene`), the point clouds
    (:mod:`~collision_sensor.engine.checker_clouds`) and the motion checks
    (:mod:`~collision_sensor.engine.checker_motion`); this class builds the checker and inspects
    it. What it answers from lives in rooms of their own too: the robot block
    (:mod:`~collision_sensor.engine.robot_block`, built once), the scene laid out for the
    engine (:mod:`~collision_sensor.engine.scene_layout`, by every structural scene change),
    the scene changes (:mod:`~collision_sensor.engine.dynamic_scene`) and the engine itself
    (``cpp/engine.hpp``).
    """

    def __init__(self, model: RobotModel, srdf: Optional[Srdf] = None,
                 scene: Sequence[SceneObject] = (), config=None):
        """Build the hierarchies and the exception list; prefer :meth:`from_urdf`.

        :param scene: world objects at the start (:meth:`add_object` adds more at any time).
        :raises CollisionSensorError: on a bad scene, configuration or exception list.
        """
        self.config = CheckerConfig.from_mapping(config)
        model = self.model = with_virtual_joint(model, srdf)
        self.kinematics: KinematicTree = build_kinematic_tree(model)
        scene = tuple(scene)
        #: Frames a world object's pose may be given in: the root link, and the parent frame of
        #: an SRDF fixed virtual joint (MoveIt's "world" above the robot).
        self.world_frames = world_frames(model, srdf)
        # The robot's trees, link boxes and pairs, and the joints' tables: built once, never
        # again. The scene is laid out by every structural scene change (_install).
        with normal_pages():
            self._robot = build_robot_block(model, self.kinematics, self.config, srdf,
                                            [obj.name for obj in scene])
        self.link_names: Tuple[str, ...] = self._robot.link_names
        self._allowed_to_come, self.config_warnings = allowed_names_to_come(
            self.config, model, self._robot.link_names, [obj.name for obj in scene])
        for line in self.config_warnings:
            warn_load(line)
        self._joints = joint_tables(model, self.kinematics)
        self.joint_names: Tuple[str, ...] = self._joints.names
        self._link_index = {name: i for i, name in enumerate(self.kinematics.link_names)}
        self.joint_limits: Dict[str, Tuple[float, float]] = self._joints.limits
        self._scene: Optional[SceneLayout] = None
        # Counts committed scene changes and moves: prepared changes must be prepared again
        # once it has changed.
        self._scene_version = 0
        self._result = CheckResult(False, (), 0)
        self._results: Dict[bytes, CheckResult] = {}
        # The engine's status_version when _result was made: _result holds while it is the
        # same, whoever ran queries on the engine in between. _answer: the engine's answer
        # object _result was last settled from (the engine gives the same object again for an
        # answer with the same fields).
        self._version = 0
        self._answer = _NO_ANSWER
        # Point clouds: {object name: the engine's VoxelCloud}, and each one's last stats.
        self._clouds: Dict[str, object] = {}
        self._cloud_stats: Dict[str, PointCloudStats] = {}
        try:
            prepared = self.prepare_scene_changes([AddObject(obj) for obj in scene])
        except SceneChangeError as error:
            raise SceneError(f'scene: {error.reason}') from None
        self._install(prepared)

    @classmethod
    def from_urdf(cls, urdf, srdf=None, package_paths: Optional[Mapping[str, str]] = None,
                  scene=None, config=None, xacro_args=None) -> 'CollisionChecker':
        """Load a robot, optionally its SRDF and a static scene, and build the checker.

        :param urdf: path to a URDF file, or the URDF's XML text.
        :param srdf: path or XML text of an SRDF, or None.
        :param package_paths: ``{package_name: directory}`` for ``package://`` mesh URIs.
        :param scene: path to a scene YAML file (or its parsed mapping), or None.
        :param config: mapping of settings (see :mod:`collision_sensor.engine.checker_config`).
        :param xacro_args: ``{name: value}`` for a ``.xacro`` ``urdf``'s ``$(arg name)``.
        :return: the checker; its ``load_warnings`` (tuple of str) are the oddities loading
            tolerated, one line each (each document's also issued as a ``LoadWarning``).
        :raises CollisionSensorError: naming the file, link or setting at fault.
        """
        settings = CheckerConfig.from_mapping(config)
        model = load_urdf(urdf, package_paths, primitive_sections=settings.primitive_sections,
                          xacro_args=xacro_args)
        srdf_model = None
        if srdf is not None:
            srdf_model = load_srdf_for_model(srdf, model)
        objects = ()
        if scene is not None:
            objects = load_scene(scene, package_paths,
                                 primitive_sections=settings.primitive_sections)
        checker = cls(model, srdf_model, objects, settings)
        # What loading tolerated (also issued as LoadWarning), for a caller's own logger.
        checker.load_warnings = tuple(f'URDF: {line}' for line in model.warnings) + tuple(
            f'SRDF: {line}' for line in (srdf_model.warnings if srdf_model else ())) + \
            checker.config_warnings
        return checker

    @property
    def pending_allowed_names(self) -> Tuple[str, ...]:
        """Names ``allowed_collisions`` gives that are no link and no scene object (yet): their
        pairs apply once an object of that name is added; sorted."""
        return tuple(sorted(name for name in self._allowed_to_come
                            if name not in self._scene.objects))

    def packed_array(self, name: str) -> np.ndarray:
        """Return the engine's array ``name`` (``cpp/layout.hpp``: CS_FLOAT_SLOTS,
        CS_INT_SLOTS) as a view of the buffer the engine reads and writes in place: for tests,
        benchmarks and inspection (writing to it changes what the engine sees)."""
        return self._views[name]

    @property
    def paddings(self) -> Dict[str, float]:
        """Each body's padding (m): the robot's links with geometry, and the scene objects
        (never padded: 0)."""
        link_padding = dict(zip(self.kinematics.link_names, self._robot.padding))
        return {**{name: float(link_padding[name]) for name in self.link_names},
                **{name: 0.0 for name in self.scene_object_names}}


    @property
    def positions(self) -> Dict[str, float]:
        """The joint positions of the last check, by name."""
        return {name: float(v) for name, v in zip(self.joint_names, self._q)}

    def link_poses(self) -> Dict[str, np.ndarray]:
        """World poses (4, 4) of every link and scene object at the last checked state."""
        T_world_body = self._poses()
        return {name: T_world_body[b].copy() for b, name in enumerate(self._scene.body_names)}

    def _poses(self) -> np.ndarray:
        """(B, 4, 4) world poses of all bodies, brought up to date (``update`` computes a
        link's pose only when a pair it re-checks needs it)."""
        self._engine.poses()
        return self._T_world_body

    def collision_boxes(self, names: Iterable[str]) -> List[Tuple[str, np.ndarray, np.ndarray]]:
        """Return each sub-group's root box of the named bodies, in the world.

        :param names: link or scene object names; names without geometry give nothing.
        :return: list of ``(name, T_world_box (4, 4), half_extents (3,))``.
        """
        boxes = []
        f = self.forest
        T_world_body = self._poses()
        for name in names:
            b = self._scene.body_index.get(name)
            if b is None:
                continue
            for e in range(self._scene.elem_start[b], self._scene.elem_end[b]):
                node = f.roots[e]
                T_body_box = np.eye(4)
                T_body_box[:3, :3] = f.axes[node]
                T_body_box[:3, 3] = f.center[node]
                boxes.append((name, T_world_body[b] @ T_body_box, f.half[node].copy()))
        return boxes


#: CollisionChecker.check_motion: a method of the class in the compiled engine's fast calling
#: convention (bind_engine.cpp: checker_check_motion), which answers from the checker's engine
#: in one call and leaves everything else to _check_motion (whose docstring it carries).
