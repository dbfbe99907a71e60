"""The serve loop: one or several nodes in a process, lockstep or paced in real time."""

from __future__ import annotations

import dataclasses
import math
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import (
    InvalidParameterTypeException,
    ParameterException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy_impl

from ..errors import InvalidInputError, PdsmcError
from ..runtime.realtime import Collector, restore
from . import intra
from .group import NodeGroup
from .io import (
    Inputs,
    pending,
    take_all,
    take_batches,
    take_local,
    take_local_batches,
)
from .lifecycle import (
    DRAIN_TIMEOUT_S,
    EXIT_BAD_INPUT,
    EXIT_FAILURE,
    EXIT_OK,
    arm_teardown_watch,
)
from .overrides import check_overrides, warn_unknown_arguments
from .params import BUSY_WAIT_S
from .realtime_params import LoopReport, apply_settings, due_reports, loop_reports


def run_node(
    name: str,
    factory: Callable[[], Any],
    args: Sequence[str] | None,
) -> int:
    """``main()`` body shared by the nodes (ros2/demos style).

    ``factory`` builds the node after ``rclpy.init``; a ConfigError or
    InvalidInputError while building it is one line on stderr and exit 2.
    The node object must offer ``node`` (the rclpy Node), ``done`` and
    ``exit_code`` attributes and may define ``close()``, ``period`` and ``tick()``.
    """
    return run_nodes(name, [factory], args)


def run_nodes(
    name: str,
    factories: Sequence[Callable[[], Any]],
    args: Sequence[str] | None,
    *,
    intra_process: bool = False,
) -> int:
    """Run one or several node wrappers in this process with one executor.

    Several wrappers make the composed mode (the nodes stay separate rclpy
    nodes, as in a component container). They are closed in reverse order of
    creation, so a recorder created first is closed last. ``intra_process``
    hands the loop's messages between them without DDS (:mod:`.intra`).
    """
    rclpy.init(args=args)
    wrappers: list[Any] = []
    reports: list[LoopReport] = []  # the real-time settings and loop statistics of each loop node
    executor: SingleThreadedExecutor | None = None
    domain = intra.IntraProcess(rclpy.get_default_context()) if intra_process else None
    code = EXIT_OK
    # our handlers from the start: a signal arriving while rclpy builds a node or the executor
    # would otherwise interrupt its __init__ (and rclpy's __del__ of the half-built object
    # prints a traceback); it is noted here and ends the loop as soon as the loop starts
    signalled = _SignalNote()
    _install_signal_handlers(signalled)
    try:
        try:
            intra.activate(domain)
            for factory in factories:
                wrappers.append(factory())
                reports += loop_reports(wrappers[-1])
            check_overrides([w.node for w in wrappers], args)  # undeclared -p: a warning; params files: errors
            if domain is not None:
                domain.bind()
        except (InvalidInputError, ParameterException, InvalidParameterTypeException, ValueError,
                TypeError) as exc:
            warn_unknown_arguments(name, args)
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            code = EXIT_BAD_INPUT  # also what the teardown watch is armed with
            return code
        except PdsmcError as exc:
            warn_unknown_arguments(name, args)
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            code = EXIT_FAILURE
            return code
        finally:
            intra.activate(None)
        group = NodeGroup(wrappers, reports)
        period = group.period
        # The loop's messages go through a hand-driven wait set (Inputs), the rest through
        # the executor between them. Real-time nodes are paced by the loop, not by rclpy
        # timers (they fired 35x too often under this wheel's EventsExecutor and wake
        # late under the default one).
        executor = SingleThreadedExecutor()
        for wrapper in wrappers:
            executor.add_node(wrapper.node)
        if signalled.stopped_by_signal:
            group.done, group.stopped_by_signal = True, signalled.stopped_by_signal
        _install_signal_handlers(group)
        with_inputs = [inputs for w in wrappers for inputs in _inputs_of(w)]
        # the loop's own inputs are taken at every pass; observers' (composed or alone) in batches
        loop_inputs = [item for inputs in with_inputs if not inputs.batch_s for item in inputs.hot]
        observed = [item for inputs in with_inputs if inputs.batch_s for item in inputs.hot]
        observe_every = min((inputs.batch_s for inputs in with_inputs if inputs.batch_s), default=0.0)
        local = _LocalInputs(
            [item for inputs in with_inputs if not inputs.batch_s for item in inputs.local],
            [item for inputs in with_inputs if inputs.batch_s for item in inputs.local],
            None if domain is None else domain.guard)
        _serve_loop(executor, group, loop_inputs, period, observed, observe_every, local,
                    busy_wait=group.busy_wait, reports=reports)
        code = group.exit_code
        if not group.stopped_by_signal:
            _drain(executor, wrappers)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = max((getattr(w, "exit_code", EXIT_OK) for w in wrappers), default=EXIT_OK)
    finally:
        for wrapper in reversed(wrappers):
            close = getattr(wrapper, "close", None)
            if close is not None:
                close()
        arm_teardown_watch(code)
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)  # before the nodes go (rclpy's order)
        for wrapper in reversed(wrappers):
            for inputs in _inputs_of(wrapper):
                inputs.destroy()
            wrapper.node.destroy_node()
        if domain is not None:
            domain.destroy()
        rclpy.try_shutdown()
    return code


def _inputs_of(wrapper: Any) -> list[Inputs]:
    """A wrapper's ``inputs`` and, if it has them, its ``observed_inputs`` (taken in batches)."""
    return [inputs for inputs in (getattr(wrapper, "inputs", None), getattr(wrapper, "observed_inputs", None))
            if inputs is not None]


@dataclasses.dataclass(frozen=True)
class _LocalInputs:
    """Inputs on the intra-process path (queues filled by publishers of this process)."""

    hot: Sequence[tuple[deque, Callable[[bytes], None]]] = ()
    observed: Sequence[tuple[deque, Callable[[bytes], None]]] = ()
    guard: Any = None  # triggered when a message is queued from another thread


STATISTICS_EVERY_S = 1.0  # real time: loop statistics on /diagnostics this often
IDLE_MARGIN = 0.3  # real time: the young generation is collected only with this share of a period to spare
COLD_PERIOD_S = 0.02  # lockstep: the executor's turn (timers, parameters, /clock) this often
# (one turn costs 0.2-1 ms of Python; every 5 ms it took 15 % of the lockstep rate)
COLD_WAIT_S = 5.0  # real time: the executor thread's longest sleep (it is woken to stop)
GIL_SWITCH_S = 0.0001  # real time: longest the executor thread keeps the GIL from the loop
# real time, from the spin before a tick to its end: the loop keeps the GIL (another thread
# taking it there could hold it through a long C call, e.g. rclpy converting a message)
HOLD_SWITCH_S = 0.005


def _serve_loop(executor: SingleThreadedExecutor, group: Any,
                hot: Sequence[tuple[Any, Callable[[bytes], None]]], period: float | None,
                observed: Sequence[tuple[Any, Callable[[bytes], None]]] = (),
                observe_every: float = 0.0, local: _LocalInputs | None = None, *,
                busy_wait: float = BUSY_WAIT_S, reports: Sequence[LoopReport] = ()) -> None:
    """Take the loop's inputs with a wait set of their own; serve the rest beside them.

    Every ready input of ``hot`` is drained (``take_message`` until empty) and handed to
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
    local = local or _LocalInputs()
    local_hot, local_observed = list(local.hot), list(local.observed)
    any_observed = bool(observed or local_observed)
    guard = local.guard if period else None  # only the real-time executor thread publishes off the loop
    wait_set = _rclpy_impl.WaitSet(len(hot) + len(observed), 0 if guard is None else 1, 0, 0, 0, 0,
                                   executor.context.handle)
    inputs = [(sub.handle, sub.msg_type, handler) for sub, handler in hot]
    observer_inputs = [(sub.handle, sub.msg_type, handler) for sub, handler in observed]
    collector = Collector() if period else Collector(young_at=50_000)
    collector.start()
    switch_interval = sys.getswitchinterval()
    if period:
        # the executor thread (timers, the recorder's flush) must hand the GIL back to the loop
        # within a fraction of a period, not after CPython's default 5 ms
        sys.setswitchinterval(GIL_SWITCH_S)
    stop = threading.Event()
    cold_thread = None
    guard_node = group.wrappers[0].node
    wake_guard = None
    if period:
        # the executor thread sleeps until it has work (timers, services); a guard condition
        # of one of its nodes ends that sleep when the loop ends (Executor.wake() does not
        # interrupt spin_once here). Waking every 0.1 s instead cost ~0.5 ms under the GIL
        # ten times a second -- a late control period each time.
        wake_guard = guard_node.create_guard_condition(lambda: None)

        def spin_cold() -> None:
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=COLD_WAIT_S)

        cold_thread = threading.Thread(target=spin_cold, name="executor", daemon=True)
        cold_thread.start()
    # after the executor thread exists (scheduling is per thread); at FIFO, busy_wait may shrink
    applied, busy_wait = apply_settings(reports, guard_node, period, busy_wait)
    next_report = clock() + STATISTICS_EVERY_S
    unpublished: list[LoopReport] = []
    holding = False  # real time: the GIL kept through the spin and the tick (HOLD_SWITCH_S)
    try:
        next_cold = float("inf") if period else 0.0
        next_tick = clock() + period if period else float("inf")
        next_observe = 0.0
        ok = executor.context.ok  # checked at ticks and executor turns, not at every pass
        while not group.done:
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
                    continue  # no time to spare
                if unpublished:
                    unpublished.pop().publish()
                else:
                    collector.idle()
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
            wait_set.clear_entities()
            for handle, _, _ in waited:
                wait_set.add_subscription(handle)
            if guard is not None:
                wait_set.add_guard_condition(guard)
            wait_set.wait(int(sleep * 1e9))
    finally:
        restore(applied)
        for report in due_reports(reports, collector):
            report.publish()
        stop.set()
        if wake_guard is not None:  # real time: stop the executor thread
            wake_guard.trigger()  # end its wait now
            cold_thread.join(timeout=2.0)
            if cold_thread.is_alive():
                print("warning: the executor thread did not stop within 2 s", file=sys.stderr, flush=True)
            guard_node.destroy_guard_condition(wake_guard)
        sys.setswitchinterval(switch_interval)
        collector.stop()


def _drain(executor: Any, wrappers: Sequence[Any], timeout: float = DRAIN_TIMEOUT_S) -> None:
    """After the work is done: let subscribers acknowledge the last messages, then linger.

    A reliable sample lost on the way is repaired only after the writer's next
    heartbeat; a node that exits at once never repairs it (a real-time
    trajectory once missed the plant's last state this way). Waits at most
    ``timeout`` in all (a killed subscriber never acknowledges), then serves
    the executor briefly for what needs a callback (parameter events, acks).
    """
    end = time.perf_counter() + timeout
    for wrapper in wrappers:
        for publisher in wrapper.node.publishers:
            left = end - time.perf_counter()
            if left <= 0.0:
                break
            publisher.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
    end = time.perf_counter() + 0.1
    while rclpy.ok() and time.perf_counter() < end:
        executor.spin_once(timeout_sec=0.02)


class _SignalNote:
    """Where a signal that arrives before the node group exists is noted."""

    done = False
    stopped_by_signal: str | None = None


def _install_signal_handlers(wrapper: Any) -> None:
    """SIGINT/SIGTERM end the spin loop; the node's close() then runs."""

    def handler(signum: int, frame: object) -> None:  # noqa: ARG001
        wrapper.done = True
        wrapper.stopped_by_signal = signal.Signals(signum).name

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
