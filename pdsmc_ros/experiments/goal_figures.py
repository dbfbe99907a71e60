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

Contour error, where the arm is known: the end effector's distance to the desired path, both in the
plane of the arm's contours (its ``position``, as every contour error of the project), the path the
forward kinematics of the desired joint positions on the grid (:func:`path_distance`). It is the
true arm's when the bag holds the true state (the MuJoCo stand-in's ``~/true_joint_states``), else
the measured one's, and says which (:attr:`GoalFigures.contour_from`).
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
    contour_mean: float | None = None  # m: the end effector's mean distance to the desired path
    contour_max: float | None = None
    contour_from: str = ""  # the joint-state topic the end effector came from (the truth where recorded)

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


def path_distance(points: FloatArray, path: FloatArray) -> FloatArray:
    """Each point's distance to the polyline ``path`` (shapes ``(N, 2)`` and ``(M, 2)``).

    The nearest of a thinned path's vertices (at most 1024) is found first, then the exact
    distance to the segments within one thinning step of it: exact unless the path passes back
    within one such step of itself.
    """
    points = np.asarray(points, dtype=float)
    path = np.asarray(path, dtype=float)
    if len(path) == 1:
        return np.asarray(np.linalg.norm(points - path[0], axis=1), dtype=float)
    stride = max(1, len(path) // 1024)
    coarse = np.arange(0, len(path), stride)
    offsets = np.arange(-stride, stride + 1)
    out = np.empty(len(points))
    for start in range(0, len(points), 256):
        p = points[start:start + 256]
        near = coarse[np.argmin(((p[:, None, :] - path[coarse][None, :, :]) ** 2).sum(-1), axis=1)]
        seg = np.clip(near[:, None] + offsets[None, :], 0, len(path) - 2)
        a, b = path[seg], path[seg + 1]
        ab = b - a
        length2 = (ab ** 2).sum(-1)
        t = np.clip(((p[:, None, :] - a) * ab).sum(-1) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
        closest = a + t[..., None] * ab
        out[start:start + 256] = np.sqrt(((p[:, None, :] - closest) ** 2).sum(-1)).min(axis=1)
    return out


def goal_figures(run: GraphRun, goal: GoalRecord, index: int, window_end: float, *,
                 velocity_limits: Sequence[float] | FloatArray, effort_limits: Sequence[float] | FloatArray,
                 settle_band: float = DEFAULT_SETTLE_BAND, robot: Any = None) -> GoalFigures:
    """The figures of ``goal`` (the ``index``-th), whose effects last until ``window_end`` (the
    next goal's acceptance or the bag's end); with the arm's model (``robot``), its contour error.

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
    contour: tuple[float | None, float | None, str] = (None, None, "")
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
            if robot is not None:
                contour = _contour(run, robot, grid, q, desired_at(reference, grid))
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
                       [float(v) for v in velocity_max], velocity_limit.tolist(), late, _trajectory_line(goal),
                       *contour)


def _contour(run: GraphRun, robot: Any, grid: FloatArray, measured: FloatArray,
             desired: FloatArray) -> tuple[float | None, float | None, str]:
    """The contour error's mean and maximum over ``grid`` and the topic its end effector came from:
    the true state where the bag has it over the whole grid, else the measured one."""
    q, source = measured, run.state_topic
    if run.truth_topic and len(run.truth_t) >= 2 and run.truth_t[0] <= grid[0] and run.truth_t[-1] >= grid[-1]:
        q = np.column_stack([np.interp(grid, run.truth_t, run.truth_q[:, j]) for j in range(q.shape[1])])
        source = f"{run.truth_topic} (the true state)"
    else:
        source = f"{source} (the measured state{'; no true state recorded' if not run.truth_topic else ''})"
    if not (np.isfinite(q).all() and np.isfinite(desired).all()):
        return None, None, source
    distance = path_distance(robot.position(q), robot.position(desired))
    return float(np.mean(distance)), float(np.max(distance)), source


def _trajectory_line(goal: GoalRecord) -> str:
    """The goal's own trajectory in a few words (its send_goal event), or "not recorded"."""
    planned = goal.trajectory
    if planned is None or goal.trajectory_points is None:
        return "not recorded"
    span = float(planned.t[-1] - goal.accepted) if len(planned.t) else 0.0
    return f"{goal.trajectory_points} points over {span:.3f} s"



def run_goal_figures(run: GraphRun, *, velocity_limits: Sequence[float] | FloatArray,
                     effort_limits: Sequence[float] | FloatArray,
                     settle_band: float = DEFAULT_SETTLE_BAND, robot: Any = None) -> list[GoalFigures]:
    """:func:`goal_figures` of every goal of ``run``, each until the next one's acceptance."""
    out = []
    last = float(run.t[-1])
    for i, goal in enumerate(run.goals):
        window_end = run.goals[i + 1].accepted if i + 1 < len(run.goals) else last
        out.append(goal_figures(run, goal, i + 1, window_end, velocity_limits=velocity_limits,
                                effort_limits=effort_limits, settle_band=settle_band, robot=robot))
    return out
