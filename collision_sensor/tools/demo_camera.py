"""The demo cell seen by a depth camera (``collision_sensor_demo --camera``), without ROS.

:class:`CameraCell` is the world the camera looks at: a checker of its own holding the demo
arm, the washer scene *and* a person standing in the arm's path (``config/demo_person.yaml``,
in no scene the sensor loads: the sensor knows the person only from the clouds). It renders that world by ray casting
(:class:`~collision_sensor.tools.depth_camera.DepthCamera`) from the camera's link in the arm's
URDF (``camera_optical_frame``, a fixed link), and says how far the arm truly is from the
person and from everything else, for the demo's summary to hold the sensor's reports against.
"""
import math
from typing import Dict, Mapping, NamedTuple, Sequence

import numpy as np

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.dynamic_scene import AddObject
from collision_sensor.model.scene import load_scene
from collision_sensor.model.share import config_path
from collision_sensor.tools.depth_camera import DepthCamera

#: The topic the demo's camera publishes on (relative: in the demo's namespace).
CLOUD_TOPIC = 'camera/depth/points'
#: The camera's image (pixels) and frame rate (Hz) unless given: small enough for the ray
#: casting to keep up with the rate on a small machine (its cost grows with the pixels).
DEFAULT_SIZE = (160, 120)
DEFAULT_RATE = 15.0
MAX_RANGE = 4.0     # m
#: The frame the camera's clouds are stamped with: a fixed link of ``config/demo_arm.urdf``
#: (the optical convention: z along the view, x right, y down).
CAMERA_OPTICAL_FRAME = 'camera_optical_frame'
#: What only the camera sees (``config/``; a scene file the sensor is never given).
PERSON_SCENE = 'demo_person.yaml'
#: Sections around the person's cylinder in the rendered world.
PERSON_SECTIONS = 48


class Clearance(NamedTuple):
    """How far the arm truly is from what the camera sees, at one state (the world's checker).

    :ivar person: the smallest distance (m) from a link to the person; <= 0 in contact.
    :ivar links_near: ``{link: distance}`` of every link within ``near`` of any world body
        (person, washer, floor).
    """

    person: float
    links_near: Dict[str, float]


class CameraCell:
    """The demo cell with the person in it, and the camera on its link.

    :param size: the image's width and height (pixels).
    :ivar world: the world's checker (the arm, the scene file's objects and the person).
    :ivar person_names: the names of what only the camera sees (``PERSON_SCENE``'s objects).
    :ivar T_world_camera: (4, 4) the optical frame's pose (fixed: a link on a fixed joint).
    """

    def __init__(self, size: Sequence[int] = DEFAULT_SIZE):
        self.world = CollisionChecker.from_urdf(config_path('demo_arm.urdf'),
                                                srdf=config_path('demo_arm.srdf'),
                                                scene=config_path('demo_scene.yaml'))
        person = load_scene(config_path(PERSON_SCENE), primitive_sections=PERSON_SECTIONS)
        self.world.apply_scene_changes([AddObject(body) for body in person])
        self.person_names = frozenset(body.name for body in person)
        self.camera = DepthCamera(width=int(size[0]), height=int(size[1]), max_range=MAX_RANGE)
        tree = self.world.kinematics
        T_world_link = tree.forward_kinematics(np.zeros(len(tree.joint_names)))
        self.T_world_camera = T_world_link[tree.link_names.index(CAMERA_OPTICAL_FRAME)]

    def _positions(self, joint_names: Sequence[str], q) -> Mapping[str, float]:
        return dict(zip(joint_names, (float(v) for v in q)))

    def render(self, joint_names: Sequence[str], q) -> np.ndarray:
        """Return the cloud the camera sees with the arm at ``q``: (H W, 3) float32 in the
        optical frame, row by row, NaN where nothing is within range."""
        self.world.check(self._positions(joint_names, q))
        return self.camera.points(self.world, self.T_world_camera)

    def clearance(self, joint_names: Sequence[str], q, near: float = 0.1) -> Clearance:
        """Return how far the arm at ``q`` is from the person and from every world body."""
        records = self.world.proximity(self._positions(joint_names, q), max_distance=near)
        links = set(self.world.link_names)
        person, links_near = math.inf, {}
        for record in records:
            if record.link_a in links and record.link_b in links:
                continue
            link, other = ((record.link_a, record.link_b) if record.link_a in links
                           else (record.link_b, record.link_a))
            links_near[link] = min(links_near.get(link, math.inf), record.distance)
            if other in self.person_names:
                person = min(person, record.distance)
        return Clearance(person, links_near)
