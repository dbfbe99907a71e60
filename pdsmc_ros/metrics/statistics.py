"""Tracking and contouring statistics as the thesis's tables compute them.

One implementation serves the in-process simulator and the bag analysis
(docs/THESIS_NOTES.md section 4): means and population standard deviations of ABSOLUTE
errors over the sampled instants; axial errors per actuated joint
(``e = q_d - q``); task-space |x error|, |y error| and the error magnitude;
contour error (Eqs. 2.9 / 2.10); share of samples within the contour bound;
maximum |torque| per actuated joint; and (not thesis statistics) the control periods
in which each joint's torque was clamped to its limit and the scores of :mod:`.scores`
(tracking, chattering, effort) of every control step (:meth:`RunStatistics.add_steps`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..checks import is_real, is_whole
from ..errors import InvalidInputError
from ..robots.base import FloatArray
from .kernel import accumulate_instants, accumulate_steps, new_accumulator
from .scores import DEFAULT_CUTOFF_HZ, SCORE_NAMES, Scores, high_frequency_power, high_frequency_share


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


def compute_metrics(samples: Samples, bound: float, *, saturated: Sequence[int] = ()) -> Metrics:
    """Thesis-style statistics of sampled signals (docs/THESIS_NOTES.md section 4), without scores;
    ``saturated``: the clamped periods of each joint, counted by the loop (every period, not only
    the samples). A run's scores come from its control steps (:meth:`RunStatistics.add_steps`).

    Raises
    ------
    InvalidInputError
        If there is no sample (every statistic would be undefined).
    """
    stats = RunStatistics(samples.q.shape[1], bound=bound)
    stats.add_samples(samples)
    return stats.metrics(saturated)


def _number(value: object) -> float:
    """``value`` as a float if it is a real number (not a bool), else NaN."""
    if not is_real(value):
        return math.nan
    return float(value)


def _positive(value: object) -> bool:
    """A finite real number above zero."""
    number = _number(value)
    return math.isfinite(number) and number > 0.0


SPECTRUM_SEGMENT = 1 << 17
"""Control steps of a segment of the high-frequency share's spectrum (Welch 1967): a run of at most
this many applied periods (26 s at 5 kHz, 131 s at 1 kHz) is one segment, the DFT of the whole run;
a longer one averages the power of consecutive segments (bins of ``rate / 131,072``: 0.08 Hz at
10 kHz), so that only one segment of torque is kept however long the run."""


class RunStatistics:
    """A run's statistics and scores, accumulated over consecutive blocks of its signals.

    The thesis's statistics come from its statistics instants (:meth:`add`, :meth:`add_samples`),
    the scores (:mod:`pdsmc_ros.metrics.scores`) from its control steps (:meth:`add_steps`): the torque of
    every period, so that switching faster than the statistics' rate is seen. The same numbers
    whether the signals come at once or a stretch at a time (:mod:`pdsmc_ros.sim.stretches`):
    every sum runs row by row in the run's order (:mod:`.metrics_kernel`), the spectrum's segments
    start at fixed steps. Memory does not grow with the run (one spectrum segment of torque is kept).

    Parameters
    ----------
    joints : int
        Actuated joints ``n``.
    bound : float
        The contour bound of ``contour_within_pct``, m.
    rate : float, optional
        The control rate (Hz; step ``k`` at ``k / rate``): the steps added are scored; None:
        statistics only.
    cutoff : float
        The high-frequency share's cutoff, Hz.

    Raises
    ------
    InvalidInputError
        If ``joints`` is not a positive integer, or ``rate``/``cutoff`` is not a positive number.
    """

    def __init__(self, joints: int, *, bound: float, rate: float | None = None,
                 cutoff: float = DEFAULT_CUTOFF_HZ) -> None:
        if not is_whole(joints) or joints < 1:
            raise InvalidInputError(f"joints must be a positive integer, got {joints!r}")
        if not (rate is None or _positive(rate)) or not _positive(cutoff):
            raise InvalidInputError(f"scores need a positive rate and cutoff; got rate {rate!r} Hz, "
                                    f"cutoff {cutoff!r} Hz")
        if not _number(bound) >= 0.0:
            raise InvalidInputError(f"the contour bound must be a number >= 0 (m), got {bound!r}")
        self.joints = int(joints)
        self.bound = float(bound)
        self.rate = None if rate is None else float(rate)
        self.cutoff = float(cutoff)
        # the accumulator's arrays (metrics_kernel's docstring)
        self._moments, self._sums, self._last, self._peaks, self._counts = new_accumulator(self.joints)
        self._pending: list[FloatArray] = []  # the torque of the steps of the spectrum's open segment
        self._pending_rows = 0
        self._high = np.zeros(self.joints)  # summed over closed segments, each of its power per step
        self._power = np.zeros(self.joints)

    @property
    def instants(self) -> int:
        """Statistics instants added so far."""
        return int(self._counts[0])

    @property
    def steps(self) -> int:
        """Control steps added so far."""
        return int(self._counts[2])

    @staticmethod
    def _rows(name: str, values: FloatArray, count: int | None, width: int) -> FloatArray:
        """``values`` as C-contiguous floats, checked to be ``count`` rows (any if None) of ``width``."""
        rows = np.ascontiguousarray(values, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != width or (count is not None and rows.shape[0] != count):
            expected = f"{'m' if count is None else count} rows of {width}"
            raise InvalidInputError(f"{name} must be {expected}; got shape {rows.shape}")
        return rows

    def add(self, axial_error: FloatArray, task_error: FloatArray, contour_error: FloatArray,
            tau: FloatArray) -> None:
        """Add ``m`` consecutive statistics instants: ``q_d - q`` (m, n), ``p_d - p`` (m, 2 or more:
        x and y are read), the contour error (m,) and the torque (m, n) commanded at each.

        Raises
        ------
        InvalidInputError
            If the shapes disagree (nothing is added).
        """
        contour = np.ascontiguousarray(contour_error, dtype=float)
        if contour.ndim != 1:
            raise InvalidInputError(f"the contour error must be one row of m values; got shape {contour.shape}")
        m, n = len(contour), self.joints
        axial = self._rows("q_d - q", axial_error, m, n)
        task = self._rows("p_d - p", np.asarray(task_error, dtype=float)[..., :2], m, 2)
        torque = self._rows("the torque", tau, m, n)
        accumulate_instants(self._moments, self._peaks, self._counts, axial, task, contour, torque, self.bound)

    def add_samples(self, samples: Samples) -> None:
        """:meth:`add` the instants of ``samples``."""
        self.add(samples.q_ref - samples.q, samples.xy_ref - samples.xy, samples.contour_error, samples.tau)

    def add_steps(self, error: FloatArray, tau: FloatArray) -> None:
        """Add ``m`` consecutive control steps: ``q_d - q`` (m, n) and the torque commanded at each
        (applied over the period that follows, but the run's last: its closing command).

        Raises
        ------
        InvalidInputError
            Without a rate, or if the shapes disagree (nothing is added).
        """
        if self.rate is None:
            raise InvalidInputError("scoring control steps needs the control rate (RunStatistics(rate=...))")
        errors = self._rows("q_d - q", error, None, self.joints)
        m = errors.shape[0]
        torque = self._rows("the torque", tau, m, self.joints)
        accumulate_steps(self._sums, self._last, self._peaks, self._counts, errors, torque, 1.0 / self.rate)
        self._pending.append(torque.copy() if torque is tau else torque)
        self._pending_rows += m
        if self._pending_rows > SPECTRUM_SEGMENT:  # a closed segment is one a later step follows
            rows = np.concatenate(self._pending)
            start = 0
            while len(rows) - start > SPECTRUM_SEGMENT:
                self._add_segment(rows[start : start + SPECTRUM_SEGMENT])
                start += SPECTRUM_SEGMENT
            self._pending = [rows[start:].copy()]
            self._pending_rows = len(rows) - start

    def pad_nan(self, instants: int, steps: int, *, block: int = 1 << 13) -> None:
        """Add NaN instants and steps up to ``instants`` and ``steps`` in all, ``block`` rows at a time:
        the rest of a run that stopped where it diverged, as NaN as its kept samples."""
        n = self.joints
        while self.instants < instants:
            rows = min(instants - self.instants, block)
            nan = np.full((rows, n), np.nan)
            self.add(nan, np.full((rows, 2), np.nan), np.full(rows, np.nan), nan)
        while self.rate is not None and self.steps < steps:
            nan = np.full((min(steps - self.steps, block), n), np.nan)
            self.add_steps(nan, nan)

    def _add_segment(self, torque: FloatArray) -> None:
        high, power = high_frequency_power(torque, float(self.rate), self.cutoff)  # type: ignore[arg-type]
        self._high += high / len(torque)
        self._power += power / len(torque)

    def scores(self) -> Scores | None:
        """The scores of the steps so far (:mod:`pdsmc_ros.metrics.scores`): None without a rate or with
        fewer than two steps (no applied period)."""
        count = self.steps
        if self.rate is None or count < 2:
            return None
        n = self.joints
        total = self._sums[0] + self._sums[1]
        periods = count - 1
        h = 1.0 / self.rate
        itae = 0.5 * h * total[n + 1 : 2 * n + 2]
        energy = total[2 * n + 2 : 3 * n + 2] * h
        tv = total[3 * n + 2 :] / (periods * h)
        peak = self._peaks[1] / h
        high, power = self._high.copy(), self._power.copy()
        applied = np.concatenate(self._pending)[:-1]  # the open segment, less the closing command
        if len(applied):
            segment_high, segment_power = high_frequency_power(applied, self.rate, self.cutoff)
            high += segment_high / len(applied)
            power += segment_power / len(applied)
        run = {
            "error_rms": float(np.sqrt(total[n] / count)),
            "error_itae": float(itae[n]),
            "torque_tv_rate": float(tv.sum()),
            "torque_hf_share": float(high_frequency_share(high.sum(), power.sum())),
            "control_energy": float(energy.sum()),
            "torque_rate_peak": float(peak.max()),
        }
        return Scores(
            error_rms=np.sqrt(total[:n] / count).tolist(),
            error_itae=itae[:n].tolist(),
            torque_tv_rate=tv.tolist(),
            torque_hf_share=high_frequency_share(high, power).tolist(),
            control_energy=energy.tolist(),
            torque_rate_peak=peak.tolist(),
            run=run,
            cutoff_hz=self.cutoff,
            rate_hz=self.rate,
        )

    def metrics(self, saturated: Sequence[int] = ()) -> Metrics:
        """The statistics of the instants so far, and the scores of the steps (with a rate);
        ``saturated``: the clamped periods of each joint, counted by the loop.

        Raises
        ------
        InvalidInputError
            If there is no instant (every statistic would be undefined).
        """
        count = self.instants
        if not count:
            raise InvalidInputError("statistics need at least one sampled instant; got none")
        n = self.joints
        mean = self._moments[0]
        sd = np.sqrt(self._moments[1] / count)
        return Metrics(
            axial_mean=mean[:n].tolist(),
            axial_sd=sd[:n].tolist(),
            task_mean={"x": float(mean[n]), "y": float(mean[n + 1]), "total": float(mean[n + 2])},
            task_sd={"x": float(sd[n]), "y": float(sd[n + 1]), "total": float(sd[n + 2])},
            contour_mean=float(mean[n + 3]),
            contour_sd=float(sd[n + 3]),
            contour_bound=self.bound,
            contour_within_pct=float(100.0 * (self._counts[1] / count)),
            max_torque=self._peaks[0].tolist(),
            samples=count,
            task_sd_signed={"x": float(sd[n + 4]), "y": float(sd[n + 5])},
            saturated_periods=[int(c) for c in saturated],
            **score_fields(self.scores()),
        )


def compute_scores(error: FloatArray, torque: FloatArray, rate: float, cutoff: float = DEFAULT_CUTOFF_HZ) -> Scores:
    """The scores of signals (:mod:`pdsmc_ros.metrics.scores`, docs/SCORES.md) through :class:`RunStatistics`.

    Parameters
    ----------
    error : ndarray, shape (N + 1, n)
        ``q_d - q`` at the instants ``t_k = k / rate``, rad.
    torque : ndarray, shape (N, n)
        The applied torque of each period (held over it), N m.
    rate : float
        Sample rate of the signals, Hz.
    cutoff : float
        Frequency above which torque power counts as high-frequency, Hz.

    A NaN in the signals (a diverged run) makes the scores it enters NaN.

    Raises
    ------
    InvalidInputError
        If there is no applied period, the shapes disagree, or ``rate``/``cutoff`` is not positive.
    """
    error = np.asarray(error, dtype=float)
    torque = np.asarray(torque, dtype=float)
    if torque.ndim != 2 or torque.shape[0] < 1 or error.shape != (torque.shape[0] + 1, torque.shape[1]):
        raise InvalidInputError(f"scores need N >= 1 applied torques (N, n) and N + 1 errors (N + 1, n); got torque "
                                f"{torque.shape}, error {error.shape}")
    stats = RunStatistics(torque.shape[1], bound=np.inf, rate=rate, cutoff=cutoff)
    # the closing command of the last instant is never applied: a zero stands in for it
    stats.add_steps(error, np.vstack([torque, np.zeros((1, torque.shape[1]))]))
    scores = stats.scores()
    if scores is None:  # not reached: N >= 1 applied periods were checked above
        raise InvalidInputError("scores need N >= 1 applied periods")
    return scores


def score_fields(scores: Scores | None) -> dict[str, Any]:
    """:class:`Metrics`' score fields of ``scores`` (none: empty)."""
    if scores is None:
        return {}
    out: dict[str, Any] = {name: list(getattr(scores, name)) for name in SCORE_NAMES}
    out["run_scores"] = {**scores.run, "cutoff_hz": scores.cutoff_hz, "rate_hz": scores.rate_hz}
    return out
