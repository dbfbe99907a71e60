"""The verdict of ``bench/storm/`` (issue 37's storm target): its intervals hold what they claim.

Lateness samples are drawn here, so the truth is known: equal distributions must not be called
beyond the target, a storm twice as late must be, one half as late must be within it; the exact
interval of the missed deadlines' rate ratio must cover the true ratio at least as often as its level.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.storm import figures, verdict


def rounds(rng: np.random.Generator, n: int, scale: float, per_round: int = 4000) -> list[np.ndarray]:
    """Lateness (s) of ``n`` windows: exponential around 30 us times ``scale``, each window with its own drift."""
    return [scale * rng.uniform(0.8, 1.25) * rng.exponential(30e-6, per_round) for _ in range(n)]


def test_equal_windows_are_never_called_beyond() -> None:
    rng = np.random.default_rng(1)
    found = verdict.ratio_intervals(rounds(rng, 10, 1.0), rounds(rng, 10, 1.0), 1e-3, resamples=300)
    for name in ("p99", "p99.9", "worst"):
        point, low, high = found[name]
        assert low <= point <= high
        assert low <= 1.0 <= high, (name, found[name])
        assert not verdict.verdict(low, high).startswith("beyond")


def test_a_storm_twice_as_late_is_beyond_and_half_as_late_within() -> None:
    rng = np.random.default_rng(2)
    idle = rounds(rng, 10, 1.0)
    _, low, high = verdict.ratio_intervals(idle, rounds(rng, 10, 2.0), 1e-3, resamples=300)["p99"]
    assert verdict.verdict(low, high) == "beyond 1.2x" and low > 1.2
    _, low, high = verdict.ratio_intervals(idle, rounds(rng, 10, 0.5), 1e-3, resamples=300)["p99"]
    assert verdict.verdict(low, high) == "within 1.2x" and high <= 1.2


def test_missed_deadlines_counted_past_one_period() -> None:
    idle = [np.full(1000, 10e-6)] * 2
    late = [np.concatenate([np.full(995, 10e-6), np.full(5, 2e-3)])] * 2  # 5 ticks a window a period late
    point, low, high = verdict.ratio_intervals(idle, late, 1e-3, resamples=50)["missed"]
    assert point == np.inf and high == np.inf and low > 1.0  # 10 against none: the storm's alone


def test_rate_ratio_interval_covers_the_true_ratio() -> None:
    rng = np.random.default_rng(3)
    ticks_storm, ticks_idle, rate = 100_000, 120_000, 1e-4
    for true in (1.0, 3.0):
        covered = 0
        for _ in range(400):
            m_storm = int(rng.poisson(true * rate * ticks_storm))
            m_idle = int(rng.poisson(rate * ticks_idle))
            _, low, high = verdict.rate_ratio_interval(m_storm, ticks_storm, m_idle, ticks_idle)
            covered += low <= true <= high
        assert covered / 400 >= 0.93, (true, covered)  # exact intervals are conservative: >= 95 % but for chance


def test_rate_ratio_interval_values() -> None:
    point, low, high = verdict.rate_ratio_interval(43, 120_000, 11, 120_000)
    assert point == pytest.approx(43 / 11)
    assert 1.0 < low < point < high  # 43 against 11 over the same ticks: beyond 1, clearly
    assert verdict.rate_ratio_interval(0, 1000, 0, 1000) == (1.0, 0.0, np.inf)
    assert verdict.verdict(0.5, 1.2) == "within 1.2x"
    assert verdict.verdict(1.21, 3.0) == "beyond 1.2x"
    assert verdict.verdict(0.9, 1.5).startswith("undecided")


def test_miss_origins_tell_a_long_tick_from_a_late_start() -> None:
    """A 1 kHz loop, ticks 50 us long, deadlines on whole milliseconds: tick 10 runs 3 ms, so tick 11
    starts when it ends, 2 ms late; tick 30 starts 2.5 ms late after a short tick."""
    period, start = 1e-3, 100.0
    rows = []  # (wall time at the end, achieved period, compute, lateness)
    for k in range(40):
        compute = 3e-3 if k == 10 else 50e-6
        lateness = {11: 2e-3, 30: 2.5e-3}.get(k, 0.0)
        rows.append([start + k * period + lateness + compute, period, compute, lateness])
    windows = [("idle", 99.0, 100.02, ""), ("storm", 100.02, 101.0, "")]
    told = figures.miss_origins(np.array(rows), windows, period)
    assert "idle: 1 after a tick still running a period past the deadline, 0 started late" in told, told
    assert "storm: 0 after a tick still running a period past the deadline, 1 started late" in told, told


def test_run_queue_waits_are_split_by_window() -> None:
    """Samples every 20 ms of two processes' cumulative run-queue waits (ns): the second waits 1 ms
    in each sample of the storm window only; each window gets the waits between its edges."""
    t = 100.0 + 0.02 * np.arange(101)  # 100.00 .. 102.00
    controller = 1e5 * np.arange(101)  # 0.1 ms a sample throughout
    driver = np.cumsum(np.where((t > 101.0) & (t <= 102.0), 1e6, 0.0))  # 1 ms a sample after 101 s
    samples = np.column_stack([t, controller, driver])
    idle = figures.runqueue_ms(samples, ["controller", "driver"], 100.0, 101.0)
    busy = figures.runqueue_ms(samples, ["controller", "driver"], 101.0, 102.0)
    assert idle == pytest.approx({"controller_rq_ms": 5.0, "driver_rq_ms": 0.0})
    assert busy == pytest.approx({"controller_rq_ms": 5.0, "driver_rq_ms": 50.0})
    assert figures.runqueue_ms(samples[:1], ["controller", "driver"], 100.0, 101.0) == {}


def test_floor_figures_count_each_window_kind() -> None:
    period = 1e-3
    t = 200.0 + period * np.arange(4000)
    lateness = np.full(len(t), 20e-6)
    lateness[[500, 2500, 3000]] = [1.5e-3, 2.5e-3, 0.9e-3]  # one miss idle, one in the storm, one late but not missed
    windows = [("idle", 200.0, 202.0, ""), ("storm", 202.0, 204.0, "")]
    told = figures.floor_figures(np.column_stack([t, lateness]), windows, period)
    assert "idle: 2000 ticks, missed 1," in told and "worst 1500 us" in told, told
    assert "storm: 2000 ticks, missed 1," in told and "worst 2500 us" in told, told


def test_misses_on_run_queue_need_a_period_of_waiting_around_them() -> None:
    period = 1e-3
    t = 100.0 + 0.02 * np.arange(101)
    waited = np.zeros(len(t))
    waited[26:] += 2e6  # 2 ms on the run queue between 100.50 and 100.52
    samples = np.column_stack([t, waited, waited])
    late = np.array([[100.51, period, 5e-5, 2e-3], [101.51, period, 5e-5, 2e-3]])  # (wall time at its end, ...)
    windows = [("idle", 100.0, 101.0, ""), ("storm", 101.0, 102.0, "")]
    told = figures.misses_on_run_queue(late, samples, windows, period)
    assert told.startswith("missed deadlines idle: 1 of 1 where"), told
    assert "missed deadlines storm: 0 of 1 where" in told, told


def test_machine_figures_share_the_cpu_time_of_a_window() -> None:
    # user nice system idle iowait irq softirq steal (s over all CPUs)
    spent = np.array([10.0, 0.0, 5.0, 4.0, 0.0, 0.0, 1.0, 0.05])
    shares = figures.machine_figures(spent)
    assert shares == pytest.approx({"cpu_idle_pct": 400 / 20.05, "cpu_kernel_pct": 600 / 20.05, "steal_ms": 50.0})
    assert figures.machine_figures(np.zeros(8)) == {}
    now = figures.cpu_times()
    assert len(now) == len(figures.CPU_TIMES) and np.all(now >= 0.0)
