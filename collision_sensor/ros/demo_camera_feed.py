"""The demo's depth camera on the ROS graph (``collision_sensor_demo --camera``): renders the
cell at each cloud's time (:class:`~collision_sensor.tools.demo_camera.CameraCell`), publishes
``sensor_msgs/PointCloud2``, and holds what the sensor said against how far the arm truly was
from the person.
"""
import math
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

from collision_sensor.ros.demo_verdicts import (
    Pair, Verdicts, change_lines, pairs_text, stamp_nanoseconds)

CLOUD_VERDICT_TIMEOUT = 10.0   # s for the node's verdict on one cloud (a lost or refused cloud)


@dataclass
class CameraRecord:
    """One verdict in camera mode: at ``t`` (s from the first frame), on the arm's state then,
    answering a frame (``cloud`` None) or cloud number ``cloud``; ``person``: how far the arm
    truly is from the person (m, <= 0 in contact; inf: more than 10 cm)."""

    t: float
    pairs: Tuple[Pair, ...]
    cloud: Optional[int]
    person: float


class CameraFeed:
    """The demo's depth camera: renders the cell (:class:`CameraCell`) at a cloud's time and
    publishes it as ``sensor_msgs/PointCloud2``; keeps what the sensor said beside the truth.

    :param seq: the sequence the arm plays (the clouds' times span it, ``rate`` per second).
    :param size: ``(width, height)`` pixels.
    :param rate: clouds per second of the recording.
    """

    def __init__(self, seq, size: Tuple[int, int], rate: float):
        from collision_sensor.tools.demo_camera import (
            CAMERA_OPTICAL_FRAME, CLOUD_TOPIC, CameraCell)
        self.cell = CameraCell(size)
        self.seq, self.rate, self.size = seq, float(rate), (int(size[0]), int(size[1]))
        self.topic, self.frame = CLOUD_TOPIC, CAMERA_OPTICAL_FRAME
        self.source = f'cloud/{CLOUD_TOPIC}'
        t0, t1 = float(seq.times[0]), float(seq.times[-1])
        self.times = t0 + np.arange(int(math.floor((t1 - t0) * self.rate + 1e-9)) + 1) / self.rate
        self.sent = 0
        self.render_seconds = 0.0
        self.valid_points = 0
        self.records: List[CameraRecord] = []
        self.publisher = None

    def start(self, node) -> None:
        """Create the publisher on ``node`` (sensor-data QoS, as the node subscribes)."""
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import PointCloud2
        self.publisher = node.create_publisher(PointCloud2, self.topic, qos_profile_sensor_data)

    def due(self, t: float) -> List[int]:
        """The clouds not sent yet whose time is at most ``t`` (s, recorded time)."""
        end = int(np.searchsorted(self.times, t + 1e-9, side='right'))
        return list(range(self.sent, max(end, self.sent)))

    def state_at(self, t: float) -> np.ndarray:
        """The arm's joint values at ``t`` (linear between frames, as the node places a
        cloud)."""
        seq = self.seq
        return np.array([np.interp(t, seq.times, seq.positions[:, j])
                         for j in range(len(seq.joint_names))])

    def publish(self, k: int) -> None:
        """Render cloud ``k`` and publish it, stamped with its time."""
        from sensor_msgs.msg import PointCloud2, PointField
        from std_msgs.msg import Header
        t = float(self.times[k])
        started = time.perf_counter()
        points = self.cell.render(self.seq.joint_names, self.state_at(t))
        self.render_seconds += time.perf_counter() - started
        self.valid_points += int(np.isfinite(points).all(axis=1).sum())
        width, height = self.size
        stamp_ns = stamp_nanoseconds(t)
        header = Header(frame_id=self.frame)
        header.stamp.sec, header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        fields = [PointField(name=axis, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, axis in enumerate('xyz')]
        self.publisher.publish(PointCloud2(
            header=header, height=height, width=width, fields=fields, is_bigendian=False,
            point_step=12, row_step=12 * width,
            data=np.ascontiguousarray(points, dtype='<f4').tobytes(), is_dense=False))
        self.sent = k + 1

    def record(self, t: float, pairs: Tuple[Pair, ...], cloud: Optional[int], q,
               previous: Tuple[Pair, ...]) -> List[str]:
        """Keep one verdict at state ``q``; return the lines of its change of pairs."""
        person = self.cell.clearance(self.seq.joint_names, q).person
        self.records.append(CameraRecord(t, pairs, cloud, person))
        if pairs == previous:
            return []
        lines = change_lines(t, previous, pairs)
        by = 'frame' if cloud is None else f'cloud {cloud}'
        lines[0] += f'   ({by}; the arm {_person_text(person)})'
        return lines

    def summary_lines(self, played: float, verdicts: Verdicts, diagonal: float) -> List[str]:
        """The camera summary: clouds, the node's filter, contacts against the truth."""
        seq, records, n = self.seq, self.records, len(self.seq)
        frames = [r for r in records if r.cloud is None]
        clouds = [r for r in records if r.cloud is not None]
        width, height = self.size
        lines = [f'summary of {seq.source} (camera {width} x {height} at {self.rate:g} Hz in '
                 f'{self.frame}, clouds on {self.topic})',
                 f'  frames:              {n} played in {played:.2f} s, {len(frames)} verdicts',
                 f'  clouds:              {self.sent} rendered by ray casting (mean '
                 f'{1e3 * self.render_seconds / max(self.sent, 1):.1f} ms each, '
                 f'{self.valid_points / max(self.sent, 1):.0f} of {width * height} points, '
                 f'the rest NaN), sent, {len(clouds)} answered by a verdict at once']
        status = verdicts.cloud_status
        if status:
            lines.append(f'  the node\'s filter (/diagnostics, a cloud of the last period): '
                         f'{status.get("points_in")} points in, {status.get("points_invalid")} '
                         f'NaN, {status.get("points_self_filtered")} self-filtered (the arm\'s), '
                         f'{status.get("points_kept")} kept in {status.get("voxels_kept")} voxels'
                         f'; clouds accepted {status.get("clouds_accepted_total")}, rejected '
                         f'{status.get("clouds_rejected_total")}')
        spans: Dict[Pair, List[float]] = {}
        for r in records:
            for pair in r.pairs:
                span = spans.setdefault(pair, [r.t, r.t, 0])
                span[1], span[2] = r.t, span[2] + 1
        if spans:
            width_ = max(len(f'{a} -- {b}') for a, b in spans)
            lines.append('  pairs in contact (times from the first frame):')
            for (a, b), (first, last, count) in sorted(spans.items(), key=lambda s: s[1][0]):
                lines.append(f'    {a + " -- " + b:<{width_}}  first {first:7.3f} s  '
                             f'last {last:7.3f} s  {count:4d} verdicts')
        else:
            lines.append('  pairs in contact:    none')
        hits = [r for r in records if any(self.source in pair for pair in r.pairs)]
        touching = [r for r in frames if r.person <= 0.0]
        if touching:
            inside = [r for r in records if r.person <= 0.0]
            seen = sum(any(self.source in pair for pair in r.pairs) for r in inside)
            lines.append(f'  the person (in no scene file): the arm in contact at '
                         f'{len(touching)} frames, {touching[0].t:.3f} s to {touching[-1].t:.3f} s'
                         f'; contact with the cloud in {seen} of the {len(inside)} verdicts '
                         'meanwhile (the person\'s points within the self-filter\'s padding of '
                         'the arm go with the arm\'s: docs/point_clouds.md, what a cloud can '
                         'tell)')
        else:
            lines.append('  the person (in no scene file): the arm never touches it')
        if hits:
            first = hits[0]
            by = 'a frame' if first.cloud is None else f'cloud {first.cloud}'
            lines.append(f'  first contact with the cloud: {first.t:.3f} s ({by}\'s verdict), '
                         f'{pairs_text([p for p in first.pairs if self.source in p])}; the arm '
                         f'{_person_text(first.person)}')
        else:
            lines.append('  first contact with the cloud: none')
        away = [r for r in records if r.person > diagonal]
        false = [r for r in away if any(self.source in pair for pair in r.pairs)]
        lines.append(f'  the arm farther than {1e3 * diagonal:.0f} mm (a voxel\'s diagonal) from '
                     f'the person: {sum(r.cloud is None for r in away)} frame and '
                     f'{sum(r.cloud is not None for r in away)} cloud verdicts, '
                     f'{len(false)} of them with contact with the cloud'
                     + (': the self-filter kept the arm\'s own points out' if not false else
                        ' (points that are not the person\'s were kept)'))
        for kind, count in sorted(verdicts.failures.items()):
            lines.append(f'  fail-safe entries {kind}: {count} verdicts')
        if verdicts.check_time.checks:
            check = verdicts.check_time
            lines.append(f'  node check time (/diagnostics): mean '
                         f'{check.total_ms / check.checks:.3f} ms, max {check.max_ms:.3f} ms '
                         f'over {check.checks} checks')
        lines.append('  result: ' + ('COLLISION' if spans else 'clear')
                     + (' (with the camera\'s cloud only: no scene file holds the person)'
                        if spans and all(self.source in pair for pair in spans) else ''))
        return lines


def _person_text(distance: float) -> str:
    if distance <= 0.0:
        return 'touches the person'
    if math.isinf(distance):
        return 'more than 10 cm from the person'
    return f'{1e3 * distance:.0f} mm from the person'
