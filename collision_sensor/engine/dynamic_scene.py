"""Scene changes while the checker runs: objects added, moved, attached and removed.

The scene is a set of named objects. A *world object* is fixed in the world frame (the
checker's root frame); an *attached object* is fixed to a robot link: its pose is given in
that link's frame, it moves with the link, and it is never checked against that link. No object
is checked against its *touch links* (MoveIt's attached bodies: a part in the gripper touches
the fingers; a table under the robot's base touches the base). The
checker (:meth:`CollisionChecker.apply_scene_changes`) takes a sequence of changes::

    AddObject(obj, attach_to=None, touch_links=(), pose=None)   # add, or replace by name
    MoveObject(name, pose)                                      # pose only
    RemoveObject(name)

applied in order and all or nothing: every change is validated and every new tree built
first (:meth:`~CollisionChecker.prepare_scene_changes`, which changes nothing and may run on
another thread while the checker answers queries), then the result replaces the scene at once
(:meth:`~CollisionChecker.commit_scene_changes`). On any error the checker is as it was.

What a change costs (the robot's trees are never rebuilt):

- moving an object writes its pose and marks its pairs for re-check (the engine's ``forced``
  list): the next ``update`` re-checks those pairs and whatever the joints moved, no more;
- adding an object (or replacing one with another shape) builds that object's tree only
  (:func:`build_object_block`), then the engine's tables are put together again from the
  robot's block and the objects' blocks, by concatenation, and every pair that still exists
  keeps its carried state (status, clearance, travel, witness); pairs of the new object are
  forced;
- removing one drops its block and its pairs the same way.

``AddObject`` of a name that exists with the same geometry, link and touch links is a move.

Pairs: every object is checked against every robot link with geometry; attached objects also
against each other (unless both hang on one link, or either's link is a touch link of the
other); world objects are never checked against each other (neither moves by itself). The
checker's exception list (``allowed_collisions``) applies to objects by name.
"""
import math
from dataclasses import dataclass
from typing import (Collection, Dict, FrozenSet, Iterable, Mapping, NamedTuple, Optional, Tuple,
                    Union)

import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.engine.obb_tree import box_table, build_forest, node_table
from collision_sensor.errors import SceneError
from collision_sensor.model import mesh_loading
from collision_sensor.model.mesh_loading import Solid, is_closed_surface
from collision_sensor.model.scene import SceneObject

#: The prefix of a point cloud's object name (``point_clouds``), which no other object may use.
CLOUD_PREFIX = 'cloud/'

#: Largest |coordinate| (m) of an object's vertices and of its position: as the engine's bound
#: on joint translations (PRISMATIC_VALUE_MAX), every coordinate, box and gap computed from
#: them then stays far from overflow (cpp/tolerances.hpp).
MAX_COORDINATE = engine.MAX_COORDINATE
#: A pose's rotation must be orthonormal to within this (max |R^T R - I|), with det +1.
ROTATION_TOLERANCE = engine.ROTATION_TOLERANCE
#: A pose's quaternion of a smaller norm is zero (cpp/tolerances.hpp).
QUATERNION_NORM_MIN = engine.QUATERNION_NORM_MIN
#: The engine's code of each solid kind of the model (cpp/layout.hpp: elem_solid).
SOLID_CODES = {mesh_loading.SOLID_BOX: engine.SOLID_BOX,
               mesh_loading.SOLID_SPHERE: engine.SOLID_SPHERE,
               mesh_loading.SOLID_CYLINDER: engine.SOLID_CYLINDER,
               mesh_loading.SOLID_CLOSED_MESH: engine.SOLID_CLOSED_MESH}


class SceneChangeError(SceneError):
    """A change of a batch that cannot apply; the checker is unchanged.

    :ivar index: the change's position in the batch.
    :ivar reason: what is wrong and the fix, without the position.
    """

    def __init__(self, index: int, reason: str):
        self.index, self.reason = index, reason
        super().__init__(f'scene change {index}: {reason}')


@dataclass(frozen=True, eq=False)
class AddObject:
    """Add ``obj``, or replace the object of that name.

    :ivar obj: the geometry (``vertices``, ``faces`` in the object frame) and its name.
    :ivar attach_to: a robot link: the object moves with it; None: fixed in the world.
    :ivar touch_links: further robot links the object may touch (never checked).
    :ivar pose: (4, 4) the object's pose, in the world frame, or in ``attach_to``'s frame;
        None: ``obj.T_world_object``.
    """

    obj: SceneObject
    attach_to: Optional[str] = None
    touch_links: Tuple[str, ...] = ()
    pose: Optional[np.ndarray] = None


@dataclass(frozen=True, eq=False)
class MoveObject:
    """Give object ``name`` a new pose (in the world, or in its link's frame if attached)."""

    name: str
    pose: np.ndarray


@dataclass(frozen=True, eq=False)
class AddCloud:
    """Add the object of a point cloud (``point_clouds``: ``cloud/<source>``), fixed in the world
    at the identity, its voxels kept by the engine; nothing if it is there already."""

    name: str


@dataclass(frozen=True, eq=False)
class RemoveObject:
    """Remove object ``name``."""

    name: str


SceneChange = Union[AddObject, MoveObject, RemoveObject, AddCloud]


@dataclass(frozen=True, eq=False)
class ObjectBlock:
    """One object's tree and engine rows, built once per shape (the engine's table formats,
    ``cpp/layout.hpp``, ``cpp/obb_tree.hpp``), with node and triangle indices local to it.

    :ivar boxes: (N, BOX_WIDTH) float64 node boxes in the object frame; node 0 is the root.
    :ivar nodes: (N, NODE_WIDTH) int64 left, right (-1 for a leaf), first triangle, count.
    :ivar volume: (N,) float64; ``gain``: (N,) float64 (see ``obb_tree.build_forest``).
    :ivar tris: (T, 3, 3) float64 triangles in leaf order.
    :ivar depth: the tree's depth.
    :ivar solid_row: (SOLID_WIDTH,) float64 what the object fills (``cpp/layout.hpp``).
    :ivar radius: the largest distance of a vertex from the object's origin.
    """

    boxes: np.ndarray
    nodes: np.ndarray
    volume: np.ndarray
    gain: np.ndarray
    tris: np.ndarray
    depth: int
    solid_row: np.ndarray
    radius: float

    @property
    def triangles(self) -> int:
        """How many triangles the object has."""
        return len(self.tris)

    @property
    def has_tree(self) -> bool:
        """False for a point cloud's object, whose geometry the engine keeps itself."""
        return len(self.boxes) > 0


#: The block of a point cloud's object (``point_clouds``): no tree; the engine keeps its voxels
#: (``cpp/voxel_cloud.hpp``) and shows them at the identity pose, in the world frame.
CLOUD_BLOCK = ObjectBlock(
    boxes=np.zeros((0, engine.BOX_WIDTH)), nodes=np.zeros((0, engine.NODE_WIDTH), np.int64),
    volume=np.zeros(0), gain=np.zeros(0), tris=np.zeros((0, 3, 3)), depth=0,
    solid_row=np.zeros(engine.SOLID_WIDTH), radius=0.0)


class PlacedObject(NamedTuple):
    """An object in the scene: geometry, tree, where it is and what it may touch (a tuple:
    a moving object makes a new one at every step, cheaply).

    :ivar pose: (4, 4) read-only, ``T_world_object``, or ``T_link_object`` when attached.
    """

    obj: SceneObject
    block: ObjectBlock
    attach_to: Optional[str]
    touch_links: Tuple[str, ...]
    pose: np.ndarray

    @property
    def name(self) -> str:
        return self.obj.name


def solid_row(solid: Optional[Solid], vertices: np.ndarray, faces: np.ndarray,
              T_body_element: np.ndarray, mesh_containment: bool) -> np.ndarray:
    """The engine's row for one element (``cpp/layout.hpp``: elem_solid, SOLID_*): what it
    fills, in its body's frame: kind, size (3), R (3, 3), t (3), and its test vertex (3),
    ``vertices[faces[0, 0]]`` in the body's frame (the vertex that decides whether the element
    lies in another body's solid). Primitives are solid; a closed mesh is with
    ``mesh_containment``.

    :return: (SOLID_WIDTH,) float64.
    """
    row = np.zeros(engine.SOLID_WIDTH)
    first = np.asarray(vertices, dtype=np.float64)[int(np.asarray(faces)[0, 0])]
    row[engine.SOLID_PROBE:engine.SOLID_PROBE + 3] = (T_body_element[:3, :3] @ first
                                                      + T_body_element[:3, 3])
    if solid is None and mesh_containment and is_closed_surface(faces):
        solid = Solid(mesh_loading.SOLID_CLOSED_MESH)
    if solid is not None:
        row[0] = SOLID_CODES[solid.kind]
        row[1:4] = solid.size
        row[4:13] = T_body_element[:3, :3].ravel()
        row[13:16] = T_body_element[:3, 3]
    return row


def cover_solid(center: np.ndarray, axes: np.ndarray, half: np.ndarray, row: np.ndarray) -> None:
    """Grow a box, in place, to hold the true solid of an element's ``row`` (:func:`solid_row`).

    A primitive's tessellation is inscribed in it (``mesh_loading``), and the engine counts a
    point in the sliver between the two as inside (``cpp/containment.hpp``); a box fitted to
    the triangles alone can leave part of that sliver out, and then a tree's root box or a
    body box would prove apart a pair whose solids meet. So the roots and body boxes hold the
    solids too (the boxes below the root need not: they only prune triangle tests). A closed
    mesh (its solid is its triangles') or no solid: unchanged.

    :param center: (3,) box centre, ``axes``: (3, 3) its axes as columns, ``half``: (3,) its
        half extents, in the element's body frame; ``row``: (SOLID_WIDTH,) float64.
    """
    kind = int(row[0])
    if kind not in (engine.SOLID_BOX, engine.SOLID_SPHERE, engine.SOLID_CYLINDER):
        return
    size = row[1:4]
    R = row[4:13].reshape(3, 3)
    t = row[13:16]
    for k in range(3):
        a = axes[:, k]
        if kind == engine.SOLID_BOX:
            reach = float(np.abs(a @ R) @ size)
        elif kind == engine.SOLID_SPHERE:
            reach = float(size[0])
        else:  # a cylinder along its z: the end discs' rims
            z = float(a @ R[:, 2])
            reach = abs(z) * size[1] + size[0] * math.sqrt(max(0.0, 1.0 - z * z))
        middle = float(a @ (t - center))
        lo = min(-half[k], middle - reach)
        hi = max(half[k], middle + reach)
        center += a * (0.5 * (lo + hi))  # along a_k only: the other axes' projections stay
        half[k] = 0.5 * (hi - lo)


def solid_radius(row: np.ndarray) -> float:
    """Return a bound on the distance from the body frame's origin to any point of the solid
    of ``row`` (0 for none or a closed mesh, whose points are its vertices)."""
    kind = int(row[0])
    size = row[1:4]
    if kind == engine.SOLID_BOX:
        extent = float(np.linalg.norm(size))
    elif kind == engine.SOLID_SPHERE:
        extent = float(size[0])
    elif kind == engine.SOLID_CYLINDER:
        extent = math.hypot(size[0], size[1])
    else:
        return 0.0
    return float(np.linalg.norm(row[13:16])) + extent


def build_object_block(obj: SceneObject, config) -> ObjectBlock:
    """Build the tree of one object and its engine rows (runs without the interpreter lock
    for most of its time: the tree is built in C++).

    :param obj: the object, already checked by :func:`check_geometry`.
    :param config: the checker's :class:`~collision_sensor.engine.checker_config.CheckerConfig`.
    """
    vertices = np.ascontiguousarray(obj.vertices, dtype=np.float64)
    forest = build_forest([(vertices, obj.faces)], leaf_size=config.leaf_size,
                          fit=config.obb_fit_code)
    row = solid_row(obj.solid, vertices, obj.faces, np.eye(4), config.mesh_containment)
    cover_solid(forest.center[0], forest.axes[0], forest.half[0], row)
    grown = 8.0 * np.prod(forest.half[0])
    if forest.left[0] >= 0:
        forest.gain[0] += grown - forest.volume[0]
    forest.volume[0] = grown
    return ObjectBlock(
        boxes=box_table(forest.center, forest.axes, forest.half), nodes=node_table(forest),
        volume=forest.volume, gain=forest.gain, tris=forest.tris,
        depth=int(forest.depth.max()),
        solid_row=row,
        radius=max(float(np.sqrt((vertices ** 2).sum(axis=1).max())), solid_radius(row)))


def check_geometry(obj, owner: str) -> None:
    """Raise :class:`SceneError` unless ``obj`` is a :class:`SceneObject` with at least one
    triangle, finite vertices within :data:`MAX_COORDINATE`, and faces indexing them."""
    if not isinstance(obj, SceneObject):
        raise SceneError(f'{owner}: expected a SceneObject, got {type(obj).__name__}; build '
                         'one with collision_sensor.model.scene.load_scene or SceneObject(...)')
    vertices, faces = np.asarray(obj.vertices), np.asarray(obj.faces)
    if vertices.ndim != 2 or vertices.shape[1:] != (3,) or faces.ndim != 2 or (
            faces.shape[1:] != (3,)) or len(faces) == 0:
        raise SceneError(f'{owner}: vertices {vertices.shape} and faces {faces.shape} must be '
                         '(n, 3) and (m, 3) with m >= 1; give at least one triangle')
    if not np.issubdtype(faces.dtype, np.integer) or faces.min() < 0 or (
            faces.max() >= len(vertices)):
        raise SceneError(f'{owner}: faces must be integer indices of its {len(vertices)} '
                         'vertices; fix the triangle list')
    if not np.isfinite(vertices).all() or np.abs(vertices).max() > MAX_COORDINATE:
        raise SceneError(f'{owner}: vertex coordinates must be finite and within '
                         f'{MAX_COORDINATE:g} m; fix the geometry or its scale')


def checked_pose(pose, owner: str) -> np.ndarray:
    """Return ``pose`` as a read-only (4, 4) float64 rigid transform (a new array).

    :raises SceneError: not (4, 4), not finite, a position beyond :data:`MAX_COORDINATE`, a
        rotation that is not orthonormal with determinant +1 (to
        :data:`ROTATION_TOLERANCE`), or a last row other than (0, 0, 0, 1).
    """
    try:
        T = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f'{owner}: pose is not a (4, 4) array of numbers; give a rigid '
                         'transform') from None
    if T.shape != (4, 4):
        raise SceneError(f'{owner}: pose has shape {T.shape}, not (4, 4); give a rigid '
                         'transform')
    # On the 16 numbers as Python floats: a move is cheap (numpy's small-array calls are not).
    r00, r01, r02, x, r10, r11, r12, y, r20, r21, r22, z, *last = T.ravel().tolist()
    if not all(map(math.isfinite, (r00, r01, r02, x, r10, r11, r12, y, r20, r21, r22, z))):
        raise SceneError(f'{owner}: pose is not finite (NaN or infinity); give a finite '
                         'rigid transform')
    if max(abs(x), abs(y), abs(z)) > MAX_COORDINATE or last != [0.0, 0.0, 0.0, 1.0]:
        raise SceneError(f'{owner}: pose position must lie within {MAX_COORDINATE:g} m and the '
                         'last row be (0, 0, 0, 1); fix the transform')
    # R^T R - I, entry by entry (symmetric: six of them).
    error = max(abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0),
                abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0),
                abs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0),
                abs(r00 * r01 + r10 * r11 + r20 * r21),
                abs(r00 * r02 + r10 * r12 + r20 * r22),
                abs(r01 * r02 + r11 * r12 + r21 * r22))
    det = (r00 * (r11 * r22 - r12 * r21) - r01 * (r10 * r22 - r12 * r20)
           + r02 * (r10 * r21 - r11 * r20))
    if not error <= ROTATION_TOLERANCE or det < 0:
        raise SceneError(f'{owner}: pose rotation is not a rotation (|R^T R - I| = {error:.3g}, '
                         f'determinant {det:.3g}); give an orthonormal matrix with '
                         'determinant +1 (a unit quaternion)')
    T.setflags(write=False)
    return T


def transform_from_xyz_quaternion(xyz, quaternion, owner: str = 'pose') -> np.ndarray:
    """Return the (4, 4) transform of a position and a quaternion ``(x, y, z, w)``.

    The quaternion is normalised (as RViz does); one that is zero or not finite is refused.

    :raises SceneError: a value that is not finite, or a quaternion of norm below
        :data:`QUATERNION_NORM_MIN` (the engine's rule for a floating joint's quaternion).
    """
    x, y, z, w = (float(v) for v in quaternion)
    position = [float(v) for v in xyz]
    if not all(map(math.isfinite, [x, y, z, w] + position)):
        raise SceneError(f'{owner}: position {position} or orientation {[x, y, z, w]} is not '
                         'finite; send finite numbers')
    # Scaled by the largest component first, as the engine does (kinematics.hpp:
    # scaled_quaternion): no square underflows or overflows.
    scale = max(abs(x), abs(y), abs(z), abs(w))
    if scale > 0.0:
        x, y, z, w = x / scale, y / scale, z / scale, w / scale
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not scale * norm >= QUATERNION_NORM_MIN:
        raise SceneError(f'{owner}: orientation quaternion {list(map(float, quaternion))} is '
                         'zero; send a unit quaternion, (0, 0, 0, 1) for no rotation')
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = position
    return T


def cloud_object(name: str) -> 'PlacedObject':
    """The placed object of a point cloud named ``name`` (no triangles; see
    :data:`CLOUD_BLOCK`)."""
    pose = np.eye(4)
    pose.setflags(write=False)
    obj = SceneObject(name=name, source='point cloud', T_world_object=pose,
                      vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64))
    return PlacedObject(obj, CLOUD_BLOCK, None, (), pose)


def same_geometry(a: SceneObject, b: SceneObject) -> bool:
    """True iff the two objects have equal triangles and solid (only the pose may differ)."""
    return a is b or (a.solid == b.solid and np.array_equal(a.faces, b.faces)
                      and np.array_equal(a.vertices, b.vertices))


@dataclass(frozen=True, eq=False)
class PreparedSceneChanges:
    """Scene changes validated, with their trees built, not yet applied
    (:meth:`CollisionChecker.prepare_scene_changes`).

    :ivar checker: the checker they were prepared for.
    :ivar base: the checker's objects they were prepared against (``{name: PlacedObject}``).
    :ivar objects: the objects after the changes.
    :ivar structural: some object is added, replaced or removed (the tables change).
    :ivar moved: objects whose pose alone changed.
    :ivar rebuilt: objects added or replaced.
    :ivar version: the checker's count of scene changes they were prepared at; any change
        committed or object moved since makes them stale.
    """

    checker: object
    base: Mapping[str, PlacedObject]
    objects: Dict[str, PlacedObject]
    structural: bool
    moved: FrozenSet[str]
    rebuilt: FrozenSet[str]
    version: int


class PreparedObjects(NamedTuple):
    """What a batch of changes makes of a scene (:func:`prepare_changes`)."""

    objects: Dict[str, PlacedObject]
    structural: bool
    moved: FrozenSet[str]
    rebuilt: FrozenSet[str]


def prepare_changes(changes: Iterable[SceneChange], base: Mapping[str, PlacedObject],
                    links: Collection[str], world_frames: Collection[str], robot: str,
                    config) -> PreparedObjects:
    """Apply ``changes`` in order to a copy of the objects ``base``, validating each and building
    the trees of the objects added or replaced; nothing else changes.

    :param links: the robot's links (an object may hang on one, and touch others).
    :param world_frames: the frames an object fixed in the world may name as its link.
    :param robot: the robot's name, for messages.
    :param config: the checker's :class:`~collision_sensor.engine.checker_config.CheckerConfig`.
    :raises SceneChangeError: the first change that cannot apply (``index``), naming the
        object and the fix.
    """
    objects = dict(base)
    moved, rebuilt = set(), set()
    structural = False
    for k, change in enumerate(changes):
        try:
            if isinstance(change, AddCloud):
                if change.name not in objects:
                    objects[change.name] = cloud_object(change.name)
                    rebuilt.add(change.name)
                    structural = True
            elif isinstance(change, AddObject):
                placed, same = _placed(change, objects, links, world_frames, robot, config)
                objects[placed.name] = placed
                (moved if same else rebuilt).add(placed.name)
                structural |= not same
            elif isinstance(change, (MoveObject, RemoveObject)):
                name = change.name
                old = objects.get(name)
                if old is None:
                    verb = 'move' if isinstance(change, MoveObject) else 'remove'
                    raise SceneError(f'no object "{name}" to {verb}; add it first '
                                     f'(objects: {", ".join(objects) or "none"})')
                if isinstance(change, MoveObject):
                    if old.block is CLOUD_BLOCK:
                        raise SceneError(f'object "{name}" is a point cloud: its points are '
                                         'given in the world or a link frame and never moved; '
                                         'give its next cloud (set_points)')
                    pose = checked_pose(change.pose, f'object "{name}"')
                    objects[name] = PlacedObject(old.obj, old.block, old.attach_to,
                                                 old.touch_links, pose)
                    moved.add(name)
                else:
                    del objects[name]
                    moved.discard(name)
                    rebuilt.discard(name)
                    structural = True
            else:
                raise SceneError(f'{type(change).__name__} is not a scene change; give '
                                 'AddObject, MoveObject or RemoveObject')
        except SceneError as error:
            raise SceneChangeError(k, str(error)) from None
    return PreparedObjects(objects, structural, frozenset(moved - rebuilt), frozenset(rebuilt))


def _placed(change: AddObject, objects: Mapping[str, PlacedObject], links: Collection[str],
            world_frames: Collection[str], robot: str, config) -> Tuple[PlacedObject, bool]:
    """The object ``change`` adds, and whether it only moves the one of its name."""
    obj = change.obj
    name = getattr(obj, 'name', None)
    if not isinstance(name, str) or not name:
        raise SceneError('the object has no name; give it a unique name')
    owner = f'object "{name}"'
    if name.startswith(CLOUD_PREFIX):
        raise SceneError(f'{owner}: names starting with "{CLOUD_PREFIX}" are the point clouds\'; '
                         'rename the object')
    if name in links or name in world_frames:
        raise SceneError(f'{owner} has the name of a link or frame of robot "{robot}"; rename '
                         'the object')
    check_geometry(obj, owner)
    attach_to = None if change.attach_to in world_frames else change.attach_to
    touch_links = tuple(dict.fromkeys(change.touch_links))
    if attach_to is not None and attach_to not in links:
        raise SceneError(f'{owner}: "{attach_to}" is not a link of robot "{robot}"; attach it '
                         f'to one of its links, or to {" or ".join(sorted(world_frames))} (the '
                         'world)')
    unknown = [link for link in touch_links if link not in links]
    if unknown:
        raise SceneError(f'{owner}: touch link "{unknown[0]}" is not a link of robot '
                         f'"{robot}"; give touch links of the robot')
    pose = checked_pose(obj.T_world_object if change.pose is None else change.pose, owner)
    old = objects.get(name)
    if (old is not None and old.attach_to == attach_to and old.touch_links == touch_links
            and same_geometry(old.obj, obj)):
        return PlacedObject(obj, old.block, attach_to, touch_links, pose), True
    return PlacedObject(obj, build_object_block(obj, config), attach_to, touch_links, pose), False
