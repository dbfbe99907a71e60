"""``pdsmc ladder``: the thesis's claims re-tested on the MuJoCo stand-in, rung by rung
(:mod:`pdsmc_ros.experiments.ladder`).

``pdsmc ladder --robot R [--contour C] [--scenario S] [--laws pd,smc,...] [--rungs ideal,friction,...] --draws N
[--more-draws M] [--seed K] [--uncertainty FILE] [--workers W | --scheduler ADDR] --out DIR``

Every law runs on ``N`` seeded draws at every rung (the comparison's Monte Carlo, on Dask); with
``--more-draws M`` the rungs where a claim is undecided after ``N`` get ``M`` more. Writes
``ladder.json``, ``ladder.csv``, ``ladder.md`` and ``ladder.png`` into ``DIR`` and prints the verdicts.
Bad input (an unknown law, robot, contour or rung, a law without gains, gains unstable at the rate, a
bad ``--uncertainty`` file, ``--out`` a file) is one line and exit 2, before anything runs.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .options import name_list, run_count, seed_value, worker_count


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``ladder`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("ladder", help="the thesis's claims re-tested on the MuJoCo stand-in, nuisance by nuisance")
    p.add_argument("--robot", required=True, help="serial_3r, parallel_5r or an arm of example-robot-data (ur5)")
    p.add_argument("--contour", default="circle", help="a contour of the robot (default circle)")
    p.add_argument("--scenario", default="nominal",
                   help="nominal (default), high_speed, ...: the thesis's scenarios (high_speed: the contour in a "
                   "shorter time)")
    p.add_argument("--laws", type=name_list, default=None,
                   help="comma-separated laws (default pd,smc,pdsmc,pdg,ctc,sta,ismc)")
    p.add_argument("--rungs", type=name_list, default=None,
                   help="comma-separated rungs (default all: ideal,friction,sensing,delay,payload,bench)")
    p.add_argument("--draws", type=run_count, required=True, help="seeded draws a rung (every law on each)")
    p.add_argument("--more-draws", type=run_count, default=None,
                   help="this many more draws on the rungs where a claim is undecided after --draws (and on "
                        "the ideal rung, which the robustness claim pairs its draws with)")
    p.add_argument("--seed", type=seed_value, default=0, help="draw i: default_rng([seed, i]) (default 0)")
    p.add_argument("--uncertainty", default=None,
                   help="YAML of the plant's spreads (default config/ladder_uncertainty.yaml)")
    p.add_argument("--workers", type=worker_count, default=None, help="local cluster processes (default: cores)")
    p.add_argument("--scheduler", default=None, help="a Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--out", required=True, help="directory for ladder.json, .csv, .md and .png")
    commands["ladder"] = run


def command_line(args: argparse.Namespace) -> str:
    """The command that re-runs this ladder (every setting spelled out; the workers left out)."""
    words = ["pdsmc", "ladder", "--robot", args.robot, "--contour", args.contour]
    if args.scenario != "nominal":
        words += ["--scenario", args.scenario]
    words += ["--laws", ",".join(args.laws),
             "--rungs", ",".join(args.rungs), "--draws", str(args.draws)]
    if args.more_draws:
        words += ["--more-draws", str(args.more_draws)]
    words += ["--seed", str(args.seed)]
    if args.uncertainty:
        words += ["--uncertainty", args.uncertainty]
    return shlex.join([*words, "--out", args.out])


def run(args: argparse.Namespace) -> int:
    from ..control import law
    from ..experiments.compare import law_specs
    from ..experiments.ladder import (
        LAWS,
        RUNG_NAMES,
        check_rungs,
        ladder_columns,
        run_ladder,
        rung_stand_ins,
        sort_rows,
        summarize,
        undecided_rungs,
        verdicts,
        write_outputs,
    )
    from ..experiments.montecarlo import LINK_PARAMETERS, load_uncertainty
    from ..robots import make_robot
    from ..sim.engine import Progress
    from .compare import _spread_text
    from .stand_in import describe_plant

    args.laws = args.laws or list(LAWS)
    args.rungs = args.rungs or list(RUNG_NAMES)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {args.out!r} is a file: give a directory")
    for name in args.laws:
        law(name)
    rungs = check_rungs(args.rungs)
    spreads = load_uncertainty(args.uncertainty, default="ladder_uncertainty")
    entries = law_specs(args.robot, args.contour, args.laws, scenario=args.scenario)
    specs = [e.spec for e in entries]
    robot, rate = specs[0].robot, specs[0].rate
    if not make_robot(robot).has_link_params and args.uncertainty is None:  # the default file's link spreads
        spreads = {k: v for k, v in spreads.items() if k not in LINK_PARAMETERS}
    stand_ins = rung_stand_ins(robot, rate, rungs)
    plants = {name: describe_plant(s, robot, rate)["summary"] for name, s in stand_ins.items()}
    labels = {e.name: e.label for e in entries}
    cols = ladder_columns(specs[0].gains.n)
    progress = Progress(args.draws * len(rungs), "ladder")
    rows = run_ladder(specs, spreads, stand_ins, args.draws, args.seed, scheduler=args.scheduler,
                      workers=args.workers, progress=progress.step)
    names = [r.name for r in rungs]
    draws = dict.fromkeys(names, args.draws)
    summary = summarize(rows, names, args.laws, cols)
    found = verdicts(summary, rows, names)
    more = undecided_rungs(found) if args.more_draws else []
    if more:
        print(f"undecided at {', '.join(more)}: {args.more_draws} more draws there", file=sys.stderr)
        progress = Progress(args.more_draws * len(more), "ladder")
        rows = sort_rows(rows + run_ladder(specs, spreads, {k: stand_ins[k] for k in more}, args.more_draws,
                                           args.seed, first=args.draws, scheduler=args.scheduler,
                                           workers=args.workers, progress=progress.step), names, args.laws)
        draws.update(dict.fromkeys(more, args.draws + args.more_draws))
        summary = summarize(rows, names, args.laws, cols)
        found = verdicts(summary, rows, names)
    meta: dict[str, Any] = {
        "command": command_line(args),
        "robot": args.robot, "contour": args.contour, "scenario": args.scenario, "laws": list(args.laws),
        "rungs": names, "draws": args.draws,
        "draws_by_rung": draws, "seed": args.seed, "control_rate_hz": rate,
        "uncertainty": {k: vars(v) for k, v in spreads.items()},
        "uncertainty_text": ", ".join(f"{k} {_spread_text(v)}" for k, v in spreads.items()) or "none",
        "plants": plants, "gains": {e.name: e.source for e in entries}}
    for v in found:
        print(f"{v.claim:9s} {v.rung:9s} {v.verdict:10s} {v.why}")
    for path in write_outputs(out, meta, rows, summary, found, cols, labels):
        print(f"wrote {path}", file=sys.stderr)
    return 0
