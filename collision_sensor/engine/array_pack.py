"""Many arrays of one dtype carried in one flat buffer, which the compiled engine reads in place.

The checker packs its arrays (the model's and the carried state alike) into two flat buffers
once; the engine (``cpp/query.hpp``) cuts them back into named arrays by the layout table in
the int buffer's header, once, when it is made. Python keeps views of the same memory, so any
array can be inspected without a copy, and a query crosses the binding with one array.

``layout[k] = (offset, size, d0, d1, d2)`` describes the k-th array packed in a buffer.
"""
from typing import Dict, List, Tuple

import numpy as np

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
