"""A sidecar that dies does not take the controller with it: the goal process killed (SIGKILL) or
stopped (SIGSTOP) mid-goal, and the gains' check process stopped mid-check.

The thesis serial 3R in the MuJoCo stand-in, the controller in real time (``goal_process:=always``
for the first two: this 2-core machine would otherwise serve the action in the controller's own
process) and a plain rclpy client in this process. Each test runs in a DDS domain of its own and
stops only the processes it started, by PID.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import next_domain

pytest.importorskip("rclpy")
pytest.importorskip("mujoco")
pytest.importorskip("control_msgs")
from action_msgs.msg import GoalStatus  # noqa: E402
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import GetParameters, SetParameters  # noqa: E402
from test_controller_mujoco import Client, goal_to, logs, quintic, start, stop  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from pdsmc_ros.ros.spun_node import wait_until  # noqa: E402

TAKEOVER_S = 2.0  # issue 54: a new goal accepted within 2 s of the child's end


def logged_pid(log: Path, pattern: str, seconds: float = 60.0) -> int:
    """The last pid the controller's log gives in a line matching ``pattern`` (its ``(\\d+)``)."""
    found: list[int] = []

    def look() -> bool:
        found[:] = [int(m) for m in re.findall(pattern, log.read_text())]
        return bool(found)

    assert wait_until(look, seconds, poll=0.1), log.read_text()
    return found[-1]


SERVES = r"goal process \(pid (\d+)\) serves"
CHECKS = r"gains' check runs in a process of its own \(pid (\d+)\)"


def accepted_after(client: Client, since: float, seconds: float = 30.0) -> float:
    """Seconds from ``since`` (monotonic) until a goal that stays where the arm is was accepted: sent as a
    client does once it sees a server, again every 0.2 s while unanswered or refused (a request sent
    before the client matched the new server's endpoints is lost)."""
    while time.monotonic() - since < seconds:
        if not client.action.server_is_ready():
            time.sleep(0.01)
            continue
        here = client.q()
        try:
            handle = client.call(lambda here=here: client.action.send_goal_async(goal_to(here, here, 0.3)), 0.2)
        except TimeoutError:
            continue
        if handle is not None and handle.accepted:  # type: ignore[attr-defined]
            return time.monotonic() - since
        time.sleep(0.05)
    return float("inf")


def parameters_answer(client: Client, seconds: float = 10.0) -> bool:
    """Whether /controller/get_parameters answers (the parameter services serve again)."""
    service = client.node.create_client(GetParameters, "/controller/get_parameters")
    try:
        if not service.wait_for_service(timeout_sec=seconds):
            return False
        answer = client.call(lambda: service.call_async(GetParameters.Request(names=["kp"])), seconds)
        return answer is not None and len(answer.values) == 1  # type: ignore[attr-defined]
    finally:
        client.node.destroy_client(service)


def set_kp(client: Client, kp: list[float], seconds: float = 30.0) -> tuple[bool, str, float]:
    """``(successful, reason, seconds to the answer)`` of setting ``kp`` through the parameter services."""
    service = client.node.create_client(SetParameters, "/controller/set_parameters")
    try:
        assert service.wait_for_service(timeout_sec=seconds)
        value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=kp)
        began = time.monotonic()
        answer = client.call(lambda: service.call_async(
            SetParameters.Request(parameters=[Parameter(name="kp", value=value)])), seconds)
        result = answer.results[0]  # type: ignore[attr-defined]
        return result.successful, result.reason, time.monotonic() - began
    finally:
        client.node.destroy_client(service)


@pytest.fixture
def arm(ros_env: dict, tmp_path: Path):  # noqa: ANN201
    """The stand-in, a controller with the given parameters and the client; all stopped at the end."""
    domain = next_domain()
    procs: list[subprocess.Popen] = []
    clients: list[Client] = []

    def make(*params: str) -> tuple[Client, Path]:
        procs.append(start(ros_env, domain, tmp_path / "driver.log", "mujoco_driver", "-p", "robot:=serial_3r"))
        log = tmp_path / "controller.log"
        procs.append(start(ros_env, domain, log, "controller", "-p", "robot:=serial_3r", "-p", "type:=pd",
                           "-p", "mode:=realtime", "-p", "rate:=1000.0", "-p", "kp:=[1200.0, 1200.0, 240.0]",
                           "-p", "kd:=[60.0, 60.0, 12.0]", "-p", "stale_periods:=200", *params))
        clients.append(Client(domain))
        assert clients[0].wait(lambda: len(clients[0].states) > 100, 90), logs(tmp_path)
        return clients[0], log

    yield make, tmp_path
    for client in clients:
        client.close()
    for proc in reversed(procs):
        stop(proc)


@pytest.mark.timeout(300)
@pytest.mark.parametrize("how", ["SIGKILL", "SIGSTOP"])
def test_the_goal_process_ended_mid_goal_aborts_it_holds_the_arm_and_is_replaced(arm, how: str) -> None:  # noqa: ANN001
    make, tmp_path = arm
    client, log = make("-p", "goal_process:=always")
    child = logged_pid(log, SERVES)
    assert client.action.wait_for_server(timeout_sec=60), logs(tmp_path)
    q0 = client.q()
    handle = client.send_goal(goal_to(q0, q0 + [0.6, 0.0, 0.0], 3.0))
    with client.spinning:  # asked at once, as a client waiting for the end does (rclpy, MoveIt)
        result = handle.get_result_async()  # type: ignore[attr-defined]
    time.sleep(0.8)
    os.kill(child, getattr(signal, how))
    ended = time.monotonic()
    # the client of the goal is told: aborted, with the reason (its result request died with the child
    # that held it; the controller's process answers it)
    assert wait_until(result.done, 10.0), logs(tmp_path)
    answered = time.monotonic() - ended
    response = result.result()
    print(f"{how}: the client got its result {answered:.2f} s after the signal: status {response.status}, "
          f"{response.result.error_code}, {response.result.error_string!r}")
    assert response.status == GoalStatus.STATUS_ABORTED, response
    assert "the goal process ended" in response.result.error_string, response
    if how == "SIGSTOP":  # found stopped, then killed; a killed one may be seen by its closed pipes first
        assert "stopped (SIGSTOP)" in response.result.error_string, response
    # the loop aborts the goal and holds: the arm stops short of the goal's end
    assert wait_until(lambda: "the goal process ended" in log.read_text(), 10), logs(tmp_path)
    time.sleep(0.3)
    at_abort = client.q()
    time.sleep(1.0)
    moved = float(np.max(np.abs(client.q() - at_abort)))
    assert moved < 0.02 and abs(client.q()[0] - (q0[0] + 0.6)) > 0.2, (moved, logs(tmp_path))
    text = log.read_text()
    assert "its goal aborted, the arm holds" in text, text
    # replaced: a new goal accepted within 2 s, the parameter services answer again, a gain change applies
    took = accepted_after(client, ended)
    print(f"{how}: a new goal accepted {took:.2f} s after the goal process ended")
    assert took < TAKEOVER_S, (took, logs(tmp_path))
    assert logged_pid(log, SERVES) != child
    assert parameters_answer(client), logs(tmp_path)
    successful, reason, _ = set_kp(client, [1100.0, 1100.0, 240.0])
    assert successful, reason
    assert wait_until(lambda: "gains changed" in log.read_text(), 10), logs(tmp_path)
    if how == "SIGSTOP":
        assert wait_until(lambda: subprocess.run(["kill", "-0", str(child)], capture_output=True).returncode != 0,
                          10), "the stopped child was not ended"


@pytest.mark.timeout(300)
def test_a_stopped_gain_check_is_a_refusal_and_the_next_change_is_checked(arm) -> None:  # noqa: ANN001
    make, tmp_path = arm
    client, log = make("-p", "goal_process:=never")
    checker = logged_pid(log, CHECKS)
    os.kill(checker, signal.SIGSTOP)
    successful, reason, took = set_kp(client, [1100.0, 1100.0, 240.0])
    print(f"a stopped gain check: refused after {took:.2f} s ({reason})")
    assert not successful and "stopped (SIGSTOP)" in reason and took < TAKEOVER_S, (reason, took)
    successful, reason, _ = set_kp(client, [1100.0, 1100.0, 240.0])
    assert successful, reason
    assert wait_until(lambda: "gains changed" in log.read_text(), 10), logs(tmp_path)


@pytest.mark.timeout(240)
@pytest.mark.parametrize("goal_process", ["never", "always"])
def test_goals_from_the_first_moment(arm, goal_process: str) -> None:  # noqa: ANN001
    """A client that sees the action server sends at once and is taken; one that sees the controller's
    ~/joint_trajectory subscription publishes one trajectory at once and the arm follows it (issue 54:
    both were refused, "the controller is not active", for about two seconds)."""
    make, tmp_path = arm
    client, log = make("-p", f"goal_process:={goal_process}")
    assert client.action.wait_for_server(timeout_sec=60), logs(tmp_path)
    here = client.q()
    handle = client.call(lambda: client.action.send_goal_async(goal_to(here, here, 0.2)))
    assert handle.accepted, logs(tmp_path)  # type: ignore[attr-defined]
    client.call(handle.get_result_async)  # type: ignore[attr-defined]
    # the topic: its subscription counted, one message, stamped 0 (start on receipt)
    assert client.wait(lambda: client.trajectory.get_subscription_count() > 0, 30), logs(tmp_path)
    q0 = client.q()
    q1 = q0 + [0.3, 0.0, 0.0]
    client.trajectory.publish(JointTrajectory(joint_names=["joint1", "joint2", "joint3"],
                                              points=quintic(q0, q1, 1.0)))
    time.sleep(2.0)
    assert abs(client.q()[0] - q1[0]) < 0.05, (client.q(), q1, logs(tmp_path))
    assert "refused" not in log.read_text() and "rejected" not in log.read_text(), logs(tmp_path)
