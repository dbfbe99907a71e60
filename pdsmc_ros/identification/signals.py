"""From recorded positions and efforts to the equations the identification fits.

A bag holds each joint's measured position and the effort the driver reports, at the driver's
rate and with its jitter. The identification needs velocities and accelerations too, and
differentiating a quantised position twice amplifies its noise by ``(2 pi f)^2``: the positions
are low-pass filtered first. The efforts must then be filtered alike, and so must the model they
are compared with -- Gautier's *parallel filtering*: the torque ``tau = Y(q, qd, qdd) pi`` is
linear in the parameters, so filtering ``tau`` and every column of ``Y`` with the same linear
filter keeps the equation exact. Filtering only the efforts would not: Coulomb friction's
``sign(qd)`` steps at each velocity reversal, the filtered efforts smear that step over the
filter's response, and a model with a sharp step is then wrong around every reversal (on a
UR5 excitation with 0.6-7 N m of Coulomb friction and a 2 kg payload, exact data at 1 kHz: that
bias was 5-40 % on the frictions and 5-30 % on the payload with a dead zone of 0.15-1 cut-off
periods; with the regressor filtered too, 0.1 % on the payload and the Coulomb frictions, 0.5 %
on the viscous ones: test/identification/test_identify.py). So:

1. resample onto a uniform grid at the median rate (:func:`uniform`);
2. choose the cut-off from the motion: the frequency below which :data:`BANDWIDTH_ENERGY` of
   the velocities' energy lies (:func:`motion_bandwidth`; an excitation of :mod:`.excitation` has
   nothing above its highest harmonic), times :data:`CUTOFF_FACTOR`;
3. positions: a zero-phase Butterworth low-pass at the cut-off (order :data:`FILTER_ORDER`,
   forwards and backwards: no delay), central differences for velocities and accelerations;
4. the model's columns are evaluated on a grid at :data:`MODEL_PER_CUTOFF` times the cut-off
   (they are smooth: products of the motion's harmonics), except the ``sign(qd)`` of Coulomb
   friction, which steps: that one is formed at the recording's rate and, like the efforts,
   low-passed at :data:`ANTI_ALIAS_PER_CUTOFF` times the cut-off before it is sampled on that
   grid (:meth:`Prepared.stepped`); on that grid the efforts and every column get the same
   zero-phase low-pass at the cut-off (:meth:`Prepared.smooth`);
5. drop the ends the filter cannot see past (:data:`EDGE_PERIODS` periods of the cut-off) and
   keep every ``k``-th sample, the kept rate :data:`KEPT_PER_CUTOFF` times the cut-off: what is
   left of the noise above the cut-off is gone, and the kept samples' errors are nearly
   independent, which the standard errors assume;
6. mark, per joint, the samples within :data:`REVERSAL_PERIODS` periods of the cut-off of a
   reversal of its velocity (:attr:`Prepared.moving`): a real joint sticks there (static
   friction, backlash) in ways ``sign(qd)`` does not model; its equation is left out there
   (a dead zone, as Swevers et al.), and wherever it is slower than :data:`SLOW_SHARE` of its
   peak speed (where a joint sticks) or within :data:`SLOW_GUARD_PERIODS` periods of the cut-off of
   such a stretch (the filter's reach);
7. Coulomb friction's ``sign(qd)`` is taken as ``sat(qd / v_s)`` (:meth:`Prepared.coulomb_sign`),
   linear through zero within a band ``v_s`` of :data:`STICK_SIGMAS` times the filtered velocity's
   noise (:attr:`Prepared.stick_band`): at rest the filtered velocity is the encoder's noise, and
   its sign flips at random between ``+1`` and ``-1``;
8. for the prediction of a held-out run with static friction as the set it is at rest
   (:meth:`Prepared.static_friction_set`): where each joint is at rest (:attr:`Prepared.rest`: the
   slope of a line fitted to the recorded positions on one side of the instant within the band
   ``v_s``, a test that reaches no farther than its window, where the filtered velocity's ringing
   reaches most of a period of the cut-off before each breakaway), and that set carried through
   the same filters as the efforts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots.base import FloatArray

__all__ = ["BANDWIDTH_ENERGY", "CUTOFF_FACTOR", "STICK_SIGMAS", "Prepared", "motion_bandwidth", "prepare",
           "rest_window", "uniform"]

BANDWIDTH_ENERGY = 0.999
"""Share of the velocities' energy below the motion's bandwidth."""
NOISE_FLOOR_FACTOR = 30.0
"""A spectral line of the positions within this many times the white floor's median is noise: a
floor's line (chi-squared of two degrees of freedom) exceeds it with probability ``2^-30``."""
CUTOFF_FACTOR = 5.0
"""Cut-off / bandwidth: a 4th-order Butterworth run both ways passes the bandwidth with a gain
of ``1 / (1 + 5^-8)``, 3e-6 short of one."""
FILTER_ORDER = 4
MODEL_PER_CUTOFF = 20.0
"""The rate the model's columns are evaluated and filtered at, in multiples of the cut-off."""
ANTI_ALIAS_PER_CUTOFF = 8.0
"""The low-pass (in multiples of the cut-off) before what steps or is noisy is sampled on that grid."""
EDGE_PERIODS = 3.0
"""Seconds dropped at each end, in periods of the cut-off."""
KEPT_PER_CUTOFF = 2.5
"""The identification rate, in multiples of the cut-off."""
REVERSAL_PERIODS = 0.1
"""Half-width of the dead zone around a velocity reversal, in periods of the cut-off."""
SLOW_GUARD_PERIODS = 1.0
"""Half-width, in periods of the cut-off, of the guard around each stretch a joint is slower than
:data:`SLOW_SHARE` of its peak speed (where it may stick), left out of the fit with it. While a
joint sticks its torque is static friction anywhere within ``+/- fc``, which the model does not
predict; the zero-phase filter spreads that error over about one period of its cut-off on either
side, into samples that are moving. There the error runs against the acceleration (at a reversal
the true friction lags the model's, which flips at once, while the joint accelerates the other
way), so it read as too little inertia: on the MuJoCo stand-in's bench arms
(docs/how-to/identify.md), with the guard at 0, 0.5 and 1 period, the serial 3R's 0.2 kg payload
came out 0.078, 0.214 and 0.197 kg, the UR5's 2 kg -0.68, +0.10 and -0.07 %. A guard around the
stretches within the Coulomb band only (a joint at rest, not merely slow) left the stick-slip
transitions in: 0.216 kg; around only the slow stretches in which the joint is at rest a while,
0.186 kg. The cost: more of a run in the dead zone (17-37 % of the samples on those arms, 14-27 %
without), so a run needs more periods for :data:`~.estimate.SAMPLES_PER_PARAMETER`; and on exact
data without friction (bench/identification.py) half the equations (610 of 1,300), the condition
number of the fitted ones 880 instead of 265, the worst motor inertia error 4.0 % instead of 1.5 %."""
SLOW_SHARE = 0.05
"""A joint slower than this share of its peak speed is in the dead zone too: there it may stick,
held by a static friction anywhere within ``+/- fc`` that ``fc sign(qd)`` does not model (on the
MuJoCo stand-in's bench UR5 under computed torque the wrists stuck for up to 40 % of a run, and
those samples held most of the residual: the frictions came out 20-160 % off with them)."""
STICK_SIGMAS = 5.0
"""Coulomb friction's band ``v_s``, in standard deviations of the filtered velocity's noise: below
it ``fc sign(qd)`` is taken as ``fc qd / v_s``, a smooth sign as in Gaz et al.'s friction (IEEE
RA-L 2019, a sigmoid in ``qd``) and Karnopp's zero-velocity band (ASME J. Dyn. Syst. 1985). A joint
at rest reads a velocity of the encoder's noise, whose ``sign`` flips at random between ``+fc`` and
``-fc``; through the parallel filter that noise reached the fitted samples beside the dead zone
too. The noise is measured (:func:`velocity_noise`); five of its standard deviations a Gaussian
exceeds with probability 6e-7. On the MuJoCo stand-in's bench UR5 (an 18-bit encoder, filtered at
13 Hz): about 1e-4 rad/s, a band of 5e-4 rad/s against peak speeds of 0.24-0.5 rad/s. Measured
(docs/how-to/identify.md, "Where the held-out error comes from"): the held-out NRMSE over every
sample 12.2 % -> 8.5 % on the worst joint, the worst viscous error 5.3 % -> 2.8 %. Never wider
than :data:`SLOW_SHARE` of the joint's peak speed: every fitted sample is then outside the band."""


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
    position's). The positions are windowed (Hann) first: a run cut anywhere but at rest would
    otherwise leak its ends' kinks over the whole spectrum.

    Only the motion's own spectrum counts: an encoder's quantisation and its noise are white,
    and weighed by ``f^2`` they would hold the velocities' energy at the highest frequencies (an
    18-bit encoder on a UR5 excitation: 0.4 % of it, so the 99.9 % point fell near the Nyquist
    frequency). Each joint's white floor -- the median of its spectrum's upper half -- is taken
    out, and what stays within :data:`NOISE_FLOOR_FACTOR` times it is noise."""
    detrended = q - np.linspace(0.0, 1.0, len(q))[:, None] * (q[-1] - q[0]) - q[0]
    spectrum = np.fft.rfft(detrended * np.hanning(len(q))[:, None], axis=0)
    f = np.fft.rfftfreq(len(q), 1.0 / rate)
    power = np.abs(spectrum) ** 2
    floor = np.median(power[len(f) // 2:], axis=0) if len(f) >= 4 else np.zeros(q.shape[1])
    power = np.where(power > NOISE_FLOOR_FACTOR * floor, power - floor / np.log(2.0), 0.0)
    energy = np.sum(power, axis=1) * f**2
    total = float(energy.sum())
    if total <= 0.0:
        return 0.0
    return float(f[int(np.searchsorted(np.cumsum(energy) / total, BANDWIDTH_ENERGY))])


def _lowpass(cutoff: float, rate: float) -> FloatArray:
    sos: FloatArray = scipy.signal.butter(FILTER_ORDER, cutoff, btype="low", fs=rate, output="sos")
    return sos


@dataclass(frozen=True)
class Prepared:
    """A recording made ready for the identification (module docstring).

    Attributes
    ----------
    grid : ndarray
        The uniform times (s) of the recording, at :attr:`rate`.
    q, qd, qdd : ndarray, shape (len(grid), n)
        Filtered positions and their derivatives at every time of ``grid``.
    model_grid : ndarray of int
        The samples of ``grid`` the model's columns are evaluated at.
    keep : ndarray of int
        The kept samples, as indices into ``model_grid``.
    tau : ndarray, shape (len(keep), n)
        The efforts, filtered, at the kept samples.
    moving : ndarray of bool, shape (len(keep), n)
        Whether each joint is away from its velocity reversals at each kept sample.
    rate, model_rate : float
        The recording's rate and the model grid's (Hz).
    bandwidth, cutoff : float
        The motion's bandwidth and the filter's cut-off (Hz).
    cutoff_given : bool
        The cut-off was given, not chosen from the bandwidth.
    stick_band : ndarray, shape (n,)
        Each joint's Coulomb band ``v_s`` (rad/s or m/s, :data:`STICK_SIGMAS`; or given).
    rest : ndarray of bool, shape (len(grid), n)
        Whether each joint is at rest at each time of :attr:`grid`: the slope of a line fitted to
        its recorded positions (:func:`rest_window` of them) ending or starting there within its
        :attr:`stick_band` (:func:`_rest`).
    rest_slope : ndarray, shape (len(grid), n)
        The slope of the line fitted to the positions centred on each time (rad/s or m/s).
    """

    grid: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    model_grid: np.ndarray
    keep: np.ndarray
    tau: FloatArray
    moving: np.ndarray
    rate: float
    model_rate: float
    bandwidth: float
    cutoff: float
    cutoff_given: bool
    stick_band: FloatArray
    rest: np.ndarray
    rest_slope: FloatArray

    @property
    def kept_rate(self) -> float:
        """The rate of the kept samples (Hz)."""
        return self.model_rate / float(self.keep[1] - self.keep[0]) if len(self.keep) > 1 else self.model_rate

    @property
    def t(self) -> FloatArray:
        """Times (s) of the kept samples."""
        out: FloatArray = self.grid[self.model_grid[self.keep]]
        return out

    def motion(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(q, qd, qdd)`` on the model grid: where the model's columns are evaluated."""
        k = self.model_grid
        return self.q[k], self.qd[k], self.qdd[k]

    def kept_motion(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(q, qd, qdd)`` at the kept samples."""
        k = self.model_grid[self.keep]
        return self.q[k], self.qd[k], self.qdd[k]

    def smooth(self, columns: FloatArray) -> FloatArray:
        """Signals on the model grid (``(len(model_grid), m)``), low-passed at the cut-off like the
        efforts, at the kept samples."""
        out: FloatArray = scipy.signal.sosfiltfilt(_lowpass(self.cutoff, self.model_rate), columns, axis=0)[self.keep]
        return out

    def stepped(self, signal: FloatArray) -> FloatArray:
        """A signal at every time of :attr:`grid` that steps (``sign(qd)``), processed as the efforts:
        anti-aliased, sampled on the model grid, low-passed at the cut-off, at the kept samples."""
        return self.smooth(_to_model_grid(signal, self.rate, self.model_rate, self.cutoff, self.model_grid))

    def coulomb_sign(self) -> FloatArray:
        """Coulomb friction's ``sign(qd)`` at every time of :attr:`grid`: ``sat(qd / v_s)``, each
        joint's :attr:`stick_band` (:data:`STICK_SIGMAS`)."""
        out: FloatArray = np.clip(self.qd / self.stick_band, -1.0, 1.0)
        return out

    def static_friction_set(self) -> tuple[FloatArray, FloatArray]:
        """Coulomb friction over ``fc``, set-valued, through the efforts' filters: ``(centre, radius)``
        at the kept samples, each ``(len(keep), n)``.

        The law is ``sign(qd)`` while a joint moves and any value in ``[-1, 1]`` while it is at rest
        (the set-valued Coulomb law: Olsson, Astrom, Canudas de Wit, Gafvert & Lischinsky, "Friction
        models and friction compensation", Eur. J. Control 4(3), 1998, section 2; Brogliato,
        *Nonsmooth Mechanics*, 1999); at rest is :attr:`rest`, the sign the fitted slope's. The
        efforts are filtered (:meth:`stepped`), so the model's prediction is that set filtered: a
        linear filter ``h`` takes a signal pointwise within ``c(t) +/- r(t)`` to one within
        ``(h * c) +/- (|h| * r)`` at each sample, and the bound is reached (each instant's value
        chosen by the sign of ``h`` there). The centre goes through the efforts' own filters; the
        radius through ``|h|``, the chain's impulse response at the recording's rate (the anti-alias
        low-pass and the cut-off's, both ways; the model grid's decimation left out: below the
        anti-alias it changes nothing the cut-off keeps). Away from every stretch at rest, by more
        than the filter's reach, the radius is 0 and the set the point ``sign(qd)``; within a stretch at
        rest it is up to ``sum |h|`` (1.38 for the cut-off's Butterworth both ways), not 1: the
        filter's negative lobes take a torque that flips within ``+/- fc`` past ``fc``."""
        centre = self.stepped(np.where(self.rest, 0.0, np.sign(self.rest_slope)))
        reach = np.abs(_chain_response(self.cutoff, self.rate, self.model_rate))
        radius = np.stack([scipy.signal.fftconvolve(self.rest[:, j].astype(float), reach, mode="same")
                           for j in range(self.rest.shape[1])], axis=1)[self.model_grid[self.keep]]
        return centre, radius

    def describe(self) -> str:
        how = "given" if self.cutoff_given else (f"{CUTOFF_FACTOR:g} x the motion's bandwidth {self.bandwidth:.3g} Hz "
                                                  f"({BANDWIDTH_ENERGY:.1%} of the velocities' energy)")
        return (f"zero-phase Butterworth low-pass (order {FILTER_ORDER}, both ways) at {self.cutoff:.3g} Hz ({how}) on "
                f"the positions, and on the efforts and the model's columns alike (parallel filtering); central "
                f"differences; {len(self.keep)} samples kept at {self.kept_rate:.3g} Hz of {self.rate:.4g} Hz; Coulomb "
                f"friction's sign linear within {', '.join(f'{v:.3g}' for v in self.stick_band)} (rad/s or m/s)")


def _chain_response(cutoff: float, rate: float, model_rate: float) -> FloatArray:
    """The impulse response of the efforts' filters at the recording's rate (:meth:`Prepared.stepped`,
    the decimation left out), over :data:`EDGE_PERIODS` periods of the cut-off either side: the
    length the filter's edges are dropped for. Beyond it lies 4e-4 of ``sum |h|`` (the Butterworth
    of order 4 both ways, at any cut-off): a set that much narrower, never wider."""
    half = int(np.ceil(EDGE_PERIODS / cutoff * rate))
    impulse = np.zeros(2 * half + 1)
    impulse[half] = 1.0
    if model_rate < rate:
        impulse = scipy.signal.sosfiltfilt(_lowpass(min(ANTI_ALIAS_PER_CUTOFF * cutoff, 0.45 * model_rate), rate),
                                           impulse)
    out: FloatArray = scipy.signal.sosfiltfilt(_lowpass(cutoff, rate), impulse)
    return out


def rest_window(sigma_q: FloatArray, band: FloatArray, rate: float) -> int:
    """The samples (odd, >= 3) of the local line fit that tells a joint at rest (:attr:`Prepared.rest`):
    the fewest whose slope's noise is at most ``band / STICK_SIGMAS`` on every joint, as the filtered
    velocity's is (:data:`STICK_SIGMAS`). A line fitted to ``N`` samples ``1 / rate`` apart, each
    with white noise ``sigma_q``, has a slope of standard deviation
    ``sigma_q rate / sqrt(N (N^2 - 1) / 12)``."""
    needed = np.where(band > 0.0, STICK_SIGMAS * np.asarray(sigma_q, dtype=float) * rate / band, 0.0)
    target = float(np.max(needed)) ** 2

    def enough(count: int) -> bool:
        return count * (count * count - 1) / 12.0 >= target

    count = 3
    while not enough(count):
        count += 2
    return count


def _rest(q: FloatArray, band: FloatArray, window: int, rate: float) -> tuple[FloatArray, np.ndarray]:
    """``(slope, rest)`` at every sample: the slope of a line fitted to the ``window`` positions
    centred on it (Savitzky-Golay, degree 1), and whether the joint is at rest there -- the slope
    of the window that ends at the sample, or of the one that starts there, within ``band``. One
    side suffices: at the first instants of a stuck stretch the centred window still holds the
    motion before it (and at the last, the breakaway after it), and its slope is the motion's."""
    window = min(window, len(q) - (1 - len(q) % 2))
    slope: FloatArray = scipy.signal.savgol_filter(q, window, 1, deriv=1, delta=1.0 / rate, axis=0, mode="nearest")
    half = window // 2
    still = np.abs(slope) < band
    ending = np.vstack([np.repeat(still[:1], half, axis=0), still[:len(still) - half]])
    starting = np.vstack([still[half:], np.repeat(still[-1:], half, axis=0)])
    return slope, ending | starting


def _to_model_grid(signal: FloatArray, rate: float, model_rate: float, cutoff: float, model_grid: np.ndarray
                   ) -> FloatArray:
    if model_rate >= rate:
        same: FloatArray = signal[model_grid]
        return same
    guard = min(ANTI_ALIAS_PER_CUTOFF * cutoff, 0.45 * model_rate)
    out: FloatArray = scipy.signal.sosfiltfilt(_lowpass(guard, rate), signal, axis=0)[model_grid]
    return out


def prepare(t: ArrayLike, q: ArrayLike, tau: ArrayLike, *, cutoff: float | None = None,
            stick_band: ArrayLike | None = None) -> Prepared:
    """Positions and efforts recorded at times ``t`` made ready for the identification (module
    docstring); ``cutoff`` (Hz) replaces the one chosen from the motion, ``stick_band`` (per joint)
    Coulomb friction's band (another run's: a held-out run is predicted with the identified model's).

    Raises
    ------
    InvalidInputError
        Too few samples, a motion without bandwidth (nothing moved), a cut-off at or above a
        fifth of the recording's rate, or a run too short to keep anything after the filter's edges.
    """
    grid, rate, (q_u, tau_u) = uniform(t, q, tau)
    bandwidth = motion_bandwidth(q_u, rate)
    if cutoff is None:
        if bandwidth <= 0.0:
            raise InvalidInputError("no joint moved: nothing to identify")
        chosen = CUTOFF_FACTOR * bandwidth
    else:
        chosen = float(cutoff)
    if not (0.0 < chosen <= 0.2 * rate):
        raise InvalidInputError(f"the filter's cut-off {chosen:.4g} Hz must be in (0, {0.2 * rate:.4g}] Hz (a fifth of "
                                f"the {rate:.4g} Hz recording rate)" + ("" if cutoff is not None else
                                                                        ": record faster, or give --cutoff"))
    sos = _lowpass(chosen, rate)
    if len(grid) <= 3 * 2 * len(sos):
        raise InvalidInputError(f"too few samples ({len(grid)}) to filter")
    q_f = scipy.signal.sosfiltfilt(sos, q_u, axis=0)
    dt = 1.0 / rate
    qd = np.gradient(q_f, dt, axis=0)
    qdd = np.gradient(qd, dt, axis=0)
    step = max(1, int(np.floor(rate / (MODEL_PER_CUTOFF * chosen))))
    model_grid = np.arange(0, len(grid), step)
    model_rate = rate / step
    tau_m = _to_model_grid(tau_u, rate, model_rate, chosen, model_grid)
    edge = int(np.ceil(EDGE_PERIODS / chosen * model_rate))
    every = max(1, int(np.floor(model_rate / (KEPT_PER_CUTOFF * chosen))))
    keep = np.arange(edge, len(model_grid) - edge, every)
    if keep.size == 0:
        raise InvalidInputError(f"the run ({grid[-1] - grid[0]:.3g} s) is shorter than the filter's edges "
                                f"({2 * edge / model_rate:.3g} s at a {chosen:.3g} Hz cut-off)")
    tau_f = scipy.signal.sosfiltfilt(_lowpass(chosen, model_rate), tau_m, axis=0)[keep]
    peak = np.max(np.abs(qd[model_grid[keep]]), axis=0)
    sigma_q = position_noise(q_u, q_f, chosen, rate)
    if stick_band is None:
        band = np.minimum(STICK_SIGMAS * velocity_noise(sigma_q, chosen, rate), SLOW_SHARE * peak)
        # a joint that never moved: a band of 1, its sign column then zero, as sign(0) is
        band = np.where(band > 0.0, band, 1.0)
    else:
        band = np.broadcast_to(np.asarray(stick_band, dtype=float), peak.shape).copy()
    moving = (_away_from_reversals(qd, int(np.ceil(REVERSAL_PERIODS / chosen * rate)))
              & _away_from(np.abs(qd) < SLOW_SHARE * peak, int(np.ceil(SLOW_GUARD_PERIODS / chosen * rate))))
    moving = moving[model_grid[keep]]
    slope, rest = _rest(q_u, band, rest_window(sigma_q, band, rate), rate)
    return Prepared(grid, q_f, qd, qdd, model_grid, keep, tau_f, moving, rate, model_rate, bandwidth, chosen,
                    cutoff is not None, band, rest, slope)


def position_noise(q: FloatArray, filtered: FloatArray, cutoff: float, rate: float) -> FloatArray:
    """Per joint, the standard deviation ``sigma_q`` of the positions' noise: what the low-pass took
    out (the motion has nothing above the cut-off). The ends (:data:`EDGE_PERIODS`), where the
    filter's start-up transient is not noise, are left out."""
    edge = int(np.ceil(EDGE_PERIODS / cutoff * rate))
    inside = slice(edge, len(q) - edge) if len(q) > 4 * edge else slice(None)
    out: FloatArray = np.std((q - filtered)[inside], axis=0)
    return out


def velocity_noise(sigma_q: FloatArray, cutoff: float, rate: float) -> FloatArray:
    """Per joint, the standard deviation of the filtered velocity's noise, from the positions'
    (:func:`position_noise`), white over the recording's band ``rate / 2``: differentiated and
    low-passed at ``f_c`` its variance is
    ``sigma_q^2 / (rate / 2) * integral_0^f_c (2 pi f)^2 df = sigma_q^2 (2 pi)^2 f_c^3 / (3 rate / 2)``."""
    out: FloatArray = np.asarray(sigma_q, dtype=float) * 2.0 * np.pi * np.sqrt(cutoff**3 / (3.0 * rate / 2.0))
    return out


def _away_from_reversals(qd: FloatArray, half_width: int) -> np.ndarray:
    """Per sample and joint: no sign change of the velocity within ``half_width`` samples."""
    sign = np.sign(qd)
    flips = np.zeros(qd.shape, dtype=bool)
    flips[1:] = sign[1:] != sign[:-1]
    flips |= sign == 0.0
    return _away_from(flips, half_width)


def _away_from(events: np.ndarray, half_width: int) -> np.ndarray:
    """Per sample and joint: no ``events`` within ``half_width`` samples."""
    # an event anywhere in [i - w, i + w]: a running count over a window of 2 w + 1
    counts = np.cumsum(np.vstack([np.zeros((1, events.shape[1]), dtype=int), events.astype(int)]), axis=0)
    index = np.arange(len(events))
    upper = np.minimum(index + half_width + 1, len(events))
    lower = np.maximum(index - half_width, 0)
    away: np.ndarray = (counts[upper] - counts[lower]) == 0
    return away
