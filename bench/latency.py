"""Controller latency in real time at 1 kHz (issue 25 item 2): prints the figures.

A plain rclpy driver in this process publishes ``/joint_states`` at 1 kHz with
wall stamps for the serial 3R (a fixed position; joint3's velocity carries the
state's sequence number k as ``k * 1e-6`` rad/s) and receives the controller's
``/effort_controller/commands``. The controller (``ros2 run pdsmc_ros controller``,
``type:=pd``, gains stable at 1 kHz) runs as its own process in a domain of its own.
With PD (Eq. 3.4) the command decodes exactly:

- joint3 is held at its position with zero reference velocity, so
  ``tau3 = -kd3 * qd3`` names the state a command was computed from: the
  latency from that state's publication to the command's arrival here;
- joint1 follows a linear trajectory ``q1 + v s`` (published with a header
  stamp on the wall clock), so ``tau1 = kp1 v s + kd1 v`` gives the trajectory
  time ``s`` the controller sampled; against the wall time the command arrived,
  the trajectory's time shift (its sampling time lags the clock by that much).

Printed: the time from the first state to the first command (hold on
activation), the first-command latency after a JointTrajectory is published, the
trajectory's time shift, and the state-to-command latency p50/p99 (ms).

Usage: ``.venv/bin/python bench/latency.py [--seconds 10] [--domain 57]``
(AMENT_PREFIX_PATH and NUMBA_CACHE_DIR as for the nodes).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

RATE = 1000.0
KP = [1000.0, 1000.0, 200.0]  # pass the real-time check at 1 kHz: margin x2.49 (pdsmc check-gains --mode realtime)
KD = [50.0, 50.0, 10.0]
Q0 = [0.3, 0.9, -0.4]
SEQ_SCALE = 1e-6  # rad/s of joint3's velocity per state
V1 = 0.05  # rad/s of joint1's linear trajectory


def controller_args(*extra: str) -> list[str]:
    return ["ros2", "run", "pdsmc_ros", "controller", "--ros-args",
            "-p", "robot:=serial_3r", "-p", "type:=pd", "-p", "mode:=realtime",
            "-p", f"rate:={RATE}", "-p", f"sample_rate:={RATE}",
            "-p", f"kp:={KP}", "-p", f"kd:={KD}", *extra]


class Driver:
    """States out at 1 kHz from a thread of their own, commands in."""

    def __init__(self, domain: int) -> None:
        import rclpy
        import rclpy.executors
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        from trajectory_msgs.msg import JointTrajectory

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("latency_driver", context=self.context)
        self.pub_state = self.node.create_publisher(JointState, "/joint_states", 10)
        self.pub_traj = self.node.create_publisher(JointTrajectory, "/controller/joint_trajectory", 10)
        self.commands: list[tuple[float, float, tuple[float, ...]]] = []  # perf, wall, data
        self.node.create_subscription(Float64MultiArray, "/effort_controller/commands", self.on_command, 1000)
        self.published: dict[int, float] = {}  # state k -> perf_counter at publication
        self.first_state: float | None = None
        self.stop = threading.Event()
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self.spin, daemon=True)
        self.spinner.start()
        self.msg = JointState(name=["joint1", "joint2", "joint3"], position=list(Q0), velocity=[0.0, 0.0, 0.0])
        self.sender = threading.Thread(target=self.send, daemon=True)

    def on_command(self, msg: object, info: dict) -> None:
        # the middleware's reception time, not the time this process's executor got to the message:
        # on a loaded machine a Python executor falls behind 1,000 messages a second
        received = info["received_timestamp"] * 1e-9
        perf = time.perf_counter() - (time.time() - received)
        self.commands.append((perf, received, tuple(msg.data)))  # type: ignore[attr-defined]

    def spin(self) -> None:
        while not self.stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def send(self) -> None:
        from rclpy.clock import Clock

        clock, period, k = Clock(), 1.0 / RATE, 0
        next_time = time.perf_counter()
        while not self.stop.is_set():
            k += 1
            self.msg.velocity = [0.0, 0.0, k * SEQ_SCALE]
            self.msg.header.stamp = clock.now().to_msg()
            now = time.perf_counter()
            self.published[k] = now
            if self.first_state is None:
                self.first_state = now
            self.pub_state.publish(self.msg)
            next_time += period
            delay = next_time - time.perf_counter()
            if delay > 0:
                time.sleep(delay)

    def trajectory(self, duration: float, *, zero_stamp: bool, fresh: bool) -> tuple[float, float]:
        """Publish joint1's linear trajectory stamped now (wall) or with a zero stamp, from the
        long-matched publisher or from a new one (as a user's script does: create it, wait until
        it matches the controller, publish); ``(perf_counter at publication, wall time then)``."""
        from builtin_interfaces.msg import Duration, Time
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        publisher = self.pub_traj
        if fresh:
            publisher = self.node.create_publisher(JointTrajectory, "/controller/joint_trajectory", 10)
            wait(lambda: publisher.get_subscription_count() > 0, 120.0)
        stamp = time.time()
        msg = JointTrajectory(joint_names=["joint1", "joint2", "joint3"])
        if not zero_stamp:
            msg.header.stamp = Time(sec=int(stamp), nanosec=int((stamp % 1.0) * 1e9))
        end = [Q0[0] + V1 * duration, Q0[1], Q0[2]]
        msg.points = [JointTrajectoryPoint(positions=list(Q0), time_from_start=Duration()),
                      JointTrajectoryPoint(positions=end, time_from_start=Duration(
                          sec=int(duration), nanosec=int((duration % 1.0) * 1e9)))]
        now = time.perf_counter()
        publisher.publish(msg)
        return now, stamp

    def close(self) -> None:
        self.stop.set()
        if self.sender.ident is not None:
            self.sender.join(timeout=2)
        self.spinner.join(timeout=2)
        self.node.destroy_node()
        self.context.try_shutdown()


def wait(condition: object, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():  # type: ignore[operator]
            return True
        time.sleep(0.005)
    return False


def active(driver: Driver) -> bool:
    """Whether the controller's lifecycle state is active."""
    from lifecycle_msgs.srv import GetState

    client = driver.node.create_client(GetState, "/controller/get_state")
    try:
        if not client.wait_for_service(timeout_sec=1.0):
            return False
        future = client.call_async(GetState.Request())
        wait(future.done, 2.0)
        return future.done() and future.result().current_state.id == 3  # type: ignore[union-attr]
    finally:
        driver.node.destroy_client(client)


def measure(driver: Driver, published: float, stamp: float, before: int, seconds: float) -> None:
    """Print the first-command latency after the trajectory, the state-to-command latency and the
    trajectory's time shift over its commands."""
    moving = lambda: [c for c in driver.commands[before:] if abs(c[2][0]) > 1e-9]  # noqa: E731
    wait(moving, 30.0)
    first = moving()
    if first:
        print(f"  JointTrajectory published -> first command from it: {(first[0][0] - published) * 1e3:.2f} ms")
    time.sleep(seconds)
    rows = [c for c in driver.commands[before:] if abs(c[2][0]) > 1e-9]
    kd3, kp1, kd1 = KD[2], KP[0], KD[0]
    latencies, shifts = [], []
    for perf, wall, data in rows:
        k = int(round(-data[2] / (kd3 * SEQ_SCALE)))
        if k in driver.published:
            latencies.append(perf - driver.published[k])
        s = (data[0] - kd1 * V1) / (kp1 * V1)  # trajectory time the controller sampled
        shifts.append((wall - stamp) - s)  # >= the command's way back; a stall's shift on top
    lat, shift = np.array(latencies) * 1e3, np.array(shifts) * 1e3
    print(f"  commands during the trajectory: {len(rows)} ({len(rows) / seconds:.0f}/s)")
    if lat.size:
        print(f"  state published -> its command received: p50 {np.percentile(lat, 50):.3f} ms, "
              f"p99 {np.percentile(lat, 99):.3f} ms, max {lat.max():.3f} ms ({lat.size} commands)")
    if shift.size:
        print(f"  trajectory time shift (command's arrival - publication or stamp - sampled time): "
              f"median {np.median(shift):.3f} ms, p99 {np.percentile(shift, 99):.3f} ms")


def run(args: argparse.Namespace, env: dict[str, str], *, start_up: bool) -> int:
    """One controller process. ``start_up``: states flow from the start and a zero-stamped
    trajectory is published by a new publisher as soon as it matches the controller (which is then
    still configuring: loading and warming its kernels); else the states start once the
    controller is active (first state -> first command) and the trajectory is stamped."""
    log = tempfile.NamedTemporaryFile("w+", prefix="latency-controller-", suffix=".log")  # noqa: SIM115
    extra = [a for p in args.param for a in ("-p", p)]
    proc = subprocess.Popen(controller_args("-p", "enforce_limits:=false", *extra), env=env, stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)
    driver = Driver(args.domain)
    try:
        if start_up:
            print("start-up: a zero-stamped trajectory published as soon as the controller subscribes")
            driver.sender.start()
            published, stamp = driver.trajectory(args.seconds + 2.0, zero_stamp=True, fresh=True)
            measure(driver, published, stamp, 0, args.seconds)
            return 0
        print("activation, then a stamped trajectory")
        if not wait(lambda: active(driver), 120):
            print("controller did not become active", file=sys.stderr)
            return 1
        # the lifecycle services answer from the executor thread before the loop's thread has
        # applied its real-time settings (lock_memory's mlockall took 0.3-1.8 s here): the loop
        # takes no state before then
        time.sleep(3.0)
        driver.sender.start()
        wait(lambda: driver.commands, 3.0)
        if driver.commands:
            print(f"  first state -> first command: {(driver.commands[0][0] - (driver.first_state or 0.0)) * 1e3:.2f}"
                  f" ms (the period is {1e3 / RATE:g} ms)")
        else:
            print("  first state -> first command: no command within 3 s of the first state")
        time.sleep(0.5)
        before = len(driver.commands)
        published, stamp = driver.trajectory(args.seconds + 2.0, zero_stamp=False, fresh=False)
        measure(driver, published, stamp, before, args.seconds)
        return 0
    finally:
        driver.close()
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.kill(proc.pid, signal.SIGKILL)
                proc.wait(timeout=10)
        log.seek(0)
        text = log.read()
        log.close()
        if os.environ.get("LATENCY_LOG"):
            print(text[-3000:], file=sys.stderr)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each trajectory phase")
    parser.add_argument("--domain", type=int, default=os.getpid() % 200 + 20)
    parser.add_argument("-p", "--param", action="append", default=[],
                        help="an extra controller parameter, e.g. -p thread_priority:=0")
    args = parser.parse_args()
    env = dict(os.environ, ROS_DOMAIN_ID=str(args.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PATH=f"{os.path.join(sys.prefix, 'bin')}{os.pathsep}{os.environ.get('PATH', '')}")
    return run(args, env, start_up=True) or run(args, env, start_up=False)


if __name__ == "__main__":
    sys.exit(main())
