"""How long a trajectory's validation takes in the action server's thread: prints the figures.

A goal or a ``~/joint_trajectory`` message is validated when it arrives
(:func:`pdsmc_ros.controller.goals.prepare_trajectory`: joint_trajectory_controller's checks, the
reference built from the measured state, the arm's limits along every segment and the step
check), in the action server's thread, never the control loop's. A trajectory longer than
:data:`pdsmc_ros.controller.joint_trajectory.MAX_POINTS` is refused before it is looked at; this
prints what the accepted sizes cost: positions only (linear segments) and with velocities
and accelerations (quintic segments), six joints, best of three, with the machine's load.

Usage: ``.venv/bin/python bench/goal_validation.py [--sizes 100 1000 5000]`` (ROS-free).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from pdsmc_ros.controller import goals as g
from pdsmc_ros.controller.joint_trajectory import MAX_POINTS
from pdsmc_ros.controller.limits import JointLimits

JOINTS = tuple(f"joint{i + 1}" for i in range(6))


class _Arm:
    position_limits = np.array([[-6.3, 6.3]] * 6)
    velocity_limits = np.full(6, 3.15)


def _points(n: int, quintic: bool) -> list[tuple]:
    points = []
    for k in range(n):
        t = 0.01 * (k + 1)
        q = list(0.1 * np.sin(np.full(6, t)))
        last = k == n - 1
        v = ([0.0] * 6 if last else list(0.1 * np.cos(np.full(6, t)))) if quintic else []
        a = [0.0] * 6 if quintic else []
        points.append((q, v, a, int(t), int(round((t % 1.0) * 1e9))))
    return points


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, MAX_POINTS])
    sizes = parser.parse_args().sizes
    limits = JointLimits.of(_Arm(), JOINTS)
    state = (np.zeros(6), np.zeros(6))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; size limit {MAX_POINTS} points")
    for n in sizes:
        for quintic in (False, True):
            points = _points(n, quintic)
            best = float("inf")
            for _ in range(3):
                start = time.perf_counter()
                reference, problem = g.prepare_trajectory(g.GoalSettings(), limits, JOINTS, 0.0, JOINTS, points,
                                                          100.0, state)
                best = min(best, time.perf_counter() - start)
            kind = "quintic  " if quintic else "positions"
            verdict = "accepted" if reference is not None else f"refused: {problem[:60]}"
            print(f"{n:6d} points, {kind}: {best * 1e3:8.1f} ms ({best / n * 1e6:6.1f} us a point), {verdict}")


if __name__ == "__main__":
    main()
