"""The robot block: what the engine reads of the robot that no scene change alters, built once.

From a loaded :class:`~collision_sensor.model.robot_model.RobotModel` and its kinematic tree:

* one OBB tree per collision element (the paper's per-link sub-groups, sec. 2.1, in link
  frames, grown by the link's padding), and each link's box over its elements, computed once:
  "the link and its bounding volume move together";
* the exception list (adjacent links, the SRDF's ``disable_collisions``, the checker's
  ``allowed_collisions``) and the self-collision pairs it leaves;
* the joints' tables: variable names, limits, mimic joints, and for each variable the links
  whose pose depends on it and whether it drives a slider (the incremental rule's inputs).

Every scene (:mod:`collision_sensor.engine.scene_layout`) is laid out from this block and the
scene's objects; the robot's trees are never rebuilt.
"""
import dataclasses
import math
from difflib import SequenceMatcher
from typing import Dict, FrozenSet, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.bounding_volumes import fit_obb
from collision_sensor.engine.checker_config import MAX_THREADS, CheckerConfig, usable_cores
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import cover_solid, solid_radius, solid_row
from collision_sensor.engine.kinematics import JOINT_PRISMATIC, KinematicTree, variables
from collision_sensor.engine.motion import motion_kinds
from collision_sensor.engine.obb_tree import box_table, build_forest, node_table
from collision_sensor.errors import ConfigError, SrdfError
from collision_sensor.model.exception_list import adjacent_pairs, parse_pair_strings, sorted_pair
from collision_sensor.model.robot_model import Joint, RobotModel
from collision_sensor.model.srdf import Srdf

Pair = Tuple[str, str]


class RobotBlock(NamedTuple):
    """What the engine reads of the robot that no scene change alters (built once).

    Trees (``boxes (N, BOX_WIDTH)``, ``nodes (N, NODE_WIDTH)``, ``volume, gain (N,)``,
    ``tris (T, 3, 3)``, ``roots (E,)``, ``depth``, ``elem_solid (E, SOLID_WIDTH)``), each
    link's element range ``elem_start, elem_end (L,)``, box ``body_boxes (L, BOX_WIDTH)``,
    vertex radius ``radius (L,)`` and padding ``padding (L,)`` (metres; its boxes are grown by
    it, see :func:`grow_boxes`); the links with geometry (``link_names``), the exception list
    (``exclusions``: pair -> reason) and the self-collision pairs it leaves (``pairs``).
    """

    boxes: np.ndarray
    nodes: np.ndarray
    volume: np.ndarray
    gain: np.ndarray
    tris: np.ndarray
    roots: np.ndarray
    depth: int
    elem_solid: np.ndarray
    elem_start: np.ndarray
    elem_end: np.ndarray
    body_boxes: np.ndarray
    radius: np.ndarray
    padding: np.ndarray
    link_names: Tuple[str, ...]
    exclusions: Dict[Pair, str]
    pairs: Tuple[Pair, ...]


class JointTables(NamedTuple):
    """The joint variables' names, index, limits and mimic joints, the incremental rule's
    inputs: ``link_depends (J, L) bool`` (link i's pose depends on variable j) and
    ``prismatic (J,) int64`` (how many sliders variable j drives), and ``motion_kind (J,)
    int64``, how each moves along a motion (:func:`~collision_sensor.engine.motion.motion_kinds`)."""

    names: Tuple[str, ...]
    index: Dict[str, int]
    derived: FrozenSet[str]
    limits: Dict[str, Tuple[float, float]]
    link_depends: np.ndarray
    prismatic: np.ndarray
    motion_kind: np.ndarray


def build_robot_block(model: RobotModel, kin: KinematicTree, config: CheckerConfig,
                      srdf: Optional[Srdf], object_names: Sequence[str]) -> RobotBlock:
    """Build the robot's trees, link boxes, exception list and self-collision pairs.

    :param object_names: the scene's objects at the start (an exception list may name them).
    :raises ConfigError: ``link_padding`` names no link of the robot; an exception list names
        an unknown body.
    """
    link_names = list(kin.link_names)
    link_index = {name: i for i, name in enumerate(link_names)}
    n_links = len(link_names)
    meshes, owners, solids = [], [], []
    for element in model.elements:
        meshes.append((_transformed(element.T_link_element, element.vertices), element.faces))
        owners.append(link_index[element.link])
        solids.append(solid_row(element.solid, element.vertices, element.faces,
                                element.T_link_element, config.mesh_containment))
    order = np.argsort(np.asarray(owners, dtype=np.int64), kind='stable')
    meshes = [meshes[i] for i in order]
    elem_solid = (np.array([solids[i] for i in order]) if solids
                  else np.zeros((0, engine.SOLID_WIDTH)))
    owners = np.asarray(owners, dtype=np.int64)[order]
    # every core the process may use: a one-time build (the setting threads is for queries)
    forest = build_forest(meshes, leaf_size=config.leaf_size, fit=config.obb_fit_code,
                          threads=min(usable_cores(), MAX_THREADS))
    counts = np.bincount(owners, minlength=n_links) if len(owners) else np.zeros(
        n_links, dtype=np.int64)
    elem_end = np.cumsum(counts).astype(np.int64)
    elem_start = (elem_end - counts).astype(np.int64)
    for e, root in enumerate(forest.roots):  # roots hold the true solids (cover_solid)
        cover_solid(forest.center[root], forest.axes[root], forest.half[root], elem_solid[e])
        grown = 8.0 * np.prod(forest.half[root])
        if forest.left[root] >= 0:
            forest.gain[root] += grown - forest.volume[root]
        forest.volume[root] = grown
    padding = link_padding(config, model.name, link_names, object_names)
    grow_boxes(forest.half, forest.roots, padding[owners])

    center, axes, half = np.zeros((n_links, 3)), np.tile(np.eye(3), (n_links, 1, 1)), \
        np.zeros((n_links, 3))
    vertex_radius = np.zeros(n_links)
    for b in range(n_links):
        chunk = [meshes[e][0] for e in range(elem_start[b], elem_end[b])]
        if chunk:
            points = np.concatenate(chunk)
            faces = np.concatenate([meshes[e][1] + sum(len(c) for c in chunk[:k])
                                    for k, e in enumerate(range(elem_start[b], elem_end[b]))])
            center[b], axes[b], half[b] = fit_obb(points, config.obb_fit_code, faces=faces)
            vertex_radius[b] = float(np.sqrt((points ** 2).sum(axis=1).max()))
            for e in range(elem_start[b], elem_end[b]):
                cover_solid(center[b], axes[b], half[b], elem_solid[e])
                vertex_radius[b] = max(vertex_radius[b], solid_radius(elem_solid[e]))
            half[b] += padding[b]   # the padded link (see grow_boxes)

    geometric = tuple(name for b, name in enumerate(link_names) if counts[b] > 0)
    exclusions = exception_list(config, model, srdf, link_names, geometric, object_names)
    robot_pairs = [sorted_pair(a, b) for i, a in enumerate(geometric) for b in geometric[i + 1:]]
    return RobotBlock(
        boxes=box_table(forest.center, forest.axes, forest.half),
        nodes=node_table(forest), volume=forest.volume, gain=forest.gain,
        tris=forest.tris, roots=forest.roots, depth=int(forest.depth.max(initial=1)),
        elem_solid=elem_solid, elem_start=elem_start, elem_end=elem_end,
        body_boxes=box_table(center, axes, half), radius=vertex_radius, padding=padding,
        link_names=geometric, exclusions=exclusions,
        pairs=tuple(sorted(pair for pair in robot_pairs if pair not in exclusions)))


def joint_tables(model: RobotModel, kin: KinematicTree) -> JointTables:
    """The joints' names, limits and mimic set, and for each variable the links whose pose
    depends on it and whether it drives a slider (the incremental rule's inputs)."""
    n_links = len(kin.link_names)
    names = tuple(kin.joint_names)
    n_joints = len(names)
    depends = np.zeros((n_joints, n_links), dtype=bool)
    prismatic = np.zeros(n_joints, dtype=np.int64)
    for i in range(n_links):  # parents come first
        if kin.parent[i] >= 0:
            depends[:, i] = depends[:, kin.parent[i]]
        if kin.q_index[i] >= 0:
            depends[variables(kin, i), i] = True
            prismatic[kin.q_index[i]] += kin.joint_type[i] == JOINT_PRISMATIC
    return JointTables(
        names=names, index={name: j for j, name in enumerate(names)},
        derived=frozenset(joint.name for joint in model.joints
                          if joint.mimic is not None and joint.type != 'fixed'),
        limits={name: (float(kin.lower[j]), float(kin.upper[j]))
                for j, name in enumerate(names)},
        link_depends=depends, prismatic=prismatic, motion_kind=motion_kinds(model, names))


def link_padding(config: CheckerConfig, robot_name: str, link_names: List[str],
                 object_names: Sequence[str]) -> np.ndarray:
    """(L,) float64: each robot link's padding (m), from ``padding`` and ``link_padding``;
    scene objects are never padded.

    :raises ConfigError: ``link_padding`` names something that is not a link of the robot.
    """
    padding = np.full(len(link_names), float(config.padding))
    index = {name: i for i, name in enumerate(link_names)}
    for name, metres in config.link_padding:
        if name not in index:
            what = ('is a scene object; only robot links are padded'
                    if name in object_names else
                    f'is not a link of robot "{robot_name}"; links: ' + ', '.join(link_names))
            raise ConfigError(f'setting link_padding: "{name}" {what}')
        padding[index[name]] = metres
    return padding


def exception_list(config: CheckerConfig, model: RobotModel, srdf: Optional[Srdf],
                   link_names: Sequence[str], geometric: Sequence[str],
                   object_names: Sequence[str]) -> Dict[Pair, str]:
    """The pairs never checked, each with its reason: adjacent links (``ignore_adjacent``:
    a link and its nearest ancestor with geometry), the SRDF's ``disable_collisions``, the
    checker's ``allowed_collisions``."""
    excluded: Dict[Pair, str] = {}
    if config.ignore_adjacent:
        parents = {link: None for link in link_names}
        for joint in model.joints:
            parents[joint.child] = joint.parent
        for pair in adjacent_pairs(parents, geometric):
            excluded[pair] = 'adjacent'
    if srdf is not None:
        for entry in srdf.disabled_pairs:
            pair = sorted_pair(entry.link1, entry.link2)
            excluded.setdefault(pair, f'srdf: {entry.reason}' if entry.reason else 'srdf')
    known = set(link_names) | set(object_names)
    # A name that is no link or object yet is kept (pending_allowed_names): a scene object may
    # come by that name.
    for pair in parse_pair_strings(config.allowed_collisions, known, pending=set()):
        excluded.setdefault(pair, 'allowed_collisions')
    return excluded


def allowed_names_to_come(config: CheckerConfig, model: RobotModel, link_names: Sequence[str],
                          object_names: Sequence[str]) -> Tuple[FrozenSet[str], Tuple[str, ...]]:
    """The names ``allowed_collisions`` gives that are no link and no scene object yet (kept
    for an object of that name added later), and a warning line for each naming the closest
    link, so a typo shows."""
    pending: set = set()
    parse_pair_strings(config.allowed_collisions, set(link_names) | set(object_names),
                       pending=pending)
    warnings = tuple(
        f'allowed_collisions: "{name}" is neither a link of robot "{model.name}" nor a scene '
        'object: kept for an object of that name added later; if you meant the link '
        f'"{max(link_names, key=lambda link: SequenceMatcher(None, name, link).ratio())}", '
        'fix the name' for name in sorted(pending))
    return frozenset(pending), warnings


def grow_boxes(half: np.ndarray, roots: np.ndarray, padding: np.ndarray) -> None:
    """Grow every box of tree e by ``padding[e]`` in each half extent, in place.

    A padded element is its geometry swept by a sphere of radius ``padding`` (the Minkowski
    sum); its box grown by the padding along each axis holds that, so every box test and box
    gap of the engine is one of the padded geometry, and only the triangle tests at the leaves
    need the padding itself (``cpp/traversal.hpp``: triangles_within). Trees are contiguous
    node ranges starting at their roots.

    :param half: (N, 3) float64 half extents of the forest's boxes.
    :param roots: (E,) int64 root node of each tree; ``padding``: (E,) float64 metres.
    """
    ends = list(roots[1:]) + [len(half)]
    for start, end, pad in zip(roots, ends, padding):
        if pad > 0.0:
            half[start:end] += pad


def with_virtual_joint(model: RobotModel, srdf: Optional[Srdf]) -> RobotModel:
    """Return ``model`` with the SRDF's planar or floating virtual joint above its root link.

    The virtual joint's ``parent_frame`` becomes the root (a link without geometry) and the
    world frame; its variables come first in ``q``, as in MoveIt's variable order. A fixed
    virtual joint changes nothing (the root link already is the world frame). Only the first
    virtual joint is used (the SRDF loader keeps only those that reach the root link).

    :raises SrdfError: the parent frame is already a link of the robot.
    """
    moving = [joint for joint in (srdf.virtual_joints if srdf is not None else ())
              if joint.type != 'fixed']
    if not moving:
        return model
    virtual = moving[0]
    if model.root_link == virtual.parent_frame and any(
            joint.name == virtual.name for joint in model.joints):
        return model   # already added (a checker built on another checker's model)
    if virtual.parent_frame in model.links:
        raise SrdfError(f'SRDF "{srdf.source}": virtual joint "{virtual.name}" has parent_frame '
                        f'"{virtual.parent_frame}", which is a link of the robot; name the '
                        'world frame differently')
    if any(joint.name == virtual.name for joint in model.joints):
        raise SrdfError(f'SRDF "{srdf.source}": virtual joint "{virtual.name}" has the name of '
                        'a URDF joint; rename it')
    joint = Joint(name=virtual.name, type=virtual.type, parent=virtual.parent_frame,
                  child=virtual.child_link, T_parent_joint=np.eye(4),
                  axis=np.array([0.0, 0.0, 1.0]), lower=-math.inf, upper=math.inf,
                  velocity=0.0, effort=0.0, mimic=None)
    order = model.joint_document_order or tuple(j.name for j in model.joints)
    return dataclasses.replace(
        model, root_link=virtual.parent_frame, links=(virtual.parent_frame,) + model.links,
        joints=(joint,) + model.joints, joint_document_order=(virtual.name,) + order)


def world_frames(model: RobotModel, srdf: Optional[Srdf]) -> FrozenSet[str]:
    """The frames a world object's pose may be given in: the root link, and the parent frame
    of an SRDF fixed virtual joint (MoveIt's "world" above the robot)."""
    return frozenset([model.root_link] + [
        joint.parent_frame for joint in (srdf.virtual_joints if srdf is not None else ())
        if joint.type == 'fixed' and joint.child_link == model.root_link])


def _transformed(T: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(vertices @ T[:3, :3].T + T[:3, 3])
