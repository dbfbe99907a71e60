"""Base parameters: the combinations of the standard parameters that joint torques determine.

Many standard parameters never change a joint torque (a planar arm's out-of-plane inertia) or
change it only together with others (the mass of the last link with the first moments of the
link before it): the regressor's columns are linearly dependent, whatever the motion. Gautier's
numerical method finds an independent set: the regressor of random states, its columns scaled to
unit norm, reduced to ``r`` independent columns (a QR decomposition; :func:`base_parameters`
keeps them in a fixed order, where the usual QR with column pivoting lets the columns' norms
choose), every other column written in them, so ``Y pi = Y_b beta`` with ``beta = K pi``
(:attr:`BaseParameters.grouping`). Which ones are independent is a property of
the arm (its structure), not of a particular motion: an excitation is good when it makes the
base regressor well conditioned (:mod:`.excitation`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..robots.base import FloatArray
from .model import ArmDynamics

__all__ = ["BaseParameters", "base_parameters", "random_states"]

RANK_TOLERANCE = 1e-8
"""A pivot below this share of the largest (columns at unit norm) is a dependent column."""
GROUPING_ROUNDING = 1e-10
"""Grouping coefficients smaller than this are zero (rounding of the factorisation)."""


@dataclass(frozen=True)
class BaseParameters:
    """The base parameters of an arm's model.

    Attributes
    ----------
    independent : ndarray of int
        The standard parameters kept (indices into ``pi``), one per base parameter.
    grouping : ndarray, shape (r, p)
        ``beta = grouping @ pi``: each base parameter is its independent standard parameter plus
        the dependent ones grouped into it.
    names : tuple of str
        Each base parameter written as its combination of standard ones.
    unidentifiable : ndarray of int
        Standard parameters that change no torque at all (zero columns).
    """

    independent: np.ndarray
    grouping: FloatArray
    names: tuple[str, ...]
    unidentifiable: np.ndarray

    @property
    def size(self) -> int:
        return len(self.independent)

    def columns(self, regressor: FloatArray) -> FloatArray:
        """The base regressor ``Y_b`` (the independent columns) of a standard regressor ``Y``."""
        return regressor[:, self.independent]

    def of(self, standard: FloatArray) -> FloatArray:
        """The base parameters of standard parameters."""
        return self.grouping @ standard


def random_states(dynamics: ArmDynamics, count: int, rng: np.random.Generator) -> tuple[FloatArray, ...]:
    """``count`` random ``(q, qd, qdd)`` within the arm's position limits (at most one turn each
    way), velocities and accelerations of order one: the generic states the structure is read from."""
    arm = dynamics.arm
    lo = np.maximum(np.where(np.isfinite(arm.position_limits[:, 0]), arm.position_limits[:, 0], -np.pi), -np.pi)
    hi = np.minimum(np.where(np.isfinite(arm.position_limits[:, 1]), arm.position_limits[:, 1], np.pi), np.pi)
    q = rng.uniform(lo, hi, size=(count, arm.n))
    qd = rng.normal(size=(count, arm.n))
    qdd = rng.normal(size=(count, arm.n))
    return q, qd, qdd


def base_parameters(dynamics: ArmDynamics, *, samples: int | None = None, seed: int = 0) -> BaseParameters:
    """The arm's base parameters (module docstring), from the regressor of ``samples`` random states
    (by default 20 per joint; ``seed`` makes it repeat).

    The independent columns are chosen in a fixed order -- the links from the base out, then the
    joints' armature and friction, the payload last -- each kept when it adds to the span of those
    kept before it (its part orthogonal to them above :data:`RANK_TOLERANCE`): the distal
    parameters are grouped into the proximal ones, as in Khalil's regrouping, and the payload
    into the end-effector's link.
    """
    rng = np.random.default_rng(seed)
    count = samples or 20 * dynamics.n
    y = dynamics.regressor(*random_states(dynamics, count, rng))
    norms = np.linalg.norm(y, axis=0)
    live = norms > RANK_TOLERANCE * float(norms.max())
    zero = np.flatnonzero(~live)
    layout = dynamics.layout
    everything = np.arange(layout.size)
    order = np.concatenate([everything[layout.links], everything[layout.links.stop + 10:],
                            everything[layout.payload]])
    basis = np.zeros((y.shape[0], 0))
    kept: list[int] = []
    for k in order:
        if not live[k]:
            continue
        column = y[:, k] / norms[k]
        for _ in range(2):  # Gram-Schmidt twice: orthogonal to working precision
            column = column - basis @ (basis.T @ column)
        size = float(np.linalg.norm(column))
        if size > RANK_TOLERANCE:
            kept.append(int(k))
            basis = np.column_stack([basis, column / size])
    independent = np.array(sorted(kept), dtype=np.intp)
    dependent = np.setdiff1d(np.flatnonzero(live), independent)
    # Y_d = Y_b C: each dependent column in the independent ones (exact: they span it)
    coupling = scipy.linalg.lstsq(y[:, independent], y[:, dependent])[0]
    grouping = np.zeros((len(independent), layout.size))
    grouping[np.arange(len(independent)), independent] = 1.0
    grouping[:, dependent] = coupling
    grouping[np.abs(grouping) < GROUPING_ROUNDING] = 0.0
    names = tuple(_combination(grouping[i], layout.names, independent[i]) for i in range(len(independent)))
    return BaseParameters(independent, grouping, names, zero)


def _combination(row: FloatArray, names: tuple[str, ...], lead: int) -> str:
    terms = [names[lead]]
    for k in np.flatnonzero(row):
        if k == lead:
            continue
        c = row[k]
        terms.append(f"{'-' if c < 0 else '+'} {abs(c):.4g} {names[k]}" if abs(c - np.sign(c)) > 1e-9
                     else f"{'-' if c < 0 else '+'} {names[k]}")
    return " ".join(terms)
