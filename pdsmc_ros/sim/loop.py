"""The discrete closed loop of a whole run: control at each instant, the plant in between.

At every control instant ``t_k = k / rate`` the law reads the state and the
reference sampled at ``t_k`` and computes a torque; the plant integrates
Eq. (4.1) over one period with that torque held (:mod:`.rk4`). One loop, compiled per robot,
runs every run: a robot or a law written in Python runs in it behind its Python form
(:mod:`pdsmc_ros.robots.python_form`, :mod:`pdsmc_ros.control.python_form`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from ..control.law import ControlLaw, law_torque
from ..control.soft_limits import effort_only_table, soft_limit
from ..kernels.options import ALLOCATION_FREE
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator
from .divergence import DivergenceCheck, watch
from .rk4 import carve, rk4_advance


def _closed_loop_for(kind: int) -> Any:
    """The closed loop compiled for robot code ``kind`` (a constant of the closure: its dynamics inlined)."""

    def closed_loop(p, code, gains, smc_model, model_kind, model_p, q, qd, tau, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
                    limit, bounds, first, at, counts, out_q, out_qd, out_tau, step_error, step_tau, work, state,
                    start_step, advance_last):
        _loop(kind, p, code, gains, smc_model, model_kind, model_p, q, qd, tau, refs, h, sample_every,
              limit, bounds, first, at, counts, out_q, out_qd, out_tau, step_error, step_tau, work, state, start_step,
              advance_last)

    return njit(**ALLOCATION_FREE)(closed_loop)


@njit(cache=True, inline="always")
def _loop(  # noqa: ANN202, PLR0913
    kind, p, code, gains, smc_model, model_kind, model_p, q, qd, tau, refs, h, sample_every,
    limit, bounds, first, at, counts, out_q, out_qd, out_tau, step_error, step_tau, work, state, start_step,
    advance_last,
):  # noqa: ANN001
    # ``q`` and ``qd`` start the run and are stepped in place: the loop ends with the state a
    # following stretch of the run starts from; ``tau`` is the step's torque (scratch). The loop
    # allocates nothing (:data:`~pdsmc_ros.kernels.options.ALLOCATION_FREE`)
    n = robot_compiled.size(kind, q.shape[0])
    steps = refs.shape[0] - 1
    every_step = step_error.shape[0] > 0  # the error and torque of every step too (the scores')
    applied = steps + advance_last  # the periods whose torque the plant is stepped with
    stages, rest = carve(work, n)
    for k in range(steps + 1):
        # the state's check at the statistics instants (every step cost the serial arm's loop 8 %): a
        # diverged run stops at the first instant after it diverged, a limit crossing is seen there
        if k % sample_every == 0:
            hit = watch(q, qd, start_step + k, bounds, first, at)
            if hit >= 0:  # diverged: stop before the law or the plant sees the state
                counts[n] = start_step + k
                counts[n + 1] = hit
                for i in range(n):
                    at[2, i] = q[i]
                    at[3, i] = qd[i]
                return
        law_torque(code, gains, smc_model, model_kind, model_p, q, qd, refs[k, 0], refs[k, 1], refs[k, 2], tau,
                   work, n, state, h)
        # the controller's output limits (np.clip where a joint's limits are unknown); a period
        # counts as saturated when it is applied
        soft_limit(tau, q, qd, limit, counts, 1 if k < applied else 0)
        if k % sample_every == 0:
            j = k // sample_every
            for i in range(n):
                out_q[j, i] = q[i]
                out_qd[j, i] = qd[i]
                out_tau[j, i] = tau[i]
        if every_step:
            for i in range(n):
                step_error[k, i] = refs[k, 0, i] - q[i]
                step_tau[k, i] = tau[i]
        if k < applied:
            rk4_advance(kind, p, q, qd, tau, h, stages, rest)


# one compiled loop per robot of the table, made from it: a process compiles (or loads) only the robots
# it runs (numba caches a closure under its code and its cells' values: one entry per code)
_CLOSED_LOOPS = {kind: _closed_loop_for(kind) for kind in robot_compiled.COMPILED}


@dataclass
class LoopOutcome:
    """What a closed loop reports besides its samples.

    Attributes
    ----------
    saturated : list of int
        Applied periods in which each joint's torque was clamped to its limit.
    diverged : str
        Why the run stopped early (:meth:`DivergenceCheck.diverged`), or ``""``.
    diverged_step : int
        The control step of the diverged state, or -1.
    warnings : list of str
        The first crossing of each joint's position and velocity limit.
    end_q, end_qd : ndarray, shape (n,)
        The state the loop ended in (after the last period when it advanced the plant over it; the
        diverged state when it stopped early).
    step_error, step_tau : ndarray, shape (N + 1, n)
        ``q_d - q`` and the applied torque at every control instant (``run_loop(...,
        every_step=True)``; NaN from a diverged step on), else empty.
    step_drive : ndarray, shape (N + 1, 3, n)
        The MuJoCo stand-in's drive at every control instant: the position and velocity it published
        and the motors' torque over the next tick (:class:`~.mujoco_lockstep.MujocoLoop`'s
        ``drive_record``), else empty.
    """

    saturated: list[int]
    diverged: str = ""
    diverged_step: int = -1
    warnings: list[str] = field(default_factory=list)
    end_q: FloatArray = field(default_factory=lambda: np.zeros(0))
    end_qd: FloatArray = field(default_factory=lambda: np.zeros(0))
    step_error: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    step_tau: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    step_drive: FloatArray = field(default_factory=lambda: np.zeros((0, 3, 0)))


def closed_loop(
    plant: Manipulator, law: ControlLaw, q0: FloatArray, refs: FloatArray, h: float, sample_every: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`run_loop` without a torque limit: the samples only."""
    q, qd, tau, _ = run_loop(plant, law, q0, refs, h, sample_every)
    return q, qd, tau


def run_loop(
    plant: Manipulator, law: ControlLaw, q0: FloatArray, refs: FloatArray, h: float, sample_every: int,
    torque_limit: FloatArray | None = None, check: DivergenceCheck | None = None, *,
    qd0: FloatArray | None = None, start_step: int = 0, advance_last: bool = False, every_step: bool = False,
) -> tuple[FloatArray, FloatArray, FloatArray, LoopOutcome]:
    """Run the loop from rest at ``q0``; the state and torque at every ``sample_every``-th instant.

    A run in stretches (:func:`pdsmc_ros.sim.simulator.simulate` with ``keep_samples=False``) runs
    each stretch but the last with ``advance_last`` and the next from the previous one's
    :attr:`LoopOutcome.end_q` and ``end_qd`` at its ``start_step``: the same steps as one call.

    Parameters
    ----------
    plant : Manipulator
        The simulated robot.
    law : ControlLaw
        The controller; a law with internal state starts from its state as it is (zeros for
        a new law) and integrates it with ``h``, in place.
    q0 : ndarray, shape (n,)
        Initial joint angles (the rates start at zero).
    refs : ndarray, shape (N + 1, 3, n)
        ``q, qd, qdd`` of the reference at the control instants.
    h : float
        Control period (s).
    sample_every : int
        Sampling of the outputs, in control steps.
    torque_limit : ndarray, shape (6, n), optional
        The controller's output limits applied to the law's torque at every step
        (:func:`~pdsmc_ros.control.soft_limits.soft_limit`, the controller node's; a table of
        :func:`~pdsmc_ros.control.soft_limits.soft_limit_table`); None: not limited.
    check : DivergenceCheck, optional
        Checks the state at every statistics instant (every ``sample_every``-th step: at every
        step it cost the serial arm's loop about 8 %): the run stops at the first instant whose
        state has diverged, and the first instant beyond each joint's position and velocity limit
        is recorded (the plant node checks every step); by default
        :meth:`DivergenceCheck.for_robot` of ``plant``.
    qd0 : ndarray, shape (n,), optional
        Initial joint rates (default zero).
    start_step : int
        The control step of ``refs[0]`` in the whole run (the steps the check and the outcome name).
    advance_last : bool
        Also step the plant over the period of the last instant (its torque applied): the loop
        ends at the instant after ``refs``' last, where the next stretch starts.
    every_step : bool
        Also keep ``q_d - q`` and the torque of every control instant
        (:attr:`LoopOutcome.step_error`, :attr:`LoopOutcome.step_tau`: what the scores read).

    Returns
    -------
    q, qd, tau : ndarray, shape (N // sample_every + 1, n)
        NaN from the first sample at or after a divergence.
    outcome : LoopOutcome
    """
    n = plant.n
    count = (refs.shape[0] - 1) // sample_every + 1
    out_q = np.empty((count, n))
    out_qd = np.empty((count, n))
    out_tau = np.empty((count, n))
    limit = effort_only_table(None, n) if torque_limit is None else np.ascontiguousarray(torque_limit, dtype=float)
    check = check or DivergenceCheck.for_robot(plant)
    counts = np.zeros(n + 2, dtype=np.int64)
    counts[n] = -1
    kind, p = robot_compiled.pack(plant)
    end_q = np.array(q0, dtype=float)  # the loop starts here and writes where it ends
    end_qd = np.zeros(n) if qd0 is None else np.array(qd0, dtype=float)
    rows = refs.shape[0] if every_step else 0
    step_error = np.empty((rows, n))
    step_tau = np.empty((rows, n))
    _CLOSED_LOOPS[kind](p, law.code, law.gains, law.smc_model, law.model_kind, law.model_params,
                        end_q, end_qd, np.empty(n), refs, h, sample_every, limit, check.bounds, check.first,
                        check.at, counts, out_q, out_qd, out_tau, step_error, step_tau,
                        robot_compiled.workspace(n), law.state, int(start_step), int(advance_last))
    outcome = LoopOutcome(counts[:n].tolist(), warnings=check.new_warnings(1.0 / h), end_q=end_q, end_qd=end_qd,
                          step_error=step_error, step_tau=step_tau)
    if counts[n] >= 0:
        step = int(counts[n])
        first_missing = -(-(step - start_step) // sample_every)  # the samples at or after the diverged step
        for out in (out_q, out_qd, out_tau):
            out[first_missing:] = np.nan
        for out in (step_error, step_tau):
            out[step - start_step:] = np.nan
        outcome.diverged_step = step
        joint = int(counts[n + 1])
        outcome.diverged = check.diverged(joint, check.at[2], check.at[3], step * h)
    return out_q, out_qd, out_tau, outcome
