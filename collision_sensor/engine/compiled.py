"""The compiled engine (``collision_sensor.engine._engine``, C++17 under ``cpp/``), checked on
import.

The extension is built when the package is installed (``make``, ``pip install``, ``colcon
build``). Importing it here, rather than from each module, gives one clear message when it is
missing or was built from other sources than the ones beside it (an editable install whose
``cpp/`` changed since the last build), instead of a confusing error deep in a query.

The extension is the one source of the engine's constants and of the layout of its packed
arrays (``cpp/layout.hpp``): the modules of this package read them from ``engine`` (e.g.
``obb_tree.BOX_WIDTH = engine.BOX_WIDTH``) and write none of them again. It raises the
package's own errors (:mod:`collision_sensor.errors`): ``EngineInputError`` for an argument it
cannot take, ``EngineBuildError`` for packed arrays whose layout is not its own.
"""
import hashlib
import os

from collision_sensor.errors import EngineBuildError
from collision_sensor.model import sequences

__all__ = ['ENGINE_API', 'EngineBuildError', 'engine', 'load_engine', 'source_digest']

#: The binding's interface version this Python code expects (cpp/bindings.cpp: ENGINE_API).
ENGINE_API = 10
_REBUILD = ('rebuild it: "make" (or "pip install -e ." in the source tree, '
            '"colcon build --packages-select collision_sensor" in a workspace)')


def _sources_beside_package():
    """Return the engine's source files when this package runs from its source tree."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    here = os.path.dirname(package)
    folder = os.path.join(here, 'cpp')
    if not os.path.isfile(os.path.join(folder, 'bindings.cpp')):
        return []
    return sorted(os.path.join(folder, name) for name in os.listdir(folder)
                  if name.endswith(('.cpp', '.hpp', '.h')))


def source_digest(paths) -> str:
    """Return the SHA-256 of the engine's sources, as setup.py computes it at build time."""
    sha = hashlib.sha256()
    for path in paths:
        with open(path, 'rb') as source:
            sha.update(os.path.basename(path).encode() + b'\0' + source.read())
    return sha.hexdigest()


def load_engine():
    """Import and return ``collision_sensor.engine._engine``; raise EngineBuildError with the
    fix."""
    try:
        from collision_sensor.engine import _engine
    except ImportError as error:
        raise EngineBuildError(
            f'the compiled engine collision_sensor.engine._engine cannot be imported ({error}); '
            f'it is built when the package is installed: {_REBUILD}') from None
    if getattr(_engine, 'ENGINE_API', None) != ENGINE_API:
        raise EngineBuildError(
            f'the compiled engine at {_engine.__file__} has interface version '
            f'{getattr(_engine, "ENGINE_API", None)}, this code expects {ENGINE_API}; '
            + _REBUILD)
    sources = _sources_beside_package()
    if sources and _engine.SOURCE_DIGEST != source_digest(sources):
        raise EngineBuildError(
            f'the compiled engine at {_engine.__file__} was built from other sources than '
            f'those in {os.path.dirname(sources[0])} (edited since the last build); '
            + _REBUILD)
    return _engine


engine = load_engine()
# Recorded CSV files are read by the engine's number parser from now on (the model layer,
# which reads them, does not import the engine).
sequences.use_number_table_parser(engine.parse_number_table)
