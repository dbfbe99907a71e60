"""Discrete-time stability of a control law sampled with a zero-order hold.

A digital controller applies ``tau_k`` over a whole period ``h``. Around the
reference, the error dynamics are ``Mbar edd = -Kp_eff e - Kd_eff ed`` with a
held input, whose exact discretisation is

    e_{k+1}  = e_k + h ed_k - (h^2/2) Mbar^{-1} (Kp e_k + Kd ed_k)
    ed_{k+1} = ed_k        - h Mbar^{-1} (Kp e_k + Kd ed_k)

(damping, Coriolis and gravity variations left out). The loop is stable at
rate ``1/h`` only if the spectral radius of that map is below 1 at every
configuration the motion visits. With the serial arm's thesis gains this
requires about 10 kHz (NOTES.md section 1).

Effective gains inside the boundary layer (``|s| < phi``), where the
switching term is linear:

* PD (Eq. 3.4): ``Kp``, ``Kd``.
* PD-SMC (Eq. 3.44): ``Kp + Ks lambda / phi``, ``Kd + Ks / phi``.
* SMC (Eq. 3.15): ``Ks lambda / phi``, ``s_M lambda Mbar + Ks / phi``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UnstableRateError
from ..presets import RunSpec
from ..robots.base import FloatArray
from ..trajectories import JointReference
from .registry import law


@dataclass(frozen=True)
class RateCheck:
    """Result of :func:`rate_margin`."""

    rate: float
    lowest_stable_rate: float
    spectral_radius: float
    worst_joint: int  # 1-based
    stable: bool


def effective_gains(spec: RunSpec, mass: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """Linear gains ``(Kp_eff, Kd_eff)`` of the law inside its boundary layer (None: the law has none)."""
    linear_gains = law(spec.controller).linear_gains
    if linear_gains is None:
        return None
    return linear_gains(spec.gains.matrix(), spec.smc_model_vector(), mass)


def spectral_radius(
    mass: FloatArray, kp: FloatArray, kd: FloatArray, h: float | FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Spectral radius of the held-input error map and the joint dominating its mode.

    Works on one configuration (``mass``, ``kp``, ``kd`` of shape ``(n, n)``,
    scalar ``h``) or on a stack of them (leading axis ``m``, ``h`` scalar or of
    shape ``(m,)``); returns the radii and the 1-based joints, of the stack's shape.
    """
    mass = np.asarray(mass, dtype=float)
    n = mass.shape[-1]
    h = np.asarray(h, dtype=float)[..., None, None]
    minv_kp = np.linalg.solve(mass, kp)
    minv_kd = np.linalg.solve(mass, kd)
    eye = np.broadcast_to(np.eye(n), minv_kp.shape)
    a = np.empty((*minv_kp.shape[:-2], 2 * n, 2 * n))
    a[..., :n, :n] = eye - 0.5 * h * h * minv_kp
    a[..., :n, n:] = h * eye - 0.5 * h * h * minv_kd
    a[..., n:, :n] = -h * minv_kp
    a[..., n:, n:] = eye - h * minv_kd
    values, vectors = np.linalg.eig(a)
    k = np.argmax(np.abs(values), axis=-1)
    radius = np.take_along_axis(np.abs(values), k[..., None], axis=-1)[..., 0]
    vec = np.take_along_axis(vectors, k[..., None, None], axis=-1)[..., 0]
    mode = np.abs(vec[..., :n]) + np.abs(vec[..., n:]) * h[..., 0]
    return radius, np.argmax(mode, axis=-1) + 1


def _lowest_rates(mass: FloatArray, kp: FloatArray, kd: FloatArray) -> FloatArray:
    """Lowest stable rate (Hz) of each configuration of a stack, by bisection."""
    m = mass.shape[0]
    lo = np.full(m, 1.0)  # Hz
    hi = np.full(m, 1e8)  # stable at 1e8 Hz for any positive gains
    stable_at_lo = spectral_radius(mass, kp, kd, 1.0 / lo)[0] < 1.0
    for _ in range(24):  # bracket ratio 1e8 -> about 0.1 % resolution
        mid = np.sqrt(lo * hi)
        stable = spectral_radius(mass, kp, kd, 1.0 / mid)[0] < 1.0
        hi = np.where(stable, mid, hi)
        lo = np.where(stable, lo, mid)
    return np.where(stable_at_lo, 1.0, hi)


def rate_margin(spec: RunSpec, reference: JointReference, *, points: int = 13) -> RateCheck:
    """Lowest stable rate over the motion and the radius at ``spec.rate``."""
    robot = spec.robot_model()
    t = np.linspace(0.0, reference.duration, points)
    q = reference.sample(t).q
    masses = robot._mass_matrix(q)
    linear = [effective_gains(spec, mass) for mass in masses]
    pairs = [pair for pair in linear if pair is not None]
    if len(pairs) < len(linear):  # a law without linear gains: not checked
        return RateCheck(spec.rate, float("nan"), float("nan"), 0, True)
    kp = np.stack([p[0] for p in pairs])
    kd = np.stack([p[1] for p in pairs])
    lowest = float(np.max(_lowest_rates(masses, kp, kd)))
    radii, joints = spectral_radius(masses, kp, kd, 1.0 / spec.rate)
    worst = int(np.argmax(radii))
    radius = float(radii[worst])
    return RateCheck(spec.rate, lowest, radius, int(joints[worst]), radius < 1.0)


def check_rate(spec: RunSpec, reference: JointReference) -> RateCheck:
    """Refuse a rate at which the gains cannot be stable.

    Raises
    ------
    UnstableRateError
        Naming the joint that dominates the unstable mode and the lowest
        rate that would work.
    """
    result = rate_margin(spec, reference)
    if not result.stable:
        suggestion = np.ceil(1.2 * result.lowest_stable_rate / spec.sample_rate) * spec.sample_rate
        raise UnstableRateError(
            f"{spec.controller} gains for {spec.robot}/{spec.contour} cannot be stable at "
            f"{spec.rate:g} Hz: joint {result.worst_joint} diverges (discrete pole radius "
            f"{result.spectral_radius:.3f} > 1); the lowest stable rate is about "
            f"{result.lowest_stable_rate:,.0f} Hz, use --rate {suggestion:g} or higher"
        )
    return result
