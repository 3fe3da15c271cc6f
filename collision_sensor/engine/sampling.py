"""Random joint configurations, uniform within the joint limits (sampling and benchmarks), and
the pairs they show near everywhere."""
import math
from dataclasses import dataclass
from typing import Dict, List, Tuple

import numpy as np

from collision_sensor.errors import JointStateError


def sampling_bounds(checker) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``(lower, upper)``, ``(J,) float``, in the order of ``checker.joint_names``.

    Infinite limits (continuous joints) become [-pi, pi].
    """
    lower = np.array([checker.joint_limits[name][0] for name in checker.joint_names])
    upper = np.array([checker.joint_limits[name][1] for name in checker.joint_names])
    return (np.where(np.isfinite(lower), lower, -math.pi),
            np.where(np.isfinite(upper), upper, math.pi))


def uniform_configurations(lower: np.ndarray, upper: np.ndarray, n: int,
                           rng: np.random.Generator) -> np.ndarray:
    """Return ``(n, J) float`` configurations uniform in ``[lower, upper]``."""
    return lower + (upper - lower) * rng.random((n, len(lower)))


def random_configurations(checker, n: int, seed: int = 0) -> np.ndarray:
    """Return ``(n, J) float`` configurations of ``checker``'s joints, uniform within limits."""
    lower, upper = sampling_bounds(checker)
    return uniform_configurations(lower, upper, n, np.random.default_rng(seed))


#: Configurations :func:`pairs_near_everywhere` samples by default (besides the neutral one).
NEAR_SAMPLES = 300
#: The share of samples in which a pair must be near to be named, as the exception-list tool's
#: "Always" (``collision_sensor_acm --always-fraction``).
NEAR_FRACTION = 0.95


@dataclass(frozen=True)
class NearPair:
    """A pair of bodies nearer than a distance in (almost) every sampled configuration.

    :ivar link_a: the pair's first name (``link_a < link_b``, as in ``checked_pairs``).
    :ivar link_b: the second name.
    :ivar near: configurations in which the pair was nearer than the distance.
    :ivar samples: configurations measured.
    :ivar largest: the pair's largest (padded) distance over the configurations in which it
        was near (m): a warning distance at or below it leaves the pair out there.
    """

    link_a: str
    link_b: str
    near: int
    samples: int
    largest: float


def pairs_near_everywhere(checker, distance: float, samples: int = NEAR_SAMPLES,
                          seed: int = 0, fraction: float = NEAR_FRACTION) -> List[NearPair]:
    """Return the checked pairs nearer than ``distance`` wherever the robot goes: in at least
    ``fraction`` of the neutral configuration and ``samples`` configurations uniform within the
    joint limits (:func:`sampling_bounds`, seeded), as ``collision_sensor_acm`` samples for
    "Always". A warning zone of that ``distance`` would report them all the time.

    Sampling is not proof: a pair near in every configuration drawn can be apart in one that was
    not drawn. The checker is left at its neutral configuration, checked from scratch.

    :param checker: a :class:`CollisionChecker` (its carried state is used, then reset).
    :param distance: metres (padded distance, as :meth:`CollisionChecker.proximity` measures).
    :return: the pairs, sorted by name.
    """
    neutral = checker.kinematics.neutral()
    lower, upper = sampling_bounds(checker)
    configurations = np.vstack([neutral[None, :], uniform_configurations(
        lower, upper, samples, np.random.default_rng(seed))])
    near: Dict[Tuple[str, str], int] = {}
    largest: Dict[Tuple[str, str], float] = {}
    measured = 0
    for q in configurations:
        try:
            records = checker.proximity(q, distance)
        except JointStateError:   # a floating joint's quaternion drawn (almost) zero
            continue
        measured += 1
        for record in records:
            if record.distance < distance:
                pair = (record.link_a, record.link_b)
                near[pair] = near.get(pair, 0) + 1
                largest[pair] = max(largest.get(pair, -math.inf), record.distance)
    checker.check(neutral)
    return [NearPair(a, b, count, measured, largest[a, b])
            for (a, b), count in sorted(near.items())
            if measured and count >= fraction * measured]


#: Configurations :func:`pairs_in_contact_by_design` samples (besides zero and home).
CONTACT_SAMPLES = 64


@dataclass(frozen=True)
class ContactByDesign:
    """The robot's own pairs in contact where it stands at rest or wherever it goes: what an
    SRDF's ``disable_collisions`` (``collision_sensor_acm``'s Default and Always) leaves out.

    :ivar at_zero: pairs in contact at the zero configuration (identity quaternions).
    :ivar at_home: pairs in contact at home: zero moved into the joint limits (``()`` when zero
        lies within them).
    :ivar mostly: pairs in contact in at least ``fraction`` of the sampled configurations.
    :ivar samples: configurations sampled.
    :ivar fraction: the share of them a pair of ``mostly`` is in contact in.
    """

    at_zero: Tuple[Tuple[str, str], ...]
    at_home: Tuple[Tuple[str, str], ...]
    mostly: Tuple[Tuple[str, str], ...]
    samples: int
    fraction: float

    @property
    def pairs(self) -> List[Tuple[str, str]]:
        """Every pair found, sorted."""
        return sorted(set(self.at_zero) | set(self.at_home) | set(self.mostly))


def pairs_in_contact_by_design(checker, samples: int = CONTACT_SAMPLES, seed: int = 0,
                               fraction: float = NEAR_FRACTION) -> ContactByDesign:
    """Return the checked pairs of ``checker``'s robot links (scene objects left out) in contact
    at the zero configuration, at home (zero within the joint limits) or in at least
    ``fraction`` of ``samples`` configurations uniform within the limits (seeded), as
    ``collision_sensor_acm`` finds "Default" and "Always" pairs. A robot loaded without an SRDF
    that disables them reports them in contact wherever it stands.

    The configurations run through :meth:`CollisionChecker.check_batch`: the carried state is
    left as it was.
    """
    zero = checker.kinematics.neutral()
    lower, upper = sampling_bounds(checker)
    home = np.clip(zero, lower, upper)
    Q = np.vstack([zero[None, :], home[None, :], uniform_configurations(
        lower, upper, samples, np.random.default_rng(seed))])
    links = set(checker.link_names)
    columns = [k for k, (a, b) in enumerate(checker.checked_pairs)
               if a in links and b in links]
    pairs = [checker.checked_pairs[k] for k in columns]
    statuses = checker.check_batch(Q)[:, columns] if columns else np.zeros((len(Q), 0), bool)
    share = statuses[2:].mean(axis=0) if samples else np.zeros(len(pairs))
    return ContactByDesign(
        at_zero=tuple(p for p, hit in zip(pairs, statuses[0]) if hit),
        at_home=tuple(p for p, hit in zip(pairs, statuses[1]) if hit)
        if not np.array_equal(home, zero) else (),
        mostly=tuple(p for p, s in zip(pairs, share) if samples and s >= fraction),
        samples=samples, fraction=fraction)
