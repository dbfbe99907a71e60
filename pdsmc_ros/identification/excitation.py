"""An exciting trajectory: a finite Fourier series per joint, optimised for the identification.

Swevers, Ganseman, Tukel, De Schutter & Van Brussel, "Optimal robot excitation and identification",
IEEE T-RA 13(5), 1997: each joint follows

    q_i(t) = q0_i + sum_{l=1..N} a_il / (w l) sin(w l t) - b_il / (w l) cos(w l t),   w = 2 pi / T,

periodic with period ``T`` and band-limited to ``N / T`` Hz (what the identification's filter
keeps: :mod:`.signals`). The coefficients are chosen so that the base regressor
(:mod:`.base`) of the motion is as well conditioned as possible, within the arm's limits.

Here the series starts and ends at rest at the arm's home: ``qd(0) = sum_l a_il = 0`` and
``qdd(0) = w sum_l l b_il = 0`` are linear in the coefficients, so the free coefficients are
those of the null space of the two (:class:`RestBasis`), and ``q0`` puts ``q(0)`` at home. The
motion ``q - home`` is then linear and homogeneous in the free coefficients: scaling them scales
every position excursion, velocity and acceleration alike. Each candidate of the search is
therefore scaled to the largest amplitude within the limits (:func:`largest_scale`: positions,
velocities, accelerations exactly; efforts under the arm's own model by bisection), and the
search over the directions alone is unconstrained: every trajectory it returns is within the
limits. The objective is the base regressor's 2-norm condition number on one period, minimised
from a few seeded random starts by L-BFGS (finite-difference gradients).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots.base import FloatArray
from .base import BaseParameters
from .model import ArmDynamics

__all__ = ["ExcitationLimits", "ExcitationResult", "FourierExcitation", "RestBasis", "condition_number",
           "excitation_limits", "largest_scale", "optimise_excitation"]

OBJECTIVE_SAMPLES = 100
"""Samples of one period the objective's regressor is built from (20 per cycle of the highest
harmonic at the default five)."""
CHECK_SAMPLES = 4000
"""Samples of one period the limits are checked on, for the search's result."""
CHECK_MARGIN = 1e-3
"""The result's amplitude stays this share below the limits met on the fine grid: between two of
its 4,000 samples a band-limited motion overshoots by about ``(pi N / 4000)^2 / 2`` of its
amplitude (2e-5 at five harmonics)."""
BISECTION_STEPS = 30
"""Halvings of the scale interval when the effort limits bind (2^-30 of it)."""


@dataclass(frozen=True)
class FourierExcitation:
    """A finite Fourier series per joint (module docstring), at rest at ``home`` at ``t = 0`` and
    at every multiple of ``period``.

    Attributes
    ----------
    home : ndarray, shape (n,)
    a, b : ndarray, shape (n, N)
        Velocity amplitudes (rad/s) of the cosine and sine terms of each harmonic.
    period : float
        Seconds: the fundamental is ``1 / period`` Hz.
    """

    home: FloatArray
    a: FloatArray
    b: FloatArray
    period: float

    @property
    def harmonics(self) -> int:
        return int(self.a.shape[1])

    @property
    def bandwidth(self) -> float:
        """The highest harmonic's frequency (Hz): the motion has nothing above it."""
        return self.harmonics / self.period

    @property
    def omega(self) -> float:
        return 2.0 * np.pi / self.period

    def sample(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(q, qd, qdd)`` at times ``t`` (each ``(k, n)``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w = self.omega * np.arange(1, self.harmonics + 1)  # (N,)
        phase = np.outer(t, w)  # (k, N)
        sin, cos = np.sin(phase), np.cos(phase)
        offset = self.home + (self.b / w) @ np.ones(self.harmonics)  # q(0) = home
        q = offset + sin @ (self.a / w).T - cos @ (self.b / w).T
        qd = cos @ self.a.T + sin @ self.b.T
        qdd = -sin @ (self.a * w).T + cos @ (self.b * w).T
        return q, qd, qdd

    def scaled(self, factor: float) -> FourierExcitation:
        return FourierExcitation(self.home, self.a * factor, self.b * factor, self.period)


class RestBasis:
    """The free coefficients of series at rest at ``t = 0``: ``a = A x_a``, ``b = B x_b`` per joint,
    ``A`` and ``B`` orthonormal bases of the null spaces of ``sum_l a_l = 0`` and ``sum_l l b_l = 0``."""

    def __init__(self, n: int, harmonics: int) -> None:
        if harmonics < 2:
            raise InvalidInputError(f"harmonics must be >= 2 (rest at both ends needs two), got {harmonics}")
        self.n = n
        self.harmonics = harmonics
        self.for_a = scipy.linalg.null_space(np.ones((1, harmonics)))
        self.for_b = scipy.linalg.null_space(np.arange(1, harmonics + 1, dtype=float)[None, :])
        self.per_joint = 2 * (harmonics - 1)

    @property
    def size(self) -> int:
        return self.n * self.per_joint

    def coefficients(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        x = np.reshape(x, (self.n, self.per_joint))
        half = self.harmonics - 1
        return x[:, :half] @ self.for_a.T, x[:, half:] @ self.for_b.T


@dataclass(frozen=True)
class ExcitationLimits:
    """What an excitation must stay within, per joint.

    Attributes
    ----------
    lower, upper : ndarray
        Position bounds (rad or m): the joint limits less a margin, and within the allowed
        excursion from home.
    velocity, acceleration, effort : ndarray
        Largest magnitudes (rad/s, rad/s^2, N m); effort under the arm's own model.
    """

    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    effort: FloatArray


def excitation_limits(dynamics: ArmDynamics, *, excursion: ArrayLike, acceleration: ArrayLike | None = None,
                      share: float = 0.8, margin: float = 0.05) -> ExcitationLimits:
    """The limits an excitation of ``dynamics``' arm keeps to.

    Parameters
    ----------
    excursion : array_like
        Largest distance from home per joint (rad or m; one for all): the arm's own links and
        its surroundings are not checked for collisions, so the motion stays near home.
    acceleration : array_like, optional
        Largest acceleration per joint; by default the velocity limit reached in half a second
        (URDF gives no acceleration limit).
    share : float
        The share of the velocity, acceleration and effort limits used (0 < share <= 1): the
        rest is the controller's, for the errors it corrects.
    margin : float
        Distance kept from each position limit (rad or m).

    Raises
    ------
    InvalidInputError
        A share outside (0, 1], a negative margin or excursion, an acceleration <= 0, or an
        arm without finite velocity or effort limits for a joint.
    """
    arm = dynamics.arm
    names = arm.joint_names
    if not (0.0 < share <= 1.0):
        raise InvalidInputError(f"share of the limits must be in (0, 1], got {share!r}")
    if not (np.isfinite(margin) and margin >= 0.0):
        raise InvalidInputError(f"position margin must be >= 0, got {margin!r}")
    reach = np.broadcast_to(np.asarray(excursion, dtype=float), (arm.n,)).copy()
    if np.any(~np.isfinite(reach) | (reach <= 0.0)):
        raise InvalidInputError(f"excursion from home must be > 0 per joint, got {np.asarray(excursion).tolist()}")
    for label, values in (("velocity", arm.velocity_limits), ("effort", arm.effort_limits)):
        if not np.all(np.isfinite(values)):
            bad = int(np.argmin(np.isfinite(values)))
            raise InvalidInputError(f"joint {names[bad]!r} has no finite {label} limit (URDF <limit {label}=> or the "
                                    f"options' {label}_limits): an excitation needs one")
    velocity = share * np.asarray(arm.velocity_limits, dtype=float)
    if acceleration is None:
        accel = 2.0 * np.asarray(arm.velocity_limits, dtype=float)
    else:
        accel = np.broadcast_to(np.asarray(acceleration, dtype=float), (arm.n,)).copy()
        if np.any(~np.isfinite(accel) | (accel <= 0.0)):
            raise InvalidInputError(f"acceleration limits must be > 0 per joint, got "
                                    f"{np.asarray(acceleration).tolist()}")
    home = np.asarray(arm.home, dtype=float)
    lower = np.maximum(arm.position_limits[:, 0] + margin, home - reach)
    upper = np.minimum(arm.position_limits[:, 1] - margin, home + reach)
    return ExcitationLimits(lower, upper, velocity, share * accel, share * np.asarray(arm.effort_limits, dtype=float))


def linear_scale(excitation: FourierExcitation, limits: ExcitationLimits, t: FloatArray) -> float:
    """The largest factor of the coefficients keeping positions, velocities and accelerations within
    ``limits`` at times ``t`` (all three are linear and homogeneous in them)."""
    q, qd, qdd = excitation.sample(t)
    dq = q - excitation.home
    with np.errstate(divide="ignore", invalid="ignore"):
        room_up = np.where(dq > 0.0, (limits.upper - excitation.home) / dq, np.inf)
        room_down = np.where(dq < 0.0, (limits.lower - excitation.home) / dq, np.inf)
        ratios = [room_up, room_down, limits.velocity / np.abs(qd), limits.acceleration / np.abs(qdd)]
    return float(min(np.min(np.nan_to_num(r, nan=np.inf)) for r in ratios))


def largest_scale(excitation: FourierExcitation, limits: ExcitationLimits, dynamics: ArmDynamics,
                  t: FloatArray) -> float:
    """The largest factor of the coefficients within every limit at times ``t``: exact for the
    positions, velocities and accelerations, then halved intervals until the arm's own model's
    efforts (:attr:`ArmDynamics.nominal`) are within theirs too."""
    top = linear_scale(excitation, limits, t)
    if not np.isfinite(top) or top <= 0.0:
        return 0.0

    def efforts_fit(factor: float) -> bool:
        q, qd, qdd = excitation.scaled(factor).sample(t)
        return bool(np.all(np.abs(dynamics.torque(dynamics.nominal, q, qd, qdd)) <= limits.effort))

    if efforts_fit(top):
        return top
    if not efforts_fit(0.0):
        return 0.0  # the arm cannot even hold home within the effort limits
    low, high = 0.0, top
    for _ in range(BISECTION_STEPS):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if efforts_fit(middle) else (low, middle)
    return low


@dataclass(frozen=True)
class ExcitationResult:
    """What :func:`optimise_excitation` found.

    Attributes
    ----------
    excitation : FourierExcitation
    condition : float
        The base regressor's 2-norm condition number on one period (:data:`OBJECTIVE_SAMPLES`).
    start_condition : float
        The best random start's, before the search.
    peak : dict
        The largest |position excursion|, |velocity|, |acceleration|, |effort| per joint over a
        period (:data:`CHECK_SAMPLES`), and each as a share of its limit (``*_share``).
    evaluations : int
    seconds : float
    """

    excitation: FourierExcitation
    condition: float
    start_condition: float
    peak: dict[str, FloatArray]
    evaluations: int
    seconds: float


def condition_number(dynamics: ArmDynamics, base: BaseParameters, excitation: FourierExcitation,
                     samples: int = OBJECTIVE_SAMPLES) -> float:
    """The base regressor's 2-norm condition number over one period of ``excitation``."""
    t = np.arange(samples) * excitation.period / samples
    singular = np.linalg.svd(base.columns(dynamics.regressor(*excitation.sample(t))), compute_uv=False)
    return float(singular[0] / singular[-1]) if singular[-1] > 0.0 else float("inf")


def optimise_excitation(dynamics: ArmDynamics, base: BaseParameters, limits: ExcitationLimits, *,
                        period: float, harmonics: int, starts: int = 3, iterations: int = 40, seed: int = 0,
                        progress: Callable[[str], None] | None = None) -> ExcitationResult:
    """The Fourier excitation of best-conditioned base regressor within ``limits`` (module docstring).

    Parameters
    ----------
    period : float
        Seconds of one period (the fundamental ``1 / period`` Hz).
    harmonics : int
        ``N`` (>= 2): the motion's bandwidth is ``N / period`` Hz.
    starts : int
        Random starting directions searched from (the best result is kept).
    iterations : int
        L-BFGS iterations from each start.
    seed : int
        Seed of the random starts: the same seed gives the same excitation.

    Raises
    ------
    InvalidInputError
        If no motion fits the limits (home outside them, or the arm cannot hold it).
    """
    began = time.perf_counter()
    n = dynamics.n
    home = np.asarray(dynamics.arm.home, dtype=float)
    if np.any(home < limits.lower) or np.any(home > limits.upper):
        bad = int(np.argmax((home < limits.lower) | (home > limits.upper)))
        raise InvalidInputError(f"home of joint {dynamics.layout.joint_names[bad]!r} ({home[bad]:.4g}) is outside the "
                                f"excitation's position bounds [{limits.lower[bad]:.4g}, {limits.upper[bad]:.4g}]")
    basis = RestBasis(n, harmonics)
    t_objective = np.arange(OBJECTIVE_SAMPLES) * period / OBJECTIVE_SAMPLES
    count = 0

    def series(x: FloatArray) -> FourierExcitation:
        a, b = basis.coefficients(x)
        return FourierExcitation(home, a, b, period)

    def fitted(x: FloatArray) -> FourierExcitation:
        shape = series(x)
        return shape.scaled(largest_scale(shape, limits, dynamics, t_objective))

    def objective(x: FloatArray) -> float:
        nonlocal count
        count += 1
        if not np.any(x):
            return 1e6
        value = condition_number(dynamics, base, fitted(x))
        return float(np.log(value)) if np.isfinite(value) else 1e6

    rng = np.random.default_rng(seed)
    best_x, best_value, start_value = None, np.inf, np.inf
    for start in range(starts):
        x0 = rng.normal(size=basis.size)
        first = objective(x0)
        start_value = min(start_value, first)
        found = scipy.optimize.minimize(objective, x0, method="L-BFGS-B",
                                        options={"maxiter": iterations, "eps": 1e-4})
        value = float(found.fun) if found.fun < first else first
        x = found.x if found.fun < first else x0
        if progress:
            progress(f"start {start + 1}/{starts}: condition number {np.exp(first):.4g} -> {np.exp(value):.4g}")
        if value < best_value:
            best_x, best_value = x, value
    if best_x is None or best_value >= np.log(1e6):
        raise InvalidInputError("no excitation fits the limits: the arm cannot move from home within them "
                                "(check home, --range and the effort limits)")
    excitation = fitted(best_x)
    # the limits on a fine grid: the search saw 100 samples a period; shrink by what it missed, and
    # by CHECK_MARGIN for what lies between the fine grid's samples
    t_check = np.arange(CHECK_SAMPLES) * period / CHECK_SAMPLES
    fits = min(1.0, largest_scale(excitation, limits, dynamics, t_check))
    excitation = excitation.scaled(fits * (1.0 - CHECK_MARGIN))
    condition = condition_number(dynamics, base, excitation)
    q, qd, qdd = excitation.sample(t_check)
    effort = np.abs(dynamics.torque(dynamics.nominal, q, qd, qdd)).max(axis=0)
    excursion = np.abs(q - home).max(axis=0)
    peak = {"excursion": excursion, "velocity": np.abs(qd).max(axis=0), "acceleration": np.abs(qdd).max(axis=0),
            "effort": effort, "velocity_share": np.abs(qd).max(axis=0) / limits.velocity,
            "acceleration_share": np.abs(qdd).max(axis=0) / limits.acceleration,
            "effort_share": effort / limits.effort}
    return ExcitationResult(excitation, condition, float(np.exp(start_value)), peak, count,
                            time.perf_counter() - began)
