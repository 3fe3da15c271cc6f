"""Independent oracles for whole-robot answers: python-fcl on the same triangles, with
pinocchio's kinematics, and a brute-force all-triangle-pairs check.

Primitives are solid (docs/engine.md, "Contact rule"): besides the surfaces, fcl's true primitive
(fcl.Box, fcl.Sphere, fcl.Cylinder) decides whether a vertex of the other body's element lies
inside it; one vertex decides for the whole element once no surfaces meet."""
import os

import numpy as np

import fcl
import pinocchio as pin

from collision_sensor import CollisionChecker
from collision_sensor.engine.dynamic_scene import AddObject, MoveObject
from collision_sensor.model.exception_list import sorted_pair

#: pinocchio's root joint for an SRDF virtual joint, by type.
ROOT_JOINTS = {'floating': pin.JointModelFreeFlyer, 'planar': pin.JointModelPlanar}


class FclOracle:
    """Colliding pairs by python-fcl BVH models built from the meshes the checker loaded.

    Link poses come from pinocchio, not from our kinematics, so the oracle shares only the
    triangles with the engine under test.
    """

    def __init__(self, checker, urdf_path):
        self.checker = checker
        build = pin.buildModelFromUrdf if os.path.exists(urdf_path) else pin.buildModelFromXML
        virtual = checker.model.joints[0] if checker.model.joints else None
        if virtual is not None and virtual.parent == checker.model.root_link and (
                virtual.type in ROOT_JOINTS and 'name="' + virtual.name + '"' not in (
                    open(urdf_path).read() if os.path.exists(urdf_path) else urdf_path)):
            # An SRDF virtual joint above the URDF root: pinocchio's own root joint.
            self.pin_model = build(urdf_path, ROOT_JOINTS[virtual.type](), virtual.name)
        else:
            self.pin_model = build(urdf_path)
        self.pin_data = self.pin_model.createData()
        # BODY: a joint may share its link's name (anymal's LF_HAA). The virtual joint's
        # parent frame is pinocchio's universe (no geometry, so never in a pair).
        self.frame_ids = {name: self.pin_model.getFrameId(name, pin.FrameType.BODY)
                          for name in checker.kinematics.link_names
                          if self.pin_model.existFrame(name, pin.FrameType.BODY)}
        self.models = {}
        self.solids = {}   # body: [(fcl primitive, T_body_element)]
        self.vertices = {}  # body: one vertex per element (faces[0, 0]), in the body frame
        for element in checker.model.elements:
            T = element.T_link_element
            vertices = element.vertices @ T[:3, :3].T + T[:3, 3]
            self.models.setdefault(element.link, []).append(self._bvh(vertices, element.faces))
            self.vertices.setdefault(element.link, []).append(vertices[element.faces[0, 0]])
            if element.solid is not None:
                self.solids.setdefault(element.link, []).append((self._primitive(element.solid),
                                                                 T))
        self.scene_poses = {}
        for name in checker.scene_object_names:
            b = checker._scene.body_index[name]
            start, end = checker._scene.elem_start[b], checker._scene.elem_end[b]
            f = checker.forest
            meshes = []
            for e in range(start, end):
                tris = self._tris_of_tree(f, f.roots[e])
                vertices = tris.reshape(-1, 3)
                faces = np.arange(len(vertices)).reshape(-1, 3)
                meshes.append(self._bvh(vertices, faces))
            self.models[name] = meshes
            self.scene_poses[name] = checker._T_world_body[b].copy()
            # An object has one tree (or none): its own first vertex stands for it, as for links,
            # never the first of our tree's order, which moves with how the tree is split.
            obj = checker.scene_objects[checker.scene_object_names.index(name)]
            self.vertices[name] = [np.asarray(obj.vertices[obj.faces[0, 0]], dtype=np.float64)
                                   for _ in range(start, end)]
            solid = obj.solid
            if solid is not None:
                self.solids[name] = [(self._primitive(solid), np.eye(4))]

    @staticmethod
    def _primitive(solid):
        from collision_sensor.model.mesh_loading import SOLID_BOX, SOLID_SPHERE
        h = solid.size
        if solid.kind == SOLID_BOX:
            return fcl.Box(2 * h[0], 2 * h[1], 2 * h[2])
        if solid.kind == SOLID_SPHERE:
            return fcl.Sphere(h[0])
        return fcl.Cylinder(h[0], 2 * h[1])

    def _solid_vertices(self, a, b, Ta, Tb):
        """Each of a's primitives with its world pose, and each test vertex of b's elements
        in the world: (primitive, T, x)."""
        for primitive, T_local in self.solids.get(a, ()):
            T = Ta @ T_local
            for vertex in self.vertices[b]:
                yield primitive, T, Tb[:3, :3] @ vertex + Tb[:3, 3]

    def _contains(self, a, b, Ta, Tb):
        """A vertex of one of b's elements inside one of a's primitives (fcl decides)."""
        request = fcl.CollisionRequest()
        for primitive, T, x in self._solid_vertices(a, b, Ta, Tb):
            solid = fcl.CollisionObject(primitive, fcl.Transform(T[:3, :3], T[:3, 3]))
            point = fcl.CollisionObject(fcl.Sphere(1e-12), fcl.Transform(np.eye(3), x))
            if fcl.collide(solid, point, request, fcl.CollisionResult()):
                return True
        return False

    def solid_gap(self, poses, a, b):
        """How far a test vertex of one body is from entering a solid primitive of the
        other (0 inside), by the primitives' own measures (inf: no primitive)."""
        Ta, Tb = poses[a], poses[b]
        return min(self._solid_gap(a, b, Ta, Tb), self._solid_gap(b, a, Tb, Ta))

    def _solid_gap(self, a, b, Ta, Tb):
        gap = np.inf
        for primitive, T, x in self._solid_vertices(a, b, Ta, Tb):
            p = T[:3, :3].T @ (x - T[:3, 3])
            if isinstance(primitive, fcl.Box):
                outside = np.maximum(np.abs(p) - 0.5 * np.asarray(primitive.side), 0.0)
                gap = min(gap, float(np.linalg.norm(outside)))
            elif isinstance(primitive, fcl.Sphere):
                gap = min(gap, max(float(np.linalg.norm(p)) - primitive.radius, 0.0))
            else:
                radial = max(float(np.hypot(p[0], p[1])) - primitive.radius, 0.0)
                axial = max(abs(float(p[2])) - 0.5 * primitive.lz, 0.0)
                gap = min(gap, float(np.hypot(radial, axial)))
        return gap

    @staticmethod
    def _tris_of_tree(forest, root):
        stack, tris = [root], []
        while stack:
            n = stack.pop()
            if forest.left[n] < 0:
                tris.append(forest.tris[forest.first[n]:forest.first[n] + forest.count[n]])
            else:
                stack += [forest.left[n], forest.right[n]]
        return np.concatenate(tris)

    @staticmethod
    def _bvh(vertices, faces):
        model = fcl.BVHModel()
        model.beginModel(len(vertices), len(faces))
        model.addSubModel(np.asarray(vertices, dtype=np.float64),
                          np.asarray(faces, dtype=np.int32))
        model.endModel()
        return model

    def link_objects(self, poses, link):
        """fcl objects of ``link`` at ``poses``: its BVH models and its solid primitives."""
        T = poses[link]
        t = fcl.Transform(T[:3, :3], T[:3, 3])
        objects = [fcl.CollisionObject(m, t) for m in self.models[link]]
        for primitive, T_local in self.solids.get(link, ()):
            Tp = T @ T_local
            objects.append(fcl.CollisionObject(primitive, fcl.Transform(Tp[:3, :3], Tp[:3, 3])))
        return objects

    def pin_configuration(self, positions):
        """pinocchio q from our joint vector (mimic joints get their derived value)."""
        from collision_sensor.model.robot_model import resolve_mimics
        q = pin.neutral(self.pin_model)
        values = dict(zip(self.checker.joint_names, positions))
        for name, (source, multiplier, offset) in resolve_mimics(
                self.checker.model.joints).items():
            values[name] = multiplier * values[source] + offset
        for name in self.pin_model.names[1:]:
            joint = self.pin_model.joints[self.pin_model.getJointId(name)]
            i = joint.idx_q
            if joint.nq == 7:   # free flyer: (x, y, z, qx, qy, qz, qw), a unit quaternion
                quaternion = np.array([values[f'{name}/rot_{a}'] for a in 'xyzw'])
                q[i:i + 3] = [values[f'{name}/trans_{a}'] for a in 'xyz']
                q[i + 3:i + 7] = quaternion / np.linalg.norm(quaternion)
            elif joint.nq == 4:   # planar: (x, y, cos theta, sin theta)
                theta = values[f'{name}/theta']
                q[i:i + 4] = values[f'{name}/x'], values[f'{name}/y'], np.cos(theta), np.sin(theta)
        for name, value in values.items():
            if self.pin_model.existJointName(name):
                joint = self.pin_model.joints[self.pin_model.getJointId(name)]
                if joint.nq == 2:   # continuous joint: (cos, sin)
                    q[joint.idx_q:joint.idx_q + 2] = np.cos(value), np.sin(value)
                else:
                    q[joint.idx_q] = value
        return q

    def poses(self, positions):
        q = self.pin_configuration(positions)
        pin.forwardKinematics(self.pin_model, self.pin_data, q)
        pin.updateFramePlacements(self.pin_model, self.pin_data)
        poses = dict(self.scene_poses)
        for name, fid in self.frame_ids.items():
            poses[name] = self.pin_data.oMf[fid].homogeneous
        return poses

    def pair_distance(self, poses, a, b):
        """fcl.distance between bodies a and b at ``poses`` (theirs): the smallest over their
        elements' BVH models (fcl answers -1 or 0 for meshes that meet)."""
        request = fcl.DistanceRequest()
        Ta, Tb = poses[a], poses[b]
        ta = fcl.Transform(Ta[:3, :3], Ta[:3, 3])
        tb = fcl.Transform(Tb[:3, :3], Tb[:3, 3])
        return min(fcl.distance(fcl.CollisionObject(ma, ta), fcl.CollisionObject(mb, tb),
                                request, fcl.DistanceResult())
                   for ma in self.models[a] for mb in self.models[b])

    def contains(self, poses, a, b):
        """True iff a vertex of one body lies inside a solid primitive of the other."""
        Ta, Tb = poses[a], poses[b]
        return self._contains(a, b, Ta, Tb) or self._contains(b, a, Tb, Ta)

    def colliding_pairs(self, positions):
        return self.colliding_among(self.checker.checked_pairs, self.poses(positions))

    def colliding_among(self, pairs, poses):
        """The pairs of ``pairs`` that collide, bodies placed at ``poses`` ({name: (4, 4)})."""
        request = fcl.CollisionRequest()
        hits = []
        for a, b in pairs:
            Ta, Tb = poses[a], poses[b]
            ta = fcl.Transform(Ta[:3, :3], Ta[:3, 3])
            tb = fcl.Transform(Tb[:3, :3], Tb[:3, 3])
            found = False
            for ma in self.models[a]:
                for mb in self.models[b]:
                    result = fcl.CollisionResult()
                    if fcl.collide(fcl.CollisionObject(ma, ta), fcl.CollisionObject(mb, tb),
                                   request, result):
                        found = True
                        break
                if found:
                    break
            if found or self._contains(a, b, Ta, Tb) or self._contains(b, a, Tb, Ta):
                hits.append((a, b))
        return tuple(hits)


def body_triangles(checker, name):
    """(n, 3, 3) the body's triangles in the world, at the checker's current state."""
    b = checker._scene.body_index[name]
    f = checker.forest
    tris = np.concatenate([FclOracle._tris_of_tree(f, f.roots[e]) for e in range(
        checker._scene.elem_start[b], checker._scene.elem_end[b])])
    T = checker._poses()[b]
    return tris @ T[:3, :3].T + T[:3, 3]


def distance_to_body(checker, x, name):
    """Distance from point x (world) to the body's triangles at the checker's state."""
    from engine_kernels import triangle_distance
    tris = body_triangles(checker, name)
    d, _, _ = triangle_distance(np.broadcast_to(x, (len(tris), 3, 3)).copy(), tris)
    return float(d.min())


class SceneOracle:
    """The scene as this test keeps it, its pairs by the documented rules, and its colliding
    pairs by python-fcl (:class:`FclOracle` for the robot: pinocchio's link poses)."""

    def __init__(self, urdf, config):
        self.robot = CollisionChecker.from_urdf(urdf, config=config)
        self.fcl = FclOracle(self.robot, urdf)
        self.objects = {}   # name: (obj, attach_to, touch_links, pose)

    def apply(self, change):
        if isinstance(change, AddObject):
            obj = change.obj
            self.objects[obj.name] = (obj, change.attach_to, tuple(change.touch_links),
                                      obj.T_world_object if change.pose is None
                                      else change.pose)
            self.fcl.models[obj.name] = [FclOracle._bvh(obj.vertices, obj.faces)]
            # The contact rule lets one vertex decide containment; for a tessellated
            # primitive partly in the sliver of another's true shape, which one matters. The
            # engine takes the element's first vertex, faces[0, 0] (as FclOracle does).
            self.fcl.vertices[obj.name] = [np.asarray(obj.vertices[obj.faces[0, 0]],
                                                      dtype=np.float64)]
            if obj.solid is not None:
                self.fcl.solids[obj.name] = [(FclOracle._primitive(obj.solid), np.eye(4))]
            else:
                self.fcl.solids.pop(obj.name, None)
        elif isinstance(change, MoveObject):
            obj, link, touch, _ = self.objects[change.name]
            self.objects[change.name] = (obj, link, touch, change.pose)
        else:
            del self.objects[change.name]

    def pairs(self):
        """Robot pairs as the robot alone has them; each object against every link with
        geometry but its own and its touch links; attached objects against each other unless
        on one link or touching; world objects never against each other."""
        pairs = set(self.robot.checked_pairs)
        links = self.robot.link_names
        for name, (_, link, touch, _) in self.objects.items():
            pairs.update(sorted_pair(name, other) for other in links
                         if other != link and other not in touch)
            for other, (_, other_link, other_touch, _) in self.objects.items():
                if other == name or (link is None and other_link is None):
                    continue
                if link is not None and other_link is not None and (
                        link == other_link or other_link in touch or link in other_touch):
                    continue
                pairs.add(sorted_pair(name, other))
        return tuple(sorted(pairs))

    def colliding_pairs(self, q):
        poses = self.fcl.poses(q)
        for name, (_, link, _, pose) in self.objects.items():
            poses[name] = pose if link is None else poses[link] @ pose
        return self.fcl.colliding_among(self.pairs(), poses)

    def changes_from_scratch(self):
        return [AddObject(obj, link, touch, pose)
                for obj, link, touch, pose in self.objects.values()]


def world_elements(checker):
    """Each collision element of the robot at the checker's state: (link, trimesh in the world,
    solid?)."""
    import trimesh
    poses = checker.link_poses()
    out = []
    for element in checker.model.elements:
        T = poses[element.link] @ element.T_link_element
        mesh = trimesh.Trimesh(element.vertices @ T[:3, :3].T + T[:3, 3], element.faces,
                               process=False)
        out.append((element.link, mesh, element.solid is not None))
    return out


def surface_points(checker, rng, per_element=2000, noise=0.002):
    """Points sampled on the robot's collision surfaces at the checker's state (world frame),
    with Gaussian noise of ``noise`` m."""
    import trimesh
    points = []
    for _, mesh, _ in world_elements(checker):
        sample, _ = trimesh.sample.sample_surface(mesh, per_element,
                                                  seed=int(rng.integers(1 << 30)))
        points.append(sample)
    points = np.concatenate(points)
    return points + rng.normal(0.0, noise, points.shape)


def voxel_manager(centres, size):
    """One fcl.Box of edge ``size`` per voxel centre (V, 3), in a dynamic AABB tree; returns
    the manager and the boxes."""
    boxes = [fcl.CollisionObject(fcl.Box(size, size, size), fcl.Transform(np.eye(3), c))
             for c in centres]
    manager = fcl.DynamicAABBTreeCollisionManager()
    manager.registerObjects(boxes)
    manager.setup()
    return manager, boxes


def voxel_links_in_contact(oracle, q, centres, size, links, padding=0.0):
    """The links of ``links`` that python-fcl finds in contact with the voxel boxes at joint
    values ``q`` (within ``padding`` when > 0), at pinocchio's poses (``oracle``: FclOracle)."""
    poses = oracle.poses(q)
    manager, _ = voxel_manager(centres, size)
    hits = set()
    for link in links:
        for obj in oracle.link_objects(poses, link):
            if padding > 0.0:
                data = fcl.DistanceData()
                manager.distance(obj, data, fcl.defaultDistanceCallback)
                if data.result.min_distance <= padding:
                    hits.add(link)
            else:
                data = fcl.CollisionData()
                manager.collide(obj, data, fcl.defaultCollisionCallback)
                if data.result.is_collision:
                    hits.add(link)
    return hits
