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
        offset = 0
        for k, array in enumerate(self._arrays):
            shape = array.shape + (1,) * (3 - array.ndim)
            layout[k] = (offset, array.size) + shape
            offset += array.size
        buffer = np.zeros(max(offset, 1), dtype=self.dtype)
        views = {}
        for name, k in self.index.items():
            array = self._arrays[k]
            view = buffer[layout[k, 0]:layout[k, 0] + layout[k, 1]].reshape(array.shape)
            view[...] = array
            views[name] = view
        return buffer, layout, views


def _c_reshape(ndim):
    """Build an intrinsic ``reshape(a, shape)``: a C-contiguous 1-D array seen as ``ndim``-D.

    ``ndarray.reshape`` in compiled code calls a C helper (``numba_attempt_nocopy_reshape``)
    each time, ~25 ns: with fifteen views cut per query that was a third of a Panda update
    (``perf``). A C-contiguous 1-D array needs no such check, so this writes the view's shape
    and strides directly. The caller guarantees ``prod(shape) == a.size``.
    """
    @intrinsic
    def reshape(typingctx, array, shape):
        if not (isinstance(array, types.Array) and array.ndim == 1 and array.layout == 'C'
                and isinstance(shape, types.UniTuple) and shape.count == ndim):
            return None
        result = array.copy(ndim=ndim, layout='C')

        def codegen(context, builder, signature, args):
            source = make_array(array)(context, builder, args[0])
            dims = cgutils.unpack_tuple(builder, args[1], ndim)
            dims = [context.cast(builder, d, shape.dtype, types.intp) for d in dims]
            strides = [source.itemsize] * ndim
            for k in range(ndim - 2, -1, -1):
                strides[k] = builder.mul(strides[k + 1], dims[k + 1])
            view = make_array(result)(context, builder)
            populate_array(view, data=source.data, shape=dims, strides=strides,
                           itemsize=source.itemsize, meminfo=source.meminfo,
                           parent=source.parent)
            return view._getvalue()
        return result(array, shape), codegen
    return reshape


def _python_reshape(array, shape):
    return array.reshape(shape)


if numba.config.DISABLE_JIT:
    # NUMBA_DISABLE_JIT runs every kernel as Python (debugging); intrinsics cannot run there.
    reshape2 = reshape3 = _python_reshape
else:
    reshape2 = _c_reshape(2)
    reshape3 = _c_reshape(3)


@numba.njit(cache=True, inline='always')
def view1(buffer, layout, k):
    """The k-th packed array, 1-D."""
    return buffer[layout[k, 0]:layout[k, 0] + layout[k, 1]]


@numba.njit(cache=True, inline='always')
def view2(buffer, layout, k):
    """The k-th packed array, 2-D."""
    return reshape2(view1(buffer, layout, k), (layout[k, 2], layout[k, 3]))


@numba.njit(cache=True, inline='always')
def view3(buffer, layout, k):
    """The k-th packed array, 3-D."""
    return reshape3(view1(buffer, layout, k), (layout[k, 2], layout[k, 3], layout[k, 4]))


bind_to_kernel_sources(globals())
