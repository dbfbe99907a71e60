"""``pdsmc compare``: control laws side by side on one robot and contour (:mod:`pdsmc_ros.experiments`).

``pdsmc compare --robot R --contour C --laws pd,smc,pdsmc[,...] [--scenario S] [--rate HZ]
[--runs N [--uncertainty FILE] --seed K --workers W] [--out DIR] [--format md|html] [--json]``

Prints one table (a row per law: errors, scores and peak torque, the best of each column marked,
lower is better) or, with ``--json``, one JSON object. With ``--out`` it writes the thesis-style
figures of every law on one axes, ``compare.md`` (``compare.html`` with ``--format html``) and
``compare.json``. With ``--runs N`` every law also runs on ``N`` plants drawn as ``pdsmc
montecarlo`` draws them, and each column gets its mean and a bootstrap 95 % interval.

Bad input (an unknown law, robot, contour or scenario, a law without gains for this arm and
contour, gains unstable at the rate, a bad ``--uncertainty`` file, ``--out`` a file) is one line
and exit 2, before anything runs or is written. A law whose nominal run diverges shows
``DIVERGED`` in its row, and the exit status is 1, as ``pdsmc simulate``'s.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError, InvalidInputError
from .options import add_model_argument, name_list, positive_float, run_count, seed_value, worker_count
from .stand_in import add_stand_in_arguments, describe_plant, stand_in_from_args

if TYPE_CHECKING:
    from ..experiments.compare import Column, LawRow, LawSpec
    from ..experiments.montecarlo import Spread
    from ..metrics.statistics import Samples

EXIT_DIVERGED = 1


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``compare`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("compare", help="control laws side by side: one table, figures, a report (and a Monte Carlo)")
    p.add_argument("--robot", required=True,
                   help="serial_3r, parallel_5r, an arm of example-robot-data (ur5, panda, ...) or a .urdf file")
    p.add_argument("--contour", required=True, help="a contour of the robot: circle, zigzag, ...")
    p.add_argument("--laws", type=name_list, required=True,
                   help="comma-separated registered control laws, e.g. pd,smc,pdsmc")
    p.add_argument("--scenario", default="nominal", help="nominal, high_speed, payload, high_pd, high_smc")
    p.add_argument("--rate", type=positive_float, default=None, help="control rate in Hz (default: the robot's)")
    p.add_argument("--smc-reading", default="literal",
                   help="model estimate of the model-based laws, config/smc_readings.yaml (default: literal)")
    p.add_argument("--params-file", action="append", default=None, metavar="FILE",
                   help="gains of the file's law (its type:) from a ROS 2 params file (pdsmc tune writes one); "
                   "repeat for other laws; the others use config/gains.yaml's presets")
    add_model_argument(p)
    p.add_argument("--runs", type=run_count, default=None, help="also run every law on this many drawn plants")
    p.add_argument("--uncertainty", default=None,
                   help="with --runs: YAML of parameter spreads (default: config/uncertainty.yaml)")
    p.add_argument("--seed", type=seed_value, default=0, help="with --runs: run i draws from default_rng([seed, i]); "
                   "with --plant mujoco also the seed of the nuisances' draws")
    p.add_argument("--workers", type=worker_count, default=None, help="with --runs: local cluster processes")
    p.add_argument("--scheduler", default=None, help="with --runs: a Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--out", default=None, help="write the figures and compare.md/.json into this directory")
    p.add_argument("--format", choices=("md", "html"), default=None,
                   help="with --out: the report as compare.md (default) or also as a self-contained compare.html")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    add_stand_in_arguments(p, seed=False)
    commands["compare"] = run


def check_arguments(args: argparse.Namespace) -> Path | None:
    """The flags that only make sense together, and ``--out``; the output directory (not created)."""
    if args.runs is None:
        for flag, value in (("--uncertainty", args.uncertainty), ("--workers", args.workers),
                            ("--scheduler", args.scheduler)):
            if value is not None:
                raise InvalidInputError(f"{flag} is for the Monte Carlo: give --runs N with it")
    if args.format is not None and args.out is None:
        raise InvalidInputError(f"--format {args.format} writes a report: give --out DIR with it")
    if args.out is None:
        return None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {args.out!r} is a file: give a directory")
    return out


def run(args: argparse.Namespace) -> int:
    """The command: check everything, run, print, then write (nothing is written on bad input)."""
    from ..control import law
    from ..experiments.compare import (
        columns,
        law_specs,
        params_by_law,
        run_laws,
        setup_description,
        table_json,
        text_table,
    )

    out = check_arguments(args)
    for name in args.laws:
        law(name)
    files = params_by_law(args.params_file or [], args.laws)
    entries = law_specs(args.robot, args.contour, args.laws, scenario=args.scenario, rate=args.rate,
                        reading=args.smc_reading, params_files=files, model=args.model)
    spreads = _check_montecarlo(args, entries) if args.runs else None
    stand_in = stand_in_from_args(args, seed=args.seed)
    plant = describe_plant(stand_in, entries[0].spec.robot, entries[0].spec.rate)  # a bad nuisance: before any run
    runs = run_laws(entries, stand_in)
    rows = [row for row, _ in runs]
    cols = columns(entries[0].spec.gains.n)
    mc: dict[str, Any] | None = None
    mc_rows = None
    if spreads is not None:
        from ..experiments.compare_mc import intervals, run_plants
        from ..sim.engine import Progress

        progress = Progress(args.runs, "compare")
        mc_rows = run_plants([e.spec for e in entries], spreads, args.runs, args.seed, scheduler=args.scheduler,
                             workers=args.workers, progress=progress.step, stand_in=stand_in)
        mc = {"runs": args.runs, "seed": args.seed, "summary": intervals(mc_rows, args.laws, cols),
              "uncertainty": {k: _spread_text(v) for k, v in spreads.items()},
              "uncertainty_source": args.uncertainty or "config/uncertainty.yaml", "figure": "compare_montecarlo.png"}
    data = {"setup": {**setup_description(entries), **plant}, **table_json(rows, cols)}
    if mc is not None:
        from ..experiments.compare_mc import intervals_json

        data["montecarlo"] = {**{k: v for k, v in mc.items() if k != "summary"},
                              "intervals": intervals_json(mc["summary"])}
    if args.json:
        print(json.dumps(data))
    else:
        if stand_in is not None:
            print(f"plant: the MuJoCo stand-in in lockstep, realism {plant['summary']}")
        print(text_table(rows, cols))
        if mc is not None:
            print(_interval_table(mc, rows, cols))
    if out is not None:
        for path in _write(out, args, entries, runs, cols, data, mc, mc_rows):
            print(f"wrote {path}", file=sys.stderr)
    diverged = [r for r in rows if r.values is None]
    if diverged:
        print("pdsmc compare: error: " + "; ".join(f"{r.label} diverged ({r.diverged})" for r in diverged),
              file=sys.stderr)
        return EXIT_DIVERGED
    return 0


def _check_montecarlo(args: argparse.Namespace, entries: Sequence[LawSpec]) -> dict[str, Spread]:
    """The spreads of ``--uncertainty`` and an arm whose parameters can be drawn (before any run)."""
    from ..experiments.montecarlo import base_specs, load_uncertainty

    spreads = load_uncertainty(args.uncertainty)
    base_specs(args.robot, args.contour, [entries[0].name], rate=args.rate, needs_gains=False)
    return spreads


def _spread_text(spread: Any) -> str:
    if spread.distribution == "normal" and spread.sd:
        return f"N(0, {spread.sd:g})"
    if spread.low or spread.high:
        return f"U({spread.low:g}, {spread.high:g})"
    return f"{spread.distribution} +-{100 * spread.relative:g} %"


def _interval_table(mc: Mapping[str, Any], rows: Sequence[LawRow], cols: Sequence[Column]) -> str:
    """The Monte Carlo's intervals as plain text: a line per column, a cell per law."""
    from ..experiments.compare import aligned
    from ..experiments.compare_mc import interval_rows

    head, body = interval_rows(mc["summary"], {r.law: r.label for r in rows}, cols)
    return aligned([[f"Monte Carlo, {mc['runs']} plants (seed {mc['seed']})", *head], *body]) + \
        "\neach cell: mean [bootstrap 95 % interval] over the runs that did not diverge"


def _write(out: Path, args: argparse.Namespace, entries: Sequence[LawSpec], runs: Sequence[tuple[LawRow, Samples]],
           cols: Sequence[Column], data: Mapping[str, Any], mc: Mapping[str, Any] | None,
           mc_rows: Sequence[Mapping[str, Any]] | None) -> list[Path]:
    """The figures and the report, into ``out``."""
    from ..experiments.compare_mc import plot_distributions
    from ..experiments.compare_report import build_report, write_figures, write_report

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {str(out)!r}: cannot create it ({exc.strerror})") from None
    figures = write_figures(runs, entries, out)
    spread = []  # the Monte Carlo's figure: in its own section of the report
    if mc is not None and mc_rows is not None:
        labels = {e.name: e.label for e in entries}
        spread.append(plot_distributions(mc_rows, args.laws, labels, cols, out / mc["figure"],
                                         f"{args.robot}/{args.contour}: {mc['runs']} drawn plants"))
    report = build_report(entries, [r for r, _ in runs], cols, figures, mc, plant=data["setup"])
    return [*figures, *spread, *write_report(report, data, mc_rows, out, args.format or "md")]
