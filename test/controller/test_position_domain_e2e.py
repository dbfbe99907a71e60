"""The position domain PD-SMC on the UR5 stand-in in real time: goals that turn back and a master at rest.

The UR5 of example-robot-data in MuJoCo (``ros2 run pdsmc_ros mujoco_driver``) and the controller
with ``type:=pdsmc_pos`` in real time at 1 kHz (the UR5's circle presets: the PD-SMC's, with
``v_rest = 0.7`` rad/s, the smallest of those measured that the real-time check accepts on the UR5's
circle, x2.014; the presets' 0.05 gives x1.96 there: docs/explanation/position-domain.md), in a DDS
domain of their own, stopped by PID. The goals
(``FollowJointTrajectory``) stop at every point, so the reference comes to rest at each (the law
goes back to the time domain there, docs/explanation/position-domain.md); one has a segment in which
the first segment's master, the shoulder pan, stays at rest while the shoulder lift and the elbow
move (the master goes to the joint that moves), and the next goal turns every joint back. Every goal
ends SUCCEEDED within its path and goal tolerances, and calm: every joint under 25 % of its
velocity limit once it has ended.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mujoco")
pytest.importorskip("control_msgs")
from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from stand_in_arm import StandInArm, duration  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from pdsmc_ros.robots import make_robot  # noqa: E402
from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402

UR5 = make_robot(resolve_robot("ur5"))
JOINTS = list(UR5.joint_names)
CALM = 0.25  # of each joint's velocity limit, once a goal has ended
PATH_TOL = 0.05  # rad
GOAL_TOL = 0.03  # rad


def velocities_since(client: StandInArm, start: float) -> np.ndarray:
    with client.lock:
        return np.array([s[2] for s in client.states if s[0] >= start])


def goal(points: list[tuple[np.ndarray, float]]) -> FollowJointTrajectory.Goal:
    """Points ``(q, t)``, each with zero velocity; the path and goal tolerances on every joint."""
    zero = [0.0] * len(JOINTS)
    trajectory = JointTrajectory(joint_names=JOINTS, points=[
        JointTrajectoryPoint(positions=[float(x) for x in q], velocities=zero, time_from_start=duration(t))
        for q, t in points])
    return FollowJointTrajectory.Goal(
        trajectory=trajectory, goal_time_tolerance=duration(2.0),
        path_tolerance=[JointTolerance(name=j, position=PATH_TOL) for j in JOINTS],
        goal_tolerance=[JointTolerance(name=j, position=GOAL_TOL, velocity=0.2) for j in JOINTS])


@pytest.mark.timeout(300)
def test_goals_that_turn_back_and_leave_the_master_at_rest_end_calm(ros_env: dict, tmp_path: Path) -> None:
    client = StandInArm(ros_env, tmp_path, "position_domain_client", JOINTS, keep=20000,
                        driver=["-p", "robot:=ur5"],
                        controller=["-p", "robot:=ur5", "-p", "contour:=circle", "-p", "type:=pdsmc_pos",
                                    "-p", "v_rest:=0.7", "-p", "mode:=realtime", "-p", "rate:=1000.0",
                                    "-p", "sample_rate:=500.0", "-p", "stale_periods:=200"])
    logs = client.logs
    try:
        assert client.up(), logs()
        time.sleep(2.0)  # settled in the hold of activation
        q0 = client.q()
        lift = q0 + [0.3, 0.05, -0.05, 0.0, 0.0, 0.0]  # the pan leads: the master
        # the pan at rest for this segment, the lift and the elbow move: the master goes to the one that moves
        rest = lift + [0.0, 0.25, -0.2, 0.0, 0.0, 0.0]
        goals = {"the master at rest for a segment": goal([(q0, 0.0), (lift, 1.5), (rest, 3.0)]),
                 "every joint turning back": goal([(rest, 0.0), (q0, 4.0)])}
        for name, g in goals.items():
            handle = client.call(lambda g=g: client.action.send_goal_async(g), 30, logs)
            assert handle.accepted, (name, logs())  # type: ignore[attr-defined]
            answer = client.call(handle.get_result_async, 60, logs)  # type: ignore[attr-defined]
            ended = time.monotonic()
            status, code, text = answer.status, answer.result.error_code, answer.result.error_string
            assert (status, code) == (GoalStatus.STATUS_SUCCEEDED, FollowJointTrajectory.Result.SUCCESSFUL), \
                (name, text, logs())
            time.sleep(1.0)
            speeds = np.max(np.abs(velocities_since(client, ended)), axis=0)
            share = speeds / UR5.velocity_limits
            print(f"{name}: after the end, peak |qd| / limit per joint {np.round(share, 4).tolist()}")
            assert np.all(share < CALM), (name, share, logs())
        assert np.max(np.abs(client.q() - q0)) < GOAL_TOL + 0.01, logs()
    finally:
        client.close()
