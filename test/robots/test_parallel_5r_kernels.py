"""The five-bar's compiled terms written out in scalars hold the generic forms' floats, bit for bit."""

from __future__ import annotations

import numpy as np
from numba import njit

from pdsmc_ros.robots import make_robot
from pdsmc_ros.robots import parallel_5r_kernels as five_bar
from pdsmc_ros.robots.chain import chain_coriolis_times


@njit
def _both(p, base, q, qd, v):  # noqa: ANN001, ANN202
    """One open chain's ``C' v``: the generic loop's floats, and the five-bar's scalar form at a geometry
    holding that chain's links' cosines and sines."""
    generic = np.empty(2)
    chain_coriolis_times(p[base:base + 4], q, qd, v, generic, np.empty(16), 2)
    geo = np.empty(4)
    first = 0.0 + q[0]  # the generic loop's absolute angles
    second = first + q[1]
    geo[0] = np.cos(first)
    geo[1] = np.sin(first)
    geo[2] = np.cos(second)
    geo[3] = np.sin(second)
    return generic, five_bar._chain_coriolis_times(p, base, geo, 0, qd[0], qd[1], v[0], v[1])


def test_the_scalar_chain_coriolis_is_the_generic_loops_floats() -> None:
    p = make_robot("parallel_5r").pack()
    rng = np.random.default_rng(3)
    for _ in range(500):
        q, qd, v = rng.uniform(-np.pi, np.pi, 2), rng.normal(0.0, 3.0, 2), rng.normal(0.0, 3.0, 2)
        for base in (five_bar._LEFT, five_bar._RIGHT):
            generic, scalar = _both(p, base, q, qd, v)
            assert generic[0] == scalar[0] and generic[1] == scalar[1], (q, qd, v)
