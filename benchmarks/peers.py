"""The peers we measure against, set up on the same robot: pinocchio+coal and python-fcl.

Both are optional imports; a missing peer is reported as such, never faked.
"""
import numpy as np


class PinocchioPeer:
    """pinocchio's ``computeCollisions`` (FK + geometry placements + every pair, coal inside)."""

    name = 'pinocchio+coal'

    def __init__(self, urdf, srdf, package_paths):
        """:param package_paths: ``{package: directory}`` as the checker takes it."""
        import os

        import pinocchio as pin
        self.pin = pin
        self.model = pin.buildModelFromUrdf(urdf)
        # pinocchio wants the folders that hold the packages, not the packages themselves.
        package_dirs = sorted({os.path.dirname(os.path.normpath(d))
                               for d in package_paths.values()})
        self.geom = pin.buildGeomFromUrdf(self.model, urdf, pin.COLLISION,
                                          package_dirs=package_dirs)
        self.geom.addAllCollisionPairs()
        if srdf:
            pin.removeCollisionPairs(self.model, self.geom, srdf)
        self.data = self.model.createData()
        self.geom_data = pin.GeometryData(self.geom)
        self.pair_count = len(self.geom.collisionPairs)

    def configuration(self, checker, positions):
        """pinocchio's q for our joint vector (mimic joints get their derived value; a
        continuous joint's angle as pinocchio holds it, its cosine and sine)."""
        q = self.pin.neutral(self.model)
        values = dict(zip(checker.joint_names, positions))
        for joint in checker.model.joints:
            if joint.mimic is not None:
                values[joint.name] = (joint.mimic.multiplier * values[joint.mimic.joint]
                                      + joint.mimic.offset)
        for name, value in values.items():
            if self.model.existJointName(name):
                joint = self.model.joints[self.model.getJointId(name)]
                if joint.nq == 2 and joint.nv == 1:  # continuous: (cos, sin) of the angle
                    q[joint.idx_q:joint.idx_q + 2] = np.cos(value), np.sin(value)
                else:
                    q[joint.idx_q] = value
        return q

    def check(self, q):
        return self.pin.computeCollisions(self.model, self.data, self.geom, self.geom_data, q,
                                          False)


class FclPeer:
    """python-fcl: one BVH model (OBBRSS) per collision element, every checked pair collided.

    Built from the triangles this package loaded, so both sides check the same geometry.
    """

    name = 'python-fcl'

    def __init__(self, checker):
        import fcl
        self.fcl = fcl
        self.checker = checker
        self.objects = {}
        for element in checker.model.elements:
            T = element.T_link_element
            vertices = element.vertices @ T[:3, :3].T + T[:3, 3]
            model = fcl.BVHModel()
            model.beginModel(len(vertices), len(element.faces))
            model.addSubModel(vertices, element.faces.astype(np.int32))
            model.endModel()
            self.objects.setdefault(element.link, []).append(fcl.CollisionObject(model))
        self.pairs = [(self.objects[a], self.objects[b]) for a, b in checker.checked_pairs
                      if a in self.objects and b in self.objects]
        self.request = fcl.CollisionRequest()

    def place(self, poses):
        """Set every object's world pose from ``{link: T_world_link}``."""
        for link, objects in self.objects.items():
            T = poses[link]
            transform = self.fcl.Transform(T[:3, :3], T[:3, 3])
            for obj in objects:
                obj.setTransform(transform)

    def check(self):
        """Collide every checked pair (all sub-groups until one hits); return the hit count."""
        hits = 0
        for objects_a, objects_b in self.pairs:
            hit = False
            for oa in objects_a:
                for ob in objects_b:
                    if self.fcl.collide(oa, ob, self.request, self.fcl.CollisionResult()):
                        hit = True
                        break
                if hit:
                    break
            hits += hit
        return hits
