"""One control law ready to run: the compiled call behind every registered law, and
:class:`ControlLaw`, what the simulator and the controller node call.

:func:`law_torque` dispatches on a law's code: every law with a compiled form
(:attr:`LawEntry.code`) adds one branch here (a law written in Python has a code from
:data:`~pdsmc_ros.control.python_form.PYTHON_LAW` up and runs behind the last). The compiled
closed loop (:mod:`pdsmc_ros.sim.loop`) inlines :func:`law_torque`; Python (the nodes, through
:class:`ControlLaw`) calls :func:`compiled_torque`. A law with internal state
(:attr:`LawEntry.state_size`) reads and updates ``state`` (shape ``(state_size, n)``, in place)
and integrates it with the control period ``h``: the torque of instant ``k`` uses the state of
instant ``k``, which then steps to ``k + 1`` (explicit Euler, once per call).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..errors import InvalidInputError
from ..kernels.options import ALLOCATION_FREE
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator
from . import python_form
from .baselines import CTC, PDG, ctc, pdg
from .laws import PD, PDSMC, SMC, errors, joint_errors, pd, pdsmc, smc
from .position_domain import PD_POS, PDSMC_VIRTUAL, position_domain
from .python_form import PYTHON_LAW
from .python_form import torque as python_torque
from .registry import LawSetup, law
from .sliding import ISMC, STA, ismc, sta

if TYPE_CHECKING:
    from .law_run import LawRun

@njit(cache=True, inline="always")
def law_torque(code, gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, n, state, h):  # noqa: ANN001, ANN201, PLR0913
    """:func:`compiled_torque` with its inputs as separate vectors of ``n`` joints.

    What a compiled loop calls: ``n`` is its constant joint count (loops of known length)
    and the reference rows are views of its samples (nothing copied).
    """
    if code >= PDG:  # a law beside the thesis's (codes 3 and up: its gain matrix has other rows)
        _beside_the_thesis(code, gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, n, state, h)
        return
    if code == PD:
        for i in range(n):
            e, ed, _ = joint_errors(gains, q, qd, q_ref, qd_ref, i)
            tau[i] = pd(gains, e, ed, i)
    elif code == PDSMC:
        for i in range(n):
            e, ed, sat = joint_errors(gains, q, qd, q_ref, qd_ref, i)
            tau[i] = pdsmc(gains, e, ed, sat, i)
    elif code == SMC:
        e = work[0:n]
        ed = work[n : 2 * n]
        sat = work[2 * n : 3 * n]
        errors(gains, q, qd, q_ref, qd_ref, e, ed, sat, n)
        smc(gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, e, ed, sat, tau, work[3 * n :])


@njit(**ALLOCATION_FREE)
def _beside_the_thesis(code, gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, n, state, h):  # noqa: ANN001, ANN202, PLR0913
    """The laws beside the thesis's, behind one call: the thesis laws' path stays what the compiled
    loop inlined before they came (bench/kernel.py within its noise of main's)."""
    e = work[0:n]
    ed = work[n : 2 * n]
    sat = work[2 * n : 3 * n]
    if code == PDG:
        errors(gains, q, qd, q_ref, qd_ref, e, ed, sat, n)
        pdg(gains, smc_model, kind, p, q, q_ref, e, ed, tau, work[3 * n :])
    elif code == CTC:
        ctc(gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work)
    elif code == STA:
        sta(gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, state, h)
    elif code == ISMC:
        ismc(gains, smc_model, kind, p, q, qd, q_ref, qd_ref, qdd_ref, tau, work, state, h)
    elif PD_POS <= code <= PDSMC_VIRTUAL:  # the position domain laws (codes 7-9)
        position_domain(gains, q, qd, q_ref, qd_ref, qdd_ref, tau, n, state, code == PDSMC_VIRTUAL)
    elif code >= PYTHON_LAW:
        python_torque(code, q, qd, q_ref, qd_ref, qdd_ref, tau)
    else:
        raise ValueError("unknown control law code: no branch in control.law")


@njit(**ALLOCATION_FREE)
def compiled_torque(code, gains, smc_model, kind, p, x, tau, work, state, h):  # noqa: ANN001, ANN201, PLR0913
    """The law ``code`` for one state, into ``tau``; its internal ``state`` stepped by ``h``.

    ``x`` holds the inputs one after the other, ``q, qd, q_d, qd_d, qdd_d`` (``5 n`` floats:
    from Python each argument of a compiled call costs about 0.1 us, and one array built from
    a flat list about half what five arrays or one built from nested tuples cost).
    ``gains`` is :attr:`LawSetup.gains`, ``smc_model`` :attr:`LawSetup.smc_model`,
    ``(kind, p)`` the nominal robot's compiled form
    (:func:`pdsmc_ros.robots.compiled.pack`), ``work`` from
    :func:`pdsmc_ros.robots.compiled.workspace`, ``state`` :attr:`LawSetup.state`.
    """
    n = tau.shape[0]
    law_torque(code, gains, smc_model, kind, p, x[0:n], x[n : 2 * n], x[2 * n : 3 * n], x[3 * n : 4 * n],
               x[4 * n : 5 * n], tau, work, n, state, h)


Vector = Sequence[float] | FloatArray
"""``n`` floats: a decoded message's tuple or an array."""


class ControlLaw:
    """A registered law with its gains and nominal model.

    Every law runs through :func:`compiled_torque`: its compiled
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
        What :func:`compiled_torque` runs.
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

    def with_gains(self, gains: FloatArray) -> ControlLaw:
        """This law with other ``gains`` (same shape), its internal state carried on: a change at
        run time. The nominal model, its packed form and the model estimate are this law's own
        (:meth:`from_spec` rebuilds the robot model: 0.36 ms on the UR5, which a controller
        applying it in the loop's spare time paid as a late period).

        Raises
        ------
        InvalidInputError
            ``gains`` of another shape or not finite.
        """
        gains = np.array(gains, dtype=float)  # a copy: the law's own
        if gains.shape != self.setup.gains.shape or not np.all(np.isfinite(gains)):
            raise InvalidInputError(f"control law {self.entry.name!r}: gains must be a finite "
                                    f"{self.setup.gains.shape} array, got shape {gains.shape}")
        law = copy.copy(self)
        law.setup = dataclasses.replace(self.setup, gains=gains, state=self.setup.state.copy())
        law.gains, law.state = law.setup.gains, law.setup.state
        law.code = python_form.handle(law) if law.entry.code is None else law.entry.code
        law._work = robot_compiled.workspace(law.n)  # never shared with a law that may still be running
        return law

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
