"""A run in stretches that keeps its statistics, not its samples: memory no longer grows with the
reference, the states and the errors of a long run.

:func:`pdsmc_ros.sim.simulate` with ``keep_samples=False``. The loop runs the same steps as in
one call (:func:`~pdsmc_ros.sim.loop.run_loop` carries the state, the law's internal state and the
step count from one stretch to the next); the reference is sampled one stretch at a time, and each
stretch's statistics instants and control steps go into :class:`pdsmc_ros.metrics.statistics.RunStatistics`,
which accumulates them row by row: the same statistics and scores as the run that keeps its
samples, to the last digit (a test runs both). Nothing grows with the run but the process's
bookkeeping (bench/long_run.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..contours import JointReference
from ..control.law import ControlLaw
from ..control.soft_limits import effort_only_table
from ..metrics.statistics import Metrics, RunStatistics, build_samples
from ..robots.base import Manipulator
from ..runs.builder import RunSpec, control_steps
from .divergence import DivergenceCheck
from .loop import LoopOutcome, run_loop

STRETCH_STEPS = 1 << 13
"""Control steps of a stretch (rounded down to whole statistics periods): its reference, its
inverse kinematics' temporaries and its samples take tens of MB for a six-joint arm."""


def run_in_stretches(spec: RunSpec, robot: Manipulator, reference: JointReference,
                     initial_error: ArrayLike | None = None,
                     stretch_steps: int | None = None) -> tuple[Metrics, int, LoopOutcome]:
    """The statistics of ``spec``'s run on ``robot`` and its loop's outcome, without its samples.

    ``stretch_steps``: control steps a stretch (default :data:`STRETCH_STEPS`).

    Returns
    -------
    metrics : Metrics
    steps : int
        Control steps of the run.
    outcome : LoopOutcome
        Saturated periods, limit warnings and divergence over the whole run.
    """
    steps = control_steps(reference.contour.duration, spec.rate)
    every = spec.sample_every
    stretch = max(every, (stretch_steps or STRETCH_STEPS) // every * every)
    count = steps // every + 1
    stats = RunStatistics(robot.n, bound=spec.bound, rate=spec.rate)
    law = ControlLaw.from_spec(spec)
    limit = effort_only_table(robot.effort_limits, robot.n) if spec.enforce_limits else None
    check = DivergenceCheck.for_robot(robot)
    h = 1.0 / spec.rate
    total = LoopOutcome([0] * robot.n)
    q = qd = np.zeros(0)
    for start in range(0, steps + 1, stretch):
        last = start + stretch >= steps + 1
        k = np.arange(start, steps + 1 if last else start + stretch)
        refs = np.ascontiguousarray(reference.sample(k / spec.rate).stacked())
        if start == 0:
            q = refs[0, 0] if initial_error is None else refs[0, 0] + np.asarray(initial_error, dtype=float)
            qd = np.zeros(robot.n)
        out_q, _, out_tau, outcome = run_loop(robot, law, q, refs, h, every, limit, check, qd0=qd, start_step=start,
                                              advance_last=not last, every_step=True)
        q, qd = outcome.end_q, outcome.end_qd
        total.saturated = [a + b for a, b in zip(total.saturated, outcome.saturated, strict=True)]
        total.warnings += outcome.warnings
        samples = build_samples(robot, reference.contour, k[::every] / spec.rate, out_q, refs[::every, 0], out_tau)
        stats.add_samples(samples)
        stats.add_steps(outcome.step_error, outcome.step_tau)
        if outcome.diverged:
            total.diverged, total.diverged_step = outcome.diverged, outcome.diverged_step
            stats.pad_nan(count, steps + 1)  # the rest of the run, NaN as in a run that keeps its samples
            break
    return stats.metrics(total.saturated), steps, total
