"""A thread of the node's own that takes work handed over by a subscription's callback, in
order, and under overload answers the newest instead of queueing old ones."""
import os
import queue
import threading
from typing import Callable, Optional

#: The joint-state rate the node is specified for (Hz): every joint state is answered up to it.
MAX_INPUT_RATE = 2000.0
#: Joint states that may wait at once before only the newest is answered: 0.1 s at
#: :data:`MAX_INPUT_RATE`, as the answers' history (``verdict_topics.VERDICT_DEPTH``).
MAX_BACKLOG = int(0.1 * MAX_INPUT_RATE)
#: The niceness added to the threads of work that yields to the joint states' verdicts.
BACKGROUND_NICE = 10


class NewestFirstWorker:
    """Handle messages on a thread of its own, handed over by a subscription's callback; under
    overload answer the newest message instead of queueing old ones.

    The executor's callback only puts each message on a queue (a C-level ``SimpleQueue``: no
    lock in Python, no allocation beyond the queue's slot), so the executor goes back to taking
    the next message at once. This thread wakes on the first message and takes every message
    waiting, in order:

    - at most ``max_backlog`` waiting (the node keeps up; the usual case, one message per
      wake-up): ``handle(batch, False)``, each to be answered in input order;
    - more than that (the input is faster than the node): ``handle(batch, True)``, every one
      still to be merged, but only the newest answered. The node stays within ``max_backlog``
      messages of the input instead of drifting behind it.

    :param handle: called with ``(messages, newest_only)`` on this thread.
    :param name: the thread's name.
    :param max_backlog: ``None``: every message answered, however many wait.
    :param nice: added to the thread's scheduling niceness (Linux: a thread's own; elsewhere
        nothing): work that must not delay the joint states' verdicts (point clouds, planned
        trajectories) yields the cores to them when both want one.
    """

    _STOP = object()

    def __init__(self, handle: Callable[[list, bool], None], name: str,
                 max_backlog: Optional[int] = MAX_BACKLOG, nice: int = 0):
        self._handle = handle
        self._max_backlog = max_backlog
        self._nice = nice
        self._queue = queue.SimpleQueue()
        self.put = self._queue.put      # the subscription's callback
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        if self._nice:
            lower_priority(self._nice)
        get, get_nowait, stop = self._queue.get, self._queue.get_nowait, self._STOP
        while True:
            batch = [get()]
            try:
                while True:
                    batch.append(get_nowait())
            except queue.Empty:
                pass
            if any(item is stop for item in batch):
                return
            limit = self._max_backlog
            self._handle(batch, limit is not None and len(batch) > limit)

    def backlog(self) -> int:
        """Return how many messages wait (approximately: another thread may be taking one)."""
        return self._queue.qsize()

    def stop(self) -> None:
        """Stop the thread and wait for it (the messages being handled are finished first)."""
        self._queue.put(self._STOP)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)


def lower_priority(nice: int) -> bool:
    """Add ``nice`` to the calling thread's niceness (Linux schedules threads one by one: the
    thread's id is a process id to ``setpriority``); return False where that cannot be done."""
    native_id = getattr(threading, 'get_native_id', None)
    if native_id is None or not hasattr(os, 'setpriority') or not os.path.isdir('/proc/self/task'):
        return False
    try:
        tid = native_id()
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + nice)
    except OSError:
        return False
    return True
