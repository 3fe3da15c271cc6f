"""How the benchmark measures time and memory, in one place.

Time: the machine is shared, so every figure is the best of ``rounds`` passes, and the passes
of the implementations being compared are interleaved (ours, peer, ours, peer, ...), so a
burst of load elsewhere hits all of them alike. A pass is a Python loop calling the
implementation once per item; the loop's own cost (tens of ns) is in every figure alike. The
garbage collector is off during a pass, as in ``timeit``.

Memory: resident set size from ``/proc/self/statm``, read before and after building a model.
With glibc, free heap memory is handed back first (``malloc_trim(0)``) on both sides, and the
dynamic mmap threshold is pinned (``mallopt``), so the difference is what the build keeps:
neither memory freed earlier in the run and reused by the build, nor the build's own freed
temporaries, blur it.
"""
import ctypes
import ctypes.util
import gc
import os
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence

M_MMAP_THRESHOLD = -3          # glibc mallopt parameter
MMAP_THRESHOLD_BYTES = 128 * 1024


@dataclass
class Candidate:
    """One implementation to time: ``call(item)`` for each item; ``before()`` once per pass.

    ``before`` is not timed (e.g. a full check that resets an incremental checker's state).
    """

    label: str
    call: Callable
    items: Sequence
    before: Optional[Callable[[], None]] = None


def interleaved_us(candidates: Sequence[Candidate], rounds: int = 3,
                   warm_items: int = 0) -> Dict[str, float]:
    """Return ``{label: best-of-rounds mean time per call, us}``, passes interleaved.

    :param warm_items: before each pass (and before ``before()``), call the candidate,
        untimed, on its first ``warm_items`` items, so that the pass starts with its data
        in the caches rather than the previous candidate's. It matters for a pass that lasts
        well under a millisecond (a whole path in one compiled call), whose first steps
        would otherwise be refilling the caches.
    """
    passes = interleaved_rounds_us(candidates, rounds, warm_items)
    return {label: min(values) for label, values in passes.items()}


def interleaved_rounds_us(candidates: Sequence[Candidate], rounds: int = 3,
                          warm_items: int = 0) -> Dict[str, List[float]]:
    """Return ``{label: [mean time per call of each pass, us]}``, passes interleaved as
    :func:`interleaved_us` runs them (which keeps the best): the spread over rounds."""
    passes: Dict[str, List[float]] = {c.label: [] for c in candidates}
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(rounds):
            for c in candidates:
                for item in c.items[:warm_items]:
                    c.call(item)
                if c.before is not None:
                    c.before()
                call, items = c.call, c.items
                start = time.perf_counter()
                for item in items:
                    call(item)
                elapsed = time.perf_counter() - start
                passes[c.label].append(elapsed / max(1, len(items)) * 1e6)
    finally:
        if enabled:
            gc.enable()
    return passes


def work_per_check(checker, configurations) -> dict:
    """Return the checker's work per full ``check`` over ``configurations`` (untimed).

    :return: ``{'boxes': box tests, 'triangles': triangle tests, 'spheres': box pairs the
        sphere pre-test skipped}``, each a mean per configuration.
    """
    from collision_sensor.engine.traversal import (
        COUNT_BOX_TESTS, COUNT_SPHERE_SKIPS, COUNT_TRIANGLE_TESTS)
    checker.counters[:] = 0
    for q in configurations:
        checker.check(q)
    mean = checker.counters / max(1, len(configurations))
    return {'boxes': float(mean[COUNT_BOX_TESTS]), 'triangles': float(mean[COUNT_TRIANGLE_TESTS]),
            'spheres': float(mean[COUNT_SPHERE_SKIPS])}


def seconds(function: Callable[[], object]):
    """Return ``(function(), wall seconds)``."""
    start = time.perf_counter()
    value = function()
    return value, time.perf_counter() - start


def _libc():
    name = ctypes.util.find_library('c')
    try:
        return ctypes.CDLL(name) if name else None
    except OSError:
        return None


def pin_mmap_threshold() -> bool:
    """Pin glibc's mmap threshold so freed large blocks leave the RSS; False if not glibc."""
    libc = _libc()
    try:
        return bool(libc is not None and libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES))
    except AttributeError:
        return False


def release_free_memory() -> None:
    """Collect garbage and return free heap pages to the system (glibc ``malloc_trim``)."""
    gc.collect()
    libc = _libc()
    try:
        if libc is not None:
            libc.malloc_trim(0)
    except AttributeError:
        pass


def resident_bytes() -> int:
    """Return this process's resident set size in bytes (0 where /proc is missing)."""
    try:
        with open('/proc/self/statm') as stream:
            return int(stream.read().split()[1]) * os.sysconf('SC_PAGE_SIZE')
    except (OSError, ValueError, IndexError):
        return 0


def resident_growth(function: Callable[[], object]):
    """Return ``(function(), RSS growth in bytes, wall seconds)`` around one call."""
    release_free_memory()
    before = resident_bytes()
    value, wall = seconds(function)
    release_free_memory()
    return value, resident_bytes() - before, wall
