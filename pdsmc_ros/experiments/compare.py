"""Control laws side by side on one robot and contour: the runs and the table of ``pdsmc compare``.

Every registered law (:func:`pdsmc_ros.control.law_names`) can be compared; nothing here names
one. Each law runs the same reference at the same rate through the one run builder
(:func:`pdsmc_ros.runs.builder.make_run`) with its own gains: the presets of ``config/gains.yaml``
or a params file's (``pdsmc tune`` writes one). The table holds, per law, the thesis's error
statistics (contour error mean and maximum, each joint's mean ``|e|``; docs/THESIS_NOTES.md), the
scores of :mod:`pdsmc_ros.metrics.scores` (docs/SCORES.md) and the peak torque. In every column lower is
better; the best value of each column is marked. A law whose run diverges has no number in its
row: it shows ``DIVERGED`` and the reason.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..control import law
from ..errors import ConfigError, MissingGainsError
from ..metrics.scores import SCORE_NAMES
from ..metrics.statistics import Samples
from ..runs.builder import RunSpec, make_run, scenario_gain_factors, smc_reading
from ..sim import RunResult

if TYPE_CHECKING:
    from ..sim.mujoco_lockstep import StandIn

DIVERGED = "DIVERGED"


@dataclass(frozen=True)
class Column:
    """One column of the table: its key in a row's values, its heading and its units."""

    key: str
    label: str
    unit: str
    per_joint: bool = False


SCORE_COLUMNS = {"error_rms": ("RMS |e|", "rad"), "error_itae": ("ITAE", "rad s^2"),
                 "torque_tv_rate": ("TV/s", "N m/s"), "torque_hf_share": ("HF share", "1"),
                 "control_energy": ("energy", "N^2 m^2 s"), "torque_rate_peak": ("peak dtau/dt", "N m/s")}
"""Headings of the run scores (:data:`pdsmc_ros.metrics.scores.SCORE_NAMES`, docs/SCORES.md)."""


def columns(n: int) -> tuple[Column, ...]:
    """The table's columns for an arm of ``n`` actuated joints (lower is better in each)."""
    out = [Column("contour_mean", "contour mean", "m"), Column("contour_max", "contour max", "m")]
    out += [Column(f"axial_mean_{j + 1}", f"|e{j + 1}| mean", "rad", per_joint=True) for j in range(n)]
    out += [Column(name, *SCORE_COLUMNS[name]) for name in SCORE_NAMES]
    out.append(Column("peak_torque", "peak |tau|", "N m"))
    return tuple(out)


@dataclass(frozen=True)
class LawSpec:
    """A law's run in the comparison and where its gains came from."""

    spec: RunSpec
    source: str

    @property
    def name(self) -> str:
        return self.spec.controller

    @property
    def label(self) -> str:
        return law(self.spec.controller).label

    def gains(self) -> dict[str, list[float]]:
        """The gains the law uses (after the scenario's factors)."""
        return {k: list(v) for k, v in self.spec.gains.items() if k in law(self.spec.controller).gain_names}


@dataclass(frozen=True)
class LawRow:
    """One law's row: its values by column key, or None and why its run diverged."""

    law: str
    label: str
    values: dict[str, float] | None
    diverged: str = ""


def run_values(result: RunResult) -> dict[str, float] | None:
    """The table's values of one run (keys of :func:`columns`); None when it diverged (a
    non-finite state stopped it, :attr:`RunResult.diverged`) or a statistic is not finite."""
    if result.diverged:
        return None
    m = result.metrics
    scores = m.run_scores or {}
    values = {"contour_mean": m.contour_mean,
              "contour_max": float(np.max(np.abs(result.samples.contour_error))),
              **{f"axial_mean_{j + 1}": float(v) for j, v in enumerate(m.axial_mean)},
              **{name: float(scores.get(name, math.nan)) for name in SCORE_NAMES},
              "peak_torque": float(np.max(m.max_torque))}
    errors = [values["contour_mean"], values["contour_max"], *m.axial_mean]
    return values if all(math.isfinite(v) for v in errors) else None


def law_row(result: RunResult) -> LawRow:
    """The row of one law's run."""
    values = run_values(result)
    reason = result.diverged or ("" if values is not None else "non-finite statistics")
    return LawRow(result.spec.controller, law(result.spec.controller).label, values, reason)


def law_specs(robot: str, contour: str, laws: Sequence[str], *, scenario: str = "nominal",
              rate: float | None = None, reading: str = "literal",
              params_files: Mapping[str, str] | None = None, model: str | None = None) -> list[LawSpec]:
    """Each law's run on ``robot``/``contour`` at one rate, checked before anything runs.

    Parameters
    ----------
    laws : sequence of str
        Registered law names.
    reading : str
        The model-based laws' model estimate (``config/smc_readings.yaml``), as ``pdsmc simulate``.
    params_files : mapping, optional
        A params file per law name (its gains replace the presets, as ``--params-file`` does).
    model : str, optional
        The arm model the laws use (``--model``: :attr:`~pdsmc_ros.runs.builder.RunSpec.model`).

    Raises
    ------
    ConfigError
        An unknown law, robot, contour or scenario; a law with no gains for this arm and contour
        (naming it and how to give them); gains that cannot be stable at the rate.
    """
    from ..control.stability import check_rate
    from ..parameters.params_file import read_gains
    from ..robots import make_robot
    from ..robots.catalog import resolve_robot

    for name in laws:
        law(name)
    files = dict(params_files or {})
    out = []
    for name in laws:
        path = files.get(name)
        params = read_gains(path, make_robot(resolve_robot(robot)).n, name) if path else None
        try:
            spec = make_run(robot, contour, name, scenario=scenario, rate=rate, params=params,
                            smc_model=smc_reading(reading) if law(name).model_based else None, model=model)
        except MissingGainsError as exc:
            raise MissingGainsError(
                f"law {name} has no gains for {robot}/{contour} ({exc}); give them in a params file: "
                f"--params-file FILE (`pdsmc tune --robot {robot} --contour {contour} --controller {name}` "
                "writes one)") from None
        factors = scenario_gain_factors(scenario, name)
        source = f"params file {path}" if path else f"presets of config/gains.yaml for {robot}/{contour}"
        if factors:
            source += f", scaled by scenario {scenario} ({', '.join(f'{k} x{v:g}' for k, v in factors.items())})"
        out.append(LawSpec(spec, source))
    for entry in out:  # refuse gains unstable at the rate before any run
        check_rate(entry.spec, entry.spec.reference())
    return out


def run_laws(entries: Sequence[LawSpec], stand_in: StandIn | None = None) -> list[tuple[LawRow, Samples]]:
    """Each law's nominal run: its row and its samples (for the figures); ``stand_in``: against the
    MuJoCo stand-in (:func:`pdsmc_ros.sim.simulate`)."""
    from ..sim import simulate

    out = []
    for entry in entries:
        result = simulate(entry.spec, check_stability=False, stand_in=stand_in)
        out.append((law_row(result), result.samples))
    return out


def best_marks(rows: Sequence[LawRow], cols: Sequence[Column]) -> dict[str, list[str]]:
    """Per column key, the laws with its lowest value as the table prints it (:func:`cell`: laws
    equal to the printed digits are all marked; diverged rows and non-finite values never compete)."""
    out: dict[str, list[str]] = {}
    for col in cols:
        finite = {r.law: float(cell(r.values[col.key], col)) for r in rows
                  if r.values is not None and math.isfinite(r.values[col.key])}
        if finite:
            lowest = min(finite.values())
            out[col.key] = [name for name, v in finite.items() if v == lowest]
    return out


def cell(value: float, col: Column) -> str:
    """A value as the table prints it."""
    if not math.isfinite(value):
        return "n/a"
    if col.unit == "m" or col.unit == "rad":
        return f"{value:.3e}"
    return f"{value:.4g}"


def aligned(lines: Sequence[Sequence[str]]) -> str:
    """Plain-text columns: the first left-aligned, the others right-aligned."""
    widths = [max(len(line[i]) for line in lines) for i in range(len(lines[0]))]
    return "\n".join("  ".join(x.rjust(w) if i else x.ljust(w) for i, (x, w) in enumerate(zip(line, widths)))
                     for line in lines)


def text_table(rows: Sequence[LawRow], cols: Sequence[Column]) -> str:
    """The plain-text table: a row per law, ``*`` after the best of each column."""
    best = best_marks(rows, cols)
    heads = ["law", *(f"{c.label} ({c.unit})" for c in cols)]
    body = []
    for r in rows:
        if r.values is None:
            body.append([r.label, DIVERGED, *("-" for _ in cols[1:])])
        else:
            body.append([r.label, *(cell(r.values[c.key], c) + ("*" if r.law in best.get(c.key, ()) else " ")
                                    for c in cols)])
    lines = [aligned([heads, *body]), "* the best of the column; lower is better in every column"]
    lines += [f"{r.label}: {DIVERGED}: {r.diverged}" for r in rows if r.values is None]
    return "\n".join(lines)


def setup_description(entries: Sequence[LawSpec]) -> dict[str, Any]:
    """The set-up shared by every law's run (robot, contour, rate ...) and each law's gains."""
    d = entries[0].spec.describe()
    keys = ("robot", "contour", "scenario", "control_rate_hz", "sample_rate_hz", "duration_s", "payload_kg",
            "contour_bound_m", "enforce_limits")
    return {**{k: d[k] for k in keys},
            "laws": [{"law": e.name, "label": e.label, "equation": law(e.name).equation, "gains": e.gains(),
                      "source": e.source} for e in entries]}


def table_json(rows: Sequence[LawRow], cols: Sequence[Column]) -> dict[str, Any]:
    """The table as plain data: columns, a row per law (``values`` null when it diverged), the best."""
    best = best_marks(rows, cols)
    return {"columns": [{"key": c.key, "label": c.label, "unit": c.unit} for c in cols],
            "lower_is_better": True,
            "rows": [{"law": r.law, "label": r.label, "diverged": r.diverged, "values": r.values,
                      "best": [c.key for c in cols if r.law in best.get(c.key, ())]} for r in rows]}


def params_by_law(paths: Sequence[str], laws: Sequence[str]) -> dict[str, str]:
    """The law each params file holds gains for (its ``type``), one file per law of ``laws``.

    Raises
    ------
    ConfigError
        A file without ``type``, for a law not compared, or two files for one law.
    """
    from ..parameters.params_file import controller_values

    out: dict[str, str] = {}
    for path in paths:
        name = controller_values(path).get("type")
        if name not in laws:
            raise ConfigError(f"params file {path!r} holds gains for type {name!r}; --laws is {','.join(laws)}: "
                              "name the law there (or set type: in the file)")
        if name in out:
            raise ConfigError(f"params files {out[name]!r} and {path!r} both hold gains for {name}: give one")
        out[str(name)] = path
    return out
