"""The ordinary real-time run end to end (issue 54's check, ``bench/ordinary_run.py``'s one run): the
MuJoCo stand-in of the serial 3R at 1 kHz in its own process, the controller as shipped (PD, real
time, every real-time setting at its default) given its joints in another order than the arm's, and
a plain rclpy client. One trajectory on ``~/joint_trajectory`` tracks within 1.5x of the same PD
against the same MuJoCo arm offline, and three FollowJointTrajectory goals end as expected
(succeeded, aborted for the path tolerance, canceled). The benchmark's own target (1.1x on a quiet
machine, over ten runs) is its, not this test's: the test machine is shared."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from conftest import next_domain

pytest.importorskip("rclpy")
pytest.importorskip("mujoco")
pytest.importorskip("control_msgs")

from bench import ordinary_run  # noqa: E402

WITHIN = 1.5  # issue 54: the end-to-end tests' bound on tracking against offline


@pytest.mark.timeout(300)
def test_the_ordinary_run_tracks_as_offline_and_ends_every_goal_as_expected(ros_env: dict, tmp_path: Path) -> None:
    index = 1  # the benchmark's odd runs give the controller its joints in another order than the arm's
    args = argparse.Namespace(domain=next_domain() - index, prefix="", param=[])
    run = ordinary_run.one_run(index, args, ros_env, tmp_path)
    logs = "\n".join(f"--- {log.name}\n{log.read_text()[-3000:]}" for log in sorted(tmp_path.glob("*.log")))
    assert "error" not in run, (run, logs)
    print(f"ratio to offline {run['ratio']:.3f}, drift {run['drift_mrad']:.1f} mrad, commands {run['commands']}, "
          f"first goal {run['first_goal_s']:.3f} s, goals {run['goals']}")
    assert run["first_goal_tries"] == 1, (run, logs)  # a client that sees the server is taken at once
    assert run["ratio"] <= WITHIN, (run, logs)
    assert run["goals_ok"], (run, logs)
