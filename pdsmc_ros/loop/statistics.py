"""Overrun accounting of a ticking node's loop, as ros2_control's controller manager keeps it:
the one place a missed deadline is defined (:func:`missed`) and counted.

ros2_control's controller manager counts the periods its update loop overran ("Overrun
detected! The controller manager missed its desired rate") and keeps statistics of the
loop's periodicity and execution time. :class:`LoopStatistics` keeps the same for one of
our real-time loops: ticks, periods missed (a tick later than a whole period), how late
the ticks were, the worst (longest) period between two ticks, the longest tick and the
loop thread's minor page faults after warm-up. The serve loop publishes
:meth:`LoopStatistics.values` once a second on ``/diagnostics`` (status
``<node>: loop statistics``, :mod:`pdsmc_ros.bag.loop_statistics`), so the bag records them.
:class:`TickTiming` is the controller's row per tick (``/pdsmc/controller_timing``), its
missed count from the first tick; ``pdsmc rt-check`` (:mod:`.rt_check`) counts its ticks'
misses by the same rule.
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
    Everything counts from the end of the first ``warm_up`` ticks (start-up: discovery,
    the nodes waiting for each other, kernels loaded); ``seen`` counts those too.
    """

    def __init__(self, period: float, *, warm_up: int = 1000) -> None:
        self.period = period
        self.warm_up = warm_up
        self.seen = 0
        self.ticks = 0
        self.missed = 0
        self.late_sum = 0.0
        self.late_max = 0.0
        self.period_worst = 0.0
        self.tick_max = 0.0
        self.faults_at_warm_up: int | None = None
        self.faults = 0
        self.collections = 0
        self._last_start: float | None = None

    def record(self, start: float, lateness: float, end: float) -> None:
        """A tick that started at ``start`` (``lateness`` s after its deadline), ended at ``end``."""
        self.seen += 1
        if self.seen <= self.warm_up:
            self._last_start = start
            return
        self.ticks += 1
        if missed(lateness, self.period):
            self.missed += 1
        self.late_sum += lateness
        if lateness > self.late_max:
            self.late_max = lateness
        if self._last_start is not None and start - self._last_start > self.period_worst:
            self.period_worst = start - self._last_start
        self._last_start = start
        if end - start > self.tick_max:
            self.tick_max = end - start

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


class TickTiming:
    """Real time: each tick's ``[wall time, achieved period, compute time, lateness, missed so far]``."""

    FIELDS = 5

    def __init__(self, period: float) -> None:
        self.period = period
        self.missed = 0
        self.last: float | None = None  # the start of the latest tick
        self.achieved = 0.0  # the latest tick's start minus the one before (0 for the first)

    def start(self, lateness: float) -> float:
        """A tick starts ``lateness`` s after its deadline; its start time (``perf_counter``)."""
        self.missed += missed(lateness, self.period)
        now = time.perf_counter()
        self.achieved = 0.0 if self.last is None else now - self.last
        self.last = now
        return now

    def row(self, start: float, lateness: float) -> list[float]:
        """The row of a tick that commanded, at its end."""
        return [time.time(), self.achieved, time.perf_counter() - start, lateness, float(self.missed)]
