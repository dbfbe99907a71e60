"""One control law ready to run: what the simulator and the controller node call."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InvalidInputError
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator
from . import python_form
from .dispatch import compiled_torque
from .registry import LawSetup, law

if TYPE_CHECKING:
    from .run import LawRun

Vector = Sequence[float] | FloatArray
"""``n`` floats: a decoded message's tuple or an array."""


class ControlLaw:
    """A registered law with its gains and nominal model.

    Every law runs through :func:`~pdsmc_ros.control.dispatch.compiled_torque`: its compiled
    form, or its Python torque behind :mod:`.python_form` (:attr:`code`); the nominal model
    likewise, through its compiled form or :mod:`pdsmc_ros.robots.python_form`'s.

    Parameters
    ----------
    name : str
        A registered law (:func:`pdsmc_ros.control.law_names`).
    gains : ndarray, shape (5, n)
        Rows ``kp, kd, ks, lam, phi``.
    smc_model : ndarray, shape (6,)
        The model estimate's scales (model-based laws).
    model : Manipulator
        The nominal robot known to the law.
    h : float
        The period (s) a law with internal state (:attr:`LawEntry.state_size`) integrates it
        with, once per :meth:`torque` call: the run's control period ``1 / rate`` (the
        controller node's nominal period, whatever its real ticks' jitter).

    Attributes
    ----------
    gains, smc_model, h
        As given (:attr:`setup`'s).
    state : ndarray, shape (state_size, n)
        The law's internal state, updated in place by :meth:`torque`.
    code : int
        What :func:`~pdsmc_ros.control.dispatch.compiled_torque` runs.
    """

    def __init__(self, name: str, gains: FloatArray, smc_model: FloatArray, model: Manipulator,
                 h: float = 0.0) -> None:
        self.entry = law(name)
        gains = np.ascontiguousarray(gains, dtype=float)
        self.n = gains.shape[1]
        if self.entry.state_size and not (np.isfinite(h) and h > 0.0):
            raise InvalidInputError(f"control law {name!r} integrates a state: its period h must be > 0 s, got {h!r}")
        state = np.zeros((self.entry.state_size, self.n))
        self.setup = LawSetup(gains, model, np.asarray(smc_model, dtype=float), state, float(h))
        # the setup's own arrays (a frozen dataclass: these never change identity), by name
        self.gains, self.smc_model, self.state, self.h = self.setup.gains, self.setup.smc_model, state, self.setup.h
        self.code = python_form.handle(self) if self.entry.code is None else self.entry.code
        self.model_kind, self.model_params = robot_compiled.pack(model)
        self._work = robot_compiled.workspace(self.n)

    @classmethod
    def from_spec(cls, spec: LawRun) -> ControlLaw:
        """The law of a run."""
        return cls(spec.controller, spec.gains.matrix(), spec.smc_model_vector(), spec.nominal_model(),
                   1.0 / spec.rate)

    def reset(self) -> ControlLaw:
        """The internal state back to zero (a controller activated anew)."""
        self.setup.state[:] = 0.0
        return self

    def torque(self, q: Vector, qd: Vector, q_ref: Vector, qd_ref: Vector, qdd_ref: Vector) -> FloatArray:
        """Torque (N m) for the measured state and the reference (new array)."""
        x = np.array([*q, *qd, *q_ref, *qd_ref, *qdd_ref])  # 5 sequences of n floats: float64
        tau = np.empty(self.n)
        compiled_torque(self.code, self.setup.gains, self.setup.smc_model, self.model_kind, self.model_params,
                        x, tau, self._work, self.setup.state, self.setup.h)
        return tau

    def python_torque(self, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                      qdd_ref: FloatArray, tau: FloatArray) -> None:
        """A law written in Python (:attr:`LawEntry.torque`): its torque into ``tau``
        (what :mod:`.python_form` calls back)."""
        torque = self.entry.torque
        if torque is None:
            raise TypeError(f"control law {self.entry.name!r} has neither a compiled form nor a Python torque")
        tau[:] = torque(self.setup, q, qd, q_ref, qd_ref, qdd_ref)

    def warm_up(self, q: FloatArray, qd: FloatArray) -> ControlLaw:
        """Load the compiled law now with one torque at a valid state (discarded).

        The first call in a process loads the kernel from numba's cache; a
        real-time controller would otherwise stall on its first tick. The state is reset after.
        """
        self.torque(q, qd, q, qd, np.zeros(self.n))
        return self.reset()
