"""The stability check with the velocity a drive estimates (issue 50): the map with the filter against
a step of the loop it models, the filter's lag counted against the delay, the stand-in agreeing,
``pdsmc check-gains --realism bench`` and ``pdsmc tune --realism bench``."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros import cli
from pdsmc_ros.control.lowpass import lowpass_gain
from pdsmc_ros.control.stability import check_gains, describe_loop, loop_matrix, rate_margin, tolerated_delay
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.runs.builder import make_run


@pytest.mark.parametrize("delay", [0, 1, 3])
def test_the_map_with_the_filter_is_one_step_of_the_loop_it_models(delay: int) -> None:
    """x_{k+1} from x_k by hand: the law's velocity is the filtered difference of the positions."""
    rng = np.random.default_rng(delay)
    n, h = 2, 1e-3
    mass = np.array([[2.0, 0.3], [0.3, 1.0]])
    kp, kd, cutoff = np.diag([400.0, 300.0]), np.diag([40.0, 20.0]), np.array([100.0, 50.0])
    e, ed, e_prev, v_prev = (rng.normal(size=n) for _ in range(4))
    waiting = [rng.normal(size=n) for _ in range(delay)]  # a_{k-1} ... a_{k-d}
    a = lowpass_gain(h, cutoff)
    v = (1.0 - a) * v_prev + a / h * (e - e_prev)
    command = -np.linalg.solve(mass, kp @ e + kd @ v)
    applied = command if delay == 0 else waiting[-1]
    moved = [command, *waiting[:-1]] if delay else []  # the new command waits, the others move one slot older
    after = np.concatenate([e + h * ed + h * h / 2 * applied, ed + h * applied, e, v, *moved])
    before = np.concatenate([e, ed, e_prev, v_prev, *waiting])
    assert np.allclose(loop_matrix(mass, kp, kd, h, delay, cutoff) @ before, after, rtol=0, atol=1e-9)
    # without a filter the map is the exact-velocity one (the state without e_{k-1}, v_{k-1})
    assert loop_matrix(mass, kp, kd, h, delay).shape == ((2 + delay) * n,) * 2


def test_the_filters_lag_counts_against_the_delay_and_the_stand_in_agrees() -> None:
    from pdsmc_ros.sim import simulate
    from pdsmc_ros.sim.mujoco_lockstep import StandIn

    spec = make_run("ur5", "circle", "pd")
    reference = spec.reference()
    exact = tolerated_delay(spec, reference)
    fast = tolerated_delay(spec, reference, filter_hz=[100.0])
    slow = tolerated_delay(spec, reference, filter_hz=[10.0])
    assert exact is not None and fast is not None and slow is not None
    assert slow < fast < exact and slow == 0  # a slower filter lags more: less delay is tolerated
    check = rate_margin(spec, reference, filter_hz=[10.0], delay_periods=1)
    assert not check.stable and "velocity differenced, filtered at 10 Hz" in describe_loop(check)
    # the stand-in with the drive's difference and 10 Hz filter: calm without delay, at its effort
    # limit (the loop oscillating) with one period
    limit = float(np.max(spec.robot_model().effort_limits))
    peaks = []
    for delay in (0, 1):
        given = {"velocity_source": "difference", "velocity_filter_hz": [10.0], "command_delay": delay}
        run = simulate(spec, check_stability=False, stand_in=StandIn(given=given))
        peaks.append(float(np.max(run.metrics.max_torque)))
    assert peaks[0] < 0.5 * limit and peaks[1] >= limit * (1 - 1e-9), peaks


def test_a_bad_cut_off_is_refused_in_one_line() -> None:
    spec = make_run("ur5", "circle", "pd")
    for bad in ([-1.0], [np.inf], [1.0, 2.0]):
        with pytest.raises(InvalidInputError, match="velocity filter cut-offs must be 1 or 6 finite numbers"):
            rate_margin(spec, spec.reference(), filter_hz=bad)


def test_check_gains_realism_bench_adds_the_drives_delay_and_filter(capsys: pytest.CaptureFixture[str]) -> None:
    from pdsmc_ros.sim.mujoco_lockstep import StandIn

    _, bench, _ = StandIn(preset="bench").resolve("ur5", 1000.0)
    delay, cutoff, viscous = bench.loop_terms()
    assert delay == 2 and cutoff is not None and np.all(cutoff == 100.0) and np.all(viscous == bench.friction_viscous)
    code = cli.main(["check-gains", "--robot", "ur5", "--contour", "circle", "--controller", "pd", "--realism",
                     "bench"])
    out = capsys.readouterr().out
    assert ("realtime (zero-order hold + 4 periods of delay + velocity differenced, filtered at 100 Hz + the arm's "
            "viscous damping") in out
    spec = make_run("ur5", "circle", "pd")
    expected = check_gains(spec, delay_periods=2, filter_hz=cutoff, friction_viscous=viscous)
    assert code == (0 if expected.passes else cli.EXIT_FAILURE)
    # the shipped UR5 PD gains do not hold the bench drive's lag in real time, the arm's damping counted
    assert code == cli.EXIT_FAILURE
    code = cli.main(["check-gains", "--robot", "ur5", "--contour", "circle", "--controller", "pd"])
    assert code == 0 and "velocity differenced" not in capsys.readouterr().out


def test_tune_realism_bench_keeps_only_gains_that_hold_on_that_arm(tmp_path: Path) -> None:
    from pdsmc_ros.experiments.tuning import Requirement, evaluate
    from pdsmc_ros.sim import simulate
    from pdsmc_ros.sim.mujoco_lockstep import StandIn

    spec = make_run("ur5", "circle", "pd")
    limit = np.asarray(spec.robot_model().effort_limits, dtype=float)
    plain, bench = Requirement(), Requirement(realism="bench")
    assert bench.loop_terms("ur5", 1000.0)[0] == 2 and "--realism bench" in bench.command()
    # the shipped gains pass the plain real-time check and are refused with the bench drive's lag
    assert evaluate(spec, spec.gains, limit, plain).ok
    refused = evaluate(spec, spec.gains, limit, bench)
    assert not refused.ok and "velocity differenced, filtered at 100 Hz" in refused.verdict
    # gentler gains pass both; their run is against the stand-in under bench
    gentle = spec.gains.scaled({"kp": 0.2, "kd": 0.4})
    kept = evaluate(spec, gentle, limit, bench)
    assert kept.ok, kept.verdict
    run = simulate(dataclasses.replace(spec, gains=gentle, enforce_limits=False), stand_in=StandIn(preset="bench"))
    assert kept.contour_mean == run.metrics.contour_mean
    with pytest.raises(Exception, match="realism must be one of ideal, bench"):
        Requirement(realism="lab")
    with pytest.raises(SystemExit) as stop:
        cli.main(["tune", "--robot", "ur5", "--contour", "circle", "--controller", "pd", "--realism", "lab",
                  "--out", str(tmp_path / "x.yaml")])
    assert stop.value.code == cli.EXIT_USAGE and not (tmp_path / "x.yaml").exists()


def test_tune_realism_bench_refuses_an_arm_held_at_its_start_by_friction() -> None:
    """The contour error is the distance to the nearest point of the path: an arm that never leaves
    its start scores zero. SMC gains too weak to break the bench arm's Coulomb friction (the ones
    ``tune --realism bench`` kept before the rule: 1.5e-7 m) are refused for not following."""
    from pdsmc_ros.experiments.tuning import FOLLOWS, Requirement, coverage, evaluate

    spec = make_run("ur5", "circle", "smc")
    limit = np.asarray(spec.robot_model().effort_limits, dtype=float)
    weak = spec.gains.scaled({"ks": 0.1 / 14.04, "lam": 0.2734 / 50.0})
    stuck = evaluate(spec, weak, limit, Requirement(realism="bench"))
    assert not stuck.ok and stuck.verdict.startswith("does not follow the contour"), stuck.verdict
    assert stuck.contour_mean is not None and stuck.contour_mean < 1e-5  # what it would have scored
    # the rule by hand: a box of half the path's diagonal covers 50 %, a point none
    path = np.array([[0.0, 0.0], [0.3, 0.0], [0.3, 0.3], [0.0, 0.3]])
    assert coverage(path / 2, path) == pytest.approx(0.5) and coverage(path[:1], path) == 0.0
    assert coverage(path, path) == 1.0 and FOLLOWS == 0.5


BENCH_FILES = sorted((Path(__file__).resolve().parents[2] / "config").glob("ur5_bench_*.yaml"))


@pytest.mark.parametrize("path", BENCH_FILES, ids=[p.stem for p in BENCH_FILES])
def test_the_ur5_bench_params_files_pass_the_bench_check_that_the_shipped_gains_fail(
        path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """config/ur5_bench_<law>.yaml (tools/bench_gains.py): accepted by ``check-gains --realism bench``
    at its x2 margin; the shipped gains of the same law are not (docs/explanation/ladder.md)."""
    law = path.stem.removeprefix("ur5_bench_")
    command = ["check-gains", "--robot", "ur5", "--contour", "circle", "--controller", law, "--rate", "1000",
               "--realism", "bench"]
    assert cli.main([*command, "--params-file", str(path)]) == 0, capsys.readouterr().out
    assert "4 periods of delay + velocity differenced, filtered at 100 Hz" in capsys.readouterr().out
    assert cli.main(command) == cli.EXIT_FAILURE


def test_a_bench_params_file_for_each_law_but_three() -> None:
    assert [p.stem for p in BENCH_FILES] == [f"ur5_bench_{law}" for law in ("ctc", "ismc", "pd", "pdg", "pdsmc", "smc")]
