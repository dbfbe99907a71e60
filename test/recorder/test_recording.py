"""The recorder beside a graph it did not start, and ``pdsmc analyze`` of what it recorded.

A plain rclpy publisher in this process publishes a known number of messages as fast as it
can while another process keeps a core busy: the bag holds every one, in order. Then the
shape of a real arm's run: the MuJoCo stand-in (``mujoco_driver``), the controller in real
time and a plain rclpy action client sending two goals (one that succeeds, one that breaks
its path tolerance), recorded by ``ros2 run pdsmc_ros recorder`` in graph mode and analysed
per goal; and the same graph started by ``scripts/run_experiment.sh --stand-in``, with a goal
sent from outside it. Each test runs its processes in a ROS domain of its own and stops them by PID.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import next_domain, stop_process

pytest.importorskip("rclpy")
pytest.importorskip("control_msgs")
import rclpy  # noqa: E402
import rclpy.executors  # noqa: E402
from action_msgs.msg import GoalStatus  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from pdsmc_ros.bag.cdr import decode_float64_multi_array  # noqa: E402
from pdsmc_ros.bag.mcapscan import scan  # noqa: E402
from pdsmc_ros.loop.lifecycle import EXIT_OK, EXIT_TEARDOWN_HUNG  # noqa: E402
from pdsmc_ros.ros.spun_node import SpunNode, wait_until  # noqa: E402

# a node whose work was done and saved may hang in Fast DDS's teardown and be ended by its watch's
# SIGALRM (scripts/run_experiment.sh counts that a warning, not a failure; Popen sees -SIGALRM)
DONE = (EXIT_OK, EXIT_TEARDOWN_HUNG, -signal.SIGALRM)

NAMES = ["joint1", "joint2", "joint3"]
COMMON = ["-p", "thread_priority:=0"]  # a shared 2-core test machine: no SCHED_FIFO spinning beside DDS
SERIAL_3R_VELOCITY_LIMITS = [25.0, 10.0, 10.0]  # config/robots.yaml


def start(env: dict, log: Path, executable: str, *params: str) -> subprocess.Popen:
    return subprocess.Popen(["ros2", "run", "pdsmc_ros", executable, "--ros-args", *COMMON, *params], env=env,
                            stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)


def logs(tmp_path: Path) -> str:
    return "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}" for p in sorted(tmp_path.glob("*.log")))


@pytest.mark.timeout(180)
def test_the_recorder_keeps_every_message_of_a_fast_publisher_on_a_busy_machine(ros_env: dict,
                                                                                   tmp_path: Path) -> None:
    count = 20_000
    env = dict(ros_env, ROS_DOMAIN_ID=str(next_domain()))
    bag = tmp_path / "bag"
    recorder = start(env, tmp_path / "recorder.log", "recorder", "-p", f"output:={bag}", "-p", "topics:=[/burst]")
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    publisher = SpunNode(int(env["ROS_DOMAIN_ID"]), "burst")
    try:
        # reliable, with a history as deep as the burst: the publisher never blocks and drops nothing
        # (a keep-all writer's publish() fails once its reader is 100 ms behind), so a loss would be the recorder's
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=count, reliability=ReliabilityPolicy.RELIABLE)
        pub = publisher.node.create_publisher(Float64MultiArray, "/burst", qos)
        # the recorder subscribes once it sees the publisher in the graph
        assert wait_until(lambda: pub.get_subscription_count() >= 1, 90), logs(tmp_path)
        began = time.monotonic()
        for i in range(count):
            pub.publish(Float64MultiArray(data=[float(i), 1.0, 2.0]))
        rate = count / (time.monotonic() - began)
        assert pub.wait_for_all_acked(rclpy.duration.Duration(seconds=60))
    finally:
        publisher.close()
        busy.kill()
        busy.wait()
        code, _ = stop_process(recorder)
    assert code in DONE, logs(tmp_path)
    data = scan(next(bag.glob("*.mcap")), ["/burst"]).messages["/burst"]
    values = [decode_float64_multi_array(d)[1][0] for d in data]
    print(f"published {count} at {rate:.0f}/s beside a busy core; recorded {len(values)}")
    assert values == [float(i) for i in range(count)]  # every one, in order


def quintic_goal(q0: np.ndarray, q1: np.ndarray, span: float, *, path: dict | None = None,
                 goal: dict | None = None, goal_time: float = 0.0) -> FollowJointTrajectory.Goal:
    zero = [0.0] * len(q0)
    points = [JointTrajectoryPoint(positions=list(q0), velocities=zero, accelerations=zero,
                                   time_from_start=Duration(sec=0)),
              JointTrajectoryPoint(positions=list(q1), velocities=zero, accelerations=zero,
                                   time_from_start=Duration(sec=int(span), nanosec=int(span % 1.0 * 1e9)))]
    return FollowJointTrajectory.Goal(
        trajectory=JointTrajectory(joint_names=NAMES, points=points),
        goal_time_tolerance=Duration(sec=int(goal_time), nanosec=int(goal_time % 1.0 * 1e9)),
        path_tolerance=[JointTolerance(name=n, position=v) for n, v in (path or {}).items()],
        goal_tolerance=[JointTolerance(name=n, position=v, velocity=0.2) for n, v in (goal or {}).items()])


@pytest.mark.timeout(240)
def test_a_stand_in_run_driven_through_the_action_is_recorded_and_analysed_per_goal(ros_env: dict,
                                                                                     tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    domain = next_domain()
    env = dict(ros_env, ROS_DOMAIN_ID=str(domain))
    bag = tmp_path / "bag"
    procs = [start(env, tmp_path / "recorder.log", "recorder", "-p", f"output:={bag}",
                   "-p", "topics:=[/joint_states,/effort_controller/commands,/controller/controller_state,"
                         "/diagnostics,/robot_description]",
                   "-p", "actions:=[/controller/follow_joint_trajectory]")]
    procs.append(start(env, tmp_path / "driver.log", "mujoco_driver", "-p", "robot:=serial_3r"))
    procs.append(start(env, tmp_path / "controller.log", "controller", "-p", "robot:=serial_3r", "-p", "type:=pd",
                       "-p", "mode:=realtime", "-p", "rate:=1000.0", "-p", "sample_rate:=1000.0",
                       "-p", "kp:=[800.0, 800.0, 160.0]", "-p", "kd:=[40.0, 40.0, 8.0]",
                       "-p", "stale_periods:=200"))
    client = SpunNode(domain, "client")
    states: list[np.ndarray] = []
    client.node.create_subscription(JointState, "/joint_states", lambda m: states.append(
        np.array([m.position[list(m.name).index(n)] for n in NAMES])), 1)
    commands: list[int] = []
    client.node.create_subscription(Float64MultiArray, "/effort_controller/commands",
                                    lambda m: commands.append(1), 1)
    action = ActionClient(client.node, FollowJointTrajectory, "/controller/follow_joint_trajectory")
    seen = []
    try:
        # the controller holds the arm, and this client has the arm's state
        assert wait_until(lambda: len(commands) > 100 and len(states) > 0, 120), logs(tmp_path)
        assert action.wait_for_server(timeout_sec=30)
        q0 = states[-1].copy()
        goals = [quintic_goal(q0, q0 + [0.2, 0.1, 0.1], 1.5, goal=dict.fromkeys(NAMES, 0.03), goal_time=2.0)]
        for goal in goals + [None]:
            if goal is None:  # the second goal starts where the first ended: joint 1 too fast for its path tolerance
                q = states[-1].copy()
                goal = quintic_goal(q, q + [0.6, 0.0, 0.0], 0.6, path={"joint1": 0.0005})
            handle = client.call(lambda g=goal: action.send_goal_async(g))
            assert handle.accepted  # type: ignore[attr-defined]
            answer = client.call(handle.get_result_async)  # type: ignore[attr-defined]
            seen.append((answer.status, answer.result.error_code))  # type: ignore[attr-defined]
            time.sleep(1.0)  # the hold after it, for the settling
    finally:
        action.destroy()
        client.close()
        codes = [stop_process(proc)[0] for proc in reversed(procs)]  # the recorder last
    assert seen == [(GoalStatus.STATUS_SUCCEEDED, FollowJointTrajectory.Result.SUCCESSFUL),
                    (GoalStatus.STATUS_ABORTED, FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED)], logs(tmp_path)
    assert codes[-1] in DONE, logs(tmp_path)

    analyze = [sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(bag), "--robot", "serial_3r"]
    table = subprocess.run(analyze, env=env, capture_output=True, text=True, timeout=120)
    print(table.stdout)
    assert table.returncode == 0, table.stderr
    assert "goal 1 (SUCCEEDED)" in table.stdout and "ABORTED (PATH_TOLERANCE_VIOLATED)" in table.stdout
    out = subprocess.run([*analyze, "--json"], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    [report] = json.loads(out.stdout)
    assert report["kind"] == "graph" and report["joints"] == NAMES
    assert report["joint_states"]["count"] > 1000 and 900 < report["joint_states"]["rate_hz"] < 1100
    first, second = report["goals"]
    # what the client saw, as the bag shows it (the status topic, and the result the recorder asked for)
    assert [(g["status"], g["result"]) for g in report["goals"]] == [("SUCCEEDED", "SUCCESSFUL"),
                                                                     ("ABORTED", "PATH_TOLERANCE_VIOLATED")]
    # the desired state from the goal's feedback or, where the controller sent none, its controller_state
    assert not report["diverged"] and first["reference"].split(" (")[0] in ("feedback", "controller_state"), first
    assert "joint1" in second["error_string"]
    # each goal's own trajectory, from the controller's send_goal events (action_introspection)
    assert [g["trajectory"] for g in report["goals"]] == ["2 points over 1.500 s", "2 points over 0.600 s"]
    # the first goal: tracked closely, settled within its goal time, moved, below the limits
    metrics = first["metrics"]
    if metrics is None:  # a loaded machine: the controller's state came too sparsely to draw the desired curve
        assert "too sparse" in first["reference"], first
    else:
        assert all(0.0 < e < 0.03 for e in metrics["axial_mean"]), metrics["axial_mean"]
        assert all(np.isfinite(metrics[k]).all() for k in ("max_torque", "error_rms", "torque_tv_rate"))
    assert 0.0 <= first["settle_time"] < 2.0, first
    assert 0.1 < first["velocity_max"][0] < SERIAL_3R_VELOCITY_LIMITS[0], first["velocity_max"]
    assert all(0.0 <= v < limit for v, limit in zip(first["velocity_max"], SERIAL_3R_VELOCITY_LIMITS, strict=True))
    assert first["velocity_limit"] == SERIAL_3R_VELOCITY_LIMITS
    # the second: aborted on its path, far from its end: not settled there
    assert second["settle_time"] is None
    assert second["start"] > first["end"] > first["start"] >= 0.0
    assert os.path.isdir(bag)


@pytest.mark.timeout(240)
def test_run_experiment_stand_in_records_a_goal_sent_from_outside(ros_env: dict, tmp_path: Path) -> None:
    """``scripts/run_experiment.sh --stand-in``: the stand-in, the controller and the recorder for
    ``--seconds``; a goal sent meanwhile by a client the script did not start is in the bag."""
    pytest.importorskip("mujoco")
    domain = next_domain()
    env = dict(ros_env, ROS_DOMAIN_ID=str(domain))
    bag = tmp_path / "bag"
    script = subprocess.Popen(
        ["bash", str(Path(__file__).resolve().parents[2] / "scripts" / "run_experiment.sh"), "--stand-in",
         "serial_3r", "--controller", "pd", "--param", "kp:=[800.0, 800.0, 160.0]", "--param",
         "kd:=[40.0, 40.0, 8.0]", "--param", "thread_priority:=0", "--param",
         "stale_periods:=200", "--seconds", "25", "--out", str(bag)],
        env=env, stdout=(tmp_path / "script.log").open("w"), stderr=subprocess.STDOUT, start_new_session=True)
    client = SpunNode(domain, "client")
    states: list[np.ndarray] = []
    client.node.create_subscription(JointState, "/joint_states", lambda m: states.append(
        np.array([m.position[list(m.name).index(n)] for n in NAMES])), 1)
    commands: list[float] = []
    client.node.create_subscription(Float64MultiArray, "/effort_controller/commands",
                                    lambda m: commands.append(time.monotonic()), 1)
    action = ActionClient(client.node, FollowJointTrajectory, "/controller/follow_joint_trajectory")
    try:
        assert action.wait_for_server(timeout_sec=60), logs(tmp_path)
        # the driver's states flow from its start; the controller commands once active (as
        # joint_trajectory_controller, it rejects goals until then, and its server exists before)
        assert wait_until(lambda: len(states) > 100 and len(commands) > 100, 60), logs(tmp_path)
        time.sleep(1.0)  # the recorder's discovery of the goal topics
        q0 = states[-1].copy()
        handle = client.call(lambda: action.send_goal_async(quintic_goal(q0, q0 + [0.1, 0.1, 0.1], 1.0)))
        assert handle.accepted, logs(tmp_path)  # type: ignore[attr-defined]
        answer = client.call(handle.get_result_async)  # type: ignore[attr-defined]
        assert answer.result.error_code == FollowJointTrajectory.Result.SUCCESSFUL  # type: ignore[attr-defined]
        code = script.wait(timeout=90)
    finally:
        action.destroy()
        client.close()
        if script.poll() is None:
            stop_process(script)
    log = (tmp_path / "script.log").read_text()
    assert code == 0, log + logs(bag.parent / "bag.logs")
    out = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "analyze", str(bag), "--robot", "serial_3r",
                          "--json"], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    (goal,) = json.loads(out.stdout)[0]["goals"]
    assert (goal["status"], goal["result"], goal["trajectory"]) == ("SUCCEEDED", "SUCCESSFUL", "2 points over 1.000 s")
