"""``pdsmc analyze`` of a recorded graph: a bag written as the recorder's graph mode writes it.

A synthetic run with known answers: the arm follows a goal's quintic 10 ms late and 1 mrad off,
then a second goal is aborted a third of the way; the joint states come in another order than
the arm's. The bag holds what the recorder would: the driver's joint states, the controller's
state, the action's status, feedback and result events (their definitions from the installed
types, as the recorder derives them).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("control_msgs")
from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from pdsmc_ros.bag.writer import MessageAppender, flush_chunk, open_new_bag  # noqa: E402
from pdsmc_ros.experiments.analysis import analyze_graph_bag, goal_table  # noqa: E402
from pdsmc_ros.recorder.graph_types import type_definition  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
T0_NS = 1_795_000_000_000_000_000  # a wall-clock epoch, as a real driver stamps (times below count from it)
RATE = 1000.0
ARM = ["joint1", "joint2", "joint3"]
SENT = ["joint3", "joint1", "joint2"]  # the driver's order (alphabetical drivers, joint_state_broadcaster)
Q0 = np.array([0.1, 0.5, -0.3])
MOVE = np.array([0.2, 0.1, 0.1])
LAG, OFFSET = 0.01, 0.001


def quintic(t: np.ndarray, start: float, span: float, q0: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = np.clip((np.asarray(t) - start) / span, 0.0, 1.0)[:, None]
    inside = ((np.asarray(t) > start) & (np.asarray(t) < start + span))[:, None]
    return q0 + dq * (10 * s**3 - 15 * s**4 + 6 * s**5), inside * dq * (30 * s**2 - 60 * s**3 + 30 * s**4) / span


def stamp(msg_header, t: float) -> None:  # noqa: ANN001
    """Stamp ``t`` s after the epoch."""
    msg_header.stamp.sec, msg_header.stamp.nanosec = divmod(T0_NS + int(round(t * 1e9)), 1_000_000_000)


def write_bag(path: Path, *, truth: bool = False) -> dict:
    """The synthetic run's bag; returns what the analysis must find. ``truth``: the true state beside
    the measured one, as the MuJoCo stand-in publishes it (the measured one's offset removed)."""
    writer = open_new_bag(str(path))
    store = get_typestore(Stores.ROS2_JAZZY)
    appenders = {}
    topics = (("/mujoco_driver/true_joint_states", "sensor_msgs/msg/JointState"),) if truth else ()
    for topic, kind in (*topics, ("/joint_states", "sensor_msgs/msg/JointState"),
                        ("/robot_description", "std_msgs/msg/String"),
                        ("/ctl/follow_joint_trajectory/_action/status", "action_msgs/msg/GoalStatusArray"),
                        ("/ctl/follow_joint_trajectory/_action/feedback",
                         "control_msgs/action/FollowJointTrajectory_FeedbackMessage"),
                        ("/ctl/follow_joint_trajectory/_action/get_result/_service_event",
                         "control_msgs/action/FollowJointTrajectory_GetResult_Event")):
        msgdef, rihs01 = type_definition(store, kind)
        appenders[topic] = MessageAppender(writer, writer.add_connection(topic, kind, msgdef=msgdef, rihs01=rihs01))

    def put(topic: str, msg: object, t: float) -> None:
        ns = T0_NS + int(round(t * 1e9))
        appenders[topic].append_received([(serialize_message(msg), ns, ns)])

    put("/robot_description", String(data=make_robot("serial_3r").description()), 0.0)
    # goal 1: accepted at 1 s, a 1 s quintic, succeeded at 2.2 s; goal 2: a 0.9 s move of joint 1
    # from 3 s, aborted at 3.3 s (the arm stops where it is)
    g1, g2 = (1.0, 1.0), (3.0, 0.9)
    move2 = np.array([0.3, 0.0, 0.0])
    q_end1 = Q0 + MOVE
    t = np.arange(int(5.0 * RATE)) / RATE
    q, qd = quintic(t - LAG, *g1, Q0, MOVE)
    q2, qd2 = quintic(t - LAG, *g2, np.zeros(3), move2)
    stop = 3.3
    frozen = quintic(np.array([stop - LAG]), *g2, np.zeros(3), move2)[0][0]
    q = q + np.where((t >= stop)[:, None], frozen, q2) + OFFSET
    qd = qd + np.where((t >= stop)[:, None], 0.0, qd2)
    effort = np.column_stack([np.full(len(t), 5.0), np.full(len(t), 20.0), np.full(len(t), -3.0)])
    saturating = (t >= 1.5 - 1e-9) & (t < 1.5 + 6.5 / RATE)  # joint 2 at its 45 N m limit for 7 periods
    effort[saturating, 1] = 45.0
    order = [ARM.index(name) for name in SENT]
    for k, tk in enumerate(t):
        msg = JointState(name=SENT, position=q[k, order].tolist(), velocity=qd[k, order].tolist(),
                         effort=effort[k, order].tolist())
        stamp(msg.header, tk)
        put("/joint_states", msg, tk + 0.0005)  # received half a millisecond later
        if truth:
            exact = JointState(name=SENT, position=(q[k, order] - OFFSET).tolist(), velocity=qd[k, order].tolist(),
                               effort=effort[k, order].tolist())
            exact.header = msg.header
            put("/mujoco_driver/true_joint_states", exact, tk + 0.0005)
    ids = [bytes([1] * 16), bytes([2] * 16)]
    for i, ((start, span), dq, base, end, final) in enumerate(
            (((g1), MOVE, Q0, 2.2, GoalStatus.STATUS_SUCCEEDED),
             ((g2), move2, q_end1, stop, GoalStatus.STATUS_ABORTED))):
        info = GoalInfo()
        info.goal_id.uuid = list(ids[i])
        stamp(info, start)
        for when, status in ((start, GoalStatus.STATUS_EXECUTING), (end, final)):
            put("/ctl/follow_joint_trajectory/_action/status",
                GoalStatusArray(status_list=[GoalStatus(goal_info=info, status=status)]), when)
        for tf in np.arange(start + 0.05, end, 0.05):  # JTC's 20 Hz feedback
            desired, rate = quintic(np.array([tf]), start, span, base if i else Q0, dq)
            fb = FollowJointTrajectory.Impl.FeedbackMessage()
            fb.goal_id.uuid = list(ids[i])
            fb.feedback.joint_names = SENT
            fb.feedback.desired.positions = desired[0, order].tolist()
            fb.feedback.desired.velocities = rate[0, order].tolist()
            stamp(fb.feedback.header, tf)
            put("/ctl/follow_joint_trajectory/_action/feedback", fb, tf)
        event = FollowJointTrajectory.Impl.GetResultService.Event()
        request = FollowJointTrajectory.Impl.GetResultService.Request()
        request.goal_id.uuid = list(ids[i])
        response = FollowJointTrajectory.Impl.GetResultService.Response(status=final)
        response.result.error_code = 0 if i == 0 else FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
        response.result.error_string = "" if i == 0 else "joint1 path tolerance"
        event.request, event.response = [request], [response]
        put("/ctl/follow_joint_trajectory/_action/get_result/_service_event", event, end + 0.01)
    flush_chunk(writer)
    writer.close()
    return {"velocity_max": 1.875 * MOVE, "stop": stop}


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("graph") / "bag"
    write_bag(path)
    return path


def expected_error(start: float, end: float) -> np.ndarray:
    """Mean |q_d - q| of goal 1 on a fine grid over [start, end] (the analytic signals)."""
    t = np.linspace(start, end, 200_001)
    desired = quintic(t, 1.0, 1.0, Q0, MOVE)[0]
    actual = quintic(t - LAG, 1.0, 1.0, Q0, MOVE)[0] + OFFSET
    return np.mean(np.abs(desired - actual), axis=0)


def test_goals_of_a_recorded_graph_get_the_figures_of_a_simulated_run(bag: Path) -> None:
    result = analyze_graph_bag(bag, robot="serial_3r")
    assert result.run.names == ARM and len(result.run.t) == 5000
    assert abs(result.rate - RATE) < 1e-6 and result.late_periods == 0 and not result.diverged
    first, second = result.goals
    assert (first.status, first.result) == ("SUCCEEDED", "SUCCESSFUL")
    assert (second.status, second.result, second.error_string) == ("ABORTED", "PATH_TOLERANCE_VIOLATED",
                                                                   "joint1 path tolerance")
    assert first.start == pytest.approx(1.0) and first.end == pytest.approx(2.2 - 0.0005, abs=1e-6)
    assert first.reference.startswith("feedback")
    # the tracking error: the lag and the offset, by the simulated run's statistics
    metrics = first.metrics
    assert metrics is not None
    np.testing.assert_allclose(metrics.axial_mean, expected_error(1.05, 2.1995), rtol=5e-3)
    assert np.all(np.asarray(first.error_max) > OFFSET)
    assert metrics.saturated_periods == [0, 7, 0]  # joint 2 at its limit, as pdsmc analyze counts a run's
    assert metrics.max_torque == pytest.approx([5.0, 45.0, 3.0])
    assert len(metrics.error_rms) == 3 and metrics.run_scores["rate_hz"] == pytest.approx(RATE)
    # the desired motion ends at 2 s (a feedback sample falls on it); the arm, 10 ms late, is within
    # 0.01 rad of the end by then
    assert first.reference_end == pytest.approx(2.0, abs=1e-6)
    assert first.settle_time == pytest.approx(0.0, abs=0.011)
    np.testing.assert_allclose(first.velocity_max, 1.875 * MOVE, rtol=1e-3)
    assert first.velocity_limit == [25.0, 10.0, 10.0]
    # the aborted goal: the arm stopped a third of the way, never reaching its end
    assert second.settle_time is None
    assert second.late_periods == 0


def test_the_settle_band_decides_when_a_goal_has_settled(bag: Path) -> None:
    # a band inside the 1 mrad offset: never settled; a wide band: settled before the motion ended
    assert analyze_graph_bag(bag, robot="serial_3r", settle_band=0.0005).goals[0].settle_time is None
    assert analyze_graph_bag(bag, robot="serial_3r", settle_band=0.05).goals[0].settle_time == 0.0


def test_pdsmc_analyze_prints_a_column_per_goal_and_json(bag: Path) -> None:
    table = goal_table(analyze_graph_bag(bag, robot="serial_3r"))
    assert "goal 1 (SUCCEEDED)" in table and "ABORTED (PATH_TOLERANCE_VIOLATED)" in table
    assert "not settled" in table and "5000 joint states" in table
    run = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(bag), "--json"],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    [report] = json.loads(run.stdout)
    # without --robot: the limits of the bag's /robot_description (the thesis arm's URDF: no real limits)
    assert report["arm"] == "the bag's /robot_description" and len(report["goals"]) == 2
    assert report["goals"][0]["result"] == "SUCCESSFUL"
    bad = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(bag), "--settle-band", "-1"],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert bad.returncode != 0 and "--settle-band" in bad.stderr and "Traceback" not in bad.stderr


def test_the_contour_error_comes_from_the_true_state_where_the_bag_has_it(tmp_path: Path) -> None:
    """The arm follows the goal 10 ms late (on the desired path: no contour error) and its encoder
    reads 1 mrad off (an offset of the end effector): the true state's contour error is nil, the
    measured one's is the offset's; each says where it came from."""
    from pdsmc_ros.experiments.goal_figures import path_distance

    write_bag(tmp_path / "plain")
    write_bag(tmp_path / "truth", truth=True)
    measured = analyze_graph_bag(tmp_path / "plain", robot="serial_3r").goals[0]
    true = analyze_graph_bag(tmp_path / "truth", robot="serial_3r").goals[0]
    assert measured.contour_from == "/joint_states (the measured state; no true state recorded)"
    assert true.contour_from == "/mujoco_driver/true_joint_states (the true state)"
    assert measured.contour_mean is not None and measured.contour_mean > 2e-4
    # (not quite nil: in its first 10 ms the late arm is where the desired path, drawn from the goal's
    # first desired sample on, has not been)
    assert true.contour_mean is not None and true.contour_mean < measured.contour_mean / 100
    # the measured figure, by brute force over every pair of points on a fine grid
    model = make_robot("serial_3r")
    t = np.linspace(1.0, 2.2, 6001)
    desired = model.position(quintic(t, 1.0, 1.0, Q0, MOVE)[0])
    actual = model.position(quintic(t - LAG, 1.0, 1.0, Q0, MOVE)[0] + OFFSET)
    brute = np.sqrt(((actual[:, None, :] - desired[None, :, :]) ** 2).sum(-1)).min(axis=1)
    assert measured.contour_mean == pytest.approx(brute.mean(), rel=0.05)
    # path_distance: exact to the polyline's segments (brute force over every segment)
    a, b = desired[:-1], desired[1:]
    p = actual[::10, None, :]
    s = np.clip(((p - a) * (b - a)).sum(-1) / ((b - a) ** 2).sum(-1).clip(1e-300), 0.0, 1.0)
    exact = np.sqrt(((p - (a + s[..., None] * (b - a))) ** 2).sum(-1)).min(axis=1)
    np.testing.assert_allclose(path_distance(actual[::10], desired), exact, rtol=1e-9, atol=1e-12)
    table = goal_table(analyze_graph_bag(tmp_path / "truth", robot="serial_3r"))
    assert "contour error mean (m)" in table and "from /mujoco_driver/true_joint_states (the true state)" in table
