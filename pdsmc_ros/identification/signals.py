"""From recorded positions and efforts to the samples the identification fits.

A bag holds each joint's measured position and the effort the driver reports, at the driver's
rate and with its jitter. The identification needs velocities and accelerations too; a drive's
own velocity is often a filtered difference, and differentiating a quantised position twice
amplifies its noise by ``(2 pi f)^2``. So (Swevers et al. 1997; Gautier's "parallel filtering"):

1. resample onto a uniform grid at the median rate (:func:`uniform`);
2. choose the cut-off from the motion itself: the frequency below which
   :data:`BANDWIDTH_ENERGY` of the velocity's energy lies (:func:`motion_bandwidth`; an
   excitation of :mod:`.excitation` has nothing above its highest harmonic), times
   :data:`CUTOFF_FACTOR`;
3. filter positions and efforts alike with a zero-phase Butterworth low-pass (order
   :data:`FILTER_ORDER`, run forwards and backwards: no delay, so the filtered efforts and
   the motion stay aligned), differentiate the filtered positions by central differences;
4. drop the ends the filter cannot see past (:data:`EDGE_PERIODS` periods of the cut-off), and
   mark, per joint, the samples within :data:`REVERSAL_PERIODS` periods of the cut-off of a
   reversal of its velocity (:attr:`Prepared.moving` false): there the filter has smeared the
   step of Coulomb friction over time that ``sign(qd)`` does not have, and a real joint sticks;
   its torque equation is left out of the fit there (a dead zone, as Swevers et al.);
5. keep every ``k``-th sample, ``k`` such that the kept rate is :data:`KEPT_PER_CUTOFF` times
   the cut-off: what is left of the noise above the cut-off is gone, and the kept samples'
   errors are nearly independent, which the standard errors assume.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots.base import FloatArray

__all__ = ["BANDWIDTH_ENERGY", "CUTOFF_FACTOR", "Prepared", "motion_bandwidth", "prepare", "uniform"]

BANDWIDTH_ENERGY = 0.999
"""Share of the velocities' energy below the motion's bandwidth."""
CUTOFF_FACTOR = 5.0
"""Cut-off / bandwidth: a 4th-order Butterworth run both ways passes the bandwidth with a gain
of ``1 / (1 + 5^-8)``, 3e-6 short of one."""
FILTER_ORDER = 4
EDGE_PERIODS = 3.0
"""Seconds dropped at each end, in periods of the cut-off."""
KEPT_PER_CUTOFF = 2.5
"""The identification rate, in multiples of the cut-off."""
REVERSAL_PERIODS = 1.0
"""Half-width of the dead zone around a velocity reversal, in periods of the cut-off."""


def uniform(t: ArrayLike, *signals: ArrayLike) -> tuple[FloatArray, float, list[FloatArray]]:
    """``(t, rate, signals)`` on a uniform grid at the median rate of ``t`` (linear interpolation).

    Raises
    ------
    InvalidInputError
        Fewer than 3 samples, or times that do not increase.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        raise InvalidInputError(f"too few samples ({t.size})")
    step = np.diff(t)
    if np.any(step <= 0.0):
        raise InvalidInputError("sample times do not increase")
    dt = float(np.median(step))
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    out = []
    for s in signals:
        s = np.asarray(s, dtype=float)
        out.append(np.stack([np.interp(grid, t, s[:, j]) for j in range(s.shape[1])], axis=-1))
    return grid, 1.0 / dt, out


def motion_bandwidth(q: FloatArray, rate: float) -> float:
    """The frequency (Hz) below which :data:`BANDWIDTH_ENERGY` of the joint velocities' energy lies
    (all joints together), from the positions' spectrum (a velocity's is ``2 pi f`` times its
    position's)."""
    detrended = q - np.linspace(0.0, 1.0, len(q))[:, None] * (q[-1] - q[0]) - q[0]
    spectrum = np.fft.rfft(detrended, axis=0)
    f = np.fft.rfftfreq(len(q), 1.0 / rate)
    energy = np.sum(np.abs(spectrum) ** 2, axis=1) * f**2
    total = float(energy.sum())
    if total <= 0.0:
        return 0.0
    return float(f[int(np.searchsorted(np.cumsum(energy) / total, BANDWIDTH_ENERGY))])


@dataclass(frozen=True)
class Prepared:
    """The samples the identification fits, and how they were made.

    Attributes
    ----------
    grid : ndarray
        The uniform times (s) of the recording.
    q, qd, qdd, tau : ndarray, shape (len(grid), n)
        Filtered positions, their derivatives and the filtered efforts, at every time of ``grid``.
    keep : ndarray of int
        The kept samples (indices into ``grid``).
    moving : ndarray of bool, shape (len(grid), n)
        Whether each joint is away from its velocity reversals (module docstring).
    rate : float
        The recording's rate (Hz, after :func:`uniform`).
    bandwidth, cutoff : float
        The motion's bandwidth and the filter's cut-off (Hz).
    cutoff_given : bool
        The cut-off was given, not chosen from the bandwidth.
    """

    grid: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    tau: FloatArray
    keep: np.ndarray
    moving: np.ndarray
    rate: float
    bandwidth: float
    cutoff: float
    cutoff_given: bool

    @property
    def kept_rate(self) -> float:
        """The rate of the kept samples (Hz)."""
        return self.rate / float(self.keep[1] - self.keep[0]) if len(self.keep) > 1 else self.rate

    def kept(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray]:
        """``(q, qd, qdd, tau, moving)`` at the kept samples."""
        k = self.keep
        return self.q[k], self.qd[k], self.qdd[k], self.tau[k], self.moving[k]

    def filtered(self, signal: FloatArray) -> FloatArray:
        """``signal`` (on :attr:`grid`) through the same zero-phase filter, at the kept samples: a
        model's torque computed at every time, made comparable with the filtered efforts."""
        sos = scipy.signal.butter(FILTER_ORDER, self.cutoff, btype="low", fs=self.rate, output="sos")
        out: FloatArray = scipy.signal.sosfiltfilt(sos, signal, axis=0)[self.keep]
        return out

    def describe(self) -> str:
        how = "given" if self.cutoff_given else (f"{CUTOFF_FACTOR:g} x the motion's bandwidth {self.bandwidth:.3g} Hz "
                                                  f"({BANDWIDTH_ENERGY:.1%} of the velocities' energy)")
        return (f"zero-phase Butterworth low-pass (order {FILTER_ORDER}, both ways) at {self.cutoff:.3g} Hz ({how}) on "
                f"positions and efforts, central differences, {len(self.keep)} samples kept at {self.kept_rate:.3g} Hz "
                f"of {self.rate:.4g} Hz")


def prepare(t: ArrayLike, q: ArrayLike, tau: ArrayLike, *, cutoff: float | None = None) -> Prepared:
    """Positions and efforts recorded at times ``t`` made into the identification's samples
    (module docstring); ``cutoff`` (Hz) replaces the one chosen from the motion.

    Raises
    ------
    InvalidInputError
        Too few samples, a motion without bandwidth (nothing moved), a cut-off at or above the
        Nyquist frequency, or a run too short to keep anything after the filter's edges.
    """
    grid, rate, (q_u, tau_u) = uniform(t, q, tau)
    bandwidth = motion_bandwidth(q_u, rate)
    if cutoff is None:
        if bandwidth <= 0.0:
            raise InvalidInputError("no joint moved: nothing to identify")
        chosen = CUTOFF_FACTOR * bandwidth
    else:
        chosen = float(cutoff)
    nyquist = 0.5 * rate
    if not (0.0 < chosen < nyquist):
        raise InvalidInputError(f"the filter's cut-off {chosen:.4g} Hz must be in (0, {nyquist:.4g}) Hz (half the "
                                f"{rate:.4g} Hz recording rate)" + ("" if cutoff is not None else
                                                                   ": record faster, or give --cutoff"))
    sos = scipy.signal.butter(FILTER_ORDER, chosen, btype="low", fs=rate, output="sos")
    if len(grid) <= 3 * 2 * len(sos):
        raise InvalidInputError(f"too few samples ({len(grid)}) to filter")
    q_f = scipy.signal.sosfiltfilt(sos, q_u, axis=0)
    tau_f = scipy.signal.sosfiltfilt(sos, tau_u, axis=0)
    dt = 1.0 / rate
    qd = np.gradient(q_f, dt, axis=0)
    qdd = np.gradient(qd, dt, axis=0)
    edge = int(np.ceil(EDGE_PERIODS / chosen * rate))
    every = max(1, int(np.floor(rate / (KEPT_PER_CUTOFF * chosen))))
    keep = np.arange(edge, len(grid) - edge, every)
    if keep.size == 0:
        raise InvalidInputError(f"the run ({grid[-1] - grid[0]:.3g} s) is shorter than the filter's edges "
                                f"({2 * edge * dt:.3g} s at a {chosen:.3g} Hz cut-off)")
    moving = _away_from_reversals(qd, int(np.ceil(REVERSAL_PERIODS / chosen * rate)))
    return Prepared(grid, q_f, qd, qdd, tau_f, keep, moving, rate, bandwidth, chosen, cutoff is not None)


def _away_from_reversals(qd: FloatArray, half_width: int) -> np.ndarray:
    """Per sample and joint: no sign change of the velocity within ``half_width`` samples."""
    sign = np.sign(qd)
    flips = np.zeros(qd.shape, dtype=bool)
    flips[1:] = sign[1:] != sign[:-1]
    flips |= sign == 0.0
    # a flip anywhere in [i - w, i + w]: a running count over a window of 2 w + 1
    counts = np.cumsum(np.vstack([np.zeros((1, qd.shape[1]), dtype=int), flips.astype(int)]), axis=0)
    index = np.arange(len(qd))
    upper = np.minimum(index + half_width + 1, len(qd))
    lower = np.maximum(index - half_width, 0)
    away: np.ndarray = (counts[upper] - counts[lower]) == 0
    return away
