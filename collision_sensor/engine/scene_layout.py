"""One scene laid out for the engine: its bodies, pairs and packed arrays.

A scene is the robot block (:mod:`collision_sensor.engine.robot_block`, built once) and the
placed objects (:mod:`collision_sensor.engine.dynamic_scene`). Laying it out puts the engine's
arrays (``cpp/layout.hpp``) together from them, by concatenation, without rebuilding a tree:

* bodies: the robot's links, the attached objects (links on fixed joints below theirs), the
  world objects;
* trees: the robot's, then each object's, node and triangle indices shifted;
* pairs: the robot's self-collision pairs, each object against every robot link with
  geometry, attached objects against each other, minus the exception list; a world object is
  always a pair's second body;
* each pair's reach bounds (:mod:`collision_sensor.engine.pair_reach`), kept while its bodies
  keep their place, and each variable's pairs and links.

A new layout takes over the carried state of the one it replaces (:meth:`SceneLayout.carry`):
every pair that survives keeps its status, clearance, travel and witness; new pairs and the
pairs of objects added or moved are forced (the engine re-checks them at the next query).
"""
import dataclasses
from typing import Dict, FrozenSet, Mapping, Sequence, Tuple

import numpy as np

from collision_sensor.engine import array_pack
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.dynamic_scene import PlacedObject
from collision_sensor.engine.kinematics import JOINT_FIXED, KinematicTree
from collision_sensor.engine.obb_tree import NODE_LEFT, NODE_RIGHT
from collision_sensor.engine.pair_reach import EngineTree, pair_rows
from collision_sensor.engine.robot_block import JointTables, RobotBlock
from collision_sensor.model.exception_list import sorted_pair

Pair = Tuple[str, str]
#: The body box of an object without a tree (a point cloud's: its engine writes its own).
EMPTY_BOX = np.zeros((1, engine.BOX_WIDTH))
EMPTY_BOX[0, engine.BOX_AXES:engine.BOX_AXES + 9] = np.eye(3).ravel()
#: A pair's rows: path (J,) int64, reach and reach_ext (J,) float64 (pair_reach.pair_rows).
Rows = Tuple[np.ndarray, np.ndarray, np.ndarray]


class SceneLayout:
    """The engine's arrays for one scene, and the names and indices the checker answers with.

    :ivar objects: ``{name: PlacedObject}`` in the order they were added.
    :ivar body_names: the engine's bodies (links, attached objects, world objects).
    :ivar body_index: ``{name: body}``; ``n_links``: links and attached objects.
    :ivar radius: (B,) float64, each body's largest vertex distance from its origin.
    :ivar elem_start, elem_end: (B,) int64, each body's trees (``roots[start:end]``).
    :ivar checked_pairs: sorted ``(a, b)``; ``pair_a, pair_b``: (P,) int64 their bodies.
    :ivar excluded_pairs: ``{pair: reason}``, the exception list with the objects'.
    :ivar object_pairs: ``{object: (k,) int64 its pairs}``.
    :ivar rows: ``{pair: Rows}``, each checked pair's reach rows.
    :ivar arrays: ``{slot: array}``, every packed array (``cpp/layout.hpp``) until packed.
    """

    def __init__(self, robot: RobotBlock, kin: KinematicTree, joints: JointTables,
                 objects: Mapping[str, PlacedObject], rows: Mapping[Pair, Rows],
                 changed: FrozenSet[str]):
        """Lay out the robot and ``objects``.

        :param rows: reach rows known from the layout before; those of a pair with a body in
            ``changed`` (added, replaced, removed, or attached and moved) are computed again.
        """
        self.objects = dict(objects)
        link_index = {name: i for i, name in enumerate(kin.link_names)}
        attached = [p for p in self.objects.values() if p.attach_to is not None]
        world = [p for p in self.objects.values() if p.attach_to is None]
        placed = attached + world
        # The forest's trees in order (the robot's, then the objects'): names and depths only,
        # no blocks (the objects' arrays are held once, by the engine's buffers: take_views).
        self._placed_names = [p.name for p in placed]
        #: (1 + objects with a tree,) the robot's deepest tree's depth, then each object's.
        self.depths = np.array([robot.depth] + [p.block.depth for p in placed
                                                if p.block.has_tree])
        self.body_names = tuple(kin.link_names) + tuple(p.name for p in placed)
        self.body_index = {name: b for b, name in enumerate(self.body_names)}
        self.n_links = n_links = len(kin.link_names) + len(attached)
        attach_links = np.array([link_index[p.attach_to] for p in attached], dtype=np.int64)
        n_attached = len(attached)
        tree = EngineTree(
            parent=np.concatenate([kin.parent, attach_links]),
            joint_type=np.concatenate([kin.joint_type, np.full(n_attached, JOINT_FIXED)]),
            q_index=np.concatenate([kin.q_index, np.full(n_attached, -1)]),
            multiplier=np.concatenate([kin.multiplier, np.ones(n_attached)]),
            T_parent_joint=np.concatenate(
                [kin.T_parent_joint, np.reshape([p.pose for p in attached], (-1, 4, 4))]))

        # The forest: the robot's trees, then one per object (node and triangle indices
        # shifted by what comes before it).
        self._node_start = node_start = len(robot.boxes) + np.cumsum(
            [0] + [len(p.block.boxes) for p in placed], dtype=np.int64)
        self._tri_start = tri_start = len(robot.tris) + np.cumsum(
            [0] + [p.block.triangles for p in placed], dtype=np.int64)
        # (A point cloud's object has no tree: no element, no triangle; its witness names a
        # voxel of its own, and its pairs are forced when its engine shows it.)
        self.tri_starts = {p.name: int(t0) for p, t0 in zip(placed, tri_start)
                           if p.block.has_tree}
        nodes = [robot.nodes]
        for p, n0, t0 in zip(placed, node_start, tri_start):
            shifted = p.block.nodes + np.array([n0, n0, t0, 0], dtype=np.int64)
            leaf = p.block.nodes[:, NODE_LEFT] < 0
            shifted[leaf, NODE_LEFT:NODE_RIGHT + 1] = -1
            nodes.append(shifted)
        trees = np.array([p.block.has_tree for p in placed], dtype=np.int64)
        first_object_element = len(robot.roots) + np.cumsum(trees) - trees
        self.elem_start = np.concatenate([robot.elem_start, first_object_element])
        self.elem_end = np.concatenate([robot.elem_end, first_object_element + trees])
        with_tree = [p for p in placed if p.block.has_tree]
        self.radius = np.concatenate([robot.radius, [p.block.radius for p in placed]])

        self.checked_pairs, self.excluded_pairs, self.object_pairs = scene_pairs(
            robot, attached, world)
        checked, n_joints = self.checked_pairs, len(joints.names)
        n_pairs = len(checked)
        pair_a = np.empty(n_pairs, dtype=np.int64)
        pair_b = np.empty(n_pairs, dtype=np.int64)
        for p, (a, b) in enumerate(checked):
            ia, ib = self.body_index[a], self.body_index[b]
            pair_a[p], pair_b[p] = (ib, ia) if ia >= n_links else (ia, ib)  # world object second
        # Each pair's rows, computed once and kept while its bodies keep their place.
        kept = {pair: row for pair, row in rows.items()
                if pair[0] not in changed and pair[1] not in changed}
        missing = [p for p, pair in enumerate(checked) if pair not in kept]
        for p, path, reach, reach_ext in zip(missing, *pair_rows(
                tree, self.radius, pair_a[missing], pair_b[missing], n_joints)):
            kept[checked[p]] = (path, reach, reach_ext)
        self.rows = {pair: kept[pair] for pair in checked}
        path = np.reshape([self.rows[pair][0] for pair in checked], (n_pairs, n_joints))
        reach = np.reshape([self.rows[pair][1] for pair in checked], (n_pairs, n_joints))
        reach_ext = np.reshape([self.rows[pair][2] for pair in checked], (n_pairs, n_joints))
        # Each variable's pairs (those with it on their path), as one list cut per variable;
        # each variable's links (whose pose depends on it), attached objects with their link.
        on_path = path.T.nonzero()
        depends = np.concatenate([joints.link_depends, joints.link_depends[:, attach_links]],
                                 axis=1)
        moves = depends.nonzero()

        n_bodies = len(self.body_names)
        T_world_body = np.tile(np.eye(4), (n_bodies, 1, 1))
        for b, p in enumerate(world, start=n_links):
            T_world_body[b] = p.pose
        stale = np.zeros(n_bodies, dtype=np.int64)
        stale[:n_links] = 1
        self.arrays = dict(
            # model
            T_parent_joint=tree.T_parent_joint, axis=np.concatenate(
                [kin.axis, np.tile([0.0, 0.0, 1.0], (n_attached, 1))]),
            multiplier=tree.multiplier,
            offset=np.concatenate([kin.offset, np.zeros(n_attached)]),
            body_boxes=np.concatenate([robot.body_boxes] + [
                p.block.boxes[:1] if p.block.has_tree else EMPTY_BOX for p in placed]),
            padding=np.concatenate([robot.padding, np.zeros(len(placed))]),
            boxes=np.concatenate([robot.boxes] + [p.block.boxes for p in placed]),
            volume=np.concatenate([robot.volume] + [p.block.volume for p in placed]),
            gain=np.concatenate([robot.gain] + [p.block.gain for p in placed]),
            tris=np.concatenate([robot.tris] + [p.block.tris for p in placed]),
            elem_solid=np.concatenate([robot.elem_solid]
                                      + [p.block.solid_row[None] for p in with_tree]),
            reach=reach, reach_ext=reach_ext,
            parent=tree.parent, joint_type=tree.joint_type, q_index=tree.q_index,
            body_elem_start=self.elem_start, body_elem_end=self.elem_end,
            roots=np.concatenate([robot.roots, node_start[:-1][trees.astype(bool)]]),
            nodes=np.concatenate(nodes), pair_a=pair_a, pair_b=pair_b,
            joint_pairs_start=np.searchsorted(on_path[0], np.arange(n_joints + 1)),
            joint_pairs=on_path[1],
            joint_links_start=np.searchsorted(moves[0], np.arange(n_joints + 1)),
            joint_links=moves[1], joint_prismatic=joints.prismatic,
            motion_kind=joints.motion_kind,
            # state: at the neutral configuration, nothing checked, every pair forced
            q_last=kin.neutral(), q_ref=kin.neutral(), extension=np.zeros(1),
            T_world_body=T_world_body, clearance=np.zeros(n_pairs),
            q_eval=np.zeros((n_pairs, n_joints)), travel=np.zeros((n_pairs, 2)),
            query_flags=np.zeros(engine.N_QUERY_FLAGS), stale=stale, status=np.zeros(n_pairs),
            witness=np.full((n_pairs, 2), -1), forced=np.ones(n_pairs),
            # work
            counters=np.zeros(engine.N_COUNTERS), scene_culled=np.zeros((len(world), n_links)),
            nearest=np.full((n_pairs, 2), -1))

    @property
    def pair_a(self) -> np.ndarray:
        return self.arrays['pair_a']

    @property
    def pair_b(self) -> np.ndarray:
        return self.arrays['pair_b']

    def carry(self, old: 'SceneLayout', forced_names: FrozenSet[str]) -> None:
        """Take over the carried state of ``old`` (the layout this one replaces, its arrays
        the engine's views): by the layout's groups, a state slot per pair row by row, per
        body for the links (an attached object's unless it was added or moved), any other
        whole. A witness moves with its object's triangles; forced are the new pairs, the
        pairs of ``forced_names`` (objects added or moved), and those still forced."""
        arrays, previous = self.arrays, old.arrays
        old_index = {pair: p for p, pair in enumerate(old.checked_pairs)}
        new, kept = [], []
        for p, pair in enumerate(self.checked_pairs):
            o = old_index.get(pair)
            if o is not None:
                new.append(p)
                kept.append(o)
        new, kept = np.asarray(new, dtype=np.int64), np.asarray(kept, dtype=np.int64)
        n_robot = len(self.body_names) - len(self.objects)   # the robot's links
        bodies, old_bodies = [], []
        for name, b in self.body_index.items():
            o = old.body_index.get(name)
            if b < self.n_links and o is not None and o < old.n_links and (
                    b < n_robot or name not in forced_names):
                bodies.append(b)
                old_bodies.append(o)
        for slot in array_pack.slots('state'):
            target, source = arrays[slot.name], previous[slot.name]
            if slot.shape[0] == 'pairs':
                target[new] = source[kept]
            elif slot.shape[0] == 'bodies':
                target[bodies] = source[old_bodies]
            else:
                arrays[slot.name] = source.copy()
        # A witness names a triangle of each body: shifted with its object's triangles.
        shift = {name: start - old.tri_starts[name] for name, start in self.tri_starts.items()
                 if name in old.tri_starts and name not in forced_names}
        witness = arrays['witness']
        for p in new:
            a, b = self.checked_pairs[p]
            names = (a, b) if self.body_index[a] == self.pair_a[p] else (b, a)
            if witness[p, 0] >= 0 and all(n in shift or n not in self.tri_starts
                                          for n in names):
                witness[p] += (shift.get(names[0], 0), shift.get(names[1], 0))
            else:
                witness[p] = -1
        arrays['forced'][[p for p, pair in enumerate(self.checked_pairs)
                          if pair not in old_index or pair[0] in forced_names
                          or pair[1] in forced_names]] = 1

    def take_views(self, robot: RobotBlock, views: Mapping[str, np.ndarray]) -> RobotBlock:
        """Keep the packed views as this layout's arrays, and point the robot's block and every
        object's block at their rows of the engine's buffers in place of their own arrays:
        nothing is held twice. Node tables of objects stay their own (the buffer
        holds them shifted); the next scene change reads the trees from these views, which
        keep the buffers alive until then. Return the robot's block so pointed."""
        self.arrays = views
        n_nodes, n_tris = len(robot.boxes), len(robot.tris)
        node_start, tri_start = self._node_start, self._tri_start
        for name, n0, n1, t0, t1 in zip(self._placed_names, node_start[:-1], node_start[1:],
                                        tri_start[:-1], tri_start[1:]):
            p = self.objects[name]
            if not p.block.has_tree:
                continue    # a point cloud's: CLOUD_BLOCK itself, which names it a cloud
            block = dataclasses.replace(
                p.block, boxes=views['boxes'][n0:n1], volume=views['volume'][n0:n1],
                gain=views['gain'][n0:n1], tris=views['tris'][t0:t1])
            self.objects[p.name] = p._replace(block=block)
        return robot._replace(
            boxes=views['boxes'][:n_nodes], nodes=views['nodes'][:n_nodes],
            volume=views['volume'][:n_nodes], gain=views['gain'][:n_nodes],
            tris=views['tris'][:n_tris])

    def tree(self) -> EngineTree:
        """The engine's kinematic arrays as they are now (views)."""
        v = self.arrays
        return EngineTree(v['parent'], v['joint_type'], v['q_index'], v['multiplier'],
                          v['T_parent_joint'])

    def attached_reach(self, name: str, pose: np.ndarray, n_joints: int
                       ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Attached object ``name`` placed at ``pose`` in its link's frame: its pairs and their
        reach rows (its lever arms run through its origin), kept as the pairs' rows."""
        b = self.body_index[name]
        pairs = self.object_pairs[name]
        origins = self.arrays['T_parent_joint'].copy()
        origins[b] = pose
        _, reach, reach_ext = pair_rows(self.tree()._replace(T_parent_joint=origins),
                                        self.radius, self.pair_a[pairs], self.pair_b[pairs],
                                        n_joints)
        for row, p in enumerate(pairs):
            pair = self.checked_pairs[p]
            self.rows[pair] = (self.rows[pair][0], reach[row], reach_ext[row])
        return pairs, reach, reach_ext


def scene_pairs(robot: RobotBlock, attached: Sequence[PlacedObject],
                world: Sequence[PlacedObject]
                ) -> Tuple[Tuple[Pair, ...], Dict[Pair, str], Dict[str, np.ndarray]]:
    """Return the checked pairs (sorted), the exception list and ``{object: its pairs'
    indices}`` for a scene of these objects (see :mod:`collision_sensor.engine.dynamic_scene`):
    an attached object is never checked against its link nor its touch links, nor against an
    object on the same link or one of those; world objects never against each other."""
    excluded = dict(robot.exclusions)
    pairs = list(robot.pairs)
    for i, placed in enumerate(attached):
        name, link = placed.name, placed.attach_to
        for other in robot.link_names:
            pair = sorted_pair(name, other)
            if other == link:
                excluded.setdefault(pair, f'attached to {link}')
            elif other in placed.touch_links:
                excluded.setdefault(pair, 'touch link')
            elif pair not in excluded:
                pairs.append(pair)
        for other in attached[i + 1:]:
            pair = sorted_pair(name, other.name)
            if other.attach_to in (link,) + placed.touch_links or (link in other.touch_links):
                excluded.setdefault(pair, 'attached to the same or touching links')
            elif pair not in excluded:
                pairs.append(pair)
    movers = list(robot.link_names) + [placed.name for placed in attached]
    for placed in world:
        for other in movers:
            pair = sorted_pair(placed.name, other)
            if other in placed.touch_links:     # a table under the base
                excluded.setdefault(pair, 'touch link')
            elif pair not in excluded:
                pairs.append(pair)
    checked = tuple(sorted(pairs))
    object_pairs = {name: [] for name in [p.name for p in attached] + [p.name for p in world]}
    for p, (a, b) in enumerate(checked):
        for name in (a, b):
            if name in object_pairs:
                object_pairs[name].append(p)
    return checked, excluded, {name: np.asarray(indices, dtype=np.int64)
                               for name, indices in object_pairs.items()}


def changed_objects(base: Mapping[str, PlacedObject], objects: Mapping[str, PlacedObject],
                    moved: FrozenSet[str], rebuilt: FrozenSet[str]) -> FrozenSet[str]:
    """The objects whose pairs' reach rows a change makes stale: added or replaced, removed,
    and attached ones moved in their link (their lever arms run through their origin)."""
    return frozenset(rebuilt | (base.keys() - objects.keys()) | {
        name for name in moved if objects[name].attach_to is not None})

