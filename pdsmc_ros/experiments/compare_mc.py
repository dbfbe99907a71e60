"""The comparison's Monte Carlo: every law against the same drawn plants, with bootstrap intervals.

The plants are :mod:`pdsmc_ros.experiments.montecarlo`'s (:func:`~pdsmc_ros.experiments.montecarlo.sample_plant`: run
``i`` draws from ``default_rng([seed, i])``, so ``pdsmc compare --runs N --seed K`` draws the
plants of ``pdsmc montecarlo --runs N --seed K``) and every law runs on each (common random
numbers); the runs go through the one engine (:mod:`pdsmc_ros.sim.engine`, Dask). Each column of
the table gets its mean over the runs that did not diverge and a percentile-bootstrap 95 %
confidence interval of that mean (:mod:`.bootstrap`); runs that diverged are counted, never
averaged.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..runs.builder import RunSpec
from .bootstrap import Interval, bootstrap_mean
from .compare import Column, cell
from .montecarlo import Spread


def compare_plant(index: int, seed: int, specs: Sequence[RunSpec], spreads: Mapping[str, Spread]
                  ) -> list[dict[str, Any]]:
    """Run ``index``: one drawn plant, every law of ``specs`` on it; a row per law with the
    table's values (:func:`.compare.run_values`) and its ``status`` (``ok``, ``diverged`` or
    ``failed: ...``). A task of the engine (module level: workers import it)."""
    from ..robots import make_robot
    from ..sim import simulate
    from .compare import run_values
    from .montecarlo import sample_plant

    params, payload, initial, _ = sample_plant(specs[0].robot, spreads, np.random.default_rng([seed, index]))
    plant = make_robot(specs[0].robot, payload=payload, params=params)
    rows: list[dict[str, Any]] = []
    for spec in specs:
        row: dict[str, Any] = {"run": index, "law": spec.controller}
        try:
            values = run_values(simulate(spec, check_stability=False, plant=plant, initial_error=initial))
        except (ValueError, ArithmeticError) as exc:
            rows.append({**row, "status": f"failed: {str(exc).splitlines()[0]}"})
            continue
        rows.append({**row, "status": "ok" if values is not None else "diverged", **(values or {})})
    return rows


def run_plants(specs: Sequence[RunSpec], spreads: Mapping[str, Spread], runs: int, seed: int, *,
               scheduler: str | None = None, workers: int | None = None,
               progress: Callable[[], None] | None = None) -> list[dict[str, Any]]:
    """Every law on ``runs`` drawn plants, on the engine's cluster; the rows in run order."""
    from ..sim.engine import dask_client, run_tasks

    rows: list[dict[str, Any]] = []
    with dask_client(scheduler, workers) as client:
        for _, result in run_tasks(client, compare_plant, [(i, seed, specs, spreads) for i in range(runs)]):
            rows += result
            if progress:
                progress()
    return sorted(rows, key=lambda r: (r["run"], [s.controller for s in specs].index(r["law"])))


def intervals(rows: Sequence[Mapping[str, Any]], laws: Sequence[str], cols: Sequence[Column]
              ) -> dict[str, dict[str, Any]]:
    """Per law: runs, runs that diverged or failed, and per column the mean of the runs that did
    not with its bootstrap interval (None when no run is left)."""
    out: dict[str, dict[str, Any]] = {}
    for name in laws:
        mine = [r for r in rows if r["law"] == name]
        ok = [r for r in mine if r["status"] == "ok"]
        entry: dict[str, Any] = {"runs": len(mine), "diverged": sum(r["status"] == "diverged" for r in mine),
                                 "failed": sum(r["status"].startswith("failed") for r in mine), "columns": {}}
        for col in cols:
            values = np.array([float(r[col.key]) for r in ok])
            values = values[np.isfinite(values)]
            entry["columns"][col.key] = bootstrap_mean(values) if values.size else None
        out[name] = entry
    return out


def intervals_json(summary: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """:func:`intervals` as plain data."""
    return {name: {**{k: v for k, v in entry.items() if k != "columns"},
                   "columns": {k: (i.as_dict() if isinstance(i, Interval) else None)
                               for k, i in entry["columns"].items()}}
            for name, entry in summary.items()}


def interval_text(interval: Interval | None, col: Column) -> str:
    """``mean [low, high]`` as the table prints ``col``'s values, or ``-`` for no run."""
    if interval is None:
        return "-"
    return f"{cell(interval.mean, col)} [{cell(interval.low, col)}, {cell(interval.high, col)}]"


def interval_rows(summary: Mapping[str, Mapping[str, Any]], labels: Mapping[str, str], cols: Sequence[Column]
                  ) -> tuple[list[str], list[list[str]]]:
    """The intervals' table (:func:`intervals`): a heading per law, a row of runs, a row per column."""
    head = [*(labels[name] for name in summary)]
    body = [["runs (diverged, failed)", *(f"{e['runs']} ({e['diverged']}, {e['failed']})" for e in summary.values())]]
    body += [[f"{c.label} ({c.unit})", *(interval_text(e["columns"][c.key], c) for e in summary.values())]
             for c in cols]
    return head, body


def plot_distributions(rows: Sequence[Mapping[str, Any]], laws: Sequence[str], labels: Mapping[str, str],
                       cols: Sequence[Column], path: Path, title: str) -> Path:
    """A box per law (median, quartiles, whiskers at 1.5 IQR, the mean as a triangle) of every
    column's values over the runs that did not diverge, a panel per column."""
    from .plots import _pyplot, _save

    plt = _pyplot()
    shown = [c for c in cols if not c.per_joint]
    across = 4
    down = math.ceil(len(shown) / across)
    fig, axes = plt.subplots(down, across, figsize=(3.2 * across, 2.8 * down + 0.6), squeeze=False)
    for ax, col in zip(axes.ravel(), shown):
        data = [np.array([float(r[col.key]) for r in rows if r["law"] == name and r["status"] == "ok"])
                for name in laws]
        data = [d[np.isfinite(d)] for d in data]
        ax.boxplot([d if d.size else [math.nan] for d in data], showmeans=True)
        ax.set_xticks(range(1, len(laws) + 1), [labels[name] for name in laws], rotation=30, ha="right", fontsize=8)
        ax.set_title(f"{col.label} ({col.unit})", fontsize=9)
        if all(d.size and np.all(d > 0) for d in data) and max(np.max(d) for d in data) > 20 * min(
                np.min(d) for d in data):
            ax.set_yscale("log")
    for ax in axes.ravel()[len(shown):]:
        ax.set_visible(False)
    fig.suptitle(title)
    return _save(fig, path)
