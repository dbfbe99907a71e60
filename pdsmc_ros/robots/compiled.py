"""The robots' compiled forms behind one interface: dispatch on the robot's code (numba).

Each robot with a compiled form (``Manipulator.kernel`` not None) contributes
one line to each dispatch function below; everything else -- the plant's RK4
step, the control laws, the closed loop -- calls only these functions, with the
robot's flat parameter array from :meth:`Manipulator.pack`.

Why compiled at all: a 10 kHz loop written with small numpy arrays spends most
of its time in per-call overhead (docs/PERFORMANCE.md). The functions allocate
nothing; temporaries live in a caller-owned scratch array (:func:`workspace`).

The hot path -- the four forward-dynamics calls of an RK4 step -- is chosen at
compile time instead: :func:`accelerations` and :func:`size` take the robot
code as a constant (callers branch once on it and pass ``SERIAL_3R``,
``PARALLEL_5R`` or ``SERIAL_CHAIN``), so each loop is compiled per robot with
that robot's terms inlined, a thesis arm's joint count is a constant and every
loop over the joints unrolls. Scratch is carved once per run, not per call.
bench/kernel.py measures the result against the same arithmetic unrolled by
hand (docs/PERFORMANCE.md).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.core import types
from numba.core.errors import TypingError
from numba.extending import overload

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


_FIXED_SIZE = {SERIAL_3R: serial.N, PARALLEL_5R: five_bar.N}


def size(kind: int, n: int) -> int:
    """Joints of robot ``kind``: the thesis arms' constant when ``kind`` is a compile-time constant, else ``n``.

    Compiled code only (:func:`numba.extending.overload`).
    """
    raise NotImplementedError("size() is called from compiled code only")


@overload(size, inline="always")
def _size(kind, n):  # noqa: ANN001, ANN202
    fixed = _FIXED_SIZE.get(kind.literal_value, 0) if isinstance(kind, types.IntegerLiteral) else 0
    if fixed:
        return lambda kind, n: fixed
    return lambda kind, n: n


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
@njit(cache=True, inline="always")
def solve_spd(m, b, out, work, n):  # noqa: ANN001, ANN201
    """Solve ``m x = b`` for a small symmetric positive definite ``m`` of size ``n`` (Cholesky)."""
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


def accelerations(kind: int, p: FloatArray, q: FloatArray, qd: FloatArray, tau: FloatArray, out: FloatArray,
                  work: FloatArray) -> None:
    """Eq. (4.1) of robot ``kind`` -- a compile-time constant -- into ``out``.

    Compiled code only (:func:`numba.extending.overload`): the call is resolved to the
    robot's own ``accelerations`` when the caller is compiled, so a loop of many steps
    pays no dispatch. The thesis arms' are written out in scalars.
    """
    raise NotImplementedError("accelerations() is called from compiled code only")


@njit(cache=True)
def _serial_chain_accelerations(p, q, qd, tau, out, work):  # noqa: ANN001, ANN202
    n = q.shape[0]
    rhs = work[0:n]
    mass = work[n : n + n * n].reshape((n, n))
    rest = work[n + n * n :]
    chain.terms(p, q, qd, mass, rhs, rest)
    for i in range(n):
        rhs[i] = tau[i] - rhs[i] - chain.damping(p, i) * qd[i]
    solve_spd(mass, rhs, out, rest, n)


_ACCELERATIONS = {SERIAL_3R: serial.accelerations, PARALLEL_5R: five_bar.accelerations,
                  SERIAL_CHAIN: _serial_chain_accelerations}


@overload(accelerations, inline="always")
def _accelerations(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN202, PLR0913
    if not isinstance(kind, types.IntegerLiteral) or kind.literal_value not in _ACCELERATIONS:
        raise TypingError(f"accelerations: the robot code must be a constant of {sorted(_ACCELERATIONS)}, got {kind}")
    robot_accelerations = _ACCELERATIONS[kind.literal_value]

    def impl(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN202, PLR0913, ARG001
        robot_accelerations(p, q, qd, tau, out, work)

    return impl


@njit(cache=True)
def forward_dynamics(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out``."""
    if kind == SERIAL_3R:
        accelerations(SERIAL_3R, p, q, qd, tau, out, work)
    elif kind == PARALLEL_5R:
        accelerations(PARALLEL_5R, p, q, qd, tau, out, work)
    elif kind == SERIAL_CHAIN:
        accelerations(SERIAL_CHAIN, p, q, qd, tau, out, work)
