"""The whole identification of one run: recorded positions and efforts in, a consistent model out.

:func:`identify` chains :mod:`.signals` (filtering, differentiation, the dead zone around velocity
reversals), :mod:`.estimate` (the excitation check, weighted least squares on the base
regressor) and :mod:`.consistent` (the LMI fit), and measures how well the result predicts the
run's own efforts; :func:`validate` does the same on another run with the same filter. Each step
is timed (:attr:`Identification.seconds`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..robots.base import FloatArray
from .base import BaseParameters, base_parameters
from .consistent import ConsistentFit, consistent_fit
from .estimate import BaseEstimate, Rows, check_excitation, nrmse, weighted_least_squares
from .model import ArmDynamics
from .signals import Prepared, prepare

__all__ = ["Identification", "filtered_regressor", "identify", "prediction_nrmse", "validate"]


@dataclass(frozen=True)
class Identification:
    """One run identified.

    Attributes
    ----------
    dynamics : ArmDynamics
        The arm's model (its own parameters are the prior).
    base : BaseParameters
    prepared : Prepared
        The run's samples and how they were made.
    regressor : ndarray
        The run's standard regressor, filtered as the efforts (:func:`filtered_regressor`).
    equations : int
        Torque equations fitted (samples times joints, less the dead zones).
    estimate : BaseEstimate
        The weighted least-squares base parameters.
    fit : ConsistentFit
        The physically consistent standard parameters.
    nrmse : ndarray
        Per joint: the fitted model's effort error on this run (:func:`prediction_nrmse`).
    nominal_nrmse : ndarray
        The same for the arm's own model (its URDF and options): what identification gained.
    condition : float
        The 2-norm condition number of the run's base regressor (the fitted equations).
    seconds : dict
        Wall time of each step.
    """

    dynamics: ArmDynamics
    base: BaseParameters
    prepared: Prepared
    regressor: FloatArray
    equations: int
    estimate: BaseEstimate
    fit: ConsistentFit
    nrmse: FloatArray
    nominal_nrmse: FloatArray
    condition: float
    seconds: dict[str, float] = field(default_factory=dict)


def filtered_regressor(dynamics: ArmDynamics, prepared: Prepared) -> FloatArray:
    """The standard regressor of the run, filtered as its efforts are (parallel filtering:
    :mod:`.signals`), at the kept samples: shape ``(kept * n, p)``, rows as
    :meth:`ArmDynamics.regressor`'s."""
    n, p = dynamics.n, dynamics.layout.size
    q, qd, qdd = prepared.motion()
    columns = dynamics.regressor(q, qd, qdd).reshape(len(q), n * p)
    smooth = prepared.smooth(columns).reshape(-1, n, p)
    steps = prepared.stepped(prepared.coulomb_sign())  # Coulomb friction's sign, from every sample
    coulomb = dynamics.layout.joint_field("friction_coulomb").start + np.arange(n)
    smooth[:, np.arange(n), coulomb] = steps
    out: FloatArray = smooth.reshape(-1, p)
    return out


def prediction_nrmse(regressor: FloatArray, parameters: FloatArray, prepared: Prepared, *,
                     moving_only: bool = False, static: slice | None = None) -> FloatArray:
    """Per joint, the NRMSE (:func:`~.estimate.nrmse`: RMS error over the measured range) of the
    efforts ``parameters`` predict against the run's, both filtered alike (``regressor``:
    :func:`filtered_regressor`), at every kept sample (velocity reversals and slow stretches
    included); ``moving_only``: at the samples each joint's equations were fitted on (outside its
    dead zone, :attr:`~.signals.Prepared.moving`), the range still the whole run's.

    ``static`` (the Coulomb frictions' slice of ``parameters``): Coulomb friction as the set-valued
    law it is (Olsson et al. 1998; Brogliato 1999): any value within ``+/- fc`` where a joint is at
    rest, ``fc sign(qd)`` where it moves, that set carried through the efforts' filters
    (:meth:`~.signals.Prepared.static_friction_set`); the prediction is the rigid body's torque,
    the motor inertia's and the viscous friction's plus that set, and the error the measured
    effort's distance from it. Whatever torque within ``+/- fc`` holds a stuck joint, it is in the
    set; a model whose ``fc`` or rigid-body torque is wrong still misses it."""
    predicted = (regressor @ parameters).reshape(prepared.tau.shape)
    if static is not None:
        fc = parameters[static]
        friction = (regressor[:, static] @ fc).reshape(prepared.tau.shape)
        centre, radius = prepared.static_friction_set()
        middle = predicted - friction + fc * centre
        predicted = np.clip(prepared.tau, middle - fc * radius, middle + fc * radius)
    if not moving_only:
        return nrmse(prepared.tau, predicted)
    spread = prepared.tau.max(axis=0) - prepared.tau.min(axis=0)
    out = np.full(prepared.tau.shape[1], np.inf)
    for j in range(len(out)):
        mine = prepared.moving[:, j]
        if np.any(mine) and spread[j] > 0.0:
            out[j] = float(np.sqrt(np.mean((prepared.tau[mine, j] - predicted[mine, j]) ** 2)) / spread[j])
    return out


def identify(dynamics: ArmDynamics, t: ArrayLike, q: ArrayLike, tau: ArrayLike, *, cutoff: float | None = None,
             base: BaseParameters | None = None) -> Identification:
    """Identify the arm from one run: times ``t`` (s), positions and efforts ``(k, n)`` in its joints'
    order; ``cutoff`` (Hz) replaces the filter's cut-off chosen from the motion.

    Raises
    ------
    InvalidInputError
        A run the filter cannot use (:func:`~.signals.prepare`).
    NotIdentifiableError
        A run that does not determine every base parameter (:func:`~.estimate.check_excitation`).
    FitError
        The consistent fit's solver failed.
    """
    seconds: dict[str, float] = {}
    began = time.perf_counter()
    base = base or base_parameters(dynamics)
    seconds["base parameters"] = time.perf_counter() - began
    began = time.perf_counter()
    prepared = prepare(t, q, tau, cutoff=cutoff)
    seconds["filtering"] = time.perf_counter() - began
    began = time.perf_counter()
    regressor = filtered_regressor(dynamics, prepared)
    rows = Rows.of(regressor, prepared.tau, prepared.moving)
    check_excitation(dynamics, base, rows, prepared.kept_motion()[0])
    estimate = weighted_least_squares(base, rows, dynamics.n)
    seconds["least squares"] = time.perf_counter() - began
    began = time.perf_counter()
    fit = consistent_fit(dynamics, base, estimate)
    seconds["consistent fit"] = time.perf_counter() - began
    began = time.perf_counter()
    fitted = prediction_nrmse(regressor, fit.values, prepared)
    nominal = prediction_nrmse(regressor, dynamics.nominal, prepared)
    seconds["prediction"] = time.perf_counter() - began
    singular = np.linalg.svd(base.columns(rows.regressor), compute_uv=False)
    return Identification(dynamics, base, prepared, regressor, rows.size, estimate, fit, fitted, nominal,
                          float(singular[0] / singular[-1]), seconds)


def validate(identification: Identification, t: ArrayLike, q: ArrayLike, tau: ArrayLike
             ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The fitted and the nominal model's NRMSE per joint on another run (held out), filtered
    with the identification's cut-off and Coulomb band; the fitted model's outside each joint's
    dead zone (:func:`prediction_nrmse`'s ``moving_only``); and the fitted model's with static
    friction the set it is at rest (:func:`prediction_nrmse`'s ``static``)."""
    prepared = prepare(t, q, tau, cutoff=identification.prepared.cutoff,
                       stick_band=identification.prepared.stick_band)
    dynamics = identification.dynamics
    regressor = filtered_regressor(dynamics, prepared)
    values = identification.fit.values
    return (prediction_nrmse(regressor, values, prepared),
            prediction_nrmse(regressor, dynamics.nominal, prepared),
            prediction_nrmse(regressor, values, prepared, moving_only=True),
            prediction_nrmse(regressor, values, prepared, static=dynamics.layout.joint_field("friction_coulomb")))
