"""Whole runs in one process: one, or many on all cores, with their statistics.

The same step code as the ROS nodes (:mod:`.loop`, :mod:`.rk4`,
:class:`pdsmc_ros.control.ControlLaw`), which is why a lockstep DDS run and
an in-process run agree to rounding.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..contours import JointReference
from ..control.law import ControlLaw
from ..control.soft_limits import effort_only_table
from ..control.stability import check_rate
from ..metrics.statistics import Metrics, RunStatistics, Samples, build_samples
from ..robots import ROBOTS
from ..robots.base import FloatArray, Manipulator
from ..runs.builder import RunSpec, control_steps
from .loop import run_loop
from .stretches import run_in_stretches


@dataclass(frozen=True)
class RunResult:
    """Outcome of one simulated run."""

    spec: RunSpec
    samples: Samples
    metrics: Metrics
    steps: int
    wall_s: float
    diverged: str = ""
    """Why the run stopped early (a non-finite or runaway state: :class:`DivergenceCheck`), or ``""``."""
    limit_warnings: tuple[str, ...] = ()
    """The first crossing of each joint's position and velocity limit (the plant's warnings)."""

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = dict(self.metrics.as_dict())
        out["run"] = self.spec.describe()
        out["steps"] = self.steps
        out["wall_s"] = self.wall_s
        out["diverged"] = self.diverged
        out["limit_warnings"] = list(self.limit_warnings)
        return out


def simulate(spec: RunSpec, *, check_stability: bool = True, plant: Manipulator | None = None,
             initial_error: ArrayLike | None = None, keep_samples: bool = True) -> RunResult:
    """Run the discrete closed loop of ``spec`` and compute its statistics.

    Parameters
    ----------
    spec : RunSpec
        The run.
    check_stability : bool
        Refuse gains that cannot be stable at the rate (before anything runs).
    plant : Manipulator, optional
        The simulated robot instead of ``spec.robot_model()`` (a plant that is not the model:
        :mod:`pdsmc_ros.experiments.montecarlo`); the controller keeps ``spec``'s nominal model.
    initial_error : array_like, optional
        Added to the joint angles the run starts from (the reference's first point), rad.
    keep_samples : bool
        Keep the samples (:attr:`RunResult.samples`). False: the run goes in stretches and keeps
        only what its statistics need (:mod:`.stretches`: the same metrics, memory that no longer
        grows with the reference and the states); its ``samples`` are empty.

    The law's torque is clamped to the arm's effort limits (``robot.effort_limits``) at every
    step unless ``spec.enforce_limits`` is False; the metrics count the saturated periods. A run
    whose state diverges (:class:`~pdsmc_ros.sim.divergence.DivergenceCheck`) stops there: its
    samples from then on are NaN (so are the statistics) and :attr:`RunResult.diverged` says why.

    Raises
    ------
    UnstableRateError
        If the gains cannot be stable at ``spec.rate`` (see :mod:`pdsmc_ros.control.stability`).
    UnreachableError
        If the contour leaves the workspace (before anything runs).
    """
    start = time.perf_counter()
    robot = plant or spec.robot_model()
    if not keep_samples:
        reference = spec.reference()
        control_steps(reference.contour.duration, spec.rate)  # a run too long to hold is refused first
        if check_stability:
            check_rate(spec, reference)
        metrics, count, outcome = run_in_stretches(spec, robot, reference, initial_error)
        return RunResult(spec, Samples.empty(robot.n), metrics, count, time.perf_counter() - start,
                         outcome.diverged, tuple(outcome.warnings))
    reference, refs = _reference_samples(spec)
    if check_stability:
        check_rate(spec, reference)
    steps = refs.shape[0] - 1
    every = spec.sample_every
    q0 = refs[0, 0] if initial_error is None else refs[0, 0] + np.asarray(initial_error, dtype=float)
    limit = effort_only_table(robot.effort_limits, robot.n) if spec.enforce_limits else None
    out_q, _, out_tau, outcome = run_loop(robot, ControlLaw.from_spec(spec), q0, refs, 1.0 / spec.rate, every,
                                          limit, every_step=True)
    t, xy_ref = _task_samples(spec, reference, steps)
    samples = build_samples(robot, reference.contour, t, out_q, refs[::every, 0], out_tau, xy_ref=xy_ref)
    stats = RunStatistics(robot.n, bound=spec.bound, rate=spec.rate)
    stats.add_samples(samples)
    stats.add_steps(outcome.step_error, outcome.step_tau)
    metrics = stats.metrics(outcome.saturated)
    return RunResult(spec, samples, metrics, steps, time.perf_counter() - start, outcome.diverged,
                     tuple(outcome.warnings))


def _reference_key(spec: RunSpec) -> tuple[object, ...]:
    """What the sampled joint reference depends on (not gains, controller or payload)."""
    waypoints = spec.waypoints_file
    stamp = os.stat(waypoints).st_mtime_ns if waypoints and os.path.exists(waypoints) else None
    # the class, not only the name: /robot_description may name another arm later in a process
    return (spec.robot, ROBOTS[spec.robot], spec.contour, spec.ellipse_error, waypoints, stamp,
            spec.segment_duration, spec.duration_factor, spec.rate)


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


_TASK_SAMPLES: dict[tuple[object, ...], tuple[FloatArray, FloatArray]] = {}


def _task_samples(spec: RunSpec, reference: JointReference, steps: int) -> tuple[FloatArray, FloatArray]:
    """The statistics instants and the desired task points there (read-only), shared like
    :func:`_reference_samples` by the runs of a process on the same reference (a Monte Carlo's)."""
    key = (*_reference_key(spec), spec.sample_every)
    hit = _TASK_SAMPLES.get(key)
    if hit is None:
        t = (np.arange(steps + 1) / spec.rate)[::spec.sample_every]
        xy_ref = np.ascontiguousarray(reference.contour.task(t).p[:, :2])
        t.flags.writeable = xy_ref.flags.writeable = False
        if len(_TASK_SAMPLES) >= 8:
            _TASK_SAMPLES.pop(next(iter(_TASK_SAMPLES)))
        hit = _TASK_SAMPLES[key] = (t, xy_ref)
    return hit


def simulate_many(
    specs: Sequence[RunSpec],
    *,
    workers: int | None = None,
    progress: Callable[[int, int, RunResult], None] | None = None,
    scheduler: str | None = None,
) -> list[RunResult]:
    """Simulate several runs on the project's one parallel engine (:mod:`pdsmc_ros.sim.engine`):
    a local Dask cluster of ``workers`` processes (default: all cores), or the cluster of
    ``scheduler`` (``tcp://HOST:PORT``); one worker or one run: in this process."""
    from .engine import dask_client, run_tasks

    results: list[RunResult | None] = [None] * len(specs)
    workers = min(workers or os.cpu_count() or 1, max(len(specs), 1))
    if scheduler is None and (workers == 1 or len(specs) == 1):
        for i, spec in enumerate(specs):
            results[i] = simulate(spec)
            if progress:
                progress(i + 1, len(specs), results[i])  # type: ignore[arg-type]
        return results  # type: ignore[return-value]
    # longest runs first keeps every worker busy until the end
    order = sorted(range(len(specs)), key=lambda i: -specs[i].contour_model().duration)
    with dask_client(scheduler, workers) as client:
        tasks = run_tasks(client, simulate, [(specs[i],) for i in order])
        for done, (k, result) in enumerate(tasks, start=1):
            results[order[k]] = result
            if progress:
                progress(done, len(specs), result)
    return results  # type: ignore[return-value]
