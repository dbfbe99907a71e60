"""Tracking and contouring statistics as the thesis's tables compute them.

One implementation serves the in-process simulator and the bag analysis
(docs/THESIS_NOTES.md section 4): means and population standard deviations of ABSOLUTE
errors over the sampled instants; axial errors per actuated joint
(``e = q_d - q``); task-space |x error|, |y error| and the error magnitude;
contour error (Eqs. 2.9 / 2.10); share of samples within the contour bound;
maximum |torque| per actuated joint; and (not thesis statistics) the control periods
in which each joint's torque was clamped to its limit and the scores of :mod:`.scores`
(tracking, chattering, effort) of the same samples (:func:`sample_scores`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .errors import InvalidInputError
from .robots.base import FloatArray
from .scores import SCORE_NAMES, Scores, compute_scores


@dataclass(frozen=True)
class Metrics:
    """Statistics of one run (units: rad, m, %, N m)."""

    axial_mean: list[float]
    axial_sd: list[float]
    task_mean: dict[str, float]
    task_sd: dict[str, float]
    contour_mean: float
    contour_sd: float
    contour_bound: float
    contour_within_pct: float
    max_torque: list[float]
    samples: int
    # S.D. of the SIGNED task-space errors (x, y): not a thesis statistic, but the thesis's
    # PD-SMC x-axis S.D. column matches it on every arm and contour (docs/REPRODUCTION.md)
    task_sd_signed: dict[str, float]
    # control periods (all of them, not only the sampled instants) in which each joint's torque
    # was clamped to its effort limit
    saturated_periods: list[int] = field(default_factory=list)
    # scores beside the errors (:mod:`.scores`, docs/SCORES.md), per joint and for the run
    # (``run_scores``), from the statistics samples (:func:`sample_scores`); empty without them
    error_rms: list[float] = field(default_factory=list)
    error_itae: list[float] = field(default_factory=list)
    torque_tv_rate: list[float] = field(default_factory=list)
    torque_hf_share: list[float] = field(default_factory=list)
    control_energy: list[float] = field(default_factory=list)
    torque_rate_peak: list[float] = field(default_factory=list)
    run_scores: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Samples:
    """Sampled signals of a run, each row one statistics instant."""

    t: FloatArray  # (S,)
    q: FloatArray  # (S, n) actual actuated joints
    q_ref: FloatArray  # (S, n) desired actuated joints
    xy: FloatArray  # (S, 2) actual end-effector
    xy_ref: FloatArray  # (S, 2) desired end-effector
    tau: FloatArray  # (S, n) applied torque
    contour_error: FloatArray  # (S,)

    @classmethod
    def empty(cls, n: int) -> Samples:
        """No instant, for ``n`` joints (a run that kept none: ``simulate(keep_samples=False)``)."""
        return cls(t=np.zeros(0), q=np.zeros((0, n)), q_ref=np.zeros((0, n)), xy=np.zeros((0, 2)),
                   xy_ref=np.zeros((0, 2)), tau=np.zeros((0, n)), contour_error=np.zeros(0))


def build_samples(
    robot: Any,
    contour: object,
    t: FloatArray,
    q: FloatArray,
    q_ref: FloatArray,
    tau: FloatArray,
    *,
    xy_ref: FloatArray | None = None,
) -> Samples:
    """Samples (actual and desired task points, contour error) from joint signals of ``robot``
    (a :class:`~pdsmc_ros.robots.base.Manipulator`: its ``position``) on ``contour``;
    ``xy_ref``: the desired task points at ``t`` if already known (``contour.task(t)``)."""
    xy = robot.position(q)
    if xy_ref is None:
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


def sample_times(duration: float, sample_rate: float) -> FloatArray:
    """Statistics instants ``0, 1/f, ..., T`` (inclusive; 2501 for 5 s at 500 Hz)."""
    count = int(round(duration * sample_rate))
    return np.arange(count + 1) / sample_rate


def compute_metrics(samples: Samples, bound: float, *, saturated: Sequence[int] = (),
                    scores: Scores | None = None) -> Metrics:
    """Thesis-style statistics of sampled signals (docs/THESIS_NOTES.md section 4); ``saturated``: the
    clamped periods of each joint, counted by the loop (every period, not only the samples);
    ``scores``: the run's scores (:func:`sample_scores`).

    Raises
    ------
    InvalidInputError
        If there is no sample (every statistic would be undefined).
    """
    return error_metrics(samples.q_ref - samples.q, samples.xy_ref - samples.xy, samples.contour_error,
                         samples.tau, bound, saturated=saturated, scores=scores)


def error_metrics(axial_error: FloatArray, task_error: FloatArray, contour_error: FloatArray, tau: FloatArray,
                  bound: float, *, saturated: Sequence[int] = (), scores: Scores | None = None) -> Metrics:
    """:func:`compute_metrics` from the errors alone (what a run that keeps no samples keeps):
    ``axial_error = q_d - q`` (S, n), ``task_error = p_d - p`` (S, 2), the contour error (S,) and
    the applied torque (S, n) at the statistics instants.

    Raises
    ------
    InvalidInputError
        If there is no sample (every statistic would be undefined).
    """
    if not len(contour_error):
        raise InvalidInputError("statistics need at least one sampled instant; got none")
    axial = np.abs(axial_error)
    ex = np.abs(task_error[:, 0])
    ey = np.abs(task_error[:, 1])
    total = np.hypot(ex, ey)
    eps = np.abs(contour_error)
    return Metrics(
        axial_mean=axial.mean(axis=0).tolist(),
        axial_sd=axial.std(axis=0).tolist(),
        task_mean={"x": float(ex.mean()), "y": float(ey.mean()), "total": float(total.mean())},
        task_sd={"x": float(ex.std()), "y": float(ey.std()), "total": float(total.std())},
        contour_mean=float(eps.mean()),
        contour_sd=float(eps.std()),
        contour_bound=float(bound),
        contour_within_pct=float(100.0 * np.mean(eps <= bound)),
        max_torque=np.max(np.abs(tau), axis=0).tolist(),
        samples=int(len(contour_error)),
        task_sd_signed={"x": float(np.std(task_error[:, 0])), "y": float(np.std(task_error[:, 1]))},
        saturated_periods=[int(c) for c in saturated],
        **score_fields(scores),
    )


def sample_scores(samples: Samples, rate: float) -> Scores | None:
    """The scores (:func:`pdsmc_ros.scores.compute_scores`) of the statistics samples, taken at
    ``rate`` Hz: the error at every sample, the torque of every sample but the last (the run's
    closing command, never applied) held until the next. None with fewer than two samples or
    samples not evenly ``1/rate`` apart (a bag with missing steps): the scores need every instant."""
    return error_scores(samples.t, samples.q_ref - samples.q, samples.tau, rate)


def error_scores(t: FloatArray, axial_error: FloatArray, tau: FloatArray, rate: float) -> Scores | None:
    """:func:`sample_scores` from the instants, ``q_d - q`` and the torque at them."""
    if len(t) < 2 or not np.allclose(np.diff(t), 1.0 / rate, rtol=1e-9, atol=0.0):
        return None
    return compute_scores(axial_error, tau[:-1], rate)


def score_fields(scores: Scores | None) -> dict[str, Any]:
    """:class:`Metrics`' score fields of ``scores`` (none: empty)."""
    if scores is None:
        return {}
    out: dict[str, Any] = {name: list(getattr(scores, name)) for name in SCORE_NAMES}
    out["run_scores"] = {**scores.run, "cutoff_hz": scores.cutoff_hz, "rate_hz": scores.rate_hz}
    return out
