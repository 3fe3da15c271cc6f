"""The engine's arrays packed into two flat buffers, which the compiled engine reads in place.

The engine (``cpp/layout.hpp``) names every array it reads from the checker, its group and
its shape in the model's dimensions, in two tables the extension exports
(``engine.FLOAT_SLOTS``, ``engine.INT_SLOTS``: ``(name, group, shape)``, shape entries an
int or a dimension's name such as ``'pairs'`` or ``'joints+1'``). :func:`pack` puts a dict
of arrays into one float64 and one int64 buffer in the tables' order, each array with its
layout row ``(offset, size, d0, d1, d2)``; the engine cuts the buffers back into named arrays
by these rows, once, when it is made, and checks each against its table. Python keeps views of
the same memory, so any array can be inspected without a copy, and a query crosses the binding
with one array.

Groups: ``model`` (what a query reads and never writes), ``state`` (the carried incremental
state, carried over a scene change pair by pair), ``work`` (what the engine works in and the
checker may read; fresh after a scene change).
"""
import contextlib
import threading
from typing import Dict, Mapping, NamedTuple, Tuple

import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.errors import EngineBuildError


class Slot(NamedTuple):
    """One packed array as the engine declares it.

    :ivar shape: each extent an int, or a dimension's name, ``'name'`` or ``'name+k'``.
    """

    name: str
    dtype: np.dtype
    group: str
    shape: Tuple


#: Every slot, float64 ones first, in the engine's order.
SLOTS: Tuple[Slot, ...] = tuple(
    Slot(name, np.dtype(dtype), group, tuple(shape))
    for dtype, table in ((np.float64, engine.FLOAT_SLOTS), (np.int64, engine.INT_SLOTS))
    for name, group, shape in table)
#: The model's dimensions the shapes are written in.
DIMS: Tuple[str, ...] = tuple(engine.DIMS)

#: Every packed array starts on a cache line of its own: the traversal reads table rows
#: (16 floats a box, 4 ints a node) that must not straddle two lines: a row split over two
#: lines costs two loads at every node pair of every descent.
CACHE_LINE_BYTES = 64


class Packed(NamedTuple):
    """The two buffers, their layout rows and a view of each array by name."""

    F: np.ndarray
    F_layout: np.ndarray
    I: np.ndarray
    I_layout: np.ndarray
    views: Dict[str, np.ndarray]


def slots(group: str) -> Tuple[Slot, ...]:
    """Return the slots of one group (``'model'``, ``'state'`` or ``'work'``)."""
    return tuple(slot for slot in SLOTS if slot.group == group)


def shape_of(slot: Slot, dims: Mapping[str, int]) -> Tuple[int, ...]:
    """Return ``slot``'s shape for the dimensions ``dims`` (``{'links': 9, ...}``)."""
    out = []
    for extent in slot.shape:
        if isinstance(extent, str):
            name, _, plus = extent.partition('+')
            extent = dims[name] + int(plus or 0)
        out.append(int(extent))
    return tuple(out)


#: numpy's switch of its transparent huge page advice (None where this numpy has none).
_HUGE_PAGE_ADVICE = getattr(getattr(np, '_core', getattr(np, 'core', None)), 'multiarray', None)
_HUGE_PAGE_ADVICE = getattr(_HUGE_PAGE_ADVICE, '_set_madvise_hugepage', None)
_huge_page_lock = threading.Lock()
_huge_page_holders = 0      # normal_pages() entered and not left
_huge_page_setting = True   # numpy's setting before the first of them


@contextlib.contextmanager
def normal_pages():
    """Arrays made inside are of normal pages: numpy asks the kernel for transparent huge pages
    for every array of 4 MiB or more, and where the kernel then compacts memory on the first
    touch (THP ``defrag`` ``madvise``, Ubuntu's default), filling a large model's fresh arrays
    stalls: building the SO-101 (398,884 triangles) spent about 1 s of system time so, for no
    measurable gain in the checks after. Nested and threaded uses keep numpy's setting off
    until the last one leaves, then restore it."""
    global _huge_page_holders, _huge_page_setting
    if _HUGE_PAGE_ADVICE is None:
        yield
        return
    with _huge_page_lock:
        if _huge_page_holders == 0:
            _huge_page_setting = _HUGE_PAGE_ADVICE(False)
        _huge_page_holders += 1
    try:
        yield
    finally:
        with _huge_page_lock:
            _huge_page_holders -= 1
            if _huge_page_holders == 0:
                _HUGE_PAGE_ADVICE(_huge_page_setting)


def _aligned_zeros(n: int, dtype: np.dtype) -> np.ndarray:
    """Return n zeros whose first item starts on a cache line (a view of a larger array)."""
    pad = CACHE_LINE_BYTES // dtype.itemsize
    raw = np.zeros(n + pad, dtype=dtype)
    start = (-raw.ctypes.data % CACHE_LINE_BYTES) // dtype.itemsize
    return raw[start:start + n]


def _pack_one(dtype: np.dtype, table, arrays: Mapping[str, np.ndarray]):
    """One buffer: its arrays in the table's order, each on a cache line of its own."""
    line = CACHE_LINE_BYTES // dtype.itemsize
    converted = [np.asarray(arrays[name], dtype=dtype) for name, _, _ in table]
    layout = np.zeros((len(table), engine.LAYOUT_WIDTH), dtype=np.int64)
    offset = 0
    for k, array in enumerate(converted):
        if not 1 <= array.ndim <= 3:
            raise EngineBuildError(f'{table[k][0]}: only 1 to 3 dimensions can be packed, '
                                   f'got {array.ndim}')
        layout[k] = (offset, array.size) + array.shape + (1,) * (3 - array.ndim)
        offset += -(-array.size // line) * line
    buffer = _aligned_zeros(max(offset, 1), dtype)
    views = {}
    for (name, _, _), array, row in zip(table, converted, layout):
        view = buffer[row[0]:row[0] + row[1]].reshape(array.shape)
        view[...] = array
        views[name] = view
    return buffer, layout, views


def pack(arrays: Mapping[str, np.ndarray]) -> Packed:
    """Pack one array per slot (converted to the slot's dtype) into the two buffers.

    :param arrays: ``{slot name: array}``, every slot of :data:`SLOTS` and no other.
    :raises EngineBuildError: a slot missing or unknown, or of more than 3 dimensions (the
        engine then checks every shape).
    """
    names = {slot.name for slot in SLOTS}
    missing, unknown = names - arrays.keys(), arrays.keys() - names
    if missing or unknown:
        raise EngineBuildError(f'packed arrays: missing {sorted(missing)}, unknown '
                               f'{sorted(unknown)}; the checker and the engine disagree on the '
                               'layout')
    F, F_layout, float_views = _pack_one(np.dtype(np.float64), engine.FLOAT_SLOTS, arrays)
    I, I_layout, int_views = _pack_one(np.dtype(np.int64), engine.INT_SLOTS, arrays)
    return Packed(F, F_layout, I, I_layout, {**float_views, **int_views})
