"""The discrete closed loop of a whole run: control at each instant, the plant in between.

At every control instant ``t_k = k / rate`` the law reads the state and the
reference sampled at ``t_k`` and computes a torque; the plant integrates
Eq. (4.1) over one period with that torque held (:mod:`.rk4`). The compiled
loop runs when the robot, the law and the nominal model all have compiled
forms; the numpy loop, the same steps, otherwise.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..control.law import ControlLaw
from ..control.laws import law_torque
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator
from ..robots.parallel_5r_kernels import PARALLEL_5R
from ..robots.serial_3r import SERIAL_3R
from ..robots.spatial_kernels import SERIAL_CHAIN
from .rk4 import carve, rk4_advance, rk4_step


@njit(cache=True)
def _closed_loop_serial_3r(p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
                           out_q, out_qd, out_tau, work):
    _loop(SERIAL_3R, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,
          out_q, out_qd, out_tau, work)


@njit(cache=True)
def _closed_loop_parallel_5r(p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
                             out_q, out_qd, out_tau, work):
    _loop(PARALLEL_5R, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,
          out_q, out_qd, out_tau, work)


@njit(cache=True)
def _closed_loop_serial_chain(p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
                              out_q, out_qd, out_tau, work):
    _loop(SERIAL_CHAIN, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,
          out_q, out_qd, out_tau, work)


# one compiled loop per robot code, its dynamics inlined: a process compiles (or loads) only the robots it runs
# (written out one per robot: numba caches no function a factory makes, and these must be cached)
_CLOSED_LOOPS = {SERIAL_3R: _closed_loop_serial_3r, PARALLEL_5R: _closed_loop_parallel_5r,
                 SERIAL_CHAIN: _closed_loop_serial_chain}


@njit(cache=True, inline="always")
def _loop(  # noqa: ANN202, PLR0913
    kind, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,
    out_q, out_qd, out_tau, work,
):  # noqa: ANN001
    n = robot_compiled.size(kind, q0.shape[0])
    steps = refs.shape[0] - 1
    stages, rest = carve(work, n)
    q = q0.copy()
    qd = qd0.copy()
    tau = np.empty(n)
    for k in range(steps + 1):
        law_torque(code, gains, smc_model, model_kind, model_p, q, qd, refs[k, 0], refs[k, 1], refs[k, 2], tau,
                   work, n)
        if k % sample_every == 0:
            j = k // sample_every
            for i in range(n):
                out_q[j, i] = q[i]
                out_qd[j, i] = qd[i]
                out_tau[j, i] = tau[i]
        if k < steps:
            rk4_advance(kind, p, q, qd, tau, h, stages, rest)


def closed_loop(
    plant: Manipulator, law: ControlLaw, q0: FloatArray, refs: FloatArray, h: float, sample_every: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Run the loop from rest at ``q0``; the state and torque at every ``sample_every``-th instant.

    Parameters
    ----------
    plant : Manipulator
        The simulated robot.
    law : ControlLaw
        The controller.
    q0 : ndarray, shape (n,)
        Initial joint angles (the rates start at zero).
    refs : ndarray, shape (N + 1, 3, n)
        ``q, qd, qdd`` of the reference at the control instants.
    h : float
        Control period (s).
    sample_every : int
        Sampling of the outputs, in control steps.

    Returns
    -------
    q, qd, tau : ndarray, shape (N // sample_every + 1, n)
    """
    n = plant.n
    count = (refs.shape[0] - 1) // sample_every + 1
    out_q = np.empty((count, n))
    out_qd = np.empty((count, n))
    out_tau = np.empty((count, n))
    if law.compiled and plant.kernel is not None:
        kind, p = robot_compiled.pack(plant)
        _CLOSED_LOOPS[kind](p, law.code, law.gains, law.smc_model, law.model_kind, law.model_params,
                              np.array(q0, dtype=float), np.zeros(n), refs, h, sample_every, out_q, out_qd, out_tau,
                              robot_compiled.workspace(n))
        return out_q, out_qd, out_tau
    q = np.array(q0, dtype=float)
    qd = np.zeros(n)
    steps = refs.shape[0] - 1
    for k in range(steps + 1):
        tau = law.torque(q, qd, refs[k, 0], refs[k, 1], refs[k, 2])
        if k % sample_every == 0:
            j = k // sample_every
            out_q[j], out_qd[j], out_tau[j] = q, qd, tau
        if k < steps:
            q, qd = rk4_step(plant, q, qd, tau, h)
    return out_q, out_qd, out_tau
