"""How much the benchmark measures: the default run, and ``--quick`` for a smoke run."""
from dataclasses import dataclass
from typing import Optional, Tuple


@dataclass(frozen=True)
class Settings:
    """Counts of one benchmark run.

    :ivar configurations: random configurations per robot (scenarios 1 and 5).
    :ivar stream_steps: steps per coherent stream (scenario 2).
    :ivar scale_configurations: configurations per terrain size (scenario 4).
    :ivar terrain_triangles: the terrain sizes of scenario 4, ascending.
    :ivar rounds: interleaved timing passes; each figure is the best of them.
    :ivar box_pairs, box_repeat: box-test pairs per set and loops over them (scenario 5).
    :ivar fits: the bounding-volume fits compared in scenario 5.
    :ivar motion_segments: random segments of scenario 10's certification part, over all its
        robots.
    :ivar motion_speed_segments: random segments per robot of scenario 10's speed part.
    :ivar motion_waypoints: waypoints of scenario 10's Panda trajectory.
    :ivar motion_paths: random paths per robot that scenario 10's certification part checks
        with ``check_path`` against ``check_motion`` segment by segment.
    :ivar motion_walk_steps: steps of scenario 10's 1 kHz walk (scenario 8's walk).
    :ivar ccd_cases: random translations per pair of primitives (scenario 10, python-fcl's
        continuousCollide).
    :ivar motion_robots: scenario 10's certification robots (labels of
        ``motion_cells.ROBOTS``; None: all).
    :ivar motion_parts: scenario 10's parts to run (``A`` certification, ``B`` speed against
        the discretized motion, ``C`` python-fcl's continuousCollide, ``D`` the streams).
    :ivar thread_rows: rows of scenario 11's batches (one thread against two).
    """

    seed: int = 1998
    quick: bool = False
    configurations: int = 2000
    stream_steps: int = 2000
    scale_configurations: int = 1000
    terrain_triangles: Tuple[int, ...] = (10_000, 100_000, 1_000_000)
    rounds: int = 5
    box_pairs: int = 100_000
    box_repeat: int = 10
    fits: Tuple[str, ...] = ('pca', 'refined', 'hull_pca', 'min_volume')
    motion_segments: int = 10_200
    motion_speed_segments: int = 200
    motion_waypoints: int = 1000
    motion_paths: int = 400
    motion_walk_steps: int = 3000
    ccd_cases: int = 40
    motion_robots: Optional[Tuple[str, ...]] = None
    motion_parts: Tuple[str, ...] = ('A', 'B', 'C', 'D')
    thread_rows: int = 10_000

    @classmethod
    def for_run(cls, quick: bool, seed: int) -> 'Settings':
        """Return the default counts, or the small ones of ``--quick``."""
        if not quick:
            return cls(seed=seed)
        # min_volume is left out of the smoke run: its Panda build alone takes ~15 s.
        return cls(seed=seed, quick=True, configurations=60, stream_steps=60,
                   scale_configurations=20, terrain_triangles=(1_000, 3_000, 10_000), rounds=2,
                   box_pairs=2_000, box_repeat=2, fits=('pca', 'refined', 'hull_pca'),
                   motion_segments=30, motion_speed_segments=10, motion_waypoints=100,
                   motion_paths=5, motion_walk_steps=300, ccd_cases=3, motion_robots=('panda', 'ur5', 'z1'),
                   thread_rows=1000)
