"""Keep numba's on-disk kernel cache honest across modules.

numba keys a cached kernel on its own source file only (modification time and size). The
query kernel inlines the traversal, box, triangle and kinematics kernels from other modules,
so editing or upgrading one of those would leave a stale compiled query on disk that numba
still loads. Each kernel module therefore calls :func:`bind_to_kernel_sources` after its
definitions: the cache stamp of every kernel it defines then also carries a digest of all the
kernel modules' sources, and any change to any of them recompiles everything that may inline
it.
"""
import hashlib
import os

# Every module of this package that defines cached kernels.
KERNEL_MODULES = ('array_pack', 'box_test', 'kinematics', 'query_kernel', 'tolerances',
                  'traversal', 'triangle_test')
_MARK = 'collision_sensor-kernels'
_digest = None


def kernel_sources_digest() -> str:
    """Return the SHA-256 of the kernel modules' sources (computed once per process)."""
    global _digest
    if _digest is None:
        here = os.path.dirname(os.path.abspath(__file__))
        sha = hashlib.sha256()
        for name in KERNEL_MODULES:
            with open(os.path.join(here, name + '.py'), 'rb') as source:
                sha.update(source.read())
        _digest = sha.hexdigest()
    return _digest


def bind_to_kernel_sources(namespace: dict) -> None:
    """Make the cache of every kernel defined in ``namespace`` depend on all kernel sources.

    :param namespace: a kernel module's ``globals()``; kernels imported into it from other
        modules are left to their own module's call.
    """
    module = namespace.get('__name__')
    for kernel in list(namespace.values()):
        cache_file = getattr(getattr(kernel, '_cache', None), '_cache_file', None)
        stamp = getattr(cache_file, '_source_stamp', None)
        py_func = getattr(kernel, 'py_func', None)
        if stamp is None or getattr(py_func, '__module__', None) != module:
            continue
        if isinstance(stamp, tuple) and stamp[:1] == (_MARK,):
            continue  # bound already
        # numba stores this stamp in the cache index and reloads only on an equal stamp.
        cache_file._source_stamp = (_MARK, kernel_sources_digest(), stamp)
