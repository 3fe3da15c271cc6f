"""The node's log: throttled warnings, and lines collected under the lock written after it.

No log line is written while the node's lock is held (logging can block on a slow stdout): code
that holds the lock appends notes ``(level, throttle kind or None, text)`` to a list, and the
list is written with :meth:`NodeLog.write` once the lock is released.
"""
import collections
import threading
from typing import Callable, Dict, Iterable, Optional, Tuple

#: s between two warnings of one kind.
WARNING_PERIOD = 1.0
#: Kinds whose lines come at most once per this many seconds (a planner that pauses makes many
#: stale episodes): the next line says how many were held back.
LONG_PERIODS = {'stale': 30.0, 'resumed': 30.0}

#: ``(level, throttle kind or None, text)``: level ``'info'``, ``'warning'`` or ``'error'``.
Note = Tuple[str, Optional[str], str]


class Throttle:
    """Let one message per key through per period, and count the ones held back."""

    def __init__(self, period: float):
        self.period = period
        self._last: Dict[str, float] = {}
        self._held = collections.Counter()
        self._lock = threading.Lock()   # used from the checking, scene and executor threads

    def admit(self, key: str, now: float, period: Optional[float] = None) -> Optional[int]:
        """Return how many were held back since the last one, or None to hold this one.

        :param period: this key's period instead of :attr:`period`.
        """
        with self._lock:
            last = self._last.get(key)
            if last is not None and now - last < (self.period if period is None else period):
                self._held[key] += 1
                return None
            self._last[key] = now
            return self._held.pop(key, 0)


class NodeLog:
    """Write a node's log lines, throttled by kind.

    :param logger: the node's ``RcutilsLogger``.
    :param context_ok: returns False once the node's context is shut down (nothing is written
        then: rosout is gone, and the lines would only be noise).
    :param clock: monotonic seconds.
    """

    def __init__(self, logger, context_ok: Callable[[], bool], clock: Callable[[], float]):
        self._logger = logger
        self._context_ok = context_ok
        self._clock = clock
        self.throttle = Throttle(WARNING_PERIOD)

    def log(self, level: str, text: str) -> None:
        """Write ``text`` at ``level`` now."""
        if not self._context_ok():
            return
        # One call site per severity: rclpy ties each call site to one severity.
        logger = self._logger
        if level == 'info':
            logger.info(text)
        elif level == 'error':
            logger.error(text)
        else:
            logger.warning(text)

    def warn(self, kind: str, text: str, level: str = 'warning') -> None:
        """Write ``text`` unless a line of ``kind`` was written less than a period ago; the
        next line of that kind says how many were held back."""
        period = LONG_PERIODS.get(kind)
        held = self.throttle.admit(kind, self._clock(), period)
        if held is None:
            return
        if not held:
            self.log(level, text)
        elif period is None:
            self.log(level, f'{text} ({held} more like this in the last {WARNING_PERIOD:g} s)')
        else:
            self.log(level, f'{text} ({held} more since the last report)')

    def write(self, notes: Iterable[Note]) -> None:
        """Write the notes collected under the lock."""
        for level, kind, text in notes:
            if kind is None:
                self.log(level, text)
            else:
                self.warn(kind, text, level)
