"""The compiled laws behind one call: :func:`law_torque` dispatches on a law's code.

Every law with a compiled form (:attr:`LawEntry.code`) adds one branch here (a law written in
Python has a code from :data:`~pdsmc_ros.control.python_form.PYTHON_LAW` up and runs behind the last); the compiled
closed loop (:mod:`pdsmc_ros.sim.loop`) inlines :func:`law_torque`, and Python (the nodes,
:class:`~pdsmc_ros.control.ControlLaw`) calls :func:`compiled_torque`. A law with internal
state (:attr:`LawEntry.state_size`) reads and updates ``state`` (shape ``(state_size, n)``,
in place) and integrates it with the control period ``h``: the torque of instant ``k`` uses
the state of instant ``k``, which then steps to ``k + 1`` (explicit Euler, once per call).
"""

from __future__ import annotations

from numba import njit

from ..kernel_options import ALLOCATION_FREE
from .baselines import CTC, PDG, ctc, pdg
from .laws import PD, PDSMC, SMC, errors, joint_errors, pd, pdsmc, smc
from .python_form import PYTHON_LAW
from .python_form import torque as python_torque
from .sliding import ISMC, STA, ismc, sta


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
    elif code >= PYTHON_LAW:
        python_torque(code, q, qd, q_ref, qd_ref, qdd_ref, tau)
    else:
        raise ValueError("unknown control law code: no branch in control.dispatch")


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
