"""The controller's output limits without ROS (issue 37): the soft limits applied after every law,
the runaway guard (a goal aborted, a stop latched until the next activation), holds that do not
creep, and an input outage that ends in a hold where the arm is."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pdsmc_ros.bag.cdr import encode_joint_state
from pdsmc_ros.control import ControlLaw
from pdsmc_ros.control.soft_limits import robot_soft_limits
from pdsmc_ros.controller import goals as g
from pdsmc_ros.controller.commanding import RunawayGuard, TorqueGuard
from pdsmc_ros.controller.core import CONTINUITY_TOLERANCE, ControllerCore
from pdsmc_ros.controller.joints import JointSelector
from pdsmc_ros.controller.limits import JointLimits
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.parameters.joint_map import JointMap
from pdsmc_ros.runs.builder import make_run

SPEC = make_run("serial_3r", "circle", "pd", rate=1000.0)
ROBOT = SPEC.robot_model()
NAMES = tuple(ROBOT.joint_names)
N = len(NAMES)
ZERO = np.zeros(N)


def runaway_guard(stop: str = "damp") -> RunawayGuard:
    return RunawayGuard(NAMES, ROBOT.position_limits, ROBOT.velocity_limits, ROBOT.effort_limits,
                        inertia=lambda q: np.diag(ROBOT.mass_matrix(q)), period=1.0 / SPEC.rate, stop=stop)


def core(runaway: RunawayGuard | None = None, holds: list[str] | None = None) -> ControllerCore:
    start = SPEC.reference().sample([0.0]).q[0]
    made = ControllerCore(SPEC, JointSelector(NAMES), JointMap(NAMES, list(NAMES)), JointLimits.of(ROBOT, NAMES),
                          TorqueGuard(robot_soft_limits(ROBOT, start, SPEC.rate)), 0.02, False,
                          (holds if holds is not None else []).append, runaway=runaway)
    made.configure()
    made.activate()
    return made


def state(q: np.ndarray, qd: np.ndarray) -> bytes:
    return encode_joint_state(1, 0, list(NAMES), q.tolist(), qd.tolist(), [])


def test_the_guard_trips_on_a_joint_beyond_its_velocity_limit_and_stays_latched() -> None:
    guard = runaway_guard()
    limit = ROBOT.velocity_limits
    assert guard.trip(ZERO, 1.2 * limit, 0.5) == ""  # within 1.25 x
    fast = np.array([0.0, 1.3 * limit[1], 0.0])
    why = guard.trip(ZERO, fast, 0.5)
    assert why.startswith("runaway stop at t = 0.5 s: joint 'joint2' rate") and "1.25 x its velocity limit" in why
    assert guard.trip(ZERO, fast, 0.6) == "" and guard.reason == why  # latched, reported once
    tau = guard.torque(fast)
    assert tau[1] < 0.0 and abs(tau[1]) <= ROBOT.effort_limits[1] and tau[0] == tau[2] == 0.0
    guard.reset()
    assert guard.reason == ""


def test_the_damp_stop_is_bounded_by_the_inertia_and_zero_gives_no_torque() -> None:
    guard = runaway_guard()
    guard.trip(ZERO, np.array([0.0, 0.0, 100.0]), 0.0)
    inertia = np.diag(ROBOT.mass_matrix(ZERO))
    assert np.all(guard.damping <= 0.25 * inertia * SPEC.rate + 1e-9)
    zero = runaway_guard("zero")
    zero.trip(ZERO, np.array([0.0, 0.0, 100.0]), 0.0)
    assert zero.torque(np.ones(N)).tolist() == [0.0] * N
    with pytest.raises(InvalidInputError, match="runaway.stop"):
        runaway_guard("brake")


def test_a_non_finite_state_trips_the_guard() -> None:
    assert "not finite" in runaway_guard().trip(np.array([np.nan, 0.0, 0.0]), ZERO, 1.0)


def test_the_guards_take_a_message_s_tuples() -> None:
    """The joint selector hands the loop tuples of floats: both guards take them as arrays."""
    assert runaway_guard().trip((0.0, 0.0, 0.0), (0.0, 0.0, 99.0), 0.0).startswith("runaway stop")
    guard = core().guard
    tau = np.array([0.0, 1e9, 0.0])
    guard.limit(tau, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert tau[1] == ROBOT.effort_limits[1]


def test_a_runaway_aborts_the_active_goal_and_commands_the_stop_until_activation() -> None:
    guard = runaway_guard()
    ctl = core(guard)
    q = SPEC.reference().sample([0.0]).q[0]
    ctl.add_state(state(q, ZERO), "joint_states")
    points = [((q + 0.1).tolist(), [0.0] * N, [0.0] * N, 2, 0)]
    execution = ctl.check_goal(0.0, NAMES, points, [0] * len(points), 0.0, [], [], 0.0).goal
    assert isinstance(execution, g.GoalExecution)
    ctl.start_goal(execution)
    fast = np.array([0.0, 0.0, 2.0 * ROBOT.velocity_limits[2]])
    tau = ctl.command(0.1, q, fast, (q, ZERO, ZERO))
    assert execution.outcome is not None and execution.outcome.error_code == g.PATH_TOLERANCE_VIOLATED
    assert execution.outcome.error_string.startswith("runaway stop")
    assert tau is not None and tau[2] < 0.0
    # latched: calm states still get the stop, whatever drives; no new goal is taken
    assert ctl.command(0.2, q, ZERO, (q + 1.0, ZERO, ZERO)).tolist() == [0.0] * N
    refused = ctl.check_goal(0.0, NAMES, points, [0] * len(points), 0.3, [], [], 0.0).goal
    assert isinstance(refused, g.Outcome) and "runaway stop is latched" in refused.error_string
    ctl.activate()
    assert np.any(ctl.command(0.3, q, ZERO, (q + 1.0, ZERO, ZERO)) != 0.0)


def test_the_soft_limits_cut_the_law_and_are_counted() -> None:
    ctl = core()
    q = SPEC.reference().sample([0.0]).q[0]
    fast = np.array([0.0, 0.95 * ROBOT.velocity_limits[1], 0.0])
    far = (q + [0.0, 20.0, 0.0], ZERO, ZERO)  # the law pushes on
    free = ControlLaw.from_spec(SPEC).torque(q, fast, *far)
    tau = ctl.command(0.0, q, fast, far)
    assert free[1] > 0.0 and tau[1] < 0.0  # above the soft velocity limit a push onward becomes braking
    k_velocity = ctl.guard.table[5, 1]
    assert tau[1] == pytest.approx(-k_velocity * 0.05 * ROBOT.velocity_limits[1])  # 5 % above the soft limit
    assert ctl.guard.clamped == 1 and ctl.guard.joint_saturated.tolist() == [0, 0, 0]  # not at the effort limit
    assert ctl.limit_note.startswith("torque limited by the soft limits")


def test_repeated_holds_keep_the_commanded_position() -> None:
    """A law with a steady-state error: the arm sits below what it is told. Holding the measured
    position every time would lower the hold by that error each time; the hold keeps the
    commanded position while the arm is within the continuity tolerance of it."""
    holds: list[str] = []
    ctl = core(holds=holds)
    q_cmd = SPEC.reference().sample([0.0]).q[0]
    sag = np.array([0.0, -0.01, 0.0])  # the law's steady-state error under gravity
    for _ in range(200):
        ctl.add_state(state(q_cmd + sag, ZERO), "joint_states")
        ctl.command(0.0, q_cmd + sag, ZERO, (q_cmd, ZERO, ZERO))
        ctl.hold("goal canceled")
        q_cmd = ctl.latest.trajectory.sample(0.0)[0]
    np.testing.assert_allclose(q_cmd, SPEC.reference().sample([0.0]).q[0], rtol=0, atol=1e-12)
    # an arm far from what it was told (it could not follow) is held where it is
    far = q_cmd + [0.0, -2 * CONTINUITY_TOLERANCE, 0.0]
    ctl.add_state(state(far, ZERO), "joint_states")
    ctl.hold("path tolerance violated")
    np.testing.assert_array_equal(ctl.latest.trajectory.sample(0.0)[0], far)


def test_after_an_outage_the_controller_holds_where_the_arm_is() -> None:
    ctl = core()
    q = SPEC.reference().sample([0.0]).q[0]
    clock = time.perf_counter
    ctl.add_state(state(q, ZERO), "joint_states")
    points = [((q + 0.5).tolist(), [0.0] * N, [0.0] * N, 1, 0)]
    execution = ctl.check_goal(0.0, NAMES, points, [0] * len(points), 0.0, [], [], 0.0).goal
    assert isinstance(execution, g.GoalExecution)
    ctl.start_goal(execution)
    tau, _ = ctl.realtime_command(clock(), lambda: 0.1)
    assert tau is not None
    tau, change = ctl.realtime_command(clock() + 1.0, lambda: 1.1)  # no state for 1 s: stale
    assert change == "stale" and tau is None
    assert isinstance(execution, g.GoalExecution) and execution.outcome is not None
    moved = q + 0.3  # where the arm is when states come back (it fell, it was pushed)
    ctl.add_state(state(moved, ZERO), "joint_states")
    tau, change = ctl.realtime_command(clock(), lambda: 5.0)  # the old goal would be at its end by now
    assert change == "fresh"
    np.testing.assert_array_equal(ctl.latest.trajectory.sample(5.0)[0], moved)


def test_a_goal_that_arrives_while_the_inputs_are_stale_does_not_succeed_unfollowed() -> None:
    """A goal started during an outage: the hold taken when the inputs are fresh again replaces its
    trajectory (the arm is where it is), so the goal ends aborted then, not SUCCEEDED at its end time
    with the arm never having followed it (seen on the UR5 bench arm with a starved machine)."""
    ctl = core()
    q = SPEC.reference().sample([0.0]).q[0]
    clock = time.perf_counter
    ctl.add_state(state(q, ZERO), "joint_states")
    tau, _ = ctl.realtime_command(clock(), lambda: 0.1)
    assert tau is not None
    tau, change = ctl.realtime_command(clock() + 1.0, lambda: 1.1)  # no state for 1 s: stale
    assert change == "stale" and tau is None
    points = [((q + 0.5).tolist(), [0.0] * N, [0.0] * N, 1, 0)]
    execution = ctl.check_goal(1.1, NAMES, points, [0] * len(points), 0.0, [], [], 0.0).goal
    assert isinstance(execution, g.GoalExecution)
    ctl.start_goal(execution)  # accepted while no state comes
    ctl.add_state(state(q, ZERO), "joint_states")
    tau, change = ctl.realtime_command(clock(), lambda: 1.2)
    assert change == "fresh"
    np.testing.assert_array_equal(ctl.latest.trajectory.sample(5.0)[0], q)  # held where the arm is
    assert execution.outcome is not None and execution.outcome.status == "aborted", execution.outcome
