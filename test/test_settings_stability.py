"""The discrete stability check with the loop's delay, against a direct simulation of the error system."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pdsmc_ros.control.stability import (
    REALTIME_DELAY_PERIODS,
    _lowest_rates,
    check_rate,
    loop_matrix,
    rate_margin,
    spectral_radius,
)
from pdsmc_ros.errors import InvalidInputError, UnstableRateError
from pdsmc_ros.runs.builder import make_run

MASS = np.array([[0.8, 0.15], [0.15, 0.2]])
KP = np.diag([4000.0, 900.0])
KD = np.diag([60.0, 25.0])


def simulate_error(rate: float, delay: int, periods: int, substeps: int = 8) -> float:
    """|x| after ``periods`` of ``Mbar edd = tau`` integrated by RK4 between control instants, the
    torque ``-(Kp e + Kd ed)`` of the state ``delay`` periods earlier held over each period."""
    h = 1.0 / rate
    x = np.array([1e-3, -2e-3, 0.0, 0.0])  # e, ed
    held = [np.zeros(2)] * delay  # commands computed but not applied yet (zero before the first)

    def rhs(state: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return np.concatenate([state[2:], np.linalg.solve(MASS, tau)])

    for _ in range(periods):
        command = -(KP @ x[:2] + KD @ x[2:])
        held.append(command)
        tau = held.pop(0)
        dt = h / substeps
        for _ in range(substeps):
            k1 = rhs(x, tau)
            k2 = rhs(x + 0.5 * dt * k1, tau)
            k3 = rhs(x + 0.5 * dt * k2, tau)
            k4 = rhs(x + dt * k3, tau)
            x = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.all(np.isfinite(x)) or np.linalg.norm(x) > 1e6:
            return float("inf")
    return float(np.linalg.norm(x))


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_lowest_stable_rate_separates_bounded_from_diverging(delay: int) -> None:
    lowest = float(_lowest_rates(MASS[None], KP[None], KD[None], delay)[0])
    start = np.linalg.norm([1e-3, -2e-3])
    assert simulate_error(lowest * 1.03, delay, 3000) < start  # just above: decays
    assert simulate_error(lowest * 0.97, delay, 3000) > 10 * start  # just below: grows


def test_delay_raises_the_lowest_stable_rate() -> None:
    rates = [float(_lowest_rates(MASS[None], KP[None], KD[None], d)[0]) for d in (0, 1, 2)]
    assert rates[0] < rates[1] < rates[2]
    assert rates[1] > 1.5 * rates[0]


def test_loop_matrix_without_delay_is_the_held_input_map() -> None:
    h = 1e-3
    minv_kp, minv_kd = np.linalg.solve(MASS, KP), np.linalg.solve(MASS, KD)
    eye = np.eye(2)
    expected = np.block([[eye - 0.5 * h * h * minv_kp, h * eye - 0.5 * h * h * minv_kd],
                         [-h * minv_kp, eye - h * minv_kd]])
    np.testing.assert_allclose(loop_matrix(MASS, KP, KD, h, 0), expected, rtol=0, atol=1e-15)
    assert loop_matrix(MASS, KP, KD, h, 2).shape == (8, 8)
    radius, joint = spectral_radius(MASS, KP, KD, h, 1)
    assert float(radius) > 0.0 and int(joint) in (1, 2)


def test_delay_must_be_a_whole_number() -> None:
    with pytest.raises(InvalidInputError, match="delay"):
        loop_matrix(MASS, KP, KD, 1e-3, -1)


def test_thesis_presets_keep_running_in_lockstep_and_are_refused_in_real_time() -> None:
    spec = make_run("serial_3r", "circle", "pdsmc")
    reference = spec.reference()
    lockstep = check_rate(spec, reference)  # the thesis's 10 kHz: stable without delay
    assert lockstep.passes and 1.0 < lockstep.margin < 2.0
    with pytest.raises(UnstableRateError) as info:
        check_rate(spec, reference, mode="realtime")
    message = str(info.value)
    assert "realtime (zero-order hold + 2 periods of delay)" in message and "--rate" in message


def test_node_errors_advise_the_parameter() -> None:
    spec = make_run("parallel_5r", "circle", "pd")
    slow = dataclasses.replace(spec, rate=50.0, sample_rate=50.0)
    with pytest.raises(UnstableRateError) as info:
        check_rate(slow, slow.reference(), mode="realtime", entry="node")
    message = str(info.value)
    assert "-p rate:=" in message and "--rate" not in message
    rate = float(message.split("-p rate:=")[1].split()[0])
    assert check_rate(dataclasses.replace(slow, rate=rate), slow.reference(), mode="realtime").passes


def test_node_margin_error_names_the_parameter_whole() -> None:
    spec = make_run("parallel_5r", "circle", "pd")
    low = rate_margin(spec, spec.reference(), mode="realtime").lowest_stable_rate
    near = dataclasses.replace(spec, rate=1.5 * low, sample_rate=1.5 * low)  # stable, below the x2 required
    with pytest.raises(UnstableRateError) as info:
        check_rate(near, near.reference(), mode="realtime", entry="node")
    assert "x2 required, -p stability_margin:=N sets it)" in str(info.value)


def test_margin_and_declared_delay() -> None:
    spec = make_run("parallel_5r", "circle", "pd")
    reference = spec.reference()
    base = rate_margin(spec, reference, mode="realtime")
    more = rate_margin(spec, reference, mode="realtime", delay_periods=2)
    assert base.delay == REALTIME_DELAY_PERIODS == 2 and more.delay == 4 and more.margin < base.margin
    with pytest.raises(UnstableRateError, match="margin"):
        check_rate(spec, reference, mode="realtime", margin=1.5 * base.margin)
    assert rate_margin(spec, reference, mode="lockstep").required_margin == 1.0
    assert base.required_margin == 2.0
