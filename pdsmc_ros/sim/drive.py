"""The drive between MuJoCo and the wire: what an arm's driver publishes and what a command does,
compiled once for the ``mujoco_driver`` node and the in-process lockstep runs (ROS-free).

The nuisances of :mod:`.realism` that are not physics act here, in one tick of the driver
(one period ``T`` of its rate, ``substeps`` MuJoCo steps):

1. **the command** (:func:`take_command`): the tick's command enters a delay line and the one
   ``command_delay`` ticks older leaves it; until a command has left it the motors have none and
   the arm stays braked (MuJoCo does not step), as the driver's arm is braked until its first
   command;
2. **the torque**, each MuJoCo step (:func:`actuate`): a first-order lag of the command
   (``torque_bandwidth_hz``, the drive's current loop), then the torque-speed line
   (``torque_speed``: at most ``e (1 - v / v0)`` in the direction of motion, as mjlab's
   ``DcMotorActuator`` clips, the speed bounded at ``2 v0``); MuJoCo's actuator saturates at the
   URDF's effort limit as before;
3. **the state it publishes** (:func:`sense`), at the end of the tick: Gaussian noise of
   ``position_noise``, then the encoder's grid (``encoder_counts``: the nearest count); the
   velocity MuJoCo's (``exact``) or the backward difference of the published positions over ``T``
   (``difference``), low-pass filtered at ``velocity_filter_hz``.

Both filters are libfranka's first-order discretisation (``franka::lowpassFilter``):
``y += a (x - y)`` with ``a = dt / (dt + 1 / (2 pi f))`` (:func:`lowpass_gain`; ``a = 1``: none).

A tick's arithmetic is :func:`run_ticks` (the driver: ticks of the latest command) and the
lockstep loop of :mod:`.mujoco_lockstep` (the law's command each tick): both call MuJoCo's
``mj_step`` from compiled code (:data:`MJ_STEP`, the C function of the ``mujoco`` wheel), so a
tick costs MuJoCo's steps and a few dozen flops. With every nuisance off a tick is the step the
driver always took: the command held over the period, the exact state published.
"""

from __future__ import annotations

import ctypes
import glob
import math
import os
from typing import Any

import numba.experimental.function_type  # noqa: F401 - registers the type of MJ_STEP (a first-class function)
import numpy as np
from numba import njit, types
from numba.core.types import WrapperAddressProtocol

from ..control.lowpass import lowpass_gain
from ..errors import InvalidInputError
from ..kernels.options import ALLOCATION_FREE
from ..parameters.tables import MAX_COMMAND_DELAY
from ..robots.base import FloatArray
from .realism import Realism, _encoder_step

# rows of the drive's parameters (ROWS x n)
P_STEP = 0  # the encoder's grid (rad or m; 0: exact)
P_NOISE = 1  # the position noise's standard deviation
P_VELOCITY = 2  # the velocity filter's gain a per tick (1: none)
P_LAG = 3  # the torque lag's gain a per MuJoCo step (1: none)
P_NO_LOAD = 4  # the no-load speed (inf: no torque-speed line)
P_EFFORT = 5  # the effort limit the torque-speed line starts from
PARAMETER_ROWS = 6
# rows of the drive's state (ROWS x n)
S_Q = 0  # the published position
S_QD = 1  # the published velocity
S_PREVIOUS = 2  # the previous published position (the difference's)
S_FILTERED = 3  # the filtered velocity
S_LAG = 4  # the torque after the lag
S_COMMAND = 5  # the command the motors take this tick (after the delay)
S_TRUE_Q = 6  # scratch: the true state of the tick
S_TRUE_QD = 7
STATE_ROWS = 8
# the drive's counters
C_HEAD = 0  # where the delay line writes next
C_SENSED = 1  # whether a state was published (the difference has a previous one)
C_STEPS = 2  # MuJoCo steps taken
C_FLAGS = 3  # the velocity source (0 exact, 1 difference)
C_DELAY = 4  # the command delay (ticks)
C_SUBSTEPS = 5  # MuJoCo steps a tick
COUNTERS = 6
VELOCITY_CODES = {"exact": 0, "difference": 1}


# --------------------------------------------------------------------------- #
# MuJoCo's mj_step, callable from compiled code
# --------------------------------------------------------------------------- #
def _libmujoco() -> ctypes.CDLL:
    import mujoco

    found = sorted(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")))
    found += sorted(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco*.dylib")))
    if not found:  # pragma: no cover - the wheel ships it
        raise InvalidInputError("the mujoco wheel has no libmujoco shared library to step from compiled code")
    return ctypes.CDLL(found[0])


class MjStep(WrapperAddressProtocol):
    """MuJoCo's ``mj_step(const mjModel*, mjData*)`` as a first-class function of numba: passed as an
    argument (a compiled caller stays cacheable), called with the addresses of an ``MjModel`` and an
    ``MjData`` (their ``_address``). The same C function ``mujoco.mj_step`` calls, from the wheel."""

    def __init__(self) -> None:
        self._address = ctypes.cast(_libmujoco().mj_step, ctypes.c_void_p).value

    def __wrapper_address__(self) -> int:
        return int(self._address)  # type: ignore[arg-type]

    def signature(self) -> Any:
        return types.void(types.intp, types.intp)


_MJ_STEP: MjStep | None = None


def mj_step_function() -> MjStep:
    """The process's :class:`MjStep` (the library is loaded once)."""
    global _MJ_STEP  # noqa: PLW0603 - one handle a process
    if _MJ_STEP is None:
        _MJ_STEP = MjStep()
    return _MJ_STEP


# --------------------------------------------------------------------------- #
# The tick's parts, compiled
# --------------------------------------------------------------------------- #
@njit(cache=True, inline="always")
def sense(q, qd, params, state, counters, noise, period):  # noqa: ANN001, ANN201
    """What the drive publishes of the true state ``q, qd`` (its actuated joints): into
    ``state[S_Q]``, ``state[S_QD]``. ``noise``: one standard normal a joint (this tick's draw)."""
    n = q.shape[0]
    difference = counters[C_FLAGS] == 1
    first = counters[C_SENSED] == 0
    for i in range(n):
        x = q[i] + params[P_NOISE, i] * noise[i]
        grid = params[P_STEP, i]
        if grid > 0.0:
            x = math.floor(x / grid + 0.5) * grid
        state[S_Q, i] = x
        if difference:
            v = 0.0 if first else (x - state[S_PREVIOUS, i]) / period
            a = params[P_VELOCITY, i]
            if a >= 1.0:
                state[S_FILTERED, i] = v
            else:
                state[S_FILTERED, i] += a * (v - state[S_FILTERED, i])
            state[S_QD, i] = state[S_FILTERED, i]
        else:
            state[S_QD, i] = qd[i]
        state[S_PREVIOUS, i] = x
    counters[C_SENSED] = 1


@njit(cache=True, inline="always")
def take_command(tau, valid, state, ring, ring_valid, counters):  # noqa: ANN001, ANN201
    """The tick's command (``valid``: 1, else 0: none) into the delay line; the one ``delay``
    ticks older into ``state[S_COMMAND]``. Returns whether the motors have a command."""
    n = tau.shape[0]
    size = ring.shape[0]
    head = counters[C_HEAD]
    for i in range(n):
        ring[head, i] = tau[i]
    ring_valid[head] = valid
    out = head - counters[C_DELAY]
    if out < 0:
        out += size
    for i in range(n):
        state[S_COMMAND, i] = ring[out, i]
    counters[C_HEAD] = head + 1 if head + 1 < size else 0
    return ring_valid[out]


@njit(cache=True, inline="always")
def actuate(params, state, qvel, vadr, ctrl):  # noqa: ANN001, ANN201
    """The motors' torque for one MuJoCo step into ``ctrl``: the command lagged, then bounded by the
    torque-speed line at the joints' true velocity (``qvel[vadr[i]]``)."""
    n = ctrl.shape[0]
    for i in range(n):
        a = params[P_LAG, i]
        t = state[S_COMMAND, i] if a >= 1.0 else state[S_LAG, i] + a * (state[S_COMMAND, i] - state[S_LAG, i])
        state[S_LAG, i] = t
        v0 = params[P_NO_LOAD, i]
        if v0 < math.inf:
            e = params[P_EFFORT, i]
            v = min(max(qvel[vadr[i]], -2.0 * v0), 2.0 * v0)
            hi = min(e * (1.0 - v / v0), e)
            lo = max(e * (-1.0 - v / v0), -e)
            t = min(max(t, lo), hi)
        ctrl[i] = t


@njit(cache=True, inline="always")
def apply_tick(step, model, data, qvel, vadr, ctrl, params, state, ring, ring_valid, counters, tau, valid):  # noqa: ANN001, ANN201, PLR0913
    """One tick of the physics: ``tau`` (``valid``) through the delay line, then ``substeps`` MuJoCo
    steps with the motors' torque; none (the brakes hold the arm, the lag restarts from zero) while
    the motors have no command. Returns whether MuJoCo stepped."""
    n = ctrl.shape[0]
    if take_command(tau, valid, state, ring, ring_valid, counters) == 0:
        for i in range(n):
            state[S_LAG, i] = 0.0
        return False
    for _ in range(counters[C_SUBSTEPS]):
        actuate(params, state, qvel, vadr, ctrl)
        step(model, data)
    counters[C_STEPS] += counters[C_SUBSTEPS]
    return True


@njit(**ALLOCATION_FREE)
def run_ticks(step, model, data, qpos, qvel, qadr, vadr, ctrl, params, state, ring, ring_valid, counters,  # noqa: ANN001, ANN201, PLR0913
              tau, valid, noise, period):
    """``noise.shape[0]`` ticks of the driver with ``tau`` its latest command (``valid`` 0: none,
    the brakes closed), each ending with the state it publishes (:func:`sense`, a row of ``noise``
    a tick). Returns the ticks in which MuJoCo stepped."""
    n = ctrl.shape[0]
    stepped = 0
    for k in range(noise.shape[0]):
        if apply_tick(step, model, data, qvel, vadr, ctrl, params, state, ring, ring_valid, counters, tau, valid):
            stepped += 1
        for i in range(n):
            state[S_TRUE_Q, i] = qpos[qadr[i]]
            state[S_TRUE_QD, i] = qvel[vadr[i]]
        sense(state[S_TRUE_Q], state[S_TRUE_QD], params, state, counters, noise[k], period)
    return stepped


@njit(**ALLOCATION_FREE)
def sense_now(qpos, qvel, qadr, vadr, params, state, counters, noise, period):  # noqa: ANN001, ANN201
    """:func:`sense` of the state MuJoCo holds now (a tick in which it did not step)."""
    n = qadr.shape[0]
    for i in range(n):
        state[S_TRUE_Q, i] = qpos[qadr[i]]
        state[S_TRUE_QD, i] = qvel[vadr[i]]
    sense(state[S_TRUE_Q], state[S_TRUE_QD], params, state, counters, noise, period)


# --------------------------------------------------------------------------- #
# The drive's arrays for a run
# --------------------------------------------------------------------------- #
class Drive:
    """The drive's parameters and state for one arm (:class:`~.realism.Realism`) at one rate.

    Parameters
    ----------
    realism : Realism
        The nuisances.
    period : float
        The tick (s): the delay counts it, the velocity is differenced over it.
    substeps : int
        MuJoCo steps a tick.
    effort_limits : ndarray, shape (n,)
        Each joint's effort limit, where the torque-speed line starts.
    revolute : ndarray of bool, shape (n,)
        Whether each joint turns (its encoder's counts are a revolution's; else a metre's).

    Attributes
    ----------
    params, state, ring, ring_valid, counters
        The compiled functions' arrays (rows: ``P_*``, ``S_*``; the delay line; ``C_*``).
    """

    def __init__(self, realism: Realism, period: float, substeps: int, effort_limits: FloatArray,
                 revolute: np.ndarray) -> None:
        if not (math.isfinite(period) and period > 0.0):
            raise InvalidInputError(f"the drive's period must be > 0 s, got {period!r}")
        if int(substeps) < 1:
            raise InvalidInputError(f"substeps must be >= 1, got {substeps!r}")
        n = realism.n
        self.n = n
        self.period = float(period)
        self.substeps = int(substeps)
        self.effort_limits = np.asarray(effort_limits, dtype=float)
        self.revolute = np.asarray(revolute, dtype=bool)
        self.params = np.zeros((PARAMETER_ROWS, n))
        self.state = np.zeros((STATE_ROWS, n))
        self.ring = np.zeros((MAX_COMMAND_DELAY + 1, n))
        self.ring_valid = np.zeros(MAX_COMMAND_DELAY + 1, dtype=np.int64)
        self.counters = np.zeros(COUNTERS, dtype=np.int64)
        self.counters[C_SUBSTEPS] = self.substeps
        self.rng = np.random.default_rng(realism.seed)
        self.realism = realism
        self.configure(realism)

    def configure(self, realism: Realism) -> None:
        """Take new drive nuisances (a parameter set while the driver runs): the delay line, the
        filters' states and the random stream carry on."""
        if realism.n != self.n:
            raise InvalidInputError(f"the drive has {self.n} joints; these nuisances are for {realism.n}")
        p = self.params
        p[P_STEP] = _encoder_step(realism.encoder_counts, self.revolute)
        p[P_NOISE] = realism.position_noise
        p[P_VELOCITY] = lowpass_gain(self.period, realism.velocity_filter_hz)
        p[P_LAG] = lowpass_gain(self.period / self.substeps, realism.torque_bandwidth_hz)
        p[P_NO_LOAD] = realism.no_load_speed if realism.torque_speed else np.inf
        p[P_EFFORT] = self.effort_limits
        self.counters[C_FLAGS] = VELOCITY_CODES[realism.velocity_source]
        self.counters[C_DELAY] = realism.command_delay
        self.realism = realism

    @property
    def noisy(self) -> bool:
        return bool(np.any(self.params[P_NOISE] > 0))

    def noise(self, ticks: int) -> FloatArray:
        """The standard normals of the next ``ticks`` ticks (zeros without position noise: the
        random stream is drawn only where it is used, in tick order)."""
        if self.noisy:
            return self.rng.standard_normal((ticks, self.n))
        return np.zeros((ticks, self.n))

    def release(self) -> None:
        """Forget the commands and the torque (brakes closed: the next command starts afresh)."""
        self.ring_valid[:] = 0
        self.state[S_LAG] = 0.0

    @property
    def published(self) -> tuple[FloatArray, FloatArray]:
        """The position and velocity the drive publishes now (views)."""
        return self.state[S_Q], self.state[S_QD]
