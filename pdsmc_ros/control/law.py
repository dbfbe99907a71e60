"""One control law ready to run: what the simulator and the controller node call."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator
from .laws import compiled_torque
from .registry import LawSetup, law

if TYPE_CHECKING:
    from .run import LawRun

Vector = Sequence[float] | FloatArray
"""``n`` floats: a decoded message's tuple or an array."""


class ControlLaw:
    """A registered law with its gains and nominal model.

    Runs the law's compiled form when the law and the model both have one
    (:attr:`compiled`), else its numpy form.

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
    """

    def __init__(self, name: str, gains: FloatArray, smc_model: FloatArray, model: Manipulator) -> None:
        self.entry = law(name)
        self.setup = LawSetup(np.ascontiguousarray(gains, dtype=float), model, np.asarray(smc_model, dtype=float))
        self.n = self.setup.gains.shape[1]
        self.compiled = self.entry.code is not None and model.kernel is not None
        self.code = -1 if self.entry.code is None else self.entry.code
        if self.compiled:
            self.model_kind, self.model_params = robot_compiled.pack(model)
            self._work = robot_compiled.workspace(self.n)

    @classmethod
    def from_spec(cls, spec: LawRun) -> ControlLaw:
        """The law of a run."""
        return cls(spec.controller, spec.gains.matrix(), spec.smc_model_vector(), spec.nominal_model())

    @property
    def gains(self) -> FloatArray:
        return self.setup.gains

    @property
    def smc_model(self) -> FloatArray:
        return self.setup.smc_model

    def torque(self, q: Vector, qd: Vector, q_ref: Vector, qd_ref: Vector, qdd_ref: Vector) -> FloatArray:
        """Torque (N m) for the measured state and the reference (new array)."""
        x = np.array([*q, *qd, *q_ref, *qd_ref, *qdd_ref])  # 5 sequences of n floats: float64
        if not self.compiled:
            return np.asarray(self.entry.torque(self.setup, *x.reshape(5, self.n)), dtype=float)
        tau = np.empty(self.n)
        compiled_torque(self.code, self.setup.gains, self.setup.smc_model, self.model_kind, self.model_params,
                        x, tau, self._work)
        return tau

    def warm_up(self, q: FloatArray, qd: FloatArray) -> ControlLaw:
        """Load the compiled law now with one torque at a valid state (discarded).

        The first call in a process loads the kernel from numba's cache; a
        real-time controller would otherwise stall on its first tick.
        """
        self.torque(q, qd, q, qd, np.zeros(self.n))
        return self
