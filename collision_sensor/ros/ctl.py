"""``collision_sensor_ctl``: the runtime commands the docs show, from a pip install (no ros2cli).

Each subcommand does what its ``ros2`` counterpart does with a running node, over the same
topics and services, so the two can be used interchangeably::

    collision_sensor_ctl param set /robot1/collision_sensor warning_distance 0.02
        # ros2 param set /robot1/collision_sensor warning_distance 0.02
    collision_sensor_ctl param get /robot1/collision_sensor warning_distance
        # ros2 param get /robot1/collision_sensor warning_distance
    collision_sensor_ctl param list /robot1/collision_sensor
        # ros2 param list /robot1/collision_sensor
    collision_sensor_ctl echo /robot1/colliding_pairs [--once]
        # ros2 topic echo /robot1/colliding_pairs [--once]
    collision_sensor_ctl trajectory /robot1/trajectory path.yaml
        # ros2 topic pub --once /robot1/trajectory trajectory_msgs/msg/JointTrajectory
        #   "$(cat path.yaml)"   (then ros2 topic echo /robot1/trajectory_result)
    collision_sensor_ctl scene /robot1/scene table.yaml [--delete NAME] [--delete-all]
        # (a MarkerArray written by hand: ros2 topic pub --once /robot1/scene ...)
    collision_sensor_ctl record -o bag /joint_states /scene
        # ros2 bag record -o bag /joint_states /scene

``trajectory`` and ``scene`` also wait for the node's answer to what they sent and print it:
the trajectory's by its digest (docs/node.md), the scene array's by the node's ``scene`` status
counting it. Exit status: 0 done (a trajectory valid, a scene array applied, a parameter set),
1 refused by the node (with its reason), 2 an error (usage, no node, nothing within
``--timeout``).
"""
import argparse
import os
import sys
import time
from typing import List, Optional, Sequence, Tuple

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter, get_parameter_value, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from collision_sensor.errors import CollisionSensorError, ConfigError
from collision_sensor.model.mesh_loading import parse_package_paths
from collision_sensor.ros.answers import (
    SCENE_COUNTS, answers_it, handled_total, status_values, trajectory_answer_from)
from collision_sensor.ros.message_yaml import fill_message, message_to_yaml, message_type
from collision_sensor.ros.scene_messages import (
    delete_all_marker, delete_markers, scene_markers)
from collision_sensor.ros.trajectory_source import RESULT_QOS, TRAJECTORY_QOS, trajectory_digest

PROG = 'collision_sensor_ctl'
EXIT_OK, EXIT_REFUSED, EXIT_ERROR = 0, 1, 2
#: s to wait for a node, a topic or an answer by default.
TIMEOUT = 10.0
_SCENE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Client:
    """This command's node and executor: spins until what it waits for happens.

    :param context: an initialised rclpy Context.
    """

    def __init__(self, context, timeout: float):
        self.context, self.timeout = context, timeout
        self.node = rclpy.create_node('collision_sensor_ctl', context=context,
                                      start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def spin_until(self, ready, what: str, timeout: Optional[float] = None):
        """Spin until ``ready()`` returns something true; return it.

        :raises ConfigError: ``timeout`` (default ``--timeout``) passed first, saying ``what``
            was awaited.
        """
        timeout = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + timeout
        while True:
            found = ready()
            if found:
                return found
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ConfigError(f'{what} within {timeout:g} s (--timeout); is the node '
                                  'running, in this ROS_DOMAIN_ID, with these names?')
            self.executor.spin_once(timeout_sec=min(remaining, 0.05))

    def topic(self, name: str) -> str:
        """``name`` resolved in this node's namespace."""
        return self.node.resolve_topic_name(name)

    def topic_type(self, topic: str) -> str:
        """Wait until ``topic`` is on the graph; return its type (``pkg/msg/Type``)."""
        def known():
            types = dict(self.node.get_topic_names_and_types()).get(topic)
            return types[0] if types else None
        return self.spin_until(known, f'no topic {topic}')

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def adapted_qos(client: Client, topic: str, depth: int = 100) -> QoSProfile:
    """A subscription profile that matches every publisher of ``topic``, as ros2 topic echo
    chooses it: reliable and transient local only when all publishers are."""
    infos = client.node.get_publishers_info_by_topic(topic)
    reliable = bool(infos) and all(info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                                   for info in infos)
    latched = bool(infos) and all(
        info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for info in infos)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


# -- param ----------------------------------------------------------------------------------------

def _parameters(client: Client, node_name: str) -> AsyncParameterClient:
    parameters = AsyncParameterClient(client.node, node_name)
    client.spin_until(parameters.services_are_ready,
                      f'no parameter services of node {node_name}')
    return parameters


def _answer(client: Client, future, what: str):
    client.spin_until(future.done, f'no answer to {what}')
    return future.result()


def run_param(client: Client, args, out) -> int:
    parameters = _parameters(client, args.node)
    if args.action == 'list':
        names = _answer(client, parameters.list_parameters(), 'list_parameters').result.names
        for name in sorted(names):
            print(f'  {name}', file=out)
        return EXIT_OK
    if args.action == 'get':
        values = _answer(client, parameters.get_parameters([args.name]), 'get_parameters')
        if not values.values or values.values[0].type == 0:
            print(f'{PROG}: {args.node} has no parameter "{args.name}"', file=out)
            return EXIT_REFUSED
        value = parameter_value_to_python(values.values[0])
        print(f'{args.name}: {yaml.safe_dump(value, default_flow_style=True, width=1000)}'
              .split('\n...')[0].strip(), file=out)
        return EXIT_OK
    parameter = Parameter(args.name, value=parameter_value_to_python(
        get_parameter_value(args.value)))
    result = _answer(client, parameters.set_parameters([parameter]), 'set_parameters')
    outcome = result.results[0]
    if outcome.successful:
        print('Set parameter successful', file=out)
        return EXIT_OK
    print(f'Setting parameter failed: {outcome.reason}', file=out)
    return EXIT_REFUSED


# -- echo -----------------------------------------------------------------------------------------

def run_echo(client: Client, args, out) -> int:
    topic = client.topic(args.topic)
    msg_class = message_type(args.type or client.topic_type(topic))
    received: List = []
    qos = adapted_qos(client, topic)
    client.node.create_subscription(msg_class, topic, received.append, qos)
    limit = 1 if args.once else args.count
    printed = 0
    try:
        while limit is None or printed < limit:
            client.executor.spin_once(timeout_sec=0.1)
            while received and (limit is None or printed < limit):
                print(message_to_yaml(received.pop(0), None if args.full else 128).rstrip(),
                      file=out)
                print('---', file=out, flush=True)
                printed += 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    return EXIT_OK


# -- trajectory -----------------------------------------------------------------------------------

def read_yaml(path: str, what: str):
    """Read the YAML document of ``path`` (``-``: standard input)."""
    try:
        if path == '-':
            return yaml.safe_load(sys.stdin)
        with open(path, encoding='utf-8') as stream:
            return yaml.safe_load(stream)
    except OSError as error:
        raise ConfigError(f'{what} "{path}": cannot read it ({error.strerror}); check the '
                          'path') from None
    except yaml.YAMLError as error:
        raise ConfigError(f'{what} "{path}": broken YAML ({error}); fix the file') from None


def sibling(topic: str, name: str) -> str:
    """The topic ``name`` in ``topic``'s namespace (``/robot1/trajectory`` ->
    ``/robot1/trajectory_result``)."""
    return f'{topic.rsplit("/", 1)[0]}/{name}'


def run_trajectory(client: Client, args, out) -> int:
    msg = fill_message(JointTrajectory(), read_yaml(args.file, 'trajectory') or {})
    digest = trajectory_digest(msg)
    topic = client.topic(args.topic)
    result_topic = client.topic(args.result_topic) if args.result_topic else \
        sibling(topic, 'trajectory_result')
    answers: List = []
    subscription = client.node.create_subscription(DiagnosticArray, result_topic,
                                                   answers.append, RESULT_QOS)
    publisher = client.node.create_publisher(JointTrajectory, topic, TRAJECTORY_QOS)
    status_name, statuses = follow_status(client, topic, 'trajectory')
    # The node's status once a second gives the count of answers so far: the answer to this
    # trajectory comes after them (older ones with its digest may reach a new subscription).
    client.spin_until(lambda: publisher.get_subscription_count() > 0
                      and subscription.get_publisher_count() > 0 and statuses,
                      f'no node subscribing {topic} and publishing {result_topic} with a '
                      f'"{status_name}" status on /diagnostics')
    answered_before = int(statuses[-1].get('trajectories_total', '0') or 0)
    publisher.publish(msg)

    def mine():
        for answer in answers:
            try:
                read = trajectory_answer_from(answer)
            except ValueError:
                continue
            if answers_it(read, digest, answered_before, msg.header):
                return answer, read
        return None
    raw, answer = client.spin_until(mine, f'no answer on {result_topic} to the trajectory '
                                    f'(digest {digest[:12]})', args.answer_timeout)
    values = status_values(raw.status[0])
    print(('valid: relayed on ' + sibling(topic, 'trajectory_out')) if answer.valid
          else f'refused ({answer.kind}): {answer.reason}', file=out)
    print(yaml.safe_dump(values, sort_keys=False, width=1000).rstrip(), file=out)
    return EXIT_OK if answer.valid else EXIT_REFUSED


# -- the node's statuses --------------------------------------------------------------------------

def follow_status(client: Client, topic: str, source: str) -> Tuple[str, List[dict]]:
    """Follow on /diagnostics the ``source`` status (``scene``, ``trajectory``) of the node that
    subscribes ``topic``; return its name and the list its values are appended to, newest
    last."""
    # A subscriber's node name is known once its participant's node list is discovered.
    subscribers = client.spin_until(
        lambda: [info for info in client.node.get_subscriptions_info_by_topic(topic)
                 if info.node_name != client.node.get_name()
                 and not info.node_name.startswith('_NODE_NAME_UNKNOWN')],
        f'no node subscribing {topic}')
    owner = subscribers[0]
    status_name = f'{owner.node_namespace.strip("/")}/{owner.node_name}'.lstrip('/') + \
        f': {source}'
    statuses: List[dict] = []

    def on_diagnostics(msg):
        statuses.extend(status_values(s) for s in msg.status if s.name == status_name)
    client.node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 100)
    return status_name, statuses


# -- scene ----------------------------------------------------------------------------------------

def run_scene(client: Client, args, out) -> int:
    markers = []
    if args.delete_all:
        markers.append(delete_all_marker())
    markers += delete_markers(args.delete)
    if args.file:
        markers += scene_markers(args.file, parse_package_paths(args.package_path) or None,
                                 args.frame, args.touch)
    if not markers:
        raise ConfigError('nothing to send: give a scene file, --delete NAME or --delete-all')
    topic = client.topic(args.topic)
    publisher = client.node.create_publisher(MarkerArray, topic, _SCENE_QOS)
    status_name, statuses = follow_status(client, topic, 'scene')
    # The node's status once a second gives the count of arrays handled so far.
    client.spin_until(lambda: publisher.get_subscription_count() > 0 and statuses,
                      f'no "{status_name}" status on /diagnostics')
    before = handled_total(statuses[-1], SCENE_COUNTS) or 0
    applied_before = int(statuses[-1]['scene_arrays_applied_total'])
    publisher.publish(MarkerArray(markers=markers))
    after = client.spin_until(
        lambda: next((v for v in statuses if (handled_total(v, SCENE_COUNTS) or 0) > before),
                     None),
        f'no answer in "{status_name}" to the scene array', args.answer_timeout)
    if int(after['scene_arrays_applied_total']) > applied_before:
        print(f'applied: {after["objects_count"]} objects ({after["objects"]})', file=out)
        return EXIT_OK
    print(f'rejected, scene unchanged: {after["last_rejection"]}', file=out)
    return EXIT_REFUSED


# -- record ---------------------------------------------------------------------------------------

def run_record(client: Client, args, out) -> int:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    topics = [client.topic(name) for name in args.topics]
    types = {topic: client.topic_type(topic) for topic in topics}
    if os.path.exists(args.output):
        raise ConfigError(f'{args.output} exists already; give another --output')
    typestore = get_typestore(Stores.ROS2_JAZZY)
    unknown = [t for t in types.values() if t not in typestore.types]
    if unknown:
        raise ConfigError(f'cannot record {", ".join(unknown)}: not a type rosbags knows for '
                          'Jazzy')
    writer = Writer(args.output, version=9, storage_plugin=StoragePlugin.MCAP
                    if args.storage == 'mcap' else StoragePlugin.SQLITE3)
    counts = {topic: 0 for topic in topics}
    writer.open()
    try:
        connections = {topic: writer.add_connection(topic, types[topic], typestore=typestore)
                       for topic in topics}

        def taker(topic):
            def take(data: bytes) -> None:
                writer.write(connections[topic], time.time_ns(), data)
                counts[topic] += 1
            return take
        for topic in topics:
            client.node.create_subscription(message_type(types[topic]), topic, taker(topic),
                                            adapted_qos(client, topic, 1000), raw=True)
        print(f'recording {", ".join(topics)} to {args.output} (Ctrl-C stops)', file=out,
              flush=True)
        end = time.monotonic() + args.duration if args.duration else None
        try:
            while end is None or time.monotonic() < end:
                client.executor.spin_once(timeout_sec=0.05)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
    finally:
        writer.close()
    print(f'recorded {sum(counts.values())} messages: ' + ', '.join(
        f'{topic} {count}' for topic, count in counts.items()), file=out)
    return EXIT_OK


# -- the command ----------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before parsing)."""
    parser = argparse.ArgumentParser(
        prog=PROG, description='Talk to a running collision_sensor_node as the ros2 command '
        'line would: parameters, topics, trajectories, scene files, bags.',
        epilog='Exit status: 0 done, 1 refused by the node (its reason printed), 2 error. '
               'Names are resolved as ROS resolves them (--ros-args -r __ns:=/robot1 makes '
               'relative ones relative to /robot1).')
    parser.add_argument('--timeout', type=float, default=TIMEOUT, metavar='S',
                        help='seconds to wait for a node, topic or service (default '
                             '%(default)s)')
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    param = commands.add_parser('param', help='list, get or set a node\'s parameters '
                                '(ros2 param)')
    actions = param.add_subparsers(dest='action', required=True, metavar='ACTION')
    for action in ('list', 'get', 'set'):
        sub = actions.add_parser(action, help=f'{action} parameters')
        sub.add_argument('node', metavar='NODE', help='e.g. /robot1/collision_sensor')
        if action != 'list':
            sub.add_argument('name', metavar='NAME')
        if action == 'set':
            sub.add_argument('value', metavar='VALUE', help='a YAML value: 0.02, true, '
                             '"[a:b, c:d]"')

    echo = commands.add_parser('echo', help='print the messages of a topic (ros2 topic echo)')
    echo.add_argument('topic', metavar='TOPIC')
    echo.add_argument('--type', metavar='pkg/msg/Type', help='the type, if not on the graph yet')
    echo.add_argument('--once', action='store_true', help='print one message and exit')
    echo.add_argument('--count', type=int, metavar='N', help='print N messages and exit')
    echo.add_argument('--full', action='store_true', help='print long arrays in full')

    trajectory = commands.add_parser(
        'trajectory', help='send a JointTrajectory from a YAML file and print the node\'s '
        'answer (ros2 topic pub --once)')
    trajectory.add_argument('topic', metavar='TOPIC', help='the node\'s trajectory topic')
    trajectory.add_argument('file', metavar='FILE', help='the JointTrajectory as YAML, as ros2 '
                            'topic pub takes it (- for standard input)')
    trajectory.add_argument('--result-topic', metavar='TOPIC',
                            help='where the answer comes (default: trajectory_result beside '
                                 'TOPIC)')

    scene = commands.add_parser('scene', help='send a scene file\'s objects to the node\'s '
                                'scene topic and print its answer')
    scene.add_argument('topic', metavar='TOPIC', help='the node\'s scene topic')
    scene.add_argument('file', metavar='FILE', nargs='?', help='a scene file (docs/'
                       'dynamic_scene.md): its objects are added or replaced')
    scene.add_argument('--frame', default='', metavar='LINK',
                       help='attach the objects to this link (poses in its frame)')
    scene.add_argument('--touch', action='append', default=[], metavar='LINK',
                       help='a link the objects may touch (repeatable)')
    scene.add_argument('--delete', action='append', default=[], metavar='NAME',
                       help='remove this object (repeatable)')
    scene.add_argument('--delete-all', action='store_true',
                       help='first remove every object that came through the topic')
    scene.add_argument('--package-path', action='append', default=[], metavar='NAME=DIR',
                       help='directory of a package named in package:// mesh URIs')

    record = commands.add_parser('record', help='record topics to a rosbag2 bag (ros2 bag '
                                 'record), which collision_sensor_check and _play read')
    record.add_argument('topics', metavar='TOPIC', nargs='+')
    record.add_argument('-o', '--output', required=True, metavar='DIR')
    record.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    record.add_argument('--duration', type=float, metavar='S', help='stop after S seconds')
    for sub in (trajectory, scene):
        sub.add_argument('--answer-timeout', type=float, default=30.0, metavar='S',
                         help='seconds to wait for the node\'s answer (default %(default)s)')
    return parser


RUN = {'param': run_param, 'echo': run_echo, 'trajectory': run_trajectory,
       'scene': run_scene, 'record': run_record}


def main(argv: Optional[Sequence[str]] = None, context=None, out=None) -> int:
    """Run one command; return its exit status.

    :param argv: arguments without the program name (default ``sys.argv[1:]``), ROS
        arguments after ``--ros-args``.
    :param context: an rclpy Context to initialise and use (default: a new one).
    :param out: where to print (default standard output).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    out = out or sys.stdout
    try:
        args = build_parser().parse_args(remove_ros_args([PROG] + argv)[1:])
    except SystemExit as exit_request:
        return exit_request.code if isinstance(exit_request.code, int) else EXIT_ERROR
    # A caller's context (a test's) keeps its process's signal handlers; as a program,
    # rclpy's shut the context down on Ctrl-C, which ends the command.
    own = context is None
    context = context or rclpy.Context()
    rclpy.init(args=[PROG] + argv, context=context,
               signal_handler_options=None if own else SignalHandlerOptions.NO)
    client = None
    try:
        client = Client(context, args.timeout)
        return RUN[args.command](client, args, out)
    except BrokenPipeError:     # the reader stopped (| head)
        return EXIT_OK
    except (CollisionSensorError, OSError) as error:
        print(f'{PROG}: error: {" ".join(str(error).split())}', file=sys.stderr)
        return EXIT_ERROR
    except (KeyboardInterrupt, ExternalShutdownException):
        return EXIT_OK
    finally:
        if client is not None:
            client.close()
        rclpy.try_shutdown(context=context)


if __name__ == '__main__':
    sys.exit(main())
