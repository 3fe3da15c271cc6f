"""The node's ``scene`` topic, with real rclpy (no launch) and python-fcl as the oracle.

Each test starts the node on the small robot of test_checker (written to a URDF file) in a
namespace of its own, publishes MarkerArrays on ``scene`` (reliable, transient local) and
joint states, and compares every verdict with python-fcl on the scene the arrays describe
(:class:`engine_oracles.SceneOracle`; the arrays are turned into objects by
scene_markers, whose rules test_scene_markers checks on their own).
"""
import threading

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import Point  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Bool  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from collision_sensor import CollisionChecker  # noqa: E402
from collision_sensor.engine.dynamic_scene import AddObject  # noqa: E402
from collision_sensor.engine.scene_markers import SceneTopic  # noqa: E402
from collision_sensor.ros.node import CollisionSensorNode, quaternion_from_matrix  # noqa: E402
from ros_helpers import WAIT, RosHarness, node_status, reliable  # noqa: E402
from small_robot import SMALL_ROBOT  # noqa: E402
from engine_oracles import SceneOracle  # noqa: E402

JOINTS = ('shoulder', 'elbow', 'extend', 'wrist')


@pytest.fixture
def ros(request):
    harness = RosHarness(request.node.name)
    yield harness
    harness.close()


@pytest.fixture(scope='module')
def robot_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('robot') / 'small.urdf'
    path.write_text(SMALL_ROBOT)
    return str(path)


def start(ros, robot_file, **overrides):
    # Instants (check_motion off): the states jump, and the oracle is python-fcl at each state;
    # test_node_motion.py checks motions against scene objects.
    values = {'urdf_path': robot_file, 'joint_states_qos': 'reliable',
              'overload_policy': 'every', 'joint_limit_policy': 'accept',
              'check_motion': False}
    values.update(overrides)
    node = CollisionSensorNode(namespace=ros.namespace, context=ros.context,
                               parameter_overrides=[Parameter(k, value=v)
                                                    for k, v in values.items()])
    return ros.add(node)


def box(ns, size=(0.1, 0.1, 0.1), position=(0.0, 0.0, 0.0), frame='', ident=0, kind=Marker.CUBE,
        action=Marker.ADD, text='', quaternion=(0.0, 0.0, 0.0, 1.0)):
    marker = Marker(ns=ns, id=ident, type=kind, action=action, text=text)
    marker.header.frame_id = frame
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = map(float,
                                                                                 position)
    (marker.pose.orientation.x, marker.pose.orientation.y, marker.pose.orientation.z,
     marker.pose.orientation.w) = map(float, quaternion)
    marker.scale.x, marker.scale.y, marker.scale.z = map(float, size)
    return marker


class SceneProbe:
    """Publishes joint states and scene arrays; records verdicts and /diagnostics; keeps the
    scene the arrays describe in an fcl oracle."""

    def __init__(self, ros, robot_file):
        self.ros = ros
        self.joint_states = ros.publisher(JointState, 'joint_states', reliable(1000))
        self.scene = ros.publisher(MarkerArray, 'scene', reliable(100, latched=True))
        self.contact = ros.record(Bool, 'contact', reliable(1000, latched=True))
        self.pairs = ros.record(DiagnosticArray, 'colliding_pairs', reliable(1000, latched=True))
        self.diagnostics = ros.record(DiagnosticArray, '/diagnostics', reliable(100))
        assert ros.wait_for_subscribers(self.joint_states, timeout=10.0)
        assert ros.wait_for_subscribers(self.scene, timeout=10.0)
        self.oracle = SceneOracle(robot_file, None)
        # The oracle's own copy of the scene rules' input (a checker of its own).
        self.mirror = CollisionChecker.from_urdf(robot_file)
        self.topic = SceneTopic()
        self.q = np.zeros(len(JOINTS))

    def verdicts(self):
        return [tuple(tuple(s.name.split(':')) for s in msg.status) for msg in self.pairs.messages]

    def send_joints(self, q):
        self.q = np.asarray(q, dtype=float)
        count = len(self.pairs)
        self.joint_states.publish(JointState(name=list(JOINTS), position=self.q.tolist()))
        assert self.ros.spin_until(lambda: len(self.pairs) > count, 10.0), 'no verdict'
        return self.verdicts()[-1]

    def send_scene(self, markers, applies=True):
        """Publish an array; when it ``applies``, wait for its verdict and mirror it."""
        count = len(self.pairs)
        self.scene.publish(MarkerArray(markers=markers))
        if not applies:
            return None
        self.mirror_scene(markers)
        assert self.ros.spin_until(lambda: len(self.pairs) > count, 10.0), 'no scene verdict'
        return self.verdicts()[-1]

    def mirror_scene(self, markers):
        """Apply an array to the mirror checker and the oracle (what the node should do)."""
        update = self.topic.update(markers, self.mirror)
        self.mirror.apply_scene_changes(update.changes)
        self.topic.accept(update)
        for change in update.changes:
            self.oracle.apply(change)

    def expected(self):
        return self.oracle.colliding_pairs(self.q)

    def scene_status(self, condition, timeout=WAIT):
        return self.status('scene', condition, timeout)

    def status(self, which, condition, timeout=WAIT):
        """The node's /diagnostics status ``which`` (``scene``, ``collision sensor``) once
        ``condition(status, values)``: (status, values)."""
        return node_status(self.ros, self.diagnostics, which, condition, timeout)


def test_add_move_remove_each_answered_at_once_as_fcl_says(ros, robot_file):
    start(ros, robot_file)
    probe = SceneProbe(ros, robot_file)
    assert probe.send_joints([0.3, 0.2, 0.0, 0.0]) == probe.expected()
    seen = set()
    rng = np.random.default_rng(11)
    for step in range(30):
        kind = rng.integers(3)
        name = f'crate/{rng.integers(3) + 1}'
        if kind == 0:      # add, or move (the same shape), anywhere near the arm
            markers = [box('crate', (0.2, 0.2, 0.2), rng.uniform(-0.6, 0.6, 3) + (0, 0, 0.5),
                           ident=int(name[-1]))]
        elif kind == 1:    # another shape: replaced
            markers = [box('crate', (0.3, 0.1, 0.2), rng.uniform(-0.6, 0.6, 3) + (0, 0, 0.5),
                           ident=int(name[-1]), kind=Marker.CUBE)]
        else:
            markers = [box('crate', ident=int(name[-1]), action=Marker.DELETE)]
        verdict = probe.send_scene(markers)
        assert verdict == probe.expected(), step
        seen.update(verdict)
        assert probe.send_joints(probe.q + rng.normal(0, 0.2, 4)) == probe.expected(), step
    assert any('crate' in ' '.join(pair) for pair in seen)


def test_every_shape_attached_and_in_the_world(ros, robot_file, tmp_path):
    import trimesh
    (tmp_path / 'meshes').mkdir()
    trimesh.creation.icosphere(2, 0.15).export(str(tmp_path / 'meshes' / 'ball.stl'))
    start(ros, robot_file, package_paths=[f'cell={tmp_path}'])
    probe = SceneProbe(ros, robot_file)
    probe.topic.package_paths = {'cell': str(tmp_path)}
    probe.send_joints([0.8, -0.5, 0.0, 0.2])
    soup = box('soup', (1.0, 1.0, 1.0), (0.3, 0.0, 0.6), kind=Marker.TRIANGLE_LIST)
    soup.points = [Point(x=x, y=y, z=z) for x, y, z in np.random.default_rng(3).uniform(
        -0.3, 0.3, (30, 3)).tolist()]
    markers = [box('cube', (0.2, 0.3, 0.1), (0.4, 0.1, 0.8)),
               box('ball', (0.3,) * 3, (0.0, 0.3, 0.6), kind=Marker.SPHERE),
               box('post', (0.1, 0.1, 1.0), (0.5, -0.2, 0.5), kind=Marker.CYLINDER),
               box('held', (0.2, 0.2, 0.2), (0.1, 0.0, 0.0), frame='tool', text='lower'),
               soup]
    mesh = box('mesh', (1.0, 1.0, 1.0), (0.2, 0.2, 0.9), kind=Marker.MESH_RESOURCE)
    mesh.mesh_resource = 'package://cell/meshes/ball.stl'
    markers.append(mesh)
    assert probe.send_scene(markers) == probe.expected()
    rng = np.random.default_rng(4)
    hits = set()
    for step in range(40):
        verdict = probe.send_joints(np.clip(probe.q + rng.normal(0, 0.25, 4), -1.5, 1.5)
                                    * (1, 1, 0.1, 1))
        assert verdict == probe.expected(), step
        hits.update(verdict)
    touched = {name for pair in hits for name in pair}
    assert {'held', 'cube'} <= touched and len(touched & {'ball', 'post', 'soup', 'mesh'}) >= 2


def test_attach_and_detach_in_contact_through_the_topic(ros, robot_file):
    start(ros, robot_file)
    probe = SceneProbe(ros, robot_file)
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    T_tool = probe.mirror.link_poses()['tool']
    world = box('part', (0.08,) * 3, T_tool[:3, 3])
    assert ('part', 'tool') in probe.send_scene([world])
    attached = box('part', (0.08,) * 3, frame='tool')    # held: not checked against the tool
    verdict = probe.send_scene([attached])
    assert ('part', 'tool') not in verdict and verdict == probe.expected()
    for shoulder in np.linspace(0.0, 1.0, 11):
        assert probe.send_joints([shoulder, 0.0, 0.0, 0.0]) == probe.expected()
    probe.mirror.check(probe.q)
    T_part = probe.mirror.link_poses()['part']
    dropped = box('part', (0.08,) * 3, T_part[:3, 3],   # let go where it is: in contact
                  quaternion=quaternion_from_matrix(T_part[:3, :3]))
    verdict = probe.send_scene([dropped])
    assert ('part', 'tool') in verdict and verdict == probe.expected()


def test_bad_arrays_are_rejected_whole_and_named(ros, robot_file):
    # Rejecting 200,001 triangles takes seconds on a loaded machine: no joint state arrives
    # meanwhile, and the sensor would rightly report them stale instead of the scene's verdict.
    start(ros, robot_file, stale_timeout=60.0)
    probe = SceneProbe(ros, robot_file)
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    probe.send_scene([box('keep', position=(0.0, 0.0, 0.95))])
    bad = [box('x', kind=Marker.ARROW), box('x', frame='map'),
           box('x', position=(float('nan'), 0, 0)), box('x', (0.1, 0.0, 0.1)),
           box('x', kind=Marker.MESH_RESOURCE), box('a:b')]
    bad[4].mesh_resource = '/etc/passwd'
    big = box('x', kind=Marker.TRIANGLE_LIST)
    big.points = [Point()] * 3 * 200_001
    bad.append(big)
    for count, marker in enumerate(bad, 1):
        before = len(probe.pairs)
        probe.send_scene([box('new', position=(0.0, 0.0, 0.95)),
                          box('keep', position=(2.0, 0.0, 0.0)), marker], applies=False)
        status, values = probe.scene_status(
            lambda status, values: values['scene_arrays_rejected_total'] == str(count))
        assert status.level == status.WARN
        assert values['last_rejection'].startswith('marker 2 (ns ')
        assert '; ' in values['last_rejection']          # the reason, then the fix
        assert values['objects'] == 'keep'
        # Every array is answered: a rejected one by a verdict on the scene as it was.
        assert probe.ros.spin_until(lambda: len(probe.pairs) > before, 10.0)
        assert probe.verdicts()[-1] == probe.expected()
    # The scene is as it was: 'keep' still touches the tool.
    assert probe.send_joints([0.0, 0.0, 0.0, 0.0]) == probe.expected()
    assert ('keep', 'tool') in probe.expected()


def test_deleteall_removes_the_topics_objects_only(ros, robot_file, tmp_path):
    scene = tmp_path / 'scene.yaml'
    scene.write_text('objects:\n  - name: wall\n    box: {size: [0.1, 2, 2]}\n'
                     '    pose: {xyz: [0.4, 0, 1]}\n')
    start(ros, robot_file, scene_path=str(scene))
    probe = SceneProbe(ros, robot_file)
    probe.mirror = CollisionChecker.from_urdf(robot_file, scene=str(scene))
    probe.oracle.apply(AddObject(probe.mirror.scene_objects[0]))
    probe.send_joints([0.9, 0.0, 0.0, 0.0])
    probe.send_scene([box('a', position=(0.3, 0, 0.5)), box('b', position=(-0.3, 0, 0.5))])
    verdict = probe.send_scene([Marker(action=Marker.DELETEALL)])
    assert verdict == probe.expected() and ('upper', 'wall') in verdict
    _, values = probe.scene_status(lambda status, values: values['topic_objects_count'] == '0')
    assert values['objects'] == 'wall'


def test_a_late_joining_node_gets_the_scene_published_before(ros, robot_file):
    early = [box('early', (0.3,) * 3, (0.0, 0.0, 0.95))]
    scene = ros.publisher(MarkerArray, 'scene', reliable(10, latched=True))
    scene.publish(MarkerArray(markers=early))
    ros.spin_for(0.2)
    start(ros, robot_file)
    probe = SceneProbe(ros, robot_file)
    probe.mirror_scene(early)
    _, values = probe.scene_status(lambda status, values: values['objects'] == 'early')
    verdict = probe.send_joints([0.0, 0.0, 0.0, 0.0])
    assert ('early', 'tool') in verdict and verdict == probe.expected()


@pytest.mark.slow
def test_joint_states_are_all_answered_while_a_large_mesh_is_added(ros, robot_file):
    """200,000 triangles arrive while joint states stream in: every joint state gets its
    verdict (overload_policy every), several of them while the tree is being built."""
    start(ros, robot_file, scene_max_total_triangles=1_000_000)
    probe = SceneProbe(ros, robot_file)
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    rng = np.random.default_rng(5)
    vertices = rng.uniform(-0.05, 0.05, (3 * 200_000, 3)) + (0.0, 0.0, 0.95)
    soup = box('soup', (1.0, 1.0, 1.0), kind=Marker.TRIANGLE_LIST)
    soup.points = [Point(x=x, y=y, z=z) for x, y, z in vertices.tolist()]
    stop = threading.Event()
    sent = []

    def stream():
        k = 0
        while not stop.is_set() and k < 100_000:
            k += 1
            msg = JointState(name=list(JOINTS), position=[0.0, 0.0, 0.0, 1e-4 * k])
            msg.header.stamp.sec, msg.header.stamp.nanosec = 1, k
            probe.joint_states.publish(msg)
            sent.append(k)
            stop.wait(0.005)

    def scene_verdict(msg):     # its header: the time and the root frame
        # (Building the soup above takes seconds: the node may have answered "stale" since.)
        return msg.header.frame_id == 'base' and not any(
            status.name == 'joint_states_stale' for status in msg.status)

    streamer = threading.Thread(target=stream)
    before = len(probe.pairs)
    streamer.start()
    try:
        probe.scene.publish(MarkerArray(markers=[soup]))
        assert probe.ros.spin_until(
            lambda: any(scene_verdict(msg) for msg in probe.pairs.messages[before:]),
            120.0), 'the mesh was never applied'
    finally:
        stop.set()
        streamer.join()
    assert probe.ros.spin_until(lambda: sum(msg.header.stamp.sec == 1 for msg in
                                            probe.pairs.messages) == len(sent), 30.0)
    stamps = [msg.header.stamp.nanosec for msg in probe.pairs.messages
              if msg.header.stamp.sec == 1]
    assert stamps == sent       # every joint state answered, in order
    messages = probe.pairs.messages[before:]
    scene_at = next(i for i, msg in enumerate(messages) if scene_verdict(msg))
    assert scene_at > 3         # joint states were answered while the tree was built
    assert ('soup', 'tool') in probe.verdicts()[-1]


def test_markers_show_scene_objects_attached_and_colliding(ros, robot_file):
    from collision_sensor.ros.node import (
        ATTACHED_OBJECT_COLOR, COLLIDING_OBJECT_COLOR, WORLD_OBJECT_COLOR)
    start(ros, robot_file, publish_markers=True)
    probe = SceneProbe(ros, robot_file)
    markers = ros.record(MarkerArray, 'collision_sensor/markers', 100)
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    probe.send_scene([box('far', position=(2.0, 0, 0)),
                      box('held', (0.05, 0.05, 0.05), (0.0, 0.0, 0.1), frame='tool')])

    def objects():
        last = markers.last
        return {m.text: m for m in (last.markers if last else []) if m.ns == 'scene_objects'}

    assert ros.spin_until(lambda: set(objects()) == {'far', 'held'})
    assert markers.last.markers[0].action == Marker.DELETEALL
    shown = objects()

    def same(a, b):      # ColorRGBA holds float32
        return (a.r, a.g, a.b, a.a) == pytest.approx((b.r, b.g, b.b, b.a), abs=1e-6)

    assert same(shown['far'].color, WORLD_OBJECT_COLOR) and shown['far'].type == Marker.CUBE
    assert same(shown['held'].color, ATTACHED_OBJECT_COLOR)
    assert shown['far'].pose.position.x == pytest.approx(2.0)
    probe.send_scene([box('far', position=(0.0, 0.0, 0.3))])     # into the upper link
    assert ros.spin_until(lambda: objects().get('far') is not None
                          and same(objects()['far'].color, COLLIDING_OBJECT_COLOR))
    assert ros.spin_until(lambda: any(m.ns == 'far' and m.type == Marker.CUBE
                                      for m in markers.last.markers))   # its box, red


# -- touch links of world objects, allowed_collisions for objects still to come (issue 28) ------

def sensor_values(probe, condition):
    """The node's ``collision sensor`` status once ``condition(values)``."""
    return probe.status('collision sensor', lambda status, values: condition(values))


def test_a_world_object_may_touch_the_links_its_text_lists(ros, robot_file):
    """A table under the robot's base: without touch links in contact for ever; with ``text``
    "base" the base is never checked against it, the arm still is; an unknown link in text
    rejects the array."""
    start(ros, robot_file)
    probe = SceneProbe(ros, robot_file)
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    table = dict(size=(1.0, 1.0, 0.1), position=(0.0, 0.0, -0.1))   # the base stands on it
    assert ('base', 'table') in probe.send_scene([box('table', **table)])
    verdict = probe.send_scene([box('table', **table, text='base')])
    assert ('base', 'table') not in verdict and verdict == probe.expected()
    hits = set()
    for shoulder in np.linspace(0.0, 2.4, 9):    # the arm folds down onto the table
        verdict = probe.send_joints([shoulder, 0.6, 0.0, 0.0])
        assert verdict == probe.expected()
        hits.update(pair for pair in verdict if 'table' in pair)
    assert hits and ('base', 'table') not in hits
    probe.send_scene([box('table', **table, text='base tabel_leg')], applies=False)
    _, values = probe.scene_status(
        lambda status, values: values['scene_arrays_rejected_total'] == '1')
    assert 'touch link "tabel_leg" (in text) is not a link of the robot' in \
        values['last_rejection']


def test_allowed_collisions_may_name_an_object_still_to_come(ros, robot_file, capfd):
    start(ros, robot_file, allowed_collisions=['tool:crate'])
    probe = SceneProbe(ros, robot_file)
    status, values = sensor_values(probe, lambda values: values['names_pending'] == 'crate')
    assert status.level == status.WARN and 'crate' in status.message
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    T_tool = probe.mirror.link_poses()['tool']
    verdict = probe.send_scene([box('crate', (0.08,) * 3, T_tool[:3, 3])])
    assert ('crate', 'tool') in probe.expected()      # it touches the tool: allowed
    assert verdict == tuple(pair for pair in probe.expected() if pair != ('crate', 'tool'))
    sensor_values(probe, lambda values: values['names_pending'] == '')
    err = capfd.readouterr().err
    assert 'allowed_collisions: "crate" is neither a link of robot "small" nor a scene object' \
        in err


def test_allowed_collisions_set_at_run_time_for_an_object_to_come(ros, robot_file):
    from test_node_parameters import Parameters
    start(ros, robot_file)
    probe = SceneProbe(ros, robot_file)
    probe.send_joints([0.0, 0.0, 0.0, 0.0])
    count = len(probe.pairs)
    assert Parameters(ros).set(allowed_collisions=['tool:crate']) == (True, '')
    assert probe.ros.spin_until(lambda: len(probe.pairs) > count, 30.0)   # the new checker
    sensor_values(probe, lambda values: values['names_pending'] == 'crate')
    T_tool = probe.mirror.link_poses()['tool']
    verdict = probe.send_scene([box('crate', (0.08,) * 3, T_tool[:3, 3])])
    assert ('crate', 'tool') in probe.expected() and ('crate', 'tool') not in verdict
