"""Per-goal figures of a real arm's run (a graph recording, :mod:`pdsmc_ros.bag.graph`).

For each action goal: the tracking error against the controller's desired state, the time to
settle, the largest joint velocity against the arm's limits, the torque and its scores,
the saturated and late periods, and the goal's result. Where a simulated run has the same
figure, it comes from the same code (:class:`~pdsmc_ros.metrics.statistics.RunStatistics`): the axial
error statistics (mean and population S.D. of ``|q_d - q|``), the largest torque, the
saturated periods (``|tau| >= effort limit``, as ``pdsmc analyze`` counts a recorded run's)
and the scores of :mod:`pdsmc_ros.metrics.scores`.

The signals are put on an even grid at the joint states' rate from the goal's first desired
state to its end (the scores need one): the measured position linearly interpolated, the
torque the driver reported held from one state to the next (what the arm got), the desired
state a cubic Hermite curve through the controller's samples (positions and velocities:
``~/controller_state``'s reference or the goal's feedback, joint_trajectory_controller's
20 Hz), exact for the cubic segments JTC interpolates and within a few micro-radians of a
quintic at 20 Hz.

Where the desired-state samples leave a gap longer than :data:`MAX_REFERENCE_GAP` within the
goal, it gets no tracking figures (the reason is in its ``reference``).

Settling: the first instant after which every joint stays within ``settle_band`` of the goal's
last desired position, up to the next goal (or the end of the bag), counted from the end of
the desired motion; None when the arm is not there by then (an aborted or preempted goal).
A late period is an interval between two joint states longer than :data:`LATE_FACTOR`
nominal periods: at least one state missed, as the loop statistics count a missed deadline.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..bag.graph import GoalRecord, GraphRun, ReferenceSamples
from ..errors import InvalidInputError
from ..metrics.statistics import Metrics, RunStatistics
from ..robots.base import FloatArray

DEFAULT_SETTLE_BAND = 0.01
"""rad: a joint within this of the goal's last desired position counts as settled."""
LATE_FACTOR = 2.0
REFERENCE_STILL = 1e-6  # rad: the desired motion has ended once the desired position stays this close to its last
MAX_REFERENCE_GAP = 0.2
"""s: the longest interval between desired-state samples a curve is drawn across (four of
joint_trajectory_controller's 20 Hz periods); a controller that published more sparsely over a
goal (a loaded machine) gets no tracking figures for it, rather than errors against a made-up curve."""


def nominal_period(t: FloatArray) -> float:
    """The joint states' nominal period: the median interval between stamps (s)."""
    steps = np.diff(np.asarray(t, dtype=float))
    steps = steps[steps > 0]
    if not len(steps):
        raise InvalidInputError("the joint states need at least two distinct stamps for a rate")
    return float(np.median(steps))


def late_periods(t: FloatArray, period: float) -> int:
    """Intervals between consecutive stamps longer than :data:`LATE_FACTOR` periods."""
    return int(np.sum(np.diff(np.asarray(t, dtype=float)) > LATE_FACTOR * period))


def desired_at(reference: ReferenceSamples, t: FloatArray) -> FloatArray:
    """Desired positions at ``t``: a cubic Hermite curve through the samples' positions and
    velocities, the first and last held outside them."""
    t = np.asarray(t, dtype=float)
    rt, q, qd = reference.t, reference.q, reference.qd
    if len(rt) == 1:
        return np.repeat(q[:1], len(t), axis=0)
    i = np.clip(np.searchsorted(rt, t, side="right") - 1, 0, len(rt) - 2)
    h = (rt[i + 1] - rt[i])[:, None]
    s = np.clip((t - rt[i])[:, None] / np.where(h > 0, h, 1.0), 0.0, 1.0)
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return h00 * q[i] + h10 * h * qd[i] + h01 * q[i + 1] + h11 * h * qd[i + 1]


@dataclass
class GoalFigures:
    """One goal's figures (times in s from the bag's first joint state)."""

    index: int
    action: str
    goal_id: str
    status: str
    result: str
    error_string: str
    start: float
    end: float | None
    reference: str  # where the desired state came from
    metrics: Metrics | None  # the simulated run's figures: axial errors, torque, saturation, scores
    error_max: list[float]
    reference_end: float | None
    settle_time: float | None
    velocity_max: list[float]
    velocity_limit: list[float]
    late_periods: int
    trajectory: str = "not recorded"  # the goal's own trajectory (its send_goal event): points and duration

    @property
    def label(self) -> str:
        return f"goal {self.index} ({self.status})"

    @property
    def velocity_share(self) -> list[float]:
        """The largest velocity of each joint as a share of its limit."""
        return [v / limit if limit > 0 else float("nan") for v, limit in zip(self.velocity_max, self.velocity_limit,
                                                                              strict=True)]

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["metrics"] = None if self.metrics is None else self.metrics.as_dict()
        out["velocity_share"] = self.velocity_share
        return out


def _window(t: FloatArray, start: float, end: float) -> np.ndarray:
    return np.flatnonzero((t >= start) & (t <= end))


def goal_figures(run: GraphRun, goal: GoalRecord, index: int, window_end: float, *,
                 velocity_limits: Sequence[float] | FloatArray, effort_limits: Sequence[float] | FloatArray,
                 settle_band: float = DEFAULT_SETTLE_BAND) -> GoalFigures:
    """The figures of ``goal`` (the ``index``-th), whose effects last until ``window_end`` (the
    next goal's acceptance or the bag's end).

    Raises
    ------
    InvalidInputError
        If the limits do not match the run's joints or ``settle_band`` is not positive.
    """
    n = len(run.names)
    velocity_limit = np.asarray(velocity_limits, dtype=float)
    effort_limit = np.asarray(effort_limits, dtype=float)
    if velocity_limit.shape != (n,) or effort_limit.shape != (n,):
        raise InvalidInputError(f"the limits need one value per joint ({n}); got {velocity_limit.shape}, "
                                f"{effort_limit.shape}")
    if not settle_band > 0:
        raise InvalidInputError(f"the settle band must be > 0 rad, got {settle_band!r}")
    t0 = float(run.t[0])
    period = nominal_period(run.t)
    end = goal.ended if goal.ended is not None else window_end
    # the denser of the goal's feedback and the controller's state over the goal
    shown = _window(run.reference.t, goal.accepted, end)
    reference = ReferenceSamples(run.reference.t[shown], run.reference.q[shown], run.reference.qd[shown])
    source = "controller_state"
    if goal.desired is not None and len(goal.desired.t) >= max(2, len(reference.t)):
        reference, source = goal.desired, "feedback"
    planned = goal.trajectory
    if planned is not None and len(reference.t) < 2 <= len(planned.t):
        # neither feedback nor controller state recorded: the goal's points, as the client sent them
        reference, source = planned, "goal trajectory"
    whole = _window(run.t, goal.accepted, window_end)
    velocity_max = (np.nanmax(np.abs(run.qd[whole]), axis=0) if len(whole) else np.full(n, np.nan))
    late = late_periods(run.t[whole], period) if len(whole) else 0
    metrics, error_max, reference_end, settle = None, [float("nan")] * n, None, None
    if len(reference.t) >= 2 and np.isfinite(reference.q).all():
        source = f"{source} ({len(reference.t)} samples)"
        start = max(float(reference.t[0]), goal.accepted)
        steps = int(np.floor((end - start) / period))
        inside = reference.t[(reference.t >= start) & (reference.t <= end)]
        gap = float(np.max(np.diff(np.concatenate([[start], inside, [end]])))) if steps >= 1 else 0.0
        if gap > MAX_REFERENCE_GAP:
            source = f"{source}; a gap of {gap:.3f} s: too sparse for tracking figures"
            steps = 0
        if steps >= 1:
            grid: FloatArray = start + np.arange(steps + 1, dtype=float) * period
            q = np.column_stack([np.interp(grid, run.t, run.q[:, j]) for j in range(n)])
            held = np.clip(np.searchsorted(run.t, grid, side="right") - 1, 0, len(run.t) - 1)
            tau = run.effort[held]
            error = desired_at(reference, grid) - q
            stats = RunStatistics(n, bound=np.inf, rate=1.0 / period)
            stats.add(error, np.zeros((len(grid), 2)), np.zeros(len(grid)), tau)
            stats.add_steps(error, tau)
            active = _window(run.t, start, end)
            with np.errstate(invalid="ignore"):
                saturated = (np.abs(run.effort[active]) >= effort_limit).sum(axis=0)
            metrics = stats.metrics([int(c) for c in saturated])
            error_max = np.nanmax(np.abs(error), axis=0).tolist()
        final = reference.q[-1]
        moving = np.flatnonzero(np.any(np.abs(reference.q - final) > REFERENCE_STILL, axis=1))
        reference_end = float(reference.t[moving[-1] + 1] if len(moving) else reference.t[0])
        if len(whole):
            out = np.flatnonzero(np.any(np.abs(run.q[whole] - final) > settle_band, axis=1))
            if not len(out):
                settle = 0.0
            elif out[-1] + 1 < len(whole):
                settle = max(0.0, float(run.t[whole[out[-1] + 1]]) - reference_end)
        reference_end -= t0
    elif len(reference.t):
        source = f"{source} ({len(reference.t)} sample: too few)"
    else:
        source = "none recorded"
    return GoalFigures(index, goal.action, goal.goal_id, goal.status_name, goal.result_name, goal.error_string,
                       goal.accepted - t0, None if goal.ended is None else goal.ended - t0, source, metrics,
                       [float(v) for v in error_max], reference_end, settle,
                       [float(v) for v in velocity_max], velocity_limit.tolist(), late, _trajectory_line(goal))


def _trajectory_line(goal: GoalRecord) -> str:
    """The goal's own trajectory in a few words (its send_goal event), or "not recorded"."""
    planned = goal.trajectory
    if planned is None or goal.trajectory_points is None:
        return "not recorded"
    span = float(planned.t[-1] - goal.accepted) if len(planned.t) else 0.0
    return f"{goal.trajectory_points} points over {span:.3f} s"



def run_goal_figures(run: GraphRun, *, velocity_limits: Sequence[float] | FloatArray,
                     effort_limits: Sequence[float] | FloatArray,
                     settle_band: float = DEFAULT_SETTLE_BAND) -> list[GoalFigures]:
    """:func:`goal_figures` of every goal of ``run``, each until the next one's acceptance."""
    out = []
    last = float(run.t[-1])
    for i, goal in enumerate(run.goals):
        window_end = run.goals[i + 1].accepted if i + 1 < len(run.goals) else last
        out.append(goal_figures(run, goal, i + 1, window_end, velocity_limits=velocity_limits,
                                effort_limits=effort_limits, settle_band=settle_band))
    return out
