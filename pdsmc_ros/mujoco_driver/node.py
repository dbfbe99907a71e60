"""MuJoCo stand-in for a robot: a ros2_control-style driver with an effort controller.

``ros2 run pdsmc_ros mujoco_driver --ros-args -p robot:=ur5`` (or ``serial_3r``, a ``.urdf``
path). Publishes ``/joint_states`` (``sensor_msgs/JointState``: position, velocity, effort =
the motors' torque; stamped with the wall clock, ``frame_id`` empty) at ``rate`` in its own
``joint_state_order`` -- what the drive reads, with the stand-in's nuisances (``realism:=bench``,
:mod:`pdsmc_ros.sim.realism`) --, the exact state beside it on ``~/true_joint_states`` (same
stamp and order), and ``/robot_description`` (transient local, as robot_state_publisher); takes
``/effort_controller/commands`` (``std_msgs/Float64MultiArray``, ``data[i]`` -> ``joints[i]``; a
wrong length or a non-finite value is dropped with a throttled warning, as
forward_command_controller does). The arm is braked (MuJoCo does not step) until the first
command, then the latest command is applied every step (:mod:`pdsmc_ros.mujoco_driver.driver`; the
model: :mod:`pdsmc_ros.sim.mujoco_model`).
"""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Sequence
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from ..bag.cdr import decode_float64_multi_array, encode_joint_state
from ..checks import are_real
from ..errors import CdrError, ConfigError, InvalidInputError
from ..loop.inputs import Inputs
from ..loop.lifecycle import EXIT_OK
from ..loop.process import run_node
from ..parameters import mujoco_driver_parameters
from ..parameters.joint_map import check_joint_names
from ..parameters.ros import declare, guard
from ..parameters.tables import PLANT_PRIORITY
from ..robots.catalog import resolve_robot
from ..robots.registry import make_robot
from ..ros.publishers import GuardedPublisher
from ..ros.topics import LATCHED_QOS, STREAM_QOS, TOPIC_EFFORT, TOPIC_JOINT_STATES, TOPIC_ROBOT_DESCRIPTION
from ..sim.mujoco_model import build_stand_in
from ..sim.realism import BY_NAME, SETTINGS, RealismError, resolve_realism
from .driver import MujocoDriver, default_positions, initial_passive, joint_state_order

TOPIC_TRUE_JOINT_STATES = "~/true_joint_states"
"""MuJoCo's exact state, beside what the drive publishes on ``/joint_states`` (the truth a run's
analysis can use: ``pdsmc analyze``)."""
WARN_EVERY_S = 1.0  # dropped commands: one warning a second at most
PERIODS_KEPT = 100_000  # achieved periods summarised at the end (the last 100 s at 1 kHz)


class MujocoDriverNode:
    """Thin wrapper: parameters, topics and the wall-clock tick around :class:`MujocoDriver`."""

    realtime_priority = PLANT_PRIORITY  # thread_priority's default: the arm's stand-in, below the controller

    def __init__(self) -> None:
        self.node = node = Node("mujoco_driver")
        values = declare(node, mujoco_driver_parameters())  # read-only; each of its type and in its bounds
        robot, rate, substeps, order = values["robot"], values["rate"], values["substeps"], values["joint_state_order"]
        joints, initial, timeout = values["joints"], values["initial_positions"], values["command_timeout"]
        self.busy_wait = values["busy_wait"]
        self.pending = None  # nuisances set while running, taken at the next tick
        try:
            robot = resolve_robot(robot)
        except ConfigError as exc:
            raise ConfigError(f"parameter robot: {exc}") from None
        model = make_robot(robot)
        command_joints = check_joint_names(list(model.joint_names) if joints is None else joints, model.n)
        self.command_joints = command_joints
        self.robot_joints = list(model.joint_names)
        self.values = {name: values[name] for name in BY_NAME}
        try:
            arm, realism, self.facts = build_stand_in(
                robot, rate=rate, substeps=substeps, preset=values["realism"], seed=values["seed"],
                given=self._nuisances(self.values))
        except RealismError as exc:
            raise ConfigError(str(exc)) from None
        guard(node, mujoco_driver_parameters(), check=self.check_set, joints=arm.n)
        q0 = default_positions(robot) if initial is None else self._positions(initial, arm.n)
        try:
            self.driver = MujocoDriver(arm, q0, passive0=initial_passive(robot, q0), command_joints=command_joints,
                                       command_timeout=timeout, realism=realism, effort_limits=model.effort_limits,
                                       substeps=substeps)
        except InvalidInputError as exc:
            raise ConfigError(f"parameter {exc}") from None
        names = list(arm.joint_names + arm.passive_joint_names)
        self.order = joint_state_order(names, str(order))
        self.names = [names[i] for i in self.order]
        self.period = 1.0 / rate  # run_node paces tick() at this period
        self.mode = "realtime"  # a loop node: real-time settings and loop statistics (realtime_params)
        self.done = False
        self.exit_code = EXIT_OK

        self.pub_state = GuardedPublisher(node.create_publisher(JointState, TOPIC_JOINT_STATES, STREAM_QOS), node)
        self.pub_true = GuardedPublisher(node.create_publisher(JointState, TOPIC_TRUE_JOINT_STATES, STREAM_QOS), node)
        self.pub_urdf = node.create_publisher(String, TOPIC_ROBOT_DESCRIPTION, LATCHED_QOS)
        self.pub_urdf.publish(String(data=make_robot(robot).description()))
        self.inputs = Inputs(node, "realtime")
        self.inputs.subscribe(Float64MultiArray, TOPIC_EFFORT, self.on_command)
        self.ticks = 0
        self.periods: deque[float] = deque(maxlen=PERIODS_KEPT)  # achieved periods (s), for the closing line
        self.last_tick = 0.0
        self.longest = (0.0, 0.0)  # the longest achieved period (s) and the wall time it ended, for the closing line
        self.publish_state()
        node.get_logger().info(
            f"MuJoCo {robot} ({arm.n} joints), {rate:g} Hz x {substeps} RK4 steps, /joint_states in "
            f"{order} order, braked until the first command on /{TOPIC_EFFORT}"
            + (f", brakes again after {timeout:g} s without one" if timeout else "")
            + f"; realism {realism.summary()}")

    @staticmethod
    def _positions(value: Any, n: int) -> np.ndarray:
        if not are_real(value):
            raise ConfigError(f"parameter initial_positions must be {n} numbers (rad), got {value!r}")
        q = np.asarray(list(value), dtype=float)
        if q.shape != (n,) or not np.all(np.isfinite(q)):
            raise ConfigError(f"parameter initial_positions needs {n} finite angles (rad), got {list(value)}")
        return q

    def _nuisances(self, values: dict[str, Any]) -> dict[str, Any]:
        """The nuisances given (not the preset or the seed), per-joint ones from ``joints`` order to the
        robot's (an empty list: not given)."""
        out: dict[str, Any] = {}
        for name, value in values.items():
            if name in SETTINGS or value is None:
                continue
            if not isinstance(value, str | bool | int | float) and len(value) == 0:
                continue
            if BY_NAME[name].per_joint and not isinstance(value, str | bool | int | float) \
                    and len(value) == len(self.command_joints):
                by_name = dict(zip(self.command_joints, value, strict=True))
                value = [by_name[j] for j in self.robot_joints]
            out[name] = value
        return out

    def check_set(self, params: Sequence[Any]) -> str | None:
        """The on-set check of the nuisances a running driver applies: resolved against the arm (the
        new values with the others in force); accepted ones are taken at the next tick."""
        changed = {p.name: p.value for p in params if p.name in BY_NAME}
        if not changed or not hasattr(self, "driver"):
            return None
        values = {**self.values, **changed}
        try:
            realism = resolve_realism(self.facts, values["realism"], self._nuisances(values), seed=values["seed"])
            if realism.payload_mass != self.driver.realism.payload_mass \
                    or not np.array_equal(realism.payload_com, self.driver.realism.payload_com):
                return "payload_mass and payload_com are read at start-up (the model MuJoCo compiled)"
        except RealismError as exc:
            return str(exc)
        self.values = values
        self.pending = realism
        return None

    def on_command(self, data: bytes) -> None:
        try:
            _, values = decode_float64_multi_array(data)
        except CdrError:
            try:  # a layout with dimensions: ros2_control ignores the layout, so do we
                values = tuple(deserialize_message(data, Float64MultiArray).data)
            except Exception as exc:  # noqa: BLE001 - rclpy raises several kinds; a node never dies on a message
                self.warn(f"command dropped: not a Float64MultiArray ({exc})")
                return
        was_braked = self.driver.braked
        dropped = self.driver.command(values, time.monotonic())
        if dropped:
            self.warn(dropped)
        elif was_braked:
            self.node.get_logger().info("first command: brakes released")

    def warn(self, text: str) -> None:
        self.node.get_logger().warn(f"{text} ({self.driver.dropped} dropped so far)",
                                    throttle_duration_sec=WARN_EVERY_S)

    def tick(self, lateness: float) -> None:  # noqa: ARG002 - the driver integrates to the wall clock
        pending, self.pending = self.pending, None
        if pending is not None:
            self.driver.set_realism(pending)
            self.node.get_logger().info(f"realism now {pending.summary()}")
        now = time.monotonic()
        if self.driver.advance(now):
            self.node.get_logger().warn(
                f"no command for {self.driver.command_timeout:g} s: brakes closed until the next one")
        if self.last_tick:
            period = now - self.last_tick
            self.periods.append(period)
            if period > self.longest[0]:
                self.longest = (period, time.time())
        self.last_tick = now
        self.publish_state()

    def publish_state(self) -> None:
        q, qd, effort = self.driver.state()
        sec, nanosec = divmod(time.time_ns(), 1_000_000_000)  # the wall clock, as a real driver stamps
        order = self.order
        self.pub_state.publish(encode_joint_state(
            sec, nanosec, self.names, q[order].tolist(), qd[order].tolist(), effort[order].tolist()))
        q, qd, effort = self.driver.true_state()
        self.pub_true.publish(encode_joint_state(
            sec, nanosec, self.names, q[order].tolist(), qd[order].tolist(), effort[order].tolist()))
        self.ticks += 1

    def close(self) -> None:
        if self.periods:
            p = np.asarray(self.periods)
            jitter = np.abs(p - self.period)
            self.node.get_logger().info(
                f"{self.ticks} states, mean rate {1.0 / p.mean():.1f} Hz, period jitter p50 "
                f"{np.percentile(jitter, 50) * 1e6:.0f} us, p99 {np.percentile(jitter, 99) * 1e6:.0f} us, "
                f"max {jitter.max() * 1e6:.0f} us; {self.driver.commands} commands, {self.driver.dropped} dropped; "
                f"longest period {self.longest[0] * 1e6:.0f} us, ended at {self.longest[1]:.3f} (wall clock)")


def main(args: Sequence[str] | None = None) -> int:
    return run_node("mujoco_driver", MujocoDriverNode, args)


if __name__ == "__main__":
    sys.exit(main())
