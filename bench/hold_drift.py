"""Benchmark: do repeated holds creep? 200 send-and-cancel pairs on the UR5 stand-in (issue 37).

The UR5 in the MuJoCo stand-in and the controller in real time with the shipped gains of each law
(as ``bench/goal_ends.py``, whose processes and client this reuses). After the activation's hold
settles, ``--pairs`` times: a goal that stays where it starts (its first point at t = 0, its last
at 1.5 s at the same position), canceled ``--cancel-after`` s after it is accepted (the controller
then holds), the next goal sent ``--gap`` s after the cancel's answer. Where it starts
(``--start``): ``measured``, the latest measured position, as MoveIt starts a trajectory; or
``reference``, the controller's reference (``/controller/controller_state``'s ``reference``: the
position it holds), which leaves the holds as the only thing that could move the arm. Before the
first pair and after the last (each after ``--settle`` s): the mean measured
position over 0.2 s. Printed per law: the drift per joint (mrad; target: every joint under 5 mrad,
the issue's "repeated holds do not creep"), how the goals ended, and the load average.

What to expect: the holds start from the commanded position (``ControllerCore.start_state``), so
goals from the reference leave the arm where it was; goals from the measured position move the
reference each time to where the arm sags to, by the law's steady-state error under gravity (PD
on the UR5's elbow: 5.3 mrad), and the arm creeps by up to that much per pair, whatever the holds.

Last line: ``worst_drift_mrad=D`` (the largest over every law and joint).

Usage: python bench/hold_drift.py [--laws pd,smc,pdsmc] [--pairs 200] [--busy]   (inside the venv,
after make setup; the venv's bin first on PATH)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from control_msgs.msg import JointTrajectoryControllerState  # noqa: E402
from goal_ends import Client, _outcome, goal, load, running  # noqa: E402

from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402


def settled(client: Client, seconds: float) -> np.ndarray:
    """The mean position over the last 0.2 s of ``seconds`` of waiting."""
    time.sleep(seconds)
    end = time.time() - 0.3  # states stamped this late have arrived (the client's lag)
    q = client.between(end - 0.2, end, position=True)
    return q.mean(axis=0) if q.size else client.q()


class Reference:
    """The controller's latest reference position (``~/controller_state``), in ``names`` order."""

    def __init__(self, client: Client, names: list[str]) -> None:
        self.names, self.latest = names, None
        with client.spinning:
            client.node.create_subscription(JointTrajectoryControllerState, "/controller/controller_state",
                                            self.on_state, 10)

    def on_state(self, msg: JointTrajectoryControllerState) -> None:
        index = [list(msg.joint_names).index(n) for n in self.names]
        self.latest = np.asarray(msg.reference.positions)[index]

    def q(self) -> np.ndarray:
        deadline = time.monotonic() + 5
        while self.latest is None and time.monotonic() < deadline:
            time.sleep(0.01)
        if self.latest is None:
            raise RuntimeError("no /controller/controller_state in 5 s")
        return self.latest.copy()


def drift(client: Client, names: list[str], pairs: int, cancel_after: float, gap: float,
          settle: float, reference: Reference | None) -> tuple[np.ndarray, dict[str, int], np.ndarray]:
    """``(drift per joint (rad), how the goals ended, reference - measured before the first pair)``"""
    start = settled(client, settle)
    offset = (reference.q() - start) if reference is not None else np.zeros_like(start)
    how: dict[str, int] = {}
    for _ in range(pairs):
        here = client.q() if reference is None else reference.q()
        handle = client.call(lambda here=here: client.action.send_goal_async(goal(names, here, here)))
        if handle is None or not handle.accepted:
            outcome = "no answer" if handle is None else "rejected"
        else:
            time.sleep(cancel_after)
            client.call(lambda handle=handle: handle.cancel_goal_async())
            outcome = _outcome(client.call(lambda handle=handle: handle.get_result_async(), 10.0))
        how[outcome] = how.get(outcome, 0) + 1
        time.sleep(gap)
    return settled(client, settle) - start, how, offset


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", default="pd,smc,pdsmc")
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--cancel-after", type=float, default=0.1, help="s between acceptance and cancel")
    parser.add_argument("--gap", type=float, default=0.05, help="s between a cancel's answer and the next goal")
    parser.add_argument("--settle", type=float, default=2.0, help="s of waiting before each measured position")
    parser.add_argument("--start", choices=("measured", "reference"), default="measured",
                        help="where each goal starts: the measured position (MoveIt) or the controller's reference")
    parser.add_argument("--busy", action="store_true", help="keep one core busy with another process")
    parser.add_argument("--domain", type=int, default=78)
    args = parser.parse_args()
    robot = make_robot(resolve_robot("ur5"))
    names = list(robot.joint_names)
    env = dict(os.environ, ROS_DOMAIN_ID=str(args.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    logs = Path(f"/tmp/hold_drift-{os.getpid()}")
    logs.mkdir(parents=True, exist_ok=True)
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.busy else None
    worst = 0.0
    try:
        for law in args.laws.split(","):
            before = load()
            with running(law, names, args.domain, env, logs, tag="-drift") as client:
                reference = Reference(client, names) if args.start == "reference" else None
                moved, how, offset = drift(client, names, args.pairs, args.cancel_after, args.gap, args.settle,
                                           reference)
            mrad = np.abs(moved) * 1e3
            worst = max(worst, float(np.max(mrad)))
            joints = ", ".join(f"{n.removesuffix('_joint')} {d * 1e3:+.2f}" for n, d in zip(names, moved, strict=True))
            if reference is not None:
                print(f"{law:8s} reference - measured before the pairs (mrad): "
                      + ", ".join(f"{d * 1e3:+.2f}" for d in offset), flush=True)
            print(f"{law:8s} {args.pairs} pairs from the {args.start} position: drift (mrad) {joints}; largest "
                  f"{np.max(mrad):.2f} "
                  f"({names[int(np.argmax(mrad))]}); {how}; load average {before} -> {load()}", flush=True)
    finally:
        if busy is not None:
            busy.kill()
    print(f"worst_drift_mrad={worst:.2f}  (logs: {logs})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
