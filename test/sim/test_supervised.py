"""The plant under supervision (the plant node's decisions) without processes."""

from __future__ import annotations

import numpy as np

from pdsmc_ros.robots import Serial3R, make_robot
from pdsmc_ros.sim import PlantStepper
from pdsmc_ros.sim.safe_mode import SafetyConfig, Watchdog
from pdsmc_ros.sim.supervised import FIRST_STATE_RESEND_S, MAX_CATCH_UP, SupervisedPlant

RATE = 1000.0
Q0 = np.array([0.3, 0.5, -0.4])


class Recorder:
    def __init__(self) -> None:
        self.states: list[int] = []
        self.reports: list[tuple[str, str]] = []


def plant(*, lockstep: bool = True, on_loss: str = "resume", last_step: int = 50) -> tuple[SupervisedPlant, Recorder]:
    seen = Recorder()
    stepper = PlantStepper(Serial3R(), 1.0 / RATE, Q0, np.zeros(3))
    supervised = SupervisedPlant(
        stepper, last_step=last_step, watchdog=Watchdog(rate=RATE, timeout_s=0.5, periods=5, time_scale=1.0),
        safety=SafetyConfig(mode="hold", on_loss=on_loss), lockstep=lockstep,
        publish_state=lambda: seen.states.append(stepper.steps),
        report=lambda level, text: seen.reports.append((level, text)))
    return supervised, seen


def test_lockstep_steps_once_per_effort_of_the_current_step() -> None:
    p, seen = plant()
    p.started = True
    p.effort(0, (1.0, 2.0, 3.0), 0.0)
    assert p.step == 1 and seen.states == [1] and np.array_equal(p.applied, [1.0, 2.0, 3.0])
    p.effort(5, (1.0, 2.0, 3.0), 0.0)  # not this step's
    p.effort(1, (1.0, float("nan"), 3.0), 0.0)
    p.effort(1, (1.0, 2.0), 0.0)
    assert p.step == 1 and p.rejected == 3
    assert p.rejected_reasons == {"out of order": 1, "non-finite value": 1, "wrong length 2": 1}
    assert [level for level, _ in seen.reports] == ["warn"] * 3


def test_the_effort_of_the_last_step_closes_the_run() -> None:
    p, _ = plant(last_step=2)
    for step in range(2):
        p.effort(step, (0.0, 0.0, 0.0), 0.0)
    assert not p.done
    p.effort(2, (0.0, 0.0, 0.0), 0.0)
    assert p.done and p.step == 2


def test_a_lost_controller_gives_safe_steps_at_wall_clock_pace_then_resumes() -> None:
    p, seen = plant()
    p.started = True
    p.effort(0, (0.0, 0.0, 0.0), 0.0)
    p.check_watchdog(0.4)
    assert p.safe_mode == "off"
    p.check_watchdog(0.6)  # 0.6 s without an effort > 0.5 s
    assert p.safe_mode == "hold" and seen.reports[-1][0] == "error"
    before = p.step
    p.check_watchdog(0.61)  # 10 ms at 1 kHz
    assert p.step == before + 10
    assert np.any(p.applied != 0.0)  # the hold torque, not the last (zero) effort
    p.effort(3, (0.0, 0.0, 0.0), 0.62)  # a controller is back with an old step: offered the state
    assert seen.states[-1] == p.step and p.rejected == 1
    p.check_watchdog(0.7)
    assert p.step == before + 10  # no stepping alone while the state is offered
    p.effort(p.step, (0.0, 0.0, 0.0), 0.71)
    assert p.safe_mode == "off" and seen.reports[-1][0] == "info"


def test_on_loss_end_ends_the_run() -> None:
    p, _ = plant(on_loss="end")
    p.started = True
    p.effort(0, (0.0, 0.0, 0.0), 0.0)
    p.check_watchdog(1.0)
    assert p.done


def test_real_time_starts_armed_and_listened_to_and_catches_up_late_ticks() -> None:
    p, seen = plant(lockstep=False, last_step=10_000)
    p.tick(0.0, lambda: True, 0.0)
    assert not p.started and p.step == 0  # no controller yet: held
    p.effort(0, (0.5, 0.5, 0.5), 0.0)
    p.tick(0.0, lambda: False, 0.0)
    assert not p.started  # the recorder is not listening yet
    p.tick(0.0, lambda: True, 0.0)
    assert p.started
    p.tick(0.0, lambda: True, 0.0)
    assert p.step == 1 and np.array_equal(p.applied, [0.5, 0.5, 0.5])
    p.tick(1e6, lambda: True, 0.0)  # a stall: catches up at most MAX_CATCH_UP periods
    assert p.step <= 2 + MAX_CATCH_UP
    assert len(seen.states) == p.step + 3


def test_real_time_loss_after_the_watchdog_periods_applies_the_safe_torque() -> None:
    p, _ = plant(lockstep=False, last_step=10_000)
    p.effort(0, (0.0, 0.0, 0.0), 0.0)
    p.started = True
    for _ in range(5):
        p.tick(0.0, lambda: True, 0.0)
    assert p.safe_mode == "off"
    p.tick(0.0, lambda: True, 0.0)
    assert p.safe_mode == "hold"


def test_plant_stepper_state_assigned_between_steps_is_the_state_stepped() -> None:
    stepper = PlantStepper(Serial3R(), 1.0 / RATE, Q0, np.zeros(3))
    stepper.q, stepper.qd = np.array([0.1, 0.2, 0.3]), np.array([0.5, 0.0, -0.5])
    fresh = PlantStepper(Serial3R(), 1.0 / RATE, [0.1, 0.2, 0.3], [0.5, 0.0, -0.5])
    stepper.step(np.ones(3))
    fresh.step(np.ones(3))
    assert np.array_equal(stepper.state, fresh.state) and np.array_equal(stepper.q, fresh.q)


def test_lockstep_sends_the_first_state_again_until_a_controller_answers() -> None:
    """A subscriber counted as matched may miss the first state (asymmetric discovery)."""
    p, seen = plant()
    p.check_watchdog(10.0)
    assert seen.states == []  # not started: nothing goes out
    p.start(100.0)
    assert seen.states == [0]
    p.check_watchdog(100.0 + FIRST_STATE_RESEND_S / 2)
    assert seen.states == [0]
    p.check_watchdog(100.0 + FIRST_STATE_RESEND_S)
    p.check_watchdog(100.0 + 1.5 * FIRST_STATE_RESEND_S)
    p.check_watchdog(100.0 + 2 * FIRST_STATE_RESEND_S)
    assert seen.states == [0, 0, 0]
    p.effort(1, (0.0, 0.0, 0.0), 100.0)  # a rogue's command does not count as an answer
    p.check_watchdog(100.0 + 3 * FIRST_STATE_RESEND_S)
    assert seen.states == [0, 0, 0, 0] and p.rejected == 1
    p.effort(0, (0.0, 0.0, 0.0), 101.0)
    assert seen.states == [0, 0, 0, 0, 1]
    p.check_watchdog(101.0 + 0.1)  # answered: no more resends, the watchdog is armed
    assert seen.states == [0, 0, 0, 0, 1] and p.safe_mode == "off"
    p.check_watchdog(101.0 + 0.6)
    assert p.safe_mode == "hold"


def limited_plant(*, lockstep: bool, limit: bool) -> tuple[SupervisedPlant, Recorder]:
    seen = Recorder()
    robot = Serial3R()
    stepper = PlantStepper(robot, 1.0 / RATE, Q0, np.zeros(3))
    supervised = SupervisedPlant(
        stepper, last_step=5000, watchdog=Watchdog(rate=RATE, timeout_s=0.5, periods=5, time_scale=1.0),
        safety=SafetyConfig(), lockstep=lockstep, publish_state=lambda: seen.states.append(stepper.steps),
        report=lambda level, text: seen.reports.append((level, text)),
        limit=robot.effort_limits if limit else None)
    return supervised, seen


def test_the_plant_saturates_at_the_effort_limits() -> None:
    p, _ = limited_plant(lockstep=True, limit=True)
    p.started = True
    p.effort(0, (1.0e3, -1.0e3, 5.0), 0.0)
    limit = make_robot("serial_3r").effort_limits  # config/robots.yaml's serial_3r limits
    assert p.applied.tolist() == [limit[0], -limit[1], 5.0]
    assert not p.failure


def test_lockstep_divergence_ends_the_run_and_integrates_no_more() -> None:
    p, seen = limited_plant(lockstep=True, limit=False)
    p.started = True
    step = 0
    while not p.done and step < 4000:  # far past the limits (none applied): the arm spins up
        p.effort(step, (300.0, -300.0, 100.0), 0.0)
        step += 1
    assert p.done and p.failure.startswith("diverged at t = ")
    assert "beyond 10 x its velocity limit" in p.failure
    errors = [text for level, text in seen.reports if level == "error"]
    assert errors == [f"the arm {p.failure}; the plant stops (nothing more is integrated)"]
    warnings = [text for level, text in seen.reports if level == "warn"]
    assert 1 <= len(warnings) <= 3 and all("beyond its velocity limit" in w for w in warnings)  # once a joint
    stopped = p.step
    p.effort(stopped, (0.0, 0.0, 0.0), 0.0)
    assert p.step == stopped and seen.states[-1] == stopped  # the diverged state went out, nothing after


def test_real_time_divergence_publishes_the_diverged_state_once() -> None:
    p, seen = limited_plant(lockstep=False, limit=False)
    p.effort(0, (1.0e6, 1.0e6, 1.0e6), 0.0)
    p.tick(0.0, lambda: True, 0.0)  # starts
    for _ in range(100):
        if p.done:
            break
        p.tick(0.0, lambda: True, 0.0)
    assert p.done and p.failure and seen.states[-1] == seen.states[-2] + 1 == p.step
