"""Settings of the collision checker, validated once, in one place.

===================== ========== ============================================================
key                   default    meaning
===================== ========== ============================================================
allowed_collisions    ()         extra pairs never checked, strings ``"link_a:link_b"``;
                                 a name that is no link or object yet is kept (with a
                                 LoadWarning) for an object added later by that name
ignore_adjacent       True       never check a link against its nearest ancestor with geometry
motion_tolerance      0.0        a joint counts as moved when it changed by more than this
                                 (rad or m) since the state the carried statuses describe;
                                 0 is exact: any change re-checks the affected pairs
box_test              'sat'      box-box test: 'sat' (15 separating axes) or 'paper' (sec. 5);
                                 both give the same answers, the default is the faster one
                                 as measured by ``python -m benchmarks``
expansion             'wider'    node expansion rule (sec. 4.1): 'same', 'alternate',
                                 'larger' (volume), 'promising', 'wider' (half diagonal);
                                 answers equal; 'wider' is the fastest on most robots and
                                 scenes the benchmarks measure
obb_fit               'refined'  box fit: 'refined' (the principal-axes box tightened by
                                 the smallest rectangle around each axis: fewer box tests a
                                 check than 'pca'), 'pca'
                                 (vertex covariance, the paper's Wu method), 'hull_pca'
                                 (area-weighted convex hull), 'min_volume' (both slow)
leaf_size             1          most triangles per tree leaf (1: a leaf box is as
                                 tight as its triangle; measured fastest on Panda and UR5)
primitive_sections    32         tessellation of URDF/scene cylinders and spheres
mesh_containment      False      also treat closed (watertight, consistently wound) meshes
                                 as solid: anything wholly inside one collides with it, as
                                 with primitives, which are always solid (docs/engine.md, "Contact
                                 rule"); costs a ray test over the mesh's triangles per
                                 element pair whose spheres overlap and surfaces do not meet
padding               0.0        metres every robot link's geometry is grown by (a sphere
                                 swept over it, as MoveIt's link padding): two bodies are in
                                 contact when their surfaces are within the sum of their
                                 paddings, and proximity reports that much less distance
link_padding          {}         ``{link: metres}``, a link's own padding instead of
                                 ``padding``; links of the robot only (scene objects are
                                 never padded)
threads               0          threads ``check_batch``, ``update_batch``, ``check_path``
                                 and ``check_spline`` run on (contiguous chunks of the rows,
                                 the same answers as one thread), and by default the pass
                                 over a cloud's rows in ``set_points``: 0 every hardware
                                 thread of the machine (std::thread::hardware_concurrency),
                                 1 the calling thread alone, at most 256
min_chunk_us          200.0      a batch is cut into chunks of at least this much work
                                 (microseconds, estimated from the checker's earlier
                                 batches): a thread costs tens of microseconds to start, so a
                                 short batch runs on fewer threads (answers never depend on
                                 it); 0: always as many chunks as threads
voxel_size            0.02       point clouds (``set_points``): the edge (m, 0.001 to 1) of
                                 the world-aligned cubes a cloud's points are grouped into
self_filter_padding   0.02       point clouds: points within this (m, 0 to 1) of the robot's
                                 collision geometry (its links and attached objects), or
                                 inside its solids, are the robot's own and removed
max_points            1000000    point clouds: most rows taken from one cloud; a larger one
                                 is subsampled (every k-th row) and the rest counted
===================== ========== ============================================================
"""
from dataclasses import dataclass, fields, replace
import math
import os
from typing import Any, Mapping, Optional, Tuple

from collision_sensor.engine.bounding_volumes import (
    OBB_HULL_PCA, OBB_MIN_VOLUME, OBB_PCA, OBB_REFINED)
from collision_sensor.engine.box_test import BOX_TEST_PAPER, BOX_TEST_SAT
from collision_sensor.engine.compiled import engine
from collision_sensor.engine.traversal import EXPANSION_RULES
from collision_sensor.errors import ConfigError

BOX_TESTS = {'paper': BOX_TEST_PAPER, 'sat': BOX_TEST_SAT}
#: The most threads the setting ``threads`` may ask for (cpp/tolerances.hpp: MAX_THREADS).
MAX_THREADS = engine.MAX_THREADS
OBB_FITS = {'pca': OBB_PCA, 'refined': OBB_REFINED, 'hull_pca': OBB_HULL_PCA,
            'min_volume': OBB_MIN_VOLUME}


def usable_cores() -> int:
    """All the cores this process may use (its CPU affinity where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


@dataclass(frozen=True)
class CheckerConfig:
    """Validated checker settings; build with :meth:`from_mapping`."""

    allowed_collisions: Tuple[str, ...] = ()
    ignore_adjacent: bool = True
    motion_tolerance: float = 0.0
    box_test: str = 'sat'
    expansion: str = 'wider'
    obb_fit: str = 'refined'
    leaf_size: int = 1
    primitive_sections: int = 32
    mesh_containment: bool = False
    padding: float = 0.0
    #: ``((link, metres), ...)`` sorted by link; given as a mapping, see :meth:`from_mapping`.
    link_padding: Tuple[Tuple[str, float], ...] = ()
    threads: int = 0
    min_chunk_us: float = 200.0
    voxel_size: float = 0.02
    self_filter_padding: float = 0.02
    max_points: int = 1_000_000

    @classmethod
    def from_mapping(cls, config: Optional[Mapping[str, Any]] = None) -> 'CheckerConfig':
        """Return settings from a mapping (or a CheckerConfig, or None for the defaults).

        :raises ConfigError: on unknown keys or bad values, naming them and the valid choices.
        """
        if config is None:
            return cls()
        if isinstance(config, CheckerConfig):
            return config
        if not isinstance(config, Mapping):
            raise ConfigError(f'config must be a mapping of settings, got {type(config).__name__}')
        valid = {f.name for f in fields(cls)}
        unknown = sorted(set(config) - valid)
        if unknown:
            raise ConfigError(f'unknown setting(s) {", ".join(unknown)}; valid settings: '
                              f'{", ".join(sorted(valid))}')
        return replace(cls(), **_converted(config))

    @property
    def box_test_code(self) -> int:
        return BOX_TESTS[self.box_test]

    @property
    def expansion_code(self) -> int:
        return EXPANSION_RULES[self.expansion]

    @property
    def obb_fit_code(self) -> int:
        return OBB_FITS[self.obb_fit]


def _choice(key, value, choices):
    if value not in choices:
        raise ConfigError(f'setting {key}: "{value}" is not one of {", ".join(sorted(choices))}')
    return value


def _metres(key, value) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not (number >= 0.0 and math.isfinite(number)):
        raise ConfigError(f'setting {key}: expected a finite number of metres >= 0, got '
                          f'{value!r}')
    return number


def _link_padding(value) -> Tuple[Tuple[str, float], ...]:
    if isinstance(value, tuple) and all(isinstance(v, tuple) for v in value):
        value = dict(value)   # a CheckerConfig's own (settings copied from another checker)
    if not isinstance(value, Mapping):
        raise ConfigError('setting link_padding: expected a mapping {link: metres}, got '
                          f'{type(value).__name__}')
    out = []
    for link, metres in value.items():
        if not isinstance(link, str) or not link:
            raise ConfigError(f'setting link_padding: link name {link!r} is not a string')
        out.append((link, _metres(f'link_padding[{link}]', metres)))
    return tuple(sorted(out))


def _converted(config):
    out = {}
    for key, value in config.items():
        if key == 'allowed_collisions':
            if isinstance(value, str) or not all(isinstance(v, str) for v in value):
                raise ConfigError('setting allowed_collisions: expected a list of strings '
                                  '"link_a:link_b"')
            out[key] = tuple(value)
        elif key in ('ignore_adjacent', 'mesh_containment'):
            if not isinstance(value, bool):
                raise ConfigError(f'setting {key}: expected true or false, got {value!r}')
            out[key] = value
        elif key == 'motion_tolerance':
            try:
                tolerance = float(value)
            except (TypeError, ValueError):
                tolerance = float('nan')
            if not tolerance >= 0.0 or tolerance == float('inf'):
                raise ConfigError(f'setting motion_tolerance: expected a finite number >= 0 '
                                  f'(rad or m), got {value!r}')
            out[key] = tolerance
        elif key == 'box_test':
            out[key] = _choice(key, value, BOX_TESTS)
        elif key == 'expansion':
            out[key] = _choice(key, value, EXPANSION_RULES)
        elif key == 'obb_fit':
            out[key] = _choice(key, value, OBB_FITS)
        elif key == 'padding':
            out[key] = _metres(key, value)
        elif key == 'min_chunk_us':
            try:
                work = float(value)
            except (TypeError, ValueError):
                work = math.nan
            if isinstance(value, bool) or not (work >= 0.0 and math.isfinite(work)):
                raise ConfigError(f'setting min_chunk_us: expected a finite number of '
                                  f'microseconds >= 0, got {value!r}')
            out[key] = work
        elif key == 'link_padding':
            out[key] = _link_padding(value)
        elif key == 'threads':
            if isinstance(value, bool) or not isinstance(value, int) or not \
                    0 <= value <= MAX_THREADS:
                raise ConfigError(f'setting threads: expected an integer from 0 (every core) to '
                                  f'{MAX_THREADS}, got {value!r}')
            out[key] = value
        elif key in ('voxel_size', 'self_filter_padding'):
            number = _metres(key, value)
            low = 0.001 if key == 'voxel_size' else 0.0
            if not low <= number <= 1.0:
                raise ConfigError(f'setting {key}: expected {low:g} to 1.0 m, got {value!r}')
            out[key] = number
        elif key == 'max_points':
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f'setting max_points: expected an integer >= 1, got {value!r}')
            out[key] = value
        elif key in ('leaf_size', 'primitive_sections'):
            minimum = 1 if key == 'leaf_size' else 3
            if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
                raise ConfigError(f'setting {key}: expected an integer >= {minimum}, '
                                  f'got {value!r}')
            out[key] = value
    return out
