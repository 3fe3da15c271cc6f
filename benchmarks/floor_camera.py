"""ROS 2's floor beside a depth camera: does a camera slow the C echo's joint states as it slows
the node's?

``python -m benchmarks.floor_camera --floor ../shared/floor [--runs 3] [--rate 1000]
[--duration 15] [--camera-rate 30] [--cloud-size 640x480]`` runs the floor probe's joint-state
stream (``floor_probe.py`` of the floor folder: reliable JointState at ``--rate``, each answer
timed from its publish stamp) against four answerers in turn within each run:

- ``rcl``: a C program over rcl (``echo_rcl_camera.c``: the floor folder's echo, which also
  takes every PointCloud2 on ``points``, serialized, and drops it), no camera publishing;
- ``rcl_camera``: the same, with a camera process publishing organised clouds (``--cloud-size``,
  x, y, z and padding as a depth camera's driver sends them, 16 bytes a point) on ``points`` at
  ``--camera-rate`` Hz, sensor-data QoS;
- ``node``: ``collision_sensor_node`` on the Panda, as the probe starts it;
- ``node_camera``: the node with ``point_cloud_topics: [points]``, the same camera publishing
  (the cloud is a wall 3 m in front of the robot: checked, never in contact).

It prints the probe's line per answerer and run, then min / median / max over the runs, and per
run the p99 with the camera over the p99 without, for the echo and for the node: if the echo's
ratio is near the node's, the camera's cost to the joint states is the machine's (taking the
clouds), not the node's.
"""
import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

from benchmarks.node_floor import load_probe

HERE = os.path.dirname(os.path.abspath(__file__))
CLOUD_TOPIC = 'points'
ANSWERERS = ('rcl', 'rcl_camera', 'node', 'node_camera')

#: The camera process: pre-serialized organised clouds published at a rate (argv: namespace,
#: rate, width, height, frame).
CAMERA = r'''
import sys, time
import numpy as np
import rclpy
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2, PointField
namespace, rate, width, height, frame = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), \
    int(sys.argv[4]), sys.argv[5]
rclpy.init()
node = rclpy.create_node('camera', namespace=namespace)
publisher = node.create_publisher(PointCloud2, 'points', qos_profile_sensor_data)
v, u = np.mgrid[0:height, 0:width]
points = np.zeros((height, width, 4), dtype=np.float32)
points[..., 0] = 3.0                                     # a wall 3 m ahead
points[..., 1] = (u - width / 2) * 3.0 / 525.0
points[..., 2] = 0.5 - (v - height / 2) * 3.0 / 525.0
points[::7, ::11, :3] = np.nan                           # holes, as a depth camera has
fields = [PointField(name=n, offset=4 * k, datatype=PointField.FLOAT32, count=1)
          for k, n in enumerate('xyz')]
msg = PointCloud2(height=height, width=width, fields=fields, is_bigendian=False, point_step=16,
                  row_step=16 * width, data=points.tobytes(), is_dense=False)
msg.header.frame_id = frame
period, start, k = 1.0 / rate, time.perf_counter(), 0
try:
    while rclpy.ok():
        wait = start + k * period - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        msg.header.stamp = node.get_clock().now().to_msg()
        publisher.publish(msg)
        k += 1
except BaseException:
    pass
'''


def build_echo(venv: str, floor: str, build: str) -> str:
    """Compile ``echo_rcl_camera.c`` as the floor folder's ``build_echo.sh`` compiles its echo
    (which it runs first, for the library paths); return the binary's path."""
    subprocess.run([os.path.join(floor, 'build_echo.sh'), venv, build], check=True,
                   stdout=subprocess.DEVNULL)
    includes = [f'-I{venv}/include/{name}' for name in (
        'rcl', 'rmw', 'rcutils', 'rosidl_runtime_c', 'rosidl_typesupport_interface',
        'rosidl_dynamic_typesupport', 'type_description_interfaces', 'service_msgs',
        'builtin_interfaces', 'rcl_yaml_param_parser', 'rcl_interfaces',
        'rosidl_typesupport_c')]
    with open(os.path.join(build, 'libs')) as stream:
        libs = stream.read().strip()
    binary = os.path.join(build, 'echo_rcl_camera')
    subprocess.run(['gcc', '-O2', '-w', '-o', binary, os.path.join(HERE, 'echo_rcl_camera.c'),
                    *includes, f'-L{venv}/lib', '-lrcl', '-lrmw', '-lrcutils',
                    '-lrosidl_runtime_c', '-lsensor_msgs__rosidl_typesupport_c',
                    '-ldiagnostic_msgs__rosidl_typesupport_c', '-Wl,--allow-shlib-undefined',
                    f'-Wl,-rpath,{libs}'], check=True)
    return binary


class Answerers:
    """Starts what the probe times (its ``start``), and the camera beside the ``_camera`` ones."""

    def __init__(self, probe, echo: str, args):
        self.probe, self.echo, self.args = probe, echo, args
        self.camera = None
        self._start = probe.start

    def start(self, kind, ns, venv, build):
        with_camera = kind.endswith('_camera')
        if with_camera:
            width, height = (int(x) for x in self.args.cloud_size.split('x'))
            frame = 'panda_link0'
            self.camera = subprocess.Popen(
                [sys.executable, '-c', CAMERA, ns, str(self.args.camera_rate), str(width),
                 str(height), frame], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if kind.startswith('rcl'):
            env = dict(os.environ, AMENT_PREFIX_PATH=venv)
            with open(os.path.join(build, 'pylib')) as stream:
                env['LD_PRELOAD'] = stream.read().strip()
            with open(os.path.join(build, 'libs')) as stream:
                env['LD_LIBRARY_PATH'] = stream.read().strip()
            return subprocess.Popen([self.echo, ns], env=env, stderr=subprocess.DEVNULL)
        if not with_camera:
            return self._start('node', ns, venv, build)
        real = self.probe.subprocess.Popen

        def popen(command, **kwargs):    # the probe's node command, with the cloud topic
            at = command.index('--ros-args') + 1
            return real(command[:at] + ['-p', f"point_cloud_topics:=['{CLOUD_TOPIC}']"]
                        + command[at:], **kwargs)
        self.probe.subprocess.Popen = popen
        try:
            return self._start('node', ns, venv, build)
        finally:
            self.probe.subprocess.Popen = real

    def stop_camera(self):
        if self.camera is not None:
            self.camera.send_signal(signal.SIGINT)
            try:
                self.camera.wait(10)
            except subprocess.TimeoutExpired:
                self.camera.kill()
            self.camera = None


def spread(values) -> str:
    return ' / '.join(f'{v:.3g}' for v in (min(values), float(np.median(values)), max(values)))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='python -m benchmarks.floor_camera',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--floor', default=os.path.join('..', 'shared', 'floor'))
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--duration', type=float, default=15.0)
    parser.add_argument('--camera-rate', type=float, default=30.0)
    parser.add_argument('--cloud-size', default='640x480')
    parser.add_argument('--venv', default='.venv')
    args = parser.parse_args(argv)
    os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'SHM')
    os.environ.setdefault('ROS_DOMAIN_ID', '94')
    probe = load_probe(args.floor)
    venv = os.path.abspath(args.venv)
    build = tempfile.mkdtemp(prefix='floor_camera_')
    answerers = Answerers(probe, build_echo(venv, os.path.abspath(args.floor), build), args)
    probe.start = answerers.start
    import rclpy
    rclpy.init()
    rows = {kind: [] for kind in ANSWERERS}
    try:
        for run in range(args.runs):
            for kind in ANSWERERS:      # alternated within each run, as the probe does
                try:
                    row = probe.measure(kind, run, args, venv, build, rclpy)
                finally:
                    answerers.stop_camera()
                rows[kind].append(row)
                if row is None:
                    print(f'{kind} run {run + 1}: never answered', flush=True)
                    continue
                print(f"{kind} run {run + 1}: answered {row['answered']}/{row['sent']} p50 "
                      f"{row['p50']:.3f} ms p99 {row['p99']:.3f} ms max {row['max']:.2f} ms "
                      f"CPU {row['cpu_us']:.0f} us/msg", flush=True)
                time.sleep(1.0)
    finally:
        rclpy.shutdown()
    print(f'\nat {args.rate:.0f} Hz, a {args.cloud_size} camera at {args.camera_rate:.0f} Hz, '
          f'{args.runs} runs of {args.duration:.0f} s (min / median / max):')
    for kind, kind_rows in rows.items():
        measured = [row for row in kind_rows if row]
        if measured:
            lost = sum(row['sent'] - row['answered'] for row in measured)
            print(f"{kind:12s} p50 ms {spread([r['p50'] for r in measured])}  p99 ms "
                  f"{spread([r['p99'] for r in measured])}  CPU us/msg "
                  f"{spread([r['cpu_us'] for r in measured])}  unanswered {lost}")
    for answerer in ('rcl', 'node'):
        pairs = [(a, b) for a, b in zip(rows[answerer], rows[answerer + '_camera']) if a and b]
        if pairs:
            print(f'{answerer:5s} p99 with the camera / without, per run: '
                  f"{spread([b['p99'] / a['p99'] for a, b in pairs])}x")
    return 0


if __name__ == '__main__':
    sys.exit(main())
