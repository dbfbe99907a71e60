"""Discrete-time stability of a control law sampled with a zero-order hold, with the loop's delay.

A digital controller applies ``tau_k`` over a whole period ``h``. Around the
reference, the error dynamics are ``Mbar edd = -Kp_eff e - Kd_eff ed`` with a
held input, whose exact discretisation is

    e_{k+1}  = e_k + h ed_k - (h^2/2) Mbar^{-1} (Kp e_k + Kd ed_k)
    ed_{k+1} = ed_k        - h Mbar^{-1} (Kp e_k + Kd ed_k)

(damping, Coriolis and gravity variations left out). That is lockstep, where the
plant waits for the command of its state. In real time the command is applied ``d``
periods after the state it was computed from (:data:`REALTIME_DELAY_PERIODS`, the loop's
delay model; ``delay_periods`` declares more, a driver's or a network's), and the map is
augmented with the ``d`` commands on their way (:func:`loop_matrix`). The loop is stable at
rate ``1/h`` only if the spectral radius of that map is below 1 at every configuration the
motion visits. With the serial arm's thesis gains this requires about 10 kHz without delay
(it diverges at 5 kHz); each period of delay raises the lowest stable rate. :func:`check_rate`
asks for a margin ``rate / lowest stable rate`` on top (:data:`REQUIRED_MARGIN`).

A drive that differences the encoder's positions and low-pass filters the result (the MuJoCo
stand-in's ``velocity_source: difference`` and ``velocity_filter_hz``; ``pdsmc check-gains
--realism bench``) gives the law a velocity that lags the true one: the map then carries the
previous error and the filter's state too (``filter_hz`` of :func:`loop_matrix`), so the filter's
phase lag counts against the rate as the delay does. The torque's own lag (the drive's current
loop, ``torque_bandwidth_hz``) is not modelled.

The arm's own viscous damping ``B`` (N m s/rad a joint) is left out by default, as the map above
has it. Given (``damping`` of :func:`loop_matrix`; ``pdsmc check-gains --realism PRESET``, which
names the arm the check describes: the description's damping plus the preset's ``friction_viscous``),
it enters the plant: ``Mbar edd = -B ed + Mbar a`` integrated exactly over the period with the
held ``a`` (the zero-order hold of the damped double integrator, :func:`held_plant`). It is linear,
it acts on the arm's true velocity at every instant and not through the drive's delay or filter,
so it belongs to the plant the map describes; on the bench arm it is what damps the mode the
undamped map finds unstable (docs/explanation/ladder.md). Coulomb friction stays out: it is not
linear, and leaving it out errs on the safe side (it only takes energy out).

The plant itself is integrated explicitly (RK4 at the control period: the in-process plant
and the MuJoCo stand-in): a joint whose damping over inertia times the period exceeds RK4's
real-axis limit diverges whatever the gains. :func:`plant_step` names that joint and the
armature or rate that fixes it.

Effective gains inside the boundary layer (``|s| < phi``), where the
switching term is linear:

* PD (Eq. 3.4): ``Kp``, ``Kd``.
* PD-SMC (Eq. 3.44): ``Kp + Ks lambda / phi``, ``Kd + Ks / phi``.
* SMC (Eq. 3.15): ``Ks lambda / phi``, ``s_M lambda Mbar + Ks / phi``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..checks import is_whole
from ..contours import JointReference
from ..errors import InvalidInputError, UnstableRateError
from ..robots.base import FloatArray, Manipulator
from .law_run import LawRun
from .lowpass import lowpass_gain
from .lyapunov import Condition, theorem_conditions
from .registry import law


def effective_gains(spec: LawRun, mass: FloatArray, qd_ref: FloatArray | None = None,
                    qdd_ref: FloatArray | None = None) -> tuple[FloatArray, FloatArray] | None:
    """Linear gains ``(Kp_eff, Kd_eff)`` of the law inside its boundary layer (None: the law has none).

    A law feeding back ``E e`` and ``E edot + G e`` (:attr:`~pdsmc_ros.control.registry.LawEntry.error_map`,
    a position domain law) has ``(Kp_eff E + Kd_eff G, Kd_eff E)`` at the reference velocity ``qd_ref``
    and acceleration ``qdd_ref`` (both required then).
    """
    entry = law(spec.controller)
    if entry.linear_gains is None:
        return None
    matrix = spec.gains.matrix()
    kp, kd = entry.linear_gains(matrix, spec.smc_model_vector(), mass)
    if entry.error_map is None:
        return kp, kd
    if qd_ref is None or qdd_ref is None:
        raise InvalidInputError(f"control law {spec.controller!r} feeds back a position domain error: its linear "
                                "gains need the reference velocity qd_ref and acceleration qdd_ref")
    e_map, g_map = entry.error_map(matrix, np.asarray(qd_ref, dtype=float), np.asarray(qdd_ref, dtype=float))
    return kp @ e_map + kd @ g_map, kd @ e_map


def held_plant(mass: FloatArray, damping: FloatArray, h: float | FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(Ad, Bd)`` of the damped double integrator ``edd = -Mbar^{-1} B ed + a`` with ``a`` held over ``h``.

    The exact zero-order-hold discretisation: the exponential (``scipy.linalg.expm``, stacks
    included) of ``h [[0, I, 0], [0, -Mbar^{-1} B, I], [0, 0, 0]]``, whose first ``2n`` rows are
    ``[Ad, Bd]``; ``B = 0`` gives the undamped ``Ad = [[I, hI], [0, I]]``, ``Bd = [h^2/2 I; h I]`` of
    :func:`loop_matrix`. ``damping``: ``B``'s diagonal (shape ``(n,)``, N m s/rad).
    """
    from scipy.linalg import expm  # here: the check without damping (every node's start) needs no scipy

    mass = np.asarray(mass, dtype=float)
    n = mass.shape[-1]
    b = np.broadcast_to(np.asarray(damping, dtype=float), (n,))
    h = np.asarray(h, dtype=float)[..., None, None]
    stack = np.broadcast_shapes(mass.shape[:-2], h.shape[:-2])
    z = np.zeros((*stack, 3 * n, 3 * n))
    eye = np.eye(n)
    z[..., :n, n:2 * n] = eye
    z[..., n:2 * n, n:2 * n] = -np.linalg.solve(mass, np.broadcast_to(np.diag(b), mass.shape))
    z[..., n:2 * n, 2 * n:] = eye
    total = expm(z * h)
    return total[..., :2 * n, :2 * n], total[..., :2 * n, 2 * n:]


def loop_matrix(mass: FloatArray, kp: FloatArray, kd: FloatArray, h: float | FloatArray,
                delay: int = 0, filter_hz: FloatArray | None = None,
                damping: FloatArray | None = None) -> FloatArray:
    """The error map of a held input applied ``delay`` periods after the state it was computed from.

    With ``a_k = -Mbar^{-1} (Kp e_k + Kd ed_k)`` the acceleration commanded from the state of
    instant ``k`` and held (zero-order hold) over a whole period ``h``, the plant applies
    ``a_{k-d}``: ``x_{k+1} = Ad x_k + Bd a_{k-d}`` with ``x = (e, ed)``, ``Ad = [[I, hI], [0, I]]``,
    ``Bd = [h^2/2 I; h I]``. The state is augmented with the ``d`` commands computed but not yet
    applied, ``X_k = (x_k, a_{k-1}, ..., a_{k-d})``, of dimension ``(2 + d) n``; ``d = 0`` is the
    plain held-input map of the module docstring. Works on one configuration or on a stack
    (leading axis ``m``, ``h`` scalar or of shape ``(m,)``).

    ``filter_hz`` (shape ``(n,)``): the law sees the velocity as a drive estimates it, the backward
    difference of the positions over the period low-pass filtered at ``filter_hz`` per joint (0: the
    difference unfiltered; the stand-in's ``velocity_source: difference``, :mod:`pdsmc_ros.sim.drive`):
    ``v_k = (1 - A) v_{k-1} + (A / h) (e_k - e_{k-1})`` with ``A`` the filter's gain a sample
    (:func:`~pdsmc_ros.control.lowpass.lowpass_gain`) and ``a_k = -Mbar^{-1} (Kp e_k + Kd v_k)``. The
    state then also holds ``e_{k-1}`` and ``v_{k-1}``: ``X_k = (x_k, e_{k-1}, v_{k-1}, a_{k-1}, ...,
    a_{k-d})``, of dimension ``(4 + d) n``. None: the exact velocity.

    ``damping`` (shape ``(n,)``, N m s/rad): the arm's viscous damping ``B``, in the plant between two
    instants (``Ad``, ``Bd`` of :func:`held_plant`); None: left out (``B = 0``, the map above).
    """
    if not is_whole(delay) or delay < 0:
        raise InvalidInputError(f"delay must be a whole number of periods >= 0, got {delay!r}")
    mass = np.asarray(mass, dtype=float)
    n = mass.shape[-1]
    h = np.asarray(h, dtype=float)[..., None, None]
    gain = -np.concatenate([np.linalg.solve(mass, kp), np.linalg.solve(mass, kd)], axis=-1)  # a = gain x
    eye = np.broadcast_to(np.eye(n), gain.shape[:-2] + (n, n))
    bd = np.concatenate([0.5 * h * h * eye, h * eye], axis=-2)  # (.., 2n, n)
    extra = 0 if filter_hz is None else 2  # e_{k-1} and v_{k-1}
    size = (2 + extra + delay) * n
    a = np.zeros((*gain.shape[:-2], size, size))
    if damping is None:
        a[..., :n, :n] = eye
        a[..., :n, n:2 * n] = h * eye
        a[..., n:2 * n, n:2 * n] = eye
    else:
        ad, bd = held_plant(mass, damping, h[..., 0, 0])
        a[..., :2 * n, :2 * n] = ad
    if filter_hz is None:
        command = gain  # a_k from (e_k, ed_k)
    else:
        f = np.broadcast_to(np.asarray(filter_hz, dtype=float), (n,))
        alpha = lowpass_gain(h[..., 0, :], f)[..., None, :]  # (.., 1, n): the gain of each joint's filter
        kp_part, kd_part = gain[..., :, :n], gain[..., :, n:]
        # v_k = (A/h) e_k - (A/h) e_{k-1} + (I - A) v_{k-1}: its rows in X_k's blocks
        v_rows = np.zeros((*gain.shape[:-2], n, 4 * n))
        v_rows[..., :, :n] = eye * alpha / h
        v_rows[..., :, 2 * n:3 * n] = -eye * alpha / h
        v_rows[..., :, 3 * n:4 * n] = eye * (1.0 - alpha)
        command = np.zeros((*gain.shape[:-2], n, 4 * n))
        command[..., :, :n] = kp_part
        command += kd_part @ v_rows
        a[..., 2 * n:3 * n, :n] = eye  # e_{k-1} of the next instant is e_k
        a[..., 3 * n:4 * n, :4 * n] = v_rows  # and v_{k-1} is v_k
    lead = (2 + extra) * n  # the state's part before the commands on their way
    if delay == 0:
        a[..., :2 * n, :lead] += bd @ command
        return a
    a[..., :2 * n, size - n:] = bd  # the oldest command is the one applied
    a[..., lead:lead + n, :lead] = command  # the command computed now waits
    for j in range(1, delay):  # and moves one slot older each period
        a[..., lead + j * n:lead + (j + 1) * n, lead + (j - 1) * n:lead + j * n] = eye
    return a


def spectral_radius(
    mass: FloatArray, kp: FloatArray, kd: FloatArray, h: float | FloatArray, delay: int = 0,
    filter_hz: FloatArray | None = None, damping: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Spectral radius of :func:`loop_matrix` (``filter_hz``: its velocity filter; ``damping``: the
    arm's viscous damping) and the joint dominating its mode.

    Works on one configuration (``mass``, ``kp``, ``kd`` of shape ``(n, n)``,
    scalar ``h``) or on a stack of them (leading axis ``m``, ``h`` scalar or of
    shape ``(m,)``); returns the radii and the 1-based joints, of the stack's shape.

    Raises
    ------
    InvalidInputError
        If the loop matrix is not finite (gains, inertia or period of infinite or NaN entries, or
        so large that the map overflows): there is no radius to give.
    """
    n = np.shape(mass)[-1]
    with np.errstate(over="ignore", invalid="ignore"):
        a = loop_matrix(mass, kp, kd, h, delay, filter_hz, damping)
    if not np.all(np.isfinite(a)):
        raise InvalidInputError("the loop matrix is not finite (gains, inertia or period infinite, NaN or so large "
                                "that it overflows): no stability to analyse")
    h = np.asarray(h, dtype=float)[..., None]
    values, vectors = np.linalg.eig(a)
    k = np.argmax(np.abs(values), axis=-1)
    radius = np.take_along_axis(np.abs(values), k[..., None], axis=-1)[..., 0]
    vec = np.take_along_axis(vectors, k[..., None, None], axis=-1)[..., 0]
    mode = np.abs(vec[..., :n]) + np.abs(vec[..., n:2 * n]) * h
    return radius, np.argmax(mode, axis=-1) + 1


LARGEST_ANALYSED = 1e150
"""Largest entry of ``Mbar^{-1} Kp_eff`` (s^-2) and ``Mbar^{-1} Kd_eff`` (s^-1) the analysis takes: the
loop map multiplies them by the period (up to 1 s in :func:`_lowest_rates`' search) and its
eigen-solver by each other, which overflows double precision near 1e308. No arm comes near it
(the shipped gains: below 1e6); beyond it, gains are refused, not judged."""


def analysable_gains(spec: LawRun, masses: FloatArray, kp: FloatArray, kd: FloatArray) -> None:
    """Refuse, naming the law's gains, effective gains the analysis cannot judge.

    ``kp``, ``kd``: the law's linear gains (:func:`effective_gains`) at the configurations whose
    inertia ``masses`` holds (stacked alike). Gains inside their declared bounds can still be so
    large (``--gain kp=1e308``) that ``Mbar^{-1} K`` overflows; numpy would then raise a
    ``LinAlgError`` deep in the eigen-solver.

    Raises
    ------
    InvalidInputError
        Naming the gains above 1e100 or below 1e-100 (all of the law's if none is) and what is allowed:
        ``Mbar^{-1} Kp_eff`` and ``Mbar^{-1} Kd_eff`` finite and at most :data:`LARGEST_ANALYSED`.
    """
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        finite = bool(np.all(np.isfinite(kp)) and np.all(np.isfinite(kd)))
        if finite:
            scaled = np.concatenate([np.linalg.solve(masses, kp), np.linalg.solve(masses, kd)], axis=-1)
            finite = bool(np.all(np.isfinite(scaled)) and np.max(np.abs(scaled)) <= LARGEST_ANALYSED)
    if finite:
        return
    gains = spec.gains.as_dict()
    huge = [name for name, values in gains.items()  # the absurd ones: beyond 1e100, or a divisor below 1e-100
            if np.max(np.abs(values)) > 1e100 or 0.0 < np.min(np.abs(values)) < 1e-100] or list(gains)
    named = ", ".join(f"{name}={gains[name]}" for name in huge)
    raise InvalidInputError(
        f"{spec.controller} gains for {spec.robot}: {named} too large to analyse (the effective stiffness and "
        f"damping over the arm's inertia must be finite and at most {LARGEST_ANALYSED:g} s^-2 and s^-1; no arm "
        f"needs gains near it); give finite, realistic gains")


def _lowest_rates(mass: FloatArray, kp: FloatArray, kd: FloatArray, delay: int,
                  filter_hz: FloatArray | None = None, damping: FloatArray | None = None) -> FloatArray:
    """Lowest stable rate (Hz) of each configuration of a stack, by bisection (the loop is
    stable above it: a faster loop is closer to the continuous one, stable for positive gains)."""
    m = mass.shape[0]
    lo = np.full(m, 1.0)  # Hz
    hi = np.full(m, 1e8)  # stable at 1e8 Hz for any positive gains
    stable_at_lo = spectral_radius(mass, kp, kd, 1.0 / lo, delay, filter_hz, damping)[0] < 1.0
    for _ in range(24):  # bracket ratio 1e8 -> about 0.1 % resolution
        mid = np.sqrt(lo * hi)
        stable = spectral_radius(mass, kp, kd, 1.0 / mid, delay, filter_hz, damping)[0] < 1.0
        hi = np.where(stable, mid, hi)
        lo = np.where(stable, lo, mid)
    return np.where(stable_at_lo, 1.0, hi)


RK4_REAL_LIMIT = 2.785293563405282
"""Largest ``|z|`` on the negative real axis where classical RK4 is stable (``|R(z)| = 1`` with
``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``): the plant's free damping ``-Mbar^{-1} B`` integrated
with step ``h`` diverges beyond ``lambda h = 2.785``."""
DAMPING_STEP_MARGIN = 2.0
"""The plant step's margin: ``damping / inertia x period`` at most RK4's limit over this (the
x2 of the real-time rate check)."""


@dataclass(frozen=True)
class PlantStep:
    """Whether the plant's explicit integration (RK4 at the control period) holds its damping.

    ``figure`` is the largest eigenvalue of ``Mbar^{-1} B`` times the period along the motion
    (for one decoupled joint, its damping over its inertia times the period), ``joint`` the joint
    dominating that mode. ``armature`` gives, for each joint that needs more, the motor inertia
    ``J`` (kg m^2, in place of the arm's) and ``rate`` the control rate (Hz) that would bring the
    figure to :data:`RK4_REAL_LIMIT` / :data:`DAMPING_STEP_MARGIN` (each rounded up).
    """

    figure: float
    joint: str
    armature: tuple[tuple[str, float], ...]
    rate: float

    @property
    def limit(self) -> float:
        return RK4_REAL_LIMIT / DAMPING_STEP_MARGIN

    @property
    def holds(self) -> bool:
        return self.figure <= self.limit

    def problem(self, entry: str = "cli") -> str:
        """One line: the joint, the figure and the fixes (armature, rate)."""
        rate = f"-p rate:={self.rate:.1f}" if entry == "node" else f"--rate {self.rate:g}"
        armature = ", ".join(f"{value:.3g} kg m^2 for {name!r}" for name, value in self.armature)
        return (f"joint {self.joint!r}: damping/inertia x period = {self.figure:.3g} > {self.limit:.3g} (RK4, the "
                f"plant's integrator, diverges beyond {RK4_REAL_LIMIT:.3g} whatever the gains; "
                f"x{DAMPING_STEP_MARGIN:g} required); give the motors' inertia, armature >= {armature} (the "
                f"arm's options file beside its URDF: armature, one value per joint), or run at {rate} or higher")


def _damping_figures(mass: FloatArray, damping: FloatArray, h: float) -> tuple[FloatArray, FloatArray]:
    """Largest eigenvalue of ``Mbar^{-1} B`` times ``h`` per configuration and its dominant joint (0-based)."""
    root = np.sqrt(damping)  # B diagonal, >= 0: the eigenvalues of B^1/2 Mbar^-1 B^1/2, symmetric
    sym = root[:, None] * np.linalg.inv(mass) * root[None, :]
    values, vectors = np.linalg.eigh(sym)
    # w = B^1/2 v: w_i^2 is joint i's share of the mode's dissipation
    return values[..., -1] * h, np.argmax(np.abs(vectors[..., :, -1]), axis=-1)


def plant_step(robot: Manipulator, q: FloatArray, rate: float) -> PlantStep:
    """:class:`PlantStep` of ``robot`` over the configurations ``q`` (``(m, n)``) at ``rate`` Hz."""
    damping = np.asarray(robot.B, dtype=float)
    mass = robot._mass_matrix(np.asarray(q, dtype=float))
    names = tuple(robot.joint_names) or tuple(f"joint{i + 1}" for i in range(robot.n))
    h = 1.0 / rate
    figures, joints = _damping_figures(mass, damping, h)
    worst = int(np.argmax(figures))
    figure, joint = float(figures[worst]), int(joints[worst])
    target = RK4_REAL_LIMIT / DAMPING_STEP_MARGIN
    if figure <= target:
        return PlantStep(figure, names[joint], (), rate)
    added = np.zeros(robot.n)  # motor inertia added, joint by joint, until every configuration holds
    for _ in range(200):
        figures, dominant = _damping_figures(mass + np.diag(added), damping, h)
        k = int(np.argmax(figures))
        if figures[k] <= target * (1.0 + 1e-9):
            break
        j = int(dominant[k])
        apparent = 1.0 / np.linalg.inv(mass[k] + np.diag(added))[j, j]  # the inertia joint j sees
        added[j] += max(damping[j] * h / target - apparent, 1e-3 * apparent)
    needs = [int(j) for j in np.argsort(-added) if added[j] > 0.0]  # the most first
    return PlantStep(figure, names[joint], tuple((names[j], _round_up(float(robot.J[j] + added[j]))) for j in needs),
                     _round_up(rate * figure / target))


def _round_up(value: float) -> float:
    """``value`` rounded up to three significant digits (a fix printed that way still holds)."""
    step = 10.0 ** (np.floor(np.log10(value)) - 2)
    return float(np.ceil(value / step * (1.0 - 1e-12)) * step)


def tolerated_delay(spec: LawRun, reference: JointReference, *, points: int = 13, most: int = 1000,
                    filter_hz: FloatArray | None = None, friction_viscous: FloatArray | None = None) -> int | None:
    """The largest whole delay (periods) at ``spec.rate`` with which the loop stays stable at every
    one of ``points`` configurations (``filter_hz``: with the velocity differenced and filtered,
    :func:`loop_matrix`; ``friction_viscous``: with the arm's damping, :func:`arm_damping`): None for a
    law without linear gains, -1 if unstable even without delay, ``most`` if stable up to it (the
    search stops there)."""
    robot = spec.robot_model()
    damping = arm_damping(robot, friction_viscous)
    sample = reference.sample(np.linspace(0.0, reference.duration, points))
    masses = robot._mass_matrix(sample.q)
    with np.errstate(over="ignore", invalid="ignore"):  # overflows: refused by analysable_gains
        linear = [effective_gains(spec, mass, qd, qdd) for mass, qd, qdd in zip(masses, sample.qd, sample.qdd,
                                                                                  strict=True)]
    if any(pair is None for pair in linear):
        return None
    kp = np.stack([p[0] for p in linear])  # type: ignore[index]
    kd = np.stack([p[1] for p in linear])  # type: ignore[index]
    analysable_gains(spec, masses, kp, kd)

    def stable(d: int) -> bool:
        return bool(np.all(spectral_radius(masses, kp, kd, 1.0 / spec.rate, d, filter_hz, damping)[0] < 1.0))

    if not stable(0):
        return -1
    lo, hi = 0, 1
    while hi <= most and stable(hi):  # the radius grows with the delay: bracket, then bisect
        lo, hi = hi, 2 * hi
    if hi > most:
        return most
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


MODES = ("lockstep", "realtime")
"""How the loop runs (the nodes' ``mode`` parameter)."""
REALTIME_DELAY_PERIODS = 2
"""Periods between the state a real-time command is computed from and the period the plant
applies it in, the delay model of this project's real-time loop (the plant, the MuJoCo
stand-in or a driver, and the controller tick on their own clocks):

* the controller's sampling: the state published at the plant's tick waits for the
  controller's next tick, up to one period (none when the controller ticks right after it);
* computation and DDS transport: tens of microseconds (bench/realtime.py: p50 lateness
  1-3 us, p99 14-90 us at 1 kHz), inside the same period unless the two clocks' phases
  nearly coincide -- then the command misses the plant's next tick;
* the plant's sampling: the command is applied from the plant's next tick, one period.

So one period when the phases are apart, two when they nearly coincide or a tick is late:
two, the worst case. Stalls come on top: bench/realtime.py measures here (1 kHz, five-bar,
quiet machine) a worst period of 6.3 ms (5.3 ms late) with four processes and 3.9 ms composed,
0.06-0.3 % missed deadlines; docs/PERFORMANCE.md has worst periods of 1.4-4.5 ms under load,
cyclictest's wake-ups up to 3.5 ms. Those are single stretched periods, not a delay every
period, and :data:`REQUIRED_MARGIN`'s x2 covers them: gains stable at half the rate with two
periods of delay stay stable at the rate with a constant delay of four to five periods (the
UR5's and the Panda's shipped gains: 4-5 ms at 1 kHz, against 2-3 ms for the gains tuned for
one period, which burst after goal ends), a persistent stall of 2-3 ms on top of the two
periods, the worst single stalls measured here (3.9-6.3 ms periods) only once in hundreds of
periods. :func:`tolerated_delay` gives the figure of any gains (``pdsmc check-gains`` prints it).
Lockstep has no delay: the plant waits for the command of its state."""
MODE_DELAY = {"lockstep": 0, "realtime": REALTIME_DELAY_PERIODS}
"""Periods of delay each mode's loop has (:data:`REALTIME_DELAY_PERIODS`)."""
REQUIRED_MARGIN = {"lockstep": 1.0, "realtime": 2.0}
"""Default ``rate / lowest stable rate`` each mode requires. Real time: x2, for what the
model leaves out: stalls that stretch single periods (:data:`REALTIME_DELAY_PERIODS`),
damping, Coriolis and a drifting inertia that change the poles -- the UR5's gains tuned
for x2 with one period of delay, x1.2 with two, oscillated after goals ended and burst to
4.5 rad/s at 1 kHz. Lockstep: stable (x1): its delay is exactly zero and the held input
exactly what the plant integrates, so the map is exact up to the terms the linearisation
leaves out; the thesis's presets run there at x1.11 (serial circle, PD-SMC) to x2.95 at the
serial arm's 10 kHz and x10.7 and up on the five-bar at 5 kHz, and must keep running
unchanged."""


def loop_delay(mode: str, delay_periods: int = 0) -> int:
    """Periods of delay the check models: the mode's own plus ``delay_periods`` declared."""
    if mode not in MODE_DELAY:
        raise InvalidInputError(f"unknown mode {mode!r}; choose one of: {', '.join(MODES)}")
    if not is_whole(delay_periods) or delay_periods < 0:
        raise InvalidInputError(f"delay_periods must be a whole number >= 0, got {delay_periods!r}")
    return MODE_DELAY[mode] + int(delay_periods)


@dataclass(frozen=True)
class RateCheck:
    """Result of :func:`rate_margin`."""

    rate: float
    lowest_stable_rate: float
    spectral_radius: float
    worst_joint: int  # 1-based
    stable: bool
    mode: str = "lockstep"
    delay: int = 0  # periods modelled
    required_margin: float = 1.0
    plant: PlantStep | None = None  # the plant's integration of its damping (None: not checked)
    joint_names: tuple[str, ...] = ()
    filter_hz: tuple[float, ...] | None = None  # the velocity's filter modelled (None: the exact velocity)
    damping: tuple[float, ...] | None = None  # the arm's viscous damping modelled, N m s/rad (None: left out)

    @property
    def worst_joint_label(self) -> str:
        """``joint 3 ('elbow_joint')``: the worst joint by number and name."""
        if 1 <= self.worst_joint <= len(self.joint_names):
            return f"joint {self.worst_joint} ({self.joint_names[self.worst_joint - 1]!r})"
        return f"joint {self.worst_joint}"

    @property
    def margin(self) -> float:
        """``rate / lowest stable rate`` (inf for a law without linear gains)."""
        if not np.isfinite(self.lowest_stable_rate):
            return float("inf")
        return self.rate / self.lowest_stable_rate

    @property
    def passes(self) -> bool:
        """Stable, with at least the required margin, on a plant whose integration holds its damping."""
        return self.stable and self.margin >= self.required_margin and (self.plant is None or self.plant.holds)


def rate_margin(spec: LawRun, reference: JointReference, *, points: int = 13, mode: str = "lockstep",
                delay_periods: int = 0, margin: float | None = None,
                filter_hz: FloatArray | None = None, friction_viscous: FloatArray | None = None) -> RateCheck:
    """Lowest stable rate over the motion and the radius at ``spec.rate``, for the loop of ``mode``
    with ``delay_periods`` more periods of delay (:func:`loop_delay`); ``margin`` is the required
    margin (default :data:`REQUIRED_MARGIN` of the mode); ``filter_hz``: the law sees the velocity
    differenced and low-pass filtered at these cut-offs (Hz per joint, 0: unfiltered), as a drive
    estimates it (:func:`loop_matrix`), instead of the exact one; ``friction_viscous``: the arm's
    viscous friction beyond its description's damping, both in the plant (:func:`arm_damping`).

    Raises
    ------
    InvalidInputError
        An unknown mode, a negative delay or margin, a cut-off or a friction that is negative, not finite
        or not one per joint.
    """
    delay = loop_delay(mode, delay_periods)
    required = REQUIRED_MARGIN[mode] if margin is None else float(margin)
    if not np.isfinite(required) or required <= 0.0:
        raise InvalidInputError(f"margin must be a positive number, got {margin!r}")
    robot = spec.robot_model()
    cutoffs = velocity_filter(filter_hz, robot.n)
    damping = arm_damping(robot, friction_viscous)
    modelled = None if damping is None else tuple(damping.tolist())
    t = np.linspace(0.0, reference.duration, points)
    sample = reference.sample(t)
    q = sample.q
    masses = robot._mass_matrix(q)
    plant = plant_step(robot, q, spec.rate)
    names = tuple(robot.joint_names)
    with np.errstate(over="ignore", invalid="ignore"):  # overflows: refused by analysable_gains
        linear = [effective_gains(spec, mass, qd, qdd) for mass, qd, qdd in zip(masses, sample.qd, sample.qdd,
                                                                                  strict=True)]
    pairs = [pair for pair in linear if pair is not None]
    if len(pairs) < len(linear):  # a law without linear gains: not checked
        return RateCheck(spec.rate, float("nan"), float("nan"), 0, True, mode, delay, required, plant, names,
                         None if cutoffs is None else tuple(cutoffs.tolist()), modelled)
    kp = np.stack([p[0] for p in pairs])
    kd = np.stack([p[1] for p in pairs])
    analysable_gains(spec, masses, kp, kd)
    lowest = float(np.max(_lowest_rates(masses, kp, kd, delay, cutoffs, damping)))
    radii, joints = spectral_radius(masses, kp, kd, 1.0 / spec.rate, delay, cutoffs, damping)
    worst = int(np.argmax(radii))
    radius = float(radii[worst])
    return RateCheck(spec.rate, lowest, radius, int(joints[worst]), radius < 1.0, mode, delay, required, plant, names,
                     None if cutoffs is None else tuple(cutoffs.tolist()), modelled)


def velocity_filter(filter_hz: FloatArray | None, n: int) -> FloatArray | None:
    """The velocity filter's cut-offs, one per joint (one value stands for all), checked; None: none.

    Raises
    ------
    InvalidInputError
        A cut-off that is negative or not finite, or a count other than 1 or ``n``.
    """
    if filter_hz is None:
        return None
    f = np.atleast_1d(np.asarray(filter_hz, dtype=float))
    if f.ndim != 1 or f.size not in (1, n) or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise InvalidInputError(f"velocity filter cut-offs must be 1 or {n} finite numbers >= 0 (Hz; 0: the "
                                f"difference unfiltered), got {np.asarray(filter_hz).tolist()!r}")
    return np.broadcast_to(f, (n,)).copy()


def arm_damping(robot: Manipulator, friction_viscous: FloatArray | None) -> FloatArray | None:
    """The viscous damping the check gives the plant: the description's ``B`` plus ``friction_viscous``
    (N m s/rad, one per joint or one for all: the stand-in's, added to the description's as the
    stand-in adds it); None (``friction_viscous`` None): left out.

    Raises
    ------
    InvalidInputError
        A friction that is negative or not finite, or a count other than 1 or ``n``.
    """
    if friction_viscous is None:
        return None
    f = np.atleast_1d(np.asarray(friction_viscous, dtype=float))
    if f.ndim != 1 or f.size not in (1, robot.n) or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise InvalidInputError(f"viscous friction must be 1 or {robot.n} finite numbers >= 0 (N m s/rad), got "
                                f"{np.asarray(friction_viscous).tolist()!r}")
    damping: FloatArray = np.asarray(robot.B, dtype=float) + np.broadcast_to(f, (robot.n,))
    return damping


ENTRY_POINTS = ("cli", "node")
"""How an error names the settings: the ``pdsmc`` command's flags or a node's parameters."""


def describe_loop(check: RateCheck) -> str:
    """``lockstep (zero-order hold)`` / ``realtime (zero-order hold + 2 periods of delay)``, and the
    velocity filter when one is modelled (``+ velocity differenced, filtered at 100 Hz``)."""
    parts = ["zero-order hold"]
    if check.delay:
        parts.append(f"{check.delay} period{'s' if check.delay > 1 else ''} of delay")
    if check.filter_hz is not None:
        f = check.filter_hz
        shown = f"{f[0]:g}" if all(x == f[0] for x in f) else ", ".join(f"{x:g}" for x in f)
        parts.append("velocity differenced" + (f", filtered at {shown} Hz" if any(f) else ""))
    if check.damping is not None:
        parts.append("the arm's viscous damping [" + ", ".join(f"{b:.3g}" for b in check.damping) + "] N m s/rad")
    return f"{check.mode} ({' + '.join(parts)})"


def check_rate(spec: LawRun, reference: JointReference, *, mode: str = "lockstep", delay_periods: int = 0,
               margin: float | None = None, entry: str = "cli", filter_hz: FloatArray | None = None) -> RateCheck:
    """Refuse gains that are not stable, with the required margin, at ``spec.rate`` in ``mode``.

    Parameters
    ----------
    mode : str
        ``lockstep`` or ``realtime`` (:data:`MODE_DELAY`).
    delay_periods : int
        Periods of delay beyond the mode's own (a driver's or a network's).
    margin : float, optional
        Required ``rate / lowest stable rate``; :data:`REQUIRED_MARGIN` of the mode by default.
    entry : str
        ``cli`` or ``node``: the error advises ``--rate 1500`` or ``-p rate:=1500.0``.
    filter_hz : array_like, optional
        The velocity filter's cut-offs (:func:`rate_margin`); None: the exact velocity.

    Raises
    ------
    UnstableRateError
        Naming the joint that dominates the slowest-to-settle mode, the lowest stable rate, the
        margin and the rate that would give the required margin, as the entry point spells it.
    """
    if entry not in ENTRY_POINTS:
        raise InvalidInputError(f"entry must be one of {ENTRY_POINTS}, got {entry!r}")
    result = rate_margin(spec, reference, mode=mode, delay_periods=delay_periods, margin=margin, filter_hz=filter_hz)
    if result.passes:
        return result
    if result.plant is not None and not result.plant.holds:
        raise UnstableRateError(f"{spec.robot} at {spec.rate:g} Hz: {result.plant.problem(entry)}")
    needed = max(1.2, result.required_margin * 1.05) * result.lowest_stable_rate
    suggestion = float(np.ceil(needed / spec.sample_rate) * spec.sample_rate)
    if entry == "node":
        rate_advice, margin_name = f"-p rate:={suggestion:.1f}", "-p stability_margin:=N "
    else:
        rate_advice, margin_name = f"--rate {suggestion:g}", "--margin "
    if result.stable:
        problem = (f"margin only x{result.margin:.2f} in {describe_loop(result)} (lowest stable rate about "
                   f"{result.lowest_stable_rate:,.0f} Hz, {result.worst_joint_label} the closest to the edge; "
                   f"x{result.required_margin:g} required, {margin_name}sets it)")
    else:
        problem = (f"{result.worst_joint_label} diverges in {describe_loop(result)} (discrete pole radius "
                   f"{result.spectral_radius:.3f} > 1); the lowest stable rate is about "
                   f"{result.lowest_stable_rate:,.0f} Hz")
    raise UnstableRateError(
        f"{spec.controller} gains for {spec.robot}/{spec.contour} at {spec.rate:g} Hz: {problem}; "
        f"use {rate_advice} or higher, or gentler gains"
    )


THEOREM_LAWS = ("pdsmc",)
"""Laws whose gains Eq. (3.19) constrains (the PD-SMC theorem of Section 3.5); the PD and the
SMC have no conditions of it."""


@dataclass(frozen=True)
class GainCheck:
    """What ``pdsmc check-gains`` decides: the law's Eq. (3.19) conditions and the rate condition."""

    conditions: tuple[Condition, ...]
    rate: RateCheck

    @property
    def passes(self) -> bool:
        return self.rate.passes and all(c.holds for c in self.conditions)

    def failure(self) -> str:
        """Why it does not pass (the first reason), or ``''``."""
        if self.rate.plant is not None and not self.rate.plant.holds:
            return self.rate.plant.problem()
        for c in self.conditions:
            if not c.holds:
                return f"Eq. 3.19 fails: {c.name} ({c.lhs:.5g} <= {c.rhs:.5g})"
        if not self.rate.stable:
            return f"unstable at {self.rate.rate:g} Hz in {describe_loop(self.rate)}"
        if not self.rate.passes:
            return (f"margin x{self.rate.margin:.2f} < x{self.rate.required_margin:g} in "
                    f"{describe_loop(self.rate)}")
        return ""


def check_gains(spec: LawRun, reference: JointReference | None = None, *, mode: str = "realtime",
                delay_periods: int = 0, margin: float | None = None, points: int = 401,
                filter_hz: FloatArray | None = None, friction_viscous: FloatArray | None = None) -> GainCheck:
    """Eq. (3.19) where the law has it (:data:`THEOREM_LAWS`) and :func:`rate_margin` in ``mode``
    (``filter_hz``: with the velocity a drive differences and filters, :func:`loop_matrix`;
    ``friction_viscous``: with the arm's viscous damping, :func:`arm_damping`).

    The default mode is the real-time loop's (:data:`REALTIME_DELAY_PERIODS`): gains that pass it
    run on a robot, and pass in lockstep too (no delay, a lower required margin).
    """
    rate = rate_margin(spec, reference or spec.reference(), mode=mode, delay_periods=delay_periods, margin=margin,
                       filter_hz=filter_hz, friction_viscous=friction_viscous)
    conditions = tuple(theorem_conditions(spec, points=points)) if spec.controller in THEOREM_LAWS else ()
    return GainCheck(conditions, rate)
