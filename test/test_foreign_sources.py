"""The controller driven by sources that are not this package's nodes (issue 14).

A plain rclpy node in this process plays a robot driver (wall-stamped
``/joint_states`` in its own order with an extra joint), a reference source,
a user with ``ros2 param set`` and lifecycle tools, and a forward command
controller listening to the efforts. The controller runs as its own process
(``ros2 run pdsmc_ros controller``) in a DDS domain of its own and is stopped
by its PID only.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
from conftest import next_domain, stop_process

from pdsmc_ros.control import ControlLaw, Gains
from pdsmc_ros.control.stability import check_rate
from pdsmc_ros.errors import UnstableRateError
from pdsmc_ros.runs.builder import make_run

pytest.importorskip("rclpy")
import rclpy.clock  # noqa: E402
import rclpy.duration  # noqa: E402
import rclpy.executors  # noqa: E402

if TYPE_CHECKING:
    from diagnostic_msgs.msg import DiagnosticArray

RATE = 2000.0  # the five-bar's preset gains hold in real time (two periods of delay) at x2.1 here
Q = {"joint1": 0.3, "joint2": 1.2}  # the driver's state, by name
QD = {"joint1": 0.1, "joint2": -0.2}
REF = ((0.35, 1.1), (0.05, 0.02), (0.5, -0.4))  # joint1, joint2: q, qd, qdd


def spec(controller: str = "pd"):  # noqa: ANN201
    return make_run("parallel_5r", "circle", controller, rate=RATE, sample_rate=RATE)


class Driver:
    """A plain rclpy node: publishes states and references, records what comes back."""

    def __init__(self, domain: int) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        from trajectory_msgs.msg import JointTrajectory

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("driver", context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.pub_state = self.node.create_publisher(JointState, "/joint_states", 10)
        self.pub_ref = self.node.create_publisher(JointTrajectory, "/reference", 10)
        self.pub_traj = self.node.create_publisher(JointTrajectory, "/controller/joint_trajectory", 10)
        self.efforts: list[tuple[float, tuple[float, ...], int]] = []
        self.diagnostics: list[tuple[int, str]] = []
        self.latest_level: dict[str, int] = {}  # each status name's latest level
        self.node.create_subscription(
            Float64MultiArray, "/effort_controller/commands",
            lambda m: self.efforts.append((time.monotonic(), tuple(m.data), m.layout.data_offset)), 100)
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics",
            self.on_diagnostics, 100)
        self.state: Callable[[], object] | None = None
        self.reference: Callable[[], object] | None = None
        self.node.create_timer(0.005, self.publish)

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            level = status.level[0] if isinstance(status.level, bytes) else status.level
            self.diagnostics.append((level, status.message))
            self.latest_level[status.name] = level

    def publish(self) -> None:
        if self.state is not None:
            self.pub_state.publish(self.state())
        if self.reference is not None:
            self.pub_ref.publish(self.reference())

    def spin(self, seconds: float, until: Callable[[], bool] | None = None) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)
            if until is not None and until():
                return

    def call(self, srv_type: type, name: str, request: object, timeout: float = 30.0):  # noqa: ANN201
        client = self.node.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=timeout), f"no service {name}"
        future = client.call_async(request)
        self.executor.spin_until_future_complete(future, timeout_sec=timeout)
        assert future.done(), f"{name} did not answer"
        return future.result()

    def set_parameter(self, name: str, values: list[float]) -> tuple[bool, str]:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(parameters=[Parameter(name, value=values).to_parameter_msg()])
        result = self.call(SetParameters, "/controller/set_parameters", request).results[0]
        return result.successful, result.reason

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def joint_state(driver: Driver, names: list[str], q: dict, qd: dict):  # noqa: ANN201
    """A JointState stamped with the wall clock, in the order of ``names``."""
    from sensor_msgs.msg import JointState

    msg = JointState()
    msg.header.stamp = rclpy.clock.Clock().now().to_msg()  # system time, as drivers stamp
    msg.name = names
    msg.position = [q.get(n, 7.0) for n in names]
    msg.velocity = [qd.get(n, 0.0) for n in names]
    return msg


def reference_message(names: list[str]):  # noqa: ANN201
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    by_name = {"joint1": 0, "joint2": 1}
    msg = JointTrajectory()
    msg.header.stamp = rclpy.clock.Clock().now().to_msg()
    msg.joint_names = names
    msg.points = [JointTrajectoryPoint(
        positions=[REF[0][by_name[n]] for n in names], velocities=[REF[1][by_name[n]] for n in names],
        accelerations=[REF[2][by_name[n]] for n in names])]
    return msg


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch, ros_env: dict) -> int:
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return next_domain()


def start_controller(ros_env: dict, domain: int, log: Path, *params: str) -> subprocess.Popen:
    args = [
        "ros2",
        "run",
        "pdsmc_ros",
        "controller",
        "--ros-args",
        "-p",
        "robot:=parallel_5r",
        "-p",
        "mode:=realtime",
        "-p",
        f"rate:={RATE}",
        "-p",
        f"sample_rate:={RATE}",
        "-p",
        "stale_periods:=400",
        # the five-bar's preset PD gains hold at 2 kHz with two periods of delay at about x2.1 of their
        # lowest stable rate: a margin this test is not about
        "-p",
        "stability_margin:=1.5",
        # these tests check the topic semantics with hand-made states far from any motion the
        # five-bar's limits allow (e.g. -20 rad/s against 15); the limits have tests of their own
        "-p",
        "enforce_limits:=false",
        *params,
    ]
    return subprocess.Popen(args, env=dict(ros_env, ROS_DOMAIN_ID=str(domain)), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, start_new_session=True)


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


def nonzero(efforts: list) -> list:
    return [e for e in efforts if any(e[1])]


@pytest.mark.timeout(150)
def test_driver_with_wall_stamps_shuffled_names_missing_joint_gains_and_sigint(
        ros_env: dict, domain: int, tmp_path: Path) -> None:
    log = tmp_path / "controller.log"
    proc = start_controller(ros_env, domain, log, "-p", "type:=pd")
    driver = Driver(domain)
    try:
        law = ControlLaw.from_spec(spec())
        q, qd = np.array([Q["joint1"], Q["joint2"]]), np.array([QD["joint1"], QD["joint2"]])
        expected = tuple(law.torque(q, qd, *map(np.array, REF)).tolist())
        # a driver's order (not the URDF's) with an extra joint; references in yet another order
        names = ["joint2", "gripper", "joint1"]
        driver.state = lambda: joint_state(driver, names, Q, QD)
        driver.reference = lambda: reference_message(["joint2", "joint1"])
        driver.spin(60, until=lambda: len(driver.efforts) > 200)
        assert proc.poll() is None, log.read_text()
        assert len(driver.efforts) > 200, log.read_text()
        last = driver.efforts[-100:]
        assert all(e[2] == 0 for e in last)  # no step index in real time
        for _, data, _ in last:
            np.testing.assert_allclose(data, expected, rtol=0, atol=1e-9)

        # joint1 missing: no torque from such a state; one zero command once the last good
        # state is stale (400 periods); an error diagnostic naming the joint
        count = len(driver.efforts)
        driver.state = lambda: joint_state(driver, ["joint2", "gripper"], Q, QD)
        driver.spin(1.5)
        after = [e[1] for e in driver.efforts[count:]]
        while after and np.allclose(after[0], expected, rtol=0, atol=1e-9):
            after.pop(0)  # computed from complete states before the incomplete ones came
        assert after == [(0.0, 0.0)], after[:5]
        assert any(level == 2 and "'joint1' missing" in text for level, text in driver.diagnostics), (
            driver.diagnostics, log.read_text())
        # a NaN velocity: the same
        driver.state = lambda: joint_state(driver, names, Q, dict(QD, joint2=float("nan")))
        driver.spin(0.5)
        assert any(level == 2 and "velocity of joint 'joint2' is not finite" in text
                   for level, text in driver.diagnostics)
        assert proc.poll() is None, log.read_text()
        # a complete state again: control resumes
        count = len(driver.efforts)
        driver.state = lambda: joint_state(driver, names, Q, QD)
        driver.spin(30, until=lambda: len(driver.efforts) > count + 100)
        np.testing.assert_allclose(driver.efforts[-1][1], expected, rtol=0, atol=1e-9)
        # the inputs' status is OK again (a loaded machine may warn of late ticks meanwhile: another status)
        assert driver.latest_level.get("controller: inputs") == 0, (driver.latest_level, driver.diagnostics[-5:])

        # an unstable gain through the parameter service: refused with the lowest stable rate
        unstable = dataclasses.replace(spec(), gains=Gains.from_mapping(
            {**spec().gains.as_dict(), "kd": [3000.0, 3000.0]}, 2, "pd"))
        with pytest.raises(UnstableRateError):
            check_rate(unstable, unstable.reference())
        ok, reason = driver.set_parameter("kd", [3000.0, 3000.0])
        assert not ok and "lowest stable rate" in reason, reason
        # a stable change is applied (post-set): the torque follows the new gains
        kp = [2.0 * k for k in spec().gains["kp"]]
        ok, reason = driver.set_parameter("kp", kp)
        assert ok, reason
        new_law = ControlLaw.from_spec(dataclasses.replace(spec(), gains=Gains.from_mapping(
            {**spec().gains.as_dict(), "kp": kp}, 2, "pd")))
        new_expected = tuple(new_law.torque(q, qd, *map(np.array, REF)).tolist())
        count = len(driver.efforts)
        driver.spin(30, until=lambda: len(driver.efforts) > count + 100)
        np.testing.assert_allclose(driver.efforts[-1][1], new_expected, rtol=0, atol=1e-9)
        assert not np.allclose(new_expected, expected)

        # SIGINT: the last command on the wire is zero
        os.kill(proc.pid, signal.SIGINT)
        driver.spin(20, until=lambda: proc.poll() is not None)
        driver.spin(0.5)
        assert proc.wait(timeout=20) == 0, log.read_text()
        assert driver.efforts[-1][1] == (0.0, 0.0), driver.efforts[-3:]
        assert "zero effort published" in log.read_text()
    finally:
        driver.close()
        stop(proc)


def _segments_of(points: list[tuple[list[float], float]], start_q: np.ndarray) -> list:
    """Linear segments ``(p0, p1, duration)`` from the state at receipt through the points."""
    segments, p, t = [], start_q, 0.0
    for positions, at in points:
        segments.append((np.asarray(p, dtype=float), np.asarray(positions, dtype=float), at - t))
        p, t = positions, at
    return segments


def _on_a_segment(law: ControlLaw, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, segments: list) -> int | None:
    """Index of the segment whose linear reference gives ``tau`` at some instant, or None.

    PD is affine in the reference, so along a linear segment the torque is
    affine in the fraction s: s is solved from joint 1 and joint 2 must agree.
    """
    zero = np.zeros(2)
    for index, (p0, p1, duration) in enumerate(segments):
        velocity = (p1 - p0) / duration
        a = law.torque(q, qd, p0, velocity, zero)
        b = law.torque(q, qd, p1, velocity, zero)
        if abs(b[0] - a[0]) < 1e-12:
            continue
        s = (tau[0] - a[0]) / (b[0] - a[0])
        if -1e-9 <= s <= 1 + 1e-9 and abs(a[1] + s * (b[1] - a[1]) - tau[1]) < 1e-9:
            return index
    return None


@pytest.mark.timeout(150)
def test_standard_trajectory_lifecycle_and_deactivate(ros_env: dict, domain: int, tmp_path: Path) -> None:
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    log = tmp_path / "controller.log"
    proc = start_controller(ros_env, domain, log, "-p", "type:=pd", "-p", "autostart:=false")
    driver = Driver(domain)
    try:
        law = ControlLaw.from_spec(spec())
        q, qd = np.array([Q["joint1"], Q["joint2"]]), np.array([QD["joint1"], QD["joint2"]])
        names = ["joint2", "gripper", "joint1"]
        driver.state = lambda: joint_state(driver, names, Q, QD)
        driver.reference = lambda: reference_message(["joint1", "joint2"])
        driver.spin(3)
        assert driver.efforts == [] and proc.poll() is None, log.read_text()  # unconfigured: silent
        for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
            result = driver.call(ChangeState, "/controller/change_state",
                                 ChangeState.Request(transition=Transition(id=transition)))
            assert result.success, log.read_text()
        driver.spin(30, until=lambda: len(driver.efforts) > 50)
        assert nonzero(driver.efforts), log.read_text()

        # a three-point trajectory (positions only: linear), names shuffled (a joint the controller
        # lacks would be refused, as joint_trajectory_controller refuses it)
        driver.reference = None
        points = [([0.4, 1.0], 0.8), ([0.5, 1.3], 1.6), ([0.2, 1.1], 2.4)]  # joint1, joint2; s from receipt
        msg = JointTrajectory()
        msg.joint_names = ["joint2", "joint1"]
        msg.points = [JointTrajectoryPoint(positions=[p[1], p[0]], time_from_start=rclpy.duration.Duration(
            seconds=at).to_msg()) for p, at in points]
        count = len(driver.efforts)
        driver.pub_traj.publish(msg)
        driver.spin(4.0)
        during = driver.efforts[count:]
        from_reference = law.torque(q, qd, *map(np.array, REF))
        while during and np.allclose(during[0][1], from_reference, rtol=0, atol=1e-9):
            during.pop(0)  # the /reference source until the trajectory came
        segments = _segments_of(points, q)
        hold = law.torque(q, qd, np.array(points[-1][0]), np.zeros(2), np.zeros(2))
        seen = set()
        for _, data, _ in during:
            tau = np.array(data)
            if np.allclose(tau, hold, rtol=0, atol=1e-9):
                seen.add("hold")
                continue
            index = _on_a_segment(law, q, qd, tau, segments)
            seen.add(index)
            assert index is not None, f"torque {data} lies on no segment of the trajectory"
        # every segment was driven, then the last point held at zero velocity
        assert seen >= {1, 2, "hold"}, seen
        np.testing.assert_allclose(during[-1][1], hold, rtol=0, atol=1e-9)

        # deactivate: one zero command, then silence
        count = len(driver.efforts)
        result = driver.call(ChangeState, "/controller/change_state",
                             ChangeState.Request(transition=Transition(id=Transition.TRANSITION_DEACTIVATE)))
        assert result.success
        driver.spin(1.0)
        after = [e[1] for e in driver.efforts[count:]]
        # (waiting for the service, this node's timer publishes no state: the controller may
        # have stopped on stale inputs and resumed meanwhile, one zero command more)
        last_torque = max(i for i, data in enumerate(after) if any(data))
        assert after[last_torque + 1:] == [(0.0, 0.0)], after[-5:]
        assert proc.poll() is None, log.read_text()
    finally:
        driver.close()
        stop_process(proc)


@pytest.mark.timeout(90)
def test_lockstep_controller_survives_a_wall_stamped_state(ros_env: dict, domain: int, tmp_path: Path) -> None:
    """Before: ``struct.error`` in encode_float64_multi_array and the node was gone."""
    log = tmp_path / "controller.log"
    args = ["ros2", "run", "pdsmc_ros", "controller", "--ros-args", "-p", "robot:=parallel_5r", "-p", "type:=pd"]
    proc = subprocess.Popen(args, env=dict(ros_env, ROS_DOMAIN_ID=str(domain)), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, start_new_session=True)
    driver = Driver(domain)
    try:
        driver.state = lambda: joint_state(driver, ["joint1", "joint2"], Q, QD)
        driver.reference = lambda: reference_message(["joint1", "joint2"])
        driver.spin(30, until=lambda: any(level == 2 for level, _ in driver.diagnostics))
        driver.spin(1.0)
        assert proc.poll() is None, log.read_text()
        assert any("is not a lockstep step" in text for _, text in driver.diagnostics), driver.diagnostics
        assert driver.efforts == []
    finally:
        driver.close()
        stop_process(proc)


@pytest.mark.timeout(90)
def test_trajectory_node_keeps_its_own_clock_next_to_a_wall_stamped_plant(
        ros_env: dict, domain: int, tmp_path: Path) -> None:
    """Before: it read the wall-clock stamp as a step and jumped to the contour's last reference."""
    from trajectory_msgs.msg import JointTrajectory

    log = tmp_path / "trajectory.log"
    args = ["ros2", "run", "pdsmc_ros", "trajectory", "--ros-args", "-p", "robot:=parallel_5r",
            "-p", "mode:=realtime", "-p", f"rate:={RATE}", "-p", f"sample_rate:={RATE}"]
    proc = subprocess.Popen(args, env=dict(ros_env, ROS_DOMAIN_ID=str(domain)), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, start_new_session=True)
    driver = Driver(domain)
    steps: list[tuple[float, int]] = []
    driver.node.create_subscription(
        JointTrajectory, "/reference",
        lambda m: steps.append((time.monotonic(), round((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9) * RATE))),
        100)
    try:
        driver.spin(30, until=lambda: len(steps) > 20)
        assert steps and all(k == 0 for _, k in steps), log.read_text()  # no state yet: the start
        driver.state = lambda: joint_state(driver, ["joint1", "joint2", "joint3", "joint4"], Q, QD)
        started = time.monotonic()
        driver.spin(1.0)
        assert proc.poll() is None, log.read_text()
        last_step = round(spec("pd").reference().duration * RATE)
        elapsed = time.monotonic() - started
        newest = steps[-1][1]
        assert 0 < newest < last_step
        # one step ahead of a clock started with the driver's second state (5 ms apart)
        assert abs(newest / RATE - elapsed) < 0.25, (newest, elapsed)
    finally:
        driver.close()
        stop_process(proc)


@pytest.mark.timeout(90)
def test_lockstep_controller_follows_a_standard_trajectory_in_sim_time(
        ros_env: dict, domain: int, tmp_path: Path) -> None:
    """Lockstep: states stamped with sim time k / rate; the trajectory sampled at the state's time."""
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    log = tmp_path / "controller.log"
    args = ["ros2", "run", "pdsmc_ros", "controller", "--ros-args", "-p", "robot:=parallel_5r", "-p", "type:=pd", "-p",
            "enforce_limits:=false"]
    proc = subprocess.Popen(args, env=dict(ros_env, ROS_DOMAIN_ID=str(domain)), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, start_new_session=True)
    driver = Driver(domain)
    step = [0]

    def sim_state() -> JointState:
        msg = JointState(name=["joint2", "joint1"], position=[Q["joint2"], Q["joint1"]],
                         velocity=[QD["joint2"], QD["joint1"]])
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(step[0] * 200_000, 1_000_000_000)  # k / 5 kHz
        step[0] += 1
        return msg

    try:
        driver.state = sim_state
        # the goal needs a state the controller has received (the motion starts from it): wait for
        # both of its subscriptions (companion nodes, discovered one by one), then for states sent since
        driver.spin(30, until=lambda: driver.pub_traj.get_subscription_count() > 0
                    and driver.pub_state.get_subscription_count() > 0)
        matched = step[0]
        driver.spin(30, until=lambda: step[0] > matched + 50)
        assert driver.efforts == [], log.read_text()  # no reference source yet
        msg = JointTrajectory(joint_names=["joint1", "joint2"], points=[JointTrajectoryPoint(
            positions=[0.4, 1.0], time_from_start=rclpy.duration.Duration(seconds=0.01).to_msg())])
        driver.pub_traj.publish(msg)
        driver.spin(30, until=lambda: len(driver.efforts) > 200)  # 10 ms of sim time is 50 states
        assert len(driver.efforts) > 200, log.read_text()
        # offsets are the states' steps: consecutive, in order
        offsets = [e[2] for e in driver.efforts]
        assert offsets == list(range(offsets[0], offsets[0] + len(offsets)))
        law = ControlLaw.from_spec(make_run("parallel_5r", "circle", "pd"))
        q, qd = np.array([Q["joint1"], Q["joint2"]]), np.array([QD["joint1"], QD["joint2"]])
        hold = law.torque(q, qd, np.array([0.4, 1.0]), np.zeros(2), np.zeros(2))
        np.testing.assert_allclose(driver.efforts[-1][1], hold, rtol=0, atol=1e-9)
        assert not np.allclose(driver.efforts[0][1], hold)  # the ramp from the state at receipt
        assert "points until t" in log.read_text() and proc.poll() is None
    finally:
        driver.close()
        stop_process(proc)
