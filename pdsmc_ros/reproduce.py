"""Run the thesis matrix (Tables 4.17-4.61) and compare every cell.

The thesis's numbers live in ``config/thesis_tables.yaml`` as targets; this
module simulates every (robot, contour, scenario, controller) they cover and
writes ``REPRODUCTION.md`` plus CSV and JSON with, per cell, the thesis value,
ours and the relative deviation.
"""

from __future__ import annotations

import csv
import dataclasses
import fnmatch
import json
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .errors import BagError, ConfigError
from .presets import CONTROLLER_LABELS as LABEL
from .presets import (
    CONTROLLER_NAMES,
    PAYLOAD_READINGS,
    Gains,
    RunSpec,
    choice,
    control_steps,
    load_config,
    make_run,
    preset_gains,
)
from .resources import ros_environment, script_path
from .simulator import RunResult, simulate, simulate_many

REPRODUCED = 0.05
"""A cell is reproduced when ours lies within this relative deviation of the thesis's."""

VERDICTS = ("reproduced", "reading", "misprint", "infeasible", "open")
"""What a cell's comparison shows (:func:`classify`): reproduced; reproduced only under a
reading the primary cells do not use (the other payload reading, the gains as printed or the
statistic as defined) that fits its row no worse; a misprint (the printed value repeats
another printed statistic of its row, and ours of that statistic matches it); infeasible (a
printed max torque below the torque needed to follow the trajectory); open."""

MISPRINT_DIGITS = 5e-4
"""Relative gap within which two printed values (four significant digits) are the same number."""

CONTINUOUS_CASE = ("serial_3r", "circle", "pdsmc")
"""The run checked against its continuous-time limit (:mod:`pdsmc_ros.continuous`)."""



# Statistics the thesis computed differently for one controller, found by comparing its
# tables with ours; per (controller, thesis statistic): our statistic it is compared with,
# and why. The report shows both our values (as read and as NOTES.md section 4 defines it).
STATISTIC_READINGS: dict[tuple[str, str], tuple[str, str]] = {
    ("pdsmc", "task_sd.x"): (
        "task_sd_signed.x",
        "The thesis's PD-SMC task-space x S.D. (the task-space tables of both arms) is the S.D. "
        "of the signed x error, not of its absolute value as in every other column: on all nine "
        "PD-SMC rows it lands within 0.1-3 % of the signed S.D., while the absolute S.D. is "
        "21-47 % below it wherever the x error changes sign (the serial ellipse's does not, and "
        "both agree there). The PD and SMC rows match the absolute S.D., and the PD-SMC x means "
        "match the absolute error, so only that S.D. was computed without abs().",
    ),
}


# Gains the thesis evidently ran with where Table 4.33 prints others; per (robot, contour,
# controller): the gains read (the others as printed) and why. The preset in config/gains.yaml
# stays as printed; the report shows every affected cell with both gains.
GAIN_READINGS: dict[tuple[str, str, str], tuple[dict[str, list[float]], str]] = {
    ("parallel_5r", "ellipse_vertical", "pd"): (
        {"kp": [250.0, 280.0], "kd": [32.0, 36.0]},
        "Table 4.33 prints the five-bar PD gains for the vertical ellipse as Kp = diag{240, 280}, "
        "Kd = diag{28, 36}, and the PD-SMC's as Kp = diag{250, 280}, Kd = diag{32, 36}; in every "
        "other contour group of both arms PD and PD-SMC share Kp and Kd. With the PD-SMC's Kp and "
        "Kd the PD row of Tables 4.50-4.53 is reproduced (median deviation 0.7 %, all 15 cells "
        "within 5 %; axis-1 mean error +0.6 %, contour S.D. +0.6 %); with the printed ones it is "
        "not (median 2.4 %, axis-1 mean +5.3 %, contour S.D. +5.7 %). The high-PD and high-SMC "
        "rows agree (contour S.D. +0.8 % / +0.6 % against +5.9 % / +5.7 %); the high-speed row "
        "does not: its contour mean fits the printed gains (-0.3 %) better than these (-8.7 %), so "
        "the reading is likely but not certain, and the score without it is given too.",
    ),
}


def read_gains(robot: str, contour: str, controller: str) -> Gains | None:
    """The preset gains with :data:`GAIN_READINGS` applied, or None if none applies."""
    reading = GAIN_READINGS.get((robot, contour, controller))
    if reading is None:
        return None
    base = preset_gains(robot, contour, controller)
    return Gains.from_mapping({**base.as_dict(), **reading[0]}, len(base.kp), controller)


@dataclass(frozen=True)
class Cell:
    """One table cell: thesis value against ours.

    ``ours_metric`` names our statistic compared with the thesis's ``metric``
    (the same one unless :data:`STATISTIC_READINGS` says otherwise); ``as_defined``
    is our value of ``metric`` itself, as NOTES.md section 4 defines it, from the
    run with the gains as printed (the same run unless :data:`GAIN_READINGS` applies).
    """

    robot: str
    contour: str
    scenario: str
    controller: str
    table: str
    metric: str
    thesis: float
    ours: float
    ours_metric: str = ""
    as_defined: float = float("nan")

    @property
    def deviation(self) -> float:
        """Relative deviation ``(ours - thesis) / thesis``."""
        if self.thesis == 0.0:
            return 0.0 if self.ours == 0.0 else float("inf")
        return (self.ours - self.thesis) / abs(self.thesis)


def smc_reading(name: str) -> dict[str, float]:
    """Model-estimate scales of a named SMC reading (``config/smc_readings.yaml``)."""
    readings = load_config("smc_readings")
    return dict(readings[choice(name, list(readings), "SMC reading")]["model"])


def matrix_specs(
    smc: str = "thesis_fit", *, gain_readings: bool = True, payload_reading: str = "tip"
) -> list[RunSpec]:
    """Every run the thesis tables report, with their tables' contour bounds.

    With ``gain_readings``, the gains of :data:`GAIN_READINGS` replace the printed
    ones (before the scenario's factors, as for any preset); ``payload_reading``
    places the payload scenario's load (:data:`presets.PAYLOAD_READINGS`).
    """
    tables = load_config("thesis_tables")
    model = smc_reading(smc)
    specs: list[RunSpec] = []
    for robot, contours in tables.items():
        for contour, scenarios in contours.items():
            for scenario, entry in scenarios.items():
                for controller in CONTROLLER_NAMES:
                    spec = make_run(
                        robot,
                        contour,
                        controller,
                        scenario=scenario,
                        gains=read_gains(robot, contour, controller) if gain_readings else None,
                        smc_model=model if controller == "smc" else None,
                        payload_reading=payload_reading,
                    )
                    specs.append(dataclasses.replace(spec, bound=float(entry["bound"])))
    return specs


def _metric_items(row: Mapping[str, Any]) -> Iterable[tuple[str, float]]:
    for key, value in row.items():
        if isinstance(value, Mapping):
            for sub, v in value.items():
                yield f"{key}.{sub}", float(v)
        elif isinstance(value, list):
            for i, v in enumerate(value):
                yield f"{key}[{i + 1}]", float(v)
        else:
            yield key, float(value)


def _lookup(metrics: Mapping[str, Any], name: str) -> float:
    if "." in name:
        key, sub = name.split(".")
        return float(metrics[key][sub])
    if "[" in name:
        key, idx = name[:-1].split("[")
        return float(metrics[key][int(idx) - 1])
    return float(metrics[name])


def _table_of(metric: str, tables: Mapping[str, str]) -> str:
    kind = (
        "axial"
        if metric.startswith("axial")
        else "task"
        if metric.startswith("task")
        else "torque"
        if metric.startswith("max_torque")
        else "contour"
    )
    return tables.get(kind, "")


def compare(results: Iterable[RunResult], printed: Mapping[str, RunResult] | None = None) -> list[Cell]:
    """Cells of every table entry the thesis prints for these runs.

    ``printed`` maps :func:`run_key` to the run with the gains as printed, for the
    runs that :data:`GAIN_READINGS` changed (their ``as_defined`` values).
    """
    tables = load_config("thesis_tables")
    cells: list[Cell] = []
    for res in results:
        s = res.spec
        entry = tables[s.robot][s.contour][s.scenario]
        metrics = res.metrics.as_dict()
        plain = (printed or {}).get(run_key(s), res).metrics.as_dict()
        for name, thesis in _metric_items(entry[s.controller]):
            ours_metric = STATISTIC_READINGS.get((s.controller, name), (name, ""))[0]
            cells.append(
                Cell(
                    s.robot,
                    s.contour,
                    s.scenario,
                    s.controller,
                    _table_of(name, entry["tables"]),
                    name,
                    thesis,
                    _lookup(metrics, ours_metric),
                    ours_metric,
                    _lookup(plain, name),
                )
            )
    return cells


def as_defined(cells: Iterable[Cell]) -> list[Cell]:
    """The same cells compared with our statistics as defined and the gains as printed
    (no statistic or gain reading)."""
    return [dataclasses.replace(c, ours=c.as_defined, ours_metric=c.metric) for c in cells]


def summarize(cells: Iterable[Cell]) -> dict[str, float]:
    """Median |relative deviation| and share of cells within 1 % and 5 %."""
    dev = np.array([abs(c.deviation) for c in cells])
    if dev.size == 0:
        return {"cells": 0, "median_abs_dev": float("nan"), "within_1pct": 0.0, "within_5pct": 0.0}
    return {
        "cells": int(dev.size),
        "median_abs_dev": float(np.median(dev)),
        "within_1pct": float(np.mean(dev <= 0.01)),
        "within_5pct": float(np.mean(dev <= 0.05)),
    }


@dataclass
class Reproduction:
    """Everything ``pdsmc reproduce`` measured.

    Attributes
    ----------
    payload_reading : str
        Reading of the payload scenario in :attr:`cells`.
    payload_cells : dict
        Per other payload reading, the payload scenario's cells with it.
    payload_results : dict
        Per other payload reading, the payload scenario's runs with it.
    needed_torque : dict
        Per ``robot/contour/scenario`` with a torque table, :func:`needed_torque` (N m).
    continuous : dict
        Statistics of :data:`CONTINUOUS_CASE` per solution (see :func:`continuous_check`);
        empty when not measured.
    """

    cells: list[Cell]
    results: list[RunResult]
    smc_reading: str
    wall_s: float
    readings: dict[str, dict[str, float]]
    payload_reading: str = "tip"
    payload_cells: dict[str, list[Cell]] = field(default_factory=dict)
    payload_results: dict[str, list[RunResult]] = field(default_factory=dict)
    needed_torque: dict[str, list[float]] = field(default_factory=dict)
    continuous: dict[str, dict[str, Any]] = field(default_factory=dict)


def needed_torque(spec: RunSpec) -> np.ndarray:
    """Max |tau| per actuated joint that the plant needs to follow the reference exactly.

    Eq. (4.1) solved for the torque along the desired motion,
    ``tau = Mbar(q_d) qdd_d + C(q_d, qd_d) qd_d + G(q_d) + B qd_d``
    (:meth:`models.Manipulator.inverse_dynamics`), at every control instant.
    """
    reference = spec.reference()
    ref = reference.sample(np.arange(control_steps(reference.duration, spec.rate) + 1) / spec.rate)
    return np.max(np.abs(spec.robot_model().inverse_dynamics(ref.q, ref.qd, ref.qdd)), axis=0)


def continuous_check(discrete: RunResult | None = None) -> dict[str, dict[str, Any]]:
    """Statistics of :data:`CONTINUOUS_CASE` at its control rate, at 40 kHz and in the
    continuous-time limit (Radau, rtol 1e-10; :func:`continuous.simulate_continuous`).

    ``discrete`` is the case's run at its own rate when already simulated.
    """
    from .continuous import simulate_continuous

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


def _joint(metric: str) -> int:
    """Index (from 0) of the joint a per-joint statistic such as ``max_torque[2]`` names."""
    return int(metric[:-1].split("[")[1]) - 1


def _same_print(a: float, b: float) -> bool:
    return abs(a - b) <= MISPRINT_DIGITS * max(abs(a), abs(b))


def _error_series(res: RunResult, metric: str) -> np.ndarray | None:
    """The absolute error whose mean and S.D. ``metric`` names (None for other statistics)."""
    smp = res.samples
    if metric.startswith(("axial_mean", "axial_sd")):
        i = _joint(metric)
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
                f"which ours reproduces ({_fmt(twin.ours, twin.metric)}, {100 * twin.deviation:+.1f} %); "
                f"ours of {c.metric} is {_fmt(c.ours, c.metric)}{extra}")))
            continue
        needed = rep.needed_torque.get(f"{c.robot}/{c.contour}/{c.scenario}")
        if c.metric.startswith("max_torque") and needed is not None:
            need = needed[_joint(c.metric)]
            if c.thesis < need - abs(c.ours - need):
                axial = summarize(o for o in row.values() if o.metric.startswith("axial"))
                verdicts.append(Verdict("infeasible", (
                    f"printed {c.thesis:.4g} N m is {100 * (1 - c.thesis / need):.1f} % below the "
                    f"{need:.4g} N m needed to follow the trajectory at all; our run's max is "
                    f"{c.ours:.4g}; this row's axial errors: median abs. deviation "
                    f"{_pct(axial['median_abs_dev'])}")))
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
            verdicts.append(Verdict("reading", f"with {name}: {_fmt(o.ours, c.metric)} "
                                               f"({100 * o.deviation:+.1f} %; its row's median abs. deviation "
                                               f"{_pct(summarize(alt)['median_abs_dev'])} against {_pct(primary)})"))
            continue
        notes = [f"with {name}: {_fmt(o.ours, c.metric)} ({100 * o.deviation:+.1f} %; its row's median "
                 f"abs. deviation {_pct(summarize(alt)['median_abs_dev'])} against {_pct(primary)})"
                 for name, o, alt in readings]
        skew = _left_skew(c, row, results, rep)
        if skew:
            notes.append(skew)
        if c.metric.startswith("max_torque") and needed is not None:
            need = needed[_joint(c.metric)]
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


def run_key(spec: RunSpec) -> str:
    """``robot/contour/scenario/controller`` (what ``--only`` patterns match)."""
    return f"{spec.robot}/{spec.contour}/{spec.scenario}/{spec.controller}"


def select(specs: list[RunSpec], only: str | None) -> list[RunSpec]:
    if not only:
        return specs
    chosen = [s for s in specs if fnmatch.fnmatch(run_key(s), only)]
    if not chosen:
        raise ConfigError(f"--only {only!r} matches no run; runs are named robot/contour/scenario/controller, "
                          "e.g. 'parallel_5r/ellipse_vertical/*/pdsmc'")
    return chosen


def run_reproduction(
    *,
    smc: str = "thesis_fit",
    workers: int | None = None,
    readings: bool = True,
    progress: Callable[[str], None] | None = None,
    only: str | None = None,
    ros_bags: Path | None = None,
    payload_reading: str = "tip",
) -> Reproduction:
    """Simulate the whole matrix (and, optionally, every SMC reading on the nominal rows,
    the other payload readings on the payload rows and, for the whole matrix, the
    continuous-time check of :func:`continuous_check`).

    ``payload_reading`` places the payload scenario's load in the primary cells.

    With ``ros_bags``, every run is executed over DDS through
    ``scripts/run_experiment.sh`` (lockstep, composed intra-process), recorded into that
    directory and analysed from its bag; each bag is checked against the
    in-process simulation of the same run (1e-9).
    """
    start = time.perf_counter()
    choice(payload_reading, tuple(PAYLOAD_READINGS), "payload reading")
    specs = select(matrix_specs(smc, payload_reading=payload_reading), only)
    if ros_bags is not None and payload_reading != "tip" and any(s.payload > 0.0 for s in specs):
        raise ConfigError(f"--payload-reading {payload_reading} runs in-process only (the ROS plant carries "
                          "the load as a point mass at the tip); drop --ros or use --payload-reading tip")
    extra: dict[str, list[RunSpec]] = {}
    payload_extra: dict[str, list[RunSpec]] = {}
    if readings:
        for name in load_config("smc_readings"):
            if name == smc:
                continue
            model = smc_reading(name)
            extra[name] = [
                dataclasses.replace(s, smc_model=model)
                for s in specs
                if s.controller == "smc" and s.scenario == "nominal"
            ]
        for name in PAYLOAD_READINGS:
            if name != payload_reading:
                payload_extra[name] = [dataclasses.replace(s, payload_reading=name)
                                       for s in specs if s.payload > 0.0]
    # the runs a gain reading changed, once more with the gains as printed (run last)
    printed_specs = [p for p, s in zip(select(matrix_specs(smc, gain_readings=False), only), specs)
                     if p.gains != s.gains]
    everything = (specs + [s for group in extra.values() for s in group]
                  + [s for group in payload_extra.values() for s in group] + printed_specs)
    tables = load_config("thesis_tables")

    def report(done: int, total: int, res: RunResult) -> None:
        if progress is None:
            return
        s = res.spec
        thesis = tables[s.robot][s.contour][s.scenario][s.controller]["contour_mean"]
        ours = res.metrics.contour_mean
        progress(
            f"[{done:3d}/{total}] {s.robot:11s} {s.contour:18s} {s.scenario:10s} "
            f"{LABEL[s.controller]:6s} contour mean {ours:.4e} m (thesis {thesis:.4e}, "
            f"{100 * (ours - thesis) / thesis:+6.1f} %)  {res.wall_s:5.2f} s"
        )

    if ros_bags is not None:
        # each case is its own process group and DDS domain; one at a time unless asked: a composed
        # intra-process run keeps a core busy, and two at once took 30 s each against 9 s alone
        from concurrent.futures import ThreadPoolExecutor

        done = iter(range(1, len(specs) + 1))

        def one(spec: RunSpec) -> RunResult:
            return _ros_result(spec, ros_bags, lambda r: report(next(done), len(specs), r))

        order = sorted(range(len(specs)), key=lambda i: -specs[i].contour_model().duration)
        with ThreadPoolExecutor(max_workers=workers or 1) as pool:
            futures = {i: pool.submit(one, specs[i]) for i in order}
            results = [futures[i].result() for i in range(len(specs))]
        results += simulate_many(everything[len(specs):], workers=workers) if len(everything) > len(specs) else []
    else:
        results = simulate_many(everything, workers=workers, progress=report)
    main = results[: len(specs)]
    printed = {run_key(r.spec): r for r in results[len(results) - len(printed_specs):]}
    cells = compare(main, printed)
    summary_by_reading = {smc: summarize(c for c in cells if c.controller == "smc" and c.scenario == "nominal")}
    offset = len(specs)
    for name, group in extra.items():
        chunk = results[offset : offset + len(group)]
        offset += len(group)
        summary_by_reading[name] = summarize(compare(chunk))
    payload_cells: dict[str, list[Cell]] = {}
    payload_results: dict[str, list[RunResult]] = {}
    for name, group in payload_extra.items():
        payload_results[name] = results[offset : offset + len(group)]
        offset += len(group)
        payload_cells[name] = compare(payload_results[name])
    needed: dict[str, list[float]] = {}
    for s in specs:
        key = f"{s.robot}/{s.contour}/{s.scenario}"
        if key not in needed and "torque" in tables[s.robot][s.contour][s.scenario]["tables"]:
            needed[key] = needed_torque(s).tolist()
    continuous: dict[str, dict[str, Any]] = {}
    if readings and not only:
        case = next(r for r in main if (r.spec.robot, r.spec.contour, r.spec.controller) == CONTINUOUS_CASE
                    and r.spec.scenario == "nominal")
        continuous = continuous_check(case)
    return Reproduction(cells, main, smc, time.perf_counter() - start, summary_by_reading,
                        payload_reading, payload_cells, payload_results, needed, continuous)


def _ros_result(spec: RunSpec, bags: Path, report: Callable[[RunResult], None]) -> RunResult:
    """One run over DDS, analysed from its bag and checked against the in-process loop."""
    import subprocess

    from .bag.reader import read_run, run_samples
    from .metrics import compute_metrics
    from .simulator import simulate

    start = time.perf_counter()
    out = bags / run_key(spec).replace("/", "-")
    script = script_path()
    reading = "thesis_fit" if spec.smc_model == smc_reading("thesis_fit") else "literal"
    cmd = ["bash", str(script), "--robot", spec.robot, "--contour", spec.contour, "--controller",
           spec.controller, "--scenario", spec.scenario, "--smc-reading", reading, "--composed",
           "--intra-process", "--out", str(out), "--timeout", "3600"]
    printed = make_run(spec.robot, spec.contour, spec.controller, scenario=spec.scenario)
    if spec.gains != printed.gains:  # a gain reading: the controller gets the gains explicitly
        for name, values in spec.gains.as_dict().items():
            if values:
                cmd += ["--param", f"{name}:=[{', '.join(repr(float(v)) for v in values)}]"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=ros_environment())
    if proc.returncode != 0:
        raise BagError(f"{run_key(spec)} over DDS failed: {proc.stderr.strip().splitlines()[-1:]}")
    run = read_run(out)
    run = dataclasses.replace(run, spec=dataclasses.replace(run.spec, bound=spec.bound))
    samples = run_samples(run)
    reference = simulate(spec)
    gap = float(np.max(np.abs(samples.q - reference.samples.q)))
    if not run.complete or gap > 1e-9:
        raise BagError(f"{run_key(spec)}: the DDS run differs from the in-process one "
                       f"(max |dq| {gap:.3g}, complete={run.complete})")
    result = RunResult(spec, samples, compute_metrics(samples, spec.bound), run.steps,
                       time.perf_counter() - start)
    report(result)
    return result


# --------------------------------------------------------------------------- #
# Report
# --------------------------------------------------------------------------- #
def _fmt(value: float, metric: str) -> str:
    if metric == "contour_within_pct":
        return f"{value:.2f} %"
    if metric.startswith("max_torque"):
        return f"{value:.4g}"
    return f"{value:.4e}"


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def write_report(rep: Reproduction, out: Path) -> dict[str, Path]:
    """Write ``REPRODUCTION.md``, ``reproduction.csv`` and ``reproduction.json`` into ``out``."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create output directory {str(out)!r}: {exc.strerror}") from exc
    readings_cfg = load_config("smc_readings")
    cells = rep.cells
    groups = {name: [c for c in cells if pred(c)] for name, pred in ROW_GROUPS.items()}
    groups["all rows"] = cells
    kinds = STATISTIC_KINDS
    verdicts = classify(rep)
    lines: list[str] = []
    add = lines.append
    add("# Reproduction of Acob (2015), Tables 4.17-4.61")
    add("")
    add(
        f"Generated by `pdsmc reproduce` (pdsmc_ros {__version__}). Every cell: the thesis's value, "
        "ours, and the relative deviation (ours - thesis) / thesis. "
        f"{len(rep.results)} runs, {sum(r.steps for r in rep.results):,} control steps, "
        f"{rep.wall_s:.1f} s wall time on {os.cpu_count()} cores"
        + (" (including the SMC-reading and payload-reading comparisons and the continuous-time check below)."
           if rep.readings and len(rep.readings) > 1 else ".")
    )
    add("")
    add("Setup: discrete loop with zero-order hold, RK4 plant between control instants; control at "
        "10 kHz (serial) / 5 kHz (parallel); the serial circle PD-SMC run lies within about 1e-5 "
        "(relative) of its continuous-time limit (see *Discrete loop against the continuous-time "
        "limit*); statistics sampled at 500 Hz / "
        "5 kHz over [0, T] inclusive (NOTES.md section 1). "
        "Contour error: Eq. 2.9 against the active segment (linear contours), Eq. 2.10 (circles), "
        "exact nearest point (ellipses).")
    add("")
    add(f"SMC model estimate used in the tables below: **{rep.smc_reading}** -- "
        f"{readings_cfg[rep.smc_reading]['description'].strip()}")
    add("")
    add("## Summary")
    add("")
    add("| rows | cells | median abs. deviation | within 1 % | within 5 % |")
    add("| --- | ---: | ---: | ---: | ---: |")
    for name, group in groups.items():
        s = summarize(group)
        add(f"| {name} | {s['cells']} | {_pct(s['median_abs_dev'])} | {_pct(s['within_1pct'])} | "
            f"{_pct(s['within_5pct'])} |")
    add("")
    read = [c for c in cells if c.ours_metric != c.metric]
    regained = [c for c in cells if (c.robot, c.contour, c.controller) in GAIN_READINGS]
    if read or regained:
        plain = summarize(c for c in as_defined(cells) if c.controller != "smc")
        add(f"With every statistic as defined in NOTES.md section 4 and every gain as printed "
            f"(no statistic or gain reading, below), the PD and PD-SMC rows give a median deviation "
            f"of {_pct(plain['median_abs_dev'])} and {_pct(plain['within_5pct'])} of cells within 5 %.")
        add("")
    add("By kind of statistic (all controllers):")
    add("")
    add("| statistic | cells | median abs. deviation | within 5 % |")
    add("| --- | ---: | ---: | ---: |")
    for name, pred in kinds.items():
        s = summarize(c for c in cells if pred(c))
        add(f"| {name} | {s['cells']} | {_pct(s['median_abs_dev'])} | {_pct(s['within_5pct'])} |")
    add("")
    add("What every cell shows (section *Every cell not reproduced* gives each one's evidence): "
        f"**reproduced** within {100 * REPRODUCED:g} %; **reading**, reproduced only under a reading the "
        "cells above do not use (the other payload reading, or the gains as printed and statistics as "
        "defined) that fits the cell's whole row no worse; **misprint**, the printed value repeats "
        "another printed statistic of its row, which ours reproduces; **infeasible**, a printed max "
        "torque below the torque the arm needs to follow the trajectory at all; **open**, the rest.")
    add("")
    add("| cells | count | " + " | ".join(VERDICTS) + " |")
    add("| --- | ---: |" + " ---: |" * len(VERDICTS))
    for name, group in verdict_groups(cells, verdicts).items():
        counts = count_verdicts(group)
        add(f"| {name} | {len(group)} | " + " | ".join(str(counts[k]) for k in VERDICTS) + " |")
    add("")
    if rep.readings:
        add("## SMC readings tried (nominal SMC rows, Tables 4.17-4.53)")
        add("")
        add("| reading | model estimate | cells | median abs. deviation | within 5 % |")
        add("| --- | --- | ---: | ---: | ---: |")
        for name, s in rep.readings.items():
            model = readings_cfg[name]["model"]
            desc = ", ".join(f"{k}={v:g}" for k, v in model.items())
            add(f"| {name} | {desc} | {s['cells']} | {_pct(s['median_abs_dev'])} | {_pct(s['within_5pct'])} |")
        add("")
        for name in rep.readings:
            add(f"- **{name}**: {readings_cfg[name]['description'].strip()}")
        add("")
    if read:
        add("## Statistic readings")
        add("")
        for (ctrl, metric), (ours_metric, why) in STATISTIC_READINGS.items():
            add(f"- **{LABEL[ctrl]} `{metric}` compared with our `{ours_metric}`.** {why}")
        add("")
        add("| robot | contour | controller | statistic | thesis | ours as read | dev | ours as defined | dev |")
        add("| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: |")
        for c, plain in zip(read, as_defined(read)):
            add(f"| {c.robot} | {c.contour} | {LABEL[c.controller]} | {c.metric} | {_fmt(c.thesis, c.metric)} | "
                f"{_fmt(c.ours, c.metric)} | {100 * c.deviation:+.1f} % | {_fmt(c.as_defined, c.metric)} | "
                f"{100 * plain.deviation:+.1f} % |")
        add("")
    if regained:
        add("## Gain readings")
        add("")
        for (robot, contour, ctrl), (gains, why) in GAIN_READINGS.items():
            printed_gains = preset_gains(robot, contour, ctrl).as_dict()
            change = "; ".join(f"{k} {printed_gains[k]} -> {v}" for k, v in gains.items())
            add(f"- **{robot} {contour} {LABEL[ctrl]}: {change}.** {why}")
        add("")
        add("| robot | contour | scenario | controller | statistic | thesis | ours, gains as read | dev | "
            "ours, gains as printed | dev |")
        add("| --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: |")
        for c, plain_cell in zip(regained, as_defined(regained)):
            add(f"| {c.robot} | {c.contour} | {c.scenario} | {LABEL[c.controller]} | {c.metric} | "
                f"{_fmt(c.thesis, c.metric)} | {_fmt(c.ours, c.metric)} | {100 * c.deviation:+.1f} % | "
                f"{_fmt(c.as_defined, c.metric)} | {100 * plain_cell.deviation:+.1f} % |")
        add("")
    lines += _payload_section(rep)
    lines += _torque_section(rep, verdicts)
    lines += _misprint_section(rep, verdicts)
    lines += _continuous_section(rep)
    add("## Every cell not reproduced")
    add("")
    add("| robot | contour | scenario | controller | statistic | thesis | ours | dev | verdict | evidence |")
    add("| --- | --- | --- | --- | --- | ---: | ---: | ---: | --- | --- |")
    for c, v in zip(cells, verdicts):
        if v.verdict != "reproduced":
            add(f"| {c.robot} | {c.contour} | {c.scenario} | {LABEL[c.controller]} | {c.metric} | "
                f"{_fmt(c.thesis, c.metric)} | {_fmt(c.ours, c.metric)} | {100 * c.deviation:+.1f} % | "
                f"{v.verdict} | {v.evidence} |")
    add("")
    add("## Largest deviations")
    add("")
    add("| robot | contour | scenario | controller | table | statistic | thesis | ours | deviation |")
    add("| --- | --- | --- | --- | --- | --- | ---: | ---: | ---: |")
    for c in sorted(cells, key=lambda c: -abs(c.deviation))[:25]:
        add(f"| {c.robot} | {c.contour} | {c.scenario} | {LABEL[c.controller]} | {c.table} | {c.metric} | "
            f"{_fmt(c.thesis, c.metric)} | {_fmt(c.ours, c.metric)} | {100 * c.deviation:+.1f} % |")
    add("")
    add("## Every table")
    thesis_tables = load_config("thesis_tables")
    by_run: dict[tuple[str, str, str], list[Cell]] = {}
    for c in cells:
        by_run.setdefault((c.robot, c.contour, c.scenario), []).append(c)
    for (robot, contour, scenario), group in by_run.items():
        entry = thesis_tables[robot][contour][scenario]
        names = ", ".join(f"{k} {v}" for k, v in entry["tables"].items())
        add("")
        add(f"### {robot} / {contour} / {scenario} (Tables: {names}; bound {entry['bound']:g} m)")
        if entry.get("notes"):
            add("")
            add(f"Note: {entry['notes']}")
        add("")
        add("| statistic | " + " | ".join(f"{LABEL[k]} thesis | {LABEL[k]} ours | dev" for k in CONTROLLER_NAMES) + " |")
        add("| --- |" + " ---: | ---: | ---: |" * len(CONTROLLER_NAMES))
        metrics = list(dict.fromkeys(c.metric for c in group))
        for metric in metrics:
            row = [metric]
            readers = [c for c in group if c.metric == metric and c.ours_metric != metric]
            if readers:
                row = [f"{metric} ({LABEL[readers[0].controller]}: vs `{readers[0].ours_metric}`, "
                       "see Statistic readings)"]
            for ctrl in CONTROLLER_NAMES:
                match = [c for c in group if c.controller == ctrl and c.metric == metric]
                if match:
                    c = match[0]
                    row += [_fmt(c.thesis, metric), _fmt(c.ours, metric), f"{100 * c.deviation:+.1f} %"]
                else:
                    row += ["", "", ""]
            add("| " + " | ".join(row) + " |")
    md = out / "REPRODUCTION.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    csv_path = out / "reproduction.csv"
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["robot", "contour", "scenario", "controller", "table", "statistic", "thesis", "ours",
                         "relative_deviation", "ours_statistic", "ours_as_defined", "verdict", "evidence"])
        for c, v in zip(cells, verdicts):
            writer.writerow([c.robot, c.contour, c.scenario, c.controller, c.table, c.metric, repr(c.thesis),
                             repr(c.ours), repr(c.deviation), c.ours_metric, repr(c.as_defined), v.verdict,
                             v.evidence])
    json_path = out / "reproduction.json"
    json_path.write_text(
        json.dumps(
            {
                "package_version": __version__,
                "smc_reading": rep.smc_reading,
                "wall_s": rep.wall_s,
                "summary": {name: summarize(group) for name, group in groups.items()},
                "summary_as_defined": {name: summarize(as_defined(group)) for name, group in groups.items()},
                "statistic_readings": {f"{ctrl}:{metric}": {"ours": ours, "why": why}
                                       for (ctrl, metric), (ours, why) in STATISTIC_READINGS.items()},
                "gain_readings": {"/".join(key): {"gains": gains, "why": why}
                                  for key, (gains, why) in GAIN_READINGS.items()},
                "smc_readings": rep.readings,
                "payload_reading": rep.payload_reading,
                "verdicts": {name: count_verdicts(group) for name, group in verdict_groups(cells, verdicts).items()},
                "needed_torque": rep.needed_torque,
                "continuous": rep.continuous,
                "payload_cells": {name: [dict(dataclasses.asdict(c), relative_deviation=c.deviation) for c in group]
                                  for name, group in rep.payload_cells.items()},
                "cells": [dict(dataclasses.asdict(c), relative_deviation=c.deviation, verdict=v.verdict,
                               evidence=v.evidence) for c, v in zip(cells, verdicts)],
                "runs": [r.as_dict() for r in rep.results],
            },
            indent=1,
        ),
        encoding="utf-8",
    )
    return {"markdown": md, "csv": csv_path, "json": json_path}


def _payload_section(rep: Reproduction) -> list[str]:
    """The payload scenario's cells under every payload reading, side by side."""
    if not rep.payload_cells:
        return []
    names = [rep.payload_reading, *rep.payload_cells]
    by_name = {rep.payload_reading: [c for c in rep.cells if c.scenario == "payload"], **rep.payload_cells}
    runs = {(rep.payload_reading, run_key(r.spec)): r for r in rep.results}
    runs.update({(name, run_key(r.spec)): r for name, group in rep.payload_results.items() for r in group})
    lines = ["## Payload readings (Section 4.5.2)", "",
             "The thesis says only that \"a simulated load of 1.5 kg was added at the end-effector\". "
             f"The cells above use the **{rep.payload_reading}** reading (`--payload-reading`); the readings:", ""]
    lines += [f"- **{name}**: {PAYLOAD_READINGS[name]}." for name in names]
    lines += ["", "| robot | contour | controller | statistic | thesis | "
              + " | ".join(f"ours, {n} | dev" for n in names) + " |",
              "| --- | --- | --- | --- | ---: |" + " ---: | ---: |" * len(names)]
    for i, c in enumerate(by_name[rep.payload_reading]):
        row = [c.robot, c.contour, LABEL[c.controller], c.metric, _fmt(c.thesis, c.metric)]
        for n in names:
            o = by_name[n][i]
            row += [_fmt(o.ours, o.metric), f"{100 * o.deviation:+.1f} %"]
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "Shape of the contour-error distribution: S.D./mean (the thesis's from its printed cells) and, "
              "for ours, median/mean (below 1: right-skewed). Where the thesis prints a mean below the bound "
              "with fewer than half of the samples within it, its median lies above the bound and so above "
              "its mean: a left-skewed distribution.", "",
              "| robot | controller | thesis S.D./mean | thesis median vs mean | "
              + " | ".join(f"{n} S.D./mean | {n} median/mean" for n in names) + " |",
              "| --- | --- | ---: | --- |" + " ---: | ---: |" * len(names)]
    rows: dict[tuple[str, str, str], dict[str, Cell]] = {}
    for c in by_name[rep.payload_reading]:
        rows.setdefault((c.robot, c.contour, c.controller), {})[c.metric] = c
    for (robot, contour, ctrl), cs in rows.items():
        mean, sd, within = cs["contour_mean"].thesis, cs["contour_sd"].thesis, cs["contour_within_pct"].thesis
        bound = load_config("thesis_tables")[robot][contour]["payload"]["bound"]
        skew = ("median > bound > mean (left-skewed)" if within < 50.0 and mean < bound
                else "median > bound" if within < 50.0 else "median <= bound")
        row = [robot, LABEL[ctrl], f"{sd / mean:.2f}", skew]
        for n in names:
            m = runs[(n, f"{robot}/{contour}/payload/{ctrl}")].metrics
            median = float(np.median(np.abs(runs[(n, f"{robot}/{contour}/payload/{ctrl}")].samples.contour_error)))
            row += [f"{m.contour_sd / m.contour_mean:.2f}", f"{median / m.contour_mean:.2f}"]
        lines.append("| " + " | ".join(row) + " |")
    lines.append("")
    return lines


def _torque_section(rep: Reproduction, verdicts: list[Verdict]) -> list[str]:
    """Printed max torques against the torque needed to follow the trajectory."""
    if not rep.needed_torque:
        return []
    torque = [(c, v) for c, v in zip(rep.cells, verdicts) if c.metric.startswith("max_torque")
              and f"{c.robot}/{c.contour}/{c.scenario}" in rep.needed_torque]
    close = [c for c, _ in torque if abs(c.ours / _needed(rep, c) - 1.0) <= 0.005]
    apart = "; ".join(f"{c.robot} {c.contour} {LABEL[c.controller]} joint {_joint(c.metric) + 1}: {c.ours:.4g} "
                      f"against {_needed(rep, c):.4g} N m (printed {c.thesis:.4g})"
                      for c, _ in torque if c not in close)
    lines = ["## Max torques against the torque needed to follow the trajectory", "",
             "Needed torque: Eq. (4.1) solved for the torque along the desired motion, "
             "tau = Mbar(q_d) qdd_d + C(q_d, qd_d) qd_d + G(q_d) + B qd_d, its max |tau| per joint over "
             "every control instant. A run that tracks the trajectory to the printed errors needs about "
             f"that torque: on {len(close)} of the {len(torque)} max-torque cells our run's max lies within "
             f"0.5 % of it{'; the others: ' + apart if apart else ''}. PD's torque is Kp e + Kd edot alone, so "
             "the feedback must supply it. A printed max below the needed torque (by more than our run's own "
             "gap to it) "
             "cannot come from a run that tracks the trajectory: **infeasible**. Where the printed max lies "
             "above, a peak the runs do not show would be needed; those cells stay open. The same rows' "
             "tracking errors are reproduced, so the max-torque column does not come from the runs that "
             "give the error columns.", "",
             "| robot | contour | controller | joint | printed | needed | ours | printed / needed | verdict |",
             "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |"]
    for c, v in torque:
        if v.verdict == "reproduced":
            continue
        need = _needed(rep, c)
        lines.append(f"| {c.robot} | {c.contour} | {LABEL[c.controller]} | {_joint(c.metric) + 1} | "
                     f"{c.thesis:.4g} | "
                     f"{need:.4g} | {c.ours:.4g} | {c.thesis / need:.3f} | {v.verdict} |")
    lines += ["", "(Cells within 5 % are left out.)", ""]
    return lines


def _needed(rep: Reproduction, c: Cell) -> float:
    return rep.needed_torque[f"{c.robot}/{c.contour}/{c.scenario}"][_joint(c.metric)]


def _misprint_section(rep: Reproduction, verdicts: list[Verdict]) -> list[str]:
    found = [(c, v) for c, v in zip(rep.cells, verdicts) if v.verdict == "misprint"]
    if not found:
        return []
    lines = ["## Misprints", "",
             "| robot | contour | controller | table | statistic | printed | ours | evidence |",
             "| --- | --- | --- | --- | --- | ---: | ---: | --- |"]
    for c, v in found:
        lines.append(f"| {c.robot} | {c.contour} | {LABEL[c.controller]} | {c.table} | {c.metric} | "
                     f"{_fmt(c.thesis, c.metric)} | {_fmt(c.ours, c.metric)} | {v.evidence} |")
    lines.append("")
    return lines


def _continuous_section(rep: Reproduction) -> list[str]:
    if not rep.continuous:
        return []
    names = list(rep.continuous)
    limit = rep.continuous[names[-1]]
    lines = ["## Discrete loop against the continuous-time limit", "",
             f"{'/'.join(CONTINUOUS_CASE)} (nominal): the same plant and control law with the law evaluated "
             f"continuously inside scipy's Radau solver (rtol 1e-10, atol 1e-12), against the discrete loop "
             "(zero-order hold, RK4) at its control rate and at 40 kHz. Relative deviation from the "
             "continuous-time limit:", "",
             "| solution | axial means | contour mean | contour S.D. | wall time |",
             "| --- | --- | ---: | ---: | ---: |"]
    for name in names:
        r = rep.continuous[name]
        if name == names[-1]:
            axial = ", ".join(f"{v:.6e}" for v in r["axial_mean"])
            lines.append(f"| {name} | {axial} rad | {r['contour_mean']:.6e} m | {r['contour_sd']:.6e} m | "
                         f"{r['wall_s']:.1f} s |")
            continue
        axial = ", ".join(f"{v / w - 1:+.2e}" for v, w in zip(r["axial_mean"], limit["axial_mean"]))
        lines.append(f"| {name} | {axial} | {r['contour_mean'] / limit['contour_mean'] - 1:+.2e} | "
                     f"{r['contour_sd'] / limit['contour_sd'] - 1:+.2e} | {r['wall_s']:.1f} s |")
    lines.append("")
    return lines
