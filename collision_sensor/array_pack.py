"""Many arrays of one dtype carried in one flat buffer, to keep kernel calls cheap.

numba checks the type of every array argument on every call (about 0.1-0.2 us each); a query
with forty arrays would spend more time being called than checking a robot. The checker packs
its arrays into a few flat buffers once, and a thin compiled wrapper cuts them back into the
named views the readable kernel takes. Cutting is free: views share the buffer's memory.

``layout[k] = (offset, size, d0, d1, d2)`` describes the k-th array packed in a buffer.
"""
from typing import Dict, List, Tuple

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from collision_sensor.kernel_cache import bind_to_kernel_sources

LAYOUT_WIDTH = 5


#: Every packed array starts on a cache line of its own: the traversal reads table rows
#: (16 floats a box, 4 ints a node) that must not straddle two lines. Without it, adding one
#: small array before the node table once made every UR5 check 1.5 times slower.
CACHE_LINE_BYTES = 64


def _aligned_zeros(n: int, dtype: np.dtype) -> np.ndarray:
    """Return n zeros whose first item starts on a cache line (a view of a larger array)."""
    pad = CACHE_LINE_BYTES // dtype.itemsize
    raw = np.zeros(n + pad, dtype=dtype)
    start = (-raw.ctypes.data % CACHE_LINE_BYTES) // dtype.itemsize
    return raw[start:start + n]


class ArrayPack:
    """Collects arrays of one dtype, then packs them into one buffer with a layout table."""

    def __init__(self, dtype):
        self.dtype = np.dtype(dtype)
        self._arrays: List[np.ndarray] = []
        self.index: Dict[str, int] = {}

    def add(self, name: str, array) -> int:
        """Add ``array`` (1-3 dimensions) under ``name``; return its slot in the layout."""
        array = np.asarray(array, dtype=self.dtype)
        if not 1 <= array.ndim <= 3:
            raise ValueError(f'{name}: only 1 to 3 dimensions can be packed, got {array.ndim}')
        self.index[name] = len(self._arrays)
        self._arrays.append(array)
        return self.index[name]

    def pack(self) -> Tuple[np.ndarray, np.ndarray, Dict[str, np.ndarray]]:
        """Return ``(buffer, layout (K, 5) int64, {name: view into buffer})``."""
        layout = np.zeros((len(self._arrays), LAYOUT_WIDTH), dtype=np.int64)
        line = CACHE_LINE_BYTES // self.dtype.itemsize
        offset = 0
        for k, array in enumerate(self._arrays):
            shape = array.shape + (1,) * (3 - array.ndim)
            layout[k] = (offset, array.size) + shape
            offset += -(-array.size // line) * line
        buffer = _aligned_zeros(max(offset, 1), self.dtype)
        views = {}
        for name, k in self.index.items():
            array = self._arrays[k]
            view = buffer[layout[k, 0]:layout[k, 0] + layout[k, 1]].reshape(array.shape)
            view[...] = array
            views[name] = view
        return buffer, layout, views


def _c_view(ndim):
    """Build an intrinsic ``view(a, start, shape)``: ``a[start:start + prod(shape)]`` of a
    C-contiguous 1-D array, seen as a C-contiguous ``ndim``-D array.

    A slice then ``ndarray.reshape`` in compiled code normalises the slice bounds and calls
    a C helper (``numba_attempt_nocopy_reshape``, ~25 ns) each time: with fifteen views cut
    per query that was a third of a Panda update (``perf``). The packed layout already
    holds valid offsets and shapes, so this writes the view's pointer, shape and strides
    directly. The caller guarantees ``start + prod(shape) <= a.size``.
    """
    @intrinsic
    def view(typingctx, array, start, shape):
        if not (isinstance(array, types.Array) and array.ndim == 1 and array.layout == 'C'
                and isinstance(start, types.Integer)
                and isinstance(shape, types.UniTuple) and shape.count == ndim):
            return None
        result = array.copy(ndim=ndim, layout='C')

        def codegen(context, builder, signature, args):
            source = make_array(array)(context, builder, args[0])
            offset = context.cast(builder, args[1], start, types.intp)
            dims = cgutils.unpack_tuple(builder, args[2], ndim)
            dims = [context.cast(builder, d, shape.dtype, types.intp) for d in dims]
            strides = [source.itemsize] * ndim
            for k in range(ndim - 2, -1, -1):
                strides[k] = builder.mul(strides[k + 1], dims[k + 1])
            data = builder.gep(source.data, [offset])
            result_array = make_array(result)(context, builder)
            populate_array(result_array, data=data, shape=dims, strides=strides,
                           itemsize=source.itemsize, meminfo=source.meminfo,
                           parent=source.parent)
            return result_array._getvalue()
        return result(array, start, shape), codegen
    return view


def _python_view(array, start, shape):
    return array[start:start + int(np.prod(shape))].reshape(shape)


if numba.config.DISABLE_JIT:
    # NUMBA_DISABLE_JIT runs every kernel as Python (debugging); intrinsics cannot run there.
    _view1 = view_at2 = _view3 = _python_view
else:
    _view1 = _c_view(1)
    view_at2 = _c_view(2)  # view_at2(buffer, start, (rows, columns)), e.g. a layout table
    _view3 = _c_view(3)


@numba.njit(cache=True, inline='always')
def view1(buffer, layout, k):
    """The k-th packed array, 1-D."""
    return _view1(buffer, layout[k, 0], (layout[k, 1],))


@numba.njit(cache=True, inline='always')
def view2(buffer, layout, k):
    """The k-th packed array, 2-D."""
    return view_at2(buffer, layout[k, 0], (layout[k, 2], layout[k, 3]))


@numba.njit(cache=True, inline='always')
def view3(buffer, layout, k):
    """The k-th packed array, 3-D."""
    return _view3(buffer, layout[k, 0], (layout[k, 2], layout[k, 3], layout[k, 4]))


bind_to_kernel_sources(globals())
