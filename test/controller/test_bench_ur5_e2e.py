"""The UR5's shipped gains of pd and pdsmc, and their bench gain files, on the bench arm in real time.

The UR5 of example-robot-data in the MuJoCo stand-in with ``realism:=bench`` (Coulomb and viscous
friction, an 18-bit encoder with noise, the velocity differenced and filtered at 100 Hz, a 2 ms
command delay, a 100 Hz torque lag, the torque-speed line, an unknown 0.925 kg tool:
docs/how-to/mujoco.md) and the controller in real time at 1 kHz with the gains a user starts from:
the shipped UR5 defaults (no params file), and the bench files ``config/ur5_bench_<law>.yaml``
(tools/bench_gains.py: the shipped gains slowed until ``pdsmc check-gains --realism bench`` without
the arm's viscous friction passes at x2). The shipped gains fail that check (x0.95 and x0.91 with the
viscous friction counted): their goal ends are calm while the loop has a core to itself, not
reliably when it shares one (one core kept busy by a spinning process, 23 runs of a law: two
bursts, one runaway stop, one goal lost to a stall), so on a loaded machine this test fails, as the
requirement it states does; the figures are in docs/explanation/ladder.md ("What each law needs to
stay calm"). In a DDS domain of their own
(stand_in_arm.py), stopped by PID; one pair per law and gains.

On each, the peer ``FollowJointTrajectory`` cases of joint_trajectory_controller
(``test/test_trajectory_actions.cpp``, restated on the serial 3R in test_jtc_conformance.py) with
JTC's outcome: a multi-point goal SUCCEEDED with feedback and its last point held; a goal preempted
by a second is ABORTED with JTC's string and the second SUCCEEDED; a cancelled goal is CANCELED with
an empty string and the position at the cancel held; a path tolerance of 0.5 mrad is
PATH_TOLERANCE_VIOLATED and the arm held. The goals give no goal tolerance (JTC's default: none):
the bench arm's Coulomb friction leaves each joint up to its friction over its Kp short of the goal
(the last wrist 0.02 rad with the shipped gains, 0.06 rad with the bench files), so "held" is within
HELD_WITHIN of the goal's end and then still. After every goal end, calm: every joint's true speed
(the stand-in's ``~/true_joint_states``, not the differenced encoder) under 25 % of its URDF
velocity limit over the second that follows; the worst joint's share is printed (``-s``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mujoco")
pytest.importorskip("control_msgs")
from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from stand_in_arm import StandInArm, duration  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from pdsmc_ros.robots import make_robot  # noqa: E402
from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402

UR5 = make_robot(resolve_robot("ur5"))
JOINTS = list(UR5.joint_names)
CALM = 0.25  # of each joint's URDF velocity limit, over the second after a goal has ended
HELD_WITHIN = 0.1  # rad: the last wrist stops up to 0.06 rad short (1.12 N m of friction over a Kp of 18-60 N m/rad)
HOLD = 0.03  # rad: a hold keeps the arm this close to where it settled
CONFIG = Path(__file__).resolve().parents[2] / "config"
SUCCESSFUL = FollowJointTrajectory.Result.SUCCESSFUL
INVALID_GOAL = FollowJointTrajectory.Result.INVALID_GOAL
PATH_TOLERANCE_VIOLATED = FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED


class Arm(StandInArm):
    """The bench stand-in and the controller of ``law`` (``params``: more of its parameters), and a client
    that also records the true velocity."""

    def __init__(self, ros_env: dict, log_dir: Path, law: str, params: tuple[str, ...] = ()) -> None:
        super().__init__(ros_env, log_dir, "bench_client", JOINTS,
                         driver=["-p", "robot:=ur5", "-p", "realism:=bench"],
                         controller=["-p", "robot:=ur5", "-p", f"type:={law}", "-p", "mode:=realtime",
                                     "-p", "stale_periods:=200", *params])
        self.truth: list[tuple[float, np.ndarray]] = []  # the true velocity (the states: the encoder's position)
        self.node.create_subscription(JointState, "/mujoco_driver/true_joint_states", self.on_truth, 1)

    def on_truth(self, msg: JointState) -> None:
        qd = self.in_order(msg, "velocity")
        with self.lock:
            self.truth.append((time.monotonic(), qd))
            del self.truth[:-20000]

    def send(self, goal: FollowJointTrajectory.Goal, feedback: list | None = None) -> object:
        callback = None if feedback is None else (lambda f: feedback.append(f.feedback))
        return self.call(lambda: self.action.send_goal_async(goal, feedback_callback=callback), 30, self.logs)

    def result(self, handle: object, seconds: float = 30.0) -> tuple[int, int, str, float]:
        """Status, error code, error string, and when the answer came (monotonic)."""
        answer = self.call(handle.get_result_async, seconds, self.logs)  # type: ignore[attr-defined]
        return answer.status, answer.result.error_code, answer.result.error_string, time.monotonic()

    def calm_after(self, ended: float, what: str, shares: dict[str, list[float]]) -> np.ndarray:
        """The largest true |qd| / velocity limit per joint over the second after ``ended``."""
        time.sleep(max(0.0, ended + 1.0 - time.monotonic()))
        with self.lock:
            window = np.array([v for t, v in self.truth if ended <= t <= ended + 1.0])
        assert len(window) > 100, ("too few true states", len(window), self.logs())
        share = np.max(np.abs(window), axis=0) / UR5.velocity_limits
        shares[what] = np.round(share, 4).tolist()
        return share

    def held_near(self, q: np.ndarray, seconds: float = 0.8) -> np.ndarray:
        """Each joint's largest distance of the published position from ``q`` over the last half of ``seconds``."""
        start = time.monotonic()
        time.sleep(seconds)

        def window() -> list[np.ndarray]:
            with self.lock:
                return [s[1] for s in self.states if s[0] >= start + seconds / 2]

        # a loaded 2-core machine can starve this client for a moment: wait for a state rather than fail
        assert self.wait(lambda: len(window()) > 0, 10.0), ("no joint states", self.logs())
        return np.max(np.abs(np.array(window()) - q), axis=0)


def goal(points: list[tuple[np.ndarray, float]], *, path: float | None = None,
         at_goal: np.ndarray | None = None) -> FollowJointTrajectory.Goal:
    """Points ``(q, t)``, the last at rest; the path and goal tolerances on every joint, if given."""
    zero = [0.0] * len(JOINTS)
    trajectory = JointTrajectory(joint_names=JOINTS, points=[
        JointTrajectoryPoint(positions=[float(x) for x in q], time_from_start=duration(t),
                             **({"velocities": zero} if k == len(points) - 1 else {}))
        for k, (q, t) in enumerate(points)])
    return FollowJointTrajectory.Goal(
        trajectory=trajectory, goal_time_tolerance=duration(2.0),
        path_tolerance=[] if path is None else [JointTolerance(name=j, position=path) for j in JOINTS],
        goal_tolerance=[] if at_goal is None else [JointTolerance(name=j, position=float(tol), velocity=0.2)
                                                   for j, tol in zip(JOINTS, at_goal, strict=True)])


def each_goal(arm: Arm, shares: dict[str, list[float]], tolerance: np.ndarray | None, hold: np.ndarray) -> None:
    """JTC's peer cases on the bench arm, calm after each end."""
    calm: Callable[[float, str], np.ndarray] = lambda ended, what: arm.calm_after(ended, what, shares)  # noqa: E731
    step = np.array([0.3, -0.2, 0.25, 0.2, -0.2, 0.3])

    # JTC test_success_multi_point_sendgoal: SUCCEEDED, SUCCESSFUL, feedback received, last point held
    feedback: list = []
    q0 = arm.q()
    q1 = q0 + step
    handle = arm.send(goal([((q0 + q1) / 2, 1.0), (q1, 2.0)], at_goal=tolerance), feedback)
    assert handle.accepted, arm.logs()  # type: ignore[attr-defined]
    status, code, text, ended = arm.result(handle)
    assert (status, code, text) == (GoalStatus.STATUS_SUCCEEDED, SUCCESSFUL, "Goal successfully reached!"), \
        (text, arm.logs())
    assert feedback and list(feedback[-1].joint_names) == JOINTS
    assert np.all(calm(ended, "multi-point goal SUCCEEDED") < CALM), (shares, arm.logs())
    held = arm.held_near(q1)
    shares["held from the goal's end (rad)"] = np.round(held, 4).tolist()
    assert np.all(held < hold), (held, arm.logs())

    # JTC preempted_goal_receives_aborted_result: A ABORTED INVALID_GOAL with JTC's string, B SUCCEEDED
    q = arm.q()
    a = arm.send(goal([(q - step, 3.0)]))
    time.sleep(0.5)
    q = arm.q()
    q_b = q + 0.1 * step
    b = arm.send(goal([(q_b, 1.0)], at_goal=tolerance))
    assert a.accepted and b.accepted, arm.logs()  # type: ignore[attr-defined]
    assert arm.result(a)[:3] == (GoalStatus.STATUS_ABORTED, INVALID_GOAL,
                                 "Current goal preempted by new incoming action."), arm.logs()
    status, code, text, ended = arm.result(b)
    assert (status, code) == (GoalStatus.STATUS_SUCCEEDED, SUCCESSFUL), (text, arm.logs())
    assert np.all(calm(ended, "preempting goal SUCCEEDED") < CALM), (shares, arm.logs())
    held = arm.held_near(q_b)
    shares["held from the preempting goal's end (rad)"] = np.round(held, 4).tolist()
    assert np.all(held < hold), (held, arm.logs())

    # JTC test_cancel_hold_position: CANCELED, SUCCESSFUL, empty string; the position at the cancel held
    q = arm.q()
    handle = arm.send(goal([(q - step, 3.0)]))
    assert handle.accepted, arm.logs()  # type: ignore[attr-defined]
    time.sleep(1.0)
    assert arm.call(handle.cancel_goal_async, 30, arm.logs).goals_canceling, \
        (arm.result(handle), arm.logs())  # type: ignore[attr-defined]  # not ended before the cancel
    status, code, text, ended = arm.result(handle)
    assert (status, code, text) == (GoalStatus.STATUS_CANCELED, SUCCESSFUL, ""), arm.logs()
    assert np.all(calm(ended, "cancelled goal") < CALM), (shares, arm.logs())
    at_rest = arm.q()
    assert np.all(arm.held_near(at_rest) < HOLD) and abs(arm.q()[0] - (q - step)[0]) > 0.1, arm.logs()

    # JTC test_state_tolerances_fail: PATH_TOLERANCE_VIOLATED, then the position held
    q = arm.q()
    handle = arm.send(goal([(q + step, 1.5)], path=0.0005))
    assert handle.accepted, arm.logs()  # type: ignore[attr-defined]
    status, code, text, ended = arm.result(handle)
    assert (status, code) == (GoalStatus.STATUS_ABORTED, PATH_TOLERANCE_VIOLATED), (text, arm.logs())
    assert np.all(calm(ended, "path tolerance violated") < CALM), (shares, arm.logs())
    at_rest = arm.q()
    assert np.all(arm.held_near(at_rest) < HOLD), arm.logs()


GAINS = {"shipped": (), **{f"bench {law}": ("--params-file", str(CONFIG / f"ur5_bench_{law}.yaml"))
                            for law in ("pd", "pdsmc")}}
"""The controller's gains: the shipped UR5 defaults (config/gains.yaml, no params file: what a user starts
with), and the bench gain files (tools/bench_gains.py)."""


@pytest.mark.timeout(240)
@pytest.mark.parametrize(("law", "gains"), [("pd", "shipped"), ("pdsmc", "shipped"),
                                            ("pd", "bench pd"), ("pdsmc", "bench pdsmc")])
def test_the_ur5_gains_end_every_goal_calm_on_the_bench_arm(ros_env: dict, tmp_path: Path, law: str,
                                                            gains: str) -> None:
    arm = Arm(ros_env, tmp_path, law, GAINS[gains])
    shares: dict[str, list[float]] = {}
    try:
        assert arm.up(), arm.logs()
        time.sleep(1.5)  # settled in the hold of activation (the arm sags until the delay line fills)
        each_goal(arm, shares, None, np.full(len(JOINTS), HELD_WITHIN))
    finally:
        for what, share in shares.items():
            print(f"{law} ({gains} gains) {what}: after the end, peak true |qd| / limit per joint {share}")
        if shares:
            worst = max(max(v) for k, v in shares.items() if not k.startswith("held"))
            print(f"{law} ({gains} gains): worst joint after a goal end {100 * worst:.1f} % of its velocity limit")
        arm.close()
