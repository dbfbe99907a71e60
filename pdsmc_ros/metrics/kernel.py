"""The statistics and scores of a run, accumulated instant by instant (compiled).

:class:`pdsmc_ros.metrics.statistics.RunStatistics` calls :func:`accumulate_instants` on consecutive
blocks of the statistics instants (the thesis's statistics) and :func:`accumulate_steps` on
consecutive blocks of the control steps (the scores): a run's signals at once, or a long run's
stretches one by one (:mod:`pdsmc_ros.sim.stretches`). Every quantity is updated row by row in
the run's order, so the result does not depend on how the rows are split into blocks, and memory
does not grow with the run: the means and population variances are Welford's (1962) running
ones, the sums are compensated (Neumaier 1974), the maxima propagate a NaN as ``np.max`` does.

The accumulator's arrays (all float64 unless said, ``n`` joints):

- ``moments``, ``(2, n + 6)``: running mean and sum of squared deviations of ``|q_d - q|`` (n),
  ``|x error|``, ``|y error|``, the task error's magnitude, ``|contour error|``, and the signed
  x and y errors, over the statistics instants;
- ``sums``, ``(2, 4 n + 2)``: compensated sums (value, compensation) over the control steps of
  ``e_i^2`` (n), ``|e|^2`` (1), the trapezoid terms of ``t |e_i|`` and ``t |e|`` (n + 1), ``u_i^2``
  (n) and ``|u_k - u_{k-1}|`` (n);
- ``last``, ``(3, n + 1)``: the previous step's ``t |e_i|``, ``t |e|``; the torque of the newest
  step (applied only if another follows: the run's closing command never is); the previous
  applied torque;
- ``peaks``, ``(2, n)``: ``max |u_i|`` over the statistics instants, ``max |u_k - u_{k-1}|`` over
  the applied periods;
- ``counts``, int64 ``(3,)``: instants seen, instants within the contour bound, steps seen.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels.options import ALLOCATION_FREE

MOMENT_COLUMNS = 6
"""Columns of ``moments`` after the joints' (x, y, magnitude, contour, signed x, signed y)."""


def new_accumulator(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Empty ``moments, sums, last, peaks, counts`` for ``n`` joints."""
    return (np.zeros((2, n + MOMENT_COLUMNS)), np.zeros((2, 4 * n + 2)), np.zeros((3, n + 1)),
            np.zeros((2, n)), np.zeros(3, dtype=np.int64))


@njit(cache=True, inline="always")
def _add(sums, j, x):  # noqa: ANN001, ANN202
    """``sums[0, j] += x`` with Neumaier's compensation kept in ``sums[1, j]``."""
    s = sums[0, j]
    t = s + x
    if math.isinf(t):  # the compensation would turn an overflow into NaN
        sums[0, j] = t
        return
    if abs(s) >= abs(x):
        sums[1, j] += (s - t) + x
    else:
        sums[1, j] += (x - t) + s
    sums[0, j] = t


@njit(cache=True, inline="always")
def _moment(moments, j, count, x):  # noqa: ANN001, ANN202
    """Welford's update of column ``j``'s mean and squared deviations with its ``count``-th value."""
    delta = x - moments[0, j]
    moments[0, j] += delta / count
    moments[1, j] += delta * (x - moments[0, j])


@njit(cache=True, inline="always")
def _peak(peaks, row, j, x):  # noqa: ANN001, ANN202
    """``peaks[row, j] = max(peaks[row, j], x)``, a NaN kept once seen (as ``np.max``)."""
    p = peaks[row, j]
    if p != p:
        return
    if x != x or x > p:
        peaks[row, j] = x


@njit(**ALLOCATION_FREE)
def accumulate_instants(moments, peaks, counts, axial, task, contour, tau, bound):  # noqa: ANN001, ANN201, PLR0913
    """Add the consecutive statistics instants ``axial = q_d - q`` (m, n), ``task = p_d - p``
    (m, 2), the contour error (m,) and the torque (m, n); ``bound`` is the contour bound."""
    n = axial.shape[1]
    for r in range(axial.shape[0]):
        count = counts[0] + 1
        counts[0] = count
        for i in range(n):
            _moment(moments, i, count, abs(axial[r, i]))
            _peak(peaks, 0, i, abs(tau[r, i]))
        ex = task[r, 0]
        ey = task[r, 1]
        _moment(moments, n, count, abs(ex))
        _moment(moments, n + 1, count, abs(ey))
        _moment(moments, n + 2, count, math.hypot(ex, ey))
        eps = abs(contour[r])
        _moment(moments, n + 3, count, eps)
        _moment(moments, n + 4, count, ex)
        _moment(moments, n + 5, count, ey)
        if eps <= bound:
            counts[1] += 1


@njit(**ALLOCATION_FREE)
def accumulate_steps(sums, last, peaks, counts, error, tau, h):  # noqa: ANN001, ANN201, PLR0913
    """Add the consecutive control steps ``error = q_d - q`` (m, n) and their torque (m, n); ``h``
    is the control period (step ``k`` at ``k h``)."""
    n = error.shape[1]
    norm_col = n
    itae_col = n + 1
    energy_col = 2 * n + 2
    tv_col = 3 * n + 2
    for r in range(error.shape[0]):
        k = counts[2]  # this step's index in the run
        counts[2] = k + 1
        t = k * h
        squares = 0.0
        for i in range(n):
            e = error[r, i]
            _add(sums, i, e * e)
            squares += e * e
            w = t * abs(e)
            if k >= 1:
                _add(sums, itae_col + i, last[0, i] + w)
            last[0, i] = w
        _add(sums, norm_col, squares)
        w = t * math.sqrt(squares)
        if k >= 1:
            _add(sums, itae_col + n, last[0, n] + w)
        last[0, n] = w
        for i in range(n):
            if k >= 1:  # the previous step's torque was applied over the period up to this one
                applied = last[1, i]
                _add(sums, energy_col + i, applied * applied)
                if k >= 2:
                    step = abs(applied - last[2, i])
                    _add(sums, tv_col + i, step)
                    _peak(peaks, 1, i, step)
                last[2, i] = applied
            last[1, i] = tau[r, i]
