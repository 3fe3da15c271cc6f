"""Random joint configurations, uniform within the joint limits (sampling and benchmarks)."""
import math
from typing import Tuple

import numpy as np


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
