"""Loop statistics as a bag records them: the ``/diagnostics`` status of a ticking node's loop
(:class:`~pdsmc_ros.loop.statistics.LoopStatistics`, once a second), read back for ``pdsmc analyze``.

:func:`status_name` names the status, :data:`FIELDS` its key-values; :func:`bag_loop_statistics`
reads the last of each node from a bag.
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
