"""joint_trajectory_controller's goal rules, ROS-free: ``validate_trajectory_msg`` in JTC's order
(``test_trajectory_controller.cpp``: invalid_message, test_partial_joint_list(_not_allowed),
expect_invalid_when_message_with_nonzero_end_velocity_and_when_param_false), tolerances
(``tolerances.hpp``, ``test_tolerances.cpp``), cmd_timeout, wrap-around, steps and the size limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pdsmc_ros.controller import goals as g
from pdsmc_ros.controller.joint_trajectory import (
    MAX_POINTS,
    JointTrajectoryReference,
    TrajectoryRules,
    check_trajectory,
)
from pdsmc_ros.controller.limits import JointLimits

JOINTS = ("joint1", "joint2", "joint3")
Q0 = np.array([1.1, 2.1, 3.1])  # JTC's INITIAL_POS_JOINTS
ZERO = np.zeros(3)


def pt(q: list[float], at: float, v: list[float] | None = None, a: list[float] | None = None) -> tuple:
    return (q, v or [], a or [], int(at // 1), int(round((at % 1.0) * 1e9)))


GOOD = [pt([1.0, 2.0, 3.0], 0.25)]


def check(points: list, names: tuple = JOINTS, *, stamp: float = 0.0, now: float = 100.0,
          rules: TrajectoryRules | None = None, efforts: tuple = ()) -> str:
    return check_trajectory(rules or TrajectoryRules(), JOINTS, stamp, names, points, now, efforts)


@pytest.mark.parametrize(("points", "names", "stamp", "efforts", "needle"), [
    (GOOD, ("joint1", "joint2"), 0.0, (), "don't match the controller joints"),  # partial not allowed
    (GOOD, (), 0.0, (), "don't match"),  # no names: the count check comes first, as JTC's
    ([], JOINTS, 0.0, (), "Empty trajectory received"),
    ([pt([1.0, 2.0, 3.0], 0.25)], ("joint1", "joint2", "wrist"), 0.0, (), "incoming joint 'wrist' doesn't match"),
    ([pt([1.0, 2.0, 3.0], 0.25, [-1.0, -2.0, -3.0])], JOINTS, 0.0, (), "velocity of the last trajectory point"),
    (GOOD, JOINTS, 1e-9, (), "before it was received"),  # End time in the past
    ([pt([1.0, 2.0, 3.0], 0.25), pt([1.0, 2.0, 3.0], 0.25)], JOINTS, 0.0, (), "is not after point 0's"),
    ([pt([1.0, 2.0], 0.25)], JOINTS, 0.0, (), "has 2 positions for 3 joint_names"),
    ([pt([1.0, 2.0, 3.0, 4.0], 0.25)], JOINTS, 0.0, (), "has 4 positions"),
    ([pt([], 0.25)], JOINTS, 0.0, (), "has 0 positions"),  # no positions (allow_integration is not supported)
    ([pt([1.0, 2.0, 3.0], 0.25, [0.0, 0.0])], JOINTS, 0.0, (), "2 velocities"),
    ([pt([1.0, 2.0, 3.0], 0.25, None, [1.0, 2.0])], JOINTS, 0.0, (), "2 accelerations"),
    (GOOD, JOINTS, 0.0, (3,), "effort field"),
    ([pt([1.0, 2.0, 3.0], 0.25)], ("joint1", "joint1", "joint2"), 0.0, (), "repeats a joint"),  # beyond JTC
])
def test_jtc_invalid_message(points, names, stamp, efforts, needle) -> None:  # noqa: ANN001
    assert needle in check(points, names, stamp=stamp, efforts=efforts)


def test_jtc_valid_messages() -> None:
    assert check(GOOD) == ""
    # End time in the future
    assert check([pt([1.0, 2.0, 3.0], 10.0)], stamp=100.0) == ""
    # jumbled joint order (test_jumbled_joint_order)
    assert check([pt([1.0, 2.0, 3.0], 0.25)], ("joint3", "joint1", "joint2")) == ""


def test_jtc_order_of_checks() -> None:
    """The first failing check in validate_trajectory_msg's order is the one reported."""
    # unknown joint and nonzero last velocity: the joint first
    both = [pt([1.0, 2.0, 3.0], 0.25, [1.0, 1.0, 1.0])]
    assert "wrist" in check(both, ("joint1", "joint2", "wrist"))
    # point 0's sizes before point 1's backwards time
    assert "positions" in check([pt([1.0], 1.0), pt([1.0, 2.0, 3.0], 0.5)])
    # point 0's backwards time (none) then point 1's time before its sizes
    assert "not after" in check([pt([1.0, 2.0, 3.0], 1.0), pt([1.0], 0.5)])
    # too many points: before everything else
    assert f"at most {MAX_POINTS} points" in check([pt([1.0], 1.0)] * (MAX_POINTS + 1), ("x",))


def test_partial_joint_list_allowed_fills_the_missing_joints() -> None:
    """JTC test_partial_joint_list: missing joints keep their current position, zero velocity."""
    rules = TrajectoryRules(allow_partial_joints_goal=True, allow_nonzero_velocity_at_trajectory_end=True)
    points = [pt([2.0, 1.0], 0.25, [0.5, 0.5])]
    names = ("joint2", "joint1")
    assert check(points, names, rules=rules) == ""
    ref, problem = JointTrajectoryReference.from_checked(JOINTS, 0.0, names, points, 100.0, Q0, ZERO)
    assert problem == "" and ref is not None
    np.testing.assert_array_equal(ref.positions[0], [1.0, 2.0, Q0[2]])
    np.testing.assert_array_equal(ref.velocities[0], [0.5, 0.5, 0.0])
    assert "don't match" in check(points, names, rules=TrajectoryRules(allow_nonzero_velocity_at_trajectory_end=True))


def test_nonzero_velocity_at_the_end_allowed_and_held() -> None:
    rules = TrajectoryRules(allow_nonzero_velocity_at_trajectory_end=True)
    points = [pt([1.0, 2.0, 3.0], 0.25, [0.1, 0.0, 0.0])]
    assert check(points, rules=rules) == ""
    ref, _ = JointTrajectoryReference.from_message(_selector(), 0.0, JOINTS, points, 100.0, Q0, ZERO, rules)
    q, qd, qdd = ref.sample(200.0)  # past the end: JTC repeats the last point, velocity included
    np.testing.assert_array_equal(qd, [0.1, 0.0, 0.0]) and np.testing.assert_array_equal(qdd, ZERO)


def _selector():  # noqa: ANN202
    from pdsmc_ros.controller.joints import JointSelector

    return JointSelector(JOINTS)


def test_non_finite_values_are_refused_beyond_jtc() -> None:
    ref, problem = g.prepare_trajectory(g.GoalSettings(), None, JOINTS, 0.0, JOINTS, [pt([1.0, math.inf, 3.0], 1.0)],
                                        100.0, (Q0, ZERO))
    assert ref is None and "positions of joint 'joint2' is not finite" in problem


class Limits:
    position_limits = np.array([[-4.0, 4.0]] * 3)
    velocity_limits = np.array([2.0, 2.0, 2.0])


def test_a_step_is_refused_naming_joint_jump_and_time_unless_within_the_start_tolerance() -> None:
    """Issue 37 item 2: a first point at t = 0 (or a stamp in the past) away from the arm is a step."""
    limits = JointLimits.of(Limits(), JOINTS)
    settings = g.GoalSettings()
    step = [pt([1.1, 2.6, 3.1], 0.0), pt([1.1, 2.6, 3.1], 1.0)]
    ref, problem = g.prepare_trajectory(settings, limits, JOINTS, 0.0, JOINTS, step, 100.0, (Q0, ZERO))
    assert ref is None and "a step: joint 'joint2' would jump +0.5 rad at once" in problem
    assert "at its velocity limit 2 rad/s that takes 0.250 s" in problem
    # the same jump spread over 0.5 s is a segment within the velocity limit
    ramp = [pt([1.1, 2.6, 3.1], 0.5), pt([1.1, 2.6, 3.1], 1.0)]
    assert g.prepare_trajectory(settings, limits, JOINTS, 0.0, JOINTS, ramp, 100.0, (Q0, ZERO))[1] == ""
    # a stamp in the past puts the reference at receipt half-way along its first segment: a step too
    past = [pt([1.1, 2.1, 3.1], 0.0), pt([1.1, 3.1, 3.1], 1.0), pt([1.1, 3.1, 3.1], 2.0)]
    assert "a step" in g.prepare_trajectory(settings, limits, JOINTS, 99.5, JOINTS, past, 100.0, (Q0, ZERO))[1]
    # MoveIt-style: the first point at t = 0 at the current state within allowed_start_tolerance
    moveit = [pt([1.105, 2.1, 3.1], 0.0, [0.0] * 3), pt([1.3, 2.2, 3.0], 1.0, [0.0] * 3)]
    assert g.prepare_trajectory(settings, limits, JOINTS, 0.0, JOINTS, moveit, 100.0, (Q0, ZERO))[1] == ""
    tight = g.GoalSettings(start_tolerance=0.001)
    assert "a step" in g.prepare_trajectory(tight, limits, JOINTS, 0.0, JOINTS, moveit, 100.0, (Q0, ZERO))[1]
    # reject_beyond_limits false: accepted, as JTC accepts it
    off = g.GoalSettings(reject_beyond_limits=False)
    assert g.prepare_trajectory(off, limits, JOINTS, 0.0, JOINTS, step, 100.0, (Q0, ZERO))[0] is not None


def test_tolerance_semantics() -> None:
    """tolerances.hpp: 0 keeps the default, -1 erases it, an unknown joint or another negative value
    makes the whole goal use the defaults; acceleration values are checked for legality too."""
    defaults = g.Tolerances.defaults(3, stopped_velocity=0.1, goal_time=1.0, trajectory=[0.1, 0.1, 0.1],
                                     goal=[0.1, 0.1, 0.1])
    got, warning = g.resolve_tolerances(defaults, JOINTS, [("joint1", 0.2, 0.3, 0.4), ("joint2", 0.0, 0.0, 0.0)],
                                        [("joint3", -1.0, 2.3, 3.3)], 2.0)
    assert warning == "" and got.goal_time == 2.0
    np.testing.assert_array_equal(got.path_position, [0.2, 0.1, 0.1])
    np.testing.assert_array_equal(got.path_velocity, [0.3, 0.0, 0.0])
    np.testing.assert_array_equal(got.goal_position, [0.1, 0.1, 0.0])
    np.testing.assert_array_equal(got.goal_velocity, [0.1, 0.1, 2.3])
    for path, goal, goal_time in (([("wrist", 0.1, 0.0, 0.0)], [], 0.0), ([("joint1", -2.0, 0.0, 0.0)], [], 0.0),
                                  ([("joint1", 0.1, 0.0, -0.5)], [], 0.0), ([], [("joint1", 0.1, -3.0, 0.0)], 0.0),
                                  ([], [], -3.0)):
        kept, warning = g.resolve_tolerances(defaults, JOINTS, path, goal, goal_time)
        assert kept is defaults and "default tolerances used" in warning


def _reference(end: float = 1.0) -> JointTrajectoryReference:
    ref, _ = JointTrajectoryReference.from_checked(JOINTS, 0.0, JOINTS, [pt([1.2, 2.1, 3.1], end)], 100.0, Q0, ZERO)
    return ref


def test_cmd_timeout_holds_a_topic_trajectory_after_its_end() -> None:
    holds: list[str] = []
    slot = g.GoalSlot(lambda ref: None, holds.append)
    settings = g.GoalSettings(defaults=g.Tolerances.defaults(3, goal_time=0.5), cmd_timeout=0.3)
    assert settings.timeout() == 0.0  # JTC: cmd_timeout must exceed constraints.goal_time
    settings = g.GoalSettings(defaults=g.Tolerances.defaults(3), cmd_timeout=0.3)
    assert settings.timeout() == 0.3
    ref = _reference()
    assert not slot.follow(ref, settings.tolerances(3), JOINTS, settings.timeout())
    end = ref.sample(101.0)
    assert slot.check(101.2, end[0], ZERO, end) == (None, False)  # a topic trajectory never "succeeds"
    outcome, held = slot.check(101.31, end[0], ZERO, end)
    assert held and "command timeout" in outcome.error_string and holds


def test_a_topic_trajectory_breaching_the_default_path_tolerance_holds() -> None:
    holds: list[str] = []
    slot = g.GoalSlot(lambda ref: None, holds.append)
    defaults = g.Tolerances.defaults(3, trajectory=[0.05, 0.05, 0.05])
    slot.follow(_reference(), defaults, JOINTS, 0.0)
    desired = slot.active.reference.sample(100.5)
    outcome, held = slot.check(100.5, desired[0] + [0.0, 0.1, 0.0], desired[1], desired)
    assert held and outcome.error_code == g.PATH_TOLERANCE_VIOLATED and "'joint2'" in outcome.error_string


def test_cancel_answers_as_jtc_and_deactivation_aborts() -> None:
    slot = g.GoalSlot(lambda ref: None, lambda why: None)
    goal = g.GoalExecution(_reference(), g.Tolerances.defaults(3), JOINTS)
    slot.start(goal)
    assert slot.cancel(goal) and goal.outcome == g.Outcome("canceled", g.SUCCESSFUL, "")
    other = g.GoalExecution(_reference(), g.Tolerances.defaults(3), JOINTS)
    slot.start(other)
    assert slot.end("Current goal cancelled during deactivate transition.") is other
    assert other.outcome.error_code == g.INVALID_GOAL


def test_errors_of_continuous_joints_wrap() -> None:
    """JTC compute_error_for_joint: angles::shortest_angular_distance for continuous joints."""
    wrap = np.array([True, False, False])
    goal = g.GoalExecution(_reference(), g.Tolerances.defaults(3, trajectory=[0.1, 0.1, 0.1]), JOINTS, wrap=wrap)
    desired = (np.array([math.pi - 0.01, 0.0, 0.0]), ZERO, ZERO)
    q = np.array([-math.pi + 0.01, 0.0, 0.0])  # 0.02 rad away the short way round
    assert goal.update(100.1, q, ZERO, desired) is None
    np.testing.assert_allclose(goal.feedback.error[0], [-0.02, 0.0, 0.0], atol=1e-12)
    # the first segment starts within half a turn of the first point (wraparound_joint)
    ref, _ = JointTrajectoryReference.from_checked(JOINTS, 0.0, JOINTS, [pt([3.0, 0.0, 0.0], 1.0)], 100.0,
                                                   np.array([3.0 - 2 * math.pi, 0.0, 0.0]), ZERO, wrap=wrap)
    np.testing.assert_allclose(ref.start_q, [3.0, 0.0, 0.0])


def test_the_limit_check_of_all_segments_at_once_finds_the_first_violation_the_loop_finds() -> None:
    """The segments between points are checked in chunks of one kind; the first violation is the one
    a segment-by-segment check finds (random trajectories mixing linear, cubic and quintic segments)."""
    rng = np.random.default_rng(7)
    limits = JointLimits(JOINTS, np.array([[-1.0, 1.0]] * 3), np.array([2.0, 2.0, 2.0]))
    for trial in range(60):
        n = int(rng.integers(2, 700))
        points = []
        for k in range(n):
            q = list(rng.uniform(-0.95, 0.95, 3) * (1.0 if rng.random() < 0.995 else 1.2))
            kind = rng.integers(0, 3)
            v = list(rng.uniform(-1.0, 1.0, 3)) if kind else None
            a = list(rng.uniform(-5.0, 5.0, 3)) if kind == 2 else None
            points.append(pt(q, 0.6 * (k + 1), v if k < n - 1 else ([0.0] * 3 if v else None), a))
        ref, problem = JointTrajectoryReference.from_checked(JOINTS, 0.0, JOINTS, points, 0.0, np.zeros(3), ZERO)
        assert problem == ""
        loop = next((k for k in range(1, n) if limits._segment_problem(ref, k)), -1)
        assert limits._first_bad_segment(ref) == loop, trial
