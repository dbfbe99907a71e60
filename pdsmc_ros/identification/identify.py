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
from .estimate import BaseEstimate, build_rows, check_excitation, nrmse, weighted_least_squares
from .model import ArmDynamics
from .signals import Prepared, prepare

__all__ = ["Identification", "identify", "prediction_nrmse", "validate"]


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
    equations: int
    estimate: BaseEstimate
    fit: ConsistentFit
    nrmse: FloatArray
    nominal_nrmse: FloatArray
    condition: float
    seconds: dict[str, float] = field(default_factory=dict)


def prediction_nrmse(dynamics: ArmDynamics, parameters: FloatArray, prepared: Prepared) -> FloatArray:
    """Per joint, the NRMSE (:func:`~.estimate.nrmse`: RMS error over the measured range) of the
    efforts ``parameters`` predict against the run's: the model's torque at every time of the
    run, through the same zero-phase filter as the efforts, at every kept sample (velocity
    reversals included)."""
    predicted = dynamics.consistent_torque(parameters, prepared.q, prepared.qd, prepared.qdd)
    return nrmse(prepared.tau[prepared.keep], prepared.filtered(predicted))


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
    q_k, qd_k, qdd_k, tau_k, moving = prepared.kept()
    rows = build_rows(dynamics, q_k, qd_k, qdd_k, tau_k, moving)
    check_excitation(dynamics, base, rows, q_k)
    estimate = weighted_least_squares(base, rows, dynamics.n)
    seconds["least squares"] = time.perf_counter() - began
    began = time.perf_counter()
    fit = consistent_fit(dynamics, base, estimate)
    seconds["consistent fit"] = time.perf_counter() - began
    began = time.perf_counter()
    fitted = prediction_nrmse(dynamics, fit.values, prepared)
    nominal = prediction_nrmse(dynamics, dynamics.nominal, prepared)
    seconds["prediction"] = time.perf_counter() - began
    singular = np.linalg.svd(base.columns(rows.regressor), compute_uv=False)
    return Identification(dynamics, base, prepared, rows.size, estimate, fit, fitted, nominal,
                          float(singular[0] / singular[-1]), seconds)


def validate(identification: Identification, t: ArrayLike, q: ArrayLike, tau: ArrayLike
             ) -> tuple[FloatArray, FloatArray]:
    """The fitted and the nominal model's NRMSE per joint on another run (held out), filtered
    with the identification's cut-off."""
    prepared = prepare(t, q, tau, cutoff=identification.prepared.cutoff)
    dynamics = identification.dynamics
    nominal = prediction_nrmse(dynamics, dynamics.nominal, prepared)
    return prediction_nrmse(dynamics, identification.fit.values, prepared), nominal
