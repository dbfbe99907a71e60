"""The ladder: the thesis's claims re-tested on the MuJoCo stand-in, one nuisance group at a time.

Chapter 5 of the thesis concludes that PD-SMC (1) contours better than PD, (2) is more robust than
SMC to unmodelled dynamics and (3) tracks comparably to SMC. It showed this on a perfect model.
The ladder re-runs every law on the stand-in (:mod:`pdsmc_ros.sim.mujoco_lockstep`) along
*rungs* (:data:`RUNGS`): the ideal arm, then each group of the ``bench`` preset's nuisances alone
on top of it (friction; encoder and velocity estimation; delay and torque lag; the unknown
payload), then all of them together (``bench``). A rung's nuisances take the values ``bench``
gives the arm (:func:`pdsmc_ros.sim.realism.bench_values`); the others are off.

Each rung is a Monte Carlo of the comparison's (:func:`pdsmc_ros.experiments.compare_mc.compare_plant`:
draw ``i`` draws its plant from ``default_rng([seed, i])`` and its nuisances' noise from
``[seed, i]``; every law on the same draw), and every column gets its mean and bootstrap 95 %
interval (:func:`pdsmc_ros.experiments.compare_mc.intervals`). The verdicts (:data:`CLAIMS`,
:func:`verdicts`) only compare those intervals: a claim *holds* where the intervals are apart in its
favour, *fails* where they are apart against it, and is *undecided* where they overlap.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ConfigError
from .bootstrap import Interval, bootstrap_mean
from .compare import Column, cell, columns
from .compare_mc import intervals, intervals_json

if TYPE_CHECKING:
    from ..runs.builder import RunSpec
    from ..sim.mujoco_lockstep import StandIn
    from .montecarlo import Spread


@dataclass(frozen=True)
class Rung:
    """One rung: its name, its label and the nuisances it turns on at their ``bench`` values
    (``None``: the ``bench`` preset itself, every nuisance)."""

    name: str
    label: str
    nuisances: tuple[str, ...] | None


RUNGS = (
    Rung("ideal", "ideal", ()),
    Rung("friction", "+ friction", ("friction_coulomb", "friction_viscous")),
    Rung("sensing", "+ encoder and velocity estimation",
         ("encoder_counts", "position_noise", "velocity_source", "velocity_filter_hz")),
    Rung("delay", "+ delay and torque lag", ("command_delay", "torque_bandwidth_hz")),
    Rung("payload", "+ unknown payload", ("payload_mass", "payload_com")),
    Rung("bench", "all together (bench)", None),
)
"""The rungs, in order. The torque-speed line of the motors is in ``bench`` only."""
RUNG_NAMES = tuple(r.name for r in RUNGS)

LAWS = ("pd", "smc", "pdsmc", "pdg", "ctc", "sta", "ismc")
"""The laws the ladder runs by default."""

COLUMN_KEYS = ("contour_mean", "contour_max", "error_rms", "torque_tv_rate", "torque_hf_share", "control_energy")
"""The columns the ladder reports (:func:`pdsmc_ros.experiments.compare.columns`' keys)."""


@dataclass(frozen=True)
class Claim:
    """One claim of Chapter 5: law ``law`` against law ``other`` on ``column``.

    ``kind``: ``lower`` (the law's mean is lower than the other's), ``robust`` (its contour error
    grows less from the ideal rung to this one, draw by draw), ``comparable`` (its mean is not
    higher than the other's: the intervals overlap or the law's lies below)."""

    name: str
    text: str
    law: str
    other: str
    column: str
    kind: str


CLAIMS = (
    Claim("contour", "PD-SMC contours better than PD (lower mean contour error)", "pdsmc", "pd", "contour_mean",
          "lower"),
    Claim("robust", "PD-SMC is more robust than SMC to unmodelled dynamics (its mean contour error grows less "
          "from the ideal rung, draw by draw)", "pdsmc", "smc", "contour_mean", "robust"),
    Claim("tracking", "PD-SMC tracks comparably to SMC (RMS tracking error not above SMC's)", "pdsmc", "smc",
          "error_rms", "comparable"),
)
"""The claims of the thesis's Chapter 5 the ladder tests."""

HOLDS, FAILS, UNDECIDED, NOT_APPLICABLE = "holds", "fails", "undecided", "n/a"


def ladder_columns(n: int) -> tuple[Column, ...]:
    """The comparison's columns (:func:`~.compare.columns`) the ladder reports, for ``n`` joints."""
    by_key = {c.key: c for c in columns(n)}
    return tuple(by_key[k] for k in COLUMN_KEYS)


def rung_stand_ins(robot: str, rate: float, rungs: Sequence[Rung], *, substeps: int = 1
                   ) -> dict[str, StandIn]:
    """Each rung's stand-in for ``robot`` at ``rate``: the ``ideal`` preset with the rung's nuisances
    at the values ``bench`` gives this arm (``bench`` itself for the last rung).

    Raises
    ------
    RealismError
        A nuisance ``bench`` cannot size for the arm (one line naming it).
    """
    from ..sim.mujoco_lockstep import StandIn

    _, bench, _ = StandIn(preset="bench", substeps=substeps).resolve(robot, rate)
    out = {}
    for rung in rungs:
        if rung.nuisances is None:
            out[rung.name] = StandIn(preset="bench", substeps=substeps)
        else:
            out[rung.name] = StandIn(preset="ideal", given={k: bench.value(k) for k in rung.nuisances},
                                     substeps=substeps)
    return out


def ladder_task(rung: str, index: int, seed: int, specs: Sequence[RunSpec], spreads: Mapping[str, Spread],
                stand_in: StandIn) -> list[dict[str, Any]]:
    """Draw ``index`` of rung ``rung``: :func:`~.compare_mc.compare_plant`'s rows, each naming the rung.
    A task of the engine (module level: workers import it)."""
    from .compare_mc import compare_plant

    return [{"rung": rung, **row} for row in compare_plant(index, seed, specs, spreads, stand_in)]


def run_ladder(specs: Sequence[RunSpec], spreads: Mapping[str, Spread], stand_ins: Mapping[str, StandIn],
               draws: int, seed: int, *, first: int = 0, scheduler: str | None = None, workers: int | None = None,
               progress: Callable[[], None] | None = None) -> list[dict[str, Any]]:
    """Draws ``first`` to ``first + draws - 1`` of every rung of ``stand_ins``, every law on each, on the
    engine's cluster (one task a rung and draw); the rows in rung, draw and law order."""
    from ..sim.engine import dask_client, run_tasks

    tasks = [(name, i, seed, specs, spreads, stand_in) for name, stand_in in stand_ins.items()
             for i in range(first, first + draws)]
    rows: list[dict[str, Any]] = []
    with dask_client(scheduler, workers) as client:
        for _, result in run_tasks(client, ladder_task, tasks):
            rows += result
            if progress:
                progress()
    return sort_rows(rows, list(stand_ins), [s.controller for s in specs])


def sort_rows(rows: Sequence[Mapping[str, Any]], rungs: Sequence[str], laws: Sequence[str]) -> list[dict[str, Any]]:
    """Rows in rung, draw and law order (the engine hands them back as they finish)."""
    return sorted((dict(r) for r in rows), key=lambda r: (rungs.index(r["rung"]), r["run"], laws.index(r["law"])))


def summarize(rows: Sequence[Mapping[str, Any]], rungs: Sequence[str], laws: Sequence[str],
              cols: Sequence[Column]) -> dict[str, dict[str, Any]]:
    """Per rung, :func:`~.compare_mc.intervals` of its rows."""
    return {rung: intervals([r for r in rows if r["rung"] == rung], laws, cols) for rung in rungs}


def degradation(rows: Sequence[Mapping[str, Any]], rung: str, law: str, column: str) -> Interval | None:
    """The mean over draws of ``law``'s ``column`` at ``rung`` over its value at the ideal rung in the
    same draw (the same plant and noise seed), with its bootstrap interval; None without a draw that
    ran at both rungs. A draw that diverged at ``rung`` only is left out here (counted in the summary)."""
    ideal = {r["run"]: float(r[column]) for r in rows
             if r["rung"] == "ideal" and r["law"] == law and r["status"] == "ok"}
    ratios = [float(r[column]) / ideal[r["run"]] for r in rows
              if r["rung"] == rung and r["law"] == law and r["status"] == "ok" and r["run"] in ideal
              and ideal[r["run"]] > 0]
    values = np.array([x for x in ratios if math.isfinite(x)])
    return bootstrap_mean(values) if values.size else None


@dataclass(frozen=True)
class Verdict:
    """A claim's verdict at one rung: ``holds``, ``fails``, ``undecided`` or ``n/a``, and why."""

    claim: str
    rung: str
    verdict: str
    law: Interval | None
    other: Interval | None
    why: str

    def as_dict(self) -> dict[str, Any]:
        return {"claim": self.claim, "rung": self.rung, "verdict": self.verdict, "why": self.why,
                "law": None if self.law is None else self.law.as_dict(),
                "other": None if self.other is None else self.other.as_dict()}


def compare_intervals(mine: Interval, theirs: Interval, kind: str) -> str:
    """The verdict of two intervals: ``lower``/``robust`` hold when ``mine`` lies wholly below,
    fail when wholly above, else undecided; ``comparable`` fails only when ``mine`` lies wholly above."""
    if mine.high < theirs.low:
        return HOLDS
    if mine.low > theirs.high:
        return FAILS
    return HOLDS if kind == "comparable" else UNDECIDED


def verdict(claim: Claim, rung: str, summary: Mapping[str, Mapping[str, Any]],
            rows: Sequence[Mapping[str, Any]]) -> Verdict:
    """``claim`` at ``rung`` from the ladder's summary and rows.

    A law that diverged or failed in every draw has no interval: if the other law did not, the claim
    fails (the law lost) or holds (the other lost); if both did, it is ``n/a``. The ``robust`` claim is
    ``n/a`` on the ideal rung (nothing is unmodelled beyond the drawn plant there).
    """
    entry = summary[rung]
    if claim.law not in entry or claim.other not in entry:
        return Verdict(claim.name, rung, NOT_APPLICABLE, None, None, "a law of the claim was not run")
    if claim.kind == "robust":
        if rung == "ideal":
            return Verdict(claim.name, rung, NOT_APPLICABLE, None, None, "the reference rung")
        if "ideal" not in summary:
            return Verdict(claim.name, rung, NOT_APPLICABLE, None, None, "the ideal rung (the reference) was not run")
        mine = degradation(rows, rung, claim.law, claim.column)
        theirs = degradation(rows, rung, claim.other, claim.column)
    else:
        mine = entry[claim.law]["columns"][claim.column]
        theirs = entry[claim.other]["columns"][claim.column]
    lost = {name: entry[name]["diverged"] + entry[name]["failed"] for name in (claim.law, claim.other)}
    if mine is None or theirs is None:
        if mine is None and theirs is None:
            return Verdict(claim.name, rung, NOT_APPLICABLE, None, None, "both laws diverged in every draw")
        if mine is None:
            return Verdict(claim.name, rung, FAILS, None, theirs, f"{claim.law} diverged in every draw")
        return Verdict(claim.name, rung, HOLDS, mine, None, f"{claim.other} diverged in every draw")
    result = compare_intervals(mine, theirs, claim.kind)
    why = "intervals apart" if result != UNDECIDED else "intervals overlap"
    if claim.kind == "comparable" and result == HOLDS and not mine.high < theirs.low:
        why = "intervals overlap"
    if lost[claim.law] or lost[claim.other]:
        why += f"; diverged or failed draws: {claim.law} {lost[claim.law]}, {claim.other} {lost[claim.other]}"
        if lost[claim.law] > lost[claim.other] and result == HOLDS and claim.kind != "comparable":
            result, why = UNDECIDED, why + f" ({claim.law} lost more draws)"
    return Verdict(claim.name, rung, result, mine, theirs, why)


def verdicts(summary: Mapping[str, Mapping[str, Any]], rows: Sequence[Mapping[str, Any]],
             rungs: Sequence[str]) -> list[Verdict]:
    """Every claim of :data:`CLAIMS` at every rung."""
    return [verdict(claim, rung, summary, rows) for claim in CLAIMS for rung in rungs]


def undecided_rungs(found: Sequence[Verdict]) -> list[str]:
    """The rungs where a claim is undecided (the ones more draws may decide), in order of first mention;
    with an undecided ``robust`` claim, the ideal rung too: that claim pairs each draw with the same
    draw at the ideal rung (:func:`degradation`), so more draws at its rung alone would add no pair."""
    robust = {claim.name for claim in CLAIMS if claim.kind == "robust"}
    out: list[str] = []
    for v in found:
        if v.verdict != UNDECIDED:
            continue
        for rung in (v.rung, "ideal") if v.claim in robust else (v.rung,):
            if rung not in out:
                out.append(rung)
    return out


def check_rungs(names: Sequence[str]) -> list[Rung]:
    """The rungs named, in the ladder's order.

    Raises
    ------
    ConfigError
        An unknown rung (one line naming the known ones).
    """
    unknown = [n for n in names if n not in RUNG_NAMES]
    if unknown:
        raise ConfigError(f"--rungs: unknown rung {unknown[0]!r}; known: {', '.join(RUNG_NAMES)}")
    return [r for r in RUNGS if r.name in names]


# --------------------------------------------------------------------------- #
# Outputs
# --------------------------------------------------------------------------- #
def ladder_json(meta: Mapping[str, Any], summary: Mapping[str, Mapping[str, Any]],
                found: Sequence[Verdict]) -> dict[str, Any]:
    """The ladder as plain data: the set-up, per rung the intervals, the verdicts."""
    return {**meta, "rungs_summary": {rung: intervals_json(entry) for rung, entry in summary.items()},
            "verdicts": [v.as_dict() for v in found]}


def _interval(interval: Interval | None, col: Column | None = None) -> str:
    if interval is None:
        return "-"
    if col is None:
        return f"{interval.mean:.3g} [{interval.low:.3g}, {interval.high:.3g}]"
    return f"{cell(interval.mean, col)} [{cell(interval.low, col)}, {cell(interval.high, col)}]"


def markdown(meta: Mapping[str, Any], summary: Mapping[str, Mapping[str, Any]], found: Sequence[Verdict],
             cols: Sequence[Column], labels: Mapping[str, str], figures: Sequence[str]) -> str:
    """The ladder's report: the command, the verdicts, then per rung the intervals of every law."""
    rungs = [r for r in RUNGS if r.name in summary]
    lines = [f"# Ladder: {meta['robot']} / {meta['contour']}", "",
             f"Command: `{meta['command']}`", "",
             (f"{meta['draws']} draws a rung (seed {meta['seed']}); plant spreads: {meta['uncertainty_text']}; "
              "each cell: mean [bootstrap 95 % interval] over the draws that did not diverge."), "",
             "## Verdicts", "", "| claim | " + " | ".join(r.label for r in rungs) + " |",
             "|---|" + "---|" * len(rungs)]
    for claim in CLAIMS:
        cells = []
        for rung in rungs:
            v = next(x for x in found if x.claim == claim.name and x.rung == rung.name)
            shown = f"**{v.verdict}**"
            if v.law is not None and v.other is not None:
                shown += f" {_interval(v.law)} vs {_interval(v.other)}"
            cells.append(shown)
        lines.append(f"| {claim.text} | " + " | ".join(cells) + " |")
    lines += ["", ("The robustness claim compares the ratio of each draw's mean contour error at the rung to the "
                   "same draw's at the ideal rung."), ""]
    laws = list(next(iter(summary.values())))
    for rung in rungs:
        entry = summary[rung.name]
        lines += [f"## {rung.label}", "", f"Plant: {meta['plants'][rung.name]}", "",
                  "| law | draws (diverged, failed) | " + " | ".join(f"{c.label} ({c.unit})" for c in cols) + " |",
                  "|---|---|" + "---|" * len(cols)]
        for name in laws:
            e = entry[name]
            lines.append(f"| {labels[name]} | {e['runs']} ({e['diverged']}, {e['failed']}) | "
                         + " | ".join(_interval(e["columns"][c.key], c) for c in cols) + " |")
        lines.append("")
    lines += [f"![{Path(f).stem}]({Path(f).name})" for f in figures]
    return "\n".join(lines) + "\n"


def plot_ladder(summary: Mapping[str, Mapping[str, Any]], cols: Sequence[Column], labels: Mapping[str, str],
                path: Path, title: str) -> Path:
    """A panel per column: each law's mean and 95 % interval at each rung (log scale where positive)."""
    from .plots import _pyplot, _save, controller_style

    plt = _pyplot()
    rungs = [r for r in RUNGS if r.name in summary]
    laws = list(next(iter(summary.values())))
    across = 3
    down = math.ceil(len(cols) / across)
    fig, axes = plt.subplots(down, across, figsize=(4.6 * across, 3.4 * down + 0.8), squeeze=False)
    x = np.arange(len(rungs))
    for ax, col in zip(axes.ravel(), cols):
        positive = True
        for k, name in enumerate(laws):
            _, colour, line = controller_style(name)
            found = [summary[r.name][name]["columns"][col.key] for r in rungs]
            mean = np.array([np.nan if i is None else i.mean for i in found])
            low = np.array([np.nan if i is None else i.low for i in found])
            high = np.array([np.nan if i is None else i.high for i in found])
            shift = (k - (len(laws) - 1) / 2) * 0.06
            ax.errorbar(x + shift, mean, yerr=[mean - low, high - mean], color=colour, linestyle=line, marker="o",
                        ms=3, lw=1.0, capsize=2, label=labels[name])
            finite = mean[np.isfinite(mean)]
            positive = positive and bool(finite.size == 0 or np.all(low[np.isfinite(low)] > 0))
        if positive:
            ax.set_yscale("log")
        ax.set_xticks(x, [r.name for r in rungs], rotation=30, ha="right", fontsize=8)
        ax.set_title(f"{col.label} ({col.unit})", fontsize=9)
    for ax in axes.ravel()[len(cols):]:
        ax.set_visible(False)
    axes.ravel()[0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def write_outputs(out: Path, meta: Mapping[str, Any], rows: Sequence[Mapping[str, Any]],
                  summary: Mapping[str, Mapping[str, Any]], found: Sequence[Verdict], cols: Sequence[Column],
                  labels: Mapping[str, str]) -> list[Path]:
    """``ladder.json``, ``ladder.csv`` (a row per rung, draw and law), ``ladder.png`` and ``ladder.md`` into ``out``."""
    import csv

    from .montecarlo import plain_cell

    out.mkdir(parents=True, exist_ok=True)
    data = out / "ladder.json"
    data.write_text(json.dumps(ladder_json(meta, summary, found), indent=2, sort_keys=True))
    table = out / "ladder.csv"
    keys: list[str] = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    with table.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys, restval="nan")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: plain_cell(v) for k, v in row.items()})
    figure = plot_ladder(summary, cols, labels, out / "ladder.png",
                         f"{meta['robot']}/{meta['contour']}: {meta['draws']} draws a rung")
    report = out / "ladder.md"
    report.write_text(markdown(meta, summary, found, cols, labels, [str(figure)]))
    return [data, table, figure, report]
