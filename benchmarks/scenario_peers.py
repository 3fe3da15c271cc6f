"""The peers, set up on a cell to check exactly the pairs our checker checks.

- pinocchio+coal: :class:`benchmarks.peers.PinocchioPeer` (its own URDF parsing,
  FK and mesh loading), with the scene's triangles added as coal BVHs (OBBRSS) fixed to the
  universe joint, and its collision pairs replaced by the geometry pairs of our checked link
  pairs. One ``computeCollisions`` call per configuration: FK, placements, every pair.
- python-fcl: :class:`FclCell`, one ``fcl.BVHModel`` (OBBRSS) per collision element and scene
  object, built from the triangles our loader produced; one ``fcl.collide`` per pair from
  Python, as :class:`benchmarks.peers.FclPeer` does, stopping at a link
  pair's first colliding sub-group. It is placed either with our kinematics' poses (FK not
  counted) or with pinocchio's FK (:class:`PinocchioFkFcl`, FK counted).

A peer that is not installed raises ImportError here; callers report it as missing.
"""
from typing import Dict, FrozenSet, Iterable, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.model.scene import SceneObject
from benchmarks.peers import PinocchioPeer

Pair = Tuple[str, str]


def pinocchio_peer(cell, checker: CollisionChecker) -> PinocchioPeer:
    """Return pinocchio+coal on ``cell``, checking the geometry pairs of ``checker``'s pairs.

    :raises ImportError: pinocchio (or coal) is not installed.
    """
    import coal
    import pinocchio as pin
    peer = PinocchioPeer(cell.pinocchio_urdf or cell.urdf, cell.srdf,
                         cell.pinocchio_package_paths or cell.package_paths)
    geom = peer.geom
    owners = [peer.model.frames[g.parentFrame].name for g in geom.geometryObjects]
    for obj in cell.scene:
        if obj.name not in checker.scene_object_names:
            continue
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(obj.faces), len(obj.vertices))
        bvh.addVertices(np.ascontiguousarray(obj.vertices, dtype=np.float64))
        bvh.addTriangles(np.ascontiguousarray(obj.faces, dtype=np.int64))
        bvh.endModel()
        T = obj.T_world_object
        placement = pin.SE3(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
        geom.addGeometryObject(pin.GeometryObject(obj.name, 0, 0, placement, bvh))
        owners.append(obj.name)
    wanted = set(checker.checked_pairs)
    geom.removeAllCollisionPairs()
    for i in range(len(owners)):
        for j in range(i + 1, len(owners)):
            if tuple(sorted((owners[i], owners[j]))) in wanted:
                geom.addCollisionPair(pin.CollisionPair(i, j))
    peer.geom_data = pin.GeometryData(geom)
    peer.pair_count = len(geom.collisionPairs)
    peer.owners = owners
    return peer


def pinocchio_colliding_pairs(peer: PinocchioPeer) -> FrozenSet[Pair]:
    """Return the link pairs found colliding by the peer's last ``check``."""
    hits = set()
    for k, pair in enumerate(peer.geom.collisionPairs):
        if peer.geom_data.collisionResults[k].isCollision():
            hits.add(tuple(sorted((peer.owners[pair.first], peer.owners[pair.second]))))
    return frozenset(hits)


def pinocchio_answers(peer: PinocchioPeer, configurations) -> List[FrozenSet[Pair]]:
    """Return the link pairs the peer finds colliding in each of its ``configurations``."""
    answers = []
    for q in configurations:
        peer.check(q)
        answers.append(pinocchio_colliding_pairs(peer))
    return answers


def fcl_answers(cell: 'FclCell', poses) -> List[FrozenSet[Pair]]:
    """Return the link pairs python-fcl finds colliding with the links at each of ``poses``."""
    answers = []
    for P in poses:
        cell.place(P)
        cell.check()
        answers.append(cell.colliding_pairs())
    return answers


def fcl_bvh(vertices: np.ndarray, faces: np.ndarray):
    """Return an ``fcl.BVHModel`` (OBBRSS, fcl's default) over the triangles.

    :param vertices: (n, 3) float.
    :param faces: (m, 3) int.
    """
    import fcl
    model = fcl.BVHModel()
    model.beginModel(len(faces), len(vertices))   # (triangles, vertices): preallocation
    model.addSubModel(np.ascontiguousarray(vertices, dtype=np.float64),
                      np.ascontiguousarray(faces, dtype=np.int32))
    model.endModel()
    return model


class FclCell:
    """python-fcl on a cell: the checker's elements and scene objects, the checker's pairs."""

    def __init__(self, checker: CollisionChecker, scene: Sequence[SceneObject] = (),
                 scene_models: Optional[Mapping[str, object]] = None):
        """Build one BVH per collision element and per scene object the checker knows.

        :param scene_models: prebuilt BVHs by scene object name (to time their build apart).
        :raises ImportError: python-fcl is not installed.
        """
        import fcl
        self.fcl = fcl
        self.objects: Dict[str, list] = {}
        for element in checker.model.elements:
            T = element.T_link_element
            vertices = element.vertices @ T[:3, :3].T + T[:3, 3]
            self.objects.setdefault(element.link, []).append(
                fcl.CollisionObject(fcl_bvh(vertices, element.faces)))
        self.links = tuple(self.objects)
        scene_models = scene_models or {}
        for obj in scene:
            if obj.name not in checker.scene_object_names:
                continue
            model = scene_models.get(obj.name) or fcl_bvh(obj.vertices, obj.faces)
            T = obj.T_world_object
            self.objects[obj.name] = [fcl.CollisionObject(
                model, fcl.Transform(T[:3, :3].copy(), T[:3, 3].copy()))]
        self.pair_names = tuple(pair for pair in checker.checked_pairs
                                if pair[0] in self.objects and pair[1] in self.objects)
        self.pairs = [(self.objects[a], self.objects[b]) for a, b in self.pair_names]
        self.request = fcl.CollisionRequest()
        self.last_hits = np.zeros(len(self.pairs), dtype=bool)

    def place(self, poses: Mapping[str, np.ndarray]) -> None:
        """Set every link's objects to ``poses[link]`` (4, 4) (scene objects stay put)."""
        Transform = self.fcl.Transform
        for link in self.links:
            T = poses[link]
            transform = Transform(T[:3, :3], T[:3, 3])
            for obj in self.objects[link]:
                obj.setTransform(transform)

    def check(self) -> int:
        """Collide every pair at the placed poses; return the number of colliding pairs."""
        collide, request, Result = self.fcl.collide, self.request, self.fcl.CollisionResult
        hits = self.last_hits
        for p, (objects_a, objects_b) in enumerate(self.pairs):
            hit = False
            for oa in objects_a:
                for ob in objects_b:
                    if collide(oa, ob, request, Result()):
                        hit = True
                        break
                if hit:
                    break
            hits[p] = hit
        return int(hits.sum())

    def colliding_pairs(self) -> FrozenSet[Pair]:
        """Return the pairs found colliding by the last :meth:`check`."""
        return frozenset(pair for pair, hit in zip(self.pair_names, self.last_hits) if hit)


class PinocchioFkFcl:
    """python-fcl placed by pinocchio's FK (``framesForwardKinematics``): FK is counted."""

    def __init__(self, peer: PinocchioPeer, fcl_cell: FclCell):
        import pinocchio as pin
        self.pin = pin
        self.model = peer.model
        self.data = peer.model.createData()
        self.fcl_cell = fcl_cell
        self.frames = [(link, peer.model.getFrameId(link)) for link in fcl_cell.links]

    def check(self, q: np.ndarray) -> int:
        """Run FK for pinocchio's ``q``, place the links, collide every pair."""
        self.pin.framesForwardKinematics(self.model, self.data, q)
        Transform = self.fcl_cell.fcl.Transform
        oMf, objects = self.data.oMf, self.fcl_cell.objects
        for link, frame in self.frames:
            M = oMf[frame]
            transform = Transform(M.rotation, M.translation)
            for obj in objects[link]:
                obj.setTransform(transform)
        return self.fcl_cell.check()


def optional_peer(build, *args) -> Tuple[Optional[object], Optional[str]]:
    """Return ``(build(*args), None)``, or ``(None, why)`` when the peer is not installed or
    cannot load the robot (a user's robot, ``--urdf``, may hold what a peer does not read)."""
    try:
        return build(*args), None
    except ImportError as exc:
        return None, f'not installed ({exc.name or exc})'
    except Exception as exc:  # noqa: B902 - the peer's own errors, of any type: reported
        first = (str(exc).strip().splitlines() or [''])[0][:160]
        return None, f'could not load the robot ({type(exc).__name__}: {first})'


def agreement(ours: Iterable[FrozenSet[Pair]], theirs: Iterable[FrozenSet[Pair]]) -> str:
    """Return ``"k/n"``: on how many configurations the colliding pair sets are equal."""
    same = total = 0
    for a, b in zip(ours, theirs):
        same += a == b
        total += 1
    return f'{same}/{total}'
