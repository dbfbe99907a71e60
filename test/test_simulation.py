"""Trajectories, control laws, compiled kernels, simulator, metrics and the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from pdsmc_ros.contours import (
    EllipseContour,
    SegmentContour,
    ellipse_distance,
    quintic,
)
from pdsmc_ros.control import ControlLaw
from pdsmc_ros.errors import ConfigError, UnreachableError, UnstableRateError
from pdsmc_ros.metrics.statistics import Samples, compute_metrics, sample_times
from pdsmc_ros.robots import Serial3R, compiled
from pdsmc_ros.runs.builder import build_contour, make_run
from pdsmc_ros.sim import PlantStepper, simulate


# --------------------------------------------------------------------------- #
# Trajectories
# --------------------------------------------------------------------------- #
def test_quintic_boundary_conditions_and_derivatives() -> None:
    s, sd, sdd = quintic([0.0, 2.0, -1.0, 3.0], 2.0)
    assert np.allclose(s, [0.0, 1.0, 0.0, 1.0])
    assert np.allclose(sd, 0.0) and np.allclose(sdd, 0.0)
    t = np.linspace(0.01, 1.99, 50)
    h = 1e-6
    s_p, sd_p, _ = quintic(t + h, 2.0)
    s_m, sd_m, _ = quintic(t - h, 2.0)
    _, sd, sdd = quintic(t, 2.0)
    assert np.allclose((s_p - s_m) / (2 * h), sd, atol=1e-7)
    assert np.allclose((sd_p - sd_m) / (2 * h), sdd, atol=1e-6)
    mid = quintic(1.0, 2.0)
    assert mid[0] == pytest.approx(0.5) and mid[2] == pytest.approx(0.0)


@pytest.mark.parametrize(
    ("robot", "contour"),
    [("serial_3r", "zigzag"), ("serial_3r", "ellipse"), ("parallel_5r", "ellipse_horizontal")],
)
def test_contour_rates_are_derivatives_of_positions(robot: str, contour: str) -> None:
    c = build_contour(robot, contour)
    t = np.linspace(0.05, c.duration - 0.05, 97)
    h = 1e-6
    fwd, back, mid = c.task(t + h), c.task(t - h), c.task(t)
    assert np.allclose((fwd.p - back.p) / (2 * h), mid.pd, atol=1e-6)
    assert np.allclose((fwd.pd - back.pd) / (2 * h), mid.pdd, atol=1e-5)


def test_serial_pose_interpolates_like_eq_4_5() -> None:
    ellipse = build_contour("serial_3r", "ellipse")
    p = ellipse.task([0.0, 4.0, 8.0]).p
    assert np.allclose(p[:, 2], [-np.pi, 0.0, np.pi])
    assert np.allclose(p[0, :2], [0.2, 0.0]) and np.allclose(p[2, :2], [0.2, 0.0])


@pytest.mark.parametrize(
    ("robot", "contour"),
    [("serial_3r", "diamond"), ("serial_3r", "circle"), ("parallel_5r", "circle"), ("parallel_5r", "zigzag")],
)
def test_joint_reference_is_continuous_and_consistent(robot: str, contour: str) -> None:
    spec = make_run(robot, contour, "pd")
    ref = spec.reference()
    model = spec.robot_model()
    t = np.linspace(0.0, ref.duration, 4001)
    js = ref.sample(t)
    task = ref.contour.task(t).p
    assert np.allclose(model.forward_kinematics(js.q)[..., : task.shape[1]], task, atol=1e-10)
    assert np.max(np.abs(np.diff(js.q, axis=0))) < 0.05  # no 2 pi jumps
    dt = t[1] - t[0]
    assert np.allclose(np.gradient(js.q, dt, axis=0)[1:-1], js.qd[1:-1], atol=2e-3)
    assert np.allclose(np.gradient(js.qd, dt, axis=0)[1:-1], js.qdd[1:-1], atol=2e-2)
    # independent of which instants were asked before
    single = ref.sample([t[1234]])
    assert np.array_equal(single.q[0], js.q[1234])


def test_diamond_reference_unwraps_like_table_4_4() -> None:
    ref = make_run("serial_3r", "diamond", "pd").reference()
    q_end = ref.sample([8.0]).q[0]
    q_start = ref.sample([0.0]).q[0]
    # q3 goes through -2 pi of pose: the reference must be continuous, so it ends ~12.57 lower
    assert q_end[2] - q_start[2] == pytest.approx(-16.81 - (-4.246), abs=5e-3)


def test_unreachable_contour_is_refused_with_time_and_point(tmp_path) -> None:  # noqa: ANN001
    path = tmp_path / "far.csv"
    path.write_text("x,y\n0.10,0.20\n0.50,0.20\n")
    spec = make_run("parallel_5r", "csv", "pd", waypoints_file=str(path))
    with pytest.raises(UnreachableError, match=r"leaves the parallel_5r workspace at t = [0-9.]+ s, point"):
        spec.reference()


def test_csv_contour_bad_file_is_a_clear_error(tmp_path) -> None:  # noqa: ANN001
    path = tmp_path / "bad.csv"
    path.write_text("x,y\n0.1,0.2\n0.1,abc\n")
    with pytest.raises(ConfigError, match=r"bad.csv:3: not a number"):
        make_run("parallel_5r", "csv", "pd", waypoints_file=str(path)).reference()
    with pytest.raises(ConfigError, match="cannot read waypoint file"):
        make_run("parallel_5r", "csv", "pd", waypoints_file=str(tmp_path / "missing.csv")).reference()


def test_ellipse_distance_of_points_along_the_normal() -> None:
    rx, ry = 0.2, 0.5
    th = np.linspace(0, 2 * np.pi, 73)
    normal = np.stack([ry * np.cos(th), rx * np.sin(th)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    for d in (1e-5, 3e-4, -2e-4):
        pts = np.stack([rx * np.cos(th), ry * np.sin(th)], axis=-1) + d * normal
        assert np.allclose(ellipse_distance(rx, ry, pts[:, 0], pts[:, 1]), abs(d), atol=1e-12)


def test_contour_error_formulas() -> None:
    circle = EllipseContour("c", [0.0, 0.1], 0.4, 0.4, 5.0, ellipse_error="nearest")
    xy = np.array([[0.4003, 0.1], [0.0, 0.1 - 0.3999]])
    assert np.allclose(circle.contour_error(np.zeros(2), xy), [3e-4, 1e-4])  # Eq. 2.10
    seg = SegmentContour("s", [[0.0, 0.0], [1.0, 1.0]], 2.0)
    t = np.array([1.0])
    on_line = seg.task(t).p + np.array([[0.3, 0.3]])  # along the segment: no contour error
    off = seg.task(t).p + np.array([[-1e-4, 1e-4]])
    assert seg.contour_error(t, on_line)[0] == pytest.approx(0.0, abs=1e-15)
    assert seg.contour_error(t, off)[0] == pytest.approx(np.sqrt(2) * 1e-4)  # Eq. 2.9
    ell = EllipseContour("e", [0.0, 0.0], 0.2, 0.5, 8.0, ellipse_error="osculating")
    pt = ell.task([2.0]).p[:, :2] * (1 + 1e-4)
    near = EllipseContour("e", [0.0, 0.0], 0.2, 0.5, 8.0, ellipse_error="nearest")
    assert ell.contour_error(np.array([2.0]), pt)[0] == pytest.approx(
        near.contour_error(np.array([2.0]), pt)[0], rel=1e-3
    )


# --------------------------------------------------------------------------- #
# Kernels against the numpy reference, control laws against their equations
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("robot", [Serial3R(), Serial3R(1.5)])
def test_kernels_match_reference_model(robot) -> None:  # noqa: ANN001
    """The serial arm's compiled terms against its planar chain in numpy. The five-bar's dynamics are
    written once (its numpy interface calls its compiled form): test_models holds them against the
    appendix's open tree with Lagrange multipliers, and test/sim/test_mujoco_model against MuJoCo."""
    rng = np.random.default_rng(7)
    kind, p = compiled.pack(robot)
    for _ in range(50):
        if robot.n == 3:
            q = rng.uniform(-3, 3, 3)
        else:
            q = robot.inverse_kinematics([0.16 + rng.uniform(-0.05, 0.05), 0.2 + rng.uniform(-0.05, 0.05)])
        qd, tau, v = rng.uniform(-2, 2, (3, robot.n))
        out = np.empty(robot.n)
        work = compiled.workspace(robot.n)
        compiled.forward_dynamics(kind, p, q, qd, tau, out, work)
        assert np.allclose(out, robot.forward_dynamics(q, qd, tau), rtol=0, atol=1e-11)
        compiled.coriolis_times(kind, p, q, qd, v, out, work)
        assert np.allclose(out, robot.coriolis_matrix(q, qd) @ v, rtol=0, atol=1e-12)
        compiled.gravity(kind, p, q, out, work)
        assert np.allclose(out, robot.gravity(q), rtol=0, atol=1e-12)


@pytest.mark.parametrize("controller", ["pd", "smc", "pdsmc"])
@pytest.mark.parametrize("robot", ["serial_3r", "parallel_5r"])
def test_control_laws_follow_the_thesis_equations(controller: str, robot: str) -> None:
    spec = make_run(robot, "circle", controller, smc_model={"damping": 1.0})
    law = ControlLaw.from_spec(spec)
    model = spec.nominal_model()
    g = spec.gains
    kp, kd, ks, lam, phi = (np.array(x) for x in (g["kp"], g["kd"], g["ks"], g["lam"], g["phi"]))
    rng = np.random.default_rng(11)
    ref = spec.reference().sample(rng.uniform(0, 5, 20))
    for k in range(20):
        q = ref.q[k] + rng.normal(0, 2e-3, model.n)
        qd = ref.qd[k] + rng.normal(0, 2e-2, model.n)
        tau = law.torque(q, qd, ref.q[k], ref.qd[k], ref.qdd[k])
        e, ed = ref.q[k] - q, ref.qd[k] - qd  # Eq. 3.2
        if controller == "pd":
            expected = kp * e + kd * ed  # Eq. 3.4
        elif controller == "pdsmc":
            expected = kp * e + kd * ed + ks * np.clip((lam * e + ed) / phi, -1, 1)  # Eq. 3.44
        else:
            e2, ed2 = -e, -ed  # Eq. 3.5
            s = ed2 + lam * e2  # Eq. 3.6
            qd_r = ref.qd[k] - lam * e2  # Eq. 3.7
            qdd_r = ref.qdd[k] - lam * ed2
            expected = (  # Eq. 3.15 with the boundary layer of Eq. 3.45
                0.9 * model.mass_matrix(q) @ qdd_r
                + 0.9 * model.coriolis_matrix(q, qd) @ qd_r
                + 1.1 * model.gravity(q)
                + model.B * qd_r
                - ks * np.clip(s / phi, -1, 1)
            )
        assert np.allclose(tau, expected, rtol=1e-12, atol=1e-10)


def test_plant_stepper_matches_in_process_loop() -> None:
    """The nodes' step wrappers reproduce the compiled closed loop bit for bit."""
    spec = make_run("serial_3r", "circle", "pdsmc")
    result = simulate(spec)
    ref = spec.reference()
    law = ControlLaw.from_spec(spec)
    plant = PlantStepper(spec.robot_model(), 1.0 / spec.rate, ref.sample([0.0]).q[0], np.zeros(3))
    steps = 200 * spec.sample_every
    t = np.arange(steps + 1) / spec.rate
    r = ref.sample(t)
    for k in range(steps):
        tau = law.torque(plant.q, plant.qd, r.q[k], r.qd[k], r.qdd[k])
        if k % spec.sample_every == 0:
            j = k // spec.sample_every
            assert np.array_equal(plant.q, result.samples.q[j])
            assert np.array_equal(tau, result.samples.tau[j])
        plant.step(tau)


# --------------------------------------------------------------------------- #
# Simulator against the thesis (PD / PD-SMC rows reproduce the continuous-time tables)
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize(
    ("robot", "contour", "controller", "thesis_contour_mean", "thesis_axial_mean"),
    [
        ("serial_3r", "circle", "pd", 1.133e-4, [5.136e-4, 3.145e-4, 2.520e-4]),
        ("serial_3r", "circle", "pdsmc", 9.422e-5, [3.485e-4, 2.630e-4, 1.806e-4]),
        ("parallel_5r", "circle", "pdsmc", 5.616e-5, [8.174e-4, 1.445e-3]),
    ],
)
def test_simulation_lands_on_thesis_tables(
    robot: str, contour: str, controller: str, thesis_contour_mean: float, thesis_axial_mean: list
) -> None:
    result = simulate(make_run(robot, contour, controller))
    assert result.metrics.contour_mean == pytest.approx(thesis_contour_mean, rel=0.01)
    assert np.allclose(result.metrics.axial_mean, thesis_axial_mean, rtol=0.01)


def test_statistics_sampling_matches_thesis_rates() -> None:
    assert len(sample_times(5.0, 500.0)) == 2501
    result = simulate(make_run("parallel_5r", "ellipse_vertical", "pd", scenario="high_speed"))
    assert result.metrics.samples == 5001  # 1 s at 5 kHz, inclusive


def test_discrete_stability_check_names_joint_and_rate() -> None:
    with pytest.raises(
        UnstableRateError, match=r"at 5000 Hz: joint \d \('joint\d'\) diverges.*lowest stable rate is about [0-9,]+ Hz"
    ):
        simulate(make_run("serial_3r", "circle", "pd", rate=5000.0))


def test_metrics_are_means_and_population_sd_of_absolute_errors() -> None:
    t = np.arange(4.0)
    q_ref = np.zeros((4, 2))
    q = np.array([[1.0, -2.0], [-1.0, 2.0], [3.0, 0.0], [-3.0, 0.0]])
    s = Samples(t, q, q_ref, np.zeros((4, 2)), np.ones((4, 2)), q, np.array([1.0, 3.0, 1.0, 3.0]))
    m = compute_metrics(s, bound=2.0)
    assert m.axial_mean == [2.0, 1.0]
    assert m.axial_sd == [1.0, 1.0]
    assert m.contour_within_pct == 50.0
    assert m.max_torque == [3.0, 2.0]
    assert m.task_mean["total"] == pytest.approx(np.sqrt(2))


def test_warm_up_changes_no_state_and_no_result() -> None:
    spec = make_run("parallel_5r", "circle", "pdsmc")
    start = spec.reference().sample([0.0])
    q0, qd0 = start.q[0], start.qd[0]
    cold, warm = PlantStepper(spec.robot_model(), 1e-3, q0, qd0), PlantStepper(spec.robot_model(), 1e-3, q0, qd0)
    warm.warm_up()
    assert warm.steps == 0 and np.array_equal(warm.q, q0) and np.array_equal(warm.qd, qd0)
    law_cold, law_warm = ControlLaw.from_spec(spec), ControlLaw.from_spec(spec)
    law_warm.warm_up(q0, qd0)
    for _ in range(3):
        tau = law_cold.torque(cold.q, cold.qd, q0, qd0, np.zeros(2))
        assert np.array_equal(tau, law_warm.torque(warm.q, warm.qd, q0, qd0, np.zeros(2)))
        cold.step(tau)
        warm.step(tau)
        assert np.array_equal(cold.q, warm.q) and np.array_equal(cold.qd, warm.qd)


def test_signed_task_sd_differs_from_absolute_only_where_the_error_changes_sign() -> None:
    t = np.arange(4.0)
    xy_ref = np.zeros((4, 2))
    # x error alternates +-1 (|e| constant: absolute S.D. 0, signed S.D. 1); y error 1, 2, 3, 4
    xy = -np.array([[1.0, 1.0], [-1.0, 2.0], [1.0, 3.0], [-1.0, 4.0]])
    q = np.zeros((4, 1))
    s = Samples(t, q, q, xy, xy_ref, q, np.zeros(4))
    m = compute_metrics(s, bound=1.0)
    assert m.task_sd["x"] == 0.0 and m.task_sd_signed["x"] == 1.0
    assert m.task_sd_signed["y"] == m.task_sd["y"] == pytest.approx(np.std([1.0, 2.0, 3.0, 4.0]))


def test_reproduction_reads_the_pdsmc_x_sd_as_signed_and_keeps_the_defined_value() -> None:
    from pdsmc_ros.experiments.thesis.cells import STATISTIC_READINGS, as_defined, compare

    results = [simulate(make_run("parallel_5r", "circle", c)) for c in ("pd", "pdsmc")]
    cells = {(c.controller, c.metric): c for c in compare(results)}
    read = cells[("pdsmc", "task_sd.x")]
    assert STATISTIC_READINGS[("pdsmc", "task_sd.x")][0] == read.ours_metric == "task_sd_signed.x"
    assert read.ours == results[1].metrics.task_sd_signed["x"]
    assert read.as_defined == results[1].metrics.task_sd["x"]
    # the PD row and every other statistic are compared as defined
    assert cells[("pd", "task_sd.x")].ours == results[0].metrics.task_sd["x"]
    assert all(c.ours == c.as_defined for key, c in cells.items() if key != ("pdsmc", "task_sd.x"))
    plain = {(c.controller, c.metric): c for c in as_defined(cells.values())}
    assert plain[("pdsmc", "task_sd.x")].ours == results[1].metrics.task_sd["x"]


# --------------------------------------------------------------------------- #
# CLI
# --------------------------------------------------------------------------- #
def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pdsmc_ros.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_cli_simulate_json_has_documented_keys() -> None:
    proc = run_cli("simulate", "--robot", "parallel_5r", "--contour", "ellipse_vertical",
                   "--controller", "pdsmc", "--scenario", "high_speed", "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    for key in ("axial_mean", "axial_sd", "task_mean", "task_sd", "contour_mean", "contour_sd",
                "contour_bound", "contour_within_pct", "max_torque", "run"):
        assert key in out
    assert set(out["task_mean"]) == {"x", "y", "total"}
    assert out["run"]["robot"] == "parallel_5r" and out["run"]["scenario"] == "high_speed"
    assert out["run"]["control_rate_hz"] == 5000.0 and "gains" in out["run"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--robot", "scara", "--contour", "circle", "--controller", "pd"],
         "unknown robot 'scara'; allowed: serial_3r, parallel_5r, ur5, ur10, ur3, panda, or a path to a .urdf file"),
        (["--robot", "serial_3r", "--contour", "circle", "--controller", "lqr"],
         "unknown controller 'lqr'; choose one of: pd, smc, pdsmc, pdg, ctc, sta, ismc"),
        (["--robot", "serial_3r", "--contour", "star", "--controller", "pd"], "unknown contour for serial_3r 'star'"),
        (
            ["--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--scenario", "x"],
            "unknown scenario 'x'",
        ),
        (
            ["--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--rate", "abc"],
            "--rate: expected a number in [0, 1e+06]",
        ),
        (["--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--rate", "9999"], "whole multiple"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(args: list, message: str) -> None:
    proc = run_cli("simulate", *args)
    assert proc.returncode == 2
    assert message in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert "Traceback" not in proc.stderr


def test_gain_reading_changes_only_its_runs_and_keeps_the_printed_result() -> None:
    """The vertical-ellipse PD runs use the read gains (before the scenario's factors); the
    printed preset is untouched, and the printed-gain run gives the cells' defined values."""
    from pdsmc_ros.experiments.thesis.cells import GAIN_READINGS, compare, matrix_specs, run_key
    from pdsmc_ros.experiments.thesis.reproduce import run_reproduction

    read = {run_key(s): s for s in matrix_specs()}
    printed = {run_key(s): s for s in matrix_specs(gain_readings=False)}
    assert read.keys() == printed.keys()
    changed = sorted(k for k in read if read[k].gains != printed[k].gains)
    assert changed and all(k.startswith("parallel_5r/ellipse_vertical/") and k.endswith("/pd") for k in changed)
    gains = GAIN_READINGS[("parallel_5r", "ellipse_vertical", "pd")][0]
    assert list(read["parallel_5r/ellipse_vertical/nominal/pd"].gains["kp"]) == gains["kp"]
    assert list(read["parallel_5r/ellipse_vertical/high_pd/pd"].gains["kd"]) == [1.5 * v for v in gains["kd"]]
    assert (
        make_run("parallel_5r", "ellipse_vertical", "pd").gains
        == printed["parallel_5r/ellipse_vertical/nominal/pd"].gains
    )

    rep = run_reproduction(only="parallel_5r/ellipse_vertical/nominal/pd", readings=False, workers=1)
    as_printed = simulate(printed["parallel_5r/ellipse_vertical/nominal/pd"])
    cells = {c.metric: c for c in rep.cells}
    assert cells["contour_sd"].ours == rep.results[0].metrics.contour_sd
    assert cells["contour_sd"].as_defined == as_printed.metrics.contour_sd != cells["contour_sd"].ours
    # without a printed run the defined value is the run's own
    assert all(c.as_defined == c.ours for c in compare([as_printed]))
