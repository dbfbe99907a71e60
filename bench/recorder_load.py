"""Benchmark: what the recorder keeps of a MuJoCo stand-in's run while another process keeps a core busy.

Starts the recorder, then the MuJoCo stand-in (``mujoco_driver``, serial 3R, 1 kHz, wall-stamped
``/joint_states``) and the controller (``type:=pd``, real time, holding the arm: its commands
on ``/effort_controller/commands`` at 1 kHz), and one busy process (a Python loop) on a
2-core machine; after ``--seconds`` it stops the driver (which logs how many states it
published), the controller, the busy process and last the recorder, and reads the bag.

Prints, for ``/joint_states``: published (the driver's own count), recorded, the longest gap
between consecutive recorded header stamps (the driver's own periods are in its log line) and
the longest gap between receive times (the recorder's stalls); for the commands, recorded.
The driver and the controller run from a git revision (``--revision``, default HEAD), the
recorder from this checkout in its graph mode, or with ``--before`` from that revision in its
pipeline mode, as a real arm's run was recorded before the graph mode existed.

Usage: python bench/recorder_load.py [--seconds 20] [--before [--revision REV]] [--busy 1]
(inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
COMMON = ["-p", "thread_priority:=0"]  # no SCHED_FIFO spinning beside DDS on a shared machine
AFTER = ["-p", "topics:=[/joint_states,/effort_controller/commands,/diagnostics,/robot_description]",
         "-p", "actions:=[/controller/follow_joint_trajectory]"]
BEFORE = ["-p", "robot:=serial_3r", "-p", "mode:=realtime"]


def stop(proc: subprocess.Popen, grace: float = 20.0) -> int:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGINT)
    try:
        return proc.wait(timeout=grace)
    except subprocess.TimeoutExpired:
        os.kill(proc.pid, signal.SIGKILL)
        return proc.wait(timeout=10)


def read(bag: Path) -> dict[str, tuple[list[bytes], np.ndarray]]:
    from rosbags.highlevel import AnyReader

    out: dict[str, tuple[list[bytes], list[int]]] = {}
    with AnyReader([bag]) as reader:
        for conn, log_ns, raw in reader.messages():
            data, times = out.setdefault(conn.topic, ([], []))
            data.append(bytes(raw))
            times.append(log_ns)
    return {t: (d, np.asarray(ts) * 1e-9) for t, (d, ts) in out.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--busy", type=int, default=1, help="busy processes beside the run")
    parser.add_argument("--before", action="store_true", help="the recorder of --revision, in its pipeline mode")
    parser.add_argument("--revision", default="HEAD")
    options = parser.parse_args()
    from pdsmc_ros.bag.cdr import decode_stamp

    work = Path(tempfile.mkdtemp(prefix="recorder_load_"))
    # the graph (driver, controller) runs from --revision's package, extracted; the recorder too with
    # --before, else from this checkout
    revision = work / "tree"
    revision.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", options.revision, "pdsmc_ros", "config",
                              "package.xml"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(revision)], input=archive, check=True)
    env = dict(os.environ, ROS_DOMAIN_ID=str(200 + os.getpid() % 30), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               AMENT_PREFIX_PATH=sys.prefix)
    env.setdefault("NUMBA_CACHE_DIR", str(Path(sys.prefix) / "numba-cache"))
    ros2 = str(Path(sys.prefix) / "bin" / "ros2")
    bag = work / "bag"

    def start(name: str, *params: str) -> subprocess.Popen:
        tree = ROOT if name == "recorder" and not options.before else revision
        return subprocess.Popen([ros2, "run", "pdsmc_ros", name, "--ros-args", *COMMON, *params],
                                env=dict(env, PYTHONPATH=str(tree)),
                                stdout=(work / f"{name}.log").open("w"), stderr=subprocess.STDOUT,
                                start_new_session=True)

    recorder = start("recorder", "-p", f"output:={bag}", *(BEFORE if options.before else AFTER))
    time.sleep(3.0)
    driver = start("mujoco_driver", "-p", "robot:=serial_3r")
    controller = start("controller", "-p", "robot:=serial_3r", "-p", "type:=pd", "-p", "mode:=realtime",
                       "-p", "rate:=1000.0", "-p", "sample_rate:=1000.0", "-p", "kp:=[800.0, 800.0, 160.0]",
                       "-p", "kd:=[40.0, 40.0, 8.0]", "-p", "stale_periods:=200")
    deadline = time.monotonic() + 120.0  # start-up (memory locked, kernels loaded) before the window
    while time.monotonic() < deadline and controller.poll() is None and "real time: " not in (
            work / "controller.log").read_text(errors="replace"):
        time.sleep(0.2)
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(options.busy)]
    window = time.time()
    try:
        time.sleep(options.seconds)
    finally:
        window_end = time.time()
        codes = {"driver": stop(driver), "controller": stop(controller)}
        for proc in busy:
            proc.kill()
            proc.wait()
        time.sleep(1.0)
        codes["recorder"] = stop(recorder)
    log = (work / "mujoco_driver.log").read_text(errors="replace")
    found = re.search(r"(\d+) states, mean rate .*? max (\d+) us", log)
    published = int(found.group(1)) if found else -1
    driver_worst_ms = int(found.group(2)) / 1000.0 if found else float("nan")
    topics = read(bag)
    states, received = topics.get("/joint_states", ([], np.empty(0)))
    stamps = np.sort(np.array([s + n * 1e-9 for s, n in (decode_stamp(d) for d in states)]))
    commands = len(topics.get("/effort_controller/commands", ([], None))[0])
    # the gaps of the loaded window (start-up's are the nodes' own: memory locking, first commands)
    inside = stamps[(stamps >= window) & (stamps <= window_end)]
    gap = float(np.diff(inside).max()) if len(inside) > 1 else float("nan")
    taken = np.sort(received[(received >= window) & (received <= window_end)])
    stall = float(np.diff(taken).max()) if len(taken) > 1 else float("nan")
    print(f"exit codes {codes}; logs and bag in {work}")
    print(f"/joint_states: published {published}, recorded {len(states)} (lost {published - len(states)}), "
          f"{len(inside)} stamped in the {options.seconds:g} s loaded window, longest stamp gap "
          f"{1e3 * gap:.1f} ms (the driver's worst period jitter {driver_worst_ms:.1f} ms), "
          f"longest receive gap {1e3 * stall:.1f} ms; /effort_controller/commands recorded {commands}")
    print(f"recorder={'before' if options.before else 'graph'} published={published} recorded={len(states)} "
          f"gap_ms={1e3 * gap:.1f} receive_gap_ms={1e3 * stall:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
