"""Scores beside the errors: tracking, chattering and effort of a run (docs/SCORES.md).

The thesis compares its laws on error statistics and peak torque only (:mod:`.metrics`).
These are the costs a control engineer weighs as well, each per actuated joint and for the
run, of a signal sampled evenly at ``rate`` (a run's control steps, every one of them:
:meth:`pdsmc_ros.metrics.statistics.RunStatistics.add_steps`, docs/SCORES.md). With ``N``
periods of ``h = 1/rate`` (``T = N h``), the tracking error ``e_k = q_d(t_k) - q(t_k)`` at
``k = 0..N`` and the torque ``u_k`` held over ``[t_k, t_{k+1})`` for ``k = 0..N-1`` (the command
at ``t_N`` closes the run and is never applied):

- ``error_rms``: ``sqrt(sum_k e_k^2 / (N + 1))`` (run: of ``|e_k|``, the Euclidean norm);
- ``error_itae``: ``int t |e| dt`` by the trapezoid rule (Graham and Lathrop 1953; run: of ``|e_k|``);
- ``torque_tv_rate``: the total variation per second ``sum_k |u_k - u_{k-1}| / T`` (Skogestad
  2003's TV of the input; run: summed over joints) -- chattering;
- ``torque_hf_share``: the share of the torque's power above ``cutoff`` Hz (default 50 Hz), from
  its discrete Fourier transform by Parseval's relation (run: of the joints' summed power) --
  chattering as the thesis describes it after Slotine and Li (1991): high-frequency torque that
  excites dynamics the model leaves out (Section 2.3.3, Fig. 2.11);
- ``control_energy``: ``int u^2 dt = sum_k u_k^2 h``, exact for the held torque (run: summed);
- ``torque_rate_peak``: ``max_k |u_k - u_{k-1}| / h`` (run: over joints).

:class:`pdsmc_ros.metrics.statistics.RunStatistics` computes them beside the statistics, instant by instant
(compensated sums; only the applied torque is kept, for its spectrum);
:func:`pdsmc_ros.metrics.statistics.compute_scores` scores two signals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..robots.base import FloatArray

DEFAULT_CUTOFF_HZ = 50.0
"""The default cutoff of the high-frequency share (docs/SCORES.md): far above the references'
content (the thesis's contours take seconds: the circle is one 0.2 Hz turn) and far below the
control rates (1 to 10 kHz), so the torque's power above it is switching and noise, not tracking."""

SCORE_NAMES = ("error_rms", "error_itae", "torque_tv_rate", "torque_hf_share", "control_energy",
               "torque_rate_peak")


@dataclass(frozen=True)
class Scores:
    """A run's scores: per joint (lists) and for the run (``run``, keyed by :data:`SCORE_NAMES`)."""

    error_rms: list[float]
    error_itae: list[float]
    torque_tv_rate: list[float]
    torque_hf_share: list[float]
    control_energy: list[float]
    torque_rate_peak: list[float]
    run: dict[str, float]
    cutoff_hz: float
    rate_hz: float


def high_frequency_power(u: FloatArray, rate: float, cutoff: float) -> tuple[FloatArray, FloatArray]:
    """Power of each column of ``u`` (``(N, n)``, sampled at ``rate``) above ``cutoff`` Hz, and in all.

    One-sided DFT ``U_m`` (``m = 0..N//2``, ``f_m = m rate / N``): the power of bin ``m`` is
    ``w_m |U_m|^2`` with ``w_m = 1`` at 0 Hz and at the Nyquist bin of an even ``N``, 2 otherwise,
    so the bins sum to ``N sum_k u_k^2`` (Parseval). Bins strictly above ``cutoff`` count as high.
    """
    count = u.shape[0]
    spectrum = np.fft.rfft(u, axis=0)
    power = spectrum.real ** 2 + spectrum.imag ** 2
    weight = np.full(power.shape[0], 2.0)
    weight[0] = 1.0
    if count % 2 == 0:
        weight[-1] = 1.0
    power *= weight[:, None]
    frequency = np.arange(power.shape[0]) * rate / count
    return power[frequency > cutoff].sum(axis=0), power.sum(axis=0)


def high_frequency_share(high: FloatArray | float, total: FloatArray | float) -> FloatArray:
    """``high / total``, 0 where there is no power at all (a zero torque has no high share)."""
    high, total = np.asarray(high, dtype=float), np.asarray(total, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        share: FloatArray = np.where(total > 0.0, high / np.where(total > 0.0, total, 1.0),
                                     np.where(np.isnan(total), np.nan, 0.0))
    return share
