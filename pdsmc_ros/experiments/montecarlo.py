"""Robustness Monte Carlo: the controllers against a spread of plausible plants (ROS-free).

The thesis tests robustness with four hand-picked scenarios (Section 4.5). Here the
simulated plant's parameters -- link masses, centres of mass and inertias, motor J and B,
a payload, the initial state -- are drawn from the distributions of an uncertainty file
(``config/uncertainty.yaml``: the documented defaults) while every controller keeps the
nominal model. Run ``i`` draws from ``numpy.random.default_rng([seed, i])``, and all
controllers run on the same draw (common random numbers), so a table depends on the seed
alone -- not on the engine, the number of workers or the order runs finish in.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..checks import is_real
from ..config import load_config, read_yaml
from ..errors import ConfigError
from ..metrics.scores import SCORE_NAMES
from ..robots import make_robot, robot_params
from ..robots.base import RobotParams
from ..runs.builder import RunSpec, make_run

if TYPE_CHECKING:
    from ..sim.mujoco_lockstep import StandIn

PARAMETERS = ("link_mass", "link_com", "link_inertia", "motor_inertia", "motor_damping", "payload",
              "initial_error")
DISTRIBUTIONS = ("uniform", "normal")
PERCENTILES = (5, 50, 95)


@dataclass(frozen=True)
class Spread:
    """One varied parameter: ``distribution`` and its ``relative`` spread, ``low``/``high`` (payload)
    or ``sd`` (initial error)."""

    distribution: str
    relative: float = 0.0
    low: float = 0.0
    high: float = 0.0
    sd: float = 0.0


def load_uncertainty(path: str | Path | None = None, default: str = "uncertainty") -> dict[str, Spread]:
    """The spreads of ``path`` (YAML), or the defaults of ``config/<default>.yaml``
    (``config/uncertainty.yaml``; the ladder's: ``config/ladder_uncertainty.yaml``).

    Raises
    ------
    ConfigError
        One line naming the file and entry: an unknown parameter or key, an unknown distribution,
        a negative or non-finite spread, ``low > high``.
    """
    where = f"config/{default}.yaml"
    if path is None:
        data = load_config(default)
    else:
        where = str(path)
        data = read_yaml(path, f"--uncertainty {where!r}")
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping of parameters ({', '.join(PARAMETERS)})")
    spreads = {}
    for name, entry in data.items():
        if name not in PARAMETERS:
            raise ConfigError(f"{where}: unknown parameter {name!r}; allowed: {', '.join(PARAMETERS)}")
        if not isinstance(entry, Mapping):
            raise ConfigError(f"{where}: {name} must be a mapping like {{distribution: uniform, relative: 0.1}}")
        unknown = sorted(set(entry) - {"distribution", "relative", "low", "high", "sd"})
        if unknown:
            raise ConfigError(f"{where}: {name}: unknown key(s) {unknown}; allowed: distribution, relative, low, "
                              "high, sd")
        distribution = entry.get("distribution", "uniform")
        if distribution not in DISTRIBUTIONS:
            raise ConfigError(f"{where}: {name}: distribution must be one of {', '.join(DISTRIBUTIONS)}, "
                              f"got {distribution!r}")
        values = {}
        for key in ("relative", "low", "high", "sd"):
            value = entry.get(key, 0.0)
            if not is_real(value) or not math.isfinite(value):
                raise ConfigError(f"{where}: {name}.{key} must be a finite number, got {value!r}")
            if value < 0.0:
                raise ConfigError(f"{where}: {name}.{key} must be >= 0 (a spread), got {value!r}")
            values[key] = float(value)
        if values["low"] > values["high"]:
            raise ConfigError(f"{where}: {name}: low {values['low']:g} > high {values['high']:g}")
        if name != "payload" and (values["low"] or values["high"]):
            raise ConfigError(f"{where}: {name}: low/high are for the payload; use relative (or sd)")
        spreads[name] = Spread(distribution, **values)
    return spreads


def _factor(rng: np.random.Generator, spread: Spread | None, size: int) -> np.ndarray:
    if spread is None or spread.relative == 0.0:
        return np.ones(size)
    if spread.distribution == "uniform":
        return rng.uniform(1.0 - spread.relative, 1.0 + spread.relative, size)
    return np.maximum(rng.normal(1.0, spread.relative, size), 1e-3)


LINK_PARAMETERS = tuple(name for name in PARAMETERS if name != "initial_error")
"""The spreads that need the arm's link and motor parameters (the thesis arms')."""


def sample_plant(robot: str, spreads: Mapping[str, Spread], rng: np.random.Generator
                 ) -> tuple[RobotParams | None, float, np.ndarray, dict[str, float]]:
    """One plant drawn around ``robot``'s nominal parameters: ``(params, payload, initial_error,
    drawn values by column name)``. The draws come in a fixed order, so a seed fixes them all.

    An arm without link parameters of its own (a URDF arm) draws its initial error only: ``params``
    is None (the arm's own).

    Raises
    ------
    ConfigError
        A URDF arm with a spread of its links, motors or payload (:data:`LINK_PARAMETERS`).
    """
    from ..robots.catalog import resolve_robot

    robot = resolve_robot(robot)  # an arm of example-robot-data: registered in this process (a Dask worker's too)
    arm = make_robot(robot)
    if not arm.has_link_params:
        spread_out = [name for name in LINK_PARAMETERS if name in spreads
                      and (spreads[name].relative or spreads[name].low or spreads[name].high)]
        if spread_out:
            raise ConfigError(f"{robot!r} is a URDF arm: only initial_error can be drawn on it (its link and motor "
                              f"parameters are not varied yet); the spreads vary {spread_out[0]}")
        spread = spreads.get("initial_error")
        initial = rng.normal(0.0, spread.sd, arm.n) if spread is not None and spread.sd else np.zeros(arm.n)
        return None, 0.0, initial, {f"initial_error_{j + 1}": float(initial[j]) for j in range(arm.n)}
    nominal = robot_params(robot)
    links = nominal.links
    k = len(links)
    mass = _factor(rng, spreads.get("link_mass"), k)
    com = _factor(rng, spreads.get("link_com"), k)
    inertia = _factor(rng, spreads.get("link_inertia"), k)
    motor_j = float(_factor(rng, spreads.get("motor_inertia"), 1)[0])
    motor_b = float(_factor(rng, spreads.get("motor_damping"), 1)[0])
    payload_spread = spreads.get("payload")
    payload = float(rng.uniform(payload_spread.low, payload_spread.high)) if payload_spread is not None else 0.0
    n = arm.n
    error_spread = spreads.get("initial_error")
    initial = rng.normal(0.0, error_spread.sd, n) if error_spread is not None and error_spread.sd else np.zeros(n)
    # plain floats: a description written from them (the stand-in's URDF) must read "0.1", not "np.float64(0.1)"
    varied = tuple(dataclasses.replace(link, mass=float(link.mass * mass[i]),
                                       com=float(min(link.com * com[i], link.length)),
                                       inertia=float(link.inertia * inertia[i])) for i, link in enumerate(links))
    params = dataclasses.replace(nominal, links=varied, motor_inertia=float(nominal.motor_inertia * motor_j),
                                 motor_damping=float(nominal.motor_damping * motor_b))
    drawn = {f"link{i + 1}_mass": varied[i].mass for i in range(k)}
    drawn.update({f"link{i + 1}_com": varied[i].com for i in range(k)})
    drawn.update({f"link{i + 1}_inertia": varied[i].inertia for i in range(k)})
    drawn.update({"motor_inertia": params.motor_inertia, "motor_damping": params.motor_damping, "payload": payload})
    drawn.update({f"initial_error_{j + 1}": float(initial[j]) for j in range(n)})
    return params, payload, initial, drawn


def flat_statistics(metrics: Mapping[str, Any]) -> dict[str, float]:
    """``simulate --json``'s statistics as columns (lists numbered from 1, dicts by key)."""
    out: dict[str, float] = {}
    for key, value in metrics.items():
        if isinstance(value, list):
            out.update({f"{key}_{i + 1}": float(v) for i, v in enumerate(value)})
        elif isinstance(value, dict):
            out.update({f"{key}_{k}": float(v) for k, v in value.items()})
        else:
            out[key] = float(value)
    return out


def run_sample(index: int, seed: int, specs: Sequence[RunSpec], spreads: Mapping[str, Spread],
               stand_in: StandIn | None = None) -> list[dict[str, Any]]:
    """Run ``index`` of the Monte Carlo: one drawn plant, every controller of ``specs`` on it
    (``stand_in``: the drawn plant is the MuJoCo stand-in's, its nuisances' draws seeded by
    ``[seed, index]``).

    A task of the engine (module level: workers import it). A run that diverges or fails
    gives a row with the reason and NaN statistics instead of stopping the table.
    """
    from ..sim import simulate  # numba: in the worker

    robot = specs[0].robot
    params, payload, initial, drawn = sample_plant(robot, spreads, np.random.default_rng([seed, index]))
    plant = make_robot(robot, payload=payload, params=params)
    mine = None if stand_in is None else stand_in.for_run(seed, index)
    rows = []
    for spec in specs:
        row: dict[str, Any] = {"run": index, "controller": spec.controller, **drawn}
        try:
            result = simulate(spec, check_stability=False, plant=plant, initial_error=initial, stand_in=mine)
            stats = flat_statistics(result.metrics.as_dict())
            row["status"] = "ok" if math.isfinite(stats["contour_mean"]) else "diverged"
        except (ValueError, ArithmeticError) as exc:
            stats, row["status"] = {}, f"failed: {str(exc).splitlines()[0]}"
        row.update(stats)
        rows.append(row)
    return rows


def base_specs(robot: str, contour: str, controllers: Sequence[str], **options: Any) -> list[RunSpec]:
    """The nominal run of each controller (presets, its own gains).

    Raises
    ------
    ConfigError
        For an arm whose parameters cannot be drawn (a URDF arm) or an unknown name.
    """
    specs = [make_run(robot, contour, controller, **options) for controller in controllers]
    if not make_robot(specs[0].robot).has_link_params:
        raise ConfigError(f"montecarlo draws the thesis arms' link and motor parameters; {robot!r} is a URDF "
                          "arm (not supported yet): use serial_3r or parallel_5r")
    return specs


def summarize(rows: Sequence[Mapping[str, Any]], controllers: Sequence[str], bound: float) -> dict[str, Any]:
    """Per controller: mean, p5, p50, p95 and worst of the runs' mean contour error, the share
    of runs whose mean contour error is within the bound (runs that failed count as outside), and
    the mean of each run score (``<score>_mean``: :data:`pdsmc_ros.metrics.scores.SCORE_NAMES`).

    The rows are taken in run order whatever order they come in (the engine hands them back as
    they finish): a sum's last digit depends on its order, and the summary depends on the seed alone.
    """
    rows = sorted(rows, key=lambda r: r["run"])
    out: dict[str, Any] = {}
    for controller in controllers:
        values = np.array([float(r.get("contour_mean", math.nan)) for r in rows if r["controller"] == controller])
        finite = values[np.isfinite(values)]
        entry: dict[str, Any] = {"runs": int(values.size), "failed": int(values.size - finite.size)}
        if finite.size:
            entry.update({"contour_mean_mean": float(np.mean(finite)),
                          **{f"contour_mean_p{p}": float(np.percentile(finite, p)) for p in PERCENTILES},
                          "contour_mean_worst": float(np.max(finite)),
                          "share_within_bound": float(np.sum(finite <= bound) / values.size)})
        for name in SCORE_NAMES:  # the run scores' mean over the runs that have them (docs/SCORES.md)
            scores = np.array([float(r.get(f"run_scores_{name}", math.nan)) for r in rows
                               if r["controller"] == controller])
            scores = scores[np.isfinite(scores)]
            if scores.size:
                entry[f"{name}_mean"] = float(np.mean(scores))
        out[controller] = entry
    return out


def plain_cell(value: Any) -> Any:
    """A CSV cell as a plain number or word: floats (numpy's too) by their shortest round-trip
    ``repr`` (``0.7591762968402793``, ``nan``), numpy integers as ``int``; under numpy 2 the
    ``repr`` of a numpy scalar is ``np.float64(0.759...)``, which a CSV reader takes for text."""
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, np.integer):
        return int(value)
    return value


def write_outputs(rows: Sequence[Mapping[str, Any]], summary: Mapping[str, Any], meta: Mapping[str, Any],
                  out: Path) -> list[Path]:
    """``montecarlo.csv`` (a row per run and controller, in run order), ``montecarlo.json``."""
    out.mkdir(parents=True, exist_ok=True)
    ordered = sorted(rows, key=lambda r: (r["run"], list(meta["controllers"]).index(r["controller"])))
    columns: list[str] = []
    for row in ordered:
        columns += [c for c in row if c not in columns]
    table = out / "montecarlo.csv"
    with table.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, restval="nan")
        writer.writeheader()
        for row in ordered:
            writer.writerow({k: plain_cell(v) for k, v in row.items()})
    report = out / "montecarlo.json"
    report.write_text(json.dumps({**meta, "controllers_summary": summary}, indent=2, sort_keys=True))
    return [table, report]


def plot_distribution(rows: Sequence[Mapping[str, Any]], controllers: Sequence[str], bound: float,
                      path: Path, title: str) -> Path:
    """Distribution of the runs' mean contour error, every controller on one axes."""
    from .plots import _pyplot, _save, controller_style

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    values = {c: np.array([float(r.get("contour_mean", math.nan)) for r in rows if r["controller"] == c])
              for c in controllers}
    finite = np.concatenate([v[np.isfinite(v)] for v in values.values()] or [np.zeros(1)])
    if finite.size and np.max(finite) > 0:
        bins = np.geomspace(max(np.min(finite[finite > 0]), 1e-12), np.max(finite), 40) if np.all(finite > 0) \
            else 40
        for controller, v in values.items():
            label, colour, _ = controller_style(controller)
            ax.hist(v[np.isfinite(v)], bins=bins, histtype="step", lw=1.4, color=colour, label=label)
        if np.all(finite > 0):
            ax.set_xscale("log")
    if bound > 0:
        ax.axvline(bound, color="k", linestyle=":", lw=0.9, label=f"bound {bound:g} m")
    ax.set_xlabel("mean contour error of a run (m)")
    ax.set_ylabel("runs")
    ax.set_title(title)
    ax.legend(fontsize=8)
    return _save(fig, path)
