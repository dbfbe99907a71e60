"""FollowJointTrajectory goal files: written as the message's YAML, read back checked."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from pdsmc_ros.contours.goal_file import duration, goal_data, read_goal, seconds, write_goal
from pdsmc_ros.errors import ConfigError


def test_a_goal_round_trips_in_the_messages_layout(tmp_path: Path) -> None:
    t = np.array([0.5, 1.25, 3.0])
    q = np.arange(6.0).reshape(3, 2) / 7.0
    goal = goal_data(["a", "b"], t, q, q * 0.0, q * 0.0)
    write_goal(tmp_path / "goal.yaml", goal, "a comment\non two lines")
    text = (tmp_path / "goal.yaml").read_text()
    assert text.startswith("# a comment\n# on two lines\n")
    back = read_goal(tmp_path / "goal.yaml")
    assert back["trajectory"]["joint_names"] == ["a", "b"]
    assert [seconds(p["time_from_start"]) for p in back["trajectory"]["points"]] == pytest.approx(t.tolist())
    np.testing.assert_allclose([p["positions"] for p in back["trajectory"]["points"]], q, atol=1e-10)
    assert set(back) == {"trajectory", "path_tolerance", "goal_tolerance", "goal_time_tolerance"}


def test_durations_are_whole_seconds_and_nanoseconds() -> None:
    assert duration(1.9999999999) == {"sec": 2, "nanosec": 0}
    assert duration(0.25) == {"sec": 0, "nanosec": 250_000_000}


@pytest.mark.parametrize(("content", "message"), [
    ("[1, 2]", "expected a FollowJointTrajectory goal"),
    ("trajectory: {joint_names: [a], points: []}", "points must be a non-empty list"),
    ("trajectory: {joint_names: [], points: [{positions: [0], time_from_start: {sec: 0, nanosec: 0}}]}",
     "joint_names must be a non-empty list"),
    ("trajectory: {joint_names: [a], points: [{positions: [x], time_from_start: {sec: 0, nanosec: 0}}]}",
     r"points\[0\].positions must be a list of numbers"),
    ("trajectory: {joint_names: [a], points: [{positions: [0], time_from_start: 1.5}]}",
     r"time_from_start must be \{sec: N, nanosec: N\}"),
    (("trajectory: {joint_names: [a], points: [{positions: [0], time_from_start: {sec: 0, nanosec: 0}}]}\n"
     "speed: 2"), r"unknown key\(s\) \['speed'\]"),
    (("trajectory: {joint_names: [a], points: [{positions: [0], time_from_start: {sec: 0, nanosec: 0}}]}\n"
     "goal_tolerance: [{name: a, position: fast}]"), r"goal_tolerance\[0\] must be"),
    ("trajectory: [", "is not YAML"),
])
def test_a_bad_goal_file_is_one_line_naming_the_field(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "goal.yaml"
    path.write_text(content)
    with pytest.raises(ConfigError, match=message) as caught:
        read_goal(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_a_missing_goal_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        read_goal(tmp_path / "none.yaml")


def test_the_excitations_goal_is_at_rest_at_home_at_both_ends(tmp_path: Path) -> None:
    """``pdsmc excite`` on the thesis arm (a short search): its goal file reads back, starts after the
    lead at home at rest and ends there."""
    pytest.importorskip("pinocchio")
    from pdsmc_ros.cli import main

    out = tmp_path / "excite"
    assert main(["excite", "--robot", "serial_3r", "--out", str(out), "--period", "4", "--harmonics", "3",
                 "--periods", "2", "--starts", "1", "--iterations", "3", "--lead", "2"]) == 0
    goal = read_goal(out / "goal.yaml")
    points = goal["trajectory"]["points"]
    description = yaml.safe_load((out / "excitation.yaml").read_text())
    for point in (points[0], points[-1]):
        np.testing.assert_allclose(point["positions"], description["home"], atol=1e-9)
        np.testing.assert_allclose(point["velocities"], 0.0, atol=1e-12)
    assert seconds(points[0]["time_from_start"]) == pytest.approx(2.0)
    assert seconds(points[-1]["time_from_start"]) == pytest.approx(2.0 + 8.0)
    assert (out / "excitation.png").stat().st_size > 10_000
    assert description["condition_number"] <= description["start_condition_number"]
