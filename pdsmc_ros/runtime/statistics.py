"""Overrun accounting of a ticking node's loop, as ros2_control's controller manager keeps it.

ros2_control's controller manager counts the periods its update loop overran ("Overrun
detected! The controller manager missed its desired rate") and keeps statistics of the
loop's periodicity and execution time. :class:`LoopStatistics` keeps the same for one of
our real-time loops: ticks, periods missed (a tick later than a whole period), how late
the ticks were, the worst (longest) period between two ticks, the longest tick and the
loop thread's minor page faults after warm-up. The serve loop publishes
:meth:`LoopStatistics.values` once a second on ``/diagnostics`` (status
``<node>: loop statistics``), so the bag records them; :func:`bag_loop_statistics` reads
the last of each node back for ``pdsmc analyze``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

STATUS_SUFFIX = ": loop statistics"
FIELDS = ("ticks", "missed", "missed_pct", "late_mean_us", "late_max_us", "period_worst_us",
          "tick_max_us", "minor_faults", "collections")


def status_name(node: str) -> str:
    """The ``/diagnostics`` status name of ``node``'s loop statistics."""
    return f"{node}{STATUS_SUFFIX}"


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
        if lateness > self.period:
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


def parse_values(values: dict[str, str]) -> dict[str, float]:
    """A status's key-values as numbers (a field not yet known is NaN)."""
    out = {}
    for key in FIELDS:
        try:
            out[key] = float(values[key])
        except (KeyError, ValueError):
            out[key] = math.nan
    return out


def bag_loop_statistics(path: str | Path) -> dict[str, dict[str, float]]:
    """The last loop statistics of every ticking node recorded in the bag at ``path``.

    Returns ``{node: {field: value}}`` (:data:`FIELDS`), empty for a bag without them
    (lockstep runs, or bags recorded before the statistics existed).
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    last: dict[str, dict[str, float]] = {}
    with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections
                 if c.topic == "/diagnostics" and c.msgtype == "diagnostic_msgs/msg/DiagnosticArray"]
        if not conns:  # (no connections would read every message of the bag)
            return last
        for conn, _, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            for status in msg.status:
                if status.name.endswith(STATUS_SUFFIX):
                    node = status.name[: -len(STATUS_SUFFIX)]
                    last[node] = parse_values({kv.key: kv.value for kv in status.values})
    return last


def format_loop_statistics(label: str, stats: dict[str, dict[str, float]]) -> list[str]:
    """One line per node for ``pdsmc analyze``."""
    lines = []
    for node, v in sorted(stats.items()):
        faults = "n/a" if math.isnan(v["minor_faults"]) else f"{v['minor_faults']:.0f}"
        lines.append(
            f"{label}: {node} loop: {v['ticks']:.0f} ticks, missed {v['missed']:.0f} ({v['missed_pct']:.3f} %), "
            f"late mean {v['late_mean_us']:.1f} us max {v['late_max_us']:.1f} us, worst period "
            f"{v['period_worst_us']:.1f} us, longest tick {v['tick_max_us']:.1f} us, "
            f"page faults after warm-up {faults}")
    return lines


def loop_report_lines(bags: Sequence[Any]) -> list[str]:
    """``pdsmc analyze``: the loop statistics of each real-time run among ``bags`` (objects
    with ``path``, ``label`` and ``run.description``, as :class:`~pdsmc_ros.experiments.analysis.AnalyzedBag`)."""
    lines = []
    for b in bags:
        if b.run.description.get("mode") == "realtime":
            lines += format_loop_statistics(b.label, bag_loop_statistics(b.path))
    return lines
