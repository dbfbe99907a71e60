"""The mujoco_driver node seen from a plain rclpy node: states at the rate, wall-clock stamps, its
own joint order, brakes until the first command, bad commands dropped, the node lives on.

The driver runs as `ros2 run pdsmc_ros mujoco_driver` in its own ROS domain, is stopped by
its PID and given a timeout.
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator

import numpy as np
import pytest
from conftest import next_domain, stop_process

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("mujoco")

from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray, String  # noqa: E402

RATE = 1000.0


class LazyState:
    """A received /joint_states message, deserialized on first use: the client takes 1 kHz of raw
    messages without falling behind (building each JointState in its callback held a full test
    run's Python process to under 300 a second, below the driver's rate it is meant to count)."""

    __slots__ = ("data", "message")

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.message: JointState | None = None

    def __getattr__(self, name: str) -> object:
        if self.message is None:
            self.message = deserialize_message(self.data, JointState)
        return getattr(self.message, name)


class Client:
    """A plain rclpy node: records /joint_states and /robot_description, publishes commands."""

    def __init__(self, domain: int) -> None:
        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = Node("driver_client", context=self.ctx)
        self.states: list[tuple[float, LazyState]] = []
        self.description: list[str] = []
        self.node.create_subscription(JointState, "/joint_states", self.on_state, 10_000, raw=True)
        self.node.create_subscription(String, "/robot_description", lambda m: self.description.append(m.data),
                                      QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                                 durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.commands = self.node.create_publisher(Float64MultiArray, "/effort_controller/commands", 10)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)

    def on_state(self, data: bytes) -> None:
        self.states.append((time.time(), LazyState(data)))

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def wait_states(self, count: int, timeout: float) -> None:
        end = time.monotonic() + timeout
        while len(self.states) < count and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)

    def command(self, values: list[float]) -> None:
        # a message published before the driver's subscription is matched is lost (seen on a
        # loaded machine: the first bad command never reached the driver)
        end = time.monotonic() + 10.0
        while self.commands.get_subscription_count() < 1 and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)
        self.commands.publish(Float64MultiArray(data=values))

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


@pytest.fixture
def domain_env(ros_env: dict[str, str]) -> tuple[int, dict[str, str]]:
    domain = next_domain()
    return domain, dict(ros_env, ROS_DOMAIN_ID=str(domain))


@pytest.fixture
def client(domain_env: tuple[int, dict[str, str]]) -> Iterator[Client]:
    made = Client(domain_env[0])
    try:
        yield made
    finally:
        made.close()


def start(env: dict[str, str], *params: str) -> subprocess.Popen:
    args = ["ros2", "run", "pdsmc_ros", "mujoco_driver", "--ros-args", "-p", f"rate:={RATE}"]
    for p in params:
        args += ["-p", p]
    return subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def stop(proc: subprocess.Popen) -> tuple[int, str]:
    return stop_process(proc)


def positions(msg: LazyState) -> np.ndarray:
    return np.asarray(msg.position)


@pytest.mark.timeout(120)
def test_states_brakes_commands_and_bad_commands(domain_env: tuple[int, dict[str, str]], client: Client) -> None:
    proc = start(domain_env[1], "robot:=serial_3r", "joint_state_order:=reversed")
    try:
        client.wait_states(1, timeout=60.0)
        assert client.states, "no /joint_states from the driver"
        client.spin_for(0.2)  # past discovery
        client.states.clear()
        client.spin_for(1.0)  # braked: a second of states
        braked = list(client.states)
        assert 0.3 * RATE <= len(braked) <= 1.5 * RATE  # about the rate, not 100 Hz nor one per spin
        first = braked[0][1]
        assert list(first.name) == ["joint3", "joint2", "joint1"]  # the declared order
        assert first.header.frame_id == ""
        stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, m in braked])
        received = np.array([t for t, _ in braked])
        assert np.all(np.diff(stamps) > 0.0)
        assert np.all(np.abs(received - stamps) < 1.0)  # wall-clock stamps, not sim time from 0
        for _, msg in braked:  # the brakes hold the arm where it started (gravity pulls on it)
            np.testing.assert_array_equal(positions(msg), positions(first))
            np.testing.assert_array_equal(msg.velocity, [0.0, 0.0, 0.0])

        client.command([1.0, 2.0])  # wrong length
        # the driver reads the newest command (keep-last 1, as ros2_control's real-time buffer):
        # one sent within the same tick would replace this one unread (seen once on CI)
        client.spin_for(0.2)
        client.command([0.0, float("nan"), 0.0])  # non-finite
        client.states.clear()
        client.spin_for(0.5)
        assert len(client.states) > 0.3 * RATE * 0.5, "the driver stopped publishing after bad commands"
        np.testing.assert_array_equal(positions(client.states[-1][1]), positions(first))

        client.command([0.0, 0.0, 0.0])  # a zero torque releases the brakes: the arm falls
        client.states.clear()
        client.spin_for(0.5)
        moved = [msg for _, msg in client.states if np.any(positions(msg) != positions(first))]
        assert moved, "a command did not release the brakes"
        assert np.abs(positions(moved[-1])[1] - positions(first)[1]) > 0.01  # joint2 sags
        assert proc.poll() is None
        assert client.description and '<robot name="serial_3r">' in client.description[0]
    finally:
        code, out = stop(proc)
    assert code == 0, out[-3000:]
    assert "command dropped: 2 values for 3 joints" in out, out[-3000:]
    assert "first command: brakes released" in out, out[-3000:]
    assert "2 dropped" in out, out[-3000:]


@pytest.mark.timeout(60)
def test_a_bad_parameter_is_one_line_and_exit_2(domain_env: tuple[int, dict[str, str]]) -> None:
    proc = start(domain_env[1], "robot:=serial_3r", "joints:=[joint1, joint2, elbow]")
    code, out = stop_after_exit(proc)
    assert code == 2, out
    lines = [line for line in out.splitlines() if line.strip()]
    assert lines[-1] == ("mujoco_driver: error: parameter joints must name each of the arm's 3 actuated joints "
                         "once (joint1, joint2, joint3), got ['joint1', 'joint2', 'elbow']"), out
    assert "Traceback" not in out, out


def stop_after_exit(proc: subprocess.Popen) -> tuple[int, str]:
    try:
        out, _ = proc.communicate(timeout=50)
    except subprocess.TimeoutExpired:
        return stop(proc)
    return proc.returncode, out


class TruthClient(Client):
    """:class:`Client` that also records ``~/true_joint_states`` and sets the driver's parameters."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain)
        from rcl_interfaces.srv import SetParameters

        self.truth: list[LazyState] = []
        self.node.create_subscription(JointState, "/mujoco_driver/true_joint_states",
                                      lambda data: self.truth.append(LazyState(data)), 10_000, raw=True)
        self.setter = self.node.create_client(SetParameters, "/mujoco_driver/set_parameters")

    def set(self, name: str, value: object) -> tuple[bool, str]:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        assert self.setter.wait_for_service(timeout_sec=30.0)
        future = self.setter.call_async(SetParameters.Request(parameters=[Parameter(name, value=value)
                                                                          .to_parameter_msg()]))
        end = time.monotonic() + 30.0
        while not future.done() and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)
        result = future.result().results[0]
        return result.successful, result.reason


@pytest.fixture
def truth_client(domain_env: tuple[int, dict[str, str]]) -> Iterator[TruthClient]:
    made = TruthClient(domain_env[0])
    try:
        yield made
    finally:
        made.close()


@pytest.mark.timeout(150)
def test_bench_publishes_the_encoders_reading_beside_the_truth_and_takes_nuisances_while_running(
        domain_env: tuple[int, dict[str, str]], truth_client: TruthClient) -> None:
    client = truth_client
    proc = start(domain_env[1], "robot:=serial_3r", "realism:=bench", "joint_state_order:=urdf", "seed:=3",
                 "command_timeout:=0.0")  # the one command held: the arm falls throughout
    try:
        client.wait_states(1, timeout=60.0)
        assert client.states, "no /joint_states from the driver"
        client.spin_for(0.3)
        client.command([0.0, 0.0, 0.0])  # the brakes open: the arm falls
        client.states.clear()
        client.truth.clear()
        client.spin_for(0.5)
        grid = 2 * np.pi / 2**18
        published = {(m.header.stamp.sec, m.header.stamp.nanosec): positions(m) for _, m in client.states}
        true = {(m.header.stamp.sec, m.header.stamp.nanosec): np.asarray(m.position) for m in client.truth}
        common = sorted(set(published) & set(true))
        assert len(common) > 100, "the truth is not published beside /joint_states, with the same stamps"
        p = np.array([published[k] for k in common])
        q = np.array([true[k] for k in common])
        np.testing.assert_allclose(p / grid, np.round(p / grid), atol=1e-6)  # the encoder's counts
        assert np.any(np.abs(q / grid - np.round(q / grid)) > 0.01)  # the truth is MuJoCo's exact state
        assert np.max(np.abs(p - q)) < 5 * grid  # the nearest count of the noisy reading
        assert np.ptp(q[:, 1]) > 0.01  # it moved

        ok, reason = client.set("friction_coulomb", [-1.0])
        assert not ok and reason.startswith("parameter friction_coulomb must be"), reason
        ok, reason = client.set("friction_viscous", [1.0, 2.0])
        assert not ok and reason == ("parameter friction_viscous needs 3 values, one per joint (or one for every "
                                     "joint), got 2"), reason
        ok, reason = client.set("payload_mass", 2.0)
        assert not ok and "read-only" in reason, reason  # rclpy refuses it (the model MuJoCo compiled)
        ok, reason = client.set("command_delay", 5)
        assert ok, reason
        client.states.clear()
        client.spin_for(0.3)
        assert len(client.states) > 0.3 * RATE * 0.3, "the driver stopped publishing after a parameter set"
        assert proc.poll() is None
    finally:
        code, out = stop(proc)
    assert code == 0, out[-3000:]
    assert "realism bench" in out and "realism now bench" in out and "command_delay 5" in out, out[-3000:]


@pytest.mark.timeout(90)
@pytest.mark.parametrize(("param", "name"), [
    ("friction_coulomb:=[-1.0]", "friction_coulomb"),
    ("encoder_counts:=[0]", "encoder_counts"),
    ("command_delay:=101", "command_delay"),
    ("position_noise:=[.nan]", "position_noise"),
    ("friction_viscous:=[1.0, 2.0]", "friction_viscous"),
    ("realism:=lab", "realism"),
])
def test_a_bad_nuisance_is_one_line_naming_it_and_exit_2(domain_env: tuple[int, dict[str, str]], param: str,
                                                          name: str) -> None:
    proc = start(domain_env[1], "robot:=serial_3r", param)
    code, out = stop_after_exit(proc)
    assert code == 2, out
    lines = [line for line in out.splitlines() if line.strip()]
    assert lines[-1].startswith(f"mujoco_driver: error: parameter {name} "), out
    assert "Traceback" not in out, out
