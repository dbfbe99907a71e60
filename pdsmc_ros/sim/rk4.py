"""The plant step: one classical Runge-Kutta step of Eq. (4.1) with the torque held.

The torque is constant over the step (zero-order hold), which is exactly what a
digital controller running at ``1 / h`` applies to the plant. Written once, compiled per
robot; a robot written in numpy only steps here too, behind
:mod:`pdsmc_ros.robots.python_form`.
"""

from __future__ import annotations

from collections.abc import Callable

from numba import njit

from ..kernels.options import ALLOCATION_FREE
from ..robots import compiled as robot
from ..robots.base import FloatArray

# the rows of ``stages``: the accelerations a1..a4, the trial rates v2..v4, the trial angles, the result
A1, A2, A3, A4, V2, V3, V4, X, Q_OUT, QD_OUT = range(10)


@njit(**ALLOCATION_FREE)
def rk4_advance(kind, p, q, qd, tau, h, stages, work):  # noqa: ANN001, ANN201, PLR0913
    """One classical RK4 step of Eq. (4.1) of length ``h`` with ``tau`` held, on ``q``, ``qd`` in place.

    The stages ``a1..a4`` are the robot's accelerations at the start, twice at the midpoint and at
    the end; ``q`` advances by ``h/6 (qd + 2 v2 + 2 v3 + v4)``, ``qd`` by ``h/6 (a1 + 2 a2 + 2 a3 + a4)``.

    ``kind`` is a compile-time constant (see :func:`pdsmc_ros.robots.compiled.accelerations`);
    ``stages`` is ``(STAGE_ROWS, n)`` (rows :data:`A1` ... :data:`QD_OUT`), ``work`` the rest: a loop of
    many steps carves them once (:func:`pdsmc_ros.sim.loop.closed_loop`). The arithmetic indexes
    ``stages`` by row and joint rather than through a named view of each row: with numba's reference
    counts the views cost the closed loop about 5 %; without them (:mod:`pdsmc_ros.kernels.options`)
    still 2-4 % of the five-bar's (``bench/kernel.py`` x1.03-1.05 against x1.01).
    """
    n = robot.size(kind, tau.shape[0])
    half = 0.5 * h
    robot.accelerations(kind, p, q, qd, tau, stages[A1], work)
    for i in range(n):
        stages[V2, i] = qd[i] + half * stages[A1, i]
        stages[X, i] = q[i] + half * qd[i]
    robot.accelerations(kind, p, stages[X], stages[V2], tau, stages[A2], work)
    for i in range(n):
        stages[V3, i] = qd[i] + half * stages[A2, i]
        stages[X, i] = q[i] + half * stages[V2, i]
    robot.accelerations(kind, p, stages[X], stages[V3], tau, stages[A3], work)
    for i in range(n):
        stages[V4, i] = qd[i] + h * stages[A3, i]
        stages[X, i] = q[i] + h * stages[V3, i]
    robot.accelerations(kind, p, stages[X], stages[V4], tau, stages[A4], work)
    sixth = h / 6.0
    for i in range(n):
        stages[Q_OUT, i] = q[i] + sixth * (qd[i] + 2.0 * stages[V2, i] + 2.0 * stages[V3, i] + stages[V4, i])
        stages[QD_OUT, i] = qd[i] + sixth * (stages[A1, i] + 2.0 * stages[A2, i] + 2.0 * stages[A3, i]
                                             + stages[A4, i])
    for i in range(n):
        q[i] = stages[Q_OUT, i]
        qd[i] = stages[QD_OUT, i]


STAGE_ROWS = QD_OUT + 1
"""Rows of ``n`` floats :func:`rk4_advance` needs (stages, trial state, result)."""


@njit(cache=True, inline="always")
def carve(work, n):  # noqa: ANN001, ANN201
    """``stages`` and the rest of :func:`rk4_advance`'s scratch, from ``work``."""
    return work[0 : STAGE_ROWS * n].reshape((STAGE_ROWS, n)), work[STAGE_ROWS * n :]


def _step_for(kind: int) -> Callable[[FloatArray, FloatArray, FloatArray, float, FloatArray], None]:
    """The RK4 step compiled for robot code ``kind`` (a constant of the closure: its dynamics inlined)."""

    def step(p, state, tau, h, work):  # noqa: ANN001, ANN202
        n = tau.shape[0]
        stages, rest = carve(work, n)
        rk4_advance(kind, p, state[0:n], state[n : 2 * n], tau, h, stages, rest)

    return njit(**ALLOCATION_FREE)(step)


# one compiled step per robot of the table, made from it: a process compiles (or loads) only the
# robots it runs (numba caches a closure under its code and its cells' values: one entry per code)
_STEPS = {kind: _step_for(kind) for kind in robot.COMPILED}


def compiled_step(kind: int) -> Callable[[FloatArray, FloatArray, FloatArray, float, FloatArray], None]:
    """:func:`rk4_step_compiled` for robot code ``kind``, without the lookup (what a stepper keeps)."""
    return _STEPS[kind]


def rk4_step_compiled(kind: int, p: FloatArray, state: FloatArray, tau: FloatArray, h: float,
                      work: FloatArray) -> None:
    """:func:`rk4_advance` for robot ``(kind, p)`` (:func:`pdsmc_ros.robots.compiled.pack`): advances
    ``state`` in place.

    ``state`` starts with ``q`` and ``qd`` (``2 n`` floats; one array: from Python each
    argument of a compiled call costs about 0.1 us); ``work`` from
    :func:`pdsmc_ros.robots.compiled.workspace`.
    """
    _STEPS[kind](p, state, tau, h, work)
