"""The serve loop of a process: its nodes' loop inputs taken with a wait set of their own,
lockstep or paced in real time, the executor served beside them.

Real time: :func:`serve_loop` keeps the schedule (each tick's deadline, and how late it
starts); :class:`NodeGroup` ticks the process's nodes as one and records each tick in the node's
loop statistics (:class:`~pdsmc_ros.loop.statistics.LoopStatistics`, which counts the missed
deadlines).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.executors import SingleThreadedExecutor

from .. import rclpy_internals as _rclpy_impl
from ..parameters.tables import AUTO_BUSY_WAIT
from .executor_thread import ExecutorThread
from .inputs import pending, take_all, take_batches, take_local, take_local_batches
from .log import loop_running
from .realtime import Collector, raise_helpers, restore
from .realtime_params import LoopReport, apply_settings, due_reports


@dataclasses.dataclass(frozen=True)
class LocalInputs:
    """Inputs on the intra-process path (queues filled by publishers of this process)."""

    hot: Sequence[tuple[deque, Callable[[bytes], None]]] = ()
    observed: Sequence[tuple[deque, Callable[[bytes], None]]] = ()
    guard: Any = None  # triggered when a message is queued from another thread


STATISTICS_EVERY_S = 1.0  # real time: loop statistics on /diagnostics this often
# real time at FIFO: threads started since the loop began (rclpy's multi-threaded executors start their
# workers at their first callback) are raised below the loop this often, as those that existed then
HELPERS_EVERY_S = 1.0
# real time: spare-time work (the young generation, a window ahead) only with this share of a period to spare
IDLE_MARGIN = 0.2
# real time: a loop with no time to spare still runs its nodes' spare-time work (the action's feedback,
# ~/controller_state) after a tick once it has gone this long without: under a busy CPU every tick may be
# late, and a goal's client would otherwise get no feedback for the whole goal (JTC: 20 Hz)
IDLE_STARVED_S = 0.25
COLD_PERIOD_S = 0.02  # lockstep: the executor's turn (timers, parameters, /clock) this often
# (one turn costs 0.2-1 ms of Python; every 5 ms it took 15 % of the lockstep rate)
GIL_SWITCH_S = 0.0001  # real time: longest the executor thread keeps the GIL from the loop
# real time, from the spin before a tick to its end: the loop keeps the GIL (another thread
# taking it there could hold it through a long C call, e.g. rclpy converting a message). It is
# also how long the loop waits for the GIL back once it released it there (a contended lock, a
# system call): 5 ms made each such release a tick up to 5 ms late while another thread ran
# (a goal validated, a log line written). 1 ms still covers the spin and a tick (~0.3 ms here).
HOLD_SWITCH_S = 0.001


def serve_loop(executor: SingleThreadedExecutor, group: Any,
                hot: Sequence[tuple[Any, Callable[[bytes], None]]], period: float | None,
                observed: Sequence[tuple[Any, Callable[[bytes], None]]] = (),
                observe_every: float = 0.0, local: LocalInputs | None = None, *,
                busy_wait: float = AUTO_BUSY_WAIT, reports: Sequence[LoopReport] = ()) -> None:
    """Take the loop's inputs with a wait set of their own; serve the rest beside them.

    Every ready input of ``hot`` is drained (taken until empty) and handed to
    its handler at every pass. Lockstep: every ``COLD_PERIOD_S`` the executor gets one
    non-blocking turn (timers, parameters, ``/clock``). Real time (a ``period``): the
    executor spins in a thread of its own (one of its turns took about 1 ms) and
    ``group.tick(lateness)`` runs on a wall-clock schedule: the loop sleeps in the wait
    set until ``busy_wait`` before the deadline and spins the rest (at normal priority a
    wake-up is late by tens of microseconds, on this VM now and then by milliseconds).
    Late ticks run at once (no catch-up beyond one period). The garbage collector is
    kept off the path, its young generation collected now and then (real time: right
    after a tick with time to spare). ``reports``: the nodes' real-time settings (applied
    to this thread once the executor thread exists) and loop statistics (published every
    ``STATISTICS_EVERY_S`` right after a tick, and at the end).

    ``observed`` are the inputs of observers (see :class:`Inputs`): once they
    have given messages, they are left alone for ``observe_every`` seconds, so
    their messages are taken in batches -- whether the observer runs alone or
    composed with the loop's nodes, whose inputs are still taken at every pass.
    ``local`` are the inputs on the intra-process path (composed
    ``--intra-process``), taken from their queues the same way; their guard
    condition wakes the loop when the real-time executor thread queues a message.
    """
    clock = time.perf_counter
    local = local or LocalInputs()
    local_hot, local_observed = list(local.hot), list(local.observed)
    any_observed = bool(observed or local_observed)
    guard = local.guard if period else None  # only the real-time executor thread publishes off the loop
    wait_set = _rclpy_impl.SubscriptionWaitSet(len(hot) + len(observed), 0 if guard is None else 1, executor.context)
    inputs = [(sub.handle, _rclpy_impl.take_raw(sub), handler) for sub, handler in hot]
    observer_inputs = [(sub.handle, _rclpy_impl.take_raw(sub), handler) for sub, handler in observed]
    hot_handles = [handle for handle, _, _ in inputs]
    every_handle = hot_handles + [handle for handle, _, _ in observer_inputs]
    collector = Collector() if period else Collector(young_at=50_000)
    collector.start()
    switch_interval = sys.getswitchinterval()
    if period:
        # the executor thread (timers, the recorder's flush) must hand the GIL back to the loop
        # within a fraction of a period, not after CPython's default 5 ms
        sys.setswitchinterval(GIL_SWITCH_S)
    first = group.wrappers[0].node  # holds the executor thread's wake-up; logs the settings
    # real time: timers and services in a thread of their own (one executor turn took about 1 ms)
    cold_thread = ExecutorThread(executor, first) if period else None
    # after the executor thread exists (scheduling is per thread); at FIFO, busy_wait may shrink
    applied, busy_wait = apply_settings(reports, first, period, busy_wait)
    next_report = next_helpers = clock() + STATISTICS_EVERY_S
    unpublished: list[LoopReport] = []
    loop_running(True)  # the nodes' loop log lines: written by the executor from now on
    holding = False  # real time: the GIL kept through the spin and the tick (HOLD_SWITCH_S)
    started = False  # real time: the first tick has run
    last_idle = clock()  # real time: when the nodes' spare-time work last ran
    try:
        next_cold = float("inf") if period else 0.0
        next_tick = clock() + period if period else float("inf")
        next_observe = 0.0
        ok = executor.context.ok  # checked at ticks and executor turns, not at every pass
        while not group.done:
            taken = clock()  # when this pass took the loop's inputs
            took = take_all(inputs)
            if local_hot and take_local(local_hot):
                took = True
            now = clock()
            if any_observed and now >= next_observe:
                # real time: a batch must not delay the next tick; what is left waits for the
                # pass after it (next_observe unchanged)
                until = next_tick - busy_wait if period else math.inf
                observed_any = take_batches(observer_inputs, until)
                if take_local_batches(local_observed, until) or observed_any:
                    took = True
                    if clock() < until:
                        next_observe = now + observe_every
            if took and group.done:
                return
            now = clock()
            if now >= next_tick:
                if not ok():
                    return
                if not started:  # the schedule starts at the first tick: the passes before it are
                    started, next_tick = True, now  # start-up (a backlog, first calls), not late periods
                if period and now - taken > period:
                    # this thread stalled since it took the inputs (the GIL held elsewhere, the CPU
                    # taken): newer ones wait in the queues. Taken again, a stall of the loop is a late
                    # tick, not an outage of its inputs (which would end the active goal)
                    take_all(inputs)
                    if local_hot:
                        take_local(local_hot)
                group.tick(now - next_tick)
                if holding:
                    sys.setswitchinterval(GIL_SWITCH_S)
                    holding = False
                next_tick += period
                if now - next_tick > period:  # more than a period behind: resynchronise
                    next_tick = now + period
                now = clock()
                if now >= next_report:  # once a second: one node's statistics after each tick
                    unpublished = due_reports(reports, collector)
                    next_report = now + STATISTICS_EVERY_S
                if next_tick - now <= busy_wait + IDLE_MARGIN * period:
                    if now - last_idle < IDLE_STARVED_S:
                        continue  # no time to spare
                    last_idle = now  # starved: once now, with a period of its own (this tick is late anyway)
                    for idle in group.idlers:
                        idle(now + period)
                    continue
                if unpublished:
                    unpublished.pop().publish()
                elif applied.helpers and now >= next_helpers:
                    # a thread at normal priority holding the GIL is preempted by the machine's load
                    # for milliseconds while the loop waits (the action server's validating workers)
                    applied.helpers += raise_helpers()
                    next_helpers = now + HELPERS_EVERY_S
                else:
                    collector.idle()
                    last_idle = now
                    for idle in group.idlers:  # e.g. a state topic at 20 Hz: not in another thread,
                        idle(next_tick - busy_wait)  # whose message conversion would hold the GIL
                continue
            if now >= next_cold:
                if not ok():
                    return
                executor.spin_once(timeout_sec=0.0)
                next_cold = now + COLD_PERIOD_S
                continue
            if not period:
                collector.idle()
            if took:
                continue
            due = min(next_cold, next_tick - busy_wait, now + 0.1)
            observing = now >= next_observe
            if not observing:
                due = min(due, next_observe)
            sleep = due - now
            if sleep <= 0.0:
                if period and not holding:
                    sys.setswitchinterval(HOLD_SWITCH_S)
                    holding = True
                continue  # busy-wait for the tick
            if pending(local_hot) or (observing and pending(local_observed)):
                continue
            waited = inputs + observer_inputs if observing else inputs
            if not waited and guard is None:
                if cold_thread is None and not any_observed:
                    executor.spin_once(timeout_sec=sleep)  # a node without inputs
                else:
                    time.sleep(sleep)
                continue
            wait_set.wait(every_handle if observing else hot_handles, int(sleep * 1e9), guard)
    finally:
        restore(applied)
        for report in due_reports(reports, collector):
            report.publish()
        if cold_thread is not None:
            cold_thread.stop()
        loop_running(False)
        sys.setswitchinterval(switch_interval)
        collector.stop()


class NodeGroup:
    """Several node wrappers seen as one: done when all are, failed if any is."""

    def __init__(self, wrappers: Sequence[Any], reports: Sequence[LoopReport] = ()) -> None:
        self.wrappers = list(wrappers)
        stats = {id(r.diagnostics.node): r.stats for r in reports if r.diagnostics is not None}
        # the ticking nodes, each with its loop statistics (None: not a loop node)
        self.ticking = [(w, stats.get(id(w.node))) for w in self.wrappers if getattr(w, "period", None)]
        # real time: work a node does off its tick, in the loop's spare time (``idle(until)``)
        self.idlers = [w.idle for w in self.wrappers if callable(getattr(w, "idle", None))]
        self.stopped_by_signal: str | None = None
        periods = {getattr(w, "period", None) for w in self.wrappers} - {None}
        self.period = min(periods) if periods else None
        # the largest spin a ticking node was given, else automatic (every one left at -1)
        self.busy_wait = max((getattr(w, "busy_wait", AUTO_BUSY_WAIT) for w in self.wrappers
                              if getattr(w, "period", None)), default=AUTO_BUSY_WAIT)
        # real time, composed: the plant's node stays in the graph after its run, so the
        # nodes that watch for it to leave are told when it is done
        self.state_sources = [w for w in self.wrappers if getattr(w, "publishes_states", False)]
        self.watchers = [w.plant_watch for w in self.wrappers if getattr(w, "plant_watch", None)]

    @property
    def done(self) -> bool:
        for w in self.wrappers:  # noqa: SIM110 (checked at every pass of the loop: no generator)
            if not w.done:
                return False
        return True

    @done.setter
    def done(self, value: bool) -> None:  # set by the signal handler
        for w in self.wrappers:
            w.done = value

    @property
    def exit_code(self) -> int:
        return max(w.exit_code for w in self.wrappers)

    def tick(self, lateness: float) -> None:
        clock = time.perf_counter
        deadline = clock() - lateness
        for w, stats in self.ticking:
            if not w.done:
                if stats is None:
                    w.tick(lateness)
                    continue
                start = clock()  # ros2_control's overrun accounting, per node
                stats.start(start - deadline, start)
                w.tick(lateness)
                stats.end(start, clock())
        if self.watchers and self.state_sources and all(w.done for w in self.state_sources):
            for watch in self.watchers:
                if not watch.gone:
                    watch.gone = True
                    watch.on_gone()
