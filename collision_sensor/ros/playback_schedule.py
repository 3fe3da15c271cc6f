"""When the player publishes what: each frame's offset from the start, a loop's period, and
each cloud's turn (at recorded timing, or after a frame). Plain arrays, no ROS.
"""
from typing import Optional

import numpy as np

from collision_sensor.model.sequences import JointSequence

#: s: a cloud logged later than this after its stamp is taken as logged on another clock.
MAX_CLOUD_DELAY = 1.0


def frame_offsets(times: np.ndarray, rate: Optional[float] = None) -> np.ndarray:
    """Return when each frame is due, in seconds after playback starts.

    :param times: (n,) float recorded times, increasing.
    :param rate: frames per second, or None to follow the recorded times.
    :return: (n,) float, starting at 0.
    """
    times = np.asarray(times, dtype=np.float64)
    if rate is not None:
        return np.arange(len(times)) / float(rate)
    return times - times[0] if len(times) else times


def loop_period(offsets: np.ndarray) -> float:
    """Return the time from the first frame of one loop to the first of the next.

    The last frame stands as long as the median frame gap before the sequence restarts.
    """
    if len(offsets) < 2:
        return 1.0 if len(offsets) == 0 else max(float(offsets[-1]), 0.0) + 0.1
    return float(offsets[-1] + np.median(np.diff(offsets)))


def cloud_after_frame(seq: JointSequence) -> np.ndarray:
    """Return, per cloud of ``seq``, the frame it is published after with ``--rate`` and
    ``--as-fast-as-possible``: the first frame at or after its stamp (the last frame for the
    later ones), -1 for those stamped before the first frame."""
    times = np.array([event.time for event in seq.clouds], dtype=np.float64)
    after = np.minimum(np.searchsorted(seq.times, times, side='left'), len(seq) - 1)
    return np.where(times < seq.times[0], -1, after)


def recorded_cloud_offsets(seq: JointSequence) -> np.ndarray:
    """Return when each cloud of ``seq`` is published at recorded timing, in seconds after
    the first frame: at its stamp plus the delay it was logged with (a log time before the
    stamp or more than :data:`MAX_CLOUD_DELAY` after it is another clock's, a bag of
    simulated time: no delay), never before the cloud before it."""
    stamps = np.array([e.time for e in seq.clouds], dtype=np.float64)
    delay = np.array([e.log_time for e in seq.clouds], dtype=np.float64) - stamps
    delay = np.where((delay >= 0.0) & (delay <= MAX_CLOUD_DELAY), delay, 0.0)
    return np.maximum.accumulate(stamps + delay - float(seq.times[0])) if len(stamps) \
        else stamps
