"""RunStatistics (pdsmc_ros/metrics/statistics.py, metrics_kernel.py): the thesis statistics and the scores,
accumulated instant by instant, against numpy's reading of the same definitions over the whole
arrays (docs/THESIS_NOTES.md section 4, docs/SCORES.md), and the same numbers however the instants
are split into blocks."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.metrics.scores import high_frequency_power
from pdsmc_ros.metrics.statistics import RunStatistics

RATE = 500.0
BOUND = 0.8


def signals(count: int, joints: int, seed: int = 3) -> tuple[np.ndarray, ...]:
    """Errors near 1e-4 with an offset (what a tracking run gives) and a torque with switching."""
    rng = np.random.default_rng(seed)
    axial = 1e-4 * (1.0 + rng.standard_normal((count, joints)))
    task = 1e-4 * (0.5 + rng.standard_normal((count, 2)))
    contour = np.abs(rng.standard_normal(count))
    t = np.arange(count) / RATE
    switching = 0.05 * np.sign(rng.standard_normal((count, joints)))
    tau = np.sin(2 * np.pi * 0.2 * t)[:, None] * np.arange(1, joints + 1) + switching
    return axial, task, contour, tau


def numpy_reading(axial: np.ndarray, task: np.ndarray, contour: np.ndarray, tau: np.ndarray) -> dict[str, object]:
    """The statistics and scores as numpy computes them from the whole arrays (the definitions)."""
    absolute = np.abs(axial)
    ex, ey = np.abs(task[:, 0]), np.abs(task[:, 1])
    total = np.hypot(ex, ey)
    h = 1.0 / RATE
    applied = tau[:-1]
    periods = len(applied)
    t = np.arange(len(axial)) * h
    norm = np.sqrt(np.sum(axial ** 2, axis=1))
    step = np.abs(np.diff(applied, axis=0))
    high, power = high_frequency_power(applied, RATE, 50.0)

    def itae(e: np.ndarray) -> np.ndarray:
        weighted = (t * np.abs(e).T).T
        return 0.5 * h * (weighted[:-1] + weighted[1:]).sum(axis=0)

    return {
        "axial_mean": absolute.mean(axis=0), "axial_sd": absolute.std(axis=0),
        "task_mean": [ex.mean(), ey.mean(), total.mean()], "task_sd": [ex.std(), ey.std(), total.std()],
        "contour": [np.abs(contour).mean(), np.abs(contour).std()],
        "within": 100.0 * np.mean(np.abs(contour) <= BOUND),
        "max_torque": np.max(np.abs(tau), axis=0),
        "signed_sd": [np.std(task[:, 0]), np.std(task[:, 1])],
        "error_rms": np.sqrt(np.mean(axial ** 2, axis=0)), "run_rms": np.sqrt(np.mean(norm ** 2)),
        "error_itae": itae(axial), "run_itae": itae(norm),
        "torque_tv_rate": step.sum(axis=0) / (periods * h),
        "torque_rate_peak": step.max(axis=0) / h,
        "control_energy": (applied ** 2).sum(axis=0) * h,
        "torque_hf_share": high / power, "run_hf_share": high.sum() / power.sum(),
    }


def test_the_accumulated_statistics_and_scores_are_numpys_to_rounding() -> None:
    axial, task, contour, tau = signals(20_001, 3)
    stats = RunStatistics(3, bound=BOUND, rate=RATE)
    stats.add(axial, task, contour, tau)
    stats.add_steps(axial, tau)  # here the statistics instants are the steps
    m = stats.metrics([4, 0, 1])
    ref = numpy_reading(axial, task, contour, tau)
    close = {"rel": 1e-13, "abs": 0.0}  # measured: <= 8e-15 (compensated and Welford sums against pairwise)
    assert m.samples == 20_001 and m.saturated_periods == [4, 0, 1]
    assert m.axial_mean == pytest.approx(ref["axial_mean"], **close)
    assert m.axial_sd == pytest.approx(ref["axial_sd"], **close)
    assert list(m.task_mean.values()) == pytest.approx(ref["task_mean"], **close)
    assert list(m.task_sd.values()) == pytest.approx(ref["task_sd"], **close)
    assert [m.contour_mean, m.contour_sd] == pytest.approx(ref["contour"], **close)
    assert m.contour_within_pct == ref["within"] and m.max_torque == list(ref["max_torque"])  # exact: counts, maxima
    assert list(m.task_sd_signed.values()) == pytest.approx(ref["signed_sd"], **close)
    for name in ("error_rms", "error_itae", "torque_tv_rate", "control_energy", "torque_hf_share"):
        assert getattr(m, name) == pytest.approx(ref[name], **close), name
    assert m.torque_rate_peak == list(ref["torque_rate_peak"])
    run = m.run_scores
    assert [run["error_rms"], run["error_itae"], run["torque_hf_share"]] == pytest.approx(
        [ref["run_rms"], ref["run_itae"], ref["run_hf_share"]], **close)
    assert run["torque_tv_rate"] == pytest.approx(np.sum(ref["torque_tv_rate"]), **close)
    assert run["rate_hz"] == RATE and run["cutoff_hz"] == 50.0


@pytest.mark.parametrize("cuts", [[1], [2, 3], [7, 4096, 4097, 9000], list(range(1, 300, 7))])
def test_the_numbers_do_not_depend_on_how_the_instants_are_split(cuts: list[int]) -> None:
    axial, task, contour, tau = signals(10_000, 2, seed=8)
    whole = RunStatistics(2, bound=BOUND, rate=RATE)
    whole.add(axial, task, contour, tau)
    whole.add_steps(axial, tau)
    split = RunStatistics(2, bound=BOUND, rate=RATE)
    edges = [0, *cuts, len(contour)]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        split.add(axial[a:b], task[a:b], contour[a:b], tau[a:b])
        split.add_steps(axial[a:b], tau[a:b])
    assert split.instants == split.steps == 10_000
    assert split.metrics().as_dict() == whole.metrics().as_dict()  # every field, every digit


def test_a_nan_makes_the_statistics_it_enters_nan_and_keeps_the_others() -> None:
    axial, task, contour, tau = signals(1_001, 2)
    axial[500:, 1] = np.nan
    tau[700:, 0] = np.nan
    stats = RunStatistics(2, bound=BOUND, rate=RATE)
    stats.add(axial, task, contour, tau)
    stats.add_steps(axial, tau)
    m = stats.metrics()
    assert np.isnan(m.axial_mean[1]) and np.isfinite(m.axial_mean[0]) and np.isfinite(m.contour_mean)
    assert np.isnan(m.max_torque[0]) and np.isfinite(m.max_torque[1])
    assert np.isnan(m.torque_rate_peak[0]) and np.isnan(m.control_energy[0]) and np.isfinite(m.control_energy[1])
    assert np.isnan(m.run_scores["error_rms"]) and np.isnan(m.torque_hf_share[0])


def test_without_a_rate_there_are_no_scores_and_bad_input_is_one_line() -> None:
    axial, task, contour, tau = signals(100, 2)
    stats = RunStatistics(2, bound=BOUND)
    stats.add(axial, task, contour, tau)
    assert stats.scores() is None and stats.metrics().run_scores == {} and stats.metrics().samples == 100
    with pytest.raises(InvalidInputError, match="needs the control rate"):
        stats.add_steps(axial, tau)
    with pytest.raises(InvalidInputError, match="at least one sampled instant"):
        RunStatistics(2, bound=BOUND).metrics()
    for bad in (0, -1, 2.5, True):
        with pytest.raises(InvalidInputError, match="joints must be a positive integer"):
            RunStatistics(bad, bound=BOUND)  # type: ignore[arg-type]
    for rate, cutoff in ((-5.0, 50.0), ("fast", 50.0), (500.0, float("nan")), (500.0, 0.0)):
        with pytest.raises(InvalidInputError, match="positive rate and cutoff"):
            RunStatistics(2, bound=BOUND, rate=rate, cutoff=cutoff)  # type: ignore[arg-type]
    for bound in (-1.0, float("nan"), "wide"):
        with pytest.raises(InvalidInputError, match="contour bound must be a number >= 0"):
            RunStatistics(2, bound=bound)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"q_d - q must be 100 rows of 2; got shape \(100, 1\)") as info:
        stats.add(axial[:, :1], task, contour, tau)
    assert "\n" not in str(info.value) and stats.instants == 100  # a refused block adds nothing
    one = RunStatistics(2, bound=BOUND, rate=RATE)
    one.add(axial[:1], task[:1], contour[:1], tau[:1])
    one.add_steps(axial[:1], tau[:1])
    with pytest.raises(InvalidInputError, match="the torque must be 1 rows of 2"):
        one.add_steps(axial[:1], tau[:2])
    assert one.scores() is None and one.metrics().samples == 1  # no applied period: nothing to score


def test_a_long_run_averages_the_spectrum_of_fixed_segments() -> None:
    """Over SPECTRUM_SEGMENT applied periods the share is Welch's: each segment's power per step,
    summed; the segments start at fixed steps, so the split of the steps does not matter."""
    from pdsmc_ros.metrics import statistics as metrics

    steps = 2 * metrics.SPECTRUM_SEGMENT + 5_001
    t = np.arange(steps) / 10_000.0
    slow = np.sin(2 * np.pi * 3.0 * t)
    tau = np.column_stack([slow + (t > 20.0) * np.sin(2 * np.pi * 700.0 * t), slow])
    error = np.zeros((steps, 2))
    stats = RunStatistics(2, bound=BOUND, rate=10_000.0)
    for a in range(0, steps, 50_000):
        stats.add_steps(error[a : a + 50_000], tau[a : a + 50_000])
    applied = tau[:-1]
    segments = [applied[:metrics.SPECTRUM_SEGMENT], applied[metrics.SPECTRUM_SEGMENT : 2 * metrics.SPECTRUM_SEGMENT],
                applied[2 * metrics.SPECTRUM_SEGMENT :]]
    high = sum(high_frequency_power(u, 10_000.0, 50.0)[0] / len(u) for u in segments)
    power = sum(high_frequency_power(u, 10_000.0, 50.0)[1] / len(u) for u in segments)
    s = stats.scores()
    assert s is not None and s.torque_hf_share == pytest.approx(list(high / power), rel=1e-12)
    assert 0.0 < s.torque_hf_share[0] < 1.0 and s.torque_hf_share[1] < 1e-3  # rectangular window: leakage
    whole = RunStatistics(2, bound=BOUND, rate=10_000.0)
    whole.add_steps(error, tau)
    assert whole.scores() == s
