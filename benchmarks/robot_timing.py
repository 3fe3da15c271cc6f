"""One robot's full check timed against pinocchio+coal on the same pairs (scenarios 7 and 13).

The same seeded random configurations go to ours (``check``: one Python call, FK and every
checked pair) and to pinocchio+coal (``computeCollisions``: its FK, placements and the geometry
pairs of exactly our checked link pairs, each stopping at its first contact). Both load the
same mesh files, each with its own loader, so a few pairs can differ where the loaders read a
file differently; ``equal`` counts configurations with equal colliding pair sets.
"""
from dataclasses import dataclass, field
from typing import Callable, Dict, Optional

from collision_sensor.engine.checker import CollisionChecker
from collision_sensor.engine.sampling import random_configurations
from benchmarks.scenario_measure import Candidate, interleaved_us, work_per_check
from benchmarks.scenario_peers import (
    agreement, optional_peer, pinocchio_answers, pinocchio_peer)


@dataclass
class RobotTiming:
    """What one robot measured; ``ours_us`` None when there was nothing to time.

    :ivar configurations: how many random configurations were timed.
    :ivar work: our mean ``{'boxes', 'triangles', 'spheres'}`` tests per check.
    :ivar colliding: our mean number of colliding pairs per configuration.
    :ivar equal: ``"k/n"`` configurations with equal colliding pair sets, or why not compared.
    :ivar pinocchio_missing: why pinocchio+coal was not timed (None: it was).
    """

    name: str
    triangles: int
    pairs: int
    configurations: int = 0
    ours_us: Optional[float] = None
    pinocchio_us: Optional[float] = None
    work: Dict[str, float] = field(default_factory=dict)
    colliding: Optional[float] = None
    equal: str = '-'
    pinocchio_missing: Optional[str] = None

    @property
    def ratio(self) -> Optional[float]:
        """Ours / pinocchio+coal, or None when either was not timed."""
        if self.ours_us is None or not self.pinocchio_us:
            return None
        return self.ours_us / self.pinocchio_us


def time_robot(cell, checker: CollisionChecker, count: Callable[[CollisionChecker], int],
               seed: int, rounds: int) -> RobotTiming:
    """Time ``checker`` (built on ``cell``) and pinocchio+coal on the same configurations.

    :param count: how many configurations to time, given the checker (fewer for big robots).
    :return: the timing; a robot without a checked pair is returned untimed, and one
        pinocchio cannot load with ``pinocchio_missing`` saying why.
    """
    timing = RobotTiming(cell.name, len(checker.forest.tris), len(checker.checked_pairs))
    if not checker.checked_pairs:
        timing.equal = 'no pair to check'
        return timing
    n = count(checker)
    timing.configurations = n
    configurations = list(random_configurations(checker, n, seed))
    ours = [frozenset(checker.check(q).colliding_pairs) for q in configurations]
    timing.colliding = sum(map(len, ours)) / n
    pin, timing.pinocchio_missing = optional_peer(pinocchio_peer, cell, checker)
    candidates = [Candidate('ours', checker.check, configurations)]
    if pin is not None:
        pin_qs = [pin.configuration(checker, q) for q in configurations]
        candidates.append(Candidate('pinocchio', pin.check, pin_qs))
        timing.equal = agreement(ours, pinocchio_answers(pin, pin_qs))
    else:
        timing.equal = timing.pinocchio_missing
    times = interleaved_us(candidates, rounds)
    timing.ours_us, timing.pinocchio_us = times['ours'], times.get('pinocchio')
    timing.work = work_per_check(checker, configurations)
    return timing
