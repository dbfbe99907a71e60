"""Benchmark: lockstep closed-loop steps per wall second over DDS.

Runs the real four-node system (plant with the serial arm's dynamics,
trajectory, controller type:=pdsmc, recorder) through scripts/run_experiment.sh
on a time-scaled serial circle at 10 kHz, in the multi-process default, in
the composed mode and with only the plant and the controller composed (each
also with ``--intra-process``), the four processes pinned with the nodes'
``cpu_affinity`` (plant and controller, which alternate, on one core; the observers
on the other), and -- in the same run -- a plain two-process
rclpy publish/echo round trip with default executors. Steps per second are taken
from the recorder's receive times of /joint_states (start-up excluded).

Last line: ``lockstep_steps_per_s=N rclpy_roundtrips_per_s=M``, N of the composed
intra-process arrangement (the fastest; the four-process and every other figure,
with its N/M, are printed above it).

Usage: python bench/lockstep.py [--steps 20000] [--nice -10]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def echo_main(seconds: float) -> None:
    """The echo side of the round trip: republish every /ping on /pong."""
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray

    rclpy.init()
    node = Node("bench_echo")
    pub = node.create_publisher(Float64MultiArray, "bench/pong", 10)
    node.create_subscription(Float64MultiArray, "bench/ping", pub.publish, 10)
    from rclpy.executors import ExternalShutdownException

    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def roundtrips_per_s(seconds: float = 4.0) -> float:
    """Plain rclpy round trips (publish, echo in another process, receive), default executors."""
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray

    echo = subprocess.Popen([sys.executable, __file__, "--echo", str(seconds + 8)])
    try:
        rclpy.init()
        node = Node("bench_ping")
        pub = node.create_publisher(Float64MultiArray, "bench/ping", 10)
        got = {"n": 0}
        node.create_subscription(Float64MultiArray, "bench/pong", lambda _m: got.__setitem__("n", got["n"] + 1), 10)
        deadline = time.monotonic() + 20
        while (
            pub.get_subscription_count() < 1 or node.count_publishers("bench/pong") < 1
        ) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        time.sleep(0.5)
        msg = Float64MultiArray(data=[0.0, 0.0, 0.0])
        count = 0
        start = time.perf_counter()
        while time.perf_counter() - start < seconds:
            expected = got["n"] + 1
            pub.publish(msg)
            while got["n"] < expected:
                rclpy.spin_once(node, timeout_sec=1.0)
            count += 1
        rate = count / (time.perf_counter() - start)
        node.destroy_node()
        rclpy.try_shutdown()
        return rate
    finally:
        echo.send_signal(__import__("signal").SIGINT)
        echo.wait(timeout=10)


def lockstep_steps_per_s(steps: int, composition: Sequence[str] = (), *, robot: str = "serial_3r",
                         circle_steps: int = 50000) -> tuple[float, int]:
    """Steps per second of one lockstep run; returns (rate, messages lost).

    ``composition``: run_experiment.sh options (``--composed`` or ``--compose LIST``);
    ``circle_steps``: the robot's circle at its default rate (the serial arm's: 5 s at 10 kHz).
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    factor = steps / circle_steps
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench"
        cmd = ["bash", str(ROOT / "scripts" / "run_experiment.sh"), "--robot", robot,
               "--contour", "circle", "--controller", "pdsmc", "--duration-factor", f"{factor:g}",
               "--out", str(out), "--timeout", "900"]
        cmd += list(composition)
        subprocess.run(cmd, check=True, env=os.environ.copy())
        stamps = []
        with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            conns = [c for c in reader.connections if c.topic == "/joint_states"]
            for _conn, t, _raw in reader.messages(connections=conns):
                stamps.append(t)
            counts = {c.topic: c.msgcount for c in reader.connections}
    stamps = np.asarray(stamps)
    expected = steps + 1
    lost = sum(expected - counts[t] for t in ("/joint_states", "/reference", "/effort_controller/commands"))
    return (len(stamps) - 1) / ((stamps[-1] - stamps[0]) * 1e-9), lost


# every arrangement of the four nodes measured (run_experiment.sh options)
ARRANGEMENTS = (
    ("4 processes", []),
    ("composed (1 process)", ["--composed"]),
    ("composed, intra-process (1 process, no DDS between the nodes)", ["--composed", "--intra-process"]),
    ("plant+controller composed, trajectory and recorder apart (3 processes)", ["--compose", "plant,controller"]),
    ("plant+controller composed intra-process, the others apart (3 processes)",
     ["--compose", "plant,controller", "--intra-process"]),
)
PINNED = "4 processes, pinned (plant+controller on core 0, trajectory+recorder on core 1; cpu_affinity)"
# each node's cpu_affinity (issue 26): the two that alternate on the loop share a core, the observers the other
PIN_PARAMS = "".join(f"{node}:\n  ros__parameters:\n    cpu_affinity: [{core}]\n" for node, core in
                     (("plant", 0), ("controller", 0), ("trajectory", 1), ("recorder", 1)))
HEADLINE = "composed, intra-process (1 process, no DDS between the nodes)"
"""The arrangement of the last line: the fastest (docs/PERFORMANCE.md); every one is printed above it."""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--nice", type=int, default=None,
                        help="niceness of the plant and the controller (run_experiment.sh --nice; negative needs root)")
    parser.add_argument("--echo", type=float, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo is not None:
        echo_main(args.echo)
        return 0
    nice = [] if args.nice is None else ["--nice", str(args.nice)]
    rates = {}
    with tempfile.NamedTemporaryFile("w", suffix=".yaml") as pin:
        pin.write(PIN_PARAMS)
        pin.flush()
        arrangements = list(ARRANGEMENTS)
        if (os.cpu_count() or 1) >= 2:
            arrangements.insert(1, (PINNED, ["--params-file", pin.name]))
        for label, options in arrangements:
            rate, lost = lockstep_steps_per_s(args.steps, [*options, *nice])
            rates[label] = rate
            print(f"lockstep, {label}: {rate:,.0f} steps/s ({args.steps} steps, {lost} messages lost)", flush=True)
    rt = roundtrips_per_s()
    print(f"plain rclpy publish/echo round trip, default executors: {rt:,.0f} round trips/s")
    for label, rate in rates.items():
        print(f"  N/M {rate / rt:4.1f}  {label}")
    four = max(rates["4 processes"], rates.get(PINNED, 0.0))
    print(f"four processes, the faster arrangement: N/M {four / rt:.2f} (target >= 2)")
    print(f"last line: {HEADLINE}")
    print(f"lockstep_steps_per_s={rates[HEADLINE]:.0f} rclpy_roundtrips_per_s={rt:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
