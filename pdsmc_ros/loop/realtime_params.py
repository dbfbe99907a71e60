"""The real-time parameters of a ticking node, named as ros2_control's.

``thread_priority`` (SCHED_FIFO priority of the loop's thread, 1-99; 0 = normal scheduling;
50 by default in ``mode:=realtime``, as the controller manager), ``cpu_affinity`` (cores the
loop's thread may run on; empty = any) and ``lock_memory`` (``mlockall`` of present and
future pages; on by default in real time). They are read once at start-up and read-only
while the loop runs; :mod:`pdsmc_ros.loop.realtime` applies them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rclpy.node import Node

from ..bag.loop_statistics import status_name
from ..errors import ConfigError
from ..parameters import realtime_parameters
from ..parameters.ros import declare
from ..parameters.tables import DEFAULT_PRIORITY
from ..ros.diagnostics import Diagnostics
from .realtime import (
    FIFO_BUSY_SHARE,
    Applied,
    Collector,
    RealtimeSettings,
    apply,
    busy_wait_for,
    minor_faults,
)
from .statistics import LoopStatistics


def declare_realtime_parameters(node: Node, mode: str, priority: int = DEFAULT_PRIORITY) -> RealtimeSettings:
    """Declare the three parameters on ``node`` (:func:`~pdsmc_ros.parameters.realtime_parameters`,
    read-only) with ``mode``'s defaults (``priority`` in real time); the validated settings, or a
    ConfigError naming the parameter and what it allows."""
    default = RealtimeSettings.for_mode(mode, priority)
    values = declare(node, realtime_parameters(priority), defaults={
        "thread_priority": default.thread_priority, "lock_memory": default.lock_memory})
    cores = values["cpu_affinity"]
    cores = [] if cores is None or list(cores) == [-1] else list(cores)
    try:
        return RealtimeSettings(values["thread_priority"], tuple(cores), values["lock_memory"]).validated()
    except ConfigError as exc:
        raise ConfigError(f"parameter {exc}") from None


class LoopReport:
    """A node's real-time settings and, if it ticks, its loop statistics on ``/diagnostics``.

    Built right after the node (while a composed process's intra-process routes are still
    being made, so a composed recorder receives the statistics too); the serve loop records
    every tick in ``stats`` and calls :meth:`publish` once a second and at the end.
    """

    def __init__(self, wrapper: Any, mode: str) -> None:
        node: Node = wrapper.node
        self.settings = declare_realtime_parameters(node, mode, getattr(wrapper, "realtime_priority", DEFAULT_PRIORITY))
        period = getattr(wrapper, "period", None)
        # a node that reads its loop's statistics in its tick (the controller's timing rows) owns them
        self.stats: LoopStatistics | None = getattr(wrapper, "loop_statistics", None)
        if self.stats is None and period:
            self.stats = LoopStatistics(period)
        self.diagnostics = None if self.stats is None else Diagnostics(
            node, status_name(node.get_name()), "pdsmc_ros/loop", values=self.stats.values)

    def publish(self) -> None:
        if self.stats is None or self.diagnostics is None or not self.stats.ticks:
            return
        missed = self.stats.missed
        self.diagnostics.publish("warn" if missed else "info",
                                 f"{missed} of {self.stats.ticks} periods missed")


def loop_reports(wrapper: Any) -> list[LoopReport]:
    """``[LoopReport]`` for a node of the control loop (it has a ``mode``: real-time defaults
    in real time) or an observer that may be pinned (``observer = True``, the recorder:
    normal scheduling by default, e.g. ``cpu_affinity`` away from the loop's core); else none."""
    if hasattr(wrapper, "mode"):
        return [LoopReport(wrapper, wrapper.mode)]
    return [LoopReport(wrapper, "lockstep")] if getattr(wrapper, "observer", False) else []


def apply_settings(reports: Sequence[LoopReport], node: Node, period: float | None,
                   busy_wait: float) -> tuple[Applied, float]:
    """Apply the loop nodes' settings (merged: one thread ticks them all) to the calling
    thread; one info line of what holds and, if the system refused something, one warning.
    Returns what was applied and the busy-wait to use: ``busy_wait`` as
    :func:`~pdsmc_ros.loop.realtime.busy_wait_for` settles it once the scheduling is known
    (a thread at SCHED_FIFO wakes on time and spins less, leaving the cores to the other loop
    processes). A given value cut to its share of the period at FIFO is said in a line.
    """
    settings = RealtimeSettings.merged([r.settings for r in reports])
    applied = apply(settings)
    logger = node.get_logger()
    if applied.warning:
        logger.warn(applied.warning)
    requested = busy_wait
    loops = sum(r.stats is not None for r in reports)
    busy_wait = busy_wait_for(requested, fifo=applied.fifo, loops=loops, period=period)
    if 0.0 <= requested != busy_wait:
        logger.info(f"busy_wait {requested:g} s at SCHED_FIFO: spinning at most {FIFO_BUSY_SHARE:g} of each period")
    # real time: this line says the loop runs (run_experiment.sh waits for it)
    if settings != RealtimeSettings() or period:
        spin = f", busy-wait {1e6 * busy_wait:g} us before each tick" if period else ""
        logger.info(applied.summary() + spin)
    return applied, busy_wait


def due_reports(reports: Sequence[LoopReport], collector: Collector) -> list[LoopReport]:
    """The reports with loop statistics, brought up to date (the loop thread's page faults and
    collections): the loop publishes one after each tick with time to spare (about 0.1 ms each)."""
    due = [r for r in reports if r.stats is not None]
    faults = minor_faults() if due else 0
    for r in due:
        if r.stats is not None:
            r.stats.page_faults(faults)
            r.stats.collections = collector.collections
    return due
