"""The storm benchmark's figures: per window, the loop's lateness, missed deadlines and what came
before them, the machine's CPU time and the loops' run-queue waits (``python bench/storm``)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pdsmc_ros.loop.statistics import missed

FLOOR_PRIORITY = 50  # --floor: the controller loop's SCHED_FIFO priority (thread_priority's default)


RUNQUEUE_EVERY_S = 0.02  # RunQueueWaits: how often the loops' run-queue waits are read


CAUSE_WINDOW_S = 0.005  # late_tick_causes: how long before a late tick's deadline an event may have caused it


def window_kind(t: float, windows: list[tuple[str, float, float, str]]) -> str | None:
    """The kind of window (``idle``, ``storm``) wall time ``t`` lies in; None between windows."""
    return next((name for name, a, b, _ in windows if a <= t < b), None)


def kind_mask(times: np.ndarray, windows: list[tuple[str, float, float, str]], kind: str) -> np.ndarray:
    """Which of the wall ``times`` lie in a window of ``kind``."""
    mask = np.zeros(len(times), dtype=bool)
    for name, a, b, _ in windows:
        if name == kind:
            mask |= (times >= a) & (times < b)
    return mask


def floor_figures(rows: np.ndarray, windows: list[tuple[str, float, float, str]], period: float) -> str:
    """The bare loop's lateness in each kind of window, pooled: missed deadlines, p99.9 and worst."""
    told = []
    for kind in ("idle", "storm"):
        late = rows[kind_mask(rows[:, 0], windows, kind), 1]
        if len(late) < 2:
            told.append(f"{kind}: no ticks")
            continue
        told.append(f"{kind}: {len(late)} ticks, missed {np.count_nonzero(missed(late, period))}, p99.9 "
                    f"{1e6 * np.percentile(late, 99.9):.0f} us, worst {1e6 * late.max():.0f} us")
    return f"a bare loop beside it (Python, SCHED_FIFO {FLOOR_PRIORITY}, no ROS): " + "; ".join(told)


CPU_TIMES = ("user", "nice", "system", "idle", "iowait", "irq", "softirq", "steal")


def cpu_times() -> np.ndarray:
    """The machine's CPU time so far by kind (seconds over all CPUs: ``/proc/stat``'s first line,
    in the order of ``CPU_TIMES``); NaN where it cannot be read."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:1 + len(CPU_TIMES)]
        return np.array([float(f) for f in fields]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError):
        return np.full(len(CPU_TIMES), np.nan)


def machine_figures(spent: np.ndarray) -> dict[str, float]:
    """What the machine's CPUs did over a window (``spent``: a difference of :func:`cpu_times`):
    the share left idle, the share in the kernel (system, interrupts) and the time the host took
    the virtual CPUs away (steal, ms)."""
    total = float(spent.sum())
    if not total > 0.0:
        return {}
    kernel = spent[CPU_TIMES.index("system")] + spent[CPU_TIMES.index("irq")] + spent[CPU_TIMES.index("softirq")]
    return {"cpu_idle_pct": 100.0 * float(spent[CPU_TIMES.index("idle")]) / total,
            "cpu_kernel_pct": 100.0 * float(kernel) / total,
            "steal_ms": 1e3 * float(spent[CPU_TIMES.index("steal")])}


def runqueue_ms(samples: np.ndarray, names: list[str], start: float, end: float) -> dict[str, float]:
    """The loops' run-queue waits (ms) between ``start`` and ``end`` (wall time), by the samples
    around them, as ``{name}_rq_ms`` (``names``: the sampled processes, in their columns' order)."""
    if len(samples) < 2:
        return {}
    at = np.interp([start, end], samples[:, 0], np.arange(len(samples)))
    first, last = int(np.floor(at[0])), int(np.ceil(at[1]))
    waited = (samples[last, 1:] - samples[first, 1:]) / 1e6
    return {f"{name}_rq_ms": float(w) for name, w in zip(names, waited, strict=True)}


def misses_on_run_queue(late: np.ndarray, samples: np.ndarray, windows: list[tuple[str, float, float, str]],
                        period: float) -> str:
    """The missed deadlines of each kind of window in a sampling interval where the controller's
    loop waited on the run queue for at least a period (its CPU withheld, not its own work late)."""
    counts = {kind: [0, 0] for kind in ("idle", "storm")}
    for tick in late[:, 0] if len(samples) >= 2 else ():
        kind = window_kind(tick, windows)
        if kind is None:
            continue
        k = int(np.searchsorted(samples[:, 0], tick))
        counts[kind][1] += 1
        if 0 < k < len(samples) and (samples[k, 1] - samples[k - 1, 1]) / 1e9 >= period:
            counts[kind][0] += 1
    return "; ".join(f"missed deadlines {kind}: {on} of {n} where the controller's loop waited a period or more "
                     f"on the run queue within {1e3 * RUNQUEUE_EVERY_S:g} ms" for kind, (on, n) in counts.items())


def late_tick_causes(late: np.ndarray, windows: list[tuple[str, float, float, str]],
                     events: list[tuple[float, str]]) -> str:
    """What the storm did just before each of its missed deadlines (``late``: the timing rows of the
    ticks that missed theirs): the events from ``CAUSE_WINDOW_S`` before the late tick's deadline
    to the tick, counted by kind (a tick late in an idle window has no storm event to blame; the
    idle windows' count is the base rate)."""
    kinds: dict[str, int] = {}
    ticks = {"idle": 0, "storm": 0}
    unexplained = 0
    times = np.array([t for t, _ in events])
    for tick, _, _, lateness in late[:, :4]:
        kind = window_kind(tick, windows)
        if kind is None:
            continue
        ticks[kind] += 1
        if kind == "idle":
            continue
        near = np.flatnonzero((times >= tick - lateness - CAUSE_WINDOW_S) & (times <= tick)) if len(times) else []
        if not len(near):
            unexplained += 1
        for k in near:
            kinds[events[k][1]] = kinds.get(events[k][1], 0) + 1
    listed = ", ".join(f"{what} {n}" for what, n in sorted(kinds.items(), key=lambda item: -item[1]))
    return (f"missed deadlines: {ticks['idle']} idle, {ticks['storm']} in the storm; storm events in the "
            f"{1e3 * CAUSE_WINDOW_S:g} ms before them: {listed or 'none'}; with none: {unexplained}")


def miss_origins(rows: np.ndarray, windows: list[tuple[str, float, float, str]], period: float) -> str:
    """Where each missed deadline came from, per kind of window: the tick before it still running
    a period past the missed tick's deadline (a long tick: the loop's own work, or a lock it
    waited for, made the next one late), or the loop starting late after a short tick (its thread
    not scheduled, or waiting for the GIL before the tick). ``rows``: timing rows in tick order
    (:meth:`~pdsmc_ros.loop.statistics.LoopStatistics.row`: wall time at the tick's end, achieved
    period, compute time, lateness)."""
    counts = {kind: {"long": 0, "late": 0, "first": 0} for kind in ("idle", "storm")}
    for k in np.flatnonzero(missed(rows[:, 3], period)):
        end, _, compute, lateness = rows[k, :4]
        kind = window_kind(end, windows)
        if kind is None:
            continue
        if k == 0:
            counts[kind]["first"] += 1
            continue
        deadline = end - compute - lateness  # the missed tick's deadline, on the wall clock
        previous_end = rows[k - 1, 0]
        counts[kind]["long" if previous_end - deadline > period else "late"] += 1
    return "; ".join(
        f"missed deadlines {kind}: {c['long']} after a tick still running a period past the deadline, "
        f"{c['late']} started late after a short tick" + (f", {c['first']} first rows" if c["first"] else "")
        for kind, c in counts.items())


def window_figures(rows: np.ndarray, start: float, end: float, period: float) -> dict[str, float]:
    """The lateness of the commanding ticks whose wall time lies in ``[start, end)``."""
    inside = rows[(rows[:, 0] >= start) & (rows[:, 0] < end)]
    if len(inside) < 2:
        return {"ticks": float(len(inside))}
    lateness = inside[:, 3]
    achieved = inside[1:, 1]
    compute = inside[:, 2]
    return {"ticks": float(len(inside)),
            "p50_us": 1e6 * float(np.percentile(lateness, 50)),
            "p99_us": 1e6 * float(np.percentile(lateness, 99)),
            "p999_us": 1e6 * float(np.percentile(lateness, 99.9)),
            "worst_us": 1e6 * float(lateness.max()),
            "missed": float(np.count_nonzero(missed(lateness, period))),
            "lost": float(np.maximum(np.round(achieved / period) - 1.0, 0.0).sum()),
            "worst_period_us": 1e6 * float(achieved.max()),
            "compute_p50_us": 1e6 * float(np.percentile(compute, 50)),
            "compute_p999_us": 1e6 * float(np.percentile(compute, 99.9))}


COLUMNS = (("ticks", "ticks", "{:.0f}"), ("p50_us", "p50 us", "{:.0f}"), ("p99_us", "p99 us", "{:.0f}"),
           ("p999_us", "p99.9 us", "{:.0f}"), ("worst_us", "worst us", "{:.0f}"), ("missed", "missed", "{:.0f}"),
           ("lost", "lost", "{:.0f}"), ("worst_period_us", "worst period us", "{:.0f}"),
           ("compute_p50_us", "tick p50 us", "{:.0f}"), ("compute_p999_us", "tick p99.9 us", "{:.0f}"),
           ("controller_rq_ms", "loop rq ms", "{:.1f}"), ("driver_rq_ms", "stand-in rq ms", "{:.1f}"),
           ("cpu_idle_pct", "cpu idle %", "{:.1f}"), ("cpu_kernel_pct", "kernel %", "{:.1f}"),
           ("steal_ms", "steal ms", "{:.0f}"))


def print_table(labelled: list[tuple[str, dict[str, float], str]]) -> None:
    header = f"{'window':14s}" + "".join(f"{title:>16s}" for _, title, _ in COLUMNS) + "  load average"
    print(header)
    for label, figures, load in labelled:
        cells = "".join(f"{(fmt.format(figures[key]) if key in figures else '-'):>16s}" for key, _, fmt in COLUMNS)
        print(f"{label:14s}{cells}  {load}")
