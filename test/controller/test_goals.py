"""The controller's ROS-free decisions: goals (joint_trajectory_controller's semantics), hold,
limits, joints by name, the real-time source switching."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros.controller import goals as g
from pdsmc_ros.controller.commanding import LatestInputs
from pdsmc_ros.controller.hold import Hold
from pdsmc_ros.controller.joint_trajectory import JointTrajectoryReference
from pdsmc_ros.controller.joints import JointSelector
from pdsmc_ros.controller.limits import JointLimits
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.parameters.joint_map import JointMap

NAMES = ("joint1", "joint2", "joint3")
SELECTOR = JointSelector(NAMES)
Q0 = np.array([0.1, 0.2, 0.3])
ZERO = np.zeros(3)


def point(q: list[float], at: float, v: list[float] | None = None) -> tuple:
    return (q, v or [], [], int(at), int(round((at % 1.0) * 1e9)))


def reference(points: list[tuple], now: float = 100.0, stamp: float = 0.0) -> JointTrajectoryReference:
    ref, problem = JointTrajectoryReference.from_message(SELECTOR, stamp, NAMES, points, now, Q0, ZERO)
    assert ref is not None, problem
    return ref


def execution(tolerances: g.Tolerances, end: float = 1.0) -> g.GoalExecution:
    ref = reference([point([0.2, 0.2, 0.3], end)])
    return g.GoalExecution(ref, tolerances, NAMES)


def tolerances(path: float = 0.0, goal: float = 0.0, goal_time: float = 0.0, stopped: float = 0.01) -> g.Tolerances:
    return g.Tolerances(np.full(3, path), np.zeros(3), np.full(3, goal), np.full(3, stopped), goal_time)


def test_goal_succeeds_at_the_end_within_the_goal_tolerances() -> None:
    run = execution(tolerances(path=0.05, goal=0.01))
    desired = run.reference.sample(100.5)
    assert run.update(100.5, desired[0], desired[1], desired) is None  # on the path, before the end
    end = run.reference.sample(101.0)
    outcome = run.update(101.0, end[0] + 0.005, ZERO, end)
    assert outcome is not None and outcome.status == "succeeded" and outcome.error_code == g.SUCCESSFUL
    assert run.done.is_set() and run.update(101.1, end[0], ZERO, end) is None  # ended once


def test_path_tolerance_breach_aborts_in_the_period_it_happens() -> None:
    run = execution(tolerances(path=0.05))
    desired = run.reference.sample(100.2)
    assert run.update(100.2, desired[0] + [0.0, 0.04, 0.0], ZERO + desired[1], desired) is None
    outcome = run.update(100.201, desired[0] + [0.0, 0.06, 0.0], desired[1], desired)
    assert outcome is not None and outcome.error_code == g.PATH_TOLERANCE_VIOLATED
    assert outcome.status == "aborted" and "'joint2'" in outcome.error_string


def test_outside_the_goal_tolerance_fails_only_after_goal_time_tolerance() -> None:
    run = execution(tolerances(goal=0.01, goal_time=0.5))
    end = run.reference.sample(101.0)
    off = end[0] + [0.02, 0.0, 0.0]
    assert run.update(101.0, off, ZERO, end) is None
    assert run.update(101.49, off, ZERO, end) is None  # still within goal_time_tolerance
    outcome = run.update(101.51, off, ZERO, end)
    assert outcome is not None and outcome.error_code == g.GOAL_TOLERANCE_VIOLATED
    assert "'joint1'" in outcome.error_string
    # goal_time 0 (the default): it waits as long as it takes, as joint_trajectory_controller
    patient = execution(tolerances(goal=0.01))
    assert patient.update(200.0, off, ZERO, end) is None
    assert patient.update(200.001, end[0], ZERO, end) is not None


def test_goal_velocity_tolerance_is_the_stopped_velocity_tolerance_by_default() -> None:
    run = execution(g.Tolerances.defaults(3))
    end = run.reference.sample(101.0)
    assert run.update(101.0, end[0], ZERO + [0.0, 0.02, 0.0], end) is None  # still moving
    assert run.update(101.001, end[0], ZERO + [0.0, 0.005, 0.0], end) is not None


def test_tolerances_resolve_as_joint_trajectory_controller() -> None:
    defaults = tolerances(path=0.1, goal=0.02)
    resolved, warning = g.resolve_tolerances(defaults, NAMES, [("joint2", 0.3, 0.0), ("joint3", -1.0, 0.0)],
                                             [("joint1", 0.0, 0.5)], 2.0)
    assert warning == ""
    np.testing.assert_array_equal(resolved.path_position, [0.1, 0.3, 0.0])  # 0 keeps, -1 erases
    np.testing.assert_array_equal(resolved.goal_velocity, [0.5, 0.01, 0.01])
    assert resolved.goal_time == 2.0
    for path, goal_time in (([("wrist", 0.1, 0.0)], 0.0), ([("joint1", -2.0, 0.0)], 0.0), ([], -3.0)):
        kept, warning = g.resolve_tolerances(defaults, NAMES, path, [], goal_time)
        assert kept is defaults and warning


def prepare(points: list[tuple], *, stamp: float = 0.0, names: tuple = NAMES, state: tuple | None = (Q0, ZERO),
            limits: JointLimits | None = None, settings: g.GoalSettings | None = None) -> tuple:
    return g.prepare_trajectory(settings or g.GoalSettings(), limits, NAMES, stamp, names, points, 100.0, state)


def test_goal_validation_reasons() -> None:
    ok = [point([0.2, 0.2, 0.3], 1.0)]
    ref, problem = prepare(ok)
    assert ref is not None and problem == ""
    for names, needle in ((("joint1", "joint2"), "'joint3' missing"), ((*NAMES, "gripper"), "don't match")):
        assert needle in prepare([point([0.2] * len(names), 1.0)], names=names)[1]
    assert "ends 49.000 s before it was received" in prepare(ok, stamp=50.0)[1]
    backwards = [point([0.2, 0.2, 0.3], 1.0), point([0.3, 0.2, 0.3], 0.5)]
    assert "not after point 0's" in prepare(backwards)[1]
    moving = [point([0.2, 0.2, 0.3], 1.0, [0.1, 0.0, 0.0])]
    assert "velocity of the last trajectory point of joint 'joint1' is not zero" in prepare(moving)[1]
    assert "no complete joint state" in prepare(ok, state=None)[1]


class FakeRobot:
    position_limits = np.array([[-1.0, 1.0], [-0.5, 0.5], [-np.inf, np.inf]])
    velocity_limits = np.array([1.0, 1.0, np.inf])


def test_limits_refuse_a_goal_naming_joint_point_and_time() -> None:
    limits = JointLimits.of(FakeRobot(), NAMES)
    beyond = [point([0.2, 0.2, 0.3], 1.0), point([0.2, 0.7, 0.3], 3.0)]
    ref, problem = prepare(beyond, limits=limits)
    assert ref is None and "'joint2'" in problem and "point 1" in problem and "t = " in problem
    assert problem.startswith("beyond the arm's limits (reject_beyond_limits)")
    fast = [point([0.9, 0.2, 0.3], 0.5)]  # 1.6 rad/s on joint1
    assert "velocity" in prepare(fast, limits=limits)[1]
    # reject_beyond_limits false: accepted as joint_trajectory_controller accepts it
    assert prepare(fast, limits=limits, settings=g.GoalSettings(reject_beyond_limits=False))[0] is not None
    outside = (np.array([0.1, 0.6, 0.3]), ZERO)  # the arm itself is outside joint2's limits
    problem = prepare([point([0.1, 0.2, 0.3], 1.0)], state=outside, limits=limits)[1]
    assert "starts from a state outside" in problem
    # a cubic segment that overshoots between two points inside the limits is caught too
    overshoot = [point([0.4, 0.2, 0.3], 1.0, [0.9, 0.0, 0.0]), point([0.45, 0.2, 0.3], 2.0, [0.0, 0.0, 0.0])]
    ref = reference(overshoot)
    peak = max(ref.sample(100.0 + t)[0][0] for t in np.linspace(1.0, 2.0, 201))
    tight = JointLimits(NAMES, np.array([[-1.0, (0.45 + peak) / 2], [-1, 1], [-1, 1]]), np.full(3, 10.0))
    assert "before point 1" in tight.trajectory_problem(ref)
    assert JointLimits.of(object(), NAMES).trajectory_problem(ref) == ""  # no limits known: none applied


def test_goal_slot_preempts_cancels_and_holds() -> None:
    driven: list[object] = []
    holds: list[str] = []
    slot = g.GoalSlot(driven.append, holds.append)
    first, second = execution(tolerances()), execution(tolerances(path=0.01))
    assert slot.start(first) is None and driven == [first.reference]
    assert slot.start(second) is first and first.outcome == g.PREEMPTED and first.done.is_set()
    assert not slot.cancel(first)  # not the active one
    assert slot.cancel(second) and second.outcome.status == "canceled" and holds == ["goal canceled"]
    third = execution(tolerances(path=0.01))
    slot.start(third)
    desired = third.reference.sample(100.5)
    outcome, held = slot.check(100.5, desired[0] + 0.1, desired[1], desired)
    assert held and outcome.error_code == g.PATH_TOLERANCE_VIOLATED and slot.active is None and len(holds) == 2
    fourth = execution(tolerances())
    slot.start(fourth)
    end = fourth.reference.sample(101.0)
    outcome, held = slot.check(101.0, end[0], ZERO, end)
    assert outcome.status == "succeeded" and not held  # the trajectory holds its last point itself
    slot.start(fifth := execution(tolerances()))
    topic = reference([point([0.3, 0.2, 0.3], 2.0)])
    # a topic trajectory replaces the running one; the goal goes on, judged against it (JTC)
    assert slot.follow(topic, tolerances(), NAMES, 0.0) and driven[-1] is topic
    assert fifth.outcome is None and fifth.reference is topic and slot.active is fifth


def test_realtime_inputs_hold_the_first_state_after_activation() -> None:
    latest = LatestInputs(stale_s=0.02)
    clock = lambda: 5.0  # noqa: E731
    assert latest.take(1.0, clock) == (None, "")  # nothing yet
    latest.add_state((0.1, 0.2, 0.3), (0.0, 0.0, 0.0), 1.0)
    inputs, _ = latest.take(1.0005, clock)
    q, qd, ref, t = inputs
    np.testing.assert_array_equal(ref[0], [0.1, 0.2, 0.3])
    assert not ref[1].any() and not ref[2].any() and t == 5.0 and isinstance(latest.trajectory, Hold)
    latest.add_state((0.2, 0.2, 0.3), (0.0, 0.0, 0.0), 1.001)
    np.testing.assert_array_equal(latest.take(1.0015, clock)[0][2][0], [0.1, 0.2, 0.3])  # still the first
    latest.hold("cancel")  # a cancel holds where the arm is now
    np.testing.assert_array_equal(latest.take(1.0016, clock)[0][2][0], [0.2, 0.2, 0.3])
    latest.activate()  # re-activation: the first state from then on
    assert latest.take(1.002, clock) == (None, "")
    latest.add_state((0.3, 0.2, 0.3), (0.0, 0.0, 0.0), 1.003)
    np.testing.assert_array_equal(latest.take(1.0035, clock)[0][2][0], [0.3, 0.2, 0.3])
    # a trajectory is sampled at the clock's time, the time the command is computed
    ref = reference([point([0.2, 0.2, 0.3], 1.0)], now=5.0)
    latest.drive(ref)
    np.testing.assert_allclose(latest.take(1.004, lambda: 5.5)[0][2][0], ref.sample(5.5)[0])


def test_joint_map_by_name() -> None:
    m = JointMap(NAMES, ["joint3", "joint1", "joint2"])
    robot = np.array([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(m.to_user(robot), [3.0, 1.0, 2.0])
    np.testing.assert_array_equal(m.to_robot(m.to_user(robot)), robot)
    assert JointMap(NAMES, list(NAMES)).identity
    with pytest.raises(ConfigError, match=r"'wrist' is not a joint of the robot; its actuated joints are \['joint1'"):
        JointMap(NAMES, ["joint1", "joint2", "wrist"])
    with pytest.raises(ConfigError, match="distinct"):
        JointMap(NAMES, ["joint1", "joint1", "joint2"])
