"""The robots' compiled forms behind one interface: one table, dispatch made from it (numba).

Each robot with a compiled form (``Manipulator.kernel`` not None) has one entry in
:data:`COMPILED`: its code and a :class:`CompiledRobot` naming its functions, all with
the signatures below. Everything else -- the plant's RK4 step, the control laws, the
closed loop -- calls only this module's functions, with the robot's flat parameter
array from :meth:`Manipulator.pack`. Adding a compiled robot is that one entry; a code
with no entry raises ``ValueError`` (never another robot's parameters).

Why compiled at all: a 10 kHz loop written with small numpy arrays spends most
of its time in per-call overhead (docs/PERFORMANCE.md). The functions allocate
nothing; temporaries live in a caller-owned scratch array (:func:`workspace`).

The hot path -- the four forward-dynamics calls of an RK4 step -- is chosen at
compile time: :func:`accelerations` and :func:`size` take the robot code as a
constant (callers make one compiled function per code of :data:`COMPILED`:
``sim.rk4``, ``sim.loop``), so each loop is compiled per robot with that robot's
terms inlined, a thesis arm's joint count is a constant and every loop over the
joints unrolls. A code known only at run time goes through a chain of comparisons
made from the table (:func:`by_code`), inlined into each function below.
bench/kernel.py measures the result against the same arithmetic unrolled by hand
(docs/PERFORMANCE.md).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from numba.core import types
from numba.core.errors import TypingError
from numba.extending import overload

from ..kernels.options import ALLOCATION_FREE
from . import parallel_5r_kernels as five_bar
from . import python_form, spatial_layout
from . import serial_3r as serial
from . import spatial_dynamics as chain
from . import spatial_kernels as chain_kinematics
from .base import FloatArray, Manipulator
from .spatial_layout import workspace_size

OUTPUTS_SIZE = 6
"""Floats of :func:`outputs`: end effector (x, y), passive joints and their rates."""


@dataclass(frozen=True)
class CompiledRobot:
    """One robot's compiled functions (numba), each with the signature given here.

    Attributes
    ----------
    joints : int
        Its number of joints when fixed (a thesis arm: the loops over them unroll), else 0.
    terms : ``(p, q, qd, mass, bias, work)``
        ``mass = Mbar(q)`` (motor inertia included), ``bias = C(q, qd) qd + G(q)``.
    accelerations : ``(p, q, qd, tau, out, work)``
        Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)``.
    coriolis_times : ``(p, q, qd, v, out, work)``
        ``C(q, qd) v``.
    gravity : ``(p, q, out, work)``
        ``G(q)``.
    damping, motor_inertia : ``(p, i) -> float``
        ``B_i`` and ``J_i``.
    outputs : ``(p, q, qd, out, work)``
        End effector ``(x, y)`` into ``out[0:2]``; a robot with passive joints also their
        angles ``out[2:4]`` and rates ``out[4:6]``.
    model_terms : ``(p, q, qd, v, mass, grav, cor, work)``, optional
        ``mass = Mbar(q)``, ``grav = G(q)`` and ``cor = C(q, qd) v`` in one call, the same floats as
        ``terms``, ``gravity`` and ``coriolis_times`` (what a model-based law needs every step). By
        default those three, one after the other; a robot whose three share costly work (the
        five-bar's loop closure) gives its own.
    """

    joints: int
    terms: Callable[..., None]
    accelerations: Callable[..., None]
    coriolis_times: Callable[..., None]
    gravity: Callable[..., None]
    damping: Callable[..., float]
    motor_inertia: Callable[..., float]
    outputs: Callable[..., None]
    model_terms: Callable[..., None] | None = None

    def __post_init__(self) -> None:
        if self.model_terms is None:
            object.__setattr__(self, "model_terms", _one_after_another(self.terms, self.gravity, self.coriolis_times))


def _one_after_another(terms: Any, gravity: Any, coriolis_times: Any) -> Callable[..., None]:
    """``model_terms`` made of a robot's ``terms``, ``gravity`` and ``coriolis_times``."""

    def model_terms(p, q, qd, v, mass, grav, cor, work):  # noqa: ANN001, ANN202, PLR0913
        terms(p, q, qd, mass, cor, work)  # its C qd + G lands in cor, which C v then overwrites
        gravity(p, q, grav, work)
        coriolis_times(p, q, qd, v, cor, work)

    return njit(inline="always")(model_terms)


COMPILED: dict[int, CompiledRobot] = {
    serial.SERIAL_3R: CompiledRobot(serial.N, serial.terms, serial.accelerations, serial.coriolis_times,
                                    serial.gravity, serial.damping, serial.motor_inertia, serial.outputs),
    five_bar.PARALLEL_5R: CompiledRobot(five_bar.N, five_bar.terms, five_bar.accelerations,
                                        five_bar.coriolis_times, five_bar.gravity, five_bar.damping,
                                        five_bar.motor_inertia, five_bar.outputs, five_bar.model_terms),
    spatial_layout.SERIAL_CHAIN: CompiledRobot(0, chain.terms, chain.accelerations, chain.coriolis_times,
                                               chain.gravity, chain.damping, chain.motor_inertia,
                                               chain_kinematics.outputs),
    python_form.PYTHON: CompiledRobot(0, python_form.terms, python_form.accelerations, python_form.coriolis_times,
                                      python_form.gravity, python_form.damping, python_form.motor_inertia,
                                      python_form.outputs),
}
"""Every robot's compiled form by its code (``Manipulator.kernel``): the one place to add one. A robot
with none of its own (``kernel`` None) runs behind :mod:`.python_form`'s, which calls its numpy methods."""


def workspace(n: int = 3) -> FloatArray:
    """Scratch array for the compiled functions of a robot with ``n`` joints."""
    return np.empty(max(128, 32 * n + 4 * n * n, 2 * n + n * n + workspace_size(n)))


def pack(robot: Manipulator) -> tuple[int, FloatArray]:
    """``(code, flat parameters)`` of ``robot``'s compiled form (:mod:`.python_form`'s for a robot
    with none of its own)."""
    if robot.kernel is None:
        return python_form.PYTHON, python_form.handle(robot)
    if robot.kernel not in COMPILED:
        raise TypeError(f"robot {robot.name!r}: code {robot.kernel} has no entry in robots.compiled.COMPILED")
    return robot.kernel, robot.pack()


# --------------------------------------------------------------------------- #
# Dispatch, made from the table
# --------------------------------------------------------------------------- #
def _caller(fn: Any) -> Callable[..., Any]:
    """A compiled ``call(args)`` that is ``fn(*args)`` for ``fn``'s number of parameters (numba inlines
    no call with ``*args``, and the thesis arms' small functions are inlined)."""
    arity = len(inspect.signature(fn.py_func).parameters)
    if arity == 2:
        return njit(inline="always")(lambda args: fn(args[0], args[1]))
    if arity == 4:
        return njit(inline="always")(lambda args: fn(args[0], args[1], args[2], args[3]))
    if arity == 5:
        return njit(inline="always")(lambda args: fn(args[0], args[1], args[2], args[3], args[4]))
    if arity == 6:
        return njit(inline="always")(lambda args: fn(args[0], args[1], args[2], args[3], args[4], args[5]))
    if arity == 8:
        return njit(inline="always")(
            lambda args: fn(args[0], args[1], args[2], args[3], args[4], args[5], args[6], args[7]))
    raise TypeError(f"{fn.py_func.__qualname__}: {arity} parameters; CompiledRobot's functions take 2, 4, 5, 6 or 8")


def by_code(function: str, entries: tuple[tuple[int, CompiledRobot], ...] | None = None) -> Callable[..., Any]:
    """A compiled ``f(kind, args)`` made from the table: the robot whose code is ``kind`` runs its
    ``function`` (a field of :class:`CompiledRobot`) on the tuple ``args``; a code with no entry
    raises ``ValueError``. Inlined into its caller: a chain of comparisons, as if written by hand."""
    entries = tuple(COMPILED.items()) if entries is None else entries
    code, robot = entries[0]
    call = _caller(getattr(robot, function))
    if len(entries) == 1:
        def last(kind, args):  # noqa: ANN001, ANN202
            if kind != code:
                raise ValueError("unknown robot code: it has no entry in robots.compiled.COMPILED")
            return call(args)
        return njit(inline="always")(last)
    rest = by_code(function, entries[1:])

    def link(kind, args):  # noqa: ANN001, ANN202
        if kind == code:
            return call(args)
        return rest(kind, args)
    return njit(inline="always")(link)


_TERMS = by_code("terms")
_CORIOLIS_TIMES = by_code("coriolis_times")
_GRAVITY = by_code("gravity")
_DAMPING = by_code("damping")
_MOTOR_INERTIA = by_code("motor_inertia")
_OUTPUTS = by_code("outputs")
_ACCELERATIONS = by_code("accelerations")
_MODEL_TERMS = by_code("model_terms")


def size(kind: int, n: int) -> int:
    """Joints of robot ``kind``: the robot's constant when ``kind`` is a compile-time constant and
    the robot's joints are fixed, else ``n``.

    Compiled code only (:func:`numba.extending.overload`).
    """
    raise NotImplementedError("size() is called from compiled code only")


@overload(size, inline="always")
def _size(kind, n):  # noqa: ANN001, ANN202
    robot = COMPILED.get(kind.literal_value) if isinstance(kind, types.IntegerLiteral) else None
    fixed = robot.joints if robot is not None else 0
    if fixed:
        return lambda kind, n: fixed
    return lambda kind, n: n


def accelerations(kind: int, p: FloatArray, q: FloatArray, qd: FloatArray, tau: FloatArray, out: FloatArray,
                  work: FloatArray) -> None:
    """Eq. (4.1) of robot ``kind`` -- a compile-time constant -- into ``out``.

    Compiled code only (:func:`numba.extending.overload`): the call is resolved to the
    robot's own ``accelerations`` when the caller is compiled, so a loop of many steps
    pays no dispatch. The thesis arms' are written out in scalars.
    """
    raise NotImplementedError("accelerations() is called from compiled code only")


@overload(accelerations, inline="always")
def _accelerations(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN202, PLR0913
    if not isinstance(kind, types.IntegerLiteral) or kind.literal_value not in COMPILED:
        raise TypingError(f"accelerations: the robot code must be a constant of {sorted(COMPILED)}, got {kind}")

    robot_accelerations = COMPILED[kind.literal_value].accelerations

    def impl(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN202, PLR0913, ARG001
        robot_accelerations(p, q, qd, tau, out, work)

    return impl


# --------------------------------------------------------------------------- #
# The interface, for a code known at run time (callable from Python too)
# --------------------------------------------------------------------------- #
@njit(**ALLOCATION_FREE)
def terms(kind, p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """``Mbar(q)`` (motor inertia included) and ``C(q, qd) qd + G(q)``."""
    _TERMS(kind, (p, q, qd, mass, bias, work))


@njit(**ALLOCATION_FREE)
def coriolis_times(kind, p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v``."""
    _CORIOLIS_TIMES(kind, (p, q, qd, v, out, work))


@njit(**ALLOCATION_FREE)
def gravity(kind, p, q, out, work):  # noqa: ANN001, ANN201
    """``G(q)``."""
    _GRAVITY(kind, (p, q, out, work))


@njit(**ALLOCATION_FREE)
def model_terms(kind, p, q, qd, v, mass, grav, cor, work):  # noqa: ANN001, ANN201, PLR0913
    """``Mbar(q)``, ``G(q)`` and ``C(q, qd) v``: :func:`terms`' mass, :func:`gravity` and
    :func:`coriolis_times` in one call (:attr:`CompiledRobot.model_terms`)."""
    _MODEL_TERMS(kind, (p, q, qd, v, mass, grav, cor, work))


@njit(**ALLOCATION_FREE)
def damping(kind, p, i):  # noqa: ANN001, ANN201
    """Motor damping ``B_i``."""
    return _DAMPING(kind, (p, i))


@njit(**ALLOCATION_FREE)
def motor_inertia(kind, p, i):  # noqa: ANN001, ANN201
    """Motor inertia ``J_i``."""
    return _MOTOR_INERTIA(kind, (p, i))


@njit(**ALLOCATION_FREE)
def outputs(kind, p, q, qd, out, work):  # noqa: ANN001, ANN201
    """What the plant reports besides ``q``, ``qd``, into ``out`` (``OUTPUTS_SIZE`` floats).

    ``out[0:2]``: end-effector ``(x, y)``; robots with passive joints: ``out[2:4]``
    their angles and ``out[4:6]`` their rates. One call instead of a dozen small
    numpy operations per published state.
    """
    _OUTPUTS(kind, (p, q, qd, out, work))


@njit(**ALLOCATION_FREE)
def forward_dynamics(kind, p, q, qd, tau, out, work):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out``."""
    _ACCELERATIONS(kind, (p, q, qd, tau, out, work))
