"""A robot with no compiled form of its own, behind the compiled interface (numba ``objmode``).

A robot written in numpy only (a :class:`~pdsmc_ros.robots.base.Manipulator` subclass with
``kernel = None``: a user's arm, a test's toy) still runs through the one closed loop, the
one RK4 step and the one form of each control law: its compiled form is this module's
functions, which call back into the robot's numpy methods. Its flat parameter array is one
float, a handle to the robot (:func:`handle`). Each call leaves compiled code for Python
(about 3 us), which is what a numpy robot's methods cost anyway; a robot that needs speed
adds its own entry to :data:`pdsmc_ros.robots.compiled.COMPILED`.
"""

from __future__ import annotations

import itertools
import weakref

import numpy as np
from numba import njit, objmode

from ..kernels.options import WITH_RUNTIME
from .base import FloatArray, Manipulator

PYTHON = -1
"""Code of this compiled form (:data:`pdsmc_ros.robots.compiled.COMPILED`)."""

_ROBOTS: weakref.WeakValueDictionary[int, Manipulator] = weakref.WeakValueDictionary()
_HANDLES: weakref.WeakKeyDictionary[Manipulator, int] = weakref.WeakKeyDictionary()
_NEXT = itertools.count()


def handle(robot: Manipulator) -> FloatArray:
    """The flat parameter array of ``robot``'s compiled form: a handle to it (held weakly)."""
    key = _HANDLES.get(robot)
    if key is None:
        key = _HANDLES[robot] = next(_NEXT)
        _ROBOTS[key] = robot
    return np.array([float(key)])


def robot_of(p: FloatArray) -> Manipulator:
    """The robot behind the parameter array ``p`` of :func:`handle`."""
    return _ROBOTS[int(p[0])]


def _terms(p: FloatArray, q: FloatArray, qd: FloatArray, mass: FloatArray, bias: FloatArray) -> None:
    mass[:, :], bias[:] = robot_of(p)._bias(q.copy(), qd.copy())


def _accelerations(p: FloatArray, q: FloatArray, qd: FloatArray, tau: FloatArray, out: FloatArray) -> None:
    out[:] = robot_of(p)._forward_dynamics(q.copy(), qd.copy(), tau.copy())


def _coriolis_times(p: FloatArray, q: FloatArray, qd: FloatArray, v: FloatArray, out: FloatArray) -> None:
    out[:] = robot_of(p)._coriolis_matrix(q.copy(), qd.copy()) @ v


def _gravity(p: FloatArray, q: FloatArray, out: FloatArray) -> None:
    out[:] = robot_of(p)._gravity(q.copy())


def _outputs(p: FloatArray, q: FloatArray, qd: FloatArray, out: FloatArray) -> None:
    robot = robot_of(p)
    out[0:2] = robot.position(q.copy())
    passive, passive_rates = robot.passive_joints(q.copy(), qd.copy())
    k = passive.shape[-1]
    out[2 : 2 + k] = passive
    out[4 : 4 + k] = passive_rates


def _damping(p: FloatArray, i: int) -> float:
    return float(robot_of(p).B[i])


def _motor_inertia(p: FloatArray, i: int) -> float:
    return float(robot_of(p).J[i])


# The compiled interface (signatures of pdsmc_ros.robots.compiled.CompiledRobot). The copies
# above: a robot's method may keep or change what it is given, and these arrays are the
# caller's scratch.
@njit(**WITH_RUNTIME)
def terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201, ARG001
    """``Mbar(q)`` and ``C(q, qd) qd + G(q)`` from the robot's ``_bias``."""
    with objmode():
        _terms(p, q, qd, mass, bias)


@njit(**WITH_RUNTIME)
def accelerations(p, q, qd, tau, out, work):  # noqa: ANN001, ANN201, ARG001
    """Eq. (4.1) from the robot's ``_forward_dynamics``."""
    with objmode():
        _accelerations(p, q, qd, tau, out)


@njit(**WITH_RUNTIME)
def coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN201, ARG001
    """``C(q, qd) v`` from the robot's ``_coriolis_matrix``."""
    with objmode():
        _coriolis_times(p, q, qd, v, out)


@njit(**WITH_RUNTIME)
def gravity(p, q, out, work):  # noqa: ANN001, ANN201, ARG001
    """``G(q)`` from the robot's ``_gravity``."""
    with objmode():
        _gravity(p, q, out)


@njit(**WITH_RUNTIME)
def outputs(p, q, qd, out, work):  # noqa: ANN001, ANN201, ARG001
    """End effector and passive joints from the robot's ``position`` and ``passive_joints``."""
    with objmode():
        _outputs(p, q, qd, out)


@njit(**WITH_RUNTIME)
def damping(p, i):  # noqa: ANN001, ANN201
    """``B_i``."""
    with objmode(value="float64"):
        value = _damping(p, i)
    return value  # noqa: RET504 - objmode hands its results out through assigned names


@njit(**WITH_RUNTIME)
def motor_inertia(p, i):  # noqa: ANN001, ANN201
    """``J_i``."""
    with objmode(value="float64"):
        value = _motor_inertia(p, i)
    return value  # noqa: RET504 - objmode hands its results out through assigned names
