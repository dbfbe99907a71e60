"""States near a run's reference, for the laws' equation tests."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from pdsmc_ros.robots.base import FloatArray
from pdsmc_ros.runs.builder import RunSpec


def states(spec: RunSpec, count: int, seed: int) -> Iterator[tuple[FloatArray, ...]]:
    """``(q, qd, q_d, qd_d, qdd_d)`` at ``count`` random instants, the state a little off the reference."""
    rng = np.random.default_rng(seed)
    ref = spec.reference().sample(rng.uniform(0, spec.contour_model().duration, count))
    n = spec.robot_model().n
    for k in range(count):
        yield ref.q[k] + rng.normal(0, 2e-3, n), ref.qd[k] + rng.normal(0, 2e-2, n), ref.q[k], ref.qd[k], ref.qdd[k]
