"""The law against the MuJoCo stand-in in lockstep, in-process (``--plant mujoco``): with every
nuisance off it reproduces the in-process simulator on the thesis arms and the UR5; with them it
repeats with its seed, runs the same in stretches as in one call, and stops a diverged run as the
simulator does (ROS-free)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

pytest.importorskip("mujoco")

from pdsmc_ros.cli import main  # noqa: E402
from pdsmc_ros.runs.builder import make_run  # noqa: E402
from pdsmc_ros.sim import simulate  # noqa: E402
from pdsmc_ros.sim.mujoco_lockstep import StandIn  # noqa: E402

# the in-process simulator's contour error, reproduced by MuJoCo with every nuisance off: measured
# here 1e-13 (serial 3R), 2e-6 (five-bar: MuJoCo's soft loop closure), 1e-15 (UR5) relative
AGREEMENT = 0.05
CASES = [("serial_3r", "circle", "pd"), ("serial_3r", "zigzag", "pdsmc"), ("serial_3r", "ellipse", "smc"),
         ("parallel_5r", "circle", "pdsmc"), ("parallel_5r", "ellipse_vertical", "pd"),
         ("ur5", "circle", "pdsmc"), ("ur5", "circle", "pd")]


@pytest.mark.parametrize(("robot", "contour", "law"), CASES)
def test_ideal_reproduces_the_in_process_simulators_contour_error(robot: str, contour: str, law: str) -> None:
    spec = make_run(robot, contour, law)
    ours = simulate(spec)
    mujoco = simulate(spec, stand_in=StandIn("ideal"))
    assert not ours.diverged and not mujoco.diverged
    for key in ("contour_mean", "contour_sd"):
        a, b = getattr(ours.metrics, key), getattr(mujoco.metrics, key)
        assert abs(b / a - 1.0) < AGREEMENT, f"{key}: {a} in-process, {b} MuJoCo"
    # closer than the target, by far: the same integrator, step and zero-order hold on the same model
    assert abs(mujoco.metrics.contour_mean / ours.metrics.contour_mean - 1.0) < (1e-4 if robot == "parallel_5r"
                                                                                 else 1e-9)


def test_bench_repeats_with_its_seed_and_runs_the_same_in_stretches() -> None:
    spec = dataclasses.replace(make_run("ur5", "circle", "pd"), duration_factor=0.6)
    bench = StandIn("bench", seed=4)
    kept = simulate(spec, stand_in=bench)
    again = simulate(spec, stand_in=bench)
    stretched = simulate(spec, stand_in=bench, keep_samples=False)
    assert kept.metrics.as_dict() == again.metrics.as_dict()
    a, b = kept.metrics.as_dict(), stretched.metrics.as_dict()
    for key in ("contour_mean", "contour_sd", "axial_mean", "max_torque"):
        np.testing.assert_allclose(b[key], a[key], rtol=1e-12, err_msg=key)
    other = simulate(spec, stand_in=dataclasses.replace(bench, seed=5))
    assert other.metrics.contour_mean != kept.metrics.contour_mean  # another draw of the noise
    ideal = simulate(spec, stand_in=StandIn("ideal"))
    assert kept.metrics.contour_mean != pytest.approx(ideal.metrics.contour_mean, rel=1e-3)


def test_the_law_sees_the_drives_reading_and_the_statistics_the_true_arm() -> None:
    spec = dataclasses.replace(make_run("serial_3r", "circle", "pd"), duration_factor=0.2)
    coarse = StandIn("ideal", given={"encoder_counts": 64})  # 0.1 rad a count: the law sees steps
    result = simulate(spec, stand_in=coarse)
    grid = 2 * np.pi / 64
    q = result.samples.q
    assert np.any(np.abs(q / grid - np.round(q / grid)) > 0.01)  # the samples: MuJoCo's exact angles
    assert result.metrics.contour_mean > 3 * simulate(spec).metrics.contour_mean


def test_a_monte_carlos_runs_draw_their_own_noise() -> None:
    bench = StandIn("bench", seed=3)
    seeds = {bench.for_run(3, i).seed for i in range(5)}
    assert len(seeds) == 5 and bench.for_run(3, 1).seed == StandIn("bench").for_run(3, 1).seed


def test_a_diverging_run_is_stopped_and_reported() -> None:
    spec = dataclasses.replace(make_run("serial_3r", "circle", "pd", overrides={"kp": [1e9, 1e9, 1e9]}),
                               enforce_limits=False)
    ours = simulate(spec, check_stability=False)
    result = simulate(spec, check_stability=False, stand_in=StandIn("ideal"))
    assert ours.diverged and result.diverged
    assert result.diverged.split(" at t = ")[0] == ours.diverged.split(" at t = ")[0]
    assert np.isnan(result.metrics.contour_mean)


def test_the_commands_run_against_the_stand_in(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--plant", "mujoco",
            "--realism", "bench", "--command-delay", "0", "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["plant"]["plant"] == "mujoco" and out["plant"]["realism"] == "bench"
    assert out["plant"]["command_delay"] == 0 and out["plant"]["sources"]["command_delay"] == "given"
    assert out["plant"]["encoder_counts"] == [2**18] * 3


@pytest.mark.parametrize(("flags", "message"), [
    (["--friction-coulomb", "1"], ("pdsmc simulate: error: --friction-coulomb is for the MuJoCo stand-in: give "
                                  "--plant mujoco with it")),
    (["--plant", "mujoco", "--friction-coulomb", "-1"], ("pdsmc simulate: error: parameter friction_coulomb must be "
     "a list of numbers (one per joint, or one for every joint), each in [0, 1000000], got [-1.0]")),
    (["--plant", "mujoco", "--velocity-filter-hz", "1,2"], ("pdsmc simulate: error: parameter velocity_filter_hz "
     "needs 3 values, one per joint (or one for every joint), got 2")),
    (["--plant", "mujoco", "--command-delay", "101"], ("pdsmc simulate: error: parameter command_delay must be a "
     "whole number in [0, 100], got 101")),
])
def test_a_bad_nuisance_is_one_line_and_exit_2(flags: list[str], message: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    args = ["simulate", "--robot", "serial_3r", "--contour", "circle", "--controller", "pd", *flags]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err == message


def _drive_record(given: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A short computed-torque run of the serial 3R on the stand-in with ``given`` nuisances: the
    true positions, the law's torques and the drive's record at every step."""
    from pdsmc_ros.control.law import ControlLaw
    from pdsmc_ros.control.registry import Gains, smc_model_vector
    from pdsmc_ros.identification.simulated import EXACT_MODEL
    from pdsmc_ros.robots.registry import make_robot

    plant = make_robot("serial_3r")
    rate = 1000.0
    law = ControlLaw("ctc", Gains.from_mapping({"omega_n": [30.0] * 3, "zeta": [1.0] * 3}, 3, "ctc").matrix(),
                     smc_model_vector(EXACT_MODEL), plant, 1.0 / rate)
    t = np.arange(301) / rate
    q0 = np.array([0.3, 0.5, -0.4])
    q = q0 + 0.1 * np.sin(2.0 * np.pi * t)[:, None]
    qd = 0.2 * np.pi * np.cos(2.0 * np.pi * t)[:, None] * np.ones(3)
    qdd = -0.4 * np.pi**2 * np.sin(2.0 * np.pi * t)[:, None] * np.ones(3)
    refs = np.ascontiguousarray(np.stack([q, qd, qdd], axis=1))
    loop = StandIn("ideal", given=given).loop("serial_3r", rate, plant)
    out_q, _, _, outcome = loop(plant, law, q0.copy(), refs, 1.0 / rate, 1, every_step=True, drive_record=True)
    return out_q, outcome.step_tau, outcome.step_drive


def test_the_drive_record_is_what_the_driver_publishes_and_the_torque_mujoco_applied() -> None:
    """Every nuisance off: the published state is the true one and the motors take the law's
    torque in its own tick; with a delay of 3 ticks they take the one 3 ticks older (none before:
    braked); with an encoder the published positions are on its grid. The last instant's torque
    is applied over no tick (the run ends there): 0."""
    true_q, tau, drive = _drive_record({})
    np.testing.assert_array_equal(drive[:, 0], true_q)
    np.testing.assert_array_equal(drive[:-1, 2], tau[:-1])
    np.testing.assert_array_equal(drive[-1, 2], 0.0)
    _, tau, drive = _drive_record({"command_delay": 3})
    np.testing.assert_array_equal(drive[:3, 2], 0.0)
    np.testing.assert_array_equal(drive[3:-1, 2], tau[:-4])
    true_q, _, drive = _drive_record({"encoder_counts": 4096})
    grid = 2.0 * np.pi / 4096
    np.testing.assert_allclose(drive[:, 0] / grid, np.round(drive[:, 0] / grid), atol=1e-9)
    assert np.max(np.abs(drive[:, 0] - true_q)) <= 0.5 * grid + 1e-12
