"""A verdict per reproduction cell (reproduced, reading, misprint, infeasible, open) with its
measured evidence: needed torque, payload readings, the continuous-time limit."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...config import load_config
from ...runs.builder import make_run
from ...sim import RunResult, simulate
from .cells import (
    CONTINUOUS_CASE,
    MISPRINT_DIGITS,
    REPRODUCED,
    VERDICTS,
    Cell,
    Reproduction,
    as_defined,
    format_pct,
    format_value,
    run_key,
    summarize,
)


def continuous_check(discrete: RunResult | None = None) -> dict[str, dict[str, Any]]:
    """Statistics of :data:`CONTINUOUS_CASE` at its control rate, at 40 kHz and in the
    continuous-time limit (Radau, rtol 1e-10; :func:`continuous.simulate_continuous`).

    ``discrete`` is the case's run at its own rate when already simulated.
    """
    from ...sim.continuous import simulate_continuous

    spec = make_run(*CONTINUOUS_CASE)
    runs = {
        f"{spec.rate / 1000:g} kHz": discrete or simulate(spec),
        "40 kHz": simulate(dataclasses.replace(spec, rate=40000.0)),
        "Radau rtol 1e-10": simulate_continuous(spec, rtol=1e-10),
    }
    return {name: {"axial_mean": r.metrics.axial_mean, "contour_mean": r.metrics.contour_mean,
                   "contour_sd": r.metrics.contour_sd, "wall_s": r.wall_s} for name, r in runs.items()}


@dataclass(frozen=True)
class Verdict:
    """What the comparison of one cell shows: one of :data:`VERDICTS`, and the evidence."""

    verdict: str
    evidence: str = ""


def _cell_key(c: Cell) -> tuple[str, str, str, str, str]:
    return (c.robot, c.contour, c.scenario, c.controller, c.metric)


def _reproduced(c: Cell) -> bool:
    return abs(c.deviation) <= REPRODUCED


def joint_index(metric: str) -> int:
    """Index (from 0) of the joint a per-joint statistic such as ``max_torque[2]`` names."""
    return int(metric[:-1].split("[")[1]) - 1


def _same_print(a: float, b: float) -> bool:
    return abs(a - b) <= MISPRINT_DIGITS * max(abs(a), abs(b))


def _error_series(res: RunResult, metric: str) -> np.ndarray | None:
    """The absolute error whose mean and S.D. ``metric`` names (None for other statistics)."""
    smp = res.samples
    if metric.startswith(("axial_mean", "axial_sd")):
        i = joint_index(metric)
        return np.abs(smp.q_ref[:, i] - smp.q[:, i])
    if metric.startswith(("task_mean", "task_sd")):
        e = np.abs(smp.xy_ref - smp.xy)
        axis = metric.split(".")[1]
        return e[:, 0] if axis == "x" else e[:, 1] if axis == "y" else np.hypot(e[:, 0], e[:, 1])
    if metric in ("contour_mean", "contour_sd"):
        return np.abs(smp.contour_error)
    return None


def classify(rep: Reproduction) -> list[Verdict]:
    """A :class:`Verdict` per cell of ``rep.cells`` (in order), with its measured evidence.

    Reproduced: within :data:`REPRODUCED`. Misprint: the printed value repeats another
    printed statistic of the same row (to its four digits), ours of that statistic is
    reproduced and ours of this one is not. Infeasible: a printed max torque below the
    needed torque (:func:`needed_torque`) by more than our run's own max differs from it.
    Reading: reproduced under another payload reading or with the gains as printed / the
    statistic as defined, which fits the cell's row (robot, contour, scenario, controller)
    with a median |deviation| no larger than the primary cells'. Everything else is open,
    with what was measured on it.
    """
    rows: dict[tuple[str, str, str, str], dict[str, Cell]] = {}
    for c in rep.cells:
        rows.setdefault(_cell_key(c)[:4], {})[c.metric] = c
    results = {run_key(r.spec): r for r in rep.results}
    others = {name: {_cell_key(c): c for c in cells} for name, cells in rep.payload_cells.items()}
    verdicts: list[Verdict] = []
    for c in rep.cells:
        row = rows[_cell_key(c)[:4]]
        if _reproduced(c):
            verdicts.append(Verdict("reproduced"))
            continue
        twin = next((o for o in row.values() if o.metric != c.metric and _same_print(o.thesis, c.thesis)
                     and _reproduced(o)), None)
        if twin is not None:
            series = _error_series(results[f"{c.robot}/{c.contour}/{c.scenario}/{c.controller}"], c.metric)
            extra = ""
            if series is not None:
                rms, peak = float(np.sqrt(np.mean(series ** 2))), float(np.max(series))
                extra = (f"; the same error's RMS is {rms:.4e} ({100 * (rms / c.thesis - 1):+.1f} %), "
                         f"its max {peak:.4e} ({100 * (peak / c.thesis - 1):+.1f} %)")
            verdicts.append(Verdict("misprint", (
                f"printed {c.thesis:.4g} repeats this row's printed {twin.metric} ({twin.thesis:.4g}), "
                f"which ours reproduces ({format_value(twin.ours, twin.metric)}, {100 * twin.deviation:+.1f} %); "
                f"ours of {c.metric} is {format_value(c.ours, c.metric)}{extra}")))
            continue
        needed = rep.needed_torque.get(f"{c.robot}/{c.contour}/{c.scenario}")
        if c.metric.startswith("max_torque") and needed is not None:
            need = needed[joint_index(c.metric)]
            if c.thesis < need - abs(c.ours - need):
                axial = summarize(o for o in row.values() if o.metric.startswith("axial"))
                verdicts.append(Verdict("infeasible", (
                    f"printed {c.thesis:.4g} N m is {100 * (1 - c.thesis / need):.1f} % below the "
                    f"{need:.4g} N m needed to follow the trajectory at all; our run's max is "
                    f"{c.ours:.4g}; this row's axial errors: median abs. deviation "
                    f"{format_pct(axial['median_abs_dev'])}")))
                continue
        readings = [(f"payload reading {name}", o[_cell_key(c)],
                     [o[_cell_key(r)] for r in row.values()]) for name, o in others.items() if _cell_key(c) in o]
        if c.as_defined != c.ours:
            readings.append(("the statistic as defined and the gains as printed",
                             dataclasses.replace(c, ours=c.as_defined), as_defined(row.values())))
        primary = summarize(row.values())["median_abs_dev"]
        # a reading explains a cell only where it fits the cell's whole row no worse than the
        # primary cells do: one cell landing within 5 % while its row gets worse explains nothing
        fits = [(name, o, alt) for name, o, alt in readings
                if _reproduced(o) and summarize(alt)["median_abs_dev"] <= primary]
        if fits:
            name, o, alt = fits[0]
            verdicts.append(
                Verdict(
                    "reading",
                    f"with {name}: {format_value(o.ours, c.metric)} "
                    f"({100 * o.deviation:+.1f} %; its row's median abs. deviation "
                    f"{format_pct(summarize(alt)['median_abs_dev'])} against {format_pct(primary)})",
                )
            )
            continue
        notes = [f"with {name}: {format_value(o.ours, c.metric)} ({100 * o.deviation:+.1f} %; its row's median "
                 f"abs. deviation {format_pct(summarize(alt)['median_abs_dev'])} against {format_pct(primary)})"
                 for name, o, alt in readings]
        skew = _left_skew(c, row, results, rep)
        if skew:
            notes.append(skew)
        if c.metric.startswith("max_torque") and needed is not None:
            need = needed[joint_index(c.metric)]
            notes.append(f"needed torque {need:.4g} N m; our run's max {c.ours:.4g}")
        verdicts.append(Verdict("open", "; ".join(notes)))
    return verdicts


def _left_skew(c: Cell, row: Mapping[str, Cell], results: Mapping[str, RunResult], rep: Reproduction) -> str:
    """For a "% within bound" cell whose printed mean lies below the bound with fewer than half
    the samples within it (so the thesis's median exceeds its mean): our median/mean per reading."""
    if c.metric != "contour_within_pct" or "contour_mean" not in row:
        return ""
    bound = float(load_config("thesis_tables")[c.robot][c.contour][c.scenario]["bound"])
    if not (c.thesis < 50.0 and row["contour_mean"].thesis < bound):
        return ""
    key = f"{c.robot}/{c.contour}/{c.scenario}/{c.controller}"
    runs = {rep.payload_reading: results[key]}
    runs.update({name: r for name, group in rep.payload_results.items() for r in group if run_key(r.spec) == key})
    ratios = ", ".join(f"{float(np.median(np.abs(r.samples.contour_error))) / r.metrics.contour_mean:.2f} ({name})"
                       for name, r in runs.items())
    return (f"the printed mean {row['contour_mean'].thesis:.4g} m lies below the {bound:g} m bound with only "
            f"{c.thesis:g} % within it, so the thesis's median exceeds its mean (left-skewed); ours has "
            f"its median below its mean, median/mean {ratios}")


def count_verdicts(verdicts: Iterable[Verdict]) -> dict[str, int]:
    """Number of cells per verdict (every name of :data:`VERDICTS`, zero included)."""
    counts = dict.fromkeys(VERDICTS, 0)
    for v in verdicts:
        counts[v.verdict] += 1
    return counts


ROW_GROUPS: dict[str, Callable[[Cell], bool]] = {
    "PD and PD-SMC rows": lambda c: c.controller != "smc",
    "SMC rows": lambda c: c.controller == "smc",
}


STATISTIC_KINDS: dict[str, Callable[[Cell], bool]] = {
    "axial errors": lambda c: c.metric.startswith("axial"),
    "task-space errors": lambda c: c.metric.startswith("task"),
    "contour mean/SD": lambda c: c.metric in ("contour_mean", "contour_sd"),
    "% within bound": lambda c: c.metric == "contour_within_pct",
    "max torque": lambda c: c.metric.startswith("max_torque"),
}


def verdict_groups(cells: list[Cell], verdicts: list[Verdict]) -> dict[str, list[Verdict]]:
    """Verdicts per group of cells: by rows, by kind of statistic and all."""
    groups = {**ROW_GROUPS, **STATISTIC_KINDS}
    out = {name: [v for c, v in zip(cells, verdicts) if pred(c)] for name, pred in groups.items()}
    out["all rows"] = list(verdicts)
    return out
