"""The controller node's decisions without ROS (:class:`ControllerCore`): which state meets which
reference, holds, topic trajectories, action goals and the torque of the running law."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros.bag.cdr import encode_joint_state, encode_joint_trajectory
from pdsmc_ros.bag.stamps import step_stamp
from pdsmc_ros.control import ControlLaw
from pdsmc_ros.controller import goals as g
from pdsmc_ros.controller.commanding import TorqueGuard
from pdsmc_ros.controller.core import SOURCE_SKEW_S, ControllerCore
from pdsmc_ros.controller.joints import JointSelector
from pdsmc_ros.controller.limits import JointLimits
from pdsmc_ros.parameters.joint_map import JointMap
from pdsmc_ros.runs.builder import make_run

SPEC = make_run("serial_3r", "circle", "pdsmc")
ROBOT = SPEC.robot_model()
NAMES = tuple(ROBOT.joint_names)


def core(lockstep: bool, holds: list[str] | None = None) -> ControllerCore:
    made = ControllerCore(SPEC, JointSelector(NAMES), JointMap(NAMES, list(NAMES)), JointLimits.of(ROBOT, NAMES),
                          TorqueGuard(None), 20 / SPEC.rate, lockstep,
                          (holds if holds is not None else []).append)
    made.configure()
    made.activate()
    return made


def state(step: int, q: np.ndarray, qd: np.ndarray) -> bytes:
    return encode_joint_state(*step_stamp(step, SPEC.rate), list(NAMES), q.tolist(), qd.tolist(), [])


def reference(step: int, q: np.ndarray) -> bytes:
    zeros = [0.0] * len(q)
    return encode_joint_trajectory(*step_stamp(step, SPEC.rate), list(NAMES), q.tolist(), zeros, zeros)


def test_lockstep_pairs_a_state_with_the_reference_of_its_step_and_commands_the_law() -> None:
    ctl = core(lockstep=True)
    start = ctl.reference.sample([0.0])
    q, qd, q_ref = start.q[0] + 0.01, np.zeros(len(NAMES)), start.q[0]
    assert ctl.add_reference(reference(0, q_ref), "reference") == (None, "")  # ahead of its state
    paired, problem = ctl.add_state(state(0, q, qd), "joint_states")
    assert problem is None and paired is not None and paired[0] == 0
    step, q_in, qd_in, ref = paired
    tau = ctl.command(step / SPEC.rate, q_in, qd_in, ref)
    expected = ControlLaw.from_spec(SPEC).torque(q, qd, q_ref, np.zeros(len(NAMES)), np.zeros(len(NAMES)))
    np.testing.assert_allclose(tau, expected, rtol=0, atol=1e-12)
    assert ctl.snapshot is not None and ctl.snapshot[0] == 0.0 and ctl.states_received == 1
    assert ctl.sim_time() == 0.0


def test_lockstep_refuses_a_state_whose_stamp_names_no_step_naming_the_topic() -> None:
    ctl = core(lockstep=True)
    q = ctl.reference.sample([0.0]).q[0]
    data = encode_joint_state(10**8, 0, list(NAMES), q.tolist(), [0.0] * len(q), [])  # a wall-clock stamp
    paired, problem = ctl.add_state(data, "joint_states")
    assert paired is None and problem is not None
    assert problem.startswith("/joint_states stamp") and "not a lockstep step" in problem
    assert ctl.states_received == 0 and ctl.last_state is None


def test_realtime_holds_the_first_state_after_activation_through_the_law() -> None:
    holds: list[str] = []
    ctl = core(lockstep=False, holds=holds)
    q = ctl.reference.sample([0.0]).q[0] + 0.02
    qd = np.full(len(NAMES), 0.1)
    assert ctl.add_state(state(0, q, qd), "joint_states") == (None, None)
    tau, change = ctl.realtime_command(ctl.latest.state_time, lambda: 7.0)
    zero = np.zeros(len(NAMES))
    np.testing.assert_allclose(tau, ControlLaw.from_spec(SPEC).torque(q, qd, q, zero, zero), rtol=0, atol=1e-12)
    assert change == "" and ctl.snapshot is not None and ctl.snapshot[0] == 7.0
    assert holds == []  # the activation's hold is not a cancel's or an abort's: nothing to tell


def test_realtime_stale_inputs_command_nothing_and_a_broken_state_stops_the_output() -> None:
    ctl = core(lockstep=False)
    q = ctl.reference.sample([0.0]).q[0]
    ctl.add_state(state(0, q, np.zeros(len(NAMES))), "joint_states")
    tau, change = ctl.realtime_command(ctl.latest.state_time + 1.0, lambda: 0.0)  # 1 s: 1000 periods
    assert tau is None and change == "stale"
    paired, problem = ctl.add_state(b"\x00\x01", "joint_states")
    assert paired is None and problem is not None and "malformed joint_states" in problem
    assert ctl.latest.state is None  # no torque from the older state meanwhile


def test_an_aborted_goal_holds_the_measured_position_from_that_period_on() -> None:
    holds: list[str] = []
    ctl = core(lockstep=False, holds=holds)
    q0 = ctl.reference.sample([0.0]).q[0]
    qd0 = np.zeros(len(NAMES))
    ctl.add_state(state(0, q0, qd0), "joint_states")
    points = [((q0 + 0.1).tolist(), [], [], 2, 0)]
    path = [(name, 0.01, 0.0, 0.0) for name in NAMES]  # path tolerance 0.01 rad on every joint
    started = ctl.check_goal(0.0, NAMES, points, (), 100.0, path, [], 0.0)
    assert isinstance(started.goal, g.GoalExecution) and started.warning == ""
    assert ctl.goals.active is None  # validated on arrival, driving once accepted
    assert not ctl.start_goal(started.goal) and ctl.goals.active is started.goal
    far = q0 + 0.5  # far off the path: aborted in this period
    ref = started.goal.reference.sample(100.5)
    tau = ctl.command(100.5, far, qd0, ref)
    assert started.goal.outcome is not None and started.goal.outcome.error_code == g.PATH_TOLERANCE_VIOLATED
    assert len(holds) == 1 and ctl.goals.active is None
    np.testing.assert_array_equal(ctl.snapshot[3][0], q0)  # the hold: the latest measured state
    np.testing.assert_allclose(tau, ControlLaw.from_spec(SPEC).torque(far, qd0, q0, qd0, qd0), rtol=0, atol=1e-12)


def test_an_invalid_goal_is_refused_with_its_code_and_drives_nothing() -> None:
    ctl = core(lockstep=False)
    q0 = ctl.reference.sample([0.0]).q[0]
    points = [(q0.tolist(), [], [], 1, 0)]
    started = ctl.check_goal(0.0, NAMES, points, (), 100.0, [], [], 0.0)
    assert isinstance(started.goal, g.Outcome) and "no complete joint state" in started.goal.error_string
    assert ctl.goals.active is None and ctl.latest.source is None


@pytest.mark.parametrize(("sent", "received", "start"), [
    (99.5, 99.8, 99.5),  # the source time, when plausible
    (100.0 - SOURCE_SKEW_S - 1.0, 99.8, 99.8),  # a source clock too far off: the reception time
    (None, None, 100.0),  # neither: now
])
def test_a_zero_stamped_topic_trajectory_starts_when_it_was_sent(sent: float | None, received: float | None,
                                                                  start: float) -> None:
    ctl = core(lockstep=False)
    q0 = ctl.reference.sample([0.0]).q[0]
    ctl.add_state(state(0, q0, np.zeros(len(NAMES))), "joint_states")
    points = [((q0 + 0.01).tolist(), [], [], 0, 0)]  # at receipt, within allowed_start_tolerance: no step
    trajectory, problem, followed = ctl.topic_trajectory(0.0, NAMES, points, (), (sent, received), 100.0)
    assert problem == "" and trajectory is not None and not followed
    assert trajectory.start_time == start and ctl.latest.trajectory is trajectory


def test_a_gain_change_keeps_a_stateful_law_integrating() -> None:
    spec = make_run("serial_3r", "circle", "sta")
    ctl = ControllerCore(spec, JointSelector(NAMES), JointMap(NAMES, list(NAMES)), None, TorqueGuard(None),
                         20 / spec.rate, True, lambda why: None)
    ctl.configure()
    ctl.activate()
    assert ctl.law is not None
    ctl.law.state[:] = 0.25
    before = ctl.law
    ctl.apply_gains(spec)
    assert ctl.law is not before and np.all(ctl.law.state == 0.25)


@pytest.mark.parametrize(("stamp", "start"), [
    (0.0, 100.3),  # JTC's Trajectory::sample: stamped 0, the loop's first sample is its start
    (100.1, 100.0),  # stamped: its times count from the stamp (kept relative to receipt at 100.0)
])
def test_an_action_goal_stamped_zero_starts_at_the_loops_first_sample(stamp: float, start: float) -> None:
    ctl = core(lockstep=False)
    q0 = ctl.reference.sample([0.0]).q[0]
    ctl.add_state(state(0, q0, np.zeros(len(NAMES))), "joint_states")
    points = [((q0 + 0.1).tolist(), [], [], 2, 0)]
    started = ctl.check_goal(stamp, NAMES, points, (), 100.0, [], [], 0.0)
    assert isinstance(started.goal, g.GoalExecution)
    reference = started.goal.reference
    ctl.start_goal(started.goal)
    tau, _ = ctl.realtime_command(ctl.latest.state_time, lambda: 100.3)  # the loop takes it 0.3 s later
    assert tau is not None
    assert reference.start_time == start and reference.end_time == start + float(reference.times[-1])
    assert reference.end_time == pytest.approx(stamp + 2.0 if stamp else 102.3, abs=1e-12)
    ctl.realtime_command(ctl.latest.state_time, lambda: 100.4)  # later samples move it no more
    assert reference.start_time == start


def test_stop_brakes_each_joint_at_its_deceleration_as_jtcs_decelerate_to_hold_position() -> None:
    from pdsmc_ros.controller.hold import Stop

    q0, qd0, a = np.array([0.1, -0.2, 0.3]), np.array([0.8, -0.5, 0.0]), np.array([4.0, 1.0, 2.0])
    stop = Stop(q0, qd0, a, "goal canceled")
    stop.begin(10.0)
    stop.begin(10.5)  # only the first sample starts it
    # integrate the sampled velocity on a fine grid: it must land where the positions say (no formula reused)
    times = np.linspace(10.0, 11.0, 100_001)
    samples = [stop.sample(t) for t in times]
    positions = np.array([s[0] for s in samples])
    velocities = np.array([s[1] for s in samples])
    integrated = q0 + np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (velocities[1:] + velocities[:-1]), axis=0)
                                      * (times[1] - times[0])])
    np.testing.assert_allclose(positions, integrated, atol=1e-8)
    np.testing.assert_allclose(positions[0], q0) and np.testing.assert_allclose(velocities[0], qd0)
    # each joint at rest after |qd0| / a (0.2 s, 0.5 s), at q0 + sign(qd0) qd0^2 / (2 a); the resting one holds
    np.testing.assert_allclose(stop.sample(10.2)[1][0], 0.0, atol=1e-12)
    assert stop.sample(10.19)[1][0] > 0.0 and stop.sample(10.49)[1][1] < 0.0
    np.testing.assert_allclose(stop.sample(11.0)[0], [0.1 + 0.08, -0.2 - 0.125, 0.3])
    np.testing.assert_allclose(stop.sample(11.0)[1], 0.0)
    np.testing.assert_allclose(stop.sample(10.1)[2], [-4.0, 1.0, 0.0])  # braking; the resting joint: nothing
    with pytest.raises(ValueError, match="deceleration > 0 per joint"):
        Stop(q0, qd0, [4.0, 0.0, 2.0], "x")


def test_with_decelerate_on_cancel_a_canceled_goal_brakes_from_where_the_hold_would_start() -> None:
    from pdsmc_ros.controller.hold import Hold, Stop

    decel = np.array([2.0, 2.0, 2.0])
    holds: list[str] = []
    ctl = ControllerCore(SPEC, JointSelector(NAMES), JointMap(NAMES, list(NAMES)), JointLimits.of(ROBOT, NAMES),
                         TorqueGuard(None), 20 / SPEC.rate, False, holds.append,
                         goal_settings=g.GoalSettings(stop_deceleration=decel))
    ctl.configure()
    ctl.activate()
    q0 = ctl.reference.sample([0.0]).q[0]
    qd = np.array([0.4, -0.2, 0.0])
    ctl.add_state(state(0, q0, qd), "joint_states")
    started = ctl.check_goal(0.0, NAMES, [((q0 + 0.1).tolist(), [], [], 2, 0)], (), 100.0, [], [], 0.0)
    ctl.start_goal(started.goal)
    assert ctl.goals.cancel(started.goal) and holds == ["goal canceled"]
    source = ctl.latest.trajectory
    assert isinstance(source, Stop)  # nothing commanded yet: from the measured state
    np.testing.assert_allclose(source.q0, q0) and np.testing.assert_allclose(source.qd0, qd)
    np.testing.assert_allclose(source.q, q0 + np.sign(qd) * qd ** 2 / (2 * decel))
    # lockstep: the same stop, sampled at the steps' times from the first step after the cancel
    locked = ControllerCore(SPEC, JointSelector(NAMES), JointMap(NAMES, list(NAMES)), JointLimits.of(ROBOT, NAMES),
                            TorqueGuard(None), 20 / SPEC.rate, True, holds.append,
                            goal_settings=g.GoalSettings(stop_deceleration=decel))
    locked.configure()
    locked.activate()
    locked.add_state(state(0, q0, qd), "joint_states")
    started = locked.check_goal(0.0, NAMES, [((q0 + 0.1).tolist(), [], [], 2, 0)], (), 0.0, [], [], 0.0)
    locked.start_goal(started.goal)
    assert locked.goals.cancel(started.goal) and isinstance(locked.pairing.trajectory, Stop)
    paired, _ = locked.add_state(state(1, q0, qd), "joint_states")
    assert paired is not None
    np.testing.assert_allclose(paired[3][0], q0) and np.testing.assert_allclose(paired[3][1], qd)  # braking starts
    paired, _ = locked.add_state(state(1 + int(SPEC.rate), q0, qd), "joint_states")  # 1 s on: at rest
    np.testing.assert_allclose(paired[3][0], q0 + np.sign(qd) * qd ** 2 / (2 * decel))
    np.testing.assert_allclose(paired[3][1], 0.0)
    # without the setting the same cancel holds at once
    plain = core(lockstep=False)
    plain.add_state(state(0, q0, qd), "joint_states")
    started = plain.check_goal(0.0, NAMES, [((q0 + 0.1).tolist(), [], [], 2, 0)], (), 100.0, [], [], 0.0)
    plain.start_goal(started.goal)
    assert plain.goals.cancel(started.goal) and isinstance(plain.latest.trajectory, Hold)


def test_an_outage_before_a_deactivation_does_not_end_a_goal_after_the_next_activation() -> None:
    ctl = core(lockstep=False)
    q0 = ctl.reference.sample([0.0]).q[0]
    zero = np.zeros(len(NAMES))
    ctl.add_state(state(0, q0, zero), "joint_states")
    assert ctl.realtime_command(ctl.latest.state_time + 1.0, lambda: 0.0)[1] == "stale"
    ctl.activate()
    ctl.add_state(state(1, q0, zero), "joint_states")
    started = ctl.check_goal(0.0, NAMES, [((q0 + 0.1).tolist(), [], [], 2, 0)], (), 100.0, [], [], 0.0)
    ctl.start_goal(started.goal)
    tau, change = ctl.realtime_command(ctl.latest.state_time, lambda: 100.0)
    assert change == "" and tau is not None
    assert started.goal.outcome is None and ctl.goals.active is started.goal
