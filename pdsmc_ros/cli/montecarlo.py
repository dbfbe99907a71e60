"""``pdsmc montecarlo``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .options import (
    RUN_DEFAULTS,
    add_engine_arguments,
    file_controller,
    name_list,
    run_count,
    seed_value,
    spec_from_args,
)


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``montecarlo`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("montecarlo", help="robustness: the controllers against a spread of plants (Dask)")
    p.add_argument("--robot", required=True, help="serial_3r or parallel_5r (their link and motor parameters vary)")
    p.add_argument("--contour", required=True)
    p.add_argument("--controllers", type=name_list, default=["pd", "smc", "pdsmc"],
                   help="comma-separated control laws (default pd,smc,pdsmc)")
    p.add_argument("--runs", type=run_count, required=True, help="plants drawn (each runs every controller)")
    p.add_argument("--seed", type=seed_value, default=0, help="run i draws from default_rng([seed, i]) (default 0)")
    p.add_argument("--params-file", default=None,
                   help="gains of the file's controller from a ROS 2 params file (pdsmc tune writes one)")
    p.add_argument("--uncertainty", default=None,
                   help="YAML of parameter spreads (default: config/uncertainty.yaml)")
    add_engine_arguments(p)
    p.add_argument("--out", required=True, help="directory for montecarlo.csv, .json and the plot")
    commands["montecarlo"] = run


def run(args: argparse.Namespace) -> int:
    from ..control import law
    from ..control.stability import check_rate
    from ..experiments.montecarlo import (
        base_specs,
        load_uncertainty,
        plot_distribution,
        run_sample,
        summarize,
        write_outputs,
    )
    from ..sim.engine import Progress, dask_client, run_tasks

    for controller in args.controllers:
        law(controller)
    spreads = load_uncertainty(args.uncertainty)
    specs = base_specs(args.robot, args.contour, args.controllers)
    if args.params_file:  # the file's controller runs the file's gains (scaled as simulate scales them)
        specs = [spec_from_args(argparse.Namespace(**{**RUN_DEFAULTS, **vars(args), "controller": spec.controller}))
                 if spec.controller == file_controller(args.params_file, args.controllers) else spec
                 for spec in specs]
    for spec in specs:  # the nominal gains must be stable at the rate; a drawn plant may still diverge
        check_rate(spec, spec.reference())
    out = Path(args.out)
    bound = specs[0].bound
    meta = {"robot": args.robot, "contour": args.contour, "controllers": list(args.controllers), "runs": args.runs,
            "seed": args.seed, "uncertainty": {k: vars(v) for k, v in spreads.items()}, "contour_bound_m": bound}
    rows: list[Any] = []
    done = 0
    progress = Progress(args.runs, "montecarlo")
    interrupted = False
    with dask_client(args.scheduler, args.workers) as client:
        try:
            for _, result in run_tasks(client, run_sample, [(i, args.seed, specs, spreads) for i in range(args.runs)]):
                rows += result
                done += 1
                progress.step()
        except KeyboardInterrupt:
            interrupted = True
    meta["runs_done"] = done
    summary = summarize(rows, args.controllers, bound)
    written = write_outputs(rows, summary, meta, out)
    if rows:
        written.append(plot_distribution(rows, args.controllers, bound, out / "montecarlo.png",
                                         f"{args.robot}/{args.contour}: {done} plants"))
    for controller in args.controllers:
        entry = summary[controller]
        if "contour_mean_mean" in entry:
            print(f"{controller:6s} contour mean over {entry['runs']} runs: mean {entry['contour_mean_mean']:.4e}  "
                  f"p5 {entry['contour_mean_p5']:.4e}  p50 {entry['contour_mean_p50']:.4e}  "
                  f"p95 {entry['contour_mean_p95']:.4e}  worst {entry['contour_mean_worst']:.4e} m; "
                  f"{100 * entry['share_within_bound']:.1f} % within {bound:g} m; {entry['failed']} failed")
    print(f"wrote {', '.join(str(p) for p in written)}", file=sys.stderr)
    if interrupted:
        print(f"pdsmc montecarlo: interrupted: the table is partial ({done} of {args.runs} runs)", file=sys.stderr)
        return 130
    return 0
