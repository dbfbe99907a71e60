"""The continuous-time limit of a run: the control law inside a stiff ODE solver.

The thesis simulated in continuous time (docs/THESIS_NOTES.md section 1); the project runs a
discrete loop (zero-order hold, RK4) fast enough to stand in for it. This module
measures how close that is: the same plant (:func:`pdsmc_ros.robots.compiled.forward_dynamics`,
Eq. 4.1) and the same control law (:class:`simulator.ControlLaw`) evaluated at every
instant the solver asks for, inside scipy's ``solve_ivp(method="Radau")``, with the
statistics taken at the same sampled instants as the discrete run.
"""

from __future__ import annotations

import time

import numpy as np

from ..control.law import ControlLaw
from ..errors import InvalidInputError
from ..metrics.statistics import build_samples, compute_metrics
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray
from ..runs.builder import RunSpec, control_steps
from .simulator import RunResult


def simulate_continuous(spec: RunSpec, *, rtol: float = 1e-10, atol: float = 1e-12) -> RunResult:
    """Run ``spec`` with the control law evaluated continuously (no hold, no control rate).

    Parameters
    ----------
    spec : RunSpec
        The run; its ``rate`` only sets the statistics instants (``sample_rate``).
    rtol, atol : float
        Tolerances of the Radau solver.

    Returns
    -------
    RunResult
        Statistics at ``spec.sample_rate`` over ``[0, T]``; ``steps`` counts the
        right-hand-side evaluations.

    Raises
    ------
    InvalidInputError
        If the solver fails.
    """
    from scipy.integrate import solve_ivp

    start = time.perf_counter()
    robot = spec.robot_model()
    reference = spec.reference()
    kind, params = robot_compiled.pack(robot)
    law = ControlLaw.from_spec(spec)
    n = robot.n
    work = robot_compiled.workspace(n)
    qdd = np.empty(n)
    evaluations = 0

    def rhs(t: float, y: FloatArray) -> FloatArray:
        nonlocal evaluations
        evaluations += 1
        ref = reference.sample(t)
        q, qd = np.ascontiguousarray(y[:n]), np.ascontiguousarray(y[n:])
        tau = law.torque(q, qd, ref.q[0], ref.qd[0], ref.qdd[0])
        robot_compiled.forward_dynamics(kind, params, q, qd, tau, qdd, work)
        return np.concatenate([qd, qdd])

    duration = reference.duration
    t = np.arange(control_steps(duration, spec.sample_rate) + 1) / spec.sample_rate
    q0 = reference.sample(0.0).q[0]
    sol = solve_ivp(rhs, (0.0, duration), np.concatenate([q0, np.zeros(n)]), method="Radau",
                    t_eval=t, rtol=rtol, atol=atol)
    if not sol.success:
        raise InvalidInputError(f"continuous-time run of {spec.robot}/{spec.contour}/{spec.controller} "
                                f"failed: {sol.message}")
    q = np.ascontiguousarray(sol.y[:n].T)
    qd = np.ascontiguousarray(sol.y[n:].T)
    refs = reference.sample(t)
    tau = np.array([law.torque(q[i], qd[i], refs.q[i], refs.qd[i], refs.qdd[i]) for i in range(len(t))])
    samples = build_samples(robot, reference.contour, t, q, refs.q, tau)
    return RunResult(spec, samples, compute_metrics(samples, spec.bound), evaluations,
                     time.perf_counter() - start)
