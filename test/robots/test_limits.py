"""Robot limits as data, applied by default, and the options YAML beside a URDF checked (issue 29).

The arm is the tests' own (arm4.py: effort limits 40, 40, 20, 6 N m), not the project's config.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from arm4 import EFFORT, OPTIONS, VELOCITY, write_arm

from pdsmc_ros.errors import ConfigError
from pdsmc_ros.robots import ROBOTS, make_robot
from pdsmc_ros.robots.catalog import resolve_robot
from pdsmc_ros.robots.registry import unregister_robot
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate


def pdsmc(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", *args], capture_output=True, text=True,
                          timeout=300)


@pytest.fixture
def arm(tmp_path: Path):  # noqa: ANN201
    urdf, points = write_arm(tmp_path / "arm")
    yield urdf, points
    unregister_robot(str(urdf))


def test_limits_come_from_the_urdf_and_the_options_override_them(arm: tuple[Path, Path]) -> None:
    urdf, _ = arm
    robot = make_robot(resolve_robot(str(urdf)))
    np.testing.assert_array_equal(robot.effort_limits, EFFORT)
    np.testing.assert_array_equal(robot.velocity_limits, [VELOCITY] * 4)
    np.testing.assert_array_equal(robot.position_limits, [[-2.5, 2.5]] * 4)
    unregister_robot(str(urdf))
    (urdf.parent / "arm4.yaml").write_text(OPTIONS + "effort_limits: [30, 30, 15, 5]\nvelocity_limits: 3.0\n"
                                           "position_limits: [[-1, 1], [-2, 2], [-2, 2], [-.inf, .inf]]\n")
    robot = make_robot(resolve_robot(str(urdf)))
    np.testing.assert_array_equal(robot.effort_limits, [30, 30, 15, 5])
    np.testing.assert_array_equal(robot.velocity_limits, [3.0] * 4)
    np.testing.assert_array_equal(robot.position_limits[3], [-np.inf, np.inf])


def test_the_thesis_arms_have_limits_no_thesis_run_reaches() -> None:
    serial, five_bar = make_robot("serial_3r"), make_robot("parallel_5r")
    assert serial.effort_limits.shape == (3,) and five_bar.effort_limits.shape == (2,)
    assert np.all(np.isfinite(serial.effort_limits)) and np.all(np.isfinite(five_bar.velocity_limits))
    assert np.all(np.isinf(serial.position_limits))  # planar joints turn freely
    # the heaviest serial case (payload, SMC) and a five-bar high-speed case: nothing clamped
    for spec in (make_run("serial_3r", "ellipse", "smc", scenario="payload"),
                 make_run("parallel_5r", "ellipse_vertical", "pd", scenario="high_speed")):
        result = simulate(spec)
        assert result.metrics.saturated_periods == [0] * len(result.metrics.max_torque)
        assert not result.diverged and not result.limit_warnings


def test_simulate_clamps_to_the_effort_limits_and_reports_it(arm: tuple[Path, Path]) -> None:
    urdf, points = arm
    spec = make_run(str(urdf), "joints", "pd", waypoints_file=str(points))
    clamped = simulate(spec)
    free = simulate(dataclasses.replace(spec, enforce_limits=False))
    assert free.metrics.max_torque[3] > 8.0  # what the law asks of the wrist
    assert clamped.metrics.max_torque[3] == EFFORT[3]  # what it gets
    assert clamped.metrics.saturated_periods[3] > 100
    assert free.metrics.saturated_periods == [0, 0, 0, 0]
    assert all(t <= limit for t, limit in zip(clamped.metrics.max_torque, EFFORT, strict=True))
    # the CLI: the clamp in the statistics, one line on stderr; --no-enforce-limits opts out
    proc = pdsmc("simulate", "--robot", str(urdf), "--contour", "joints", "--waypoints", str(points),
                 "--controller", "pd", "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["max_torque"][3] == EFFORT[3] and result["saturated_periods"][3] > 100
    assert result["run"]["enforce_limits"] is True
    clamp_lines = [line for line in proc.stderr.splitlines() if "clamped" in line]
    assert len(clamp_lines) == 1 and "joint 4 (|tau| <= 6 N m)" in clamp_lines[0]
    proc = pdsmc("simulate", "--robot", str(urdf), "--contour", "joints", "--waypoints", str(points),
                 "--controller", "pd", "--json", "--no-enforce-limits")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["max_torque"][3] > 8.0 and "clamped" not in proc.stderr


def test_the_plant_warns_once_per_joint_on_its_velocity_limit(arm: tuple[Path, Path]) -> None:
    urdf, points = arm
    result = simulate(make_run(str(urdf), "joints", "pd", waypoints_file=str(points)))
    wrist = [w for w in result.limit_warnings if "'wrist'" in w]
    assert len(wrist) == 1 and "beyond its velocity limit 2 rad/s at t = " in wrist[0]


@pytest.mark.parametrize(("extra", "message"), [
    ("armature: [0.05, 0.05, 0.05]\n",
     (r"arm4.yaml: armature needs 4 numbers \(one per joint: base_yaw, shoulder, elbow, wrist\) or one number "
      r"for all, got 3 values")),
    ("home: [0, 0, 0]\n", r"arm4.yaml: home needs 4 numbers \(one per joint: .*\), got 3 values"),
    ("effort_limits: [40, 40, 20]\n", r"arm4.yaml: effort_limits needs 4 numbers"),
    ("effort_limits: [40, 40, 20, 0]\n", r"arm4.yaml: effort_limits of joint 'wrist' must be a number > 0, got 0.0"),
    ("velocity_limits: fast\n", r"arm4.yaml: velocity_limits needs 4 numbers .*, got 'fast'"),
    ("position_limits: [[-1, 1], [-1, 1], [1, -1], [-1, 1]]\n",
     r"arm4.yaml: position_limits of joint 'elbow' must be \[lower, upper\] with lower < upper"),
    ("position_limits: [-1, 1]\n", r"arm4.yaml: position_limits needs 4 pairs \[lower, upper\]"),
    ("ee_frame: 3\n", r"arm4.yaml: ee_frame must be a name \(a string\), got 3"),
    ("locked_joints: wrist\n", r"arm4.yaml: locked_joints must be a list of joint names, got 'wrist'"),
    ("plane: {origin: [0, 0], u: [1, 0, 0], v: [0, 0, 1]}\n", r"arm4.yaml: plane must give origin, u and v"),
    ("contour_size: -1\n", r"arm4.yaml: contour_size must be a number > 0"),
    ("armatur: 0.05\n", r"arm4.yaml: unknown key\(s\) \['armatur'\]; allowed: armature, ee_frame, .*gains"),
])
def test_each_bad_option_is_one_line_naming_the_file_and_key(tmp_path: Path, extra: str, message: str) -> None:
    options = "\n".join(line for line in OPTIONS.splitlines() if not line.startswith(extra.split(":")[0] + ":"))
    urdf, _ = write_arm(tmp_path / "arm", options=options + "\n" + extra)
    try:
        with pytest.raises(ConfigError, match=message) as info:
            resolve_robot(str(urdf))
        assert "\n" not in str(info.value) and "broadcast" not in str(info.value)
    finally:
        unregister_robot(str(urdf))


def test_a_continuous_joint_is_refused_naming_it(tmp_path: Path) -> None:
    urdf, _ = write_arm(tmp_path / "arm", wrist="continuous")
    with pytest.raises(ConfigError, match=r"joint 'wrist' is continuous") as info:
        resolve_robot(str(urdf))
    assert "JointModel" not in str(info.value)
    assert str(urdf) not in ROBOTS


def test_a_bad_option_from_the_cli_is_one_line_and_exit_2(tmp_path: Path) -> None:
    urdf, points = write_arm(tmp_path / "arm", options=OPTIONS.replace("armature: 0.05", "armature: [1, 2, 3]"))
    proc = pdsmc("simulate", "--robot", str(urdf), "--contour", "joints", "--waypoints", str(points),
                 "--controller", "pd")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "arm4.yaml: armature needs 4 numbers" in proc.stderr
    assert "Traceback" not in proc.stderr
