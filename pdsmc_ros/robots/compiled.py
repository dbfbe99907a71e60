"""The robots' compiled forms behind one interface: dispatch on the robot's code (numba).

Each robot with a compiled form (``Manipulator.kernel`` not None) contributes
one line to each dispatch function below; everything else -- the plant's RK4
step, the control laws, the closed loop -- calls only these functions, with the
robot's flat parameter array from :meth:`Manipulator.pack`.

Why compiled at all: a 10 kHz loop written with small numpy arrays spends most
of its time in per-call overhead (docs/PERFORMANCE.md). The functions allocate
nothing; temporaries live in a caller-owned scratch array (:func:`workspace`),
carved into rows of ``n`` with :func:`rows`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import parallel_5r_kernels as five_bar
from . import serial_3r as serial
from . import spatial_kernels as chain
from .base import FloatArray, Manipulator
from .parallel_5r_kernels import PARALLEL_5R
from .serial_3r import SERIAL_3R
from .spatial_kernels import SERIAL_CHAIN, workspace_size

OUTPUTS_SIZE = 6
"""Floats of :func:`outputs`: end effector (x, y), passive joints and their rates."""


def workspace(n: int = 3) -> FloatArray:
    """Scratch array for the compiled functions of a robot with ``n`` joints."""
    return np.empty(max(128, 32 * n + 4 * n * n, 2 * n + n * n + workspace_size(n)))


def pack(robot: Manipulator) -> tuple[int, FloatArray]:
    """``(code, flat parameters)`` of ``robot``'s compiled form."""
    if robot.kernel is None:
        raise TypeError(f"robot {robot.name!r} has no compiled form")
    return robot.kernel, robot.pack()


@njit(cache=True)
def rows(work, count, n):  # noqa: ANN001, ANN201
    """``count`` rows of ``n`` floats from the front of ``work``, and the rest of it."""
    return work[0 : count * n].reshape((count, n)), work[count * n :]


# --------------------------------------------------------------------------- #
# Dispatch: one line per robot
# --------------------------------------------------------------------------- #
@njit(cache=True)
def terms(kind, p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """``Mbar(q)`` (motor inertia included) and ``C(q, qd) qd + G(q)``."""
    if kind == SERIAL_3R:
        serial.terms(p, q, qd, mass, bias, work)
    elif kind == PARALLEL_5R:
        five_bar.terms(p, q, qd, mass, bias, work)
    elif kind == SERIAL_CHAIN:
        chain.terms(p, q, qd, mass, bias, work)


@njit(cache=True)
def coriolis_times(kind, p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v``."""
    if kind == SERIAL_3R:
        serial.coriolis_times(p, q, qd, v, out, work)
    elif kind == PARALLEL_5R:
        five_bar.coriolis_times(p, q, qd, v, out, work)
    elif kind == SERIAL_CHAIN:
        chain.coriolis_times(p, q, qd, v, out, work)


@njit(cache=True)
def gravity(kind, p, q, out, work):  # noqa: ANN001, ANN201
    """``G(q)``."""
    if kind == SERIAL_3R:
        serial.gravity(p, q, out)
    elif kind == PARALLEL_5R:
        five_bar.gravity(p, q, out, work)
    elif kind == SERIAL_CHAIN:
        chain.gravity(p, q, out, work)


@njit(cache=True)
def damping(kind, p, i):  # noqa: ANN001, ANN201
    """Motor damping ``B_i``."""
    if kind == SERIAL_3R:
        return serial.damping(p, i)
    if kind == SERIAL_CHAIN:
        return chain.damping(p, i)
    return five_bar.damping(p, i)


@njit(cache=True)
def motor_inertia(kind, p, i):  # noqa: ANN001, ANN201
    """Motor inertia ``J_i``."""
    if kind == SERIAL_3R:
        return serial.motor_inertia(p, i)
    if kind == SERIAL_CHAIN:
        return chain.motor_inertia(p, i)
    return five_bar.motor_inertia(p, i)


@njit(cache=True)
def outputs(kind, p, q, qd, out, work):  # noqa: ANN001, ANN201
    """What the plant reports besides ``q``, ``qd``, into ``out`` (``OUTPUTS_SIZE`` floats).

    ``out[0:2]``: end-effector ``(x, y)``; robots with passive joints: ``out[2:4]``
    their angles and ``out[4:6]`` their rates. One call instead of a dozen small
    numpy operations per published state.
    """
    if kind == SERIAL_3R:
        serial.outputs(p, q, out)
    elif kind == PARALLEL_5R:
        five_bar.outputs(p, q, qd, out, work)
    elif kind == SERIAL_CHAIN:
        chain.outputs(p, q, out, work)


# --------------------------------------------------------------------------- #
# Any robot
# --------------------------------------------------------------------------- #
@njit(cache=True)
def solve_spd(m, b, out, work):  # noqa: ANN001, ANN201
    """Solve ``m x = b`` for a small symmetric positive definite ``m`` (Cholesky)."""
    n = b.shape[0]
    lower = work[0 : n * n]  # row-major; only the lower triangle is used
    y = work[n * n : n * n + n]
    for i in range(n):
        for j in range(i + 1):
            s = m[i, j]
            for k in range(j):
                s -= lower[i * n + k] * lower[j * n + k]
            if i == j:
                lower[i * n + i] = math.sqrt(s)
            else:
                lower[i * n + j] = s / lower[j * n + j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= lower[i * n + k] * y[k]
        y[i] = s / lower[i * n + i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= lower[k * n + i] * out[k]
        out[i] = s / lower[i * n + i]


@njit(cache=True)
def forward_dynamics(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out``."""
    n = q.shape[0]
    vectors, rest = rows(work, 2, n)
    bias = vectors[0]
    rhs = vectors[1]
    mass = rest[0 : n * n].reshape((n, n))
    rest = rest[n * n :]
    terms(kind, p, q, qd, mass, bias, rest)
    for i in range(n):
        rhs[i] = tau[i] - bias[i] - damping(kind, p, i) * qd[i]
    solve_spd(mass, rhs, out, rest)
