"""Joint-space via points with quintic time scaling (issue 16): any arm, no inverse kinematics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros.contours import JointPath, load_joint_waypoints
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate


def test_the_path_rests_at_every_via_point_and_its_rates_are_its_derivatives() -> None:
    times, points = np.array([0.0, 1.0, 2.5]), np.array([[0.0, 1.0], [0.5, -1.0], [0.2, 0.0]])
    path = JointPath(times, points)
    at = path.sample(times)
    np.testing.assert_allclose(at.q, points, rtol=0, atol=1e-15)
    np.testing.assert_allclose(at.qd, 0.0, atol=1e-15)
    np.testing.assert_allclose(at.qdd, 0.0, atol=1e-12)
    t = np.linspace(0.2, 2.3, 21001)
    s = path.sample(t)
    np.testing.assert_allclose(np.gradient(s.q, t, axis=0)[1:-1], s.qd[1:-1], atol=1e-5)
    np.testing.assert_allclose(path.sample([5.0]).q[0], points[-1])  # held after the end


def test_files_load_as_csv_or_yaml_and_bad_ones_are_one_line(tmp_path: Path) -> None:
    csv = tmp_path / "via.csv"
    csv.write_text("t,q1,q2\n0,0,1\n1.5,0.5,-1\n")
    yaml = tmp_path / "via.yaml"
    yaml.write_text("points:\n  - {t: 0, q: [0, 1]}\n  - {t: 1.5, q: [0.5, -1]}\n")
    for path in (csv, yaml):
        times, points = load_joint_waypoints(path, 2)
        np.testing.assert_array_equal(times, [0.0, 1.5])
        np.testing.assert_array_equal(points, [[0.0, 1.0], [0.5, -1.0]])
    cases = {
        "0,0,1\n1,0.5\n": r"via.csv:2: expected 3 columns \(t, q1..q2\), got 2",
        "0,0,1\n1,x,1\n": r"via.csv:2: expected numbers",
        "0,0,1\n": "need at least 2 points, got 1",
        "0.5,0,1\n1,0,1\n": "times must start at 0 and increase",
    }
    for text, message in cases.items():
        csv.write_text(text)
        with pytest.raises(ConfigError, match=message) as info:
            load_joint_waypoints(csv, 2)
        assert "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="No such file or directory"):
        load_joint_waypoints(tmp_path / "missing.csv", 2)


def test_a_joint_path_run_on_the_serial_arm_tracks_it(tmp_path: Path) -> None:
    via = tmp_path / "via.csv"
    via.write_text("t,q1,q2,q3\n0,0.3,1.2,-0.5\n1.0,0.8,0.9,-0.2\n2.0,0.2,1.5,-1.0\n")
    spec = make_run("serial_3r", "joints", "pdsmc", waypoints_file=str(via))
    result = simulate(spec)
    assert result.spec.describe()["contour_definition"]["type"] == "joints"
    assert result.metrics.contour_mean < 5e-4 and max(result.metrics.axial_mean) < 1e-3
    with pytest.raises(ConfigError, match="contour 'joints' needs a file of joint via points"):
        make_run("serial_3r", "joints", "pdsmc").contour_model()
