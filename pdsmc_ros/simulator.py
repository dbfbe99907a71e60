"""The discrete closed loop the ROS nodes run, in one process.

At every control instant ``t_k = k / rate`` the controller reads the state and
the reference sampled at ``t_k`` and computes a torque; the plant integrates
Eq. (4.1) over one period with that torque held (zero-order hold, RK4). The
:class:`PlantStepper` and :class:`ControlLaw` wrappers expose the very same
compiled step functions to the ROS nodes.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from . import kernels
from .errors import InvalidInputError
from .metrics import Metrics, Samples, compute_metrics
from .models import FloatArray, Manipulator, as_vector
from .presets import RunSpec, control_steps
from .stability import check_rate
from .trajectories import JointReference

CONTROLLER_CODES = {"pd": kernels.CTRL_PD, "smc": kernels.CTRL_SMC, "pdsmc": kernels.CTRL_PDSMC}


class PlantStepper:
    """The plant of Eq. (4.1) advanced one control period at a time.

    Parameters
    ----------
    robot : Manipulator
        Simulated robot (with payload if any).
    period : float
        Control period (s) over which each torque is held.
    q0, qd0 : array_like
        Initial joint angles and rates.
    """

    def __init__(self, robot: Manipulator, period: float, q0: ArrayLike, qd0: ArrayLike) -> None:
        if not np.isfinite(period) or period <= 0.0:
            raise InvalidInputError(f"period must be > 0 s, got {period!r}")
        self.robot = robot
        self.period = float(period)
        self.kind, self.params = kernels.pack_robot(robot)
        self.q = as_vector(q0, robot.n, "q0").astype(float).copy()
        self.qd = as_vector(qd0, robot.n, "qd0").astype(float).copy()
        self._q_next = np.empty(robot.n)
        self._qd_next = np.empty(robot.n)
        self._work = kernels.workspace()
        self._outputs = np.empty(kernels.OUTPUTS_SIZE)
        self.steps = 0

    def step(self, tau: FloatArray) -> None:
        """Integrate one period with ``tau`` held (RK4, :func:`kernels.rk4_step`)."""
        kernels.rk4_step(
            self.kind, self.params, self.q, self.qd, tau, self.period, self._q_next, self._qd_next,
            self._work,
        )
        self.q, self._q_next = self._q_next, self.q
        self.qd, self._qd_next = self._qd_next, self.qd
        self.steps += 1

    def outputs(self) -> FloatArray:
        """End-effector ``(x, y)`` and, for the five-bar, passive joints and rates now.

        A view of ``kernels.OUTPUTS_SIZE`` floats overwritten by the next call
        (layout: :func:`kernels.robot_outputs`).
        """
        kernels.robot_outputs(self.kind, self.params, self.q, self.qd, self._outputs, self._work)
        return self._outputs

    def warm_up(self) -> None:
        """Load the compiled step now, leaving the state untouched.

        The first call of a kernel in a process loads it from numba's cache
        (tens of ms); a real-time loop calls this before its first tick.
        """
        kernels.rk4_step(
            self.kind, self.params, self.q, self.qd, np.zeros(self.robot.n), self.period,
            self._q_next, self._qd_next, self._work,
        )
        self.outputs()


class ControlLaw:
    """PD, SMC or PD-SMC torque for one state (:func:`kernels.control_torque`)."""

    def __init__(self, spec: RunSpec) -> None:
        self.spec = spec
        self.code = CONTROLLER_CODES[spec.controller]
        self.gains = spec.gains.matrix()
        self.model = spec.smc_model_vector()
        self.model_kind, self.model_params = kernels.pack_robot(spec.nominal_model())
        self.n = self.gains.shape[1]
        self._work = kernels.workspace()

    def torque(
        self, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray, qdd_ref: FloatArray
    ) -> FloatArray:
        """Torque (N m) for the measured state and the reference (new array)."""
        tau = np.empty(self.n)
        kernels.control_torque(
            self.code, self.gains, self.model, self.model_kind, self.model_params,
            q, qd, q_ref, qd_ref, qdd_ref, tau, self._work,
        )
        return tau

    def warm_up(self, q: FloatArray, qd: FloatArray) -> None:
        """Load the compiled law now with one torque at a valid state (discarded).

        The first call in a process loads the kernel from numba's cache (about
        0.7 s here); a real-time controller would otherwise stall on its first tick.
        """
        self.torque(q, qd, q, qd, np.zeros(self.n))


@dataclass(frozen=True)
class RunResult:
    """Outcome of one simulated run."""

    spec: RunSpec
    samples: Samples
    metrics: Metrics
    steps: int
    wall_s: float

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = dict(self.metrics.as_dict())
        out["run"] = self.spec.describe()
        out["steps"] = self.steps
        out["wall_s"] = self.wall_s
        return out


def simulate(spec: RunSpec, *, check_stability: bool = True) -> RunResult:
    """Run the discrete closed loop of ``spec`` and compute its statistics.

    Raises
    ------
    UnstableRateError
        If the gains cannot be stable at ``spec.rate`` (see :mod:`pdsmc_ros.stability`).
    UnreachableError
        If the contour leaves the workspace (before anything runs).
    """
    start = time.perf_counter()
    robot = spec.robot_model()
    reference, refs = _reference_samples(spec)
    if check_stability:
        check_rate(spec, reference)
    contour = reference.contour
    steps = refs.shape[0] - 1
    t_ctrl = np.arange(steps + 1) / spec.rate
    every = spec.sample_every
    count = steps // every + 1
    out_q = np.empty((count, robot.n))
    out_qd = np.empty((count, robot.n))
    out_tau = np.empty((count, robot.n))
    law = ControlLaw(spec)
    kind, params = kernels.pack_robot(robot)
    kernels.run_closed_loop(
        kind, params, law.code, law.gains, law.model, law.model_kind, law.model_params,
        refs[0, 0].copy(), np.zeros(robot.n), refs, 1.0 / spec.rate, every,
        out_q, out_qd, out_tau,
    )
    t = t_ctrl[::every]
    samples = build_samples(robot, contour, t, out_q, refs[::every, 0], out_tau)
    metrics = compute_metrics(samples, spec.bound)
    return RunResult(spec, samples, metrics, steps, time.perf_counter() - start)


def _reference_key(spec: RunSpec) -> tuple[object, ...]:
    """What the sampled joint reference depends on (not gains, controller or payload)."""
    waypoints = spec.waypoints_file
    stamp = os.stat(waypoints).st_mtime_ns if waypoints and os.path.exists(waypoints) else None
    return (spec.robot, spec.contour, spec.ellipse_error, waypoints, stamp, spec.segment_duration,
            spec.duration_factor, spec.rate)


_REFERENCES: dict[tuple[object, ...], tuple[JointReference, FloatArray]] = {}


def _reference_samples(spec: RunSpec) -> tuple[JointReference, FloatArray]:
    """The joint reference and its samples at every control instant (read-only), shared
    by the runs of a process that differ only in gains, controller or payload."""
    key = _reference_key(spec)
    hit = _REFERENCES.get(key)
    if hit is None:
        reference = spec.reference()
        steps = control_steps(reference.contour.duration, spec.rate)
        refs = np.ascontiguousarray(reference.sample(np.arange(steps + 1) / spec.rate).stacked())
        refs.flags.writeable = False
        if len(_REFERENCES) >= 8:
            _REFERENCES.pop(next(iter(_REFERENCES)))
        hit = _REFERENCES[key] = (reference, refs)
    return hit


def build_samples(
    robot: Manipulator,
    contour: object,
    t: FloatArray,
    q: FloatArray,
    q_ref: FloatArray,
    tau: FloatArray,
) -> Samples:
    """Samples (actual and desired task points, contour error) from joint signals."""
    xy = robot.position(q)
    xy_ref = contour.task(t).p[:, :2]  # type: ignore[attr-defined]
    return Samples(
        t=t,
        q=q,
        q_ref=q_ref,
        xy=xy,
        xy_ref=xy_ref,
        tau=tau,
        contour_error=contour.contour_error(t, xy),  # type: ignore[attr-defined]
    )


def simulate_many(
    specs: Sequence[RunSpec],
    *,
    workers: int | None = None,
    progress: Callable[[int, int, RunResult], None] | None = None,
) -> list[RunResult]:
    """Simulate several runs, on ``workers`` processes (default: all cores)."""
    # a process per run at the most: a pool forks all its workers up front
    workers = min(workers or os.cpu_count() or 1, max(len(specs), 1))
    results: list[RunResult | None] = [None] * len(specs)
    if workers == 1 or len(specs) == 1:
        for i, spec in enumerate(specs):
            results[i] = simulate(spec)
            if progress:
                progress(i + 1, len(specs), results[i])  # type: ignore[arg-type]
        return results  # type: ignore[return-value]
    # longest runs first keeps both cores busy until the end
    order = sorted(range(len(specs)), key=lambda i: -specs[i].contour_model().duration)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(simulate, specs[i]): i for i in order}
        for done, future in enumerate(as_completed(futures), start=1):
            i = futures[future]
            results[i] = future.result()
            if progress:
                progress(done, len(specs), results[i])  # type: ignore[arg-type]
    return results  # type: ignore[return-value]
