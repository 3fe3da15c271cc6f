"""Containment: anything wholly inside a primitive (box, sphere, cylinder) collides with it, as
FCL reports for primitives; a closed mesh does so with ``mesh_containment``. python-fcl with
primitive shapes (fcl.Box, fcl.Sphere, fcl.Cylinder) for primitives is the oracle."""
import numpy as np
import pytest
import trimesh

from collision_sensor import CollisionChecker
from collision_sensor.model.mesh_loading import is_closed_surface

fcl = pytest.importorskip('fcl')

# Two branches from a base, so that "hand" and "finger" are not adjacent: the hand holds a
# big box (a safety box, as TIAGo's hand does) and swings, the finger (a small shape) slides
# along three axes. Prismatic x, y, z put the finger anywhere near the hand.
URDF = '''<robot name="containment">
  <link name="base"/>
  <link name="hand"><collision><geometry>{hand}</geometry></collision></link>
  <link name="sx"/><link name="sy"/>
  <link name="finger"><collision><geometry>{finger}</geometry></collision></link>
  <joint name="swing" type="revolute"><parent link="base"/><child link="hand"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/>
    <limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="x" type="prismatic"><parent link="base"/><child link="sx"/>
    <axis xyz="1 0 0"/><limit lower="-0.6" upper="0.6" effort="1" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="sx"/><child link="sy"/>
    <axis xyz="0 1 0"/><limit lower="-0.6" upper="0.6" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="sy"/><child link="finger"/>
    <axis xyz="0 0 1"/><limit lower="0.0" upper="1.0" effort="1" velocity="1"/></joint>
</robot>
'''
SHAPES = {
    'box': ('<box size="0.5 0.3 0.4"/>', lambda: fcl.Box(0.5, 0.3, 0.4)),
    'sphere': ('<sphere radius="0.25"/>', lambda: fcl.Sphere(0.25)),
    'cylinder': ('<cylinder radius="0.2" length="0.5"/>', lambda: fcl.Cylinder(0.2, 0.5)),
    'small_box': ('<box size="0.04 0.06 0.05"/>', lambda: fcl.Box(0.04, 0.06, 0.05)),
    'small_sphere': ('<sphere radius="0.03"/>', lambda: fcl.Sphere(0.03)),
    'small_cylinder': ('<cylinder radius="0.02" length="0.08"/>',
                       lambda: fcl.Cylinder(0.02, 0.08)),
}


def _checker(hand, finger, **config):
    urdf = URDF.format(hand=SHAPES[hand][0], finger=SHAPES[finger][0])
    return CollisionChecker.from_urdf(urdf, config=config or None)


def _fcl_collide(checker, hand, finger):
    poses = checker.link_poses()
    objects = []
    for link, shape in (('hand', hand), ('finger', finger)):
        T = poses[link]
        objects.append(fcl.CollisionObject(SHAPES[shape][1](),
                                           fcl.Transform(T[:3, :3], T[:3, 3])))
    return bool(fcl.collide(objects[0], objects[1], fcl.CollisionRequest(),
                            fcl.CollisionResult()))


def _inside_outside_or_crossing(checker, q, hand, finger):
    """True when the finger is clearly inside, clearly apart or clearly crossing the hand's
    true primitive (more than the tessellation's slack from touching): python-fcl's signed
    distance between the true shapes, and between the finger and the hand's surface."""
    poses = checker.link_poses()
    objects = []
    for link, shape in (('hand', hand), ('finger', finger)):
        T = poses[link]
        objects.append(fcl.CollisionObject(SHAPES[shape][1](),
                                           fcl.Transform(T[:3, :3], T[:3, 3])))
    request = fcl.DistanceRequest(enable_signed_distance=True)
    distance = fcl.distance(objects[0], objects[1], request, fcl.DistanceResult())
    return abs(distance) > 0.01


@pytest.mark.parametrize('hand', ['box', 'sphere', 'cylinder'])
@pytest.mark.parametrize('finger', ['small_box', 'small_sphere', 'small_cylinder'])
def test_a_part_wholly_inside_a_primitive_collides_as_fcl_says(hand, finger):
    checker = _checker(hand, finger)
    assert checker.checked_pairs == (('finger', 'hand'),)
    rng = np.random.default_rng(len(hand) * 7 + len(finger))
    inside = compared = 0
    for _ in range(600):
        # Around the hand's centre (0, 0, 0.5), often well inside it.
        q = np.array([rng.uniform(-3.1, 3.1), *rng.normal(0.0, 0.15, 2),
                      0.5 + rng.normal(0.0, 0.15)])
        q[1:3] = np.clip(q[1:3], -0.6, 0.6)
        q[3] = np.clip(q[3], 0.0, 1.0)
        ours = checker.check(q).in_collision
        theirs = _fcl_collide(checker, hand, finger)
        if ours != theirs:
            # Only where the finger is within the tessellation's slack of the true surface.
            assert not _inside_outside_or_crossing(checker, q, hand, finger), list(q)
            continue
        compared += 1
        inside += ours and not checker.check(q).rechecked_pairs == 0
    assert compared > 550 and inside > 50


def test_containment_needs_a_solid_a_surface_mesh_contains_nothing(tmp_path):
    """A closed mesh around the finger: not solid by default (FCL's mesh-mesh rule), solid
    with mesh_containment; a mesh with a hole is never solid."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.25)
    closed = tmp_path / 'closed.stl'
    sphere.export(str(closed))
    open_mesh = trimesh.Trimesh(sphere.vertices, sphere.faces[1:], process=False)
    holed = tmp_path / 'holed.stl'
    open_mesh.export(str(holed))
    assert is_closed_surface(sphere.faces) and not is_closed_surface(open_mesh.faces)
    q = np.array([0.3, 0.0, 0.0, 0.5])  # the finger at the hand's centre
    for path, solid in ((closed, True), (holed, False)):
        SHAPES['mesh'] = (f'<mesh filename="file://{path}"/>', None)
        plain = _checker('mesh', 'small_box')
        assert not plain.check(q).in_collision
        with_option = _checker('mesh', 'small_box', mesh_containment=True)
        assert with_option.check(q).in_collision == solid
        # The finger out of the sphere: apart either way.
        assert not with_option.check(np.array([0.3, 0.5, 0.5, 0.5])).in_collision


def test_update_equals_check_as_a_part_slides_in_and_out_of_a_solid():
    incremental = _checker('box', 'small_sphere')
    scratch = _checker('box', 'small_sphere')
    rng = np.random.default_rng(5)
    q = np.array([0.0, 0.0, 0.0, 0.5])
    changes, previous = 0, None
    for _ in range(3000):
        q = q + rng.normal(0.0, 0.01, 4)
        q[1:3] = np.clip(q[1:3], -0.6, 0.6)
        q[3] = np.clip(q[3], 0.0, 1.0)
        got = incremental.update(q).colliding_pairs
        assert got == scratch.check(q).colliding_pairs, list(q)
        changes += got != previous
        previous = got
    assert changes > 4


def test_scene_primitives_are_solid_too():
    """A robot part inside a scene box, a scene sphere inside the robot's box."""
    checker = CollisionChecker.from_urdf(
        URDF.format(hand=SHAPES['box'][0], finger=SHAPES['small_box'][0]),
        scene={'objects': [
            {'name': 'crate', 'box': {'size': [0.3, 0.3, 0.3]}, 'pose': {'xyz': [0.4, 0.4, 0.3]}},
            {'name': 'pebble', 'sphere': {'radius': 0.02}, 'pose': {'xyz': [0.05, 0.0, 0.5]}},
        ]})
    result = checker.check(np.array([0.0, 0.4, 0.4, 0.3]))   # finger in the crate
    assert ('crate', 'finger') in result.colliding_pairs
    assert ('hand', 'pebble') in result.colliding_pairs      # the pebble in the hand's box
    result = checker.check(np.array([0.0, -0.4, -0.4, 0.9]))
    assert ('crate', 'finger') not in result.colliding_pairs
    assert ('hand', 'pebble') in result.colliding_pairs
