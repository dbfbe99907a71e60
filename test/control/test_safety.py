"""The plant's watchdog and the controller's staleness check as core state machines (no processes)."""

from __future__ import annotations

import pytest

from pdsmc_ros.controller.commanding import Staleness
from pdsmc_ros.sim.safe_mode import Watchdog

RATE = 1000.0


def lockstep_watchdog(time_scale: float = 1.0) -> Watchdog:
    return Watchdog(rate=RATE, timeout_s=0.5, periods=10, time_scale=time_scale)


def test_not_armed_until_a_controller_answers() -> None:
    watch = lockstep_watchdog()
    assert not watch.lost_in_lockstep(100.0)  # start-up may take any time
    assert watch.safe_steps_owed(100.0) == 0
    watch.effort(100.0)
    assert not watch.lost_in_lockstep(100.4)
    assert watch.lost_in_lockstep(100.6)


def test_lockstep_safe_mode_keeps_wall_clock_pace_and_caps_a_stall() -> None:
    watch = lockstep_watchdog(time_scale=0.5)
    watch.effort(0.0)
    watch.enter(1.0)
    assert not watch.lost_in_lockstep(2.0)  # already lost: entered once
    assert watch.safe_steps_owed(1.01) == 5  # 10 ms x 0.5 x 1 kHz
    assert watch.safe_steps_owed(1.0125) == 1  # 1.25 steps owed: one now, a quarter kept
    assert watch.safe_steps_owed(1.014) == 1  # 0.25 + 0.75
    # a 10 s stall catches up at most 0.1 s of wall time (plus the step in hand)
    assert watch.safe_steps_owed(11.014) == int(0.1 * 0.5 * RATE + 1.0)


def test_frozen_safe_mode_takes_no_step() -> None:
    watch = lockstep_watchdog(time_scale=0.0)
    watch.effort(0.0)
    watch.enter(1.0)
    assert watch.safe_steps_owed(5.0) == 0


def test_a_controller_back_is_offered_the_state_once_and_resumes() -> None:
    watch = lockstep_watchdog()
    assert not watch.offer_resume()  # not in safe mode: an out-of-order effort is just rejected
    watch.effort(0.0)
    watch.enter(1.0)
    assert watch.offer_resume() and not watch.offer_resume()
    assert watch.safe_steps_owed(2.0) == 0  # waiting for it: no stepping alone
    assert watch.effort(2.1)  # the in-order effort ends safe mode
    assert not watch.safe and not watch.effort(2.2)
    assert not watch.lost_in_lockstep(2.6) and watch.lost_in_lockstep(2.8)


def test_real_time_loss_after_the_given_periods_and_recovery() -> None:
    watch = Watchdog(rate=RATE, timeout_s=0.5, periods=3, time_scale=1.0)
    watch.effort(0.0)
    assert [watch.lost_in_period() for _ in range(4)] == [False, False, False, True]
    watch.enter(0.004)
    assert not watch.lost_in_period()  # lost once
    assert watch.effort(0.005) and not watch.safe
    assert not watch.lost_in_period()


@pytest.mark.parametrize("computed_reference", [False, True])
def test_staleness_reports_each_change_once(computed_reference: bool) -> None:
    check = Staleness(0.02)
    ref = None if computed_reference else 0.0
    assert check.update(0.01, 0.0, ref) == "" and not check.stale
    assert check.update(0.03, 0.0, ref) == "stale" and check.stale
    assert check.update(0.04, 0.0, ref) == ""  # reported once
    assert check.update(0.05, 0.045, None if computed_reference else 0.045) == "fresh"
    assert not check.stale


def test_an_old_reference_alone_is_stale() -> None:
    check = Staleness(0.02)
    assert check.update(1.0, 0.99, 0.5) == "stale"
    assert check.update(1.0, 0.99, None) == "fresh"  # a locally computed reference is never old


def test_lockstep_pairing_pairs_by_step_and_drops_skipped_references() -> None:
    from pdsmc_ros.controller.commanding import LockstepPairing

    pairing = LockstepPairing(rate=100.0, last_step=10)
    for step in range(6):  # the trajectory sends references ahead: nothing to pair yet
        assert pairing.add_reference(step, (step,)) is None  # type: ignore[arg-type]
    assert pairing.add_state(0, "q0", "qd0") == (0, "q0", "qd0", (0,))  # type: ignore[arg-type]
    assert pairing.take() is None  # no new state
    # states 1 and 2 never came (the plant stepped alone): their references are dropped
    assert pairing.add_state(3, "q3", "qd3") == (3, "q3", "qd3", (3,))  # type: ignore[arg-type]
    assert sorted(pairing.refs) == [4, 5] and pairing.next_step == 4
    assert pairing.add_reference(2, (2,)) is None  # type: ignore[arg-type]  # too late: ignored
    assert sorted(pairing.refs) == [4, 5]
    assert pairing.add_state(7, "q7", "qd7") is None  # type: ignore[arg-type]  # its reference is not in yet
    assert pairing.add_reference(7, (7,)) == (7, "q7", "qd7", (7,))  # type: ignore[arg-type]
    assert not pairing.refs and not pairing.finished
    assert pairing.add_state(10, "q", "qd") is None  # type: ignore[arg-type]
    assert pairing.add_reference(10, (10,)) is not None and pairing.finished  # type: ignore[arg-type]
    assert pairing.step_of(0, 50_000_000) == 5 and pairing.step_of(-1, 0) is None


def test_lockstep_pairing_takes_a_window_sent_again_from_before_the_first_reference_it_received() -> None:
    """A controller whose reference reader matched the trajectory in the middle of its first window
    (steps 3.. arrived, 0-2 were sent before): the window sent again when the plant offers its
    first state again pairs step 0 (before, the references before the first received were dropped
    as too late, and the run waited for step 0's effort until it timed out)."""
    from pdsmc_ros.controller.commanding import LockstepPairing

    pairing = LockstepPairing(rate=100.0, last_step=10)
    for step in range(3, 6):
        assert pairing.add_reference(step, (step,)) is None  # type: ignore[arg-type]
    assert pairing.add_state(0, "q0", "qd0") is None  # type: ignore[arg-type]  # its reference never came
    assert pairing.add_reference(0, (0,)) == (0, "q0", "qd0", (0,))  # type: ignore[arg-type]  # sent again
    for step in (1, 2, 3):  # the rest of the window sent again: kept once, in step order
        assert pairing.add_reference(step, (step,)) is None  # type: ignore[arg-type]
    assert pairing.add_state(1, "q1", "qd1") == (1, "q1", "qd1", (1,))  # type: ignore[arg-type]
    assert pairing.add_reference(0, (0,)) is None  # type: ignore[arg-type]  # paired already: too late
    assert sorted(pairing.refs) == [2, 3, 4, 5]


def test_tick_timing_periods_are_between_tick_starts_and_misses_count() -> None:
    from pdsmc_ros.loop.statistics import LoopStatistics

    stats = LoopStatistics(period=0.001, warm_up=1)
    first = stats.start(0.0)
    assert stats.row(first, 0.0)[1] == 0.0 and stats.missed_total == 0  # no tick before the first
    second = stats.start(0.002)  # two periods late: a missed deadline
    row = stats.row(second, 0.002)
    assert row[1] == second - first and row[3] == 0.002 and row[4] == 1.0
    assert len(row) == LoopStatistics.ROW_FIELDS
    assert stats.missed == 1 and stats.ticks == 1  # one object: the same miss in the statistics


def test_missed_ticks_are_counted_once_from_the_first_and_reported_after_the_warm_up() -> None:
    from pdsmc_ros.loop.statistics import LoopStatistics

    stats = LoopStatistics(period=0.001, warm_up=3)
    for k, lateness in enumerate((0.005, 0.0, 0.0, 0.002, 0.0, 0.0015)):  # misses at ticks 0, 3 and 5
        stats.record(k * 0.001, lateness, k * 0.001 + 1e-4)
    assert stats.missed_total == 3  # the timing rows' "missed so far": every tick
    assert stats.missed == 2 and stats.ticks == 3  # /diagnostics: after the three warm-up ticks
    assert stats.values()["missed"] == "2"
