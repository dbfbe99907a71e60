"""Overrun accounting of a ticking node's loop, as ros2_control's controller manager keeps it:
the one place a missed deadline is defined (:func:`missed`) and counted (:class:`LoopStatistics`).

ros2_control's controller manager counts the periods its update loop overran ("Overrun
detected! The controller manager missed its desired rate") and keeps statistics of the
loop's periodicity and execution time. :class:`LoopStatistics` keeps the same for one of
our real-time loops: ticks, periods missed (a tick later than a whole period), how late
the ticks were, the worst (longest) period between two ticks, the longest tick and the
loop thread's minor page faults after warm-up. One object per loop feeds everything that
reports it: the serve loop records each tick in it and publishes :meth:`LoopStatistics.values`
once a second on ``/diagnostics`` (status ``<node>: loop statistics``,
:mod:`pdsmc_ros.bag.loop_statistics`), so the bag records them; the controller writes its
:meth:`LoopStatistics.row` per tick on ``/pdsmc/controller_timing``; ``pdsmc rt-check``
(:mod:`.rt_check`) records its ticks in one too.
"""

from __future__ import annotations

import time
from typing import Any


def missed(lateness: Any, period: float) -> Any:
    """Whether a tick ``lateness`` s after its deadline missed it: it started more than a whole
    period late (the deadline passed and the next one too: ros2_control's overrun). Elementwise
    on an array of latenesses."""
    return lateness > period


class LoopStatistics:
    """Counters of one loop at one ``period`` (seconds); cheap enough to run at every tick.

    A tick is *missed* when it starts more than one period after its deadline (the
    deadline passed and the next one too: ros2_control's overrun); ``late`` is how long
    after its deadline a tick started; the *period* is the time between two tick starts.
    Every tick is counted in :attr:`missed_total` (from the first: the timing rows' "missed so
    far"); the statistics count from the end of the first ``warm_up`` ticks (start-up:
    discovery, the nodes waiting for each other, kernels loaded), :attr:`missed` among them;
    ``seen`` counts every tick.
    """

    ROW_FIELDS = 5
    """:meth:`row`'s length."""

    def __init__(self, period: float, *, warm_up: int = 1000) -> None:
        self.period = period
        self.warm_up = warm_up
        self.seen = 0
        self.ticks = 0
        self.missed_total = 0  # every missed tick, from the first
        self.missed_at_warm_up = 0  # those among the warm-up ticks
        self.late_sum = 0.0
        self.late_max = 0.0
        self.period_worst = 0.0
        self.tick_max = 0.0
        self.faults_at_warm_up: int | None = None
        self.faults = 0
        self.collections = 0
        self.last_start: float | None = None  # the latest tick's start (``perf_counter``)
        self.achieved = 0.0  # the latest tick's start minus the one before (0 for the first)

    @property
    def missed(self) -> int:
        """Ticks missed after the warm-up."""
        return self.missed_total - self.missed_at_warm_up

    def start(self, lateness: float, start: float | None = None) -> float:
        """A tick starts ``lateness`` s after its deadline, at ``start`` (``perf_counter``; now
        if None); returns its start."""
        if start is None:
            start = time.perf_counter()
        self.seen += 1
        self.missed_total += missed(lateness, self.period)
        last, self.last_start = self.last_start, start
        self.achieved = 0.0 if last is None else start - last
        if self.seen <= self.warm_up:
            self.missed_at_warm_up = self.missed_total
            return start
        self.ticks += 1
        self.late_sum += lateness
        if lateness > self.late_max:
            self.late_max = lateness
        if self.achieved > self.period_worst:
            self.period_worst = self.achieved
        return start

    def end(self, start: float, end: float) -> None:
        """The tick that started at ``start`` ended at ``end``."""
        if self.seen > self.warm_up and end - start > self.tick_max:
            self.tick_max = end - start

    def record(self, start: float, lateness: float, end: float) -> None:
        """A whole tick: started at ``start`` (``lateness`` s after its deadline), ended at ``end``."""
        self.end(self.start(lateness, start), end)

    def row(self, start: float, lateness: float) -> list[float]:
        """The controller's timing row of the tick started at ``start``, at its end: ``[wall time,
        achieved period, compute time, lateness, missed so far]`` (``/pdsmc/controller_timing``)."""
        return [time.time(), self.achieved, time.perf_counter() - start, lateness, float(self.missed_total)]

    def page_faults(self, total: int) -> None:
        """The loop thread's minor-fault count now; counted from the end of the warm-up."""
        if self.faults_at_warm_up is None:
            if self.seen >= self.warm_up:
                self.faults_at_warm_up = total
            return
        self.faults = total - self.faults_at_warm_up

    def values(self) -> dict[str, str]:
        """The key-values of the ``/diagnostics`` status (strings, as ``KeyValue`` holds them)."""
        ticks = max(self.ticks, 1)
        return {
            "ticks": str(self.ticks),
            "missed": str(self.missed),
            "missed_pct": f"{100.0 * self.missed / ticks:.4f}",
            "late_mean_us": f"{1e6 * self.late_sum / ticks:.1f}",
            "late_max_us": f"{1e6 * self.late_max:.1f}",
            "period_worst_us": f"{1e6 * self.period_worst:.1f}",
            "tick_max_us": f"{1e6 * self.tick_max:.1f}",
            "minor_faults": str(self.faults) if self.faults_at_warm_up is not None else "warming up",
            "collections": str(self.collections),
        }
