"""Scores beside the errors (pdsmc_ros/metrics/scores.py, docs/SCORES.md): properties of each formula,
and the scores of a simulated run."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.metrics.scores import DEFAULT_CUTOFF_HZ, high_frequency_power
from pdsmc_ros.metrics.statistics import compute_scores

RATE = 1000.0


def periods(seconds: float, rate: float = RATE) -> np.ndarray:
    """The instants of the applied periods, ``k / rate`` for ``k = 0..N-1``."""
    return np.arange(int(round(seconds * rate))) / rate


def test_a_constant_torque_has_no_variation_no_high_share_and_energy_tau_squared_t() -> None:
    t = periods(2.0)
    torque = np.column_stack([np.full(t.size, 3.0), np.full(t.size, -0.5), np.zeros(t.size)])
    s = compute_scores(np.zeros((t.size + 1, 3)), torque, RATE)
    assert s.torque_tv_rate == [0.0, 0.0, 0.0] and s.torque_rate_peak == [0.0, 0.0, 0.0]
    # all of it at 0 Hz (to the FFT's rounding: 5e-35 here); none at all for the zero torque
    assert s.torque_hf_share == pytest.approx([0.0, 0.0, 0.0], abs=1e-15) and s.torque_hf_share[2] == 0.0
    assert s.control_energy == pytest.approx([9.0 * 2.0, 0.25 * 2.0, 0.0], rel=1e-12)  # tau^2 T
    assert s.run["control_energy"] == pytest.approx(9.0 * 2.0 + 0.25 * 2.0, rel=1e-12)
    assert s.run["torque_hf_share"] == pytest.approx(0.0, abs=1e-15) and s.run["torque_tv_rate"] == 0.0
    assert s.error_rms == [0.0, 0.0, 0.0] and s.run["error_itae"] == 0.0


@pytest.mark.parametrize("frequency", [120.0, 333.3, 60.0])
def test_a_sine_above_the_cutoff_has_all_its_power_above_it(frequency: float) -> None:
    t = periods(3.0)
    s = compute_scores(np.zeros((t.size + 1, 1)), np.sin(2 * np.pi * frequency * t)[:, None], RATE)
    assert s.torque_hf_share[0] == pytest.approx(1.0, abs=2e-3)  # leakage below 50 Hz when not on a bin
    # its total variation: 4 amplitudes a period, less what the sampling cuts off the peaks
    assert 0.7 * 4 * frequency <= s.torque_tv_rate[0] <= 4 * frequency  # >= 3 samples a period: >= 0.75


def test_a_sine_below_the_cutoff_has_none_and_the_share_splits_a_mixture_by_power() -> None:
    t = periods(2.0)
    slow = np.sin(2 * np.pi * 5.0 * t)
    s = compute_scores(np.zeros((t.size + 1, 1)), slow[:, None], RATE)
    assert s.torque_hf_share[0] == pytest.approx(0.0, abs=1e-12)
    mixed = 2.0 * slow + np.sin(2 * np.pi * 200.0 * t)  # powers 4:1 (both on bins of a 2 s window)
    s = compute_scores(np.zeros((t.size + 1, 1)), mixed[:, None], RATE, cutoff=DEFAULT_CUTOFF_HZ)
    assert s.torque_hf_share[0] == pytest.approx(0.2, rel=1e-9)
    high, total = high_frequency_power(mixed[:, None], RATE, 50.0)
    assert total[0] == pytest.approx(t.size * np.sum(mixed ** 2), rel=1e-12)  # Parseval, one-sided bins
    # a higher cutoff than both: nothing above it
    assert compute_scores(np.zeros((t.size + 1, 1)), mixed[:, None], RATE, cutoff=300.0).torque_hf_share[0] == \
        pytest.approx(0.0, abs=1e-12)


def test_chattering_at_the_control_rate_is_total_variation_and_peak_rate() -> None:
    t = periods(1.0)
    bang = np.where(np.arange(t.size) % 2 == 0, 1.0, -1.0)  # switches every period (Nyquist)
    s = compute_scores(np.zeros((t.size + 1, 1)), bang[:, None], RATE)
    assert s.torque_tv_rate[0] == pytest.approx(2.0 * (t.size - 1) / 1.0)
    assert s.torque_rate_peak[0] == pytest.approx(2.0 * RATE)
    assert s.torque_hf_share[0] == pytest.approx(1.0)
    assert s.control_energy[0] == pytest.approx(1.0)


def test_rms_and_itae_of_known_errors() -> None:
    t = np.arange(2001) / RATE  # N = 2000 periods, T = 2 s
    error = np.column_stack([np.full(t.size, 0.1), t, np.zeros(t.size)])
    s = compute_scores(error, np.zeros((2000, 3)), RATE)
    assert s.error_rms[0] == pytest.approx(0.1, rel=1e-12)
    assert s.error_rms[1] == pytest.approx(np.sqrt(np.mean(t ** 2)), rel=1e-12)
    assert s.error_itae[0] == pytest.approx(0.1 * 2.0 ** 2 / 2, rel=1e-12)  # int_0^T 0.1 t dt, exact
    assert s.error_itae[1] == pytest.approx(2.0 ** 3 / 3, rel=1e-6)  # int t^2 dt, trapezoid error O(h^2)
    norm = np.hypot(0.1, t)
    assert s.run["error_rms"] == pytest.approx(np.sqrt(np.mean(norm ** 2)), rel=1e-12)
    assert s.run["error_itae"] > max(s.error_itae)


def test_nan_makes_the_scores_nan_and_bad_shapes_are_one_line() -> None:
    torque = np.ones((10, 2))
    torque[5, 1] = np.nan
    s = compute_scores(np.zeros((11, 2)), torque, RATE)
    assert s.control_energy[0] == pytest.approx(10.0 / RATE) and np.isnan(s.control_energy[1])
    assert np.isnan(s.torque_rate_peak[1]) and np.isnan(s.run["torque_rate_peak"])
    assert np.isnan(s.torque_hf_share[1])
    for error, tau in ((np.zeros((10, 2)), np.ones((10, 2))), (np.zeros((1, 2)), np.ones((0, 2)))):
        with pytest.raises(InvalidInputError, match="scores need N >= 1") as info:
            compute_scores(error, tau, RATE)
        assert "\n" not in str(info.value)
    with pytest.raises(InvalidInputError, match="positive rate and cutoff"):
        compute_scores(np.zeros((11, 2)), torque, RATE, cutoff=0.0)


def test_a_simulated_run_carries_the_scores_of_its_control_steps() -> None:
    """The serial arm's SMC at 10 kHz has its statistics samples at 500 Hz; its scores see every
    10 kHz period (what the samples alias away), with or without its samples kept."""
    import dataclasses

    from pdsmc_ros.control import ControlLaw
    from pdsmc_ros.control.soft_limits import effort_only_table
    from pdsmc_ros.runs.builder import make_run
    from pdsmc_ros.sim import simulate
    from pdsmc_ros.sim.loop import run_loop
    from pdsmc_ros.sim.simulator import _reference_samples

    spec = dataclasses.replace(make_run("serial_3r", "circle", "smc"), duration_factor=0.04)
    result = simulate(spec)
    m = result.metrics
    assert spec.sample_every == 20 and m.samples == result.steps // 20 + 1
    _, refs = _reference_samples(spec)
    robot = spec.robot_model()
    q, _, tau, _ = run_loop(robot, ControlLaw.from_spec(spec), refs[0, 0], refs, 1.0 / spec.rate, 1,
                            effort_only_table(robot.effort_limits, robot.n))
    expected = compute_scores(refs[:, 0] - q, tau[:-1], spec.rate)  # every step, the loop's own samples
    assert m.control_energy == expected.control_energy and m.torque_tv_rate == expected.torque_tv_rate
    assert m.error_itae == expected.error_itae and m.run_scores["error_rms"] == expected.run["error_rms"]
    assert m.torque_hf_share == expected.torque_hf_share and m.torque_rate_peak == expected.torque_rate_peak
    assert m.run_scores["rate_hz"] == 10_000.0 and m.run_scores["cutoff_hz"] == DEFAULT_CUTOFF_HZ
    assert np.all(np.isfinite(m.torque_hf_share)) and m.run_scores["error_rms"] > 0
    flat = result.as_dict()
    assert flat["torque_hf_share"] == m.torque_hf_share and "control_energy" in flat["run_scores"]
    lean = simulate(spec, keep_samples=False).metrics
    assert lean.run_scores == m.run_scores and lean.torque_tv_rate == m.torque_tv_rate
